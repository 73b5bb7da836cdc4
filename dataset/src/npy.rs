//! A reader for NumPy `.npy` files holding a little-endian float array (what LLFF's
//! `poses_bounds.npy` is). Only what datasets use is supported: `<f8` and `<f4`, C order.

use std::path::Path;

use crate::DatasetError;

/// A float array with its shape, values in C (row-major) order.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    pub shape: Vec<usize>,
    pub data: Vec<f64>,
}

/// Reads a `.npy` file.
pub fn read_npy(path: &Path) -> Result<NpyArray, DatasetError> {
    let bytes = crate::read_file(path)?;
    parse_npy(&bytes).map_err(|message| DatasetError::malformed(path, message))
}

/// Parses `.npy` bytes (format versions 1, 2 and 3).
pub fn parse_npy(bytes: &[u8]) -> Result<NpyArray, String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a .npy file (bad magic)".into());
    }
    let (header_len, header_start): (usize, usize) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => match bytes.get(8..12) {
            Some(len) => (u32::from_le_bytes(len.try_into().expect("4 bytes")) as usize, 12),
            None => return Err("truncated header".into()),
        },
        v => return Err(format!("unsupported .npy version {v}")),
    };
    let header_end = header_start.checked_add(header_len).filter(|&e| e <= bytes.len()).ok_or("truncated header")?;
    let header = std::str::from_utf8(&bytes[header_start..header_end]).map_err(|_| "header is not text")?;
    let descr = dict_value(header, "descr").ok_or("header has no 'descr'")?;
    let descr = descr.split(['\'', '"']).nth(1).ok_or("malformed 'descr'")?;
    let item_size = match descr {
        "<f8" => 8,
        "<f4" => 4,
        other => return Err(format!("unsupported dtype {other} (expected <f8 or <f4)")),
    };
    if dict_value(header, "fortran_order").is_some_and(|v| v.starts_with("True")) {
        return Err("Fortran-ordered arrays are not supported".into());
    }
    let shape_text = dict_value(header, "shape").ok_or("header has no 'shape'")?;
    let shape_text = shape_text.trim_start_matches('(');
    let shape_text = &shape_text[..shape_text.find(')').ok_or("malformed shape")?];
    let shape: Vec<usize> = shape_text
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| format!("bad dimension `{s}` in shape")))
        .collect::<Result<_, _>>()?;
    let count = shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d)).ok_or("shape overflows")?;
    let data_bytes = &bytes[header_end..];
    if count.checked_mul(item_size).is_none_or(|n| n > data_bytes.len()) {
        return Err(format!("data holds {} bytes, shape {shape:?} needs {count} x {item_size}", data_bytes.len()));
    }
    let data = data_bytes
        .chunks_exact(item_size)
        .take(count)
        .map(|c| match item_size {
            8 => f64::from_le_bytes(c.try_into().expect("8 bytes")),
            _ => f32::from_le_bytes(c.try_into().expect("4 bytes")) as f64,
        })
        .collect();
    Ok(NpyArray { shape, data })
}

/// The raw text after `'key':` in a NumPy header dict.
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header.find(&format!("'{key}'"))?;
    let rest = &header[at + key.len() + 2..];
    Some(rest.trim_start().strip_prefix(':')?.trim_start())
}

/// Encodes a `<f8` array as `.npy` version 1 (used to make test data).
pub fn encode_npy(array: &NpyArray) -> Vec<u8> {
    let dims: Vec<String> = array.shape.iter().map(|d| d.to_string()).collect();
    let shape = if dims.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for v in &array.data {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let a = NpyArray { shape: vec![2, 3], data: vec![1.0, -2.5, 3.25, 1e-300, f64::MAX, 0.0] };
        assert_eq!(parse_npy(&encode_npy(&a)).unwrap(), a);
    }

    #[test]
    fn corrupt_inputs_are_errors() {
        let bytes = encode_npy(&NpyArray { shape: vec![4, 17], data: vec![0.5; 68] });
        for cut in [0, 5, 9, 20, bytes.len() - 1] {
            assert!(parse_npy(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        // A header declaring far more data than the file holds fails before allocating.
        let huge = encode_npy(&NpyArray { shape: vec![4_000_000_000_000, 17], data: vec![0.5; 68] });
        assert!(parse_npy(&huge).unwrap_err().contains("needs"));
        let mut ints = bytes.clone();
        let at = ints.windows(3).position(|w| w == b"<f8").unwrap();
        ints[at + 1] = b'i';
        assert!(parse_npy(&ints).unwrap_err().contains("dtype"));
    }
}

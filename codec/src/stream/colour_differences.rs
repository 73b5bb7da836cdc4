//! Colour differences (section `CDIF`, SPEC.md section 6.6): every colour triple of `COLR` and
//! `SHRS` coded as (r - g, g, b - g). The channels of captured scenes move together (greys,
//! browns), so the differences are narrower than the colours: measured on the uniformly
//! quantized DC colours of biker, a third fewer bits, of guitar 7-9% fewer.

use pwgs_bitstream::Tag;

use super::DecodeError;
use super::entropy::MAX_MAGNITUDE;

pub const COLOUR_DIFFERENCES: Tag = Tag(*b"CDIF");

/// Channel `c` of the coded triple of `rgb`.
pub fn coded(rgb: [i32; 3], c: usize) -> i32 {
    match c {
        1 => rgb[1],
        _ => rgb[c] - rgb[1],
    }
}

/// Whether every triple of `values` (r, g, b, r, g, b, ...) codes within the values' limit:
/// a difference may reach twice a colour's magnitude.
pub fn fit(values: &[i32]) -> bool {
    values
        .chunks_exact(3)
        .all(|t| (0..3).all(|c| i64::from(coded([t[0], t[1], t[2]], c)).abs() < i64::from(MAX_MAGNITUDE)))
}

/// Turns decoded triples of section `tag` back into colours, in place; a colour whose
/// magnitude reaches 2^24 is an error.
pub(super) fn undo(tag: Tag, values: &mut [i32]) -> Result<(), DecodeError> {
    for (t, triple) in values.chunks_exact_mut(3).enumerate() {
        let g = i64::from(triple[1]);
        for c in [0, 2] {
            let v = i64::from(triple[c]) + g;
            if v.abs() >= i64::from(MAX_MAGNITUDE) {
                let problem = format!("colour difference {} plus green {g} (triple {t}) reaches 2^24", triple[c]);
                return Err(DecodeError::invalid(tag, problem));
            }
            triple[c] = v as i32;
        }
    }
    Ok(())
}

/// `CDIF` carries nothing: its presence is the signal.
pub(super) fn check_payload(payload: &[u8]) -> Result<(), DecodeError> {
    match payload.len() {
        0 => Ok(()),
        n => Err(DecodeError::invalid(COLOUR_DIFFERENCES, format!("holds {n} bytes; the section must be empty"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_round_trip_and_their_limit_is_checked() {
        let colours = vec![5, -3, 7, 0, 0, 0, -(MAX_MAGNITUDE - 1), 0, MAX_MAGNITUDE - 1];
        assert!(fit(&colours));
        let mut coded_values: Vec<i32> =
            colours.chunks_exact(3).flat_map(|t| (0..3).map(move |c| coded([t[0], t[1], t[2]], c))).collect();
        assert_eq!(&coded_values[..3], &[8, -3, 10]);
        undo(COLOUR_DIFFERENCES, &mut coded_values).unwrap();
        assert_eq!(coded_values, colours);
        // A green far from red: the difference would reach 2^24.
        assert!(!fit(&[MAX_MAGNITUDE - 1, -1, 0]));
        let mut bad = vec![MAX_MAGNITUDE - 1, 1, 0];
        let e = undo(COLOUR_DIFFERENCES, &mut bad).unwrap_err().to_string();
        assert!(e.contains("CDIF") && e.contains("reaches 2^24"), "{e}");
        assert!(check_payload(&[]).is_ok());
        assert!(check_payload(&[0]).unwrap_err().to_string().contains("must be empty"));
    }
}

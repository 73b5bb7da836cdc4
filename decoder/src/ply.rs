//! PLY reading and writing for Gaussian splats (the INRIA 3DGS layout) and plain point clouds.
//!
//! Properties are read by name, never by position, so files whose writers ordered them
//! differently (or left out normals or `f_rest_*`) load the same. ASCII and both binary
//! encodings are parsed; every element before the vertex element is skipped properly, list
//! properties included. Declared counts are checked against the bytes actually present before
//! anything is allocated, so a corrupt header cannot trigger a huge allocation.

use std::collections::HashMap;
use std::path::Path;

use crate::gaussians::{Gaussians, MAX_SH_DEGREE, sh_coeff_count};

/// A problem with a PLY file; `source` names the file.
#[derive(Debug, thiserror::Error)]
#[error("{source_name}: {problem}")]
pub struct PlyError {
    pub source_name: String,
    pub problem: PlyProblem,
}

#[derive(Debug, thiserror::Error)]
pub enum PlyProblem {
    #[error("cannot read or write the file: {0}")]
    Io(#[from] std::io::Error),
    #[error("not a PLY file (missing `ply` magic line)")]
    NotPly,
    #[error("malformed header line {line}: {message}")]
    Header { line: usize, message: String },
    #[error("the file has no `vertex` element")]
    NoVertexElement,
    #[error("vertex property `{0}` is missing")]
    MissingProperty(String),
    #[error("{0} f_rest_* properties do not make a whole SH degree up to {MAX_SH_DEGREE}")]
    BadShCount(usize),
    #[error("data ends early: element `{element}` row {row} of {count}")]
    Truncated { element: String, row: usize, count: usize },
    #[error("bad value in element `{element}` row {row}: {message}")]
    BadValue { element: String, row: usize, message: String },
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn read_binary(self, bytes: &[u8], big_endian: bool) -> f64 {
        macro_rules! conv {
            ($t:ty, $n:expr) => {{
                let arr: [u8; $n] = bytes[..$n].try_into().expect("length checked by caller");
                (if big_endian { <$t>::from_be_bytes(arr) } else { <$t>::from_le_bytes(arr) }) as f64
            }};
        }
        match self {
            Self::I8 => bytes[0] as i8 as f64,
            Self::U8 => bytes[0] as f64,
            Self::I16 => conv!(i16, 2),
            Self::U16 => conv!(u16, 2),
            Self::I32 => conv!(i32, 4),
            Self::U32 => conv!(u32, 4),
            Self::F32 => conv!(f32, 4),
            Self::F64 => conv!(f64, 8),
        }
    }
}

#[derive(Debug, Clone)]
enum Property {
    Scalar { name: String, ty: Scalar },
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

/// The vertex element of a PLY file, column by property name. Values are kept in f64 so that
/// f32 and integer properties convert back exactly.
#[derive(Debug, Clone)]
pub struct VertexTable {
    pub count: usize,
    columns: HashMap<String, Vec<f64>>,
}

impl VertexTable {
    /// A column by property name.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns.get(name).map(Vec::as_slice)
    }

    fn require(&self, name: &str) -> Result<&[f64], PlyProblem> {
        self.column(name).ok_or_else(|| PlyProblem::MissingProperty(name.to_string()))
    }
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    data_start: usize,
}

fn parse_header(bytes: &[u8]) -> Result<Header, PlyProblem> {
    let mut pos = 0;
    let mut line_no = 0;
    let next_line = |pos: &mut usize| -> Option<String> {
        let rest = &bytes[*pos..];
        let end = rest.iter().position(|&b| b == b'\n')?;
        *pos += end + 1;
        Some(String::from_utf8_lossy(&rest[..end]).trim_end_matches('\r').to_string())
    };
    if next_line(&mut pos).as_deref().map(str::trim) != Some("ply") {
        return Err(PlyProblem::NotPly);
    }
    let header_err = |line: usize, message: &str| PlyProblem::Header { line, message: message.to_string() };
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line_no += 1;
        let line = next_line(&mut pos).ok_or_else(|| header_err(line_no + 1, "header has no `end_header`"))?;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["end_header"] => break,
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["format", fmt, _version] => {
                encoding = Some(match *fmt {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittleEndian,
                    "binary_big_endian" => Encoding::BinaryBigEndian,
                    _ => return Err(header_err(line_no + 1, &format!("unknown format `{fmt}`"))),
                })
            }
            ["element", name, count] => {
                let count =
                    count.parse().map_err(|_| header_err(line_no + 1, &format!("bad element count `{count}`")))?;
                elements.push(Element { name: name.to_string(), count, properties: Vec::new() });
            }
            ["property", "list", count_ty, item_ty, _name] => {
                let count = Scalar::parse(count_ty)
                    .ok_or_else(|| header_err(line_no + 1, &format!("unknown type `{count_ty}`")))?;
                let item = Scalar::parse(item_ty)
                    .ok_or_else(|| header_err(line_no + 1, &format!("unknown type `{item_ty}`")))?;
                let element =
                    elements.last_mut().ok_or_else(|| header_err(line_no + 1, "property before any element"))?;
                element.properties.push(Property::List { count, item });
            }
            ["property", ty, name] => {
                let ty = Scalar::parse(ty).ok_or_else(|| header_err(line_no + 1, &format!("unknown type `{ty}`")))?;
                let element =
                    elements.last_mut().ok_or_else(|| header_err(line_no + 1, "property before any element"))?;
                element.properties.push(Property::Scalar { name: name.to_string(), ty });
            }
            _ => return Err(header_err(line_no + 1, &format!("unexpected line `{line}`"))),
        }
    }
    let encoding = encoding.ok_or_else(|| header_err(1, "no `format` line"))?;
    Ok(Header { encoding, elements, data_start: pos })
}

/// Reads values one at a time from the data part of a PLY file.
enum Cursor<'a> {
    Ascii(std::str::SplitAsciiWhitespace<'a>),
    Binary { data: &'a [u8], big_endian: bool },
}

impl Cursor<'_> {
    /// The next value; `Ok(None)` when the data ends, `Err` when a token is not a number.
    fn next(&mut self, ty: Scalar) -> Result<Option<f64>, String> {
        match self {
            Self::Ascii(tokens) => match tokens.next() {
                None => Ok(None),
                Some(token) => token.parse().map(Some).map_err(|_| format!("`{token}` is not a number")),
            },
            Self::Binary { data, big_endian } => {
                if data.len() < ty.size() {
                    return Ok(None);
                }
                let value = ty.read_binary(data, *big_endian);
                *data = &data[ty.size()..];
                Ok(Some(value))
            }
        }
    }

    /// Bytes left, or for ASCII an upper bound on the values left.
    fn remaining(&self, file_len: usize) -> usize {
        match self {
            Self::Ascii(_) => file_len,
            Self::Binary { data, .. } => data.len(),
        }
    }
}

/// Reads the vertex element of a PLY file held in memory.
pub fn read_vertex_table(bytes: &[u8]) -> Result<VertexTable, PlyProblem> {
    let header = parse_header(bytes)?;
    let data = &bytes[header.data_start..];
    let mut cursor = match header.encoding {
        Encoding::Ascii => Cursor::Ascii(
            std::str::from_utf8(data)
                .map_err(|_| PlyProblem::BadValue {
                    element: "data".into(),
                    row: 0,
                    message: "ASCII data is not UTF-8".into(),
                })?
                .split_ascii_whitespace(),
        ),
        Encoding::BinaryLittleEndian => Cursor::Binary { data, big_endian: false },
        Encoding::BinaryBigEndian => Cursor::Binary { data, big_endian: true },
    };
    for element in &header.elements {
        let is_vertex = element.name == "vertex";
        // Bound the allocation by what the file can hold: every row takes at least one byte.
        let min_row = element
            .properties
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => ty.size(),
                Property::List { count, .. } => count.size(),
            })
            .sum::<usize>()
            .max(1);
        if element.count > cursor.remaining(bytes.len()) / min_row {
            return Err(PlyProblem::Truncated { element: element.name.clone(), row: 0, count: element.count });
        }
        let scalar_count = element.properties.iter().filter(|p| matches!(p, Property::Scalar { .. })).count();
        let mut columns: Vec<Vec<f64>> =
            if is_vertex { (0..scalar_count).map(|_| Vec::with_capacity(element.count)).collect() } else { Vec::new() };
        for row in 0..element.count {
            let bad = |message: String| PlyProblem::BadValue { element: element.name.clone(), row, message };
            let read = |cursor: &mut Cursor, ty: Scalar| {
                cursor.next(ty).map_err(bad)?.ok_or_else(|| PlyProblem::Truncated {
                    element: element.name.clone(),
                    row,
                    count: element.count,
                })
            };
            let mut column = 0;
            for property in &element.properties {
                match property {
                    Property::Scalar { ty, .. } => {
                        let value = read(&mut cursor, *ty)?;
                        if is_vertex {
                            columns[column].push(value);
                        }
                        column += 1;
                    }
                    Property::List { count, item } => {
                        let n = read(&mut cursor, *count)?;
                        if !(n >= 0.0 && n <= u32::MAX as f64) {
                            return Err(PlyProblem::BadValue {
                                element: element.name.clone(),
                                row,
                                message: format!("list length {n} is not a count"),
                            });
                        }
                        for _ in 0..n as usize {
                            read(&mut cursor, *item)?;
                        }
                    }
                }
            }
        }
        if is_vertex {
            let names = element.properties.iter().filter_map(|p| match p {
                Property::Scalar { name, .. } => Some(name.clone()),
                Property::List { .. } => None,
            });
            return Ok(VertexTable { count: element.count, columns: names.zip(columns).collect() });
        }
    }
    Err(PlyProblem::NoVertexElement)
}

/// Gaussians loaded from a PLY file, with what had to be repaired on the way.
#[derive(Debug, Clone)]
pub struct PlyGaussians {
    pub gaussians: Gaussians,
    /// Gaussians dropped because a position, scale, rotation or color was NaN or infinite.
    pub dropped_non_finite: usize,
    /// Opacity logits that were infinite and were clamped to +/- `OPACITY_LOGIT_LIMIT`.
    pub clamped_opacities: usize,
}

/// Infinite opacity logits (fully opaque or fully transparent splats, which some trainers
/// produce) are clamped to this magnitude: sigmoid(20) rounds to 1 in f32.
pub const OPACITY_LOGIT_LIMIT: f32 = 20.0;

fn with_source<T>(name: &str, result: Result<T, PlyProblem>) -> Result<T, PlyError> {
    result.map_err(|problem| PlyError { source_name: name.to_string(), problem })
}

/// Reads Gaussians from an INRIA-layout PLY file.
pub fn read_gaussians(path: &Path) -> Result<PlyGaussians, PlyError> {
    let name = path.display().to_string();
    let bytes = with_source(&name, std::fs::read(path).map_err(PlyProblem::from))?;
    with_source(&name, gaussians_from_bytes(&bytes))
}

/// Reads Gaussians from PLY bytes. Non-finite values never reach the result: see
/// [`PlyGaussians`] for what is dropped or clamped.
pub fn gaussians_from_bytes(bytes: &[u8]) -> Result<PlyGaussians, PlyProblem> {
    let table = read_vertex_table(bytes)?;
    let rest_count = (0..).take_while(|i| table.column(&format!("f_rest_{i}")).is_some()).count();
    let coeffs = rest_count / 3 + 1;
    let degree = (0..=MAX_SH_DEGREE).find(|&d| sh_coeff_count(d) == coeffs);
    let degree = match degree {
        Some(d) if rest_count % 3 == 0 => d,
        _ => return Err(PlyProblem::BadShCount(rest_count)),
    };
    let get = |name: &str| table.require(name);
    let pos = [get("x")?, get("y")?, get("z")?];
    let scale = [get("scale_0")?, get("scale_1")?, get("scale_2")?];
    let rot = [get("rot_0")?, get("rot_1")?, get("rot_2")?, get("rot_3")?];
    let opacity = get("opacity")?;
    let dc = [get("f_dc_0")?, get("f_dc_1")?, get("f_dc_2")?];
    let rest: Vec<&[f64]> = (0..rest_count).map(|i| get(&format!("f_rest_{i}"))).collect::<Result<_, _>>()?;

    let mut out =
        PlyGaussians { gaussians: Gaussians::with_degree(degree), dropped_non_finite: 0, clamped_opacities: 0 };
    let mut sh = vec![0.0f32; coeffs * 3];
    for i in 0..table.count {
        let mean = pos.map(|c| c[i] as f32);
        let log_scale = scale.map(|c| c[i] as f32);
        let rotation = rot.map(|c| c[i] as f32);
        for c in 0..3 {
            sh[c] = dc[c][i] as f32;
            // INRIA stores the higher coefficients channel-major: f_rest[c * (K - 1) + (k - 1)].
            for k in 1..coeffs {
                sh[k * 3 + c] = rest[c * (coeffs - 1) + k - 1][i] as f32;
            }
        }
        let finite = mean.iter().chain(&log_scale).chain(&rotation).chain(&sh).all(|v| v.is_finite());
        let mut logit = opacity[i] as f32;
        if !finite || logit.is_nan() {
            out.dropped_non_finite += 1;
            continue;
        }
        if logit.is_infinite() {
            logit = logit.signum() * OPACITY_LOGIT_LIMIT;
            out.clamped_opacities += 1;
        }
        out.gaussians.push(mean, log_scale, rotation, logit, &sh);
    }
    Ok(out)
}

/// Property names of the INRIA layout for a given SH degree, in the order INRIA writes them.
fn inria_property_names(degree: u32) -> Vec<String> {
    let rest = (sh_coeff_count(degree) - 1) * 3;
    let mut names: Vec<String> =
        ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"].iter().map(|s| s.to_string()).collect();
    names.extend((0..rest).map(|i| format!("f_rest_{i}")));
    names.extend(
        ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"].iter().map(|s| s.to_string()),
    );
    names
}

fn inria_header(count: usize, names: &[String]) -> String {
    let mut out = format!("ply\nformat binary_little_endian 1.0\nelement vertex {count}\n");
    for name in names {
        out.push_str(&format!("property float {name}\n"));
    }
    out.push_str("end_header\n");
    out
}

/// Size in bytes of [`gaussians_to_bytes`]'s output, without encoding anything.
pub fn inria_ply_size(g: &Gaussians) -> usize {
    let names = inria_property_names(g.sh_degree);
    inria_header(g.len(), &names).len() + g.len() * names.len() * 4
}

/// Encodes Gaussians as a binary little-endian PLY in the INRIA layout (zero normals).
pub fn gaussians_to_bytes(g: &Gaussians) -> Vec<u8> {
    assert!(g.is_consistent(), "Gaussian arrays have inconsistent lengths");
    let names = inria_property_names(g.sh_degree);
    let mut bytes = inria_header(g.len(), &names).into_bytes();
    let coeffs = g.coeffs_per_channel();
    bytes.reserve(g.len() * names.len() * 4);
    for i in 0..g.len() {
        let sh = g.sh_of(i);
        let mut row: Vec<f32> = Vec::with_capacity(names.len());
        row.extend_from_slice(&g.means[i]);
        row.extend_from_slice(&[0.0; 3]);
        row.extend((0..3).map(|c| sh[c]));
        for c in 0..3 {
            row.extend((1..coeffs).map(|k| sh[k * 3 + c]));
        }
        row.push(g.opacity_logits[i]);
        row.extend_from_slice(&g.log_scales[i]);
        row.extend_from_slice(&g.rotations[i]);
        for v in row {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    bytes
}

/// Writes Gaussians to a PLY file (INRIA layout). The file is written to a temporary name and
/// renamed, so an existing file is never left half-written.
pub fn write_gaussians(path: &Path, g: &Gaussians) -> Result<(), PlyError> {
    let name = path.display().to_string();
    with_source(&name, crate::atomic_file::write_atomically(path, &gaussians_to_bytes(g)).map_err(PlyProblem::from))
}

/// A colored point cloud (e.g. SfM points for initialization), colors in [0, 1].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    pub positions: Vec<[f32; 3]>,
    pub colors: Vec<[f32; 3]>,
}

/// Reads a point cloud from PLY bytes: `x, y, z` and optionally `red, green, blue` (uchar, or
/// float in [0, 1]). Points with non-finite coordinates are dropped.
pub fn point_cloud_from_bytes(bytes: &[u8]) -> Result<PointCloud, PlyProblem> {
    let table = read_vertex_table(bytes)?;
    let pos = [table.require("x")?, table.require("y")?, table.require("z")?];
    let colors = ["red", "green", "blue"].map(|n| table.column(n));
    let max_color = colors.iter().flatten().flat_map(|c| c.iter()).fold(0.0f64, |m, &v| m.max(v));
    let color_scale = if max_color > 1.0 { 1.0 / 255.0 } else { 1.0 };
    let mut cloud = PointCloud::default();
    for i in 0..table.count {
        let p = pos.map(|c| c[i] as f32);
        if !p.iter().all(|v| v.is_finite()) {
            continue;
        }
        let rgb = colors.map(|c| c.map_or(0.5, |c| (c[i] * color_scale).clamp(0.0, 1.0) as f32));
        cloud.positions.push(p);
        cloud.colors.push(rgb);
    }
    Ok(cloud)
}

/// Encodes a point cloud as binary PLY with uchar colors.
pub fn point_cloud_to_bytes(cloud: &PointCloud) -> Vec<u8> {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        cloud.positions.len()
    )
    .into_bytes();
    for (p, c) in cloud.positions.iter().zip(&cloud.colors) {
        for v in p {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes.extend(c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8));
    }
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(degree: u32, n: usize) -> Gaussians {
        let mut g = Gaussians::with_degree(degree);
        let k = sh_coeff_count(degree) * 3;
        for i in 0..n {
            let f = i as f32;
            let sh: Vec<f32> = (0..k).map(|j| (f * 0.37 + j as f32 * 1.1).sin()).collect();
            g.push([f, -f * 0.5, 1e-7 * f], [-3.0, -2.5, f.cos()], [1.0, 0.1 * f, -0.2, 0.3], f - 2.0, &sh);
        }
        g
    }

    #[test]
    fn round_trip_is_lossless_for_every_degree() {
        for degree in 0..=MAX_SH_DEGREE {
            let g = sample(degree, 17);
            let bytes = gaussians_to_bytes(&g);
            assert_eq!(bytes.len(), inria_ply_size(&g));
            let back = gaussians_from_bytes(&bytes).unwrap();
            assert_eq!(back.gaussians, g, "degree {degree}");
            assert_eq!(back.dropped_non_finite, 0);
        }
    }

    #[test]
    fn reads_properties_by_name_in_any_order_and_ascii() {
        let text = "ply\nformat ascii 1.0\ncomment reordered\nelement face 1\nproperty list uchar int vertex_indices\n\
                    element vertex 2\nproperty float opacity\nproperty float rot_0\nproperty float rot_1\n\
                    property float rot_2\nproperty float rot_3\nproperty float f_dc_2\nproperty float f_dc_1\n\
                    property float f_dc_0\nproperty float scale_2\nproperty float scale_1\nproperty float scale_0\n\
                    property float z\nproperty float y\nproperty float x\nend_header\n\
                    3 0 1 2\n\
                    0.5 1 0 0 0 0.3 0.2 0.1 -1 -2 -3 3 2 1\n\
                    -0.5 1 0 0 0 0 0 0 0 0 0 6 5 4\n";
        let g = gaussians_from_bytes(text.as_bytes()).unwrap().gaussians;
        assert_eq!(g.sh_degree, 0);
        assert_eq!(g.means, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(g.log_scales[0], [-3.0, -2.0, -1.0]);
        assert_eq!(&g.sh[..3], &[0.1, 0.2, 0.3]);
        assert_eq!(g.opacity_logits, vec![0.5, -0.5]);
    }

    #[test]
    fn non_finite_values_are_dropped_or_clamped() {
        let mut g = sample(1, 4);
        g.means[1][2] = f32::NAN;
        g.sh[2 * 12 + 5] = f32::INFINITY;
        g.opacity_logits[3] = f32::INFINITY;
        let back = gaussians_from_bytes(&gaussians_to_bytes(&g)).unwrap();
        assert_eq!(back.dropped_non_finite, 2);
        assert_eq!(back.clamped_opacities, 1);
        assert_eq!(back.gaussians.len(), 2);
        assert_eq!(back.gaussians.opacity_logits[1], OPACITY_LOGIT_LIMIT);
        assert!(back.gaussians.sh.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn truncated_and_corrupt_files_are_errors() {
        let bytes = gaussians_to_bytes(&sample(2, 5));
        for cut in [0, 3, 40, bytes.len() / 2, bytes.len() - 1] {
            assert!(gaussians_from_bytes(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let huge = String::from_utf8_lossy(&bytes).replacen("element vertex 5", "element vertex 99999999999", 1);
        assert!(matches!(gaussians_from_bytes(huge.as_bytes()), Err(PlyProblem::Truncated { .. })));
        let bad_type = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float128 x\nend_header\n";
        assert!(matches!(gaussians_from_bytes(bad_type), Err(PlyProblem::Header { .. })));
        let no_scale = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n";
        assert!(matches!(gaussians_from_bytes(no_scale), Err(PlyProblem::MissingProperty(_))));
    }

    #[test]
    fn point_cloud_round_trip() {
        let cloud = PointCloud {
            positions: vec![[1.0, 2.0, 3.0], [-1.0, 0.5, 9.0]],
            colors: vec![[1.0, 0.0, 0.2], [0.0, 1.0, 0.6]],
        };
        let back = point_cloud_from_bytes(&point_cloud_to_bytes(&cloud)).unwrap();
        assert_eq!(back.positions, cloud.positions);
        for (a, b) in back.colors.iter().flatten().zip(cloud.colors.iter().flatten()) {
            assert!((a - b).abs() <= 0.5 / 255.0);
        }
    }
}

//! PLY reading and writing for Gaussian splats (the INRIA 3DGS layout; PlayCanvas's compressed
//! layout is read too) and plain point clouds.
//!
//! Properties are read by name, never by position, so files whose writers ordered them
//! differently (or left out normals or `f_rest_*`) load the same. ASCII and both binary
//! encodings are parsed, see [`vertex_table`] for how a hostile header or body is kept from
//! causing harm.

mod compressed;
mod vertex_table;

use std::path::Path;

pub use vertex_table::{ElementTable, read_tables, read_vertex_table};

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
    #[error("the file has no `{element}` element: {why}")]
    MissingElement { element: String, why: String },
    #[error("vertex property `{0}` is missing")]
    MissingProperty(String),
    #[error("{0} f_rest_* properties do not make a whole SH degree up to {MAX_SH_DEGREE}")]
    BadShCount(usize),
    #[error(
        "vertex property `{name}` breaks the f_rest_* numbering: the properties from f_rest_0 on stop after \
         {consecutive}"
    )]
    ShGap { name: String, consecutive: usize },
    #[error("data ends early: element `{element}` row {row} of {count}")]
    Truncated { element: String, row: usize, count: usize },
    #[error(
        "element `{element}` declares {count} rows, but the {bytes} data bytes left hold at most {max_rows}; \
         the file is truncated or its header corrupt"
    )]
    CountTooLarge { element: String, count: usize, bytes: usize, max_rows: usize },
    #[error("bad value in element `{element}` row {row}: {message}")]
    BadValue { element: String, row: usize, message: String },
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

/// Reads Gaussians from a PLY file: the INRIA layout, or the compressed layout of PlayCanvas's
/// tools (see [`compressed`]).
pub fn read_gaussians(path: &Path) -> Result<PlyGaussians, PlyError> {
    let name = path.display().to_string();
    let bytes = with_source(&name, std::fs::read(path).map_err(PlyProblem::from))?;
    with_source(&name, gaussians_from_bytes(&bytes))
}

/// Reads Gaussians from PLY bytes. Non-finite values never reach the result: see
/// [`PlyGaussians`] for what is dropped or clamped.
pub fn gaussians_from_bytes(bytes: &[u8]) -> Result<PlyGaussians, PlyProblem> {
    let tables = read_tables(bytes)?;
    let table = tables.iter().find(|t| t.name == "vertex").ok_or(PlyProblem::NoVertexElement)?;
    if compressed::is_compressed(table) {
        return compressed::gaussians(&tables, table);
    }
    let rest_count = (0..).take_while(|i| table.column(&format!("f_rest_{i}")).is_some()).count();
    // A gap in the numbering would otherwise silently drop the coefficients after it.
    let rest_names: Vec<String> = (0..rest_count).map(|i| format!("f_rest_{i}")).collect();
    if let Some(name) = table.names().find(|n| n.starts_with("f_rest_") && !rest_names.iter().any(|r| r == n)) {
        return Err(PlyProblem::ShGap { name: name.to_string(), consecutive: rest_count });
    }
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
    let rest: Vec<&[f64]> = rest_names.iter().map(|name| get(name)).collect::<Result<_, _>>()?;

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
        out.push(mean, log_scale, rotation, opacity[i] as f32, &sh);
    }
    Ok(out)
}

impl PlyGaussians {
    /// Adds a Gaussian as read, under the NaN policy: one with a non-finite value is dropped
    /// (counted), an infinite opacity logit clamped (counted).
    fn push(&mut self, mean: [f32; 3], log_scale: [f32; 3], rotation: [f32; 4], logit: f32, sh: &[f32]) {
        let finite = mean.iter().chain(&log_scale).chain(&rotation).chain(sh).all(|v| v.is_finite());
        if !finite || logit.is_nan() {
            self.dropped_non_finite += 1;
            return;
        }
        let logit = if logit.is_infinite() {
            self.clamped_opacities += 1;
            logit.signum() * OPACITY_LOGIT_LIMIT
        } else {
            logit
        };
        self.gaussians.push(mean, log_scale, rotation, logit, sh);
    }
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

/// Reads a point cloud from PLY bytes: `x, y, z` and optionally `red, green, blue`. Integer
/// colors are scaled by their type's maximum (255 for `uchar`); float colors are taken as
/// [0, 1], or as 0 to 255 when some value exceeds 1 (writers differ). A non-finite position or
/// color is an error: unlike a trained model's Gaussians (see [`PlyGaussians`]), a point cloud
/// has no known producer of such values, so one means a corrupt file.
pub fn point_cloud_from_bytes(bytes: &[u8]) -> Result<PointCloud, PlyProblem> {
    let table = read_vertex_table(bytes)?;
    let pos = [table.require("x")?, table.require("y")?, table.require("z")?];
    let colors = ["red", "green", "blue"].map(|n| table.column(n).map(|values| (n, values)));
    let integer_max = |name: &str| table.column_type(name).and_then(|ty| ty.integer_range()).map(|(_, max)| max);
    let float_0_to_255 =
        colors.iter().flatten().any(|&(name, values)| integer_max(name).is_none() && values.iter().any(|&v| v > 1.0));
    let color_scale = colors.map(|color| {
        let (name, _) = color?;
        Some(match integer_max(name) {
            Some(max) => 1.0 / max,
            None if float_0_to_255 => 1.0 / 255.0,
            None => 1.0,
        })
    });
    let bad = |row: usize, message: String| PlyProblem::BadValue { element: "vertex".into(), row, message };
    let mut cloud = PointCloud::default();
    for i in 0..table.count {
        let p = pos.map(|c| c[i] as f32);
        if !p.iter().all(|v| v.is_finite()) {
            return Err(bad(i, format!("position {:?} is not finite (in f32)", pos.map(|c| c[i]))));
        }
        let mut rgb = [0.5f32; 3];
        for (channel, (color, scale)) in colors.iter().zip(color_scale).enumerate() {
            let (Some((name, values)), Some(scale)) = (color, scale) else { continue };
            if !values[i].is_finite() {
                return Err(bad(i, format!("color `{name}` is {}", values[i])));
            }
            rgb[channel] = (values[i] * scale).clamp(0.0, 1.0) as f32;
        }
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
        let err = gaussians_from_bytes(huge.as_bytes()).unwrap_err();
        assert!(matches!(err, PlyProblem::CountTooLarge { .. }), "{err:?}");
        assert!(err.to_string().contains("element `vertex` declares 99999999999 rows"), "{err}");
        let bad_type = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float128 x\nend_header\n";
        assert!(matches!(gaussians_from_bytes(bad_type), Err(PlyProblem::Header { .. })));
        let no_scale = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n";
        assert!(matches!(gaussians_from_bytes(no_scale), Err(PlyProblem::MissingProperty(_))));
    }

    /// The error reading `text` as a point cloud, which must fail.
    fn cloud_error(text: &str) -> String {
        point_cloud_from_bytes(text.as_bytes()).expect_err(text).to_string()
    }

    const XYZ_ASCII: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                             property float z\nend_header\n";

    #[test]
    fn short_ascii_rows_are_not_mistaken_for_a_truncated_file() {
        // 50 rows of 6 bytes, where the binary sizes (12 bytes a row) would allow only 25.
        let text = format!("{}{}", XYZ_ASCII.replace("vertex 3", "vertex 50"), "0 1 2\n".repeat(50));
        assert_eq!(point_cloud_from_bytes(text.as_bytes()).unwrap().positions, vec![[0.0, 1.0, 2.0]; 50]);
        let text = format!("{}{}", XYZ_ASCII.replace("vertex 3", "vertex 51"), "0 1 2\n".repeat(50));
        assert!(cloud_error(&text).contains("element `vertex` declares 51 rows"));
    }

    #[test]
    fn an_ascii_line_with_a_value_too_many_or_too_few_is_an_error() {
        // Reading values as one stream would shift every later value instead.
        let err = cloud_error(&format!("{XYZ_ASCII}0 1 2\n3 4 5 6\n7 8 9\n"));
        assert!(err.contains("row 1: the line has more values than the header declares (`6` is extra)"), "{err}");
        let err = cloud_error(&format!("{XYZ_ASCII}0 1 2\n3 4\n5 6 7\n8 9 10\n"));
        assert!(err.contains("row 1: the line has fewer values than the header declares"), "{err}");
        // Blank lines between rows are fine; a missing last row is truncation.
        assert_eq!(
            point_cloud_from_bytes(format!("{XYZ_ASCII}\n0 1 2\n\n3 4 5\r\n6 7 8").as_bytes()).unwrap().positions.len(),
            3
        );
        let err = cloud_error(&format!("{XYZ_ASCII}0.000 1.000 2.000\n3 4 5\n"));
        assert!(err.contains("data ends early: element `vertex` row 2 of 3"), "{err}");
    }

    #[test]
    fn ascii_values_must_fit_their_declared_type() {
        let header = "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n\
                      element vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n\
                      end_header\n";
        assert!(cloud_error(&format!("{header}0\n0 0 0 300\n")).contains("row 0: `300` is not a `uchar` value"));
        assert!(cloud_error(&format!("{header}0\n0 0 0 1.5\n")).contains("`1.5` is not a `uchar` value"));
        let err = cloud_error(&format!("{header}2.5 0 1\n0 0 0 1\n"));
        assert!(err.contains("element `face` row 0: `2.5` is not a `uchar` value"), "{err}");
        let float_count = header.replace("list uchar int", "list float int");
        let err = cloud_error(&format!("{float_count}1 0\n0 0 0 1\n"));
        assert!(err.contains("list `vertex_indices` has count type `float`, which is not an integer type"), "{err}");
    }

    #[test]
    fn a_property_declared_twice_is_an_error() {
        let err = cloud_error(&XYZ_ASCII.replace("property float z", "property float x"));
        assert!(err.contains("header line 6: element `vertex` declares property `x` twice"), "{err}");
    }

    #[test]
    fn a_gap_in_the_f_rest_numbering_is_an_error() {
        // f_rest_0..8 and f_rest_10: without the check, degree 1 and f_rest_10 silently ignored.
        let text = String::from_utf8_lossy(&gaussians_to_bytes(&sample(1, 2))).into_owned();
        let text = text.replacen("property float f_rest_8\n", "property float f_rest_8\nproperty float f_rest_10\n", 1);
        let bytes = [text.as_bytes(), &[0u8; 8]].concat(); // room for the extra float in each row
        let err = gaussians_from_bytes(&bytes).unwrap_err().to_string();
        assert!(err.contains("`f_rest_10` breaks the f_rest_* numbering") && err.contains("stop after 9"), "{err}");
    }

    #[test]
    fn point_clouds_reject_non_finite_values() {
        let err = cloud_error(&format!("{XYZ_ASCII}0 1 2\n3 nan 5\n6 7 8\n"));
        assert!(err.contains("row 1: position [3.0, NaN, 5.0] is not finite"), "{err}");
        let err = cloud_error(&format!("{XYZ_ASCII}0 1 2\n3 1e39 5\n6 7 8\n"));
        assert!(err.contains("row 1: position") && err.contains("not finite (in f32)"), "{err}");
        let colored = XYZ_ASCII.replace("end_header", "property float red\nproperty float green\nend_header");
        let err = cloud_error(&format!("{colored}0 1 2 0 0\n3 4 5 0.5 inf\n6 7 8 1 1\n"));
        assert!(err.contains("row 1: color `green` is inf"), "{err}");
    }

    #[test]
    fn integer_colors_are_scaled_by_their_type() {
        // Colors of 0 and 1 in a uchar file are dark, whatever the largest value.
        let header = XYZ_ASCII
            .replace("vertex 3", "vertex 1")
            .replace("end_header", "property uchar red\nproperty ushort green\nend_header");
        let cloud = point_cloud_from_bytes(format!("{header}0 0 0 1 65535\n").as_bytes()).unwrap();
        assert_eq!(cloud.colors, vec![[(1.0f64 / 255.0) as f32, 1.0, 0.5]]);
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

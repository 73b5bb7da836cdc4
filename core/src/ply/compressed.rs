//! The compressed PLY layout of PlayCanvas's tools (SuperSplat, splat-transform): Gaussians in
//! chunks of 256, each chunk with the bounds of its positions, log-scales and (optionally)
//! colors in a `chunk` element; per Gaussian four `uint` words in the `vertex` element
//! (`packed_position` and `packed_scale` as 11-10-11-bit fractions of the chunk's bounds,
//! `packed_rotation` as the largest component's index and three 10-bit components,
//! `packed_color` as 8-bit color fractions and opacity); and the higher SH coefficients as
//! bytes in an optional `sh` element. It is recognized by the `packed_position` property.

use super::{ElementTable, PlyGaussians, PlyProblem};
use crate::gaussians::{Gaussians, MAX_SH_DEGREE, sh_coeff_count};

/// Gaussians per row of the `chunk` element.
const CHUNK: usize = 256;
/// The constant SH basis function: DC color = 0.5 + SH_C0 * coefficient.
const SH_C0: f64 = 0.28209479177387814;

/// Whether `vertex` is in the compressed layout.
pub(super) fn is_compressed(vertex: &ElementTable) -> bool {
    vertex.column("packed_position").is_some()
}

/// The `bits`-bit field of `word` at `shift`, as a fraction of its largest value.
fn unorm(word: u32, shift: u32, bits: u32) -> f64 {
    let max = (1u32 << bits) - 1;
    f64::from((word >> shift) & max) / f64::from(max)
}

fn lerp(lo: f64, hi: f64, t: f64) -> f64 {
    lo * (1.0 - t) + hi * t
}

/// A packed word as stored (a `uint` property holds every u32 exactly in f64).
fn word(column: &[f64], i: usize) -> u32 {
    column[i] as u32
}

/// The three 11-10-11-bit fields of `word` mapped into the bounds `lo` .. `hi`.
fn unpack_111011(word: u32, lo: [f64; 3], hi: [f64; 3]) -> [f32; 3] {
    let t = [unorm(word, 21, 11), unorm(word, 11, 10), unorm(word, 0, 11)];
    std::array::from_fn(|a| lerp(lo[a], hi[a], t[a]) as f32)
}

/// A quaternion stored as the index of its largest component (2 bits) and the other three
/// in 10 bits each, in [-1/sqrt(2), 1/sqrt(2)]; the largest is recovered from unit length.
fn unpack_rotation(word: u32) -> [f32; 4] {
    let norm = std::f64::consts::SQRT_2;
    let small = [20, 10, 0].map(|shift| (unorm(word, shift, 10) - 0.5) * norm);
    let largest = (1.0 - small.iter().map(|v| v * v).sum::<f64>()).max(0.0).sqrt();
    let index = (word >> 30) as usize;
    let mut q = [0.0f32; 4];
    let mut others = small.iter();
    for (i, value) in q.iter_mut().enumerate() {
        *value = if i == index { largest } else { *others.next().expect("three small components") } as f32;
    }
    q
}

/// A higher SH coefficient stored as a byte: 0 and 255 are the ends of [-4, 4], the others
/// the centres of 256 bins.
fn unpack_sh_byte(byte: f64) -> f32 {
    let t = if byte <= 0.0 {
        0.0
    } else if byte >= 255.0 {
        1.0
    } else {
        (byte + 0.5) / 256.0
    };
    ((t - 0.5) * 8.0) as f32
}

/// Reads the Gaussians of a compressed PLY from its element tables.
pub(super) fn gaussians(tables: &[ElementTable], vertex: &ElementTable) -> Result<PlyGaussians, PlyProblem> {
    let n = vertex.count;
    let chunk = tables.iter().find(|t| t.name == "chunk").ok_or_else(|| PlyProblem::MissingElement {
        element: "chunk".into(),
        why: "a compressed PLY (with `packed_position`) keeps its bounds there".into(),
    })?;
    let needed = n.div_ceil(CHUNK);
    if chunk.count < needed {
        return Err(PlyProblem::BadValue {
            element: "chunk".into(),
            row: chunk.count,
            message: format!(
                "{} rows hold the bounds of at most {} Gaussians, not {n}",
                chunk.count,
                chunk.count * CHUNK
            ),
        });
    }
    let bounds = |prefix: &str, axes: [&str; 3]| -> Result<[[&[f64]; 3]; 2], PlyProblem> {
        let get = |end: &str, axis: &str| chunk.require(&format!("{end}_{prefix}{axis}"));
        Ok([
            [get("min", axes[0])?, get("min", axes[1])?, get("min", axes[2])?],
            [get("max", axes[0])?, get("max", axes[1])?, get("max", axes[2])?],
        ])
    };
    let position = bounds("", ["x", "y", "z"])?;
    let scale = bounds("scale_", ["x", "y", "z"])?;
    let color = match chunk.column("min_r") {
        Some(_) => Some(bounds("", ["r", "g", "b"])?),
        None => None,
    };
    let packed = ["packed_position", "packed_rotation", "packed_scale", "packed_color"];
    let [pos_words, rot_words, scale_words, color_words] = packed.map(|name| vertex.require(name));
    let (pos_words, rot_words, scale_words, color_words) = (pos_words?, rot_words?, scale_words?, color_words?);

    let sh = tables.iter().find(|t| t.name == "sh");
    let rest_count = sh.map_or(0, |t| t.names().filter(|name| name.starts_with("f_rest_")).count());
    let degree = (0..=MAX_SH_DEGREE).find(|&d| (sh_coeff_count(d) - 1) * 3 == rest_count);
    let Some(degree) = degree else { return Err(PlyProblem::BadShCount(rest_count)) };
    let rest: Vec<&[f64]> = match sh {
        Some(t) if rest_count > 0 => {
            if t.count != n {
                return Err(PlyProblem::BadValue {
                    element: "sh".into(),
                    row: t.count.min(n),
                    message: format!("{} rows for {n} Gaussians", t.count),
                });
            }
            (0..rest_count).map(|i| t.require(&format!("f_rest_{i}"))).collect::<Result<_, _>>()?
        }
        _ => Vec::new(),
    };

    let coeffs = sh_coeff_count(degree);
    let mut out =
        PlyGaussians { gaussians: Gaussians::with_degree(degree), dropped_non_finite: 0, clamped_opacities: 0 };
    let mut coefficients = vec![0.0f32; coeffs * 3];
    for i in 0..n {
        let c = i / CHUNK;
        let at = |b: &[[&[f64]; 3]; 2]| (b[0].map(|col| col[c]), b[1].map(|col| col[c]));
        let (lo, hi) = at(&position);
        let mean = unpack_111011(word(pos_words, i), lo, hi);
        let (lo, hi) = at(&scale);
        let log_scale = unpack_111011(word(scale_words, i), lo, hi);
        let rotation = unpack_rotation(word(rot_words, i));
        let rgba = word(color_words, i);
        let fractions = [unorm(rgba, 24, 8), unorm(rgba, 16, 8), unorm(rgba, 8, 8)];
        let rgb: [f64; 3] = match &color {
            Some(b) => {
                let (lo, hi) = at(b);
                std::array::from_fn(|a| lerp(lo[a], hi[a], fractions[a]))
            }
            None => fractions,
        };
        for (channel, value) in rgb.iter().enumerate() {
            coefficients[channel] = ((value - 0.5) / SH_C0) as f32;
            // The `sh` element stores coefficients channel-major, as INRIA's f_rest does.
            for k in 1..coeffs {
                coefficients[k * 3 + channel] = unpack_sh_byte(rest[channel * (coeffs - 1) + k - 1][i]);
            }
        }
        let alpha = unorm(rgba, 0, 8);
        out.push(mean, log_scale, rotation, -(1.0 / alpha - 1.0).ln() as f32, &coefficients);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::gaussians_from_bytes;
    use super::*;
    use crate::random::{SplitMix64, random_gaussians};

    /// Fraction `t` of the field's largest value, rounded, at `shift`.
    fn field(t: f64, shift: u32, bits: u32) -> u32 {
        let max = (1u32 << bits) - 1;
        ((t.clamp(0.0, 1.0) * f64::from(max)).round() as u32) << shift
    }

    fn pack_111011(v: [f32; 3], lo: [f32; 3], hi: [f32; 3]) -> u32 {
        let t = |a: usize| f64::from((v[a] - lo[a]) / (hi[a] - lo[a]).max(1e-12));
        field(t(0), 21, 11) | field(t(1), 11, 10) | field(t(2), 0, 11)
    }

    fn pack_rotation(q: [f32; 4]) -> u32 {
        let norm = q.iter().map(|v| v * v).sum::<f32>().sqrt();
        let largest = (0..4).max_by(|&a, &b| q[a].abs().total_cmp(&q[b].abs())).unwrap();
        let sign = q[largest].signum() / norm;
        let small = (0..4).filter(|&i| i != largest).map(|i| f64::from(q[i] * sign) / std::f64::consts::SQRT_2 + 0.5);
        small.zip([20, 10, 0]).fold((largest as u32) << 30, |w, (t, shift)| w | field(t, shift, 10))
    }

    /// `g` as PlayCanvas's tools write it (per-chunk bounds of positions, log-scales and
    /// colors; SH bytes when the degree is above 0), a binary little-endian PLY.
    fn compressed_ply(g: &Gaussians) -> Vec<u8> {
        let n = g.len();
        let coeffs = g.coeffs_per_channel();
        let rgb = |i: usize| -> [f32; 3] { std::array::from_fn(|c| 0.5 + SH_C0 as f32 * g.sh_of(i)[c]) };
        let mut header = format!("ply\nformat binary_little_endian 1.0\nelement chunk {}\n", n.div_ceil(CHUNK));
        let xyz = ["x", "y", "z"];
        for (what, axes) in [("", xyz), ("scale_", xyz), ("", ["r", "g", "b"])] {
            for end in ["min", "max"] {
                axes.iter().for_each(|axis| header += &format!("property float {end}_{what}{axis}\n"));
            }
        }
        header += &format!("element vertex {n}\n");
        for name in ["position", "rotation", "scale", "color"] {
            header += &format!("property uint packed_{name}\n");
        }
        if coeffs > 1 {
            header += &format!("element sh {n}\n");
            (0..(coeffs - 1) * 3).for_each(|i| header += &format!("property uchar f_rest_{i}\n"));
        }
        let mut bytes = (header + "end_header\n").into_bytes();
        let mut chunk_bounds = Vec::new();
        for start in (0..n).step_by(CHUNK) {
            let rows = start..(start + CHUNK).min(n);
            let bounds = |value: &dyn Fn(usize) -> [f32; 3]| {
                let fold = |pick: fn(f32, f32) -> f32, init: f32| {
                    rows.clone().fold([init; 3], |acc, i| std::array::from_fn(|a| pick(acc[a], value(i)[a])))
                };
                (fold(f32::min, f32::INFINITY), fold(f32::max, f32::NEG_INFINITY))
            };
            let b = [bounds(&|i| g.means[i]), bounds(&|i| g.log_scales[i]), bounds(&rgb)];
            b.iter().flat_map(|(lo, hi)| lo.iter().chain(hi)).for_each(|v| bytes.extend(v.to_le_bytes()));
            chunk_bounds.push(b);
        }
        for i in 0..n {
            let [p, s, c] = chunk_bounds[i / CHUNK];
            let color = rgb(i);
            let t = |a: usize| f64::from((color[a] - c.0[a]) / (c.1[a] - c.0[a]).max(1e-12));
            let alpha = 1.0 / (1.0 + f64::from(-g.opacity_logits[i]).exp());
            let packed_color = field(t(0), 24, 8) | field(t(1), 16, 8) | field(t(2), 8, 8) | field(alpha, 0, 8);
            let words = [
                pack_111011(g.means[i], p.0, p.1),
                pack_rotation(g.rotations[i]),
                pack_111011(g.log_scales[i], s.0, s.1),
                packed_color,
            ];
            words.iter().for_each(|w| bytes.extend(w.to_le_bytes()));
        }
        for i in 0..n {
            for channel in 0..3 {
                for k in 1..coeffs {
                    let t = (f64::from(g.sh_of(i)[k * 3 + channel]) / 8.0 + 0.5).clamp(0.0, 1.0);
                    bytes.push((t * 256.0).floor().min(255.0) as u8);
                }
            }
        }
        bytes
    }

    #[test]
    fn reads_the_gaussians_within_the_layouts_quantization() {
        let g = random_gaussians(&mut SplitMix64(21), 600, 1, [-4.0, -1.0]);
        let read = gaussians_from_bytes(&compressed_ply(&g)).unwrap();
        let r = &read.gaussians;
        assert_eq!((r.len(), r.sh_degree, read.dropped_non_finite), (600, 1, 0));
        for i in 0..600 {
            let c = i / CHUNK;
            let span = |v: &dyn Fn(usize) -> f32| {
                let chunk = c * CHUNK..((c + 1) * CHUNK).min(600);
                chunk.clone().map(v).fold(f32::NEG_INFINITY, f32::max) - chunk.map(v).fold(f32::INFINITY, f32::min)
            };
            for a in 0..3 {
                // Half a step of 10 bits (the middle field; 11 bits elsewhere) of the chunk's span.
                let pos_tolerance = span(&|j| g.means[j][a]) / 1023.0 / 2.0 + 1e-5;
                assert!((r.means[i][a] - g.means[i][a]).abs() <= pos_tolerance, "mean {i} axis {a}");
                let scale_tolerance = span(&|j| g.log_scales[j][a]) / 1023.0 / 2.0 + 1e-5;
                assert!((r.log_scales[i][a] - g.log_scales[i][a]).abs() <= scale_tolerance, "scale {i} axis {a}");
                let dc_tolerance = span(&|j| g.sh_of(j)[a]) / 255.0 / 2.0 + 1e-5;
                assert!((r.sh_of(i)[a] - g.sh_of(i)[a]).abs() <= dc_tolerance, "color {i} channel {a}");
                // SH bytes: bins of 8 / 256.
                assert!((r.sh_of(i)[3 + a] - g.sh_of(i)[3 + a]).abs() <= 8.0 / 256.0, "sh {i} channel {a}");
            }
            let unit = |q: [f32; 4]| {
                let n = q.iter().map(|v| v * v).sum::<f32>().sqrt();
                q.map(|v| v / n)
            };
            let (a, b) = (unit(r.rotations[i]), unit(g.rotations[i]));
            let dot: f32 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
            assert!(dot.abs() > 1.0 - 1e-5, "rotation {i}: {a:?} vs {b:?}");
            let alpha = |logit: f32| 1.0 / (1.0 + (-logit).exp());
            assert!(
                (alpha(r.opacity_logits[i]) - alpha(g.opacity_logits[i])).abs() <= 0.5 / 255.0 + 1e-5,
                "opacity {i}"
            );
        }
    }

    #[test]
    fn broken_layouts_are_errors_naming_what_is_wrong() {
        let g = random_gaussians(&mut SplitMix64(4), 300, 0, [-4.0, -1.0]);
        let text = |bytes: &[u8]| gaussians_from_bytes(bytes).unwrap_err().to_string();
        let good = compressed_ply(&g);
        let header_end = good.windows(11).position(|w| w == b"end_header\n").unwrap();
        let header = String::from_utf8_lossy(&good[..header_end]).to_string();
        // One chunk row too few: the header says so and the data is one row shorter.
        let short = header.replace("element chunk 2", "element chunk 1");
        let chunk_row = 18 * 4;
        let body = [&good[header_end..header_end + 11], &good[header_end + 11 + chunk_row..]].concat();
        let message = text(&[short.as_bytes(), &body].concat());
        assert!(message.contains("chunk") && message.contains("at most 256 Gaussians"), "{message}");
        // No chunk element at all.
        let renamed = header.replace("element chunk", "element bounds");
        assert!(text(&[renamed.as_bytes(), &good[header_end..]].concat()).contains("no `chunk` element"));
        // A missing bound.
        let missing = header.replace("max_scale_z", "max_scale_w");
        assert!(text(&[missing.as_bytes(), &good[header_end..]].concat()).contains("max_scale_z"));
    }
}

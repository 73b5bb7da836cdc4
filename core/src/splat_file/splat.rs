//! antimatter15's `.splat` format, the one the original WebGL splat viewer streams: no header,
//! just 32-byte little-endian records of
//!
//! | bytes | content |
//! | --- | --- |
//! | 0..12 | position, 3 x f32 |
//! | 12..24 | scale, 3 x f32, linear (the exponential of the 3DGS log-scale) |
//! | 24..28 | color R, G, B and opacity A, 4 x u8, each value / 255 |
//! | 28..32 | rotation quaternion (w, x, y, z), 4 x u8, each `q * 128 + 128` clamped to 0..=255 |
//!
//! The converter that writes these files takes the INRIA PLY's axes unchanged, so no
//! coordinate conversion is needed. Only the base color survives (degree-0 SH), and color and
//! opacity are quantized to 1/255.

use super::SplatFileProblem;
use crate::gaussians::{Gaussians, SH_C0, rgb_to_sh_dc};

/// Size of one `.splat` record in bytes.
pub const SPLAT_RECORD_BYTES: usize = 32;

/// The smallest log-scale the reader returns. Writers store `exp(log_scale)`, which underflows
/// to 0 for a flattened axis, and some tools write 0 on purpose for flat splats; `ln(0)` would
/// be minus infinity. `exp(-30)` (about 1e-13) is invisible at any scene scale, and a finite
/// floor keeps later quantization of the log-scales well-conditioned.
pub const SPLAT_MIN_LOG_SCALE: f32 = -30.0;

/// Opacities are clamped into [`ALPHA_MIN`, `1 - ALPHA_MIN`] before the logit is taken, so that
/// the bytes 0 and 255 give finite logits (about -6.2 and 6.2). Half a quantization step moves
/// the opacity by no more than the 8-bit storage already did.
const ALPHA_MIN: f32 = 0.5 / 255.0;

/// Decodes `.splat` bytes into degree-0 Gaussians in the INRIA PLY convention: log-scale =
/// `ln(scale)` (floored at [`SPLAT_MIN_LOG_SCALE`]), opacity logit = `logit(A / 255)` with the
/// opacity clamped half a quantization step inside (0, 1), DC = the color's SH coefficient. A
/// rotation of four 128 bytes (the zero quaternion, which no rotation encodes to) becomes the
/// identity.
///
/// A length that is not a multiple of 32 is an error rather than a dropped partial record: it
/// means a truncated download or a file of another format. A non-finite position or scale, or
/// a negative scale, is an error naming the record, because no writer produces one and any
/// guess at the intended value would be arbitrary.
pub fn gaussians_from_splat_bytes(bytes: &[u8]) -> Result<Gaussians, SplatFileProblem> {
    let extra = bytes.len() % SPLAT_RECORD_BYTES;
    if extra != 0 {
        return Err(SplatFileProblem::SplatLength { len: bytes.len(), extra });
    }
    let count = bytes.len() / SPLAT_RECORD_BYTES;
    let mut g = Gaussians::with_degree(0);
    g.means.reserve_exact(count);
    g.log_scales.reserve_exact(count);
    g.rotations.reserve_exact(count);
    g.opacity_logits.reserve_exact(count);
    g.sh.reserve_exact(count * 3);
    for (record, r) in bytes.chunks_exact(SPLAT_RECORD_BYTES).enumerate() {
        let f32_at = |k: usize| f32::from_le_bytes([r[4 * k], r[4 * k + 1], r[4 * k + 2], r[4 * k + 3]]);
        let mean = [f32_at(0), f32_at(1), f32_at(2)];
        let scale = [f32_at(3), f32_at(4), f32_at(5)];
        if !mean.iter().all(|v| v.is_finite()) {
            return Err(SplatFileProblem::NonFinite { record, field: "position", values: mean.to_vec() });
        }
        if !scale.iter().all(|v| v.is_finite()) {
            return Err(SplatFileProblem::NonFinite { record, field: "scale", values: scale.to_vec() });
        }
        if scale.iter().any(|&s| s < 0.0) {
            return Err(SplatFileProblem::NegativeScale { record, values: scale });
        }
        let log_scale = scale.map(|s| s.ln().max(SPLAT_MIN_LOG_SCALE));
        let alpha = (r[27] as f32 / 255.0).clamp(ALPHA_MIN, 1.0 - ALPHA_MIN);
        let logit = (alpha / (1.0 - alpha)).ln();
        let q = [r[28], r[29], r[30], r[31]];
        let rotation = if q == [128; 4] { [1.0, 0.0, 0.0, 0.0] } else { q.map(|b| (b as f32 - 128.0) / 128.0) };
        let dc = [r[24], r[25], r[26]].map(|c| rgb_to_sh_dc(c as f32 / 255.0));
        g.push(mean, log_scale, rotation, logit, &dc);
    }
    Ok(g)
}

/// Encodes Gaussians as `.splat` records, in their order (the web viewer sorts on load, so
/// no importance order is needed). Only the DC term of the SH survives; the color is clamped
/// to [0, 1] and the quaternion normalized (a zero one written as the identity).
///
/// Panics if the Gaussians' arrays are inconsistent, like the PLY writer.
pub fn gaussians_to_splat_bytes(g: &Gaussians) -> Vec<u8> {
    assert!(g.is_consistent(), "Gaussian arrays have inconsistent lengths");
    let to_u8 = |v: f32| (v * 255.0).round().clamp(0.0, 255.0) as u8;
    let mut out = Vec::with_capacity(g.len() * SPLAT_RECORD_BYTES);
    for i in 0..g.len() {
        // The format stores linear scales in f32: a log-scale above ln(f32::MAX) (a reader may
        // return one where ln rounds down) is written as the largest finite scale.
        for v in g.means[i].iter().chain(&g.log_scales[i].map(|l| l.exp().min(f32::MAX))) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let sh = g.sh_of(i);
        out.extend((0..3).map(|c| to_u8(SH_C0 * sh[c] + 0.5)));
        out.push(to_u8(1.0 / (1.0 + (-g.opacity_logits[i]).exp())));
        let q = g.rotations[i];
        let norm = q.iter().map(|v| v * v).sum::<f32>().sqrt();
        let q = if norm > 0.0 { q.map(|v| v / norm) } else { [1.0, 0.0, 0.0, 0.0] };
        out.extend(q.map(|v| (v * 128.0 + 128.0).round().clamp(0.0, 255.0) as u8));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::{SplitMix64, random_gaussians};
    use crate::splat_file::tests::quaternion_gap;

    fn sigmoid(x: f32) -> f32 {
        1.0 / (1.0 + (-x).exp())
    }

    fn record(mean: [f32; 3], scale: [f32; 3], rgba: [u8; 4], rot: [u8; 4]) -> Vec<u8> {
        let mut r: Vec<u8> = mean.iter().chain(&scale).flat_map(|v| v.to_le_bytes()).collect();
        r.extend_from_slice(&rgba);
        r.extend_from_slice(&rot);
        r
    }

    /// The largest scale a record holds reads back to a log-scale whose `exp` rounds to
    /// infinity; written again, it is the largest finite scale, and reads again (a fuzz finding).
    #[test]
    fn the_largest_scale_writes_and_reads_again() {
        let file = record([0.0; 3], [f32::MAX, 1.0, 1.0], [128, 128, 128, 255], [255, 128, 128, 128]);
        let g = gaussians_from_splat_bytes(&file).unwrap();
        let again = gaussians_from_splat_bytes(&gaussians_to_splat_bytes(&g)).unwrap();
        assert_eq!(again.len(), 1);
        assert!(again.log_scales[0].iter().all(|v| v.is_finite()));
    }

    /// Tolerances: positions are stored as f32 (exact) and scales as `exp` in f32 (a relative
    /// error of a few ulps, so 1e-5 in log-scale); color and opacity are rounded to 1/255, so
    /// color is within 0.5/255 (DC within 0.5/255/SH_C0) and opacity within 0.5/255; each
    /// quaternion component is rounded to 1/256 (or clamped by up to 1/128 at +1), so the unit
    /// quaternion is within 2/128 after renormalization.
    #[test]
    fn round_trip_is_within_the_quantization() {
        let g = random_gaussians(&mut SplitMix64(11), 300, 0, [-5.0, 0.0]);
        let bytes = gaussians_to_splat_bytes(&g);
        assert_eq!(bytes.len(), 300 * SPLAT_RECORD_BYTES);
        let back = gaussians_from_splat_bytes(&bytes).unwrap();
        assert!(back.is_consistent() && back.len() == g.len() && back.sh_degree == 0);
        assert_eq!(back.means, g.means);
        for i in 0..g.len() {
            for c in 0..3 {
                assert!((back.log_scales[i][c] - g.log_scales[i][c]).abs() < 1e-5, "log-scale {i}");
                assert!((back.sh[i * 3 + c] - g.sh[i * 3 + c]).abs() <= 0.5 / 255.0 / SH_C0 + 1e-5, "color {i}");
            }
            let (a, b) = (sigmoid(back.opacity_logits[i]), sigmoid(g.opacity_logits[i]));
            assert!((a - b).abs() <= 0.5 / 255.0 + 1e-6, "opacity {i}: {a} vs {b}");
            let gap = quaternion_gap(back.rotations[i], g.rotations[i]);
            assert!(gap <= 2.0 / 128.0, "rotation {i}: {:?} vs {:?}", back.rotations[i], g.rotations[i]);
        }
    }

    #[test]
    fn a_hand_made_record_decodes_to_the_3dgs_parameters() {
        let bytes = record([1.0, -2.0, 3.5], [0.5, 1.0, 2.0], [255, 128, 0, 64], [255, 128, 1, 192]);
        let g = gaussians_from_splat_bytes(&bytes).unwrap();
        assert_eq!(g.means, [[1.0, -2.0, 3.5]]);
        assert_eq!(g.log_scales, [[0.5f32.ln(), 0.0, 2.0f32.ln()]]);
        assert_eq!(g.rotations, [[127.0 / 128.0, 0.0, -127.0 / 128.0, 0.5]]);
        assert!((sigmoid(g.opacity_logits[0]) - 64.0 / 255.0).abs() < 1e-6);
        let colors: Vec<f32> = g.sh.iter().map(|dc| SH_C0 * dc + 0.5).collect();
        assert!(colors.iter().zip([1.0, 128.0 / 255.0, 0.0]).all(|(a, b)| (a - b).abs() < 1e-6), "{colors:?}");
    }

    #[test]
    fn edge_values_stay_finite() {
        let mut bytes = record([0.0; 3], [0.0, 1e-40, 1.0], [0, 0, 0, 0], [128; 4]);
        bytes.extend(record([0.0; 3], [1.0; 3], [255; 4], [0; 4]));
        let g = gaussians_from_splat_bytes(&bytes).unwrap();
        assert_eq!(g.log_scales[0], [SPLAT_MIN_LOG_SCALE, SPLAT_MIN_LOG_SCALE, 0.0]);
        assert_eq!(g.rotations[0], [1.0, 0.0, 0.0, 0.0], "the zero quaternion becomes the identity");
        let expected = (ALPHA_MIN / (1.0 - ALPHA_MIN)).ln();
        assert!((g.opacity_logits[0] - expected).abs() < 1e-4 && (g.opacity_logits[1] + expected).abs() < 1e-4);
        assert!(g.opacity_logits[0] < -6.0 && g.opacity_logits[1] > 6.0);
        assert_eq!(g.rotations[1], [-1.0; 4]);
    }

    #[test]
    fn non_finite_and_negative_values_are_errors_naming_the_record() {
        let good = record([0.0; 3], [1.0; 3], [1; 4], [128; 4]);
        let cases = [
            (
                record([0.0, f32::NAN, 0.0], [1.0; 3], [1; 4], [128; 4]),
                "record 2: position [0.0, NaN, 0.0] is not finite",
            ),
            (
                record([0.0; 3], [1.0, f32::INFINITY, 1.0], [1; 4], [128; 4]),
                "record 2: scale [1.0, inf, 1.0] is not finite",
            ),
            (record([0.0; 3], [1.0, -0.5, 1.0], [1; 4], [128; 4]), "record 2: scale [1.0, -0.5, 1.0] is negative"),
        ];
        for (bad, message) in cases {
            let bytes = [good.clone(), good.clone(), bad].concat();
            let err = gaussians_from_splat_bytes(&bytes).unwrap_err().to_string();
            assert_eq!(err, message);
        }
    }

    #[test]
    fn every_truncation_is_an_error_or_whole_records() {
        let bytes = gaussians_to_splat_bytes(&random_gaussians(&mut SplitMix64(3), 4, 0, [-3.0, -1.0]));
        let full = gaussians_from_splat_bytes(&bytes).unwrap();
        for len in 0..bytes.len() {
            match gaussians_from_splat_bytes(&bytes[..len]) {
                Ok(g) => {
                    assert_eq!(len % SPLAT_RECORD_BYTES, 0, "{len} bytes were accepted");
                    assert_eq!(g.len(), len / SPLAT_RECORD_BYTES);
                    assert_eq!(g.means[..], full.means[..g.len()]);
                }
                Err(e) => {
                    assert!(
                        matches!(e, SplatFileProblem::SplatLength { extra, .. } if extra == len % 32),
                        "{len}: {e}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_writer_keeps_only_the_dc_term_and_normalizes() {
        let mut g = random_gaussians(&mut SplitMix64(5), 10, 3, [-3.0, -1.0]);
        g.rotations[0] = [0.0; 4];
        g.rotations[1] = [2.0, 0.0, 0.0, 0.0];
        let back = gaussians_from_splat_bytes(&gaussians_to_splat_bytes(&g)).unwrap();
        assert_eq!(back.sh_degree, 0);
        // The identity's w = 1 encodes as 256, clamped to 255.
        assert_eq!(back.rotations[0], [127.0 / 128.0, 0.0, 0.0, 0.0], "a zero quaternion is written as the identity");
        assert_eq!(back.rotations[1], [127.0 / 128.0, 0.0, 0.0, 0.0]);
        for i in 0..g.len() {
            for c in 0..3 {
                assert!((back.sh[i * 3 + c] - g.sh_of(i)[c]).abs() <= 0.5 / 255.0 / SH_C0 + 1e-5);
            }
        }
    }
}

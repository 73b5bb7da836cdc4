//! The common randomness of the perceptual wrapper (SPEC.md section 11.1): a pyramid of
//! i.i.d. standard-normal grids C_0..C_7, C_i of ceil(H/2^i) x ceil(W/2^i), each upsampled
//! bilinearly to H x W. Encoder and decoder regenerate it from the stream's seed, so it costs
//! no bits; it is normative, bit for bit, which is why nothing here calls a platform math
//! function: samples come from a counter-based generator (every sample is a pure function of
//! seed, level and position, so any thread may compute any sample) mapped through a fixed
//! table, and the upsampling uses only `+ - * /` and `floor` in binary64 in a fixed order.

use crate::hashing::Hasher;
use rayon::prelude::*;

use pwgs_core::random::splitmix64_at;

use super::normal_table::POSITIVE_QUANTILES;

/// Pyramid levels (C_0 .. C_7).
pub const NOISE_LEVELS: usize = 8;

/// The standard-normal value of a 64-bit random word: its top 12 bits select one of 4096
/// equiprobable quantiles, the negative half mirroring the positive one exactly.
pub fn standard_normal(word: u64) -> f32 {
    let k = (word >> 52) as usize;
    if k >= 2048 { f32::from_bits(POSITIVE_QUANTILES[k - 2048]) } else { -f32::from_bits(POSITIVE_QUANTILES[2047 - k]) }
}

/// Sample (x, y) of grid C_level: output number `level * 2^48 + y * 2^24 + x` of SplitMix64
/// started at `seed`, mapped by [`standard_normal`]. Sides are below 2^24.
pub fn grid_sample(seed: u64, level: usize, x: usize, y: usize) -> f32 {
    let counter = ((level as u64) << 48) | ((y as u64) << 24) | x as u64;
    standard_normal(splitmix64_at(seed, counter))
}

/// Size of grid C_level for an image of `width` x `height`: (ceil(W / 2^i), ceil(H / 2^i)).
pub fn grid_size(width: usize, height: usize, level: usize) -> (usize, usize) {
    (width.div_ceil(1 << level), height.div_ceil(1 << level))
}

/// Where output pixel `i` of `out` samples an input of `input` samples (half-pixel centers,
/// clamped to the edge): the two source indices and the weight of the second.
fn source(i: usize, input: usize, out: usize) -> (usize, usize, f64) {
    // ((i + 0.5) * input / out - 0.5): the numerator and denominator are exact integers in
    // binary64, so the division is the only rounding.
    let s = ((2 * i + 1) * input) as f64 / (2 * out) as f64 - 0.5;
    let s = s.clamp(0.0, (input - 1) as f64);
    let i0 = s.floor() as usize;
    (i0, (i0 + 1).min(input - 1), s - i0 as f64)
}

/// The grids C_0..C_7 of one image size and seed, from which any row of the upsampled pyramid
/// can be produced on its own (so a decoder never needs the whole pyramid in memory).
#[derive(Debug, Clone)]
pub struct NoiseGrids {
    width: usize,
    height: usize,
    /// Per level: (grid width, grid height, samples row by row).
    grids: Vec<(usize, usize, Vec<f64>)>,
}

impl NoiseGrids {
    /// Draws the grids for a `width` x `height` image. The sample index of SPEC.md 11.1 needs
    /// sides below 2^24; a [`Camera`](pwgs_core::camera::Camera) is at most
    /// [`MAX_SIDE`](pwgs_core::camera::MAX_SIDE) wide, so views never come near it and the assertion
    /// only guards direct callers.
    pub fn new(seed: u64, width: usize, height: usize) -> Self {
        assert!(width > 0 && height > 0 && width < 1 << 24 && height < 1 << 24, "noise pyramid size");
        let grids = (0..NOISE_LEVELS)
            .map(|level| {
                let (w, h) = grid_size(width, height, level);
                let values =
                    (0..w * h).into_par_iter().map(|p| f64::from(grid_sample(seed, level, p % w, p / w))).collect();
                (w, h, values)
            })
            .collect();
        Self { width, height, grids }
    }

    /// Row `y` of the upsampled pyramid into `row` (`width * 8` values, pixel-interleaved).
    /// Binary64 arithmetic, rounded to binary32 at the end:
    /// `((1 - fy) * ((1 - fx) * c00 + fx * c01) + fy * ((1 - fx) * c10 + fx * c11))`.
    pub fn row(&self, y: usize, row: &mut [f32]) {
        assert_eq!(row.len(), self.width * NOISE_LEVELS, "noise row length");
        for (level, (w, h, values)) in self.grids.iter().enumerate() {
            let (y0, y1, fy) = source(y, *h, self.height);
            for x in 0..self.width {
                let (x0, x1, fx) = source(x, *w, self.width);
                let top = (1.0 - fx) * values[y0 * w + x0] + fx * values[y0 * w + x1];
                let bottom = (1.0 - fx) * values[y1 * w + x0] + fx * values[y1 * w + x1];
                row[x * NOISE_LEVELS + level] = ((1.0 - fy) * top + fy * bottom) as f32;
            }
        }
    }
}

/// The upsampled pyramid for a `width` x `height` image, pixel-interleaved: value
/// `(y * width + x) * 8 + level` (see [`NoiseGrids::row`]).
pub fn noise_pyramid(seed: u64, width: usize, height: usize) -> Vec<f32> {
    let grids = NoiseGrids::new(seed, width, height);
    let mut out = vec![0.0f32; width * height * NOISE_LEVELS];
    out.par_chunks_mut(width * NOISE_LEVELS).enumerate().for_each(|(y, row)| grids.row(y, row));
    out
}

/// SHA-256 (hex) of a pyramid's values as little-endian binary32, in [`noise_pyramid`] order.
pub fn pyramid_sha256(values: &[f32]) -> String {
    let mut h = Hasher::default();
    h.floats(values);
    h.hex()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Φ(t) - 1/2 for sorted t ≥ 0, by composite Simpson integration of the density in
    /// binary64 (error far below the tolerance used).
    fn half_cdf_sorted(ts: &[f64]) -> Vec<f64> {
        let density = |t: f64| (-0.5 * t * t).exp() / (2.0 * std::f64::consts::PI).sqrt();
        let mut acc = 0.0;
        let mut at = 0.0;
        ts.iter()
            .map(|&t| {
                // Simpson's rule needs an even number of steps.
                let steps = ((((t - at) / 1e-4).ceil() as usize).max(1) + 1) & !1;
                let h = (t - at) / steps as f64;
                let mut sum = density(at) + density(t);
                for i in 1..steps {
                    sum += density(at + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
                }
                acc += sum * h / 3.0;
                at = t;
                acc
            })
            .collect()
    }

    #[test]
    fn normal_table_is_the_quantile_function() {
        let values: Vec<f64> = POSITIVE_QUANTILES.iter().map(|&b| f64::from(f32::from_bits(b))).collect();
        assert!(values.windows(2).all(|w| w[0] < w[1]), "the table must increase");
        let cdf = half_cdf_sorted(&values);
        for (k, (&t, &c)) in values.iter().zip(&cdf).enumerate() {
            let wanted = (2048.0 + k as f64 + 0.5) / 4096.0 - 0.5;
            // Within one binary32 step of the true quantile: |Φ(t) - p| <= density(t) * ulp(t).
            let ulp = f64::from(f32::from_bits(f32::to_bits(t as f32) + 1)) - t;
            let density = (-0.5 * t * t).exp() / (2.0 * std::f64::consts::PI).sqrt();
            assert!((c - wanted).abs() <= density * ulp, "entry {k}: {t} has Φ - 1/2 = {c}, wanted {wanted}");
        }
        let bytes: Vec<f32> = values.iter().map(|&v| v as f32).collect();
        assert_eq!(pyramid_sha256(&bytes), "b16a47a034479c8425d918a7876cf47c38ab290a9a9d3f2f2a79e98cea1b7632");
    }

    #[test]
    fn samples_are_standard_normal() {
        let n = 200_000;
        let samples: Vec<f64> = (0..n).map(|i| f64::from(grid_sample(7, 0, i % 1000, i / 1000))).collect();
        let mean = samples.iter().sum::<f64>() / n as f64;
        let var = samples.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.01, "variance {var}");
        let beyond_2 = samples.iter().filter(|v| v.abs() > 2.0).count() as f64 / n as f64;
        assert!((beyond_2 - 0.0455).abs() < 0.003, "P(|z| > 2) = {beyond_2}");
    }

    #[test]
    fn mirror_halves_are_exact() {
        for k in 0..4096u64 {
            assert_eq!(standard_normal(k << 52), -standard_normal((4095 - k) << 52));
        }
    }

    #[test]
    fn level_zero_is_the_grid_itself_and_coarse_levels_interpolate() {
        let (w, h) = (37, 23);
        let p = noise_pyramid(5, w, h);
        for y in 0..h {
            for x in 0..w {
                assert_eq!(p[(y * w + x) * NOISE_LEVELS], grid_sample(5, 0, x, y));
            }
        }
        // Level 7 of a 37 x 23 image is a single sample: constant everywhere.
        assert!(p.chunks_exact(NOISE_LEVELS).all(|px| px[7] == grid_sample(5, 7, 0, 0)));
        // Level 1 at output (1, 1) sits at source (0.25, 0.25) of a 19 x 12 grid ((1.5 * 19 / 37) - 0.5).
        let sx = 3.0 * 19.0 / 74.0 - 0.5;
        let sy = 3.0 * 12.0 / 46.0 - 0.5;
        let g = |x, y| f64::from(grid_sample(5, 1, x, y));
        let want = (1.0 - sy) * ((1.0 - sx) * g(0, 0) + sx * g(1, 0)) + sy * ((1.0 - sx) * g(0, 1) + sx * g(1, 1));
        assert_eq!(p[(w + 1) * NOISE_LEVELS + 1], want as f32);
        // The first pixel is clamped onto the first sample of every grid.
        for level in 0..NOISE_LEVELS {
            assert_eq!(p[level], grid_sample(5, level, 0, 0));
        }
    }

    #[test]
    fn different_seeds_and_levels_differ() {
        let a = noise_pyramid(1, 16, 16);
        let b = noise_pyramid(2, 16, 16);
        assert_ne!(a, b);
        assert_ne!(grid_sample(1, 0, 0, 0), grid_sample(1, 1, 0, 0));
    }
}

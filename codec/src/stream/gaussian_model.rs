//! Parametric probability models (SPEC.md section 5.4): a quantized Gaussian given by a mean
//! and a scale on normative grids, turned into a [`FrequencyTable`] by a construction that uses
//! only IEEE `+ - * /` and the portable `exp`, so that every decoder builds the same table.
//!
//! The stream carries three bytes or so per model instead of a whole frequency table, and the
//! model has the form of the training-time rate estimate (a factorized Gaussian), so the rate
//! the encoder trains against is the one the stream pays.

use pwgs_bitstream::{FieldError, FieldReader, FieldWriter};

use super::entropy::{FrequencyTable, MAX_TABLE_SYMBOLS, TOTAL};
use crate::portable_math::exp_f64;

/// Means are multiples of 1/64 of the quantization unit.
pub const MEAN_DENOMINATOR: i32 = 64;
/// Largest mean magnitude, in 64ths: means stay within ±2^23 units.
pub const MAX_MEAN: i32 = 1 << 29;
/// Scale index `j` gives `sigma = 2^((j - SCALE_OFFSET) / 8)` units: 2^-12 to about 2^19.9.
pub const SCALE_OFFSET: i32 = 96;
/// Half-width of the table window, in scales (beyond it values are escaped).
const WINDOW_SCALES: f64 = 8.0;

// Abramowitz & Stegun 7.1.26: erfc(x) ≈ (a1 t + ... + a5 t^5) exp(-x^2), t = 1 / (1 + p x),
// x >= 0, absolute error below 1.5e-7.
const AS_P: f64 = 0.327_591_1;
const AS_A: [f64; 5] = [1.061_405_429, -1.453_152_027, 1.421_413_741, -0.284_496_736, 0.254_829_592];
const FRAC_1_SQRT_2: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// ln(2) / 8, nearest binary64.
const LN2_EIGHTH: f64 = 0.086_643_397_569_993_16;

/// A quantized Gaussian over the integers: mean `mean / 64`, scale index `scale`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct GaussianModel {
    pub mean: i32,
    pub scale: u8,
}

/// The normative standard normal CDF: `0.5 erfc(-z / sqrt 2)` with A&S 7.1.26's erfc, clamped
/// to [0, 1].
pub fn normal_cdf(z: f64) -> f64 {
    let x = if z < 0.0 { -z } else { z } * FRAC_1_SQRT_2;
    let t = 1.0 / (1.0 + AS_P * x);
    let poly = AS_A.iter().fold(0.0, |acc, &a| acc * t + a) * t;
    let tail = 0.5 * (poly * exp_f64(-(x * x)));
    let cdf = if z < 0.0 { tail } else { 1.0 - tail };
    cdf.clamp(0.0, 1.0)
}

impl GaussianModel {
    /// The scale in quantization units.
    pub fn sigma(self) -> f64 {
        exp_f64(f64::from(i32::from(self.scale) - SCALE_OFFSET) * LN2_EIGHTH)
    }

    pub fn mean_units(self) -> f64 {
        f64::from(self.mean) / f64::from(MEAN_DENOMINATOR)
    }

    /// The table: integers `lo .. lo + n` around the mean's nearest integer, `n = 2 h + 1`
    /// with `h = min(ceil(8 sigma), 2047)`; each symbol gets `floor(P * (2^16 - n - 1)) + 1`,
    /// `P` the mass of its unit bin under the clamped-monotone CDF, and the escape the rest.
    pub fn table(self) -> FrequencyTable {
        let (mu, sigma) = (self.mean_units(), self.sigma());
        let half = Self::half_window(sigma);
        let center = (mu + 0.5).floor() as i64;
        let lo = center - half;
        let n = (2 * half + 1) as usize;
        let spare = f64::from(TOTAL - n as u32 - 1);
        let mut previous = normal_cdf((lo as f64 - 0.5 - mu) / sigma);
        let mut frequencies = Vec::with_capacity(n + 1);
        for s in 0..n as i64 {
            let upper = normal_cdf(((lo + s) as f64 + 0.5 - mu) / sigma).max(previous);
            frequencies.push(((upper - previous) * spare).floor() as u32 + 1);
            previous = upper;
        }
        let used: u32 = frequencies.iter().sum();
        frequencies.push(TOTAL - used);
        FrequencyTable::from_frequencies(lo as i32, &frequencies).expect("the construction gives a valid table")
    }

    /// The table's in-range symbols, `n = 2 h + 1` (as [`Self::table`] builds it), without
    /// building it: what a decoder counts against a bound on the tables it builds.
    pub fn table_symbols(self) -> u32 {
        2 * Self::half_window(self.sigma()) as u32 + 1
    }

    /// `h = min(ceil(8 sigma), 2047)`.
    fn half_window(sigma: f64) -> i64 {
        let half_max = (MAX_TABLE_SYMBOLS as i64 - 1) / 2;
        ((WINDOW_SCALES * sigma).ceil() as i64).clamp(0, half_max)
    }

    /// Syntax: mean (signed varint, 64ths), scale (u8).
    pub fn write(self, w: &mut FieldWriter) {
        w.signed_varint(self.mean);
        w.u8(self.scale);
    }

    pub fn read(r: &mut FieldReader) -> Result<Self, FieldError> {
        let mean = r.signed_varint("model mean")?;
        if mean.unsigned_abs() > MAX_MEAN as u32 {
            return Err(r.error("model mean", format!("{mean} exceeds ±{MAX_MEAN}")));
        }
        Ok(Self { mean, scale: r.u8("model scale")? })
    }

    /// The model an encoder uses for `values` (not normative): the mean snapped from the
    /// values' mean, and of the scales near their spread, the one that codes them in the fewest
    /// bits.
    pub fn fit(values: &[i32]) -> Self {
        if values.is_empty() {
            return Self { mean: 0, scale: 0 };
        }
        let count = values.len() as f64;
        let average = values.iter().map(|&v| f64::from(v)).sum::<f64>() / count;
        let variance = values.iter().map(|&v| (f64::from(v) - average) * (f64::from(v) - average)).sum::<f64>() / count;
        let mean = ((average * f64::from(MEAN_DENOMINATOR)).round() as i64).clamp(-(MAX_MEAN as i64), MAX_MEAN as i64);
        // The scales tried around this guess are costed exactly; the guess only narrows them.
        #[expect(clippy::disallowed_methods, reason = "the encoder's guess, not normative")]
        let guess = (variance.sqrt().max(1e-6).log2() * 8.0).round() as i32 + SCALE_OFFSET;
        let candidates = (guess - 8..=guess + 8).filter_map(|j| u8::try_from(j).ok());
        candidates
            .map(|scale| Self { mean: mean as i32, scale })
            .min_by(|a, b| a.cost_bits(values).total_cmp(&b.cost_bits(values)))
            .unwrap_or(Self { mean: mean as i32, scale: 0 })
    }

    /// Bits `values` cost under this model (escapes included).
    pub fn cost_bits(self, values: &[i32]) -> f64 {
        let table = self.table();
        values.iter().map(|&v| table.cost_bits(v)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cdf_is_close_to_the_true_normal_cdf() {
        // Φ at a few points (true values to 9 digits).
        for (z, expected) in [(0.0, 0.5), (1.0, 0.841344746), (-1.0, 0.158655254), (2.5, 0.993790335), (-4.0, 3.167e-5)]
        {
            assert!((normal_cdf(z) - expected).abs() < 2e-7, "Φ({z}) = {}", normal_cdf(z));
        }
        assert_eq!(normal_cdf(-40.0), 0.0);
        assert_eq!(normal_cdf(40.0), 1.0);
    }

    #[test]
    fn tables_follow_the_gaussian_and_stay_valid_at_the_extremes() {
        // σ = 2^((104 - 96) / 8) = 2, mean 0.5: symbols 0 and 1 are equally likely.
        let model = GaussianModel { mean: 32, scale: 104 };
        assert!((model.sigma() - 2.0).abs() < 1e-12);
        let table = model.table();
        assert!((table.cost_bits(0) - table.cost_bits(1)).abs() < 1e-3);
        // The bin [-0.5, 0.5) under N(0.5, 2) holds Φ(-0.5) - Φ(-0.25)... of (0, 1) symmetric ones.
        let p0 = normal_cdf(0.0) - normal_cdf(-0.5);
        assert!((table.cost_bits(0) + p0.log2()).abs() < 0.01, "{} vs {}", table.cost_bits(0), -p0.log2());
        // Tiny, huge and far-off models all give valid tables.
        for model in [
            GaussianModel { mean: 0, scale: 0 },
            GaussianModel { mean: -MAX_MEAN, scale: 255 },
            GaussianModel { mean: MAX_MEAN, scale: 0 },
        ] {
            let t = model.table();
            assert!(t.symbols() >= 1 && t.symbols() <= MAX_TABLE_SYMBOLS);
        }
        assert!(GaussianModel { mean: 0, scale: 0 }.table().cost_bits(0) < 0.001);
    }

    #[test]
    fn the_symbol_count_is_that_of_the_table() {
        for scale in 0..=255 {
            for mean in [-65, 0, 31, 63] {
                let model = GaussianModel { mean, scale };
                assert_eq!(model.table_symbols(), model.table().symbols(), "{model:?}");
            }
        }
        assert_eq!(GaussianModel { mean: 0, scale: 0 }.table_symbols(), 3);
        assert_eq!(GaussianModel { mean: 0, scale: 255 }.table_symbols(), MAX_TABLE_SYMBOLS - 1);
    }

    #[test]
    fn fitting_finds_the_spread_of_the_values() {
        // Roughly N(3, 4^2): 12 uniforms summed, rounded.
        let mut rng = pwgs_core::random::SplitMix64(5);
        let values: Vec<i32> = (0..20_000)
            .map(|_| ((0..12).map(|_| rng.uniform(-0.5, 0.5)).sum::<f32>() * 4.0 + 3.0).round() as i32)
            .collect();
        let model = GaussianModel::fit(&values);
        assert!((model.mean_units() - 3.0).abs() < 0.1 && (3.6..4.4).contains(&model.sigma()), "{model:?}");
        // Within 0.05 bits of the values' empirical entropy.
        let mut counts = std::collections::HashMap::new();
        values.iter().for_each(|v| *counts.entry(v).or_insert(0usize) += 1);
        let n = values.len() as f64;
        let entropy: f64 = counts.values().map(|&c| -(c as f64 / n) * (c as f64 / n).log2()).sum();
        let bits = model.cost_bits(&values) / n;
        assert!(bits < entropy + 0.05, "{bits} bits per value, entropy {entropy}");
        assert!(GaussianModel::fit(&[5; 10]).table().cost_bits(5) < 0.01);
    }

    #[test]
    fn models_round_trip_and_refuse_large_means() {
        let model = GaussianModel { mean: -1234, scale: 77 };
        let mut w = FieldWriter::new();
        model.write(&mut w);
        let bytes = w.into_bytes();
        assert_eq!(GaussianModel::read(&mut FieldReader::new("T", &bytes)).unwrap(), model);
        let mut w = FieldWriter::new();
        w.signed_varint(MAX_MEAN + 1);
        w.u8(0);
        let bytes = w.into_bytes();
        let err = GaussianModel::read(&mut FieldReader::new("T", &bytes)).unwrap_err().to_string();
        assert!(err.contains("model mean"), "{err}");
    }
}

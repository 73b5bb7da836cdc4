//! The `WRAP` section (SPEC.md section 11.4): the perceptual wrapper's configuration, the noise
//! seed and the synthesis network's weights, quantized to power-of-two steps (one for weights,
//! one for biases) and written as signed varints. Dequantization is exact in binary32, so the
//! encoder can evaluate with precisely the weights every decoder will use.

use pwgs_bitstream::{FieldError, FieldReader, FieldWriter, MINOR_VERSION, Tag};

use crate::wrapper::synthesis::{RESIDUAL_TAPS, SynthesisWeights, WrapperConfig};

pub const WRAPPER: Tag = Tag(*b"WRAP");

/// Widest hidden layer a stream may declare.
pub const MAX_WIDTH: usize = 64;

/// Range of the step exponents: steps 2^-30 .. 2^0.
pub const MIN_EXPONENT: i8 = -30;
pub const MAX_EXPONENT: i8 = 0;

/// Quantized values stay below 2^24 in magnitude, so `q * step` is exact in binary32.
pub const MAX_QUANTIZED: i32 = (1 << 24) - 1;

/// The activation of the hidden layer; the only one defined is ReLU (code 0).
const RELU: u8 = 0;

const NOISE_FLAG: u8 = 1;
const PLUCKER_FLAG: u8 = 2;

/// f's weights as the stream holds them.
#[derive(Debug, Clone, PartialEq)]
pub struct QuantizedSynthesis {
    pub config: WrapperConfig,
    /// Step of the convolution weights: 2^weight_exponent.
    pub weight_exponent: i8,
    /// Step of the biases: 2^bias_exponent.
    pub bias_exponent: i8,
    /// Every parameter in [`SynthesisWeights::values`] order.
    pub values: Vec<i32>,
}

/// 2^e as binary32, built from its bits (no `powf`).
pub fn power_of_two(e: i8) -> f32 {
    assert!((MIN_EXPONENT..=MAX_EXPONENT).contains(&e), "step exponent {e} out of range");
    f32::from_bits(((127 + i32::from(e)) as u32) << 23)
}

/// `v` rounded to the nearest multiple of `step`, as an integer within the quantized range.
pub fn quantize_to_step(v: f32, step: f32) -> i32 {
    (v / step).round().clamp(-MAX_QUANTIZED as f32, MAX_QUANTIZED as f32) as i32
}

/// For every parameter in stream order, whether it is a bias.
fn bias_mask(config: &WrapperConfig) -> Vec<bool> {
    let (w, cin) = (config.width, config.input_channels());
    let mut mask = Vec::with_capacity(config.parameter_count());
    for (count, bias) in [(w * cin, false), (w, true), (3 * w, false), (3, true)] {
        mask.extend(std::iter::repeat_n(bias, count));
    }
    for _ in 0..2 {
        mask.extend(std::iter::repeat_n(false, RESIDUAL_TAPS));
        mask.extend(std::iter::repeat_n(true, 3));
    }
    mask
}

impl QuantizedSynthesis {
    /// Rounds every parameter to the nearest multiple of its step (clamped to the quantized
    /// range).
    pub fn quantize(weights: &SynthesisWeights, weight_exponent: i8, bias_exponent: i8) -> Self {
        let (weight_step, bias_step) = (power_of_two(weight_exponent), power_of_two(bias_exponent));
        let values = weights
            .values()
            .iter()
            .zip(bias_mask(&weights.config))
            .map(|(&v, bias)| quantize_to_step(v, if bias { bias_step } else { weight_step }))
            .collect();
        Self { config: weights.config, weight_exponent, bias_exponent, values }
    }

    /// Normative reconstruction: `q * 2^exponent` in binary32 (exact).
    pub fn dequantize(&self) -> SynthesisWeights {
        let (weight_step, bias_step) = (power_of_two(self.weight_exponent), power_of_two(self.bias_exponent));
        let values: Vec<f32> = self
            .values
            .iter()
            .zip(bias_mask(&self.config))
            .map(|(&q, bias)| q as f32 * if bias { bias_step } else { weight_step })
            .collect();
        SynthesisWeights::from_values(self.config, &values)
    }

    pub fn write(&self) -> Vec<u8> {
        let c = &self.config;
        let mut w = FieldWriter::new();
        w.u8(RELU);
        w.u8(c.width as u8);
        w.u8(if c.noise { NOISE_FLAG } else { 0 } | if c.plucker { PLUCKER_FLAG } else { 0 });
        w.u64(c.seed);
        w.u8(self.weight_exponent as u8);
        w.u8(self.bias_exponent as u8);
        self.values.iter().for_each(|&q| w.signed_varint(q));
        w.into_bytes()
    }

    /// Reads the section; fields appended by a newer minor version are skipped.
    pub fn read(payload: &[u8], minor: u16) -> Result<Self, FieldError> {
        let mut r = FieldReader::new("WRAP", payload);
        let activation = r.u8("activation")?;
        if activation != RELU {
            return Err(r.error("activation", format!("unknown activation {activation}")));
        }
        let width = usize::from(r.u8("width")?);
        if !(1..=MAX_WIDTH).contains(&width) {
            return Err(r.error("width", format!("{width} is outside 1..={MAX_WIDTH}")));
        }
        let inputs = r.u8("inputs")?;
        if inputs & !(NOISE_FLAG | PLUCKER_FLAG) != 0 {
            return Err(r.error("inputs", format!("unknown input flags {inputs:#04x}")));
        }
        let seed = r.u64("seed")?;
        let mut exponent = |field| -> Result<i8, FieldError> {
            let e = r.u8(field)? as i8;
            if !(MIN_EXPONENT..=MAX_EXPONENT).contains(&e) {
                return Err(r.error(field, format!("{e} is outside {MIN_EXPONENT}..={MAX_EXPONENT}")));
            }
            Ok(e)
        };
        let weight_exponent = exponent("weight step exponent")?;
        let bias_exponent = exponent("bias step exponent")?;
        let config =
            WrapperConfig { width, noise: inputs & NOISE_FLAG != 0, plucker: inputs & PLUCKER_FLAG != 0, seed };
        let mut values = Vec::with_capacity(config.parameter_count());
        for _ in 0..config.parameter_count() {
            let q = r.signed_varint("parameter")?;
            if q.unsigned_abs() > MAX_QUANTIZED as u32 {
                return Err(r.error("parameter", format!("{q} exceeds the magnitude limit {MAX_QUANTIZED}")));
            }
            values.push(q);
        }
        r.finish(minor > MINOR_VERSION)?;
        Ok(Self { config, weight_exponent, bias_exponent, values })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pwgs_core::random::SplitMix64;

    fn sample() -> SynthesisWeights {
        let config = WrapperConfig { width: 6, noise: true, plucker: false, seed: 0xDEAD_BEEF_0123_4567 };
        let mut rng = SplitMix64(1);
        let values: Vec<f32> = (0..config.parameter_count()).map(|_| rng.uniform(-0.3, 0.3)).collect();
        SynthesisWeights::from_values(config, &values)
    }

    #[test]
    fn round_trip_and_exact_dequantization() {
        let w = sample();
        let q = QuantizedSynthesis::quantize(&w, -10, -14);
        let back = QuantizedSynthesis::read(&q.write(), MINOR_VERSION).unwrap();
        assert_eq!(back, q);
        let d = q.dequantize();
        for ((a, b), bias) in d.values().iter().zip(w.values()).zip(bias_mask(&w.config)) {
            let step = if bias { 2f32.powi(-14) } else { 2f32.powi(-10) };
            assert!((a - b).abs() <= step / 2.0 + 1e-9, "{a} vs {b}");
            assert_eq!(a / step, (a / step).round(), "a multiple of the step");
        }
    }

    #[test]
    fn powers_of_two_are_exact() {
        for e in MIN_EXPONENT..=MAX_EXPONENT {
            assert_eq!(power_of_two(e), 2f32.powi(i32::from(e)));
        }
    }

    #[test]
    fn malformed_sections_are_refused_with_the_field_named() {
        let good = QuantizedSynthesis::quantize(&sample(), -8, -8).write();
        let mut bad_activation = good.clone();
        bad_activation[0] = 1;
        let mut zero_width = good.clone();
        zero_width[1] = 0;
        let mut flags = good.clone();
        flags[2] = 4;
        let mut exponent = good.clone();
        exponent[11] = 5;
        for (bytes, field) in [
            (bad_activation, "activation"),
            (zero_width, "width"),
            (flags, "inputs"),
            (exponent, "weight step exponent"),
            (good[..good.len() - 1].to_vec(), "parameter"),
        ] {
            let e = QuantizedSynthesis::read(&bytes, MINOR_VERSION).unwrap_err();
            assert!(e.to_string().contains(field), "{e} should name {field}");
        }
        let mut trailing = good.clone();
        trailing.push(0);
        assert!(QuantizedSynthesis::read(&trailing, MINOR_VERSION).is_err());
    }
}

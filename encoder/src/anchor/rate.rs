//! The rate term of anchor training: the bits an anchor's quantized attributes cost under a
//! factorized Gaussian model (one learned mean and scale per channel), the training-time
//! estimate of what the stream's per-channel tables code (HAC's entropy model without its
//! hash-grid context).
//!
//! A value x with quantization step Δ, seen with uniform noise as x̃, costs
//! `-log2(Φ((x̃ + Δ/2 - μ) / σ) - Φ((x̃ - Δ/2 - μ) / σ))` bits, floored at 2^-30 probability
//! so that a far outlier's gradient stays finite. This is an estimate for training only: the
//! stream's tables are fitted to the rounded values and never evaluate Φ.

use burn::tensor::Tensor;

/// Smallest probability a quantization bin is given (≈ 30 bits).
const MIN_PROBABILITY: f32 = 9.3e-10;

/// Smallest scale σ, as a fraction of the step: below it one bin holds all the mass anyway.
const MIN_SCALE_STEPS: f32 = 0.05;

/// Bits of each element of `x` (rows of values; `mean` and `log_scale` are [1, C], one per
/// column, or one per element) quantized with `step` ([1, 1]: a learned step passes its
/// gradient).
pub fn factorized_bits(x: Tensor<2>, mean: Tensor<2>, log_scale: Tensor<2>, step: Tensor<2>) -> Tensor<2> {
    // max(σ, floor), with the [1, 1] floor broadcast.
    let floor = step.clone() * MIN_SCALE_STEPS;
    let scale = (log_scale.exp() - floor.clone()).clamp_min(0.0) + floor;
    let centered = x - mean;
    let cdf = |t: Tensor<2>| ((t / (scale.clone() * std::f32::consts::SQRT_2)).erf() + 1.0) * 0.5;
    let half = step / 2.0;
    let upper = cdf(centered.clone() + half.clone());
    let lower = cdf(centered - half);
    (upper - lower).clamp_min(MIN_PROBABILITY).log() * (-std::f32::consts::LOG2_E)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Device, TensorData};

    use crate::train::params::tensor_values as values;

    fn tensor(values: &[f32], shape: [usize; 2]) -> Tensor<2> {
        Tensor::from_data(TensorData::new(values.to_vec(), shape), &Device::flex())
    }

    #[test]
    fn bits_follow_the_quantized_gaussian() {
        // σ = 1, Δ = 1: the bin at the mean holds erf(0.5/√2) = 0.38292 of the mass (1.385 bits),
        // the bin at 3 holds Φ(3.5) - Φ(2.5) = 0.0059765 (7.386 bits).
        let x = tensor(&[0.0, 3.0, -3.0], [1, 3]);
        let one = || tensor(&[1.0], [1, 1]);
        let bits = values(factorized_bits(x, tensor(&[0.0; 3], [1, 3]), tensor(&[0.0; 3], [1, 3]), one()));
        for (b, expected) in bits.iter().zip([1.3849, 7.3864, 7.3864]) {
            assert!((b - expected).abs() < 2e-3, "{b} vs {expected}");
        }
        // A narrow model puts the whole mass in the mean's bin (≈ 0 bits), and a far value hits
        // the floor rather than infinity.
        let x = tensor(&[2.0, 400.0], [1, 2]);
        let narrow = values(factorized_bits(x, tensor(&[2.0, 0.0], [1, 2]), tensor(&[-5.0, -5.0], [1, 2]), one()));
        assert!(narrow[0] < 1e-3, "{}", narrow[0]);
        assert!((narrow[1] - 30.0).abs() < 0.1, "{}", narrow[1]);
    }

    #[test]
    fn the_rate_gradient_pulls_values_toward_the_mean() {
        let x = tensor(&[1.5, -2.0], [1, 2]).autodiff().require_grad();
        let step = tensor(&[0.5], [1, 1]).autodiff().require_grad();
        let bits = factorized_bits(x.clone(), tensor(&[0.0; 2], [1, 2]), tensor(&[0.0; 2], [1, 2]), step.clone()).sum();
        let grads = bits.backward();
        let g = values(x.grad(&grads).unwrap());
        assert!(g[0] > 0.0 && g[1] < 0.0, "{g:?}");
        // A larger step costs fewer bits.
        assert!(values(step.grad(&grads).unwrap())[0] < 0.0);
    }
}

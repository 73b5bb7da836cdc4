//! The perceptual wrapper's synthesis network f on Burn, for training. The parameters live in
//! one flat tensor in the stream's order ([`SynthesisWeights::values`]), so one Adam state
//! covers them and the host copy is the decoder's own weight type; the decoder's plain-Rust
//! evaluation is the reference this forward pass is tested against.
//!
//! Choosing the quantization steps is also here: the encoder evaluates exactly the weights the
//! stream will hold.
#![cfg_attr(not(test), deny(clippy::disallowed_methods))] // the determinism rule: no platform math (clippy.toml)

use burn::tensor::activation::relu;
use burn::tensor::module::conv2d;
use burn::tensor::ops::{ConvOptions, PadMode};
use burn::tensor::{Device, Tensor, TensorData, s};
use pwgs_codec::stream::wrap::{MAX_EXPONENT, MIN_EXPONENT, QuantizedSynthesis};
use pwgs_codec::wrapper::synthesis::{RESIDUAL_TAPS, SynthesisWeights, WrapperConfig};
use pwgs_core::random::SplitMix64;

use crate::train::params::tensor_values;

/// The initial parameters: the first layer uniform in ±1/sqrt(fan-in) (from `rng`), everything
/// after it zero, so f starts at R = 0 and the wrapper begins as the identity.
pub fn initial_parameters(config: &WrapperConfig, rng: &mut SplitMix64) -> Vec<f32> {
    let cin = config.input_channels();
    let bound = 1.0 / (cin as f32).sqrt();
    let mut values = vec![0.0; config.parameter_count()];
    for v in &mut values[..config.width * cin] {
        *v = rng.uniform(-bound, bound);
    }
    values
}

/// The residual R [1, 3, H, W] of f with the flat parameters `flat` on `input` [H * W, C_in]
/// (pixel-major rows: base RGB, then the conditioning channels). Differentiable in both.
pub fn forward(config: &WrapperConfig, flat: Tensor<1>, input: Tensor<2>, height: usize, width: usize) -> Tensor<4> {
    let (w, cin) = (config.width, config.input_channels());
    let mut at = 0;
    let mut take = |n: usize| {
        let t = flat.clone().slice(s![at..at + n]);
        at += n;
        t
    };
    let hidden = take(w * cin).reshape([w, cin]);
    let hidden_bias = take(w).reshape([1, w]);
    let output = take(3 * w).reshape([3, w]);
    let output_bias = take(3).reshape([1, 3]);
    let h = relu(input.matmul(hidden.transpose()) + hidden_bias);
    let r = h.matmul(output.transpose()) + output_bias;
    let mut r: Tensor<4> = r.reshape([height, width, 3]).permute([2, 0, 1]).unsqueeze();
    for _ in 0..2 {
        let taps = take(RESIDUAL_TAPS).reshape([3, 3, 3, 3]);
        let bias = take(3);
        let padded = r.clone().pad([(1, 1), (1, 1)], PadMode::Edge);
        r = r + conv2d(padded, taps, Some(bias), ConvOptions::new([1, 1], [0, 0], [1, 1], 1));
    }
    r
}

/// A host vector as a tensor.
pub fn flat_tensor(values: &[f32], device: &Device) -> Tensor<1> {
    Tensor::from_data(TensorData::new(values.to_vec(), [values.len()]), device)
}

/// The decoder-side weights of a flat parameter tensor.
pub fn host_weights(config: WrapperConfig, flat: Tensor<1>) -> SynthesisWeights {
    SynthesisWeights::from_values(config, &tensor_values(flat))
}

/// One sample f is checked on when choosing steps: a base image and its conditioning.
pub struct QuantizationSample {
    pub base: Vec<f32>,
    pub conditioning: Vec<f32>,
    pub width: usize,
    pub height: usize,
}

/// The coarsest power-of-two steps (biases 2^-4 finer than weights: they are few and shift
/// whole images) whose residual stays within `tolerance` of the float network's at every
/// sample pixel; the finest allowed steps if none does.
pub fn choose_quantization(
    weights: &SynthesisWeights,
    samples: &[QuantizationSample],
    tolerance: f32,
) -> QuantizedSynthesis {
    let reference: Vec<Vec<f32>> =
        samples.iter().map(|s| weights.residual(&s.base, &s.conditioning, s.width, s.height)).collect();
    let candidate = |e: i8| QuantizedSynthesis::quantize(weights, e, (e - 4).max(MIN_EXPONENT));
    for e in (MIN_EXPONENT..=MAX_EXPONENT).rev() {
        let q = candidate(e);
        let d = q.dequantize();
        let close = samples.iter().zip(&reference).all(|(s, r)| {
            let got = d.residual(&s.base, &s.conditioning, s.width, s.height);
            got.iter().zip(r).all(|(a, b)| (a - b).abs() <= tolerance)
        });
        if close {
            return q;
        }
    }
    candidate(MIN_EXPONENT)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn initial_network_is_zero() {
        let config = WrapperConfig { width: 16, noise: true, plucker: true, seed: 0 };
        let values = initial_parameters(&config, &mut SplitMix64(1));
        let device = Device::flex();
        let input = Tensor::<2>::ones([6, 17], &device);
        let r = forward(&config, flat_tensor(&values, &device), input, 2, 3);
        assert!(tensor_values(r.reshape([18])).iter().all(|&v| v == 0.0));
        assert!(values[..16 * 17].iter().any(|&v| v != 0.0));
    }

    #[test]
    fn coarser_tolerance_gives_coarser_steps() {
        let config = WrapperConfig { width: 4, noise: false, plucker: false, seed: 0 };
        let mut rng = SplitMix64(3);
        let values: Vec<f32> = (0..config.parameter_count()).map(|_| rng.uniform(-0.4, 0.4)).collect();
        let w = SynthesisWeights::from_values(config, &values);
        let base: Vec<f32> = (0..8 * 6 * 3).map(|_| rng.uniform(0.0, 1.0)).collect();
        let samples = [QuantizationSample { base, conditioning: Vec::new(), width: 8, height: 6 }];
        let fine = choose_quantization(&w, &samples, 1e-4);
        let coarse = choose_quantization(&w, &samples, 1e-2);
        assert!(coarse.weight_exponent > fine.weight_exponent);
        let d = fine.dequantize();
        let (a, b) = (w.residual(&samples[0].base, &[], 8, 6), d.residual(&samples[0].base, &[], 8, 6));
        assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-4));
    }
}

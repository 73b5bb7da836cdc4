//! The quantization noise without a per-step upload: uniform values in ±1/2 drawn once from the
//! trainer's generator and kept on the training device; each step reads a window of them at an
//! offset drawn on the host. An element sees a different pool value at every step (the offsets
//! differ), which is all the rounding proxy needs; what a step moves is one offset per tensor.

use burn::tensor::{Device, Tensor, TensorData};
use pwgs_core::random::SplitMix64;

pub(super) struct NoisePool {
    values: Tensor<1>,
}

impl NoisePool {
    /// A pool for windows of up to `window` values: twice the next power of two, so that the
    /// offsets span at least as many positions as a window holds, and the anchors' growth
    /// rarely outgrows it.
    pub fn new(window: usize, rng: &mut SplitMix64, device: &Device) -> Self {
        let len = 2 * window.max(1).next_power_of_two();
        let values: Vec<f32> = (0..len).map(|_| rng.uniform(-0.5, 0.5)).collect();
        Self { values: Tensor::from_data(TensorData::new(values, [len]), device) }
    }

    fn len(&self) -> usize {
        self.values.dims()[0]
    }

    /// Whether windows of `window` values are drawn from enough offsets.
    pub fn fits(&self, window: usize) -> bool {
        2 * window <= self.len()
    }

    /// Noise shaped `shape`, from an offset drawn with `rng`.
    pub fn draw(&self, shape: [usize; 2], rng: &mut SplitMix64) -> Tensor<2> {
        let size = shape[0] * shape[1];
        let start = (rng.next_u64() % (self.len() - size + 1) as u64) as usize;
        self.values.clone().slice(start..start + size).reshape(shape)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::params::tensor_values;

    #[test]
    fn windows_are_uniform_in_half_a_step_and_differ_between_draws() {
        let mut rng = SplitMix64(3);
        let pool = NoisePool::new(1000, &mut rng, &Device::flex());
        assert!(pool.fits(1000) && !pool.fits(1025));
        let a = tensor_values(pool.draw([100, 10], &mut rng));
        let b = tensor_values(pool.draw([100, 10], &mut rng));
        assert_eq!(a.len(), 1000);
        assert!(a.iter().chain(&b).all(|v| (-0.5..0.5).contains(v)));
        let mean = a.iter().sum::<f32>() / a.len() as f32;
        let variance = a.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / a.len() as f32;
        assert!(mean.abs() < 0.03 && (variance - 1.0 / 12.0).abs() < 0.01, "mean {mean}, variance {variance}");
        let same = a.iter().zip(&b).filter(|(x, y)| x == y).count();
        assert!(same < 10, "two draws share {same} of 1,000 values in place");
    }
}

//! The training side of the anchors' context model (HAC's hash-grid context): a
//! binary context grid ([`pwgs_codec::context_grid`]) and an MLP that maps each anchor's
//! context to the mean and log scale of every one of its stored values, replacing the
//! factorized model's one mean and scale per channel.
//!
//! The grid's entries train as floats and enter the context through their sign (HAC's
//! straight-through binarization: the gradient passes where |entry| <= 1). The anchors do not
//! move during training, so each anchor's corners and weights are computed once.

use burn::tensor::{Device, Int, Tensor, TensorData};
use pwgs_codec::context_grid::{ContextGridShape, Corner};
use pwgs_core::random::SplitMix64;

/// Width of the context MLP's hidden layer: 32 gives about 4,900 parameters at F = 32, K = 10
/// (a few KB in the stream against the tens of KB the context saves on fern).
pub const CONTEXT_HIDDEN: usize = 32;

/// The network's steps in the stream: 2^-8 for weights and biases. Its outputs are means and
/// log2 scales in quantization units, which tolerate errors of a few hundredths, so it needs
/// fewer bits per parameter than the MLPs that make the Gaussians.
pub const CONTEXT_STEP_EXPONENT: i8 = -8;

/// The grid an anchor model trains with: 6 levels from 8 to 256 cells per axis, 2^12
/// entries per hashed grid, 2 channels (about 6 KB before coding; HAC's 2^13 x 12 levels x 4
/// channels is sized for 10x more anchors), and 2D planes at the levels `planes` (HAC has 4).
pub fn context_shape(planes: Vec<u8>) -> ContextGridShape {
    ContextGridShape { levels: vec![3, 4, 5, 6, 7, 8], planes, table_log2: 12, channels: 2 }
}

/// What the context model needs of the anchors, fixed for a run.
pub struct ContextLookup {
    pub shape: ContextGridShape,
    /// Entries of the grid's tables together.
    pub entries: usize,
    /// Per anchor, group and corner: the entry [N * G * 8] and its weight [N * G * 8, 1].
    corner_entries: Tensor<1, Int>,
    corner_weights: Tensor<2>,
    /// Which entries some anchor weighs (weight > 0).
    used: Vec<bool>,
    anchors: usize,
}

impl ContextLookup {
    /// The lookup of anchors at integer octree coordinates `coords` on an octree of `depth`.
    pub fn new(shape: ContextGridShape, coords: &[[u32; 3]], depth: u8, device: &Device) -> Self {
        let mut corners: Vec<Corner> = Vec::with_capacity(coords.len() * shape.groups() * 8);
        for &q in coords {
            shape.corners(q, depth, &mut corners);
        }
        let len = corners.len();
        let used = shape.used_entries(&corners, depth);
        let entries: Vec<i64> = corners.iter().map(|c| i64::from(c.entry)).collect();
        let weights: Vec<f32> = corners.iter().map(|c| c.weight).collect();
        Self {
            entries: shape.entries(depth) as usize,
            shape,
            corner_entries: Tensor::from_data(TensorData::new(entries, [len]), device),
            corner_weights: Tensor::from_data(TensorData::new(weights, [len, 1]), device),
            used,
            anchors: coords.len(),
        }
    }

    /// The trainable tensors: the grid's entries [E, C] (uniform in ±1e-4, as HAC, so that
    /// their signs start random and any gradient can flip them), then the MLP's W1 [L*C, H],
    /// b1 [1, H], W2 [H, outputs] (zero: every anchor starts with the same model) and b2.
    pub fn initial_parameters(&self, outputs: usize, rng: &mut SplitMix64, device: &Device) -> Vec<Tensor<2>> {
        let c = usize::from(self.shape.channels);
        let inputs = self.shape.context_len();
        let uniform = |n: usize, bound: f32, rng: &mut SplitMix64| -> Vec<f32> {
            (0..n).map(|_| rng.uniform(-bound, bound)).collect()
        };
        let host = |v: Vec<f32>, shape: [usize; 2]| Tensor::from_data(TensorData::new(v, shape), device);
        let w1_bound = 1.0 / (inputs as f32).sqrt();
        vec![
            host(uniform(self.entries * c, 1e-4, rng), [self.entries, c]),
            host(uniform(inputs * CONTEXT_HIDDEN, w1_bound, rng), [inputs, CONTEXT_HIDDEN]),
            Tensor::zeros([1, CONTEXT_HIDDEN], device),
            Tensor::zeros([CONTEXT_HIDDEN, outputs], device),
            Tensor::zeros([1, outputs], device),
        ]
    }

    /// Each anchor's context [N, G * C] (G groups of corners) from the grid's entries [E, C]
    /// (autodiff), through their signs.
    pub fn context(&self, grid: Tensor<2>) -> Tensor<2> {
        let c = usize::from(self.shape.channels);
        let groups = self.shape.groups();
        let clipped = grid.clone().clamp(-1.0, 1.0);
        let signs = grid.greater_equal_elem(0.0).float() * 2.0 - 1.0;
        let binary = clipped.clone() + (signs - clipped).detach();
        let gathered = binary.select(0, self.corner_entries.clone()) * self.corner_weights.clone().autodiff();
        gathered.reshape([self.anchors, groups, 8, c]).sum_dim(2).reshape([self.anchors, groups * c])
    }

    /// The model's outputs [N, outputs] for `params` as [`Self::initial_parameters`] lays them
    /// out (autodiff).
    pub fn outputs(&self, params: &[Tensor<2>]) -> Tensor<2> {
        let context = self.context(params[0].clone());
        let hidden = (context.matmul(params[1].clone()) + params[2].clone()).clamp_min(0.0);
        hidden.matmul(params[3].clone()) + params[4].clone()
    }

    /// The entropy of the grid's used signs, in bits: each entry that some anchor weighs
    /// (weight > 0) coded with one adaptive probability per channel, as a coder would.
    pub fn grid_bits(&self, grid: &[f32]) -> f64 {
        let c = usize::from(self.shape.channels);
        let mut bits = 0.0;
        for channel in 0..c {
            let values: Vec<bool> =
                (0..self.entries).filter(|&e| self.used[e]).map(|e| grid[e * c + channel] >= 0.0).collect();
            let ones = values.iter().filter(|&&v| v).count() as f64;
            let n = values.len() as f64;
            for (count, p) in [(ones, ones / n), (n - ones, 1.0 - ones / n)] {
                if count > 0.0 {
                    bits -= count * p.log2();
                }
            }
        }
        bits
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::params::tensor_values;

    #[test]
    fn the_context_uses_signs_and_passes_gradients() {
        let device = Device::flex();
        let shape = ContextGridShape { levels: vec![1], planes: vec![], table_log2: 8, channels: 1 };
        // Depth 2: q = (1, 0, 0) lies halfway between entries 0 and 1; (2, 2, 2) on entry 13.
        let lookup = ContextLookup::new(shape, &[[1, 0, 0], [2, 2, 2]], 2, &device);
        assert_eq!(lookup.entries, 27);
        let mut values = vec![0.5f32; 27];
        values[0] = -3e-5;
        values[1] = 2.0;
        values[13] = -0.25;
        let grid = Tensor::<2>::from_data(TensorData::new(values, [27, 1]), &device).autodiff().require_grad();
        let context = lookup.context(grid.clone());
        assert_eq!(tensor_values(context.clone().inner()), vec![0.0, -1.0]);
        let grads = context.sum().backward();
        let g = tensor_values(grid.grad(&grads).unwrap());
        // Entry 1 (|2| > 1) gets no gradient; entries 0 and 13 get their weights.
        assert_eq!((g[0], g[1], g[13]), (0.5, 0.0, 1.0));
    }

    #[test]
    fn grid_bits_count_only_used_entries() {
        let device = Device::flex();
        let shape = ContextGridShape { levels: vec![1], planes: vec![], table_log2: 8, channels: 1 };
        let lookup = ContextLookup::new(shape, &[[1, 0, 0], [0, 0, 0]], 2, &device);
        // Entries 0 and 1 are used: one +1 and one -1 cost 2 bits; the other 25 are free.
        let mut grid = vec![1.0f32; 27];
        grid[1] = -1.0;
        assert!((lookup.grid_bits(&grid) - 2.0).abs() < 1e-9);
        grid[1] = 1.0;
        assert_eq!(lookup.grid_bits(&grid), 0.0);
    }
}

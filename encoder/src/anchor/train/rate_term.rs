//! The rate side of anchor training: the mean bits per stored value under the factorized or
//! the context model, and the quantization steps, learned per attribute group when asked.

use burn::tensor::Tensor;

use super::{AnchorTrainer, LOG_STEP_RANGE, PARAMETERS, RATE_MODEL};
use crate::anchor::host::host_tensor;
use crate::anchor::quantize::AnchorSteps;
use crate::anchor::rate::factorized_bits;
use crate::train::params::tensor_values;
use pwgs_codec::stream::anchor_context::predicted_values;
use pwgs_codec::stream::octree::{self, OctreeError};

/// Bits the stream spends on an open anchor besides its values, on average: its position (the
/// open anchors' voxels coded as `APOS` codes them) and its K masks (each offset's mask at its
/// channel's frequency among the open anchors, as `AMSK`'s static tables code them). An anchor
/// with every mask shut leaves the stream and costs none of it.
pub(super) fn side_bits(voxels: &[[u32; 3]], depth: u8, masks: &[bool], k: usize) -> Result<f32, OctreeError> {
    let open: Vec<usize> = (0..voxels.len()).filter(|&a| masks[a * k..(a + 1) * k].iter().any(|&m| m)).collect();
    if open.is_empty() {
        return Ok(0.0);
    }
    let points: Vec<[u32; 3]> = open.iter().map(|&a| voxels[a]).collect();
    let position_bits = 8 * octree::encode(&points, depth)?.0.len();
    let mask_bits: f64 = (0..k)
        .map(|j| {
            let p = open.iter().filter(|&&a| masks[a * k + j]).count() as f64 / open.len() as f64;
            let h = |q: f64| if q > 0.0 { -q * q.log2() } else { 0.0 };
            h(p) + h(1.0 - p)
        })
        .sum();
    Ok((position_bits as f64 / open.len() as f64 + mask_bits) as f32)
}

/// Steps between countings of the side bits: they change only as anchors shut or grow, and
/// counting them reads every mask back and codes the open anchors' positions on the host.
const SIDE_BITS_EVERY: u32 = 100;

impl AnchorTrainer {
    /// The side bits of an open anchor under `masks` [N, K] ([`side_bits`]), counted again
    /// every [`SIDE_BITS_EVERY`] steps and after each growth event; 0 without a placement.
    pub(super) fn side_bits(&mut self, masks: &Tensor<2>) -> Result<f32, OctreeError> {
        let (iteration, k) = (self.iteration, self.shape[2]);
        let Some(placement) = &mut self.placement else { return Ok(0.0) };
        match placement.side_bits {
            Some((counted, bits)) if iteration < counted + SIDE_BITS_EVERY => Ok(bits),
            _ => {
                let open: Vec<bool> = tensor_values(masks.clone()).into_iter().map(|m| m > 0.5).collect();
                let bits = side_bits(&placement.voxels, placement.grid.depth, &open, k)?;
                placement.side_bits = Some((iteration, bits));
                Ok(bits)
            }
        }
    }

    /// Learns a factor on each group's quantization step (features, scaling, offsets) while the
    /// rate term is on: the rate pulls steps up, the distortion of the noisy values down
    /// (HAC's adaptive quantization, one factor per group for the whole scene, which the
    /// stream's step fields hold). Call after [`Self::with_context`].
    pub fn with_learned_steps(mut self) -> Self {
        let factors = Tensor::zeros([1, 3], &self.positions.device());
        self.moments.push((factors.zeros_like(), factors.zeros_like()));
        self.learned_steps = Some(self.params.len());
        self.params.push(factors);
        self
    }

    /// The quantization steps the stream is written with: the base steps, times the learned
    /// factors when there are any.
    pub fn steps(&self) -> Option<AnchorSteps> {
        let (base, _) = self.noise?;
        let Some(i) = self.learned_steps else { return Some(base) };
        let f = tensor_values(self.params[i].clone())
            .iter()
            .map(|&v| v.clamp(-LOG_STEP_RANGE, LOG_STEP_RANGE).exp())
            .collect::<Vec<_>>();
        Some(AnchorSteps {
            feature: base.feature * f[0],
            scaling: base.scaling * f[1],
            offset: base.offset * f[2],
            ..base
        })
    }

    /// The three groups' steps for this step, as [1, 1] tensors: learned (with gradients) while
    /// the rate term is on, the learned factors as constants before it (computed on the device:
    /// reading them back would wait for the GPU at every step), else the base steps.
    pub(super) fn step_tensors(&self, tracked: &[Tensor<2>]) -> Option<[Tensor<2>; 3]> {
        let (base, _) = self.noise?;
        let base = [base.feature, base.scaling, base.offset];
        let device = self.positions.device();
        Some(match self.learned_steps {
            Some(i) => {
                let source = match self.lambda() {
                    Some(_) => tracked[i].clone(),
                    None => self.params[i].clone().autodiff(),
                };
                let factors = source.clamp(-LOG_STEP_RANGE, LOG_STEP_RANGE).exp();
                std::array::from_fn(|g| factors.clone().slice([0..1, g..g + 1]) * base[g])
            }
            None => std::array::from_fn(|g| host_tensor(&[base[g]], [1, 1], &device).autodiff()),
        })
    }

    /// Mean bits per stored value: features and scaling of every anchor with an open mask (of
    /// `masks` [N, K]), and `side` bits for its position and masks ([`Self::side_bits`]), offsets of every open mask,
    /// over all N x (F + 6 + 3K) values. Both are gated so that their bits reach the masks: an
    /// offset's through its own mask, an anchor's own bits through the mean of its masks
    /// (HAC++'s adaptive anchor mask), so that the rate can shut an anchor whose Gaussians are
    /// not worth what the anchor itself costs. With the anchor's bits held constant, as
    /// before, the last open mask of an anchor cost only its three offsets.
    pub(super) fn mean_bits(
        &self,
        attributes: &[Tensor<2>],
        tracked: &[Tensor<2>],
        steps: &[Tensor<2>; 3],
        gate: Tensor<2>,
        masks: Tensor<2>,
        side: f32,
    ) -> Tensor<1> {
        let [n, f, k] = self.shape;
        let widths = [f, 6, 3 * k];
        let values = predicted_values(f, k);
        let context = self.context.as_ref().map(|lookup| lookup.outputs(&tracked[PARAMETERS..]));
        // Mean and log scale of group j: per anchor from the context model (whose outputs are,
        // per value, the mean in steps, then log2 of the scale in steps: SPEC.md section 12.7),
        // else per channel.
        let model = |j: usize| match &context {
            Some(out) => {
                let (start, w, step) = (widths[..j].iter().sum::<usize>(), widths[j], steps[j].clone());
                let mean = out.clone().slice([0..n, start..start + w]) * step.clone();
                let log2_scale = out.clone().slice([0..n, values + start..values + start + w]);
                (mean, log2_scale * std::f32::consts::LN_2 + step.log())
            }
            None => (tracked[RATE_MODEL + 2 * j].clone(), tracked[RATE_MODEL + 2 * j + 1].clone()),
        };
        let anchor_open = masks.max_dim(1).autodiff();
        // Straight through: 1 or 0 forward (any mask open), the masks' mean backward.
        let share = gate.clone().mean_dim(1);
        let anchor_gate = share.clone() - share.detach() + anchor_open;
        let (mean, scale) = model(0);
        let features = factorized_bits(attributes[0].clone(), mean, scale, steps[0].clone()).sum_dim(1);
        let (mean, scale) = model(1);
        let scaling = factorized_bits(attributes[1].clone(), mean, scale, steps[1].clone()).sum_dim(1);
        let (mean, scale) = model(2);
        let offsets = match &context {
            Some(_) => factorized_bits(attributes[2].clone(), mean, scale, steps[2].clone()).reshape([n * k, 3]),
            None => factorized_bits(attributes[2].clone().reshape([n * k, 3]), mean, scale, steps[2].clone()),
        };
        let offsets = (offsets.sum_dim(1).reshape([n, k]) * gate).sum_dim(1);
        let total = ((features + scaling).add_scalar(side) * anchor_gate + offsets).sum();
        total / self.rated_values() as f32
    }
}

#[cfg(test)]
mod tests {
    use pwgs_codec::anchor::AnchorModel;
    use pwgs_codec::stream::plain::PositionGrid;
    use pwgs_dataset::synthetic::{SyntheticOptions, generate};
    use pwgs_dataset::{Dataset, LoadOptions, load_scene};

    use super::super::{MASK_LOGITS, mask_gate};
    use super::*;
    use crate::anchor::init::{AnchorShape, initial_model};
    use crate::anchor::quantize::grid_coordinates;

    /// A small generated scene and its initial anchors with features of `f` and `k` offsets.
    fn small_model(seed: u64, f: usize, k: usize) -> (Dataset, AnchorModel, PositionGrid) {
        let tmp = tempfile::tempdir().unwrap();
        let options = SyntheticOptions { width: 32, height: 24, views: 2, seed, points: 300 };
        generate(tmp.path(), &options).unwrap();
        let data = load_scene(tmp.path(), &LoadOptions::default()).unwrap();
        let shape = AnchorShape { feature_dim: f, offsets_per_anchor: k, voxel: 0.05 * data.normalization.scale };
        let (model, grid) = initial_model(data.points.as_ref().unwrap(), shape, 0).unwrap();
        (data, model, grid)
    }

    /// A trainer of `model` with the rate term on from the start.
    fn rated_trainer(model: &AnchorModel, data: &Dataset) -> AnchorTrainer {
        AnchorTrainer::new(model, data, 10, [0.0; 3], 0, &burn::tensor::Device::flex())
            .unwrap()
            .with_quantization_noise(AnchorSteps::default(), 0)
            .with_rate(1.0, 0)
    }

    /// The mean bits of `trainer`'s model and their gradient on each mask logit.
    fn bits_and_mask_gradients(trainer: &mut AnchorTrainer) -> (f32, Vec<f32>) {
        let tracked: Vec<Tensor<2>> = trainer.params.iter().map(|p| p.clone().autodiff().require_grad()).collect();
        let steps = trainer.step_tensors(&tracked).unwrap();
        let masks = trainer.open_masks();
        let gate = mask_gate(tracked[MASK_LOGITS].clone(), masks.clone());
        let side = trainer.side_bits(&masks).unwrap();
        let bits = trainer.mean_bits(&tracked[..3], &tracked, &steps, gate, masks, side);
        let value = tensor_values(bits.clone().inner())[0];
        let grads = bits.backward();
        (value, tensor_values(tracked[MASK_LOGITS].grad(&grads).unwrap()))
    }

    /// Of two anchors alike but for their features, the masks of the one whose features cost
    /// more bits are pushed harder towards shutting: an anchor's own bits reach its masks.
    #[test]
    fn an_anchors_own_bits_reach_its_masks() {
        let (f, k) = (4, 2);
        let (data, mut model, _) = small_model(5, f, k);
        assert!(model.len() >= 2);
        model.scaling[1] = model.scaling[0];
        model.offsets.copy_within(0..3 * k, 3 * k);
        model.features[..f].fill(0.0);
        model.features[f..2 * f].fill(30.0);
        let (_, g) = bits_and_mask_gradients(&mut rated_trainer(&model, &data));
        let (cheap, costly) = (g[0] + g[1], g[2] + g[3]);
        assert!(cheap > 0.0, "shutting a mask saves bits: {:?}", &g[..4]);
        assert!(costly > 2.0 * cheap, "the costly features' bits do not reach the masks: {:?}", &g[..4]);
    }

    /// Placed on its grid, an open anchor also costs its position and masks: the mean bits
    /// grow by exactly that cost over the rated values, and the masks are pushed harder.
    #[test]
    fn a_placed_anchors_position_and_masks_reach_its_masks() {
        let k = 3;
        let (data, model, grid) = small_model(6, 4, k);
        let voxels = grid_coordinates(&model.positions, &grid).unwrap();
        let mut unplaced = rated_trainer(&model, &data);
        let rated = unplaced.rated_values();
        let (plain, plain_grad) = bits_and_mask_gradients(&mut unplaced);
        let (placed, placed_grad) =
            bits_and_mask_gradients(&mut rated_trainer(&model, &data).with_placement(grid, voxels.clone()));
        // Every mask is open at the start: each anchor costs its octree share, masks nothing.
        let side = side_bits(&voxels, grid.depth, &vec![true; voxels.len() * k], k).unwrap();
        assert!(side > 1.0, "an anchor's position costs bits: {side}");
        let expected = plain + side * model.len() as f32 / rated as f32;
        assert!((placed - expected).abs() < 1e-4 * expected, "{placed} against {expected}");
        let (plain_grad, placed_grad): (f32, f32) = (plain_grad.iter().sum(), placed_grad.iter().sum());
        assert!(placed_grad > 1.1 * plain_grad && plain_grad > 0.0, "{placed_grad} against {plain_grad}");
    }

    #[test]
    fn side_bits_count_the_open_anchors_positions_and_masks() {
        let voxels = [[0, 0, 0], [5, 1, 7], [2, 2, 2], [7, 7, 0]];
        // Two masks per anchor; anchor 2 is shut and leaves the stream.
        let masks = [true, false, true, true, false, false, true, false];
        let bits = side_bits(&voxels, 3, &masks, 2).unwrap();
        let open = [voxels[0], voxels[1], voxels[3]];
        let position = 8.0 * octree::encode(&open, 3).unwrap().0.len() as f64 / 3.0;
        // Mask 0 is open in every open anchor (no information), mask 1 in one of three.
        let third = 1.0f64 / 3.0;
        let mask = -(third * third.log2() + (1.0 - third) * (1.0 - third).log2());
        assert!((f64::from(bits) - (position + mask)).abs() < 1e-5, "{bits} against {}", position + mask);
        assert_eq!(side_bits(&voxels, 3, &[false; 8], 2).unwrap(), 0.0, "no open anchor, no stream");
    }
}

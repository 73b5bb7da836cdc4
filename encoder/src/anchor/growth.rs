//! Growing and pruning anchors during training: Scaffold-GS's anchor densification (HAC and
//! HAC++ keep it), with its schedule scaled to the run.
//!
//! Every step adds to the statistics: per neural Gaussian, its screen-space gradient (in
//! normalized device coordinates, as 3DGS's densification) over the steps it was seen; per
//! anchor, the steps it was seen and the opacity its neural Gaussians had. At each event:
//! - growing: at level i of 3, neural Gaussians seen in at least 40% of the steps whose mean
//!   gradient reaches 2e-4 x 2^i, each kept with probability 1 - 0.5^(i+1), propose the cell of
//!   16 / 4^i voxels around them; every proposed cell that holds no anchor gets one at its
//!   center, with the largest of its proposers' anchors' features, all 6 log scales at the
//!   cell's size, zero offsets and open masks;
//! - pruning: an anchor seen in more than 80% of the steps whose neural Gaussians' opacity
//!   averaged below 0.005 per step is removed.
//!
//! Grown anchors sit on the voxel grid the stream codes positions on (cells outside its cube are
//! not grown), so that the stream holds them exactly.

use std::collections::{BTreeMap, HashSet};

use burn::tensor::{Device, Tensor};
use pwgs_core::random::SplitMix64;

use crate::plain::densify::{DeviceGradStats, GradStats};
use crate::train::params::tensor_values;

/// Levels of growth and the cell of the coarsest, in voxels (Scaffold-GS's `update_depth` and
/// `update_init_factor`); each level's cell is 4x smaller and its threshold 2x larger.
const LEVELS: u32 = 3;
const COARSEST_CELL: u32 = 16;
/// Mean screen gradient (NDC) that makes a neural Gaussian propose a cell at level 0.
const GRADIENT_THRESHOLD: f32 = 2e-4;
/// An anchor whose neural Gaussians' opacity averages less than this per step is pruned.
const MIN_OPACITY: f32 = 0.005;

/// When growing and pruning happen, and how many anchors they may reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GrowthSchedule {
    /// First and last iteration with an event, and the iterations between events.
    pub from: u32,
    pub until: u32,
    pub every: u32,
    /// Growing stops at this many anchors.
    pub max_anchors: usize,
}

impl GrowthSchedule {
    /// Scaffold-GS's schedule (events every 100 iterations from 1,500 to 15,000 of 30,000)
    /// scaled to `iterations` of stage 1: every 100 iterations from 5% to half of the run.
    pub fn scaled(iterations: u32, max_anchors: usize) -> Self {
        Self { from: (iterations / 20).max(100), until: iterations / 2, every: 100, max_anchors }
    }

    /// Whether the step that has just finished `iteration` steps is followed by an event.
    pub fn is_event(&self, iteration: u32) -> bool {
        iteration >= self.from && iteration <= self.until && iteration.is_multiple_of(self.every.max(1))
    }
}

/// What the steps since the last event saw, as [`plan`] reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct AnchorStats {
    /// Per neural Gaussian (anchor-major, N x K).
    gradients: GradStats,
    /// Per anchor: the steps it was seen and the opacity its neural Gaussians summed to.
    seen: Vec<u32>,
    opacity: Vec<f32>,
    steps: u32,
    per_anchor: usize,
}

/// [`AnchorStats`] gathered on the training device, so that a step reads nothing back; read
/// at each event.
#[derive(Debug, Clone)]
pub struct DeviceAnchorStats {
    gradients: DeviceGradStats,
    seen: Tensor<1>,
    opacity: Tensor<1>,
    steps: u32,
    shape: [usize; 2],
}

impl DeviceAnchorStats {
    pub fn new(anchors: usize, per_anchor: usize, device: &Device) -> Self {
        Self {
            gradients: DeviceGradStats::new(anchors * per_anchor, device),
            seen: Tensor::zeros([anchors], device),
            opacity: Tensor::zeros([anchors], device),
            steps: 0,
            shape: [anchors, per_anchor],
        }
    }

    /// One step: every neural Gaussian's screen gradient norm and opacity ([N x K] each; zero
    /// for those not rendered). A Gaussian (and its anchor) counts as seen when its norm is
    /// positive; an anchor's opacity sums over its seen Gaussians.
    pub fn add(&mut self, norms: Tensor<1>, opacity: Tensor<1>) {
        let [n, k] = self.shape;
        let seen = norms.clone().greater_elem(0.0);
        self.gradients.add(norms);
        let seen_opacity = opacity.mask_fill(seen.clone().bool_not(), 0.0).reshape([n, k]).sum_dim(1);
        self.opacity = self.opacity.clone() + seen_opacity.reshape([n]);
        self.seen = self.seen.clone() + seen.float().reshape([n, k]).max_dim(1).reshape([n]);
        self.steps += 1;
    }

    pub fn to_host(&self) -> AnchorStats {
        AnchorStats {
            gradients: self.gradients.to_host(),
            seen: tensor_values(self.seen.clone()).into_iter().map(|v| v as u32).collect(),
            opacity: tensor_values(self.opacity.clone()),
            steps: self.steps,
            per_anchor: self.shape[1],
        }
    }
}

/// An anchor to add: its voxel, the side of the cell it grew in (in voxels) and the anchors
/// whose neural Gaussians proposed it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GrownAnchor {
    pub voxel: [u32; 3],
    pub cell: u32,
    pub parents: Vec<usize>,
}

/// What an event does: the anchors kept (ascending) and those added after them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GrowthPlan {
    pub keep: Vec<usize>,
    pub grown: Vec<GrownAnchor>,
}

/// The event's plan for anchors at `voxels` (on a grid of `depth` levels) whose neural
/// Gaussians sit at `neural` (in voxel units from the grid's origin, N x K of them).
pub fn plan(
    stats: &AnchorStats,
    voxels: &[[u32; 3]],
    depth: u8,
    neural: &[[f64; 3]],
    schedule: &GrowthSchedule,
    rng: &mut SplitMix64,
) -> GrowthPlan {
    let k = stats.per_anchor;
    let steps = stats.steps as f32;
    let faint_anchors_pruned: Vec<usize> = (0..voxels.len())
        .filter(|&a| {
            let seen = stats.seen[a] as f32;
            !(seen > 0.8 * steps && stats.opacity[a] < MIN_OPACITY * seen)
        })
        .collect();
    // A run never prunes its last anchor.
    let keep = if faint_anchors_pruned.is_empty() { (0..voxels.len()).collect() } else { faint_anchors_pruned };
    let side = 1i64 << depth;
    let mut occupied: HashSet<[u32; 3]> = keep.iter().map(|&a| voxels[a]).collect();
    let mut grown: Vec<(f32, GrownAnchor)> = Vec::new();
    for level in 0..LEVELS {
        let cell = COARSEST_CELL >> (2 * level);
        let threshold = GRADIENT_THRESHOLD * (1u32 << level) as f32;
        let keep_probability = 1.0 - 0.5f32.powi(level as i32 + 1);
        let cell_of = |p: [f64; 3]| p.map(|c| (c / f64::from(cell)).round() as i64);
        let taken: HashSet<[i64; 3]> = occupied.iter().map(|v| cell_of(v.map(f64::from))).collect();
        let mut proposals: BTreeMap<[i64; 3], (f32, Vec<usize>)> = BTreeMap::new();
        for (j, &p) in neural.iter().enumerate() {
            let g = stats.gradients.mean(j);
            let often = stats.gradients.views[j] as f32 >= 0.4 * steps;
            if !often || g < threshold || rng.uniform(0.0, 1.0) >= keep_probability {
                continue;
            }
            let c = cell_of(p);
            if taken.contains(&c) || c.iter().any(|&v| v < 0 || v * i64::from(cell) >= side) {
                continue;
            }
            let entry = proposals.entry(c).or_insert((0.0, Vec::new()));
            entry.0 = entry.0.max(g);
            if !entry.1.contains(&(j / k)) {
                entry.1.push(j / k);
            }
        }
        for (c, (g, parents)) in proposals {
            let voxel = c.map(|v| (v * i64::from(cell)) as u32);
            if occupied.insert(voxel) {
                grown.push((g, GrownAnchor { voxel, cell, parents }));
            }
        }
    }
    // Under the cap, the strongest gradients win (ties: the order found, deterministic).
    grown.sort_by(|a, b| b.0.total_cmp(&a.0));
    grown.truncate(schedule.max_anchors.saturating_sub(keep.len()));
    GrowthPlan { keep, grown: grown.into_iter().map(|(_, g)| g).collect() }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The statistics of `anchors` x `k` neural Gaussians after `steps` (each step's norms and
    /// opacities, N x K), gathered on the CPU device.
    fn stats_of(anchors: usize, k: usize, steps: &[(&[f32], &[f32])]) -> AnchorStats {
        let device = Device::flex();
        let mut stats = DeviceAnchorStats::new(anchors, k, &device);
        let tensor = |v: &[f32]| Tensor::<1>::from_data(burn::tensor::TensorData::new(v.to_vec(), [v.len()]), &device);
        for (norms, opacity) in steps {
            stats.add(tensor(norms), tensor(opacity));
        }
        stats.to_host()
    }

    #[test]
    fn an_anchor_is_seen_and_sums_opacity_through_its_seen_gaussians() {
        // Anchor 0: Gaussian 0 seen twice, Gaussian 1 never (its opacity does not count);
        // anchor 1: Gaussian 3 seen once (a NaN norm is not seen).
        let stats = stats_of(
            2,
            2,
            &[(&[0.5, 0.0, 0.0, 2.0], &[0.25, 0.75, 0.5, 0.5]), (&[1.5, 0.0, f32::NAN, 0.0], &[0.25, 0.75, 0.5, 0.5])],
        );
        assert_eq!(stats.steps, 2);
        assert_eq!(stats.seen, vec![2, 1]);
        assert_eq!(stats.opacity, vec![0.5, 0.5]);
        assert_eq!(stats.gradients.views, vec![2, 0, 0, 1]);
        assert_eq!((stats.gradients.mean(0), stats.gradients.mean(3)), (1.0, 2.0));
    }

    fn schedule() -> GrowthSchedule {
        GrowthSchedule { from: 100, until: 1000, every: 100, max_anchors: 100 }
    }

    #[test]
    fn the_schedule_scales_with_the_run() {
        let s = GrowthSchedule::scaled(2000, 10);
        assert_eq!((s.from, s.until, s.every), (100, 1000, 100));
        assert!(s.is_event(100) && s.is_event(1000) && !s.is_event(1100) && !s.is_event(150) && !s.is_event(0));
    }

    #[test]
    fn strong_gradients_grow_anchors_in_empty_cells_and_faint_anchors_are_pruned() {
        // Two anchors of 2 neural Gaussians on a 64-voxel grid.
        let voxels = [[0, 0, 0], [40, 40, 40]];
        // Gaussian 1 (anchor 0) has a strong gradient; anchor 1 is seen but transparent.
        let step: (&[f32], &[f32]) = (&[1e-5, 1.0, 1e-5, 0.0], &[0.5, 0.5, 0.001, 0.0]);
        let stats = stats_of(2, 2, &[step; 10]);
        let neural = [[0.0; 3], [30.0, 2.0, 2.0], [40.0; 3], [40.0; 3]];
        let mut rng = SplitMix64(7);
        let p = plan(&stats, &voxels, 6, &neural, &schedule(), &mut rng);
        assert_eq!(p.keep, vec![0], "anchor 1's opacity averaged 0.001 < 0.005");
        // Level 0 (16 voxels): cell (2, 0, 0) around (30, 2, 2), free; level 1 (4 voxels): cell
        // (8, 0, 0)... every grown anchor is anchor 0's child, on the grid, at most one per voxel.
        assert!(!p.grown.is_empty());
        let mut seen = HashSet::new();
        for g in &p.grown {
            assert_eq!(g.parents, vec![0]);
            assert!(g.voxel.iter().all(|&v| v < 64) && g.voxel[0] % g.cell == 0);
            assert!(seen.insert(g.voxel) && g.voxel != voxels[0]);
            let d: f64 = g.voxel.iter().zip([30.0, 2.0, 2.0]).map(|(&v, p)| (f64::from(v) - p).abs()).sum();
            assert!(d <= 3.0 * f64::from(g.cell) / 2.0, "{g:?} is the cell around the Gaussian");
        }
        // The same statistics and seed give the same plan.
        assert_eq!(plan(&stats, &voxels, 6, &neural, &schedule(), &mut SplitMix64(7)), p);
    }

    #[test]
    fn weak_or_rare_gradients_and_full_grids_grow_nothing() {
        let voxels = [[0, 0, 0]];
        let stats = stats_of(1, 1, &[(&[1e-5], &[0.5])]);
        let far = [[30.0, 0.0, 0.0]];
        assert!(plan(&stats, &voxels, 6, &far, &schedule(), &mut SplitMix64(1)).grown.is_empty());
        // A strong gradient seen once in 10 steps is too rare.
        let mut steps: Vec<(&[f32], &[f32])> = vec![(&[1.0], &[0.5])];
        steps.extend([(&[0.0][..], &[0.0][..]); 9]);
        let rare = stats_of(1, 1, &steps);
        assert!(plan(&rare, &voxels, 6, &far, &schedule(), &mut SplitMix64(1)).grown.is_empty());
        // Outside the grid's cube (depth 2: 4 voxels) nothing grows; at the cap neither.
        let strong = stats_of(1, 1, &[(&[1.0], &[0.5])]);
        assert!(plan(&strong, &voxels, 2, &far, &schedule(), &mut SplitMix64(1)).grown.is_empty());
        let capped = GrowthSchedule { max_anchors: 1, ..schedule() };
        assert!(plan(&strong, &voxels, 6, &far, &capped, &mut SplitMix64(1)).grown.is_empty());
        assert!(!plan(&strong, &voxels, 6, &far, &schedule(), &mut SplitMix64(1)).grown.is_empty());
    }
}

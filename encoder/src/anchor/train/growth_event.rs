//! Growing and pruning events of anchor training ([`crate::anchor::growth`]): the statistics'
//! plan applied to every per-anchor tensor, the masks and the context lookup.

use super::{AnchorTrainer, Growth, GrowthTotals, INITIAL_MASK_LOGIT, MASK_LOGITS};
use crate::anchor::context::ContextLookup;
use crate::anchor::growth::{DeviceAnchorStats, GrowthPlan, GrowthSchedule, plan};
use crate::anchor::host::kept_and_added;
use crate::train::params::tensor_values;

impl AnchorTrainer {
    /// Grows and prunes anchors on `schedule`, on the grid of [`Self::with_placement`] (which
    /// must come first).
    pub fn with_growth(mut self, schedule: GrowthSchedule) -> Self {
        assert!(self.placement.is_some(), "growth places anchors on the trainer's grid");
        let [n, _, k] = self.shape;
        let stats = DeviceAnchorStats::new(n, k, &self.positions.device());
        self.growth = Some(Growth { schedule, stats, totals: GrowthTotals::default() });
        self
    }

    /// Anchors grown and pruned so far, when growing is on.
    pub fn growth_totals(&self) -> Option<GrowthTotals> {
        self.growth.as_ref().map(|g| g.totals)
    }

    /// A growth event: plans from the statistics, then rebuilds every per-anchor tensor (kept
    /// rows, then the grown anchors' with zero moments), the masks and the context lookup.
    pub(super) fn grow_and_prune(&mut self) {
        let (Some(growth), Some(placement)) = (&mut self.growth, &mut self.placement) else { return };
        let [n, f, k] = self.shape;
        let device = self.positions.device();
        let positions = tensor_values(self.positions.clone());
        let scaling = tensor_values(self.params[1].clone());
        let offsets = tensor_values(self.params[2].clone());
        let grid = placement.grid;
        // Where the neural Gaussians are, in voxels from the grid's origin (as a step places
        // them: anchor + offset x exp(offset scale)).
        let neural: Vec<[f64; 3]> = (0..n * k)
            .map(|j| {
                let a = j / k;
                std::array::from_fn(|x| {
                    let p = positions[3 * a + x] + offsets[3 * j + x] * scaling[6 * a + x].exp();
                    (f64::from(p) - f64::from(grid.origin[x])) / f64::from(grid.cell)
                })
            })
            .collect();
        let GrowthPlan { keep, grown } =
            plan(&growth.stats.to_host(), &placement.voxels, grid.depth, &neural, &growth.schedule, &mut self.rng);
        let features = tensor_values(self.params[0].clone());
        let mut added: [Vec<f32>; 4] = Default::default();
        for g in &grown {
            added[0].extend((0..f).map(|c| g.parents.iter().map(|&a| features[a * f + c]).fold(f32::MIN, f32::max)));
            added[1].extend([(g.cell as f32 * grid.cell).ln(); 6]);
            added[2].extend(std::iter::repeat_n(0.0, 3 * k));
            added[3].extend(std::iter::repeat_n(INITIAL_MASK_LOGIT, k));
        }
        for (i, new_rows) in [0, 1, 2, MASK_LOGITS].into_iter().zip(&added) {
            let zeros = vec![0.0; new_rows.len()];
            self.params[i] = kept_and_added(&self.params[i], &keep, new_rows);
            let (first, second) = &mut self.moments[i];
            *first = kept_and_added(first, &keep, &zeros);
            *second = kept_and_added(second, &keep, &zeros);
        }
        let new_positions: Vec<f32> = grown.iter().flat_map(|g| grid.position(g.voxel)).collect();
        self.positions = kept_and_added(&self.positions, &keep, &new_positions);
        self.masks = kept_and_added(&self.masks, &keep, &vec![1.0; grown.len() * k]);
        placement.side_bits = None;
        placement.voxels = keep.iter().map(|&a| placement.voxels[a]).chain(grown.iter().map(|g| g.voxel)).collect();
        let anchors = placement.voxels.len();
        growth.totals.grown += grown.len();
        growth.totals.pruned += n - keep.len();
        growth.stats = DeviceAnchorStats::new(anchors, k, &device);
        self.shape[0] = anchors;
        if let Some(lookup) = &self.context {
            self.context = Some(ContextLookup::new(lookup.shape.clone(), &placement.voxels, grid.depth, &device));
        }
    }
}

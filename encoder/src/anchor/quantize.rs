//! Turning a trained anchor model into what an anchor stream stores (SPEC.md section 12):
//! anchor positions as integer voxel coordinates, per-anchor attributes as multiples of their
//! steps, MLP weights as multiples of power-of-two steps. The decoder's reconstruction of the
//! result is the model every view is rendered from, so evaluation always goes through it.
#![cfg_attr(not(test), deny(clippy::disallowed_methods))] // the determinism rule: no platform math (clippy.toml)

use anyhow::{Result, bail, ensure};
use pwgs_codec::anchor::{AnchorModel, Mlp};
use pwgs_codec::context_grid::ContextGridShape;
use pwgs_codec::stream::anchor::{QuantizedAnchors, QuantizedMlp};
use pwgs_codec::stream::anchor_context::QuantizedContext;
use pwgs_codec::stream::octree::MAX_DEPTH;
use pwgs_codec::stream::plain::PositionGrid;

use super::context::CONTEXT_STEP_EXPONENT;

/// Quantization steps of an anchor stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnchorSteps {
    pub feature: f32,
    /// Of the 6 log scales.
    pub scaling: f32,
    /// Of the offsets, in units of each anchor's offset scale.
    pub offset: f32,
    /// MLP weights: 2^weight_exponent; biases: 2^bias_exponent.
    pub weight_exponent: i8,
    pub bias_exponent: i8,
}

impl Default for AnchorSteps {
    /// Features and offsets at 1/8 (both are O(1)), log scales at 1/16, weights at 2^-11,
    /// biases at 2^-12. On fern at 2,000 iterations these steps (λ = 0.002) gave 270 KB at
    /// 27.02 dB, twice them 224 KB at 26.46 dB, both ahead of the plain base at its sizes
    /// (303 KB: 26.18 dB; 229 KB: 25.99 dB).
    fn default() -> Self {
        Self { feature: 1.0 / 8.0, scaling: 1.0 / 16.0, offset: 1.0 / 8.0, weight_exponent: -11, bias_exponent: -12 }
    }
}

impl AnchorSteps {
    /// The same steps with every attribute step multiplied by `factor` (weights unchanged).
    pub fn scaled(self, factor: f32) -> Self {
        Self { feature: self.feature * factor, scaling: self.scaling * factor, offset: self.offset * factor, ..self }
    }
}

/// The grid the anchors of a voxel size sit on: the origin is the smallest coordinate per
/// axis, the cell the voxel, and the depth the fewest levels that hold every anchor.
pub fn anchor_grid(cells: &[[i64; 3]], voxel: f32) -> Result<(PositionGrid, Vec<[u32; 3]>)> {
    ensure!(!cells.is_empty(), "no anchors to place on a grid");
    let lo: [i64; 3] = std::array::from_fn(|a| cells.iter().map(|c| c[a]).min().expect("not empty"));
    let q: Vec<[u32; 3]> =
        cells.iter().map(|c| std::array::from_fn(|a| u32::try_from(c[a] - lo[a]).unwrap_or(u32::MAX))).collect();
    let largest = q.iter().flatten().copied().max().unwrap_or(0);
    let depth = (u32::BITS - largest.leading_zeros()).max(1);
    if depth > u32::from(MAX_DEPTH) {
        bail!("the anchors span {largest} voxels along an axis, more than a {MAX_DEPTH}-level grid holds");
    }
    let origin = lo.map(|l| (l as f64 * f64::from(voxel)) as f32);
    Ok((PositionGrid { origin, cell: voxel, depth: depth as u8 }, q))
}

/// The integer coordinates of positions that lie on `grid` (as [`anchor_grid`] places them).
pub fn grid_coordinates(positions: &[[f32; 3]], grid: &PositionGrid) -> Result<Vec<[u32; 3]>> {
    positions
        .iter()
        .map(|p| {
            let q: [u32; 3] = std::array::from_fn(|a| {
                ((f64::from(p[a]) - f64::from(grid.origin[a])) / f64::from(grid.cell)).round().max(0.0) as u32
            });
            match grid.position(q) == *p {
                true => Ok(q),
                false => bail!("anchor {p:?} is not on the grid it was placed on"),
            }
        })
        .collect()
}

fn round_all(values: &[f32], step: f32) -> Vec<i32> {
    values.iter().map(|&v| (v / step).round() as i32).collect()
}

/// The stream content of `model`, whose anchors sit on `grid`: anchors with every mask shut
/// show nothing and are left out, and offsets under a shut mask are not stored (0).
pub fn quantize(model: &AnchorModel, grid: &PositionGrid, steps: &AnchorSteps) -> Result<QuantizedAnchors> {
    ensure!(model.is_consistent(), "the anchor model is inconsistent");
    let finite = model.features.iter().chain(model.scaling.iter().flatten()).chain(&model.offsets);
    ensure!(finite.into_iter().all(|v| v.is_finite()), "the anchor model has a non-finite attribute");
    let (f, k) = (model.feature_dim, model.offsets_per_anchor);
    let kept: Vec<usize> = (0..model.len()).filter(|&i| model.masks[i * k..(i + 1) * k].iter().any(|&m| m)).collect();
    let rows = |values: &[f32], width: usize| -> Vec<f32> {
        kept.iter().flat_map(|&i| values[i * width..(i + 1) * width].iter().copied()).collect()
    };
    let masks: Vec<bool> = kept.iter().flat_map(|&i| model.masks[i * k..(i + 1) * k].iter().copied()).collect();
    let mut offsets = round_all(&rows(&model.offsets, 3 * k), steps.offset);
    offsets.chunks_exact_mut(3).zip(&masks).filter(|(_, open)| !**open).for_each(|(o, _)| o.fill(0));
    let positions: Vec<[f32; 3]> = kept.iter().map(|&i| model.positions[i]).collect();
    let (e_w, e_b) = (steps.weight_exponent, steps.bias_exponent);
    Ok(QuantizedAnchors {
        grid: *grid,
        positions: grid_coordinates(&positions, grid)?,
        feature_dim: f,
        offsets_per_anchor: k,
        feature_step: steps.feature,
        features: round_all(&rows(&model.features, f), steps.feature),
        scaling_step: steps.scaling,
        scaling: kept.iter().map(|&i| model.scaling[i].map(|v| (v / steps.scaling).round() as i32)).collect(),
        offset_step: steps.offset,
        offsets,
        masks,
        mlps: [&model.opacity, &model.color, &model.covariance].map(|m| QuantizedMlp::quantize(m, e_w, e_b)),
        context: None,
    })
}

/// A trained context model ([`super::context`]): the grid's float entries (entry-major) and
/// the network as a decoder evaluates it.
pub struct TrainedContext {
    pub shape: ContextGridShape,
    pub grid: Vec<f32>,
    pub mlp: Mlp,
}

/// Adds the context model to `content`: the grid's signs and the network's weights at
/// [`CONTEXT_STEP_EXPONENT`]. Entries no stored anchor weighs take the commonest sign of their
/// channel, which the adaptive coder then codes almost for free.
pub fn quantize_context(content: &mut QuantizedAnchors, trained: &TrainedContext) {
    let depth = content.grid.depth;
    let c = usize::from(trained.shape.channels);
    let entries = trained.shape.entries(depth) as usize;
    let mut corners = Vec::new();
    for &q in &content.positions {
        trained.shape.corners(q, depth, &mut corners);
    }
    let used = trained.shape.used_entries(&corners, depth);
    let sign = |e: usize, ch: usize| trained.grid[e * c + ch] >= 0.0;
    let common: Vec<bool> = (0..c)
        .map(|ch| {
            let ones = (0..entries).filter(|&e| used[e] && sign(e, ch)).count();
            2 * ones >= used.iter().filter(|&&u| u).count()
        })
        .collect();
    let signs = (0..entries * c).map(|i| if used[i / c] { sign(i / c, i % c) } else { common[i % c] }).collect();
    content.context = Some(QuantizedContext {
        shape: trained.shape.clone(),
        signs,
        mlp: QuantizedMlp::quantize(&trained.mlp, CONTEXT_STEP_EXPONENT, CONTEXT_STEP_EXPONENT),
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_holds_every_cell_from_the_smallest() {
        let cells = [[-3, 4, 10], [5, 4, 11], [-3, 7, 10]];
        let (grid, q) = anchor_grid(&cells, 0.25).unwrap();
        assert_eq!(grid.origin, [-0.75, 1.0, 2.5]);
        assert_eq!(grid.depth, 4); // 8 voxels along x need 4 levels (0..=8)
        assert_eq!(q, vec![[0, 0, 0], [8, 0, 1], [0, 3, 0]]);
        let positions: Vec<[f32; 3]> = q.iter().map(|&c| grid.position(c)).collect();
        assert_eq!(grid_coordinates(&positions, &grid).unwrap(), q);
        assert!(grid_coordinates(&[[0.1, 1.0, 2.5]], &grid).is_err(), "off the grid");
        assert_eq!(anchor_grid(&[[2, 2, 2]], 1.0).unwrap().0.depth, 1);
        assert!(anchor_grid(&[[0, 0, 0], [1 << 25, 0, 0]], 1.0).is_err());
    }

    #[test]
    fn shut_masks_drop_offsets_and_anchors() {
        let (grid, q) = anchor_grid(&[[0, 0, 0], [1, 0, 0], [0, 1, 0]], 0.5).unwrap();
        let mlp = |outputs| pwgs_codec::anchor::Mlp {
            inputs: 5,
            hidden: 2,
            outputs,
            w1: vec![0.1; 10],
            b1: vec![0.0; 2],
            w2: vec![0.2; 2 * outputs],
            b2: vec![0.0; outputs],
        };
        let model = AnchorModel {
            feature_dim: 1,
            offsets_per_anchor: 2,
            positions: q.iter().map(|&c| grid.position(c)).collect(),
            features: vec![0.5, 1.0, 1.5],
            scaling: vec![[0.0; 6]; 3],
            offsets: (0..18).map(|v| v as f32).collect(),
            masks: vec![true, false, false, false, false, true],
            opacity: mlp(2),
            color: mlp(6),
            covariance: mlp(14),
        };
        let steps = AnchorSteps { feature: 0.5, scaling: 1.0, offset: 1.0, weight_exponent: -8, bias_exponent: -8 };
        let content = quantize(&model, &grid, &steps).unwrap();
        assert_eq!(content.positions, vec![[0, 0, 0], [0, 1, 0]], "the anchor with both masks shut is gone");
        assert_eq!(content.features, vec![1, 3]);
        assert_eq!(content.masks, vec![true, false, false, true]);
        assert_eq!(content.offsets, vec![0, 1, 2, 0, 0, 0, 0, 0, 0, 15, 16, 17]);
    }
}

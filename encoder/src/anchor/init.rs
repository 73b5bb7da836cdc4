//! The initial anchor model from a point cloud, as Scaffold-GS initializes from SfM points:
//! one anchor per occupied voxel (at the voxel's center of rounding, `round(p / v) * v`, as the
//! stream's grid reconstructs it), a
//! zero feature and zero offsets, all 6 log scales set from the distance to the nearest other
//! anchors, every offset unmasked, and MLPs with PyTorch's default initialization.

use anyhow::{Result, ensure};
use pwgs_codec::anchor::{AnchorModel, Mlp};
use pwgs_codec::stream::plain::PositionGrid;
use pwgs_core::ply::PointCloud;
use pwgs_core::random::SplitMix64;

use super::quantize::anchor_grid;
use crate::plain::init::gaussians_from_points;

/// The shape of an anchor model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnchorShape {
    /// Feature length F (Scaffold-GS 32, HAC 50).
    pub feature_dim: usize,
    /// Neural Gaussians per anchor, K.
    pub offsets_per_anchor: usize,
    /// Voxel edge for the anchors, in scene units.
    pub voxel: f32,
}

/// The occupied voxels of edge `voxel`, sorted (x, then y, then z), on the grid that holds
/// them, and one anchor position per voxel.
pub fn voxel_anchors(cloud: &PointCloud, voxel: f32) -> Result<(PositionGrid, Vec<[f32; 3]>)> {
    let mut cells: Vec<[i64; 3]> =
        cloud.positions.iter().map(|p| p.map(|c| (f64::from(c) / f64::from(voxel)).round() as i64)).collect();
    cells.sort_unstable();
    cells.dedup();
    let (grid, q) = anchor_grid(&cells, voxel)?;
    Ok((grid, q.iter().map(|&c| grid.position(c)).collect()))
}

/// Weights uniform in ±1/sqrt(inputs), as PyTorch initializes `nn.Linear`.
fn mlp(inputs: usize, hidden: usize, outputs: usize, rng: &mut SplitMix64) -> Mlp {
    let mut layer = |n: usize, fan_in: usize| {
        let bound = 1.0 / (fan_in as f32).sqrt();
        (0..n).map(|_| rng.uniform(-bound, bound)).collect::<Vec<f32>>()
    };
    Mlp {
        inputs,
        hidden,
        outputs,
        w1: layer(hidden * inputs, inputs),
        b1: layer(hidden, inputs),
        w2: layer(outputs * hidden, hidden),
        b2: layer(outputs, hidden),
    }
}

/// The initial model of `cloud` (at least one point), with hidden layers of width F, and the
/// grid its anchors sit on.
pub fn initial_model(cloud: &PointCloud, shape: AnchorShape, seed: u64) -> Result<(AnchorModel, PositionGrid)> {
    ensure!(!cloud.positions.is_empty(), "no points to place anchors on");
    ensure!(shape.voxel > 0.0 && shape.voxel.is_finite(), "the voxel size must be positive");
    let (grid, positions) = voxel_anchors(cloud, shape.voxel)?;
    let anchors = PointCloud { colors: vec![[0.5; 3]; positions.len()], positions };
    // The plain initialization's scale: sqrt of the mean squared distance to 3 neighbours.
    let scales = gaussians_from_points(&anchors, 0)?.log_scales;
    let (n, f, k) = (anchors.positions.len(), shape.feature_dim, shape.offsets_per_anchor);
    let mut rng = SplitMix64(seed ^ 0x414e_4348);
    let model = AnchorModel {
        feature_dim: f,
        offsets_per_anchor: k,
        features: vec![0.0; n * f],
        scaling: scales.iter().map(|s| [s[0]; 6]).collect(),
        offsets: vec![0.0; n * k * 3],
        masks: vec![true; n * k],
        opacity: mlp(f + 4, f, k, &mut rng),
        color: mlp(f + 4, f, 3 * k, &mut rng),
        covariance: mlp(f + 4, f, 7 * k, &mut rng),
        positions: anchors.positions,
    };
    Ok((model, grid))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anchors_sit_on_occupied_voxels_once() {
        let cloud = PointCloud {
            positions: vec![
                [0.04, 0.0, 0.0],
                [0.06, 0.01, 0.0],
                [0.14, 0.0, 0.0],
                [-0.21, 0.3, 0.0],
                [0.049, 0.0, 0.0],
            ],
            colors: vec![[0.5; 3]; 5],
        };
        // Voxel 0.1: cells (0,0,0), (1,0,0) twice, (1,0,0), (-2,3,0), (0,0,0).
        let (grid, anchors) = voxel_anchors(&cloud, 0.1).unwrap();
        assert_eq!(anchors.len(), 3);
        assert_eq!(anchors[0], grid.position([0, 3, 0]), "the grid starts at the smallest cell per axis");
        assert_eq!(anchors[0], [(-2.0f64 * 0.1) as f32, (3.0f64 * 0.1f64) as f32, 0.0]);
        let shape = AnchorShape { feature_dim: 4, offsets_per_anchor: 3, voxel: 0.1 };
        let (model, _) = initial_model(&cloud, shape, 1).unwrap();
        assert!(model.is_consistent());
        assert_eq!((model.len(), model.opacity.hidden), (3, 4));
        assert!(model.features.iter().chain(&model.offsets).all(|&v| v == 0.0));
        assert!(model.scaling.iter().all(|s| s.iter().all(|&v| v == s[0] && v.is_finite())));
        let bound = 1.0 / 8f32.sqrt();
        assert!(model.opacity.w1.iter().all(|w| w.abs() <= bound) && model.opacity.w1.iter().any(|&w| w != 0.0));
        assert!(initial_model(&PointCloud::default(), shape, 1).is_err());
    }
}

//! Initial Gaussians from a point cloud, as 3DGS initializes from SfM points: one isotropic
//! Gaussian per point, sized by the distance to its nearest neighbours, colored by the point,
//! nearly transparent (opacity 0.1) so that training decides what stays.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use pwgs_core::gaussians::{Gaussians, opacity_to_logit, rgb_to_sh_dc, sh_coeff_count};
use pwgs_core::ply::PointCloud;
use pwgs_core::random::SplitMix64;
use pwgs_dataset::Dataset;

/// Opacity of freshly initialized Gaussians.
pub const INITIAL_OPACITY: f32 = 0.1;

/// Neighbours averaged for the initial scale.
const NEIGHBOURS: usize = 3;

/// Smallest initial scale: coincident points would otherwise give log(0).
const MIN_SCALE: f32 = 1e-7;

/// Points sampled when a dataset has no point cloud.
pub const RANDOM_POINTS: usize = 10_000;

/// The initial Gaussians of a dataset: from its point cloud, or, when it has none, from
/// [`RANDOM_POINTS`] points sampled in the training cameras' view frusta; at most `max` of
/// them (see [`subsample`]).
pub fn initial_gaussians(data: &Dataset, seed: u64, max: usize) -> anyhow::Result<Gaussians> {
    let cloud = match &data.points {
        Some(points) if !points.positions.is_empty() => subsample(points, max, seed),
        _ => random_frustum_points(data, RANDOM_POINTS.min(max), seed)?,
    };
    gaussians_from_points(&cloud, 0)
}

/// At most `max` points of `cloud`, chosen at random (a seeded partial shuffle) and kept in
/// their original order, so that a Gaussian cap bounds the model from the first iteration even
/// when the SfM cloud is larger than the cap. A cloud within the cap is returned whole.
pub fn subsample(cloud: &PointCloud, max: usize, seed: u64) -> PointCloud {
    let n = cloud.positions.len();
    if n <= max {
        return cloud.clone();
    }
    let mut rng = SplitMix64(seed ^ 0x5355_4253);
    let mut order: Vec<usize> = (0..n).collect();
    for i in 0..max {
        let j = i + (rng.next_u64() % (n - i) as u64) as usize;
        order.swap(i, j);
    }
    let mut kept = order[..max].to_vec();
    kept.sort_unstable();
    PointCloud {
        positions: kept.iter().map(|&i| cloud.positions[i]).collect(),
        colors: kept.iter().map(|&i| cloud.colors[i]).collect(),
    }
}

/// Points along random pixel rays of the training cameras, at depths spread around the scene
/// center's distance, with mid-gray color.
pub fn random_frustum_points(data: &Dataset, count: usize, seed: u64) -> anyhow::Result<PointCloud> {
    anyhow::ensure!(!data.train.is_empty(), "no training views to sample points from");
    let mut rng = SplitMix64(seed);
    let mut cloud = PointCloud::default();
    for k in 0..count {
        let cam = &data.train[k % data.train.len()].camera;
        let (u, v) = (rng.uniform(0.0, cam.width as f32), rng.uniform(0.0, cam.height as f32));
        let distance = cam.center().distance(data.normalization.center).max(1e-3);
        let depth = distance * rng.uniform(0.3, 1.5);
        let p = cam.center() + cam.ray_direction(u, v) * depth;
        cloud.positions.push(p.to_array());
        cloud.colors.push([0.5; 3]);
    }
    Ok(cloud)
}

/// One Gaussian per point; scale = sqrt(mean squared distance to the 3 nearest other points).
pub fn gaussians_from_points(cloud: &PointCloud, sh_degree: u32) -> anyhow::Result<Gaussians> {
    let tree = ImmutableKdTree::<f32, 3>::new_from_slice(&cloud.positions)
        .map_err(|e| anyhow::anyhow!("cannot index {} points: {e:?}", cloud.positions.len()))?;
    let mut g = Gaussians::with_degree(sh_degree);
    let mut sh = vec![0.0f32; sh_coeff_count(sh_degree) * 3];
    let logit = opacity_to_logit(INITIAL_OPACITY);
    for (p, color) in cloud.positions.iter().zip(&cloud.colors) {
        // The nearest hit is the point itself (distance 0) unless it has duplicates, which then
        // count as neighbours at distance 0, as in 3DGS.
        let count = std::num::NonZero::new(NEIGHBOURS + 1).expect("non-zero");
        let hits = tree.query(p).nearest_n::<SquaredEuclidean<f32>>(count).execute();
        let others: Vec<f32> = hits.iter().skip(1).map(|n| n.distance).collect();
        let mean_sq = if others.is_empty() { 1.0 } else { others.iter().sum::<f32>() / others.len() as f32 };
        let scale = mean_sq.sqrt().max(MIN_SCALE);
        for c in 0..3 {
            sh[c] = rgb_to_sh_dc(color[c]);
        }
        g.push(*p, [scale.ln(); 3], [1.0, 0.0, 0.0, 0.0], logit, &sh);
    }
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_follows_neighbour_distance_and_color_round_trips() {
        let cloud = PointCloud {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [10.0, 0.0, 0.0]],
            colors: vec![[0.2, 0.4, 0.6]; 5],
        };
        let g = gaussians_from_points(&cloud, 1).unwrap();
        assert_eq!(g.len(), 5);
        assert!((g.log_scales[0][0] - 0.0).abs() < 1e-6, "three unit neighbours give scale 1");
        assert!(g.log_scales[4][0] > 2.0, "an isolated point gets a large scale");
        let color = pwgs_core::gaussians::SH_C0 * g.sh[0] + 0.5;
        assert!((color - 0.2).abs() < 1e-6);
        assert!((1.0 / (1.0 + (-g.opacity_logits[0]).exp()) - INITIAL_OPACITY).abs() < 1e-6);
    }

    #[test]
    fn a_cloud_above_the_cap_is_subsampled_in_order() {
        let cloud = PointCloud {
            positions: (0..100).map(|i| [i as f32, 0.0, 0.0]).collect(),
            colors: (0..100).map(|i| [i as f32 / 100.0; 3]).collect(),
        };
        assert_eq!(subsample(&cloud, 100, 1), cloud);
        let kept = subsample(&cloud, 30, 1);
        assert_eq!((kept.positions.len(), kept.colors.len()), (30, 30));
        let xs: Vec<f32> = kept.positions.iter().map(|p| p[0]).collect();
        assert!(xs.windows(2).all(|w| w[0] < w[1]), "distinct points in their order: {xs:?}");
        assert!(kept.positions.iter().zip(&kept.colors).all(|(p, c)| c[0] == p[0] / 100.0), "colors follow");
        assert_eq!(subsample(&cloud, 30, 1), kept, "the same seed keeps the same points");
        assert_ne!(subsample(&cloud, 30, 2), kept);
        // Spread over the cloud, not its first points.
        assert!(xs[29] > 60.0, "{xs:?}");
    }
}

//! How much each Gaussian shows, for importance classes (SPEC.md section 6.5): its blending
//! weight summed over the pixels of views from all around the model, and from it a class per
//! Gaussian, each class a factor 2 coarser than the one before. A value's error shows in
//! proportion to that weight, so steps shrinking as its inverse square root minimize the
//! weighted squared error for the bytes (measured: summing over the views codes guitar about
//! 2% smaller at equal PSNR than taking each Gaussian's largest view).
//!
//! The views look at the scene's center from directions spread over the upper half of the
//! sphere (the points on a grid cube's surface), so that no way round is favoured, and they
//! need no trigonometry: with `+ - * / sqrt` only, the classes, and so the stream,
//! are the same on every machine.
#![cfg_attr(not(test), deny(clippy::disallowed_methods))] // the determinism rule: no platform math (clippy.toml)

use glam::Vec3;
use pwgs_codec::stream::classes::ImportanceClasses;
use pwgs_core::camera::{Camera, CameraError, Intrinsics};
use pwgs_core::gaussians::Gaussians;
use pwgs_render::raster::blend::splat_weights;
use pwgs_render::raster::{RenderOptions, Window, tiles, visible_splats};
use rayon::prelude::*;

use crate::plain::compress::{StreamContext, sqrt2_power};

/// Width and height of the views.
pub const VIEW_SIZE: u32 = 512;
/// Most classes: 0 (the reference) to 6 (steps 64 times coarser, positions 6 levels coarser;
/// classes that far down code guitar about 1.6% smaller at equal PSNR at quality 10 than
/// stopping at 16 times).
pub const MAX_CLASSES: u8 = 7;
/// The weight that class 0 starts at: this quantile (in percent) of all the weights.
const REFERENCE_PERCENTILE: usize = 90;

/// The unit directions from the center of a 5 x 5 x 5 grid of points to the 98 points on its
/// surface: spread over the sphere about evenly (within a factor 2 of each other in angle).
/// More directions than a cube's 26 show more of what occludes what: on biker, 57 views on or
/// above the horizon code about 6% smaller at equal PSNR than 17 (guitar 1-2%); 121 views
/// (a 7 x 7 x 7 grid) gain nothing more.
fn directions() -> Vec<Vec3> {
    let mut out = Vec::with_capacity(98);
    for x in -2i8..=2 {
        for y in -2i8..=2 {
            for z in -2i8..=2 {
                if x.abs().max(y.abs()).max(z.abs()) == 2 {
                    out.push(Vec3::new(f32::from(x), f32::from(y), f32::from(z)).normalize());
                }
            }
        }
    }
    out
}

/// Cameras of `size` pixels and a 60-degree field of view at the scene's scale from its
/// center, looking at it from those of the 98 [`directions`] on or above the horizon of `up`
/// (57 when `up` is an axis): where a viewer walks around a scene, not from under its floor.
pub fn cameras(context: &StreamContext, up: Vec3, size: u32) -> Result<Vec<Camera>, CameraError> {
    let up = up.normalize_or_zero();
    if up == Vec3::ZERO {
        return Err(CameraError::NonFinitePose);
    }
    // 1 / tan(30 degrees) = sqrt(3).
    let f = size as f32 / 2.0 * 3f32.sqrt();
    let intrinsics =
        Intrinsics { width: size, height: size, fx: f, fy: f, cx: size as f32 / 2.0, cy: size as f32 / 2.0 };
    let center = Vec3::from(context.center);
    directions()
        .into_iter()
        .filter(|d| d.dot(up) >= -1e-6)
        .map(|d| {
            let camera_up = if d.cross(up).length_squared() < 1e-6 { up.any_orthonormal_vector() } else { up };
            Camera::look_at(intrinsics, center + d * context.scale, center, camera_up)
        })
        .collect()
}

/// Per Gaussian, its blending weight summed over every pixel of `cameras` (pixels' worth of
/// colour). Gaussians inside an opaque model, or too faint, get 0.
pub fn blend_weights(g: &Gaussians, cameras: &[Camera], options: &RenderOptions) -> Vec<f32> {
    let per_view = |camera: &Camera| {
        let splats = visible_splats(g, camera, &options.projection);
        let bins = tiles::bin(&splats, Window::full(camera));
        splat_weights(&bins, &splats, options, g.len())
    };
    // Summed in view order, so that the sums do not depend on threads.
    let views: Vec<Vec<f32>> = cameras.par_iter().map(per_view).collect();
    let mut total = vec![0.0f32; g.len()];
    for view in &views {
        total.iter_mut().zip(view).for_each(|(t, w)| *t += w);
    }
    total
}

/// The weight importance is measured against: the [`REFERENCE_PERCENTILE`]th percentile of
/// `weights` (0 when there are none).
pub fn reference(weights: &[f32]) -> f32 {
    let mut sorted = weights.to_vec();
    sorted.sort_by(f32::total_cmp);
    sorted.get(sorted.len().saturating_sub(1) * REFERENCE_PERCENTILE / 100).copied().unwrap_or(0.0)
}

/// Classes for Gaussians of weights `weights`: class `k` where `reference` over the Gaussian's
/// weight `w` is about `4^k`: `w * sqrt(2)^(4j - 3) <= reference` for `j = 1 ..= k` (so class
/// `k` holds the ratios from `2^(2k - 1.5)` up to `2^(2k + 0.5)`), at most `count - 1` (also for
/// weight 0). Class `k` multiplies the steps by `sqrt(2)^(spread k)` (with `spread` 2 they
/// double each class and grow as `w^(-1/2)`) and drops `k` position levels, at most
/// `max_refine`. Classes above the coarsest one used are left out (at
/// least 2 remain), and the refinement goes no deeper than the largest drop used: levels every
/// Gaussian codes cost less in the octree.
///
/// Measured against classes a factor sqrt(2) apart (`w * sqrt(2)^(2j - 1) <= reference`): 2.4%
/// to 2.9% smaller at equal PSNR on guitar and 3% to 4% on biker, the class symbols costing
/// about a bit less a Gaussian.
pub fn classes(weights: &[f32], reference: f32, (count, spread): (u8, u8), max_refine: u8) -> ImportanceClasses {
    let thresholds: Vec<f32> = (1..i32::from(count)).map(|j| sqrt2_power(4 * j - 3)).collect();
    let of: Vec<u8> =
        weights.iter().map(|&w| thresholds.iter().filter(|&&t| w * t <= reference).count() as u8).collect();
    let used = of.iter().max().map_or(2, |&k| (k + 1).max(2));
    let refine = (used - 1).min(max_refine);
    ImportanceClasses {
        refine,
        factors: (0..i32::from(used)).map(|k| sqrt2_power(i32::from(spread) * k)).collect(),
        drops: (0..used).map(|k| k.min(refine)).collect(),
        of,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_views_surround_the_center_at_the_scene_scale() {
        let context = StreamContext { center: [1.0, 2.0, 3.0], scale: 4.0, background: [0.0; 3] };
        let cams = cameras(&context, Vec3::NEG_Y, 64).unwrap();
        assert_eq!(cams.len(), 57);
        let mean = cams.iter().map(|c| c.center()).sum::<Vec3>() / 57.0;
        // The ring on the horizon and the upper half: the mean is above the center (-y).
        assert!((mean.x - 1.0).abs() < 1e-5 && (mean.z - 3.0).abs() < 1e-5 && mean.y < 2.0 - 1.0, "{mean}");
        assert!(cams.iter().all(|c| c.center().y <= 2.0 + 1e-5), "a view from below");
        assert!(cameras(&context, Vec3::ZERO, 64).is_err());
        for c in &cams {
            assert!((c.center().distance(Vec3::new(1.0, 2.0, 3.0)) - 4.0).abs() < 1e-5);
            let ahead = c.world_to_camera(Vec3::new(1.0, 2.0, 3.0));
            assert!(ahead.x.abs() < 1e-4 && ahead.y.abs() < 1e-4 && ahead.z > 3.99, "{ahead}");
        }
    }

    #[test]
    fn each_class_holds_a_factor_4_of_weight() {
        // Reference (90th percentile of 10 weights: the 9th smallest, index 8) is 8.
        let weights = [8.0, 9.0, 8.0, 5.7, 5.6, 2.9, 2.8, 0.004, 0.0, 8.0];
        assert_eq!(reference(&weights), 8.0);
        assert_eq!(reference(&[]), 0.0);
        let c = classes(&weights, 8.0, (7, 2), 6);
        // Class 1 from a ratio of 2^0.5 (8 / 5.7 = 1.40 is below, 8 / 5.6 = 1.43 above), class 2
        // from 2^2.5 = 5.66 (8 / 2.9 = 2.76 and 8 / 2.8 = 2.86 are still class 1), 2000 (above
        // 2^10.5 = 1448) and 0 in the last class (6).
        assert_eq!(c.of, vec![0, 0, 0, 0, 1, 1, 1, 6, 6, 0]);
        assert_eq!(c.drops, vec![0, 1, 2, 3, 4, 5, 6]);
        assert_eq!(c.factors, vec![1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0]);
        assert_eq!(classes(&weights, 8.0, (7, 2), 2).drops, vec![0, 1, 2, 2, 2, 2, 2]);
        let three = classes(&weights, 8.0, (3, 2), 6);
        assert_eq!(three.of, vec![0, 0, 0, 0, 1, 1, 1, 2, 2, 0]);
        assert_eq!((three.refine, three.drops), (2, vec![0, 1, 2]));
        // Without the faintest two, classes 2 to 6 are empty: left out, and the refinement
        // stops at class 1's one level.
        let bright = classes(&weights[..7], 8.0, (7, 2), 6);
        assert_eq!((bright.factors.len(), bright.refine, bright.drops.clone()), (2, 1, vec![0, 1]));
        // Every Gaussian in class 0: still two classes (SPEC.md 6.5), one level refined.
        let flat = classes(&[8.0; 5], 8.0, (7, 2), 6);
        assert_eq!((flat.factors.len(), flat.refine), (2, 1));
    }
}

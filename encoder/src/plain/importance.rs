//! How much each Gaussian shows, for importance classes (SPEC.md section 6.5): its blending
//! weight summed over the pixels of views from all around the model, and from it a class per
//! Gaussian, each class a factor 2 coarser than the one before. A value's error shows in
//! proportion to that weight, so steps shrinking as its inverse square root minimize the
//! weighted squared error for the bytes (measured: summing over the views codes guitar about
//! 2% smaller at equal PSNR than taking each Gaussian's largest view).
//!
//! The views look at the scene's center from directions spread over the whole sphere (the
//! points on a grid cube's surface), so that no way round is favoured, and they need no
//! trigonometry: with `+ - * / sqrt` only, the classes, and so the stream, are the same on every
//! machine. The classes must hold on any view a user may take ([`class_cameras`]: from above the
//! horizon alone, guitar's default lost 7 to 10 dB on an orbit from below), and so must pruning
//! (`--prune-faint`), whose costs also come from views closer in ([`Importance::prune_costs`]).
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
/// Width and height of the other views pruning holds on: a quarter of the pixels, each view's
/// share measured against its own pixel count. With these, guitar's 124 views take about as
/// long as its 57 class views of [`VIEW_SIZE`] alone did.
pub const OTHER_VIEW_SIZE: u32 = 256;
/// Most pixels an import's [`Importance`] renders, whatever the up direction (the 98 directions at
/// [`VIEW_SIZE`], the 26 closer ones at [`OTHER_VIEW_SIZE`]): what bounds an import's work.
/// With a capture's views (`--views`) it renders at most [`MAX_CAPTURE_VIEWS`] more of at most
/// [`VIEW_SIZE`] squared.
pub const MAX_RENDERED_PIXELS: u64 =
    98 * (VIEW_SIZE as u64 * VIEW_SIZE as u64) + 26 * (OTHER_VIEW_SIZE as u64 * OTHER_VIEW_SIZE as u64);
/// Most classes: 0 (the reference) to 6 (steps 64 times coarser, positions 6 levels coarser;
/// classes that far down code guitar about 1.6% smaller at equal PSNR at quality 10 than
/// stopping at 16 times).
pub const MAX_CLASSES: u8 = 7;
/// The weight that class 0 starts at: this quantile (in percent) of all the weights.
const REFERENCE_PERCENTILE: usize = 90;

/// The unit directions from the center of an `n` x `n` x `n` grid of points (`n` odd) to the
/// points on its surface. With `n` = 5, 98 directions spread over the sphere about evenly
/// (within a factor 2 of each other in angle). More directions than a cube's 26 show more of
/// what occludes what: on biker, 57 views on or above the horizon code about 6% smaller at
/// equal PSNR than 17 (guitar 1-2%); 121 views (a 7 x 7 x 7 grid) gain nothing more.
fn directions(n: i8) -> Vec<Vec3> {
    let h = n / 2;
    let mut out = Vec::new();
    for x in -h..=h {
        for y in -h..=h {
            for z in -h..=h {
                if x.abs().max(y.abs()).max(z.abs()) == h {
                    out.push(Vec3::new(f32::from(x), f32::from(y), f32::from(z)).normalize());
                }
            }
        }
    }
    out
}

/// Cameras of `size` pixels and a 60-degree field of view at the scene's scale from its
/// center, looking at it from those of the 98 [`directions`] on or above the horizon of `up`
/// (57 when `up` is an axis): where a viewer walks around a scene most.
fn upper_cameras(context: &StreamContext, up: Vec3, size: u32) -> Result<Vec<Camera>, CameraError> {
    ring_cameras(context, up, size, (&directions(5), 1.0), |d| d.dot(up) >= -1e-6)
}

/// The views the classes' weights come from, which the refits ([`crate::plain::colour_refit`],
/// [`crate::plain::shape_refit`]) also fit the decoded model to: [`upper_cameras`] of
/// [`VIEW_SIZE`] and the rest of the sphere ([`below_cameras`]), each of those counting as a view
/// of [`VIEW_SIZE`] ([`Importance::of_views`]).
///
/// Weights from the upper views alone gave a Gaussian seen only from below the coarsest class:
/// guitar's default (level 2, quality 10) scored 56.75 dB on the orbit 20 degrees above the
/// horizon and 47.22 dB on one 35 degrees below, where uniform steps lose 0.15 dB. Refits fitted
/// on the upper views alone let such a Gaussian go wherever that helped them (level 4 from below:
/// guitar q9 39.73 dB against 45.02 dB with these views, biker q11 26.39 against 43.69 dB).
pub fn class_cameras(context: &StreamContext, up: Vec3) -> Result<Vec<Camera>, CameraError> {
    let mut out = upper_cameras(context, up, VIEW_SIZE)?;
    out.extend(below_cameras(context, up)?);
    Ok(out)
}

/// Most views of a capture ([`capture_cameras`]) an import weighs.
pub const MAX_CAPTURE_VIEWS: usize = 64;

/// A capture's own cameras as importance views, besides [`class_cameras`] (a model trained on a
/// capture is mostly seen from where it was taken, which for a scene shot from the front is a
/// small part of the sphere): at most [`MAX_CAPTURE_VIEWS`] of them, spread over the list, each
/// resized to [`VIEW_SIZE`] pixels on its longer side (its weights then count as a view of that
/// size, [`Importance::of_views`]).
pub fn capture_cameras(cameras: &[Camera]) -> Result<Vec<Camera>, CameraError> {
    let kept = cameras.len().min(MAX_CAPTURE_VIEWS);
    (0..kept)
        .map(|k| {
            let c = &cameras[k * cameras.len() / kept];
            let longer = c.width.max(c.height);
            // Rounded to the nearest pixel, at least one.
            let side =
                |s: u32| ((u64::from(s) * u64::from(VIEW_SIZE) + u64::from(longer) / 2) / u64::from(longer)).max(1);
            c.resized(side(c.width) as u32, side(c.height) as u32)
        })
        .collect()
}

/// The views that pruning must hold on besides [`class_cameras`], of [`OTHER_VIEW_SIZE`]
/// pixels: the 26 directions of a 3 x 3 x 3 grid at half the distance, closer in, where the
/// model's middle fills twice the width. (Counted in the classes' weights too, they coded guitar
/// about 0.5% larger at equal PSNR on the orbit and alike from below.)
pub fn closer_cameras(context: &StreamContext, up: Vec3) -> Result<Vec<Camera>, CameraError> {
    ring_cameras(context, up, OTHER_VIEW_SIZE, (&directions(3), 0.5), |_| true)
}

/// The 41 of the 98 [`directions`] below the horizon of `up`, at the distance of
/// [`upper_cameras`], of [`OTHER_VIEW_SIZE`] pixels.
fn below_cameras(context: &StreamContext, up: Vec3) -> Result<Vec<Camera>, CameraError> {
    ring_cameras(context, up, OTHER_VIEW_SIZE, (&directions(5), 1.0), |d| d.dot(up) < -1e-6)
}

/// Cameras looking at the scene's center from `distance` times its scale along each of
/// `directions` that `keep` accepts.
fn ring_cameras(
    context: &StreamContext,
    up: Vec3,
    size: u32,
    (directions, distance): (&[Vec3], f32),
    keep: impl Fn(Vec3) -> bool,
) -> Result<Vec<Camera>, CameraError> {
    let up = up.normalize_or_zero();
    if up == Vec3::ZERO {
        return Err(CameraError::NonFinitePose);
    }
    // 1 / tan(30 degrees) = sqrt(3).
    let f = size as f32 / 2.0 * 3f32.sqrt();
    let intrinsics =
        Intrinsics { width: size, height: size, fx: f, fy: f, cx: size as f32 / 2.0, cy: size as f32 / 2.0 };
    let center = Vec3::from(context.center);
    (directions.iter().copied())
        .filter(|&d| keep(d))
        .map(|d| {
            let camera_up = if d.cross(up).length_squared() < 1e-6 { up.any_orthonormal_vector() } else { up };
            Camera::look_at(intrinsics, center + d * (distance * context.scale), center, camera_up)
        })
        .collect()
}

/// What the importance views measure of each Gaussian.
#[derive(Debug, Clone)]
pub struct Importance {
    /// Its blending weight summed over the class views (pixels' worth of colour, each view's
    /// scaled to the first's pixel count): what the classes and the order of dropping for a
    /// target size come from.
    pub weights: Vec<f32>,
    /// What dropping it costs in the view that loses most ([`prune_costs`]).
    pub prune_costs: Vec<f32>,
}

impl Importance {
    /// The weights from `class_views` (each counting as a view of the first one's size: a view of
    /// a quarter of its pixels sees each Gaussian at a quarter of the weight), the pruning costs
    /// from those and `other_views`.
    pub fn of_views(g: &Gaussians, views: (&[Camera], &[Camera]), options: &RenderOptions) -> Self {
        Self::of_views_reporting(g, views, options, &|| {})
    }

    /// [`of_views`](Self::of_views), calling `done` after each view (a progress bar's tick).
    pub fn of_views_reporting(
        g: &Gaussians,
        (class_views, other_views): (&[Camera], &[Camera]),
        options: &RenderOptions,
        done: &(dyn Fn() + Sync),
    ) -> Self {
        let all: Vec<&Camera> = class_views.iter().chain(other_views).collect();
        let per_view: Vec<Vec<f32>> = all
            .par_iter()
            .map(|camera| {
                let weights = view_weights(g, camera, options);
                done();
                weights
            })
            .collect();
        let pixels: Vec<f32> = all.iter().map(|c| c.width as f32 * c.height as f32).collect();
        let full = pixels.first().copied().unwrap_or(1.0);
        let scales: Vec<f32> = pixels[..class_views.len()].iter().map(|&p| full / p).collect();
        let weights = sum_in_order(&per_view[..class_views.len()], &scales, g.len());
        Self { prune_costs: prune_costs(&per_view, &pixels), weights }
    }
}

/// Each Gaussian's blending weight, summed over every pixel of `camera`.
fn view_weights(g: &Gaussians, camera: &Camera, options: &RenderOptions) -> Vec<f32> {
    let splats = visible_splats(g, camera, &options.projection);
    let bins = tiles::bin(&splats, Window::full(camera));
    splat_weights(&bins, &splats, options, g.len())
}

/// Per-view weights, each view's times its scale, summed in view order, so that the sums do not
/// depend on threads.
fn sum_in_order(per_view: &[Vec<f32>], scales: &[f32], gaussians: usize) -> Vec<f32> {
    let mut total = vec![0.0f32; gaussians];
    for (view, &scale) in per_view.iter().zip(scales) {
        total.iter_mut().zip(view).for_each(|(t, w)| *t += scale * w);
    }
    total
}

/// What pruning each Gaussian costs, so that no view loses much, whichever Gaussians go: with
/// the Gaussians ordered by their weight summed over all views (faintest first, then by index),
/// the cost of the `k`th is the largest share of a view's pixels that the first `k` together
/// cover in that view (their weights summed, over its pixel count). Pruning every Gaussian whose
/// cost is at most a budget drops a prefix of that order, and leaves every view at least
/// `1 - budget` of its pixels' colour. A threshold on each Gaussian's own weight does not: many
/// faint Gaussians together (fine texture, or a side only some views show) can be much of what
/// a view shows (guitar at quality 8, at about equal bytes: an orbit from 35 degrees below gets
/// 43.68 dB with these costs, 38.81 dB with such a threshold).
fn prune_costs(per_view: &[Vec<f32>], pixels: &[f32]) -> Vec<f32> {
    let gaussians = per_view.first().map_or(0, Vec::len);
    // Summed as weights, not as shares: ordering by shares (the closer views' 256x256 pixels
    // counting 4 times) coded guitar 1.7 dB lower at quality 10 for the same bytes.
    let totals = sum_in_order(per_view, &vec![1.0; per_view.len()], gaussians);
    let mut order: Vec<usize> = (0..gaussians).collect();
    order.sort_by(|&a, &b| totals[a].total_cmp(&totals[b]).then(a.cmp(&b)));
    // The largest share over views after each prefix: a maximum, the same in any view order.
    let worst = per_view
        .par_iter()
        .zip(pixels)
        .map(|(view, &pixels)| {
            let mut covered = 0.0f32;
            order
                .iter()
                .map(|&i| {
                    covered += view[i];
                    covered / pixels
                })
                .collect::<Vec<f32>>()
        })
        .reduce(|| vec![0.0; gaussians], |a, b| a.iter().zip(&b).map(|(x, y)| x.max(*y)).collect());
    let mut costs = vec![0.0f32; gaussians];
    order.iter().zip(&worst).for_each(|(&i, &c)| costs[i] = c);
    costs
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
        let cams = upper_cameras(&context, Vec3::NEG_Y, 64).unwrap();
        assert_eq!(cams.len(), 57);
        let mean = cams.iter().map(|c| c.center()).sum::<Vec3>() / 57.0;
        // The ring on the horizon and the upper half: the mean is above the center (-y).
        assert!((mean.x - 1.0).abs() < 1e-5 && (mean.z - 3.0).abs() < 1e-5 && mean.y < 2.0 - 1.0, "{mean}");
        assert!(cams.iter().all(|c| c.center().y <= 2.0 + 1e-5), "a view from below");
        assert!(upper_cameras(&context, Vec3::ZERO, 64).is_err());
        for c in &cams {
            assert!((c.center().distance(Vec3::new(1.0, 2.0, 3.0)) - 4.0).abs() < 1e-5);
            let ahead = c.world_to_camera(Vec3::new(1.0, 2.0, 3.0));
            assert!(ahead.x.abs() < 1e-4 && ahead.y.abs() < 1e-4 && ahead.z > 3.99, "{ahead}");
        }
    }

    #[test]
    fn classes_and_refits_see_the_whole_sphere_and_pruning_closer_in() {
        let context = StreamContext { center: [1.0, 2.0, 3.0], scale: 2.0, background: [0.0; 3] };
        let up = Vec3::Z;
        let views = class_cameras(&context, up).unwrap();
        let height = |c: &Camera| (c.center() - Vec3::from(context.center)).dot(up);
        assert_eq!(views.len(), 57 + 41);
        assert!(views[..57].iter().all(|c| c.width == VIEW_SIZE && height(c) > -1e-3));
        assert!(views[57..].iter().all(|c| c.width == OTHER_VIEW_SIZE && height(c) < -1e-3));
        let distance = |c: &Camera| (c.center() - Vec3::from(context.center)).length();
        assert!(views.iter().all(|c| (distance(c) - 2.0).abs() < 1e-5));
        let closer = closer_cameras(&context, up).unwrap();
        assert_eq!(closer.len(), 26);
        assert!(closer.iter().all(|c| (distance(c) - 1.0).abs() < 1e-5 && c.width == OTHER_VIEW_SIZE));
    }

    #[test]
    fn a_pruning_cost_is_the_worst_view_share_of_the_faintest_first() {
        // Totals 0, 4, 2, 20: the order is 0, 2, 1, 3. View 0's shares after each: 0, 0.2, 0.3,
        // 1.3; view 1's: 0, 0, 0.3, 1.3 (pixels 10 each).
        let per_view = [vec![0.0, 1.0, 2.0, 10.0], vec![0.0, 3.0, 0.0, 10.0]];
        assert_eq!(prune_costs(&per_view, &[10.0, 10.0]), vec![0.0, 0.3, 0.2, 1.3]);
        // A view with fewer pixels loses a larger share of them.
        assert_eq!(prune_costs(&per_view, &[10.0, 5.0]), vec![0.0, 0.6, 0.2, 2.6]);
        assert!(prune_costs(&[], &[]).is_empty());
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

    #[test]
    fn a_capture_counts_at_most_64_views_at_the_class_views_size() {
        let intrinsics = Intrinsics { width: 1008, height: 756, fx: 800.0, fy: 800.0, cx: 504.0, cy: 378.0 };
        let eye = |k: usize| Vec3::new(k as f32, 0.0, -5.0);
        let capture: Vec<Camera> =
            (0..100).map(|k| Camera::look_at(intrinsics, eye(k), Vec3::ZERO, Vec3::NEG_Y).unwrap()).collect();
        let views = capture_cameras(&capture).unwrap();
        assert_eq!(views.len(), MAX_CAPTURE_VIEWS);
        // Spread over the list, from its first view on.
        assert_eq!(views[0].center(), capture[0].center());
        assert!(views[63].center().distance(capture[98].center()) < 1e-5, "{}", views[63].center());
        for v in &views {
            assert_eq!((v.width, v.height), (VIEW_SIZE, 384));
            assert!((v.fx - 800.0 * 512.0 / 1008.0).abs() < 1e-3, "{}", v.fx);
        }
        // A short list is kept whole; a portrait view is 512 high.
        let portrait = Intrinsics { width: 300, height: 400, fx: 300.0, fy: 300.0, cx: 150.0, cy: 200.0 };
        let few = [Camera::look_at(portrait, eye(0), Vec3::ZERO, Vec3::NEG_Y).unwrap()];
        let views = capture_cameras(&few).unwrap();
        assert_eq!((views.len(), views[0].width, views[0].height), (1, 384, VIEW_SIZE));
        assert!(capture_cameras(&[]).unwrap().is_empty());
    }
}

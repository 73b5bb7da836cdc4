//! Projection of 3D Gaussians to screen-space ellipses (EWA splatting), and the sole visibility
//! gate of the rasterizer: a Gaussian that fails any test here is culled and can never touch a
//! pixel.
//!
//! Every guard is phrased positively (`if !(x > 0)` rather than `if x <= 0`) so that NaN fails
//! it: NaN compares false with everything. The 2x2 determinant and the conic's Cholesky factor
//! come from forms without subtraction, so needle-like footprints keep their digits at any
//! axis ratio. [`project_detail`] runs in f64: it is the reference, and the backward pass
//! differentiates its values. Rendering ([`Projector`]) computes the same footprint in f32
//! ([`project_f32`]; 1.1-1.3 times faster), falling back to f64 where f32 cannot decide.

use glam::{DMat3, DVec3};

use super::{project_f32, sh};
use pwgs_codec::portable_math::{exp_f64, ln_f32};
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;

/// Constants of the projection, as gsplat and the original 3DGS use them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectionSettings {
    /// Gaussians whose center is closer than this (camera z) are culled.
    pub near: f64,
    /// Screen-space low-pass added to the 2D covariance's diagonal, in pixels^2: every splat
    /// covers at least about a pixel, which keeps sub-pixel Gaussians from aliasing.
    pub blur: f64,
    /// Smallest alpha that counts; also sets the opacity-aware extent.
    pub alpha_min: f64,
}

impl Default for ProjectionSettings {
    fn default() -> Self {
        Self { near: 0.01, blur: 0.3, alpha_min: 1.0 / 255.0 }
    }
}

/// The EWA Jacobian clamps the view direction to 1.3x the field of view (gsplat's limit): far
/// outside the frustum the linearization is meaningless and would produce huge ellipses.
pub const JACOBIAN_FOV_LIMIT: f64 = 1.3;

/// Guard band: a center further outside the image than one image width (height) is culled;
/// closer ones are kept so large splats just off-screen still cover the edge.
pub const GUARD_BAND: f64 = 1.0;

/// Quaternions shorter than this have no reliable direction (zero, or denormal after decay).
pub const MIN_QUATERNION_NORM_SQUARED: f64 = 1e-16;

/// Everything the projection computes for one visible Gaussian; the backward pass reuses these
/// values instead of recomputing them differently.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectionDetail {
    /// Normalized quaternion (w, x, y, z) and its rotation matrix.
    pub quaternion: [f64; 4],
    pub rotation: DMat3,
    pub scale: DVec3,
    /// Mean in camera coordinates.
    pub mean_cam: DVec3,
    /// Whether the Jacobian's x / y view-direction was clamped (then its gradient is zero).
    pub clamped: [bool; 2],
    /// EWA Jacobian rows (2x3).
    pub jacobian: [DVec3; 2],
    /// 2D covariance after the blur: (xx, xy, yy).
    pub cov2d: [f64; 3],
    /// Its determinant, from a sum of non-negative terms (see [`project_detail`]).
    pub det: f64,
    /// Unnormalized viewing direction (mean - camera center) and its length.
    pub view_dir: DVec3,
    /// Color before the clamp at zero.
    pub color_unclamped: [f64; 3],
    /// sigmoid(opacity logit).
    pub opacity: f64,
}

/// A visible Gaussian, as blending needs it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Splat {
    /// Pixel coordinates of the center (pixel centers at +0.5).
    pub mean: [f32; 2],
    /// Inverse 2D covariance (xx, xy, yy): sigma = 0.5 (a dx^2 + c dy^2) + b dx dy.
    pub conic: [f32; 3],
    /// Cholesky factor (l11, l21, l22) of the conic: sigma = 0.5 ((l11 dx + l21 dy)^2 +
    /// (l22 dy)^2). Blending evaluates this form: it is never negative and, unlike the expanded
    /// quadratic form, does not lose digits to cancellation for needle-like splats in f32.
    pub cholesky: [f32; 3],
    pub opacity: f32,
    pub color: [f32; 3],
    /// Camera-space z.
    pub depth: f32,
    /// Pixel range covered: x in [x0, x1), y in [y0, y1), clipped to the image.
    pub bbox: [u32; 4],
    /// Index of the Gaussian in the input set.
    pub index: u32,
}

/// Numerically stable logistic function.
pub fn sigmoid(x: f64) -> f64 {
    if x >= 0.0 {
        1.0 / (1.0 + exp_f64(-x))
    } else {
        let e = exp_f64(x);
        e / (1.0 + e)
    }
}

/// The values in f64, or `None` if any is NaN or infinite.
fn finite<const N: usize>(v: [f32; N]) -> Option<[f64; N]> {
    v.iter().all(|x| x.is_finite()).then(|| v.map(f64::from))
}

/// Rotation matrix of a normalized quaternion (w, x, y, z).
pub fn rotation_matrix(q: [f64; 4]) -> DMat3 {
    let [w, x, y, z] = q;
    DMat3::from_cols(
        DVec3::new(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y)),
        DVec3::new(2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x)),
        DVec3::new(2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)),
    )
}

/// Projects Gaussian `i`, or returns `None` when it is culled: a non-finite parameter, a
/// degenerate quaternion or covariance, behind the near plane, outside the guard band, too
/// transparent, or not overlapping the image.
pub fn project_detail(
    g: &Gaussians,
    i: usize,
    camera: &Camera,
    settings: &ProjectionSettings,
) -> Option<ProjectionDetail> {
    let mean = finite(g.means[i])?;
    let log_scale = finite(g.log_scales[i])?;
    let q = finite(g.rotations[i])?;
    let logit = g.opacity_logits[i] as f64;
    let coeffs = g.sh_of(i);
    if !(logit.is_finite() && coeffs.iter().all(|c| c.is_finite())) {
        return None;
    }
    let opacity = sigmoid(logit);
    if !(opacity >= settings.alpha_min) {
        return None;
    }
    let norm2 = q.iter().map(|v| v * v).sum::<f64>();
    if !(norm2 >= MIN_QUATERNION_NORM_SQUARED) {
        return None;
    }
    let inv_norm = 1.0 / norm2.sqrt();
    let quaternion = [q[0] * inv_norm, q[1] * inv_norm, q[2] * inv_norm, q[3] * inv_norm];

    let mean = DVec3::from(mean);
    let w2c = camera.rotation.as_dmat3();
    let mean_cam = w2c * mean + camera.translation.as_dvec3();
    if !(mean_cam.z >= settings.near) {
        return None;
    }
    let (fx, fy) = (camera.fx as f64, camera.fy as f64);
    let (cx, cy) = (camera.cx as f64, camera.cy as f64);
    let (w, h) = (camera.width as f64, camera.height as f64);
    let (tan_x, tan_y) = (mean_cam.x / mean_cam.z, mean_cam.y / mean_cam.z);
    // Tangents of the image edges seen from the camera center.
    let (left, right) = (cx / fx, (w - cx) / fx);
    let (top, bottom) = (cy / fy, (h - cy) / fy);
    let (band_x, band_y) = (GUARD_BAND * w / fx, GUARD_BAND * h / fy);
    if !(tan_x >= -left - band_x && tan_x <= right + band_x && tan_y >= -top - band_y && tan_y <= bottom + band_y) {
        return None;
    }

    let rotation = rotation_matrix(quaternion);
    let scale = DVec3::new(exp_f64(log_scale[0]), exp_f64(log_scale[1]), exp_f64(log_scale[2]));
    let m = rotation * DMat3::from_diagonal(scale);

    let (slack_x, slack_y) =
        ((JACOBIAN_FOV_LIMIT - 1.0) * (left + right) / 2.0, (JACOBIAN_FOV_LIMIT - 1.0) * (top + bottom) / 2.0);
    let clamped_tan_x = tan_x.clamp(-left - slack_x, right + slack_x);
    let clamped_tan_y = tan_y.clamp(-top - slack_y, bottom + slack_y);
    let clamped = [clamped_tan_x != tan_x, clamped_tan_y != tan_y];
    let z = mean_cam.z;
    let jacobian = [DVec3::new(fx / z, 0.0, -fx * clamped_tan_x / z), DVec3::new(0.0, fy / z, -fy * clamped_tan_y / z)];
    // The 2D covariance is B B^T + blur I with B = J W R S (2x3, rows b0 and b1), so its
    // determinant is |b0 x b1|^2 + blur (|b0|^2 + |b1|^2) + blur^2 (Lagrange's identity): a
    // sum of non-negative terms, where `a c - b^2` cancels to noise once the footprint's axis
    // ratio passes about 1e8 even in f64.
    let wm = w2c * m;
    let b0 = wm.transpose() * jacobian[0];
    let b1 = wm.transpose() * jacobian[1];
    let blur = settings.blur;
    let (n0, n1) = (b0.length_squared(), b1.length_squared());
    let cov2d = [n0 + blur, b0.dot(b1), n1 + blur];
    let det = b0.cross(b1).length_squared() + blur * (n0 + n1) + blur * blur;
    if !(det > 0.0 && det.is_finite() && cov2d.iter().all(|v| v.is_finite())) {
        return None;
    }

    let view_dir = mean - camera.center().as_dvec3();
    let length = view_dir.length();
    if !(length > 0.0) {
        return None;
    }
    let color_unclamped = sh::unclamped_color(g.sh_degree, coeffs, (view_dir / length).to_array());
    Some(ProjectionDetail {
        quaternion,
        rotation,
        scale,
        mean_cam,
        clamped,
        jacobian,
        cov2d,
        det,
        view_dir,
        color_unclamped,
        opacity,
    })
}

/// Projects Gaussians into [`Splat`]s for one camera, with the constants they share computed
/// once.
pub struct Projector<'a> {
    camera: &'a Camera,
    settings: ProjectionSettings,
    view: project_f32::View,
}

impl<'a> Projector<'a> {
    pub fn new(camera: &'a Camera, settings: &ProjectionSettings) -> Self {
        Self { camera, settings: *settings, view: project_f32::View::new(camera, settings) }
    }

    /// Gaussian `i`'s splat with its opacity-aware pixel extent, or `None` when it is culled
    /// (see [`project_detail`]) or covers no pixel of the image. The footprint is computed in
    /// f32 ([`project_f32`], as GPU renderers do: a splat keeps f32 values only); a Gaussian
    /// whose footprint f32 cannot decide is projected in f64 ([`project_precise`]) instead.
    pub fn project(&self, g: &Gaussians, i: usize) -> Option<Splat> {
        match project_f32::footprint(g, i, &self.view) {
            project_f32::Outcome::Footprint(f) => splat_of(&f, i, self.camera, &self.settings),
            project_f32::Outcome::Culled => None,
            project_f32::Outcome::Imprecise => project_precise(g, i, self.camera, &self.settings),
        }
    }
}

/// [`Projector::project`] computed in f64 throughout: the reference the f32 projection is tested against.
pub fn project_precise(g: &Gaussians, i: usize, camera: &Camera, settings: &ProjectionSettings) -> Option<Splat> {
    let d = project_detail(g, i, camera, settings)?;
    let footprint = Footprint {
        mean: [
            camera.fx as f64 * d.mean_cam.x / d.mean_cam.z + camera.cx as f64,
            camera.fy as f64 * d.mean_cam.y / d.mean_cam.z + camera.cy as f64,
        ],
        cov2d: d.cov2d,
        det: d.det,
        opacity: d.opacity,
        color_unclamped: d.color_unclamped,
        depth: d.mean_cam.z,
    };
    splat_of(&footprint, i, camera, settings)
}

/// A visible Gaussian's screen-space ellipse before its pixel box: what both projections
/// compute and [`splat_of`] turns into a [`Splat`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Pixel coordinates of the center.
    pub mean: [f64; 2],
    /// 2D covariance after the blur (xx, xy, yy) and its determinant (positive, finite).
    pub cov2d: [f64; 3],
    pub det: f64,
    pub opacity: f64,
    pub color_unclamped: [f64; 3],
    /// Camera-space z.
    pub depth: f64,
}

/// The splat of Gaussian `index`'s footprint, or `None` when its box covers no pixel.
fn splat_of(f: &Footprint, index: usize, camera: &Camera, settings: &ProjectionSettings) -> Option<Splat> {
    let [a, b, c] = f.cov2d;
    let det = f.det;
    // alpha = opacity * exp(-sigma) >= alpha_min  <=>  sigma <= ln(opacity / alpha_min): the
    // ellipse of Mahalanobis radius sqrt(2 ln(opacity / alpha_min)), whose bounding box has
    // half-sizes radius * sqrt(cov_xx) and radius * sqrt(cov_yy).
    // The box needs no more than f32's digits (a splat keeps f32 values only).
    let radius = (2.0 * ln_f32((f.opacity / settings.alpha_min) as f32) as f64).max(0.0).sqrt();
    let (ex, ey) = (radius * a.sqrt(), radius * c.sqrt());
    // Pixel i is covered when its center i + 0.5 lies within [mean - e, mean + e].
    let range = |center: f64, extent: f64, size: u32| -> Option<[u32; 2]> {
        let lo = (center - extent - 0.5).ceil().max(0.0);
        let hi = (center + extent - 0.5).floor().min(size as f64 - 1.0);
        (lo <= hi).then_some([lo as u32, hi as u32 + 1])
    };
    let [x0, x1] = range(f.mean[0], ex, camera.width)?;
    let [y0, y1] = range(f.mean[1], ey, camera.height)?;
    let color = f.color_unclamped.map(|v| v.max(0.0) as f32);
    let inv_det = 1.0 / det;
    let conic = [c * inv_det, -b * inv_det, a * inv_det];
    let l11 = conic[0].sqrt();
    let l21 = conic[1] / l11;
    // conic_yy - l21^2 = (a c - b^2) / (c det) = 1 / c, without the subtraction.
    let l22 = (1.0 / c).sqrt();
    Some(Splat {
        mean: f.mean.map(|v| v as f32),
        conic: conic.map(|v| v as f32),
        cholesky: [l11 as f32, l21 as f32, l22 as f32],
        opacity: f.opacity as f32,
        color,
        depth: f.depth as f32,
        bbox: [x0, x1, y0, y1],
        index: index as u32,
    })
}

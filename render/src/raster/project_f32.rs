//! The projection's fast path, in f32: what
//! [`Projector::project`](super::project::Projector::project) renders with.
//!
//! A splat keeps f32 values only, and the 2D covariance's determinant comes from a sum of
//! non-negative terms (see [`project_detail`](super::project::project_detail)), so f32 loses
//! nothing there that the splat would keep; GPU renderers project in f32 for the same reason.
//! Where f32 cannot decide what f64 would (an intermediate overflows or underflows to zero),
//! the Gaussian goes to the f64 projection instead. The guards are phrased positively so that
//! NaN fails them, as in the f64 projection.

use glam::{DMat3, DVec3, Mat3, Quat, Vec3};

use super::project::{Footprint, GUARD_BAND, JACOBIAN_FOV_LIMIT, MIN_QUATERNION_NORM_SQUARED, ProjectionSettings};
use super::sh;
use pwgs_codec::portable_math::exp_f32;
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;

/// What the f32 projection found for one Gaussian.
pub enum Outcome {
    Footprint(Footprint),
    Culled,
    /// An f32 intermediate overflowed or underflowed where f64 might not: project in f64.
    Imprecise,
}

/// Numerically stable logistic function in f32.
fn sigmoid(x: f32) -> f32 {
    if x >= 0.0 {
        1.0 / (1.0 + exp_f32(-x))
    } else {
        let e = exp_f32(x);
        e / (1.0 + e)
    }
}

/// A camera's constants in f32, computed once for all its Gaussians.
pub struct View {
    rotation: Mat3,
    /// The pose in f64 too: see [`footprint`].
    rotation_f64: DMat3,
    translation: DVec3,
    center: DVec3,
    focal: [f32; 2],
    principal: [f32; 2],
    /// Tangents of the image edges seen from the camera center (left, right, top, bottom).
    edges: [f32; 4],
    /// The guard band in tangents (x, y), and the Jacobian's clamp beyond the edges (x, y).
    band: [f32; 2],
    slack: [f32; 2],
    near: f32,
    alpha_min: f32,
    blur: f32,
}

impl View {
    pub fn new(camera: &Camera, settings: &ProjectionSettings) -> Self {
        let (fx, fy, cx, cy) = (camera.fx, camera.fy, camera.cx, camera.cy);
        let (w, h) = (camera.width as f32, camera.height as f32);
        let edges = [cx / fx, (w - cx) / fx, cy / fy, (h - cy) / fy];
        let band = GUARD_BAND as f32;
        let limit = JACOBIAN_FOV_LIMIT as f32 - 1.0;
        Self {
            rotation: camera.rotation,
            rotation_f64: camera.rotation.as_dmat3(),
            translation: camera.translation.as_dvec3(),
            center: camera.center().as_dvec3(),
            focal: [fx, fy],
            principal: [cx, cy],
            edges,
            band: [band * w / fx, band * h / fy],
            slack: [limit * (edges[0] + edges[1]) / 2.0, limit * (edges[2] + edges[3]) / 2.0],
            near: settings.near as f32,
            alpha_min: settings.alpha_min as f32,
            blur: settings.blur as f32,
        }
    }
}

/// Gaussian `i`'s footprint in f32, with the same culling as the f64 projection.
pub fn footprint(g: &Gaussians, i: usize, view: &View) -> Outcome {
    use Outcome::{Culled, Imprecise};
    let (mean, log_scale, q) = (g.means[i], g.log_scales[i], g.rotations[i]);
    let logit = g.opacity_logits[i];
    let coeffs = g.sh_of(i);
    let finite = mean.iter().chain(&log_scale).chain(&q).all(|v| v.is_finite());
    if !(finite && logit.is_finite() && coeffs.iter().all(|c| c.is_finite())) {
        return Culled;
    }
    let opacity = sigmoid(logit);
    if !(opacity >= view.alpha_min) {
        return Culled;
    }
    let norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if !norm2.is_finite() {
        return Imprecise;
    }
    if !(norm2 >= MIN_QUATERNION_NORM_SQUARED as f32) {
        return Culled;
    }
    let inv_norm = 1.0 / norm2.sqrt();

    // The camera-space mean and the viewing direction subtract the camera's position from the
    // mean's: in f64, so that a scene far from the origin keeps the digits its f32 positions
    // have (18 operations of a Gaussian's few hundred).
    let mean = DVec3::from(mean.map(f64::from));
    let mean_cam = (view.rotation_f64 * mean + view.translation).as_vec3();
    if !mean_cam.is_finite() {
        return Imprecise;
    }
    let z = mean_cam.z;
    if !(z >= view.near) {
        return Culled;
    }
    let inv_z = 1.0 / z;
    let (tan_x, tan_y) = (mean_cam.x * inv_z, mean_cam.y * inv_z);
    let [left, right, top, bottom] = view.edges;
    let [band_x, band_y] = view.band;
    if !(tan_x >= -left - band_x && tan_x <= right + band_x && tan_y >= -top - band_y && tan_y <= bottom + band_y) {
        return Culled;
    }

    let scale = Vec3::from(log_scale.map(exp_f32));
    if !scale.is_finite() {
        return Imprecise;
    }
    let [qw, qx, qy, qz] = q.map(|v| v * inv_norm);
    let m = Mat3::from_quat(Quat::from_xyzw(qx, qy, qz, qw)) * Mat3::from_diagonal(scale);
    let [slack_x, slack_y] = view.slack;
    let clamped_tan_x = tan_x.clamp(-left - slack_x, right + slack_x);
    let clamped_tan_y = tan_y.clamp(-top - slack_y, bottom + slack_y);
    let [fx, fy] = view.focal;
    let (fx_z, fy_z) = (fx * inv_z, fy * inv_z);
    let j0 = Vec3::new(fx_z, 0.0, -fx_z * clamped_tan_x);
    let j1 = Vec3::new(0.0, fy_z, -fy_z * clamped_tan_y);
    let wm_t = (view.rotation * m).transpose();
    let (b0, b1) = (wm_t * j0, wm_t * j1);
    let blur = view.blur;
    let (n0, n1) = (b0.length_squared(), b1.length_squared());
    let cov2d = [n0 + blur, b0.dot(b1), n1 + blur];
    let det = b0.cross(b1).length_squared() + blur * (n0 + n1) + blur * blur;
    if !(det > 0.0 && det.is_finite() && cov2d.iter().all(|v| v.is_finite())) {
        return Imprecise;
    }

    let view_dir = mean - view.center;
    let length = view_dir.length();
    if !(length > 0.0) {
        return Culled;
    }
    let dir = (view_dir / length).to_array();
    let [cx, cy] = view.principal;
    Outcome::Footprint(Footprint {
        mean: [(fx * tan_x + cx) as f64, (fy * tan_y + cy) as f64],
        cov2d: cov2d.map(f64::from),
        det: det as f64,
        opacity: opacity as f64,
        color_unclamped: sh::unclamped_color(g.sh_degree, coeffs, dir),
        depth: z as f64,
    })
}

//! Backward of the projection: from a splat's screen-space gradient to the gradients of its
//! Gaussian's parameters (mean, log-scales, unnormalized quaternion, opacity logit, SH).
//!
//! The forward values come from the decoder's own [`project_detail`], so the chain rule is
//! applied to exactly what was rendered. Chain, in order: color -> SH coefficients and view
//! direction -> mean; conic -> 2D covariance -> (EWA Jacobian, camera-space covariance) ->
//! camera-space mean and world covariance -> rotation and scales -> quaternion (through its
//! normalization) and log-scales.

use glam::{DMat3, DVec3};
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_render::raster::project::{ProjectionSettings, project_detail};
use pwgs_render::raster::sh;

use super::blend::SplatGrad;
use super::sh::basis_gradient;

/// Gradients of one Gaussian's parameters.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GaussianGrad {
    pub mean: [f64; 3],
    pub log_scale: [f64; 3],
    pub rotation: [f64; 4],
    pub opacity_logit: f64,
    /// [coefficient][rgb], `(degree + 1)^2 * 3` values.
    pub sh: Vec<f64>,
}

/// Symmetric 2x2 matrix (xx, xy, yy) times a general 2x3 matrix given by rows.
fn sym2_times(m: [f64; 3], rows: [DVec3; 2]) -> [DVec3; 2] {
    [rows[0] * m[0] + rows[1] * m[1], rows[0] * m[1] + rows[1] * m[2]]
}

/// Chains the screen-space gradient `v` of Gaussian `i` back to its parameters. Returns `None`
/// when the Gaussian is culled (then it has no gradient).
pub fn projection_backward(
    g: &Gaussians,
    i: usize,
    camera: &Camera,
    settings: &ProjectionSettings,
    v: &SplatGrad,
) -> Option<GaussianGrad> {
    let d = project_detail(g, i, camera, settings)?;
    let w2c = camera.rotation.as_dmat3();
    let (fx, fy) = (camera.fx as f64, camera.fy as f64);
    let DVec3 { x, y, z } = d.mean_cam;
    let mut v_mean_cam = DVec3::ZERO;

    // Screen-space center u = fx x / z + cx, v = fy y / z + cy.
    v_mean_cam.x += fx / z * v.mean[0];
    v_mean_cam.y += fy / z * v.mean[1];
    v_mean_cam.z -= (fx * x * v.mean[0] + fy * y * v.mean[1]) / (z * z);

    // Conic = inverse of the 2D covariance: dL/dCov = -C G C, with G the gradient with respect
    // to the symmetric matrix C (its off-diagonal entries each get half of the b gradient).
    let [a, b, c] = d.cov2d;
    let det = d.det;
    let conic = [c / det, -b / det, a / det];
    let gm = [v.conic[0], 0.5 * v.conic[1], v.conic[2]];
    // C G
    let cg = [
        [conic[0] * gm[0] + conic[1] * gm[1], conic[0] * gm[1] + conic[1] * gm[2]],
        [conic[1] * gm[0] + conic[2] * gm[1], conic[1] * gm[1] + conic[2] * gm[2]],
    ];
    // -(C G) C, symmetric: (xx, xy, yy).
    let v_cov2d = [
        -(cg[0][0] * conic[0] + cg[0][1] * conic[1]),
        -(cg[0][0] * conic[1] + cg[0][1] * conic[2]),
        -(cg[1][0] * conic[1] + cg[1][1] * conic[2]),
    ];

    // cov2d = J Sc J^T + blur: dL/dSc = J^T M J, dL/dJ = 2 M J Sc.
    let m = d.rotation * DMat3::from_diagonal(d.scale);
    let cov_world = m * m.transpose();
    let cov_cam = w2c * cov_world * w2c.transpose();
    let j = d.jacobian;
    let mj = sym2_times(v_cov2d, j);
    let v_cov_cam = outer(j[0], mj[0]) + outer(j[1], mj[1]);
    let v_j = [cov_cam * mj[0] * 2.0, cov_cam * mj[1] * 2.0];

    // J = [[fx/z, 0, -fx tx/z], [0, fy/z, -fy ty/z]] with tx = x/z unless clamped.
    let (z2, z3) = (z * z, z * z * z);
    v_mean_cam.z -= fx / z2 * v_j[0].x + fy / z2 * v_j[1].y;
    if d.clamped[0] {
        v_mean_cam.z += -j[0].z / z * v_j[0].z;
    } else {
        v_mean_cam.x -= fx / z2 * v_j[0].z;
        v_mean_cam.z += 2.0 * fx * x / z3 * v_j[0].z;
    }
    if d.clamped[1] {
        v_mean_cam.z += -j[1].z / z * v_j[1].z;
    } else {
        v_mean_cam.y -= fy / z2 * v_j[1].z;
        v_mean_cam.z += 2.0 * fy * y / z3 * v_j[1].z;
    }

    // Sc = W S W^T, camera-space mean = W mean + t.
    let v_cov_world = w2c.transpose() * v_cov_cam * w2c;
    let mut v_mean = w2c.transpose() * v_mean_cam;

    // S = M M^T with M = R diag(s): dL/dM = 2 dL/dS M (dL/dS is symmetric).
    let v_m = v_cov_world * m * 2.0;
    let mut log_scale = [0.0; 3];
    let mut v_r = DMat3::ZERO;
    for k in 0..3 {
        let (col_r, col_vm) = (d.rotation.col(k), v_m.col(k));
        log_scale[k] = col_r.dot(col_vm) * d.scale[k];
        *v_r.col_mut(k) = col_vm * d.scale[k];
    }
    let rotation = quaternion_backward(d.quaternion, &v_r, g.rotations[i]);

    // Opacity: o = sigmoid(logit).
    let opacity_logit = v.opacity * d.opacity * (1.0 - d.opacity);

    // Color = max(SH(dir) + 0.5, 0): no gradient where the clamp is active.
    let v_rgb: [f64; 3] = std::array::from_fn(|ch| if d.color_unclamped[ch] > 0.0 { v.color[ch] } else { 0.0 });
    let length = d.view_dir.length();
    let dir = d.view_dir / length;
    let degree = g.sh_degree;
    let basis = sh::basis(degree, dir.to_array());
    let coeffs = g.sh_of(i);
    let sh_grad: Vec<f64> = (0..coeffs.len()).map(|n| basis[n / 3] * v_rgb[n % 3]).collect();
    if degree > 0 {
        let dbasis = basis_gradient(degree, dir.to_array());
        let mut v_dir = DVec3::ZERO;
        for (k, chunk) in coeffs.chunks_exact(3).enumerate() {
            let weight: f64 = (0..3).map(|ch| chunk[ch] as f64 * v_rgb[ch]).sum();
            v_dir += DVec3::from(dbasis[k]) * weight;
        }
        // d(view_dir / |view_dir|) = (I - dir dir^T) / |view_dir|.
        v_mean += (v_dir - dir * dir.dot(v_dir)) / length;
    }

    Some(GaussianGrad { mean: v_mean.to_array(), log_scale, rotation, opacity_logit, sh: sh_grad })
}

/// Outer product a b^T.
fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// From dL/dR (R the rotation of the normalized quaternion q) to dL/d(raw quaternion).
fn quaternion_backward(q: [f64; 4], v_r: &DMat3, raw: [f32; 4]) -> [f64; 4] {
    let [w, x, y, z] = q;
    let r = |i: usize, j: usize| v_r.col(j)[i];
    let v_qn = [
        2.0 * (-z * r(0, 1) + y * r(0, 2) + z * r(1, 0) - x * r(1, 2) - y * r(2, 0) + x * r(2, 1)),
        2.0 * (y * r(0, 1) + z * r(0, 2) + y * r(1, 0) - 2.0 * x * r(1, 1) - w * r(1, 2) + z * r(2, 0) + w * r(2, 1)
            - 2.0 * x * r(2, 2)),
        2.0 * (-2.0 * y * r(0, 0) + x * r(0, 1) + w * r(0, 2) + x * r(1, 0) + z * r(1, 2) - w * r(2, 0) + z * r(2, 1)
            - 2.0 * y * r(2, 2)),
        2.0 * (-2.0 * z * r(0, 0) - w * r(0, 1) + x * r(0, 2) + w * r(1, 0) - 2.0 * z * r(1, 1)
            + y * r(1, 2)
            + x * r(2, 0)
            + y * r(2, 1)),
    ];
    // q_n = q / |q|: dL/dq = (dL/dq_n - q_n (q_n . dL/dq_n)) / |q|.
    let norm = raw.iter().map(|&v| (v as f64) * (v as f64)).sum::<f64>().sqrt();
    let dot: f64 = (0..4).map(|k| q[k] * v_qn[k]).sum();
    std::array::from_fn(|k| (v_qn[k] - q[k] * dot) / norm)
}

//! Backward of the projection, as a CubeCL kernel: one unit per Gaussian sums its list
//! entries' screen-space gradients (in list order, so the sum does not depend on scheduling)
//! and chains them to the Gaussian's parameters, the reference's
//! `train::backward::projection` in f32. The forward values are recomputed by the same code
//! the projection kernel runs.

use burn_cubecl::cubecl;
use burn_cubecl::cubecl::prelude::*;

use super::blend::ENTRY_GRAD;
use super::project::{
    SH_C1, SH_C2, SH_C3, camera_space, clamped_tangents, covariance_2d, frame_at, scaled_rotation, sh_basis, sh_color,
    sigmoid, unit_quaternion, view_at,
};
use super::sort::element_index;

/// d basis_k / d(x, y, z) at (x, y, z), the components taken as independent (the reference's
/// `basis_gradient`).
#[cube]
fn sh_basis_gradient(k: u32, x: f32, y: f32, z: f32) -> (f32, f32, f32) {
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let mut gx = 0.0f32.runtime();
    let mut gy = 0.0f32.runtime();
    let mut gz = 0.0f32.runtime();
    if k == 1 {
        gy = -SH_C1 + 0.0 * y;
    } else if k == 2 {
        gz = SH_C1 + 0.0 * z;
    } else if k == 3 {
        gx = -SH_C1 + 0.0 * x;
    } else if k == 4 {
        gx = SH_C2[0] * y;
        gy = SH_C2[0] * x;
    } else if k == 5 {
        gy = SH_C2[1] * z;
        gz = SH_C2[1] * y;
    } else if k == 6 {
        gx = 0.0 - 2.0 * SH_C2[2] * x;
        gy = 0.0 - 2.0 * SH_C2[2] * y;
        gz = 4.0 * SH_C2[2] * z;
    } else if k == 7 {
        gx = SH_C2[3] * z;
        gz = SH_C2[3] * x;
    } else if k == 8 {
        gx = 2.0 * SH_C2[4] * x;
        gy = 0.0 - 2.0 * SH_C2[4] * y;
    } else if k == 9 {
        gx = 6.0 * SH_C3[0] * x * y;
        gy = SH_C3[0] * (3.0 * xx - 3.0 * yy);
    } else if k == 10 {
        gx = SH_C3[1] * y * z;
        gy = SH_C3[1] * x * z;
        gz = SH_C3[1] * x * y;
    } else if k == 11 {
        gx = 0.0 - 2.0 * SH_C3[2] * x * y;
        gy = SH_C3[2] * (4.0 * zz - xx - 3.0 * yy);
        gz = 8.0 * SH_C3[2] * y * z;
    } else if k == 12 {
        gx = 0.0 - 6.0 * SH_C3[3] * x * z;
        gy = 0.0 - 6.0 * SH_C3[3] * y * z;
        gz = SH_C3[3] * (6.0 * zz - 3.0 * xx - 3.0 * yy);
    } else if k == 13 {
        gx = SH_C3[4] * (4.0 * zz - 3.0 * xx - yy);
        gy = 0.0 - 2.0 * SH_C3[4] * x * y;
        gz = 8.0 * SH_C3[4] * x * z;
    } else if k == 14 {
        gx = 2.0 * SH_C3[5] * x * z;
        gy = 0.0 - 2.0 * SH_C3[5] * y * z;
        gz = SH_C3[5] * (xx - yy);
    } else if k == 15 {
        gx = SH_C3[6] * (3.0 * xx - 3.0 * yy);
        gy = 0.0 - 6.0 * SH_C3[6] * x * y;
    }
    (gx, gy, gz)
}

/// out = op(a) op(b) for row-major 3x3 matrices, op transposing where asked.
#[cube]
fn mat_mul(a: &Array<f32>, b: &Array<f32>, out: &mut Array<f32>, #[comptime] ta: bool, #[comptime] tb: bool) {
    for r in 0..3u32 {
        for c in 0..3u32 {
            let mut sum = 0.0f32.runtime();
            for k in 0..3u32 {
                let mut av = a[(r * 3 + k) as usize];
                if ta {
                    av = a[(k * 3 + r) as usize];
                }
                let mut bv = b[(k * 3 + c) as usize];
                if tb {
                    bv = b[(c * 3 + k) as usize];
                }
                sum += av * bv;
            }
            out[(r * 3 + c) as usize] = sum;
        }
    }
}

/// Row `r` of a row-major 3x3 matrix times vector (x, y, z).
#[cube]
fn row_dot(m: &Array<f32>, r: u32, x: f32, y: f32, z: f32) -> f32 {
    m[(r * 3) as usize] * x + m[(r * 3 + 1) as usize] * y + m[(r * 3 + 2) as usize] * z
}

/// One unit per depth rank: the Gaussian of that rank gets the gradient of its parameters
/// (zeros when it was culled), the norm of its screen-space gradient, and that gradient
/// (`screen_xy`, [N, 2]: a view rendered in windows sums it over them before the norm).
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn project_backward(
    means: &Tensor<f32>,
    log_scales: &Tensor<f32>,
    rotations: &Tensor<f32>,
    logits: &Tensor<f32>,
    sh: &Tensor<f32>,
    view: &Tensor<f32>,
    frame: &Tensor<u32>,
    order: &Tensor<u32>,
    tile_counts: &Tensor<u32>,
    offsets: &Tensor<u32>,
    entry_grads: &Tensor<f32>,
    grad_means: &mut Tensor<f32>,
    grad_log_scales: &mut Tensor<f32>,
    grad_rotations: &mut Tensor<f32>,
    grad_logits: &mut Tensor<f32>,
    grad_sh: &mut Tensor<f32>,
    grad_screen: &mut Tensor<f32>,
    screen_xy: &mut Tensor<f32>,
    count: u32,
) {
    let rank = element_index();
    if rank >= count {
        terminate!();
    }
    let g = order[rank as usize];
    let sh_coeffs = frame[frame_at::SH_COEFFS as usize];
    for k in 0..3u32 {
        grad_means[(g * 3 + k) as usize] = 0.0;
        grad_log_scales[(g * 3 + k) as usize] = 0.0;
    }
    for k in 0..4u32 {
        grad_rotations[(g * 4 + k) as usize] = 0.0;
    }
    grad_logits[g as usize] = 0.0;
    for k in 0..sh_coeffs * 3 {
        grad_sh[(g * sh_coeffs * 3 + k) as usize] = 0.0;
    }
    grad_screen[g as usize] = 0.0;
    screen_xy[(g * 2) as usize] = 0.0;
    screen_xy[(g * 2 + 1) as usize] = 0.0;
    if tile_counts[g as usize] == 0 {
        terminate!();
    }
    let mut v = Array::<f32>::new(9usize);
    for c in 0..ENTRY_GRAD {
        v[c as usize] = 0.0;
    }
    let first = offsets[rank as usize];
    let end = offsets[(rank + 1) as usize];
    for e in first..end {
        for c in 0..ENTRY_GRAD {
            v[c as usize] += entry_grads[(e * ENTRY_GRAD + c) as usize];
        }
    }
    let (vmx, vmy) = (v[0], v[1]);
    grad_screen[g as usize] = (vmx * vmx + vmy * vmy).sqrt();
    screen_xy[(g * 2) as usize] = vmx;
    screen_xy[(g * 2 + 1) as usize] = vmy;

    // The forward values, as the projection kernel computes them.
    let opacity = sigmoid(logits[g as usize]);
    let (qw, qx, qy, qz, norm) = unit_quaternion(rotations, g);
    let (x, y, z, dir_x, dir_y, dir_z) = camera_space(means, g, view);
    let inv_z = 1.0 / z;
    let (tan_x, tan_y) = (x * inv_z, y * inv_z);
    let (ctx, cty) = clamped_tangents(view, tan_x, tan_y);
    let fx = view[view_at::FOCAL as usize];
    let fy = view[view_at::FOCAL as usize + 1];
    let sb = (g * 3) as usize;
    let sx = log_scales[sb].exp();
    let sy = log_scales[sb + 1].exp();
    let sz = log_scales[sb + 2].exp();

    let mut rot = Array::<f32>::new(9usize);
    scaled_rotation(qw, qx, qy, qz, 1.0, 1.0, 1.0, &mut rot);
    let mut m = Array::<f32>::new(9usize);
    scaled_rotation(qw, qx, qy, qz, sx, sy, sz, &mut m);
    let mut w = Array::<f32>::new(9usize);
    for k in 0..9u32 {
        w[k as usize] = view[(view_at::ROTATION + k) as usize];
    }
    let mut wm = Array::<f32>::new(9usize);
    mat_mul(&w, &m, &mut wm, false, false);
    let mut cov_cam = Array::<f32>::new(9usize);
    mat_mul(&wm, &wm, &mut cov_cam, false, true);
    let (cov_a, cov_b, cov_c, det) = covariance_2d(view, &m, fx * inv_z, fy * inv_z, ctx, cty);
    let (ca, cb, cc) = (cov_c / det, -cov_b / det, cov_a / det);
    // The EWA Jacobian's rows (j0x, 0, j0z) and (0, j1y, j1z).
    let (j0x, j0z) = (fx * inv_z, -fx * inv_z * ctx);
    let (j1y, j1z) = (fy * inv_z, -fy * inv_z * cty);

    // Screen-space center u = fx x / z + cx, v = fy y / z + cy.
    let mut vcx = fx * inv_z * vmx;
    let mut vcy = fy * inv_z * vmy;
    let mut vcz = -(fx * x * vmx + fy * y * vmy) * inv_z * inv_z;

    // Conic = inverse of the 2D covariance: dL/dCov = -C G C.
    let (g0, g1, g2) = (v[2], 0.5 * v[3], v[4]);
    let cg00 = ca * g0 + cb * g1;
    let cg01 = ca * g1 + cb * g2;
    let cg10 = cb * g0 + cc * g1;
    let cg11 = cb * g1 + cc * g2;
    let vc00 = -(cg00 * ca + cg01 * cb);
    let vc01 = -(cg00 * cb + cg01 * cc);
    let vc11 = -(cg10 * cb + cg11 * cc);

    // cov2d = J Sc J^T + blur: dL/dSc = J^T V J, dL/dJ = 2 V J Sc.
    let mj0x = j0x * vc00;
    let mj0y = j1y * vc01;
    let mj0z = j0z * vc00 + j1z * vc01;
    let mj1x = j0x * vc01;
    let mj1y = j1y * vc11;
    let mj1z = j0z * vc01 + j1z * vc11;
    let mut v_cov_cam = Array::<f32>::new(9usize);
    v_cov_cam[0] = j0x * mj0x;
    v_cov_cam[1] = j0x * mj0y;
    v_cov_cam[2] = j0x * mj0z;
    v_cov_cam[3] = j1y * mj1x;
    v_cov_cam[4] = j1y * mj1y;
    v_cov_cam[5] = j1y * mj1z;
    v_cov_cam[6] = j0z * mj0x + j1z * mj1x;
    v_cov_cam[7] = j0z * mj0y + j1z * mj1y;
    v_cov_cam[8] = j0z * mj0z + j1z * mj1z;
    let vj0x = 2.0 * row_dot(&cov_cam, 0, mj0x, mj0y, mj0z);
    let vj0z = 2.0 * row_dot(&cov_cam, 2, mj0x, mj0y, mj0z);
    let vj1y = 2.0 * row_dot(&cov_cam, 1, mj1x, mj1y, mj1z);
    let vj1z = 2.0 * row_dot(&cov_cam, 2, mj1x, mj1y, mj1z);

    // J = [[fx/z, 0, -fx tx/z], [0, fy/z, -fy ty/z]] with tx = x/z unless clamped.
    let inv_z2 = inv_z * inv_z;
    vcz -= fx * inv_z2 * vj0x + fy * inv_z2 * vj1y;
    if ctx != tan_x {
        vcz += -j0z * inv_z * vj0z;
    } else {
        vcx -= fx * inv_z2 * vj0z;
        vcz += 2.0 * fx * x * inv_z2 * inv_z * vj0z;
    }
    if cty != tan_y {
        vcz += -j1z * inv_z * vj1z;
    } else {
        vcy -= fy * inv_z2 * vj1z;
        vcz += 2.0 * fy * y * inv_z2 * inv_z * vj1z;
    }

    // Sc = W S W^T, camera-space mean = W mean + t.
    let mut tmp = Array::<f32>::new(9usize);
    mat_mul(&w, &v_cov_cam, &mut tmp, true, false);
    let mut v_cov_world = Array::<f32>::new(9usize);
    mat_mul(&tmp, &w, &mut v_cov_world, false, false);
    let mut vmean_x = w[0] * vcx + w[3] * vcy + w[6] * vcz;
    let mut vmean_y = w[1] * vcx + w[4] * vcy + w[7] * vcz;
    let mut vmean_z = w[2] * vcx + w[5] * vcy + w[8] * vcz;

    // S = M M^T with M = R diag(s): dL/dM = 2 dL/dS M.
    let mut v_m = Array::<f32>::new(9usize);
    mat_mul(&v_cov_world, &m, &mut v_m, false, false);
    let mut v_r = Array::<f32>::new(9usize);
    let mut scale = Array::<f32>::new(3usize);
    scale[0] = sx;
    scale[1] = sy;
    scale[2] = sz;
    for k in 0..3u32 {
        let mut dot = 0.0f32.runtime();
        for r in 0..3u32 {
            let vm = 2.0 * v_m[(r * 3 + k) as usize];
            dot += rot[(r * 3 + k) as usize] * vm;
            v_r[(r * 3 + k) as usize] = vm * scale[k as usize];
        }
        grad_log_scales[(g * 3 + k) as usize] = dot * scale[k as usize];
    }

    // dL/dR to the normalized quaternion, then through the normalization.
    let (w_, x_, y_, z_) = (qw, qx, qy, qz);
    let vq_w = 2.0 * (-z_ * v_r[1] + y_ * v_r[2] + z_ * v_r[3] - x_ * v_r[5] - y_ * v_r[6] + x_ * v_r[7]);
    let vq_x = 2.0
        * (y_ * v_r[1] + z_ * v_r[2] + y_ * v_r[3] - 2.0 * x_ * v_r[4] - w_ * v_r[5] + z_ * v_r[6] + w_ * v_r[7]
            - 2.0 * x_ * v_r[8]);
    let vq_y = 2.0
        * (x_ * v_r[1] - 2.0 * y_ * v_r[0] + w_ * v_r[2] + x_ * v_r[3] + z_ * v_r[5] - w_ * v_r[6] + z_ * v_r[7]
            - 2.0 * y_ * v_r[8]);
    let vq_z = 2.0
        * (x_ * v_r[2] - 2.0 * z_ * v_r[0] - w_ * v_r[1] + w_ * v_r[3] - 2.0 * z_ * v_r[4]
            + y_ * v_r[5]
            + x_ * v_r[6]
            + y_ * v_r[7]);
    let dot = w_ * vq_w + x_ * vq_x + y_ * vq_y + z_ * vq_z;
    grad_rotations[(g * 4) as usize] = (vq_w - w_ * dot) / norm;
    grad_rotations[(g * 4 + 1) as usize] = (vq_x - x_ * dot) / norm;
    grad_rotations[(g * 4 + 2) as usize] = (vq_y - y_ * dot) / norm;
    grad_rotations[(g * 4 + 3) as usize] = (vq_z - z_ * dot) / norm;

    grad_logits[g as usize] = v[5] * opacity * (1.0 - opacity);

    // Color = max(SH(dir) + 0.5, 0): no gradient where the clamp is active.
    let length = (dir_x * dir_x + dir_y * dir_y + dir_z * dir_z).sqrt();
    let (ux, uy, uz) = (dir_x / length, dir_y / length, dir_z / length);
    let mut v_rgb = Array::<f32>::new(3usize);
    for c in 0..3u32 {
        v_rgb[c as usize] = 0.0;
        if sh_color(sh, g, c, sh_coeffs, ux, uy, uz) > 0.0 {
            v_rgb[c as usize] = v[(6 + c) as usize];
        }
    }
    let mut vdx = 0.0f32.runtime();
    let mut vdy = 0.0f32.runtime();
    let mut vdz = 0.0f32.runtime();
    for k in 0..sh_coeffs {
        let basis = sh_basis(k, ux, uy, uz);
        let mut weight = 0.0f32.runtime();
        for c in 0..3u32 {
            let at = ((g * sh_coeffs + k) * 3 + c) as usize;
            grad_sh[at] = basis * v_rgb[c as usize];
            weight += sh[at] * v_rgb[c as usize];
        }
        let (gx, gy, gz) = sh_basis_gradient(k, ux, uy, uz);
        vdx += gx * weight;
        vdy += gy * weight;
        vdz += gz * weight;
    }
    // d(dir / |dir|) = (I - u u^T) / |dir|.
    let radial = ux * vdx + uy * vdy + uz * vdz;
    vmean_x += (vdx - ux * radial) / length;
    vmean_y += (vdy - uy * radial) / length;
    vmean_z += (vdz - uz * radial) / length;
    grad_means[(g * 3) as usize] = vmean_x;
    grad_means[(g * 3 + 1) as usize] = vmean_y;
    grad_means[(g * 3 + 2) as usize] = vmean_z;
}

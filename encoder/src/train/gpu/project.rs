//! Projection of every Gaussian to its splat, as a CubeCL kernel: the f32 projection of the
//! reference rasterizer (`pwgs_render::raster::project_f32`, same culling, same footprint,
//! same pixel box), one unit per Gaussian.
//!
//! Where the reference falls back to f64 (an f32 intermediate overflows), the kernel culls the
//! Gaussian: that happens only for scales beyond e^88 or 2D covariances beyond 3e38 pixels^2,
//! which training never reaches. The camera-space mean is computed from the mean minus the
//! camera center, the center given as the sum of two f32 values, so that a scene far from the
//! origin keeps the digits the reference's f64 subtraction keeps.

use burn_cubecl::cubecl;
use burn_cubecl::cubecl::prelude::*;
use pwgs_render::raster::project::{GUARD_BAND, JACOBIAN_FOV_LIMIT, MIN_QUATERNION_NORM_SQUARED};
use pwgs_render::raster::sh::{C0, C1, C2, C3};
use pwgs_render::raster::{RenderOptions, TILE_SIZE, Window};

use super::super::splat_op::SplatView;
use super::sort::element_index;

/// Floats per projected splat: center (2), conic (3), Cholesky factor of the conic (3),
/// opacity, color (3), depth.
pub const SPLAT_FLOATS: u32 = 13;
pub const MEAN: u32 = 0;
pub const CONIC: u32 = 2;
pub const CHOLESKY: u32 = 5;
pub const OPACITY: u32 = 8;
pub const COLOR: u32 = 9;
pub const DEPTH: u32 = 12;

/// u32 per splat: its pixel box x0, x1, y0, y1 (clipped to the window).
pub const BOX_WORDS: u32 = 4;

/// Key of a culled Gaussian in the depth sort: after every visible one (depths are positive
/// floats, whose bits order like their values).
pub const CULLED_KEY: u32 = u32::MAX;

/// The camera and settings as the kernels read them: one small f32 tensor.
pub mod view_at {
    /// World-to-camera rotation, row-major.
    pub const ROTATION: u32 = 0;
    /// Camera center as high and low f32 parts.
    pub const CENTER_HI: u32 = 9;
    pub const CENTER_LO: u32 = 12;
    pub const FOCAL: u32 = 15;
    pub const PRINCIPAL: u32 = 17;
    pub const SIZE: u32 = 19;
    pub const NEAR: u32 = 21;
    pub const BLUR: u32 = 22;
    pub const ALPHA_MIN: u32 = 23;
    /// Tangents of the image edges: left, right, top, bottom.
    pub const EDGES: u32 = 24;
    /// Guard band (x, y) and the Jacobian's clamp beyond the edges (x, y), in tangents.
    pub const BAND: u32 = 28;
    pub const SLACK: u32 = 30;
    pub const LEN: usize = 32;
}

/// The values of [`view`] for a view, computed as the reference's `project_f32::View` does.
pub fn view_values(view: &SplatView) -> Vec<f32> {
    let camera = &view.camera;
    let settings = &view.options.projection;
    let mut v = vec![0.0f32; view_at::LEN];
    let r = camera.rotation;
    for row in 0..3 {
        for col in 0..3 {
            v[view_at::ROTATION as usize + row * 3 + col] = r.col(col)[row];
        }
    }
    let center = camera.center().as_dvec3().to_array();
    for k in 0..3 {
        let hi = center[k] as f32;
        v[view_at::CENTER_HI as usize + k] = hi;
        v[view_at::CENTER_LO as usize + k] = (center[k] - hi as f64) as f32;
    }
    let (fx, fy, cx, cy) = (camera.fx, camera.fy, camera.cx, camera.cy);
    let (w, h) = (camera.width as f32, camera.height as f32);
    let edges = [cx / fx, (w - cx) / fx, cy / fy, (h - cy) / fy];
    let band = GUARD_BAND as f32;
    let limit = JACOBIAN_FOV_LIMIT as f32 - 1.0;
    let values: [(u32, &[f32]); 10] = [
        (view_at::FOCAL, &[fx, fy]),
        (view_at::PRINCIPAL, &[cx, cy]),
        (view_at::SIZE, &[w, h]),
        (view_at::NEAR, &[settings.near as f32]),
        (view_at::BLUR, &[settings.blur as f32]),
        (view_at::ALPHA_MIN, &[settings.alpha_min as f32]),
        (view_at::EDGES, &edges),
        (view_at::BAND, &[band * w / fx, band * h / fy]),
        (view_at::SLACK, &[limit * (edges[0] + edges[1]) / 2.0, limit * (edges[2] + edges[3]) / 2.0]),
        (view_at::ROTATION, &[]),
    ];
    for (at, vals) in values {
        v[at as usize..at as usize + vals.len()].copy_from_slice(vals);
    }
    v
}

/// The integer settings of a render, passed to kernels as a small u32 tensor.
pub mod frame_at {
    pub const WINDOW: u32 = 0;
    pub const TILES_X: u32 = 4;
    pub const TILES_Y: u32 = 5;
    /// SH coefficients per channel of the SH tensor (all of them rendered).
    pub const SH_COEFFS: u32 = 6;
    /// The window's place in the image-sized arrays the blend kernels fill: x and y offset,
    /// and the arrays' width.
    pub const OUTPUT: u32 = 7;
    pub const LEN: usize = 10;
}

pub fn frame_values(window: Window, sh_coeffs: u32, output: Window) -> Vec<u32> {
    let (tiles_x, tiles_y) = window.tile_counts();
    let (x, y) = (window.x0 - output.x0, window.y0 - output.y0);
    vec![window.x0, window.y0, window.width, window.height, tiles_x, tiles_y, sh_coeffs, x, y, output.width]
}

/// Smallest alpha, largest alpha, transmittance stop and background, as the blend kernels
/// read them.
pub fn blend_values(options: &RenderOptions) -> Vec<f32> {
    let [r, g, b] = options.background;
    vec![options.projection.alpha_min as f32, options.alpha_max, options.transmittance_min, r, g, b]
}

pub(super) const SH_C0: f32 = C0 as f32;
pub(super) const SH_C1: f32 = C1 as f32;
pub(super) const SH_C2: [f32; 5] = [C2[0] as f32, C2[1] as f32, C2[2] as f32, C2[3] as f32, C2[4] as f32];
pub(super) const SH_C3: [f32; 7] =
    [C3[0] as f32, C3[1] as f32, C3[2] as f32, C3[3] as f32, C3[4] as f32, C3[5] as f32, C3[6] as f32];
const MIN_NORM_SQUARED: f32 = MIN_QUATERNION_NORM_SQUARED as f32;

/// Numerically stable logistic function.
#[cube]
pub fn sigmoid(x: f32) -> f32 {
    let e = (-x.abs()).exp();
    let mut s = 1.0 / (1.0 + e);
    if x < 0.0 {
        s = e / (1.0 + e);
    }
    s
}

/// SH basis function `k` at unit direction (x, y, z), in the reference's convention.
#[cube]
pub fn sh_basis(k: u32, x: f32, y: f32, z: f32) -> f32 {
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let mut b = SH_C0 + 0.0 * x;
    if k == 1 {
        b = 0.0 - SH_C1 * y;
    } else if k == 2 {
        b = SH_C1 * z;
    } else if k == 3 {
        b = 0.0 - SH_C1 * x;
    } else if k == 4 {
        b = SH_C2[0] * x * y;
    } else if k == 5 {
        b = SH_C2[1] * y * z;
    } else if k == 6 {
        b = SH_C2[2] * (2.0 * zz - xx - yy);
    } else if k == 7 {
        b = SH_C2[3] * x * z;
    } else if k == 8 {
        b = SH_C2[4] * (xx - yy);
    } else if k == 9 {
        b = SH_C3[0] * y * (3.0 * xx - yy);
    } else if k == 10 {
        b = SH_C3[1] * x * y * z;
    } else if k == 11 {
        b = SH_C3[2] * y * (4.0 * zz - xx - yy);
    } else if k == 12 {
        b = SH_C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
    } else if k == 13 {
        b = SH_C3[4] * x * (4.0 * zz - xx - yy);
    } else if k == 14 {
        b = SH_C3[5] * z * (xx - yy);
    } else if k == 15 {
        b = SH_C3[6] * x * (xx - 3.0 * yy);
    }
    b
}

/// Whether Gaussian `i`'s parameters are all finite.
#[cube]
pub fn finite_parameters(
    means: &Tensor<f32>,
    log_scales: &Tensor<f32>,
    rotations: &Tensor<f32>,
    logits: &Tensor<f32>,
    sh: &Tensor<f32>,
    i: u32,
    sh_coeffs: u32,
) -> bool {
    let mut ok = finite(logits[i as usize]);
    for k in 0..3u32 {
        ok = ok && finite(means[(i * 3 + k) as usize]) && finite(log_scales[(i * 3 + k) as usize]);
    }
    for k in 0..4u32 {
        ok = ok && finite(rotations[(i * 4 + k) as usize]);
    }
    for k in 0..sh_coeffs * 3 {
        ok = ok && finite(sh[(i * sh_coeffs * 3 + k) as usize]);
    }
    ok
}

#[cube]
pub fn finite(x: f32) -> bool {
    !(x.is_nan() || x.is_inf())
}

/// The unit quaternion of Gaussian `i` and the raw quaternion's norm. The norm is taken of the
/// quaternion divided by its largest component (a sum of squares in [1, 4]), so that it
/// neither overflows nor underflows; a zero quaternion has norm 0.
#[cube]
pub fn unit_quaternion(rotations: &Tensor<f32>, i: u32) -> (f32, f32, f32, f32, f32) {
    let base = (i * 4) as usize;
    let (w, x, y, z) = (rotations[base], rotations[base + 1], rotations[base + 2], rotations[base + 3]);
    let m = w.abs().max(x.abs()).max(y.abs().max(z.abs()));
    let mut inv = 0.0f32.runtime();
    if m > 0.0 {
        inv = 1.0 / m;
    }
    let (w, x, y, z) = (w * inv, x * inv, y * inv, z * inv);
    let scaled = (w * w + x * x + y * y + z * z).sqrt();
    let to_unit = 1.0 / scaled;
    (w * to_unit, x * to_unit, y * to_unit, z * to_unit, m * scaled)
}

/// The view direction's tangents clamped to the Jacobian's limit (1.3 times the field of
/// view).
#[cube]
pub fn clamped_tangents(view: &Tensor<f32>, tan_x: f32, tan_y: f32) -> (f32, f32) {
    let e = view_at::EDGES as usize;
    let s = view_at::SLACK as usize;
    let ctx = tan_x.clamp(-view[e] - view[s], view[e + 1] + view[s]);
    let cty = tan_y.clamp(-view[e + 2] - view[s + 1], view[e + 3] + view[s + 1]);
    (ctx, cty)
}

/// Camera-space mean and the unnormalized viewing direction (mean minus camera center).
#[cube]
pub fn camera_space(means: &Tensor<f32>, i: u32, view: &Tensor<f32>) -> (f32, f32, f32, f32, f32, f32) {
    let base = (i * 3) as usize;
    let hi = view_at::CENTER_HI as usize;
    let lo = view_at::CENTER_LO as usize;
    let dx = (means[base] - view[hi]) - view[lo];
    let dy = (means[base + 1] - view[hi + 1]) - view[lo + 1];
    let dz = (means[base + 2] - view[hi + 2]) - view[lo + 2];
    let r = view_at::ROTATION as usize;
    let cam_x = view[r] * dx + view[r + 1] * dy + view[r + 2] * dz;
    let cam_y = view[r + 3] * dx + view[r + 4] * dy + view[r + 5] * dz;
    let cam_z = view[r + 6] * dx + view[r + 7] * dy + view[r + 8] * dz;
    (cam_x, cam_y, cam_z, dx, dy, dz)
}

/// Unclamped color channel `c` of Gaussian `i` seen along unit direction (x, y, z).
#[cube]
pub fn sh_color(sh: &Tensor<f32>, i: u32, c: u32, sh_coeffs: u32, x: f32, y: f32, z: f32) -> f32 {
    let mut color = 0.5f32.runtime();
    for k in 0..sh_coeffs {
        color += sh_basis(k, x, y, z) * sh[((i * sh_coeffs + k) * 3 + c) as usize];
    }
    color
}

/// One unit per Gaussian: its splat, pixel box, tile count (0 when culled) and depth key.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn project_kernel(
    means: &Tensor<f32>,
    log_scales: &Tensor<f32>,
    rotations: &Tensor<f32>,
    logits: &Tensor<f32>,
    sh: &Tensor<f32>,
    view: &Tensor<f32>,
    frame: &Tensor<u32>,
    splats: &mut Tensor<f32>,
    boxes: &mut Tensor<u32>,
    tile_counts: &mut Tensor<u32>,
    depth_keys: &mut Tensor<u32>,
    count: u32,
) {
    let i = element_index();
    if i >= count {
        terminate!();
    }
    tile_counts[i as usize] = 0;
    depth_keys[i as usize] = CULLED_KEY;
    let sh_coeffs = frame[frame_at::SH_COEFFS as usize];
    if !finite_parameters(means, log_scales, rotations, logits, sh, i, sh_coeffs) {
        terminate!();
    }
    let opacity = sigmoid(logits[i as usize]);
    if !(opacity >= view[view_at::ALPHA_MIN as usize]) {
        terminate!();
    }
    let (qw, qx, qy, qz, norm) = unit_quaternion(rotations, i);
    if !(norm * norm >= MIN_NORM_SQUARED) {
        terminate!();
    }

    let (cam_x, cam_y, z, dir_x, dir_y, dir_z) = camera_space(means, i, view);
    if !(z >= view[view_at::NEAR as usize]) {
        terminate!();
    }
    let inv_z = 1.0 / z;
    let tan_x = cam_x * inv_z;
    let tan_y = cam_y * inv_z;
    let e = view_at::EDGES as usize;
    let (left, right, top, bottom) = (view[e], view[e + 1], view[e + 2], view[e + 3]);
    let band_x = view[view_at::BAND as usize];
    let band_y = view[view_at::BAND as usize + 1];
    if !(tan_x >= -left - band_x && tan_x <= right + band_x && tan_y >= -top - band_y && tan_y <= bottom + band_y) {
        terminate!();
    }

    let sb = (i * 3) as usize;
    let sx = log_scales[sb].exp();
    let sy = log_scales[sb + 1].exp();
    let sz = log_scales[sb + 2].exp();
    if !(finite(sx) && finite(sy) && finite(sz)) {
        terminate!();
    }
    let (ctx, cty) = clamped_tangents(view, tan_x, tan_y);
    let fx = view[view_at::FOCAL as usize];
    let fy = view[view_at::FOCAL as usize + 1];
    let (fx_z, fy_z) = (fx * inv_z, fy * inv_z);

    let mut m = Array::<f32>::new(9usize);
    scaled_rotation(qw, qx, qy, qz, sx, sy, sz, &mut m);
    let (cov_a, cov_b, cov_c, det) = covariance_2d(view, &m, fx_z, fy_z, ctx, cty);
    if !(det > 0.0 && finite(det) && finite(cov_a) && finite(cov_b) && finite(cov_c)) {
        terminate!();
    }

    let length = (dir_x * dir_x + dir_y * dir_y + dir_z * dir_z).sqrt();
    if !(length > 0.0) {
        terminate!();
    }
    let (ux, uy, uz) = (dir_x / length, dir_y / length, dir_z / length);
    let px = view[view_at::PRINCIPAL as usize];
    let py = view[view_at::PRINCIPAL as usize + 1];
    let mean_x = fx * tan_x + px;
    let mean_y = fy * tan_y + py;

    // The pixel box of the ellipse where alpha >= alpha_min (see the reference's splat_of).
    let alpha_min = view[view_at::ALPHA_MIN as usize];
    let radius = (2.0 * (opacity / alpha_min).ln()).max(0.0).sqrt();
    let ex = radius * cov_a.sqrt();
    let ey = radius * cov_c.sqrt();
    let wb = frame_at::WINDOW as usize;
    let (wx0, wy0, ww, wh) = (frame[wb], frame[wb + 1], frame[wb + 2], frame[wb + 3]);
    let width = view[view_at::SIZE as usize];
    let height = view[view_at::SIZE as usize + 1];
    let x_lo = (mean_x - ex - 0.5).ceil().max(0.0).max(wx0 as f32);
    let x_hi = (mean_x + ex - 0.5).floor().min(width - 1.0).min((wx0 + ww - 1) as f32);
    let y_lo = (mean_y - ey - 0.5).ceil().max(0.0).max(wy0 as f32);
    let y_hi = (mean_y + ey - 0.5).floor().min(height - 1.0).min((wy0 + wh - 1) as f32);
    if !(x_lo <= x_hi && y_lo <= y_hi) {
        terminate!();
    }
    let (x0, x1) = (x_lo as u32, x_hi as u32 + 1);
    let (y0, y1) = (y_lo as u32, y_hi as u32 + 1);

    let inv_det = 1.0 / det;
    let conic_a = cov_c * inv_det;
    let conic_b = -cov_b * inv_det;
    let conic_c = cov_a * inv_det;
    let l11 = conic_a.sqrt();
    let o = (i * SPLAT_FLOATS) as usize;
    splats[o + MEAN as usize] = mean_x;
    splats[o + MEAN as usize + 1] = mean_y;
    splats[o + CONIC as usize] = conic_a;
    splats[o + CONIC as usize + 1] = conic_b;
    splats[o + CONIC as usize + 2] = conic_c;
    splats[o + CHOLESKY as usize] = l11;
    splats[o + CHOLESKY as usize + 1] = conic_b / l11;
    splats[o + CHOLESKY as usize + 2] = (1.0 / cov_c).sqrt();
    splats[o + OPACITY as usize] = opacity;
    for c in 0..3u32 {
        splats[o + (COLOR + c) as usize] = sh_color(sh, i, c, sh_coeffs, ux, uy, uz).max(0.0);
    }
    splats[o + DEPTH as usize] = z;
    let bo = (i * BOX_WORDS) as usize;
    boxes[bo] = x0;
    boxes[bo + 1] = x1;
    boxes[bo + 2] = y0;
    boxes[bo + 3] = y1;
    let tx0 = (x0 - wx0) / TILE_SIZE;
    let tx1 = (x1 - 1 - wx0) / TILE_SIZE + 1;
    let ty0 = (y0 - wy0) / TILE_SIZE;
    let ty1 = (y1 - 1 - wy0) / TILE_SIZE + 1;
    tile_counts[i as usize] = (tx1 - tx0) * (ty1 - ty0);
    depth_keys[i as usize] = u32::reinterpret(z);
}

/// R(q) diag(s) into `m`, row-major, for a unit quaternion (w, x, y, z) (the reference's
/// `rotation_matrix`).
#[cube]
#[allow(clippy::too_many_arguments)]
pub fn scaled_rotation(w: f32, x: f32, y: f32, z: f32, sx: f32, sy: f32, sz: f32, m: &mut Array<f32>) {
    m[0] = (1.0 - 2.0 * (y * y + z * z)) * sx;
    m[1] = 2.0 * (x * y - w * z) * sy;
    m[2] = 2.0 * (x * z + w * y) * sz;
    m[3] = 2.0 * (x * y + w * z) * sx;
    m[4] = (1.0 - 2.0 * (x * x + z * z)) * sy;
    m[5] = 2.0 * (y * z - w * x) * sz;
    m[6] = 2.0 * (x * z - w * y) * sx;
    m[7] = 2.0 * (y * z + w * x) * sy;
    m[8] = (1.0 - 2.0 * (x * x + y * y)) * sz;
}

/// The 2D covariance (xx, xy, yy) after the blur and its determinant, for M = R S (row-major)
/// and the EWA Jacobian's entries fx/z, fy/z and clamped tangents (ctx, cty). It is B B^T +
/// blur I with B = J W M (rows b0, b1), so its determinant is |b0 x b1|^2 + blur (|b0|^2 +
/// |b1|^2) + blur^2 (Lagrange's identity): a sum of non-negative terms, where a c - b^2
/// cancels to noise for needle-like footprints.
#[cube]
pub fn covariance_2d(
    view: &Tensor<f32>,
    m: &Array<f32>,
    fx_z: f32,
    fy_z: f32,
    ctx: f32,
    cty: f32,
) -> (f32, f32, f32, f32) {
    // Rows of J W (each row of J has one zero), then times M.
    let r = view_at::ROTATION as usize;
    let a0 = fx_z * view[r] - fx_z * ctx * view[r + 6];
    let a1 = fx_z * view[r + 1] - fx_z * ctx * view[r + 7];
    let a2 = fx_z * view[r + 2] - fx_z * ctx * view[r + 8];
    let c0 = fy_z * view[r + 3] - fy_z * cty * view[r + 6];
    let c1 = fy_z * view[r + 4] - fy_z * cty * view[r + 7];
    let c2 = fy_z * view[r + 5] - fy_z * cty * view[r + 8];
    let b00 = a0 * m[0] + a1 * m[3] + a2 * m[6];
    let b01 = a0 * m[1] + a1 * m[4] + a2 * m[7];
    let b02 = a0 * m[2] + a1 * m[5] + a2 * m[8];
    let b10 = c0 * m[0] + c1 * m[3] + c2 * m[6];
    let b11 = c0 * m[1] + c1 * m[4] + c2 * m[7];
    let b12 = c0 * m[2] + c1 * m[5] + c2 * m[8];
    let blur = view[view_at::BLUR as usize];
    let n0 = b00 * b00 + b01 * b01 + b02 * b02;
    let n1 = b10 * b10 + b11 * b11 + b12 * b12;
    let cross_x = b01 * b12 - b02 * b11;
    let cross_y = b02 * b10 - b00 * b12;
    let cross_z = b00 * b11 - b01 * b10;
    let det = (cross_x * cross_x + cross_y * cross_y + cross_z * cross_z) + blur * (n0 + n1) + blur * blur;
    (n0 + blur, b00 * b10 + b01 * b11 + b02 * b12, n1 + blur, det)
}

//! Front-to-back blending of each tile's splats and its backward pass, as CubeCL kernels: one
//! cube per 16x16 tile, one unit per pixel, the tile's list read into shared memory a batch at
//! a time. Every decision is the reference's (`pwgs_render::raster::blend`): a splat counts
//! for a pixel inside its box whose alpha reaches alpha_min, alpha is clamped to alpha_max, and
//! a pixel stops before the splat that would bring its transmittance to the minimum.
//!
//! The backward pass walks each pixel's list back to front from the last splat the forward
//! pass blended, recovering transmittance by division, as the reference does. Each splat's
//! gradient is summed over the tile's pixels in shared memory (by rows, then over the rows; no
//! atomics, no subgroup operations, which lavapipe lacks) and written to the splat's entry of
//! the list, so the sums do not depend on scheduling.

use burn_cubecl::cubecl;
use burn_cubecl::cubecl::prelude::*;
use pwgs_render::raster::TILE_SIZE;
use pwgs_render::raster::blend::SMOOTH_CUTOFF_BAND;

use super::project::{BOX_WORDS, CHOLESKY, COLOR, CONIC, MEAN, OPACITY, SPLAT_FLOATS, frame_at};
use super::sort::{BLOCK, BLOCK_SLOTS};

/// Floats of a splat the blend reads: center (2), conic (3), Cholesky factor (3), opacity,
/// color (3).
const LOADED: u32 = 12;
const LOADED_SLOTS: usize = BLOCK_SLOTS * LOADED as usize;
const BOX_SLOTS: usize = BLOCK_SLOTS * BOX_WORDS as usize;

/// Gradient values per list entry: center (2), conic (3), opacity, color (3).
pub const ENTRY_GRAD: u32 = 9;
const SUM_SLOTS: usize = BLOCK_SLOTS * ENTRY_GRAD as usize;
const ROW_SUM_SLOTS: usize = (TILE_SIZE * ENTRY_GRAD) as usize;

/// Positions of the blend limits (`project::blend_values`).
const ALPHA_MIN: usize = 0;
const ALPHA_MAX: usize = 1;
const T_MIN: usize = 2;
const BACKGROUND: usize = 3;

/// The pixel this unit blends: window coordinates, and whether it lies inside the window.
#[cube]
fn tile_pixel(frame: &Tensor<u32>) -> (u32, u32, bool) {
    let lx = CUBE_POS_X * TILE_SIZE + UNIT_POS_X;
    let ly = CUBE_POS_Y * TILE_SIZE + UNIT_POS_Y;
    let w = frame_at::WINDOW as usize;
    (lx, ly, lx < frame[w + 2] && ly < frame[w + 3])
}

/// Where window pixel (lx, ly) sits in the image-sized arrays: a window rendered on its own
/// fills them whole, one of several windows of a view ([`super::bins::windows`]) its part.
#[cube]
fn output_index(frame: &Tensor<u32>, lx: u32, ly: u32) -> usize {
    let o = frame_at::OUTPUT as usize;
    ((ly + frame[o + 1]) * frame[o + 2] + lx + frame[o]) as usize
}

/// Copies the splat of list entry `k` (if below `end`) into this unit's shared slot.
#[cube]
fn load_splat(
    splats: &Tensor<f32>,
    boxes: &Tensor<u32>,
    entry_splat: &Tensor<u32>,
    k: u32,
    end: u32,
    floats: &mut Shared<[f32]>,
    words: &mut Shared<[u32]>,
) {
    if k < end {
        let g = entry_splat[k as usize];
        let u = UNIT_POS;
        for c in 0..LOADED {
            floats[(u * LOADED + c) as usize] = splats[(g * SPLAT_FLOATS + c) as usize];
        }
        for c in 0..BOX_WORDS {
            words[(u * BOX_WORDS + c) as usize] = boxes[(g * BOX_WORDS + c) as usize];
        }
    }
}

/// Alpha and falloff of shared splat `j` at pixel (x, y), or alpha 0 when it does not count.
#[cube]
fn sample(
    floats: &Shared<[f32]>,
    words: &Shared<[u32]>,
    j: u32,
    x: u32,
    y: u32,
    limits: &Tensor<f32>,
    #[comptime] smooth: bool,
) -> (f32, f32, f32, f32) {
    let b = j * BOX_WORDS;
    let inside = x >= words[b as usize]
        && x < words[(b + 1) as usize]
        && y >= words[(b + 2) as usize]
        && y < words[(b + 3) as usize];
    let f = j * LOADED;
    let dx = floats[(f + MEAN) as usize] - (f32::cast_from(x) + 0.5);
    let dy = floats[(f + MEAN + 1) as usize] - (f32::cast_from(y) + 0.5);
    let p = floats[(f + CHOLESKY) as usize] * dx + floats[(f + CHOLESKY + 1) as usize] * dy;
    let q = floats[(f + CHOLESKY + 2) as usize] * dy;
    let falloff = (0.0 - 0.5 * (p * p + q * q)).exp();
    let raw = floats[(f + OPACITY) as usize] * falloff;
    let alpha_min = limits[ALPHA_MIN];
    let mut alpha = raw.min(limits[ALPHA_MAX]);
    if smooth {
        let t = ((raw - alpha_min) / SMOOTH_CUTOFF_BAND).min(1.0f32);
        alpha = alpha * t * t * (3.0 - 2.0 * t);
    }
    if !(inside && raw >= alpha_min) {
        alpha = 0.0;
    }
    (alpha, falloff, dx, dy)
}

/// Forward blend: color, final transmittance and last blended list position per pixel.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn blend_forward(
    splats: &Tensor<f32>,
    boxes: &Tensor<u32>,
    entry_splat: &Tensor<u32>,
    tile_start: &Tensor<u32>,
    tile_end: &Tensor<u32>,
    frame: &Tensor<u32>,
    limits: &Tensor<f32>,
    image: &mut Tensor<f32>,
    transmittance: &mut Tensor<f32>,
    last: &mut Tensor<u32>,
    #[comptime] smooth: bool,
) {
    let mut floats = Shared::<[f32]>::new_slice(LOADED_SLOTS);
    let mut words = Shared::<[u32]>::new_slice(BOX_SLOTS);
    let (lx, ly, inside) = tile_pixel(frame);
    let w = frame_at::WINDOW as usize;
    let (x, y) = (frame[w] + lx, frame[w + 1] + ly);
    let tile = (CUBE_POS_Y * frame[frame_at::TILES_X as usize] + CUBE_POS_X) as usize;
    let (start, end) = (tile_start[tile], tile_end[tile]);
    let t_min = limits[T_MIN];
    let mut trans = 1.0f32.runtime();
    let mut r = 0.0f32.runtime();
    let mut g = 0.0f32.runtime();
    let mut b = 0.0f32.runtime();
    let mut blended = 0u32.runtime();
    let mut done = !inside;
    let mut base = start;
    while base < end {
        sync_cube();
        load_splat(splats, boxes, entry_splat, base + UNIT_POS, end, &mut floats, &mut words);
        sync_cube();
        let batch = (end - base).min(BLOCK);
        for j in 0..batch {
            if !done {
                let (alpha, _falloff, _dx, _dy) = sample(&floats, &words, j, x, y, limits, smooth);
                if alpha > 0.0 {
                    let next = trans * (1.0 - alpha);
                    if next <= t_min {
                        done = true;
                    } else {
                        let weight = alpha * trans;
                        let f = j * LOADED + COLOR;
                        r += floats[f as usize] * weight;
                        g += floats[(f + 1) as usize] * weight;
                        b += floats[(f + 2) as usize] * weight;
                        trans = next;
                        blended = base - start + j + 1;
                    }
                }
            }
        }
        base += BLOCK;
    }
    if inside {
        let p = output_index(frame, lx, ly);
        image[p * 3] = r + trans * limits[BACKGROUND];
        image[p * 3 + 1] = g + trans * limits[BACKGROUND + 1];
        image[p * 3 + 2] = b + trans * limits[BACKGROUND + 2];
        transmittance[p] = trans;
        last[p] = blended;
    }
}

/// The tile-wide maximum of `value` (through shared memory `scratch`, left undefined).
#[cube]
fn tile_max(value: u32, scratch: &mut Shared<[u32]>) -> u32 {
    let u = UNIT_POS as usize;
    scratch[u] = value;
    sync_cube();
    let mut stride = (BLOCK / 2).runtime();
    while stride > 0 {
        if UNIT_POS < stride {
            let other = scratch[u + stride as usize];
            if other > scratch[u] {
                scratch[u] = other;
            }
        }
        sync_cube();
        stride /= 2;
    }
    let result = scratch[0];
    sync_cube();
    result
}

/// Backward blend: each list entry's gradient (center, conic, opacity, color) from dL/d(color)
/// per pixel, into `entry_grads` at the entry's position before the tile sort (`entry_slot`).
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn blend_backward(
    splats: &Tensor<f32>,
    boxes: &Tensor<u32>,
    entry_splat: &Tensor<u32>,
    entry_slot: &Tensor<u32>,
    tile_start: &Tensor<u32>,
    frame: &Tensor<u32>,
    limits: &Tensor<f32>,
    transmittance: &Tensor<f32>,
    last: &Tensor<u32>,
    v_image: &Tensor<f32>,
    entry_grads: &mut Tensor<f32>,
    #[comptime] smooth: bool,
) {
    let mut floats = Shared::<[f32]>::new_slice(LOADED_SLOTS);
    let mut words = Shared::<[u32]>::new_slice(BOX_SLOTS);
    let mut slots = Shared::<[u32]>::new_slice(BLOCK_SLOTS);
    let mut sums = Shared::<[f32]>::new_slice(SUM_SLOTS);
    let mut row_sums = Shared::<[f32]>::new_slice(ROW_SUM_SLOTS);
    let (lx, ly, inside) = tile_pixel(frame);
    let w = frame_at::WINDOW as usize;
    let (x, y) = (frame[w] + lx, frame[w + 1] + ly);
    let tile = (CUBE_POS_Y * frame[frame_at::TILES_X as usize] + CUBE_POS_X) as usize;
    let start = tile_start[tile];
    let p = output_index(frame, lx, ly);

    let mut t_final = 1.0f32.runtime();
    let mut own_last = 0u32.runtime();
    let mut vr = 0.0f32.runtime();
    let mut vg = 0.0f32.runtime();
    let mut vb = 0.0f32.runtime();
    if inside {
        t_final = transmittance[p];
        own_last = last[p];
        vr = v_image[p * 3];
        vg = v_image[p * 3 + 1];
        vb = v_image[p * 3 + 2];
    }
    let bg_term = limits[BACKGROUND] * vr + limits[BACKGROUND + 1] * vg + limits[BACKGROUND + 2] * vb;
    let mut trans = t_final;
    let mut behind_r = 0.0f32.runtime();
    let mut behind_g = 0.0f32.runtime();
    let mut behind_b = 0.0f32.runtime();
    // Entries past every pixel's last blended one contribute nothing.
    let deepest = tile_max(own_last, &mut slots);
    let alpha_max = limits[ALPHA_MAX];
    let alpha_min = limits[ALPHA_MIN];
    let u = UNIT_POS;

    let mut top = start + deepest;
    while top > start {
        let low = select(top - start > BLOCK, top - BLOCK, start);
        sync_cube();
        load_splat(splats, boxes, entry_splat, low + u, top, &mut floats, &mut words);
        if low + u < top {
            slots[u as usize] = entry_slot[(low + u) as usize];
        }
        sync_cube();
        let batch = top - low;
        for step in 0..batch {
            let j = batch - 1 - step;
            let position = low - start + j;
            let (alpha, falloff, dx, dy) = sample(&floats, &words, j, x, y, limits, smooth);
            // center (2), conic (3), opacity, color (3): the order of ENTRY_GRAD.
            let mut g_mx = 0.0f32.runtime();
            let mut g_my = 0.0f32.runtime();
            let mut g_ca = 0.0f32.runtime();
            let mut g_cb = 0.0f32.runtime();
            let mut g_cc = 0.0f32.runtime();
            let mut g_op = 0.0f32.runtime();
            let mut g_r = 0.0f32.runtime();
            let mut g_g = 0.0f32.runtime();
            let mut g_b = 0.0f32.runtime();
            if position < own_last && alpha > 0.0 {
                let f = j * LOADED;
                let ra = 1.0 / (1.0 - alpha);
                trans *= ra;
                let cr = floats[(f + COLOR) as usize];
                let cg = floats[(f + COLOR + 1) as usize];
                let cb = floats[(f + COLOR + 2) as usize];
                let weight = alpha * trans;
                g_r = weight * vr;
                g_g = weight * vg;
                g_b = weight * vb;
                let v_alpha = -t_final * ra * bg_term
                    + (cr * trans - behind_r * ra) * vr
                    + (cg * trans - behind_g * ra) * vg
                    + (cb * trans - behind_b * ra) * vb;
                behind_r += cr * weight;
                behind_g += cg * weight;
                behind_b += cb * weight;
                let opacity = floats[(f + OPACITY) as usize];
                let raw = opacity * falloff;
                let mut slope = select(raw < alpha_max, 1.0f32, 0.0f32);
                if smooth {
                    let t = ((raw - alpha_min) / SMOOTH_CUTOFF_BAND).min(1.0f32);
                    let eased = t * t * (3.0 - 2.0 * t);
                    let d_eased = select(t < 1.0, 6.0 * t * (1.0 - t) / SMOOTH_CUTOFF_BAND, 0.0f32);
                    slope = slope * eased + raw.min(alpha_max) * d_eased;
                }
                let v_raw = v_alpha * slope;
                g_op = falloff * v_raw;
                let v_sigma = -opacity * falloff * v_raw;
                let a = floats[(f + CONIC) as usize];
                let b = floats[(f + CONIC + 1) as usize];
                let c = floats[(f + CONIC + 2) as usize];
                g_mx = (a * dx + b * dy) * v_sigma;
                g_my = (b * dx + c * dy) * v_sigma;
                g_ca = 0.5 * dx * dx * v_sigma;
                g_cb = dx * dy * v_sigma;
                g_cc = 0.5 * dy * dy * v_sigma;
            }
            let at = u as usize;
            let stride_c = BLOCK_SLOTS;
            sums[at] = g_mx;
            sums[at + stride_c] = g_my;
            sums[at + 2 * stride_c] = g_ca;
            sums[at + 3 * stride_c] = g_cb;
            sums[at + 4 * stride_c] = g_cc;
            sums[at + 5 * stride_c] = g_op;
            sums[at + 6 * stride_c] = g_r;
            sums[at + 7 * stride_c] = g_g;
            sums[at + 8 * stride_c] = g_b;
            sync_cube();
            // Two barriers a splat: each of ENTRY_GRAD x 16 units sums one row of the tile for
            // one value, then ENTRY_GRAD units sum the 16 rows. The next splat's writes to
            // `sums` come after every read of it (the second barrier), and its row sums after
            // the reads of these (its first barrier).
            if u < ENTRY_GRAD * TILE_SIZE {
                let (c, row) = (u / TILE_SIZE, u % TILE_SIZE);
                let first = (c * BLOCK + row * TILE_SIZE) as usize;
                let mut total = 0.0f32.runtime();
                for x in 0..TILE_SIZE {
                    total += sums[first + x as usize];
                }
                row_sums[u as usize] = total;
            }
            sync_cube();
            if u < ENTRY_GRAD {
                let mut total = 0.0f32.runtime();
                for row in 0..TILE_SIZE {
                    total += row_sums[(u * TILE_SIZE + row) as usize];
                }
                entry_grads[(slots[j as usize] * ENTRY_GRAD + u) as usize] = total;
            }
        }
        top = low;
    }
}

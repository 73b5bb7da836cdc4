//! Front-to-back blending eight pixels of a tile row at a time (`wide::f32x8`): the same
//! arithmetic as [`super::blend`], lane by lane and in the same order, so the image is bit for
//! bit the scalar path's (the tests compare them) at a fraction of its time.
//!
//! Each row of a splat's box is blended in chunks that start at the box's first column (one
//! chunk for a box up to eight pixels wide, two up to the tile's 16), not at fixed columns:
//! most splats are a few pixels wide, and a fixed grid would cut half of their rows in two.

use wide::{f32x8, i32x8, u32x8};

use super::blend::{Band, SMOOTH_CUTOFF_BAND};
use super::project::Splat;
use super::tiles::{ListOrder, TileBins};
use super::{Cutoff, RenderOptions, TILE_SIZE, Window};
use crate::portable_math::{EXP_F32_COEFFICIENTS, EXP_F32_HI, EXP_F32_LN2_HI, EXP_F32_LN2_LO, EXP_F32_LO, ROUND_F32};

/// Pixels per vector: a tile row is two chunks.
pub const LANES: usize = 8;

/// [`crate::portable_math::exp_f32`] on eight lanes, operation for operation.
#[inline]
fn exp8(x: f32x8) -> f32x8 {
    let round = f32x8::splat(ROUND_F32);
    let k = (x * f32x8::splat(std::f32::consts::LOG2_E) + round) - round;
    let r = (x - k * f32x8::splat(EXP_F32_LN2_HI)) - k * f32x8::splat(EXP_F32_LN2_LO);
    let p = EXP_F32_COEFFICIENTS.iter().fold(f32x8::splat(0.0), |p, &c| p * r + f32x8::splat(c));
    // k << 23 as k * 2^23 in f32 (exact: k is a whole number of at most 129 in magnitude
    // wherever the result is kept), because `wide`'s shift by a constant builds its count on
    // the stack and reloads it, a stalled store forwarding that took 12% of the blend.
    let shift: u32x8 = bytemuck::cast((k * f32x8::splat(8_388_608.0)).trunc_int());
    let scaled = f32x8::from_bits(p.to_bits() + shift);
    let scaled = x.simd_gt(f32x8::splat(EXP_F32_HI)).select(f32x8::splat(f32::INFINITY), scaled);
    x.simd_lt(f32x8::splat(EXP_F32_LO)).select(f32x8::splat(0.0), scaled)
}

/// [`super::blend::splat_alpha`] at eight pixels of a row.
#[derive(Debug, Clone, Copy)]
pub struct AlphaLanes {
    pub alpha: f32x8,
    pub falloff: f32x8,
    /// All ones in the lanes where the splat contributes (its alpha reaches alpha_min).
    pub contributes: f32x8,
}

/// The offsets from splat `s`'s center of the eight pixel centers from column `start` on, as
/// the scalar path computes each: `mean_x - (px + 0.5)`.
#[inline]
pub fn chunk_dx(s: &Splat, start: u32) -> f32x8 {
    f32x8::splat(s.mean[0]) - (f32x8::splat(start as f32) + f32x8::new(LANE_CENTERS))
}

/// [`super::blend::splat_alpha`] on eight lanes, operation for operation: offsets `dx` (see
/// [`chunk_dx`]) on a row at offset `dy`.
#[inline]
pub fn splat_alpha8(s: &Splat, dx: f32x8, dy: f32, options: &RenderOptions) -> AlphaLanes {
    let [l11, l21, l22] = s.cholesky;
    let q = l22 * dy;
    let p = f32x8::splat(l11) * dx + f32x8::splat(l21 * dy);
    let falloff = exp8(f32x8::splat(-0.5) * (p * p + f32x8::splat(q * q)));
    let raw = f32x8::splat(s.opacity) * falloff;
    let alpha_min = options.projection.alpha_min as f32;
    let contributes = !raw.simd_lt(f32x8::splat(alpha_min));
    let mut alpha = raw.min(f32x8::splat(options.alpha_max));
    if options.cutoff == Cutoff::Smooth {
        let t = ((raw - f32x8::splat(alpha_min)) / f32x8::splat(SMOOTH_CUTOFF_BAND)).min(f32x8::splat(1.0));
        alpha = alpha * t * t * (f32x8::splat(3.0) - f32x8::splat(2.0) * t);
    }
    AlphaLanes { alpha, falloff, contributes }
}

/// A tile's blending state, pixel by pixel, rows of [`TILE_SIZE`] (whatever the tile's width),
/// plus a vector's worth at the end: a splat's row is blended from the first pixel of its box
/// on, eight pixels at a time, so a chunk may start anywhere in a row and run past its end
/// (lanes outside the box are masked and written back unchanged).
struct TileState {
    trans: [f32; STATE_LEN],
    rgb: [[f32; STATE_LEN]; 3],
    depth: [f32; STATE_LEN],
    last: [i32; STATE_LEN],
    /// All ones in pixels that stopped blending.
    done: [u32; STATE_LEN],
}

const TILE_PIXELS: usize = (TILE_SIZE * TILE_SIZE) as usize;
const STATE_LEN: usize = TILE_PIXELS + LANES;

impl TileState {
    fn new() -> Self {
        Self {
            trans: [1.0; STATE_LEN],
            rgb: [[0.0; STATE_LEN]; 3],
            depth: [0.0; STATE_LEN],
            last: [0; STATE_LEN],
            done: [0; STATE_LEN],
        }
    }
}

/// The eight values of `a` from `o` on.
#[inline]
fn load(a: &[f32; STATE_LEN], o: usize) -> f32x8 {
    f32x8::new(a[o..o + LANES].try_into().expect("eight values"))
}

#[inline]
fn store(a: &mut [f32; STATE_LEN], o: usize, v: f32x8) {
    a[o..o + LANES].copy_from_slice(&v.to_array());
}

/// Lane offsets plus the pixel-center half: lane l of a chunk starting at x is pixel x + l,
/// centered at x + l + 0.5 (exact in f32 for any image size pwgs accepts).
const LANE_CENTERS: [f32; LANES] = [0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5];

/// [`super::blend::blend_band`], vectorized.
pub fn blend_band(ty: u32, bins: &TileBins, splats: &[Splat], options: &RenderOptions, mut band: Band) {
    let lane_index = i32x8::new([0, 1, 2, 3, 4, 5, 6, 7]);
    for tx in 0..bins.tiles_x {
        let t = (ty * bins.tiles_x + tx) as usize;
        let [x0, x1, y0, y1] = bins.tile_rect(t);
        let mut state = TileState::new();
        let mut remaining = (x1 - x0) as usize * (y1 - y0) as usize;
        for (k, s) in bins.splats(t, splats, ListOrder::FrontToBack) {
            if remaining == 0 {
                break;
            }
            let [bx0, bx1, by0, by1] = s.bbox;
            let (xa, xb) = (bx0.max(x0), bx1.min(x1));
            if xa >= xb {
                continue;
            }
            let contributor = i32x8::splat(k as i32 + 1);
            // At most two chunks a row (a tile row is 16 pixels): their offsets from the
            // splat's center and the lanes inside its box, the same on every row.
            let chunks = ((xb - xa) as usize).div_ceil(LANES);
            let dx = [0, 1].map(|c| chunk_dx(&s, xa + (c * LANES) as u32));
            let inside = [0, 1].map(|c| {
                let lanes = lane_index + i32x8::splat((c * LANES) as i32);
                bytemuck::cast::<i32x8, u32x8>(lanes.simd_lt(i32x8::splat((xb - xa) as i32)))
            });
            for py in by0.max(y0)..by1.min(y1) {
                let dy = s.mean[1] - (py as f32 + 0.5);
                let row = (py - y0) as usize * TILE_SIZE as usize + (xa - x0) as usize;
                for c in 0..chunks {
                    let o = row + c * LANES;
                    let done = u32x8::new(state.done[o..o + LANES].try_into().expect("eight values"));
                    let active: f32x8 = bytemuck::cast(inside[c] & !done);
                    if !active.any() {
                        continue;
                    }
                    let AlphaLanes { alpha, contributes, .. } = splat_alpha8(&s, dx[c], dy, options);
                    let valid = active & contributes;
                    let trans = load(&state.trans, o);
                    let next = trans * (f32x8::splat(1.0) - alpha);
                    let stop = valid & next.simd_le(f32x8::splat(options.transmittance_min));
                    if stop.any() {
                        let now_done = done | bytemuck::cast::<f32x8, u32x8>(stop);
                        state.done[o..o + LANES].copy_from_slice(&now_done.to_array());
                        remaining -= stop.to_bitmask().count_ones() as usize;
                    }
                    let blend = valid & !stop;
                    let weight = alpha * trans;
                    for ch in 0..3 {
                        let v = load(&state.rgb[ch], o);
                        store(&mut state.rgb[ch], o, blend.select(v + f32x8::splat(s.color[ch]) * weight, v));
                    }
                    let d = load(&state.depth, o);
                    store(&mut state.depth, o, blend.select(d + f32x8::splat(s.depth) * weight, d));
                    store(&mut state.trans, o, blend.select(next, trans));
                    let last = i32x8::new(state.last[o..o + LANES].try_into().expect("eight values"));
                    let last = bytemuck::cast::<f32x8, i32x8>(blend).select(contributor, last);
                    state.last[o..o + LANES].copy_from_slice(&last.to_array());
                }
            }
        }
        write_tile(&state, [x0, x1, y0, y1], bins.window, options, &mut band);
    }
}

/// Copies a finished tile into the band (whose first row is the tile's), as
/// [`super::blend::blend_band`] does.
fn write_tile(state: &TileState, [x0, x1, y0, y1]: [u32; 4], window: Window, options: &RenderOptions, band: &mut Band) {
    for py in y0..y1 {
        let row = (py - y0) as usize;
        for px in x0..x1 {
            let p = row * TILE_SIZE as usize + (px - x0) as usize;
            let o = row * window.width as usize + (px - window.x0) as usize;
            let trans = state.trans[p];
            for ch in 0..3 {
                band.color[o * 3 + ch] = state.rgb[ch][p] + trans * options.background[ch];
            }
            band.transmittance[o] = trans;
            let covered = 1.0 - trans;
            band.depth[o] = if covered > 0.0 { state.depth[p] / covered } else { 0.0 };
            band.last_contributor[o] = state.last[p] as u32;
        }
    }
}

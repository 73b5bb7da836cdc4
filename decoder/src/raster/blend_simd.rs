//! Front-to-back blending eight pixels of a tile row at a time (`wide::f32x8`): the same
//! arithmetic as [`super::blend`], lane by lane and in the same order, so the image is bit for
//! bit the scalar path's (the tests compare them) at a fraction of its time.
//!
//! A tile's state is kept as vectors: 16 rows of two 8-pixel chunks. Lanes outside the tile
//! (its right edge at the image border) start out done and never blend.

use wide::{f32x8, i32x8, u32x8};

use super::blend::{Band, SMOOTH_CUTOFF_BAND};
use super::project::Splat;
use super::tiles::{ListOrder, TileBins};
use super::{Cutoff, RenderOptions, TILE_SIZE, Window};
use crate::portable_math::{EXP_F32_COEFFICIENTS, EXP_F32_HI, EXP_F32_LN2_HI, EXP_F32_LN2_LO, EXP_F32_LO, ROUND_F32};

/// Pixels per vector: a tile row is two chunks.
pub const LANES: usize = 8;
const CHUNKS_PER_ROW: usize = TILE_SIZE as usize / LANES;
const CHUNKS: usize = TILE_SIZE as usize * CHUNKS_PER_ROW;

/// [`crate::portable_math::exp_f32`] on eight lanes, operation for operation.
#[inline]
fn exp8(x: f32x8) -> f32x8 {
    let round = f32x8::splat(ROUND_F32);
    let k = (x * f32x8::splat(std::f32::consts::LOG2_E) + round) - round;
    let r = (x - k * f32x8::splat(EXP_F32_LN2_HI)) - k * f32x8::splat(EXP_F32_LN2_LO);
    let p = EXP_F32_COEFFICIENTS.iter().fold(f32x8::splat(0.0), |p, &c| p * r + f32x8::splat(c));
    let shift: u32x8 = bytemuck::cast(k.trunc_int() << 23);
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

/// A tile's blending state.
struct TileState {
    trans: [f32x8; CHUNKS],
    rgb: [[f32x8; CHUNKS]; 3],
    depth: [f32x8; CHUNKS],
    last: [i32x8; CHUNKS],
    /// All ones in lanes that stopped blending (or lie outside the tile).
    done: [f32x8; CHUNKS],
}

/// Lane offsets plus the pixel-center half: lane l of a chunk starting at x is pixel x + l,
/// centered at x + l + 0.5 (exact in f32 for any image size pwgs accepts).
const LANE_CENTERS: [f32; LANES] = [0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5];

/// [`super::blend::blend_band`], vectorized.
pub fn blend_band(ty: u32, bins: &TileBins, splats: &[Splat], options: &RenderOptions, mut band: Band) {
    let window = bins.window;
    let all = f32x8::splat(f32::from_bits(u32::MAX));
    let lane_index = i32x8::new([0, 1, 2, 3, 4, 5, 6, 7]);
    for tx in 0..bins.tiles_x {
        let t = (ty * bins.tiles_x + tx) as usize;
        let [x0, x1, y0, y1] = bins.tile_rect(t);
        let tw = (x1 - x0) as i32;
        let mut state = TileState {
            trans: [f32x8::splat(1.0); CHUNKS],
            rgb: [[f32x8::splat(0.0); CHUNKS]; 3],
            depth: [f32x8::splat(0.0); CHUNKS],
            last: [i32x8::splat(0); CHUNKS],
            done: [f32x8::splat(0.0); CHUNKS],
        };
        // Lanes right of the tile's last column are done from the start.
        for c in 0..CHUNKS_PER_ROW {
            let outside: f32x8 =
                bytemuck::cast((lane_index + i32x8::splat((c * LANES) as i32)).simd_gt(i32x8::splat(tw - 1)));
            for row in 0..TILE_SIZE as usize {
                state.done[row * CHUNKS_PER_ROW + c] = outside;
            }
        }
        let mut remaining = tw as usize * (y1 - y0) as usize;
        for (k, s) in bins.splats(t, splats, ListOrder::FrontToBack) {
            if remaining == 0 {
                break;
            }
            let s = &s;
            let [bx0, bx1, by0, by1] = s.bbox;
            let (xa, xb) = (bx0.max(x0), bx1.min(x1));
            if xa >= xb {
                continue;
            }
            let contributor = i32x8::splat(k as i32 + 1);
            for py in by0.max(y0)..by1.min(y1) {
                let dy = s.mean[1] - (py as f32 + 0.5);
                let row = (py - y0) as usize * CHUNKS_PER_ROW;
                for c in ((xa - x0) as usize / LANES)..=((xb - 1 - x0) as usize / LANES) {
                    let i = row + c;
                    let start = x0 + (c * LANES) as u32;
                    let lanes = lane_index + i32x8::splat(start as i32);
                    let in_box = !(lanes.simd_lt(i32x8::splat(xa as i32)) | lanes.simd_gt(i32x8::splat(xb as i32 - 1)));
                    let active = bytemuck::cast::<i32x8, f32x8>(in_box) & !state.done[i];
                    if !active.any() {
                        continue;
                    }
                    let AlphaLanes { alpha, contributes, .. } = splat_alpha8(s, chunk_dx(s, start), dy, options);
                    let valid = active & contributes;
                    let trans = state.trans[i];
                    let next = trans * (f32x8::splat(1.0) - alpha);
                    let stop = valid & next.simd_le(f32x8::splat(options.transmittance_min));
                    state.done[i] |= stop;
                    remaining -= stop.to_bitmask().count_ones() as usize;
                    let blend = valid & (stop ^ all);
                    let weight = alpha * trans;
                    for ch in 0..3 {
                        let v = state.rgb[ch][i];
                        state.rgb[ch][i] = blend.select(v + f32x8::splat(s.color[ch]) * weight, v);
                    }
                    let d = state.depth[i];
                    state.depth[i] = blend.select(d + f32x8::splat(s.depth) * weight, d);
                    state.trans[i] = blend.select(next, trans);
                    state.last[i] = bytemuck::cast::<f32x8, i32x8>(blend).select(contributor, state.last[i]);
                }
            }
        }
        write_tile(&state, [x0, x1, y0, y1], window, options, &mut band);
    }
}

/// Copies a finished tile into the band (whose first row is the tile's), as
/// [`super::blend::blend_band`] does.
fn write_tile(state: &TileState, [x0, x1, y0, y1]: [u32; 4], window: Window, options: &RenderOptions, band: &mut Band) {
    for py in y0..y1 {
        let row = (py - y0) as usize;
        for c in 0..CHUNKS_PER_ROW {
            let i = row * CHUNKS_PER_ROW + c;
            let (trans, depth, last) = (state.trans[i].to_array(), state.depth[i].to_array(), state.last[i].to_array());
            let rgb = state.rgb.map(|channel| channel[i].to_array());
            for lane in 0..LANES {
                let px = x0 + (c * LANES + lane) as u32;
                if px >= x1 {
                    break;
                }
                let o = row * window.width as usize + (px - window.x0) as usize;
                for ch in 0..3 {
                    band.color[o * 3 + ch] = rgb[ch][lane] + trans[lane] * options.background[ch];
                }
                band.transmittance[o] = trans[lane];
                let covered = 1.0 - trans[lane];
                band.depth[o] = if covered > 0.0 { depth[lane] / covered } else { 0.0 };
                band.last_contributor[o] = last[lane] as u32;
            }
        }
    }
}

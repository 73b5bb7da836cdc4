//! Front-to-back blending eight pixels of a tile row at a time (eight f32 lanes: AVX2 where the
//! CPU has it, else `wide::f32x8`, see [`super::lanes`]): the same
//! arithmetic as [`super::blend`], lane by lane and in the same order, so the image is bit for
//! bit the scalar path's (the tests compare them) at a fraction of its time.
//!
//! Each row of a splat's box is blended in chunks that start at the box's first column (one
//! chunk for a box up to eight pixels wide, two up to the tile's 16), not at fixed columns:
//! most splats are a few pixels wide, and a fixed grid would cut half of their rows in two.

#[cfg(target_arch = "x86_64")]
use super::lanes::Avx2;
use super::lanes::{Lanes8, Portable};

use super::blend::{Band, SMOOTH_CUTOFF_BAND};
use super::project::Splat;
use super::tiles::{ListOrder, TileBins};
use super::{Cutoff, RenderOptions, TILE_SIZE, Window};
use crate::portable_math::{EXP_F32_COEFFICIENTS, EXP_F32_HI, EXP_F32_LN2_HI, EXP_F32_LN2_LO, EXP_F32_LO, ROUND_F32};

/// Pixels per vector: a tile row is two chunks.
pub const LANES: usize = 8;

/// [`crate::portable_math::exp_f32`] on eight lanes, operation for operation.
#[inline(always)]
fn exp8<L: Lanes8>(l: L, x: L::V) -> L::V {
    let round = l.splat(ROUND_F32);
    let k = l.sub(l.add(l.mul(x, l.splat(std::f32::consts::LOG2_E)), round), round);
    let r = l.sub(l.sub(x, l.mul(k, l.splat(EXP_F32_LN2_HI))), l.mul(k, l.splat(EXP_F32_LN2_LO)));
    // Loops, not closures, here and in the blend: a closure is a function of its own, compiled
    // without the AVX2 features, and the operations in it would not be inlined.
    let mut p = l.splat(0.0);
    for c in EXP_F32_COEFFICIENTS {
        p = l.add(l.mul(p, r), l.splat(c));
    }
    // k << 23 as the integer k * 2^23 (exact: k is a whole number of at most 129 in magnitude
    // wherever the result is kept): `wide`'s shift by a constant builds its count on the stack
    // and reloads it, a stalled store forwarding that took 12% of the blend.
    let scaled = l.add_bits(p, l.trunc_int(l.mul(k, l.splat(8_388_608.0))));
    let scaled = l.select(l.gt(x, l.splat(EXP_F32_HI)), l.splat(f32::INFINITY), scaled);
    l.select(l.lt(x, l.splat(EXP_F32_LO)), l.splat(0.0), scaled)
}

/// [`super::blend::splat_alpha`] at eight pixels of a row.
#[derive(Debug, Clone, Copy)]
pub struct AlphaLanes<V> {
    pub alpha: V,
    pub falloff: V,
    /// All ones in the lanes where the splat contributes (its alpha reaches alpha_min).
    pub contributes: V,
}

/// The offsets from splat `s`'s center of the eight pixel centers from column `start` on, as
/// the scalar path computes each: `mean_x - (px + 0.5)`.
#[inline(always)]
pub fn chunk_dx<L: Lanes8>(l: L, s: &Splat, start: u32) -> L::V {
    l.sub(l.splat(s.mean[0]), l.add(l.splat(start as f32), l.load_array(LANE_CENTERS)))
}

/// [`super::blend::splat_alpha`] on eight lanes, operation for operation: offsets `dx` (see
/// [`chunk_dx`]) on a row at offset `dy`.
#[inline(always)]
pub fn splat_alpha8<L: Lanes8>(l: L, s: &Splat, dx: L::V, dy: f32, options: &RenderOptions) -> AlphaLanes<L::V> {
    let [l11, l21, l22] = s.cholesky;
    let q = l22 * dy;
    let p = l.add(l.mul(l.splat(l11), dx), l.splat(l21 * dy));
    let falloff = exp8(l, l.mul(l.splat(-0.5), l.add(l.mul(p, p), l.splat(q * q))));
    let raw = l.mul(l.splat(s.opacity), falloff);
    let alpha_min = options.projection.alpha_min as f32;
    let contributes = l.and_not(l.splat(f32::from_bits(u32::MAX)), l.lt(raw, l.splat(alpha_min)));
    let mut alpha = l.min(raw, l.splat(options.alpha_max));
    if options.cutoff == Cutoff::Smooth {
        let t = l.min(l.div(l.sub(raw, l.splat(alpha_min)), l.splat(SMOOTH_CUTOFF_BAND)), l.splat(1.0));
        alpha = l.mul(l.mul(l.mul(alpha, t), t), l.sub(l.splat(3.0), l.mul(l.splat(2.0), t)));
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
    /// One past the list position of the last splat blended, as bits (only ever selected).
    last: [f32; STATE_LEN],
    /// All ones in pixels that stopped blending, as bits.
    done: [f32; STATE_LEN],
}

const TILE_PIXELS: usize = (TILE_SIZE * TILE_SIZE) as usize;
const STATE_LEN: usize = TILE_PIXELS + LANES;

impl TileState {
    fn new() -> Self {
        Self {
            trans: [1.0; STATE_LEN],
            rgb: [[0.0; STATE_LEN]; 3],
            depth: [0.0; STATE_LEN],
            last: [0.0; STATE_LEN],
            done: [0.0; STATE_LEN],
        }
    }
}

/// The eight values of `a` from `o` on.
#[inline(always)]
fn load<L: Lanes8>(l: L, a: &[f32; STATE_LEN], o: usize) -> L::V {
    l.load_array(a[o..o + LANES].try_into().expect("eight values"))
}

#[inline(always)]
fn store<L: Lanes8>(l: L, a: &mut [f32; STATE_LEN], o: usize, v: L::V) {
    a[o..o + LANES].copy_from_slice(&l.to_array(v));
}

/// Lane offsets plus the pixel-center half: lane l of a chunk starting at x is pixel x + l,
/// centered at x + l + 0.5 (exact in f32 for any image size pwgs accepts).
const LANE_CENTERS: [f32; LANES] = [0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5];

/// [`super::blend::blend_band`], vectorized: with AVX2 where the CPU has it (unless `portable`
/// asks for `wide`'s vectors), else with `wide`'s.
pub fn blend_band(ty: u32, bins: &TileBins, splats: &[Splat], options: &RenderOptions, band: Band, portable: bool) {
    #[cfg(target_arch = "x86_64")]
    if let Some(avx2) = Avx2::detect().filter(|_| !portable) {
        return avx2.0.vectorize(
            #[inline(always)]
            || blend_band_in(avx2, ty, bins, splats, options, band),
        );
    }
    blend_band_in(Portable, ty, bins, splats, options, band)
}

#[inline(always)]
fn blend_band_in<L: Lanes8>(l: L, ty: u32, bins: &TileBins, splats: &[Splat], options: &RenderOptions, mut band: Band) {
    let lane_index = l.load_array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
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
            let contributor = l.splat(f32::from_bits(k as u32 + 1));
            // At most two chunks a row (a tile row is 16 pixels): their offsets from the
            // splat's center and the lanes inside its box, the same on every row.
            let chunks = ((xb - xa) as usize).div_ceil(LANES);
            let dx = [chunk_dx(l, &s, xa), chunk_dx(l, &s, xa + LANES as u32)];
            let width = l.splat((xb - xa) as f32);
            let inside = [l.lt(lane_index, width), l.lt(l.add(lane_index, l.splat(LANES as f32)), width)];
            for py in by0.max(y0)..by1.min(y1) {
                let dy = s.mean[1] - (py as f32 + 0.5);
                let row = (py - y0) as usize * TILE_SIZE as usize + (xa - x0) as usize;
                for c in 0..chunks {
                    let o = row + c * LANES;
                    let done = load(l, &state.done, o);
                    let active = l.and_not(inside[c], done);
                    if l.bitmask(active) == 0 {
                        continue;
                    }
                    let AlphaLanes { alpha, contributes, .. } = splat_alpha8(l, &s, dx[c], dy, options);
                    let valid = l.and(active, contributes);
                    let trans = load(l, &state.trans, o);
                    let next = l.mul(trans, l.sub(l.splat(1.0), alpha));
                    let stop = l.and(valid, l.le(next, l.splat(options.transmittance_min)));
                    let stopped = l.bitmask(stop);
                    if stopped != 0 {
                        store(l, &mut state.done, o, l.or(done, stop));
                        remaining -= stopped.count_ones() as usize;
                    }
                    let blend = l.and_not(valid, stop);
                    let weight = l.mul(alpha, trans);
                    for ch in 0..3 {
                        let v = load(l, &state.rgb[ch], o);
                        let sum = l.add(v, l.mul(l.splat(s.color[ch]), weight));
                        store(l, &mut state.rgb[ch], o, l.select(blend, sum, v));
                    }
                    let d = load(l, &state.depth, o);
                    store(l, &mut state.depth, o, l.select(blend, l.add(d, l.mul(l.splat(s.depth), weight)), d));
                    store(l, &mut state.trans, o, l.select(blend, next, trans));
                    let last = load(l, &state.last, o);
                    store(l, &mut state.last, o, l.select(blend, contributor, last));
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
            band.last_contributor[o] = state.last[p].to_bits();
        }
    }
}

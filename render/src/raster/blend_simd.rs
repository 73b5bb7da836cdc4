//! Front-to-back blending eight pixels of a tile row at a time (eight f32 lanes: AVX2 where the
//! CPU has it, else `wide::f32x8`, see [`super::lanes`]): the blending arithmetic of
//! [`super::blend`], lane by lane and in the same order, with alpha from
//! [`super::alpha_lanes`] (a cheaper falloff of stated error), so the image is within rounding
//! of the scalar path's (the tests bound the difference) at a fraction of its time. AVX2 and
//! portable lanes give the same bits.
//!
//! Each row of a splat's box is blended in chunks that start at the box's first column (one
//! chunk for a box up to eight pixels wide, two up to the tile's 16), not at fixed columns:
//! most splats are a few pixels wide, and a fixed grid would cut half of their rows in two.

use super::lanes::{LaneKernel, Lanes4d, Lanes8, run_kernel};

use super::alpha_lanes::{AlphaLanes, LANES, SplatRows, box_lanes, chunk_dx};
use super::blend::Band;
use super::project::Splat;
use super::tiles::{ListOrder, TileBins};
use super::{RenderOptions, TILE_SIZE, Window};

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

/// [`super::blend::blend_band`], vectorized: with AVX2 where the CPU has it (unless `portable`
/// asks for `wide`'s vectors), else with `wide`'s.
pub fn blend_band(ty: u32, bins: &TileBins, splats: &[Splat], options: &RenderOptions, band: Band, portable: bool) {
    run_kernel(BandKernel { ty, bins, splats, options, band }, portable)
}

/// [`blend_band`]'s arguments, to run on the lanes [`run_kernel`] picks.
struct BandKernel<'a> {
    ty: u32,
    bins: &'a TileBins,
    splats: &'a [Splat],
    options: &'a RenderOptions,
    band: Band<'a>,
}

impl LaneKernel for BandKernel<'_> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lanes4d>(self, l: L) {
        blend_band_in(l, self.ty, self.bins, self.splats, self.options, self.band)
    }
}

#[inline(always)]
fn blend_band_in<L: Lanes8>(l: L, ty: u32, bins: &TileBins, splats: &[Splat], options: &RenderOptions, mut band: Band) {
    for tx in 0..bins.tiles_x {
        let t = (ty * bins.tiles_x + tx) as usize;
        let [x0, x1, y0, y1] = bins.tile_rect(t);
        let mut state = TileState::new();
        let mut remaining = (x1 - x0) as usize * (y1 - y0) as usize;
        let mut list = bins.splats(t, splats, ListOrder::FrontToBack);
        'tile: while let Some(block) = list.next_block() {
            for &(k, ref s) in block {
                if remaining == 0 {
                    break 'tile;
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
                let rows = SplatRows::new(l, s, [chunk_dx(l, s, xa), chunk_dx(l, s, xa + LANES as u32)]);
                let inside = box_lanes(l, xb - xa);
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
                        let AlphaLanes { alpha, contributes, .. } = rows.alpha(l, c, dy, options);
                        let valid = l.and(active, contributes);
                        let trans = load(l, &state.trans, o);
                        let next = l.mul(trans, l.sub(l.splat(1.0), alpha));
                        let stop = l.and(valid, l.le(next, l.splat(options.transmittance_min)));
                        let stopped = l.bitmask(stop);
                        if stopped != 0 {
                            store(l, &mut state.done, o, l.or(done, stop));
                            remaining -= stopped.count_ones() as usize;
                        }
                        // Alpha is zero outside `blend`, where the updates below then leave
                        // the state as it was (x + 0 = x and T (1 - 0) = T exactly; colors and
                        // depths are never negative) without a select: LLVM turns a select
                        // stored back where it was loaded into a masked store, which the next
                        // splat's load of the same pixels cannot be forwarded from (twice the
                        // time of the blend in a release build on AMD).
                        let blend = l.and_not(valid, stop);
                        let alpha = l.and(blend, alpha);
                        let weight = l.mul(alpha, trans);
                        for ch in 0..3 {
                            let v = load(l, &state.rgb[ch], o);
                            store(l, &mut state.rgb[ch], o, l.add(v, l.mul(l.splat(s.color[ch]), weight)));
                        }
                        let d = load(l, &state.depth, o);
                        store(l, &mut state.depth, o, l.add(d, l.mul(l.splat(s.depth), weight)));
                        store(l, &mut state.trans, o, l.mul(trans, l.sub(l.splat(1.0), alpha)));
                        // Positions grow along the list, so the last contributor is the largest.
                        let last = load(l, &state.last, o);
                        store(l, &mut state.last, o, l.max_bits(last, l.and(blend, contributor)));
                    }
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

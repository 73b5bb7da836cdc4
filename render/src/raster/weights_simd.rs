//! Each Gaussian's summed blending weight over a window ([`super::blend::splat_weights`]),
//! eight pixels of a tile row at a time: the decisions of [`super::blend_simd`]'s forward blend
//! (its cheaper falloff, its stops), with each splat's weights summed in its lanes and the lanes
//! added in a fixed order once the splat is done. The encoder measures importance from these
//! sums over dozens of views, where the scalar walk took 80% of an import's time; AVX2 and
//! portable lanes give the same bits, so the sums do not depend on the CPU either.

use super::alpha_lanes::{AlphaLanes, LANES, SplatRows, box_lanes, chunk_dx};
use super::lanes::{LaneKernel, Lanes4d, Lanes8, run_kernel};
use super::project::Splat;
use super::tiles::{ListOrder, TileBins};
use super::{RenderOptions, TILE_SIZE};

/// A tile's transmittance and stopped pixels, rows of [`TILE_SIZE`] plus a vector's worth at
/// the end (a splat's row chunk may run past the row, as in [`super::blend_simd`]).
const STATE_LEN: usize = (TILE_SIZE * TILE_SIZE) as usize + LANES;

/// Per Gaussian (`0 .. gaussians`), `sum T * alpha` over the pixels of the bins' window its
/// splat is blended into, on the vector lanes (`portable` asks for `wide`'s whatever the CPU).
/// Tiles in order on one thread, so the sums do not depend on threads.
pub fn splat_weights(bins: &TileBins, splats: &[Splat], options: &RenderOptions, gaussians: usize, portable: bool) -> Vec<f32> {
    run_kernel(WeightsKernel { bins, splats, options, gaussians }, portable)
}

struct WeightsKernel<'a> {
    bins: &'a TileBins,
    splats: &'a [Splat],
    options: &'a RenderOptions,
    gaussians: usize,
}

impl LaneKernel for WeightsKernel<'_> {
    type Output = Vec<f32>;
    #[inline(always)]
    fn run<L: Lanes4d>(self, l: L) -> Vec<f32> {
        let mut weights = vec![0.0f32; self.gaussians];
        for t in 0..(self.bins.tiles_x * self.bins.tiles_y) as usize {
            tile_weights(l, t, self.bins, self.splats, self.options, &mut weights);
        }
        weights
    }
}

#[inline(always)]
fn tile_weights<L: Lanes8>(l: L, t: usize, bins: &TileBins, splats: &[Splat], options: &RenderOptions, weights: &mut [f32]) {
    let [x0, x1, y0, y1] = bins.tile_rect(t);
    let mut trans = [1.0f32; STATE_LEN];
    let mut done = [0.0f32; STATE_LEN];
    let mut remaining = (x1 - x0) as usize * (y1 - y0) as usize;
    let mut list = bins.splats(t, splats, ListOrder::FrontToBack);
    'tile: while let Some(block) = list.next_block() {
        for (_, s) in block {
            if remaining == 0 {
                break 'tile;
            }
            let [bx0, bx1, by0, by1] = s.bbox;
            let (xa, xb) = (bx0.max(x0), bx1.min(x1));
            if xa >= xb {
                continue;
            }
            let chunks = ((xb - xa) as usize).div_ceil(LANES);
            let rows = SplatRows::new(l, s, [chunk_dx(l, s, xa), chunk_dx(l, s, xa + LANES as u32)]);
            let inside = box_lanes(l, xb - xa);
            let mut sum = l.splat(0.0);
            for py in by0.max(y0)..by1.min(y1) {
                let dy = s.mean[1] - (py as f32 + 0.5);
                let row = (py - y0) as usize * TILE_SIZE as usize + (xa - x0) as usize;
                for c in 0..chunks {
                    let o = row + c * LANES;
                    let stopped = load(l, &done, o);
                    let active = l.and_not(inside[c], stopped);
                    if l.bitmask(active) == 0 {
                        continue;
                    }
                    let AlphaLanes { alpha, contributes, .. } = rows.alpha(l, c, dy, options);
                    let valid = l.and(active, contributes);
                    let before = load(l, &trans, o);
                    let next = l.mul(before, l.sub(l.splat(1.0), alpha));
                    let stop = l.and(valid, l.le(next, l.splat(options.transmittance_min)));
                    let count = l.bitmask(stop);
                    if count != 0 {
                        store(l, &mut done, o, l.or(stopped, stop));
                        remaining -= count.count_ones() as usize;
                    }
                    let alpha = l.and(l.and_not(valid, stop), alpha);
                    sum = l.add(sum, l.mul(alpha, before));
                    store(l, &mut trans, o, l.mul(before, l.sub(l.splat(1.0), alpha)));
                }
            }
            weights[s.index as usize] += l.to_array(sum).iter().fold(0.0, |a, &w| a + w);
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

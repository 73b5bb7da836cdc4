//! The parts of a render that are linear in the Gaussians' colours, eight pixels of a tile row
//! at a time: each Gaussian's summed blending weight ([`super::blend::splat_weights`]), the
//! colour map and its adjoint ([`super::blend::ColourMap`]). All three walk a tile with the
//! decisions of [`super::blend_simd`]'s forward blend (its cheaper falloff, its stops) and hand
//! each chunk's weights `T * alpha` to a [`Visit`]. The encoder measures importance and refits
//! colours with these over dozens of views, where the scalar walk took most of an import's
//! time. Sums run in a fixed order (tiles in order on one thread, a splat's lanes added in lane
//! order), and AVX2 and portable lanes give the same bits, so nothing depends on the CPU.

use super::alpha_lanes::{AlphaLanes, LANES, SplatRows, box_lanes, chunk_dx};
use super::lanes::{LaneKernel, Lanes4d, Lanes8, run_kernel};
use super::project::Splat;
use super::tiles::{ListOrder, TileBins};
use super::{RenderOptions, TILE_SIZE};

/// Per-pixel state of a tile, rows of [`TILE_SIZE`] (whatever the tile's width) plus a vector's
/// worth at the end: a splat's row is walked from the first pixel of its box on, eight pixels
/// at a time, so a chunk may run past the row's end (its lanes outside the box are masked).
const STATE_LEN: usize = (TILE_SIZE * TILE_SIZE) as usize + LANES;

type TileValues = [f32; STATE_LEN];

/// What a walk does with the weights it finds.
trait Visit<L: Lanes8> {
    /// Tile `rect` (`[x0, x1, y0, y1]`, image pixels) begins.
    fn tile(&mut self, _l: L, _rect: [u32; 4]) {}
    /// A splat begins.
    fn splat(&mut self, _l: L, _s: &Splat) {}
    /// The splat's weights at the chunk starting at tile offset `o` (zero in lanes it does not
    /// blend into).
    fn chunk(&mut self, l: L, s: &Splat, o: usize, weight: L::V);
    /// The splat is done in this tile.
    fn splat_done(&mut self, _l: L, _s: &Splat) {}
    /// The tile is done.
    fn tile_done(&mut self, _l: L, _rect: [u32; 4]) {}
}

/// The splats of a view binned in tiles, with the options that decide their blending: what
/// every walk goes over.
#[derive(Clone, Copy)]
struct Walk<'a> {
    bins: &'a TileBins,
    splats: &'a [Splat],
    options: &'a RenderOptions,
}

/// Walks every tile of `bins` in order, front to back, with `visit`.
#[inline(always)]
fn walk<L: Lanes8, V: Visit<L>>(l: L, Walk { bins, splats, options }: Walk, visit: &mut V) {
    for t in 0..(bins.tiles_x * bins.tiles_y) as usize {
        let rect @ [x0, x1, y0, y1] = bins.tile_rect(t);
        visit.tile(l, rect);
        let mut trans: TileValues = [1.0; STATE_LEN];
        let mut done: TileValues = [0.0; STATE_LEN];
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
                visit.splat(l, s);
                let chunks = ((xb - xa) as usize).div_ceil(LANES);
                let rows = SplatRows::new(l, s, [chunk_dx(l, s, xa), chunk_dx(l, s, xa + LANES as u32)]);
                let inside = box_lanes(l, xb - xa);
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
                        visit.chunk(l, s, o, l.mul(alpha, before));
                        store(l, &mut trans, o, l.mul(before, l.sub(l.splat(1.0), alpha)));
                    }
                }
                visit.splat_done(l, s);
            }
        }
        visit.tile_done(l, rect);
    }
}

/// Each pixel of tile `rect` (`[x0, x1, y0, y1]`) as its offset in the tile's planes and that of
/// its red value in an RGB image of the window `[x0, y0, width]`.
fn tile_pixels([x0, x1, y0, y1]: [u32; 4], [wx, wy, width]: [u32; 3]) -> impl Iterator<Item = (usize, usize)> {
    (y0..y1).flat_map(move |py| {
        (x0..x1).map(move |px| {
            let p = (py - y0) as usize * TILE_SIZE as usize + (px - x0) as usize;
            (p, ((py - wy) as usize * width as usize + (px - wx) as usize) * 3)
        })
    })
}

/// The lanes of `v` added in lane order.
#[inline(always)]
fn lane_sum<L: Lanes8>(l: L, v: L::V) -> f32 {
    l.to_array(v).iter().fold(0.0, |a, &w| a + w)
}

/// The eight values of `a` from `o` on.
#[inline(always)]
fn load<L: Lanes8>(l: L, a: &TileValues, o: usize) -> L::V {
    l.load_array(a[o..o + LANES].try_into().expect("eight values"))
}

#[inline(always)]
fn store<L: Lanes8>(l: L, a: &mut TileValues, o: usize, v: L::V) {
    a[o..o + LANES].copy_from_slice(&l.to_array(v));
}

/// Per Gaussian (`0 .. gaussians`), `sum T * alpha` over the pixels of the bins' window its
/// splat is blended into (`portable` asks for `wide`'s lanes whatever the CPU).
pub fn splat_weights(
    bins: &TileBins,
    splats: &[Splat],
    options: &RenderOptions,
    gaussians: usize,
    portable: bool,
) -> Vec<f32> {
    run_kernel(WeightsKernel { walk: Walk { bins, splats, options }, gaussians }, portable)
}

struct WeightsKernel<'a> {
    walk: Walk<'a>,
    gaussians: usize,
}

/// Sums each splat's weights in its lanes, and the lanes once the splat is done.
struct Weights<V> {
    weights: Vec<f32>,
    sum: V,
}

impl<L: Lanes8> Visit<L> for Weights<L::V> {
    #[inline(always)]
    fn splat(&mut self, l: L, _s: &Splat) {
        self.sum = l.splat(0.0);
    }
    #[inline(always)]
    fn chunk(&mut self, l: L, _s: &Splat, _o: usize, weight: L::V) {
        self.sum = l.add(self.sum, weight);
    }
    #[inline(always)]
    fn splat_done(&mut self, l: L, s: &Splat) {
        self.weights[s.index as usize] += lane_sum(l, self.sum);
    }
}

impl LaneKernel for WeightsKernel<'_> {
    type Output = Vec<f32>;
    #[inline(always)]
    fn run<L: Lanes4d>(self, l: L) -> Vec<f32> {
        let mut visit = Weights { weights: vec![0.0; self.gaussians], sum: l.splat(0.0) };
        walk(l, self.walk, &mut visit);
        visit.weights
    }
}

/// The image `sum w values[i]` over the bins' window (no background), RGB interleaved.
pub fn colour_map_apply(
    bins: &TileBins,
    splats: &[Splat],
    options: &RenderOptions,
    values: &[[f32; 3]],
    portable: bool,
) -> Vec<f32> {
    run_kernel(ApplyKernel { walk: Walk { bins, splats, options }, values }, portable)
}

struct ApplyKernel<'a> {
    walk: Walk<'a>,
    values: &'a [[f32; 3]],
}

/// Adds each splat's value times its weights into the tile's planes, then copies the tile
/// into the image.
struct Apply<'a> {
    values: &'a [[f32; 3]],
    tile: [TileValues; 3],
    image: Vec<f32>,
    /// The image's window: origin and width.
    window: [u32; 3],
}

impl<L: Lanes8> Visit<L> for Apply<'_> {
    #[inline(always)]
    fn tile(&mut self, _l: L, _rect: [u32; 4]) {
        self.tile = [[0.0; STATE_LEN]; 3];
    }
    #[inline(always)]
    fn chunk(&mut self, l: L, s: &Splat, o: usize, weight: L::V) {
        let value = self.values[s.index as usize];
        for (plane, v) in self.tile.iter_mut().zip(value) {
            store(l, plane, o, l.add(load(l, plane, o), l.mul(l.splat(v), weight)));
        }
    }
    #[inline(always)]
    fn tile_done(&mut self, _l: L, rect: [u32; 4]) {
        for (p, o) in tile_pixels(rect, self.window) {
            (0..3).for_each(|c| self.image[o + c] = self.tile[c][p]);
        }
    }
}

impl LaneKernel for ApplyKernel<'_> {
    type Output = Vec<f32>;
    #[inline(always)]
    fn run<L: Lanes4d>(self, l: L) -> Vec<f32> {
        let w = self.walk.bins.window;
        let image = vec![0.0; w.width as usize * w.height as usize * 3];
        let mut visit =
            Apply { values: self.values, tile: [[0.0; STATE_LEN]; 3], image, window: [w.x0, w.y0, w.width] };
        walk(l, self.walk, &mut visit);
        visit.image
    }
}

/// Per Gaussian (`0 .. gaussians`), `sum w image` over the pixels it is blended into, and
/// `sum w^2`: the colour map's adjoint applied to `image` (RGB interleaved over the bins'
/// window) and the diagonal of its normal matrix.
pub fn colour_map_transpose(
    bins: &TileBins,
    splats: &[Splat],
    options: &RenderOptions,
    (image, gaussians): (&[f32], usize),
    portable: bool,
) -> (Vec<[f32; 3]>, Vec<f32>) {
    run_kernel(TransposeKernel { walk: Walk { bins, splats, options }, image, gaussians }, portable)
}

struct TransposeKernel<'a> {
    walk: Walk<'a>,
    image: &'a [f32],
    gaussians: usize,
}

/// Copies each tile of the image into planes, sums each splat's weighted values and squared
/// weights in its lanes, and the lanes once the splat is done.
struct Transpose<'a, V> {
    image: &'a [f32],
    window: [u32; 3],
    tile: [TileValues; 3],
    sums: Vec<[f32; 3]>,
    squares: Vec<f32>,
    lanes: [V; 4],
}

impl<L: Lanes8> Visit<L> for Transpose<'_, L::V> {
    #[inline(always)]
    fn tile(&mut self, _l: L, rect: [u32; 4]) {
        for (p, o) in tile_pixels(rect, self.window) {
            (0..3).for_each(|c| self.tile[c][p] = self.image[o + c]);
        }
    }
    #[inline(always)]
    fn splat(&mut self, l: L, _s: &Splat) {
        self.lanes = [l.splat(0.0); 4];
    }
    #[inline(always)]
    fn chunk(&mut self, l: L, _s: &Splat, o: usize, weight: L::V) {
        for c in 0..3 {
            self.lanes[c] = l.add(self.lanes[c], l.mul(weight, load(l, &self.tile[c], o)));
        }
        self.lanes[3] = l.add(self.lanes[3], l.mul(weight, weight));
    }
    #[inline(always)]
    fn splat_done(&mut self, l: L, s: &Splat) {
        let i = s.index as usize;
        (0..3).for_each(|c| self.sums[i][c] += lane_sum(l, self.lanes[c]));
        self.squares[i] += lane_sum(l, self.lanes[3]);
    }
}

impl LaneKernel for TransposeKernel<'_> {
    type Output = (Vec<[f32; 3]>, Vec<f32>);
    #[inline(always)]
    fn run<L: Lanes4d>(self, l: L) -> Self::Output {
        let w = self.walk.bins.window;
        let mut visit = Transpose {
            image: self.image,
            window: [w.x0, w.y0, w.width],
            // Pixels past a narrow tile's width stay 0 (their weights are 0 too).
            tile: [[0.0; STATE_LEN]; 3],
            sums: vec![[0.0; 3]; self.gaussians],
            squares: vec![0.0; self.gaussians],
            lanes: [l.splat(0.0); 4],
        };
        walk(l, self.walk, &mut visit);
        (visit.sums, visit.squares)
    }
}

/// The colour map applied to `values` and, in the same walk, its adjoint applied to that image:
/// `(A v, A^T A v)` over the bins' window (see [`colour_map_apply`], [`colour_map_transpose`]).
/// A pixel belongs to one tile, so its value is complete once the tile's splats are walked:
/// each splat's weights are kept for the tile and replayed against it, and the falloffs are
/// evaluated once instead of twice (conjugate gradients need both products every iteration).
pub fn colour_map_normal(
    bins: &TileBins,
    splats: &[Splat],
    options: &RenderOptions,
    (values, gaussians): (&[[f32; 3]], usize),
    portable: bool,
) -> (Vec<f32>, Vec<[f32; 3]>) {
    run_kernel(NormalKernel { walk: Walk { bins, splats, options }, values, gaussians }, portable)
}

struct NormalKernel<'a> {
    walk: Walk<'a>,
    values: &'a [[f32; 3]],
    gaussians: usize,
}

/// [`Apply`], keeping each chunk's weights (splat, tile offset, lanes) until the tile is done,
/// then summing each splat's weighted image values in its lanes, in the walk's order.
struct Normal<'a> {
    apply: Apply<'a>,
    kept: Vec<(u32, usize, [f32; LANES])>,
    normal: Vec<[f32; 3]>,
}

impl<L: Lanes8> Visit<L> for Normal<'_> {
    #[inline(always)]
    fn tile(&mut self, l: L, rect: [u32; 4]) {
        Visit::<L>::tile(&mut self.apply, l, rect);
        self.kept.clear();
    }
    #[inline(always)]
    fn chunk(&mut self, l: L, s: &Splat, o: usize, weight: L::V) {
        self.apply.chunk(l, s, o, weight);
        self.kept.push((s.index, o, l.to_array(weight)));
    }
    #[inline(always)]
    fn tile_done(&mut self, l: L, rect: [u32; 4]) {
        let mut kept = self.kept.iter().peekable();
        while let Some(&(index, o, weight)) = kept.next() {
            let weight = l.load_array(weight);
            let mut lanes = [l.splat(0.0); 3];
            for c in 0..3 {
                lanes[c] = l.mul(weight, load(l, &self.apply.tile[c], o));
            }
            // The splat's further chunks in this tile (they follow each other).
            while let Some(&(_, o, weight)) = kept.next_if(|(next, ..)| *next == index) {
                let weight = l.load_array(weight);
                for c in 0..3 {
                    lanes[c] = l.add(lanes[c], l.mul(weight, load(l, &self.apply.tile[c], o)));
                }
            }
            (0..3).for_each(|c| self.normal[index as usize][c] += lane_sum(l, lanes[c]));
        }
        Visit::<L>::tile_done(&mut self.apply, l, rect);
    }
}

impl LaneKernel for NormalKernel<'_> {
    type Output = (Vec<f32>, Vec<[f32; 3]>);
    #[inline(always)]
    fn run<L: Lanes4d>(self, l: L) -> Self::Output {
        let w = self.walk.bins.window;
        let image = vec![0.0; w.width as usize * w.height as usize * 3];
        let apply = Apply { values: self.values, tile: [[0.0; STATE_LEN]; 3], image, window: [w.x0, w.y0, w.width] };
        let mut visit = Normal { apply, kept: Vec::new(), normal: vec![[0.0; 3]; self.gaussians] };
        walk(l, self.walk, &mut visit);
        (visit.apply.image, visit.normal)
    }
}

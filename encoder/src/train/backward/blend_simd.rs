//! The backward walk through a tile four pixels at a time (f64 lanes: AVX2 registers where the
//! CPU has them, else `wide::f64x4`, see [`pwgs_render::raster::lanes`]): per pixel the same
//! f64 operations as the scalar walk in [`super::blend`], lane by lane; each splat's
//! gradient is summed per lane and the four lane sums are added at the end in a fixed order, so
//! it differs from the scalar sum only by rounding (the tests bound it) and does not depend
//! on the number of threads. Alpha and falloff come from the forward pass's vector function
//! ([`SplatRows::alpha`], eight pixels at a time), so the walk takes the decisions the vector
//! forward pass took.
//!
//! As in the forward pass, each row of a splat's box is walked in chunks of eight pixels that
//! start at the box's first column, over per-pixel state in rows of 16 (plus a chunk's worth
//! of padding): one chunk for most splats' rows, where a fixed grid of chunks cuts many in two.

use pwgs_render::raster::alpha_lanes::{LANES as CHUNK, SplatRows, box_lanes, chunk_dx};
use pwgs_render::raster::blend::SMOOTH_CUTOFF_BAND;
use pwgs_render::raster::lanes::{LaneKernel, Lanes4d, run_kernel};
use pwgs_render::raster::tiles::ListOrder;
use pwgs_render::raster::{Cutoff, RenderOptions, Rendered, TILE_SIZE};

use super::blend::{EntryGrad, SplatGrad};

const LANES: usize = 4;
const ROW: usize = TILE_SIZE as usize;
const STATE_LEN: usize = ROW * ROW + CHUNK;

type Pixels = [f64; STATE_LEN];

/// Per-pixel state of the walk (see `PixelState` in [`super::blend`]), rows of 16 pixels.
struct TileState {
    v_color: [Pixels; 3],
    transmittance: Pixels,
    t_final: Pixels,
    bg_term: Pixels,
    behind: [Pixels; 3],
    /// Splats at tile positions >= this were not blended into the pixel (0 outside the tile),
    /// as f64 (exact) to compare in lanes.
    last: Pixels,
}

/// Four values of `a` from `o` on.
#[inline(always)]
fn load<D: Lanes4d>(d: D, a: &Pixels, o: usize) -> D::D {
    d.load_array_d(a[o..o + LANES].try_into().expect("four values"))
}

#[inline(always)]
fn store<D: Lanes4d>(d: D, a: &mut Pixels, o: usize, v: D::D) {
    a[o..o + LANES].copy_from_slice(&d.to_array_d(v));
}

/// Per-lane sums of one splat's gradient.
struct Sums<V> {
    mean: [V; 2],
    conic: [V; 3],
    opacity: V,
    color: [V; 3],
}

fn load_state(t: usize, rendered: &Rendered, options: &RenderOptions, v_color: &[f32]) -> TileState {
    let bins = &rendered.bins;
    let [x0, x1, y0, y1] = bins.tile_rect(t);
    let zero = [0.0; STATE_LEN];
    let mut s = TileState {
        v_color: [zero; 3],
        transmittance: zero,
        t_final: zero,
        bg_term: zero,
        behind: [zero; 3],
        last: zero,
    };
    for py in y0..y1 {
        for px in x0..x1 {
            let i = (py - y0) as usize * ROW + (px - x0) as usize;
            let p = bins.pixel_index(px, py);
            let v = [0, 1, 2].map(|c| f64::from(v_color[p * 3 + c]));
            for c in 0..3 {
                s.v_color[c][i] = v[c];
            }
            s.transmittance[i] = f64::from(rendered.transmittance[p]);
            s.t_final[i] = s.transmittance[i];
            s.bg_term[i] = (0..3).map(|c| f64::from(options.background[c]) * v[c]).sum();
            s.last[i] = f64::from(rendered.last_contributor[p]);
        }
    }
    s
}

/// [`super::blend`]'s `alpha_slope` on four lanes.
#[inline(always)]
fn alpha_slope<D: Lanes4d>(d: D, raw: D::D, options: &RenderOptions) -> D::D {
    let (one, zero) = (d.splat_d(1.0), d.splat_d(0.0));
    let alpha_max = d.splat_d(f64::from(options.alpha_max));
    let clamp_slope = d.select_d(d.lt_d(raw, alpha_max), one, zero);
    match options.cutoff {
        Cutoff::Hard => clamp_slope,
        Cutoff::Smooth => {
            let band = d.splat_d(f64::from(SMOOTH_CUTOFF_BAND));
            let t = d.min_d(d.div_d(d.sub_d(raw, d.splat_d(options.projection.alpha_min)), band), one);
            let smooth = d.mul_d(d.mul_d(t, t), d.sub_d(d.splat_d(3.0), d.mul_d(d.splat_d(2.0), t)));
            let slope = d.div_d(d.mul_d(d.mul_d(d.splat_d(6.0), t), d.sub_d(one, t)), band);
            let d_smooth = d.select_d(d.lt_d(t, one), slope, zero);
            d.add_d(d.mul_d(clamp_slope, smooth), d.mul_d(d.min_d(raw, alpha_max), d_smooth))
        }
    }
}

/// The backward walk through tile `t`, four pixels at a time: each entry's gradient into
/// `grads`, indexed like the tile's list. In AVX2 registers where the CPU has them, unless
/// `portable` asks for `wide`'s vectors.
pub(super) fn tile_backward(
    t: usize,
    rendered: &Rendered,
    options: &RenderOptions,
    v_color: &[f32],
    grads: &mut [EntryGrad],
    portable: bool,
) {
    run_kernel(TileKernel { t, rendered, options, v_color, grads }, portable)
}

/// [`tile_backward`]'s arguments, to run on the lanes [`run_kernel`] picks.
struct TileKernel<'a> {
    t: usize,
    rendered: &'a Rendered,
    options: &'a RenderOptions,
    v_color: &'a [f32],
    grads: &'a mut [EntryGrad],
}

impl LaneKernel for TileKernel<'_> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lanes4d>(self, l: L) {
        tile_backward_in(l, self.t, self.rendered, self.options, self.v_color, self.grads)
    }
}

/// [`tile_backward`] on the lanes of `l`. No closures in here: a closure is compiled without
/// the AVX2 features, and the lane operations in it would not be inlined.
#[inline(always)]
fn tile_backward_in<L: Lanes4d>(
    l: L,
    t: usize,
    rendered: &Rendered,
    options: &RenderOptions,
    v_color: &[f32],
    grads: &mut [EntryGrad],
) {
    let bins = &rendered.bins;
    let [x0, x1, y0, y1] = bins.tile_rect(t);
    let mut state = load_state(t, rendered, options, v_color);
    let deepest = state.last.iter().copied().fold(0.0, f64::max) as usize;
    let (one, zero, half) = (l.splat_d(1.0), l.splat_d(0.0), l.splat_d(0.5));
    let mut list = bins.splats(t, &rendered.splats, ListOrder::BackToFront { end: deepest });
    while let Some(block) = list.next_block() {
        for &(k, ref s) in block {
            let [bx0, bx1, by0, by1] = s.bbox;
            let (xa, xb) = (bx0.max(x0), bx1.min(x1));
            if xa >= xb {
                continue;
            }
            let [a, b, c_conic] =
                [l.splat_d(f64::from(s.conic[0])), l.splat_d(f64::from(s.conic[1])), l.splat_d(f64::from(s.conic[2]))];
            let opacity = l.splat_d(f64::from(s.opacity));
            let color =
                [l.splat_d(f64::from(s.color[0])), l.splat_d(f64::from(s.color[1])), l.splat_d(f64::from(s.color[2]))];
            let position = l.splat_d(k as f64);
            // At most two chunks a row, from the box's first column: their offsets from the
            // splat's center (in f32 for alpha, widened for the gradients) and the lanes inside
            // the box, the same on every row.
            let chunks = ((xb - xa) as usize).div_ceil(CHUNK);
            let dx8 = [chunk_dx(l, s, xa), chunk_dx(l, s, xa + CHUNK as u32)];
            let rows = SplatRows::new(l, s, dx8);
            let dx = [l.widen(dx8[0]), l.widen(dx8[1])];
            let inside = box_lanes(l, xb - xa);
            let mut sums = Sums { mean: [zero; 2], conic: [zero; 3], opacity: zero, color: [zero; 3] };
            for py in by0.max(y0)..by1.min(y1) {
                let dy_f32 = s.mean[1] - (py as f32 + 0.5);
                let dy = l.splat_d(f64::from(dy_f32));
                let row = (py - y0) as usize * ROW + (xa - x0) as usize;
                for c in 0..chunks {
                    // Alpha for eight pixels with the forward pass's own vector function.
                    let lanes = rows.alpha(l, c, dy_f32, options);
                    let live = l.and(lanes.contributes, inside[c]);
                    if l.bitmask(live) == 0 {
                        continue;
                    }
                    // Masks do not survive widening (all ones is a NaN): widen ones and zeros.
                    let live = l.widen(l.and(live, l.splat(1.0)));
                    let (alpha4, falloff4) = (l.widen(lanes.alpha), l.widen(lanes.falloff));
                    for h in 0..CHUNK / LANES {
                        let i = row + c * CHUNK + h * LANES;
                        let valid = l.and_d(l.eq_d(live[h], one), l.lt_d(position, load(l, &state.last, i)));
                        if !l.any_d(valid) {
                            continue;
                        }
                        // Alpha is zero outside `valid`, where the state's updates below then
                        // leave it as it was (T / (1 - 0) = T and x + 0 = x exactly; the colors
                        // behind are never negative) without a select: LLVM turns a select
                        // stored back where it was loaded into a masked store, which the next
                        // splat's load of the same pixels cannot be forwarded from.
                        let (alpha, falloff) = (l.and_d(valid, alpha4[h]), falloff4[h]);
                        let dx = dx[c][h];
                        let ra = l.div_d(one, l.sub_d(one, alpha));
                        let before = load(l, &state.transmittance, i);
                        let trans = l.mul_d(before, ra);
                        store(l, &mut state.transmittance, i, trans);
                        let t_final = load(l, &state.t_final, i);
                        let mut v_alpha = l.mul_d(l.mul_d(l.sub_d(zero, t_final), ra), load(l, &state.bg_term, i));
                        for ch in 0..3 {
                            let vc = load(l, &state.v_color[ch], i);
                            let behind = load(l, &state.behind[ch], i);
                            sums.color[ch] = l.add_d(sums.color[ch], l.mul_d(l.mul_d(alpha, trans), vc));
                            let term = l.sub_d(l.mul_d(color[ch], trans), l.mul_d(behind, ra));
                            v_alpha = l.add_d(v_alpha, l.mul_d(term, vc));
                            let behind_next = l.add_d(behind, l.mul_d(l.mul_d(color[ch], alpha), trans));
                            store(l, &mut state.behind[ch], i, behind_next);
                        }
                        let v_raw = l.mul_d(v_alpha, alpha_slope(l, l.mul_d(opacity, falloff), options));
                        sums.opacity = l.add_d(sums.opacity, l.select_d(valid, l.mul_d(falloff, v_raw), zero));
                        let v_sigma = l.select_d(valid, l.mul_d(l.mul_d(l.sub_d(zero, opacity), falloff), v_raw), zero);
                        sums.conic[0] = l.add_d(sums.conic[0], l.mul_d(l.mul_d(l.mul_d(half, dx), dx), v_sigma));
                        sums.conic[1] = l.add_d(sums.conic[1], l.mul_d(l.mul_d(dx, dy), v_sigma));
                        sums.conic[2] = l.add_d(sums.conic[2], l.mul_d(l.mul_d(l.mul_d(half, dy), dy), v_sigma));
                        let mean_x = l.add_d(l.mul_d(a, dx), l.mul_d(b, dy));
                        let mean_y = l.add_d(l.mul_d(b, dx), l.mul_d(c_conic, dy));
                        sums.mean[0] = l.add_d(sums.mean[0], l.mul_d(mean_x, v_sigma));
                        sums.mean[1] = l.add_d(sums.mean[1], l.mul_d(mean_y, v_sigma));
                    }
                }
            }
            let g = SplatGrad {
                mean: [l.sum_d(sums.mean[0]), l.sum_d(sums.mean[1])],
                conic: [l.sum_d(sums.conic[0]), l.sum_d(sums.conic[1]), l.sum_d(sums.conic[2])],
                opacity: l.sum_d(sums.opacity),
                color: [l.sum_d(sums.color[0]), l.sum_d(sums.color[1]), l.sum_d(sums.color[2])],
            };
            grads[k] = EntryGrad::from(&g);
        }
    }
}

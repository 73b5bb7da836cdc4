//! The backward walk through a tile four pixels at a time (f64 lanes: AVX2 registers where the
//! CPU has them, else `wide::f64x4`, see [`pwgs_decoder::raster::lanes`]): per pixel the same
//! f64 operations as the scalar walk in [`super::blend`], lane by lane; each splat's
//! gradient is summed per lane and the four lane sums are added in lane order at the end, so
//! it differs from the scalar sum only by rounding (the tests bound it) and does not depend
//! on the number of threads. Alpha and falloff come from the forward pass's vector function
//! (`splat_alpha8`, eight pixels at a time, the scalar `splat_alpha`'s bits).
//!
//! As in the forward pass, each row of a splat's box is walked in chunks of eight pixels that
//! start at the box's first column, over per-pixel state in rows of 16 (plus a chunk's worth
//! of padding): one chunk for most splats' rows, where a fixed grid of chunks cuts many in two.

use pwgs_decoder::raster::blend::SMOOTH_CUTOFF_BAND;
use pwgs_decoder::raster::blend_simd::{LANES as CHUNK, chunk_dx, splat_alpha8};
#[cfg(target_arch = "x86_64")]
use pwgs_decoder::raster::lanes::Avx2;
use pwgs_decoder::raster::lanes::{Lanes4d, Lanes8, Portable};
use pwgs_decoder::raster::tiles::ListOrder;
use pwgs_decoder::raster::{Cutoff, RenderOptions, Rendered, TILE_SIZE};

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

/// The lanes of `v` added in lane order.
#[inline(always)]
fn lane_sum<D: Lanes4d>(d: D, v: D::D) -> f64 {
    let a = d.to_array_d(v);
    ((a[0] + a[1]) + a[2]) + a[3]
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

/// The lanes of a four-lane mask whose bits (lane l: bit l) are set.
#[inline(always)]
fn mask_of_bits<D: Lanes4d>(d: D, bits: u32) -> D::D {
    let lanes = [bits & 1, (bits >> 1) & 1, (bits >> 2) & 1, (bits >> 3) & 1];
    d.eq_d(
        d.load_array_d([f64::from(lanes[0]), f64::from(lanes[1]), f64::from(lanes[2]), f64::from(lanes[3])]),
        d.splat_d(1.0),
    )
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
    #[cfg(target_arch = "x86_64")]
    if let Some(avx2) = Avx2::detect().filter(|_| !portable) {
        return avx2.0.vectorize(
            #[inline(always)]
            || tile_backward_in(avx2, t, rendered, options, v_color, grads),
        );
    }
    tile_backward_in(Portable, t, rendered, options, v_color, grads)
}

/// [`tile_backward`] on the lanes of `l`. No closures in here: a closure is compiled without
/// the AVX2 features, and the lane operations in it would not be inlined.
#[inline(always)]
fn tile_backward_in<L: Lanes8 + Lanes4d>(
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
    for (k, s) in bins.splats(t, &rendered.splats, ListOrder::BackToFront { end: deepest }) {
        let s = &s;
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
        let mut dx = [[zero; 2]; 2];
        for c in 0..2 {
            let v = l.to_array(dx8[c]).map(f64::from);
            dx[c] = [l.load_array_d([v[0], v[1], v[2], v[3]]), l.load_array_d([v[4], v[5], v[6], v[7]])];
        }
        let width = (xb - xa) as usize;
        let inside = [(1u32 << width.min(CHUNK)) - 1, (1u32 << width.saturating_sub(CHUNK).min(CHUNK)) - 1];
        let mut sums = Sums { mean: [zero; 2], conic: [zero; 3], opacity: zero, color: [zero; 3] };
        for py in by0.max(y0)..by1.min(y1) {
            let dy_f32 = s.mean[1] - (py as f32 + 0.5);
            let dy = l.splat_d(f64::from(dy_f32));
            let row = (py - y0) as usize * ROW + (xa - x0) as usize;
            for c in 0..chunks {
                // Alpha for eight pixels with the forward pass's own vector function.
                let lanes = splat_alpha8(l, s, dx8[c], dy_f32, options);
                let live = l.bitmask(lanes.contributes) & inside[c];
                if live == 0 {
                    continue;
                }
                let (alpha8, falloff8) =
                    (l.to_array(lanes.alpha).map(f64::from), l.to_array(lanes.falloff).map(f64::from));
                for h in 0..CHUNK / LANES {
                    let i = row + c * CHUNK + h * LANES;
                    let valid =
                        l.and_d(mask_of_bits(l, live >> (h * LANES)), l.lt_d(position, load(l, &state.last, i)));
                    if !l.any_d(valid) {
                        continue;
                    }
                    let j = h * LANES;
                    let alpha = l.load_array_d([alpha8[j], alpha8[j + 1], alpha8[j + 2], alpha8[j + 3]]);
                    let falloff = l.load_array_d([falloff8[j], falloff8[j + 1], falloff8[j + 2], falloff8[j + 3]]);
                    let dx = dx[c][h];
                    let ra = l.div_d(one, l.sub_d(one, alpha));
                    let before = load(l, &state.transmittance, i);
                    let trans = l.mul_d(before, ra);
                    store(l, &mut state.transmittance, i, l.select_d(valid, trans, before));
                    let t_final = load(l, &state.t_final, i);
                    let mut v_alpha = l.mul_d(l.mul_d(l.sub_d(zero, t_final), ra), load(l, &state.bg_term, i));
                    for ch in 0..3 {
                        let vc = load(l, &state.v_color[ch], i);
                        let behind = load(l, &state.behind[ch], i);
                        sums.color[ch] =
                            l.add_d(sums.color[ch], l.select_d(valid, l.mul_d(l.mul_d(alpha, trans), vc), zero));
                        let term = l.sub_d(l.mul_d(color[ch], trans), l.mul_d(behind, ra));
                        v_alpha = l.add_d(v_alpha, l.mul_d(term, vc));
                        let behind_next = l.add_d(behind, l.mul_d(l.mul_d(color[ch], alpha), trans));
                        store(l, &mut state.behind[ch], i, l.select_d(valid, behind_next, behind));
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
            mean: [lane_sum(l, sums.mean[0]), lane_sum(l, sums.mean[1])],
            conic: [lane_sum(l, sums.conic[0]), lane_sum(l, sums.conic[1]), lane_sum(l, sums.conic[2])],
            opacity: lane_sum(l, sums.opacity),
            color: [lane_sum(l, sums.color[0]), lane_sum(l, sums.color[1]), lane_sum(l, sums.color[2])],
        };
        grads[k] = EntryGrad::from(&g);
    }
}

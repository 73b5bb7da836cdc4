//! The backward walk through a tile four pixels at a time (`wide::f64x4`): per pixel the same
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
use pwgs_decoder::raster::tiles::ListOrder;
use pwgs_decoder::raster::{Cutoff, RenderOptions, Rendered, TILE_SIZE};
use wide::f64x4;

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
#[inline]
fn load(a: &Pixels, o: usize) -> f64x4 {
    f64x4::new(a[o..o + LANES].try_into().expect("four values"))
}

#[inline]
fn store(a: &mut Pixels, o: usize, v: f64x4) {
    a[o..o + LANES].copy_from_slice(&v.to_array());
}

/// Per-lane sums of one splat's gradient.
#[derive(Default)]
struct Sums {
    mean: [f64x4; 2],
    conic: [f64x4; 3],
    opacity: f64x4,
    color: [f64x4; 3],
}

/// The lanes of `v` added in lane order.
fn lane_sum(v: f64x4) -> f64 {
    let a = v.to_array();
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
#[inline]
fn mask_of_bits(bits: u32) -> f64x4 {
    f64x4::new([0, 1, 2, 3].map(|l| f64::from((bits >> l) & 1))).simd_eq(f64x4::splat(1.0))
}

/// [`super::blend`]'s `alpha_slope` on four lanes.
fn alpha_slope(raw: f64x4, options: &RenderOptions) -> f64x4 {
    let (one, zero) = (f64x4::splat(1.0), f64x4::splat(0.0));
    let alpha_max = f64::from(options.alpha_max);
    let clamp_slope = raw.simd_lt(f64x4::splat(alpha_max)).select(one, zero);
    match options.cutoff {
        Cutoff::Hard => clamp_slope,
        Cutoff::Smooth => {
            let band = f64x4::splat(f64::from(SMOOTH_CUTOFF_BAND));
            let t = ((raw - f64x4::splat(options.projection.alpha_min)) / band).min(one);
            let smooth = t * t * (f64x4::splat(3.0) - f64x4::splat(2.0) * t);
            let d_smooth = t.simd_lt(one).select(f64x4::splat(6.0) * t * (one - t) / band, zero);
            clamp_slope * smooth + raw.min(f64x4::splat(alpha_max)) * d_smooth
        }
    }
}

/// The backward walk through tile `t`, four pixels at a time: each entry's gradient into
/// `grads`, indexed like the tile's list.
pub(super) fn tile_backward(
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
    let (one, zero) = (f64x4::splat(1.0), f64x4::splat(0.0));
    for (k, s) in bins.splats(t, &rendered.splats, ListOrder::BackToFront { end: deepest }) {
        let s = &s;
        let [bx0, bx1, by0, by1] = s.bbox;
        let (xa, xb) = (bx0.max(x0), bx1.min(x1));
        if xa >= xb {
            continue;
        }
        let [a, b, c_conic] = s.conic.map(f64::from).map(f64x4::splat);
        let opacity = f64x4::splat(f64::from(s.opacity));
        let color = s.color.map(|v| f64x4::splat(f64::from(v)));
        let position = f64x4::splat(k as f64);
        // At most two chunks a row, from the box's first column: their offsets from the
        // splat's center and the lanes inside the box, the same on every row.
        let chunks = ((xb - xa) as usize).div_ceil(CHUNK);
        let dx8 = [0, 1].map(|c| chunk_dx(s, xa + (c * CHUNK) as u32));
        let dx = [0, 1].map(|c| {
            let v = dx8[c].to_array();
            [0, 1].map(|h| f64x4::new([0, 1, 2, 3].map(|l| f64::from(v[h * LANES + l]))))
        });
        let width = (xb - xa) as usize;
        let inside: [u32; 2] = [0, 1].map(|c| (1u32 << width.saturating_sub(c * CHUNK).min(CHUNK)) - 1);
        let mut sums = Sums::default();
        for py in by0.max(y0)..by1.min(y1) {
            let dy_f32 = s.mean[1] - (py as f32 + 0.5);
            let dy = f64x4::splat(f64::from(dy_f32));
            let row = (py - y0) as usize * ROW + (xa - x0) as usize;
            for c in 0..chunks {
                // Alpha for eight pixels with the forward pass's own vector function.
                let lanes = splat_alpha8(s, dx8[c], dy_f32, options);
                let live = lanes.contributes.to_bitmask() as u32 & inside[c];
                if live == 0 {
                    continue;
                }
                let (alpha8, falloff8) = (lanes.alpha.to_array(), lanes.falloff.to_array());
                for half in 0..CHUNK / LANES {
                    let i = row + c * CHUNK + half * LANES;
                    let valid = mask_of_bits(live >> (half * LANES)) & position.simd_lt(load(&state.last, i));
                    if !valid.any() {
                        continue;
                    }
                    let widen = |v: &[f32; CHUNK]| f64x4::new([0, 1, 2, 3].map(|l| f64::from(v[half * LANES + l])));
                    let (alpha, falloff, dx) = (widen(&alpha8), widen(&falloff8), dx[c][half]);
                    let ra = one / (one - alpha);
                    let before = load(&state.transmittance, i);
                    let trans = before * ra;
                    store(&mut state.transmittance, i, valid.select(trans, before));
                    let t_final = load(&state.t_final, i);
                    let mut v_alpha = -t_final * ra * load(&state.bg_term, i);
                    for ch in 0..3 {
                        let vc = load(&state.v_color[ch], i);
                        let behind = load(&state.behind[ch], i);
                        sums.color[ch] += valid.select(alpha * trans * vc, zero);
                        v_alpha += (color[ch] * trans - behind * ra) * vc;
                        store(&mut state.behind[ch], i, valid.select(behind + color[ch] * alpha * trans, behind));
                    }
                    let v_raw = v_alpha * alpha_slope(opacity * falloff, options);
                    sums.opacity += valid.select(falloff * v_raw, zero);
                    let v_sigma = valid.select(-opacity * falloff * v_raw, zero);
                    sums.conic[0] += f64x4::splat(0.5) * dx * dx * v_sigma;
                    sums.conic[1] += dx * dy * v_sigma;
                    sums.conic[2] += f64x4::splat(0.5) * dy * dy * v_sigma;
                    sums.mean[0] += (a * dx + b * dy) * v_sigma;
                    sums.mean[1] += (b * dx + c_conic * dy) * v_sigma;
                }
            }
        }
        let g = SplatGrad {
            mean: sums.mean.map(lane_sum),
            conic: sums.conic.map(lane_sum),
            opacity: lane_sum(sums.opacity),
            color: sums.color.map(lane_sum),
        };
        grads[k] = EntryGrad::from(&g);
    }
}

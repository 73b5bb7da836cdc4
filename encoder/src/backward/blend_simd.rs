//! The backward walk through a tile four pixels at a time (`wide::f64x4`): per pixel the same
//! f64 operations as the scalar walk in [`super::blend`], lane by lane; each splat's
//! gradient is summed per lane and the four lane sums are added in lane order at the end, so
//! it differs from the scalar sum only by rounding (the tests bound it) and does not depend
//! on the number of threads. Alpha and falloff come from the forward pass's vector function
//! (`splat_alpha8`, eight pixels at a time, the scalar `splat_alpha`'s bits).

use pwgs_decoder::raster::blend::SMOOTH_CUTOFF_BAND;
use pwgs_decoder::raster::blend_simd::{LANES as CHUNK, chunk_dx, splat_alpha8};
use pwgs_decoder::raster::tiles::ListOrder;
use pwgs_decoder::raster::{Cutoff, RenderOptions, Rendered, TILE_SIZE};
use wide::f64x4;

use super::blend::{EntryGrad, SplatGrad};

const LANES: usize = 4;
const QUADS_PER_ROW: usize = TILE_SIZE as usize / LANES;
const QUADS: usize = TILE_SIZE as usize * QUADS_PER_ROW;

/// Per-pixel state of the walk, four pixels a vector (see `PixelState` in [`super::blend`]).
struct TileState {
    v_color: [[f64x4; QUADS]; 3],
    transmittance: [f64x4; QUADS],
    t_final: [f64x4; QUADS],
    bg_term: [f64x4; QUADS],
    behind: [[f64x4; QUADS]; 3],
    /// Splats at tile positions >= this were not blended into the pixel (0 outside the tile).
    last: [[usize; LANES]; QUADS],
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
    let zero = [f64x4::splat(0.0); QUADS];
    let mut s = TileState {
        v_color: [zero; 3],
        transmittance: zero,
        t_final: zero,
        bg_term: zero,
        behind: [zero; 3],
        last: [[0; LANES]; QUADS],
    };
    for py in y0..y1 {
        for q in 0..QUADS_PER_ROW {
            let i = (py - y0) as usize * QUADS_PER_ROW + q;
            let mut v = [[0.0; LANES]; 3];
            let (mut t_final, mut bg) = ([0.0; LANES], [0.0; LANES]);
            for lane in 0..LANES {
                let px = x0 + (q * LANES + lane) as u32;
                if px >= x1 {
                    break;
                }
                let p = bins.pixel_index(px, py);
                for c in 0..3 {
                    v[c][lane] = f64::from(v_color[p * 3 + c]);
                }
                t_final[lane] = f64::from(rendered.transmittance[p]);
                bg[lane] = (0..3).map(|c| f64::from(options.background[c]) * v[c][lane]).sum();
                s.last[i][lane] = rendered.last_contributor[p] as usize;
            }
            for c in 0..3 {
                s.v_color[c][i] = f64x4::new(v[c]);
            }
            s.transmittance[i] = f64x4::new(t_final);
            s.t_final[i] = f64x4::new(t_final);
            s.bg_term[i] = f64x4::new(bg);
        }
    }
    s
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
    let deepest = state.last.iter().flatten().copied().max().unwrap_or(0);
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
        let mut sums = Sums::default();
        for py in by0.max(y0)..by1.min(y1) {
            let dy_f32 = s.mean[1] - (py as f32 + 0.5);
            let dy = f64x4::splat(f64::from(dy_f32));
            let row = (py - y0) as usize * QUADS_PER_ROW;
            for c in ((xa - x0) as usize / CHUNK)..=((xb - 1 - x0) as usize / CHUNK) {
                // Alpha for eight pixels with the forward pass's own vector function.
                let start = x0 + (c * CHUNK) as u32;
                let lanes = splat_alpha8(s, chunk_dx(s, start), dy_f32, options);
                let (alpha8, falloff8, contributes) =
                    (lanes.alpha.to_array(), lanes.falloff.to_array(), lanes.contributes.to_bitmask());
                let dx8 = chunk_dx(s, start).to_array();
                for half in 0..CHUNK / LANES {
                    let i = row + c * (CHUNK / LANES) + half;
                    let mut valid = [0.0; LANES];
                    for lane in 0..LANES {
                        let j = half * LANES + lane;
                        let px = start + j as u32;
                        if px >= xa && px < xb && k < state.last[i][lane] && contributes & (1 << j) != 0 {
                            valid[lane] = 1.0;
                        }
                    }
                    let valid = f64x4::new(valid).simd_eq(one);
                    if !valid.any() {
                        continue;
                    }
                    let widen = |v: &[f32; CHUNK]| f64x4::new([0, 1, 2, 3].map(|l| f64::from(v[half * LANES + l])));
                    let (alpha, falloff, dx) = (widen(&alpha8), widen(&falloff8), widen(&dx8));
                    let ra = one / (one - alpha);
                    let trans = state.transmittance[i] * ra;
                    state.transmittance[i] = valid.select(trans, state.transmittance[i]);
                    let mut v_alpha = -state.t_final[i] * ra * state.bg_term[i];
                    for ch in 0..3 {
                        let vc = state.v_color[ch][i];
                        sums.color[ch] += valid.select(alpha * trans * vc, zero);
                        v_alpha += (color[ch] * trans - state.behind[ch][i] * ra) * vc;
                        let behind = state.behind[ch][i] + color[ch] * alpha * trans;
                        state.behind[ch][i] = valid.select(behind, state.behind[ch][i]);
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

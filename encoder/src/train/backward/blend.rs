//! Backward of front-to-back blending: from dL/d(pixel color) to the gradients of each splat's
//! screen-space parameters (center, conic, opacity, color).
//!
//! Per pixel the splats are walked back to front from the last one the forward pass blended,
//! recovering each splat's transmittance by division (T_k = T_{k+1} / (1 - alpha_k); alpha is at
//! most 0.99, so the division is safe). Tiles run in parallel; each writes its per-entry
//! gradients into its own slice, and the per-splat sums are then taken in a fixed tile order,
//! so the result does not depend on the number of threads.

use pwgs_render::raster::blend::{SMOOTH_CUTOFF_BAND, splat_alpha};
use pwgs_render::raster::lanes::prefetch;
use pwgs_render::raster::project::Splat;
use pwgs_render::raster::tiles::ListOrder;
use pwgs_render::raster::{Cutoff, RenderOptions, Rendered};
use rayon::prelude::*;

/// Gradient of the loss with respect to one splat's screen-space parameters.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SplatGrad {
    pub mean: [f64; 2],
    /// With respect to the conic entries (a, b, c) of sigma = 0.5 (a dx^2 + c dy^2) + b dx dy.
    pub conic: [f64; 3],
    pub opacity: f64,
    pub color: [f64; 3],
}

impl SplatGrad {
    fn add(&mut self, other: &SplatGrad) {
        for i in 0..2 {
            self.mean[i] += other.mean[i];
        }
        for i in 0..3 {
            self.conic[i] += other.conic[i];
            self.color[i] += other.color[i];
        }
        self.opacity += other.opacity;
    }
}

/// A [`SplatGrad`] in f32: mean (2), conic (3), opacity, color (3).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct EntryGrad([f32; 9]);

impl From<&SplatGrad> for EntryGrad {
    fn from(g: &SplatGrad) -> Self {
        let v =
            [g.mean[0], g.mean[1], g.conic[0], g.conic[1], g.conic[2], g.opacity, g.color[0], g.color[1], g.color[2]];
        Self(v.map(|x| x as f32))
    }
}

impl EntryGrad {
    fn widen(&self) -> SplatGrad {
        let v = self.0.map(f64::from);
        SplatGrad { mean: [v[0], v[1]], conic: [v[2], v[3], v[4]], opacity: v[5], color: [v[6], v[7], v[8]] }
    }
}

/// d alpha / d(opacity * falloff) at a sample, following the forward's clamp and cutoff.
pub(super) fn alpha_slope(s: &Splat, falloff: f64, options: &RenderOptions) -> f64 {
    let raw = s.opacity as f64 * falloff;
    let clamp_slope = if raw < options.alpha_max as f64 { 1.0 } else { 0.0 };
    match options.cutoff {
        Cutoff::Hard => clamp_slope,
        Cutoff::Smooth => {
            let band = SMOOTH_CUTOFF_BAND as f64;
            let t = ((raw - options.projection.alpha_min) / band).min(1.0);
            let smooth = t * t * (3.0 - 2.0 * t);
            let d_smooth = if t < 1.0 { 6.0 * t * (1.0 - t) / band } else { 0.0 };
            clamp_slope * smooth + raw.min(options.alpha_max as f64) * d_smooth
        }
    }
}

/// Per-pixel state of the backward walk through one tile.
struct PixelState {
    /// dL/d(color) of the pixel.
    v_color: [f64; 3],
    /// Transmittance in front of the splat being visited (recovered by division).
    transmittance: f64,
    /// Final transmittance, and background . v_color.
    t_final: f64,
    bg_term: f64,
    /// Color of everything behind the splat being visited, as seen from it.
    behind: [f64; 3],
    /// Splats at tile positions >= this were not blended into the pixel.
    last: usize,
}

/// How many entries ahead [`blend_backward`]'s sum over tiles prefetches.
const TOTALS_AHEAD: usize = 16;

/// Gradients of every visible splat (indexed like `rendered.splats`) given dL/d(color) per
/// pixel (`v_color`, interleaved RGB like the image).
///
/// Within a tile, splats are visited back to front and each only over its own pixel box, so
/// the work is that of the forward pass, not pixels x splats.
pub fn blend_backward(rendered: &Rendered, options: &RenderOptions, v_color: &[f32]) -> Vec<SplatGrad> {
    assert_eq!(v_color.len(), rendered.color.data.len(), "v_color must match the image");
    let bins = &rendered.bins;
    let tile_count = (bins.tiles_x * bins.tiles_y) as usize;
    // One gradient per (tile, splat) entry, in f32 to halve the traffic: each sums at most
    // 256 pixels; the sums over tiles below run in f64.
    let mut per_entry = vec![EntryGrad::default(); bins.entries.len()];
    // Split the per-entry buffer into one slice per tile so tiles can run in parallel.
    let mut slices: Vec<&mut [EntryGrad]> = Vec::with_capacity(tile_count);
    let mut rest = per_entry.as_mut_slice();
    for t in 0..tile_count {
        let (head, tail) = rest.split_at_mut(bins.offsets[t + 1] - bins.offsets[t]);
        slices.push(head);
        rest = tail;
    }
    slices.into_par_iter().enumerate().for_each(|(t, grads)| match options.blend.vector_lanes() {
        None => tile_backward(t, rendered, options, v_color, grads),
        Some(portable) => super::blend_simd::tile_backward(t, rendered, options, v_color, grads, portable),
    });
    let mut totals = vec![SplatGrad::default(); rendered.splats.len()];
    for (j, (entry, grad)) in bins.entries.iter().zip(&per_entry).enumerate() {
        // The entries index the totals at random: ask for the line a few entries ahead.
        if let Some(&ahead) = bins.entries.get(j + TOTALS_AHEAD) {
            prefetch(&totals[ahead as usize]);
        }
        totals[*entry as usize].add(&grad.widen());
    }
    totals
}

/// The backward walk through tile `t`, one pixel at a time (the reference): each entry's
/// gradient into `grads`, indexed like the tile's list.
fn tile_backward(t: usize, rendered: &Rendered, options: &RenderOptions, v_color: &[f32], grads: &mut [EntryGrad]) {
    let bins = &rendered.bins;
    let [x0, x1, y0, y1] = bins.tile_rect(t);
    let tw = (x1 - x0) as usize;
    let mut pixels: Vec<PixelState> = Vec::with_capacity(tw * (y1 - y0) as usize);
    for py in y0..y1 {
        for px in x0..x1 {
            let p = bins.pixel_index(px, py);
            let v = [v_color[p * 3], v_color[p * 3 + 1], v_color[p * 3 + 2]].map(f64::from);
            let t_final = rendered.transmittance[p] as f64;
            pixels.push(PixelState {
                v_color: v,
                transmittance: t_final,
                t_final,
                bg_term: (0..3).map(|c| options.background[c] as f64 * v[c]).sum(),
                behind: [0.0; 3],
                last: rendered.last_contributor[p] as usize,
            });
        }
    }
    let deepest = pixels.iter().map(|p| p.last).max().unwrap_or(0);
    let mut list = bins.splats(t, &rendered.splats, ListOrder::BackToFront { end: deepest });
    while let Some(block) = list.next_block() {
        for &(k, ref s) in block {
            let [bx0, bx1, by0, by1] = s.bbox;
            let [a, b, c] = s.conic.map(f64::from);
            let opacity = s.opacity as f64;
            let color = s.color.map(f64::from);
            let mut g = SplatGrad::default();
            for py in by0.max(y0)..by1.min(y1) {
                for px in bx0.max(x0)..bx1.min(x1) {
                    let state = &mut pixels[(py - y0) as usize * tw + (px - x0) as usize];
                    if k >= state.last {
                        continue;
                    }
                    let dx = s.mean[0] - (px as f32 + 0.5);
                    let dy = s.mean[1] - (py as f32 + 0.5);
                    let Some(sample) = splat_alpha(s, dx, dy, options) else { continue };
                    let alpha = sample.alpha as f64;
                    let falloff = sample.falloff as f64;
                    let ra = 1.0 / (1.0 - alpha);
                    state.transmittance *= ra;
                    let trans = state.transmittance;
                    let mut v_alpha = -state.t_final * ra * state.bg_term;
                    for ch in 0..3 {
                        g.color[ch] += alpha * trans * state.v_color[ch];
                        v_alpha += (color[ch] * trans - state.behind[ch] * ra) * state.v_color[ch];
                        state.behind[ch] += color[ch] * alpha * trans;
                    }
                    let v_raw = v_alpha * alpha_slope(s, falloff, options);
                    g.opacity += falloff * v_raw;
                    let v_sigma = -opacity * falloff * v_raw;
                    let (dx, dy) = (dx as f64, dy as f64);
                    g.conic[0] += 0.5 * dx * dx * v_sigma;
                    g.conic[1] += dx * dy * v_sigma;
                    g.conic[2] += 0.5 * dy * dy * v_sigma;
                    g.mean[0] += (a * dx + b * dy) * v_sigma;
                    g.mean[1] += (b * dx + c * dy) * v_sigma;
                }
            }
            grads[k] = EntryGrad::from(&g);
        }
    }
}

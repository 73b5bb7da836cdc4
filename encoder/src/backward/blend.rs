//! Backward of front-to-back blending: from dL/d(pixel color) to the gradients of each splat's
//! screen-space parameters (center, conic, opacity, color).
//!
//! Per pixel the splats are walked back to front from the last one the forward pass blended,
//! recovering each splat's transmittance by division (T_k = T_{k+1} / (1 - alpha_k); alpha is at
//! most 0.99, so the division is safe). Tiles run in parallel; each writes its per-entry
//! gradients into its own slice, and the per-splat sums are then taken in a fixed tile order,
//! so the result does not depend on the number of threads.

use pwgs_decoder::raster::blend::SMOOTH_CUTOFF_BAND;
use pwgs_decoder::raster::project::Splat;
use pwgs_decoder::raster::{Cutoff, RenderOptions, Rendered};
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

/// Alpha of a splat at a pixel and d alpha / d(opacity * exp(-sigma)), mirroring the forward
/// pass's [`pwgs_decoder::raster::blend::splat_alpha`] decision for decision.
struct AlphaEval {
    alpha: f64,
    /// exp(-sigma).
    gaussian: f64,
    d_alpha_d_raw: f64,
}

fn eval_alpha(s: &Splat, dx: f32, dy: f32, options: &RenderOptions) -> Option<AlphaEval> {
    // The forward decision (contributes or not) is taken by the forward's own function, in f32,
    // so that both passes skip exactly the same splats.
    let alpha = pwgs_decoder::raster::blend::splat_alpha(s, dx, dy, options)?;
    let [a, b, c] = s.conic.map(f64::from);
    let (dx, dy) = (dx as f64, dy as f64);
    let sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy;
    let gaussian = (-sigma).exp();
    let raw = s.opacity as f64 * gaussian;
    let clamp_slope = if raw < options.alpha_max as f64 { 1.0 } else { 0.0 };
    let d_alpha_d_raw = match options.cutoff {
        Cutoff::Hard => clamp_slope,
        Cutoff::Smooth => {
            let band = SMOOTH_CUTOFF_BAND as f64;
            let t = ((raw - options.projection.alpha_min) / band).min(1.0);
            let smooth = t * t * (3.0 - 2.0 * t);
            let d_smooth = if t < 1.0 { 6.0 * t * (1.0 - t) / band } else { 0.0 };
            clamp_slope * smooth + raw.min(options.alpha_max as f64) * d_smooth
        }
    };
    Some(AlphaEval { alpha: alpha as f64, gaussian, d_alpha_d_raw })
}

/// Gradients of every visible splat (indexed like `rendered.splats`) given dL/d(color) per
/// pixel (`v_color`, interleaved RGB like the image).
pub fn blend_backward(rendered: &Rendered, options: &RenderOptions, v_color: &[f32]) -> Vec<SplatGrad> {
    let (width, height) = (rendered.color.width, rendered.color.height);
    assert_eq!(v_color.len(), rendered.color.data.len(), "v_color must match the image");
    let bins = &rendered.bins;
    let tile_count = (bins.tiles_x * bins.tiles_y) as usize;
    let mut per_entry = vec![SplatGrad::default(); bins.entries.len()];
    // Split the per-entry buffer into one slice per tile so tiles can run in parallel.
    let mut slices: Vec<&mut [SplatGrad]> = Vec::with_capacity(tile_count);
    let mut rest = per_entry.as_mut_slice();
    for t in 0..tile_count {
        let (head, tail) = rest.split_at_mut(bins.offsets[t + 1] - bins.offsets[t]);
        slices.push(head);
        rest = tail;
    }
    slices.into_par_iter().enumerate().for_each(|(t, grads)| {
        let entries = bins.tile(t);
        let [x0, x1, y0, y1] = bins.tile_rect(t, width, height);
        for py in y0..y1 {
            for px in x0..x1 {
                let p = (py * width + px) as usize;
                let last = rendered.last_contributor[p] as usize;
                if last == 0 {
                    continue;
                }
                let v_c = [v_color[p * 3], v_color[p * 3 + 1], v_color[p * 3 + 2]].map(f64::from);
                let t_final = rendered.transmittance[p] as f64;
                let bg_term: f64 = (0..3).map(|c| options.background[c] as f64 * v_c[c]).sum();
                let mut trans = t_final;
                // Color of everything behind the current splat, weighted as seen from it.
                let mut behind = [0.0f64; 3];
                for k in (0..last).rev() {
                    let s = &rendered.splats[entries[k] as usize];
                    let [bx0, bx1, by0, by1] = s.bbox;
                    if px < bx0 || px >= bx1 || py < by0 || py >= by1 {
                        continue;
                    }
                    let dx = s.mean[0] - (px as f32 + 0.5);
                    let dy = s.mean[1] - (py as f32 + 0.5);
                    let Some(e) = eval_alpha(s, dx, dy, options) else { continue };
                    let ra = 1.0 / (1.0 - e.alpha);
                    trans *= ra;
                    let g = &mut grads[k];
                    let mut v_alpha = -t_final * ra * bg_term;
                    for c in 0..3 {
                        g.color[c] += e.alpha * trans * v_c[c];
                        v_alpha += (s.color[c] as f64 * trans - behind[c] * ra) * v_c[c];
                        behind[c] += s.color[c] as f64 * e.alpha * trans;
                    }
                    let v_raw = v_alpha * e.d_alpha_d_raw;
                    g.opacity += e.gaussian * v_raw;
                    let v_sigma = -(s.opacity as f64) * e.gaussian * v_raw;
                    let (dx, dy) = (dx as f64, dy as f64);
                    let [a, b, c] = s.conic.map(f64::from);
                    g.conic[0] += 0.5 * dx * dx * v_sigma;
                    g.conic[1] += dx * dy * v_sigma;
                    g.conic[2] += 0.5 * dy * dy * v_sigma;
                    g.mean[0] += (a * dx + b * dy) * v_sigma;
                    g.mean[1] += (b * dx + c * dy) * v_sigma;
                }
            }
        }
    });
    let mut totals = vec![SplatGrad::default(); rendered.splats.len()];
    for (entry, grad) in bins.entries.iter().zip(&per_entry) {
        totals[*entry as usize].add(grad);
    }
    totals
}

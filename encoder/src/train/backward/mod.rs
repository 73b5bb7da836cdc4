//! Analytic gradients of the reference rasterizer (the decoder's forward pass), in plain Rust
//! on the CPU: [`blend`] takes dL/d(pixel) to each splat's screen-space parameters,
//! [`projection`] takes those to the Gaussian's parameters.
//!
//! What the forward pass keeps for this (the [`Rendered`] value: visible splats, tile lists,
//! final transmittance and last contributor per pixel) is all the state there is; projection
//! intermediates are recomputed, per visible Gaussian, by the decoder's own projection.

pub mod blend;
mod blend_simd;
pub mod projection;
pub mod sh;

use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_render::raster::{RenderOptions, Rendered};
use rayon::prelude::*;

/// Gradients with respect to every parameter of a Gaussian set, laid out like [`Gaussians`].
/// Culled Gaussians get zeros.
#[derive(Debug, Clone, PartialEq)]
pub struct Gradients {
    pub means: Vec<[f32; 3]>,
    pub log_scales: Vec<[f32; 3]>,
    pub rotations: Vec<[f32; 4]>,
    pub opacity_logits: Vec<f32>,
    pub sh: Vec<f32>,
    /// |dL/d(projected center)| in pixels: the densification signal of 3DGS.
    pub screen_mean: Vec<f32>,
}

impl Gradients {
    fn zeros(g: &Gaussians) -> Self {
        let n = g.len();
        Self {
            means: vec![[0.0; 3]; n],
            log_scales: vec![[0.0; 3]; n],
            rotations: vec![[0.0; 4]; n],
            opacity_logits: vec![0.0; n],
            sh: vec![0.0; g.sh.len()],
            screen_mean: vec![0.0; n],
        }
    }
}

/// Gradients of a loss with respect to the Gaussians, given dL/d(color) per pixel (`v_color`,
/// interleaved RGB) and the forward pass's [`Rendered`] for the same Gaussians, camera and
/// options.
pub fn backward(
    g: &Gaussians,
    camera: &Camera,
    options: &RenderOptions,
    rendered: &Rendered,
    v_color: &[f32],
) -> Gradients {
    let splat_grads = blend::blend_backward(rendered, options, v_color);
    let per_splat: Vec<_> = rendered
        .splats
        .par_iter()
        .zip(&splat_grads)
        .map(|(s, v)| {
            (
                s.index as usize,
                projection::projection_backward(g, s.index as usize, camera, &options.projection, v),
                v.mean,
            )
        })
        .collect();
    let mut out = Gradients::zeros(g);
    let k = g.coeffs_per_channel() * 3;
    for (i, grad, screen) in per_splat {
        let Some(grad) = grad else { continue };
        out.means[i] = grad.mean.map(|v| v as f32);
        out.log_scales[i] = grad.log_scale.map(|v| v as f32);
        out.rotations[i] = grad.rotation.map(|v| v as f32);
        out.opacity_logits[i] = grad.opacity_logit as f32;
        for (dst, src) in out.sh[i * k..(i + 1) * k].iter_mut().zip(&grad.sh) {
            *dst = *src as f32;
        }
        out.screen_mean[i] = (screen[0] * screen[0] + screen[1] * screen[1]).sqrt() as f32;
    }
    out
}

//! Shapes refitted to the quantized positions (`pwenc --from X --importance-classes
//! --refit-shapes`). Positions are the largest part of an imported stream's error (on biker at
//! quality 11 about 40% of it, pruning another 28%), and no other attribute's step can undo a
//! shift: but the Gaussians around a moved or dropped one can lean into the gap. With every
//! kept Gaussian at its decoded position, a few epochs of Adam on the rasterizer's analytic
//! gradients ([`crate::backward`]) move the scales, rotations, opacities and SH so that the
//! model renders closest to itself on the importance views. The refitted values then go through
//! the same quantizer as any other; nothing in the stream changes but their values.
//!
//! Most of what the refit gains is finer than the quantizer's steps and goes when they are
//! rounded (on biker at quality 11: 56.8 -> 58.4 dB on the views over 6 epochs, then 56.4 dB
//! once quantized, against 55.0 dB without the refit); what stays is a better start for
//! [`crate::colour_refit`], which must then fit the input's renders, not the refitted model's
//! (at the input's positions that model no longer renders like the input). Together they reach
//! 58.25 dB on biker's orbit against 58.00 dB for the colours alone.

use pwgs_decoder::camera::Camera;
use pwgs_decoder::gaussians::{Gaussians, sh_band};
use pwgs_decoder::random_scene::SplitMix64;
use pwgs_decoder::raster::{RenderOptions, rasterize, render};
use rayon::prelude::*;
use serde::Serialize;

use crate::backward::backward;
use crate::compress::{Coding, CompressError, StreamContext, reconstruction};
use crate::metrics::psnr::mse;
use crate::train::adam::SliceAdam;

/// The optimizer's rate for each attribute, as a fraction of that attribute's quantizer step
/// at the quality being coded, so that one setting suits every quality. On biker at quality 11
/// over 3 epochs, 0.1 diverges (55.7 -> 54.4 dB on the views), 0.01 climbs 56.7 -> 57.6 dB and
/// 0.03 56.8 -> 57.8 dB.
const STEP_FRACTION: f32 = 0.03;

/// Seeds the order of the views in each epoch.
const ORDER_SEED: u64 = 0x5eed_5eed;

/// What a refit did: the mean squared error of the model at its decoded positions against
/// the model's renders over each epoch's views, as each was rendered during that epoch.
#[derive(Debug, Clone, Serialize)]
pub struct ShapeRefitOutcome {
    pub views: usize,
    pub gaussians: usize,
    pub mse_per_epoch: Vec<f64>,
}

/// `g` with the scales, rotations, opacities and SH of the Gaussians `coding` keeps refitted
/// over `epochs` passes through `cameras` (each in a shuffled order, the same on every run), so
/// that, at their quantized positions, they render closest to `g`.
pub fn refit_shapes(
    g: &Gaussians,
    coding: Coding,
    context: &StreamContext,
    (cameras, options): (&[Camera], &RenderOptions),
    epochs: usize,
) -> Result<(Gaussians, ShapeRefitOutcome), CompressError> {
    let (keep, decoded) = reconstruction(g, coding, context)?;
    let mut model = subset(g, &keep);
    model.means = decoded.means;
    let targets: Vec<_> = cameras.par_iter().map(|camera| render(g, camera, options)).collect();

    let s = coding.settings;
    let k = g.coeffs_per_channel() * 3;
    let sh_rates: Vec<f32> =
        (0..k).map(|i| STEP_FRACTION * if i < 3 { s.dc_step } else { s.band_steps[sh_band(i / 3) - 1] }).collect();
    let mut scales = SliceAdam::new(model.len() * 3);
    let mut rotations = SliceAdam::new(model.len() * 4);
    let mut opacities = SliceAdam::new(model.len());
    let mut sh = SliceAdam::new(model.sh.len());
    let mut rng = SplitMix64(ORDER_SEED);
    let mut mse_per_epoch = Vec::with_capacity(epochs);
    let mut step = 0;
    for _ in 0..epochs {
        let mut order: Vec<usize> = (0..cameras.len()).collect();
        rng.shuffle(&mut order);
        // The views are all the same size: the mean of their errors is the pooled one.
        let mut errors = 0.0f64;
        for &v in &order {
            let rendered = rasterize(&model, &cameras[v], options);
            let target = &targets[v];
            errors += mse(&rendered.color, target);
            let scale = 2.0 / target.data.len() as f32;
            let v_color: Vec<f32> =
                rendered.color.data.iter().zip(&target.data).map(|(c, t)| scale * (c - t)).collect();
            let grads = backward(&model, &cameras[v], options, &rendered, &v_color);
            step += 1;
            scales.step(
                model.log_scales.as_flattened_mut(),
                grads.log_scales.as_flattened(),
                |_| STEP_FRACTION * s.log_scale_step,
                step,
            );
            rotations.step(
                model.rotations.as_flattened_mut(),
                grads.rotations.as_flattened(),
                |_| STEP_FRACTION * s.rotation_step,
                step,
            );
            opacities.step(&mut model.opacity_logits, &grads.opacity_logits, |_| STEP_FRACTION * s.opacity_step, step);
            sh.step(&mut model.sh, &grads.sh, |i| sh_rates[i % k], step);
        }
        mse_per_epoch.push(errors / order.len().max(1) as f64);
    }

    let mut refitted = g.clone();
    for (r, &i) in keep.iter().enumerate() {
        refitted.log_scales[i] = model.log_scales[r];
        refitted.rotations[i] = model.rotations[r];
        refitted.opacity_logits[i] = model.opacity_logits[r];
        refitted.sh[i * k..(i + 1) * k].copy_from_slice(model.sh_of(r));
    }
    Ok((refitted, ShapeRefitOutcome { views: cameras.len(), gaussians: model.len(), mse_per_epoch }))
}

/// The Gaussians `keep` (indices into `g`), in that order.
fn subset(g: &Gaussians, keep: &[usize]) -> Gaussians {
    let mut out = Gaussians::with_degree(g.sh_degree);
    for &i in keep {
        out.push(g.means[i], g.log_scales[i], g.rotations[i], g.opacity_logits[i], g.sh_of(i));
    }
    out
}

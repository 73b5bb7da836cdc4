//! Shapes refitted to the quantized positions (`pwenc --from X --importance-classes
//! --refit-shapes`). Positions are the largest part of an imported stream's error (on biker at
//! quality 11 about 40% of it, pruning another 28%), and no other attribute's step can undo a
//! shift: but the Gaussians around a moved or dropped one can lean into the gap. With every
//! kept Gaussian at its decoded position, a few epochs of Adam on the rasterizer's analytic
//! gradients ([`crate::train::backward`]) move the scales, rotations, opacities and colours (the SH
//! DC terms; bands 1-3 stay as the model has them) so that the model renders closest to itself
//! on the refit views
//! ([`crate::plain::importance::class_cameras`]). The refitted values then go through the same
//! quantizer as any other; nothing in the stream changes but their values.
//!
//! Most of what the refit gains is finer than the quantizer's steps and goes when they are rounded
//! (on biker at quality 11, at a rate of 0.03: 56.8 -> 58.4 dB on the views over 6 epochs, then
//! 56.4 dB once quantized, against 55.0 dB without the refit); what stays is a better start for
//! [`crate::plain::colour_refit`], which must then fit the input's renders, not the refitted
//! model's (at the input's positions that model no longer renders like the input). Together they
//! reach 58.25 dB on biker's orbit against 58.00 dB for the colours alone.

use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::random::SplitMix64;
use pwgs_core::rgb_image::RgbImage;
use pwgs_render::raster::{RenderOptions, rasterize, render};
use rayon::prelude::*;
use serde::Serialize;

use crate::metrics::psnr::mse;
use crate::plain::compress::{Coding, CompressError, QuantizerSettings, StreamContext, reconstruction};
use crate::train::adam::SliceAdam;
use crate::train::backward::backward;

/// The optimizer's rate for each attribute, as a fraction of that attribute's quantizer step
/// at the quality being coded, so that one setting suits every quality. At 0.03 the views of
/// fox (SH degree 3) at quality 7 fell over the first epochs (46.89 -> 43.90 dB, about 46.4 dB
/// again by the 24th); at 0.01 they climb on every model (fox 47.48 -> 50.06 dB over 24 epochs),
/// and with 24 epochs fox codes 0.6 dB higher closer in, guitar (quality 10) and biker (11)
/// within 0.2 dB of 0.03 for the same bytes. 0.1 diverges (biker: 55.7 -> 54.4 dB over 3 epochs).
const STEP_FRACTION: f32 = 0.01;

/// Seeds the order of the views in each epoch.
const ORDER_SEED: u64 = 0x5eed_5eed;

/// What a refit did: the mean squared error of the model at its decoded positions against
/// the model's renders over each epoch's views, as each was rendered during that epoch.
#[derive(Debug, Clone, Serialize)]
pub struct ShapeRefitOutcome {
    pub views: usize,
    pub gaussians: usize,
    /// Gaussians whose shapes were rounded in turns ([`ROUNDING_TURNS`]).
    pub rounded: usize,
    pub mse_per_epoch: Vec<f64>,
}

/// Turns in which the refitted shapes are rounded, as the colour refit rounds its colours:
/// after the epochs, every `ROUNDING_TURNS`-th kept Gaussian's scales, rotation and opacity are
/// set to what the stream will hold and [`TURN_EPOCHS`] more epochs refit the others around
/// them; the last turn's are rounded by the stream itself. On biker at quality 10 (search, both
/// refits, the doubled faint floor) halves lift the orbit from 53.86 to 53.91 dB for 0.05% more
/// bytes; thirds (with the colours in quarters) from 54.01 dB with halves to 54.07, for 0.03%
/// fewer bytes; quarters with one epoch each reach 54.05.
const ROUNDING_TURNS: usize = 3;

/// Epochs after each rounding turn.
const TURN_EPOCHS: usize = 2;

/// `g` with the scales, rotations, opacities and colours of the Gaussians `coding` keeps refitted
/// over `epochs` passes through `cameras` (each in a shuffled order, the same on every run), so
/// that, at their quantized positions, they render closest to `g`; then rounded in turns.
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
    let mut fit = ShapeFit::new(model, coding, (cameras, options, &targets));
    // Per kept Gaussian, once rounded: the shape that quantizes to what it now renders as.
    let mut held: Vec<Option<Shape>> = vec![None; keep.len()];
    for _ in 0..epochs {
        fit.epoch(&held);
    }
    // The rounded Gaussians render as the stream holds them but keep the values that quantize
    // to it: their decoded rotation can sit in another of its equivalent frames (when two are
    // nearly as close to the identity), which would quantize anew.
    for turn in 0..ROUNDING_TURNS - 1 {
        // What the stream holds now; a Gaussian the refit made invisible is left free.
        let (coded_keep, coded) = reconstruction(&write_back(g, &keep, &fit.model), coding, context)?;
        for r in (turn..keep.len()).step_by(ROUNDING_TURNS) {
            if let Ok(c) = coded_keep.binary_search(&keep[r]) {
                let m = &mut fit.model;
                held[r] = Some((m.log_scales[r], m.rotations[r], m.opacity_logits[r]));
                m.log_scales[r] = coded.log_scales[c];
                m.rotations[r] = coded.rotations[c];
                m.opacity_logits[r] = coded.opacity_logits[c];
            }
        }
        for _ in 0..TURN_EPOCHS {
            fit.epoch(&held);
        }
    }
    let outcome = ShapeRefitOutcome {
        views: cameras.len(),
        gaussians: keep.len(),
        rounded: held.iter().flatten().count(),
        mse_per_epoch: fit.mse_per_epoch,
    };
    let mut model = fit.model;
    for (r, shape) in held.into_iter().enumerate() {
        if let Some((log_scales, rotation, opacity_logit)) = shape {
            (model.log_scales[r], model.rotations[r], model.opacity_logits[r]) = (log_scales, rotation, opacity_logit);
        }
    }
    Ok((write_back(g, &keep, &model), outcome))
}

/// A Gaussian's log-scales, rotation and opacity logit.
type Shape = ([f32; 3], [f32; 4], f32);

/// The optimizer's state over one model at its decoded positions.
struct ShapeFit<'a> {
    model: Gaussians,
    views: (&'a [Camera], &'a RenderOptions, &'a [RgbImage]),
    settings: &'a QuantizerSettings,
    scales: SliceAdam,
    rotations: SliceAdam,
    opacities: SliceAdam,
    sh: SliceAdam,
    order: SplitMix64,
    step: u32,
    mse_per_epoch: Vec<f64>,
}

impl<'a> ShapeFit<'a> {
    fn new(model: Gaussians, coding: Coding<'a>, views: (&'a [Camera], &'a RenderOptions, &'a [RgbImage])) -> Self {
        let s = coding.settings;
        Self {
            scales: SliceAdam::new(model.len() * 3),
            rotations: SliceAdam::new(model.len() * 4),
            opacities: SliceAdam::new(model.len()),
            sh: SliceAdam::new(model.sh.len()),
            model,
            views,
            settings: s,
            order: SplitMix64(ORDER_SEED),
            step: 0,
            mse_per_epoch: Vec::new(),
        }
    }

    /// One pass through the views in a shuffled order; the shapes of the Gaussians `held`
    /// holds stay (their colours still move: the colour refit rounds those).
    fn epoch(&mut self, held: &[Option<Shape>]) {
        let (cameras, options, targets) = self.views;
        let s = self.settings;
        let k = self.model.coeffs_per_channel() * 3;
        let free = |per: usize, rate: f32| move |i: usize| if held[i / per].is_some() { 0.0 } else { rate };
        let mut order: Vec<usize> = (0..cameras.len()).collect();
        self.order.shuffle(&mut order);
        // The mean of the views' errors, each view counting alike whatever its size.
        let mut errors = 0.0f64;
        for &v in &order {
            let rendered = rasterize(&self.model, &cameras[v], options);
            let target = &targets[v];
            errors += mse(&rendered.color, target);
            let scale = 2.0 / target.data.len() as f32;
            let v_color: Vec<f32> =
                rendered.color.data.iter().zip(&target.data).map(|(c, t)| scale * (c - t)).collect();
            let grads = backward(&self.model, &cameras[v], options, &rendered, &v_color);
            self.step += 1;
            let model = &mut self.model;
            let step = self.step;
            let scales = free(3, STEP_FRACTION * s.log_scale_step);
            self.scales.step(model.log_scales.as_flattened_mut(), grads.log_scales.as_flattened(), scales, step);
            let rotations = free(4, STEP_FRACTION * s.rotation_step);
            self.rotations.step(model.rotations.as_flattened_mut(), grads.rotations.as_flattened(), rotations, step);
            let opacities = free(1, STEP_FRACTION * s.opacity_step);
            self.opacities.step(&mut model.opacity_logits, &grads.opacity_logits, opacities, step);
            // The view-dependent bands stay: fitted view by view from all round, they chase each
            // view's colours and the model diverges. Fox (SH degree 3) at quality 7, effort 6, at
            // a rate of 0.03: with bands 1-3 refitted too the views fell from 44.07 dB (the first
            // epoch's mean) to 34.41 dB in the third epoch and ended at 37.90 dB; with them held,
            // 46.89 -> 43.90 -> 45.67 dB, and the stream 674,521 bytes at 41.08 / 40.19 dB on the
            // orbit / from below against 674,993 bytes at 40.55 / 39.58 dB. (A band a model leaves
            // at 0, as guitar's PLY does, would also cost the stream a whole block for small gains.)
            let dc_rate = STEP_FRACTION * s.dc_step;
            self.sh.step(&mut model.sh, &grads.sh, |i| if i % k < 3 { dc_rate } else { 0.0 }, step);
        }
        self.mse_per_epoch.push(errors / order.len().max(1) as f64);
    }
}

/// `g` with the kept Gaussians' shapes and SH from `model` (row `r` is Gaussian `keep[r]`).
fn write_back(g: &Gaussians, keep: &[usize], model: &Gaussians) -> Gaussians {
    let k = g.coeffs_per_channel() * 3;
    let mut refitted = g.clone();
    for (r, &i) in keep.iter().enumerate() {
        refitted.log_scales[i] = model.log_scales[r];
        refitted.rotations[i] = model.rotations[r];
        refitted.opacity_logits[i] = model.opacity_logits[r];
        refitted.sh[i * k..(i + 1) * k].copy_from_slice(model.sh_of(r));
    }
    refitted
}

/// The Gaussians `keep` (indices into `g`), in that order.
fn subset(g: &Gaussians, keep: &[usize]) -> Gaussians {
    let mut out = Gaussians::with_degree(g.sh_degree);
    for &i in keep {
        out.push(g.means[i], g.log_scales[i], g.rotations[i], g.opacity_logits[i], g.sh_of(i));
    }
    out
}

//! Choosing the power-of-two steps of an anchor stream's networks once training is done. The
//! stream states every network's step exponents (SPEC.md sections 12.1 and 12.7), so these are
//! the encoder's choice, and fixed fine steps cost a fixed overhead that matters most at low
//! rates: on fern at λ = 0.05 the three Gaussian MLPs took 9.4 KB of a 73 KB stream at 2^-11,
//! and the context network 5 KB more at 2^-8.
//!
//! - The context network only shapes probability tables, so its step changes the rate alone:
//!   the exponent that codes the stream in the fewest bytes wins.
//! - The Gaussian MLPs change what is rendered, so their step is chosen as training traded
//!   distortion against rate: the pixel objective on training views plus λ times the stream's
//!   bits per rated value, the units of the rate term.

use std::ops::RangeInclusive;

use anyhow::Result;
use burn::tensor::{Device, Tensor};
use pwgs_codec::anchor::Mlp;
use pwgs_codec::stream::anchor::{QuantizedAnchors, QuantizedMlp};
use pwgs_codec::stream::header::Header;
use pwgs_codec::stream::{self};
use pwgs_dataset::scene::View;
use pwgs_render::raster::{RenderOptions, render};

use super::train::pixel_loss;
use crate::train::views::hwc_tensor;

/// Weight step exponents the Gaussian MLPs are tried at, finest first; biases take a step
/// 2^-1 finer (they are few, and shift every Gaussian of an anchor at once). 2^-11 was the
/// fixed step before the choice; 2^-4 is far past where fern's renders fall apart (2^-5 cost
/// 3 dB there).
pub const WEIGHT_EXPONENTS: RangeInclusive<i8> = -11..=-4;

/// Exponents the context network is tried at (weights and biases alike), finest first; 2^-8
/// was the fixed step before the choice.
pub const CONTEXT_EXPONENTS: RangeInclusive<i8> = -8..=0;

/// Training views the MLP step choice renders, at most (evenly spaced).
pub const CHOICE_VIEWS: usize = 8;

/// What the choice of the MLPs' steps weighed, per candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepCandidate {
    pub weight_exponent: i8,
    pub bytes: usize,
    /// Mean pixel objective over the chosen views.
    pub distortion: f64,
    /// distortion + λ * 8 * bytes / rated values.
    pub cost: f64,
}

/// Sets the context network's step to the exponent in [`CONTEXT_EXPONENTS`] that codes
/// `content` in the fewest bytes (the finest on ties); returns it. Does nothing without a
/// context model.
pub fn choose_context_step(content: &mut QuantizedAnchors, trained: &Mlp, header: &Header) -> Result<Option<i8>> {
    if content.context.is_none() {
        return Ok(None);
    }
    let mut best: Option<(usize, i8)> = None;
    for e in CONTEXT_EXPONENTS {
        set_context_step(content, trained, e);
        let bytes = stream::encode(header, &*content, None)?.len();
        if best.is_none_or(|(b, _)| bytes < b) {
            best = Some((bytes, e));
        }
    }
    let (_, e) = best.expect("the range is not empty");
    set_context_step(content, trained, e);
    Ok(Some(e))
}

fn set_context_step(content: &mut QuantizedAnchors, trained: &Mlp, e: i8) {
    if let Some(context) = content.context.as_mut() {
        context.mlp = QuantizedMlp::quantize(trained, e, e);
    }
}

/// The rate-distortion setting of the MLP step choice.
pub struct StepObjective<'a> {
    /// Training views with their ground truth; up to [`CHOICE_VIEWS`] of them are rendered.
    pub views: &'a [View],
    pub options: RenderOptions,
    /// The rate term's weight and the number of values its mean bits are over.
    pub lambda: f32,
    pub rated_values: usize,
}

/// Sets the three Gaussian MLPs of `content` (opacity, color, covariance, as floats in
/// `networks`) to the candidate step of [`WEIGHT_EXPONENTS`] with the least cost under
/// `objective` (the finest on ties); returns every candidate, the chosen one marked by
/// `content`'s exponents.
pub fn choose_mlp_steps(
    content: &mut QuantizedAnchors,
    networks: [&Mlp; 3],
    header: &Header,
    objective: &StepObjective,
) -> Result<Vec<StepCandidate>> {
    let device = Device::flex();
    let picked = spaced(objective.views, CHOICE_VIEWS);
    let targets: Vec<Tensor<3>> = picked.iter().map(|v| hwc_tensor(&v.image, &device)).collect();
    let mut candidates = Vec::new();
    for e in WEIGHT_EXPONENTS {
        set_mlp_steps(content, networks, e);
        let bytes = stream::encode(header, &*content, None)?.len();
        let model = content.dequantize();
        let distortion = picked
            .iter()
            .zip(&targets)
            .map(|(v, target)| {
                let image = render(&model.gaussians_for(&v.camera), &v.camera, &objective.options);
                let loss = pixel_loss(hwc_tensor(&image, &device), target.clone());
                loss.into_data().convert::<f64>().try_into_vec::<f64>().expect("a scalar")[0]
            })
            .sum::<f64>()
            / picked.len().max(1) as f64;
        let rate = 8.0 * bytes as f64 / objective.rated_values.max(1) as f64;
        let cost = distortion + f64::from(objective.lambda) * rate;
        candidates.push(StepCandidate { weight_exponent: e, bytes, distortion, cost });
    }
    let best = candidates.iter().min_by(|a, b| a.cost.total_cmp(&b.cost)).expect("the range is not empty");
    set_mlp_steps(content, networks, best.weight_exponent);
    Ok(candidates)
}

fn set_mlp_steps(content: &mut QuantizedAnchors, networks: [&Mlp; 3], e: i8) {
    content.mlps = networks.map(|m| QuantizedMlp::quantize(m, e, e - 1));
}

/// Up to `n` of `views`, evenly spaced from the first.
fn spaced(views: &[View], n: usize) -> Vec<&View> {
    let stride = views.len().div_ceil(n.max(1)).max(1);
    views.iter().step_by(stride).collect()
}

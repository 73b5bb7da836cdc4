//! A per-model search of the quantizer's balance (`pwenc --from X --importance-classes
//! --search-steps`): how coarse each attribute's step is against the others, how far apart the
//! importance classes are, and how much of any view pruning may take. A quality level fixes all of
//! them together, but the balance that codes one model smallest does not suit another: on biker
//! (positions and opacities where its error is), rotations, scales and colours can be coarser
//! than on guitar. The stream holds every step, so any balance decodes with any decoder.
//!
//! The search measures what it changes: each candidate is written and decoded as a decoder
//! would, rendered from views around the model, and scored by its bytes and its mean squared
//! error against the model's own renders. It keeps the quality level's error and looks for
//! fewer bytes, one notch at a time (marginal analysis): while the error is within the level's,
//! it takes the coarser notch that saves the most bytes for the error it adds; once beyond, the
//! finer notch that takes away the most error for the bytes it adds; it stops when that would
//! go back to where it has been, and keeps the smallest candidate within the error.
//!
//! Renders are not bit-normative, so two machines could choose differently where two
//! candidates score within rounding of each other; either stream decodes the same everywhere.

use std::collections::HashMap;

use pwgs_codec::scene::{Base, Scene};
use pwgs_core::camera::Camera;
use pwgs_core::frame::SceneFrame;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::rgb_image::RgbImage;
use pwgs_render::raster::RenderOptions;
use serde::Serialize;

use crate::metrics::psnr::mse;
use crate::plain::compress::{Coding, CompressError, QuantizerSettings, StreamContext, compress_to_size, sqrt2_power};
use crate::plain::fidelity::renders;

/// The knobs, each moved in notches from the search's base settings.
pub const KNOBS: [&str; 7] = ["scale", "rotation", "opacity", "colour", "position", "class spread", "prune budget"];
/// Farthest a knob moves from the quality level's setting, in notches.
const MAX_NOTCHES: i8 = 4;
/// Most moves the search makes.
const MAX_MOVES: usize = 12;

/// The balance an import with importance classes starts from, in notches from the quality
/// level's settings (which were set for models pwenc trains): scales a notch coarser, rotations
/// three, colours one. In imported models rotations and scales took far more of the bytes than
/// of the error (biker at quality 11: rotations 28% of the bytes for 2.5% of the squared
/// error), and the search moved them this way on both test models. Measured at effort 2
/// (`pwenc compare`'s orbit, equal PSNR): biker 6% fewer bytes at qualities 10-12, guitar 1.7%
/// to 3.6% at 9-10; with rotations two notches coarser alone, guitar 1.5-2.4%.
pub const IMPORT_BALANCE: Notches = Notches([1, 3, 0, 1, 0, 0, 0]);

/// Notches of each knob away from a quality level's settings: a notch is a factor sqrt(2) in
/// the scale, rotation, opacity and colour steps and the position grid's cell, one sqrt(2) in
/// the factor between successive importance classes, and a factor 2 in the prune budget.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize)]
pub struct Notches(pub [i8; 7]);

impl Notches {
    /// `base` moved by these notches (all at 0: `base` itself).
    pub fn apply(&self, base: &QuantizerSettings) -> QuantizerSettings {
        let [scale, rotation, opacity, colour, position, spread, budget] = self.0.map(i32::from);
        let half_bits = (2 * i32::from(base.position_bits) + i32::from(base.position_half_bit) - position).clamp(2, 48);
        QuantizerSettings {
            log_scale_step: base.log_scale_step * sqrt2_power(scale),
            rotation_step: base.rotation_step * sqrt2_power(rotation),
            opacity_step: base.opacity_step * sqrt2_power(opacity),
            dc_step: base.dc_step * sqrt2_power(colour),
            band_steps: base.band_steps.map(|s| s * sqrt2_power(colour)),
            position_bits: (half_bits / 2) as u8,
            position_half_bit: half_bits % 2 == 1,
            class_spread: (i32::from(base.class_spread) + spread).clamp(1, 8) as u8,
            prune_budget: base.prune_budget * sqrt2_power(2 * budget),
            ..base.clone()
        }
    }

    fn moved(self, knob: usize, by: i8) -> Option<Self> {
        let mut next = self;
        next.0[knob] = self.0[knob].checked_add(by).filter(|n| n.abs() <= MAX_NOTCHES)?;
        Some(next)
    }
}

/// What the search measures a candidate against: the model, how it is coded apart from the
/// steps, and the views with the model's own renders.
pub struct Probe<'a> {
    pub gaussians: &'a Gaussians,
    pub weights: &'a [f32],
    /// With pruning: the pruning costs ([`Coding::prune_costs`]).
    pub prune_costs: Option<&'a [f32]>,
    pub context: &'a StreamContext,
    pub cameras: &'a [Camera],
    pub options: &'a RenderOptions,
}

/// A candidate's bytes and mean squared error over the probe's views.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Score {
    pub bytes: usize,
    pub mse: f64,
}

/// What the search chose and measured.
#[derive(Debug, Clone, Serialize)]
pub struct SearchOutcome {
    /// The chosen notches, in the order of [`KNOBS`].
    pub notches: Notches,
    pub settings: QuantizerSettings,
    /// The quality level's own settings, and the chosen ones, on the probe's views.
    pub before: Score,
    pub after: Score,
    /// Candidates written, decoded and rendered.
    pub candidates: usize,
}

/// Searches the notches from `base` (a quality level's settings, or those moved by
/// [`IMPORT_BALANCE`]) for the model (see the module's documentation).
pub fn search(probe: &Probe, base: &QuantizerSettings) -> Result<SearchOutcome, CompressError> {
    let frame = SceneFrame { center: probe.context.center.into(), scale: probe.context.scale };
    let model = Base::Plain(probe.gaussians.clone());
    let model = Scene { base: model, wrapper: None, frame, background: probe.options.background };
    let references = renders(&model, probe.cameras, probe.options);
    let mut scored: HashMap<Notches, Score> = HashMap::new();
    let mut score = |notches: Notches| -> Result<Score, CompressError> {
        if let Some(&s) = scored.get(&notches) {
            return Ok(s);
        }
        let s = measure(probe, &notches.apply(base), &references)?;
        scored.insert(notches, s);
        Ok(s)
    };
    let before = score(Notches::default())?;
    let (mut current, mut at) = (Notches::default(), before);
    let mut best = (current, at);
    let mut visited = vec![current];
    for _ in 0..MAX_MOVES {
        // Within the error: the coarser notch that saves the most bytes for the error it adds;
        // beyond it: the finer notch that takes away the most error for the bytes it adds.
        let coarsen = at.mse <= before.mse;
        let mut chosen: Option<(f64, Notches, Score)> = None;
        for knob in 0..KNOBS.len() {
            let Some(next) = current.moved(knob, if coarsen { 1 } else { -1 }) else { continue };
            let s = score(next)?;
            let (gain, cost) = match coarsen {
                true => ((at.bytes as f64 / s.bytes as f64).ln(), (s.mse / at.mse).ln()),
                false => ((at.mse / s.mse).ln(), (s.bytes as f64 / at.bytes as f64).ln()),
            };
            let merit = if cost > 0.0 { gain / cost } else { f64::INFINITY };
            if gain > 0.0 && chosen.is_none_or(|(m, ..)| merit > m) {
                chosen = Some((merit, next, s));
            }
        }
        // No move left, or back where the search has been: the notches have settled.
        let Some((_, next, s)) = chosen.filter(|(_, next, _)| !visited.contains(next)) else { break };
        (current, at) = (next, s);
        visited.push(current);
        if at.mse <= before.mse && at.bytes < best.1.bytes {
            best = (current, at);
        }
    }
    Ok(SearchOutcome { notches: best.0, settings: best.0.apply(base), before, after: best.1, candidates: scored.len() })
}

/// Writes and decodes the model with `settings`, and scores the decoded Gaussians' renders.
fn measure(probe: &Probe, settings: &QuantizerSettings, references: &[RgbImage]) -> Result<Score, CompressError> {
    let coding = Coding { settings, weights: Some(probe.weights), prune_costs: probe.prune_costs };
    let compressed = compress_to_size(probe.gaussians, coding, probe.context, None, usize::MAX)?;
    let candidate = renders(&compressed.decoded.scene, probe.cameras, probe.options);
    let mse = candidate.iter().zip(references).map(|(a, b)| mse(a, b)).sum::<f64>() / references.len().max(1) as f64;
    Ok(Score { bytes: compressed.bytes.len(), mse })
}

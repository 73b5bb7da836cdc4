//! `pwenc --from MODEL`: compress a 3DGS model trained elsewhere, optionally checking the
//! decoded stream's renders against the model's own on an orbit.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use pwgs_codec::scene::{Base, Scene};
use pwgs_core::gaussians::Gaussians;
use pwgs_core::say;
use pwgs_core::splat_file::SpzAxes;
use pwgs_dataset::SceneViews;
use pwgs_render::raster::RenderOptions;
use serde::Serialize;

use super::effort::Tools;
use super::job::{Coded, EncodeReport, Finish, RunReport};
use super::{StreamOptions, StreamSummary, code_stream, read_model};
use crate::metrics::psnr::{psnr, psnr_of_mse};
use crate::plain::colour_refit::{self, RefitOutcome};
use crate::plain::compress::{Coding, QuantizerSettings, StreamContext};
use crate::plain::fidelity::{Orbit, orbit_cameras, renders};
use crate::plain::importance::{self, Importance};
use crate::plain::shape_refit::{self, ShapeRefitOutcome};
use crate::plain::step_search::{self, IMPORT_BALANCE, KNOBS, Probe, SearchOutcome};

/// Compressing a model trained elsewhere.
#[derive(Debug, Clone)]
pub struct ModelImport {
    /// An INRIA PLY, PlayCanvas's compressed PLY, `.splat`, `.spz` or SOG, by extension.
    pub path: PathBuf,
    /// The axes of an `.spz` input that names none.
    pub spz_axes: SpzAxes,
    /// The stream's quality level, 0 (smallest) to
    /// [`MAX_QUALITY`](crate::plain::compress::MAX_QUALITY).
    pub quality: u8,
    pub background: [f32; 3],
    /// Views rendered from the input and from the decoded stream.
    pub orbit: Option<Orbit>,
    /// Save the orbit's renders (input and decoded) as PNGs here.
    pub orbit_renders: Option<PathBuf>,
    /// The model's up direction (the orbit's, and the importance views' horizon).
    pub up: [f32; 3],
    /// The views of the capture the model was trained on, when known: the importance views
    /// include them ([`importance::capture_cameras`]).
    pub capture: Option<SceneViews>,
    /// The tools that code it smaller ([`Tools::of_effort`]).
    pub tools: Tools,
}

#[derive(Serialize)]
pub struct ImportReport {
    pub input: String,
    pub ply_bytes: u64,
    pub stream: StreamSummary,
    pub compression_ratio: f64,
    pub orbit_views: usize,
    pub orbit_size: Option<u32>,
    pub orbit_psnr: Vec<f64>,
    pub orbit_psnr_mean: Option<f64>,
    pub orbit_psnr_min: Option<f64>,
    /// What `--search-steps` chose and measured.
    pub step_search: Option<SearchOutcome>,
    /// What `--refit-colours` measured.
    pub colour_refit: Option<RefitOutcome>,
    /// What `--refit-shapes` measured.
    pub shape_refit: Option<ShapeRefitOutcome>,
}

/// Codes the model `job` names into the stream of `finish`'s outputs, and finishes: the orbit,
/// when asked for, scores the decoded stream against the input once the stream is written.
pub(super) fn run(job: &ModelImport, finish: Finish) -> Result<EncodeReport> {
    let ply = &job.path;
    let path = finish.outputs.stream.clone().context("an import needs a stream to write (-o)")?;
    let gaussians = read_model(ply, job.spz_axes)?;
    let ply_bytes = std::fs::metadata(ply).with_context(|| format!("cannot read {}", ply.display()))?.len();
    let context = StreamContext::from_gaussians(&gaussians, job.background);
    let options = RenderOptions { background: job.background, ..Default::default() };
    let plan = plan_coding(job, &gaussians, &context, &options)?;
    let coded = plan.refitted.as_ref().unwrap_or(&gaussians);
    let stream_options = StreamOptions {
        path,
        quality: job.quality,
        target_bytes: finish.outputs.target_bytes,
        prune_faint: job.tools.prune_faint,
    };
    let (compressed, stream) =
        code_stream(coded, (&context, &plan.settings), &stream_options, None, plan.importance.as_ref())?;
    let decoded_scene = &compressed.decoded.scene;
    let coded = Coded { stream: Some(&compressed.bytes), shown: decoded_scene, test: &[], export: None };
    finish.finish(coded, || {
        let orbit_psnr = score_orbit(job, gaussians, decoded_scene, (&context, &options))?;
        Ok(RunReport::Model(Box::new(import_report(job, ply_bytes, stream, orbit_psnr, plan))))
    })
}

/// PSNR of the decoded stream's renders against the input model's on `job`'s orbit (none
/// without one), saving the renders when asked.
fn score_orbit(
    job: &ModelImport,
    input: Gaussians,
    decoded_scene: &Scene,
    (context, options): (&StreamContext, &RenderOptions),
) -> Result<Vec<f64>> {
    let mut orbit_psnr = Vec::new();
    if let Some(orbit) = &job.orbit {
        let cameras = orbit_cameras(context, orbit).with_context(|| views_problem("orbit", context))?;
        let (frame, background) = (decoded_scene.frame, decoded_scene.background);
        let input = Scene { base: Base::Plain(input), wrapper: None, frame, background };
        let reference = renders(&input, &cameras, options);
        let decoded = renders(decoded_scene, &cameras, options);
        orbit_psnr = decoded.iter().zip(&reference).map(|(a, b)| psnr(a, b)).collect();
        if let Some(dir) = &job.orbit_renders {
            for (i, (input, decoded)) in reference.iter().zip(&decoded).enumerate() {
                input.save_png(&dir.join(format!("orbit_{i:03}_input.png")))?;
                decoded.save_png(&dir.join(format!("orbit_{i:03}_decoded.png")))?;
            }
        }
        for (i, p) in orbit_psnr.iter().enumerate() {
            say!("orbit view {i:>3}: PSNR {p:.2} dB against the input model");
        }
    }
    Ok(orbit_psnr)
}

fn import_report(
    job: &ModelImport,
    ply_bytes: u64,
    stream: StreamSummary,
    orbit_psnr: Vec<f64>,
    plan: CodingPlan,
) -> ImportReport {
    let mean = (!orbit_psnr.is_empty()).then(|| orbit_psnr.iter().sum::<f64>() / orbit_psnr.len() as f64);
    let min = orbit_psnr.iter().copied().reduce(f64::min);
    if let (Some(mean), Some(min)) = (mean, min) {
        say!("orbit: mean PSNR {mean:.2} dB, lowest {min:.2} dB over {} views", orbit_psnr.len());
    }
    let ratio = ply_bytes as f64 / stream.bytes as f64;
    say!("{} -> {}: {ply_bytes} -> {} bytes ({ratio:.1}x smaller)", job.path.display(), stream.path, stream.bytes);
    ImportReport {
        input: job.path.display().to_string(),
        ply_bytes,
        stream,
        compression_ratio: ratio,
        orbit_views: orbit_psnr.len(),
        orbit_size: job.orbit.as_ref().map(|o| o.size),
        orbit_psnr,
        orbit_psnr_mean: mean,
        orbit_psnr_min: min,
        step_search: plan.step_search,
        colour_refit: plan.colour_refit,
        shape_refit: plan.shape_refit,
    }
}

/// What to say when views around the model cannot be placed: cameras are binary32, and a model
/// whose radius is beyond about 1e19 (positions that far from their median) puts them where a
/// direction's squared length overflows.
fn views_problem(views: &str, context: &StreamContext) -> String {
    format!("cannot place the {views} views {:e} from the model's center {:?}", context.scale, context.center)
}

/// `--search-steps` scores candidates on every third importance view (19 of 57), a third of
/// the rendering (about a minute on biker's 153,000 Gaussians).
const SEARCH_VIEW_STRIDE: usize = 3;

fn print_search(outcome: &SearchOutcome, views: usize, seconds: f64) {
    let moved: Vec<String> = (KNOBS.iter().zip(outcome.notches.0))
        .filter(|(_, n)| *n != 0)
        .map(|(knob, n)| format!("{knob} {n:+}"))
        .collect();
    let moved = if moved.is_empty() { "none".to_string() } else { moved.join(", ") };
    say!(
        "step search: {} candidates on {views} importance views in {seconds:.1} s; notches moved: {moved}; \
         {} bytes at {:.2} dB -> {} bytes at {:.2} dB on those views",
        outcome.candidates,
        outcome.before.bytes,
        psnr_of_mse(outcome.before.mse),
        outcome.after.bytes,
        psnr_of_mse(outcome.after.mse),
    );
}

/// How an import codes its model: the importance weights, the settings, and the model to code
/// (the input, or the input with refitted colours).
struct CodingPlan {
    importance: Option<Importance>,
    settings: QuantizerSettings,
    step_search: Option<SearchOutcome>,
    refitted: Option<Gaussians>,
    colour_refit: Option<RefitOutcome>,
    shape_refit: Option<ShapeRefitOutcome>,
}

fn plan_coding(
    job: &ModelImport,
    gaussians: &Gaussians,
    context: &StreamContext,
    options: &RenderOptions,
) -> Result<CodingPlan> {
    let mut plan = CodingPlan {
        importance: None,
        settings: QuantizerSettings::for_quality(job.quality),
        step_search: None,
        refitted: None,
        colour_refit: None,
        shape_refit: None,
    };
    let mut tools = job.tools;
    if !tools.importance {
        return Ok(plan);
    }
    plan.settings = IMPORT_BALANCE.apply(&plan.settings);
    let start = Instant::now();
    let up = Vec3::from(job.up);
    let placed = || views_problem("importance", context);
    let mut cameras = importance::class_cameras(context, up).with_context(placed)?;
    let all_round = cameras.len();
    if let Some(views) = &job.capture {
        let scene = || format!("cannot use the views of {}", views.scene.display());
        let capture: Vec<_> = views.cameras().with_context(scene)?.into_iter().map(|v| v.camera).collect();
        cameras.extend(importance::capture_cameras(&capture).with_context(scene)?);
    }
    let others =
        if tools.prune_faint { importance::closer_cameras(context, up).with_context(placed)? } else { Vec::new() };
    let bar = phase_bar(cameras.len() + others.len(), "importance views");
    let measured = Importance::of_views_reporting(gaussians, (&cameras, &others), options, &|| bar.inc(1));
    bar.finish_and_clear();
    let hidden = measured.weights.iter().filter(|&&w| w == 0.0).count();
    let full = cameras[..all_round].iter().filter(|c| c.width == importance::VIEW_SIZE).count();
    let capture = match cameras.len() - all_round {
        0 => String::new(),
        n => format!(", {n} of the capture"),
    };
    say!(
        "importance: {} views ({full} of {size}x{size}, {} of {other}x{other}{capture}) in {:.1} s; {hidden} of {} \
         Gaussians never blended in the class views",
        cameras.len() + others.len(),
        all_round + others.len() - full,
        start.elapsed().as_secs_f64(),
        gaussians.len(),
        size = importance::VIEW_SIZE,
        other = importance::OTHER_VIEW_SIZE,
    );
    let (weights, prune_costs) = (&measured.weights[..], tools.prune_faint.then_some(&measured.prune_costs[..]));
    if tools.search_steps {
        let start = Instant::now();
        let views: Vec<_> = cameras.iter().step_by(SEARCH_VIEW_STRIDE).cloned().collect();
        let probe = Probe { gaussians, weights, prune_costs, context, cameras: &views, options };
        let outcome = step_search::search(&probe, &plan.settings)?;
        print_search(&outcome, views.len(), start.elapsed().as_secs_f64());
        plan.settings = outcome.settings.clone();
        plan.step_search = Some(outcome);
    }
    let refits = tools.refit_shapes.is_some() || tools.refit_colours.is_some();
    // The refits fit the class views.
    let refit_views = cameras;
    let held = refit_bytes(gaussians.len(), refit_views.len());
    if refits && held > REFIT_MEMORY_BUDGET {
        say!(
            "refits left out: {} Gaussians on {} views would hold about {:.1} GB of splats (at most {} GB)",
            gaussians.len(),
            refit_views.len(),
            held as f64 / f64::from(1u32 << 30),
            REFIT_MEMORY_BUDGET >> 30,
        );
        tools = tools.without_refits();
    }
    if tools.refit_shapes.is_some() {
        plan.settings.prune_budget *= REFIT_BUDGET_FACTOR;
    }
    let coding = Coding { settings: &plan.settings, weights: Some(weights), prune_costs };
    if let Some(epochs) = tools.refit_shapes {
        let start = Instant::now();
        let (refitted, outcome) =
            shape_refit::refit_shapes(gaussians, coding, context, (&refit_views, options), epochs)?;
        say!(
            "shape refit: {} Gaussians on {} views in {:.1} s: {} dB per epoch (at the quantized positions, before quantizing the rest)",
            outcome.gaussians,
            outcome.views,
            start.elapsed().as_secs_f64(),
            outcome.mse_per_epoch.iter().map(|&m| format!("{:.2}", psnr_of_mse(m))).collect::<Vec<_>>().join(" -> "),
        );
        plan.refitted = Some(refitted);
        plan.shape_refit = Some(outcome);
    }
    if let Some(refit) = tools.refit_colours {
        let start = Instant::now();
        let model = plan.refitted.as_ref().unwrap_or(gaussians);
        let bar = phase_bar(refit.steps(), "colour refit iterations");
        let (refitted, outcome) = colour_refit::refit_colours(
            (model, gaussians),
            coding,
            context,
            (&refit_views, options),
            (refit, &|| bar.inc(1)),
        )?;
        bar.finish_and_clear();
        say!(
            "colour refit: {} Gaussians on {} views in {:.1} s: {:.2} dB -> {} dB (before quantizing the colours)",
            outcome.gaussians,
            outcome.views,
            start.elapsed().as_secs_f64(),
            psnr_of_mse(outcome.mse_before),
            outcome.mse_after.iter().map(|&m| format!("{:.2}", psnr_of_mse(m))).collect::<Vec<_>>().join(" -> "),
        );
        plan.refitted = Some(refitted);
        plan.colour_refit = Some(outcome);
    }
    plan.importance = Some(measured);
    Ok(plan)
}

/// The refits hold every refit view's splats and tile lists at once: biker (130,657 Gaussians
/// kept) peaked at 1.1 GB with the colour refit on 57 views and 1.66 GB on the 98 of
/// [`importance::class_cameras`] (whose 41 smaller views hold about as much each: the splats,
/// not the tiles, fill them), about 150 bytes per Gaussian and view. Beyond the budget an import
/// leaves the refits out, with a message, rather than exhaust memory (about 290,000 Gaussians
/// fit; a 3M-Gaussian model would hold about 41 GB).
const REFIT_MEMORY_BUDGET: usize = 4 << 30;
const REFIT_BYTES_PER_SPLAT: usize = 150;

/// What the refits would hold for `gaussians` on `views` views.
fn refit_bytes(gaussians: usize, views: usize) -> usize {
    gaussians.saturating_mul(views).saturating_mul(REFIT_BYTES_PER_SPLAT)
}

/// A progress bar over one phase of an import, `len` steps of `what`: drawn on a terminal
/// only (the log's lines say what each phase did).
fn phase_bar(len: usize, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed_precise}<{eta_precise}]")
            .expect("valid template"),
    );
    bar.set_message(what.to_string());
    bar
}

/// With `--refit-shapes` the prune budget (the step search's, or the quality level's) is this
/// much larger: the refitted Gaussians around a pruned one fill its gap. On the models without
/// SH bands that trades the views below the horizon for the orbit above it: with 2 epochs guitar
/// at quality 10 and biker at 11 code 2.8% and 1.1% smaller at equal PSNR on an orbit above the
/// horizon but 5.6% and 2.9% larger on one 35 degrees below than at the budget itself; on fox
/// and fern (SH degree 3, quality 7) the budget itself codes 2-10% larger on the orbit, from
/// below and closer in alike.
const REFIT_BUDGET_FACTOR: f32 = 2.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refits_fit_for_models_of_biker_size_and_not_for_millions() {
        assert!(refit_bytes(152_746, 98) <= REFIT_MEMORY_BUDGET);
        assert!(refit_bytes(250_000, 98) <= REFIT_MEMORY_BUDGET);
        assert!(refit_bytes(400_000, 98) > REFIT_MEMORY_BUDGET);
        assert_eq!(refit_bytes(usize::MAX, 98), usize::MAX);
    }
}

//! `pwenc SCENE --base anchor`: trains the anchor base (quantization noise, the rate term and,
//! with a wrapper, stage 2 with the perceptual wrapper), quantizes it into an anchor stream
//! (SPEC.md section 12), fits it to the target size, and finishes with what a decoder
//! reconstructs from that stream. The stages: `configure`, `train`, `quantize`, `fit`, then
//! the pipeline's common finish.

use std::borrow::Cow;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use pwgs_codec::scene::Base;
use pwgs_codec::stream::anchor::QuantizedAnchors;
use pwgs_codec::stream::header::{BaseKind, Header};
use pwgs_codec::stream::plain::PositionGrid;
use pwgs_codec::stream::wrap::QuantizedSynthesis;
use pwgs_codec::stream::{self, Decoded};
use pwgs_core::camera::Camera;
use pwgs_core::say;
use pwgs_dataset::Dataset;
use pwgs_render::anchor_export::{agreement_psnr, export_gaussians};
use pwgs_render::raster::{RenderOptions, render};
use pwgs_render::show::SceneRender;
use serde::Serialize;

use super::job::{Coded, EncodeReport, Finish, RunReport, SceneSummary};
use super::{WrapperSummary, print_wrapper, quantize_wrapper, section_sizes, size_limit};
use crate::anchor::context::{ContextLookup, context_shape};
use crate::anchor::growth::GrowthSchedule;
use crate::anchor::init::{AnchorShape, initial_model};
use crate::anchor::network_steps::{StepCandidate, StepObjective, choose_context_step, choose_mlp_steps};
use crate::anchor::quantize::{AnchorSteps, grid_coordinates, quantize as quantize_anchors, quantize_context};
use crate::anchor::train::{AnchorTrainer, GrowthTotals, StageTwoLambda};
use crate::anchor::trim::fit_anchors;
use crate::train::device::{StepTrace, TrainingDevice};
use crate::wrapper::stage::WrapperTraining;

/// Training the anchor base.
#[derive(Debug, Clone)]
pub struct AnchorTraining {
    pub iterations: u32,
    pub feature_dim: usize,
    pub offsets_per_anchor: usize,
    /// Voxel edge for the anchors, as a fraction of the scene's normalization scale.
    pub relative_voxel: f32,
    pub background: [f32; 3],
    pub seed: u64,
    pub steps: AnchorSteps,
    /// Train with quantization noise (from a tenth of the iterations on).
    pub quantization_noise: bool,
    /// λ of the rate term (from 30% of the iterations on, with learned masks); `None`: no rate
    /// term, every mask open.
    pub lambda: Option<f32>,
    /// Train and code with the context model (SPEC.md section 12.7); needs the rate term.
    pub context: bool,
    /// How λ carries over into stage 2, with the wrapper.
    pub stage_two_lambda: StageTwoLambda,
    /// The context grid's 2D plane levels (SPEC.md section 12.7; none: 3D levels only).
    pub context_planes: Vec<u8>,
    /// Grow and prune anchors over the first half of stage 1 ([`crate::anchor::growth`]), up
    /// to `max_anchors` (default: twice the initial anchors).
    pub growth: bool,
    pub max_anchors: Option<usize>,
    /// Learn a factor on each group's step while the rate term is on (the stream is written
    /// with the learned steps).
    pub learned_steps: bool,
    /// Bytes of training images kept on the training device ([`crate::train::views`]).
    pub image_budget: usize,
    /// Stage 2 with the perceptual wrapper after the `iterations` of stage 1, for
    /// `crops_per_view` steps per training view.
    pub wrapper: Option<WrapperTraining>,
}

impl AnchorTraining {
    /// Refuses settings that contradict each other.
    pub fn check(&self) -> Result<()> {
        anyhow::ensure!(
            self.lambda.is_none() || self.quantization_noise,
            "the rate term (--lambda) needs the quantization noise"
        );
        anyhow::ensure!(!self.context || self.lambda.is_some(), "the context model needs the rate term (--lambda > 0)");
        Ok(())
    }
}

/// The anchor stream as written.
#[derive(Serialize)]
pub struct AnchorStreamSummary {
    pub path: Option<String>,
    pub bytes: usize,
    pub feature_step: f32,
    pub scaling_step: f32,
    pub offset_step: f32,
    /// The Gaussian MLPs' steps (chosen by rate-distortion with the rate term).
    pub weight_step_log2: i8,
    pub bias_step_log2: i8,
    /// The context network's step (chosen for the fewest bytes), with the context model.
    pub context_step_log2: Option<i8>,
    pub sections: Vec<(String, usize)>,
    pub attribute_sha256: String,
    pub wrapper: Option<WrapperSummary>,
}

#[derive(Serialize)]
pub struct AnchorReport {
    #[serde(flatten)]
    pub scene: SceneSummary,
    pub anchors: usize,
    pub feature_dim: usize,
    pub offsets_per_anchor: usize,
    pub voxel: f32,
    pub iterations: u32,
    pub training_seconds: f64,
    /// Neural Gaussians rendered at the last step.
    pub last_step_gaussians: usize,
    pub quantization_noise: bool,
    pub lambda: Option<f32>,
    /// With the wrapper and the rate term: λ's factor at the last step of stage 2.
    pub stage_two_lambda_factor: Option<f32>,
    /// The rate model's estimate of the attributes' size at the last step, in bytes.
    pub estimated_attribute_bytes: Option<f64>,
    /// With the context model: its grid's size as an adaptive binary coder would code it.
    pub context_grid_bytes: Option<f64>,
    /// Anchors grown and pruned during training, when growing was on.
    pub growth: Option<GrowthTotals>,
    /// Anchors in the stream (those with an open mask).
    pub stream_anchors: usize,
    pub target_bytes: Option<u64>,
    /// Anchors dropped to meet the target size.
    pub anchors_dropped_to_fit: usize,
    /// The stream (also when none was written to a file: the evaluation renders its decoding).
    pub stream: AnchorStreamSummary,
}

/// Trains the anchor base on `data` (loaded from `scene`), codes its stream and finishes.
pub(super) fn run(
    job: &AnchorTraining,
    (scene, data): (&Path, &Dataset),
    device: &TrainingDevice,
    finish: Finish,
) -> Result<EncodeReport> {
    let Configured { mut trainer, grid, anchors, voxel } = configure(job, data, device)?;
    let trained = train(job, &mut trainer)?;
    let Quantized { content, header, steps, context_step_log2, wrapper } = quantize(job, data, &trainer, &grid)?;
    let cameras: Vec<Camera> = data.train.iter().map(|v| v.camera).collect();
    let fitted = fit(content, (&header, wrapper.as_ref()), size_limit(finish.outputs.target_bytes), &cameras)?;
    if let Some(target) = finish.outputs.target_bytes {
        say!("target {target} bytes: {} least important anchors dropped to fit", fitted.dropped);
    }
    let shown = &fitted.decoded.scene;
    let export = || {
        let Base::Anchors(model) = &shown.base else { anyhow::bail!("an anchor stream decoded to plain Gaussians") };
        let export = export_gaussians(model, &cameras);
        // Checked on the test views (the fit saw only the training views).
        let test: Vec<Camera> = data.test.iter().map(|v| v.camera).collect();
        let checked = if test.is_empty() { &cameras[..cameras.len().min(8)] } else { &test[..] };
        let psnr = agreement_psnr(model, &export, checked, &shown.render_options());
        say!("export: SH degree 3 fitted, PSNR {psnr:.2} dB against the anchor renders of {} views", checked.len());
        Ok(Cow::Owned(export))
    };
    let coded = Coded { stream: Some(&fitted.bytes), shown, test: &data.test, export: Some(&export) };
    let stream_path = finish.outputs.stream.as_ref().map(|p| p.display().to_string());
    let target_bytes = finish.outputs.target_bytes;
    finish.finish(coded, || {
        let stream = AnchorStreamSummary {
            path: stream_path,
            bytes: fitted.bytes.len(),
            feature_step: steps.feature,
            scaling_step: steps.scaling,
            offset_step: steps.offset,
            weight_step_log2: fitted.content.mlps[0].weight_exponent,
            bias_step_log2: fitted.content.mlps[0].bias_exponent,
            context_step_log2,
            sections: section_sizes(&fitted.bytes),
            attribute_sha256: shown.attribute_hash(),
            wrapper: wrapper.as_ref().map(WrapperSummary::of),
        };
        Ok(RunReport::Anchor(Box::new(AnchorReport {
            scene: SceneSummary::of(scene, data, "anchor", device),
            anchors,
            feature_dim: job.feature_dim,
            offsets_per_anchor: job.offsets_per_anchor,
            voxel,
            iterations: trained.iterations,
            training_seconds: trained.seconds,
            last_step_gaussians: trained.last_step_gaussians,
            quantization_noise: job.quantization_noise,
            lambda: job.lambda,
            stage_two_lambda_factor: trained.stage_two_lambda_factor,
            estimated_attribute_bytes: trained.estimated_attribute_bytes,
            context_grid_bytes: trained.context_grid_bytes,
            growth: trained.growth,
            stream_anchors: fitted.content.len(),
            target_bytes,
            anchors_dropped_to_fit: fitted.dropped,
            stream,
        })))
    })
}

/// A trainer set up for a job, with the grid its anchors sit on.
struct Configured {
    trainer: AnchorTrainer,
    grid: PositionGrid,
    /// Anchors at the start.
    anchors: usize,
    /// The voxel edge, in scene units.
    voxel: f32,
}

/// Places the initial anchors on the scene's points and sets the trainer up with every term
/// `job` asks for.
fn configure(job: &AnchorTraining, data: &Dataset, device: &TrainingDevice) -> Result<Configured> {
    let points = data.points.as_ref().context("the anchor base starts from the scene's SfM points; it has none")?;
    let voxel = job.relative_voxel * data.normalization.scale;
    let shape = AnchorShape { feature_dim: job.feature_dim, offsets_per_anchor: job.offsets_per_anchor, voxel };
    let (initial, grid) = initial_model(points, shape, job.seed)?;
    say!(
        "{} anchors from {} points (voxel {voxel:.5}), {} neural Gaussians each, features of {}",
        initial.len(),
        points.positions.len(),
        job.offsets_per_anchor,
        job.feature_dim
    );
    let stage_two = job.wrapper.as_ref().map_or(0, |w| w.stage_two_steps(data.train.len()));
    let total = job.iterations.saturating_add(stage_two);
    let mut trainer = AnchorTrainer::new(&initial, data, total, job.background, job.seed, &device.device)?
        .with_image_budget(job.image_budget);
    if let Some(w) = &job.wrapper {
        trainer = trainer.with_wrapper(w.clone())?.with_stage_two_lambda(job.stage_two_lambda);
        say!(
            "stage 1: {} iterations; stage 2: {stage_two} steps ({} crops per training view, at least {})",
            job.iterations,
            w.crops_per_view,
            w.min_steps
        );
    }
    if job.quantization_noise {
        trainer = trainer.with_quantization_noise(job.steps, job.iterations / 10);
    }
    if let Some(lambda) = job.lambda {
        trainer = trainer.with_rate(lambda, job.iterations * 3 / 10);
    }
    let coords = grid_coordinates(&initial.positions, &grid)?;
    if job.context {
        let lookup =
            ContextLookup::new(context_shape(job.context_planes.clone()), &coords, grid.depth, &trainer.device());
        let shape = &lookup.shape;
        say!(
            "context grid: {} entries in {} levels and {} plane levels",
            lookup.entries,
            shape.levels.len(),
            shape.planes.len()
        );
        trainer = trainer.with_context(lookup);
    }
    if job.learned_steps && job.lambda.is_some() {
        trainer = trainer.with_learned_steps();
    }
    trainer = trainer.with_placement(grid, coords);
    if job.growth {
        let schedule = GrowthSchedule::scaled(job.iterations, job.max_anchors.unwrap_or(2 * initial.len()));
        say!(
            "growing and pruning anchors every {} iterations from {} to {}, up to {}",
            schedule.every,
            schedule.from,
            schedule.until,
            schedule.max_anchors
        );
        trainer = trainer.with_growth(schedule);
    }
    Ok(Configured { trainer, grid, anchors: initial.len(), voxel })
}

/// What training measured, for the report.
struct Trained {
    iterations: u32,
    seconds: f64,
    last_step_gaussians: usize,
    stage_two_lambda_factor: Option<f32>,
    estimated_attribute_bytes: Option<f64>,
    context_grid_bytes: Option<f64>,
    growth: Option<GrowthTotals>,
}

/// Runs every iteration of both stages, with a line every 100.
fn train(job: &AnchorTraining, trainer: &mut AnchorTrainer) -> Result<Trained> {
    let start = Instant::now();
    let mut last_step_gaussians = 0;
    let mut last_bits = None;
    let mut trace = StepTrace::from_env();
    while trainer.iteration < trainer.iterations {
        let step = trainer.step()?;
        trace.step(trainer.iteration);
        last_step_gaussians = step.gaussians;
        last_bits = step.bits_per_value;
        let it = trainer.iteration;
        if it.is_multiple_of(100) || it == trainer.iterations {
            let rate = f64::from(it) / start.elapsed().as_secs_f64().max(1e-9);
            let bits = step.bits_per_value.map(|b| format!("  {b:.3} bits/value")).unwrap_or_default();
            eprintln!(
                "iteration {it}/{}  loss {:.4}  PSNR {:.2}  Gaussians {}  open masks {}{bits}  {rate:.2} it/s",
                trainer.iterations, step.loss, step.psnr, step.gaussians, step.open_masks
            );
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    say!("trained {} iterations in {seconds:.1} s", trainer.iteration);
    let stage_two_lambda_factor = (job.wrapper.is_some() && job.lambda.is_some()).then(|| trainer.lambda_factor());
    if let Some(factor) = stage_two_lambda_factor {
        say!("stage 2 ended with λ x {factor:.2}");
    }
    let growth = trainer.growth_totals();
    if let Some(g) = growth {
        say!("anchors: {} grown, {} pruned", g.grown, g.pruned);
    }
    // What the rate model says the attributes cost (at the last step's noisy values), to set
    // beside the stream's sections.
    let estimated_attribute_bytes = last_bits.map(|b| f64::from(b) * trainer.rated_values() as f64 / 8.0);
    let context_grid_bytes = trainer.context_grid_bits().map(|b| b / 8.0);
    if let Some(bytes) = estimated_attribute_bytes {
        let grid = context_grid_bytes.map(|g| format!(", grid {g:.0} bytes")).unwrap_or_default();
        let model = if job.context { "context" } else { "factorized" };
        say!("rate model ({model}) estimate: attributes, anchor positions and masks {bytes:.0} bytes{grid}");
    }
    Ok(Trained {
        iterations: trainer.iteration,
        seconds,
        last_step_gaussians,
        stage_two_lambda_factor,
        estimated_attribute_bytes,
        context_grid_bytes,
        growth,
    })
}

/// The trained anchors as a stream codes them, before any are dropped for size.
struct Quantized {
    content: QuantizedAnchors,
    header: Header,
    /// The attribute steps: learned, or the job's.
    steps: AnchorSteps,
    context_step_log2: Option<i8>,
    wrapper: Option<QuantizedSynthesis>,
}

/// Quantizes the anchors with the learned steps, chooses the networks' steps (the context
/// network's for the fewest bytes, the Gaussian MLPs' by rate-distortion) and the wrapper's.
fn quantize(job: &AnchorTraining, data: &Dataset, trainer: &AnchorTrainer, grid: &PositionGrid) -> Result<Quantized> {
    let steps = trainer.steps().unwrap_or(job.steps);
    if steps != job.steps {
        say!(
            "learned steps: features {:.4}, scaling {:.4}, offsets {:.4} (from {}, {}, {})",
            steps.feature,
            steps.scaling,
            steps.offset,
            job.steps.feature,
            job.steps.scaling,
            job.steps.offset
        );
    }
    let model = trainer.model();
    let mut content = quantize_anchors(&model, grid, &steps)?;
    let header = Header {
        base: BaseKind::Anchors,
        gaussian_count: u32::try_from(content.len()).context("too many anchors for a stream")?,
        sh_degree: 0,
        center: data.normalization.center.to_array(),
        scale: data.normalization.scale,
        background: job.background,
    };
    let context_step_log2 = match trainer.context_model() {
        Some(trained) => {
            quantize_context(&mut content, &trained);
            choose_context_step(&mut content, &trained.mlp, &header)?
        }
        None => None,
    };
    if let Some(lambda) = job.lambda {
        let objective = StepObjective {
            views: &data.train,
            options: RenderOptions { background: job.background, ..Default::default() },
            lambda,
            rated_values: trainer.rated_values(),
        };
        let candidates =
            choose_mlp_steps(&mut content, [&model.opacity, &model.color, &model.covariance], &header, &objective)?;
        print_step_choice(&candidates, content.mlps[0].weight_exponent, context_step_log2);
    }
    let wrapper = match trainer.synthesis() {
        Some(weights) => {
            // f's steps are chosen on renders of the anchors as a decoder lists them (in the
            // octree's order, which the depth sort's ties follow).
            let Decoded { scene: stored, .. } = decode_own(&stream::encode(&header, &content, None)?)?;
            let options = RenderOptions { background: job.background, ..Default::default() };
            let base_render = |camera: &Camera| render(&stored.gaussians_for(camera), camera, &options).data;
            let w = quantize_wrapper(&weights, &base_render, data, data.normalization.frame());
            print_wrapper(&w);
            Some(w)
        }
        None => None,
    };
    Ok(Quantized { content, header, steps, context_step_log2, wrapper })
}

/// The stream fitted to a size, and what a decoder reconstructs from it.
struct Fitted {
    content: QuantizedAnchors,
    bytes: Vec<u8>,
    /// Anchors dropped to fit.
    dropped: usize,
    decoded: Decoded,
}

/// Drops the anchors that show least over `cameras` until the stream fits in `limit` bytes
/// (without a limit every anchor fits: the stream is written once, nothing is ranked).
fn fit(
    content: QuantizedAnchors,
    (header, wrapper): (&Header, Option<&QuantizedSynthesis>),
    limit: usize,
    cameras: &[Camera],
) -> Result<Fitted> {
    let (content, bytes, dropped) = fit_anchors(content, header, wrapper, limit, cameras)?;
    let decoded = decode_own(&bytes)?;
    Ok(Fitted { content, bytes, dropped, decoded })
}

/// One line per candidate of the MLP step choice, and the steps chosen.
fn print_step_choice(candidates: &[StepCandidate], chosen: i8, context: Option<i8>) {
    for c in candidates {
        say!(
            "  MLP weights at 2^{}: {} bytes, pixel objective {:.5}, cost {:.5}{}",
            c.weight_exponent,
            c.bytes,
            c.distortion,
            c.cost,
            if c.weight_exponent == chosen { "  (chosen)" } else { "" }
        );
    }
    if let Some(e) = context {
        say!("context network at 2^{e} (the fewest bytes)");
    }
}

/// What every decoder reconstructs from the encoder's own anchor stream `bytes`.
fn decode_own(bytes: &[u8]) -> Result<Decoded> {
    stream::decode(bytes).context("the encoder's own anchor stream does not decode")
}

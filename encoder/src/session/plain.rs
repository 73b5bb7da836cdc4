//! `pwenc SCENE --base 3dgs`: train plain Gaussians on a scene's views, then code the stream
//! and finish (write, export, evaluate, report).

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Result;
use indicatif::{ProgressBar, ProgressStyle};
use pwgs_codec::scene::{Base, Scene};
use pwgs_codec::stream::wrap::QuantizedSynthesis;
use pwgs_core::camera::Camera;
use pwgs_core::say;
use pwgs_dataset::Dataset;
use pwgs_render::raster::{RenderOptions, render};
use serde::Serialize;

use super::job::{Coded, EncodeReport, Finish, RunReport, SceneSummary, export_ply};
use super::{StreamOptions, StreamSummary, code_stream, print_wrapper, quantize_wrapper, read_ply};
use crate::plain::compress::{QuantizerSettings, StreamContext};
use crate::plain::init::initial_gaussians;
use crate::plain::train::{TrainConfig, TrainSummary, Trainer, train};
use crate::train::device::TrainingDevice;

/// Training the plain base. `config.background` is also the scene's background.
#[derive(Debug, Clone)]
pub struct PlainTraining {
    /// Start from this INRIA PLY instead of the scene's points.
    pub init_ply: Option<PathBuf>,
    pub config: TrainConfig,
    /// The stream's quality level, 0 (smallest) to
    /// [`MAX_QUALITY`](crate::plain::compress::MAX_QUALITY).
    pub quality: u8,
}

#[derive(Serialize)]
pub struct PlainReport {
    #[serde(flatten)]
    pub scene: SceneSummary,
    pub load_seconds: f64,
    pub training: TrainSummary,
    /// Size of the trained model as an uncompressed INRIA PLY.
    pub ply_bytes: usize,
    pub stream: Option<StreamSummary>,
}

/// Trains plain Gaussians on `data` (loaded from `scene` in `load_seconds`), codes the stream
/// when one is asked for, and finishes.
pub(super) fn run(
    job: &PlainTraining,
    (scene, data, load_seconds): (&Path, &Dataset, f64),
    device: &TrainingDevice,
    finish: Finish,
) -> Result<EncodeReport> {
    let cap = job.config.densify.max_gaussians;
    let initial = match &job.init_ply {
        Some(path) => read_ply(path)?,
        None => initial_gaussians(data, job.config.seed, cap)?,
    };
    if let Some(points) = data.points.as_ref().filter(|p| job.init_ply.is_none() && p.positions.len() > cap) {
        say!("initialization: {} of the {} SfM points (--max-gaussians {cap})", initial.len(), points.positions.len());
    }
    let mut config = job.config.clone();
    config.initial_sh_degree = initial.sh_degree;
    config.schedule_stage_two(data.train.len());
    if let Some(w) = &config.wrapper {
        say!(
            "stage 1: {} iterations; stage 2: {} steps ({} crops per training view, at least {})",
            w.start,
            config.iterations - w.start,
            w.crops_per_view,
            w.min_steps
        );
    }
    let background = config.background;
    let iterations = config.iterations;
    let mut trainer = Trainer::new(config, data, &initial, device.device.clone())?;
    let result = train_with_progress(&mut trainer, iterations);
    let gaussians = trainer.gaussians();
    let training = match result {
        Ok(training) => training,
        Err(e) => {
            // The model holds its last good state: save it before saying what went wrong.
            if let Some(path) = &finish.outputs.export_ply {
                export_ply(path, &gaussians)?;
            }
            return Err(e);
        }
    };
    say!("trained {} iterations in {:.1} s: {} Gaussians", training.iterations, training.seconds, training.gaussians);
    let n = data.normalization;
    let frame = n.frame();
    let options = RenderOptions { background, ..Default::default() };
    let base_render = |camera: &Camera| render(&gaussians, camera, &options).data;
    let wrapper = trainer.synthesis().map(|w| quantize_wrapper(&w, &base_render, data, frame));
    if let Some(w) = &wrapper {
        print_wrapper(w);
    }
    let (compressed, summary) = match &finish.outputs.stream {
        Some(path) => {
            let context = StreamContext { center: n.center.to_array(), scale: n.scale, background };
            let options = StreamOptions {
                path: path.clone(),
                quality: job.quality,
                target_bytes: finish.outputs.target_bytes,
                prune_faint: false,
            };
            let settings = QuantizerSettings::for_quality(job.quality);
            let (compressed, summary) =
                code_stream(&gaussians, (&context, &settings), &options, wrapper.as_ref(), None)?;
            (Some(compressed), Some(summary))
        }
        None => (None, None),
    };
    let ply_bytes = pwgs_core::ply::inria_ply_size(&gaussians);
    // What is evaluated is what a decoder shows: the decoded stream when there is one, else the
    // trained model with the wrapper's dequantized weights (which then holds the Gaussians).
    let trained;
    let (shown, model) = match &compressed {
        Some(c) => (&c.decoded.scene, &gaussians),
        None => {
            let wrapper = wrapper.as_ref().map(QuantizedSynthesis::dequantize);
            trained = Scene { base: Base::Plain(gaussians), wrapper, frame, background };
            (&trained, trained.plain_gaussians().expect("a plain scene holds Gaussians"))
        }
    };
    let coded = Coded {
        stream: compressed.as_ref().map(|c| &c.bytes[..]),
        shown,
        test: &data.test,
        export: Some(&|| Ok(Cow::Borrowed(model))),
    };
    finish.finish(coded, || {
        Ok(RunReport::Plain(Box::new(PlainReport {
            scene: SceneSummary::of(scene, data, "3dgs", device),
            load_seconds,
            training,
            ply_bytes,
            stream: summary,
        })))
    })
}

/// Trains to the end, with a progress bar on a terminal and a line every 100 iterations
/// without one (logs, CI).
fn train_with_progress(trainer: &mut Trainer, iterations: u32) -> Result<TrainSummary> {
    let bar = ProgressBar::new(u64::from(iterations));
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} [{elapsed_precise}<{eta_precise}] {msg}")
            .expect("valid template"),
    );
    let mut timer = (Instant::now(), 0u32);
    let result = train(trainer, |it, step| {
        bar.set_position(u64::from(it));
        if it % 10 == 0 || it == iterations {
            let rate = (it - timer.1) as f64 / timer.0.elapsed().as_secs_f64().max(1e-9);
            timer = (Instant::now(), it);
            let message =
                format!("loss {:.4}  PSNR {:.2}  Gaussians {}  {rate:.2} it/s", step.loss, step.psnr, step.gaussians);
            if bar.is_hidden() && (it % 100 == 0 || it == iterations) {
                eprintln!("iteration {it}/{iterations}  {message}");
            }
            bar.set_message(message);
        }
    });
    bar.finish();
    result
}

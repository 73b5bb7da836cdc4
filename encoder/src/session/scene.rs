//! `pwenc SCENE`: train on a scene's views, then write the stream, evaluate what a decoder
//! shows, and report.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use burn::tensor::Device;
use indicatif::{ProgressBar, ProgressStyle};
use pwgs_codec::scene::{Base, Scene};
use pwgs_codec::stream::wrap::QuantizedSynthesis;
use pwgs_core::camera::Camera;
use pwgs_core::say;
use pwgs_dataset::{LoadOptions, load_scene};
use pwgs_render::raster::{RenderOptions, render};
use serde::Serialize;

use super::{
    StreamOptions, StreamSummary, check_outputs, peak_resident_mib, print_wrapper, quantize_wrapper, read_ply,
    write_report, write_stream,
};
use crate::metrics::evaluate::{EvalOptions, Evaluation, MeanScore, ViewScore};
use crate::plain::compress::{QuantizerSettings, StreamContext};
use crate::plain::init::initial_gaussians;
use crate::plain::train::{TrainConfig, TrainSummary, Trainer, train};

/// Everything a training run does. `config.background` is also the scene's background.
#[derive(Debug, Clone)]
pub struct SceneJob {
    pub scene: PathBuf,
    pub load: LoadOptions,
    /// Start from this INRIA PLY instead of the scene's points.
    pub init_ply: Option<PathBuf>,
    pub config: TrainConfig,
    pub stream: Option<StreamOptions>,
    /// Write the trained Gaussians as an INRIA PLY.
    pub export_ply: Option<PathBuf>,
    /// Render the test views and score them.
    pub eval: Option<EvalOptions>,
    pub report: Option<PathBuf>,
}

#[derive(Serialize)]
pub struct Report {
    pub scene: String,
    pub format: &'static str,
    pub base: &'static str,
    pub resolution: [u32; 2],
    pub train_views: usize,
    pub test_views: usize,
    pub load_seconds: f64,
    pub training: TrainSummary,
    /// Size of the trained model as an uncompressed INRIA PLY.
    pub ply_bytes: usize,
    pub stream: Option<StreamSummary>,
    /// Scores of the decoded stream when one was written, else of the trained model.
    pub mean: Option<MeanScore>,
    pub views: Vec<ViewScore>,
    /// Peak resident memory of the whole run, in MiB, where the system says it.
    pub peak_resident_mib: Option<f64>,
}

pub fn encode_scene(job: SceneJob) -> Result<Report> {
    let files = job.stream.iter().map(|s| &s.path).chain(&job.report).chain(&job.export_ply);
    check_outputs(files, job.eval.iter().map(|e| &e.dir))?;
    let evaluation = job.eval.as_ref().map(Evaluation::prepare).transpose()?;
    let scene = &job.scene;
    let start = Instant::now();
    let data = load_scene(scene, &job.load).with_context(|| format!("cannot load the scene {}", scene.display()))?;
    let load_seconds = start.elapsed().as_secs_f64();
    let first = &data.train[0].image;
    say!(
        "{}: {} ({} train / {} test views, {}x{})",
        scene.display(),
        data.format,
        data.train.len(),
        data.test.len(),
        first.width,
        first.height
    );
    let cap = job.config.densify.max_gaussians;
    let initial = match &job.init_ply {
        Some(path) => read_ply(path)?,
        None => initial_gaussians(&data, job.config.seed, cap)?,
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
    let mut trainer = Trainer::new(config, &data, &initial, Device::flex())?;
    let result = train_with_progress(&mut trainer, iterations);
    // Whatever happened in training, the model holds its last good state: save it.
    let gaussians = trainer.gaussians();
    if let Some(path) = &job.export_ply {
        pwgs_core::ply::write_gaussians(path, &gaussians)?;
        say!("wrote {} Gaussians to {}", gaussians.len(), path.display());
    }
    let training = result?;
    say!("trained {} iterations in {:.1} s: {} Gaussians", training.iterations, training.seconds, training.gaussians);
    let n = data.normalization;
    let frame = n.frame();
    let options = RenderOptions { background, ..Default::default() };
    let base_render = |camera: &Camera| render(&gaussians, camera, &options).data;
    let wrapper = trainer.synthesis().map(|w| quantize_wrapper(&w, &base_render, &data, frame));
    if let Some(w) = &wrapper {
        print_wrapper(w);
    }
    let stream = match &job.stream {
        Some(stream) => {
            let context = StreamContext { center: n.center.to_array(), scale: n.scale, background };
            Some(write_stream(
                &gaussians,
                (&context, &QuantizerSettings::for_quality(stream.quality)),
                stream,
                wrapper.as_ref(),
                None,
            )?)
        }
        None => None,
    };
    let ply_bytes = pwgs_core::ply::inria_ply_size(&gaussians);
    // What is evaluated is what a decoder shows: the decoded stream when there is one, else the
    // trained model with the wrapper's dequantized weights.
    let trained;
    let shown = match &stream {
        Some((c, _)) => &c.decoded.scene,
        None => {
            let wrapper = wrapper.as_ref().map(QuantizedSynthesis::dequantize);
            trained = Scene { base: Base::Plain(gaussians), wrapper, frame, background };
            &trained
        }
    };
    let (views, mean) = match &evaluation {
        Some(e) => e.run(shown, &data.test).map(|(views, mean)| (views, Some(mean)))?,
        None => (Vec::new(), None),
    };
    let report = Report {
        scene: scene.display().to_string(),
        format: data.format,
        base: "3dgs",
        resolution: [first.width, first.height],
        train_views: data.train.len(),
        test_views: data.test.len(),
        load_seconds,
        training,
        ply_bytes,
        stream: stream.map(|(_, summary)| summary),
        mean,
        views,
        peak_resident_mib: peak_resident_mib(),
    };
    if let Some(path) = &job.report {
        write_report(path, &report)?;
    }
    Ok(report)
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

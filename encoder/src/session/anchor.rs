//! `pwenc SCENE --base anchor`: trains the anchor base for pixels and evaluates it as a
//! decoder derives it. The anchor base has no stream syntax yet (issue 15), so this job
//! writes a report and renders, not a stream.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use pwgs_dataset::{LoadOptions, load_scene};
use pwgs_decoder::scene::{Base, Scene};
use serde::Serialize;

use super::{check_outputs, write_report};
use crate::anchor::init::{AnchorShape, initial_model};
use crate::anchor::train::AnchorTrainer;
use crate::evaluate::{EvalOptions, Evaluation, MeanScore, ViewScore};

/// An anchor training run.
#[derive(Debug, Clone)]
pub struct AnchorJob {
    pub scene: PathBuf,
    pub load: LoadOptions,
    pub iterations: u32,
    pub feature_dim: usize,
    pub offsets_per_anchor: usize,
    /// Voxel edge for the anchors, as a fraction of the scene's normalization scale.
    pub relative_voxel: f32,
    pub background: [f32; 3],
    pub seed: u64,
    pub eval: Option<EvalOptions>,
    pub report: Option<PathBuf>,
}

#[derive(Serialize)]
pub struct AnchorReport {
    pub scene: String,
    pub base: &'static str,
    pub resolution: [u32; 2],
    pub train_views: usize,
    pub test_views: usize,
    pub anchors: usize,
    pub feature_dim: usize,
    pub offsets_per_anchor: usize,
    pub voxel: f32,
    pub iterations: u32,
    pub training_seconds: f64,
    /// Neural Gaussians rendered at the last step.
    pub last_step_gaussians: usize,
    pub mean: Option<MeanScore>,
    pub views: Vec<ViewScore>,
}

pub fn train_anchor_scene(job: &AnchorJob) -> Result<AnchorReport> {
    check_outputs(&job.report, job.eval.iter().map(|e| &e.dir))?;
    let evaluation = job.eval.as_ref().map(Evaluation::prepare).transpose()?;
    let data =
        load_scene(&job.scene, &job.load).with_context(|| format!("cannot load the scene {}", job.scene.display()))?;
    let points = data.points.as_ref().context("the anchor base starts from the scene's SfM points; it has none")?;
    let voxel = job.relative_voxel * data.normalization.scale;
    let shape = AnchorShape { feature_dim: job.feature_dim, offsets_per_anchor: job.offsets_per_anchor, voxel };
    let initial = initial_model(points, shape, job.seed)?;
    println!(
        "{} anchors from {} points (voxel {voxel:.5}), {} neural Gaussians each, features of {}",
        initial.len(),
        points.positions.len(),
        job.offsets_per_anchor,
        job.feature_dim
    );
    let mut trainer = AnchorTrainer::new(&initial, &data, job.iterations, job.background, job.seed)?;
    let start = Instant::now();
    let mut last_step_gaussians = 0;
    while trainer.iteration < trainer.iterations {
        let step = trainer.step()?;
        last_step_gaussians = step.gaussians;
        let it = trainer.iteration;
        if it % 100 == 0 || it == trainer.iterations {
            let rate = f64::from(it) / start.elapsed().as_secs_f64().max(1e-9);
            eprintln!(
                "iteration {it}/{}  loss {:.4}  PSNR {:.2}  Gaussians {}  {rate:.2} it/s",
                trainer.iterations, step.loss, step.psnr, step.gaussians
            );
        }
    }
    let training_seconds = start.elapsed().as_secs_f64();
    let model = trainer.model();
    println!("trained {} iterations in {training_seconds:.1} s", trainer.iteration);
    let scene = Scene {
        base: Base::Anchors(Box::new(model)),
        wrapper: None,
        frame: data.normalization.frame(),
        background: job.background,
    };
    let (views, mean) = match &evaluation {
        Some(e) => e.run(&scene, &data).map(|(views, mean)| (views, Some(mean)))?,
        None => (Vec::new(), None),
    };
    let first = &data.train[0].image;
    let report = AnchorReport {
        scene: job.scene.display().to_string(),
        base: "anchor",
        resolution: [first.width, first.height],
        train_views: data.train.len(),
        test_views: data.test.len(),
        anchors: initial.len(),
        feature_dim: job.feature_dim,
        offsets_per_anchor: job.offsets_per_anchor,
        voxel,
        iterations: trainer.iteration,
        training_seconds,
        last_step_gaussians,
        mean,
        views,
    };
    if let Some(path) = &job.report {
        write_report(path, &report)?;
    }
    Ok(report)
}

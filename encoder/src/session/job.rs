//! The encode pipeline's job and report: a job names its input (a scene to train a base on, or
//! a model trained elsewhere) and its outputs; [`encode`] checks every output before any work,
//! runs the input's stages, and hands what they coded to [`Finish`], which writes the stream
//! and the export, evaluates what a decoder shows, and writes the report.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use pwgs_codec::scene::Scene;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::say;
use pwgs_dataset::{Dataset, LoadOptions, View, load_scene};
use serde::Serialize;

use super::anchor::{AnchorReport, AnchorTraining};
use super::import::{ImportReport, ModelImport};
use super::plain::{PlainReport, PlainTraining};
use super::{check_outputs, peak_resident_mib, write_report};
use crate::metrics::evaluate::{EvalOptions, Evaluation, MeanScore, ViewScore};
use crate::train::device::{DeviceChoice, TrainingDevice};

/// Everything an encoder run does.
#[derive(Debug, Clone)]
pub struct EncodeJob {
    pub input: Input,
    pub outputs: Outputs,
}

/// What a run reads.
#[derive(Debug, Clone)]
pub enum Input {
    /// A scene's views (COLMAP, transforms.json or LLFF) to train a base on.
    Scene { path: PathBuf, load: LoadOptions, base: BaseTraining, device: DeviceChoice },
    /// A model trained elsewhere, compressed as it is.
    Model(Box<ModelImport>),
}

/// Which base a scene trains, with its settings.
#[derive(Debug, Clone)]
pub enum BaseTraining {
    /// Plain 3D Gaussians with densification.
    Plain(Box<PlainTraining>),
    /// Anchors whose MLPs give each view's Gaussians (SPEC.md section 12).
    Anchor(Box<AnchorTraining>),
}

/// What a run writes. Every file is checked writable, and every folder created, before any
/// work; every file is written atomically.
#[derive(Debug, Clone, Default)]
pub struct Outputs {
    /// The stream (an import needs one).
    pub stream: Option<PathBuf>,
    /// Largest stream size in bytes: the least important Gaussians or anchors are dropped to
    /// fit.
    pub target_bytes: Option<u64>,
    /// The model as an INRIA PLY: the trained Gaussians (plain base), or the decoded anchors as
    /// SH-degree-3 Gaussians fitted over the training cameras (anchor base).
    pub export_ply: Option<PathBuf>,
    /// Render the test views as a decoder shows them and score them.
    pub eval: Option<EvalOptions>,
    /// The report, as JSON.
    pub report: Option<PathBuf>,
}

/// What a run did: what its input's stages report, then the scores of what a decoder shows.
#[derive(Serialize)]
pub struct EncodeReport {
    #[serde(flatten)]
    pub run: RunReport,
    /// Mean scores of the test views (with [`Outputs::eval`]): of the decoded stream when one
    /// was coded, else of the trained model.
    pub mean: Option<MeanScore>,
    pub views: Vec<ViewScore>,
    /// Peak resident memory of the whole run, in MiB, where the system says it.
    pub peak_resident_mib: Option<f64>,
}

/// The input's part of a report; its fields sit at the top level of the JSON.
#[derive(Serialize)]
#[serde(untagged)]
pub enum RunReport {
    Plain(Box<PlainReport>),
    Anchor(Box<AnchorReport>),
    Model(Box<ImportReport>),
}

/// Runs `job`.
pub fn encode(job: &EncodeJob) -> Result<EncodeReport> {
    let o = &job.outputs;
    let orbit_renders = match &job.input {
        Input::Model(m) => {
            anyhow::ensure!(o.export_ply.is_none(), "an import has no trained model to export as PLY");
            anyhow::ensure!(o.eval.is_none(), "an import has no test views to evaluate (its orbit scores it)");
            m.orbit_renders.as_ref()
        }
        Input::Scene { base: BaseTraining::Anchor(anchor), .. } => {
            anchor.check()?;
            None
        }
        Input::Scene { base: BaseTraining::Plain(_), .. } => None,
    };
    check_outputs(
        o.stream.iter().chain(&o.report).chain(&o.export_ply),
        o.eval.iter().map(|e| &e.dir).chain(orbit_renders),
    )?;
    let finish = Finish { outputs: o, evaluation: o.eval.as_ref().map(Evaluation::prepare).transpose()? };
    match &job.input {
        Input::Scene { path, load, base, device } => {
            let device = device.resolve(|e| say!("no GPU to train on: {e:#}"))?;
            say!("training on {}", device.name);
            let start = Instant::now();
            let data = load_scene(path, load).with_context(|| format!("cannot load the scene {}", path.display()))?;
            let load_seconds = start.elapsed().as_secs_f64();
            let first = &data.train[0].image;
            say!(
                "{}: {} ({} train / {} test views, {}x{})",
                path.display(),
                data.format,
                data.train.len(),
                data.test.len(),
                first.width,
                first.height
            );
            match base {
                BaseTraining::Plain(plain) => super::plain::run(plain, (path, &data, load_seconds), &device, finish),
                BaseTraining::Anchor(anchor) => super::anchor::run(anchor, (path, &data), &device, finish),
            }
        }
        Input::Model(model) => super::import::run(model, finish),
    }
}

/// The scene a base trained on, at the top of the base's report.
#[derive(Serialize)]
pub struct SceneSummary {
    pub scene: String,
    /// The loader that read it.
    pub format: &'static str,
    pub base: &'static str,
    /// What trained it: the GPU adapter, or the CPU backend.
    pub device: String,
    pub resolution: [u32; 2],
    pub train_views: usize,
    pub test_views: usize,
}

impl SceneSummary {
    pub(super) fn of(path: &Path, data: &Dataset, base: &'static str, device: &TrainingDevice) -> Self {
        let first = &data.train[0].image;
        Self {
            scene: path.display().to_string(),
            format: data.format,
            base,
            device: device.name.clone(),
            resolution: [first.width, first.height],
            train_views: data.train.len(),
            test_views: data.test.len(),
        }
    }
}

/// What a pipeline coded, for [`Finish::finish`].
pub(super) struct Coded<'a> {
    /// The stream, when one was coded.
    pub stream: Option<&'a [u8]>,
    /// What a decoder shows: the decoded stream, or the trained model when no stream was coded.
    pub shown: &'a Scene,
    /// The test views to score `shown` on.
    pub test: &'a [View],
    /// Makes the Gaussians [`Outputs::export_ply`] gets (called only when it is set); an
    /// import has none.
    pub export: Option<&'a dyn Fn() -> Result<Cow<'a, Gaussians>>>,
}

/// The stages every pipeline ends with.
pub(super) struct Finish<'a> {
    pub outputs: &'a Outputs,
    evaluation: Option<Evaluation<'a>>,
}

impl Finish<'_> {
    /// Writes the stream and the export, then `describe`s the run (an import scores its orbit
    /// there), evaluates the test views and writes the report.
    pub fn finish(self, coded: Coded, describe: impl FnOnce() -> Result<RunReport>) -> Result<EncodeReport> {
        if let (Some(path), Some(bytes)) = (&self.outputs.stream, coded.stream) {
            write_file(path, bytes)?;
            say!("wrote {} ({} bytes)", path.display(), bytes.len());
        }
        if let (Some(path), Some(export)) = (&self.outputs.export_ply, coded.export) {
            export_ply(path, &*export()?)?;
        }
        let run = describe()?;
        let (views, mean) = match &self.evaluation {
            Some(e) => e.run(coded.shown, coded.test).map(|(views, mean)| (views, Some(mean)))?,
            None => (Vec::new(), None),
        };
        let report = EncodeReport { run, mean, views, peak_resident_mib: peak_resident_mib() };
        if let Some(path) = &self.outputs.report {
            write_report(path, &report)?;
        }
        Ok(report)
    }
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    pwgs_core::atomic_file::write_atomically(path, bytes).with_context(|| format!("cannot write {}", path.display()))
}

/// Writes `gaussians` as an INRIA PLY.
pub(super) fn export_ply(path: &Path, gaussians: &Gaussians) -> Result<()> {
    pwgs_core::ply::write_gaussians(path, gaussians)?;
    say!("wrote {} Gaussians to {}", gaussians.len(), path.display());
    Ok(())
}

//! `pwenc compare`: how closely a model in another form (a splat file in any format `--from`
//! reads, or a pwgs stream) renders like a reference model, on an orbit of views around the
//! reference or on the views of the capture it was trained on. This is how streams are
//! compared with other formats (SPZ, SOG, compressed PLY) at equal cameras; the report has the layout `pwbench` reads (the file's size as the
//! stream's, mean and per-view scores), so formats and qualities plot as RD curves.

use std::path::PathBuf;

use anyhow::{Context, Result};
use glam::Vec3;
use pwgs_codec::scene::{Base, Scene};
use pwgs_codec::stream;
use pwgs_core::say;
use pwgs_core::splat_file::SpzAxes;
use pwgs_dataset::{NamedCamera, SceneViews, View};
use pwgs_render::raster::RenderOptions;
use serde::Serialize;

use super::{Orbit, check_outputs, read_model, write_report};
use crate::metrics::evaluate::{EvalOptions, Evaluation, MeanScore, ViewScore};
use crate::plain::compress::StreamContext;
use crate::plain::fidelity::{orbit_cameras, renders};

/// Everything a comparison does.
#[derive(Debug, Clone)]
pub struct CompareJob {
    /// The model whose renders are the ground truth; the orbit circles it.
    pub reference: PathBuf,
    /// The model scored: a `.pwb` stream (shown as a decoder shows it) or a splat file.
    pub candidate: PathBuf,
    /// The file whose size the report gives (a format's own file, when the candidate is its
    /// conversion back to PLY); by default the candidate's.
    pub size_of: Option<PathBuf>,
    /// The axes of `.spz` files that name none.
    pub spz_axes: SpzAxes,
    pub orbit: Orbit,
    /// A capture's own views to score on instead of the orbit (the reference trained on it).
    pub views: Option<SceneViews>,
    pub background: [f32; 3],
    /// Metrics besides PSNR and SSIM, and where the renders and their ground truth go
    /// (`<dir>/orbit_NNN.png`, `<dir>/gt/orbit_NNN.png`; named after the images with `views`).
    pub eval: EvalOptions,
    pub report: Option<PathBuf>,
    pub times: CodingTimes,
}

/// How long writing and reading the candidate took, as whoever made it measured them: the
/// report carries them beside the scores, so that `pwbench` shows each format's speed.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct CodingTimes {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub encode_seconds: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decode_seconds: Option<f64>,
}

/// A file and its size.
#[derive(Serialize)]
pub struct SizedFile {
    pub path: String,
    pub bytes: u64,
}

#[derive(Serialize)]
pub struct CompareReport {
    pub reference: String,
    pub candidate: String,
    /// The compared file's size (named `stream` as in `pwenc --report`, which `pwbench` reads).
    pub stream: SizedFile,
    /// The views scored: the orbit's, or those of `views_from`.
    pub orbit_views: usize,
    /// The orbit views' width and height (none with `views_from`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orbit_size: Option<u32>,
    /// The scene folder and split whose cameras were scored, instead of an orbit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub views_from: Option<String>,
    #[serde(flatten)]
    pub times: CodingTimes,
    pub mean: MeanScore,
    pub views: Vec<ViewScore>,
}

pub fn compare_models(job: &CompareJob) -> Result<CompareReport> {
    check_outputs(&job.report, [&job.eval.dir])?;
    let evaluation = Evaluation::prepare(&job.eval)?;
    let gaussians = read_model(&job.reference, job.spz_axes)?;
    let context = StreamContext::from_gaussians(&gaussians, job.background);
    let frame = pwgs_core::frame::SceneFrame { center: Vec3::from(context.center), scale: context.scale };
    let reference = Scene { base: Base::Plain(gaussians), wrapper: None, frame, background: job.background };
    let candidate = read_candidate(job, &reference)?;
    let sized = job.size_of.as_ref().unwrap_or(&job.candidate);
    let bytes = std::fs::metadata(sized).with_context(|| format!("cannot read {}", sized.display()))?.len();

    let cameras = match &job.views {
        Some(views) => {
            views.cameras().with_context(|| format!("cannot load the views of {}", views.scene.display()))?
        }
        None => (orbit_cameras(&context, &job.orbit)?.into_iter().enumerate())
            .map(|(i, camera)| NamedCamera { name: format!("orbit_{i:03}"), camera })
            .collect(),
    };
    let options = RenderOptions { background: job.background, ..Default::default() };
    let truths = renders(&reference, &cameras.iter().map(|c| c.camera).collect::<Vec<_>>(), &options);
    let views: Vec<View> = (cameras.into_iter().zip(truths))
        .map(|(view, image)| View { name: view.stem(), camera: view.camera, image })
        .collect();
    let (views, mean) = evaluation.run(&candidate, &views)?;
    say!("{}: {bytes} bytes ({})", job.candidate.display(), sized.display());
    let report = CompareReport {
        reference: job.reference.display().to_string(),
        candidate: job.candidate.display().to_string(),
        stream: SizedFile { path: sized.display().to_string(), bytes },
        orbit_views: views.len(),
        orbit_size: job.views.is_none().then_some(job.orbit.size),
        views_from: job.views.as_ref().map(|v| format!("{} ({} views)", v.scene.display(), v.split.name())),
        times: job.times,
        mean,
        views,
    };
    if let Some(path) = &job.report {
        write_report(path, &report)?;
    }
    Ok(report)
}

/// The candidate as a scene: a stream decoded, or a splat file read and rendered like the
/// reference (its background and frame).
fn read_candidate(job: &CompareJob, reference: &Scene) -> Result<Scene> {
    let path = &job.candidate;
    let is_stream = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("pwb"));
    if is_stream {
        let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        let decoded =
            stream::decode(&bytes).with_context(|| format!("{} is not a valid pwgs stream", path.display()))?;
        return Ok(decoded.scene);
    }
    let gaussians = read_model(path, job.spz_axes)?;
    Ok(Scene { base: Base::Plain(gaussians), wrapper: None, frame: reference.frame, background: reference.background })
}

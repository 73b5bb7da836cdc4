//! Whole encoder runs as a library (docs/architecture.md section 2.1): what `pwenc` does once its
//! arguments are parsed, so that the player and scripts can run the same pipeline. One job type
//! ([`EncodeJob`]) names the input and the outputs; [`encode`] runs the input's stages (plain
//! training, anchor training, or an import) and ends every one the same way (write, export,
//! evaluate, report), with one report type ([`EncodeReport`]).

mod anchor;
mod compare;
mod effort;
mod import;
mod job;
mod plain;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use pwgs_bitstream::Container;
use pwgs_codec::stream::wrap::QuantizedSynthesis;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::say;
use pwgs_core::splat_file::SpzAxes;
use serde::Serialize;

use crate::plain::compress::{Coding, Compressed, QuantizerSettings, StreamContext, compress_to_size};
use crate::plain::importance::Importance;
use crate::wrapper::synthesis::{QuantizationSample, choose_quantization};
use pwgs_codec::wrapper::conditioning;
use pwgs_codec::wrapper::synthesis::SynthesisWeights;
use pwgs_core::camera::Camera;
use pwgs_core::frame::SceneFrame;
use pwgs_dataset::Dataset;

pub use crate::plain::fidelity::Orbit;
pub use anchor::{AnchorReport, AnchorStreamSummary, AnchorTraining};
pub use compare::{CodingTimes, CompareJob, CompareReport, compare_models};
pub use effort::{DEFAULT_EFFORT, MAX_EFFORT, Tools};
pub use import::{ImportReport, ModelImport};
pub use job::{BaseTraining, EncodeJob, EncodeReport, Input, Outputs, RunReport, SceneSummary, encode};
pub use plain::{PlainReport, PlainTraining};

/// How a plain stream is coded.
#[derive(Debug, Clone)]
struct StreamOptions {
    pub path: PathBuf,
    /// 0 (smallest) to [`MAX_QUALITY`](crate::plain::compress::MAX_QUALITY).
    pub quality: u8,
    /// Largest stream size in bytes; the least important Gaussians are dropped to fit.
    pub target_bytes: Option<u64>,
    /// With importance: drop the Gaussians too faint to pay for their bytes.
    pub prune_faint: bool,
}

/// What a written stream holds.
#[derive(Serialize)]
pub struct StreamSummary {
    pub path: String,
    pub bytes: usize,
    pub quality: u8,
    pub gaussians: u32,
    pub dropped_invisible: usize,
    /// Visible Gaussians dropped as too faint in the importance views to pay for their bytes
    /// (`--prune-faint`).
    pub dropped_faint: usize,
    /// Visible Gaussians dropped to meet the target size.
    pub pruned_to_fit: usize,
    /// Gaussians dropped, the least important first, where more than 255 shared one cell of the
    /// finest position grid (many at one position): a stream cell holds at most 255.
    pub dropped_crowded: usize,
    pub target_bytes: Option<u64>,
    pub sh_degree_in: u32,
    pub sh_degree: u32,
    /// Bytes of each section, container overhead (tag, length, CRC) included.
    pub sections: Vec<(String, usize)>,
    pub wrapper: Option<WrapperSummary>,
    pub attribute_sha256: String,
    pub seconds: f64,
}

/// The wrapper a stream carries.
#[derive(Serialize)]
pub struct WrapperSummary {
    pub width: usize,
    pub noise: bool,
    pub plucker: bool,
    pub seed: u64,
    pub parameters: usize,
    pub weight_step_log2: i8,
    pub bias_step_log2: i8,
}

impl WrapperSummary {
    fn of(w: &QuantizedSynthesis) -> Self {
        Self {
            width: w.config.width,
            noise: w.config.noise,
            plucker: w.config.plucker,
            seed: w.config.seed,
            parameters: w.values.len(),
            weight_step_log2: w.weight_exponent,
            bias_step_log2: w.bias_exponent,
        }
    }
}

/// Compresses `g` with `settings` into the stream `options` names (written by
/// [`job::Finish`]) and decodes it back through the decoder library.
fn code_stream(
    g: &Gaussians,
    (context, settings): (&StreamContext, &QuantizerSettings),
    options: &StreamOptions,
    wrapper: Option<&QuantizedSynthesis>,
    importance: Option<&Importance>,
) -> Result<(Compressed, StreamSummary)> {
    let start = Instant::now();
    let limit = size_limit(options.target_bytes);
    let coding = Coding {
        settings,
        weights: importance.map(|i| &i.weights[..]),
        prune_costs: importance.filter(|_| options.prune_faint).map(|i| &i.prune_costs[..]),
    };
    let compressed = compress_to_size(g, coding, context, wrapper, limit)?;
    let path = &options.path;
    let sections = section_sizes(&compressed.bytes);
    let header = &compressed.decoded.header;
    let summary = StreamSummary {
        path: path.display().to_string(),
        bytes: compressed.bytes.len(),
        quality: options.quality,
        gaussians: header.gaussian_count,
        dropped_invisible: compressed.invisible,
        dropped_faint: compressed.faint,
        pruned_to_fit: compressed.pruned,
        dropped_crowded: compressed.crowded,
        target_bytes: options.target_bytes,
        sh_degree_in: g.sh_degree,
        sh_degree: header.sh_degree,
        sections,
        wrapper: wrapper.map(WrapperSummary::of),
        attribute_sha256: compressed.decoded.scene.attribute_hash(),
        seconds: start.elapsed().as_secs_f64(),
    };
    say!(
        "coded {} bytes: {} Gaussians, SH degree {}, {} invisible dropped, in {:.2} s",
        summary.bytes,
        summary.gaussians,
        summary.sh_degree,
        summary.dropped_invisible,
        summary.seconds
    );
    if summary.dropped_crowded > 0 {
        eprintln!(
            "warning: {} Gaussians dropped where more than 255 shared one cell of the finest position grid \
             (each such cell keeps its 255 most important; a stream cell holds no more)",
            summary.dropped_crowded
        );
    }
    if options.prune_faint {
        say!("{} Gaussians too faint in the importance views dropped (--prune-faint)", summary.dropped_faint);
    }
    if let Some(target) = options.target_bytes {
        say!("target {target} bytes: {} least important Gaussians dropped to fit", summary.pruned_to_fit);
    }
    Ok((compressed, summary))
}

/// A stream's size limit in bytes for `--target-bytes` (none: every Gaussian or anchor fits).
fn size_limit(target_bytes: Option<u64>) -> usize {
    target_bytes.map_or(usize::MAX, |t| usize::try_from(t).unwrap_or(usize::MAX))
}

/// Each section's tag and its bytes in the stream, header and CRC included.
fn section_sizes(stream: &[u8]) -> Vec<(String, usize)> {
    pwgs_codec::stream::section_sizes(&Container::parse(stream).expect("the encoder's own stream parses"))
}

/// Quantizes f with steps chosen on renders of the first training views (`base_render` gives
/// a view's base render, [H, W, 3]): the coarsest whose residual stays within a quarter of a
/// gray level of the float network's.
fn quantize_wrapper(
    weights: &SynthesisWeights,
    base_render: &dyn Fn(&Camera) -> Vec<f32>,
    data: &Dataset,
    frame: SceneFrame,
) -> QuantizedSynthesis {
    let samples: Vec<QuantizationSample> = data
        .train
        .iter()
        .take(2)
        .map(|view| QuantizationSample {
            base: base_render(&view.camera),
            conditioning: conditioning(&weights.config, &view.camera, frame),
            width: view.camera.width as usize,
            height: view.camera.height as usize,
        })
        .collect();
    choose_quantization(weights, &samples, 0.25 / 255.0)
}

/// Prints f's quantization.
fn print_wrapper(w: &QuantizedSynthesis) {
    say!(
        "wrapper: {} parameters, steps 2^{} (weights) and 2^{} (biases)",
        w.values.len(),
        w.weight_exponent,
        w.bias_exponent
    );
}

/// The process's peak resident memory so far, in MiB (Linux's VmHWM; `None` elsewhere), which
/// reports state beside the run's time.
fn peak_resident_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.trim_start_matches("VmHWM:").trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kib / 1024.0)
}

fn write_report(path: &Path, report: &impl Serialize) -> Result<()> {
    pwgs_core::atomic_file::write_atomically(path, &serde_json::to_vec_pretty(report)?)
        .with_context(|| format!("cannot write {}", path.display()))
}

/// A model trained elsewhere: an INRIA PLY (see [`read_ply`]), or antimatter15's `.splat`,
/// Niantic's `.spz` (unmarked ones taken to store `spz_axes`) or PlayCanvas's SOG (see
/// [`pwgs_core::splat_file`]), chosen by the file's extension.
fn read_model(path: &Path, spz_axes: SpzAxes) -> Result<Gaussians> {
    let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("splat" | "spz" | "sog" | "json") => Ok(pwgs_core::splat_file::read_splat_file(path, spz_axes)?),
        _ => read_ply(path),
    }
}

/// An INRIA PLY, saying how many Gaussians with non-finite values were dropped.
fn read_ply(path: &Path) -> Result<Gaussians> {
    let loaded = pwgs_core::ply::read_gaussians(path)?;
    if loaded.dropped_non_finite + loaded.clamped_opacities > 0 {
        eprintln!(
            "{}: dropped {} Gaussians with non-finite values, clamped {} infinite opacities",
            path.display(),
            loaded.dropped_non_finite,
            loaded.clamped_opacities
        );
    }
    Ok(loaded.gaussians)
}

/// Fails now, rather than after the work, if a file cannot be written; creates the folders.
fn check_outputs<'a>(
    files: impl IntoIterator<Item = &'a PathBuf>,
    folders: impl IntoIterator<Item = &'a PathBuf>,
) -> Result<()> {
    for path in files {
        pwgs_core::atomic_file::check_writable(path).with_context(|| format!("cannot write {}", path.display()))?;
    }
    for dir in folders {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    Ok(())
}

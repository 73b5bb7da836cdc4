//! Runs as `pwenc --report` writes them, grouped into curves.

use std::path::Path;

use anyhow::{Context, Result, bail};
use serde_json::Value;

/// The metrics a report may hold, in the order tables list them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Metric {
    Psnr,
    Ssim,
    Lpips,
    Dists,
    Wd,
}

impl Metric {
    pub const ALL: [Metric; 5] = [Metric::Psnr, Metric::Ssim, Metric::Lpips, Metric::Dists, Metric::Wd];

    /// The key in a report's `mean`.
    pub fn key(self) -> &'static str {
        match self {
            Metric::Psnr => "psnr",
            Metric::Ssim => "ssim",
            Metric::Lpips => "lpips",
            Metric::Dists => "dists",
            Metric::Wd => "wd",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Metric::Psnr => "PSNR (dB)",
            Metric::Ssim => "SSIM",
            Metric::Lpips => "LPIPS",
            Metric::Dists => "DISTS",
            Metric::Wd => "WD",
        }
    }

    pub fn higher_is_better(self) -> bool {
        matches!(self, Metric::Psnr | Metric::Ssim)
    }
}

/// Scores per [`Metric::ALL`], each when the report has it.
pub type Scores = [Option<f64>; 5];

fn scores_of(v: &Value) -> Scores {
    Metric::ALL.map(|m| v[m.key()].as_f64())
}

fn index(metric: Metric) -> usize {
    Metric::ALL.iter().position(|&m| m == metric).expect("every metric is listed")
}

/// One decoded test view of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewRun {
    pub name: String,
    pub scores: Scores,
    pub render_seconds: Option<f64>,
}

impl ViewRun {
    pub fn score(&self, metric: Metric) -> Option<f64> {
        self.scores[index(metric)]
    }
}

/// One encoded stream and the mean scores of its decoded test views.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    pub file: String,
    pub bytes: f64,
    /// The encoder's time: a scene's training, or what the caller measured for a file written
    /// by other software (`pwenc compare --encode-seconds`).
    pub encode_seconds: Option<f64>,
    /// The time to decode the file, where the caller measured it (`pwenc compare
    /// --decode-seconds`).
    pub decode_seconds: Option<f64>,
    /// Mean time to render one test view from the decoded stream.
    pub render_seconds: Option<f64>,
    /// The whole encoding run's peak resident memory, where the report states it.
    pub peak_resident_mib: Option<f64>,
    pub scores: Scores,
    pub views: Vec<ViewRun>,
}

impl Run {
    pub fn score(&self, metric: Metric) -> Option<f64> {
        self.scores[index(metric)]
    }

    /// Reads a report of `pwenc --report` (plain or anchor base) that has a stream.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        let r: Value = serde_json::from_str(&text).with_context(|| format!("{} is not JSON", path.display()))?;
        let Some(bytes) = r["stream"]["bytes"].as_f64() else {
            bail!("{} has no stream size (was it written with -o?)", path.display());
        };
        // A plain-base report nests its training time, an anchor-base report has it on top, and
        // `pwenc compare` names the time its caller measured.
        let encode_seconds = r["training"]["seconds"]
            .as_f64()
            .or_else(|| r["training_seconds"].as_f64())
            .or_else(|| r["encode_seconds"].as_f64());
        let scores = scores_of(&r["mean"]);
        if scores.iter().all(Option::is_none) {
            bail!("{} has no mean scores (was it written with --eval?)", path.display());
        }
        let views: Vec<ViewRun> = r["views"]
            .as_array()
            .map(|views| {
                views
                    .iter()
                    .map(|v| ViewRun {
                        name: v["name"].as_str().unwrap_or("?").to_string(),
                        scores: scores_of(v),
                        render_seconds: v["render_seconds"].as_f64(),
                    })
                    .collect()
            })
            .unwrap_or_default();
        let times: Vec<f64> = views.iter().filter_map(|v| v.render_seconds).collect();
        let render_seconds = (!times.is_empty()).then(|| times.iter().sum::<f64>() / times.len() as f64);
        Ok(Self {
            file: path.display().to_string(),
            bytes,
            encode_seconds,
            decode_seconds: r["decode_seconds"].as_f64(),
            render_seconds,
            peak_resident_mib: r["peak_resident_mib"].as_f64(),
            scores,
            views,
        })
    }

    /// The run's position on `axis`, when the report has it.
    pub fn position(&self, axis: Axis) -> Option<f64> {
        match axis {
            Axis::Kilobytes => Some(self.bytes / 1000.0),
            Axis::RenderSeconds => self.render_seconds,
            Axis::EncodeSeconds => self.encode_seconds,
        }
    }
}

/// A named set of runs of one method at several rates, sorted by size.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    pub name: String,
    pub runs: Vec<Run>,
}

impl Curve {
    /// Parses `NAME=a.json,b.json,...` and reads the reports.
    pub fn parse(arg: &str) -> Result<Self> {
        let Some((name, files)) = arg.split_once('=') else {
            bail!("`{arg}`: expected NAME=report.json[,report.json...]");
        };
        if name.is_empty() {
            bail!("`{arg}`: the curve needs a name");
        }
        let runs = files.split(',').map(|f| Run::read(Path::new(f))).collect::<Result<Vec<_>>>()?;
        Ok(Self::new(name.to_string(), runs))
    }

    /// The curve of `runs`, sorted by size.
    pub fn new(name: String, mut runs: Vec<Run>) -> Self {
        runs.sort_by(|a, b| a.bytes.total_cmp(&b.bytes));
        Self { name, runs }
    }

    /// (bytes, score) of every run that has `metric`.
    pub fn points(&self, metric: Metric) -> Vec<(f64, f64)> {
        self.runs.iter().filter_map(|r| r.score(metric).map(|s| (r.bytes, s))).collect()
    }

    /// (position on `axis`, score) of every run that has both, in the curve's (size) order.
    pub fn points_on(&self, axis: Axis, metric: Metric) -> Vec<(f64, f64)> {
        self.runs.iter().filter_map(|r| Some((r.position(axis)?, r.score(metric)?))).collect()
    }
}

/// What a chart's horizontal axis shows: the stream's size, or a cost in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    Kilobytes,
    /// Mean render time of a decoded test view (speed against error at each quality).
    RenderSeconds,
    /// The encoder's time (speed against error over iteration budgets or effort levels).
    EncodeSeconds,
}

impl Axis {
    pub fn label(self) -> &'static str {
        match self {
            Axis::Kilobytes => "stream size (KB)",
            Axis::RenderSeconds => "render time per test view (s)",
            Axis::EncodeSeconds => "encode time (s)",
        }
    }
}

//! `pwenc compare`'s options.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use pwgs_cli::values::parse_vector;
use pwgs_dataset::{SceneViews, ViewSplit};
use pwgs_encoder::metrics::evaluate::EvalOptions;
use pwgs_encoder::metrics::lpips::LpipsInput;
use pwgs_encoder::metrics::suite::{DEFAULT_WD_LOG2_SIGMA, Metric, SuiteSettings};
use pwgs_encoder::metrics::weights::default_dirs;
use pwgs_encoder::session::{CodingTimes, CompareJob, Orbit};

use crate::values::{
    SpzAxesArg, check_extra_metrics, parse_color, parse_degrees_within, parse_positive, parse_seconds,
};

#[derive(Args)]
pub(crate) struct CompareArgs {
    /// The model whose renders are the ground truth (a splat file as for --from).
    reference: PathBuf,
    /// The model to score: a pwgs stream (.pwb) or a splat file as for --from.
    candidate: PathBuf,
    /// Folder for the candidate's renders (orbit_NNN.png) and the reference's (gt/).
    #[arg(short, long)]
    output: PathBuf,
    /// Report this file's size instead of the candidate's (the format's own file, when the
    /// candidate is its conversion back to PLY).
    #[arg(long)]
    size_of: Option<PathBuf>,
    /// The axes of `.spz` files (reference or candidate) that name no coordinate system: `rub`
    /// as the format specifies (Niantic's files), `rdf` for a PLY's own axes, which
    /// PlayCanvas's splat-transform (3.7.0) writes unconverted and unmarked (its files load
    /// upside down otherwise).
    #[arg(long, value_enum, default_value = "rub")]
    spz_axes: SpzAxesArg,
    /// Views on the orbit around the reference.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=1024))]
    orbit: u32,
    /// Up direction of the orbit (`x,y,z`; captures in COLMAP conventions usually have -y up).
    #[arg(long, default_value = "0,-1,0", value_parser = parse_vector)]
    up: [f32; 3],
    /// Width and height of the orbit views.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(8..=8192))]
    orbit_size: u32,
    /// The orbit's distance from the reference's center, in units of its radius (the
    /// normalization's: 1.1 times the 95th percentile of the distances to the median).
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    orbit_distance: f32,
    /// The orbit's height as an angle from the horizon, in degrees (negative: from below).
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true, value_parser = |s: &str| parse_degrees_within(s, -89.0, 89.0))]
    orbit_elevation: f32,
    /// The orbit views' field of view in degrees.
    #[arg(long, default_value_t = 60.0, value_parser = |s: &str| parse_degrees_within(s, 1.0, 170.0))]
    orbit_fov: f32,
    /// Score on the cameras of this scene folder (COLMAP, transforms.json or LLFF) instead of the
    /// orbit: a model trained on that capture, seen from its own views.
    #[arg(long)]
    views: Option<PathBuf>,
    /// Which views of --views: test, train or all.
    #[arg(long, default_value = "test", requires = "views")]
    split: ViewSplit,
    /// Image downscale of --views (the views' size: e.g. 8 for fern at 504x378).
    #[arg(long, default_value_t = 1, requires = "views", value_parser = clap::value_parser!(u32).range(1..=64))]
    downscale: u32,
    /// Background: `white`, `black` or `r,g,b`.
    #[arg(long, default_value = "black", value_parser = parse_color)]
    background: [f32; 3],
    /// Metrics besides PSNR and SSIM (lpips, dists, wd).
    #[arg(long, value_enum, value_delimiter = ',')]
    metrics: Vec<Metric>,
    /// log2 of WD's pooling width σ for --metrics wd (0..=5).
    #[arg(long, default_value_t = DEFAULT_WD_LOG2_SIGMA)]
    wd_log2_sigma: f64,
    /// A folder searched first for the metrics' weights (then $PWGS_WEIGHTS_DIR and the cache).
    #[arg(long)]
    weights: Option<PathBuf>,
    /// Write the sizes and scores as JSON (the layout `pwbench` reads).
    #[arg(long)]
    report: Option<PathBuf>,
    /// The time that writing the candidate took, in seconds, as the caller measured it (our
    /// encoder's, or another format's writer's): recorded in the report.
    #[arg(long, value_parser = parse_seconds)]
    encode_seconds: Option<f64>,
    /// The time that reading the candidate back took, in seconds, as the caller measured it:
    /// recorded in the report.
    #[arg(long, value_parser = parse_seconds)]
    decode_seconds: Option<f64>,
}

impl CompareArgs {
    pub(crate) fn job(self) -> Result<CompareJob> {
        check_extra_metrics("--metrics", &self.metrics)?;
        Ok(CompareJob {
            reference: self.reference,
            candidate: self.candidate,
            size_of: self.size_of,
            spz_axes: self.spz_axes.into(),
            orbit: Orbit {
                distance: self.orbit_distance,
                elevation_degrees: self.orbit_elevation,
                fov_degrees: self.orbit_fov,
                ..Orbit::ring(self.orbit as usize, self.up, self.orbit_size)
            },
            views: self.views.map(|scene| SceneViews { scene, split: self.split, downscale: self.downscale }),
            background: self.background,
            eval: EvalOptions {
                dir: self.output,
                metrics: self.metrics,
                settings: SuiteSettings {
                    weights: self.weights.into_iter().chain(default_dirs()).collect(),
                    wd_log2_sigma: self.wd_log2_sigma,
                    lpips_input: LpipsInput::Official,
                },
            },
            report: self.report,
            times: CodingTimes { encode_seconds: self.encode_seconds, decode_seconds: self.decode_seconds },
        })
    }
}

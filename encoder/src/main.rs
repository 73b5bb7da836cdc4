//! `pwenc`: the pwgs encoder's command line.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_dataset::{LoadOptions, load_scene};
use pwgs_decoder::raster::RenderOptions;
use pwgs_encoder::preview::{evaluate, initial_gaussians};
use serde::Serialize;

#[derive(Parser)]
#[command(name = "pwenc", version, about = "pwgs encoder: 3D Gaussian Splatting scenes with a perceptual wrapper")]
struct Cli {
    #[command(subcommand)]
    command: Command,
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
    /// Load a scene and print what was found: format, views, resolution, points, normalization.
    Inspect {
        scene: PathBuf,
        #[command(flatten)]
        load: LoadArgs,
    },
    /// Initialize Gaussians from the scene's SfM points (no training yet), render the test views
    /// and report their PSNR against the ground truth.
    Preview {
        scene: PathBuf,
        #[command(flatten)]
        load: LoadArgs,
        /// Folder for the rendered test views.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write the initial Gaussians as an INRIA PLY.
        #[arg(long)]
        export_ply: Option<PathBuf>,
        /// Write per-view scores and timings as JSON.
        #[arg(long)]
        report: Option<PathBuf>,
    },
}

#[derive(clap::Args)]
struct LoadArgs {
    /// Integer image downscale (uses images_N when present).
    #[arg(long, default_value_t = 1)]
    downscale: u32,
    /// Background for transparent pixels: `white`, `black` or `r,g,b` in [0, 1].
    #[arg(long, default_value = "black", value_parser = parse_color)]
    background: [f32; 3],
}

impl LoadArgs {
    fn options(&self) -> LoadOptions {
        LoadOptions { downscale: self.downscale, background: self.background, ..Default::default() }
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
struct PreviewReport<'a> {
    scene: String,
    format: &'a str,
    gaussians: usize,
    mean_psnr: f64,
    views: Vec<pwgs_encoder::preview::ViewScore>,
    load_seconds: f64,
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Command::GenerateScene { dir, width, height, views, seed } => {
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
        }
        Command::Inspect { scene, load } => {
            let data = load_scene(&scene, &load.options())?;
            let first = data.train.first().context("no training views")?;
            println!("format          {}", data.format);
            println!("views           {} train, {} test", data.train.len(), data.test.len());
            println!("resolution      {}x{}", first.image.width, first.image.height);
            println!("focal           fx {:.3}, fy {:.3}", first.camera.fx, first.camera.fy);
            println!("points          {}", data.points.as_ref().map_or(0, |p| p.positions.len()));
            let n = data.normalization;
            println!("normalization   center {:?}, scale {:.4}", n.center.to_array(), n.scale);
        }
        Command::Preview { scene, load, out, export_ply, report } => {
            let start = Instant::now();
            let data = load_scene(&scene, &load.options())?;
            let load_seconds = start.elapsed().as_secs_f64();
            let gaussians = initial_gaussians(&data)?;
            if let Some(path) = &export_ply {
                pwgs_decoder::ply::write_gaussians(path, &gaussians)?;
            }
            let render = RenderOptions { background: load.background, ..Default::default() };
            let views = evaluate(&gaussians, &data, &render, out.as_deref())?;
            for v in &views {
                println!("{:<24} PSNR {:6.2} dB   render {:.3} s", v.name, v.psnr, v.render_seconds);
            }
            let mean_psnr = views.iter().map(|v| v.psnr).sum::<f64>() / views.len().max(1) as f64;
            println!("{} Gaussians from {} points; mean test PSNR {mean_psnr:.2} dB", gaussians.len(), gaussians.len());
            if let Some(path) = report {
                let report = PreviewReport {
                    scene: scene.display().to_string(),
                    format: data.format,
                    gaussians: gaussians.len(),
                    mean_psnr,
                    views,
                    load_seconds,
                };
                let json = serde_json::to_vec_pretty(&report)?;
                pwgs_decoder::atomic_file::write_atomically(&path, &json)
                    .with_context(|| format!("cannot write {}", path.display()))?;
            }
        }
    }
    Ok(())
}

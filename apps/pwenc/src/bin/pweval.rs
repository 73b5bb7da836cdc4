//! `pweval`: image quality metrics between two images, or between same-named images of two
//! folders, as a table (per image and mean) or JSON.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::Parser;
use pwgs_core::rgb_image::RgbImage;
use pwgs_core::say;
use pwgs_encoder::metrics::lpips::LpipsInput;
use pwgs_encoder::metrics::suite::{DEFAULT_WD_LOG2_SIGMA, Metric, MetricSuite, SuiteSettings};
use pwgs_encoder::metrics::weights::default_dirs;
use serde_json::json;

#[derive(Parser)]
#[command(name = "pweval", version, about = "Image quality metrics: PSNR, SSIM, LPIPS, DISTS, Wasserstein Distortion")]
struct Cli {
    /// An image, or a folder of images.
    a: PathBuf,
    /// An image of the same size, or a folder with images of the same names.
    b: PathBuf,
    /// Metrics to compute (repeat or separate with commas); default: all but wd.
    #[arg(long, value_enum, value_delimiter = ',')]
    metric: Vec<Metric>,
    /// log2 of the WD pooling width σ, constant over the image (0..=5).
    #[arg(long, default_value_t = DEFAULT_WD_LOG2_SIGMA)]
    log2_sigma: f64,
    /// LPIPS on [0, 1] input as 3DGS's metrics.py computes it, instead of the official [-1, 1].
    #[arg(long)]
    lpips_3dgs: bool,
    /// A folder to search first for the weight files (then $PWGS_WEIGHTS_DIR and the cache).
    #[arg(long)]
    weights: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

const IMAGE_EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "bmp"];

/// (name, path in A, path in B) for every image to compare.
fn pairs(a: &Path, b: &Path) -> Result<Vec<(String, PathBuf, PathBuf)>> {
    if !a.is_dir() {
        if b.is_dir() {
            bail!("{} is a file but {} is a folder", a.display(), b.display());
        }
        return Ok(vec![(a.file_name().unwrap_or_default().to_string_lossy().into_owned(), a.into(), b.into())]);
    }
    if !b.is_dir() {
        bail!("{} is a folder but {} is not", a.display(), b.display());
    }
    let images = |dir: &Path| -> Result<BTreeMap<String, PathBuf>> {
        let mut out = BTreeMap::new();
        for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
            let path = entry?.path();
            let is_image = path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()));
            if path.is_file() && is_image {
                out.insert(path.file_name().unwrap_or_default().to_string_lossy().into_owned(), path);
            }
        }
        Ok(out)
    };
    let (in_a, mut in_b) = (images(a)?, images(b)?);
    let mut out = Vec::new();
    for (name, path_a) in in_a {
        match in_b.remove(&name) {
            Some(path_b) => out.push((name, path_a, path_b)),
            None => eprintln!("warning: {name} is only in {}", a.display()),
        }
    }
    for name in in_b.keys() {
        eprintln!("warning: {name} is only in {}", b.display());
    }
    if out.is_empty() {
        bail!("no same-named images in {} and {}", a.display(), b.display());
    }
    Ok(out)
}

fn main() -> ExitCode {
    pwgs_cli::report(run(Cli::parse()))
}

fn run(cli: Cli) -> Result<()> {
    let metrics = if cli.metric.is_empty() {
        vec![Metric::Psnr, Metric::Ssim, Metric::Ssim3dgs, Metric::Lpips, Metric::Dists]
    } else {
        cli.metric.clone()
    };
    let pairs = pairs(&cli.a, &cli.b)?;
    let settings = SuiteSettings {
        weights: cli.weights.iter().cloned().chain(default_dirs()).collect(),
        wd_log2_sigma: cli.log2_sigma,
        lpips_input: if cli.lpips_3dgs { LpipsInput::Unit } else { LpipsInput::Official },
    };
    let suite = MetricSuite::load(&metrics, settings)?;
    let metrics = suite.metrics();

    let mut rows: Vec<(String, Vec<f64>)> = Vec::new();
    for (name, path_a, path_b) in &pairs {
        let a = RgbImage::load(path_a, [0.0; 3])?;
        let b = RgbImage::load(path_b, [0.0; 3])?;
        rows.push((name.clone(), suite.score(&a, &b).with_context(|| name.clone())?));
    }
    let means: Vec<f64> =
        (0..metrics.len()).map(|k| rows.iter().map(|(_, v)| v[k]).sum::<f64>() / rows.len() as f64).collect();

    if cli.json {
        let record = |values: &[f64]| {
            metrics.iter().zip(values).map(|(m, v)| (m.name().to_string(), json!(v))).collect::<serde_json::Map<_, _>>()
        };
        let images: Vec<_> = rows
            .iter()
            .map(|(name, values)| {
                let mut r = record(values);
                r.insert("image".into(), json!(name));
                r
            })
            .collect();
        let mut settings = serde_json::Map::new();
        if metrics.contains(&Metric::Lpips) {
            settings
                .insert("lpips_input".into(), json!(if cli.lpips_3dgs { "[0,1] (3dgs)" } else { "[-1,1] (official)" }));
        }
        if metrics.contains(&Metric::Wd) {
            settings.insert("log2_sigma".into(), json!(cli.log2_sigma));
        }
        let out = json!({ "settings": settings, "images": images, "mean": record(&means), "count": rows.len() });
        say!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let width = rows.iter().map(|(n, _)| n.len()).chain([5]).max().unwrap_or(5);
        let header: String = metrics.iter().map(|m| format!(" {:>10}", m.name())).collect();
        say!("{:<width$}{header}", "image");
        for (name, values) in rows.iter().map(|(n, v)| (n.as_str(), v)).chain([("mean", &means)]) {
            let cells: String = values.iter().map(|v| format!(" {v:>10.5}")).collect();
            say!("{name:<width$}{cells}");
        }
    }
    Ok(())
}

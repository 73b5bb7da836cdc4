//! Evaluation on views with a ground truth (a dataset's test views, or a reference model's
//! renders on an orbit): render each, compare with the ground truth (PSNR, and
//! SSIM in the 3DGS zero-padded convention that published 3DGS numbers use, and any metrics of
//! a [`MetricSuite`]), optionally save the renders.

use pwgs_render::show::SceneRender;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use burn::tensor::Device;
use pwgs_codec::scene::Scene;
use pwgs_core::rgb_image::RgbImage;
use pwgs_core::say;
use pwgs_dataset::View;
use serde::Serialize;

use crate::metrics::image_tensor::image_tensor;
use crate::metrics::psnr::psnr;
use crate::metrics::ssim::{SsimConvention, ssim};
use crate::metrics::suite::{Metric, MetricSuite, SuiteSettings};

/// Quality of one rendered test view.
#[derive(Debug, Clone, Serialize)]
pub struct ViewScore {
    pub name: String,
    pub psnr: f64,
    /// 3DGS convention (zero-padded windows).
    pub ssim: f64,
    pub render_seconds: f64,
    /// The suite's metrics by name (LPIPS, DISTS, WD, ...), when one was given.
    #[serde(flatten)]
    pub metrics: BTreeMap<String, f64>,
}

/// Mean scores over views.
#[derive(Debug, Clone, Serialize)]
pub struct MeanScore {
    pub psnr: f64,
    pub ssim: f64,
    #[serde(flatten)]
    pub metrics: BTreeMap<String, f64>,
}

impl MeanScore {
    pub fn of(views: &[ViewScore]) -> Self {
        let n = views.len().max(1) as f64;
        let mean = |value: &dyn Fn(&ViewScore) -> f64| views.iter().map(value).sum::<f64>() / n;
        let names = views.first().map(|v| v.metrics.keys().cloned().collect::<Vec<_>>()).unwrap_or_default();
        Self {
            psnr: mean(&|v| v.psnr),
            ssim: mean(&|v| v.ssim),
            metrics: names.into_iter().map(|k| (k.clone(), mean(&|v| v.metrics[&k]))).collect(),
        }
    }
}

/// A suite's scores as `  NAME value` pairs for a log line (empty without a suite).
fn describe(metrics: &BTreeMap<String, f64>) -> String {
    metrics.iter().map(|(k, v)| format!("  {} {v:.4}", k.to_uppercase())).collect()
}

/// SSIM of two images, 3DGS convention, on the CPU backend.
pub fn ssim_3dgs(a: &RgbImage, b: &RgbImage) -> f64 {
    let device = Device::flex();
    let value = ssim(image_tensor(a, &device), image_tensor(b, &device), SsimConvention::ZeroPadded);
    value.into_data().convert::<f64>().try_into_vec::<f64>().expect("scalar")[0]
}

/// Renders every view as a decoder shows it (through the wrapper when the scene has one,
/// clamped to the displayable range), optionally saving `<out>/<name>.png` and the ground
/// truth as loaded (undistorted, downscaled) as `<out>/gt/<name>.png` for `pweval`, and scores
/// it with PSNR, SSIM and `suite`'s metrics.
pub fn evaluate(
    scene: &Scene,
    views: &[View],
    out: Option<&Path>,
    suite: Option<&MetricSuite>,
) -> Result<Vec<ViewScore>> {
    if let Some(dir) = out {
        let gt = dir.join("gt");
        std::fs::create_dir_all(&gt).with_context(|| format!("cannot create {}", gt.display()))?;
    }
    views
        .iter()
        .map(|view| {
            let start = Instant::now();
            let mut image = scene.render(&view.camera, &scene.render_options(), true)?.image;
            let render_seconds = start.elapsed().as_secs_f64();
            image.clamp_to_displayable();
            if let Some(dir) = out {
                let stem =
                    Path::new(&view.name).file_stem().map_or_else(|| view.name.clone(), |s| s.to_string_lossy().into());
                image.save_png(&dir.join(format!("{stem}.png")))?;
                view.image.save_png(&dir.join("gt").join(format!("{stem}.png")))?;
            }
            Ok(ViewScore {
                name: view.name.clone(),
                psnr: psnr(&image, &view.image),
                ssim: ssim_3dgs(&image, &view.image),
                render_seconds,
                metrics: suite.map(|s| s.score_named(&image, &view.image)).transpose()?.unwrap_or_default(),
            })
        })
        .collect()
}

/// Where a job scores its test views, and with which metrics besides PSNR and SSIM.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    /// The renders and, in `gt/`, the ground truth as training saw it.
    pub dir: PathBuf,
    pub metrics: Vec<Metric>,
    pub settings: SuiteSettings,
}

/// An evaluation ready to run: its metrics' networks loaded, so that missing weights stop a
/// job before it trains rather than after.
pub struct Evaluation<'a> {
    options: &'a EvalOptions,
    suite: Option<MetricSuite>,
}

impl<'a> Evaluation<'a> {
    pub fn prepare(options: &'a EvalOptions) -> Result<Self> {
        let suite = match options.metrics.is_empty() {
            true => None,
            false => Some(MetricSuite::load(&options.metrics, options.settings.clone())?),
        };
        Ok(Self { options, suite })
    }

    /// Scores `scene` on `views` (a dataset's test views, say), printing a line per view and
    /// the mean.
    pub fn run(&self, scene: &Scene, views: &[View]) -> Result<(Vec<ViewScore>, MeanScore)> {
        let views = evaluate(scene, views, Some(&self.options.dir), self.suite.as_ref())?;
        for v in &views {
            say!(
                "{:<24} PSNR {:6.2} dB  SSIM {:.4}{}  render {:.3} s",
                v.name,
                v.psnr,
                v.ssim,
                describe(&v.metrics),
                v.render_seconds
            );
        }
        let mean = MeanScore::of(&views);
        say!(
            "mean over {} test views: PSNR {:.2} dB, SSIM {:.4}{}",
            views.len(),
            mean.psnr,
            mean.ssim,
            describe(&mean.metrics)
        );
        Ok((views, mean))
    }
}

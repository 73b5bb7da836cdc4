//! A chosen set of metrics with their networks loaded once, scoring image pairs: what `pweval`
//! prints and what `pwenc --eval --eval-metrics` adds to each test view.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Result, bail};
use burn::tensor::{Device, Tensor};
use clap::ValueEnum;
use pwgs_core::rgb_image::RgbImage;

use super::dists::Dists;
use super::image_tensor::image_tensor;
use super::lpips::{Lpips, LpipsInput};
use super::psnr::psnr;
use super::sigma_map::{LEVELS, Log2Sigma};
use super::ssim::{SsimConvention, ssim};
use super::vgg_wasserstein::VggWasserstein;

/// One image quality metric.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, ValueEnum)]
pub enum Metric {
    Psnr,
    /// SSIM with valid windows (Wang et al., scikit-image).
    Ssim,
    /// SSIM with zero-padded windows over all pixels (3DGS).
    #[value(name = "ssim-3dgs")]
    Ssim3dgs,
    Lpips,
    Dists,
    Wd,
}

impl Metric {
    /// The name reports use.
    pub fn name(self) -> &'static str {
        match self {
            Metric::Psnr => "psnr",
            Metric::Ssim => "ssim",
            Metric::Ssim3dgs => "ssim-3dgs",
            Metric::Lpips => "lpips",
            Metric::Dists => "dists",
            Metric::Wd => "wd",
        }
    }
}

/// WD's default pooling width for scoring, log2σ (pixels).
pub const DEFAULT_WD_LOG2_SIGMA: f64 = 2.0;

/// How the metrics that have settings are computed.
#[derive(Debug, Clone, PartialEq)]
pub struct SuiteSettings {
    /// Folders searched for the weight files, first to last.
    pub weights: Vec<PathBuf>,
    /// WD's pooling width, constant over the image.
    pub wd_log2_sigma: f64,
    pub lpips_input: LpipsInput,
}

/// Metrics with their networks, ready to score pairs.
pub struct MetricSuite {
    metrics: Vec<Metric>,
    settings: SuiteSettings,
    lpips: Option<Lpips>,
    dists: Option<Dists>,
    wd: Option<VggWasserstein>,
    device: Device,
}

impl MetricSuite {
    /// Loads what `metrics` need (sorted, each once); a missing weights file is an error here,
    /// before any image is scored.
    pub fn load(metrics: &[Metric], settings: SuiteSettings) -> Result<Self> {
        let mut metrics = metrics.to_vec();
        metrics.sort();
        metrics.dedup();
        if let Err(e) = Log2Sigma::Constant(settings.wd_log2_sigma).validate() {
            bail!("WD log2 sigma: {e} (the WD pyramid has {LEVELS} levels)");
        }
        let device = Device::flex();
        let dirs = &settings.weights;
        let wants = |m: Metric| metrics.contains(&m);
        Ok(Self {
            lpips: wants(Metric::Lpips).then(|| Lpips::load(dirs, &device)).transpose()?,
            dists: wants(Metric::Dists).then(|| Dists::load(dirs, &device)).transpose()?,
            wd: wants(Metric::Wd).then(|| VggWasserstein::load(dirs, &device)).transpose()?,
            metrics,
            settings,
            device,
        })
    }

    /// The metrics, in the order [`Self::score`] returns them.
    pub fn metrics(&self) -> &[Metric] {
        &self.metrics
    }

    pub fn settings(&self) -> &SuiteSettings {
        &self.settings
    }

    /// Each metric of `a` against the reference `b` (same size).
    pub fn score(&self, a: &RgbImage, b: &RgbImage) -> Result<Vec<f64>> {
        if (a.width, a.height) != (b.width, b.height) {
            bail!("images of different sizes: {}x{} vs {}x{}", a.width, a.height, b.width, b.height);
        }
        let (ta, tb) = (image_tensor(a, &self.device), image_tensor(b, &self.device));
        let scalar = |t: Tensor<1>| f64::from(t.into_scalar::<f32>());
        let loaded = "loaded for the metrics it scores";
        Ok(self
            .metrics
            .iter()
            .map(|metric| match metric {
                Metric::Psnr => psnr(a, b),
                Metric::Ssim => scalar(ssim(ta.clone(), tb.clone(), SsimConvention::Valid)),
                Metric::Ssim3dgs => scalar(ssim(ta.clone(), tb.clone(), SsimConvention::ZeroPadded)),
                Metric::Lpips => scalar(self.lpips.as_ref().expect(loaded).distance(
                    ta.clone(),
                    tb.clone(),
                    self.settings.lpips_input,
                )),
                Metric::Dists => scalar(self.dists.as_ref().expect(loaded).distance(ta.clone(), tb.clone())),
                Metric::Wd => {
                    let sigma = Log2Sigma::Constant(self.settings.wd_log2_sigma);
                    scalar(self.wd.as_ref().expect(loaded).distortion_pair(ta.clone(), tb.clone(), &sigma))
                }
            })
            .collect())
    }

    /// [`Self::score`] as a map from metric name to value.
    pub fn score_named(&self, a: &RgbImage, b: &RgbImage) -> Result<BTreeMap<String, f64>> {
        Ok(self.metrics.iter().map(|m| m.name().to_string()).zip(self.score(a, b)?).collect())
    }
}

//! The perceptual wrapper's options: on by default, `--no-wrapper` for the base alone.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use pwgs_codec::stream::wrap::MAX_WIDTH;
use pwgs_codec::wrapper::synthesis::WrapperConfig;
use pwgs_core::random::SplitMix64;
use pwgs_encoder::metrics::sigma_map::{LEVELS, Log2Sigma, SigmaMap};
use pwgs_encoder::metrics::vgg_wasserstein::{IMAGE_SCALES, MIN_SIDE, WdDepth};
use pwgs_encoder::metrics::vgg16::VGG_BLOCKS;
use pwgs_encoder::wrapper::stage::{DEFAULT_CROPS_PER_VIEW, DEFAULT_MIN_STEPS, DEFAULT_WD_SCALES};
use pwgs_encoder::wrapper::stage::{WdFeatures, WrapperTraining};

use crate::values::parse_weight;

/// The perceptual wrapper's training options.
#[derive(Args)]
#[command(next_help_heading = "Perceptual wrapper (stage 2, trained by default)")]
pub(crate) struct WrapperArgs {
    /// Train the base alone, without the perceptual wrapper.
    ///
    /// The wrapper (stage 2: Wasserstein Distortion and the synthesis network f, stored in the
    /// stream) is trained by default.
    #[arg(long)]
    pub(crate) no_wrapper: bool,
    /// Train the perceptual wrapper: the default, accepted so that a command can say so.
    #[arg(long, conflicts_with = "no_wrapper", hide_short_help = true)]
    wrapper: bool,
    /// Stage 2's length in steps (one crop each) per training view.
    ///
    /// It follows the --iters iterations of stage 1, so that every view is seen as often
    /// whatever the scene's size (--iters 0: stage 2 only, e.g. on a model from --init-ply).
    #[arg(long, default_value_t = DEFAULT_CROPS_PER_VIEW, conflicts_with = "no_wrapper", value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=10_000))]
    wrapper_crops_per_view: u32,
    /// Stage 2's least length in steps, for scenes with few views (0: none).
    #[arg(long, default_value_t = DEFAULT_MIN_STEPS, conflicts_with = "no_wrapper", hide_short_help = true)]
    wrapper_min_steps: u32,
    /// Memory for cached WD features and f's conditioning, in MiB.
    ///
    /// A 128-pixel crop's ground-truth features take about 11 MB, a view's conditioning
    /// channels 56 bytes a pixel; beyond this budget they are recomputed at each use.
    #[arg(long, default_value_t = 2048, conflicts_with = "no_wrapper", hide_short_help = true)]
    wd_cache_mib: usize,
    /// Hidden channels of f.
    #[arg(long, default_value_t = 16, conflicts_with = "no_wrapper", hide_short_help = true,
          value_parser = clap::value_parser!(u8).range(1..=MAX_WIDTH as i64))]
    wrapper_width: u8,
    /// Do not feed f the noise pyramid (ablation).
    #[arg(long, conflicts_with = "no_wrapper", hide_short_help = true)]
    no_noise: bool,
    /// Do not feed f the Plücker embeddings (ablation).
    #[arg(long, conflicts_with = "no_wrapper", hide_short_help = true)]
    no_plucker: bool,
    /// Seed of the noise pyramid (default: derived from --seed).
    #[arg(long, conflicts_with = "no_wrapper", hide_short_help = true)]
    wrapper_seed: Option<u64>,
    /// Adam learning rate of f.
    ///
    /// 5e-3 beat 2e-3 together with log2σ 4 on fern.
    #[arg(long, default_value_t = 5e-3, conflicts_with = "no_wrapper", hide_short_help = true)]
    wrapper_lr: f32,
    /// Multiplies the base's learning rates in stage 2 (0 freezes the base).
    ///
    /// 1: as in stage 1; 0 trains f alone. Default: 1 for plain Gaussians, 0.1 for anchors
    /// (whose shared MLPs WD otherwise pulls away from the pixels: on fern 0.1 gave a 10%
    /// smaller stream, LPIPS 0.190 instead of 0.202 and 1.9 dB more at the same DISTS).
    #[arg(long, conflicts_with = "no_wrapper", value_parser = parse_weight, hide_short_help = true)]
    wrapper_base_lr_scale: Option<f32>,
    /// log2 of WD's pooling width σ in pixels, 0 to 5.
    ///
    /// The same everywhere; 4 gave a lower DISTS than 3 on fern.
    #[arg(long, default_value_t = 4.0, conflicts_with = "no_wrapper", value_name = "LOG2")]
    wd_log2_sigma: f64,
    /// A per-pixel log2σ map instead: a grayscale PNG of the views' size.
    ///
    /// log2σ = 5 * gray / 255.
    #[arg(long, conflicts_with = "no_wrapper", conflicts_with = "wd_log2_sigma", hide_short_help = true)]
    wd_log2_sigma_map: Option<PathBuf>,
    /// Side of the square crop WD scores at each step.
    #[arg(long, default_value_t = 128, conflicts_with = "no_wrapper", hide_short_help = true)]
    wd_crop: usize,
    /// Weight of the base's pixel objective on the crop, added to WD in stage 2.
    ///
    /// 0.8 L1 + 0.2 (1 - SSIM) of the base render: keeps the Gaussians faithful to the pixels
    /// while f synthesizes texture (0: WD alone).
    #[arg(long, default_value_t = 0.0, conflicts_with = "no_wrapper", value_parser = parse_weight,
          hide_short_help = true)]
    wd_pixel_weight: f32,
    /// Features WD compares: VGG16 (the reference) or the image alone (cheap, no weights).
    #[arg(long, value_enum, default_value = "vgg", conflicts_with = "no_wrapper", hide_short_help = true)]
    wd_features: FeatureKind,
    /// VGG16 blocks WD compares, 1 to 5.
    ///
    /// relu1_2 .. relu5_3; fewer skip the deeper layers: a cheaper step.
    #[arg(long, default_value_t = VGG_BLOCKS as u8, conflicts_with = "no_wrapper", hide_short_help = true,
          value_parser = clap::value_parser!(u8).range(1..=VGG_BLOCKS as i64))]
    wd_vgg_blocks: u8,
    /// Image scales stage 2's WD compares, 1 to 3.
    ///
    /// Each half the previous; fewer are cheaper; the full-resolution scale alone gave fern
    /// and fox lower DISTS and LPIPS.
    #[arg(long, default_value_t = DEFAULT_WD_SCALES as u8, conflicts_with = "no_wrapper", hide_short_help = true,
          value_parser = clap::value_parser!(u8).range(1..=IMAGE_SCALES as i64))]
    wd_scales: u8,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum FeatureKind {
    Vgg,
    Pixels,
}

impl WrapperArgs {
    /// Stage 2's settings for a run of `iterations`, or `None` with --no-wrapper.
    /// `base_lr_scale` is the base's stage-2 learning-rate factor unless the command line sets one.
    pub(crate) fn training(
        &self,
        iterations: u32,
        seed: u64,
        weights: Vec<PathBuf>,
        base_lr_scale: f32,
    ) -> Result<Option<WrapperTraining>> {
        if self.no_wrapper {
            return Ok(None);
        }
        if self.wd_crop < MIN_SIDE {
            bail!("--wd-crop must be at least {MIN_SIDE} (VGG's deepest layer needs it)");
        }
        let log2_sigma = match &self.wd_log2_sigma_map {
            Some(path) => {
                let gray = image::open(path).with_context(|| format!("cannot read {}", path.display()))?.to_luma8();
                let values = gray.pixels().map(|p| LEVELS as f64 * f64::from(p.0[0]) / 255.0).collect();
                Log2Sigma::Map(SigmaMap { height: gray.height() as usize, width: gray.width() as usize, values })
            }
            None => Log2Sigma::Constant(self.wd_log2_sigma),
        };
        log2_sigma.validate().map_err(|e| anyhow::anyhow!("WD log2 sigma: {e}"))?;
        let features = match self.wd_features {
            FeatureKind::Vgg => WdFeatures::Vgg(weights),
            FeatureKind::Pixels => WdFeatures::Pixels,
        };
        Ok(Some(WrapperTraining {
            config: WrapperConfig {
                width: usize::from(self.wrapper_width),
                noise: !self.no_noise,
                plucker: !self.no_plucker,
                seed: self.wrapper_seed.unwrap_or_else(|| SplitMix64(seed ^ 0x5752_4150).next_u64()),
            },
            start: iterations,
            crops_per_view: self.wrapper_crops_per_view,
            min_steps: self.wrapper_min_steps,
            cache_bytes: self.wd_cache_mib.saturating_mul(1 << 20),
            log2_sigma,
            crop: self.wd_crop,
            learning_rate: self.wrapper_lr,
            base_lr_scale: self.wrapper_base_lr_scale.unwrap_or(base_lr_scale),
            features,
            wd_depth: WdDepth { blocks: usize::from(self.wd_vgg_blocks), scales: usize::from(self.wd_scales) },
            pixel_weight: self.wd_pixel_weight,
        }))
    }
}

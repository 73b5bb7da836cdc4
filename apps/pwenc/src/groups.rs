//! `pwenc`'s encoding options in groups, one per part of the method; each group's help has its
//! own heading, and which jobs read a group decides which options a job refuses
//! ([`crate::args::EncodeArgs::check_options`]). Each option's first paragraph is its line in
//! `--help`; `--help-all` adds the rest, and the options marked `hide_short_help` (experts'
//! knobs, ablations).

use std::path::PathBuf;

use clap::Args;
use pwgs_cli::values::parse_vector;
use pwgs_encoder::anchor::train::StageTwoLambda;
use pwgs_encoder::metrics::suite::{DEFAULT_WD_LOG2_SIGMA, Metric};
use pwgs_encoder::plain::colour_refit::FULL_REFIT;
use pwgs_encoder::plain::compress::{DEFAULT_QUALITY, MAX_QUALITY};
use pwgs_encoder::session::{DEFAULT_EFFORT, MAX_EFFORT, Tools};
use pwgs_encoder::train::device::DeviceChoice;
use pwgs_encoder::train::views::DEFAULT_IMAGE_BUDGET;

use crate::values::{SpzAxesArg, parse_positive, parse_rate_pair, parse_stage_two_lambda, parse_weight};

/// Options of `--from`, compressing a model trained elsewhere.
#[derive(Args)]
#[command(next_help_heading = "Import (--from MODEL)")]
pub(crate) struct ImportArgs {
    /// Axes of an `.spz` that names none: `rub` (the format's) or `rdf`.
    ///
    /// `rub` as the format specifies (Niantic's files), `rdf` for a PLY's own axes, which
    /// PlayCanvas's splat-transform (3.7.0) writes unconverted and unmarked (its files load
    /// upside down otherwise).
    #[arg(long, value_enum, default_value = "rub", hide_short_help = true)]
    pub(crate) spz_axes: SpzAxesArg,
    /// Report the PSNR of this many orbit views, input against stream.
    ///
    /// Renders the views on an orbit around the model, from the input and from the decoded
    /// stream.
    #[arg(long, value_name = "VIEWS")]
    pub(crate) orbit: Option<usize>,
    /// Up direction (`x,y,z`) of the orbit and the importance views.
    ///
    /// Captures in COLMAP conventions usually have -y up.
    #[arg(long, default_value = "0,-1,0", value_name = "X,Y,Z", value_parser = parse_vector)]
    pub(crate) up: [f32; 3],
    /// Width and height of the orbit views.
    #[arg(long, default_value_t = 512, hide_short_help = true)]
    pub(crate) orbit_size: u32,
    /// Weigh the views of the capture the model was trained on too: the cameras of this scene
    /// folder (COLMAP, transforms.json or LLFF), all of them.
    ///
    /// The importance classes, pruning and refits then hold on the capture's own views as well
    /// as on the views all round the model (at most 64 of them, each resized to 512 pixels
    /// on its longer side).
    #[arg(long, value_name = "SCENE")]
    pub(crate) views: Option<PathBuf>,
    /// Save the orbit renders (input and decoded) as PNGs in this folder.
    #[arg(long, requires = "orbit", hide_short_help = true)]
    pub(crate) orbit_renders: Option<PathBuf>,
    /// How hard to work for a smaller stream: 0 (fastest) to 9 (smallest).
    ///
    /// Each level is a fixed set of the tools below: 0 uniform steps, 1 importance classes, 2
    /// with pruning, 3 to 5 with a colour refit (2 and 8 iterations, then 8 rounded in
    /// quarters), 6 to 9 with a shape refit too (1, 2, 3 and 6 epochs). The options below add
    /// their tool to the level's. With --target-bytes the refits are left out.
    #[arg(long, default_value_t = DEFAULT_EFFORT, value_name = "0..9",
          value_parser = clap::value_parser!(u8).range(0..=MAX_EFFORT as i64))]
    pub(crate) effort: u8,
    /// Coarser steps for the Gaussians that show less (importance classes).
    ///
    /// Each Gaussian is coded with steps by how much it shows from 98 views all round the model
    /// (SPEC.md section 6.5).
    #[arg(long, hide_short_help = true)]
    pub(crate) importance_classes: bool,
    /// Drop the Gaussians that show least (with importance classes).
    ///
    /// Drops the faintest Gaussians, as many as leave every importance view (all round the
    /// model, and closer in) at least 1 - 2^(1 - quality) of its colour (at most an eighth
    /// lost).
    #[arg(long, hide_short_help = true)]
    pub(crate) prune_faint: bool,
    /// Search this model's steps for the fewest bytes (with importance classes).
    ///
    /// Searches how coarse each attribute's steps are against the others' (and how far apart
    /// the classes are and how much pruning may take) for the fewest bytes along the quality
    /// curve, scoring candidates on renders of the importance views. Slower (tens of
    /// candidates, each written, decoded and rendered).
    #[arg(long, hide_short_help = true)]
    pub(crate) search_steps: bool,
    /// Refit the colours to the quantized geometry (with importance classes).
    ///
    /// So that the stream renders closest to the model on the importance views and 41 more
    /// below their horizon (least squares, the geometry held; 8 conjugate-gradient iterations,
    /// then rounded in quarters with the rest refitted between), before they are quantized.
    /// Not with --target-bytes (the refit is for the Gaussians the quality keeps).
    #[arg(long, conflicts_with = "target_bytes", hide_short_help = true)]
    pub(crate) refit_colours: bool,
    /// Refit the shapes to the quantized positions for EPOCHS (with importance classes).
    ///
    /// Refits the scales, rotations, opacities and SH to the quantized positions (and to the
    /// Gaussians pruned) so that the stream renders closest to the model on the importance
    /// views and 41 more below their horizon: this many epochs of gradient descent over those
    /// views, before they are quantized (and before --refit-colours). Not with --target-bytes.
    #[arg(long, conflicts_with = "target_bytes", value_name = "EPOCHS", hide_short_help = true,
          value_parser = clap::value_parser!(u16).range(1..=100))]
    pub(crate) refit_shapes: Option<u16>,
}

impl ImportArgs {
    /// The effort's tools with those the options add; the refits left out for a target size.
    pub(crate) fn tools(&self, target_size: bool) -> Tools {
        let given = Tools {
            importance: self.importance_classes,
            prune_faint: self.prune_faint,
            search_steps: self.search_steps,
            refit_shapes: self.refit_shapes.map(usize::from),
            refit_colours: self.refit_colours.then_some(FULL_REFIT),
        };
        let tools = Tools::of_effort(self.effort).with(given);
        if target_size { tools.without_refits() } else { tools }
    }
}

/// Options of the plain base (and `--quality`, which an import reads too).
#[derive(Args)]
#[command(next_help_heading = "Plain base (--base 3dgs) and import")]
pub(crate) struct PlainArgs {
    /// Size against quality, 0 (smallest) to 14 (most faithful).
    ///
    /// Each step scales every quantization step by 1/sqrt(2). The anchor base sets its size
    /// with --lambda instead.
    #[arg(long, default_value_t = DEFAULT_QUALITY, value_name = "0..14", value_parser = clap::value_parser!(u8).range(0..=MAX_QUALITY as i64))]
    pub(crate) quality: u8,
    /// Cap on the number of Gaussians densification may reach.
    #[arg(long, default_value_t = 1_000_000, value_name = "N")]
    pub(crate) max_gaussians: usize,
    /// Start from this INRIA PLY instead of the scene's points.
    ///
    /// To resume, or to refine a model trained elsewhere.
    #[arg(long, value_name = "PLY")]
    pub(crate) init_ply: Option<PathBuf>,
    /// Last iteration of densification.
    ///
    /// Default: half of --iters, and with the wrapper at most the end of stage 1.
    #[arg(long, hide_short_help = true)]
    pub(crate) densify_until: Option<u32>,
    /// Position learning rate `start,end`, times the scene extent.
    ///
    /// Default 1.6e-4,1.6e-6 as 3DGS. To continue a model from --init-ply where its schedule
    /// ended, give the end value twice.
    #[arg(long, value_parser = parse_rate_pair, hide_short_help = true)]
    pub(crate) position_lr: Option<[f32; 2]>,
}

/// Options of the anchor base.
#[derive(Args)]
#[command(next_help_heading = "Anchor base (the default)")]
pub(crate) struct AnchorArgs {
    /// λ of the rate term: larger is smaller; 0 turns it off.
    ///
    /// HAC's convention: λ x mean bits per stored value. 0 turns the rate term and the learned
    /// masks off.
    #[arg(long, default_value_t = 0.002, value_name = "λ", value_parser = parse_weight)]
    pub(crate) lambda: f32,
    /// The anchors' feature length.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u16).range(1..=256), hide_short_help = true)]
    pub(crate) anchor_features: u16,
    /// Neural Gaussians per anchor.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u16).range(1..=64), hide_short_help = true)]
    pub(crate) anchor_offsets: u16,
    /// The anchors' voxel edge, as a fraction of the scene's scale.
    #[arg(long, default_value_t = 0.005, value_parser = parse_positive, hide_short_help = true)]
    pub(crate) voxel: f32,
    /// Multiplies the quantization steps of features, scales and offsets.
    ///
    /// 1: features and offsets 1/8, log scales 1/16; larger is smaller.
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive, hide_short_help = true)]
    pub(crate) anchor_step_scale: f32,
    /// Train without the quantization noise (the stream is rounded all the same).
    #[arg(long, hide_short_help = true)]
    pub(crate) no_quantization_noise: bool,
    /// One model per channel instead of the context model.
    ///
    /// The context model (a binary grid over the anchors and an MLP giving each anchor's
    /// means and scales, HAC's hash-grid context; SPEC.md section 12.7) is trained by the rate
    /// term; on fern it gave streams 8-10% smaller at equal or higher PSNR.
    #[arg(long, hide_short_help = true)]
    pub(crate) no_anchor_context: bool,
    /// Add HAC's 2D planes to the context grid at these levels (`r,r,...`).
    ///
    /// Planes xy, xz and yz of 2^r cells per axis, r from 1 to 24; the 3D levels are 3 to 8.
    #[arg(long, value_delimiter = ',', value_parser = clap::value_parser!(u8).range(1..=24),
          conflicts_with = "no_anchor_context", hide_short_help = true)]
    pub(crate) context_planes: Vec<u8>,
    /// With the wrapper: λ in stage 2, `auto` or a multiple of stage 1's.
    ///
    /// `auto` scales it by the ratio of the two stages' mean distortions (WD against the pixel
    /// loss), so that the rate term keeps its weight; a number F multiplies it by F (1: as in
    /// stage 1).
    #[arg(long, default_value = "auto", value_parser = parse_stage_two_lambda, conflicts_with = "no_wrapper",
          hide_short_help = true)]
    pub(crate) wrapper_lambda_scale: StageTwoLambda,
    /// Grow and prune anchors over the first half of the iterations.
    ///
    /// Grows anchors where neural Gaussians keep large screen gradients and prunes those that
    /// stay transparent (Scaffold-GS's anchor densification).
    #[arg(long)]
    pub(crate) anchor_growth: bool,
    /// With --anchor-growth: growing stops at this many anchors (default: twice the initial).
    #[arg(long, requires = "anchor_growth", hide_short_help = true)]
    pub(crate) max_anchors: Option<usize>,
    /// Keep the steps of features, scaling and offsets at their base values.
    ///
    /// Instead of learning a factor on each with the rate term, which on fern gave 0.66 dB
    /// more at equal size (see --anchor-step-scale).
    #[arg(long, hide_short_help = true)]
    pub(crate) fixed_anchor_steps: bool,
}

/// Options of training on a scene, either base.
#[derive(Args)]
#[command(next_help_heading = "Training")]
pub(crate) struct TrainingArgs {
    /// Training iterations of stage 1 (0: evaluate the initialization).
    #[arg(long, default_value_t = 3000, value_name = "N")]
    pub(crate) iters: u32,
    /// Integer image downscale (uses images_N when present).
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub(crate) downscale: u32,
    /// Write the trained Gaussians as an INRIA PLY.
    ///
    /// An anchor base is exported as standard Gaussians fitted to its renders.
    #[arg(long, value_name = "PLY")]
    pub(crate) export_ply: Option<PathBuf>,
    /// Seed of every random choice in training.
    #[arg(long, default_value_t = 0, hide_short_help = true)]
    pub(crate) seed: u64,
    /// Train on `gpu`, `cpu`, or `auto`: a GPU when there is one (builds with the `gpu`
    /// feature), else the CPU.
    #[arg(long, value_enum, default_value = "auto")]
    pub(crate) device: DeviceChoice,
    /// Training images kept on the training device, in MiB.
    ///
    /// Views beyond it stay in host memory and are uploaded each time a step draws them.
    #[arg(long, default_value_t = DEFAULT_IMAGE_BUDGET >> 20, value_name = "MIB", hide_short_help = true)]
    pub(crate) image_budget_mib: usize,
}

/// Options of the evaluation on the test views after training.
#[derive(Args)]
#[command(next_help_heading = "Evaluation")]
pub(crate) struct EvalArgs {
    /// Render the test views into this folder (default `eval`) and score them.
    ///
    /// PSNR and SSIM, and --eval-metrics.
    #[arg(long, num_args = 0..=1, default_missing_value = "eval", value_name = "DIR")]
    pub(crate) eval: Option<PathBuf>,
    /// More metrics for --eval: lpips, dists, wd (comma-separated).
    ///
    /// Per view and on average; their weights are searched as for the wrapper.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        requires = "eval",
        value_name = "METRICS",
        hide_possible_values = true
    )]
    pub(crate) eval_metrics: Vec<Metric>,
    /// log2 of WD's pooling width σ for --eval-metrics wd (0..=5).
    #[arg(long, default_value_t = DEFAULT_WD_LOG2_SIGMA, requires = "eval", hide_short_help = true)]
    pub(crate) eval_wd_log2_sigma: f64,
    /// A folder searched first for the VGG16, LPIPS and DISTS weights.
    ///
    /// Then $PWGS_WEIGHTS_DIR and the cache (`pwenc fetch-weights`).
    #[arg(long, value_name = "DIR")]
    pub(crate) weights: Option<PathBuf>,
}

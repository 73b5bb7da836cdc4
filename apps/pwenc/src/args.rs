//! `pwenc`'s encoding options and the jobs they make, refusing an option the job would ignore
//! (which options a job reads follows from the groups of [`crate::groups`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, CommandFactory, ValueEnum};
use pwgs_codec::stream::anchor_context::MAX_LEVELS;
use pwgs_dataset::{Dataset, LoadOptions, SceneViews, ViewSplit, images, load_scene};
use pwgs_encoder::anchor::quantize::AnchorSteps;
use pwgs_encoder::anchor::train::ANCHOR_STAGE_TWO_LR_SCALE;
use pwgs_encoder::metrics::evaluate::EvalOptions;
use pwgs_encoder::metrics::lpips::LpipsInput;
use pwgs_encoder::metrics::suite::SuiteSettings;
use pwgs_encoder::metrics::weights::default_dirs;
use pwgs_encoder::plain::train::TrainConfig;
use pwgs_encoder::session::{
    AnchorTraining, BaseTraining, EncodeJob, Input, ModelImport, Orbit, Outputs, PlainTraining,
};

use crate::groups::{AnchorArgs, EvalArgs, ImportArgs, PlainArgs, TrainingArgs};
use crate::values::{check_extra_metrics, parse_color};
use crate::wrapper_args::WrapperArgs;

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

/// What `pwenc SCENE` and `pwenc --from MODEL` take: the options every job reads, then the
/// groups of [`crate::groups`].
#[derive(Args)]
pub(crate) struct EncodeArgs {
    /// Scene folder (COLMAP, transforms.json or LLFF) to train on.
    #[arg(required_unless_present = "from_ply")]
    pub(crate) scene: Option<PathBuf>,
    /// Compress a model trained elsewhere instead: PLY, compressed PLY, .splat, .spz or SOG.
    ///
    /// A PLY in INRIA's layout or PlayCanvas's compressed one, a `.splat`, an `.spz` (versions
    /// 2 to 4) or a SOG (`.sog`, or the `meta.json` of an unbundled one), by extension.
    #[arg(long, visible_alias = "from", value_name = "MODEL", conflicts_with_all = ["scene", "init_ply", "eval"])]
    pub(crate) from_ply: Option<PathBuf>,
    /// Write the stream here.
    #[arg(short, long, value_name = "STREAM")]
    output: Option<PathBuf>,
    /// Base representation: `anchor` (the default) or `3dgs`.
    #[arg(long, value_enum, default_value = "anchor")]
    pub(crate) base: Base,
    /// Largest stream size in bytes: the least important Gaussians or anchors are dropped.
    ///
    /// When the stream would be larger, the least important Gaussians (plain base: lowest
    /// opacity times area) or anchors (anchor base: least opacity times area over the training
    /// views) are dropped until it fits. Two runs with the same target compare at equal size
    /// (within a few Gaussians' bytes); on the anchor base, choose a --lambda whose stream is a
    /// little larger than the target.
    #[arg(long, requires = "output", value_name = "BYTES", value_parser = clap::value_parser!(u64).range(1..))]
    target_bytes: Option<u64>,
    /// Background for transparent pixels and renders: `white`, `black` or `r,g,b`.
    #[arg(long, default_value = "black", value_name = "COLOUR", value_parser = parse_color)]
    background: [f32; 3],
    /// Write scores, timings and the model size as JSON.
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
    #[command(flatten)]
    training: TrainingArgs,
    #[command(flatten)]
    eval: EvalArgs,
    #[command(flatten)]
    wrapper: WrapperArgs,
    #[command(flatten)]
    anchor: AnchorArgs,
    #[command(flatten)]
    plain: PlainArgs,
    #[command(flatten)]
    import: ImportArgs,
}

/// The options `inspect` takes to load a scene.
#[derive(Args)]
pub(crate) struct LoadArgs {
    /// Integer image downscale (uses images_N when present).
    #[arg(long, default_value_t = 1)]
    downscale: u32,
    /// Background for transparent pixels: `white`, `black` or `r,g,b`.
    #[arg(long, default_value = "black", value_parser = parse_color)]
    background: [f32; 3],
}

impl LoadArgs {
    pub(crate) fn load(&self, scene: &Path) -> Result<Dataset> {
        let options = LoadOptions { downscale: self.downscale, background: self.background, ..Default::default() };
        load_scene(scene, &options).with_context(|| format!("cannot load the scene {}", scene.display()))
    }
}

/// The argument ids of an option group.
fn ids<A: Args>() -> Vec<String> {
    A::augment_args(clap::Command::new("group")).get_arguments().map(|a| a.get_id().to_string()).collect()
}

/// Options of the training groups that an import reads too: its size knob, and the wrapper's
/// switch (an import has no wrapper to train).
const IMPORT_READS: [&str; 2] = ["quality", "no_wrapper"];

impl EncodeArgs {
    /// Refuses an option that the job these arguments make would ignore, so that no run
    /// silently differs from its command line. `given(id)` says whether the command line set
    /// the argument `id`.
    pub(crate) fn check_options(&self, given: impl Fn(&str) -> bool) -> Result<()> {
        let (ignored, why): (Vec<String>, &str) = match (&self.from_ply, self.base) {
            (Some(_), _) => {
                let training = [ids::<TrainingArgs>(), ids::<EvalArgs>(), ids::<WrapperArgs>()];
                let bases = [ids::<AnchorArgs>(), ids::<PlainArgs>(), vec!["base".into()]];
                let ignored = training.into_iter().chain(bases).flatten();
                (
                    ignored.filter(|id| !IMPORT_READS.contains(&id.as_str())).collect(),
                    "applies to training on a scene; --from-ply compresses the model as it is",
                )
            }
            (None, Base::Anchor) => (
                ids::<PlainArgs>(),
                "applies to the plain base (--base 3dgs); the anchor base, the default, sets its size with --lambda",
            ),
            (None, Base::ThreeDgs) => {
                (ids::<AnchorArgs>(), "applies to the anchor base; this run trains plain Gaussians (--base 3dgs)")
            }
        };
        if let Some(id) = ignored.iter().find(|id| given(id)) {
            bail!("{} {why}", spelling(id));
        }
        match ids::<ImportArgs>().iter().find(|id| self.from_ply.is_none() && given(id)) {
            Some(id) => bail!("{} applies to --from-ply; this run trains on a scene", spelling(id)),
            None => Ok(()),
        }
    }

    fn load_options(&self) -> LoadOptions {
        LoadOptions { downscale: self.training.downscale, background: self.background, ..Default::default() }
    }

    /// The job these arguments describe.
    pub(crate) fn job(&self) -> Result<EncodeJob> {
        let input = match (&self.from_ply, &self.scene) {
            (Some(model), _) => Input::Model(Box::new(self.model_import(model))),
            (None, Some(scene)) => Input::Scene {
                path: scene.clone(),
                load: self.load_options(),
                base: match self.base {
                    Base::Anchor => BaseTraining::Anchor(Box::new(self.anchor_training()?)),
                    Base::ThreeDgs => BaseTraining::Plain(Box::new(self.plain_training()?)),
                },
                device: self.training.device,
            },
            (None, None) => bail!("give a scene to train on, or --from MODEL"),
        };
        if matches!(input, Input::Model(_)) && self.output.is_none() {
            bail!("--from-ply needs -o/--output for the stream");
        }
        let outputs = Outputs {
            stream: self.output.clone(),
            target_bytes: self.target_bytes,
            export_ply: self.training.export_ply.clone(),
            eval: self.eval_options()?,
            report: self.report.clone(),
        };
        Ok(EncodeJob { input, outputs })
    }

    /// `--eval` with its metrics, when given.
    fn eval_options(&self) -> Result<Option<EvalOptions>> {
        check_extra_metrics("--eval-metrics", &self.eval.eval_metrics)?;
        Ok(self.eval.eval.clone().map(|dir| EvalOptions {
            dir,
            metrics: self.eval.eval_metrics.clone(),
            settings: SuiteSettings {
                weights: self.weight_dirs(),
                wd_log2_sigma: self.eval.eval_wd_log2_sigma,
                lpips_input: LpipsInput::Official,
            },
        }))
    }

    /// Where weight files are searched: --weights, then the defaults.
    fn weight_dirs(&self) -> Vec<PathBuf> {
        self.eval.weights.iter().cloned().chain(default_dirs()).collect()
    }

    /// `--base anchor`: the anchor base's training, refusing what it cannot do.
    fn anchor_training(&self) -> Result<AnchorTraining> {
        let (a, t) = (&self.anchor, &self.training);
        if a.context_planes.len() > MAX_LEVELS {
            bail!("--context-planes takes at most {MAX_LEVELS} levels");
        }
        if !a.context_planes.is_empty() && a.lambda == 0.0 {
            bail!("--context-planes belongs to the context model, which --lambda 0 turns off");
        }
        Ok(AnchorTraining {
            iterations: t.iters,
            feature_dim: usize::from(a.anchor_features),
            offsets_per_anchor: usize::from(a.anchor_offsets),
            relative_voxel: a.voxel,
            background: self.background,
            seed: t.seed,
            steps: AnchorSteps::default().scaled(a.anchor_step_scale),
            quantization_noise: !a.no_quantization_noise,
            lambda: (a.lambda > 0.0).then_some(a.lambda),
            context: !a.no_anchor_context && a.lambda > 0.0,
            context_planes: a.context_planes.clone(),
            stage_two_lambda: a.wrapper_lambda_scale,
            growth: a.anchor_growth,
            max_anchors: a.max_anchors,
            learned_steps: !a.fixed_anchor_steps,
            image_budget: t.image_budget_mib.saturating_mul(1 << 20),
            wrapper: self.wrapper.training(t.iters, t.seed, self.weight_dirs(), ANCHOR_STAGE_TWO_LR_SCALE)?,
        })
    }

    /// `--from-ply`: the import.
    fn model_import(&self, model: &Path) -> ModelImport {
        let i = &self.import;
        ModelImport {
            path: model.to_path_buf(),
            spz_axes: i.spz_axes.into(),
            quality: self.plain.quality,
            background: self.background,
            orbit: i.orbit.map(|views| Orbit::ring(views, i.up, i.orbit_size)),
            orbit_renders: i.orbit_renders.clone(),
            up: i.up,
            capture: i.views.clone().map(|scene| {
                // The import resizes every capture view to its own size: any stored images do.
                let downscale = images::stored_downscale(&scene, "images");
                SceneViews { scene, split: ViewSplit::All, downscale }
            }),
            tools: i.tools(self.target_bytes.is_some()),
        }
    }

    /// `--base 3dgs`: the plain base's training.
    fn plain_training(&self) -> Result<PlainTraining> {
        let (p, t) = (&self.plain, &self.training);
        let mut config = TrainConfig::for_iterations(t.iters);
        config.wrapper = self.wrapper.training(t.iters, t.seed, self.weight_dirs(), 1.0)?;
        if let Some(until) = p.densify_until {
            config.densify_until = until;
        }
        if let Some(rates) = p.position_lr {
            config.lr_position = rates;
        }
        if let Some(w) = &config.wrapper {
            config.densify_until = config.densify_until.min(w.start);
        }
        config.background = self.background;
        config.seed = t.seed;
        config.image_budget = t.image_budget_mib.saturating_mul(1 << 20);
        config.densify.max_gaussians = p.max_gaussians;
        Ok(PlainTraining { init_ply: p.init_ply.clone(), config, quality: p.quality })
    }
}

/// How the command line spells the encoding argument `id` (`--max-gaussians` for `max_gaussians`).
fn spelling(id: &str) -> String {
    let command = crate::Cli::command();
    let long = command.get_arguments().find(|a| a.get_id() == id).and_then(|a| a.get_long());
    long.map_or_else(|| id.to_string(), |l| format!("--{l}"))
}

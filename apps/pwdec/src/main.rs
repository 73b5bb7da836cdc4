//! `pwdec`: the pwgs decoder's command line. Decodes a stream with the decoder library and
//! renders views from camera files or a dataset's cameras, exports the Gaussians as a PLY or
//! an SPZ, or prints what a stream holds.

use pwgs_render::show::SceneRender;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use pwgs_codec::anchor::AnchorModel;
use pwgs_codec::scene::{Base, Scene};
use pwgs_codec::stream;
use pwgs_codec::stream::header::Header;
use pwgs_codec::wrapper::residual_picture;
use pwgs_core::atomic_file::write_atomically;
use pwgs_core::camera::Camera;
use pwgs_core::camera_json::parse_camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::say;
use pwgs_core::splat_file::{SpzVersion, gaussians_to_spz_bytes};
use pwgs_dataset::{LoadOptions, SceneViews, ViewSplit, load_cameras};
use pwgs_render::anchor_export::{agreement_psnr, export_gaussians, sphere_cameras};

#[derive(Parser)]
#[command(
    name = "pwdec",
    version,
    about = "pwgs decoder: renders views of a pwgs stream, exports it as PLY, prints its contents",
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    decode: DecodeArgs,
}

#[derive(Subcommand)]
enum Command {
    /// Print the stream's version, header and section sizes (verifies every CRC; decodes
    /// nothing else).
    Info { stream: PathBuf },
}

#[derive(Args)]
struct DecodeArgs {
    /// The stream (.pwb).
    #[arg(required = true)]
    stream: Option<PathBuf>,
    /// Render the view described by this camera file (see SPEC.md annex A) to -o.
    #[arg(long, requires = "output", conflicts_with = "views")]
    view: Option<PathBuf>,
    /// Render the cameras of this scene folder (COLMAP, transforms.json or LLFF) into the folder
    /// -o, one PNG per view named after its image.
    #[arg(long, requires = "output")]
    views: Option<PathBuf>,
    /// Which views of --views to render: test, train or all.
    #[arg(long, default_value = "test")]
    split: ViewSplit,
    /// Image downscale of --views (as at encoding, e.g. 8 for fern at 504x378).
    #[arg(long, default_value_t = 1)]
    downscale: u32,
    /// Output PNG (--view) or folder (--views).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Write the decoded Gaussians as an INRIA PLY. An anchor base is turned into standard
    /// Gaussians with SH colors of degree 3, fitted over --fit-views (or cameras on a sphere
    /// around the scene), and the PSNR of the export against the anchor renders is printed.
    #[arg(long)]
    export_ply: Option<PathBuf>,
    /// Write the decoded Gaussians (exported as for --export-ply) as a Niantic SPZ file,
    /// version 3, in the RUB axes the format specifies: positions to 1/4096 (fewer fractional
    /// bits where a coordinate needs them), rotations as "smallest three", the other values in
    /// 8 bits, which viewers of the format open.
    #[arg(long)]
    export_spz: Option<PathBuf>,
    /// With --export-ply or --export-spz of an anchor base: fit the colors over this scene
    /// folder's training cameras (at --downscale), as the encoder saw them.
    #[arg(long)]
    fit_views: Option<PathBuf>,
    /// Show the base render only, without the perceptual wrapper the stream carries.
    #[arg(long)]
    no_wrapper: bool,
    /// With --view: also write the wrapper's residual R as an image (0.5 + R: mid-gray where
    /// the wrapper changes nothing).
    #[arg(long, requires = "view", conflicts_with = "no_wrapper")]
    residual: Option<PathBuf>,
    /// Print the SHA-256 of the decoded attributes (equal hashes: bit-identical decoding).
    #[arg(long)]
    hash: bool,
    /// Worker threads (default: all cores). The output does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Refuse views larger than this many pixels. A wrapped render peaks at about 50 bytes per
    /// pixel plus its tile lists, which grow with the scene (measured on a 7070-Gaussian stream
    /// at 4096 x 3072), so the default, 8192 x 8192, needs some 3 GiB or more.
    #[arg(long, default_value_t = 1 << 26)]
    max_pixels: u64,
}

fn main() -> ExitCode {
    pwgs_cli::report(run(Cli::parse()))
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Some(Command::Info { stream }) => info(&stream),
        None => decode(cli.decode),
    }
}

fn read_stream(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))
}

fn info(path: &Path) -> Result<()> {
    let bytes = read_stream(path)?;
    let lines =
        stream::describe::describe(&bytes).with_context(|| format!("{} is not a valid stream", path.display()))?;
    say!("stream        {} ({} bytes)", path.display(), bytes.len());
    for line in lines {
        say!("{line}");
    }
    Ok(())
}

fn decode(args: DecodeArgs) -> Result<()> {
    let exports = args.export_ply.is_some() || args.export_spz.is_some();
    if args.view.is_none() && args.views.is_none() && !exports && !args.hash {
        bail!("nothing to do: give --view, --views, --export-ply, --export-spz or --hash (or run `pwdec info STREAM`)");
    }
    if args.fit_views.is_some() && !exports {
        bail!("--fit-views applies to --export-ply and --export-spz, and neither is given");
    }
    if let Some(threads) = args.threads {
        rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build_global().context("cannot start threads")?;
    }
    let path = args.stream.as_deref().expect("clap requires the stream");
    let bytes = read_stream(path)?;
    let start = Instant::now();
    let decoded = stream::decode(&bytes).with_context(|| format!("cannot decode {}", path.display()))?;
    let scene = &decoded.scene;
    eprintln!("decoded {} Gaussians in {:.3} s", scene.gaussian_count(), start.elapsed().as_secs_f64());
    if args.residual.is_some() && scene.wrapper.is_none() {
        bail!("--residual: {} has no perceptual wrapper", path.display());
    }
    let wrapped = !args.no_wrapper;
    if args.hash {
        say!("{}", scene.attribute_hash());
    }
    if exports {
        let exported;
        let gaussians = match &scene.base {
            Base::Plain(g) => g,
            Base::Anchors(model) => {
                exported = export_anchors(model, &decoded.header, args.fit_views.as_deref(), args.downscale, scene)?;
                &exported
            }
        };
        if let Some(ply) = &args.export_ply {
            pwgs_core::ply::write_gaussians(ply, gaussians)?;
            eprintln!("wrote {}", ply.display());
        }
        if let Some(spz) = &args.export_spz {
            let bytes = gaussians_to_spz_bytes(gaussians, SpzVersion::V3);
            write_atomically(spz, &bytes).with_context(|| format!("cannot write {}", spz.display()))?;
            eprintln!("wrote {} ({} bytes, SPZ version 3)", spz.display(), bytes.len());
        }
    }
    if let Some(view) = &args.view {
        let text = std::fs::read_to_string(view).with_context(|| format!("cannot read {}", view.display()))?;
        let camera = parse_camera(&text).with_context(|| format!("{}: bad camera", view.display()))?;
        let out = args.output.as_deref().expect("clap requires -o");
        render_to(scene, wrapped, &camera, args.max_pixels, out, args.residual.as_deref())?;
    }
    if let Some(folder) = &args.views {
        let out = args.output.as_deref().expect("clap requires -o");
        let dataset = SceneViews { scene: folder.clone(), split: args.split, downscale: args.downscale };
        render_dataset(scene, wrapped, &dataset, args.max_pixels, out)?;
    }
    Ok(())
}

/// Renders one view (through the wrapper, if any, when `wrapped`) to `out`, and the residual
/// to `residual`.
fn render_to(
    scene: &Scene,
    wrapped: bool,
    camera: &Camera,
    max_pixels: u64,
    out: &Path,
    residual: Option<&Path>,
) -> Result<()> {
    let pixels = u64::from(camera.width) * u64::from(camera.height);
    if pixels > max_pixels {
        bail!(
            "{}: the view is {}x{} = {pixels} pixels, more than --max-pixels {max_pixels}",
            out.display(),
            camera.width,
            camera.height
        );
    }
    let start = Instant::now();
    let shown = scene.render(camera, &scene.render_options(), wrapped).with_context(|| out.display().to_string())?;
    shown.image.save_png(out)?;
    if let (Some(path), Some(r)) = (residual, shown.residual) {
        residual_picture(&r, camera.width, camera.height).save_png(path)?;
        eprintln!("wrote {}", path.display());
    }
    eprintln!("wrote {} ({}x{}) in {:.3} s", out.display(), camera.width, camera.height, start.elapsed().as_secs_f64());
    Ok(())
}

/// Standard Gaussians for an anchor base, fitted over the training cameras of `fit_views` or
/// over 64 cameras on a sphere of the scene's scale; prints how faithful they are.
fn export_anchors(
    model: &AnchorModel,
    header: &Header,
    fit_views: Option<&Path>,
    downscale: u32,
    scene: &Scene,
) -> Result<Gaussians> {
    // Fitted over the training cameras, checked on the test cameras when there are any.
    let (cameras, checked): (Vec<Camera>, Vec<Camera>) = match fit_views {
        Some(folder) => {
            let options = LoadOptions { downscale, ..Default::default() };
            let data = load_cameras(folder, &options)
                .with_context(|| format!("cannot load the scene {}", folder.display()))?;
            let train: Vec<Camera> = data.train.iter().map(|v| v.camera).collect();
            let test: Vec<Camera> = data.test.iter().map(|v| v.camera).collect();
            let checked = if test.is_empty() { train.iter().take(8).copied().collect() } else { test };
            (train, checked)
        }
        None => {
            let sphere = sphere_cameras(header.center, header.scale, 64, 256);
            let checked = sphere_cameras(header.center, header.scale * 1.1, 8, 256);
            (sphere, checked)
        }
    };
    if cameras.is_empty() {
        bail!("--export-ply/--export-spz: no cameras to fit the anchor base's colors over");
    }
    let export = export_gaussians(model, &cameras);
    let psnr = agreement_psnr(model, &export, &checked, &scene.render_options());
    eprintln!(
        "exported {} Gaussians (SH degree 3) from {} anchors, fitted over {} views; PSNR {psnr:.2} dB against the \
         anchor renders of {} other views",
        export.len(),
        model.len(),
        cameras.len(),
        checked.len()
    );
    if fit_views.is_none() {
        eprintln!(
            "(those views are on a sphere around the scene's center and may see little of a forward-facing capture: \
             --fit-views SCENE_DIR fits and checks over the capture's own cameras)"
        );
    }
    Ok(export)
}

fn render_dataset(scene: &Scene, wrapped: bool, views: &SceneViews, max_pixels: u64, out: &Path) -> Result<()> {
    let views = views.cameras().with_context(|| format!("cannot load the scene {}", views.scene.display()))?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    for view in views {
        render_to(scene, wrapped, &view.camera, max_pixels, &out.join(format!("{}.png", view.stem())), None)?;
    }
    Ok(())
}

//! `pwplay`: opens a stream in the player's window, or renders one view headless.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::Parser;
use pwgs_cli::values::parse_vector;
use pwgs_player::app::{PlayerOptions, run};
use pwgs_player::headless::screenshot;
use pwgs_player::view_mode::{Renderer, ViewMode};

/// The interactive player of pwgs streams (GPU rendering through wgpu; without a GPU, Mesa's
/// lavapipe works).
#[derive(Parser)]
#[command(name = "pwplay", version)]
struct Args {
    /// The stream to open (or open one from the window, or drop it on the window).
    stream: Option<PathBuf>,
    /// The dataset the stream was encoded from: its cameras to snap to, with their ground truth.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Image downscale of --scene, as at encoding (e.g. 8 for fern at 504x378).
    #[arg(long, default_value_t = 1)]
    downscale: u32,
    /// The world's up of the free camera, `x,y,z` (COLMAP captures: 0,-1,0; Blender and
    /// nerfstudio ones: 0,0,1; pwenc's generated scene: 0,1,0); the window can change it.
    #[arg(long, default_value = "0,-1,0", value_parser = parse_vector)]
    up: [f32; 3],
    /// Headless: the camera (JSON, SPEC.md annex A) of the view to render to --screenshot.
    #[arg(long, requires = "screenshot")]
    view: Option<PathBuf>,
    /// Headless with --view: the PNG to write. Without --view: a screenshot of the whole
    /// window once the first view is shown, after which the window closes.
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// Headless: the base render, without the wrapper.
    #[arg(long, requires = "view", conflicts_with = "residual")]
    no_wrapper: bool,
    /// Headless: the wrapper's residual R, as 0.5 + 4 R.
    #[arg(long, requires = "view")]
    residual: bool,
    /// Headless: after the screenshot, render the view this many times more and print the
    /// median time of each stage and the frame rate.
    #[arg(long, requires = "view", default_value_t = 0)]
    frames: u32,
    /// What renders the pictures: `auto` is the GPU unless its adapter is a software rasterizer
    /// (then the CPU renderer, faster on the same cores, with the wrapper's network on the CPU
    /// too); the window stays on wgpu.
    #[arg(long, value_enum, default_value_t = Renderer::Auto)]
    renderer: Renderer,
}

fn main() -> ExitCode {
    pwgs_cli::report(start(Args::parse()))
}

fn start(args: Args) -> Result<()> {
    if let (Some(view), Some(out)) = (&args.view, &args.screenshot) {
        let Some(stream) = &args.stream else { bail!("--view renders a stream: give its path") };
        let mode = match (args.no_wrapper, args.residual) {
            (true, _) => ViewMode::Base,
            (_, true) => ViewMode::Residual,
            _ => ViewMode::Shown,
        };
        return screenshot(stream, view, mode, args.renderer, out, args.frames);
    }
    run(PlayerOptions {
        stream: args.stream,
        scene: args.scene,
        downscale: args.downscale,
        up: glam::Vec3::from(args.up),
        window_screenshot: args.screenshot,
        renderer: args.renderer,
    })
}

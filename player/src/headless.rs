//! `pwplay STREAM --view CAM --screenshot OUT`: one picture through the player's render path,
//! without a window, for scripts and tests.

use std::path::Path;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use pwgs_core::camera_json::parse_camera;
use pwgs_render::gpu::{GpuRenderer, StageTimes};

use crate::loaded::LoadedStream;
use crate::view_mode::{Painter, Renderer, ViewMode, picture};

/// Gain of the residual picture: R is a few hundredths, 4x makes it visible.
pub const RESIDUAL_GAIN: f32 = 4.0;

/// Renders `mode`'s picture of the view in the camera file `view` to the PNG `out`, then, when
/// `frames` > 0, renders it `frames` times more and prints the median time of each stage and
/// the frame rate they allow (the first picture pays for shader compilation, so it is not
/// counted).
pub fn screenshot(
    stream: &Path,
    view: &Path,
    mode: ViewMode,
    renderer: Renderer,
    out: &Path,
    frames: u32,
) -> Result<()> {
    let text = std::fs::read_to_string(view).with_context(|| format!("cannot read {}", view.display()))?;
    let camera = parse_camera(&text).with_context(|| format!("{}: bad camera", view.display()))?;
    let loaded = LoadedStream::open(stream)?;
    if mode.needs_wrapper() && loaded.scene.wrapper.is_none() {
        bail!("{}: the stream has no perceptual wrapper to show the {} of", stream.display(), mode.label());
    }
    let gpu = GpuRenderer::new()?;
    let prepared;
    let painter = if renderer.on_cpu(&gpu) {
        Painter::Cpu
    } else {
        prepared = gpu.prepare(&loaded.scene)?;
        Painter::Gpu(&gpu, &prepared)
    };
    let (image, times) = picture(painter, &loaded.scene, &camera, mode, RESIDUAL_GAIN)?;
    image.save_png(out).with_context(|| format!("cannot write {}", out.display()))?;
    eprintln!(
        "wrote {} ({}x{}, {}) on {}: {}",
        out.display(),
        camera.width,
        camera.height,
        mode.label(),
        renderer.describe(&gpu),
        describe_times(&times)
    );
    if frames > 0 {
        let mut all = Vec::with_capacity(frames as usize);
        for _ in 0..frames {
            all.push(picture(painter, &loaded.scene, &camera, mode, RESIDUAL_GAIN)?.1);
        }
        print_frame_rate(&all);
    }
    Ok(())
}

/// Each stage's time in milliseconds, on one line.
pub fn describe_times(t: &StageTimes) -> String {
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    format!(
        "{:.1} ms: Gaussians {:.1}, projection {:.1}, readback, sort and binning {:.1}; raster {:.1}, synthesis {:.1}, readback {:.1}",
        ms(t.total()),
        ms(t.gaussians),
        ms(t.projection),
        ms(t.sort),
        ms(t.raster),
        ms(t.synthesis),
        ms(t.readback)
    )
}

/// Each stage's median over `times`, and the frames per second of the median total.
fn print_frame_rate(times: &[StageTimes]) {
    let median = |stage: fn(&StageTimes) -> Duration| {
        let mut v: Vec<Duration> = times.iter().map(stage).collect();
        v.sort();
        v[v.len() / 2]
    };
    let stages = StageTimes {
        gaussians: median(|t| t.gaussians),
        projection: median(|t| t.projection),
        sort: median(|t| t.sort),
        raster: median(|t| t.raster),
        synthesis: median(|t| t.synthesis),
        readback: median(|t| t.readback),
    };
    let total = median(StageTimes::total).as_secs_f64();
    println!(
        "{} frames: median {:.2} ms a frame ({:.1} frames/s); stage medians {}",
        times.len(),
        total * 1e3,
        1.0 / total,
        describe_times(&stages)
    );
}

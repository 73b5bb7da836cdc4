//! `pwplay STREAM --view CAM --screenshot OUT`: one picture through the player's GPU path,
//! without a window, for scripts and tests.

use std::path::Path;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use pwgs_decoder::camera_json::parse_camera;
use pwgs_decoder::gpu::{GpuRenderer, StageTimes};

use crate::loaded::LoadedStream;
use crate::view_mode::{ViewMode, picture};

/// Gain of the residual picture: R is a few hundredths, 4x makes it visible.
pub const RESIDUAL_GAIN: f32 = 4.0;

/// Renders `mode`'s picture of the view in the camera file `view` to the PNG `out`, then, when
/// `frames` > 0, renders it `frames` times more and prints the median time of each stage and
/// the frame rate they allow (the first picture pays for shader compilation, so it is not
/// counted).
pub fn screenshot(stream: &Path, view: &Path, mode: ViewMode, out: &Path, frames: u32) -> Result<()> {
    let text = std::fs::read_to_string(view).with_context(|| format!("cannot read {}", view.display()))?;
    let camera = parse_camera(&text).with_context(|| format!("{}: bad camera", view.display()))?;
    let loaded = LoadedStream::open(stream)?;
    if mode.needs_wrapper() && loaded.scene.wrapper.is_none() {
        bail!("{}: the stream has no perceptual wrapper to show the {} of", stream.display(), mode.label());
    }
    let gpu = GpuRenderer::new()?;
    let (image, times) = picture(&gpu, &loaded.scene, &camera, mode, RESIDUAL_GAIN)?;
    image.save_png(out).with_context(|| format!("cannot write {}", out.display()))?;
    eprintln!(
        "wrote {} ({}x{}, {}) on {}: prepare {:.1} ms, raster {:.1} ms, synthesis {:.1} ms",
        out.display(),
        camera.width,
        camera.height,
        mode.label(),
        gpu.adapter_name(),
        times.prepare.as_secs_f64() * 1e3,
        times.raster.as_secs_f64() * 1e3,
        times.synthesis.as_secs_f64() * 1e3
    );
    if frames > 0 {
        let mut all = Vec::with_capacity(frames as usize);
        for _ in 0..frames {
            all.push(picture(&gpu, &loaded.scene, &camera, mode, RESIDUAL_GAIN)?.1);
        }
        print_frame_rate(&all);
    }
    Ok(())
}

/// The median of each stage over `times`, and the frames per second of their sum's median.
fn print_frame_rate(times: &[StageTimes]) {
    let median = |stage: fn(&StageTimes) -> Duration| {
        let mut v: Vec<Duration> = times.iter().map(stage).collect();
        v.sort();
        v[v.len() / 2].as_secs_f64() * 1e3
    };
    let total = median(|t| t.prepare + t.raster + t.synthesis + t.readback);
    println!(
        "{} frames: median {total:.2} ms a frame ({:.1} frames/s): prepare {:.2} ms, raster {:.2} ms, \
         synthesis {:.2} ms, readback {:.2} ms",
        times.len(),
        1e3 / total,
        median(|t| t.prepare),
        median(|t| t.raster),
        median(|t| t.synthesis),
        median(|t| t.readback)
    );
}

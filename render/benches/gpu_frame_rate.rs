//! GPU renderer benchmark (feature `gpu`): frame time of each stage and frames per second for
//! random scenes of 10k, 100k and 1M Gaussians at 1600x1063, without and with a width-16
//! wrapper, against the CPU reference's time for the same picture and the largest difference
//! between the two (speed against error). Run with
//! `cargo bench -p pwgs-render --features gpu --bench gpu_frame_rate` (add `-- --quick` for
//! 10k and 100k at 800x532). It renders on the first adapter wgpu offers (lavapipe where there
//! is no GPU): report the figures with the adapter it prints.

use pwgs_render::show::SceneRender;
use std::time::{Duration, Instant};

use pwgs_codec::random_scene::wrapped_random_scene;
use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};
use pwgs_render::gpu::{GpuRenderer, Output, StageTimes};

/// Frames timed per case, after one untimed warm-up frame (shader compilation, first uploads).
const FRAMES: usize = 5;

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let gpu = match GpuRenderer::new() {
        Ok(gpu) => gpu,
        Err(e) => {
            eprintln!("no GPU adapter: {e}");
            std::process::exit(1);
        }
    };
    let (width, height) = if quick { (800, 532) } else { (1600, 1063) };
    let counts: &[usize] = if quick { &[10_000, 100_000] } else { &[10_000, 100_000, 1_000_000] };
    println!("adapter: {}; {width}x{height}; median of {FRAMES} frames", gpu.adapter_name());
    println!(
        "| Gaussians | upload ms | wrapper | projection ms | readback+sort+binning ms | raster ms | synthesis ms | readback ms | frame ms | frames/s | CPU ms | CPU/GPU | max abs diff |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let camera =
        axis_camera(width, height, 0.9 * width as f32, 0.9 * width as f32, 0.5 * width as f32, 0.5 * height as f32);
    for &n in counts {
        let mut rng = SplitMix64(n as u64);
        // Smaller splats for more Gaussians, so that every count covers the view alike.
        let shrink = 0.5 * (n as f32 / 10_000.0).log10();
        let gaussians = random_gaussians(&mut rng, n, 3, [-4.5 - shrink, -2.5 - shrink]);
        let scene = wrapped_random_scene(&mut rng, gaussians, [0.1, 0.1, 0.1]);
        let options = scene.render_options();
        let start = Instant::now();
        let prepared = gpu.prepare(&scene).expect("uploads");
        let upload_ms = start.elapsed().as_secs_f64() * 1e3;
        for output in [Output::Base, Output::Shown] {
            let wrapped = output == Output::Shown;
            let _ = gpu.render(&scene, &prepared, &camera, &options, output).expect("renders");
            let mut times: Vec<StageTimes> = Vec::with_capacity(FRAMES);
            let mut last = None;
            for _ in 0..FRAMES {
                let (shown, t) = gpu.render(&scene, &prepared, &camera, &options, output).expect("renders");
                times.push(t);
                last = Some(shown);
            }
            let median = |stage: fn(&StageTimes) -> Duration| {
                let mut v: Vec<Duration> = times.iter().map(stage).collect();
                v.sort();
                v[v.len() / 2].as_secs_f64() * 1e3
            };
            let start = Instant::now();
            let cpu = scene.render(&camera, &options, wrapped).expect("within the CPU work limit");
            let cpu_ms = start.elapsed().as_secs_f64() * 1e3;
            let gpu_image = last.expect("frames were rendered").image;
            let max = cpu.image.data.iter().zip(&gpu_image.data).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
            let frame = median(StageTimes::total);
            println!(
                "| {n} | {upload_ms:.0} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {frame:.1} | {:.2} | {cpu_ms:.0} | {:.2} | {max:.1e} |",
                if wrapped { "on" } else { "off" },
                median(|t| t.gaussians + t.projection),
                median(|t| t.sort),
                median(|t| t.raster),
                median(|t| t.synthesis),
                median(|t| t.readback),
                1e3 / frame,
                cpu_ms / frame,
            );
        }
    }
}

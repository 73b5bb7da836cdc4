//! Training throughput per device, on Burn's CPU backend and, in a build with `--features gpu`,
//! on the first wgpu adapter (a software rasterizer only with `PWGS_ALLOW_SOFTWARE_GPU=1`):
//!
//! - stage 1: whole training steps of each base (render, loss, backward, Adam; densification
//!   and anchor growth off, so the count stays put) on a generated scene of 500k points at
//!   1008x756 and one of 1M points at 1600x1063, and on `--scene DIR` (for example fern with
//!   `--downscale 4`, 1008x756) when given;
//! - stage 2 without the splat operation (f and WD on VGG16 features, forward, backward and
//!   Adam; see `pwgs_encoder::wrapper::throughput`) at 1008x756 with the default 128-pixel
//!   crops and with whole images, and whole images at 1600x1063.
//!
//! Prints the device's name, the first step's time (kernel compilation, the target's
//! features), steps per second after it and the device memory reserved. Run with `cargo bench
//! -p pwgs-encoder --bench training_device [--features gpu] [-- --quick] [--gpu-steps N]
//! [--scene DIR --downscale N]` (`--quick`: the smallest case of each stage; `--gpu-steps`
//! replaces every case's GPU step count: 1 checks the GPU path on a software rasterizer;
//! `--gpu-only` skips the CPU device and `--crops-only` stage 2 on whole images, for a short
//! lease of a GPU machine; `--cases plain,anchor,stage2,generated` runs only the cases named:
//! the bases' stage 1, stage 2's networks, and the generated scenes beside `--scene`, for
//! `scripts/profile_kernels.sh`).
//! Timings depend on the machine: report them with it.
//!
//! `-- --memory` instead measures, on the GPU device only, the memory one stage-1 step of each
//! base reserves at 1600x1063 for two scene sizes, and extrapolates linearly to 1M Gaussians
//! (plain) or 100k anchors (1M neural Gaussians), adding 300 views' images.

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_dataset::{Dataset, LoadOptions, load_scene};
use pwgs_encoder::anchor::init::{AnchorShape, initial_model};
use pwgs_encoder::anchor::train::AnchorTrainer;
use pwgs_encoder::plain::init::initial_gaussians;
use pwgs_encoder::plain::train::{TrainConfig, Trainer};
use pwgs_encoder::train::device::{StepTrace, TrainingDevice};
use pwgs_encoder::wrapper::throughput::stage_two_throughput;

/// A stage-2 measurement: view size, crop side, steps timed on the CPU and on a GPU.
struct StageTwo {
    size: (u32, u32),
    crop: usize,
    cpu_steps: usize,
    gpu_steps: usize,
}

/// First step's seconds and steps per second after it. With `PWGS_TRACE_STEPS` set, each step
/// is also timed ([`StepTrace`]; a step reads its loss back, so it returns when the device is
/// done with it).
fn time_steps(steps: usize, mut step: impl FnMut() -> Result<()>, device: &TrainingDevice) -> Result<(f64, f64)> {
    let mut trace = StepTrace::from_env();
    let start = Instant::now();
    step()?;
    device.sync()?;
    trace.step(1);
    let first = start.elapsed().as_secs_f64();
    let start = Instant::now();
    for k in 2..steps as u32 + 2 {
        step()?;
        trace.step(k);
    }
    device.sync()?;
    Ok((first, steps as f64 / start.elapsed().as_secs_f64()))
}

fn mib(bytes: u64) -> String {
    format!("{:.0} MiB", bytes as f64 / (1 << 20) as f64)
}

fn memory(device: &TrainingDevice) -> String {
    device.bytes_reserved().map_or("not reported".to_string(), mib)
}

/// A base's stage-1 steps on a scene: the Gaussians or anchors, the first step's seconds and
/// steps per second after it.
type StageOneSteps = fn(&Dataset, usize, &TrainingDevice) -> Result<(usize, f64, f64)>;

/// Plain 3DGS from the scene's points, densification off.
fn plain_steps(data: &Dataset, steps: usize, device: &TrainingDevice) -> Result<(usize, f64, f64)> {
    let initial = initial_gaussians(data, 0, usize::MAX)?;
    let mut config = TrainConfig::for_iterations(steps as u32 + 1);
    config.densify_until = 0;
    let mut trainer = Trainer::new(config, data, &initial, device.device.clone())?;
    let (first, rate) = time_steps(steps, || trainer.step().map(|_| ()), device)?;
    Ok((initial.len(), first, rate))
}

/// The anchor base at its defaults (32 features, 10 offsets, voxel 0.01 of the scene scale),
/// rate term off, growth off.
fn anchor_steps(data: &Dataset, steps: usize, device: &TrainingDevice) -> Result<(usize, f64, f64)> {
    let points = data.points.as_ref().ok_or_else(|| anyhow::anyhow!("the scene has no points"))?;
    let shape = AnchorShape { feature_dim: 32, offsets_per_anchor: 10, voxel: 0.01 * data.normalization.scale };
    let (initial, _) = initial_model(points, shape, 0)?;
    let mut trainer = AnchorTrainer::new(&initial, data, steps as u32 + 1, [0.0; 3], 0, &device.device)?;
    let (first, rate) = time_steps(steps, || trainer.step().map(|_| ()), device)?;
    Ok((initial.len(), first, rate))
}

fn generated(dir: &Path, (width, height): (u32, u32), points: usize, views: usize) -> Result<Dataset> {
    generate(dir, &SyntheticOptions { width, height, views, seed: 1, points })?;
    Ok(load_scene(dir, &LoadOptions::default())?)
}

/// Memory reserved by one stage-1 step of each base at 1600x1063 on `device` (views are
/// uploaded when first drawn, so one view's image is resident) for two scene sizes, and the
/// estimate for 1M Gaussians (plain) or 100k anchors (anchor base, 10 neural Gaussians each)
/// with 300 views: the fit's slope per Gaussian or anchor, plus every view's image (f32) on top
/// of the measured figure, which already holds one.
fn memory_scaling(device: &TrainingDevice, dir: &Path) -> Result<()> {
    const POINTS: [usize; 2] = [50_000, 100_000];
    const VIEWS: usize = 4;
    let (width, height) = (1600u32, 1063u32);
    let image_bytes = (width * height * 3) as f64 * size_of::<f32>() as f64;
    let mut reserved = [[0.0; 2]; 2];
    let mut counts = [[0.0; 2]; 2];
    for (i, points) in POINTS.into_iter().enumerate() {
        let data = generated(&dir.join(format!("memory{i}")), (width, height), points, VIEWS)?;
        for (b, run) in [plain_steps as StageOneSteps, anchor_steps].into_iter().enumerate() {
            device.device.memory_cleanup();
            let (count, _, _) = run(&data, 0, device)?;
            let bytes = device.bytes_reserved().ok_or_else(|| anyhow::anyhow!("the device reports no memory"))?;
            (reserved[b][i], counts[b][i]) = (bytes as f64, count as f64);
            let what = ["Gaussians", "anchors"][b];
            println!("  memory {} {count} {what}, {width}x{height}: {} reserved", ["plain", "anchor"][b], mib(bytes));
        }
    }
    for (b, (target, what)) in [(1e6, "1M Gaussians"), (1e5, "100k anchors")].into_iter().enumerate() {
        let per_item = (reserved[b][1] - reserved[b][0]) / (counts[b][1] - counts[b][0]);
        let estimate = reserved[b][0] + per_item * (target - counts[b][0]) + image_bytes * 300.0;
        println!(
            "  estimate {}: {per_item:.0} bytes an item; {what} and 300 views' images: {}",
            ["plain", "anchor"][b],
            mib(estimate as u64)
        );
    }
    Ok(())
}

/// Stage-1 steps of both bases on `data` on each device, a line each.
fn stage_one(
    devices: &[TrainingDevice],
    (name, data): (&str, &Dataset),
    cases: &[&str],
    steps_of: &dyn Fn(&TrainingDevice, usize, usize) -> usize,
) {
    let image = &data.train[0].image;
    for device in devices {
        let steps = steps_of(device, 1, 30);
        for (base, run) in [("plain", plain_steps as StageOneSteps), ("anchor", anchor_steps)] {
            if !cases.contains(&base) {
                continue;
            }
            match run(data, steps, device) {
                Ok((count, first, rate)) => println!(
                    "  {}: stage 1 {base} on {name} ({}x{}, {count} {}): first step {first:.2} s, {rate:.2} it/s over {steps}, device memory reserved {}",
                    device.name,
                    image.width,
                    image.height,
                    if base == "plain" { "Gaussians" } else { "anchors" },
                    memory(device)
                ),
                Err(e) => println!("  {}: stage 1 {base} on {name}: failed: {e:#}", device.name),
            }
        }
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let value = |flag: &str| args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1));
    let quick = args.iter().any(|a| a == "--quick");
    let gpu_steps: Option<usize> = value("--gpu-steps").and_then(|n| n.parse().ok());
    let allow_software = std::env::var("PWGS_ALLOW_SOFTWARE_GPU").is_ok_and(|v| v == "1");
    let mut devices = if args.iter().any(|a| a == "--gpu-only") { vec![] } else { vec![TrainingDevice::cpu()] };
    match TrainingDevice::gpu(allow_software) {
        Ok(gpu) => devices.push(gpu),
        Err(e) => println!("no GPU device: {e:#}"),
    }

    let tmp = tempfile::tempdir()?;
    if args.iter().any(|a| a == "--memory") {
        let gpu = devices.iter().find(|d| d.gpu).ok_or_else(|| anyhow::anyhow!("--memory measures a GPU device"))?;
        println!("device: {}", gpu.name);
        return memory_scaling(gpu, tmp.path());
    }
    for device in &devices {
        println!("device: {}", device.name);
    }
    let cases: Vec<&str> =
        value("--cases").map_or(vec!["plain", "anchor", "stage2", "generated"], |v| v.split(',').collect());
    let steps_of = |device: &TrainingDevice, cpu: usize, gpu: usize| {
        if device.gpu { gpu_steps.unwrap_or(gpu) } else { cpu }
    };
    // The given scene first, then stage 2, then the generated scenes (slowest to make), each
    // made just before its cases run: a run cut short by a time limit has printed every case
    // it finished.
    if let Some(scene) = value("--scene") {
        let downscale = value("--downscale").and_then(|n| n.parse().ok()).unwrap_or(1);
        let data = load_scene(Path::new(scene), &LoadOptions { downscale, ..Default::default() })?;
        stage_one(&devices, (scene, &data), &cases, &steps_of);
    }
    let mut stage_two = Vec::new();
    if cases.contains(&"stage2") {
        stage_two.push(StageTwo { size: (1008, 756), crop: 128, cpu_steps: 3, gpu_steps: 50 });
    }
    if cases.contains(&"stage2") && !quick && !args.iter().any(|a| a == "--crops-only") {
        stage_two.push(StageTwo { size: (1008, 756), crop: 1008, cpu_steps: 1, gpu_steps: 20 });
        stage_two.push(StageTwo { size: (1600, 1063), crop: 1600, cpu_steps: 0, gpu_steps: 10 });
    }
    for case in &stage_two {
        for device in &devices {
            let steps = steps_of(device, case.cpu_steps, case.gpu_steps);
            if steps == 0 {
                continue;
            }
            let (w, h) = case.size;
            let what = if case.crop >= w.max(h) as usize {
                "whole image".to_string()
            } else {
                format!("{0}x{0} crops", case.crop)
            };
            match stage_two_throughput(device, case.size, case.crop, steps) {
                Ok(t) => println!(
                    "  {}: stage 2 (f + WD, no splat) {w}x{h}, {what}: first step {:.2} s, {:.2} steps/s over {steps}, device memory reserved {}",
                    device.name,
                    t.first_step_seconds,
                    t.steps_per_second,
                    t.bytes_reserved.map_or("not reported".to_string(), mib)
                ),
                Err(e) => println!("  {}: stage 2 {w}x{h}, {what}: failed: {e:#}", device.name),
            }
        }
    }
    let sizes: &[((u32, u32), usize)] =
        if quick { &[((1008, 756), 500_000)] } else { &[((1008, 756), 500_000), ((1600, 1063), 1_000_000)] };
    for (i, &(size, points)) in sizes.iter().enumerate().filter(|_| cases.contains(&"generated")) {
        let data = generated(&tmp.path().join(i.to_string()), size, points, 8)?;
        let name = format!("generated {}x{}, {points} points", size.0, size.1);
        stage_one(&devices, (&name, &data), &cases, &steps_of);
    }
    Ok(())
}

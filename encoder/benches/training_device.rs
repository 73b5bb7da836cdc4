//! Training throughput per device: stage 2's steps without the splat operation (f and WD on
//! VGG16 features, forward, backward and Adam; see `pwgs_encoder::wrapper::throughput`) at
//! fern's 1008x756 with the default 128-pixel crops and with whole images, and whole images at
//! 1600x1063, on Burn's CPU backend and, in a build with `--features gpu`, on the first wgpu
//! adapter (a software rasterizer only with `PWGS_ALLOW_SOFTWARE_GPU=1`). Prints the device's
//! name, the first step's time (kernel compilation and the target's features), steps per
//! second after it and the device memory reserved. Run with `cargo bench -p pwgs-encoder
//! --bench training_device [--features gpu] [-- --quick] [--gpu-steps N]` (`--gpu-steps`
//! replaces every case's GPU step count: 1 checks the GPU path on a software rasterizer);
//! timings depend on the machine: report them with it.

use pwgs_encoder::train::device::TrainingDevice;
use pwgs_encoder::wrapper::throughput::stage_two_throughput;

/// One measurement: view size, crop side, steps timed on the CPU and on a GPU.
struct Case {
    size: (u32, u32),
    crop: usize,
    cpu_steps: usize,
    gpu_steps: usize,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let gpu_steps: Option<usize> =
        args.iter().position(|a| a == "--gpu-steps").and_then(|i| args.get(i + 1)).and_then(|n| n.parse().ok());
    let allow_software = std::env::var("PWGS_ALLOW_SOFTWARE_GPU").is_ok_and(|v| v == "1");
    let mut devices = vec![TrainingDevice::cpu()];
    match TrainingDevice::gpu(allow_software) {
        Ok(gpu) => devices.push(gpu),
        Err(e) => println!("no GPU device: {e:#}"),
    }
    let mut cases = vec![Case { size: (1008, 756), crop: 128, cpu_steps: 3, gpu_steps: 50 }];
    if !quick {
        cases.push(Case { size: (1008, 756), crop: 1008, cpu_steps: 1, gpu_steps: 20 });
        cases.push(Case { size: (1600, 1063), crop: 1600, cpu_steps: 0, gpu_steps: 10 });
    }
    for device in &devices {
        println!("device: {}", device.name);
        for case in &cases {
            let steps = if device.gpu { gpu_steps.unwrap_or(case.gpu_steps) } else { case.cpu_steps };
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
                    "  stage 2 (f + WD, no splat) {w}x{h}, {what}: first step {:.2} s, {:.2} steps/s over {steps}, device memory reserved {}",
                    t.first_step_seconds,
                    t.steps_per_second,
                    t.bytes_reserved
                        .map_or("not reported".to_string(), |b| format!("{:.0} MiB", b as f64 / (1 << 20) as f64)),
                ),
                Err(e) => println!("  stage 2 {w}x{h}, {what}: failed: {e:#}"),
            }
        }
    }
}

//! Training on the GPU (feature `gpu`, `--device gpu`) end to end: each base with the
//! perceptual wrapper trains on the adapter, its stream decodes, and what a decoder shows
//! lands within 0.5 dB of the CPU run with the same settings. Mesa's lavapipe is accepted
//! (`PWGS_ALLOW_SOFTWARE_GPU=1`); without any adapter these tests skip, saying so, unless
//! `PWGS_REQUIRE_GPU` is set (CI installs lavapipe and sets it).
#![cfg(feature = "gpu")]

use std::path::Path;
use std::process::Command;

use pwgs_encoder::train::device::TrainingDevice;

fn adapter() -> Option<String> {
    match TrainingDevice::gpu(true) {
        Ok(d) => Some(d.name),
        Err(e) if std::env::var_os("PWGS_REQUIRE_GPU").is_some() => panic!("PWGS_REQUIRE_GPU is set: {e}"),
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
}

fn pwenc(args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_pwenc"))
        .args(args)
        .env("PWGS_ALLOW_SOFTWARE_GPU", "1")
        .output()
        .expect("pwenc runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    eprintln!("{stderr}");
    let report = args.iter().position(|a| *a == "--report").map(|i| args[i + 1]).expect("a report");
    serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap()
}

/// Trains `base` with the wrapper on the CPU and on the GPU; both decoded streams' mean PSNR.
fn both_devices(base: &str) -> Option<(f64, f64)> {
    let gpu_name = adapter()?;
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let scene = dir("scene");
    let generated = Command::new(env!("CARGO_BIN_EXE_pwenc"))
        .args(["generate-scene", &scene, "--width", "64", "--height", "64", "--views", "8", "--points", "300"])
        .output()
        .unwrap();
    assert!(generated.status.success());
    let run = |device: &str| {
        let (stream, eval, report) = (dir(&format!("{device}.pwb")), dir(device), dir(&format!("{device}.json")));
        let args = [
            scene.as_str(),
            "--base",
            base,
            "--device",
            device,
            "--iters",
            "12",
            "--wrapper-crops-per-view",
            "2",
            "--wrapper-min-steps",
            "0",
            "--wd-features",
            "pixels",
            "--wd-crop",
            "64",
            "-o",
            &stream,
            "--eval",
            &eval,
            "--report",
            &report,
        ];
        let report = pwenc(&args);
        assert!(Path::new(&stream).is_file());
        report
    };
    let (cpu, gpu) = (run("cpu"), run("gpu"));
    assert_eq!(gpu["device"].as_str(), Some(gpu_name.as_str()), "the report names the adapter");
    assert!(cpu["device"].as_str().unwrap().contains("CPU"), "{}", cpu["device"]);
    let psnr = |r: &serde_json::Value| r["mean"]["psnr"].as_f64().unwrap();
    eprintln!("{base}: decoded PSNR {:.3} dB on the CPU, {:.3} dB on {gpu_name}", psnr(&cpu), psnr(&gpu));
    Some((psnr(&cpu), psnr(&gpu)))
}

/// Both bases in one test: two lavapipe runs at once on a 2-core machine take 3.6 times as long
/// as one after the other.
#[test]
fn both_bases_with_the_wrapper_train_on_the_gpu_like_on_the_cpu() {
    for base in ["3dgs", "anchor"] {
        let Some((cpu, gpu)) = both_devices(base) else { return };
        assert!((cpu - gpu).abs() <= 0.5, "{base}: CPU {cpu:.3} dB, GPU {gpu:.3} dB");
    }
}

//! `pweval` end to end on small folders: pairing by name, the JSON report, and the values the
//! library gives for the same files (PSNR and both SSIMs; the VGG metrics are covered by the
//! calibration tests).

use std::path::Path;
use std::process::Command;

use burn::tensor::Device;
use pwgs_core::rgb_image::RgbImage;
use pwgs_encoder::metrics::image_tensor::image_tensor;
use pwgs_encoder::metrics::psnr::psnr;
use pwgs_encoder::metrics::ssim::{SsimConvention, ssim};

fn image(width: u32, height: u32, phase: f32) -> RgbImage {
    let mut img = RgbImage::filled(width, height, [0.0; 3]);
    for y in 0..height {
        for x in 0..width {
            let v = |c: f32| 0.5 + 0.4 * (0.3 * x as f32 + 0.2 * y as f32 + c + phase).sin();
            img.set_pixel(x, y, [v(0.0), v(1.0), v(2.0)]);
        }
    }
    img
}

/// serde_json's default float parser is not exactly round-trip; beyond that, values must agree.
fn assert_close(json: &serde_json::Value, expected: f64, what: &str) {
    let value = json.as_f64().unwrap();
    assert!((value - expected).abs() <= 1e-12 * expected.abs(), "{what}: {value} vs {expected}");
}

fn run(a: &Path, b: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pweval")).arg(a).arg(b).args(extra).output().unwrap()
}

#[test]
fn folders_are_paired_by_name_and_reported_as_json() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    for (name, phase) in [("x.png", 0.3), ("y.png", 0.6)] {
        image(40, 32, 0.0).save_png(&a.path().join(name)).unwrap();
        image(40, 32, phase).save_png(&b.path().join(name)).unwrap();
    }
    image(40, 32, 0.0).save_png(&a.path().join("only_in_a.png")).unwrap();
    let out = run(a.path(), b.path(), &["--metric", "psnr,ssim,ssim-3dgs", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("only_in_a.png is only in"));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["count"], 2);
    let device = Device::flex();
    let mut sum = 0.0;
    for (k, name) in ["x.png", "y.png"].iter().enumerate() {
        let row = &report["images"][k];
        assert_eq!(row["image"], *name);
        let ia = RgbImage::load(&a.path().join(name), [0.0; 3]).unwrap();
        let ib = RgbImage::load(&b.path().join(name), [0.0; 3]).unwrap();
        let p = psnr(&ia, &ib);
        assert_close(&row["psnr"], p, name);
        sum += p;
        for (key, convention) in [("ssim", SsimConvention::Valid), ("ssim-3dgs", SsimConvention::ZeroPadded)] {
            let s = ssim(image_tensor(&ia, &device), image_tensor(&ib, &device), convention).into_scalar::<f32>();
            assert_close(&row[key], s as f64, key);
        }
    }
    assert_close(&report["mean"]["psnr"], sum / 2.0, "mean");
}

#[test]
fn a_table_for_two_files_and_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, small) = (dir.path().join("a.png"), dir.path().join("b.png"), dir.path().join("s.png"));
    image(40, 32, 0.0).save_png(&a).unwrap();
    image(40, 32, 0.5).save_png(&b).unwrap();
    image(20, 16, 0.5).save_png(&small).unwrap();
    let out = run(&a, &b, &["--metric", "psnr"]);
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(table.lines().next().unwrap().contains("psnr") && table.lines().any(|l| l.starts_with("mean")), "{table}");
    let out = run(&a, &small, &["--metric", "psnr"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("40x32 vs 20x16"));
    let out = run(&a, &b, &["--metric", "wd", "--log2-sigma", "5.5"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("at most 5"));
}

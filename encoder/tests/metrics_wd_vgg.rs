//! Wasserstein Distortion on VGG16 features: the third-party cross-check value of
//! `shared/metrics-calib/README.md`, the target cache, and (ignored by default) the time of a
//! forward+backward pass at 504x378. Needs the weights (see `shared_weights` for when their
//! absence skips).

#[path = "../../render/tests/shared_data/mod.rs"]
mod shared_data;
mod shared_weights;

use std::time::Instant;

use burn::tensor::{Device, Tensor, TensorData};
use pwgs_encoder::metrics::sigma_map::{Log2Sigma, SigmaMap};
use pwgs_encoder::metrics::vgg_wasserstein::{VggWasserstein, WdDepth};

fn load(device: &Device) -> Option<VggWasserstein> {
    shared_weights::loaded(VggWasserstein::load(&shared_weights::search_dirs(), device))
}

/// NCHW pattern image: value ((idx·multiplier + offset) mod 256) / 255 at flat index idx.
fn pattern(shape: [usize; 4], multiplier: usize, offset: usize, device: &Device) -> Tensor<4> {
    let n: usize = shape.iter().product();
    let values: Vec<f32> = (0..n).map(|i| ((i * multiplier + offset) % 256) as f32 / 255.0).collect();
    Tensor::from_data(TensorData::new(values, shape), device)
}

fn scalar(t: Tensor<1>) -> f64 {
    t.into_scalar::<f32>() as f64
}

#[test]
fn matches_the_third_party_value_and_caches_the_target() {
    let device = Device::flex();
    let Some(wd) = load(&device) else { return };
    let a = pattern([1, 3, 64, 64], 37, 0, &device);
    let b = pattern([1, 3, 64, 64], 73, 19, &device);
    let sigma = Log2Sigma::Constant(2.0);
    let value = scalar(wd.distortion_pair(a.clone(), b.clone(), &sigma));
    let reference = 10.540908813476562;
    let relative = (value - reference).abs() / reference;
    println!("VGG WD 64x64, log2σ=2: {value:.9} (third party {reference}, relative difference {relative:.1e})");
    // A float32 value from another implementation: agreement to float32 accumulation error.
    assert!(relative < 1e-5, "{value} vs {reference}");
    let target = wd.target(b);
    assert_eq!(scalar(wd.distortion(a.clone(), &target, &sigma)), value as f32 as f64);
    assert_eq!(scalar(wd.distortion(a.clone(), &wd.target(a), &sigma)), 0.0);
}

/// A per-pixel σ map goes through resampling and level blending per array; a constant map
/// must give what the constant gives, and a map that varies must give something else.
#[test]
fn a_constant_sigma_map_equals_the_constant() {
    let device = Device::flex();
    let Some(wd) = load(&device) else { return };
    let a = pattern([1, 3, 64, 72], 37, 0, &device);
    let target = wd.target(pattern([1, 3, 64, 72], 73, 19, &device));
    let constant = scalar(wd.distortion(a.clone(), &target, &Log2Sigma::Constant(2.5)));
    let flat = Log2Sigma::Map(SigmaMap::constant(64, 72, 2.5));
    let mapped = scalar(wd.distortion(a.clone(), &target, &flat));
    assert!((mapped - constant).abs() <= 1e-6 * constant, "{mapped} vs {constant}");
    let ramp = SigmaMap { height: 64, width: 72, values: (0..64 * 72).map(|i| 5.0 * (i % 72) as f64 / 71.0).collect() };
    let varying = scalar(wd.distortion(a, &target, &Log2Sigma::Map(ramp)));
    assert!((varying - constant).abs() > 1e-3 * constant, "{varying} vs {constant}");
}

/// A shallower pyramid compares exactly the reference's arrays it keeps (the normalized
/// image, then the first blocks at the first scales), and so scores at most what it does.
#[test]
fn a_shallower_pyramid_keeps_the_reference_arrays() {
    let device = Device::flex();
    let Some(full) = load(&device) else { return };
    let Some(shallow) = load(&device) else { return };
    let shallow = shallow.with_depth(WdDepth { blocks: 2, scales: 2 });
    let a = pattern([1, 3, 64, 64], 37, 0, &device);
    let all = full.features(a.clone());
    let kept = shallow.features(a.clone());
    assert_eq!(all.len(), 16);
    // Arrays 0 (the image), 1-2 (scale 0, blocks 1-2) and 6-7 (scale 1, blocks 1-2).
    assert_eq!(kept.len(), 5);
    for (k, i) in [0, 1, 2, 6, 7].into_iter().enumerate() {
        assert_eq!(kept[k].to_data(), all[i].to_data(), "array {k} of the shallow pyramid is not the reference's {i}");
    }
    let b = pattern([1, 3, 64, 64], 73, 19, &device);
    let sigma = Log2Sigma::Constant(2.0);
    let (whole, part) =
        (scalar(full.distortion_pair(a.clone(), b.clone(), &sigma)), scalar(shallow.distortion_pair(a, b, &sigma)));
    assert!(part > 0.0 && part < whole, "{part} against {whole}");
}

#[test]
fn gradient_reaches_every_pixel() {
    let device = Device::flex().autodiff();
    let Some(wd) = load(&device) else { return };
    let a = pattern([1, 3, 64, 64], 37, 0, &device).require_grad();
    let target = wd.target(pattern([1, 3, 64, 64], 73, 19, &device));
    let grads = wd.distortion(a.clone(), &target, &Log2Sigma::Constant(2.0)).backward();
    let g: Vec<f32> = a.grad(&grads).unwrap().into_data().convert::<f32>().try_into_vec::<f32>().unwrap();
    assert!(g.iter().all(|v| v.is_finite()));
    assert!(g.iter().filter(|v| **v != 0.0).count() == g.len(), "some pixels get no gradient");
}

/// `cargo test --release -p pwgs-encoder --test metrics_wd_vgg -- --ignored --nocapture`
#[test]
#[ignore = "timing at 504x378: tens of seconds"]
fn forward_backward_time_at_504x378() {
    let device = Device::flex().autodiff();
    let Some(wd) = load(&device) else { return };
    let shape = [1, 3, 378, 504];
    let target = wd.target(pattern(shape, 73, 19, &device));
    for sigma in [2.0, 4.0] {
        for _ in 0..2 {
            let image = pattern(shape, 37, 0, &device).require_grad();
            let start = Instant::now();
            let loss = wd.distortion(image.clone(), &target, &Log2Sigma::Constant(sigma));
            let value = scalar(loss.clone());
            let forward = start.elapsed().as_secs_f64();
            let grads = loss.backward();
            let g = image.grad(&grads).unwrap().abs().sum().into_scalar::<f32>();
            let total = start.elapsed().as_secs_f64();
            println!(
                "504x378 log2σ={sigma}: WD {value:.4}, forward {forward:.2} s, forward+backward {total:.2} s (|grad|₁ {g:.3e})"
            );
        }
    }
}

//! The synthesis network on Burn (training) against the decoder's plain-Rust evaluation, on
//! random weights and the real conditioning (noise pyramid and Plücker embeddings).

use burn::tensor::{Device, Tensor, TensorData};
use glam::Vec3;
use pwgs_codec::wrapper::conditioning;
use pwgs_codec::wrapper::synthesis::{SynthesisWeights, WrapperConfig};
use pwgs_core::camera::{Camera, Intrinsics};
use pwgs_core::frame::SceneFrame;
use pwgs_core::random::SplitMix64;
use pwgs_encoder::wrapper::synthesis::{flat_tensor, forward};

fn values(t: Tensor<4>) -> Vec<f32> {
    t.into_data().convert::<f32>().try_into_vec::<f32>().unwrap()
}

fn check(config: WrapperConfig, width: u32, height: u32) {
    let intrinsics = Intrinsics { width, height, fx: 40.0, fy: 42.0, cx: 15.3, cy: 11.0 };
    let camera = Camera::look_at(intrinsics, Vec3::new(2.0, -1.0, -3.0), Vec3::ZERO, Vec3::NEG_Y).unwrap();
    let frame = SceneFrame { center: Vec3::new(0.1, 0.2, 0.3), scale: 1.7 };
    let mut rng = SplitMix64(config.seed ^ 77);
    let params: Vec<f32> = (0..config.parameter_count()).map(|_| rng.uniform(-0.3, 0.3)).collect();
    let weights = SynthesisWeights::from_values(config, &params);
    let (w, h) = (width as usize, height as usize);
    let base: Vec<f32> = (0..w * h * 3).map(|_| rng.uniform(0.0, 1.0)).collect();
    let cond = conditioning(&config, &camera, frame);
    let expected = weights.residual(&base, &cond, w, h);

    let device = Device::flex();
    let k = config.conditioning_channels();
    let input: Vec<f32> =
        (0..w * h).flat_map(|p| base[p * 3..p * 3 + 3].iter().chain(&cond[p * k..(p + 1) * k])).copied().collect();
    let input = Tensor::<2>::from_data(TensorData::new(input, [w * h, 3 + k]), &device);
    let r = forward(&config, flat_tensor(&params, &device), input, h, w);
    assert_eq!(r.dims(), [1, 3, h, w]);
    let planar = values(r);
    let mut worst = 0.0f32;
    for p in 0..w * h {
        for c in 0..3 {
            worst = worst.max((planar[c * w * h + p] - expected[p * 3 + c]).abs());
        }
    }
    assert!(worst <= 1e-5, "Burn and decoder differ by {worst}");
}

#[test]
fn burn_forward_matches_the_decoder_within_1e_5() {
    check(WrapperConfig { width: 16, noise: true, plucker: true, seed: 1 }, 31, 23);
    check(WrapperConfig { width: 7, noise: false, plucker: true, seed: 2 }, 12, 9);
    check(WrapperConfig { width: 3, noise: true, plucker: false, seed: 3 }, 5, 40);
}

#[test]
fn gradients_reach_every_layer() {
    let config = WrapperConfig { width: 4, noise: false, plucker: false, seed: 0 };
    let device = Device::flex();
    let mut rng = SplitMix64(5);
    let params: Vec<f32> = (0..config.parameter_count()).map(|_| rng.uniform(-0.5, 0.5)).collect();
    let flat = flat_tensor(&params, &device).autodiff().require_grad();
    let input: Vec<f32> = (0..6 * 5 * 3).map(|_| rng.uniform(0.0, 1.0)).collect();
    let input = Tensor::<2>::from_data(TensorData::new(input, [30, 3]), &device).autodiff();
    let r = forward(&config, flat.clone(), input, 5, 6);
    let grads = (r.clone() * r).sum().backward();
    let g = flat.grad(&grads).unwrap().into_data().convert::<f32>().try_into_vec::<f32>().unwrap();
    // Every block of parameters (first layer, output layer, both residual convolutions) moves.
    let blocks = [0..12, 16..28, 31..112, 115..196];
    for block in blocks {
        assert!(g[block.clone()].iter().any(|v| *v != 0.0), "no gradient in {block:?}");
    }
}

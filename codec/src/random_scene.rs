//! A random scene with a perceptual wrapper, for tests and benchmarks of the decoder: the
//! Gaussians of [`pwgs_core::random::random_gaussians`] with random weights, and a random anchor
//! model.

use glam::Vec3;
use pwgs_core::frame::SceneFrame;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::random::SplitMix64;

use crate::anchor::{AnchorModel, Mlp};
use crate::scene::{Base, Scene};
use crate::wrapper::synthesis::{SynthesisWeights, WrapperConfig};

/// `gaussians` as a scene in the view of [`axis_camera`] (its frame centered 4 ahead) with a
/// width-16 wrapper of every input whose weights are drawn from `rng` in [-0.3, 0.3]: strong
/// enough that a wrong residual shows.
pub fn wrapped_random_scene(rng: &mut SplitMix64, gaussians: Gaussians, background: [f32; 3]) -> Scene {
    let config = WrapperConfig { width: 16, noise: true, plucker: true, seed: 7 };
    let values: Vec<f32> = (0..config.parameter_count()).map(|_| rng.uniform(-0.3, 0.3)).collect();
    Scene {
        base: Base::Plain(gaussians),
        wrapper: Some(SynthesisWeights::from_values(config, &values)),
        frame: SceneFrame { center: Vec3::new(0.0, 0.0, 4.0), scale: 2.0 },
        background,
    }
}

/// An MLP whose weights are `w(i)` for the i-th value (w1, b1, w2, b2 in order).
fn mlp(inputs: usize, hidden: usize, outputs: usize, w: &mut impl FnMut() -> f32) -> Mlp {
    let mut take = |n: usize| (0..n).map(|_| w()).collect::<Vec<f32>>();
    Mlp {
        inputs,
        hidden,
        outputs,
        w1: take(hidden * inputs),
        b1: take(hidden),
        w2: take(outputs * hidden),
        b2: take(outputs),
    }
}

/// A random anchor model of `n` anchors with `f` features and `k` offsets each, small random
/// networks of 6 hidden units, and every fifth offset masked.
pub fn random_anchor_model(rng: &mut SplitMix64, n: usize, f: usize, k: usize) -> AnchorModel {
    let mut w = || rng.uniform(-0.5, 0.5);
    let (opacity, color, covariance) =
        (mlp(f + 4, 6, k, &mut w), mlp(f + 4, 6, 3 * k, &mut w), mlp(f + 4, 6, 7 * k, &mut w));
    AnchorModel {
        feature_dim: f,
        offsets_per_anchor: k,
        positions: (0..n).map(|_| [rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)]).collect(),
        features: (0..n * f).map(|_| rng.uniform(-1.0, 1.0)).collect(),
        scaling: (0..n).map(|_| [0, 0, 0, 0, 0, 0].map(|_: i32| rng.uniform(-3.0, -1.0))).collect(),
        offsets: (0..n * k * 3).map(|_| rng.uniform(-1.0, 1.0)).collect(),
        masks: (0..n * k).map(|i| i % 5 != 0).collect(),
        opacity,
        color,
        covariance,
    }
}

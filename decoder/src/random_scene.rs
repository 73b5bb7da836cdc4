//! A random scene with a perceptual wrapper, for tests and benchmarks of the decoder: the
//! Gaussians of [`pwgs_core::random::random_gaussians`] with random weights.

use glam::Vec3;
use pwgs_core::frame::SceneFrame;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::random::SplitMix64;

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

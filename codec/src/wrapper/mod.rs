//! The perceptual wrapper on the decoder side (SPEC.md section 11): the common-randomness noise
//! pyramid, Plücker embeddings and the synthesis network f, which turn a base render I_base
//! into the image shown, clamp(I_base + f(I_base, noise, Plücker), 0, 1).

pub mod noise;
mod normal_table;
pub mod plucker;
pub mod synthesis;

use pwgs_core::frame::SceneFrame;

use noise::{NOISE_LEVELS, NoiseGrids};
use plucker::{PLUCKER_CHANNELS, PluckerRays};
use pwgs_core::camera::Camera;
use pwgs_core::rgb_image::RgbImage;
use rayon::prelude::*;
use synthesis::{SynthesisWeights, WrapperConfig};

/// The per-pixel inputs of f after the base RGB for one view: the 8 noise levels, then the 6
/// Plücker channels, each group only when the configuration feeds it. Produced row by row.
#[derive(Debug, Clone)]
pub struct Conditioning {
    noise: Option<NoiseGrids>,
    plucker: Option<PluckerRays>,
    /// Values per pixel ([`WrapperConfig::conditioning_channels`]).
    channels: usize,
    width: usize,
    height: usize,
}

impl Conditioning {
    pub fn new(config: &WrapperConfig, camera: &Camera, frame: SceneFrame) -> Self {
        let (width, height) = (camera.width as usize, camera.height as usize);
        Self {
            noise: config.noise.then(|| NoiseGrids::new(config.seed, width, height)),
            plucker: config.plucker.then(|| PluckerRays::new(camera, frame.center, frame.scale)),
            channels: config.conditioning_channels(),
            width,
            height,
        }
    }

    /// Row `y` into `row` (`width * channels` values, pixel-interleaved).
    pub fn row(&self, y: usize, row: &mut [f32]) {
        match (&self.noise, &self.plucker) {
            (Some(noise), Some(plucker)) => {
                let mut n = vec![0.0f32; self.width * NOISE_LEVELS];
                let mut p = vec![0.0f32; self.width * PLUCKER_CHANNELS];
                noise.row(y, &mut n);
                plucker.row(y, &mut p);
                let pixels = n.chunks_exact(NOISE_LEVELS).zip(p.chunks_exact(PLUCKER_CHANNELS));
                for (out, (a, b)) in row.chunks_exact_mut(NOISE_LEVELS + PLUCKER_CHANNELS).zip(pixels) {
                    out[..NOISE_LEVELS].copy_from_slice(a);
                    out[NOISE_LEVELS..].copy_from_slice(b);
                }
            }
            (Some(noise), None) => noise.row(y, row),
            (None, Some(plucker)) => plucker.row(y, row),
            (None, None) => {}
        }
    }

    /// Every row, one after the other (what training feeds f as a tensor).
    pub fn image(&self) -> Vec<f32> {
        let mut out = vec![0.0f32; self.width * self.height * self.channels];
        if self.channels > 0 {
            out.par_chunks_mut(self.width * self.channels).enumerate().for_each(|(y, row)| self.row(y, row));
        }
        out
    }
}

/// The whole conditioning image of `camera` (see [`Conditioning`]).
pub fn conditioning(config: &WrapperConfig, camera: &Camera, frame: SceneFrame) -> Vec<f32> {
    Conditioning::new(config, camera, frame).image()
}

/// What the wrapper produces for one view.
#[derive(Debug, Clone, PartialEq)]
pub struct Wrapped {
    /// clamp(I_base + R, 0, 1): the image shown.
    pub image: RgbImage,
    /// R, interleaved RGB, unclamped.
    pub residual: Vec<f32>,
}

/// Applies f to a base render of `camera`.
pub fn apply(weights: &SynthesisWeights, base: &RgbImage, camera: &Camera, frame: SceneFrame) -> Wrapped {
    assert_eq!((base.width, base.height), (camera.width, camera.height), "base render and camera differ in size");
    let (width, height) = (base.width as usize, base.height as usize);
    let conditioning = Conditioning::new(&weights.config, camera, frame);
    let residual = weights.residual_by_rows(&base.data, width, height, |y, row| conditioning.row(y, row));
    let data = base.data.iter().zip(&residual).map(|(b, r)| (b + r).clamp(0.0, 1.0)).collect();
    Wrapped { image: RgbImage { width: base.width, height: base.height, data }, residual }
}

/// R as a picture: 0.5 + R, clamped (mid-gray where the wrapper changes nothing).
pub fn residual_picture(residual: &[f32], width: u32, height: u32) -> RgbImage {
    RgbImage { width, height, data: residual.iter().map(|r| (0.5 + r).clamp(0.0, 1.0)).collect() }
}

/// A trained wrapper and the scene frame of its stream.
#[derive(Debug, Clone, Copy)]
pub struct WrapperView<'a> {
    pub weights: &'a SynthesisWeights,
    pub frame: SceneFrame,
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use noise::noise_pyramid;
    use plucker::plucker_embeddings;
    use pwgs_core::camera::Intrinsics;
    use pwgs_core::random::SplitMix64;

    #[test]
    fn rows_interleave_noise_then_plucker_and_match_the_whole_image_evaluation() {
        let intrinsics = Intrinsics { width: 11, height: 7, fx: 9.0, fy: 9.5, cx: 5.2, cy: 3.4 };
        let camera = Camera::look_at(intrinsics, Vec3::new(1.0, 2.0, -3.0), Vec3::ZERO, Vec3::Y).unwrap();
        let frame = SceneFrame { center: Vec3::new(0.1, -0.2, 0.3), scale: 1.7 };
        let config = WrapperConfig { width: 6, noise: true, plucker: true, seed: 42 };
        let all = conditioning(&config, &camera, frame);
        let noise = noise_pyramid(42, 11, 7);
        let plucker = plucker_embeddings(&camera, frame.center, frame.scale);
        let pixels = noise.chunks_exact(NOISE_LEVELS).zip(plucker.chunks_exact(PLUCKER_CHANNELS));
        for (px, (n, p)) in all.chunks_exact(NOISE_LEVELS + PLUCKER_CHANNELS).zip(pixels) {
            assert_eq!(&px[..NOISE_LEVELS], n);
            assert_eq!(&px[NOISE_LEVELS..], p);
        }
        let mut rng = SplitMix64(3);
        let values: Vec<f32> = (0..config.parameter_count()).map(|_| rng.uniform(-0.3, 0.3)).collect();
        let weights = SynthesisWeights::from_values(config, &values);
        let base = RgbImage { width: 11, height: 7, data: (0..11 * 7 * 3).map(|_| rng.uniform(0.0, 1.0)).collect() };
        let wrapped = apply(&weights, &base, &camera, frame);
        assert_eq!(wrapped.residual, weights.residual(&base.data, &all, 11, 7));
        assert!(wrapped.residual.iter().any(|&r| r != 0.0));
    }
}

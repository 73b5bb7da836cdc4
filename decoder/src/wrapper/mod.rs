//! The perceptual wrapper on the decoder side (SPEC.md section 11): the common-randomness noise
//! pyramid, Plücker embeddings and the synthesis network f, which turn a base render I_base
//! into the image shown, clamp(I_base + f(I_base, noise, Plücker), 0, 1).

pub mod noise;
mod normal_table;
pub mod plucker;
pub mod synthesis;

use glam::Vec3;

use crate::camera::Camera;
use crate::rgb_image::RgbImage;
use noise::{NOISE_LEVELS, noise_pyramid};
use plucker::{PLUCKER_CHANNELS, plucker_embeddings};
use synthesis::{SynthesisWeights, WrapperConfig};

/// The scene normalization the Plücker moments are taken in (the stream header's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneFrame {
    pub center: Vec3,
    pub scale: f32,
}

/// The per-pixel inputs of f after the base RGB, pixel-interleaved: the 8 noise levels, then
/// the 6 Plücker channels, each group only when the configuration feeds it.
pub fn conditioning(config: &WrapperConfig, camera: &Camera, frame: SceneFrame) -> Vec<f32> {
    let (width, height) = (camera.width as usize, camera.height as usize);
    let noise = config.noise.then(|| noise_pyramid(config.seed, width, height));
    let plucker = config.plucker.then(|| plucker_embeddings(camera, frame.center, frame.scale));
    match (noise, plucker) {
        (Some(n), Some(p)) => n
            .chunks_exact(NOISE_LEVELS)
            .zip(p.chunks_exact(PLUCKER_CHANNELS))
            .flat_map(|(a, b)| a.iter().chain(b).copied())
            .collect(),
        (Some(n), None) => n,
        (None, Some(p)) => p,
        (None, None) => Vec::new(),
    }
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
    let residual = weights.residual(&base.data, &conditioning(&weights.config, camera, frame), width, height);
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

/// What a decoder shows for `camera`: the base render, passed through the wrapper when one is
/// given (then the residual comes along).
pub fn render_shown(
    g: &crate::gaussians::Gaussians,
    wrapper: Option<WrapperView>,
    camera: &Camera,
    options: &crate::raster::RenderOptions,
) -> (RgbImage, Option<Vec<f32>>) {
    let base = crate::raster::render(g, camera, options);
    match wrapper {
        Some(w) => {
            let wrapped = apply(w.weights, &base, camera, w.frame);
            (wrapped.image, Some(wrapped.residual))
        }
        None => (base, None),
    }
}

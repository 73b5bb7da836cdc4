//! What the player shows of a view: the decoded image, the base alone, the wrapper's residual
//! (amplified, since R is small), or the noise the wrapper is conditioned on.

use pwgs_codec::scene::Scene;
use pwgs_codec::wrapper::noise::{NOISE_LEVELS, noise_pyramid};
use pwgs_core::camera::Camera;
use pwgs_core::rgb_image::RgbImage;
use pwgs_render::gpu::{GpuError, GpuRenderer, GpuScene, Output, StageTimes};
use pwgs_render::show::SceneRender;

/// One of the player's pictures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewMode {
    /// What a decoder shows (through the wrapper when the stream has one).
    Shown,
    /// The Gaussians' render, without the wrapper.
    Base,
    /// 0.5 + gain * R: mid-gray where the wrapper changes nothing.
    Residual,
    /// The finest level of the common-randomness noise pyramid, as gray.
    Noise,
}

impl ViewMode {
    pub const ALL: [ViewMode; 4] = [ViewMode::Shown, ViewMode::Base, ViewMode::Residual, ViewMode::Noise];

    pub fn label(self) -> &'static str {
        match self {
            ViewMode::Shown => "decoded",
            ViewMode::Base => "base only",
            ViewMode::Residual => "residual R",
            ViewMode::Noise => "noise",
        }
    }

    /// Whether the mode needs the stream's wrapper.
    pub fn needs_wrapper(self) -> bool {
        matches!(self, ViewMode::Residual | ViewMode::Noise)
    }
}

/// Renders `mode`'s picture of `camera`'s view of `scene` (`prepared` for `gpu`); `gain`
/// scales the residual. A mode that needs the wrapper falls back to [`ViewMode::Shown`] on a
/// stream without one (callers say so).
pub fn picture(
    gpu: &GpuRenderer,
    scene: &Scene,
    prepared: &GpuScene,
    camera: &Camera,
    mode: ViewMode,
    gain: f32,
) -> Result<(RgbImage, StageTimes), GpuError> {
    let options = scene.render_options();
    let (width, height) = (camera.width, camera.height);
    match (mode, &scene.wrapper) {
        (ViewMode::Base, _) => gpu.render(scene, prepared, camera, &options, Output::Base).map(|(s, t)| (s.image, t)),
        (ViewMode::Residual, Some(_)) => {
            let (shown, times) = gpu.render(scene, prepared, camera, &options, Output::Shown)?;
            let r = shown.residual.unwrap_or_default();
            let data = r.iter().map(|v| (0.5 + gain * v).clamp(0.0, 1.0)).collect();
            Ok((RgbImage { width, height, data }, times))
        }
        (ViewMode::Noise, Some(w)) => {
            let noise = noise_pyramid(w.config.seed, width as usize, height as usize);
            let data =
                noise.chunks_exact(NOISE_LEVELS).flat_map(|n| [(0.5 + 0.15 * n[0]).clamp(0.0, 1.0); 3]).collect();
            Ok((RgbImage { width, height, data }, StageTimes::default()))
        }
        _ => gpu.render(scene, prepared, camera, &options, Output::Shown).map(|(s, t)| (s.image, t)),
    }
}

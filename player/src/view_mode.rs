//! What the player shows of a view: the decoded image, the base alone, the wrapper's residual
//! (amplified, since R is small), or the noise the wrapper is conditioned on.

use std::time::Instant;

use pwgs_codec::scene::Scene;
use pwgs_codec::wrapper::noise::{NOISE_LEVELS, noise_pyramid};
use pwgs_core::camera::Camera;
use pwgs_core::rgb_image::RgbImage;
use pwgs_render::gpu::{GpuError, GpuRenderer, GpuScene, Output, StageTimes};
use pwgs_render::show::{SceneRender, Shown};

/// Which renderer draws the pictures: the GPU (wgpu), or the decoder's CPU renderer with the
/// wrapper's network on the CPU too (the window stays on wgpu either way).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Renderer {
    /// The GPU, unless its adapter is a software rasterizer: then the CPU renderer, which is
    /// faster on the same cores (a 60,000-splat 1920x1080 view: 0.3 s against lavapipe's 5 s).
    #[default]
    Auto,
    Gpu,
    Cpu,
}

impl Renderer {
    /// Whether pictures are rendered on the CPU with `gpu`'s adapter.
    pub fn on_cpu(self, gpu: &GpuRenderer) -> bool {
        match self {
            Renderer::Auto => gpu.is_software(),
            Renderer::Gpu => false,
            Renderer::Cpu => true,
        }
    }

    /// What renders the pictures, for logs and the panel.
    pub fn describe(self, gpu: &GpuRenderer) -> String {
        if self.on_cpu(gpu) {
            format!("the CPU renderer (window on {})", gpu.adapter_name())
        } else {
            gpu.adapter_name()
        }
    }
}

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

/// What renders a picture ([`Renderer::on_cpu`] chooses): the GPU renderer with the scene it
/// prepared, or the CPU renderer (which needs nothing prepared).
#[derive(Clone, Copy)]
pub enum Painter<'a> {
    Gpu(&'a GpuRenderer, &'a GpuScene),
    Cpu,
}

impl Painter<'_> {
    fn render(&self, scene: &Scene, camera: &Camera, output: Output) -> Result<(Shown, StageTimes), GpuError> {
        let options = scene.render_options();
        match self {
            Painter::Gpu(gpu, prepared) => gpu.render(scene, prepared, camera, &options, output),
            Painter::Cpu => {
                let start = Instant::now();
                let shown = scene.render(camera, &options, output == Output::Shown)?;
                Ok((shown, StageTimes { raster: start.elapsed(), ..StageTimes::default() }))
            }
        }
    }
}

/// Renders `mode`'s picture of `camera`'s view of `scene` with `painter`; `gain` scales the
/// residual. A mode that needs the wrapper falls back to [`ViewMode::Shown`] on a stream
/// without one (callers say so).
pub fn picture(
    painter: Painter,
    scene: &Scene,
    camera: &Camera,
    mode: ViewMode,
    gain: f32,
) -> Result<(RgbImage, StageTimes), GpuError> {
    let (width, height) = (camera.width, camera.height);
    match (mode, &scene.wrapper) {
        (ViewMode::Base, _) => painter.render(scene, camera, Output::Base).map(|(s, t)| (s.image, t)),
        (ViewMode::Residual, Some(_)) => {
            let (shown, times) = painter.render(scene, camera, Output::Shown)?;
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
        _ => painter.render(scene, camera, Output::Shown).map(|(s, t)| (s.image, t)),
    }
}

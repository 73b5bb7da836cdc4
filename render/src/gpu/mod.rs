//! The GPU renderer (feature `gpu`): the decoder's views on a wgpu device, for the
//! player and for scripts that render many views.
//!
//! What runs where:
//! - CPU: the anchors' per-view MLPs ([`Scene::gaussians_for`]), the depth sort and tile
//!   binning of the projected splats' boxes (the reference's binning, [`crate::raster::tiles`]),
//!   and the wrapper's conditioning (the normative noise pyramid and the Plücker rays,
//!   [`pwgs_codec::wrapper::Conditioning`]).
//! - GPU: projection ([`project`]; a plain base's Gaussians are uploaded once, by
//!   [`GpuRenderer::prepare`]), alpha blending of the binned splats ([`blend`]) and the
//!   synthesis network f ([`synthesis`]); splats and the base render stay on the device.
//!
//! The CPU rasterizer stays the definition. Projection here follows its rules in f32 (with
//! forms free of the cancellation its f64 guards against), blending follows its rules in its
//! order, and the compiler may fuse multiply-adds, so images agree within a tolerance
//! (`render/tests/gpu.rs` states it), not bit for bit.

mod blend;
mod buffers;
mod pass;
mod project;
mod synthesis;

use std::time::{Duration, Instant};

use crate::raster::opaque_tiles::{Footprint, Stops, list_ends};
use crate::raster::tile_lists::{BinBudget, BlendLimit, ListEnds, TooMuchBlending};
use crate::raster::{RenderOptions, Window};
use crate::show::Shown;
use project::DeviceGaussians;
use pwgs_codec::scene::{Base, Scene};
use pwgs_codec::wrapper::Conditioning;
use pwgs_core::camera::Camera;
use pwgs_core::rgb_image::RgbImage;

/// Why the GPU renderer cannot start or render.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter is available ({0}); on Linux without a GPU, install Mesa's lavapipe (mesa-vulkan-drivers)")]
    NoAdapter(String),
    #[error("the GPU adapter refused a device: {0}")]
    NoDevice(String),
    #[error("{what} needs {bytes} bytes in one GPU buffer, more than this device's limit of {limit}")]
    TooLarge { what: &'static str, bytes: u64, limit: u64 },
    #[error("the wrapper's hidden width {0} is above the GPU renderer's 64")]
    WrapperTooWide(usize),
    #[error("the GPU renderer blends with the hard alpha cutoff only (the smooth one is for gradient checks)")]
    SmoothCutoff,
    #[error("reading the image back from the GPU failed: {0}")]
    Readback(String),
    #[error("the GPU renderer projects SH up to degree 3; the scene has degree {0}")]
    ShDegree(u32),
    #[error("the scene was prepared for the GPU as another scene (prepare each scene it renders)")]
    NotPrepared,
    #[error(transparent)]
    TooMuchBlending(#[from] TooMuchBlending),
}

/// Which image a render returns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// What a decoder shows: through the wrapper when the stream has one.
    Shown,
    /// The base render alone, wrapper or not.
    Base,
}

/// Where a render's time went.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// The view's Gaussians (an anchor stream's MLPs, on the CPU) and their upload; nothing
    /// for a plain base, uploaded once.
    pub gaussians: Duration,
    /// Projection to splats, on the GPU.
    pub projection: Duration,
    /// Reading the splats' boxes and depths back, the depth sort and tile binning (CPU).
    pub sort: Duration,
    /// Blending on the GPU, including the upload of the tile lists.
    pub raster: Duration,
    /// The wrapper: conditioning on the CPU, f on the GPU.
    pub synthesis: Duration,
    /// Copying the result back.
    pub readback: Duration,
}

impl StageTimes {
    /// The whole render.
    pub fn total(&self) -> Duration {
        self.gaussians + self.projection + self.sort + self.raster + self.synthesis + self.readback
    }
}

/// Storage buffers the projection binds (the most of any pass; WebGPU's default limit).
const STORAGE_BUFFERS: u32 = 8;

/// A wgpu device with the renderer's pipelines.
pub struct GpuRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: wgpu::AdapterInfo,
    project: project::ProjectPass,
    blend: blend::BlendPass,
    synthesis: synthesis::SynthesisPass,
    /// How much of a view's tile lists one blend pass holds ([`BinBudget::DEFAULT`]).
    bin_budget: BinBudget,
}

/// A scene made ready for [`GpuRenderer::render`]: a plain base's Gaussians on the device
/// (uploaded once; an anchor base's depend on the view and are uploaded at each render).
pub struct GpuScene {
    plain: Option<DeviceGaussians>,
    /// Which scene this is: the address and length of its Gaussian (or anchor) arrays, which
    /// stay put while the scene lives, so that a render of another scene is refused.
    identity: (usize, usize),
}

fn identity(scene: &Scene) -> (usize, usize) {
    match &scene.base {
        Base::Plain(g) => (g.means.as_ptr() as usize, g.len()),
        Base::Anchors(model) => (&**model as *const _ as usize, 0),
    }
}

impl GpuRenderer {
    /// Opens the first adapter wgpu offers (a real GPU before a software one) without a
    /// window.
    pub fn new() -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        Self::with_adapter(&adapter)
    }

    /// The renderer on `adapter` (the player passes the one its window uses).
    pub fn with_adapter(adapter: &wgpu::Adapter) -> Result<Self, GpuError> {
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("pwgs"),
            required_limits: wgpu::Limits {
                max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
                max_buffer_size: limits.max_buffer_size,
                // Projection binds 8 storage buffers, blending 5, the synthesis network 5.
                max_storage_buffers_per_shader_stage: limits.max_storage_buffers_per_shader_stage,
                ..wgpu::Limits::downlevel_defaults()
            },
            ..Default::default()
        }))
        .map_err(|e| GpuError::NoDevice(e.to_string()))?;
        Self::with_device(device, queue, adapter.get_info())
    }

    /// The renderer on an existing device (shared with a window's renderer).
    pub fn with_device(device: wgpu::Device, queue: wgpu::Queue, adapter: wgpu::AdapterInfo) -> Result<Self, GpuError> {
        let storage = device.limits().max_storage_buffers_per_shader_stage;
        if storage < STORAGE_BUFFERS {
            return Err(GpuError::NoDevice(format!(
                "the device allows {storage} storage buffers per shader stage; projection binds {STORAGE_BUFFERS}"
            )));
        }
        let project = project::ProjectPass::new(&device);
        let blend = blend::BlendPass::new(&device);
        let synthesis = synthesis::SynthesisPass::new(&device);
        Ok(Self { device, queue, adapter, project, blend, synthesis, bin_budget: BinBudget::DEFAULT })
    }

    /// Blends views window by window within `budget` (tests use small ones to exercise many
    /// windows; the default bounds a view's tile lists at 64 MiB).
    pub fn set_bin_budget(&mut self, budget: BinBudget) {
        self.bin_budget = budget;
    }

    /// Makes `scene` ready to render: uploads a plain base's Gaussians.
    pub fn prepare(&self, scene: &Scene) -> Result<GpuScene, GpuError> {
        let plain = match &scene.base {
            Base::Plain(g) => Some(DeviceGaussians::upload(self, g)?),
            Base::Anchors(_) => None,
        };
        Ok(GpuScene { plain, identity: identity(scene) })
    }

    /// Whether the adapter is a software rasterizer (Mesa's lavapipe): one blends a tile-list
    /// entry some 50 times slower than the CPU renderer does on the same cores.
    pub fn is_software(&self) -> bool {
        self.adapter.device_type == wgpu::DeviceType::Cpu
    }

    /// The adapter's name and backend, for logs and the player's panel.
    pub fn adapter_name(&self) -> String {
        format!("{} ({:?})", self.adapter.name, self.adapter.backend)
    }

    /// Renders `camera`'s view of `scene` (made ready by [`Self::prepare`] as `prepared`);
    /// with [`Output::Shown`] and a wrapper, also returns the residual R.
    pub fn render(
        &self,
        scene: &Scene,
        prepared: &GpuScene,
        camera: &Camera,
        options: &RenderOptions,
        output: Output,
    ) -> Result<(Shown, StageTimes), GpuError> {
        if prepared.identity != identity(scene) {
            return Err(GpuError::NotPrepared);
        }
        let mut times = StageTimes::default();
        let start = Instant::now();
        let per_view;
        let gaussians = match &prepared.plain {
            Some(g) => g,
            None => {
                per_view = DeviceGaussians::upload(self, &scene.gaussians_for(camera))?;
                &per_view
            }
        };
        times.gaussians = start.elapsed();
        let start = Instant::now();
        let projected = self.project.run(self, gaussians, camera, &options.projection)?;
        self.wait();
        times.projection = start.elapsed();
        let start = Instant::now();
        let (order, boxes) = projected.front_to_back(self)?;
        let bbox = |k: usize| boxes[order[k] as usize];
        let view = Window::full(camera);
        let full = ListEnds::full(order.len(), bbox, view);
        let mut windows = full.windows(self.bin_budget);
        // Lists too long for one window, or more blend work than the limit, are ended where
        // their tile is surely opaque, with the bound taken of the splats as the blend pass
        // reads them (read back: 48 bytes per Gaussian, a cost an ordinary view, whose lists fit
        // one window, does not pay), and refused past the limit, as pwdec refuses them.
        let limit = BlendLimit::DEFAULT;
        let ends = match windows.len() {
            1 if full.work <= limit.of(view, gaussians.count()) => full,
            _ => {
                let values = projected.splat_values(self)?;
                let footprint = |k: usize| {
                    let s = order[k] as usize * project::SPLAT_STRIDE;
                    Footprint {
                        bbox: bbox(k),
                        mean: [values[s], values[s + 1]],
                        cholesky: [values[s + 2], values[s + 3], values[s + 4]],
                        opacity: values[s + 5],
                    }
                };
                let ends = list_ends(
                    order.len(),
                    footprint,
                    view,
                    Stops::of(options),
                    (BlendLimit::DEFAULT, gaussians.count()),
                )?;
                windows = ends.windows(self.bin_budget);
                ends
            }
        };
        times.sort = start.elapsed();

        // Window by window, as the CPU renderer does: the tile lists of a view stay bounded
        // whatever its splats.
        let (width, height) = (camera.width, camera.height);
        let base = self.blend.image(self, width, height)?;
        for window in windows {
            let start = Instant::now();
            let mut bins = ends.bin(order.len(), bbox, window);
            // The blend pass reads splats by Gaussian index.
            bins.entries.iter_mut().for_each(|e| *e = order[*e as usize]);
            times.sort += start.elapsed();
            let start = Instant::now();
            self.blend.run(self, &projected, &bins, options, (&base, width, height))?;
            self.wait();
            times.raster += start.elapsed();
        }

        let wrapper = scene.wrapper_view().filter(|_| output == Output::Shown);
        let Some(view) = wrapper else {
            let start = Instant::now();
            let data = buffers::read_f32(self, &base, width as usize * height as usize * 3)?;
            times.readback = start.elapsed();
            return Ok((Shown { image: RgbImage { width, height, data }, residual: None }, times));
        };
        let start = Instant::now();
        let conditioning = Conditioning::new(&view.weights.config, camera, view.frame).image();
        let (residual, image) = self.synthesis.run(self, view.weights, &base, &conditioning, width, height)?;
        self.wait();
        times.synthesis = start.elapsed();
        let start = Instant::now();
        let pixels = width as usize * height as usize * 3;
        let data = buffers::read_f32(self, &image, pixels)?;
        let residual = buffers::read_f32(self, &residual, pixels)?;
        times.readback = start.elapsed();
        Ok((Shown { image: RgbImage { width, height, data }, residual: Some(residual) }, times))
    }

    /// Blocks until the queue's work is done.
    fn wait(&self) {
        // A lost device surfaces as an error on the next readback; nothing to do here.
        let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
    }
}

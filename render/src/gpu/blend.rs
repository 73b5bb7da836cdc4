//! Blending on the GPU (`blend.wgsl`): the projection's splats stay on the device, the tile
//! lists (of Gaussian indices, front to back) are uploaded, one workgroup blends one tile, and
//! the base render stays in a device buffer.

use crate::raster::tiles::TileBins;
use crate::raster::{Cutoff, RenderOptions};

use super::buffers::{output, storage, uniform};
use super::pass::{compute_pipeline, dispatch};
use super::project::Projected;
use super::{GpuError, GpuRenderer};

/// The blending pipeline.
pub struct BlendPass {
    pipeline: wgpu::ComputePipeline,
}

impl BlendPass {
    pub fn new(device: &wgpu::Device) -> Self {
        let pipeline = compute_pipeline(device, "blend", include_str!("blend.wgsl"));
        Self { pipeline }
    }

    /// Submits the blending of the `projected` splats that `bins` lists (by Gaussian index,
    /// front to back) over its window into `image` (interleaved RGB of the whole
    /// `width` x `height` view), one workgroup per tile of the window.
    pub fn run(
        &self,
        gpu: &GpuRenderer,
        projected: &Projected,
        bins: &TileBins,
        options: &RenderOptions,
        (image, width, height): (&wgpu::Buffer, u32, u32),
    ) -> Result<(), GpuError> {
        // The smooth cutoff exists for finite-difference checks of the CPU backward pass; a
        // viewer has no use for it, and the shader implements the standard hard threshold.
        if options.cutoff != Cutoff::Hard {
            return Err(GpuError::SmoothCutoff);
        }
        let window = bins.window;
        let offsets: Vec<u32> = bins
            .offsets
            .iter()
            .map(|&o| {
                u32::try_from(o).map_err(|_| GpuError::TooLarge {
                    what: "tile lists",
                    bytes: o as u64 * 4,
                    limit: u64::from(u32::MAX),
                })
            })
            .collect::<Result<_, _>>()?;
        let background = options.background;
        let params = uniform(
            gpu,
            &[
                width,
                height,
                bins.tiles_x,
                window.x0,
                window.y0,
                window.x0 + window.width,
                window.y0 + window.height,
                0,
                (options.projection.alpha_min as f32).to_bits(),
                options.alpha_max.to_bits(),
                options.transmittance_min.to_bits(),
                0,
                background[0].to_bits(),
                background[1].to_bits(),
                background[2].to_bits(),
                0,
            ],
        );
        let offsets = storage(gpu, "tile offsets", bytemuck::cast_slice(&offsets))?;
        let lists = storage(gpu, "tile lists", bytemuck::cast_slice(&bins.entries))?;
        let buffers = [&params, &projected.splats, &projected.boxes, &offsets, &lists, image];
        dispatch(gpu, &self.pipeline, &buffers, [bins.tiles_x, bins.tiles_y]);
        Ok(())
    }

    /// The buffer a view's base render lands in (interleaved RGB).
    pub fn image(&self, gpu: &GpuRenderer, width: u32, height: u32) -> Result<wgpu::Buffer, GpuError> {
        output(gpu, "base render", width as usize * height as usize * 3)
    }
}

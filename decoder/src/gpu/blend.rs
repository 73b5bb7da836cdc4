//! Blending on the GPU (`blend.wgsl`): the projection's splats stay on the device, the tile
//! lists (of Gaussian indices, front to back) are uploaded, one workgroup blends one tile, and
//! the base render stays in a device buffer.

use crate::raster::tiles::TileBins;
use crate::raster::{Cutoff, RenderOptions};

use super::buffers::{output, storage, uniform};
use super::project::Projected;
use super::{GpuError, GpuRenderer};

/// The blending pipeline.
pub struct BlendPass {
    pipeline: wgpu::ComputePipeline,
}

impl BlendPass {
    pub fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("blend"),
            source: wgpu::ShaderSource::Wgsl(include_str!("blend.wgsl").into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("blend"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        Self { pipeline }
    }

    /// Submits the blending of the `projected` splats that `bins` lists (by Gaussian index,
    /// front to back, over the whole image) and returns the buffer the image lands in
    /// (interleaved RGB).
    pub fn run(
        &self,
        gpu: &GpuRenderer,
        projected: &Projected,
        bins: &TileBins,
        options: &RenderOptions,
    ) -> Result<wgpu::Buffer, GpuError> {
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
        let pixels = window.width as usize * window.height as usize;
        let background = options.background;
        let params = uniform(
            gpu,
            &[
                window.width,
                window.height,
                bins.tiles_x,
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
        let image = output(gpu, "base render", pixels * 3)?;
        let buffers = [&params, &projected.splats, &projected.boxes, &offsets, &lists, &image];
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
            .collect();
        let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("blend"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(bins.tiles_x, bins.tiles_y, 1);
        }
        gpu.queue.submit([encoder.finish()]);
        Ok(image)
    }
}

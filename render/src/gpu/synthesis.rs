//! The synthesis network f on the GPU (`synthesis.wgsl`): the pointwise layers, the two
//! residual convolutions (ping-ponging between two buffers) and the clamp onto the base render.

use pwgs_codec::wrapper::synthesis::{RESIDUAL_TAPS, SynthesisWeights};

use super::buffers::{output, storage, uniform};
use super::{GpuError, GpuRenderer};

/// The widest hidden layer the shader holds per invocation (`MAX_HIDDEN` there); the stream
/// allows no more (SPEC.md section 11).
const MAX_HIDDEN: usize = 64;

/// The three pipelines, sharing one bind group layout.
pub struct SynthesisPass {
    layout: wgpu::BindGroupLayout,
    pointwise: wgpu::ComputePipeline,
    residual: wgpu::ComputePipeline,
    compose: wgpu::ComputePipeline,
}

impl SynthesisPass {
    pub fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("synthesis"),
            source: wgpu::ShaderSource::Wgsl(include_str!("synthesis.wgsl").into()),
        });
        let storage_entry = |binding: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let uniform_entry = wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("synthesis"),
            entries: &[
                uniform_entry,
                storage_entry(1, true),
                storage_entry(2, true),
                storage_entry(3, true),
                storage_entry(4, true),
                storage_entry(5, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("synthesis"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        Self { pointwise: pipeline("pointwise"), residual: pipeline("residual"), compose: pipeline("compose"), layout }
    }

    /// Submits f on the base render in `base` with the pixel-interleaved `conditioning`;
    /// returns the buffers of R and of the image shown, clamp(base + R, 0, 1).
    pub fn run(
        &self,
        gpu: &GpuRenderer,
        weights: &SynthesisWeights,
        base: &wgpu::Buffer,
        conditioning: &[f32],
        width: u32,
        height: u32,
    ) -> Result<(wgpu::Buffer, wgpu::Buffer), GpuError> {
        let config = weights.config;
        if config.width > MAX_HIDDEN {
            return Err(GpuError::WrapperTooWide(config.width));
        }
        let pixels = width as usize * height as usize;
        let values = weights.values();
        let parameters = storage(gpu, "synthesis weights", bytemuck::cast_slice(&values))?;
        let conditioning = storage(gpu, "conditioning", bytemuck::cast_slice(conditioning))?;
        let [a, b, image] = [
            output(gpu, "residual", pixels * 3)?,
            output(gpu, "residual", pixels * 3)?,
            output(gpu, "image", pixels * 3)?,
        ];
        // Where each residual convolution's taps start in the flat parameters.
        let (w, cin) = (config.width, config.input_channels());
        let first_taps = w * cin + w + 3 * w + 3;
        let layers: [(&wgpu::ComputePipeline, usize, &wgpu::Buffer, &wgpu::Buffer); 4] = [
            (&self.pointwise, 0, &b, &a),
            (&self.residual, first_taps, &a, &b),
            (&self.residual, first_taps + RESIDUAL_TAPS + 3, &b, &a),
            (&self.compose, 0, &a, &image),
        ];
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        for (pipeline, offset, input, out) in layers {
            let params =
                uniform(gpu, &[width, height, config.conditioning_channels() as u32, w as u32, offset as u32, 0, 0, 0]);
            let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("synthesis"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: parameters.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: base.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: conditioning.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 4, resource: input.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 5, resource: out.as_entire_binding() },
                ],
            });
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        }
        gpu.queue.submit([encoder.finish()]);
        Ok((a, image))
    }
}

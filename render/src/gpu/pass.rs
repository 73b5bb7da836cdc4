//! What the single-pipeline passes (projection, blending) share: a compute pipeline from a
//! WGSL source whose bindings are its storage and uniform buffers in binding order, and one
//! dispatch of it.

use super::GpuRenderer;

/// A compute pipeline of `source`'s `main`, its layout taken from the shader.
pub fn compute_pipeline(device: &wgpu::Device, label: &'static str, source: &'static str) -> wgpu::ComputePipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// Submits `groups` workgroups of `pipeline` with `buffers` bound at 0, 1, 2, ... of group 0.
pub fn dispatch(gpu: &GpuRenderer, pipeline: &wgpu::ComputePipeline, buffers: &[&wgpu::Buffer], groups: [u32; 2]) {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
        .collect();
    let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.dispatch_workgroups(groups[0], groups[1], 1);
    }
    gpu.queue.submit([encoder.finish()]);
}

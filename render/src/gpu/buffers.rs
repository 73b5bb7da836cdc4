//! Buffers the GPU renderer's passes share: uploads checked against the device's binding
//! limit (so that an oversized scene is an error naming it, not a device loss), uniforms, and
//! reading results back.

use std::sync::mpsc;

use wgpu::util::DeviceExt;

use super::{GpuError, GpuRenderer};

/// A storage buffer holding `contents` (at least 4 bytes: wgpu refuses empty bindings).
pub fn storage(gpu: &GpuRenderer, what: &'static str, contents: &[u8]) -> Result<wgpu::Buffer, GpuError> {
    check(gpu, what, contents.len() as u64)?;
    let padded;
    let contents = match contents.len() {
        0 => {
            padded = [0u8; 4];
            &padded[..]
        }
        _ => contents,
    };
    Ok(gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(what),
        contents,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    }))
}

/// An uninitialized storage buffer of `floats` f32 values that a pass writes.
pub fn output(gpu: &GpuRenderer, what: &'static str, floats: usize) -> Result<wgpu::Buffer, GpuError> {
    let bytes = (floats.max(1) * 4) as u64;
    check(gpu, what, bytes)?;
    Ok(gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(what),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    }))
}

/// A uniform buffer of 32-bit words (floats as their bits).
pub fn uniform(gpu: &GpuRenderer, words: &[u32]) -> wgpu::Buffer {
    gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("parameters"),
        contents: bytemuck::cast_slice(words),
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

fn check(gpu: &GpuRenderer, what: &'static str, bytes: u64) -> Result<(), GpuError> {
    let limits = gpu.device.limits();
    let limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    match bytes <= limit {
        true => Ok(()),
        false => Err(GpuError::TooLarge { what, bytes, limit }),
    }
}

/// The first `count` f32 values of `buffer`, copied back to the host.
pub fn read_f32(gpu: &GpuRenderer, buffer: &wgpu::Buffer, count: usize) -> Result<Vec<f32>, GpuError> {
    Ok(read_words(gpu, buffer, count)?.into_iter().map(f32::from_bits).collect())
}

/// The first `count` 32-bit words of `buffer`, copied back to the host.
pub fn read_words(gpu: &GpuRenderer, buffer: &wgpu::Buffer, count: usize) -> Result<Vec<u32>, GpuError> {
    let bytes = (count.max(1) * 4) as u64;
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, bytes);
    gpu.queue.submit([encoder.finish()]);
    let (sender, receiver) = mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |result| {
        // The receiver waits below; if it is gone there is no one to tell.
        let _ = sender.send(result);
    });
    gpu.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| GpuError::Readback(e.to_string()))?;
    receiver.recv().map_err(|e| GpuError::Readback(e.to_string()))?.map_err(|e| GpuError::Readback(e.to_string()))?;
    let view = staging.get_mapped_range(..).map_err(|e| GpuError::Readback(e.to_string()))?;
    Ok(view.chunks_exact(4).take(count).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect())
}

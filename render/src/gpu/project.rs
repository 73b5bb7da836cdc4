//! Projection on the GPU (`project.wgsl`): Gaussians held on the device are projected to
//! splats in place, and only what ordering needs (each splat's pixel box and depth, 20 bytes)
//! comes back to the CPU. A plain base's Gaussians are uploaded once ([`DeviceGaussians`]), so
//! a new view of them costs a uniform's upload, the projection and that readback.

use rayon::slice::ParallelSliceMut;

use crate::raster::project::ProjectionSettings;
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::{Gaussians, sh_coeff_count};

use super::buffers::{output, read_f32, read_words, storage, uniform};
use super::pass::{compute_pipeline, dispatch};
use super::{GpuError, GpuRenderer};

/// Values per splat in the buffer the projection writes and blending reads (`blend.wgsl`).
pub const SPLAT_STRIDE: usize = 12;

/// Invocations per workgroup (`project.wgsl`).
const WORKGROUP: u32 = 64;

/// The most workgroups a dispatch may have along one dimension (WebGPU's limit).
const MAX_GROUPS_PER_DIMENSION: u32 = 65_535;

/// Gaussians on the device, in `project.wgsl`'s layout: per Gaussian its mean, log scales,
/// quaternion and opacity logit in one buffer, and its SH coefficients in one buffer per band
/// (so that 1M Gaussians of degree 3 fit bindings of 128 MiB, WebGPU's default limit).
pub struct DeviceGaussians {
    geometry: wgpu::Buffer,
    bands: [wgpu::Buffer; 4],
    count: u32,
    sh_degree: u32,
}

impl DeviceGaussians {
    /// How many Gaussians were uploaded.
    pub fn count(&self) -> usize {
        self.count as usize
    }

    /// Uploads `gaussians` (SH degree at most 3).
    pub fn upload(gpu: &GpuRenderer, gaussians: &Gaussians) -> Result<Self, GpuError> {
        assert!(gaussians.is_consistent(), "Gaussian arrays have inconsistent lengths");
        if gaussians.sh_degree > 3 {
            return Err(GpuError::ShDegree(gaussians.sh_degree));
        }
        let n = gaussians.len();
        let count = u32::try_from(n).map_err(|_| GpuError::TooLarge {
            what: "Gaussians",
            bytes: n as u64 * 44,
            limit: u32::MAX.into(),
        })?;
        let mut geometry = Vec::with_capacity(n * 11);
        for i in 0..n {
            geometry.extend(gaussians.means[i]);
            geometry.extend(gaussians.log_scales[i]);
            geometry.extend(gaussians.rotations[i]);
            geometry.push(gaussians.opacity_logits[i]);
        }
        // Band l holds coefficients l^2 .. (l + 1)^2 of every Gaussian.
        let per_gaussian = 3 * sh_coeff_count(gaussians.sh_degree);
        let band = |l: usize| -> Vec<f32> {
            if l as u32 > gaussians.sh_degree {
                return Vec::new();
            }
            let (from, to) = (3 * l * l, 3 * (l + 1) * (l + 1));
            gaussians.sh.chunks_exact(per_gaussian).flat_map(|c| c[from..to].iter().copied()).collect()
        };
        let names = ["SH band 0", "SH band 1", "SH band 2", "SH band 3"];
        let mut bands = Vec::with_capacity(4);
        for (l, name) in names.into_iter().enumerate() {
            bands.push(storage(gpu, name, bytemuck::cast_slice(&band(l)))?);
        }
        Ok(Self {
            geometry: storage(gpu, "Gaussians", bytemuck::cast_slice(&geometry))?,
            bands: bands.try_into().expect("four bands"),
            count,
            sh_degree: gaussians.sh_degree,
        })
    }
}

/// A view's splats on the device, one slot per Gaussian (culled ones have an empty box).
pub struct Projected {
    /// [`SPLAT_STRIDE`] values per Gaussian.
    pub splats: wgpu::Buffer,
    /// x0, x1, y0, y1 per Gaussian: the pixels it covers.
    pub boxes: wgpu::Buffer,
    depths: wgpu::Buffer,
    count: usize,
}

impl Projected {
    /// The visible splats' Gaussian indices, front to back (by depth, ties by index, as
    /// [`crate::raster::sort_front_to_back`] orders them), with every Gaussian's box.
    pub fn front_to_back(&self, gpu: &GpuRenderer) -> Result<(Vec<u32>, Vec<[u32; 4]>), GpuError> {
        let words = read_words(gpu, &self.boxes, 4 * self.count)?;
        let boxes: Vec<[u32; 4]> = words.chunks_exact(4).map(|b| [b[0], b[1], b[2], b[3]]).collect();
        let depths = read_words(gpu, &self.depths, self.count)?;
        // A visible splat's depth is at least the near plane, so positive: its bits order as
        // its value, and (bits, index) in one u64 sorts as (depth, index).
        let mut keys: Vec<u64> = (0..self.count)
            .filter(|&i| boxes[i][0] < boxes[i][1])
            .map(|i| (u64::from(depths[i]) << 32) | i as u64)
            .collect();
        keys.par_sort_unstable();
        Ok((keys.into_iter().map(|k| k as u32).collect(), boxes))
    }

    /// Every Gaussian's splat as the blend pass reads it: [`SPLAT_STRIDE`] values each (mean
    /// x, y, Cholesky l11, l21, l22, opacity, r, g, b, unused).
    pub fn splat_values(&self, gpu: &GpuRenderer) -> Result<Vec<f32>, GpuError> {
        read_f32(gpu, &self.splats, SPLAT_STRIDE * self.count)
    }
}

/// The projection pipeline.
pub struct ProjectPass {
    pipeline: wgpu::ComputePipeline,
}

impl ProjectPass {
    pub fn new(device: &wgpu::Device) -> Self {
        let pipeline = compute_pipeline(device, "project", include_str!("project.wgsl"));
        Self { pipeline }
    }

    /// Submits the projection of `gaussians` for `camera`.
    pub fn run(
        &self,
        gpu: &GpuRenderer,
        gaussians: &DeviceGaussians,
        camera: &Camera,
        settings: &ProjectionSettings,
    ) -> Result<Projected, GpuError> {
        let count = gaussians.count as usize;
        let groups = gaussians.count.div_ceil(WORKGROUP);
        let groups_x = groups.clamp(1, MAX_GROUPS_PER_DIMENSION);
        let groups_y = groups.div_ceil(groups_x);
        let rows = [0, 1, 2].map(|r| camera.rotation.row(r));
        let t = camera.translation;
        let center = camera.center();
        let f = |v: f32| v.to_bits();
        #[rustfmt::skip]
        let words = [
            f(rows[0].x), f(rows[0].y), f(rows[0].z), f(t.x),
            f(rows[1].x), f(rows[1].y), f(rows[1].z), f(t.y),
            f(rows[2].x), f(rows[2].y), f(rows[2].z), f(t.z),
            f(center.x), f(center.y), f(center.z), 0,
            f(camera.fx), f(camera.fy), f(camera.cx), f(camera.cy),
            f(camera.width as f32), f(camera.height as f32), f(settings.near as f32), f(settings.blur as f32),
            f(settings.alpha_min as f32), gaussians.count, gaussians.sh_degree, 0,
            groups_x * WORKGROUP, 0, 0, 0,
        ];
        let buffers = [
            uniform(gpu, &words),
            output(gpu, "splats", count * SPLAT_STRIDE)?,
            output(gpu, "splat boxes", count * 4)?,
            output(gpu, "splat depths", count)?,
        ];
        let [b0, b1, b2, b3] = &gaussians.bands;
        let resources = [&buffers[0], &gaussians.geometry, b0, b1, b2, b3, &buffers[1], &buffers[2], &buffers[3]];
        if count > 0 {
            dispatch(gpu, &self.pipeline, &resources, [groups_x, groups_y]);
        }
        let [_, splats, boxes, depths] = buffers;
        Ok(Projected { splats, boxes, depths, count })
    }
}

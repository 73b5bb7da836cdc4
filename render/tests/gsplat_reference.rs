//! The forward rasterizer against gsplat, an implementation nobody here wrote: 16 Gaussians
//! with SH degree 3 rendered by gsplat (CUDA, classic mode), from `../shared/reference-renders`
//! (see `shared_data` for when its absence skips and when it fails).

mod shared_data;

use glam::{Mat3, Vec3};
use pwgs_core::camera::{Camera, Intrinsics};
use pwgs_core::gaussians::Gaussians;
use pwgs_render::raster::{RenderOptions, rasterize};
use safetensors::SafeTensors;

fn floats(tensors: &SafeTensors, name: &str) -> (Vec<usize>, Vec<f32>) {
    let t = tensors.tensor(name).unwrap_or_else(|e| panic!("tensor {name}: {e}"));
    assert_eq!(t.dtype(), safetensors::Dtype::F32, "{name} must be f32");
    let values = t.data().chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    (t.shape().to_vec(), values)
}

#[test]
fn matches_gsplat_basic_case() {
    let Some(path) = shared_data::path("reference-renders/gsplat_basic_case.safetensors") else { return };
    let bytes = std::fs::read(path).unwrap();
    let tensors = SafeTensors::deserialize(&bytes).unwrap();
    let (_, means) = floats(&tensors, "means");
    let (_, scales) = floats(&tensors, "scales");
    let (_, quats) = floats(&tensors, "quats");
    let (coeff_shape, coeffs) = floats(&tensors, "coeffs");
    let (_, opacities) = floats(&tensors, "opacities");
    let (img_shape, expected) = floats(&tensors, "out_img");
    assert_eq!(coeff_shape, vec![16, 16, 3]);
    assert_eq!(img_shape, vec![82, 123, 4]);

    let mut g = Gaussians::with_degree(3);
    for i in 0..16 {
        let v3 = |a: &[f32]| [a[i * 3], a[i * 3 + 1], a[i * 3 + 2]];
        let q = [quats[i * 4], quats[i * 4 + 1], quats[i * 4 + 2], quats[i * 4 + 3]];
        g.push(v3(&means), v3(&scales), q, opacities[i], &coeffs[i * 48..(i + 1) * 48]);
    }
    let center = Vec3::new(0.123, 0.456, -8.0);
    let cam = Camera::new(
        Intrinsics { width: 123, height: 82, fx: 61.5, fy: 61.5, cx: 61.5, cy: 41.0 },
        Mat3::IDENTITY,
        -center,
    )
    .unwrap();
    let out = rasterize(&g, &cam, &RenderOptions::default());
    let mut worst = 0.0f32;
    let mut covered = 0;
    for p in 0..123 * 82 {
        let ours =
            [out.color.data[p * 3], out.color.data[p * 3 + 1], out.color.data[p * 3 + 2], 1.0 - out.transmittance[p]];
        let reference = &expected[p * 4..p * 4 + 4];
        for c in 0..4 {
            let excess = (ours[c] - reference[c]).abs() - (1e-5 + 1e-2 * reference[c].abs());
            worst = worst.max(excess);
        }
        covered += usize::from(reference[3] > 0.1);
    }
    assert!(covered > 500, "the reference image should show the splats ({covered} pixels)");
    assert!(worst <= 0.0, "exceeds |ours - ref| < 1e-5 + 1e-2 |ref| by {worst}");
}

//! The GPU renderer (feature `gpu`) against the CPU reference: the conformance vectors (both
//! bases, the wrapper on and off) within SPEC.md section 8's render tolerance, and random
//! scenes within a float tolerance: at most 1e-4 per channel and 1e-6 on average (on lavapipe
//! the largest difference is about 2e-6: the GPU projects in f32 where the CPU projects in
//! f64, blending uses the CPU's exp, and a GPU compiler may fuse multiply-adds). Without a GPU
//! adapter these tests skip, saying so, unless `PWGS_REQUIRE_GPU` is set (CI installs lavapipe
//! and sets it).
#![cfg(feature = "gpu")]

use pwgs_render::show::SceneRender;
use std::path::Path;

use pwgs_codec::random_scene::wrapped_random_scene;
use pwgs_codec::stream;
use pwgs_core::camera_json::parse_camera;
use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};
use pwgs_core::rgb_image::RgbImage;
use pwgs_render::gpu::{GpuRenderer, Output};
use pwgs_render::raster::tile_lists::BinBudget;

fn renderer() -> Option<GpuRenderer> {
    match GpuRenderer::new() {
        Ok(gpu) => {
            eprintln!("GPU adapter: {}", gpu.adapter_name());
            Some(gpu)
        }
        Err(e) if std::env::var_os("PWGS_REQUIRE_GPU").is_some() => panic!("PWGS_REQUIRE_GPU is set: {e}"),
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
}

/// Largest and mean absolute difference of two images of one size.
fn differences(a: &RgbImage, b: &RgbImage) -> (f32, f64) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let d: Vec<f32> = a.data.iter().zip(&b.data).map(|(x, y)| (x - y).abs()).collect();
    (d.iter().copied().fold(0.0, f32::max), d.iter().map(|&v| f64::from(v)).sum::<f64>() / d.len() as f64)
}

/// SPEC.md section 8's tolerance on 8-bit renders: at most 2/255 per channel, 99.9% within 1/255.
fn within_render_tolerance(a: &RgbImage, b: &RgbImage) -> bool {
    let quantize = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as i32;
    let d: Vec<i32> = a.data.iter().zip(&b.data).map(|(x, y)| (quantize(*x) - quantize(*y)).abs()).collect();
    let within_one = d.iter().filter(|&&v| v <= 1).count() as f64 / d.len() as f64;
    d.iter().all(|&v| v <= 2) && within_one >= 0.999
}

#[test]
fn conformance_vectors_render_alike_on_the_gpu() {
    let Some(gpu) = renderer() else { return };
    let vectors = Path::new(env!("CARGO_MANIFEST_DIR")).join("../conformance/vectors");
    for name in ["anchors", "anchors-context", "generated-3dgs", "generated-3dgs-wrapped", "wrap-both-w64"] {
        let dir = vectors.join(name);
        let decoded = stream::decode(&std::fs::read(dir.join("stream.pwb")).unwrap()).unwrap();
        let scene = &decoded.scene;
        let prepared = gpu.prepare(scene).unwrap();
        let mut cameras: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "json") && p.file_name().unwrap() != "expected.json")
            .collect();
        cameras.sort();
        assert!(!cameras.is_empty(), "{name} has views");
        for path in cameras {
            let camera = parse_camera(&std::fs::read_to_string(&path).unwrap()).unwrap();
            let options = scene.render_options();
            for output in [Output::Shown, Output::Base] {
                let cpu = scene.render(&camera, &options, output == Output::Shown).unwrap();
                let (shown, _) = gpu.render(scene, &prepared, &camera, &options, output).unwrap();
                let (max, mean) = differences(&cpu.image, &shown.image);
                eprintln!("{name} {} {output:?}: max {max:.2e}, mean {mean:.2e}", path.display());
                assert!(within_render_tolerance(&cpu.image, &shown.image), "{name} {output:?}: max difference {max}");
                assert!(max < 1e-4 && mean < 1e-6, "{name} {output:?}: difference max {max}, mean {mean}");
                assert_eq!(shown.residual.is_some(), output == Output::Shown && scene.wrapper.is_some());
                if let (Some(a), Some(b)) = (&cpu.residual, &shown.residual) {
                    let worst = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max);
                    assert!(worst < 1e-4, "{name}: residual differs by {worst}");
                }
            }
        }
    }
}

/// A dense random scene (many overlapping splats per tile, early termination, a wrapper with
/// every input) agrees with the CPU in floats, not only in 8 bits.
#[test]
fn a_random_scene_renders_alike_on_the_gpu() {
    let Some(gpu) = renderer() else { return };
    let mut rng = SplitMix64(11);
    let gaussians = random_gaussians(&mut rng, 3000, 3, [-3.5, -1.5]);
    let camera = axis_camera(133, 97, 120.0, 118.0, 66.0, 49.0);
    let scene = wrapped_random_scene(&mut rng, gaussians, [0.2, 0.3, 0.4]);
    let options = scene.render_options();
    let prepared = gpu.prepare(&scene).unwrap();
    for output in [Output::Base, Output::Shown] {
        let cpu = scene.render(&camera, &options, output == Output::Shown).unwrap();
        let (gpu_shown, times) = gpu.render(&scene, &prepared, &camera, &options, output).unwrap();
        let (max, mean) = differences(&cpu.image, &gpu_shown.image);
        eprintln!("{output:?}: max {max:.2e}, mean {mean:.2e}; {times:?}");
        assert!(max < 1e-4 && mean < 1e-6, "{output:?}: difference max {max}, mean {mean}");
        assert!(within_render_tolerance(&cpu.image, &gpu_shown.image), "{output:?}: max difference {max}");
    }
}

/// Blended window by window within a small budget (bands of tile rows, spans of a row), the
/// view is the one the default budget gives, bit for bit: every pixel reads the same list.
#[test]
fn a_view_blended_in_many_windows_is_the_same_view() {
    let Some(mut gpu) = renderer() else { return };
    let mut rng = SplitMix64(17);
    let gaussians = random_gaussians(&mut rng, 2000, 1, [-3.0, -1.0]);
    let camera = axis_camera(150, 90, 130.0, 128.0, 75.0, 45.0);
    let scene = wrapped_random_scene(&mut rng, gaussians, [0.2, 0.3, 0.4]);
    let options = scene.render_options();
    let prepared = gpu.prepare(&scene).unwrap();
    let (whole, _) = gpu.render(&scene, &prepared, &camera, &options, Output::Base).unwrap();
    for budget in [BinBudget { entries: 3000, pixels: 1 << 20 }, BinBudget { entries: 1 << 30, pixels: 512 }] {
        gpu.set_bin_budget(budget);
        let (windowed, _) = gpu.render(&scene, &prepared, &camera, &options, Output::Base).unwrap();
        assert_eq!(windowed.image, whole.image, "{budget:?}");
    }
}

/// Large, nearly opaque splats whose lists exceed the bin budget (a small one here): the GPU's
/// tile lists end where a tile is surely opaque (the bound taken of the splats as the device
/// projected them), and its view agrees with the CPU's render from the full lists.
#[test]
fn lists_ending_at_opaque_tiles_render_alike_on_the_gpu() {
    let Some(mut gpu) = renderer() else { return };
    gpu.set_bin_budget(BinBudget { entries: 3000, pixels: 1 << 20 });
    let mut rng = SplitMix64(23);
    let mut gaussians = random_gaussians(&mut rng, 600, 1, [-1.5, 0.5]);
    for (i, o) in gaussians.opacity_logits.iter_mut().enumerate() {
        *o = if i % 5 == 0 { -4.0 } else { 3.0 };
    }
    let camera = axis_camera(120, 80, 110.0, 108.0, 60.0, 40.0);
    let scene = wrapped_random_scene(&mut rng, gaussians.clone(), [0.2, 0.3, 0.4]);
    let options = scene.render_options();
    let prepared = gpu.prepare(&scene).unwrap();
    let (shown, _) = gpu.render(&scene, &prepared, &camera, &options, Output::Base).unwrap();
    let full_lists = pwgs_render::raster::rasterize(&gaussians, &camera, &options);
    let (max, mean) = differences(&full_lists.color, &shown.image);
    assert!(max < 1e-4 && mean < 1e-6, "difference max {max}, mean {mean}");
}

/// Hard cases for the GPU's f32 projection against the CPU's f64: needles (axis ratios up to
/// e^14, 1.2 million), Gaussians larger than the scene (up to e^40, which the GPU projects in
/// shifted units, and e^10 far away, so that they show as blobs) and tiny ones (e^-30), one just past the near plane, and ones every renderer
/// must cull (behind the camera, NaN, an infinite scale, a zero quaternion), among ordinary
/// ones, and a line of scales e^40 and 1 (an axis ratio of 2e17, where `a c - b^2` would
/// cancel to noise even in f64; both renderers take the determinant as a sum of squares).
#[test]
fn hard_gaussians_project_alike_on_the_gpu() {
    let Some(gpu) = renderer() else { return };
    let mut rng = SplitMix64(5);
    let mut gaussians = random_gaussians(&mut rng, 1500, 3, [-3.5, -1.5]);
    for i in 0..300 {
        let l = gaussians.log_scales[i][0];
        gaussians.log_scales[i] = match i % 3 {
            0 => [l, l - 7.0, l],
            1 => [l + 1.0, l - 7.0, l - 14.0],
            _ => [l - 14.0, l, l - 14.0],
        };
    }
    let sh = gaussians.sh_of(0).to_vec();
    let q = [0.9, 0.1, -0.3, 0.2];
    // Low opacity, so that what they cover still shows.
    gaussians.push([0.2, -0.1, 3.0], [12.0, 11.0, 10.0], q, -3.0, &sh);
    gaussians.push([-0.3, 0.2, 4.0], [40.0, 39.0, 38.5], q, -3.5, &sh);
    gaussians.push([0.3, -0.2, 4.0], [40.0, 0.0, -5.0], q, -1.0, &sh);
    // Above e^8 and far away: blobs of tens of pixels, behind everything.
    gaussians.push([0.0, 0.0, 1e5], [10.0, 9.5, 10.2], q, 2.0, &sh);
    gaussians.push([2e4, 1e4, 1e5], [10.5, 6.0, 8.0], q, 2.0, &sh);
    gaussians.push([0.1, 0.1, 2.5], [-30.0, -30.0, -30.0], q, 3.0, &sh);
    gaussians.push([0.0, 0.0, 0.02], [-4.0, -4.5, -5.0], q, -2.0, &sh);
    gaussians.push([0.0, 0.0, -1.0], [-1.0; 3], q, 3.0, &sh);
    gaussians.push([f32::NAN, 0.0, 3.0], [-1.0; 3], q, 3.0, &sh);
    gaussians.push([0.0, 0.0, 3.0], [f32::INFINITY, -1.0, -1.0], q, 3.0, &sh);
    gaussians.push([0.0, 0.0, 3.0], [-1.0; 3], [0.0; 4], 3.0, &sh);
    let camera = axis_camera(160, 120, 150.0, 150.0, 80.0, 60.0);
    let scene = wrapped_random_scene(&mut rng, gaussians, [0.2, 0.3, 0.4]);
    let options = scene.render_options();
    let prepared = gpu.prepare(&scene).unwrap();
    let cpu = scene.render(&camera, &options, false).unwrap();
    let (shown, _) = gpu.render(&scene, &prepared, &camera, &options, Output::Base).unwrap();
    let (max, mean) = differences(&cpu.image, &shown.image);
    eprintln!("hard cases: max {max:.2e}, mean {mean:.2e}");
    assert!(max < 1e-4 && mean < 1e-6, "difference max {max}, mean {mean}");
}

//! Loading the real captures in `../shared/scenes` (see `shared_data` for when an absent scene
//! skips and when it fails).

#[path = "../../render/tests/shared_data/mod.rs"]
mod shared_data;

use std::path::PathBuf;

use pwgs_dataset::colmap::{CameraModel, find_model_dir, read_model};
use pwgs_dataset::undistort::Distortion;
use pwgs_dataset::{LoadOptions, load_cameras, load_scene};

fn shared_scene(name: &str) -> Option<PathBuf> {
    shared_data::path(&format!("scenes/{name}"))
}

#[test]
fn reads_the_fern_model() {
    let Some(scene) = shared_scene("fern") else { return };
    let dir = find_model_dir(&scene).expect("fern has a COLMAP model");
    let model = read_model(&dir).unwrap();
    assert_eq!(model.cameras.len(), 1);
    let camera = &model.cameras[0];
    assert_eq!((camera.model, camera.width, camera.height), (CameraModel::SimpleRadial, 4032, 3024));
    assert!((camera.params[0] - 3260.5).abs() < 1.0, "{camera:?}");
    assert!(matches!(camera.distortion(&dir).unwrap(), Distortion::Radial { .. }));
    assert_eq!(model.images.len(), 20);
    assert!(model.images.iter().all(|image| image.name.starts_with("IMG_") && image.camera_id == camera.id));
    assert_eq!(model.points.len(), 10_091);
    assert!(model.points.iter().all(|point| point.xyz.iter().all(|v| v.is_finite())));
}

#[test]
fn fern_from_colmap() {
    let Some(dir) = shared_scene("fern") else { return };
    let data = load_scene(&dir, &LoadOptions { downscale: 8, ..Default::default() }).unwrap();
    assert_eq!(data.format, "COLMAP");
    assert_eq!((data.train.len(), data.test.len()), (17, 3));
    assert_eq!(
        data.test.iter().map(|v| v.name.as_str()).collect::<Vec<_>>(),
        ["IMG_4026.JPG", "IMG_4034.JPG", "IMG_4042.JPG"]
    );
    for view in data.train.iter().chain(&data.test) {
        let cam = &view.camera;
        assert_eq!((cam.width, cam.height, view.image.width, view.image.height), (504, 378, 504, 378));
        // f = 3260.5 px at 4032 wide, scaled by 504 / 4032.
        assert!((cam.fx - 3260.526 / 8.0).abs() < 0.01 && (cam.fy - cam.fx).abs() < 1e-3, "fx {}", cam.fx);
        assert!((cam.cx - 252.0).abs() < 0.01 && (cam.cy - 189.0).abs() < 0.01);
    }
    // Reading only the JPEG headers gives the same cameras.
    let cameras = load_cameras(&dir, &LoadOptions { downscale: 8, ..Default::default() }).unwrap();
    let named = cameras.train.iter().chain(&cameras.test).map(|c| (c.name.as_str(), c.camera));
    assert!(named.eq(data.train.iter().chain(&data.test).map(|v| (v.name.as_str(), v.camera))));
    // Every view sees most SfM points in front of it and inside the image (a forward-facing
    // capture): wrong poses, axes or intrinsics would throw them out.
    let points = data.points.as_ref().expect("COLMAP scenes carry their SfM points");
    assert_eq!(points.positions.len(), 10_091);
    for view in data.train.iter().chain(&data.test) {
        let inside = points
            .positions
            .iter()
            .filter_map(|p| view.camera.project(glam::Vec3::from(*p)))
            .filter(|&(u, v)| (0.0..504.0).contains(&u) && (0.0..378.0).contains(&v))
            .count();
        let share = inside as f64 / points.positions.len() as f64;
        assert!(share > 0.8, "{}: only {:.1}% of points project inside", view.name, share * 100.0);
    }
    // The SfM points' colors agree with the images where they land, far better than at a
    // position shifted by 12 pixels (foliage makes single-pixel colors noisy, so the check is
    // relative).
    let view = &data.train[0];
    let color_error = |shift: f32| {
        let (mut err, mut n) = (0.0f64, 0usize);
        for (p, c) in points.positions.iter().zip(&points.colors) {
            let Some((u, v)) = view.camera.project(glam::Vec3::from(*p)) else { continue };
            let u = u + shift;
            if (0.0..504.0).contains(&u) && (0.0..378.0).contains(&v) {
                let px = view.image.pixel(u as u32, v as u32);
                err += (0..3).map(|k| (px[k] - c[k]).abs() as f64).sum::<f64>() / 3.0;
                n += 1;
            }
        }
        err / n as f64
    };
    let (aligned, shifted) = (color_error(0.0), color_error(12.0));
    eprintln!("SfM color error: {aligned:.4} aligned, {shifted:.4} shifted by 12 px");
    assert!(aligned < 0.75 * shifted, "SfM colors do not match the image: error {aligned} vs {shifted} when shifted");
}

#[test]
fn fern_llff_poses_agree_with_colmap() {
    let Some(dir) = shared_scene("fern") else { return };
    // Copy poses_bounds.npy and the images next to each other, without the sparse model, so the
    // LLFF fallback is used.
    let tmp = tempfile::tempdir().unwrap();
    std::fs::copy(dir.join("poses_bounds.npy"), tmp.path().join("poses_bounds.npy")).unwrap();
    std::os::unix::fs::symlink(dir.join("images_8"), tmp.path().join("images_8")).unwrap();
    let options = LoadOptions { downscale: 8, ..Default::default() };
    let llff = load_scene(tmp.path(), &options).unwrap();
    let colmap = load_scene(&dir, &options).unwrap();
    assert_eq!(llff.format, "LLFF poses_bounds.npy");
    assert_eq!((llff.train.len(), llff.test.len()), (17, 3));
    for (a, b) in llff.train.iter().zip(&colmap.train) {
        let da = a.camera.center().distance(b.camera.center());
        let rot = (a.camera.rotation - b.camera.rotation).to_cols_array().iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(da < 1e-3 && rot < 1e-3, "{}: center off by {da}, rotation by {rot}", a.name);
        assert!((a.camera.fx - b.camera.fx).abs() < 0.5, "focal {} vs {}", a.camera.fx, b.camera.fx);
    }
}

#[test]
fn lego_blender_over_white() {
    let Some(dir) = shared_scene("lego") else { return };
    let data = load_scene(&dir, &LoadOptions { downscale: 4, background: [1.0; 3], ..Default::default() }).unwrap();
    assert_eq!((data.train.len(), data.test.len()), (100, 25));
    let angle_x: f64 = 0.6911112070083618;
    let expected_fx = (0.5 * 800.0 / (0.5 * angle_x).tan() / 4.0) as f32;
    for view in data.train.iter().chain(&data.test) {
        assert_eq!((view.image.width, view.image.height), (200, 200));
        assert!((view.camera.fx - expected_fx).abs() < 1e-2 && view.camera.cx == 100.0);
        // The object is at the origin: every camera looks at it.
        let (u, v) = view.camera.project(glam::Vec3::ZERO).expect("origin in front");
        assert!((u - 100.0).abs() < 20.0 && (v - 100.0).abs() < 20.0, "{}: origin at ({u}, {v})", view.name);
    }
    // Corners are background: composited over white.
    assert_eq!(data.train[0].image.pixel(0, 0), [1.0; 3]);
}

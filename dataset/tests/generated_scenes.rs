//! Loading on data the project generates: the procedural scene as transforms.json, the same
//! cameras as COLMAP models (binary and text), and broken inputs.

use std::path::Path;

use pwgs_core::camera::matrix_to_quaternion;
use pwgs_dataset::colmap::{
    CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint, write_binary, write_text,
};
use pwgs_dataset::npy::{NpyArray, encode_npy};
use pwgs_dataset::synthetic::{SyntheticOptions, cameras, generate};
use pwgs_dataset::{Dataset, DatasetError, LoadOptions, load_cameras, load_scene};

fn small() -> SyntheticOptions {
    SyntheticOptions { width: 48, height: 36, views: 10, seed: 3, points: 300 }
}

fn generated(dir: &Path) -> Dataset {
    generate(dir, &small()).unwrap();
    load_scene(dir, &LoadOptions::default()).unwrap()
}

#[test]
fn generated_scene_loads_with_every_8th_view_for_testing() {
    let tmp = tempfile::tempdir().unwrap();
    let data = generated(tmp.path());
    assert_eq!(data.format, "transforms");
    assert_eq!((data.train.len(), data.test.len()), (8, 2));
    assert_eq!(data.test[1].name, "view_008.png");
    assert_eq!(data.points.as_ref().unwrap().positions.len(), 300);
    let expected = cameras(&small());
    for (view, cam) in data.test.iter().zip([expected[0], expected[8]]) {
        assert!((view.camera.center() - cam.center()).length() < 1e-4);
        assert!((view.camera.fx - cam.fx).abs() < 1e-4 && (view.camera.cy - cam.cy).abs() < 1e-4);
    }
}

#[test]
fn downscale_halves_images_and_intrinsics() {
    let tmp = tempfile::tempdir().unwrap();
    generate(tmp.path(), &small()).unwrap();
    let full = load_scene(tmp.path(), &LoadOptions::default()).unwrap();
    let half = load_scene(tmp.path(), &LoadOptions { downscale: 2, ..Default::default() }).unwrap();
    let (a, b) = (&full.train[0], &half.train[0]);
    assert_eq!((b.image.width, b.image.height), (24, 18));
    assert!((b.camera.fx * 2.0 - a.camera.fx).abs() < 1e-4 && (b.camera.cx * 2.0 - a.camera.cx).abs() < 1e-4);
    // A 2x2 block average of the full image.
    let p = a.image.pixel(6, 8);
    let q = [a.image.pixel(7, 8), a.image.pixel(6, 9), a.image.pixel(7, 9)];
    let mean = std::array::from_fn::<f32, 3, _>(|c| (p[c] + q[0][c] + q[1][c] + q[2][c]) / 4.0);
    assert_eq!(b.image.pixel(3, 4), mean);
}

/// Writes the generated scene's cameras as a COLMAP model next to its images.
fn as_colmap(data: &Dataset, dir: &Path, text: bool) {
    write_colmap(&colmap_model(data), dir, text);
}

fn write_colmap(model: &ColmapModel, dir: &Path, text: bool) {
    let sparse = dir.join("sparse/0");
    std::fs::create_dir_all(&sparse).unwrap();
    if text { write_text(model, &sparse).unwrap() } else { write_binary(model, &sparse).unwrap() }
}

/// The generated scene's cameras as a COLMAP model, with one 3D point.
fn colmap_model(data: &Dataset) -> ColmapModel {
    let views: Vec<_> = data.test.iter().chain(&data.train).collect();
    let cam = views[0].camera;
    let mut model = ColmapModel {
        cameras: vec![ColmapCamera {
            id: 1,
            model: CameraModel::Pinhole,
            width: cam.width as u64,
            height: cam.height as u64,
            params: vec![cam.fx as f64, cam.fy as f64, cam.cx as f64, cam.cy as f64],
        }],
        ..Default::default()
    };
    for (id, view) in views.iter().enumerate() {
        model.images.push(ColmapImage {
            id: id as u32 + 1,
            qvec: matrix_to_quaternion(view.camera.rotation),
            tvec: view.camera.translation.as_dvec3().to_array(),
            camera_id: 1,
            name: view.name.clone(),
            points2d: Vec::new(),
        });
    }
    model.points.push(ColmapPoint { id: 1, xyz: [0.0, 0.1, 0.2], rgb: [10, 20, 30], error: 0.5, track: Vec::new() });
    model
}

#[test]
fn colmap_binary_and_text_models_give_the_same_cameras() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    let data = generated(&scene);
    for text in [false, true] {
        let dir = tmp.path().join(if text { "colmap_text" } else { "colmap_bin" });
        std::fs::create_dir_all(&dir).unwrap();
        std::os::unix::fs::symlink(scene.join("images"), dir.join("images")).unwrap();
        as_colmap(&data, &dir, text);
        let loaded = load_scene(&dir, &LoadOptions::default()).unwrap();
        assert_eq!(loaded.format, "COLMAP");
        assert_eq!((loaded.train.len(), loaded.test.len()), (8, 2));
        for (a, b) in loaded.train.iter().chain(&loaded.test).zip(data.train.iter().chain(&data.test)) {
            assert_eq!(a.name, b.name);
            assert!((a.camera.center() - b.camera.center()).length() < 1e-4, "{}", a.name);
            assert!((a.camera.rotation - b.camera.rotation).abs_diff_eq(glam::Mat3::ZERO, 1e-5));
            assert_eq!(a.image, b.image);
        }
        assert_eq!(loaded.points.unwrap().positions, vec![[0.0, 0.1, 0.2]]);
    }
}

#[test]
fn cameras_alone_are_those_of_the_loaded_views() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    let data = generated(&scene);
    let colmap = tmp.path().join("colmap");
    std::fs::create_dir_all(&colmap).unwrap();
    std::os::unix::fs::symlink(scene.join("images"), colmap.join("images")).unwrap();
    as_colmap(&data, &colmap, false);
    for (dir, downscale) in [(&scene, 1), (&scene, 2), (&colmap, 3)] {
        let options = LoadOptions { downscale, ..Default::default() };
        let views = load_scene(dir, &options).unwrap();
        let cameras = load_cameras(dir, &options).unwrap();
        for (views, cameras) in [(&views.train, &cameras.train), (&views.test, &cameras.test)] {
            assert_eq!(views.len(), cameras.len());
            for (view, named) in views.iter().zip(cameras) {
                assert_eq!((&named.name, named.camera), (&view.name, view.camera), "downscale {downscale}");
                assert_eq!((named.camera.width, named.camera.height), (view.image.width, view.image.height));
            }
        }
    }
    // A file that is not an image is named in the error.
    std::fs::write(scene.join("images/view_003.png"), b"not a png").unwrap();
    let message = load_cameras(&scene, &LoadOptions::default()).unwrap_err().to_string();
    assert!(message.contains("view_003.png"), "{message}");
}

/// Loading must fail with an error whose message contains `needle`.
fn assert_load_error(dir: &Path, needle: &str) {
    match load_scene(dir, &LoadOptions::default()) {
        Ok(_) => panic!("loading {} should fail", dir.display()),
        Err(e) => {
            let message = e.to_string();
            assert!(message.contains(needle), "error `{message}` should mention `{needle}`");
        }
    }
}

fn edit_transforms(dir: &Path, edit: impl Fn(&mut serde_json::Value)) {
    let path = dir.join("transforms.json");
    let mut json: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    edit(&mut json);
    std::fs::write(path, serde_json::to_vec(&json).unwrap()).unwrap();
}

#[test]
fn broken_inputs_are_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    assert_load_error(&tmp.path().join("missing"), "does not exist");
    assert!(matches!(load_scene(tmp.path(), &LoadOptions::default()), Err(DatasetError::UnknownFormat { .. })));

    let fresh = |name: &str| {
        let dir = tmp.path().join(name);
        generate(&dir, &small()).unwrap();
        dir
    };
    let dir = fresh("truncated");
    let text = std::fs::read(dir.join("transforms.json")).unwrap();
    std::fs::write(dir.join("transforms.json"), &text[..text.len() / 2]).unwrap();
    assert_load_error(&dir, "transforms.json: invalid JSON");

    let dir = fresh("missing_image");
    std::fs::remove_file(dir.join("images/view_003.png")).unwrap();
    assert_load_error(&dir, "view_003.png");

    let dir = fresh("nan_pose");
    edit_transforms(&dir, |j| j["frames"][2]["transform_matrix"][0][3] = serde_json::json!("NaN"));
    assert_load_error(&dir, "transforms.json");

    let dir = fresh("scaled_pose");
    edit_transforms(&dir, |j| {
        for r in 0..3 {
            for c in 0..3 {
                let v = j["frames"][1]["transform_matrix"][r][c].as_f64().unwrap();
                j["frames"][1]["transform_matrix"][r][c] = serde_json::json!(v * 2.0);
            }
        }
    });
    assert_load_error(&dir, "not orthonormal");

    let dir = fresh("no_focal");
    edit_transforms(&dir, |j| {
        j.as_object_mut().unwrap().remove("fl_x");
    });
    assert_load_error(&dir, "no focal length");

    let dir = fresh("fisheye");
    edit_transforms(&dir, |j| j["camera_model"] = serde_json::json!("OPENCV_FISHEYE"));
    assert_load_error(&dir, "OPENCV_FISHEYE");

    let dir = fresh("corrupt_png");
    std::fs::write(dir.join("images/view_001.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    assert_load_error(&dir, "view_001.png");

    let dir = fresh("bad_points");
    std::fs::write(
        dir.join("points3d.ply"),
        b"ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nend_header\n1 2\n",
    )
    .unwrap();
    assert_load_error(&dir, "points3d.ply");
}

#[test]
fn hostile_colmap_values_are_errors_naming_file_and_record() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    let data = generated(&scene);
    type Edit = fn(&mut ColmapModel);
    let cases: [(&str, Edit, &str); 6] = [
        (
            "nan_point",
            |m| m.points[0].xyz[1] = f64::NAN,
            "points3D.{ext}: point 1 has position [0.0, NaN, 0.2], which is not finite (in f32)",
        ),
        ("f32_overflow_point", |m| m.points[0].xyz[0] = 1e39, "points3D.{ext}: point 1 has position [1e39,"),
        (
            "nan_distortion",
            |m| {
                m.cameras[0].model = CameraModel::SimpleRadial;
                m.cameras[0].params = vec![m.cameras[0].params[0], 24.0, 18.0, f64::NAN];
            },
            "cameras.{ext}: camera 1: distortion Radial { k1: NaN, k2: 0.0 } has a non-finite coefficient",
        ),
        (
            // f = 40 px on 48x36 images: corners at a normalized radius of 0.75; k1 = -1 folds
            // the image over from a radius of 0.58 on.
            "folding_distortion",
            |m| {
                m.cameras[0].model = CameraModel::SimpleRadial;
                m.cameras[0].params = vec![40.0, 24.0, 18.0, -1.0];
            },
            "cameras.{ext}: camera 1: distortion Radial { k1: -1.0, k2: 0.0 } folds the image over",
        ),
        ("zero_focal", |m| m.cameras[0].params[0] = 0.0, "cameras.{ext}: camera 1: camera rejected (params [0.0,"),
        (
            "f32_overflow_translation",
            |m| m.images[3].tvec[2] = -1e300, // view_002: the model lists the test views first
            "images.{ext}: image `view_002.png`: translation [",
        ),
    ];
    for (name, edit, expected) in cases {
        for text in [false, true] {
            let dir = tmp.path().join(format!("{name}_{text}"));
            std::fs::create_dir_all(&dir).unwrap();
            std::os::unix::fs::symlink(scene.join("images"), dir.join("images")).unwrap();
            let mut model = colmap_model(&data);
            edit(&mut model);
            write_colmap(&model, &dir, text);
            assert_load_error(&dir, &expected.replace("{ext}", if text { "txt" } else { "bin" }));
        }
    }
}

#[test]
fn hostile_transforms_values_are_errors_naming_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let fresh = |name: &str| {
        let dir = tmp.path().join(name);
        generate(&dir, &small()).unwrap();
        dir
    };
    type Edit = fn(&mut serde_json::Value);
    let cases: [(&str, Edit, &str); 5] = [
        (
            // Degrees instead of radians give a plausible focal length of the wrong size.
            "angle_in_degrees",
            |j| {
                j.as_object_mut().unwrap().remove("fl_x");
                j["camera_angle_x"] = serde_json::json!(40.0);
            },
            "frame 0 (`images/view_000.png`): `camera_angle_x` = 40 is not a field of view in radians",
        ),
        (
            "flat_angle_y",
            |j| {
                j.as_object_mut().unwrap().remove("fl_x");
                j["camera_angle_x"] = serde_json::json!(1.0);
                j["camera_angle_y"] = serde_json::json!(0.0);
            },
            "`camera_angle_y` = 0 is not a field of view in radians",
        ),
        ("fractional_size", |j| j["w"] = serde_json::json!(48.5), "intrinsic image size 48.5x36 is not whole pixels"),
        (
            "folding_distortion",
            |j| j["k1"] = serde_json::json!(-1.0),
            "distortion Opencv { k1: -1.0, k2: 0.0, p1: 0.0, p2: 0.0 } folds the image over",
        ),
        (
            // Cameras 6.4e38 apart: each pose is fine, the scene's extent overflows f32.
            "far_apart_cameras",
            |j| {
                j["frames"][1]["transform_matrix"][0][3] = serde_json::json!(3.2e38);
                j["frames"][2]["transform_matrix"][0][3] = serde_json::json!(-3.2e38);
            },
            "the training cameras are too far apart to normalize the scene in 32-bit floats",
        ),
    ];
    for (name, edit, expected) in cases {
        let dir = fresh(name);
        edit_transforms(&dir, edit);
        assert_load_error(&dir, expected);
    }
}

#[test]
fn llff_sizes_must_be_whole_pixels() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    generate(&scene, &small()).unwrap();
    let dir = tmp.path().join("llff");
    std::fs::create_dir_all(&dir).unwrap();
    std::os::unix::fs::symlink(scene.join("images"), dir.join("images")).unwrap();
    // Identity poses, h = 36.5: read as 36 before, silently.
    let mut row = [0.0; 17];
    (row[1], row[5], row[12]) = (1.0, -1.0, 1.0); // (down, right, back) columns
    (row[4], row[9], row[14]) = (36.5, 48.0, 40.0);
    let data = row.iter().copied().cycle().take(17 * small().views).collect();
    let npy = NpyArray { shape: vec![small().views, 17], data };
    std::fs::write(dir.join("poses_bounds.npy"), encode_npy(&npy)).unwrap();
    assert_load_error(&dir, "poses_bounds.npy: pose 0: image size 48x36.5 is not whole pixels in 1..=65535");
}

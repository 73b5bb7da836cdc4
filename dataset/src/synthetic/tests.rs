use std::path::Path;

use glam::{Mat4, Vec2, Vec3};
use pwgs_core::camera::{Camera, Intrinsics};
use pwgs_core::ply::point_cloud_from_bytes;

use super::scene::{OBJECTS, Shape, intersect};
use super::*;

/// Small enough to keep the tests fast, large enough that every object shows.
fn small_options() -> SyntheticOptions {
    SyntheticOptions { width: 64, height: 48, views: 4, seed: 7, points: 500 }
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn generates_a_complete_dataset_byte_identically() {
    let options = small_options();
    let (first, second) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    // A nested path checks that missing folders are created.
    let dir = first.path().join("scene");
    let summary = generate(&dir, &options).unwrap();
    assert_eq!(summary, SyntheticSummary { views: 4, width: 64, height: 48, points: 500 });
    generate(second.path(), &options).unwrap();

    let json: serde_json::Value = serde_json::from_slice(&read(&dir.join("transforms.json"))).unwrap();
    assert_eq!(json["camera_model"], "PINHOLE");
    assert_eq!((json["w"].as_u64(), json["h"].as_u64()), (Some(64), Some(48)));
    assert_eq!(json["ply_file_path"], "points3d.ply");
    let frames = json["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 4);
    let mut files = vec!["transforms.json".to_string(), "points3d.ply".to_string()];
    for frame in frames {
        let file = frame["file_path"].as_str().unwrap().to_string();
        assert_eq!(image::image_dimensions(dir.join(&file)).unwrap(), (64, 48), "{file}");
        files.push(file);
    }
    let cloud = point_cloud_from_bytes(&read(&dir.join("points3d.ply"))).unwrap();
    assert_eq!(cloud.positions.len(), 500);
    for file in files {
        assert!(read(&dir.join(&file)) == read(&second.path().join(&file)), "{file} differs between runs");
    }
}

/// The poses in transforms.json, read back through the OpenGL constructor, are the cameras.
#[test]
fn transforms_poses_are_the_cameras_in_opengl_convention() {
    let options = small_options();
    let dir = tempfile::tempdir().unwrap();
    generate(dir.path(), &options).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&read(&dir.path().join("transforms.json"))).unwrap();
    let number = |key: &str| json[key].as_f64().unwrap() as f32;
    for (frame, expected) in json["frames"].as_array().unwrap().iter().zip(cameras(&options)) {
        let rows: Vec<f32> = frame["transform_matrix"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|row| row.as_array().unwrap().iter().map(|v| v.as_f64().unwrap() as f32))
            .collect();
        let c2w = Mat4::from_cols_slice(&rows).transpose();
        let camera = Camera::from_opengl_camera_to_world(
            Intrinsics {
                width: 64,
                height: 48,
                fx: number("fl_x"),
                fy: number("fl_y"),
                cx: number("cx"),
                cy: number("cy"),
            },
            c2w,
        )
        .unwrap();
        assert!((camera.rotation - expected.rotation).abs_diff_eq(glam::Mat3::ZERO, 1e-5));
        assert!(camera.translation.abs_diff_eq(expected.translation, 1e-5));
        assert_eq!((camera.fx, camera.cx, camera.cy), (expected.fx, expected.cx, expected.cy));
    }
}

#[test]
fn rendering_does_not_depend_on_the_thread_count() {
    let camera = cameras(&small_options())[1];
    let on = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render(&camera, 7))
    };
    let single = on(1);
    assert!(single.data.iter().all(|v| (0.0..=1.0).contains(v)));
    assert!(single == on(3));
}

/// Whether every ray through the corners and the center of pixel (x, y) satisfies `accept`,
/// which receives the hit, if any. Corners are included so that a pixel straddling an edge is
/// not counted as inside a region.
fn pixel_rays_all(camera: &Camera, x: u32, y: u32, accept: impl Fn(Option<scene::Hit>) -> bool) -> bool {
    let (u, v) = (x as f32, y as f32);
    [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)]
        .into_iter()
        .all(|(du, dv)| accept(intersect(camera.center(), camera.ray_direction(u + du, v + dv))))
}

/// The ground is exactly the hits at height 0 facing up (object hits are never at height 0
/// with an upward normal).
fn is_ground(hit: Option<scene::Hit>) -> bool {
    hit.is_some_and(|hit| hit.point.y == 0.0 && hit.normal == Vec3::Y)
}

/// Mean absolute difference between horizontally adjacent pixels, over pairs both in a region.
fn adjacent_difference(camera: &Camera, image: &RgbImage, in_region: &dyn Fn(u32, u32) -> bool) -> f32 {
    let (mut sum, mut pairs) = (0.0, 0);
    for y in 0..image.height {
        for x in 0..image.width - 1 {
            if in_region(x, y) && in_region(x + 1, y) {
                let (a, b) = (image.pixel(x, y), image.pixel(x + 1, y));
                sum += (0..3).map(|c| (a[c] - b[c]).abs()).sum::<f32>() / 3.0;
                pairs += 1;
            }
        }
    }
    assert!(pairs > 100, "only {pairs} pixel pairs in the region of a {}x{} view", camera.width, camera.height);
    sum / pairs as f32
}

/// A 3x3 box blur (borders kept): roughly what a splat model that cannot resolve single pixels
/// renders.
fn box_blur(image: &RgbImage) -> RgbImage {
    let mut blurred = image.clone();
    for y in 1..image.height - 1 {
        for x in 1..image.width - 1 {
            let mut sum = [0.0; 3];
            for (dx, dy) in (0..3).flat_map(|dy| (0..3).map(move |dx| (dx, dy))) {
                let p = image.pixel(x + dx - 1, y + dy - 1);
                (0..3).for_each(|c| sum[c] += p[c] / 9.0);
            }
            blurred.set_pixel(x, y, sum);
        }
    }
    blurred
}

/// The codec's perceptual wrapper exists for texture that Gaussians blur, so the scene must
/// have it. At the default resolution adjacent ground pixels differ by 0.05 to 0.07 on average
/// over the 24 views (13 to 18 levels of 8 bits); the threshold 0.04 leaves a margin. Most of
/// that difference must be at the finest scale: a 3x3 box blur removes about 70% of it (a
/// smooth texture would lose almost nothing), so the test asks for a 2.5x drop. The sky, a
/// smooth gradient, differs by under 0.0001 between neighbors.
#[test]
fn ground_texture_is_high_frequency() {
    let camera = cameras(&SyntheticOptions::default())[0];
    let image = render(&camera, 1);
    // Away from the border, which the blur leaves unchanged.
    let interior = |x, y| x > 0 && y > 0 && x + 2 < camera.width && y + 1 < camera.height;
    let ground = |x, y| interior(x, y) && pixel_rays_all(&camera, x, y, is_ground);
    let sky = |x, y| pixel_rays_all(&camera, x, y, |hit| hit.is_none());
    let ground_difference = adjacent_difference(&camera, &image, &ground);
    let blurred_difference = adjacent_difference(&camera, &box_blur(&image), &ground);
    let sky_difference = adjacent_difference(&camera, &image, &sky);
    assert!(ground_difference > 0.04, "ground texture too weak: {ground_difference}");
    assert!(
        ground_difference > 2.5 * blurred_difference,
        "ground texture not fine: {ground_difference}, blurred {blurred_difference}"
    );
    assert!(sky_difference < 0.001, "sky not smooth: {sky_difference}");
    assert!(ground_difference > 40.0 * sky_difference);
}

/// Distance from `p` to the surface of `shape` (exact for these shapes).
fn surface_distance(shape: Shape, p: Vec3) -> f32 {
    match shape {
        Shape::Disk { radius } => (p.y.abs()).max(Vec2::new(p.x, p.z).length() - radius),
        Shape::Sphere { center, radius } => ((p - center).length() - radius).abs(),
        Shape::Cuboid { min, max } => {
            let q = (p - 0.5 * (min + max)).abs() - 0.5 * (max - min);
            (q.max(Vec3::ZERO).length() + q.max_element().min(0.0)).abs()
        }
        Shape::Cylinder { base, radius, height } => {
            let local = p - base;
            let q =
                Vec2::new(Vec2::new(local.x, local.z).length() - radius, (local.y - 0.5 * height).abs() - 0.5 * height);
            (q.max(Vec2::ZERO).length() + q.max_element().min(0.0)).abs()
        }
    }
}

/// SfM points must be where a trained model needs them: on surfaces, above the ground, and seen
/// unoccluded by at least one camera.
#[test]
fn points_lie_on_visible_surfaces() {
    let options = small_options();
    let cameras = cameras(&options);
    let cloud = sample_points(&cameras, 400, options.seed).unwrap();
    assert_eq!(cloud.positions.len(), 400);
    let (mut on_objects, mut in_sky) = (0, 0);
    for (position, color) in cloud.positions.iter().zip(&cloud.colors) {
        let p = Vec3::from_array(*position);
        if ((p - TARGET).length() - SKY_RADIUS).abs() < 1e-3 * SKY_RADIUS {
            // A sky point: seen by a camera through a ray that misses the scene.
            in_sky += 1;
            let seen = cameras.iter().any(|camera| {
                let direction = (p - camera.center()).normalize();
                let inside = camera.project(p).is_some_and(|(u, v)| {
                    (0.0..camera.width as f32).contains(&u) && (0.0..camera.height as f32).contains(&v)
                });
                inside && intersect(camera.center(), direction).is_none()
            });
            assert!(seen, "sky point {p} is not seen past the scene by any camera");
            continue;
        }
        assert!(p.y >= -1e-4, "{p} is below the ground");
        assert!(color.iter().all(|c| (0.0..=1.0).contains(c)), "{color:?}");
        let distance = OBJECTS.iter().map(|object| surface_distance(object.shape, p)).fold(f32::MAX, f32::min);
        assert!(distance < 1e-3, "{p} is {distance} away from every surface");
        on_objects += usize::from(p.y > 1e-3);
        let seen = cameras.iter().any(|camera| {
            let inside = camera.project(p).is_some_and(|(u, v)| {
                (0.0..camera.width as f32).contains(&u) && (0.0..camera.height as f32).contains(&v)
            });
            let to_point = p - camera.center();
            let first = intersect(camera.center(), to_point.normalize());
            inside && first.is_some_and(|hit| (hit.point - p).length() < 1e-3 * to_point.length())
        });
        assert!(seen, "{p} is not seen by any camera");
    }
    assert!(on_objects > 40, "only {on_objects} of 400 points are on the objects");
    assert!(in_sky > 0 && in_sky < 200, "{in_sky} of 400 points are in the sky");
}

#[test]
fn every_camera_sees_the_scene_center() {
    for options in
        [SyntheticOptions::default(), small_options(), SyntheticOptions { views: 3, seed: 99, ..small_options() }]
    {
        let cameras = cameras(&options);
        assert_eq!(cameras.len(), options.views);
        for camera in &cameras {
            let (u, v) = camera.project(TARGET).expect("scene center behind a camera");
            assert!((u - camera.cx).abs() < 1e-3 && (v - camera.cy).abs() < 1e-3, "center projects to ({u}, {v})");
            assert!(camera.center().y > 1.0, "camera {} is too low", camera.center());
        }
    }
}

/// The jitter must move cameras off a single circle, so views are not all coplanar.
#[test]
fn cameras_are_not_coplanar() {
    let heights: Vec<f32> = cameras(&SyntheticOptions::default()).iter().map(|c| c.center().y).collect();
    let (low, high) = heights.iter().fold((f32::MAX, f32::MIN), |(l, h), &y| (l.min(y), h.max(y)));
    assert!(high - low > 0.2, "camera heights span only {}", high - low);
}

#[test]
fn bad_options_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("never");
    let bad = [
        SyntheticOptions { width: 0, ..small_options() },
        SyntheticOptions { height: 0, ..small_options() },
        SyntheticOptions { width: 8193, ..small_options() },
        SyntheticOptions { views: 0, ..small_options() },
        SyntheticOptions { views: usize::MAX, ..small_options() },
        SyntheticOptions { points: usize::MAX, ..small_options() },
    ];
    for options in bad {
        let result = generate(&target, &options);
        assert!(matches!(result, Err(DatasetError::Malformed { .. })), "{options:?} gave {result:?}");
    }
    assert!(!target.exists(), "a rejected generation created files");
}

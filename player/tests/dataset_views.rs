//! `pwplay --scene`: the dataset's cameras to snap to and the ground truth beside the render,
//! on a generated scene.

use pwgs_core::rgb_image::RgbImage;
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_player::dataset_views::DatasetViews;

#[test]
fn dataset_views_give_their_cameras_and_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    generate(dir.path(), &SyntheticOptions { width: 64, height: 48, views: 9, seed: 3, points: 500 }).unwrap();
    let views = DatasetViews::load(dir.path(), 1).unwrap();
    let names = views.names();
    assert_eq!(names.len(), 9);
    // Every 8th view is a test view, listed first.
    assert_eq!(names.iter().filter(|n| n.starts_with("test ")).count(), 2);
    assert!(names[0].starts_with("test ") && names[2].starts_with("train "), "{names:?}");
    for i in 0..names.len() {
        let camera = views.camera(i);
        let again = views.orbit(i).camera(camera.width, camera.height).unwrap();
        assert!((again.center() - camera.center()).length() < 1e-3, "view {i}: the orbit starts at the camera");
        assert!((again.rotation.row(2) - camera.rotation.row(2)).length() < 1e-3, "view {i}: and looks where it looks");
    }
    // Split at 1: all ground truth; at 0: the render untouched; half: the left half.
    let render = RgbImage::filled(32, 24, [1.0, 0.0, 1.0]);
    let truth = image::open(dir.path().join("images/view_000.png")).unwrap().to_rgb8();
    let mut all = render.clone();
    views.overlay_ground_truth(0, &mut all, 1.0);
    let mut none = render.clone();
    views.overlay_ground_truth(0, &mut none, 0.0);
    assert_eq!(none.data, render.data);
    let mut half = render.clone();
    views.overlay_ground_truth(0, &mut half, 0.5);
    for (x, y) in [(0, 0), (15, 23), (31, 11)] {
        let expected = truth.get_pixel(2 * x, 2 * y).0.map(|v| f32::from(v) / 255.0);
        let got = all.pixel(x, y);
        assert!(
            got.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1.0 / 255.0),
            "({x}, {y}): {got:?} vs {expected:?}"
        );
        assert_eq!(half.pixel(x, y), if x < 16 { got } else { [1.0, 0.0, 1.0] });
    }
}

//! nerfstudio / Blender `transforms.json` loading: `transforms::parse`, then, for a file it
//! accepts, `load_cameras` (the view split and the fitting of each camera to its image).
//!
//! The input is written as `transforms.json` to a scratch folder that also holds three 8x6
//! images, `images/view_000.png` to `view_002.png`, and `points3d.ply`: the names
//! `pwenc generate-scene --views 3` uses, so its output (with 8x6 views) is a valid seed.
#![no_main]

use std::path::Path;
use std::sync::Once;

use libfuzzer_sys::fuzz_target;
use pwgs_dataset::{LoadOptions, load_cameras, transforms};
use pwgs_core::ply::{PointCloud, point_cloud_to_bytes};
use pwgs_core::rgb_image::RgbImage;
use pwgs_fuzz::{scratch_dir, write_scratch};

fn write_fixtures(dir: &Path) {
    let images = dir.join("images");
    std::fs::create_dir_all(&images).expect("scratch image folder");
    for i in 0..3 {
        let path = images.join(format!("view_{i:03}.png"));
        RgbImage::filled(8, 6, [0.25, 0.5, 0.75]).save_png(&path).expect("scratch image");
    }
    let cloud = PointCloud { positions: vec![[0.0, 1.0, 2.0], [-1.0, 0.5, 0.0]], colors: vec![[1.0, 0.0, 0.5]; 2] };
    write_scratch(&dir.join("points3d.ply"), &point_cloud_to_bytes(&cloud));
}

fuzz_target!(|data: &[u8]| {
    static FIXTURES: Once = Once::new();
    let dir = scratch_dir("transforms");
    FIXTURES.call_once(|| write_fixtures(dir));
    write_scratch(&dir.join("transforms.json"), data);
    if transforms::parse(dir).is_ok() {
        let _ = load_cameras(dir, &LoadOptions::default());
    }
});

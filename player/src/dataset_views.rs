//! `pwplay --scene DIR`: the dataset's cameras to snap to, with their ground truth beside the
//! render.

use std::path::Path;

use anyhow::{Context, Result};
use glam::Vec3;
use pwgs_core::camera::Camera;
use pwgs_core::rgb_image::RgbImage;
use pwgs_dataset::scene::{Dataset, LoadOptions, View, load_scene};

use crate::orbit::Orbit;

/// A dataset's training and test views, test views first.
pub struct DatasetViews {
    data: Dataset,
    /// The world's up: the mean of the cameras' up directions (OpenCV's -y).
    up: Vec3,
}

impl DatasetViews {
    pub fn load(dir: &Path, downscale: u32) -> Result<Self> {
        let options = LoadOptions { downscale: downscale.max(1), ..Default::default() };
        let data = load_scene(dir, &options).with_context(|| format!("cannot load the scene {}", dir.display()))?;
        let up = data.test.iter().chain(&data.train).map(|v| -(v.camera.rotation.transpose() * Vec3::Y)).sum::<Vec3>();
        Ok(Self { up: up.try_normalize().unwrap_or(Vec3::NEG_Y), data })
    }

    fn view(&self, i: usize) -> &View {
        let test = self.data.test.len();
        if i < test { &self.data.test[i] } else { &self.data.train[i - test] }
    }

    /// "test NAME" and "train NAME" for every view, in index order.
    pub fn names(&self) -> Vec<String> {
        let test = self.data.test.iter().map(|v| format!("test {}", v.name));
        test.chain(self.data.train.iter().map(|v| format!("train {}", v.name))).collect()
    }

    pub fn camera(&self, i: usize) -> Camera {
        self.view(i).camera
    }

    /// An orbit that starts at view `i`'s camera, around the point of the scene's center
    /// straight ahead of it.
    pub fn orbit(&self, i: usize) -> Orbit {
        let camera = self.camera(i);
        let distance = (self.data.normalization.center - camera.center()).length().max(1e-3);
        Orbit::from_camera(&camera, distance, self.up)
    }

    /// Puts view `i`'s ground truth into `image` left of `split` (a fraction of the width),
    /// scaled to `image`'s size.
    pub fn overlay_ground_truth(&self, i: usize, image: &mut RgbImage, split: f32) {
        let truth = &self.view(i).image;
        let columns = ((split.clamp(0.0, 1.0) * image.width as f32).round() as u32).min(image.width);
        for y in 0..image.height {
            let ty = (u64::from(y) * u64::from(truth.height) / u64::from(image.height)) as u32;
            for x in 0..columns {
                let tx = (u64::from(x) * u64::from(truth.width) / u64::from(image.width)) as u32;
                image.set_pixel(x, y, truth.pixel(tx, ty));
            }
        }
    }
}

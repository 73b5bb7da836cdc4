//! Loading a scene folder into a [`Dataset`]: format detection, image loading at the requested
//! downscale, distortion removal, train/test split and normalization.

use std::path::{Path, PathBuf};

use pwgs_core::camera::Camera;
use pwgs_core::ply::PointCloud;
use pwgs_core::rgb_image::RgbImage;
use rayon::prelude::*;

use crate::normalization::SceneNormalization;
use crate::undistort::{Distortion, undistort};
use crate::{DatasetError, colmap, colmap_scene, images, llff, transforms};

/// How to load a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadOptions {
    /// Integer downscale of the images (1 = as stored); intrinsics follow.
    pub downscale: u32,
    /// Color that transparent pixels (RGBA datasets) are composited over.
    pub background: [f32; 3],
    /// Every `test_every`-th view (0, N, 2N, ...) is a test view, unless the dataset has its own
    /// split.
    pub test_every: usize,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self { downscale: 1, background: [0.0; 3], test_every: 8 }
    }
}

/// One image with its camera (at the image's resolution, distortion removed).
#[derive(Debug, Clone)]
pub struct View {
    pub name: String,
    pub camera: Camera,
    pub image: RgbImage,
}

/// A loaded scene.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// Which loader read it, for reports.
    pub format: &'static str,
    pub train: Vec<View>,
    pub test: Vec<View>,
    /// SfM points for initialization, when the dataset has them.
    pub points: Option<PointCloud>,
    /// Derived from the training cameras.
    pub normalization: SceneNormalization,
}

/// A view before its image is loaded: the camera is at the resolution the format states its
/// intrinsics for.
#[derive(Debug, Clone)]
pub struct ViewSpec {
    pub name: String,
    pub image_path: PathBuf,
    pub camera: Camera,
    pub distortion: Distortion,
}

/// What a format loader produces.
#[derive(Debug, Clone)]
pub struct ParsedScene {
    pub format: &'static str,
    pub views: Vec<ViewSpec>,
    /// The dataset's own test views, when it defines a split.
    pub explicit_test: Option<Vec<ViewSpec>>,
    /// SfM points, when the format has them.
    pub points: Option<PointCloud>,
}

/// A view's name and camera, without its image.
#[derive(Debug, Clone)]
pub struct NamedCamera {
    pub name: String,
    pub camera: Camera,
}

impl NamedCamera {
    /// The view's name as a file stem: its image's name without folders or extension (what
    /// renders of the view are saved as).
    pub fn stem(&self) -> String {
        Path::new(&self.name).file_stem().map_or_else(|| self.name.clone(), |s| s.to_string_lossy().into())
    }
}

/// The cameras of a scene's views, split as [`load_scene`] splits them.
#[derive(Debug, Clone)]
pub struct SceneCameras {
    pub train: Vec<NamedCamera>,
    pub test: Vec<NamedCamera>,
}

/// Loads a scene folder. See the crate documentation for the formats, tried in order.
pub fn load_scene(dir: &Path, options: &LoadOptions) -> Result<Dataset, DatasetError> {
    let scene = parse_and_split(dir, options)?;
    let train = load_views(scene.train, scene.factor, options.background)?;
    let test = load_views(scene.test, scene.factor, options.background)?;
    let cameras: Vec<Camera> = train.iter().map(|v| v.camera).collect();
    let normalization = SceneNormalization::from_cameras(&cameras).ok_or_else(|| {
        DatasetError::malformed(dir, "the training cameras are too far apart to normalize the scene in 32-bit floats")
    })?;
    Ok(Dataset { format: scene.format, normalization, train, test, points: scene.points })
}

/// The cameras [`load_scene`] would give the views, reading only the images' headers: renderers
/// that need a dataset's viewpoints but not its pictures skip decoding them.
pub fn load_cameras(dir: &Path, options: &LoadOptions) -> Result<SceneCameras, DatasetError> {
    let scene = parse_and_split(dir, options)?;
    let cameras = |specs: Vec<ViewSpec>| {
        specs
            .into_par_iter()
            .map(|spec| {
                let (width, height) = images::dimensions(&spec.image_path, scene.factor)?;
                Ok(NamedCamera { camera: fit_camera(&spec, width, height)?, name: spec.name })
            })
            .collect::<Result<Vec<_>, DatasetError>>()
    };
    Ok(SceneCameras { train: cameras(scene.train)?, test: cameras(scene.test)? })
}

/// A parsed scene's views, split for training and testing, before any image is read.
struct SplitScene {
    format: &'static str,
    train: Vec<ViewSpec>,
    test: Vec<ViewSpec>,
    /// Downscale still to apply to the images as read.
    factor: u32,
    points: Option<PointCloud>,
}

/// Detects the format, parses the cameras and splits the views.
fn parse_and_split(dir: &Path, options: &LoadOptions) -> Result<SplitScene, DatasetError> {
    if !dir.is_dir() {
        let problem = if dir.exists() { "is not a folder" } else { "does not exist" };
        return Err(DatasetError::io(dir, std::io::Error::new(std::io::ErrorKind::NotFound, problem)));
    }
    if options.downscale == 0 || options.test_every == 0 {
        return Err(DatasetError::malformed(dir, "downscale and test_every must be at least 1"));
    }
    let (parsed, factor) = if let Some(model_dir) = colmap::find_model_dir(dir) {
        let source = images::choose_source(dir, "images", options.downscale)?;
        (colmap_scene::parse(&model_dir, &source.folder)?, source.extra_factor)
    } else if transforms::detect(dir) {
        (transforms::parse(dir)?, options.downscale)
    } else if dir.join(llff::POSES_FILE).is_file() {
        let source = images::choose_source(dir, "images", options.downscale)?;
        (llff::parse(dir, &source.folder)?, source.extra_factor)
    } else {
        return Err(DatasetError::UnknownFormat { path: dir.to_path_buf() });
    };

    let (train, test) = match parsed.explicit_test {
        Some(test) => (parsed.views, test),
        None => {
            let (test, train): (Vec<_>, Vec<_>) =
                parsed.views.into_iter().enumerate().partition(|(i, _)| i % options.test_every == 0);
            (train.into_iter().map(|(_, v)| v).collect(), test.into_iter().map(|(_, v)| v).collect())
        }
    };
    if train.is_empty() {
        return Err(DatasetError::malformed(dir, "the scene has no training views"));
    }
    Ok(SplitScene { format: parsed.format, train, test, factor, points: parsed.points })
}

/// Loads the images (in parallel), fits each camera to its image's resolution and removes lens
/// distortion.
fn load_views(specs: Vec<ViewSpec>, factor: u32, background: [f32; 3]) -> Result<Vec<View>, DatasetError> {
    specs
        .into_par_iter()
        .map(|spec| {
            let image = images::load(&spec.image_path, background, factor)?;
            let camera = fit_camera(&spec, image.width, image.height)?;
            let image = undistort(&image, [camera.fx, camera.fy, camera.cx, camera.cy].map(f64::from), spec.distortion);
            Ok(View { name: spec.name, camera, image })
        })
        .collect()
}

/// Scales the intrinsics from the resolution they were stated for to the loaded image's. The
/// aspect ratios must agree (within the rounding of downscaled sizes).
fn fit_camera(spec: &ViewSpec, width: u32, height: u32) -> Result<Camera, DatasetError> {
    let (cw, ch) = (spec.camera.width as f64, spec.camera.height as f64);
    let (iw, ih) = (width as f64, height as f64);
    let (sx, sy) = (iw / cw, ih / ch);
    let tolerance = 1.0 / iw.min(ih) + 1e-3;
    if (sx / sy - 1.0).abs() > tolerance {
        return Err(DatasetError::malformed(
            &spec.image_path,
            format!("image is {iw}x{ih} but its camera is {cw}x{ch}: aspect ratios differ"),
        ));
    }
    spec.camera.resized(width, height).map_err(|source| DatasetError::Camera { path: spec.image_path.clone(), source })
}

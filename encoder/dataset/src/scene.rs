//! Loading a scene folder into a [`Dataset`]: format detection, image loading at the requested
//! downscale, distortion removal, train/test split and normalization.

use std::path::{Path, PathBuf};

use pwgs_decoder::camera::{Camera, Intrinsics};
use pwgs_decoder::ply::PointCloud;
use pwgs_decoder::rgb_image::RgbImage;
use rayon::prelude::*;

use crate::normalization::SceneNormalization;
use crate::undistort::{Distortion, undistort};
use crate::{DatasetError, colmap, images, llff, transforms};

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

/// Loads a scene folder. See the crate documentation for the formats, tried in order.
pub fn load_scene(dir: &Path, options: &LoadOptions) -> Result<Dataset, DatasetError> {
    if !dir.is_dir() {
        let problem = if dir.exists() { "is not a folder" } else { "does not exist" };
        return Err(DatasetError::io(dir, std::io::Error::new(std::io::ErrorKind::NotFound, problem)));
    }
    if options.downscale == 0 || options.test_every == 0 {
        return Err(DatasetError::malformed(dir, "downscale and test_every must be at least 1"));
    }
    let (parsed, extra_factor) = if let Some(model_dir) = colmap::find_model_dir(dir) {
        let source = images::choose_source(dir, "images", options.downscale)?;
        (colmap_scene(&model_dir, &source.folder)?, source.extra_factor)
    } else if transforms::detect(dir) {
        (transforms::parse(dir)?, options.downscale)
    } else if dir.join(llff::POSES_FILE).is_file() {
        let source = images::choose_source(dir, "images", options.downscale)?;
        (llff::parse(dir, &source.folder)?, source.extra_factor)
    } else {
        return Err(DatasetError::UnknownFormat { path: dir.to_path_buf() });
    };

    let (train_specs, test_specs) = match parsed.explicit_test {
        Some(test) => (parsed.views, test),
        None => {
            let (test, train): (Vec<_>, Vec<_>) =
                parsed.views.into_iter().enumerate().partition(|(i, _)| i % options.test_every == 0);
            (train.into_iter().map(|(_, v)| v).collect(), test.into_iter().map(|(_, v)| v).collect())
        }
    };
    if train_specs.is_empty() {
        return Err(DatasetError::malformed(dir, "the scene has no training views"));
    }
    let train = load_views(train_specs, extra_factor, options.background)?;
    let test = load_views(test_specs, extra_factor, options.background)?;
    let cameras: Vec<Camera> = train.iter().map(|v| v.camera).collect();
    Ok(Dataset {
        format: parsed.format,
        normalization: SceneNormalization::from_cameras(&cameras),
        train,
        test,
        points: parsed.points,
    })
}

/// Loads the images (in parallel), fits each camera to its image's resolution and removes lens
/// distortion.
fn load_views(specs: Vec<ViewSpec>, factor: u32, background: [f32; 3]) -> Result<Vec<View>, DatasetError> {
    specs
        .into_par_iter()
        .map(|spec| {
            let image = images::load(&spec.image_path, background, factor)?;
            let camera = fit_camera(&spec, &image)?;
            let image = undistort(&image, [camera.fx, camera.fy, camera.cx, camera.cy].map(f64::from), spec.distortion);
            Ok(View { name: spec.name, camera, image })
        })
        .collect()
}

/// Scales the intrinsics from the resolution they were stated for to the loaded image's. The
/// aspect ratios must agree (within the rounding of downscaled sizes).
fn fit_camera(spec: &ViewSpec, image: &RgbImage) -> Result<Camera, DatasetError> {
    let (cw, ch) = (spec.camera.width as f64, spec.camera.height as f64);
    let (iw, ih) = (image.width as f64, image.height as f64);
    let (sx, sy) = (iw / cw, ih / ch);
    let tolerance = 1.0 / iw.min(ih) + 1e-3;
    if (sx / sy - 1.0).abs() > tolerance {
        return Err(DatasetError::malformed(
            &spec.image_path,
            format!("image is {iw}x{ih} but its camera is {cw}x{ch}: aspect ratios differ"),
        ));
    }
    spec.camera
        .resized(image.width, image.height)
        .map_err(|source| DatasetError::Camera { path: spec.image_path.clone(), source })
}

/// Turns a COLMAP model into views, matching its image names to the image folder: by name
/// (any extension), or, when none of the names exist (LLFF-style renamed copies such as fern's
/// `image000.png` for `IMG_4026.JPG`), by sorted order if the counts agree.
fn colmap_scene(model_dir: &Path, image_folder: &Path) -> Result<ParsedScene, DatasetError> {
    let model = colmap::read_model(model_dir)?;
    let mut model_images: Vec<&colmap::ColmapImage> = model.images.iter().collect();
    model_images.sort_by(|a, b| a.name.cmp(&b.name));
    let files = images::list_images(image_folder)?;
    let by_name: Vec<Option<PathBuf>> = model_images.iter().map(|im| find_by_name(&files, &im.name)).collect();
    let paths: Vec<PathBuf> = if by_name.iter().all(Option::is_some) {
        by_name.into_iter().flatten().collect()
    } else if by_name.iter().all(Option::is_none) && files.len() == model_images.len() {
        files
    } else {
        let missing = model_images.iter().zip(&by_name).find(|(_, p)| p.is_none()).map(|(im, _)| im.name.as_str());
        return Err(DatasetError::malformed(
            image_folder,
            format!(
                "image `{}` of the COLMAP model is missing ({} model images, {} files)",
                missing.unwrap_or_default(),
                model_images.len(),
                files.len()
            ),
        ));
    };
    let views = model_images
        .iter()
        .zip(paths)
        .map(|(im, image_path)| {
            let cam = model.cameras.iter().find(|c| c.id == im.camera_id).ok_or_else(|| {
                DatasetError::malformed(model_dir, format!("image `{}` uses unknown camera {}", im.name, im.camera_id))
            })?;
            let distortion = cam.distortion(model_dir)?;
            let rotation = pwgs_decoder::camera::quaternion_to_matrix(im.qvec).ok_or_else(|| {
                DatasetError::malformed(model_dir, format!("image `{}` has a zero or non-finite quaternion", im.name))
            })?;
            let [fx, fy, cx, cy] = cam.pinhole().map(|v| v as f32);
            let translation = glam::DVec3::from(im.tvec).as_vec3();
            let (w, h) = (u32::try_from(cam.width), u32::try_from(cam.height));
            let (Ok(w), Ok(h)) = (w, h) else {
                return Err(DatasetError::malformed(model_dir, format!("camera {} has an absurd size", cam.id)));
            };
            let camera = Camera::new(Intrinsics { width: w, height: h, fx, fy, cx, cy }, rotation, translation)
                .map_err(|source| DatasetError::Camera { path: model_dir.join(&im.name), source })?;
            Ok(ViewSpec { name: im.name.clone(), image_path, camera, distortion })
        })
        .collect::<Result<_, DatasetError>>()?;
    let points = PointCloud {
        positions: model.points.iter().map(|p| p.xyz.map(|v| v as f32)).collect(),
        colors: model.points.iter().map(|p| p.rgb.map(|c| c as f32 / 255.0)).collect(),
    };
    Ok(ParsedScene { format: "COLMAP", views, explicit_test: None, points: Some(points) })
}

/// A file whose name equals `name`, or whose stem does (images re-encoded to another format).
fn find_by_name(files: &[PathBuf], name: &str) -> Option<PathBuf> {
    let name = Path::new(name);
    let stem = name.file_stem();
    files
        .iter()
        .find(|f| f.file_name() == name.file_name())
        .or_else(|| files.iter().find(|f| f.file_stem() == stem))
        .cloned()
}

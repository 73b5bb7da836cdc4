//! A COLMAP model as a scene: its registered images paired with the image files, their
//! cameras checked and converted, and its 3D points as the initialization point cloud.
//!
//! The model reader ([`crate::colmap`]) keeps values as the files hold them; this is where they
//! are judged, and every error names the model file the offending value came from.

use std::path::{Path, PathBuf};

use pwgs_core::camera::{Camera, CameraError, Intrinsics, quaternion_to_matrix};
use pwgs_core::ply::PointCloud;

use crate::colmap::{self, ColmapImage, ColmapModel, ColmapPoint};
use crate::scene::{ParsedScene, ViewSpec};
use crate::{DatasetError, images};

/// Turns the model in `model_dir` into views, matching its image names to the image folder: by
/// name (any extension), or, when none of the names exist (LLFF-style renamed copies such as
/// fern's `image000.png` for `IMG_4026.JPG`), by sorted order if the counts agree.
pub fn parse(model_dir: &Path, image_folder: &Path) -> Result<ParsedScene, DatasetError> {
    let model = colmap::read_model(model_dir)?;
    let mut model_images: Vec<&ColmapImage> = model.images.iter().collect();
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
        .map(|(image, image_path)| view(model_dir, &model, image, image_path))
        .collect::<Result<_, DatasetError>>()?;
    let points = point_cloud(&model.points, &colmap::model_file(model_dir, "points3D"))?;
    Ok(ParsedScene { format: "COLMAP", views, explicit_test: None, points: Some(points) })
}

/// One registered image's view: its pose from the images file, its intrinsics and distortion
/// from the cameras file.
fn view(
    model_dir: &Path,
    model: &ColmapModel,
    image: &ColmapImage,
    image_path: PathBuf,
) -> Result<ViewSpec, DatasetError> {
    let images_file = colmap::model_file(model_dir, "images");
    let cameras_file = colmap::model_file(model_dir, "cameras");
    let in_images =
        |message: String| DatasetError::malformed(&images_file, format!("image `{}`: {message}", image.name));
    let cam = model
        .cameras
        .iter()
        .find(|c| c.id == image.camera_id)
        .ok_or_else(|| in_images(format!("uses unknown camera {}", image.camera_id)))?;
    let in_cameras = |message: String| DatasetError::malformed(&cameras_file, format!("camera {}: {message}", cam.id));
    let distortion = cam.distortion(&cameras_file)?;
    let rotation = quaternion_to_matrix(image.qvec)
        .ok_or_else(|| in_images(format!("quaternion {:?} is zero or not finite", image.qvec)))?;
    let translation = glam::DVec3::from(image.tvec).as_vec3();
    if !translation.is_finite() {
        return Err(in_images(format!("translation {:?} is not finite (in f32)", image.tvec)));
    }
    let (Ok(width), Ok(height)) = (u32::try_from(cam.width), u32::try_from(cam.height)) else {
        return Err(in_cameras(format!("size {}x{} is too large", cam.width, cam.height)));
    };
    let [fx, fy, cx, cy] = cam.pinhole().map(|v| v as f32);
    let intrinsics = Intrinsics { width, height, fx, fy, cx, cy };
    // The pose was checked above, so what the camera rejects is an intrinsic.
    let camera = Camera::new(intrinsics, rotation, translation).map_err(|e| match e {
        CameraError::NotARotation { .. } | CameraError::NonFinitePose => in_images(format!("camera rejected: {e}")),
        _ => in_cameras(format!("camera rejected (params {:?}): {e}", cam.params)),
    })?;
    distortion.check(&camera).map_err(in_cameras)?;
    Ok(ViewSpec { name: image.name.clone(), image_path, camera, distortion })
}

/// The model's 3D points; a position that is not finite (or beyond f32) is an error naming
/// the point, since it would otherwise become a Gaussian at infinity.
fn point_cloud(points: &[ColmapPoint], points_file: &Path) -> Result<PointCloud, DatasetError> {
    let mut cloud = PointCloud::default();
    for point in points {
        let position = point.xyz.map(|v| v as f32);
        if !position.iter().all(|v| v.is_finite()) {
            return Err(DatasetError::malformed(
                points_file,
                format!("point {} has position {:?}, which is not finite (in f32)", point.id, point.xyz),
            ));
        }
        cloud.positions.push(position);
        cloud.colors.push(point.rgb.map(|c| f32::from(c) / 255.0));
    }
    Ok(cloud)
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

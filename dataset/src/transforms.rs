//! nerfstudio and Blender (NeRF-synthetic) `transforms*.json` datasets.
//!
//! Intrinsics come from `camera_angle_x` (Blender: square pixels, centered principal point) or
//! from `fl_x`, `fl_y`, `cx`, `cy`, `w`, `h` (nerfstudio), at the top level or per frame.
//! `transform_matrix` is an OpenGL camera-to-world matrix and is converted once. nerfstudio's
//! OPENCV distortion (`k1`, `k2`, `p1`, `p2`) is removed at load; fisheye models are refused.
//! With `transforms_train.json` the dataset's own split is used (`transforms_test.json` for
//! test views); a single `transforms.json` is split every 8th view.

use std::path::{Path, PathBuf};

use glam::DMat4;
use pwgs_core::camera::{Camera, Intrinsics, MAX_SIDE};
use pwgs_core::camera_json::focal_from_angle;
use pwgs_core::ply::{PlyError, PointCloud};
use serde::Deserialize;

use crate::DatasetError;
use crate::scene::{ParsedScene, ViewSpec};
use crate::undistort::Distortion;

/// Intrinsics and distortion fields that may appear at the top level or per frame.
#[derive(Debug, Clone, Default, Deserialize)]
struct CameraFields {
    camera_angle_x: Option<f64>,
    camera_angle_y: Option<f64>,
    fl_x: Option<f64>,
    fl_y: Option<f64>,
    cx: Option<f64>,
    cy: Option<f64>,
    w: Option<f64>,
    h: Option<f64>,
    k1: Option<f64>,
    k2: Option<f64>,
    p1: Option<f64>,
    p2: Option<f64>,
    camera_model: Option<String>,
}

impl CameraFields {
    /// Frame fields override the file's.
    fn or(self, file: &CameraFields) -> CameraFields {
        CameraFields {
            camera_angle_x: self.camera_angle_x.or(file.camera_angle_x),
            camera_angle_y: self.camera_angle_y.or(file.camera_angle_y),
            fl_x: self.fl_x.or(file.fl_x),
            fl_y: self.fl_y.or(file.fl_y),
            cx: self.cx.or(file.cx),
            cy: self.cy.or(file.cy),
            w: self.w.or(file.w),
            h: self.h.or(file.h),
            k1: self.k1.or(file.k1),
            k2: self.k2.or(file.k2),
            p1: self.p1.or(file.p1),
            p2: self.p2.or(file.p2),
            camera_model: self.camera_model.or_else(|| file.camera_model.clone()),
        }
    }
}

#[derive(Debug, Deserialize)]
struct Frame {
    file_path: String,
    transform_matrix: [[f64; 4]; 4],
    #[serde(flatten)]
    camera: CameraFields,
}

#[derive(Debug, Deserialize)]
struct TransformsFile {
    #[serde(flatten)]
    camera: CameraFields,
    ply_file_path: Option<String>,
    frames: Vec<Frame>,
}

/// True when `dir` holds a transforms dataset.
pub fn detect(dir: &Path) -> bool {
    dir.join("transforms.json").is_file() || dir.join("transforms_train.json").is_file()
}

/// Reads the dataset description (images are loaded later by the scene loader).
pub fn parse(dir: &Path) -> Result<ParsedScene, DatasetError> {
    let train_file = dir.join("transforms_train.json");
    if train_file.is_file() {
        let (train, points) = parse_file(dir, &train_file)?;
        let test_file = dir.join("transforms_test.json");
        let test = if test_file.is_file() { parse_file(dir, &test_file)?.0 } else { Vec::new() };
        return Ok(ParsedScene {
            format: "transforms (train/test files)",
            views: train,
            explicit_test: Some(test),
            points,
        });
    }
    let (views, points) = parse_file(dir, &dir.join("transforms.json"))?;
    Ok(ParsedScene { format: "transforms", views, explicit_test: None, points })
}

type FileContent = (Vec<ViewSpec>, Option<PointCloud>);

fn parse_file(dir: &Path, path: &Path) -> Result<FileContent, DatasetError> {
    let text = crate::read_file(path)?;
    let file: TransformsFile =
        serde_json::from_slice(&text).map_err(|e| DatasetError::malformed(path, format!("invalid JSON: {e}")))?;
    if file.frames.is_empty() {
        return Err(DatasetError::malformed(path, "`frames` is empty"));
    }
    let views = file
        .frames
        .into_iter()
        .enumerate()
        .map(|(i, frame)| frame_view(dir, path, i, frame, &file.camera))
        .collect::<Result<_, _>>()?;
    let points = file.ply_file_path.map(|p| read_points(&dir.join(p))).transpose()?;
    Ok((views, points))
}

fn frame_view(
    dir: &Path,
    path: &Path,
    index: usize,
    frame: Frame,
    file: &CameraFields,
) -> Result<ViewSpec, DatasetError> {
    let context =
        |message: String| DatasetError::malformed(path, format!("frame {index} (`{}`): {message}", frame.file_path));
    let image_path = resolve_image(dir, &frame.file_path).ok_or_else(|| context("image file not found".into()))?;
    let (img_w, img_h) =
        image::image_dimensions(&image_path).map_err(|e| context(format!("cannot read image size: {e}")))?;
    let fields = frame.camera.or(file);
    let distortion = distortion(&fields).map_err(|m| DatasetError::unsupported(path, format!("frame {index}: {m}")))?;
    // Intrinsics are given for (w, h) when stated, else for the image as stored.
    let (w, h) = (fields.w.unwrap_or(img_w as f64), fields.h.unwrap_or(img_h as f64));
    if !(w >= 1.0
        && h >= 1.0
        && w <= f64::from(MAX_SIDE)
        && h <= f64::from(MAX_SIDE)
        && w.fract() == 0.0
        && h.fract() == 0.0)
    {
        return Err(context(format!("intrinsic image size {w}x{h} is not whole pixels in 1..={MAX_SIDE}")));
    }
    let (fx, fy) = match (fields.fl_x, fields.fl_y, fields.camera_angle_x) {
        (Some(fx), fy, _) => (fx, fy.unwrap_or(fx)),
        (None, _, Some(angle_x)) => {
            let fx = focal_from_angle(angle_x, w, "camera_angle_x").map_err(context)?;
            let fy = match fields.camera_angle_y {
                Some(angle_y) => focal_from_angle(angle_y, h, "camera_angle_y").map_err(context)?,
                None => fx,
            };
            (fx, fy)
        }
        (None, _, None) => return Err(context("no focal length (`fl_x` or `camera_angle_x`)".into())),
    };
    let (cx, cy) = (fields.cx.unwrap_or(w / 2.0), fields.cy.unwrap_or(h / 2.0));
    let m = frame.transform_matrix;
    let c2w = DMat4::from_cols_array_2d(&m).transpose().as_mat4();
    let camera = Camera::from_opengl_camera_to_world(
        Intrinsics { width: w as u32, height: h as u32, fx: fx as f32, fy: fy as f32, cx: cx as f32, cy: cy as f32 },
        c2w,
    )
    .map_err(|e| context(format!("camera rejected: {e}")))?;
    distortion.check(&camera).map_err(context)?;
    let name = image_path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    Ok(ViewSpec { name, image_path, camera, distortion })
}

fn distortion(fields: &CameraFields) -> Result<Distortion, String> {
    match fields.camera_model.as_deref() {
        None | Some("PINHOLE" | "SIMPLE_PINHOLE" | "OPENCV" | "SIMPLE_RADIAL" | "RADIAL") => {}
        Some(other) => {
            return Err(format!("camera model `{other}` is not supported; undistort the images to PINHOLE first"));
        }
    }
    let [k1, k2, p1, p2] = [fields.k1, fields.k2, fields.p1, fields.p2].map(|v| v.unwrap_or(0.0));
    Ok(if [k1, k2, p1, p2] == [0.0; 4] { Distortion::None } else { Distortion::Opencv { k1, k2, p1, p2 } })
}

/// Loads the initialization point cloud that `ply_file_path` names.
fn read_points(path: &Path) -> Result<PointCloud, DatasetError> {
    pwgs_core::ply::point_cloud_from_bytes(&crate::read_file(path)?)
        .map_err(|problem| PlyError { source_name: path.display().to_string(), problem }.into())
}

/// Frame paths are relative to the dataset folder and may omit the extension (Blender's
/// `./train/r_0`).
fn resolve_image(dir: &Path, file_path: &str) -> Option<PathBuf> {
    let base = dir.join(file_path);
    if base.is_file() {
        return Some(base);
    }
    ["png", "jpg", "jpeg", "PNG", "JPG"]
        .iter()
        .map(|ext| PathBuf::from(format!("{}.{ext}", base.display())))
        .find(|p| p.is_file())
}

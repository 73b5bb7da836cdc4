//! LLFF `poses_bounds.npy`, the fallback when a capture has no COLMAP model.
//!
//! Each row holds a 3x5 matrix (row-major) and two depth bounds. The first three columns are the
//! camera-to-world rotation with LLFF's axis order (down, right, backwards), the fourth the
//! camera center, the fifth (height, width, focal) at the original resolution. Images are the
//! sorted files of the image folder, one per row.

use std::path::Path;

use glam::{DMat4, DVec4};
use pwgs_core::camera::{Camera, Intrinsics, MAX_SIDE};

use crate::DatasetError;
use crate::npy::read_npy;
use crate::scene::{ParsedScene, ViewSpec};
use crate::undistort::Distortion;

pub const POSES_FILE: &str = "poses_bounds.npy";

/// Reads the poses and pairs them with the images of `image_folder` in sorted order.
pub fn parse(dir: &Path, image_folder: &Path) -> Result<ParsedScene, DatasetError> {
    let path = dir.join(POSES_FILE);
    let array = read_npy(&path)?;
    if array.shape.len() != 2 || array.shape[1] != 17 {
        return Err(DatasetError::malformed(&path, format!("expected shape (N, 17), found {:?}", array.shape)));
    }
    let images = crate::images::list_images(image_folder)?;
    if images.len() != array.shape[0] {
        return Err(DatasetError::malformed(
            &path,
            format!("{} poses but {} images in {}", array.shape[0], images.len(), image_folder.display()),
        ));
    }
    let views = array
        .data
        .chunks_exact(17)
        .zip(images)
        .enumerate()
        .map(|(i, (row, image_path))| {
            let camera = pose_to_camera(row).map_err(|m| DatasetError::malformed(&path, format!("pose {i}: {m}")))?;
            let name = image_path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
            Ok(ViewSpec { name, image_path, camera, distortion: Distortion::None })
        })
        .collect::<Result<_, DatasetError>>()?;
    Ok(ParsedScene { format: "LLFF poses_bounds.npy", views, explicit_test: None, points: None })
}

fn pose_to_camera(row: &[f64]) -> Result<Camera, String> {
    let m = |r: usize, c: usize| row[r * 5 + c];
    let (h, w, f) = (m(0, 4), m(1, 4), m(2, 4));
    let side = |v: f64| v >= 1.0 && v <= f64::from(MAX_SIDE) && v.fract() == 0.0;
    if !(side(w) && side(h)) {
        return Err(format!("image size {w}x{h} is not whole pixels in 1..={MAX_SIDE}"));
    }
    let col = |c: usize| DVec4::new(m(0, c), m(1, c), m(2, c), 0.0);
    // (down, right, back) -> OpenGL (right, up, back).
    let c2w = DMat4::from_cols(col(1), -col(0), col(2), col(3) + DVec4::W);
    Camera::from_opengl_camera_to_world(
        Intrinsics {
            width: w as u32,
            height: h as u32,
            fx: f as f32,
            fy: f as f32,
            cx: (w / 2.0) as f32,
            cy: (h / 2.0) as f32,
        },
        c2w.as_mat4(),
    )
    .map_err(|e| format!("camera rejected: {e}"))
}

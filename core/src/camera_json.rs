//! The camera file `pwdec --view` reads (docs/architecture.md section 1.5, SPEC.md annex A), in one of two
//! forms:
//!
//! - pwgs: `{"width", "height", "fx", "fy", "cx", "cy", "camera_to_world"}` with a 4x4
//!   row-major camera-to-world matrix in OpenCV axes (x right, y down, z forward);
//! - a nerfstudio/Blender frame: `"transform_matrix"` (4x4 row-major, OpenGL axes) with
//!   `"w"`, `"h"` and either `"fl_x"` (`"fl_y"`, `"cx"`, `"cy"` optional) or `"camera_angle_x"`
//!   (radians, strictly between 0 and pi).

use glam::{DMat4, Mat4};
use serde::{Deserialize, Serialize};

use crate::camera::{Camera, Intrinsics};

/// Why a camera file was rejected.
#[derive(Debug, thiserror::Error)]
pub enum CameraJsonError {
    #[error("not a camera: {0}")]
    Syntax(#[from] serde_json::Error),
    #[error("{0}")]
    Invalid(String),
}

#[derive(Deserialize)]
#[serde(untagged)]
enum CameraFile {
    Pwgs(PwgsCamera),
    Nerfstudio(NerfstudioFrame),
}

/// The pwgs form.
#[derive(Serialize, Deserialize)]
struct PwgsCamera {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    camera_to_world: [[f64; 4]; 4],
}

#[derive(Deserialize)]
struct NerfstudioFrame {
    transform_matrix: [[f64; 4]; 4],
    w: f64,
    h: f64,
    fl_x: Option<f64>,
    fl_y: Option<f64>,
    cx: Option<f64>,
    cy: Option<f64>,
    camera_angle_x: Option<f64>,
}

fn matrix(rows: &[[f64; 4]; 4]) -> Result<Mat4, CameraJsonError> {
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(CameraJsonError::Invalid("the pose matrix holds a non-finite value".into()));
    }
    Ok(DMat4::from_cols_array_2d(rows).transpose().as_mat4())
}

/// An intrinsic as the camera stores it: a value beyond f32's range would become infinite (or
/// zero) there and be reported as something the file does not say.
fn intrinsic(value: f64, name: &str) -> Result<f32, CameraJsonError> {
    let single = value as f32;
    if single.is_finite() && (single != 0.0 || value == 0.0) {
        Ok(single)
    } else {
        Err(CameraJsonError::Invalid(format!("`{name}` = {value:e} is outside the range of a 32-bit float")))
    }
}

/// The focal length for a field of view of `angle` radians across `extent` pixels. An angle
/// outside (0, pi) has no such focal length (an angle in degrees is the common mistake): it
/// would give an infinite, negative or near-zero one.
pub fn focal_from_angle(angle: f64, extent: f64, name: &str) -> Result<f64, String> {
    if angle > 0.0 && angle < std::f64::consts::PI {
        Ok(0.5 * extent / (0.5 * angle).tan())
    } else {
        Err(format!("`{name}` = {angle} is not a field of view in radians (0 < angle < pi)"))
    }
}

fn size(value: f64, name: &str) -> Result<u32, CameraJsonError> {
    if value >= 1.0 && value <= f64::from(u16::MAX) && value.fract() == 0.0 {
        Ok(value as u32)
    } else {
        Err(CameraJsonError::Invalid(format!("`{name}` = {value} is not an image size in 1..=65535")))
    }
}

/// Parses a camera file in either form.
pub fn parse_camera(text: &str) -> Result<Camera, CameraJsonError> {
    let invalid = |e: crate::camera::CameraError| CameraJsonError::Invalid(e.to_string());
    let value: serde_json::Value = serde_json::from_str(text)?;
    if !value.is_object() {
        return Err(CameraJsonError::Invalid("expected a JSON object".into()));
    }
    let file: CameraFile = serde_json::from_value(value).map_err(|_| {
        CameraJsonError::Invalid(
            "expected either width/height/fx/fy/cx/cy/camera_to_world (pwgs, OpenCV axes) or \
             transform_matrix/w/h with fl_x or camera_angle_x (nerfstudio, OpenGL axes)"
                .into(),
        )
    })?;
    match file {
        CameraFile::Pwgs(c) => {
            let intrinsics = Intrinsics {
                width: size(f64::from(c.width), "width")?,
                height: size(f64::from(c.height), "height")?,
                fx: intrinsic(c.fx, "fx")?,
                fy: intrinsic(c.fy, "fy")?,
                cx: intrinsic(c.cx, "cx")?,
                cy: intrinsic(c.cy, "cy")?,
            };
            Camera::from_camera_to_world(intrinsics, matrix(&c.camera_to_world)?).map_err(invalid)
        }
        CameraFile::Nerfstudio(f) => {
            let (width, height) = (size(f.w, "w")?, size(f.h, "h")?);
            let fx = match (f.fl_x, f.camera_angle_x) {
                (Some(fx), _) => fx,
                (None, Some(angle)) => {
                    focal_from_angle(angle, f.w, "camera_angle_x").map_err(CameraJsonError::Invalid)?
                }
                (None, None) => {
                    return Err(CameraJsonError::Invalid("no focal length (`fl_x` or `camera_angle_x`)".into()));
                }
            };
            let intrinsics = Intrinsics {
                width,
                height,
                fx: intrinsic(fx, "fl_x")?,
                fy: intrinsic(f.fl_y.unwrap_or(fx), "fl_y")?,
                cx: intrinsic(f.cx.unwrap_or(f.w / 2.0), "cx")?,
                cy: intrinsic(f.cy.unwrap_or(f.h / 2.0), "cy")?,
            };
            Camera::from_opengl_camera_to_world(intrinsics, matrix(&f.transform_matrix)?).map_err(invalid)
        }
    }
}

/// The pwgs form of a camera.
pub fn camera_to_json(camera: &Camera) -> String {
    let m = camera.camera_to_world().as_dmat4().transpose().to_cols_array_2d();
    let c = PwgsCamera {
        width: camera.width,
        height: camera.height,
        fx: f64::from(camera.fx),
        fy: f64::from(camera.fy),
        cx: f64::from(camera.cx),
        cy: f64::from(camera.cy),
        camera_to_world: m,
    };
    serde_json::to_string_pretty(&c).expect("a camera serializes")
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn sample() -> Camera {
        let intrinsics = Intrinsics { width: 64, height: 48, fx: 50.0, fy: 52.0, cx: 31.5, cy: 24.5 };
        Camera::look_at(intrinsics, Vec3::new(1.0, -2.0, 3.0), Vec3::ZERO, Vec3::new(0.0, -1.0, 0.0)).unwrap()
    }

    #[test]
    fn pwgs_form_round_trips() {
        let cam = sample();
        let back = parse_camera(&camera_to_json(&cam)).unwrap();
        assert_eq!(back.intrinsics(), cam.intrinsics());
        assert!((back.center() - cam.center()).length() < 1e-5);
        let p = Vec3::new(0.2, 0.1, -0.3);
        let (a, b) = (cam.project(p).unwrap(), back.project(p).unwrap());
        assert!((a.0 - b.0).abs() < 1e-3 && (a.1 - b.1).abs() < 1e-3);
    }

    #[test]
    fn nerfstudio_frame_is_opengl() {
        let text = r#"{"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,2],[0,0,0,1]],
                       "w": 40, "h": 30, "camera_angle_x": 1.0}"#;
        let cam = parse_camera(text).unwrap();
        // The camera sits at z = 2 looking down -z: the origin projects to the center.
        let (u, v) = cam.project(Vec3::ZERO).unwrap();
        assert!((u - 20.0).abs() < 1e-4 && (v - 15.0).abs() < 1e-4);
        assert!((cam.fx - 0.5 * 40.0 / 0.5f32.tan()).abs() < 1e-3);
    }

    #[test]
    fn malformed_cameras_are_named() {
        let cases = [
            ("[1, 2]", "JSON object"),
            ("{\"width\": 10}", "expected either"),
            (
                "{\"width\": 0, \"height\": 10, \"fx\": 1, \"fy\": 1, \"cx\": 0, \"cy\": 0, \"camera_to_world\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}",
                "`width`",
            ),
            (
                "{\"width\": 10, \"height\": 10, \"fx\": -1, \"fy\": 1, \"cx\": 0, \"cy\": 0, \"camera_to_world\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}",
                "fx",
            ),
            (
                "{\"width\": 10, \"height\": 10, \"fx\": 1, \"fy\": 1, \"cx\": 0, \"cy\": 0, \"camera_to_world\": [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}",
                "rotation",
            ),
            ("{\"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], \"w\": 10, \"h\": 10}", "focal"),
            ("{\"width\": 10,", "not a camera"),
            // An angle in degrees would give a plausible but wrong focal length; pi a near-zero one.
            (
                "{\"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], \"w\": 10, \"h\": 10, \"camera_angle_x\": 50}",
                "`camera_angle_x` = 50 is not a field of view in radians",
            ),
            (
                "{\"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], \"w\": 10, \"h\": 10, \"camera_angle_x\": 3.141592653589793}",
                "`camera_angle_x` = 3.141592653589793 is not a field of view",
            ),
            (
                "{\"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], \"w\": 10, \"h\": 10, \"camera_angle_x\": 0}",
                "`camera_angle_x` = 0 is not a field of view",
            ),
            // Beyond f32: would be reported as an infinite or zero focal length the file does not hold.
            (
                "{\"width\": 10, \"height\": 10, \"fx\": 1e39, \"fy\": 1, \"cx\": 0, \"cy\": 0, \"camera_to_world\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}",
                "`fx` = 1e39 is outside the range of a 32-bit float",
            ),
            (
                "{\"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], \"w\": 10, \"h\": 10, \"fl_x\": 1e-50}",
                "`fl_x` = 9.999999999999999e-51 is outside the range", // serde_json's parse of 1e-50
            ),
        ];
        for (text, needle) in cases {
            let err = parse_camera(text).unwrap_err().to_string();
            assert!(err.contains(needle), "{text}: {err}");
        }
    }
}

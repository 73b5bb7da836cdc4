//! Pinhole cameras in the project's one internal convention (docs/architecture.md section 1.5): OpenCV axes
//! (x right, y down, z forward), a world-to-camera rotation and translation, and intrinsics in
//! pixels at the rendered resolution with pixel centers at (i + 0.5, j + 0.5).
//!
//! Datasets in other conventions (OpenGL/Blender camera-to-world, COLMAP quaternions) are
//! converted once, at load, by the constructors here; nothing downstream ever sees another
//! convention.

use glam::{Mat3, Mat4, Vec3, Vec4};

/// Why a camera was rejected.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CameraError {
    #[error("image size {width}x{height} is outside 1..={MAX_SIDE} per side")]
    BadSize { width: u32, height: u32 },
    #[error("intrinsic `{name}` = {value} must be finite and positive")]
    BadFocal { name: &'static str, value: f32 },
    #[error("principal point ({cx}, {cy}) is not finite")]
    BadPrincipalPoint { cx: f32, cy: f32 },
    #[error("pose contains a non-finite value")]
    NonFinitePose,
    #[error("rotation is not orthonormal with determinant +1 (max deviation {deviation:.3e})")]
    NotARotation { deviation: f32 },
    #[error("camera-to-world matrix has last row {row:?}, expected [0, 0, 0, 1]")]
    NotRigid { row: [f32; 4] },
}

/// Largest |R R^T - I| entry (and |det R - 1|) accepted for a rotation. Poses in datasets are
/// stored with 6-9 significant digits, so a tolerance far above f32 epsilon is needed, while a
/// matrix carrying scale or shear is still rejected.
const ROTATION_TOLERANCE: f32 = 1e-3;

/// Largest image side, in pixels (SPEC.md annex A). It keeps pixel coordinates exact in f32
/// and every per-pixel index (noise pyramid, tiles) far from overflow, whatever a camera file
/// or an image header claims.
pub const MAX_SIDE: u32 = 65535;

/// Pinhole intrinsics in pixels at the rendered resolution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
}

/// A pinhole camera with OpenCV axes. See the module documentation for the conventions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    /// World-to-camera rotation.
    pub rotation: Mat3,
    /// World-to-camera translation: `x_cam = rotation * x_world + translation`.
    pub translation: Vec3,
}

impl Camera {
    /// Builds a camera and checks that it is usable: a size of 1 to [`MAX_SIDE`] per side,
    /// positive focal lengths, finite principal point and pose, and a proper rotation
    /// (re-orthonormalized afterwards so that rounding in the source file does not leak into
    /// rendering).
    pub fn new(intrinsics: Intrinsics, rotation: Mat3, translation: Vec3) -> Result<Self, CameraError> {
        let Intrinsics { width, height, fx, fy, cx, cy } = intrinsics;
        if !((1..=MAX_SIDE).contains(&width) && (1..=MAX_SIDE).contains(&height)) {
            return Err(CameraError::BadSize { width, height });
        }
        for (name, value) in [("fx", fx), ("fy", fy)] {
            // Phrased positively so that NaN fails the check.
            if !(value.is_finite() && value > 0.0) {
                return Err(CameraError::BadFocal { name, value });
            }
        }
        if !(cx.is_finite() && cy.is_finite()) {
            return Err(CameraError::BadPrincipalPoint { cx, cy });
        }
        if !(rotation.is_finite() && translation.is_finite()) {
            return Err(CameraError::NonFinitePose);
        }
        let deviation = rotation_deviation(rotation);
        if !(deviation <= ROTATION_TOLERANCE) {
            return Err(CameraError::NotARotation { deviation });
        }
        Ok(Self { width, height, fx, fy, cx, cy, rotation: orthonormalize(rotation), translation })
    }

    /// Builds a camera from a camera-to-world matrix whose axes follow OpenCV.
    pub fn from_camera_to_world(intrinsics: Intrinsics, camera_to_world: Mat4) -> Result<Self, CameraError> {
        let row = camera_to_world.row(3);
        if !row.is_finite() {
            return Err(CameraError::NonFinitePose);
        }
        if (row - Vec4::W).abs().max_element() > 1e-6 {
            return Err(CameraError::NotRigid { row: row.to_array() });
        }
        let r_c2w = Mat3::from_mat4(camera_to_world);
        let center = camera_to_world.w_axis.truncate();
        let rotation = r_c2w.transpose();
        Self::new(intrinsics, rotation, -(rotation * center))
    }

    /// Builds a camera from an OpenGL/Blender camera-to-world matrix (x right, y up, camera
    /// looking down -z), flipping the y and z axes into OpenCV.
    pub fn from_opengl_camera_to_world(intrinsics: Intrinsics, camera_to_world: Mat4) -> Result<Self, CameraError> {
        let flip = Mat4::from_diagonal(Vec4::new(1.0, -1.0, -1.0, 1.0));
        Self::from_camera_to_world(intrinsics, camera_to_world * flip)
    }

    /// A camera at `eye` looking at `target`, with `up` pointing up in the image (OpenCV's y
    /// axis points down, so it is the opposite of `up` made orthogonal to the view direction).
    pub fn look_at(intrinsics: Intrinsics, eye: Vec3, target: Vec3, up: Vec3) -> Result<Self, CameraError> {
        let z = unit(target - eye);
        let x = unit((-up).cross(z));
        if z == Vec3::ZERO || x == Vec3::ZERO {
            return Err(CameraError::NonFinitePose);
        }
        let y = z.cross(x);
        let rotation = Mat3::from_cols(x, y, z).transpose();
        Self::new(intrinsics, rotation, -(rotation * eye))
    }

    /// `count` cameras evenly spaced on a circle of `radius` around `center`, raised by
    /// `elevation` radians above the plane orthogonal to `up`, all looking at `center`.
    pub fn orbit(
        intrinsics: Intrinsics,
        center: Vec3,
        up: Vec3,
        radius: f32,
        elevation: f32,
        count: usize,
    ) -> Result<Vec<Self>, CameraError> {
        let up = up.normalize_or_zero();
        let side = up.any_orthonormal_vector();
        let forward = up.cross(side);
        (0..count)
            .map(|i| {
                let azimuth = i as f32 / count as f32 * std::f32::consts::TAU;
                let horizontal = side * azimuth.cos() + forward * azimuth.sin();
                let eye = center + radius * (horizontal * elevation.cos() + up * elevation.sin());
                Self::look_at(intrinsics, eye, center, up)
            })
            .collect()
    }

    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics { width: self.width, height: self.height, fx: self.fx, fy: self.fy, cx: self.cx, cy: self.cy }
    }

    /// Camera center in world coordinates.
    pub fn center(&self) -> Vec3 {
        -(self.rotation.transpose() * self.translation)
    }

    /// Camera-to-world matrix, OpenCV axes.
    pub fn camera_to_world(&self) -> Mat4 {
        let r = self.rotation.transpose();
        Mat4::from_cols(r.x_axis.extend(0.0), r.y_axis.extend(0.0), r.z_axis.extend(0.0), self.center().extend(1.0))
    }

    /// A point in camera coordinates.
    pub fn world_to_camera(&self, p: Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }

    /// Pixel coordinates of a world point (continuous, pixel centers at +0.5), or `None` when the
    /// point is not in front of the camera.
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let c = self.world_to_camera(p);
        (c.z > 0.0).then(|| (self.fx * c.x / c.z + self.cx, self.fy * c.y / c.z + self.cy))
    }

    /// Unit direction, in world coordinates, of the ray through continuous pixel position (u, v).
    pub fn ray_direction(&self, u: f32, v: f32) -> Vec3 {
        let d_cam = Vec3::new((u - self.cx) / self.fx, (v - self.cy) / self.fy, 1.0);
        (self.rotation.transpose() * d_cam).normalize()
    }

    /// The same camera rendering at another resolution: intrinsics scale with the image, so the
    /// field of view is kept.
    pub fn resized(&self, width: u32, height: u32) -> Result<Self, CameraError> {
        let sx = width as f32 / self.width as f32;
        let sy = height as f32 / self.height as f32;
        let intrinsics =
            Intrinsics { width, height, fx: self.fx * sx, fy: self.fy * sy, cx: self.cx * sx, cy: self.cy * sy };
        Self::new(intrinsics, self.rotation, self.translation)
    }
}

fn rotation_deviation(r: Mat3) -> f32 {
    let gram = r * r.transpose() - Mat3::IDENTITY;
    let entries = gram.to_cols_array();
    let off = entries.iter().fold(0.0f32, |m, e| m.max(e.abs()));
    off.max((r.determinant() - 1.0).abs())
}

/// Nearest rotation by Gram-Schmidt on the rows (the input is already within tolerance).
fn orthonormalize(r: Mat3) -> Mat3 {
    let r = r.transpose(); // columns of r^T are the rows of r
    let x = r.x_axis.normalize();
    let y = (r.y_axis - x * x.dot(r.y_axis)).normalize();
    let z = x.cross(y);
    Mat3::from_cols(x, y, z).transpose()
}

/// Converts a unit quaternion (w, x, y, z), as COLMAP stores world-to-camera rotations, to a
/// matrix. The quaternion is normalized first; a zero quaternion yields `None`.
pub fn quaternion_to_matrix(q: [f64; 4]) -> Option<Mat3> {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(n.is_finite() && n > 1e-12) {
        return None;
    }
    let [w, x, y, z] = q.map(|v| v / n);
    let m = [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ];
    Some(glam::DMat3::from_cols_array_2d(&m).transpose().as_mat3())
}

/// Converts a rotation matrix to a unit quaternion (w, x, y, z) with w >= 0.
pub fn matrix_to_quaternion(r: Mat3) -> [f64; 4] {
    let q = glam::DQuat::from_mat3(&r.as_dmat3()).normalize();
    let q = if q.w < 0.0 { -q } else { q };
    [q.w, q.x, q.y, q.z]
}

/// `v` normalized, or zero when it has no direction. A vector whose squared length overflows
/// (components beyond about 1e19, a scene far from the origin) is scaled down first; others are
/// normalized as they are, so ordinary cameras keep their bits.
fn unit(v: Vec3) -> Vec3 {
    if v.length_squared().is_finite() || !v.is_finite() {
        return v.normalize_or_zero();
    }
    (v / v.abs().max_element()).normalize_or_zero()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_camera() -> Camera {
        let rotation = quaternion_to_matrix([0.9, 0.1, -0.3, 0.2]).unwrap();
        Camera::new(
            Intrinsics { width: 64, height: 48, fx: 50.0, fy: 55.0, cx: 31.0, cy: 25.0 },
            rotation,
            Vec3::new(0.1, -0.2, 3.0),
        )
        .unwrap()
    }

    #[test]
    fn quaternion_round_trip() {
        let q = [0.9f64, 0.1, -0.3, 0.2];
        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        let back = matrix_to_quaternion(quaternion_to_matrix(q).unwrap());
        for i in 0..4 {
            assert!((back[i] - q[i] / n).abs() < 1e-6, "{back:?} vs {q:?}");
        }
    }

    #[test]
    fn camera_to_world_inverts_world_to_camera() {
        let cam = test_camera();
        let p = Vec3::new(0.3, -1.0, 2.0);
        let back = cam.camera_to_world().transform_point3(cam.world_to_camera(p));
        assert!((back - p).length() < 1e-5);
        let again = Camera::from_camera_to_world(
            Intrinsics { width: 64, height: 48, fx: 50.0, fy: 55.0, cx: 31.0, cy: 25.0 },
            cam.camera_to_world(),
        )
        .unwrap();
        assert!((again.translation - cam.translation).length() < 1e-5);
    }

    #[test]
    fn projection_of_ray_lands_on_pixel() {
        let cam = test_camera();
        let d = cam.ray_direction(10.5, 40.5);
        let (u, v) = cam.project(cam.center() + 2.5 * d).unwrap();
        assert!((u - 10.5).abs() < 1e-3 && (v - 40.5).abs() < 1e-3, "({u}, {v})");
    }

    #[test]
    fn orbit_cameras_look_at_the_center_with_up_at_the_top() {
        let intrinsics = Intrinsics { width: 40, height: 30, fx: 30.0, fy: 30.0, cx: 20.0, cy: 15.0 };
        let center = Vec3::new(1.0, 2.0, 3.0);
        let up = Vec3::new(0.0, 0.0, 1.0);
        let cams = Camera::orbit(intrinsics, center, up, 4.0, 0.3, 6).unwrap();
        for cam in &cams {
            assert!(((cam.center() - center).length() - 4.0).abs() < 1e-4);
            let (u, v) = cam.project(center).unwrap();
            assert!((u - 20.0).abs() < 1e-3 && (v - 15.0).abs() < 1e-3, "center at ({u}, {v})");
            let (_, v_up) = cam.project(center + up * 0.5).unwrap();
            assert!(v_up < 15.0, "up should be toward the top of the image");
        }
        assert!(Camera::look_at(intrinsics, center, center, up).is_err());
        assert!(Camera::look_at(intrinsics, center, center + up, up).is_err(), "view along up has no roll");
        // A scene far from the origin: the squared distance overflows binary32.
        let far = Vec3::new(3e19, -2e19, 1e20);
        let cam = Camera::look_at(intrinsics, far, far + Vec3::new(0.0, 4e19, 0.0), up).expect("a direction");
        assert!(cam.rotation.is_finite() && (cam.rotation.row(2) - Vec3::Y).length() < 1e-6, "{:?}", cam.rotation);
    }

    #[test]
    fn opengl_camera_looks_down_minus_z() {
        let cam = Camera::from_opengl_camera_to_world(
            Intrinsics { width: 10, height: 10, fx: 5.0, fy: 5.0, cx: 5.0, cy: 5.0 },
            Mat4::IDENTITY,
        )
        .unwrap();
        // In OpenGL the identity camera looks down -z with y up.
        let (u, v) = cam.project(Vec3::new(0.0, 1.0, -2.0)).unwrap();
        assert!((u - 5.0).abs() < 1e-6 && v < 5.0);
        assert!(cam.project(Vec3::new(0.0, 0.0, 2.0)).is_none());
    }

    #[test]
    fn rejects_bad_cameras() {
        let r = Mat3::IDENTITY;
        assert!(matches!(
            Camera::new(Intrinsics { width: 0, height: 4, fx: 1.0, fy: 1.0, cx: 0.0, cy: 0.0 }, r, Vec3::ZERO),
            Err(CameraError::BadSize { .. })
        ));
        // An image header may claim any width; the limit keeps every pixel index in range.
        let huge = Intrinsics { width: MAX_SIDE + 1, height: 4, fx: 1.0, fy: 1.0, cx: 0.0, cy: 0.0 };
        assert_eq!(Camera::new(huge, r, Vec3::ZERO), Err(CameraError::BadSize { width: MAX_SIDE + 1, height: 4 }));
        let widest = Intrinsics { width: MAX_SIDE, ..huge };
        assert!(Camera::new(widest, r, Vec3::ZERO).is_ok());
        assert!(matches!(
            Camera::new(Intrinsics { width: 4, height: 4, fx: f32::NAN, fy: 1.0, cx: 0.0, cy: 0.0 }, r, Vec3::ZERO),
            Err(CameraError::BadFocal { .. })
        ));
        assert!(matches!(
            Camera::new(Intrinsics { width: 4, height: 4, fx: 1.0, fy: 1.0, cx: 0.0, cy: 0.0 }, r * 2.0, Vec3::ZERO),
            Err(CameraError::NotARotation { .. })
        ));
        assert!(matches!(
            Camera::new(
                Intrinsics { width: 4, height: 4, fx: 1.0, fy: 1.0, cx: 0.0, cy: 0.0 },
                r,
                Vec3::new(f32::INFINITY, 0.0, 0.0)
            ),
            Err(CameraError::NonFinitePose)
        ));
    }

    #[test]
    fn resizing_keeps_the_field_of_view() {
        let cam = test_camera();
        let half = cam.resized(32, 24).unwrap();
        assert_eq!((half.fx, half.cx), (25.0, 15.5));
        let p = Vec3::new(0.2, 0.1, 1.0);
        let (u, _) = cam.project(p).unwrap();
        let (uh, _) = half.project(p).unwrap();
        assert!((u / 2.0 - uh).abs() < 1e-4);
    }
}

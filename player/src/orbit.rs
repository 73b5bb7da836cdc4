//! The player's camera: an orbit around a target point (drag to turn, scroll to zoom, drag
//! with the right button to pan) that can also fly (keys move the target and the eye
//! together), starting from the stream's normalization or from a dataset camera.

use glam::Vec3;
use pwgs_codec::scene::{Base, Scene};
use pwgs_core::camera::{Camera, CameraError, Intrinsics};

/// Steepest pitch, short of the poles where the view direction meets `up`.
const MAX_PITCH: f32 = 1.55;
/// A new orbit looks down by this much (radians), as captures usually do.
const START_PITCH: f32 = 0.35;

/// An orbit camera. The view direction is `yaw` around `up` and `pitch` towards it, in a frame
/// fixed by `up`; the eye is `distance` behind `target` along it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orbit {
    pub target: Vec3,
    pub distance: f32,
    pub yaw: f32,
    pub pitch: f32,
    pub up: Vec3,
    /// Vertical field of view, radians.
    pub fov_y: f32,
}

impl Orbit {
    /// Looking at `target` from `distance` away, a little from above, with `up` as the
    /// world's up.
    pub fn around(target: Vec3, distance: f32, up: Vec3) -> Self {
        let up = up.try_normalize().unwrap_or(Vec3::NEG_Y);
        Self { target, distance: distance.max(1e-6), yaw: 0.0, pitch: -START_PITCH, up, fov_y: 0.9 }
    }

    /// The first view of a stream: at the median of its positions (Gaussians or anchors), which
    /// the content surrounds, from the stream's scale (streams normalize the training cameras
    /// to about that distance from their center).
    pub fn for_scene(scene: &Scene, up: Vec3) -> Self {
        let positions = match &scene.base {
            Base::Plain(g) => &g.means,
            Base::Anchors(a) => &a.positions,
        };
        Self::around(median(positions).unwrap_or(scene.frame.center), scene.frame.scale, up)
    }

    /// Where `camera` is and looks, orbiting a point `distance` in front of it, with `up` as
    /// the world's up.
    pub fn from_camera(camera: &Camera, distance: f32, up: Vec3) -> Self {
        let up = up.try_normalize().unwrap_or(Vec3::NEG_Y);
        let forward = camera.rotation.transpose() * Vec3::Z;
        let (f0, r0) = frame(up);
        let pitch = forward.dot(up).clamp(-1.0, 1.0).asin().clamp(-MAX_PITCH, MAX_PITCH);
        let yaw = forward.dot(r0).atan2(forward.dot(f0));
        let fov_y = 2.0 * (0.5 * camera.height as f32 / camera.fy).atan();
        Self { target: camera.center() + forward * distance, distance, yaw, pitch, up, fov_y }
    }

    /// The unit view direction.
    pub fn forward(&self) -> Vec3 {
        let (f0, r0) = frame(self.up);
        let horizontal = f0 * self.yaw.cos() + r0 * self.yaw.sin();
        horizontal * self.pitch.cos() + self.up.normalize() * self.pitch.sin()
    }

    pub fn eye(&self) -> Vec3 {
        self.target - self.forward() * self.distance
    }

    /// Turns by `dx`, `dy` radians (yaw, pitch), orbiting the target.
    pub fn rotate(&mut self, dx: f32, dy: f32) {
        self.yaw += dx;
        self.pitch = (self.pitch + dy).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Multiplies the distance to the target by `factor`.
    pub fn zoom(&mut self, factor: f32) {
        self.distance = (self.distance * factor).clamp(1e-6, 1e9);
    }

    /// Moves the target (and the eye) by `right` and `up` in units of the distance, in the
    /// image plane.
    pub fn pan(&mut self, right: f32, up: f32) {
        let forward = self.forward();
        let r = forward.cross(self.up).normalize_or_zero();
        let u = r.cross(forward);
        self.target += (r * right + u * up) * self.distance;
    }

    /// Moves the eye and the target together along the view (`ahead`), sideways and along
    /// `up`, in units of the distance.
    pub fn fly(&mut self, ahead: f32, right: f32, up: f32) {
        let forward = self.forward();
        let r = forward.cross(self.up).normalize_or_zero();
        self.target += (forward * ahead + r * right + self.up.normalize() * up) * self.distance;
    }

    /// The camera of a `width` x `height` view (principal point at the center).
    pub fn camera(&self, width: u32, height: u32) -> Result<Camera, CameraError> {
        let f = 0.5 * height as f32 / (0.5 * self.fov_y).tan();
        let intrinsics = Intrinsics { width, height, fx: f, fy: f, cx: 0.5 * width as f32, cy: 0.5 * height as f32 };
        Camera::look_at(intrinsics, self.eye(), self.target, self.up)
    }
}

/// The per-axis median of finite `points`, or `None` without any.
fn median(points: &[[f32; 3]]) -> Option<Vec3> {
    let mut m = [0.0; 3];
    for (axis, v) in m.iter_mut().enumerate() {
        let mut values: Vec<f32> = points.iter().map(|p| p[axis]).filter(|x| x.is_finite()).collect();
        if values.is_empty() {
            return None;
        }
        let mid = values.len() / 2;
        *v = *values.select_nth_unstable_by(mid, f32::total_cmp).1;
    }
    Some(Vec3::from(m))
}

/// Two unit vectors orthogonal to `up` and to each other: yaw 0 looks along the first, yaw
/// pi/2 along the second.
fn frame(up: Vec3) -> (Vec3, Vec3) {
    let up = up.normalize();
    let f0 = up.any_orthonormal_vector();
    (f0, f0.cross(up))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_orbit_from_a_camera_gives_that_camera_back() {
        let intrinsics = Intrinsics { width: 64, height: 48, fx: 50.0, fy: 50.0, cx: 32.0, cy: 24.0 };
        let up = Vec3::new(0.1, -1.0, 0.2);
        let camera = Camera::look_at(intrinsics, Vec3::new(1.0, -0.5, -3.0), Vec3::new(0.2, 0.1, 0.5), up).unwrap();
        let orbit = Orbit::from_camera(&camera, 2.0, up);
        let again = orbit.camera(64, 48).unwrap();
        assert!((again.center() - camera.center()).length() < 1e-4, "{:?}", again.center());
        assert!((again.rotation.row(2) - camera.rotation.row(2)).length() < 1e-4, "same view direction");
        assert!((again.fy - camera.fy).abs() < 1e-3);
    }

    #[test]
    fn turning_keeps_the_distance_and_panning_keeps_the_direction() {
        let mut orbit = Orbit::around(Vec3::new(1.0, 2.0, 3.0), 4.0, Vec3::NEG_Y);
        let target = orbit.target;
        orbit.rotate(0.7, 0.3);
        assert!(((orbit.eye() - target).length() - 4.0).abs() < 1e-4);
        let forward = orbit.forward();
        orbit.pan(0.1, -0.2);
        orbit.fly(0.5, 0.0, 0.0);
        assert!((orbit.forward() - forward).length() < 1e-6);
        assert!(orbit.target != target);
        assert_eq!(median(&[[1.0, 5.0, f32::NAN], [3.0, -1.0, 2.0], [2.0, 0.0, 1.0]]), Some(Vec3::new(2.0, 0.0, 2.0)));
        assert_eq!(median(&[]), None);
        orbit.rotate(0.0, 10.0);
        assert!(orbit.pitch <= MAX_PITCH, "pitch is clamped short of the pole");
        assert!(orbit.camera(32, 32).is_ok());
    }
}

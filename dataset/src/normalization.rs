//! Scene normalization: a center and a scale derived from the training cameras, so that
//! learning rates, densification thresholds and the wrapper's Plücker embeddings do not depend
//! on the units a capture happens to use. Stored in the stream header.

use glam::{DVec3, Vec3};
use pwgs_core::camera::Camera;
use pwgs_core::frame::SceneFrame;

/// Maps world coordinates to normalized ones: `(p - center) / scale`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneNormalization {
    pub center: Vec3,
    pub scale: f32,
}

impl SceneNormalization {
    /// Center of the camera centers, and 1.1 times the largest distance of a camera from it
    /// (the 3DGS "camera extent"). A single camera, or cameras all at one point, give scale 1.
    /// Computed in f64, so that cameras far from the origin cannot overflow the sum; `None`
    /// when the result does not fit in f32 (or a camera center does not).
    pub fn from_cameras(cameras: &[Camera]) -> Option<Self> {
        if cameras.is_empty() {
            return Some(Self { center: Vec3::ZERO, scale: 1.0 });
        }
        let centers: Vec<DVec3> = cameras.iter().map(|c| c.center().as_dvec3()).collect();
        let center = centers.iter().copied().sum::<DVec3>() / centers.len() as f64;
        let radius = centers.iter().map(|c| c.distance(center)).fold(0.0f64, f64::max);
        let scale = if radius > 1e-6 { 1.1 * radius } else { 1.0 };
        let normalization = Self { center: center.as_vec3(), scale: scale as f32 };
        (normalization.center.is_finite() && normalization.scale.is_finite()).then_some(normalization)
    }

    pub fn normalize(&self, p: Vec3) -> Vec3 {
        (p - self.center) / self.scale
    }

    /// The same normalization as the perceptual wrapper's Plücker embeddings take it.
    pub fn frame(&self) -> SceneFrame {
        SceneFrame { center: self.center, scale: self.scale }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat3;
    use pwgs_core::camera::Intrinsics;

    #[test]
    fn centers_cameras_and_scales_to_extent() {
        let cams: Vec<Camera> = [Vec3::new(1.0, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0)]
            .iter()
            .map(|c| {
                Camera::new(Intrinsics { width: 4, height: 4, fx: 2.0, fy: 2.0, cx: 2.0, cy: 2.0 }, Mat3::IDENTITY, -*c)
                    .unwrap()
            })
            .collect();
        let n = SceneNormalization::from_cameras(&cams).unwrap();
        assert!((n.center - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6);
        assert!((n.scale - 1.1).abs() < 1e-6);
        assert_eq!(SceneNormalization::from_cameras(&cams[..1]).unwrap().scale, 1.0);
    }

    #[test]
    fn cameras_far_from_the_origin_do_not_overflow() {
        let at = |x: f32| {
            let intrinsics = Intrinsics { width: 4, height: 4, fx: 2.0, fy: 2.0, cx: 2.0, cy: 2.0 };
            Camera::new(intrinsics, Mat3::IDENTITY, Vec3::new(-x, 0.0, 0.0)).unwrap()
        };
        // Their sum overflows f32; the mean does not.
        let n = SceneNormalization::from_cameras(&[at(3e38), at(3e38)]).unwrap();
        assert_eq!((n.center.x, n.scale), (3e38, 1.0));
        // A scale of 1.1 times 3.2e38 does not fit in f32.
        assert_eq!(SceneNormalization::from_cameras(&[at(3.2e38), at(-3.2e38)]), None);
    }
}

//! Scene normalization: a center and a scale derived from the training cameras, so that
//! learning rates, densification thresholds and the wrapper's Plücker embeddings do not depend
//! on the units a capture happens to use. Stored in the stream header.

use glam::Vec3;
use pwgs_decoder::camera::Camera;
use pwgs_decoder::wrapper::SceneFrame;

/// Maps world coordinates to normalized ones: `(p - center) / scale`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneNormalization {
    pub center: Vec3,
    pub scale: f32,
}

impl SceneNormalization {
    /// Center of the camera centers, and 1.1 times the largest distance of a camera from it
    /// (the 3DGS "camera extent"). A single camera, or cameras all at one point, give scale 1.
    pub fn from_cameras(cameras: &[Camera]) -> Self {
        if cameras.is_empty() {
            return Self { center: Vec3::ZERO, scale: 1.0 };
        }
        let centers: Vec<Vec3> = cameras.iter().map(Camera::center).collect();
        let center = centers.iter().copied().sum::<Vec3>() / centers.len() as f32;
        let radius = centers.iter().map(|c| c.distance(center)).fold(0.0f32, f32::max);
        let scale = if radius > 1e-6 { 1.1 * radius } else { 1.0 };
        Self { center, scale }
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
    use pwgs_decoder::camera::Intrinsics;

    #[test]
    fn centers_cameras_and_scales_to_extent() {
        let cams: Vec<Camera> = [Vec3::new(1.0, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0)]
            .iter()
            .map(|c| {
                Camera::new(Intrinsics { width: 4, height: 4, fx: 2.0, fy: 2.0, cx: 2.0, cy: 2.0 }, Mat3::IDENTITY, -*c)
                    .unwrap()
            })
            .collect();
        let n = SceneNormalization::from_cameras(&cams);
        assert!((n.center - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6);
        assert!((n.scale - 1.1).abs() < 1e-6);
        assert_eq!(SceneNormalization::from_cameras(&cams[..1]).scale, 1.0);
    }
}

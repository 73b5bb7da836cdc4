//! How faithfully a stream reproduces the model it was made from: renders of the original and
//! of the decoded Gaussians from the same cameras, compared by PSNR. Used for imported models,
//! which come without cameras, on an orbit around the scene.

use glam::Vec3;
use pwgs_codec::scene::Scene;
use pwgs_core::camera::{Camera, CameraError, Intrinsics};
use pwgs_core::rgb_image::RgbImage;
use pwgs_render::raster::{RenderOptions, render};

use crate::plain::compress::StreamContext;

/// Horizontal field of view of orbit cameras.
const ORBIT_FOV_DEGREES: f32 = 60.0;
/// Orbit radius in units of the normalization scale, and its elevation.
const ORBIT_RADIUS: f32 = 1.0;
const ORBIT_ELEVATION_DEGREES: f32 = 20.0;

/// `count` square cameras of `size` pixels circling the scene's normalization center.
pub fn orbit_cameras(context: &StreamContext, up: Vec3, count: usize, size: u32) -> Result<Vec<Camera>, CameraError> {
    let f = size as f32 / 2.0 / (ORBIT_FOV_DEGREES.to_radians() / 2.0).tan();
    let intrinsics =
        Intrinsics { width: size, height: size, fx: f, fy: f, cx: size as f32 / 2.0, cy: size as f32 / 2.0 };
    Camera::orbit(
        intrinsics,
        Vec3::from(context.center),
        up,
        ORBIT_RADIUS * context.scale,
        ORBIT_ELEVATION_DEGREES.to_radians(),
        count,
    )
}

/// Base renders of `scene` (the encoder's own, so without a work limit) from each camera,
/// clamped to the displayable range.
pub fn renders(scene: &Scene, cameras: &[Camera], options: &RenderOptions) -> Vec<RgbImage> {
    cameras
        .iter()
        .map(|cam| {
            let mut image = render(&scene.gaussians_for(cam), cam, options);
            image.clamp_to_displayable();
            image
        })
        .collect()
}

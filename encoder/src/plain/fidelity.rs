//! How faithfully a stream reproduces the model it was made from: renders of the original and
//! of the decoded Gaussians from the same cameras, compared by PSNR. Used for imported models,
//! which come without cameras, on an orbit around the scene.

use glam::Vec3;
use pwgs_codec::scene::Scene;
use pwgs_core::camera::{Camera, CameraError, Intrinsics};
use pwgs_core::rgb_image::RgbImage;
use pwgs_render::raster::{RenderOptions, render};

use crate::plain::compress::StreamContext;

/// Views on a circle around a model, looking at its normalization center.
#[derive(Debug, Clone)]
pub struct Orbit {
    pub views: usize,
    pub up: [f32; 3],
    /// Width and height of the views.
    pub size: u32,
    /// The circle's distance from the center, in units of the normalization scale.
    pub distance: f32,
    /// Its height above the center, as an angle from the horizon of `up` (negative: below).
    pub elevation_degrees: f32,
    /// The views' field of view (horizontal and vertical).
    pub fov_degrees: f32,
}

impl Orbit {
    /// The default circle: at the normalization's radius, 20 degrees up, 60-degree views.
    pub fn ring(views: usize, up: [f32; 3], size: u32) -> Self {
        Self { views, up, size, distance: 1.0, elevation_degrees: 20.0, fov_degrees: 60.0 }
    }
}

/// The square cameras of `orbit` around the scene's normalization center.
pub fn orbit_cameras(context: &StreamContext, orbit: &Orbit) -> Result<Vec<Camera>, CameraError> {
    let size = orbit.size;
    let f = size as f32 / 2.0 / (orbit.fov_degrees.to_radians() / 2.0).tan();
    let intrinsics =
        Intrinsics { width: size, height: size, fx: f, fy: f, cx: size as f32 / 2.0, cy: size as f32 / 2.0 };
    Camera::orbit(
        intrinsics,
        Vec3::from(context.center),
        Vec3::from(orbit.up),
        orbit.distance * context.scale,
        orbit.elevation_degrees.to_radians(),
        orbit.views,
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

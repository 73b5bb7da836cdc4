//! Plücker ray embeddings (docs/architecture.md section 1.2): for every pixel the line through the camera
//! center and the pixel center, as its unit direction d and its moment m = o x d about the
//! scene center, with o in scene-normalized coordinates so that |m| (the line's distance from
//! the scene center) does not grow with the capture's units. Channels [dx, dy, dz, mx, my, mz].

use glam::Vec3;
use rayon::prelude::*;

use pwgs_core::camera::Camera;

/// Channels per pixel.
pub const PLUCKER_CHANNELS: usize = 6;

/// The rays of one camera in a scene frame, from which any row of embeddings can be produced on
/// its own.
#[derive(Debug, Clone, Copy)]
pub struct PluckerRays {
    camera: Camera,
    /// The camera center in scene-normalized coordinates.
    origin: Vec3,
}

impl PluckerRays {
    /// `center` and `scale` normalize the scene: o = (camera center - center) / scale.
    pub fn new(camera: &Camera, center: Vec3, scale: f32) -> Self {
        Self { camera: *camera, origin: (camera.center() - center) / scale }
    }

    /// Row `y` of the embeddings into `row` (`width * 6` values, pixel-interleaved).
    pub fn row(&self, y: usize, row: &mut [f32]) {
        assert_eq!(row.len(), self.camera.width as usize * PLUCKER_CHANNELS, "Plücker row length");
        for (x, px) in row.chunks_exact_mut(PLUCKER_CHANNELS).enumerate() {
            let d = self.camera.ray_direction(x as f32 + 0.5, y as f32 + 0.5);
            let m = self.origin.cross(d);
            px.copy_from_slice(&[d.x, d.y, d.z, m.x, m.y, m.z]);
        }
    }
}

/// The embeddings of every pixel of `camera`, pixel-interleaved (`(y * width + x) * 6 + c`).
pub fn plucker_embeddings(camera: &Camera, center: Vec3, scale: f32) -> Vec<f32> {
    let rays = PluckerRays::new(camera, center, scale);
    let mut out = vec![0.0f32; camera.width as usize * camera.height as usize * PLUCKER_CHANNELS];
    out.par_chunks_mut(camera.width as usize * PLUCKER_CHANNELS).enumerate().for_each(|(y, row)| rays.row(y, row));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use pwgs_core::camera::Intrinsics;

    #[test]
    fn directions_are_unit_and_moments_are_perpendicular_and_invariant_along_the_ray() {
        let intrinsics = Intrinsics { width: 9, height: 7, fx: 8.0, fy: 9.0, cx: 4.0, cy: 3.7 };
        let eye = Vec3::new(3.0, -1.0, 2.0);
        let camera = Camera::look_at(intrinsics, eye, Vec3::ZERO, Vec3::Y).unwrap();
        let (center, scale) = (Vec3::new(0.5, 0.0, -0.5), 2.0);
        let e = plucker_embeddings(&camera, center, scale);
        assert_eq!(e.len(), 9 * 7 * 6);
        for px in e.chunks_exact(6) {
            let d = Vec3::new(px[0], px[1], px[2]);
            let m = Vec3::new(px[3], px[4], px[5]);
            assert!((d.length() - 1.0).abs() < 1e-6);
            assert!(d.dot(m).abs() < 1e-5);
            // Any point of the ray gives the same moment.
            let further = (eye + 3.0 * d - center) / scale;
            assert!((further.cross(d) - m).length() < 1e-5);
        }
        // The central pixel's ray points roughly at the target.
        let mid = &e[(3 * 9 + 4) * 6..][..3];
        assert!(Vec3::from_slice(mid).dot(-eye.normalize()) > 0.99);
    }
}

//! Lens distortion removal. Datasets whose cameras carry radial or tangential distortion are
//! resampled once at load onto an ideal pinhole camera with the same intrinsics, so that the
//! rasterizer (which only knows pinhole cameras) sees geometrically correct images.
//!
//! Output pixels whose distorted source position falls outside the image are filled by edge
//! clamping; with the mild distortions of real captures (fern: k1 = 0.02) this touches a few
//! pixels at the corners.

use pwgs_core::camera::Camera;
use pwgs_core::rgb_image::RgbImage;

/// Points per side of the grid over the image on which [`Distortion::check`] evaluates the
/// distortion.
const CHECK_GRID: u32 = 65;

/// A distortion model in normalized image coordinates (x = (u - cx) / fx, y = (v - cy) / fy).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distortion {
    None,
    /// Radial polynomial: r' = r (1 + k1 r^2 + k2 r^4) (COLMAP SIMPLE_RADIAL has k2 = 0).
    Radial {
        k1: f64,
        k2: f64,
    },
    /// OpenCV's radial + tangential model (COLMAP OPENCV, nerfstudio OPENCV).
    Opencv {
        k1: f64,
        k2: f64,
        p1: f64,
        p2: f64,
    },
}

impl Distortion {
    /// Maps undistorted normalized coordinates to distorted ones.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        match *self {
            Self::None => (x, y),
            Self::Radial { k1, k2 } => {
                let r2 = x * x + y * y;
                let f = 1.0 + k1 * r2 + k2 * r2 * r2;
                (x * f, y * f)
            }
            Self::Opencv { k1, k2, p1, p2 } => {
                let r2 = x * x + y * y;
                let f = 1.0 + k1 * r2 + k2 * r2 * r2;
                let xy = x * y;
                (x * f + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x), y * f + 2.0 * p2 * xy + p1 * (r2 + 2.0 * y * y))
            }
        }
    }

    pub fn is_none(&self) -> bool {
        matches!(self, Self::None) || self.distort(0.3, -0.2) == (0.3, -0.2)
    }

    /// (k1, k2, p1, p2), zero where the model has no such coefficient.
    fn coefficients(&self) -> [f64; 4] {
        match *self {
            Self::None => [0.0; 4],
            Self::Radial { k1, k2 } => [k1, k2, 0.0, 0.0],
            Self::Opencv { k1, k2, p1, p2 } => [k1, k2, p1, p2],
        }
    }

    /// The determinant of the Jacobian of [`Self::distort`] at (x, y): positive where the map
    /// keeps the image's orientation, zero or negative where it folds the image over.
    pub fn jacobian_determinant(&self, x: f64, y: f64) -> f64 {
        let [k1, k2, p1, p2] = self.coefficients();
        let r2 = x * x + y * y;
        let f = 1.0 + k1 * r2 + k2 * r2 * r2;
        // d f / d x = g x and d f / d y = g y.
        let g = 2.0 * k1 + 4.0 * k2 * r2;
        let dxd_dx = f + g * x * x + 2.0 * p1 * y + 6.0 * p2 * x;
        let dxd_dy = g * x * y + 2.0 * p1 * x + 2.0 * p2 * y;
        let dyd_dx = g * x * y + 2.0 * p2 * y + 2.0 * p1 * x;
        let dyd_dy = f + g * y * y + 2.0 * p2 * x + 6.0 * p1 * y;
        dxd_dx * dyd_dy - dxd_dy * dyd_dx
    }

    /// Checks that [`undistort`] gives a meaningful image for `camera` (at the resolution the
    /// distortion is stated for): finite coefficients, and over the whole image (a grid of
    /// [`CHECK_GRID`]² points, borders included) a map that does not fold the image over (a
    /// strongly negative k1 at a wide field of view does: parts of the scene would appear twice,
    /// mirrored) and moves no pixel by more than the image's size (coefficients that large send
    /// every sample to the clamped border).
    pub fn check(&self, camera: &Camera) -> Result<(), String> {
        let coefficients = self.coefficients();
        if coefficients.iter().any(|c| !c.is_finite()) {
            return Err(format!("distortion {self:?} has a non-finite coefficient"));
        }
        let [fx, fy, cx, cy] = [camera.fx, camera.fy, camera.cx, camera.cy].map(f64::from);
        let (w, h) = (f64::from(camera.width), f64::from(camera.height));
        let last = f64::from(CHECK_GRID - 1);
        for j in 0..CHECK_GRID {
            for i in 0..CHECK_GRID {
                let (u, v) = (w * f64::from(i) / last, h * f64::from(j) / last);
                let (x, y) = ((u - cx) / fx, (v - cy) / fy);
                let (xd, yd) = self.distort(x, y);
                let shift = ((xd - x) * fx).hypot((yd - y) * fy);
                if !(self.jacobian_determinant(x, y) > 0.0) {
                    return Err(format!(
                        "distortion {self:?} folds the image over near pixel ({u:.0}, {v:.0}) of {w}x{h}; \
                         it cannot be undistorted"
                    ));
                }
                if !(shift <= w.max(h)) {
                    return Err(format!(
                        "distortion {self:?} moves pixel ({u:.0}, {v:.0}) by {shift:.3e} pixels, more than the \
                         {w}x{h} image's size"
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Resamples `image` (taken with the given intrinsics and distortion) onto the ideal pinhole
/// camera with the same intrinsics, bilinearly.
pub fn undistort(image: &RgbImage, intrinsics: [f64; 4], distortion: Distortion) -> RgbImage {
    if distortion.is_none() {
        return image.clone();
    }
    let [fx, fy, cx, cy] = intrinsics;
    let mut out = RgbImage::filled(image.width, image.height, [0.0; 3]);
    for j in 0..image.height {
        for i in 0..image.width {
            let x = (i as f64 + 0.5 - cx) / fx;
            let y = (j as f64 + 0.5 - cy) / fy;
            let (xd, yd) = distortion.distort(x, y);
            let rgb = sample_bilinear(image, xd * fx + cx, yd * fy + cy);
            out.set_pixel(i, j, rgb);
        }
    }
    out
}

/// Bilinear sample at continuous pixel position (u, v) (pixel centers at +0.5), edges clamped.
pub fn sample_bilinear(image: &RgbImage, u: f64, v: f64) -> [f32; 3] {
    let max_x = image.width as f64 - 1.0;
    let max_y = image.height as f64 - 1.0;
    let x = (u - 0.5).clamp(0.0, max_x);
    let y = (v - 0.5).clamp(0.0, max_y);
    let (x0, y0) = (x.floor(), y.floor());
    let (x1, y1) = ((x0 + 1.0).min(max_x), (y0 + 1.0).min(max_y));
    let (tx, ty) = ((x - x0) as f32, (y - y0) as f32);
    let p = |xx: f64, yy: f64| image.pixel(xx as u32, yy as u32);
    let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
    std::array::from_fn(|k| {
        let top = a[k] + (b[k] - a[k]) * tx;
        let bottom = c[k] + (d[k] - c[k]) * tx;
        top + (bottom - top) * ty
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(width: u32, height: u32, focal: f32) -> Camera {
        let intrinsics = pwgs_core::camera::Intrinsics {
            width,
            height,
            fx: focal,
            fy: focal,
            cx: width as f32 / 2.0,
            cy: height as f32 / 2.0,
        };
        Camera::new(intrinsics, glam::Mat3::IDENTITY, glam::Vec3::ZERO).unwrap()
    }

    #[test]
    fn jacobian_determinant_matches_finite_differences() {
        let d = Distortion::Opencv { k1: -0.3, k2: 0.08, p1: 0.01, p2: -0.02 };
        let h = 1e-6;
        for (x, y) in [(0.0, 0.0), (0.4, -0.7), (-1.1, 0.3), (0.9, 0.9)] {
            let (ax, ay) = d.distort(x + h, y);
            let (bx, by) = d.distort(x - h, y);
            let (cx, cy) = d.distort(x, y + h);
            let (ex, ey) = d.distort(x, y - h);
            let numeric = ((ax - bx) * (cy - ey) - (cx - ex) * (ay - by)) / (4.0 * h * h);
            let analytic = d.jacobian_determinant(x, y);
            assert!((numeric - analytic).abs() < 1e-6 * analytic.abs().max(1.0), "({x}, {y}): {numeric} vs {analytic}");
        }
    }

    #[test]
    fn usable_distortions_pass_the_check() {
        // fern's SIMPLE_RADIAL camera, and a strong but regular wide-angle barrel.
        assert_eq!(Distortion::Radial { k1: 0.0198, k2: 0.0 }.check(&camera(4032, 3024, 3260.5)), Ok(()));
        let barrel = Distortion::Opencv { k1: -0.25, k2: 0.05, p1: 1e-3, p2: -1e-3 };
        assert_eq!(barrel.check(&camera(1920, 1080, 1000.0)), Ok(()));
        assert_eq!(Distortion::None.check(&camera(10, 10, 1.0)), Ok(()));
    }

    #[test]
    fn degenerate_distortions_are_named() {
        let wide = camera(640, 480, 200.0); // corners at a normalized radius of 2
        let cases = [
            (Distortion::Radial { k1: f64::NAN, k2: 0.0 }, "has a non-finite coefficient"),
            (Distortion::Opencv { k1: 0.0, k2: 0.0, p1: f64::INFINITY, p2: 0.0 }, "has a non-finite coefficient"),
            // 1 - 3 r^2 / 4 reaches zero at r = 1.15: the image folds over beyond it.
            (Distortion::Radial { k1: -0.25, k2: 0.0 }, "folds the image over near pixel"),
            (Distortion::Radial { k1: 1e30, k2: 0.0 }, "more than the 640x480 image's size"),
        ];
        for (distortion, needle) in cases {
            let err = distortion.check(&wide).unwrap_err();
            assert!(err.contains(needle) && err.contains(&format!("{distortion:?}")), "{err}");
        }
    }

    #[test]
    fn identity_distortion_is_a_copy() {
        let mut img = RgbImage::filled(5, 4, [0.2, 0.4, 0.6]);
        img.set_pixel(2, 1, [1.0, 0.0, 0.5]);
        assert_eq!(undistort(&img, [4.0, 4.0, 2.5, 2.0], Distortion::Radial { k1: 0.0, k2: 0.0 }), img);
    }

    #[test]
    fn undistortion_moves_a_distorted_dot_back() {
        // Draw a dot where the lens put the point that ideally projects to (30.5, 20.5).
        let (fx, fy, cx, cy) = (40.0, 40.0, 32.0, 24.0);
        let distortion = Distortion::Radial { k1: 0.2, k2: 0.05 };
        let (xd, yd) = distortion.distort((30.5 - 0.0 - cx) / fx + 0.6, (20.5 - cy) / fy - 0.3);
        let mut img = RgbImage::filled(64, 48, [0.0; 3]);
        let (ud, vd) = (xd * fx + cx, yd * fy + cy);
        img.set_pixel(ud as u32, vd as u32, [1.0; 3]);
        let out = undistort(&img, [fx, fy, cx, cy], distortion);
        let (ui, vi) = ((0.6 * fx + 30.5) as u32, (-0.3 * fy + 20.5) as u32);
        let near = (ui - 1..=ui + 1).flat_map(|u| (vi - 1..=vi + 1).map(move |v| (u, v)));
        let energy: f32 = near.map(|(u, v)| out.pixel(u, v)[0]).sum();
        assert!(energy > 0.5, "dot not found near ({ui}, {vi}): {energy}");
    }
}

//! Lens distortion removal. Datasets whose cameras carry radial or tangential distortion are
//! resampled once at load onto an ideal pinhole camera with the same intrinsics, so that the
//! rasterizer (which only knows pinhole cameras) sees geometrically correct images.
//!
//! Output pixels whose distorted source position falls outside the image are filled by edge
//! clamping; with the mild distortions of real captures (fern: k1 = 0.02) this touches a few
//! pixels at the corners.

use pwgs_decoder::rgb_image::RgbImage;

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

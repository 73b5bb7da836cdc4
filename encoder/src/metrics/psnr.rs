//! Peak signal-to-noise ratio for images in [0, 1].

use pwgs_core::rgb_image::RgbImage;

/// Mean squared error over all pixels and channels, accumulated in f64.
pub fn mse(a: &RgbImage, b: &RgbImage) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height), "images differ in size");
    let sum: f64 = a.data.iter().zip(&b.data).map(|(x, y)| ((x - y) as f64).powi(2)).sum();
    sum / a.data.len() as f64
}

/// PSNR in dB with peak 1: 10 log10(1 / MSE). Identical images give +infinity.
pub fn psnr(a: &RgbImage, b: &RgbImage) -> f64 {
    psnr_of_mse(mse(a, b))
}

/// The PSNR in dB (peak 1) of a mean squared error.
pub fn psnr_of_mse(mse: f64) -> f64 {
    -10.0 * mse.log10()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_value() {
        let a = RgbImage::filled(4, 4, [0.5; 3]);
        let b = RgbImage::filled(4, 4, [0.6; 3]);
        assert!((psnr(&a, &b) - 20.0).abs() < 1e-5);
        assert_eq!(psnr(&a, &a), f64::INFINITY);
    }
}

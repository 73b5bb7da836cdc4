//! Images as the NCHW tensors the metrics take.

use burn::tensor::{Device, Tensor, TensorData};
use pwgs_core::rgb_image::RgbImage;

/// `image` as a [1, 3, H, W] tensor (planar channels) on `device`.
pub fn image_tensor(image: &RgbImage, device: &Device) -> Tensor<4> {
    let (w, h) = (image.width as usize, image.height as usize);
    let mut planar = vec![0.0f32; 3 * w * h];
    for (p, rgb) in image.data.chunks_exact(3).enumerate() {
        for c in 0..3 {
            planar[c * w * h + p] = rgb[c];
        }
    }
    Tensor::from_data(TensorData::new(planar, [1, 3, h, w]), device)
}

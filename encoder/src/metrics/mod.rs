//! Image quality metrics: PSNR and SSIM, and the VGG16-based LPIPS, DISTS and Wasserstein
//! Distortion, all as Burn functions (differentiable where they serve as losses).

mod depthwise;
pub mod dists;
pub mod evaluate;
pub mod image_tensor;
mod lowpass_op;
pub mod lpips;
pub mod pickle;
pub mod psnr;
pub mod sigma_map;
pub mod ssim;
pub mod suite;
pub mod vgg16;
pub mod vgg_wasserstein;
pub mod wasserstein;
pub mod weights;
pub mod weights_fetch;

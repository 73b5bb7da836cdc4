//! Image quality metrics.

pub mod psnr;

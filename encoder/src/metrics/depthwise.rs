//! Separable depthwise filtering on NCHW tensors: the one convolution shape that SSIM's Gaussian
//! window, WD's binomial lowpass and DISTS' L2 pooling all share.
//!
//! A separable kernel `k ⊗ k` with zero padding `p` and stride `s` equals a row pass
//! (padding `p`, stride `s` along the width) followed by a column pass (the same along the
//! height): the row pass of an all-zero padded row is zero again. Two 1-D passes cost `2k`
//! multiply-adds per output instead of `k²`.

use burn::tensor::module::conv2d;
use burn::tensor::ops::ConvOptions;
use burn::tensor::{Tensor, TensorData};

/// Filters every channel of `x` [N, C, H, W] with `taps ⊗ taps` (the same 1-D taps vertically
/// and horizontally), zero padding `padding` on each side, sampling every `stride`-th output.
/// The output is [N, C, (H + 2p - k) / s + 1, (W + 2p - k) / s + 1], in `x`'s float type (the
/// taps are converted to it); differentiable in `x`.
pub fn separable_filter(x: Tensor<4>, taps: &[f64], stride: usize, padding: usize) -> Tensor<4> {
    let [_, channels, _, _] = x.dims();
    let k = taps.len();
    let device = x.device();
    let data = TensorData::new(taps.repeat(channels), [channels, 1, 1, k]);
    let row = Tensor::<4>::from_data(data, (&device, x.dtype()));
    let column = row.clone().reshape([channels, 1, k, 1]);
    let x = conv2d(x, row, None, ConvOptions::new([1, stride], [0, padding], [1, 1], channels));
    conv2d(x, column, None, ConvOptions::new([stride, 1], [padding, 0], [1, 1], channels))
}

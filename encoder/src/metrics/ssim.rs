//! Structural similarity (SSIM, Wang et al. 2004) as a differentiable Burn function, in the two
//! boundary conventions that published numbers use.
//!
//! Per channel, with an 11x11 Gaussian window (sigma 1.5) giving local means mu, biased local
//! variances sigma² = E(x²) - mu² and covariance sigma_ab:
//! `ssim = (2 mu_a mu_b + C1)(2 sigma_ab + C2) / ((mu_a² + mu_b² + C1)(sigma_a² + sigma_b² + C2))`,
//! C1 = 0.01², C2 = 0.03² (data range 1), averaged over channels, pixels and the batch.

use burn::tensor::Tensor;

use super::depthwise::separable_filter;
use super::lowpass_op::ssim_window;

/// Window side; the window is centred, so it reaches `WINDOW / 2` pixels either side.
const WINDOW: usize = 11;
const SIGMA: f64 = 1.5;
const C1: f64 = 0.01 * 0.01;
const C2: f64 = 0.03 * 0.03;

/// Which windows the mean runs over. The two differ near the border (by ~0.02 on a 32x40 image),
/// so a score is only comparable with others of the same convention.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SsimConvention {
    /// The 3DGS convention (`gaussian-splatting/utils/loss_utils.py`, used for its training loss
    /// and its reported SSIM): the window is zero-padded by 5 pixels, and every pixel's window
    /// counts, border pixels included.
    ZeroPadded,
    /// Wang et al. / scikit-image / pytorch_msssim: only windows that lie entirely inside the
    /// image. The image must be at least 11x11.
    Valid,
}

/// The normalized 1-D Gaussian taps; the 2-D window is their outer product.
pub(super) fn gaussian_taps() -> Vec<f64> {
    let center = (WINDOW / 2) as f64;
    let g: Vec<f64> = (0..WINDOW).map(|x| (-(x as f64 - center).powi(2) / (2.0 * SIGMA * SIGMA)).exp()).collect();
    let sum: f64 = g.iter().sum();
    g.iter().map(|v| v / sum).collect()
}

/// Mean SSIM of `a` against `b`, both [N, C, H, W] with values in [0, 1]; returns a `[1]` tensor.
///
/// Differentiable in both inputs, so a training loss is `0.8 * l1 + 0.2 * (1 - ssim(render, gt,
/// SsimConvention::ZeroPadded))`. Panics if the shapes differ, or for [`SsimConvention::Valid`]
/// if the image is smaller than the window.
pub fn ssim(a: Tensor<4>, b: Tensor<4>, convention: SsimConvention) -> Tensor<1> {
    assert_eq!(a.dims(), b.dims(), "SSIM of tensors of different shapes");
    let [_, channels, height, width] = a.dims();
    // One depthwise pass filters all five moment images at once.
    let moments = Tensor::cat(vec![a.clone(), b.clone(), a.clone() * a.clone(), b.clone() * b.clone(), a * b], 1);
    let filtered = match convention {
        SsimConvention::ZeroPadded => ssim_window(moments),
        SsimConvention::Valid => {
            assert!(
                height >= WINDOW && width >= WINDOW,
                "valid-window SSIM needs at least 11x11, got {width}x{height}"
            );
            separable_filter(moments, &gaussian_taps(), 1, 0)
        }
    };
    let [mu_a, mu_b, e_aa, e_bb, e_ab]: [Tensor<4>; 5] = filtered
        .split(channels, 1)
        .try_into()
        .unwrap_or_else(|_| unreachable!("five moment groups of {channels} channels"));
    let mu_ab = mu_a.clone() * mu_b.clone();
    let mu_aa = mu_a.clone() * mu_a;
    let mu_bb = mu_b.clone() * mu_b;
    let var_a = e_aa - mu_aa.clone();
    let var_b = e_bb - mu_bb.clone();
    let cov = e_ab - mu_ab.clone();
    let numerator = (mu_ab.mul_scalar(2.0).add_scalar(C1)) * (cov.mul_scalar(2.0).add_scalar(C2));
    let denominator = (mu_aa + mu_bb).add_scalar(C1) * (var_a + var_b).add_scalar(C2);
    (numerator / denominator).mean()
}

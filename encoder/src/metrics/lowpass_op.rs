//! Same-size symmetric filters (WD's stride-1 binomial lowpass, SSIM's Gaussian window) as Burn
//! operations with their own backward pass on the `flex` backend.
//!
//! Autodiff would differentiate the depthwise convolutions through `conv_transpose2d`, which
//! `flex` runs as one GEMM per channel group plus a scatter: 5-6x slower than the forward (2.7 s
//! against 0.5 s for 256 channels at 504x378), most of WD's cost besides VGG, and about a tenth
//! of an anchor training step (SSIM's backward). Both filters are symmetric and zero-padded by
//! half their width with stride 1, so each is its own adjoint: the input gradient is the same
//! filter of the output gradient, computed with the fast forward convolution.
//! On other backends [`binomial_lowpass`] and [`ssim_window`] fall back to plain differentiable
//! convolutions.

use burn::backend::autodiff::Autodiff;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops};
use burn::backend::ops::{FloatTensorOps, ModuleOps};
use burn::backend::tensor::FloatTensor;
use burn::backend::{Backend, Dispatch, DispatchDevice, Flex, TensorMetadata, backend_extension};
use burn::tensor::ops::ConvOptions;
use burn::tensor::{Shape, Tensor, TensorData};

use super::depthwise::separable_filter;
use super::sigma_map::BINOMIAL;
use super::ssim::gaussian_taps;

#[backend_extension(Flex, Autodiff)]
pub trait LowpassBackend: Backend {
    /// The 3x3 binomial lowpass of every channel of [N, C, H, W], zero padding 1, stride 1.
    fn binomial_lowpass(x: FloatTensor<Self>) -> FloatTensor<Self>;
    /// SSIM's 11x11 Gaussian window over every channel of [N, C, H, W], zero padding 5, stride 1.
    fn ssim_window(x: FloatTensor<Self>) -> FloatTensor<Self>;
}

/// A symmetric separable filter that keeps the image's size.
#[derive(Debug, Clone, Copy)]
enum SameSizeFilter {
    Binomial,
    SsimWindow,
}

impl SameSizeFilter {
    fn taps(self) -> Vec<f64> {
        match self {
            Self::Binomial => BINOMIAL.to_vec(),
            Self::SsimWindow => gaussian_taps(),
        }
    }

    /// The same filter as plain differentiable convolutions, for backends without the op.
    fn plain(self, x: Tensor<4>) -> Tensor<4> {
        let taps = self.taps();
        separable_filter(x, &taps, 1, taps.len() / 2)
    }

    /// Row pass then column pass, each a depthwise convolution (flex has a fast path for those).
    fn apply(self, x: FloatTensor<Flex>) -> FloatTensor<Flex> {
        let channels = x.shape()[1];
        let device = x.device();
        let taps = self.taps();
        let (k, padding) = (taps.len(), taps.len() / 2);
        let data = TensorData::new(taps.repeat(channels), [channels, 1, 1, k]).convert_dtype(x.dtype());
        let row = Flex::float_from_data(data, &device);
        let column = Flex::float_reshape(row.clone(), Shape::new([channels, 1, k, 1]));
        let x = Flex::conv2d(x, row, None, ConvOptions::new([1, 1], [0, padding], [1, 1], channels));
        Flex::conv2d(x, column, None, ConvOptions::new([1, 1], [padding, 0], [1, 1], channels))
    }

    fn with_backward<C: CheckpointStrategy>(self, x: FloatTensor<Autodiff<Flex, C>>) -> FloatTensor<Autodiff<Flex, C>> {
        let node = x.node();
        let output = self.apply(x.primitive().clone());
        FilterBackward(self).prepare::<C>([node]).compute_bound().stateless(output)
    }
}

impl LowpassBackend for Flex {
    fn binomial_lowpass(x: FloatTensor<Self>) -> FloatTensor<Self> {
        SameSizeFilter::Binomial.apply(x)
    }

    fn ssim_window(x: FloatTensor<Self>) -> FloatTensor<Self> {
        SameSizeFilter::SsimWindow.apply(x)
    }
}

#[derive(Debug)]
struct FilterBackward(SameSizeFilter);

impl Backward<Flex, 1> for FilterBackward {
    type State = ();

    fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _checkpointer: &mut Checkpointer) {
        let grad = grads.consume::<Flex>(&ops.node);
        if let [Some(parent)] = ops.parents {
            grads.register::<Flex>(parent.id, self.0.apply(grad));
        }
    }
}

impl<C: CheckpointStrategy> LowpassBackend for Autodiff<Flex, C> {
    fn binomial_lowpass(x: FloatTensor<Self>) -> FloatTensor<Self> {
        SameSizeFilter::Binomial.with_backward::<C>(x)
    }

    fn ssim_window(x: FloatTensor<Self>) -> FloatTensor<Self> {
        SameSizeFilter::SsimWindow.with_backward::<C>(x)
    }
}

fn on_flex(x: &Tensor<4>) -> bool {
    matches!(x.device().without_autodiff().as_dispatch(), DispatchDevice::Flex(_))
}

/// The binomial lowpass `[[1,2,1],[2,4,2],[1,2,1]] / 16` of every channel of `x` [N, C, H, W], zero
/// padding 1, stride 1; differentiable, with the fast backward on `flex`.
pub fn binomial_lowpass(x: Tensor<4>) -> Tensor<4> {
    if on_flex(&x) {
        Tensor::from_dispatch(<Dispatch as LowpassBackend>::binomial_lowpass(x.into_dispatch()))
    } else {
        SameSizeFilter::Binomial.plain(x)
    }
}

/// SSIM's Gaussian window (11 taps, sigma 1.5) over every channel of `x` [N, C, H, W], zero
/// padding 5, stride 1; differentiable, with the fast backward on `flex`.
pub fn ssim_window(x: Tensor<4>) -> Tensor<4> {
    if on_flex(&x) {
        Tensor::from_dispatch(<Dispatch as LowpassBackend>::ssim_window(x.into_dispatch()))
    } else {
        SameSizeFilter::SsimWindow.plain(x)
    }
}

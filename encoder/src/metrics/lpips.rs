//! LPIPS v0.1 with the VGG16 trunk (Zhang et al. 2018), as `richzhang/PerceptualSimilarity`
//! computes it: VGG16 (max pooling) features relu1_2 .. relu5_3, each unit-normalized across
//! channels (f / (‖f‖ + 1e-10)), squared differences weighted per channel by the learned linear
//! heads, averaged over space and summed over layers.

use std::path::PathBuf;

use burn::tensor::{Device, Tensor, TensorData};

use super::vgg16::{Pooling, Vgg16, channel_affine};
use super::weights::{WeightFile, WeightsError, load};

/// LPIPS' ScalingLayer: (x − shift) / scale on input in [−1, 1]; the same as ImageNet
/// normalization of the [0, 1] image.
const SHIFT: [f64; 3] = [-0.030, -0.088, -0.188];
const SCALE: [f64; 3] = [0.458, 0.448, 0.450];

/// How [0, 1] images enter the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LpipsInput {
    /// The official convention: images mapped to [−1, 1] (2x − 1) first.
    Official,
    /// What 3DGS's `metrics.py` (its `lpipsPyTorch` copy) does: [0, 1] fed to the scaling layer
    /// unchanged (a known departure of that script from the official LPIPS). Published 3DGS LPIPS figures
    /// use this; they are not comparable with official ones.
    Unit,
}

/// LPIPS (VGG, v0.1) on one device.
pub struct Lpips {
    vgg: Vgg16,
    /// The linear heads as [1, C, 1, 1] channel weights.
    heads: Vec<Tensor<4>>,
}

impl Lpips {
    /// Loads the VGG16 and LPIPS head weights from the first of `dirs` holding each.
    pub fn load(dirs: &[PathBuf], device: &Device) -> Result<Self, WeightsError> {
        let vgg = Vgg16::load(dirs, device)?;
        let weights = load(WeightFile::LpipsVgg, dirs)?;
        let heads = (0..5)
            .map(|k| {
                let w = &weights[&format!("lin{k}.model.1.weight")];
                let shape: [usize; 4] = w.shape.clone().try_into().expect("checked (1, C, 1, 1) shape");
                Tensor::from_data(TensorData::new(w.values.clone(), shape), device)
            })
            .collect();
        Ok(Self { vgg, heads })
    }

    /// LPIPS of each image pair of `a`, `b` [N, 3, H, W] in [0, 1]: `[N]` values, 0 for identical
    /// images. Differentiable in both.
    pub fn distance(&self, a: Tensor<4>, b: Tensor<4>, input: LpipsInput) -> Tensor<1> {
        assert_eq!(a.dims(), b.dims(), "LPIPS of images of different shapes");
        let n = a.dims()[0];
        let features = |x: Tensor<4>| {
            let x = match input {
                LpipsInput::Official => x.mul_scalar(2.0).sub_scalar(1.0),
                LpipsInput::Unit => x,
            };
            self.vgg.features(channel_affine(x, SHIFT, SCALE), Pooling::Max)
        };
        let unit = |f: Tensor<4>| f.clone() / f.square().sum_dim(1).sqrt().add_scalar(1e-10);
        let mut total: Option<Tensor<4>> = None;
        for ((fa, fb), head) in features(a).into_iter().zip(features(b)).zip(&self.heads) {
            let difference = (unit(fa) - unit(fb)).square();
            let term = (difference * head.clone()).sum_dim(1).mean_dim(2).mean_dim(3);
            total = Some(match total {
                Some(t) => t + term,
                None => term,
            });
        }
        total.expect("five layers").reshape([n])
    }
}

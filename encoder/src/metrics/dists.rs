//! DISTS (Ding et al. 2020, "Image Quality Assessment: Unifying Structure and Texture
//! Similarity") as its official code (`dingkeyan93/DISTS`, `DISTS_pt.py`) computes it.
//!
//! VGG16 with L2 pooling on ImageNet-normalized input; the feature list is the raw [0, 1] image
//! followed by relu1_2 .. relu5_3 (3 + 1472 = 1475 channels). Per channel, over the whole image:
//! texture similarity S1 = (2 μa μb + c1) / (μa² + μb² + c1) and structure similarity
//! S2 = (2 σab + c2) / (σa² + σb² + c2), population statistics, c1 = c2 = 1e-6.
//! DISTS = 1 − Σ (α S1 + β S2) with the learned α, β normalized to sum to one.
//! The official demo first resizes images whose short side exceeds 256; the metric does not,
//! and neither does this.

use std::path::PathBuf;

use burn::tensor::{Device, Tensor, TensorData};

use super::vgg16::{Pooling, Vgg16, imagenet_normalize};
use super::weights::{HostTensor, VGG16_LAYER_CHANNELS, WeightFile, WeightsError, load};

const C1: f64 = 1e-6;
const C2: f64 = 1e-6;

/// DISTS on one device.
pub struct Dists {
    vgg: Vgg16,
    /// Per feature array (image, then the five VGG layers): α and β as [1, C, 1, 1], already
    /// divided by Σα + Σβ.
    alpha: Vec<Tensor<4>>,
    beta: Vec<Tensor<4>>,
}

impl Dists {
    /// Loads the VGG16 and DISTS weights from the first of `dirs` holding each.
    pub fn load(dirs: &[PathBuf], device: &Device) -> Result<Self, WeightsError> {
        let vgg = Vgg16::load(dirs, device)?;
        let weights = load(WeightFile::DistsAlphaBeta, dirs)?;
        Ok(Self::new(vgg, &weights["alpha"], &weights["beta"], device))
    }

    fn new(vgg: Vgg16, alpha: &HostTensor, beta: &HostTensor, device: &Device) -> Self {
        let total: f64 = alpha.values.iter().chain(&beta.values).map(|&v| v as f64).sum();
        let split = |w: &HostTensor| {
            let mut start = 0;
            std::iter::once(3)
                .chain(VGG16_LAYER_CHANNELS)
                .map(|c| {
                    let values: Vec<f64> = w.values[start..start + c].iter().map(|&v| v as f64 / total).collect();
                    start += c;
                    Tensor::<4>::from_data(TensorData::new(values, [1, c, 1, 1]), device)
                })
                .collect()
        };
        Self { vgg, alpha: split(alpha), beta: split(beta) }
    }

    /// DISTS of each image pair of `a`, `b` [N, 3, H, W] in [0, 1]: `[N]` values, 0 for identical
    /// images. Symmetric; differentiable in both.
    pub fn distance(&self, a: Tensor<4>, b: Tensor<4>) -> Tensor<1> {
        assert_eq!(a.dims(), b.dims(), "DISTS of images of different shapes");
        let n = a.dims()[0];
        let features = |x: Tensor<4>| {
            let mut f = vec![x.clone()];
            f.extend(self.vgg.features(imagenet_normalize(x), Pooling::L2));
            f
        };
        let mut similarity: Option<Tensor<4>> = None;
        for (k, (fa, fb)) in features(a).into_iter().zip(features(b)).enumerate() {
            let spatial_mean = |t: Tensor<4>| t.mean_dim(2).mean_dim(3);
            let mean_a = spatial_mean(fa.clone());
            let mean_b = spatial_mean(fb.clone());
            let var_a = spatial_mean((fa.clone() - mean_a.clone()).square());
            let var_b = spatial_mean((fb.clone() - mean_b.clone()).square());
            let cov = spatial_mean(fa * fb) - mean_a.clone() * mean_b.clone();
            let texture = (mean_a.clone() * mean_b.clone()).mul_scalar(2.0).add_scalar(C1)
                / (mean_a.square() + mean_b.square()).add_scalar(C1);
            let structure = cov.mul_scalar(2.0).add_scalar(C2) / (var_a + var_b).add_scalar(C2);
            let term = (texture * self.alpha[k].clone() + structure * self.beta[k].clone()).sum_dim(1);
            similarity = Some(match similarity {
                Some(s) => s + term,
                None => term,
            });
        }
        similarity.expect("six feature arrays").reshape([n]).neg().add_scalar(1.0)
    }
}

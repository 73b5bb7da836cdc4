//! Wasserstein Distortion on VGG16 features, the wrapper's training loss, as the reference
//! computes it (`codex/loss/pretrained_features.py` and its PyTorch port; wd-spec.md §1.2).
//!
//! Feature arrays (16): the ImageNet-normalized image itself, then relu1_2 .. relu5_3 of VGG16
//! with 2x2 average pooling, at 3 image scales (each scale the binomial stride-2 lowpass of the
//! previous, applied to the normalized image). WD is the sum over the arrays of
//! [`wasserstein_distortion`](super::wasserstein::wasserstein_distortion), each with the image's
//! log2σ map resampled to its size and lowered by its stride.
//!
//! Training compares many renders with the same few ground-truth images, so the target's
//! features are computed once per view ([`WdTarget`]) and only the render goes through VGG.

use std::path::PathBuf;

use burn::tensor::{Device, Tensor};

use super::sigma_map::Log2Sigma;
use super::vgg16::{Pooling, Vgg16, imagenet_normalize};
use super::wasserstein::{lowpass, multi_wasserstein_distortion};
use super::weights::WeightsError;

/// Image scales of the feature pyramid.
pub const IMAGE_SCALES: usize = 3;

/// The smallest image side: relu5_3 of the coarsest scale must keep at least one pixel.
pub const MIN_SIDE: usize = 61;

/// The target side of a WD comparison: its features, detached, and its size.
#[derive(Clone)]
pub struct WdTarget {
    features: Vec<Tensor<4>>,
    size: [usize; 4],
}

impl WdTarget {
    /// Memory the cached features take (f32 values).
    pub fn bytes(&self) -> usize {
        self.features.iter().map(|f| f.dims().iter().product::<usize>() * 4).sum()
    }
}

/// WD with VGG16 features on one device.
pub struct VggWasserstein {
    /// `None`: the cheap variant that compares the normalized image's 3 scales only.
    vgg: Option<Vgg16>,
}

impl VggWasserstein {
    /// Loads the VGG16 weights from the first of `dirs` holding them.
    pub fn load(dirs: &[PathBuf], device: &Device) -> Result<Self, WeightsError> {
        Ok(Self { vgg: Some(Vgg16::load(dirs, device)?) })
    }

    /// WD on pixels alone: the normalized image at the 3 scales, no VGG features. Much cheaper
    /// and needs no weights, but blind to texture beyond local color statistics.
    pub fn pixels_only() -> Self {
        Self { vgg: None }
    }

    /// The 16 feature arrays of `x` [N, 3, H, W] in [0, 1]: the normalized image, then
    /// relu1_2 .. relu5_3 at each of the 3 scales (pixels only: the normalized image at each
    /// scale). Differentiable in `x`. Panics if a side is below [`MIN_SIDE`].
    pub fn features(&self, x: Tensor<4>) -> Vec<Tensor<4>> {
        let [_, _, height, width] = x.dims();
        assert!(
            height >= MIN_SIDE && width >= MIN_SIDE,
            "VGG WD needs at least {MIN_SIDE}x{MIN_SIDE}, got {width}x{height}"
        );
        let mut scale = imagenet_normalize(x);
        let mut features = vec![scale.clone()];
        for s in 0..IMAGE_SCALES {
            match &self.vgg {
                Some(vgg) => features.extend(vgg.features(scale.clone(), Pooling::Average)),
                None if s > 0 => features.push(scale.clone()),
                None => {}
            }
            if s + 1 < IMAGE_SCALES {
                scale = lowpass(scale, 2);
            }
        }
        features
    }

    /// Computes and detaches the features of a target image, for [`Self::distortion`]; cache
    /// it per training view.
    pub fn target(&self, image: Tensor<4>) -> WdTarget {
        let size = image.dims();
        WdTarget { features: self.features(image.detach()).into_iter().map(Tensor::detach).collect(), size }
    }

    /// WD of `image` [N, 3, H, W] in [0, 1] against a cached target of the same size, with the
    /// given log2σ (at the image's resolution). Returns a `[1]` tensor, differentiable in `image`.
    pub fn distortion(&self, image: Tensor<4>, target: &WdTarget, log2_sigma: &Log2Sigma) -> Tensor<1> {
        assert_eq!(image.dims(), target.size, "WD image and target differ in size");
        let [_, _, height, width] = image.dims();
        multi_wasserstein_distortion(&self.features(image), &target.features, log2_sigma, [height, width])
    }

    /// WD of `a` against `b`, both [N, 3, H, W] in [0, 1], without a cache; differentiable in
    /// `a` only (`b` is the target).
    pub fn distortion_pair(&self, a: Tensor<4>, b: Tensor<4>, log2_sigma: &Log2Sigma) -> Tensor<1> {
        let target = self.target(b);
        self.distortion(a, &target, log2_sigma)
    }
}

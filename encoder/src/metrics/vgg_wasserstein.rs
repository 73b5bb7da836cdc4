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
use super::vgg16::{Pooling, VGG_BLOCKS, Vgg16, imagenet_normalize};
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

/// How much of the feature pyramid WD compares: the reference's is every VGG16 block at every
/// image scale; fewer cost less (training's speed-against-error table, docs/results/cpu-speed.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WdDepth {
    /// VGG16 blocks, 1 to 5: relu1_2 .. relu(blocks)_x.
    pub blocks: usize,
    /// Image scales, 1 to [`IMAGE_SCALES`].
    pub scales: usize,
}

impl Default for WdDepth {
    fn default() -> Self {
        Self { blocks: VGG_BLOCKS, scales: IMAGE_SCALES }
    }
}

/// WD with VGG16 features on one device.
pub struct VggWasserstein {
    /// `None`: the cheap variant that compares the normalized image's scales only.
    vgg: Option<Vgg16>,
    depth: WdDepth,
}

impl VggWasserstein {
    /// Loads the VGG16 weights from the first of `dirs` holding them.
    pub fn load(dirs: &[PathBuf], device: &Device) -> Result<Self, WeightsError> {
        Ok(Self { vgg: Some(Vgg16::load(dirs, device)?), depth: WdDepth::default() })
    }

    /// WD with the features of `vgg`.
    pub fn with_network(vgg: Vgg16) -> Self {
        Self { vgg: Some(vgg), depth: WdDepth::default() }
    }

    /// WD on pixels alone: the normalized image at the 3 scales, no VGG features. Much cheaper
    /// and needs no weights, but blind to texture beyond local color statistics.
    pub fn pixels_only() -> Self {
        Self { vgg: None, depth: WdDepth::default() }
    }

    /// The same WD on part of the pyramid (the defaults are the reference's). Panics outside
    /// 1..=5 blocks or 1..=3 scales.
    pub fn with_depth(self, depth: WdDepth) -> Self {
        assert!((1..=VGG_BLOCKS).contains(&depth.blocks), "WD compares 1 to {VGG_BLOCKS} VGG blocks");
        assert!((1..=IMAGE_SCALES).contains(&depth.scales), "WD compares 1 to {IMAGE_SCALES} image scales");
        Self { depth, ..self }
    }

    /// The feature arrays of `x` [N, 3, H, W] in [0, 1]: the normalized image, then relu1_2 ..
    /// relu5_3 at each of the 3 scales, 16 arrays (pixels only: the normalized image at each
    /// scale; a shallower [`WdDepth`]: its blocks at its scales). Differentiable in `x`.
    /// Panics if a side is below [`MIN_SIDE`].
    pub fn features(&self, x: Tensor<4>) -> Vec<Tensor<4>> {
        let [_, _, height, width] = x.dims();
        assert!(
            height >= MIN_SIDE && width >= MIN_SIDE,
            "VGG WD needs at least {MIN_SIDE}x{MIN_SIDE}, got {width}x{height}"
        );
        let WdDepth { blocks, scales } = self.depth;
        let mut scale = imagenet_normalize(x);
        let mut features = vec![scale.clone()];
        for s in 0..scales {
            match &self.vgg {
                Some(vgg) => features.extend(vgg.first_features(scale.clone(), Pooling::Average, blocks)),
                None if s > 0 => features.push(scale.clone()),
                None => {}
            }
            if s + 1 < scales {
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

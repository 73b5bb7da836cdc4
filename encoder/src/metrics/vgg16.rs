//! The VGG16 feature extractor behind LPIPS, DISTS and WD: torchvision's ImageNet VGG16 conv
//! stack (3x3 convs, zero padding 1, ReLU), returning relu1_2, relu2_2, relu3_3, relu4_3 and
//! relu5_3. The metrics differ only in the input scaling and in the pooling between blocks,
//! so both are the caller's choice.

use std::collections::HashMap;
use std::path::PathBuf;

use burn::tensor::activation::relu;
use burn::tensor::module::{avg_pool2d, conv2d, max_pool2d};
use burn::tensor::ops::{AvgPoolOptions, ConvOptions, MaxPoolOptions};
use burn::tensor::{Device, Tensor, TensorData};
use pwgs_core::random::SplitMix64;

use super::depthwise::separable_filter;
use super::sigma_map::BINOMIAL;
use super::weights::{HostTensor, VGG16_CONVS, WeightFile, WeightsError, load};

/// Convolutions per block; each block but the first starts with a pooling.
const BLOCKS: [usize; 5] = [2, 2, 3, 3, 3];

/// VGG16's blocks, each ending in one of the feature arrays relu1_2 .. relu5_3.
pub const VGG_BLOCKS: usize = BLOCKS.len();

/// ImageNet channel statistics of torchvision's preprocessing.
pub const IMAGENET_MEAN: [f64; 3] = [0.485, 0.456, 0.406];
pub const IMAGENET_STD: [f64; 3] = [0.229, 0.224, 0.225];

/// The downsampling between blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pooling {
    /// VGG's own 2x2 max pooling, stride 2 (LPIPS).
    Max,
    /// 2x2 average pooling, stride 2, no padding, sizes floored (WD: max pooling's gradient
    /// reaches one pixel in four, which makes a poor texture loss).
    Average,
    /// DISTS' L2 pooling: sqrt(binomial3x3(x²) + 1e-12), stride 2, zero padding 1, so the size
    /// is ceil(h/2); it is anti-aliased, so the features do not alias under shifts.
    L2,
}

struct Conv {
    weight: Tensor<4>,
    bias: Tensor<1>,
}

/// VGG16's conv stack on one device. Weights are constants: gradients flow to the input only.
pub struct Vgg16 {
    convs: Vec<Conv>,
}

impl Vgg16 {
    /// Loads `vgg16_features.safetensors` from the first of `dirs` that has it
    /// ([`super::weights::default_dirs`] for the usual places).
    pub fn load(dirs: &[PathBuf], device: &Device) -> Result<Self, WeightsError> {
        Ok(Self::from_tensors(&load(WeightFile::Vgg16, dirs)?, device))
    }

    /// Builds the network from already checked weights ([`super::weights::load`]).
    pub fn from_tensors(tensors: &HashMap<String, HostTensor>, device: &Device) -> Self {
        let tensor = |key: String| &tensors[&key];
        let convs = VGG16_CONVS
            .iter()
            .map(|&(i, out, inp)| {
                let w = tensor(format!("features.{i}.weight"));
                let b = tensor(format!("features.{i}.bias"));
                Conv {
                    weight: Tensor::from_data(TensorData::new(w.values.clone(), [out, inp, 3, 3]), device),
                    bias: Tensor::from_data(TensorData::new(b.values.clone(), [out]), device),
                }
            })
            .collect();
        Self { convs }
    }

    /// VGG16's shapes with weights drawn at random (uniform, He-scaled, zero biases): the same
    /// arithmetic as the trained network, for timing where the weights file is not at hand.
    pub fn random(seed: u64, device: &Device) -> Self {
        let mut rng = SplitMix64(seed);
        let convs = VGG16_CONVS
            .iter()
            .map(|&(_, out, inp)| {
                let bound = (6.0 / (inp * 9) as f32).sqrt();
                let values: Vec<f32> = (0..out * inp * 9).map(|_| rng.uniform(-bound, bound)).collect();
                Conv {
                    weight: Tensor::from_data(TensorData::new(values, [out, inp, 3, 3]), device),
                    bias: Tensor::zeros([out], device),
                }
            })
            .collect();
        Self { convs }
    }

    /// relu1_2, relu2_2, relu3_3, relu4_3, relu5_3 of `x` [N, 3, H, W], which must already be
    /// scaled as the metric requires (see [`imagenet_normalize`]). Differentiable in `x`.
    pub fn features(&self, x: Tensor<4>, pooling: Pooling) -> Vec<Tensor<4>> {
        self.first_features(x, pooling, BLOCKS.len())
    }

    /// The first `blocks` (1 to 5) of [`Self::features`], without running the deeper layers.
    pub fn first_features(&self, x: Tensor<4>, pooling: Pooling, blocks: usize) -> Vec<Tensor<4>> {
        assert!((1..=BLOCKS.len()).contains(&blocks), "VGG16 has blocks 1 to {}, not {blocks}", BLOCKS.len());
        let mut convs = self.convs.iter();
        let mut h = x;
        let mut out = Vec::with_capacity(blocks);
        for (block, &count) in BLOCKS.iter().enumerate().take(blocks) {
            if block > 0 {
                h = pool(h, pooling);
            }
            for conv in convs.by_ref().take(count) {
                let options = ConvOptions::new([1, 1], [1, 1], [1, 1], 1);
                h = relu(conv2d(h, conv.weight.clone(), Some(conv.bias.clone()), options));
            }
            out.push(h.clone());
        }
        out
    }
}

fn pool(x: Tensor<4>, pooling: Pooling) -> Tensor<4> {
    match pooling {
        Pooling::Max => max_pool2d(x, MaxPoolOptions::new([2, 2])),
        Pooling::Average => avg_pool2d(x, AvgPoolOptions::new([2, 2])),
        Pooling::L2 => separable_filter(x.square(), &BINOMIAL, 2, 1).add_scalar(1e-12).sqrt(),
    }
}

/// (x − mean) / std per channel with per-channel `mean` and `std`, on [N, 3, H, W].
pub fn channel_affine(x: Tensor<4>, mean: [f64; 3], std: [f64; 3]) -> Tensor<4> {
    let device = x.device();
    let options = (&device, x.dtype());
    let mean = Tensor::<4>::from_data(TensorData::new(mean.to_vec(), [1, 3, 1, 1]), options);
    let std = Tensor::<4>::from_data(TensorData::new(std.to_vec(), [1, 3, 1, 1]), options);
    (x - mean) / std
}

/// torchvision's ImageNet normalization of [0, 1] images, the input VGG16 was trained on.
pub fn imagenet_normalize(x: Tensor<4>) -> Tensor<4> {
    channel_affine(x, IMAGENET_MEAN, IMAGENET_STD)
}

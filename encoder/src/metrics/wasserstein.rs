//! Wasserstein Distortion (WD; Qiu, Wagner, Ballé, Theis 2024) on feature arrays, as the PyTorch
//! port of the reference implementation (`balle-lab/wasserstein-distortion`) computes it; see
//! `shared/reference/wd-spec.md` §1.
//!
//! At every location, WD compares the local feature distributions of two images, pooled over a
//! window of width ~2^log2σ, with the 2-Wasserstein distance between diagonal Gaussians:
//! Σ_c (μa − μb)² + (νa − νb)², ν the local standard deviation. Small σ asks for the same
//! features (fidelity), large σ only for the same texture statistics (realism).
//!
//! Local statistics come from a pyramid of 3x3 binomial lowpasses (zero padding): level l ≥ 1
//! pools the level l−1 moments, and each level after the first works on every other sample.
//! Level 0 is the unpooled squared difference. The σ map blends neighbouring levels
//! ([`level_weights`]).

use burn::tensor::{Tensor, TensorData, s};

use super::depthwise::separable_filter;
use super::lowpass_op::binomial_lowpass;
use super::sigma_map::{BINOMIAL, Log2Sigma, SigmaMap, level_weights};

/// Variances are clamped here before the square root (PyTorch port): it keeps the derivative
/// of sqrt finite where a window is flat, and passes no gradient through clamped values.
const VARIANCE_FLOOR: f64 = 1e-8;

/// The 3x3 binomial lowpass `[[1,2,1],[2,4,2],[1,2,1]] / 16` of every channel, zero padding 1,
/// keeping every `stride`-th sample from index 0 (output j centred on input stride·j), so the
/// output is ceil(h/stride) x ceil(w/stride). Differentiable.
pub fn lowpass(x: Tensor<4>, stride: usize) -> Tensor<4> {
    match stride {
        1 => binomial_lowpass(x),
        _ => separable_filter(x, &BINOMIAL, stride, 1),
    }
}

/// A host weight map as a [1, 1, h, w] tensor in `like`'s device and float type.
fn weight_tensor(map: &SigmaMap, like: &Tensor<4>) -> Tensor<4> {
    let data = TensorData::new(map.values.clone(), [1, 1, map.height, map.width]);
    Tensor::from_data(data, (&like.device(), like.dtype()))
}

/// `mean(weight ⊙ map)` over all N·C·h·w elements, the weight broadcast over batch and channels.
fn weighted_mean(map: Tensor<4>, weight: &SigmaMap) -> Tensor<1> {
    let weight = weight_tensor(weight, &map);
    (map * weight).mean()
}

/// WD between two feature arrays `a`, `b` [N, C, h, w] with the log2σ map `log2_sigma` (h x w):
/// Σ_i mean(weight_i ⊙ W2map_i) over levels 0..=5. With N > 1 this is the mean of the per-image
/// values. Levels whose weight is zero everywhere are never computed. Differentiable in both
/// arrays; identical arrays give exactly 0.
pub fn wasserstein_distortion(a: Tensor<4>, b: Tensor<4>, log2_sigma: &SigmaMap) -> Tensor<1> {
    assert_eq!(a.dims(), b.dims(), "WD of feature arrays of different shapes");
    let [_, channels, height, width] = a.dims();
    assert_eq!((log2_sigma.height, log2_sigma.width), (height, width), "log2 sigma map size");
    let (device, dtype) = (a.device(), a.dtype());
    let weights = level_weights(log2_sigma);
    let mut terms = Vec::new();
    if let Some(weight) = &weights[0] {
        terms.push(weighted_mean((a.clone() - b.clone()).square(), weight));
    }
    let top = weights.iter().rposition(Option::is_some).unwrap_or(0);
    // The raw first and second moments of both arrays, filtered together in one depthwise pass.
    let mut moments = Tensor::cat(vec![a.clone(), a.square(), b.clone(), b.square()], 1);
    for (level, weight) in weights.iter().enumerate().take(top + 1).skip(1) {
        let pooled = lowpass(moments, 1);
        if let Some(weight) = weight {
            let [mean_a, power_a, mean_b, power_b]: [Tensor<4>; 4] =
                pooled.clone().split(channels, 1).try_into().unwrap_or_else(|_| unreachable!("four moment groups"));
            let sd =
                |mean: Tensor<4>, power: Tensor<4>| (power - mean.clone().square()).clamp_min(VARIANCE_FLOOR).sqrt();
            let sd_a = sd(mean_a.clone(), power_a);
            let sd_b = sd(mean_b.clone(), power_b);
            terms.push(weighted_mean((mean_a - mean_b).square() + (sd_a - sd_b).square(), weight));
        }
        // The next level pools these moments on every other sample; keeping indices 0, 2, ...
        // of the stride-1 lowpass is the stride-2 lowpass centred on even samples.
        if level == top {
            break;
        }
        moments = pooled.slice(s![.., .., ..;2, ..;2]);
    }
    terms.into_iter().reduce(|x, y| x + y).unwrap_or_else(|| Tensor::zeros([1], (&device, dtype)))
}

/// WD summed over several feature arrays of one image pair (`multi_wasserstein_distortion` in
/// the reference): array k gets the image's σ map resampled to its size and lowered by its
/// stride ([`Log2Sigma::for_array`]). `image_size` is [H, W] of the image the arrays come from.
/// No per-array weights: each array's term is already a channel mean. Panics if `log2_sigma`
/// fails [`Log2Sigma::validate`].
pub fn multi_wasserstein_distortion(
    a: &[Tensor<4>],
    b: &[Tensor<4>],
    log2_sigma: &Log2Sigma,
    image_size: [usize; 2],
) -> Tensor<1> {
    assert_eq!(a.len(), b.len(), "WD of feature lists of different lengths");
    assert!(!a.is_empty(), "WD of no feature arrays");
    if let Err(e) = log2_sigma.validate() {
        panic!("{e}");
    }
    let [image_height, image_width] = image_size;
    a.iter()
        .zip(b)
        .map(|(fa, fb)| {
            let [_, _, height, width] = fa.dims();
            let map = log2_sigma.for_array(image_height, image_width, height, width);
            wasserstein_distortion(fa.clone(), fb.clone(), &map)
        })
        .reduce(|x, y| x + y)
        .expect("at least one array")
}

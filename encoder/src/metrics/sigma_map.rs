//! The pooling-width maps of Wasserstein Distortion, computed on the host in float64.
//!
//! WD pools features over a window of width ~2^log2σ. The σ map is an input, never trained, so
//! everything derived from it (its resampling to each feature array, the per-level blending
//! weights) is plain arithmetic here; the loss only multiplies the resulting constant weight
//! maps into its differentiable terms. Conventions are the PyTorch port of the reference WD
//! (`balle-lab/wasserstein-distortion`), see `shared/reference/wd-spec.md` §1.5–1.7.

/// Number of pooling levels; log2σ = l selects level l, so values must lie in [0, LEVELS].
pub const LEVELS: usize = 5;

/// The 1-D binomial lowpass taps, [1, 2, 1] / 4; the 2-D kernel is their outer product.
pub const BINOMIAL: [f64; 3] = [0.25, 0.5, 0.25];

/// A log2σ map over an image or a feature array, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct SigmaMap {
    pub height: usize,
    pub width: usize,
    pub values: Vec<f64>,
}

/// How wide WD pools, given for the whole image.
#[derive(Debug, Clone, PartialEq)]
pub enum Log2Sigma {
    /// The same log2σ at every pixel (the reference scripts use 2 or 4).
    Constant(f64),
    /// A per-pixel log2σ at the image's resolution (e.g. from a saliency model: small where
    /// the eye looks, so detail must match exactly; large elsewhere, so texture statistics suffice).
    Map(SigmaMap),
}

impl SigmaMap {
    pub fn constant(height: usize, width: usize, value: f64) -> Self {
        Self { height, width, values: vec![value; height * width] }
    }

    fn at(&self, y: isize, x: isize) -> f64 {
        if y < 0 || x < 0 || y >= self.height as isize || x >= self.width as isize {
            0.0
        } else {
            self.values[y as usize * self.width + x as usize]
        }
    }

    /// The binomial lowpass with zero padding 1 and stride 2, output j centred on input 2j
    /// (PyTorch-port parity; JAX "SAME" centres on 2j+1 for even sizes). Zero padding makes
    /// the map decay toward 0 at the borders, as in both reference implementations.
    pub fn lowpass_stride2(&self) -> Self {
        let (height, width) = (self.height.div_ceil(2), self.width.div_ceil(2));
        let mut values = Vec::with_capacity(height * width);
        for j in 0..height {
            for i in 0..width {
                let mut sum = 0.0;
                for (dy, ky) in BINOMIAL.iter().enumerate() {
                    for (dx, kx) in BINOMIAL.iter().enumerate() {
                        sum += ky * kx * self.at(2 * j as isize + dy as isize - 1, 2 * i as isize + dx as isize - 1);
                    }
                }
                values.push(sum);
            }
        }
        Self { height, width, values }
    }

    /// Resamples to `height` x `width` like PyTorch's `F.interpolate(mode="bilinear",
    /// antialias=True, align_corners=False)`: a triangle filter stretched by the scale factor
    /// when shrinking, plain bilinear when enlarging, with weights renormalized at the borders.
    pub fn resize(&self, height: usize, width: usize) -> Self {
        let rows = resample_weights(self.height, height);
        let columns = resample_weights(self.width, width);
        let mut values = Vec::with_capacity(height * width);
        for (y0, wy) in &rows {
            for (x0, wx) in &columns {
                let mut sum = 0.0;
                for (dy, ky) in wy.iter().enumerate() {
                    let row = &self.values[(y0 + dy) * self.width..];
                    sum += ky * wx.iter().enumerate().map(|(dx, kx)| kx * row[x0 + dx]).sum::<f64>();
                }
                values.push(sum);
            }
        }
        Self { height, width, values }
    }

    /// The largest value, or 0 for an empty map.
    fn max(&self) -> f64 {
        self.values.iter().copied().fold(0.0, f64::max)
    }
}

/// For each output index, the first input index and the normalized weights from there on.
/// Follows ATen's antialiased separable interpolation (`_compute_indices_weights_aa`).
fn resample_weights(input: usize, output: usize) -> Vec<(usize, Vec<f64>)> {
    let scale = input as f64 / output as f64;
    let (support, inverse) = if scale >= 1.0 { (scale, 1.0 / scale) } else { (1.0, 1.0) };
    (0..output)
        .map(|i| {
            let center = scale * (i as f64 + 0.5);
            // ATen truncates toward zero here; the lower bound is clamped at 0 right after.
            let start = ((center - support + 0.5).trunc().max(0.0)) as usize;
            let end = ((center + support + 0.5).trunc() as usize).min(input);
            let weights: Vec<f64> =
                (start..end).map(|j| (1.0 - ((j as f64 - center + 0.5) * inverse).abs()).max(0.0)).collect();
            let total: f64 = weights.iter().sum();
            (start, weights.iter().map(|w| w / total).collect())
        })
        .collect()
}

impl Log2Sigma {
    /// Checks the values: finite and at most [`LEVELS`] (above it the level weights no longer sum
    /// to one; the JAX reference rejects such maps too), and a map of the stated size.
    pub fn validate(&self) -> Result<(), String> {
        let values = match self {
            Log2Sigma::Constant(v) => std::slice::from_ref(v),
            Log2Sigma::Map(map) => {
                if map.values.len() != map.height * map.width {
                    return Err(format!(
                        "log2 sigma map: {} values for {}x{}",
                        map.values.len(),
                        map.width,
                        map.height
                    ));
                }
                &map.values[..]
            }
        };
        match values.iter().find(|v| !(v.is_finite() && **v <= LEVELS as f64)) {
            Some(v) => Err(format!("log2 sigma must be finite and at most {LEVELS}, got {v}")),
            None => Ok(()),
        }
    }

    /// The σ map of one feature array of `height` x `width` taken from an image of
    /// `image_height` x `image_width`: resampled to the array's size, then lowered by the
    /// array's mean log2 stride, (log2(H/h) + log2(W/w)) / 2, and clamped at 0. A feature
    /// pixel already spans 2^stride image pixels, so it needs that much less pooling.
    pub fn for_array(&self, image_height: usize, image_width: usize, height: usize, width: usize) -> SigmaMap {
        let shift = ((image_height as f64 / height as f64).log2() + (image_width as f64 / width as f64).log2()) / 2.0;
        let mut map = match self {
            // Resampling a constant gives the constant: the weights are normalized.
            Log2Sigma::Constant(v) => SigmaMap::constant(height, width, *v),
            Log2Sigma::Map(map) => {
                assert_eq!((map.height, map.width), (image_height, image_width), "log2 sigma map size");
                map.resize(height, width)
            }
        };
        for v in &mut map.values {
            *v = (*v - shift).max(0.0);
        }
        map
    }
}

/// The blending weights of the WD levels 0..=LEVELS for one feature array:
/// `weight_i = max(0, 1 - |ls_i - i|)`, where levels 0 and 1 use the array's own map and level
/// i ≥ 2 the map lowpassed (stride 2) i - 1 times, matching that level's resolution.
///
/// A level whose weight is zero everywhere is `None`: the loss skips it, value and gradient
/// unchanged. Lowpassing never raises the maximum of a non-negative map, so every level above
/// ceil(max ls) is skipped, and for ls ≥ 1 everywhere level 0 is too.
pub fn level_weights(log2_sigma: &SigmaMap) -> Vec<Option<SigmaMap>> {
    let mut ls = log2_sigma.clone();
    let mut levels = Vec::with_capacity(LEVELS + 1);
    for i in 0..=LEVELS {
        if i >= 2 {
            ls = ls.lowpass_stride2();
        }
        if ls.max() <= i as f64 - 1.0 {
            // All higher levels have zero weight too (see above).
            levels.resize(LEVELS + 1, None);
            break;
        }
        let weights: Vec<f64> = ls.values.iter().map(|v| (1.0 - (v - i as f64).abs()).max(0.0)).collect();
        let used = weights.iter().any(|&w| w > 0.0);
        levels.push(used.then_some(SigmaMap { height: ls.height, width: ls.width, values: weights }));
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    /// wd-spec.md §1.9: the 16→8 antialiased resize of a 0..4 ramp (the T5 σ map).
    #[test]
    fn antialiased_resize_matches_the_reference_row() {
        let ramp = SigmaMap { height: 16, width: 16, values: (0..256).map(|i| 4.0 * (i % 16) as f64 / 15.0).collect() };
        let row = &ramp.resize(8, 8).values[..8];
        let expected = [0.190476, 0.666667, 1.2, 1.733333, 2.266667, 2.8, 3.333333, 3.809524];
        for (v, e) in row.iter().zip(expected) {
            assert!((v - e).abs() < 1e-6, "{row:?}");
        }
    }

    /// wd-spec.md §1.7: lowpass(arange(16).reshape(4,4), stride 2), PyTorch-port parity.
    #[test]
    fn stride2_lowpass_is_centred_on_even_samples() {
        let map = SigmaMap { height: 4, width: 4, values: (0..16).map(f64::from).collect() };
        assert_eq!(map.lowpass_stride2().values, [0.9375, 2.5, 6.25, 10.0]);
    }

    #[test]
    fn levels_beyond_the_largest_sigma_are_skipped() {
        let levels = level_weights(&SigmaMap::constant(8, 8, 2.0));
        let used: Vec<bool> = levels.iter().map(Option::is_some).collect();
        // Levels 0 and 1 see ls = 2 everywhere (weight 0); level 2's map is 2 inside and
        // decays toward the border; level 3's map is at most 2, so it and all above weigh 0.
        assert_eq!(used, [false, false, true, false, false, false]);
    }
}

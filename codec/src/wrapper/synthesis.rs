//! The synthesis network f of the perceptual wrapper, evaluated in plain Rust: per pixel a
//! 1x1 convolution from the input channels (base RGB, noise, Plücker) to `width` channels,
//! ReLU, a 1x1 convolution to 3 channels, then two residual 3x3 convolutions 3 -> 3 with
//! replicate padding (`r = r + conv(pad(r))`, no activation: the output is a signed residual
//! R, and a ReLU would delete its negative half). The decoder shows clamp(I_base + R, 0, 1).
//!
//! Every output pixel is computed on its own in a fixed order of operations, so the result does
//! not depend on how rows are spread over threads.

use rayon::prelude::*;

use super::noise::NOISE_LEVELS;
use super::plucker::PLUCKER_CHANNELS;

/// Kernel taps of a residual convolution (3 x 3 x 3 x 3: out, in, ky, kx).
pub const RESIDUAL_TAPS: usize = 27 * 3;

/// Which inputs f sees and how wide it is (the `WRAP` section's configuration).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WrapperConfig {
    /// Channels of the hidden layer (W).
    pub width: usize,
    /// Feed the noise pyramid C_0..C_7.
    pub noise: bool,
    /// Feed the Plücker embeddings.
    pub plucker: bool,
    /// Seed of the noise pyramid.
    pub seed: u64,
}

impl WrapperConfig {
    /// Input channels: 3 (base RGB) + 8 (noise) + 6 (Plücker), less what is switched off.
    pub fn input_channels(&self) -> usize {
        3 + self.conditioning_channels()
    }

    /// The channels after the base RGB, in input order: noise levels, then Plücker.
    pub fn conditioning_channels(&self) -> usize {
        usize::from(self.noise) * NOISE_LEVELS + usize::from(self.plucker) * PLUCKER_CHANNELS
    }

    /// Number of parameters, in [`SynthesisWeights::values`] order.
    pub fn parameter_count(&self) -> usize {
        let (w, cin) = (self.width, self.input_channels());
        w * cin + w + 3 * w + 3 + 2 * (RESIDUAL_TAPS + 3)
    }
}

/// The parameters of f, as the decoder evaluates them.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthesisWeights {
    pub config: WrapperConfig,
    /// [width][input channels]
    pub hidden: Vec<f32>,
    /// [width]
    pub hidden_bias: Vec<f32>,
    /// [3][width]
    pub output: Vec<f32>,
    pub output_bias: [f32; 3],
    /// Two residual convolutions, [out][in][ky][kx].
    pub residual: [[f32; RESIDUAL_TAPS]; 2],
    pub residual_bias: [[f32; 3]; 2],
}

impl SynthesisWeights {
    /// Rebuilds the weights from the flat parameter list in stream order: hidden, hidden bias,
    /// output, output bias, residual 1, its bias, residual 2, its bias. Panics on a wrong length.
    pub fn from_values(config: WrapperConfig, values: &[f32]) -> Self {
        assert_eq!(values.len(), config.parameter_count(), "synthesis parameter count");
        let (w, cin) = (config.width, config.input_channels());
        let mut rest = values;
        let mut take = |n: usize| {
            let (head, tail) = rest.split_at(n);
            rest = tail;
            head.to_vec()
        };
        let hidden = take(w * cin);
        let hidden_bias = take(w);
        let output = take(3 * w);
        let output_bias = take(3).try_into().expect("3 values");
        let mut residual = [[0.0; RESIDUAL_TAPS]; 2];
        let mut residual_bias = [[0.0; 3]; 2];
        for (taps, bias) in residual.iter_mut().zip(&mut residual_bias) {
            taps.copy_from_slice(&take(RESIDUAL_TAPS));
            bias.copy_from_slice(&take(3));
        }
        Self { config, hidden, hidden_bias, output, output_bias, residual, residual_bias }
    }

    /// The flat parameter list in stream order (the inverse of [`Self::from_values`]).
    pub fn values(&self) -> Vec<f32> {
        let mut v = Vec::with_capacity(self.config.parameter_count());
        v.extend(&self.hidden);
        v.extend(&self.hidden_bias);
        v.extend(&self.output);
        v.extend(self.output_bias);
        for (taps, bias) in self.residual.iter().zip(&self.residual_bias) {
            v.extend(taps);
            v.extend(bias);
        }
        v
    }

    /// The residual R [H * W * 3, interleaved] for a base image `base` (interleaved RGB) and the
    /// pixel-interleaved `conditioning` ([`WrapperConfig::conditioning_channels`] per pixel).
    pub fn residual(&self, base: &[f32], conditioning: &[f32], width: usize, height: usize) -> Vec<f32> {
        let row_len = width * self.config.conditioning_channels();
        assert_eq!(conditioning.len(), row_len * height, "conditioning size");
        self.residual_by_rows(base, width, height, |y, row| {
            row.copy_from_slice(&conditioning[y * row_len..(y + 1) * row_len]);
        })
    }

    /// [`Self::residual`] with the conditioning produced one row at a time by
    /// `conditioning_row(y, row)`, so that it never has to exist for the whole image.
    pub fn residual_by_rows(
        &self,
        base: &[f32],
        width: usize,
        height: usize,
        conditioning_row: impl Fn(usize, &mut [f32]) + Sync,
    ) -> Vec<f32> {
        let k = self.config.conditioning_channels();
        assert_eq!(base.len(), width * height * 3, "base image size");
        let mut r = vec![0.0f32; width * height * 3];
        r.par_chunks_mut(width * 3).enumerate().for_each(|(y, row)| {
            let mut conditioning = vec![0.0f32; width * k];
            conditioning_row(y, &mut conditioning);
            let mut input = vec![0.0f32; 3 + k];
            let mut hidden = vec![0.0f32; self.config.width];
            for (x, out) in row.chunks_exact_mut(3).enumerate() {
                let p = y * width + x;
                input[..3].copy_from_slice(&base[p * 3..p * 3 + 3]);
                input[3..].copy_from_slice(&conditioning[x * k..(x + 1) * k]);
                for (j, h) in hidden.iter_mut().enumerate() {
                    *h =
                        dot(&self.hidden[j * input.len()..(j + 1) * input.len()], &input, self.hidden_bias[j]).max(0.0);
                }
                for (c, o) in out.iter_mut().enumerate() {
                    let w = self.config.width;
                    *o = dot(&self.output[c * w..(c + 1) * w], &hidden, self.output_bias[c]);
                }
            }
        });
        for (taps, bias) in self.residual.iter().zip(&self.residual_bias) {
            r = residual_conv(&r, taps, bias, width, height);
        }
        r
    }
}

/// `bias + Σ a_i b_i`, summed left to right.
fn dot(a: &[f32], b: &[f32], bias: f32) -> f32 {
    a.iter().zip(b).fold(bias, |acc, (x, y)| acc + x * y)
}

/// `r + bias + conv3x3(replicate_pad(r))` on an interleaved 3-channel image.
fn residual_conv(r: &[f32], taps: &[f32; RESIDUAL_TAPS], bias: &[f32; 3], width: usize, height: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; r.len()];
    out.par_chunks_mut(width * 3).enumerate().for_each(|(y, row)| {
        for (x, px) in row.chunks_exact_mut(3).enumerate() {
            for (o, value) in px.iter_mut().enumerate() {
                let mut acc = bias[o];
                for i in 0..3 {
                    for ky in 0..3 {
                        let sy = (y + ky).saturating_sub(1).min(height - 1);
                        for kx in 0..3 {
                            let sx = (x + kx).saturating_sub(1).min(width - 1);
                            acc += taps[((o * 3 + i) * 3 + ky) * 3 + kx] * r[(sy * width + sx) * 3 + i];
                        }
                    }
                }
                *value = r[(y * width + x) * 3 + o] + acc;
            }
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use pwgs_core::random::SplitMix64;

    fn random_weights(config: WrapperConfig, seed: u64) -> SynthesisWeights {
        let mut rng = SplitMix64(seed);
        let values: Vec<f32> = (0..config.parameter_count()).map(|_| rng.uniform(-0.5, 0.5)).collect();
        SynthesisWeights::from_values(config, &values)
    }

    #[test]
    fn values_round_trip_and_count_follows_the_inputs() {
        let config = WrapperConfig { width: 16, noise: true, plucker: true, seed: 3 };
        assert_eq!(config.input_channels(), 17);
        assert_eq!(config.parameter_count(), 17 * 16 + 16 + 48 + 3 + 2 * 84);
        let w = random_weights(config, 1);
        assert_eq!(SynthesisWeights::from_values(config, &w.values()), w);
        let bare = WrapperConfig { noise: false, plucker: false, ..config };
        assert_eq!(bare.input_channels(), 3);
    }

    /// A straightforward evaluation with explicit padding, in f64.
    fn reference(w: &SynthesisWeights, base: &[f32], cond: &[f32], width: usize, height: usize) -> Vec<f64> {
        let k = w.config.conditioning_channels();
        let cin = 3 + k;
        let mut r = vec![0.0f64; width * height * 3];
        for p in 0..width * height {
            let input: Vec<f64> =
                base[p * 3..p * 3 + 3].iter().chain(&cond[p * k..(p + 1) * k]).map(|&v| f64::from(v)).collect();
            let hidden: Vec<f64> = (0..w.config.width)
                .map(|j| {
                    let s: f64 = (0..cin).map(|c| f64::from(w.hidden[j * cin + c]) * input[c]).sum();
                    (s + f64::from(w.hidden_bias[j])).max(0.0)
                })
                .collect();
            for c in 0..3 {
                let s: f64 = (0..w.config.width).map(|j| f64::from(w.output[c * w.config.width + j]) * hidden[j]).sum();
                r[p * 3 + c] = s + f64::from(w.output_bias[c]);
            }
        }
        for (taps, bias) in w.residual.iter().zip(&w.residual_bias) {
            let at = |r: &[f64], x: isize, y: isize, c: usize| {
                let x = x.clamp(0, width as isize - 1) as usize;
                let y = y.clamp(0, height as isize - 1) as usize;
                r[(y * width + x) * 3 + c]
            };
            let mut next = r.clone();
            for y in 0..height as isize {
                for x in 0..width as isize {
                    for o in 0..3 {
                        let mut s = f64::from(bias[o]);
                        for i in 0..3 {
                            for ky in 0..3isize {
                                for kx in 0..3isize {
                                    let t = taps[((o * 3 + i) * 3 + ky as usize) * 3 + kx as usize];
                                    s += f64::from(t) * at(&r, x + kx - 1, y + ky - 1, i);
                                }
                            }
                        }
                        next[(y as usize * width + x as usize) * 3 + o] += s;
                    }
                }
            }
            r = next;
        }
        r
    }

    #[test]
    fn matches_a_plain_reference_and_threads_do_not_matter() {
        let config = WrapperConfig { width: 5, noise: true, plucker: false, seed: 0 };
        let w = random_weights(config, 9);
        let (width, height) = (7, 5);
        let mut rng = SplitMix64(4);
        let base: Vec<f32> = (0..width * height * 3).map(|_| rng.uniform(0.0, 1.0)).collect();
        let cond: Vec<f32> = (0..width * height * 8).map(|_| rng.uniform(-2.0, 2.0)).collect();
        let r = w.residual(&base, &cond, width, height);
        for (a, b) in r.iter().zip(reference(&w, &base, &cond, width, height)) {
            assert!((f64::from(*a) - b).abs() < 1e-5 * (1.0 + b.abs()), "{a} vs {b}");
        }
        let single = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        assert_eq!(single.install(|| w.residual(&base, &cond, width, height)), r);
    }

    #[test]
    fn zero_output_layers_give_zero_residual() {
        let config = WrapperConfig { width: 4, noise: false, plucker: true, seed: 0 };
        let mut w = random_weights(config, 2);
        w.output.fill(0.0);
        w.output_bias = [0.0; 3];
        w.residual_bias = [[0.0; 3]; 2];
        let base = vec![0.5; 4 * 3 * 3];
        let cond = vec![1.0; 4 * 3 * 6];
        assert!(w.residual(&base, &cond, 4, 3).iter().all(|&v| v == 0.0));
    }
}

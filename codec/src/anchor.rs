//! The anchor base (docs/architecture.md section 1.1; Scaffold-GS as HAC uses it): anchors with a feature,
//! offsets and scales, from which three small MLPs derive each view's Gaussians ("neural
//! Gaussians"). This module holds the decoded model and the derivation; training and coding
//! build on it.
//!
//! For a camera at c and an anchor at a with feature f, scaling s (6 values, log space),
//! offsets o_k and masks m_k (k < K):
//!
//! ```text
//! v = a - c,  d = |v|,  in = [f, v/d, d]
//! α_k = tanh(MLP_opacity(in)_k)            kept when α_k > 0 and m_k
//! c_k = sigmoid(MLP_color(in)_{3k..3k+3})
//! q_k = MLP_cov(in)_{7k..7k+7}
//! μ_k = a + o_k ⊙ exp(s[0..3]),  scale_k = exp(s[3..6]) ⊙ sigmoid(q_k[0..3]),  rotation_k = q_k[3..7]
//! ```
//!
//! Every MLP is Linear, ReLU, Linear, evaluated in f32 in a fixed order with the portable
//! `exp`, so the derived Gaussians are the same on every machine.

use crate::hashing::Hasher;
use crate::portable_math::{exp_f32, ln_f64};
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::{Gaussians, rgb_to_sh_dc};

/// A two-layer perceptron: `out = W2 · relu(W1 · in + b1) + b2`, weights row-major
/// ([output][input]).
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    pub inputs: usize,
    pub hidden: usize,
    pub outputs: usize,
    pub w1: Vec<f32>,
    pub b1: Vec<f32>,
    pub w2: Vec<f32>,
    pub b2: Vec<f32>,
}

impl Mlp {
    /// Whether the weight arrays have the sizes the shape implies.
    pub fn is_consistent(&self) -> bool {
        self.w1.len() == self.hidden * self.inputs
            && self.b1.len() == self.hidden
            && self.w2.len() == self.outputs * self.hidden
            && self.b2.len() == self.outputs
    }

    /// The MLP laid out for evaluation.
    pub fn evaluator(&self) -> MlpEvaluator {
        MlpEvaluator {
            first: PackedLayer::new(&self.w1, &self.b1, self.inputs),
            second: PackedLayer::new(&self.w2, &self.b2, self.hidden),
        }
    }

    fn hash_into(&self, h: &mut Hasher) {
        [self.inputs, self.hidden, self.outputs].iter().for_each(|&v| h.u64(v as u64));
        h.floats(self.w1.iter().chain(&self.b1).chain(&self.w2).chain(&self.b2));
    }
}

/// An [`Mlp`] laid out for evaluation: each layer's rows in groups of eight, the group's
/// weights of one input side by side, so that eight sums advance together (one vector multiply
/// and add per input) instead of each waiting on its previous addition. Each sum still starts
/// from its bias and takes its terms in index order: the result is that of the row-by-row sums,
/// bit for bit.
pub struct MlpEvaluator {
    first: PackedLayer,
    second: PackedLayer,
}

impl MlpEvaluator {
    /// The MLP at `input` into `out` (`hidden`, of the hidden width, is scratch space):
    /// `out = W2 · relu(W1 · input + b1) + b2`.
    pub fn forward(&self, input: &[f32], hidden: &mut [f32], out: &mut [f32]) {
        self.first.apply(input, hidden);
        hidden.iter_mut().for_each(|h| *h = h.max(0.0));
        self.second.apply(hidden, out);
    }
}

/// Rows evaluated together.
const LANES: usize = 8;

/// One layer `y = W x + b`: per group of [`LANES`] rows, for each input the group's weights
/// (rows past the last padded with 0), and the group's biases.
struct PackedLayer {
    inputs: usize,
    weights: Vec<[f32; LANES]>,
    biases: Vec<[f32; LANES]>,
}

impl PackedLayer {
    /// The layer of row-major `w` ([output][input]) and `b`.
    fn new(w: &[f32], b: &[f32], inputs: usize) -> Self {
        let groups = b.len().div_ceil(LANES);
        let lane = |g: usize, r: usize, value: &dyn Fn(usize) -> f32| match g * LANES + r {
            o if o < b.len() => value(o),
            _ => 0.0,
        };
        let weights = (0..groups)
            .flat_map(|g| (0..inputs).map(move |i| std::array::from_fn(|r| lane(g, r, &|o| w[o * inputs + i]))))
            .collect();
        let biases = (0..groups).map(|g| std::array::from_fn(|r| lane(g, r, &|o| b[o]))).collect();
        Self { inputs, weights, biases }
    }

    fn apply(&self, x: &[f32], y: &mut [f32]) {
        let groups = self.weights.chunks_exact(self.inputs.max(1)).zip(&self.biases);
        for ((weights, &bias), out) in groups.zip(y.chunks_mut(LANES)) {
            let mut sums = bias;
            for (w, &xi) in weights.iter().zip(x) {
                sums = std::array::from_fn(|r| sums[r] + w[r] * xi);
            }
            out.copy_from_slice(&sums[..out.len()]);
        }
    }
}

/// Decoded anchors and the MLPs that turn them into Gaussians.
#[derive(Debug, Clone, PartialEq)]
pub struct AnchorModel {
    /// Feature length F.
    pub feature_dim: usize,
    /// Offsets (neural Gaussians) per anchor, K.
    pub offsets_per_anchor: usize,
    pub positions: Vec<[f32; 3]>,
    /// N x F.
    pub features: Vec<f32>,
    /// Log scales: [0..3] scale the offsets, [3..6] are the Gaussians' base scale.
    pub scaling: Vec<[f32; 6]>,
    /// N x K x 3, in units of the offset scale.
    pub offsets: Vec<f32>,
    /// N x K: whether each neural Gaussian may be kept.
    pub masks: Vec<bool>,
    /// F + 4 inputs, K outputs.
    pub opacity: Mlp,
    /// F + 4 inputs, 3K outputs.
    pub color: Mlp,
    /// F + 4 inputs, 7K outputs.
    pub covariance: Mlp,
}

impl AnchorModel {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Whether every array and MLP has the size the anchor count, F and K imply.
    pub fn is_consistent(&self) -> bool {
        let (n, f, k) = (self.len(), self.feature_dim, self.offsets_per_anchor);
        let mlp = |m: &Mlp, outputs: usize| m.is_consistent() && m.inputs == f + 4 && m.outputs == outputs;
        self.features.len() == n * f
            && self.scaling.len() == n
            && self.offsets.len() == n * k * 3
            && self.masks.len() == n * k
            && mlp(&self.opacity, k)
            && mlp(&self.color, 3 * k)
            && mlp(&self.covariance, 7 * k)
    }

    /// SHA-256 of the anchors and MLPs in a canonical layout (sizes, then every array as
    /// little-endian binary32, masks as bytes): equal hashes mean the same model.
    pub fn hash(&self) -> String {
        let mut h = Hasher::default();
        [self.len(), self.feature_dim, self.offsets_per_anchor].iter().for_each(|&v| h.u64(v as u64));
        let floats = self.positions.iter().flatten().chain(&self.features).chain(self.scaling.iter().flatten());
        h.floats(floats.chain(&self.offsets));
        h.bytes(&self.masks.iter().map(|&m| u8::from(m)).collect::<Vec<_>>());
        for mlp in [&self.opacity, &self.color, &self.covariance] {
            mlp.hash_into(&mut h);
        }
        h.hex()
    }

    /// The Gaussians `camera` sees: for each anchor, its kept neural Gaussians (degree-0
    /// colors), in anchor and offset order.
    pub fn gaussians_for(&self, camera: &Camera) -> Gaussians {
        let mut out = Gaussians::with_degree(0);
        self.visit_neural_gaussians(camera, |_, g| {
            out.push(g.mean, g.log_scale, g.rotation, g.opacity_logit, &g.rgb.map(rgb_to_sh_dc))
        });
        out
    }

    /// Calls `visit` with `(anchor * K + offset, Gaussian)` for every neural Gaussian `camera`
    /// keeps, in anchor and offset order.
    pub fn visit_neural_gaussians(&self, camera: &Camera, mut visit: impl FnMut(usize, NeuralGaussian)) {
        let (f, k) = (self.feature_dim, self.offsets_per_anchor);
        let center = camera.center().to_array();
        let mut input = vec![0.0f32; f + 4];
        let mut hidden = vec![0.0f32; self.opacity.hidden.max(self.color.hidden).max(self.covariance.hidden)];
        let (mut alpha, mut color, mut cov) = (vec![0.0f32; k], vec![0.0f32; 3 * k], vec![0.0f32; 7 * k]);
        let [opacity, color_net, covariance] = [&self.opacity, &self.color, &self.covariance].map(Mlp::evaluator);
        for (i, a) in self.positions.iter().enumerate() {
            let v = [a[0] - center[0], a[1] - center[1], a[2] - center[2]];
            let d = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if d == 0.0 {
                continue; // the camera sits on the anchor: no view direction
            }
            input[..f].copy_from_slice(&self.features[i * f..(i + 1) * f]);
            input[f..].copy_from_slice(&[v[0] / d, v[1] / d, v[2] / d, d]);
            opacity.forward(&input, &mut hidden[..self.opacity.hidden], &mut alpha);
            let masks = &self.masks[i * k..(i + 1) * k];
            if !alpha.iter().zip(masks).any(|(&x, &m)| m && x > 0.0) {
                continue;
            }
            color_net.forward(&input, &mut hidden[..self.color.hidden], &mut color);
            covariance.forward(&input, &mut hidden[..self.covariance.hidden], &mut cov);
            let s = &self.scaling[i];
            let offset_scale = [exp_f32(s[0]), exp_f32(s[1]), exp_f32(s[2])];
            for j in 0..k {
                // tanh(x) > 0 exactly when x > 0.
                if !masks[j] || alpha[j] <= 0.0 {
                    continue;
                }
                let o = &self.offsets[(i * k + j) * 3..][..3];
                let q = &cov[7 * j..7 * j + 7];
                visit(
                    i * k + j,
                    NeuralGaussian {
                        mean: [0, 1, 2].map(|c| a[c] + o[c] * offset_scale[c]),
                        // log(exp(s) * sigmoid(q)) = s - log(1 + exp(-q)).
                        log_scale: [0, 1, 2].map(|c| s[3 + c] - ln_f64(1.0 + f64::from(exp_f32(-q[c]))) as f32),
                        rotation: [q[3], q[4], q[5], q[6]],
                        opacity_logit: opacity_logit_of_tanh(alpha[j]),
                        rgb: [0, 1, 2].map(|c| sigmoid(color[3 * j + c])),
                    },
                );
            }
        }
    }
}

/// One neural Gaussian as a view derives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeuralGaussian {
    pub mean: [f32; 3],
    pub log_scale: [f32; 3],
    /// Not normalized.
    pub rotation: [f32; 4],
    pub opacity_logit: f32,
    /// View-dependent color in [0, 1].
    pub rgb: [f32; 3],
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + exp_f32(-x))
}

/// The logit of tanh(x) for x > 0: with t = tanh(x) = (1 - e) / (1 + e), e = exp(-2x),
/// t / (1 - t) = (1 - e) / (2e), computed without forming t, so that small and large x keep
/// their precision; the rasterizer's sigmoid turns it back into t.
fn opacity_logit_of_tanh(x: f32) -> f32 {
    // Beyond x = 43.6, e underflows; its floor keeps the logit finite (about 87).
    let e = f64::from(exp_f32(-2.0 * x)).max(1e-38);
    ln_f64((1.0 - e) / (2.0 * e)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random_scene::random_anchor_model as model;
    use pwgs_core::random::{SplitMix64, axis_camera};

    #[test]
    fn an_mlp_is_linear_relu_linear() {
        // in = [1, 2]; hidden = relu([1*1 + 2*(-1) + 0.5, 1*2 + 2*1 - 1]) = relu([-0.5, 3]) = [0, 3];
        // out = [0*4 + 3*(-2) + 1] = [-5].
        let m = Mlp {
            inputs: 2,
            hidden: 2,
            outputs: 1,
            w1: vec![1.0, -1.0, 2.0, 1.0],
            b1: vec![0.5, -1.0],
            w2: vec![4.0, -2.0],
            b2: vec![1.0],
        };
        assert!(m.is_consistent());
        let (mut hidden, mut out) = ([0.0; 2], [0.0; 1]);
        m.evaluator().forward(&[1.0, 2.0], &mut hidden, &mut out);
        assert_eq!((hidden, out), ([0.0, 3.0], [-5.0]));
    }

    #[test]
    fn the_evaluator_sums_each_row_in_order_bit_for_bit() {
        let mut rng = SplitMix64(11);
        for (inputs, hidden, outputs) in [(1, 1, 1), (5, 8, 3), (13, 17, 16), (3, 15, 530), (9, 7, 9)] {
            let mut draw = |n: usize| (0..n).map(|_| rng.uniform(-3.0, 3.0)).collect::<Vec<f32>>();
            let (w1, b1, w2, b2) = (draw(hidden * inputs), draw(hidden), draw(outputs * hidden), draw(outputs));
            let input = draw(inputs);
            let m = Mlp { inputs, hidden, outputs, w1, b1, w2, b2 };
            let row_by_row = |w: &[f32], b: &[f32], x: &[f32]| -> Vec<f32> {
                w.chunks_exact(x.len())
                    .zip(b)
                    .map(|(row, b)| row.iter().zip(x).fold(*b, |s, (w, x)| s + w * x))
                    .collect()
            };
            let h: Vec<f32> = row_by_row(&m.w1, &m.b1, &input).iter().map(|h| h.max(0.0)).collect();
            let expected = row_by_row(&m.w2, &m.b2, &h);
            let (mut hidden_out, mut out) = (vec![0.0; hidden], vec![0.0; outputs]);
            m.evaluator().forward(&input, &mut hidden_out, &mut out);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&hidden_out), bits(&h), "{inputs} {hidden} {outputs}");
            assert_eq!(bits(&out), bits(&expected), "{inputs} {hidden} {outputs}");
        }
    }

    #[test]
    fn neural_gaussians_follow_the_formulas() {
        let mut rng = SplitMix64(3);
        let m = model(&mut rng, 30, 5, 4);
        assert!(m.is_consistent());
        let camera = axis_camera(32, 24, 30.0, 30.0, 16.0, 12.0);
        let g = m.gaussians_for(&camera);
        assert!(g.is_consistent() && !g.is_empty());
        assert!(g.len() < 30 * 4, "masked and non-positive opacities are dropped");

        // Recompute every kept Gaussian from the formulas, the view input and the activations in
        // f64 (so agreement is to f32 precision, not bit for bit).
        let c = camera.center().to_array().map(f64::from);
        let mut next = 0;
        for (i, a) in m.positions.iter().enumerate() {
            let v: Vec<f64> = (0..3).map(|j| f64::from(a[j]) - c[j]).collect();
            let d = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let mut input: Vec<f32> = m.features[i * 5..(i + 1) * 5].to_vec();
            input.extend([v[0] / d, v[1] / d, v[2] / d, d].map(|x| x as f32));
            let run = |mlp: &Mlp| {
                let mut out = vec![0.0; mlp.outputs];
                mlp.evaluator().forward(&input, &mut vec![0.0; mlp.hidden], &mut out);
                out
            };
            let (alpha, color, cov) = (run(&m.opacity), run(&m.color), run(&m.covariance));
            for j in 0..4 {
                if !m.masks[i * 4 + j] || alpha[j] <= 0.0 {
                    continue;
                }
                let close = |a: f32, b: f64, what: &str| {
                    assert!(
                        (f64::from(a) - b).abs() <= 1e-5 * (1.0 + b.abs()),
                        "anchor {i} offset {j} {what}: {a} vs {b}"
                    )
                };
                let s = m.scaling[i].map(f64::from);
                for x in 0..3 {
                    let mean = f64::from(a[x]) + f64::from(m.offsets[(i * 4 + j) * 3 + x]) * s[x].exp();
                    close(g.means[next][x], mean, "mean");
                    let scale = s[3 + x].exp() / (1.0 + (-f64::from(cov[7 * j + x])).exp());
                    close(g.log_scales[next][x], scale.ln(), "log scale");
                    let rgb = 1.0 / (1.0 + (-f64::from(color[3 * j + x])).exp());
                    close(g.sh[next * 3 + x] * pwgs_core::gaussians::SH_C0 + 0.5, rgb, "color");
                }
                let t = f64::from(alpha[j]).tanh();
                close(g.opacity_logits[next], (t / (1.0 - t)).ln(), "opacity logit");
                for x in 0..4 {
                    close(g.rotations[next][x], f64::from(cov[7 * j + 3 + x]), "rotation");
                }
                next += 1;
            }
        }
        assert_eq!(next, g.len());
    }

    #[test]
    fn the_hash_covers_every_array() {
        let mut rng = SplitMix64(8);
        let m = model(&mut rng, 6, 3, 2);
        let base = m.hash();
        let mut changed = Vec::new();
        let mut edit = |f: &dyn Fn(&mut AnchorModel)| {
            let mut other = m.clone();
            f(&mut other);
            changed.push(other.hash() != base);
        };
        edit(&|m| m.positions[5][2] += 1.0);
        edit(&|m| m.features[17] += 1.0);
        edit(&|m| m.scaling[0][5] += 1.0);
        edit(&|m| m.offsets[35] += 1.0);
        edit(&|m| m.masks[11] = !m.masks[11]);
        edit(&|m| m.opacity.b2[1] += 1.0);
        edit(&|m| m.color.w1[0] += 1.0);
        edit(&|m| m.covariance.w2[3] += 1.0);
        assert!(changed.iter().all(|&c| c), "{changed:?}");
        assert_eq!(m.clone().hash(), base);
    }
}

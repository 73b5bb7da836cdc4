//! Adam on the parameter tensors, with a learning rate per parameter, as 3DGS uses it. The
//! moments are tensors shaped like the parameters so that densification can carry them along.

use burn::tensor::Tensor;

use super::params::SplatParams;

const BETA1: f32 = 0.9;
const BETA2: f32 = 0.999;
/// 3DGS's epsilon: gradients of individual Gaussians are tiny (the loss is a mean over pixels).
const EPSILON: f32 = 1e-15;

/// First and second moments, shaped like the parameters.
#[derive(Debug, Clone)]
pub struct Moments {
    pub first: SplatParams,
    pub second: SplatParams,
}

/// Learning rates for one step, per parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LearningRates {
    pub means: f32,
    pub log_scales: f32,
    pub rotations: f32,
    pub opacity_logits: f32,
    pub sh_dc: f32,
    pub sh_rest: f32,
}

/// Updates the moments with `grad` and returns the bias-corrected Adam direction.
pub fn direction<const D: usize>(
    grad: Tensor<D>,
    first: &mut Tensor<D>,
    second: &mut Tensor<D>,
    step: u32,
) -> Tensor<D> {
    *first = first.clone() * BETA1 + grad.clone() * (1.0 - BETA1);
    *second = second.clone() * BETA2 + grad.clone() * grad * (1.0 - BETA2);
    let first_scale = 1.0 / (1.0 - BETA1.powi(step as i32));
    let second_scale = 1.0 / (1.0 - BETA2.powi(step as i32));
    (first.clone() * first_scale) / ((second.clone() * second_scale).sqrt() + EPSILON)
}

impl Moments {
    pub fn zeros_like(p: &SplatParams) -> Self {
        let zeros = SplatParams {
            means: p.means.zeros_like(),
            log_scales: p.log_scales.zeros_like(),
            rotations: p.rotations.zeros_like(),
            opacity_logits: p.opacity_logits.zeros_like(),
            sh: p.sh.zeros_like(),
        };
        Self { first: zeros.clone(), second: zeros }
    }

    /// One Adam step (`step` counts from 1) of every parameter.
    pub fn step(&mut self, p: SplatParams, g: SplatParams, lr: &LearningRates, step: u32) -> SplatParams {
        let (m, v) = (&mut self.first, &mut self.second);
        let [_, k, _] = p.sh.dims();
        // SH: the DC band learns faster than the view-dependent bands.
        let sh_lr = Tensor::<3>::cat(
            vec![
                Tensor::full([1, 1, 3], lr.sh_dc, &p.sh.device()),
                Tensor::full([1, k - 1, 3], lr.sh_rest, &p.sh.device()),
            ],
            1,
        );
        SplatParams {
            means: p.means - direction(g.means, &mut m.means, &mut v.means, step) * lr.means,
            log_scales: p.log_scales
                - direction(g.log_scales, &mut m.log_scales, &mut v.log_scales, step) * lr.log_scales,
            rotations: p.rotations - direction(g.rotations, &mut m.rotations, &mut v.rotations, step) * lr.rotations,
            opacity_logits: p.opacity_logits
                - direction(g.opacity_logits, &mut m.opacity_logits, &mut v.opacity_logits, step) * lr.opacity_logits,
            sh: p.sh - direction(g.sh, &mut m.sh, &mut v.sh, step) * sh_lr,
        }
    }
}

/// Adam on a plain slice of parameters, for the refits that run the rasterizer's gradients
/// without Burn ([`crate::plain::shape_refit`]): the same moments and bias correction as [`direction`].
#[derive(Debug, Clone)]
pub struct SliceAdam {
    first: Vec<f32>,
    second: Vec<f32>,
}

impl SliceAdam {
    pub fn new(len: usize) -> Self {
        Self { first: vec![0.0; len], second: vec![0.0; len] }
    }

    /// One step (`step` counts from 1) of `params` along `grads`, `rate(i)` the learning rate
    /// of parameter `i`. Unlike [`direction`], the denominator is at least the slice's root
    /// mean square gradient: Adam moves every parameter by about its rate whatever its
    /// gradient's size, so parameters that a refit's few views barely see would drift by
    /// noise; here a parameter with a smaller gradient than is typical moves proportionally less.
    pub fn step(&mut self, params: &mut [f32], grads: &[f32], rate: impl Fn(usize) -> f32, step: u32) {
        let first_scale = 1.0 / (1.0 - BETA1.powi(step as i32));
        let second_scale = 1.0 / (1.0 - BETA2.powi(step as i32));
        let mut total = 0.0f64;
        for ((g, m), v) in grads.iter().zip(&mut self.first).zip(&mut self.second) {
            *m = BETA1 * *m + (1.0 - BETA1) * g;
            *v = BETA2 * *v + (1.0 - BETA2) * g * g;
            total += f64::from(*v);
        }
        let floor = ((total / self.second.len().max(1) as f64) as f32 * second_scale).sqrt() + EPSILON;
        let moments = self.first.iter().zip(&self.second);
        for (i, (p, (m, v))) in params.iter_mut().zip(moments).enumerate() {
            *p -= rate(i) * (m * first_scale) / (v * second_scale).sqrt().max(floor);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::SliceAdam;

    #[test]
    fn a_parameter_with_a_smaller_gradient_than_is_typical_moves_proportionally_less() {
        let mut adam = SliceAdam::new(2);
        let mut params = [0.0f32, 0.0];
        adam.step(&mut params, &[1.0, 0.01], |_| 0.1, 1);
        // After one step the bias-corrected moments are g and g^2: the floor is the root mean
        // square gradient, sqrt((1 + 1e-4) / 2).
        assert!((params[0] + 0.1).abs() < 1e-6, "{params:?}");
        let floor = (0.5f32 * (1.0 + 1e-4)).sqrt();
        assert!((params[1] + 0.1 * 0.01 / floor).abs() < 1e-6, "{params:?}");
    }
}

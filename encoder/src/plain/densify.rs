//! Adaptive density control of 3DGS, on host rows: Gaussians whose projected centers keep
//! receiving large gradients are cloned (small ones) or split in two (large ones); nearly
//! transparent or oversized ones are pruned. New Gaussians start with zero optimizer moments,
//! as in 3DGS.

use burn::tensor::{Device, Tensor};
use glam::DVec3;
use pwgs_core::gaussians::opacity_to_logit;
use pwgs_core::random::SplitMix64;
use pwgs_render::raster::project::{rotation_matrix, sigmoid};

use crate::train::params::{PARAM_COUNT, Rows, tensor_values};

/// Thresholds of the density control (3DGS defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DensifyConfig {
    /// Mean screen-space gradient norm (in normalized device coordinates) that triggers
    /// densification.
    pub grad_threshold: f32,
    /// Gaussians larger than this fraction of the scene extent are split, smaller ones cloned.
    pub percent_dense: f32,
    /// Gaussians less opaque than this are pruned.
    pub min_opacity: f32,
    /// Once opacity resets have begun, Gaussians larger than this fraction of the extent are
    /// pruned.
    pub max_world_scale: f32,
    /// Densification never grows the set beyond this.
    pub max_gaussians: usize,
}

impl Default for DensifyConfig {
    fn default() -> Self {
        Self {
            grad_threshold: 2e-4,
            percent_dense: 0.01,
            min_opacity: 0.005,
            max_world_scale: 0.1,
            max_gaussians: 1_000_000,
        }
    }
}

/// Per-Gaussian screen-space gradient statistics since the last densification.
#[derive(Debug, Clone, PartialEq)]
pub struct GradStats {
    pub sum: Vec<f32>,
    pub views: Vec<u32>,
}

impl GradStats {
    pub fn mean(&self, i: usize) -> f32 {
        if self.views[i] == 0 { 0.0 } else { self.sum[i] / self.views[i] as f32 }
    }
}

/// [`GradStats`] accumulated on the training device, so that a step reads nothing back; read at
/// densification time.
#[derive(Debug, Clone)]
pub struct DeviceGradStats {
    sum: Tensor<1>,
    views: Tensor<1>,
}

impl DeviceGradStats {
    pub fn new(n: usize, device: &Device) -> Self {
        Self { sum: Tensor::zeros([n], device), views: Tensor::zeros([n], device) }
    }

    /// Adds one view's gradient norms; a Gaussian counts as seen when its norm is positive
    /// (a NaN norm is not seen).
    pub fn add(&mut self, norms: Tensor<1>) {
        let seen = norms.clone().greater_elem(0.0);
        self.sum = self.sum.clone() + norms.mask_fill(seen.clone().bool_not(), 0.0);
        self.views = self.views.clone() + seen.float();
    }

    pub fn to_host(&self) -> GradStats {
        let views = tensor_values(self.views.clone()).into_iter().map(|v| v as u32).collect();
        GradStats { sum: tensor_values(self.sum.clone()), views }
    }
}

/// What one densification step did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DensifyReport {
    pub cloned: usize,
    pub split: usize,
    pub pruned: usize,
}

/// Parameters and both Adam moments, as host rows.
pub struct HostState {
    pub params: [Rows; PARAM_COUNT],
    pub first: [Rows; PARAM_COUNT],
    pub second: [Rows; PARAM_COUNT],
}

/// A row of the new state: copied from `source`, with optional new mean and log-scale, and with
/// zero moments when `fresh`.
struct NewRow {
    source: usize,
    mean: Option<[f32; 3]>,
    log_scale: Option<[f32; 3]>,
    fresh: bool,
}

fn standard_normal(rng: &mut SplitMix64) -> f64 {
    // Box-Muller; u1 in (0, 1] keeps the logarithm finite.
    let u1 = 1.0 - rng.uniform(0.0, 1.0) as f64;
    let u2 = rng.uniform(0.0, 1.0) as f64;
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Clones and splits the Gaussians with large gradients, then prunes. `extent` is the scene
/// extent (the normalization scale); `prune_large` enables the world-size pruning.
pub fn densify(
    state: &HostState,
    stats: &GradStats,
    config: &DensifyConfig,
    extent: f32,
    prune_large: bool,
    rng: &mut SplitMix64,
) -> (HostState, DensifyReport) {
    let [means, log_scales, rotations, opacity, _] = &state.params;
    let n = means.len();
    let max_scale = |i: usize| log_scales.row(i).iter().fold(f32::MIN, |m, &v| m.max(v)).exp();
    let mut candidates: Vec<usize> = (0..n).filter(|&i| stats.mean(i) >= config.grad_threshold).collect();
    // Under the cap, the strongest gradients win; ties go to the lower index (deterministic).
    candidates.sort_by(|&a, &b| stats.mean(b).total_cmp(&stats.mean(a)).then(a.cmp(&b)));
    candidates.truncate(config.max_gaussians.saturating_sub(n));
    let mut split = vec![false; n];
    let mut rows: Vec<NewRow> = Vec::with_capacity(n + candidates.len() * 2);
    let mut report = DensifyReport::default();
    for &i in &candidates {
        if max_scale(i) <= config.percent_dense * extent {
            rows.push(NewRow { source: i, mean: None, log_scale: None, fresh: true });
            report.cloned += 1;
        } else {
            split[i] = true;
            report.split += 1;
        }
    }
    let mut kept: Vec<NewRow> = (0..n)
        .filter(|&i| !split[i])
        .map(|i| NewRow { source: i, mean: None, log_scale: None, fresh: false })
        .collect();
    for (i, _) in split.iter().enumerate().filter(|(_, s)| **s) {
        // Two children sampled from the parent's own distribution, each 1.6x smaller.
        let q = rotations.row(i);
        let norm = q.iter().map(|v| (*v as f64).powi(2)).sum::<f64>().sqrt().max(1e-12);
        let r = rotation_matrix([q[0], q[1], q[2], q[3]].map(|v| v as f64 / norm));
        let scale = DVec3::from(<[f32; 3]>::try_from(log_scales.row(i)).expect("3 values").map(|v| (v as f64).exp()));
        let center = DVec3::from(<[f32; 3]>::try_from(means.row(i)).expect("3 values").map(f64::from));
        let child_scale = log_scales.row(i).iter().map(|v| v - 1.6f32.ln()).collect::<Vec<_>>();
        for _ in 0..2 {
            let local = DVec3::new(standard_normal(rng), standard_normal(rng), standard_normal(rng)) * scale;
            let mean = (center + r * local).as_vec3().to_array();
            kept.push(NewRow {
                source: i,
                mean: Some(mean),
                log_scale: Some([child_scale[0], child_scale[1], child_scale[2]]),
                fresh: true,
            });
        }
    }
    kept.extend(rows);
    let before = kept.len();
    kept.retain(|row| {
        let o = sigmoid(opacity.row(row.source)[0] as f64) as f32;
        let s =
            row.log_scale.map_or_else(|| max_scale(row.source), |l| l.iter().fold(f32::MIN, |m, &v| m.max(v)).exp());
        o >= config.min_opacity && !(prune_large && s > config.max_world_scale * extent)
    });
    report.pruned = before - kept.len();
    (build(state, &kept), report)
}

fn build(state: &HostState, rows: &[NewRow]) -> HostState {
    let gather = |src: &[Rows; PARAM_COUNT], zero_fresh: bool, overrides: bool| -> [Rows; PARAM_COUNT] {
        std::array::from_fn(|p| {
            let width = src[p].width;
            let mut out = Rows { data: Vec::with_capacity(rows.len() * width), width };
            for row in rows {
                if zero_fresh && row.fresh {
                    out.data.extend(std::iter::repeat_n(0.0, width));
                    continue;
                }
                let values = match (overrides, p, row.mean, row.log_scale) {
                    (true, 0, Some(m), _) => m.to_vec(),
                    (true, 1, _, Some(s)) => s.to_vec(),
                    _ => src[p].row(row.source).to_vec(),
                };
                out.data.extend(values);
            }
            out
        })
    };
    HostState {
        params: gather(&state.params, false, true),
        first: gather(&state.first, true, false),
        second: gather(&state.second, true, false),
    }
}

/// Opacity reset of 3DGS: every opacity above `ceiling` is lowered to it, and the opacity
/// moments restart from zero, so Gaussians that matter regain opacity and the rest get pruned.
pub fn reset_opacity(state: &mut HostState, ceiling: f32) {
    let limit = opacity_to_logit(ceiling);
    for v in &mut state.params[3].data {
        *v = v.min(limit);
    }
    state.first[3].data.fill(0.0);
    state.second[3].data.fill(0.0);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::params::ROW_WIDTHS;

    fn state(log_scale: [f32; 2], opacity: [f32; 2]) -> HostState {
        let mut params: [Rows; PARAM_COUNT] = std::array::from_fn(|p| Rows::zeros(2, ROW_WIDTHS[p]));
        for i in 0..2 {
            params[1].row_mut(i).fill(log_scale[i]);
            params[2].row_mut(i)[0] = 1.0;
            params[3].row_mut(i)[0] = opacity_to_logit(opacity[i]);
        }
        params[0].row_mut(1).copy_from_slice(&[1.0, 2.0, 3.0]);
        let ones: [Rows; PARAM_COUNT] =
            std::array::from_fn(|p| Rows { data: vec![1.0; 2 * ROW_WIDTHS[p]], width: ROW_WIDTHS[p] });
        HostState { params, first: ones.clone(), second: ones }
    }

    #[test]
    fn small_gaussians_clone_large_ones_split() {
        // Gaussian 0 is small (scale 0.001), Gaussian 1 large (scale 1) for extent 1.
        let s = state([(0.001f32).ln(), 0.0], [0.5, 0.5]);
        let stats = GradStats { sum: vec![1.0, 1.0], views: vec![1, 1] };
        let (out, report) = densify(&s, &stats, &DensifyConfig::default(), 1.0, false, &mut SplitMix64(1));
        assert_eq!(report, DensifyReport { cloned: 1, split: 1, pruned: 0 });
        // Kept: 0; split children of 1 (two); clone of 0.
        assert_eq!(out.params[0].len(), 4);
        assert_eq!(out.first[0].row(0), &[1.0; 3], "kept Gaussians keep their moments");
        assert!(out.first[0].row(1).iter().chain(out.first[0].row(3)).all(|&v| v == 0.0), "new ones start at zero");
        let child = out.params[1].row(1)[0];
        assert!((child - (0.0 - 1.6f32.ln())).abs() < 1e-6);
        let offset: f32 = out.params[0].row(1).iter().zip([1.0, 2.0, 3.0]).map(|(a, b)| (a - b).abs()).sum();
        assert!(offset > 0.0 && offset < 10.0, "children are sampled around the parent");
    }

    #[test]
    fn cap_prefers_strongest_gradients_and_prunes_transparent() {
        let s = state([(0.001f32).ln(); 2], [0.5, 0.001]);
        let stats = GradStats { sum: vec![1.0, 2.0], views: vec![1, 1] };
        let config = DensifyConfig { max_gaussians: 3, ..Default::default() };
        let (out, report) = densify(&s, &stats, &config, 1.0, false, &mut SplitMix64(1));
        // Only one clone fits under the cap: Gaussian 1 (larger gradient); then both copies of
        // the transparent Gaussian 1 are pruned.
        assert_eq!(report, DensifyReport { cloned: 1, split: 0, pruned: 2 });
        assert_eq!(out.params[0].len(), 1);
    }

    #[test]
    fn opacity_reset_caps_opacity_and_clears_its_moments() {
        let mut s = state([0.0; 2], [0.9, 0.005]);
        reset_opacity(&mut s, 0.01);
        assert!((sigmoid(s.params[3].data[0] as f64) - 0.01).abs() < 1e-6);
        assert!((sigmoid(s.params[3].data[1] as f64) - 0.005).abs() < 1e-6);
        assert!(s.first[3].data.iter().all(|&v| v == 0.0));
    }
}

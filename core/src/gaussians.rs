//! Plain 3D Gaussians in the parameterization 3DGS trains and the INRIA PLY stores: mean,
//! log-scale, unnormalized rotation quaternion (w, x, y, z), opacity logit and real spherical
//! harmonics coefficients per color channel.

/// Most Gaussians a scene may hold in pwgs: what a stream may declare (SPEC.md section 9) and
/// an imported file may hold, a bound on what a reader allocates.
pub const MAX_GAUSSIANS: u32 = 1 << 24;

/// Number of SH coefficients per channel for a degree.
pub const fn sh_coeff_count(degree: u32) -> usize {
    ((degree + 1) * (degree + 1)) as usize
}

/// SH band (degree) of coefficient index `k` within a channel: `floor(sqrt(k))`, 0 for the DC
/// term.
pub fn sh_band(k: usize) -> usize {
    let mut band = 0;
    while (band + 1) * (band + 1) <= k {
        band += 1;
    }
    band
}

/// Highest SH degree the project supports (the 3DGS standard).
pub const MAX_SH_DEGREE: u32 = 3;

/// A set of Gaussians, stored as structure of arrays.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Gaussians {
    pub means: Vec<[f32; 3]>,
    pub log_scales: Vec<[f32; 3]>,
    /// Quaternions (w, x, y, z); not necessarily normalized.
    pub rotations: Vec<[f32; 4]>,
    pub opacity_logits: Vec<f32>,
    pub sh_degree: u32,
    /// `len() * sh_coeff_count(sh_degree) * 3` values, laid out [gaussian][coefficient][rgb].
    pub sh: Vec<f32>,
}

impl Gaussians {
    /// An empty set with the given SH degree.
    pub fn with_degree(sh_degree: u32) -> Self {
        Self { sh_degree, ..Self::default() }
    }

    pub fn len(&self) -> usize {
        self.means.len()
    }

    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// Coefficients per channel.
    pub fn coeffs_per_channel(&self) -> usize {
        sh_coeff_count(self.sh_degree)
    }

    /// The SH coefficients of Gaussian `i`, [coefficient][rgb].
    pub fn sh_of(&self, i: usize) -> &[f32] {
        let n = self.coeffs_per_channel() * 3;
        &self.sh[i * n..(i + 1) * n]
    }

    /// Appends one Gaussian; `sh` holds `coeffs_per_channel() * 3` values.
    pub fn push(&mut self, mean: [f32; 3], log_scale: [f32; 3], rotation: [f32; 4], opacity_logit: f32, sh: &[f32]) {
        assert_eq!(sh.len(), self.coeffs_per_channel() * 3, "SH length does not match the degree");
        self.means.push(mean);
        self.log_scales.push(log_scale);
        self.rotations.push(rotation);
        self.opacity_logits.push(opacity_logit);
        self.sh.extend_from_slice(sh);
    }

    /// Checks that every array has the length the Gaussian count implies.
    pub fn is_consistent(&self) -> bool {
        let n = self.len();
        self.log_scales.len() == n
            && self.rotations.len() == n
            && self.opacity_logits.len() == n
            && self.sh.len() == n * self.coeffs_per_channel() * 3
            && self.sh_degree <= MAX_SH_DEGREE
    }
}

/// The degree-0 SH basis constant: color = SH_C0 * dc + 0.5.
pub const SH_C0: f32 = 0.282_094_8;

/// DC coefficient that renders a given color (inverse of `SH_C0 * dc + 0.5`).
pub fn rgb_to_sh_dc(rgb: f32) -> f32 {
    (rgb - 0.5) / SH_C0
}

/// Opacity logit of an opacity in (0, 1).
pub fn opacity_to_logit(opacity: f32) -> f32 {
    (opacity / (1.0 - opacity)).ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sh_band_is_the_floor_of_the_square_root() {
        let bands: Vec<usize> = (0..16).map(sh_band).collect();
        assert_eq!(bands, [0, 1, 1, 1, 2, 2, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3]);
    }
}

//! The deterministic random numbers of pwgs: SplitMix64, whose output function also drives the
//! wrapper's normative noise (SPEC.md section 11.1), and random Gaussian scenes for tests and
//! benchmarks, identical on every machine and every run.
#![cfg_attr(not(test), deny(clippy::disallowed_methods))] // the determinism rule: no platform math (clippy.toml)

use glam::{Mat3, Vec3};

use crate::camera::{Camera, Intrinsics};
use crate::gaussians::{Gaussians, sh_coeff_count};

/// The golden-ratio increment of SplitMix64.
pub const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// The SplitMix64 output function: a bijective 64-bit mixer.
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The n-th output (from 0) of SplitMix64 started at `seed`: `mix64(seed + (n + 1) * GOLDEN)`.
pub fn splitmix64_at(seed: u64, n: u64) -> u64 {
    mix64(seed.wrapping_add(n.wrapping_add(1).wrapping_mul(GOLDEN)))
}

/// splitmix64: tiny, fast, deterministic on every platform.
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(GOLDEN);
        mix64(self.0)
    }

    /// Shuffles `items` in place (Fisher-Yates, from the end).
    pub fn shuffle<T>(&mut self, items: &mut [T]) {
        for i in (1..items.len()).rev() {
            let j = (self.next_u64() % (i as u64 + 1)) as usize;
            items.swap(i, j);
        }
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        let u = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * u
    }
}

/// A camera at the origin looking down +z (OpenCV axes) with the given intrinsics.
pub fn axis_camera(width: u32, height: u32, fx: f32, fy: f32, cx: f32, cy: f32) -> Camera {
    Camera::new(Intrinsics { width, height, fx, fy, cx, cy }, Mat3::IDENTITY, Vec3::ZERO).expect("valid intrinsics")
}

/// `n` random Gaussians in the view of [`axis_camera`] (z in [2, 6], within about +/-25
/// degrees of the axis): anisotropic, rotated, opacities from about 0.1 to 0.95, SH of the
/// given degree with a strong DC term. `log_scale` is the range of the log-scales.
pub fn random_gaussians(rng: &mut SplitMix64, n: usize, degree: u32, log_scale: [f32; 2]) -> Gaussians {
    let mut g = Gaussians::with_degree(degree);
    let k = sh_coeff_count(degree) * 3;
    let mut sh = vec![0.0f32; k];
    for _ in 0..n {
        let z = rng.uniform(2.0, 6.0);
        let mean = [rng.uniform(-0.5, 0.5) * z, rng.uniform(-0.4, 0.4) * z, z];
        let scale = [(); 3].map(|_| rng.uniform(log_scale[0], log_scale[1]));
        let rotation = [(); 4].map(|_| rng.uniform(-1.0, 1.0));
        let opacity = rng.uniform(-2.0, 3.0);
        for (j, v) in sh.iter_mut().enumerate() {
            *v = if j < 3 { rng.uniform(-1.5, 1.5) } else { rng.uniform(-0.3, 0.3) };
        }
        g.push(mean, scale, rotation, opacity, &sh);
    }
    g
}

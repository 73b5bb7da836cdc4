//! A splat's alpha at eight pixels of a row, for the vector blends (forward and backward): what
//! [`super::blend::splat_alpha`] computes, with a cheaper falloff whose error is stated below.
//!
//! The scalar path evaluates exp(-sigma) with [`pwgs_codec::portable_math::exp_f32`] (within 2 ulps
//! everywhere). Here sigma is taken in base 2 from the start: the Cholesky factors are scaled
//! by sqrt(log2(e) / 2) once per splat, so exp(-sigma) = 2^-s with s = p^2 + q^2, and 2^-s
//! needs no multiplication by log2(e) nor a split ln 2 (a shorter chain of dependent operations
//! from a pixel's offset to its alpha). The polynomial is a degree-5 minimax fit evaluated by
//! Estrin's scheme (three levels, not six) and s is clamped instead of selecting the underflow
//! result. Blending is not bit-normative (SPEC.md section 8): the tests bound the difference
//! of the vector images and gradients from the scalar path's.

use super::blend::SMOOTH_CUTOFF_BAND;
use super::lanes::Lanes8;
use super::project::Splat;
use super::{Cutoff, RenderOptions};
use pwgs_codec::portable_math::ROUND_F32;

/// Pixels per vector: a tile row is two chunks.
pub const LANES: usize = 8;

/// sqrt(log2(e) / 2): sigma = 0.5 (p^2 + q^2) in nats is (p'^2 + q'^2) in bits when p, q come
/// from factors scaled by this.
const BASE2_SCALE: f32 = 0.849_321_8;

/// Where [`pow2_neg`] clamps its argument: 2^-92 (2e-28) is still a normal f32.
const POW2_CLAMP: f32 = 92.0;

/// 2^r on [-1/2, 1/2] to within 9.2e-8 relative (a Lawson-iterated minimax fit with the
/// constant term held at 1, so that 2^-0 is exactly 1; rounded to f32), lowest order first.
#[allow(clippy::approx_constant, reason = "the fitted linear term, 3 ulps from ln 2, is not ln 2")]
const POW2_COEFFICIENTS: [f32; 6] = [1.0, 0.693_147, 0.240_222_41, 0.055_507_343, 0.009_671_566, 0.001_326_465_9];

/// 2^-s on eight lanes, s >= 0 and not NaN: within 2.2e-7 of the exact value, relative, for s
/// up to 92, and 2^-92 beyond (a splat of opacity at most 1 reaches alpha_min = 1/255 only for
/// s below log2(255) = 8).
#[inline(always)]
pub fn pow2_neg<L: Lanes8>(l: L, s: L::V) -> L::V {
    let s = l.min(s, l.splat(POW2_CLAMP));
    let round = l.splat(ROUND_F32);
    let k = l.sub(l.add(s, round), round);
    let r = l.sub(k, s);
    let c = POW2_COEFFICIENTS;
    let r2 = l.mul(r, r);
    let low = l.add(l.splat(c[0]), l.mul(l.splat(c[1]), r));
    let mid = l.add(l.splat(c[2]), l.mul(l.splat(c[3]), r));
    let high = l.add(l.splat(c[4]), l.mul(l.splat(c[5]), r));
    let p = l.add(low, l.mul(r2, l.add(mid, l.mul(r2, high))));
    // p 2^-k as the integer -k 2^23 added to p's bits (exact: 0 <= k <= 92).
    l.add_bits(p, l.trunc_int(l.mul(k, l.splat(-8_388_608.0))))
}

/// [`super::blend::splat_alpha`] at eight pixels of a row.
#[derive(Debug, Clone, Copy)]
pub struct AlphaLanes<V> {
    pub alpha: V,
    pub falloff: V,
    /// All ones in the lanes where the splat contributes (its alpha reaches alpha_min).
    pub contributes: V,
}

/// The offsets from splat `s`'s center of the eight pixel centers from column `start` on, as
/// the scalar path computes each: `mean_x - (px + 0.5)`.
#[inline(always)]
pub fn chunk_dx<L: Lanes8>(l: L, s: &Splat, start: u32) -> L::V {
    l.sub(l.splat(s.mean[0]), l.add(l.splat(start as f32), l.load_array(LANE_CENTERS)))
}

/// The lanes of a box row's two chunks (see [`chunk_dx`]) that lie inside the box, `width`
/// pixels wide: all ones there.
#[inline(always)]
pub fn box_lanes<L: Lanes8>(l: L, width: u32) -> [L::V; 2] {
    let index = l.load_array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    let width = l.splat(width as f32);
    [l.lt(index, width), l.lt(l.add(index, l.splat(LANES as f32)), width)]
}

/// Lane offsets plus the pixel-center half: lane l of a chunk starting at x is pixel x + l,
/// centered at x + l + 0.5 (exact in f32 for any image size pwgs accepts).
const LANE_CENTERS: [f32; LANES] = [0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5];

/// What a splat's alpha needs on every row of its box: the scaled Cholesky factors and, per
/// chunk of a row (at most two), the first factor times the chunk's offsets.
#[derive(Debug, Clone, Copy)]
pub struct SplatRows<V> {
    x_terms: [V; 2],
    l21: f32,
    l22: f32,
    opacity: V,
}

impl<V: Copy> SplatRows<V> {
    /// Splat `s`'s terms for chunks with offsets `dx` (see [`chunk_dx`]).
    #[inline(always)]
    pub fn new<L: Lanes8<V = V>>(l: L, s: &Splat, dx: [V; 2]) -> Self {
        let [l11, l21, l22] = s.cholesky;
        let l11 = l.splat(l11 * BASE2_SCALE);
        Self {
            x_terms: [l.mul(l11, dx[0]), l.mul(l11, dx[1])],
            l21: l21 * BASE2_SCALE,
            l22: l22 * BASE2_SCALE,
            opacity: l.splat(s.opacity),
        }
    }

    /// The splat's alpha at chunk `c` of the row at offset `dy` from its center.
    #[inline(always)]
    pub fn alpha<L: Lanes8<V = V>>(&self, l: L, c: usize, dy: f32, options: &RenderOptions) -> AlphaLanes<V> {
        let q = self.l22 * dy;
        let p = l.add(self.x_terms[c], l.splat(self.l21 * dy));
        let falloff = pow2_neg(l, l.add(l.mul(p, p), l.splat(q * q)));
        let raw = l.mul(self.opacity, falloff);
        let alpha_min = options.projection.alpha_min as f32;
        let contributes = l.and_not(l.splat(f32::from_bits(u32::MAX)), l.lt(raw, l.splat(alpha_min)));
        let mut alpha = l.min(raw, l.splat(options.alpha_max));
        if options.cutoff == Cutoff::Smooth {
            let t = l.min(l.div(l.sub(raw, l.splat(alpha_min)), l.splat(SMOOTH_CUTOFF_BAND)), l.splat(1.0));
            alpha = l.mul(l.mul(l.mul(alpha, t), t), l.sub(l.splat(3.0), l.mul(l.splat(2.0), t)));
        }
        AlphaLanes { alpha, falloff, contributes }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::lanes::Portable;

    /// The stated bound, on a fine grid of s over the whole clamped range, in both lane kinds.
    #[test]
    fn pow2_neg_is_within_its_stated_error() {
        let check = |l: &dyn Fn([f32; 8]) -> [f32; 8]| {
            let mut worst = 0.0f64;
            for i in 0..200_000 {
                let s: [f32; 8] = std::array::from_fn(|j| (i * 8 + j) as f32 * (92.0 / 1.6e6));
                for (x, y) in s.iter().zip(l(s)) {
                    worst = worst.max((f64::from(y) / (-f64::from(*x)).exp2() - 1.0).abs());
                    assert!(y <= 1.0, "2^-{x} = {y}: a falloff above 1");
                }
            }
            assert!(worst <= 2.2e-7, "worst relative error {worst}");
            let beyond = l([92.0, 100.0, 1e6, f32::INFINITY, 200.0, 93.0, 1e30, 92.5]);
            assert!(beyond.iter().all(|&y| y > 0.0 && y < 1e-27), "beyond the clamp: {beyond:?}");
            assert_eq!(l([0.0; 8])[0], 1.0, "2^0");
        };
        check(&|s| Portable.to_array(pow2_neg(Portable, Portable.load_array(s))));
        #[cfg(target_arch = "x86_64")]
        if let Some(avx2) = crate::raster::lanes::Avx2::detect() {
            check(&|s| avx2.to_array(pow2_neg(avx2, avx2.load_array(s))));
        }
    }
}

//! Eight f32 lanes ([`Lanes8`], the forward blend and alpha) and four f64 lanes ([`Lanes4d`],
//! the backward blend), two ways: `wide`'s portable vectors (what a plain x86-64 build
//! compiles them to: pairs of SSE registers) and, where the CPU has them, AVX2 registers
//! through `pulp`'s V3 token, found at run time. The blends are written once over these
//! traits; each operation is one IEEE operation per lane in both, so the two give the same
//! bits (the tests compare both with the scalar path).
//!
//! Masks are vectors too: all ones in the lanes where a comparison holds.
//!
//! Everything here is `#[inline(always)]`: the AVX2 code only gets its instructions when it is
//! inlined into the function that `pulp` compiles with the features enabled; a call that is
//! not inlined would run each operation out of line.

use wide::{f32x8, f64x4, u32x8};

/// The operations the blend needs on eight f32 lanes.
pub trait Lanes8: Copy {
    type V: Copy;
    fn splat(self, x: f32) -> Self::V;
    fn load_array(self, a: [f32; 8]) -> Self::V;
    fn to_array(self, v: Self::V) -> [f32; 8];
    fn add(self, a: Self::V, b: Self::V) -> Self::V;
    fn sub(self, a: Self::V, b: Self::V) -> Self::V;
    fn mul(self, a: Self::V, b: Self::V) -> Self::V;
    fn div(self, a: Self::V, b: Self::V) -> Self::V;
    fn min(self, a: Self::V, b: Self::V) -> Self::V;
    fn lt(self, a: Self::V, b: Self::V) -> Self::V;
    fn le(self, a: Self::V, b: Self::V) -> Self::V;
    fn gt(self, a: Self::V, b: Self::V) -> Self::V;
    fn and(self, a: Self::V, b: Self::V) -> Self::V;
    fn or(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a & !b`.
    fn and_not(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a` in the lanes of `mask`, `b` elsewhere.
    fn select(self, mask: Self::V, a: Self::V, b: Self::V) -> Self::V;
    /// Each lane truncated to an i32, as bits.
    fn trunc_int(self, a: Self::V) -> Self::V;
    /// The lanes' bits added as u32s (wrapping).
    fn add_bits(self, a: Self::V, b: Self::V) -> Self::V;
    /// Lane l's mask in bit l.
    fn bitmask(self, mask: Self::V) -> u32;
}

/// The operations the backward blend needs on four f64 lanes (masks as in [`Lanes8`]).
pub trait Lanes4d: Copy {
    type D: Copy;
    fn splat_d(self, x: f64) -> Self::D;
    fn load_array_d(self, a: [f64; 4]) -> Self::D;
    fn to_array_d(self, v: Self::D) -> [f64; 4];
    fn add_d(self, a: Self::D, b: Self::D) -> Self::D;
    fn sub_d(self, a: Self::D, b: Self::D) -> Self::D;
    fn mul_d(self, a: Self::D, b: Self::D) -> Self::D;
    fn div_d(self, a: Self::D, b: Self::D) -> Self::D;
    fn min_d(self, a: Self::D, b: Self::D) -> Self::D;
    fn lt_d(self, a: Self::D, b: Self::D) -> Self::D;
    fn eq_d(self, a: Self::D, b: Self::D) -> Self::D;
    fn and_d(self, a: Self::D, b: Self::D) -> Self::D;
    fn select_d(self, mask: Self::D, a: Self::D, b: Self::D) -> Self::D;
    /// Whether any lane of the mask is set.
    fn any_d(self, mask: Self::D) -> bool;
}

/// `wide`'s vectors: every target, whatever the build's features.
#[derive(Debug, Clone, Copy)]
pub struct Portable;

impl Lanes8 for Portable {
    type V = f32x8;
    #[inline(always)]
    fn splat(self, x: f32) -> f32x8 {
        f32x8::splat(x)
    }
    #[inline(always)]
    fn load_array(self, a: [f32; 8]) -> f32x8 {
        f32x8::new(a)
    }
    #[inline(always)]
    fn to_array(self, v: f32x8) -> [f32; 8] {
        v.to_array()
    }
    #[inline(always)]
    fn add(self, a: f32x8, b: f32x8) -> f32x8 {
        a + b
    }
    #[inline(always)]
    fn sub(self, a: f32x8, b: f32x8) -> f32x8 {
        a - b
    }
    #[inline(always)]
    fn mul(self, a: f32x8, b: f32x8) -> f32x8 {
        a * b
    }
    #[inline(always)]
    fn div(self, a: f32x8, b: f32x8) -> f32x8 {
        a / b
    }
    #[inline(always)]
    fn min(self, a: f32x8, b: f32x8) -> f32x8 {
        a.min(b)
    }
    #[inline(always)]
    fn lt(self, a: f32x8, b: f32x8) -> f32x8 {
        a.simd_lt(b)
    }
    #[inline(always)]
    fn le(self, a: f32x8, b: f32x8) -> f32x8 {
        a.simd_le(b)
    }
    #[inline(always)]
    fn gt(self, a: f32x8, b: f32x8) -> f32x8 {
        a.simd_gt(b)
    }
    #[inline(always)]
    fn and(self, a: f32x8, b: f32x8) -> f32x8 {
        a & b
    }
    #[inline(always)]
    fn or(self, a: f32x8, b: f32x8) -> f32x8 {
        a | b
    }
    #[inline(always)]
    fn and_not(self, a: f32x8, b: f32x8) -> f32x8 {
        a & !b
    }
    #[inline(always)]
    fn select(self, mask: f32x8, a: f32x8, b: f32x8) -> f32x8 {
        mask.select(a, b)
    }
    #[inline(always)]
    fn trunc_int(self, a: f32x8) -> f32x8 {
        bytemuck::cast(a.trunc_int())
    }
    #[inline(always)]
    fn add_bits(self, a: f32x8, b: f32x8) -> f32x8 {
        bytemuck::cast(bytemuck::cast::<f32x8, u32x8>(a) + bytemuck::cast::<f32x8, u32x8>(b))
    }
    #[inline(always)]
    fn bitmask(self, mask: f32x8) -> u32 {
        mask.to_bitmask()
    }
}

impl Lanes4d for Portable {
    type D = f64x4;
    #[inline(always)]
    fn splat_d(self, x: f64) -> f64x4 {
        f64x4::splat(x)
    }
    #[inline(always)]
    fn load_array_d(self, a: [f64; 4]) -> f64x4 {
        f64x4::new(a)
    }
    #[inline(always)]
    fn to_array_d(self, v: f64x4) -> [f64; 4] {
        v.to_array()
    }
    #[inline(always)]
    fn add_d(self, a: f64x4, b: f64x4) -> f64x4 {
        a + b
    }
    #[inline(always)]
    fn sub_d(self, a: f64x4, b: f64x4) -> f64x4 {
        a - b
    }
    #[inline(always)]
    fn mul_d(self, a: f64x4, b: f64x4) -> f64x4 {
        a * b
    }
    #[inline(always)]
    fn div_d(self, a: f64x4, b: f64x4) -> f64x4 {
        a / b
    }
    #[inline(always)]
    fn min_d(self, a: f64x4, b: f64x4) -> f64x4 {
        a.min(b)
    }
    #[inline(always)]
    fn lt_d(self, a: f64x4, b: f64x4) -> f64x4 {
        a.simd_lt(b)
    }
    #[inline(always)]
    fn eq_d(self, a: f64x4, b: f64x4) -> f64x4 {
        a.simd_eq(b)
    }
    #[inline(always)]
    fn and_d(self, a: f64x4, b: f64x4) -> f64x4 {
        a & b
    }
    #[inline(always)]
    fn select_d(self, mask: f64x4, a: f64x4, b: f64x4) -> f64x4 {
        mask.select(a, b)
    }
    #[inline(always)]
    fn any_d(self, mask: f64x4) -> bool {
        mask.any()
    }
}

#[cfg(target_arch = "x86_64")]
pub use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use pulp::x86::V3;
    use pulp::{f32x8, f64x4, m32x8, m64x4};

    use super::{Lanes4d, Lanes8};

    /// AVX2 registers, on a CPU that has them (x86-64-v3: AVX2, FMA, BMI; FMA is not used).
    #[derive(Debug, Clone, Copy)]
    pub struct Avx2(pub V3);

    impl Avx2 {
        /// The CPU's AVX2, if it has it.
        pub fn detect() -> Option<Self> {
            V3::try_new().map(Self)
        }
    }

    #[inline(always)]
    fn mask(m: m32x8) -> f32x8 {
        bytemuck::cast(m)
    }

    #[inline(always)]
    fn as_mask(v: f32x8) -> m32x8 {
        bytemuck::cast(v)
    }

    impl Lanes8 for Avx2 {
        type V = f32x8;
        #[inline(always)]
        fn splat(self, x: f32) -> f32x8 {
            self.0.splat_f32x8(x)
        }
        #[inline(always)]
        fn load_array(self, a: [f32; 8]) -> f32x8 {
            bytemuck::cast(a)
        }
        #[inline(always)]
        fn to_array(self, v: f32x8) -> [f32; 8] {
            bytemuck::cast(v)
        }
        #[inline(always)]
        fn add(self, a: f32x8, b: f32x8) -> f32x8 {
            self.0.add_f32x8(a, b)
        }
        #[inline(always)]
        fn sub(self, a: f32x8, b: f32x8) -> f32x8 {
            self.0.sub_f32x8(a, b)
        }
        #[inline(always)]
        fn mul(self, a: f32x8, b: f32x8) -> f32x8 {
            self.0.mul_f32x8(a, b)
        }
        #[inline(always)]
        fn div(self, a: f32x8, b: f32x8) -> f32x8 {
            self.0.div_f32x8(a, b)
        }
        #[inline(always)]
        fn min(self, a: f32x8, b: f32x8) -> f32x8 {
            self.0.min_f32x8(a, b)
        }
        #[inline(always)]
        fn lt(self, a: f32x8, b: f32x8) -> f32x8 {
            mask(self.0.cmp_lt_f32x8(a, b))
        }
        #[inline(always)]
        fn le(self, a: f32x8, b: f32x8) -> f32x8 {
            mask(self.0.cmp_le_f32x8(a, b))
        }
        #[inline(always)]
        fn gt(self, a: f32x8, b: f32x8) -> f32x8 {
            mask(self.0.cmp_gt_f32x8(a, b))
        }
        #[inline(always)]
        fn and(self, a: f32x8, b: f32x8) -> f32x8 {
            self.0.and_f32x8(a, b)
        }
        #[inline(always)]
        fn or(self, a: f32x8, b: f32x8) -> f32x8 {
            self.0.or_f32x8(a, b)
        }
        #[inline(always)]
        fn and_not(self, a: f32x8, b: f32x8) -> f32x8 {
            // pulp's andnot is `!first & second`.
            self.0.andnot_f32x8(b, a)
        }
        #[inline(always)]
        fn select(self, m: f32x8, a: f32x8, b: f32x8) -> f32x8 {
            self.0.select_f32x8(as_mask(m), a, b)
        }
        #[inline(always)]
        fn trunc_int(self, a: f32x8) -> f32x8 {
            bytemuck::cast(self.0.convert_f32x8_to_i32x8(a))
        }
        #[inline(always)]
        fn add_bits(self, a: f32x8, b: f32x8) -> f32x8 {
            bytemuck::cast(self.0.wrapping_add_u32x8(bytemuck::cast(a), bytemuck::cast(b)))
        }
        #[inline(always)]
        fn bitmask(self, m: f32x8) -> u32 {
            self.0.avx._mm256_movemask_ps(bytemuck::cast(m)) as u32
        }
    }

    #[inline(always)]
    fn mask_d(m: m64x4) -> f64x4 {
        bytemuck::cast(m)
    }

    impl Lanes4d for Avx2 {
        type D = f64x4;
        #[inline(always)]
        fn splat_d(self, x: f64) -> f64x4 {
            self.0.splat_f64x4(x)
        }
        #[inline(always)]
        fn load_array_d(self, a: [f64; 4]) -> f64x4 {
            bytemuck::cast(a)
        }
        #[inline(always)]
        fn to_array_d(self, v: f64x4) -> [f64; 4] {
            bytemuck::cast(v)
        }
        #[inline(always)]
        fn add_d(self, a: f64x4, b: f64x4) -> f64x4 {
            self.0.add_f64x4(a, b)
        }
        #[inline(always)]
        fn sub_d(self, a: f64x4, b: f64x4) -> f64x4 {
            self.0.sub_f64x4(a, b)
        }
        #[inline(always)]
        fn mul_d(self, a: f64x4, b: f64x4) -> f64x4 {
            self.0.mul_f64x4(a, b)
        }
        #[inline(always)]
        fn div_d(self, a: f64x4, b: f64x4) -> f64x4 {
            self.0.div_f64x4(a, b)
        }
        #[inline(always)]
        fn min_d(self, a: f64x4, b: f64x4) -> f64x4 {
            self.0.min_f64x4(a, b)
        }
        #[inline(always)]
        fn lt_d(self, a: f64x4, b: f64x4) -> f64x4 {
            mask_d(self.0.cmp_lt_f64x4(a, b))
        }
        #[inline(always)]
        fn eq_d(self, a: f64x4, b: f64x4) -> f64x4 {
            mask_d(self.0.cmp_eq_f64x4(a, b))
        }
        #[inline(always)]
        fn and_d(self, a: f64x4, b: f64x4) -> f64x4 {
            self.0.and_f64x4(a, b)
        }
        #[inline(always)]
        fn select_d(self, m: f64x4, a: f64x4, b: f64x4) -> f64x4 {
            self.0.select_f64x4(bytemuck::cast(m), a, b)
        }
        #[inline(always)]
        fn any_d(self, m: f64x4) -> bool {
            self.0.avx._mm256_movemask_pd(bytemuck::cast(m)) != 0
        }
    }
}

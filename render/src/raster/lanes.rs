//! Eight f32 lanes ([`Lanes8`], the forward blend and alpha) and four f64 lanes ([`Lanes4d`],
//! the backward blend), two ways: `wide`'s portable vectors (what a plain x86-64 build
//! compiles them to: pairs of SSE registers) and, where the CPU has them, AVX2 registers
//! through `pulp`'s V3 token, found at run time. The blends are written once over these
//! traits; each operation is one IEEE operation per lane in both, so the two give the same
//! bits (the blends' tests check it).
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
    /// The larger of each pair (neither may be NaN: the two implementations differ there).
    fn max(self, a: Self::V, b: Self::V) -> Self::V;
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
    /// The larger bits of each pair, as u32s.
    fn max_bits(self, a: Self::V, b: Self::V) -> Self::V;
    /// Lane l's mask in bit l.
    fn bitmask(self, mask: Self::V) -> u32;
}

/// The operations the backward blend needs on four f64 lanes (masks as in [`Lanes8`]).
pub trait Lanes4d: Lanes8 {
    type D: Copy;
    /// The eight lanes of `v` in f64 (exact): the first four and the last four.
    fn widen(self, v: Self::V) -> [Self::D; 2];
    /// The lanes' sum, as (a0 + a2) + (a1 + a3) (the order AVX's halves give cheaply).
    fn sum_d(self, v: Self::D) -> f64;
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

/// Asks the CPU to bring `value`'s cache lines (its first and last byte's) into its caches,
/// for reads that are coming but would miss: x86-64's prefetch instruction (safe through
/// `pulp`'s token), nothing elsewhere.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    if let Some(sse) = pulp::core_arch::x86::Sse::try_new() {
        const T0: i32 = 3;
        let first = (value as *const T).cast::<i8>();
        sse._mm_prefetch::<T0>(first);
        sse._mm_prefetch::<T0>(first.wrapping_add(size_of::<T>().saturating_sub(1)));
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// A computation written once over the lane traits (see [`run_kernel`]).
pub trait LaneKernel {
    type Output;
    /// The computation on lanes `l` (f64 lanes and, through [`Lanes4d`]'s supertrait, f32
    /// ones). Implementations are `#[inline(always)]`, and so is everything they call that
    /// uses the lanes.
    fn run<L: Lanes4d>(self, l: L) -> Self::Output;
}

/// Runs `kernel` in AVX2 registers where the CPU has them (unless `portable` asks for `wide`'s
/// vectors), else in `wide`'s. The kernel goes to `pulp` as a value whose call is
/// `#[inline(always)]`, not as a closure: a closure reaches it through a `FnOnce` shim that
/// LLVM may decline to inline once the kernel is large, and the kernel then runs without the
/// AVX2 features, each lane operation a call (the backward blend became 20 times slower so).
#[inline(always)]
pub fn run_kernel<K: LaneKernel>(kernel: K, portable: bool) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    if let Some(avx2) = Avx2::detect().filter(|_| !portable) {
        return avx2.0.vectorize(avx2::InAvx2(kernel, avx2));
    }
    let _ = portable;
    kernel.run(Portable)
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
    fn max(self, a: f32x8, b: f32x8) -> f32x8 {
        a.max(b)
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
    fn max_bits(self, a: f32x8, b: f32x8) -> f32x8 {
        bytemuck::cast(bytemuck::cast::<f32x8, u32x8>(a).max(bytemuck::cast::<f32x8, u32x8>(b)))
    }
    #[inline(always)]
    fn bitmask(self, mask: f32x8) -> u32 {
        mask.to_bitmask()
    }
}

impl Lanes4d for Portable {
    type D = f64x4;
    #[inline(always)]
    fn widen(self, v: f32x8) -> [f64x4; 2] {
        let a = v.to_array().map(f64::from);
        [f64x4::new([a[0], a[1], a[2], a[3]]), f64x4::new([a[4], a[5], a[6], a[7]])]
    }
    #[inline(always)]
    fn sum_d(self, v: f64x4) -> f64 {
        let a = v.to_array();
        (a[0] + a[2]) + (a[1] + a[3])
    }
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

    use super::{LaneKernel, Lanes4d, Lanes8};

    /// A kernel and the AVX2 lanes it runs on, as `pulp` calls it (inside a function compiled
    /// with the features).
    pub(super) struct InAvx2<K>(pub K, pub Avx2);

    impl<K: LaneKernel> pulp::NullaryFnOnce for InAvx2<K> {
        type Output = K::Output;
        #[inline(always)]
        fn call(self) -> K::Output {
            self.0.run(self.1)
        }
    }

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
        fn max(self, a: f32x8, b: f32x8) -> f32x8 {
            self.0.max_f32x8(a, b)
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
        fn max_bits(self, a: f32x8, b: f32x8) -> f32x8 {
            bytemuck::cast(self.0.avx2._mm256_max_epu32(bytemuck::cast(a), bytemuck::cast(b)))
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
        fn widen(self, v: f32x8) -> [f64x4; 2] {
            let avx = self.0.avx;
            let v = bytemuck::cast(v);
            [
                bytemuck::cast(avx._mm256_cvtps_pd(avx._mm256_castps256_ps128(v))),
                bytemuck::cast(avx._mm256_cvtps_pd(avx._mm256_extractf128_ps::<1>(v))),
            ]
        }
        #[inline(always)]
        fn sum_d(self, v: f64x4) -> f64 {
            let (avx, sse2) = (self.0.avx, self.0.sse2);
            let v = bytemuck::cast(v);
            let halves = sse2._mm_add_pd(avx._mm256_castpd256_pd128(v), avx._mm256_extractf128_pd::<1>(v));
            sse2._mm_cvtsd_f64(sse2._mm_add_sd(halves, sse2._mm_unpackhi_pd(halves, halves)))
        }
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

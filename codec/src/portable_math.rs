//! `exp` and `ln` from IEEE-754 `+ - * /` and exact bit operations only, in a fixed order, so
//! that they give the same bits on every machine (docs/architecture.md section 3, rule 1).
//!
//! The platform's `exp` and `ln` (libm, or an intrinsic the compiler picks) may round the last
//! bit differently from one machine or library to another. The rasterizer's results feed a
//! normative choice, the quantization steps of the wrapper's weights (the encoder picks the
//! coarsest steps whose output stays within a tolerance on rendered views), so its
//! transcendentals must be portable. Accuracy, measured against `std` by the tests: within 2
//! units in the last place for `exp` and `exp_f32`, 4 for `ln_f64` and `ln_f32`.

/// 1.5 * 2^52: adding and subtracting it rounds an f64 of magnitude below 2^51 to the nearest
/// integer (ties to even) with two exact-order IEEE additions, whatever the target's rounding
/// instructions.
const ROUND_F64: f64 = 6_755_399_441_055_744.0;
/// 1.5 * 2^23, the same for f32 below 2^22.
pub const ROUND_F32: f32 = 12_582_912.0;

/// ln 2 split so that `k * LN2_HI` is exact for |k| < 2^11 (its low 32 bits are zero).
const LN2_HI: f64 = 0.693_147_180_369_123_8;
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
const LOG2_E: f64 = std::f64::consts::LOG2_E;
const SQRT_2: f64 = std::f64::consts::SQRT_2;

/// ln 2 split for f32: `EXP_F32_LN2_HI` has 9 significant bits, so `k * EXP_F32_LN2_HI` is exact for
/// |k| < 2^15.
pub(crate) const EXP_F32_LN2_HI: f32 = 0.693_359_4;
pub(crate) const EXP_F32_LN2_LO: f32 = -2.121_944_4e-4;
/// Above this `exp_f32` is infinity, below `EXP_F32_LO` zero.
pub(crate) const EXP_F32_HI: f32 = 88.72;
pub(crate) const EXP_F32_LO: f32 = -87.33;

/// 1/n! for n = 13 down to 0, the Taylor coefficients of e^r from the highest.
const EXP_TAYLOR: [f64; 14] = [
    1.0 / 6_227_020_800.0,
    1.0 / 479_001_600.0,
    1.0 / 39_916_800.0,
    1.0 / 3_628_800.0,
    1.0 / 362_880.0,
    1.0 / 40_320.0,
    1.0 / 5_040.0,
    1.0 / 720.0,
    1.0 / 120.0,
    1.0 / 24.0,
    1.0 / 6.0,
    0.5,
    1.0,
    1.0,
];
/// 1/n! for n = 7 down to 0.
pub(crate) const EXP_F32_COEFFICIENTS: [f32; 8] =
    [1.0 / 5_040.0, 1.0 / 720.0, 1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0, 1.0];
/// 1/(2n + 1) for n = 12 down to 0: atanh(s) / s as a series in s^2, from the highest term.
const ATANH_SERIES: [f64; 13] = [
    1.0 / 25.0,
    1.0 / 23.0,
    1.0 / 21.0,
    1.0 / 19.0,
    1.0 / 17.0,
    1.0 / 15.0,
    1.0 / 13.0,
    1.0 / 11.0,
    1.0 / 9.0,
    1.0 / 7.0,
    1.0 / 5.0,
    1.0 / 3.0,
    1.0,
];

/// 1/(2n + 1) for n = 4 down to 0: [`ATANH_SERIES`]'s terms that f32 needs.
const ATANH_SERIES_F32: [f32; 5] = [1.0 / 9.0, 1.0 / 7.0, 1.0 / 5.0, 1.0 / 3.0, 1.0];

/// 2^k for an integer exponent within the normal range.
fn pow2_f64(k: i64) -> f64 {
    f64::from_bits(((k + 1023) as u64) << 52)
}

/// e^x in f64. Results below the smallest subnormal are 0, above `f64::MAX` infinity.
pub fn exp_f64(x: f64) -> f64 {
    if x.is_nan() {
        return x;
    }
    if x > 709.8 {
        return f64::INFINITY;
    }
    if x < -745.2 {
        return 0.0;
    }
    // x = k ln2 + r with |r| <= ln2 / 2 (Cody and Waite's two-part reduction).
    let k = (x * LOG2_E + ROUND_F64) - ROUND_F64;
    let r = (x - k * LN2_HI) - k * LN2_LO;
    // e^r by its Taylor series to r^13 (truncation below 1e-17 for |r| <= 0.35), Horner order.
    let p = EXP_TAYLOR.iter().fold(0.0, |p, &c| p * r + c);
    // Scale by 2^k in two halves, so that neither factor leaves the normal range (k reaches
    // 1024 near overflow and -1075 near underflow, where the product rounds to a subnormal).
    let k = k as i64;
    let half = k / 2;
    p * pow2_f64(half) * pow2_f64(k - half)
}

/// e^x in f32. Results below 2^-126 are 0 (the rasterizer's falloff is cut far above), above
/// `f32::MAX` infinity. This is the rasterizer's innermost call, so it takes no branch for NaN
/// (which flows through the arithmetic) and scales by adding k to the exponent bits.
#[inline]
pub fn exp_f32(x: f32) -> f32 {
    if x > EXP_F32_HI {
        return f32::INFINITY;
    }
    if x < EXP_F32_LO {
        return 0.0;
    }
    let k = (x * std::f32::consts::LOG2_E + ROUND_F32) - ROUND_F32;
    let r = (x - k * EXP_F32_LN2_HI) - k * EXP_F32_LN2_LO;
    // Taylor series to r^7 (truncation below 3e-9 for |r| <= 0.35).
    let p = EXP_F32_COEFFICIENTS.iter().fold(0.0, |p, &c| p * r + c);
    // p * 2^k by exponent arithmetic: p lies in [0.70, 1.42] and, within the bounds above, a
    // k of -126 comes with p > 1 and a k of 128 with p >= 1 only past f32::MAX, where the
    // exponent field becomes all ones: infinity, as it should. A NaN x gives k = 0 and p NaN.
    f32::from_bits(p.to_bits().wrapping_add(((k as i32) << 23) as u32))
}

/// The natural logarithm in f64: NaN below 0, -infinity at 0.
pub fn ln_f64(x: f64) -> f64 {
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return f64::NEG_INFINITY;
    }
    if x == f64::INFINITY {
        return x;
    }
    // x = m 2^e with m in [sqrt(1/2), sqrt(2)); subnormals are scaled up by 2^54 first.
    let (x, bias) = if x < f64::MIN_POSITIVE { (x * pow2_f64(54), 54) } else { (x, 0) };
    let bits = x.to_bits();
    let mut e = ((bits >> 52) & 0x7ff) as i64 - 1023 - bias;
    let mut m = f64::from_bits((bits & ((1 << 52) - 1)) | (1023 << 52));
    if m > SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    // ln m = 2 atanh(s) = 2 (s + s^3/3 + s^5/5 + ...), s = (m - 1) / (m + 1), |s| <= 0.1716:
    // to s^25 the truncation is below 1e-19.
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = ATANH_SERIES.iter().fold(0.0, |p, &c| p * s2 + c);
    let ln_m = 2.0 * s * series;
    let e = e as f64;
    e * LN2_HI + (ln_m + e * LN2_LO)
}

/// The natural logarithm in f32, as [`ln_f64`]: NaN below 0, -infinity at 0.
pub fn ln_f32(x: f32) -> f32 {
    if x.is_nan() || x < 0.0 {
        return f32::NAN;
    }
    if x == 0.0 {
        return f32::NEG_INFINITY;
    }
    if x == f32::INFINITY {
        return x;
    }
    // x = m 2^e with m in [sqrt(1/2), sqrt(2)); subnormals are scaled up by 2^25 first.
    let (x, bias) = if x < f32::MIN_POSITIVE { (x * 33_554_432.0, 25) } else { (x, 0) };
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127 - bias;
    let mut m = f32::from_bits((bits & ((1 << 23) - 1)) | (127 << 23));
    if m > std::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    // ln m = 2 atanh(s), s = (m - 1) / (m + 1), |s| <= 0.1716: to s^9 the truncation is below
    // 3e-9 of the result.
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = ATANH_SERIES_F32.iter().fold(0.0, |p, &c| p * s2 + c);
    let ln_m = 2.0 * s * series;
    let e = e as f32;
    e * EXP_F32_LN2_HI + (ln_m + e * EXP_F32_LN2_LO)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Units in the last place between `got` and the platform's (correctly rounded or nearly
    /// so) value.
    fn ulps_f64(got: f64, want: f64) -> f64 {
        if got == want {
            return 0.0;
        }
        let ulp = f64::from_bits(want.abs().to_bits() + 1) - want.abs();
        ((got - want) / ulp).abs()
    }

    fn ulps_f32(got: f32, want: f32) -> f32 {
        if got == want {
            return 0.0;
        }
        let ulp = f32::from_bits(want.abs().to_bits() + 1) - want.abs();
        ((got - want) / ulp).abs()
    }

    /// Points spread over [lo, hi], ends included.
    fn grid(lo: f64, hi: f64, n: usize) -> impl Iterator<Item = f64> {
        (0..=n).map(move |i| lo + (hi - lo) * i as f64 / n as f64)
    }

    #[test]
    fn exp_is_within_two_ulps() {
        let worst = grid(-700.0, 709.0, 200_003).map(|x| ulps_f64(exp_f64(x), x.exp())).fold(0.0, f64::max);
        assert!(worst <= 2.0, "worst error {worst} ulps");
        assert_eq!(exp_f64(0.0), 1.0);
    }

    #[test]
    fn exp_handles_the_ends_of_its_range() {
        assert_eq!(exp_f64(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp_f64(-800.0), 0.0);
        assert_eq!(exp_f64(710.0), f64::INFINITY);
        assert_eq!(exp_f64(f64::INFINITY), f64::INFINITY);
        assert!(exp_f64(f64::NAN).is_nan());
        // Near the top k reaches 1024; near the bottom the result is subnormal.
        assert!(ulps_f64(exp_f64(709.7), 709.7f64.exp()) <= 2.0);
        let tiny = exp_f64(-740.0);
        assert!(tiny > 0.0 && tiny < f64::MIN_POSITIVE);
        assert!((tiny / (-740f64).exp() - 1.0).abs() < 1e-3);
    }

    #[test]
    fn exp_f32_is_within_two_ulps() {
        let worst =
            grid(-87.0, 88.0, 200_003).map(|x| x as f32).map(|x| ulps_f32(exp_f32(x), x.exp())).fold(0.0, f32::max);
        assert!(worst <= 2.0, "worst error {worst} ulps");
        // The ends, where k is -126 and 128.
        for x in [-87.33f32, -87.3, 88.7, 88.72] {
            assert!(ulps_f32(exp_f32(x), x.exp()) <= 2.0, "exp_f32({x}) = {} vs {}", exp_f32(x), x.exp());
        }
        assert_eq!(exp_f32(0.0), 1.0);
        assert_eq!(exp_f32(-100.0), 0.0);
        assert_eq!(exp_f32(100.0), f32::INFINITY);
        assert!(exp_f32(f32::NAN).is_nan());
    }

    #[test]
    fn ln_is_within_four_ulps() {
        let xs = grid(-700.0, 700.0, 100_003).map(f64::exp).chain(grid(0.5, 2.0, 100_003));
        let worst = xs.map(|x| ulps_f64(ln_f64(x), x.ln())).fold(0.0, f64::max);
        assert!(worst <= 4.0, "worst error {worst} ulps");
        assert_eq!(ln_f64(1.0), 0.0);
        let subnormal = f64::MIN_POSITIVE / 1024.0;
        assert!(ulps_f64(ln_f64(subnormal), subnormal.ln()) <= 4.0);
        assert_eq!(ln_f64(0.0), f64::NEG_INFINITY);
        assert!(ln_f64(-1.0).is_nan() && ln_f64(f64::NAN).is_nan());
        assert_eq!(ln_f64(f64::INFINITY), f64::INFINITY);
    }

    #[test]
    fn ln_f32_is_within_four_ulps() {
        let xs = grid(-87.0, 88.0, 100_003).map(f64::exp).chain(grid(0.5, 2.0, 100_003)).map(|x| x as f32);
        let worst = xs.map(|x| ulps_f32(ln_f32(x), x.ln())).fold(0.0, f32::max);
        assert!(worst <= 4.0, "worst error {worst} ulps");
        assert_eq!(ln_f32(1.0), 0.0);
        let subnormal = f32::MIN_POSITIVE / 1024.0;
        assert!(ulps_f32(ln_f32(subnormal), subnormal.ln()) <= 4.0);
        assert_eq!(ln_f32(0.0), f32::NEG_INFINITY);
        assert!(ln_f32(-1.0).is_nan() && ln_f32(f32::NAN).is_nan());
        assert_eq!(ln_f32(f32::INFINITY), f32::INFINITY);
    }
}

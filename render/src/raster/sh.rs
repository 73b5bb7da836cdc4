//! Real spherical harmonics up to degree 3 in the basis and sign convention of 3DGS (and
//! gsplat, brush): color = max(sum_k basis_k(dir) * coeff_k + 0.5, 0), dir the unit vector from
//! the camera center to the Gaussian's mean.

/// Basis constants (Sloan, "Efficient Spherical Harmonic Evaluation", JCGT 2013).
pub const C0: f64 = 0.282_094_791_773_878_14;
pub const C1: f64 = 0.488_602_511_902_919_9;
pub const C2: [f64; 5] = [
    1.092_548_430_592_079_2,
    -1.092_548_430_592_079_2,
    0.315_391_565_252_520_05,
    -1.092_548_430_592_079_2,
    0.546_274_215_296_039_6,
];
pub const C3: [f64; 7] = [
    -0.590_043_589_926_643_5,
    2.890_611_442_640_554,
    -0.457_045_799_464_465_8,
    0.373_176_332_590_115_4,
    -0.457_045_799_464_465_8,
    1.445_305_721_320_277,
    -0.590_043_589_926_643_5,
];

/// The basis functions evaluated at unit direction `d`; the first `(degree + 1)^2` entries are
/// meaningful, the rest are zero.
pub fn basis(degree: u32, d: [f64; 3]) -> [f64; 16] {
    let [x, y, z] = d;
    let mut b = [0.0; 16];
    b[0] = C0;
    if degree >= 1 {
        b[1] = -C1 * y;
        b[2] = C1 * z;
        b[3] = -C1 * x;
    }
    if degree >= 2 {
        let (xx, yy, zz) = (x * x, y * y, z * z);
        b[4] = C2[0] * x * y;
        b[5] = C2[1] * y * z;
        b[6] = C2[2] * (2.0 * zz - xx - yy);
        b[7] = C2[3] * x * z;
        b[8] = C2[4] * (xx - yy);
        if degree >= 3 {
            b[9] = C3[0] * y * (3.0 * xx - yy);
            b[10] = C3[1] * x * y * z;
            b[11] = C3[2] * y * (4.0 * zz - xx - yy);
            b[12] = C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
            b[13] = C3[4] * x * (4.0 * zz - xx - yy);
            b[14] = C3[5] * z * (xx - yy);
            b[15] = C3[6] * x * (xx - 3.0 * yy);
        }
    }
    b
}

/// Color before the clamp at zero: `sum_k basis_k * coeff_k + 0.5` per channel. `coeffs` is
/// laid out [coefficient][rgb].
pub fn unclamped_color(degree: u32, coeffs: &[f32], d: [f64; 3]) -> [f64; 3] {
    let b = basis(degree, d);
    let mut rgb = [0.5; 3];
    for (k, chunk) in coeffs.chunks_exact(3).enumerate() {
        for c in 0..3 {
            rgb[c] += b[k] * chunk[c] as f64;
        }
    }
    rgb
}

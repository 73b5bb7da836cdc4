//! The frame a Gaussian's rotation is coded in.
//!
//! A 3D Gaussian's covariance `R diag(s)^2 R^T` does not change when its axes are relabelled:
//! turning `R` by any of the cube's 24 rotations `P` (which map the axes onto each other, signs
//! included) and permuting the scales alike gives the same Gaussian. The plain base codes a
//! rotation as the three smallest components of its quaternion, each within +-0.707; of the 24
//! equivalent quaternions, the one nearest the identity has its `w` largest (so the index of the
//! largest component is always 0) and its other components within +-0.414 (`|x| + |y| + |z|
//! <= w`). Coding that one takes fewer bits for the same step and the same error, and the stream
//! format does not change: decoders see an ordinary rotation and scales.

use pwgs_render::raster::project::rotation_matrix;

/// The cube's rotations as unit quaternions `(w, x, y, z)`, each once up to sign: the identity,
/// the half turns about the axes, the thirds of a turn about the diagonals, the quarter turns
/// about the axes and the half turns about the face diagonals.
fn cube_rotations() -> [[f64; 4]; 24] {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let mut out = [[0.0; 4]; 24];
    for (axis, q) in out[..4].iter_mut().enumerate() {
        q[axis] = 1.0;
    }
    for (signs, q) in out[4..12].iter_mut().enumerate() {
        let s = |bit: usize| if signs >> bit & 1 == 1 { -0.5 } else { 0.5 };
        *q = [0.5, s(0), s(1), s(2)];
    }
    let mut next = 12;
    for i in 0..4 {
        for j in i + 1..4 {
            for sign in [1.0, -1.0] {
                out[next][i] = h;
                out[next][j] = sign * h;
                next += 1;
            }
        }
    }
    out
}

/// Hamilton product `a b`: the rotation `a` after `b`, so that `R(a b) = R(a) R(b)`.
fn multiply(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]
}

/// For a cube rotation `p`, the axis each column of its matrix points along: column `j` of
/// `R(p)` is `+-e[axis[j]]`.
fn column_axes(p: [f64; 4]) -> [usize; 3] {
    let r = rotation_matrix(p);
    std::array::from_fn(|j| {
        let c = r.col(j).abs().to_array();
        (0..3).fold(0, |best, a| if c[a] > c[best] { a } else { best })
    })
}

/// The equivalent (rotation, log-scales) of a Gaussian whose unit quaternion is nearest the
/// identity, with `w >= 0`. A zero or non-finite quaternion is returned as it is (the caller's
/// quantizer decides what it becomes).
pub fn canonical_frame(rotation: [f32; 4], log_scales: [f32; 3]) -> ([f32; 4], [f32; 3]) {
    let q = rotation.map(f64::from);
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    if !(norm > 0.0 && norm.is_finite()) {
        return (rotation, log_scales);
    }
    let q = q.map(|c| c / norm);
    // The first of the candidates with the largest |w|.
    let (turned, p) = cube_rotations()
        .map(|p| (multiply(q, p), p))
        .into_iter()
        .reduce(|best, candidate| if best.0[0].abs() >= candidate.0[0].abs() { best } else { candidate })
        .expect("24 candidates");
    let sign = if turned[0] < 0.0 { -1.0 } else { 1.0 };
    let axes = column_axes(p);
    (turned.map(|c| (c * sign) as f32), axes.map(|a| log_scales[a]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The covariance `R diag(exp(2 s)) R^T` of a (rotation, log-scales) pair.
    fn covariance(q: [f32; 4], s: [f32; 3]) -> [[f64; 3]; 3] {
        let q = q.map(f64::from);
        let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        let r = rotation_matrix(q.map(|c| c / n));
        std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|k| r.col(k)[i] * r.col(k)[j] * (2.0 * f64::from(s[k])).exp()).sum())
        })
    }

    /// Deterministic pseudo-random values in [-1, 1).
    fn values(seed: u64, n: usize) -> Vec<f32> {
        let mut state = seed;
        (0..n)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((state >> 40) as f32 / (1u64 << 23) as f32) - 1.0
            })
            .collect()
    }

    #[test]
    fn the_cube_has_24_distinct_rotations() {
        let all = cube_rotations();
        assert_eq!(all.len(), 24);
        for (i, a) in all.iter().enumerate() {
            assert!((a.iter().map(|c| c * c).sum::<f64>() - 1.0).abs() < 1e-15);
            for b in &all[i + 1..] {
                let dot: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
                assert!(dot.abs() < 1.0 - 1e-9, "{a:?} and {b:?} are one rotation");
            }
        }
    }

    #[test]
    fn the_canonical_frame_is_the_same_gaussian_nearest_the_identity() {
        let v = values(7, 7 * 500);
        for g in v.chunks_exact(7) {
            let q = [g[0], g[1], g[2], g[3]];
            let s = [g[4] * 3.0, g[5] * 3.0 - 1.0, g[6] * 2.0];
            let (q2, s2) = canonical_frame(q, s);
            let (a, b) = (covariance(q, s), covariance(q2, s2));
            for i in 0..3 {
                for j in 0..3 {
                    let scale = a[i][i].max(a[j][j]);
                    assert!((a[i][j] - b[i][j]).abs() <= 1e-5 * scale, "{q:?} {s:?} -> {q2:?} {s2:?}");
                }
            }
            let [w, x, y, z] = q2.map(f64::from);
            // Nearest the identity among the 24: the bounds of its cell.
            assert!(w >= 0.0 && x.abs() + y.abs() + z.abs() <= w + 1e-6, "{q2:?}");
            for c in [x, y, z] {
                assert!(c.abs() <= (std::f64::consts::SQRT_2 - 1.0) * w + 1e-6, "{q2:?}");
            }
        }
    }

    #[test]
    fn a_degenerate_quaternion_is_left_alone() {
        let s = [0.1, 0.2, 0.3];
        assert_eq!(canonical_frame([0.0; 4], s), ([0.0; 4], s));
        let nan = [f32::NAN, 0.0, 0.0, 1.0];
        assert_eq!(canonical_frame(nan, s).1, s);
    }
}

//! Derivatives of the SH basis with respect to the (unit) viewing direction, for the gradient
//! that flows from color through the view direction into the Gaussian's mean. The basis itself
//! is the decoder's ([`pwgs_render::raster::sh::basis`]).

use pwgs_render::raster::sh::{C1, C2, C3};

/// d basis_k / d(x, y, z) for the first `(degree + 1)^2` basis functions, treating the
/// direction's components as independent (the caller projects out the radial part).
pub fn basis_gradient(degree: u32, d: [f64; 3]) -> [[f64; 3]; 16] {
    let [x, y, z] = d;
    let mut g = [[0.0; 3]; 16];
    if degree >= 1 {
        g[1] = [0.0, -C1, 0.0];
        g[2] = [0.0, 0.0, C1];
        g[3] = [-C1, 0.0, 0.0];
    }
    if degree >= 2 {
        g[4] = [C2[0] * y, C2[0] * x, 0.0];
        g[5] = [0.0, C2[1] * z, C2[1] * y];
        g[6] = [-2.0 * C2[2] * x, -2.0 * C2[2] * y, 4.0 * C2[2] * z];
        g[7] = [C2[3] * z, 0.0, C2[3] * x];
        g[8] = [2.0 * C2[4] * x, -2.0 * C2[4] * y, 0.0];
    }
    if degree >= 3 {
        let (xx, yy, zz) = (x * x, y * y, z * z);
        g[9] = [6.0 * C3[0] * x * y, C3[0] * (3.0 * xx - 3.0 * yy), 0.0];
        g[10] = [C3[1] * y * z, C3[1] * x * z, C3[1] * x * y];
        g[11] = [-2.0 * C3[2] * x * y, C3[2] * (4.0 * zz - xx - 3.0 * yy), 8.0 * C3[2] * y * z];
        g[12] = [-6.0 * C3[3] * x * z, -6.0 * C3[3] * y * z, C3[3] * (6.0 * zz - 3.0 * xx - 3.0 * yy)];
        g[13] = [C3[4] * (4.0 * zz - 3.0 * xx - yy), -2.0 * C3[4] * x * y, 8.0 * C3[4] * x * z];
        g[14] = [2.0 * C3[5] * x * z, -2.0 * C3[5] * y * z, C3[5] * (xx - yy)];
        g[15] = [C3[6] * (3.0 * xx - 3.0 * yy), -6.0 * C3[6] * x * y, 0.0];
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use pwgs_render::raster::sh::basis;

    #[test]
    fn matches_finite_differences_of_the_basis() {
        let d = [0.3, -0.5, 0.81];
        let g = basis_gradient(3, d);
        let h = 1e-6;
        for axis in 0..3 {
            let (mut plus, mut minus) = (d, d);
            plus[axis] += h;
            minus[axis] -= h;
            let (bp, bm) = (basis(3, plus), basis(3, minus));
            for k in 0..16 {
                let numeric = (bp[k] - bm[k]) / (2.0 * h);
                assert!((numeric - g[k][axis]).abs() < 1e-6, "basis {k} axis {axis}: {numeric} vs {}", g[k][axis]);
            }
        }
    }
}

//! Standard 3DGS Gaussians from an anchor model, for viewers that do not run its MLPs (the
//! export users of HAC-style codecs ask for most). Not normative: an approximation whose
//! quality `pwdec --export-ply` states as PSNR against the anchor renders.
//!
//! Every neural Gaussian an anchor may show becomes one Gaussian: its mean (view-independent),
//! its log scales and rotation averaged over the cameras that see it, its opacity the mean over
//! all cameras (0 where it is not shown), and its view-dependent color fitted by least squares
//! to SH of degree 3 over the directions it was seen from (ridge-damped above degree 0, so a
//! Gaussian seen from few cameras keeps a plain color).

use crate::raster::sh::basis;
use crate::raster::{RenderOptions, render};
use pwgs_codec::anchor::AnchorModel;
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::{Gaussians, opacity_to_logit, sh_coeff_count};

/// SH degree of the export.
pub const EXPORT_DEGREE: u32 = 3;

/// Ridge weight on every coefficient above the DC, relative to one sample.
const RIDGE: f64 = 0.1;

/// Opacity below which an exported Gaussian is left out (the renderer skips it anyway).
const MIN_OPACITY: f32 = 1.0 / 255.0;

const COEFFS: usize = sh_coeff_count(EXPORT_DEGREE);

/// What the cameras showed of one neural Gaussian.
#[derive(Clone)]
struct Seen {
    mean: [f32; 3],
    log_scale: [f64; 3],
    rotation: [f64; 4],
    opacity: f64,
    /// Normal equations of the SH fit: B^T B (upper triangle used) and B^T (rgb - 0.5).
    gram: [[f64; COEFFS]; COEFFS],
    moment: [[f64; 3]; COEFFS],
    count: usize,
}

impl Default for Seen {
    fn default() -> Self {
        Self {
            mean: [0.0; 3],
            log_scale: [0.0; 3],
            rotation: [0.0; 4],
            opacity: 0.0,
            gram: [[0.0; COEFFS]; COEFFS],
            moment: [[0.0; 3]; COEFFS],
            count: 0,
        }
    }
}

/// The plain Gaussians that approximate `model` as seen from `cameras` (at least one).
pub fn export_gaussians(model: &AnchorModel, cameras: &[Camera]) -> Gaussians {
    let mut seen = vec![Seen::default(); model.len() * model.offsets_per_anchor];
    for camera in cameras {
        let center = camera.center();
        model.visit_neural_gaussians(camera, |r, g| {
            let s = &mut seen[r];
            let direction = (glam::Vec3::from(g.mean) - center).normalize_or_zero().as_dvec3().to_array();
            let b = basis(EXPORT_DEGREE, direction);
            for (i, row) in s.gram.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v += b[i] * b[j];
                }
                for c in 0..3 {
                    s.moment[i][c] += b[i] * (f64::from(g.rgb[c]) - 0.5);
                }
            }
            let norm = g.rotation.iter().map(|&q| f64::from(q) * f64::from(q)).sum::<f64>().sqrt().max(1e-12);
            // q and -q are the same rotation: align with the running sum before adding.
            let dot: f64 = s.rotation.iter().zip(&g.rotation).map(|(a, &b)| a * f64::from(b)).sum();
            let sign = if dot < 0.0 { -1.0 } else { 1.0 };
            for (acc, &q) in s.rotation.iter_mut().zip(&g.rotation) {
                *acc += sign * f64::from(q) / norm;
            }
            for (acc, &l) in s.log_scale.iter_mut().zip(&g.log_scale) {
                *acc += f64::from(l);
            }
            s.opacity += 1.0 / (1.0 + (-f64::from(g.opacity_logit)).exp());
            s.mean = g.mean;
            s.count += 1;
        });
    }
    let mut out = Gaussians::with_degree(EXPORT_DEGREE);
    let views = cameras.len().max(1) as f64;
    for s in seen.iter().filter(|s| s.count > 0) {
        let opacity = (s.opacity / views) as f32;
        if opacity < MIN_OPACITY {
            continue;
        }
        let n = s.count as f64;
        let sh = fit_sh(s);
        out.push(
            s.mean,
            s.log_scale.map(|l| (l / n) as f32),
            s.rotation.map(|q| q as f32),
            opacity_to_logit(opacity.min(0.999)),
            &sh,
        );
    }
    out
}

/// SH coefficients [coefficient][rgb] solving the ridge-damped normal equations.
fn fit_sh(s: &Seen) -> Vec<f32> {
    let mut a = s.gram;
    for (i, row) in a.iter_mut().enumerate().skip(1) {
        row[i] += RIDGE;
    }
    let mut b = s.moment;
    // Gaussian elimination with partial pivoting (the matrix is symmetric positive definite
    // once damped, unless the DC row is empty, which a seen Gaussian's is not).
    for col in 0..COEFFS {
        let pivot = (col..COEFFS).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs())).expect("rows");
        a.swap(col, pivot);
        b.swap(col, pivot);
        let p = a[col][col];
        if p.abs() < 1e-12 {
            continue;
        }
        for row in col + 1..COEFFS {
            let factor = a[row][col] / p;
            for k in col..COEFFS {
                a[row][k] -= factor * a[col][k];
            }
            for c in 0..3 {
                b[row][c] -= factor * b[col][c];
            }
        }
    }
    let mut x = [[0.0f64; 3]; COEFFS];
    for row in (0..COEFFS).rev() {
        for c in 0..3 {
            let rest: f64 = (row + 1..COEFFS).map(|k| a[row][k] * x[k][c]).sum();
            x[row][c] = if a[row][row].abs() < 1e-12 { 0.0 } else { (b[row][c] - rest) / a[row][row] };
        }
    }
    x.iter().flat_map(|c| c.map(|v| v as f32)).collect()
}

/// Mean PSNR of `export`'s renders against the anchor model's from `cameras` (colors clamped to
/// [0, 1]): how faithful the export is.
pub fn agreement_psnr(model: &AnchorModel, export: &Gaussians, cameras: &[Camera], options: &RenderOptions) -> f64 {
    let psnr = |camera: &Camera| {
        let reference = render(&model.gaussians_for(camera), camera, options);
        let exported = render(export, camera, options);
        let mse = reference.data.iter().zip(&exported.data).map(|(a, b)| {
            let d = f64::from(a.clamp(0.0, 1.0) - b.clamp(0.0, 1.0));
            d * d
        });
        let mse = mse.sum::<f64>() / reference.data.len().max(1) as f64;
        -10.0 * mse.max(1e-12).log10()
    };
    cameras.iter().map(psnr).sum::<f64>() / cameras.len().max(1) as f64
}

/// Cameras around the model when no views are given: `count` on a sphere (Fibonacci lattice)
/// of `radius` around `center`, looking at it.
pub fn sphere_cameras(center: [f32; 3], radius: f32, count: usize, size: u32) -> Vec<Camera> {
    let center = glam::Vec3::from(center);
    let f = size as f32;
    let intrinsics = pwgs_core::camera::Intrinsics {
        width: size,
        height: size,
        fx: f,
        fy: f,
        cx: size as f32 / 2.0,
        cy: size as f32 / 2.0,
    };
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..count)
        .filter_map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let r = (1.0 - y * y).sqrt();
            let t = golden * i as f32;
            let eye = center + radius * glam::Vec3::new(r * t.cos(), y, r * t.sin());
            let up = if y.abs() > 0.99 { glam::Vec3::Z } else { glam::Vec3::Y };
            Camera::look_at(intrinsics, eye, center, up).ok()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::sh::unclamped_color;

    #[test]
    fn the_sh_fit_recovers_a_color_that_is_sh() {
        // Samples of a degree-1 color field over many directions, fitted at degree 3.
        let truth: Vec<f32> = vec![0.4, -0.2, 0.1, 0.05, 0.0, -0.1, 0.0, 0.2, 0.0, -0.1, 0.0, 0.0];
        let mut s = Seen::default();
        for i in 0..200 {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / 200.0;
            let r = (1.0 - y * y).sqrt();
            let t = 2.399_963 * i as f64;
            let d = [r * t.cos(), y, r * t.sin()];
            let rgb = unclamped_color(1, &truth, d);
            let b = basis(EXPORT_DEGREE, d);
            for i in 0..COEFFS {
                for j in 0..COEFFS {
                    s.gram[i][j] += b[i] * b[j];
                }
                for c in 0..3 {
                    s.moment[i][c] += b[i] * (rgb[c] - 0.5);
                }
            }
        }
        let fitted = fit_sh(&s);
        for (k, (a, b)) in fitted.iter().zip(truth.iter().chain(std::iter::repeat(&0.0))).enumerate() {
            assert!((a - b).abs() < 0.01, "coefficient {k}: {a} vs {b}");
        }
    }
}

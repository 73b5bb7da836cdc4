//! Shared test scaffolding: a deterministic random number generator, random Gaussian scenes
//! and cameras, and the naive reference renderer.
#![allow(dead_code, unused_imports)] // each test binary (and the benchmark) uses a different part

use glam::{DMat3, DVec3};
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::rgb_image::RgbImage;
use pwgs_render::raster::RenderOptions;
use pwgs_render::raster::sh;

pub use pwgs_core::random::{SplitMix64 as Rng, axis_camera as camera};

/// Random scenes as the rasterizer tests use them: log-scales in [-4, -1.5].
pub fn random_gaussians(rng: &mut Rng, n: usize, degree: u32) -> Gaussians {
    pwgs_core::random::random_gaussians(rng, n, degree, [-4.0, -1.5])
}

/// The naive reference renderer: for every pixel, every Gaussian, in f64, depth-sorted, no
/// tiles, no bounding boxes. It restates the projection with full matrices (J W Sigma W^T J^T)
/// and shares with the real rasterizer only the SH basis and the constants.
pub fn naive_render(g: &Gaussians, cam: &Camera, options: &RenderOptions) -> (RgbImage, Vec<f64>) {
    struct P {
        mean: [f64; 2],
        inv: [f64; 3],
        opacity: f64,
        color: [f64; 3],
        depth: f64,
    }
    let w2c = cam.rotation.as_dmat3();
    let t = cam.translation.as_dvec3();
    let center = cam.center().as_dvec3();
    let settings = &options.projection;
    let mut ps: Vec<(P, usize)> = Vec::new();
    for i in 0..g.len() {
        let mean = DVec3::from(g.means[i].map(f64::from));
        let p_cam = w2c * mean + t;
        let q = g.rotations[i].map(f64::from);
        let qn = (q.iter().map(|v| v * v).sum::<f64>()).sqrt();
        if !(p_cam.z >= settings.near) || !(qn > 1e-8) {
            continue;
        }
        let [w, x, y, z] = q.map(|v| v / qn);
        let r = DMat3::from_cols_array(&[
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y + w * z),
            2.0 * (x * z - w * y),
            2.0 * (x * y - w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z + w * x),
            2.0 * (x * z + w * y),
            2.0 * (y * z - w * x),
            1.0 - 2.0 * (x * x + y * y),
        ]);
        let s = DMat3::from_diagonal(DVec3::from(g.log_scales[i].map(|v| (v as f64).exp())));
        let sigma = r * s * s * r.transpose();
        let (fx, fy) = (cam.fx as f64, cam.fy as f64);
        let lim = |c: f64, size: f64, f: f64| (-(c / f) - 0.15 * size / f, (size - c) / f + 0.15 * size / f);
        let (lx0, lx1) = lim(cam.cx as f64, cam.width as f64, fx);
        let (ly0, ly1) = lim(cam.cy as f64, cam.height as f64, fy);
        // Guard band: centers more than one image size outside the image are culled.
        let (gx, gy) = (cam.width as f64 / fx, cam.height as f64 / fy);
        let (ux, uy) = (p_cam.x / p_cam.z, p_cam.y / p_cam.z);
        let (left, right) = (-(cam.cx as f64) / fx, (cam.width as f64 - cam.cx as f64) / fx);
        let (top, bottom) = (-(cam.cy as f64) / fy, (cam.height as f64 - cam.cy as f64) / fy);
        if !(ux >= left - gx && ux <= right + gx && uy >= top - gy && uy <= bottom + gy) {
            continue;
        }
        let tx = (p_cam.x / p_cam.z).clamp(lx0, lx1) * p_cam.z;
        let ty = (p_cam.y / p_cam.z).clamp(ly0, ly1) * p_cam.z;
        let zz = p_cam.z;
        // J as a 3x3 with a zero last row, so the product stays in glam types.
        let j = DMat3::from_cols(
            DVec3::new(fx / zz, 0.0, 0.0),
            DVec3::new(0.0, fy / zz, 0.0),
            DVec3::new(-fx * tx / (zz * zz), -fy * ty / (zz * zz), 0.0),
        );
        let cov = j * w2c * sigma * w2c.transpose() * j.transpose();
        let (a, b, c) = (cov.x_axis.x + settings.blur, cov.y_axis.x, cov.y_axis.y + settings.blur);
        let det = a * c - b * b;
        let l = g.opacity_logits[i] as f64;
        let opacity = 1.0 / (1.0 + (-l).exp());
        let dir = (mean - center).normalize();
        let coeffs = g.sh_of(i);
        let basis = sh::basis(g.sh_degree, dir.to_array());
        let mut color = [0.5f64; 3];
        for (k, chunk) in coeffs.chunks_exact(3).enumerate() {
            for ch in 0..3 {
                color[ch] += basis[k] * chunk[ch] as f64;
            }
        }
        let p = P {
            mean: [fx * p_cam.x / zz + cam.cx as f64, fy * p_cam.y / zz + cam.cy as f64],
            inv: [c / det, -b / det, a / det],
            opacity,
            color: color.map(|v| v.max(0.0)),
            depth: zz,
        };
        ps.push((p, i));
    }
    ps.sort_by(|a, b| a.0.depth.total_cmp(&b.0.depth).then(a.1.cmp(&b.1)));
    let mut img = RgbImage::filled(cam.width, cam.height, [0.0; 3]);
    let mut trans = vec![1.0f64; img.pixel_count()];
    for py in 0..cam.height {
        for px in 0..cam.width {
            let (u, v) = (px as f64 + 0.5, py as f64 + 0.5);
            let mut tr = 1.0f64;
            let mut rgb = [0.0f64; 3];
            for (p, _) in &ps {
                let (dx, dy) = (p.mean[0] - u, p.mean[1] - v);
                let sigma = 0.5 * (p.inv[0] * dx * dx + p.inv[2] * dy * dy) + p.inv[1] * dx * dy;
                if sigma < 0.0 {
                    continue;
                }
                let raw = p.opacity * (-sigma).exp();
                if raw < settings.alpha_min {
                    continue;
                }
                let alpha = raw.min(options.alpha_max as f64);
                let next = tr * (1.0 - alpha);
                if next <= options.transmittance_min as f64 {
                    break;
                }
                for ch in 0..3 {
                    rgb[ch] += p.color[ch] * alpha * tr;
                }
                tr = next;
            }
            let bg = options.background;
            img.set_pixel(px, py, std::array::from_fn(|ch| (rgb[ch] + tr * bg[ch] as f64) as f32));
            trans[(py * cam.width + px) as usize] = tr;
        }
    }
    (img, trans)
}

/// Largest absolute difference between two images of the same size.
pub fn max_abs_diff(a: &RgbImage, b: &RgbImage) -> f32 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.data.iter().zip(&b.data).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

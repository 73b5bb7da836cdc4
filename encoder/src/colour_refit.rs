//! Colours refitted to the quantized geometry (`pwenc --from X --importance-classes
//! --refit-colours`). Once positions, scales, rotations and opacities are quantized (and faint
//! Gaussians pruned), the colours that render closest to the model are no longer the model's:
//! a neighbour's colour can make up for a Gaussian that moved or went. With the geometry held,
//! a render is linear in the Gaussians' colours (each pixel is `sum T alpha c` plus the
//! background), so the best colours on a set of views solve a linear least-squares problem:
//! conjugate gradients on its normal equations (CGLS, with the normal matrix's diagonal as
//! preconditioner), each iteration one pass of the map and one of its adjoint over every view.
//! The refitted colours then go through the same quantizer as any other; nothing in the
//! stream changes but their values (point-cloud codecs call this recolouring).

use pwgs_decoder::camera::Camera;
use pwgs_decoder::gaussians::{Gaussians, SH_C0};
use pwgs_decoder::raster::blend::ColourMap;
use pwgs_decoder::raster::{RenderOptions, Rendered, rasterize, render};
use rayon::prelude::*;
use serde::Serialize;

use crate::compress::{Coding, CompressError, StreamContext, reconstruction};

/// What a refit did, on its views: the mean squared error of the reconstruction's renders
/// against the model's before, and of the linear model after each iteration.
#[derive(Debug, Clone, Serialize)]
pub struct RefitOutcome {
    pub views: usize,
    pub gaussians: usize,
    pub mse_before: f64,
    pub mse_after: Vec<f64>,
}

/// `g` with the colours (the SH DC terms) of the Gaussians `coding` keeps refitted, over
/// `iterations` iterations, so that the reconstruction renders closest to `g` on `cameras`.
pub fn refit_colours(
    g: &Gaussians,
    coding: Coding,
    context: &StreamContext,
    (cameras, options): (&[Camera], &RenderOptions),
    iterations: usize,
) -> Result<(Gaussians, RefitOutcome), CompressError> {
    let (keep, decoded) = reconstruction(g, coding, context)?;
    let n = decoded.len();
    let (geometry, mut residuals): (Vec<_>, Vec<Vec<f32>>) = cameras
        .par_iter()
        .map(|camera| {
            // The decoded model's render and the splats and bins it came from, which the map walks.
            let Rendered { color, splats, bins, .. } = rasterize(&decoded, camera, options);
            let target = render(g, camera, options);
            let residual: Vec<f32> = target.data.iter().zip(&color.data).map(|(t, c)| t - c).collect();
            ((splats, bins), residual)
        })
        .unzip();
    let maps: Vec<ColourMap> = geometry.iter().map(|(splats, bins)| ColourMap { bins, splats, options }).collect();
    let values = residuals.iter().map(Vec::len).sum::<usize>().max(1) as f64;
    let mse = |images: &[Vec<f32>]| images.iter().flatten().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>() / values;
    let mse_before = mse(&residuals);

    // Sums over the views in view order, so that the result does not depend on threads.
    let transpose = |images: &[Vec<f32>]| {
        let parts: Vec<_> = maps.par_iter().zip(images).map(|(m, image)| m.transpose(image, n)).collect();
        let mut sums = vec![[0.0f32; 3]; n];
        let mut squares = vec![0.0f32; n];
        for (s, q) in parts {
            sums.iter_mut().zip(s).for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(a, b)| *a += b));
            squares.iter_mut().zip(q).for_each(|(a, b)| *a += b);
        }
        (sums, squares)
    };
    let precondition = |s: &[[f32; 3]], diagonal: &[f32]| -> Vec<[f32; 3]> {
        s.iter().zip(diagonal).map(|(s, &d)| if d > 0.0 { s.map(|v| v / d) } else { [0.0; 3] }).collect()
    };
    let dot = |a: &[[f32; 3]], b: &[[f32; 3]]| -> [f64; 3] {
        let mut out = [0.0f64; 3];
        for (a, b) in a.iter().zip(b) {
            (0..3).for_each(|c| out[c] += f64::from(a[c]) * f64::from(b[c]));
        }
        out
    };

    let mut change = vec![[0.0f32; 3]; n];
    let (s, diagonal) = transpose(&residuals);
    let mut z = precondition(&s, &diagonal);
    let mut direction = z.clone();
    let mut gamma = dot(&s, &z);
    let mut mse_after = Vec::with_capacity(iterations);
    for _ in 0..iterations {
        let images: Vec<Vec<f32>> = maps.par_iter().map(|m| m.apply(&direction)).collect();
        let mut energy = [0.0f64; 3];
        for (i, v) in images.iter().flatten().enumerate() {
            energy[i % 3] += f64::from(*v) * f64::from(*v);
        }
        let step: [f32; 3] = std::array::from_fn(|c| if energy[c] > 0.0 { (gamma[c] / energy[c]) as f32 } else { 0.0 });
        for (x, p) in change.iter_mut().zip(&direction) {
            (0..3).for_each(|c| x[c] += step[c] * p[c]);
        }
        for (r, q) in residuals.iter_mut().zip(&images) {
            r.iter_mut().zip(q).enumerate().for_each(|(i, (r, q))| *r -= step[i % 3] * q);
        }
        mse_after.push(mse(&residuals));
        let (s, _) = transpose(&residuals);
        z = precondition(&s, &diagonal);
        let next = dot(&s, &z);
        let beta: [f32; 3] = std::array::from_fn(|c| if gamma[c] > 0.0 { (next[c] / gamma[c]) as f32 } else { 0.0 });
        for (p, z) in direction.iter_mut().zip(&z) {
            (0..3).for_each(|c| p[c] = z[c] + beta[c] * p[c]);
        }
        gamma = next;
    }

    let mut refitted = g.clone();
    let per_gaussian = g.coeffs_per_channel() * 3;
    for (r, &i) in keep.iter().enumerate() {
        for c in 0..3 {
            refitted.sh[i * per_gaussian + c] = decoded.sh_of(r)[c] + change[r][c] / SH_C0;
        }
    }
    Ok((refitted, RefitOutcome { views: cameras.len(), gaussians: n, mse_before, mse_after }))
}

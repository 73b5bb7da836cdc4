//! Colours refitted to the quantized geometry (`pwenc --from X --importance-classes
//! --refit-colours`). Once positions, scales, rotations and opacities are quantized (and faint
//! Gaussians pruned), the colours that render closest to the model are no longer the model's:
//! a neighbour's colour can make up for a Gaussian that moved or went. With the geometry held,
//! a render is linear in the Gaussians' colours (each pixel is `sum T alpha c` plus the
//! background), so the best colours on a set of views solve a linear least-squares problem:
//! conjugate gradients on its normal equations (CGLS, with the normal matrix's diagonal as
//! preconditioner), each iteration one pass of the map and one of its adjoint over every view.
//! The refitted colours are then rounded in turns: part of them to what the stream will hold,
//! the rest refitted to make up for it, and so on; the last part goes through the quantizer
//! like any other value. Nothing in the stream changes but the colours' values (point-cloud
//! codecs call this recolouring).

use pwgs_core::camera::Camera;
use pwgs_core::gaussians::{Gaussians, SH_C0};
use pwgs_render::raster::blend::ColourMap;
use pwgs_render::raster::{RenderOptions, Rendered, rasterize, render};
use rayon::prelude::*;
use serde::Serialize;

use crate::plain::compress::{Coding, CompressError, StreamContext, reconstruction};

/// What a refit did, on its views: the mean squared error of the reconstruction's renders
/// against the model's before, and of the linear model after each iteration (those after
/// each rounding turn included).
#[derive(Debug, Clone, Serialize)]
pub struct RefitOutcome {
    pub views: usize,
    pub gaussians: usize,
    pub mse_before: f64,
    pub mse_after: Vec<f64>,
}

/// How hard a refit works: CGLS iterations, then the turns in which the refitted colours are
/// rounded, with [`TURN_ITERATIONS`] after each turn but the last. Each iteration is a pass of
/// the colour map and one of its adjoint over every view; a turn costs a reconstruction too.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct ColourRefit {
    pub iterations: usize,
    /// 1: the refitted colours go through the quantizer at once.
    pub rounding_turns: usize,
}

impl ColourRefit {
    /// CGLS iterations in all, those after the rounding turns included.
    pub fn steps(&self) -> usize {
        self.iterations + (self.rounding_turns.max(1) - 1) * TURN_ITERATIONS
    }
}

/// `g` with the colours (the SH DC terms) of the Gaussians `coding` keeps refitted as `refit`
/// says, so that its reconstruction renders closest to `reference` on `cameras`: the model
/// itself, or the input when `g` is already refitted ([`crate::plain::shape_refit`]) and no
/// longer renders like it. `done` is called after each CGLS iteration (a progress bar's tick;
/// [`ColourRefit::steps`] in all).
pub fn refit_colours(
    (g, reference): (&Gaussians, &Gaussians),
    coding: Coding,
    context: &StreamContext,
    (cameras, options): (&[Camera], &RenderOptions),
    (refit, done): (ColourRefit, &dyn Fn()),
) -> Result<(Gaussians, RefitOutcome), CompressError> {
    let turns = refit.rounding_turns.max(1);
    let (keep, decoded) = reconstruction(g, coding, context)?;
    let n = decoded.len();
    let (geometry, mut residuals): (Vec<_>, Vec<Vec<f32>>) = cameras
        .par_iter()
        .map(|camera| {
            // The decoded model's render and the splats and bins it came from, which the map walks.
            let Rendered { color, splats, bins, .. } = rasterize(&decoded, camera, options);
            let target = render(reference, camera, options);
            let residual: Vec<f32> = target.data.iter().zip(&color.data).map(|(t, c)| t - c).collect();
            ((splats, bins), residual)
        })
        .unzip();
    let maps: Vec<ColourMap> = geometry.iter().map(|(splats, bins)| ColourMap { bins, splats, options }).collect();
    let mut fit = LinearFit::new(&maps, n, &residuals);
    let mse_before = fit.mse(&residuals);

    // The colour changes being fitted, and the colours already rounded (None: still free).
    let mut change = vec![[0.0f32; 3]; n];
    let mut rounded: Vec<Option<[f32; 3]>> = vec![None; n];
    fit.cgls(&mut change, &mut residuals, &rounded, (refit.iterations, done));
    // Rounding in turns: each turn rounds every `turns`-th of the free colours to what the
    // stream will hold, takes what that moved out of the residuals and refits the rest, which
    // make up for it; the last turn's colours are rounded by the stream itself.
    for turn in 0..turns - 1 {
        // Colours change neither which Gaussians a stream keeps nor their order.
        let coded = reconstruction(&with_colours(g, (&keep, &decoded), &change, &rounded), coding, context)?.1;
        let mut moved = vec![[0.0f32; 3]; n];
        for r in (turn..n).step_by(turns) {
            let value: [f32; 3] = coded.sh_of(r)[..3].try_into().expect("three DC terms");
            let target: [f32; 3] = std::array::from_fn(|c| (value[c] - decoded.sh_of(r)[c]) * SH_C0);
            moved[r] = std::array::from_fn(|c| target[c] - change[r][c]);
            change[r] = target;
            rounded[r] = Some(value);
        }
        let shifts: Vec<Vec<f32>> = maps.par_iter().map(|m| m.apply(&moved)).collect();
        for (r, q) in residuals.iter_mut().zip(&shifts) {
            r.iter_mut().zip(q).for_each(|(r, q)| *r -= q);
        }
        fit.cgls(&mut change, &mut residuals, &rounded, (TURN_ITERATIONS, done));
    }
    let refitted = with_colours(g, (&keep, &decoded), &change, &rounded);
    let mse_after = fit.mse_after;
    Ok((refitted, RefitOutcome { views: cameras.len(), gaussians: n, mse_before, mse_after }))
}

/// The least-squares problem over every view's colour map: CGLS with the normal matrix's
/// diagonal as preconditioner, over the colours still free.
struct LinearFit<'a> {
    maps: &'a [ColourMap<'a>],
    gaussians: usize,
    /// Values (pixels times channels) over all views.
    values: f64,
    /// The normal matrix's diagonal: per Gaussian, its squared blending weights summed (from
    /// the first adjoint pass).
    diagonal: Vec<f32>,
    /// The mean squared residual after each iteration.
    mse_after: Vec<f64>,
}

impl<'a> LinearFit<'a> {
    fn new(maps: &'a [ColourMap<'a>], gaussians: usize, residuals: &[Vec<f32>]) -> Self {
        let values = residuals.iter().map(Vec::len).sum::<usize>().max(1) as f64;
        Self { maps, gaussians, values, diagonal: Vec::new(), mse_after: Vec::new() }
    }

    fn mse(&self, images: &[Vec<f32>]) -> f64 {
        images.iter().flatten().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>() / self.values
    }

    /// The adjoint of every view's map applied to `images`, summed over the views in view
    /// order so that the result does not depend on threads, and the squared weights' sums.
    fn transpose(&self, images: &[Vec<f32>]) -> (Vec<[f32; 3]>, Vec<f32>) {
        let n = self.gaussians;
        let parts: Vec<_> = self.maps.par_iter().zip(images).map(|(m, image)| m.transpose(image, n)).collect();
        let mut sums = vec![[0.0f32; 3]; n];
        let mut squares = vec![0.0f32; n];
        for (s, q) in parts {
            sums.iter_mut().zip(s).for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(a, b)| *a += b));
            squares.iter_mut().zip(q).for_each(|(a, b)| *a += b);
        }
        (sums, squares)
    }

    /// The preconditioned gradient: zero for the colours already rounded.
    fn precondition(&self, s: &[[f32; 3]], rounded: &[Option<[f32; 3]>]) -> Vec<[f32; 3]> {
        s.iter()
            .zip(&self.diagonal)
            .zip(rounded)
            .map(|((s, &d), rounded)| if rounded.is_none() && d > 0.0 { s.map(|v| v / d) } else { [0.0; 3] })
            .collect()
    }

    /// Every view's map applied to `direction`, and the adjoint of each applied to its image,
    /// summed over the views in view order.
    fn apply_and_normal(&self, direction: &[[f32; 3]]) -> (Vec<Vec<f32>>, Vec<[f32; 3]>) {
        let n = self.gaussians;
        let parts: Vec<_> = self.maps.par_iter().map(|m| m.apply_and_normal(direction, n)).collect();
        let mut normal = vec![[0.0f32; 3]; n];
        let images = parts
            .into_iter()
            .map(|(image, part)| {
                normal.iter_mut().zip(part).for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(a, b)| *a += b));
                image
            })
            .collect();
        (images, normal)
    }

    /// `iterations` of CGLS from `change`, moving the free colours and the `residuals` with them.
    /// The adjoint of the residuals is carried along (`A^T r` less the step times `A^T A p`), so
    /// that an iteration walks each view once.
    fn cgls(
        &mut self,
        change: &mut [[f32; 3]],
        residuals: &mut [Vec<f32>],
        rounded: &[Option<[f32; 3]>],
        (iterations, done): (usize, &dyn Fn()),
    ) {
        let (mut s, squares) = self.transpose(residuals);
        if self.diagonal.is_empty() {
            self.diagonal = squares;
        }
        let mut z = self.precondition(&s, rounded);
        let mut direction = z.clone();
        let mut gamma = dot(&s, &z);
        for _ in 0..iterations {
            let (images, normal) = self.apply_and_normal(&direction);
            let mut energy = [0.0f64; 3];
            for (i, v) in images.iter().flatten().enumerate() {
                energy[i % 3] += f64::from(*v) * f64::from(*v);
            }
            let step: [f32; 3] =
                std::array::from_fn(|c| if energy[c] > 0.0 { (gamma[c] / energy[c]) as f32 } else { 0.0 });
            for (x, p) in change.iter_mut().zip(&direction) {
                (0..3).for_each(|c| x[c] += step[c] * p[c]);
            }
            for (r, q) in residuals.iter_mut().zip(&images) {
                r.iter_mut().zip(q).enumerate().for_each(|(i, (r, q))| *r -= step[i % 3] * q);
            }
            self.mse_after.push(self.mse(residuals));
            for (s, q) in s.iter_mut().zip(&normal) {
                (0..3).for_each(|c| s[c] -= step[c] * q[c]);
            }
            z = self.precondition(&s, rounded);
            let next = dot(&s, &z);
            let beta: [f32; 3] =
                std::array::from_fn(|c| if gamma[c] > 0.0 { (next[c] / gamma[c]) as f32 } else { 0.0 });
            for (p, z) in direction.iter_mut().zip(&z) {
                (0..3).for_each(|c| p[c] = z[c] + beta[c] * p[c]);
            }
            gamma = next;
            done();
        }
    }
}

/// Per channel, the dot product of two colour vectors.
fn dot(a: &[[f32; 3]], b: &[[f32; 3]]) -> [f64; 3] {
    let mut out = [0.0f64; 3];
    for (a, b) in a.iter().zip(b) {
        (0..3).for_each(|c| out[c] += f64::from(a[c]) * f64::from(b[c]));
    }
    out
}

/// The refit of `pwenc --refit-colours` and the highest effort levels. On biker (quality 11,
/// 57 views) rounding in halves with 3 iterations between lifts the orbit's PSNR by 0.19 dB, in
/// quarters by 0.28 dB, for 0.1-0.2% more bytes and about twice the refit's time.
pub const FULL_REFIT: ColourRefit = ColourRefit { iterations: 8, rounding_turns: 4 };
/// Iterations refitting the free colours after each turn's rounding.
const TURN_ITERATIONS: usize = 3;

/// `g` with the colours (SH DC terms) of the Gaussians `keep` set to the decoded ones plus
/// `change` (in rendered colour, hence the division by the DC basis constant), or to the
/// value they were rounded to, exactly, so that the stream codes that value.
fn with_colours(
    g: &Gaussians,
    (keep, decoded): (&[usize], &Gaussians),
    change: &[[f32; 3]],
    rounded: &[Option<[f32; 3]>],
) -> Gaussians {
    let mut refitted = g.clone();
    let per_gaussian = g.coeffs_per_channel() * 3;
    for (r, &i) in keep.iter().enumerate() {
        let value = rounded[r].unwrap_or_else(|| std::array::from_fn(|c| decoded.sh_of(r)[c] + change[r][c] / SH_C0));
        refitted.sh[i * per_gaussian..i * per_gaussian + 3].copy_from_slice(&value);
    }
    refitted
}

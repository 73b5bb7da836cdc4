//! Front-to-back alpha blending of the splats of each tile.
//!
//! Per pixel: alpha = min(alpha_max, opacity * exp(-sigma)); splats with alpha < alpha_min
//! are skipped; blending stops before a splat that would bring the
//! transmittance to transmittance_min or below. Each pixel's sum runs in the tiles' fixed
//! front-to-back order on one thread, so the image is bit-identical for any thread count.

use super::project::Splat;
use super::tiles::{ListOrder, TileBins};
use super::{Cutoff, RenderOptions, TILE_SIZE, linear_simd};
use pwgs_codec::portable_math::exp_f32;

const TILE_PIXELS: usize = (TILE_SIZE * TILE_SIZE) as usize;

/// Width of the smoothstep that replaces the hard alpha_min cutoff in [`Cutoff::Smooth`].
pub const SMOOTH_CUTOFF_BAND: f32 = 1e-3;

/// A splat evaluated at a pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlphaSample {
    /// The alpha blended.
    pub alpha: f32,
    /// exp(-sigma), the Gaussian's falloff at the pixel.
    pub falloff: f32,
}

/// Alpha of a splat at offset (dx, dy) from its center, or `None` when it does not contribute.
/// The backward pass calls this too, so both passes take exactly the same decisions.
#[inline]
pub fn splat_alpha(s: &Splat, dx: f32, dy: f32, options: &RenderOptions) -> Option<AlphaSample> {
    let [l11, l21, l22] = s.cholesky;
    let (p, q) = (l11 * dx + l21 * dy, l22 * dy);
    let falloff = exp_f32(-0.5 * (p * p + q * q));
    let raw = s.opacity * falloff;
    let alpha_min = options.projection.alpha_min as f32;
    if raw < alpha_min {
        return None;
    }
    let alpha = raw.min(options.alpha_max);
    let alpha = match options.cutoff {
        Cutoff::Hard => alpha,
        Cutoff::Smooth => {
            let t = ((raw - alpha_min) / SMOOTH_CUTOFF_BAND).min(1.0);
            alpha * t * t * (3.0 - 2.0 * t)
        }
    };
    Some(AlphaSample { alpha, falloff })
}

/// Output buffers for one band of tiles (TILE_SIZE rows of the window).
pub struct Band<'a> {
    pub color: &'a mut [f32],
    pub transmittance: &'a mut [f32],
    pub depth: &'a mut [f32],
    pub last_contributor: &'a mut [u32],
}

/// Walks tile `t`'s splats front to back over its pixels with the blending decisions (alpha
/// from [`splat_alpha`], the stop before the transmittance falls to its minimum), calling
/// `blend(k, splat, p, alpha, T)` for each splat blended into a pixel (`k` its position in the
/// tile's list, `p` the pixel within the tile, row by row, `T` the transmittance before it),
/// and returns every pixel's final transmittance.
fn walk_tile(
    bins: &TileBins,
    t: usize,
    splats: &[Splat],
    options: &RenderOptions,
    mut blend: impl FnMut(usize, &Splat, usize, f32, f32),
) -> [f32; TILE_PIXELS] {
    let [x0, x1, y0, y1] = bins.tile_rect(t);
    let tw = (x1 - x0) as usize;
    let mut trans = [1.0f32; TILE_PIXELS];
    let mut done = [false; TILE_PIXELS];
    let mut remaining = tw * (y1 - y0) as usize;
    let mut list = bins.splats(t, splats, ListOrder::FrontToBack);
    'tile: while let Some(block) = list.next_block() {
        for &(k, ref s) in block {
            if remaining == 0 {
                break 'tile;
            }
            let [bx0, bx1, by0, by1] = s.bbox;
            for py in by0.max(y0)..by1.min(y1) {
                let dy = s.mean[1] - (py as f32 + 0.5);
                for px in bx0.max(x0)..bx1.min(x1) {
                    let p = (py - y0) as usize * tw + (px - x0) as usize;
                    if done[p] {
                        continue;
                    }
                    let dx = s.mean[0] - (px as f32 + 0.5);
                    let Some(AlphaSample { alpha, .. }) = splat_alpha(s, dx, dy, options) else { continue };
                    let next = trans[p] * (1.0 - alpha);
                    if next <= options.transmittance_min {
                        done[p] = true;
                        remaining -= 1;
                        continue;
                    }
                    blend(k, s, p, alpha, trans[p]);
                    trans[p] = next;
                }
            }
        }
    }
    trans
}

/// Blends tile row `ty` into `band`. Pixel coordinates are the image's, whatever the window,
/// so a window's pixels are bit-identical to the same pixels of the whole image.
pub fn blend_band(ty: u32, bins: &TileBins, splats: &[Splat], options: &RenderOptions, band: Band) {
    let window = bins.window;
    for tx in 0..bins.tiles_x {
        let t = (ty * bins.tiles_x + tx) as usize;
        let [x0, x1, y0, y1] = bins.tile_rect(t);
        let tw = (x1 - x0) as usize;
        let mut rgb = [[0.0f32; 3]; TILE_PIXELS];
        let mut depth = [0.0f32; TILE_PIXELS];
        let mut last = [0u32; TILE_PIXELS];
        let trans = walk_tile(bins, t, splats, options, |k, s, p, alpha, trans| {
            let weight = alpha * trans;
            for c in 0..3 {
                rgb[p][c] += s.color[c] * weight;
            }
            depth[p] += s.depth * weight;
            last[p] = k as u32 + 1;
        });
        for py in y0..y1 {
            for px in x0..x1 {
                let p = (py - y0) as usize * tw + (px - x0) as usize;
                // The band starts at the tile's first row.
                let o = (py - y0) as usize * window.width as usize + (px - window.x0) as usize;
                for c in 0..3 {
                    band.color[o * 3 + c] = rgb[p][c] + trans[p] * options.background[c];
                }
                band.transmittance[o] = trans[p];
                let covered = 1.0 - trans[p];
                band.depth[o] = if covered > 0.0 { depth[p] / covered } else { 0.0 };
                band.last_contributor[o] = last[p];
            }
        }
    }
}

/// Each Gaussian's summed blending weight over the bins' window, `sum T * alpha` over the
/// pixels its splat is blended into (what it adds to the image per unit of colour), for
/// Gaussians `0 .. gaussians` (0 for those without a splat), on the blend path `options` names:
/// the same decisions as that path's blend. Tiles in order on one thread, so the sums do not
/// depend on threads.
pub fn splat_weights(bins: &TileBins, splats: &[Splat], options: &RenderOptions, gaussians: usize) -> Vec<f32> {
    match options.blend.vector_lanes() {
        None => scalar_weights(bins, splats, options, gaussians),
        Some(portable) => linear_simd::splat_weights(bins, splats, options, gaussians, portable),
    }
}

/// [`splat_weights`] one pixel at a time, with [`blend_band`]'s decisions.
fn scalar_weights(bins: &TileBins, splats: &[Splat], options: &RenderOptions, gaussians: usize) -> Vec<f32> {
    let mut weights = vec![0.0f32; gaussians];
    for t in 0..(bins.tiles_x * bins.tiles_y) as usize {
        walk_tile(bins, t, splats, options, |_, s, _, alpha, trans| weights[s.index as usize] += alpha * trans);
    }
    weights
}

/// The blending weights `w = T * alpha` as a linear map from per-Gaussian colours to an
/// image (the image is `sum w c` plus the background times the final transmittance), for
/// fitting colours to a target with the geometry held: [`apply`](Self::apply) is the map,
/// [`transpose`](Self::transpose) its adjoint. Both walk the tiles with [`blend_band`]'s
/// decisions, in order on one thread, so their sums do not depend on threads.
pub struct ColourMap<'a> {
    pub bins: &'a TileBins,
    pub splats: &'a [Splat],
    pub options: &'a RenderOptions,
}

impl ColourMap<'_> {
    /// Visits each blended (pixel index in the window, splat, weight).
    fn walk(&self, mut visit: impl FnMut(usize, &Splat, f32)) {
        let window = self.bins.window;
        for t in 0..(self.bins.tiles_x * self.bins.tiles_y) as usize {
            let [x0, x1, y0, _] = self.bins.tile_rect(t);
            let tw = (x1 - x0) as usize;
            walk_tile(self.bins, t, self.splats, self.options, |_, s, p, alpha, trans| {
                let (x, y) = ((x0 - window.x0) as usize + p % tw, (y0 - window.y0) as usize + p / tw);
                visit(y * window.width as usize + x, s, alpha * trans);
            });
        }
    }

    /// The image `sum w values[i]` over the window (no background), RGB interleaved, on the
    /// blend path the options name.
    pub fn apply(&self, values: &[[f32; 3]]) -> Vec<f32> {
        let (bins, splats, options) = (self.bins, self.splats, self.options);
        match options.blend.vector_lanes() {
            None => self.scalar_apply(values),
            Some(portable) => linear_simd::colour_map_apply(bins, splats, options, values, portable),
        }
    }

    /// Per Gaussian (`0 .. gaussians`), `sum w image` over the pixels it is blended into, and
    /// `sum w^2` (the diagonal of the map's normal matrix), on the blend path the options name.
    pub fn transpose(&self, image: &[f32], gaussians: usize) -> (Vec<[f32; 3]>, Vec<f32>) {
        let (bins, splats, options) = (self.bins, self.splats, self.options);
        match options.blend.vector_lanes() {
            None => self.scalar_transpose(image, gaussians),
            Some(portable) => linear_simd::colour_map_transpose(bins, splats, options, (image, gaussians), portable),
        }
    }

    /// The map applied to `values`, and its adjoint applied to that image: `(A v, A^T A v)`
    /// for Gaussians `0 .. gaussians`. On the vector lanes in one walk (the falloffs evaluated
    /// once); on the scalar path as [`apply`](Self::apply) then [`transpose`](Self::transpose).
    pub fn apply_and_normal(&self, values: &[[f32; 3]], gaussians: usize) -> (Vec<f32>, Vec<[f32; 3]>) {
        let (bins, splats, options) = (self.bins, self.splats, self.options);
        match options.blend.vector_lanes() {
            None => {
                let image = self.scalar_apply(values);
                let normal = self.scalar_transpose(&image, gaussians).0;
                (image, normal)
            }
            Some(portable) => linear_simd::colour_map_normal(bins, splats, options, (values, gaussians), portable),
        }
    }

    /// [`apply`](Self::apply) one pixel at a time.
    fn scalar_apply(&self, values: &[[f32; 3]]) -> Vec<f32> {
        let w = self.bins.window;
        let mut image = vec![0.0f32; w.width as usize * w.height as usize * 3];
        self.walk(|p, s, weight| {
            let v = values[s.index as usize];
            image[p * 3..p * 3 + 3].iter_mut().zip(v).for_each(|(o, v)| *o += weight * v);
        });
        image
    }

    /// [`transpose`](Self::transpose) one pixel at a time.
    fn scalar_transpose(&self, image: &[f32], gaussians: usize) -> (Vec<[f32; 3]>, Vec<f32>) {
        let mut sums = vec![[0.0f32; 3]; gaussians];
        let mut squares = vec![0.0f32; gaussians];
        self.walk(|p, s, weight| {
            let i = s.index as usize;
            sums[i].iter_mut().zip(&image[p * 3..p * 3 + 3]).for_each(|(o, v)| *o += weight * v);
            squares[i] += weight * weight;
        });
        (sums, squares)
    }
}

//! Tile lists that end where their tile is surely opaque: the colour-only render's binning.
//!
//! Blending stops at a pixel once its transmittance would fall to the minimum, so in a tile
//! that front splats have made opaque, no later splat is ever blended; listing those splats
//! only costs time. 60,000 splats that each cover a 1920x1080 view list 490M entries, of which
//! the blend reads a few dozen per tile: binning took 90% of such a render.
//!
//! A splat whose pixel box covers a whole tile blends into each of its pixels, until the pixel
//! is done, with at least the tile's smallest alpha, which is at a corner of the tile's pixel
//! centres (the falloff's exponent is a convex quadratic). The product of (1 - that alpha) over
//! the front splats bounds every pixel's transmittance from above; once it is below the
//! minimum, every pixel of the tile is done at the latest at that splat, and the tile's list
//! ends there. The bound is taken with margins far above the blend paths' rounding and their
//! falloff approximation, so the image is the one the full lists give, bit for bit.

use super::Window;
use super::project::Splat;
use super::tile_lists::{BlendLimit, ListEnds, TooMuchBlending};
use pwgs_codec::portable_math::exp_f64;

/// Relative margin taken off each splat's smallest alpha (the blends' falloffs are within
/// about 1e-6 of exp).
const ALPHA_MARGIN: f64 = 1e-3;
/// The bound must fall this far below the minimum transmittance (products of hundreds of
/// factors round by well under 1e-3).
const TRANSMITTANCE_MARGIN: f64 = 0.5;

/// Blending rules the bound needs (the hard cutoff's).
#[derive(Debug, Clone, Copy)]
pub struct Stops {
    pub alpha_min: f64,
    pub alpha_max: f64,
    pub transmittance_min: f64,
}

/// What the bound needs of a splat: its pixel box, centre, the Cholesky factor of its conic
/// (as [`Splat`] holds them) and its opacity.
#[derive(Debug, Clone, Copy)]
pub struct Footprint {
    pub bbox: [u32; 4],
    pub mean: [f32; 2],
    pub cholesky: [f32; 3],
    pub opacity: f32,
}

impl From<&Splat> for Footprint {
    fn from(s: &Splat) -> Self {
        Self { bbox: s.bbox, mean: s.mean, cholesky: s.cholesky, opacity: s.opacity }
    }
}

/// Where each tile's list of `splats` (front to back) over `view` ends: at the splat after
/// which the tile is surely opaque; refused once the lists' blend work passes `limit` (for a
/// view of `gaussians` Gaussians).
pub fn splat_list_ends(
    splats: &[Splat],
    view: Window,
    stops: Stops,
    (limit, gaussians): (BlendLimit, usize),
) -> Result<ListEnds, TooMuchBlending> {
    list_ends(splats.len(), |i| Footprint::from(&splats[i]), view, stops, (limit, gaussians))
}

/// [`splat_list_ends`] for `count` splats (front to back) given by `footprint` (the GPU
/// renderer's, read back from the device).
pub fn list_ends(
    count: usize,
    footprint: impl Fn(usize) -> Footprint,
    view: Window,
    stops: Stops,
    (limit, gaussians): (BlendLimit, usize),
) -> Result<ListEnds, TooMuchBlending> {
    let (tiles_x, tiles_y) = view.tile_counts();
    // Per tile, the bound of its pixels' transmittance after the splats so far.
    let mut bound = vec![1.0f64; (tiles_x * tiles_y) as usize];
    let opaque_below = stops.transmittance_min * TRANSMITTANCE_MARGIN;
    let units = limit.of(view, gaussians);
    let ends = ListEnds::closing(
        count,
        |i| footprint(i).bbox,
        view,
        units,
        |i, tx, ty| {
            let Some(alpha) = smallest_alpha(&footprint(i), view.tile_rect(tx, ty), stops) else { return false };
            let t = (ty * tiles_x + tx) as usize;
            bound[t] *= 1.0 - alpha;
            bound[t] <= opaque_below
        },
    );
    ends.ok_or_else(|| limit.refusal(view, gaussians))
}

/// A lower bound, with margin, of the alpha `s` blends into every pixel of the tile `rect`,
/// clamped as the blend clamps it; `None` unless the splat covers the whole tile with an alpha
/// surely above the cutoff.
fn smallest_alpha(s: &Footprint, [x0, x1, y0, y1]: [u32; 4], stops: Stops) -> Option<f64> {
    let [bx0, bx1, by0, by1] = s.bbox;
    if bx0 > x0 || bx1 < x1 || by0 > y0 || by1 < y1 {
        return None;
    }
    let [l11, l21, l22] = s.cholesky.map(f64::from);
    let sigma = |px: u32, py: u32| {
        let (dx, dy) = (f64::from(s.mean[0]) - (f64::from(px) + 0.5), f64::from(s.mean[1]) - (f64::from(py) + 0.5));
        let (p, q) = (l11 * dx + l21 * dy, l22 * dy);
        0.5 * (p * p + q * q)
    };
    let largest = [(x0, y0), (x1 - 1, y0), (x0, y1 - 1), (x1 - 1, y1 - 1)]
        .into_iter()
        .map(|(px, py)| sigma(px, py))
        .fold(0.0f64, f64::max);
    let alpha = f64::from(s.opacity) * exp_f64(-largest) * (1.0 - ALPHA_MARGIN);
    (alpha >= stops.alpha_min * (1.0 + ALPHA_MARGIN)).then(|| alpha.min(stops.alpha_max))
}

impl Stops {
    pub fn of(options: &super::RenderOptions) -> Self {
        Self {
            alpha_min: options.projection.alpha_min,
            alpha_max: f64::from(options.alpha_max),
            transmittance_min: f64::from(options.transmittance_min),
        }
    }
}

//! Turning trained Gaussians into a stream: the encoder's choices (quantization steps, grid
//! resolution, what to drop), then the decoder library's writer, then the decoder library's
//! reader, so that what the encoder evaluates is exactly what a decoder will show.
#![cfg_attr(not(test), deny(clippy::disallowed_methods))] // the determinism rule: no platform math (clippy.toml)

mod grid;

use std::cmp::Ordering;

use pwgs_codec::stream::header::{BaseKind, Header};
use pwgs_codec::stream::octree::{MAX_POINTS_PER_VOXEL, OctreeError};
use pwgs_codec::stream::plain::{PlainGaussians, PositionGrid, QuantizedRotation};
use pwgs_codec::stream::wrap::QuantizedSynthesis;
use pwgs_codec::stream::{self, Decoded};
use pwgs_core::gaussians::{Gaussians, sh_band, sh_coeff_count};

use crate::plain::importance;
use crate::plain::rotation_frame::canonical_frame;
use crate::size_fit::{Fit, most_important_fitting};

/// The size/quality knob: 5 is the default; each step up halves every quantization step's
/// square (steps shrink by sqrt(2)) and refines the position grid by a bit every second step.
pub const DEFAULT_QUALITY: u8 = 5;
pub const MAX_QUALITY: u8 = 14;

/// Quantization choices of the plain-3DGS coder.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct QuantizerSettings {
    /// Grid cells along the robust extent of the scene (the central 98% of positions) are
    /// `2^position_bits`, times sqrt(2) with `position_half_bit`.
    pub position_bits: u8,
    pub position_half_bit: bool,
    pub log_scale_step: f32,
    pub rotation_step: f32,
    pub opacity_step: f32,
    pub dc_step: f32,
    /// Steps of SH bands 1, 2, 3.
    pub band_steps: [f32; 3],
    /// Importance classes, when the Gaussians' weights are known: 2 to 7 (none below 2); the
    /// coarsest class's steps are about those of quality 0, so that no class leaves the range
    /// where a step's error stays small against the value (a scale step beyond that turns a
    /// faint Gaussian into a large one).
    pub importance_classes: u8,
    /// Factor between the steps of successive importance classes, in sqrt(2)s: 2 (a factor 2,
    /// steps growing as the inverse square root of the weight, which minimizes the weighted
    /// squared error for the bytes when the error is the weight times the step squared).
    pub class_spread: u8,
    /// With pruning: the share of a view's pixels that the Gaussians dropped as faint may cover
    /// together, in every importance view ([`importance::Importance::prune_costs`]),
    /// `2^(1 - quality)` (at most [`MAX_PRUNE_BUDGET`]). Their error when missing is about that
    /// share of the view's squared colour error, and a kept Gaussian's quantization error about
    /// a step squared: so the budget falls with the step squared, a factor 2 each quality level.
    /// It replaced a floor on each Gaussian's own weight, which an orbit 35 degrees below the
    /// horizon showed failing (guitar q8: 38.81 dB there against 43.68 with a budget 4 times
    /// this one, at about equal bytes). The factor is a trade between views: with the classes'
    /// weights from the whole sphere, at default effort, guitar q9 / q11 and biker q10 / q11 /
    /// q12 against SOG at equal PSNR on the orbit 20 degrees up and on one 35 degrees below
    /// (interpolated in log size): `2^(3 - quality)` 2.23x / 1.72x (extrapolated) and 1.76x /
    /// 1.59x; this budget 2.19x / 1.86x and 1.74x / 1.67x; `2^(0 - quality)` 2.11x / 1.92x and
    /// 1.71x / 1.71x.
    pub prune_budget: f32,
}

impl QuantizerSettings {
    /// Settings for a quality level in `0..=MAX_QUALITY`. Computed exactly (no platform
    /// `powf`), so a model quantizes to the same stream on every machine.
    pub fn for_quality(quality: u8) -> Self {
        let q = i32::from(quality.min(MAX_QUALITY));
        let d = i32::from(DEFAULT_QUALITY);
        let factor = sqrt2_power(d - q);
        Self {
            // 12 + (q - d) / 2, halves rounded up.
            position_bits: (25 + q - d).div_euclid(2) as u8,
            position_half_bit: false,
            log_scale_step: 0.16 * factor,
            rotation_step: 0.016 * factor,
            opacity_step: 0.4 * factor,
            dc_step: 0.16 * factor,
            band_steps: [0.06 * factor, 0.08 * factor, 0.1 * factor],
            importance_classes: ((q as u8).div_ceil(2) + 1).min(importance::MAX_CLASSES),
            class_spread: 2,
            prune_budget: sqrt2_power(2 * (1 - q)),
        }
    }
}

/// `sqrt(2)^k` as f32: a power of two built from its exponent, times `SQRT_2` when `k` is odd.
pub(crate) fn sqrt2_power(k: i32) -> f32 {
    let two_power = f32::from_bits(((127 + k.div_euclid(2)) as u32) << 23);
    if k.rem_euclid(2) == 1 { two_power * std::f32::consts::SQRT_2 } else { two_power }
}

impl Default for QuantizerSettings {
    fn default() -> Self {
        Self::for_quality(DEFAULT_QUALITY)
    }
}

/// A written stream, what a decoder reconstructs from it, and what the encoder dropped.
pub struct Compressed {
    pub bytes: Vec<u8>,
    pub decoded: Decoded,
    /// Gaussians dropped as invisible (opacity below 1/255 after quantization).
    pub invisible: usize,
    /// Visible Gaussians dropped as too faint to pay for their bytes ([`Coding::prune_costs`]).
    pub faint: usize,
    /// Visible Gaussians dropped, least important first, to fit a target size.
    pub pruned: usize,
    /// Gaussians dropped because more than 255 shared a cell of the finest position grid (the
    /// least important of each such cell; a stream's cell holds at most 255).
    pub crowded: usize,
}

/// Why Gaussians could not be compressed.
#[derive(Debug, thiserror::Error)]
pub enum CompressError {
    #[error("the model has a non-finite {0}")]
    NonFinite(&'static str),
    #[error(transparent)]
    Octree(#[from] OctreeError),
    #[error("the stream the encoder wrote does not decode: {0}")]
    SelfCheck(#[from] stream::DecodeError),
    #[error("{count} Gaussians exceed the stream limit of {limit}")]
    TooMany { count: usize, limit: u32 },
    #[error("{weights} importance weights for {gaussians} Gaussians")]
    Weights { weights: usize, gaussians: usize },
    #[error("a stream of at most {target} bytes is impossible: without any Gaussian it takes {minimum}")]
    TargetTooSmall { target: usize, minimum: usize },
    #[error(
        "positions span {low:.3e} to {high:.3e}: the stream's position grid cannot hold them (its origin's \
         magnitude plus its extent must stay below 3.4e38, the largest binary32)"
    )]
    Span { low: f32, high: f32 },
}

/// Scene normalization and render settings stored in the header.
#[derive(Debug, Clone, Copy)]
pub struct StreamContext {
    pub center: [f32; 3],
    pub scale: f32,
    pub background: [f32; 3],
}

impl StreamContext {
    /// A normalization for Gaussians without cameras (an imported PLY): the per-axis median
    /// position and 1.1 times the 95th percentile of the distance to it (measured in binary64,
    /// where no finite positions' distance overflows, and at most the largest binary32).
    pub fn from_gaussians(g: &Gaussians, background: [f32; 3]) -> Self {
        if g.is_empty() {
            return Self { center: [0.0; 3], scale: 1.0, background };
        }
        let center: [f32; 3] = std::array::from_fn(|a| {
            let mut v: Vec<f32> = g.means.iter().map(|m| m[a]).collect();
            v.sort_by(f32::total_cmp);
            v[v.len() / 2]
        });
        let mut d: Vec<f64> = g
            .means
            .iter()
            .map(|m| {
                let [x, y, z] = std::array::from_fn(|a| f64::from(m[a]) - f64::from(center[a]));
                (x * x + y * y + z * z).sqrt()
            })
            .collect();
        d.sort_by(f64::total_cmp);
        let scale = (d[(d.len() * 95 / 100).min(d.len() - 1)] * 1.1).clamp(1e-6, f64::from(f32::MAX)) as f32;
        Self { center, scale, background }
    }
}

/// Quantizes, writes (with the wrapper's section when given) and decodes back.
pub fn compress(
    g: &Gaussians,
    settings: &QuantizerSettings,
    context: &StreamContext,
    wrapper: Option<&QuantizedSynthesis>,
) -> Result<Compressed, CompressError> {
    compress_to_size(g, Coding { settings, weights: None, prune_costs: None }, context, wrapper, usize::MAX)
}

/// How to code the Gaussians: the steps and grid, and optionally each Gaussian's blending
/// weight ([`importance::Importance::weights`]), which puts them in importance classes (SPEC.md
/// section 6.5).
#[derive(Debug, Clone, Copy)]
pub struct Coding<'a> {
    pub settings: &'a QuantizerSettings,
    pub weights: Option<&'a [f32]>,
    /// Each Gaussian's pruning cost ([`importance::Importance::prune_costs`]), to drop those
    /// within [`QuantizerSettings::prune_budget`] (with `weights` only): what no view shows
    /// much of.
    pub prune_costs: Option<&'a [f32]>,
}

/// [`compress`] into at most `target` bytes: every visible Gaussian if the stream fits, else
/// the most important ones (see [`importance`]), as many as fit ([`most_important_fitting`]): the
/// result lands within a few Gaussians' bytes of the target, which makes equal-size
/// comparisons one option away.
pub fn compress_to_size(
    g: &Gaussians,
    coding: Coding,
    context: &StreamContext,
    wrapper: Option<&QuantizedSynthesis>,
    target: usize,
) -> Result<Compressed, CompressError> {
    let Selection { visible, invisible, faint, reference } = select(g, coding)?;
    let rank = || {
        let mut ranked = visible.clone();
        ranked.sort_by(|&a, &b| more_important(g, coding.weights, a, b));
        ranked
    };
    let write = |keep: Option<&[usize]>| {
        write_selected(g, keep.unwrap_or(&visible), (coding, reference), context, wrapper).map(|w| w.bytes)
    };
    let (kept, bytes) = match most_important_fitting(visible.len(), target, rank, write)? {
        Fit::Fits { kept, bytes } => (kept.map_or(visible.len(), |k| k.len()), bytes),
        Fit::TooSmall { minimum } => return Err(CompressError::TargetTooSmall { target, minimum }),
    };
    let decoded = stream::decode(&bytes)?;
    // What the grid could not hold of the Gaussians kept for the size.
    let crowded = kept - decoded.header.gaussian_count as usize;
    Ok(Compressed { bytes, decoded, invisible, faint, pruned: visible.len() - kept, crowded })
}

/// What [`compress_to_size`] with `coding` and no target size keeps of `g` (indices into `g`,
/// increasing) and those Gaussians as a decoder reconstructs them, in that order (the
/// stream's own order is the octree's).
pub fn reconstruction(
    g: &Gaussians,
    coding: Coding,
    context: &StreamContext,
) -> Result<(Vec<usize>, Gaussians), CompressError> {
    let Selection { visible, reference, .. } = select(g, coding)?;
    let Written { content, kept, .. } = write_selected(g, &visible, (coding, reference), context, None)?;
    Ok((kept, content.dequantize()))
}

/// The Gaussians a stream can hold, before any target size.
struct Selection {
    /// Indices into the model, increasing.
    visible: Vec<usize>,
    /// Dropped as invisible, and as too faint.
    invisible: usize,
    faint: usize,
    /// The reference weight of the importance classes (0 without weights).
    reference: f32,
}

fn select(g: &Gaussians, coding: Coding) -> Result<Selection, CompressError> {
    check_finite(g)?;
    for given in [coding.weights, coding.prune_costs].into_iter().flatten() {
        if given.len() != g.len() {
            return Err(CompressError::Weights { weights: given.len(), gaussians: g.len() });
        }
    }
    let mut visible = visible_after_quantization(g, coding.settings.opacity_step);
    let invisible = g.len() - visible.len();
    // Classes measure from the visible Gaussians' reference weight.
    let reference = coding.weights.map(|w| importance::reference(&visible.iter().map(|&i| w[i]).collect::<Vec<_>>()));
    if let (Some(costs), Some(_)) = (coding.prune_costs, coding.weights) {
        let budget = coding.settings.prune_budget.min(MAX_PRUNE_BUDGET);
        visible.retain(|&i| costs[i] > budget);
    }
    let faint = g.len() - invisible - visible.len();
    Ok(Selection { visible, invisible, faint, reference: reference.unwrap_or(0.0) })
}

/// The most of a view's colour pruning may take, whatever the settings: quality 4's budget. A
/// budget of 1 would drop every Gaussian (no view's weights add up to more than its pixels).
const MAX_PRUNE_BUDGET: f32 = 0.125;

/// How much a Gaussian can show, for choosing what to drop: the log of its opacity times its
/// projected area, log sigmoid(l) + (2/3) (s_x + s_y + s_z), with log sigmoid(l) taken as
/// min(l, 0) (within ln 2) so that only `+ - *` decide what a stream holds, on every machine.
fn importance(g: &Gaussians, i: usize) -> f32 {
    let [sx, sy, sz] = g.log_scales[i];
    g.opacity_logits[i].min(0.0) + (2.0 / 3.0) * (sx + sy + sz)
}

/// Orders Gaussians (indices into `g`) most important first: by importance weight when there
/// are weights (what shows in views), else by opacity times area ([`importance`]); then by index.
fn more_important(g: &Gaussians, weights: Option<&[f32]>, a: usize, b: usize) -> Ordering {
    match weights {
        Some(w) => w[b].total_cmp(&w[a]),
        None => importance(g, b).total_cmp(&importance(g, a)),
    }
    .then(a.cmp(&b))
}

/// A written stream of some Gaussians.
struct Written {
    bytes: Vec<u8>,
    content: PlainGaussians,
    /// The Gaussians it holds (indices into the model, increasing): those asked for but what
    /// [`on_grid`] drops.
    kept: Vec<usize>,
}

/// The stream of the Gaussians `keep` (indices into `g`, increasing), and what it codes.
fn write_selected(
    g: &Gaussians,
    keep: &[usize],
    coding: (Coding, f32),
    context: &StreamContext,
    wrapper: Option<&QuantizedSynthesis>,
) -> Result<Written, CompressError> {
    if keep.len() > stream::header::MAX_GAUSSIANS as usize {
        return Err(CompressError::TooMany { count: keep.len(), limit: stream::header::MAX_GAUSSIANS });
    }
    let (kept, content) = on_grid(g, keep, coding)?;
    let header = Header {
        base: BaseKind::Plain3dgs,
        gaussian_count: content.len() as u32,
        sh_degree: content.sh_degree,
        center: context.center,
        scale: context.scale,
        background: context.background,
    };
    let bytes = stream::encode(&header, &content, wrapper)?;
    if !content.colour_differences_fit() {
        return Ok(Written { bytes, content, kept });
    }
    // The colours as differences (SPEC.md 6.6) when that is smaller: it is on captured scenes
    // (a third of the colours' bytes on biker), not on random ones.
    let differences = PlainGaussians { colour_differences: true, ..content };
    let other = stream::encode(&header, &differences, wrapper)?;
    if other.len() < bytes.len() {
        return Ok(Written { bytes: other, content: differences, kept });
    }
    Ok(Written { bytes, content: PlainGaussians { colour_differences: false, ..differences }, kept })
}

/// The Gaussians `keep` quantized on a grid where no cell of `POSN` holds more than 255 of
/// them (SPEC.md section 9), and which of them that is.
///
/// Several Gaussians can share a cell; the grid is refined, level by level, until none holds
/// more than 255. Where even the finest grid ([`grid::GridChoice::finest`]) has a cell with
/// more (many Gaussians at one position, which real models have, or within a 2^24th of a scene
/// whose outliers stretch the grid), no stream can hold them all: each such cell keeps its 255
/// most important ([`more_important`]) and the others are dropped, which the caller reports
/// ([`Compressed::crowded`]). At 255 Gaussians on one spot the ones behind hardly show.
fn on_grid(
    g: &Gaussians,
    keep: &[usize],
    (coding, reference): (Coding, f32),
) -> Result<(Vec<usize>, PlainGaussians), CompressError> {
    let s = coding.settings;
    // Each level finer makes the grid a level deeper until it is the finest: at most 24 turns.
    let mut finer = 0;
    loop {
        let choice = grid::choose(g, keep, (u32::from(s.position_bits) + finer, s.position_half_bit))?;
        let content = quantize(g, keep, (coding, reference), &choice.grid);
        let refine = content.refine();
        let cells: Vec<[u32; 3]> = content.positions.iter().map(|q| q.map(|c| c >> refine)).collect();
        let overfull = grid::overfull_cells(&cells);
        if overfull.is_empty() {
            return Ok((keep.to_vec(), content));
        }
        if !choice.finest {
            finer += 1;
            continue;
        }
        let mut dropped = vec![false; keep.len()];
        for mut rows in overfull {
            rows.sort_by(|&a, &b| more_important(g, coding.weights, keep[a], keep[b]));
            rows[MAX_POINTS_PER_VOXEL as usize..].iter().for_each(|&r| dropped[r] = true);
        }
        let kept: Vec<usize> = keep.iter().zip(&dropped).filter(|&(_, &d)| !d).map(|(&i, _)| i).collect();
        // On the same grid: the cells of `POSN` are those above, or finer ones where fewer
        // classes refine less, so none holds more than 255 now.
        let content = quantize(g, &kept, (coding, reference), &choice.grid);
        return Ok((kept, content));
    }
}

fn check_finite(g: &Gaussians) -> Result<(), CompressError> {
    let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
    let checks: [(&'static str, bool); 5] = [
        ("position", finite(g.means.as_flattened())),
        ("scale", finite(g.log_scales.as_flattened())),
        ("rotation", finite(g.rotations.as_flattened())),
        ("opacity", finite(&g.opacity_logits)),
        ("SH coefficient", finite(&g.sh)),
    ];
    match checks.iter().find(|(_, ok)| !ok) {
        Some((what, _)) => Err(CompressError::NonFinite(what)),
        None => Ok(()),
    }
}

fn quantize_value(v: f32, step: f32) -> i32 {
    let limit = (pwgs_codec::stream::entropy::MAX_MAGNITUDE - 1) as f32;
    (v / step).round().clamp(-limit, limit) as i32
}

/// sigmoid(x) >= 1/255  <=>  x >= ln(1/254) = -5.537334267...: the binary32 nearest to it,
/// written out so that no platform `ln` decides which Gaussians are dropped.
const VISIBLE_LOGIT: f32 = -5.537_334_4;

/// Indices of Gaussians that can show in a render: the rasterizer skips any alpha below 1/255,
/// and alpha never exceeds the opacity, so lower opacities never contribute.
fn visible_after_quantization(g: &Gaussians, opacity_step: f32) -> Vec<usize> {
    (0..g.len())
        .filter(|&i| quantize_value(g.opacity_logits[i], opacity_step) as f32 * opacity_step >= VISIBLE_LOGIT)
        .collect()
}

fn quantize_rotation(q: [f32; 4], step: f32) -> QuantizedRotation {
    let norm = q.iter().map(|&c| f64::from(c) * f64::from(c)).sum::<f64>().sqrt();
    let unit: [f64; 4] = if norm > 0.0 { q.map(|c| f64::from(c) / norm) } else { [1.0, 0.0, 0.0, 0.0] };
    let largest = (0..4).fold(0, |best, i| if unit[i].abs() > unit[best].abs() { i } else { best });
    let sign = if unit[largest] < 0.0 { -1.0 } else { 1.0 };
    let mut rest = [0; 3];
    for (slot, i) in (0..4).filter(|&i| i != largest).enumerate() {
        rest[slot] = quantize_value((unit[i] * sign) as f32, step);
    }
    QuantizedRotation { largest: largest as u8, rest }
}

/// The quantized Gaussians `keep`, on the grid `fine` (`POSN`'s grid refined by the classes'
/// levels), with importance classes measured from `reference` when `coding` has weights.
fn quantize(g: &Gaussians, keep: &[usize], (coding, reference): (Coding, f32), fine: &PositionGrid) -> PlainGaussians {
    let s = coding.settings;
    let count = s.importance_classes;
    let classes = coding.weights.filter(|_| count >= 2).map(|w| {
        let weights: Vec<f32> = keep.iter().map(|&i| w[i]).collect();
        importance::classes(&weights, reference, (count, s.class_spread), (count - 1).min(fine.depth - 1))
    });
    // Row `r` (Gaussian `keep[r]`)'s step for a block of step `step`, as the decoder takes it.
    let step = |r: usize, step: f32| classes.as_ref().map_or(step, |c| c.step(r, step));
    let k = sh_coeff_count(g.sh_degree);
    let full_rest: Vec<i32> = keep
        .iter()
        .enumerate()
        .flat_map(|(r, &i)| {
            let sh = g.sh_of(i);
            (3..k * 3).map(move |j| quantize_value(sh[j], step(r, s.band_steps[sh_band(j / 3) - 1])))
        })
        .collect();
    // Keep the bands up to the highest one with any nonzero quantized coefficient.
    let rest_in = (k - 1) * 3;
    let degree = (0..=g.sh_degree)
        .rev()
        .find(|&d| {
            let lo = (sh_coeff_count(d.saturating_sub(1)) - 1) * 3;
            let hi = (sh_coeff_count(d) - 1) * 3;
            d == 0 || full_rest.chunks(rest_in).any(|c| c[lo..hi].iter().any(|&v| v != 0))
        })
        .unwrap_or(0);
    let rest_out = (sh_coeff_count(degree) - 1) * 3;
    let sh_rest =
        if rest_in == 0 { vec![] } else { full_rest.chunks(rest_in).flat_map(|c| c[..rest_out].to_vec()).collect() };
    // Each Gaussian in the frame whose rotation codes smallest (the same covariance).
    let (rotations, log_scales): (Vec<_>, Vec<_>) =
        keep.iter().map(|&i| canonical_frame(g.rotations[i], g.log_scales[i])).unzip();
    let mut positions = grid::quantize_positions(g, keep, fine);
    let refine = classes.as_ref().map_or(0, |c| c.refine);
    if let Some(c) = &classes {
        for (q, &class) in positions.iter_mut().zip(&c.of) {
            *q = q.map(|v| c.snap(class, v));
        }
    }
    PlainGaussians {
        positions,
        // POSN's grid: `refine` levels coarser (the cell times a power of two, exact).
        grid: PositionGrid { cell: fine.cell * (1u32 << refine) as f32, depth: fine.depth - refine, ..*fine },
        scale_step: s.log_scale_step,
        log_scales: (log_scales.iter().enumerate())
            .map(|(r, l)| l.map(|v| quantize_value(v, step(r, s.log_scale_step))))
            .collect(),
        rotation_step: s.rotation_step,
        rotations: (rotations.iter().enumerate())
            .map(|(r, &q)| quantize_rotation(q, step(r, s.rotation_step)))
            .collect(),
        opacity_step: s.opacity_step,
        opacity_logits: (keep.iter().enumerate())
            .map(|(r, &i)| quantize_value(g.opacity_logits[i], step(r, s.opacity_step)))
            .collect(),
        sh_degree: degree,
        dc_step: s.dc_step,
        sh_dc: (keep.iter().enumerate())
            .map(|(r, &i)| std::array::from_fn(|c| quantize_value(g.sh_of(i)[c], step(r, s.dc_step))))
            .collect(),
        band_steps: s.band_steps[..degree as usize].to_vec(),
        sh_rest,
        colour_differences: false,
        adaptive: true,
        classes,
    }
}

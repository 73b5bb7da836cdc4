//! Where a plain stream's positions go (SPEC.md section 6.1): a grid with its origin at the
//! Gaussians' minimum corner, cells sized from their robust extent, deep enough to reach the
//! farthest one and near enough to zero for a decoder to accept it; and which of its cells hold
//! more Gaussians than a cell may.
//!
//! Everything is measured in binary64: positions anywhere in binary32's range (up to 3.4e38 on
//! either side) have differences beyond it.

use std::f64::consts::SQRT_2;

use pwgs_codec::stream::octree::{MAX_DEPTH, MAX_POINTS_PER_VOXEL};
use pwgs_codec::stream::plain::PositionGrid;
use pwgs_core::gaussians::Gaussians;

use super::CompressError;

/// A grid for a set of Gaussians.
pub(super) struct GridChoice {
    pub grid: PositionGrid,
    /// No finer grid separates Gaussians that this one puts in one cell: it is [`MAX_DEPTH`]
    /// levels deep, or its cell is the smallest normal binary32 (no coarser than the spacing of
    /// the binary32 values near zero), or the Gaussians all share one position.
    pub finest: bool,
}

/// `2^k` as binary64, exactly (no platform `powf`: the grid, and so the stream, is the same on
/// every machine).
fn two_power(k: u32) -> f64 {
    f64::from_bits(u64::from(1023 + k.min(1023)) << 52)
}

/// The grid for the Gaussians `keep` (indices into `g`): `2^bits` cells (times sqrt(2) with
/// `half_bit`) along their robust extent (the central 98% of positions, largest axis), or their
/// full extent where the robust one is 0; deep enough to hold every position (cells coarser
/// than asked if 24 levels cannot reach the farthest outlier).
///
/// A decoder refuses a grid whose largest origin magnitude plus its extent (`cell * 2^depth`)
/// is not below the largest binary32 (SPEC.md section 6.1): where the grid asked for reaches
/// that far, the cell shrinks to the least that still covers every position, and where even
/// that does, the positions cannot be coded ([`CompressError::Span`]).
pub(super) fn choose(
    g: &Gaussians,
    keep: &[usize],
    (bits, half_bit): (u32, bool),
) -> Result<GridChoice, CompressError> {
    if keep.is_empty() {
        return Ok(GridChoice { grid: PositionGrid { origin: [0.0; 3], cell: 1.0, depth: 1 }, finest: true });
    }
    let (mut robust, mut full) = (0.0f64, 0.0f64);
    let (mut low, mut high) = ([0.0f32; 3], [0.0f32; 3]);
    for a in 0..3 {
        let mut v: Vec<f32> = keep.iter().map(|&i| g.means[i][a]).collect();
        v.sort_by(f32::total_cmp);
        let at = |p: usize| f64::from(v[(v.len() - 1) * p / 100]);
        robust = robust.max(at(99) - at(1));
        (low[a], high[a]) = (v[0], v[v.len() - 1]);
        full = full.max(f64::from(high[a]) - f64::from(low[a]));
    }
    let smallest = f64::from(f32::MIN_POSITIVE);
    let cells = two_power(bits) * if half_bit { SQRT_2 } else { 1.0 };
    let wanted = if robust > 0.0 { robust } else { full } / cells;
    let mut cell = wanted.max(smallest);
    let depth = match (1..=MAX_DEPTH).find(|&d| two_power(d.into()) * cell > full) {
        Some(d) => d,
        None => {
            cell = full / (two_power(MAX_DEPTH.into()) - 1.0);
            MAX_DEPTH
        }
    };
    let reach = low.iter().map(|o| f64::from(o.abs())).fold(0.0, f64::max);
    let fits = |cell: f32| reach + f64::from(cell) * two_power(depth.into()) < f64::from(f32::MAX);
    let mut cell32 = cell as f32;
    if !fits(cell32) && full > 0.0 {
        cell32 = (full / (two_power(depth.into()) - 1.0)).max(smallest) as f32;
    }
    if !fits(cell32) {
        let low = low.into_iter().fold(f32::INFINITY, f32::min);
        let high = high.into_iter().fold(f32::NEG_INFINITY, f32::max);
        return Err(CompressError::Span { low, high });
    }
    let finest = depth == MAX_DEPTH || wanted <= smallest;
    Ok(GridChoice { grid: PositionGrid { origin: low, cell: cell32, depth }, finest })
}

/// Each of `keep`'s positions on `grid`, rounded to the nearest point within it.
pub(super) fn quantize_positions(g: &Gaussians, keep: &[usize], grid: &PositionGrid) -> Vec<[u32; 3]> {
    let max = (1u64 << grid.depth) - 1;
    keep.iter()
        .map(|&i| {
            std::array::from_fn(|a| {
                let t = (f64::from(g.means[i][a]) - f64::from(grid.origin[a])) / f64::from(grid.cell);
                (t.round().max(0.0) as u64).min(max) as u32
            })
        })
        .collect()
}

/// The rows of `cells` (grid coordinates) in the cells that more than [`MAX_POINTS_PER_VOXEL`]
/// rows share, grouped by cell: empty when every cell fits the octree.
pub(super) fn overfull_cells(cells: &[[u32; 3]]) -> Vec<Vec<usize>> {
    let mut rows: Vec<usize> = (0..cells.len()).collect();
    rows.sort_unstable_by_key(|&r| cells[r]);
    rows.chunk_by(|&a, &b| cells[a] == cells[b])
        .filter(|rows| rows.len() > MAX_POINTS_PER_VOXEL as usize)
        .map(<[usize]>::to_vec)
        .collect()
}

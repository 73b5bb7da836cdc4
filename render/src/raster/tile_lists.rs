//! A view's tile lists in bounded memory: how long each tile's list is, the windows the view is
//! blended in, and each window's lists.
//!
//! Holding every tile's list at once takes items x tiles entries: 60,000 splats covering a
//! 1920x1080 view are 490M entries (2 GB). [`ListEnds`] first works out, per tile, where its
//! list ends and how many entries it holds, in memory of the tiles alone; [`ListEnds::windows`]
//! then cuts the view into windows whose lists fit a [`BinBudget`], and [`ListEnds::bin`] fills
//! one window's lists at a time.
//!
//! A list may end before the last item that overlaps its tile (where the tile is surely opaque,
//! [`super::opaque_tiles`]). Both passes walk, per item and tile row, only the tiles still open
//! ([`OpenTiles`]): their work is that of the entries listed, plus one step per item and row,
//! however many items overlap tiles that have closed.
//!
//! Memory is bounded that way, but not time: splats that cross tiles without covering them
//! (needles, faint edges) never close a tile, and 30,000 needles across a 1920x1080 view list
//! 240M entries, half a minute of blending. A view's [`ListEnds::work`] counts what its blend
//! will do, and a render within a [`BlendLimit`] refuses the view as soon as finding its list
//! ends passes the limit, before any list is filled or blended.

use std::ops::ControlFlow;

use super::tiles::{TileBins, tile_range};
use super::{TILE_SIZE, Window};

/// How much one binning may hold: tile-list entries (4 bytes each) and window pixels (the
/// blend's per-pixel arrays take 24 bytes each).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BinBudget {
    pub entries: u64,
    pub pixels: u64,
}

impl BinBudget {
    /// 2^24 entries (64 MiB of lists) and 2^20 pixels (24 MiB of blend arrays): a view of any
    /// size and any splats renders within about 100 MiB besides its image and its splats.
    pub const DEFAULT: Self = Self { entries: 1 << 24, pixels: 1 << 20 };
}

/// The most blend work a render takes on (SPEC.md section 9): `per_pixel` units per pixel of
/// the view, `per_gaussian` per Gaussian rendered and `fixed` units, a unit being one entry of
/// a tile list or one pixel row of an entry's box within its tile ([`ListEnds::work`]: the
/// blend loops run per row of the box, 13-20 ns a unit on the machine of
/// docs/results/bounded-inputs.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlendLimit {
    pub per_pixel: u64,
    pub per_gaussian: u64,
    pub fixed: u64,
}

impl BlendLimit {
    /// 32 units per pixel, 48 per Gaussian and 2^24: a view of a 1 MB stream (at most 500,000
    /// Gaussians) renders in at most about 1.7 s per megapixel at 1920x1080 on the 2-core
    /// machine of docs/results/bounded-inputs.md, in the dev profile, and the real models
    /// measured there need a sixth of the pixels' share at 1920x1080.
    pub const DEFAULT: Self = Self { per_pixel: 32, per_gaussian: 48, fixed: 1 << 24 };
    /// No limit: for the encoder's renders of scenes it made itself.
    pub const NONE: Self = Self { per_pixel: 0, per_gaussian: 0, fixed: u64::MAX };

    /// The limit for `view` of `gaussians` Gaussians.
    pub fn of(&self, view: Window, gaussians: usize) -> u64 {
        let pixels = u64::from(view.width) * u64::from(view.height);
        self.fixed
            .saturating_add(self.per_pixel.saturating_mul(pixels))
            .saturating_add(self.per_gaussian.saturating_mul(gaussians as u64))
    }

    /// The error refusing `view` of `gaussians` Gaussians.
    pub fn refusal(&self, view: Window, gaussians: usize) -> TooMuchBlending {
        TooMuchBlending {
            width: view.width,
            height: view.height,
            gaussians,
            limit: self.of(view, gaussians),
            rule: *self,
        }
    }
}

/// A view refused for the blend work it needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "the {width}x{height} view of {gaussians} Gaussians needs more than {limit} units of blend work (SPEC.md section 9 \
     limits a view to {} per pixel, {} per Gaussian and {} more): its splats cross too many tiles without covering \
     them; render a smaller view", rule.per_pixel, rule.per_gaussian, rule.fixed
)]
pub struct TooMuchBlending {
    pub width: u32,
    pub height: u32,
    pub gaussians: usize,
    pub limit: u64,
    pub rule: BlendLimit,
}

/// Position of a tile that never closes.
pub const OPEN: u32 = u32::MAX;

/// Per tile of a view (row-major), where its list ends and how long it is.
#[derive(Debug, Clone, PartialEq)]
pub struct ListEnds {
    /// The whole view; tiles start at its top left corner.
    pub view: Window,
    pub tiles_x: u32,
    pub tiles_y: u32,
    /// Position of the last item listed in each tile ([`OPEN`]: the list runs to the last item
    /// that overlaps the tile).
    pub closed_at: Vec<u32>,
    /// Entries in each tile's list.
    pub lengths: Vec<u32>,
    /// The blend work of the lists: per entry, one plus the pixel rows its box has in its tile.
    pub work: u64,
}

impl ListEnds {
    /// The lists of `count` items (front to back) whose pixel boxes (x0, x1, y0, y1, inside
    /// `view`) `bbox` gives, every list running to its tile's last item. Their lengths come
    /// from a difference array over the tiles, in one step per item and tile rather than one
    /// per entry (60,000 splats covering a 1920x1080 view are 490M entries).
    pub fn full(count: usize, bbox: impl Fn(usize) -> [u32; 4], view: Window) -> Self {
        let (tiles_x, tiles_y) = view.tile_counts();
        let stride = tiles_x as usize + 1;
        // Each item adds one to the rectangle of tiles its box meets.
        let mut sums = vec![0i64; stride * (tiles_y as usize + 1)];
        let mut work = 0u64;
        for i in 0..count {
            let b @ [_, _, y0, y1] = bbox(i);
            let Some([tx0, tx1, ty0, ty1]) = tile_box(b, view) else { continue };
            // Per tile of a column: one unit per entry plus its rows, which over the column's
            // tiles add up to the box's rows inside the view.
            let rows = y1.min(view.y0 + view.height) - y0.max(view.y0);
            work += u64::from(tx1 - tx0) * u64::from(ty1 - ty0 + rows);
            let [tx0, tx1, ty0, ty1] = [tx0, tx1, ty0, ty1].map(|v| v as usize);
            sums[ty0 * stride + tx0] += 1;
            sums[ty0 * stride + tx1] -= 1;
            sums[ty1 * stride + tx0] -= 1;
            sums[ty1 * stride + tx1] += 1;
        }
        for ty in 0..tiles_y as usize {
            for tx in 0..stride {
                let above = if ty > 0 { sums[(ty - 1) * stride + tx] } else { 0 };
                let left = if tx > 0 { sums[ty * stride + tx - 1] } else { 0 };
                let diagonal = if ty > 0 && tx > 0 { sums[(ty - 1) * stride + tx - 1] } else { 0 };
                sums[ty * stride + tx] += above + left - diagonal;
            }
        }
        let lengths = (0..tiles_y as usize)
            .flat_map(|ty| (0..tiles_x as usize).map(move |tx| (ty, tx)))
            .map(|(ty, tx)| sums[ty * stride + tx] as u32)
            .collect();
        let tile_count = (tiles_x * tiles_y) as usize;
        Self { view, tiles_x, tiles_y, closed_at: vec![OPEN; tile_count], lengths, work }
    }

    /// The lists of `count` items with boxes `bbox`, each ending at the first item for which
    /// `closes(item, tx, ty)` holds (asked of each item in order, for the tiles still open), or
    /// `None` as soon as their [`work`](Self::work) passes `limit` units.
    pub fn closing(
        count: usize,
        bbox: impl Fn(usize) -> [u32; 4],
        view: Window,
        limit: u64,
        mut closes: impl FnMut(usize, u32, u32) -> bool,
    ) -> Option<Self> {
        let (tiles_x, tiles_y) = view.tile_counts();
        let tile_count = (tiles_x * tiles_y) as usize;
        let (closed_at, lengths) = (vec![OPEN; tile_count], vec![0; tile_count]);
        let mut ends = Self { view, tiles_x, tiles_y, closed_at, lengths, work: 0 };
        let walk = walk_open_tiles(count, bbox, view, |i, b, tx, ty| {
            let t = (ty * tiles_x + tx) as usize;
            ends.lengths[t] += 1;
            ends.work += entry_work(b, view, ty);
            if ends.work > limit {
                return ControlFlow::Break(());
            }
            let closed = closes(i, tx, ty);
            if closed {
                ends.closed_at[t] = i as u32;
            }
            ControlFlow::Continue(closed)
        });
        walk.ok().map(|()| ends)
    }

    /// Windows of the view whose lists hold at most `budget`: bands of whole tile rows, top to
    /// bottom, and where a single tile row holds more than the budget, spans of its tiles, left
    /// to right. A single tile is never split, so a window may exceed the entry budget when one
    /// tile alone does.
    pub fn windows(&self, budget: BinBudget) -> Vec<Window> {
        let row_entries: Vec<u64> =
            (0..self.tiles_y).map(|ty| self.row(ty).iter().map(|&n| u64::from(n)).sum()).collect();
        let row_pixels = u64::from(self.tiles_x) * u64::from(TILE_SIZE * TILE_SIZE);
        let mut windows = Vec::new();
        let mut ty = 0;
        while ty < self.tiles_y {
            if row_entries[ty as usize] > budget.entries || row_pixels > budget.pixels {
                windows.extend(self.row_spans(ty, budget));
                ty += 1;
                continue;
            }
            let (mut end, mut entries, mut pixels) = (ty, 0u64, 0u64);
            while end < self.tiles_y
                && entries + row_entries[end as usize] <= budget.entries
                && pixels + row_pixels <= budget.pixels
            {
                entries += row_entries[end as usize];
                pixels += row_pixels;
                end += 1;
            }
            windows.push(self.view.tiles([0, self.tiles_x, ty, end]));
            ty = end;
        }
        windows
    }

    /// Spans of tile row `ty` within `budget`, left to right.
    fn row_spans(&self, ty: u32, budget: BinBudget) -> Vec<Window> {
        let tile_pixels = u64::from(TILE_SIZE * TILE_SIZE);
        let (mut spans, mut start, mut entries) = (Vec::new(), 0, 0u64);
        for (tx, &length) in (0..).zip(self.row(ty)) {
            let pixels = u64::from(tx - start) * tile_pixels;
            if tx > start && (entries + u64::from(length) > budget.entries || pixels + tile_pixels > budget.pixels) {
                spans.push(self.view.tiles([start, tx, ty, ty + 1]));
                (start, entries) = (tx, 0);
            }
            entries += u64::from(length);
        }
        spans.push(self.view.tiles([start, self.tiles_x, ty, ty + 1]));
        spans
    }

    fn row(&self, ty: u32) -> &[u32] {
        let start = (ty * self.tiles_x) as usize;
        &self.lengths[start..start + self.tiles_x as usize]
    }

    /// The lists of `window` (made of whole tiles of the view, as [`ListEnds::windows`] gives
    /// them) of the `count` items with boxes `bbox` these ends were found for: `entries` are
    /// item positions, front to back in each tile.
    pub fn bin(&self, count: usize, bbox: impl Fn(usize) -> [u32; 4], window: Window) -> TileBins {
        let (tiles_x, tiles_y) = window.tile_counts();
        let (ox, oy) = ((window.x0 - self.view.x0) / TILE_SIZE, (window.y0 - self.view.y0) / TILE_SIZE);
        let view_tile = |tx: u32, ty: u32| ((ty + oy) * self.tiles_x + tx + ox) as usize;
        let mut offsets = Vec::with_capacity((tiles_x * tiles_y) as usize + 1);
        offsets.push(0usize);
        for ty in 0..tiles_y {
            for tx in 0..tiles_x {
                offsets.push(offsets.last().expect("starts with 0") + self.lengths[view_tile(tx, ty)] as usize);
            }
        }
        let mut cursor = offsets.clone();
        let mut entries = vec![0u32; *offsets.last().expect("starts with 0")];
        let walk = walk_open_tiles(count, bbox, window, |i, _, tx, ty| {
            let t = (ty * tiles_x + tx) as usize;
            entries[cursor[t]] = i as u32;
            cursor[t] += 1;
            ControlFlow::<(), _>::Continue(self.closed_at[view_tile(tx, ty)] == i as u32)
        });
        debug_assert!(walk.is_ok(), "filling the lists is never stopped");
        debug_assert_eq!(cursor[..cursor.len() - 1], offsets[1..], "the lists are as long as counted");
        TileBins { window, tiles_x, tiles_y, offsets, entries }
    }
}

/// The blend work of an entry of tile row `ty` of `view` for an item with pixel box `bbox`:
/// one, plus the box's pixel rows in that tile row.
fn entry_work([_, _, y0, y1]: [u32; 4], view: Window, ty: u32) -> u64 {
    let top = view.y0 + ty * TILE_SIZE;
    let rows = y1.min(top + TILE_SIZE).saturating_sub(y0.max(top));
    1 + u64::from(rows)
}

/// Walks `count` items (front to back) with pixel boxes `bbox` over the tiles of `window` that
/// each meets and that are still open, calling `visit(item, its box, tx, ty)`; a tile closes
/// when `visit` continues with true, the walk ends once every tile has closed, and stops where
/// `visit` breaks.
fn walk_open_tiles<B>(
    count: usize,
    bbox: impl Fn(usize) -> [u32; 4],
    window: Window,
    mut visit: impl FnMut(usize, [u32; 4], u32, u32) -> ControlFlow<B, bool>,
) -> Result<(), B> {
    let (tiles_x, tiles_y) = window.tile_counts();
    let mut open = OpenTiles::new(tiles_x, tiles_y);
    for i in 0..count {
        if open.none() {
            break;
        }
        let item = bbox(i);
        let Some(range) = tile_box(item, window) else { continue };
        if let ControlFlow::Break(b) = open.walk(range, |tx, ty| visit(i, item, tx, ty)) {
            return Err(b);
        }
    }
    Ok(())
}

/// The tiles [tx0, tx1) x [ty0, ty1) of `window` that the pixel box `bbox` meets, if any.
fn tile_box([x0, x1, y0, y1]: [u32; 4], window: Window) -> Option<[u32; 4]> {
    let [x0, x1] = [x0.max(window.x0), x1.min(window.x0 + window.width)];
    let [y0, y1] = [y0.max(window.y0), y1.min(window.y0 + window.height)];
    (x0 < x1 && y0 < y1).then(|| {
        let (xs, ys) = (tile_range(x0 - window.x0, x1 - window.x0), tile_range(y0 - window.y0, y1 - window.y0));
        [xs.start, xs.end, ys.start, ys.end]
    })
}

/// The tiles not yet closed, row by row: in each row, every tile points to the first open tile
/// at or after it (closed tiles are skipped in near-constant time, pointers being shortened as
/// they are followed), so a walk over a box costs its open tiles plus one step per row.
struct OpenTiles {
    tiles_x: u32,
    /// Per row, `tiles_x + 1` pointers (the last, one past the row, is never closed).
    next: Vec<u32>,
    open_in_row: Vec<u32>,
    open: usize,
}

impl OpenTiles {
    fn new(tiles_x: u32, tiles_y: u32) -> Self {
        let next = (0..tiles_y).flat_map(|_| 0..=tiles_x).collect();
        Self { tiles_x, next, open_in_row: vec![tiles_x; tiles_y as usize], open: (tiles_x * tiles_y) as usize }
    }

    fn none(&self) -> bool {
        self.open == 0
    }

    /// Calls `visit(tx, ty)` for the open tiles of [tx0, tx1) x [ty0, ty1), row by row, left to
    /// right; a tile closes when `visit` continues with true, and the walk stops where it breaks.
    fn walk<B>(
        &mut self,
        [tx0, tx1, ty0, ty1]: [u32; 4],
        mut visit: impl FnMut(u32, u32) -> ControlFlow<B, bool>,
    ) -> ControlFlow<B> {
        let stride = self.tiles_x as usize + 1;
        for ty in ty0..ty1 {
            if self.open_in_row[ty as usize] == 0 {
                continue;
            }
            let row = &mut self.next[ty as usize * stride..(ty as usize + 1) * stride];
            let mut tx = first_open(row, tx0);
            while tx < tx1 {
                if visit(tx, ty)? {
                    row[tx as usize] = tx + 1;
                    self.open_in_row[ty as usize] -= 1;
                    self.open -= 1;
                }
                tx = first_open(row, tx + 1);
            }
        }
        ControlFlow::Continue(())
    }
}

/// The first open tile at or after `tx` in `row`, halving the paths followed.
fn first_open(row: &mut [u32], mut tx: u32) -> u32 {
    while row[tx as usize] != tx {
        let skip = row[row[tx as usize] as usize];
        row[tx as usize] = skip;
        tx = skip;
    }
    tx
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every list of a window holds exactly the items whose boxes meet its tile, up to the
    /// position where the tile closed, in order; windows split the view within the budget.
    #[test]
    fn lists_hold_the_overlapping_items_up_to_where_their_tile_closed() {
        let view = Window { x0: 0, y0: 0, width: 100, height: 70 };
        let boxes: Vec<[u32; 4]> = (0..300u32)
            .map(|i| {
                let (x, y, w, h) = ((i * 37) % 97, (i * 53) % 67, 1 + (i * 7) % 60, 1 + (i * 11) % 40);
                [x, (x + w).min(100), y, (y + h).min(70)]
            })
            .collect();
        // Tile (tx, ty) closes at the (tx + ty + 2)-th item that reaches it.
        let mut reached = [0u32; 7 * 5];
        let mut closes = |_, tx, ty| {
            let t = (ty * 7 + tx) as usize;
            reached[t] += 1;
            reached[t] == tx + ty + 2
        };
        let ends = ListEnds::closing(boxes.len(), |i| boxes[i], view, u64::MAX, &mut closes).expect("no limit");
        let expected = |tx: u32, ty: u32| -> Vec<u32> {
            let (px, py) = (tx * TILE_SIZE, ty * TILE_SIZE);
            let meets = |b: &[u32; 4]| b[0] < px + TILE_SIZE && b[1] > px && b[2] < py + TILE_SIZE && b[3] > py;
            (0..300u32).filter(|&i| meets(&boxes[i as usize])).take((tx + ty + 2) as usize).collect()
        };
        for budget in [BinBudget { entries: 1 << 20, pixels: 1 << 20 }, BinBudget { entries: 30, pixels: 1 << 20 }] {
            let windows = ends.windows(budget);
            assert_eq!(windows.len() > 1, budget.entries == 30, "{budget:?}");
            let mut covered = 0;
            for w in windows {
                let bins = ends.bin(boxes.len(), |i| boxes[i], w);
                assert!(bins.entries.len() as u64 <= budget.entries || bins.tiles_x * bins.tiles_y == 1, "{w:?}");
                for t in 0..(bins.tiles_x * bins.tiles_y) as usize {
                    let [x0, _, y0, _] = bins.tile_rect(t);
                    assert_eq!(bins.tile(t), expected(x0 / TILE_SIZE, y0 / TILE_SIZE), "window {w:?}, tile {t}");
                }
                covered += w.width * w.height;
            }
            assert_eq!(covered, 100 * 70, "the windows tile the view");
        }
        let work: u64 = (0..7 * 5)
            .map(|t| {
                let (tx, ty) = (t % 7, t / 7);
                let rows = |i: u32| {
                    let [_, _, y0, y1] = boxes[i as usize];
                    u64::from(y1.min((ty + 1) * TILE_SIZE) - y0.max(ty * TILE_SIZE))
                };
                expected(tx, ty).into_iter().map(|i| 1 + rows(i)).sum::<u64>()
            })
            .sum();
        assert_eq!(ends.work, work, "one unit per entry and one per pixel row of its box in its tile");
    }

    /// Finding list ends stops as soon as their work passes the limit, and only then.
    #[test]
    fn list_ends_are_refused_past_the_work_limit() {
        let view = Window { x0: 0, y0: 0, width: 64, height: 40 };
        let boxes: Vec<[u32; 4]> = (0..50u32).map(|i| [i % 30, 34 + i % 30, i % 20, 20 + i % 20]).collect();
        let full = ListEnds::full(boxes.len(), |i| boxes[i], view);
        let never = |_, _, _| false;
        let within = ListEnds::closing(boxes.len(), |i| boxes[i], view, full.work, never).expect("at the limit");
        assert_eq!(
            (within.work, &within.lengths),
            (full.work, &full.lengths),
            "lists that never close are the full lists"
        );
        assert_eq!(ListEnds::closing(boxes.len(), |i| boxes[i], view, full.work - 1, never), None);
        let limit = BlendLimit { per_pixel: 3, per_gaussian: 5, fixed: 7 };
        assert_eq!(limit.of(view, 11), 7 + 3 * 64 * 40 + 5 * 11);
        assert_eq!(BlendLimit::NONE.of(view, 11), u64::MAX);
    }

    /// The full lists' lengths (a difference array) count every box that meets each tile, and
    /// their lists hold exactly those boxes.
    #[test]
    fn full_lists_hold_every_overlapping_item() {
        let view = Window { x0: 0, y0: 0, width: 90, height: 45 };
        let boxes: Vec<[u32; 4]> = (0..200u32)
            .map(|i| {
                let (x, y, w, h) = ((i * 31) % 89, (i * 17) % 44, 1 + (i * 13) % 70, 1 + (i * 5) % 30);
                [x, (x + w).min(90), y, (y + h).min(45)]
            })
            .collect();
        let ends = ListEnds::full(boxes.len(), |i| boxes[i], view);
        let bins = ends.bin(boxes.len(), |i| boxes[i], view);
        for t in 0..(ends.tiles_x * ends.tiles_y) as usize {
            let [x0, x1, y0, y1] = bins.tile_rect(t);
            let meets = |b: &[u32; 4]| b[0] < x1 && b[1] > x0 && b[2] < y1 && b[3] > y0;
            let meeting: Vec<u32> = (0..200u32).filter(|&i| meets(&boxes[i as usize])).collect();
            assert_eq!(ends.lengths[t] as usize, meeting.len(), "tile {t}");
            assert_eq!(bins.tile(t), meeting, "tile {t}");
        }
        assert!(ends.closed_at.iter().all(|&c| c == OPEN));
    }
}

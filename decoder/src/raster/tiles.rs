//! Binning of depth-sorted splats into 16x16 pixel tiles of the rendered window.
//!
//! Splats arrive sorted front to back; a counting sort by tile keeps that order inside each
//! tile, so no per-tile sort is needed and the result does not depend on threading.

use super::lanes::prefetch;
use super::project::Splat;
use super::{TILE_SIZE, Window};

/// For each tile (row-major), the splats that may touch it, front to back.
#[derive(Debug, Clone, PartialEq)]
pub struct TileBins {
    /// The part of the image rendered; tiles start at its top left corner.
    pub window: Window,
    pub tiles_x: u32,
    pub tiles_y: u32,
    /// `entries[offsets[t]..offsets[t + 1]]` are tile t's splats.
    pub offsets: Vec<usize>,
    /// Indices into the splat list.
    pub entries: Vec<u32>,
}

impl TileBins {
    /// Splat indices of tile `t`, front to back.
    pub fn tile(&self, t: usize) -> &[u32] {
        &self.entries[self.offsets[t]..self.offsets[t + 1]]
    }

    /// Pixel rectangle of tile `t` in image coordinates: x in [x0, x1), y in [y0, y1).
    pub fn tile_rect(&self, t: usize) -> [u32; 4] {
        let w = self.window;
        let (tx, ty) = (t as u32 % self.tiles_x, t as u32 / self.tiles_x);
        let (x0, y0) = (w.x0 + tx * TILE_SIZE, w.y0 + ty * TILE_SIZE);
        [x0, (x0 + TILE_SIZE).min(w.x0 + w.width), y0, (y0 + TILE_SIZE).min(w.y0 + w.height)]
    }

    /// Tile `t`'s splats with their positions in its list, in the given order (see
    /// [`TileSplats`]). The first block of tile t + 1 (the one the blend loops walk next) is
    /// requested from memory now, so that it arrives while this tile is blended.
    pub fn splats<'a>(&'a self, t: usize, splats: &'a [Splat], order: ListOrder) -> TileSplats<'a> {
        if t + 1 < self.offsets.len() - 1 {
            let next = self.tile(t + 1);
            let first = match order {
                ListOrder::FrontToBack => &next[..next.len().min(GATHER_BLOCK)],
                ListOrder::BackToFront { .. } => &next[next.len().saturating_sub(GATHER_BLOCK)..],
            };
            for &i in first {
                prefetch(&splats[i as usize]);
            }
        }
        let list = self.tile(t);
        let (next, end) = match order {
            ListOrder::FrontToBack => (0, list.len()),
            ListOrder::BackToFront { end } => (end.min(list.len()), 0),
        };
        TileSplats {
            list,
            splats,
            reverse: matches!(order, ListOrder::BackToFront { .. }),
            next,
            end,
            block: Vec::with_capacity(GATHER_BLOCK),
        }
    }

    /// Index in the window's pixel arrays of image pixel (x, y).
    pub fn pixel_index(&self, x: u32, y: u32) -> usize {
        let w = self.window;
        (y - w.y0) as usize * w.width as usize + (x - w.x0) as usize
    }
}

/// Which way [`TileBins::splats`] walks a tile's list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ListOrder {
    FrontToBack,
    /// Positions `end - 1` down to 0.
    BackToFront {
        end: usize,
    },
}

/// Splats per copied block: a few kilobytes, enough misses in flight to hide the latency.
const GATHER_BLOCK: usize = 32;

/// The splats of one tile's list, in order, with their positions in the list, a block at a
/// time ([`TileSplats::next_block`]).
///
/// They are copied out of the splat array a block at a time. A tile's list indexes that array
/// (7 MB for 100k splats) at random; read in the blend loop, each splat's first load waited for
/// memory (a third of the vectorized blend's time on 100k splats at 504x378), while the block
/// copy's loads are independent, so the memory system serves them together.
pub struct TileSplats<'a> {
    list: &'a [u32],
    splats: &'a [Splat],
    reverse: bool,
    /// The next list position to copy, and where copying stops.
    next: usize,
    end: usize,
    block: Vec<(usize, Splat)>,
}

impl TileSplats<'_> {
    /// The next block of the tile's splats, with their positions in its list, in order; `None`
    /// after the last. The blend loops read each splat from the block where it was copied (an
    /// iterator handing out copies one at a time made each read wait for a store-to-load
    /// forwarding of the 80-byte item: a tenth of the vectorized blend's time).
    pub fn next_block(&mut self) -> Option<&[(usize, Splat)]> {
        self.block.clear();
        let (list, splats) = (self.list, self.splats);
        let block = self.block_from(self.next);
        if self.reverse {
            self.next = block.start;
            self.block.extend(block.rev().map(|k| (k, splats[list[k] as usize])));
        } else {
            self.next = block.end;
            self.block.extend(block.map(|k| (k, splats[list[k] as usize])));
        }
        // The next block's splats, requested now: they arrive while this block is blended.
        for k in self.block_from(self.next) {
            prefetch(&splats[list[k] as usize]);
        }
        (!self.block.is_empty()).then_some(self.block.as_slice())
    }

    /// The list positions of the block that `next` starts, in ascending order.
    fn block_from(&self, next: usize) -> std::ops::Range<usize> {
        if self.reverse {
            next.saturating_sub(GATHER_BLOCK).max(self.end)..next
        } else {
            next..(next + GATHER_BLOCK).min(self.end)
        }
    }
}

/// Tile range [t0, t1) covered by a pixel range [p0, p1).
fn tile_range(p0: u32, p1: u32) -> std::ops::Range<u32> {
    p0 / TILE_SIZE..(p1 - 1) / TILE_SIZE + 1
}

/// Bins splats (already sorted front to back, pixel boxes clipped to `window`) into the
/// window's tiles.
pub fn bin(splats: &[Splat], window: Window) -> TileBins {
    bin_boxes(splats.len(), |i| splats[i].bbox, window)
}

/// Bins `count` items, front to back, whose pixel boxes (x0, x1, y0, y1, clipped to `window`)
/// `bbox` gives: `entries` are positions in that order.
pub fn bin_boxes(count: usize, bbox: impl Fn(usize) -> [u32; 4], window: Window) -> TileBins {
    bin_boxes_with(count, bbox, window, Keep { row: |_, _| true, tile: |_, _| true })
}

/// [`bin_boxes`], listing only what `keep` keeps.
fn bin_boxes_with(
    count: usize,
    bbox: impl Fn(usize) -> [u32; 4],
    window: Window,
    keep: Keep<impl Fn(u32, usize) -> bool, impl Fn(usize, usize) -> bool>,
) -> TileBins {
    let tiles_x = window.width.div_ceil(TILE_SIZE);
    let tiles_y = window.height.div_ceil(TILE_SIZE);
    let tile_count = (tiles_x * tiles_y) as usize;
    let mut offsets = vec![0usize; tile_count + 1];
    let for_each_tile = |i: usize, f: &mut dyn FnMut(usize)| {
        let [x0, x1, y0, y1] = bbox(i);
        for ty in tile_range(y0 - window.y0, y1 - window.y0).filter(|&ty| (keep.row)(ty, i)) {
            for tx in tile_range(x0 - window.x0, x1 - window.x0) {
                let t = (ty * tiles_x + tx) as usize;
                if (keep.tile)(t, i) {
                    f(t);
                }
            }
        }
    };
    for i in 0..count {
        for_each_tile(i, &mut |t| offsets[t + 1] += 1);
    }
    for t in 0..tile_count {
        offsets[t + 1] += offsets[t];
    }
    let mut cursor = offsets.clone();
    let mut entries = vec![0u32; offsets[tile_count]];
    for i in 0..count {
        for_each_tile(i, &mut |t| {
            entries[cursor[t]] = i as u32;
            cursor[t] += 1;
        });
    }
    TileBins { window, tiles_x, tiles_y, offsets, entries }
}

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

/// Splits `full` into windows whose binning keeps within `budget`: bands of whole tile rows,
/// top to bottom, and where a single tile row holds more entries than the budget, spans of its
/// tiles, left to right. `count` items (front to back) have pixel boxes `bbox` (x0, x1, y0,
/// y1, inside `full`). A single tile is never split, so a window may exceed the entry budget
/// when one tile alone does (at most `count` entries).
///
/// Holding every tile's list at once takes items x tiles entries: 60,000 splats covering a
/// 1920x1080 view are 490M entries (2 GB). Windows keep memory bounded; the work stays that
/// of the entries, plus one pass over the items per window.
pub fn bounded_windows(count: usize, bbox: impl Fn(usize) -> [u32; 4], full: Window, budget: BinBudget) -> Vec<Window> {
    let tiles_x = full.width.div_ceil(TILE_SIZE);
    let tiles_y = full.height.div_ceil(TILE_SIZE);
    let tile_ranges = |i: usize| {
        let [x0, x1, y0, y1] = bbox(i);
        (tile_range(x0 - full.x0, x1 - full.x0), tile_range(y0 - full.y0, y1 - full.y0))
    };
    // Entries per tile row: each item adds its span of tiles to every row it covers.
    let mut rows = vec![0i64; tiles_y as usize + 1];
    for i in 0..count {
        let (xs, ys) = tile_ranges(i);
        rows[ys.start as usize] += i64::from(xs.len() as u32);
        rows[ys.end as usize] -= i64::from(xs.len() as u32);
    }
    let mut running = 0i64;
    let row_entries: Vec<u64> = rows[..tiles_y as usize]
        .iter()
        .map(|d| {
            running += d;
            running as u64
        })
        .collect();
    let row_pixels = u64::from(tiles_x) * u64::from(TILE_SIZE * TILE_SIZE);
    let tile_rows = |ty0: u32, ty1: u32| {
        let y0 = full.y0 + ty0 * TILE_SIZE;
        Window { x0: full.x0, y0, width: full.width, height: (ty1 * TILE_SIZE).min(full.height) - ty0 * TILE_SIZE }
    };
    let mut windows = Vec::new();
    let mut ty = 0;
    while ty < tiles_y {
        if row_entries[ty as usize] > budget.entries || row_pixels > budget.pixels {
            windows.extend(row_spans(count, &tile_ranges, tile_rows(ty, ty + 1), ty, budget));
            ty += 1;
            continue;
        }
        let (mut end, mut entries, mut pixels) = (ty, 0u64, 0u64);
        while end < tiles_y
            && entries + row_entries[end as usize] <= budget.entries
            && pixels + row_pixels <= budget.pixels
        {
            entries += row_entries[end as usize];
            pixels += row_pixels;
            end += 1;
        }
        windows.push(tile_rows(ty, end));
        ty = end;
    }
    windows
}

/// Spans of tile row `ty` (the window `row`) within `budget`, left to right.
fn row_spans(
    count: usize,
    tile_ranges: &impl Fn(usize) -> (std::ops::Range<u32>, std::ops::Range<u32>),
    row: Window,
    ty: u32,
    budget: BinBudget,
) -> Vec<Window> {
    let tiles_x = row.width.div_ceil(TILE_SIZE);
    let mut columns = vec![0i64; tiles_x as usize + 1];
    for i in 0..count {
        let (xs, ys) = tile_ranges(i);
        if ys.contains(&ty) {
            columns[xs.start as usize] += 1;
            columns[xs.end as usize] -= 1;
        }
    }
    let tile_pixels = u64::from(TILE_SIZE * TILE_SIZE);
    let span = |tx0: u32, tx1: u32| Window {
        x0: row.x0 + tx0 * TILE_SIZE,
        width: (tx1 * TILE_SIZE).min(row.width) - tx0 * TILE_SIZE,
        ..row
    };
    let (mut spans, mut start, mut entries, mut running) = (Vec::new(), 0, 0u64, 0i64);
    for tx in 0..tiles_x {
        running += columns[tx as usize];
        let pixels = u64::from(tx - start) * tile_pixels;
        if tx > start && (entries + running as u64 > budget.entries || pixels + tile_pixels > budget.pixels) {
            spans.push(span(start, tx));
            (start, entries) = (tx, 0);
        }
        entries += running as u64;
    }
    spans.push(span(start, tiles_x));
    spans
}

/// Bins, into `window`'s tiles, the items among `count` (front to back) whose pixel boxes
/// `bbox` meet the window, their boxes clipped to it: `entries` are item positions, as
/// [`bin_boxes`] gives them for all items.
pub fn bin_window(count: usize, bbox: impl Fn(usize) -> [u32; 4], window: Window) -> TileBins {
    bin_window_with(count, bbox, window, Keep { row: |_, _| true, tile: |_, _| true })
}

/// Which items a binning lists: item `i` in tile row `ty` only where `row(ty, i)` (a cheap test
/// that skips whole rows), and in tile `t` only where `tile(t, i)` (tiles and rows numbered in
/// the window).
pub struct Keep<R: Fn(u32, usize) -> bool, T: Fn(usize, usize) -> bool> {
    pub row: R,
    pub tile: T,
}

/// [`bin_window`], listing only what `keep` keeps.
pub fn bin_window_with(
    count: usize,
    bbox: impl Fn(usize) -> [u32; 4],
    window: Window,
    keep: Keep<impl Fn(u32, usize) -> bool, impl Fn(usize, usize) -> bool>,
) -> TileBins {
    let (x_end, y_end) = (window.x0 + window.width, window.y0 + window.height);
    let clipped = |i: usize| {
        let [x0, x1, y0, y1] = bbox(i);
        [x0.max(window.x0), x1.min(x_end), y0.max(window.y0), y1.min(y_end)]
    };
    let inside: Vec<u32> = (0..count)
        .filter(|&i| {
            let [x0, x1, y0, y1] = clipped(i);
            x0 < x1 && y0 < y1
        })
        .map(|i| i as u32)
        .collect();
    let item = |k: usize| inside[k] as usize;
    let keep = Keep { row: |ty, k| (keep.row)(ty, item(k)), tile: |t, k| (keep.tile)(t, item(k)) };
    let mut bins = bin_boxes_with(inside.len(), |k| clipped(item(k)), window, keep);
    bins.entries.iter_mut().for_each(|e| *e = inside[*e as usize]);
    bins
}

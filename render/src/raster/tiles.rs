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
        self.window.tile_rect(t as u32 % self.tiles_x, t as u32 / self.tiles_x)
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
pub(super) fn tile_range(p0: u32, p1: u32) -> std::ops::Range<u32> {
    p0 / TILE_SIZE..(p1 - 1) / TILE_SIZE + 1
}

/// Bins splats (already sorted front to back, pixel boxes clipped to `window`) into the
/// window's tiles, every list whole (the training path's binning, whose backward pass walks
/// them; colour renders bin in bounded memory, [`super::tile_lists`]).
pub fn bin(splats: &[Splat], window: Window) -> TileBins {
    let (tiles_x, tiles_y) = window.tile_counts();
    let tile_count = (tiles_x * tiles_y) as usize;
    let mut offsets = vec![0usize; tile_count + 1];
    let for_each_tile = |s: &Splat, f: &mut dyn FnMut(usize)| {
        let [x0, x1, y0, y1] = s.bbox;
        for ty in tile_range(y0 - window.y0, y1 - window.y0) {
            for tx in tile_range(x0 - window.x0, x1 - window.x0) {
                f((ty * tiles_x + tx) as usize);
            }
        }
    };
    for s in splats {
        for_each_tile(s, &mut |t| offsets[t + 1] += 1);
    }
    for t in 0..tile_count {
        offsets[t + 1] += offsets[t];
    }
    let mut cursor = offsets.clone();
    let mut entries = vec![0u32; offsets[tile_count]];
    for (i, s) in splats.iter().enumerate() {
        for_each_tile(s, &mut |t| {
            entries[cursor[t]] = i as u32;
            cursor[t] += 1;
        });
    }
    TileBins { window, tiles_x, tiles_y, offsets, entries }
}

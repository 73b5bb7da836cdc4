//! The anchors' context grid (HAC's binary hash grid, issue 15): a few 3D grids of binary
//! entries at dyadic resolutions over the anchors' octree cube, each entry holding a few ±1
//! channels. An anchor's context is, per level, the trilinear interpolation of the 8 entries
//! around it; an entropy model maps it to the means and scales of that anchor's attributes, so
//! that the model adapts to where the anchor is.
//!
//! Everything here is integer arithmetic or IEEE `* - +` in a fixed order, so that the encoder
//! and every decoder compute the same context bit for bit: an anchor sits on integer octree
//! coordinates and a level's cells are 2^s voxels wide, so its interpolation weights are
//! dyadic fractions (exact in binary32 for s <= 8).

/// The shape of a context grid.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ContextGridShape {
    /// Per level, r: the level has 2^r cells per axis over the octree cube (fewer when the
    /// cube is smaller: a cell is never narrower than a voxel).
    pub levels: Vec<u8>,
    /// A level with more corner points than 2^table_log2 is hashed into that many entries.
    pub table_log2: u8,
    /// ±1 channels per entry.
    pub channels: u8,
}

/// One of the 8 entries an anchor's context interpolates on a level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    /// Entry index in the concatenation of every level's table.
    pub entry: u32,
    pub weight: f32,
}

/// The multipliers of HAC's (and Instant-NGP's) spatial hash, per axis.
const HASH_PRIMES: [u32; 3] = [1, 2_654_435_761, 805_459_861];

impl ContextGridShape {
    /// Log2 of a level's cell width, in voxels, on an octree of `depth` levels.
    fn cell_log2(r: u8, depth: u8) -> u8 {
        depth.saturating_sub(r)
    }

    /// Corner points per axis of a level: cells + 1.
    fn side(r: u8, depth: u8) -> u64 {
        (1u64 << (depth - Self::cell_log2(r, depth))) + 1
    }

    /// Whether a level stores each corner point (else it hashes them).
    fn dense(&self, r: u8, depth: u8) -> bool {
        Self::side(r, depth).pow(3) <= 1u64 << self.table_log2
    }

    /// Entries of one level's table.
    pub fn level_entries(&self, r: u8, depth: u8) -> u32 {
        match self.dense(r, depth) {
            true => Self::side(r, depth).pow(3) as u32,
            false => 1 << self.table_log2,
        }
    }

    /// Entries of every level's table together.
    pub fn entries(&self, depth: u8) -> u32 {
        self.levels.iter().map(|&r| self.level_entries(r, depth)).sum()
    }

    /// Length of an anchor's context: one value per level and channel.
    pub fn context_len(&self) -> usize {
        self.levels.len() * usize::from(self.channels)
    }

    /// Appends the 8 corners of every level (level by level; corners in x, then y, then z
    /// order of their offset bits) of the anchor at `q` on an octree of `depth` levels.
    pub fn corners(&self, q: [u32; 3], depth: u8, out: &mut Vec<Corner>) {
        let mut base = 0u32;
        for &r in &self.levels {
            let s = Self::cell_log2(r, depth);
            let cell = q.map(|c| c >> s);
            let unit = (1u32 << s) as f32;
            let t = q.map(|c| (c & ((1u32 << s) - 1)) as f32 / unit);
            let side = Self::side(r, depth) as u32;
            let dense = self.dense(r, depth);
            for bits in 0..8u32 {
                let b = [bits & 1, (bits >> 1) & 1, (bits >> 2) & 1];
                let p: [u32; 3] = std::array::from_fn(|a| cell[a] + b[a]);
                let index = match dense {
                    true => p[0] + side * (p[1] + side * p[2]),
                    false => {
                        let h = (0..3).fold(0u32, |h, a| h ^ p[a].wrapping_mul(HASH_PRIMES[a]));
                        h & ((1u32 << self.table_log2) - 1)
                    }
                };
                let factor = |a: usize| if b[a] == 1 { t[a] } else { 1.0 - t[a] };
                let weight = factor(0) * factor(1) * factor(2);
                out.push(Corner { entry: base + index, weight });
            }
            base += self.level_entries(r, depth);
        }
    }

    /// Which entries of the grid on an octree of `depth` any of `corners` weighs (weight > 0):
    /// the only ones whose signs affect a context.
    pub fn used_entries(&self, corners: &[Corner], depth: u8) -> Vec<bool> {
        let mut used = vec![false; self.entries(depth) as usize];
        corners.iter().filter(|c| c.weight > 0.0).for_each(|c| used[c.entry as usize] = true);
        used
    }

    /// An anchor's context from its corners ([`Self::corners`]) and the table (entry-major,
    /// `channels` bits per entry, true for +1): per level and channel, the weighted sum of the
    /// corners' ±1 values in corner order.
    pub fn context(&self, corners: &[Corner], table: &[bool]) -> Vec<f32> {
        let c = usize::from(self.channels);
        let mut out = Vec::with_capacity(self.context_len());
        for level in corners.chunks_exact(8) {
            for channel in 0..c {
                let value = |k: &Corner| if table[k.entry as usize * c + channel] { k.weight } else { -k.weight };
                out.push(level.iter().fold(0.0f32, |sum, k| sum + value(k)));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape() -> ContextGridShape {
        ContextGridShape { levels: vec![1, 3, 6], table_log2: 8, channels: 2 }
    }

    #[test]
    fn small_levels_are_dense_and_large_ones_hashed() {
        let s = shape();
        // Depth 4: r = 1 has 3^3 = 27 points, r = 3 has 9^3 = 729 > 256 (hashed), r = 6 is as
        // fine as the voxels (17^3, hashed).
        assert_eq!(s.level_entries(1, 4), 27);
        assert_eq!(s.level_entries(3, 4), 256);
        assert_eq!(s.level_entries(6, 4), 256);
        assert_eq!(s.entries(4), 27 + 512);
        assert_eq!(s.context_len(), 6);
    }

    #[test]
    fn weights_are_trilinear_and_sum_to_one() {
        let s = shape();
        let mut corners = Vec::new();
        // Depth 4, level r = 1: cells of 8 voxels; q = (3, 0, 7) lies 3/8, 0, 7/8 into cell 0.
        s.corners([3, 0, 7], 4, &mut corners);
        assert_eq!(corners.len(), 24);
        let level0 = &corners[..8];
        assert_eq!(level0[0], Corner { entry: 0, weight: 0.625 * 1.0 * 0.125 });
        assert_eq!(level0[1], Corner { entry: 1, weight: 0.375 * 1.0 * 0.125 });
        assert_eq!(level0[4].entry, 9, "z + 1 is one plane of 3 x 3 further");
        assert_eq!(level0[4].weight, 0.625 * 0.875);
        for level in corners.chunks_exact(8) {
            assert_eq!(level.iter().map(|c| c.weight).sum::<f32>(), 1.0);
            assert!(level.iter().all(|c| c.entry < s.entries(4)));
        }
        // Hashed levels start after the dense one's 27 entries.
        assert!(corners[8..16].iter().all(|c| (27..27 + 256).contains(&c.entry)));
        // At the finest level an anchor sits on a corner: all the weight on one entry.
        assert_eq!(corners[16].weight, 1.0);
        assert!(corners[17..24].iter().all(|c| c.weight == 0.0));
    }

    #[test]
    fn the_context_interpolates_the_signs() {
        let s = ContextGridShape { levels: vec![1], table_log2: 8, channels: 2 };
        let mut corners = Vec::new();
        // Depth 2, r = 1: cells of 2 voxels; q.x = 1 is halfway between corner points 0 and 1.
        s.corners([1, 0, 0], 2, &mut corners);
        let mut table = vec![false; 2 * s.entries(2) as usize];
        table[0] = true; // entry 0, channel 0
        table[2] = true; // entry 1, channel 0
        table[1] = true; // entry 0, channel 1 (entry 1's stays -1)
        assert_eq!(s.context(&corners, &table), vec![1.0, 0.0]);
        table[2] = false;
        assert_eq!(s.context(&corners, &table), vec![0.0, 0.0]);
    }
}

//! The anchors' context grid (HAC's binary hash grid): a few 3D grids of binary
//! entries at dyadic resolutions over the anchors' octree cube, each entry holding a few ±1
//! channels. An anchor's context is, per level, the trilinear interpolation of the 8 entries
//! around it; an entropy model maps it to the means and scales of that anchor's attributes, so
//! that the model adapts to where the anchor is. HAC's 2D planes add, per plane level, three
//! 2D grids (xy, xz, yz) interpolated bilinearly: a plane entry is shared by a line of cells,
//! so a plane level can be finer than a 3D level of the same table size.
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
    /// Per plane level, r as for `levels`: the level has three 2D grids, xy, xz and yz.
    pub planes: Vec<u8>,
    /// A grid with more corner points than 2^table_log2 is hashed into that many entries.
    pub table_log2: u8,
    /// ±1 channels per entry.
    pub channels: u8,
}

/// One of the 8 entries an anchor's context interpolates on a 3D level, or of the 4 on a plane
/// (then followed by 4 corners of weight 0, so that every group of corners has 8).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    /// Entry index in the concatenation of every level's table.
    pub entry: u32,
    pub weight: f32,
}

/// The multipliers of HAC's (and Instant-NGP's) spatial hash, per axis (a plane hashes its two
/// axes with the first two).
const HASH_PRIMES: [u32; 3] = [1, 2_654_435_761, 805_459_861];

/// The axes of the three planes of a plane level, in order: xy, xz, yz.
const PLANE_AXES: [[usize; 2]; 3] = [[0, 1], [0, 2], [1, 2]];

impl ContextGridShape {
    /// Log2 of a level's cell width, in voxels, on an octree of `depth` levels.
    fn cell_log2(r: u8, depth: u8) -> u8 {
        depth.saturating_sub(r)
    }

    /// Corner points per axis of a level: cells + 1.
    fn side(r: u8, depth: u8) -> u64 {
        (1u64 << (depth - Self::cell_log2(r, depth))) + 1
    }

    /// Whether a grid of `dims` dimensions (3, or 2 for a plane) at level `r` stores each
    /// corner point, which it does when they fit in 2^table_log2 entries (else it hashes them).
    fn dense(&self, r: u8, depth: u8, dims: u32) -> bool {
        Self::side(r, depth).saturating_pow(dims) <= 1u64 << self.table_log2
    }

    /// Entries of one grid of `dims` dimensions at level `r`: its corner points when dense,
    /// else 2^table_log2.
    fn grid_entries(&self, r: u8, depth: u8, dims: u32) -> u32 {
        match self.dense(r, depth, dims) {
            true => Self::side(r, depth).pow(dims) as u32,
            false => 1 << self.table_log2,
        }
    }

    /// Entries of one 3D level's table.
    pub fn level_entries(&self, r: u8, depth: u8) -> u32 {
        self.grid_entries(r, depth, 3)
    }

    /// Entries of every table together: the 3D levels', then each plane level's three planes'.
    pub fn entries(&self, depth: u8) -> u32 {
        let volumes: u32 = self.levels.iter().map(|&r| self.level_entries(r, depth)).sum();
        volumes + self.planes.iter().map(|&r| 3 * self.grid_entries(r, depth, 2)).sum::<u32>()
    }

    /// Groups of 8 corners per anchor: one per 3D level, three per plane level.
    pub fn groups(&self) -> usize {
        self.levels.len() + 3 * self.planes.len()
    }

    /// Length of an anchor's context: one value per group and channel.
    pub fn context_len(&self) -> usize {
        self.groups() * usize::from(self.channels)
    }

    /// Appends the corners of every group of the anchor at `q` on an octree of `depth` levels:
    /// per 3D level its 8 corners (in x, then y, then z order of their offset bits), then per
    /// plane level and plane (xy, xz, yz) its 4 corners (first axis, then second) and 4 of
    /// weight 0.
    pub fn corners(&self, q: [u32; 3], depth: u8, out: &mut Vec<Corner>) {
        let grid = |r: u8, dims: u32, base: u32| Grid {
            r,
            depth,
            dense: self.dense(r, depth, dims),
            table_log2: self.table_log2,
            base,
        };
        let mut base = 0u32;
        for &r in &self.levels {
            grid_corners(q, [0, 1, 2], grid(r, 3, base), out);
            base += self.level_entries(r, depth);
        }
        for &r in &self.planes {
            for axes in PLANE_AXES {
                grid_corners(q, axes, grid(r, 2, base), out);
                out.extend([Corner { entry: base, weight: 0.0 }; 4]);
                base += self.grid_entries(r, depth, 2);
            }
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
    /// `channels` bits per entry, true for +1): per group and channel, the weighted sum of the
    /// corners' ±1 values in corner order (a plane's corners of weight 0 add ±0, which leaves
    /// a sum that starts at +0 unchanged).
    pub fn context(&self, corners: &[Corner], table: &[bool]) -> Vec<f32> {
        let c = usize::from(self.channels);
        let mut out = Vec::with_capacity(self.context_len());
        for group in corners.chunks_exact(8) {
            for channel in 0..c {
                let value = |k: &Corner| if table[k.entry as usize * c + channel] { k.weight } else { -k.weight };
                out.push(group.iter().fold(0.0f32, |sum, k| sum + value(k)));
            }
        }
        out
    }
}

/// One grid of a level: where its table starts and how it is indexed.
struct Grid {
    r: u8,
    depth: u8,
    /// Whether it stores each corner point (else it hashes them).
    dense: bool,
    table_log2: u8,
    /// Its first entry in the concatenation of every table.
    base: u32,
}

/// Appends the 2^D corners (D = `axes.len()`: 3 for a level, 2 for a plane) around `q` on
/// `grid`, over the axes `axes` of `q`; the corners' offset bits go in axis order.
fn grid_corners<const D: usize>(q: [u32; 3], axes: [usize; D], grid: Grid, out: &mut Vec<Corner>) {
    let s = ContextGridShape::cell_log2(grid.r, grid.depth);
    let side = ContextGridShape::side(grid.r, grid.depth) as u32;
    let unit = (1u32 << s) as f32;
    let coords = axes.map(|a| q[a]);
    let cell = coords.map(|c| c >> s);
    let t = coords.map(|c| (c & ((1u32 << s) - 1)) as f32 / unit);
    for bits in 0..1u32 << D {
        let b: [u32; D] = std::array::from_fn(|a| (bits >> a) & 1);
        let p: [u32; D] = std::array::from_fn(|a| cell[a] + b[a]);
        let index = match grid.dense {
            true => p.iter().rev().fold(0u32, |index, &c| index * side + c),
            false => {
                let h = (0..D).fold(0u32, |h, a| h ^ p[a].wrapping_mul(HASH_PRIMES[a]));
                h & ((1u32 << grid.table_log2) - 1)
            }
        };
        let factor = |a: usize| if b[a] == 1 { t[a] } else { 1.0 - t[a] };
        let weight = (1..D).fold(factor(0), |w, a| w * factor(a));
        out.push(Corner { entry: grid.base + index, weight });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape() -> ContextGridShape {
        ContextGridShape { levels: vec![1, 3, 6], planes: vec![], table_log2: 8, channels: 2 }
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
        let s = ContextGridShape { levels: vec![1], planes: vec![], table_log2: 8, channels: 2 };
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

    #[test]
    fn planes_interpolate_bilinearly_after_the_levels() {
        let s = ContextGridShape { levels: vec![1], planes: vec![1, 3], table_log2: 6, channels: 1 };
        // Depth 2, plane level r = 1: cells of 2 voxels, 3 x 3 = 9 points per plane (dense);
        // r = 3 is as fine as the voxels, 5 x 5 = 25 points (dense). 27 + 3 * 9 + 3 * 25.
        assert_eq!(s.entries(2), 27 + 27 + 75);
        assert_eq!((s.groups(), s.context_len()), (7, 7));
        let mut corners = Vec::new();
        s.corners([1, 2, 3], 2, &mut corners);
        assert_eq!(corners.len(), 7 * 8);
        // The xz plane of level r = 1 (group 2): x is 1/2 into cell 0, z 1/2 into cell 1.
        let xz = &corners[16..24];
        assert_eq!(xz[0], Corner { entry: 27 + 9 + 3, weight: 0.25 }, "(x, z) = (0, 1) at 0 + 3 * 1");
        assert_eq!(xz[1].entry, 27 + 9 + 4);
        assert_eq!(xz[3].entry, 27 + 9 + 1 + 3 * 2);
        assert!(xz[4..].iter().all(|c| c.weight == 0.0), "a plane's group is padded with weight 0");
        for group in corners.chunks_exact(8) {
            assert_eq!(group.iter().map(|c| c.weight).sum::<f32>(), 1.0);
            assert!(group.iter().all(|c| c.entry < s.entries(2)));
        }
        // At voxel resolution each plane puts all the weight on one corner of its own table.
        let yz = &corners[48..56];
        assert_eq!(yz[0], Corner { entry: 27 + 27 + 50 + 2 + 5 * 3, weight: 1.0 });
        // The padding changes no context: signs of the padded entries do not matter.
        let table = vec![true; s.entries(2) as usize];
        let mut flipped = table.clone();
        flipped[27 + 9] = false; // the xz table's first entry, which its padding points at
        assert_eq!(s.context(&corners, &table)[2], 1.0);
        assert_eq!(s.context(&corners, &flipped)[2], 1.0);
    }

    #[test]
    fn large_planes_are_hashed_with_the_first_two_primes() {
        let s = ContextGridShape { levels: vec![], planes: vec![8], table_log2: 4, channels: 1 };
        let mut corners = Vec::new();
        // Depth 8: 257 x 257 points per plane > 16, hashed; q on corner (5, 6) of the xy plane.
        s.corners([5, 6, 7], 8, &mut corners);
        let expected = (5u32 ^ 6u32.wrapping_mul(2_654_435_761)) & 15;
        assert_eq!(corners[0], Corner { entry: expected, weight: 1.0 });
        assert!(corners.iter().all(|c| c.entry < 48));
    }
}

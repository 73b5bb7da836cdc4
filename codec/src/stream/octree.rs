//! Lossless coding of integer positions on a `2^depth` grid per axis as an octree
//! (SPEC.md section 6.1): nodes are visited breadth-first in Morton order, each node's eight
//! child-occupancy bits are coded with adaptive binary contexts, and every leaf voxel carries
//! the number of points in it (several Gaussians may share a voxel).

use super::entropy::{BitContext, EntropyError, SymbolDecoder, SymbolEncoder};

/// Deepest grid: 24 bits per axis.
pub const MAX_DEPTH: u8 = 24;
/// Most points one voxel may hold.
pub const MAX_POINTS_PER_VOXEL: u32 = 255;

/// Why coded positions could not be decoded.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum OctreeError {
    #[error(transparent)]
    Entropy(#[from] EntropyError),
    #[error("the octree holds more than the {expected} points the header declares")]
    TooManyPoints { expected: usize },
    #[error("the octree holds {found} points, the header declares {expected}")]
    CountMismatch { found: usize, expected: usize },
    #[error("{count} points share one grid cell; at most {MAX_POINTS_PER_VOXEL} may (use a finer grid)")]
    VoxelOverflow { count: usize },
    #[error("octree depth {0} is outside 1..={MAX_DEPTH}")]
    Depth(u8),
}

/// The adaptive contexts of the occupancy and count bits (SPEC.md section 6.1).
struct Contexts {
    /// Indexed by [level][child index][min(ones so far, 2)][parent class].
    occupancy: Vec<BitContext>,
    /// "One more point in this voxel", indexed by min(points so far - 1, 3).
    count: [BitContext; 4],
}

impl Contexts {
    fn new(depth: u8) -> Self {
        Self { occupancy: vec![BitContext::default(); depth as usize * 8 * 3 * 4], count: [BitContext::default(); 4] }
    }

    fn occupancy(&mut self, level: usize, child: usize, ones: u32, parent_class: usize) -> &mut BitContext {
        &mut self.occupancy[((level * 8 + child) * 3 + ones.min(2) as usize) * 4 + parent_class]
    }
}

/// Class of a node by its parent's number of occupied children: 1, 2, 3-4, 5-8 (the root
/// counts as class 3).
fn parent_class(parent_children: u32) -> usize {
    match parent_children {
        0 | 1 => 0,
        2 => 1,
        3 | 4 => 2,
        _ => 3,
    }
}

/// The Morton key of a grid point: from the top level down, three bits `x y z` per level.
fn morton(p: [u32; 3], depth: u8) -> u128 {
    (0..depth).rev().fold(0u128, |key, bit| {
        let digit = ((p[0] >> bit) & 1) << 2 | ((p[1] >> bit) & 1) << 1 | ((p[2] >> bit) & 1);
        key << 3 | u128::from(digit)
    })
}

fn child_digit(key: u128, depth: u8, level: usize) -> usize {
    ((key >> (3 * (depth as usize - 1 - level))) & 7) as usize
}

/// Codes points (each coordinate below `2^depth`) and returns the coded bytes together with
/// the order in which a decoder will list them: `order[i]` is the index in `points` of the
/// i-th decoded point (Morton order, points sharing a voxel in their input order).
pub fn encode(points: &[[u32; 3]], depth: u8) -> Result<(Vec<u8>, Vec<usize>), OctreeError> {
    assert!((1..=MAX_DEPTH).contains(&depth), "octree depth {depth} outside 1..={MAX_DEPTH}");
    assert!(points.iter().flatten().all(|&c| u64::from(c) < 1u64 << depth), "point outside the grid");
    let keys: Vec<u128> = points.iter().map(|&p| morton(p, depth)).collect();
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by_key(|&i| (keys[i], i));
    let sorted: Vec<u128> = order.iter().map(|&i| keys[i]).collect();
    let mut run = 1;
    for w in sorted.windows(2) {
        run = if w[0] == w[1] { run + 1 } else { 1 };
        if run > MAX_POINTS_PER_VOXEL as usize {
            return Err(OctreeError::VoxelOverflow { count: run });
        }
    }

    let mut contexts = Contexts::new(depth);
    let mut coder = SymbolEncoder::new();
    // Each node: the range of sorted points under it and its parent's class.
    let mut nodes: Vec<(usize, usize, usize)> = if sorted.is_empty() { vec![] } else { vec![(0, sorted.len(), 3)] };
    for level in 0..depth as usize {
        let mut next = Vec::with_capacity(nodes.len() * 2);
        for &(start, end, class) in &nodes {
            let mut children = [(0usize, 0usize); 8];
            let mut at = start;
            while at < end {
                let digit = child_digit(sorted[at], depth, level);
                let run_end = at + sorted[at..end].partition_point(|&k| child_digit(k, depth, level) == digit);
                children[digit] = (at, run_end);
                at = run_end;
            }
            let occupied = children.iter().filter(|(s, e)| e > s).count() as u32;
            let mut ones = 0;
            for (child, &(s, e)) in children.iter().enumerate() {
                let bit = e > s;
                if !(child == 7 && ones == 0) {
                    coder.bit(contexts.occupancy(level, child, ones, class), bit);
                }
                ones += u32::from(bit);
            }
            next.extend(children.iter().filter(|(s, e)| e > s).map(|&(s, e)| (s, e, parent_class(occupied))));
        }
        nodes = next;
    }
    for &(start, end, _) in &nodes {
        let n = (end - start) as u32;
        for k in 0..(n - 1).min(MAX_POINTS_PER_VOXEL - 1) {
            coder.bit(&mut contexts.count[k.min(3) as usize], true);
        }
        if n < MAX_POINTS_PER_VOXEL {
            coder.bit(&mut contexts.count[(n - 1).min(3) as usize], false);
        }
    }
    Ok((coder.finish(), order))
}

/// Decodes exactly `count` points from a chunk that holds exactly them. Memory stays within
/// `count`: every node holds at least one point, so a level with more nodes than `count` is an
/// error before anything is allocated. (Work is bounded by `count` too; the caller bounds
/// `count` by the stream's size, SPEC.md section 9.)
pub fn decode(bytes: &[u8], depth: u8, count: usize) -> Result<Vec<[u32; 3]>, OctreeError> {
    if !(1..=MAX_DEPTH).contains(&depth) {
        return Err(OctreeError::Depth(depth));
    }
    let mut coder = SymbolDecoder::new(bytes)?;
    if count == 0 {
        coder.finish()?;
        return Ok(vec![]);
    }
    let mut contexts = Contexts::new(depth);
    // Each node: its coordinates so far and its parent's class.
    let mut nodes: Vec<([u32; 3], usize)> = vec![([0; 3], 3)];
    for level in 0..depth as usize {
        let mut next = Vec::new();
        for &(p, class) in &nodes {
            let mut occupied = [false; 8];
            let mut ones = 0;
            for child in 0..8 {
                occupied[child] = if child == 7 && ones == 0 {
                    true
                } else {
                    coder.bit(contexts.occupancy(level, child, ones, class))?
                };
                ones += u32::from(occupied[child]);
            }
            if next.len() + ones as usize > count {
                return Err(OctreeError::TooManyPoints { expected: count });
            }
            for child in (0..8).filter(|&c| occupied[c]) {
                let q = [
                    p[0] << 1 | (child as u32 >> 2),
                    p[1] << 1 | (child as u32 >> 1 & 1),
                    p[2] << 1 | (child as u32 & 1),
                ];
                next.push((q, parent_class(ones)));
            }
        }
        nodes = next;
    }
    let mut points = Vec::with_capacity(nodes.len());
    for &(p, _) in &nodes {
        let mut n = 1u32;
        while n < MAX_POINTS_PER_VOXEL && coder.bit(&mut contexts.count[(n - 1).min(3) as usize])? {
            n += 1;
        }
        if points.len() + n as usize > count {
            return Err(OctreeError::TooManyPoints { expected: count });
        }
        points.extend(std::iter::repeat_n(p, n as usize));
    }
    if points.len() != count {
        return Err(OctreeError::CountMismatch { found: points.len(), expected: count });
    }
    coder.finish()?;
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pwgs_core::random::SplitMix64;

    fn random_points(n: usize, depth: u8, seed: u64) -> Vec<[u32; 3]> {
        let mut rng = SplitMix64(seed);
        let side = (1u64 << depth) as f32;
        // Clustered: points near a few centers, as Gaussians are near surfaces.
        (0..n)
            .map(|i| {
                let c = ((i % 7) as f32 + 0.5) / 7.0 * side;
                let spread = side / 64.0;
                std::array::from_fn(|_| (c + rng.uniform(-spread, spread)).clamp(0.0, side - 1.0) as u32)
            })
            .collect()
    }

    #[test]
    fn round_trip_in_morton_order_with_shared_voxels() {
        for (depth, n) in [(1u8, 20usize), (3, 200), (12, 5000), (MAX_DEPTH, 3000)] {
            let mut points = random_points(n, depth, depth as u64);
            points.extend_from_within(..5); // shared voxels
            let (bytes, order) = encode(&points, depth).unwrap();
            let decoded = decode(&bytes, depth, points.len()).unwrap();
            let expected: Vec<[u32; 3]> = order.iter().map(|&i| points[i]).collect();
            assert_eq!(decoded, expected, "depth {depth}");
            let keys: Vec<u128> = decoded.iter().map(|&p| morton(p, depth)).collect();
            assert!(keys.windows(2).all(|w| w[0] <= w[1]), "not in Morton order");
        }
    }

    #[test]
    fn full_voxels_and_single_points_round_trip() {
        let points = vec![[5u32, 6, 7]; MAX_POINTS_PER_VOXEL as usize];
        let (bytes, _) = encode(&points, 4).unwrap();
        let mut overfull = points.clone();
        overfull.push([5, 6, 7]);
        assert_eq!(encode(&overfull, 4).err(), Some(OctreeError::VoxelOverflow { count: 256 }));
        assert_eq!(decode(&bytes, 4, points.len()).unwrap(), points);
        let (bytes, _) = encode(&[[0, 0, 0]], MAX_DEPTH).unwrap();
        assert_eq!(decode(&bytes, MAX_DEPTH, 1).unwrap(), vec![[0, 0, 0]]);
    }

    #[test]
    fn a_wrong_declared_count_is_an_error() {
        let points = random_points(300, 10, 5);
        let (bytes, _) = encode(&points, 10).unwrap();
        assert!(matches!(decode(&bytes, 10, 299), Err(OctreeError::TooManyPoints { .. })));
        assert!(matches!(decode(&bytes, 10, 301), Err(OctreeError::CountMismatch { found: 300, expected: 301 })));
    }

    #[test]
    fn bad_depths_trailing_words_and_chunks_without_points_are_errors() {
        assert_eq!(decode(&[], 0, 1), Err(OctreeError::Depth(0)));
        assert_eq!(decode(&[], MAX_DEPTH + 1, 1), Err(OctreeError::Depth(MAX_DEPTH + 1)));
        let (bytes, _) = encode(&random_points(50, 8, 3), 8).unwrap();
        let mut padded = bytes.clone();
        padded.extend([0; 8]);
        assert_eq!(decode(&padded, 8, 50), Err(OctreeError::Entropy(EntropyError::Unread(4))), "two words padded");
        assert_eq!(decode(&[], 8, 0), Ok(vec![]));
        assert_eq!(decode(&bytes, 8, 0), Err(OctreeError::Entropy(EntropyError::Unread(bytes.len()))));
    }

    #[test]
    fn dense_clusters_cost_few_bits_per_point() {
        let points = random_points(20_000, 16, 9);
        let (bytes, _) = encode(&points, 16).unwrap();
        let bits_per_point = bytes.len() as f64 * 8.0 / points.len() as f64;
        // 48 raw bits per point; clusters of 2857 points in 1/64-wide boxes (2^10 per side)
        // leave about 30 bits of entropy per point, minus what the tree shares.
        assert!(bits_per_point < 30.0, "{bits_per_point:.1} bits per point");
    }
}

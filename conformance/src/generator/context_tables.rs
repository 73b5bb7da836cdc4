//! Anchors whose context model (SPEC.md section 12.7) needs as many wide tables as a stream
//! may build: for streams at and past the table bound of 12.7, and the 1 MB stream at every
//! anchor bound at once.
//!
//! The network reads three inputs from one level of two cells per axis whose signs follow the
//! corner's side, so that an anchor at `(x, y, z)` (x, y, z < 64 on an octree of depth 7) gets
//! `x / 32 - 1`, `y / 32 - 1` and `z / 32 - 1`. Two hidden units then single out the 64 anchors
//! at `(x, 0, 0)`: the first is `x / 32` there and 0 elsewhere, the second 1 there and 0
//! elsewhere. Those anchors predict their first `scales` values with mean `x / 64` (each anchor
//! one of the 64 fractions) and scales 255, 254, ... (windows of 4,095 symbols), so the tables
//! number 64 x `scales`; every other value of every anchor is predicted at 0 with the
//! narrowest scale, so the values (all 0) cost almost nothing.

use pwgs_codec::context_grid::ContextGridShape;
use pwgs_codec::stream::anchor::{QuantizedAnchors, QuantizedMlp};
use pwgs_codec::stream::anchor_context::{QuantizedContext, predicted_values};
use pwgs_codec::stream::plain::PositionGrid;

/// The octree's depth: the level's cells (2 per axis) are 64 voxels wide.
const DEPTH: u8 = 7;
const SIDE: u32 = 1 << DEPTH;

/// `content` (every value 0) moved onto a depth-7 grid over [-1, 1]^3, its first 64 anchors at
/// `(x, 0, 0)` and the others in distinct cells off that row, with a context model of
/// `hidden` (at least 2) units that needs 64 x `scales` tables of 4,095 symbols.
pub fn with_wide_tables(mut content: QuantizedAnchors, scales: usize, hidden: usize) -> QuantizedAnchors {
    let n = content.len();
    let values = predicted_values(content.feature_dim, content.offsets_per_anchor);
    assert!(hidden >= 2 && scales <= values.min(96), "{scales} wide scales of {values} values, {hidden} units");
    assert!(n >= 64 && n as u64 <= u64::from(SIDE).pow(3) - u64::from(SIDE), "{n} anchors");
    content.grid = PositionGrid { origin: [-1.0; 3], cell: 2.0 / SIDE as f32, depth: DEPTH };
    content.positions = (0..n as u32)
        .map(|i| match i < 64 {
            true => [i, 0, 0],
            // Skip the row y = z = 0.
            false => {
                let j = i - 64 + SIDE;
                [j % SIDE, (j / SIDE) % SIDE, j / (SIDE * SIDE)]
            }
        })
        .collect();
    let shape = ContextGridShape { levels: vec![1], planes: vec![], table_log2: 12, channels: 3 };
    // The level's 3 x 3 x 3 corner points, x fastest; channel c is +1 past the first point of
    // axis c.
    let signs = (0..27).flat_map(|e: u32| [e % 3, (e / 3) % 3, e / 9].map(|p| p >= 1)).collect();
    // Weights in eighths, biases in units.
    let mut w1 = vec![0; hidden * 3];
    w1[..6].copy_from_slice(&[8, -512, -512, 0, -256, -256]);
    let mut b1 = vec![0; hidden];
    b1[..2].copy_from_slice(&[-127, -63]);
    let mut w2 = vec![0; 2 * values * hidden];
    let mut b2 = vec![0; 2 * values];
    for t in 0..scales {
        // Mean x / 64 = h0 / 2; log2 scale -12 + h1 * J / 8, J = 255 - t.
        w2[t * hidden] = 4;
        w2[(values + t) * hidden + 1] = 255 - t as i32;
    }
    b2[values..].fill(-12);
    let mlp = QuantizedMlp { hidden, weight_exponent: -3, bias_exponent: 0, w1, b1, w2, b2 };
    content.context = Some(QuantizedContext { shape, signs, mlp });
    content
}

/// The in-range symbols of the tables [`with_wide_tables`] makes a stream need: 64 x `scales`
/// windows of 4,095, and the narrowest table of mean 0 (3 symbols).
pub fn wide_table_symbols(scales: usize) -> u64 {
    64 * scales as u64 * 4095 + 3
}

//! Class 3, degenerate geometry in the importers (`pwenc --from`): more Gaussians on one
//! position than a grid cell of a stream holds (255), positions towards the ends of binary32
//! (whose differences, squared, overflow it), and scales and opacities at the ends of their
//! ranges, as an INRIA PLY, a `.splat` and SOG archives. Every value is written exactly (no
//! platform `exp` or `ln`), so the bytes are the same on every machine.
//!
//! What the encoder does with them (`encoder/src/plain/compress.rs`): a cell of the finest grid that
//! more than 255 Gaussians share keeps its 255 most important (the rest are dropped, with a
//! warning); positions that no grid within binary32 reaches are refused by name.

use pwgs_core::gaussians::Gaussians;
use serde_json::json;

use super::imports_bombs::stored_zip;
use super::{Hostile, HostileEntry, Outcome, Tool};

/// What the encoder says of positions that no stream's grid can hold.
const SPAN_ERROR: &str = "the stream's position grid cannot hold them";

pub fn files() -> Vec<Hostile> {
    vec![
        accepted(
            "ply-300-at-one-position.ply",
            ply(&pile(300, [1.5, -2.0, 3.0], &[])),
            "INRIA PLY of 300 Gaussians at one position (a grid cell holds at most 255): no grid separates them, \
             which once refined the grid without end (a shift overflow in the dev profile, a hang in release); \
             the 255 most important are kept and the others dropped with a warning",
        ),
        accepted(
            "ply-1000-at-one-position-and-5-elsewhere.ply",
            ply(&pile(
                1000,
                [0.25, 0.5, 0.75],
                &[[-3.0, 1.0, 2.0], [4.0, -1.0, 0.5], [0.0, 2.5, -2.0], [1.0; 3], [0.2501, 0.5, 0.75]],
            )),
            "INRIA PLY of 1,000 Gaussians at one position and 5 elsewhere (one 1e-4 from the pile): the grid is \
             refined to 24 levels, then the pile keeps its 255 most important and every other Gaussian is kept",
        ),
        accepted(
            "ply-pile-in-one-cell-beside-an-outlier.ply",
            ply(&pile_beside_an_outlier()),
            "INRIA PLY of 300 Gaussians within 3e-4 of each other and one 1e30 away: 24 levels of cells 6e22 wide \
             put the 300 in one cell, which keeps its 255 most important",
        ),
        accepted(
            "ply-positions-to-3e38.ply",
            ply(&far_positions(&[1e19, 4.2e25, 1e30, 3e38])),
            "INRIA PLY of 40 Gaussians within a unit of the origin and 4 at 1e19, 4.2e25, 1e30 and 3e38 on one \
             side: distances to the median squared in binary32 overflowed (\"only finite floats are written\"); \
             a grid from the origin to 3e38 stays within binary32, so they encode",
        ),
        refused(
            "ply-positions-both-sides-3e38.ply",
            ply(&far_positions(&[-3e38, 1e30, 3e38])),
            SPAN_ERROR,
            "INRIA PLY of 40 Gaussians near the origin and 3 at -3e38, 1e30 and 3e38: a grid's origin magnitude \
             plus its extent must stay below 3.4e38 (SPEC.md section 6.1), and this one would need 9e38: refused \
             with the span named",
        ),
        accepted(
            "ply-extreme-attributes.ply",
            ply(&extreme_attributes()),
            "INRIA PLY of SH degree 1 whose log-scales, opacity logits, rotation components and SH coefficients \
             reach +-88 and +-3.4e38, with a zero and a denormal quaternion and denormal positions: quantized \
             values saturate, nothing overflows",
        ),
        accepted(
            "ply-300-a-denormal-apart.ply",
            ply(&denormal_pile()),
            "INRIA PLY of 300 Gaussians 1.4e-45 apart (the binary32 denormals): no grid cell is finer than the \
             smallest normal binary32, so they share one, which keeps 255",
        ),
        accepted(
            "splat-extreme-scales.splat",
            extreme_splat(),
            ".splat of 64 Gaussians with scales of 0, 1e-45, 1e-38 and 3.4e38 (log-scales down to the reader's \
             floor and up to 88.7), opacities of 0 and 255, and positions from -1e38 to 1e38 on each axis: encodes",
        ),
        refused(
            "sog-log-positions-88.sog",
            sog([-88.0; 3], [88.0; 3]),
            SPAN_ERROR,
            "SOG whose means' mins and maxs are -88 and 88 in log space: positions of +-1.65e38, whose squared \
             distances overflowed binary32; no grid within binary32 reaches from one end to the other: refused \
             with the span named",
        ),
        accepted(
            "sog-log-positions-0-to-88.sog",
            sog([0.0; 3], [88.0; 3]),
            "SOG whose means span 0 to 88 in log space (positions 0 to 1.65e38) and whose log-scale codebook \
             spans -88 to 88: a grid from 0 to 1.65e38 stays within binary32, so it encodes",
        ),
    ]
}

fn accepted(file: &str, bytes: Vec<u8>, description: &str) -> Hostile {
    hostile(file, bytes, Outcome::Accepted, description)
}

fn refused(file: &str, bytes: Vec<u8>, error: &str, description: &str) -> Hostile {
    hostile(file, bytes, Outcome::Refused(error.to_string()), description)
}

fn hostile(file: &str, bytes: Vec<u8>, outcome: Outcome, description: &str) -> Hostile {
    let entry =
        HostileEntry { class: 3, tool: Tool::PwencFrom, view: None, outcome, description: description.to_string() };
    Hostile { file: file.to_string(), entry, bytes }
}

fn ply(g: &Gaussians) -> Vec<u8> {
    pwgs_core::ply::gaussians_to_bytes(g)
}

/// `n` Gaussians at `at`, each a little larger than the one before, then one at each of
/// `others`.
fn pile(n: usize, at: [f32; 3], others: &[[f32; 3]]) -> Gaussians {
    let mut g = Gaussians::with_degree(0);
    for i in 0..n {
        let s = -3.0 + i as f32 / 1024.0;
        g.push(at, [s, s - 0.5, s], [1.0, 0.125, 0.0, -0.25], -1.0 + (i % 7) as f32 / 4.0, &[0.25, -0.125, 0.5]);
    }
    for &p in others {
        g.push(p, [-2.0; 3], [1.0, 0.0, 0.0, 0.0], 2.0, &[0.0; 3]);
    }
    g
}

fn pile_beside_an_outlier() -> Gaussians {
    let mut g = pile(300, [0.0; 3], &[[1e30, 0.0, 0.0]]);
    for i in 0..300 {
        g.means[i] = [i as f32 * 1e-6, 0.5, -0.5];
    }
    g
}

/// 40 Gaussians on a small lattice around the origin, then one at `(x, x / 2, 7)` for each of
/// `far`.
fn far_positions(far: &[f32]) -> Gaussians {
    let mut g = pile(40, [0.0; 3], &[]);
    for i in 0..40 {
        g.means[i] = [(i % 4) as f32 / 4.0, (i / 4 % 5) as f32 / 5.0, (i / 20) as f32 / 2.0];
    }
    for &x in far {
        g.push([x, x / 2.0, 7.0], [-1.0; 3], [1.0, 0.0, 0.0, 0.0], 1.0, &[0.5; 3]);
    }
    g
}

fn extreme_attributes() -> Gaussians {
    let (big, tiny) = (f32::MAX, 1e-40);
    let mut g = Gaussians::with_degree(1);
    let sh = |v: f32| [v; 12];
    g.push([0.0; 3], [88.0, -88.0, 88.7], [1.0, 0.0, 0.0, 0.0], 1e30, &sh(1.0));
    g.push([1.0, 0.0, 0.0], [big, -big, 0.0], [big, -big, big, 0.0], big, &sh(big));
    g.push([0.0, 1.0, 0.0], [-big; 3], [0.0; 4], 20.0, &sh(-big));
    g.push([0.0, 0.0, 1.0], [0.0; 3], [tiny, 0.0, 0.0, 0.0], -big, &sh(0.0));
    g.push([tiny, -tiny, 0.0], [-88.0; 3], [1.0; 4], 0.0, &sh(tiny));
    g.push([0.5; 3], [88.0; 3], [-1.0, 0.0, 0.0, 0.0], -88.0, &sh(-88.0));
    g
}

fn denormal_pile() -> Gaussians {
    let mut g = pile(300, [0.0; 3], &[]);
    for i in 0..300 {
        g.means[i] = [f32::from_bits(i as u32), 0.0, f32::from_bits(300 - i as u32)];
    }
    g
}

/// 64 `.splat` records (position, scale as 3 x f32, RGBA, rotation as 4 bytes around 128).
fn extreme_splat() -> Vec<u8> {
    let scales = [0.0, 1e-45, 1e-38, f32::MAX];
    let positions = [-1e38, -1.0, 1.0, 1e38];
    let mut out = Vec::with_capacity(64 * 32);
    for i in 0..64 {
        let mean = [positions[i % 4], positions[i / 4 % 4], positions[i / 16]];
        let scale = [scales[i % 4], scales[(i + 1) % 4], scales[i / 4 % 4]];
        for v in mean.iter().chain(&scale) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let alpha = if i % 3 == 0 { 0 } else { 255 };
        out.extend_from_slice(&[(i * 4) as u8, 128, 255 - (i * 4) as u8, alpha, 255, 128, 128, 128]);
    }
    out
}

/// A SOG of 16 Gaussians whose means span `mins` to `maxs` (in SOG's log space, `sign(x) *
/// ln(1 + |x|)`): one at each end, the others within 1/2048 of the range of its middle. The
/// log-scale codebook spans -88 to 88.
fn sog(mins: [f64; 3], maxs: [f64; 3]) -> Vec<u8> {
    const N: usize = 16;
    const SIDE: u32 = 4;
    // 16-bit fractions of the range: 0, 65535, then around 32768.
    let fraction = |i: usize| match i {
        0 => 0u16,
        1 => u16::MAX,
        _ => 32768 + i as u16 * 2,
    };
    let image = |pixel: &dyn Fn(usize) -> [u8; 4]| -> Vec<u8> {
        let rgba: Vec<u8> = (0..N).flat_map(pixel).collect();
        let mut out = Vec::new();
        image::codecs::webp::WebPEncoder::new_lossless(&mut out)
            .encode(&rgba, SIDE, SIDE, image::ExtendedColorType::Rgba8)
            .expect("encoding to memory cannot fail");
        out
    };
    let byte = |i: usize, shift: u32| (fraction(i) >> shift) as u8;
    let [low, high] = [0, 8].map(|shift| image(&|i| [byte(i, shift), byte(i, shift), byte(i, shift), 255]));
    let codebook = |lo: f64, hi: f64| (0..256).map(|k| lo + (hi - lo) * f64::from(k) / 255.0).collect::<Vec<_>>();
    let meta = json!({
        "version": 2, "count": N,
        "means": {"mins": mins, "maxs": maxs, "files": ["means_l.webp", "means_u.webp"]},
        "scales": {"codebook": codebook(-88.0, 88.0), "files": ["scales.webp"]},
        "quats": {"files": ["quats.webp"]},
        "sh0": {"codebook": codebook(-2.0, 2.0), "files": ["sh0.webp"]},
    });
    let files = [
        ("meta.json", serde_json::to_vec(&meta).expect("JSON values serialize")),
        ("means_l.webp", low),
        ("means_u.webp", high),
        ("quats.webp", image(&|i| [128, (i * 8) as u8, 128, 252])),
        ("scales.webp", image(&|i| [(i * 17) as u8, 255 - (i * 17) as u8, (i * 5) as u8, 255])),
        ("sh0.webp", image(&|i| [(i * 16) as u8, 128, 64, if i % 2 == 0 { 255 } else { 128 }])),
    ];
    stored_zip(&files.map(|(name, data)| (name.to_string(), data)))
}

//! Anchor-base vectors (SPEC.md section 12): a synthetic anchor model drawn as integers, whose
//! networks make visible neural Gaussians in front of the suite's cameras, and streams that
//! break its syntax.

use pwgs_bitstream::{Container, Tag, reseal, write_container};
use pwgs_codec::context_grid::ContextGridShape;
use pwgs_codec::stream::anchor::{self, QuantizedAnchors, QuantizedMlp};
use pwgs_codec::stream::anchor_context::{self, QuantizedContext};
use pwgs_codec::stream::header::{BaseKind, Header};
use pwgs_codec::stream::plain::PositionGrid;
use pwgs_codec::stream::{self, PADDING};

use super::content::Draws;
use super::context_tables;
use super::{Refusal, Vector};

/// F and K of the vectors.
const FEATURES: usize = 6;
const OFFSETS: usize = 4;

fn mlp(draws: &mut Draws, hidden: usize, outputs: usize, bias: &dyn Fn(usize) -> [i32; 2]) -> QuantizedMlp {
    let inputs = FEATURES + 4;
    let mut many = |n: usize, range: [i32; 2]| (0..n).map(|_| draws.i32(range)).collect::<Vec<_>>();
    QuantizedMlp {
        hidden,
        weight_exponent: -7,
        bias_exponent: -6,
        w1: many(hidden * inputs, [-40, 40]),
        b1: many(hidden, [0, 30]),
        w2: many(outputs * hidden, [-40, 40]),
        b2: (0..outputs).map(|o| draws.i32(bias(o))).collect(),
    }
}

/// `n` anchors in distinct cells of a 5-level grid over [-1, 1]^3, every fifth mask shut.
pub fn synthetic_anchors(n: usize, seed: u64) -> QuantizedAnchors {
    let mut draws = Draws::new(seed);
    let mut positions: Vec<[u32; 3]> = Vec::with_capacity(n);
    while positions.len() < n {
        let p = draws.point(5);
        if !positions.contains(&p) {
            positions.push(p);
        }
    }
    let k = OFFSETS;
    // Opacity biases mostly positive (visible), rotation w strongly positive, scale logits 0.
    let covariance_bias = |o: usize| match o % 7 {
        3 => [40, 64],
        0..3 => [-10, 10],
        _ => [-20, 20],
    };
    QuantizedAnchors {
        grid: PositionGrid { origin: [-1.0, -1.0, -1.0], cell: 0.0625, depth: 5 },
        positions,
        feature_dim: FEATURES,
        offsets_per_anchor: k,
        feature_step: 0.125,
        features: (0..n * FEATURES).map(|_| draws.i32([-12, 12])).collect(),
        scaling_step: 0.0625,
        // Offset scale e^-2.5 ≈ 0.08, Gaussian scale e^-3.5 ≈ 0.03 (log values -40, -56).
        scaling: (0..n)
            .map(|_| std::array::from_fn(|c| draws.i32(if c < 3 { [-44, -36] } else { [-60, -52] })))
            .collect(),
        offset_step: 0.25,
        offsets: (0..n * 3 * k).map(|r| if (r / 3) % 5 == 4 { 0 } else { draws.i32([-6, 6]) }).collect(),
        masks: (0..n * k).map(|r| r % 5 != 4).collect(),
        mlps: [
            mlp(&mut draws, 8, k, &|_| [-10, 60]),
            mlp(&mut draws, 8, 3 * k, &|_| [-60, 60]),
            mlp(&mut draws, 8, 7 * k, &covariance_bias),
        ],
        context: None,
    }
}

pub fn header(content: &QuantizedAnchors) -> Header {
    Header {
        base: BaseKind::Anchors,
        gaussian_count: content.len() as u32,
        sh_degree: 0,
        center: [0.0; 3],
        scale: 1.0,
        background: [0.1, 0.1, 0.1],
    }
}

pub fn encode(content: &QuantizedAnchors) -> Vec<u8> {
    stream::encode(&header(content), content, None).expect("the synthetic anchors fit the octree")
}

/// `anchors` with a context model (SPEC.md section 12.7): a dense, a hashed and a voxel-fine
/// level of 2 channels, and a network whose means spread over tens of units and whose scales
/// range from a fraction of a unit to hundreds, so that the synthetic values exercise moved
/// tables and escapes.
pub fn with_context(mut content: QuantizedAnchors, seed: u64) -> QuantizedAnchors {
    let mut draws = Draws::new(seed);
    let shape = ContextGridShape { levels: vec![1, 3, 5], planes: vec![2, 6], table_log2: 7, channels: 2 };
    let signs = (0..shape.entries(content.grid.depth) * 2).map(|_| draws.i32([0, 1]) == 1).collect();
    let (inputs, hidden) = (shape.context_len(), 6);
    let outputs = 2 * anchor_context::predicted_values(FEATURES, OFFSETS);
    let mut many = |n: usize, range: [i32; 2]| (0..n).map(|_| draws.i32(range)).collect::<Vec<_>>();
    let mlp = QuantizedMlp {
        hidden,
        weight_exponent: -4,
        bias_exponent: -3,
        w1: many(hidden * inputs, [-30, 30]),
        b1: many(hidden, [0, 20]),
        w2: many(outputs * hidden, [-12, 12]),
        b2: many(outputs, [-24, 24]),
    };
    content.context = Some(QuantizedContext { shape, signs, mlp });
    content
}

pub fn vectors() -> Vec<Vector> {
    let mut v = vec![Vector {
        name: "anchors",
        description: format!(
            "Base kind 1: 120 anchors (F = {FEATURES}, K = {OFFSETS}, every fifth mask shut) with networks of width 8: \
             every anchor section, Gaussian models for features, scaling, offsets and weights, and the neural \
             Gaussians each camera derives."
        ),
        clauses: vec![
            "S12.1-networks",
            "S12.2-positions",
            "S12.3-blocks",
            "S12.4-neural",
            "S12.6-hash",
            "S5.4-gaussian",
        ],
        stream: encode(&synthetic_anchors(120, 31)),
        cameras: &["front", "side"],
    }];
    v.push(Vector {
        name: "anchors-context",
        description: format!(
            "Base kind 1 with ACTX: 120 anchors (F = {FEATURES}, K = {OFFSETS}) coded with a context model of 3 \
             levels (dense, hashed, voxel-fine) and 2 channels, every value with its own Gaussian model."
        ),
        clauses: vec!["S12.7-context", "S12.6-hash", "S5.4-gaussian"],
        stream: encode(&with_context(synthetic_anchors(120, 35), 36)),
        cameras: &["front"],
    });
    v
}

/// The payload of `tag` in `bytes` replaced by `edit`'s, CRCs sealed again.
fn edited(bytes: &[u8], tag: Tag, edit: impl Fn(&mut Vec<u8>)) -> Vec<u8> {
    let container = Container::parse(bytes).expect("a valid stream");
    let mut sections: Vec<(Tag, Vec<u8>)> = container.sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect();
    sections.iter_mut().filter(|(t, _)| *t == tag).for_each(|(_, p)| edit(p));
    let mut out = write_container(&sections);
    reseal(&mut out);
    out
}

/// `anchors` with every value and every network parameter 0 (they code to almost nothing).
fn zeroed(mut anchors: QuantizedAnchors) -> QuantizedAnchors {
    anchors.features.fill(0);
    anchors.scaling.fill([0; 6]);
    anchors.offsets.fill(0);
    for m in &mut anchors.mlps {
        [&mut m.w1, &mut m.b1, &mut m.w2, &mut m.b2].into_iter().for_each(|t| t.fill(0));
    }
    anchors
}

/// `bytes` with its padding section replaced so that the stream is exactly `len` bytes (a
/// stream at a chosen distance from a per-byte limit).
fn padded_to(bytes: &[u8], len: usize) -> Vec<u8> {
    let container = Container::parse(bytes).expect("a valid stream");
    let sections: Vec<(Tag, Vec<u8>)> =
        container.sections.iter().filter(|s| s.tag != PADDING).map(|s| (s.tag, s.payload.to_vec())).collect();
    let unpadded = write_container(&sections).len();
    assert!(unpadded < len, "the stream is {unpadded} bytes without padding, not below {len}");
    (0..len - unpadded)
        .map(|pad| {
            let mut with = sections.clone();
            with.push((PADDING, vec![0; pad]));
            write_container(&with)
        })
        .find(|out| out.len() == len)
        .expect("a padding of some length gives the stream's length")
}

pub fn refusals() -> Vec<Refusal> {
    let valid = encode(&synthetic_anchors(40, 32));
    let refusal = |file: &str, clause, error: &str, description: &str, bytes| Refusal {
        file: format!("{file}.pwb"),
        clause,
        error: error.into(),
        description: description.into(),
        bytes,
    };
    // 400 anchors with F = 200 and all-zero values: 200 + 6 + 16 = 222 values each, 88,800 in
    // all, so at least 2,775 bytes at 32 values per byte; padded to 2,774.
    let mut wide = synthetic_anchors(400, 33);
    wide.feature_dim = 200;
    wide.features = vec![0; 400 * 200];
    wide.scaling.fill([0; 6]);
    wide.offsets.fill(0);
    for m in &mut wide.mlps {
        m.w1 = vec![0; m.hidden * 204];
        [&mut m.b1, &mut m.w2, &mut m.b2].into_iter().for_each(|t| t.fill(0));
    }
    let one_byte_short = padded_to(&encode(&wide), 2774);
    let with_grid = encode(&with_context(synthetic_anchors(40, 37), 38));
    // 40 anchors (F = 6, K = 4) with networks of width 256: 74 x 256 = 18,944 multiply-adds
    // per anchor and view, 757,760 in all, so at least 740 bytes; padded to 739.
    let mut wide_networks = zeroed(synthetic_anchors(40, 39));
    for (m, outputs) in wide_networks.mlps.iter_mut().zip([OFFSETS, 3 * OFFSETS, 7 * OFFSETS]) {
        *m = QuantizedMlp {
            hidden: 256,
            w1: vec![0; 256 * (FEATURES + 4)],
            b1: vec![0; 256],
            w2: vec![0; outputs * 256],
            b2: vec![0; outputs],
            ..m.clone()
        };
    }
    // 400 anchors with a context network of width 128: 8 x 18 + 128 x (18 + 48) = 8,592
    // multiply-adds per anchor, 3,436,800 in all, so at least 3,357 bytes; padded to 3,356.
    let mut wide_context = with_context(zeroed(synthetic_anchors(400, 40)), 41);
    if let Some(c) = &mut wide_context.context {
        let outputs = c.mlp.b2.len();
        let inputs = c.shape.context_len();
        // Every value predicted at 0 with a scale of 1/16 unit (log2 scale -4 = -32 x 2^-3),
        // so that the all-zero values cost almost nothing.
        c.mlp = QuantizedMlp {
            hidden: 128,
            w1: vec![0; 128 * inputs],
            b1: vec![0; 128],
            w2: vec![0; outputs * 128],
            b2: (0..outputs).map(|o| if o < outputs / 2 { 0 } else { -32 }).collect(),
            ..c.mlp.clone()
        };
    }
    // 128 anchors whose context model needs 64 x 5 tables of 4,095 symbols and one of 3
    // (1,310,403 symbols), so at least (1,310,403 - 2^20) / 8 bytes, 32,729; padded to 32,728.
    let wide_tables = context_tables::with_wide_tables(zeroed(synthetic_anchors(128, 43)), 5, 2);
    // 1,000 anchors with every mask open: 4,000 unmasked offsets, so at least 8,000 bytes at
    // two per offset; padded to 7,999 (the values need 1,000 x 28 / 32 = 875 bytes, the
    // networks 1,000 x 592 / 1024 = 579).
    let mut open = zeroed(synthetic_anchors(1000, 42));
    open.masks.fill(true);
    vec![
        refusal(
            "anchor-multiply-adds-per-byte",
            "S12.1-work-bound",
            "section 'AMLP': 40 anchors of 18944 multiply-adds each exceed the stream's length of 739 bytes",
            "40 anchors whose three networks are 256 wide: 18,944 multiply-adds per anchor and view in a stream of \
             739 bytes, one byte short of 1024 multiply-adds per byte.",
            padded_to(&encode(&wide_networks), 739),
        ),
        refusal(
            "anchor-context-multiply-adds-per-byte",
            "S12.7-context",
            "section 'ACTX': 400 anchors of 8592 multiply-adds each exceed the stream's length of 3356 bytes",
            "400 anchors whose context network is 128 wide: 8,592 multiply-adds per anchor in a stream of 3,356 \
             bytes, one byte short of 1024 multiply-adds per byte.",
            padded_to(&encode(&wide_context), 3356),
        ),
        refusal(
            "anchor-context-table-symbols",
            "S12.7-context",
            "more than the 1310400 a stream of 32728 bytes may build",
            "128 anchors whose context model needs 321 tables of 1,310,403 symbols in all in a stream of 32,728 bytes, \
             one byte short of 2^20 plus 8 table symbols per byte.",
            padded_to(&encode(&wide_tables), 32728),
        ),
        refusal(
            "anchor-unmasked-offsets-per-byte",
            "S12.3-neural-bound",
            "section 'AMSK': 4000 unmasked offsets exceed half the stream's length of 7999 bytes",
            "1,000 anchors of K = 4 with every mask open in a stream of 7,999 bytes: one byte short of two bytes \
             per unmasked offset.",
            padded_to(&encode(&open), 7999),
        ),
        refusal(
            "anchor-context-level",
            "S12.7-context",
            "section 'ACTX', field `level` … 0 is outside 1..=24",
            "ACTX declares a level of resolution 2^0.",
            edited(&with_grid, anchor_context::CONTEXT, |p| p[1] = 0),
        ),
        refusal(
            "anchor-context-grid-bound",
            "S12.7-context",
            "section 'ACTX': a grid of",
            "ACTX's levels and planes made dense (table log2 22) with 8 channels: more than 64 grid bits per byte \
             of the stream.",
            edited(&with_grid, anchor_context::CONTEXT, |p| (p[7], p[8]) = (22, 8)),
        ),
        refusal(
            "anchor-context-plane-level",
            "S12.7-context",
            "section 'ACTX', field `plane level` … 0 is outside 1..=24",
            "ACTX declares a plane level of resolution 2^0.",
            edited(&with_grid, anchor_context::CONTEXT, |p| p[5] = 0),
        ),
        refusal(
            "anchor-sh-degree",
            "S4-sh-degree",
            "section 'HEAD', field `sh degree` … is not 0",
            "An anchor stream (base 1) whose header declares SH degree 1.",
            edited(&valid, Tag::HEAD, |p| p[5] = 1),
        ),
        refusal(
            "anchor-offsets-zero",
            "S12.1-networks",
            "section 'AMLP', field `offsets per anchor` … 0 is outside 1..=64",
            "AMLP declares 0 offsets per anchor.",
            edited(&valid, anchor::NETWORKS, |p| p[1] = 0),
        ),
        refusal(
            "anchor-values-per-byte",
            "S12.1-work-bound",
            "section 'AMLP': 400 anchors of 222 values each exceed the stream's length",
            "400 anchors of F = 200 in a stream of 2,774 bytes, one byte short of 32 values per byte.",
            one_byte_short,
        ),
        refusal(
            "anchor-missing-masks",
            "S12-sections",
            "the stream has no 'AMSK' section",
            "An anchor stream without its AMSK section.",
            {
                let container = Container::parse(&valid).expect("a valid stream");
                let sections: Vec<(Tag, Vec<u8>)> = container
                    .sections
                    .iter()
                    .filter(|s| s.tag != anchor::MASKS)
                    .map(|s| (s.tag, s.payload.to_vec()))
                    .collect();
                write_container(&sections)
            },
        ),
        refusal(
            "anchor-plain-section",
            "S12-sections",
            "POSN",
            "An anchor stream that also holds the plain base's critical POSN section.",
            {
                let container = Container::parse(&valid).expect("a valid stream");
                let mut sections: Vec<(Tag, Vec<u8>)> =
                    container.sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect();
                sections.push((Tag(*b"POSN"), vec![0; 16]));
                write_container(&sections)
            },
        ),
    ]
}

//! Hostile streams of classes 1 and 2 (rendering memory, the anchor base's work): valid
//! streams at the limits SPEC.md section 9 sets per byte, whose views are heavy to derive or to
//! render, with the cameras to render them from. Each must decode and render within the
//! resource test's memory and time.

use glam::Vec3;
use pwgs_codec::context_grid::ContextGridShape;
use pwgs_codec::stream::anchor::{QuantizedAnchors, QuantizedMlp};
use pwgs_codec::stream::anchor_context::{QuantizedContext, predicted_values};
use pwgs_codec::stream::plain::PositionGrid;
use pwgs_codec::stream::{self, Content};
use pwgs_core::camera::{Camera, Intrinsics};
use pwgs_core::camera_json::camera_to_json;

use pwgs_codec::stream::plain::{PlainGaussians, QuantizedRotation};

use super::super::content::{Draws, gaussians, header, ordinary, unit_cube};
use super::super::context_tables::{wide_table_symbols, with_wide_tables};
use super::{Hostile, HostileEntry, Outcome, Tool};

/// A camera `width` x `height` 3.4 units in front of the unit cube, looking at its centre.
fn camera(width: u32, height: u32) -> Camera {
    let f = width as f32 * 0.9;
    let intrinsics = Intrinsics { width, height, fx: f, fy: f, cx: width as f32 / 2.0, cy: height as f32 / 2.0 };
    Camera::look_at(intrinsics, Vec3::new(0.4, -0.6, -3.4), Vec3::ZERO, Vec3::new(0.0, -1.0, 0.0))
        .expect("a valid camera")
}

/// The camera file of a `width` x `height` view, named after its size.
pub fn view(width: u32, height: u32) -> (String, Vec<u8>) {
    (format!("view-{width}x{height}.json"), format!("{}\n", camera_to_json(&camera(width, height))).into_bytes())
}

/// The views the hostile streams are rendered from.
pub fn views() -> Vec<(String, Vec<u8>)> {
    vec![view(1920, 1080), view(320, 240), view(64, 48)]
}

fn accepted(file: &str, class: u8, view: Option<(u32, u32)>, description: String, bytes: Vec<u8>) -> Hostile {
    hostile(file, class, view, Outcome::Accepted, description, bytes)
}

/// What `pwdec` says of a view refused for its blend work.
const TOO_MUCH_BLENDING: &str = "units of blend work";

fn too_much_blending(file: &str, view: (u32, u32), description: String, bytes: Vec<u8>) -> Hostile {
    hostile(file, 1, Some(view), Outcome::Refused(TOO_MUCH_BLENDING.into()), description, bytes)
}

fn hostile(
    file: &str,
    class: u8,
    view: Option<(u32, u32)>,
    outcome: Outcome,
    description: String,
    bytes: Vec<u8>,
) -> Hostile {
    let entry = HostileEntry {
        class,
        tool: Tool::Pwdec,
        view: view.map(|(w, h)| format!("view-{w}x{h}.json")),
        outcome,
        description,
    };
    Hostile { file: file.to_string(), entry, bytes }
}

/// 60,000 plain Gaussians of scale about 1 (the cube is 2 across) on a 64^3 grid: every
/// splat covers most of a 1920x1080 view, 490M tile-list entries if binned at once.
fn large_plain_gaussians() -> Vec<u8> {
    let mut draws = Draws::new(4601);
    let positions = (0..60_000).map(|_| draws.point(6)).collect();
    let (steps, mut ranges) = ordinary(0);
    // Narrow ranges: the file stays near the 60,000 bytes its count needs.
    (ranges.log_scale, ranges.rotation, ranges.opacity, ranges.dc) = ([-8, 0], [-4, 4], [8, 24], [-8, 8]);
    let content = gaussians(&mut draws, unit_cube(6), positions, 0, steps, &ranges);
    stream::encode(&header(&content), &content, None).expect("the Gaussians fit the octree")
}

/// `n` needles on a lattice over the unit cube: scale 1 along one axis and e^-7 across, opacity
/// 0.98, turned 45 degrees either way about z, so that each crosses a view in front of the cube
/// diagonally, about 3 px wide: its pixel box meets every tile, but it covers none and closes
/// none. 30,000 of them list 200M entries at 1920x1080.
fn needles(n: usize) -> Vec<u8> {
    let mut content = lattice_gaussians(n, 4605, [0, -224, -224], 64);
    // Rotation step 1/1024: sin(22.5 degrees) = 392/1024.
    for (i, r) in content.rotations.iter_mut().enumerate() {
        *r = QuantizedRotation { largest: 0, rest: [0, 0, if i % 2 == 0 { 392 } else { -392 }] };
    }
    plain_stream(&content)
}

/// `n` faint discs on a lattice over the unit cube: scale 1, opacity 0.008, so alpha is at
/// least 1/255 within 1.2 standard deviations only, and a tile closes only after about 2,500 of
/// them cover it whole; the tiles on their edges never close.
fn faint_discs(n: usize) -> Vec<u8> {
    plain_stream(&lattice_gaussians(n, 4607, [0; 3], -77))
}

/// `n` grey Gaussians of SH degree 0 on the cells of [`grid_for`]'s grid, all of log scale
/// `log_scale` (steps of 1/32) and opacity logit `opacity` (steps of 1/16), unrotated: the
/// writer pads such a stream to the least length its count allows.
fn lattice_gaussians(n: usize, seed: u64, log_scale: [i32; 3], opacity: i32) -> PlainGaussians {
    let (side, depth) = grid_for(n);
    let (steps, mut ranges) = ordinary(0);
    (ranges.log_scale, ranges.rotation, ranges.opacity, ranges.dc) = ([0, 0], [0, 0], [opacity, opacity], [0, 0]);
    let grid = PositionGrid { origin: [-1.0; 3], cell: 2.0 / side as f32, depth };
    let mut content = gaussians(&mut Draws::new(seed), grid, cells(n), 0, steps, &ranges);
    content.log_scales.fill(log_scale);
    content.rotations.fill(QuantizedRotation { largest: 0, rest: [0; 3] });
    content
}

fn plain_stream(content: &PlainGaussians) -> Vec<u8> {
    stream::encode(&header(content), content, None).expect("the Gaussians fit the octree")
}

/// `n` anchors in distinct cells of a 32^3 grid over [-1, 1]^3 with every value 0 and every
/// mask open: their neural Gaussians sit at the anchors, scale 1/2, opacity tanh(5/8), grey.
/// The networks' weights are 0 and their biases set that; the writer pads the stream to the
/// least length its counts allow, so the stream is exactly at SPEC.md's per-byte limits.
fn uniform_anchors(n: usize, (f, k): (usize, usize), hidden: [usize; 3]) -> QuantizedAnchors {
    let (side, depth) = grid_for(n);
    let network = |m: usize, outputs: usize, bias: &dyn Fn(usize) -> i32| QuantizedMlp {
        hidden: hidden[m],
        weight_exponent: -7,
        bias_exponent: -6,
        w1: vec![0; hidden[m] * (f + 4)],
        b1: vec![0; hidden[m]],
        w2: vec![0; outputs * hidden[m]],
        b2: (0..outputs).map(bias).collect(),
    };
    QuantizedAnchors {
        grid: PositionGrid { origin: [-1.0; 3], cell: 2.0 / side as f32, depth },
        positions: cells(n),
        feature_dim: f,
        offsets_per_anchor: k,
        feature_step: 0.125,
        features: vec![0; n * f],
        scaling_step: 0.0625,
        scaling: vec![[0; 6]; n],
        offset_step: 0.25,
        offsets: vec![0; n * 3 * k],
        masks: vec![true; n * k],
        mlps: [
            network(0, k, &|_| 40),
            network(1, 3 * k, &|_| 0),
            network(2, 7 * k, &|o| if o % 7 == 3 { 64 } else { 0 }),
        ],
        context: None,
    }
}

/// The side and depth of the smallest grid of at least 32^3 cells holding `n` distinct cells.
fn grid_for(n: usize) -> (u32, u8) {
    let depth = (5..=24).find(|&d| 1u64 << (3 * d) >= n as u64).expect("n below 2^72");
    (1 << depth, depth)
}

/// The first `n` cells of [`grid_for`]'s grid, x fastest.
fn cells(n: usize) -> Vec<[u32; 3]> {
    let (side, _) = grid_for(n);
    (0..n as u32).map(|i| [i % side, (i / side) % side, i / (side * side)]).collect()
}

/// 500,000 plain Gaussians of SH degree 3, every value 0, in a 1,000,000-byte stream: the
/// most Gaussians and values a 1 MB stream holds (2N = L).
fn most_plain_gaussians() -> Vec<u8> {
    let n = 500_000;
    let (side, depth) = grid_for(n);
    let (steps, mut ranges) = ordinary(3);
    (ranges.log_scale, ranges.rotation, ranges.opacity, ranges.dc, ranges.sh_rest) =
        ([-80, -80], [0, 0], [0, 0], [0, 0], [0, 0]);
    let grid = PositionGrid { origin: [-1.0; 3], cell: 2.0 / side as f32, depth };
    plain_stream(&gaussians(&mut Draws::new(4603), grid, cells(n), 3, steps, &ranges))
}

/// 500,000 plain Gaussians of SH degree 0 on a depth-24 octree, at the corners of a 100 x 100
/// x 50 lattice of cells 2^17 apart: below level 7 every node has one child, so the octree's
/// bits are nearly free and its nodes the most a 1 MB stream holds (17 levels of 500,000 nodes).
fn deepest_octree() -> Vec<u8> {
    let positions = (0..500_000u32).map(|i| [i % 100, (i / 100) % 100, i / 10_000].map(|c| c << 17)).collect();
    let (steps, mut ranges) = ordinary(0);
    (ranges.log_scale, ranges.rotation, ranges.opacity, ranges.dc) = ([-128, -128], [0, 0], [0, 0], [0, 0]);
    let grid = PositionGrid { origin: [-1.0; 3], cell: 2.0 / (1u32 << 24) as f32, depth: 24 };
    plain_stream(&gaussians(&mut Draws::new(4604), grid, positions, 0, steps, &ranges))
}

fn anchor_stream(content: &QuantizedAnchors) -> Vec<u8> {
    let bytes = super::super::anchor_vectors::encode(content);
    let decoded = stream::decode(&bytes).expect("the writer's stream decodes");
    assert!(matches!(decoded.content, Content::Anchors(_)));
    bytes
}

/// A context model whose network costs the most a stream of its length allows: 16 levels and
/// 16 plane levels of resolution 2 (dense, small), 8 channels and 128 hidden units, so 512
/// inputs and 75,776 multiply-adds per anchor.
fn widest_context(content: &mut QuantizedAnchors) {
    let shape = ContextGridShape { levels: vec![1; 16], planes: vec![1; 16], table_log2: 12, channels: 8 };
    let mut draws = Draws::new(4602);
    let signs = (0..shape.entries(content.grid.depth) * 8).map(|_| draws.i32([0, 1]) == 1).collect();
    let (inputs, hidden) = (shape.context_len(), 128);
    let outputs = 2 * predicted_values(content.feature_dim, content.offsets_per_anchor);
    let mlp = QuantizedMlp {
        hidden,
        weight_exponent: -8,
        bias_exponent: -8,
        w1: vec![0; hidden * inputs],
        b1: vec![0; hidden],
        w2: vec![0; outputs * hidden],
        // Means 0, log2 scales 4 units.
        b2: (0..outputs).map(|o| if o < outputs / 2 { 0 } else { 1024 }).collect(),
    };
    content.context = Some(QuantizedContext { shape, signs, mlp });
}

pub fn files() -> Vec<Hostile> {
    let neural = uniform_anchors(6000, (6, 14), [8, 8, 8]);
    let mut widest_networks = uniform_anchors(700, (256, 64), [256; 3]);
    widest_networks.scaling.fill([0, 0, 0, -24, -24, -24]);
    let mut context = uniform_anchors(3500, (6, 4), [1; 3]);
    widest_context(&mut context);
    let tables = with_wide_tables(uniform_anchors(128, (6, 4), [1; 3]), 5, 2);
    vec![
        accepted(
            "plain-60k-large.pwb",
            1,
            Some((1920, 1080)),
            "60,000 plain Gaussians of scale e^-0.25 to 1 and opacity 0.62 to 0.82 in the unit cube: each covers most of a \
             1920x1080 view, 490M tile-list entries (2 GB) if a renderer bins them at once."
                .into(),
            large_plain_gaussians(),
        ),
        accepted(
            "anchors-neural-gaussians-at-limit.pwb",
            1,
            Some((320, 240)),
            "6,000 anchors with K = 14 and every mask open: 84,000 neural Gaussians of scale 1/2 in a 168,000-byte \
             stream (2M = L, the most SPEC 12.3 allows), 25M tile-list entries at 320x240."
                .into(),
            anchor_stream(&neural),
        ),
        too_much_blending(
            "plain-30k-needles.pwb",
            (1920, 1080),
            "30,000 plain needles (scale 1 by e^-7, opacity 0.98) crossing a 1920x1080 view diagonally: each meets \
             every tile's box but covers no tile, so no list ends early; 200M tile-list entries, half a minute of \
             blending, past the work limit of SPEC 9."
                .into(),
            needles(30_000),
        ),
        accepted(
            "anchors-view-networks-at-limit.pwb",
            2,
            Some((64, 48)),
            "700 anchors with F = 256, K = 64 and hidden widths 256: 379,904 multiply-adds per anchor and view, \
             1024 per byte of stream (the limit of SPEC 12.1), 44,800 neural Gaussians."
                .into(),
            anchor_stream(&widest_networks),
        ),
        accepted(
            "anchors-context-network-at-limit.pwb",
            2,
            None,
            "3,500 anchors with a context model of 32 levels and planes, 8 channels and 128 hidden units: 75,776 \
             multiply-adds per anchor, 1024 per byte of stream (the limit of SPEC 12.7)."
                .into(),
            anchor_stream(&context),
        ),
        accepted(
            "anchors-context-tables-at-limit.pwb",
            2,
            None,
            format!(
                "128 anchors whose context model needs 321 tables of {} symbols in all (64 x 5 of the widest) in a \
                 stream of 32,729 bytes: 2^20 plus 8 per byte, the limit of SPEC 12.7.",
                wide_table_symbols(5)
            ),
            anchor_stream(&tables),
        ),
    ]
}

/// Streams of 1,000,000 bytes at SPEC.md section 9's per-byte limits, the heaviest a 1 MB
/// stream can be to decode or to view: not in the suite (3 MB of files, and their decoding
/// takes seconds), written by `cargo run --release -p pwgs-conformance --bin limit-streams DIR`
/// for measuring a decoder's time and memory on them.
pub fn at_one_megabyte() -> Vec<Hostile> {
    // The most values a 1 MB stream holds: 120,300 anchors of 266 values (F = 256, K = 1), 32 per byte of 1,000,000 bytes.
    let most_values = uniform_anchors(120_300, (256, 1), [1; 3]);
    // At all three limits: 500,000 anchors (2N = L) of K = 1 (2M = L) and F = 54 (32 values per byte).
    let most_anchors = uniform_anchors(500_000, (54, 1), [1; 3]);
    // At every bound of an anchor stream with ACTX: the values of `most_values`, a context
    // network of 15 units (120,300 x 8,019 multiply-adds, 94% of 1024 per byte) and 64 x 34
    // tables of 4,095 symbols (8.9M symbols, 98% of 2^20 + 8 per byte).
    let every_bound = with_wide_tables(uniform_anchors(120_300, (256, 1), [1; 3]), 34, 15);
    vec![
        too_much_blending(
            "anchors-values-and-neural-gaussians-at-limit.pwb",
            (1920, 1080),
            "500,000 anchors of F = 54 and K = 1 in a 1,000,000-byte stream: 32 values per byte and one anchor and one \
             neural Gaussian per two bytes, the limits of SPEC 4, 12.1 and 12.3; at 1920x1080 its large faint splats \
             need 153M units of blend work, past the limit of SPEC 9 (107M)."
                .into(),
            anchor_stream(&most_anchors),
        ),
        accepted(
            "plain-500k-sh3-at-limit.pwb",
            1,
            Some((1920, 1080)),
            "500,000 plain Gaussians of SH degree 3 (every value 0, scale e^-2.5) in a 1,000,000-byte stream: \
             the most Gaussians (2N = L) and values a 1 MB plain stream holds, at 1920x1080."
                .into(),
            most_plain_gaussians(),
        ),
        accepted(
            "plain-500k-deepest-octree.pwb",
            2,
            None,
            "500,000 plain Gaussians on a depth-24 octree in a 1,000,000-byte stream, each below level 7 the only \
             child of its parent: 68M octree bits, nearly free to code."
                .into(),
            deepest_octree(),
        ),
        accepted(
            "anchors-values-at-limit.pwb",
            2,
            Some((1920, 1080)),
            "120,300 anchors of F = 256 and K = 1 in a 1,000,000-byte stream: 32 values per byte, the most SPEC 12.1 \
             allows, at 1920x1080."
                .into(),
            anchor_stream(&most_values),
        ),
        accepted(
            "anchors-context-every-bound.pwb",
            2,
            Some((1920, 1080)),
            format!(
                "120,300 anchors of F = 256 and K = 1 with a context model in a 1,000,000-byte stream: 32 values per \
                 byte, 965M multiply-adds of the context network and tables of {} symbols (64 x 34 of the widest), \
                 at or near the limits of SPEC 12.1 and 12.7.",
                wide_table_symbols(34)
            ),
            anchor_stream(&every_bound),
        ),
        too_much_blending(
            "plain-500k-needles.pwb",
            (64, 48),
            "500,000 plain needles crossing the view diagonally in a 1,000,000-byte stream: past the work limit of \
             SPEC 9 even at 64x48 (6M tile-list entries)."
                .into(),
            needles(500_000),
        ),
        accepted(
            "plain-500k-faint-discs.pwb",
            1,
            Some((64, 48)),
            "500,000 plain Gaussians of scale 1 and opacity 0.008 in a 1,000,000-byte stream: a tile's list ends only \
             after about 2,500 cover it whole."
                .into(),
            faint_discs(500_000),
        ),
    ]
}

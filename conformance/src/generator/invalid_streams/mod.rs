//! The invalid streams: valid generated streams with one thing broken (two, for the cases that
//! pin which failure is reported first: decision 7), CRCs sealed again so that each reaches the
//! check it targets. Each names the SPEC.md clause it breaks and the error it must produce.

mod classes;
mod coding;
mod container;
mod differences;
mod order;
mod sections;
mod trees;

use pwgs_bitstream::Tag;
use pwgs_codec::stream::plain::{COLORS, OPACITIES, ROTATIONS, SCALES, SH_REST};
use pwgs_codec::stream::wrap::QuantizedSynthesis;
use pwgs_codec::wrapper::synthesis::WrapperConfig;

use super::Refusal;
use super::content::{self, BlockValues, Ranges, ordinary, ordinary_gaussians};
use super::raw::{BlockParts, Sections};
use super::valid_vectors::encode;

/// Every invalid stream.
pub fn refusals() -> Vec<Refusal> {
    let bases = Bases::new();
    let mut cases = Cases::default();
    container::container_and_fields(&bases, &mut cases);
    coding::coding(&bases, &mut cases);
    sections::sections(&bases, &mut cases);
    order::order(&bases, &mut cases);
    classes::classes(&mut cases);
    differences::differences(&mut cases);
    trees::trees(&mut cases);
    cases.0
}

/// The refusals made so far.
#[derive(Default)]
struct Cases(Vec<Refusal>);

impl Cases {
    /// Adds the stream `file`.pwb, which must be refused for breaking `clause` with an error
    /// matching `error`.
    fn add(&mut self, file: &str, clause: &'static str, error: &str, description: &str, bytes: Vec<u8>) {
        let (file, error, description) = (format!("{file}.pwb"), error.into(), description.into());
        self.0.push(Refusal { file, clause, error, description, bytes });
    }
}

/// Byte offsets of the `HEAD` fields (SPEC.md section 4).
mod head {
    pub const BASE: usize = 0;
    pub const COUNT: usize = 1;
    pub const DEGREE: usize = 5;
    pub const CENTER: usize = 6;
    pub const SCALE: usize = 18;
    pub const BACKGROUND: usize = 22;
}

/// Byte offsets of the `POSN` fields (SPEC.md section 6.1).
mod posn {
    pub const ORIGIN: usize = 0;
    pub const CELL: usize = 12;
    pub const DEPTH: usize = 16;
}

/// Byte offsets of the `WRAP` fields (SPEC.md section 11.4).
mod wrap {
    pub const ACTIVATION: usize = 0;
    pub const WIDTH: usize = 1;
    pub const INPUTS: usize = 2;
    pub const WEIGHT_EXPONENT: usize = 11;
    pub const BIAS_EXPONENT: usize = 12;
    pub const PARAMETERS: usize = 13;
}

/// (steps, channels) of each attribute block of the base stream (SH degree 2).
fn geometry(tag: Tag) -> (usize, usize) {
    match tag {
        SCALES => (1, 3),
        ROTATIONS => (1, 4),
        OPACITIES => (1, 1),
        COLORS => (1, 3),
        SH_REST => (2, 24),
        other => panic!("{other} is no attribute block"),
    }
}

/// The streams the cases break.
struct Bases {
    /// 12 Gaussians of degree 2 with a wrapper (width 2, both inputs); their log-scales
    /// (-100..=-90) and coded rotation components (-20..=20) lie inside the hand-made tables of
    /// the escape and rotation-index cases.
    plain: Vec<u8>,
    synthesis: QuantizedSynthesis,
    values: BlockValues,
    /// N = 0, degree 1.
    empty: Vec<u8>,
}

impl Bases {
    fn new() -> Self {
        // Narrow ranges keep the tables, hence every invalid file, small.
        let mut draws = content::Draws::new(90);
        let positions = (0..12).map(|_| draws.point(8)).collect();
        let ranges =
            Ranges { log_scale: [-100, -90], rotation: [-20, 20], opacity: [0, 10], dc: [-10, 10], sh_rest: [-3, 3] };
        let content = content::gaussians(&mut draws, content::unit_cube(8), positions, 2, ordinary(2).0, &ranges);
        let synthesis = content::synthesis(WrapperConfig { width: 2, noise: true, plucker: true, seed: 5 }, 91);
        Self {
            plain: encode(&content, Some(&synthesis)),
            synthesis,
            values: BlockValues::of(&content),
            empty: encode(&ordinary_gaussians(92, 0, 1), None),
        }
    }
}

/// Edits the sections of `stream` and seals them again.
fn edit(stream: &[u8], f: impl FnOnce(&mut Sections)) -> Vec<u8> {
    let mut s = Sections::of(stream);
    f(&mut s);
    s.seal()
}

/// Overwrites bytes of a payload.
fn put(payload: &mut [u8], at: usize, bytes: &[u8]) {
    payload[at..at + bytes.len()].copy_from_slice(bytes);
}

/// Edits one attribute block of the base stream, split into its fields.
fn edit_block(s: &mut Sections, tag: Tag, f: impl FnOnce(&mut BlockParts)) {
    let (steps, channels) = geometry(tag);
    let mut parts = BlockParts::split(s.payload(tag), steps, channels);
    f(&mut parts);
    *s.payload(tag) = parts.join();
}

/// Adds a critical section 'ZZZZ', which version 1.0 does not define.
fn unknown_critical(s: &mut Sections) {
    s.list.push((Tag(*b"ZZZZ"), vec![1, 2, 3]));
}

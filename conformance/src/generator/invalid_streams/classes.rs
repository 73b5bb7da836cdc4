//! Invalid importance classes (SPEC.md section 6.5): each field of `IMPC` out of its range, a
//! class step that overflows, a chunk that ends early or holds too much, and `IMPC` in an
//! anchor stream.

use pwgs_codec::stream::classes::CLASSES;

use super::{Cases, edit, put};
use crate::generator::anchor_vectors::{self, synthetic_anchors};
use crate::generator::content::classed_gaussians;
use crate::generator::raw::Sections;
use crate::generator::valid_vectors::encode;

/// Byte offsets of the `IMPC` fields of the base stream (3 classes).
mod impc {
    pub const CLASSES: usize = 0;
    pub const REFINE: usize = 1;
    pub const FACTORS: usize = 2;
    pub const DROPS: usize = 14;
}

pub(super) fn classes(cases: &mut Cases) {
    // 10 Gaussians of degree 0, 3 classes, POSN depth 6 refined by 2 levels.
    let p = &encode(&classed_gaussians(93, 10, 0, (3, 2, 6)), None);
    let field = |file: &str, clause: &'static str, error: &str, description: &str, at: usize, bytes: &[u8]| {
        let stream = edit(p, |s| put(s.payload(CLASSES), at, bytes));
        (file.to_string(), clause, error.to_string(), description.to_string(), stream)
    };
    let factor = |k: usize| impc::FACTORS + 4 * k;
    let edits = [
        field(
            "impc-classes-1",
            "S6.5-classes-count",
            "section 'IMPC', field `classes` … 1 is outside 2..=16",
            "IMPC declares 1 class.",
            impc::CLASSES,
            &[1],
        ),
        field(
            "impc-classes-17",
            "S6.5-classes-count",
            "section 'IMPC', field `classes` … 17 is outside 2..=16",
            "IMPC declares 17 classes.",
            impc::CLASSES,
            &[17],
        ),
        field(
            "impc-refine-past-24",
            "S6.5-refine",
            "section 'IMPC', field `refine` … exceed 24",
            "IMPC refines POSN's 6 levels by 19: 25 in all.",
            impc::REFINE,
            &[19],
        ),
        field(
            "impc-factor-zero",
            "S6.5-factor-positive",
            "section 'IMPC', field `factor` … 0 is not positive",
            "Class 1's factor is 0.",
            factor(1),
            &0f32.to_le_bytes(),
        ),
        field(
            "impc-factor-negative",
            "S6.5-factor-positive",
            "section 'IMPC', field `factor` … -2 is not positive",
            "Class 2's factor is -2.",
            factor(2),
            &(-2f32).to_le_bytes(),
        ),
        field(
            "impc-factor-nan",
            "S1-f32-nan",
            "section 'IMPC', field `factor` … NaN is not finite",
            "Class 0's factor is NaN.",
            factor(0),
            &f32::NAN.to_le_bytes(),
        ),
        field(
            "impc-drop-above-refine",
            "S6.5-drop",
            "section 'IMPC', field `drop` … 3 exceeds refine 2",
            "Class 2 drops 3 levels of the 2 refined.",
            impc::DROPS + 2,
            &[3],
        ),
        field(
            "impc-class-step-too-large",
            "S6.5-class-step",
            "section 'SCAL', field `step` … times class 2's factor",
            "Class 2's factor is 2^127: SCAL's step times it, times 2^24, is infinite in f32.",
            factor(2),
            &f32::from_bits(0x7F00_0000).to_le_bytes(),
        ),
    ];
    for (file, clause, error, description, bytes) in edits {
        cases.add(&file, clause, &error, &description, bytes);
    }
    cases.add(
        "impc-chunk-unaligned",
        "S6.5-chunk",
        "section 'IMPC': coded data: coded data length … is not a multiple of 4 bytes",
        "IMPC's chunk is 2 bytes longer than a whole number of words.",
        edit(p, |s| s.payload(CLASSES).extend([0; 2])),
    );
    cases.add(
        "impc-chunk-extra-words",
        "S6.5-chunk",
        "section 'IMPC': coded data: 4 unread bytes after the last symbol",
        "IMPC's chunk has two zero words appended; its decoding reads one of them (in place of an overrun), \
         the other is never read.",
        edit(p, |s| s.payload(CLASSES).extend([0; 8])),
    );
    let anchors = anchor_vectors::encode(&synthetic_anchors(20, 94));
    let payload = Sections::of(p).payload(CLASSES).clone();
    cases.add(
        "impc-in-anchor-stream",
        "S6.5-plain-only",
        "IMPC",
        "The anchors vector's stream with the IMPC section of a plain stream: the anchor base does not \
         define it, so it is an unknown critical section there.",
        edit(&anchors, |s| s.insert(2, CLASSES, payload)),
    );
}

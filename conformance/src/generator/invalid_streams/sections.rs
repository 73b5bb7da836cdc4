//! Invalid plain-3DGS sections and wrappers.

use pwgs_bitstream::Tag;
use pwgs_codec::stream::entropy::MAX_MAGNITUDE;
use pwgs_codec::stream::plain::{COLORS, OPACITIES, POSITIONS, ROTATIONS, SCALES, SH_REST};
use pwgs_codec::stream::wrap::WRAPPER;

use super::{Bases, Cases, edit, head, posn, put, wrap};
use crate::generator::raw::{BlockParts, Sections, block, flat_table};
use crate::generator::valid_vectors::largest_step;

/// A ROTN block coding `index` as the first Gaussian's largest-component index.
fn rotn_with_first_index(b: &Bases, s: &mut Sections, index: i32) {
    let mut values = b.values.rotations.clone();
    values[0][0] = index;
    let rest = flat_table(-512, 1025);
    *s.payload(ROTATIONS) = block(&[1.0 / 1024.0], &[flat_table(0, 5), rest.clone(), rest.clone(), rest], &values);
}

/// The sections of a plain-3DGS stream, their fields and the wrapper (SPEC.md sections 6 and
/// 11.4, decision 5).
pub(super) fn sections(b: &Bases, cases: &mut Cases) {
    let p = &b.plain;
    // Which sections a plain-3DGS stream holds: SPEC.md section 6 and decision 5.
    for tag in [POSITIONS, COLORS, SH_REST] {
        let name = String::from_utf8_lossy(&tag.0).to_lowercase();
        let error = format!("the stream has no {tag} section");
        let description = format!("The {tag} section is missing (SH degree 2).");
        cases.add(&format!("missing-{name}"), "S6-missing-section", &error, &description, edit(p, |s| s.remove(tag)));
    }
    cases.add(
        "shrs-with-degree-0",
        "S6-shrs-with-d0",
        "section 'SHRS': present, but the SH degree is 0",
        "HEAD's SH degree is 0 and the stream holds SHRS (decision 5).",
        edit(p, |s| s.payload(Tag::HEAD)[head::DEGREE] = 0),
    );

    // POSN: SPEC.md section 6.1.
    for (file, value, error) in [
        ("posn-cell-zero", 0.0f32, "section 'POSN', field `cell` … 0 is not positive"),
        ("posn-cell-negative", -0.25, "section 'POSN', field `cell` … -0.25 is not positive"),
        ("posn-cell-nan", f32::NAN, "section 'POSN', field `cell` … NaN is not finite"),
    ] {
        let bytes = edit(p, |s| put(s.payload(POSITIONS), posn::CELL, &f32::to_le_bytes(value)));
        let clause = if value.is_nan() { "S1-f32-nan" } else { "S6.1-cell-positive" };
        cases.add(file, clause, error, &format!("POSN's cell is {value}."), bytes);
    }
    for (file, depth, error) in [
        ("posn-depth-0", 0u8, "section 'POSN', field `depth` … 0 is outside 1..=24"),
        ("posn-depth-25", 25, "section 'POSN', field `depth` … 25 is outside 1..=24"),
    ] {
        let bytes = edit(p, |s| s.payload(POSITIONS)[posn::DEPTH] = depth);
        cases.add(file, "S6.1-depth", error, &format!("POSN's depth is {depth}."), bytes);
    }
    cases.add(
        "posn-grid-reaches-f32-max",
        "S6.1-extent",
        "section 'POSN', field `cell` … reaches beyond binary32",
        "Origin 0 and cell (2 - 2^-23) * 2^119 on a depth-8 grid: cell * 2^8 is exactly the largest binary32, \
         which the extent must stay below.",
        edit(p, |s| {
            let payload = s.payload(POSITIONS);
            put(payload, posn::ORIGIN, &[0; 12]);
            put(payload, posn::CELL, &f32::to_le_bytes(f32::MAX / 256.0));
        }),
    );
    let count = |n: u32| move |s: &mut Sections| put(s.payload(Tag::HEAD), head::COUNT, &n.to_le_bytes());
    cases.add(
        "posn-more-points-than-count",
        "S6.1-too-many-points",
        "section 'POSN': coded data: the octree holds more than the 11 points the header declares",
        "HEAD declares 11 Gaussians; the octree holds 12.",
        edit(p, count(11)),
    );
    cases.add(
        "posn-fewer-points-than-count",
        "S6.1-too-few-points",
        "section 'POSN': coded data: the octree holds 12 points, the header declares 13",
        "HEAD declares 13 Gaussians; the octree holds 12.",
        edit(p, count(13)),
    );

    // Attribute blocks: SPEC.md section 6.2.
    let too_large = f32::from_bits(largest_step().to_bits() + 1);
    let step_cases: [(&str, &'static str, Tag, usize, f32, &str); 7] = [
        ("scal-step-zero", "S6.2-step-positive", SCALES, 0, 0.0, "section 'SCAL', field `step` … 0 is not positive"),
        (
            "opac-step-negative",
            "S6.2-step-positive",
            OPACITIES,
            0,
            -0.5,
            "section 'OPAC', field `step` … -0.5 is not positive",
        ),
        (
            "shrs-second-step-zero",
            "S6.2-step-positive",
            SH_REST,
            1,
            0.0,
            "section 'SHRS', field `step` … 0 is not positive",
        ),
        ("colr-step-nan", "S1-f32-nan", COLORS, 0, f32::NAN, "section 'COLR', field `step` … NaN is not finite"),
        (
            "scal-step-infinite",
            "S1-f32-before-constraint",
            SCALES,
            0,
            f32::INFINITY,
            "section 'SCAL', field `step` … inf is not finite",
        ),
        (
            "rotn-step-too-large",
            "S6.2-step-too-large",
            ROTATIONS,
            0,
            too_large,
            "section 'ROTN', field `step` … 20282410000000000000000000000000 is not positive or too large",
        ),
        (
            "shrs-step-minus-zero",
            "S6.2-step-positive",
            SH_REST,
            0,
            -0.0,
            "section 'SHRS', field `step` … -0 is not positive",
        ),
    ];
    for (file, clause, tag, index, value, error) in step_cases {
        let bytes = edit(p, |s| put(s.payload(tag), 4 * index, &f32::to_le_bytes(value)));
        let description =
            format!("{tag}'s step {index} is {value:e} (steps must be positive, with step * 2^24 finite).");
        cases.add(file, clause, error, &description, bytes);
    }
    cases.add(
        "rotn-index-4",
        "S6.2-rotn-largest",
        "section 'ROTN': largest-component index 4 is not 0..=3",
        "The first Gaussian's largest-component index is 4 (its table covers 0..=4).",
        edit(p, |s| rotn_with_first_index(b, s, 4)),
    );
    cases.add(
        "rotn-index-negative",
        "S6.2-rotn-largest",
        "section 'ROTN': largest-component index -1 is not 0..=3",
        "The first Gaussian's largest-component index is -1 (escaped).",
        edit(p, |s| rotn_with_first_index(b, s, -1)),
    );

    // The perceptual wrapper: SPEC.md section 11.4.
    let wrap_cases: [(&str, &'static str, usize, u8, &str); 7] = [
        (
            "wrap-activation-1",
            "S11.4-activation",
            wrap::ACTIVATION,
            1,
            "section 'WRAP', field `activation` … unknown activation 1",
        ),
        ("wrap-width-0", "S11.4-width", wrap::WIDTH, 0, "section 'WRAP', field `width` … 0 is outside 1..=64"),
        ("wrap-width-65", "S11.4-width", wrap::WIDTH, 65, "section 'WRAP', field `width` … 65 is outside 1..=64"),
        (
            "wrap-inputs-bit-2",
            "S11.4-inputs",
            wrap::INPUTS,
            0x07,
            "section 'WRAP', field `inputs` … unknown input flags 0x07",
        ),
        (
            "wrap-inputs-bit-7",
            "S11.4-inputs",
            wrap::INPUTS,
            0x80,
            "section 'WRAP', field `inputs` … unknown input flags 0x80",
        ),
        (
            "wrap-weight-exponent-1",
            "S11.4-weight-exponent",
            wrap::WEIGHT_EXPONENT,
            1,
            "section 'WRAP', field `weight step exponent` … 1 is outside -30..=0",
        ),
        (
            "wrap-bias-exponent-minus-31",
            "S11.4-bias-exponent",
            wrap::BIAS_EXPONENT,
            (-31i8) as u8,
            "section 'WRAP', field `bias step exponent` … -31 is outside -30..=0",
        ),
    ];
    for (file, clause, at, value, error) in wrap_cases {
        let bytes = edit(p, |s| s.payload(WRAPPER)[at] = value);
        cases.add(file, clause, error, &format!("WRAP's byte {at} is {value:#04x}."), bytes);
    }
    let mut large = b.synthesis.clone();
    large.values[0] = MAX_MAGNITUDE;
    cases.add(
        "wrap-parameter-2-24",
        "S11.4-parameter-magnitude",
        "section 'WRAP', field `parameter` … 16777216 exceeds the magnitude limit",
        "WRAP's first parameter is 2^24.",
        edit(p, |s| *s.payload(WRAPPER) = large.write()),
    );
    cases.add(
        "wrap-parameters-truncated",
        "S11.4-parameter-count",
        "section 'WRAP', field `parameter` … needs 1 bytes, 0 left",
        "WRAP stops before its last parameter.",
        edit(p, |s| {
            s.payload(WRAPPER).pop();
        }),
    );
    cases.add(
        "wrap-seed-truncated",
        "S11.4-seed-truncated",
        "section 'WRAP', field `seed` … needs 8 bytes, 4 left",
        "WRAP stops inside its u64 seed (decision 9).",
        edit(p, |s| s.payload(WRAPPER).truncate(7)),
    );

    // More of SPEC.md sections 6 and 11.4.
    cases.add(
        "missing-scal-and-rotn",
        "S6-missing-order",
        "the stream has no 'SCAL' section",
        "ROTN and SCAL are both missing: SCAL comes first in the order of decision 7.",
        edit(p, |s| {
            s.remove(ROTATIONS);
            s.remove(SCALES);
        }),
    );
    cases.add(
        "shrs-with-degree-0-and-no-colr",
        "S6-shrs-d0-after-missing",
        "the stream has no 'COLR' section",
        "SH degree 0 with an SHRS section, and no COLR: missing sections come first.",
        edit(p, |s| {
            s.payload(Tag::HEAD)[head::DEGREE] = 0;
            s.remove(COLORS);
        }),
    );
    cases.add(
        "posn-cell-minus-zero",
        "S6.1-cell-positive",
        "section 'POSN', field `cell` … -0 is not positive",
        "POSN's cell is -0.0.",
        edit(p, |s| put(s.payload(POSITIONS), posn::CELL, &(-0.0f32).to_le_bytes())),
    );
    cases.add(
        "posn-more-nodes-than-count",
        "S6.1-too-many-nodes",
        "section 'POSN': coded data: the octree holds more than the 1 points the header declares",
        "HEAD declares 1 Gaussian; the octree's root has several occupied children.",
        edit(p, count(1)),
    );
    cases.add(
        "colr-tables-truncated",
        "S6.2-block-table-count",
        "section 'COLR', field `table lo`",
        "COLR stops after its step and first table.",
        edit(p, |s| {
            let parts = BlockParts::split(s.payload(COLORS), 1, 3);
            let len = parts.steps.len() + parts.tables[0].len();
            s.payload(COLORS).truncate(len);
        }),
    );
    cases.add(
        "rotn-index-before-opac-chunk",
        "S6.2-rotn-largest-order",
        "section 'ROTN': largest-component index 4 is not 0..=3",
        "The first largest-component index is 4 and OPAC's chunk has 3 trailing words: ROTN's values come \
         before OPAC in the order of decision 7.",
        edit(p, |s| {
            rotn_with_first_index(b, s, 4);
            s.payload(OPACITIES).extend([0; 12]);
        }),
    );
    let mut overlong = b.synthesis.clone();
    overlong.values[0] = 0;
    let mut payload = overlong.write();
    payload.splice(wrap::PARAMETERS..wrap::PARAMETERS + 1, [0x80, 0x00]);
    cases.add(
        "wrap-parameter-overlong",
        "S11.4-parameter-varint",
        "section 'WRAP', field `parameter` … overlong varint",
        "WRAP's first parameter, 0, written in two bytes.",
        edit(p, |s| *s.payload(WRAPPER) = payload),
    );
    cases.add(
        "wrap-parameter-truncated-varint",
        "S1-varint-truncated",
        "section 'WRAP', field `parameter` … needs 1 bytes, 0 left",
        "WRAP's last byte has its high bit set: the last parameter's varint runs past the payload.",
        edit(p, |s| *s.payload(WRAPPER).last_mut().expect("parameters") |= 0x80),
    );
    cases.add(
        "wrap-width-and-inputs",
        "S11.4-field-order",
        "section 'WRAP', field `width` … 0 is outside 1..=64",
        "WRAP's width is 0 and its inputs 4: width comes first.",
        edit(p, |s| {
            s.payload(WRAPPER)[wrap::WIDTH] = 0;
            s.payload(WRAPPER)[wrap::INPUTS] = 4;
        }),
    );
    cases.add(
        "wrap-extra-parameters",
        "S11.4-parameter-extra",
        "section 'WRAP', field `end of section` … 2 unexpected trailing bytes",
        "Version 1.0 with two parameters (1 and 2) after the last one WRAP's configuration has.",
        edit(p, |s| s.payload(WRAPPER).extend([0x02, 0x04])),
    );
}

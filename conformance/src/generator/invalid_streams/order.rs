//! Streams with two failures: the decoder must report the one decision 7 checks first.

use pwgs_bitstream::Tag;
use pwgs_codec::stream::entropy::TOTAL;
use pwgs_codec::stream::plain::{COLORS, OPACITIES, POSITIONS, ROTATIONS, SCALES};
use pwgs_codec::stream::wrap::WRAPPER;

use super::{Bases, Cases, edit, edit_block, head, posn, put, unknown_critical, wrap};
use crate::generator::raw::{Sections, raw_table, section_offsets};

/// The order cases.
pub(super) fn order(b: &Bases, cases: &mut Cases) {
    let p = &b.plain;
    let zero_cell = |s: &mut Sections| put(s.payload(POSITIONS), posn::CELL, &[0; 4]);
    let zero_step = |tag: Tag| move |s: &mut Sections| put(s.payload(tag), 0, &[0; 4]);
    let large_count = |s: &mut Sections| put(s.payload(Tag::HEAD), head::COUNT, &(1u32 << 20).to_le_bytes());
    let mut bytes = p.clone();
    bytes[8] = 2;
    cases.add(
        "order-major-before-crc",
        "S2.2-major",
        "stream is version 2.0; this decoder reads major version 1",
        "Major version 2 written over a 1.0 stream, CRC not updated: the version is refused before anything \
         is verified.",
        bytes,
    );
    let mut bytes = edit(p, |s| s.insert(1, Tag(*b"x*yz"), vec![0; 4]));
    let at = section_offsets(&bytes)[1] + 4;
    put(&mut bytes, at, &((1u32 << 28) + 1).to_le_bytes());
    cases.add(
        "order-tag-before-length",
        "S2.3-order-tag-before-length",
        "section tag [78, 2a, 79, 7a] at byte 58 is malformed",
        "A section tagged 'x*yz' declaring 2^28 + 1 bytes: within a section header, the tag is checked \
         before the length (SPEC.md section 2.3).",
        bytes,
    );
    let mut bytes = edit(p, |s| s.payload(Tag::HEAD)[head::BASE] = 1);
    let at = section_offsets(&bytes)[2] + 20;
    bytes[at] ^= 1;
    cases.add(
        "order-container-before-head",
        "S6.4-a-before-b",
        "section 'SCAL' at byte 139 is corrupt",
        "HEAD's base is 1 and SCAL's CRC fails: container checks come first.",
        bytes,
    );
    cases.add(
        "order-head-fields",
        "S3-field-order",
        "section 'HEAD', field `sh degree` … 4 exceeds 3",
        "HEAD's SH degree is 4 and its scale 0: HEAD's fields are checked in table order.",
        edit(p, |s| {
            s.payload(Tag::HEAD)[head::DEGREE] = 4;
            put(s.payload(Tag::HEAD), head::SCALE, &[0; 4]);
        }),
    );
    cases.add(
        "order-head-before-unknown-critical",
        "S6.4-b-before-c",
        "section 'HEAD', field `scale` … 0 is not positive",
        "HEAD's scale is 0 and a critical section 'ZZZZ' is unknown.",
        edit(p, |s| {
            put(s.payload(Tag::HEAD), head::SCALE, &[0; 4]);
            unknown_critical(s);
        }),
    );
    cases.add(
        "order-unknown-critical-before-count",
        "S6.4-c-before-d",
        "section 'ZZZZ', which this decoder does not know",
        "An unknown critical section and a count of 2^20 in a stream of a few hundred bytes.",
        edit(p, |s| {
            large_count(s);
            unknown_critical(s);
        }),
    );
    cases.add(
        "order-count-before-presence",
        "S6.4-d-before-e",
        "section 'HEAD': gaussian count 1048576 exceeds half the stream's length",
        "A count of 2^20 in a stream of a few hundred bytes, and no COLR section.",
        edit(p, |s| {
            large_count(s);
            s.remove(COLORS);
        }),
    );
    cases.add(
        "order-presence-before-posn",
        "S6.4-e-before-f",
        "the stream has no 'COLR' section",
        "No COLR section, and POSN's cell is 0.",
        edit(p, |s| {
            zero_cell(s);
            s.remove(COLORS);
        }),
    );
    cases.add(
        "order-shrs-absence-before-posn",
        "S6.4-e-before-f",
        "section 'SHRS': present, but the SH degree is 0",
        "SH degree 0 with an SHRS section, and POSN's cell is 0.",
        edit(p, |s| {
            zero_cell(s);
            s.payload(Tag::HEAD)[head::DEGREE] = 0;
        }),
    );
    cases.add(
        "order-posn-before-blocks",
        "S6.4-f-before-g",
        "section 'POSN', field `cell` … 0 is not positive",
        "POSN's cell is 0 and SCAL's step is 0.",
        edit(p, |s| {
            zero_cell(s);
            zero_step(SCALES)(s);
        }),
    );
    cases.add(
        "order-posn-chunk-before-blocks",
        "S6.4-f-before-g",
        "section 'POSN': coded data: … unread bytes",
        "POSN's chunk has 3 trailing words and SCAL's step is 0: POSN is decoded before any block.",
        edit(p, |s| {
            s.payload(POSITIONS).extend([0; 12]);
            zero_step(SCALES)(s);
        }),
    );
    cases.add(
        "order-blocks-in-section-order",
        "S6.4-g-section-order",
        "section 'ROTN', field `table lo/size` … 0 symbols",
        "ROTN's third table has 0 symbols and OPAC's chunk has 3 trailing words: ROTN comes first.",
        edit(p, |s| {
            s.payload(OPACITIES).extend([0; 12]);
            edit_block(s, ROTATIONS, |b| b.tables[2] = raw_table(0, 0, &[TOTAL]));
        }),
    );
    cases.add(
        "order-blocks-not-stream-order",
        "S6.4-g-section-order",
        "section 'SCAL': coded data: … unread bytes",
        "COLR (step 0) comes before SCAL (3 trailing words) in the stream: SCAL is reported, as the decision's \
         order is that of the sections, not of the stream.",
        edit(p, |s| {
            zero_step(COLORS)(s);
            s.payload(SCALES).extend([0; 12]);
            let scal = s.index(SCALES);
            let colr = s.index(COLORS);
            s.list.swap(scal, colr);
        }),
    );
    cases.add(
        "order-step-before-table",
        "S6.4-g-within",
        "section 'SCAL', field `step` … 0 is not positive",
        "SCAL's step is 0 and its first table has 0 symbols: steps, then tables.",
        edit(p, |s| {
            zero_step(SCALES)(s);
            edit_block(s, SCALES, |b| b.tables[0] = raw_table(0, 0, &[TOTAL]));
        }),
    );
    cases.add(
        "order-table-before-chunk",
        "S6.4-g-within",
        "section 'SCAL', field `table frequencies` … frequencies sum to 300",
        "SCAL's last table sums to 300 and its chunk is unaligned: tables, then the chunk.",
        edit(p, |s| {
            edit_block(s, SCALES, |b| {
                b.tables[2] = raw_table(-100, 1, &[100, 200]);
                b.chunk.push(0);
            })
        }),
    );
    cases.add(
        "order-blocks-before-wrap",
        "S6.4-g-before-h",
        "section 'COLR', field `step` … 0 is not positive",
        "WRAP's width is 0 and COLR's step is 0: WRAP comes last.",
        edit(p, |s| {
            s.payload(WRAPPER)[wrap::WIDTH] = 0;
            zero_step(COLORS)(s);
        }),
    );
    cases.add(
        "order-count-before-posn",
        "S4-count-vs-length-order",
        "section 'HEAD': gaussian count 1048576 exceeds half the stream's length",
        "A count of 2^20 in a stream of a few hundred bytes, and POSN's chunk has 3 trailing words.",
        edit(p, |s| {
            large_count(s);
            s.payload(POSITIONS).extend([0; 12]);
        }),
    );
}

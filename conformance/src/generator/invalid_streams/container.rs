//! Invalid containers, field syntax, HEAD fields and counts beyond the work bound.

use pwgs_bitstream::{FieldReader, FieldWriter, MAGIC, SECTION_OVERHEAD, Tag};
use pwgs_codec::stream::PADDING;
use pwgs_codec::stream::plain::{POSITIONS, PlainGaussians, SCALES};
use pwgs_codec::stream::wrap::WRAPPER;

use super::{Bases, Cases, edit, edit_block, head, posn, put, unknown_critical};
use crate::generator::raw::{Sections, section_offsets};
use crate::generator::valid_vectors::{alike_gaussians, encode};

/// Bytes before the first section: magic and version.
const MAGIC_AND_VERSION: usize = MAGIC.len() + 4;

/// `content`'s stream with its padding section resized to make it exactly `len` bytes long.
fn padded(content: &PlainGaussians, len: usize) -> Vec<u8> {
    let mut sections = Sections::of(&encode(content, None));
    sections.list.retain(|(tag, _)| *tag != PADDING);
    let short = sections.seal().len() + SECTION_OVERHEAD;
    assert!(short <= len, "the stream is already {short} bytes with an empty pad, more than {len}");
    sections.list.push((PADDING, vec![0; len - short]));
    sections.seal()
}

/// A table's syntax with its size written in an overlong varint of two bytes.
fn overlong_size(table: &[u8]) -> Vec<u8> {
    let mut r = FieldReader::new("table", table);
    let lo = r.signed_varint("lo").expect("valid");
    let n = r.varint("n").expect("valid");
    assert!(n < 128, "a one-byte size");
    let mut w = FieldWriter::new();
    w.signed_varint(lo);
    w.extend(&[n as u8 | 0x80, 0]);
    w.extend(r.rest());
    w.into_bytes()
}

/// A table's syntax with its size replaced by the given varint bytes.
fn size_bytes(table: &[u8], size: &[u8]) -> Vec<u8> {
    let mut r = FieldReader::new("table", table);
    let lo = r.signed_varint("lo").expect("valid");
    r.varint("n").expect("valid");
    let mut w = FieldWriter::new();
    w.signed_varint(lo);
    w.extend(size);
    w.extend(r.rest());
    w.into_bytes()
}

/// The container (SPEC.md sections 2.1 to 2.3), field syntax (1 and 3), HEAD (4) and the work
/// bound (decision 6).
pub(super) fn container_and_fields(b: &Bases, cases: &mut Cases) {
    let p = &b.plain;
    // Container: SPEC.md sections 2.1 to 2.3.
    let mut bytes = p.clone();
    bytes[0] = 0x88;
    cases.add("magic", "S2.3-magic", "not a pwgs stream", "The first byte of the magic is 0x88.", bytes);
    cases.add(
        "major-2",
        "S2.2-major",
        "stream is version 2.0; this decoder reads major version 1",
        "Major version 2.",
        edit(p, |s| s.major = 2),
    );
    let mut bytes = p.clone();
    bytes[10] = 1;
    cases.add(
        "version-outside-crc",
        "S2.1-crc-first-covers-header",
        "section 'HEAD' at byte 12 is corrupt",
        "The minor version changed to 1 without sealing again: the first section's CRC covers the version.",
        bytes,
    );
    let mut bytes = p.clone();
    let at = section_offsets(p)[2] + 20;
    bytes[at] ^= 0x40;
    cases.add(
        "crc-mismatch",
        "S2.1-crc-mismatch",
        "section 'SCAL' at byte 139 is corrupt: CRC-32C",
        "A SCAL payload byte flipped, CRC not updated.",
        bytes,
    );
    let mut bytes = p.clone();
    bytes.truncate(p.len() - 6);
    cases.add(
        "end-header-truncated",
        "S2.3-header-truncated",
        "stream is truncated: a section header at byte",
        "The stream stops inside END's header.",
        bytes,
    );
    cases.add(
        "no-end",
        "S2.3-no-end",
        "stream is truncated: a section header at byte",
        "The stream stops after its last section, without END.",
        Sections::of(p).seal_without_end(),
    );
    let mut bytes = p.clone();
    bytes.truncate(p.len() - 2);
    cases.add(
        "crc-truncated",
        "S2.3-crc-truncated",
        "stream is truncated: a section CRC at byte",
        "The stream stops inside END's CRC.",
        bytes,
    );
    let mut bytes = p.clone();
    let at = section_offsets(p)[2] + 4;
    put(&mut bytes, at, &((1u32 << 28) + 1).to_le_bytes());
    cases.add(
        "length-over-limit",
        "S2.1-length-limit",
        "section 'SCAL' at byte 139 declares 268435457 bytes, more than the 268435456",
        "SCAL declares 2^28 + 1 bytes.",
        bytes,
    );
    let mut bytes = p.clone();
    put(&mut bytes, at, &100_000u32.to_le_bytes());
    cases.add(
        "payload-truncated",
        "S2.3-payload-truncated",
        "stream is truncated: a section payload at byte 147",
        "SCAL declares 100000 bytes; fewer remain.",
        bytes,
    );
    cases.add(
        "tag-punctuation",
        "S2.1-tag-bad-byte",
        "section tag [78, 2a, 79, 7a] at byte 58 is malformed",
        "An optional section tagged 'x*yz'.",
        edit(p, |s| s.insert(1, Tag(*b"x*yz"), vec![0])),
    );
    cases.add(
        "tag-digit-first",
        "S2.1-tag-first-not-letter",
        "section tag [31, 61, 62, 63] at byte 58 is malformed",
        "A section tagged '1abc' (the first byte must be a letter).",
        edit(p, |s| s.insert(1, Tag(*b"1abc"), vec![0])),
    );
    cases.add(
        "first-not-head",
        "S2.1-first-head",
        "the first section is 'POSN'",
        "POSN comes before HEAD.",
        edit(p, |s| s.list.swap(0, 1)),
    );
    let mut end = Sections::of(p);
    end.list.push((Tag::END, vec![0]));
    cases.add(
        "end-not-empty",
        "S2.1-end-empty",
        "'END ' section must be empty",
        "END holds one byte.",
        end.seal_without_end(),
    );
    let mut bytes = p.clone();
    bytes.push(0);
    cases.add("after-end", "S2.1-end-last", "1 bytes follow the 'END ' section", "A byte follows END.", bytes);
    cases.add(
        "duplicate-critical",
        "S2.1-duplicate-critical",
        "section 'SCAL' appears twice",
        "SCAL appears twice.",
        edit(p, |s| {
            let scal = s.payload(SCALES).clone();
            s.insert(3, SCALES, scal);
        }),
    );
    cases.add(
        "duplicate-optional",
        "S2.1-duplicate-optional",
        "section 'note' appears twice",
        "The optional section 'note' appears twice.",
        edit(p, |s| {
            s.list.push((Tag(*b"note"), vec![1]));
            s.list.push((Tag(*b"note"), vec![2]));
        }),
    );
    cases.add(
        "too-many-sections",
        "S2.1-too-many-sections",
        "more than 64 sections",
        "65 sections besides END (57 optional ones added to the 8 of the stream).",
        edit(p, |s| {
            (0..57).for_each(|i| s.list.push((Tag(format!("o{i:03}").as_bytes().try_into().unwrap()), vec![])))
        }),
    );
    cases.add(
        "unknown-critical",
        "S2.2-unknown-critical",
        "section 'ZZZZ', which this decoder does not know",
        "A critical section 'ZZZZ' that version 1.0 does not define.",
        edit(p, unknown_critical),
    );
    cases.add(
        "head-trailing-byte",
        "S2.2-head-trailing",
        "section 'HEAD', field `end of section` … 1 unexpected trailing bytes",
        "Version 1.0 with a byte after HEAD's last field.",
        edit(p, |s| s.payload(Tag::HEAD).push(0)),
    );
    cases.add(
        "wrap-trailing-byte",
        "S2.2-wrap-trailing",
        "section 'WRAP', field `end of section` … 1 unexpected trailing bytes",
        "Version 1.0 with a byte after WRAP's last parameter.",
        edit(p, |s| s.payload(WRAPPER).push(0)),
    );
    cases.add(
        "posn-appended-minor-1",
        "S2.2-chunk-sections-not-extensible",
        "section 'POSN': coded data: … unread bytes",
        "Version 1.1 with 12 bytes appended to POSN: its payload ends in a coded chunk, which takes no appended \
         fields (decision 3). (Up to two appended words can stand in for the words the decoder reads past the \
         end, so 3 are appended.)",
        edit(p, |s| {
            s.minor = 1;
            s.payload(POSITIONS).extend([0; 12]);
        }),
    );
    cases.add(
        "scal-appended-minor-1",
        "S2.2-chunk-sections-not-extensible",
        "section 'SCAL': coded data: … unread bytes",
        "Version 1.1 with 12 bytes appended to SCAL (decision 3).",
        edit(p, |s| {
            s.minor = 1;
            s.payload(SCALES).extend([1; 12]);
        }),
    );

    // Field syntax: SPEC.md sections 1 and 3.
    cases.add(
        "varint-overlong",
        "S1-varint-overlong",
        "section 'SCAL', field `table size` … overlong varint",
        "SCAL's first table size written in two bytes, the last 0.",
        edit(p, |s| edit_block(s, SCALES, |b| b.tables[0] = overlong_size(&b.tables[0]))),
    );
    cases.add(
        "varint-33-bits",
        "S1-varint-33-bits",
        "section 'SCAL', field `table size` … varint exceeds 32 bits",
        "SCAL's first table size is a 5-byte varint above 2^32 - 1.",
        edit(p, |s| edit_block(s, SCALES, |b| b.tables[0] = size_bytes(&b.tables[0], &[0xff, 0xff, 0xff, 0xff, 0x1f]))),
    );
    cases.add(
        "varint-6-bytes",
        "S1-varint-6-bytes",
        "section 'SCAL', field `table size` … varint longer than 5 bytes",
        "SCAL's first table size is a 6-byte varint.",
        edit(p, |s| {
            edit_block(s, SCALES, |b| b.tables[0] = size_bytes(&b.tables[0], &[0x80, 0x80, 0x80, 0x80, 0x80, 0x01]))
        }),
    );
    cases.add(
        "head-center-nan",
        "S1-f32-nan",
        "section 'HEAD', field `center x` … NaN is not finite",
        "HEAD's center x is a NaN.",
        edit(p, |s| put(s.payload(Tag::HEAD), head::CENTER, &f32::to_le_bytes(f32::NAN))),
    );
    cases.add(
        "posn-origin-infinite",
        "S1-f32-inf",
        "section 'POSN', field `origin y` … inf is not finite",
        "POSN's origin y is +infinity.",
        edit(p, |s| put(s.payload(POSITIONS), posn::ORIGIN + 4, &f32::to_le_bytes(f32::INFINITY))),
    );
    cases.add(
        "head-truncated",
        "S3-field-past-end",
        "section 'HEAD', field `background` … needs 4 bytes, 2 left",
        "HEAD stops in the middle of the last background value.",
        edit(p, |s| s.payload(Tag::HEAD).truncate(32)),
    );
    cases.add(
        "posn-truncated",
        "S3-field-past-end",
        "section 'POSN', field `depth` … needs 1 bytes, 0 left",
        "POSN stops before its depth.",
        edit(p, |s| s.payload(POSITIONS).truncate(16)),
    );

    // HEAD: SPEC.md section 4.
    for (file, value, error) in [
        ("head-base-2", 2u8, "section 'HEAD', field `base` … unknown base kind 2"),
        ("head-base-255", 255, "section 'HEAD', field `base` … unknown base kind 255"),
    ] {
        let description = format!("HEAD's base is {value} (0 and 1 are the only base kinds).");
        cases.add(file, "S4-base", error, &description, edit(p, |s| s.payload(Tag::HEAD)[head::BASE] = value));
    }
    cases.add(
        "head-count-over-limit",
        "S4-count-limit",
        "section 'HEAD', field `gaussian count` … 16777217 exceeds the limit",
        "HEAD declares 2^24 + 1 Gaussians.",
        edit(p, |s| put(s.payload(Tag::HEAD), head::COUNT, &((1u32 << 24) + 1).to_le_bytes())),
    );
    cases.add(
        "head-degree-4",
        "S4-sh-degree",
        "section 'HEAD', field `sh degree` … 4 exceeds 3",
        "HEAD's SH degree is 4.",
        edit(p, |s| s.payload(Tag::HEAD)[head::DEGREE] = 4),
    );
    for (file, value, error) in [
        ("head-scale-zero", 0.0f32, "section 'HEAD', field `scale` … 0 is not positive"),
        ("head-scale-negative", -2.0, "section 'HEAD', field `scale` … -2 is not positive"),
    ] {
        let description = format!("HEAD's scale is {value}.");
        cases.add(
            file,
            "S4-scale-positive",
            error,
            &description,
            edit(p, |s| put(s.payload(Tag::HEAD), head::SCALE, &f32::to_le_bytes(value))),
        );
    }
    for (file, channel, value, error) in [
        (
            "head-background-above-1",
            1,
            1.000_000_1f32,
            "section 'HEAD', field `background` … 1.0000001 is outside [0, 1]",
        ),
        (
            "head-background-negative",
            2,
            -1e-30,
            "section 'HEAD', field `background` … -0.000000000000000000000000000001 is outside [0, 1]",
        ),
    ] {
        let description = format!("HEAD's background channel {channel} is {value}.");
        let bytes = edit(p, |s| put(s.payload(Tag::HEAD), head::BACKGROUND + 4 * channel, &f32::to_le_bytes(value)));
        cases.add(file, "S4-background-range", error, &description, bytes);
    }

    // The work bound: decision 6 (SPEC.md section 9).
    let alike = alike_gaussians();
    cases.add(
        "count-exceeds-length",
        "S4-count-vs-length",
        "section 'HEAD': gaussian count 510 exceeds half the stream's length of 1019 bytes",
        "510 Gaussians in a stream of 1,019 bytes (the vector count-at-half-length, one byte shorter).",
        padded(&alike, 2 * alike.len() - 1),
    );
    let mut huge = Sections::of(p);
    put(huge.payload(Tag::HEAD), head::COUNT, &(1u32 << 24).to_le_bytes());
    huge.payload(Tag::HEAD)[head::DEGREE] = 3;
    huge.list.push((Tag(*b"fill"), vec![0x55; 3000]));
    cases.add(
        "count-2-24-in-few-kb",
        "S9-count-few-kb",
        "section 'HEAD': gaussian count 16777216 exceeds half the stream's length",
        "A stream of about 4 KB declaring 2^24 Gaussians of degree 3: refused before any section is decoded.",
        huge.seal(),
    );

    // More of SPEC.md sections 2 to 4.
    cases.add(
        "magic-short",
        "S2.3-short-magic",
        "not a pwgs stream",
        "A file of the magic's first 5 bytes.",
        p[..5].to_vec(),
    );
    cases.add(
        "version-truncated",
        "S2.3-version-truncated",
        "stream is truncated: the version at byte 8",
        "The magic and 2 bytes.",
        p[..10].to_vec(),
    );
    let mut bytes = p.clone();
    let at = section_offsets(p)[2];
    bytes[at + 3] = b'M';
    cases.add(
        "crc-covers-tag",
        "S2.1-crc-covers-tag-length",
        "section 'SCAM' at byte 139 is corrupt",
        "SCAL's tag changed to 'SCAM' (still well formed), CRC not updated.",
        bytes,
    );
    let mut bytes = edit(p, |s| s.list.push((Tag(*b"note"), vec![1, 2, 3])));
    let at = section_offsets(&bytes).iter().rev().nth(1).copied().expect("the note section") + 8;
    bytes[at] ^= 0x10;
    cases.add(
        "optional-crc-mismatch",
        "S2.2-optional-crc-checked",
        "section 'note' at byte",
        "An unknown optional section whose payload no longer matches its CRC.",
        bytes,
    );
    let mut bytes = edit(p, |s| s.list.swap(0, 1));
    bytes[MAGIC_AND_VERSION + 20] ^= 1;
    cases.add(
        "order-crc-before-head",
        "S2.3-order-crc-before-head",
        "section 'POSN' at byte 12 is corrupt",
        "POSN comes first, and its CRC fails: the CRC is checked before the first section's tag.",
        bytes,
    );
    let mut bytes = edit(p, |s| {
        let scal = s.payload(SCALES).clone();
        s.insert(3, SCALES, scal);
    });
    let at = section_offsets(&bytes)[3] + 10;
    bytes[at] ^= 1;
    cases.add(
        "order-crc-before-duplicate",
        "S2.3-order-crc-before-duplicate",
        "is corrupt",
        "SCAL appears twice, and the second copy's CRC fails.",
        bytes,
    );
    let mut bytes = edit(p, |s| s.payload(Tag::HEAD)[head::BASE] = 1);
    bytes.push(0);
    cases.add(
        "order-container-first",
        "S2.3-order-container-first",
        "1 bytes follow the 'END ' section",
        "A byte after END, and HEAD's base is 1: container checks come first.",
        bytes,
    );
    cases.add(
        "head-scale-nan",
        "S1-f32-before-constraint",
        "section 'HEAD', field `scale` … NaN is not finite",
        "HEAD's scale is a NaN: reported as not finite.",
        edit(p, |s| put(s.payload(Tag::HEAD), head::SCALE, &f32::NAN.to_le_bytes())),
    );
    cases.add(
        "head-scale-minus-zero",
        "S4-scale-positive",
        "section 'HEAD', field `scale` … -0 is not positive",
        "HEAD's scale is -0.0.",
        edit(p, |s| put(s.payload(Tag::HEAD), head::SCALE, &(-0.0f32).to_le_bytes())),
    );
    cases.add(
        "varint-5-bytes-overlong",
        "S1-varint-order",
        "section 'SCAL', field `table size` … overlong varint",
        "SCAL's first table size is a 5-byte varint whose last byte is 0: overlong, whatever its length.",
        edit(p, |s| edit_block(s, SCALES, |b| b.tables[0] = size_bytes(&b.tables[0], &[0x81, 0x80, 0x80, 0x80, 0x00]))),
    );
    let mut bytes = p.clone();
    let at = *section_offsets(p).last().expect("END") + 4;
    put(&mut bytes, at, &((1u32 << 28) + 1).to_le_bytes());
    cases.add(
        "end-length-over-limit",
        "S2.3-order-length-before-crc",
        "section 'END ' at byte … declares 268435457 bytes, more than the 268435456",
        "END declares 2^28 + 1 bytes, and none follow: the length is refused, not reported as truncated.",
        bytes,
    );
}

//! Invalid coded chunks and frequency tables.

use pwgs_codec::stream::entropy::{MAX_MAGNITUDE, TOTAL};
use pwgs_codec::stream::plain::{COLORS, OPACITIES, POSITIONS, ROTATIONS, SCALES};

use super::{Bases, Cases, edit, edit_block};
use crate::generator::raw::{
    BlockParts, Interval, Sections, block, coded_intervals, flat_frequencies, flat_table, raw_table,
};

/// A SCAL block whose first value is escaped although it lies in its table's range, or
/// escaped with a magnitude of 2^24 or more: what no correct encoder writes.
fn scal_with_first_escaped(b: &Bases, s: &mut Sections, first: i64) {
    let (lo, n) = (-128, 49);
    let frequencies = flat_frequencies(n);
    let mut symbols = Vec::new();
    for (g, values) in b.values.scales.iter().enumerate() {
        for (c, &v) in values.iter().enumerate() {
            if g == 0 && c == 0 {
                symbols.extend(Interval::escaped(&frequencies, first));
            } else {
                symbols.push(Interval::of_table(&frequencies, (v - lo) as usize));
            }
        }
    }
    let table = flat_table(lo, n);
    let mut payload = block(&[1.0 / 32.0], &[table.clone(), table.clone(), table], &[]);
    payload.extend(coded_intervals(&symbols));
    *s.payload(SCALES) = payload;
}

/// Coded chunks, the range decoder and frequency tables (SPEC.md section 5, decisions 1 to 4).
/// A case whose stream has `table` as ROTN's third frequency table.
fn add_rotn_table(
    b: &Bases,
    cases: &mut Cases,
    (file, clause, error): (&str, &'static str, &str),
    table: Vec<u8>,
    what: &str,
) {
    let bytes = edit(&b.plain, |s| edit_block(s, ROTATIONS, |block| block.tables[2] = table));
    cases.add(file, clause, error, &format!("ROTN's third table: {what}."), bytes);
}

pub(super) fn coding(b: &Bases, cases: &mut Cases) {
    let p = &b.plain;
    // Coded chunks and the range decoder: SPEC.md sections 5.1 and 5.2.
    cases.add(
        "chunk-unaligned",
        "S5.1-unaligned",
        "section 'SCAL': coded data: coded data length … is not a multiple of 4 bytes",
        "SCAL's chunk is 2 bytes longer than a whole number of words.",
        edit(p, |s| s.payload(SCALES).extend([0, 0])),
    );
    cases.add(
        "chunk-quantile",
        "S5.2-quantile",
        "section 'SCAL': coded data: coded data is invalid",
        "SCAL's chunk starts with two words 0xFFFFFFFF: the first quantile is 2^16.",
        edit(p, |s| edit_block(s, SCALES, |b| b.chunk = vec![0xff; 8])),
    );
    cases.add(
        "chunk-exhausted",
        "S5.2-overruns",
        "section 'SCAL': coded data: coded data ends before all symbols were decoded",
        "SCAL's tables give the only in-range symbol a frequency of 1 and its chunk is empty: the fourth \
         symbol needs a third word past the end.",
        edit(p, |s| {
            edit_block(s, SCALES, |b| {
                b.tables = vec![raw_table(0, 1, &[1, TOTAL - 1]); 3];
                b.chunk.clear();
            })
        }),
    );
    cases.add(
        "scal-trailing-words",
        "S5.1-unread",
        "section 'SCAL': coded data: … unread bytes after the last symbol",
        "SCAL's chunk has 3 words after its last symbol (decision 3).",
        edit(p, |s| s.payload(SCALES).extend([0; 12])),
    );
    cases.add(
        "posn-trailing-words",
        "S5.1-unread",
        "section 'POSN': coded data: … unread bytes after the last symbol",
        "POSN's octree chunk has 3 words after its last symbol (decision 3; up to 2 of them are read in place \
         of the words past the end a correct chunk needs).",
        edit(p, |s| s.payload(POSITIONS).extend([0x11; 12])),
    );
    cases.add(
        "empty-posn-chunk",
        "S5.1-empty-when-n0",
        "section 'POSN': coded data: 4 unread bytes",
        "N = 0 with a 4-byte POSN chunk (decision 4: every chunk must then be empty).",
        edit(&b.empty, |s| s.payload(POSITIONS).extend([0; 4])),
    );
    cases.add(
        "empty-bad-table",
        "S5.3-table-size-zero",
        "section 'SCAL', field `table lo/size` … 0 symbols",
        "N = 0 with a SCAL table of 0 symbols: tables are still checked (decision 4).",
        edit(&b.empty, |s| edit_block(s, SCALES, |b| b.tables[1] = raw_table(0, 0, &[TOTAL]))),
    );
    cases.add(
        "empty-colr-chunk",
        "S5.1-empty-when-n0",
        "section 'COLR': coded data: 8 unread bytes",
        "N = 0 with an 8-byte COLR chunk (decision 4).",
        edit(&b.empty, |s| s.payload(COLORS).extend([1; 8])),
    );

    // Frequency tables: SPEC.md section 5.3 and decisions 1 and 2.
    let n4097 = {
        let mut f = vec![15; 4097];
        f.push(TOTAL - 15 * 4097);
        f
    };
    let i32_max_lo = i32::MAX - 4096 + 1;
    let table_cases: [(&str, &'static str, Vec<u8>, &str, String); 8] = [
        (
            "table-zero-symbols",
            "S5.3-table-size-zero",
            raw_table(0, 0, &[TOTAL]),
            "section 'ROTN', field `table lo/size` … 0 symbols, expected 1..=4096",
            "n = 0".into(),
        ),
        (
            "table-4097-symbols",
            "S5.3-table-size-large",
            raw_table(0, 4097, &n4097),
            "section 'ROTN', field `table lo/size` … 4097 symbols, expected 1..=4096",
            "n = 4097".into(),
        ),
        (
            "table-zero-frequency",
            "S5.3-table-freq-zero",
            raw_table(-100, 1, &[0, TOTAL]),
            "section 'ROTN', field `table frequencies` … a frequency is 0",
            "the in-range symbol has frequency 0".into(),
        ),
        (
            "table-sum",
            "S5.3-table-freq-sum",
            raw_table(-100, 1, &[100, 200]),
            "section 'ROTN', field `table frequencies` … frequencies sum to 300",
            "frequencies sum to 300".into(),
        ),
        (
            "table-sum-overflow",
            "S5.3-table-freq-sum",
            raw_table(-100, 1, &[u32::MAX, 1]),
            "section 'ROTN', field `table frequencies` … frequencies sum to 4294967295",
            "frequencies 2^32 - 1 and 1, whose sum overflows 32 bits".into(),
        ),
        (
            "table-lo-below",
            "S5.3-table-lo-low",
            raw_table(-MAX_MAGNITUDE, 1, &[TOTAL - 1, 1]),
            "section 'ROTN', field `table lo/size` … range -16777216..-16777215 reaches beyond",
            "lo = -2^24 (decision 1: lo >= -(2^24 - 1))".into(),
        ),
        (
            "table-end-above",
            "S5.3-table-lo-high",
            raw_table(MAX_MAGNITUDE - 1, 2, &[TOTAL - 2, 1, 1]),
            "section 'ROTN', field `table lo/size` … range 16777215..16777217 reaches beyond",
            "lo = 2^24 - 1, n = 2: lo + n = 2^24 + 1 (decision 1: lo + n <= 2^24)".into(),
        ),
        (
            "table-lo-near-i32-max",
            "S5.3-table-lo-high",
            raw_table(i32_max_lo, 4096, &flat_frequencies(4096)),
            "section 'ROTN', field `table lo/size` … range 2147479552..2147483648 reaches beyond",
            "lo = i32::MAX - 4096 + 1, n = 4096: lo + n overflows 32 bits".into(),
        ),
    ];
    for (file, clause, table, error, what) in table_cases {
        add_rotn_table(b, cases, (file, clause, error), table, &what);
    }
    cases.add(
        "escape-in-range",
        "S5.3-escape-in-range",
        "section 'SCAL': coded data: escaped value -100 lies inside the table's range",
        "SCAL's first value, -100, is coded as the escape although its table covers -128..-80 (decision 2).",
        edit(p, |s| scal_with_first_escaped(b, s, -100)),
    );
    cases.add(
        "escape-2-24",
        "S5.3-escape-magnitude",
        "section 'SCAL': coded data: escaped value 16777216 is outside",
        "SCAL's first value is escaped as 2^24.",
        edit(p, |s| scal_with_first_escaped(b, s, 1 << 24)),
    );
    cases.add(
        "escape-i32-min",
        "S5.3-escape-magnitude",
        "section 'SCAL': coded data: escaped value -2147483648 is outside",
        "SCAL's first value is escaped as -2^31 (zig-zag form 2^32 - 1).",
        edit(p, |s| scal_with_first_escaped(b, s, i64::from(i32::MIN))),
    );

    // More of SPEC.md section 5.
    cases.add(
        "empty-scal-unaligned",
        "S5.1-unaligned",
        "section 'SCAL': coded data: coded data length 3 is not a multiple of 4 bytes",
        "N = 0 with a 3-byte SCAL chunk.",
        edit(&b.empty, |s| s.payload(SCALES).extend([0; 3])),
    );
    cases.add(
        "escape-minus-2-24",
        "S5.3-escape-magnitude",
        "section 'SCAL': coded data: escaped value -16777216 is outside",
        "SCAL's first value is escaped as -2^24 (zig-zag form 2^25 - 1).",
        edit(p, |s| scal_with_first_escaped(b, s, -(1 << 24))),
    );
    let more_tables: [(&str, &'static str, Vec<u8>, &str, &str); 5] = [
        (
            "table-size-u32-max",
            "S5.3-table-size-large",
            raw_table(0, u32::MAX, &[]),
            "section 'ROTN', field `table lo/size` … 4294967295 symbols, expected 1..=4096",
            "n = 2^32 - 1 (refused before anything is allocated)",
        ),
        (
            "table-lo-i32-min",
            "S5.3-table-lo-low",
            raw_table(i32::MIN, 1, &[TOTAL - 1, 1]),
            "section 'ROTN', field `table lo/size` … reaches beyond",
            "lo = i32::MIN",
        ),
        (
            "table-lo-i32-max",
            "S5.3-table-lo-high",
            raw_table(i32::MAX, 1, &[TOTAL - 1, 1]),
            "section 'ROTN', field `table lo/size` … reaches beyond",
            "lo = i32::MAX, n = 1 (lo + n wraps in 32 bits)",
        ),
        (
            "table-zero-frequency-and-sum",
            "S5.3-table-order-zero-before-sum",
            raw_table(-100, 1, &[0, 100]),
            "section 'ROTN', field `table frequencies` … a frequency is 0",
            "frequencies 0 and 100: the zero frequency is reported, not the sum",
        ),
        (
            "table-zero-then-overlong-frequency",
            "S5.3-table-order-read-before-check",
            [raw_table(-100, 2, &[]), vec![0x00, 0x81, 0x00, 0xff, 0xff, 0x03]].concat(),
            "section 'ROTN', field `table frequency` … overlong varint",
            "a frequency of 0, then one written as an overlong varint: all frequencies are read before any \
             is checked",
        ),
    ];
    for (file, clause, table, error, what) in more_tables {
        add_rotn_table(b, cases, (file, clause, error), table, what);
    }
    cases.add(
        "table-frequencies-truncated",
        "S5.3-table-freq-truncated",
        "section 'OPAC', field `table frequency` … needs 1 bytes, 0 left",
        "OPAC stops inside its table's frequencies.",
        edit(p, |s| {
            let parts = BlockParts::split(s.payload(OPACITIES), 1, 1);
            let len = parts.steps.len() + parts.tables[0].len() - 1;
            s.payload(OPACITIES).truncate(len);
        }),
    );
    cases.add(
        "table-size-before-frequencies",
        "S5.3-table-order-size-before-freq",
        "section 'OPAC', field `table lo/size` … 5000 symbols, expected 1..=4096",
        "OPAC's table declares 5000 symbols and the payload ends after the size: the size is checked before \
         any frequency is read.",
        edit(p, |s| {
            let mut payload = s.payload(OPACITIES)[..4].to_vec();
            payload.extend(raw_table(0, 5000, &[]));
            *s.payload(OPACITIES) = payload;
        }),
    );
}

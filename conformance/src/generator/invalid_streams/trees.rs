//! Invalid adaptive tree coding (SPEC.md section 6.7): `ADPT` payloads that are not one byte,
//! name reserved or absent blocks; tree models out of their bounds; a chunk decoding to a
//! symbol past its tree's values.

use pwgs_bitstream::FieldWriter;
use pwgs_codec::stream::entropy::SymbolEncoder;
use pwgs_codec::stream::plain::{PlainGaussians, SCALES};
use pwgs_codec::stream::trees::{ADAPTIVE, TreeModel, Trees};

use super::{Cases, edit};
use crate::generator::content::{classed_gaussians, ordinary_gaussians, smooth};
use crate::generator::raw::Sections;
use crate::generator::valid_vectors::{adaptive, encode};

/// A SCAL payload of step 1/32 with tree models written field by field (`(lo, size, trees,
/// thresholds)`), and `chunk` after them.
fn scales(models: &[(i32, u32, u8, &[i32])], chunk: &[u8]) -> Vec<u8> {
    let mut w = FieldWriter::new();
    w.f32(1.0 / 32.0);
    for &(lo, size, trees, thresholds) in models {
        w.signed_varint(lo);
        w.varint(size);
        w.u8(trees);
        thresholds.iter().for_each(|&t| w.signed_varint(t));
    }
    w.extend(chunk);
    w.into_bytes()
}

pub(super) fn trees(cases: &mut Cases) {
    // 300 Gaussians of degree 1 following their positions: every block coded with trees.
    let p = &adaptive(smooth(ordinary_gaussians(96, 300, 1), 97), 0b1_1111).expect("trees in every block");
    let mask = |payload: Vec<u8>| move |s: &mut Sections| *s.payload(ADAPTIVE) = payload;
    cases.add(
        "adpt-empty",
        "S6.7-payload",
        "section 'ADPT': holds 0 bytes; the section holds one",
        "ADPT's payload is empty.",
        edit(p, mask(vec![])),
    );
    cases.add(
        "adpt-two-bytes",
        "S6.7-payload",
        "section 'ADPT': holds 2 bytes; the section holds one",
        "ADPT's payload is two bytes.",
        edit(p, mask(vec![0x1f, 0])),
    );
    cases.add(
        "adpt-reserved-bit",
        "S6.7-payload",
        "section 'ADPT': blocks 0x3f: bits above 4 are reserved",
        "ADPT names every block and sets bit 5.",
        edit(p, mask(vec![0x3f])),
    );
    let degree_0 = &adaptive(smooth(ordinary_gaussians(98, 300, 0), 99), 0b0_1111).expect("trees in every block");
    cases.add(
        "adpt-names-absent-shrs",
        "S6.7-payload",
        "section 'ADPT': blocks 0x1f: names 'SHRS', which the stream does not hold",
        "A stream of SH degree 0 (no SHRS) whose ADPT sets bit 4.",
        edit(degree_0, mask(vec![0x1f])),
    );
    let scal = |payload: Vec<u8>| move |s: &mut Sections| *s.payload(SCALES) = payload;
    let one = |lo, size| (lo, size, 1, &[][..]);
    cases.add(
        "tree-size-4097",
        "S6.7-model",
        "section 'SCAL', field `tree lo/size` … 4097 symbols, expected 1..=4096",
        "SCAL's first tree model spans 4097 values.",
        edit(p, scal(scales(&[one(0, 4097)], &[]))),
    );
    cases.add(
        "tree-lo-past-2-24",
        "S6.7-model",
        "section 'SCAL', field `tree lo/size` … range 16777215..16777217 reaches beyond +/-(2^24 - 1)",
        "SCAL's first tree model spans 2^24 - 1 and 2^24.",
        edit(p, scal(scales(&[one((1 << 24) - 1, 2)], &[]))),
    );
    cases.add(
        "tree-count-0",
        "S6.7-model",
        "section 'SCAL', field `trees` … 0 is outside 1..=16",
        "SCAL's first tree model has 0 trees.",
        edit(p, scal(scales(&[(0, 8, 0, &[])], &[]))),
    );
    cases.add(
        "tree-count-17",
        "S6.7-model",
        "section 'SCAL', field `trees` … 17 is outside 1..=16",
        "SCAL's first tree model has 17 trees.",
        edit(p, scal(scales(&[(0, 8, 17, &[])], &[]))),
    );
    cases.add(
        "tree-thresholds-equal",
        "S6.7-model",
        "section 'SCAL', field `threshold` … 4 is not above the one before (4)",
        "SCAL's first tree model has 3 trees and the thresholds 4, 4.",
        edit(p, scal(scales(&[(0, 8, 3, &[4, 4])], &[]))),
    );
    // 9 classes x 3 channels of 16 trees of 4096 values: 27 x 2^16 nodes.
    let classed = PlainGaussians { adaptive: true, ..classed_gaussians(71, 300, 1, (9, 4, 8)) };
    let classed = &encode(&classed, None);
    let wide: Vec<i32> = (0..15).collect();
    let widest = vec![(0, 4096, 16, &wide[..]); 27];
    cases.add(
        "tree-nodes-past-2-20",
        "S6.7-nodes",
        "section 'SCAL', field `trees` … the block's trees hold 1769472 nodes, more than 2^20",
        "A stream of 9 importance classes whose ADPT names SCAL, and SCAL's 27 tree models each of 16 trees \
         of 4096 values (2^16 nodes each).",
        edit(classed, |s| {
            *s.payload(ADAPTIVE) = vec![1];
            scal(scales(&widest, &[]))(s);
        }),
    );
    // Slot 0 (x) holds 3 values but the chunk was coded with 4, its first value the fourth.
    let mut coder = SymbolEncoder::new();
    let full = TreeModel { lo: 0, size: 4, thresholds: vec![] };
    let single = TreeModel { lo: 0, size: 1, thresholds: vec![] };
    let mut trees = Trees::new(vec![full, single.clone(), single]);
    trees.encode(&mut coder, 0, 3);
    cases.add(
        "tree-symbol-outside",
        "S6.7-symbol",
        "section 'SCAL': coded data: tree symbol 3 is outside the tree's 3 values",
        "SCAL's x slot spans 3 values (2 bits a value) and its chunk's first value decodes to the fourth.",
        edit(p, scal(scales(&[one(0, 3), one(0, 1), one(0, 1)], &coder.finish()))),
    );
    cases.add(
        "order-adpt-before-blocks",
        "S6.4-f'-before-g",
        "section 'ADPT': blocks 0x3f: bits above 4 are reserved",
        "ADPT sets a reserved bit and SCAL's step is 0.",
        edit(p, |s| {
            *s.payload(ADAPTIVE) = vec![0x3f];
            s.payload(SCALES)[..4].copy_from_slice(&0f32.to_le_bytes());
        }),
    );
}

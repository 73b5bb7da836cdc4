//! Invalid colour differences (SPEC.md section 6.6): a `CDIF` with a payload, and coded
//! differences whose colour reaches 2^24.

use pwgs_codec::stream::colour_differences::COLOUR_DIFFERENCES;
use pwgs_codec::stream::plain::{COLORS, PlainGaussians};

use super::{Cases, edit};
use crate::generator::content::ordinary_gaussians;
use crate::generator::raw::{block, flat_table};
use crate::generator::valid_vectors::encode;

pub(super) fn differences(cases: &mut Cases) {
    // 6 Gaussians of degree 0, colours as differences.
    let content = PlainGaussians { colour_differences: true, ..ordinary_gaussians(95, 6, 0) };
    let p = &encode(&content, None);
    cases.add(
        "cdif-not-empty",
        "S6.6-empty",
        "section 'CDIF': holds 1 bytes; the section must be empty",
        "CDIF holds one byte.",
        edit(p, |s| s.payload(COLOUR_DIFFERENCES).push(0)),
    );
    // COLR rewritten with hand-made triples: Gaussian 2's red difference plus its green reaches
    // 2^24 (the limit is checked on the sum, not on the coded values, which are in range).
    let mut triples: Vec<Vec<i32>> = (0..6).map(|_| vec![0, 0, 0]).collect();
    triples[2] = vec![(1 << 24) - 1, 1, 0];
    let colours = block(&[content.dc_step], &[flat_table(0, 1), flat_table(0, 1), flat_table(0, 1)], &triples);
    cases.add(
        "cdif-colour-reaches-2-24",
        "S6.6-limit",
        "section 'COLR': colour difference 16777215 plus green 1 (triple 2) reaches 2^24",
        "COLR's third triple is (2^24 - 1, 1, 0): red = 2^24.",
        edit(p, |s| *s.payload(COLORS) = colours),
    );
    let mut blue = triples.clone();
    blue[2] = vec![0, -1, -((1 << 24) - 1)];
    let colours = block(&[content.dc_step], &[flat_table(0, 1), flat_table(0, 1), flat_table(0, 1)], &blue);
    cases.add(
        "cdif-blue-reaches-2-24",
        "S6.6-limit",
        "section 'COLR': colour difference -16777215 plus green -1 (triple 2) reaches 2^24",
        "COLR's third triple is (0, -1, -(2^24 - 1)): blue = -2^24.",
        edit(p, |s| *s.payload(COLORS) = colours),
    );
}

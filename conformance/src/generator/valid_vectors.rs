//! The synthetic valid vectors: each a stream exercising stated SPEC.md clauses, written with
//! the decoder library's writer or as a hand-made section list.

use anyhow::{Result, ensure};
use pwgs_bitstream::{FieldWriter, Tag, write_container};
use pwgs_codec::stream;
use pwgs_codec::stream::entropy::{FrequencyTable, MAX_MAGNITUDE};
use pwgs_codec::stream::plain::{self, PlainGaussians, PositionGrid};
use pwgs_codec::stream::trees::ADAPTIVE;
use pwgs_codec::stream::wrap::{QuantizedSynthesis, WRAPPER};
use pwgs_codec::wrapper::synthesis::WrapperConfig;

use super::Vector;
use super::content::{self, BlockValues, Draws, Ranges, Steps, classed_gaussians, header, ordinary_gaussians, smooth};
use super::raw::{Sections, block, flat_table};

/// Largest quantized magnitude a stream may hold: 2^24 - 1.
const LARGEST: i32 = MAX_MAGNITUDE - 1;

/// The largest step SPEC.md section 6.2 allows: `step * 2^24` is the largest finite binary32.
pub fn largest_step() -> f32 {
    f32::MAX / MAX_MAGNITUDE as f32
}

/// A stream of `content` with its header and, optionally, a wrapper.
pub fn encode(content: &PlainGaussians, wrapper: Option<&QuantizedSynthesis>) -> Vec<u8> {
    stream::encode(&header(content), content, wrapper).expect("the generated content fits the octree")
}

/// The content the `sh1` vector holds (and others reuse).
fn sh1_content() -> PlainGaussians {
    ordinary_gaussians(11, 40, 1)
}

/// 2 x 255 Gaussians in two cells of a depth-1 grid, all alike: their content codes to far
/// fewer bytes than their count, so the writer pads the stream to one byte per Gaussian.
pub fn alike_gaussians() -> PlainGaussians {
    let mut content = ordinary_gaussians(5, 510, 0);
    content.grid = content::unit_cube(1);
    for i in 0..content.len() {
        content.positions[i] = if i < 255 { [0, 0, 0] } else { [1, 1, 0] };
        content.log_scales[i] = [-100; 3];
        content.rotations[i] = content.rotations[0];
        content.opacity_logits[i] = 40;
        content.sh_dc[i] = [60, -30, 10];
    }
    content
}

pub fn vectors() -> Result<Vec<Vector>> {
    let sh1 = encode(&sh1_content(), None);
    let sh1_hash = stream::decode(&sh1)?.scene.attribute_hash();
    let narrow = narrow_tables(&sh1_content());
    ensure!(stream::decode(&narrow)?.scene.attribute_hash() == sh1_hash, "narrow-tables decodes unlike sh1");
    let unknown = unknown_optional_sections(&sh1);
    ensure!(stream::decode(&unknown)?.scene.attribute_hash() == sh1_hash, "optional sections changed sh1");
    let sh2 = encode(&ordinary_gaussians(12, 40, 2), None);
    let reordered = reordered(&sh2);
    ensure!(stream::decode(&reordered)?.scene == stream::decode(&sh2)?.scene, "reordering changed sh2");
    let (extra_word_tag, extra_word) = extra_zero_word(&sh1)?;
    ensure!(stream::decode(&extra_word)?.scene.attribute_hash() == sh1_hash, "the extra word changed sh1");
    let alike = alike_gaussians();
    let alike_stream = encode(&alike, None);
    ensure!(alike_stream.len() == 2 * alike.len(), "the writer padded to {} bytes", alike_stream.len());

    let mut vectors = vec![
        Vector {
            name: "single-sh0",
            description: "One Gaussian of SH degree 0: no SHRS section, a one-point octree.".into(),
            clauses: vec!["S6.1-octree", "S6.2-reconstruction", "S7.2-hash"],
            stream: encode(&ordinary_gaussians(1, 1, 0), None),
            cameras: &["front"],
        },
        Vector {
            name: "sh1",
            description: "40 Gaussians of SH degree 1 on a 256^3 grid: SHRS with one band step.".into(),
            clauses: vec!["S6.2-sh-bands", "S6.3-meaning", "S7.1-gaussian-order", "S7.2-hash"],
            stream: sh1,
            cameras: &["front", "side"],
        },
        Vector {
            name: "sh2",
            description: "40 Gaussians of SH degree 2: SHRS with two band steps, 24 channels.".into(),
            clauses: vec!["S6.2-sh-bands", "S7.2-hash"],
            stream: sh2,
            cameras: &["front", "side"],
        },
        Vector {
            name: "chunk-extra-zero-word",
            description: format!(
                "The sh1 stream with a zero word appended to the chunk of {extra_word_tag}, the first whose \
                 decoding reads a word past its end: the word is read in place of that overrun, so the chunk \
                 is still read exactly and decodes to sh1's attributes (a correct chunk is not the only one \
                 accepted)."
            ),
            clauses: vec!["S5.1-one-zero-word"],
            stream: extra_word,
            cameras: &[],
        },
        Vector {
            name: "sections-reordered",
            description: "The sh2 stream with its sections after HEAD in reverse order (SHRS first, POSN last): \
                          decoders must not depend on the order. Decodes to sh2's attributes."
                .into(),
            clauses: vec!["S6-section-order"],
            stream: reordered,
            cameras: &["front"],
        },
        Vector {
            name: "sh3",
            description: "40 Gaussians of SH degree 3: SHRS with three band steps, 45 channels.".into(),
            clauses: vec!["S6.2-sh-bands", "S7.2-hash"],
            stream: encode(&ordinary_gaussians(13, 40, 3), None),
            cameras: &["front", "side"],
        },
        Vector {
            name: "empty",
            description: "N = 0 with SH degree 2: every section present with its steps and tables, every coded \
                          chunk empty (decision 4); renders show the background."
                .into(),
            clauses: vec!["S5.1-n0-valid"],
            stream: encode(&ordinary_gaussians(2, 0, 2), None),
            cameras: &["front"],
        },
        Vector {
            name: "escapes",
            description: "64 Gaussians of degree 3 quantized with fine steps (2^-21 to 2^-24), so values spread \
                          over millions: in every block one channel escapes the values outside its table's \
                          4096-wide window, among them the magnitude 2^24 - 1."
                .into(),
            clauses: vec!["S5.3-escape-edges"],
            stream: encode(&escapes(), None),
            cameras: &["front", "side"],
        },
        Vector {
            name: "narrow-tables",
            description: "The sh1 Gaussians with hand-made tables: one-symbol tables (so most values, the \
                          rotation's largest-component index included, are escaped) and tables at both bounds \
                          of decision 1 (lo = -(2^24 - 1), lo + n = 2^24). Decodes to sh1's attributes."
                .into(),
            clauses: vec!["S5.3-escape-edges", "S5.3-table-lo-low", "S5.3-table-lo-high"],
            stream: narrow,
            cameras: &["front"],
        },
        Vector {
            name: "cell-255",
            description: "255 Gaussians of degree 2 with varied attributes in one grid cell (the most one cell may \
                          hold), with 20 others around them."
                .into(),
            clauses: vec!["S6.1-cell-255", "S7.1-gaussian-order"],
            stream: encode(&full_cell(), None),
            cameras: &["front"],
        },
        Vector {
            name: "steps-smallest",
            description: "Every step the smallest positive binary32 (2^-149, subnormal), values up to 2^24 - 1 \
                          in magnitude (in the first channel of every block): reconstructions are subnormal and \
                          must not be flushed to zero."
                .into(),
            clauses: vec!["S1-arithmetic", "S6.2-step-positive"],
            stream: encode(&smallest_steps(), None),
            cameras: &["front"],
        },
        Vector {
            name: "steps-largest",
            description: "Every step the largest allowed ((2 - 2^-23) * 2^103, so step * 2^24 is the largest \
                          finite binary32), values 0, +/-1 and (in the first channel of every block) +/-(2^24 - \
                          1), on a depth-24 grid reaching 1.99 * 2^127: attributes at the limits of binary32 \
                          (rotations overflow to m = 0). Not rendered."
                .into(),
            clauses: vec!["S1-arithmetic", "S6.2-step-too-large", "S6.1-extent", "S6.1-depth-edges"],
            stream: encode(&largest_steps(), None),
            cameras: &[],
        },
        Vector {
            name: "depth-1",
            description: "An octree of depth 1 (a 2x2x2 grid), 7 cells of 3 Gaussians, SH degree 0.".into(),
            clauses: vec!["S6.1-depth-edges", "S6.1-octree"],
            stream: encode(&depth_one(), None),
            cameras: &["front"],
        },
        Vector {
            name: "depth-24",
            description: "An octree of depth 24 over the unit cube, points at both corners of the grid.".into(),
            clauses: vec!["S6.1-depth-edges", "S6.1-octree"],
            stream: encode(&depth_24(), None),
            cameras: &["front"],
        },
        Vector {
            name: "count-at-half-length",
            description: "510 Gaussians in a stream of exactly 1,020 bytes (the writer pads their content with \
                          an optional 'pad ' section): the bound 2N <= L of SPEC section 4 holds with equality."
                .into(),
            clauses: vec!["S4-count-vs-length", "S4-encoder-pad"],
            stream: alike_stream,
            cameras: &["front"],
        },
        Vector {
            name: "unknown-optional-sections",
            description: "The sh1 stream with 57 optional sections a decoder does not know, one after HEAD and \
                          the others last, 64 sections in all (the limit): skipped, the attributes are sh1's."
                .into(),
            clauses: vec!["S2.2-unknown-optional", "S2.1-too-many-sections"],
            stream: unknown,
            cameras: &["front"],
        },
        Vector {
            name: "minor-version-appended",
            description: "Version 1.1: HEAD and WRAP carry bytes after the fields of 1.0, which a 1.0 decoder \
                          skips (decision 3: only sections without a coded chunk take appended fields), and an \
                          optional section follows."
                .into(),
            clauses: vec!["S2.2-minor-appended", "S2.2-minor-any"],
            stream: newer_minor(),
            cameras: &["front"],
        },
        Vector {
            name: "colour-differences",
            description: "40 Gaussians of degree 2 with CDIF: every colour triple of COLR and SHRS coded as \
                          (r - g, g, b - g)."
                .into(),
            clauses: vec!["S6.6-differences"],
            stream: encode(&PlainGaussians { colour_differences: true, ..ordinary_gaussians(14, 40, 2) }, None),
            cameras: &["front", "side"],
        },
        Vector {
            name: "colour-differences-at-limits",
            description: "CDIF with differences at the values' limits: Gaussian 0's r - g is 2^24 - 1 (r = 2^23, \
                          g = -(2^23 - 1)), Gaussian 1's b - g is -(2^24 - 1) (b = -(2^24 - 1), g = 0) and its \
                          r is 2^24 - 1. Not rendered."
                .into(),
            clauses: vec!["S6.6-differences", "S6.6-limit"],
            stream: encode(&colours_at_limits(), None),
            cameras: &[],
        },
        Vector {
            name: "importance-classes",
            description: "300 Gaussians of degree 1 in 9 importance classes (IMPC): factors sqrt(2)^k, POSN on a \
                          256^3 grid refined by 4 levels, class k dropping floor(k / 2) of them; every attribute \
                          block with 9 x C tables, class-major."
                .into(),
            clauses: vec!["S6.5-classes", "S6.5-positions", "S6.5-attributes"],
            stream: encode(&classed_gaussians(71, 300, 1, (9, 4, 8)), None),
            cameras: &["front", "side"],
        },
        Vector {
            name: "importance-classes-deepest",
            description: "40 Gaussians of degree 0 in 3 classes on a 22-level POSN grid refined by 2 levels: \
                          depth + refine = 24, the most; class 2 drops 1 level."
                .into(),
            clauses: vec!["S6.5-classes", "S6.5-positions", "S6.5-refine-edge"],
            stream: encode(&classed_gaussians(72, 40, 0, (3, 2, 22)), None),
            cameras: &["front"],
        },
        Vector {
            name: "adaptive-trees",
            description: "1500 Gaussians of degree 1 in 3 importance classes, values following their positions, \
                          with CDIF and ADPT naming every block: 5 x 3 x C tree models (up to 8 trees each, \
                          chosen by the previous value of the class and channel), ROTN's index slots of one \
                          value taking no bits."
                .into(),
            clauses: vec!["S6.7-trees", "S6.7-one-value"],
            stream: adaptive(
                PlainGaussians { colour_differences: true, ..smooth(classed_gaussians(73, 1500, 1, (3, 2, 8)), 74) },
                0b1_1111,
            )?,
            cameras: &["front", "side"],
        },
        Vector {
            name: "adaptive-some-blocks",
            description: "300 Gaussians of degree 2 with ADPT naming SCAL, OPAC and COLR (bits 0, 2, 3: 0x0d), \
                          coded with trees; ROTN and SHRS keep their tables."
                .into(),
            clauses: vec!["S6.7-trees", "S6.7-blocks"],
            stream: some_blocks(ordinary_gaussians(75, 300, 2))?,
            cameras: &["front"],
        },
    ];
    vectors.extend(wrapped());
    Ok(vectors)
}

/// The stream of `content` with adaptive trees where they code smaller, which must be the
/// blocks `mask` names (ADPT's payload, SPEC.md section 6.7).
pub fn adaptive(content: PlainGaussians, mask: u8) -> Result<Vec<u8>> {
    let stream = encode(&PlainGaussians { adaptive: true, ..content }, None);
    let payload = Sections::of(&stream).payload(ADAPTIVE).clone();
    ensure!(payload == [mask], "ADPT holds {payload:?}, expected [{mask:#04x}]");
    Ok(stream)
}

/// The stream of `content` with trees in `SCAL`, `OPAC` and `COLR` only: the writer's stream
/// with trees in every block, `ROTN` and `SHRS` taken from its stream without trees.
fn some_blocks(content: PlainGaussians) -> Result<Vec<u8>> {
    let trees = adaptive(content.clone(), 0b1_1111)?;
    let tables = Sections::of(&encode(&content, None));
    let mut mixed = Sections::of(&trees);
    for tag in [plain::ROTATIONS, plain::SH_REST] {
        *mixed.payload(tag) = tables.list[tables.index(tag)].1.clone();
    }
    *mixed.payload(ADAPTIVE) = vec![0b0_1101];
    let mixed = mixed.seal();
    ensure!(stream::decode(&mixed)?.scene.attribute_hash() == stream::decode(&trees)?.scene.attribute_hash());
    Ok(mixed)
}

/// The wrapper vectors: every input combination, widths 1 and 64.
fn wrapped() -> Vec<Vector> {
    let cases: [(&'static str, usize, bool, bool, u64); 5] = [
        ("wrap-none-w64", 64, false, false, 7),
        ("wrap-noise-w1", 1, true, false, u64::MAX),
        ("wrap-plucker-w64", 64, false, true, 0),
        ("wrap-both-w1", 1, true, true, 0x0123_4567_89AB_CDEF),
        ("wrap-both-w64", 64, true, true, 2026),
    ];
    cases
        .into_iter()
        .enumerate()
        .map(|(i, (name, width, noise, plucker, seed))| {
            let config = WrapperConfig { width, noise, plucker, seed };
            let content = ordinary_gaussians(40 + i as u64, 60, 1);
            Vector {
                name,
                description: format!(
                    "60 Gaussians of degree 1 with a perceptual wrapper of width {width}, noise input {}, Plücker \
                     input {}, seed {seed}; weights step 2^-7, biases 2^-9.",
                    if noise { "on" } else { "off" },
                    if plucker { "on" } else { "off" },
                ),
                clauses: [noise.then_some("S11.1-noise"), plucker.then_some("S11.2-plucker")]
                    .into_iter()
                    .flatten()
                    .chain(["S11.3-network", "S11.4-wrap"])
                    .collect(),
                stream: encode(&content, Some(&content::synthesis(config, 100 + i as u64))),
                cameras: &["front", "side"],
            }
        })
        .collect()
}

/// Moves a value into a 64-wide cluster above `center`.
fn cluster(v: &mut i32, center: i32) {
    *v = center + v.rem_euclid(64);
}

/// Fine steps, so that values spread over millions: in every block the first channel (the first
/// coded component for ROTN) holds values spread far beyond a table's 4096-wide window, half of
/// them, and the magnitude 2^24 - 1; the other channels stay in narrow clusters (small tables).
fn escapes() -> PlainGaussians {
    let mut draws = Draws::new(3);
    let positions = (0..64).map(|_| draws.point(8)).collect();
    let steps = Steps {
        scale: 2f32.powi(-22),
        rotation: 2f32.powi(-24),
        opacity: 2f32.powi(-21),
        dc: 2f32.powi(-22),
        bands: vec![2f32.powi(-23), 2f32.powi(-24), 2f32.powi(-24)],
    };
    let ranges = Ranges {
        log_scale: [-LARGEST, -(1 << 23)],
        rotation: [-(1 << 23), 1 << 23],
        opacity: [-(1 << 22), LARGEST],
        dc: [-(1 << 23), 1 << 23],
        sh_rest: [-(1 << 22), 1 << 22],
    };
    let mut c = content::gaussians(&mut draws, content::unit_cube(8), positions, 3, steps, &ranges);
    let rest = c.sh_rest.len() / c.len();
    for i in 0..c.len() {
        // Channel 0 of every block is clustered for even i only; the other channels always.
        let from = usize::from(i % 2 == 1);
        c.log_scales[i][from..].iter_mut().for_each(|v| cluster(v, -3 << 22));
        c.rotations[i].rest[from..].iter_mut().for_each(|v| cluster(v, 1000));
        c.opacity_logits[i..i + 1 - from].iter_mut().for_each(|v| cluster(v, 1 << 22));
        c.sh_dc[i][from..].iter_mut().for_each(|v| cluster(v, -2000));
        c.sh_rest[i * rest + from..(i + 1) * rest].iter_mut().for_each(|v| cluster(v, 300));
    }
    // Gaussian 1 carries the largest magnitude in the spread channel of every block.
    c.log_scales[1][0] = -LARGEST;
    c.rotations[1].rest[0] = LARGEST;
    c.opacity_logits[1] = LARGEST;
    c.sh_dc[1][0] = -LARGEST;
    c.sh_rest[rest] = LARGEST;
    c
}

/// Colour differences reaching the values' limit (the `colour-differences-at-limits` vector).
fn colours_at_limits() -> PlainGaussians {
    let mut c = PlainGaussians { colour_differences: true, ..ordinary_gaussians(15, 20, 0) };
    c.sh_dc[0] = [1 << 23, -((1 << 23) - 1), 0];
    c.sh_dc[1] = [LARGEST, 0, -LARGEST];
    c
}

/// `content`'s stream with hand-made tables (see the `narrow-tables` vector).
fn narrow_tables(content: &PlainGaussians) -> Vec<u8> {
    let one = |lo| flat_table(lo, 1);
    let v = BlockValues::of(content);
    let mut sections = Sections::of(&encode(content, None));
    *sections.payload(plain::SCALES) =
        block(&[content.scale_step], &[one(-LARGEST), flat_table(MAX_MAGNITUDE - 4096, 4096), one(0)], &v.scales);
    *sections.payload(plain::ROTATIONS) = block(
        &[content.rotation_step],
        &[one(0), flat_table(-LARGEST, 4096), one(LARGEST), flat_table(-2, 5)],
        &v.rotations,
    );
    *sections.payload(plain::OPACITIES) = block(&[content.opacity_step], &[flat_table(-3, 2)], &v.opacities);
    *sections.payload(plain::COLORS) = block(&[content.dc_step], &[one(-LARGEST), one(LARGEST), one(0)], &v.colors);
    let rest_tables: Vec<FrequencyTable> = (0..9).map(|_| one(0)).collect();
    *sections.payload(plain::SH_REST) = block(&content.band_steps, &rest_tables, &v.sh_rest);
    sections.seal()
}

/// The sh1 stream with optional sections: `xtra` after HEAD, then 56 more at the end, 64
/// sections in all (the most a stream may hold besides END).
fn unknown_optional_sections(sh1: &[u8]) -> Vec<u8> {
    let mut sections = Sections::of(sh1);
    sections.insert(1, Tag(*b"xtra"), b"an optional section this decoder does not know".to_vec());
    for i in 0..56u8 {
        sections.list.push((Tag([b'n', b'0' + i / 10, b'0' + i % 10, b' ']), vec![i; usize::from(i % 5)]));
    }
    assert_eq!(sections.list.len(), pwgs_bitstream::MAX_SECTIONS);
    write_container(&sections.list)
}

/// The sh1 stream with a zero word appended to the first chunk (in section order) to which one
/// can be appended: one whose decoding reads a word past its end.
fn extra_zero_word(sh1: &[u8]) -> Result<(Tag, Vec<u8>)> {
    let sections = Sections::of(sh1);
    for (tag, _) in &sections.list[1..] {
        let mut extended = sections.clone();
        extended.payload(*tag).extend([0; 4]);
        let bytes = extended.seal();
        if stream::decode(&bytes).is_ok() {
            return Ok((*tag, bytes));
        }
    }
    anyhow::bail!("no chunk of sh1 reads past its end")
}

/// The sh2 stream with its sections in reverse order after HEAD.
fn reordered(sh2: &[u8]) -> Vec<u8> {
    let mut sections = Sections::of(sh2);
    sections.list[1..].reverse();
    write_container(&sections.list)
}

fn full_cell() -> PlainGaussians {
    let mut draws = Draws::new(21);
    let mut positions = vec![[3, 5, 6]; 255];
    positions.extend((0..20).map(|_| draws.point(4)));
    // Keep the other 20 out of the full cell.
    positions.iter_mut().skip(255).for_each(|p| p[0] = (p[0] + 1).clamp(4, 15));
    let (steps, ranges) = content::ordinary(2);
    content::gaussians(&mut draws, content::unit_cube(4), positions, 2, steps, &ranges)
}

/// Sets the first channel of every block (the first coded component for ROTN) of every
/// Gaussian to `value()`: wide values there, narrow ones elsewhere, keep the tables small.
fn set_first_channels(c: &mut PlainGaussians, mut value: impl FnMut() -> i32) {
    let rest = c.sh_rest.len() / c.len();
    for i in 0..c.len() {
        c.log_scales[i][0] = value();
        c.rotations[i].rest[0] = value();
        c.opacity_logits[i] = value();
        c.sh_dc[i][0] = value();
        if rest > 0 {
            c.sh_rest[i * rest] = value();
        }
    }
}

fn smallest_steps() -> PlainGaussians {
    let mut draws = Draws::new(31);
    let positions = (0..30).map(|_| draws.point(8)).collect();
    let narrow = [-20, 20];
    let ranges = Ranges { log_scale: narrow, rotation: narrow, opacity: narrow, dc: narrow, sh_rest: narrow };
    let steps = Steps::all(f32::from_bits(1), 1);
    let mut c = content::gaussians(&mut draws, content::unit_cube(8), positions, 1, steps, &ranges);
    set_first_channels(&mut c, || draws.i32([-LARGEST, LARGEST]));
    c.log_scales[0][0] = LARGEST;
    c.log_scales[1][0] = -LARGEST;
    c
}

fn largest_steps() -> PlainGaussians {
    let mut draws = Draws::new(41);
    let mut positions: Vec<[u32; 3]> = (0..22).map(|_| draws.point(24)).collect();
    positions.extend([[0; 3], [(1 << 24) - 1; 3]]);
    // x reaches 0.49 * 2^127 below zero, z as far above: with 1.5 * 2^127 of grid on top the
    // farthest mean is 1.99 * 2^127, just under the largest binary32 (2 - 2^-23) * 2^127.
    let edge = 0.49 * 2f32.powi(127);
    let grid = PositionGrid { origin: [-edge, 0.0, edge], cell: 1.5 * 2f32.powi(103), depth: 24 };
    let unit = [-1, 1];
    let ranges = Ranges { log_scale: unit, rotation: unit, opacity: unit, dc: unit, sh_rest: unit };
    let mut c = content::gaussians(&mut draws, grid, positions, 3, Steps::all(largest_step(), 3), &ranges);
    let values = [0, 1, -1, LARGEST, -LARGEST];
    set_first_channels(&mut c, || values[draws.int(0, 4) as usize]);
    c
}

fn depth_one() -> PlainGaussians {
    let mut draws = Draws::new(51);
    let cells: Vec<[u32; 3]> = (0..8).filter(|&c| c != 5).map(|c| [c >> 2, (c >> 1) & 1, c & 1]).collect();
    let positions = cells.iter().flat_map(|&p| [p; 3]).collect();
    let (steps, ranges) = content::ordinary(0);
    content::gaussians(&mut draws, content::unit_cube(1), positions, 0, steps, &ranges)
}

fn depth_24() -> PlainGaussians {
    let mut draws = Draws::new(61);
    let mut positions: Vec<[u32; 3]> = (0..48).map(|_| draws.point(24)).collect();
    positions.extend([[0; 3], [(1 << 24) - 1; 3]]);
    let (steps, ranges) = content::ordinary(1);
    content::gaussians(&mut draws, content::unit_cube(24), positions, 1, steps, &ranges)
}

/// A wrapped stream re-sealed as version 1.1 with fields appended to HEAD and WRAP.
fn newer_minor() -> Vec<u8> {
    let content = ordinary_gaussians(71, 30, 1);
    let config = WrapperConfig { width: 4, noise: true, plucker: true, seed: 77 };
    let mut sections = Sections::of(&encode(&content, Some(&content::synthesis(config, 72))));
    sections.minor = 1;
    let mut appended = FieldWriter::new();
    appended.u32(0xDEAD_BEEF);
    appended.varint(300);
    sections.payload(Tag::HEAD).extend(&appended.bytes);
    sections.payload(WRAPPER).extend([7, 7, 7]);
    sections.list.push((Tag(*b"nu11"), vec![1, 1]));
    sections.seal()
}

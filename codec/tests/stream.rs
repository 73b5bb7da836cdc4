//! Stream round trips, thread independence, and robustness against corrupt input: every
//! mutation of a valid stream must give a clean error (or a valid decode), never a panic, a
//! hang or a huge allocation.

use pwgs_bitstream::{Container, MAGIC, Tag};
use pwgs_codec::stream::header::{BaseKind, Header, MAX_GAUSSIANS};
use pwgs_codec::stream::plain::{PlainGaussians, PositionGrid, QuantizedRotation};
use pwgs_codec::stream::{self, Content, DecodeError};
use pwgs_core::gaussians::sh_coeff_count;
use pwgs_core::random::SplitMix64;

fn int(rng: &mut SplitMix64, spread: f32) -> i32 {
    // Roughly Laplacian around 0, with a rare large outlier that needs the escape.
    let u = rng.uniform(-1.0, 1.0);
    let v = (u.signum() * (1.0 - u.abs()).max(1e-6).ln() * -spread) as i32;
    if rng.uniform(0.0, 1.0) < 0.002 { v * 5000 } else { v }
}

fn random_content(n: usize, degree: u32, seed: u64) -> PlainGaussians {
    let mut rng = SplitMix64(seed);
    let depth = 12;
    let side = 1u32 << depth;
    let rest = (sh_coeff_count(degree) - 1) * 3;
    let positions: Vec<[u32; 3]> = (0..n)
        .map(|i| {
            // A few shared cells, as duplicated Gaussians produce.
            if i % 50 == 1 { [7, 7, 7] } else { std::array::from_fn(|_| (rng.uniform(0.3, 0.7) * side as f32) as u32) }
        })
        .collect();
    PlainGaussians {
        grid: PositionGrid { origin: [-1.0, -2.0, 0.5], cell: 1e-3, depth },
        positions,
        classes: None,
        scale_step: 0.05,
        log_scales: (0..n).map(|_| std::array::from_fn(|_| int(&mut rng, 4.0) - 80)).collect(),
        rotation_step: 0.01,
        rotations: (0..n)
            .map(|_| QuantizedRotation {
                largest: (rng.uniform(0.0, 4.0) as u8).min(3),
                rest: std::array::from_fn(|_| (int(&mut rng, 10.0)).clamp(-70, 70)),
            })
            .collect(),
        opacity_step: 0.1,
        opacity_logits: (0..n).map(|_| int(&mut rng, 8.0)).collect(),
        sh_degree: degree,
        dc_step: 0.05,
        sh_dc: (0..n).map(|_| std::array::from_fn(|_| int(&mut rng, 6.0))).collect(),
        band_steps: [0.03, 0.04, 0.05][..degree as usize].to_vec(),
        sh_rest: (0..n * rest).map(|_| int(&mut rng, 1.0)).collect(),
        colour_differences: false,
        adaptive: false,
    }
}

fn header_for(content: &PlainGaussians) -> Header {
    Header {
        base: BaseKind::Plain3dgs,
        gaussian_count: content.len() as u32,
        sh_degree: content.sh_degree,
        center: [0.1, 0.2, 0.3],
        scale: 2.5,
        background: [1.0, 1.0, 1.0],
    }
}

fn encode(content: &PlainGaussians) -> Vec<u8> {
    stream::encode(&header_for(content), content, None).unwrap()
}

/// The content as a decoder lists it: the octree's order.
fn reordered(content: &PlainGaussians) -> PlainGaussians {
    let (_, order) = pwgs_codec::stream::octree::encode(&content.positions, content.grid.depth).unwrap();
    let rest = (sh_coeff_count(content.sh_degree) - 1) * 3;
    PlainGaussians {
        positions: order.iter().map(|&i| content.positions[i]).collect(),
        log_scales: order.iter().map(|&i| content.log_scales[i]).collect(),
        rotations: order.iter().map(|&i| content.rotations[i]).collect(),
        opacity_logits: order.iter().map(|&i| content.opacity_logits[i]).collect(),
        sh_dc: order.iter().map(|&i| content.sh_dc[i]).collect(),
        sh_rest: order.iter().flat_map(|&i| content.sh_rest[i * rest..(i + 1) * rest].to_vec()).collect(),
        ..content.clone()
    }
}

#[test]
fn every_degree_round_trips_exactly() {
    for degree in 0..=3 {
        for adaptive in [false, true] {
            let content = PlainGaussians { adaptive, ..random_content(700, degree, degree as u64 + 1) };
            let bytes = encode(&content);
            let decoded = stream::decode(&bytes).unwrap();
            assert_eq!(decoded.header, header_for(&content));
            let expected = Content::Plain(Box::new(reordered(&content)));
            assert_eq!(decoded.content, expected, "degree {degree}, adaptive {adaptive}");
            assert_eq!(decoded.scene.base, decoded.content.dequantize());
            assert!(decoded.scene.plain_gaussians().unwrap().is_consistent());
        }
    }
}

/// With `ADPT` (SPEC.md 6.7) each block takes trees only where they code smaller: never a
/// larger stream than tables alone, and on 700 random Gaussians (whose tables cost about as
/// much as their values) smaller.
#[test]
fn adaptive_trees_never_cost_more_than_tables() {
    for degree in [0, 2] {
        let content = random_content(700, degree, 40 + u64::from(degree));
        let tables = encode(&content).len();
        let bytes = encode(&PlainGaussians { adaptive: true, ..content });
        let adpt = Container::parse(&bytes).unwrap().section(Tag(*b"ADPT")).map(|s| s.payload.to_vec());
        assert!(bytes.len() < tables, "degree {degree}: {} bytes with trees, {tables} without", bytes.len());
        assert!(adpt.is_some_and(|mask| mask.len() == 1 && mask[0] != 0), "degree {degree}");
    }
}

#[test]
fn empty_streams_round_trip() {
    let content = random_content(0, 1, 3);
    let decoded = stream::decode(&encode(&content)).unwrap();
    assert!(decoded.scene.plain_gaussians().unwrap().is_empty());
}

#[test]
fn decoding_does_not_depend_on_the_thread_count() {
    let bytes = encode(&random_content(3000, 3, 9));
    let hashes: Vec<String> = [1, 2, 5]
        .iter()
        .map(|&threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| stream::decode(&bytes).unwrap().scene.attribute_hash())
        })
        .collect();
    assert!(hashes.windows(2).all(|w| w[0] == w[1]), "{hashes:?}");
}

#[test]
fn reconstruction_follows_the_spec_formulas() {
    let content = random_content(50, 1, 4);
    let g = content.dequantize();
    for i in 0..content.len() {
        let q = content.positions[i];
        for a in 0..3 {
            let expected = (content.grid.origin[a] as f64 + q[a] as f64 * content.grid.cell as f64) as f32;
            assert_eq!(g.means[i][a].to_bits(), expected.to_bits());
        }
        let r = g.rotations[i];
        let norm: f32 = r.iter().map(|c| c * c).sum::<f32>().sqrt();
        assert!(
            (norm - 1.0).abs() < 1e-5
                || content.rotations[i].rest.iter().map(|&v| (v as f32 * 0.01).powi(2)).sum::<f32>() > 1.0
        );
        assert!(r[content.rotations[i].largest as usize] >= 0.0);
        assert_eq!(g.opacity_logits[i], content.opacity_logits[i] as f32 * 0.1);
        // Band-1 coefficients use the band-1 step.
        assert_eq!(g.sh_of(i)[3], content.sh_rest[i * 9] as f32 * 0.03);
    }
}

fn fix_crcs(bytes: &mut [u8]) {
    let mut at = MAGIC.len() + 4;
    let mut first = true;
    while at + 8 <= bytes.len() {
        let len = u32::from_le_bytes(bytes[at + 4..at + 8].try_into().unwrap()) as usize;
        let end = at + 8 + len;
        if end + 4 > bytes.len() {
            return;
        }
        let from = if first { 0 } else { at };
        let crc = crc32c(&bytes[from..end]);
        bytes[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        first = false;
        at = end + 4;
    }
}

/// CRC-32C (Castagnoli), bitwise: an independent check of the container's CRC.
fn crc32c(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 { (crc >> 1) ^ 0x82F6_3B78 } else { crc >> 1 };
        }
    }
    !crc
}

#[test]
fn container_crc_matches_an_independent_crc32c() {
    assert_eq!(crc32c(b"123456789"), 0xE306_9283, "CRC-32C check value");
    let bytes = encode(&random_content(30, 0, 2));
    let mut fixed = bytes.clone();
    fix_crcs(&mut fixed);
    assert_eq!(fixed, bytes);
}

/// Deterministic mutation fuzzing: bit flips, byte rewrites, truncations, insertions and
/// deletions, each also with the CRCs recomputed so that the mutation reaches the section
/// decoders. Each decode must return, Ok or Err, without panicking.
#[test]
fn mutated_streams_never_panic() {
    // Every other pair of rounds mutates the stream whose blocks are coded with trees.
    let content = random_content(400, 2, 21);
    let originals = [encode(&content), encode(&PlainGaussians { adaptive: true, ..content })];
    let mut rng = SplitMix64(99);
    let mut outcomes = [0usize; 2];
    let start = std::time::Instant::now();
    for round in 0..3000 {
        let original = &originals[round / 2 % 2];
        let mut b = original.clone();
        let pick = |rng: &mut SplitMix64, len: usize| (rng.uniform(0.0, 1.0) * len as f32) as usize % len.max(1);
        for _ in 0..1 + round % 4 {
            match round % 5 {
                0 => {
                    let i = pick(&mut rng, b.len() * 8);
                    b[i / 8] ^= 1 << (i % 8);
                }
                1 => {
                    let i = pick(&mut rng, b.len());
                    b[i] = (rng.next_u64() & 0xff) as u8;
                }
                2 => b.truncate(pick(&mut rng, b.len())),
                3 => {
                    let i = pick(&mut rng, b.len());
                    b.insert(i, (rng.next_u64() & 0xff) as u8);
                }
                _ => {
                    let i = pick(&mut rng, b.len());
                    b.remove(i);
                }
            }
        }
        if round % 2 == 1 {
            fix_crcs(&mut b);
        }
        if round % 3 == 2 {
            // Rewrite one byte inside a section's payload, keeping the container valid.
            let tags: Vec<Tag> =
                pwgs_bitstream::Container::parse(original).unwrap().sections.iter().map(|s| s.tag).collect();
            let tag = tags[pick(&mut rng, tags.len())];
            let (at, value) = (rng.next_u64() as usize, (rng.next_u64() & 0xff) as u8);
            b = with_payload(original, tag, |p| {
                if !p.is_empty() {
                    let i = at % p.len();
                    p[i] = value;
                }
            });
        }
        let result = stream::decode(&b);
        if let Ok(d) = &result {
            assert!(d.scene.plain_gaussians().unwrap().is_consistent());
            let g = &d.scene.plain_gaussians().unwrap();
            let all = g.means.iter().flatten().chain(g.log_scales.iter().flatten()).chain(g.rotations.iter().flatten());
            assert!(all.chain(&g.opacity_logits).chain(&g.sh).all(|v| v.is_finite()), "non-finite decoded value");
            assert!(d.header.gaussian_count <= MAX_GAUSSIANS);
        }
        outcomes[result.is_ok() as usize] += 1;
    }
    eprintln!(
        "3000 mutations: {} rejected, {} decoded, {:.1} s",
        outcomes[0],
        outcomes[1],
        start.elapsed().as_secs_f64()
    );
    assert!(outcomes[0] > 1500, "most mutations must be detected: {outcomes:?}");
}

/// Rewrites a section's payload (by tag) and fixes the CRCs.
fn with_payload(bytes: &[u8], tag: Tag, edit: impl Fn(&mut Vec<u8>)) -> Vec<u8> {
    let c = pwgs_bitstream::Container::parse(bytes).unwrap();
    let mut sections: Vec<(Tag, Vec<u8>)> = c.sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect();
    for (t, p) in &mut sections {
        if *t == tag {
            edit(p);
        }
    }
    pwgs_bitstream::write_container(&sections)
}

#[test]
fn absurd_declared_sizes_are_refused_quickly() {
    let bytes = encode(&random_content(200, 1, 5));
    let start = std::time::Instant::now();
    // The header declares more Gaussians than the octree holds, within the length bound.
    let more = with_payload(&bytes, Tag::HEAD, |p| p[1..5].copy_from_slice(&1000u32.to_le_bytes()));
    let err = stream::decode(&more).unwrap_err().to_string();
    assert!(err.contains("POSN"), "{err}");
    // The maximum count in a stream padded to 40 KB: more than one Gaussian per two bytes.
    let mut sections: Vec<(Tag, Vec<u8>)> = pwgs_bitstream::Container::parse(&bytes)
        .unwrap()
        .sections
        .iter()
        .map(|s| (s.tag, s.payload.to_vec()))
        .collect();
    sections[0].1[1..5].copy_from_slice(&MAX_GAUSSIANS.to_le_bytes());
    sections[0].1[5] = 3;
    sections.push((Tag(*b"pad "), vec![0; 40_000]));
    let huge = pwgs_bitstream::write_container(&sections);
    let err = stream::decode(&huge).unwrap_err().to_string();
    assert!(err.contains("HEAD") && err.contains("gaussian count 16777216 exceeds half the stream's length"), "{err}");
    let over = with_payload(&bytes, Tag::HEAD, |p| p[1..5].copy_from_slice(&(MAX_GAUSSIANS + 1).to_le_bytes()));
    assert!(stream::decode(&over).unwrap_err().to_string().contains("exceeds the limit"));
    // A frequency table claiming 2^32 - 1 symbols.
    let table = with_payload(&bytes, Tag(*b"SCAL"), |p| p.splice(5..6, [0xff, 0xff, 0xff, 0xff, 0x0f]).for_each(drop));
    assert!(stream::decode(&table).is_err());
    assert!(start.elapsed().as_secs() < 10, "refusals took {:?}", start.elapsed());
}

#[test]
fn structural_errors_name_the_problem() {
    let bytes = encode(&random_content(50, 0, 6));
    let missing = {
        let c = pwgs_bitstream::Container::parse(&bytes).unwrap();
        let sections: Vec<(Tag, Vec<u8>)> =
            c.sections.iter().filter(|s| s.tag != Tag(*b"OPAC")).map(|s| (s.tag, s.payload.to_vec())).collect();
        pwgs_bitstream::write_container(&sections)
    };
    assert_eq!(stream::decode(&missing).unwrap_err(), DecodeError::MissingSection(Tag(*b"OPAC")));
    let unknown = {
        let c = pwgs_bitstream::Container::parse(&bytes).unwrap();
        let mut sections: Vec<(Tag, Vec<u8>)> = c.sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect();
        sections.push((Tag(*b"ZZZZ"), vec![1, 2, 3]));
        sections.push((Tag(*b"note"), b"optional sections are skipped".to_vec()));
        pwgs_bitstream::write_container(&sections)
    };
    assert_eq!(stream::decode(&unknown).unwrap_err(), DecodeError::UnknownCriticalSection(Tag(*b"ZZZZ")));
    let optional = with_payload(&unknown, Tag(*b"ZZZZ"), |_| {});
    let skipped = {
        let c = pwgs_bitstream::Container::parse(&optional).unwrap();
        let sections: Vec<(Tag, Vec<u8>)> =
            c.sections.iter().filter(|s| s.tag != Tag(*b"ZZZZ")).map(|s| (s.tag, s.payload.to_vec())).collect();
        pwgs_bitstream::write_container(&sections)
    };
    assert_eq!(
        stream::decode(&skipped).unwrap().scene.plain_gaussians().unwrap(),
        stream::decode(&bytes).unwrap().scene.plain_gaussians().unwrap()
    );
    let bad_step = with_payload(&bytes, Tag(*b"SCAL"), |p| p[..4].copy_from_slice(&(-1.0f32).to_le_bytes()));
    let err = stream::decode(&bad_step).unwrap_err().to_string();
    assert!(err.contains("SCAL") && err.contains("step"), "{err}");
}

/// A stream whose first SCAL table has `lo = i32::MAX - n + 1`: `lo + n` overflows i32 (a
/// panic in the dev profile, and an accepted table in release, before the check was widened).
#[test]
fn a_table_reaching_past_i32_is_refused() {
    let bytes = encode(&random_content(40, 0, 8));
    for n in [1u32, 4096] {
        let scal = with_payload(&bytes, Tag(*b"SCAL"), |p| {
            let mut w = pwgs_bitstream::FieldWriter::new();
            w.f32(0.05);
            for _ in 0..3 {
                w.signed_varint(i32::MAX - n as i32 + 1);
                w.varint(n);
                w.varint(65536 - n);
                (0..n).for_each(|_| w.varint(1));
            }
            *p = w.into_bytes();
        });
        let err = stream::decode(&scal).unwrap_err().to_string();
        assert!(err.contains("SCAL") && err.contains("table lo") && err.contains("beyond"), "{err}");
    }
}

#[test]
fn chunks_must_hold_exactly_their_symbols() {
    let bytes = encode(&random_content(60, 1, 9));
    for tag in ["POSN", "SCAL", "ROTN", "OPAC", "COLR", "SHRS"] {
        let tag = Tag(tag.as_bytes().try_into().unwrap());
        let padded = with_payload(&bytes, tag, |p| p.extend([0; 8]));
        let err = stream::decode(&padded).unwrap_err().to_string();
        assert!(err.contains(&tag.to_string()) && err.contains("after the last symbol"), "{tag}: {err}");
    }
    // With N = 0 every chunk must be empty.
    let empty = encode(&random_content(0, 1, 9));
    assert_eq!(stream::decode(&empty).unwrap().scene.plain_gaussians().unwrap().len(), 0);
    for tag in ["POSN", "OPAC"] {
        let tag = Tag(tag.as_bytes().try_into().unwrap());
        let err = stream::decode(&with_payload(&empty, tag, |p| p.extend([1, 2, 3, 4]))).unwrap_err().to_string();
        assert!(err.contains(&tag.to_string()) && err.contains("unread"), "{tag}: {err}");
    }
}

#[test]
fn sh_rest_must_be_absent_at_degree_zero_and_checks_run_in_spec_order() {
    let degree0 = encode(&random_content(30, 0, 10));
    let degree1 = encode(&random_content(30, 1, 10));
    let shrs = pwgs_bitstream::Container::parse(&degree1).unwrap().section(Tag(*b"SHRS")).unwrap().payload.to_vec();
    let sections = |bytes: &[u8]| -> Vec<(Tag, Vec<u8>)> {
        pwgs_bitstream::Container::parse(bytes).unwrap().sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect()
    };
    let mut with_shrs = sections(&degree0);
    with_shrs.push((Tag(*b"SHRS"), shrs));
    let err = stream::decode(&pwgs_bitstream::write_container(&with_shrs)).unwrap_err().to_string();
    assert!(err.contains("SHRS") && err.contains("SH degree is 0"), "{err}");
    // A missing section is reported before a corrupt POSN is decoded.
    let mut broken = sections(&degree1);
    broken.retain(|(t, _)| *t != Tag(*b"COLR"));
    broken[1].1.truncate(20);
    assert_eq!(
        stream::decode(&pwgs_bitstream::write_container(&broken)).unwrap_err(),
        DecodeError::MissingSection(Tag(*b"COLR"))
    );
    // Of two corrupt attribute blocks, the first in section order is reported.
    let two = with_payload(&degree1, Tag(*b"SHRS"), |p| p.truncate(2));
    let two = with_payload(&two, Tag(*b"ROTN"), |p| p.truncate(2));
    let err = stream::decode(&two).unwrap_err().to_string();
    assert!(err.contains("ROTN"), "{err}");
}

/// 400 identical Gaussians in two grid cells code to less than two bytes per Gaussian: the
/// writer pads such a stream, so that what it writes decodes (a fuzz finding: it did not).
#[test]
fn redundant_content_is_padded_to_two_bytes_per_gaussian() {
    let mut content = random_content(400, 0, 11);
    content.positions = (0..400).map(|i| [i % 2, 0, 0]).collect();
    content.log_scales.fill([-80; 3]);
    content.rotations.fill(QuantizedRotation { largest: 0, rest: [0; 3] });
    content.opacity_logits.fill(3);
    content.sh_dc.fill([1, 2, 3]);
    let bytes = encode(&content);
    let c = pwgs_bitstream::Container::parse(&bytes).unwrap();
    let pad = c.section(stream::PADDING).expect("padded");
    assert_eq!(bytes.len(), 800, "exactly the least length 400 Gaussians need");
    assert!(pad.payload.len() + pwgs_bitstream::SECTION_OVERHEAD < 800);
    assert_eq!(stream::decode(&bytes).unwrap().content, Content::Plain(Box::new(reordered(&content))));
    // Real content needs no padding.
    let plain = encode(&random_content(400, 0, 11));
    assert!(pwgs_bitstream::Container::parse(&plain).unwrap().section(stream::PADDING).is_none());
}

/// A bad rotation index is reported as ROTN's value is decoded, before a later section's fault.
#[test]
fn a_bad_rotation_index_is_reported_before_later_sections() {
    let mut content = random_content(30, 0, 12);
    content.rotations[7].largest = 5;
    let bytes = stream::encode(&header_for(&content), &content, None).unwrap();
    let err = stream::decode(&bytes).unwrap_err().to_string();
    assert!(err.contains("ROTN") && err.contains("largest-component index 5"), "{err}");
    let broken_opacities = with_payload(&bytes, Tag(*b"OPAC"), |p| p.truncate(2));
    let err = stream::decode(&broken_opacities).unwrap_err().to_string();
    assert!(err.contains("ROTN") && err.contains("largest-component index 5"), "{err}");
}

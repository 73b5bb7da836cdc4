//! Importance classes (SPEC.md section 6.5): streams with `IMPC` round-trip (also with colour
//! differences, 6.6), reconstruct by the spec's formulas, and every malformed field or chunk is
//! an error naming it.

use pwgs_bitstream::{Container, Tag, write_container};
use pwgs_codec::stream::classes::{CLASSES, ImportanceClasses};
use pwgs_codec::stream::header::{BaseKind, Header};
use pwgs_codec::stream::plain::{PlainGaussians, PositionGrid, QuantizedRotation};
use pwgs_codec::stream::{self, Content, DecodeError};
use pwgs_core::random::SplitMix64;

const REFINE: u8 = 3;

/// `n` Gaussians of SH degree 1 in 4 classes (factors 1, 1.5, 2, 4; drops 0 to 3) on a grid of
/// 10 + 3 levels, clustered so that coarse cells are shared.
fn content(n: usize, seed: u64) -> PlainGaussians {
    let mut rng = SplitMix64(seed);
    let mut int = |spread: f32| (rng.uniform(-spread, spread)).round() as i32;
    let of: Vec<u8> = (0..n).map(|i| (i * 7 % 4) as u8).collect();
    let classes = ImportanceClasses { refine: REFINE, factors: vec![1.0, 1.5, 2.0, 4.0], drops: vec![0, 1, 2, 3], of };
    let positions = (0..n)
        .map(|i| {
            let q: [u32; 3] = std::array::from_fn(|a| (4000 + (i as i32 * (5 + a as i32) % 300) + int(40.0)) as u32);
            q.map(|c| classes.snap(classes.of[i], c))
        })
        .collect();
    PlainGaussians {
        grid: PositionGrid { origin: [-1.0, -2.0, 0.5], cell: 1e-3 * 8.0, depth: 10 },
        positions,
        scale_step: 0.05,
        log_scales: (0..n).map(|_| std::array::from_fn(|_| int(4.0) - 80)).collect(),
        rotation_step: 0.01,
        rotations: (0..n).map(|_| QuantizedRotation { largest: 0, rest: std::array::from_fn(|_| int(30.0)) }).collect(),
        opacity_step: 0.1,
        opacity_logits: (0..n).map(|_| int(8.0)).collect(),
        sh_degree: 1,
        dc_step: 0.05,
        sh_dc: (0..n).map(|_| std::array::from_fn(|_| int(6.0))).collect(),
        band_steps: vec![0.03],
        sh_rest: (0..n * 9).map(|_| int(2.0)).collect(),
        colour_differences: false,
        adaptive: false,
        classes: Some(classes),
    }
}

fn encode(content: &PlainGaussians) -> Vec<u8> {
    let header = Header {
        base: BaseKind::Plain3dgs,
        gaussian_count: content.len() as u32,
        sh_degree: content.sh_degree,
        center: [0.0; 3],
        scale: 1.0,
        background: [0.0; 3],
    };
    stream::encode(&header, content, None).unwrap()
}

fn decoded_content(bytes: &[u8]) -> PlainGaussians {
    match stream::decode(bytes).unwrap().content {
        Content::Plain(p) => *p,
        Content::Anchors(_) => panic!("a plain stream decoded as anchors"),
    }
}

/// The stream with one section's payload edited (CRCs recomputed).
fn edited(bytes: &[u8], tag: Tag, edit: impl Fn(&mut Vec<u8>)) -> Vec<u8> {
    let container = Container::parse(bytes).unwrap();
    let sections: Vec<(Tag, Vec<u8>)> = container
        .sections
        .iter()
        .map(|s| {
            let mut payload = s.payload.to_vec();
            if s.tag == tag {
                edit(&mut payload);
            }
            (s.tag, payload)
        })
        .collect();
    write_container(&sections)
}

fn error_of(bytes: &[u8]) -> String {
    stream::decode(bytes).expect_err("an invalid stream decoded").to_string()
}

#[test]
fn classes_round_trip_in_the_octree_order() {
    let original = content(400, 1);
    let bytes = encode(&original);
    let decoded = decoded_content(&bytes);
    assert_eq!(decoded.len(), 400);
    // The decoder lists Gaussians in the coarse octree's order; as a multiset of rows they are
    // the original ones.
    let row = |c: &PlainGaussians, i: usize| {
        let classes = c.classes.as_ref().unwrap();
        (c.positions[i], classes.of[i], c.log_scales[i], c.rotations[i].rest, c.opacity_logits[i], c.sh_dc[i])
    };
    let mut a: Vec<_> = (0..400).map(|i| format!("{:?}", row(&original, i))).collect();
    let mut b: Vec<_> = (0..400).map(|i| format!("{:?}", row(&decoded, i))).collect();
    a.sort();
    b.sort();
    assert_eq!(a, b);
    // Writing the decoded content again gives the same stream.
    assert_eq!(encode(&decoded), bytes);
    // With the colours as differences too (SPEC.md 6.6): the same Gaussians, CDIF present.
    let both = PlainGaussians { colour_differences: true, ..original.clone() };
    let bytes = encode(&both);
    assert!(Container::parse(&bytes).unwrap().section(Tag(*b"CDIF")).is_some());
    let again = decoded_content(&bytes);
    assert!(again.colour_differences);
    assert_eq!(again.dequantize(), decoded.dequantize(), "differences changed the Gaussians");
    // And with adaptive trees (SPEC.md 6.7), a tree model per class and channel.
    let trees = PlainGaussians { adaptive: true, ..both };
    let bytes = encode(&trees);
    let mask = Container::parse(&bytes).unwrap().section(Tag(*b"ADPT")).map(|s| s.payload.to_vec());
    assert!(mask.is_some_and(|m| m[0] != 0), "no block took trees");
    let again = decoded_content(&bytes);
    assert!(again.adaptive);
    assert_eq!(again.dequantize(), decoded.dequantize(), "trees changed the Gaussians");
    assert_eq!(encode(&again), bytes);
}

#[test]
fn reconstruction_follows_the_spec_formulas() {
    let bytes = encode(&content(200, 2));
    let decoded = stream::decode(&bytes).unwrap();
    let Content::Plain(c) = &decoded.content else { panic!("not plain") };
    let classes = c.classes.as_ref().unwrap();
    let g = decoded.scene.plain_gaussians().unwrap();
    let fine_cell = f64::from(c.grid.cell) / 8.0;
    for i in 0..c.len() {
        let k = usize::from(classes.of[i]);
        let m = classes.factors[k];
        for a in 0..3 {
            let r = c.positions[i][a];
            // The dropped levels hold the centre pattern: 1 then zeros.
            let d = classes.drops[k];
            if d > 0 {
                assert_eq!(r & ((1 << d) - 1), 1 << (d - 1), "Gaussian {i} axis {a}");
            }
            let mean = (f64::from(c.grid.origin[a]) + f64::from(r) * fine_cell) as f32;
            assert_eq!(g.means[i][a].to_bits(), mean.to_bits());
            assert_eq!(g.log_scales[i][a].to_bits(), (c.log_scales[i][a] as f32 * (0.05f32 * m)).to_bits());
        }
        assert_eq!(g.opacity_logits[i].to_bits(), (c.opacity_logits[i] as f32 * (0.1f32 * m)).to_bits());
        let sh = g.sh_of(i);
        assert_eq!(sh[0].to_bits(), (c.sh_dc[i][0] as f32 * (0.05f32 * m)).to_bits());
        assert_eq!(sh[3].to_bits(), (c.sh_rest[i * 9] as f32 * (0.03f32 * m)).to_bits());
        assert_eq!(g.rotations[i], c.rotations[i].quaternion(0.01 * m));
    }
}

#[test]
fn dropped_levels_cost_no_bytes() {
    let mut coarse = content(2000, 3);
    // The same Gaussians (positions already at their centres) with every level coded.
    let mut fine = coarse.clone();
    fine.classes.as_mut().unwrap().drops = vec![0; 4];
    let size = |c: &PlainGaussians| {
        let bytes = encode(c);
        let container = Container::parse(&bytes).unwrap();
        container.section(CLASSES).unwrap().payload.len()
    };
    // Classes 1, 2 and 3 (three quarters of the Gaussians) drop 1, 2 and 3 levels: 6 levels
    // of 3 bits in every 4 Gaussians, about 4.5 bits a Gaussian, at least 2 of them saved.
    let saved = (size(&fine) - size(&coarse)) as f64 * 8.0 / 2000.0;
    assert!(saved > 2.0, "{saved:.2} bits a Gaussian saved");
    assert_eq!(decoded_content(&encode(&fine)).dequantize().means.len(), 2000);
    coarse.classes = None;
    coarse.positions = coarse.positions.iter().map(|q| q.map(|c| c >> REFINE)).collect();
    assert!(stream::decode(&encode(&coarse)).is_ok(), "and without classes the same content codes");
}

#[test]
fn malformed_fields_are_errors_naming_them() {
    let bytes = encode(&content(100, 4));
    type Edit = Box<dyn Fn(&mut Vec<u8>)>;
    let cases: [(&str, Edit); 6] = [
        ("classes", Box::new(|p| p[0] = 1)),
        ("classes", Box::new(|p| p[0] = 17)),
        ("refine", Box::new(|p| p[1] = 15)),
        ("factor", Box::new(|p| p[2..6].copy_from_slice(&0.0f32.to_le_bytes()))),
        ("factor", Box::new(|p| p[2..6].copy_from_slice(&f32::NAN.to_le_bytes()))),
        ("drop", Box::new(|p| p[18] = 4)),
    ];
    for (field, edit) in cases {
        let message = error_of(&edited(&bytes, CLASSES, edit));
        assert!(message.contains("IMPC") && message.contains(field), "{field}: {message}");
    }
    // A factor whose product with a step overflows: named by the attribute section.
    let huge = edited(&bytes, CLASSES, |p| p[14..18].copy_from_slice(&1e38f32.to_le_bytes()));
    let message = error_of(&huge);
    assert!(message.contains("SCAL") && message.contains("class 3"), "{message}");
    // A truncated chunk, and one with an extra word.
    let short = edited(&bytes, CLASSES, |p| p.truncate(p.len() - 8));
    assert!(error_of(&short).contains("IMPC"), "{}", error_of(&short));
    let long = edited(&bytes, CLASSES, |p| p.extend([0; 8]));
    assert!(error_of(&long).contains("IMPC"), "{}", error_of(&long));
}

#[test]
fn a_stream_without_its_classes_is_refused_not_misread() {
    let bytes = encode(&content(100, 5));
    let container = Container::parse(&bytes).unwrap();
    let without: Vec<(Tag, Vec<u8>)> =
        container.sections.iter().filter(|s| s.tag != CLASSES).map(|s| (s.tag, s.payload.to_vec())).collect();
    // The attribute sections hold a table per class and channel: read as one per channel, the
    // tables end early and the chunk fails, or the count of values does.
    assert!(matches!(stream::decode(&write_container(&without)), Err(DecodeError::Invalid { .. })));
}

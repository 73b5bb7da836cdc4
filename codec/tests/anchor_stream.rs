//! Anchor streams (base 1): round trips, the normative reconstruction, and refusal of corrupt
//! or oversized input with an error naming the problem.

use pwgs_bitstream::{Container, Tag, write_container};
use pwgs_codec::context_grid::ContextGridShape;
use pwgs_codec::stream::anchor::{self, QuantizedAnchors, QuantizedMlp};
use pwgs_codec::stream::anchor_context::{self, ContextNetwork, QuantizedContext};
use pwgs_codec::stream::header::{BaseKind, Header};
use pwgs_codec::stream::plain::PositionGrid;
use pwgs_codec::stream::{self, Content};
use pwgs_core::random::{SplitMix64, axis_camera};

fn ints(rng: &mut SplitMix64, n: usize, spread: f32) -> Vec<i32> {
    (0..n).map(|_| (rng.uniform(-spread, spread)).round() as i32).collect()
}

fn mlp(rng: &mut SplitMix64, inputs: usize, hidden: usize, outputs: usize) -> QuantizedMlp {
    QuantizedMlp {
        hidden,
        weight_exponent: -8,
        bias_exponent: -10,
        w1: ints(rng, hidden * inputs, 60.0),
        b1: ints(rng, hidden, 200.0),
        w2: ints(rng, outputs * hidden, 60.0),
        b2: ints(rng, outputs, 200.0),
    }
}

/// `n` distinct anchors on a 6-level grid with F = 5, K = 3.
fn random_anchors(n: usize, seed: u64) -> QuantizedAnchors {
    anchors_with_features(n, 5, seed)
}

/// `n` distinct anchors on a 6-level grid with F = `f`, K = 3.
fn anchors_with_features(n: usize, f: usize, seed: u64) -> QuantizedAnchors {
    let mut rng = SplitMix64(seed);
    let k = 3;
    let mut positions: Vec<[u32; 3]> = Vec::new();
    while positions.len() < n {
        let p: [u32; 3] = std::array::from_fn(|_| (rng.next_u64() % 64) as u32);
        if !positions.contains(&p) {
            positions.push(p);
        }
    }
    QuantizedAnchors {
        grid: PositionGrid { origin: [-0.5, -0.5, 2.0], cell: 1.0 / 64.0, depth: 6 },
        positions,
        feature_dim: f,
        offsets_per_anchor: k,
        feature_step: 0.05,
        features: ints(&mut rng, n * f, 20.0),
        scaling_step: 0.02,
        scaling: (0..n).map(|_| std::array::from_fn(|_| (rng.uniform(-250.0, -150.0)) as i32)).collect(),
        offset_step: 0.03,
        offsets: ints(&mut rng, n * 3 * k, 30.0),
        masks: (0..n * k).map(|i| i % 5 != 0).collect(),
        mlps: [mlp(&mut rng, f + 4, 6, k), mlp(&mut rng, f + 4, 4, 3 * k), mlp(&mut rng, f + 4, 5, 7 * k)],
        context: None,
    }
}

fn header_for(content: &QuantizedAnchors) -> Header {
    Header {
        base: BaseKind::Anchors,
        gaussian_count: content.len() as u32,
        sh_degree: 0,
        center: [0.0; 3],
        scale: 1.0,
        background: [0.0; 3],
    }
}

fn encode(content: &QuantizedAnchors) -> Vec<u8> {
    stream::encode(&header_for(content), content, None).unwrap()
}

/// The content as a decoder lists it: anchors in the octree's order.
fn reordered(c: &QuantizedAnchors) -> QuantizedAnchors {
    let (_, order) = stream::octree::encode(&c.positions, c.grid.depth).unwrap();
    let (f, k) = (c.feature_dim, c.offsets_per_anchor);
    let rows = |v: &[i32], w: usize| order.iter().flat_map(|&i| v[i * w..(i + 1) * w].to_vec()).collect::<Vec<_>>();
    let masks: Vec<bool> = order.iter().flat_map(|&i| c.masks[i * k..(i + 1) * k].to_vec()).collect();
    // The stream holds no offsets of masked neural Gaussians: they decode as 0.
    let mut offsets = rows(&c.offsets, 3 * k);
    offsets.chunks_exact_mut(3).zip(&masks).filter(|(_, m)| !**m).for_each(|(o, _)| o.fill(0));
    QuantizedAnchors {
        positions: order.iter().map(|&i| c.positions[i]).collect(),
        features: rows(&c.features, f),
        scaling: order.iter().map(|&i| c.scaling[i]).collect(),
        offsets,
        masks,
        ..c.clone()
    }
}

fn with_payload(bytes: &[u8], tag: Tag, edit: impl Fn(&mut Vec<u8>)) -> Vec<u8> {
    let c = Container::parse(bytes).unwrap();
    let mut sections: Vec<(Tag, Vec<u8>)> = c.sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect();
    sections.iter_mut().filter(|(t, _)| *t == tag).for_each(|(_, p)| edit(p));
    write_container(&sections)
}

#[test]
fn anchor_streams_round_trip_in_octree_order() {
    let content = random_anchors(120, 1);
    let decoded = stream::decode(&encode(&content)).unwrap();
    assert_eq!(decoded.header.base, BaseKind::Anchors);
    let expected = reordered(&content);
    assert_eq!(decoded.content, Content::Anchors(Box::new(expected.clone())));
    assert_eq!(decoded.scene.base, decoded.content.dequantize());
    let model = expected.dequantize();
    assert!(model.is_consistent());
    // The normative reconstruction: every value is its integer times its step.
    assert_eq!(model.features[7], expected.features[7] as f32 * 0.05);
    assert_eq!(model.scaling[3][4], expected.scaling[3][4] as f32 * 0.02);
    assert_eq!(model.offsets[11], expected.offsets[11] as f32 * 0.03);
    assert_eq!(model.opacity.w1[2], expected.mlps[0].w1[2] as f32 / 256.0);
    assert_eq!(model.color.b2[1], expected.mlps[1].b2[1] as f32 / 1024.0);
    assert_eq!(model.positions[5], expected.grid.position(expected.positions[5]));
    // A decoded anchor scene renders views whose Gaussians its MLPs derive.
    let camera = axis_camera(48, 32, 40.0, 40.0, 24.0, 16.0);
    assert_eq!(decoded.scene.gaussians_for(&camera).as_ref(), &model.gaussians_for(&camera));
    assert!(decoded.scene.plain_gaussians().is_none());
}

#[test]
fn quantizing_an_mlp_rounds_to_its_power_of_two_steps() {
    let mut rng = SplitMix64(3);
    let m = mlp(&mut rng, 7, 3, 2).dequantize(7, 2);
    let mut noisy = m.clone();
    noisy.w1.iter_mut().for_each(|w| *w += 0.3 / 256.0);
    noisy.b2.iter_mut().for_each(|b| *b -= 0.4 / 1024.0);
    assert_eq!(QuantizedMlp::quantize(&noisy, -8, -10).dequantize(7, 2), m);
}

#[test]
fn empty_anchor_streams_decode() {
    let mut content = random_anchors(0, 2);
    content.features.clear();
    let decoded = stream::decode(&encode(&content)).unwrap();
    assert_eq!(decoded.content, Content::Anchors(Box::new(content)));
}

#[test]
fn corrupt_anchor_sections_are_named() {
    let bytes = encode(&random_anchors(60, 4));
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (with_payload(&bytes, anchor::NETWORKS, |p| p[0] = 0), "feature dimension"),
        (with_payload(&bytes, anchor::NETWORKS, |p| p[1] = 65), "offsets per anchor"),
        (with_payload(&bytes, anchor::NETWORKS, |p| p[3] = 1), "weight step exponent"),
        (with_payload(&bytes, anchor::NETWORKS, |p| p.truncate(12)), "AMLP"),
        (with_payload(&bytes, anchor::ANCHOR_POSITIONS, |p| p.truncate(14)), "APOS"),
        (with_payload(&bytes, anchor::FEATURES, |p| p[0..4].copy_from_slice(&(-1.0f32).to_le_bytes())), "AFEA"),
        (with_payload(&bytes, anchor::OFFSETS, |p| p.truncate(8)), "AOFF"),
        (with_payload(&bytes, anchor::MASKS, |p| p.truncate(1)), "AMSK"),
        (with_payload(&bytes, Tag::HEAD, |p| p[5] = 1), "sh degree"),
    ];
    for (stream_bytes, needle) in cases {
        let Err(err) = stream::decode(&stream_bytes).map(|_| ()) else { panic!("the case naming {needle} decoded") };
        let err = err.to_string();
        assert!(err.contains(needle), "{err} should name {needle}");
    }
    // A plain base's section in an anchor stream is an unknown critical section.
    let mut sections: Vec<(Tag, Vec<u8>)> =
        Container::parse(&bytes).unwrap().sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect();
    sections.push((Tag(*b"POSN"), vec![]));
    let err = stream::decode(&write_container(&sections)).unwrap_err().to_string();
    assert!(err.contains("POSN"), "{err}");
    // A missing section is named.
    sections.retain(|(t, _)| *t != anchor::MASKS && *t != Tag(*b"POSN"));
    let err = stream::decode(&write_container(&sections)).unwrap_err().to_string();
    assert!(err.contains("AMSK"), "{err}");
}

#[test]
fn a_mask_other_than_zero_or_one_is_refused() {
    let mut content = random_anchors(20, 5);
    content.masks.fill(true);
    let bytes = encode(&content);
    // AMSK rewritten with every mask coded as 2.
    let mut sections: Vec<(Tag, Vec<u8>)> =
        Container::parse(&bytes).unwrap().sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect();
    let twos = {
        use pwgs_bitstream::FieldWriter;
        use pwgs_codec::stream::entropy::{FrequencyTable, SymbolEncoder};
        let table = FrequencyTable::fit(&[2]);
        let mut w = FieldWriter::new();
        (0..3).for_each(|_| table.write(&mut w));
        let mut coder = SymbolEncoder::new();
        (0..20 * 3).for_each(|_| coder.value(&table, 2));
        w.extend(&coder.finish());
        w.into_bytes()
    };
    sections.iter_mut().filter(|(t, _)| *t == anchor::MASKS).for_each(|(_, p)| *p = twos.clone());
    let err = stream::decode(&write_container(&sections)).unwrap_err().to_string();
    assert!(err.contains("AMSK") && err.contains("mask value 2"), "{err}");
}

/// SPEC.md section 9: an anchor count whose values cannot fit the stream's bytes is refused
/// before any position is decoded, and a writer pads redundant content to what its count needs.
#[test]
fn the_anchor_count_is_bounded_by_the_stream_length() {
    // 80 + 6 + 4 x 3 = 98 values per anchor: at the most anchors the length allows (one per two
    // bytes) more than the 64 values per anchor that 32 per byte give, so this bound refuses.
    let content = anchors_with_features(40, 80, 6);
    let bytes = encode(&content);
    let most = (bytes.len() / 2) as u32;
    let big = with_payload(&bytes, Tag::HEAD, |p| p[1..5].copy_from_slice(&most.to_le_bytes()));
    let err = stream::decode(&big).unwrap_err().to_string();
    assert!(err.contains("AMLP") && err.contains("values per byte"), "{err}");
    // All-alike anchors code to almost nothing: the stream is padded, and it decodes.
    let mut alike = anchors_with_features(1000, 200, 7);
    alike.features.fill(0);
    alike.offsets.fill(0);
    alike.scaling.fill([0; 6]);
    alike.masks.fill(true);
    for m in &mut alike.mlps {
        [&mut m.w1, &mut m.b1, &mut m.w2, &mut m.b2].into_iter().for_each(|t| t.fill(0));
    }
    let bytes = encode(&alike);
    let per_anchor = anchor::values_per_anchor(200, 3);
    assert!(bytes.len() as u64 >= 1000 * per_anchor / anchor::VALUES_PER_BYTE);
    assert!(Container::parse(&bytes).unwrap().section(stream::PADDING).is_some());
    assert_eq!(stream::decode(&bytes).unwrap().content, Content::Anchors(Box::new(reordered(&alike))));
}

#[test]
fn every_truncation_and_byte_flip_is_an_error_or_a_decode() {
    let bytes = encode(&random_anchors(30, 8));
    for len in 0..bytes.len() {
        let _ = stream::decode(&bytes[..len]);
    }
    flip_bits(&bytes, 1500, 9);
}

/// Flips `count` random bits of `bytes`, one at a time: each result is an error or a stream
/// that decodes consistently.
fn flip_bits(bytes: &[u8], count: usize, seed: u64) {
    let mut rng = SplitMix64(seed);
    for _ in 0..count {
        let mut b = bytes.to_vec();
        let at = (rng.next_u64() % b.len() as u64) as usize;
        b[at] ^= 1 << (rng.next_u64() % 8);
        // Recompute CRCs so that the mutation reaches the payload parsers.
        pwgs_bitstream::reseal(&mut b);
        if let Ok(d) = stream::decode(&b) {
            assert_eq!(d.scene.base, d.content.dequantize());
        }
    }
}

/// A context model for anchors of F = 5, K = 3 on a 6-level grid: random signs, a network
/// whose means spread over tens of units and whose scales are all 1 unit.
fn random_context(seed: u64) -> QuantizedContext {
    let mut rng = SplitMix64(seed);
    let shape = ContextGridShape { levels: vec![1, 2, 4], planes: vec![3], table_log2: 6, channels: 2 };
    let signs = (0..shape.entries(6) * 2).map(|_| rng.next_u64() & 1 == 1).collect();
    let values = anchor_context::predicted_values(5, 3);
    let mut mlp =
        QuantizedMlp { weight_exponent: -4, bias_exponent: -4, ..mlp(&mut rng, shape.context_len(), 8, 2 * values) };
    mlp.w2[values * 8..].fill(0);
    mlp.b2[values..].fill(0);
    QuantizedContext { shape, signs, mlp }
}

/// Anchors whose values lie within a unit of what `context` predicts for them.
fn predictable_anchors(n: usize, context: QuantizedContext, seed: u64) -> QuantizedAnchors {
    let mut content = random_anchors(n, seed);
    let mut rng = SplitMix64(seed ^ 0xc0de);
    let (f, k) = (5, 3);
    let network = ContextNetwork::new(&context, content.grid.depth, (f, k));
    let mut models = Vec::new();
    network.models(&content.positions, &mut models);
    for (i, anchor) in models.chunks_exact(network.values()).enumerate() {
        let mut draw = |t: usize| (anchor[t].mean as f32 / 64.0).round() as i32 + ints(&mut rng, 1, 1.0)[0];
        (0..f).for_each(|c| content.features[i * f + c] = draw(c));
        (0..6).for_each(|c| content.scaling[i][c] = draw(f + c));
        for j in 0..k {
            for a in 0..3 {
                let open = content.masks[i * k + j];
                content.offsets[(i * k + j) * 3 + a] = if open { draw(f + 6 + 3 * j + a) } else { 0 };
            }
        }
    }
    content.context = Some(context);
    content
}

fn attribute_bytes(bytes: &[u8]) -> usize {
    let c = Container::parse(bytes).unwrap();
    [anchor::FEATURES, anchor::SCALING, anchor::OFFSETS].iter().map(|&t| c.section(t).unwrap().payload.len()).sum()
}

#[test]
fn context_coded_streams_round_trip_and_code_predictable_values_smaller() {
    let content = predictable_anchors(400, random_context(12), 13);
    let bytes = encode(&content);
    assert!(Container::parse(&bytes).unwrap().section(anchor_context::CONTEXT).is_some());
    let decoded = stream::decode(&bytes).unwrap();
    assert_eq!(decoded.content, Content::Anchors(Box::new(reordered(&content))));
    // The same values with one model per channel: the spread of the predicted means costs
    // bits that the context model does not pay.
    let plain = QuantizedAnchors { context: None, ..content.clone() };
    let (with, without) = (attribute_bytes(&bytes), attribute_bytes(&encode(&plain)));
    assert!((with as f64) < 0.7 * without as f64, "{with} bytes with the context, {without} without");
}

#[test]
fn corrupt_context_sections_are_named() {
    let bytes = encode(&predictable_anchors(60, random_context(14), 15));
    let context = |edit: &dyn Fn(&mut Vec<u8>)| with_payload(&bytes, anchor_context::CONTEXT, edit);
    let cases: Vec<(Vec<u8>, &str, &str)> = vec![
        (context(&|p| p[0] = 0), "ACTX", "levels"),
        (context(&|p| p[1] = 0), "ACTX", "level"),
        // After the 3 levels: 1 plane level (r = 3), then T and C.
        (context(&|p| p[4] = 17), "ACTX", "plane levels"),
        (context(&|p| p[5] = 25), "ACTX", "plane level"),
        (context(&|p| p[6] = 3), "ACTX", "table log2"),
        (context(&|p| p[7] = 9), "ACTX", "channels"),
        // A dense finest level of 65^3 entries: far more grid than the stream's bytes allow.
        (context(&|p| (p[3], p[6]) = (20, 22)), "ACTX", "exceeds the stream's length"),
        (context(&|p| p.truncate(p.len() / 2)), "ACTX", "coded data"),
        (with_payload(&bytes, anchor::SCALING, |p| p.truncate(6)), "ASCL", "coded data"),
    ];
    for (stream_bytes, tag, needle) in cases {
        let Err(err) = stream::decode(&stream_bytes).map(|_| ()) else { panic!("the case naming {needle} decoded") };
        let err = err.to_string();
        assert!(err.contains(tag) && err.contains(needle), "{err} should name {tag} and {needle}");
    }
    flip_bits(&bytes, 1000, 16);
}

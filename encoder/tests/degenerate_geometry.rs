//! Degenerate geometry in imported models: Gaussians piled on one position,
//! positions towards the ends of binary32, extreme scales and opacities. Each model either
//! encodes, and decodes to the Gaussians the encoder says it kept, or is refused with an error
//! naming the problem; none panics or loops.

use pwgs_codec::stream;
use pwgs_core::gaussians::Gaussians;
use pwgs_encoder::plain::compress::{
    Coding, CompressError, Compressed, QuantizerSettings, StreamContext, compress, reconstruction,
};

/// `n` Gaussians at `at`, Gaussian `i` a little larger than `i - 1` (more important), all
/// visible.
fn piled(n: usize, at: [f32; 3]) -> Gaussians {
    let mut g = Gaussians::with_degree(0);
    for i in 0..n {
        let s = -3.0 + i as f32 * 1e-3;
        g.push(at, [s; 3], [1.0, 0.1, 0.0, 0.0], -1.0, &[0.2, -0.1, 0.4]);
    }
    g
}

fn add(g: &mut Gaussians, at: [f32; 3]) {
    g.push(at, [-2.0; 3], [1.0, 0.0, 0.0, 0.0], 2.0, &[0.0; 3]);
}

fn encode(g: &Gaussians, settings: &QuantizerSettings) -> Result<Compressed, CompressError> {
    compress(g, settings, &StreamContext::from_gaussians(g, [0.0; 3]), None)
}

fn plain(settings: &QuantizerSettings) -> Coding<'_> {
    Coding { settings, weights: None, prune_costs: None }
}

/// What the encoder keeps (indices, increasing) and each kept Gaussian's decoded position, in
/// that order; checked against the stream itself.
fn kept(g: &Gaussians, settings: &QuantizerSettings) -> (Vec<usize>, Vec<[f32; 3]>) {
    let context = StreamContext::from_gaussians(g, [0.0; 3]);
    let c = compress(g, settings, &context, None).unwrap();
    assert_eq!(stream::decode(&c.bytes).unwrap(), c.decoded);
    let (keep, decoded) = reconstruction(g, plain(settings), &context).unwrap();
    assert_eq!(keep.len(), c.decoded.header.gaussian_count as usize);
    assert_eq!(c.crowded + keep.len(), g.len() - c.invisible);
    (keep, decoded.means)
}

#[test]
fn more_than_255_gaussians_at_one_position_keep_the_255_most_important() {
    let at = [1.5, -2.0, 3.0];
    for settings in
        [QuantizerSettings::default(), QuantizerSettings::for_quality(0), QuantizerSettings::for_quality(14)]
    {
        let g = piled(300, at);
        let c = encode(&g, &settings).unwrap();
        assert_eq!((c.decoded.header.gaussian_count, c.crowded), (255, 45));
        let (keep, means) = kept(&g, &settings);
        assert_eq!(keep, (45..300).collect::<Vec<_>>(), "the largest are kept");
        assert!(means.iter().all(|&m| m == at), "one position, exactly");
    }
    // 255 fit in one cell.
    let c = encode(&piled(255, at), &QuantizerSettings::default()).unwrap();
    assert_eq!((c.decoded.header.gaussian_count, c.crowded), (255, 0));
}

#[test]
fn a_pile_beside_other_gaussians_loses_only_its_least_important() {
    let mut g = piled(1000, [0.25, 0.5, 0.75]);
    let others = [[-3.0, 1.0, 2.0], [4.0, -1.0, 0.5], [0.0, 2.5, -2.0], [1.0, 1.0, 1.0], [0.2501, 0.5, 0.75]];
    others.iter().for_each(|&p| add(&mut g, p));
    let (keep, means) = kept(&g, &QuantizerSettings::default());
    let expected: Vec<usize> = (745..1005).collect();
    assert_eq!(keep, expected, "the 255 largest of the pile and every other Gaussian");
    // The grid spans 7 units in 2^24 cells: within a cell, with the cell's and the sum's
    // roundings to binary32.
    for (&i, m) in keep.iter().zip(&means) {
        assert!((0..3).all(|a| (m[a] - g.means[i][a]).abs() <= 2.0 * 7.0 / 16_777_215.0), "{i}: {m:?}");
    }
}

#[test]
fn importance_weights_choose_what_a_pile_keeps() {
    let at = [0.0, 1.0, 2.0];
    let mut g = piled(300, at);
    // Against the scales' order: the first are the heaviest.
    let mut weights: Vec<f32> = (0..300).map(|i| 300.0 - i as f32).collect();
    // Alone, the pile has a one-level grid; with others around it the grid is 24 levels deep
    // and the classes refine it (the pile then crowds a cell of `POSN`'s coarser grid).
    for (k, p) in [[3.0, 0.0, 0.0], [-2.0, 1.0, 0.5], [0.0, -1.0, 4.0]].into_iter().enumerate() {
        add(&mut g, p);
        weights.push([1000.0, 10.0, 0.5][k]);
    }
    for (n, settings) in [(300, QuantizerSettings::for_quality(9)), (303, QuantizerSettings::for_quality(12))] {
        let g = Gaussians {
            means: g.means[..n].to_vec(),
            log_scales: g.log_scales[..n].to_vec(),
            rotations: g.rotations[..n].to_vec(),
            opacity_logits: g.opacity_logits[..n].to_vec(),
            sh_degree: 0,
            sh: g.sh[..3 * n].to_vec(),
        };
        let context = StreamContext::from_gaussians(&g, [0.0; 3]);
        let coding = Coding { settings: &settings, weights: Some(&weights[..n]), prune_costs: None };
        let (keep, decoded) = reconstruction(&g, coding, &context).unwrap();
        assert_eq!(keep, (0..255).chain(300..n).collect::<Vec<_>>());
        assert!(decoded.means[..255].iter().all(|&m| (0..3).all(|a| (m[a] - at[a]).abs() < 1e-4)));
        let c = pwgs_encoder::plain::compress::compress_to_size(&g, coding, &context, None, usize::MAX).unwrap();
        assert_eq!((c.decoded.header.gaussian_count as usize, c.crowded), (keep.len(), 45));
        assert_eq!(stream::decode(&c.bytes).unwrap(), c.decoded);
    }
}

#[test]
fn a_pile_within_one_cell_of_a_grid_stretched_by_an_outlier_is_thinned() {
    // 300 Gaussians within 3e-4 of each other and one 1e30 away: the 2^24 cells are 6e22 wide.
    let mut g = piled(300, [0.0; 3]);
    for i in 0..300 {
        g.means[i] = [i as f32 * 1e-6, 0.5, -0.5];
    }
    add(&mut g, [1e30, 0.0, 0.0]);
    let (keep, means) = kept(&g, &QuantizerSettings::default());
    assert_eq!(keep, (45..301).collect::<Vec<_>>());
    let far = means.last().unwrap();
    assert!((far[0] - 1e30).abs() <= 2.0 * 1e30 / 16_777_215.0, "{far:?}");
}

#[test]
fn positions_up_to_the_end_of_binary32_on_one_side_encode() {
    let mut g = piled(20, [0.0; 3]);
    for i in 0..20 {
        g.means[i] = [i as f32 * 0.1, -1.0, 1.0];
    }
    for x in [1e19, 4.2e25, 1e30, 3e38] {
        add(&mut g, [x, x / 2.0, 7.0]);
    }
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    // The 95th percentile of the distances (the 23rd of 24) is 1e30's.
    assert!(context.scale.is_finite() && context.scale > 1e30, "{}", context.scale);
    let (keep, means) = kept(&g, &QuantizerSettings::default());
    assert_eq!(keep.len(), 24);
    for (&i, m) in keep.iter().zip(&means) {
        assert!((0..3).all(|a| (m[a] - g.means[i][a]).abs() <= 2.0 * 3e38 / 16_777_215.0), "{i}: {m:?}");
    }
}

#[test]
fn positions_a_grid_cannot_reach_are_refused_by_name() {
    // The grid's origin magnitude plus its extent stays below binary32's largest: spanning
    // -1.65e38 to 1.65e38 (a SOG's +-88 in log space) reaches 4.95e38.
    for (low, high) in [(-1.65e38, 1.65e38), (-3e38, 3e38), (f32::MAX, f32::MAX), (f32::MIN, 0.0)] {
        let mut g = piled(10, [0.0; 3]);
        add(&mut g, [low, 0.0, 0.0]);
        add(&mut g, [high, 1.0, 0.0]);
        let context = StreamContext::from_gaussians(&g, [0.0; 3]);
        assert!(context.scale.is_finite() && context.scale > 0.0);
        let err = encode(&g, &QuantizerSettings::default()).err().unwrap();
        assert!(matches!(err, CompressError::Span { .. }), "{err}");
        assert!(err.to_string().contains("the stream's position grid cannot hold them"), "{err}");
    }
    // Half of binary32's largest on one side fits (a grid from 0 reaches just past it; one
    // reaching a position at the largest itself would reach beyond).
    let mut g = piled(10, [0.0; 3]);
    add(&mut g, [f32::MAX / 2.0, 0.0, 0.0]);
    assert_eq!(encode(&g, &QuantizerSettings::default()).unwrap().decoded.header.gaussian_count, 11);
}

#[test]
fn extreme_attributes_encode() {
    let mut g = Gaussians::with_degree(1);
    let sh = |v: f32| [v; 12];
    let big = f32::MAX;
    g.push([0.0; 3], [88.0, -88.0, 88.7], [1.0, 0.0, 0.0, 0.0], 1e30, &sh(1.0));
    g.push([1.0, 0.0, 0.0], [big, -big, 0.0], [big, -big, big, 0.0], big, &sh(big));
    g.push([0.0, 1.0, 0.0], [-big; 3], [0.0; 4], 20.0, &sh(-big));
    g.push([0.0, 0.0, 1.0], [0.0; 3], [1e-40, 0.0, 0.0, 0.0], -big, &sh(0.0));
    g.push([1e-40, -1e-40, 0.0], [0.0; 3], [1.0; 4], 0.0, &sh(1e-40));
    for quality in [0, 5, 14] {
        let c = encode(&g, &QuantizerSettings::for_quality(quality)).unwrap();
        assert_eq!((c.decoded.header.gaussian_count, c.invisible), (4, 1), "quality {quality}");
    }
}

#[test]
fn positions_a_denormal_apart_encode() {
    let mut g = Gaussians::with_degree(0);
    for i in 0..300 {
        g.push([i as f32 * 1e-45, 0.0, 0.0], [0.0; 3], [1.0, 0.0, 0.0, 0.0], 0.0, &[0.0; 3]);
    }
    let c = encode(&g, &QuantizerSettings::default()).unwrap();
    // All within the smallest normal cell: one cell's worth.
    assert_eq!((c.decoded.header.gaussian_count, c.crowded), (255, 45));
}

//! Importance classes (SPEC.md section 6.5) as the encoder uses them: weights from renders,
//! classes from weights, and what they buy on the views the weights came from.

use pwgs_codec::stream::Content;
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};
use pwgs_encoder::metrics::psnr::psnr;
use pwgs_encoder::plain::compress::{Coding, QuantizerSettings, StreamContext, compress_to_size};
use pwgs_encoder::plain::importance::Importance;
use pwgs_render::raster::{RenderOptions, render};

/// Random Gaussians in front of [`camera`], 4000 of them, so that many hide others.
fn scene() -> Gaussians {
    random_gaussians(&mut SplitMix64(7), 4000, 0, [-4.5, -2.5])
}

fn camera() -> Camera {
    axis_camera(160, 120, 150.0, 150.0, 80.0, 60.0)
}

/// (bytes, PSNR against the model's render) of the stream at `quality`, with or without classes.
fn point(g: &Gaussians, quality: u8, weights: Option<&[f32]>) -> (usize, f64) {
    let context = StreamContext::from_gaussians(g, [0.0; 3]);
    let settings = QuantizerSettings::for_quality(quality);
    let c = compress_to_size(g, Coding { settings: &settings, weights, prune_costs: None }, &context, None, usize::MAX)
        .unwrap();
    let options = RenderOptions::default();
    let decoded = render(c.decoded.scene.plain_gaussians().unwrap(), &camera(), &options);
    (c.bytes.len(), psnr(&decoded, &render(g, &camera(), &options)))
}

#[test]
fn classes_beat_uniform_steps_on_the_views_they_come_from() {
    let g = scene();
    let weights = Importance::of_views(&g, (&[camera()], &[]), &RenderOptions::default()).weights;
    let uniform: Vec<(usize, f64)> = (0..=12).map(|q| point(&g, q, None)).collect();
    // The uniform curve's PSNR at `bytes`, linear between its points.
    let at = |bytes: usize| {
        let w = uniform.windows(2).find(|w| w[0].0 <= bytes && bytes <= w[1].0).expect("inside the curve");
        let t = (bytes - w[0].0) as f64 / (w[1].0 - w[0].0) as f64;
        w[0].1 + t * (w[1].1 - w[0].1)
    };
    for q in [4u8, 6, 8] {
        let (bytes, p) = point(&g, q, Some(&weights));
        // Measured: 3.6 to 4.8 dB above the curve at these qualities.
        assert!(p > at(bytes) + 1.0, "quality {q}: {bytes} bytes at {p:.2} dB, uniform steps {:.2} dB", at(bytes));
    }
}

/// A class view of a quarter of the first's pixels (half the focal length: the same view at half
/// the resolution) counts as much as a full one: each Gaussian's weight about doubles.
#[test]
fn a_smaller_class_view_counts_as_a_full_one() {
    let g = scene();
    let options = RenderOptions::default();
    let half = axis_camera(80, 60, 75.0, 75.0, 40.0, 30.0);
    let one = Importance::of_views(&g, (&[camera()], &[]), &options).weights;
    let both = Importance::of_views(&g, (&[camera(), half], &[]), &options).weights;
    let (one, both): (f64, f64) = (one.iter().map(|&w| f64::from(w)).sum(), both.iter().map(|&w| f64::from(w)).sum());
    // Unscaled, the half view would add a quarter (sum ratio 1.25).
    assert!((both / one - 2.0).abs() < 0.1, "{both} against {one}");
}

#[test]
fn unseen_gaussians_take_the_coarsest_class() {
    let mut g = scene();
    let mut rng = SplitMix64(8);
    for _ in 0..200 {
        let mean = [rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-4.0, -2.0)];
        g.push(mean, [-3.0; 3], [1.0, 0.0, 0.0, 0.0], 2.0, &[0.3; 3]);
    }
    let importance = Importance::of_views(&g, (&[camera()], &[]), &RenderOptions::default());
    let weights = &importance.weights;
    let unseen = weights.iter().filter(|&&w| w == 0.0).count();
    assert!(unseen >= 200, "only {unseen} Gaussians unseen");
    let compressed = |quality: u8, prune: bool| {
        let context = StreamContext::from_gaussians(&g, [0.0; 3]);
        let settings = QuantizerSettings::for_quality(quality);
        let prune_costs = prune.then_some(&importance.prune_costs[..]);
        let coding = Coding { settings: &settings, weights: Some(weights), prune_costs };
        compress_to_size(&g, coding, &context, None, usize::MAX).unwrap()
    };
    let classes_at = |quality: u8| match compressed(quality, false).decoded.content {
        Content::Plain(content) => content.classes,
        Content::Anchors(_) => panic!("not a plain stream"),
    };
    let classes = classes_at(8).expect("classes");
    assert_eq!(classes.factors.len(), 5);
    // (The decoded order is the octree's, so count rather than match.)
    let last = classes.of.iter().filter(|&&k| k == 4).count();
    assert!(last >= unseen, "{last} Gaussians in the last class, {unseen} unseen");
    // Pruned instead: gone, and counted.
    let pruned = compressed(8, true);
    assert!(pruned.faint >= unseen && pruned.invisible == 0, "{} faint, {unseen} unseen", pruned.faint);
    assert_eq!(pruned.decoded.header.gaussian_count as usize, g.len() - pruned.faint);
    let means = &pruned.decoded.scene.plain_gaussians().unwrap().means;
    assert!(means.iter().all(|m| m[2] > 0.0), "a Gaussian behind the camera was kept");
    // A target size drops the least weighty first: the unseen ones go before any seen one
    // (ranked by opacity times area instead, these bright ones would stay).
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let settings = QuantizerSettings::for_quality(8);
    let coding = Coding { settings: &settings, weights: Some(weights), prune_costs: None };
    let target = compressed(8, false).bytes.len() * 9 / 10;
    let fitted = compress_to_size(&g, coding, &context, None, target).unwrap();
    assert!(fitted.pruned >= unseen, "{} pruned, {unseen} unseen", fitted.pruned);
    let means = &fitted.decoded.scene.plain_gaussians().unwrap().means;
    assert!(means.iter().all(|m| m[2] > 0.0), "an unseen Gaussian was kept");
    // Quality 2 allows classes 0 and 1 only: the coarsest steps are about quality 0's.
    assert_eq!(classes_at(2).expect("classes").factors.len(), 2);
    assert!(classes_at(0).is_none(), "quality 0 has one class: no IMPC");
}

#[test]
fn weights_of_the_wrong_length_are_refused() {
    let g = scene();
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let settings = QuantizerSettings::default();
    let short = vec![1.0; 10];
    let coding = Coding { settings: &settings, weights: Some(&short), prune_costs: None };
    assert!(compress_to_size(&g, coding, &context, None, usize::MAX).is_err());
}

#[test]
fn more_gaussians_in_one_place_than_a_cell_holds_keep_the_most_important_not_a_hang() {
    // 300 copies of one Gaussian: no grid separates them (a cell holds at most 255), with the
    // classes' coarser POSN grid as without; the cell keeps its 255 most important (by weight,
    // or, all alike, the first) and the others are dropped.
    let mut g = Gaussians::with_degree(0);
    for _ in 0..300 {
        g.push([0.0, 0.0, 3.0], [-3.0; 3], [1.0, 0.0, 0.0, 0.0], 2.0, &[0.3; 3]);
    }
    g.push([1.0, 1.0, 4.0], [-3.0; 3], [1.0, 0.0, 0.0, 0.0], 2.0, &[0.3; 3]);
    let weights: Vec<f32> = (0..g.len()).map(|i| 1.0 + i as f32).collect();
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let settings = QuantizerSettings::for_quality(10);
    for w in [None, Some(&weights[..])] {
        let coding = Coding { settings: &settings, weights: w, prune_costs: None };
        let c = compress_to_size(&g, coding, &context, None, usize::MAX).unwrap();
        assert_eq!((c.decoded.header.gaussian_count, c.crowded), (256, 45));
    }
}

/// A patch of small faint Gaussians, each too faint to matter alone, which together are most of
/// what a close view of them shows (fine texture): pruning must keep them when that view is one
/// it holds on, and a wide view alone, where the patch is a few pixels, lets them go.
#[test]
fn pruning_holds_on_every_view_it_is_measured_on() {
    let mut g = scene();
    let mut rng = SplitMix64(9);
    for _ in 0..3000 {
        let mean = [rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), 1.5];
        g.push(mean, [-6.5; 3], [1.0, 0.0, 0.0, 0.0], -1.0, &[rng.uniform(-1.0, 1.0); 3]);
    }
    let wide = camera();
    // 40 times the focal length: the patch fills the view.
    let close = axis_camera(160, 120, 6000.0, 6000.0, 80.0, 60.0);
    let options = RenderOptions::default();
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let settings = QuantizerSettings::for_quality(10);
    // (Gaussians pruned, PSNR of the close view) with pruning costs from the wide view and
    // `others`, or without pruning.
    let coded = |others: Option<&[Camera]>| {
        let importance = Importance::of_views(&g, (&[wide], others.unwrap_or(&[])), &options);
        let costs = others.map(|_| &importance.prune_costs[..]);
        let coding = Coding { settings: &settings, weights: Some(&importance.weights), prune_costs: costs };
        let c = compress_to_size(&g, coding, &context, None, usize::MAX).unwrap();
        let decoded = render(c.decoded.scene.plain_gaussians().unwrap(), &close, &options);
        (c.faint, psnr(&decoded, &render(&g, &close, &options)))
    };
    let (unpruned, wide_only, close_too) = (coded(None), coded(Some(&[])), coded(Some(&[close])));
    // Measured: 28.70 dB unpruned (the patch in the coarsest classes); the wide view alone
    // prunes 3,892 Gaussians (14.33 dB), with the close view 2,097 (29.55 dB: the classes'
    // reference weight moves with what is pruned).
    assert!(wide_only.0 > 3000, "the wide view alone prunes {} Gaussians", wide_only.0);
    assert!(wide_only.1 < unpruned.1 - 6.0, "wide view alone: {wide_only:?}, unpruned {unpruned:?}");
    assert!(
        close_too.0 > 1000 && close_too.1 > unpruned.1 - 0.5,
        "close view kept: {close_too:?}, unpruned {unpruned:?}"
    );
}

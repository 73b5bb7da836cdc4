//! The encoder's quantizer and writer: what it drops, what it keeps, how faithful the decoded
//! stream is, and that its own reconstruction is the decoder's.

use pwgs_codec::stream;
use pwgs_core::gaussians::sh_coeff_count;
use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};
use pwgs_encoder::metrics::psnr::psnr;
use pwgs_encoder::plain::compress::{
    Coding, CompressError, QuantizerSettings, StreamContext, compress, compress_to_size,
};
use pwgs_render::raster::{RenderOptions, render};

fn scene() -> pwgs_core::gaussians::Gaussians {
    let mut g = random_gaussians(&mut SplitMix64(5), 3000, 3, [-4.5, -2.5]);
    let k = sh_coeff_count(3) * 3;
    for i in 0..g.len() {
        // Band 3 is empty, as in models trained without it; every 10th Gaussian is invisible.
        g.sh[i * k + 27..(i + 1) * k].iter_mut().for_each(|v| *v = 0.0);
        if i % 10 == 0 {
            g.opacity_logits[i] = -7.0;
        }
    }
    g
}

#[test]
fn default_stream_is_faithful_and_drops_what_the_scene_does_not_need() {
    let g = scene();
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let c = compress(&g, &QuantizerSettings::default(), &context, None).unwrap();
    assert_eq!(c.invisible, 300);
    assert_eq!(c.decoded.header.gaussian_count, 2700);
    assert_eq!(c.decoded.header.sh_degree, 2, "the empty third band is dropped");
    // The encoder's reconstruction is exactly what decoding its bytes gives.
    assert_eq!(stream::decode(&c.bytes).unwrap(), c.decoded);
    // This scene is harsher than a trained model (random colors of +/-1.5 in SH, random
    // view-dependent bands, overlapping Gaussians of random size): the default keeps it above
    // 35 dB, quality 8 above 40 dB (a real model, guitar_inria.ply, is above 45 dB at the default).
    let camera = axis_camera(160, 120, 150.0, 150.0, 80.0, 60.0);
    let options = RenderOptions::default();
    let reference = render(&g, &camera, &options);
    let p = psnr(&render(c.decoded.scene.plain_gaussians().unwrap(), &camera, &options), &reference);
    assert!(p > 35.0, "decoded render PSNR {p:.2} dB at the default quality");
    let fine = compress(&g, &QuantizerSettings::for_quality(8), &context, None).unwrap();
    let p = psnr(&render(fine.decoded.scene.plain_gaussians().unwrap(), &camera, &options), &reference);
    assert!(p > 40.0, "decoded render PSNR {p:.2} dB at quality 8");
    // Rotations are coded in the frame nearest the identity (`rotation_frame`): w is always
    // the largest component, far above the others (random rotations have it in a quarter).
    let rotations = &c.decoded.scene.plain_gaussians().unwrap().rotations;
    assert!(rotations.iter().all(|q| q[1..].iter().all(|c| c.abs() < 0.5 * q[0])), "a rotation off its frame");
    let raw = pwgs_core::ply::inria_ply_size(&g);
    assert!(c.bytes.len() * 8 < raw, "{} bytes against {raw} as PLY", c.bytes.len());
}

#[test]
fn the_quality_knob_trades_size_for_fidelity() {
    let g = scene();
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let camera = axis_camera(160, 120, 150.0, 150.0, 80.0, 60.0);
    let options = RenderOptions::default();
    let reference = render(&g, &camera, &options);
    let points: Vec<(usize, f64)> = [1u8, 5, 9]
        .iter()
        .map(|&q| {
            let c = compress(&g, &QuantizerSettings::for_quality(q), &context, None).unwrap();
            (c.bytes.len(), psnr(&render(c.decoded.scene.plain_gaussians().unwrap(), &camera, &options), &reference))
        })
        .collect();
    assert!(points.windows(2).all(|w| w[0].0 < w[1].0 && w[0].1 < w[1].1), "{points:?}");
}

#[test]
fn non_finite_models_are_refused() {
    let mut g = scene();
    g.log_scales[17][1] = f32::NAN;
    let context = StreamContext { center: [0.0; 3], scale: 1.0, background: [0.0; 3] };
    let err = compress(&g, &QuantizerSettings::default(), &context, None).err().unwrap();
    assert!(matches!(err, CompressError::NonFinite("scale")), "{err}");
}

#[test]
fn gaussians_sharing_a_cell_refine_the_grid() {
    let mut g = random_gaussians(&mut SplitMix64(8), 400, 0, [-4.0, -3.0]);
    // 300 Gaussians 1e-4 apart: one cell at the default resolution, more than a cell may hold.
    for i in 0..300 {
        g.means[i] = [0.1 + i as f32 * 1e-4, 0.0, 3.0];
    }
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let c = compress(&g, &QuantizerSettings::default(), &context, None).unwrap();
    assert_eq!(c.decoded.scene.plain_gaussians().unwrap().len(), g.len());
}

#[test]
fn quality_steps_are_exact_powers_of_sqrt2() {
    let default = QuantizerSettings::default();
    for q in 0..=pwgs_encoder::plain::compress::MAX_QUALITY {
        let s = QuantizerSettings::for_quality(q);
        let k = 5 - i32::from(q);
        // sqrt(2)^k: a power of two, times SQRT_2 for odd k.
        let expected = 2f32.powi(k.div_euclid(2)) * if k.rem_euclid(2) == 1 { std::f32::consts::SQRT_2 } else { 1.0 };
        assert_eq!(s.log_scale_step, default.log_scale_step * expected, "quality {q}");
        assert_eq!(s.band_steps[2], default.band_steps[2] * expected, "quality {q}");
        let bits = [10, 10, 11, 11, 12, 12, 13, 13, 14, 14, 15, 15, 16, 16, 17][usize::from(q)];
        assert_eq!(s.position_bits, bits, "quality {q}");
        // Importance classes, a factor 2 apart: as many as make the coarsest class about quality
        // 0's steps, at most 7.
        assert_eq!(s.importance_classes, (q.div_ceil(2) + 1).min(7), "quality {q}");
    }
    assert_eq!(QuantizerSettings::for_quality(200), QuantizerSettings::for_quality(14), "clamped");
}

/// The same model gives the same bytes whatever the number of threads (docs/architecture.md section 3, rule 4).
#[test]
fn stream_bytes_do_not_depend_on_the_thread_count() {
    let g = scene();
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let bytes = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| compress(&g, &QuantizerSettings::for_quality(7), &context, None).unwrap().bytes)
    };
    let one = bytes(1);
    assert_eq!(bytes(2), one);
    assert_eq!(bytes(5), one);
}

#[test]
fn a_target_size_drops_the_least_important_gaussians() {
    let g = scene();
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let settings = QuantizerSettings::default();
    let full = compress(&g, &settings, &context, None).unwrap();
    assert_eq!(full.pruned, 0);
    let roomy = compress_to_size(
        &g,
        Coding { settings: &settings, weights: None, prune_costs: None },
        &context,
        None,
        full.bytes.len(),
    )
    .unwrap();
    assert_eq!((roomy.bytes, roomy.pruned), (full.bytes.clone(), 0), "a stream that fits is left whole");
    for target in [full.bytes.len() * 2 / 3, full.bytes.len() / 4] {
        let c = compress_to_size(
            &g,
            Coding { settings: &settings, weights: None, prune_costs: None },
            &context,
            None,
            target,
        )
        .unwrap();
        assert!(c.bytes.len() <= target, "{} bytes for a target of {target}", c.bytes.len());
        // Within about a Gaussian's worth of bytes (some tens) of the target.
        assert!(c.bytes.len() + 200 > target, "{} bytes for a target of {target}", c.bytes.len());
        assert_eq!(c.decoded.header.gaussian_count as usize + c.pruned, full.decoded.header.gaussian_count as usize);
        // The kept Gaussians are the most visible: the mean opacity rises as more are dropped.
        let mean_logit = |d: &stream::Decoded| {
            d.scene.plain_gaussians().unwrap().opacity_logits.iter().sum::<f32>()
                / d.scene.plain_gaussians().unwrap().opacity_logits.len() as f32
        };
        assert!(mean_logit(&c.decoded) > mean_logit(&full.decoded));
    }
    let err =
        compress_to_size(&g, Coding { settings: &settings, weights: None, prune_costs: None }, &context, None, 50)
            .err()
            .unwrap();
    assert!(matches!(err, CompressError::TargetTooSmall { target: 50, .. }), "{err}");
}

/// Colours as differences (SPEC.md 6.6) where they code smaller: on grey colours, not on the
/// random ones.
#[test]
fn grey_colours_are_coded_as_differences() {
    let has_differences = |g: &pwgs_core::gaussians::Gaussians| {
        let context = StreamContext::from_gaussians(g, [0.0; 3]);
        let c = compress(g, &QuantizerSettings::default(), &context, None).unwrap();
        let container = pwgs_bitstream::Container::parse(&c.bytes).unwrap();
        container.section(pwgs_codec::stream::colour_differences::COLOUR_DIFFERENCES).is_some()
    };
    let mut g = scene();
    assert!(!has_differences(&g), "random colours");
    let k = sh_coeff_count(g.sh_degree) * 3;
    for i in 0..g.len() {
        // Every coefficient grey: r = b = g.
        for coefficient in g.sh[i * k..(i + 1) * k].chunks_exact_mut(3) {
            coefficient[0] = coefficient[1];
            coefficient[2] = coefficient[1];
        }
    }
    assert!(has_differences(&g), "grey colours");
}

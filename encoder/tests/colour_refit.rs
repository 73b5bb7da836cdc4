//! `--refit-colours`: colours refitted to the quantized geometry render closer to the model on
//! the views they were fitted on, and change nothing but the colours.

use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};
use pwgs_encoder::metrics::psnr::psnr;
use pwgs_encoder::plain::colour_refit::{FULL_REFIT, refit_colours};
use pwgs_encoder::plain::compress::{Coding, QuantizerSettings, StreamContext, compress_to_size, reconstruction};
use pwgs_encoder::plain::importance::Importance;
use pwgs_render::raster::{RenderOptions, render};

#[test]
fn refitted_colours_render_closer_with_the_same_geometry() {
    let g = random_gaussians(&mut SplitMix64(21), 2000, 1, [-4.5, -2.5]);
    let cameras = [axis_camera(160, 120, 150.0, 150.0, 80.0, 60.0), axis_camera(160, 120, 150.0, 150.0, 70.0, 50.0)];
    let options = RenderOptions::default();
    let weights = Importance::of_views(&g, (&cameras, &[]), &options).weights;
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let settings = QuantizerSettings::for_quality(5);
    let coding = Coding { settings: &settings, weights: Some(&weights), prune_costs: None };
    let (refitted, outcome) =
        refit_colours((&g, &g), coding, &context, (&cameras, &options), (FULL_REFIT, &|| {})).unwrap();
    // Conjugate gradients never go uphill; rounding a quarter of the colours does, then the
    // refit of the others climbs back down.
    assert_eq!(outcome.mse_after.len(), 8 + 3 * 3, "8 iterations, then 3 after each of 3 roundings");
    for run in
        [&outcome.mse_after[..8], &outcome.mse_after[8..11], &outcome.mse_after[11..14], &outcome.mse_after[14..]]
    {
        assert!(run.windows(2).all(|w| w[1] <= w[0]), "{outcome:?}");
    }
    // Measured: 4.5e-4 -> 7.1e-5 on the linear model.
    assert!(outcome.mse_after[7] < 0.25 * outcome.mse_before, "{outcome:?}");

    let plain = compress_to_size(&g, coding, &context, None, usize::MAX).unwrap();
    let refit = compress_to_size(&refitted, coding, &context, None, usize::MAX).unwrap();
    let (a, b) = (plain.decoded.scene.plain_gaussians().unwrap(), refit.decoded.scene.plain_gaussians().unwrap());
    assert_eq!(
        (&a.means, &a.log_scales, &a.rotations, &a.opacity_logits),
        (&b.means, &b.log_scales, &b.rotations, &b.opacity_logits)
    );
    let per_gaussian = a.coeffs_per_channel() * 3;
    let rest = |x: &pwgs_core::gaussians::Gaussians| -> Vec<f32> {
        x.sh.chunks(per_gaussian).flat_map(|c| c[3..].to_vec()).collect()
    };
    assert_eq!(rest(a), rest(b), "only the DC terms change");
    // Three turns rounded three of every four kept Gaussians' colours to what the stream holds:
    // the stream codes exactly the refitted value (the reconstruction is in the model's order).
    let (keep, coded) = reconstruction(&refitted, coding, &context).unwrap();
    let dc = |x: &pwgs_core::gaussians::Gaussians, i: usize| x.sh_of(i)[..3].to_vec();
    assert!((0..keep.len()).filter(|r| r % 4 != 3).all(|r| dc(&coded, r) == dc(&refitted, keep[r])));
    let unrounded = (3..keep.len()).step_by(4).filter(|&r| dc(&coded, r) != dc(&refitted, keep[r])).count();
    assert!(unrounded > keep.len() / 8, "the last quarter is left to the stream's quantizer: {unrounded}");
    for camera in &cameras {
        let truth = render(&g, camera, &options);
        let (before, after) = (psnr(&render(a, camera, &options), &truth), psnr(&render(b, camera, &options), &truth));
        assert!(after > before + 2.0, "{before:.2} dB -> {after:.2} dB");
    }
}

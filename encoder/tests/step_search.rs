//! `--search-steps`: the per-model search of the quantizer's balance keeps the quality level's
//! error on its views and finds fewer bytes where the model lets it.

use pwgs_core::gaussians::Gaussians;
use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};
use pwgs_encoder::plain::compress::{QuantizerSettings, StreamContext};
use pwgs_encoder::plain::importance::Importance;
use pwgs_encoder::plain::step_search::{KNOBS, Notches, Probe, search};
use pwgs_render::raster::RenderOptions;

/// Round Gaussians (three equal scales): their rotation cannot show in any render.
fn round_gaussians() -> Gaussians {
    let mut g = random_gaussians(&mut SplitMix64(11), 1500, 0, [-4.0, -2.5]);
    for s in &mut g.log_scales {
        *s = [s[0]; 3];
    }
    g
}

#[test]
fn rotations_of_round_gaussians_go_to_the_coarsest_notch() {
    let g = round_gaussians();
    let cameras = [axis_camera(160, 120, 150.0, 150.0, 80.0, 60.0)];
    let options = RenderOptions::default();
    let weights = Importance::of_views(&g, (&cameras, &[]), &options).weights;
    let context = StreamContext::from_gaussians(&g, [0.0; 3]);
    let probe = Probe {
        gaussians: &g,
        weights: &weights,
        prune_costs: None,
        context: &context,
        cameras: &cameras,
        options: &options,
    };
    let outcome = search(&probe, &QuantizerSettings::for_quality(6)).unwrap();
    let rotation = KNOBS.iter().position(|&k| k == "rotation").unwrap();
    // Coarser rotations cost no error: the search takes every notch it may.
    assert_eq!(outcome.notches.0[rotation], 4, "{outcome:?}");
    assert!(outcome.after.bytes < outcome.before.bytes, "{outcome:?}");
    assert!(outcome.after.mse <= outcome.before.mse, "{outcome:?}");
    assert_eq!(outcome.settings, outcome.notches.apply(&QuantizerSettings::for_quality(6)));
}

#[test]
fn notches_move_each_setting_by_its_factor() {
    let base = QuantizerSettings::for_quality(8);
    assert_eq!(Notches::default().apply(&base), base);
    let moved = Notches([1, 2, -1, -2, 1, 1, -1]).apply(&base);
    let sqrt2 = std::f32::consts::SQRT_2;
    assert_eq!(moved.log_scale_step, base.log_scale_step * sqrt2);
    assert_eq!(moved.rotation_step, base.rotation_step * 2.0);
    // sqrt(2)^-1 as the settings build it: 2^-1 times sqrt(2).
    assert_eq!(moved.opacity_step, base.opacity_step * (0.5 * sqrt2));
    assert_eq!((moved.dc_step, moved.band_steps[1]), (base.dc_step / 2.0, base.band_steps[1] / 2.0));
    // A notch coarser: half a bit fewer, that is a bit fewer and then half a bit more.
    assert_eq!((moved.position_bits, moved.position_half_bit), (base.position_bits - 1, true));
    assert_eq!(moved.class_spread, base.class_spread + 1);
    assert_eq!(moved.prune_budget, base.prune_budget / 2.0);
    let finer = Notches([0, 0, 0, 0, -3, 0, 0]).apply(&base);
    assert_eq!((finer.position_bits, finer.position_half_bit), (base.position_bits + 1, true));
}

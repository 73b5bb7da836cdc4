//! The trained splat files in `../shared/scenes/splats` load (see `shared_data` for when an
//! absent file skips and when it fails).

mod shared_data;

use pwgs_core::ply::read_gaussians;

#[test]
fn guitar_inria_layout_loads_with_its_clamped_opacities() {
    let Some(path) = shared_data::path("scenes/splats/guitar_inria.ply") else { return };
    let loaded = read_gaussians(&path).unwrap();
    let g = &loaded.gaussians;
    assert_eq!(g.len() + loaded.dropped_non_finite, 90_854);
    assert_eq!(loaded.dropped_non_finite, 0);
    assert!(g.is_consistent());
    // The source's infinite opacities were clamped to a logit of +/-20 before it was shared.
    assert!(g.opacity_logits.iter().any(|&o| o == 20.0 || o == -20.0));
    assert!(g.means.iter().flatten().chain(&g.sh).all(|v| v.is_finite()));
}

#[test]
fn biker_reordered_properties_without_f_rest_load_by_name() {
    let Some(path) = shared_data::path("scenes/splats/biker.ply") else { return };
    let loaded = read_gaussians(&path).unwrap();
    let g = &loaded.gaussians;
    assert_eq!(g.len(), 152_746);
    assert_eq!(g.sh_degree, 0, "no f_rest properties: degree 0");
    // Quaternions read from rot_0..rot_3 by name: mostly unit length.
    let unit = g.rotations.iter().filter(|q| (q.iter().map(|v| v * v).sum::<f32>().sqrt() - 1.0).abs() < 0.01).count();
    assert!(unit * 10 > g.len() * 9, "rotations were not read by name ({unit} of {} unit)", g.len());
    // Scales are log-scales of a real capture: mostly negative (sub-unit sizes).
    let small = g.log_scales.iter().flatten().filter(|&&s| s < 0.0).count();
    assert!(small * 10 > g.len() * 3 * 8);
}

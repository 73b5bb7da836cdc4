//! The f32 projection the rasterizer uses against the f64 projection it is checked by: the
//! same Gaussians culled, splats within f32's rounding, and the f64 projection wherever f32
//! cannot decide.

mod common;

use common::{Rng, camera, random_gaussians};
use glam::{Mat3, Vec3};
use pwgs_core::camera::{Camera, Intrinsics};
use pwgs_core::gaussians::Gaussians;
use pwgs_render::raster::project::{ProjectionSettings, Projector, Splat, project_precise};

/// Relative tolerance: f32's unit roundoff (6e-8) times a chain of a few dozen operations (the
/// largest seen here is about 2e-6, in the conic).
const TOL: f32 = 4e-6;

/// Whether the f32 splat is the f64 one up to f32 rounding: every field against its own scale
/// (the conic's cross term against sqrt(xx yy), which it never exceeds, since it cancels).
fn assert_close(fast: &Splat, precise: &Splat, fx: f32, what: &str) {
    let near = |a: f32, b: f32, scale: f32| (a - b).abs() <= TOL * scale;
    assert_eq!(fast.index, precise.index, "{what}");
    for k in 0..2 {
        assert!(near(fast.mean[k], precise.mean[k], precise.mean[k].abs() + fx), "{what}: mean {fast:?} {precise:?}");
    }
    let [c0, c1, c2] = precise.conic;
    let cross = (c0 * c2).sqrt();
    assert!(
        near(fast.conic[0], c0, c0) && near(fast.conic[1], c1, cross) && near(fast.conic[2], c2, c2),
        "{what}: conic {:?} {:?}",
        fast.conic,
        precise.conic
    );
    let [l11, l21, l22] = precise.cholesky;
    assert!(
        near(fast.cholesky[0], l11, l11) && near(fast.cholesky[1], l21, c2.sqrt()) && near(fast.cholesky[2], l22, l22),
        "{what}: cholesky {:?} {:?}",
        fast.cholesky,
        precise.cholesky
    );
    assert!(near(fast.opacity, precise.opacity, precise.opacity), "{what}: opacity");
    assert!(near(fast.depth, precise.depth, precise.depth), "{what}: depth");
    for k in 0..3 {
        assert!(near(fast.color[k], precise.color[k], 1.0), "{what}: color {:?} {:?}", fast.color, precise.color);
    }
    // A box edge moves only where the ellipse's extent lands within rounding of a pixel edge.
    for k in 0..4 {
        assert!(fast.bbox[k].abs_diff(precise.bbox[k]) <= 1, "{what}: box {:?} {:?}", fast.bbox, precise.bbox);
    }
}

/// Projects every Gaussian both ways; returns how many were visible.
fn compare(g: &Gaussians, cam: &Camera, what: &str) -> usize {
    let settings = ProjectionSettings::default();
    let projector = Projector::new(cam, &settings);
    let mut visible = 0;
    for i in 0..g.len() {
        match (projector.project(g, i), project_precise(g, i, cam, &settings)) {
            (Some(fast), Some(precise)) => {
                assert_close(&fast, &precise, cam.fx, &format!("{what}, Gaussian {i}"));
                visible += 1;
            }
            (None, None) => {}
            (fast, precise) => panic!("{what}, Gaussian {i}: culled by one projection only: {fast:?} {precise:?}"),
        }
    }
    visible
}

#[test]
fn the_f32_projection_matches_the_f64_one_on_random_scenes() {
    for (seed, degree, (w, h)) in [(1u64, 3, (504, 378)), (2, 0, (64, 48)), (3, 1, (1008, 756)), (4, 2, (33, 65))] {
        let g = random_gaussians(&mut Rng(seed), 2_000, degree);
        let cam = camera(w, h, 0.8 * w as f32, 0.9 * w as f32, w as f32 * 0.47, h as f32 * 0.55);
        let visible = compare(&g, &cam, &format!("seed {seed}"));
        assert!(visible > 1_000, "seed {seed}: {visible} visible");
    }
}

/// Needles at every angle (axis ratios up to 1e6), a line longer than the view (e^40, whose
/// covariance is 1e37 and still fits f32), sub-pixel and near-plane Gaussians.
#[test]
fn the_f32_projection_matches_on_hard_footprints() {
    let cam = camera(64, 64, 60.0, 60.0, 32.0, 32.0);
    let mut g = Gaussians::with_degree(0);
    for k in 0..24 {
        let half_angle = k as f32 * std::f32::consts::PI / 24.0;
        let q = [half_angle.cos(), 0.3 * half_angle.sin(), 0.1, half_angle.sin()];
        g.push([0.1, -0.2, 4.0], [0.0, (1e-6f32).ln(), (1e-3f32).ln()], q, 3.0, &[1.0, 1.0, 1.0]);
        g.push([0.0, 0.0, 4.0], [40.0, (0.1f32).ln(), (0.1f32).ln()], q, 1.0, &[0.5; 3]);
        g.push([0.05 * k as f32, 0.0, 2.0], [(1e-5f32).ln(); 3], q, 4.0, &[0.2; 3]);
        g.push([0.0, 0.01 * k as f32, 0.0101], [-3.0; 3], q, 2.0, &[0.7; 3]);
    }
    assert!(compare(&g, &cam, "hard footprints") >= 72);
}

/// A scene 10^4 from the origin, seen from beside it: the camera-space mean subtracts two
/// large numbers, which the f32 projection does in f64.
#[test]
fn the_f32_projection_keeps_a_far_scene_in_place() {
    let offset = Vec3::new(1e4, -2e4, 3e4);
    let mut g = random_gaussians(&mut Rng(9), 500, 1);
    for m in &mut g.means {
        *m = (Vec3::from(*m) + offset).to_array();
    }
    let intrinsics = Intrinsics { width: 200, height: 150, fx: 180.0, fy: 180.0, cx: 100.0, cy: 75.0 };
    let cam = Camera::new(intrinsics, Mat3::IDENTITY, -offset).expect("valid camera");
    assert!(compare(&g, &cam, "far scene") > 250);
}

/// Where an f32 intermediate overflows (scales of e^60: a covariance of 1e54 pixels^2), the
/// splat is the f64 projection's, exactly.
#[test]
fn overflowing_footprints_are_projected_in_f64() {
    let cam = camera(64, 64, 60.0, 60.0, 32.0, 32.0);
    let mut g = Gaussians::with_degree(0);
    g.push([0.0, 0.0, 4.0], [60.0, -2.0, -2.0], [0.9, 0.1, 0.2, 0.3], 1.0, &[0.5; 3]);
    g.push([0.0, 0.0, 4.0], [1.0, 1.0, 1.0], [3e19, 1e19, 0.0, 0.0], 1.0, &[0.5; 3]);
    let settings = ProjectionSettings::default();
    let projector = Projector::new(&cam, &settings);
    for i in 0..g.len() {
        let precise = project_precise(&g, i, &cam, &settings);
        assert!(precise.is_some(), "Gaussian {i} is visible in f64");
        assert_eq!(projector.project(&g, i), precise, "Gaussian {i}");
    }
}

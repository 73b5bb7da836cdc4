//! The rasterizer's analytic gradients against central finite differences of the decoder's
//! forward pass, for every parameter kind.
//!
//! The forward uses the smooth-cutoff variant (a C1 smoothstep replaces the hard 1/255 alpha
//! threshold), without which differences jump whenever a pixel crosses the threshold. The loss
//! is a fixed random weighting of every pixel's color, so each pixel's gradient differs.

use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};
use pwgs_encoder::train::backward::backward;
use pwgs_render::raster::{Cutoff, RenderOptions, rasterize};

struct Case {
    name: &'static str,
    gaussians: Gaussians,
    camera: Camera,
    /// The scene's unit of length, which sets the step for means.
    length: f32,
}

fn options() -> RenderOptions {
    RenderOptions { background: [0.3, 0.6, 0.1], cutoff: Cutoff::Smooth, ..Default::default() }
}

fn loss(g: &Gaussians, cam: &Camera, weights: &[f32]) -> f64 {
    let image = rasterize(g, cam, &options()).color;
    image.data.iter().zip(weights).map(|(&c, &w)| c as f64 * w as f64).sum()
}

/// Mutable access to parameter `slot` of Gaussian `i` for each parameter kind.
#[derive(Clone, Copy, Debug)]
enum Kind {
    Mean,
    LogScale,
    Rotation,
    Opacity,
    Sh,
}

impl Kind {
    fn slots(self, g: &Gaussians) -> usize {
        match self {
            Kind::Mean | Kind::LogScale => 3,
            Kind::Rotation => 4,
            Kind::Opacity => 1,
            Kind::Sh => g.coeffs_per_channel() * 3,
        }
    }

    fn param(self, g: &mut Gaussians, i: usize, slot: usize) -> &mut f32 {
        let k = g.coeffs_per_channel() * 3;
        match self {
            Kind::Mean => &mut g.means[i][slot],
            Kind::LogScale => &mut g.log_scales[i][slot],
            Kind::Rotation => &mut g.rotations[i][slot],
            Kind::Opacity => &mut g.opacity_logits[i],
            Kind::Sh => &mut g.sh[i * k + slot],
        }
    }

    fn analytic(self, grads: &pwgs_encoder::train::backward::Gradients, g: &Gaussians, i: usize, slot: usize) -> f64 {
        let k = g.coeffs_per_channel() * 3;
        (match self {
            Kind::Mean => grads.means[i][slot],
            Kind::LogScale => grads.log_scales[i][slot],
            Kind::Rotation => grads.rotations[i][slot],
            Kind::Opacity => grads.opacity_logits[i],
            Kind::Sh => grads.sh[i * k + slot],
        }) as f64
    }

    /// Step for central differences. It must resolve the smooth cutoff's narrow band (alpha
    /// from 1/255 to 1/255 + 1e-3), so a mean moves by well under a tenth of a pixel; color is
    /// linear in SH, where a larger step only lowers the effect of f32 rounding.
    fn step(self, length: f32) -> f32 {
        match self {
            Kind::Mean => 1e-3 * length,
            Kind::Sh => 1e-2,
            _ => 1e-3,
        }
    }
}

fn check(case: &Case) {
    let mut rng = SplitMix64(99);
    let pixels = (case.camera.width * case.camera.height * 3) as usize;
    let weights: Vec<f32> = (0..pixels).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let rendered = rasterize(&case.gaussians, &case.camera, &options());
    assert!(rendered.splats.len() * 2 > case.gaussians.len(), "{}: most Gaussians must be visible", case.name);
    let grads = backward(&case.gaussians, &case.camera, &options(), &rendered, &weights);
    for kind in [Kind::Mean, Kind::LogScale, Kind::Rotation, Kind::Opacity, Kind::Sh] {
        let (mut pairs, mut norm) = (Vec::new(), 0.0f64);
        for i in 0..case.gaussians.len() {
            for slot in 0..kind.slots(&case.gaussians) {
                let mut g = case.gaussians.clone();
                let original = *kind.param(&mut g, i, slot);
                let h = kind.step(case.length);
                *kind.param(&mut g, i, slot) = original + h;
                let plus = loss(&g, &case.camera, &weights);
                *kind.param(&mut g, i, slot) = original - h;
                let minus = loss(&g, &case.camera, &weights);
                // The step actually taken in f32.
                let taken = ((original + h) as f64) - ((original - h) as f64);
                let numeric = (plus - minus) / taken;
                let analytic = kind.analytic(&grads, &case.gaussians, i, slot);
                norm = norm.max(numeric.abs());
                pairs.push((i, slot, analytic, numeric));
            }
        }
        assert!(norm > 1e-3, "{} {kind:?}: gradients vanish, the check would be empty", case.name);
        let diff: f64 = pairs.iter().map(|(_, _, a, n)| (a - n).powi(2)).sum::<f64>().sqrt();
        let total: f64 = pairs.iter().map(|(_, _, _, n)| n * n).sum::<f64>().sqrt();
        assert!(diff / total < 1e-2, "{} {kind:?}: relative error {:.2e} over all parameters", case.name, diff / total);
        // Element-wise: relative error below 1e-2, plus the rounding noise of the differences
        // themselves. The forward pass is f32; a loss summed over P pixel values carries
        // about 1e-7 sqrt(P) of rounding error, divided by the 2h of the central difference.
        let h = kind.step(case.length) as f64;
        let noise = 1e-7 * (pixels as f64).sqrt() / h;
        for (i, slot, a, n) in pairs {
            let allowed = 1e-2 * n.abs().max(a.abs()) + noise;
            assert!(
                (a - n).abs() < allowed,
                "{} {kind:?} Gaussian {i} slot {slot}: analytic {a} numeric {n}",
                case.name
            );
        }
    }
}

#[test]
fn random_anisotropic_rotated_scene() {
    let mut rng = SplitMix64(1);
    let gaussians = random_gaussians(&mut rng, 12, 3, [-2.6, -1.6]);
    check(&Case { name: "random", gaussians, camera: axis_camera(40, 32, 36.0, 36.0, 20.0, 16.0), length: 1.0 });
}

#[test]
fn off_center_principal_point_and_unequal_focal() {
    let mut rng = SplitMix64(2);
    let gaussians = random_gaussians(&mut rng, 10, 2, [-2.6, -1.6]);
    check(&Case { name: "intrinsics", gaussians, camera: axis_camera(44, 30, 30.0, 41.0, 18.5, 16.0), length: 1.0 });
}

#[test]
fn near_camera_gaussians() {
    let mut rng = SplitMix64(3);
    let mut gaussians = random_gaussians(&mut rng, 10, 1, [-3.0, -2.2]);
    // Pull everything to 0.3-0.9 units from the camera, where perspective is strongest.
    let length = 0.15;
    for m in &mut gaussians.means {
        *m = m.map(|v| v * length);
    }
    for s in &mut gaussians.log_scales {
        *s = s.map(|v| v + length.ln());
    }
    check(&Case { name: "near", gaussians, camera: axis_camera(36, 36, 30.0, 30.0, 18.0, 18.0), length });
}

/// The vectorized backward walk agrees with the scalar reference up to its cheaper falloff's
/// error and the rounding of its different summation order, on both cutoffs, edge tiles and
/// saturated pixels.
#[test]
fn vectorized_backward_matches_the_scalar_walk() {
    use pwgs_encoder::train::backward::blend::blend_backward;
    use pwgs_render::raster::BlendPath;
    for (seed, n, (w, h), cutoff) in
        [(31u64, 400, (64, 48), Cutoff::Hard), (32, 1500, (53, 37), Cutoff::Smooth), (33, 80, (17, 30), Cutoff::Hard)]
    {
        let g = random_gaussians(&mut SplitMix64(seed), n, 2, [-3.5, -1.5]);
        let cam = axis_camera(w, h, 0.8 * w as f32, 0.8 * w as f32, w as f32 / 2.0, h as f32 / 2.0);
        let options = RenderOptions { background: [0.3, 0.6, 0.1], cutoff, ..Default::default() };
        let rendered = |blend| rasterize(&g, &cam, &RenderOptions { blend, ..options });
        let scalar = rendered(BlendPath::Scalar);
        assert!(scalar.transmittance.iter().any(|&t| t < 0.2), "seed {seed}: the scene covers the view");
        let mut rng = SplitMix64(seed + 100);
        let v_color: Vec<f32> = (0..scalar.color.data.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
        // Each path walks back through its own forward pass (the vector one's alphas differ
        // from the scalar one's in the last bits: see the forward pass's test).
        let grads = |blend| blend_backward(&rendered(blend), &RenderOptions { blend, ..options }, &v_color);
        let flat = |gs: &[pwgs_encoder::train::backward::blend::SplatGrad]| -> Vec<f64> {
            gs.iter().flat_map(|g| g.mean.into_iter().chain(g.conic).chain([g.opacity]).chain(g.color)).collect()
        };
        let a = flat(&grads(BlendPath::Scalar));
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(a.iter().filter(|v| **v != 0.0).count() > a.len() / 2, "seed {seed}: most gradients are non-zero");
        // Both vector paths: AVX2 where this CPU has it, and `wide`'s portable vectors.
        let (avx, portable) = (flat(&grads(BlendPath::Vectorized)), flat(&grads(BlendPath::Portable)));
        for b in [&avx, &portable] {
            let worst = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
            // Per entry the sums are stored in f32 (6e-8 of the largest value) and the two
            // paths' alphas differ by a few 1e-7, relative: 1e-6 of the largest gradient.
            // Under the smooth cutoff alpha's slope near alpha_min is 1 / SMOOTH_CUTOFF_BAND
            // (1,000) times raw alpha's, so there the alphas' difference is amplified by raw
            // alpha / band, up to 10 for the splats in the band.
            let bound = match cutoff {
                Cutoff::Hard => 1e-6,
                Cutoff::Smooth => 1e-5,
            } * scale;
            assert!(worst <= bound, "seed {seed}: worst difference {worst} against scale {scale}");
        }
        // The two vector paths do the same operations in the same order.
        assert_eq!(avx, portable, "seed {seed}: AVX2 and portable lanes differ");
    }
}

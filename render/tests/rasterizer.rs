//! Forward rasterizer: agreement with the naive reference, with gsplat, and the hard cases.

mod common;

use common::{Rng, camera, max_abs_diff, naive_render, random_gaussians};
use pwgs_core::gaussians::{Gaussians, SH_C0, rgb_to_sh_dc};
use pwgs_render::raster::blend::{ColourMap, splat_weights};
use pwgs_render::raster::opaque_tiles::{Stops, splat_list_ends};
use pwgs_render::raster::tile_lists::{BinBudget, BlendLimit, ListEnds, TooMuchBlending};
use pwgs_render::raster::tiles::ListOrder;
use pwgs_render::raster::{
    BlendPath, RenderOptions, Window, rasterize, rasterize_window, render, render_within, visible_splats,
};

#[test]
fn matches_naive_reference_on_random_scenes() {
    for (seed, degree, n, (w, h)) in
        [(1u64, 3, 200, (64, 48)), (2, 0, 500, (37, 29)), (3, 1, 50, (80, 80)), (4, 2, 300, (33, 65))]
    {
        let mut rng = Rng(seed);
        let g = random_gaussians(&mut rng, n, degree);
        let cam = camera(w, h, 0.8 * w as f32, 0.9 * w as f32, w as f32 * 0.47, h as f32 * 0.55);
        let options = RenderOptions { background: [0.2, 0.5, 0.9], ..Default::default() };
        let fast = render(&g, &cam, &options);
        let (naive, _) = naive_render(&g, &cam, &options);
        let diff = max_abs_diff(&fast, &naive);
        assert!(diff < 1e-5, "seed {seed}: max difference {diff}");
    }
}

#[test]
fn a_window_is_exactly_that_part_of_the_whole_image() {
    let mut rng = Rng(11);
    let g = random_gaussians(&mut rng, 400, 2);
    let cam = camera(70, 50, 60.0, 62.0, 33.0, 26.0);
    let options = RenderOptions { background: [0.3, 0.1, 0.6], ..Default::default() };
    let full = rasterize(&g, &cam, &options);
    // Windows off the tile grid, at the image's edges, one pixel wide, and the whole image.
    for window in [
        Window { x0: 5, y0: 7, width: 37, height: 21 },
        Window { x0: 40, y0: 30, width: 30, height: 20 },
        Window { x0: 0, y0: 49, width: 70, height: 1 },
        Window::full(&cam),
    ] {
        let part = rasterize_window(&g, &cam, window, &options);
        assert_eq!((part.color.width, part.color.height), (window.width, window.height));
        for y in 0..window.height {
            for x in 0..window.width {
                let (p, q) = ((y * window.width + x) as usize, ((window.y0 + y) * 70 + window.x0 + x) as usize);
                assert_eq!(
                    part.color.data[p * 3..p * 3 + 3],
                    full.color.data[q * 3..q * 3 + 3],
                    "{window:?} at {x},{y}"
                );
                assert_eq!(part.transmittance[p], full.transmittance[q]);
                assert_eq!(part.depth[p], full.depth[q]);
            }
        }
        assert!(part.splats.len() <= full.splats.len());
    }
    assert!(!Window { x0: 60, y0: 0, width: 11, height: 5 }.fits(&cam));
}

/// One opaque-ish Gaussian at `mean` with isotropic scale.
/// Small budgets split a view into many windows, by rows and within rows: each window's lists
/// are the whole view's, the image is the one-binning image bit for bit, and no window's lists
/// exceed the budget unless one tile does.
#[test]
fn a_render_within_a_budget_is_the_whole_render() {
    let mut rng = Rng(23);
    let g = random_gaussians(&mut rng, 600, 1);
    let cam = camera(150, 90, 120.0, 125.0, 70.0, 47.0);
    let options = RenderOptions { background: [0.1, 0.4, 0.2], ..Default::default() };
    let whole = rasterize(&g, &cam, &options);
    let splats = visible_splats(&g, &cam, &options.projection);
    let per_tile = |t: usize| whole.bins.tile(t).len() as u64;
    let largest_tile = (0..(whole.bins.tiles_x * whole.bins.tiles_y) as usize).map(per_tile).max().unwrap();
    for budget in [
        BinBudget { entries: 1 << 30, pixels: 1 << 30 },
        BinBudget { entries: 1 << 30, pixels: 256 * 12 },
        BinBudget { entries: 2000, pixels: 1 << 30 },
        BinBudget { entries: largest_tile, pixels: 256 },
        BinBudget { entries: 1, pixels: 1 },
    ] {
        let ends = ListEnds::full(splats.len(), |i| splats[i].bbox, Window::full(&cam));
        let windows = ends.windows(budget);
        let covered: u64 = windows.iter().map(|w| u64::from(w.width) * u64::from(w.height)).sum();
        assert_eq!(covered, 150 * 90, "{budget:?}: the windows tile the view");
        for w in &windows {
            let bins = ends.bin(splats.len(), |i| splats[i].bbox, *w);
            let tiles = u64::from(bins.tiles_x * bins.tiles_y);
            for t in 0..tiles as usize {
                let [x0, _, y0, _] = bins.tile_rect(t);
                let whole_tile = (y0 / 16 * whole.bins.tiles_x + x0 / 16) as usize;
                assert_eq!(bins.tile(t), whole.bins.tile(whole_tile), "{budget:?}: window {w:?}, tile {t}");
            }
            assert!(
                bins.entries.len() as u64 <= budget.entries.max(largest_tile)
                    && u64::from(w.width * w.height) <= budget.pixels.max(256)
                    || tiles == 1,
                "{budget:?}: window {w:?} holds {} entries",
                bins.entries.len()
            );
        }
        assert!(budget.entries > 1 << 20 || windows.len() > 1, "{budget:?} splits the view");
        assert_eq!(render_within(&g, &cam, &options, budget, BlendLimit::NONE), Ok(whole.color.clone()), "{budget:?}");
    }
}

/// A view is refused exactly when its lists' blend work passes the limit, with an error naming
/// the view and the limit; within it, the render is the unlimited one.
#[test]
fn a_render_past_the_work_limit_is_refused() {
    let mut rng = Rng(31);
    let g = random_gaussians(&mut rng, 300, 0);
    let cam = camera(120, 80, 100.0, 100.0, 60.0, 40.0);
    let options = RenderOptions::default();
    let splats = visible_splats(&g, &cam, &options.projection);
    let full = Window::full(&cam);
    let work = splat_list_ends(&splats, full, Stops::of(&options), (BlendLimit::NONE, g.len())).expect("no limit").work;
    assert!(work > 120 * 80 + 2 * 300, "{work} units");
    // 120 x 80 pixels and 300 Gaussians.
    let at = BlendLimit { per_pixel: 1, per_gaussian: 2, fixed: work - 9600 - 600 };
    assert_eq!(render_within(&g, &cam, &options, BinBudget::DEFAULT, at), Ok(render(&g, &cam, &options)));
    let below = BlendLimit { fixed: work - 9600 - 601, ..at };
    let refused = render_within(&g, &cam, &options, BinBudget::DEFAULT, below).expect_err("one unit short");
    assert_eq!(refused, TooMuchBlending { width: 120, height: 80, gaussians: 300, limit: work - 1, rule: below });
    assert!(refused.to_string().starts_with("the 120x80 view of 300 Gaussians needs more than"), "{refused}");
}

/// Large, nearly opaque splats: tiles turn opaque after a few of them, and the colour render's
/// lists end there; the image is the full lists' image bit for bit on every blend path.
#[test]
fn lists_that_end_at_opaque_tiles_change_no_pixel() {
    let mut rng = Rng(29);
    let mut g = random_gaussians(&mut rng, 400, 1);
    for (i, (s, o)) in g.log_scales.iter_mut().zip(&mut g.opacity_logits).enumerate() {
        *s = s.map(|v| v + 2.5);
        // Some faint ones among them, which bound nothing but are blended until the tile closes.
        *o = if i % 5 == 0 { -4.0 } else { 2.0 + (i % 7) as f32 };
    }
    let cam = camera(100, 70, 90.0, 92.0, 50.0, 35.0);
    for blend in [BlendPath::Scalar, BlendPath::Vectorized, BlendPath::Portable] {
        let options = RenderOptions { background: [0.7, 0.2, 0.4], blend, ..Default::default() };
        let whole = rasterize(&g, &cam, &options);
        let splats = visible_splats(&g, &cam, &options.projection);
        let full = Window::full(&cam);
        let shortened = splat_list_ends(&splats, full, Stops::of(&options), (BlendLimit::NONE, g.len()))
            .expect("no limit")
            .bin(splats.len(), |i| splats[i].bbox, full);
        assert!(
            shortened.entries.len() * 4 < whole.bins.entries.len(),
            "{} of {} entries kept",
            shortened.entries.len(),
            whole.bins.entries.len()
        );
        assert_eq!(render(&g, &cam, &options), whole.color, "{blend:?}");
    }
}

fn single(mean: [f32; 3], log_scale: f32, opacity_logit: f32, rgb: [f32; 3]) -> Gaussians {
    let mut g = Gaussians::with_degree(0);
    g.push(mean, [log_scale; 3], [1.0, 0.0, 0.0, 0.0], opacity_logit, &rgb.map(rgb_to_sh_dc));
    g
}

#[test]
fn empty_scene_is_exactly_the_background() {
    let cam = camera(19, 7, 10.0, 10.0, 9.5, 3.5);
    let bg = [0.25, 0.5, 0.125];
    let out = rasterize(&Gaussians::with_degree(2), &cam, &RenderOptions { background: bg, ..Default::default() });
    assert!(out.color.data.chunks(3).all(|p| p == bg));
    assert!(out.transmittance.iter().all(|&t| t == 1.0));
}

/// Renders `g` and `g` plus `extra`; the extra Gaussians must not change a single value.
fn assert_invisible(g: &Gaussians, extra: &Gaussians, cam: &pwgs_core::camera::Camera, what: &str) {
    let mut both = g.clone();
    for i in 0..extra.len() {
        both.push(extra.means[i], extra.log_scales[i], extra.rotations[i], extra.opacity_logits[i], extra.sh_of(i));
    }
    let options = RenderOptions { background: [0.1, 0.2, 0.3], ..Default::default() };
    let base = rasterize(g, cam, &options);
    let with = rasterize(&both, cam, &options);
    assert_eq!(base.color, with.color, "{what} changed the image");
    assert_eq!(base.transmittance, with.transmittance, "{what} changed the alpha");
}

fn scene(seed: u64, n: usize) -> Gaussians {
    random_gaussians(&mut Rng(seed), n, 1)
}

#[test]
fn behind_camera_and_near_plane() {
    let cam = camera(48, 32, 40.0, 40.0, 24.0, 16.0);
    let g = scene(7, 60);
    let mut extra = Gaussians::with_degree(1);
    let sh = [0.8f32; 12];
    extra.push([0.0, 0.0, -1.0], [0.0; 3], [1.0, 0.0, 0.0, 0.0], 5.0, &sh); // behind, large
    extra.push([0.0, 0.0, 0.005], [-1.0; 3], [1.0, 0.0, 0.0, 0.0], 5.0, &sh); // center before near
    assert_invisible(&g, &extra, &cam, "Gaussians behind the near plane");
    // Straddling: center just past the near plane, extent reaching behind the camera. It is
    // drawn (the center is visible), stays finite and covers the whole view.
    let straddling = single([0.0, 0.0, 0.02], -2.0, 5.0, [0.9, 0.1, 0.1]);
    let out = rasterize(&straddling, &cam, &RenderOptions::default());
    assert!(out.color.data.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
    assert!(out.transmittance.iter().all(|&t| t < 0.05), "straddling Gaussian should cover the view");
}

#[test]
fn needle_with_scale_ratio_1e6() {
    let cam = camera(64, 64, 60.0, 60.0, 32.0, 32.0);
    let mut g = Gaussians::with_degree(0);
    let half_angle = std::f32::consts::PI / 8.0;
    // Long axis 1e0, short axes 1e-6, rotated 45 degrees about z: a diagonal line.
    let q = [half_angle.cos(), 0.0, 0.0, half_angle.sin()];
    g.push([0.0, 0.0, 4.0], [0.0, (1e-6f32).ln(), (1e-6f32).ln()], q, 3.0, &[1.0, 1.0, 1.0]);
    let options = RenderOptions::default();
    let out = rasterize(&g, &cam, &options);
    let (naive, _) = naive_render(&g, &cam, &options);
    assert!(max_abs_diff(&out.color, &naive) < 1e-5);
    // The needle is a diagonal line: pixels on the diagonal are covered, off-diagonal corners are not.
    let alpha = |x: u32, y: u32| 1.0 - out.transmittance[(y * 64 + x) as usize];
    assert!(
        alpha(20, 20) > 0.4 && alpha(44, 44) > 0.4,
        "needle missing on the diagonal: {} {} (anti-diagonal {} {})",
        alpha(20, 20),
        alpha(44, 44),
        alpha(20, 44),
        alpha(44, 20)
    );
    assert!(alpha(20, 44) == 0.0 && alpha(44, 20) == 0.0, "needle leaked off the diagonal");
}

/// A line far longer than the view (scales e^40 and 0.1: an axis ratio of 2e18) keeps its
/// width: across it, alpha is opacity x exp(-d^2 / 2 (w^2 + blur)), w = 0.1 f / z. With the
/// determinant taken as `a c - b^2` the f64 subtraction loses every digit here.
#[test]
fn a_line_longer_than_the_view_keeps_its_width() {
    let cam = camera(64, 64, 60.0, 60.0, 32.0, 32.0);
    let mut g = Gaussians::with_degree(0);
    let half_angle = std::f32::consts::PI / 8.0;
    let q = [half_angle.cos(), 0.0, 0.0, half_angle.sin()];
    g.push([0.0, 0.0, 4.0], [40.0, (0.1f32).ln(), (0.1f32).ln()], q, 1.0, &[0.5, 0.5, 0.5]);
    let options = RenderOptions::default();
    let out = rasterize(&g, &cam, &options);
    let opacity = 1.0 / (1.0 + (-1.0f64).exp());
    let variance = (0.1f64 * 60.0 / 4.0).powi(2) + options.projection.blur;
    for x in 26..40u32 {
        // Row 31's pixel centers against the diagonal through (32, 32).
        let d = (f64::from(x) + 0.5 - 31.5) / std::f64::consts::SQRT_2;
        let falloff = (-0.5 * d * d / variance).exp();
        let expected = if opacity * falloff < 1.0 / 255.0 { 0.0 } else { opacity * falloff };
        let alpha = 1.0 - f64::from(out.transmittance[(31 * 64 + x) as usize]);
        assert!((alpha - expected).abs() < 1e-4, "pixel ({x}, 31): alpha {alpha}, expected {expected}");
    }
}

#[test]
fn full_screen_gaussian() {
    let cam = camera(50, 30, 30.0, 30.0, 25.0, 15.0);
    let g = single([0.0, 0.0, 3.0], 2.0, 0.0, [0.2, 0.7, 0.4]);
    let options = RenderOptions::default();
    let out = rasterize(&g, &cam, &options);
    assert!(out.transmittance.iter().all(|&t| t < 0.6), "every pixel is covered");
    assert_eq!(out.bins.entries.len(), (out.bins.tiles_x * out.bins.tiles_y) as usize, "one entry per tile");
    let (naive, _) = naive_render(&g, &cam, &options);
    assert!(max_abs_diff(&out.color, &naive) < 1e-5);
}

#[test]
fn sub_pixel_gaussian_is_blurred_and_centered() {
    let cam = camera(21, 21, 20.0, 20.0, 10.5, 10.5);
    // Projects to (13.2, 8.7); world scale 1e-5 is far below a pixel.
    let (u, v) = (13.2f32, 8.7f32);
    let z = 2.0;
    let g = single([(u - 10.5) * z / 20.0, (v - 10.5) * z / 20.0, z], (1e-5f32).ln(), 4.0, [1.0; 3]);
    let out = rasterize(&g, &cam, &RenderOptions::default());
    let mut sum = 0.0f64;
    let mut centroid = [0.0f64; 2];
    for y in 0..21u32 {
        for x in 0..21u32 {
            let a = 1.0 - out.transmittance[(y * 21 + x) as usize] as f64;
            sum += a;
            centroid[0] += a * (x as f64 + 0.5);
            centroid[1] += a * (y as f64 + 0.5);
        }
    }
    assert!(sum > 0.5, "the 0.3 px blur keeps a sub-pixel Gaussian visible ({sum})");
    let c = centroid.map(|c| c / sum);
    assert!((c[0] - u as f64).abs() < 0.1 && (c[1] - v as f64).abs() < 0.1, "centroid {c:?}");
}

#[test]
fn zero_and_denormal_quaternions_are_culled() {
    let cam = camera(32, 32, 30.0, 30.0, 16.0, 16.0);
    let g = scene(11, 40);
    for q in [[0.0f32; 4], [1e-40, 0.0, 0.0, 0.0], [0.0, -1e-39, 1e-41, 0.0], [f32::MIN_POSITIVE; 4]] {
        let mut extra = Gaussians::with_degree(1);
        extra.push([0.0, 0.0, 2.0], [-1.0; 3], q, 3.0, &[0.5; 12]);
        assert_invisible(&g, &extra, &cam, &format!("quaternion {q:?}"));
    }
}

#[test]
fn opacity_clamps_at_0_99() {
    let cam = camera(17, 17, 20.0, 20.0, 8.5, 8.5);
    let g = single([0.0, 0.0, 2.0], -1.0, 30.0, [1.0; 3]);
    let out = rasterize(&g, &cam, &RenderOptions::default());
    let center_t = out.transmittance[8 * 17 + 8];
    assert!((center_t - 0.01).abs() < 1e-6, "transmittance at the center {center_t}");
    assert!(out.transmittance.iter().all(|&t| t >= 0.01 - 1e-6));
}

#[test]
fn ten_thousand_gaussians_in_one_tile() {
    let cam = camera(16, 16, 16.0, 16.0, 8.0, 8.0);
    let mut rng = Rng(5);
    let mut g = Gaussians::with_degree(0);
    for _ in 0..10_000 {
        let z = rng.uniform(1.0, 10.0);
        let sh = [rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)];
        g.push([rng.uniform(-0.3, 0.3) * z, rng.uniform(-0.3, 0.3) * z, z], [-4.0; 3], [1.0, 0.0, 0.0, 0.0], -3.0, &sh);
    }
    let options = RenderOptions::default();
    let out = rasterize(&g, &cam, &options);
    assert_eq!(out.bins.tile(0).len(), 10_000);
    let (naive, _) = naive_render(&g, &cam, &options);
    let diff = max_abs_diff(&out.color, &naive);
    assert!(diff < 1e-5, "difference {diff}");
    // The blend loops read a tile's splats through block copies: every position once, in order.
    let list = out.bins.tile(0);
    let expected = |k: usize| (k, out.splats[list[k] as usize]);
    let walk = |order| {
        let (mut list, mut all) = (out.bins.splats(0, &out.splats, order), Vec::new());
        while let Some(block) = list.next_block() {
            all.extend_from_slice(block);
        }
        all
    };
    let front = walk(ListOrder::FrontToBack);
    assert_eq!(front, (0..list.len()).map(expected).collect::<Vec<_>>());
    for end in [0, 1, 31, 32, 33, 9_999, 10_000, 20_000] {
        let back = walk(ListOrder::BackToFront { end });
        assert_eq!(back, (0..end.min(list.len())).rev().map(expected).collect::<Vec<_>>(), "end {end}");
    }
}

#[test]
fn non_finite_parameters_are_culled_and_change_no_pixel() {
    let cam = camera(40, 30, 35.0, 35.0, 20.0, 15.0);
    let g = scene(13, 50);
    let template = scene(14, 1);
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        // Every parameter slot: 3 mean, 3 scale, 4 rotation, 1 opacity, 12 SH.
        for slot in 0..23 {
            let mut extra = template.clone();
            match slot {
                0..3 => extra.means[0][slot] = bad,
                3..6 => extra.log_scales[0][slot - 3] = bad,
                6..10 => extra.rotations[0][slot - 6] = bad,
                10 => extra.opacity_logits[0] = bad,
                _ => extra.sh[slot - 11] = bad,
            }
            assert_invisible(&g, &extra, &cam, &format!("{bad} in slot {slot}"));
        }
    }
}

#[test]
fn principal_point_and_anisotropic_focal() {
    let (cx, cy) = (7.25f32, 20.5f32);
    let cam = camera(40, 24, 30.0, 45.0, cx, cy);
    let g = single([0.0, 0.0, 3.0], -3.0, 3.0, [1.0; 3]);
    let out = rasterize(&g, &cam, &RenderOptions::default());
    let (mut sum, mut mx, mut my) = (0.0f64, 0.0f64, 0.0f64);
    for y in 0..24u32 {
        for x in 0..40u32 {
            let a = 1.0 - out.transmittance[(y * 40 + x) as usize] as f64;
            sum += a;
            mx += a * (x as f64 + 0.5);
            my += a * (y as f64 + 0.5);
        }
    }
    assert!(
        (mx / sum - cx as f64).abs() < 0.15 && (my / sum - cy as f64).abs() < 0.15,
        "centroid off the principal point"
    );
    // fx != fy stretches the footprint: the vertical extent is larger.
    let covered = |horizontal: bool| {
        (0..if horizontal { 40 } else { 24 })
            .filter(|&i| {
                let (x, y) = if horizontal { (i, 20) } else { (7, i) };
                out.transmittance[(y * 40 + x) as usize] < 0.99
            })
            .count()
    };
    assert!(covered(false) > covered(true), "fy > fx must stretch the splat vertically");
}

#[test]
fn tiny_and_odd_image_sizes() {
    let g = scene(17, 80);
    for (w, h) in [(1, 1), (1, 17), (17, 1), (33, 17), (15, 49)] {
        let cam = camera(w, h, 0.9 * w.max(h) as f32, 0.9 * w.max(h) as f32, w as f32 / 2.0, h as f32 / 2.0);
        let options = RenderOptions::default();
        let out = render(&g, &cam, &options);
        assert_eq!(out.data.len(), (w * h * 3) as usize);
        let (naive, _) = naive_render(&g, &cam, &options);
        let diff = max_abs_diff(&out, &naive);
        assert!(diff < 1e-5, "{w}x{h}: difference {diff}");
    }
}

#[test]
fn output_is_identical_for_any_thread_count() {
    let g = random_gaussians(&mut Rng(21), 3000, 3);
    let cam = camera(96, 80, 80.0, 80.0, 48.0, 40.0);
    let options = RenderOptions::default();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| rasterize(&g, &cam, &options))
    };
    let one = run(1);
    let many = run(4);
    assert_eq!(one.color, many.color);
    assert_eq!(one.transmittance, many.transmittance);
    assert_eq!(one.depth, many.depth);
    assert_eq!(one.splats, many.splats);
}

/// The vectorized blend (AVX2 and portable, which give the same bits) against the scalar
/// reference, on edge tiles (sizes off the 16-pixel grid), windows, dense tiles that saturate,
/// and both cutoffs. The vector falloff is within 2.2e-7 (relative) of its exact value and
/// the scalar one within 2 ulps, so each alpha differs by a few 1e-7 and each pixel's sum by
/// about that times the number of splats blended: within 1e-5 wherever both paths took the
/// same decisions. A splat whose alpha is within that of alpha_min, or a pixel whose
/// transmittance is within it of transmittance_min, may be decided the other way: such pixels
/// are rare and differ by at most one splat's contribution, within the render tolerance of
/// SPEC.md section 8 (2/255).
#[test]
fn vectorized_blending_matches_the_scalar_path() {
    use pwgs_render::raster::Cutoff;
    let (mut pixels, mut decided_otherwise) = (0usize, 0usize);
    let mut check = |g: &Gaussians, cam: &pwgs_core::camera::Camera, window: Window, cutoff: Cutoff, what: &str| {
        let options = RenderOptions { background: [0.25, 0.5, 0.75], cutoff, ..Default::default() };
        let render = |blend| rasterize_window(g, cam, window, &RenderOptions { blend, ..options });
        let (scalar, vector, portable) =
            (render(BlendPath::Scalar), render(BlendPath::Vectorized), render(BlendPath::Portable));
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        // AVX2 (where this CPU has it) and `wide`'s portable vectors: the same operations.
        assert_eq!(bits(&vector.color.data), bits(&portable.color.data), "{what}: AVX2 and portable colors");
        assert_eq!(bits(&vector.transmittance), bits(&portable.transmittance), "{what}: transmittance");
        assert_eq!(bits(&vector.depth), bits(&portable.depth), "{what}: depth");
        assert_eq!(vector.last_contributor, portable.last_contributor, "{what}: last contributors");
        for p in 0..scalar.transmittance.len() {
            pixels += 1;
            let (a, b) = (&scalar.color.data[p * 3..p * 3 + 3], &vector.color.data[p * 3..p * 3 + 3]);
            let worst = a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
            let worst = worst.max((scalar.transmittance[p] - vector.transmittance[p]).abs());
            if scalar.last_contributor[p] == vector.last_contributor[p] && worst <= 1e-5 {
                let depth = (scalar.depth[p] - vector.depth[p]).abs();
                // Depth is a sum divided by the coverage 1 - T, which loses digits where the
                // coverage is small: its bound grows as 1 / (1 - T).
                let bound = scalar.depth[p].abs() * (1e-5 + 1e-6 / (1.0 - scalar.transmittance[p]));
                assert!(depth == 0.0 || depth <= bound, "{what} pixel {p}: depth off by {depth}, more than {bound}");
            } else {
                decided_otherwise += 1;
                assert!(
                    worst <= 2.0 / 255.0,
                    "{what} pixel {p}: off by {worst} (last contributor {} against {})",
                    vector.last_contributor[p],
                    scalar.last_contributor[p]
                );
            }
        }
        assert!(scalar.transmittance.iter().any(|&t| t < 0.5), "{what}: the scene covers the view");
    };
    for (seed, n, (w, h)) in [(21u64, 300, (64, 48)), (22, 800, (37, 29)), (23, 2000, (83, 41)), (24, 60, (9, 17))] {
        let g = random_gaussians(&mut Rng(seed), n, 1);
        let cam = camera(w, h, 0.8 * w as f32, 0.9 * w as f32, w as f32 * 0.47, h as f32 * 0.55);
        for cutoff in [Cutoff::Hard, Cutoff::Smooth] {
            check(&g, &cam, Window::full(&cam), cutoff, &format!("seed {seed} {cutoff:?}"));
        }
        let window = Window { x0: 3, y0: 2, width: w - 5, height: h - 3 };
        check(&g, &cam, window, Cutoff::Hard, &format!("seed {seed} window"));
    }
    assert!(decided_otherwise * 1000 <= pixels, "{decided_otherwise} of {pixels} pixels decided otherwise");
}

#[test]
fn splat_weights_add_up_to_each_pixels_coverage() {
    // Per pixel the blended weights T * alpha sum to 1 - T_final, so over the image the
    // Gaussians' weights sum to the total coverage; a Gaussian out of view weighs 0. On every
    // blend path, each against its own render.
    let mut g = scene(12, 400);
    g.push([0.0, 0.0, -5.0], [-2.0; 3], [1.0, 0.0, 0.0, 0.0], 3.0, &[0.5; 12]);
    let cam = camera(96, 72, 80.0, 80.0, 48.0, 36.0);
    let mut per_path = Vec::new();
    for blend in [BlendPath::Scalar, BlendPath::Vectorized, BlendPath::Portable] {
        let options = RenderOptions { blend, ..Default::default() };
        let r = rasterize(&g, &cam, &options);
        let weights = splat_weights(&r.bins, &r.splats, &options, g.len());
        assert_eq!(weights.len(), g.len());
        assert_eq!(weights[g.len() - 1], 0.0, "{blend:?}: behind the camera");
        assert!(weights.iter().all(|&w| w >= 0.0), "{blend:?}");
        let coverage: f64 = r.transmittance.iter().map(|&t| 1.0 - f64::from(t)).sum();
        let total: f64 = weights.iter().map(|&w| f64::from(w)).sum();
        assert!(coverage > 100.0, "{blend:?}: the scene covers {coverage} pixels");
        assert!((total - coverage).abs() < 1e-4 * coverage, "{blend:?}: {total} against {coverage}");
        per_path.push(weights);
    }
    // The vector lanes give the same bits on AVX2 and portable vectors, and each Gaussian's
    // weight is within the cheaper falloff's rounding of the scalar path's.
    assert_eq!(per_path[1], per_path[2], "AVX2 and portable lanes differ");
    for (i, (s, v)) in per_path[0].iter().zip(&per_path[1]).enumerate() {
        assert!((s - v).abs() <= 1e-4 * s.max(1.0), "Gaussian {i}: scalar {s}, vectorized {v}");
    }
}

#[test]
fn the_colour_map_is_the_render_and_its_transpose_is_its_adjoint() {
    // Degree 0 and colours in [0, 1] (no clamping): the render is the map of the colours plus
    // the background times the final transmittance. On every blend path, against its own
    // render; 100 pixels wide, so that the last tile column is 4 pixels wide.
    let g = random_gaussians(&mut Rng(13), 400, 0);
    let cam = camera(100, 72, 80.0, 80.0, 50.0, 36.0);
    let mut transposes = Vec::new();
    for blend in [BlendPath::Scalar, BlendPath::Vectorized, BlendPath::Portable] {
        let options = RenderOptions { blend, background: [0.2, 0.3, 0.4], ..Default::default() };
        let r = rasterize(&g, &cam, &options);
        let map = ColourMap { bins: &r.bins, splats: &r.splats, options: &options };
        let colours: Vec<[f32; 3]> =
            (0..g.len()).map(|i| std::array::from_fn(|c| SH_C0 * g.sh_of(i)[c] + 0.5)).collect();
        let mut image = map.apply(&colours);
        for (p, &t) in r.transmittance.iter().enumerate() {
            (0..3).for_each(|c| image[p * 3 + c] += t * options.background[c]);
        }
        let worst = image.iter().zip(&r.color.data).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "{blend:?}: the map differs from the render by {worst}");
        assert!(r.transmittance.iter().filter(|&&t| t < 0.5).count() > 500, "the scene covers too little");
        // <A v, u> = <v, A^T u>, and the squares are each Gaussian's |A e_i|^2.
        let mut rng = Rng(14);
        let v: Vec<[f32; 3]> = (0..g.len()).map(|_| std::array::from_fn(|_| rng.uniform(-1.0, 1.0))).collect();
        let u: Vec<f32> = (0..image.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let (transposed, squares) = map.transpose(&u, g.len());
        let lhs: f64 = map.apply(&v).iter().zip(&u).map(|(a, b)| f64::from(*a) * f64::from(*b)).sum();
        let rhs: f64 =
            v.iter().flatten().zip(transposed.iter().flatten()).map(|(a, b)| f64::from(*a) * f64::from(*b)).sum();
        assert!((lhs - rhs).abs() < 1e-4 * lhs.abs().max(1.0), "{blend:?}: {lhs} against {rhs}");
        for i in [0, 57, 399] {
            let mut unit = vec![[0.0f32; 3]; g.len()];
            unit[i] = [1.0, 0.0, 0.0];
            let norm: f64 = map.apply(&unit).iter().map(|&a| f64::from(a) * f64::from(a)).sum();
            assert!(
                (norm - f64::from(squares[i])).abs() <= 1e-5 * norm.max(1e-3),
                "{blend:?}, Gaussian {i}: {norm} against {}",
                squares[i]
            );
        }
        // The fused walk gives the map's image and the adjoint of that image, as the two
        // passes do.
        let (image, normal) = map.apply_and_normal(&v, g.len());
        assert_eq!(image, map.apply(&v), "{blend:?}");
        assert_eq!(normal, map.transpose(&image, g.len()).0, "{blend:?}");
        transposes.push((transposed, squares));
    }
    assert_eq!(transposes[1], transposes[2], "AVX2 and portable lanes differ");
}

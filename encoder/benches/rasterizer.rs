//! Rasterizer benchmark: forward and backward time with the scalar and the vectorized blend
//! (and their ratio, which survives a noisy machine), the blending alone of each pass (the same
//! splats and tile lists; projection, sorting and the projection's backward are shared by the
//! two paths; the vectorized blend in AVX2 registers where the CPU has them, and in `wide`'s
//! portable vectors, what other CPUs run, with its ratio to the scalar path), the projection
//! alone in f32 (what rendering uses) and in f64 (its reference), blend evaluations per second,
//! and the speedup over the naive reference renderer,
//! for 10k / 100k / 1M random Gaussians at 504x378 and 1008x756. Run with `cargo bench -p
//! pwgs-encoder --bench rasterizer` (add `-- --quick` for 10k and 100k only). Timings depend on
//! the machine: report them with it.

#[path = "../../render/tests/common/mod.rs"]
mod common;

use std::time::Instant;

use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};
use pwgs_encoder::train::backward::backward;
use pwgs_encoder::train::backward::blend::blend_backward;
use pwgs_render::raster::project::project_precise;
use pwgs_render::raster::{BlendPath, RenderOptions, Rendered, blend_bins, project_visible, rasterize};
use rayon::prelude::*;

/// Median of `runs` timings of `f`, in seconds.
fn time<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut times = Vec::with_capacity(runs);
    let mut last = None;
    for _ in 0..runs {
        let start = Instant::now();
        last = Some(f());
        times.push(start.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    (times[runs / 2], last.expect("at least one run"))
}

/// Splat-pixel pairs blending visits: for every tile entry, the pixels of the splat's box in
/// that tile (an upper bound on alpha evaluations, before early termination).
fn blend_pairs(r: &Rendered) -> u64 {
    let mut pairs = 0u64;
    for t in 0..(r.bins.tiles_x * r.bins.tiles_y) as usize {
        let [x0, x1, y0, y1] = r.bins.tile_rect(t);
        for &i in r.bins.tile(t) {
            let [bx0, bx1, by0, by1] = r.splats[i as usize].bbox;
            let nx = bx1.min(x1).saturating_sub(bx0.max(x0)) as u64;
            let ny = by1.min(y1).saturating_sub(by0.max(y0)) as u64;
            pairs += nx * ny;
        }
    }
    pairs
}

/// Gaussians whose footprints shrink as their number grows, so images stay comparably covered.
fn scene(n: usize) -> Gaussians {
    let center = (0.02 * (1e4 / n as f32).sqrt()).ln();
    random_gaussians(&mut SplitMix64(n as u64), n, 3, [center - 0.7, center + 0.7])
}

fn camera(width: u32, height: u32) -> Camera {
    axis_camera(width, height, 0.8 * width as f32, 0.8 * width as f32, width as f32 / 2.0, height as f32 / 2.0)
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let counts: &[usize] = if quick { &[10_000, 100_000] } else { &[10_000, 100_000, 1_000_000] };
    let options = RenderOptions::default();
    println!("threads: {}", rayon::current_num_threads());
    let scalar = RenderOptions { blend: BlendPath::Scalar, ..options };
    let portable = RenderOptions { blend: BlendPath::Portable, ..options };
    println!(
        "{:>9} {:>10} {:>9} {:>10} {:>10} {:>6} {:>10} {:>10} {:>6} {:>10} {:>6} {:>10} {:>10} {:>6} {:>10} {:>10} {:>6} {:>10} {:>6} {:>10} {:>10} {:>6} {:>12} {:>11}",
        "gaussians",
        "image",
        "visible",
        "fwd scalar",
        "fwd simd",
        "ratio",
        "blend sc.",
        "blend simd",
        "ratio",
        "blend port",
        "ratio",
        "bwd scalar",
        "bwd simd",
        "ratio",
        "bblend sc.",
        "bblend sd.",
        "ratio",
        "bblend pt.",
        "ratio",
        "proj f64",
        "proj f32",
        "ratio",
        "blend pairs",
        "pairs/s bl."
    );
    for &(width, height) in &[(504u32, 378u32), (1008, 756)] {
        let cam = camera(width, height);
        for &n in counts {
            let g = scene(n);
            let runs = if n >= 1_000_000 { 3 } else { 5 };
            let (forward_scalar, _) = time(runs, || rasterize(&g, &cam, &scalar));
            let (forward, rendered) = time(runs, || rasterize(&g, &cam, &options));
            let weights = vec![1.0f32; rendered.color.data.len()];
            let (backward_scalar, _) = time(runs, || backward(&g, &cam, &scalar, &rendered, &weights));
            let (backward_s, _) = time(runs, || backward(&g, &cam, &options, &rendered, &weights));
            let (blend_scalar, _) = time(runs, || blend_bins(&rendered.splats, &rendered.bins, &scalar));
            let (blend_s, _) = time(runs, || blend_bins(&rendered.splats, &rendered.bins, &options));
            let (blend_p, _) = time(runs, || blend_bins(&rendered.splats, &rendered.bins, &portable));
            let (bblend_scalar, _) = time(runs, || blend_backward(&rendered, &scalar, &weights));
            let (bblend_s, _) = time(runs, || blend_backward(&rendered, &options, &weights));
            let (bblend_p, _) = time(runs, || blend_backward(&rendered, &portable, &weights));
            let settings = options.projection;
            let precise = || (0..g.len()).into_par_iter().filter_map(|i| project_precise(&g, i, &cam, &settings));
            let (project_f64, _) = time(runs, || precise().collect::<Vec<_>>());
            let (project_f32, _) = time(runs, || project_visible(&g, &cam, &settings));
            let pairs = blend_pairs(&rendered);
            println!(
                "{n:>9} {:>10} {:>9} {forward_scalar:>10.4} {forward:>10.4} {:>6.2} {blend_scalar:>10.4} {blend_s:>10.4} {:>6.2} {blend_p:>10.4} {:>6.2} {backward_scalar:>10.4} {backward_s:>10.4} {:>6.2} {bblend_scalar:>10.4} {bblend_s:>10.4} {:>6.2} {bblend_p:>10.4} {:>6.2} {project_f64:>10.4} {project_f32:>10.4} {:>6.2} {pairs:>12} {:>11.3e}",
                format!("{width}x{height}"),
                rendered.splats.len(),
                forward_scalar / forward,
                blend_scalar / blend_s,
                blend_scalar / blend_p,
                backward_scalar / backward_s,
                bblend_scalar / bblend_s,
                bblend_scalar / bblend_p,
                project_f64 / project_f32,
                pairs as f64 / blend_s
            );
        }
    }
    // The naive reference evaluates every Gaussian at every pixel; time it on a band of rows at
    // the image center and scale to the full image (its cost per row is nearly constant).
    let n = 10_000;
    let g = scene(n);
    let (width, height, band) = (504u32, 378u32, 8u32);
    let full = camera(width, height);
    let strip = Camera { height: band, cy: full.cy - (height - band) as f32 / 2.0, ..full };
    let (naive_band, _) = time(1, || common::naive_render(&g, &strip, &options));
    let naive = naive_band * height as f64 / band as f64;
    let (fast, _) = time(5, || rasterize(&g, &full, &options));
    println!(
        "naive reference, {n} Gaussians at {width}x{height}: {naive:.2} s (from {band} rows), tiled: {fast:.4} s, speedup {:.0}x",
        naive / fast
    );
}

//! Where a CPU render of a stream's view goes: decoding, deriving the view's Gaussians,
//! projection and sort, finding where each tile's list ends (the windows), filling the lists
//! and blending, each timed alone, with the tile-list entries blended and their work units
//! ([`ListEnds::work`](pwgs_render::raster::tile_lists::ListEnds), no work limit). For the heavy streams of
//! `limit-streams` and the hostile files:
//! `cargo bench -p pwgs-render --bench render_phases -- STREAM CAMERA.json` (one run; report
//! the figures with the machine and the thread count).

use pwgs_render::show::SceneRender;
use std::time::Instant;

use anyhow::{Context, Result};
use pwgs_core::camera_json::parse_camera;
use pwgs_render::raster::opaque_tiles::{Stops, splat_list_ends};
use pwgs_render::raster::tile_lists::{BinBudget, BlendLimit};
use pwgs_render::raster::{Window, blend_bins, visible_splats};

fn main() -> Result<()> {
    // cargo bench passes `--bench` after the user's arguments.
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let [stream, camera] = &args[..] else {
        anyhow::bail!("usage: cargo bench -p pwgs-render --bench render_phases -- STREAM CAMERA.json");
    };
    let bytes = std::fs::read(stream).with_context(|| format!("cannot read {stream}"))?;
    let text = std::fs::read_to_string(camera).with_context(|| format!("cannot read {camera}"))?;
    let camera = parse_camera(&text).with_context(|| format!("{camera}: bad camera"))?;
    let timed = |name: &str, start: Instant| println!("{name}: {:.3} s", start.elapsed().as_secs_f64());

    let start = Instant::now();
    let scene = pwgs_codec::stream::decode(&bytes)?.scene;
    timed("decode", start);
    let start = Instant::now();
    let gaussians = scene.gaussians_for(&camera);
    timed("the view's Gaussians", start);
    let options = scene.render_options();
    let start = Instant::now();
    let splats = visible_splats(&gaussians, &camera, &options.projection);
    timed(&format!("projection and sort ({} splats)", splats.len()), start);
    let start = Instant::now();
    let view = Window::full(&camera);
    let ends = splat_list_ends(&splats, view, Stops::of(&options), (BlendLimit::NONE, gaussians.len()))?;
    let windows = ends.windows(BinBudget::DEFAULT);
    timed(&format!("list ends and windows ({} windows)", windows.len()), start);
    let (mut binning, mut blending, mut entries) = (0.0, 0.0, 0);
    for window in windows {
        let start = Instant::now();
        let bins = ends.bin(splats.len(), |i| splats[i].bbox, window);
        binning += start.elapsed().as_secs_f64();
        entries += bins.entries.len();
        let start = Instant::now();
        blend_bins(&splats, &bins, &options);
        blending += start.elapsed().as_secs_f64();
    }
    println!("filling the lists: {binning:.3} s");
    let pixels = u64::from(camera.width) * u64::from(camera.height);
    let work = ends.work;
    println!(
        "blending {entries} entries, {work} work units ({:.1} per pixel): {blending:.3} s",
        work as f64 / pixels as f64
    );
    println!("{:.2} ns per work unit", blending * 1e9 / work as f64);
    Ok(())
}

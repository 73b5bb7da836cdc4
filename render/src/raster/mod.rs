//! The reference Gaussian rasterizer (forward), in plain Rust on the CPU.
//!
//! Pipeline: project and cull every Gaussian ([`project`]), sort the visible splats front to
//! back, bin them into 16x16 tiles ([`tiles`]), blend each tile ([`blend`]). Projection runs
//! in parallel per Gaussian and blending per row of tiles; every per-pixel sum runs in a fixed
//! order on one thread, so the output does not depend on the number of threads.
//!
//! Rendering is not normative bit for bit (docs/architecture.md section 3); this implementation
//! is the one GPU renderers and the encoder's backward pass are checked against.
#![cfg_attr(not(test), deny(clippy::disallowed_methods))] // the determinism rule: no platform math (clippy.toml)

pub mod alpha_lanes;
pub mod blend;
pub mod blend_simd;
pub mod lanes;
pub mod linear_simd;
pub mod opaque_tiles;
pub mod project;
pub mod project_f32;
pub mod sh;
pub mod tile_lists;
pub mod tiles;

use rayon::prelude::*;

use opaque_tiles::Stops;
use project::{ProjectionSettings, Splat};
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::rgb_image::RgbImage;
use tile_lists::{BinBudget, BlendLimit, ListEnds, TooMuchBlending};
use tiles::TileBins;

/// Tile edge in pixels.
pub const TILE_SIZE: u32 = 16;

/// How the alpha_min threshold is applied.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cutoff {
    /// The standard hard threshold.
    Hard,
    /// A C1 smoothstep over a narrow band above alpha_min, so that the image is a smooth
    /// function of the parameters; used by finite-difference gradient checks.
    Smooth,
}

/// Which implementation blends the tiles. The vector paths take alpha from a cheaper falloff
/// ([`alpha_lanes`], error stated there): their images are within rounding of the scalar
/// path's (the tests bound the difference), and AVX2 and portable lanes give the same bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlendPath {
    /// One pixel at a time: the reference.
    Scalar,
    /// Eight pixels of a tile row at a time ([`blend_simd`]), in AVX2 registers where the CPU
    /// has them.
    Vectorized,
    /// [`BlendPath::Vectorized`] with `wide`'s portable vectors whatever the CPU (what other
    /// CPUs run; tests and benchmarks compare it with the others).
    Portable,
}

impl BlendPath {
    /// `None` on the scalar path; on a vector path, whether it asks for `wide`'s portable
    /// lanes (the `portable` argument of the vector kernels).
    pub fn vector_lanes(self) -> Option<bool> {
        match self {
            BlendPath::Scalar => None,
            BlendPath::Vectorized => Some(false),
            BlendPath::Portable => Some(true),
        }
    }
}

/// Rendering settings; the defaults are those of 3DGS and gsplat.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    pub background: [f32; 3],
    pub projection: ProjectionSettings,
    /// Alpha of a single splat is clamped to this.
    pub alpha_max: f32,
    /// Blending stops before the transmittance would fall to this or below.
    pub transmittance_min: f32,
    pub cutoff: Cutoff,
    pub blend: BlendPath,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            background: [0.0; 3],
            projection: ProjectionSettings::default(),
            alpha_max: 0.99,
            transmittance_min: 1e-4,
            cutoff: Cutoff::Hard,
            blend: BlendPath::Vectorized,
        }
    }
}

/// A rectangle of the image in pixels: x in [x0, x0 + width), y in [y0, y0 + height). A
/// window's render is exactly that part of the whole image's render, at the cost of its own
/// pixels (every Gaussian is still projected).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
}

impl Window {
    /// The whole image of `camera`.
    pub fn full(camera: &Camera) -> Self {
        Self { x0: 0, y0: 0, width: camera.width, height: camera.height }
    }

    /// Whether the window is non-empty and inside `camera`'s image.
    pub fn fits(&self, camera: &Camera) -> bool {
        self.width > 0
            && self.height > 0
            && u64::from(self.x0) + u64::from(self.width) <= u64::from(camera.width)
            && u64::from(self.y0) + u64::from(self.height) <= u64::from(camera.height)
    }

    /// Tiles across and down, counted from the window's top left corner (the last ones cut at
    /// its edges).
    pub fn tile_counts(&self) -> (u32, u32) {
        (self.width.div_ceil(TILE_SIZE), self.height.div_ceil(TILE_SIZE))
    }

    /// The pixels of tiles [tx0, tx1) x [ty0, ty1) of the window, cut at its edges.
    pub fn tiles(&self, [tx0, tx1, ty0, ty1]: [u32; 4]) -> Window {
        let (x0, y0) = (tx0 * TILE_SIZE, ty0 * TILE_SIZE);
        Window {
            x0: self.x0 + x0,
            y0: self.y0 + y0,
            width: (tx1 * TILE_SIZE).min(self.width) - x0,
            height: (ty1 * TILE_SIZE).min(self.height) - y0,
        }
    }

    /// Pixel rectangle of tile (tx, ty) of the window: x in [x0, x1), y in [y0, y1).
    pub fn tile_rect(&self, tx: u32, ty: u32) -> [u32; 4] {
        let tile = self.tiles([tx, tx + 1, ty, ty + 1]);
        [tile.x0, tile.x0 + tile.width, tile.y0, tile.y0 + tile.height]
    }
}

/// A rendered view (or window of one) with what the backward pass needs. Per-pixel arrays
/// cover the window, row by row.
#[derive(Debug, Clone)]
pub struct Rendered {
    pub color: RgbImage,
    /// Final transmittance per pixel (alpha = 1 - T).
    pub transmittance: Vec<f32>,
    /// Expected depth of the covered part of each pixel (0 where nothing is covered).
    pub depth: Vec<f32>,
    /// Per pixel, one past the position (within its tile's list) of the last splat blended.
    pub last_contributor: Vec<u32>,
    /// Visible splats, front to back.
    pub splats: Vec<Splat>,
    pub bins: TileBins,
}

/// Projects and sorts the visible splats front to back (ties broken by index).
pub fn visible_splats(gaussians: &Gaussians, camera: &Camera, settings: &ProjectionSettings) -> Vec<Splat> {
    let mut splats = project_visible(gaussians, camera, settings);
    sort_front_to_back(&mut splats);
    splats
}

/// The splats of the Gaussians `camera` sees, in index order.
pub fn project_visible(gaussians: &Gaussians, camera: &Camera, settings: &ProjectionSettings) -> Vec<Splat> {
    assert!(gaussians.is_consistent(), "Gaussian arrays have inconsistent lengths");
    let projector = project::Projector::new(camera, settings);
    (0..gaussians.len()).into_par_iter().filter_map(|i| projector.project(gaussians, i)).collect()
}

/// Blending order: by depth, ties broken by index (so the order does not depend on threads).
pub fn sort_front_to_back(splats: &mut [Splat]) {
    splats.par_sort_unstable_by(|a, b| a.depth.total_cmp(&b.depth).then(a.index.cmp(&b.index)));
}

/// Renders a view.
pub fn rasterize(gaussians: &Gaussians, camera: &Camera, options: &RenderOptions) -> Rendered {
    rasterize_window(gaussians, camera, Window::full(camera), options)
}

/// Renders a window of a view. Panics unless the window [`fits`](Window::fits) the camera.
pub fn rasterize_window(gaussians: &Gaussians, camera: &Camera, window: Window, options: &RenderOptions) -> Rendered {
    assert!(window.fits(camera), "window {window:?} is not inside the {}x{} image", camera.width, camera.height);
    let mut splats = visible_splats(gaussians, camera, &options.projection);
    if window != Window::full(camera) {
        splats = clip_to_window(splats, window);
    }
    let bins = tiles::bin(&splats, window);
    let Blended { color, transmittance, depth, last_contributor } = blend_bins(&splats, &bins, options);
    Rendered { color, transmittance, depth, last_contributor, splats, bins }
}

/// The per-pixel results of blending a window, row by row.
pub struct Blended {
    pub color: RgbImage,
    pub transmittance: Vec<f32>,
    pub depth: Vec<f32>,
    pub last_contributor: Vec<u32>,
}

/// Blends `splats` (front to back) binned in `bins` over the bins' window, band by band of
/// tile rows in parallel, on the blend path `options` names.
pub fn blend_bins(splats: &[Splat], bins: &TileBins, options: &RenderOptions) -> Blended {
    let (width, height) = (bins.window.width, bins.window.height);
    let pixels = width as usize * height as usize;
    let mut color = vec![0.0f32; pixels * 3];
    let mut transmittance = vec![0.0f32; pixels];
    let mut depth = vec![0.0f32; pixels];
    let mut last_contributor = vec![0u32; pixels];
    let band_pixels = (TILE_SIZE * width) as usize;
    color
        .par_chunks_mut(band_pixels * 3)
        .zip(transmittance.par_chunks_mut(band_pixels))
        .zip(depth.par_chunks_mut(band_pixels))
        .zip(last_contributor.par_chunks_mut(band_pixels))
        .enumerate()
        .for_each(|(ty, (((color, transmittance), depth), last_contributor))| {
            let band = blend::Band { color, transmittance, depth, last_contributor };
            match options.blend.vector_lanes() {
                None => blend::blend_band(ty as u32, bins, splats, options, band),
                Some(portable) => blend_simd::blend_band(ty as u32, bins, splats, options, band, portable),
            }
        });
    Blended { color: RgbImage { width, height, data: color }, transmittance, depth, last_contributor }
}

/// The splats whose pixel box meets `window`, boxes clipped to it, order kept.
fn clip_to_window(splats: Vec<Splat>, window: Window) -> Vec<Splat> {
    let (x_end, y_end) = (window.x0 + window.width, window.y0 + window.height);
    splats
        .into_iter()
        .filter_map(|mut s| {
            let [x0, x1, y0, y1] = s.bbox;
            let [x0, x1, y0, y1] = [x0.max(window.x0), x1.min(x_end), y0.max(window.y0), y1.min(y_end)];
            (x0 < x1 && y0 < y1).then(|| {
                s.bbox = [x0, x1, y0, y1];
                s
            })
        })
        .collect()
}

/// Renders a view's colors only, in bounded memory: the view is blended window by window
/// ([`ListEnds::windows`] within [`BinBudget::DEFAULT`]), each tile's list ending where the tile
/// is surely opaque ([`opaque_tiles`]), so that whatever the splats, a render takes besides its
/// image (12 bytes per pixel) and its splats (80 bytes each) about 100 MiB of tile lists and
/// per-pixel arrays. The pixels are those of [`rasterize`]: every window's pixels are blended
/// from the image's coordinates in the same order. Its time is not bounded: decoders render
/// streams with [`render_limited`].
pub fn render(gaussians: &Gaussians, camera: &Camera, options: &RenderOptions) -> RgbImage {
    render_within(gaussians, camera, options, BinBudget::DEFAULT, BlendLimit::NONE)
        .expect("a render without a work limit is never refused")
}

/// [`render`] within [`BlendLimit::DEFAULT`]: a view whose blend work passes it is refused
/// after projection, before any list is filled, so that the time a render of any stream takes
/// is bounded by its pixels and Gaussians.
pub fn render_limited(
    gaussians: &Gaussians,
    camera: &Camera,
    options: &RenderOptions,
) -> Result<RgbImage, TooMuchBlending> {
    render_within(gaussians, camera, options, BinBudget::DEFAULT, BlendLimit::DEFAULT)
}

/// [`render`] within `budget` and `limit` (tests use small budgets to exercise many windows).
/// The limit applies with the hard cutoff (the smooth one is for gradient checks).
pub fn render_within(
    gaussians: &Gaussians,
    camera: &Camera,
    options: &RenderOptions,
    budget: BinBudget,
    limit: BlendLimit,
) -> Result<RgbImage, TooMuchBlending> {
    let splats = visible_splats(gaussians, camera, &options.projection);
    let full = Window::full(camera);
    let bbox = |i: usize| splats[i].bbox;
    // The smooth cutoff (gradient checks) blends below alpha_min: no tile is surely opaque.
    let ends = match options.cutoff {
        Cutoff::Hard => opaque_tiles::splat_list_ends(&splats, full, Stops::of(options), (limit, gaussians.len()))?,
        Cutoff::Smooth => ListEnds::full(splats.len(), bbox, full),
    };
    let windows = ends.windows(budget);
    let mut image = RgbImage { width: camera.width, height: camera.height, data: Vec::new() };
    if let [window] = windows[..] {
        image.data = blend_bins(&splats, &ends.bin(splats.len(), bbox, window), options).color.data;
        return Ok(image);
    }
    image.data = vec![0.0; full.width as usize * full.height as usize * 3];
    for window in windows {
        let bins = ends.bin(splats.len(), bbox, window);
        let part = blend_bins(&splats, &bins, options).color;
        let row = window.width as usize * 3;
        for (y, source) in part.data.chunks_exact(row).enumerate() {
            let start = ((window.y0 as usize + y) * full.width as usize + window.x0 as usize) * 3;
            image.data[start..start + row].copy_from_slice(source);
        }
    }
    Ok(image)
}

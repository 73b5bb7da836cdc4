//! Stage 2 of training: the perceptual wrapper. From the split iteration on, the distortion is
//! Wasserstein Distortion between the wrapped render clamp-free I_base + f(I_base, noise,
//! Plücker) and the ground truth, and f trains jointly with the Gaussians (docs/architecture.md section 1.2).
//!
//! WD goes through VGG16, far too slow on a CPU for whole images at every step, so each step
//! scores one crop: the crops of a view come from a fixed grid of positions covering the
//! image, which lets the ground truth's features be computed once per (view, crop) and cached,
//! up to a memory budget (a 128-pixel crop's features take about 11 MB; past the budget a
//! target is computed at each use, a VGG forward pass without gradients). Only the crop's
//! window is rendered: the crop grown by the reach of f's two 3x3 convolutions, so that f's
//! output on the crop is what it would be on the whole image (the noise and Plücker inputs
//! keep their full-image coordinates).

use std::collections::HashMap;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use burn::tensor::{Device, Tensor, TensorData};
use pwgs_codec::wrapper::conditioning;
use pwgs_codec::wrapper::synthesis::{SynthesisWeights, WrapperConfig};
use pwgs_core::camera::Camera;
use pwgs_core::frame::SceneFrame;
use pwgs_core::random::SplitMix64;
use pwgs_render::raster::Window;

use crate::metrics::sigma_map::{Log2Sigma, SigmaMap};
use crate::metrics::vgg_wasserstein::{MIN_SIDE, VggWasserstein, WdDepth, WdTarget};
use crate::train::adam::direction;
use crate::wrapper::synthesis::{flat_tensor, forward, host_weights, initial_parameters};

/// Stage 2's default length per training view. On fox (58 training views) 34 crops per view
/// gave DISTS 0.0803 where 17 gave 0.0844 and 64 gave no better (0.0816, with the pixel
/// term). A step takes about 1 s on the 2-core machines, so 32 costs about half a minute per
/// view.
pub const DEFAULT_CROPS_PER_VIEW: u32 = 32;

/// Stage 2's default least length: a scene with few views still gets this many steps. Fern (17
/// views) gained from 578 to 1,088 steps (DISTS 0.0833 -> 0.0795 with the pixel term) and had
/// its best figure at 1,000 (0.0722 without), where 32 per view would give it 544.
pub const DEFAULT_MIN_STEPS: u32 = 1000;

/// Image scales stage 2's WD compares by default: the full-resolution scale only. Against all
/// three (the reference's, which the evaluation keeps), on fern's plain base with two seeds
/// DISTS fell 12-14% and LPIPS 6-10% at equal size, at 0.4-0.6 dB less PSNR, in 0.68 of the
/// time; on fox's plain base DISTS 2.7% and LPIPS 2.4% lower (within a seed's spread), 0.26 dB
/// less, in 0.69 of the time; with fern's anchor base the wrapper's stream then had DISTS
/// 38.4% below the base alone at equal size.
pub const DEFAULT_WD_SCALES: usize = 1;

/// Which features WD compares.
#[derive(Debug, Clone, PartialEq)]
pub enum WdFeatures {
    /// The reference: the image and VGG16 relu1_2 .. relu5_3 at 3 scales; weights searched in
    /// these folders.
    Vgg(Vec<PathBuf>),
    /// The image alone at 3 scales: cheap, needs no weights, blind to texture.
    Pixels,
}

/// Settings of stage 2.
#[derive(Debug, Clone, PartialEq)]
pub struct WrapperTraining {
    pub config: WrapperConfig,
    /// First iteration of stage 2.
    pub start: u32,
    /// Stage 2's length per training view (see [`crate::plain::train::TrainConfig::schedule_stage_two`]).
    pub crops_per_view: u32,
    /// Stage 2's least length, whatever the number of views.
    pub min_steps: u32,
    pub log2_sigma: Log2Sigma,
    /// Side of the square crops WD scores (clamped to the image).
    pub crop: usize,
    pub learning_rate: f32,
    /// Multiplies the base's learning rates during stage 2 (1: as in stage 1; 0 freezes the
    /// base, so that only f learns).
    pub base_lr_scale: f32,
    pub features: WdFeatures,
    /// How much of the feature pyramid WD compares (the default is the reference's).
    pub wd_depth: WdDepth,
    /// Weight of the base's own objective (L1 + SSIM) on the crop of the base render I_base,
    /// added to WD: it keeps the Gaussians faithful to the pixels while f synthesizes texture
    /// (0: WD alone).
    pub pixel_weight: f32,
    /// Memory the cached ground-truth features and conditioning channels may take, in bytes.
    pub cache_bytes: usize,
}

/// The wrapper's training state.
pub(crate) struct WrapperStage {
    settings: WrapperTraining,
    wd: VggWasserstein,
    /// f's parameters, flat in stream order, and their Adam moments.
    flat: Tensor<1>,
    first: Tensor<1>,
    second: Tensor<1>,
    steps: u32,
    /// The training views' size.
    width: usize,
    height: usize,
    /// The training cameras and the scene's frame, which f's conditioning channels depend on.
    cameras: Vec<Camera>,
    frame: SceneFrame,
    /// Per training view, its conditioning channels [H, W, k] (when f has any), while they fit
    /// in `settings.cache_bytes`: held for every view, they took 6 GB on a 250-view scene at
    /// 800x533 (14 channels of f32 per pixel).
    conditioning: Vec<Option<Tensor<3>>>,
    /// Ground-truth features per (view, crop), while they fit in `settings.cache_bytes`.
    targets: HashMap<(usize, usize), WdTarget>,
    /// What the two caches hold.
    cached_bytes: usize,
}

/// Pixels beyond a crop that f's output on the crop depends on (two 3x3 convolutions).
const F_REACH: usize = 2;

/// What one stage-2 step scores.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepCrop {
    /// Which crop of the view's grid.
    pub index: usize,
    /// The crop WD scores.
    pub crop: Window,
    /// The part of the image rendered: the crop grown by [`F_REACH`], clipped to the image.
    pub window: Window,
}

/// The crop grid of a view along one axis: evenly spaced origins, from the start to the end,
/// at least 3 and as many as it takes for the crops to cover every pixel (a fixed 3 left
/// bands that WD never scored: 24% of fern's columns, 20% of fox's rows at 128 pixels).
fn crop_origins(size: usize, crop: usize) -> Vec<usize> {
    let span = size - crop;
    let count = size.div_ceil(crop).max(3);
    let mut v: Vec<usize> = (0..count).map(|i| i * span / (count - 1)).collect();
    v.dedup();
    v
}

/// A crop of a log2σ setting (a constant stays constant).
fn crop_log2_sigma(log2_sigma: &Log2Sigma, x0: usize, y0: usize, w: usize, h: usize) -> Log2Sigma {
    match log2_sigma {
        Log2Sigma::Constant(v) => Log2Sigma::Constant(*v),
        Log2Sigma::Map(map) => Log2Sigma::Map(SigmaMap {
            height: h,
            width: w,
            values: (y0..y0 + h).flat_map(|y| &map.values[y * map.width + x0..][..w]).copied().collect(),
        }),
    }
}

impl WrapperTraining {
    /// Stage 2's length on `train_views` views: `crops_per_view` per view, at least
    /// `min_steps`.
    pub fn stage_two_steps(&self, train_views: usize) -> u32 {
        let per_view = u64::from(self.crops_per_view) * train_views as u64;
        u32::try_from(per_view.max(u64::from(self.min_steps))).unwrap_or(u32::MAX)
    }

    /// Checks the settings against the training `cameras` and loads what WD compares (VGG16
    /// unless pixels only). Training calls it before its first step, so that a missing weights
    /// file or an unusable setting is reported before stage 1 spends its time, not after.
    pub fn prepare(&self, cameras: &[Camera], device: &Device) -> Result<VggWasserstein> {
        let (width, height) = (cameras[0].width as usize, cameras[0].height as usize);
        if cameras.iter().any(|c| (c.width as usize, c.height as usize) != (width, height)) {
            bail!("the perceptual wrapper trains on views of one size");
        }
        if width.min(height) < MIN_SIDE {
            bail!("the perceptual wrapper's WD needs images of at least {MIN_SIDE}x{MIN_SIDE}, got {width}x{height}");
        }
        if let Log2Sigma::Map(map) = &self.log2_sigma
            && (map.width, map.height) != (width, height)
        {
            bail!("the log2 sigma map is {}x{}, the training views {width}x{height}", map.width, map.height);
        }
        self.log2_sigma.validate().map_err(anyhow::Error::msg)?;
        let wd = match &self.features {
            WdFeatures::Vgg(dirs) => VggWasserstein::load(dirs, device)
                .context(
                "the perceptual wrapper's WD needs the VGG16 weights: run `pwenc fetch-weights` (or pass --weights DIR), \
                 or train the base alone with --no-wrapper",
            )?,
            WdFeatures::Pixels => VggWasserstein::pixels_only(),
        };
        Ok(wd.with_depth(self.wd_depth))
    }
}

impl WrapperStage {
    /// Starts stage 2 on the training `cameras`, with `wd` from [`WrapperTraining::prepare`].
    pub fn new(
        settings: WrapperTraining,
        wd: VggWasserstein,
        cameras: &[Camera],
        frame: SceneFrame,
        rng: &mut SplitMix64,
        device: &Device,
    ) -> Self {
        let (width, height) = (cameras[0].width as usize, cameras[0].height as usize);
        let flat = flat_tensor(&initial_parameters(&settings.config, rng), device);
        Self {
            first: flat.zeros_like(),
            second: flat.zeros_like(),
            flat,
            steps: 0,
            width,
            height,
            cameras: cameras.to_vec(),
            frame,
            conditioning: vec![None; cameras.len()],
            targets: HashMap::new(),
            cached_bytes: 0,
            wd,
            settings,
        }
    }

    /// Crop `index` of the grid (any number, taken modulo the grid's size) and its window.
    pub fn crop(&self, index: usize) -> StepCrop {
        let (cw, ch) = (self.settings.crop.min(self.width), self.settings.crop.min(self.height));
        let (xs, ys) = (crop_origins(self.width, cw), crop_origins(self.height, ch));
        let index = index % (xs.len() * ys.len());
        let (x0, y0) = (xs[index % xs.len()], ys[index / xs.len()]);
        let (wx0, wy0) = (x0.saturating_sub(F_REACH), y0.saturating_sub(F_REACH));
        let (wx1, wy1) = ((x0 + cw + F_REACH).min(self.width), (y0 + ch + F_REACH).min(self.height));
        let rect = |x0: usize, y0: usize, w: usize, h: usize| Window {
            x0: x0 as u32,
            y0: y0 as u32,
            width: w as u32,
            height: h as u32,
        };
        StepCrop { index, crop: rect(x0, y0, cw, ch), window: rect(wx0, wy0, wx1 - wx0, wy1 - wy0) }
    }

    /// The stage-2 loss of one step: WD of `step.crop` of the wrapped render of `step.window`
    /// (`image` [h, w, 3], autodiff) of training view `view` against the whole view's `target`
    /// [H, W, 3]. Returns the loss, the wrapped window [h, w, 3] and the tracked parameters
    /// whose gradient [`Self::update`] takes.
    pub fn loss(
        &mut self,
        view: usize,
        step: StepCrop,
        image: Tensor<3>,
        target: &Tensor<3>,
    ) -> (Tensor<1>, Tensor<3>, Tensor<1>) {
        let [height, width, _] = image.dims();
        let StepCrop { index, crop, window } = step;
        assert_eq!((width, height), (window.width as usize, window.height as usize), "render and window differ");
        let flat = self.flat.clone().autodiff().require_grad();
        let (wx, wy) = (window.x0 as usize, window.y0 as usize);
        let pixels = image.clone().reshape([height * width, 3]);
        let input = match self.view_conditioning(view) {
            Some(c) => {
                let k = c.dims()[2];
                let c = c.clone().slice([wy..wy + height, wx..wx + width, 0..k]).reshape([height * width, k]);
                Tensor::cat(vec![pixels, c.autodiff()], 1)
            }
            None => pixels,
        };
        let residual = forward(&self.settings.config, flat.clone(), input, height, width);
        let shown = image.permute([2, 0, 1]).unsqueeze::<4>() + residual;
        let (cx, cy, cw, ch) = (crop.x0 as usize, crop.y0 as usize, crop.width as usize, crop.height as usize);
        let key = (view, index);
        let uncached = (!self.targets.contains_key(&key)).then(|| {
            let t: Tensor<4> = target.clone().permute([2, 0, 1]).unsqueeze();
            self.wd.target(t.slice([0..1, 0..3, cy..cy + ch, cx..cx + cw]))
        });
        let uncached = match uncached {
            Some(t) if self.cached_bytes + t.bytes() <= self.settings.cache_bytes => {
                self.cached_bytes += t.bytes();
                self.targets.insert(key, t);
                None
            }
            other => other,
        };
        let target = uncached.as_ref().unwrap_or_else(|| &self.targets[&key]);
        let log2_sigma = crop_log2_sigma(&self.settings.log2_sigma, cx, cy, cw, ch);
        let inside = [0..1, 0..3, cy - wy..cy - wy + ch, cx - wx..cx - wx + cw];
        let loss = self.wd.distortion(shown.clone().slice(inside), target, &log2_sigma);
        let shown = shown.squeeze_dim::<3>(0).permute([1, 2, 0]);
        (loss, shown, flat)
    }

    /// View `view`'s conditioning channels [H, W, k], or `None` when f has none: from the
    /// cache, or computed and kept if they fit in the cache's budget.
    fn view_conditioning(&mut self, view: usize) -> Option<Tensor<3>> {
        let config = self.settings.config;
        let k = config.conditioning_channels();
        if k == 0 {
            return None;
        }
        if let Some(c) = &self.conditioning[view] {
            return Some(c.clone());
        }
        let (height, width) = (self.height, self.width);
        let values = conditioning(&config, &self.cameras[view], self.frame);
        let c = Tensor::from_data(TensorData::new(values, [height, width, k]), &self.flat.device());
        let bytes = height * width * k * size_of::<f32>();
        if self.cached_bytes + bytes <= self.settings.cache_bytes {
            self.cached_bytes += bytes;
            self.conditioning[view] = Some(c.clone());
        }
        Some(c)
    }

    /// The Adam step of f, or `None` (and nothing changed) if it would leave a non-finite value.
    pub fn update(&mut self, grad: Tensor<1>) -> Option<()> {
        let (mut first, mut second) = (self.first.clone(), self.second.clone());
        let next =
            self.flat.clone() - direction(grad, &mut first, &mut second, self.steps + 1) * self.settings.learning_rate;
        if !next.clone().is_finite().all().into_scalar::<bool>() {
            return None;
        }
        (self.flat, self.first, self.second) = (next, first, second);
        self.steps += 1;
        Some(())
    }

    /// Weight of the pixel term on the base render (see [`WrapperTraining::pixel_weight`]).
    pub fn pixel_weight(&self) -> f32 {
        self.settings.pixel_weight
    }

    /// What the base's learning rates are multiplied by while the stage runs.
    pub fn base_lr_scale(&self) -> f32 {
        self.settings.base_lr_scale
    }

    /// f's current weights.
    pub fn weights(&self) -> SynthesisWeights {
        host_weights(self.settings.config, self.flat.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crops_cover_the_image() {
        assert_eq!(crop_origins(504, 128), vec![0, 125, 250, 376]);
        assert_eq!(crop_origins(378, 128), vec![0, 125, 250]);
        assert_eq!(crop_origins(100, 100), vec![0]);
        for (size, crop) in [(480, 128), (504, 128), (1000, 129), (130, 128), (777, 64)] {
            let o = crop_origins(size, crop);
            assert_eq!((o[0], *o.last().unwrap()), (0, size - crop));
            assert!(o.windows(2).all(|w| w[1] > w[0] && w[1] - w[0] <= crop), "{size}/{crop}: {o:?}");
        }
        let map = SigmaMap { height: 3, width: 4, values: (0..12).map(f64::from).collect() };
        let Log2Sigma::Map(c) = crop_log2_sigma(&Log2Sigma::Map(map), 1, 1, 2, 2) else { panic!() };
        assert_eq!(c.values, vec![5.0, 6.0, 9.0, 10.0]);
    }

    /// Pixel-only settings of width 4 for the tests.
    fn settings(crops_per_view: u32, min_steps: u32) -> WrapperTraining {
        WrapperTraining {
            config: WrapperConfig { width: 4, noise: true, plucker: true, seed: 9 },
            start: 0,
            crops_per_view,
            min_steps,
            log2_sigma: Log2Sigma::Constant(2.0),
            crop: 64,
            learning_rate: 0.01,
            base_lr_scale: 1.0,
            features: WdFeatures::Pixels,
            wd_depth: WdDepth::default(),
            pixel_weight: 0.0,
            cache_bytes: 0,
        }
    }

    #[test]
    fn stage_two_scales_with_the_views_above_its_floor() {
        // Fern's 17 views and fox's 58 at the defaults: the floor, then 32 per view.
        assert_eq!(settings(DEFAULT_CROPS_PER_VIEW, DEFAULT_MIN_STEPS).stage_two_steps(17), 1000);
        assert_eq!(settings(DEFAULT_CROPS_PER_VIEW, DEFAULT_MIN_STEPS).stage_two_steps(58), 1856);
        assert_eq!(settings(3, 0).stage_two_steps(7), 21);
        assert_eq!(settings(u32::MAX, 0).stage_two_steps(3), u32::MAX, "saturates");
    }

    /// Rendering only a crop's window must not change the loss: f's output on the crop is the
    /// same as on the whole image, including at the image's edges.
    #[test]
    fn the_crop_window_gives_the_loss_of_the_whole_image() {
        use crate::train::params::tensor_values;
        use pwgs_core::random::axis_camera;
        let (width, height) = (90, 75);
        let camera = axis_camera(width as u32, height as u32, 70.0, 70.0, 44.0, 37.0);
        let device = Device::flex();
        let settings = settings(1, 0);
        let frame = SceneFrame { center: glam::Vec3::ZERO, scale: 1.0 };
        let mut rng = SplitMix64(1);
        let wd = settings.prepare(&[camera], &device).unwrap();
        let mut stage = WrapperStage::new(settings, wd, &[camera], frame, &mut rng, &device);
        // Random f, so that every layer (the residual convolutions included) is active.
        let values: Vec<f32> = (0..stage.flat.dims()[0]).map(|_| rng.uniform(-0.4, 0.4)).collect();
        stage.flat = flat_tensor(&values, &device);
        let random_image = |rng: &mut SplitMix64| {
            let v: Vec<f32> = (0..width * height * 3).map(|_| rng.uniform(0.0, 1.0)).collect();
            Tensor::<3>::from_data(TensorData::new(v, [height, width, 3]), &device)
        };
        let (image, target) = (random_image(&mut rng), random_image(&mut rng));
        let part = |w: Window| {
            image.clone().slice([
                w.y0 as usize..(w.y0 + w.height) as usize,
                w.x0 as usize..(w.x0 + w.width) as usize,
                0..3,
            ])
        };
        let value = |t: Tensor<1>| tensor_values(t.inner())[0];
        let mut uncached = vec![];
        for index in 0..4 {
            let step = stage.crop(index);
            assert!(step.window.width < width as u32 || step.window.height < height as u32);
            let whole = StepCrop { window: Window::full(&camera), ..step };
            let a = value(stage.loss(0, step, part(step.window).autodiff(), &target).0);
            let b = value(stage.loss(0, whole, image.clone().autodiff(), &target).0);
            assert!((a - b).abs() <= 1e-6 * b.abs(), "crop {index}: window {a} vs whole {b}");
            uncached.push(a);
        }
        assert!(stage.targets.is_empty(), "a cache of 0 bytes holds nothing");
        assert!(stage.conditioning[0].is_none(), "not even the conditioning channels");

        // With room for two targets, the first two crops are cached and give the same losses
        // on every later use; the others are computed each time.
        let one = stage.wd.target(target.clone().permute([2, 0, 1]).unsqueeze().slice([0..1, 0..3, 0..64, 0..64]));
        stage.settings.cache_bytes = 2 * one.bytes();
        for _ in 0..2 {
            for (index, &expected) in uncached.iter().enumerate() {
                let step = stage.crop(index);
                assert_eq!(value(stage.loss(0, step, part(step.window).autodiff(), &target).0), expected);
            }
        }
        assert_eq!(stage.targets.len(), 2);
        assert_eq!(stage.cached_bytes, 2 * one.bytes());
        assert!(stage.conditioning[0].is_none(), "the conditioning channels (378 KB) did not fit");

        // With room for the conditioning channels too, they are kept from their first use on,
        // and the losses stay the same.
        let conditioning_bytes = width * height * stage.settings.config.conditioning_channels() * 4;
        stage.settings.cache_bytes += conditioning_bytes;
        for (index, &expected) in uncached.iter().enumerate() {
            let step = stage.crop(index);
            assert_eq!(value(stage.loss(0, step, part(step.window).autodiff(), &target).0), expected);
            assert!(stage.conditioning[0].is_some(), "crop {index}: the channels are cached");
        }
        assert_eq!(stage.cached_bytes, 2 * one.bytes() + conditioning_bytes);
    }
}

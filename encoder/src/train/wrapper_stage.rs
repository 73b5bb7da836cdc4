//! Stage 2 of training: the perceptual wrapper. From the split iteration on, the distortion is
//! Wasserstein Distortion between the wrapped render clamp-free I_base + f(I_base, noise,
//! Plücker) and the ground truth, and f trains jointly with the Gaussians (DESIGN.md section 7).
//!
//! WD goes through VGG16, far too slow on a CPU for whole images at every step, so each step
//! scores one crop: the crops of a view come from a fixed 3 x 3 grid of positions, which lets
//! the ground truth's features be computed once per (view, crop) and cached. f itself runs on
//! the whole image (it is cheap), so the noise and Plücker inputs keep their full-image
//! coordinates.

use std::collections::HashMap;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use burn::tensor::{Device, Tensor, TensorData};
use pwgs_decoder::camera::Camera;
use pwgs_decoder::random_scene::SplitMix64;
use pwgs_decoder::wrapper::synthesis::{SynthesisWeights, WrapperConfig};
use pwgs_decoder::wrapper::{SceneFrame, conditioning};

use super::adam::direction;
use crate::metrics::sigma_map::{Log2Sigma, SigmaMap};
use crate::metrics::vgg_wasserstein::{MIN_SIDE, VggWasserstein, WdTarget};
use crate::synthesis::{flat_tensor, forward, host_weights, initial_parameters};

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
    pub log2_sigma: Log2Sigma,
    /// Side of the square crops WD scores (clamped to the image).
    pub crop: usize,
    pub learning_rate: f32,
    pub features: WdFeatures,
}

/// The wrapper's training state.
pub(super) struct WrapperStage {
    settings: WrapperTraining,
    wd: VggWasserstein,
    /// f's parameters, flat in stream order, and their Adam moments.
    flat: Tensor<1>,
    first: Tensor<1>,
    second: Tensor<1>,
    steps: u32,
    /// Per training view: the conditioning channels [H * W, k].
    conditioning: Vec<Tensor<2>>,
    targets: HashMap<(usize, usize), WdTarget>,
}

/// The crop grid of a view: up to 3 positions per axis (start, middle, end).
fn crop_origins(size: usize, crop: usize) -> Vec<usize> {
    let mut v = vec![0, (size - crop) / 2, size - crop];
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

impl WrapperStage {
    /// Prepares stage 2 for the training `cameras` (all of one size), loading VGG16 if needed.
    pub fn new(
        settings: WrapperTraining,
        cameras: &[Camera],
        frame: SceneFrame,
        rng: &mut SplitMix64,
        device: &Device,
    ) -> Result<Self> {
        let (width, height) = (cameras[0].width as usize, cameras[0].height as usize);
        if cameras.iter().any(|c| (c.width as usize, c.height as usize) != (width, height)) {
            bail!("the perceptual wrapper trains on views of one size");
        }
        if width.min(height) < MIN_SIDE {
            bail!("the perceptual wrapper's WD needs images of at least {MIN_SIDE}x{MIN_SIDE}, got {width}x{height}");
        }
        if let Log2Sigma::Map(map) = &settings.log2_sigma
            && (map.width, map.height) != (width, height)
        {
            bail!("the log2 sigma map is {}x{}, the training views {width}x{height}", map.width, map.height);
        }
        settings.log2_sigma.validate().map_err(anyhow::Error::msg)?;
        let wd = match &settings.features {
            WdFeatures::Vgg(dirs) => VggWasserstein::load(dirs, device)
                .context("WD needs the VGG16 weights (run `pwenc fetch-weights`, or pass --weights DIR)")?,
            WdFeatures::Pixels => VggWasserstein::pixels_only(),
        };
        let config = settings.config;
        let k = config.conditioning_channels();
        let conditioning = cameras
            .iter()
            .map(|camera| {
                let values = conditioning(&config, camera, frame);
                Tensor::from_data(TensorData::new(values, [width * height, k]), device)
            })
            .collect();
        let flat = flat_tensor(&initial_parameters(&config, rng), device);
        Ok(Self {
            first: flat.zeros_like(),
            second: flat.zeros_like(),
            flat,
            steps: 0,
            conditioning,
            targets: HashMap::new(),
            wd,
            settings,
        })
    }

    /// Number of crops of a view.
    pub fn crop_count(&self, width: usize, height: usize) -> usize {
        let c = self.settings.crop;
        crop_origins(width, c.min(width)).len() * crop_origins(height, c.min(height)).len()
    }

    /// The stage-2 loss of one step: WD of crop `crop` of the wrapped render `image` [H, W, 3]
    /// (autodiff) of training view `view` against `target` [H, W, 3]. Returns the loss, the
    /// wrapped image [H, W, 3] and the tracked parameters whose gradient [`Self::update`] takes.
    pub fn loss(
        &mut self,
        view: usize,
        crop: usize,
        image: Tensor<3>,
        target: &Tensor<3>,
    ) -> (Tensor<1>, Tensor<3>, Tensor<1>) {
        let [height, width, _] = image.dims();
        let flat = self.flat.clone().autodiff().require_grad();
        let input = Tensor::cat(
            vec![image.clone().reshape([height * width, 3]), self.conditioning[view].clone().autodiff()],
            1,
        );
        let residual = forward(&self.settings.config, flat.clone(), input, height, width);
        let shown = image.permute([2, 0, 1]).unsqueeze::<4>() + residual;
        let (cw, ch) = (self.settings.crop.min(width), self.settings.crop.min(height));
        let xs = crop_origins(width, cw);
        let ys = crop_origins(height, ch);
        let (x0, y0) = (xs[crop % xs.len()], ys[crop / xs.len()]);
        let window = [0..1, 0..3, y0..y0 + ch, x0..x0 + cw];
        let wd = &self.wd;
        let target = self.targets.entry((view, crop)).or_insert_with(|| {
            let t: Tensor<4> = target.clone().permute([2, 0, 1]).unsqueeze();
            wd.target(t.slice(window.clone()))
        });
        let log2_sigma = crop_log2_sigma(&self.settings.log2_sigma, x0, y0, cw, ch);
        let loss = wd.distortion(shown.clone().slice(window), target, &log2_sigma);
        let shown = shown.squeeze_dim::<3>(0).permute([1, 2, 0]);
        (loss, shown, flat)
    }

    /// The Adam step of f, or `None` (and nothing changed) if it would leave a non-finite value.
    pub fn update(&mut self, grad: Tensor<1>) -> Option<()> {
        let (mut first, mut second) = (self.first.clone(), self.second.clone());
        let next =
            self.flat.clone() - direction(grad, &mut first, &mut second, self.steps + 1) * self.settings.learning_rate;
        let values = next.clone().into_data().convert::<f32>().try_into_vec::<f32>().expect("f32 data");
        if !values.iter().all(|v| v.is_finite()) {
            return None;
        }
        (self.flat, self.first, self.second) = (next, first, second);
        self.steps += 1;
        Some(())
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
        assert_eq!(crop_origins(504, 128), vec![0, 188, 376]);
        assert_eq!(crop_origins(100, 100), vec![0]);
        let map = SigmaMap { height: 3, width: 4, values: (0..12).map(f64::from).collect() };
        let Log2Sigma::Map(c) = crop_log2_sigma(&Log2Sigma::Map(map), 1, 1, 2, 2) else { panic!() };
        assert_eq!(c.values, vec![5.0, 6.0, 9.0, 10.0]);
    }
}

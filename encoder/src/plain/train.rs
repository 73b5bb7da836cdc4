//! Training of plain 3D Gaussians on Burn: the 3DGS recipe (Adam with per-parameter learning
//! rates and a decaying position rate scaled by the scene extent, SH bands enabled one at a
//! time, loss 0.8 L1 + 0.2 (1 - SSIM), adaptive density control with opacity resets) on the
//! rasterizer op of [`crate::train::splat_op`].
//!
//! With a [`WrapperTraining`] configured, stage 2 (from its start iteration) swaps the
//! distortion for Wasserstein Distortion of the wrapped render and trains the synthesis
//! network f jointly ([`crate::wrapper::stage`]).
//!
//! Training never writes a non-finite value into the model: after every step the parameters
//! are checked, and a step that produced NaN or infinity is undone (see [`Trainer::step`]).

use std::time::Instant;

use anyhow::{Result, bail};
use burn::tensor::{Device, Tensor};
use pwgs_core::gaussians::{Gaussians, MAX_SH_DEGREE, sh_coeff_count};
use pwgs_core::random::SplitMix64;
use pwgs_dataset::Dataset;
use pwgs_render::raster::RenderOptions;

use super::densify::{DensifyConfig, DensifyReport, DeviceGradStats, HostState, densify, reset_opacity};
use crate::metrics::ssim::{SsimConvention, ssim};
use crate::metrics::vgg_wasserstein::VggWasserstein;
use crate::train::adam::{LearningRates, Moments};
use crate::train::device::StepTrace;
use crate::train::params::{SplatParams, tensor_values};
use crate::train::splat_op::{SplatView, render};
use crate::train::views::{DEFAULT_IMAGE_BUDGET, TrainViews};
use crate::wrapper::stage::{WrapperStage, WrapperTraining};
use pwgs_codec::wrapper::synthesis::SynthesisWeights;
use pwgs_core::frame::SceneFrame;

/// Training settings. [`TrainConfig::for_iterations`] gives the 3DGS defaults with the
/// schedule fitted to a run length.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainConfig {
    pub iterations: u32,
    /// Highest SH degree; one more band is enabled every `sh_interval` iterations.
    pub sh_degree: u32,
    pub sh_interval: u32,
    /// Degree active from the start: a model resumed from a PLY keeps the bands it has.
    pub initial_sh_degree: u32,
    /// Position learning rate at the start and the end (times the scene extent), decayed
    /// log-linearly.
    pub lr_position: [f32; 2],
    pub lr_log_scales: f32,
    pub lr_rotations: f32,
    pub lr_opacity: f32,
    pub lr_sh_dc: f32,
    /// Rate of the view-dependent SH bands (3DGS: the DC rate / 20).
    pub lr_sh_rest: f32,
    /// Weight of (1 - SSIM) in the loss; L1 gets the rest.
    pub ssim_weight: f32,
    pub densify_from: u32,
    pub densify_until: u32,
    pub densify_every: u32,
    pub opacity_reset_every: u32,
    pub densify: DensifyConfig,
    pub background: [f32; 3],
    pub seed: u64,
    /// Stage 2 with the perceptual wrapper; `None` trains the base alone.
    pub wrapper: Option<WrapperTraining>,
    /// Bytes of target images kept on the training device ([`TrainViews`]).
    pub image_budget: usize,
}

impl TrainConfig {
    /// 3DGS's settings, with densification over the first half of the run (3DGS: 500 to
    /// 15,000 of 30,000 iterations) and SH bands spread over the first half.
    pub fn for_iterations(iterations: u32) -> Self {
        Self {
            iterations,
            sh_degree: MAX_SH_DEGREE,
            sh_interval: (iterations / 6).clamp(1, 1000),
            initial_sh_degree: 0,
            lr_position: [1.6e-4, 1.6e-6],
            lr_log_scales: 5e-3,
            lr_rotations: 1e-3,
            lr_opacity: 5e-2,
            lr_sh_dc: 2.5e-3,
            lr_sh_rest: 2.5e-3 / 20.0,
            ssim_weight: 0.2,
            densify_from: 500.min(iterations / 10),
            densify_until: iterations / 2,
            densify_every: 100,
            opacity_reset_every: 3000,
            densify: DensifyConfig::default(),
            background: [0.0; 3],
            seed: 0,
            wrapper: None,
            image_budget: DEFAULT_IMAGE_BUDGET,
        }
    }

    /// The Gaussians' rates at an iteration: the 3DGS schedule, times the wrapper's
    /// `base_lr_scale` in stage 2.
    fn learning_rates(&self, iteration: u32, extent: f32) -> LearningRates {
        let t = iteration as f32 / self.iterations.max(1) as f32;
        let [start, end] = self.lr_position;
        let position = (start.ln() * (1.0 - t) + end.ln() * t).exp() * extent;
        let scale = match &self.wrapper {
            Some(w) if iteration >= w.start => w.base_lr_scale,
            _ => 1.0,
        };
        LearningRates {
            means: position * scale,
            log_scales: self.lr_log_scales * scale,
            rotations: self.lr_rotations * scale,
            opacity_logits: self.lr_opacity * scale,
            sh_dc: self.lr_sh_dc * scale,
            sh_rest: self.lr_sh_rest * scale,
        }
    }

    /// Places stage 2 after the `iterations` of stage 1 and extends the run by its
    /// `crops_per_view` steps per training view (at least `min_steps`), so that each view is
    /// scored about as often whatever the scene's size. Without a wrapper nothing changes.
    pub fn schedule_stage_two(&mut self, train_views: usize) {
        if let Some(w) = &mut self.wrapper {
            w.start = self.iterations;
            self.iterations = self.iterations.saturating_add(w.stage_two_steps(train_views));
        }
    }

    /// Active SH degree at an iteration.
    pub fn active_degree(&self, iteration: u32) -> u32 {
        (iteration / self.sh_interval.max(1)).max(self.initial_sh_degree).min(self.sh_degree)
    }
}

/// What one step reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    pub loss: f32,
    pub psnr: f32,
    pub gaussians: usize,
    pub densified: Option<DensifyReport>,
}

/// The training state.
pub struct Trainer {
    pub config: TrainConfig,
    pub params: SplatParams,
    moments: Moments,
    stats: DeviceGradStats,
    views: TrainViews,
    order: Vec<usize>,
    extent: f32,
    frame: SceneFrame,
    rng: SplitMix64,
    /// What stage 2's WD compares, loaded before training starts; moves into the stage.
    wd: Option<VggWasserstein>,
    /// Stage 2's state, from its first iteration on.
    wrapper: Option<WrapperStage>,
    device: Device,
    /// Next iteration, from 0.
    pub iteration: u32,
    /// Consecutive steps undone because they produced non-finite values.
    failed_steps: u32,
}

impl Trainer {
    /// Prepares training of `initial` (SH padded to the full degree) on the dataset's
    /// training views.
    pub fn new(config: TrainConfig, dataset: &Dataset, initial: &Gaussians, device: Device) -> Result<Self> {
        if initial.is_empty() {
            bail!("nothing to train: the initial model has no Gaussians");
        }
        if dataset.train.is_empty() {
            bail!("the dataset has no training views");
        }
        if !initial.is_consistent() {
            bail!("the initial model's arrays have inconsistent lengths");
        }
        let params = SplatParams::from_gaussians(initial, &device);
        if let Some(bad) = non_finite_parameter(&params, 0.0) {
            bail!("the initial model has NaN or infinite {bad}; repair or drop those Gaussians first");
        }
        let cameras: Vec<_> = dataset.train.iter().map(|v| v.camera).collect();
        let wd = config.wrapper.as_ref().map(|w| w.prepare(&cameras, &device)).transpose()?;
        let views = TrainViews::new(&dataset.train, config.image_budget, &device);
        Ok(Self {
            moments: Moments::zeros_like(&params),
            stats: DeviceGradStats::new(params.len(), &device),
            params,
            views,
            order: Vec::new(),
            extent: dataset.normalization.scale,
            frame: dataset.normalization.frame(),
            rng: SplitMix64(config.seed),
            wd,
            wrapper: None,
            device,
            iteration: 0,
            failed_steps: 0,
            config,
        })
    }

    /// The next view in a random order that visits every view once per epoch.
    fn next_view(&mut self) -> usize {
        if self.order.is_empty() {
            self.order = (0..self.views.len()).collect();
            self.rng.shuffle(&mut self.order);
        }
        self.order.pop().expect("refilled above")
    }

    /// One optimization step on one view, then density control when it is due.
    ///
    /// If the step leaves a non-finite value in any parameter (or the loss is not finite),
    /// the step is undone and the Adam moments restart from zero; after three such steps in a
    /// row training stops with an error naming the parameter, and the model holds the last
    /// good state.
    pub fn step(&mut self) -> Result<StepReport> {
        self.start_wrapper_if_due();
        let it = self.iteration;
        let view_index = self.next_view();
        let (camera, target) = self.views.get(view_index);
        let degree = self.config.active_degree(it);
        let n = self.params.len();
        let p = &self.params;
        let track = |t: Tensor<2>| t.autodiff().require_grad();
        let means = track(p.means.clone());
        let log_scales = track(p.log_scales.clone());
        let rotations = track(p.rotations.clone());
        let opacity = p.opacity_logits.clone().autodiff().require_grad();
        let sh = p.sh.clone().autodiff().require_grad();
        let probe = Tensor::<1>::zeros([n], &self.device).autodiff().require_grad();
        let active_sh = sh.clone().slice([0..n, 0..sh_coeff_count(degree), 0..3]);
        let step_crop = self.wrapper.as_ref().map(|stage| stage.crop(self.rng.next_u64() as usize));
        let mut view =
            SplatView::full(camera, RenderOptions { background: self.config.background, ..Default::default() });
        if let Some(c) = step_crop {
            view.window = c.window;
        }
        let image = render(
            means.clone(),
            log_scales.clone(),
            rotations.clone(),
            opacity.clone(),
            active_sh,
            probe.clone(),
            view,
        );
        // Stage 2 may keep the base's own objective on the crop of the base render.
        let pixel_term = match (&self.wrapper, step_crop) {
            (Some(stage), Some(step)) if stage.pixel_weight() > 0.0 => {
                let (c, w) = (step.crop, step.window);
                let crop = |t: Tensor<3>, x0: u32, y0: u32| {
                    let (x, y) = (x0 as usize, y0 as usize);
                    t.slice([y..y + c.height as usize, x..x + c.width as usize, 0..3])
                };
                let base = crop(image.clone(), c.x0 - w.x0, c.y0 - w.y0);
                let truth = crop(target.clone().autodiff(), c.x0, c.y0);
                Some(self.base_loss(base, truth) * stage.pixel_weight())
            }
            _ => None,
        };
        let (loss, shown, wrapper_params) = match (&mut self.wrapper, step_crop) {
            (Some(stage), Some(step)) => {
                let (wd, shown, params) = stage.loss(view_index, step, image, &target);
                (pixel_term.map_or(wd.clone(), |pixels| wd + pixels), shown, Some(params))
            }
            _ => (self.base_loss(image.clone(), target.clone().autodiff()), image, None),
        };
        // PSNR of what was rendered (in stage 2, the crop's window).
        let w = view.window;
        let (x0, y0) = (w.x0 as usize, w.y0 as usize);
        let target = target.slice([y0..y0 + w.height as usize, x0..x0 + w.width as usize, 0..3]);
        let mse = (shown.inner() - target).powi_scalar(2).mean();
        // Taken out one by one in a fixed order: gradients left in `grads` drop in hash order,
        // a different operation stream each step for Burn's fusion to explore again.
        let mut grads = loss.backward();
        let loss_value = tensor_values(loss.inner())[0];
        let psnr = -10.0 * tensor_values(mse)[0].log10();

        let grad = |g: Option<Tensor<2>>, like: &Tensor<2>| g.unwrap_or_else(|| like.zeros_like());
        let g = SplatParams {
            means: grad(means.grad_remove(&mut grads), &p.means),
            log_scales: grad(log_scales.grad_remove(&mut grads), &p.log_scales),
            rotations: grad(rotations.grad_remove(&mut grads), &p.rotations),
            opacity_logits: opacity.grad_remove(&mut grads).unwrap_or_else(|| p.opacity_logits.zeros_like()),
            sh: sh.grad_remove(&mut grads).unwrap_or_else(|| p.sh.zeros_like()),
        };
        // 3DGS thresholds the gradient with respect to normalized device coordinates, which
        // span the image with 2 units: d/d(ndc) = d/d(pixel) * size / 2.
        let ndc = 0.5 * camera.width.max(camera.height) as f32;
        let screen = probe.grad_remove(&mut grads).map(|t| t * ndc);

        let lr = self.config.learning_rates(it, self.extent);
        let updated = self.moments.step(self.params.clone(), g, &lr, it + 1);
        let wrapper_grad = wrapper_params.map(|p| p.grad_remove(&mut grads).unwrap_or_else(|| p.inner().zeros_like()));
        let mut bad = non_finite_parameter(&updated, loss_value);
        if bad.is_none()
            && let (Some(stage), Some(grad)) = (&mut self.wrapper, wrapper_grad)
            && stage.update(grad).is_none()
        {
            bad = Some("the synthesis network");
        }
        if let Some(bad) = bad {
            // `self.params` still holds the state before this step.
            self.moments = Moments::zeros_like(&self.params);
            self.failed_steps += 1;
            self.iteration += 1;
            if self.failed_steps >= 3 {
                bail!(
                    "training diverged: {bad} became non-finite at iteration {it} three steps in a row; the last good model is kept"
                );
            }
            eprintln!("warning: iteration {it}: {bad} became non-finite; step undone, optimizer state reset");
            return Ok(StepReport { loss: f32::NAN, psnr: f32::NAN, gaussians: n, densified: None });
        }
        self.failed_steps = 0;
        self.params = updated;
        if let Some(screen) = screen {
            self.stats.add(screen);
        }
        self.iteration += 1;
        let densified = self.control_density();
        Ok(StepReport { loss: loss_value, psnr, gaussians: self.params.len(), densified })
    }

    /// The base's own objective: (1 - w) L1 + w (1 - SSIM).
    fn base_loss(&self, image: Tensor<3>, target: Tensor<3>) -> Tensor<1> {
        let l1 = (image.clone() - target.clone()).abs().mean();
        let to_nchw = |t: Tensor<3>| t.permute([2, 0, 1]).unsqueeze::<4>();
        let structural = ssim(to_nchw(image), to_nchw(target), SsimConvention::ZeroPadded);
        let w = self.config.ssim_weight;
        l1 * (1.0 - w) + (structural.neg() + 1.0) * w
    }

    /// Enters stage 2 at its first iteration.
    fn start_wrapper_if_due(&mut self) {
        if let Some(settings) = &self.config.wrapper
            && self.iteration >= settings.start
            && let Some(wd) = self.wd.take()
        {
            let cameras = self.views.cameras();
            self.wrapper =
                Some(WrapperStage::new(settings.clone(), wd, cameras, self.frame, &mut self.rng, &self.device));
        }
    }

    /// The synthesis network's current (float) weights, once stage 2 has begun.
    pub fn synthesis(&self) -> Option<SynthesisWeights> {
        self.wrapper.as_ref().map(WrapperStage::weights)
    }

    /// Densification, pruning and opacity resets on their schedule.
    fn control_density(&mut self) -> Option<DensifyReport> {
        let it = self.iteration;
        let c = &self.config;
        let densify_now = it > c.densify_from && it <= c.densify_until && it.is_multiple_of(c.densify_every);
        let reset_now = it <= c.densify_until && it.is_multiple_of(c.opacity_reset_every);
        if !densify_now && !reset_now {
            return None;
        }
        let mut state = HostState {
            params: self.params.to_host(),
            first: self.moments.first.to_host(),
            second: self.moments.second.to_host(),
        };
        let mut report = None;
        if densify_now {
            let prune_large = it > c.opacity_reset_every;
            let stats = self.stats.to_host();
            let (next, r) = densify(&state, &stats, &c.densify, self.extent, prune_large, &mut self.rng);
            state = next;
            report = Some(r);
            self.stats = DeviceGradStats::new(state.params[0].len(), &self.device);
        }
        if reset_now {
            reset_opacity(&mut state, 0.01);
        }
        self.params = SplatParams::from_host(&state.params, &self.device);
        self.moments = Moments {
            first: SplatParams::from_host(&state.first, &self.device),
            second: SplatParams::from_host(&state.second, &self.device),
        };
        report
    }

    /// The current model, SH at the active degree.
    pub fn gaussians(&self) -> Gaussians {
        self.params.to_gaussians(self.config.active_degree(self.iteration))
    }
}

/// The name of the first parameter holding NaN or infinity, or "the loss".
fn non_finite_parameter(p: &SplatParams, loss: f32) -> Option<&'static str> {
    if !loss.is_finite() {
        return Some("the loss");
    }
    p.first_non_finite()
}

/// Timing and outcome of a whole run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrainSummary {
    pub iterations: u32,
    pub seconds: f64,
    pub gaussians: usize,
    pub final_loss: f32,
}

/// Runs every remaining iteration, calling `progress` after each.
pub fn train(trainer: &mut Trainer, mut progress: impl FnMut(u32, &StepReport)) -> Result<TrainSummary> {
    let start = Instant::now();
    let mut last = None;
    let mut trace = StepTrace::from_env();
    while trainer.iteration < trainer.config.iterations {
        let report = trainer.step()?;
        trace.step(trainer.iteration);
        progress(trainer.iteration, &report);
        last = Some(report);
    }
    Ok(TrainSummary {
        iterations: trainer.iteration,
        seconds: start.elapsed().as_secs_f64(),
        gaussians: trainer.params.len(),
        final_loss: last.map_or(f32::NAN, |r| r.loss),
    })
}

//! Training the anchor base for pixels (Scaffold-GS's objective: 0.8 L1 + 0.2 (1 - SSIM) +
//! 0.01 x the mean volume of the neural Gaussians), with Scaffold-GS's learning rates. Each
//! step derives the view's neural Gaussians with the same formulas as
//! [`pwgs_codec::anchor`], on tensors, and renders them with the differentiable rasterizer.
//!
//! With quantization noise on, the anchors' features, scaling and offsets are perturbed by
//! uniform noise of their quantization steps (the usual proxy for rounding, as in HAC), so that
//! the model the stream stores, rounded, renders as well as the trained one.
//!
//! With a rate term (`λ`), the loss adds λ x the mean bits per stored value under a factorized
//! Gaussian model ([`super::rate`]), and each neural Gaussian gets a learned mask (HAC's
//! straight-through `sigmoid(logit) > 0.01`): a masked Gaussian is not rendered and its offsets
//! cost nothing, so the rate pushes masks shut wherever a Gaussian is not worth its bits
//! (HAC++), and an anchor with every mask shut leaves the stream.
//!
//! With a [`WrapperTraining`], stage 2 (from its start iteration) scores a crop of each step's
//! view with WD through the perceptual wrapper f, which trains jointly, exactly as on the plain
//! base ([`crate::wrapper::stage`]); the rate term stays on, its λ scaled to WD's size
//! ([`StageTwoLambda`]).
//!
//! With a context model ([`super::context`]), the rate's means and scales come per anchor
//! from the model's grid and network instead of per channel.
//!
//! With a [`GrowthSchedule`], anchors are grown where neural Gaussians keep large screen
//! gradients and pruned where they stay transparent ([`super::growth`]); the context model's
//! lookup is rebuilt for the new anchors.

use anyhow::{Result, bail};
use burn::tensor::activation::{log_sigmoid, sigmoid};
use burn::tensor::{Device, Tensor, TensorData};
use pwgs_codec::anchor::AnchorModel;
use pwgs_codec::stream::anchor_context::predicted_values;
use pwgs_codec::stream::plain::PositionGrid;
use pwgs_core::gaussians::SH_C0;
use pwgs_core::random::SplitMix64;
use pwgs_dataset::Dataset;
use pwgs_render::raster::RenderOptions;

mod growth_event;
mod noise_pool;
mod rate_term;
mod stage_two_lambda;

use noise_pool::NoisePool;

use stage_two_lambda::DistortionScale;
pub use stage_two_lambda::StageTwoLambda;

use super::context::ContextLookup;
use super::growth::{DeviceAnchorStats, GrowthSchedule};
use super::host::{host_tensor, mlp_of, mlp_tensors};
use super::quantize::{AnchorSteps, TrainedContext};
use crate::metrics::ssim::{SsimConvention, ssim};
use crate::metrics::vgg_wasserstein::VggWasserstein;
use crate::train::adam::direction;
use crate::train::params::tensor_values;
use crate::train::splat_op::{SplatView, render};
use crate::train::views::{DEFAULT_IMAGE_BUDGET, TrainViews};
use crate::wrapper::stage::{WrapperStage, WrapperTraining};
use pwgs_codec::wrapper::synthesis::SynthesisWeights;
use pwgs_core::frame::SceneFrame;

/// The trained tensors, in this order: features [N, F], scaling [N, 6], offsets [N, 3K], then
/// for each MLP (opacity, color, covariance) W1 [in, hidden], b1 [1, hidden], W2 [hidden, out],
/// b2 [1, out]; then mask logits [N, K]; then the rate model's mean and log scale per channel
/// of features [1, F], scaling [1, 6] and offsets [1, 3] (one per axis, as the stream's tables);
/// then, with a context model, its grid and MLP ([`ContextLookup::initial_parameters`]).
const PARAMETERS: usize = 22;

/// Index of the mask logits among the parameters, and of the first rate-model tensor.
const MASK_LOGITS: usize = 15;
const RATE_MODEL: usize = 16;

/// A mask is open while sigmoid(logit) > 0.01, i.e. logit > ln(0.01 / 0.99).
const MASK_THRESHOLD_LOGIT: f32 = -4.595_12;

/// Initial mask logit (sigmoid 0.12): near enough to the threshold that a short run can shut
/// the masks the rate does not pay for (HAC starts at 0.73 with 30,000 iterations to go).
const INITIAL_MASK_LOGIT: f32 = -2.0;

/// Learning rates at the start and the end of training (log-linear decay), per parameter
/// group, from Scaffold-GS; the offsets' rates are also scaled by the scene extent.
const RATES: [[f32; 2]; 8] = [
    [0.0075, 0.0075], // features
    [0.007, 0.007],   // scaling
    [0.01, 1e-4],     // offsets
    [0.002, 2e-5],    // opacity MLP
    [0.008, 5e-5],    // color MLP
    [0.004, 0.004],   // covariance MLP
    [0.01, 0.01],     // mask logits
    [0.005, 0.005],   // rate model
];

/// The anchors' learning rates in stage 2 (the wrapper's), as a multiple of stage 1's: their
/// MLPs are shared by every Gaussian, and at full rate WD pulled them from the pixels. On fern
/// (1,000 + 1,000 iterations) 0.1 gave 256 KB, DISTS 0.066, LPIPS 0.190, 25.9 dB where 1 gave
/// 285 KB, DISTS 0.065, LPIPS 0.202, 24.0 dB. The mask logits are excepted (see `rate`).
pub const ANCHOR_STAGE_TWO_LR_SCALE: f32 = 0.1;

/// Learned step factors stay within e^±this (×0.1 to ×10) of the base steps.
const LOG_STEP_RANGE: f32 = 2.3;

/// Weight of the neural Gaussians' mean volume in the loss (Scaffold-GS).
const VOLUME_WEIGHT: f32 = 0.01;

/// The anchor trainer's state.
pub struct AnchorTrainer {
    positions: Tensor<2>,
    params: Vec<Tensor<2>>,
    moments: Vec<(Tensor<2>, Tensor<2>)>,
    shape: [usize; 3],
    /// The masks [N, K] (1 open, 0 shut) while the rate term does not learn them.
    masks: Tensor<2>,
    views: TrainViews,
    background: [f32; 3],
    extent: f32,
    rng: SplitMix64,
    /// Quantization steps of features, scaling and offsets, and the iteration from which
    /// their noise is on.
    noise: Option<(AnchorSteps, u32)>,
    noise_pool: Option<NoisePool>,
    /// λ and the iteration from which the rate term and the learned masks are on.
    rate_term: Option<(f32, u32)>,
    /// The context model that replaces the factorized one in the rate term, when on.
    context: Option<ContextLookup>,
    /// Where the log factors [1, 3] on the three groups' steps are among the parameters, when
    /// the steps are learned.
    learned_steps: Option<usize>,
    /// Stage 2's settings and what its WD compares, until it starts; then the stage.
    wrapper_settings: Option<(WrapperTraining, VggWasserstein)>,
    wrapper: Option<WrapperStage>,
    /// With a stage 2: λ's factor there, from the running means of both stages' distortions.
    distortion_scale: Option<DistortionScale>,
    placement: Option<Placement>,
    growth: Option<Growth>,
    frame: SceneFrame,
    pub iteration: u32,
    pub iterations: u32,
}

/// The grid the anchors sit on and their voxels on it, in the trainer's order: growth places
/// new anchors on it, and the rate term codes the open anchors' voxels as the stream does.
struct Placement {
    grid: PositionGrid,
    voxels: Vec<[u32; 3]>,
    /// The rate term's side bits per open anchor ([`rate_term::side_bits`]) and the iteration
    /// they were counted at.
    side_bits: Option<(u32, f32)>,
}

/// Growing and pruning: when, what the steps since the last event saw, and the totals so far.
struct Growth {
    schedule: GrowthSchedule,
    stats: DeviceAnchorStats,
    totals: GrowthTotals,
}

/// Anchors added and removed over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct GrowthTotals {
    pub grown: usize,
    pub pruned: usize,
}

/// What one step reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnchorStep {
    pub loss: f32,
    pub psnr: f32,
    /// Neural Gaussians rendered.
    pub gaussians: usize,
    /// Mean bits per stored value under the rate model, while the rate term is on.
    pub bits_per_value: Option<f32>,
    /// Open masks, out of N x K.
    pub open_masks: usize,
}

/// Scaffold-GS's pixel objective: 0.8 L1 + 0.2 (1 - SSIM).
pub(crate) fn pixel_loss(image: Tensor<3>, target: Tensor<3>) -> Tensor<1> {
    let l1 = (image.clone() - target.clone()).abs().mean();
    let to_nchw = |t: Tensor<3>| t.permute([2, 0, 1]).unsqueeze::<4>();
    let structural = ssim(to_nchw(image), to_nchw(target), SsimConvention::ZeroPadded);
    l1 * 0.8 + (structural.neg() + 1.0) * 0.2
}

/// Straight-through masks [N, K] from their logits: `masks` (1 or 0) forward, the sigmoid's
/// gradient backward.
fn mask_gate(logits: Tensor<2>, masks: Tensor<2>) -> Tensor<2> {
    let soft = sigmoid(logits);
    soft.clone() - soft.detach() + masks.autodiff()
}

/// relu(x W1 + b1) W2 + b2 for rows x.
fn forward(x: Tensor<2>, t: &[Tensor<2>]) -> Tensor<2> {
    (x.matmul(t[0].clone()) + t[1].clone()).clamp_min(0.0).matmul(t[2].clone()) + t[3].clone()
}

impl AnchorTrainer {
    /// Prepares `iterations` steps of training `initial` on the dataset's training views, on
    /// `device` (the wrapper of stage 2 trains there too).
    pub fn new(
        initial: &AnchorModel,
        data: &Dataset,
        iterations: u32,
        background: [f32; 3],
        seed: u64,
        device: &Device,
    ) -> Result<Self> {
        if initial.is_empty() || !initial.is_consistent() {
            bail!("the initial anchor model is empty or inconsistent");
        }
        if data.train.is_empty() {
            bail!("the dataset has no training views");
        }
        let device = device.clone();
        let (n, f, k) = (initial.len(), initial.feature_dim, initial.offsets_per_anchor);
        let positions: Vec<f32> = initial.positions.iter().flatten().copied().collect();
        let scaling: Vec<f32> = initial.scaling.iter().flatten().copied().collect();
        let mut params = Vec::with_capacity(PARAMETERS);
        params.extend([
            host_tensor(&initial.features, [n, f], &device),
            host_tensor(&scaling, [n, 6], &device),
            host_tensor(&initial.offsets, [n, 3 * k], &device),
        ]);
        for m in [&initial.opacity, &initial.color, &initial.covariance] {
            params.extend(mlp_tensors(m, &device));
        }
        let open: Vec<f32> = initial.masks.iter().map(|&m| f32::from(u8::from(m))).collect();
        let logits: Vec<f32> = initial
            .masks
            .iter()
            .map(|&open| if open { INITIAL_MASK_LOGIT } else { 2.0 * MASK_THRESHOLD_LOGIT })
            .collect();
        params.push(host_tensor(&logits, [n, k], &device));
        for width in [f, 6, 3] {
            params.push(Tensor::zeros([1, width], &device));
            params.push(Tensor::zeros([1, width], &device));
        }
        let views = TrainViews::new(&data.train, DEFAULT_IMAGE_BUDGET, &device);
        Ok(Self {
            positions: host_tensor(&positions, [n, 3], &device),
            moments: params.iter().map(|p| (p.zeros_like(), p.zeros_like())).collect(),
            params,
            shape: [n, f, k],
            masks: host_tensor(&open, [n, k], &device),
            views,
            background,
            extent: data.normalization.scale,
            rng: SplitMix64(seed),
            noise: None,
            noise_pool: None,
            rate_term: None,
            context: None,
            learned_steps: None,
            wrapper_settings: None,
            wrapper: None,
            distortion_scale: None,
            placement: None,
            growth: None,
            frame: data.normalization.frame(),
            iteration: 0,
            iterations,
        })
    }

    /// Keeps at most `bytes` of target images on the training device ([`TrainViews`]).
    pub fn with_image_budget(mut self, bytes: usize) -> Self {
        self.views.set_budget(bytes);
        self
    }

    /// Trains with the quantization noise of `steps` from iteration `from` on.
    pub fn with_quantization_noise(mut self, steps: AnchorSteps, from: u32) -> Self {
        self.noise = Some((steps, from));
        self
    }

    /// Adds λ x the rate to the loss and learns the masks from iteration `from` on (needs the
    /// quantization noise: the rate is that of the noisy values).
    pub fn with_rate(mut self, lambda: f32, from: u32) -> Self {
        self.rate_term = Some((lambda, from));
        self
    }

    /// Places the anchors on `grid` at `voxels` (one per anchor, in the model's order), as the
    /// stream will: growth needs it, and with it the rate term also counts what each open
    /// anchor costs besides its values (its position and masks, [`rate_term::side_bits`]).
    pub fn with_placement(mut self, grid: PositionGrid, voxels: Vec<[u32; 3]>) -> Self {
        assert_eq!(voxels.len(), self.shape[0], "one voxel per anchor");
        self.placement = Some(Placement { grid, voxels, side_bits: None });
        self
    }

    /// Takes the rate of every anchor's values from the context model of `lookup` (made for
    /// this model's anchors, in its order) instead of the factorized model.
    pub fn with_context(mut self, lookup: ContextLookup) -> Self {
        assert_eq!(self.params.len(), PARAMETERS, "the context model's tensors follow the base's");
        let [_, f, k] = self.shape;
        let outputs = 2 * predicted_values(f, k);
        let device = self.positions.device();
        for p in lookup.initial_parameters(outputs, &mut self.rng, &device) {
            self.moments.push((p.zeros_like(), p.zeros_like()));
            self.params.push(p);
        }
        self.context = Some(lookup);
        self
    }

    /// With a context model: the bits its grid's used signs take (an adaptive binary coder's
    /// estimate).
    pub fn context_grid_bits(&self) -> Option<f64> {
        let lookup = self.context.as_ref()?;
        Some(lookup.grid_bits(&tensor_values(self.params[PARAMETERS].clone())))
    }

    /// The trained context model, when there is one.
    pub fn context_model(&self) -> Option<TrainedContext> {
        let lookup = self.context.as_ref()?;
        Some(TrainedContext {
            shape: lookup.shape.clone(),
            grid: tensor_values(self.params[PARAMETERS].clone()),
            mlp: mlp_of(&self.params[PARAMETERS + 1..PARAMETERS + 5]),
        })
    }

    /// Trains the perceptual wrapper from `settings.start` on. Loads what WD compares now, so
    /// that missing weights are reported before any training.
    pub fn with_wrapper(mut self, settings: WrapperTraining) -> Result<Self> {
        let wd = settings.prepare(self.views.cameras(), &self.positions.device())?;
        self.wrapper_settings = Some((settings, wd));
        self.distortion_scale = Some(DistortionScale::new(StageTwoLambda::Scaled));
        Ok(self)
    }

    /// How λ carries over into stage 2 ([`Self::with_wrapper`] scales it by the distortions'
    /// ratio); without a stage 2 there is nothing to carry over.
    pub fn with_stage_two_lambda(mut self, rule: StageTwoLambda) -> Self {
        self.distortion_scale = self.distortion_scale.map(|_| DistortionScale::new(rule));
        self
    }

    /// λ's factor now: 1 in stage 1, in stage 2 what [`StageTwoLambda`] makes of the
    /// distortions so far.
    pub fn lambda_factor(&self) -> f32 {
        self.distortion_scale.as_ref().map_or(1.0, |scale| scale.factor(self.wrapper.is_some()))
    }

    /// The synthesis network's current (float) weights, once stage 2 has begun.
    pub fn synthesis(&self) -> Option<SynthesisWeights> {
        self.wrapper.as_ref().map(WrapperStage::weights)
    }

    /// Enters stage 2 at its first iteration.
    fn start_wrapper_if_due(&mut self) {
        if self.wrapper_settings.as_ref().is_some_and(|(s, _)| self.iteration >= s.start)
            && let Some((settings, wd)) = self.wrapper_settings.take()
        {
            let device = self.positions.device();
            let cameras = self.views.cameras();
            self.wrapper = Some(WrapperStage::new(settings, wd, cameras, self.frame, &mut self.rng, &device));
        }
    }

    /// λ, while the rate term is on.
    fn lambda(&self) -> Option<f32> {
        let (lambda, from) = self.rate_term?;
        (self.iteration >= from && self.noise.is_some()).then_some(lambda)
    }

    /// The masks [N, K] as the stream stores them (1 open, 0 shut): fixed ones until the rate
    /// term starts learning them.
    fn open_masks(&self) -> Tensor<2> {
        match self.rate_term {
            Some(_) => self.params[MASK_LOGITS].clone().greater_elem(MASK_THRESHOLD_LOGIT).float(),
            None => self.masks.clone(),
        }
    }

    /// Uniform noise in ±1/2 shaped like parameter `i` (to be scaled by its step), or `None`
    /// while noise is off.
    fn quantization_noise(&mut self, i: usize) -> Option<Tensor<2>> {
        let (_, from) = self.noise?;
        if self.iteration < from {
            return None;
        }
        let shape = self.params[i].dims();
        let window = shape[0] * shape[1];
        if !self.noise_pool.as_ref().is_some_and(|pool| pool.fits(window)) {
            let largest = (0..3).map(|j| self.params[j].shape().num_elements()).max().unwrap_or(window);
            self.noise_pool = Some(NoisePool::new(largest, &mut self.rng, &self.positions.device()));
        }
        self.noise_pool.as_ref().map(|pool| pool.draw(shape, &mut self.rng))
    }

    /// The learning rate of parameter `i` at the current iteration (in stage 2, times the
    /// wrapper's `base_lr_scale`, but for the masks).
    fn rate(&self, i: usize) -> f32 {
        let group = match i {
            0..3 => i,
            MASK_LOGITS => 6,
            RATE_MODEL.. => 7,
            _ => 3 + (i - 3) / 4,
        };
        let [start, end] = RATES[group];
        let t = self.iteration as f32 / self.iterations.max(1) as f32;
        // The masks answer to the rate, which stage 2 raises: they keep stage 1's learning
        // rate. On fern at λ 0.05 that made 73,322 bytes at DISTS 0.1275, where masks at a tenth
        // made 100,662 bytes at 0.1096 and the anchor base alone 73,429 bytes at 0.1645.
        let stage_two =
            if i == MASK_LOGITS { 1.0 } else { self.wrapper.as_ref().map_or(1.0, WrapperStage::base_lr_scale) };
        let rate = (start.ln() * (1.0 - t) + end.ln() * t).exp() * stage_two;
        if group == 2 { rate * self.extent } else { rate }
    }

    /// One step on a random training view.
    pub fn step(&mut self) -> Result<AnchorStep> {
        self.start_wrapper_if_due();
        let [n, _, k] = self.shape;
        let view_index = (self.rng.next_u64() % self.views.len() as u64) as usize;
        let (camera, target) = self.views.get(view_index);
        let device = self.positions.device();
        let tracked: Vec<Tensor<2>> = self.params.iter().map(|p| p.clone().autodiff().require_grad()).collect();
        // Features, scaling and offsets as the step sees them: with quantization noise when on.
        let steps = self.step_tensors(&tracked);
        let attributes: Vec<Tensor<2>> = (0..3)
            .map(|i| match (self.quantization_noise(i), &steps) {
                (Some(noise), Some(steps)) => tracked[i].clone() + noise.autodiff() * steps[i].clone(),
                _ => tracked[i].clone(),
            })
            .collect();
        let center = Tensor::<2>::from_data(TensorData::new(camera.center().to_array().to_vec(), [1, 3]), &device);
        let v = self.positions.clone() - center;
        let d = (v.clone() * v.clone()).sum_dim(1).sqrt();
        let input = Tensor::cat(vec![attributes[0].clone(), (v / d.clone()).autodiff(), d.autodiff()], 1);
        let alpha = forward(input.clone(), &tracked[3..7]).tanh();
        let lambda = self.lambda();
        let masks = if lambda.is_some() { self.open_masks() } else { self.masks.clone() };
        let mask_gate = mask_gate(tracked[MASK_LOGITS].clone(), masks.clone());
        // The kept neural Gaussians: positive opacity and an open mask. Every Gaussian is
        // rendered, the others at an opacity the rasterizer culls (and so with no gradient),
        // which keeps the step's shapes and the choice on the device.
        let opacity = alpha.clone().inner().reshape([n * k]);
        let kept = opacity.clone().greater_elem(0.0).float() * masks.clone().reshape([n * k]);
        let dropped = kept.clone().lower_elem(0.5).reshape([n * k, 1]);
        let per_anchor = |t: Tensor<2>, width: usize| t.unsqueeze_dim::<3>(1).repeat_dim(1, k).reshape([n * k, width]);
        let alpha = if lambda.is_some() { alpha * mask_gate.clone() } else { alpha };
        let alpha = alpha.reshape([n * k, 1]).clamp(1e-6, 1.0 - 1e-6).mask_fill(dropped.clone(), 1e-6);
        let color = sigmoid(forward(input.clone(), &tracked[7..11])).reshape([n * k, 3]);
        let cov = forward(input, &tracked[11..15]).reshape([n * k, 7]);
        let scaling = per_anchor(attributes[1].clone(), 6);
        let anchors = per_anchor(self.positions.clone().autodiff(), 3);
        let offsets = attributes[2].clone().reshape([n * k, 3]);
        let means = anchors + offsets * scaling.clone().slice([0..n * k, 0..3]).exp();
        let log_scales = scaling.slice([0..n * k, 3..6]) + log_sigmoid(cov.clone().slice([0..n * k, 0..3]));
        let rotations = cov.slice([0..n * k, 3..7]);
        let opacity_logits = (alpha.clone() / (alpha.neg() + 1.0)).log().reshape([n * k]);
        let sh = ((color - 0.5) / SH_C0).reshape([n * k, 1, 3]);
        let gathering = self.growth.as_ref().is_some_and(|g| self.iteration < g.schedule.until);
        let probe = Tensor::<1>::zeros([n * k], &device).autodiff();
        let probe = if gathering { probe.require_grad() } else { probe };
        let step_crop = self.wrapper.as_ref().map(|stage| stage.crop(self.rng.next_u64() as usize));
        let mut view = SplatView::full(camera, RenderOptions { background: self.background, ..Default::default() });
        if let Some(c) = step_crop {
            view.window = c.window;
        }
        let image = render(means, log_scales.clone(), rotations, opacity_logits, sh, probe.clone(), view);
        // The mean over the kept Gaussians (exp(-inf) = 0 has no gradient, where a dropped
        // Gaussian's overflowing volume times 0 would make a NaN).
        let kept_count = kept.sum();
        let volume = log_scales.sum_dim(1).mask_fill(dropped, f32::NEG_INFINITY).exp().sum() / kept_count.clone()
            * VOLUME_WEIGHT;
        let (distortion, shown, wrapper_params) = match (&mut self.wrapper, step_crop) {
            (Some(stage), Some(step)) => {
                // WD of the wrapped crop, plus the base's objective on the crop when weighted.
                let (c, w) = (step.crop, step.window);
                let crop = |t: Tensor<3>, x0: u32, y0: u32| {
                    let (x, y) = (x0 as usize, y0 as usize);
                    t.slice([y..y + c.height as usize, x..x + c.width as usize, 0..3])
                };
                let weight = stage.pixel_weight();
                let pixels = (weight > 0.0).then(|| {
                    let base = crop(image.clone(), c.x0 - w.x0, c.y0 - w.y0);
                    pixel_loss(base, crop(target.clone().autodiff(), c.x0, c.y0)) * weight
                });
                let (wd, shown, params) = stage.loss(view_index, step, image, &target);
                (pixels.map_or(wd.clone(), |p| wd + p), shown, Some(params))
            }
            _ => (pixel_loss(image.clone(), target.clone().autodiff()), image, None),
        };
        let w = view.window;
        let (x0, y0) = (w.x0 as usize, w.y0 as usize);
        let seen = target.slice([y0..y0 + w.height as usize, x0..x0 + w.width as usize, 0..3]);
        let mse = (shown.inner() - seen).powi_scalar(2).mean();
        let mut loss = distortion.clone() + volume;
        let mut bits = None;
        if let Some(lambda) = lambda {
            let steps = steps.expect("the rate needs the quantization steps");
            let side = self.side_bits(&masks)?;
            let bpp = self.mean_bits(&attributes, &tracked, &steps, mask_gate, masks.clone(), side);
            bits = Some(bpp.clone().inner());
            loss = loss + bpp * (lambda * self.lambda_factor());
        }
        // Gradients are taken out of `grads` one by one in a fixed order: what is left in it
        // drops in hash order, a different operation stream each step, which Burn's fusion
        // would explore again every step.
        let mut grads = loss.backward();
        // The step's one read-back: its scalars.
        let zero = || Tensor::<1>::zeros([1], &device);
        let scalars =
            [loss.inner(), distortion.inner(), bits.clone().unwrap_or_else(zero), mse, kept_count, masks.sum()];
        let [loss_value, distortion_value, bits_value, mse, kept, open] =
            tensor_values(Tensor::cat(scalars.to_vec(), 0)).try_into().expect("six scalars");
        if kept == 0.0 {
            bail!("no anchor gives a visible Gaussian at iteration {}", self.iteration);
        }
        if !loss_value.is_finite() {
            bail!("anchor training diverged at iteration {}: the loss is {loss_value}", self.iteration);
        }
        if let Some(scale) = &mut self.distortion_scale {
            scale.record(self.wrapper.is_some(), distortion_value);
        }
        if gathering && let (Some(growth), Some(screen)) = (&mut self.growth, probe.grad_remove(&mut grads)) {
            // As 3DGS, in normalized device coordinates: d/d(ndc) = d/d(pixel) * size / 2.
            let ndc = 0.5 * camera.width.max(camera.height) as f32;
            growth.stats.add(screen.abs() * ndc, opacity);
        }
        let wrapper_grad = wrapper_params.map(|p| p.grad_remove(&mut grads).unwrap_or_else(|| p.inner().zeros_like()));
        if let (Some(stage), Some(grad)) = (&mut self.wrapper, wrapper_grad)
            && stage.update(grad).is_none()
        {
            bail!("anchor training diverged at iteration {}: the synthesis network became non-finite", self.iteration);
        }
        for (i, t) in tracked.iter().enumerate() {
            let grad = t.grad_remove(&mut grads).unwrap_or_else(|| self.params[i].zeros_like());
            let rate = self.rate(i);
            let (first, second) = &mut self.moments[i];
            self.params[i] = self.params[i].clone() - direction(grad, first, second, self.iteration + 1) * rate;
        }
        self.iteration += 1;
        if self.growth.as_ref().is_some_and(|g| g.schedule.is_event(self.iteration)) {
            self.grow_and_prune();
        }
        let psnr = -10.0 * mse.log10();
        let bits_per_value = bits.map(|_| bits_value);
        Ok(AnchorStep { loss: loss_value, psnr, gaussians: kept as usize, bits_per_value, open_masks: open as usize })
    }

    pub fn device(&self) -> Device {
        self.positions.device()
    }

    /// Values the rate term's mean is taken over: N x (F + 6 + 3K).
    pub fn rated_values(&self) -> usize {
        let [n, f, k] = self.shape;
        n * predicted_values(f, k)
    }

    /// The current model, as a decoder holds it.
    pub fn model(&self) -> AnchorModel {
        let [_, f, k] = self.shape;
        let rows = |i: usize| tensor_values(self.params[i].clone());
        let positions = tensor_values(self.positions.clone());
        let scaling = rows(1);
        AnchorModel {
            feature_dim: f,
            offsets_per_anchor: k,
            positions: positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            features: rows(0),
            scaling: scaling.chunks_exact(6).map(|c| [c[0], c[1], c[2], c[3], c[4], c[5]]).collect(),
            offsets: rows(2),
            masks: tensor_values(self.open_masks()).into_iter().map(|m| m > 0.5).collect(),
            opacity: mlp_of(&self.params[3..7]),
            color: mlp_of(&self.params[7..11]),
            covariance: mlp_of(&self.params[11..15]),
        }
    }
}

//! Stage 2's throughput on a device, without the splat operation: each step runs f and WD
//! (VGG16 features, the defaults' depth) on a crop of a fixed base image, forward and
//! backward, and f's Adam step, as stage 2 does after rendering. The splat operation's own
//! time is the rasterizer benchmark's; the two add up to a stage-2 step.

use std::time::Instant;

use anyhow::{Result, bail};
use burn::tensor::{Distribution, Tensor};
use glam::Vec3;
use pwgs_codec::wrapper::synthesis::WrapperConfig;
use pwgs_core::frame::SceneFrame;
use pwgs_core::random::{SplitMix64, axis_camera};

use crate::metrics::sigma_map::Log2Sigma;
use crate::metrics::vgg_wasserstein::{VggWasserstein, WdDepth};
use crate::metrics::vgg16::{VGG_BLOCKS, Vgg16};
use crate::train::device::TrainingDevice;
use crate::wrapper::stage::{DEFAULT_WD_SCALES, WdFeatures, WrapperStage, WrapperTraining};

/// What [`stage_two_throughput`] measured.
#[derive(Debug, Clone)]
pub struct StageTwoTiming {
    /// The first step alone: it also computes the target's features and compiles kernels.
    pub first_step_seconds: f64,
    /// The steps after the first.
    pub steps_per_second: f64,
    /// The device's reserved memory after the last step, where the backend says it.
    pub bytes_reserved: Option<u64>,
}

/// Times `steps` stage-2 steps (after one untimed warm-up step) on `width` x `height` views with
/// `crop`-pixel crops (`crop` at least the larger side: whole images), with f at the defaults
/// (16 channels, noise and Plücker inputs) and a VGG16 of random weights.
pub fn stage_two_throughput(
    device: &TrainingDevice,
    (width, height): (u32, u32),
    crop: usize,
    steps: usize,
) -> Result<StageTwoTiming> {
    if steps == 0 {
        bail!("time at least one step");
    }
    let focal = 0.8 * width as f32;
    let camera = axis_camera(width, height, focal, focal, 0.5 * width as f32, 0.5 * height as f32);
    let settings = WrapperTraining {
        config: WrapperConfig { width: 16, noise: true, plucker: true, seed: 1 },
        start: 0,
        crops_per_view: 1,
        min_steps: 0,
        log2_sigma: Log2Sigma::Constant(4.0),
        crop,
        learning_rate: 5e-3,
        base_lr_scale: 1.0,
        features: WdFeatures::Pixels,
        wd_depth: WdDepth { blocks: VGG_BLOCKS, scales: DEFAULT_WD_SCALES },
        pixel_weight: 0.0,
        cache_bytes: 1 << 30,
    };
    let d = &device.device;
    let wd = VggWasserstein::with_network(Vgg16::random(2, d)).with_depth(settings.wd_depth);
    let frame = SceneFrame { center: Vec3::ZERO, scale: 1.0 };
    let mut stage = WrapperStage::new(settings, wd, &[camera], frame, &mut SplitMix64(3), d);
    let (w, h) = (width as usize, height as usize);
    let target: Tensor<3> = Tensor::random([h, w, 3], Distribution::Uniform(0.0, 1.0), d);
    let base: Tensor<3> = Tensor::random([h, w, 3], Distribution::Uniform(0.0, 1.0), d);
    let mut step = |i: usize| -> Result<()> {
        let crop = stage.crop(i);
        let (x, y) = (crop.window.x0 as usize, crop.window.y0 as usize);
        let (cw, ch) = (crop.window.width as usize, crop.window.height as usize);
        // The render's place in the graph: a tracked tensor, as the splat operation's output is.
        let image = base.clone().slice([y..y + ch, x..x + cw, 0..3]).autodiff().require_grad();
        let (loss, _, params) = stage.loss(0, crop, image, &target);
        let mut grads = loss.backward();
        let grad = params.grad_remove(&mut grads).unwrap_or_else(|| params.inner().zeros_like());
        if stage.update(grad).is_none() {
            bail!("the synthesis network became non-finite");
        }
        device.sync()
    };
    let start = Instant::now();
    step(0)?;
    let first_step_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    for i in 1..=steps {
        step(i)?;
    }
    let steps_per_second = steps as f64 / start.elapsed().as_secs_f64();
    Ok(StageTwoTiming { first_step_seconds, steps_per_second, bytes_reserved: device.bytes_reserved() })
}

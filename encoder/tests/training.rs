//! Training on the generated scene: it learns, it never keeps a non-finite value, and a model
//! exported to PLY resumes exactly.

use burn::tensor::Device;
use pwgs_codec::scene::{Base, Scene};
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_dataset::{Dataset, LoadOptions, load_scene};
use pwgs_encoder::metrics::evaluate::{MeanScore, evaluate};
use pwgs_encoder::plain::compress::{QuantizerSettings, StreamContext, compress};
use pwgs_encoder::plain::init::initial_gaussians;
use pwgs_encoder::plain::train::{TrainConfig, Trainer, train};

fn small_scene(dir: &std::path::Path) -> Dataset {
    let options = SyntheticOptions { width: 80, height: 60, views: 16, seed: 4, points: 1500 };
    generate(dir, &options).unwrap();
    load_scene(dir, &LoadOptions::default()).unwrap()
}

fn mean_psnr(g: &pwgs_core::gaussians::Gaussians, data: &Dataset) -> f64 {
    let scene =
        Scene { base: Base::Plain(g.clone()), wrapper: None, frame: data.normalization.frame(), background: [0.0; 3] };
    MeanScore::of(&evaluate(&scene, &data.test, None, None).unwrap()).psnr
}

/// The README's main job: the default generated scene, 600 iterations.
#[test]
fn the_main_job_reaches_its_psnr() {
    let tmp = tempfile::tempdir().unwrap();
    generate(tmp.path(), &SyntheticOptions::default()).unwrap();
    let data = load_scene(tmp.path(), &LoadOptions::default()).unwrap();
    let initial = initial_gaussians(&data, 0, usize::MAX).unwrap();
    let before = mean_psnr(&initial, &data);
    let mut trainer = Trainer::new(TrainConfig::for_iterations(600), &data, &initial, Device::flex()).unwrap();
    let summary = train(&mut trainer, |_, _| {}).unwrap();
    assert_eq!(summary.iterations, 600);
    let after = mean_psnr(&trainer.gaussians(), &data);
    eprintln!("test-view PSNR {before:.2} dB at initialization, {after:.2} dB after 600 iterations");
    assert!(after > before + 5.0, "training gained only {:.2} dB", after - before);
    // Measured 25.27 dB when this test was written (`pwenc demo --iters 600`, from 9.2 dB);
    // 2 dB of margin absorbs platform differences in floating point and small schedule changes.
    assert!(after > 23.27, "test-view PSNR {after:.2} dB");
    // The README writes the model as a stream at the default quality: the decoded stream lost
    // 0.29 dB (24.98 against 25.27 dB) when this was written; it must stay within 0.6 dB.
    let model = trainer.gaussians();
    let n = data.normalization;
    let context = StreamContext { center: n.center.to_array(), scale: n.scale, background: [0.0; 3] };
    let stream = compress(&model, &QuantizerSettings::default(), &context, None).unwrap();
    let decoded = mean_psnr(stream.decoded.scene.plain_gaussians().unwrap(), &data);
    eprintln!("decoded stream: {decoded:.2} dB, {} bytes", stream.bytes.len());
    assert!(decoded > after - 0.6, "the stream lost {:.2} dB", after - decoded);
    assert!(stream.bytes.len() * 8 < pwgs_core::ply::inria_ply_size(&model));
}

#[test]
fn a_diverging_step_is_undone_and_training_stops_with_the_last_good_model() {
    let tmp = tempfile::tempdir().unwrap();
    let data = small_scene(tmp.path());
    let initial = initial_gaussians(&data, 0, usize::MAX).unwrap();
    let mut config = TrainConfig::for_iterations(50);
    config.lr_log_scales = f32::INFINITY;
    let mut trainer = Trainer::new(config, &data, &initial, Device::flex()).unwrap();
    let error = train(&mut trainer, |_, _| {}).unwrap_err().to_string();
    assert!(error.contains("log_scales") && error.contains("iteration 2"), "{error}");
    let kept = trainer.gaussians();
    assert_eq!(kept.log_scales, initial.log_scales, "the model holds the state before the bad steps");
    assert!(kept.means.iter().flatten().chain(kept.sh.iter()).all(|v| v.is_finite()));
}

#[test]
fn non_finite_initial_models_are_rejected() {
    let tmp = tempfile::tempdir().unwrap();
    let data = small_scene(tmp.path());
    let mut initial = initial_gaussians(&data, 0, usize::MAX).unwrap();
    initial.opacity_logits[7] = f32::NAN;
    let error = Trainer::new(TrainConfig::for_iterations(10), &data, &initial, Device::flex()).err().unwrap();
    assert!(error.to_string().contains("opacity_logits"), "{error}");
}

#[test]
fn training_resumes_from_an_exported_ply() {
    let tmp = tempfile::tempdir().unwrap();
    let data = small_scene(&tmp.path().join("scene"));
    let initial = initial_gaussians(&data, 0, usize::MAX).unwrap();
    let mut trainer = Trainer::new(TrainConfig::for_iterations(60), &data, &initial, Device::flex()).unwrap();
    train(&mut trainer, |_, _| {}).unwrap();
    let trained = trainer.gaussians();
    let path = tmp.path().join("model.ply");
    pwgs_core::ply::write_gaussians(&path, &trained).unwrap();
    let loaded = pwgs_core::ply::read_gaussians(&path).unwrap().gaussians;
    assert_eq!(loaded, trained, "the PLY round trip is exact");
    // A resumed run starts from exactly the exported model.
    let resumed = Trainer::new(TrainConfig::for_iterations(10), &data, &loaded, Device::flex()).unwrap();
    assert_eq!(resumed.params.to_gaussians(trained.sh_degree), trained);
    assert_eq!(mean_psnr(&resumed.params.to_gaussians(trained.sh_degree), &data), mean_psnr(&trained, &data));
}

/// Stage 2's pixel term adds the base's own objective on the crop of the base render to WD:
/// the same first step with and without it differs by a loss in (0, 1].
/// Pixel-feature stage-2 settings from the first iteration on, for the tests.
fn stage_two_settings(pixel_weight: f32, base_lr_scale: f32) -> pwgs_encoder::wrapper::stage::WrapperTraining {
    use pwgs_codec::wrapper::synthesis::WrapperConfig;
    use pwgs_encoder::metrics::sigma_map::Log2Sigma;
    use pwgs_encoder::wrapper::stage::{WdFeatures, WrapperTraining};
    WrapperTraining {
        config: WrapperConfig { width: 4, noise: true, plucker: false, seed: 3 },
        start: 0,
        log2_sigma: Log2Sigma::Constant(2.0),
        crop: 64,
        learning_rate: 0.01,
        base_lr_scale,
        features: WdFeatures::Pixels,
        wd_depth: Default::default(),
        pixel_weight,
        crops_per_view: 1,
        min_steps: 0,
        cache_bytes: usize::MAX,
    }
}

/// A scene whose views are large enough for WD (at least 61 x 61 pixels).
fn wd_scene(dir: &std::path::Path) -> Dataset {
    generate(dir, &SyntheticOptions { width: 72, height: 64, views: 6, seed: 4, points: 800 }).unwrap();
    load_scene(dir, &LoadOptions::default()).unwrap()
}

#[test]
fn the_stage_two_pixel_term_adds_the_base_objective() {
    let tmp = tempfile::tempdir().unwrap();
    let data = wd_scene(tmp.path());
    let initial = initial_gaussians(&data, 0, usize::MAX).unwrap();
    let first_loss = |pixel_weight: f32| {
        let mut config = TrainConfig::for_iterations(1);
        config.wrapper = Some(stage_two_settings(pixel_weight, 1.0));
        let mut trainer = Trainer::new(config, &data, &initial, Device::flex()).unwrap();
        trainer.step().unwrap().loss
    };
    let (wd, both) = (first_loss(0.0), first_loss(1.0));
    assert!(both > wd && both - wd <= 1.0, "WD {wd}, WD + pixel term {both}");
    let doubled = first_loss(2.0) - wd;
    assert!((doubled - 2.0 * (both - wd)).abs() < 1e-5, "the term scales with its weight: {doubled}");
}

#[test]
fn a_zero_base_rate_freezes_the_gaussians_in_stage_two() {
    let tmp = tempfile::tempdir().unwrap();
    let data = wd_scene(tmp.path());
    let initial = initial_gaussians(&data, 0, usize::MAX).unwrap();
    let moved = |base_lr_scale: f32| {
        let mut config = TrainConfig::for_iterations(2);
        config.wrapper = Some(stage_two_settings(0.0, base_lr_scale));
        config.densify_until = 0;
        config.sh_interval = 100;
        let mut trainer = Trainer::new(config, &data, &initial, Device::flex()).unwrap();
        let before = trainer.gaussians();
        trainer.step().unwrap();
        trainer.step().unwrap();
        assert!(trainer.synthesis().is_some(), "stage 2 ran");
        trainer.gaussians() != before
    };
    assert!(!moved(0.0), "scale 0 keeps every Gaussian as it was");
    assert!(moved(1.0), "scale 1 trains them");
}

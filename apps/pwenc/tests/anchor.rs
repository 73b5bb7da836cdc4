//! The anchor base trains on the generated scene: the decoder's derivation of the trained
//! model's Gaussians shows the scene far better than the initial model's, and its stream, as
//! rounded, shows it almost as well as the trained model.

use pwgs_codec::anchor::AnchorModel;
use pwgs_codec::scene::{Base, Scene};
use pwgs_codec::stream;
use pwgs_codec::stream::plain::PositionGrid;
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_dataset::{Dataset, LoadOptions, load_scene};
use pwgs_encoder::anchor::context::{ContextLookup, context_shape};
use pwgs_encoder::anchor::growth::GrowthSchedule;
use pwgs_encoder::anchor::init::{AnchorShape, initial_model};
use pwgs_encoder::anchor::network_steps::{
    CONTEXT_EXPONENTS, StepObjective, WEIGHT_EXPONENTS, choose_context_step, choose_mlp_steps,
};
use pwgs_encoder::anchor::quantize::{AnchorSteps, grid_coordinates, quantize, quantize_context};
use pwgs_encoder::anchor::train::AnchorTrainer;
use pwgs_encoder::metrics::evaluate::{MeanScore, evaluate};

/// A generated scene in `dir` and its initial anchor model (F = 8, K = 4, voxels of 5% of the
/// scene's scale), with the grid the anchors sit on.
fn anchor_scene(dir: &std::path::Path, options: &SyntheticOptions) -> (Dataset, AnchorModel, PositionGrid) {
    generate(dir, options).unwrap();
    let data = load_scene(dir, &LoadOptions::default()).unwrap();
    let shape = AnchorShape { feature_dim: 8, offsets_per_anchor: 4, voxel: 0.05 * data.normalization.scale };
    let (initial, grid) = initial_model(data.points.as_ref().unwrap(), shape, 0).unwrap();
    (data, initial, grid)
}

/// The scene most tests here train on: 16 views of 80 x 60.
const SMALL: SyntheticOptions = SyntheticOptions { width: 80, height: 60, views: 16, seed: 4, points: 1500 };

#[test]
fn anchors_learn_the_generated_scene() {
    let tmp = tempfile::tempdir().unwrap();
    let (data, initial, grid) = anchor_scene(tmp.path(), &SMALL);
    let psnr = |model: &AnchorModel| {
        let scene = Scene {
            base: Base::Anchors(Box::new(model.clone())),
            wrapper: None,
            frame: data.normalization.frame(),
            background: [0.0; 3],
        };
        MeanScore::of(&evaluate(&scene, &data.test, None, None).unwrap()).psnr
    };
    let before = psnr(&initial);
    let steps = AnchorSteps::default();
    let mut trainer = AnchorTrainer::new(&initial, &data, 300, [0.0; 3], 0, &burn::tensor::Device::flex())
        .unwrap()
        .with_quantization_noise(steps, 30);
    let mut last = None;
    while trainer.iteration < trainer.iterations {
        last = Some(trainer.step().unwrap());
    }
    let trained = trainer.model();
    assert!(trained.is_consistent());
    assert_eq!(trained.positions, initial.positions, "anchors stay in place");
    let after = psnr(&trained);
    let last = last.unwrap();
    eprintln!(
        "{} anchors; test-view PSNR {before:.2} -> {after:.2} dB; last step {:.2} dB on {} Gaussians",
        trained.len(),
        last.psnr,
        last.gaussians
    );
    assert!(after > before + 4.0, "training gained only {:.2} dB", after - before);
    // Rounded to the stream's steps, the model loses little.
    let rounded = quantize(&trained, &grid, &steps).unwrap().dequantize();
    let quantized = psnr(&rounded);
    eprintln!("as the stream rounds it: {quantized:.2} dB");
    assert!(quantized > after - 0.3, "rounding cost {:.2} dB", after - quantized);
    assert_ne!(rounded, trained, "the steps round something");
}

/// Anchors grown and pruned during training (with the rate term and the context model) stay on
/// the stream's grid, one per voxel, and their stream decodes to what was trained.
#[test]
fn grown_anchors_train_and_code() {
    let tmp = tempfile::tempdir().unwrap();
    let (data, initial, grid) = anchor_scene(tmp.path(), &SMALL);
    let coords = grid_coordinates(&initial.positions, &grid).unwrap();
    let steps = AnchorSteps::default();
    let schedule = GrowthSchedule { from: 50, until: 150, every: 50, max_anchors: 2 * initial.len() };
    let trainer = AnchorTrainer::new(&initial, &data, 200, [0.0; 3], 0, &burn::tensor::Device::flex()).unwrap();
    // With 2D planes, so that they train, code and decode too.
    let lookup = ContextLookup::new(context_shape(vec![6, 8]), &coords, grid.depth, &trainer.device());
    let mut trainer = trainer
        .with_quantization_noise(steps, 20)
        .with_rate(0.002, 60)
        .with_context(lookup)
        .with_placement(grid, coords)
        .with_growth(schedule);
    while trainer.iteration < trainer.iterations {
        trainer.step().unwrap();
    }
    let totals = trainer.growth_totals().unwrap();
    let trained = trainer.model();
    eprintln!("{} anchors -> {} ({totals:?})", initial.len(), trained.len());
    assert!(totals.grown > 0, "nothing grew");
    assert!(trained.is_consistent());
    assert_eq!(trained.len(), initial.len() + totals.grown - totals.pruned);
    assert!(trained.len() <= schedule.max_anchors);
    let voxels = grid_coordinates(&trained.positions, &grid).expect("every anchor on the grid");
    let distinct: std::collections::HashSet<_> = voxels.iter().collect();
    assert_eq!(distinct.len(), voxels.len(), "one anchor per voxel");
    let mut content = quantize(&trained, &grid, &steps).unwrap();
    quantize_context(&mut content, &trainer.context_model().unwrap());
    let header = anchor_header(&data, content.len());
    let decoded = stream::decode(&stream::encode(&header, &content, None).unwrap()).unwrap();
    let Base::Anchors(model) = &decoded.scene.base else { panic!("an anchor stream") };
    // The stream holds every anchor with an open mask, at its trained position.
    let open: std::collections::HashSet<[u32; 3]> = voxels
        .iter()
        .zip(trained.masks.chunks_exact(4))
        .filter(|(_, m)| m.iter().any(|&o| o))
        .map(|(v, _)| *v)
        .collect();
    let stored = grid_coordinates(&model.positions, &grid).unwrap();
    assert_eq!(stored.len(), open.len());
    assert!(stored.iter().all(|v| open.contains(v)), "the stream's anchors are the trained ones");
}

/// The networks' steps are the encoder's choice: the context network's changes only the
/// probability tables (the decoded model is the same, in fewer bytes), and the Gaussian MLPs'
/// follows λ, from the least distortion at λ = 0 to the fewest bytes under a heavy rate term.
#[test]
fn network_steps_follow_the_objective() {
    let tmp = tempfile::tempdir().unwrap();
    let options = SyntheticOptions { width: 64, height: 48, views: 8, seed: 6, points: 800 };
    let (data, initial, grid) = anchor_scene(tmp.path(), &options);
    let coords = grid_coordinates(&initial.positions, &grid).unwrap();
    let steps = AnchorSteps::default();
    let trainer = AnchorTrainer::new(&initial, &data, 150, [0.0; 3], 0, &burn::tensor::Device::flex()).unwrap();
    let lookup = ContextLookup::new(context_shape(vec![]), &coords, grid.depth, &trainer.device());
    let mut trainer = trainer.with_quantization_noise(steps, 15).with_rate(0.004, 45).with_context(lookup);
    while trainer.iteration < trainer.iterations {
        trainer.step().unwrap();
    }
    let (model, trained) = (trainer.model(), trainer.context_model().unwrap());
    let mut content = quantize(&model, &grid, &steps).unwrap();
    quantize_context(&mut content, &trained);
    let header = anchor_header(&data, content.len());
    let default_stream = stream::encode(&header, &content, None).unwrap();
    let e = choose_context_step(&mut content, &trained.mlp, &header).unwrap().expect("a context model");
    assert!(CONTEXT_EXPONENTS.contains(&e));
    assert_eq!(content.context.as_ref().unwrap().mlp.weight_exponent, e);
    let chosen_stream = stream::encode(&header, &content, None).unwrap();
    eprintln!("context network at 2^{e}: {} -> {} bytes", default_stream.len(), chosen_stream.len());
    assert!(chosen_stream.len() <= default_stream.len());
    let hash = |bytes: &[u8]| stream::decode(bytes).unwrap().scene.attribute_hash();
    assert_eq!(hash(&chosen_stream), hash(&default_stream), "the context's step changes no decoded value");

    let networks = [&model.opacity, &model.color, &model.covariance];
    let mut choose = |lambda: f32| {
        let objective = StepObjective { views: &data.train, options: Default::default(), lambda, rated_values: 1000 };
        let candidates = choose_mlp_steps(&mut content, networks, &header, &objective).unwrap();
        assert_eq!(candidates.len(), WEIGHT_EXPONENTS.count());
        let chosen = *candidates.iter().find(|c| c.weight_exponent == content.mlps[0].weight_exponent).unwrap();
        assert!(content.mlps.iter().all(|m| m.weight_exponent == chosen.weight_exponent));
        assert_eq!(stream::encode(&header, &content, None).unwrap().len(), chosen.bytes);
        (candidates, chosen)
    };
    let (candidates, exact) = choose(0.0);
    for c in &candidates {
        eprintln!("2^{}: {} bytes, distortion {:.5}", c.weight_exponent, c.bytes, c.distortion);
    }
    assert!(candidates.iter().all(|c| c.distortion >= exact.distortion), "λ = 0 picks the least distortion");
    assert!(candidates[0].bytes > candidates.last().unwrap().bytes, "coarser weights take fewer bytes");
    let (candidates, cheap) = choose(1e4);
    assert!(candidates.iter().all(|c| c.bytes >= cheap.bytes), "a heavy rate term picks the fewest bytes");
    assert!(cheap.bytes < exact.bytes);
    assert!(cheap.weight_exponent > exact.weight_exponent);
}

/// The header of an anchor stream of `anchors` anchors for `data`.
fn anchor_header(data: &Dataset, anchors: usize) -> stream::header::Header {
    stream::header::Header {
        base: stream::header::BaseKind::Anchors,
        gaussian_count: anchors as u32,
        sh_degree: 0,
        center: data.normalization.center.to_array(),
        scale: data.normalization.scale,
        background: [0.0; 3],
    }
}

/// Learned steps follow λ: a heavy rate term coarsens every group's step, a light one refines
/// them, and the trainer reports the steps the stream is written with.
#[test]
fn learned_steps_follow_lambda() {
    let tmp = tempfile::tempdir().unwrap();
    let options = SyntheticOptions { width: 64, height: 48, views: 8, seed: 5, points: 600 };
    let (data, initial, _) = anchor_scene(tmp.path(), &options);
    let base = AnchorSteps::default();
    let learned = |lambda: f32| {
        let mut trainer = AnchorTrainer::new(&initial, &data, 120, [0.0; 3], 0, &burn::tensor::Device::flex())
            .unwrap()
            .with_quantization_noise(base, 0)
            .with_rate(lambda, 20)
            .with_learned_steps();
        assert_eq!(trainer.steps(), Some(base), "the factors start at 1");
        while trainer.iteration < trainer.iterations {
            trainer.step().unwrap();
        }
        let s = trainer.steps().unwrap();
        [s.feature / base.feature, s.scaling / base.scaling, s.offset / base.offset]
    };
    let (heavy, light) = (learned(1.0), learned(1e-6));
    eprintln!("step factors: λ 1 {heavy:?}, λ 1e-6 {light:?}");
    assert!(heavy.iter().all(|&f| f > 1.0), "{heavy:?}");
    assert!(light.iter().all(|&f| f < 1.0), "{light:?}");
    assert!(heavy.iter().chain(&light).all(|&f| (0.1..=10.0).contains(&f)), "within the factors' range");
}

#[test]
fn pwenc_trains_and_evaluates_the_anchor_base() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let pwenc = |args: &[&str]| std::process::Command::new(env!("CARGO_BIN_EXE_pwenc")).args(args).output().unwrap();
    let out = pwenc(&["generate-scene", &dir("scene"), "--width", "48", "--height", "36", "--views", "9"]);
    assert!(out.status.success());
    // The anchor base is the default.
    let common = [dir("scene"), "--no-wrapper".into(), "--iters".into(), "20".into()];
    let mut args: Vec<&str> = common.iter().map(String::as_str).collect();
    let (eval, report) = (dir("eval"), dir("r.json"));
    args.extend(["--anchor-features", "6", "--anchor-offsets", "3", "--eval", &eval, "--report", &report]);
    args.push("--fixed-anchor-steps");
    let out = pwenc(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(report["stream"]["feature_step"].as_f64(), Some(0.125), "--fixed-anchor-steps keeps the base step");
    assert_eq!((report["base"].as_str(), report["iterations"].as_u64()), (Some("anchor"), Some(20)));
    assert!(report["anchors"].as_u64().unwrap() > 0);
    assert!(report["mean"]["psnr"].as_f64().unwrap() > 5.0);
    assert!(std::path::Path::new(&eval).join("view_008.png").is_file());

    // -o writes the stream the evaluation decoded: its hash is the report's.
    let stream_path = dir("s.pwb");
    let mut args: Vec<&str> = common.iter().map(String::as_str).collect();
    let report2 = dir("r2.json");
    args.extend(["--anchor-features", "6", "--anchor-offsets", "3", "-o", &stream_path, "--report", &report2]);
    args.extend(["--context-planes", "4,6"]);

    let out = pwenc(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let bytes = std::fs::read(&stream_path).unwrap();
    let decoded = stream::decode(&bytes).unwrap();
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&report2).unwrap()).unwrap();
    assert_eq!(report["stream"]["bytes"].as_u64(), Some(bytes.len() as u64));
    assert_eq!(report["stream"]["attribute_sha256"].as_str(), Some(decoded.scene.attribute_hash().as_str()));
    assert_eq!(decoded.header.base, stream::header::BaseKind::Anchors);
    // The context model codes the attributes by default, and its grid's size is reported.
    let stream::Content::Anchors(content) = &decoded.content else { panic!("an anchor stream") };
    let context = content.context.as_ref().expect("no ACTX section in the default stream");
    assert_eq!(context.shape.planes, vec![4, 6], "--context-planes adds 2D planes");
    assert!(report["context_grid_bytes"].as_f64().is_some_and(|b| b > 0.0), "{report}");
    // The steps are learned by default: the stream holds them, no longer the base ones.
    let step = report["stream"]["feature_step"].as_f64().unwrap();
    assert!(step != 0.125 && step > 0.0, "{step}");
    let stored = content.feature_step;
    assert_eq!(stored, step as f32);
    // The networks' steps are chosen after training, and the report says which.
    let reported = |key: &str| report["stream"][key].as_i64().unwrap();
    assert_eq!(reported("weight_step_log2"), i64::from(content.mlps[0].weight_exponent));
    assert_eq!(reported("context_step_log2"), i64::from(context.mlp.weight_exponent));

    // --target-bytes cuts the same run's stream to size by dropping anchors.
    let target = (bytes.len() * 9 / 10).to_string();
    let (cut_path, report3) = (dir("cut.pwb"), dir("r3.json"));
    let mut args: Vec<&str> = common.iter().map(String::as_str).collect();
    args.extend(["--anchor-features", "6", "--anchor-offsets", "3", "-o", &cut_path, "--report", &report3]);
    args.extend(["--context-planes", "4,6", "--target-bytes", &target]);
    let out = pwenc(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let cut = std::fs::read(&cut_path).unwrap();
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&report3).unwrap()).unwrap();
    assert!(cut.len() <= bytes.len() * 9 / 10, "{} bytes against a target of {target}", cut.len());
    let dropped = report["anchors_dropped_to_fit"].as_u64().unwrap() as usize;
    assert!(dropped > 0);
    assert_eq!(report["stream_anchors"].as_u64().unwrap() as usize + dropped, content.len());
    assert_eq!(stream::decode(&cut).unwrap().header.gaussian_count as usize, content.len() - dropped);

    // --export-ply writes standard Gaussians of SH degree 3; --init-ply is refused before any
    // training, and nothing is written.
    let ply = dir("x.ply");
    let mut args: Vec<&str> = common.iter().map(String::as_str).collect();
    args.extend(["--anchor-features", "6", "--anchor-offsets", "3", "--export-ply", &ply]);
    let out = pwenc(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(pwgs_core::ply::read_gaussians(std::path::Path::new(&ply)).unwrap().gaussians.sh_degree, 3);
    let mut args: Vec<&str> = common.iter().map(String::as_str).collect();
    let stream = dir("w.pwb");
    args.extend(["-o", &stream, "--init-ply", &ply]);
    let out = pwenc(&args);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--init-ply"));
    assert!(!std::path::Path::new(&stream).exists());
}

/// The perceptual wrapper trains on the anchor base as on the plain one: the stream carries it
/// and its decoded renders differ from the base's. Both are the default: no option names them.
#[test]
fn pwenc_trains_the_wrapper_on_anchors() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let pwenc = |args: &[&str]| std::process::Command::new(env!("CARGO_BIN_EXE_pwenc")).args(args).output().unwrap();
    let out = pwenc(&["generate-scene", &dir("scene"), "--width", "80", "--height", "64", "--views", "9"]);
    assert!(out.status.success());
    let (scene, stream, report) = (dir("scene"), dir("s.pwb"), dir("r.json"));
    let args = [
        scene.as_str(),
        "--iters",
        "10",
        "--anchor-features",
        "6",
        "--anchor-offsets",
        "3",
        "--wd-features",
        "pixels",
        "--wd-crop",
        "64",
        "--wrapper-crops-per-view",
        "2",
        "--wrapper-min-steps",
        "0",
        "-o",
        &stream,
        "--report",
        &report,
    ];
    let out = pwenc(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("stage 2: 14 steps"), "{stdout}"); // 2 crops x 7 training views
    let decoded = stream::decode(&std::fs::read(&stream).unwrap()).unwrap();
    let wrapper = decoded.scene.wrapper.as_ref().expect("the stream carries the wrapper");
    assert_eq!(wrapper.config.width, 16);
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(report["iterations"].as_u64(), Some(24));
    assert!(report["stream"]["wrapper"]["parameters"].as_u64().unwrap() > 0);
    // λ follows the distortion into stage 2 (WD on pixels here against stage 1's pixel loss).
    let factor = report["stage_two_lambda_factor"].as_f64().expect("the report gives λ's factor");
    assert!(factor.is_finite() && factor > 0.0 && factor != 1.0, "{factor}");
}

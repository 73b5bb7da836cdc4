//! The perceptual wrapper end to end on a small generated scene: `pwenc --wrapper` trains it
//! (WD on pixels, so no VGG weights are needed here), stores it, and what a decoder shows from
//! the stream is what the encoder evaluated; decoding is repeatable and thread-independent.

use pwgs_render::show::SceneRender;
use std::path::Path;
use std::process::Command;

use pwgs_codec::stream;
use pwgs_core::rgb_image::RgbImage;
use pwgs_dataset::{LoadOptions, load_scene};

fn pwenc(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pwenc")).args(args).output().expect("pwenc runs")
}

fn success(out: std::process::Output) {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// Renders every test view of `scene` from the stream at `path` as a decoder shows it.
fn shown(path: &Path, scene: &Path, wrapped: bool) -> Vec<(String, RgbImage)> {
    let decoded = stream::decode(&std::fs::read(path).unwrap()).unwrap();
    let data = load_scene(scene, &LoadOptions::default()).unwrap();
    let options = decoded.scene.render_options();
    data.test
        .iter()
        .map(|v| {
            let stem = Path::new(&v.name).file_stem().unwrap().to_string_lossy().into_owned();
            (stem, decoded.scene.render(&v.camera, &options, wrapped).unwrap().image)
        })
        .collect()
}

#[test]
fn decoder_shows_what_the_encoder_evaluated() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    success(pwenc(&["generate-scene", &dir("scene"), "--width", "80", "--height", "64", "--views", "9"]));
    success(pwenc(&[
        &dir("scene"),
        "--iters",
        "20",
        "--base",
        "3dgs",
        "--wrapper-crops-per-view",
        "3",
        "--wrapper-min-steps",
        "0",
        "--wd-features",
        "pixels",
        "--wd-crop",
        "64",
        "-o",
        &dir("s.pwb"),
        "--eval",
        &dir("eval"),
        "--report",
        &dir("report.json"),
    ]));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(dir("report.json")).unwrap()).unwrap();
    // Stage 2 follows the 20 iterations of stage 1, 3 steps per training view.
    let views = report["train_views"].as_u64().unwrap();
    assert!(views >= 7, "{views} training views");
    assert_eq!(report["training"]["iterations"].as_u64().unwrap(), 20 + 3 * views);
    let wrapper = &report["stream"]["wrapper"];
    assert_eq!(wrapper["width"], 16);
    assert_eq!(wrapper["parameters"], 17 * 16 + 16 + 48 + 3 + 2 * 84);
    let sections = report["stream"]["sections"].as_array().unwrap();
    assert!(sections.iter().any(|s| s[0] == "WRAP"), "{sections:?}");

    let stream_path = Path::new(&dir("s.pwb")).to_path_buf();
    let scene = Path::new(&dir("scene")).to_path_buf();
    let views = shown(&stream_path, &scene, true);
    for (stem, image) in &views {
        let evaluated = image::open(Path::new(&dir("eval")).join(format!("{stem}.png"))).unwrap().to_rgb8();
        let ours = image.to_rgb8();
        let diffs: Vec<u8> = ours.as_raw().iter().zip(evaluated.as_raw()).map(|(a, b)| a.abs_diff(*b)).collect();
        let within = diffs.iter().filter(|&&d| d <= 1).count() as f64 / diffs.len() as f64;
        assert!(within >= 0.999, "{stem}: only {:.4}% within 1/255", within * 100.0);
    }
    // The wrapper trained: it changes what is shown.
    let base = shown(&stream_path, &scene, false);
    assert!(views.iter().zip(&base).any(|(a, b)| a.1 != b.1), "the wrapper changes nothing");
    // Decoding again, and on one thread, gives the same pixels.
    assert_eq!(shown(&stream_path, &scene, true), views);
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    assert_eq!(single.install(|| shown(&stream_path, &scene, true)), views);
}

#[test]
fn ablations_and_bad_wrapper_options() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    success(pwenc(&["generate-scene", &dir("scene"), "--width", "64", "--height", "64", "--views", "5"]));
    let common = [
        dir("scene"),
        "--iters".into(),
        "4".into(),
        "--base".into(),
        "3dgs".into(),
        "--wrapper-crops-per-view".into(),
        "1".into(),
        "--wrapper-min-steps".into(),
        "0".into(),
    ];
    let mut args: Vec<&str> = common.iter().map(String::as_str).collect();
    let out = dir("a.pwb");
    args.extend(["--wd-features", "pixels", "--no-noise", "--wrapper-width", "5", "--wd-crop", "64", "-o", &out]);
    success(pwenc(&args));
    let decoded = stream::decode(&std::fs::read(&out).unwrap()).unwrap();
    let config = decoded.scene.wrapper.unwrap().config;
    assert!(!config.noise && config.plucker && config.width == 5);

    // No weights anywhere: not in a shared folder, not in a cache. Runs pwenc with `args`, which
    // must fail mentioning `needle`, and returns what it printed on stderr.
    let empty = dir("no-weights");
    let fails = |args: &[&str], needle: &str| {
        let out = Command::new(env!("CARGO_BIN_EXE_pwenc"))
            .args(args)
            .env("PWGS_WEIGHTS_DIR", &empty)
            .env("XDG_CACHE_HOME", &empty)
            .env("HOME", &empty)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(!out.status.success() && stderr.contains(needle), "{args:?}: {stderr}");
        stderr
    };
    let bad = |extra: &[&str], needle: &str| {
        let mut args: Vec<&str> = common.iter().map(String::as_str).collect();
        args.extend(extra);
        fails(&args, needle);
    };
    bad(&["--wd-features", "pixels", "--wd-crop", "20"], "--wd-crop");
    bad(&["--wd-features", "pixels", "--wrapper-crops-per-view", "0"], "--wrapper-crops-per-view");
    bad(&["--wd-features", "pixels", "--wd-log2-sigma", "9"], "log2 sigma");
    bad(&["--wd-features", "pixels", "--wd-log2-sigma-map", "/nonexistent.png"], "nonexistent");
    bad(&["--weights", "/nonexistent"], "VGG16");

    // Settings that stage 2 cannot use are refused before stage 1 trains (on the default
    // anchor base, with the wrapper by default): no progress line comes before the error.
    let early = |scene: &str, extra: &[&str], needle: &str| {
        let mut args = vec![scene, "--iters", "200"];
        args.extend(extra);
        let stderr = fails(&args, needle);
        assert!(!stderr.contains("iteration 100/"), "{extra:?} failed only after stage 1: {stderr}");
        stderr
    };
    // Without the weights, the default run says how to get them, or how to go without.
    let stderr = early(&dir("scene"), &["--weights", &empty], "VGG16");
    assert!(stderr.contains("pwenc fetch-weights") && stderr.contains("--no-wrapper"), "{stderr}");
    success(pwenc(&["generate-scene", &dir("small"), "--width", "48", "--height", "48", "--views", "5"]));
    early(&dir("small"), &["--wd-features", "pixels", "--wd-crop", "64"], "at least 61x61");
}

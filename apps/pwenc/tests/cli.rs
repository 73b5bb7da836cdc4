//! `pwenc` end to end on a small generated scene, and its errors on bad input.

use std::process::Command;

fn pwenc(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pwenc")).args(args).output().expect("pwenc runs")
}

/// A JSON file a run wrote.
fn read_json(path: &str) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

#[test]
fn trains_evaluates_and_writes_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let out = pwenc(&["generate-scene", &dir("scene"), "--width", "48", "--height", "36", "--views", "9"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = pwenc(&[
        &dir("scene"),
        "--base",
        "3dgs",
        "--no-wrapper",
        "--iters",
        "30",
        "--export-ply",
        &dir("model.ply"),
        "--eval",
        &dir("eval"),
        "--report",
        &dir("report.json"),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = read_json(&dir("report.json"));
    assert_eq!(report["training"]["iterations"], 30);
    assert!(!report["device"].as_str().unwrap().is_empty(), "the report names what trained");
    assert_eq!(report["views"].as_array().unwrap().len(), 2);
    assert!(report["mean"]["psnr"].as_f64().unwrap() > 8.0);
    if cfg!(target_os = "linux") {
        // The run's peak memory: more than the 1 MiB the process starts with, less than 24 GiB.
        let peak = report["peak_resident_mib"].as_f64().expect("Linux reports the peak memory");
        assert!(peak > 1.0 && peak < 24.0 * 1024.0, "{peak} MiB");
    }
    assert!(std::path::Path::new(&dir("eval")).join("view_008.png").is_file());
    assert!(std::path::Path::new(&dir("eval")).join("gt/view_008.png").is_file());
    let model = pwgs_core::ply::read_gaussians(std::path::Path::new(&dir("model.ply"))).unwrap();
    assert_eq!(model.gaussians.len() as u64, report["training"]["gaussians"].as_u64().unwrap());
    // Resuming from the exported model works.
    let out =
        pwenc(&[&dir("scene"), "--base", "3dgs", "--no-wrapper", "--iters", "5", "--init-ply", &dir("model.ply")]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    // A cap below the SfM cloud's size bounds the model from the start, and says so.
    let capped = ["--iters", "3", "--max-gaussians", "40", "--export-ply", &dir("capped.ply")];
    let out = pwenc(&[&[dir("scene").as_str(), "--base", "3dgs", "--no-wrapper"][..], &capped[..]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("initialization: 40 of the "), "{stdout}");
    let capped = pwgs_core::ply::read_gaussians(std::path::Path::new(&dir("capped.ply"))).unwrap();
    assert!(capped.gaussians.len() <= 40, "{} Gaussians", capped.gaussians.len());
}

/// A model trained on a capture, seen from the capture's own views: `pwenc compare --views`
/// scores on them instead of an orbit, and `pwenc --from --views` weighs them in the import.
#[test]
fn a_captures_own_views_score_and_weigh_an_import() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let json = |name: &str| read_json(&dir(name));
    let out = pwenc(&["generate-scene", &dir("scene"), "--width", "48", "--height", "36", "--views", "9"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let train = [&dir("scene"), "--base", "3dgs", "--no-wrapper", "--iters", "10", "--export-ply", &dir("model.ply")];
    assert!(pwenc(&train).status.success());

    let import = ["--from", &dir("model.ply"), "-o", &dir("s.pwb"), "--views", &dir("scene")];
    let out = pwenc(&import);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains(", 9 of the capture)"), "{stdout}");

    let compare = ["compare", &dir("model.ply"), &dir("s.pwb"), "-o", &dir("r"), "--views", &dir("scene")];
    let out = pwenc(&[&compare[..], &["--report", &dir("c.json")]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = json("c.json");
    // The test views of a scene without its own split: the 1st and the 9th.
    let names: Vec<&str> = report["views"].as_array().unwrap().iter().map(|v| v["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["view_000", "view_008"]);
    assert!(report["mean"]["psnr"].as_f64().unwrap() > 20.0, "{report}");
    assert!(report.get("orbit_size").is_none() && report["views_from"].as_str().unwrap().contains("(test views)"));
    assert!(std::path::Path::new(&dir("r/view_008.png")).is_file());
    assert!(std::path::Path::new(&dir("r/gt/view_008.png")).is_file());
    let all = pwenc(&[&compare[..], &["--split", "all", "--downscale", "2", "--report", &dir("all.json")]].concat());
    assert!(all.status.success(), "{}", String::from_utf8_lossy(&all.stderr));
    assert_eq!(json("all.json")["views"].as_array().unwrap().len(), 9);

    // A scene that is not there is named, and no stream is written.
    let out = pwenc(&["--from", &dir("model.ply"), "-o", &dir("t.pwb"), "--views", &dir("nowhere")]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("nowhere"));
    assert!(!std::path::Path::new(&dir("t.pwb")).exists());
    let out = pwenc(&["compare", &dir("model.ply"), &dir("s.pwb"), "-o", &dir("r2"), "--split", "train"]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("--views"));
}

/// A build without the `gpu` feature trains on the CPU: `--device auto` (the default) says so in
/// the report, and `--device gpu` is refused before any work, naming the feature.
#[cfg(not(feature = "gpu"))]
#[test]
fn a_build_without_the_gpu_feature_trains_on_the_cpu() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let out = pwenc(&["generate-scene", &dir("scene"), "--width", "32", "--height", "24", "--views", "4"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let common = ["--base", "3dgs", "--no-wrapper", "--iters", "2"];
    let out = pwenc(&[&[dir("scene").as_str(), "--report", &dir("r.json")][..], &common[..]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = read_json(&dir("r.json"));
    assert_eq!(report["device"], "CPU (Burn flex backend)");
    let out = pwenc(&[&[dir("scene").as_str(), "--device", "gpu", "-o", &dir("s.pwb")][..], &common[..]].concat());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("`gpu` feature"), "{stderr}");
    assert!(!std::path::Path::new(&dir("s.pwb")).exists());
}

#[test]
fn bad_input_is_a_clear_error() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("missing");
    let scene = tmp.path().join("scene");
    let scene = scene.to_str().unwrap();
    assert!(pwenc(&["generate-scene", scene, "--width", "16", "--height", "12", "--views", "3"]).status.success());
    for (args, needle) in [
        (vec![missing.to_str().unwrap()], "does not exist"),
        (vec!["generate-scene", tmp.path().join("s").to_str().unwrap(), "--width", "0"], "image size 0x120"),
        (vec![tmp.path().to_str().unwrap(), "--background", "purple"], "purple"),
        (vec![scene, "--position-lr", "1e-4"], "two positive rates"),
        (vec![tmp.path().to_str().unwrap()], "no supported scene"),
        (vec![scene, "--base", "3dgs", "--init-ply", missing.to_str().unwrap()], "missing"),
        (vec![scene, "--downscale", "0"], "downscale"),
    ] {
        let out = pwenc(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(stderr.contains(needle), "{args:?}: `{stderr}` should mention `{needle}`");
        assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    }
    // An output that cannot be written is refused before training, and an existing file in its
    // place is left as it was.
    let kept = tmp.path().join("kept");
    std::fs::write(&kept, b"earlier output").unwrap();
    let folder = tmp.path().to_path_buf();
    for (kept_as, flag, path) in [
        ("--report", "-o", missing.join("out.pwb")),
        ("-o", "--report", missing.join("r.json")),
        ("-o", "--export-ply", folder),
    ] {
        let args = [scene, "--iters", "300", kept_as, kept.to_str().unwrap(), flag, path.to_str().unwrap()];
        let out = pwenc(&args);
        let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(!out.status.success() && stderr.contains("cannot write"), "{args:?}: {stderr}");
        assert!(!stdout.contains("trained"), "{args:?} trained before failing: {stdout}");
        assert_eq!(std::fs::read(&kept).unwrap(), b"earlier output");
    }
}

#[test]
fn compresses_an_imported_ply() {
    let tmp = tempfile::tempdir().unwrap();
    let path = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let model = pwgs_core::random::random_gaussians(&mut pwgs_core::random::SplitMix64(3), 800, 2, [-4.0, -2.5]);
    pwgs_core::ply::write_gaussians(std::path::Path::new(&path("in.ply")), &model).unwrap();
    let out = pwenc(&[
        "--from-ply",
        &path("in.ply"),
        "-o",
        &path("out.pwb"),
        "--quality",
        "7",
        "--effort",
        "0",
        "--orbit",
        "2",
        "--orbit-size",
        "64",
        "--up",
        "0,-1,0",
        "--report",
        &path("report.json"),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = read_json(&path("report.json"));
    let bytes = std::fs::read(path("out.pwb")).unwrap();
    assert_eq!(report["stream"]["bytes"].as_u64().unwrap(), bytes.len() as u64);
    assert_eq!(report["orbit_psnr"].as_array().unwrap().len(), 2);
    // The hash the encoder reports is that of what the decoder library decodes.
    let decoded = pwgs_codec::stream::decode(&bytes).unwrap();
    assert_eq!(report["stream"]["attribute_sha256"], decoded.scene.attribute_hash());
    assert_eq!(decoded.scene.plain_gaussians().unwrap().len(), 800);
    // A target size half the stream's drops Gaussians until it fits, and says so.
    let target = (bytes.len() / 2).to_string();
    let args = [
        "--from-ply",
        &path("in.ply"),
        "-o",
        &path("half.pwb"),
        "--quality",
        "7",
        "--effort",
        "0",
        "--target-bytes",
        &target,
    ];
    let out = pwenc(&[&args[..], &["--report", &path("half.json")]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = read_json(&path("half.json"));
    let half = std::fs::read(path("half.pwb")).unwrap().len();
    assert!(half <= bytes.len() / 2 && half + 200 > bytes.len() / 2, "{half} bytes for a target of {target}");
    let pruned = report["stream"]["pruned_to_fit"].as_u64().unwrap();
    assert!(pruned > 300 && report["stream"]["gaussians"].as_u64().unwrap() + pruned == 800, "{report}");
    // Importance classes (effort 1, or effort 0 with the option): the stream holds IMPC and
    // the same Gaussians, with the steps of the import's balance (a rotation step three
    // notches coarser than the quality level's, which effort 0 keeps).
    let rotation_step = |stream: &[u8]| {
        let container = pwgs_bitstream::Container::parse(stream).unwrap();
        let payload = container.section(pwgs_codec::stream::plain::ROTATIONS).unwrap().payload;
        f32::from_le_bytes(payload[..4].try_into().unwrap())
    };
    let quality = pwgs_encoder::plain::compress::QuantizerSettings::for_quality(7);
    assert_eq!(rotation_step(&bytes), quality.rotation_step);
    let balanced = pwgs_encoder::plain::step_search::IMPORT_BALANCE.apply(&quality);
    assert_eq!(balanced.rotation_step, quality.rotation_step * 2.0 * std::f32::consts::SQRT_2);
    for tools in [&["--effort", "1"][..], &["--effort", "0", "--importance-classes"]] {
        let (input, output) = (path("in.ply"), path("classes.pwb"));
        let args = [&["--from", &input, "-o", &output, "--quality", "7"][..], tools].concat();
        let out = pwenc(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        // The class views: 57 on or above the horizon and 41 below it.
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(said.contains("importance: 98 views (57 of 512x512, 41 of 256x256)"), "{tools:?}: {said}");
        let classes = std::fs::read(path("classes.pwb")).unwrap();
        let container = pwgs_bitstream::Container::parse(&classes).unwrap();
        assert!(container.section(pwgs_codec::stream::classes::CLASSES).is_some());
        assert_eq!(pwgs_codec::stream::decode(&classes).unwrap().scene.plain_gaussians().unwrap().len(), 800);
        assert_eq!(rotation_step(&classes), balanced.rotation_step, "{tools:?}");
    }
    // The default effort prunes too, and codes smaller than effort 0.
    let out = pwenc(&["--from", &path("in.ply"), "-o", &path("default.pwb"), "--quality", "7"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let default = std::fs::read(path("default.pwb")).unwrap();
    assert!(default.len() < bytes.len(), "default {} bytes, effort 0 {}", default.len(), bytes.len());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("importance: 124 views") && stdout.contains("too faint in the importance views dropped"));
    // Without -o there is nowhere to write.
    let out = pwenc(&["--from-ply", &path("in.ply")]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--output"));

    // `--from` takes .splat and .spz files too: the stream holds their Gaussians.
    use pwgs_core::splat_file::{SpzVersion, gaussians_to_splat_bytes, gaussians_to_spz_bytes};
    std::fs::write(path("in.splat"), gaussians_to_splat_bytes(&model)).unwrap();
    std::fs::write(path("in.spz"), gaussians_to_spz_bytes(&model, SpzVersion::V3)).unwrap();
    for input in ["in.splat", "in.spz"] {
        let out = pwenc(&["--from", &path(input), "-o", &path("other.pwb"), "--effort", "0"]);
        assert!(out.status.success(), "{input}: {}", String::from_utf8_lossy(&out.stderr));
        let decoded = pwgs_codec::stream::decode(&std::fs::read(path("other.pwb")).unwrap()).unwrap();
        let expected =
            pwgs_core::splat_file::read_splat_file(std::path::Path::new(&path(input)), Default::default()).unwrap();
        assert_eq!(decoded.header.sh_degree, expected.sh_degree, "{input}");
        assert!(decoded.header.gaussian_count > 700, "{input}: {} Gaussians", decoded.header.gaussian_count);
    }
    // An unmarked SPZ is read in RUB axes, or in a PLY's own (splat-transform's files) when asked.
    let mut lifted = model.clone();
    lifted.means.iter_mut().for_each(|m| m[1] += 5.0);
    std::fs::write(path("lifted.spz"), gaussians_to_spz_bytes(&lifted, SpzVersion::V3)).unwrap();
    let center_y = |axes: &[&str]| {
        let out = pwenc(&[&["--from", &path("lifted.spz"), "-o", &path("axes.pwb")], axes].concat());
        assert!(out.status.success(), "{axes:?}: {}", String::from_utf8_lossy(&out.stderr));
        pwgs_codec::stream::decode(&std::fs::read(path("axes.pwb")).unwrap()).unwrap().header.center[1]
    };
    let (rub, rdf) = (center_y(&[]), center_y(&["--spz-axes", "rdf"]));
    assert!(rub > 4.0 && rdf < -4.0, "centers' y: {rub} (RUB), {rdf} (RDF)");
    std::fs::write(path("broken.spz"), b"not gzip").unwrap();
    let out = pwenc(&["--from", &path("broken.spz"), "-o", &path("broken.pwb")]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("broken.spz"));
    assert!(!std::path::Path::new(&path("broken.pwb")).exists());
}

/// `pwenc ... | head -1`: a standard output closed before the job ends is no error; the stream
/// is written all the same (`println!` would panic at the first message).
#[test]
fn a_closed_standard_output_loses_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let (model, stream) = (tmp.path().join("in.ply"), tmp.path().join("out.pwb"));
    let g = pwgs_core::random::random_gaussians(&mut pwgs_core::random::SplitMix64(4), 300, 0, [-4.0, -2.5]);
    pwgs_core::ply::write_gaussians(&model, &g).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_pwenc"))
        .args(["--from", model.to_str().unwrap(), "-o", stream.to_str().unwrap(), "--effort", "0"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(pwgs_codec::stream::decode(&std::fs::read(&stream).unwrap()).unwrap().header.gaussian_count, 300);
}

#[test]
fn compares_a_model_with_a_reference_on_an_orbit() {
    let tmp = tempfile::tempdir().unwrap();
    let path = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let json = |name: &str| read_json(&path(name));
    let mut rng = pwgs_core::random::SplitMix64(8);
    let model = pwgs_core::random::random_gaussians(&mut rng, 600, 1, [-4.0, -2.5]);
    pwgs_core::ply::write_gaussians(std::path::Path::new(&path("in.ply")), &model).unwrap();
    let orbit = ["--orbit", "3", "--orbit-size", "48"];
    let import = [&["--from", &path("in.ply"), "-o", &path("s.pwb"), "--report", &path("import.json")], &orbit[..]];
    let out = pwenc(&import.concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    // A stream scores as the import's own orbit check scored it: the same cameras and renders.
    let compare =
        [&["compare", &path("in.ply"), &path("s.pwb"), "-o", &path("r"), "--report", &path("c.json")], &orbit[..]];
    let out = pwenc(&compare.concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (report, import) = (json("c.json"), json("import.json"));
    let psnr = report["mean"]["psnr"].as_f64().unwrap();
    assert!((psnr - import["orbit_psnr_mean"].as_f64().unwrap()).abs() < 1e-9, "{psnr} vs {import}");
    assert_eq!(report["stream"]["bytes"].as_u64().unwrap(), std::fs::metadata(path("s.pwb")).unwrap().len());
    assert_eq!(report["views"].as_array().unwrap().len(), 3);
    assert!(std::path::Path::new(&path("r/orbit_002.png")).is_file());
    assert!(std::path::Path::new(&path("r/gt/orbit_002.png")).is_file());

    assert!(report.get("encode_seconds").is_none() && report.get("decode_seconds").is_none(), "{report}");

    // A splat file is read as --from reads it; --size-of names the file whose size counts, and
    // the times the caller measured go into the report.
    std::fs::write(path("in.splat"), pwgs_core::splat_file::gaussians_to_splat_bytes(&model)).unwrap();
    let args = ["compare", &path("in.ply"), &path("in.splat"), "-o", &path("r2"), "--size-of", &path("in.ply")];
    let times = ["--encode-seconds", "1.5", "--decode-seconds", "0.25"];
    let out = pwenc(&[&args[..], &times[..], &["--report", &path("c2.json")], &orbit[..]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = json("c2.json");
    assert_eq!((report["encode_seconds"].as_f64(), report["decode_seconds"].as_f64()), (Some(1.5), Some(0.25)));
    assert_eq!(report["stream"]["bytes"].as_u64().unwrap(), std::fs::metadata(path("in.ply")).unwrap().len());
    let out = pwenc(&[&args[..], &["--encode-seconds=-1"], &orbit[..]].concat());
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("seconds"));
    let splat_psnr = report["mean"]["psnr"].as_f64().unwrap();
    assert!(splat_psnr.is_finite() && splat_psnr > 15.0, "{splat_psnr}");

    // A missing candidate is named, and no report is written.
    let out = pwenc(&["compare", &path("in.ply"), &path("gone.pwb"), "-o", &path("r3"), "--report", &path("c3.json")]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("gone.pwb"));
    assert!(!std::path::Path::new(&path("c3.json")).exists());
}

#[test]
fn an_option_the_job_would_ignore_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    let scene = scene.to_str().unwrap();
    assert!(pwenc(&["generate-scene", scene, "--width", "16", "--height", "12", "--views", "3"]).status.success());
    for (args, needle) in [
        // The default base is the anchor base, which plain-only options would not reach.
        (vec![scene, "--max-gaussians", "40"], "--max-gaussians applies to the plain base"),
        (vec![scene, "--base", "anchor", "--quality", "3"], "--quality applies to the plain base"),
        (vec![scene, "--base", "3dgs", "--lambda", "0.01"], "--lambda applies to the anchor base"),
        (vec![scene, "--base", "3dgs", "--anchor-growth"], "--anchor-growth applies to the anchor base"),
        (vec!["--from-ply", "m.ply", "-o", "x.pwb", "--iters", "9"], "--iters applies to training on a scene"),
        (vec!["--from-ply", "m.ply", "-o", "x.pwb", "--base", "anchor"], "--base applies to training"),
        (vec!["--from-ply", "m.ply", "-o", "x.pwb", "--wrapper"], "--wrapper applies to training"),
        (vec!["--from-ply", "m.ply", "-o", "x.pwb", "--wrapper-lr", "0.1"], "--wrapper-lr applies to training"),
        // Options of a job on a scene's views, which an import has none of.
        (vec!["--from", "m.ply", "-o", "x.pwb", "--downscale", "2"], "--downscale applies to training"),
        (vec!["--from", "m.ply", "-o", "x.pwb", "--export-ply", "y.ply"], "--export-ply applies to training"),
        (vec!["--from", "m.ply", "-o", "x.pwb", "--weights", "w"], "--weights applies to training"),
        (vec![scene, "--no-wrapper", "--wrapper-width", "8"], "--wrapper-width"),
        (vec![scene, "--lambda", "0", "--context-planes", "6"], "--context-planes belongs to the context model"),
        (vec![scene, "--wrapper-lambda-scale", "twice"], "nor `auto`"),
        (vec![scene, "--base", "3dgs", "--wrapper-lambda-scale", "2"], "--wrapper-lambda-scale applies to the anchor"),
        (vec![scene, "--spz-axes", "rdf"], "--spz-axes applies to --from-ply"),
        (vec![scene, "--orbit", "4"], "--orbit applies to --from-ply"),
        (vec![scene, "--importance-classes"], "--importance-classes applies to --from-ply"),
        (vec![scene, "--effort", "3"], "--effort applies to --from-ply"),
        (vec!["--from", "m.ply", "-o", "x.pwb", "--effort", "10"], "--effort"),
        (vec![scene, "--search-steps"], "--search-steps applies to --from-ply"),
        (
            vec!["--from", "m.ply", "-o", "x.pwb", "--importance-classes", "--refit-colours", "--target-bytes", "9"],
            "--target-bytes",
        ),
        (
            vec!["--from", "m.ply", "-o", "x.pwb", "--importance-classes", "--refit-shapes=4", "--target-bytes=9"],
            "--target-bytes",
        ),
        (vec!["--from", "m.ply", "-o", "x.pwb", "--importance-classes", "--refit-shapes", "0"], "--refit-shapes"),
        (vec![scene, "--importance-classes", "--refit-shapes", "4"], "applies to --from-ply"),
    ] {
        let out = pwenc(&args);
        let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(stderr.contains(needle), "{args:?}: `{stderr}` should mention `{needle}`");
        assert!(!stdout.contains("iteration"), "{args:?} trained before failing: {stdout}");
    }
}

#[test]
fn help_gives_the_main_options_by_group_and_help_all_every_option() {
    let text = |args: &[&str]| {
        let out = pwenc(args);
        assert!(out.status.success(), "{args:?}");
        String::from_utf8(out.stdout).unwrap()
    };
    let (short, all) = (text(&["--help"]), text(&["--help-all"]));
    assert!(short.lines().count() <= 60, "--help is {} lines:\n{short}", short.lines().count());
    assert_eq!(short, text(&["-h"]));
    for heading in
        ["Training:", "Evaluation:", "Perceptual wrapper", "Anchor base", "Plain base", "Import (--from MODEL):"]
    {
        assert!(short.contains(heading) && all.contains(heading), "{heading}");
    }
    // The main options are in both; experts' knobs and ablations only in --help-all, with details.
    for option in ["--from", "--lambda", "--quality", "--no-wrapper", "--effort", "--eval"] {
        assert!(short.contains(option), "{option}");
    }
    for option in
        ["--wd-vgg-blocks", "--no-plucker", "--context-planes", "--position-lr", "--spz-axes", "--prune-faint"]
    {
        assert!(!short.contains(option) && all.contains(option), "{option}");
    }
    assert!(all.contains("Niantic") && !short.contains("Niantic"), "details only in --help-all");
    // Every subcommand has its own help.
    for (command, option) in [
        ("generate-scene", "--points"),
        ("fetch-weights", "--dists-wheel"),
        ("inspect", "--downscale"),
        ("compare", "--orbit"),
    ] {
        for flag in ["--help", "-h"] {
            assert!(text(&[command, flag]).contains(option), "{command} {flag}");
        }
    }
    assert!(all.lines().count() > 3 * short.lines().count() / 2);
}

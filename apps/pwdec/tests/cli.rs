//! `pwdec` end to end on the conformance stream, and its errors on bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn pwdec(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pwdec")).args(args).output().expect("pwdec runs")
}

fn vector(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../conformance/vectors/generated-3dgs").join(name)
}

fn expected_hash() -> String {
    let text = std::fs::read_to_string(vector("expected.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["attribute_sha256"].as_str().unwrap().to_string()
}

fn stdout(out: &Output) -> String {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn hash_is_the_encoders_with_any_thread_count() {
    let stream = vector("stream.pwb");
    for threads in ["1", "4"] {
        let out = pwdec(&[stream.to_str().unwrap(), "--hash", "--threads", threads]);
        assert_eq!(stdout(&out).trim(), expected_hash(), "{threads} threads");
    }
}

#[test]
fn renders_views_exports_ply_and_prints_info() {
    let tmp = tempfile::tempdir().unwrap();
    let stream = vector("stream.pwb");
    let s = stream.to_str().unwrap();
    let png = tmp.path().join("view.png");
    let ply = tmp.path().join("model.ply");
    stdout(&pwdec(&[s, "--view", vector("view_opencv.json").to_str().unwrap(), "-o", png.to_str().unwrap()]));
    assert_eq!(image::open(&png).unwrap().to_rgb8(), image::open(vector("view_opencv.png")).unwrap().to_rgb8());
    stdout(&pwdec(&[s, "--export-ply", ply.to_str().unwrap()]));
    let exported = pwgs_core::ply::read_gaussians(&ply).unwrap().gaussians;
    let decoded = pwgs_codec::stream::decode(&std::fs::read(&stream).unwrap()).unwrap();
    assert_eq!(Some(&exported), decoded.scene.plain_gaussians());
    let info = stdout(&pwdec(&["info", s]));
    for needle in ["version       1.0", "gaussians     7077", "'POSN'", "'SHRS'"] {
        assert!(info.contains(needle), "`{needle}` missing from:\n{info}");
    }
    assert!(!info.contains("tree coding"), "a stream without ADPT:\n{info}");
    // A stream with adaptive trees in some blocks names them.
    let some = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../conformance/vectors/adaptive-some-blocks/stream.pwb");
    let info = stdout(&pwdec(&["info", some.to_str().unwrap()]));
    assert!(info.contains("tree coding   'SCAL', 'OPAC', 'COLR' (ADPT"), "{info}");
}

/// `pwdec info s.pwb | head -1`: a standard output closed early is no error (no panic).
#[test]
fn a_closed_standard_output_is_not_an_error() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_pwdec"))
        .args(["info", vector("stream.pwb").to_str().unwrap()])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// `--export-spz`: the library's SPZ writer on the decoded Gaussians, which the SPZ reader
/// reads back to the same Gaussians within the format's quantization.
#[test]
fn exports_spz() {
    use pwgs_core::splat_file::{SpzAxes, SpzVersion, gaussians_from_spz_bytes, gaussians_to_spz_bytes};
    let tmp = tempfile::tempdir().unwrap();
    let stream = vector("stream.pwb");
    let spz = tmp.path().join("model.spz");
    let out = pwdec(&[stream.to_str().unwrap(), "--export-spz", spz.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("SPZ version 3"), "{out:?}");
    let decoded = pwgs_codec::stream::decode(&std::fs::read(&stream).unwrap()).unwrap();
    let gaussians = decoded.scene.plain_gaussians().unwrap();
    let bytes = std::fs::read(&spz).unwrap();
    assert_eq!(bytes, gaussians_to_spz_bytes(gaussians, SpzVersion::V3));
    let back = gaussians_from_spz_bytes(&bytes, SpzAxes::Rub).unwrap();
    assert_eq!((back.len(), back.sh_degree), (gaussians.len(), gaussians.sh_degree));
    let gap = back.means.iter().flatten().zip(gaussians.means.iter().flatten()).map(|(a, b)| (a - b).abs());
    assert!(gap.fold(0.0, f32::max) <= 0.5 / 4096.0 + 1e-6, "positions beyond half a step of 2^-12");

    let err = pwdec(&[stream.to_str().unwrap(), "--hash", "--fit-views", "scene"]);
    assert!(!err.status.success());
    assert!(String::from_utf8_lossy(&err.stderr).contains("--fit-views applies to --export-ply and --export-spz"));
}

/// An anchor stream: its hash with any thread count, its info, and its export as standard
/// Gaussians of SH degree 3 with the agreement it states.
#[test]
fn anchor_streams_hash_show_their_sections_and_export_standard_gaussians() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../conformance/vectors/anchors");
    let stream = dir.join("stream.pwb");
    let s = stream.to_str().unwrap();
    let expected: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("expected.json")).unwrap()).unwrap();
    for threads in ["1", "3"] {
        let out = pwdec(&[s, "--hash", "--threads", threads]);
        assert_eq!(stdout(&out).trim(), expected["attribute_sha256"].as_str().unwrap(), "{threads} threads");
    }
    let info = stdout(&pwdec(&["info", s]));
    for needle in ["base          anchor", "anchors       120", "'AMLP'", "'AOFF'"] {
        assert!(info.contains(needle), "`{needle}` missing from:\n{info}");
    }
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("export.ply");
    let out = pwdec(&[s, "--export-ply", ply.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    let exported = pwgs_core::ply::read_gaussians(&ply).unwrap().gaussians;
    assert_eq!(exported.sh_degree, 3);
    assert!(exported.len() > 100 && exported.len() <= 120 * 4, "{} Gaussians", exported.len());
    let psnr: f64 = stderr.split("PSNR ").nth(1).and_then(|t| t.split(' ').next()).unwrap().parse().unwrap();
    assert!(psnr > 20.0, "the export agrees with the anchor renders to only {psnr} dB: {stderr}");
    // A stream with a context model describes it.
    let context = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../conformance/vectors/anchors-context/stream.pwb");
    let info = stdout(&pwdec(&["info", context.to_str().unwrap()]));
    for needle in ["'ACTX'", "levels [1, 3, 5], plane levels [2, 6]", "2 channels: 742 entries; network width 6"] {
        assert!(info.contains(needle), "`{needle}` missing from:\n{info}");
    }
}

#[test]
fn bad_input_is_a_clear_error_and_leaves_outputs_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let good = std::fs::read(vector("stream.pwb")).unwrap();
    let write = |name: &str, bytes: &[u8]| {
        let p = tmp.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p.to_str().unwrap().to_string()
    };
    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x10;
    let mut future = good.clone();
    future[8] = 2;
    let corrupt = write("corrupt.pwb", &flipped);
    let truncated = write("truncated.pwb", &good[..good.len() - 100]);
    let future = write("future.pwb", &future);
    let text = write("text.pwb", b"hello");
    let camera = write("camera.json", b"{\"width\": 10, \"height\": 10}");
    let huge = write(
        "huge.json",
        b"{\"width\": 65535, \"height\": 65535, \"fx\": 1e4, \"fy\": 1e4, \"cx\": 32767, \"cy\": 32767, \
          \"camera_to_world\": [[1,0,0,0],[0,1,0,0],[0,0,1,-5],[0,0,0,1]]}",
    );
    let good_stream = write("good.pwb", &good);
    let existing = write("existing.png", b"keep me");
    let missing = tmp.path().join("missing.pwb");
    for (args, needle) in [
        (vec![corrupt.as_str(), "--hash"], "CRC"),
        (vec![truncated.as_str(), "--hash"], "truncated"),
        (vec![future.as_str(), "--hash"], "version 2.0"),
        (vec![text.as_str(), "--hash"], "not a pwgs stream"),
        (vec![missing.to_str().unwrap(), "--hash"], "missing.pwb"),
        (vec!["info", truncated.as_str()], "truncated"),
        (vec![good_stream.as_str()], "nothing to do"),
        (vec![good_stream.as_str(), "--view", camera.as_str(), "-o", existing.as_str()], "camera.json"),
        (vec![corrupt.as_str(), "--view", camera.as_str(), "-o", existing.as_str()], "CRC"),
        (vec![good_stream.as_str(), "--view", huge.as_str(), "-o", existing.as_str()], "--max-pixels"),
    ] {
        let out = pwdec(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(stderr.contains(needle), "{args:?}: `{stderr}` should mention `{needle}`");
        assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    }
    assert_eq!(std::fs::read(&existing).unwrap(), b"keep me");
}

fn wrapped_vector(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../conformance/vectors/generated-3dgs-wrapped").join(name)
}

#[test]
fn wrapped_stream_renders_with_and_without_the_wrapper_and_its_residual() {
    let tmp = tempfile::tempdir().unwrap();
    let stream = wrapped_vector("stream.pwb");
    let s = stream.to_str().unwrap();
    let camera = wrapped_vector("view_opencv.json");
    let c = camera.to_str().unwrap();
    let path = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let read = |name: &str| image::open(tmp.path().join(name)).unwrap().to_rgb8();
    for threads in ["1", "3"] {
        let out = format!("wrapped_{threads}.png");
        let residual = format!("residual_{threads}.png");
        stdout(&pwdec(&[s, "--view", c, "-o", &path(&out), "--residual", &path(&residual), "--threads", threads]));
    }
    stdout(&pwdec(&[s, "--view", c, "-o", &path("base.png"), "--no-wrapper"]));
    // Thread counts do not change a pixel; the wrapper does.
    assert_eq!(read("wrapped_1.png"), read("wrapped_3.png"));
    assert_eq!(read("residual_1.png"), read("residual_3.png"));
    let (wrapped, base, residual) = (read("wrapped_1.png"), read("base.png"), read("residual_1.png"));
    assert_ne!(wrapped, base);
    // Where nothing clamps (the base render itself may exceed 1), wrapped = base + (residual -
    // 0.5), up to 8-bit rounding.
    let mut checked = 0;
    for ((w, b), r) in wrapped.as_raw().iter().zip(base.as_raw()).zip(residual.as_raw()) {
        let predicted = i32::from(*b) + i32::from(*r) - 128;
        if (3..253).contains(&predicted) && (3..253).contains(r) && (3..253).contains(b) {
            assert!((i32::from(*w) - predicted).abs() <= 2, "wrapped {w}, base {b}, residual {r}");
            checked += 1;
        }
    }
    assert!(checked > 1000, "only {checked} values checked");
    let info = stdout(&pwdec(&["info", s]));
    assert!(info.contains("WRAP") && info.contains("width 16, noise on, plücker on"), "{info}");
    // --residual needs a wrapper.
    let plain = vector("stream.pwb");
    let out = pwdec(&[plain.to_str().unwrap(), "--view", c, "-o", &path("x.png"), "--residual", &path("r.png")]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("no perceptual wrapper"));
}

/// A dataset of two views (a test and a training view) of `width` x `height` pixels.
fn dataset_of_size(dir: &Path, width: u32, height: u32) -> String {
    image::RgbImage::new(width, height).save(dir.join("a.png")).unwrap();
    let pose = "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]";
    let frame = format!(r#"{{"file_path": "a.png", "transform_matrix": {pose}}}"#);
    let json = format!(r#"{{"camera_angle_x": 0.8, "frames": [{frame}, {frame}]}}"#);
    std::fs::write(dir.join("transforms.json"), json).unwrap();
    dir.to_str().unwrap().to_string()
}

/// Views are sized from image headers, which may claim anything: a side beyond 65535 used to
/// reach the noise pyramid's assertion on a wrapped stream; now it is an error naming the image.
#[test]
fn views_of_absurd_size_are_refused_before_rendering() {
    let tmp = tempfile::tempdir().unwrap();
    let stream = wrapped_vector("stream.pwb");
    let out = tmp.path().join("out");
    let wide = tmp.path().join("wide");
    std::fs::create_dir(&wide).unwrap();
    let dataset = dataset_of_size(&wide, 70_000, 1);
    let run = pwdec(&[stream.to_str().unwrap(), "--views", &dataset, "--split", "all", "-o", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && err.contains("a.png") && err.contains("70000x1"), "{err}");
    assert!(!out.join("a.png").exists());
    // Within the side limit, the pixel limit still applies.
    let tall = tmp.path().join("tall");
    std::fs::create_dir(&tall).unwrap();
    let dataset = dataset_of_size(&tall, 2, 60_000);
    let run = pwdec(&[
        stream.to_str().unwrap(),
        "--views",
        &dataset,
        "--split",
        "all",
        "--max-pixels",
        "100000",
        "-o",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && err.contains("--max-pixels"), "{err}");
}

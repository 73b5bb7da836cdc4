//! `pwplay` as a user runs it: the headless screenshot through the GPU path against the CPU
//! reference (decoded, base only, residual), its errors, and the real window under Xvfb showing
//! the scene. Without a GPU adapter (or Xvfb, for the window) these tests skip, saying so,
//! unless `PWGS_REQUIRE_GPU` is set (CI installs lavapipe and Xvfb and sets it).

use pwgs_render::show::SceneRender;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use pwgs_codec::stream;
use pwgs_core::camera_json::parse_camera;
use pwgs_render::gpu::GpuRenderer;

fn required() -> bool {
    std::env::var_os("PWGS_REQUIRE_GPU").is_some()
}

/// Whether a GPU adapter is there; without one the test skips, or fails under CI.
fn gpu_present() -> bool {
    match GpuRenderer::new() {
        Ok(_) => true,
        Err(e) if required() => panic!("PWGS_REQUIRE_GPU is set: {e}"),
        Err(e) => {
            eprintln!("skipped: {e}");
            false
        }
    }
}

fn vector(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../conformance/vectors").join(name)
}

fn pwplay(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pwplay")).args(args).output().expect("pwplay runs")
}

/// SPEC.md section 8's tolerance on 8-bit renders: at most 2/255 per channel, 99.9% within 1/255.
fn assert_within_render_tolerance(what: &str, expected: &[u8], got: &[u8]) {
    assert_eq!(expected.len(), got.len(), "{what}: size");
    let d: Vec<i32> = expected.iter().zip(got).map(|(a, b)| (i32::from(*a) - i32::from(*b)).abs()).collect();
    let within_one = d.iter().filter(|&&v| v <= 1).count() as f64 / d.len() as f64;
    let worst = d.iter().copied().max().unwrap_or(0);
    eprintln!("{what}: largest difference {worst}/255, {:.4}% within 1/255", 100.0 * within_one);
    assert!(worst <= 2 && within_one >= 0.999, "{what}: largest difference {worst}/255, {within_one} within 1/255");
}

#[test]
fn headless_screenshots_match_the_cpu_reference() {
    if !gpu_present() {
        return;
    }
    let dir = vector("generated-3dgs-wrapped");
    let stream_path = dir.join("stream.pwb");
    let view = dir.join("view_opencv.json");
    let decoded = stream::decode(&std::fs::read(&stream_path).unwrap()).unwrap();
    let camera = parse_camera(&std::fs::read_to_string(&view).unwrap()).unwrap();
    let options = decoded.scene.render_options();
    let shown = decoded.scene.render(&camera, &options, true).unwrap();
    let base = decoded.scene.render(&camera, &options, false).unwrap();
    let residual: Vec<u8> = shown
        .residual
        .as_ref()
        .expect("the vector has a wrapper")
        .iter()
        .map(|r| ((0.5 + pwgs_player::headless::RESIDUAL_GAIN * r).clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    let out = tempfile::tempdir().unwrap();
    let cases: [(&str, Option<&str>, Vec<u8>); 3] = [
        ("decoded", None, shown.image.to_rgb8().into_raw()),
        ("base only", Some("--no-wrapper"), base.image.to_rgb8().into_raw()),
        ("residual", Some("--residual"), residual),
    ];
    for (what, flag, expected) in cases {
        // The GPU path within the render tolerance; the CPU renderer (what a software adapter
        // gets by default) is the reference itself.
        for renderer in ["gpu", "cpu"] {
            let png = out.path().join(format!("{what}-{renderer}.png"));
            let mut args = vec![
                stream_path.as_os_str(),
                "--view".as_ref(),
                view.as_os_str(),
                "--screenshot".as_ref(),
                png.as_os_str(),
                "--renderer".as_ref(),
                renderer.as_ref(),
            ];
            args.extend(flag.map(std::ffi::OsStr::new));
            let run = pwplay(&args);
            let says = String::from_utf8_lossy(&run.stderr);
            assert!(run.status.success(), "{what} on {renderer}: {says}");
            assert_eq!(says.contains("the CPU renderer"), renderer == "cpu", "{says}");
            let got = image::open(&png).unwrap().to_rgb8();
            assert_eq!((got.width(), got.height()), (camera.width, camera.height), "{what}");
            match renderer {
                "gpu" => assert_within_render_tolerance(what, &expected, got.as_raw()),
                _ => assert!(&expected == got.as_raw(), "{what}: the CPU renderer's screenshot is not the reference"),
            }
        }
    }
}

#[test]
fn headless_errors_name_the_problem_and_write_nothing() {
    let out = tempfile::tempdir().unwrap();
    let png = out.path().join("never.png");
    let plain = vector("generated-3dgs");
    let view = plain.join("view_opencv.json");
    let missing = out.path().join("missing.pwb");
    let (plain_stream, not_a_camera) = (plain.join("stream.pwb"), plain.join("expected.json"));
    let cases: [(Vec<&std::ffi::OsStr>, &str); 3] = [
        (
            vec![missing.as_os_str(), "--view".as_ref(), view.as_os_str(), "--screenshot".as_ref(), png.as_os_str()],
            "missing.pwb",
        ),
        (
            vec![
                plain_stream.as_os_str(),
                "--view".as_ref(),
                not_a_camera.as_os_str(),
                "--screenshot".as_ref(),
                png.as_os_str(),
            ],
            "bad camera",
        ),
        (
            vec![
                plain_stream.as_os_str(),
                "--view".as_ref(),
                view.as_os_str(),
                "--screenshot".as_ref(),
                png.as_os_str(),
                "--residual".as_ref(),
            ],
            "no perceptual wrapper",
        ),
    ];
    for (args, says) in cases {
        let run = pwplay(&args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{says}: pwplay succeeded");
        assert!(stderr.contains(says) && !stderr.contains("panicked"), "expected \"{says}\" in: {stderr}");
        assert!(!png.exists(), "{says}: a screenshot was written");
    }
}

/// Runs `command` until it exits or `limit` passes (then kills it and fails).
fn run_with_limit(command: &mut Command, limit: Duration) -> Output {
    let mut child = command.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("starts");
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            let output = child.wait_with_output().unwrap();
            panic!("still running after {limit:?}: {}", String::from_utf8_lossy(&output.stderr));
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    child.wait_with_output().unwrap()
}

/// The real window, on a virtual X display: it opens the stream, shows its first view and saves
/// a screenshot of itself. The picture must show the scene: the conformance scene's Gaussians
/// are saturated colors, which egui's gray panels and text never are.
#[test]
fn the_window_shows_the_scene_under_xvfb() {
    if !gpu_present() {
        return;
    }
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        assert!(!required(), "PWGS_REQUIRE_GPU is set but xvfb-run is missing");
        eprintln!("skipped: no xvfb-run (package xvfb)");
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let png = out.path().join("window.png");
    let stream_path = vector("generated-3dgs-wrapped").join("stream.pwb");
    let run = run_with_limit(
        Command::new("xvfb-run")
            .args(["-a", "-s", "-screen 0 1280x800x24"])
            .arg(env!("CARGO_BIN_EXE_pwplay"))
            .arg(&stream_path)
            .arg("--screenshot")
            .arg(&png)
            .env("XDG_RUNTIME_DIR", out.path())
            .env("WGPU_BACKEND", "vulkan"),
        Duration::from_secs(300),
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success() && png.exists(), "the window failed: {stderr}");
    let shot = image::open(&png).unwrap().to_rgb8();
    assert!(shot.width() >= 800 && shot.height() >= 500, "window of {}x{}", shot.width(), shot.height());
    // The central panel: right of the controls (340 points wide).
    let saturated: Vec<[u8; 3]> = shot
        .enumerate_pixels()
        .filter(|(x, _, _)| *x > 360)
        .map(|(_, _, p)| p.0)
        .filter(|p| p.iter().max().unwrap() - p.iter().min().unwrap() > 40)
        .collect();
    let area = (shot.width() - 360) as usize * shot.height() as usize;
    let mut distinct = saturated.clone();
    distinct.sort_unstable();
    distinct.dedup();
    eprintln!("{} of {area} central pixels saturated, {} distinct colors", saturated.len(), distinct.len());
    assert!(saturated.len() * 20 > area, "the central panel shows no scene: {stderr}");
    assert!(distinct.len() > 200, "the central panel is flat, not a render: {stderr}");
}

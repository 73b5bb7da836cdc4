//! Bounded work and memory for every input: `pwdec` on every invalid file of the
//! conformance suite and on every hostile stream (`conformance/hostile/`), each under a 1 GiB
//! address-space limit and within its CPU-time bound (1 s, plus 2 s per megapixel rendered):
//! refused with its error, or decoded and rendered, never a panic, an abort or a hang. The
//! importers' hostile files are `pwenc`'s (`apps/pwenc/tests/import_resources.rs`).
//!
//! One test in this binary: the CPU time of each run is read from this process's children.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use pwgs_conformance::generator::hostile::{self, Outcome, Tool};
use pwgs_conformance::invalid::expected_refusals;
use pwgs_conformance::resources::{check_run, cpu_bound, run_limited};

fn conformance() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../conformance")
}

/// The pixels of a camera file's view (0 if it does not parse: it is then refused).
fn view_pixels(camera: &Path) -> u64 {
    let text = std::fs::read_to_string(camera).unwrap_or_default();
    pwgs_core::camera_json::parse_camera(&text).map_or(0, |c| u64::from(c.width) * u64::from(c.height))
}

#[test]
fn every_invalid_and_hostile_file_keeps_to_the_bounds() {
    let pwdec = Path::new(env!("CARGO_BIN_EXE_pwdec"));
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("view.png");
    let some_stream = conformance().join("vectors/sh1/stream.pwb");
    let mut runs: Vec<(String, Vec<PathBuf>, Outcome, f64)> = Vec::new();
    let invalid = conformance().join("invalid");
    for (name, refusal) in expected_refusals(&invalid).unwrap() {
        let file = invalid.join(&name);
        // The first part of the listed error: the section or field it names.
        let error = refusal.error.split(" … ").next().unwrap().to_string();
        let args = match name.ends_with(".json") {
            true => vec![some_stream.clone(), "--view".into(), file, "-o".into(), png.clone()],
            false => vec![file, "--hash".into()],
        };
        runs.push((name, args, Outcome::Refused(error), cpu_bound(0)));
    }
    let hostile_dir = conformance().join(hostile::HOSTILE_DIR);
    for (name, entry) in hostile::expected(&conformance()).unwrap() {
        if entry.tool != Tool::Pwdec {
            continue;
        }
        let file = hostile_dir.join(&name);
        let (args, pixels) = match &entry.view {
            Some(view) => {
                let camera = hostile_dir.join(view);
                let pixels = view_pixels(&camera);
                (vec![file, "--view".into(), camera, "-o".into(), png.clone()], pixels)
            }
            None => (vec![file, "--hash".into()], 0),
        };
        runs.push((name, args, entry.outcome, cpu_bound(pixels)));
    }
    assert!(runs.len() > 150, "only {} files found", runs.len());
    let mut failures = Vec::new();
    let mut slowest = (String::new(), 0.0f64);
    for (name, args, outcome, limit) in &runs {
        let args: Vec<&OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        let run = run_limited(pwdec, &args);
        if run.cpu_seconds > slowest.1 {
            slowest = (name.clone(), run.cpu_seconds);
        }
        if let Err(e) = check_run(name, &run, outcome, *limit) {
            failures.push(e);
        }
    }
    eprintln!("{} files; the slowest, {}, took {:.2} s of CPU", runs.len(), slowest.0, slowest.1);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

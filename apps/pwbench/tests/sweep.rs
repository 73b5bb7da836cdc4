//! `pwbench sweep` end to end with a stand-in for pwenc (a shell script that writes the report
//! a run would): every point runs once, a second sweep runs none, and a failing point stops
//! the sweep naming it while the finished runs stay.
#![cfg(unix)]

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Output};

/// A pwenc that prints progress lines, counts its runs in `calls`, fails on `--fail`, and
/// writes a report whose size is 1e6 / λ bytes and whose PSNR grows with it.
const STAND_IN: &str = r#"#!/bin/sh
echo "$@" >> "$(dirname "$0")/calls"
report=""; lambda=1
while [ $# -gt 0 ]; do
    case $1 in
        --report) report=$2; shift ;;
        --lambda) lambda=$2; shift ;;
        --fail) echo "iteration 1/4" >&2; echo "error: made to fail" >&2; exit 3 ;;
    esac
    shift
done
echo "iteration 2/4  loss 0.1" >&2
echo "iteration 4/4  loss 0.1" >&2
awk -v l="$lambda" 'BEGIN { printf "{\"stream\":{\"bytes\":%f},\"mean\":{\"psnr\":%f,\"dists\":%f}}", 1e6 / l, 30 - l, 0.05 * l }' > "$report"
"#;

fn sweep(dir: &Path, plan: &str) -> Output {
    let plan_path = dir.join("plan.json");
    std::fs::write(&plan_path, plan).unwrap();
    Command::new(env!("CARGO_BIN_EXE_pwbench"))
        .args(["sweep", plan_path.to_str().unwrap(), "--pwenc", dir.join("pwenc").to_str().unwrap()])
        .args(["-o", dir.join("out").to_str().unwrap(), "--reference", "plain"])
        .output()
        .unwrap()
}

fn calls(dir: &Path) -> usize {
    std::fs::read_to_string(dir.join("calls")).map_or(0, |s| s.lines().count())
}

#[test]
fn a_sweep_runs_each_point_once_and_resumes() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("pwenc"), STAND_IN).unwrap();
    std::fs::set_permissions(d.join("pwenc"), std::fs::Permissions::from_mode(0o755)).unwrap();
    let plan = r#"{"scene": "fern", "common": ["--downscale", "8"], "curves": [
        {"name": "plain", "points": [["--lambda", "1"], ["--lambda", "2"], ["--lambda", "4"]]},
        {"name": "anchor λ.5", "points": [["--lambda", "2"], ["--lambda", "4"], ["--lambda", "8"]]}]}"#;
    let out = sweep(d, plan);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(calls(d), 6);
    // Each run got the scene, the common options, its own, then its outputs.
    let first = std::fs::read_to_string(d.join("calls")).unwrap();
    let runs = d.join("out/runs");
    let expected = format!(
        "fern --downscale 8 --lambda 1 -o {0}/plain_0.pwb --eval {0}/plain_0_eval --report {0}/plain_0.json",
        runs.display()
    );
    assert_eq!(first.lines().next().unwrap(), expected);
    assert!(runs.join("anchor__.5_2.json").is_file(), "a dotted name keeps its dots");
    assert!(std::fs::read_to_string(runs.join("plain_1.log")).unwrap().contains("iteration 4/4"));
    let md = std::fs::read_to_string(d.join("out/report.md")).unwrap();
    let row = md.lines().find(|l| l.starts_with("| anchor λ.5 | 125000 |")).unwrap_or_else(|| panic!("{md}"));
    assert!(row.contains("| 22.00 |"), "{row}");

    // Run again: every report is there, so nothing runs and the report is rewritten.
    std::fs::remove_file(d.join("out/report.md")).unwrap();
    let out = sweep(d, plan);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(calls(d), 6);
    assert!(d.join("out/report.md").is_file());

    // A failing point stops the sweep, naming the point and its log; the runs before it stay.
    let failing = plan.replace(r#"["--lambda", "8"]"#, r#"["--fail"]"#).replace("λ.5", "broken");
    let out = sweep(d, &failing);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("the point 2 of `anchor broken` (--fail)") && stderr.contains("anchor_broken_2.log"),
        "{stderr}"
    );
    assert!(std::fs::read_to_string(runs.join("anchor_broken_2.log")).unwrap().contains("made to fail"));
    assert!(runs.join("anchor_broken_1.json").is_file() && runs.join("plain_0.json").is_file());
}

#[test]
fn bad_plans_are_refused_before_any_run() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    for (plan, needle) in [
        ("{", "is not a sweep plan"),
        (r#"{"scene": "s", "curves": []}"#, "no curves"),
        (r#"{"scene": "s", "curves": [{"name": "a", "points": []}]}"#, "`a` has no points"),
        (r#"{"scene": "s", "curves": [{"name": "a+", "points": [[]]}, {"name": "a!", "points": [[]]}]}"#, "share"),
        (r#"{"scene": "s", "curves": [{"name": "a", "points": [["-o", "x.pwb"]]}]}"#, "`-o` in the curve `a`"),
        (r#"{"scene": "s", "curves": [{"name": "/", "points": [[]]}]}"#, "a letter or digit"),
        (r#"{"scene": "s", "curves": [], "extra": 1}"#, "unknown field"),
    ] {
        let out = sweep(d, plan);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(needle), "{plan}: {stderr}");
    }
    assert!(!d.join("out/runs").exists() || std::fs::read_dir(d.join("out/runs")).unwrap().next().is_none());
}

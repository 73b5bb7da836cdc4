//! `pwbench` end to end on made-up reports: the report states the Bjøntegaard deltas the
//! curves were built to have, and draws a chart per metric they carry.

use std::path::Path;
use std::process::Command;

/// How a report states its times.
#[derive(Clone, Copy)]
enum Times {
    /// `pwenc --report` of the plain base: the training time nested.
    PlainBase,
    /// `pwenc --report` of the anchor base: the training time on top.
    AnchorBase,
    /// `pwenc compare --encode-seconds 120 --decode-seconds 0.25`.
    Compare,
}

/// A report as `pwenc --report` or `pwenc compare --report` writes it (only the fields pwbench
/// reads).
fn report(dir: &Path, name: &str, bytes: f64, psnr: f64, dists: f64, times: Times) -> String {
    let path = dir.join(format!("{name}.json"));
    let training = match times {
        Times::PlainBase => serde_json::json!({ "training": { "iterations": 2000, "seconds": 100.0 } }),
        Times::AnchorBase => serde_json::json!({ "iterations": 2000, "training_seconds": 120.0 }),
        Times::Compare => serde_json::json!({ "encode_seconds": 120.0, "decode_seconds": 0.25 }),
    };
    // Two views around the mean; rendering takes longer the larger the stream.
    let views: Vec<serde_json::Value> = [-0.5, 0.5]
        .iter()
        .enumerate()
        .map(|(i, d)| {
            serde_json::json!({ "name": format!("view{i}.png"), "psnr": psnr + d, "ssim": 0.8,
                                "dists": dists, "render_seconds": bytes / 1e6 + 0.01 * i as f64 })
        })
        .collect();
    let mut value = serde_json::json!({
        "stream": { "bytes": bytes },
        "mean": { "psnr": psnr, "ssim": 0.8, "dists": dists },
        "views": views,
        "peak_resident_mib": 512.0,
    });
    value.as_object_mut().unwrap().extend(training.as_object().unwrap().clone());
    std::fs::write(&path, value.to_string()).unwrap();
    path.display().to_string()
}

#[test]
fn the_report_states_the_deltas_the_curves_were_made_with() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // "half" needs half the bytes of "base" for every PSNR and DISTS.
    let points = [(100_000.0, 25.0, 0.14), (200_000.0, 26.5, 0.12), (400_000.0, 27.5, 0.10)];
    let base: Vec<String> = points
        .iter()
        .enumerate()
        .map(|(i, &(b, p, s))| report(d, &format!("b{i}"), b, p, s, Times::PlainBase))
        .collect();
    let half: Vec<String> = points
        .iter()
        .enumerate()
        .map(|(i, &(b, p, s))| {
            let times = if i == 0 { Times::AnchorBase } else { Times::Compare };
            report(d, &format!("h{i}"), b / 2.0, p, s, times)
        })
        .collect();
    let out = d.join("out");
    let status = Command::new(env!("CARGO_BIN_EXE_pwbench"))
        .args([format!("base={}", base.join(",")), format!("half={}", half.join(","))])
        .args(["-o", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let deltas = md.split("## Bjøntegaard").nth(1).unwrap_or_else(|| panic!("{md}"));
    let row = deltas.lines().find(|l| l.starts_with("| half |")).unwrap_or_else(|| panic!("{md}"));
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    // Columns: name, BD-rate on PSNR, SSIM, LPIPS, DISTS, WD, then BD-PSNR.
    assert!(cells[2].starts_with("-50.0% (over 25.00 to 27.50)"), "{row}");
    assert_eq!(cells[3], "no overlap", "SSIM is the same at every rate: {row}");
    assert_eq!(cells[4], "no overlap", "no run has LPIPS: {row}");
    assert!(cells[5].starts_with("-50.0% (over 0.1000 to 0.1400)"), "{row}");
    let bd_psnr: f64 = cells[7].split(' ').next().unwrap().parse().unwrap();
    assert!(bd_psnr > 1.0 && bd_psnr < 2.5, "{row}");
    // Each run of "half" against "base" at its own score: half the bytes.
    let equal = md.split("## Size at equal score").nth(1).unwrap_or_else(|| panic!("{md}"));
    let row = equal.lines().find(|l| l.starts_with("| half | 100000 | PSNR (dB) |")).unwrap_or_else(|| panic!("{md}"));
    assert!(row.ends_with("| 26.50 | 200000 | 0.50 |"), "{row}");
    let row = equal.lines().find(|l| l.starts_with("| half | 200000 | DISTS |")).unwrap_or_else(|| panic!("{md}"));
    assert!(row.ends_with("| 0.1000 | 400000 | 0.50 |"), "{row}");
    // Each run of "half" against "base" at its own size: base's own points where they coincide.
    let equal = md.split("## Scores at equal size").nth(1).unwrap_or_else(|| panic!("{md}"));
    let row = equal.lines().find(|l| l.starts_with("| half | 200000 | PSNR (dB) |")).unwrap_or_else(|| panic!("{md}"));
    assert!(row.ends_with("| 27.50 | 26.50 | +1.00 dB |"), "{row}");
    let row = equal.lines().find(|l| l.starts_with("| half | 200000 | DISTS |")).unwrap_or_else(|| panic!("{md}"));
    assert!(row.ends_with("| 0.1000 | 0.1200 | -16.7% |"), "{row}");
    let row = equal.lines().find(|l| l.starts_with("| half | 50000 | DISTS |")).unwrap_or_else(|| panic!("{md}"));
    assert!(row.ends_with("| outside its range | - |"), "{row}");
    for metric in ["psnr", "ssim", "dists"] {
        let svg = std::fs::read_to_string(out.join(format!("rd_{metric}.svg"))).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("half"), "rd_{metric}.svg");
    }
    assert!(!out.join("rd_wd.svg").exists(), "no run has WD");
    // Speed against error: each run's mean render time (bytes / 1e6 + 0.005 s) and encode time.
    for chart in ["speed_render_psnr", "speed_render_dists", "speed_encode_psnr", "speed_encode_dists"] {
        let svg = std::fs::read_to_string(out.join(format!("{chart}.svg"))).unwrap();
        assert!(svg.contains("half") && md.contains(&format!("({chart}.svg)")), "{chart}");
    }
    let runs = md.split("## Runs").nth(1).unwrap();
    // Columns after the five metrics: encode s, decode s, render s/view, peak MiB.
    let cells_of = |bytes: &str| -> Vec<String> {
        let row =
            runs.lines().find(|l| l.starts_with(&format!("| half | {bytes} |"))).unwrap_or_else(|| panic!("{md}"));
        row.split('|').map(|c| c.trim().to_string()).collect()
    };
    assert_eq!(cells_of("50000")[8..12], ["120.0", "-", "0.055", "512"], "an anchor-base report");
    assert_eq!(cells_of("100000")[8..12], ["120.0", "0.25", "0.105", "512"], "a compare report with its times");
    // Per-view scores: both views of every run.
    let views = md.split("## Per-view scores").nth(1).unwrap_or_else(|| panic!("{md}"));
    assert_eq!(views.lines().filter(|l| l.starts_with("| ")).count(), 1 + 12, "a header and 6 runs x 2 views");
    assert!(views.contains("| base | 100000 | view1.png | 25.50 |"), "{views}");
}

#[test]
fn bad_arguments_are_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_pwbench")).args(args).output().unwrap();
    let out = run(&["nonsense", "-o", tmp.path().to_str().unwrap()]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("NAME=report.json"));
    let missing = tmp.path().join("missing.json");
    let out = run(&[&format!("a={}", missing.display()), "-o", tmp.path().to_str().unwrap()]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("cannot read"));
    let no_stream = tmp.path().join("r.json");
    std::fs::write(&no_stream, r#"{"mean": {"psnr": 20}}"#).unwrap();
    let out = run(&[&format!("a={}", no_stream.display()), "-o", tmp.path().to_str().unwrap()]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("no stream size"));
}

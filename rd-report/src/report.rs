//! The report: `report.md` with the runs, the Bjøntegaard deltas of every curve against the
//! reference curve, each other run's size against the reference at equal score and its scores
//! against the reference at equal size, one RD chart
//! per metric, speed-versus-error charts (render and training time against PSNR and DISTS) and
//! every run's per-view scores, the charts beside it.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::bjontegaard::{RdPoint, bd_quality, bd_rate, bytes_at, quality_at};
use crate::plot::chart;
use crate::runs::{Axis, Curve, Metric};

fn rd_points(curve: &Curve, metric: Metric) -> Vec<RdPoint> {
    curve.points(metric).into_iter().map(|(bytes, quality)| RdPoint { bytes, quality }).collect()
}

fn cell(value: Option<f64>, digits: usize) -> String {
    value.map_or_else(|| "-".into(), |v| format!("{v:.digits$}"))
}

/// Digits a metric is printed with.
fn digits(metric: Metric) -> usize {
    match metric {
        Metric::Psnr => 2,
        Metric::Wd => 3,
        _ => 4,
    }
}

/// The runs of every curve, one table.
fn runs_table(curves: &[Curve]) -> String {
    let mut s = String::from(
        "| curve | bytes | PSNR | SSIM | LPIPS | DISTS | WD | encode s | decode s | render s/view | peak MiB | report |\n",
    );
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for c in curves {
        for r in &c.runs {
            let scores: Vec<String> = Metric::ALL.iter().map(|&m| cell(r.score(m), digits(m))).collect();
            let _ = writeln!(
                s,
                "| {} | {:.0} | {} | {} | {} | {} | {} | `{}` |",
                c.name,
                r.bytes,
                scores.join(" | "),
                cell(r.encode_seconds, 1),
                cell(r.decode_seconds, 2),
                cell(r.render_seconds, 3),
                cell(r.peak_resident_mib, 0),
                r.file
            );
        }
    }
    s
}

/// Every run's test views, one row each.
fn views_table(curves: &[Curve]) -> String {
    let mut s = String::from("| curve | bytes | view | PSNR | SSIM | LPIPS | DISTS | WD | render s |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|\n");
    for c in curves {
        for r in &c.runs {
            for v in &r.views {
                let scores: Vec<String> = Metric::ALL.iter().map(|&m| cell(v.score(m), digits(m))).collect();
                let time = cell(v.render_seconds, 3);
                let _ = writeln!(s, "| {} | {:.0} | {} | {} | {time} |", c.name, r.bytes, v.name, scores.join(" | "));
            }
        }
    }
    s
}

/// BD-rate on every metric and BD-PSNR of each curve against `reference`.
fn deltas_table(curves: &[Curve], reference: &Curve) -> String {
    let mut s = String::from("| curve | ");
    for m in Metric::ALL {
        let _ = write!(s, "BD-rate on {} | ", m.label());
    }
    s.push_str("BD-PSNR |\n|---|");
    s.push_str(&"---|".repeat(Metric::ALL.len() + 1));
    s.push('\n');
    for c in curves.iter().filter(|c| c.name != reference.name) {
        let _ = write!(s, "| {} | ", c.name);
        for m in Metric::ALL {
            let text = match bd_rate(&rd_points(reference, m), &rd_points(c, m)) {
                Some(d) => format!("{:+.1}% (over {:.d$} to {:.d$})", d.value, d.over.0, d.over.1, d = digits(m)),
                None => "no overlap".into(),
            };
            let _ = write!(s, "{text} | ");
        }
        let psnr = bd_quality(&rd_points(reference, Metric::Psnr), &rd_points(c, Metric::Psnr));
        let text = psnr.map_or_else(
            || "no overlap".into(),
            |d| format!("{:+.2} dB (over {:.0} to {:.0} bytes)", d.value, 10f64.powf(d.over.0), 10f64.powf(d.over.1)),
        );
        let _ = writeln!(s, "{text} |");
    }
    s
}

/// For each run of the other curves, the bytes `reference` needs for the same score (on each
/// metric the run has), and the ratio: how a single file of another format compares with a
/// curve of qualities.
fn equal_score_table(curves: &[Curve], reference: &Curve) -> String {
    let mut s = format!(
        "| curve | bytes | metric | score | `{}` bytes at that score | bytes / `{}` bytes |\n|---|---|---|---|---|---|\n",
        reference.name, reference.name
    );
    for c in curves.iter().filter(|c| c.name != reference.name) {
        for r in &c.runs {
            for m in Metric::ALL {
                let Some(score) = r.score(m) else { continue };
                let (at, ratio) = match bytes_at(&rd_points(reference, m), score) {
                    Some(b) => (format!("{b:.0}"), format!("{:.2}", r.bytes / b)),
                    None => ("outside its range".into(), "-".into()),
                };
                let d = digits(m);
                let _ = writeln!(s, "| {} | {:.0} | {} | {score:.d$} | {at} | {ratio} |", c.name, r.bytes, m.label());
            }
        }
    }
    s
}

/// For each run of the other curves, the score `reference` has at the run's size, and the
/// difference: the equal-size comparison (say, a wrapper run against the base's curve) without
/// needing a second run of exactly that size. PSNR differs in dB, the other metrics in percent.
fn equal_size_table(curves: &[Curve], reference: &Curve) -> String {
    let mut s = format!(
        "| curve | bytes | metric | score | `{}` at that size | difference |\n|---|---|---|---|---|---|\n",
        reference.name
    );
    for c in curves.iter().filter(|c| c.name != reference.name) {
        for r in &c.runs {
            for m in Metric::ALL {
                let Some(score) = r.score(m) else { continue };
                let d = digits(m);
                let (at, change) = match quality_at(&rd_points(reference, m), r.bytes) {
                    Some(q) if m == Metric::Psnr => (format!("{q:.d$}"), format!("{:+.2} dB", score - q)),
                    Some(q) => (format!("{q:.d$}"), format!("{:+.1}%", (score / q - 1.0) * 100.0)),
                    None => ("outside its range".into(), "-".into()),
                };
                let _ = writeln!(s, "| {} | {:.0} | {} | {score:.d$} | {at} | {change} |", c.name, r.bytes, m.label());
            }
        }
    }
    s
}

/// Writes the charts and `report.md` into `dir` (created if needed); returns the report's path.
pub fn write_report(curves: &[Curve], reference: &Curve, title: &str, dir: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut md = format!("# {title}\n\n## Runs\n\n{}\n", runs_table(curves));
    let _ = writeln!(
        md,
        "## Bjøntegaard deltas against `{}`\n\nBD-rate: how many percent more (+) or fewer (-) bytes a curve needs for \
         the same score, averaged over the scores both curves reach (piecewise cubic interpolation of log rate); \
         BD-PSNR: its PSNR difference at equal size. A curve needs 2 runs or more.\n\n{}",
        reference.name,
        deltas_table(curves, reference)
    );
    for (heading, at, like, table) in [
        ("Size at equal score", "score", "BD-rate", equal_score_table(curves, reference)),
        ("Scores at equal size", "size", "BD-PSNR", equal_size_table(curves, reference)),
    ] {
        let _ = writeln!(
            md,
            "## {heading}\n\nEach run of the other curves against `{}` interpolated at the run's {at} \
             (as {like} interpolates; a curve of 2 runs or more).\n\n{table}",
            reference.name
        );
    }
    md.push_str("## Rate-distortion charts\n\n");
    for m in Metric::ALL {
        let file = format!("rd_{}.svg", m.key());
        if chart(curves, Axis::Kilobytes, m, &format!("{title}: {}", m.label()), &dir.join(&file))? {
            let _ = writeln!(md, "![{}]({file})\n", m.label());
        }
    }
    md.push_str(
        "## Speed against error\n\nRender time: the mean time to render one decoded test view, at each rate \
         point; encode time: the encoder's (a scene's training). Times are the machines' the runs were made on.\n\n",
    );
    for (axis, name) in [(Axis::RenderSeconds, "render"), (Axis::EncodeSeconds, "encode")] {
        for m in [Metric::Psnr, Metric::Dists] {
            let file = format!("speed_{name}_{}.svg", m.key());
            let caption = format!("{title}: {} against {name} time", m.label());
            if chart(curves, axis, m, &caption, &dir.join(&file))? {
                let _ = writeln!(md, "![{caption}]({file})\n");
            }
        }
    }
    let _ = write!(md, "## Per-view scores\n\n{}", views_table(curves));
    let path = dir.join("report.md");
    std::fs::write(&path, md).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path)
}

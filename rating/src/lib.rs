//! pwrate's library: a human A/B rating study of renders ([`study`]) served as a
//! local page ([`server`]), its judgments screened by golden questions ([`judgments`]), and
//! their Bayesian Elo fit ([`elo`]) with a chart ([`chart`]).

pub mod chart;
pub mod elo;
pub mod judgments;
pub mod server;
pub mod study;

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;

use chart::{Z95, elo_chart};

/// `pwrate fit`: reads and screens the judgments, fits them, optionally draws the chart, and
/// says what it did: each rater's golden record, each method's Elo with its 95% interval
/// (strongest first), and the probability that each method is stronger than each other one.
pub fn fit_study(path: &Path, prior_elo: f64, min_golden: f64, chart: Option<&Path>) -> Result<String> {
    let all = judgments::read(path)?;
    let screened = judgments::screen(&all, min_golden);
    let mut out = String::new();
    for (rater, (asked, right)) in &screened.golden {
        let verdict = if screened.rejected.contains(rater) { "rejected" } else { "kept" };
        let _ = writeln!(out, "rater {rater}: {right}/{asked} golden questions right, {verdict}");
    }
    let f = elo::fit(&screened.kept, prior_elo)?;
    let _ = writeln!(out, "{} judgments of {} fitted (prior sd {prior_elo} Elo)", f.judgments, all.len());
    let mut order: Vec<usize> = (0..f.methods.len()).collect();
    order.sort_by(|&a, &b| f.elo[b].total_cmp(&f.elo[a]));
    let _ = writeln!(out, "{:<24} {:>8} {:>18}", "method", "Elo", "95% interval");
    for &i in &order {
        let (e, half) = (f.elo[i], Z95 * f.sd(i));
        let _ = writeln!(out, "{:<24} {e:>8.1} {:>8.1} .. {:<8.1}", f.methods[i], e - half, e + half);
    }
    let _ = writeln!(out, "P(row stronger than column):");
    for &i in &order {
        let cells: Vec<String> = order.iter().map(|&j| format!("{:.3}", f.probability_stronger(i, j))).collect();
        let _ = writeln!(out, "{:<24} {}", f.methods[i], cells.join(" "));
    }
    if let Some(path) = chart {
        elo_chart(&f, "Bayesian Elo", path)?;
        let _ = writeln!(out, "wrote {}", path.display());
    }
    Ok(out)
}

//! `pwrate fit judgments.jsonl`: the Bayesian Elo of the methods a rating study compared.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};
use pwgs_rate::chart::{Z95, elo_chart};
use pwgs_rate::elo::fit;
use pwgs_rate::judgments::{read, screen};

#[derive(Parser)]
#[command(name = "pwrate", version, about = "Human A/B ratings of renders and their Bayesian Elo")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fit Bayesian Elo to a judgments file (one JSON object per line), after screening raters
    /// by their golden questions.
    Fit {
        judgments: PathBuf,
        /// Prior standard deviation of every method's strength, in Elo points.
        #[arg(long, default_value_t = 400.0)]
        prior_elo: f64,
        /// Least share of golden questions a rater must get right to be kept.
        #[arg(long, default_value_t = 0.8)]
        min_golden: f64,
        /// Also draw the methods' Elo with their 95% intervals into this SVG.
        #[arg(long)]
        chart: Option<PathBuf>,
    },
}

fn run(cli: Cli) -> Result<()> {
    let Command::Fit { judgments, prior_elo, min_golden, chart } = cli.command;
    let all = read(&judgments)?;
    let screened = screen(&all, min_golden);
    for (rater, (asked, right)) in &screened.golden {
        let verdict = if screened.rejected.contains(rater) { "rejected" } else { "kept" };
        println!("rater {rater}: {right}/{asked} golden questions right, {verdict}");
    }
    let f = fit(&screened.kept, prior_elo)?;
    println!("{} judgments of {} fitted (prior sd {prior_elo} Elo)", f.judgments, all.len());
    let mut order: Vec<usize> = (0..f.methods.len()).collect();
    order.sort_by(|&a, &b| f.elo[b].total_cmp(&f.elo[a]));
    println!("{:<24} {:>8} {:>18}", "method", "Elo", "95% interval");
    for &i in &order {
        let (e, half) = (f.elo[i], Z95 * f.sd(i));
        println!("{:<24} {e:>8.1} {:>8.1} .. {:<8.1}", f.methods[i], e - half, e + half);
    }
    println!("P(row stronger than column):");
    for &i in &order {
        let cells: Vec<String> = order.iter().map(|&j| format!("{:.3}", f.probability_stronger(i, j))).collect();
        println!("{:<24} {}", f.methods[i], cells.join(" "));
    }
    if let Some(path) = chart {
        elo_chart(&f, "Bayesian Elo", &path)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

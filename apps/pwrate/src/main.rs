//! `pwrate serve STUDY --judgments FILE`: the rating page; `pwrate fit FILE`: the Bayesian
//! Elo of the methods a rating study compared.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};
use pwgs_rating::fit_study;
use pwgs_rating::server::serve;
use pwgs_rating::study::Study;

#[derive(Parser)]
#[command(name = "pwrate", version, about = "Human A/B ratings of renders and their Bayesian Elo")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Serve the rating page of a study folder (gt/ plus one folder of renders per method) on
    /// 127.0.0.1, appending each judgment to a file as it is made.
    Serve {
        /// A study folder: gt/ and one folder of renders per method.
        #[arg(required_unless_present = "run", conflicts_with = "run")]
        study: Option<PathBuf>,
        /// Instead of a study folder, a run's eval folder (`pwenc --eval DIR`) as NAME=DIR, two
        /// or more: rated against the first run's DIR/gt.
        #[arg(long, value_parser = parse_run)]
        run: Vec<(String, PathBuf)>,
        /// The judgments file (JSON lines; created, or appended to).
        #[arg(long)]
        judgments: PathBuf,
        /// Port (0: any free one; the address is printed).
        #[arg(long, default_value_t = 8017)]
        port: u16,
    },
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

fn parse_run(s: &str) -> Result<(String, PathBuf), String> {
    match s.split_once('=') {
        Some((name, dir)) if !name.is_empty() && !dir.is_empty() => Ok((name.to_string(), PathBuf::from(dir))),
        _ => Err(format!("`{s}`: expected NAME=EVAL_DIR")),
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Serve { study, run, judgments, port } => {
            let study = match study {
                Some(folder) => Study::open(&folder)?,
                None => Study::of_runs(&run)?,
            };
            serve(study, judgments, port)
        }
        Command::Fit { judgments, prior_elo, min_golden, chart } => {
            print!("{}", fit_study(&judgments, prior_elo, min_golden, chart.as_deref())?);
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    pwgs_cli::report(run(Cli::parse()))
}

//! `pwbench NAME=a.json,b.json ... -o DIR`: a rate-distortion report (Markdown with SVG charts
//! and Bjøntegaard deltas) from reports written by `pwenc --report`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::Parser;
use pwgs_bench::report::write_report;
use pwgs_bench::runs::Curve;

#[derive(Parser)]
#[command(name = "pwbench", version, about = "Rate-distortion reports from pwenc's --report files")]
struct Cli {
    /// Curves: NAME=report.json,report.json,... (one report per rate point, each written by
    /// `pwenc ... -o X.pwb --eval --report X.json`).
    #[arg(required = true)]
    curves: Vec<String>,
    /// Folder for report.md and the charts.
    #[arg(short, long)]
    output: PathBuf,
    /// The curve the others are compared with (default: the first).
    #[arg(long)]
    reference: Option<String>,
    /// The report's title.
    #[arg(long, default_value = "Rate-distortion report")]
    title: String,
}

fn run(cli: Cli) -> Result<()> {
    let curves = cli.curves.iter().map(|c| Curve::parse(c)).collect::<Result<Vec<_>>>()?;
    let reference = match &cli.reference {
        Some(name) => match curves.iter().find(|c| &c.name == name) {
            Some(c) => c,
            None => bail!("--reference {name}: no curve has that name"),
        },
        None => &curves[0],
    };
    let path = write_report(&curves, reference, &cli.title, &cli.output)?;
    println!("wrote {}", path.display());
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

//! `pwbench NAME=a.json,b.json ... -o DIR`: a rate-distortion report (Markdown with SVG charts
//! and Bjøntegaard deltas) from reports written by `pwenc --report`; `pwbench sweep PLAN -o DIR`
//! runs `pwenc` for a plan's settings first.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::{Args, Parser, Subcommand};
use pwgs_rd_report::report::write_report;
use pwgs_rd_report::runs::Curve;
use pwgs_rd_report::sweep::Plan;

#[derive(Parser)]
#[command(
    name = "pwbench",
    version,
    about = "Rate-distortion reports from pwenc's --report files",
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Curves: NAME=report.json,report.json,... (one report per rate point, each written by
    /// `pwenc ... -o X.pwb --eval --report X.json`).
    #[arg(required = true)]
    curves: Vec<String>,
    // Always there without a subcommand: its --output is required then.
    #[command(flatten)]
    output: Option<Output>,
}

#[derive(Subcommand)]
enum Command {
    /// Run pwenc for every point of a plan (JSON: `{"scene": DIR, "common": [options...],
    /// "curves": [{"name": N, "points": [[options...], ...]}, ...]}`), keeping each finished
    /// run in DIR/runs so that a stopped sweep resumes, then write the report.
    Sweep {
        plan: PathBuf,
        /// The pwenc to run (default: the one beside pwbench, else pwenc on the PATH).
        #[arg(long)]
        pwenc: Option<PathBuf>,
        #[command(flatten)]
        output: Output,
    },
}

/// Where the report goes and what it compares with.
#[derive(Args)]
struct Output {
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

impl Output {
    fn write(&self, curves: &[Curve]) -> Result<()> {
        let reference = match &self.reference {
            Some(name) => match curves.iter().find(|c| &c.name == name) {
                Some(c) => c,
                None => bail!("--reference {name}: no curve has that name"),
            },
            None => &curves[0],
        };
        let path = write_report(curves, reference, &self.title, &self.output)?;
        println!("wrote {}", path.display());
        Ok(())
    }
}

/// pwenc beside this executable when there is one, else the name for a PATH search.
fn default_pwenc() -> PathBuf {
    let beside = std::env::current_exe().ok().and_then(|exe| Some(exe.parent()?.join("pwenc")));
    beside.filter(|p| p.is_file()).unwrap_or_else(|| PathBuf::from("pwenc"))
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Some(Command::Sweep { plan, pwenc, output }) => {
            let plan = Plan::read(&plan)?;
            let curves = plan.run(&pwenc.unwrap_or_else(default_pwenc), &output.output)?;
            output.write(&curves)
        }
        None => {
            let curves = cli.curves.iter().map(|c| Curve::parse(c)).collect::<Result<Vec<_>>>()?;
            cli.output.expect("clap requires --output with curves").write(&curves)
        }
    }
}

fn main() -> ExitCode {
    pwgs_cli::report(run(Cli::parse()))
}

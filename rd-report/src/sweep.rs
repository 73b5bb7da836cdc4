//! `pwbench sweep`: runs `pwenc` for every point of a plan (curves of settings on one scene),
//! keeping each finished run, so that a sweep stopped halfway resumes where it stopped, then
//! reads their reports into curves.
//!
//! A point's files are `DIR/runs/NAME_I.{pwb,json,log}` and its decoded test views
//! `DIR/runs/NAME_I_eval/`. A point whose report reads is done and is not run again.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context, Result, bail};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use serde::Deserialize;

use crate::runs::{Curve, Run};

/// What to run: `pwenc SCENE COMMON... POINT... -o ... --eval ... --report ...` per point.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// The scene folder every run trains on.
    pub scene: PathBuf,
    /// Options every run gets, before its own (e.g. `--downscale 8`, `--eval-metrics ...`).
    #[serde(default)]
    pub common: Vec<String>,
    pub curves: Vec<PlanCurve>,
}

/// One curve: a name and the options of each of its points (one rate point each).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanCurve {
    pub name: String,
    pub points: Vec<Vec<String>>,
}

/// Options pwbench sets on every run itself.
const OWN_OPTIONS: [&str; 5] = ["-o", "--output", "--eval", "--report", "--from-ply"];

impl Plan {
    /// Reads and checks a plan file (JSON).
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read the plan {}", path.display()))?;
        let plan: Plan =
            serde_json::from_str(&text).with_context(|| format!("{} is not a sweep plan", path.display()))?;
        plan.check().with_context(|| format!("the plan {}", path.display()))?;
        Ok(plan)
    }

    fn check(&self) -> Result<()> {
        if self.curves.is_empty() {
            bail!("it has no curves");
        }
        let mut stems: Vec<String> = Vec::new();
        for curve in &self.curves {
            let stem = file_stem(&curve.name);
            if stem.is_empty() {
                bail!("a curve needs a name with a letter or digit in it");
            }
            if stems.contains(&stem) {
                bail!("two curves would share the files `{stem}_*`: give `{}` another name", curve.name);
            }
            stems.push(stem);
            if curve.points.is_empty() {
                bail!("the curve `{}` has no points", curve.name);
            }
            let options = self.common.iter().chain(curve.points.iter().flatten());
            if let Some(own) = options.into_iter().find(|o| OWN_OPTIONS.contains(&o.as_str())) {
                bail!("`{own}` in the curve `{}`: pwbench sets the outputs of each run itself", curve.name);
            }
        }
        Ok(())
    }

    /// Runs every point whose report is missing with `pwenc`, writing into `dir/runs`, and
    /// returns the curves, in the plan's order.
    pub fn run(&self, pwenc: &Path, dir: &Path) -> Result<Vec<Curve>> {
        let runs = dir.join("runs");
        std::fs::create_dir_all(&runs).with_context(|| format!("cannot create {}", runs.display()))?;
        let total: usize = self.curves.iter().map(|c| c.points.len()).sum();
        let bars = MultiProgress::new();
        let overall = bars.add(ProgressBar::new(total as u64));
        overall.set_style(style("points {pos}/{len} [{elapsed_precise}] {msg}"));
        let mut curves = Vec::with_capacity(self.curves.len());
        for curve in &self.curves {
            let mut done = Vec::with_capacity(curve.points.len());
            for (i, point) in curve.points.iter().enumerate() {
                let stem = runs.join(format!("{}_{i}", file_stem(&curve.name)));
                let report = with_suffix(&stem, ".json");
                overall.set_message(format!("{} {}", curve.name, point.join(" ")));
                let run = match Run::read(&report) {
                    Ok(kept) => kept,
                    Err(_) => {
                        let bar = bars.add(ProgressBar::new(0));
                        bar.set_style(style("  {bar:30} {pos}/{len} iterations [{elapsed_precise}<{eta_precise}]"));
                        let outcome = self.run_point(pwenc, point, &stem, &bar);
                        bar.finish_and_clear();
                        outcome.with_context(|| format!("the point {i} of `{}` ({})", curve.name, point.join(" ")))?;
                        Run::read(&report)?
                    }
                };
                done.push(run);
                overall.inc(1);
            }
            curves.push(Curve::new(curve.name.clone(), done));
        }
        overall.finish_and_clear();
        Ok(curves)
    }

    /// One run of `pwenc` with its outputs at `stem.*`, its output lines in `stem.log`, and its
    /// progress lines (`iteration I/N ...`) on `bar`.
    fn run_point(&self, pwenc: &Path, point: &[String], stem: &Path, bar: &ProgressBar) -> Result<()> {
        let log_path = with_suffix(stem, ".log");
        let mut log =
            std::fs::File::create(&log_path).with_context(|| format!("cannot write {}", log_path.display()))?;
        let eval = with_suffix(stem, "_eval");
        let mut child = Command::new(pwenc)
            .arg(&self.scene)
            .args(&self.common)
            .args(point)
            .arg("-o")
            .arg(with_suffix(stem, ".pwb"))
            .arg("--eval")
            .arg(&eval)
            .arg("--report")
            .arg(with_suffix(stem, ".json"))
            .stdout(log.try_clone()?)
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| format!("cannot run {}", pwenc.display()))?;
        let stderr = child.stderr.take().expect("stderr is piped");
        for line in BufReader::new(stderr).lines() {
            let line = line.context("cannot read pwenc's output")?;
            writeln!(log, "{line}").with_context(|| format!("cannot write {}", log_path.display()))?;
            if let Some((done, of)) = progress(&line) {
                bar.set_length(of);
                bar.set_position(done);
            }
        }
        let status = child.wait().context("pwenc did not finish")?;
        if !status.success() {
            bail!("pwenc failed ({status}); its output is in {}", log_path.display());
        }
        Ok(())
    }
}

/// `stem` with `suffix` appended (a curve's name may hold dots, which are no extension).
fn with_suffix(stem: &Path, suffix: &str) -> PathBuf {
    let mut path = stem.as_os_str().to_owned();
    path.push(suffix);
    PathBuf::from(path)
}

/// The progress bars' look.
fn style(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template).expect("the templates are valid")
}

/// `iteration I/N` at the start of one of pwenc's progress lines.
fn progress(line: &str) -> Option<(u64, u64)> {
    let (done, of) = line.strip_prefix("iteration ")?.split_whitespace().next()?.split_once('/')?;
    Some((done.parse().ok()?, of.parse().ok()?))
}

/// A curve's name as a file name: letters, digits, `-` and `.`; anything else becomes `_`.
fn file_stem(name: &str) -> String {
    let stem: String =
        name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '.' { c } else { '_' }).collect();
    match stem.chars().any(|c| c.is_ascii_alphanumeric()) {
        true => stem,
        false => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_lines_and_file_stems() {
        assert_eq!(progress("iteration 300/2000  loss 0.0608  PSNR 25.72"), Some((300, 2000)));
        assert_eq!(progress("trained 2000 iterations in 12 s"), None);
        assert_eq!(progress("iteration x/2000"), None);
        assert_eq!(file_stem("anchor+wrapper λ"), "anchor_wrapper__");
        assert_eq!(file_stem("../.."), "");
    }

    #[test]
    fn the_committed_plans_read() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("plans");
        let mut plans = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let plan = Plan::read(&entry.unwrap().path()).unwrap();
            assert!(plan.curves.iter().all(|c| !c.points.is_empty()));
            plans += 1;
        }
        assert!(plans > 0, "no plan in {}", dir.display());
    }
}

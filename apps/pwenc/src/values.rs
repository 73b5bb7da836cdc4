//! Parsers of pwenc's option values, each refusing what the option cannot mean.

use clap::ValueEnum;
use pwgs_cli::values::three_numbers;
use pwgs_core::splat_file::SpzAxes;
use pwgs_encoder::anchor::train::StageTwoLambda;
use pwgs_encoder::metrics::suite::Metric;

pub(crate) fn parse_rate_pair(s: &str) -> Result<[f32; 2], String> {
    let parts: Option<Vec<f32>> = s.split(',').map(|p| p.trim().parse::<f32>().ok()).collect();
    match parts.as_deref() {
        Some(&[a, b]) if a > 0.0 && b > 0.0 && a.is_finite() && b.is_finite() => Ok([a, b]),
        _ => Err(format!("`{s}` is not two positive rates start,end")),
    }
}

pub(crate) fn parse_positive(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a finite number > 0")),
    }
}

/// A time in seconds: finite and not negative.
pub(crate) fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a finite number of seconds >= 0")),
    }
}

/// An angle in degrees from `low` to `high`.
pub(crate) fn parse_degrees_within(s: &str, low: f32, high: f32) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (low..=high).contains(&v) => Ok(v),
        _ => Err(format!("`{s}` is not an angle from {low} to {high} degrees")),
    }
}

pub(crate) fn parse_weight(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a finite weight >= 0")),
    }
}

pub(crate) fn parse_color(s: &str) -> Result<[f32; 3], String> {
    match s {
        "white" => return Ok([1.0; 3]),
        "black" => return Ok([0.0; 3]),
        _ => {}
    }
    match three_numbers(s) {
        Some(rgb) if rgb.iter().all(|v| (0.0..=1.0).contains(v)) => Ok(rgb),
        _ => Err(format!("`{s}` is not `white`, `black` or three values in [0, 1] like 0.5,0.5,0.5")),
    }
}

pub(crate) fn parse_stage_two_lambda(s: &str) -> Result<StageTwoLambda, String> {
    match s {
        "auto" => Ok(StageTwoLambda::Scaled),
        _ => parse_weight(s).map(StageTwoLambda::Times).map_err(|e| format!("{e}, nor `auto`")),
    }
}

/// Refuses PSNR and SSIM in a list of extra metrics (`flag` names the option): every
/// evaluation reports them already.
pub(crate) fn check_extra_metrics(flag: &str, metrics: &[Metric]) -> anyhow::Result<()> {
    match metrics.iter().find(|m| matches!(m, Metric::Psnr | Metric::Ssim | Metric::Ssim3dgs)) {
        Some(m) => {
            anyhow::bail!(
                "{flag} {}: PSNR and SSIM (3DGS convention) are always reported; it takes lpips, dists and wd",
                m.name()
            )
        }
        None => Ok(()),
    }
}

/// `--spz-axes`: the axes an `.spz` stores when it names none (the format says RUB;
/// splat-transform 3.7.0 writes a PLY's own axes, RDF, unmarked).
#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum SpzAxesArg {
    Rub,
    Rdf,
}

impl From<SpzAxesArg> for SpzAxes {
    fn from(axes: SpzAxesArg) -> Self {
        match axes {
            SpzAxesArg::Rub => SpzAxes::Rub,
            SpzAxesArg::Rdf => SpzAxes::Rdf,
        }
    }
}

//! Parsers of pwenc's option values, each refusing what the option cannot mean.

use pwgs_encoder::anchor::train::StageTwoLambda;

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

pub(crate) fn parse_weight(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a finite weight >= 0")),
    }
}

/// Three comma-separated numbers, or `None`.
pub(crate) fn three_numbers(s: &str) -> Option<[f32; 3]> {
    let parts: Vec<f32> = s.split(',').map(|p| p.trim().parse::<f32>()).collect::<Result<_, _>>().ok()?;
    parts.try_into().ok()
}

pub(crate) fn parse_vector(s: &str) -> Result<[f32; 3], String> {
    match three_numbers(s) {
        Some(v) if v.iter().all(|c| c.is_finite()) && v.iter().any(|c| *c != 0.0) => Ok(v),
        _ => Err(format!("`{s}` is not a nonzero vector x,y,z")),
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

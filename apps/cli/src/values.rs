//! Parsers of command-line values that several of the programs take (pwenc, pwplay),
//! each refusing what the option cannot mean.

/// Three comma-separated numbers, or `None`.
pub fn three_numbers(s: &str) -> Option<[f32; 3]> {
    let parts: Vec<f32> = s.split(',').map(|p| p.trim().parse::<f32>()).collect::<Result<_, _>>().ok()?;
    parts.try_into().ok()
}

/// A finite, nonzero direction `x,y,z` (an up vector).
pub fn parse_vector(s: &str) -> Result<[f32; 3], String> {
    match three_numbers(s) {
        Some(v) if v.iter().all(|c| c.is_finite()) && v.iter().any(|c| *c != 0.0) => Ok(v),
        _ => Err(format!("`{s}` is not a nonzero vector x,y,z")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_are_three_finite_numbers_not_all_zero() {
        assert_eq!(parse_vector("0, -1,0"), Ok([0.0, -1.0, 0.0]));
        for bad in ["0,0,0", "1,2", "1,2,3,4", "nan,1,0", "inf,0,0", "x,y,z", ""] {
            assert!(parse_vector(bad).is_err(), "{bad}");
        }
    }
}

//! Cutting a stream to a byte budget (`--target-bytes`): keep the first k items of a ranking,
//! most important first, with k as large as fits. Both bases use it (plain Gaussians ranked by
//! opacity times area, anchors by what their neural Gaussians show over the training views).

/// The outcome of [`largest_fitting`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Fit {
    /// The stream of the first `kept` items, the largest that fits.
    Fits { kept: usize, bytes: Vec<u8> },
    /// Even the stream of no item exceeds the target; it takes `minimum` bytes.
    TooSmall { minimum: usize },
}

/// The largest `k <= n` whose stream `write(k)` fits in `target` bytes. Streams grow with `k`
/// by about an item's bytes at a time (entropy coding makes this nearly, not strictly,
/// monotone), so bisection lands within a few items' bytes of the target; `write(n)` is tried
/// first, so a stream that fits as it is costs one write.
pub fn largest_fitting<E>(
    n: usize,
    target: usize,
    mut write: impl FnMut(usize) -> Result<Vec<u8>, E>,
) -> Result<Fit, E> {
    let all = write(n)?;
    if all.len() <= target {
        return Ok(Fit::Fits { kept: n, bytes: all });
    }
    let mut bytes = write(0)?;
    if bytes.len() > target {
        return Ok(Fit::TooSmall { minimum: bytes.len() });
    }
    // Invariant: `lo` items fit (their stream is `bytes`), `hi` do not.
    let (mut lo, mut hi) = (0, n);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        let candidate = write(mid)?;
        if candidate.len() <= target {
            (lo, bytes) = (mid, candidate);
        } else {
            hi = mid;
        }
    }
    Ok(Fit::Fits { kept: lo, bytes })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stream of a 10-byte header and 7 bytes an item.
    fn stream(k: usize) -> Result<Vec<u8>, ()> {
        Ok(vec![0; 10 + 7 * k])
    }

    #[test]
    fn keeps_as_many_items_as_fit() {
        assert_eq!(largest_fitting(100, 10 + 7 * 40 + 6, stream), Ok(Fit::Fits { kept: 40, bytes: vec![0; 290] }));
        assert_eq!(largest_fitting(100, 10 + 7 * 41, stream), Ok(Fit::Fits { kept: 41, bytes: vec![0; 297] }));
        assert_eq!(largest_fitting(100, 10_000, stream), Ok(Fit::Fits { kept: 100, bytes: vec![0; 710] }));
        assert_eq!(largest_fitting(100, 10, stream), Ok(Fit::Fits { kept: 0, bytes: vec![0; 10] }));
    }

    #[test]
    fn a_target_below_the_empty_stream_is_refused() {
        assert_eq!(largest_fitting(100, 9, stream), Ok(Fit::TooSmall { minimum: 10 }));
    }

    #[test]
    fn a_stream_that_fits_costs_one_write() {
        let mut writes = 0;
        let fit = largest_fitting(100, 10_000, |k| {
            writes += 1;
            stream(k)
        });
        assert!(matches!(fit, Ok(Fit::Fits { kept: 100, .. })));
        assert_eq!(writes, 1);
    }

    #[test]
    fn write_errors_pass_through() {
        assert_eq!(largest_fitting(100, 50, |k| if k == 50 { Err("boom") } else { Ok(vec![0; 10 + k]) }), Err("boom"));
    }
}

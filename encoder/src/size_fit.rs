//! Cutting a stream to a byte budget (`--target-bytes`): keep the first k items of a ranking,
//! most important first, with k as large as fits. Both bases use it (plain Gaussians ranked by
//! opacity times area, anchors by what their neural Gaussians show over the training views).

/// The outcome of [`largest_fitting`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Fit<K> {
    /// The stream of what `kept` says, the largest that fits.
    Fits { kept: K, bytes: Vec<u8> },
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
) -> Result<Fit<usize>, E> {
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

/// [`largest_fitting`] over `n` items ranked by `rank` (item numbers, most important first; it
/// runs only when the stream of every item does not fit): `write(None)` writes every item,
/// `write(Some(keep))` the items `keep`, in increasing order. `kept` in the result is `None`
/// when every item fits, else the items kept, in increasing order.
pub fn most_important_fitting<E>(
    n: usize,
    target: usize,
    rank: impl FnOnce() -> Vec<usize>,
    mut write: impl FnMut(Option<&[usize]>) -> Result<Vec<u8>, E>,
) -> Result<Fit<Option<Vec<usize>>>, E> {
    let mut rank = Some(rank);
    let mut ranked = Vec::new();
    let mut first = |k: usize| {
        if let Some(rank) = rank.take() {
            ranked = rank();
        }
        let mut keep = ranked[..k].to_vec();
        keep.sort_unstable();
        keep
    };
    let fit = largest_fitting(n, target, |k| if k == n { write(None) } else { write(Some(&first(k))) })?;
    Ok(match fit {
        Fit::Fits { kept, bytes } => Fit::Fits { kept: (kept < n).then(|| first(kept)), bytes },
        Fit::TooSmall { minimum } => Fit::TooSmall { minimum },
    })
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

    /// Ten items ranked 9, 8, ..., 0, each worth its number plus one in bytes.
    fn ranked_stream(keep: Option<&[usize]>) -> Result<Vec<u8>, ()> {
        let all: Vec<usize> = (0..10).collect();
        Ok(vec![0; keep.unwrap_or(&all).iter().map(|i| i + 1).sum()])
    }

    #[test]
    fn the_most_important_items_are_kept_in_order() {
        let rank = || (0..10).rev().collect();
        // 10 + 9 + 8 = 27 bytes fit in 30; adding 7 would not.
        let fit = most_important_fitting(10, 30, rank, ranked_stream);
        assert_eq!(fit, Ok(Fit::Fits { kept: Some(vec![7, 8, 9]), bytes: vec![0; 27] }));
        // Not even the most important item fits: the empty stream does.
        assert_eq!(
            most_important_fitting(10, 9, rank, ranked_stream),
            Ok(Fit::Fits { kept: Some(vec![]), bytes: vec![] })
        );
    }

    #[test]
    fn nothing_is_ranked_when_every_item_fits() {
        let fit = most_important_fitting(10, 55, || panic!("ranked though every item fits"), ranked_stream);
        assert_eq!(fit, Ok(Fit::Fits { kept: None, bytes: vec![0; 55] }));
    }
}

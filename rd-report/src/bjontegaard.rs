//! Bjøntegaard deltas between two rate-distortion curves (VCEG-M33, with the piecewise cubic
//! interpolation common codec practice has used since): the average difference in rate at
//! equal quality (BD-rate, in percent) and in quality at equal rate (BD-quality), each over the
//! range where both curves have data, which the result states.
//!
//! Rates are compared in log10; each curve is interpolated by a monotone piecewise cubic
//! Hermite (PCHIP, Fritsch-Carlson) through its points sorted by the abscissa, and the
//! integral is taken numerically on a fine grid.

/// A point of a curve: rate (bytes) and quality (any metric).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RdPoint {
    pub bytes: f64,
    pub quality: f64,
}

/// A Bjøntegaard delta and the range it was averaged over.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Delta {
    /// BD-rate: percent change in rate of the test curve at equal quality (negative: smaller);
    /// BD-quality: change in quality at equal rate.
    pub value: f64,
    /// The overlap of the two curves on the integration axis (quality for BD-rate, log10
    /// bytes for BD-quality).
    pub over: (f64, f64),
}

/// Samples per integral.
const SAMPLES: usize = 2000;

/// A monotone cubic interpolant through points with increasing x.
struct Pchip {
    x: Vec<f64>,
    y: Vec<f64>,
    slope: Vec<f64>,
}

impl Pchip {
    /// Through `points` (x, y), sorted by x here; `None` with fewer than 2 distinct x.
    fn new(mut points: Vec<(f64, f64)>) -> Option<Self> {
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        points.dedup_by(|a, b| a.0 == b.0);
        if points.len() < 2 {
            return None;
        }
        let (x, y): (Vec<f64>, Vec<f64>) = points.into_iter().unzip();
        let n = x.len();
        let secant: Vec<f64> = (0..n - 1).map(|i| (y[i + 1] - y[i]) / (x[i + 1] - x[i])).collect();
        let mut slope = vec![0.0; n];
        slope[0] = secant[0];
        slope[n - 1] = secant[n - 2];
        for i in 1..n - 1 {
            let (a, b) = (secant[i - 1], secant[i]);
            // Fritsch-Carlson: zero at a local extremum, else a weighted harmonic mean.
            slope[i] = if a * b <= 0.0 {
                0.0
            } else {
                let (h0, h1) = (x[i] - x[i - 1], x[i + 1] - x[i]);
                let (w0, w1) = (2.0 * h1 + h0, h1 + 2.0 * h0);
                (w0 + w1) / (w0 / a + w1 / b)
            };
        }
        Some(Self { x, y, slope })
    }

    fn range(&self) -> (f64, f64) {
        (self.x[0], self.x[self.x.len() - 1])
    }

    fn at(&self, t: f64) -> f64 {
        let i = self.x.partition_point(|&x| x <= t).clamp(1, self.x.len() - 1) - 1;
        let h = self.x[i + 1] - self.x[i];
        let s = (t - self.x[i]) / h;
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        h00 * self.y[i] + h10 * h * self.slope[i] + h01 * self.y[i + 1] + h11 * h * self.slope[i + 1]
    }
}

/// Mean of `f - g` over the overlap of their ranges, or `None` when they do not overlap.
fn mean_difference(f: &Pchip, g: &Pchip) -> Option<(f64, (f64, f64))> {
    let (lo, hi) = (f.range().0.max(g.range().0), f.range().1.min(g.range().1));
    if !(hi > lo) {
        return None;
    }
    // Trapezoid rule on a fine grid.
    let step = (hi - lo) / SAMPLES as f64;
    let d = |k: usize| {
        let t = lo + step * k as f64;
        f.at(t) - g.at(t)
    };
    let sum: f64 = (1..SAMPLES).map(d).sum::<f64>() + 0.5 * (d(0) + d(SAMPLES));
    Some((sum / SAMPLES as f64, (lo, hi)))
}

/// BD-rate of `test` against `reference`: how many percent more (positive) or fewer (negative)
/// bytes `test` needs for the same quality, averaged over their common quality range.
pub fn bd_rate(reference: &[RdPoint], test: &[RdPoint]) -> Option<Delta> {
    let curve = |c: &[RdPoint]| Pchip::new(c.iter().map(|p| (p.quality, p.bytes.log10())).collect());
    let (mean, over) = mean_difference(&curve(test)?, &curve(reference)?)?;
    Some(Delta { value: (10f64.powf(mean) - 1.0) * 100.0, over })
}

/// BD-quality of `test` against `reference`: the average change in quality at equal rate, over
/// their common range of log10 bytes.
pub fn bd_quality(reference: &[RdPoint], test: &[RdPoint]) -> Option<Delta> {
    let curve = |c: &[RdPoint]| Pchip::new(c.iter().map(|p| (p.bytes.log10(), p.quality)).collect());
    let (mean, over) = mean_difference(&curve(test)?, &curve(reference)?)?;
    Some(Delta { value: mean, over })
}

/// The bytes `curve` needs for `quality`, interpolated as BD-rate interpolates (log rate
/// against quality); `None` outside the qualities the curve spans, or with fewer than 2 points.
/// This places a single run of another codec (one file per format) against a curve.
pub fn bytes_at(curve: &[RdPoint], quality: f64) -> Option<f64> {
    let interpolant = Pchip::new(curve.iter().map(|p| (p.quality, p.bytes.log10())).collect())?;
    let (lo, hi) = interpolant.range();
    (lo..=hi).contains(&quality).then(|| 10f64.powf(interpolant.at(quality)))
}

/// The quality `curve` has at `bytes`, interpolated as BD-quality interpolates (quality against
/// log rate); `None` outside the sizes the curve spans, or with fewer than 2 points. This is the
/// equal-size comparison of a single run against a curve: what the curve's codec would score
/// with a stream exactly as large.
pub fn quality_at(curve: &[RdPoint], bytes: f64) -> Option<f64> {
    let interpolant = Pchip::new(curve.iter().map(|p| (p.bytes.log10(), p.quality)).collect())?;
    let (lo, hi) = interpolant.range();
    let x = bytes.log10();
    (lo..=hi).contains(&x).then(|| interpolant.at(x))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(points: &[(f64, f64)]) -> Vec<RdPoint> {
        points.iter().map(|&(bytes, quality)| RdPoint { bytes, quality }).collect()
    }

    #[test]
    fn half_the_bytes_at_every_quality_is_minus_fifty_percent() {
        let reference = curve(&[(100_000.0, 25.0), (200_000.0, 27.0), (400_000.0, 28.5), (800_000.0, 29.2)]);
        let half: Vec<RdPoint> = reference.iter().map(|p| RdPoint { bytes: p.bytes / 2.0, ..*p }).collect();
        let d = bd_rate(&reference, &half).unwrap();
        assert!((d.value + 50.0).abs() < 1e-9, "{d:?}");
        assert_eq!(d.over, (25.0, 29.2));
        // The other way round: twice the bytes.
        assert!((bd_rate(&half, &reference).unwrap().value - 100.0).abs() < 1e-9);
    }

    #[test]
    fn one_db_better_everywhere_is_plus_one_db() {
        let reference = curve(&[(100_000.0, 25.0), (200_000.0, 27.0), (400_000.0, 28.5)]);
        let better: Vec<RdPoint> = reference.iter().map(|p| RdPoint { quality: p.quality + 1.0, ..*p }).collect();
        let d = bd_quality(&reference, &better).unwrap();
        assert!((d.value - 1.0).abs() < 1e-9, "{d:?}");
        assert!((d.over.0 - 5.0).abs() < 1e-12 && (d.over.1 - 400_000f64.log10()).abs() < 1e-12);
    }

    #[test]
    fn the_average_is_over_the_overlap_only() {
        // Quality linear in log rate: q = 10 log10(bytes) - 25 for the reference; the test curve
        // is the same line shifted by +0.3 in log10 rate, over a quality range half inside.
        let line = |lo: f64, shift: f64| -> Vec<RdPoint> {
            (0..5)
                .map(|i| {
                    let l = lo + 0.25 * i as f64;
                    RdPoint { bytes: 10f64.powf(l + shift), quality: 10.0 * l - 25.0 }
                })
                .collect()
        };
        let (reference, test) = (line(5.0, 0.0), line(5.5, 0.3));
        let d = bd_rate(&reference, &test).unwrap();
        assert!((d.value - (10f64.powf(0.3) - 1.0) * 100.0).abs() < 1e-6, "{d:?}");
        assert!((d.over.0 - 30.0).abs() < 1e-9 && (d.over.1 - 35.0).abs() < 1e-9, "{:?}", d.over);
        // Disjoint curves, or a single point, have no delta.
        assert!(bd_rate(&line(5.0, 0.0), &line(7.0, 0.0)).is_none());
        assert!(bd_rate(&reference, &reference[..1]).is_none());
    }

    #[test]
    fn the_interpolant_is_monotone_between_monotone_points() {
        let p = Pchip::new(vec![(0.0, 0.0), (1.0, 0.1), (2.0, 5.0), (3.0, 5.1)]).unwrap();
        let mut last = f64::NEG_INFINITY;
        for k in 0..=300 {
            let v = p.at(k as f64 / 100.0);
            assert!(v >= last - 1e-12, "not monotone at {k}: {v} < {last}");
            last = v;
        }
        assert!((p.at(2.0) - 5.0).abs() < 1e-12);
    }

    #[test]
    fn bytes_at_a_quality_follow_the_curve_and_stop_at_its_ends() {
        // Ten times the bytes for every 10 units of quality: log-linear, so exact between points.
        let c = curve(&[(1e3, 20.0), (1e4, 30.0), (1e5, 40.0)]);
        let at = |q| bytes_at(&c, q);
        assert!((at(25.0).unwrap() / 10f64.powf(3.5) - 1.0).abs() < 1e-9);
        assert!((at(40.0).unwrap() / 1e5 - 1.0).abs() < 1e-9);
        assert_eq!(at(19.9), None);
        assert_eq!(at(40.1), None);
        assert_eq!(bytes_at(&c[..1], 20.0), None);
    }

    #[test]
    fn quality_at_a_size_follows_the_curve_and_stops_at_its_ends() {
        // 10 units of quality per decade of bytes: linear in log rate, so exact between points.
        let c = curve(&[(1e3, 20.0), (1e4, 30.0), (1e5, 40.0)]);
        let at = |b| quality_at(&c, b);
        assert!((at(10f64.powf(3.5)).unwrap() - 25.0).abs() < 1e-9);
        assert!((at(1e5).unwrap() - 40.0).abs() < 1e-9);
        assert_eq!(at(999.0), None);
        assert_eq!(at(1.001e5), None);
        assert_eq!(quality_at(&c[..1], 1e3), None);
        // A curve whose quality falls with size (a distance, lower is better) works the same way.
        let falling = curve(&[(1e3, 0.2), (1e4, 0.1)]);
        assert!((quality_at(&falling, 10f64.powf(3.5)).unwrap() - 0.15).abs() < 1e-9);
    }
}

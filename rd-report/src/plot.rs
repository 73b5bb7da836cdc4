//! Charts (SVG), one line per curve: rate-distortion (stream size against a metric) and
//! speed-versus-error (render or training time against a metric).

use std::path::Path;

use anyhow::{Result, anyhow};
use plotters::prelude::*;

use crate::runs::{Axis, Curve, Metric};

/// Distinct line colors, cycled.
const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
];

/// Draws `metric` against `axis` for every curve into the SVG `path`; `false` (and nothing
/// written) when no run has both.
pub fn chart(curves: &[Curve], axis: Axis, metric: Metric, title: &str, path: &Path) -> Result<bool> {
    let series: Vec<(&str, Vec<(f64, f64)>)> =
        curves.iter().map(|c| (c.name.as_str(), c.points_on(axis, metric))).filter(|(_, p)| !p.is_empty()).collect();
    let all: Vec<(f64, f64)> = series.iter().flat_map(|(_, p)| p.iter().copied()).collect();
    if all.is_empty() {
        return Ok(false);
    }
    let range = |values: Vec<f64>| {
        let (lo, hi) = values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        let pad = ((hi - lo) * 0.08).max(hi.abs() * 0.01).max(1e-6);
        (lo - pad)..(hi + pad)
    };
    let x = range(all.iter().map(|p| p.0).collect());
    let y = range(all.iter().map(|p| p.1).collect());
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::new(path, (720, 460)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(64)
            .build_cartesian_2d(x, y)?;
        chart.configure_mesh().x_desc(axis.label()).y_desc(metric.label()).draw()?;
        for (i, (name, points)) in series.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            chart
                .draw_series(LineSeries::new(points.iter().copied(), color.stroke_width(2)))?
                .label(*name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
        }
        let corner =
            if metric.higher_is_better() { SeriesLabelPosition::LowerRight } else { SeriesLabelPosition::UpperRight };
        chart
            .configure_series_labels()
            .position(corner)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| anyhow!("cannot draw {}: {e}", path.display()))?;
    Ok(true)
}

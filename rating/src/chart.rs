//! The fit as a chart (SVG): each method's Elo with its 95% credible interval.

use std::path::Path;

use anyhow::{Result, anyhow};
use plotters::prelude::*;

use crate::elo::Fit;

/// Half-width of a 95% interval in standard deviations.
pub const Z95: f64 = 1.959_963_984_540_054;

/// Draws the fit's methods (one row each, strongest on top) into the SVG `path`.
pub fn elo_chart(fit: &Fit, title: &str, path: &Path) -> Result<()> {
    let mut order: Vec<usize> = (0..fit.methods.len()).collect();
    order.sort_by(|&a, &b| fit.elo[a].total_cmp(&fit.elo[b]));
    let lo = order.iter().map(|&i| fit.elo[i] - Z95 * fit.sd(i)).fold(f64::INFINITY, f64::min);
    let hi = order.iter().map(|&i| fit.elo[i] + Z95 * fit.sd(i)).fold(f64::NEG_INFINITY, f64::max);
    let pad = ((hi - lo) * 0.1).max(10.0);
    let rows = order.len() as f64;
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::new(path, (720, 120 + 40 * order.len() as u32)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(160)
            .build_cartesian_2d((lo - pad)..(hi + pad), -0.5..(rows - 0.5))?;
        let label = |y: &f64| {
            let row = y.round();
            if (y - row).abs() < 1e-9 && row >= 0.0 && row < rows {
                fit.methods[order[row as usize]].clone()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .x_desc("Elo (95% credible interval)")
            .y_labels(order.len())
            .y_label_formatter(&label)
            .disable_y_mesh()
            .draw()?;
        for (row, &i) in order.iter().enumerate() {
            let (y, e, half) = (row as f64, fit.elo[i], Z95 * fit.sd(i));
            chart.draw_series(std::iter::once(PathElement::new(
                vec![(e - half, y), (e + half, y)],
                BLACK.stroke_width(2),
            )))?;
            chart.draw_series(std::iter::once(Circle::new((e, y), 5, BLUE.filled())))?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| anyhow!("cannot draw {}: {e}", path.display()))
}

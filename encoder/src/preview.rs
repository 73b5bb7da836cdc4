//! The point-cloud preview: initialize Gaussians from a scene's SfM points and render its test
//! views. It is the starting point training improves on, and exercises loading, initialization
//! and rendering end to end.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use pwgs_dataset::Dataset;
use pwgs_decoder::gaussians::Gaussians;
use pwgs_decoder::raster::{RenderOptions, render};
use serde::Serialize;

use crate::init::gaussians_from_points;
use crate::metrics::psnr::psnr;

/// Quality of one rendered test view.
#[derive(Debug, Clone, Serialize)]
pub struct ViewScore {
    pub name: String,
    pub psnr: f64,
    pub render_seconds: f64,
}

/// Initial Gaussians of a dataset, from its point cloud.
pub fn initial_gaussians(data: &Dataset) -> Result<Gaussians> {
    let points = data.points.as_ref().context("the scene has no point cloud to initialize from")?;
    anyhow::ensure!(!points.positions.is_empty(), "the scene's point cloud is empty");
    gaussians_from_points(points, 0)
}

/// Renders every test view, optionally saving `<out>/<name>.png`, and scores it with PSNR.
pub fn evaluate(g: &Gaussians, data: &Dataset, options: &RenderOptions, out: Option<&Path>) -> Result<Vec<ViewScore>> {
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    data.test
        .iter()
        .map(|view| {
            let start = Instant::now();
            let image = render(g, &view.camera, options);
            let render_seconds = start.elapsed().as_secs_f64();
            if let Some(dir) = out {
                let stem =
                    Path::new(&view.name).file_stem().map_or_else(|| view.name.clone(), |s| s.to_string_lossy().into());
                image.save_png(&dir.join(format!("{stem}.png")))?;
            }
            Ok(ViewScore { name: view.name.clone(), psnr: psnr(&image, &view.image), render_seconds })
        })
        .collect()
}

//! `--target-bytes` on the anchor base: a trained anchor stream cut to a byte budget by
//! dropping the anchors that show least, so that a run with the wrapper and one without it can
//! be compared at equal size. The rate term sets the size only roughly (λ); the cut
//! is meant for the last few percent, after a λ that lands a little above the target.
//!
//! An anchor's importance is what its neural Gaussians show over the training views: the sum,
//! over views and over its Gaussians that survive projection, of opacity times the splat's
//! area in pixels (capped at the image). This is an encoder choice: decoders read whatever
//! anchors the stream holds.

use anyhow::{Context, Result, bail};
use pwgs_codec::anchor::AnchorModel;
use pwgs_codec::stream::{self, anchor::QuantizedAnchors, header::Header, wrap::QuantizedSynthesis};
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_render::raster::project::ProjectionSettings;
use pwgs_render::raster::project_visible;

use crate::size_fit::{Fit, most_important_fitting};

/// `content`'s stream (with `wrapper`) in at most `target` bytes: every anchor if it fits, else
/// the most important ones over `cameras` (see the module's doc), as many as fit. Returns the
/// anchors kept, their stream and how many were dropped.
pub fn fit_anchors(
    content: QuantizedAnchors,
    header: &Header,
    wrapper: Option<&QuantizedSynthesis>,
    target: usize,
    cameras: &[Camera],
) -> Result<(QuantizedAnchors, Vec<u8>, usize)> {
    let n = content.len();
    let rank = || {
        let importance = anchor_importance(&content.dequantize(), cameras);
        let mut ranked: Vec<usize> = (0..n).collect();
        ranked.sort_by(|&a, &b| importance[b].total_cmp(&importance[a]).then(a.cmp(&b)));
        ranked
    };
    let write = |keep: Option<&[usize]>| {
        let subset = keep.map(|keep| keep_anchors(&content, keep));
        let kept = subset.as_ref().unwrap_or(&content);
        let count = u32::try_from(kept.len()).context("too many anchors for a stream")?;
        let header = Header { gaussian_count: count, ..header.clone() };
        stream::encode(&header, kept, wrapper).context("cannot write the anchor stream")
    };
    match most_important_fitting(n, target, rank, write)? {
        Fit::Fits { kept: None, bytes } => Ok((content, bytes, 0)),
        Fit::Fits { kept: Some(keep), bytes } => Ok((keep_anchors(&content, &keep), bytes, n - keep.len())),
        Fit::TooSmall { minimum } => {
            bail!("a stream of at most {target} bytes is impossible: without any anchor it takes {minimum}")
        }
    }
}

/// How much each anchor of `model` shows over `cameras` (see the module's doc).
pub fn anchor_importance(model: &AnchorModel, cameras: &[Camera]) -> Vec<f64> {
    let k = model.offsets_per_anchor;
    let settings = ProjectionSettings::default();
    let mut importance = vec![0.0f64; model.len()];
    for camera in cameras {
        let mut gaussians = Gaussians::with_degree(0);
        let mut anchor_of = Vec::new();
        model.visit_neural_gaussians(camera, |id, g| {
            // Colors do not count: a black Gaussian hides what lies behind it all the same.
            gaussians.push(g.mean, g.log_scale, g.rotation, g.opacity_logit, &[0.0; 3]);
            anchor_of.push(id / k);
        });
        let image = f64::from(camera.width) * f64::from(camera.height);
        for s in project_visible(&gaussians, camera, &settings) {
            let [a, b, c] = s.conic.map(f64::from);
            let det = a * c - b * b;
            // The ellipse's area is pi / sqrt(det) at one standard deviation; pi is common to all.
            let area = if det > 0.0 { (1.0 / det.sqrt()).min(image) } else { image };
            importance[anchor_of[s.index as usize]] += f64::from(s.opacity) * area;
        }
    }
    importance
}

/// `content` with only the anchors `keep` (increasing indices, so the octree's order holds);
/// networks, steps and the context model as they were.
pub fn keep_anchors(content: &QuantizedAnchors, keep: &[usize]) -> QuantizedAnchors {
    let (f, k) = (content.feature_dim, content.offsets_per_anchor);
    fn rows<T: Copy>(values: &[T], width: usize, keep: &[usize]) -> Vec<T> {
        keep.iter().flat_map(|&i| values[i * width..(i + 1) * width].iter().copied()).collect()
    }
    QuantizedAnchors {
        grid: content.grid,
        positions: rows(&content.positions, 1, keep),
        feature_dim: f,
        offsets_per_anchor: k,
        feature_step: content.feature_step,
        features: rows(&content.features, f, keep),
        scaling_step: content.scaling_step,
        scaling: rows(&content.scaling, 1, keep),
        offset_step: content.offset_step,
        offsets: rows(&content.offsets, 3 * k, keep),
        masks: rows(&content.masks, k, keep),
        mlps: content.mlps.clone(),
        context: content.context.clone(),
    }
}

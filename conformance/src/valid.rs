//! Checking the decoder library against the valid vectors: a decoder conforms when, for every
//! vector in `vectors/`, it decodes the stream to attributes with the expected SHA-256
//! (bit-exact: SPEC.md section 7), decodes the wrapper's parameters and noise pyramids to their
//! pinned hashes (bit-exact: SPEC.md section 11), and renders each listed camera within the
//! render tolerance (rendering is not bit-normative: docs/architecture.md section 3).

use pwgs_render::show::SceneRender;
use std::path::Path;

use anyhow::{Context, Result, bail};
use pwgs_codec::hashing::Hasher;
use pwgs_codec::stream;
use pwgs_codec::wrapper::noise::{noise_pyramid, pyramid_sha256};
use pwgs_codec::wrapper::synthesis::SynthesisWeights;
use pwgs_core::camera_json::parse_camera;
use serde::Deserialize;

use crate::expected::ExpectedVector;
use crate::vectors_dir;

/// Largest difference of an 8-bit channel value allowed anywhere (SPEC.md section 8).
pub const MAX_CHANNEL_DIFFERENCE: u8 = 2;
/// Fraction of channel values that must be within 1 of the expected value (SPEC.md section 8).
pub const WITHIN_ONE_FRACTION: f64 = 0.999;

/// What checking one render found.
#[derive(Debug)]
pub struct RenderCheck {
    pub image: String,
    pub max_difference: u8,
    pub within_one: f64,
}

/// SHA-256 (hex) of a wrapper's dequantized parameters in stream order, each as little-endian
/// binary32 (SPEC.md section 11.4).
pub fn wrapper_sha256(weights: &SynthesisWeights) -> String {
    let mut h = Hasher::default();
    h.floats(&weights.values());
    h.hex()
}

/// Compares a render with the reference image under the tolerance of SPEC.md section 8.
pub fn compare_render(name: &str, ours: &image::RgbImage, reference: &image::RgbImage) -> Result<RenderCheck> {
    if ours.dimensions() != reference.dimensions() {
        bail!("{name}: rendered {:?}, expected {:?}", ours.dimensions(), reference.dimensions());
    }
    let diffs: Vec<u8> = ours.as_raw().iter().zip(reference.as_raw()).map(|(a, b)| a.abs_diff(*b)).collect();
    let max_difference = diffs.iter().copied().max().unwrap_or(0);
    let within_one = diffs.iter().filter(|&&d| d <= 1).count() as f64 / diffs.len() as f64;
    if max_difference > MAX_CHANNEL_DIFFERENCE || within_one < WITHIN_ONE_FRACTION {
        bail!("{name}: max difference {max_difference}/255, {:.4}% within 1/255", within_one * 100.0);
    }
    Ok(RenderCheck { image: name.to_string(), max_difference, within_one })
}

/// Checks the decoder library against one vector.
pub fn check_vector(dir: &Path) -> Result<Vec<RenderCheck>> {
    let text = std::fs::read_to_string(dir.join("expected.json"))?;
    let expected: ExpectedVector = serde_json::from_str(&text).context("expected.json")?;
    let stream_path = dir.join(&expected.stream);
    let bytes = std::fs::read(&stream_path).with_context(|| format!("cannot read {}", stream_path.display()))?;
    let (container, _) = stream::parse(&bytes)?;
    if [container.major, container.minor] != expected.version {
        bail!("version {}.{}, expected {:?}", container.major, container.minor, expected.version);
    }
    let decoded = stream::decode(&bytes)?;
    if decoded.header.gaussian_count != expected.gaussians || decoded.header.sh_degree != expected.sh_degree {
        bail!("{} Gaussians of degree {}", decoded.header.gaussian_count, decoded.header.sh_degree);
    }
    let scene = &decoded.scene;
    let hash = scene.attribute_hash();
    if hash != expected.attribute_sha256 {
        bail!("decoded attributes hash to {hash}, expected {}", expected.attribute_sha256);
    }
    if decoded.scene.wrapper.is_some() != expected.wrapper {
        bail!("wrapper present: {}, expected {}", decoded.scene.wrapper.is_some(), expected.wrapper);
    }
    if let Some(weights) = &decoded.scene.wrapper {
        let hash = wrapper_sha256(weights);
        let pinned = expected.wrapper_sha256.as_ref().with_context(|| format!("no wrapper_sha256 pinned ({hash})"))?;
        if &hash != pinned {
            bail!("decoded wrapper parameters hash to {hash}, expected {pinned}");
        }
    }
    let noise_seed = decoded.scene.wrapper.as_ref().filter(|w| w.config.noise).map(|w| w.config.seed);
    let options = scene.render_options();
    let mut checks = Vec::new();
    for r in &expected.renders {
        let camera = parse_camera(&std::fs::read_to_string(dir.join(&r.camera))?)?;
        if let Some(seed) = noise_seed {
            let hash = pyramid_sha256(&noise_pyramid(seed, camera.width as usize, camera.height as usize));
            let pinned =
                r.noise_sha256.as_ref().with_context(|| format!("{}: no noise_sha256 pinned ({hash})", r.camera))?;
            if &hash != pinned {
                bail!("{}: noise pyramid of seed {seed} hashes to {hash}, expected {pinned}", r.camera);
            }
        }
        let ours = scene.render(&camera, &options, true)?.image.to_rgb8();
        let reference = image::open(dir.join(&r.image))?.to_rgb8();
        checks.push(compare_render(&r.image, &ours, &reference)?);
    }
    Ok(checks)
}

#[derive(Deserialize)]
struct PinnedPyramid {
    seed: u64,
    width: usize,
    height: usize,
    sha256: String,
}

/// Checks the decoder's noise pyramids against `noise_pyramids.json` (SPEC.md section 11.1:
/// they are bit-normative). Returns how many were checked.
pub fn check_noise_pyramids() -> Result<usize> {
    let path = vectors_dir().join("noise_pyramids.json");
    let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let pinned: Vec<PinnedPyramid> = serde_json::from_str(&text).context("noise_pyramids.json")?;
    for p in &pinned {
        let hash = pyramid_sha256(&noise_pyramid(p.seed, p.width, p.height));
        if hash != p.sha256 {
            bail!(
                "noise pyramid of seed {} at {}x{} hashes to {hash}, expected {}",
                p.seed,
                p.width,
                p.height,
                p.sha256
            );
        }
    }
    Ok(pinned.len())
}

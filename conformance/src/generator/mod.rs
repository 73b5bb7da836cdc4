//! The generator of the suite's synthetic vectors and invalid files: streams built from
//! integer content with the decoder library's writer (`stream::encode`, or hand-made section
//! lists), camera files, and the expected hashes and renders the reference decoder gives for
//! them. Generating twice gives the same bytes; `tests/regenerate.rs` checks the committed
//! files against a fresh generation, so a change in the writer or the decoder shows up there.
//!
//! `cargo run -p pwgs-conformance --bin regenerate` writes the files (README.md).

mod anchor_vectors;
pub mod content;
pub mod context_tables;
pub mod hostile;
mod invalid_cameras;
mod invalid_streams;
pub mod raw;
mod valid_vectors;

use pwgs_render::show::SceneRender;
use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail, ensure};
use pwgs_codec::stream;
use pwgs_codec::wrapper::noise::{noise_pyramid, pyramid_sha256};
use pwgs_core::camera_json::{camera_to_json, parse_camera};

use crate::expected::{ExpectedRefusal, ExpectedRefusals, ExpectedRender, ExpectedVector};
use crate::invalid::EXPECTED_FILE;
use crate::valid::{compare_render, wrapper_sha256};

/// Generated files by path relative to the conformance folder (`vectors/NAME/...`,
/// `invalid/...`).
pub type Files = BTreeMap<PathBuf, Vec<u8>>;

/// Name of the stream file in a vector folder.
const STREAM_FILE: &str = "stream.pwb";

/// One valid vector before its expectations are computed.
pub struct Vector {
    pub name: &'static str,
    pub description: String,
    /// SPEC.md clause IDs (README.md's table).
    pub clauses: Vec<&'static str>,
    pub stream: Vec<u8>,
    /// Cameras of [`content::camera`] to render; none where the Gaussians are not meant to be
    /// looked at (values at the limits of binary32).
    pub cameras: &'static [&'static str],
}

/// One invalid file and the refusal it must produce.
pub struct Refusal {
    pub file: String,
    pub clause: &'static str,
    pub error: String,
    pub description: String,
    pub bytes: Vec<u8>,
}

/// Every generated file: the synthetic vectors and the invalid folder.
pub fn generate() -> Result<Files> {
    let mut files = Files::new();
    for vector in valid_vectors::vectors()?.into_iter().chain(anchor_vectors::vectors()) {
        let name = vector.name;
        add_vector(&mut files, vector).with_context(|| format!("vector {name}"))?;
    }
    let mut refusals = ExpectedRefusals::new();
    let invalid = invalid_streams::refusals().into_iter().chain(anchor_vectors::refusals());
    for r in invalid.chain(invalid_cameras::refusals()) {
        let entry = ExpectedRefusal { clause: r.clause.to_string(), error: r.error, description: r.description };
        ensure!(refusals.insert(r.file.clone(), entry).is_none(), "invalid file {} made twice", r.file);
        files.insert(PathBuf::from("invalid").join(&r.file), r.bytes);
    }
    files.insert(PathBuf::from("invalid").join(EXPECTED_FILE), json(&refusals)?);
    files.extend(hostile::files()?);
    Ok(files)
}

/// Files on disk under `root` (the conformance folder) in the folders `files` fills that are not
/// among `files`: left over from an earlier generation. Dotfiles (`invalid/.gitignore`) are not
/// part of the suite and never stale.
pub fn stale_files(root: &Path, files: &Files) -> Result<Vec<PathBuf>> {
    let mut folders: Vec<&Path> = files.keys().filter_map(|p| p.parent()).collect();
    folders.dedup();
    let mut stale = Vec::new();
    for folder in folders {
        let Ok(entries) = std::fs::read_dir(root.join(folder)) else { continue };
        for entry in entries {
            let name = entry?.file_name();
            let path = folder.join(&name);
            if !name.to_string_lossy().starts_with('.') && !files.contains_key(&path) {
                stale.push(path);
            }
        }
    }
    Ok(stale)
}

/// Pretty JSON with a final newline.
fn json(value: &impl serde::Serialize) -> Result<Vec<u8>> {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    Ok(text.into_bytes())
}

/// Decodes a vector's stream with the reference decoder and adds its folder: the stream, the
/// cameras and their renders, and `expected.json`.
fn add_vector(files: &mut Files, v: Vector) -> Result<()> {
    let dir = PathBuf::from("vectors").join(v.name);
    let decoded = stream::decode(&v.stream).context("the reference decoder refuses the vector")?;
    let (container, _) = stream::parse(&v.stream)?;
    let scene = &decoded.scene;
    let options = scene.render_options();
    let mut renders = Vec::new();
    for &name in v.cameras {
        let camera_json = camera_to_json(&content::camera(name));
        // Render the camera as a decoder reads it from the file.
        let camera = parse_camera(&camera_json)?;
        let shown = scene.render(&camera, &options, true)?.image;
        if scene.wrapper.is_some() {
            let base = scene.render_base(&camera, &options)?.to_rgb8();
            if compare_render(name, &base, &shown.to_rgb8()).is_ok() {
                bail!("the wrapper moves the {name} view within the tolerance: a decoder ignoring it would pass");
            }
        }
        let mut png = Vec::new();
        image::DynamicImage::ImageRgb8(shown.to_rgb8())
            .write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)?;
        let noise_sha256 = decoded
            .scene
            .wrapper
            .as_ref()
            .filter(|w| w.config.noise)
            .map(|w| pyramid_sha256(&noise_pyramid(w.config.seed, camera.width as usize, camera.height as usize)));
        let (camera_file, image_file) = (format!("view_{name}.json"), format!("view_{name}.png"));
        files.insert(dir.join(&camera_file), format!("{camera_json}\n").into_bytes());
        files.insert(dir.join(&image_file), png);
        renders.push(ExpectedRender { camera: camera_file, image: image_file, noise_sha256 });
    }
    let expected = ExpectedVector {
        description: v.description,
        clauses: v.clauses.iter().map(|c| c.to_string()).collect(),
        stream: STREAM_FILE.to_string(),
        version: [container.major, container.minor],
        gaussians: decoded.header.gaussian_count,
        sh_degree: decoded.header.sh_degree,
        attribute_sha256: scene.attribute_hash(),
        wrapper: decoded.scene.wrapper.is_some(),
        wrapper_sha256: decoded.scene.wrapper.as_ref().map(wrapper_sha256),
        renders,
    };
    files.insert(dir.join("expected.json"), json(&expected)?);
    files.insert(dir.join(STREAM_FILE), v.stream);
    Ok(())
}

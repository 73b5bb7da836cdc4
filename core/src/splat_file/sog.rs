//! PlayCanvas's SOG (version 2): lossless WebP images holding one pixel per Gaussian, and a
//! `meta.json` with what turns the pixels into values, either bundled in a zip archive
//! (`.sog`) or as a folder (`meta.json` beside the images).
//!
//! - `means_l`/`means_u`: low and high bytes of a 16-bit fraction per axis between `mins` and
//!   `maxs` of the positions after `sign(x) * ln(1 + |x|)`, undone here.
//! - `quats`: the three smaller components of the unit quaternion in [-1/sqrt(2), 1/sqrt(2)]
//!   as bytes, and 252 + the index (w, x, y, z) of the largest, recovered from unit length.
//! - `scales`: per axis an index into a 256-entry codebook of log-scales.
//! - `sh0`: per color an index into a codebook of SH DC coefficients, and the opacity as a
//!   byte fraction (its logit clamped to the byte range's ends as PlayCanvas's reader does).
//! - `shN` (optional): a 16-bit label per Gaussian (red and green bytes) into a palette of
//!   `count` entries, each `3, 8 or 15` pixels of a row 64 entries wide, whose bytes index a
//!   codebook of the higher SH coefficients.
//!
//! A codebook entry may be `null` (PlayCanvas writes a non-finite sentinel so); a Gaussian that
//! uses one is dropped, as the PLY reader drops non-finite values. Anything else out of place
//! (a tag, label or index out of range, an image too small) is an error naming the file.
//!
//! Bounds, all checked before the work they bound: `count` at most [`MAX_IMPORTED_POINTS`] and
//! the palette at most 2^16 entries (its labels are 16-bit); `meta.json` at most a megabyte;
//! only the files `meta.json` names are read (an archive's other entries are never opened), each
//! through a cap (see [`images`]); every image's size, from its header, against the Gaussians
//! it holds; and the pixels all images decode to against [`super::decompressed_limit`] of the input.

mod images;
#[cfg(test)]
mod tests;

use std::io::{Read, Seek};
use std::path::Path;

use serde::Deserialize;

use super::{MAX_IMPORTED_POINTS, SplatFileProblem};
use crate::gaussians::Gaussians;
use images::Layout;

/// A SOG's `meta.json` holds a few kilobytes (bounds and three 256-entry codebooks); a megabyte
/// leaves room for indentation and unknown fields while bounding what parsing it allocates.
const MAX_META_BYTES: u64 = 1 << 20;
/// The most palette entries: a Gaussian's label is 16-bit, so more could never be used.
const MAX_PALETTE: usize = 1 << 16;

#[derive(Deserialize)]
struct Meta {
    version: u32,
    count: usize,
    means: Means,
    scales: Codebooked,
    quats: Files,
    sh0: Codebooked,
    #[serde(rename = "shN")]
    sh_n: Option<HigherSh>,
}

#[derive(Deserialize)]
struct Means {
    mins: [f64; 3],
    maxs: [f64; 3],
    files: Vec<String>,
}

#[derive(Deserialize)]
struct Files {
    files: Vec<String>,
}

#[derive(Deserialize)]
struct Codebooked {
    codebook: Vec<Option<f64>>,
    files: Vec<String>,
}

#[derive(Deserialize)]
struct HigherSh {
    count: usize,
    bands: u32,
    codebook: Vec<Option<f64>>,
    files: Vec<String>,
}

fn problem(part: &str, message: impl Into<String>) -> SplatFileProblem {
    SplatFileProblem::Sog { part: part.to_string(), message: message.into() }
}

/// Reads a SOG: a folder's files (given the folder or its `meta.json`), or a zip archive's
/// entries.
pub(super) fn read_sog(path: &Path) -> Result<Gaussians, SplatFileProblem> {
    if path.is_dir() || path.file_name().is_some_and(|n| n.eq_ignore_ascii_case("meta.json")) {
        let dir = if path.is_dir() { path } else { path.parent().unwrap_or(Path::new(".")) };
        return gaussians_from_sog(None, |name, cap| {
            Ok(read_capped(std::fs::File::open(dir.join(file_name(name)?))?, cap)?)
        });
    }
    let file = std::fs::File::open(path)?;
    let archive_bytes = file.metadata()?.len();
    from_archive(std::io::BufReader::new(file), archive_bytes)
}

/// Decodes a SOG archive (the bytes of a `.sog` file, a zip) into Gaussians in the INRIA PLY
/// convention, as [`super::read_splat_file`] reads a `.sog` file.
pub fn gaussians_from_sog_bytes(archive: &[u8]) -> Result<Gaussians, SplatFileProblem> {
    from_archive(std::io::Cursor::new(archive), archive.len() as u64)
}

/// Only the entries `meta.json` names are opened, each read no further than its cap: the
/// archive's directory (names, sizes, offsets) is untrusted, and its entries may overlap or
/// decompress to anything.
fn from_archive(reader: impl Read + Seek, archive_bytes: u64) -> Result<Gaussians, SplatFileProblem> {
    let mut archive =
        zip::ZipArchive::new(reader).map_err(|e| problem("archive", format!("not a zip archive: {e}")))?;
    gaussians_from_sog(Some(archive_bytes), |name, cap| match archive.by_name(name) {
        Ok(entry) => read_capped(entry, cap).map_err(|e| problem(name, e.to_string())),
        Err(zip::result::ZipError::FileNotFound) => Err(problem(name, "missing from the archive")),
        Err(e) => Err(problem(name, e.to_string())),
    })
}

/// At most `cap + 1` bytes of `reader`: one past the cap shows that there is more.
fn read_capped(reader: impl Read, cap: u64) -> std::io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    reader.take(cap.saturating_add(1)).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// A plain file name: meta.json may not point outside the SOG's folder.
fn file_name(name: &str) -> Result<&str, SplatFileProblem> {
    let plain = !name.is_empty() && !name.contains(['/', '\\']) && name != "..";
    if plain { Ok(name) } else { Err(problem("meta.json", format!("`{name}` is not a file name"))) }
}

fn one_file<'a>(files: &'a [String], part: &str, n: usize) -> Result<&'a [String], SplatFileProblem> {
    if files.len() == n { Ok(files) } else { Err(problem(part, format!("{} files listed, {n} expected", files.len()))) }
}

/// A codebook entry as f32; `None` for a null entry (or a value beyond f32).
fn entry(codebook: &[Option<f64>], index: u8, part: &str) -> Result<Option<f32>, SplatFileProblem> {
    match codebook.get(usize::from(index)) {
        Some(v) => Ok(v.map(|v| v as f32).filter(|v| v.is_finite())),
        None => Err(problem(part, format!("index {index} is past the {}-entry codebook", codebook.len()))),
    }
}

/// Decodes a SOG whose files `load(name, cap)` returns by name, each read no further than
/// `cap + 1` bytes; `archive_bytes` is the size of the archive holding them (`None` for a
/// folder, whose files are the input themselves).
pub(super) fn gaussians_from_sog(
    archive_bytes: Option<u64>,
    mut load: impl FnMut(&str, u64) -> Result<Vec<u8>, SplatFileProblem>,
) -> Result<Gaussians, SplatFileProblem> {
    let meta_bytes = load("meta.json", MAX_META_BYTES)?;
    if meta_bytes.len() as u64 > MAX_META_BYTES {
        return Err(problem("meta.json", format!("more than {MAX_META_BYTES} bytes (a SOG's holds a few kilobytes)")));
    }
    let meta: Meta =
        serde_json::from_slice(&meta_bytes).map_err(|e| problem("meta.json", format!("malformed: {e}")))?;
    if meta.version != 2 {
        return Err(problem("meta.json", format!("version {} (this reader reads version 2)", meta.version)));
    }
    let n = meta.count;
    if n > MAX_IMPORTED_POINTS as usize {
        let message = format!("count {n} is more than the {MAX_IMPORTED_POINTS} Gaussians a pwgs stream holds");
        return Err(problem("meta.json", message));
    }
    let means = one_file(&meta.means.files, "means", 2)?;
    let mut planned = vec![(&means[0], Layout::Texture { count: n }), (&means[1], Layout::Texture { count: n })];
    for (files, part) in [(&meta.quats.files, "quats"), (&meta.scales.files, "scales"), (&meta.sh0.files, "sh0")] {
        planned.push((&one_file(files, part, 1)?[0], Layout::Texture { count: n }));
    }
    let higher = match &meta.sh_n {
        Some(h) if h.bands > 0 => {
            let Some(&coeffs) = [3usize, 8, 15].get(h.bands as usize - 1) else {
                return Err(problem("shN", format!("{} bands (1 to 3 expected)", h.bands)));
            };
            if h.count > MAX_PALETTE {
                let message =
                    format!("{} palette entries, more than the {MAX_PALETTE} 16-bit labels can name", h.count);
                return Err(problem("shN", message));
            }
            let files = one_file(&h.files, "shN", 2)?;
            planned.push((&files[0], Layout::Palette { entries: h.count, coeffs }));
            planned.push((&files[1], Layout::Texture { count: n }));
            Some((h, coeffs))
        }
        _ => None,
    };
    let planned: Vec<(&str, Layout)> = planned.into_iter().map(|(name, layout)| (name.as_str(), layout)).collect();
    let mut images = images::read(&planned, archive_bytes, meta_bytes.len() as u64, &mut load)?.into_iter();
    let mut next = || images.next().expect("one image per planned file");
    let (low, high, quats, scales, sh0) = (next(), next(), next(), next(), next());
    let higher = higher.map(|(h, coeffs)| (h, coeffs, next(), next()));
    let degree = higher.as_ref().map_or(0, |(h, ..)| h.bands);
    let mut out = Gaussians::with_degree(degree);
    let mut sh = vec![0.0f32; out.coeffs_per_channel() * 3];
    let pixel = |image: &image::RgbaImage, i: usize| {
        let width = image.width() as usize;
        image.get_pixel((i % width) as u32, (i / width) as u32).0
    };
    'gaussians: for i in 0..n {
        let (lo, hi) = (pixel(&low, i), pixel(&high, i));
        let mean: [f32; 3] = std::array::from_fn(|a| {
            let (min, max) = (meta.means.mins[a], meta.means.maxs[a]);
            let range = if max - min == 0.0 { 1.0 } else { max - min };
            let v = min + range * f64::from(u16::from(lo[a]) | u16::from(hi[a]) << 8) / 65535.0;
            (v.signum() * (v.abs().exp() - 1.0)) as f32
        });
        let q = pixel(&quats, i);
        let Some(largest) = q[3].checked_sub(252).filter(|&t| t < 4) else {
            return Err(problem(
                &meta.quats.files[0],
                format!("pixel {i}: largest-component tag {} (252 to 255 expected)", q[3]),
            ));
        };
        let small = [q[0], q[1], q[2]].map(|b| (f64::from(b) / 255.0 * 2.0 - 1.0) / std::f64::consts::SQRT_2);
        let mut rotation = [0.0f32; 4];
        let mut others = small.iter();
        for (c, value) in rotation.iter_mut().enumerate() {
            *value = if c == usize::from(largest) {
                (1.0 - small.iter().map(|v| v * v).sum::<f64>()).max(0.0).sqrt() as f32
            } else {
                *others.next().expect("three smaller components") as f32
            };
        }
        let s = pixel(&scales, i);
        let mut log_scale = [0.0f32; 3];
        for a in 0..3 {
            let Some(v) = entry(&meta.scales.codebook, s[a], "scales")? else { continue 'gaussians };
            log_scale[a] = v;
        }
        let c = pixel(&sh0, i);
        for channel in 0..3 {
            let Some(v) = entry(&meta.sh0.codebook, c[channel], "sh0")? else { continue 'gaussians };
            sh[channel] = v;
        }
        let opacity = (f64::from(c[3]) / 255.0).clamp(1e-6, 1.0 - 1e-6);
        let logit = (opacity / (1.0 - opacity)).ln() as f32;
        if let Some((h, coeffs, centroids, labels)) = &higher {
            let l = pixel(labels, i);
            let label = usize::from(l[0]) | usize::from(l[1]) << 8;
            if label >= h.count {
                return Err(problem(
                    &h.files[1],
                    format!("pixel {i}: label {label} is past the {}-entry palette", h.count),
                ));
            }
            for j in 0..*coeffs {
                let texel = centroids.get_pixel(((label % 64) * coeffs + j) as u32, (label / 64) as u32).0;
                for channel in 0..3 {
                    let Some(v) = entry(&h.codebook, texel[channel], "shN")? else { continue 'gaussians };
                    sh[(j + 1) * 3 + channel] = v;
                }
            }
        }
        if mean.iter().all(|v| v.is_finite()) {
            out.push(mean, log_scale, rotation, logit, &sh);
        }
    }
    Ok(out)
}

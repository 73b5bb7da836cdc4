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

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use serde::Deserialize;

use super::SplatFileProblem;
use crate::gaussians::Gaussians;

/// The largest decoded image, in bytes of RGBA, and the largest side.
const MAX_IMAGE_BYTES: u64 = 1 << 30;
const MAX_SIDE: u32 = 16384;

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

/// The files of a SOG: a zip archive's entries, or a folder's files (given its `meta.json`).
pub(super) fn read_sog(path: &Path) -> Result<Gaussians, SplatFileProblem> {
    if path.is_dir() || path.file_name().is_some_and(|n| n.eq_ignore_ascii_case("meta.json")) {
        let dir = if path.is_dir() { path } else { path.parent().unwrap_or(Path::new(".")) };
        return gaussians_from_sog(|name| Ok(std::fs::read(dir.join(file_name(name)?))?));
    }
    let file = std::fs::File::open(path)?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| problem("archive", format!("not a zip archive: {e}")))?;
    let mut entries = HashMap::new();
    for i in 0..archive.len() {
        let mut entry = archive.by_index(i).map_err(|e| problem("archive", e.to_string()))?;
        let name = entry.name().to_string();
        if entry.size() > MAX_IMAGE_BYTES {
            return Err(problem(&name, format!("{} bytes is more than a SOG file holds", entry.size())));
        }
        let mut bytes = Vec::with_capacity(entry.size() as usize);
        entry.by_ref().take(MAX_IMAGE_BYTES).read_to_end(&mut bytes).map_err(|e| problem(&name, e.to_string()))?;
        entries.insert(name, bytes);
    }
    gaussians_from_sog(|name| entries.remove(name).ok_or_else(|| problem(name, "missing from the archive")))
}

/// A plain file name: meta.json may not point outside the SOG's folder.
fn file_name(name: &str) -> Result<&str, SplatFileProblem> {
    let plain = !name.is_empty() && !name.contains(['/', '\\']) && name != "..";
    if plain { Ok(name) } else { Err(problem("meta.json", format!("`{name}` is not a file name"))) }
}

/// An RGBA image of at least `count` pixels.
fn image(bytes: &[u8], name: &str, count: usize) -> Result<image::RgbaImage, SplatFileProblem> {
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::WebP);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    limits.max_alloc = Some(MAX_IMAGE_BYTES);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| problem(name, format!("not a readable WebP image: {e}")))?.to_rgba8();
    let pixels = decoded.width() as usize * decoded.height() as usize;
    if pixels < count {
        return Err(problem(name, format!("{pixels} pixels for {count} Gaussians")));
    }
    Ok(decoded)
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

/// Decodes a SOG whose files `load` returns by name.
pub(super) fn gaussians_from_sog(
    mut load: impl FnMut(&str) -> Result<Vec<u8>, SplatFileProblem>,
) -> Result<Gaussians, SplatFileProblem> {
    let meta: Meta =
        serde_json::from_slice(&load("meta.json")?).map_err(|e| problem("meta.json", format!("malformed: {e}")))?;
    if meta.version != 2 {
        return Err(problem("meta.json", format!("version {} (this reader reads version 2)", meta.version)));
    }
    let n = meta.count;
    // Every texture holds a pixel per Gaussian but the palette, which holds its own count.
    let mut texture = |name: &str, count: usize| -> Result<image::RgbaImage, SplatFileProblem> {
        image(&load(file_name(name)?)?, name, count)
    };
    let means = one_file(&meta.means.files, "means", 2)?;
    let (low, high) = (texture(&means[0], n)?, texture(&means[1], n)?);
    let quats = texture(&one_file(&meta.quats.files, "quats", 1)?[0], n)?;
    let scales = texture(&one_file(&meta.scales.files, "scales", 1)?[0], n)?;
    let sh0 = texture(&one_file(&meta.sh0.files, "sh0", 1)?[0], n)?;
    let higher = match &meta.sh_n {
        Some(h) if h.bands > 0 => {
            let Some(&coeffs) = [3usize, 8, 15].get(h.bands as usize - 1) else {
                return Err(problem("shN", format!("{} bands (1 to 3 expected)", h.bands)));
            };
            let files = one_file(&h.files, "shN", 2)?;
            let centroids = texture(&files[0], 0)?;
            if centroids.width() as usize != 64 * coeffs || (centroids.height() as usize) * 64 < h.count {
                return Err(problem(
                    &files[0],
                    format!(
                        "{}x{} pixels for {} palette entries of {coeffs} coefficients",
                        centroids.width(),
                        centroids.height(),
                        h.count
                    ),
                ));
            }
            Some((h, coeffs, centroids, texture(&files[1], n)?))
        }
        _ => None,
    };
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

#[cfg(test)]
mod tests {
    use std::io::Write;

    use super::*;
    use crate::random_scene::{SplitMix64, random_gaussians};

    /// A lossless WebP of `n` RGBA pixels, `width` wide.
    fn webp(pixels: &[[u8; 4]], width: u32) -> Vec<u8> {
        let height = (pixels.len() as u32).div_ceil(width);
        let mut data: Vec<u8> = pixels.iter().flatten().copied().collect();
        data.resize((width * height * 4) as usize, 0);
        let mut out = Vec::new();
        image::codecs::webp::WebPEncoder::new_lossless(&mut out)
            .encode(&data, width, height, image::ExtendedColorType::Rgba8)
            .unwrap();
        out
    }

    /// 256 levels spanning `values`, and each value's nearest level.
    fn codebook(values: &[f32]) -> (Vec<f64>, Vec<u8>) {
        let (lo, hi) = values.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        let step = f64::from(hi - lo).max(1e-9) / 255.0;
        let levels = (0..256).map(|k| f64::from(lo) + step * f64::from(k)).collect();
        (levels, values.iter().map(|&v| (f64::from(v - lo) / step).round() as u8).collect())
    }

    /// `g` (SH degree 0 or 1) as the files of a SOG, the palette holding one entry per Gaussian.
    fn sog_files(g: &Gaussians) -> Files {
        let n = g.len();
        let width = 16;
        let log = |x: f32| f64::from(x).signum() * f64::from(x).abs().ln_1p();
        let mins: [f64; 3] = std::array::from_fn(|a| g.means.iter().map(|m| log(m[a])).fold(f64::INFINITY, f64::min));
        let maxs: [f64; 3] =
            std::array::from_fn(|a| g.means.iter().map(|m| log(m[a])).fold(f64::NEG_INFINITY, f64::max));
        let q16 = |i: usize, a: usize| ((log(g.means[i][a]) - mins[a]) / (maxs[a] - mins[a]) * 65535.0).round() as u16;
        let bytes = |shift: u32| -> Vec<[u8; 4]> {
            (0..n)
                .map(|i| {
                    let [x, y, z] = [0, 1, 2].map(|a| (q16(i, a) >> shift) as u8);
                    [x, y, z, 255]
                })
                .collect()
        };
        let (low, high) = (bytes(0), bytes(8));
        let quats: Vec<[u8; 4]> = g
            .rotations
            .iter()
            .map(|q| {
                let norm = q.iter().map(|v| v * v).sum::<f32>().sqrt();
                let largest = (0..4).max_by(|&a, &b| q[a].abs().total_cmp(&q[b].abs())).unwrap();
                let sign = q[largest].signum() / norm;
                let mut small = (0..4).filter(|&c| c != largest).map(|c| {
                    let v = f64::from(q[c] * sign) * std::f64::consts::SQRT_2;
                    ((v + 1.0) / 2.0 * 255.0).round() as u8
                });
                [small.next().unwrap(), small.next().unwrap(), small.next().unwrap(), 252 + largest as u8]
            })
            .collect();
        let flat =
            |f: &dyn Fn(usize, usize) -> f32, k: usize| -> Vec<f32> { (0..n * k).map(|j| f(j / k, j % k)).collect() };
        let (scale_book, scale_index) = codebook(&flat(&|i, a| g.log_scales[i][a], 3));
        let (dc_book, dc_index) = codebook(&flat(&|i, c| g.sh_of(i)[c], 3));
        let scales: Vec<[u8; 4]> =
            (0..n).map(|i| [scale_index[3 * i], scale_index[3 * i + 1], scale_index[3 * i + 2], 255]).collect();
        let sh0: Vec<[u8; 4]> = (0..n)
            .map(|i| {
                let alpha = 1.0 / (1.0 + f64::from(-g.opacity_logits[i]).exp());
                [dc_index[3 * i], dc_index[3 * i + 1], dc_index[3 * i + 2], (alpha * 255.0).round() as u8]
            })
            .collect();
        let mut meta = serde_json::json!({
            "version": 2, "count": n,
            "means": {"mins": mins, "maxs": maxs, "files": ["means_l.webp", "means_u.webp"]},
            "scales": {"codebook": scale_book, "files": ["scales.webp"]},
            "quats": {"files": ["quats.webp"]},
            "sh0": {"codebook": dc_book, "files": ["sh0.webp"]},
        });
        let mut files: Files = [
            ("means_l.webp", webp(&low, width)),
            ("means_u.webp", webp(&high, width)),
            ("quats.webp", webp(&quats, width)),
            ("scales.webp", webp(&scales, width)),
            ("sh0.webp", webp(&sh0, width)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        if g.sh_degree == 1 {
            let (book, index) = codebook(&flat(&|i, k| g.sh_of(i)[3 + k], 9));
            // Entry i's three pixels hold coefficient j's r, g, b indices.
            let centroids: Vec<[u8; 4]> = (0..n * 3)
                .map(|p| [0, 1, 2].map(|c| index[(p / 3) * 9 + (p % 3) * 3 + c]))
                .map(|[r, g, b]| [r, g, b, 255])
                .collect();
            let labels: Vec<[u8; 4]> = (0..n).map(|i| [i as u8, (i >> 8) as u8, 0, 255]).collect();
            files.insert("shN_centroids.webp".into(), webp(&centroids, 64 * 3));
            files.insert("shN_labels.webp".into(), webp(&labels, width));
            meta["shN"] = serde_json::json!({"count": n, "bands": 1, "codebook": book, "files": ["shN_centroids.webp", "shN_labels.webp"]});
        }
        files.insert("meta.json".into(), serde_json::to_vec(&meta).unwrap());
        files
    }

    type Files = HashMap<String, Vec<u8>>;

    fn read(files: &Files) -> Result<Gaussians, SplatFileProblem> {
        gaussians_from_sog(|name| files.get(name).cloned().ok_or_else(|| problem(name, "missing")))
    }

    #[test]
    fn reads_the_gaussians_within_the_formats_quantization() {
        let g = random_gaussians(&mut SplitMix64(17), 300, 1, [-4.0, -1.0]);
        let r = read(&sog_files(&g)).unwrap();
        assert_eq!((r.len(), r.sh_degree), (300, 1));
        let spread = |v: &dyn Fn(usize) -> f32, k: usize| {
            let all: Vec<f32> = (0..300 * k).map(v).collect();
            all.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)) - all.iter().fold(f32::INFINITY, |a, &b| a.min(b))
        };
        let scale_step = spread(&|j| g.log_scales[j / 3][j % 3], 3) / 255.0;
        let dc_step = spread(&|j| g.sh_of(j / 3)[j % 3], 3) / 255.0;
        let rest_step = spread(&|j| g.sh_of(j / 9)[3 + j % 9], 9) / 255.0;
        for i in 0..300 {
            for a in 0..3 {
                let (x, y) = (g.means[i][a], r.means[i][a]);
                assert!((x - y).abs() <= (1.0 + x.abs()) * 12.0 / 65535.0, "mean {i} axis {a}: {x} vs {y}");
                assert!((g.log_scales[i][a] - r.log_scales[i][a]).abs() <= scale_step * 0.51, "scale {i} axis {a}");
                assert!((g.sh_of(i)[a] - r.sh_of(i)[a]).abs() <= dc_step * 0.51, "color {i} channel {a}");
            }
            for k in 3..12 {
                assert!((g.sh_of(i)[k] - r.sh_of(i)[k]).abs() <= rest_step * 0.51, "sh {i} value {k}");
            }
            let unit = |q: [f32; 4]| q.map(|v| v / q.iter().map(|v| v * v).sum::<f32>().sqrt());
            let dot: f32 = unit(g.rotations[i]).iter().zip(unit(r.rotations[i])).map(|(a, b)| a * b).sum();
            assert!(dot.abs() > 0.999, "rotation {i}");
            let alpha = |logit: f32| 1.0 / (1.0 + (-logit).exp());
            assert!(
                (alpha(g.opacity_logits[i]) - alpha(r.opacity_logits[i])).abs() <= 0.5 / 255.0 + 1e-5,
                "opacity {i}"
            );
        }
    }

    #[test]
    fn an_archive_and_a_folder_read_the_same() {
        let g = random_gaussians(&mut SplitMix64(2), 50, 0, [-4.0, -1.0]);
        let files = sog_files(&g);
        let dir = tempfile::tempdir().unwrap();
        let mut zip = zip::ZipWriter::new(std::fs::File::create(dir.path().join("m.sog")).unwrap());
        let stored = zip::write::FileOptions::default().compression_method(zip::CompressionMethod::Stored);
        for (name, bytes) in &files {
            zip.start_file(name, stored).unwrap();
            zip.write_all(bytes).unwrap();
            std::fs::write(dir.path().join(name), bytes).unwrap();
        }
        zip.finish().unwrap();
        let archive = read_sog(&dir.path().join("m.sog")).unwrap();
        assert_eq!(archive, read_sog(&dir.path().join("meta.json")).unwrap());
        assert_eq!(archive, read(&files).unwrap());
        assert_eq!(archive.len(), 50);
    }

    #[test]
    fn broken_files_are_errors_naming_the_part() {
        let g = random_gaussians(&mut SplitMix64(3), 40, 1, [-4.0, -1.0]);
        let files = sog_files(&g);
        let message = |edit: &dyn Fn(&mut Files)| {
            let mut f = files.clone();
            edit(&mut f);
            read(&f).unwrap_err().to_string()
        };
        let meta = |f: &mut Files, from: &str, to: &str| {
            let text = String::from_utf8(f["meta.json"].clone()).unwrap().replace(from, to);
            f.insert("meta.json".into(), text.into_bytes());
        };
        assert!(message(&|f| meta(f, "\"version\":2", "\"version\":1")).contains("version 1"));
        assert!(message(&|f| meta(f, "\"count\":40", "\"count\":4000")).contains("pixels for 4000 Gaussians"));
        assert!(
            message(&|f| meta(f, "\"count\":40,\"files\"", "\"count\":10,\"files\""))
                .contains("past the 10-entry palette")
        );
        assert!(message(&|f| meta(f, "quats.webp\"]", "../quats.webp\"]")).contains("is not a file name"));
        assert!(message(&|f| drop(f.remove("scales.webp"))).contains("scales.webp"));
        assert!(
            message(&|f| drop(f.insert("sh0.webp".into(), b"RIFF".to_vec()))).contains("sh0.webp: not a readable WebP")
        );
        let tags = vec![[128, 128, 128, 7u8]; 40];
        assert!(message(&|f| drop(f.insert("quats.webp".into(), webp(&tags, 16)))).contains("largest-component tag 7"));
        assert!(message(&|f| meta(f, "\"version\"", "\"versio\"")).contains("meta.json: malformed"));
    }
}

use std::collections::HashMap;
use std::io::{Read, Write};

use super::*;
use crate::random::{SplitMix64, random_gaussians};
use crate::splat_file::decompressed_limit;

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
    let maxs: [f64; 3] = std::array::from_fn(|a| g.means.iter().map(|m| log(m[a])).fold(f64::NEG_INFINITY, f64::max));
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

/// Reads `files` as a folder would be read: each file up to one byte past its cap.
fn read(files: &Files) -> Result<Gaussians, SplatFileProblem> {
    gaussians_from_sog(None, |name, cap| {
        let bytes = files.get(name).ok_or_else(|| problem(name, "missing"))?;
        Ok(bytes[..bytes.len().min(cap as usize + 1)].to_vec())
    })
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
        assert!((alpha(g.opacity_logits[i]) - alpha(r.opacity_logits[i])).abs() <= 0.5 / 255.0 + 1e-5, "opacity {i}");
    }
}

/// `files` as a zip archive, in name order, each entry compressed with `method`.
fn zip_archive(files: &Files, method: zip::CompressionMethod) -> Vec<u8> {
    let mut names: Vec<&String> = files.keys().collect();
    names.sort();
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::FileOptions::default().compression_method(method);
    for name in names {
        zip.start_file(name.as_str(), options).unwrap();
        zip.write_all(&files[name]).unwrap();
    }
    zip.finish().unwrap().into_inner()
}

/// A lossless WebP of `width` x `height` pixels, all `rgba`, written bit by bit: each of the
/// five prefix codes has a single symbol, so the pixels take no bits and the file is 34 bytes
/// whatever its size (the VP8L bitstream, RFC 9649).
fn uniform_webp(width: u32, height: u32, [r, g, b, a]: [u8; 4]) -> Vec<u8> {
    let (mut bits, mut count) = (0u128, 0);
    let mut put = |value: u8, n: u32| {
        bits |= u128::from(value) << count;
        count += n;
    };
    put(0x2f, 8);
    for byte in ((width - 1) | (height - 1) << 14 | 1 << 28).to_le_bytes() {
        put(byte, 8); // sizes less one, "alpha is used", version 0
    }
    put(0, 3); // no transform, no color cache, no meta prefix codes
    for symbol in [g, r, b, a, 0] {
        put(0b101, 3); // a simple code of one symbol, stored in 8 bits
        put(symbol, 8);
    }
    let data = &bits.to_le_bytes()[..count.div_ceil(8) as usize];
    let mut chunk = [b"VP8L".as_slice(), &(data.len() as u32).to_le_bytes(), data].concat();
    chunk.resize(chunk.len().next_multiple_of(2), 0);
    [b"RIFF".as_slice(), &(4 + chunk.len() as u32).to_le_bytes(), b"WEBP", &chunk].concat()
}

/// `meta.json` of `files` changed by `edit`.
fn edit_meta(files: &mut Files, edit: impl FnOnce(&mut serde_json::Value)) {
    let mut meta: serde_json::Value = serde_json::from_slice(&files["meta.json"]).unwrap();
    edit(&mut meta);
    files.insert("meta.json".into(), serde_json::to_vec(&meta).unwrap());
}

const TEXTURES: [&str; 5] = ["means_l.webp", "means_u.webp", "quats.webp", "scales.webp", "sh0.webp"];

/// `count` identical Gaussians in images of `width` x `height` pixels (a valid SOG).
fn uniform_sog(count: usize, width: u32, height: u32) -> Files {
    let mut files = sog_files(&random_gaussians(&mut SplitMix64(5), 1, 0, [-4.0, -1.0]));
    edit_meta(&mut files, |meta| meta["count"] = count.into());
    for name in TEXTURES {
        let tag = if name == "quats.webp" { 252 } else { 255 };
        files.insert(name.into(), uniform_webp(width, height, [0, 0, 0, tag]));
    }
    files
}

#[test]
fn an_archive_and_a_folder_read_the_same() {
    let g = random_gaussians(&mut SplitMix64(2), 50, 0, [-4.0, -1.0]);
    let files = sog_files(&g);
    let dir = tempfile::tempdir().unwrap();
    let archive = zip_archive(&files, zip::CompressionMethod::Stored);
    std::fs::write(dir.path().join("m.sog"), &archive).unwrap();
    for (name, bytes) in &files {
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }
    let from_file = read_sog(&dir.path().join("m.sog")).unwrap();
    assert_eq!(from_file, read_sog(&dir.path().join("meta.json")).unwrap());
    assert_eq!(from_file, gaussians_from_sog_bytes(&archive).unwrap());
    assert_eq!(from_file, read(&files).unwrap());
    assert_eq!(from_file.len(), 50);
    let deflated = zip_archive(&files, zip::CompressionMethod::Deflated);
    assert_eq!(gaussians_from_sog_bytes(&deflated).unwrap(), from_file);
}

#[test]
fn a_hand_made_uniform_webp_decodes() {
    let bytes = uniform_webp(5, 3, [10, 20, 30, 252]);
    assert_eq!(bytes.len(), 34);
    let image = image::load_from_memory_with_format(&bytes, image::ImageFormat::WebP).unwrap().into_rgba8();
    assert_eq!(image.dimensions(), (5, 3));
    assert!(image.pixels().all(|p| p.0 == [10, 20, 30, 252]));
    // Identical Gaussians, as many as the images hold, are a valid SOG.
    let g = read(&uniform_sog(4096, 64, 64)).unwrap();
    assert_eq!(g.len(), 4096);
    assert!(g.means.iter().all(|m| *m == g.means[0]));
}

#[test]
fn the_counts_are_bounded_before_any_image_is_read() {
    let mut files = sog_files(&random_gaussians(&mut SplitMix64(3), 40, 1, [-4.0, -1.0]));
    let meta_only = |files: &Files| {
        let meta = files["meta.json"].clone();
        let result = gaussians_from_sog(None, |name, _| match name {
            "meta.json" => Ok(meta.clone()),
            _ => panic!("{name} was read"),
        });
        result.unwrap_err().to_string()
    };
    edit_meta(&mut files, |meta| meta["count"] = (MAX_IMPORTED_POINTS as u64 + 1).into());
    let err = meta_only(&files);
    assert_eq!(err, "SOG meta.json: count 16777217 is more than the 16777216 Gaussians a pwgs stream holds");
    edit_meta(&mut files, |meta| {
        meta["count"] = 40.into();
        meta["shN"]["count"] = (MAX_PALETTE + 1).into();
    });
    assert!(meta_only(&files).contains("shN: 65537 palette entries, more than the 65536"));
    edit_meta(&mut files, |meta| meta["version"] = 3.into());
    assert!(meta_only(&files).contains("version 3"));
    files.insert("meta.json".into(), vec![b' '; MAX_META_BYTES as usize + 1]);
    assert!(meta_only(&files).contains("meta.json: more than 1048576 bytes"));
}

#[test]
fn image_sizes_are_checked_before_any_pixel_is_decoded() {
    let files = sog_files(&random_gaussians(&mut SplitMix64(3), 40, 1, [-4.0, -1.0]));
    let message = |name: &str, image: Vec<u8>| {
        let mut f = files.clone();
        f.insert(name.into(), image);
        read(&f).unwrap_err().to_string()
    };
    // Only the header: decoding any pixel would fail, so the size must be refused first.
    let huge = uniform_webp(16383, 16383, [0, 0, 0, 255])[..25].to_vec();
    let err = message("means_l.webp", huge);
    assert!(err.starts_with("SOG means_l.webp: 16383x16383 pixels for 40 Gaussians: more than the 4096"), "{err}");
    let err = message("shN_labels.webp", uniform_webp(8, 4, [0, 0, 0, 255]));
    assert_eq!(err, "SOG shN_labels.webp: 8x4 pixels for 40 Gaussians");
    let err = message("shN_centroids.webp", uniform_webp(193, 1, [0, 0, 0, 255]));
    assert_eq!(err, "SOG shN_centroids.webp: 193x1 pixels for 40 palette entries of 3 coefficients");
    let err = message("shN_centroids.webp", uniform_webp(192, 100, [0, 0, 0, 255])[..25].to_vec());
    assert!(err.contains("192x100 pixels for 40 palette entries of 3 coefficients: more than the 4096"), "{err}");
}

#[test]
fn decoded_pixels_are_bounded_by_the_input_size() {
    // 2^20 Gaussians in five uniform 1024 x 1024 images: 20 MiB of pixels from 10 KB.
    let files = uniform_sog(1 << 20, 1024, 1024);
    let archive = zip_archive(&files, zip::CompressionMethod::Stored);
    assert!(archive.len() < 20_000, "{} bytes", archive.len());
    let limit = decompressed_limit(archive.len() as u64);
    let err = gaussians_from_sog_bytes(&archive).unwrap_err().to_string();
    let expected =
        format!("SOG means_l.webp: the images up to this one decode to 4194304 bytes, more than the {limit}");
    assert!(err.starts_with(&expected), "{err}");
    // A folder of the same files: its input is the files themselves.
    assert!(read(&files).unwrap_err().to_string().contains("decode to 4194304 bytes"));
}

#[test]
fn only_the_named_entries_are_read_each_through_its_cap() {
    let g = random_gaussians(&mut SplitMix64(4), 40, 1, [-4.0, -1.0]);
    let mut files = sog_files(&g);
    // An entry meta.json does not name, whose checksum fails when it is read.
    files.insert("junk.bin".into(), vec![7; 1000]);
    let mut archive = zip_archive(&files, zip::CompressionMethod::Stored);
    let at = archive.windows(8).position(|w| w == b"junk.bin").unwrap() + 8;
    archive[at + 100] ^= 1;
    let mut corrupt = zip::ZipArchive::new(std::io::Cursor::new(&archive)).unwrap();
    assert!(corrupt.by_name("junk.bin").unwrap().read_to_end(&mut Vec::new()).is_err());
    assert_eq!(gaussians_from_sog_bytes(&archive).unwrap(), read(&sog_files(&g)).unwrap());

    // A named entry that inflates past what a WebP of 40 Gaussians' pixels takes.
    files.insert("means_l.webp".into(), vec![0; 8 << 20]);
    let archive = zip_archive(&files, zip::CompressionMethod::Deflated);
    let err = gaussians_from_sog_bytes(&archive).unwrap_err().to_string();
    assert!(err.starts_with("SOG means_l.webp: more than 81920 bytes"), "{err}");

    // Entries each within their cap but together far beyond the archive's size.
    let mut files = uniform_sog(1 << 20, 1024, 1024);
    for name in TEXTURES {
        files.insert(name.into(), vec![0; 4 << 20]);
    }
    let archive = zip_archive(&files, zip::CompressionMethod::Deflated);
    let err = gaussians_from_sog_bytes(&archive).unwrap_err().to_string();
    assert!(err.starts_with("SOG means_l.webp: the files meta.json names decompress to more than"), "{err}");
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
        message(&|f| meta(f, "\"count\":40,\"files\"", "\"count\":10,\"files\"")).contains("past the 10-entry palette")
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

use std::io::Read;

use super::*;
use crate::gaussians::sh_coeff_count;
use crate::random::{SplitMix64, random_gaussians};
use crate::splat_file::tests::quaternion_gap;

fn gzip(raw: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    encoder.write_all(raw).unwrap();
    encoder.finish().unwrap()
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    let mut raw = Vec::new();
    flate2::read::GzDecoder::new(bytes).read_to_end(&mut raw).unwrap();
    raw
}

fn header(version: u32, points: u32, degree: u8, flags: u8) -> Vec<u8> {
    let mut h = [MAGIC, version, points].iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
    h.extend_from_slice(&[degree, 12, flags, 0]);
    h
}

fn fixed24(v: i32) -> [u8; 3] {
    let b = v.to_le_bytes();
    [b[0], b[1], b[2]]
}

/// One version-3, degree-1 point stored (RUB) at (1, 2, -3) with 12 fractional bits, rotated
/// 90 degrees about y, opacity byte 255, colors (255, 0, 128), log-scale bytes (160, 0, 255),
/// and SH bytes 192, 64, 160 for coefficients 1, 2, 3 in every channel.
fn hand_made_body() -> Vec<u8> {
    let mut body: Vec<u8> = [4096, 8192, -12288].into_iter().flat_map(fixed24).collect();
    body.push(255);
    body.extend_from_slice(&[255, 0, 128]);
    body.extend_from_slice(&[160, 0, 255]);
    // Largest component w (index 3); then x = 0, y = +sqrt(1/2) (magnitude 511), z = 0.
    body.extend_from_slice(&((3u32 << 30) | (511 << 10)).to_le_bytes());
    for byte in [192, 64, 160] {
        body.extend_from_slice(&[byte; 3]);
    }
    body
}

fn coordinate_record(code: u32) -> Vec<u8> {
    [EXTENSION_COORDINATE_SYSTEM, 4, code].iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn assert_close(actual: &[f32], expected: &[f32], tolerance: f32) {
    assert_eq!(actual.len(), expected.len());
    let ok = actual.iter().zip(expected).all(|(a, e)| (a - e).abs() <= tolerance);
    assert!(ok, "{actual:?} vs {expected:?}");
}

#[test]
fn stored_rub_axes_are_read_as_ply_axes() {
    let bytes = gzip(&[header(3, 1, 1, 0), hand_made_body()].concat());
    let g = gaussians_from_spz_bytes(&bytes, SpzAxes::Rub).unwrap();
    assert_eq!(g.means, [[1.0, -2.0, 3.0]]);
    assert_eq!(g.log_scales, [[0.0, -10.0, 255.0 / 16.0 - 10.0]]);
    assert_close(&g.rotations[0], &[SQRT_HALF, 0.0, -SQRT_HALF, 0.0], 1e-6);
    let alpha_max = 1.0 - ALPHA_MIN;
    assert_close(&g.opacity_logits, &[(alpha_max / (1.0 - alpha_max)).ln()], 1e-5);
    let dc = [0.5 / COLOR_SCALE, -0.5 / COLOR_SCALE, (128.0 / 255.0 - 0.5) / COLOR_SCALE];
    // Coefficient 1 is odd in y, 2 in z, 3 in x: the first two change sign, the third stays.
    let rest = [[-0.5; 3], [0.5; 3], [0.25; 3]];
    let expected: Vec<f32> = dc.iter().chain(rest.iter().flatten()).copied().collect();
    assert_close(&g.sh, &expected, 1e-5);
}

#[test]
fn unmarked_files_are_read_in_the_axes_the_caller_names() {
    // Without records, and with a record saying "unspecified" (code 0).
    let plain = gzip(&[header(3, 1, 1, 0), hand_made_body()].concat());
    let unspecified = gzip(&[header(3, 1, 1, 2), hand_made_body(), coordinate_record(0)].concat());
    for bytes in [&plain, &unspecified] {
        let rdf = gaussians_from_spz_bytes(bytes, SpzAxes::Rdf).unwrap();
        assert_eq!(rdf.means, [[1.0, 2.0, -3.0]], "stored as the PLY's axes: nothing flips");
        assert_close(&rdf.rotations[0], &[SQRT_HALF, 0.0, SQRT_HALF, 0.0], 1e-6);
        assert_close(&rdf.sh[3..], &[0.5, 0.5, 0.5, -0.5, -0.5, -0.5, 0.25, 0.25, 0.25], 1e-6);
        assert_eq!(gaussians_from_spz_bytes(bytes, SpzAxes::Rub).unwrap().means, [[1.0, -2.0, 3.0]]);
    }
    // A record naming the axes wins over the caller's choice.
    let marked_rub = gzip(&[header(3, 1, 1, 2), hand_made_body(), coordinate_record(4)].concat());
    assert_eq!(gaussians_from_spz_bytes(&marked_rub, SpzAxes::Rdf).unwrap().means, [[1.0, -2.0, 3.0]]);
}

#[test]
fn the_coordinate_system_extension_selects_the_axis_flips() {
    let read = |records: Vec<u8>| {
        gaussians_from_spz_bytes(&gzip(&[header(3, 1, 1, 2), hand_made_body(), records].concat()), SpzAxes::Rub)
    };
    // Stored RDF: nothing to convert. An unknown record before it is skipped.
    let unknown: Vec<u8> = [0x1234_0001u32, 3].iter().flat_map(|v| v.to_le_bytes()).chain([9, 9, 9]).collect();
    let g = read([unknown, coordinate_record(6)].concat()).unwrap();
    assert_eq!(g.means, [[1.0, 2.0, -3.0]]);
    assert_close(&g.rotations[0], &[SQRT_HALF, 0.0, SQRT_HALF, 0.0], 1e-6);
    assert_close(&g.sh[3..], &[0.5, 0.5, 0.5, -0.5, -0.5, -0.5, 0.25, 0.25, 0.25], 1e-6);
    // Stored LDB: x and z flip, a reflection; the rotation stays a rotation.
    let g = read(coordinate_record(1)).unwrap();
    assert_eq!(g.means, [[-1.0, 2.0, 3.0]]);
    assert_close(&g.rotations[0], &[SQRT_HALF, 0.0, SQRT_HALF, 0.0], 1e-6);
    assert_close(&g.sh[3..], &[0.5, 0.5, 0.5, 0.5, 0.5, 0.5, -0.25, -0.25, -0.25], 1e-6);
    // Code 0 (unspecified) and no record at all both mean RUB.
    assert_eq!(read(coordinate_record(0)).unwrap().means, [[1.0, -2.0, 3.0]]);
    assert_eq!(read(Vec::new()).unwrap().means, [[1.0, -2.0, 3.0]]);

    let err = read(coordinate_record(12)).unwrap_err().to_string();
    assert!(err.contains("coordinate system 12 is not supported"), "{err}");
    let err = read(coordinate_record(6)[..10].to_vec()).unwrap_err().to_string();
    assert!(err.contains("at byte 0") && err.contains("declares 4 payload bytes, 2 remain"), "{err}");
    let err = read([coordinate_record(6), vec![1, 2, 3]].concat()).unwrap_err().to_string();
    assert!(err.contains("at byte 12") && err.contains("needs 8 bytes, 3 remain"), "{err}");
}

/// Tolerances, from the format's quantization: positions within half a step of 2^-12 (the
/// writer's 12 fractional bits suffice for this scene); log-scales within 1/32 (steps of
/// 1/16); opacity within 0.5/255; DC within 0.5/255/0.15; the other SH within 0.5/128. Version
/// 3 stores three quaternion components to sqrt(1/2)/511/2 (7e-4) and derives the largest,
/// at least 1/2, from the unit norm, which can triple that error: 3e-3 for the unit
/// quaternion. Version 2 stores x, y, z to 1/255 and derives w, whose error grows like the
/// square root of theirs as w approaches 0: up to about 0.12.
#[test]
fn round_trips_are_within_the_quantization() {
    for (version, rotation_tolerance) in [(SpzVersion::V3, 3e-3), (SpzVersion::V2, 0.12)] {
        for degree in 0..=3 {
            let g = random_gaussians(&mut SplitMix64(100 + degree as u64), 200, degree, [-5.0, 0.0]);
            let back = gaussians_from_spz_bytes(&gaussians_to_spz_bytes(&g, version), SpzAxes::Rub).unwrap();
            assert!(back.is_consistent() && back.len() == g.len() && back.sh_degree == degree);
            let (mut worst_rotation, coeffs) = (0.0f32, sh_coeff_count(degree) * 3);
            for i in 0..g.len() {
                assert_close(&back.means[i], &g.means[i], 0.5 / 4096.0 + 1e-5);
                assert_close(&back.log_scales[i], &g.log_scales[i], 1.0 / 32.0 + 1e-5);
                let sigmoid = |l: f32| 1.0 / (1.0 + (-l).exp());
                assert_close(&[sigmoid(back.opacity_logits[i])], &[sigmoid(g.opacity_logits[i])], 0.5 / 255.0 + 1e-6);
                assert_close(&back.sh_of(i)[..3], &g.sh_of(i)[..3], 0.5 / 255.0 / COLOR_SCALE + 1e-5);
                assert_close(&back.sh_of(i)[3..coeffs], &g.sh_of(i)[3..coeffs], 0.5 / 128.0 + 1e-6);
                worst_rotation = worst_rotation.max(quaternion_gap(back.rotations[i], g.rotations[i]));
            }
            assert!(worst_rotation <= rotation_tolerance, "{version:?}: rotation off by {worst_rotation}");
        }
    }
}

#[test]
fn every_truncation_is_an_error() {
    let g = random_gaussians(&mut SplitMix64(9), 3, 1, [-3.0, -1.0]);
    let bytes = gaussians_to_spz_bytes(&g, SpzVersion::V3);
    assert!(gaussians_from_spz_bytes(&bytes, SpzAxes::Rub).is_ok());
    for len in 0..bytes.len() {
        let err =
            gaussians_from_spz_bytes(&bytes[..len], SpzAxes::Rub).expect_err(&format!("{len} bytes were accepted"));
        let expected = match len {
            0..=1 => matches!(err, SplatFileProblem::NotSpz),
            _ => matches!(err, SplatFileProblem::Gzip(_)),
        };
        assert!(expected, "{len} bytes: {err}");
    }
    // A complete gzip stream holding a truncated SPZ.
    let raw = gunzip(&bytes);
    for len in 0..raw.len() {
        let err = gaussians_from_spz_bytes(&gzip(&raw[..len]), SpzAxes::Rub)
            .expect_err(&format!("{len} raw bytes were accepted"));
        let expected = match len {
            0..HEADER_BYTES => matches!(err, SplatFileProblem::ShortHeader { found } if found == len),
            _ => matches!(err, SplatFileProblem::ShortData { points: 3, needed, found }
                if needed == raw.len() as u64 - 16 && found == len as u64 - 16),
        };
        assert!(expected, "{len} raw bytes: {err}");
    }
}

#[test]
fn bad_headers_are_named() {
    let raw =
        gunzip(&gaussians_to_spz_bytes(&random_gaussians(&mut SplitMix64(2), 2, 0, [-3.0, -1.0]), SpzVersion::V3));
    let edit = |at: usize, value: &[u8]| {
        let mut r = raw.clone();
        r[at..at + value.len()].copy_from_slice(value);
        gaussians_from_spz_bytes(&gzip(&r), SpzAxes::Rub).unwrap_err().to_string()
    };
    assert_eq!(edit(0, b"NGSQ"), "bad SPZ magic 0x5153474e (expected 0x5053474e, `NGSP`)");
    for version in [0u32, 1, 4, 5] {
        let err = edit(4, &version.to_le_bytes());
        assert!(err.starts_with(&format!("SPZ version {version} is not supported")), "{err}");
    }
    assert!(edit(4, &1u32.to_le_bytes()).contains("float16 positions"));
    assert!(edit(12, &[5]).contains("SH degree 5"));
    let err = edit(8, &3u32.to_le_bytes());
    assert_eq!(err, "the SPZ header declares 3 points, which need 60 bytes of data, but the data holds 40");
    let err = edit(8, &1u32.to_le_bytes());
    assert_eq!(err, "data continues after the 1 points, and the SPZ header announces no extension records");
    // More points than a pwgs stream holds: refused from the header alone.
    let err = [edit(8, &u32::MAX.to_le_bytes()), edit(8, &53_000_000u32.to_le_bytes())];
    assert!(err.iter().all(|e| e.contains("points, more than the 16777216 a pwgs stream holds")), "{err:?}");
    // Within that, but more data than a file of this size may decompress to.
    let err = edit(8, &10_000_000u32.to_le_bytes());
    assert!(err.contains("10000000 points, which need 200000000 bytes of data, more than the"), "{err}");
    // Within both but beyond the data: only the data present is ever read.
    assert!(edit(8, &50_000u32.to_le_bytes()).ends_with("but the data holds 40"));

    // Version 4 keeps its header outside any compression.
    let v4 = [b"NGSP".as_slice(), &4u32.to_le_bytes(), &[0; 24]].concat();
    let err = gaussians_from_spz_bytes(&v4, SpzAxes::Rub).unwrap_err().to_string();
    assert!(err.contains("0 streams for SH degree 0 (expected 5)"), "{err}");
    let v5 = [b"NGSP".as_slice(), &5u32.to_le_bytes(), &[0; 24]].concat();
    assert!(
        gaussians_from_spz_bytes(&v5, SpzAxes::Rub).unwrap_err().to_string().contains("SPZ version 5 is not supported")
    );
}

/// Version 3 bytes rewritten as version 4: the plain header with the stream count and table
/// offset, optional extension records, the table, and each block as its own zstd stream.
fn to_v4(v3: &[u8], points: usize, degree: u32, extensions: &[u8]) -> Vec<u8> {
    let raw = gunzip(v3);
    let n = points;
    let mut sizes = vec![9 * n, n, 3 * n, 3 * n, 4 * n];
    if degree > 0 {
        sizes.push(3 * (sh_coeff_count(degree) - 1) * n);
    }
    let mut at = HEADER_BYTES;
    let streams: Vec<Vec<u8>> = sizes
        .iter()
        .map(|&size| {
            at += size;
            zstd::encode_all(&raw[at - size..at], 3).unwrap()
        })
        .collect();
    let mut out = raw[..HEADER_BYTES].to_vec();
    out[4..8].copy_from_slice(&4u32.to_le_bytes());
    out[14] |= if extensions.is_empty() { 0 } else { FLAG_EXTENSIONS };
    out[15] = streams.len() as u8;
    out.extend_from_slice(&(32 + extensions.len() as u32).to_le_bytes());
    out.resize(32, 0);
    out.extend_from_slice(extensions);
    for (stream, size) in streams.iter().zip(&sizes) {
        out.extend_from_slice(&(stream.len() as u64).to_le_bytes());
        out.extend_from_slice(&(*size as u64).to_le_bytes());
    }
    streams.iter().for_each(|s| out.extend_from_slice(s));
    out
}

#[test]
fn version_4_reads_as_version_3() {
    for degree in [0, 2] {
        let g = random_gaussians(&mut SplitMix64(30 + degree as u64), 70, degree, [-4.0, -1.0]);
        let v3 = gaussians_to_spz_bytes(&g, SpzVersion::V3);
        let expected = gaussians_from_spz_bytes(&v3, SpzAxes::Rub).unwrap();
        assert_eq!(
            gaussians_from_spz_bytes(&to_v4(&v3, 70, degree, &[]), SpzAxes::Rub).unwrap(),
            expected,
            "degree {degree}"
        );
        // An axis convention in an extension record applies as in version 3: RDF is stored
        // unflipped, so positions keep their y and z signs.
        let rdf = [EXTENSION_COORDINATE_SYSTEM.to_le_bytes(), 4u32.to_le_bytes(), 2u32.to_le_bytes()].concat();
        let flipped = gaussians_from_spz_bytes(&to_v4(&v3, 70, degree, &rdf), SpzAxes::Rub).unwrap();
        assert_eq!(flipped.means[5][1], -expected.means[5][1], "degree {degree}");
    }
    let v3 = gaussians_to_spz_bytes(&random_gaussians(&mut SplitMix64(1), 20, 0, [-4.0, -1.0]), SpzVersion::V3);
    let good = to_v4(&v3, 20, 0, &[]);
    let message = |bytes: &[u8]| gaussians_from_spz_bytes(bytes, SpzAxes::Rub).unwrap_err().to_string();
    assert!(message(&good[..good.len() - 1]).contains("runs past the end of the file"));
    assert!(message(&[&good[..], &[0]].concat()).contains("data continues after the 20 points"));
    let mut wrong_size = good.clone();
    wrong_size[32 + 8] ^= 1;
    assert!(message(&wrong_size).contains("stream 0 declares 181 bytes, 180 expected"));
    // The first stream's zstd magic number, after the header and the table of 5 entries.
    let mut corrupt = good.clone();
    corrupt[32 + 5 * 16] ^= 0xff;
    assert!(message(&corrupt).contains("stream 0:"), "{}", message(&corrupt));
    assert!(message(&good[..20]).contains("end inside the 32-byte header"));
}

#[test]
fn garbage_is_an_error() {
    assert!(matches!(gaussians_from_spz_bytes(b"", SpzAxes::Rub), Err(SplatFileProblem::NotSpz)));
    assert!(matches!(gaussians_from_spz_bytes(b"ply\nformat", SpzAxes::Rub), Err(SplatFileProblem::NotSpz)));
    let mut rng = SplitMix64(1);
    for len in [2, 10, 100, 1000] {
        let mut bytes: Vec<u8> = (0..len).map(|_| rng.next_u64() as u8).collect();
        bytes[..2].copy_from_slice(&[0x1f, 0x8b]);
        let err = gaussians_from_spz_bytes(&bytes, SpzAxes::Rub).unwrap_err();
        assert!(matches!(err, SplatFileProblem::Gzip(_)), "{len}: {err}");
    }
}

/// Random byte changes in the compressed file and in the decompressed data (header included)
/// must give either an error or consistent, finite Gaussians; never a panic.
#[test]
fn corrupt_files_never_panic() {
    let g = random_gaussians(&mut SplitMix64(4), 5, 2, [-3.0, -1.0]);
    let mut rng = SplitMix64(77);
    let (mut accepted, mut rejected) = (0, 0);
    for version in [SpzVersion::V2, SpzVersion::V3] {
        let bytes = gaussians_to_spz_bytes(&g, version);
        let raw = gunzip(&bytes);
        for trial in 0..400 {
            let mut corrupt = if trial % 2 == 0 { bytes.clone() } else { raw.clone() };
            for _ in 0..1 + rng.next_u64() % 3 {
                let at = (rng.next_u64() % corrupt.len() as u64) as usize;
                corrupt[at] = rng.next_u64() as u8;
            }
            let corrupt = if trial % 2 == 0 { corrupt } else { gzip(&corrupt) };
            match gaussians_from_spz_bytes(&corrupt, SpzAxes::Rub) {
                Ok(back) => {
                    accepted += 1;
                    assert!(back.is_consistent());
                    let floats = back.means.iter().flatten().chain(back.log_scales.iter().flatten());
                    let floats = floats.chain(back.rotations.iter().flatten()).chain(&back.opacity_logits);
                    assert!(floats.chain(&back.sh).all(|v| v.is_finite()));
                }
                Err(_) => rejected += 1,
            }
        }
    }
    assert!(accepted > 0 && rejected > 0, "{accepted} accepted, {rejected} rejected");
}

#[test]
fn degree_four_loses_its_fourth_band_and_empty_files_are_empty() {
    let g = random_gaussians(&mut SplitMix64(8), 4, 3, [-3.0, -1.0]);
    let bytes = gaussians_to_spz_bytes(&g, SpzVersion::V3);
    let degree3 = gaussians_from_spz_bytes(&bytes, SpzAxes::Rub).unwrap();
    let raw = gunzip(&bytes);
    let (sh_start, per_point) = (HEADER_BYTES + 4 * (9 + 1 + 3 + 3 + 4), 45);
    let mut degree4 = raw[..sh_start].to_vec();
    degree4[12] = 4;
    for point in raw[sh_start..].chunks(per_point) {
        degree4.extend_from_slice(point);
        degree4.extend_from_slice(&[200; 27]);
    }
    assert_eq!(gaussians_from_spz_bytes(&gzip(&degree4), SpzAxes::Rub).unwrap(), degree3);

    let empty =
        gaussians_from_spz_bytes(&gaussians_to_spz_bytes(&Gaussians::with_degree(2), SpzVersion::V2), SpzAxes::Rub)
            .unwrap();
    assert!(empty.is_empty() && empty.sh_degree == 2);
}

#[test]
fn the_writer_chooses_fractional_bits_that_fit() {
    let mut g = random_gaussians(&mut SplitMix64(6), 3, 0, [-3.0, -1.0]);
    g.means[1] = [5000.0, -3000.0, 0.25];
    let bytes = gaussians_to_spz_bytes(&g, SpzVersion::V3);
    assert_eq!(gunzip(&bytes)[13], 10, "2^10 * 5000 fits 24 bits, 2^11 * 5000 does not");
    let back = gaussians_from_spz_bytes(&bytes, SpzAxes::Rub).unwrap();
    assert_close(&back.means[1], &g.means[1], 0.5 / 1024.0);
}

/// A gzip stream of `raw` followed by `zeros` zero bytes, compressed as far as gzip goes.
fn gzip_with_zeros(raw: &[u8], zeros: usize) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    encoder.write_all(raw).unwrap();
    let block = vec![0u8; 1 << 20];
    for start in (0..zeros).step_by(block.len()) {
        encoder.write_all(&block[..block.len().min(zeros - start)]).unwrap();
    }
    encoder.finish().unwrap()
}

#[test]
fn decompression_bombs_are_refused_before_they_are_inflated() {
    // 53 million points of degree 0 (1.06 GB of data; 64 MiB of it here, in 65 KB).
    let bomb = gzip_with_zeros(&header(3, 53_000_000, 0, 0), 64 << 20);
    let err = gaussians_from_spz_bytes(&bomb, SpzAxes::Rub).unwrap_err();
    assert!(matches!(err, SplatFileProblem::TooManyPoints { points: 53_000_000, limit: 16_777_216 }), "{err}");
    // 4 million points, fewer than a stream holds, whose 84 MB of data is all there: zeros,
    // which gzip shrinks 1000 times. Refused from the header, against the file's size.
    let points = 1u32 << 22;
    let needed = 20 * u64::from(points);
    let bomb = gzip_with_zeros(&header(3, points, 0, 0), needed as usize);
    let file_bytes = bomb.len() as u64;
    assert!(file_bytes < 100_000, "{file_bytes} bytes");
    let err = gaussians_from_spz_bytes(&bomb, SpzAxes::Rub).unwrap_err();
    let limit = 32 * file_bytes + (1 << 20);
    assert!(
        matches!(err, SplatFileProblem::TooLarge { points: p, needed: n, limit: l, file_bytes: f }
            if p == points && n == needed && l == limit && f == file_bytes),
        "{err}"
    );
    // Version 4: the same counts in its plain header, the streams never opened.
    let v4 = |points: u32| [b"NGSP".as_slice(), &4u32.to_le_bytes(), &points.to_le_bytes(), &[0; 20]].concat();
    let err = gaussians_from_spz_bytes(&v4(53_000_000), SpzAxes::Rub).unwrap_err().to_string();
    assert!(err.contains("53000000 points, more than the 16777216"), "{err}");
    let err = gaussians_from_spz_bytes(&v4(1 << 24), SpzAxes::Rub).unwrap_err().to_string();
    assert!(
        err.contains("which need 335544320 bytes of data, more than the 1049600-byte limit for a 32-byte"),
        "{err}"
    );
}

#[test]
fn repetitive_files_within_the_allowance_are_read() {
    // 50,000 identical points: 1 MB of data from about 1 KB, within the allowance.
    let g = random_gaussians(&mut SplitMix64(12), 1, 0, [-3.0, -1.0]);
    let raw = gunzip(&gaussians_to_spz_bytes(&g, SpzVersion::V3));
    let n = 50_000;
    let mut many = header(3, n as u32, 0, 0);
    many[13] = raw[13];
    for (offset, size) in [(16, 9), (25, 1), (26, 3), (29, 3), (32, 4)] {
        many.extend(raw[offset..offset + size].repeat(n));
    }
    let bytes = gzip_with_zeros(&many, 0);
    assert!(bytes.len() < 10_000, "{} bytes", bytes.len());
    let back = gaussians_from_spz_bytes(&bytes, SpzAxes::Rub).unwrap();
    assert_eq!(back.len(), n);
    assert_eq!(back.means[n - 1], gaussians_from_spz_bytes(&gzip(&raw), SpzAxes::Rub).unwrap().means[0]);
    // Data past what the header needs is read no further than one byte past it.
    let trailing = gzip_with_zeros(&raw, 16 << 20);
    let err = gaussians_from_spz_bytes(&trailing, SpzAxes::Rub).unwrap_err();
    assert!(matches!(err, SplatFileProblem::TrailingData { points: 1 }), "{err}");
}

//! Class 4, decompression bombs in the splat-file importers (`pwenc --from`): SPZ files whose
//! header claims more points than a stream holds or than the file can plausibly carry, compressed
//! as far as gzip and zstd go; SOG archives whose lossless WebPs declare huge images in 34 bytes,
//! whose zip entries all point at one deflated payload, or whose `meta.json` claims more
//! Gaussians than a stream holds; and one SOG laid out as PlayCanvas's writer lays it out, which
//! must import. Every compressed stream is written here bit by bit (deflate, zstd frames, VP8L,
//! zip), so the bytes depend on no compressor's version, and each would decode to what it claims
//! if a reader did not refuse it first.

use pwgs_core::random::SplitMix64;
use serde_json::json;

use super::{Hostile, HostileEntry, Outcome, Tool};

/// SPZ's header magic, `NGSP`.
const SPZ_MAGIC: &[u8; 4] = b"NGSP";
/// Bytes per point of SPZ version 3 (and 4) data of SH degree 0: position 9, alpha 1, color 3,
/// scale 3, rotation 4.
const SPZ_V3_POINT_BYTES: u64 = 20;
/// Points the original report's files claimed, three times what a pwgs stream holds.
const CLAIMED_POINTS: u32 = 53_000_000;
/// As many points as a pwgs stream holds (2^24).
const STREAM_POINTS: u32 = 1 << 24;
/// The SOG images every version-2 file has.
const TEXTURES: [&str; 5] = ["means_l.webp", "means_u.webp", "quats.webp", "scales.webp", "sh0.webp"];

pub fn files() -> Vec<Hostile> {
    let v3_full = STREAM_POINTS as u64 * SPZ_V3_POINT_BYTES;
    vec![
        refused(
            "spz-v3-53m-points.spz",
            gzip(&spz_v3_header(CLAIMED_POINTS), 16 << 20),
            "53000000 points, more than the 16777216",
            "SPZ version 3 (gzip) whose header claims 53,000,000 points of SH degree 0 (1.06 GB of data), followed \
             by 16 MiB of zero data in 16 KB: refused from the header before anything is inflated",
        ),
        refused(
            "spz-v3-16m-points-zeros.spz",
            gzip(&spz_v3_header(STREAM_POINTS), v3_full),
            "which need 335544320 bytes of data, more than the",
            "SPZ version 3 of 2^24 identical points (as many as a stream holds), all 335 MB of their data present as \
             zeros that gzip carries in 325 KB; decoded it would take 1.3 GB: refused from the header, as more data \
             than a file of this size may decompress to",
        ),
        refused(
            "spz-v3-short-data.spz",
            gzip(&spz_v3_header(50_000), 64 << 10),
            "which need 1000000 bytes of data, but the data holds 65536",
            "SPZ version 3 whose header claims 50,000 points (within every limit) but whose gzip stream ends after \
             64 KiB of their data: refused once the data ends",
        ),
        refused(
            "spz-v4-53m-points.spz",
            spz_v4(CLAIMED_POINTS),
            "53000000 points, more than the 16777216",
            "SPZ version 4 whose header claims 53,000,000 points, its five zstd streams all present as RLE blocks \
             of zeros (1.06 GB in 32 KB): refused from the plain header before any stream is opened",
        ),
        refused(
            "spz-v4-16m-points-zeros.spz",
            spz_v4(STREAM_POINTS),
            "which need 335544320 bytes of data, more than the",
            "SPZ version 4 of 2^24 identical points, 335 MB of zero data in 10 KB of zstd RLE blocks: refused from \
             the header, as more data than a file of this size may decompress to",
        ),
        refused(
            "sog-webp-16383.sog",
            sog(1000, 16383),
            "16383x16383 pixels for 1000 Gaussians: more than the 4096",
            "SOG of 1,000 Gaussians whose five lossless WebPs are 34 bytes each and declare 16383 x 16383 pixels \
             (1 GiB of RGBA each, single-symbol prefix codes): refused from the image headers before any pixel \
             is decoded",
        ),
        refused(
            "sog-webp-4096-16m.sog",
            sog(STREAM_POINTS as usize, 4096),
            "decode to 67108864 bytes, more than the",
            "SOG of 2^24 Gaussians (as many as a stream holds) in five uniform 4096 x 4096 lossless WebPs of 34 \
             bytes each: 320 MiB of pixels and 0.9 GB of Gaussians from 5 KB, refused from the image headers as \
             more pixels than an input of this size may decode to",
        ),
        refused(
            "sog-zip-overlapping.sog",
            overlapping_zip(),
            "means_l.webp: more than 81920 bytes",
            "SOG zip whose central directory holds 505 entries (the five images meta.json names and 500 it does \
             not) that all point at one deflated payload of 64 MiB of zeros: only the named entries are opened, \
             and the first stops at the size a WebP of 1,000 Gaussians' pixels may have",
        ),
        refused(
            "sog-count-over-limit.sog",
            sog(STREAM_POINTS as usize + 1, 4),
            "count 16777217 is more than the 16777216",
            "SOG whose meta.json claims 2^24 + 1 Gaussians, one more than a stream holds: refused before any \
             image is read",
        ),
        hostile(
            "sog-playcanvas-layout.sog",
            playcanvas_sog(100),
            Outcome::Accepted,
            "SOG of 100 Gaussians with SH degree 1 laid out as PlayCanvas's writer lays it out (12 x 12 images, \
             both sides rounded up to a multiple of 4; a 192 x 2 palette of 100 entries): within every bound, \
             imported",
        ),
    ]
}

fn refused(file: &str, bytes: Vec<u8>, error: &str, description: &str) -> Hostile {
    hostile(file, bytes, Outcome::Refused(error.to_string()), description)
}

fn hostile(file: &str, bytes: Vec<u8>, outcome: Outcome, description: &str) -> Hostile {
    let entry =
        HostileEntry { class: 4, tool: Tool::PwencFrom, view: None, outcome, description: description.to_string() };
    Hostile { file: file.to_string(), entry, bytes }
}

/// The 16-byte SPZ version 3 header of `points` points of SH degree 0, 12 fractional bits.
fn spz_v3_header(points: u32) -> Vec<u8> {
    [SPZ_MAGIC.as_slice(), &3u32.to_le_bytes(), &points.to_le_bytes(), &[0, 12, 0, 0]].concat()
}

/// An SPZ version 4 file of `points` points of SH degree 0, all zero (a valid point each): the
/// 32-byte header, the table of contents, and each attribute block as a zstd frame.
fn spz_v4(points: u32) -> Vec<u8> {
    let n = u64::from(points);
    let frames: Vec<(u64, Vec<u8>)> = [9 * n, n, 3 * n, 3 * n, 4 * n].map(|size| (size, zstd_zeros(size))).into();
    let mut out = spz_v3_header(points);
    out[4..8].copy_from_slice(&4u32.to_le_bytes());
    out[15] = frames.len() as u8;
    out.extend_from_slice(&32u32.to_le_bytes());
    out.resize(32, 0);
    for (size, frame) in &frames {
        out.extend_from_slice(&(frame.len() as u64).to_le_bytes());
        out.extend_from_slice(&size.to_le_bytes());
    }
    frames.iter().for_each(|(_, frame)| out.extend_from_slice(frame));
    out
}

/// A zstd frame (RFC 8878) of `size` zero bytes: RLE blocks of 128 KiB, each 4 bytes.
fn zstd_zeros(size: u64) -> Vec<u8> {
    const BLOCK: u64 = 128 << 10;
    // Magic; 8-byte content size, not single-segment; a 128 KiB window (2^(10 + 7)).
    let mut out = [0x28, 0xb5, 0x2f, 0xfd, 0xc0, 7 << 3].to_vec();
    out.extend_from_slice(&size.to_le_bytes());
    let blocks = size.div_ceil(BLOCK).max(1);
    for k in 0..blocks {
        let len = (size - k * BLOCK).min(BLOCK);
        let (last, rle) = (u32::from(k + 1 == blocks), u32::from(len > 0));
        out.extend_from_slice(&(last | rle << 1 | (len as u32) << 3).to_le_bytes()[..3]);
        if len > 0 {
            out.push(0);
        }
    }
    out
}

/// Bits written least significant first, as deflate and VP8L pack them.
#[derive(Default)]
struct Bits {
    bytes: Vec<u8>,
    pending: u64,
    count: u32,
}

impl Bits {
    /// The `n <= 32` low bits of `value`.
    fn put(&mut self, value: u64, n: u32) {
        self.pending |= value << self.count;
        self.count += n;
        while self.count >= 8 {
            self.bytes.push(self.pending as u8);
            self.pending >>= 8;
            self.count -= 8;
        }
    }

    /// A deflate prefix code of `len` bits, which is packed most significant bit first.
    fn code(&mut self, code: u64, len: u32) {
        (0..len).rev().for_each(|i| self.put(code >> i & 1, 1));
    }

    fn finish(mut self) -> Vec<u8> {
        if self.count > 0 {
            self.bytes.push(self.pending as u8);
        }
        self.bytes
    }
}

/// Raw deflate (RFC 1951) of `prefix` then `zeros >= 1` zero bytes: the prefix as a stored block,
/// then one block of dynamic codes that give the length-258 match 1 bit and distance 1 another,
/// so every 258 zeros take 2 bits (1:1032, as far as deflate goes).
fn deflate(prefix: &[u8], zeros: u64) -> Vec<u8> {
    let mut bits = Bits::default();
    if !prefix.is_empty() {
        bits.put(0, 8); // not the last block, stored (3 bits), padded to a byte boundary
        bits.put(prefix.len() as u64, 16);
        bits.put(!prefix.len() as u64 & 0xffff, 16);
        prefix.iter().for_each(|&b| bits.put(u64::from(b), 8));
    }
    bits.put(1 | 2 << 1, 3); // the last block, dynamic codes
    bits.put(286 - 257, 5); // literal/length codes 0 to 285
    bits.put(2 - 1, 5); // distance codes 0 and 1
    bits.put(18 - 4, 4); // code-length code lengths, in the order 16 17 18 0 8 7 9 6 10 5 11 4 12 3 13 2 14 1
    [0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 2].iter().for_each(|&len| bits.put(len, 3));
    // Code lengths with the code-length codes 18 -> 0, 1 -> 10, 2 -> 11: literal 0 gets 2 bits,
    // 1 to 255 none, end of block 2, 257 to 284 none, 285 (length 258) 1; both distances 1.
    let (one, two) = (|b: &mut Bits| b.code(0b10, 2), |b: &mut Bits| b.code(0b11, 2));
    let zero_run = |b: &mut Bits, run: u64| {
        b.code(0, 1);
        b.put(run - 11, 7);
    };
    two(&mut bits);
    zero_run(&mut bits, 138);
    zero_run(&mut bits, 117);
    two(&mut bits);
    zero_run(&mut bits, 28);
    (0..3).for_each(|_| one(&mut bits));
    // Canonical codes: 285 -> 0, literal 0 -> 10, end of block -> 11; distance 1 -> 0.
    let matches = (zeros - 1) / 258;
    bits.code(0b10, 2);
    let mut match_bits = 2 * matches;
    while match_bits > 0 {
        let n = match_bits.min(32);
        bits.put(0, n as u32);
        match_bits -= n;
    }
    (0..(zeros - 1) % 258).for_each(|_| bits.code(0b10, 2));
    bits.code(0b11, 2);
    bits.finish()
}

/// The CRC-32 of `prefix` then `zeros` zero bytes.
fn crc32(prefix: &[u8], zeros: u64) -> u32 {
    let mut crc = flate2::Crc::new();
    crc.update(prefix);
    let block = vec![0u8; 1 << 20];
    let mut left = zeros;
    while left > 0 {
        let n = left.min(block.len() as u64);
        crc.update(&block[..n as usize]);
        left -= n;
    }
    crc.sum()
}

/// A gzip file (RFC 1952) of `prefix` then `zeros` zero bytes.
fn gzip(prefix: &[u8], zeros: u64) -> Vec<u8> {
    let mut out = vec![0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 255];
    out.extend(deflate(prefix, zeros));
    out.extend_from_slice(&crc32(prefix, zeros).to_le_bytes());
    out.extend_from_slice(&((prefix.len() as u64 + zeros) as u32).to_le_bytes());
    out
}

/// A lossless WebP (VP8L, RFC 9649) of `width` x `height` pixels all `rgba`: five prefix codes of
/// a single symbol each, so the pixels take no bits and the file is 34 bytes whatever its size.
fn uniform_webp(width: u32, height: u32, [r, g, b, a]: [u8; 4]) -> Vec<u8> {
    let mut bits = Bits::default();
    bits.put(0x2f, 8);
    bits.put(u64::from(width - 1), 14);
    bits.put(u64::from(height - 1), 14);
    bits.put(1, 4); // alpha is used; version 0
    bits.put(0, 3); // no transform, no color cache, no meta prefix codes
    for symbol in [g, r, b, a, 0] {
        bits.put(0b101, 3); // a simple code of one symbol, stored in 8 bits
        bits.put(u64::from(symbol), 8);
    }
    riff_webp(&bits.finish())
}

/// A VP8L bitstream in its RIFF container.
fn riff_webp(vp8l: &[u8]) -> Vec<u8> {
    let mut chunk = [b"VP8L".as_slice(), &(vp8l.len() as u32).to_le_bytes(), vp8l].concat();
    chunk.resize(chunk.len().next_multiple_of(2), 0);
    [b"RIFF".as_slice(), &(4 + chunk.len() as u32).to_le_bytes(), b"WEBP", &chunk].concat()
}

/// A version-2 `meta.json` of `count` Gaussians of SH degree 0 with 256-entry codebooks.
fn meta_json(count: usize) -> serde_json::Value {
    let codebook: Vec<f64> = (0..256).map(|k| (k as f64 - 128.0) / 64.0).collect();
    json!({
        "version": 2, "count": count,
        "means": {"mins": [-1.0, -1.0, -1.0], "maxs": [1.0, 1.0, 1.0], "files": ["means_l.webp", "means_u.webp"]},
        "scales": {"codebook": codebook.iter().map(|v| v - 4.0).collect::<Vec<_>>(), "files": ["scales.webp"]},
        "quats": {"files": ["quats.webp"]},
        "sh0": {"codebook": codebook, "files": ["sh0.webp"]},
    })
}

/// A SOG zip of `count` identical Gaussians whose images are uniform, `side` x `side` pixels.
fn sog(count: usize, side: u32) -> Vec<u8> {
    let meta = serde_json::to_vec(&meta_json(count)).expect("JSON values serialize");
    let mut files = vec![("meta.json".to_string(), meta)];
    for name in TEXTURES {
        let tag = if name == "quats.webp" { 252 } else { 255 };
        files.push((name.to_string(), uniform_webp(side, side, [128, 128, 128, tag])));
    }
    stored_zip(&files)
}

/// One file of a zip archive, as its local header and data hold it.
struct ZipPayload {
    name: String,
    /// 0 stored, 8 deflated.
    method: u16,
    crc: u32,
    size: u64,
    data: Vec<u8>,
}

/// A zip archive of `payloads`, whose central directory lists each `(name, payload)`: names
/// may differ from the payload's own, and several may point at one payload.
fn zip(payloads: &[ZipPayload], directory: &[(String, usize)]) -> Vec<u8> {
    /// Version 2.0; no flags; the method; 1980-01-01 00:00; CRC and sizes; name and no extra.
    fn fields(out: &mut Vec<u8>, p: &ZipPayload, name: &str) {
        for v in [20, 0, p.method, 0, 0x21] {
            out.extend_from_slice(&u16::to_le_bytes(v));
        }
        for v in [p.crc, p.data.len() as u32, p.size as u32] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&(name.len() as u16).to_le_bytes());
        out.extend_from_slice(&0u16.to_le_bytes());
    }
    let mut out = Vec::new();
    let mut offsets = Vec::new();
    for p in payloads {
        offsets.push(out.len() as u32);
        out.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        fields(&mut out, p, &p.name);
        out.extend_from_slice(p.name.as_bytes());
        out.extend_from_slice(&p.data);
    }
    let start = out.len();
    for (name, index) in directory {
        out.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        out.extend_from_slice(&20u16.to_le_bytes()); // made by version 2.0
        fields(&mut out, &payloads[*index], name);
        out.extend_from_slice(&[0; 10]); // no comment, disk 0, no attributes
        out.extend_from_slice(&offsets[*index].to_le_bytes());
        out.extend_from_slice(name.as_bytes());
    }
    let (entries, directory_bytes) = ((directory.len() as u16).to_le_bytes(), (out.len() - start) as u32);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    out.extend_from_slice(&[0, 0, 0, 0, entries[0], entries[1], entries[0], entries[1]]);
    out.extend_from_slice(&directory_bytes.to_le_bytes());
    out.extend_from_slice(&(start as u32).to_le_bytes());
    out.extend_from_slice(&[0, 0]);
    out
}

/// A zip of `files`, each stored and listed once (as PlayCanvas's writer stores a SOG).
pub(super) fn stored_zip(files: &[(String, Vec<u8>)]) -> Vec<u8> {
    let payloads: Vec<ZipPayload> = files
        .iter()
        .map(|(name, data)| ZipPayload {
            name: name.clone(),
            method: 0,
            crc: crc32(data, 0),
            size: data.len() as u64,
            data: data.clone(),
        })
        .collect();
    let directory: Vec<(String, usize)> = files.iter().enumerate().map(|(i, (name, _))| (name.clone(), i)).collect();
    zip(&payloads, &directory)
}

/// A SOG of 1,000 Gaussians whose images, and 500 entries nobody names, are all one deflated
/// payload of 64 MiB of zeros.
fn overlapping_zip() -> Vec<u8> {
    const ZEROS: u64 = 64 << 20;
    let meta = serde_json::to_vec(&meta_json(1000)).expect("JSON values serialize");
    let payloads = [
        ZipPayload { name: "meta.json".into(), method: 0, crc: crc32(&meta, 0), size: meta.len() as u64, data: meta },
        ZipPayload {
            name: TEXTURES[0].into(),
            method: 8,
            crc: crc32(&[], ZEROS),
            size: ZEROS,
            data: deflate(&[], ZEROS),
        },
    ];
    let mut directory = vec![("meta.json".to_string(), 0)];
    directory.extend(TEXTURES.iter().map(|name| (name.to_string(), 1)));
    directory.extend((0..500).map(|k| (format!("unused-{k:03}.webp"), 1)));
    zip(&payloads, &directory)
}

/// A SOG of `count` Gaussians of SH degree 1 with varied values, in images sized as
/// PlayCanvas's writer sizes them: width the square root rounded up to a multiple of 4, height
/// the rows that need rounded up to a multiple of 4, the palette 64 entries to a row.
fn playcanvas_sog(count: usize) -> Vec<u8> {
    let width = ((count as f64).sqrt() / 4.0).ceil() as u32 * 4;
    let height = (count as f64 / f64::from(width) / 4.0).ceil() as u32 * 4;
    let mut rng = SplitMix64(46);
    // Random red, green and blue; alpha from the pixel's index and a random byte.
    let mut image = |alpha: fn(usize, u8) -> u8| {
        let mut pixels = vec![0u8; (width * height * 4) as usize];
        for (i, pixel) in pixels.chunks_mut(4).take(count).enumerate() {
            let [r, g, b, a, ..] = rng.next_u64().to_le_bytes();
            pixel.copy_from_slice(&[r, g, b, alpha(i, a)]);
        }
        webp(&pixels, width, height)
    };
    let opaque: fn(usize, u8) -> u8 = |_, _| 255;
    let mut files = vec![
        ("means_l.webp".to_string(), image(opaque)),
        ("means_u.webp".to_string(), image(opaque)),
        ("quats.webp".to_string(), image(|i, _| 252 + (i % 4) as u8)),
        ("scales.webp".to_string(), image(opaque)),
        ("sh0.webp".to_string(), image(|_, a| 128 + a / 2)),
    ];
    let rows = count.div_ceil(64) as u32;
    let mut centroids = vec![255u8; (64 * 3 * rows * 4) as usize];
    let mut rng = SplitMix64(47);
    centroids.chunks_mut(4).for_each(|p| p[..3].copy_from_slice(&[0, 1, 2].map(|_| rng.next_u64() as u8)));
    files.push(("shN_centroids.webp".to_string(), webp(&centroids, 64 * 3, rows)));
    let mut labels = vec![255u8; (width * height * 4) as usize];
    for (i, pixel) in labels.chunks_mut(4).take(count).enumerate() {
        pixel[..3].copy_from_slice(&[(i * 37 % count) as u8, 0, 0]);
    }
    files.push(("shN_labels.webp".to_string(), webp(&labels, width, height)));
    let mut meta = meta_json(count);
    let codebook: Vec<f64> = (0..256).map(|k| (k as f64 - 128.0) / 256.0).collect();
    meta["shN"] = json!({"count": count, "bands": 1, "codebook": codebook,
        "files": ["shN_centroids.webp", "shN_labels.webp"]});
    files.insert(0, ("meta.json".to_string(), serde_json::to_vec(&meta).expect("JSON values serialize")));
    stored_zip(&files)
}

/// `rgba` (`width` x `height` pixels) as a lossless WebP by the image crate's encoder.
fn webp(rgba: &[u8], width: u32, height: u32) -> Vec<u8> {
    let mut out = Vec::new();
    image::codecs::webp::WebPEncoder::new_lossless(&mut out)
        .encode(rgba, width, height, image::ExtendedColorType::Rgba8)
        .expect("encoding to memory cannot fail");
    out
}

#[cfg(test)]
mod tests {
    use std::io::Read;

    use pwgs_core::splat_file::{SpzAxes, gaussians_from_sog_bytes, gaussians_from_spz_bytes};

    use super::*;

    /// Each file gives its outcome when read as `pwenc --from` reads it, and is at most 1 MiB.
    #[test]
    fn the_readers_give_each_files_outcome() {
        for h in files() {
            assert!(h.bytes.len() <= 1 << 20, "{}: {} bytes", h.file, h.bytes.len());
            let read = match h.file.ends_with(".sog") {
                true => gaussians_from_sog_bytes(&h.bytes),
                false => gaussians_from_spz_bytes(&h.bytes, SpzAxes::Rub),
            };
            match (&h.entry.outcome, read) {
                (Outcome::Refused(error), Err(e)) => assert!(e.to_string().contains(error.as_str()), "{}: {e}", h.file),
                (Outcome::Accepted, Ok(g)) => assert_eq!(g.len(), 100, "{}", h.file),
                (outcome, read) => panic!("{}: {outcome:?} expected, read {:?}", h.file, read.map(|g| g.len())),
            }
        }
    }

    /// The bombs are what they claim: the gzip streams inflate to the header and the zeros with
    /// a matching CRC, the zstd frames to the attribute blocks, the WebPs to their pixels.
    #[test]
    fn the_hand_written_streams_decode() {
        let inflated = |bytes: &[u8]| {
            let mut head = Vec::new();
            let mut gz = flate2::read::GzDecoder::new(bytes);
            gz.by_ref().take(16).read_to_end(&mut head).unwrap();
            (head, std::io::copy(&mut gz, &mut std::io::sink()).unwrap())
        };
        assert_eq!(inflated(&gzip(&spz_v3_header(7), 16 << 20)), (spz_v3_header(7), 16 << 20));
        assert_eq!(inflated(&gzip(&[], 259 * 3)), (vec![0; 16], 259 * 3 - 16));

        let v4 = spz_v4(1_000_000);
        let mut at = 32 + 5 * 16;
        for (k, size) in [9, 1, 3, 3, 4].map(|per_point| per_point * 1_000_000u64).into_iter().enumerate() {
            let compressed = u64::from_le_bytes(v4[32 + 16 * k..][..8].try_into().unwrap()) as usize;
            let mut frame = zstd::stream::read::Decoder::new(&v4[at..at + compressed]).unwrap();
            assert_eq!(std::io::copy(&mut frame, &mut std::io::sink()).unwrap(), size);
            at += compressed;
        }
        assert_eq!(at, v4.len());

        let webp = uniform_webp(4096, 4096, [1, 2, 3, 252]);
        let image = image::load_from_memory_with_format(&webp, image::ImageFormat::WebP).unwrap().into_rgba8();
        assert!(image.dimensions() == (4096, 4096) && image.pixels().all(|p| p.0 == [1, 2, 3, 252]));
    }
}

//! Niantic's `.spz` format, versions 2 to 4: in versions 2 and 3 one gzip stream holding a
//! 16-byte header and the quantized attributes, each attribute stored for all points before the
//! next begins; in version 4 a plain header and each attribute block as its own zstd stream
//! (see [`unpack_v4`]), the blocks' contents as in version 3.
//!
//! Header (little-endian): magic `0x5053474e` ("NGSP"), version u32, point count u32, SH
//! degree u8 (0 to 4), fractional bits u8, flags u8 (0x1: trained with antialiasing, 0x2:
//! extension records follow the data), one reserved byte. Then, per point and in this order
//! of blocks: position 3 x 24-bit signed fixed point (`value / 2^fractional_bits`); opacity u8
//! (`A / 255`); color 3 x u8 (`(C / 255 - 0.5) / 0.15` is the SH DC term: a scale smaller than
//! the SH constant, so that colors somewhat outside [0, 1] survive); log-scale 3 x u8
//! (`S / 16 - 10`); rotation, in version 2 three u8 `(x, y, z) = B / 127.5 - 1` with `w >= 0`
//! derived from the unit norm, in version 3 "smallest three": a little-endian u32 whose top
//! two bits index the largest of (x, y, z, w), derived from the unit norm, and whose 30 low
//! bits hold the other three, first component highest, each as a sign bit and a 9-bit
//! magnitude of `|q| / sqrt(1/2) * 511`; and SH coefficients beyond the DC as u8
//! `(B - 128) / 128`, coefficient-major with the color channel fastest.
//!
//! Axes: SPZ stores its data in the RUB convention of OpenGL and three.js (x right, y up, z
//! back), where the INRIA PLY and the rest of this project use RDF (x right, y down, z
//! forward). The two differ by a rotation of 180 degrees about x, which the reader applies:
//! y and z of positions negated, the quaternion conjugated accordingly (its y and z negated),
//! and each SH coefficient negated when its basis function is odd in y and z together. An
//! `SPZ_ADOBE_coordinate_system` extension record (type 0xADBE0003) names another storage
//! convention; the axis-flip ones (codes 1 to 8) are converted the same way, the rotated ones
//! (9 to 16) are refused. Files written before the public library declared RUB (late 2024)
//! may hold RDF data unmarked, and PlayCanvas's splat-transform (3.7.0) still writes the PLY's
//! axes unconverted and unmarked: nothing in such a file tells it from a RUB one, so the axes
//! of unmarked files are the caller's choice ([`SpzAxes`]), RUB by default as the format says.
//!
//! Not supported: version 1 (float16 positions, never released), the rotated-family coordinate
//! systems.
//! The antialiasing flag is ignored: this project renders without the mip-splatting filter, so
//! such a model looks slightly sharper here than in a viewer that applies it. SH degree 4
//! files lose their fourth band, which this project does not carry (its maximum is degree 3).

use std::io::{Read, Write};

use super::{MAX_IMPORTED_POINTS, SplatFileProblem, decompressed_limit};
use crate::gaussians::{Gaussians, MAX_SH_DEGREE, sh_coeff_count};

/// Decompressed data beyond this many bytes is refused, before anything is allocated for it:
/// about 11 million points of degree 3, larger than any scene this project compresses.
pub const SPZ_MAX_DECOMPRESSED_BYTES: u64 = 1 << 30;

const MAGIC: u32 = 0x5053_474e;
const HEADER_BYTES: usize = 16;
const FLAG_EXTENSIONS: u8 = 0x2;
/// Extension records are small metadata (camera limits, an axis convention); a megabyte is far
/// beyond any defined one, and bounds what a hostile file can make the reader hold.
const MAX_EXTENSION_BYTES: u64 = 1 << 20;
const EXTENSION_COORDINATE_SYSTEM: u32 = 0xADBE_0003;
/// SPZ's coordinate-system codes: 1 to 8 spell the axis directions, with bit 0 of `code - 1`
/// meaning x points right, bit 1 y up, bit 2 z forward.
const RUB: u32 = 4;
const RDF: u32 = 6;
const COLOR_SCALE: f32 = 0.15;
const SQRT_HALF: f32 = std::f32::consts::FRAC_1_SQRT_2;
/// Opacities are kept half a quantization step inside (0, 1) so that the bytes 0 and 255 give
/// finite logits; the shift is within the 8-bit storage's own error.
const ALPHA_MIN: f32 = 0.5 / 255.0;
/// Per SH coefficient k = 1..=15 (3DGS order), the axes in which its basis function is odd
/// (bit 0: x, bit 1: y, bit 2: z); reflecting those axes negates the coefficient.
const SH_ODD_AXES: [u8; 15] = [2, 4, 1, 3, 6, 0, 5, 0, 2, 7, 2, 4, 1, 4, 1];

/// The axes an SPZ file is taken to store when no coordinate-system record names them (or
/// the record says "unspecified").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum SpzAxes {
    /// RUB (x right, y up, z back): what the format specifies and Niantic's library writes.
    #[default]
    Rub,
    /// RDF (x right, y down, z forward): an INRIA PLY's own axes, which PlayCanvas's
    /// splat-transform (3.7.0) and files older than late 2024 store unconverted.
    Rdf,
}

impl SpzAxes {
    /// The SPZ coordinate-system code of these axes.
    fn code(self) -> u32 {
        match self {
            Self::Rub => RUB,
            Self::Rdf => RDF,
        }
    }
}

/// The SPZ versions [`gaussians_to_spz_bytes`] can write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpzVersion {
    /// Rotations as three bytes (x, y, z) with w derived: coarse when w is small.
    V2,
    /// Rotations as "smallest three" in four bytes: about 1e-3 per component everywhere.
    V3,
}

/// Sign flips that convert between SPZ's stored axes and RDF; each is its own inverse.
#[derive(Debug, Clone, Copy)]
struct AxisFlips([f32; 3]);

impl AxisFlips {
    fn from_stored(code: u32) -> Result<Self, SplatFileProblem> {
        if !(1..=8).contains(&code) {
            return Err(SplatFileProblem::CoordinateSystem(code));
        }
        let bits = code - 1;
        let sign = |flip: bool| if flip { -1.0 } else { 1.0 };
        Ok(Self([sign(bits & 1 == 0), sign(bits & 2 != 0), sign(bits & 4 == 0)]))
    }

    fn position(self, p: [f32; 3]) -> [f32; 3] {
        [p[0] * self.0[0], p[1] * self.0[1], p[2] * self.0[2]]
    }

    /// A rotation conjugated by the reflection: each vector component is multiplied by the
    /// product of the two other axes' signs, w is kept (the result is again a rotation).
    fn quaternion(self, [w, x, y, z]: [f32; 4]) -> [f32; 4] {
        let [fx, fy, fz] = self.0;
        [w, x * fy * fz, y * fx * fz, z * fx * fy]
    }

    /// The sign of SH coefficient `k >= 1`.
    fn sh_sign(self, k: usize) -> f32 {
        (0..3).filter(|&axis| SH_ODD_AXES[k - 1] >> axis & 1 != 0).map(|axis| self.0[axis]).product()
    }
}

fn rotation_bytes(version: u32) -> usize {
    if version >= 3 { 4 } else { 3 }
}

/// SH coefficients per channel beyond the DC term.
fn sh_rest(degree: u32) -> usize {
    sh_coeff_count(degree) - 1
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn read_up_to(reader: &mut impl Read, limit: u64) -> Result<Vec<u8>, SplatFileProblem> {
    let mut out = Vec::new();
    reader.take(limit).read_to_end(&mut out).map_err(SplatFileProblem::Gzip)?;
    Ok(out)
}

/// Decodes SPZ bytes (versions 2 to 4) into Gaussians in the INRIA PLY convention; see the
/// module documentation for the layout and the axis conversion.
///
/// The header's point count is checked against [`MAX_IMPORTED_POINTS`], and the data it needs
/// against [`decompressed_limit`] of the file's size and [`SPZ_MAX_DECOMPRESSED_BYTES`], before
/// anything is decompressed; decompression stops one byte past what the header requires, and
/// Gaussians are made only from data actually present, so a hostile header can neither inflate
/// a bomb nor cause a large allocation. Data after the points is an error unless the header
/// announces extension records. Every decoded value is finite by construction (the format
/// stores only small integers); opacity bytes 0 and 255 are moved half a step inside (0, 1).
/// A header declaring zero points gives an empty set. A file that names no coordinate system
/// is taken to store `unmarked` axes.
pub fn gaussians_from_spz_bytes(bytes: &[u8], unmarked: SpzAxes) -> Result<Gaussians, SplatFileProblem> {
    let (head, body) = if bytes.starts_with(b"NGSP") { unpack_v4(bytes)? } else { gunzip(bytes)? };
    decode(&head, &body, unmarked.code())
}

/// Bytes the blocks of `points` points of SH `degree` take, with rotations of `rot_bytes`.
fn data_bytes(points: u32, degree: u32, rot_bytes: usize) -> u64 {
    points as u64 * (9 + 1 + 3 + 3 + rot_bytes + 3 * sh_rest(degree)) as u64
}

/// Refuses a header whose `points` (taking `needed` bytes of data) a file of `file_bytes` cannot
/// plausibly hold, before any of it is decompressed: more points than a pwgs stream holds, or
/// more data than [`decompressed_limit`] allows (and at most [`SPZ_MAX_DECOMPRESSED_BYTES`]).
fn check_declared(points: u32, needed: u64, file_bytes: usize) -> Result<(), SplatFileProblem> {
    if points > MAX_IMPORTED_POINTS {
        return Err(SplatFileProblem::TooManyPoints { points, limit: MAX_IMPORTED_POINTS });
    }
    let file_bytes = file_bytes as u64;
    let limit = decompressed_limit(file_bytes).min(SPZ_MAX_DECOMPRESSED_BYTES);
    if needed > limit {
        return Err(SplatFileProblem::TooLarge { points, needed, limit, file_bytes });
    }
    Ok(())
}

/// Versions 2 and 3: the header and what follows it (the blocks, then any extension records)
/// from the gzip stream, read no further than the header allows.
fn gunzip(bytes: &[u8]) -> Result<(Vec<u8>, Vec<u8>), SplatFileProblem> {
    if !bytes.starts_with(&[0x1f, 0x8b]) {
        return Err(SplatFileProblem::NotSpz);
    }
    let mut reader = flate2::read::GzDecoder::new(bytes);
    let head = read_up_to(&mut reader, HEADER_BYTES as u64)?;
    if head.len() < HEADER_BYTES {
        return Err(SplatFileProblem::ShortHeader { found: head.len() });
    }
    let magic = u32_at(&head, 0);
    if magic != MAGIC {
        return Err(SplatFileProblem::BadMagic { found: magic });
    }
    let version = u32_at(&head, 4);
    if !(2..=3).contains(&version) {
        return Err(SplatFileProblem::UnsupportedVersion(version));
    }
    let (points, degree) = (u32_at(&head, 8), head[12] as u32);
    if degree > 4 {
        return Err(SplatFileProblem::ShDegree(head[12]));
    }
    let needed = data_bytes(points, degree, rotation_bytes(version));
    check_declared(points, needed, bytes.len())?;
    let allowance = if head[14] & FLAG_EXTENSIONS != 0 { MAX_EXTENSION_BYTES } else { 0 };
    // One byte past what may follow tells trailing data apart from the end of the stream.
    let body = read_up_to(&mut reader, needed + allowance + 1)?;
    Ok((head, body))
}

/// Version 4: a plain 32-byte header (version 3's 16 bytes, then the stream count u8 and the
/// table of contents' offset u32), extension records up to the table, the table (per stream,
/// compressed and decompressed sizes as u64), then one zstd stream per block in version 3's
/// order. Returned as version 3's header and body (blocks, then the extension records), so
/// that one decoder reads both.
fn unpack_v4(bytes: &[u8]) -> Result<(Vec<u8>, Vec<u8>), SplatFileProblem> {
    const V4_HEADER_BYTES: usize = 32;
    if bytes.len() < V4_HEADER_BYTES {
        let message = format!("the file's {} bytes end inside the 32-byte header", bytes.len());
        return Err(SplatFileProblem::BadStreams { message });
    }
    let version = u32_at(bytes, 4);
    if version != 4 {
        return Err(SplatFileProblem::UnsupportedVersion(version));
    }
    let (points, degree) = (u32_at(bytes, 8), bytes[12] as u32);
    if degree > 4 {
        return Err(SplatFileProblem::ShDegree(bytes[12]));
    }
    let n = points as u64;
    let mut sizes = vec![9 * n, n, 3 * n, 3 * n, 4 * n];
    if degree > 0 {
        sizes.push(3 * sh_rest(degree) as u64 * n);
    }
    check_declared(points, sizes.iter().sum(), bytes.len())?;
    let bad = |message: String| SplatFileProblem::BadStreams { message };
    let (streams, toc) = (bytes[15] as usize, u32_at(bytes, 16) as usize);
    if streams != sizes.len() {
        return Err(bad(format!("{streams} streams for SH degree {degree} (expected {})", sizes.len())));
    }
    let data_start = toc.checked_add(16 * streams).filter(|&end| toc >= V4_HEADER_BYTES && end <= bytes.len());
    let Some(mut at) = data_start else {
        return Err(bad(format!("the table of contents at byte {toc} lies outside the {}-byte file", bytes.len())));
    };
    let extensions = &bytes[V4_HEADER_BYTES..toc];
    if extensions.len() as u64 > MAX_EXTENSION_BYTES {
        return Err(bad(format!("{} bytes of extension records", extensions.len())));
    }
    // Grown as the streams decompress: the table's sizes are only claims until then.
    let mut body = Vec::new();
    for (i, &size) in sizes.iter().enumerate() {
        let entry = &bytes[toc + 16 * i..];
        let u64_at = |k: usize| u64::from_le_bytes(entry[k..k + 8].try_into().expect("8 bytes"));
        let (compressed, decompressed) = (u64_at(0), u64_at(8));
        if decompressed != size {
            return Err(bad(format!("stream {i} declares {decompressed} bytes, {size} expected for {points} points")));
        }
        let end = (at as u64).checked_add(compressed).filter(|&end| end <= bytes.len() as u64);
        let Some(end) = end else {
            return Err(bad(format!("stream {i} of {compressed} bytes at byte {at} runs past the end of the file")));
        };
        let decoder =
            zstd::stream::read::Decoder::new(&bytes[at..end as usize]).map_err(|e| bad(format!("stream {i}: {e}")))?;
        let before = body.len();
        decoder.take(size + 1).read_to_end(&mut body).map_err(|e| bad(format!("stream {i}: {e}")))?;
        if (body.len() - before) as u64 != size {
            return Err(bad(format!("stream {i} holds {} bytes, {size} expected", body.len() - before)));
        }
        at = end as usize;
    }
    if at != bytes.len() {
        return Err(SplatFileProblem::TrailingData { points });
    }
    body.extend_from_slice(extensions);
    let mut head = bytes[..HEADER_BYTES].to_vec();
    head[4..8].copy_from_slice(&3u32.to_le_bytes());
    head[14] = (head[14] & !FLAG_EXTENSIONS) | if extensions.is_empty() { 0 } else { FLAG_EXTENSIONS };
    head[15] = 0;
    Ok((head, body))
}

/// The Gaussians of a version 2 or 3 header and its body (the blocks, then any extension
/// records); `unmarked` is the coordinate-system code of a file whose records name none.
fn decode(head: &[u8], body: &[u8], unmarked: u32) -> Result<Gaussians, SplatFileProblem> {
    let version = u32_at(head, 4);
    let points = u32_at(head, 8);
    let (degree, fractional_bits, flags) = (head[12] as u32, head[13], head[14]);
    let rot_bytes = rotation_bytes(version);
    let needed = data_bytes(points, degree, rot_bytes);
    let has_extensions = flags & FLAG_EXTENSIONS != 0;
    if (body.len() as u64) < needed {
        return Err(SplatFileProblem::ShortData { points, needed, found: body.len() as u64 });
    }
    let (data, rest) = body.split_at(needed as usize);
    let flips = match has_extensions {
        false if !rest.is_empty() => return Err(SplatFileProblem::TrailingData { points }),
        false => AxisFlips::from_stored(unmarked)?,
        true => AxisFlips::from_stored(stored_coordinate_system(rest)?.unwrap_or(unmarked))?,
    };

    let n = points as usize;
    let (positions, data) = data.split_at(9 * n);
    let (alphas, data) = data.split_at(n);
    let (colors, data) = data.split_at(3 * n);
    let (scales, data) = data.split_at(3 * n);
    let (rotations, sh) = data.split_at(rot_bytes * n);
    let stored_rest = sh_rest(degree);
    let out_degree = degree.min(MAX_SH_DEGREE);
    let position_step = 0.5f64.powi(fractional_bits as i32);
    let mut g = Gaussians::with_degree(out_degree);
    let mut coeffs = vec![0.0f32; sh_coeff_count(out_degree) * 3];
    let signs: Vec<f32> =
        (0..sh_coeff_count(out_degree)).map(|k| if k == 0 { 1.0 } else { flips.sh_sign(k) }).collect();
    for i in 0..n {
        let mean = std::array::from_fn(|c| {
            let b = &positions[9 * i + 3 * c..];
            let fixed = i32::from_le_bytes([0, b[0], b[1], b[2]]) >> 8;
            (fixed as f64 * position_step) as f32
        });
        let log_scale = std::array::from_fn(|c| scales[3 * i + c] as f32 / 16.0 - 10.0);
        let rotation = match version {
            2 => first_three(&rotations[3 * i..3 * i + 3]),
            _ => smallest_three(u32_at(rotations, 4 * i)),
        };
        let alpha = (alphas[i] as f32 / 255.0).clamp(ALPHA_MIN, 1.0 - ALPHA_MIN);
        for c in 0..3 {
            coeffs[c] = (colors[3 * i + c] as f32 / 255.0 - 0.5) / COLOR_SCALE;
        }
        for k in 1..sh_coeff_count(out_degree) {
            for c in 0..3 {
                let byte = sh[(i * stored_rest + k - 1) * 3 + c];
                coeffs[k * 3 + c] = (byte as f32 - 128.0) / 128.0 * signs[k];
            }
        }
        let logit = (alpha / (1.0 - alpha)).ln();
        g.push(flips.position(mean), log_scale, flips.quaternion(rotation), logit, &coeffs);
    }
    Ok(g)
}

/// The coordinate-system code the extension records name, if one does (code 0, "unspecified",
/// names none). Each record is a u32 type, a u32 payload length and the payload; records of
/// other types are skipped.
fn stored_coordinate_system(records: &[u8]) -> Result<Option<u32>, SplatFileProblem> {
    if records.len() as u64 > MAX_EXTENSION_BYTES {
        let message = format!("the extension block exceeds {MAX_EXTENSION_BYTES} bytes");
        return Err(SplatFileProblem::BadExtension { offset: 0, message });
    }
    let (mut offset, mut code) = (0, None);
    while offset < records.len() {
        let bad = |message: String| SplatFileProblem::BadExtension { offset, message };
        let left = records.len() - offset;
        if left < 8 {
            return Err(bad(format!("a record header needs 8 bytes, {left} remain")));
        }
        let (kind, len) = (u32_at(records, offset), u32_at(records, offset + 4) as usize);
        if len > left - 8 {
            return Err(bad(format!("the record declares {len} payload bytes, {} remain", left - 8)));
        }
        if kind == EXTENSION_COORDINATE_SYSTEM {
            if len != 4 {
                return Err(bad(format!("the coordinate-system record has {len} payload bytes instead of 4")));
            }
            code = Some(u32_at(records, offset + 8)).filter(|&stored| stored != 0);
        }
        offset += 8 + len;
    }
    Ok(code)
}

/// Version 2 rotation bytes to (w, x, y, z); w >= 0 from the unit norm (0 if the three
/// components already exceed it, as rounding can make them).
fn first_three(b: &[u8]) -> [f32; 4] {
    let [x, y, z] = [b[0], b[1], b[2]].map(|v| v as f32 / 127.5 - 1.0);
    [(1.0 - x * x - y * y - z * z).max(0.0).sqrt(), x, y, z]
}

/// Version 3 "smallest three" rotation to (w, x, y, z).
fn smallest_three(mut packed: u32) -> [f32; 4] {
    let largest = (packed >> 30) as usize;
    let mut xyzw = [0.0f32; 4];
    for k in (0..4).rev().filter(|&k| k != largest) {
        let magnitude = SQRT_HALF * (packed & 511) as f32 / 511.0;
        xyzw[k] = if packed & 512 != 0 { -magnitude } else { magnitude };
        packed >>= 10;
    }
    xyzw[largest] = (1.0 - xyzw.iter().map(|v| v * v).sum::<f32>()).max(0.0).sqrt();
    [xyzw[3], xyzw[0], xyzw[1], xyzw[2]]
}

/// Encodes Gaussians as an SPZ file of the given version, storing RUB axes without extension
/// records, as Niantic's library does by default. SH coefficients are stored with all 8 bits
/// (Niantic's writer rounds them further to help gzip; readers cannot tell). Positions use 12
/// fractional bits, or fewer when a coordinate would not fit 24 bits, and are clamped to the
/// range at 0 fractional bits; colors, log-scales and SH saturate at their byte ranges.
///
/// Panics if the Gaussians' arrays are inconsistent, like the PLY writer.
pub fn gaussians_to_spz_bytes(g: &Gaussians, version: SpzVersion) -> Vec<u8> {
    assert!(g.is_consistent(), "Gaussian arrays have inconsistent lengths");
    let flips = AxisFlips::from_stored(RUB).expect("RUB is an axis-flip convention");
    let n = g.len();
    let max_abs = g.means.iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
    let limit = ((1 << 23) - 1) as f32;
    let fractional_bits = (0..=12).rev().find(|&b| max_abs * (1u32 << b) as f32 <= limit).unwrap_or(0);
    let (version_number, rot_bytes) = match version {
        SpzVersion::V2 => (2u32, 3),
        SpzVersion::V3 => (3u32, 4),
    };
    let mut raw = Vec::with_capacity(HEADER_BYTES + n * (19 + rot_bytes + 3 * sh_rest(g.sh_degree)));
    raw.extend_from_slice(&MAGIC.to_le_bytes());
    raw.extend_from_slice(&version_number.to_le_bytes());
    raw.extend_from_slice(&(n as u32).to_le_bytes());
    raw.extend_from_slice(&[g.sh_degree as u8, fractional_bits as u8, 0, 0]);
    let to_u8 = |v: f32| v.round().clamp(0.0, 255.0) as u8;
    for mean in &g.means {
        for v in flips.position(*mean) {
            let fixed = (v * (1u32 << fractional_bits) as f32).round().clamp(-limit - 1.0, limit) as i32;
            raw.extend_from_slice(&fixed.to_le_bytes()[..3]);
        }
    }
    raw.extend(g.opacity_logits.iter().map(|&l| to_u8(255.0 / (1.0 + (-l).exp()))));
    raw.extend(
        (0..n).flat_map(|i| (0..3).map(move |c| g.sh_of(i)[c])).map(|dc| to_u8(dc * COLOR_SCALE * 255.0 + 127.5)),
    );
    raw.extend(g.log_scales.iter().flatten().map(|&s| to_u8((s + 10.0) * 16.0)));
    for q in &g.rotations {
        let norm = q.iter().map(|v| v * v).sum::<f32>().sqrt();
        let [w, x, y, z] = flips.quaternion(if norm > 0.0 { q.map(|v| v / norm) } else { [1.0, 0.0, 0.0, 0.0] });
        let xyzw = [x, y, z, w];
        match version {
            SpzVersion::V2 => {
                let sign = if w < 0.0 { -1.0 } else { 1.0 };
                raw.extend(xyzw[..3].iter().map(|v| to_u8(sign * v * 127.5 + 127.5)));
            }
            SpzVersion::V3 => raw.extend_from_slice(&pack_smallest_three(xyzw).to_le_bytes()),
        }
    }
    for i in 0..n {
        let sh = g.sh_of(i);
        for k in 1..g.coeffs_per_channel() {
            raw.extend((0..3).map(|c| to_u8(sh[k * 3 + c] * flips.sh_sign(k) * 128.0 + 128.0)));
        }
    }
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(&raw).expect("writing to memory cannot fail");
    encoder.finish().expect("writing to memory cannot fail")
}

/// A unit quaternion (x, y, z, w) as "smallest three": the largest component made positive
/// (q and -q are the same rotation) and left out, the others as sign and 9-bit magnitude.
fn pack_smallest_three(q: [f32; 4]) -> u32 {
    let largest = (0..4).fold(0, |best, k| if q[k].abs() > q[best].abs() { k } else { best });
    let sign = if q[largest] < 0.0 { -1.0 } else { 1.0 };
    let mut packed = largest as u32;
    for k in (0..4).filter(|&k| k != largest) {
        let v = sign * q[k];
        let magnitude = ((v.abs() / SQRT_HALF * 511.0).round() as u32).min(511);
        packed = (packed << 10) | ((v < 0.0) as u32 * 512) | magnitude;
    }
    packed
}

#[cfg(test)]
mod tests;

//! Readers for the splat files people already have, beside the INRIA PLY: antimatter15's
//! `.splat` (the web viewer's 32-byte records), Niantic's `.spz` (quantized, gzip
//! compressed) and PlayCanvas's SOG (WebP images and codebooks), so that an existing model can
//! be compressed without retraining.
//!
//! Every reader returns [`Gaussians`] in the convention of an INRIA PLY (3DGS training axes,
//! log-scales, opacity logits, SH DC terms), which is what the rest of the project expects; the
//! conversions each format needs are documented in its module. The inputs are untrusted: a
//! corrupt or hostile file is an error naming the file and the problem, never a panic, and
//! nothing is allocated beyond what the bytes actually present can fill.
//!
//! Compressed inputs (SPZ's gzip and zstd streams, SOG's zip entries and WebP images) are
//! bounded before they are expanded: a header's or `meta.json`'s point count by what a pwgs
//! stream holds ([`MAX_IMPORTED_POINTS`]), the bytes it makes the reader decompress or decode by
//! [`decompressed_limit`] of the input's size, and every decompression stops one byte past what
//! the counts require, so that a small file claiming millions of points is refused before it
//! is inflated rather than after.
//!
//! The `*_to_*_bytes` writers exist so that round trips can be tested without external files;
//! they are small and write only what the readers need to be exercised.

mod sog;
mod splat;
mod spz;

use std::path::Path;

pub use sog::gaussians_from_sog_bytes;
pub use splat::{SPLAT_MIN_LOG_SCALE, SPLAT_RECORD_BYTES, gaussians_from_splat_bytes, gaussians_to_splat_bytes};
pub use spz::{SPZ_MAX_DECOMPRESSED_BYTES, SpzAxes, SpzVersion, gaussians_from_spz_bytes, gaussians_to_spz_bytes};

use crate::gaussians::Gaussians;
use crate::ply::PlyProblem;

/// The most points (Gaussians) an imported file may declare: as many as one pwgs stream holds
/// (`bitstream-spec/SPEC.md` section 9), checked before anything is decompressed or allocated.
pub const MAX_IMPORTED_POINTS: u32 = crate::gaussians::MAX_GAUSSIANS;

/// How many bytes of decompressed data (SPZ) or decoded pixels (SOG) one byte of input may
/// expand to. Real splat data is quantized noise that gzip, zstd and lossless WebP shrink 1.2
/// to 5 times, so 32 leaves wide room; without such a bound the point limit alone would let a
/// few hundred kilobytes of zeros (gzip's 1:1032, zstd's RLE blocks at 1:32768) demand 2^24
/// points: 335 MB of SPZ data and 0.9 GB of Gaussians.
pub const MAX_EXPANSION: u64 = 32;

/// Decompressed bytes every input may use whatever its size, for small files of repetitive
/// content (test scenes, a few identical Gaussians) that compress far better than real data.
pub const EXPANSION_ALLOWANCE: u64 = 1 << 20;

/// The most bytes reading an input of `input_bytes` may decompress or decode: [`MAX_EXPANSION`]
/// times its size plus [`EXPANSION_ALLOWANCE`] (33 MiB for a 1 MB file).
pub fn decompressed_limit(input_bytes: u64) -> u64 {
    input_bytes.saturating_mul(MAX_EXPANSION).saturating_add(EXPANSION_ALLOWANCE)
}

/// A problem with a splat file; `source_name` names the file.
#[derive(Debug, thiserror::Error)]
#[error("{source_name}: {problem}")]
pub struct SplatFileError {
    pub source_name: String,
    pub problem: SplatFileProblem,
}

/// What is wrong with a splat file. The variants name the record, byte count or header field
/// at fault, so that a user can tell a truncated download from a format this reader lacks.
#[derive(Debug, thiserror::Error)]
pub enum SplatFileProblem {
    #[error("cannot read the file: {0}")]
    Io(#[from] std::io::Error),
    #[error("unknown splat file type `{0}` (expected a .ply, .splat, .spz or .sog file name, or a SOG's meta.json)")]
    UnknownFormat(String),
    #[error("{0}")]
    Ply(#[from] PlyProblem),
    #[error(
        "{len} bytes are not a whole number of {SPLAT_RECORD_BYTES}-byte .splat records ({extra} bytes over); the \
         file is truncated or not a .splat file"
    )]
    SplatLength { len: usize, extra: usize },
    #[error("record {record}: {field} {values:?} is not finite")]
    NonFinite { record: usize, field: &'static str, values: Vec<f32> },
    #[error("record {record}: scale {values:?} is negative")]
    NegativeScale { record: usize, values: [f32; 3] },
    #[error("not an SPZ file: it starts neither with a gzip header (versions 1 to 3) nor with `NGSP` (version 4)")]
    NotSpz,
    #[error("the gzip stream is corrupt or truncated: {0}")]
    Gzip(std::io::Error),
    #[error("bad SPZ magic {found:#010x} (expected 0x5053474e, `NGSP`)")]
    BadMagic { found: u32 },
    #[error("SPZ version {0} is not supported (this reader supports versions 2 to 4{hint})", hint = version_hint(*.0))]
    UnsupportedVersion(u32),
    #[error("SH degree {0} in the SPZ header is out of range (SPZ allows 0 to 4)")]
    ShDegree(u8),
    #[error("the decompressed data ends after {found} bytes, inside the 16-byte SPZ header")]
    ShortHeader { found: usize },
    #[error("the SPZ header declares {points} points, which need {needed} bytes of data, but the data holds {found}")]
    ShortData { points: u32, needed: u64, found: u64 },
    #[error("the SPZ header declares {points} points, more than the {limit} a pwgs stream holds")]
    TooManyPoints { points: u32, limit: u32 },
    #[error(
        "the SPZ header declares {points} points, which need {needed} bytes of data, more than the {limit}-byte \
         limit for a {file_bytes}-byte file ({MAX_EXPANSION} times its size plus {EXPANSION_ALLOWANCE} bytes, at most \
         {SPZ_MAX_DECOMPRESSED_BYTES}): real SPZ data does not compress that far"
    )]
    TooLarge { points: u32, needed: u64, limit: u64, file_bytes: u64 },
    #[error("data continues after the {points} points, and the SPZ header announces no extension records")]
    TrailingData { points: u32 },
    #[error("malformed SPZ extension record at byte {offset} of the extension block: {message}")]
    BadExtension { offset: usize, message: String },
    #[error("SPZ coordinate system {0} is not supported (only the axis-flip family 1 to 8 is)")]
    CoordinateSystem(u32),
    #[error("SPZ version 4 streams: {message}")]
    BadStreams { message: String },
    #[error("SOG {part}: {message}")]
    Sog { part: String, message: String },
}

fn version_hint(version: u32) -> &'static str {
    match version {
        1 => "; version 1 stored float16 positions and was never released",
        _ => "",
    }
}

/// Reads Gaussians from a `.ply` (INRIA or compressed layout), `.splat`, `.spz` or SOG (`.sog`
/// archive, or a folder's `meta.json`) file, chosen by the file
/// name's extension (case-insensitive): the formats carry no common magic, and a `.splat` file
/// has none at all, so sniffing the content could not tell them apart reliably.
///
/// A PLY's non-finite Gaussians are dropped and its infinite opacities clamped as
/// [`crate::ply::read_gaussians`] does, and a SOG's Gaussians that use a null codebook entry
/// are dropped; `.splat` and `.spz` reject non-finite values, see their byte-level readers.
/// An `.spz` that names no coordinate system is taken to store `spz_axes`.
pub fn read_splat_file(path: &Path, spz_axes: SpzAxes) -> Result<Gaussians, SplatFileError> {
    let name = path.display().to_string();
    let wrap = |problem: SplatFileProblem| SplatFileError { source_name: name.clone(), problem };
    let extension = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    match extension.as_str() {
        "ply" => crate::ply::read_gaussians(path)
            .map(|ply| ply.gaussians)
            .map_err(|e| SplatFileError { source_name: e.source_name, problem: SplatFileProblem::Ply(e.problem) }),
        "splat" => {
            let bytes = std::fs::read(path).map_err(|e| wrap(e.into()))?;
            gaussians_from_splat_bytes(&bytes).map_err(wrap)
        }
        "spz" => {
            let bytes = std::fs::read(path).map_err(|e| wrap(e.into()))?;
            gaussians_from_spz_bytes(&bytes, spz_axes).map_err(wrap)
        }
        "sog" | "json" => sog::read_sog(path).map_err(wrap),
        _ => Err(wrap(SplatFileProblem::UnknownFormat(extension))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::{SplitMix64, random_gaussians};

    /// The largest component difference between the unit quaternions of `a` and `b`, taking
    /// the sign that matches better: `q` and `-q` are the same rotation.
    pub(super) fn quaternion_gap(a: [f32; 4], b: [f32; 4]) -> f32 {
        let unit = |q: [f32; 4]| q.map(|v| v / q.iter().map(|v| v * v).sum::<f32>().sqrt());
        let (a, b) = (unit(a), unit(b));
        let gap = |sign: f32| (0..4).map(|k| (a[k] - sign * b[k]).abs()).fold(0.0, f32::max);
        gap(1.0).min(gap(-1.0))
    }

    #[test]
    fn files_are_read_by_extension() {
        let tmp = tempfile::tempdir().unwrap();
        let g = random_gaussians(&mut SplitMix64(7), 20, 0, [-4.0, -1.0]);
        let ply = tmp.path().join("a.ply");
        let splat = tmp.path().join("a.SPLAT");
        let spz = tmp.path().join("a.spz");
        crate::ply::write_gaussians(&ply, &g).unwrap();
        std::fs::write(&splat, gaussians_to_splat_bytes(&g)).unwrap();
        std::fs::write(&spz, gaussians_to_spz_bytes(&g, SpzVersion::V3)).unwrap();
        assert_eq!(read_splat_file(&ply, SpzAxes::Rub).unwrap(), g, "a PLY round trip is exact");
        let from_splat = read_splat_file(&splat, SpzAxes::Rub).unwrap();
        let from_spz = read_splat_file(&spz, SpzAxes::Rub).unwrap();
        for read in [&from_splat, &from_spz] {
            assert_eq!(read.len(), g.len());
            for (a, b) in read.means.iter().zip(&g.means) {
                assert!((0..3).all(|c| (a[c] - b[c]).abs() < 1e-3), "{a:?} vs {b:?}");
            }
        }
        // The content decides nothing: SPZ bytes under a .splat name are not read as SPZ.
        std::fs::write(&splat, gaussians_to_spz_bytes(&g, SpzVersion::V3)).unwrap();
        assert!(
            read_splat_file(&splat, SpzAxes::Rub)
                .is_err_and(|e| matches!(e.problem, SplatFileProblem::SplatLength { .. }))
        );
    }

    #[test]
    fn errors_name_the_file_and_the_problem() {
        let tmp = tempfile::tempdir().unwrap();
        let unknown = tmp.path().join("scene.glb");
        std::fs::write(&unknown, b"glTF").unwrap();
        let err = read_splat_file(&unknown, SpzAxes::Rub).unwrap_err().to_string();
        assert!(err.contains("scene.glb") && err.contains("unknown splat file type `glb`"), "{err}");

        let missing = tmp.path().join("missing.spz");
        let err = read_splat_file(&missing, SpzAxes::Rub).unwrap_err().to_string();
        assert!(err.contains("missing.spz: cannot read the file"), "{err}");

        let short = tmp.path().join("short.splat");
        std::fs::write(&short, [0u8; 40]).unwrap();
        let err = read_splat_file(&short, SpzAxes::Rub).unwrap_err().to_string();
        assert!(err.contains("short.splat") && err.contains("40 bytes") && err.contains("8 bytes over"), "{err}");

        let bad_ply = tmp.path().join("bad.ply");
        std::fs::write(&bad_ply, b"not a ply").unwrap();
        let err = read_splat_file(&bad_ply, SpzAxes::Rub).unwrap_err().to_string();
        assert!(err.contains("bad.ply") && err.contains("not a PLY file"), "{err}");
    }
}

//! A SOG's WebP images, read so that no file can make the reader decompress or decode more than
//! the Gaussians it describes need: each file is read through a cap from the pixels its layout
//! allows ([`Layout::file_cap`]), and, from an archive, all of them together no further than
//! [`decompressed_limit`] of the archive's size; then every image's size, from its header, is
//! checked against its layout, and the pixels all of them decode to against
//! [`decompressed_limit`] of the input, before a single pixel is decoded. A lossless WebP of 34
//! bytes can declare 16383 x 16383 pixels (1 GiB of RGBA), so nothing else bounds the work.

use std::io::Cursor;

use image::{ImageFormat, ImageReader, RgbaImage};

use super::{file_name, problem};
use crate::splat_file::{EXPANSION_ALLOWANCE, MAX_EXPANSION, SplatFileProblem, decompressed_limit};

/// Headers and the odd metadata chunk a WebP may carry beyond its pixels.
const WEBP_OVERHEAD_BYTES: u64 = 1 << 16;

/// How an image's pixels are used, which bounds its size.
#[derive(Debug, Clone, Copy)]
pub(super) enum Layout {
    /// One pixel per Gaussian, row by row, in rows of any width.
    Texture { count: usize },
    /// A palette of `entries` entries of `coeffs` pixels each, 64 entries to a row.
    Palette { entries: usize, coeffs: usize },
}

impl Layout {
    /// The pixels the image must at least have (whole rows, for a palette).
    fn needed(self) -> u64 {
        match self {
            Self::Texture { count } => count as u64,
            Self::Palette { entries, coeffs } => 64 * coeffs as u64 * entries.div_ceil(64) as u64,
        }
    }

    /// The most pixels the image may have: four times what it needs, or 4096 for a small one.
    /// Writers pad little: PlayCanvas's rounds both sides up to a multiple of 4 (a square of
    /// about sqrt(count) + 4 a side), a palette is exactly as many rows as it fills.
    fn allowed(self) -> u64 {
        4 * self.needed().max(1024)
    }

    /// The most bytes the image's file may hold: a lossless WebP of the allowed pixels stored
    /// uncompressed (4 bytes a pixel) and its headers.
    pub(super) fn file_cap(self) -> u64 {
        4 * self.allowed() + WEBP_OVERHEAD_BYTES
    }

    /// Checks a `width` x `height` image for this layout.
    fn check(self, name: &str, width: u32, height: u32) -> Result<(), SplatFileProblem> {
        let pixels = u64::from(width) * u64::from(height);
        let (fits, what) = match self {
            Self::Texture { count } => (pixels >= count as u64, format!("{count} Gaussians")),
            Self::Palette { entries, coeffs } => (
                width as usize == 64 * coeffs && height as usize * 64 >= entries,
                format!("{entries} palette entries of {coeffs} coefficients"),
            ),
        };
        if !fits {
            return Err(problem(name, format!("{width}x{height} pixels for {what}")));
        }
        let allowed = self.allowed();
        if pixels > allowed {
            let message = format!(
                "{width}x{height} pixels for {what}: more than the {allowed} an image for them may have (4 times \
                 the {} needed, at least 4096)",
                self.needed()
            );
            return Err(problem(name, message));
        }
        Ok(())
    }
}

/// The images of the `planned` files in order, as RGBA, with the bounds of the module
/// documentation; `load(name, cap)` reads at most `cap + 1` bytes of a file, `archive_bytes`
/// is the size of the archive holding the files (`None` for a folder) and `meta_bytes` that of
/// `meta.json`.
pub(super) fn read(
    planned: &[(&str, Layout)],
    archive_bytes: Option<u64>,
    meta_bytes: u64,
    load: &mut impl FnMut(&str, u64) -> Result<Vec<u8>, SplatFileProblem>,
) -> Result<Vec<RgbaImage>, SplatFileProblem> {
    // An archive's entries are decompressed: together they get the archive's limit. A folder's
    // files are the input itself, bounded by their caps alone.
    let entry_limit = archive_bytes.map(decompressed_limit);
    let mut files = Vec::with_capacity(planned.len());
    let mut read_bytes = 0u64;
    for &(name, layout) in planned {
        let name = file_name(name)?;
        let left = entry_limit.map_or(u64::MAX, |limit| limit.saturating_sub(read_bytes));
        let cap = layout.file_cap().min(left);
        let bytes = load(name, cap)?;
        if bytes.len() as u64 > cap {
            let message = match (archive_bytes, entry_limit) {
                (Some(archive), Some(limit)) if left < layout.file_cap() => format!(
                    "the files meta.json names decompress to more than {limit} bytes, the limit for a {archive}-byte \
                     archive ({MAX_EXPANSION} times its size plus {EXPANSION_ALLOWANCE} bytes)"
                ),
                _ => format!("more than {cap} bytes, more than a WebP of the pixels its Gaussians allow"),
            };
            return Err(problem(name, message));
        }
        read_bytes += bytes.len() as u64;
        files.push(bytes);
    }

    let input = archive_bytes.unwrap_or(meta_bytes + read_bytes);
    let pixel_limit = decompressed_limit(input);
    let mut sizes = Vec::with_capacity(planned.len());
    let mut decoded_bytes = 0u64;
    for (&(name, layout), bytes) in planned.iter().zip(&files) {
        let (width, height) = ImageReader::with_format(Cursor::new(bytes), ImageFormat::WebP)
            .into_dimensions()
            .map_err(|e| problem(name, format!("not a readable WebP image: {e}")))?;
        layout.check(name, width, height)?;
        decoded_bytes += 4 * u64::from(width) * u64::from(height);
        if decoded_bytes > pixel_limit {
            let message = format!(
                "the images up to this one decode to {decoded_bytes} bytes, more than the {pixel_limit}-byte limit \
                 for a {input}-byte input ({MAX_EXPANSION} times its size plus {EXPANSION_ALLOWANCE} bytes): real SOG \
                 images do not compress that far"
            );
            return Err(problem(name, message));
        }
        sizes.push((width, height));
    }

    let checked = planned.iter().zip(files).zip(sizes);
    checked.map(|((&(name, _), bytes), size)| decode(&bytes, name, size)).collect()
}

/// The RGBA pixels of a WebP image whose header declared `width` x `height`.
fn decode(bytes: &[u8], name: &str, (width, height): (u32, u32)) -> Result<RgbaImage, SplatFileProblem> {
    let mut reader = ImageReader::with_format(Cursor::new(bytes), ImageFormat::WebP);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    limits.max_alloc = Some(4 * u64::from(width) * u64::from(height) + WEBP_OVERHEAD_BYTES);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| problem(name, format!("not a readable WebP image: {e}")))?;
    Ok(decoded.into_rgba8())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every size PlayCanvas's writer gives (both sides rounded up to a multiple of 4, the
    /// width from the square root) and this crate's test writer gives (16 wide) is accepted.
    #[test]
    fn the_writers_layouts_are_accepted() {
        for count in [0, 1, 2, 15, 100, 1000, 12_345, 65_537, 1 << 20, 3_000_001, 1 << 24] {
            let width = ((count as f64).sqrt() / 4.0).ceil() as u32 * 4;
            let height = (count as f64 / f64::from(width.max(1)) / 4.0).ceil() as u32 * 4;
            let texture = Layout::Texture { count };
            assert!(texture.check("t", width.max(4), height.max(4)).is_ok(), "{count}: {width}x{height}");
            assert!(texture.check("t", 16, count.div_ceil(16).max(1) as u32).is_ok(), "{count}: 16 wide");
        }
        for (entries, coeffs) in [(1, 3), (1000, 8), (1 << 16, 15)] {
            let palette = Layout::Palette { entries, coeffs };
            assert!(palette.check("p", 64 * coeffs as u32, entries.div_ceil(64) as u32).is_ok());
        }
        let err = Layout::Texture { count: 10 }.check("t", 16383, 16383).unwrap_err().to_string();
        assert!(err.contains("16383x16383 pixels for 10 Gaussians: more than the 4096"), "{err}");
    }
}

//! Finding, loading and resizing a dataset's images.
//!
//! Downscaled copies follow the COLMAP/LLFF naming (`images_2`, `images_4`, `images_8` beside
//! `images`). A requested downscale uses the matching folder when it exists, and otherwise
//! resizes a larger copy on load.

use std::path::{Path, PathBuf};

use pwgs_core::rgb_image::RgbImage;

use crate::DatasetError;

/// Where to read images from for a requested downscale factor.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageSource {
    pub folder: PathBuf,
    /// Further integer downscale to apply after loading (1 = none).
    pub extra_factor: u32,
}

/// Picks `base_N` for downscale N if present, else the largest folder `base_K` (K dividing N,
/// `base` itself for K = 1) to be downscaled by N / K.
pub fn choose_source(scene_dir: &Path, base: &str, downscale: u32) -> Result<ImageSource, DatasetError> {
    let folder_for = |k: u32| if k == 1 { scene_dir.join(base) } else { scene_dir.join(format!("{base}_{k}")) };
    let candidates = (1..=downscale).rev().filter(|k| downscale.is_multiple_of(*k));
    for k in candidates {
        let folder = folder_for(k);
        if folder.is_dir() {
            return Ok(ImageSource { folder, extra_factor: downscale / k });
        }
    }
    Err(DatasetError::malformed(
        scene_dir,
        format!("no image folder for downscale {downscale}: looked for {base}_{downscale} and {base}"),
    ))
}

/// The smallest downscale whose images a scene stores as they are: 1 when it has a `base` folder
/// (or none of `base_N`, whose loader then says what is missing), else the smallest `N` of its
/// `base_N` folders. For callers that need the cameras only, at any size: a capture shipped with
/// `images_4` and `images_8` alone (LLFF's fern) has no views at downscale 1.
pub fn stored_downscale(scene_dir: &Path, base: &str) -> u32 {
    if scene_dir.join(base).is_dir() {
        return 1;
    }
    let Ok(entries) = std::fs::read_dir(scene_dir) else { return 1 };
    let prefix = format!("{base}_");
    entries
        .filter_map(|entry| {
            let entry = entry.ok()?;
            let factor = entry.file_name().to_str()?.strip_prefix(&prefix)?.parse::<u32>().ok()?;
            (factor >= 1 && entry.path().is_dir()).then_some(factor)
        })
        .min()
        .unwrap_or(1)
}

/// Image files in a folder (png, jpg, jpeg; any case), sorted by name.
pub fn list_images(folder: &Path) -> Result<Vec<PathBuf>, DatasetError> {
    let entries = std::fs::read_dir(folder).map_err(|e| DatasetError::io(folder, e))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| DatasetError::io(folder, e))?.path();
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if matches!(ext.as_deref(), Some("png" | "jpg" | "jpeg")) {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// Loads an image and downscales it by an integer factor.
pub fn load(path: &Path, background: [f32; 3], factor: u32) -> Result<RgbImage, DatasetError> {
    let image = RgbImage::load(path, background)?;
    downscaled_size(path, image.width, image.height, factor)?;
    Ok(if factor <= 1 { image } else { downscale(&image, factor) })
}

/// The size [`load`] gives an image, read from the file's header without decoding its pixels.
pub fn dimensions(path: &Path, factor: u32) -> Result<(u32, u32), DatasetError> {
    let reader = image::ImageReader::open(path).map_err(|e| DatasetError::io(path, e))?;
    let reader = reader.with_guessed_format().map_err(|e| DatasetError::io(path, e))?;
    let (width, height) = reader
        .into_dimensions()
        .map_err(|e| DatasetError::malformed(path, format!("cannot read the image's size: {e}")))?;
    downscaled_size(path, width, height, factor)
}

/// The size of a `width` x `height` image downscaled by `factor` (see [`downscale`]); an image
/// smaller than one block is an error.
fn downscaled_size(path: &Path, width: u32, height: u32, factor: u32) -> Result<(u32, u32), DatasetError> {
    if factor <= 1 {
        return Ok((width, height));
    }
    if width < factor || height < factor {
        return Err(DatasetError::malformed(
            path,
            format!("{width}x{height} image is too small to downscale by {factor}"),
        ));
    }
    Ok((width / factor, height / factor))
}

/// Box-filter downscale by an integer factor (the mean of each factor x factor block); a
/// remainder at the right or bottom edge is dropped, as COLMAP's and LLFF's downscalers do
/// (they round the size down).
pub fn downscale(image: &RgbImage, factor: u32) -> RgbImage {
    let (w, h) = (image.width / factor, image.height / factor);
    let mut out = RgbImage::filled(w, h, [0.0; 3]);
    let norm = 1.0 / (factor as f32 * factor as f32);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f32; 3];
            for dy in 0..factor {
                for dx in 0..factor {
                    let p = image.pixel(x * factor + dx, y * factor + dy);
                    (0..3).for_each(|c| sum[c] += p[c]);
                }
            }
            out.set_pixel(x, y, sum.map(|s| s * norm));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downscale_averages_blocks() {
        let mut img = RgbImage::filled(5, 4, [0.0; 3]);
        img.set_pixel(0, 0, [1.0, 0.5, 0.0]);
        let small = downscale(&img, 2);
        assert_eq!((small.width, small.height), (2, 2));
        assert_eq!(small.pixel(0, 0), [0.25, 0.125, 0.0]);
        assert_eq!(small.pixel(1, 1), [0.0; 3]);
    }

    #[test]
    fn source_prefers_matching_folder() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("images")).unwrap();
        std::fs::create_dir(dir.path().join("images_2")).unwrap();
        let s = choose_source(dir.path(), "images", 4).unwrap();
        assert_eq!((s.folder, s.extra_factor), (dir.path().join("images_2"), 2));
        let s = choose_source(dir.path(), "images", 3).unwrap();
        assert_eq!((s.folder, s.extra_factor), (dir.path().join("images"), 3));
        assert!(choose_source(dir.path(), "pictures", 1).is_err());
    }

    #[test]
    fn stored_downscale_is_the_largest_images_a_scene_has() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(stored_downscale(dir.path(), "images"), 1, "no folder: the loader names it");
        for name in ["images_8", "images_4", "images_x", "images_0"] {
            std::fs::create_dir(dir.path().join(name)).unwrap();
        }
        std::fs::write(dir.path().join("images_2"), b"a file, not a folder").unwrap();
        assert_eq!(stored_downscale(dir.path(), "images"), 4);
        assert_eq!(choose_source(dir.path(), "images", 4).unwrap().extra_factor, 1);
        std::fs::create_dir(dir.path().join("images")).unwrap();
        assert_eq!(stored_downscale(dir.path(), "images"), 1);
    }
}

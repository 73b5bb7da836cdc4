//! RGB images as the codec handles them: f32 in [0, 1], display-space values (no gamma
//! conversion anywhere), rows top to bottom, channels interleaved. On disk they are 8-bit PNG.

use std::path::Path;

/// An interleaved RGB f32 image.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    /// `width * height * 3` values, row-major, RGB interleaved.
    pub data: Vec<f32>,
}

/// Why an image could not be read or written; names the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: cannot decode image: {source}")]
    Decode { path: String, source: image::ImageError },
    #[error("{path}: cannot write image: {source}")]
    Encode { path: String, source: image::ImageError },
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
}

impl RgbImage {
    /// A constant-color image.
    pub fn filled(width: u32, height: u32, rgb: [f32; 3]) -> Self {
        let data = rgb.iter().copied().cycle().take(width as usize * height as usize * 3).collect();
        Self { width, height, data }
    }

    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    pub fn pixel(&self, x: u32, y: u32) -> [f32; 3] {
        let i = (y as usize * self.width as usize + x as usize) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    pub fn set_pixel(&mut self, x: u32, y: u32, rgb: [f32; 3]) {
        let i = (y as usize * self.width as usize + x as usize) * 3;
        self.data[i..i + 3].copy_from_slice(&rgb);
    }

    /// Converts an 8-bit RGBA buffer, compositing straight alpha over `background`.
    pub fn from_rgba8(img: &image::RgbaImage, background: [f32; 3]) -> Self {
        let mut data = Vec::with_capacity(img.width() as usize * img.height() as usize * 3);
        for p in img.pixels() {
            let a = p[3] as f32 / 255.0;
            for c in 0..3 {
                data.push(p[c] as f32 / 255.0 * a + background[c] * (1.0 - a));
            }
        }
        Self { width: img.width(), height: img.height(), data }
    }

    /// Reads an image file (PNG, JPEG); an alpha channel is composited over `background`.
    pub fn load(path: &Path, background: [f32; 3]) -> Result<Self, ImageError> {
        let name = path.display().to_string();
        let reader = image::ImageReader::open(path).map_err(|source| ImageError::Io { path: name.clone(), source })?;
        let mut reader =
            reader.with_guessed_format().map_err(|source| ImageError::Io { path: name.clone(), source })?;
        reader.limits(decode_limits());
        let decoded = reader.decode().map_err(|source| ImageError::Decode { path: name, source })?;
        Ok(Self::from_rgba8(&decoded.to_rgba8(), background))
    }

    /// Clamps every value to [0, 1]: the image as a display (or a PNG, before rounding) shows
    /// it, which is what quality scores compare.
    pub fn clamp_to_displayable(&mut self) {
        self.data.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
    }

    /// Quantizes to 8 bits (values clamped to [0, 1], rounded to nearest).
    pub fn to_rgb8(&self) -> image::RgbImage {
        let bytes = self.data.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8).collect();
        image::RgbImage::from_raw(self.width, self.height, bytes).expect("buffer length matches the size")
    }

    /// Writes an 8-bit PNG through a temporary file, so an existing file is never half-written.
    pub fn save_png(&self, path: &Path) -> Result<(), ImageError> {
        let name = path.display().to_string();
        let mut bytes = Vec::new();
        self.to_rgb8()
            .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)
            .map_err(|source| ImageError::Encode { path: name.clone(), source })?;
        crate::atomic_file::write_atomically(path, &bytes).map_err(|source| ImageError::Io { path: name, source })
    }
}

/// What an image file may make [`RgbImage::load`] allocate, whatever its header claims: sides
/// up to a camera's [`MAX_SIDE`](crate::camera::MAX_SIDE) and 256 MiB of decoded pixels (64
/// megapixels of RGBA, four times a 16-megapixel photo), refused before decoding.
fn decode_limits() -> image::Limits {
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(crate::camera::MAX_SIDE);
    limits.max_image_height = Some(crate::camera::MAX_SIDE);
    limits.max_alloc = Some(256 << 20);
    limits
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn images_beyond_the_limits_are_refused_before_decoding() {
        let tmp = tempfile::tempdir().unwrap();
        let wide = tmp.path().join("wide.png");
        image::RgbImage::new(70_000, 1).save(&wide).unwrap();
        let err = RgbImage::load(&wide, [0.0; 3]).unwrap_err().to_string();
        assert!(err.contains("wide.png") && err.contains("limit"), "{err}");
        let small = tmp.path().join("small.png");
        image::RgbImage::from_pixel(3, 2, image::Rgb([255, 0, 0])).save(&small).unwrap();
        let loaded = RgbImage::load(&small, [0.0; 3]).unwrap();
        assert_eq!((loaded.width, loaded.height, loaded.data[0]), (3, 2, 1.0));
    }
}

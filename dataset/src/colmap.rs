//! COLMAP sparse models (`cameras`, `images`, `points3D`) in COLMAP's binary and text formats.
//!
//! These files come from other tools and from users, so reading is defensive: every error names
//! the file (and, for text, the line), a truncated file is an error rather than a panic, and a
//! binary count is checked against the bytes left before anything is allocated, so a corrupt
//! count fails at once instead of exhausting memory. Values are not judged here (a NaN pose reads
//! as NaN): the scene loader (`colmap_scene.rs`) decides what it can use.
//!
//! COLMAP documents camera, image and 2D point ids as `int`, but writes them as `uint32`; the two
//! agree below 2^31, and reading them as `u32` accepts every file COLMAP can write.
//!
//! Text is written with Rust's shortest round-trip float formatting, so text round trips are exact.

mod binary;
#[cfg(test)]
mod tests;
mod text;

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use binary::{cameras_from_bin, cameras_to_bin, images_from_bin, images_to_bin, points_from_bin, points_to_bin};
use text::{cameras_from_text, cameras_to_text, images_from_text, images_to_text, points_from_text, points_to_text};

use crate::undistort::Distortion;
use crate::{DatasetError, read_file};

/// COLMAP's camera models; the declaration order is COLMAP's numeric model id.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CameraModel {
    SimplePinhole,
    Pinhole,
    SimpleRadial,
    Radial,
    Opencv,
    OpencvFisheye,
    FullOpencv,
    Fov,
    SimpleRadialFisheye,
    RadialFisheye,
    ThinPrismFisheye,
}

impl CameraModel {
    /// Every model, indexed by its COLMAP id.
    const ALL: [Self; 11] = [
        Self::SimplePinhole,
        Self::Pinhole,
        Self::SimpleRadial,
        Self::Radial,
        Self::Opencv,
        Self::OpencvFisheye,
        Self::FullOpencv,
        Self::Fov,
        Self::SimpleRadialFisheye,
        Self::RadialFisheye,
        Self::ThinPrismFisheye,
    ];

    /// COLMAP's numeric model id, as stored in `cameras.bin`.
    pub fn id(self) -> i32 {
        self as i32
    }

    /// COLMAP's model name, as written in `cameras.txt`.
    pub fn name(self) -> &'static str {
        match self {
            Self::SimplePinhole => "SIMPLE_PINHOLE",
            Self::Pinhole => "PINHOLE",
            Self::SimpleRadial => "SIMPLE_RADIAL",
            Self::Radial => "RADIAL",
            Self::Opencv => "OPENCV",
            Self::OpencvFisheye => "OPENCV_FISHEYE",
            Self::FullOpencv => "FULL_OPENCV",
            Self::Fov => "FOV",
            Self::SimpleRadialFisheye => "SIMPLE_RADIAL_FISHEYE",
            Self::RadialFisheye => "RADIAL_FISHEYE",
            Self::ThinPrismFisheye => "THIN_PRISM_FISHEYE",
        }
    }

    /// How many parameters the model has; binary files store no count, so this decides the layout.
    pub fn param_count(self) -> usize {
        match self {
            Self::SimplePinhole => 3,
            Self::Pinhole | Self::SimpleRadial | Self::SimpleRadialFisheye => 4,
            Self::Radial | Self::Fov | Self::RadialFisheye => 5,
            Self::Opencv | Self::OpencvFisheye => 8,
            Self::FullOpencv | Self::ThinPrismFisheye => 12,
        }
    }

    pub fn from_id(id: i32) -> Option<Self> {
        usize::try_from(id).ok().and_then(|i| Self::ALL.get(i).copied())
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|model| model.name() == name)
    }

    /// Whether the model has one focal length for both axes: its params then start (f, cx, cy)
    /// instead of (fx, fy, cx, cy).
    fn single_focal(self) -> bool {
        matches!(
            self,
            Self::SimplePinhole | Self::SimpleRadial | Self::Radial | Self::SimpleRadialFisheye | Self::RadialFisheye
        )
    }
}

/// One camera (intrinsics shared by the images that name it).
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapCamera {
    pub id: u32,
    pub model: CameraModel,
    pub width: u64,
    pub height: u64,
    pub params: Vec<f64>,
}

impl ColmapCamera {
    /// (fx, fy, cx, cy) in pixels of the model's width x height. Params missing from a camera
    /// built by hand read as NaN, which camera construction downstream rejects.
    pub fn pinhole(&self) -> [f64; 4] {
        let p = |i: usize| self.params.get(i).copied().unwrap_or(f64::NAN);
        if self.model.single_focal() { [p(0), p(0), p(1), p(2)] } else { [p(0), p(1), p(2), p(3)] }
    }

    /// The lens distortion, or an Unsupported error naming the model for the models pwgs cannot
    /// undistort itself (fisheye, FOV, FULL_OPENCV, THIN_PRISM_FISHEYE). `path` names the file the
    /// camera came from, for the error.
    pub fn distortion(&self, path: &Path) -> Result<Distortion, DatasetError> {
        self.check_params().map_err(|message| DatasetError::malformed(path, message))?;
        let p = &self.params;
        Ok(match self.model {
            CameraModel::SimplePinhole | CameraModel::Pinhole => Distortion::None,
            CameraModel::SimpleRadial => Distortion::Radial { k1: p[3], k2: 0.0 },
            CameraModel::Radial => Distortion::Radial { k1: p[3], k2: p[4] },
            CameraModel::Opencv => Distortion::Opencv { k1: p[4], k2: p[5], p1: p[6], p2: p[7] },
            unsupported => {
                return Err(DatasetError::unsupported(
                    path,
                    format!(
                        "camera {} uses the {} model, which pwgs cannot undistort; the images must be \
                         undistorted first (e.g. with COLMAP's image_undistorter) and the undistorted \
                         scene loaded instead",
                        self.id,
                        unsupported.name()
                    ),
                ));
            }
        })
    }

    /// Fails when the params do not match the model, since neither format could store them.
    fn check_params(&self) -> Result<(), String> {
        let expected = self.model.param_count();
        if self.params.len() == expected {
            Ok(())
        } else {
            Err(format!(
                "camera {} has {} params, but {} takes {expected}",
                self.id,
                self.params.len(),
                self.model.name()
            ))
        }
    }
}

/// A 2D feature of an image, and the 3D point it observes (-1 when none).
#[derive(Debug, Clone, PartialEq)]
pub struct Point2D {
    pub xy: [f64; 2],
    pub point3d_id: i64,
}

/// One registered image: its world-to-camera pose and the camera it was taken with.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapImage {
    pub id: u32,
    /// World-to-camera rotation as a quaternion (w, x, y, z).
    pub qvec: [f64; 4],
    /// World-to-camera translation.
    pub tvec: [f64; 3],
    pub camera_id: u32,
    pub name: String,
    pub points2d: Vec<Point2D>,
}

/// One observation of a 3D point: an image and the index of a 2D point in it.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackElement {
    pub image_id: u32,
    pub point2d_idx: u32,
}

/// One triangulated point.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapPoint {
    pub id: u64,
    pub xyz: [f64; 3],
    pub rgb: [u8; 3],
    pub error: f64,
    pub track: Vec<TrackElement>,
}

/// A whole sparse model, records in file order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ColmapModel {
    pub cameras: Vec<ColmapCamera>,
    pub images: Vec<ColmapImage>,
    pub points: Vec<ColmapPoint>,
}

/// The model folder of a scene: `sparse/0` (COLMAP's layout) or else `sparse` (common in
/// hand-made datasets), whichever holds `cameras.bin` or `cameras.txt`.
pub fn find_model_dir(scene_dir: &Path) -> Option<PathBuf> {
    let sparse = scene_dir.join("sparse");
    [sparse.join("0"), sparse]
        .into_iter()
        .find(|dir| dir.join("cameras.bin").is_file() || dir.join("cameras.txt").is_file())
}

/// Whether [`read_model`] reads the binary files: when `cameras.bin` exists (COLMAP's default
/// output).
fn is_binary(model_dir: &Path) -> bool {
    model_dir.join("cameras.bin").is_file()
}

/// Reads a model, binary if `cameras.bin` exists (COLMAP's default output), else text.
pub fn read_model(model_dir: &Path) -> Result<ColmapModel, DatasetError> {
    if is_binary(model_dir) { read_binary(model_dir) } else { read_text(model_dir) }
}

/// The file [`read_model`] reads for `stem` (`cameras`, `images` or `points3D`), for errors
/// about the values it held.
pub fn model_file(model_dir: &Path, stem: &str) -> PathBuf {
    model_dir.join(format!("{stem}.{}", if is_binary(model_dir) { "bin" } else { "txt" }))
}

pub fn read_binary(model_dir: &Path) -> Result<ColmapModel, DatasetError> {
    Ok(ColmapModel {
        cameras: read_with(&model_dir.join("cameras.bin"), cameras_from_bin)?,
        images: read_with(&model_dir.join("images.bin"), images_from_bin)?,
        points: read_with(&model_dir.join("points3D.bin"), points_from_bin)?,
    })
}

pub fn read_text(model_dir: &Path) -> Result<ColmapModel, DatasetError> {
    Ok(ColmapModel {
        cameras: read_with(&model_dir.join("cameras.txt"), cameras_from_text)?,
        images: read_with(&model_dir.join("images.txt"), images_from_text)?,
        points: read_with(&model_dir.join("points3D.txt"), points_from_text)?,
    })
}

/// Writes `cameras.bin`, `images.bin` and `points3D.bin`, creating the folder. Nothing is written
/// when the model cannot be stored (params not matching a model, a name holding a 0 byte).
pub fn write_binary(model: &ColmapModel, model_dir: &Path) -> Result<(), DatasetError> {
    write_files(
        model_dir,
        [
            ("cameras.bin", cameras_to_bin(&model.cameras)),
            ("images.bin", images_to_bin(&model.images)),
            ("points3D.bin", points_to_bin(&model.points)),
        ],
    )
}

/// Writes `cameras.txt`, `images.txt` and `points3D.txt`, creating the folder. Nothing is written
/// when the model cannot be stored (params not matching a model, a name that is empty, has a line
/// break or starts or ends with whitespace).
pub fn write_text(model: &ColmapModel, model_dir: &Path) -> Result<(), DatasetError> {
    write_files(
        model_dir,
        [
            ("cameras.txt", cameras_to_text(&model.cameras).map(String::into_bytes)),
            ("images.txt", images_to_text(&model.images).map(String::into_bytes)),
            ("points3D.txt", points_to_text(&model.points).map(String::into_bytes)),
        ],
    )
}

fn read_with<T>(path: &Path, decode: fn(&Path, &[u8]) -> Result<Vec<T>, DatasetError>) -> Result<Vec<T>, DatasetError> {
    decode(path, &read_file(path)?)
}

/// Writes already encoded files; encoding all of them first means a model that cannot be stored
/// leaves no partial model behind.
fn write_files(dir: &Path, files: [(&str, Result<Vec<u8>, String>); 3]) -> Result<(), DatasetError> {
    let encoded = files
        .into_iter()
        .map(|(name, bytes)| {
            let path = dir.join(name);
            match bytes {
                Ok(bytes) => Ok((path, bytes)),
                Err(message) => Err(DatasetError::malformed(path, message)),
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    std::fs::create_dir_all(dir).map_err(|e| DatasetError::io(dir, e))?;
    for (path, bytes) in encoded {
        std::fs::write(&path, bytes).map_err(|e| DatasetError::io(&path, e))?;
    }
    Ok(())
}

/// Records an id, failing when it was seen before: lookups by id would silently pick one of two.
fn check_unique(seen: &mut HashSet<u64>, kind: &str, id: u64) -> Result<(), String> {
    if seen.insert(id) { Ok(()) } else { Err(format!("{kind} id {id} appears more than once")) }
}

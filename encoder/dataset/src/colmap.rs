//! COLMAP sparse models (`cameras`, `images`, `points3D`) in COLMAP's binary and text formats.
//!
//! These files come from other tools and from users, so reading is defensive: every error names
//! the file (and, for text, the line), a truncated file is an error rather than a panic, and a
//! binary count is checked against the bytes left before anything is allocated, so a corrupt
//! count fails at once instead of exhausting memory. Values are not judged here (a NaN pose reads
//! as NaN): the scene loader decides what it can use.
//!
//! COLMAP documents camera, image and 2D point ids as `int`, but writes them as `uint32`; the two
//! agree below 2^31, and reading them as `u32` accepts every file COLMAP can write.
//!
//! Text is written with Rust's shortest round-trip float formatting, so text round trips are exact.

use std::collections::HashSet;
use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::str::FromStr;

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

/// Reads a model, binary if `cameras.bin` exists (COLMAP's default output), else text.
pub fn read_model(model_dir: &Path) -> Result<ColmapModel, DatasetError> {
    if model_dir.join("cameras.bin").is_file() { read_binary(model_dir) } else { read_text(model_dir) }
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

// ---------------------------------------------------------------------------------------------
// Binary reading

/// Smallest size of each binary record, to bound declared counts by the bytes actually left.
const CAMERA_MIN_BYTES: usize = 4 + 4 + 8 + 8 + 3 * 8; // SIMPLE_PINHOLE, 3 params
const IMAGE_MIN_BYTES: usize = 4 + 7 * 8 + 4 + 1 + 8; // empty name, no 2D points
const POINT2D_BYTES: usize = 2 * 8 + 8;
const POINT3D_MIN_BYTES: usize = 8 + 3 * 8 + 3 + 8 + 8; // empty track
const TRACK_ELEMENT_BYTES: usize = 4 + 4;

/// Reads little-endian values from a binary file, turning every overrun into an error that names
/// the file, the byte offset and the record being read.
struct ByteCursor<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
    /// (1-based index, count) of the top-level record being read, for error messages.
    record: Option<(usize, usize)>,
}

impl<'a> ByteCursor<'a> {
    fn new(path: &'a Path, bytes: &'a [u8]) -> Self {
        Self { path, bytes, pos: 0, record: None }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn error(&self, message: impl Display) -> DatasetError {
        let record = self.record.map(|(index, count)| format!(", record {index} of {count}")).unwrap_or_default();
        DatasetError::malformed(self.path, format!("byte {}{record}: {message}", self.pos))
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], DatasetError> {
        let bytes: &'a [u8] = self.bytes;
        let Some(chunk) = bytes[self.pos..].first_chunk::<N>() else {
            return Err(
                self.error(format!("file ends while reading {what} ({N} bytes needed, {} left)", self.remaining()))
            );
        };
        self.pos += N;
        Ok(*chunk)
    }

    fn u32(&mut self, what: &str) -> Result<u32, DatasetError> {
        self.take(what).map(u32::from_le_bytes)
    }

    fn i32(&mut self, what: &str) -> Result<i32, DatasetError> {
        self.take(what).map(i32::from_le_bytes)
    }

    fn u64(&mut self, what: &str) -> Result<u64, DatasetError> {
        self.take(what).map(u64::from_le_bytes)
    }

    fn i64(&mut self, what: &str) -> Result<i64, DatasetError> {
        self.take(what).map(i64::from_le_bytes)
    }

    fn f64(&mut self, what: &str) -> Result<f64, DatasetError> {
        self.take(what).map(f64::from_le_bytes)
    }

    fn f64s<const N: usize>(&mut self, what: &str) -> Result<[f64; N], DatasetError> {
        let mut values = [0.0; N];
        for value in &mut values {
            *value = self.f64(what)?;
        }
        Ok(values)
    }

    /// Reads a record count and checks that the bytes left can hold that many records of at
    /// least `min_bytes` each, so that a corrupt count fails here rather than in an allocation.
    fn count(&mut self, what: &str, min_bytes: usize) -> Result<usize, DatasetError> {
        let count = self.u64(what)?;
        let room = self.remaining() / min_bytes;
        match usize::try_from(count) {
            Ok(count) if count <= room => Ok(count),
            _ => Err(self.error(format!(
                "{what} is {count}, but the {} bytes left hold at most {room} ({min_bytes} bytes or more each); \
                 the file is truncated or corrupt",
                self.remaining()
            ))),
        }
    }

    /// Reads a 0-terminated UTF-8 string.
    fn c_string(&mut self, what: &str) -> Result<String, DatasetError> {
        let rest: &'a [u8] = &self.bytes[self.pos..];
        let Some(len) = rest.iter().position(|&b| b == 0) else {
            return Err(self.error(format!("file ends inside {what} (no terminating 0 byte)")));
        };
        let text = std::str::from_utf8(&rest[..len]).map_err(|e| {
            self.error(format!("{what} {:?} is not valid UTF-8 ({e})", String::from_utf8_lossy(&rest[..len])))
        })?;
        self.pos += len + 1;
        Ok(text.to_owned())
    }

    /// Reads a count, then that many records with `read`, rejecting repeated ids.
    fn records<T>(
        &mut self,
        kind: &str,
        min_bytes: usize,
        id: fn(&T) -> u64,
        read: fn(&mut Self) -> Result<T, DatasetError>,
    ) -> Result<Vec<T>, DatasetError> {
        let count = self.count(&format!("the number of {kind}s"), min_bytes)?;
        let mut seen = HashSet::with_capacity(count);
        let mut records = Vec::with_capacity(count);
        for index in 0..count {
            self.record = Some((index + 1, count));
            let record = read(self)?;
            check_unique(&mut seen, kind, id(&record)).map_err(|message| self.error(message))?;
            records.push(record);
        }
        self.record = None;
        Ok(records)
    }

    /// Fails on bytes after the last record: they mean the records were misread.
    fn finish(&self) -> Result<(), DatasetError> {
        match self.remaining() {
            0 => Ok(()),
            left => Err(self.error(format!("{left} unexpected bytes after the last record"))),
        }
    }
}

/// Parses a whole binary file of records.
fn decode_bin<T>(
    path: &Path,
    bytes: &[u8],
    kind: &str,
    min_bytes: usize,
    id: fn(&T) -> u64,
    read: fn(&mut ByteCursor) -> Result<T, DatasetError>,
) -> Result<Vec<T>, DatasetError> {
    let mut cursor = ByteCursor::new(path, bytes);
    let records = cursor.records(kind, min_bytes, id, read)?;
    cursor.finish()?;
    Ok(records)
}

fn cameras_from_bin(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapCamera>, DatasetError> {
    decode_bin(path, bytes, "camera", CAMERA_MIN_BYTES, |camera| camera.id.into(), read_camera)
}

fn images_from_bin(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>, DatasetError> {
    decode_bin(path, bytes, "image", IMAGE_MIN_BYTES, |image| image.id.into(), read_image)
}

fn points_from_bin(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapPoint>, DatasetError> {
    decode_bin(path, bytes, "point", POINT3D_MIN_BYTES, |point| point.id, read_point)
}

fn read_camera(c: &mut ByteCursor) -> Result<ColmapCamera, DatasetError> {
    let id = c.u32("camera_id")?;
    let model_id = c.i32("model_id")?;
    let model = CameraModel::from_id(model_id)
        .ok_or_else(|| c.error(format!("camera {id} has unknown camera model id {model_id} (known ids: 0 to 10)")))?;
    let width = c.u64("width")?;
    let height = c.u64("height")?;
    let params = (0..model.param_count()).map(|_| c.f64("params")).collect::<Result<_, _>>()?;
    Ok(ColmapCamera { id, model, width, height, params })
}

fn read_image(c: &mut ByteCursor) -> Result<ColmapImage, DatasetError> {
    let id = c.u32("image_id")?;
    let qvec = c.f64s("qvec")?;
    let tvec = c.f64s("tvec")?;
    let camera_id = c.u32("camera_id")?;
    let name = c.c_string("name")?;
    let count = c.count("num_points2D", POINT2D_BYTES)?;
    let points2d = (0..count)
        .map(|_| Ok(Point2D { xy: c.f64s("point2D xy")?, point3d_id: c.i64("point2D point3D_id")? }))
        .collect::<Result<_, DatasetError>>()?;
    Ok(ColmapImage { id, qvec, tvec, camera_id, name, points2d })
}

fn read_point(c: &mut ByteCursor) -> Result<ColmapPoint, DatasetError> {
    let id = c.u64("point3D_id")?;
    let xyz = c.f64s("xyz")?;
    let rgb = c.take("rgb")?;
    let error = c.f64("error")?;
    let count = c.count("track_length", TRACK_ELEMENT_BYTES)?;
    let track = (0..count)
        .map(|_| Ok(TrackElement { image_id: c.u32("track image_id")?, point2d_idx: c.u32("track point2D_idx")? }))
        .collect::<Result<_, DatasetError>>()?;
    Ok(ColmapPoint { id, xyz, rgb, error, track })
}

// ---------------------------------------------------------------------------------------------
// Binary writing

fn count_bytes(count: usize) -> Vec<u8> {
    (count as u64).to_le_bytes().to_vec()
}

fn cameras_to_bin(cameras: &[ColmapCamera]) -> Result<Vec<u8>, String> {
    let mut out = count_bytes(cameras.len());
    for camera in cameras {
        camera.check_params()?;
        out.extend(camera.id.to_le_bytes());
        out.extend(camera.model.id().to_le_bytes());
        out.extend(camera.width.to_le_bytes());
        out.extend(camera.height.to_le_bytes());
        out.extend(camera.params.iter().flat_map(|p| p.to_le_bytes()));
    }
    Ok(out)
}

fn images_to_bin(images: &[ColmapImage]) -> Result<Vec<u8>, String> {
    let mut out = count_bytes(images.len());
    for image in images {
        if image.name.contains('\0') {
            return Err(format!("image {} has a 0 byte in its name {:?}", image.id, image.name));
        }
        out.extend(image.id.to_le_bytes());
        out.extend(image.qvec.iter().chain(&image.tvec).flat_map(|v| v.to_le_bytes()));
        out.extend(image.camera_id.to_le_bytes());
        out.extend(image.name.as_bytes());
        out.push(0);
        out.extend(count_bytes(image.points2d.len()));
        for point in &image.points2d {
            out.extend(point.xy.iter().flat_map(|v| v.to_le_bytes()));
            out.extend(point.point3d_id.to_le_bytes());
        }
    }
    Ok(out)
}

fn points_to_bin(points: &[ColmapPoint]) -> Result<Vec<u8>, String> {
    let mut out = count_bytes(points.len());
    for point in points {
        out.extend(point.id.to_le_bytes());
        out.extend(point.xyz.iter().flat_map(|v| v.to_le_bytes()));
        out.extend(point.rgb);
        out.extend(point.error.to_le_bytes());
        out.extend(count_bytes(point.track.len()));
        for element in &point.track {
            out.extend(element.image_id.to_le_bytes());
            out.extend(element.point2d_idx.to_le_bytes());
        }
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------------
// Text reading

/// The whitespace-separated fields of one line, parsed in order, with errors naming the line.
struct Fields<'a> {
    path: &'a Path,
    line: usize,
    rest: &'a str,
}

impl<'a> Fields<'a> {
    /// `index` is the 0-based line index; messages use 1-based numbers, as editors do.
    fn new(path: &'a Path, index: usize, text: &'a str) -> Self {
        Self { path, line: index + 1, rest: text }
    }

    fn error(&self, message: impl Display) -> DatasetError {
        DatasetError::malformed(self.path, format!("line {}: {message}", self.line))
    }

    fn at_end(&self) -> bool {
        self.rest.trim_start().is_empty()
    }

    fn token(&mut self) -> Option<&'a str> {
        let text = self.rest.trim_start();
        let end = text.find(char::is_whitespace).unwrap_or(text.len());
        let (token, rest) = text.split_at(end);
        self.rest = rest;
        (!token.is_empty()).then_some(token)
    }

    fn next<T: FromStr>(&mut self, what: &str) -> Result<T, DatasetError>
    where
        T::Err: Display,
    {
        let token = self.token().ok_or_else(|| self.error(format!("missing {what}")))?;
        token.parse().map_err(|e| self.error(format!("{what}: cannot parse {token:?} ({e})")))
    }

    /// The rest of the line, trimmed: image names may contain spaces.
    fn rest(&self) -> &'a str {
        self.rest.trim()
    }

    fn check_unique(&self, seen: &mut HashSet<u64>, kind: &str, id: u64) -> Result<(), DatasetError> {
        check_unique(seen, kind, id).map_err(|message| self.error(message))
    }
}

/// Decodes a text file as UTF-8, naming the first line that is not.
fn decode_text<'a>(path: &Path, bytes: &'a [u8]) -> Result<&'a str, DatasetError> {
    std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        DatasetError::malformed(path, format!("line {line}: not valid UTF-8"))
    })
}

/// Whether a line holds data: COLMAP skips blank lines and `#` comments.
fn is_data(line: &str) -> bool {
    let line = line.trim_start();
    !line.is_empty() && !line.starts_with('#')
}

/// The data lines of a one-line-per-record text file.
fn data_lines<'a>(path: &'a Path, text: &'a str) -> impl Iterator<Item = Fields<'a>> {
    text.lines().enumerate().filter(|(_, line)| is_data(line)).map(move |(index, line)| Fields::new(path, index, line))
}

fn cameras_from_text(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapCamera>, DatasetError> {
    let mut seen = HashSet::new();
    data_lines(path, decode_text(path, bytes)?)
        .map(|mut fields| {
            let camera = parse_camera(&mut fields)?;
            fields.check_unique(&mut seen, "camera", camera.id.into())?;
            Ok(camera)
        })
        .collect()
}

fn parse_camera(f: &mut Fields) -> Result<ColmapCamera, DatasetError> {
    let id = f.next("CAMERA_ID")?;
    let name: String = f.next("MODEL")?;
    let model = CameraModel::from_name(&name)
        .ok_or_else(|| f.error(format!("camera {id} has unknown camera model {name:?}")))?;
    let width = f.next("WIDTH")?;
    let height = f.next("HEIGHT")?;
    let mut params = Vec::new();
    while !f.at_end() {
        params.push(f.next("PARAMS")?);
    }
    let camera = ColmapCamera { id, model, width, height, params };
    camera.check_params().map_err(|message| f.error(message))?;
    Ok(camera)
}

/// Images take two lines each: the pose, then the 2D points (a line that may be empty, and that
/// may be missing altogether after the last image).
fn images_from_text(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>, DatasetError> {
    let mut seen = HashSet::new();
    let mut images = Vec::new();
    let mut lines = decode_text(path, bytes)?.lines().enumerate();
    while let Some((index, line)) = lines.next() {
        if !is_data(line) {
            continue;
        }
        let mut fields = Fields::new(path, index, line);
        let mut image = parse_image(&mut fields)?;
        fields.check_unique(&mut seen, "image", image.id.into())?;
        if let Some((index, line)) = lines.next() {
            image.points2d = parse_points2d(&mut Fields::new(path, index, line))?;
        }
        images.push(image);
    }
    Ok(images)
}

fn parse_image(f: &mut Fields) -> Result<ColmapImage, DatasetError> {
    let id = f.next("IMAGE_ID")?;
    let qvec = [f.next("QW")?, f.next("QX")?, f.next("QY")?, f.next("QZ")?];
    let tvec = [f.next("TX")?, f.next("TY")?, f.next("TZ")?];
    let camera_id = f.next("CAMERA_ID")?;
    let name = f.rest();
    if name.is_empty() {
        return Err(f.error("missing NAME"));
    }
    Ok(ColmapImage { id, qvec, tvec, camera_id, name: name.to_owned(), points2d: Vec::new() })
}

fn parse_points2d(f: &mut Fields) -> Result<Vec<Point2D>, DatasetError> {
    let mut points = Vec::new();
    while !f.at_end() {
        let xy = [f.next("2D point X")?, f.next("2D point Y")?];
        points.push(Point2D { xy, point3d_id: f.next("2D point POINT3D_ID")? });
    }
    Ok(points)
}

fn points_from_text(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapPoint>, DatasetError> {
    let mut seen = HashSet::new();
    data_lines(path, decode_text(path, bytes)?)
        .map(|mut fields| {
            let point = parse_point(&mut fields)?;
            fields.check_unique(&mut seen, "point", point.id)?;
            Ok(point)
        })
        .collect()
}

fn parse_point(f: &mut Fields) -> Result<ColmapPoint, DatasetError> {
    let id = f.next("POINT3D_ID")?;
    let xyz = [f.next("X")?, f.next("Y")?, f.next("Z")?];
    let rgb = [f.next("R")?, f.next("G")?, f.next("B")?];
    let error = f.next("ERROR")?;
    let mut track = Vec::new();
    while !f.at_end() {
        track.push(TrackElement { image_id: f.next("track IMAGE_ID")?, point2d_idx: f.next("track POINT2D_IDX")? });
    }
    Ok(ColmapPoint { id, xyz, rgb, error, track })
}

// ---------------------------------------------------------------------------------------------
// Text writing

fn spaced<T: Display>(values: impl IntoIterator<Item = T>) -> String {
    values.into_iter().map(|v| v.to_string()).collect::<Vec<_>>().join(" ")
}

/// The mean of a per-record count, for COLMAP's informational header lines.
fn mean(total: usize, count: usize) -> f64 {
    if count == 0 { 0.0 } else { total as f64 / count as f64 }
}

fn cameras_to_text(cameras: &[ColmapCamera]) -> Result<String, String> {
    let mut out = format!(
        "# Camera list with one line of data per camera:\n\
         #   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n\
         # Number of cameras: {}\n",
        cameras.len()
    );
    for c in cameras {
        c.check_params()?;
        out += &format!("{} {} {} {} {}\n", c.id, c.model.name(), c.width, c.height, spaced(&c.params));
    }
    Ok(out)
}

/// Fails on names the line-based format cannot hold unchanged.
fn check_text_name(image: &ColmapImage) -> Result<(), String> {
    let name = &image.name;
    if name.is_empty() || name.trim() != name || name.contains(['\n', '\r']) {
        Err(format!(
            "image {} has name {name:?}, which images.txt cannot store (empty, line break, or whitespace at an end)",
            image.id
        ))
    } else {
        Ok(())
    }
}

fn images_to_text(images: &[ColmapImage]) -> Result<String, String> {
    let observations = images.iter().map(|image| image.points2d.len()).sum();
    let mut out = format!(
        "# Image list with two lines of data per image:\n\
         #   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n\
         #   POINTS2D[] as (X, Y, POINT3D_ID)\n\
         # Number of images: {}, mean observations per image: {}\n",
        images.len(),
        mean(observations, images.len())
    );
    for image in images {
        check_text_name(image)?;
        let points = image.points2d.iter().map(|p| format!("{} {} {}", p.xy[0], p.xy[1], p.point3d_id));
        out += &format!(
            "{} {} {} {} {}\n{}\n",
            image.id,
            spaced(image.qvec),
            spaced(image.tvec),
            image.camera_id,
            image.name,
            spaced(points)
        );
    }
    Ok(out)
}

fn points_to_text(points: &[ColmapPoint]) -> Result<String, String> {
    let observations = points.iter().map(|point| point.track.len()).sum();
    let mut out = format!(
        "# 3D point list with one line of data per point:\n\
         #   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n\
         # Number of points: {}, mean track length: {}\n",
        points.len(),
        mean(observations, points.len())
    );
    for p in points {
        let track = p.track.iter().map(|t| format!("{} {}", t.image_id, t.point2d_idx));
        let line = format!("{} {} {} {} {}", p.id, spaced(p.xyz), spaced(p.rgb), p.error, spaced(track));
        out += line.trim_end();
        out.push('\n');
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model exercising every branch of both formats: several camera models, images with and
    /// without 2D points (one name with spaces and non-ASCII), ids above 2^31, awkward floats.
    fn sample_model() -> ColmapModel {
        let camera = |id, model, width, height, params: Vec<f64>| ColmapCamera { id, model, width, height, params };
        let point2d = |x, y, point3d_id| Point2D { xy: [x, y], point3d_id };
        let track = |pairs: &[(u32, u32)]| {
            pairs.iter().map(|&(image_id, point2d_idx)| TrackElement { image_id, point2d_idx }).collect()
        };
        ColmapModel {
            cameras: vec![
                camera(1, CameraModel::SimplePinhole, 640, 480, vec![500.25, 320.0, 240.5]),
                camera(2, CameraModel::SimpleRadial, 4032, 3024, vec![3260.5, 2016.0, 1512.0, 0.0198]),
                camera(7, CameraModel::Opencv, 1920, 1080, vec![1000.1, 1001.2, 960.3, 540.4, -0.1, 0.01, 1e-4, -2e-5]),
                camera(
                    9,
                    CameraModel::ThinPrismFisheye,
                    100,
                    50,
                    (0..12).map(|i| f64::from(i) * 0.1 + 1.0 / 3.0).collect(),
                ),
            ],
            images: vec![
                ColmapImage {
                    id: 1,
                    qvec: [0.9, 0.1, -0.3, 0.2],
                    tvec: [0.1 + 0.2, -5e-324, 1e300],
                    camera_id: 2,
                    name: "IMG_4026.JPG".into(),
                    points2d: vec![point2d(10.5, 20.25, 0), point2d(-1.0, 1e-10, -1), point2d(3.0, 4.0, 5)],
                },
                ColmapImage {
                    id: 3,
                    qvec: [1.0, 0.0, 0.0, 0.0],
                    tvec: [0.0, -0.0, f64::MAX],
                    camera_id: 1,
                    name: "sub dir/ümlaut 2.png".into(),
                    points2d: vec![],
                },
                ColmapImage {
                    id: 4_000_000_000,
                    qvec: [0.5, 0.5, 0.5, -0.5],
                    tvec: [1.0 / 3.0, 2.0, -3.5],
                    camera_id: 9,
                    name: "x".into(),
                    points2d: vec![point2d(0.5, 0.5, 0)],
                },
            ],
            points: vec![
                ColmapPoint {
                    id: 0,
                    xyz: [1.5, -2.25, 1.0 / 7.0],
                    rgb: [0, 128, 255],
                    error: 0.75,
                    track: track(&[(1, 0), (4_000_000_000, 0)]),
                },
                ColmapPoint { id: 5, xyz: [-1e-7, 3e8, 0.0], rgb: [1, 2, 3], error: 1.25, track: track(&[(1, 2)]) },
                ColmapPoint { id: u64::MAX, xyz: [0.1, 0.2, 0.3], rgb: [9, 9, 9], error: 0.0, track: vec![] },
            ],
        }
    }

    type Decode = fn(&Path, &[u8]) -> Result<(), DatasetError>;

    /// The sample model's binary files, each with its decoder.
    fn binary_files(model: &ColmapModel) -> [(&'static str, Vec<u8>, Decode); 3] {
        [
            ("cameras.bin", cameras_to_bin(&model.cameras).unwrap(), |p, b| cameras_from_bin(p, b).map(drop)),
            ("images.bin", images_to_bin(&model.images).unwrap(), |p, b| images_from_bin(p, b).map(drop)),
            ("points3D.bin", points_to_bin(&model.points).unwrap(), |p, b| points_from_bin(p, b).map(drop)),
        ]
    }

    #[test]
    fn binary_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let model = sample_model();
        write_binary(&model, dir.path()).unwrap();
        assert_eq!(read_binary(dir.path()).unwrap(), model);
        assert_eq!(read_model(dir.path()).unwrap(), model);
    }

    #[test]
    fn text_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let model = sample_model();
        write_text(&model, dir.path()).unwrap();
        assert_eq!(read_text(dir.path()).unwrap(), model);
        assert_eq!(read_model(dir.path()).unwrap(), model, "without cameras.bin, read_model reads text");
    }

    #[test]
    fn empty_model_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        write_binary(&ColmapModel::default(), &dir.path().join("bin")).unwrap();
        write_text(&ColmapModel::default(), &dir.path().join("txt")).unwrap();
        assert_eq!(read_binary(&dir.path().join("bin")).unwrap(), ColmapModel::default());
        assert_eq!(read_text(&dir.path().join("txt")).unwrap(), ColmapModel::default());
    }

    #[test]
    fn non_finite_poses_are_left_to_the_loader() {
        let mut model = sample_model();
        model.images[0].qvec[0] = f64::NAN;
        model.images[0].tvec[2] = f64::NEG_INFINITY;
        type Write = fn(&ColmapModel, &Path) -> Result<(), DatasetError>;
        type Read = fn(&Path) -> Result<ColmapModel, DatasetError>;
        for (write, read) in [(write_binary as Write, read_binary as Read), (write_text, read_text)] {
            let dir = tempfile::tempdir().unwrap();
            write(&model, dir.path()).unwrap();
            let image = &read(dir.path()).unwrap().images[0];
            assert!(image.qvec[0].is_nan());
            assert_eq!(image.tvec[2], f64::NEG_INFINITY);
        }
    }

    #[test]
    fn every_truncation_of_a_binary_file_is_an_error() {
        for (name, bytes, decode) in binary_files(&sample_model()) {
            let path = Path::new(name);
            decode(path, &bytes).unwrap();
            for len in 0..bytes.len() {
                let err = decode(path, &bytes[..len]).expect_err(&format!("{name} cut at {len}")).to_string();
                assert!(err.starts_with(&format!("{name}: byte ")), "{err}");
            }
        }
    }

    #[test]
    fn a_truncated_file_on_disk_is_named() {
        let dir = tempfile::tempdir().unwrap();
        write_binary(&sample_model(), dir.path()).unwrap();
        let path = dir.path().join("points3D.bin");
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
        let err = read_model(dir.path()).unwrap_err().to_string();
        assert!(err.contains("points3D.bin") && err.contains("record 3 of 3") && err.contains("file ends"), "{err}");
    }

    #[test]
    fn trailing_bytes_are_an_error() {
        for (name, mut bytes, decode) in binary_files(&sample_model()) {
            bytes.push(0);
            let err = decode(Path::new(name), &bytes).unwrap_err().to_string();
            assert!(err.contains("1 unexpected bytes after the last record"), "{err}");
        }
    }

    #[test]
    fn huge_counts_fail_before_allocating() {
        let huge = (1u64 << 60).to_le_bytes();
        let mut bytes = huge.to_vec();
        bytes.extend([0; 100]);
        for (name, _, decode) in binary_files(&sample_model()) {
            let err = decode(Path::new(name), &bytes).unwrap_err().to_string();
            assert!(err.contains("is 1152921504606846976") && err.contains("100 bytes left"), "{err}");
        }
        // Nested counts: an image without 2D points and a point without a track end with them.
        let model = sample_model();
        let with_huge_tail = |mut bytes: Vec<u8>| {
            let at = bytes.len() - 8;
            bytes[at..].copy_from_slice(&huge);
            bytes
        };
        let images = with_huge_tail(images_to_bin(&model.images[1..2]).unwrap());
        let err = images_from_bin(Path::new("images.bin"), &images).unwrap_err().to_string();
        assert!(err.contains("num_points2D is 1152921504606846976"), "{err}");
        let points = with_huge_tail(points_to_bin(&model.points[2..]).unwrap());
        let err = points_from_bin(Path::new("points3D.bin"), &points).unwrap_err().to_string();
        assert!(err.contains("track_length is 1152921504606846976"), "{err}");
    }

    #[test]
    fn unknown_model_id_names_file_camera_and_id() {
        let mut bytes = cameras_to_bin(&sample_model().cameras[2..3]).unwrap();
        bytes[12..16].copy_from_slice(&42i32.to_le_bytes()); // after the count and the camera id
        let err = cameras_from_bin(Path::new("scene/cameras.bin"), &bytes).unwrap_err().to_string();
        assert!(err.starts_with("scene/cameras.bin: ") && err.contains("camera 7") && err.contains("id 42"), "{err}");
    }

    #[test]
    fn non_utf8_names_are_errors() {
        let model = sample_model();
        let mut bytes = images_to_bin(&model.images).unwrap();
        let at = bytes.windows(3).position(|w| w == b"IMG").unwrap();
        bytes[at] = 0xFF;
        let err = images_from_bin(Path::new("images.bin"), &bytes).unwrap_err().to_string();
        assert!(err.contains("record 1 of 3") && err.contains("not valid UTF-8"), "{err}");

        let dir = tempfile::tempdir().unwrap();
        write_text(&model, dir.path()).unwrap();
        let path = dir.path().join("images.txt");
        let mut bytes = std::fs::read(&path).unwrap();
        let at = bytes.windows(3).position(|w| w == b"IMG").unwrap();
        bytes[at] = 0xFE;
        std::fs::write(&path, bytes).unwrap();
        let err = read_text(dir.path()).unwrap_err().to_string();
        assert!(err.contains("images.txt: line 5: not valid UTF-8"), "{err}");
    }

    #[test]
    fn repeated_ids_are_errors() {
        let model = sample_model();
        let twice = [model.cameras[1].clone(), model.cameras[1].clone()];
        let err = cameras_from_bin(Path::new("cameras.bin"), &cameras_to_bin(&twice).unwrap()).unwrap_err();
        assert!(err.to_string().contains("record 2 of 2: camera id 2 appears more than once"), "{err}");
        let text = points_to_text(&[model.points[0].clone(), model.points[0].clone()]).unwrap();
        let err = points_from_text(Path::new("points3D.txt"), text.as_bytes()).unwrap_err();
        assert!(err.to_string().contains("line 5: point id 0 appears more than once"), "{err}");
    }

    /// Replaces one line (1-based) of a text file of the sample model and returns the read error.
    fn text_error_with_line(file: &str, number: usize, replacement: &str) -> String {
        let dir = tempfile::tempdir().unwrap();
        write_text(&sample_model(), dir.path()).unwrap();
        let path = dir.path().join(file);
        let mut lines: Vec<String> = std::fs::read_to_string(&path).unwrap().lines().map(String::from).collect();
        lines[number - 1] = replacement.to_owned();
        std::fs::write(&path, lines.join("\n")).unwrap();
        read_text(dir.path()).unwrap_err().to_string()
    }

    #[test]
    fn bad_text_lines_are_errors_naming_the_line() {
        // Headers: cameras.txt and points3D.txt 3 lines, images.txt 4 lines.
        let cases = [
            (
                "cameras.txt",
                4,
                "1 SIMPLE_PINHOLE 640 480 500 320",
                "cameras.txt: line 4: camera 1 has 2 params, but SIMPLE_PINHOLE takes 3",
            ),
            (
                "cameras.txt",
                5,
                "2 FANCY 640 480 1 2 3",
                "cameras.txt: line 5: camera 2 has unknown camera model \"FANCY\"",
            ),
            ("cameras.txt", 6, "7 OPENCV 1920", "cameras.txt: line 6: missing HEIGHT"),
            ("images.txt", 5, "1 abc 0 0 0 0 0 0 2 a.png", "images.txt: line 5: QW: cannot parse \"abc\""),
            ("images.txt", 7, "3 1 0 0 0 0 0 0 1", "images.txt: line 7: missing NAME"),
            ("images.txt", 6, "10.5 20.25 0 1 2", "images.txt: line 6: missing 2D point POINT3D_ID"),
            ("points3D.txt", 4, "0 1 2 3 300 0 0 0.5", "points3D.txt: line 4: R: cannot parse \"300\""),
            ("points3D.txt", 5, "5 1 2 3 1 2 3 0.5 1", "points3D.txt: line 5: missing track POINT2D_IDX"),
        ];
        for (file, number, replacement, expected) in cases {
            let err = text_error_with_line(file, number, replacement);
            assert!(err.contains(expected), "expected {expected:?} in {err:?}");
        }
    }

    #[test]
    fn writers_refuse_what_they_cannot_store_and_write_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let mut model = sample_model();
        model.cameras[0].params.pop();
        let err = write_binary(&model, dir.path()).unwrap_err().to_string();
        assert!(err.contains("cameras.bin: camera 1 has 2 params, but SIMPLE_PINHOLE takes 3"), "{err}");
        assert!(write_text(&model, dir.path()).is_err());

        let mut model = sample_model();
        model.images[1].name = "a\0b".into();
        assert!(write_binary(&model, dir.path()).unwrap_err().to_string().contains("0 byte"));
        for name in ["", " a", "a\nb", "a\t"] {
            model.images[1].name = name.into();
            assert!(write_text(&model, dir.path()).unwrap_err().to_string().contains("images.txt cannot store"));
        }
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "a refused model leaves no files");
    }

    #[test]
    fn model_ids_names_and_param_counts() {
        for (id, model) in CameraModel::ALL.into_iter().enumerate() {
            assert_eq!(CameraModel::from_id(model.id()), Some(model));
            assert_eq!(model.id() as usize, id);
            assert_eq!(CameraModel::from_name(model.name()), Some(model));
        }
        assert_eq!(CameraModel::from_id(11), None);
        assert_eq!(CameraModel::from_id(-1), None);
        assert_eq!(CameraModel::from_name("pinhole"), None);
        let counts = CameraModel::ALL.map(CameraModel::param_count);
        assert_eq!(counts, [3, 4, 4, 5, 8, 8, 12, 5, 4, 5, 12]);
    }

    #[test]
    fn pinhole_and_distortion_follow_the_model() {
        let path = Path::new("cameras.bin");
        let cameras = sample_model().cameras;
        assert_eq!(cameras[0].pinhole(), [500.25, 500.25, 320.0, 240.5]);
        assert_eq!(cameras[0].distortion(path).unwrap(), Distortion::None);
        assert_eq!(cameras[1].pinhole(), [3260.5, 3260.5, 2016.0, 1512.0]);
        assert_eq!(cameras[1].distortion(path).unwrap(), Distortion::Radial { k1: 0.0198, k2: 0.0 });
        assert_eq!(cameras[2].pinhole(), [1000.1, 1001.2, 960.3, 540.4]);
        let opencv = Distortion::Opencv { k1: -0.1, k2: 0.01, p1: 1e-4, p2: -2e-5 };
        assert_eq!(cameras[2].distortion(path).unwrap(), opencv);
        let radial = ColmapCamera {
            id: 4,
            model: CameraModel::Radial,
            width: 8,
            height: 6,
            params: vec![5.0, 4.0, 3.0, 0.1, 0.2],
        };
        assert_eq!(radial.distortion(path).unwrap(), Distortion::Radial { k1: 0.1, k2: 0.2 });

        let err = cameras[3].distortion(path).unwrap_err();
        assert!(matches!(err, DatasetError::Unsupported { .. }), "{err:?}");
        let message = err.to_string();
        assert!(
            message.contains("camera 9 uses the THIN_PRISM_FISHEYE model") && message.contains("image_undistorter"),
            "{message}"
        );

        let short = ColmapCamera { params: vec![1.0], ..cameras[2].clone() };
        assert!(short.pinhole()[1].is_nan());
        assert!(short.distortion(path).is_err());
    }

    #[test]
    fn find_model_dir_prefers_sparse_0() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(find_model_dir(dir.path()), None);
        let sparse = dir.path().join("sparse");
        write_text(&sample_model(), &sparse).unwrap();
        assert_eq!(find_model_dir(dir.path()), Some(sparse.clone()));
        std::fs::create_dir(sparse.join("0")).unwrap();
        assert_eq!(find_model_dir(dir.path()), Some(sparse.clone()), "an empty sparse/0 is not a model");
        write_binary(&sample_model(), &sparse.join("0")).unwrap();
        assert_eq!(find_model_dir(dir.path()), Some(sparse.join("0")));
    }

    #[test]
    fn reads_the_fern_model() {
        let scene = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/scenes/fern"));
        let Some(dir) = find_model_dir(scene) else {
            println!("skipped: no COLMAP model under {} (the shared scenes folder is absent)", scene.display());
            return;
        };
        let model = read_model(&dir).unwrap();
        assert_eq!(model.cameras.len(), 1);
        let camera = &model.cameras[0];
        assert_eq!((camera.model, camera.width, camera.height), (CameraModel::SimpleRadial, 4032, 3024));
        assert!((camera.params[0] - 3260.5).abs() < 1.0, "{camera:?}");
        assert!(matches!(camera.distortion(&dir).unwrap(), Distortion::Radial { .. }));
        assert_eq!(model.images.len(), 20);
        assert!(model.images.iter().all(|image| image.name.starts_with("IMG_") && image.camera_id == camera.id));
        assert_eq!(model.points.len(), 10_091);
        assert!(model.points.iter().all(|point| point.xyz.iter().all(|v| v.is_finite())));
    }
}

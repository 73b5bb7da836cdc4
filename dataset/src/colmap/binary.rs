//! COLMAP's binary model files: a little-endian `u64` record count, then the records. Every
//! overrun is an error naming the file, the byte offset and the record, and every count is
//! checked against the bytes left before anything is allocated.

use std::collections::HashSet;
use std::fmt::Display;
use std::path::Path;

use super::{CameraModel, ColmapCamera, ColmapImage, ColmapPoint, Point2D, TrackElement, check_unique};
use crate::DatasetError;
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

pub(super) fn cameras_from_bin(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapCamera>, DatasetError> {
    decode_bin(path, bytes, "camera", CAMERA_MIN_BYTES, |camera| camera.id.into(), read_camera)
}

pub(super) fn images_from_bin(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>, DatasetError> {
    decode_bin(path, bytes, "image", IMAGE_MIN_BYTES, |image| image.id.into(), read_image)
}

pub(super) fn points_from_bin(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapPoint>, DatasetError> {
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

pub(super) fn cameras_to_bin(cameras: &[ColmapCamera]) -> Result<Vec<u8>, String> {
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

pub(super) fn images_to_bin(images: &[ColmapImage]) -> Result<Vec<u8>, String> {
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

pub(super) fn points_to_bin(points: &[ColmapPoint]) -> Result<Vec<u8>, String> {
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

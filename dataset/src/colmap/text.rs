//! COLMAP's text model files: one record per line (two per image), blank lines and `#`
//! comments skipped; every error names the file and the line.

use std::collections::HashSet;
use std::fmt::Display;
use std::path::Path;
use std::str::FromStr;

use super::{CameraModel, ColmapCamera, ColmapImage, ColmapPoint, Point2D, TrackElement, check_unique};
use crate::DatasetError;
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

pub(super) fn cameras_from_text(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapCamera>, DatasetError> {
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
pub(super) fn images_from_text(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>, DatasetError> {
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

pub(super) fn points_from_text(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapPoint>, DatasetError> {
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

pub(super) fn cameras_to_text(cameras: &[ColmapCamera]) -> Result<String, String> {
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

pub(super) fn images_to_text(images: &[ColmapImage]) -> Result<String, String> {
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

pub(super) fn points_to_text(points: &[ColmapPoint]) -> Result<String, String> {
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

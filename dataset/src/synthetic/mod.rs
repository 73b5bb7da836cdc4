//! The project's own small default scene, generated: a gravel-and-grass ground with four
//! textured objects under a sky gradient, rendered exactly by ray casting analytic shapes from
//! cameras on a ring, and written as a nerfstudio-style `transforms.json` dataset with an
//! SfM-like point cloud.
//!
//! It is the default input and the tests' data, so it has what the codec must cope with:
//! real high-frequency texture that Gaussians blur, edges, occlusion and shadows. Because the
//! images come from an exact, non-Gaussian renderer, a trained model's error against them is
//! honest. Generation is deterministic: every pixel is a pure function of the camera and the
//! seed, so files are bit-identical across runs and thread counts.

mod noise;
mod scene;
mod texture;

use std::path::Path;

use glam::{Mat3, Mat4, Vec3, Vec4};
use pwgs_core::camera::Camera;
use pwgs_core::ply::PointCloud;
use pwgs_core::rgb_image::RgbImage;
use rayon::prelude::*;
use serde::Serialize;

use crate::DatasetError;
use pwgs_core::random::SplitMix64;

/// What to generate.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SyntheticOptions {
    pub width: u32,
    pub height: u32,
    /// Number of cameras on the ring.
    pub views: usize,
    /// Seeds the textures, the camera jitter and the point sampling.
    pub seed: u64,
    /// Number of points in `points3d.ply`.
    pub points: usize,
}

impl Default for SyntheticOptions {
    fn default() -> Self {
        Self { width: 160, height: 120, views: 24, seed: 1, points: 4000 }
    }
}

/// What [`generate`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SyntheticSummary {
    pub views: usize,
    pub width: u32,
    pub height: u32,
    pub points: usize,
}

/// Largest accepted image side.
const MAX_SIZE: u32 = 8192;
/// Bounds on the counts, to turn a typo into an error rather than hours of work or an
/// exhausted disk.
const MAX_VIEWS: usize = 10_000;
const MAX_POINTS: usize = 10_000_000;

/// Point every camera looks at: the middle of the objects, a little above the ground.
const TARGET: Vec3 = Vec3::new(0.0, 0.35, 0.0);
/// Mean camera distance from [`TARGET`]: the objects span about half the image width.
const DISTANCE: f32 = 3.8;
/// Mean elevation of the cameras above the horizontal through [`TARGET`], in degrees.
const ELEVATION_DEG: f32 = 30.0;
/// Focal length as a fraction of the image width (a horizontal field of view of about 58°).
const FOCAL_PER_WIDTH: f32 = 0.9;
/// Sub-pixel samples per pixel side: 3x3 stratified supersampling antialiases edges and texture.
const STRATA: u32 = 3;
/// Point sampling gives up after this many rays per requested point (only a fraction of rays,
/// those into the sky, miss the scene).
const ATTEMPTS_PER_POINT: usize = 64;
/// Salts separating the random streams drawn from one seed.
const CAMERA_SALT: u64 = 0x4341_4d45_5241_0001;
const POINTS_SALT: u64 = 0x504f_494e_5453_0002;

/// Generates the dataset into `dir` (created if missing): `images/view_NNN.png`,
/// `points3d.ply` and, last, `transforms.json`, so that a folder interrupted halfway is not
/// mistaken for a complete dataset.
pub fn generate(dir: &Path, options: &SyntheticOptions) -> Result<SyntheticSummary, DatasetError> {
    validate(dir, options)?;
    let images = dir.join("images");
    std::fs::create_dir_all(&images).map_err(|e| DatasetError::io(&images, e))?;
    let cameras = cameras(options);
    let mut frames = Vec::with_capacity(cameras.len());
    for (index, camera) in cameras.iter().enumerate() {
        let file_path = format!("images/view_{index:03}.png");
        render(camera, options.seed).save_png(&dir.join(&file_path))?;
        frames.push(Frame { file_path, transform_matrix: opengl_camera_to_world_rows(camera) });
    }
    let ply_path = dir.join(PLY_FILE);
    let cloud = sample_points(&cameras, options.points, options.seed)
        .ok_or_else(|| DatasetError::malformed(&ply_path, "too few camera rays hit the scene to sample the points"))?;
    let ply = pwgs_core::ply::point_cloud_to_bytes(&cloud);
    pwgs_core::atomic_file::write_atomically(&ply_path, &ply).map_err(|e| DatasetError::io(&ply_path, e))?;
    let transforms_path = dir.join("transforms.json");
    let json = serde_json::to_vec_pretty(&transforms(&cameras[0], frames))
        .map_err(|e| DatasetError::malformed(&transforms_path, e.to_string()))?;
    pwgs_core::atomic_file::write_atomically(&transforms_path, &json)
        .map_err(|e| DatasetError::io(&transforms_path, e))?;
    Ok(SyntheticSummary {
        views: options.views,
        width: options.width,
        height: options.height,
        points: cloud.positions.len(),
    })
}

fn validate(dir: &Path, options: &SyntheticOptions) -> Result<(), DatasetError> {
    let problem = if !(1..=MAX_SIZE).contains(&options.width) || !(1..=MAX_SIZE).contains(&options.height) {
        format!("image size {}x{} must be between 1 and {MAX_SIZE} per side", options.width, options.height)
    } else if !(1..=MAX_VIEWS).contains(&options.views) {
        format!("{} views requested, must be between 1 and {MAX_VIEWS}", options.views)
    } else if options.points > MAX_POINTS {
        format!("{} points requested, at most {MAX_POINTS} are supported", options.points)
    } else {
        return Ok(());
    };
    Err(DatasetError::malformed(dir, problem))
}

/// The cameras the generator uses (OpenCV convention), so tests can use them without reading
/// files: `views` cameras spread around a ring, each looking at the scene center, with a
/// deterministic jitter of azimuth, elevation (25° to 35°) and distance so that the views are
/// not coplanar. Options are not validated here (see [`generate`]); a zero size gives cameras
/// that render empty images.
pub fn cameras(options: &SyntheticOptions) -> Vec<Camera> {
    let mut rng = SplitMix64(options.seed ^ CAMERA_SALT);
    (0..options.views)
        .map(|index| {
            let azimuth =
                std::f32::consts::TAU * (index as f32 + 0.3 * (rng.uniform(0.0, 1.0) - 0.5)) / options.views as f32;
            let elevation = (ELEVATION_DEG + 10.0 * (rng.uniform(0.0, 1.0) - 0.5)).to_radians();
            let distance = DISTANCE * (1.0 + 0.1 * (rng.uniform(0.0, 1.0) - 0.5));
            let offset = Vec3::new(elevation.cos() * azimuth.cos(), elevation.sin(), elevation.cos() * azimuth.sin());
            look_at(options.width, options.height, TARGET + distance * offset, TARGET)
        })
        .collect()
}

/// A pinhole camera at `eye` looking at `target` with no roll (image x stays horizontal).
fn look_at(width: u32, height: u32, eye: Vec3, target: Vec3) -> Camera {
    let forward = (target - eye).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let down = forward.cross(right);
    // Rows of the world-to-camera rotation are the camera axes in world coordinates; they are
    // orthonormal by construction, so the checks of `Camera::new` have nothing to reject.
    let rotation = Mat3::from_cols(right, down, forward).transpose();
    let focal = FOCAL_PER_WIDTH * width as f32;
    Camera {
        width,
        height,
        fx: focal,
        fy: focal,
        cx: 0.5 * width as f32,
        cy: 0.5 * height as f32,
        rotation,
        translation: -(rotation * eye),
    }
}

/// Renders one view exactly (the ray caster), for tests and for any resolution. Rows are
/// rendered in parallel; each pixel is a pure function of the camera and the seed, so the
/// result does not depend on the thread count.
pub fn render(camera: &Camera, seed: u64) -> RgbImage {
    let (width, height) = (camera.width, camera.height);
    let mut data = vec![0.0; width as usize * height as usize * 3];
    // `max(1)`: a zero-width image has no rows, but chunks must not be empty.
    data.par_chunks_mut((width as usize * 3).max(1)).enumerate().for_each(|(row, out)| {
        for (column, rgb) in out.chunks_exact_mut(3).enumerate() {
            rgb.copy_from_slice(&pixel(camera, seed, column as u32, row as u32).to_array());
        }
    });
    RgbImage { width, height, data }
}

/// Mean of the stratified sub-pixel samples, each clamped to the displayable range first.
fn pixel(camera: &Camera, seed: u64, column: u32, row: u32) -> Vec3 {
    let origin = camera.center();
    let mut sum = Vec3::ZERO;
    for sy in 0..STRATA {
        for sx in 0..STRATA {
            let u = column as f32 + (sx as f32 + 0.5) / STRATA as f32;
            let v = row as f32 + (sy as f32 + 0.5) / STRATA as f32;
            sum += scene::radiance(origin, camera.ray_direction(u, v), seed).clamp(Vec3::ZERO, Vec3::ONE);
        }
    }
    sum / (STRATA * STRATA) as f32
}

/// SfM-like points: the surface points seen through random pixels of random views, with the
/// shaded color there. Like SfM points they lie on visible surfaces, more densely where the
/// views see more. Rays that miss the scene give a point on the sky sphere (radius
/// [`SKY_RADIUS`] around the scene center) with the sky's color, as SfM triangulates distant
/// background features; without them training has nothing to cover the sky with. `None` when
/// too few points were found (never for the ring cameras).
fn sample_points(cameras: &[Camera], count: usize, seed: u64) -> Option<PointCloud> {
    let mut rng = SplitMix64(seed ^ POINTS_SALT);
    let mut cloud = PointCloud::default();
    for _ in 0..count.saturating_mul(ATTEMPTS_PER_POINT) {
        if cloud.positions.len() == count {
            break;
        }
        let camera = &cameras[(rng.next_u64() % cameras.len() as u64) as usize];
        let u = rng.uniform(0.0, 1.0) * camera.width as f32;
        let v = rng.uniform(0.0, 1.0) * camera.height as f32;
        let (origin, direction) = (camera.center(), camera.ray_direction(u, v));
        let (point, color) = match scene::intersect(origin, direction) {
            Some(hit) => (hit.point, scene::shade(&hit, seed)),
            None => (sky_sphere_point(origin, direction), scene::sky(direction)),
        };
        cloud.positions.push(point.to_array());
        cloud.colors.push(color.clamp(Vec3::ZERO, Vec3::ONE).to_array());
    }
    (cloud.positions.len() == count).then_some(cloud)
}

/// Radius of the sphere, around [`TARGET`], on which sky points are placed: several times the
/// camera distance, so the sky sits well behind the scene.
const SKY_RADIUS: f32 = 4.0 * DISTANCE;

/// Where a ray from inside the sky sphere leaves it.
fn sky_sphere_point(origin: Vec3, direction: Vec3) -> Vec3 {
    let offset = origin - TARGET;
    let b = offset.dot(direction);
    let c = offset.length_squared() - SKY_RADIUS * SKY_RADIUS;
    origin + direction * (-b + (b * b - c).sqrt())
}

const PLY_FILE: &str = "points3d.ply";

/// `transforms.json` as nerfstudio writes it (shared intrinsics, per-frame poses).
#[derive(Serialize)]
struct Transforms {
    camera_model: &'static str,
    fl_x: f32,
    fl_y: f32,
    cx: f32,
    cy: f32,
    w: u32,
    h: u32,
    ply_file_path: &'static str,
    frames: Vec<Frame>,
}

#[derive(Serialize)]
struct Frame {
    file_path: String,
    /// Camera-to-world, OpenGL axes (x right, y up, looking down -z), rows.
    transform_matrix: [[f32; 4]; 4],
}

/// The file's header; all ring cameras share the intrinsics of `camera`.
fn transforms(camera: &Camera, frames: Vec<Frame>) -> Transforms {
    Transforms {
        camera_model: "PINHOLE",
        fl_x: camera.fx,
        fl_y: camera.fy,
        cx: camera.cx,
        cy: camera.cy,
        w: camera.width,
        h: camera.height,
        ply_file_path: PLY_FILE,
        frames,
    }
}

/// The camera-to-world matrix in the OpenGL/nerfstudio convention, as rows: the OpenCV one
/// with the camera's y and z axes (columns 1 and 2) flipped.
fn opengl_camera_to_world_rows(camera: &Camera) -> [[f32; 4]; 4] {
    let flip = Mat4::from_diagonal(Vec4::new(1.0, -1.0, -1.0, 1.0));
    (camera.camera_to_world() * flip).transpose().to_cols_array_2d()
}

#[cfg(test)]
mod tests;

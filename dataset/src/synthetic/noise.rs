//! Deterministic hashing and noise for the procedural textures and the camera jitter. Every
//! value is a pure function of integer coordinates and a seed, so an image comes out
//! bit-identical however its pixels are scheduled across threads.

use glam::Vec3;

/// The splitmix64 increment (2^64 / golden ratio).
const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// The splitmix64 finalizer: a cheap, well-mixed 64-bit hash.
pub(super) fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A float in [0, 1) from the top 24 bits of a hash, so every value is exact in f32.
pub(super) fn unit(h: u64) -> f32 {
    (h >> 40) as f32 * (1.0 / 16_777_216.0)
}

/// A second float in [0, 1), independent of [`unit`]'s, from the next 24 bits of the hash.
pub(super) fn unit_low(h: u64) -> f32 {
    ((h >> 16) & 0xFF_FFFF) as f32 * (1.0 / 16_777_216.0)
}

/// Hash of a 3D lattice point. Each coordinate is spread by a different odd constant before
/// mixing, so neighboring points (and swapped coordinates) hash independently.
pub(super) fn lattice(seed: u64, x: i32, y: i32, z: i32) -> u64 {
    let spread = |v: i32, k: u64| u64::from(v as u32).wrapping_mul(k);
    mix64(seed ^ spread(x, GOLDEN) ^ spread(y, 0xC2B2_AE3D_27D4_EB4F) ^ spread(z, 0x1656_67B1_9E37_79F9))
}

/// Quintic fade: C2-continuous interpolation, so shading of the noise shows no lattice creases.
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// Value noise in [0, 1) with one lattice cell per unit.
pub(super) fn value2(seed: u64, x: f32, y: f32) -> f32 {
    let (xf, yf) = (x.floor(), y.floor());
    let (i, j) = (xf as i32, yf as i32);
    let (tx, ty) = (fade(x - xf), fade(y - yf));
    let corner = |di: i32, dj: i32| unit(lattice(seed, i + di, j + dj, 0));
    lerp(lerp(corner(0, 0), corner(1, 0), tx), lerp(corner(0, 1), corner(1, 1), tx), ty)
}

/// Solid value noise in [0, 1): for textures on curved surfaces, which have no seam-free 2D
/// parameterization.
pub(super) fn value3(seed: u64, p: Vec3) -> f32 {
    let f = p.floor();
    let (i, j, k) = (f.x as i32, f.y as i32, f.z as i32);
    let t = p - f;
    let (tx, ty, tz) = (fade(t.x), fade(t.y), fade(t.z));
    let corner = |di: i32, dj: i32, dk: i32| unit(lattice(seed, i + di, j + dj, k + dk));
    let face = |dk: i32| {
        let bottom = lerp(corner(0, 0, dk), corner(1, 0, dk), tx);
        let top = lerp(corner(0, 1, dk), corner(1, 1, dk), tx);
        lerp(bottom, top, ty)
    };
    lerp(face(0), face(1), tz)
}

/// Fractal sum of `octaves` octaves of [`value2`], normalized to [0, 1). Each octave has its
/// own seed so that lattice points of different octaves do not line up.
pub(super) fn fbm2(seed: u64, x: f32, y: f32, octaves: u32) -> f32 {
    let (mut sum, mut norm, mut amplitude, mut frequency) = (0.0, 0.0, 1.0, 1.0);
    for octave in 0..octaves {
        sum += amplitude * value2(seed.wrapping_add(u64::from(octave)), x * frequency, y * frequency);
        norm += amplitude;
        amplitude *= 0.5;
        frequency *= 2.0;
    }
    sum / norm
}

/// Fractal sum of [`value3`], as [`fbm2`].
pub(super) fn fbm3(seed: u64, p: Vec3, octaves: u32) -> f32 {
    let (mut sum, mut norm, mut amplitude, mut frequency) = (0.0, 0.0, 1.0, 1.0);
    for octave in 0..octaves {
        sum += amplitude * value3(seed.wrapping_add(u64::from(octave)), p * frequency);
        norm += amplitude;
        amplitude *= 0.5;
        frequency *= 2.0;
    }
    sum / norm
}

/// The result of a Worley (cellular) lookup.
pub(super) struct Cell {
    /// Distance to the nearest feature point, in lattice units.
    pub(super) nearest: f32,
    /// Distance to the second nearest; `second - nearest` is zero on the border between cells.
    pub(super) second: f32,
    /// Hash of the nearest cell, to give each cell its own color.
    pub(super) id: u64,
}

/// Worley noise with one jittered feature point per lattice cell, searched over the 3x3
/// neighborhood.
pub(super) fn worley2(seed: u64, x: f32, y: f32) -> Cell {
    let (i, j) = (x.floor() as i32, y.floor() as i32);
    let mut cell = Cell { nearest: f32::MAX, second: f32::MAX, id: 0 };
    for dj in -1..=1 {
        for di in -1..=1 {
            let h = lattice(seed, i + di, j + dj, 0);
            let px = (i + di) as f32 + unit(h);
            let py = (j + dj) as f32 + unit(mix64(h));
            let d = ((px - x) * (px - x) + (py - y) * (py - y)).sqrt();
            if d < cell.nearest {
                cell.second = cell.nearest;
                cell.nearest = d;
                cell.id = h;
            } else if d < cell.second {
                cell.second = d;
            }
        }
    }
    cell
}

/// Hermite smoothstep from 0 at `edge0` to 1 at `edge1`.
pub(super) fn smoothstep(edge0: f32, edge1: f32, x: f32) -> f32 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

//! Procedural albedos. Each is defined on the surface (world or object space, never screen
//! space), so every view sees the same texture, and each has detail down to a few pixels at the
//! default resolution: that fine, irregular texture (gravel, grass, brick grit, wood fibers) is
//! what Gaussian splats blur and what the codec's perceptual wrapper has to resynthesize.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

use super::noise::{fbm2, fbm3, lattice, mix64, smoothstep, unit, unit_low, value2, value3, worley2};

/// Salts that keep the noise fields of the different materials independent under one seed.
mod salt {
    pub const PATCH: u64 = 0x5041_5443_4800_0001;
    pub const GRAVEL: u64 = 0x4752_4156_454c_0002;
    pub const GRIT: u64 = 0x4752_4954_0000_0003;
    pub const LEAN: u64 = 0x4c45_414e_0000_0004;
    pub const BLADE: u64 = 0x424c_4144_4500_0005;
    pub const LUSH: u64 = 0x4c55_5348_0000_0006;
    pub const PAINT: u64 = 0x5041_494e_5400_0007;
    pub const BRICK: u64 = 0x4252_4943_4b00_0008;
    pub const GRAIN: u64 = 0x4752_4149_4e00_0009;
    pub const FIBER: u64 = 0x4649_4245_5200_000a;
    pub const VEIN: u64 = 0x5645_494e_0000_000b;
}

/// Ground at world (x, z): gravel with patches of grass whose ragged borders follow the blades.
pub(super) fn ground(seed: u64, x: f32, z: f32) -> Vec3 {
    /// Grass covers the ground where the patch field exceeds the threshold, give or take the
    /// blade term, which makes tufts reach into the gravel.
    const THRESHOLD: f32 = 0.49;
    const RAGGEDNESS: f32 = 0.06;
    /// Half-width of the blend between gravel and grass, in patch-field units.
    const BLEND: f32 = 0.05;
    let patch = fbm2(seed ^ salt::PATCH, x * 0.8, z * 0.8, 3) - THRESHOLD;
    // Only what can show is evaluated: most of the ground is all gravel or all grass.
    if patch < -RAGGEDNESS - BLEND {
        return gravel(seed, x, z);
    }
    let (grass, blade) = grass(seed, x, z);
    if patch > RAGGEDNESS + BLEND {
        return grass;
    }
    let cover = smoothstep(-BLEND, BLEND, patch + RAGGEDNESS * (2.0 * blade - 1.0));
    gravel(seed, x, z).lerp(grass, cover)
}

/// Pebbles as Worley cells: a color per stone, dark crevices where stones meet, fine grit.
fn gravel(seed: u64, x: f32, z: f32) -> Vec3 {
    /// Stone size in world units: about three pixels at the default resolution and distance.
    const STONE: f32 = 0.07;
    let cell = worley2(seed ^ salt::GRAVEL, x / STONE, z / STONE);
    let tone = 0.6 + 0.6 * unit(cell.id);
    let hue = Vec3::new(0.50, 0.48, 0.45).lerp(Vec3::new(0.68, 0.58, 0.46), unit(mix64(cell.id)));
    let grit = 0.8 + 0.4 * value2(seed ^ salt::GRIT, x * 150.0, z * 150.0);
    let crevice = 0.2 + 0.8 * smoothstep(0.0, 0.3, cell.second - cell.nearest);
    hue * tone * grit * crevice
}

/// Grass seen from above: blades scattered over a dark undergrowth. Returns the color and the
/// blade coverage (1 on a blade, 0 between blades).
fn grass(seed: u64, x: f32, z: f32) -> (Vec3, f32) {
    let Some((shade, along)) = top_blade(seed, x, z) else {
        let undergrowth = 0.7 + 0.6 * value2(seed ^ salt::LUSH, x * 90.0, z * 90.0);
        return (Vec3::new(0.06, 0.13, 0.03) * undergrowth, 0.0);
    };
    // Each blade has its own green, lighter towards the tip where it catches more light.
    let green = Vec3::new(0.16, 0.34, 0.06).lerp(Vec3::new(0.55, 0.72, 0.20), shade);
    let lush = 0.8 + 0.4 * value2(seed ^ salt::LUSH ^ 1, x * 2.0, z * 2.0);
    (green * (0.6 + 0.4 * along) * lush, 1.0)
}

/// Blades are rooted in square cells; a blade never reaches farther than one cell from its
/// root, so the 3x3 cells around a point hold every blade that can cover it.
const BLADE_CELL: f32 = 0.08;
const BLADES_PER_CELL: u64 = 7;

/// The topmost blade covering (x, z), as (its shade in [0, 1], the position along it from root
/// 0 to tip 1). Blade directions follow a slowly turning "combed" direction plus a random
/// spread, as grass lies in a lawn.
fn top_blade(seed: u64, x: f32, z: f32) -> Option<(f32, f32)> {
    let (i, j) = ((x / BLADE_CELL).floor() as i32, (z / BLADE_CELL).floor() as i32);
    // The lean is taken at the shaded point rather than at each root: it turns so slowly that
    // the difference is invisible, and it saves a noise lookup per blade.
    let lean = value2(seed ^ salt::LEAN, x * 0.7, z * 0.7) * TAU;
    let mut top: Option<(u64, f32, f32)> = None;
    for dj in -1..=1 {
        for di in -1..=1 {
            let cell = lattice(seed ^ salt::BLADE, i + di, j + dj, 0);
            for blade in 0..BLADES_PER_CELL {
                let h = mix64(cell ^ blade);
                let root = Vec2::new((i + di) as f32 + unit(h), (j + dj) as f32 + unit_low(h)) * BLADE_CELL;
                let offset = Vec2::new(x, z) - root;
                let shape = mix64(h);
                let length = BLADE_CELL * (0.5 + 0.5 * unit(shape));
                if offset.length_squared() >= length * length || top.is_some_and(|(height, ..)| height > h) {
                    continue;
                }
                let direction = Vec2::from_angle(lean + 1.6 * (unit_low(shape) - 0.5));
                let along = offset.dot(direction) / length;
                // Blades taper from 0.01 at the root to a point at the tip.
                if along >= 0.0 && offset.perp_dot(direction).abs() < 0.01 * (1.0 - along) {
                    top = Some((h, unit(mix64(shape)), along));
                }
            }
        }
    }
    top.map(|(_, shade, along)| (shade, along))
}

/// A painted ball: red and cream checker in longitude and latitude, with a grainy finish.
/// `n` is the unit vector from the center.
pub(super) fn checker(seed: u64, n: Vec3) -> Vec3 {
    let lon = n.z.atan2(n.x) / TAU + 0.5;
    let lat = n.y.clamp(-1.0, 1.0).asin() / PI + 0.5;
    // 12 columns (even), so the parity is continuous across the longitude seam.
    let parity = ((lon * 12.0).floor() as i32 + (lat * 8.0).floor() as i32) & 1;
    let paint = if parity == 0 { Vec3::new(0.78, 0.12, 0.09) } else { Vec3::new(0.93, 0.87, 0.70) };
    paint * (0.8 + 0.35 * fbm3(seed ^ salt::PAINT, n * 30.0, 2))
}

/// Brick wall on every face of a box; `local` is relative to the box's minimum corner. Each
/// brick has its own tone, the mortar is light, and both carry fine grit.
pub(super) fn brick(seed: u64, local: Vec3, normal: Vec3) -> Vec3 {
    const WIDTH: f32 = 0.16;
    const HEIGHT: f32 = 0.07;
    const MORTAR: f32 = 0.014;
    let (face, s, t) = match normal.abs().max_position() {
        0 => (0, local.z, local.y),
        1 => (1, local.x, local.z),
        _ => (2, local.x, local.y),
    };
    let row = (t / HEIGHT).floor();
    let s = s + if row as i32 & 1 == 1 { 0.5 * WIDTH } else { 0.0 };
    let column = (s / WIDTH).floor();
    let grit = value2(seed ^ salt::GRIT, s * 130.0, t * 130.0);
    if s - column * WIDTH < MORTAR || t - row * HEIGHT < MORTAR {
        return Vec3::new(0.74, 0.71, 0.64) * (0.75 + 0.35 * grit);
    }
    let h = lattice(seed ^ salt::BRICK, column as i32, row as i32, face);
    let clay = Vec3::new(0.64, 0.24, 0.13).lerp(Vec3::new(0.50, 0.33, 0.22), unit(mix64(h)));
    clay * (0.7 + 0.45 * unit(h)) * (0.75 + 0.4 * grit)
}

/// A wooden post: growth rings on the top cap, long wavy grain stripes and fibers on the side.
/// `local` is relative to the center of the post's base.
pub(super) fn wood(seed: u64, local: Vec3, normal: Vec3) -> Vec3 {
    let radial = Vec2::new(local.x, local.z);
    let rings = if normal.y > 0.5 {
        radial.length() * 30.0 + 1.5 * fbm2(seed ^ salt::GRAIN, local.x * 6.0, local.z * 6.0, 3)
    } else {
        // An integer number of stripes around the post, so the angle's seam does not show.
        let stripes = (local.z.atan2(local.x) / TAU) * 40.0;
        stripes + 1.5 * fbm3(seed ^ salt::GRAIN, local * Vec3::new(4.0, 1.2, 4.0), 3)
    };
    let phase = rings - rings.floor();
    let band = smoothstep(0.0, 0.35, phase) * smoothstep(1.0, 0.6, phase);
    let fiber = value3(seed ^ salt::FIBER, local * Vec3::new(160.0, 8.0, 160.0));
    let color = Vec3::new(0.42, 0.25, 0.11).lerp(Vec3::new(0.80, 0.60, 0.36), band);
    color * (0.8 + 0.3 * fiber)
}

/// Green-veined marble; `n` is the unit vector from the center.
pub(super) fn marble(seed: u64, n: Vec3) -> Vec3 {
    let turbulence = fbm3(seed ^ salt::VEIN, n * 3.0, 5);
    let wave = (n.x * 5.0 + n.y * 7.0 + 16.0 * turbulence).sin().abs();
    let vein = 1.0 - smoothstep(0.0, 0.45, wave);
    let stone = Vec3::new(0.84, 0.88, 0.85) * (0.85 + 0.2 * value3(seed ^ salt::GRIT, n * 60.0));
    stone.lerp(Vec3::new(0.06, 0.32, 0.28), vein)
}

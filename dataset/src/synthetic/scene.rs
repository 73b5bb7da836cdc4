//! The scene's geometry and its exact renderer: rays are intersected with analytic shapes (no
//! Gaussians anywhere), shaded with a Lambertian sun, ambient light and hard shadows. World
//! axes: y up, the ground is the disk y = 0. Shading depends on the surface point only, never on
//! the viewer, so all views agree, as a radiance field assumes.

use glam::Vec3;

use super::noise::smoothstep;
use super::texture;

/// Radius of the ground disk. Beyond it rays see the sky, which keeps far ground (and its
/// aliasing) out of the images and leaves a sky region in every view.
const GROUND_RADIUS: f32 = 3.0;

/// Ray parameters below this are self-intersections.
const EPSILON: f32 = 1e-4;

/// How far shadow rays start off the surface, against self-shadowing from rounding.
const SHADOW_OFFSET: f32 = 1e-3;

#[derive(Debug, Clone, Copy)]
pub(super) enum Shape {
    /// The ground: the disk y = 0, x^2 + z^2 <= radius^2, seen from above.
    Disk {
        radius: f32,
    },
    Sphere {
        center: Vec3,
        radius: f32,
    },
    /// An axis-aligned box.
    Cuboid {
        min: Vec3,
        max: Vec3,
    },
    /// A vertical cylinder standing on `base`: the side and the top cap (the bottom rests on
    /// the ground and is never seen).
    Cylinder {
        base: Vec3,
        radius: f32,
        height: f32,
    },
}

#[derive(Debug, Clone, Copy)]
enum Material {
    Ground,
    Checker,
    Brick,
    Wood,
    Marble,
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Object {
    pub(super) shape: Shape,
    material: Material,
}

/// The ground and four objects resting on it, spread around the origin so that every view of
/// the ring sees some of them in front of others.
pub(super) const OBJECTS: [Object; 5] = [
    Object { shape: Shape::Disk { radius: GROUND_RADIUS }, material: Material::Ground },
    Object { shape: Shape::Sphere { center: Vec3::new(-0.75, 0.55, 0.35), radius: 0.55 }, material: Material::Checker },
    Object {
        shape: Shape::Cuboid { min: Vec3::new(0.15, 0.0, -1.1), max: Vec3::new(1.0, 0.7, -0.35) },
        material: Material::Brick,
    },
    Object {
        shape: Shape::Cylinder { base: Vec3::new(0.8, 0.0, 0.7), radius: 0.3, height: 1.0 },
        material: Material::Wood,
    },
    Object { shape: Shape::Sphere { center: Vec3::new(-0.4, 0.3, -0.9), radius: 0.3 }, material: Material::Marble },
];

/// Direction towards the sun.
fn sun() -> Vec3 {
    Vec3::new(-0.45, 0.8, 0.4).normalize()
}

const SUN_COLOR: Vec3 = Vec3::new(0.80, 0.76, 0.68);
/// Ambient light, slightly blue as from the sky, so that shadowed sides keep their texture.
const AMBIENT: Vec3 = Vec3::new(0.34, 0.37, 0.42);

/// A ray's nearest intersection.
pub(super) struct Hit {
    pub(super) point: Vec3,
    pub(super) normal: Vec3,
    object: Object,
}

/// The color seen along a ray: the shaded surface it hits, else the sky.
pub(super) fn radiance(origin: Vec3, direction: Vec3, seed: u64) -> Vec3 {
    intersect(origin, direction).map_or_else(|| sky(direction), |hit| shade(&hit, seed))
}

/// The sky: a function of the direction only, so it is the same backdrop from every camera.
/// Pale haze around the horizon, deepening to blue at the zenith and to grey-blue below.
pub(super) fn sky(direction: Vec3) -> Vec3 {
    let below = Vec3::new(0.58, 0.64, 0.70);
    let haze = Vec3::new(0.82, 0.87, 0.92);
    let zenith = Vec3::new(0.26, 0.47, 0.82);
    let y = direction.y;
    below.lerp(haze, smoothstep(-1.0, 0.0, y)).lerp(zenith, smoothstep(0.0, 1.0, y))
}

/// Lambertian shading with a hard shadow from the sun.
pub(super) fn shade(hit: &Hit, seed: u64) -> Vec3 {
    let sun = sun();
    let cosine = hit.normal.dot(sun).max(0.0);
    let lit = cosine > 0.0 && intersect(hit.point + SHADOW_OFFSET * hit.normal, sun).is_none();
    albedo(hit, seed) * (AMBIENT + if lit { cosine * SUN_COLOR } else { Vec3::ZERO })
}

/// The material's texture, in coordinates relative to the shape's anchor so that textures
/// stay attached to their objects.
fn albedo(hit: &Hit, seed: u64) -> Vec3 {
    let local = hit.point - hit.object.shape.anchor();
    match hit.object.material {
        Material::Ground => texture::ground(seed, local.x, local.z),
        Material::Checker => texture::checker(seed, local.normalize()),
        Material::Marble => texture::marble(seed, local.normalize()),
        Material::Brick => texture::brick(seed, local, hit.normal),
        Material::Wood => texture::wood(seed, local, hit.normal),
    }
}

impl Shape {
    /// The origin of the shape's texture coordinates: the center of a disk or sphere, the
    /// minimum corner of a box, the center of a cylinder's base.
    fn anchor(self) -> Vec3 {
        match self {
            Shape::Disk { .. } => Vec3::ZERO,
            Shape::Sphere { center, .. } => center,
            Shape::Cuboid { min, .. } => min,
            Shape::Cylinder { base, .. } => base,
        }
    }
}

/// The nearest object hit by the ray from `origin` along the unit vector `direction`.
pub(super) fn intersect(origin: Vec3, direction: Vec3) -> Option<Hit> {
    let mut best: Option<(f32, Vec3, Object)> = None;
    for object in OBJECTS {
        if let Some((t, normal)) = intersect_shape(object.shape, origin, direction)
            && best.is_none_or(|(best_t, ..)| t < best_t)
        {
            best = Some((t, normal, object));
        }
    }
    best.map(|(t, normal, object)| Hit { point: surface_point(object.shape, origin + t * direction), normal, object })
}

/// Snaps ground points exactly onto the plane, so rounding never puts them below it.
fn surface_point(shape: Shape, p: Vec3) -> Vec3 {
    match shape {
        Shape::Disk { .. } => Vec3::new(p.x, 0.0, p.z),
        _ => p,
    }
}

/// Ray parameter and outward unit normal of the ray's first entry into `shape`.
fn intersect_shape(shape: Shape, o: Vec3, d: Vec3) -> Option<(f32, Vec3)> {
    match shape {
        Shape::Disk { radius } => intersect_disk(o, d, radius),
        Shape::Sphere { center, radius } => intersect_sphere(o, d, center, radius),
        Shape::Cuboid { min, max } => intersect_cuboid(o, d, min, max),
        Shape::Cylinder { base, radius, height } => intersect_cylinder(o, d, base, radius, height),
    }
}

fn intersect_disk(o: Vec3, d: Vec3, radius: f32) -> Option<(f32, Vec3)> {
    if d.y >= 0.0 {
        return None;
    }
    let t = -o.y / d.y;
    let p = o + t * d;
    (t > EPSILON && p.x * p.x + p.z * p.z <= radius * radius).then_some((t, Vec3::Y))
}

fn intersect_sphere(o: Vec3, d: Vec3, center: Vec3, radius: f32) -> Option<(f32, Vec3)> {
    let oc = o - center;
    let b = oc.dot(d);
    let discriminant = b * b - (oc.length_squared() - radius * radius);
    if discriminant < 0.0 {
        return None;
    }
    let t = -b - discriminant.sqrt();
    (t > EPSILON).then(|| (t, (oc + t * d) / radius))
}

/// The slab method: the entry parameter is the largest of the per-axis entries, and the axis
/// that attains it is the face that was hit.
fn intersect_cuboid(o: Vec3, d: Vec3, min: Vec3, max: Vec3) -> Option<(f32, Vec3)> {
    let inverse = d.recip();
    let (t0, t1) = ((min - o) * inverse, (max - o) * inverse);
    let (entry, exit) = (t0.min(t1), t0.max(t1));
    let (near, far) = (entry.max_element(), exit.min_element());
    if near > far || near <= EPSILON {
        return None;
    }
    let axis = entry.max_position();
    let mut normal = Vec3::ZERO;
    normal[axis] = -d[axis].signum();
    Some((near, normal))
}

fn intersect_cylinder(o: Vec3, d: Vec3, base: Vec3, radius: f32, height: f32) -> Option<(f32, Vec3)> {
    let side = intersect_cylinder_side(o, d, base, radius, height);
    let cap = intersect_cylinder_cap(o, d, base, radius, height);
    match (side, cap) {
        (Some(s), Some(c)) => Some(if s.0 < c.0 { s } else { c }),
        (s, c) => s.or(c),
    }
}

fn intersect_cylinder_side(o: Vec3, d: Vec3, base: Vec3, radius: f32, height: f32) -> Option<(f32, Vec3)> {
    let (ox, oz) = (o.x - base.x, o.z - base.z);
    let a = d.x * d.x + d.z * d.z;
    let b = ox * d.x + oz * d.z;
    let discriminant = b * b - a * (ox * ox + oz * oz - radius * radius);
    if a <= 0.0 || discriminant < 0.0 {
        return None;
    }
    let t = (-b - discriminant.sqrt()) / a;
    let y = o.y + t * d.y - base.y;
    (t > EPSILON && (0.0..=height).contains(&y)).then(|| (t, Vec3::new(ox + t * d.x, 0.0, oz + t * d.z) / radius))
}

fn intersect_cylinder_cap(o: Vec3, d: Vec3, base: Vec3, radius: f32, height: f32) -> Option<(f32, Vec3)> {
    if d.y >= 0.0 {
        return None;
    }
    let t = (base.y + height - o.y) / d.y;
    let (x, z) = (o.x + t * d.x - base.x, o.z + t * d.z - base.z);
    (t > EPSILON && x * x + z * z <= radius * radius).then_some((t, Vec3::Y))
}

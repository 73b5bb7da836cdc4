//! Deterministic content for the generated vectors: quantized Gaussians and wrapper parameters
//! drawn as integers from SplitMix64 (no training, no float arithmetic before the stream), the
//! headers around them and the cameras they are rendered from.

use glam::Vec3;
use pwgs_codec::stream::classes::ImportanceClasses;
use pwgs_codec::stream::header::{BaseKind, Header};
use pwgs_codec::stream::octree;
use pwgs_codec::stream::plain::{PlainGaussians, PositionGrid, QuantizedRotation};
use pwgs_codec::stream::wrap::QuantizedSynthesis;
use pwgs_codec::wrapper::synthesis::{RESIDUAL_TAPS, WrapperConfig};
use pwgs_core::camera::{Camera, Intrinsics};
use pwgs_core::gaussians::sh_coeff_count;
use pwgs_core::random::SplitMix64;

/// Integer draws from SplitMix64.
pub struct Draws(SplitMix64);

impl Draws {
    pub fn new(seed: u64) -> Self {
        Self(SplitMix64(seed))
    }

    /// An integer in `lo ..= hi` (the modulo's bias does not matter here).
    pub fn int(&mut self, lo: i64, hi: i64) -> i64 {
        lo + (self.0.next_u64() % (hi - lo + 1) as u64) as i64
    }

    pub fn i32(&mut self, [lo, hi]: [i32; 2]) -> i32 {
        self.int(lo.into(), hi.into()) as i32
    }

    /// A grid point with every coordinate below `2^depth`.
    pub fn point(&mut self, depth: u8) -> [u32; 3] {
        std::array::from_fn(|_| self.int(0, (1i64 << depth) - 1) as u32)
    }
}

/// Quantization steps of every attribute block.
#[derive(Debug, Clone, PartialEq)]
pub struct Steps {
    pub scale: f32,
    pub rotation: f32,
    pub opacity: f32,
    pub dc: f32,
    /// One per SH band 1..=degree.
    pub bands: Vec<f32>,
}

impl Steps {
    /// Every step the same (one per band up to `degree`).
    pub fn all(step: f32, degree: u32) -> Self {
        Self { scale: step, rotation: step, opacity: step, dc: step, bands: vec![step; degree as usize] }
    }
}

/// Inclusive ranges the quantized values are drawn from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ranges {
    pub log_scale: [i32; 2],
    /// The three coded quaternion components.
    pub rotation: [i32; 2],
    pub opacity: [i32; 2],
    pub dc: [i32; 2],
    pub sh_rest: [i32; 2],
}

/// Steps and ranges of ordinary-looking Gaussians in the unit cube: scales e^-4 to e^-2.5,
/// opacities 0.27 to 0.98, colors 0.5 +/- 0.44, view-dependent terms up to +/- 0.3.
pub fn ordinary(degree: u32) -> (Steps, Ranges) {
    let steps = Steps {
        scale: 1.0 / 32.0,
        rotation: 1.0 / 1024.0,
        opacity: 1.0 / 16.0,
        dc: 1.0 / 64.0,
        bands: (1..=degree).map(|band| 1.0 / (64 << band) as f32).collect(),
    };
    let ranges = Ranges {
        log_scale: [-128, -80],
        rotation: [-512, 512],
        opacity: [-16, 64],
        dc: [-100, 100],
        sh_rest: [-80, 80],
    };
    (steps, ranges)
}

/// The grid of `depth` levels spanning the cube [-1, 1]^3.
pub fn unit_cube(depth: u8) -> PositionGrid {
    PositionGrid { origin: [-1.0; 3], cell: 2.0 / (1u64 << depth) as f32, depth }
}

/// Gaussians at `positions` with attributes drawn from `ranges`.
pub fn gaussians(
    draws: &mut Draws,
    grid: PositionGrid,
    positions: Vec<[u32; 3]>,
    degree: u32,
    steps: Steps,
    ranges: &Ranges,
) -> PlainGaussians {
    let n = positions.len();
    let rest = (sh_coeff_count(degree) - 1) * 3;
    assert_eq!(steps.bands.len(), degree as usize, "one step per SH band");
    PlainGaussians {
        grid,
        positions,
        classes: None,
        scale_step: steps.scale,
        log_scales: (0..n).map(|_| std::array::from_fn(|_| draws.i32(ranges.log_scale))).collect(),
        rotation_step: steps.rotation,
        rotations: (0..n)
            .map(|_| QuantizedRotation {
                largest: draws.int(0, 3) as u8,
                rest: std::array::from_fn(|_| draws.i32(ranges.rotation)),
            })
            .collect(),
        opacity_step: steps.opacity,
        opacity_logits: (0..n).map(|_| draws.i32(ranges.opacity)).collect(),
        sh_degree: degree,
        dc_step: steps.dc,
        sh_dc: (0..n).map(|_| std::array::from_fn(|_| draws.i32(ranges.dc))).collect(),
        band_steps: steps.bands,
        sh_rest: (0..n * rest).map(|_| draws.i32(ranges.sh_rest)).collect(),
        colour_differences: false,
        adaptive: false,
    }
}

/// `n` ordinary Gaussians of degree `degree` at random points of a 256^3 grid on the unit cube.
pub fn ordinary_gaussians(seed: u64, n: usize, degree: u32) -> PlainGaussians {
    let mut draws = Draws::new(seed);
    let positions = (0..n).map(|_| draws.point(8)).collect();
    let (steps, ranges) = ordinary(degree);
    gaussians(&mut draws, unit_cube(8), positions, degree, steps, &ranges)
}

/// `n` Gaussians of degree `degree` in `classes` importance classes (SPEC.md section 6.5) with
/// factors `sqrt(2)^k` (as f32: powers of two, or their products with sqrt 2 rounded), dropping
/// `floor(k / 2)` of `refine` levels below a `base_depth`-level grid over the unit cube; each
/// position drawn on the fine grid and its dropped levels set to their centre.
pub fn classed_gaussians(
    seed: u64,
    n: usize,
    degree: u32,
    (classes, refine, base_depth): (u8, u8, u8),
) -> PlainGaussians {
    let mut draws = Draws::new(seed);
    let of: Vec<u8> = (0..n).map(|_| draws.int(0, i64::from(classes) - 1) as u8).collect();
    let factors =
        (0..classes).map(|k| (1u32 << (k / 2)) as f32 * if k % 2 == 1 { std::f32::consts::SQRT_2 } else { 1.0 });
    let classes = ImportanceClasses {
        refine,
        factors: factors.collect(),
        drops: (0..classes).map(|k| (k / 2).min(refine)).collect(),
        of,
    };
    let positions = (0..n).map(|i| draws.point(base_depth + refine).map(|c| classes.snap(classes.of[i], c))).collect();
    let (steps, ranges) = ordinary(degree);
    let mut content = gaussians(&mut draws, unit_cube(base_depth), positions, degree, steps, &ranges);
    content.classes = Some(classes);
    content
}

/// `content` with every value following its position: a ramp across the cube over a quarter
/// of its range, plus noise of +/- 2, and every rotation's largest component `w` (index 0).
/// Neighbours in octree order then hold similar values, as a captured scene's do, which is
/// where adaptive trees (SPEC.md section 6.7) code smaller than tables.
pub fn smooth(mut content: PlainGaussians, seed: u64) -> PlainGaussians {
    let mut draws = Draws::new(seed);
    let depth = content.grid.depth + content.refine();
    let ramps: Vec<i64> =
        content.positions.iter().map(|p| p.iter().map(|&c| i64::from(c >> (depth - 8))).sum::<i64>()).collect();
    let (_, ranges) = ordinary(content.sh_degree);
    let mut value = |i: usize, [lo, hi]: [i32; 2]| {
        let (lo, hi) = (i64::from(lo), i64::from(hi));
        (lo + ramps[i] * (hi - lo) / (4 * 765) + draws.int(-2, 2)).clamp(lo, hi) as i32
    };
    let rest = content.sh_rest.len() / content.len().max(1);
    for i in 0..content.len() {
        content.log_scales[i] = std::array::from_fn(|_| value(i, ranges.log_scale));
        content.rotations[i] =
            QuantizedRotation { largest: 0, rest: std::array::from_fn(|_| value(i, ranges.rotation)) };
        content.opacity_logits[i] = value(i, ranges.opacity);
        content.sh_dc[i] = std::array::from_fn(|_| value(i, ranges.dc));
        for v in &mut content.sh_rest[i * rest..(i + 1) * rest] {
            *v = value(i, ranges.sh_rest);
        }
    }
    content
}

/// The header of `content`, with a colored background and the unit cube's normalization.
pub fn header(content: &PlainGaussians) -> Header {
    Header {
        base: BaseKind::Plain3dgs,
        gaussian_count: content.len() as u32,
        sh_degree: content.sh_degree,
        center: [0.0, 0.0, 0.0],
        scale: 1.0,
        background: [0.1, 0.15, 0.25],
    }
}

/// Parameters of a synthesis network whose residual visibly moves the render: weights of step
/// 2^-7 and biases of step 2^-9, the output layer scaled down as the hidden layer widens.
pub fn synthesis(config: WrapperConfig, seed: u64) -> QuantizedSynthesis {
    let mut draws = Draws::new(seed);
    let (w, cin) = (config.width, config.input_channels());
    let output = (64 / w as i32).max(2);
    let mut values = Vec::with_capacity(config.parameter_count());
    let mut push = |count: usize, range: [i32; 2]| values.extend((0..count).map(|_| draws.i32(range)));
    push(w * cin, [-16, 16]);
    push(w, [-24, 24]);
    push(3 * w, [-output, output]);
    push(3, [-8, 8]);
    for _ in 0..2 {
        push(RESIDUAL_TAPS, [-4, 4]);
        push(3, [-8, 8]);
    }
    QuantizedSynthesis { config, weight_exponent: -7, bias_exponent: -9, values }
}

/// The cameras vectors are rendered from: `front` 64x48 slightly above the cube, `side` 40x30
/// at an angle (so view-dependent color and Plücker rays differ), both looking at its center.
pub fn camera(name: &str) -> Camera {
    let (width, height, eye) = match name {
        "front" => (64, 48, Vec3::new(0.4, -0.6, -3.4)),
        "side" => (40, 30, Vec3::new(-2.6, -1.1, -2.0)),
        other => panic!("no camera {other}"),
    };
    let f = width as f32 * 0.9;
    let intrinsics = Intrinsics { width, height, fx: f, fy: f, cx: width as f32 / 2.0, cy: height as f32 / 2.0 };
    Camera::look_at(intrinsics, eye, Vec3::ZERO, Vec3::new(0.0, -1.0, 0.0)).expect("a valid camera")
}

/// The attribute values of `content` per Gaussian in stream order, one list per block.
pub struct BlockValues {
    pub scales: Vec<Vec<i32>>,
    pub rotations: Vec<Vec<i32>>,
    pub opacities: Vec<Vec<i32>>,
    pub colors: Vec<Vec<i32>>,
    pub sh_rest: Vec<Vec<i32>>,
}

impl BlockValues {
    pub fn of(c: &PlainGaussians) -> Self {
        let (_, order) = octree::encode(&c.positions, c.grid.depth).expect("fits the octree");
        let rest = c.sh_rest.len() / c.len().max(1);
        let each = |f: &dyn Fn(usize) -> Vec<i32>| order.iter().map(|&i| f(i)).collect();
        Self {
            scales: each(&|i| c.log_scales[i].to_vec()),
            rotations: each(&|i| {
                let r = c.rotations[i];
                vec![i32::from(r.largest), r.rest[0], r.rest[1], r.rest[2]]
            }),
            opacities: each(&|i| vec![c.opacity_logits[i]]),
            colors: each(&|i| c.sh_dc[i].to_vec()),
            sh_rest: each(&|i| c.sh_rest[i * rest..(i + 1) * rest].to_vec()),
        }
    }
}

// Front-to-back alpha blending of binned splats, one workgroup per 16x16 tile and one
// invocation per pixel: the same per-pixel rules, in the same order, as the CPU reference
// (decoder/src/raster/blend.rs). Only `exp` differs (the GPU's own), so the image agrees
// within the tolerance the tests state rather than bit for bit.

// The view is blended window by window (bounded tile lists): each dispatch covers one window's
// tiles, [x0, x1) x [y0, y1) in the view's pixels, tile-aligned at its top left corner.
struct Params {
    width: u32,
    height: u32,
    tiles_x: u32,
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    _pad0: u32,
    alpha_min: f32,
    alpha_max: f32,
    transmittance_min: f32,
    _pad1: f32,
    background: vec4<f32>,
}

// Per splat, 12 values: mean x, mean y, l11, l21, l22, opacity, r, g, b, then 3 unused.
const SPLAT_STRIDE: u32 = 12u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> splats: array<f32>;
// Per splat: x0, x1, y0, y1 (pixels covered: x in [x0, x1), y in [y0, y1)).
@group(0) @binding(2) var<storage, read> boxes: array<vec4<u32>>;
// Tile t of the window (row-major) has entries[offsets[t] .. offsets[t + 1]], front to back.
@group(0) @binding(3) var<storage, read> offsets: array<u32>;
@group(0) @binding(4) var<storage, read> entries: array<u32>;
// Interleaved RGB, row by row.
@group(0) @binding(5) var<storage, read_write> image: array<f32>;

// The CPU reference's exp_f32 (decoder/src/portable_math.rs), for x <= 0 as the falloff's
// argument always is: k = round(x log2 e), r = x - k ln 2 in two parts, a Taylor polynomial
// to r^7, times 2^k. WGSL's own exp may differ in the last bits, and a last-bit difference
// can decide an alpha threshold differently; this keeps the two renderers apart only by what
// the GPU compiler does with the same operations (fused multiply-adds).
fn portable_exp(x: f32) -> f32 {
    if x < -87.33 {
        return 0.0;
    }
    let k = round(x * 1.4426950408889634);
    let r = (x - k * 0.693359375) - k * -2.1219444e-4;
    var p = 1.0 / 5040.0;
    p = p * r + 1.0 / 720.0;
    p = p * r + 1.0 / 120.0;
    p = p * r + 1.0 / 24.0;
    p = p * r + 1.0 / 6.0;
    p = p * r + 0.5;
    p = p * r + 1.0;
    p = p * r + 1.0;
    return ldexp(p, i32(k));
}

@compute @workgroup_size(16, 16, 1)
fn main(@builtin(workgroup_id) tile: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>) {
    let px = params.x0 + tile.x * 16u + local.x;
    let py = params.y0 + tile.y * 16u + local.y;
    if px >= params.x1 || py >= params.y1 {
        return;
    }
    let t = tile.y * params.tiles_x + tile.x;
    var trans = 1.0;
    var rgb = vec3<f32>(0.0, 0.0, 0.0);
    let cx = f32(px) + 0.5;
    let cy = f32(py) + 0.5;
    for (var k = offsets[t]; k < offsets[t + 1u]; k = k + 1u) {
        let i = entries[k];
        let b = boxes[i];
        if px < b.x || px >= b.y || py < b.z || py >= b.w {
            continue;
        }
        let s = i * SPLAT_STRIDE;
        let dx = splats[s] - cx;
        let dy = splats[s + 1u] - cy;
        let p = splats[s + 2u] * dx + splats[s + 3u] * dy;
        let q = splats[s + 4u] * dy;
        let falloff = portable_exp(-0.5 * (p * p + q * q));
        let raw = splats[s + 5u] * falloff;
        if raw < params.alpha_min {
            continue;
        }
        let alpha = min(raw, params.alpha_max);
        let next = trans * (1.0 - alpha);
        if next <= params.transmittance_min {
            break;
        }
        let weight = alpha * trans;
        rgb = rgb + vec3<f32>(splats[s + 6u], splats[s + 7u], splats[s + 8u]) * weight;
        trans = next;
    }
    let o = (py * params.width + px) * 3u;
    let color = rgb + trans * params.background.xyz;
    image[o] = color.x;
    image[o + 1u] = color.y;
    image[o + 2u] = color.z;
}

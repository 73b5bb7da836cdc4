// Projection of 3D Gaussians to splats, one invocation per Gaussian: the CPU reference's
// rules (decoder/src/raster/project.rs: the same culling tests, EWA with the clamped Jacobian,
// the blur, the opacity-aware pixel box, SH up to degree 3) in f32 instead of f64. Where f64
// protected the CPU from cancellation, this shader uses forms that have none: the 2D
// covariance is B B^T + blur I with B = J W R S (2x3), so its determinant is
// |b0 x b1|^2 + blur (|b0|^2 + |b1|^2) + blur^2, a sum of non-negative terms, and the conic's
// Cholesky factor is (sqrt(c / det), -b / sqrt(c det), 1 / sqrt(c)).

struct Params {
    // Rows of the world-to-camera rotation, the translation in w.
    rot0: vec4<f32>,
    rot1: vec4<f32>,
    rot2: vec4<f32>,
    // The camera center in world coordinates (xyz).
    center: vec4<f32>,
    // fx, fy, cx, cy.
    intrinsics: vec4<f32>,
    // Image width and height in pixels, the near plane, the blur (pixels^2).
    size: vec4<f32>,
    alpha_min: f32,
    count: u32,
    sh_degree: u32,
    _pad3: u32,
    // Invocations per row of the dispatch (workgroups in x times 64).
    row: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
// Per Gaussian, 11 values: mean (3), log scales (3), quaternion w x y z (4), opacity logit.
@group(0) @binding(1) var<storage, read> gaussians: array<f32>;
// The SH coefficients, one buffer per band (so that no binding outgrows a device's limit):
// per Gaussian 1, 3, 5 and 7 coefficients, [coefficient][rgb]; bands above the degree are
// placeholders.
@group(0) @binding(2) var<storage, read> band0: array<f32>;
@group(0) @binding(3) var<storage, read> band1: array<f32>;
@group(0) @binding(4) var<storage, read> band2: array<f32>;
@group(0) @binding(5) var<storage, read> band3: array<f32>;
// Per Gaussian, as blend.wgsl reads them: mean x, mean y, l11, l21, l22, opacity, r, g, b,
// then 3 unused.
@group(0) @binding(6) var<storage, read_write> splats: array<f32>;
// Per Gaussian: x0, x1, y0, y1 (pixels covered); all zero when culled.
@group(0) @binding(7) var<storage, read_write> boxes: array<vec4<u32>>;
// Per Gaussian: camera-space z, the sort key.
@group(0) @binding(8) var<storage, read_write> depths: array<f32>;

const GEOMETRY_STRIDE: u32 = 11u;

const SPLAT_STRIDE: u32 = 12u;
const JACOBIAN_FOV_LIMIT: f32 = 1.3;
const GUARD_BAND: f32 = 1.0;
const MIN_QUATERNION_NORM_SQUARED: f32 = 1e-16;

// Sloan's real SH basis constants, as decoder/src/raster/sh.rs.
const C0: f32 = 0.28209479177387814;
const C1: f32 = 0.4886025119029199;
const C2: array<f32, 5> = array<f32, 5>(1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396);
const C3: array<f32, 7> = array<f32, 7>(-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154, -0.4570457994644658, 1.445305721320277, -0.5900435899266435);

fn all_finite3(v: vec3<f32>) -> bool {
    // NaN fails every comparison; infinities fail the bound.
    return all(abs(v) <= vec3<f32>(3.4e38));
}

fn finite(x: f32) -> bool {
    return abs(x) <= 3.4e38;
}

fn sigmoid(x: f32) -> f32 {
    if x >= 0.0 {
        return 1.0 / (1.0 + exp(-x));
    }
    let e = exp(x);
    return e / (1.0 + e);
}

fn cull(i: u32) {
    boxes[i] = vec4<u32>(0u, 0u, 0u, 0u);
}

// The basis at unit direction d, coefficient k (k < (degree + 1)^2).
fn basis(k: u32, d: vec3<f32>) -> f32 {
    let x = d.x;
    let y = d.y;
    let z = d.z;
    let xx = x * x;
    let yy = y * y;
    let zz = z * z;
    switch k {
        case 0u: { return C0; }
        case 1u: { return -C1 * y; }
        case 2u: { return C1 * z; }
        case 3u: { return -C1 * x; }
        case 4u: { return C2[0] * x * y; }
        case 5u: { return C2[1] * y * z; }
        case 6u: { return C2[2] * (2.0 * zz - xx - yy); }
        case 7u: { return C2[3] * x * z; }
        case 8u: { return C2[4] * (xx - yy); }
        case 9u: { return C3[0] * y * (3.0 * xx - yy); }
        case 10u: { return C3[1] * x * y * z; }
        case 11u: { return C3[2] * y * (4.0 * zz - xx - yy); }
        case 12u: { return C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy); }
        case 13u: { return C3[4] * x * (4.0 * zz - xx - yy); }
        case 14u: { return C3[5] * z * (xx - yy); }
        default: { return C3[6] * x * (xx - 3.0 * yy); }
    }
}

// SH coefficient k (rgb) of Gaussian i.
fn coefficient(i: u32, k: u32) -> vec3<f32> {
    if k == 0u {
        return vec3<f32>(band0[3u * i], band0[3u * i + 1u], band0[3u * i + 2u]);
    }
    if k < 4u {
        let o = 9u * i + 3u * (k - 1u);
        return vec3<f32>(band1[o], band1[o + 1u], band1[o + 2u]);
    }
    if k < 9u {
        let o = 15u * i + 3u * (k - 4u);
        return vec3<f32>(band2[o], band2[o + 1u], band2[o + 2u]);
    }
    let o = 21u * i + 3u * (k - 9u);
    return vec3<f32>(band3[o], band3[o + 1u], band3[o + 2u]);
}

// Pixels [lo, hi) whose centers lie within [center - extent, center + extent], clipped to
// [0, size); lo == hi when none.
fn pixel_range(center: f32, extent: f32, size: f32) -> vec2<u32> {
    let lo = max(ceil(center - extent - 0.5), 0.0);
    let hi = min(floor(center + extent - 0.5), size - 1.0);
    if !(lo <= hi) {
        return vec2<u32>(0u, 0u);
    }
    return vec2<u32>(u32(lo), u32(hi) + 1u);
}

// The standard deviation sqrt(v) e^shift of a variance v in units of e^shift, at most 1e30.
fn extent(v: f32, shift: f32) -> f32 {
    if shift == 0.0 {
        return sqrt(v);
    }
    return exp(min(shift + 0.5 * log(v), 69.0));
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.y * params.row + id.x;
    if i >= params.count {
        return;
    }
    let g = i * GEOMETRY_STRIDE;
    let mean = vec3<f32>(gaussians[g], gaussians[g + 1u], gaussians[g + 2u]);
    let log_scale = vec3<f32>(gaussians[g + 3u], gaussians[g + 4u], gaussians[g + 5u]);
    let q = vec4<f32>(gaussians[g + 6u], gaussians[g + 7u], gaussians[g + 8u], gaussians[g + 9u]);
    let logit = gaussians[g + 10u];
    let coefficients = (params.sh_degree + 1u) * (params.sh_degree + 1u);
    var coefficients_finite = true;
    for (var k = 0u; k < coefficients; k = k + 1u) {
        coefficients_finite = coefficients_finite && all_finite3(coefficient(i, k));
    }
    if !(all_finite3(mean) && all_finite3(log_scale) && all_finite3(q.xyz) && finite(q.w) && finite(logit) && coefficients_finite) {
        cull(i);
        return;
    }
    let opacity = sigmoid(logit);
    if !(opacity >= params.alpha_min) {
        cull(i);
        return;
    }
    let norm2 = dot(q, q);
    if !(norm2 >= MIN_QUATERNION_NORM_SQUARED) {
        cull(i);
        return;
    }
    let qn = q / sqrt(norm2);

    let mean_cam = vec3<f32>(
        dot(params.rot0.xyz, mean) + params.rot0.w,
        dot(params.rot1.xyz, mean) + params.rot1.w,
        dot(params.rot2.xyz, mean) + params.rot2.w,
    );
    let near = params.size.z;
    if !(mean_cam.z >= near) {
        cull(i);
        return;
    }
    let fx = params.intrinsics.x;
    let fy = params.intrinsics.y;
    let cx = params.intrinsics.z;
    let cy = params.intrinsics.w;
    let w = params.size.x;
    let h = params.size.y;
    let tan_x = mean_cam.x / mean_cam.z;
    let tan_y = mean_cam.y / mean_cam.z;
    let left = cx / fx;
    let right = (w - cx) / fx;
    let top = cy / fy;
    let bottom = (h - cy) / fy;
    let band_x = GUARD_BAND * w / fx;
    let band_y = GUARD_BAND * h / fy;
    if !(tan_x >= -left - band_x && tan_x <= right + band_x && tan_y >= -top - band_y && tan_y <= bottom + band_y) {
        cull(i);
        return;
    }

    // Beyond e^300 the CPU's f64 covariance overflows and it culls; so does this.
    let lmax = max(log_scale.x, max(log_scale.y, log_scale.z));
    if !(lmax <= 300.0) {
        cull(i);
        return;
    }
    // Huge Gaussians (largest scale above e^8, far beyond a normalized scene) are projected in
    // units of e^shift, so that every f32 value below stays finite (|cross(b0, b1)|^2 grows
    // as the fourth power of the scale): the 2D covariance and the blur in those units are
    // e^-2shift times the real ones, the conic's Cholesky factor e^shift times, the extents
    // e^-shift times. Others (shift 0) take exactly the plain formulas.
    let shift = max(lmax - 8.0, 0.0);
    let unit = exp(-shift);
    let scale = exp(log_scale - shift);
    // Columns of R, each times its scale, then turned into camera axes (W R S).
    let qw = qn.x;
    let qx = qn.y;
    let qy = qn.z;
    let qz = qn.w;
    let r0 = vec3<f32>(1.0 - 2.0 * (qy * qy + qz * qz), 2.0 * (qx * qy + qw * qz), 2.0 * (qx * qz - qw * qy)) * scale.x;
    let r1 = vec3<f32>(2.0 * (qx * qy - qw * qz), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz + qw * qx)) * scale.y;
    let r2 = vec3<f32>(2.0 * (qx * qz + qw * qy), 2.0 * (qy * qz - qw * qx), 1.0 - 2.0 * (qx * qx + qy * qy)) * scale.z;
    let wr0 = vec3<f32>(dot(params.rot0.xyz, r0), dot(params.rot1.xyz, r0), dot(params.rot2.xyz, r0));
    let wr1 = vec3<f32>(dot(params.rot0.xyz, r1), dot(params.rot1.xyz, r1), dot(params.rot2.xyz, r1));
    let wr2 = vec3<f32>(dot(params.rot0.xyz, r2), dot(params.rot1.xyz, r2), dot(params.rot2.xyz, r2));

    let slack_x = (JACOBIAN_FOV_LIMIT - 1.0) * (left + right) / 2.0;
    let slack_y = (JACOBIAN_FOV_LIMIT - 1.0) * (top + bottom) / 2.0;
    let ctx = clamp(tan_x, -left - slack_x, right + slack_x);
    let cty = clamp(tan_y, -top - slack_y, bottom + slack_y);
    let z = mean_cam.z;
    let j0 = vec3<f32>(fx / z, 0.0, -fx * ctx / z);
    let j1 = vec3<f32>(0.0, fy / z, -fy * cty / z);
    let b0 = vec3<f32>(dot(j0, wr0), dot(j0, wr1), dot(j0, wr2));
    let b1 = vec3<f32>(dot(j1, wr0), dot(j1, wr1), dot(j1, wr2));
    let blur = params.size.w * unit * unit;
    let n0 = dot(b0, b0);
    let n1 = dot(b1, b1);
    let a = n0 + blur;
    let b = dot(b0, b1);
    let c = n1 + blur;
    let cross_b = cross(b0, b1);
    let det = dot(cross_b, cross_b) + blur * (n0 + n1) + blur * blur;
    if !(det > 0.0 && finite(det) && finite(a) && finite(b) && finite(c)) {
        cull(i);
        return;
    }

    let view_dir = mean - params.center.xyz;
    let length = sqrt(dot(view_dir, view_dir));
    if !(length > 0.0) {
        cull(i);
        return;
    }
    let d = view_dir / length;
    var rgb = vec3<f32>(0.5, 0.5, 0.5);
    for (var k = 0u; k < coefficients; k = k + 1u) {
        rgb = rgb + basis(k, d) * coefficient(i, k);
    }

    let mx = fx * mean_cam.x / z + cx;
    let my = fy * mean_cam.y / z + cy;
    // alpha = opacity exp(-sigma) >= alpha_min inside the ellipse of Mahalanobis radius
    // sqrt(2 ln(opacity / alpha_min)).
    let radius = sqrt(max(2.0 * log(opacity / params.alpha_min), 0.0));
    // sqrt(a) / unit, kept finite: past 1e30 pixels an extent covers any image.
    let xs = pixel_range(mx, radius * extent(a, shift), w);
    let ys = pixel_range(my, radius * extent(c, shift), h);
    if xs.x == xs.y || ys.x == ys.y {
        cull(i);
        return;
    }
    let s = i * SPLAT_STRIDE;
    splats[s] = mx;
    splats[s + 1u] = my;
    splats[s + 2u] = sqrt(c / det) * unit;
    splats[s + 3u] = -b / sqrt(c * det) * unit;
    splats[s + 4u] = unit / sqrt(c);
    splats[s + 5u] = opacity;
    splats[s + 6u] = max(rgb.x, 0.0);
    splats[s + 7u] = max(rgb.y, 0.0);
    splats[s + 8u] = max(rgb.z, 0.0);
    depths[i] = z;
    boxes[i] = vec4<u32>(xs.x, xs.y, ys.x, ys.y);
}

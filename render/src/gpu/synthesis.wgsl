// The synthesis network f of the perceptual wrapper (decoder/src/wrapper/synthesis.rs), one
// invocation per pixel and entry point per layer, each sum in the CPU reference's order:
// `pointwise` (1x1 to the hidden width, ReLU, 1x1 to 3 channels), `residual` (r + bias +
// 3x3 convolution with replicate padding, run twice) and `compose` (clamp(base + R, 0, 1)).

struct Params {
    width: u32,
    height: u32,
    // Conditioning channels per pixel (noise levels, then Plücker).
    conditioning: u32,
    // Hidden width W.
    hidden: u32,
    // Where the current layer's weights start in `weights`.
    offset: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
// Every parameter in stream order (SynthesisWeights::values).
@group(0) @binding(1) var<storage, read> weights: array<f32>;
// Interleaved base RGB.
@group(0) @binding(2) var<storage, read> base: array<f32>;
// Pixel-interleaved conditioning.
@group(0) @binding(3) var<storage, read> conditioning: array<f32>;
// The layer's input residual (unused by `pointwise`) and its output.
@group(0) @binding(4) var<storage, read> r_in: array<f32>;
@group(0) @binding(5) var<storage, read_write> r_out: array<f32>;

const MAX_HIDDEN: u32 = 64u;

@compute @workgroup_size(8, 8, 1)
fn pointwise(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let p = id.y * params.width + id.x;
    let k = params.conditioning;
    let cin = 3u + k;
    let w = params.hidden;
    var hidden: array<f32, MAX_HIDDEN>;
    for (var j = 0u; j < w; j = j + 1u) {
        let row = j * cin;
        var acc = weights[w * cin + j];
        for (var c = 0u; c < 3u; c = c + 1u) {
            acc = acc + weights[row + c] * base[p * 3u + c];
        }
        for (var c = 0u; c < k; c = c + 1u) {
            acc = acc + weights[row + 3u + c] * conditioning[p * k + c];
        }
        hidden[j] = max(acc, 0.0);
    }
    let output = w * cin + w;
    for (var o = 0u; o < 3u; o = o + 1u) {
        var acc = weights[output + 3u * w + o];
        for (var j = 0u; j < w; j = j + 1u) {
            acc = acc + weights[output + o * w + j] * hidden[j];
        }
        r_out[p * 3u + o] = acc;
    }
}

@compute @workgroup_size(8, 8, 1)
fn residual(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let taps = params.offset;
    let bias = taps + 81u;
    let x = i32(id.x);
    let y = i32(id.y);
    let p = id.y * params.width + id.x;
    for (var o = 0u; o < 3u; o = o + 1u) {
        var acc = weights[bias + o];
        for (var i = 0u; i < 3u; i = i + 1u) {
            for (var ky = 0; ky < 3; ky = ky + 1) {
                let sy = u32(clamp(y + ky - 1, 0, i32(params.height) - 1));
                for (var kx = 0; kx < 3; kx = kx + 1) {
                    let sx = u32(clamp(x + kx - 1, 0, i32(params.width) - 1));
                    let tap = weights[taps + ((o * 3u + i) * 3u + u32(ky)) * 3u + u32(kx)];
                    acc = acc + tap * r_in[(sy * params.width + sx) * 3u + i];
                }
            }
        }
        r_out[p * 3u + o] = r_in[p * 3u + o] + acc;
    }
}

@compute @workgroup_size(8, 8, 1)
fn compose(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let p = id.y * params.width + id.x;
    for (var c = 0u; c < 3u; c = c + 1u) {
        r_out[p * 3u + c] = clamp(base[p * 3u + c] + r_in[p * 3u + c], 0.0, 1.0);
    }
}

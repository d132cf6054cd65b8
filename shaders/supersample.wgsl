// Supersampling's resolve: the frame drawn at k times the target's size (k × k samples per
// pixel) box-filtered to the target in linear light, as the CPU's `RgbaImage::downsample`:
// each sample's sRGB byte decoded, the k² samples averaged, the mean encoded and rounded to a
// byte again. Output pixel (x, y) reads samples (x·k + i, y·k + j), i, j < k.
// #import common/types.wgsl

struct Supersample {
    // Samples per pixel side.
    k: u32,
    // The target's size in pixels.
    width: u32,
    height: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: Supersample;
@group(0) @binding(1) var samples: texture_2d<f32>;
@group(0) @binding(2) var output: texture_storage_2d<rgba8unorm, write>;

fn srgb_byte(c: f32) -> f32 {
    // textureLoad of an Rgba8Unorm texel gives byte / 255; decode that byte exactly.
    return srgb_to_linear(round(c * 255.0) / 255.0);
}

@compute @workgroup_size(8, 8)
fn resolve_samples(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let k = params.k;
    var sum = vec4<f32>(0.0);
    for (var j = 0u; j < k; j++) {
        for (var i = 0u; i < k; i++) {
            let c = textureLoad(samples, vec2<i32>(gid.xy * k + vec2<u32>(i, j)), 0);
            sum += vec4<f32>(srgb_byte(c.r), srgb_byte(c.g), srgb_byte(c.b), round(c.a * 255.0));
        }
    }
    let mean = sum / f32(k * k);
    let srgb = vec3<f32>(linear_to_srgb(mean.r), linear_to_srgb(mean.g), linear_to_srgb(mean.b));
    textureStore(output, vec2<i32>(gid.xy), vec4<f32>(round(srgb * 255.0) / 255.0, round(mean.a) / 255.0));
}

// Composites the renderer's RGBA8 target into the editor's viewport rectangle (egui-wgpu sets
// the viewport and scissor to the rectangle). The target already holds sRGB-encoded values and
// egui draws into a non-sRGB framebuffer with gamma-space colours, so texels are copied as they
// are.

@group(0) @binding(0) var frame_tex: texture_2d<f32>;
@group(0) @binding(1) var frame_sampler: sampler;

struct VsOut {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

// One triangle that covers the viewport: vertices at (-1,-1), (3,-1), (-1,3).
@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> VsOut {
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    var out: VsOut;
    out.position = vec4<f32>(x, y, 0.0, 1.0);
    out.uv = vec2<f32>((x + 1.0) * 0.5, (1.0 - y) * 0.5);
    return out;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(textureSample(frame_tex, frame_sampler, in.uv).rgb, 1.0);
}

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

// For an sRGB framebuffer (which encodes on write): decode so the pixel ends up unchanged.
@fragment
fn fs_srgb_target(in: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(srgb_to_linear(textureSample(frame_tex, frame_sampler, in.uv).rgb), 1.0);
}

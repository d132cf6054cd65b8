// Triangle meshes drawn into the same packed depth+id key buffer as the voxel splats: the
// fragment stage does the atomic write instead of a hardware depth test, so meshes and voxels
// occlude each other by exactly the same rule (smallest NDC depth, then smallest id).
// #import common/types.wgsl

// 11 vec4 per world-space triangle (`GpuTriangle` in app/src/gpu/gpu_data.rs): 3 positions,
// 3 normals (w = 1 when the part has vertex normals, else 0: use the face normal), 3 linear
// RGBA colours (material × vertex colour), texture coordinates (a.uv, b.uv), (c.uv, texture
// index or -1, 0). This pass reads only the positions. TRI_STRIDE: generated.

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> tris: array<vec4<f32>>;

struct MeshVarying {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) tri: u32,
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> MeshVarying {
    let tri = vi / 3u;
    let p = tris[TRI_STRIDE * tri + vi % 3u].xyz;
    var out: MeshVarying;
    out.position = view.clip_from_world * vec4<f32>(p, 1.0);
    out.tri = tri;
    return out;
}

// The key's depth half for a fragment.
fn fragment_depth_bits(frag: vec4<f32>) -> u32 {
    return bitcast<u32>(clamp(frag.z, 0.0, 1.0));
}

fn fragment_pixel(frag: vec4<f32>) -> u32 {
    let xy = vec2<u32>(frag.xy);
    return xy.y * view.size.x + xy.x;
}

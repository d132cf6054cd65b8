// Resolve: packed depth+id keys → G-buffer. Voxel ids index the attribute pool (colour, the
// node's normal and its object); mesh ids index the world-space triangle list, whose
// attributes are interpolated at the pixel's unprojected position (as the CPU reference), and
// their base-colour texture sampled there (`Texture::sample_linear`).
// G-buffer texel: x = unorm16 albedo.rg, y = unorm16 (albedo.b, normal.z · 0.5 + 0.5),
// z = snorm16 normal.xy, w = NDC depth bits (EMPTY: background). 16-bit channels keep the
// final 8-bit sRGB exact without needing f16 support.
// #import common/types.wgsl
// #import common/skin.wgsl

// `GpuTriangle` (app/src/gpu/gpu_data.rs, TRI_STRIDE vec4 each, generated); the layout is
// described in common/mesh.wgsl.
// Mesh textures (app/src/gpu/scene.rs): TEXTURE_LUT_WORDS (generated) words sRGB byte →
// linear (f32 bits), then TEXTURE_ENTRY_WORDS words per texture (first texel word, width,
// height, 0), then RGBA8 texels, rows top to bottom.

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> keys: array<vec2<u32>>;
// x = sRGB RGBA8 colour, y = octahedral normal (bits 0..15) | object index (bits 16..31).
@group(0) @binding(2) var<storage, read> attrs: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read> objects: array<ObjectInfo>;
@group(0) @binding(4) var<storage, read> tris: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> gbuffer: array<vec4<u32>>;
@group(0) @binding(8) var<storage, read> textures: array<u32>;
// The voxel pools are split into chunks of whole objects (app/src/gpu/scene.rs): one dispatch
// per chunk, with that chunk's attributes (and skin data) bound; ids stay global.
// `ResolveChunk` in app/src/gpu/gpu_data.rs.
struct ResolveChunk {
    // Global id of attrs[0].
    attr_start: u32,
    // One past the last voxel id this dispatch resolves.
    attr_end: u32,
    // Nonzero: this dispatch also writes the background and mesh pixels.
    others: u32,
    pad: u32,
}
@group(0) @binding(9) var<uniform> resolve_range: ResolveChunk;

fn barycentric(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let n = cross(b - a, c - a);
    let nn = dot(n, n);
    if !(nn > 0.0) {
        return vec3<f32>(1.0, 0.0, 0.0);
    }
    let wa = dot(cross(b - p, c - p), n) / nn;
    let wb = dot(cross(c - p, a - p), n) / nn;
    let bary = max(vec3<f32>(wa, wb, 1.0 - wa - wb), vec3<f32>(0.0));
    let s = bary.x + bary.y + bary.z;
    if s > 0.0 {
        return bary / s;
    }
    return vec3<f32>(1.0, 0.0, 0.0);
}

// One texel as linear RGBA, decoded like the CPU's (`srgb_byte_to_linear`, alpha / 255).
fn texel_linear(base: u32, w: u32, h: u32, xi: i32, yi: i32) -> vec4<f32> {
    // Repeat wrapping (`rem_euclid`): xi >= -1 and xi <= w, so adding w keeps it positive.
    let x = u32(xi + i32(w)) % w;
    let y = u32(yi + i32(h)) % h;
    let p = textures[base + y * w + x];
    return vec4<f32>(
        bitcast<f32>(textures[p & 0xffu]),
        bitcast<f32>(textures[(p >> 8u) & 0xffu]),
        bitcast<f32>(textures[(p >> 16u) & 0xffu]),
        f32(p >> 24u) / 255.0,
    );
}

fn finite(x: f32) -> bool {
    // By the bits: WGSL lets a compiler assume floats are finite, so `x == x` may fold away.
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn lerp4(a: vec4<f32>, b: vec4<f32>, s: f32) -> vec4<f32> {
    // glam's `Vec4::lerp`, operation for operation.
    return a * (1.0 - s) + b * s;
}

// `Texture::sample_linear`: bilinear, repeat wrapping, texel centres at half-integers, UV (0,0)
// the top-left corner; white where the CPU returns white (a non-finite UV).
fn sample_texture(index: u32, uv: vec2<f32>) -> vec4<f32> {
    if !finite(uv.x) || !finite(uv.y) {
        return vec4<f32>(1.0);
    }
    let e = TEXTURE_LUT_WORDS + TEXTURE_ENTRY_WORDS * index;
    let base = textures[e];
    let w = textures[e + 1u];
    let h = textures[e + 2u];
    let u = uv.x - floor(uv.x);
    let v = uv.y - floor(uv.y);
    let x = u * f32(w) - 0.5;
    let y = v * f32(h) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let xi = i32(x0);
    let yi = i32(y0);
    let top = lerp4(texel_linear(base, w, h, xi, yi), texel_linear(base, w, h, xi + 1, yi), fx);
    let bottom = lerp4(
        texel_linear(base, w, h, xi, yi + 1),
        texel_linear(base, w, h, xi + 1, yi + 1),
        fx,
    );
    return lerp4(top, bottom, fy);
}

@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= view.size.x || gid.y >= view.size.y {
        return;
    }
    let pixel = gid.y * view.size.x + gid.x;
    let key = keys[pixel];
    let voxel = key.y != EMPTY && (key.x & MESH_ID_FLAG) == 0u;
    let attr_id = key.x >> FACE_BITS;
    if voxel && (attr_id < resolve_range.attr_start || attr_id >= resolve_range.attr_end) {
        return;
    }
    if !voxel && resolve_range.others == 0u {
        return;
    }
    if key.y == EMPTY {
        gbuffer[pixel] = vec4<u32>(0u, 0u, 0u, EMPTY);
        return;
    }
    let id = key.x;
    var albedo = vec3<f32>(0.0);
    var normal = vec3<f32>(0.0);
    if (id & MESH_ID_FLAG) != 0u {
        let t = TRI_STRIDE * (id & ~MESH_ID_FLAG);
        let a = tris[t].xyz;
        let b = tris[t + 1u].xyz;
        let c = tris[t + 2u].xyz;
        let depth = bitcast<f32>(key.y);
        let p = unproject(view, vec2<f32>(gid.xy) + 0.5, depth);
        let bary = barycentric(p, a, b, c);
        albedo = (tris[t + 6u] * bary.x + tris[t + 7u] * bary.y + tris[t + 8u] * bary.z).xyz;
        let uv_ab = tris[t + 9u];
        let uv_c = tris[t + 10u];
        if uv_c.z >= 0.0 {
            let uv = uv_ab.xy * bary.x + uv_ab.zw * bary.y + uv_c.xy * bary.z;
            albedo *= sample_texture(u32(uv_c.z), uv).xyz;
        }
        let face = cross(b - a, c - a);
        var n = face;
        if tris[t + 3u].w > 0.0 {
            n = (tris[t + 3u] * bary.x + tris[t + 4u] * bary.y + tris[t + 5u] * bary.z).xyz;
        }
        n = normalize_or_zero(n);
        // Two-sided: light the side facing the viewer.
        if dot(face, toward_eye(view, p)) < 0.0 {
            n = -n;
        }
        normal = n;
    } else {
        let attr = attrs[attr_id - resolve_range.attr_start];
        let rgba = unpack4x8unorm(attr.x);
        albedo = vec3<f32>(srgb_to_linear(rgba.x), srgb_to_linear(rgba.y), srgb_to_linear(rgba.z));
        let o = objects[attr.y >> 16u];
        // An exact cube's pixel is shaded with the face it shows (the CPU's `face_normal`), a
        // splat with the node's own normal.
        var nv = decode_normal(attr.y & 0xffffu);
        let face = id & FACE_MASK;
        if face >= 1u && face <= 6u {
            let axis = (face - 1u) / 2u;
            let sign = select(1.0, -1.0, face % 2u == 0u);
            nv = vec3<f32>(0.0);
            nv[axis] = sign;
        }
        if o.skin_attr.x != 0u {
            // A rigged object's node: its own blended matrix turns the normal.
            let leaf = attr_id >= o.skin_attr.z;
            normal = skinned_normal(o.skin, leaf, attr_id - select(o.skin_attr.y, o.skin_attr.z, leaf), nv);
        } else {
            normal = normalize_or_zero(o.normal_x.xyz * nv.x + o.normal_y.xyz * nv.y + o.normal_z.xyz * nv.z);
        }
    }
    gbuffer[pixel] = vec4<u32>(
        pack2x16unorm(albedo.xy),
        pack2x16unorm(vec2<f32>(albedo.z, normal.z * 0.5 + 0.5)),
        pack2x16snorm(normal.xy),
        key.y,
    );
}

// Shared constants, structs and helpers for every pass.
// Keep in sync with app/src/gpu/gpu_data.rs (the struct layouts are checked by the gpu_layout
// test; the constants both sides use are generated from gpu_data.rs: gpu_data::WGSL_CONSTANTS,
// prepended to every shader as constants.wgsl by gpu::shaders::compose).

// An empty pixel: both halves of the packed key are all ones (depth bits above any finite
// depth in 0..1, id above any id), so an atomic minimum replaces it with the first splat.
const EMPTY: u32 = 0xffffffffu;
// Ids with this bit set are triangles (bits 0..30: triangle index); below it, voxel attribute
// indices (paper's node id): MESH_ID_FLAG, generated.
// Low bits of a voxel id: the face an exact cube's pixel shows (1..6: +x, -x, +y, -y, +z, -z
// in the node's own axes; 0: a splat, shaded with the node's normal). Voxel ids are
// attribute index << FACE_BITS | face (the CPU's `render::asvo::FACE_BITS`; FACE_BITS and
// FACE_MASK generated).

// How splats and fragments write the key buffer (View::write_mode, generated):
// MODE_KEY64, 64-bit path: one atomicMin of (depth << 32 | id);
// MODE_DEPTH, 32-bit path, pass 1 (and shadow maps): atomicMin of the depth bits;
// MODE_ID, 32-bit path, pass 2: atomicMin of the id where the stored depth equals ours.

// Counter buffer layout (array<atomic<u32>>).
const QUEUE_COUNTS: u32 = 0u;   // 32 entries: nodes queued for each level
// Generated: OVERFLOW_COUNTER (children dropped because a queue was full),
// SPLAT_PIXEL_COUNTERS (key atomics of voxel splats: [0] the view, [1] shadow maps),
// CUBE_PIXEL_COUNTERS (pixels tested by exact cubes: [0] the view, [1] shadow maps),
// STATS_START (first per-view statistics counter, the view's), MAX_LEVELS.

// A camera with its image size (the view, or a light's shadow camera).
struct View {
    view_from_world: mat4x4<f32>,
    clip_from_world: mat4x4<f32>,
    world_from_view: mat4x4<f32>,
    size: vec2<u32>,
    perspective: u32,
    write_mode: u32,
    // Pixels per view unit at view depth 1 (perspective) or per unit (orthographic).
    fx: f32,
    fy: f32,
    near: f32,
    far: f32,
    lod_pixel_threshold: f32,
    // 1: cull nodes behind the hierarchical depth tiles (hiz.wgsl); 0: no occlusion culling.
    occlusion: u32,
    // Occlusion tiles per row (ceil(width / OCCLUSION_TILE)).
    tiles_x: u32,
    // Splats wider or taller than this many pixels are drawn as their exact cube.
    cube_pixel_threshold: f32,
}

// OCCLUSION_TILE (generated): edge of an occlusion tile in pixels.
// Most tiles a node's rectangle may span for the occlusion test (larger nodes are not tested).
const OCCLUSION_MAX_TILES: u32 = 16u;

// One traversal dispatch: an object seen from a view, at one octree level.
struct NodeParams {
    // Columns of the linear part of view_from_voxel.
    linear_x: vec4<f32>,
    linear_y: vec4<f32>,
    linear_z: vec4<f32>,
    // xyz: translation of view_from_voxel; w: longest world edge of a 1-voxel node.
    translation_edge: vec4<f32>,
    // View-space AABB half extent of a 1-voxel node.
    half_extent_unit: vec4<f32>,
    level: u32,
    node_size: u32,
    leaf_level: u32,
    queue_capacity: u32,
    inner_base: u32,
    leaf_base: u32,
    attr_inner_base: u32,
    attr_leaf_base: u32,
    stats_base: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    // Rigged objects: how nodes are skinned (strategy SKIN_RIGID for rigid objects).
    skin: SkinParams,
}

// SkinParams::strategy: a rigid object, or a rigged one's stretch strategy (SKIN_RIGID,
// SKIN_OFF, SKIN_THESIS, SKIN_CORNERS, SKIN_ADAPTIVE: generated from gpu_data::SkinStrategy).
// SkinParams::flags: SKIN_HAS_CORNERS, SKIN_HAS_OVERRIDES (generated).

// Per-object skinning constants (app/src/gpu/skin.rs): joint matrices in `joints`, word
// offsets of the object's sections of `skin_data` (common/skin.wgsl), stretch settings.
struct SkinParams {
    joint_base: u32,
    joint_count: u32,
    strategy: u32,
    flags: u32,
    inner_skin: u32,
    leaf_skin: u32,
    inner_corners: u32,
    leaf_corners: u32,
    subtree_ranges: u32,
    subtree_joints: u32,
    overrides: u32,
    _pad0: u32,
    multiplier: f32,
    min_factor: f32,
    max_factor: f32,
    // Largest factor a descendant may be drawn with (culling boxes): max(1, max_factor,
    // largest override) × multiplier.
    grow: f32,
}

// Per-object constants the resolve pass needs.
struct ObjectInfo {
    // Columns of the inverse transpose of world_from_voxel's linear part.
    normal_x: vec4<f32>,
    normal_y: vec4<f32>,
    normal_z: vec4<f32>,
    // Rigged objects: x = 1, y = attribute index of inner node 0, z = of leaf 0 (to tell the
    // pool of an id); SKIN_RIGID objects have x = 0.
    skin_attr: vec4<u32>,
    // Rigged objects: the SkinParams the resolve needs (joints, node-skin offsets).
    skin: SkinParams,
}

// One directional light.
struct LightGpu {
    // Unit vector toward the light.
    to_light: vec3<f32>,
    // Index of its shadow map in the shade pass's ShadowMap array, or NO_SHADOW_MAP.
    shadow_map: u32,
    // Linear colour × intensity.
    color: vec4<f32>,
}

// NO_SHADOW_MAP (generated): LightGpu::shadow_map of a light without a shadow map this frame.

// One light's shadow map: its camera and its first word in the shared shadow key buffer
// (texel p's depth bits at key_word_offset + 2p + 1).
struct ShadowMap {
    view: View,
    key_word_offset: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Deferred-shading constants.
struct Shading {
    ambient: vec4<f32>,
    background: vec4<f32>,
    light_count: u32,
    pcf_radius: u32,
    // max(1, lod pixel threshold): the receiver's splat size in pixels, for the shadow bias.
    receiver_px: f32,
    // Ambient occlusion: sample count (0 = off), world radius, per-sample phases (core's
    // `ao_sample_phases`: elevation stratum start, azimuth phase, distance phase).
    ao_count: u32,
    ao_radius: f32,
    // Entries per pixel of the KRS lighting buffer (0: no KRS this frame; krs_trace.wgsl).
    krs_stride: u32,
    _pad1: u32,
    _pad2: u32,
    ao_kernel: array<vec4<f32>, 64>,
}

// NDC depth (0 near, 1 far) of a view depth.
fn ndc_depth(v: View, view_depth: f32) -> f32 {
    if v.perspective != 0u {
        return v.far / (v.far - v.near) * (1.0 - v.near / view_depth);
    }
    return (view_depth - v.near) / (v.far - v.near);
}

// Unit direction from a world point towards the eye: the view axis's back direction for an
// orthographic view, whose rays are parallel (core::render::Camera::toward_eye).
fn toward_eye(v: View, p: vec3<f32>) -> vec3<f32> {
    if v.perspective != 0u {
        return normalize_or_zero(v.world_from_view[3].xyz - p);
    }
    return normalize_or_zero(v.world_from_view[2].xyz);
}

// Inverse of ndc_depth.
fn view_depth_of(v: View, ndc: f32) -> f32 {
    if v.perspective != 0u {
        return v.near / (1.0 - ndc * (v.far - v.near) / v.far);
    }
    return v.near + ndc * (v.far - v.near);
}

// Screen position (pixels, row 0 at the top) and view depth of a view-space point.
fn project_view(v: View, p_view: vec3<f32>) -> vec3<f32> {
    let d = -p_view.z;
    var s = p_view.xy;
    if v.perspective != 0u {
        s = p_view.xy / d;
    }
    let size = vec2<f32>(v.size);
    return vec3<f32>(0.5 * size.x + v.fx * s.x, 0.5 * size.y - v.fy * s.y, d);
}

// World position of a screen point at an NDC depth.
fn unproject(v: View, screen: vec2<f32>, ndc: f32) -> vec3<f32> {
    let d = view_depth_of(v, ndc);
    let size = vec2<f32>(v.size);
    let sx = (screen.x - 0.5 * size.x) / v.fx;
    let sy = (0.5 * size.y - screen.y) / v.fy;
    var p_view = vec3<f32>(sx, sy, -d);
    if v.perspective != 0u {
        p_view = vec3<f32>(sx * d, sy * d, -d);
    }
    return (v.world_from_view * vec4<f32>(p_view, 1.0)).xyz;
}

// World size of one pixel at a view depth.
fn pixel_world_size(v: View, view_depth: f32) -> f32 {
    if v.perspective != 0u {
        return abs(view_depth) / v.fy;
    }
    return 1.0 / min(v.fx, v.fy);
}

fn oct_wrap(p: vec2<f32>) -> vec2<f32> {
    let s = select(vec2<f32>(-1.0), vec2<f32>(1.0), p >= vec2<f32>(0.0));
    return (vec2<f32>(1.0) - abs(p.yx)) * s;
}

// Inverse of core::svo::encode_normal (8+8-bit octahedral).
fn decode_normal(e: u32) -> vec3<f32> {
    let p = vec2<f32>(f32(e & 0xffu), f32((e >> 8u) & 0xffu)) / 255.0 * 2.0 - 1.0;
    let z = 1.0 - abs(p.x) - abs(p.y);
    var xy = p;
    if z < 0.0 {
        xy = oct_wrap(p);
    }
    let n = vec3<f32>(xy, z);
    let len = length(n);
    if len > 0.0 {
        return n / len;
    }
    return vec3<f32>(0.0, 0.0, 1.0);
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        return c / 12.92;
    }
    return pow((c + 0.055) / 1.055, 2.4);
}

fn linear_to_srgb(c_in: f32) -> f32 {
    let c = clamp(c_in, 0.0, 1.0);
    if c <= 0.0031308 {
        return c * 12.92;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

// Unit vector or zero (never NaN).
fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let l = length(v);
    if l > 0.0 && l < 3.0e38 {
        return v / l;
    }
    return vec3<f32>(0.0);
}

// Wellons' lowbias32 finaliser: core's `krs::lowbias32`, bit for bit.
fn lowbias32(seed: u32) -> u32 {
    var x = seed;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

// A jitter in [0, 1) from a seed (a pixel index): core's `krs::ao_jitter` (lowbias32, top 24
// bits), shared by the KRS AO (krs_trace.wgsl) and the screen-space AO (shade.wgsl).
fn ao_jitter(seed: u32) -> f32 {
    return f32(lowbias32(seed) >> 8u) / 16777216.0;
}

// KRS pass (KRS paper §4, §6): per-pixel sphere tracing into the shared depth + G-buffer,
// then per-pixel KRS lighting inputs for the deferred shade pass. The GPU port of core::krs
// (object.rs, kernel.rs, distort.rs, trace.rs, shade.rs) and core::render::krs, in f32 (see
// docs/gpu.md "KRS pass"). Keep the structs in sync with app/src/gpu/gpu_data.rs
// (`KrsObjectGpu`, `KrsKernelGpu`, `KrsFrameUniform`).
//
// Entry points: `trace` (one invocation per pixel, 8×8 workgroups = the CPU's KRS_TILE cone
// tiles) runs after resolve: a hit nearer than the G-buffer's depth overwrites the G-buffer
// texel and records the exact hit point, epsilon and Algorithm 2 factors in `krs_light`;
// `light` then computes, for every covered pixel, KRS ambient occlusion and per-light shadow
// rays through the KRS, which shade.wgsl multiplies in.
// #import common/types.wgsl

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<uniform> krs: KrsFrame;
@group(0) @binding(2) var<storage, read> krs_objects: array<KrsObject>;
@group(0) @binding(3) var<storage, read> krs_kernels: array<KrsKernel>;
// Mirrors (normal, offset), then empty zones (centre, radius), then lights (to_light, 1 when
// the light takes KRS shadow rays), each object indexing its own ranges.
@group(0) @binding(4) var<storage, read> krs_vectors: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> gbuffer: array<vec4<u32>>;
// Per pixel `krs.stride` entries. After `trace`: [0] = (exact hit point, epsilon) on KRS
// pixels, w = -1 elsewhere; [1 + l] = (Algorithm 2 factor, 1 when it replaces n·l, 1, 0).
// After `light`: [0] = (shading point, KRS ambient accessibility, plus 2 on KRS pixels so the
// shade pass's screen AO can skip them as occluders); [1 + l].z = visibility of light l
// through the KRS.
@group(0) @binding(6) var<storage, read_write> krs_light: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> counters: array<atomic<u32>>;

// First KRS word of the counter buffer (`KRS_COUNTERS` in gpu_data.rs): rays, hits, steps
// (lo, hi), max steps of one ray, exhausted rays, relaxation fallbacks, tile steps, shadow
// rays, shadow steps (lo, hi), AO evaluations (lo, hi). Generated.

// Kernel kinds (`KrsKernelGpu::kind`: KRS_EMPTY, KRS_SPHERE, KRS_PLANE, KRS_CAPSULE, KRS_BOX,
// KRS_TORUS_SEGMENT, KRS_TOROIDAL_CAPSULE), texture modes (KRS_TEXTURE_NONE,
// KRS_TEXTURE_TRIPLANAR, KRS_TEXTURE_KERNEL_PARAM) and patterns (KRS_PATTERN_CHECKER,
// KRS_PATTERN_BARK): generated from gpu_data's KrsKernelKind, KrsTextureMode, KrsPattern.

// Object flags (KRS_OBJ_EMPTY, KRS_OBJ_DISTORTED, KRS_OBJ_BOUNDED) and frame flags
// (KRS_FRAME_TILES, KRS_FRAME_SHADOWS, KRS_FRAME_SOFT): generated.

// "No distance" (the CPU's f32::INFINITY): WGSL has no infinity literal.
const KRS_FAR: f32 = 3.0e38;
const KRS_TAU: f32 = 6.283185307179586;
const KRS_PI: f32 = 3.141592653589793;

struct KrsObject {
    inv_rotation: vec4<f32>,
    rotation: vec4<f32>,
    // xyz translation, w uniform scale.
    translation_scale: vec4<f32>,
    // World bounding ball (valid with KRS_OBJ_BOUNDED).
    bound: vec4<f32>,
    first_mirror: u32,
    mirror_count: u32,
    first_kernel: u32,
    first_zone: u32,
    zone_count: u32,
    flags: u32,
    texture_mode: u32,
    pattern: u32,
    inv_scale: f32,
    lipschitz: f32,
    amplitude: f32,
    frequency: f32,
    seed: u32,
    tex_scale: f32,
    tex_contrast: f32,
    tex_sharpness: f32,
}

struct KrsKernel {
    // x: kind; yzw unused.
    kind: vec4<u32>,
    // rgb: linear material colour.
    colour: vec4<f32>,
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
    d: vec4<f32>,
    e: vec4<f32>,
    f: vec4<f32>,
}

struct KrsFrame {
    eps_scale: f32,
    pixel_cone: f32,
    min_epsilon: f32,
    max_steps: u32,
    over_relaxation: f32,
    grid_q0: f32,
    grid_t0: f32,
    grid_log_step: f32,
    grid_u0: f32,
    object_count: u32,
    light_count: u32,
    light_base: u32,
    flags: u32,
    ao_samples: u32,
    ao_spacing: f32,
    receiver_px: f32,
    // Entries of `krs_light` per pixel (1 + light count).
    stride: u32,
    smoothing_px: f32,
    soft_k: f32,
    pad: u32,
}

fn quat_rotate(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    let b = q.xyz;
    let w = q.w;
    return v * (w * w - dot(b, b)) + b * (dot(v, b) * 2.0) + cross(b, v) * (w * 2.0);
}

fn normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let l = length(v);
    if l > 0.0 && l < 3.0e38 {
        return v / l;
    }
    return fallback;
}

// glam's Vec3::any_orthonormal_vector (Pixar's branchless basis).
fn any_perpendicular(v: vec3<f32>) -> vec3<f32> {
    let s = select(-1.0, 1.0, v.z >= 0.0);
    let a = -1.0 / (s + v.z);
    let b = v.x * v.y * a;
    return vec3<f32>(b, s + v.y * v.y * a, -v.y);
}

fn sign_not_zero(v: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(-1.0), vec3<f32>(1.0), v >= vec3<f32>(0.0));
}

fn closest_on_segment(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    let ab = b - a;
    let len2 = dot(ab, ab);
    if !(len2 > 0.0) {
        return a;
    }
    let t = clamp(dot(p - a, ab) / len2, 0.0, 1.0);
    return a + ab * t;
}

// Torus layout: a = (centre, major), b = (axis, minor), c = (start_dir u, sweep),
// d = (axis × start_dir w, sin sweep), e = (end point, cos sweep), f = (start point, 0).
// Returns the closest arc point (xyz) and its angle (w).
fn torus_closest(k: KrsKernel, p: vec3<f32>) -> vec4<f32> {
    let q = p - k.a.xyz;
    let x = dot(q, k.c.xyz);
    let y = dot(q, k.d.xyz);
    var theta = atan2(y, x);
    if theta < 0.0 {
        theta += KRS_TAU;
    }
    if theta <= k.c.w {
        return vec4<f32>(k.a.xyz + k.a.w * (cos(theta) * k.c.xyz + sin(theta) * k.d.xyz), theta);
    }
    let a = k.f.xyz;
    let b = k.e.xyz;
    let da = p - a;
    let db = p - b;
    if dot(da, da) <= dot(db, db) {
        return vec4<f32>(a, 0.0);
    }
    return vec4<f32>(b, k.c.w);
}

// Wedge distance (x) and outward gradient (yzw).
fn torus_wedge(k: KrsKernel, p: vec3<f32>) -> vec4<f32> {
    let q = p - k.a.xyz;
    let u = k.c.xyz;
    let w = k.d.xyz;
    let h0 = -dot(q, w);
    let tangent_end = -k.d.w * u + k.e.w * w;
    let h1 = dot(q, tangent_end);
    var use_first = h0 <= h1;
    if k.c.w <= KRS_PI {
        use_first = h0 >= h1;
    }
    if use_first {
        return vec4<f32>(h0, -w);
    }
    return vec4<f32>(h1, tangent_end);
}

fn kernel_distance(k: KrsKernel, p: vec3<f32>) -> f32 {
    switch k.kind.x {
        case KRS_SPHERE: {
            return distance(p, k.a.xyz) - k.a.w;
        }
        case KRS_PLANE: {
            return dot(k.a.xyz, p) - k.a.w;
        }
        case KRS_CAPSULE: {
            return distance(p, closest_on_segment(p, k.a.xyz, k.b.xyz)) - k.a.w;
        }
        case KRS_BOX: {
            let q = quat_rotate(k.b, p - k.a.xyz);
            let e = abs(q) - k.c.xyz + vec3<f32>(k.a.w);
            return length(max(e, vec3<f32>(0.0))) + min(max(e.x, max(e.y, e.z)), 0.0) - k.a.w;
        }
        case KRS_TORUS_SEGMENT: {
            let c = torus_closest(k, p);
            let tube = distance(p, c.xyz) - k.b.w;
            return max(tube, torus_wedge(k, p).x);
        }
        case KRS_TOROIDAL_CAPSULE: {
            let c = torus_closest(k, p);
            return distance(p, c.xyz) - k.b.w;
        }
        default: {
            return KRS_FAR;
        }
    }
}

fn torus_tube_normal(k: KrsKernel, p: vec3<f32>) -> vec3<f32> {
    let c = torus_closest(k, p).xyz;
    let n = p - c;
    if dot(n, n) > 0.0 {
        return n;
    }
    return normalize_or(c - k.a.xyz, k.c.xyz);
}

fn kernel_normal(k: KrsKernel, p: vec3<f32>) -> vec3<f32> {
    var n = vec3<f32>(0.0, 1.0, 0.0);
    switch k.kind.x {
        case KRS_SPHERE: {
            n = p - k.a.xyz;
        }
        case KRS_PLANE: {
            n = k.a.xyz;
        }
        case KRS_CAPSULE: {
            n = p - closest_on_segment(p, k.a.xyz, k.b.xyz);
            if !(dot(n, n) > 0.0) {
                n = any_perpendicular(normalize_or(k.b.xyz - k.a.xyz, vec3<f32>(0.0, 1.0, 0.0)));
            }
        }
        case KRS_BOX: {
            let q = quat_rotate(k.b, p - k.a.xyz);
            let e = abs(q) - k.c.xyz + vec3<f32>(k.a.w);
            var local = vec3<f32>(0.0);
            if max(e.x, max(e.y, e.z)) > 0.0 {
                local = max(e, vec3<f32>(0.0)) * sign_not_zero(q);
            } else if e.x >= e.y && e.x >= e.z {
                local.x = sign_not_zero(q).x;
            } else if e.y >= e.z {
                local.y = sign_not_zero(q).y;
            } else {
                local.z = sign_not_zero(q).z;
            }
            n = quat_rotate(k.d, local);
        }
        case KRS_TORUS_SEGMENT: {
            let c = torus_closest(k, p);
            let tube = distance(p, c.xyz) - k.b.w;
            let wedge = torus_wedge(k, p);
            if wedge.x > tube {
                n = wedge.yzw;
            } else {
                n = torus_tube_normal(k, p);
            }
        }
        case KRS_TOROIDAL_CAPSULE: {
            n = torus_tube_normal(k, p);
        }
        default: {}
    }
    return normalize_or(n, vec3<f32>(0.0, 1.0, 0.0));
}

// Kernel-parametrised coordinates (§6.2), as core's `Kernel::param_coords`.
fn kernel_param_coords(k: KrsKernel, p: vec3<f32>) -> vec2<f32> {
    switch k.kind.x {
        case KRS_SPHERE: {
            let q = normalize_or(p - k.a.xyz, vec3<f32>(0.0, 1.0, 0.0));
            return vec2<f32>(atan2(q.z, q.x) * k.a.w, asin(clamp(q.y, -1.0, 1.0)) * k.a.w);
        }
        case KRS_PLANE: {
            let u = any_perpendicular(k.a.xyz);
            let v = cross(k.a.xyz, u);
            return vec2<f32>(dot(p, u), dot(p, v));
        }
        case KRS_CAPSULE: {
            let axis = normalize_or(k.b.xyz - k.a.xyz, vec3<f32>(0.0, 1.0, 0.0));
            let u = any_perpendicular(axis);
            let v = cross(axis, u);
            let q = p - k.a.xyz;
            return vec2<f32>(dot(q, axis), atan2(dot(q, v), dot(q, u)) * k.a.w);
        }
        case KRS_BOX: {
            let q = quat_rotate(k.b, p - k.a.xyz);
            let a = abs(q) / max(k.c.xyz, vec3<f32>(1e-30));
            if a.x >= a.y && a.x >= a.z {
                return q.yz;
            } else if a.y >= a.z {
                return q.xz;
            }
            return q.xy;
        }
        case KRS_TORUS_SEGMENT, KRS_TOROIDAL_CAPSULE: {
            let c = torus_closest(k, p);
            let radial = normalize_or(c.xyz - k.a.xyz, k.c.xyz);
            let q = p - c.xyz;
            let around = atan2(dot(q, k.b.xyz), dot(q, radial));
            return vec2<f32>(c.w * k.a.w, around * k.b.w);
        }
        default: {
            return vec2<f32>(0.0);
        }
    }
}

// ---- distortion (value noise warp, core::krs::distort) ----

fn krs_hash(x: i32, y: i32, z: i32, seed: u32) -> u32 {
    return lowbias32((bitcast<u32>(x) * 0x8da6b343u) ^ (bitcast<u32>(y) * 0xd8163841u)
        ^ (bitcast<u32>(z) * 0xcb1ab31fu) ^ (seed * 0x9e3779b9u));
}

fn unit_value(h: u32) -> f32 {
    return f32(h >> 8u) * (2.0 / 16777215.0) - 1.0;
}

fn value_noise3(p: vec3<f32>, seed: u32) -> vec3<f32> {
    let cell = floor(p);
    let t = clamp(p - cell, vec3<f32>(0.0), vec3<f32>(1.0));
    let s = t * t * (vec3<f32>(3.0) - 2.0 * t);
    let ic = vec3<i32>(cell);
    var corners: array<vec3<f32>, 8>;
    for (var i = 0; i < 8; i++) {
        let h = krs_hash(ic.x + (i & 1), ic.y + ((i >> 1u) & 1), ic.z + ((i >> 2u) & 1), seed);
        corners[i] = vec3<f32>(
            unit_value(h),
            unit_value(krs_hash(bitcast<i32>(h), 1, 0, seed)),
            unit_value(krs_hash(bitcast<i32>(h), 2, 0, seed)),
        );
    }
    let x00 = mix(corners[0], corners[1], s.x);
    let x10 = mix(corners[2], corners[3], s.x);
    let x01 = mix(corners[4], corners[5], s.x);
    let x11 = mix(corners[6], corners[7], s.x);
    let y0 = mix(x00, x10, s.y);
    let y1 = mix(x01, x11, s.y);
    return mix(y0, y1, s.z);
}

fn warp(o: KrsObject, p: vec3<f32>) -> vec3<f32> {
    return p + o.amplitude * value_noise3(p * o.frequency, o.seed);
}

// ---- Algorithm 1 ----

fn object_from_world(o: KrsObject, p_world: vec3<f32>) -> vec3<f32> {
    return quat_rotate(o.inv_rotation, p_world - o.translation_scale.xyz) * o.inv_scale;
}

// Algorithm 1's fold of one object, written once for every caller (distance, surface, smooth
// diffuse): the object-space point folded through the mirrors so far, coarsest level first;
// `e`, the signed distance of the point to the last mirror before its reflection; and the
// nearest non-empty kernel met so far (index, distance, the folded point it was measured at).
struct KrsFold {
    p: vec3<f32>,
    e: f32,
    best_p: vec3<f32>,
    best_d: f32,
    best_k: u32,
}

fn krs_mirror(o: KrsObject, i: u32) -> vec4<f32> {
    return krs_vectors[o.first_mirror + i];
}

// Kernel i at the folded point, kept when it is the nearest so far (empty kernels skipped).
fn fold_kernel(o: KrsObject, f_in: KrsFold, i: u32) -> KrsFold {
    var f = f_in;
    let k = krs_kernels[o.first_kernel + i];
    if k.kind.x != KRS_EMPTY {
        let d = kernel_distance(k, f.p);
        if d < f.best_d {
            f.best_d = d;
            f.best_k = i;
            f.best_p = f.p;
        }
    }
    return f;
}

// The fold at an object-space (warped) point before any mirror: the top level's kernel
// (index mirror_count).
fn fold_start(o: KrsObject, p: vec3<f32>) -> KrsFold {
    var f: KrsFold;
    f.p = p;
    f.e = 0.0;
    f.best_p = p;
    f.best_d = KRS_FAR;
    f.best_k = 0xffffffffu;
    return fold_kernel(o, f, o.mirror_count);
}

// One level down: reflect through mirror i when the point is on its positive side, then
// kernel i. Callers step i = mirror_count - 1 down to 0.
fn fold_next(o: KrsObject, f_in: KrsFold, i: u32) -> KrsFold {
    var f = f_in;
    let m = krs_mirror(o, i);
    f.e = dot(m.xyz, f.p) - m.w;
    if f.e > 0.0 {
        f.p -= (2.0 * f.e) * m.xyz;
    }
    return fold_kernel(o, f, i);
}

// Distance from an object-space (warped) point: the fold's nearest kernel (KRS_FAR when every
// kernel is empty).
fn distance_object(o: KrsObject, p: vec3<f32>) -> f32 {
    let n = o.mirror_count;
    var f = fold_start(o, p);
    for (var j = 0u; j < n; j++) {
        f = fold_next(o, f, n - 1u - j);
    }
    return f.best_d;
}

fn distance_world(o: KrsObject, p_world: vec3<f32>) -> f32 {
    var p = object_from_world(o, p_world);
    if (o.flags & KRS_OBJ_DISTORTED) != 0u {
        p = warp(o, p);
    }
    var d = distance_object(o, p);
    if d < KRS_FAR {
        d = d * o.translation_scale.w / o.lipschitz;
    }
    for (var z = 0u; z < o.zone_count; z++) {
        let zone = krs_vectors[o.first_zone + z];
        d = max(d, zone.w - distance(p_world, zone.xyz));
    }
    return d;
}

// Distance to the union of all objects (bound culling is exact, as the CPU's).
fn scene_distance(p: vec3<f32>) -> f32 {
    var best = KRS_FAR;
    for (var i = 0u; i < krs.object_count; i++) {
        let o = krs_objects[i];
        if (o.flags & KRS_OBJ_EMPTY) != 0u {
            continue;
        }
        if (o.flags & KRS_OBJ_BOUNDED) != 0u && (distance(p, o.bound.xyz) - o.bound.w) / o.lipschitz >= best {
            continue;
        }
        best = min(best, distance_world(o, p));
    }
    return best;
}

// Index of the nearest object (u32 max when none).
fn nearest_object(p: vec3<f32>) -> u32 {
    var best = KRS_FAR;
    var found = 0xffffffffu;
    for (var i = 0u; i < krs.object_count; i++) {
        let o = krs_objects[i];
        if (o.flags & KRS_OBJ_EMPTY) != 0u {
            continue;
        }
        if found != 0xffffffffu && (o.flags & KRS_OBJ_BOUNDED) != 0u
            && (distance(p, o.bound.xyz) - o.bound.w) / o.lipschitz >= best {
            continue;
        }
        let d = distance_world(o, p);
        if d < KRS_FAR && (found == 0xffffffffu || d < best) {
            best = d;
            found = i;
        }
    }
    return found;
}

struct KrsSurface {
    normal: vec3<f32>,
    kernel: u32,
    kernel_point: vec3<f32>,
}

fn householder(n: vec3<f32>) -> mat3x3<f32> {
    return mat3x3<f32>(
        vec3<f32>(1.0, 0.0, 0.0) - 2.0 * n * n.x,
        vec3<f32>(0.0, 1.0, 0.0) - 2.0 * n * n.y,
        vec3<f32>(0.0, 0.0, 1.0) - 2.0 * n * n.z,
    );
}

// Algorithm 1 with the nearest kernel, its kernel-space point and the reflection product; the
// world normal (§6.1, through the warp's Jacobian and the empty zones as the CPU's
// `sample_world`).
fn surface_world(o: KrsObject, p_world: vec3<f32>) -> KrsSurface {
    let p0 = object_from_world(o, p_world);
    var q = p0;
    let distorted = (o.flags & KRS_OBJ_DISTORTED) != 0u;
    if distorted {
        q = warp(o, p0);
    }
    let n = o.mirror_count;
    var frame = mat3x3<f32>(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
    var best_frame = frame;
    var f = fold_start(o, q);
    for (var j = 0u; j < n; j++) {
        let i = n - 1u - j;
        f = fold_next(o, f, i);
        if f.e > 0.0 {
            frame = frame * householder(krs_mirror(o, i).xyz);
        }
        if f.best_k == i {
            best_frame = frame;
        }
    }
    let best_d = f.best_d;
    let best_k = f.best_k;
    let best_p = f.best_p;
    var s: KrsSurface;
    s.kernel = best_k;
    s.kernel_point = best_p;
    if best_k == 0xffffffffu {
        s.normal = vec3<f32>(0.0, 1.0, 0.0);
        return s;
    }
    var dist = best_d * o.translation_scale.w / o.lipschitz;
    var n_object = best_frame * kernel_normal(krs_kernels[o.first_kernel + best_k], best_p);
    if distorted {
        let h = 1e-3 / max(o.frequency, 1e-3);
        let jx = (warp(o, p0 + vec3<f32>(h, 0.0, 0.0)) - warp(o, p0 - vec3<f32>(h, 0.0, 0.0))) / (2.0 * h);
        let jy = (warp(o, p0 + vec3<f32>(0.0, h, 0.0)) - warp(o, p0 - vec3<f32>(0.0, h, 0.0))) / (2.0 * h);
        let jz = (warp(o, p0 + vec3<f32>(0.0, 0.0, h)) - warp(o, p0 - vec3<f32>(0.0, 0.0, h))) / (2.0 * h);
        n_object = vec3<f32>(dot(jx, n_object), dot(jy, n_object), dot(jz, n_object));
    }
    var n_world = normalize_or(quat_rotate(o.rotation, n_object), vec3<f32>(0.0, 1.0, 0.0));
    for (var z = 0u; z < o.zone_count; z++) {
        let zone = krs_vectors[o.first_zone + z];
        let carve = zone.w - distance(p_world, zone.xyz);
        if carve > dist {
            dist = carve;
            n_world = normalize_or(zone.xyz - p_world, vec3<f32>(0.0, 1.0, 0.0));
        }
    }
    s.normal = n_world;
    return s;
}

// Algorithm 2 (§6.1): the Lambert factor with the light direction carried into kernel space,
// blended within `e_threshold_world` of each mirror plane.
fn smooth_diffuse(o: KrsObject, p_world: vec3<f32>, light_world: vec3<f32>, e_threshold_world: f32) -> f32 {
    let p0 = object_from_world(o, p_world);
    var p = p0;
    let light_object = normalize_or(quat_rotate(o.inv_rotation, light_world), vec3<f32>(0.0, 1.0, 0.0));
    var omega = light_object;
    // Distorted: carry J·l (core::krs::shade::smooth_shading) and rescale at the end.
    let distorted = (o.flags & KRS_OBJ_DISTORTED) != 0u;
    var jx = vec3<f32>(1.0, 0.0, 0.0);
    var jy = vec3<f32>(0.0, 1.0, 0.0);
    var jz = vec3<f32>(0.0, 0.0, 1.0);
    var light_len = 1.0;
    if distorted {
        let h = 1e-3 / max(o.frequency, 1e-3);
        jx = (warp(o, p0 + vec3<f32>(h, 0.0, 0.0)) - warp(o, p0 - vec3<f32>(h, 0.0, 0.0))) / (2.0 * h);
        jy = (warp(o, p0 + vec3<f32>(0.0, h, 0.0)) - warp(o, p0 - vec3<f32>(0.0, h, 0.0))) / (2.0 * h);
        jz = (warp(o, p0 + vec3<f32>(0.0, 0.0, h)) - warp(o, p0 - vec3<f32>(0.0, 0.0, h))) / (2.0 * h);
        let jl = jx * light_object.x + jy * light_object.y + jz * light_object.z;
        omega = normalize_or(jl, light_object);
        light_len = length(jl);
        p = warp(o, p0);
    }
    var frame = mat3x3<f32>(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
    var best_frame = frame;
    let e_threshold = max(e_threshold_world / o.translation_scale.w, 0.0);
    let n = o.mirror_count;
    var best_omega = omega;
    var f = fold_start(o, p);
    for (var j = 0u; j < n; j++) {
        let i = n - 1u - j;
        f = fold_next(o, f, i);
        let e = f.e;
        let m = krs_mirror(o, i);
        if distorted && e > 0.0 {
            frame = frame * householder(m.xyz);
        }
        let rho = omega - 2.0 * dot(m.xyz, omega) * m.xyz;
        var w = 0.0;
        if e_threshold > 0.0 {
            w = clamp(e / e_threshold + 0.5, 0.0, 1.0);
        } else if e > 0.0 {
            w = 1.0;
        }
        omega = normalize_or(mix(omega, rho, w), select(omega, rho, e > 0.0));
        if f.best_k == i {
            best_omega = omega;
            best_frame = frame;
        }
    }
    let best_k = f.best_k;
    let best_p = f.best_p;
    if best_k == 0xffffffffu {
        return 0.0;
    }
    let normal_kernel = kernel_normal(krs_kernels[o.first_kernel + best_k], best_p);
    var diffuse = max(dot(normal_kernel, best_omega), 0.0);
    if distorted {
        let nf = best_frame * normal_kernel;
        let jt_n = length(vec3<f32>(dot(jx, nf), dot(jy, nf), dot(jz, nf)));
        if jt_n > 0.0 {
            diffuse = min(diffuse * light_len / jt_n, 1.0);
        } else {
            diffuse = 0.0;
        }
    }
    return diffuse;
}

// ---- texturing (§6.2, core::krs::shade) ----

fn hash2(x: i32, y: i32) -> f32 {
    var h = (bitcast<u32>(x) * 0x8da6b343u) ^ (bitcast<u32>(y) * 0xd8163841u);
    h ^= h >> 15u;
    h *= 0x2c1b3c6du;
    h ^= h >> 12u;
    h *= 0x297a2d39u;
    h ^= h >> 15u;
    return f32(h >> 8u) / 16777215.0;
}

fn value_noise2(p: vec2<f32>) -> f32 {
    let c = floor(p);
    let t = p - c;
    let s = t * t * (vec2<f32>(3.0) - 2.0 * t);
    let x = i32(c.x);
    let y = i32(c.y);
    let a = hash2(x, y) + (hash2(x + 1, y) - hash2(x, y)) * s.x;
    let b = hash2(x, y + 1) + (hash2(x + 1, y + 1) - hash2(x, y + 1)) * s.x;
    return a + (b - a) * s.y;
}

fn pattern_value(pattern: u32, uv: vec2<f32>) -> f32 {
    if pattern == KRS_PATTERN_CHECKER {
        let cell = floor(uv);
        if ((i32(cell.x) + i32(cell.y)) & 1) == 0 {
            return 1.0;
        }
        return 0.0;
    }
    let streak = value_noise2(vec2<f32>(uv.x * 0.25, uv.y * 3.0));
    let detail = value_noise2(uv * 2.0 + vec2<f32>(17.0));
    return clamp(0.75 * streak + 0.25 * detail, 0.0, 1.0);
}

fn modulate(base: vec3<f32>, value: f32, contrast: f32) -> vec3<f32> {
    return clamp(base * (1.0 + clamp(contrast, 0.0, 1.0) * (value - 0.5)), vec3<f32>(0.0), vec3<f32>(1.0));
}

// Textured albedo of a hit (`shade_colour`), clamped to [0, 1].
fn krs_albedo(o: KrsObject, s: KrsSurface, p_world: vec3<f32>) -> vec3<f32> {
    if s.kernel == 0xffffffffu {
        return vec3<f32>(0.6);
    }
    let k = krs_kernels[o.first_kernel + s.kernel];
    let base = k.colour.xyz;
    var c = base;
    if o.texture_mode == KRS_TEXTURE_TRIPLANAR {
        let p = object_from_world(o, p_world);
        let n = quat_rotate(o.inv_rotation, s.normal);
        var w = pow(abs(n), vec3<f32>(max(o.tex_sharpness, 1.0)));
        let sum = w.x + w.y + w.z;
        if sum > 0.0 && sum < 3.0e38 {
            w = w / sum;
        } else {
            w = vec3<f32>(1.0 / 3.0);
        }
        let q = p * o.tex_scale;
        let v = w.x * pattern_value(o.pattern, q.yz) + w.y * pattern_value(o.pattern, q.xz)
            + w.z * pattern_value(o.pattern, q.xy);
        c = modulate(base, v, o.tex_contrast);
    } else if o.texture_mode == KRS_TEXTURE_KERNEL_PARAM {
        let uv = kernel_param_coords(k, s.kernel_point);
        c = modulate(base, pattern_value(o.pattern, uv * o.tex_scale), o.tex_contrast);
    }
    return clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
}

// ---- rays ----

// Pixel-cone epsilon at ray parameter t.
fn krs_epsilon(t: f32) -> f32 {
    return max(krs.eps_scale * krs.pixel_cone * t, krs.min_epsilon);
}

// Ray-parameter interval in which geometry can lie (bounding balls inflated by Lipschitz ×
// epsilon at the ball's far side), clipped to [start, max]; x > y when empty. `eps_fixed` < 0:
// use the pixel-cone epsilon.
fn ray_interval(o: vec3<f32>, d: vec3<f32>, start: f32, max_t: f32, eps_fixed: f32) -> vec2<f32> {
    var lo = KRS_FAR;
    var hi = -KRS_FAR;
    for (var i = 0u; i < krs.object_count; i++) {
        let obj = krs_objects[i];
        if (obj.flags & KRS_OBJ_EMPTY) != 0u {
            continue;
        }
        if (obj.flags & KRS_OBJ_BOUNDED) == 0u {
            return vec2<f32>(start, max_t);
        }
        let oc = o - obj.bound.xyz;
        let far = length(oc) + obj.bound.w;
        var eps = eps_fixed;
        if eps < 0.0 {
            eps = krs_epsilon(far);
        }
        let r = obj.bound.w * (1.0 + 1e-6) + 1e-6 + 1.01 * obj.lipschitz * eps;
        let b = dot(oc, d);
        // r² minus the squared distance of the ball's centre from the ray's line (better
        // conditioned in f32 than b² − (|oc|² − r²)).
        let perp = oc - b * d;
        let disc = r * r - dot(perp, perp);
        if disc < 0.0 {
            continue;
        }
        let s = sqrt(disc);
        lo = min(lo, -b - s);
        hi = max(hi, -b + s);
    }
    return vec2<f32>(max(lo, start), min(hi, max_t));
}

// Light visibility through the KRS along a shadow ray (core's `shadow_counted`); y = steps.
fn krs_shadow(origin: vec3<f32>, dir: vec3<f32>, start: f32, max_t: f32, eps: f32) -> vec2<f32> {
    let iv = ray_interval(origin, dir, start, max_t, eps);
    if !(iv.x <= iv.y) {
        return vec2<f32>(1.0, 0.0);
    }
    var t = max(iv.x, start);
    var visibility = 1.0;
    let soft = (krs.flags & KRS_FRAME_SOFT) != 0u;
    var steps = 0u;
    for (var i = 0u; i < krs.max_steps; i++) {
        if t > iv.y {
            break;
        }
        steps++;
        let dist = scene_distance(origin + dir * t);
        if !(dist < KRS_FAR) {
            break;
        }
        if dist < eps {
            return vec2<f32>(0.0, f32(steps));
        }
        if soft {
            visibility = min(visibility, krs.soft_k * dist / max(t, 1e-12));
        }
        t += dist;
    }
    return vec2<f32>(clamp(visibility, 0.0, 1.0), f32(steps));
}


// Ambient accessibility from distance samples along the normal (core's `ambient_occlusion`):
// one sample per stratum of the reach at `(i + 1 - jitter) * spacing`, weights 2^(-4h/R)
// normalised by their integral over the reach R, so the mean over the jitter is the same for
// every sample count.
fn krs_ambient(p: vec3<f32>, n_in: vec3<f32>, jitter: f32) -> f32 {
    let n = normalize_or_zero(n_in);
    if all(n == vec3<f32>(0.0)) || krs.ao_samples == 0u || !(krs.ao_spacing > 0.0) {
        return 1.0;
    }
    let reach = f32(krs.ao_samples) * krs.ao_spacing;
    let weight_integral = reach * (15.0 / 16.0) / (4.0 * 0.6931472);
    let offset = 1.0 - clamp(jitter, 0.0, 1.0);
    var occlusion = 0.0;
    for (var i = 0u; i < krs.ao_samples; i++) {
        let h = max(f32(i) + offset, 1e-3) * krs.ao_spacing;
        let d = scene_distance(p + n * h);
        var shortfall = 0.0;
        if d < KRS_FAR {
            shortfall = clamp((h - d) / h, 0.0, 1.0);
        }
        occlusion += exp2(-4.0 * h / reach) * shortfall;
    }
    return clamp(1.0 - occlusion * krs.ao_spacing / weight_integral, 0.0, 1.0);
}

// ---- primary rays ----

// Sample grid (core's `SampleGrid`): hits are only reported on these ray parameters.
fn grid_index(t: f32) -> f32 {
    if t < krs.grid_t0 {
        return t / krs.grid_q0;
    }
    return krs.grid_u0 + log(t / krs.grid_t0) / krs.grid_log_step;
}

fn grid_param(u: f32) -> f32 {
    if u < krs.grid_u0 {
        return u * krs.grid_q0;
    }
    return krs.grid_t0 * exp((u - krs.grid_u0) * krs.grid_log_step);
}

// Certified-free radius of a sample at t with estimate dist.
fn free_radius(t: f32, dist: f32) -> f32 {
    return dist - 1.001 * krs_epsilon(t + max(dist, 0.0));
}

struct TraceOut {
    hit: bool,
    t: f32,
    steps: u32,
    fallbacks: u32,
    exhausted: bool,
}

// core's `trace`: canonical grid, certified skips, over-relaxed probes with the slope cap and
// fallbacks, pending stretches of rejected probes.
fn trace_ray(o: vec3<f32>, d: vec3<f32>, start: f32, max_t: f32) -> TraceOut {
    var out: TraceOut;
    let iv = ray_interval(o, d, start, max_t, -1.0);
    if !(iv.x <= iv.y) {
        return out;
    }
    var omega = clamp(krs.over_relaxation, 1.0, 1.99);
    let omega_max = omega;
    var k = ceil(grid_index(iv.x));
    var steps = 0u;
    var fallbacks = 0u;
    var exhausted = true;
    var last_grid_d = KRS_FAR;
    var has_pending = false;
    var pending = vec2<f32>(0.0);
    var has_prev = false;
    var prev = vec2<f32>(0.0);
    var slope = 0.0;
    loop {
        if steps >= krs.max_steps {
            break;
        }
        let t = grid_param(k);
        if t > iv.y {
            exhausted = false;
            break;
        }
        let dist = scene_distance(o + d * t);
        steps++;
        if !(dist < KRS_FAR) {
            exhausted = false;
            break;
        }
        if dist < krs_epsilon(t) {
            out.hit = true;
            out.t = t;
            exhausted = false;
            break;
        }
        if has_prev && t > prev.x {
            slope = (prev.y - dist) / (t - prev.x);
        }
        prev = vec2<f32>(t, dist);
        has_prev = true;
        if omega_max > 1.0 && dist > last_grid_d {
            omega = omega_max;
        }
        last_grid_d = dist;
        var reach = t + free_radius(t, dist);
        var cur_t = t;
        var cur_d = dist;
        loop {
            if !(omega > 1.0 && steps < krs.max_steps) {
                break;
            }
            let r = free_radius(cur_t, cur_d);
            let w = min(2.0 / (1.0 + max(slope, 0.0)), omega);
            if w <= 1.0 || (w - 1.0) * r < 0.5 * krs_epsilon(cur_t) {
                break;
            }
            let t2 = cur_t + w * r;
            if t2 > iv.y {
                break;
            }
            let d2 = scene_distance(o + d * t2);
            steps++;
            var r2 = -1.0;
            if d2 < KRS_FAR {
                r2 = free_radius(t2, d2);
                slope = (cur_d - d2) / (t2 - cur_t);
            }
            if !(r2 > 0.0 && t2 - r2 <= reach) {
                fallbacks++;
                omega = 1.0;
                if r2 > 0.0 {
                    pending = vec2<f32>(t2 - r2, t2 + r2);
                    has_pending = true;
                }
                break;
            }
            prev = vec2<f32>(t2, d2);
            reach = t2 + r2;
            cur_t = t2;
            cur_d = d2;
        }
        if has_pending && reach >= pending.x {
            reach = max(reach, pending.y);
            has_pending = false;
        }
        k = max(k + 1.0, floor(grid_index(max(reach, t))) + 1.0);
    }
    out.steps = steps;
    out.fallbacks = fallbacks;
    out.exhausted = exhausted;
    return out;
}

// A camera ray (core's `PixelRay`): view depth = depth0 + t·cos.
struct PixelRay {
    origin: vec3<f32>,
    dir: vec3<f32>,
    depth0: f32,
    cos: f32,
}

fn pixel_ray(sx: f32, sy: f32) -> PixelRay {
    let x = (sx - 0.5 * f32(view.size.x)) / view.fx;
    let y = (0.5 * f32(view.size.y) - sy) / view.fy;
    let rot = mat3x3<f32>(view.world_from_view[0].xyz, view.world_from_view[1].xyz, view.world_from_view[2].xyz);
    var r: PixelRay;
    if view.perspective != 0u {
        let dv = normalize_or(vec3<f32>(x, y, -1.0), vec3<f32>(0.0, 0.0, -1.0));
        r.origin = view.world_from_view[3].xyz;
        r.dir = normalize_or(rot * dv, vec3<f32>(0.0, 0.0, -1.0));
        r.depth0 = 0.0;
        r.cos = -dv.z;
    } else {
        r.origin = (view.world_from_view * vec4<f32>(x, y, -view.near, 1.0)).xyz;
        r.dir = normalize_or(rot * vec3<f32>(0.0, 0.0, -1.0), vec3<f32>(0.0, 0.0, -1.0));
        r.depth0 = view.near;
        r.cos = 1.0;
    }
    return r;
}

fn t_of_depth(r: PixelRay, depth: f32) -> f32 {
    return (depth - r.depth0) / max(r.cos, 1e-12);
}

// §4.1: a start parameter safe for every ray of the cone (core's `tile_start_distance`); y =
// evaluations spent.
fn tile_start(eye: vec3<f32>, axis: vec3<f32>, half_angle: f32, max_t: f32) -> vec2<f32> {
    if !(half_angle >= 0.0 && half_angle < 1.5) {
        return vec2<f32>(0.0);
    }
    let tan_h = tan(half_angle);
    var t = 0.0;
    var steps = 0u;
    for (var i = 0u; i < krs.max_steps; i++) {
        let dist = scene_distance(eye + axis * t);
        steps++;
        if !(dist < KRS_FAR) {
            return vec2<f32>(max_t, f32(steps));
        }
        let w = (t + dist) * tan_h;
        let radius = dist - 1.001 * krs_epsilon(t + max(dist, 0.0));
        if radius <= w {
            break;
        }
        t += sqrt(radius * radius - w * w);
        if t >= max_t {
            return vec2<f32>(max_t, f32(steps));
        }
    }
    return vec2<f32>(t * (1.0 - 1e-6), f32(steps));
}

var<workgroup> wg_tile_start: f32;
var<workgroup> wg_rays: atomic<u32>;
var<workgroup> wg_hits: atomic<u32>;
var<workgroup> wg_steps: atomic<u32>;
var<workgroup> wg_max: atomic<u32>;
var<workgroup> wg_exhausted: atomic<u32>;
var<workgroup> wg_fallbacks: atomic<u32>;
var<workgroup> wg_tile_steps: atomic<u32>;

// Adds to a 64-bit counter held as (lo, hi) words.
fn add64(i: u32, v: u32) {
    if v == 0u {
        return;
    }
    let old = atomicAdd(&counters[i], v);
    if old + v < old {
        atomicAdd(&counters[i + 1u], 1u);
    }
}

fn trace_pixel(px: vec2<u32>, tile_t: f32) {
    let pixel = px.y * view.size.x + px.x;
    let base = pixel * krs.stride;
    krs_light[base] = vec4<f32>(0.0, 0.0, 0.0, -1.0);
    for (var l = 0u; l < krs.light_count; l++) {
        krs_light[base + 1u + l] = vec4<f32>(0.0, 0.0, 1.0, 0.0);
    }
    let g = gbuffer[pixel];
    let ray = pixel_ray(f32(px.x) + 0.5, f32(px.y) + 0.5);
    var limit_depth = view.far;
    if g.w != EMPTY {
        limit_depth = min(view_depth_of(view, bitcast<f32>(g.w)), view.far);
    }
    let t_min = max(t_of_depth(ray, view.near), 0.0);
    let t_max = t_of_depth(ray, limit_depth);
    if !(t_max > t_min) {
        return;
    }
    // A hair beyond the held depth: a tie goes to the depth comparison below.
    let r = trace_ray(ray.origin, ray.dir, max(t_min, tile_t), t_max * (1.0 + 1e-6));
    atomicAdd(&wg_rays, 1u);
    atomicAdd(&wg_steps, r.steps);
    atomicMax(&wg_max, r.steps);
    atomicAdd(&wg_fallbacks, r.fallbacks);
    if r.exhausted {
        atomicAdd(&wg_exhausted, 1u);
    }
    if !r.hit {
        return;
    }
    let ndc = ndc_depth(view, ray.depth0 + r.t * ray.cos);
    let pos = ray.origin + ray.dir * r.t;
    if !(ndc >= 0.0 && ndc <= 1.0) {
        return;
    }
    // Voxels and meshes win ties (their ids are below the KRS ids on the CPU).
    if g.w != EMPTY && bitcast<u32>(ndc) >= g.w {
        return;
    }
    atomicAdd(&wg_hits, 1u);
    let oi = nearest_object(pos);
    var normal = -ray.dir;
    var albedo = vec3<f32>(0.6);
    let eps = krs_epsilon(r.t);
    krs_light[base] = vec4<f32>(pos, eps);
    if oi != 0xffffffffu {
        let o = krs_objects[oi];
        let s = surface_world(o, pos);
        normal = normalize_or(s.normal, -ray.dir);
        albedo = krs_albedo(o, s, pos);
        // §6.1: the blend zone is a fixed screen width.
        let threshold = max(krs.smoothing_px * krs.pixel_cone * r.t, 0.0);
        for (var l = 0u; l < krs.light_count; l++) {
            let to_light = krs_vectors[krs.light_base + l].xyz;
            krs_light[base + 1u + l] = vec4<f32>(smooth_diffuse(o, pos, to_light, threshold), 1.0, 1.0, 0.0);
        }
    }
    gbuffer[pixel] = vec4<u32>(
        pack2x16unorm(albedo.xy),
        pack2x16unorm(vec2<f32>(albedo.z, normal.z * 0.5 + 0.5)),
        pack2x16snorm(normal.xy),
        bitcast<u32>(ndc),
    );
}

@compute @workgroup_size(8, 8)
fn trace(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let w = view.size.x;
    let h = view.size.y;
    if li == 0u {
        wg_tile_start = 0.0;
        if (krs.flags & KRS_FRAME_TILES) != 0u && view.perspective != 0u {
            // The tile is this workgroup (8×8 = core's KRS_TILE): its four corner rays.
            let x0 = wid.x * 8u;
            let y0 = wid.y * 8u;
            let x1 = min(x0 + 8u, w);
            let y1 = min(y0 + 8u, h);
            let d0 = pixel_ray(f32(x0), f32(y0)).dir;
            let d1 = pixel_ray(f32(x1), f32(y0)).dir;
            let d2 = pixel_ray(f32(x0), f32(y1)).dir;
            let d3 = pixel_ray(f32(x1), f32(y1)).dir;
            let axis = normalize_or(d0 + d1 + d2 + d3, vec3<f32>(0.0, 0.0, -1.0));
            let min_cos = clamp(min(min(dot(d0, axis), dot(d1, axis)), min(dot(d2, axis), dot(d3, axis))), -1.0, 1.0);
            let half_angle = acos(min_cos) * (1.0 + 1e-4) + 1e-6;
            let centre = pixel_ray(0.5 * f32(x0 + x1), 0.5 * f32(y0 + y1));
            let s = tile_start(centre.origin, axis, half_angle, t_of_depth(centre, view.far) * 2.0);
            wg_tile_start = s.x;
            atomicAdd(&wg_tile_steps, u32(s.y));
        }
    }
    workgroupBarrier();
    let tile_t = wg_tile_start;
    if gid.x < w && gid.y < h {
        trace_pixel(gid.xy, tile_t);
    }
    workgroupBarrier();
    if li == 0u {
        atomicAdd(&counters[KRS_COUNTERS], atomicLoad(&wg_rays));
        atomicAdd(&counters[KRS_COUNTERS + 1u], atomicLoad(&wg_hits));
        add64(KRS_COUNTERS + 2u, atomicLoad(&wg_steps));
        atomicMax(&counters[KRS_COUNTERS + 4u], atomicLoad(&wg_max));
        atomicAdd(&counters[KRS_COUNTERS + 5u], atomicLoad(&wg_exhausted));
        atomicAdd(&counters[KRS_COUNTERS + 6u], atomicLoad(&wg_fallbacks));
        atomicAdd(&counters[KRS_COUNTERS + 7u], atomicLoad(&wg_tile_steps));
    }
}

// ---- lighting inputs ----

var<workgroup> wg_shadow_rays: atomic<u32>;
var<workgroup> wg_shadow_steps: atomic<u32>;
var<workgroup> wg_ao: atomic<u32>;

fn light_pixel(px: vec2<u32>) {
    let pixel = px.y * view.size.x + px.x;
    let g = gbuffer[pixel];
    if g.w == EMPTY {
        return;
    }
    let base = pixel * krs.stride;
    // The G-buffer normal, decoded exactly as shade.wgsl does.
    let bz = unpack2x16unorm(g.y);
    let n = normalize_or_zero(vec3<f32>(unpack2x16snorm(g.z), bz.y * 2.0 - 1.0));
    let depth = bitcast<f32>(g.w);
    let receiver = pixel_world_size(view, view_depth_of(view, depth)) * krs.receiver_px;
    let e0 = krs_light[base];
    var p = unproject(view, vec2<f32>(px) + 0.5, depth);
    var footprint = receiver;
    if e0.w >= 0.0 {
        // A KRS pixel keeps its exact hit point; its epsilon is how far it may be off.
        p = e0.xyz;
        footprint = max(e0.w, receiver);
    }
    let open = krs_ambient(p, n, ao_jitter(pixel));
    atomicAdd(&wg_ao, krs.ao_samples);
    krs_light[base] = vec4<f32>(p, select(open, open + 2.0, e0.w >= 0.0));
    for (var l = 0u; l < krs.light_count; l++) {
        let light = krs_vectors[krs.light_base + l];
        var e = krs_light[base + 1u + l];
        var ndotl = dot(n, light.xyz);
        if e.y > 0.0 {
            ndotl = e.x;
        }
        var vis = 1.0;
        if ndotl > 0.0 && (krs.flags & KRS_FRAME_SHADOWS) != 0u && light.w > 0.0 {
            // Leave the receiver: it may be a KRS surface whose estimate there is ~epsilon.
            let s = krs_shadow(p + n * (2.0 * footprint), light.xyz, 2.0 * footprint, 1e6, 0.5 * footprint);
            vis = s.x;
            atomicAdd(&wg_shadow_rays, 1u);
            atomicAdd(&wg_shadow_steps, u32(s.y));
        }
        e.z = vis;
        krs_light[base + 1u + l] = e;
    }
}

@compute @workgroup_size(8, 8)
fn light(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    if gid.x < view.size.x && gid.y < view.size.y {
        light_pixel(gid.xy);
    }
    workgroupBarrier();
    if li == 0u {
        atomicAdd(&counters[KRS_COUNTERS + 8u], atomicLoad(&wg_shadow_rays));
        add64(KRS_COUNTERS + 9u, atomicLoad(&wg_shadow_steps));
        add64(KRS_COUNTERS + 11u, atomicLoad(&wg_ao));
    }
}

// Skinned voxel nodes (paper §3.1, §3.3, §6, §8.1.3): where a node of a rigged model is drawn,
// computed per node when the traversal needs its screen position, exactly as the CPU
// reference's `core::skin::SkinDeform` (`place`, `subtree_bounds`) and `normal_to_world`.
// Shared by the traversal (asvo.wgsl) and the resolve pass, which bind the two buffers below
// at the same slots of group 0.
// Keep in sync with app/src/gpu/skin.rs (layout of `skin_data`) and core/src/skin/deform.rs.
// #import common/types.wgsl

// Static per-node skin data of every rigged object, uploaded with the pools (u32 words; the
// per-object offsets are in SkinParams):
//   node skins: 2 words per node (4 joint bytes, 4 weight bytes), inner and leaf pools;
//   corner skins: 16 words per node (8 corners × the same 2 words), when the rig has them;
//   subtree ranges: 2 words per inner node (start, count) into the subtree joint list;
//   subtree joints: 1 word per entry;
//   overrides: 1 byte per leaf, 4 per word (0: none; else the factor in 1/64 steps).
@group(0) @binding(6) var<storage, read> skin_data: array<u32>;
// `world_from_voxel` of every joint of every rigged object (`world_from_object ·
// skinning[j] · object_from_voxel`), rewritten when a pose changes.
@group(0) @binding(7) var<storage, read> joints: array<mat4x4<f32>>;

// Whether every component is finite (NaN fails every comparison).
fn finite3(v: vec3<f32>) -> bool {
    return all(abs(v) <= vec3<f32>(3.4028235e38));
}

// Where a node is drawn: a world-space parallelepiped (centre ± three half-axes).
struct Placed {
    center: vec3<f32>,
    half_axes: mat3x3<f32>,
}

// The blend weights of a node-skin word pair as the CPU's `Skin4::blend_weights` (the empty
// skin blends as full weight on its joint 0).
fn skin_weights(w: u32) -> vec4<f32> {
    if w == 0u {
        return vec4<f32>(1.0, 0.0, 0.0, 0.0);
    }
    return vec4<f32>(
        f32(w & 0xffu),
        f32((w >> 8u) & 0xffu),
        f32((w >> 16u) & 0xffu),
        f32(w >> 24u),
    ) * (1.0 / 255.0);
}

fn skin_joint(j: u32, k: u32) -> u32 {
    return (j >> (8u * k)) & 0xffu;
}

// Σ wᵢ · M[jᵢ] (`lbs::blend_matrix`): zero weights and joints past the table are skipped.
fn blend_matrix(s: SkinParams, j: u32, w: u32) -> mat4x4<f32> {
    let wf = skin_weights(w);
    var m = mat4x4<f32>(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
    for (var k = 0u; k < 4u; k++) {
        let jk = skin_joint(j, k);
        if wf[k] != 0.0 && jk < s.joint_count {
            m += joints[s.joint_base + jk] * wf[k];
        }
    }
    return m;
}

// Σ wᵢ · (M[jᵢ] · p) (`lbs::skin_point`).
fn skin_point(s: SkinParams, j: u32, w: u32, p: vec3<f32>) -> vec3<f32> {
    let wf = skin_weights(w);
    let p4 = vec4<f32>(p, 1.0);
    var acc = vec4<f32>(0.0);
    for (var k = 0u; k < 4u; k++) {
        let jk = skin_joint(j, k);
        if wf[k] != 0.0 && jk < s.joint_count {
            acc += (joints[s.joint_base + jk] * p4) * wf[k];
        }
    }
    return acc.xyz;
}

fn mat3_of(m: mat4x4<f32>) -> mat3x3<f32> {
    return mat3x3<f32>(m[0].xyz, m[1].xyz, m[2].xyz);
}

// Longest column (the largest scale a voxel axis gets).
fn column_scale(m: mat3x3<f32>) -> f32 {
    return max(length(m[0]), max(length(m[1]), length(m[2])));
}

// Half extents of the AABB of a parallelepiped with half-axes as columns.
fn abs_rows(a: mat3x3<f32>) -> vec3<f32> {
    return abs(a[0]) + abs(a[1]) + abs(a[2]);
}

// Sign pattern of corner k (x fastest).
fn corner_offset(k: u32) -> vec3<f32> {
    return select(vec3<f32>(-1.0), vec3<f32>(1.0), vec3<u32>(k & 1u, k & 2u, k & 4u) != vec3<u32>(0u));
}

// `W` of the paper clamped to 1..2 (`stretch::thesis_factor`).
fn thesis_factor(w: u32) -> f32 {
    let n = u32((w & 0xffu) != 0u) + u32((w & 0xff00u) != 0u) + u32((w & 0xff0000u) != 0u)
        + u32((w & 0xff000000u) != 0u);
    return f32(clamp(n, 1u, 2u));
}

// Skin-record word offsets of a node: its own pair and its corner block.
fn node_skin_word(s: SkinParams, leaf: bool, index: u32) -> u32 {
    return select(s.inner_skin, s.leaf_skin, leaf) + 2u * index;
}

// `stretch::containing_factor`; a negative result stands for "none" (collapsed frame).
fn containing_factor(skinned: array<vec3<f32>, 8>, half: f32, center: vec3<f32>, a: mat3x3<f32>) -> f32 {
    // glam's Mat3::determinant / inverse: cofactors over the determinant.
    let c0 = cross(a[1], a[2]);
    let c1 = cross(a[2], a[0]);
    let c2 = cross(a[0], a[1]);
    let det = dot(a[2], c2);
    let scale = column_scale(a);
    if !(abs(det) > 1e-6 * scale * scale * scale && half > 0.0) {
        return -1.0;
    }
    let inv = transpose(mat3x3<f32>(c0, c1, c2)) * (1.0 / det);
    var worst = 0.0;
    for (var k = 0u; k < 8u; k++) {
        let q = abs(inv * (skinned[k] - center));
        worst = max(worst, max(q.x, max(q.y, q.z)));
    }
    let f = worst / half;
    if !(abs(f) <= 3.4028235e38) {
        return -1.0;
    }
    return f;
}

// The splat box of node `index` (leaf pool when `leaf`) with minimum corner `origin` and edge
// `size` voxels (`SkinDeform::place`).
fn place_skinned(s: SkinParams, leaf: bool, index: u32, origin: vec3<u32>, size: f32) -> Placed {
    let rec = node_skin_word(s, leaf, index);
    let sj = skin_data[rec];
    let sw = skin_data[rec + 1u];
    let half = 0.5 * size;
    let c = vec3<f32>(origin) + vec3<f32>(half);
    let blended = blend_matrix(s, sj, sw);
    let center = (blended * vec4<f32>(c, 1.0)).xyz;
    let linear = mat3_of(blended);
    var out: Placed;
    out.center = center;
    var code = 0u;
    if leaf && (s.flags & SKIN_HAS_OVERRIDES) != 0u {
        code = (skin_data[s.overrides + index / 4u] >> (8u * (index % 4u))) & 0xffu;
    }
    var f = 1.0;
    if code != 0u {
        f = f32(code) / 64.0;
    } else if s.strategy == SKIN_OFF {
        f = 1.0;
    } else if s.strategy == SKIN_THESIS || (s.flags & SKIN_HAS_CORNERS) == 0u {
        f = clamp(thesis_factor(sw), s.min_factor, s.max_factor);
    } else {
        let cb = select(s.inner_corners, s.leaf_corners, leaf) + 16u * index;
        var skinned: array<vec3<f32>, 8>;
        var lo = vec3<f32>(3.0e38);
        var hi = vec3<f32>(-3.0e38);
        for (var k = 0u; k < 8u; k++) {
            let p = skin_point(s, skin_data[cb + 2u * k], skin_data[cb + 2u * k + 1u], c + corner_offset(k) * half);
            skinned[k] = p;
            lo = min(lo, p);
            hi = max(hi, p);
        }
        let he = (hi - lo) * (0.5 * s.multiplier);
        let mid = (lo + hi) * 0.5;
        let finite = all(abs(he) <= vec3<f32>(3.4028235e38)) && all(abs(mid) <= vec3<f32>(3.4028235e38));
        if s.strategy == SKIN_CORNERS && finite {
            // Not capped by max_factor: the pose bounds the box (`SkinDeform::place`).
            out.center = mid;
            out.half_axes = mat3x3<f32>(vec3<f32>(he.x, 0.0, 0.0), vec3<f32>(0.0, he.y, 0.0), vec3<f32>(0.0, 0.0, he.z));
            return out;
        }
        if s.strategy == SKIN_CORNERS {
            f = clamp(thesis_factor(sw), s.min_factor, s.max_factor);
            out.half_axes = linear * (f * half * s.multiplier);
            return out;
        }
        var a = containing_factor(skinned, half, center, linear);
        if a < 0.0 {
            a = thesis_factor(sw);
        }
        f = clamp(a, s.min_factor, s.max_factor);
    }
    out.half_axes = linear * (f * half * s.multiplier);
    return out;
}

// A world AABB holding inner node `index` and its whole subtree (`SkinDeform::subtree_bounds`),
// as centre and half extents; `ok` false when the node has no subtree joints or the box is not
// finite (then the splat box is used, as on the CPU).
struct CullBox {
    center: vec3<f32>,
    half_extent: vec3<f32>,
    ok: bool,
}

fn subtree_box(s: SkinParams, splat: Placed, index: u32, origin: vec3<u32>, size: f32) -> CullBox {
    var out: CullBox;
    out.ok = false;
    let r = s.subtree_ranges + 2u * index;
    let start = skin_data[r];
    let count = skin_data[r + 1u];
    if count == 0u {
        return out;
    }
    let half = 0.5 * size;
    let c = vec4<f32>(vec3<f32>(origin) + vec3<f32>(half), 1.0);
    let she = abs_rows(splat.half_axes);
    var lo = splat.center - she;
    var hi = splat.center + she;
    let reach = half * (1.0 + 0.5 * s.grow);
    for (var i = 0u; i < count; i++) {
        let j = skin_data[s.subtree_joints + start + i];
        if j >= s.joint_count {
            continue;
        }
        let m = joints[s.joint_base + j];
        let centre = (m * c).xyz;
        let he = abs_rows(mat3_of(m)) * reach;
        lo = min(lo, centre - he);
        hi = max(hi, centre + he);
    }
    if !(finite3(lo) && finite3(hi)) {
        return out;
    }
    out.center = (lo + hi) * 0.5;
    out.half_extent = (hi - lo) * 0.5;
    out.ok = true;
    return out;
}

// A skinned node's normal in world space (`SkinDeform::normal_to_world` →
// `lbs::transform_normal`): the cofactor matrix of the blended linear part, sign-corrected.
fn skinned_normal(s: SkinParams, leaf: bool, index: u32, n: vec3<f32>) -> vec3<f32> {
    let rec = node_skin_word(s, leaf, index);
    let a = mat3_of(blend_matrix(s, skin_data[rec], skin_data[rec + 1u]));
    let cof = mat3x3<f32>(cross(a[1], a[2]), cross(a[2], a[0]), cross(a[0], a[1]));
    let det = dot(a[0], cof[0]);
    let sign = select(1.0, -1.0, det < 0.0);
    let v = cof * n * sign;
    let l = length(v);
    if l > 0.0 && l < 3.0e38 {
        return v / l;
    }
    let u = a * n;
    let lu = length(u);
    if lu > 0.0 && lu < 3.0e38 {
        return u / lu;
    }
    return normalize_or_zero(n);
}

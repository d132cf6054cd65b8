// ASVO traversal (paper §4, Fig. 8): one octree level per dispatch. Each invocation takes one
// queued node, places it in view space with its object's transform, culls it against the
// frustum, then either queues its children for the next level (projected edge above the LOD
// threshold and it has children) or returns the splat: the pixel rectangle of its projected
// box at the NDC depth of its nearest point, or, when that rectangle exceeds
// view.cube_pixel_threshold, the node's exact box (`cube_pixel`). Mirrors core::render's CPU
// traversal.
// #import common/types.wgsl
// #import common/skin.wgsl

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read_write> counters: array<atomic<u32>>;
// Inner nodes of every object: x = first child (object-local), y = child mask.
@group(0) @binding(2) var<storage, read> inner_nodes: array<vec2<u32>>;
// Farthest depth bits per occlusion tile, refreshed between levels (hiz.wgsl).
@group(0) @binding(5) var<storage, read> occlusion_tiles: array<u32>;
@group(1) @binding(0) var<uniform> params: NodeParams;
// Queue entries: x = node index (object-local; inner pool, or leaf pool at the leaf level),
// yzw = the node's minimum corner in voxel coordinates.
@group(2) @binding(0) var<storage, read> queue_in: array<vec4<u32>>;
@group(2) @binding(1) var<storage, read_write> queue_out: array<vec4<u32>>;

const VISIT_NONE: u32 = 0u;
const VISIT_SPLAT: u32 = 1u;
const WORKGROUP: u32 = 64u;

// Per-workgroup counters (visited, split, splatted, frustum culled, occlusion culled, of the
// splatted those drawn as exact cubes), flushed once per group (STATS_PER_LEVEL: generated).
var<workgroup> wg_stats: array<atomic<u32>, STATS_PER_LEVEL>;
// Pixels the workgroup's splats cover, i.e. key atomics issued, flushed with the counters: the
// byte count of the splat bandwidth measurement (app/src/gpu/splat_bw.rs).
var<workgroup> wg_splat_pixels: atomic<u32>;
// Pixels the workgroup's exact cubes tested (one ray–box test each).
var<workgroup> wg_cube_pixels: atomic<u32>;

struct Visit {
    kind: u32,
    // Inclusive pixel rectangle x0, y0, x1, y1.
    rect: vec4<u32>,
    depth_bits: u32,
    // attribute << FACE_BITS; an exact cube's pixels add their face code.
    id: u32,
    // Nonzero: drawn as the node's exact box, view point p inside it when
    // cube_to_local * (p - cube_center) lies in [-1, 1]^3. CUBE_FACES: its pixels carry the
    // face they show (rigid objects); CUBE_DEPTH: the node's normal (a deformed object, whose
    // neighbouring boxes do not tile: the CPU's `CubeBox::faces`).
    cube: u32,
    cube_center: vec3<f32>,
    cube_to_local: mat3x3<f32>,
}

// How far past its faces a cube's slabs reach, in half edges (the CPU's `CUBE_SLAB`):
// neighbouring cubes are intersected in their own frames, and rounding must not crack them.
const CUBE_SLAB: f32 = 1.001;
const CUBE_FACES: u32 = 1u;
const CUBE_DEPTH: u32 = 2u;
// `cube_pixel`'s depth for a pixel whose ray misses the box.
const CUBE_MISS: u32 = 0xffffffffu;

// Inverse of a 3×3 matrix by cofactors (rows of the inverse are the cross products of its
// columns over the determinant).
fn inverse3(m: mat3x3<f32>) -> mat3x3<f32> {
    let r0 = cross(m[1], m[2]);
    let r1 = cross(m[2], m[0]);
    let r2 = cross(m[0], m[1]);
    let det = dot(m[0], r0);
    return transpose(mat3x3<f32>(r0, r1, r2)) * (1.0 / det);
}

fn finite_f32(x: f32) -> bool {
    // By the bits: WGSL lets a compiler assume floats are finite, so `x == x` may fold away.
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// Makes `out` an exact cube (`kind` CUBE_FACES or CUBE_DEPTH) of the box with view-space
// centre `c` and view-space half axes `half_axes` when its rectangle (`extent_px` wide or
// tall) exceeds the threshold and the box is not degenerate (the CPU's `Footprint::splat` and
// `cube_in_view`).
fn make_cube(
    out: ptr<function, Visit>,
    kind: u32,
    extent_px: f32,
    c: vec3<f32>,
    half_axes: mat3x3<f32>,
) {
    if !(extent_px > view.cube_pixel_threshold) {
        return;
    }
    let m = inverse3(half_axes);
    let ok = finite_f32(m[0].x) && finite_f32(m[0].y) && finite_f32(m[0].z)
        && finite_f32(m[1].x) && finite_f32(m[1].y) && finite_f32(m[1].z)
        && finite_f32(m[2].x) && finite_f32(m[2].y) && finite_f32(m[2].z);
    if ok {
        (*out).cube = kind;
        (*out).cube_center = c;
        (*out).cube_to_local = m;
    }
}

// Depth bits and face code where pixel (x, y)'s centre ray enters the visit's box (the CPU's
// `write_cube` and `enter_box`): the near plane, with face 0, where the box crosses it;
// x = CUBE_MISS where the ray misses. The ray is o + t·dir with dir.z = -1, so t is the view
// depth in both projections.
fn cube_pixel(v: Visit, x: u32, y: u32) -> vec2<u32> {
    let miss = vec2<u32>(CUBE_MISS, 0u);
    let w = f32(view.size.x);
    let h = f32(view.size.y);
    let vx = (f32(x) + 0.5 - 0.5 * w) / view.fx;
    let vy = (0.5 * h - (f32(y) + 0.5)) / view.fy;
    var o = vec3<f32>(0.0);
    var dir = vec3<f32>(vx, vy, -1.0);
    if view.perspective == 0u {
        o = vec3<f32>(vx, vy, 0.0);
        dir = vec3<f32>(0.0, 0.0, -1.0);
    }
    let ol = v.cube_to_local * (o - v.cube_center);
    let dl = v.cube_to_local * dir;
    // Slabs of the three axes at once; an axis the ray runs parallel to (a zero component)
    // either holds the whole ray or none of it.
    let slab = vec3<f32>(CUBE_SLAB);
    let parallel = dl == vec3<f32>(0.0);
    if any(parallel & (abs(ol) > slab)) {
        return miss;
    }
    let safe = select(dl, vec3<f32>(1.0), parallel);
    let ta = (-slab - ol) / safe;
    let tb = (slab - ol) / safe;
    let tn = select(min(ta, tb), vec3<f32>(-3.4028235e38), parallel);
    let tf = select(max(ta, tb), vec3<f32>(3.4028235e38), parallel);
    let t1 = min(tf.x, min(tf.y, tf.z));
    // The entry is the latest slab entry; ties keep the lower axis, as the CPU's scan does.
    var t0 = tn.x;
    var face = 1u + select(0u, 1u, dl.x > 0.0);
    if tn.y > t0 {
        t0 = tn.y;
        face = 3u + select(0u, 1u, dl.y > 0.0);
    }
    if tn.z > t0 {
        t0 = tn.z;
        face = 5u + select(0u, 1u, dl.z > 0.0);
    }
    if parallel.x && parallel.y && parallel.z {
        return miss;
    }
    if !(t0 <= t1) || face == 0u || t1 < view.near || t0 > view.far {
        return miss;
    }
    var depth = t0;
    if t0 < view.near || v.cube != CUBE_FACES {
        face = 0u;
    }
    if t0 < view.near {
        depth = view.near;
    }
    return vec2<u32>(bitcast<u32>(clamp(ndc_depth(view, depth), 0.0, 1.0)), face);
}

// Pixels whose centres lie in [s0, s1], or the one under the centre when none do (sub-pixel
// nodes never vanish), clamped to the image.
fn pixel_span(s0: f32, s1: f32, n: u32) -> vec2<u32> {
    let max_px = f32(n) - 1.0;
    var a = ceil(s0 - 0.5);
    var b = floor(s1 - 0.5);
    if b < a {
        a = floor(0.5 * (s0 + s1));
        b = a;
    }
    return vec2<u32>(u32(clamp(a, 0.0, max_px)), u32(clamp(b, 0.0, max_px)));
}

fn count_stat(k: u32) {
    if view.write_mode != MODE_ID {
        atomicAdd(&wg_stats[k], 1u);
    }
}

// Counts the pixels of a splat's rectangle (one key atomic each, at most, for an exact cube
// also one ray–box test; not in the id pass, which repeats the depth pass's splats).
fn count_splat_pixels(v: Visit) {
    if view.write_mode != MODE_ID {
        let rect = v.rect;
        let n = (rect.z - rect.x + 1u) * (rect.w - rect.y + 1u);
        atomicAdd(&wg_splat_pixels, n);
        if v.cube != 0u {
            atomicAdd(&wg_cube_pixels, n);
        }
    }
}

// Bit of a queue entry's node index marking a virtual node inside a tile (core's
// `svo::IN_TILE`): the rest of the index is then the tile's inner index.
const IN_TILE: u32 = 0x80000000u;
// The first-child word of a tile (core's `svo::TILE`), whose child mask is empty: an inner node
// standing for a full region of equal voxels, its attributes theirs.
const TILE_FIRST: u32 = 0xffffffffu;
// Where an inner node's mask word lists its interior children (app's `node_word`).
const INTERIOR_CHILDREN_SHIFT: u32 = 8u;

// The attribute id of a queued node: an inner node's (and a tile's virtual nodes', whose index
// is the tile's), or a leaf's.
fn node_attr_id(x: u32, has_children: bool) -> u32 {
    if has_children || (x & IN_TILE) != 0u {
        return (params.attr_inner_base + (x & ~IN_TILE)) << FACE_BITS;
    }
    return (params.attr_leaf_base + x) << FACE_BITS;
}

fn push_children(entry: vec4<u32>) {
    // A tile and its virtual nodes have all eight children, each a virtual node of the tile.
    var in_tile = (entry.x & IN_TILE) != 0u;
    var mask = 0xffu;
    var first = 0u;
    var interior_children = 0u;
    if !in_tile {
        let node = inner_nodes[params.inner_base + entry.x];
        in_tile = node.x == TILE_FIRST && (node.y & 0xffu) == 0u;
        if !in_tile {
            mask = node.y & 0xffu;
            first = node.x;
            interior_children = (node.y >> INTERIOR_CHILDREN_SHIFT) & 0xffu;
        }
    }
    // Interior children (every voxel below them enclosed) can never show: they are not
    // queued, as on the CPU; the node's word lists them. A tile's children are never interior
    // (an interior tile is not queued).
    var shown = mask;
    if !in_tile {
        shown = mask & ~(interior_children);
    }
    let n = countOneBits(shown);
    let base = atomicAdd(&counters[QUEUE_COUNTS + params.level + 1u], n);
    let half = params.node_size / 2u;
    var r = 0u;
    var w = 0u;
    for (var k = 0u; k < 8u; k++) {
        if (mask & (1u << k)) == 0u {
            continue;
        }
        if (shown & (1u << k)) != 0u {
            let slot = base + w;
            if slot < params.queue_capacity {
                let offset = vec3<u32>(k & 1u, (k >> 1u) & 1u, (k >> 2u) & 1u) * half;
                queue_out[slot] = vec4<u32>(select(first + r, entry.x | IN_TILE, in_tile), entry.yzw + offset);
            } else {
                atomicAdd(&counters[OVERFLOW_COUNTER], 1u);
            }
            w++;
        }
        r++;
    }
}

// Whether everything drawn so far under the pixel rectangle is nearer than `depth_bits` (paper
// §8.1.2, as the CPU's `DepthTarget::occluded`): then neither the node nor its children can
// show. Conservative: ties are kept, and rectangles over OCCLUSION_MAX_TILES tiles are kept.
fn occluded(xs: vec2<u32>, ys: vec2<u32>, depth_bits: u32) -> bool {
    let t0 = vec2<u32>(xs.x, ys.x) / OCCLUSION_TILE;
    let t1 = vec2<u32>(xs.y, ys.y) / OCCLUSION_TILE;
    if (t1.x - t0.x + 1u) * (t1.y - t0.y + 1u) > OCCLUSION_MAX_TILES {
        return false;
    }
    for (var ty = t0.y; ty <= t1.y; ty++) {
        for (var tx = t0.x; tx <= t1.x; tx++) {
            if occlusion_tiles[ty * view.tiles_x + tx] >= depth_bits {
                return false;
            }
        }
    }
    return true;
}

// Processes queue entry `i` of the current level.
fn visit(i: u32) -> Visit {
    var out: Visit;
    out.kind = VISIT_NONE;
    out.cube = 0u;
    let queued = min(atomicLoad(&counters[QUEUE_COUNTS + params.level]), params.queue_capacity);
    if i >= queued {
        return out;
    }
    count_stat(0u);
    let entry = queue_in[i];
    if params.skin.strategy != SKIN_RIGID {
        return visit_skinned(entry);
    }
    let size = f32(params.node_size);
    let center_voxel = vec3<f32>(entry.yzw) + vec3<f32>(0.5 * size);
    let c = params.linear_x.xyz * center_voxel.x + params.linear_y.xyz * center_voxel.y
        + params.linear_z.xyz * center_voxel.z + params.translation_edge.xyz;
    let he = params.half_extent_unit.xyz * size;
    let edge_world = params.translation_edge.w * size;
    let d = -c.z;
    let d_near = d - he.z;
    let d_far = d + he.z;
    if d_far <= view.near || d_near > view.far {
        count_stat(3u);
        return out;
    }
    let w = f32(view.size.x);
    let h = f32(view.size.y);
    let perspective = view.perspective != 0u;
    let crosses_near = perspective && d_near < view.near;
    let dn = max(d_near, view.near);
    var lo = c.xy - he.xy;
    var hi = c.xy + he.xy;
    var edge_px = edge_world * max(view.fx, view.fy);
    if perspective {
        // Extremes of x/d over the box lie at its nearest (clamped) or farthest depth.
        let l = min(lo / dn, lo / d_far);
        let u = max(hi / dn, hi / d_far);
        lo = l;
        hi = u;
        edge_px = edge_world * view.fy / dn;
    }
    let sx0 = 0.5 * w + view.fx * lo.x;
    let sx1 = 0.5 * w + view.fx * hi.x;
    let sy0 = 0.5 * h - view.fy * hi.y;
    let sy1 = 0.5 * h - view.fy * lo.y;
    if sx1 < 0.0 || sy1 < 0.0 || sx0 > w || sy0 > h {
        count_stat(3u);
        return out;
    }
    let has_children = params.level < params.leaf_level;
    let xs = pixel_span(sx0, sx1, view.size.x);
    let ys = pixel_span(sy0, sy1, view.size.y);
    let depth_bits = bitcast<u32>(clamp(ndc_depth(view, dn), 0.0, 1.0));
    if view.occlusion != 0u && !crosses_near && occluded(xs, ys, depth_bits) {
        count_stat(4u);
        return out;
    }
    if has_children && (crosses_near || edge_px > view.lod_pixel_threshold) {
        count_stat(1u);
        push_children(entry);
        return out;
    }
    count_stat(2u);
    out.kind = VISIT_SPLAT;
    out.rect = vec4<u32>(xs.x, ys.x, xs.y, ys.y);
    out.depth_bits = depth_bits;
    out.id = node_attr_id(entry.x, has_children);
    let linear = mat3x3<f32>(params.linear_x.xyz, params.linear_y.xyz, params.linear_z.xyz);
    make_cube(&out, CUBE_FACES, max(sx1 - sx0, sy1 - sy0), c, linear * (0.5 * size));
    if out.cube != 0u {
        count_stat(5u);
    }
    return out;
}

// Linear invocation index of a 2D indirect dispatch (x is capped at 65535 groups).
fn invocation_index(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return (wid.y * nwg.x + wid.x) * WORKGROUP + lid;
}

// Adds the workgroup's counters to the level's totals (call in uniform control flow).
fn flush_stats(lid: u32) {
    workgroupBarrier();
    if lid < STATS_PER_LEVEL {
        let s = atomicLoad(&wg_stats[lid]);
        if s > 0u {
            atomicAdd(&counters[params.stats_base + STATS_PER_LEVEL * params.level + lid], s);
        }
    }
    if lid == 0u {
        let view_index = select(1u, 0u, params.stats_base == STATS_START);
        let p = atomicLoad(&wg_splat_pixels);
        if p > 0u {
            atomicAdd(&counters[SPLAT_PIXEL_COUNTERS + view_index], p);
        }
        let cp = atomicLoad(&wg_cube_pixels);
        if cp > 0u {
            atomicAdd(&counters[CUBE_PIXEL_COUNTERS + view_index], cp);
        }
    }
}

// Screen footprint of a view-space box (the CPU's `asvo::footprint`).
struct Footprint {
    ok: bool,
    // Pixels whose centres it covers (the splat), inclusive.
    xs: vec2<u32>,
    ys: vec2<u32>,
    // Every pixel it touches (the occlusion test).
    oxs: vec2<u32>,
    oys: vec2<u32>,
    depth_bits: u32,
    d_near: f32,
    crosses_near: bool,
    // The rectangle's larger side in pixels (exact cubes above the threshold).
    extent_px: f32,
}

// Every pixel that [s0, s1] touches, clamped to the image.
fn overlapped_span(s0: f32, s1: f32, n: u32) -> vec2<u32> {
    let max_px = f32(n) - 1.0;
    return vec2<u32>(u32(clamp(floor(s0), 0.0, max_px)), u32(clamp(floor(s1), 0.0, max_px)));
}

fn footprint(c: vec3<f32>, he: vec3<f32>) -> Footprint {
    var fp: Footprint;
    fp.ok = false;
    let d = -c.z;
    let d_near = d - he.z;
    let d_far = d + he.z;
    if !(abs(d_near) <= 3.4028235e38 && abs(d_far) <= 3.4028235e38) {
        return fp;
    }
    if d_far <= view.near || d_near > view.far {
        return fp;
    }
    let w = f32(view.size.x);
    let h = f32(view.size.y);
    let perspective = view.perspective != 0u;
    fp.crosses_near = perspective && d_near < view.near;
    let dn = max(d_near, view.near);
    var lo = c.xy - he.xy;
    var hi = c.xy + he.xy;
    if perspective {
        let l = min(lo / dn, lo / d_far);
        let u = max(hi / dn, hi / d_far);
        lo = l;
        hi = u;
    }
    let sx0 = 0.5 * w + view.fx * lo.x;
    let sx1 = 0.5 * w + view.fx * hi.x;
    let sy0 = 0.5 * h - view.fy * hi.y;
    let sy1 = 0.5 * h - view.fy * lo.y;
    if sx1 < 0.0 || sy1 < 0.0 || sx0 > w || sy0 > h {
        return fp;
    }
    fp.ok = true;
    fp.xs = pixel_span(sx0, sx1, view.size.x);
    fp.ys = pixel_span(sy0, sy1, view.size.y);
    fp.oxs = overlapped_span(sx0, sx1, view.size.x);
    fp.oys = overlapped_span(sy0, sy1, view.size.y);
    fp.depth_bits = bitcast<u32>(clamp(ndc_depth(view, dn), 0.0, 1.0));
    fp.d_near = dn;
    fp.extent_px = max(sx1 - sx0, sy1 - sy0);
    return fp;
}

// A node of a rigged object: placed by linear-blend skinning with the object's stretch
// strategy (common/skin.wgsl), culled with the box that holds its whole subtree, split or
// splatted by its own box, as the CPU reference's `classify` without the rigid fast path.
fn visit_skinned(entry: vec4<u32>) -> Visit {
    var out: Visit;
    out.kind = VISIT_NONE;
    out.cube = 0u;
    let s = params.skin;
    let size = f32(params.node_size);
    let has_children = params.level < params.leaf_level;
    let placed = place_skinned(s, !has_children, entry.x, entry.yzw, size);
    let vfw = view.view_from_world;
    let view_rot = mat3x3<f32>(vfw[0].xyz, vfw[1].xyz, vfw[2].xyz);
    let c = (vfw * vec4<f32>(placed.center, 1.0)).xyz;
    let he = abs_rows(view_rot * placed.half_axes);
    let edge_world = 2.0 * column_scale(placed.half_axes);
    let splat = footprint(c, he);
    var cull = splat;
    if has_children {
        let cb = subtree_box(s, placed, entry.x, entry.yzw, size);
        if cb.ok {
            let cc = (vfw * vec4<f32>(cb.center, 1.0)).xyz;
            let ch = abs_rows(view_rot * mat3x3<f32>(
                vec3<f32>(cb.half_extent.x, 0.0, 0.0),
                vec3<f32>(0.0, cb.half_extent.y, 0.0),
                vec3<f32>(0.0, 0.0, cb.half_extent.z),
            ));
            let f = footprint(cc, ch);
            // As the CPU: a culling box off screen falls back to the splat's footprint.
            if f.ok {
                cull = f;
            }
        }
    }
    if !cull.ok {
        count_stat(3u);
        return out;
    }
    if view.occlusion != 0u && !cull.crosses_near && occluded(cull.oxs, cull.oys, cull.depth_bits) {
        count_stat(4u);
        return out;
    }
    if !splat.ok {
        // The node's own box is off screen but its subtree may not be.
        count_stat(1u);
        push_children(entry);
        return out;
    }
    var edge_px = edge_world * max(view.fx, view.fy);
    if view.perspective != 0u {
        edge_px = edge_world * view.fy / splat.d_near;
    }
    if has_children && (splat.crosses_near || edge_px > view.lod_pixel_threshold) {
        count_stat(1u);
        push_children(entry);
        return out;
    }
    count_stat(2u);
    out.kind = VISIT_SPLAT;
    out.rect = vec4<u32>(splat.xs.x, splat.ys.x, splat.xs.y, splat.ys.y);
    out.depth_bits = splat.depth_bits;
    out.id = node_attr_id(entry.x, has_children);
    make_cube(&out, CUBE_DEPTH, splat.extent_px, c, view_rot * placed.half_axes);
    if out.cube != 0u {
        count_stat(5u);
    }
    return out;
}

// ASVO traversal with the 64-bit splat: one atomicMin of (depth bits << 32 | id) per covered
// pixel (needs SHADER_INT64_ATOMIC_MIN_MAX). Positive floats order like their bit patterns,
// so the minimum key is the nearest splat, ties going to the smaller id. An exact cube writes
// only the pixels whose ray hits its box, each at its own depth with its face in the id.
// #import common/asvo.wgsl

@group(0) @binding(4) var<storage, read_write> keys: array<atomic<u64>>;

@compute @workgroup_size(64)
fn traverse(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let v = visit(invocation_index(wid, nwg, lid));
    if v.kind == VISIT_SPLAT {
        count_splat_pixels(v);
        let key = (u64(v.depth_bits) << 32u) | u64(v.id);
        for (var y = v.rect.y; y <= v.rect.w; y++) {
            for (var x = v.rect.x; x <= v.rect.z; x++) {
                if v.cube != 0u {
                    let hit = cube_pixel(v, x, y);
                    if hit.x != CUBE_MISS {
                        atomicMin(&keys[y * view.size.x + x], (u64(hit.x) << 32u) | u64(v.id | hit.y));
                    }
                } else {
                    atomicMin(&keys[y * view.size.x + x], key);
                }
            }
        }
    }
    flush_stats(lid);
}

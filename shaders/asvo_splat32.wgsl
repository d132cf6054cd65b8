// ASVO traversal with the two-pass 32-bit splat (adapters without 64-bit atomics, and shadow
// maps, which need depth only). The key buffer has the 64-bit layout as two u32 per pixel:
// [2p] = id, [2p + 1] = depth bits. MODE_DEPTH: atomicMin the depth. MODE_ID (a second full
// traversal after every depth write of the frame): atomicMin the id where the stored depth
// equals ours, which picks the same winner as the 64-bit minimum. An exact cube computes each
// pixel's depth and face the same way in both passes.
// #import common/asvo.wgsl

@group(0) @binding(4) var<storage, read_write> keys: array<atomic<u32>>;

@compute @workgroup_size(64)
fn traverse(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let v = visit(invocation_index(wid, nwg, lid));
    if v.kind == VISIT_SPLAT {
        count_splat_pixels(v);
        for (var y = v.rect.y; y <= v.rect.w; y++) {
            for (var x = v.rect.x; x <= v.rect.z; x++) {
                var depth_bits = v.depth_bits;
                var id = v.id;
                if v.cube != 0u {
                    let hit = cube_pixel(v, x, y);
                    if hit.x == CUBE_MISS {
                        continue;
                    }
                    depth_bits = hit.x;
                    id = v.id | hit.y;
                }
                let p = y * view.size.x + x;
                if view.write_mode == MODE_ID {
                    if atomicLoad(&keys[2u * p + 1u]) == depth_bits {
                        atomicMin(&keys[2u * p], id);
                    }
                } else {
                    atomicMin(&keys[2u * p + 1u], depth_bits);
                }
            }
        }
    }
    flush_stats(lid);
}

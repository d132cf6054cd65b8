// Queue bookkeeping for the ASVO traversal, so no level needs a CPU read-back:
// `seed` resets the per-level counts and queues the root; `prepare_indirect` turns the count
// queued for a level into that level's indirect dispatch size.
// #import common/asvo.wgsl

// Indirect dispatch arguments, 3 per level. In its own group so the traversal dispatches,
// which read it as INDIRECT, do not also bind it as storage.
@group(3) @binding(0) var<storage, read_write> indirect: array<u32>;

@compute @workgroup_size(32)
fn seed(@builtin(local_invocation_index) lid: u32) {
    atomicStore(&counters[QUEUE_COUNTS + lid], select(0u, 1u, lid == 0u));
    if lid == 0u {
        // The root: inner node 0 at the origin (dispatched with the pair whose output is the
        // level-0 input queue).
        queue_out[0] = vec4<u32>(0u);
    }
}

@compute @workgroup_size(1)
fn prepare_indirect() {
    let n = min(atomicLoad(&counters[QUEUE_COUNTS + params.level]), params.queue_capacity);
    let groups = (n + WORKGROUP - 1u) / WORKGROUP;
    let gx = min(groups, 65535u);
    let gy = select(0u, (groups + gx - 1u) / max(gx, 1u), groups > 0u);
    indirect[3u * params.level] = gx;
    indirect[3u * params.level + 1u] = gy;
    indirect[3u * params.level + 2u] = 1u;
}

// Mesh pass, 64-bit path: one atomicMin of (depth << 32 | MESH_ID_FLAG | triangle).
// #import common/mesh.wgsl

@group(0) @binding(2) var<storage, read_write> keys: array<atomic<u64>>;

@fragment
fn fs_main(in: MeshVarying) {
    let key = (u64(fragment_depth_bits(in.position)) << 32u) | u64(MESH_ID_FLAG | in.tri);
    atomicMin(&keys[fragment_pixel(in.position)], key);
}

// Mesh pass, two-pass 32-bit path (and shadow maps): see asvo_splat32.wgsl for the layout.
// #import common/mesh.wgsl

@group(0) @binding(2) var<storage, read_write> keys: array<atomic<u32>>;

@fragment
fn fs_main(in: MeshVarying) {
    let p = fragment_pixel(in.position);
    let depth_bits = fragment_depth_bits(in.position);
    if view.write_mode == MODE_ID {
        if atomicLoad(&keys[2u * p + 1u]) == depth_bits {
            atomicMin(&keys[2u * p], MESH_ID_FLAG | in.tri);
        }
    } else {
        atomicMin(&keys[2u * p + 1u], depth_bits);
    }
}

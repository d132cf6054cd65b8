// Hierarchical depth for occlusion culling (paper §8.1.2): the farthest depth drawn in each
// OCCLUSION_TILE × OCCLUSION_TILE tile of the key buffer (an empty pixel counts as infinitely
// far). Run after the mesh pass and after every traversal level of the view, so later levels
// skip nodes hidden behind what earlier levels splatted.
// #import common/types.wgsl

@group(0) @binding(0) var<uniform> view: View;
// The key buffer as u32 pairs: [2p + 1] is the depth word in both splat layouts.
@group(0) @binding(1) var<storage, read> keys: array<u32>;
@group(0) @binding(2) var<storage, read_write> tiles: array<u32>;

@compute @workgroup_size(8, 8)
fn build_tiles(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tiles_y = (view.size.y + OCCLUSION_TILE - 1u) / OCCLUSION_TILE;
    if gid.x >= view.tiles_x || gid.y >= tiles_y {
        return;
    }
    let x0 = gid.x * OCCLUSION_TILE;
    let y0 = gid.y * OCCLUSION_TILE;
    let x1 = min(x0 + OCCLUSION_TILE, view.size.x);
    let y1 = min(y0 + OCCLUSION_TILE, view.size.y);
    var far = 0u;
    for (var y = y0; y < y1; y++) {
        for (var x = x0; x < x1; x++) {
            far = max(far, keys[2u * (y * view.size.x + x) + 1u]);
        }
    }
    tiles[gid.y * view.tiles_x + gid.x] = far;
}

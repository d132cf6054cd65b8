//! What tiles (issue 43: uniform interiors stored once) would leave of a solid import: the
//! Spot mesh voxelized solid and as a surface at one depth, and the solid octree's nodes
//! counted as a tiled octree would keep them. A node becomes an *interior tile* when every
//! voxel in its box is solid and no voxel of the box is exposed (each face's neighbouring slab
//! outside the box is solid too); its subtree is then one node. The estimate prices kept
//! inner nodes and tiles at the solid octree's bytes per inner node and kept leaves at its
//! bytes per leaf, against the surface import's measured bytes.
//!
//! `cargo run --release -p thicket-core --example tile_estimate -- [DEPTH]` (default 9; reads
//! ../shared/assets/static/spot/spot_triangulated.obj).

use glam::UVec3;
use thicket_core::svo::{NodeRef, Svo};
use thicket_core::voxelize::{Mode, Resolution, VoxelizeSettings, voxelize};

/// Whether every voxel of the box `lo .. lo + size` is solid, and the subtree counts of a
/// full node.
fn full(svo: &Svo, node: &NodeRef, memo: &mut std::collections::HashMap<(u8, u32), bool>) -> bool {
    if svo.is_leaf(node) {
        return true;
    }
    if let Some(&f) = memo.get(&(node.level, node.index)) {
        return f;
    }
    let f = svo.child_mask(node) == 0xff
        && (0..8).all(|k| svo.child(node, k).is_some_and(|c| full(svo, &c, memo)));
    memo.insert((node.level, node.index), f);
    f
}

/// Whether the slab of voxels just outside each face of the box is solid (none of the box's
/// voxels is exposed). A face on the octree's edge counts as exposed.
fn enclosed(svo: &Svo, lo: UVec3, size: u32) -> bool {
    let ext = svo.extent();
    for axis in 0..3 {
        for side in [false, true] {
            let coord = if side {
                lo[axis] + size
            } else if lo[axis] == 0 {
                return false;
            } else {
                lo[axis] - 1
            };
            if coord >= ext {
                return false;
            }
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for a in 0..size {
                for b in 0..size {
                    let mut p = lo;
                    p[axis] = coord;
                    p[u] += a;
                    p[v] += b;
                    if svo.get(p).is_none() {
                        return false;
                    }
                }
            }
        }
    }
    true
}

#[derive(Default, Debug)]
struct Kept {
    inner: u64,
    tiles: u64,
    tile_voxels: u64,
    leaves: u64,
}

fn walk(
    svo: &Svo,
    node: &NodeRef,
    memo: &mut std::collections::HashMap<(u8, u32), bool>,
    kept: &mut Kept,
) {
    if svo.is_leaf(node) {
        kept.leaves += 1;
        return;
    }
    let size = svo.node_size(node.level);
    if full(svo, node, memo) && enclosed(svo, node.origin, size) {
        kept.tiles += 1;
        kept.tile_voxels += u64::from(size).pow(3);
        return;
    }
    kept.inner += 1;
    for k in 0..8 {
        if let Some(c) = svo.child(node, k) {
            walk(svo, &c, memo, kept);
        }
    }
}

fn main() {
    let depth: u8 = std::env::args()
        .nth(1)
        .map_or(9, |s| s.parse().expect("an octree depth"));
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/assets/static/spot/spot_triangulated.obj");
    let spot = match thicket_core::io::import_obj(&path) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("{}: {e}", path.display());
            std::process::exit(1);
        }
    };
    let vox = |mode| {
        let settings = VoxelizeSettings {
            resolution: Resolution::Depth(depth),
            mode,
            ..VoxelizeSettings::default()
        };
        match voxelize(&spot, &settings, &|_| true) {
            Ok(v) => v.svo,
            Err(e) => {
                eprintln!("Spot at depth {depth}, {mode:?}: {e}");
                std::process::exit(1);
            }
        }
    };
    let surface = vox(Mode::Surface);
    let solid = vox(Mode::Solid);
    let (s_mem, d_mem) = (surface.memory_stats(), solid.memory_stats());
    let mut kept = Kept::default();
    let mut memo = std::collections::HashMap::new();
    walk(&solid, &solid.root(), &mut memo, &mut kept);
    let per_inner = d_mem.inner_bytes as f64 / d_mem.inner_nodes.max(1) as f64;
    let per_leaf = d_mem.leaf_bytes as f64 / (d_mem.leaves - d_mem.tile_voxels).max(1) as f64;
    let tiled = (kept.inner + kept.tiles) as f64 * per_inner + kept.leaves as f64 * per_leaf;
    let mib = |b: f64| b / (1024.0 * 1024.0);
    println!(
        "Spot at depth {depth}: surface {} voxels, {:.1} MiB; solid {} voxels, {:.1} MiB",
        s_mem.leaves,
        mib(s_mem.total_bytes as f64),
        d_mem.leaves,
        mib(d_mem.total_bytes as f64)
    );
    println!(
        "tiled solid: {} inner nodes, {} interior tiles standing for {} voxels, {} leaves kept; \
         about {:.1} MiB = {:.2}x the surface import",
        kept.inner,
        kept.tiles,
        kept.tile_voxels,
        kept.leaves,
        mib(tiled),
        tiled / s_mem.total_bytes as f64
    );
    println!(
        "the solid import as built (uniform tiles only): {} tiles standing for {} voxels, {:.1} \
         MiB = {:.2}x the surface import",
        d_mem.tiles,
        d_mem.tile_voxels,
        mib(d_mem.total_bytes as f64),
        d_mem.total_bytes as f64 / s_mem.total_bytes as f64
    );
}

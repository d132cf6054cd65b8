//! The CPU renderer draws a tiled octree exactly as the leaf-only octree holding the same
//! voxels: the same image, G-buffer depths and traversal counts, on the samples and on a solid.

use glam::{UVec3, Vec3};

use super::*;
use crate::quality::QualityPreset;
use crate::scene::{ObjectKind, VoxelModel};
use crate::svo::{Svo, Voxel};

fn sample(name: &str) -> Document {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../projects")
        .join(format!("{name}.thicket.json"));
    crate::io::project::load(&path).expect("a sample project")
}

/// `doc` with every rigid voxel model stored leaf-only, the same stored with tiles, and how
/// many tiles those hold.
fn both(doc: &Document) -> (Document, Document, u64) {
    let (mut leaf_only, mut tiled) = (doc.clone(), doc.clone());
    let mut tiles = 0;
    for (a, b) in leaf_only.objects.iter_mut().zip(&mut tiled.objects) {
        if let (ObjectKind::Voxels(a), ObjectKind::Voxels(b)) = (&mut a.kind, &mut b.kind)
            && a.rig.is_none()
        {
            a.svo = std::mem::take(&mut a.svo).without_tiles();
            b.svo = std::mem::take(&mut b.svo).with_tiles();
            tiles += b.svo.tile_count();
        }
    }
    (leaf_only, tiled, tiles)
}

/// A document holding one solid ball: one colour inside, a shell of many.
fn solid_ball() -> Document {
    let mut doc = Document::default();
    let (depth, r) = (6u8, 27.0f32);
    let e = 1u32 << depth;
    let c = e as f32 / 2.0;
    let mut voxels = Vec::new();
    for z in 0..e {
        for y in 0..e {
            for x in 0..e {
                let p = Vec3::new(x as f32, y as f32, z as f32) + 0.5 - c;
                let d = p.length();
                if d <= r {
                    let v = if d > r - 1.5 {
                        Voxel::new([(x * 4) as u8, (y * 4) as u8, 90, 255], p)
                    } else {
                        Voxel::new([200, 60, 20, 255], Vec3::Z)
                    };
                    voxels.push((UVec3::new(x, y, z), v));
                }
            }
        }
    }
    let svo = Svo::from_voxels(depth, false, voxels).unwrap();
    doc.add(
        "Ball",
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: 0.05,
            ..VoxelModel::default()
        }),
    );
    doc.camera.frame(Vec3::splat(0.0), Vec3::splat(3.2));
    doc
}

#[test]
fn a_tiled_octree_renders_as_its_leaf_only_octree() {
    let mut docs: Vec<(String, Document)> = ["house", "mixed", "terrain", "tree"]
        .iter()
        .map(|n| (n.to_string(), sample(n)))
        .collect();
    docs.push(("solid ball".into(), solid_ball()));
    for (name, doc) in docs {
        let (doc, tiled_doc, tiles) = both(&doc);
        // Surface-only samples (terrain) may have none; the house's walls and the ball do.
        if name == "house" || name == "solid ball" {
            assert!(tiles > 50, "{name}: {tiles} tiles");
        }
        for quality in [
            Quality::preset(QualityPreset::Draft),
            Quality::preset(QualityPreset::Balanced),
        ] {
            let view = View {
                width: 160,
                height: 120,
                camera: None,
                quality,
            };
            let (a, fa, sa) = render_document(&doc, &view).unwrap();
            let (b, fb, sb) = render_document(&tiled_doc, &view).unwrap();
            assert!(a == b, "{name}: the images differ");
            assert_eq!(fa.depth, fb.depth, "{name}: depths differ");
            assert_eq!(
                (sa.nodes_visited(), sa.splats()),
                (sb.nodes_visited(), sb.splats()),
                "{name}: traversal differs"
            );
        }
    }
}

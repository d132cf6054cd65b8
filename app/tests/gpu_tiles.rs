//! The GPU renderer draws a tiled octree (core's `svo` tiles) as the leaf-only octree holding
//! the same voxels, on lavapipe in CI: a tile's virtual nodes are queued with the tile's index
//! and read its attributes. Never skipped: no adapter is a failure.

use glam::{UVec3, Vec3};
use thicket::gpu::{GpuContext, RenderTarget, Renderer, read_rgba8};
use thicket_core::quality::{Quality, QualityPreset};
use thicket_core::scene::{Document, ObjectKind, VoxelModel};
use thicket_core::svo::{Svo, Voxel};

fn context() -> GpuContext {
    GpuContext::new_headless(wgpu::PowerPreference::HighPerformance)
        .expect("a GPU adapter (install mesa-vulkan-drivers for lavapipe)")
}

fn sample(name: &str) -> Document {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../projects")
        .join(format!("{name}.thicket.json"));
    thicket_core::io::project::load(&path).expect("a sample project")
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

/// A solid ball: one colour inside, a shell of many.
fn solid_ball() -> Document {
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
    let mut doc = Document::default();
    doc.add(
        "Ball",
        ObjectKind::Voxels(VoxelModel {
            svo: Svo::from_voxels(depth, false, voxels).expect("in range"),
            voxel_size: 0.05,
            ..VoxelModel::default()
        }),
    );
    doc.camera.frame(Vec3::ZERO, Vec3::splat(3.2));
    doc
}

fn draw(ctx: &GpuContext, r: &mut Renderer, doc: &Document, q: &Quality) -> (Vec<u8>, u64) {
    let target = RenderTarget::new(&ctx.device, 160, 120).expect("target");
    let stats = r
        .render(
            &ctx.device,
            &ctx.queue,
            doc,
            &target.view(&doc.camera, q),
            &target,
        )
        .expect("frame renders");
    let rgba = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    assert!(ctx.errors.take().is_none(), "uncaptured GPU error");
    let visited = stats.levels.iter().map(|l| l.visited).sum();
    (rgba, visited)
}

#[test]
fn a_tiled_octree_renders_on_the_gpu_as_its_leaf_only_octree() {
    let ctx = context();
    let mut docs: Vec<(String, Document)> = ["house", "mixed"]
        .iter()
        .map(|n| (n.to_string(), sample(n)))
        .collect();
    docs.push(("solid ball".into(), solid_ball()));
    for (name, doc) in docs {
        let (doc, tiled_doc, tiles) = both(&doc);
        assert!(tiles > 0, "{name}: no tiles");
        for preset in [QualityPreset::Draft, QualityPreset::Balanced] {
            let q = Quality::preset(preset);
            let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
            let (a, na) = draw(&ctx, &mut r, &doc, &q);
            let (b, nb) = draw(&ctx, &mut r, &tiled_doc, &q);
            let differ = a.chunks(4).zip(b.chunks(4)).filter(|(p, q)| p != q).count();
            eprintln!("{name} {preset:?}: {differ} pixels differ, nodes {na} / {nb}");
            assert_eq!(differ, 0, "{name} {preset:?}");
            assert_eq!(na, nb, "{name} {preset:?}: nodes visited");
        }
    }
}

//! The GPU renderer draws a tiled octree (core's `svo` tiles) as the leaf-only octree holding
//! the same voxels, on lavapipe in CI: a tile's virtual nodes are queued with the tile's index
//! and read its attributes; a skinned model's interior tiles are never queued, and its skin
//! pass reads their slots. Never skipped: no adapter is a failure.

use glam::{UVec3, Vec3};
use thicket::gpu::{GpuContext, RenderTarget, Renderer, read_rgba8};

mod common;
use common::gpu::{context, gpu_frame, project};
use thicket_core::quality::{Quality, QualityPreset};
use thicket_core::render::scenes;
use thicket_core::scene::{Document, ObjectKind};
use thicket_core::svo::{Svo, Voxel};

fn draw(ctx: &GpuContext, r: &mut Renderer, doc: &Document, q: &Quality) -> (Vec<u8>, u64) {
    let (img, _, stats) = gpu_frame(ctx, r, doc, (160, 120), q);
    (img.pixels, stats.levels.iter().map(|l| l.visited).sum())
}

#[test]
fn a_tiled_octree_renders_on_the_gpu_as_its_leaf_only_octree() {
    let ctx = context();
    let mut docs: Vec<(String, Document)> = ["house", "mixed"]
        .iter()
        .map(|n| (n.to_string(), project(n)))
        .collect();
    docs.push(("solid ball".into(), scenes::solid_ball()));
    docs.push((
        "interior ball".into(),
        scenes::ball(scenes::BallInside::Interior),
    ));
    // Skinned and posed: interior tiles carrying their joint's weights (the skin pass reads
    // their slots' subtree joints and corner weights, and never queues them).
    docs.push(("rigid solid figure".into(), scenes::rigid_solid_figure()));
    for (name, doc) in docs {
        let (doc, tiled_doc, tiles) = scenes::without_and_with_tiles(&doc);
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

fn svo_mut(d: &mut Document) -> &mut Svo {
    match &mut d.objects[0].kind {
        ObjectKind::Voxels(v) => &mut v.svo,
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => unreachable!("the first object is voxels"),
    }
}

#[test]
fn edits_that_split_and_join_tiles_upload_incrementally_as_a_full_upload_would() {
    let ctx = context();
    // The coloured ball and one whose inside is interior (a carve reveals voxels, and the
    // interior marks of the nodes it opens are uploaded with them).
    for ball in [
        scenes::solid_ball(),
        scenes::ball(scenes::BallInside::Interior),
    ] {
        edits_upload_incrementally(&ctx, &ball);
    }
    assert!(ctx.errors.take().is_none(), "uncaptured GPU error");
}

fn edits_upload_incrementally(ctx: &GpuContext, ball: &Document) {
    let q = Quality::preset(QualityPreset::Balanced);
    let (mut leaf_doc, mut doc, tiles) = scenes::without_and_with_tiles(ball);
    assert!(tiles > 20, "{tiles} tiles");
    let id = doc.objects[0].id;
    let target = RenderTarget::new(&ctx.device, 160, 120).expect("target");
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let view = target.view(&doc.camera, &q);
    r.render(&ctx.device, &ctx.queue, &doc, &view, &target)
        .expect("frame");
    let mut before = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    // 1. Carve a sphere out of the front (splits the tiles it reaches); 2. fill a box with one
    // value (new tiles, blocks joined into them); 3. paint by position inside it (splits them).
    let centre = UVec3::new(32, 40, 52);
    let carve =
        move |c: UVec3, v: Voxel| (c.as_vec3().distance(centre.as_vec3()) > 14.0).then_some(v);
    let fill = |_: UVec3, _: Option<Voxel>| Some(Voxel::new([20, 220, 240, 255], Vec3::Y));
    let paint = |c: UVec3, v: Voxel| {
        Some(Voxel {
            color: [(c.x * 8) as u8, 30, 30, 255],
            ..v
        })
    };
    for step in 0..3 {
        let mut changed = None;
        for d in [&mut doc, &mut leaf_doc] {
            let svo = svo_mut(d);
            let e = match step {
                0 => svo.edit_existing(UVec3::splat(10), UVec3::splat(63), carve),
                1 => svo.edit_region(UVec3::new(8, 8, 40), UVec3::new(39, 23, 55), fill),
                _ => svo.edit_existing(UVec3::new(8, 8, 40), UVec3::new(39, 23, 55), paint),
            }
            .expect("edit");
            changed = e.changed;
        }
        let (lo, hi) = changed.expect("voxels changed");
        let up = r
            .update_voxel_region(&ctx.device, &ctx.queue, &doc, id, lo, hi)
            .expect("update");
        assert!(!up.full, "step {step}: {up:?}");
        let stats = r
            .render_uploaded(&ctx.device, &ctx.queue, &doc, &view, &target)
            .expect("frame");
        assert!(!stats.upload.full, "step {step}");
        let inc = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
        let mut fresh = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
        let (full, _) = draw(ctx, &mut fresh, &doc, &q);
        let (leaf, _) = draw(ctx, &mut fresh, &leaf_doc, &q);
        assert!(
            inc == full,
            "step {step}: incremental differs from a full upload"
        );
        assert!(full == leaf, "step {step}: tiled differs from leaf-only");
        assert!(
            full != before,
            "step {step}: the edit shows (else this proves nothing)"
        );
        before = full;
    }
}

#[test]
fn interior_nodes_are_not_queued_on_the_gpu_and_a_solid_draws_as_its_shell() {
    let ctx = context();
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    for preset in [QualityPreset::Draft, QualityPreset::Balanced] {
        let q = Quality::preset(preset);
        let (solid, n_solid) = draw(
            &ctx,
            &mut r,
            &scenes::ball(scenes::BallInside::Interior),
            &q,
        );
        let (shell, n_shell) = draw(&ctx, &mut r, &scenes::ball(scenes::BallInside::Hollow), &q);
        let (_, n_coloured) = draw(&ctx, &mut r, &scenes::solid_ball(), &q);
        let differ = solid
            .chunks(4)
            .zip(shell.chunks(4))
            .filter(|(p, q)| p != q)
            .count();
        eprintln!(
            "{preset:?}: {differ} pixels differ; nodes {n_solid} (shell {n_shell}, coloured \
             {n_coloured})"
        );
        assert_eq!(
            differ, 0,
            "{preset:?}: the solid's pixels differ from its shell's"
        );
        // Interior children, leaves included, are never queued (the node's word lists them):
        // the solid visits exactly its shell's nodes (lavapipe: draft 6,592, balanced 11,113,
        // against the coloured ball's 41,920 and 95,945).
        assert_eq!(n_solid, n_shell, "{preset:?}: nodes visited");
        assert!(
            n_solid * 2 <= n_coloured,
            "{preset:?}: {n_solid} against {n_coloured}"
        );
    }
    assert!(ctx.errors.take().is_none(), "uncaptured GPU error");
}

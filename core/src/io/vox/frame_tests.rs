//! Animated `.vox`: frames become one object with a frame sequence, shown one at a time, and
//! export writes them back as MagicaVoxel 0.99.7 writes an animation.

use std::path::Path;

use super::import::world_cells;
use super::instance_tests::{chunk_ids, count, group, model_chunks, shape, transform, wrap_main};
use super::*;
use crate::render::{View, render_document};
use crate::scene::{DEFAULT_FRAME_SECS, Document, Object, ObjectKind, VoxelModel};

fn import(bytes: &[u8]) -> VoxScene {
    import_vox_bytes(bytes, Path::new("anim.vox"), &VoxImportOptions::default()).unwrap()
}

fn model(o: &Object) -> &VoxelModel {
    match &o.kind {
        ObjectKind::Voxels(v) => v,
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => panic!("not voxels"),
    }
}

/// Frame `i` of `o` as a still object (its voxels and origin, the object's transform).
fn still_frame(o: &Object, i: usize) -> Object {
    let v = model(o);
    let (svo, origin) = v.frame(i).unwrap();
    Object {
        kind: ObjectKind::Voxels(VoxelModel {
            svo: svo.clone(),
            origin,
            frames: None,
            ..v.clone()
        }),
        ..o.clone()
    }
}

/// World cells with colours of frame `i`, sorted.
fn frame_cells(o: &Object, i: usize) -> Vec<([i64; 3], [u8; 4])> {
    let mut out: Vec<([i64; 3], [u8; 4])> = world_cells(&still_frame(o, i))
        .into_iter()
        .map(|(c, v)| (c, v.color))
        .collect();
    out.sort_unstable();
    out
}

fn per_frame_counts(o: &Object) -> Vec<u64> {
    let v = model(o);
    (0..v.frame_count())
        .map(|i| v.frame(i).unwrap().0.leaf_count())
        .collect()
}

/// Three models of 2, 3 and 4 voxels in different sizes and colours, no scene graph (how
/// MagicaVoxel wrote animations before 0.99).
pub(super) fn legacy_animation() -> Vec<u8> {
    let mut main = Vec::new();
    model_chunks(&mut main, [2, 1, 1], &[[0, 0, 0, 1], [1, 0, 0, 1]]);
    model_chunks(
        &mut main,
        [3, 1, 2],
        &[[0, 0, 0, 2], [1, 0, 0, 2], [2, 0, 1, 3]],
    );
    model_chunks(
        &mut main,
        [2, 2, 2],
        &[[0, 0, 0, 4], [1, 0, 0, 4], [0, 1, 0, 5], [1, 1, 1, 5]],
    );
    wrap_main(&main)
}

#[test]
fn several_models_without_a_scene_graph_are_one_animated_object() {
    let scene = import(&legacy_animation());
    assert_eq!(scene.model_count, 3);
    assert_eq!(scene.objects.len(), 1);
    let o = &scene.objects[0];
    let v = model(o);
    assert_eq!(v.frame_count(), 3);
    assert_eq!(per_frame_counts(o), [2, 3, 4]);
    assert_eq!(scene.voxel_count(), 9);
    let seq = v.frames.as_ref().unwrap();
    assert_eq!(seq.frame_secs, DEFAULT_FRAME_SECS);
    assert_eq!(seq.shown, 0);
    // Each frame sits where a still model would: MagicaVoxel (x, y, z) → Y-up (x, z, -y - 1).
    assert_eq!(
        frame_cells(o, 1).iter().map(|c| c.0).collect::<Vec<_>>(),
        vec![[0, 0, -1], [1, 0, -1], [2, 1, -1]]
    );
    let colour = |i: usize| scene.palette[i - 1];
    assert_eq!(frame_cells(o, 1)[2].1, colour(3));
    let mut doc = Document::default();
    scene.add_to(&mut doc);
    doc.validate().unwrap();
    assert_eq!(model(&doc.objects[0]).frame_count(), 3);
}

#[test]
fn the_playhead_picks_one_frame_and_swaps_it_in() {
    let scene = import(&legacy_animation());
    let mut v = model(&scene.objects[0]).clone();
    let before: Vec<_> = (0..3).map(|i| v.frame(i).unwrap().0.leaves()).collect();
    // 0.1 s per frame: 0.15 s is frame 1; 0.35 s wraps to frame 0; -0.05 s is the last frame.
    for (t, want) in [(0.15, 1), (0.25, 2), (0.35, 0), (-0.05, 2), (0.0, 0)] {
        v.set_frame_time(t);
        let seq = v.frames.as_ref().unwrap();
        assert_eq!(seq.shown, want, "t = {t}");
        assert_eq!(v.svo.leaves(), before[want], "t = {t}");
        assert!(seq.frames[want].svo.is_empty());
        // Every frame is still there, whichever is shown.
        for (i, b) in before.iter().enumerate() {
            assert_eq!(&v.frame(i).unwrap().0.leaves(), b);
        }
    }
    assert!(!v.set_frame_time(f32::NAN));
}

/// MagicaVoxel 0.99.7: one nSHP lists models with `_f`, its nTRN has keyframes with `_f`.
pub(super) fn keyframed_animation() -> Vec<u8> {
    let mut main = Vec::new();
    model_chunks(&mut main, [1, 1, 1], &[[0, 0, 0, 1]]);
    model_chunks(&mut main, [2, 1, 1], &[[0, 0, 0, 2], [1, 0, 0, 2]]);
    model_chunks(
        &mut main,
        [3, 1, 1],
        &[[0, 0, 0, 3], [1, 0, 0, 3], [2, 0, 0, 3]],
    );
    transform(&mut main, 0, 1, &[&[]]);
    group(&mut main, 1, &[2]);
    transform(
        &mut main,
        2,
        3,
        &[
            &[("_f", "0"), ("_t", "0 0 0")],
            &[("_f", "3"), ("_t", "5 0 0")],
        ],
    );
    shape(
        &mut main,
        3,
        &[
            (0, &[("_f", "0")]),
            (1, &[("_f", "2")]),
            (2, &[("_f", "5")]),
        ],
    );
    wrap_main(&main)
}

#[test]
fn keyframed_shapes_and_transforms_hold_each_key_until_the_next() {
    let scene = import(&keyframed_animation());
    assert_eq!(scene.objects.len(), 1);
    let o = &scene.objects[0];
    // Frames 0..=5: the model keys at 0, 2, 5 and the transform keys at 0, 3.
    assert_eq!(per_frame_counts(o), [1, 1, 2, 2, 2, 3]);
    // Frames 2 and 3 show the same model, 5 voxels apart in x.
    let (a, b) = (frame_cells(o, 2), frame_cells(o, 3));
    assert_eq!(a.len(), 2);
    for (p, q) in a.iter().zip(&b) {
        assert_eq!(
            [q.0[0] - p.0[0], q.0[1] - p.0[1], q.0[2] - p.0[2]],
            [5, 0, 0]
        );
        assert_eq!(p.1, q.1);
    }
    // A still file (one key) stays a still object.
    let mut main = Vec::new();
    model_chunks(&mut main, [1, 1, 1], &[[0, 0, 0, 1]]);
    transform(&mut main, 0, 1, &[&[("_f", "7"), ("_t", "1 2 3")]]);
    shape(&mut main, 1, &[(0, &[("_f", "7")])]);
    let still = import(&wrap_main(&main));
    assert!(model(&still.objects[0]).frames.is_none());
}

#[test]
fn bad_frame_indices_are_errors() {
    let mut main = Vec::new();
    model_chunks(&mut main, [1, 1, 1], &[[0, 0, 0, 1]]);
    transform(&mut main, 0, 1, &[&[]]);
    shape(&mut main, 1, &[(0, &[("_f", "0")]), (0, &[("_f", "x")])]);
    let e = import_vox_bytes(
        &wrap_main(&main),
        Path::new("anim.vox"),
        &VoxImportOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("anim.vox: scene graph node 1: model 1: frame index _f \"x\""),
        "{e}"
    );
    let mut main = Vec::new();
    model_chunks(&mut main, [1, 1, 1], &[[0, 0, 0, 1]]);
    transform(&mut main, 0, 1, &[&[("_f", "99999999")]]);
    shape(&mut main, 1, &[(0, &[])]);
    let e = import_vox_bytes(
        &wrap_main(&main),
        Path::new("anim.vox"),
        &VoxImportOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("node 0: frame 0: frame index _f") && e.contains("below 4096"),
        "{e}"
    );
}

fn export(objects: &[Object]) -> (Vec<u8>, VoxExportReport) {
    export_vox_bytes(objects, Path::new("out.vox"), &VoxExportOptions::default()).unwrap()
}

#[test]
fn animations_round_trip_frame_by_frame() {
    for (file, models, frames) in [(legacy_animation(), 3, 3), (keyframed_animation(), 3, 6)] {
        let first = import(&file);
        let o = &first.objects[0];
        let (bytes, report) = export(&first.objects);
        let ids = chunk_ids(&bytes);
        // One shape, each distinct frame written once.
        assert_eq!(count(&ids, "nSHP"), 1);
        assert_eq!(count(&ids, "XYZI"), models);
        assert_eq!((report.models, report.placements), (models, 1));
        let raw = dot_vox::load_bytes(&bytes).unwrap();
        let shape_models = raw
            .scenes
            .iter()
            .find_map(|n| match n {
                dot_vox::SceneNode::Shape { models, .. } => Some(models.len()),
                _ => None,
            })
            .unwrap();
        assert_eq!(shape_models, frames);
        let second = import(&bytes);
        assert_eq!(second.objects.len(), 1);
        let back = &second.objects[0];
        assert_eq!(model(back).frame_count(), frames);
        assert_eq!(per_frame_counts(back), per_frame_counts(o));
        for i in 0..frames {
            assert_eq!(frame_cells(back, i), frame_cells(o, i), "frame {i}");
        }
    }
}

#[test]
fn animation_frames_too_large_or_empty_are_refused() {
    let mut scene = import(&legacy_animation());
    if let ObjectKind::Voxels(v) = &mut scene.objects[0].kind {
        v.frames.as_mut().unwrap().frames[2].svo = crate::svo::Svo::new(1, false).unwrap();
    }
    let e = export_vox_bytes(
        &scene.objects,
        Path::new("out.vox"),
        &VoxExportOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("frame 2 of 3 is empty"), "{e}");
}

#[test]
fn renderers_see_only_the_shown_frame() {
    // The CPU renderer draws the animated object exactly as the shown frame alone.
    let scene = import(&legacy_animation());
    let mut doc = Document::default();
    scene.add_to(&mut doc);
    let mut cam = doc.camera;
    cam.frame(glam::Vec3::splat(-3.0), glam::Vec3::splat(3.0));
    doc.camera = cam;
    let req = View::new(48, 48);
    let mut images = Vec::new();
    for t in [0.0, 0.1, 0.2] {
        if let ObjectKind::Voxels(v) = &mut doc.objects[0].kind {
            v.set_frame_time(t);
        }
        let shown = model(&doc.objects[0]).frames.as_ref().unwrap().shown;
        let mut alone = doc.clone();
        alone.objects[0] = still_frame(&doc.objects[0], shown);
        let (a, _, _) = render_document(&doc, &req).unwrap();
        let (b, _, _) = render_document(&alone, &req).unwrap();
        assert!(
            a == b,
            "t = {t}: the animated object differs from frame {shown} alone"
        );
        images.push(a);
    }
    // The frames look different, so the comparisons above mean something.
    assert!(images[0] != images[1] && images[1] != images[2]);
}

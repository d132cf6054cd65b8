use glam::{UVec3, Vec3};
use thicket_core::render::{Quality, QualityPreset};
use thicket_core::scene::{Document, ObjectKind, Transform, VoxelModel};
use thicket_core::svo::{Svo, Voxel};

use super::*;

fn voxels(n: u32) -> ObjectKind {
    let mut svo = Svo::new(5, false).unwrap();
    for x in 0..n {
        svo.set(
            UVec3::new(x, 0, 0),
            Voxel::new([200, 100, 50, 255], Vec3::Y),
        )
        .unwrap();
    }
    ObjectKind::Voxels(VoxelModel {
        svo,
        ..VoxelModel::default()
    })
}

fn editor_with_two() -> (Editor, u64, u64) {
    let mut ed = Editor::default();
    let a = ed.add_object("A", voxels(3));
    let b = ed.add_object("B", voxels(5));
    (ed, a, b)
}

#[test]
fn add_rename_delete_undo_redo_round_trip() {
    let (mut ed, a, b) = editor_with_two();
    assert_ne!(a, b);
    assert_eq!(ed.selection, Some(Selection::Object(b)));
    let after_add = ed.doc().clone();

    ed.rename(a, "  Rock ").unwrap();
    assert_eq!(ed.object(a).unwrap().name, "Rock");
    ed.delete(b).unwrap();
    assert!(ed.object(b).is_none());
    assert_eq!(
        ed.selection, None,
        "selection of a deleted object is dropped"
    );

    assert!(ed.undo());
    assert_eq!(ed.object(b).unwrap().name, "B");
    assert_eq!(
        ed.doc().objects[1].id,
        b,
        "undo restores the outliner position"
    );
    assert!(ed.undo());
    assert_eq!(ed.doc(), &after_add);
    assert!(ed.redo());
    assert!(ed.redo());
    assert!(ed.object(b).is_none());
    assert_eq!(ed.object(a).unwrap().name, "Rock");
    assert!(!ed.redo(), "nothing left to redo");
}

#[test]
fn undo_everything_returns_to_the_start_and_clears_dirty() {
    let mut ed = Editor::default();
    let start = ed.doc().clone();
    assert!(!ed.is_dirty());
    let a = ed.add_object("A", voxels(2));
    let copy = ed.duplicate(a).unwrap();
    assert_eq!(ed.object(copy).unwrap().name, "A copy");
    assert_eq!(ed.doc().objects.len(), 2);
    ed.set_visible(a, false).unwrap();
    assert!(ed.is_dirty());
    while ed.undo() {}
    assert_eq!(ed.doc(), &start);
    assert!(
        !ed.is_dirty(),
        "back at the loaded state means nothing to save"
    );
}

#[test]
fn a_drag_is_one_undo_step() {
    let (mut ed, a, _) = editor_with_two();
    let before = ed.history().undo_len();
    for i in 1..=10 {
        let t = Transform {
            translation: Vec3::new(i as f32, 0.0, 0.0),
            ..Transform::default()
        };
        ed.set_transform(a, t).unwrap();
    }
    ed.end_interaction();
    assert_eq!(ed.history().undo_len(), before + 1);
    assert!((ed.object(a).unwrap().transform.translation.x - 10.0).abs() < 1e-6);
    ed.undo();
    assert_eq!(ed.object(a).unwrap().transform, Transform::default());
    // A second drag after the interaction ended is a second step.
    ed.set_transform(
        a,
        Transform {
            translation: Vec3::ONE,
            ..Transform::default()
        },
    )
    .unwrap();
    ed.end_interaction();
    ed.set_transform(
        a,
        Transform {
            translation: Vec3::splat(2.0),
            ..Transform::default()
        },
    )
    .unwrap();
    ed.undo();
    assert_eq!(ed.object(a).unwrap().transform.translation, Vec3::ONE);
}

#[test]
fn invalid_transforms_are_refused_and_change_nothing() {
    let (mut ed, a, _) = editor_with_two();
    let doc = ed.doc().clone();
    let undo_len = ed.history().undo_len();
    for bad in [
        Transform {
            scale: Vec3::new(1.0, 0.0, 1.0),
            ..Transform::default()
        },
        Transform {
            translation: Vec3::new(f32::NAN, 0.0, 0.0),
            ..Transform::default()
        },
        Transform {
            scale: Vec3::splat(f32::INFINITY),
            ..Transform::default()
        },
    ] {
        let e = ed.set_transform(a, bad).unwrap_err();
        assert!(matches!(e, CommandError::Invalid(_)), "{e}");
        assert!(
            e.to_string().contains('A'),
            "the message names the object: {e}"
        );
    }
    assert_eq!(ed.doc(), &doc);
    assert_eq!(ed.history().undo_len(), undo_len);
    assert!(ed.rename(a, "   ").is_err());
    assert!(matches!(ed.delete(999), Err(CommandError::NoObject(999))));
}

#[test]
fn lights_and_quality_validate_and_undo() {
    let mut ed = Editor::default();
    let mut light = ed.doc().lights[0].clone();
    light.direction = Vec3::ZERO;
    assert!(ed.set_light(0, light.clone()).is_err());
    light.direction = Vec3::new(0.0, -1.0, 0.0);
    light.intensity = 3.0;
    ed.set_light(0, light.clone()).unwrap();
    assert_eq!(ed.doc().lights[0], light);
    assert!(ed.set_light(7, light).is_err());

    let mut q = ed.doc().quality.clone();
    q.lod_pixel_threshold = f32::NAN;
    assert!(ed.set_quality(q).is_err());
    ed.apply_quality_preset(QualityPreset::Final);
    assert_eq!(ed.doc().quality, Quality::preset(QualityPreset::Final));
    ed.undo();
    assert_eq!(ed.doc().quality, Quality::default());
    ed.undo();
    assert!((ed.doc().lights[0].intensity - 1.0).abs() < 1e-6);
}

#[test]
fn history_is_bounded_and_keeps_the_latest_step() {
    let (mut ed, a, _) = editor_with_two();
    ed.history.capacity = 3;
    for i in 0..10 {
        ed.rename(a, &format!("n{i}")).unwrap();
    }
    assert_eq!(ed.history().undo_len(), 3);
    ed.undo();
    assert_eq!(ed.object(a).unwrap().name, "n8");
}

#[test]
fn camera_moves_are_not_edits() {
    let (mut ed, _, _) = editor_with_two();
    ed.mark_saved(std::path::PathBuf::from("x.thicket.json"));
    let rev = ed.revision();
    ed.frame_selection();
    assert!(ed.revision() > rev, "framing changes the view");
    assert!(!ed.is_dirty());
    let mut cam = ed.doc().camera;
    cam.distance = -1.0;
    ed.set_camera(cam);
    assert!(
        ed.doc().camera.distance > 0.0,
        "an invalid camera is ignored"
    );
}

#[test]
fn import_adds_objects_with_fresh_ids() {
    let (mut ed, a, b) = editor_with_two();
    let mut other = Document::default();
    other.add("X", voxels(1));
    other.add("Y", voxels(1));
    let ids = ed.add_objects_from(other);
    assert_eq!(ids.len(), 2);
    assert!(!ids.contains(&a) && !ids.contains(&b));
    ed.doc().validate().unwrap();
    ed.undo();
    ed.undo();
    assert_eq!(ed.doc().objects.len(), 2);
}

#[test]
fn recent_files_are_unique_and_bounded() {
    let mut ed = Editor::default();
    for i in 0..15 {
        ed.push_recent(format!("p{i}.thicket.json").into());
    }
    ed.push_recent("p3.thicket.json".into());
    assert_eq!(ed.recent.len(), MAX_RECENT);
    assert_eq!(ed.recent[0], std::path::PathBuf::from("p3.thicket.json"));
    assert_eq!(
        ed.recent
            .iter()
            .filter(|p| p.ends_with("p3.thicket.json"))
            .count(),
        1
    );
}

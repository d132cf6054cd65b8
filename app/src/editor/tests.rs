use glam::{IVec3, UVec3, Vec3};
use thicket_core::quality::{Quality, QualityPreset};
use thicket_core::scene::{Document, Light, ObjectKind, Transform, VoxelModel};
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
fn lights_stop_at_the_maximum_a_document_may_have() {
    use thicket_core::scene::MAX_LIGHTS;
    let mut ed = Editor::default();
    let added = ed.import_lights(vec![Light::default(); MAX_LIGHTS + 5]);
    assert_eq!(
        added,
        MAX_LIGHTS - 1,
        "the default sun plus the imported fill the maximum"
    );
    assert_eq!(ed.doc().lights.len(), MAX_LIGHTS);
    let e = ed.add_light(ed.new_light()).unwrap_err().to_string();
    assert!(e.contains("already has 256 lights"), "{e}");
    assert_eq!(ed.doc().lights.len(), MAX_LIGHTS);
    assert!(ed.doc().validate().is_ok());
}

#[test]
fn lights_are_added_and_deleted_validated_undone_and_redone() {
    let mut ed = Editor::default();
    let sun = ed.doc().lights[0].clone();
    // A bad light is refused and changes nothing.
    let bad = Light {
        direction: Vec3::new(f32::NAN, -1.0, 0.0),
        ..ed.new_light()
    };
    assert!(ed.add_light(bad).is_err());
    let negative = Light {
        intensity: -1.0,
        ..ed.new_light()
    };
    assert!(ed.add_light(negative).is_err());
    assert_eq!(ed.doc().lights.len(), 1);
    assert!(!ed.is_dirty());

    // A new light comes from another side than the sun, with a fresh name, and is selected.
    let fill = ed.new_light();
    assert_eq!(fill.name, "Light 2");
    assert!(
        fill.direction
            .normalize_or_zero()
            .dot(sun.direction.normalize_or_zero())
            < 0.9
    );
    let i = ed.add_light(fill.clone()).unwrap();
    assert_eq!(i, 1);
    assert_eq!(ed.doc().lights, vec![sun.clone(), fill.clone()]);
    assert_eq!(ed.selection, Some(Selection::Light(1)));
    assert!(ed.doc().validate().is_ok());
    // Its edits merge as a drag, separately from the add.
    let mut brighter = fill.clone();
    brighter.intensity = 2.0;
    ed.set_light(1, brighter.clone()).unwrap();
    ed.end_interaction();

    // Deleting the first light moves the selection with the light it named.
    ed.delete_light(0).unwrap();
    assert_eq!(ed.doc().lights, vec![brighter.clone()]);
    assert_eq!(ed.selection, Some(Selection::Light(0)));
    // The last light may go too: the scene keeps its ambient light and still renders.
    ed.delete_light(0).unwrap();
    assert!(ed.doc().lights.is_empty());
    assert_eq!(ed.selection, None);
    assert!(ed.doc().validate().is_ok());
    assert_eq!(ed.delete_light(0), Err(CommandError::NoLight(0)));

    // Undo puts each light back at its place, in order; redo removes them again.
    assert!(ed.undo());
    assert_eq!(ed.doc().lights, vec![brighter.clone()]);
    assert!(ed.undo());
    assert_eq!(ed.doc().lights, vec![sun.clone(), brighter.clone()]);
    assert!(ed.undo());
    assert_eq!(ed.doc().lights, vec![sun.clone(), fill.clone()]);
    assert!(ed.undo());
    assert_eq!(ed.doc().lights, vec![sun.clone()]);
    assert!(!ed.is_dirty());
    assert!(ed.redo());
    assert!(ed.redo());
    assert!(ed.redo());
    assert_eq!(ed.doc().lights, vec![brighter.clone()]);
    assert!(ed.redo());
    assert!(ed.doc().lights.is_empty());
    // A selection left pointing past the list by an undo is dropped.
    ed.undo();
    ed.selection = Some(Selection::Light(0));
    ed.undo();
    ed.selection = Some(Selection::Light(1));
    ed.redo();
    assert_eq!(ed.selection, None);
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
    // The same file by its absolute path is the same entry.
    let p3 = std::env::current_dir().unwrap().join("p3.thicket.json");
    ed.push_recent(p3.clone());
    assert_eq!(ed.recent.len(), MAX_RECENT);
    assert_eq!(ed.recent[0], p3, "stored absolute");
    assert_eq!(
        ed.recent
            .iter()
            .filter(|p| p.ends_with("p3.thicket.json"))
            .count(),
        1
    );
}

/// A 16³ model with a solid 8×4×8 slab at the bottom.
fn slab_editor() -> (Editor, u64) {
    let mut svo = Svo::new(4, false).unwrap();
    for x in 0..8 {
        for y in 0..4 {
            for z in 0..8 {
                svo.set(UVec3::new(x, y, z), Voxel::new([90, 90, 90, 255], Vec3::Y))
                    .unwrap();
            }
        }
    }
    let mut ed = Editor::default();
    let id = ed.add_object(
        "Slab",
        ObjectKind::Voxels(VoxelModel {
            svo,
            ..VoxelModel::default()
        }),
    );
    (ed, id)
}

fn svo_of(ed: &Editor, id: u64) -> Svo {
    match &ed.object(id).unwrap().kind {
        ObjectKind::Voxels(v) => v.svo.clone(),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => panic!("not voxels"),
    }
}

#[test]
fn picking_hits_the_top_face_of_the_slab() {
    let (ed, id) = slab_editor();
    // Straight down onto voxel column (2, *, 5): the top voxel is y = 3, entered through +Y.
    let pick = ed
        .pick_voxel(Vec3::new(2.5, 20.0, 5.5), Vec3::NEG_Y)
        .expect("a hit");
    assert_eq!(pick.object, id);
    assert_eq!(pick.voxel, UVec3::new(2, 3, 5));
    assert_eq!(pick.normal, glam::IVec3::Y);
    assert!((pick.t - 16.0).abs() < 1e-4, "t = {}", pick.t);
    assert!(
        ed.pick_voxel(Vec3::new(12.5, 20.0, 12.5), Vec3::NEG_Y)
            .is_none()
    );
    // A moved object is picked where it is drawn.
    let mut ed = ed;
    let t = Transform {
        translation: Vec3::new(100.0, 0.0, 0.0),
        ..Transform::default()
    };
    ed.set_transform(id, t).unwrap();
    assert!(
        ed.pick_voxel(Vec3::new(2.5, 20.0, 5.5), Vec3::NEG_Y)
            .is_none()
    );
    assert!(
        ed.pick_voxel(Vec3::new(102.5, 20.0, 5.5), Vec3::NEG_Y)
            .is_some()
    );
}

#[test]
fn a_stroke_is_one_undo_step_and_undo_restores_every_voxel() {
    let (mut ed, id) = slab_editor();
    let before = svo_of(&ed, id);
    let steps_before = ed.history().undo_len();
    let brush = thicket_core::sculpt::Brush {
        op: thicket_core::sculpt::BrushOp::Remove,
        radius: 1.5,
        ..Default::default()
    };
    ed.begin_stroke();
    // Overlapping dabs along x: later dabs touch voxels earlier dabs already changed.
    for x in 0..6 {
        ed.sculpt_dab(id, &brush, Vec3::new(x as f32 + 0.5, 3.5, 3.5), Vec3::ZERO)
            .unwrap();
    }
    let painted = thicket_core::sculpt::Brush {
        op: thicket_core::sculpt::BrushOp::Paint,
        color: [255, 0, 0, 255],
        radius: 2.0,
        ..Default::default()
    };
    ed.sculpt_dab(id, &painted, Vec3::new(3.5, 2.5, 3.5), Vec3::ZERO)
        .unwrap();
    let after = svo_of(&ed, id);
    assert_ne!(after, before);
    assert!(after.leaf_count() < before.leaf_count());
    assert_eq!(ed.history().undo_len(), steps_before + 1, "one step");
    assert!(ed.is_dirty());

    ed.end_interaction();
    assert!(ed.undo());
    assert_eq!(svo_of(&ed, id).leaves(), before.leaves());
    assert!(ed.redo());
    assert_eq!(svo_of(&ed, id).leaves(), after.leaves());

    // A second stroke is a second step.
    ed.begin_stroke();
    ed.sculpt_dab(id, &brush, Vec3::new(6.5, 3.5, 6.5), Vec3::ZERO)
        .unwrap();
    assert_eq!(ed.history().undo_len(), steps_before + 2);
}

#[test]
fn symmetric_dabs_mirror_across_the_model_centre() {
    let (mut ed, id) = slab_editor();
    let center = ed.voxel_center(id).unwrap();
    assert_eq!(center, Vec3::new(4.0, 2.0, 4.0));
    let brush = thicket_core::sculpt::Brush {
        op: thicket_core::sculpt::BrushOp::Remove,
        radius: 0.5,
        symmetry: [true, false, false],
        ..Default::default()
    };
    ed.begin_stroke();
    ed.sculpt_dab(id, &brush, Vec3::new(1.5, 3.5, 2.5), center)
        .unwrap();
    let svo = svo_of(&ed, id);
    assert!(svo.get(UVec3::new(1, 3, 2)).is_none());
    assert!(svo.get(UVec3::new(6, 3, 2)).is_none(), "mirrored along x");
    assert!(svo.get(UVec3::new(1, 3, 5)).is_some(), "not along z");
}

#[test]
fn sculpting_a_mesh_or_with_a_bad_brush_is_refused() {
    let (mut ed, id) = slab_editor();
    let bad = thicket_core::sculpt::Brush {
        radius: f32::NAN,
        ..Default::default()
    };
    let before = svo_of(&ed, id);
    assert!(ed.sculpt_dab(id, &bad, Vec3::ONE, Vec3::ZERO).is_err());
    assert_eq!(svo_of(&ed, id), before);
    assert!(
        ed.sculpt_dab(999, &Default::default(), Vec3::ONE, Vec3::ZERO)
            .is_err()
    );
}

#[test]
fn history_memory_bound_drops_old_steps_but_keeps_the_latest() {
    let (mut ed, id) = slab_editor();
    ed.history.max_bytes = 1;
    let brush = thicket_core::sculpt::Brush {
        op: thicket_core::sculpt::BrushOp::Remove,
        radius: 1.0,
        ..Default::default()
    };
    for z in 0..3 {
        ed.begin_stroke();
        ed.sculpt_dab(
            id,
            &brush,
            Vec3::new(1.5, 3.5, z as f32 * 2.5 + 0.5),
            Vec3::ZERO,
        )
        .unwrap();
    }
    assert_eq!(ed.history().undo_len(), 1, "only the latest step fits");
    let before_undo = svo_of(&ed, id).leaf_count();
    assert!(ed.undo());
    assert!(svo_of(&ed, id).leaf_count() > before_undo);
}

#[test]
fn rays_through_the_view_centre_point_at_the_target() {
    let cam = thicket_core::scene::OrbitCamera::default();
    let (origin, dir) = ray_through(cam.clip_from_world(1.5), glam::Vec2::ZERO).unwrap();
    let to_target = (cam.target - origin).normalize_or_zero();
    assert!(dir.dot(to_target) > 0.9999, "{dir} vs {to_target}");
    assert!(origin.distance(cam.eye()) < cam.near * 2.0);
}

/// A two-joint rig (root at the origin, a child one unit up) on a few voxels, with a clip that
/// moves the root up by one unit over one second.
fn rigged_editor() -> (Editor, u64) {
    use thicket_core::skin::{
        AnimationClip, Channel, Interpolation, Joint, Property, Rig, Skeleton,
        Transform as JointTransform,
    };
    let joints = vec![
        Joint {
            name: "root".into(),
            ..Joint::default()
        },
        Joint {
            name: "tip".into(),
            parent: Some(0),
            rest: JointTransform {
                translation: Vec3::Y,
                ..JointTransform::IDENTITY
            },
            inverse_bind: glam::Mat4::from_translation(-Vec3::Y),
            ..Joint::default()
        },
    ];
    let (skeleton, _) = Skeleton::new(joints).unwrap();
    let clip = AnimationClip {
        name: "rise".into(),
        duration_secs: 1.0,
        channels: vec![Channel {
            joint: 0,
            property: Property::Translation,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![glam::Vec4::ZERO, glam::Vec4::new(0.0, 1.0, 0.0, 0.0)],
        }],
        ..AnimationClip::default()
    };
    let ObjectKind::Voxels(mut model) = voxels(3) else {
        unreachable!()
    };
    model.rig = Some(Rig::new(skeleton, vec![clip]));
    let mut ed = Editor::default();
    let id = ed.add_object("Figure", ObjectKind::Voxels(model));
    ed.mark_saved(std::path::PathBuf::from("figure.thicket.json"));
    (ed, id)
}

#[test]
fn a_joint_drag_is_one_undo_step_and_moves_the_children() {
    let (mut ed, id) = rigged_editor();
    let tip_before = ed.joint_frames(id).unwrap().position(1).unwrap();
    assert!((tip_before - Vec3::Y).length() < 1e-5, "{tip_before}");
    let steps = ed.history().undo_len();
    // A gizmo drag: several updates from the same base, then release.
    for deg in [10.0_f32, 45.0, 90.0] {
        ed.rotate_joint(id, 0, None, glam::Quat::from_rotation_z(deg.to_radians()))
            .unwrap();
    }
    ed.end_interaction();
    assert_eq!(ed.history().undo_len(), steps + 1, "one step per drag");
    assert_eq!(ed.rig(id).unwrap().pose_overrides.len(), 1);
    // The root turned 90 degrees about Z: the tip one unit up is now one unit along -X.
    let tip = ed.joint_frames(id).unwrap().position(1).unwrap();
    assert!((tip - Vec3::NEG_X).length() < 1e-5, "{tip}");
    assert!(ed.is_dirty());

    // A second drag on the tip, translating it, is a second step.
    ed.translate_joint(id, 1, None, Vec3::new(0.0, 0.5, 0.0))
        .unwrap();
    ed.end_interaction();
    assert_eq!(ed.history().undo_len(), steps + 2);
    let tip = ed.joint_frames(id).unwrap().position(1).unwrap();
    assert!((tip - Vec3::new(-1.5, 0.0, 0.0)).length() < 1e-5, "{tip}");

    assert!(ed.undo());
    assert!(ed.undo());
    assert!(ed.rig(id).unwrap().pose_overrides.is_empty());
    assert!(!ed.is_dirty(), "back at the saved state");
    assert!(ed.redo());
    let tip = ed.joint_frames(id).unwrap().position(1).unwrap();
    assert!((tip - Vec3::NEG_X).length() < 1e-5, "{tip}");
}

#[test]
fn pose_overrides_are_validated_and_reset() {
    let (mut ed, id) = rigged_editor();
    let bad = thicket_core::skin::JointOverride {
        joint: 7,
        ..Default::default()
    };
    assert!(ed.set_joint_override(id, bad).is_err());
    let nan = thicket_core::skin::JointOverride {
        joint: 1,
        translation: Some(Vec3::NAN),
        ..Default::default()
    };
    let err = ed.set_joint_override(id, nan).unwrap_err().to_string();
    assert!(err.contains("tip"), "{err}");
    assert!(ed.rig(id).unwrap().pose_overrides.is_empty());
    // Posing an object without a rig is refused with its name.
    let plain = ed.add_object("Plain", voxels(2));
    let err = ed
        .rotate_joint(plain, 0, None, glam::Quat::IDENTITY)
        .unwrap_err()
        .to_string();
    assert!(err.contains("Plain"), "{err}");

    ed.rotate_joint(id, 1, None, glam::Quat::from_rotation_x(0.3))
        .unwrap();
    ed.end_interaction();
    ed.clear_pose(id, Some(1)).unwrap();
    assert!(ed.rig(id).unwrap().pose_overrides.is_empty());
    assert!(ed.undo());
    assert_eq!(ed.rig(id).unwrap().pose_overrides.len(), 1);
}

#[test]
fn playback_is_not_an_edit_but_changes_the_animation_key() {
    let (mut ed, id) = rigged_editor();
    let key = ed.animation_key();
    let content = ed.content_key();
    let mut p = ed.rig(id).unwrap().playback;
    assert_eq!(p.clip, Some(0));
    p.time_secs = 0.5;
    ed.set_playback(id, p).unwrap();
    assert_ne!(ed.animation_key(), key);
    assert_eq!(ed.content_key(), content, "scrubbing is not an edit");
    assert!(!ed.is_dirty());
    // Half way through the clip the root has risen by half a unit.
    let root = ed.joint_frames(id).unwrap().position(0).unwrap();
    assert!((root - Vec3::new(0.0, 0.5, 0.0)).length() < 1e-5, "{root}");
    p.clip = Some(3);
    assert!(ed.set_playback(id, p).is_err());
    p.clip = Some(0);
    p.time_secs = f32::NAN;
    assert!(ed.set_playback(id, p).is_err());
    assert_eq!(ed.rig(id).unwrap().playback.time_secs, 0.5);
}

#[test]
fn stretch_settings_are_validated_and_one_step_per_drag() {
    let (mut ed, id) = rigged_editor();
    let mut s = ed.rig(id).unwrap().stretch;
    s.multiplier = 0.0;
    let err = ed.set_stretch(id, s).unwrap_err().to_string();
    assert!(err.contains("multiplier"), "{err}");
    let steps = ed.history().undo_len();
    for m in [1.2_f32, 1.4, 1.6] {
        s.multiplier = m;
        s.strategy = thicket_core::skin::StretchStrategy::Adaptive;
        ed.set_stretch(id, s).unwrap();
    }
    ed.end_interaction();
    assert_eq!(ed.history().undo_len(), steps + 1);
    assert_eq!(ed.rig(id).unwrap().stretch.multiplier, 1.6);
    assert!(ed.undo());
    assert_eq!(
        ed.rig(id).unwrap().stretch,
        thicket_core::skin::StretchSettings::default()
    );
}

#[test]
fn krs_edits_are_validated_normalised_and_undoable() {
    let mut ed = Editor::default();
    let id = ed.add_object("Tree", ObjectKind::Krs(thicket_core::krs::presets::tree()));
    let original = ed.krs(id).unwrap().clone();
    assert!(!original.mirrors.is_empty());

    // A zero mirror normal is refused with a message naming the object and the mirror.
    let mut k = original.clone();
    k.mirrors[0].normal = Vec3::ZERO;
    let err = ed.set_krs(id, &k).unwrap_err().to_string();
    assert!(
        err.contains("\"Tree\"") && err.contains("mirror 0"),
        "{err}"
    );
    assert_eq!(ed.krs(id).unwrap(), &original);

    // A non-unit normal is stored normalised, keeping the plane.
    let mut k = original.clone();
    k.mirrors[0] = thicket_core::krs::MirrorPlane {
        normal: Vec3::new(0.0, 2.0, 0.0),
        offset: 1.0,
    };
    ed.set_krs(id, &k).unwrap();
    ed.end_interaction();
    let m = ed.krs(id).unwrap().mirrors[0];
    assert!(
        (m.normal - Vec3::Y).length() < 1e-6 && (m.offset - 0.5).abs() < 1e-6,
        "{m:?}"
    );

    // A kernel parameter out of range is refused by core's validation.
    let mut k = ed.krs(id).unwrap().clone();
    k.kernels[0] = thicket_core::krs::Kernel::RoundedBox(thicket_core::krs::BoxKernel {
        half_extents: Vec3::splat(0.1),
        rounding: 0.5,
        ..Default::default()
    });
    let err = ed.set_krs(id, &k).unwrap_err().to_string();
    assert!(err.contains("rounding"), "{err}");

    // Texturing out of the document's ranges (which core's object validation does not check)
    // and a negative warp amplitude are refused too; in range they are stored.
    let before = ed.krs(id).unwrap().clone();
    for edit in [
        (|k: &mut thicket_core::krs::KrsObject| k.texturing.contrast = 1.5) as fn(&mut _),
        |k| k.texturing.sharpness = 65.0,
        |k| k.texturing.scale = f32::NAN,
        |k| {
            k.distortion = Some(thicket_core::krs::Distortion {
                amplitude: -0.1,
                ..Default::default()
            });
        },
    ] {
        let mut k = before.clone();
        edit(&mut k);
        assert!(ed.set_krs(id, &k).is_err(), "{:?}", k.texturing);
        assert_eq!(ed.krs(id).unwrap(), &before);
    }
    let mut k = before.clone();
    k.texturing.contrast = 1.0;
    k.texturing.sharpness = 64.0;
    ed.set_krs(id, &k).unwrap();
    assert_eq!(ed.krs(id).unwrap().texturing, k.texturing);
    ed.end_interaction();
    assert!(ed.undo());
    assert_eq!(ed.krs(id).unwrap(), &before);

    // A preset is one step; undo twice gets the original back.
    ed.apply_krs_preset(id, "coral").unwrap();
    let coral = thicket_core::krs::presets::coral().validated(0).unwrap();
    assert_eq!(ed.krs(id).unwrap().kernels, coral.kernels);
    assert!(ed.apply_krs_preset(id, "no such").is_err());
    assert!(ed.undo());
    assert!(ed.undo());
    assert_eq!(ed.krs(id).unwrap(), &original);
}

/// What a GPU-like consumer reading `chain` holds now: the regions ending at the editor's
/// content key.
fn upload_regions(ed: &Editor, chain: &mut RegionChain) -> Vec<VoxelRegion> {
    chain.read(ed.changes(), |c| Redo::for_upload(ed.doc(), c));
    chain.ending_at(ed.content_key()).to_vec()
}

#[test]
fn voxel_edits_report_their_region_for_incremental_uploads() {
    let (mut ed, id) = slab_editor();
    let brush = thicket_core::sculpt::Brush {
        op: thicket_core::sculpt::BrushOp::Remove,
        radius: 1.5,
        ..Default::default()
    };
    let start = ed.content_key();
    let (mut gpu, mut other) = (
        RegionChain::from_end(ed.changes()),
        RegionChain::from_end(ed.changes()),
    );
    ed.begin_stroke();
    ed.sculpt_dab(id, &brush, Vec3::new(2.5, 3.5, 3.5), Vec3::ZERO)
        .unwrap();
    // A consumer reading between the dabs keeps a region per read (it may hold the state in
    // between); one reading after both sees them merged.
    assert_eq!(upload_regions(&ed, &mut gpu).len(), 1);
    ed.sculpt_dab(id, &brush, Vec3::new(6.5, 3.5, 3.5), Vec3::ZERO)
        .unwrap();
    let each = upload_regions(&ed, &mut gpu);
    assert_eq!(each.len(), 2, "{each:?}");
    assert_eq!((each[0].from, each[1].to), (start, ed.content_key()));
    assert_eq!(each[0].to, each[1].from);
    let r = upload_regions(&ed, &mut other)[0];
    assert_eq!((r.from, r.to, r.object), (start, ed.content_key(), id));
    assert!(r.lo.x <= 2 && r.hi.x >= 6, "{r:?}");
    assert!(
        r.lo.cmple(each[0].lo.min(each[1].lo)).all()
            && r.hi.cmpge(each[0].hi.max(each[1].hi)).all(),
        "the merged box holds both: {r:?} {each:?}"
    );
    // After another kind of edit the next dab starts a new region from there.
    ed.end_interaction();
    ed.rename(id, "Slab 2").unwrap();
    let renamed = ed.content_key();
    ed.begin_stroke();
    ed.sculpt_dab(id, &brush, Vec3::new(2.5, 2.5, 6.5), Vec3::ZERO)
        .unwrap();
    assert_eq!(upload_regions(&ed, &mut gpu)[0].from, renamed);
}

/// The changes a consumer reads from `cursor`, in order.
fn read_changes(ed: &Editor, cursor: &mut ChangeCursor) -> Vec<ChangeEntry> {
    match ed.changes().read(cursor) {
        ChangesRead::Changes(entries) => entries.copied().collect(),
        ChangesRead::Lagged => panic!("nothing was dropped"),
    }
}

#[test]
fn each_consumer_sees_each_change_once_typed_and_undo_as_its_own_change() {
    let (mut ed, slab) = slab_editor();
    let ObjectKind::Voxels(figure) = rigged_editor().0.doc().objects[0].kind.clone() else {
        unreachable!()
    };
    let figure = ed.add_object("Figure", ObjectKind::Voxels(figure));
    let rock = ed.add_object("Rock", ObjectKind::Krs(thicket_core::krs::presets::rock()));
    ed.end_interaction();
    // Three consumers: a raw reader after every action, one that reads once at the end, and
    // the two renderers' region chains.
    let mut each = ed.changes().cursor_at_end();
    let mut at_end = ed.changes().cursor_at_end();
    let mut gpu = RegionChain::from_end(ed.changes());
    let mut shadows = RegionChain::from_end(ed.changes());
    let shadow_regions = |ed: &Editor, chain: &mut RegionChain| {
        chain.read(ed.changes(), |c| Redo::for_shadow_maps(ed.doc(), c));
        chain.ending_at(ed.content_key()).to_vec()
    };
    let brush = thicket_core::sculpt::Brush {
        op: thicket_core::sculpt::BrushOp::Remove,
        radius: 1.5,
        ..Default::default()
    };
    let kinds = |entries: &[ChangeEntry]| entries.iter().map(|e| e.change).collect::<Vec<_>>();
    let mut seen = Vec::new();

    // A brush stroke: one change per dab, each with its box.
    let start = ed.content_key();
    ed.begin_stroke();
    for x in [2.5, 5.5] {
        ed.sculpt_dab(slab, &brush, Vec3::new(x, 3.5, 3.5), Vec3::ZERO)
            .unwrap();
    }
    ed.end_interaction();
    let stroke = read_changes(&ed, &mut each);
    assert_eq!(stroke.len(), 2, "{stroke:?}");
    assert!(
        stroke.iter().all(
            |e| matches!(e.change, Change::Voxels { object, region: Some(_) } if object == slab)
        ),
        "{stroke:?}"
    );
    assert_eq!((stroke[0].from, stroke[1].to), (start, ed.content_key()));
    assert_eq!(stroke[0].to, stroke[1].from, "the changes chain");
    assert_eq!(
        upload_regions(&ed, &mut gpu).len(),
        1,
        "merged into one box"
    );
    assert_eq!(shadow_regions(&ed, &mut shadows).len(), 1);
    seen.extend(stroke);

    // A rig edit: the pose; the GPU keeps its upload, the shadow maps are drawn again.
    ed.rotate_joint(figure, 0, None, glam::Quat::from_rotation_z(0.5))
        .unwrap();
    ed.end_interaction();
    let pose = read_changes(&ed, &mut each);
    assert_eq!(kinds(&pose), [Change::Pose { object: figure }]);
    assert_eq!(upload_regions(&ed, &mut gpu)[0].from, start);
    assert!(shadow_regions(&ed, &mut shadows).is_empty());
    seen.extend(pose);

    // A KRS edit and a light move: each once, each breaking the GPU's chain.
    let mut k = ed.krs(rock).unwrap().clone();
    k.mirrors[0].offset += 0.25;
    ed.set_krs(rock, &k).unwrap();
    ed.end_interaction();
    let krs = read_changes(&ed, &mut each);
    assert_eq!(kinds(&krs), [Change::Krs { object: rock }]);
    assert!(upload_regions(&ed, &mut gpu).is_empty());
    seen.extend(krs);
    let mut light = ed.doc().lights[0].clone();
    light.direction = Vec3::new(0.3, -1.0, 0.2);
    ed.set_light(0, light).unwrap();
    ed.end_interaction();
    let lights = read_changes(&ed, &mut each);
    assert_eq!(kinds(&lights), [Change::Lights]);
    seen.extend(lights);

    // Undo of each, newest first: the same kinds; the stroke's undo as its written box.
    for expected in [
        Change::Lights,
        Change::Krs { object: rock },
        Change::Pose { object: figure },
    ] {
        let before = ed.content_key();
        assert!(ed.undo());
        let undone = read_changes(&ed, &mut each);
        assert_eq!(kinds(&undone), [expected]);
        assert_eq!((undone[0].from, undone[0].to), (before, ed.content_key()));
        seen.extend(undone);
    }
    let mut shadows = RegionChain::from_end(ed.changes());
    assert!(ed.undo());
    let undone = read_changes(&ed, &mut each);
    let [
        ChangeEntry {
            change:
                Change::Voxels {
                    object,
                    region: Some((lo, hi)),
                },
            ..
        },
    ] = undone[..]
    else {
        panic!("{undone:?}");
    };
    assert_eq!(object, slab);
    assert!(lo.x <= 1 && hi.x >= 6, "the whole stroke's box: {lo} {hi}");
    assert_eq!(
        shadow_regions(&ed, &mut shadows).len(),
        1,
        "an undone stroke patches the shadow maps"
    );
    seen.extend(undone);

    // The reader that waited sees the same changes, once each, in order.
    assert_eq!(read_changes(&ed, &mut at_end), seen);
    assert!(read_changes(&ed, &mut at_end).is_empty());
    let seqs: Vec<u64> = seen.iter().map(|e| e.seq).collect();
    assert!(seqs.windows(2).all(|w| w[1] == w[0] + 1), "{seqs:?}");
}

#[test]
fn the_tree_builder_rebuilds_a_krs_object_and_refuses_bad_parameters() {
    let mut ed = Editor::default();
    let id = ed.add_object("Shrub", ObjectKind::Krs(thicket_core::krs::presets::rock()));
    let rock = ed.krs(id).unwrap().clone();
    let mut params = thicket_core::krs::TreeParams::default();
    params.widths[0] = -1.0;
    let err = ed.build_tree(id, &params).unwrap_err().to_string();
    assert!(err.contains("negative width"), "{err}");
    assert_eq!(ed.krs(id).unwrap(), &rock);

    let steps = ed.history().undo_len();
    let mut params = thicket_core::krs::TreeParams::default();
    for dy in [0.1_f32, 0.2, 0.3] {
        let last = params.route.len() - 1;
        params.route[last].y += dy;
        ed.build_tree(id, &params).unwrap();
    }
    ed.end_interaction();
    assert_eq!(ed.history().undo_len(), steps + 1, "a drag is one step");
    let built = ed.krs(id).unwrap();
    assert_eq!(built.name, rock.name, "the object keeps its name");
    let expected = params.build().unwrap().validated(0).unwrap();
    assert_eq!(built.kernels, expected.kernels);
    assert_eq!(built.mirrors, expected.mirrors);
    assert!(ed.undo());
    assert_eq!(ed.krs(id).unwrap(), &rock);
}

/// A bumpy 16³ model: a slab with columns, so enhancement has surface to work on.
fn bumpy_editor() -> (Editor, u64) {
    let mut svo = Svo::new(4, false).unwrap();
    for x in 1..14 {
        for z in 1..14 {
            let h = 3 + (x * 7 + z * 3) % 4;
            for y in 0..h {
                let mut v = Voxel::new([60 + 10 * x as u8, 90, 40 + 12 * z as u8, 255], Vec3::Y);
                v.material = u8::from(y > 3);
                svo.set(UVec3::new(x, y, z), v).unwrap();
            }
        }
    }
    let mut ed = Editor::default();
    let id = ed.add_object(
        "Bumps",
        ObjectKind::Voxels(VoxelModel {
            svo,
            ..VoxelModel::default()
        }),
    );
    (ed, id)
}

fn enhance_linked(
    ed: &mut Editor,
    id: u64,
    settings: thicket_core::enhance::EnhanceSettings,
) -> u64 {
    let ObjectKind::Voxels(v) = &ed.object(id).unwrap().kind else {
        panic!("voxels")
    };
    let (fine, _) = v
        .enhanced(&settings, thicket_core::enhance::Control::default())
        .unwrap();
    // No live enhancer handed over: the first dab builds one (the file-open path).
    ed.add_enhancement(id, settings, fine, None).unwrap()
}

#[test]
fn strokes_on_an_enhanced_model_keep_its_enhancement_equal_to_a_fresh_one() {
    use thicket_core::enhance::{EnhanceSettings, Method, enhance};
    for settings in [
        EnhanceSettings {
            factor: 4,
            ..EnhanceSettings::default()
        },
        EnhanceSettings {
            method: Method::Resample,
            factor: 3,
            ..EnhanceSettings::default()
        },
    ] {
        let (mut ed, id) = bumpy_editor();
        let original = svo_of(&ed, id);
        let fine_id = enhance_linked(&mut ed, id, settings.clone());
        let fine_before = svo_of(&ed, fine_id);
        assert!(
            !ed.object(id).unwrap().visible,
            "the coarse model is hidden"
        );
        assert_eq!(ed.doc().enhancement_of(id).unwrap().target, fine_id);
        // Picking goes through the visible fine model to the hidden coarse one.
        let pick = ed
            .pick_voxel(Vec3::new(6.5, 40.0, 6.5), Vec3::NEG_Y)
            .expect("a hit");
        assert_eq!(pick.object, id);

        let steps = ed.history().undo_len();
        let mut chain = RegionChain::from_end(ed.changes());
        let before_stroke = ed.content_key();
        ed.begin_stroke();
        for (i, op) in [
            thicket_core::sculpt::BrushOp::Remove,
            thicket_core::sculpt::BrushOp::Add,
            thicket_core::sculpt::BrushOp::Paint,
        ]
        .into_iter()
        .enumerate()
        {
            let brush = thicket_core::sculpt::Brush {
                op,
                radius: 2.0,
                color: [250, 20, 20, 255],
                ..Default::default()
            };
            ed.sculpt_dab(
                id,
                &brush,
                Vec3::new(4.5 + 2.0 * i as f32, 5.5, 6.5),
                Vec3::ZERO,
            )
            .unwrap();
        }
        ed.end_interaction();
        assert_eq!(ed.history().undo_len(), steps + 1, "one step per stroke");
        // Only the fine model is drawn: a renderer uploads its changed box.
        let regions = upload_regions(&ed, &mut chain);
        assert_eq!(regions.len(), 1, "{regions:?}");
        assert_eq!(regions[0].object, fine_id);
        assert_eq!(
            regions[0].from, before_stroke,
            "the coarse model's edit breaks nothing"
        );
        let coarse = svo_of(&ed, id);
        assert_ne!(coarse, original);
        let t0 = std::time::Instant::now();
        let fresh = enhance(&coarse, &settings).unwrap();
        // Figures for the report (no timing assert: the machine is shared).
        eprintln!(
            "{:?} x{}: full enhancement {:.2} ms, last incremental update {:.2} ms ({} cells, {} fine voxels written)",
            settings.method,
            settings.factor,
            t0.elapsed().as_secs_f64() * 1e3,
            ed.last_enhance_update().map_or(0.0, |u| u.millis),
            ed.last_enhance_update().map_or(0, |u| u.cells),
            ed.last_enhance_update().map_or(0, |u| u.fine_changes),
        );
        assert_eq!(svo_of(&ed, fine_id), fresh, "{:?}", settings.method);
        assert_ne!(svo_of(&ed, fine_id), fine_before);
        let u = ed.last_enhance_update().expect("an update ran");
        assert!(u.source == id && u.fine_changes > 0 && u.cells > 0);
        assert!(
            !u.rebuilt,
            "built before the first dab, updated incrementally"
        );

        // Undo restores the coarse model and its enhancement; redo both again.
        assert!(ed.undo());
        assert_eq!(svo_of(&ed, id).leaves(), original.leaves());
        assert_eq!(svo_of(&ed, fine_id).leaves(), fine_before.leaves());
        assert!(ed.redo());
        assert_eq!(svo_of(&ed, fine_id).leaves(), fresh.leaves());

        // The fine model cannot be sculpted itself while linked; unlinked it can.
        let brush = thicket_core::sculpt::Brush::default();
        let e = ed
            .sculpt_dab(fine_id, &brush, Vec3::splat(20.5), Vec3::ZERO)
            .unwrap_err()
            .to_string();
        assert!(e.contains("detail enhancement of \"Bumps\""), "{e}");
        ed.unlink_enhancement(id).unwrap();
        assert!(ed.doc().enhancements.is_empty());
        ed.begin_stroke();
        ed.sculpt_dab(id, &brush, Vec3::new(8.5, 6.5, 8.5), Vec3::ZERO)
            .unwrap();
        assert_eq!(svo_of(&ed, fine_id), fresh, "unlinked: no longer follows");
        assert!(ed.undo() && ed.undo());
        assert_eq!(ed.doc().enhancement_of(id).unwrap().target, fine_id);
    }
}

/// A document whose linked fine model (`fine_id`, enhanced from `id` with `settings`) is
/// stored as `stale`, not what the link makes of the coarse model (made elsewhere).
struct Stale {
    doc: Document,
    id: u64,
    fine_id: u64,
    stale: Svo,
    settings: thicket_core::enhance::EnhanceSettings,
}

fn stale_enhancement() -> Stale {
    let settings = thicket_core::enhance::EnhanceSettings {
        factor: 4,
        ..Default::default()
    };
    let (mut ed, id) = bumpy_editor();
    let fine_id = enhance_linked(&mut ed, id, settings.clone());
    let mut doc = ed.doc().clone();
    let stale = svo_of(&ed, id);
    for o in &mut doc.objects {
        if o.id == fine_id {
            o.kind = ObjectKind::Voxels(VoxelModel {
                svo: stale.clone(),
                ..VoxelModel::default()
            });
        }
    }
    Stale {
        doc,
        id,
        fine_id,
        stale,
        settings,
    }
}

#[test]
fn an_opened_document_brings_its_enhancers_so_the_first_dab_builds_none() {
    use thicket_core::enhance::enhance;
    // Both ways of opening must replace the stale fine model.
    let Stale {
        doc,
        id,
        fine_id,
        stale,
        settings,
    } = stale_enhancement();
    // What the open job does on its worker thread, then installs.
    let prepared = PreparedDocument::new(doc.clone(), None);
    assert_eq!(prepared.enhancer_count(), 1);
    let mut opened = Editor::default();
    opened.replace_document_prepared(prepared, None);
    assert_ne!(svo_of(&opened, fine_id), stale, "replaced when prepared");
    // The old way: the first dab builds the enhancer on the editor's thread.
    let mut plain = Editor::default();
    plain.replace_document(doc, None);
    let brush = thicket_core::sculpt::Brush {
        op: thicket_core::sculpt::BrushOp::Remove,
        radius: 2.0,
        ..Default::default()
    };
    for e in [&mut opened, &mut plain] {
        e.begin_stroke();
        e.sculpt_dab(id, &brush, Vec3::new(6.5, 5.5, 6.5), Vec3::ZERO)
            .unwrap();
        e.end_interaction();
    }
    assert_eq!(opened.enhancer_rebuilds(), 0, "no full build on the dab");
    assert!(!opened.last_enhance_update().unwrap().rebuilt);
    assert_eq!(
        plain.enhancer_rebuilds(),
        1,
        "unprepared: the dab builds it"
    );
    // Identical results either way, and equal to a fresh enhancement.
    assert_eq!(svo_of(&opened, id), svo_of(&plain, id));
    assert_eq!(svo_of(&opened, fine_id), svo_of(&plain, fine_id));
    let fresh = enhance(&svo_of(&opened, id), &settings).unwrap();
    assert_eq!(svo_of(&opened, fine_id), fresh);
    // Undo keeps the prepared enhancer too (no rebuild).
    assert!(opened.undo());
    assert_eq!(opened.enhancer_rebuilds(), 0);
}

/// Replacing a stale fine model is not an edit, but it changes what is drawn: the content key
/// must change with it, even when the dab that triggered it wrote nothing (a renderer or the
/// CPU preview's shadow cache keyed on the content would otherwise keep the old voxels).
#[test]
fn replacing_a_stale_enhancement_changes_the_content_key() {
    use thicket_core::enhance::enhance;
    let Stale {
        doc,
        id,
        fine_id,
        stale,
        settings,
    } = stale_enhancement();
    let mut plain = Editor::default();
    plain.replace_document(doc, None);
    assert_eq!(svo_of(&plain, fine_id), stale);
    let key = plain.content_key();
    // Removing air: the dab writes nothing, so no history step.
    let brush = thicket_core::sculpt::Brush {
        op: thicket_core::sculpt::BrushOp::Remove,
        radius: 1.0,
        ..Default::default()
    };
    plain.begin_stroke();
    let written = plain
        .sculpt_dab(id, &brush, Vec3::new(7.5, 14.5, 7.5), Vec3::ZERO)
        .unwrap();
    plain.end_interaction();
    assert_eq!(written, None, "the dab removed nothing");
    assert_eq!(plain.enhancer_rebuilds(), 1, "the dab built the enhancer");
    assert_eq!(svo_of(&plain, fine_id), enhance(&stale, &settings).unwrap());
    assert_ne!(plain.content_key(), key, "the fine model changed");
    let mut from_key = RegionChain::default();
    assert!(
        upload_regions(&plain, &mut from_key).is_empty(),
        "no region to patch: upload it all"
    );
    let last = plain.changes().len() - 1;
    let mut cursor = ChangeCursor::default();
    let ChangesRead::Changes(entries) = plain.changes().read(&mut cursor) else {
        panic!("nothing dropped");
    };
    let rebuilt = entries.last().unwrap();
    assert_eq!(rebuilt.seq, last);
    assert_eq!(
        rebuilt.change,
        Change::Voxels {
            object: fine_id,
            region: None
        },
        "the rebuilt fine model"
    );
}

#[test]
fn enhancement_links_go_with_deleted_objects_and_come_back_on_undo() {
    let (mut ed, id) = bumpy_editor();
    let fine_id = enhance_linked(&mut ed, id, Default::default());
    ed.delete(fine_id).unwrap();
    assert!(ed.doc().enhancements.is_empty());
    assert!(ed.undo());
    assert_eq!(ed.doc().enhancement_of(id).unwrap().target, fine_id);
    // Undoing the enhancement removes the object and the link and shows the source again.
    assert!(ed.undo());
    assert!(ed.object(fine_id).is_none() && ed.doc().enhancements.is_empty());
    assert!(ed.object(id).unwrap().visible);
    // Bad settings are refused and change nothing.
    let bad = thicket_core::enhance::EnhanceSettings {
        factor: 3,
        ..Default::default()
    };
    let e = ed
        .add_enhancement(id, bad, VoxelModel::default(), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("power of two"), "{e}");
    assert!(ed.doc().enhancements.is_empty());
}

#[test]
fn tree_builder_parameters_are_stored_undone_and_dropped_by_a_preset() {
    let mut ed = Editor::default();
    let id = ed.add_object("Tree", ObjectKind::Krs(thicket_core::krs::presets::rock()));
    assert!(ed.tree_params(id).is_none());
    let mut params = thicket_core::krs::TreeParams::default();
    ed.build_tree(id, &params).unwrap();
    ed.end_interaction();
    assert_eq!(ed.tree_params(id), Some(&params));
    params.widths[0] *= 1.5;
    ed.build_tree(id, &params).unwrap();
    ed.end_interaction();
    assert_eq!(ed.tree_params(id), Some(&params));
    assert!(ed.undo());
    assert_eq!(
        ed.tree_params(id),
        Some(&thicket_core::krs::TreeParams::default())
    );
    assert!(ed.redo());
    ed.apply_krs_preset(id, "rock").unwrap();
    assert!(ed.tree_params(id).is_none(), "a preset is not a built tree");
    assert!(ed.undo());
    assert_eq!(ed.tree_params(id), Some(&params));
    // Deleting the object drops its parameters with it (and undo restores them).
    ed.delete(id).unwrap();
    assert!(ed.doc().tree_builders.is_empty());
    assert!(ed.undo());
    assert_eq!(ed.tree_params(id), Some(&params));
}

#[test]
fn a_builder_preset_brings_its_tree_parameters() {
    use thicket_core::krs::presets;
    let mut ed = Editor::default();
    let id = ed.add_object("Rock", ObjectKind::Krs(presets::rock()));
    ed.apply_krs_preset(id, "coral").unwrap();
    let params = presets::coral_params();
    assert_eq!(ed.tree_params(id), Some(&params));
    // The builder continues from the coral: rebuilding from its parameters changes nothing,
    // its distortion included (the builder makes kernels and mirrors only).
    let before = ed.krs(id).unwrap().clone();
    assert!(before.distortion.is_some());
    let steps = ed.history().undo_len();
    ed.build_tree(id, &params).unwrap();
    assert_eq!(ed.krs(id).unwrap(), &before);
    assert_eq!(ed.history().undo_len(), steps, "nothing to undo");
    assert!(ed.undo());
    assert!(ed.tree_params(id).is_none(), "the rock had none");
}

#[test]
fn an_added_krs_object_stands_beside_the_scene_with_its_builder_parameters_and_is_framed() {
    use thicket_core::krs::presets;
    let mut ed = Editor::default();
    // Into an empty scene: where the preset was made (nothing to avoid).
    let first = ed.add_krs_object("KRS tree", presets::tree(), presets::builder_params("tree"));
    let o = ed.object(first).unwrap();
    assert_eq!(o.transform.translation, Vec3::ZERO);
    assert_eq!(ed.tree_params(first), Some(&presets::tree_params()));
    let (alo, ahi) = o.world_bounds().unwrap();
    // A second one goes beside the first, not on top of it, at the same height.
    let camera = ed.doc().camera;
    let steps = ed.history().undo_len();
    let second = ed.add_krs_object("KRS bush", presets::bush(), presets::builder_params("bush"));
    assert_eq!(ed.history().undo_len(), steps + 1, "one undo step");
    assert_eq!(ed.selection, Some(Selection::Object(second)));
    let o = ed.object(second).unwrap();
    assert_eq!(o.transform.translation.y, 0.0);
    let (blo, bhi) = o.world_bounds().unwrap();
    let apart = (0..3).any(|a| bhi[a] < alo[a] || blo[a] > ahi[a]);
    assert!(apart, "the boxes overlap: {alo}..{ahi} and {blo}..{bhi}");
    assert_eq!(ed.tree_params(second), Some(&presets::bush_params()));
    // The camera frames the new object: it looks at its centre.
    assert_ne!(ed.doc().camera, camera);
    let target = ed.doc().camera.target;
    assert!((target - 0.5 * (blo + bhi)).length() < 1e-3, "{target}");
    // Undo takes the object and its parameters away together.
    assert!(ed.undo());
    assert!(ed.object(second).is_none());
    assert!(ed.tree_params(second).is_none());
    assert!(ed.tree_params(first).is_some());
    // A preset the builder does not make has no parameters. The rock has no bounding ball
    // (half-space kernels): its probed box goes beside the tree all the same.
    let rock = ed.add_krs_object("KRS rock", presets::rock(), presets::builder_params("rock"));
    assert!(ed.tree_params(rock).is_none());
    let o = ed.object(rock).unwrap();
    let k = o.krs_in_world().unwrap();
    let scene = thicket_core::krs::KrsScene { objects: vec![k] }
        .prepare()
        .unwrap();
    let (rlo, rhi) = thicket_core::io::gltf_export::krs_region(&scene.objects[0]).unwrap();
    let apart = (0..3).any(|a| rhi[a] < alo[a] || rlo[a] > ahi[a]);
    assert!(apart, "the rock {rlo}..{rhi} is on the tree {alo}..{ahi}");
}

#[test]
fn a_stretch_paint_stroke_is_one_step_erases_and_saves() {
    let (mut ed, id) = rigged_editor();
    let steps = ed.history().undo_len();
    ed.begin_stroke();
    // voxels(3): voxels (0..3, 0, 0). Two dabs of radius 1, overlapping at x = 1.
    assert_eq!(
        ed.paint_stretch(id, Vec3::new(0.5, 0.5, 0.5), 1.0, Some(2.0))
            .unwrap(),
        2
    );
    assert_eq!(
        ed.paint_stretch(id, Vec3::new(2.5, 0.5, 0.5), 1.0, Some(1.5))
            .unwrap(),
        2
    );
    ed.end_interaction();
    assert_eq!(ed.history().undo_len(), steps + 1, "one step per stroke");
    assert_eq!(ed.stretch_override(id, UVec3::new(0, 0, 0)), Some(2.0));
    assert_eq!(ed.stretch_override(id, UVec3::new(1, 0, 0)), Some(1.5));
    assert_eq!(ed.stretch_override(id, UVec3::new(2, 0, 0)), Some(1.5));
    // Painting the same value again changes nothing and makes no step.
    ed.begin_stroke();
    assert_eq!(
        ed.paint_stretch(id, Vec3::new(1.5, 0.5, 0.5), 0.6, Some(1.5))
            .unwrap(),
        0
    );
    assert_eq!(ed.history().undo_len(), steps + 1);

    // Saved and loaded with the project.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("figure.thicket.json");
    let mut doc = ed.doc().clone();
    // The bare test model has no skin weights; give it some so the file validates.
    if let ObjectKind::Voxels(v) = &mut doc.objects[0].kind {
        let mut svo = Svo::new(v.svo.depth(), true).unwrap();
        for (p, mut vox) in v.svo.leaves() {
            vox.skin = thicket_core::svo::Skin4::from_influences(&[(0, 1.0)]);
            svo.set(p, vox).unwrap();
        }
        v.svo = svo;
    }
    thicket_core::io::project::save(&doc, &path).unwrap();
    let back = thicket_core::io::project::load(&path).unwrap();
    let ObjectKind::Voxels(v) = &back.objects[0].kind else {
        panic!("voxels")
    };
    assert_eq!(v.rig.as_ref().unwrap().stretch_overrides.len(), 3);

    // Erase, then undo the erase and the paint: every override comes and goes exactly.
    ed.begin_stroke();
    assert_eq!(
        ed.paint_stretch(id, Vec3::new(0.5, 0.5, 0.5), 1.0, None)
            .unwrap(),
        2
    );
    assert_eq!(ed.stretch_override(id, UVec3::ZERO), None);
    assert!(ed.undo());
    assert_eq!(ed.stretch_override(id, UVec3::ZERO), Some(2.0));
    assert!(ed.undo());
    for x in 0..3 {
        assert_eq!(ed.stretch_override(id, UVec3::new(x, 0, 0)), None);
    }
    assert!(ed.redo());
    assert_eq!(ed.stretch_override(id, UVec3::new(1, 0, 0)), Some(1.5));
    // Clear removes all of them in one step; undo restores them.
    assert_eq!(ed.clear_stretch_overrides(id).unwrap(), 3);
    assert_eq!(ed.stretch_override(id, UVec3::new(0, 0, 0)), None);
    assert!(ed.undo());
    assert_eq!(ed.stretch_override(id, UVec3::new(0, 0, 0)), Some(2.0));
    // Refusals name the problem.
    let e = ed
        .paint_stretch(id, Vec3::ZERO, 1.0, Some(9.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("stretch override 9"), "{e}");
    let plain = ed.add_object("Plain", voxels(2));
    let e = ed
        .paint_stretch(plain, Vec3::ZERO, 1.0, Some(1.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("no skeleton"), "{e}");
    // The node a preview pixel shows maps back to its voxel.
    let ObjectKind::Voxels(v) = &ed.object(id).unwrap().kind else {
        panic!("voxels")
    };
    let depth = u64::from(v.svo.depth());
    let centers: Vec<Vec3> = (0..3)
        .filter_map(|i| ed.node_center(id, (depth << 32) | i))
        .collect();
    assert_eq!(centers.len(), 3);
    assert!(centers.contains(&Vec3::new(2.5, 0.5, 0.5)));
    assert_eq!(ed.node_center(id, (depth << 32) | 99), None);
}

#[test]
fn keys_store_the_posed_joint_in_the_clip_and_undo() {
    let (mut ed, id) = rigged_editor();
    // Pose the tip at t = 0.5 and key it: the clip gets rotation, translation and scale keys
    // and samples to the same pose with the override gone.
    let mut p = ed.rig(id).unwrap().playback;
    p.time_secs = 0.5;
    ed.set_playback(id, p).unwrap();
    ed.rotate_joint(id, 1, None, glam::Quat::from_rotation_z(0.8))
        .unwrap();
    ed.end_interaction();
    ed.scale_joint(id, 1, ed.joint_override(id, 1), Vec3::new(1.0, 2.0, 1.0))
        .unwrap();
    ed.end_interaction();
    let posed = ed.rig(id).unwrap().current_pose().locals[1];
    assert!((posed.scale - Vec3::new(1.0, 2.0, 1.0)).length() < 1e-6);
    let steps = ed.history().undo_len();
    ed.set_joint_key(id, 1).unwrap();
    assert_eq!(ed.history().undo_len(), steps + 1, "one step");
    assert!(ed.joint_override(id, 1).is_none(), "folded into the keys");
    let keyed = ed.rig(id).unwrap().current_pose().locals[1];
    assert!(keyed.rotation.angle_between(posed.rotation) < 1e-4);
    assert!((keyed.scale - posed.scale).length() < 1e-5);
    assert!((keyed.translation - posed.translation).length() < 1e-5);
    assert_eq!(ed.joint_key_times(id, 1), vec![0.5]);
    // Keying again at the same time replaces; at another time past the end extends the clip.
    ed.set_joint_key(id, 1).unwrap();
    assert_eq!(ed.joint_key_times(id, 1), vec![0.5]);
    // (Looping, 1.5 s would wrap to 0.5 s: hold the last frame instead.)
    p.time_secs = 1.5;
    p.wrap = thicket_core::skin::Wrap::Clamp;
    ed.set_playback(id, p).unwrap();
    ed.set_joint_key(id, 1).unwrap();
    assert_eq!(ed.joint_key_times(id, 1), vec![0.5, 1.5]);
    assert!((ed.rig(id).unwrap().clips[0].duration_secs - 1.5).abs() < 1e-6);
    assert!(ed.rig(id).unwrap().validate().is_ok());
    // Delete the key at 1.5: the clip keeps the length it grew to (as the dope sheet's
    // deletes do; the artist sets a length in the Rig section).
    assert!(ed.delete_joint_key(id, 1).unwrap());
    assert_eq!(ed.joint_key_times(id, 1), vec![0.5]);
    assert!((ed.rig(id).unwrap().clips[0].duration_secs - 1.5).abs() < 1e-6);
    assert!(
        !ed.delete_joint_key(id, 1).unwrap(),
        "no key at 1.5 any more"
    );
    assert!(ed.undo());
    assert_eq!(ed.joint_key_times(id, 1), vec![0.5, 1.5]);
    assert!(ed.undo() && ed.undo() && ed.undo());
    assert!(ed.joint_key_times(id, 1).is_empty());
    assert!(ed.joint_override(id, 1).is_some(), "the override is back");

    // On the rest pose a key makes a clip "Pose" and plays it; undo removes it and the
    // playhead leaves the missing clip.
    p.clip = None;
    p.time_secs = 0.0;
    ed.set_playback(id, p).unwrap();
    ed.set_joint_key(id, 0).unwrap();
    let rig = ed.rig(id).unwrap();
    assert_eq!(rig.clips.len(), 2);
    assert_eq!(rig.clips[1].name, "Pose");
    assert_eq!(rig.playback.clip, Some(1));
    assert!(ed.undo());
    assert_eq!(ed.rig(id).unwrap().clips.len(), 1);
    assert_eq!(ed.rig(id).unwrap().playback.clip, None);
    // Bad scale factors are refused.
    assert!(
        ed.scale_joint(id, 1, None, Vec3::new(0.0, 1.0, 1.0))
            .is_err()
    );
    assert!(ed.scale_joint(id, 1, None, Vec3::NAN).is_err());
}

// ---------------------------------------------------------------- voxel tools

use thicket_core::sculpt::model_ops::{Anchor, InitialFill};
use thicket_core::sculpt::select::SelTransform;
use thicket_core::sculpt::shapes::{Ink, Mirror, ShapeOp};
use thicket_core::svo::decode_normal;

const RED: Ink = Ink {
    color: [220, 30, 30, 255],
    material: 0,
};

fn new_model_editor(size: u32, fill: InitialFill) -> (Editor, u64) {
    let mut ed = Editor::default();
    let id = ed
        .add_voxel_model(&NewModelSpec {
            size: UVec3::splat(size),
            fill,
            ..NewModelSpec::default()
        })
        .unwrap();
    (ed, id)
}

#[test]
fn a_new_model_is_refused_beyond_the_octree_limit_and_for_huge_fills() {
    let mut ed = Editor::default();
    let too_wide = NewModelSpec {
        size: UVec3::new(MAX_EXTENT + 1, 4, 4),
        ..NewModelSpec::default()
    };
    let e = ed.add_voxel_model(&too_wide).unwrap_err().to_string();
    assert!(e.contains("2097152") && e.contains("2^21"), "{e}");
    let zero = NewModelSpec {
        size: UVec3::new(0, 4, 4),
        ..NewModelSpec::default()
    };
    assert!(ed.add_voxel_model(&zero).is_err());
    let huge_fill = NewModelSpec {
        size: UVec3::splat(1024),
        fill: InitialFill::SolidBox,
        ..NewModelSpec::default()
    };
    let e = ed.add_voxel_model(&huge_fill).unwrap_err().to_string();
    assert!(e.contains("1073741824 voxels"), "{e}");
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        let spec = NewModelSpec {
            voxel_size: bad,
            ..NewModelSpec::default()
        };
        assert!(ed.add_voxel_model(&spec).is_err(), "voxel size {bad}");
    }
    assert!(ed.doc().objects.is_empty(), "nothing was added");
    // The widest model the octree holds is accepted when it starts empty.
    let widest = NewModelSpec {
        size: UVec3::new(MAX_EXTENT, 1, 1),
        voxel_size: 0.001,
        ..NewModelSpec::default()
    };
    let id = ed.add_voxel_model(&widest).unwrap();
    assert_eq!(ed.volume_of(id), Some(UVec3::new(MAX_EXTENT, 1, 1)));
    // A box at the far end of that volume, hanging out of it, is clipped and says so.
    let o = ed
        .shape_box(
            id,
            IVec3::new(MAX_EXTENT as i32 - 2, 0, 0),
            IVec3::new(MAX_EXTENT as i32 + 5, 3, 0),
            ShapeOp::Add,
            RED,
            Mirror::default(),
        )
        .unwrap();
    assert_eq!(svo_of(&ed, id).leaf_count(), 2);
    assert!(
        o.clipped > 0 && o.message("Box").contains("clipped"),
        "{o:?}"
    );
}

#[test]
fn a_slab_model_stands_on_the_ground_and_every_tool_edit_is_one_undo_step() {
    let (mut ed, id) = new_model_editor(16, InitialFill::GroundSlab { height: 2 });
    let start = svo_of(&ed, id);
    assert_eq!(start.leaf_count(), 16 * 16 * 2);
    let o = ed.object(id).unwrap();
    let (lo, hi) = o.world_bounds().unwrap();
    assert!(lo.y.abs() < 1e-6 && (hi.y - 0.2).abs() < 1e-5, "{lo} {hi}");
    let steps = ed.history().undo_len();
    let mut chain = RegionChain::from_end(ed.changes());
    let box_edit = ed
        .shape_box(
            id,
            IVec3::new(2, 2, 2),
            IVec3::new(4, 5, 6),
            ShapeOp::Add,
            RED,
            Mirror::default(),
        )
        .unwrap();
    assert_eq!(svo_of(&ed, id).leaf_count(), 512 + 3 * 4 * 5);
    assert_eq!(ed.history().undo_len(), steps + 1);
    // The renderer is told the region, not the whole model.
    let region = upload_regions(&ed, &mut chain)[0];
    assert_eq!(region.object, id);
    assert!(region.lo.cmple(UVec3::new(2, 2, 2)).all());
    let (lo, hi) = box_edit.changed.expect("a changed box");
    assert!(lo.cmple(UVec3::new(2, 2, 2)).all() && hi.cmpge(UVec3::new(4, 5, 6)).all());
    // Mirrored X line: both halves.
    ed.shape_cells(
        id,
        &[IVec3::new(0, 2, 8), IVec3::new(1, 2, 8)],
        ShapeOp::Add,
        RED,
        Mirror {
            axes: [true, false, false],
        },
        false,
    )
    .unwrap();
    for x in [0, 1, 14, 15] {
        assert!(
            svo_of(&ed, id).get(UVec3::new(x, 2, 8)).is_some(),
            "x = {x}"
        );
    }
    // Flood fill paint of the slab (one colour, connected) recolours all of it.
    ed.flood_fill(
        id,
        UVec3::new(10, 1, 10),
        IVec3::Y,
        None,
        ShapeOp::Paint,
        RED,
    )
    .unwrap();
    let reds = svo_of(&ed, id)
        .leaves()
        .iter()
        .filter(|(_, v)| v.color == RED.color)
        .count();
    assert_eq!(reds as u64, svo_of(&ed, id).leaf_count());
    // Extrude the slab's top face (now one colour with the box's) in by one.
    let before = svo_of(&ed, id).leaf_count();
    ed.extrude_face(id, UVec3::new(10, 1, 10), IVec3::Y, -1)
        .unwrap();
    assert!(svo_of(&ed, id).leaf_count() < before);
    for _ in 0..4 {
        assert!(ed.undo());
    }
    assert_eq!(
        svo_of(&ed, id),
        start,
        "four undos restore the slab exactly"
    );
}

#[test]
fn copy_paste_move_rotate_and_refused_pastes() {
    let (mut ed, id) = new_model_editor(32, InitialFill::Empty);
    ed.shape_box(
        id,
        IVec3::new(1, 0, 1),
        IVec3::new(3, 1, 4),
        ShapeOp::Add,
        RED,
        Mirror::default(),
    )
    .unwrap();
    let n = ed.select_all_voxels(id).unwrap();
    assert_eq!(n, 3 * 2 * 4);
    assert_eq!(ed.copy_voxels().unwrap(), 24);
    ed.start_paste(id).unwrap();
    ed.move_floating(IVec3::new(10, 0, 0));
    ed.commit_floating().unwrap();
    let svo = svo_of(&ed, id);
    assert_eq!(svo.leaf_count(), 48);
    assert!(svo.get(UVec3::new(11, 0, 1)).is_some() && svo.get(UVec3::new(13, 1, 4)).is_some());
    // The pasted copy is selected; move it up, rotate it, all undoable.
    assert_eq!(ed.voxel_selection().unwrap().cells.len(), 24);
    ed.transform_selected_voxels(SelTransform::Move(IVec3::Y))
        .unwrap();
    assert!(svo_of(&ed, id).get(UVec3::new(11, 2, 1)).is_some());
    let before_turns = svo_of(&ed, id);
    for _ in 0..4 {
        ed.transform_selected_voxels(SelTransform::Rotate {
            axis: 1,
            quarter_turns: 1,
        })
        .unwrap();
    }
    // Four turns give back every cell and colour; normals (re-quantised each turn and
    // re-estimated beside the moving cells) come back to within a few degrees.
    let (after, before) = (svo_of(&ed, id).leaves(), before_turns.leaves());
    let cells_and_colours =
        |l: &[(UVec3, Voxel)]| l.iter().map(|(c, v)| (*c, v.color)).collect::<Vec<_>>();
    assert_eq!(
        cells_and_colours(&after),
        cells_and_colours(&before),
        "four quarter turns"
    );
    for ((c, a), (_, b)) in after.iter().zip(&before) {
        let (na, nb) = (decode_normal(a.normal), decode_normal(b.normal));
        assert!(na.dot(nb) > 0.99, "normal at {c} turned from {nb} to {na}");
    }
    // A paste hanging out of the volume is clipped and counted.
    ed.start_paste(id).unwrap();
    ed.move_floating(IVec3::new(30, 0, 0));
    let o = ed.commit_floating().unwrap();
    assert!(o.clipped > 0, "{o:?}");
    // A model of another voxel size refuses the paste, and nothing changes.
    let other = ed
        .add_voxel_model(&NewModelSpec {
            voxel_size: 0.5,
            ..NewModelSpec::default()
        })
        .unwrap();
    let e = ed.start_paste(other).unwrap_err().to_string();
    assert!(e.contains("voxel size"), "{e}");
    assert!(ed.floating().is_none());
    assert!(svo_of(&ed, other).is_empty());
    // Selection to a new object keeps the voxels' place in the world.
    ed.select_all_voxels(id).unwrap();
    let part = ed.selection_to_new_object().unwrap();
    let (a, b) = (
        ed.object(id).unwrap().world_bounds().unwrap(),
        ed.object(part).unwrap().world_bounds().unwrap(),
    );
    assert!(
        (a.0 - b.0).length() < 1e-5 && (a.1 - b.1).length() < 1e-5,
        "{a:?} {b:?}"
    );
}

#[test]
fn resize_canvas_keeps_voxels_in_the_world_and_undoes() {
    let (mut ed, id) = new_model_editor(8, InitialFill::SolidBox);
    let before = ed.object(id).unwrap().world_bounds().unwrap();
    let dropped = ed
        .resize_canvas(
            id,
            UVec3::new(16, 8, 16),
            [Anchor::Center, Anchor::Min, Anchor::Center],
        )
        .unwrap();
    assert_eq!(dropped, 0);
    assert_eq!(ed.volume_of(id), Some(UVec3::new(16, 8, 16)));
    let after = ed.object(id).unwrap().world_bounds().unwrap();
    assert!((before.0 - after.0).length() < 1e-5, "{before:?} {after:?}");
    assert_eq!(svo_of(&ed, id).leaf_count(), 512);
    // Shrinking drops what falls outside.
    let dropped = ed
        .resize_canvas(
            id,
            UVec3::new(16, 4, 16),
            [Anchor::Min, Anchor::Min, Anchor::Min],
        )
        .unwrap();
    assert_eq!(dropped, 256);
    assert!(ed.undo() && ed.undo());
    assert_eq!(ed.volume_of(id), Some(UVec3::splat(8)));
    assert_eq!(svo_of(&ed, id).leaf_count(), 512);
    // Hollow keeps a one-voxel shell of the 8³ cube: 8³ − 6³.
    ed.model_op(id, ModelOp::Hollow(1)).unwrap();
    assert_eq!(svo_of(&ed, id).leaf_count(), 512 - 216);
    ed.model_op(id, ModelOp::FillInterior(None)).unwrap();
    assert_eq!(svo_of(&ed, id).leaf_count(), 512);
    assert!(ed.model_op(id, ModelOp::Hollow(0)).is_err());
}

#[test]
fn a_box_on_an_enhanced_model_keeps_its_enhancement_equal_to_a_fresh_one() {
    use thicket_core::enhance::{EnhanceSettings, enhance};
    let (mut ed, id) = bumpy_editor();
    let settings = EnhanceSettings {
        factor: 4,
        ..EnhanceSettings::default()
    };
    let fine_id = enhance_linked(&mut ed, id, settings.clone());
    ed.shape_box(
        id,
        IVec3::new(3, 7, 3),
        IVec3::new(6, 8, 5),
        ShapeOp::Add,
        RED,
        Mirror::default(),
    )
    .unwrap();
    ed.flood_fill(
        id,
        UVec3::new(5, 7, 4),
        IVec3::Y,
        Some(1),
        ShapeOp::Paint,
        Ink {
            color: [10, 200, 10, 255],
            material: 0,
        },
    )
    .unwrap();
    let fresh = enhance(&svo_of(&ed, id), &settings).unwrap();
    assert_eq!(svo_of(&ed, fine_id), fresh);
    let u = ed.last_enhance_update().expect("an incremental update");
    assert!(u.source == id && !u.rebuilt);
    // The fine model cannot be edited directly.
    let e = ed
        .shape_box(
            fine_id,
            IVec3::ZERO,
            IVec3::ONE,
            ShapeOp::Add,
            RED,
            Mirror::default(),
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("detail enhancement"), "{e}");
}

/// A frame sequence of three frames (1, 2 and 3 voxels in a row), showing frame 0.
fn frame_sequence() -> ObjectKind {
    use thicket_core::scene::{FrameSequence, VoxelFrame};
    let row = |n: u32| {
        let ObjectKind::Voxels(v) = voxels(n) else {
            unreachable!("voxels() makes a voxel model")
        };
        v.svo
    };
    ObjectKind::Voxels(VoxelModel {
        svo: row(1),
        frames: Some(FrameSequence {
            frames: vec![
                VoxelFrame::default(),
                VoxelFrame {
                    svo: row(2),
                    origin: Vec3::ZERO,
                },
                VoxelFrame {
                    svo: row(3),
                    origin: Vec3::ZERO,
                },
            ],
            ..FrameSequence::default()
        }),
        ..VoxelModel::default()
    })
}

fn frame_counts(ed: &Editor, id: u64) -> Vec<u64> {
    let ObjectKind::Voxels(v) = &ed.object(id).unwrap().kind else {
        panic!("voxels")
    };
    (0..v.frame_count())
        .map(|i| v.frame(i).unwrap().0.leaf_count())
        .collect()
}

#[test]
fn the_timeline_plays_frame_sequences_and_undo_writes_the_frame_it_was_made_on() {
    let mut ed = Editor::default();
    let id = ed.add_object("walk", frame_sequence());
    ed.end_interaction();
    let saved_dirty = ed.is_dirty();
    // Scrubbing shows the frame at the playhead (0.1 s each) and gives renderers a new key.
    let key = ed.content_key();
    ed.set_frame_time(id, 0.15).unwrap();
    assert_eq!(ed.frames(id).unwrap().shown, 1);
    assert_eq!(svo_of(&ed, id).leaf_count(), 2);
    assert_ne!(ed.content_key(), key);
    assert_eq!(ed.is_dirty(), saved_dirty, "scrubbing is not editing");
    assert!(ed.set_frame_time(id, f32::NAN).is_err());
    let still = ed.add_object("still", voxels(2));
    assert!(ed.set_frame_time(still, 0.1).is_err());

    // An edit of frame 1, then the playhead moves to frame 2: undo puts frame 1 back in view
    // and removes the voxels there, leaving frame 2 alone.
    ed.shape_box(
        id,
        IVec3::new(0, 1, 0),
        IVec3::new(1, 1, 0),
        ShapeOp::Add,
        RED,
        Mirror::default(),
    )
    .unwrap();
    ed.end_interaction();
    assert_eq!(frame_counts(&ed, id), [1, 4, 3]);
    ed.set_frame_time(id, 0.25).unwrap();
    assert_eq!(ed.frames(id).unwrap().shown, 2);
    assert!(ed.undo());
    assert_eq!(ed.frames(id).unwrap().shown, 1);
    assert_eq!(frame_counts(&ed, id), [1, 2, 3]);
    assert!(ed.redo());
    assert_eq!(frame_counts(&ed, id), [1, 4, 3]);
    ed.doc().validate().unwrap();
}

#[test]
fn imported_lights_are_added_one_undo_step_each_and_bad_ones_skipped() {
    let mut ed = Editor::default();
    let sun = ed.doc().lights[0].clone();
    let key = Light {
        name: "Key".into(),
        casts_shadows: false,
        ..ed.new_light()
    };
    let bad = Light {
        intensity: f32::NAN,
        ..key.clone()
    };
    let selection = ed.selection;
    assert_eq!(ed.import_lights(vec![key.clone(), bad]), 1);
    assert_eq!(ed.doc().lights, vec![sun.clone(), key]);
    assert_eq!(ed.selection, selection, "the selection stays on the import");
    ed.undo();
    assert_eq!(ed.doc().lights, vec![sun]);
}

#[test]
fn a_vox_export_names_what_it_leaves_out_and_why() {
    use thicket_core::scene::{MeshObject, Object};
    let mut rock = Object {
        name: "Rock".into(),
        kind: ObjectKind::Mesh(MeshObject::default()),
        ..Object::default()
    };
    rock.visible = true;
    let hidden = Object {
        name: "Old".into(),
        kind: voxels(2),
        visible: false,
        ..Object::default()
    };
    let objects = vec![rock, hidden];
    let text = super::jobs::vox_left_out(&objects, &["Rock".into(), "Old".into()]);
    assert_eq!(
        text,
        "; left out: \"Rock\" (a mesh: .vox holds voxels only; Model > Voxelize mesh makes a voxel model of it), \"Old\" (hidden)"
    );
    assert_eq!(super::jobs::vox_left_out(&objects, &[]), "");
}

/// Rigid per-object animation: an unrigged object keyed at two times moves between them on
/// its own playhead; a rigged one follows its rig's playhead; keys and deletes are one undo
/// step each, and scrubbing is not an edit.
#[test]
fn object_transform_keys_move_the_object_on_its_clock() {
    use thicket_core::skin::Wrap;
    let mut ed = Editor::default();
    let id = ed.add_object("Box", voxels(3));
    assert!(ed.motion(id).is_none());
    let steps = ed.history().undo_len();
    ed.set_object_key(id).unwrap();
    assert_eq!(ed.object_key_times(id), [0.0]);
    assert_eq!(ed.history().undo_len(), steps + 1);
    // To 2 s, moved and turned, keyed there.
    ed.set_motion_time(id, 2.0, Wrap::Clamp).unwrap();
    let moved = Transform {
        translation: Vec3::new(4.0, 0.0, -2.0),
        rotation: glam::Quat::from_rotation_y(1.0),
        ..Transform::default()
    };
    ed.set_transform(id, moved).unwrap();
    ed.set_object_key(id).unwrap();
    assert_eq!(ed.object_key_times(id), [0.0, 2.0]);
    // Scrubbing moves the object and is not an edit.
    let steps = ed.history().undo_len();
    ed.set_motion_time(id, 1.0, Wrap::Clamp).unwrap();
    assert_eq!(ed.history().undo_len(), steps);
    let mid = ed.object(id).unwrap().transform;
    assert!((mid.translation - Vec3::new(2.0, 0.0, -1.0)).length() < 1e-5);
    assert!(mid.rotation.angle_between(glam::Quat::from_rotation_y(0.5)) < 1e-4);
    ed.set_motion_time(id, 0.0, Wrap::Clamp).unwrap();
    assert!(ed.object(id).unwrap().transform.translation.length() < 1e-6);
    // Delete the key at 0: one key left, which holds; deleting it too removes the motion.
    assert!(ed.delete_object_key(id).unwrap());
    assert_eq!(ed.object_key_times(id), [2.0]);
    ed.set_motion_time(id, 2.0, Wrap::Clamp).unwrap();
    assert!(ed.delete_object_key(id).unwrap());
    assert!(ed.motion(id).is_none());
    assert!(!ed.delete_object_key(id).unwrap(), "nothing left to delete");
    assert!(ed.undo() && ed.undo());
    assert_eq!(ed.object_key_times(id), [0.0, 2.0]);
    assert!(ed.doc().validate().is_ok());

    // A rigged model's keys follow its rig's playhead.
    let (mut ed, id) = rigged_editor();
    let mut p = ed.rig(id).unwrap().playback;
    p.wrap = Wrap::Clamp;
    p.time_secs = 0.0;
    ed.set_playback(id, p).unwrap();
    ed.set_object_key(id).unwrap();
    p.time_secs = 1.0;
    ed.set_playback(id, p).unwrap();
    ed.set_transform(
        id,
        Transform {
            translation: Vec3::X * 3.0,
            ..Transform::default()
        },
    )
    .unwrap();
    ed.set_object_key(id).unwrap();
    assert_eq!(ed.object_key_times(id), [0.0, 1.0]);
    p.time_secs = 0.5;
    ed.set_playback(id, p).unwrap();
    let t = ed.object(id).unwrap().transform.translation;
    assert!((t - Vec3::X * 1.5).length() < 1e-5, "{t}");
}

#[test]
fn replacing_a_palette_colour_is_one_named_undo_step() {
    let mut ed = Editor::default();
    let id = ed.add_object("A", voxels(3));
    let from = [200, 100, 50, 255];
    let to = [10, 20, 30, 255];
    ed.set_palette(id, vec![[1, 2, 3, 255], from]).unwrap();
    let before = ed.doc().objects.clone();
    let steps = ed.history().undo_len();
    ed.replace_color(id, from, to).unwrap();
    let ObjectKind::Voxels(v) = &ed.object(id).unwrap().kind else {
        unreachable!()
    };
    assert_eq!(
        v.palette,
        vec![[1, 2, 3, 255], to],
        "the palette entry follows"
    );
    assert_eq!(v.svo.leaves()[0].1.color, to);
    assert_eq!(ed.history().undo_len(), steps + 1, "one step");
    assert_eq!(ed.history().labels().0.last(), Some(&"Replace colour"));
    let after = ed.doc().objects.clone();
    assert!(ed.undo());
    assert_eq!(
        ed.doc().objects,
        before,
        "one undo restores voxels and palette"
    );
    assert!(ed.redo());
    assert_eq!(ed.doc().objects, after);
    assert_eq!(
        ed.history().labels().0,
        vec!["Add A", "Set palette", "Replace colour"]
    );
}

#[test]
fn history_names_each_step_and_goes_to_any_of_them() {
    let (mut ed, id) = slab_editor();
    let brush = thicket_core::sculpt::Brush {
        op: thicket_core::sculpt::BrushOp::Remove,
        radius: 1.5,
        ..Default::default()
    };
    let start = ed.history().undo_len();
    let at_start = ed.doc().objects.clone();
    // A stroke of three dabs is one step, named once.
    ed.begin_stroke();
    for x in 0..3 {
        ed.sculpt_dab(id, &brush, Vec3::new(x as f32 + 0.5, 3.5, 3.5), Vec3::ZERO)
            .unwrap();
    }
    ed.end_interaction();
    let name = ed.object(id).unwrap().name.clone();
    ed.rename(id, "Ground").unwrap();
    ed.set_visible(id, false).unwrap();
    let (labels, done) = ed.history().labels();
    let labels: Vec<String> = labels.into_iter().map(str::to_owned).collect();
    assert_eq!(
        labels[start..].to_vec(),
        vec![
            "Brush stroke".to_owned(),
            format!("Rename {name} to Ground"),
            "Hide Ground".to_owned()
        ]
    );
    assert_eq!(done, labels.len());
    let all = ed.doc().objects.clone();
    // Going to the step before the stroke is three undos; the undone steps stay listed.
    assert_eq!(ed.go_to_step(start), 3);
    assert_eq!(ed.doc().objects, at_start);
    assert_eq!(ed.history().labels().0.len(), labels.len());
    assert_eq!(ed.history().redo_len(), 3);
    assert_eq!(ed.go_to_step(start + 3), 3);
    assert_eq!(ed.doc().objects, all, "and forward again");
    assert_eq!(
        ed.go_to_step(usize::MAX),
        0,
        "past the end: nothing to redo"
    );
}

#[test]
fn binding_weights_is_named_in_the_history() {
    let (mut ed, id) = slab_editor();
    let hip = ed
        .add_joint(id, None, Vec3::new(4.0, 3.0, 4.0), Some("hip"))
        .unwrap();
    ed.add_joint(id, Some(hip), Vec3::new(4.0, 1.0, 7.0), Some("leg"))
        .unwrap();
    ed.bind_now(id, thicket_core::skin::BindMethod::Geodesic)
        .unwrap();
    assert_eq!(ed.history().labels().0.last(), Some(&"Bind weights"));
}

#[test]
fn a_stroke_delta_on_another_frame_starts_a_step_instead_of_being_dropped() {
    // A stroke is one step while its dabs write one model's one frame; a dab on another frame
    // (the playhead moved mid-stroke) keeps its own old values in a step of its own.
    let delta = |x: u32| thicket_core::svo::UndoDelta {
        entries: vec![(UVec3::new(x, 0, 0), None)],
    };
    let mut h = History::default();
    let key = Some(MergeKey::Stroke(1));
    let voxels = |x: u32, frame: usize| Edit::Voxels {
        id: 1,
        delta: delta(x),
        frame,
    };
    h.push_named(voxels(0, 0), key, "Brush stroke".into());
    h.push_named(voxels(1, 0), key, "Brush stroke".into());
    assert_eq!(h.undo_len(), 1, "same frame: one step");
    h.push_named(voxels(2, 3), key, "Brush stroke".into());
    assert_eq!(h.undo_len(), 2, "another frame: a step of its own");
    assert_eq!(
        h.next_undo().map(Edit::voxel_boxes),
        Some(vec![(1, UVec3::new(2, 0, 0), UVec3::new(2, 0, 0))])
    );
    // A snapshot edit of a drag still merges by keeping the first revert.
    let mut h = History::default();
    let pose = Some(MergeKey::Pose(1));
    for _ in 0..3 {
        h.push_named(
            Edit::SetPose {
                id: 1,
                overrides: Vec::new(),
            },
            pose,
            "Pose".into(),
        );
    }
    assert_eq!(h.undo_len(), 1);
}

#[test]
fn undoing_an_edit_of_another_frame_keeps_the_enhancement_equal_to_a_fresh_one() {
    let mut ed = Editor::default();
    let id = ed.add_object("walk", frame_sequence());
    ed.end_interaction();
    let settings = thicket_core::enhance::EnhanceSettings::default();
    let fine_id = enhance_linked(&mut ed, id, settings.clone());
    let fresh = |ed: &Editor| {
        let ObjectKind::Voxels(v) = &ed.object(id).unwrap().kind else {
            panic!("voxels")
        };
        v.enhanced(&settings, thicket_core::enhance::Control::default())
            .unwrap()
            .0
            .svo
    };
    // An edit of frame 1, then the playhead moves to frame 2, where another edit builds the
    // enhancer from frame 2.
    ed.set_frame_time(id, 0.15).unwrap();
    ed.shape_box(
        id,
        IVec3::new(0, 1, 0),
        IVec3::new(1, 1, 0),
        ShapeOp::Add,
        RED,
        Mirror::default(),
    )
    .unwrap();
    ed.end_interaction();
    assert_eq!(svo_of(&ed, fine_id), fresh(&ed));
    ed.set_frame_time(id, 0.25).unwrap();
    ed.shape_box(
        id,
        IVec3::new(0, 3, 0),
        IVec3::new(0, 3, 0),
        ShapeOp::Add,
        RED,
        Mirror::default(),
    )
    .unwrap();
    ed.end_interaction();
    assert_eq!(svo_of(&ed, fine_id), fresh(&ed));
    // Undo twice: the second undo shows frame 1 again; the enhancement follows frame 1.
    assert!(ed.undo());
    assert_eq!(svo_of(&ed, fine_id), fresh(&ed), "frame 2's edit undone");
    assert!(ed.undo());
    assert_eq!(ed.frames(id).unwrap().shown, 1);
    assert_eq!(
        svo_of(&ed, fine_id),
        fresh(&ed),
        "frame 1's edit undone, with frame 1 shown again"
    );
    assert!(ed.redo());
    assert_eq!(svo_of(&ed, fine_id), fresh(&ed), "frame 1's edit redone");
}

#[test]
fn a_tool_that_refuses_says_why_and_changes_nothing() {
    // A box of 400³ cells is more than one undo step may write: the tool refuses, and the
    // editor passes its reason on (it used to report an edit of no voxels).
    let (mut ed, id) = new_model_editor(512, InitialFill::Empty);
    let before = svo_of(&ed, id);
    let e = ed
        .shape_box(
            id,
            IVec3::ZERO,
            IVec3::splat(399),
            ShapeOp::Add,
            RED,
            Mirror::default(),
        )
        .expect_err("refused");
    let text = e.to_string();
    assert!(
        text.contains("64000000") && text.contains("edit a smaller region"),
        "{text}"
    );
    assert!(svo_of(&ed, id) == before);
}

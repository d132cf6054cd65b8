//! Rigging a model made in the editor: joints placed at mid-thickness, chains, branches,
//! mirrors, templates, binding, weight painting and clips, each one undo step.

use glam::{UVec3, Vec3};
use thicket_core::scene::{ObjectKind, VoxelModel};
use thicket_core::skin::BindMethod;
use thicket_core::svo::{Svo, Voxel};

use super::*;

/// A figure of three boxes (a body on two legs with a gap between them), 1-unit voxels at the
/// origin, no transform.
fn figure(ed: &mut Editor) -> u64 {
    let mut voxels = Vec::new();
    let mut put = |lo: [u32; 3], hi: [u32; 3]| {
        for z in lo[2]..hi[2] {
            for y in lo[1]..hi[1] {
                for x in lo[0]..hi[0] {
                    voxels.push((UVec3::new(x, y, z), Voxel::new([180, 90, 60, 255], Vec3::Y)));
                }
            }
        }
    };
    put([0, 0, 0], [4, 12, 4]); // leg R
    put([6, 0, 0], [10, 12, 4]); // leg L
    put([0, 12, 0], [10, 24, 4]); // body
    let svo = Svo::from_voxels(5, false, voxels).unwrap();
    ed.add_object(
        "figure",
        ObjectKind::Voxels(VoxelModel {
            svo,
            ..VoxelModel::default()
        }),
    )
}

/// The figure with a hip in the body and a joint at the top of the right leg, bound
/// geodesically: (editor, model, hip, leg).
fn bound_hip_and_leg() -> (Editor, u64, usize, usize) {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    let hip = ed
        .add_joint(id, None, Vec3::new(5.0, 13.0, 2.0), Some("hip"))
        .unwrap();
    let leg = ed
        .add_joint(id, Some(hip), Vec3::new(2.0, 11.0, 2.0), Some("leg.R"))
        .unwrap();
    ed.bind_now(id, BindMethod::Geodesic).unwrap();
    (ed, id, hip, leg)
}

fn model(ed: &Editor, id: u64) -> &VoxelModel {
    match &ed.object(id).unwrap().kind {
        ObjectKind::Voxels(v) => v,
        _ => panic!("a voxel model"),
    }
}

#[test]
fn a_click_places_a_joint_at_the_middle_of_the_thickness() {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    // A ray along -Z through the body at x = 5, y = 18: enters at z = 4, leaves at z = 0.
    let p = ed
        .mid_thickness(id, Vec3::new(5.0, 18.0, 50.0), Vec3::NEG_Z)
        .unwrap();
    assert!(p.abs_diff_eq(Vec3::new(5.0, 18.0, 2.0), 1e-3), "{p}");
    // Through the gap between the legs nothing is hit; a slanted ray through the right leg
    // takes the middle of the run it crosses.
    assert!(
        ed.mid_thickness(id, Vec3::new(5.0, 6.0, 50.0), Vec3::NEG_Z)
            .is_none()
    );
    let p = ed
        .mid_thickness(id, Vec3::new(-10.0, 6.0, 2.0), Vec3::X)
        .unwrap();
    assert!(p.abs_diff_eq(Vec3::new(2.0, 6.0, 2.0), 1e-3), "{p}");
    // The object's transform is honoured: moved by +100 in x, the same voxels answer.
    let mut t = ed.object(id).unwrap().transform;
    t.translation.x = 100.0;
    ed.set_transform(id, t).unwrap();
    let p = ed
        .mid_thickness(id, Vec3::new(105.0, 18.0, 50.0), Vec3::NEG_Z)
        .unwrap();
    assert!(p.abs_diff_eq(Vec3::new(5.0, 18.0, 2.0), 1e-3), "{p}");
}

#[test]
fn chains_branches_renames_and_deletes_are_single_undo_steps() {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    let plain = ed.doc().clone();
    let hip = ed
        .add_joint(id, None, Vec3::new(5.0, 12.0, 2.0), None)
        .unwrap();
    let knee = ed
        .add_joint(id, Some(hip), Vec3::new(8.0, 6.0, 2.0), None)
        .unwrap();
    let foot = ed
        .add_joint(id, Some(knee), Vec3::new(8.0, 1.0, 2.0), None)
        .unwrap();
    let spine = ed
        .add_joint(id, Some(hip), Vec3::new(5.0, 20.0, 2.0), None)
        .unwrap();
    let spec = ed.skeleton_spec(id).unwrap();
    let names: Vec<&str> = spec.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(names, ["root", "bone", "bone.001", "bone.002"]);
    assert_eq!(spec.joints[spine].parent.as_deref(), Some("root"));
    assert_eq!(spec.joints[foot].parent.as_deref(), Some("bone"));

    ed.rename_joint(id, knee, "shin.L").unwrap();
    assert_eq!(
        ed.skeleton_spec(id).unwrap().joints[foot].parent.as_deref(),
        Some("shin.L"),
        "children follow a rename"
    );
    // A joint under its own descendant is refused, and changes nothing.
    let before = ed.doc().clone();
    let err = ed.reparent_joint(id, hip, Some(foot)).unwrap_err();
    assert!(err.to_string().contains("cycle"), "{err}");
    assert_eq!(ed.doc(), &before);
    // A duplicate name is refused.
    assert!(ed.rename_joint(id, spine, "shin.L").is_err());
    // Delete the knee: the foot hangs from the hip.
    ed.delete_joint(id, knee).unwrap();
    let spec = ed.skeleton_spec(id).unwrap();
    assert_eq!(spec.joints.len(), 3);
    let foot = spec
        .joints
        .iter()
        .position(|j| j.name == "bone.001")
        .unwrap();
    assert_eq!(spec.joints[foot].parent.as_deref(), Some("root"));
    // Six steps (four joints, a rename, a delete) undo to the plain model.
    for _ in 0..6 {
        assert!(ed.undo());
    }
    assert_eq!(ed.doc(), &plain);
    assert!(model(&ed, id).rig.is_none());
}

#[test]
fn a_mirrored_chain_lands_across_the_model_with_sided_names() {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    let hip = ed
        .add_joint(id, None, Vec3::new(5.0, 12.0, 2.0), Some("hip"))
        .unwrap();
    let leg = ed
        .add_joint(id, Some(hip), Vec3::new(8.0, 11.0, 2.0), Some("leg"))
        .unwrap();
    ed.add_joint(id, Some(leg), Vec3::new(8.0, 1.0, 2.0), Some("foot"))
        .unwrap();
    let copy = ed.mirror_chain(id, leg).unwrap();
    let spec = ed.skeleton_spec(id).unwrap();
    let by = |n: &str| spec.joints.iter().find(|j| j.name == n).unwrap();
    // The model spans x 0..10: its centre is x = 5.
    assert_eq!(by("leg.L").position, [8.0, 11.0, 2.0]);
    assert_eq!(by("leg.R").position, [2.0, 11.0, 2.0]);
    assert_eq!(by("foot.R").position, [2.0, 1.0, 2.0]);
    assert_eq!(by("foot.R").parent.as_deref(), Some("leg.R"));
    assert_eq!(by("leg.R").parent.as_deref(), Some("hip"));
    assert_eq!(spec.joints[copy].name, "leg.R");
    // Mirroring again would duplicate names: refused.
    assert!(ed.mirror_chain(id, leg).is_err());
}

#[test]
fn templates_fit_the_model_and_binding_gives_every_limb_its_joint() {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    ed.apply_skeleton_template(id, SkeletonTemplate::Biped)
        .unwrap();
    let spec = ed.skeleton_spec(id).unwrap();
    let (lo, hi) = model(&ed, id).bounds().unwrap();
    for j in &spec.joints {
        let p = Vec3::from(j.position);
        assert!(p.cmpge(lo).all() && p.cmple(hi).all(), "{} at {p}", j.name);
    }
    // A hand-made skeleton for the two legs and the body, bound geodesically.
    let empty = thicket_core::skin::SkeletonSpec::default();
    ed.set_skeleton(id, &empty, WeightsOnEdit::Keep, None)
        .unwrap();
    assert!(model(&ed, id).rig.is_none() && !model(&ed, id).svo.has_skin());
    let hip = ed
        .add_joint(id, None, Vec3::new(5.0, 13.0, 2.0), Some("hip"))
        .unwrap();
    ed.add_joint(id, Some(hip), Vec3::new(5.0, 23.0, 2.0), Some("chest"))
        .unwrap();
    let leg_r = ed
        .add_joint(id, Some(hip), Vec3::new(2.0, 11.0, 2.0), Some("leg.R"))
        .unwrap();
    ed.add_joint(id, Some(leg_r), Vec3::new(2.0, 0.5, 2.0), Some("foot.R"))
        .unwrap();
    let leg_l = ed
        .add_joint(id, Some(hip), Vec3::new(8.0, 11.0, 2.0), Some("leg.L"))
        .unwrap();
    ed.add_joint(id, Some(leg_l), Vec3::new(8.0, 0.5, 2.0), Some("foot.L"))
        .unwrap();
    let unbound = ed.doc().clone();
    let report = ed.bind_now(id, BindMethod::Geodesic).unwrap();
    assert_eq!(report.voxels, model(&ed, id).svo.leaf_count());
    let rig = model(&ed, id).rig.clone().unwrap();
    assert!(!rig.weights_stale());
    let strongest = |c: UVec3| {
        let s = model(&ed, id).svo.get(c).unwrap().skin;
        rig.skeleton.joints[usize::from(s.joints[0])].name.clone()
    };
    assert_eq!(strongest(UVec3::new(1, 6, 1)), "leg.R");
    assert_eq!(strongest(UVec3::new(8, 6, 1)), "leg.L");
    assert_eq!(strongest(UVec3::new(5, 20, 1)), "hip");
    // Moving a joint marks the weights stale; binding is one undo step.
    ed.move_joint(id, leg_l, Vec3::new(8.0, 10.0, 2.0)).unwrap();
    assert!(model(&ed, id).rig.as_ref().unwrap().weights_stale());
    assert!(ed.undo());
    assert!(ed.undo());
    assert_eq!(ed.doc(), &unbound);
}

#[test]
fn weight_painting_renormalises_and_its_undo_restores_the_octree_exactly() {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    let hip = ed
        .add_joint(id, None, Vec3::new(5.0, 13.0, 2.0), Some("hip"))
        .unwrap();
    let leg = ed
        .add_joint(id, Some(hip), Vec3::new(2.0, 11.0, 2.0), Some("leg.R"))
        .unwrap();
    ed.add_joint(id, Some(leg), Vec3::new(2.0, 0.5, 2.0), Some("foot.R"))
        .unwrap();
    ed.bind_now(id, BindMethod::Geodesic).unwrap();
    let bound = model(&ed, id).svo.clone();
    // Two dabs of one stroke add the hip's weight around a leg voxel.
    let c = UVec3::new(2, 6, 2);
    let w = |ed: &Editor| {
        let s = model(ed, id).svo.get(c).unwrap().skin;
        s.influences()
            .filter(|&(j, _)| usize::from(j) == hip)
            .map(|(_, w)| w)
            .sum::<f32>()
    };
    let before = w(&ed);
    let n = ed
        .paint_weights(id, hip, c.as_vec3() + 0.5, 3.0, 0.6, false)
        .unwrap();
    assert!(n > 10, "{n} voxels painted");
    ed.paint_weights(id, hip, c.as_vec3() + 0.5, 3.0, 0.6, false)
        .unwrap();
    ed.end_interaction();
    let after = w(&ed);
    assert!(after > before + 0.5, "{before} -> {after}");
    model(&ed, id).svo.for_each_leaf(|c, v| {
        let sum: u32 = v.skin.weights.iter().map(|&b| u32::from(b)).sum();
        assert_eq!(sum, 255, "{c}: {:?}", v.skin);
    });
    // Smoothing moves a voxel toward its neighbours.
    ed.paint_weights(id, hip, c.as_vec3() + 0.5, 2.0, 0.0, true)
        .unwrap();
    ed.end_interaction();
    assert!(ed.undo(), "the smoothing stroke");
    assert!(ed.undo(), "the two dabs are one step");
    assert!(model(&ed, id).svo == bound, "undo restores every weight");
    // A model with joints but no binding can be painted by hand: its voxels follow the root
    // until a joint's weight is painted onto them. A joint that does not exist is refused.
    let mut plain = Editor::default();
    let other = figure(&mut plain);
    let root = plain
        .add_joint(other, None, Vec3::new(5.0, 13.0, 2.0), None)
        .unwrap();
    let tip = plain
        .add_joint(other, Some(root), Vec3::new(5.0, 22.0, 2.0), None)
        .unwrap();
    assert!(
        plain
            .paint_weights(other, 7, Vec3::splat(2.0), 2.0, 1.0, false)
            .is_err()
    );
    let top = UVec3::new(5, 22, 2);
    plain
        .paint_weights(other, tip, top.as_vec3() + 0.5, 2.0, 1.0, false)
        .unwrap();
    let s = model(&plain, other).svo.get(top).unwrap().skin;
    assert_eq!((s.joints[0], s.weights[0]), (tip as u8, 255), "{s:?}");
}

#[test]
fn a_new_clip_plays_and_keys_a_posed_joint_at_two_times() {
    let (mut ed, id, _hip, leg) = bound_hip_and_leg();
    let clip = ed.new_clip(id, "kick", 1.0).unwrap();
    assert_eq!(ed.rig(id).unwrap().playback.clip, Some(clip));
    assert_eq!(ed.clip_names(id), ["kick"]);
    assert_eq!(ed.new_clip(id, "kick", 2.0).unwrap(), 1);
    assert_eq!(ed.clip_names(id), ["kick", "kick.001"]);
    let mut playback = ed.rig(id).unwrap().playback;
    playback.clip = Some(clip);
    // Held, not looping: a key at the clip's end stays there (looping, 1 s would be 0 s).
    playback.wrap = thicket_core::skin::Wrap::Clamp;
    for (t, deg) in [(0.0f32, 0.0f32), (1.0, 60.0)] {
        playback.time_secs = t;
        ed.set_playback(id, playback).unwrap();
        ed.rotate_joint(id, leg, None, glam::Quat::from_rotation_x(deg.to_radians()))
            .unwrap();
        ed.set_joint_key(id, leg).unwrap();
    }
    let rig = ed.rig(id).unwrap();
    assert!(
        rig.clips[clip].channels.iter().all(|c| c.joint == leg),
        "{:?}",
        rig.clips[clip]
    );
    let at = |t: f32| rig.clips[clip].sample(t, &rig.skeleton).locals[leg].rotation;
    assert!(at(0.0).angle_between(at(1.0)) > 0.9, "the keys differ");
}

#[test]
fn baking_the_pose_keys_every_posed_joint_in_one_step() {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    let hip = ed
        .add_joint(id, None, Vec3::new(5.0, 13.0, 2.0), Some("hip"))
        .unwrap();
    let leg = ed
        .add_joint(id, Some(hip), Vec3::new(2.0, 11.0, 2.0), Some("leg.R"))
        .unwrap();
    let foot = ed
        .add_joint(id, Some(leg), Vec3::new(2.0, 1.0, 2.0), Some("foot.R"))
        .unwrap();
    ed.bind_now(id, BindMethod::Geodesic).unwrap();
    assert_eq!(ed.bake_pose(id).unwrap(), 0, "nothing posed, nothing keyed");
    ed.rotate_joint(id, leg, None, glam::Quat::from_rotation_x(0.5))
        .unwrap();
    ed.end_interaction();
    ed.rotate_joint(id, foot, None, glam::Quat::from_rotation_z(0.3))
        .unwrap();
    ed.end_interaction();
    let posed = ed.rig(id).unwrap().current_pose();
    let steps = ed.history().undo_len();
    assert_eq!(ed.bake_pose(id).unwrap(), 2);
    assert_eq!(ed.history().undo_len(), steps + 1, "one step");
    let rig = ed.rig(id).unwrap();
    assert!(
        rig.pose_overrides.is_empty(),
        "the overrides are folded into keys"
    );
    let clip = rig.playback.clip.expect("a Pose clip plays");
    assert_eq!(rig.clips[clip].name, "Pose");
    let keyed = rig.current_pose();
    for j in [leg, foot] {
        assert!(
            keyed.locals[j]
                .rotation
                .abs_diff_eq(posed.locals[j].rotation, 1e-5),
            "joint {j}"
        );
    }
    assert!(ed.undo());
    assert_eq!(ed.rig(id).unwrap().pose_overrides.len(), 2);
}

#[test]
fn clips_are_renamed_duplicated_resized_and_deleted_one_step_each() {
    let (mut ed, id, _hip, leg) = bound_hip_and_leg();
    let walk = ed.new_clip(id, "walk", 1.0).unwrap();
    let mut playback = ed.rig(id).unwrap().playback;
    playback.wrap = thicket_core::skin::Wrap::Clamp;
    playback.time_secs = 0.8;
    ed.set_playback(id, playback).unwrap();
    ed.rotate_joint(id, leg, None, glam::Quat::from_rotation_x(0.4))
        .unwrap();
    ed.set_joint_key(id, leg).unwrap();
    let run = ed.new_clip(id, "run", 0.5).unwrap();
    assert_eq!((walk, run), (0, 1));
    let start = ed.doc().clone();

    assert!(
        ed.rename_clip(id, run, "walk").is_err(),
        "names stay unique"
    );
    assert!(ed.rename_clip(id, run, "  ").is_err());
    ed.rename_clip(id, run, "sprint").unwrap();
    assert_eq!(ed.clip_names(id), ["walk", "sprint"]);
    let copy = ed.duplicate_clip(id, walk).unwrap();
    assert_eq!(ed.clip_names(id), ["walk", "sprint", "walk.copy"]);
    assert_eq!(
        ed.rig(id).unwrap().clips[copy].channels,
        ed.rig(id).unwrap().clips[walk].channels
    );
    assert!(
        ed.set_clip_length(id, walk, 0.5).is_err(),
        "a key sits at 0.8 s"
    );
    ed.set_clip_length(id, walk, 2.0).unwrap();
    assert_eq!(ed.rig(id).unwrap().clips[walk].duration_secs, 2.0);
    // Deleting the first clip: the playing one ("sprint", index 1) becomes index 0.
    assert_eq!(ed.rig(id).unwrap().playback.clip, Some(1));
    ed.delete_clip(id, walk).unwrap();
    assert_eq!(ed.clip_names(id), ["sprint", "walk.copy"]);
    assert_eq!(ed.rig(id).unwrap().playback.clip, Some(0));
    // Deleting the playing clip returns to the rest pose; undo plays it again.
    ed.delete_clip(id, 0).unwrap();
    assert_eq!(ed.rig(id).unwrap().playback.clip, None);
    assert!(ed.undo());
    assert_eq!(ed.rig(id).unwrap().playback.clip, Some(0));
    assert_eq!(ed.clip_names(id), ["sprint", "walk.copy"]);
    assert!(
        ed.undo(),
        "undoing the first delete plays sprint at its old index"
    );
    assert_eq!(ed.rig(id).unwrap().playback.clip, Some(1));
    assert!(ed.redo());
    assert!(ed.redo());
    for _ in 0..5 {
        assert!(ed.undo());
    }
    assert_eq!(
        ed.rig(id).unwrap().clips,
        start_clips(&start, id),
        "five steps undo to the clips before"
    );
}

fn start_clips(
    doc: &thicket_core::scene::Document,
    id: u64,
) -> Vec<thicket_core::skin::AnimationClip> {
    match &doc.objects.iter().find(|o| o.id == id).unwrap().kind {
        ObjectKind::Voxels(v) => v.rig.as_ref().unwrap().clips.clone(),
        _ => Vec::new(),
    }
}

#[test]
fn mirroring_a_chain_without_sides_keeps_its_weights_and_keys_on_the_renamed_joints() {
    let (mut ed, id, _hip, leg) = bound_hip_and_leg();
    let foot = ed
        .add_joint(id, Some(leg), Vec3::new(2.0, 1.0, 2.0), Some("foot"))
        .unwrap();
    ed.rename_joint(id, leg, "leg").unwrap();
    ed.bind_now(id, BindMethod::Geodesic).unwrap();
    ed.new_clip(id, "kick", 1.0).unwrap();
    ed.rotate_joint(id, foot, None, glam::Quat::from_rotation_x(0.3))
        .unwrap();
    ed.set_joint_key(id, foot).unwrap();
    let before = model(&ed, id).svo.clone();
    let weight_of = |ed: &Editor, name: &str| {
        let rig = ed.rig(id).unwrap();
        let j = rig.skeleton.find(name).unwrap();
        let mut sum = 0.0;
        model(ed, id).svo.for_each_leaf(|_, v| {
            sum += v
                .skin
                .influences()
                .filter(|&(k, _)| usize::from(k) == j)
                .map(|(_, w)| w)
                .sum::<f32>();
        });
        sum
    };
    let leg_weight = weight_of(&ed, "leg");
    assert!(leg_weight > 10.0, "{leg_weight}");
    ed.mirror_chain(id, leg).unwrap();
    // The originals are renamed (.L), not replaced: same weights, same keys.
    assert_eq!(weight_of(&ed, "leg.L"), leg_weight);
    assert!(model(&ed, id).svo == before, "no voxel's weights changed");
    let rig = ed.rig(id).unwrap();
    let foot_l = rig.skeleton.find("foot.L").unwrap();
    assert!(rig.clips[0].channels.iter().any(|c| c.joint == foot_l));
    assert!(rig.skeleton.find("leg.R").is_some() && rig.skeleton.find("foot.R").is_some());
}

#[test]
fn reparenting_returns_the_joints_new_index() {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    let hip = ed
        .add_joint(id, None, Vec3::new(5.0, 13.0, 2.0), Some("hip"))
        .unwrap();
    let arm = ed
        .add_joint(id, Some(hip), Vec3::new(1.0, 20.0, 2.0), Some("arm"))
        .unwrap();
    ed.add_joint(id, Some(hip), Vec3::new(5.0, 20.0, 2.0), Some("spine"))
        .unwrap();
    let spine = ed.rig(id).unwrap().skeleton.find("spine").unwrap();
    assert!(arm < spine);
    let moved = ed.reparent_joint(id, arm, Some(spine)).unwrap();
    let rig = ed.rig(id).unwrap();
    assert_eq!(rig.skeleton.joints[moved].name, "arm");
    assert_eq!(
        rig.skeleton.joints[moved].parent,
        rig.skeleton.find("spine")
    );
}

#[test]
fn an_imported_rig_is_renamed_in_place_and_not_rebuilt_from_positions() {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    ed.add_joint(id, None, Vec3::new(5.0, 13.0, 2.0), Some("hip"))
        .unwrap();
    // Give the joint a rotated frame, as imported rigs have.
    let mut model_now = model(&ed, id).clone();
    let rig = model_now.rig.as_mut().unwrap();
    rig.skeleton.joints[0].rest.rotation = glam::Quat::from_rotation_z(0.5);
    ed.apply(
        Edit::SetVoxelModel {
            id,
            model: Box::new(model_now),
        },
        None,
    );
    ed.rename_joint(id, 0, "pelvis").unwrap();
    let rig = ed.rig(id).unwrap();
    assert_eq!(rig.skeleton.joints[0].name, "pelvis");
    assert!(
        rig.skeleton.joints[0]
            .rest
            .rotation
            .abs_diff_eq(glam::Quat::from_rotation_z(0.5), 1e-6),
        "the frame is kept"
    );
    let before = ed.doc().clone();
    let err = ed
        .add_joint(id, Some(0), Vec3::new(2.0, 5.0, 2.0), None)
        .unwrap_err();
    assert!(err.to_string().contains("imported"), "{err}");
    assert_eq!(ed.doc(), &before);
}

#[test]
fn smoothing_reads_an_empty_skin_as_the_root_at_full_weight() {
    let mut ed = Editor::default();
    let id = figure(&mut ed);
    let root = ed
        .add_joint(id, None, Vec3::new(5.0, 13.0, 2.0), None)
        .unwrap();
    let tip = ed
        .add_joint(id, Some(root), Vec3::new(5.0, 22.0, 2.0), None)
        .unwrap();
    let c = UVec3::new(5, 18, 2);
    // One voxel painted fully onto the tip, its neighbours still empty (on the root).
    ed.paint_weights(id, tip, c.as_vec3() + 0.5, 0.5, 1.0, false)
        .unwrap();
    ed.end_interaction();
    let tip_weight = |ed: &Editor| {
        let s = model(ed, id).svo.get(c).unwrap().skin;
        s.influences()
            .filter(|&(j, _)| usize::from(j) == tip)
            .map(|(_, w)| w)
            .sum::<f32>()
    };
    assert_eq!(tip_weight(&ed), 1.0);
    // Smoothing the root there pulls the voxel back toward its neighbours' root weight.
    ed.paint_weights(id, root, c.as_vec3() + 0.5, 0.5, 0.0, true)
        .unwrap();
    assert!(tip_weight(&ed) < 0.75, "{}", tip_weight(&ed));
}

/// A clip "kick" on the bound figure with the leg keyed at 0, 0.5 and 1 s (0°, 60°, then 20°
/// more) and the hip at 0.5 s.
fn kicking() -> (Editor, u64, usize, usize) {
    let (mut ed, id, hip, leg) = bound_hip_and_leg();
    ed.new_clip(id, "kick", 1.0).unwrap();
    let mut playback = ed.rig(id).unwrap().playback;
    playback.wrap = thicket_core::skin::Wrap::Clamp;
    for (joint, t, deg) in [
        (leg, 0.0f32, 0.0f32),
        (leg, 0.5, 60.0),
        (leg, 1.0, 20.0),
        (hip, 0.5, 10.0),
    ] {
        playback.time_secs = t;
        ed.set_playback(id, playback).unwrap();
        ed.rotate_joint(
            id,
            joint,
            None,
            glam::Quat::from_rotation_x(deg.to_radians()),
        )
        .unwrap();
        ed.set_joint_key(id, joint).unwrap();
    }
    (ed, id, hip, leg)
}

fn leg_angle_deg(ed: &Editor, id: u64, leg: usize, t: f32) -> f32 {
    let rig = ed.rig(id).unwrap();
    let clip = &rig.clips[rig.playback.clip.unwrap()];
    let q = clip.sample(t, &rig.skeleton).locals[leg].rotation;
    q.angle_between(glam::Quat::IDENTITY).to_degrees()
}

#[test]
fn dope_sheet_moves_deletes_copies_and_pastes_keys_one_step_each() {
    use thicket_core::skin::KeyRef;
    let (mut ed, id, hip, leg) = kicking();
    let key = |joint, time_secs| KeyRef { joint, time_secs };
    let start = ed.rig(id).unwrap().clips.clone();
    let steps = ed.history().undo_len();
    // The last key: 20° posed on top of the 60° the clip held there.
    let end_deg = leg_angle_deg(&ed, id, leg, 1.0);
    assert!((end_deg - 80.0).abs() < 0.01, "{end_deg}");

    // Move the leg's middle key to 0.75 s: its 60° goes with it, the hip stays.
    let moved = ed.move_keys(id, &[key(leg, 0.5)], 0.25).unwrap();
    assert_eq!(moved, [key(leg, 0.75)]);
    assert_eq!(ed.history().undo_len(), steps + 1);
    assert_eq!(ed.joint_key_times(id, leg), [0.0, 0.75, 1.0]);
    assert!((leg_angle_deg(&ed, id, leg, 0.75) - 60.0).abs() < 0.01);
    assert_eq!(ed.joint_key_times(id, hip), [0.5]);

    // Copy both leg keys at 0.75 and 1 s, paste them at 2 s: the clip grows to 2.25 s.
    let clipboard = ed.copy_keys(id, &[key(leg, 0.75), key(leg, 1.0)]).unwrap();
    let written = ed.paste_keys(id, &clipboard, 2.0).unwrap();
    assert_eq!(written, [key(leg, 2.0), key(leg, 2.25)]);
    assert_eq!(ed.history().undo_len(), steps + 2);
    assert!((leg_angle_deg(&ed, id, leg, 2.0) - 60.0).abs() < 0.01);
    assert!((leg_angle_deg(&ed, id, leg, 2.25) - end_deg).abs() < 0.01);
    assert!((ed.playing_clip(id).unwrap().1.duration_secs - 2.25).abs() < 1e-6);

    // Delete them again; the length stays.
    assert_eq!(
        ed.delete_keys(id, &written).unwrap(),
        6,
        "3 channels × 2 keys"
    );
    assert_eq!(ed.joint_key_times(id, leg), [0.0, 0.75, 1.0]);
    assert!(ed.rig(id).unwrap().validate().is_ok());

    // Cubic, then a frame rate: one step each, keyed values kept.
    ed.set_keys_interpolation(id, &[leg], thicket_core::skin::Interpolation::CubicSpline)
        .unwrap();
    assert!((leg_angle_deg(&ed, id, leg, 0.75) - 60.0).abs() < 0.01);
    let clip = ed.rig(id).unwrap().playback.clip.unwrap();
    ed.set_clip_frame_rate(id, clip, 30.0).unwrap();
    assert_eq!(ed.playing_clip(id).unwrap().1.frame_rate, 30.0);
    assert!(ed.set_clip_frame_rate(id, clip, 0.0).is_err());
    assert!(ed.set_clip_frame_rate(id, clip, f32::NAN).is_err());
    assert_eq!(ed.history().undo_len(), steps + 5);

    // Undoing every step gives the clip back exactly.
    for _ in 0..5 {
        assert!(ed.undo());
    }
    assert_eq!(ed.rig(id).unwrap().clips, start);

    // Keys paste by joint name into another rig's clip, and not where no name matches.
    let clipboard = ed.copy_keys(id, &[key(leg, 0.5)]).unwrap();
    let (mut other, oid, _, oleg) = kicking();
    other.rename_joint(oid, 0, "pelvis").unwrap();
    let written = other.paste_keys(oid, &clipboard, 0.25).unwrap();
    assert_eq!(written, [key(oleg, 0.25)]);
    let mut none = clipboard.clone();
    none.joint_names = vec!["nobody".into(); none.joint_names.len()];
    assert!(other.paste_keys(oid, &none, 0.0).is_err());
    // On the rest pose there is no clip to edit: a clear error, nothing changes.
    let mut p = other.rig(oid).unwrap().playback;
    p.clip = None;
    other.set_playback(oid, p).unwrap();
    assert!(other.move_keys(oid, &[key(oleg, 0.25)], 0.1).is_err());
}

#[test]
fn ik_puts_the_foot_on_the_target_turning_only_the_two_joints_above_it() {
    let (mut ed, id, _hip, leg) = bound_hip_and_leg();
    let knee = ed
        .add_joint(id, Some(leg), Vec3::new(2.0, 6.0, 2.5), Some("knee.R"))
        .unwrap();
    let foot = ed
        .add_joint(id, Some(knee), Vec3::new(2.0, 1.0, 2.0), Some("foot.R"))
        .unwrap();
    let at = |ed: &Editor, j: usize| ed.joint_frames(id).unwrap().position(j).unwrap();
    let (hip_at, foot_at) = (at(&ed, 0), at(&ed, foot));
    let steps = ed.history().undo_len();
    // A drag: the target moves forward and up in two steps, one undo step in all.
    for k in [0.5f32, 1.0] {
        let target = foot_at + Vec3::new(0.0, 3.0, 4.0) * k;
        assert!(ed.pose_ik(id, foot, target, None).unwrap());
        assert!(
            (at(&ed, foot) - target).length() < 1e-3,
            "{}",
            at(&ed, foot)
        );
    }
    ed.end_interaction();
    assert_eq!(ed.history().undo_len(), steps + 1);
    assert!((at(&ed, 0) - hip_at).length() < 1e-5, "the hip stays");
    let posed: Vec<usize> = ed
        .rig(id)
        .unwrap()
        .pose_overrides
        .iter()
        .map(|o| o.joint)
        .collect();
    assert_eq!(posed, [leg, knee]);
    // The knee bent forward (+z, where it was), and keying bakes both turned joints.
    assert!(at(&ed, knee).z > 2.5, "{}", at(&ed, knee));
    ed.new_clip(id, "reach", 1.0).unwrap();
    ed.set_joint_keys(id, &[leg, knee]).unwrap();
    let rig = ed.rig(id).unwrap();
    let clip = &rig.clips[rig.playback.clip.unwrap()];
    assert!(!clip.joint_key_times(leg).is_empty() && !clip.joint_key_times(knee).is_empty());
    assert!(rig.pose_overrides.is_empty(), "folded into the keys");
    assert!((at(&ed, foot) - (foot_at + Vec3::new(0.0, 3.0, 4.0))).length() < 1e-3);
    // A joint without a grandparent cannot be solved: a clear error.
    assert!(ed.pose_ik(id, leg, Vec3::ZERO, None).is_err());
    // Undo everything: the rest pose again.
    while ed.undo() {}
    assert!(ed.rig(id).is_none_or(|r| r.pose_overrides.is_empty()));
}

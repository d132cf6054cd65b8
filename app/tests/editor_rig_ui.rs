//! Rigging and animating a model made in the editor, on the real app through egui_kittest: a
//! new model, a body and two legs boxed in, Place joints clicked on the legs (a hip and two leg
//! chains, each joint at the middle of the limb's thickness), Bind, a new clip with a knee
//! rotation keyed at two times through the timeline's Set key, playback: the two frames' images
//! differ, the leg's voxels moved and the body's did not; save, reopen, equal; export. Snapshots
//! of the Rig section with its skeleton and of the weight heat map.
//!
//! No GPU viewport is attached: the view is the CPU preview (which the weight heat map reads).

mod common;

use egui_kittest::kittest::Queryable as _;
use egui_kittest::{Harness, SnapshotOptions};
use glam::{IVec3, UVec3, Vec3};
use thicket::editor::{Editor, NewModelSpec};
use thicket::ui::EditorApp;
use thicket::ui::view::Projector;
use thicket_core::scene::ObjectKind;
use thicket_core::sculpt::{Ink, Mirror, ShapeOp};

const SIZE: egui::Vec2 = egui::vec2(1280.0, 800.0);

fn harness(editor: Editor) -> Harness<'static, EditorApp> {
    common::ui_harness(editor, SIZE)
}

/// A 16×24×8 model of 0.1 m voxels: two legs (x 2..=5 and 10..=13, y 0..=10) under a body
/// (x 1..=14, y 11..=21), all 4 voxels deep (z 2..=5: the front face at z = 6).
fn figure() -> (Editor, u64) {
    let mut ed = Editor::default();
    let id = ed
        .add_voxel_model(&NewModelSpec {
            name: "Figure".into(),
            size: UVec3::new(16, 24, 8),
            voxel_size: 0.1,
            fill: thicket_core::sculpt::model_ops::InitialFill::Empty,
            ..NewModelSpec::default()
        })
        .unwrap();
    let ink = Ink {
        color: [200, 80, 60, 255],
        material: 0,
    };
    for (a, b) in [
        (IVec3::new(2, 0, 2), IVec3::new(5, 10, 5)),
        (IVec3::new(10, 0, 2), IVec3::new(13, 10, 5)),
        (IVec3::new(1, 11, 2), IVec3::new(14, 21, 5)),
    ] {
        ed.shape_box(id, a, b, ShapeOp::Add, ink, Mirror::default())
            .unwrap();
    }
    // Look at the figure from the front (+Z), orthographic (key 1's view), framed: every
    // pointer ray runs along -Z.
    let mut camera = ed.doc().camera;
    camera.yaw_deg = 0.0;
    camera.pitch_deg = 0.0;
    camera.orthographic = true;
    ed.set_camera(camera);
    ed.selection = Some(thicket::editor::Selection::Object(id));
    ed.frame_selection();
    (ed, id)
}

fn model(h: &Harness<'static, EditorApp>, id: u64) -> thicket_core::scene::VoxelModel {
    match &h.state().editor.object(id).unwrap().kind {
        ObjectKind::Voxels(v) => v.clone(),
        _ => panic!("a voxel model"),
    }
}

/// The screen point over the front face of voxel column (x, y) of the model.
fn front_of(h: &Harness<'static, EditorApp>, id: u64, x: f32, y: f32) -> egui::Pos2 {
    let v = model(h, id);
    let o = h.state().editor.object(id).unwrap();
    let world = o
        .transform
        .matrix()
        .transform_point3(v.object_from_voxel().transform_point3(Vec3::new(x, y, 6.0)));
    let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
    proj.to_screen(world).expect("in front of the camera")
}

/// Where a voxel lands at `t` seconds of clip `clip` (object space).
fn skinned_at(v: &thicket_core::scene::VoxelModel, clip: usize, t: f32, c: UVec3) -> Vec3 {
    let rig = v.rig.as_ref().unwrap();
    let m = rig.skinning_at(Some(clip), t);
    let p = v.object_from_voxel().transform_point3(c.as_vec3() + 0.5);
    let s = v.svo.get(c).unwrap().skin;
    s.influences().fold(Vec3::ZERO, |acc, (j, w)| {
        acc + m[usize::from(j)].transform_point3(p) * w
    })
}

#[test]
fn a_model_made_here_is_rigged_bound_keyed_played_saved_and_exported() {
    let (ed, id) = figure();
    let mut h = harness(ed);
    // Fold the inspector's Transform and Voxels sections so the Rig section fits the window.
    for section in ["Transform", "Voxels"] {
        // The section header comes before the "Voxels" row of the section itself.
        h.get_all_by_label(section).next().unwrap().click();
        h.run_steps(2);
    }
    // Place joints: a hip in the body, then a chain down the right leg; the hip's dot again to
    // branch, then a chain down the left leg.
    h.get_by_label("Place joints").click();
    h.run_steps(2);
    assert!(h.state().pose.rig.placing);
    for (x, y) in [(8.0, 11.5), (4.0, 5.5), (4.0, 1.0)] {
        let p = front_of(&h, id, x, y);
        common::click_at(&mut h, p);
    }
    // The hip's dot, where the skeleton overlay draws it.
    let hip = {
        let frames = h.state().editor.joint_frames(id).unwrap();
        let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
        proj.to_screen(frames.position(0).unwrap()).unwrap()
    };
    common::click_at(&mut h, hip);
    for (x, y) in [(12.0, 5.5), (12.0, 1.0)] {
        let p = front_of(&h, id, x, y);
        common::click_at(&mut h, p);
    }
    let spec = h.state().editor.skeleton_spec(id).unwrap();
    let names: Vec<&str> = spec.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(
        names,
        ["root", "bone", "bone.001", "bone.002", "bone.003"],
        "{spec:?}"
    );
    let parents: Vec<Option<&str>> = spec.joints.iter().map(|j| j.parent.as_deref()).collect();
    assert_eq!(
        parents,
        [
            None,
            Some("root"),
            Some("bone"),
            Some("root"),
            Some("bone.002")
        ]
    );
    // Every joint at the middle of the thickness: the ray enters at z = 6 and leaves at z = 2
    // (voxels), so z = 4 voxels past the model's origin.
    let origin = model(&h, id).origin;
    for j in &spec.joints {
        let z = (j.position[2] - origin.z) / 0.1;
        assert!((z - 4.0).abs() < 0.05, "{} at z = {z} voxels", j.name);
    }
    // While placing, the selected joint's gizmo moves its rest position along the model's
    // axes: drag the Y arrow (up the screen in this front view) 30 points up, one undo step,
    // no pose override; then undo it.
    let last = spec.joints.len() - 1;
    assert_eq!(h.state().pose.joint.map(|j| j.joint), Some(last));
    let (dot, per_point) = {
        let frames = h.state().editor.joint_frames(id).unwrap();
        let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
        let p = frames.position(last).unwrap();
        (proj.to_screen(p).unwrap(), proj.world_per_point(p))
    };
    let steps = h.state().editor.history().undo_len();
    let grab = dot + egui::vec2(0.0, -40.0);
    h.drag_at(grab);
    h.run_steps(1);
    h.hover_at(grab + egui::vec2(0.0, -15.0));
    h.run_steps(1);
    h.hover_at(grab + egui::vec2(0.0, -30.0));
    h.run_steps(1);
    h.drop_at(grab + egui::vec2(0.0, -30.0));
    h.run_steps(2);
    let moved = h.state().editor.skeleton_spec(id).unwrap();
    let (a, b) = (spec.joints[last].position, moved.joints[last].position);
    assert!(
        (b[1] - a[1] - 30.0 * per_point).abs() < 0.1 * 30.0 * per_point,
        "{a:?} -> {b:?} ({per_point} per point)"
    );
    assert!(
        (b[0] - a[0]).abs() < 1e-4 && (b[2] - a[2]).abs() < 1e-4,
        "{a:?} {b:?}"
    );
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");
    assert!(h.state().editor.rig(id).unwrap().pose_overrides.is_empty());
    assert!(h.state_mut().editor.undo());
    h.run_steps(1);
    assert_eq!(h.state().editor.skeleton_spec(id).unwrap(), spec);
    h.get_by_label("Place joints").click();
    h.run_steps(1);
    common::settle_preview(&mut h);
    h.snapshot_options(
        "rig_placed_joints",
        &SnapshotOptions::new().max_failed_pixels(300),
    );

    // Bind (a job with progress), one undo step.
    let steps = h.state().editor.history().undo_len();
    h.get_by_label("Bind").click_accesskit();
    h.run_steps(1);
    let ctx = h.ctx.clone();
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    assert_eq!(h.state().editor.history().undo_len(), steps + 1);
    let v = model(&h, id);
    assert!(v.svo.has_skin());
    let rig = v.rig.clone().unwrap();
    let strongest = |c: UVec3| {
        let s = v.svo.get(c).unwrap().skin;
        rig.skeleton.joints[usize::from(s.joints[0])].name.clone()
    };
    // "bone" is the right knee (it owns the shin below it), "bone.002" the left one.
    assert_eq!(strongest(UVec3::new(3, 3, 3)), "bone", "right shin");
    assert_eq!(strongest(UVec3::new(12, 3, 3)), "bone.002", "left shin");
    assert_eq!(strongest(UVec3::new(7, 18, 3)), "root", "body");
    h.get_by_label_contains("geodesic binding of this skeleton");

    // The weight heat map of the right knee.
    h.state_mut().pose.select_joint(id, 1);
    h.get_by_label("Show weights").click_accesskit();
    h.run_steps(2);
    common::settle_preview(&mut h);
    h.snapshot_options(
        "rig_weights",
        &SnapshotOptions::new().max_failed_pixels(300),
    );
    h.get_by_label("Show weights").click_accesskit();
    h.run_steps(2);

    // A new clip; the right knee keyed straight at 0 s and bent 50° at 1 s through the
    // timeline's Set key.
    h.get_by_label("New clip").click();
    h.run_steps(2);
    let clip = h.state().editor.rig(id).unwrap().playback.clip.unwrap();
    for (t, deg) in [(0.0f32, 0.0f32), (1.0, -50.0)] {
        let mut playback = h.state().editor.rig(id).unwrap().playback;
        playback.time_secs = t;
        playback.wrap = thicket_core::skin::Wrap::Clamp;
        h.state_mut().editor.set_playback(id, playback).unwrap();
        h.state_mut()
            .editor
            .rotate_joint(id, 1, None, glam::Quat::from_rotation_x(deg.to_radians()))
            .unwrap();
        h.run_steps(1);
        h.get_by_label("Set key").click();
        h.run_steps(2);
    }
    let times = h.state().editor.joint_key_times(id, 1);
    assert_eq!(times, [0.0, 1.0]);

    // Play: the playhead moves; two instants draw different images; the shin's voxels moved
    // and the body's did not.
    let mut playback = h.state().editor.rig(id).unwrap().playback;
    playback.time_secs = 0.0;
    h.state_mut().editor.set_playback(id, playback).unwrap();
    h.run_steps(1);
    let t0 = h.state().editor.rig(id).unwrap().playback.time_secs;
    h.get_by_label("Play").click();
    h.run_steps(1);
    assert!(h.state().pose.playing, "Play starts playback");
    for _ in 0..5 {
        std::thread::sleep(std::time::Duration::from_millis(20));
        h.run_steps(1);
    }
    let t1 = h.state().editor.rig(id).unwrap().playback.time_secs;
    assert!(t1 != t0, "the playhead moves: {t0} -> {t1}");
    h.state_mut().pose.playing = false;
    h.run_steps(1);
    let shot = |h: &mut Harness<'static, EditorApp>, t: f32| {
        let mut playback = h.state().editor.rig(id).unwrap().playback;
        playback.time_secs = t;
        h.state_mut().editor.set_playback(id, playback).unwrap();
        common::settle_preview(h);
        h.render().expect("render")
    };
    let (a, b) = (shot(&mut h, 0.1), shot(&mut h, 0.9));
    let changed = a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
    assert!(
        changed > 500,
        "only {changed} pixels differ between 0.1 s and 0.9 s"
    );
    let v = model(&h, id);
    let foot = UVec3::new(3, 1, 3);
    let body = UVec3::new(7, 18, 3);
    let moved = |c| (skinned_at(&v, clip, 0.9, c) - skinned_at(&v, clip, 0.1, c)).length();
    assert!(moved(foot) > 0.2, "the foot swings: {}", moved(foot));
    assert!(moved(body) < 1e-4, "the body stays: {}", moved(body));

    // Save, reopen, equal; export a skinned glTF with the clip.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("figure.thicket.json");
    thicket::files::save_project(h.state().editor.doc(), &path).unwrap();
    let back = thicket::files::load_document(&path).unwrap();
    assert!(
        &back == h.state().editor.doc(),
        "the reopened project equals the edited one"
    );
    let glb = dir.path().join("figure.glb");
    let report = thicket_core::io::gltf_export::export_gltf(
        &back,
        &glb,
        &thicket_core::io::gltf_export::GltfExportOptions::default(),
        &|_| true,
    )
    .unwrap();
    assert!(report.triangles > 100, "{report:?}");
    let (gltf, _, _) = gltf::import(&glb).unwrap();
    assert_eq!(gltf.skins().next().unwrap().joints().count(), 5);
    assert_eq!(gltf.animations().count(), 1);
}

/// The dope sheet on the critter sample's walk: opened from the timeline, a key clicked and
/// dragged two frames later (one undo step, on the frame), every key selected, deleted and
/// brought back by undo, then copied and pasted at the playhead. Snapshot looked at.
#[test]
fn the_dope_sheet_selects_drags_deletes_copies_and_pastes_keys() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/critter.thicket.json"
    );
    let doc = thicket_core::io::project::load(std::path::Path::new(path)).expect("critter");
    let mut h = harness(Editor::new(doc, None));
    let id = thicket::ui::pose::timeline_target(&h.state().editor).expect("rigged");
    let clip_of = |h: &Harness<'static, EditorApp>| {
        h.state()
            .editor
            .playing_clip(id)
            .expect("walk plays")
            .1
            .clone()
    };
    let start = clip_of(&h);
    let all_keys = start.keys();
    assert!(all_keys.len() > 10, "{}", all_keys.len());
    h.get_by_label("Dope sheet").click();
    h.run_steps(2);
    h.get_by_label_contains("key(s) selected");

    // The track's geometry, as the sheet lays it out: keys span the clip's length.
    let rows = h.get_by_label("Dope sheet keys").rect();
    let (left, width) = (rows.left() + 7.0, rows.width() - 14.0);
    let span = start.duration_secs.max(start.last_key_time());
    let joint = all_keys[0].joint;
    let t = start.joint_key_times(joint)[1];
    let at = |t: f32| egui::pos2(left + t / span * width, rows.top() + 9.0);
    common::click_at(&mut h, at(t));
    assert_eq!(h.state().pose.dope.selected.len(), 1);
    assert_eq!(h.state().pose.dope.selected[0].joint, joint);
    // Shift+click adds the next key of the row, and again removes it.
    let t2 = start.joint_key_times(joint)[2];
    for expected in [2, 1] {
        for pressed in [true, false] {
            h.event_modifiers(
                egui::Event::PointerButton {
                    pos: at(t2),
                    button: egui::PointerButton::Primary,
                    pressed,
                    modifiers: egui::Modifiers::SHIFT,
                },
                egui::Modifiers::SHIFT,
            );
            h.run_steps(1);
        }
        h.run_steps(1);
        assert_eq!(h.state().pose.dope.selected.len(), expected);
    }

    // Drag it two frames (and a bit) later: it lands on the frame, one undo step.
    let steps = h.state().editor.history().undo_len();
    let frame = 1.0 / start.frame_rate;
    h.drag_at(at(t));
    h.run_steps(1);
    h.hover_at(at(t + frame));
    h.run_steps(1);
    h.hover_at(at(t + 2.2 * frame));
    h.run_steps(1);
    h.drop_at(at(t + 2.2 * frame));
    h.run_steps(2);
    let times = clip_of(&h).joint_key_times(joint);
    assert!(
        times.iter().any(|&x| (x - (t + 2.0 * frame)).abs() < 1e-4),
        "{times:?}"
    );
    assert!(!times.iter().any(|&x| (x - t).abs() < 1e-4), "{times:?}");
    assert_eq!(h.state().editor.history().undo_len(), steps + 1);
    h.try_snapshot_options("dope_sheet", &SnapshotOptions::new().max_failed_pixels(200))
        .unwrap();
    assert!(h.state_mut().editor.undo());
    h.run_steps(1);
    assert_eq!(clip_of(&h), start);

    // Select all, delete, undo.
    h.get_by_label("Select all").click();
    h.run_steps(1);
    assert_eq!(h.state().pose.dope.selected.len(), all_keys.len());
    h.get_by_label("Delete keys").click();
    h.run_steps(2);
    assert!(clip_of(&h).channels.is_empty());
    h.get_by_label_contains("No keys yet");
    assert!(h.state_mut().editor.undo());
    // The timeline panel grows back to hold the rows over a frame or two.
    h.run_steps(3);
    assert_eq!(clip_of(&h), start);

    // Copy every key and paste it with the playhead held at 2 s: the clip grows to 3 s and
    // the pasted keys repeat the first second.
    h.get_by_label("Select all").click();
    h.run_steps(1);
    assert_eq!(h.state().pose.dope.selected.len(), all_keys.len());
    h.get_by_label("Copy").click();
    h.run_steps(1);
    assert!(h.state().pose.dope.clipboard.is_some());
    let mut playback = h.state().editor.rig(id).unwrap().playback;
    playback.wrap = thicket_core::skin::Wrap::Clamp;
    playback.time_secs = 2.0;
    h.state_mut().editor.set_playback(id, playback).unwrap();
    h.run_steps(1);
    h.get_by_label("Paste at playhead").click();
    h.run_steps(2);
    let pasted = clip_of(&h);
    assert!(
        (pasted.duration_secs - (2.0 + start.last_key_time())).abs() < 1e-4,
        "{} {:?}",
        pasted.duration_secs,
        h.state().pose.dope.error
    );
    let rig = h.state().editor.rig(id).unwrap();
    // At every key time the pasted pose is the copied one (values are pasted; the tangents of
    // the cubic walk are flat at pasted keys, so between keys the curves differ).
    for s in start.joint_key_times(joint) {
        let a = start.sample(s, &rig.skeleton);
        let b = pasted.sample(2.0 + s, &rig.skeleton);
        for (x, y) in a.locals.iter().zip(&b.locals) {
            assert!(x.rotation.angle_between(y.rotation) < 1e-3, "at {s}");
        }
    }
}

/// Two-bone IK through the real UI: IK (2 bones) on, the foot's X arrow dragged 30 points
/// right in the front view: the foot follows exactly (the target moved along the model's X),
/// only the two joints above it are posed, in one undo step.
#[test]
fn ik_drags_a_foot_and_the_leg_follows() {
    let (mut ed, id) = figure();
    let v = match &ed.object(id).unwrap().kind {
        ObjectKind::Voxels(v) => v.clone(),
        _ => unreachable!(),
    };
    let at = |x: f32, y: f32, z: f32| v.object_from_voxel().transform_point3(Vec3::new(x, y, z));
    let hip = ed
        .add_joint(id, None, at(8.0, 11.5, 4.0), Some("hip"))
        .unwrap();
    let thigh = ed
        .add_joint(id, Some(hip), at(4.0, 10.0, 4.0), Some("thigh.R"))
        .unwrap();
    // The knee a little forward: the leg bends, so the foot has room to move.
    let shin = ed
        .add_joint(id, Some(thigh), at(4.0, 5.5, 5.5), Some("shin.R"))
        .unwrap();
    let foot = ed
        .add_joint(id, Some(shin), at(4.0, 1.0, 4.0), Some("foot.R"))
        .unwrap();
    ed.bind_now(id, thicket_core::skin::BindMethod::Geodesic)
        .unwrap();
    let mut h = harness(ed);
    h.state_mut().pose.select_joint(id, foot);
    h.run_steps(2);
    h.get_by_label("IK (2 bones)").click();
    h.run_steps(2);
    assert!(h.state().pose.ik);
    let (dot, per_point, before) = {
        let frames = h.state().editor.joint_frames(id).unwrap();
        let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
        let p = frames.position(foot).unwrap();
        (proj.to_screen(p).unwrap(), proj.world_per_point(p), p)
    };
    let steps = h.state().editor.history().undo_len();
    let grab = dot + egui::vec2(40.0, 0.0);
    h.drag_at(grab);
    h.run_steps(1);
    h.hover_at(grab + egui::vec2(15.0, 0.0));
    h.run_steps(1);
    h.hover_at(grab + egui::vec2(30.0, 0.0));
    h.run_steps(1);
    h.drop_at(grab + egui::vec2(30.0, 0.0));
    h.run_steps(2);
    let after = h
        .state()
        .editor
        .joint_frames(id)
        .unwrap()
        .position(foot)
        .unwrap();
    let moved = after - before;
    assert!(
        (moved.x - 30.0 * per_point).abs() < 0.05 * 30.0 * per_point,
        "{moved} ({per_point} per point)"
    );
    assert!(moved.y.abs() < 1e-3 && moved.z.abs() < 1e-3, "{moved}");
    let posed: Vec<usize> = h
        .state()
        .editor
        .rig(id)
        .unwrap()
        .pose_overrides
        .iter()
        .map(|o| o.joint)
        .collect();
    assert_eq!(posed, [thigh, shin]);
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");
    assert_eq!(h.state().pose.ik_reached, Some(true));
    common::settle_preview(&mut h);
    h.try_snapshot_options("pose_ik", &SnapshotOptions::new().max_failed_pixels(200))
        .unwrap();
}

/// Keying an object's transform through the inspector: Key transform at 0 s, the object moved
/// and keyed again at 1 s (the motion timeline's playhead), then the timeline's scrub puts it
/// half way. Snapshot of the motion timeline, looked at.
#[test]
fn an_object_keyed_in_the_inspector_moves_on_its_timeline() {
    let (ed, id) = figure();
    let mut h = harness(ed);
    assert!(h.state().editor.motion(id).is_none());
    h.get_by_label("Key transform").click();
    h.run_steps(2);
    assert_eq!(h.state().editor.object_key_times(id), [0.0]);
    // The timeline now drives the object.
    h.get_by_label("1 key(s)");
    let t = h.state().editor.motion(id).unwrap().wrap;
    h.state_mut().editor.set_motion_time(id, 1.0, t).unwrap();
    let mut moved = h.state().editor.object(id).unwrap().transform;
    moved.translation.x += 1.0;
    h.state_mut().editor.set_transform(id, moved).unwrap();
    h.run_steps(1);
    h.get_by_label("Key transform").click();
    h.run_steps(2);
    assert_eq!(h.state().editor.object_key_times(id), [0.0, 1.0]);
    h.state_mut()
        .editor
        .set_motion_time(id, 0.5, thicket_core::skin::Wrap::Clamp)
        .unwrap();
    common::settle_preview(&mut h);
    let x = h.state().editor.object(id).unwrap().transform.translation.x;
    assert!((x - 0.5).abs() < 1e-5, "{x}");
    h.get_by_label("Clear key").click_accesskit();
    h.run_steps(1);
    assert_eq!(
        h.state().editor.object_key_times(id),
        [0.0, 1.0],
        "no key at 0.5 s: nothing deleted"
    );
    h.try_snapshot_options(
        "object_motion",
        &SnapshotOptions::new().max_failed_pixels(200),
    )
    .unwrap();
}

//! The pose tool, the timeline and the KRS editor on the real app, driven by egui_kittest:
//! pick a joint in the inspector's tree, drag its gizmo ring in the view, undo and redo the
//! drag; play the timeline; change a KRS mirror plane through its gizmo and its DragValues (a
//! typed normal component is kept until Enter, then the normal is made unit length), undo and
//! redo; the tree builder on the tree sample; snapshot them, the view included.
//!
//! No GPU viewport is attached: the view draws with core's CPU preview renderer (what the
//! editor uses without a GPU, for KRS objects, and for the hole / bloat overlay of rigged
//! models).

mod common;

use egui_kittest::kittest::Queryable as _;
use egui_kittest::{Harness, SnapshotOptions};
use glam::Vec3;
use thicket::editor::Editor;
use thicket::ui::EditorApp;
use thicket::ui::view::Projector;
use thicket_core::scene::{Document, ObjectKind};

const SIZE: egui::Vec2 = egui::vec2(1100.0, 720.0);

fn harness(doc: Document) -> Harness<'static, EditorApp> {
    let mut app = EditorApp::new(Editor::new(doc, None));
    // The UI tests must not touch the user's recovery folder or depend on it.
    app.autosave_secs = 0;
    app.native_dialogs = false;
    let mut h = Harness::builder()
        .with_size(SIZE)
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    h
}

/// Where the camera looks from and how (its clip planes follow the scene's bounds, which a
/// pose or a KRS edit changes: not an orbit).
fn view_of(c: thicket_core::scene::OrbitCamera) -> (Vec3, [f32; 4], bool) {
    (
        c.target,
        [c.yaw_deg, c.pitch_deg, c.distance, c.fov_y_deg],
        c.orthographic,
    )
}

/// Lets the CPU preview catch up with the document and shows its image.
fn settle_preview(h: &mut Harness<'static, EditorApp>) {
    for _ in 0..4 {
        h.state_mut().view.wait_for_cpu_preview();
        h.run_steps(1);
    }
}

fn snapshot(h: &mut Harness<'static, EditorApp>, name: &str) {
    h.snapshot_options(name, &SnapshotOptions::new().max_failed_pixels(200));
}

/// RiggedFigure (Khronos sample, CC BY 4.0; see shared/assets/LICENSES.md) voxelized in its bind
/// pose at octree depth `depth`, with its skeleton and clip.
fn rigged_figure(depth: u8) -> Document {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/skinned/RiggedFigure.glb"
    );
    let import = thicket_core::io::import_skinned(path).expect("RiggedFigure imports");
    let settings = thicket_core::voxelize::VoxelizeSettings {
        resolution: thicket_core::voxelize::Resolution::Depth(depth),
        ..Default::default()
    };
    let v = thicket_core::io::voxelize_skinned(&import, &settings, &|_| true)
        .expect("RiggedFigure voxelizes");
    let mut doc = Document::default();
    doc.add("Figure", ObjectKind::Voxels(v.model));
    doc.quality.shadows = false;
    if let Some((lo, hi)) = doc.bounds() {
        doc.camera.frame(lo, hi);
    }
    doc
}

#[test]
fn pose_a_joint_with_the_gizmo_undo_redo_and_play_the_timeline() {
    let mut h = harness(rigged_figure(5));
    let id = h.state().editor.doc().objects[0].id;
    let rig = h.state().editor.rig(id).expect("rigged").clone();
    assert!(rig.skeleton.len() > 2);

    // The inspector lists the joints as a tree; pick one that has a parent.
    let joint = 2;
    let name = rig.skeleton.joints[joint].name.clone();
    assert!(!name.is_empty());
    h.get_by_label(&name).click_accesskit();
    h.run_steps(2);
    let sel = h.state().pose.joint.expect("a joint is selected");
    assert_eq!((sel.object, sel.joint), (id, joint));

    // Pause at the clip's start so the skeleton holds still while we aim at it.
    let steps = h.state().editor.history().undo_len();
    let frames = h.state().editor.joint_frames(id).expect("joint frames");
    let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
    let p = frames.position(joint).unwrap();
    let w = frames.world_from_joint[joint];
    // The ring that faces the camera most: a drag along it turns the joint by the angle swept.
    let view_dir = (p - proj.eye()).normalize_or_zero();
    let axis = (0..3)
        .max_by(|&a, &b| {
            let fa = w.col(a).truncate().normalize_or_zero().dot(view_dir).abs();
            let fb = w.col(b).truncate().normalize_or_zero().dot(view_dir).abs();
            fa.total_cmp(&fb)
        })
        .unwrap();
    let a = w.col(axis).truncate().normalize_or_zero();
    let (u, v) = a.any_orthonormal_pair();
    let size = 70.0 * proj.world_per_point(p);
    let on_ring = |t: f32| {
        proj.to_screen(p + size * (t.cos() * u + t.sin() * v))
            .expect("the ring is in front of the camera")
    };
    h.hover_at(on_ring(0.0));
    h.step();
    h.drag_at(on_ring(0.0));
    h.step();
    for k in 1..=6 {
        h.hover_at(on_ring(0.1 * k as f32));
        h.step();
    }
    h.drop_at(on_ring(0.6));
    h.run_steps(2);

    let ed = &h.state().editor;
    let o = ed
        .joint_override(id, joint)
        .expect("the drag posed the joint");
    let (_, angle) = o.rotation.expect("a rotation").to_axis_angle();
    assert!(
        (0.3..=0.9).contains(&angle),
        "the joint turned by about the swept 0.6 rad: {angle}"
    );
    assert_eq!(ed.history().undo_len(), steps + 1, "one undo step per drag");
    assert_eq!(
        view_of(ed.doc().camera),
        view_of(proj.camera),
        "dragging the gizmo does not orbit"
    );
    let posed_tip = ed.joint_frames(id).unwrap().position(joint + 1);
    assert!(ed.is_dirty());
    settle_preview(&mut h);
    if let Some((ms, [w, hh])) = h.state().view.cpu_preview().stats() {
        eprintln!("CPU preview of the posed figure: {ms:.1} ms at {w} x {hh} px");
    }
    snapshot(&mut h, "pose_rigged_figure");

    // Undo and redo through the Edit menu and the keyboard.
    h.get_by_label("Edit").click();
    h.run_steps(2);
    h.get_by_label_contains("Undo").click();
    h.run_steps(2);
    assert!(h.state().editor.joint_override(id, joint).is_none());
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::Z,
    );
    h.run_steps(2);
    assert_eq!(h.state().editor.joint_override(id, joint), Some(o));
    assert_eq!(
        h.state()
            .editor
            .joint_frames(id)
            .unwrap()
            .position(joint + 1),
        posed_tip
    );

    // G switches the gizmo to arrows; dragging one moves the joint along that axis of its
    // parent's frame (one more undo step), and undo takes only that step back.
    h.key_press(egui::Key::G);
    h.run_steps(1);
    assert_eq!(h.state().pose.mode, thicket::ui::pose::GizmoMode::Translate);
    let steps = h.state().editor.history().undo_len();
    let frames = h.state().editor.joint_frames(id).unwrap();
    let p = frames.position(joint).unwrap();
    let parent = frames.world_from_parent[joint];
    let size = 70.0 * proj.world_per_point(p);
    let center = proj.to_screen(p).unwrap();
    let (axis, arrow) = (0..3)
        .map(|k| {
            let d = parent.col(k).truncate().normalize_or_zero();
            (k, proj.to_screen(p + d * size).unwrap() - center)
        })
        .max_by(|a, b| a.1.length().total_cmp(&b.1.length()))
        .unwrap();
    let grab = center + arrow * 0.7;
    let pull = arrow.normalized() * 25.0;
    h.hover_at(grab);
    h.step();
    h.drag_at(grab);
    h.step();
    for k in 1..=3 {
        h.hover_at(grab + pull * (k as f32 / 3.0));
        h.step();
    }
    h.drop_at(grab + pull);
    h.run_steps(2);
    let moved = h
        .state()
        .editor
        .joint_override(id, joint)
        .and_then(|o| o.translation)
        .expect("the arrow moved the joint");
    assert!(moved[axis] > 0.0, "along +{axis}: {moved}");
    let others = (0..3)
        .filter(|&k| k != axis)
        .map(|k| moved[k].abs())
        .sum::<f32>();
    assert!(others < 1e-6, "only along the dragged axis: {moved}");
    assert_eq!(h.state().editor.history().undo_len(), steps + 1);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(1);
    assert_eq!(h.state().editor.joint_override(id, joint), Some(o));

    // The timeline plays the clip; playing moves the playhead but is not an edit.
    let key = h.state().editor.animation_key();
    let steps = h.state().editor.history().undo_len();
    h.get_by_label("Play").click();
    h.run_steps(3);
    let t = h.state().editor.rig(id).unwrap().playback.time_secs;
    assert!(t > 0.0, "the playhead moved: {t}");
    assert_ne!(h.state().editor.animation_key(), key);
    assert_eq!(
        h.state().editor.history().undo_len(),
        steps,
        "playing is not an edit"
    );
    // By the wall clock (kittest's clock advances 0.25 s per frame): two frames play 0.5 s of
    // clip, not two capped frame steps.
    let playback = |h: &Harness<'static, EditorApp>| h.state().editor.rig(id).unwrap().playback;
    let t0 = playback(&h).time_secs;
    h.run_steps(2);
    let duration =
        h.state().editor.rig(id).unwrap().clips[playback(&h).clip.unwrap()].duration_secs;
    let played = (playback(&h).time_secs - t0).rem_euclid(duration);
    assert!(
        (played - 0.5_f32.rem_euclid(duration)).abs() < 1e-3,
        "played {played} s of a {duration} s clip in 0.5 s"
    );
    h.get_by_label("Pause").click();
    h.run_steps(1);
    assert!(!h.state().pose.playing);

    // Stretch: the strategy picker is one undoable edit.
    let steps = h.state().editor.history().undo_len();
    h.get(
        egui_kittest::kittest::by()
            .role(egui::accesskit::Role::ComboBox)
            .value("Thesis"),
    )
    .click_accesskit();
    h.run_steps(2);
    h.get_by_label("Adaptive").click_accesskit();
    h.run_steps(2);
    assert_eq!(
        h.state().editor.rig(id).unwrap().stretch.strategy,
        thicket_core::skin::StretchStrategy::Adaptive
    );
    assert_eq!(h.state().editor.history().undo_len(), steps + 1);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(1);
    assert_eq!(
        h.state().editor.rig(id).unwrap().stretch.strategy,
        thicket_core::skin::StretchStrategy::Thesis
    );
}

/// Ctrl+Z (`redo`: Ctrl+Shift+Z) `n` times, a frame after each.
fn press_undo(h: &mut Harness<'static, EditorApp>, n: usize, redo: bool) {
    let mods = if redo {
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT
    } else {
        egui::Modifiers::COMMAND
    };
    for _ in 0..n {
        h.key_press_modifiers(mods, egui::Key::Z);
        h.run_steps(1);
    }
}

/// The coral preset alone, framed, without shadows or AO (a quick CPU preview).
fn coral_doc() -> Document {
    let mut doc = Document::default();
    doc.add(
        "Coral",
        ObjectKind::Krs(thicket_core::krs::presets::coral()),
    );
    doc.quality.shadows = false;
    doc.quality.ao_samples = 0;
    if let Some((lo, hi)) = doc.bounds() {
        doc.camera.frame(lo, hi);
    }
    doc
}

#[test]
fn mirror_planes_show_only_for_the_level_being_edited_while_the_krs_editor_is_open() {
    use thicket::ui::krs_panel::{mirror_outlines, pick_mirror};
    let mut h = harness(coral_doc());
    // (planes drawn, gizmo handles, whether a click on each drawn outline picks that plane)
    let shown = |h: &Harness<'static, EditorApp>| {
        let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
        let (editor, krs) = (&h.state().editor, &h.state().krs);
        let outlines = mirror_outlines(editor, krs, &proj);
        let picked = outlines.iter().all(|o| {
            let (seg, _) = o.segments[o.segments.len() / 2];
            pick_mirror(editor, krs, &proj, seg[0].lerp(seg[1], 0.5)) == Some(o.index)
        });
        let mut drawn: Vec<usize> = outlines.iter().map(|o| o.index).collect();
        drawn.sort_unstable();
        (drawn, krs.mirror_handles(editor, &proj).len(), picked)
    };
    // Nothing is being edited yet: no plane clutters the view.
    assert_eq!(shown(&h), (vec![], 0, true));
    h.get_by_label("R0").click_accesskit();
    h.run_steps(1);
    let (drawn, handles, picked) = shown(&h);
    assert_eq!(drawn, [0], "only the highlighted plane");
    assert!(
        handles == 3 && picked,
        "the highlighted plane has its gizmo and is pickable"
    );
    // Opening kernel K2's entry edits that level: its plane R2 is drawn (and pickable) too.
    h.get_by_label_contains("K2: ").click_accesskit();
    h.run_steps(2);
    assert_eq!(shown(&h), (vec![0, 2], 3, true));
    // Each outline is the plane clipped to the object's bounding box: the centre of the box
    // projects inside the box's outline, and every outline point is a point of the box.
    let ed = &h.state().editor;
    let k = ed.doc().objects[0].krs_in_world().unwrap();
    let (c, r) = k.bounding_sphere_object().unwrap();
    for m in [0, 2] {
        let polygon = thicket::ui::krs_panel::plane_in_box(
            k.mirrors[m].normal,
            k.mirrors[m].offset,
            c - Vec3::splat(r),
            c + Vec3::splat(r),
        );
        assert!(polygon.len() >= 3, "R{m} cuts the box");
        for p in &polygon {
            assert!((*p - c).abs().max_element() <= r * (1.0 + 1e-5), "{p}");
        }
    }
    // Folding the KRS editor away hides the planes, their gizmo and their picking.
    h.get_by_label("KRS editor").click_accesskit();
    h.run_steps(3);
    assert!(!h.state().krs.editor_open);
    assert_eq!(shown(&h), (vec![], 0, true));
    h.get_by_label("KRS editor").click_accesskit();
    h.run_steps(3);
    assert_eq!(shown(&h), (vec![0, 2], 3, true));
}

#[test]
fn change_a_krs_mirror_plane_through_its_arrow_and_normal_fields_undo_redo() {
    let mut h = harness(coral_doc());
    let id = h.state().editor.doc().objects[0].id;
    let original = h.state().editor.krs(id).unwrap().clone();
    assert!(!original.mirrors.is_empty());

    // The inspector's KRS editor lists the mirror planes; highlight R0 in the view.
    h.get_by_label("R0").click_accesskit();
    h.run_steps(1);
    assert_eq!(h.state().krs.mirror, Some(0));

    // Drag R0's gizmo arrow (along the plane's normal) in the view: the plane moves along its
    // normal, in one undo step, and the camera stays.
    let steps = h.state().editor.history().undo_len();
    let camera = h.state().editor.doc().camera;
    let proj = Projector::new(camera, h.state().view.last_rect);
    let handles = h.state().krs.mirror_handles(&h.state().editor, &proj);
    let arrow = handles
        .iter()
        .find(|s| s.handle == thicket::ui::krs_panel::MirrorHandle::Offset)
        .expect("the highlighted plane has an arrow");
    let (a, b) = (arrow.points[0], arrow.points[1]);
    let grab = a + (b - a) * 0.7;
    let along = (b - a).normalized() * 30.0;
    h.hover_at(grab);
    h.step();
    h.drag_at(grab);
    h.step();
    for k in 1..=3 {
        h.hover_at(grab + along * (k as f32 / 3.0));
        h.step();
    }
    h.drop_at(grab + along);
    h.run_steps(2);
    let moved = h.state().editor.krs(id).unwrap().mirrors[0];
    assert_eq!(moved.normal, original.mirrors[0].normal.normalize_or_zero());
    assert!(
        moved.offset > original.mirrors[0].offset + 1e-3,
        "dragging the arrow outward moves the plane along its normal: {:?} -> {moved:?}",
        original.mirrors[0]
    );
    assert_eq!(h.state().editor.history().undo_len(), steps + 1);
    assert_eq!(
        view_of(h.state().editor.doc().camera),
        view_of(camera),
        "no orbit"
    );
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(1);
    assert_eq!(h.state().editor.krs(id).unwrap().mirrors, original.mirrors);

    // Set normal components through the DragValues of R0 (the first "nx", "ny", "nz"): each
    // is kept as given and the other two are scaled to make a unit normal.
    let steps = h.state().editor.history().undo_len();
    h.query_all_by_label("nx")
        .next()
        .unwrap()
        .set_value_accesskit(0.6);
    h.run_steps(2);
    let m = h.state().editor.krs(id).unwrap().mirrors[0];
    assert!(
        (m.normal.x - 0.6).abs() < 1e-6 && (m.normal.length() - 1.0).abs() < 1e-5,
        "x kept, the normal stored normalised: {m:?}"
    );
    h.query_all_by_label("nz")
        .next()
        .unwrap()
        .set_value_accesskit(0.0);
    h.run_steps(2);
    let m = h.state().editor.krs(id).unwrap().mirrors[0];
    assert!(
        m.normal.z.abs() < 1e-6
            && (m.normal.x - 0.6).abs() < 1e-5
            && (m.normal.y.abs() - 0.8).abs() < 1e-5,
        "z set to 0, x and y scaled together: {m:?}"
    );
    let changed = h.state().editor.history().undo_len() - steps;
    assert!((1..=2).contains(&changed), "{changed} steps");

    // A value beyond 1 is clamped: the normal becomes that axis, never zero.
    h.query_all_by_label("ny")
        .next()
        .unwrap()
        .set_value_accesskit(-3.0);
    h.run_steps(2);
    let now = h.state().editor.krs(id).unwrap().mirrors[0];
    assert!((now.normal - Vec3::NEG_Y).length() < 1e-6, "{now:?}");
    assert!(h.state().krs.error.is_none());
    settle_preview(&mut h);
    if let Some((ms, [w, hh])) = h.state().view.cpu_preview().stats() {
        eprintln!("CPU preview of the coral: {ms:.1} ms at {w} x {hh} px");
    }
    snapshot(&mut h, "krs_mirror_edited");

    // Undo every step of the edit: the preset's plane is back; redo brings the change back.
    let after = h.state().editor.krs(id).unwrap().clone();
    let n = h.state().editor.history().undo_len() - steps;
    press_undo(&mut h, n, false);
    assert_eq!(h.state().editor.krs(id).unwrap().mirrors, original.mirrors);
    press_undo(&mut h, n, true);
    assert_eq!(h.state().editor.krs(id).unwrap(), &after);
}

#[test]
fn a_typed_normal_component_stays_as_typed_until_enter_then_the_normal_is_unit() {
    let mut h = harness(coral_doc());
    let id = h.state().editor.doc().objects[0].id;
    // A fork plane with a normal off every axis (R0, the leaf's, is along x).
    let i = h
        .state()
        .editor
        .krs(id)
        .unwrap()
        .mirrors
        .iter()
        .position(|m| m.normal.abs().min_element() > 0.05 && (m.normal.x - 0.2).abs() > 0.05);
    let i = i.expect("a tilted plane");
    let before = h.state().editor.krs(id).unwrap().mirrors[i];
    let steps = h.state().editor.history().undo_len();
    // Click its "nx" field to type into it (its text is selected), and type 0.2.
    h.query_all_by_label("nx").nth(i).unwrap().click_accesskit();
    h.run_steps(2);
    let field = h.get_by(|n| n.is_focused());
    field.type_text("0.2");
    h.run_steps(3);
    // While typing, the field shows what was typed and the plane has not changed.
    assert_eq!(h.get_by(|n| n.is_focused()).value().as_deref(), Some("0.2"));
    assert_eq!(h.state().editor.krs(id).unwrap().mirrors[i], before);
    assert_eq!(h.state().editor.history().undo_len(), steps);
    // Enter commits: x is 0.2 and the other two are scaled to make a unit normal.
    h.key_press(egui::Key::Enter);
    h.run_steps(2);
    assert!(h.query_by(|n| n.is_focused()).is_none(), "the field let go");
    let m = h.state().editor.krs(id).unwrap().mirrors[i];
    assert!(
        (m.normal.x - 0.2).abs() < 1e-6 && (m.normal.length() - 1.0).abs() < 1e-5,
        "{m:?}"
    );
    let rest = |n: Vec3| Vec3::new(0.0, n.y, n.z).normalize_or_zero();
    assert!(
        (rest(m.normal) - rest(before.normal)).length() < 1e-5,
        "y and z keep their proportions: {before:?} -> {m:?}"
    );
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");
}

/// Clicks "Start from the default tree" and confirms it with Replace.
fn start_from_the_default_tree(h: &mut Harness<'static, EditorApp>) {
    h.get_by_label("Start from the default tree")
        .click_accesskit();
    h.run_steps(2);
    h.get_by_label("Replace").click_accesskit();
    h.run_steps(2);
}

/// projects/tree.thicket.json without shadows or AO (a quick CPU preview).
fn tree_sample() -> Document {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../projects/tree.thicket.json");
    let mut doc = thicket_core::io::project::load(std::path::Path::new(path)).unwrap();
    doc.quality.shadows = false;
    doc.quality.ao_samples = 0;
    doc
}

#[test]
fn the_tree_sample_opens_in_the_builder_and_the_default_tree_asks_first() {
    let doc = tree_sample();
    let id = doc.object_by_name("Tree").expect("a tree").id;
    let stored = doc
        .tree_params_of(id)
        .cloned()
        .expect("the sample has its parameters");
    assert_eq!(stored, thicket_core::krs::presets::tree_params());
    let mut h = harness(doc);
    h.state_mut().editor.selection = Some(thicket::editor::Selection::Object(id));
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("Not built by the tree builder")
            .is_none()
    );
    h.get_by_label("Edit tree").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().krs.tree.as_ref().map(|t| &t.1), Some(&stored));
    // The builder rebuilds the same tree from them: nothing changes until an edit.
    let built = stored.build().unwrap();
    let tree = h.state().editor.krs(id).unwrap().clone();
    assert_eq!(
        (&built.kernels, &built.mirrors),
        (&tree.kernels, &tree.mirrors)
    );
    h.get_by_label("Close builder").click_accesskit();
    h.run_steps(2);

    // "Start from the default tree" asks before it replaces anything; Cancel keeps the tree.
    let steps = h.state().editor.history().undo_len();
    h.get_by_label("Start from the default tree")
        .click_accesskit();
    h.run_steps(2);
    h.get_by_label("Replace this object with the default tree?");
    assert_eq!(h.state().editor.krs(id).unwrap(), &tree);
    assert!(h.state().krs.tree.is_none(), "the builder stays closed");
    h.get_by_label("Cancel").click_accesskit();
    h.run_steps(2);
    assert!(
        h.query_by_label("Replace this object with the default tree?")
            .is_none()
    );
    assert_eq!(h.state().editor.krs(id).unwrap(), &tree);
    assert_eq!(h.state().editor.history().undo_len(), steps);
}

#[test]
fn a_krs_object_the_builder_did_not_make_says_so_and_is_replaced_only_when_confirmed() {
    let mut doc = Document::default();
    doc.add("Rock", ObjectKind::Krs(thicket_core::krs::presets::rock()));
    doc.quality.shadows = false;
    doc.quality.ao_samples = 0;
    let mut h = harness(doc);
    let id = h.state().editor.doc().objects[0].id;
    let rock = h.state().editor.krs(id).unwrap().clone();
    h.get_by_label("Not built by the tree builder: its kernels are not a branch route");
    assert!(h.query_by_label("Edit tree").is_none());
    let steps = h.state().editor.history().undo_len();
    h.get_by_label("Start from the default tree")
        .click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().editor.krs(id).unwrap(), &rock, "not replaced yet");
    h.get_by_label("Replace").click_accesskit();
    h.run_steps(2);
    let params = thicket_core::krs::TreeParams::default();
    assert_eq!(h.state().krs.tree.as_ref().map(|t| &t.1), Some(&params));
    assert_eq!(h.state().editor.tree_params(id), Some(&params));
    assert_eq!(
        h.state().editor.krs(id).unwrap().kernels,
        params.build().unwrap().validated(0).unwrap().kernels
    );
    assert_eq!(h.state().editor.history().undo_len(), steps + 1);
    assert!(
        h.query_by_label_contains("Not built by the tree builder")
            .is_none()
    );
    press_undo(&mut h, 1, false);
    assert_eq!(h.state().editor.krs(id).unwrap(), &rock);
}

#[test]
fn the_tree_sample_shows_the_plane_of_the_level_being_edited_clipped_and_faded() {
    use thicket::ui::krs_panel::{FAR_ALPHA, mirror_outlines};
    let doc = tree_sample();
    let id = doc.object_by_name("Tree").expect("a tree").id;
    let mut h = harness(doc);
    h.state_mut().editor.selection = Some(thicket::editor::Selection::Object(id));
    h.run_steps(2);
    // The trunk's fork: the last mirror of the tree (the coarsest level).
    let last = h.state().editor.krs(id).unwrap().mirrors.len() - 1;
    h.get_by_label(&format!("R{last}")).click_accesskit();
    h.run_steps(2);
    let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
    let outlines = mirror_outlines(&h.state().editor, &h.state().krs, &proj);
    assert_eq!(outlines.len(), 1, "one plane: the level being edited");
    let o = &outlines[0];
    assert_eq!(o.index, last);
    let alphas: Vec<f32> = o.segments.iter().map(|(_, a)| *a).collect();
    let (lo, hi) = alphas
        .iter()
        .fold((f32::INFINITY, 0.0f32), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(
        hi == 1.0 && (FAR_ALPHA..0.5).contains(&lo),
        "the outline fades with distance: {lo}..{hi}"
    );
    // Clipped to the object's box: the outline stays within the box's projection.
    let k = h
        .state()
        .editor
        .doc()
        .objects
        .iter()
        .find(|o| o.id == id)
        .unwrap();
    let (blo, bhi) = k.world_bounds().unwrap();
    let corners: Vec<egui::Pos2> = thicket_core::scene::box_corners(blo, bhi)
        .iter()
        .filter_map(|c| proj.to_screen(*c))
        .collect();
    let screen_box = egui::Rect::from_points(&corners).expand(1.0);
    assert!(
        o.segments
            .iter()
            .all(|(s, _)| screen_box.contains(s[0]) && screen_box.contains(s[1]))
    );
    settle_preview(&mut h);
    snapshot(&mut h, "krs_tree_plane_edited");
}

#[test]
fn importing_a_skinned_gltf_gives_a_rigged_model_with_a_timeline() {
    let mut h = harness(Document::default());
    let path = std::path::PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/skinned/RiggedFigure.glb"
    ));
    h.state_mut().start_import(path);
    let ctx = h.ctx.clone();
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    let ed = &h.state().editor;
    let o = ed.doc().objects.last().expect("an imported object");
    let rig = ed.rig(o.id).expect("the skin came along as a rig");
    assert_eq!(rig.skeleton.len(), 19, "RiggedFigure has 19 joints");
    assert_eq!(rig.clips.len(), 1);
    match &o.kind {
        ObjectKind::Voxels(v) => assert!(v.svo.has_skin() && v.svo.leaf_count() > 1000),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => panic!("expected voxels"),
    }
    // The timeline appears for it and shows the clip's length.
    h.get_by_label("Play");
    h.get_by_label_contains("/ 1.25 s");
    // The Import report says the depth it was voxelized at (the CLI's default) and imports it
    // again at another: the object is replaced by one with a coarser octree.
    let (voxels7, depth7) = match &o.kind {
        ObjectKind::Voxels(v) => (v.svo.leaf_count(), v.svo.depth()),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => unreachable!(),
    };
    assert_eq!(depth7, 7);
    let report = h
        .state()
        .import_report
        .clone()
        .expect("a report for a skinned import");
    assert_eq!(report.skinned_depth, Some(7));
    assert!(
        report.lines[0].starts_with("skinned: voxelized at depth 7"),
        "{:?}",
        report.lines
    );
    h.state_mut().import_report.as_mut().unwrap().skinned_depth = Some(6);
    h.run_steps(1);
    h.get_by_label("Import again at this depth").click();
    h.run_steps(1);
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    let ed = &h.state().editor;
    assert_eq!(ed.doc().objects.len(), 1, "replaced, not added");
    match &ed.doc().objects[0].kind {
        ObjectKind::Voxels(v) => {
            assert_eq!(v.svo.depth(), 6);
            assert!(
                v.svo.leaf_count() < voxels7 / 2,
                "{} vs {voxels7}",
                v.svo.leaf_count()
            );
            assert!(v.rig.is_some());
        }
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => panic!("expected voxels"),
    }
    assert_eq!(
        h.state()
            .import_report
            .as_ref()
            .and_then(|r| r.skinned_depth),
        Some(6)
    );
}

#[test]
fn the_tree_builder_rebuilds_from_a_dragged_fork_and_undoes() {
    let mut doc = Document::default();
    doc.add("Tree", ObjectKind::Krs(thicket_core::krs::presets::tree()));
    doc.quality.shadows = false;
    doc.quality.ao_samples = 0;
    // The tree's bounding ball is loose; aim at the tree itself.
    doc.camera.target = glam::Vec3::new(0.0, 3.0, 0.0);
    doc.camera.distance = 11.0;
    let mut h = harness(doc);
    let id = h.state().editor.doc().objects[0].id;
    let original = h.state().editor.krs(id).unwrap().clone();

    start_from_the_default_tree(&mut h);
    let route = h
        .state()
        .krs
        .tree
        .as_ref()
        .expect("the builder is open")
        .1
        .route
        .clone();
    let steps = h.state().editor.history().undo_len();

    // Drag the twig tip's handle 40 points to the right in the view.
    let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
    let tips = h.state().krs.route_points(&h.state().editor, &proj);
    let tip = tips
        .last()
        .copied()
        .flatten()
        .expect("the tip is on screen");
    h.hover_at(tip);
    h.step();
    h.drag_at(tip);
    h.step();
    for k in 1..=4 {
        h.hover_at(tip + egui::vec2(10.0 * k as f32, 0.0));
        h.step();
    }
    h.drop_at(tip + egui::vec2(40.0, 0.0));
    h.run_steps(2);
    let moved = h.state().krs.tree.as_ref().unwrap().1.route.clone();
    let last = route.len() - 1;
    assert_ne!(moved[last], route[last], "the tip moved");
    assert_eq!(moved[..last], route[..last], "only the tip moved");
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");
    let rebuilt = h.state().editor.krs(id).unwrap().clone();
    assert_ne!(rebuilt.kernels, original.kernels, "the object was rebuilt");
    settle_preview(&mut h);
    snapshot(&mut h, "krs_tree_builder");

    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(1);
    assert_ne!(h.state().editor.krs(id).unwrap(), &rebuilt);
}

#[test]
fn the_tree_builder_turns_a_fork_plane_with_its_normal_handle_and_undoes() {
    let mut doc = Document::default();
    doc.add("Tree", ObjectKind::Krs(thicket_core::krs::presets::tree()));
    doc.quality.shadows = false;
    doc.quality.ao_samples = 0;
    doc.camera.target = glam::Vec3::new(0.0, 3.0, 0.0);
    doc.camera.distance = 11.0;
    let mut h = harness(doc);
    let id = h.state().editor.doc().objects[0].id;
    start_from_the_default_tree(&mut h);
    // Every fork has a normal row in the builder, showing the normal in use.
    h.get_by_label("Fork 1 normal");
    let before = h.state().krs.tree.as_ref().expect("open").1.clone();
    let built = h.state().editor.krs(id).unwrap().clone();
    let steps = h.state().editor.history().undo_len();

    // Drag the first fork's normal handle 40 points to the right.
    let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
    let handles = h.state().krs.fork_normal_points(&h.state().editor, &proj);
    assert_eq!(handles.len(), before.route.len() - 2, "one handle per fork");
    let tip = handles[0].1.expect("the handle is on screen");
    h.hover_at(tip);
    h.step();
    h.drag_at(tip);
    h.step();
    for k in 1..=4 {
        h.hover_at(tip + egui::vec2(10.0 * k as f32, 0.0));
        h.step();
    }
    h.drop_at(tip + egui::vec2(40.0, 0.0));
    h.run_steps(2);
    let after = h.state().krs.tree.as_ref().unwrap().1.clone();
    assert_eq!(after.route, before.route, "the forks stay where they are");
    let (n0, n1) = (before.fork_mirror(1).normal, after.fork_mirror(1).normal);
    assert!(
        n0.angle_between(n1) > 0.05,
        "the plane turned: {n0} -> {n1}"
    );
    for k in 2..before.route.len() - 1 {
        assert_eq!(
            before.fork_mirror(k),
            after.fork_mirror(k),
            "fork {k} is untouched"
        );
    }
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");
    let rebuilt = h.state().editor.krs(id).unwrap().clone();
    assert_ne!(rebuilt.mirrors, built.mirrors, "the object was rebuilt");
    settle_preview(&mut h);
    snapshot(&mut h, "krs_tree_fork_normal");

    press_undo(&mut h, 1, false);
    assert_eq!(h.state().editor.krs(id).unwrap(), &built);
    press_undo(&mut h, 1, true);
    assert_eq!(h.state().editor.krs(id).unwrap(), &rebuilt);

    // "Default fork planes" forgets the edited normal: the default tree again, one more step.
    h.get_by_label("Default fork planes").click_accesskit();
    h.run_steps(2);
    assert!(
        h.state()
            .krs
            .tree
            .as_ref()
            .unwrap()
            .1
            .fork_normals
            .is_empty()
    );
    assert_eq!(h.state().editor.krs(id).unwrap(), &built);
    assert_eq!(h.state().editor.history().undo_len(), steps + 2);
    press_undo(&mut h, 1, false);
    assert_eq!(h.state().editor.krs(id).unwrap(), &rebuilt);
}

#[test]
fn the_hole_overlay_counts_fewer_holes_with_corner_stretch_than_without() {
    // Fine enough voxels that stretching matters (coarse ones bloat over every hole).
    let mut h = harness(rigged_figure(7));
    let id = h.state().editor.doc().objects[0].id;
    // A posed frame of the clip.
    let mut playback = h.state().editor.rig(id).unwrap().playback;
    playback.time_secs = 0.6;
    h.state_mut().editor.set_playback(id, playback).unwrap();
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label("Hole / bloat overlay").click();
    h.run_steps(2);
    h.key_press(egui::Key::Escape);
    assert!(h.state().view.show_holes);

    let mut counts = Vec::new();
    for strategy in [
        thicket_core::skin::StretchStrategy::Off,
        thicket_core::skin::StretchStrategy::Corners,
    ] {
        let mut s = h.state().editor.rig(id).unwrap().stretch;
        s.strategy = strategy;
        h.state_mut().editor.set_stretch(id, s).unwrap();
        settle_preview(&mut h);
        let c = h
            .state()
            .view
            .cpu_preview()
            .hole_counts()
            .expect("hole counts");
        eprintln!("{strategy:?}: {c:?}");
        counts.push(c);
    }
    assert!(counts[0].mesh_pixels > 1000, "{counts:?}");
    assert!(
        counts[0].holes > 0,
        "unstretched voxels leave holes in this pose: {counts:?}"
    );
    assert_eq!(
        counts[0].mesh_pixels, counts[1].mesh_pixels,
        "same pose, same mesh"
    );
    assert!(
        counts[1].holes <= counts[0].holes,
        "corner stretch closes holes: {counts:?}"
    );
    snapshot(&mut h, "pose_hole_overlay");
}

#[test]
fn the_stretch_heat_map_follows_the_multiplier_and_painted_overrides() {
    let mut h = harness(rigged_figure(5));
    let id = h.state().editor.doc().objects[0].id;
    let mut s = h.state().editor.rig(id).unwrap().stretch;
    s.strategy = thicket_core::skin::StretchStrategy::Off;
    h.state_mut().editor.set_stretch(id, s).unwrap();
    h.state_mut().editor.end_interaction();
    settle_preview(&mut h);
    let plain_ms = h.state().view.cpu_preview().stats().map(|(ms, _)| ms);
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label("Stretch heat map").click();
    h.run_steps(2);
    h.key_press(egui::Key::Escape);
    assert!(h.state().view.show_stretch);
    settle_preview(&mut h);
    // No stretch: every splat has its voxel's own size.
    let off = h
        .state()
        .view
        .cpu_preview()
        .stretch_stats()
        .expect("heat map statistics");
    // Figures for the report (no timing assert).
    eprintln!(
        "CPU preview without / with the heat map: {plain_ms:?} / {:?} ms",
        h.state().view.cpu_preview().stats().map(|(ms, _)| ms)
    );
    assert!(off.pixels > 500, "{off:?}");
    assert!(
        (off.min - 1.0).abs() < 1e-4 && (off.max - 1.0).abs() < 1e-4,
        "{off:?}"
    );
    // Thesis: min(2, W) for W joints with weight, within the settings' range.
    s.strategy = thicket_core::skin::StretchStrategy::Thesis;
    h.state_mut().editor.set_stretch(id, s).unwrap();
    h.state_mut().editor.end_interaction();
    settle_preview(&mut h);
    let base = h.state().view.cpu_preview().stretch_stats().unwrap();
    eprintln!("Thesis x1: {base:?}");
    assert!(base.min >= 1.0 - 1e-4 && base.max <= 2.0 + 1e-4, "{base:?}");
    assert!(base.mean > 1.0, "blended voxels stretch: {base:?}");

    // The multiplier scales every factor.
    s.multiplier = 1.5;
    h.state_mut().editor.set_stretch(id, s).unwrap();
    h.state_mut().editor.end_interaction();
    settle_preview(&mut h);
    let scaled = h.state().view.cpu_preview().stretch_stats().unwrap();
    assert!(
        (scaled.max - 1.5 * base.max).abs() < 1e-3,
        "{scaled:?} vs {base:?}"
    );
    assert!(
        (scaled.min - 1.5 * base.min).abs() < 1e-3,
        "{scaled:?} vs {base:?}"
    );
    s.multiplier = 1.0;
    h.state_mut().editor.set_stretch(id, s).unwrap();
    h.state_mut().editor.end_interaction();
    settle_preview(&mut h);

    // Paint overrides with the stretch brush across the figure's middle: S, Stretch, factor
    // 3.5, one stroke, one undo step; the heat map shows the painted factor.
    h.key_press(egui::Key::S);
    h.run_steps(1);
    h.get_by_label("Stretch paint").click();
    h.run_steps(2);
    assert!(h.state().sculpt.stretch_paint);
    h.state_mut().sculpt.stretch_factor = 3.5;
    h.state_mut().sculpt.brush.radius = 3.0;
    let rect = h.state().view.last_rect;
    let (lo, hi) = h
        .state()
        .editor
        .object(id)
        .and_then(thicket_core::scene::Object::world_bounds)
        .unwrap();
    let proj = Projector::new(h.state().editor.doc().camera, rect);
    let mid = proj.to_screen((lo + hi) * 0.5).expect("on screen");
    let hit = h
        .state()
        .view
        .cpu_preview()
        .hit(&h.state().editor, rect, mid);
    assert!(
        hit.is_some_and(|(o, _)| o == id),
        "the figure is under the brush"
    );
    let steps = h.state().editor.history().undo_len();
    h.hover_at(mid);
    h.step();
    h.drag_at(mid);
    h.step();
    for k in 1..=5 {
        h.hover_at(mid + egui::vec2(0.0, 8.0 * k as f32));
        h.step();
    }
    h.drop_at(mid + egui::vec2(0.0, 40.0));
    h.run_steps(2);
    let painted = h.state().editor.rig(id).unwrap().stretch_overrides.len();
    assert!(painted > 0, "the stroke painted overrides");
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");
    settle_preview(&mut h);
    let with = h.state().view.cpu_preview().stretch_stats().unwrap();
    // Leaves drawn as leaves show the painted 3.5; LOD may draw some as their parents.
    assert!(
        with.max > 2.1 && with.max <= 3.5 + 0.02,
        "the painted factor shows: {with:?}"
    );
    snapshot(&mut h, "pose_stretch_heatmap");

    h.key_press(egui::Key::Escape);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(1);
    let count =
        |h: &Harness<'static, EditorApp>| h.state().editor.rig(id).unwrap().stretch_overrides.len();
    assert_eq!(count(&h), 0);
    // Redo, then the inspector's Clear overrides removes them all in one step.
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::Z,
    );
    h.run_steps(2);
    assert_eq!(count(&h), painted);
    h.get_by_label_contains(&format!("{painted} voxel(s) with a painted"));
    // The inspector scrolls: an accessibility click reaches a button below the fold.
    h.get_by_label("Clear overrides").click_accesskit();
    h.run_steps(2);
    assert_eq!(count(&h), 0);
}

#[test]
fn scale_a_joint_and_key_it_on_the_timeline() {
    let mut h = harness(rigged_figure(5));
    let id = h.state().editor.doc().objects[0].id;
    let rig = h.state().editor.rig(id).unwrap().clone();
    let joint = 2;
    h.get_by_label(&rig.skeleton.joints[joint].name)
        .click_accesskit();
    h.run_steps(2);
    h.get_by_label("Scale joint").click();
    h.run_steps(2);
    // Drag the handle of the axis that shows longest on the screen outward by half its length.
    let frames = h.state().editor.joint_frames(id).unwrap();
    let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
    let p = frames.position(joint).unwrap();
    let w = frames.world_from_joint[joint];
    let size = 70.0 * proj.world_per_point(p);
    let c = proj.to_screen(p).unwrap();
    let (axis, end) = (0..3)
        .filter_map(|a| {
            let d = w.col(a).truncate().normalize_or_zero();
            proj.to_screen(p + d * size).map(|e| (a, e))
        })
        .max_by(|x, y| (x.1 - c).length().total_cmp(&(y.1 - c).length()))
        .unwrap();
    let steps = h.state().editor.history().undo_len();
    h.hover_at(end);
    h.step();
    h.drag_at(end);
    h.step();
    let out = (end - c) * 0.5;
    for k in 1..=4 {
        h.hover_at(end + out * (k as f32 / 4.0));
        h.step();
    }
    h.drop_at(end + out);
    h.run_steps(2);
    let o = h
        .state()
        .editor
        .joint_override(id, joint)
        .expect("the drag scaled the joint");
    let scale = o.scale.expect("a scale");
    assert!(
        (scale[axis] - 1.5).abs() < 0.1,
        "about 1.5 along the dragged axis: {scale}"
    );
    assert!((scale[(axis + 1) % 3] - 1.0).abs() < 1e-6);
    assert_eq!(
        h.state().editor.history().undo_len(),
        steps + 1,
        "one step per drag"
    );

    // Set key at the playhead, through the timeline's button: the clip holds the pose.
    let mut playback = h.state().editor.rig(id).unwrap().playback;
    playback.time_secs = 0.5;
    playback.wrap = thicket_core::skin::Wrap::Clamp;
    h.state_mut().editor.set_playback(id, playback).unwrap();
    h.run_steps(1);
    let posed = h.state().editor.rig(id).unwrap().current_pose().locals[joint];
    h.get_by_label("Set key").click();
    h.run_steps(2);
    assert!(h.state().editor.joint_override(id, joint).is_none());
    let keyed = h.state().editor.rig(id).unwrap().current_pose().locals[joint];
    assert!(
        (keyed.scale - posed.scale).length() < 1e-4,
        "{keyed:?} vs {posed:?}"
    );
    let times = h.state().editor.joint_key_times(id, joint);
    assert!(times.iter().any(|t| (t - 0.5).abs() < 1e-3), "{times:?}");
    h.get_by_label_contains("key(s) in this clip");
    settle_preview(&mut h);
    snapshot(&mut h, "pose_scaled_keyed");
    // Delete key removes it again (one step), undo brings it back.
    h.get_by_label("Delete key").click();
    h.run_steps(2);
    let after = h.state().editor.joint_key_times(id, joint);
    assert!(!after.iter().any(|t| (t - 0.5).abs() < 1e-3), "{after:?}");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(1);
    assert_eq!(h.state().editor.joint_key_times(id, joint), times);
}

#[test]
fn a_saved_tree_reopens_in_the_builder_with_its_parameters() {
    let mut doc = Document::default();
    doc.add("Tree", ObjectKind::Krs(thicket_core::krs::presets::tree()));
    doc.quality.shadows = false;
    doc.quality.ao_samples = 0;
    let mut h = harness(doc);
    let id = h.state().editor.doc().objects[0].id;
    start_from_the_default_tree(&mut h);
    // Thicken the trunk through the builder's state and a rebuild (what the width field does).
    let mut params = h.state().krs.tree.as_ref().unwrap().1.clone();
    params.widths[0] *= 1.4;
    h.state_mut().editor.build_tree(id, &params).unwrap();
    h.state_mut().editor.end_interaction();
    h.run_steps(2);
    assert_eq!(
        h.state().krs.tree.as_ref().unwrap().1,
        params,
        "the builder shows the document's"
    );

    // Save, open the file in a fresh editor: the builder reopens with those parameters.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tree.thicket.json");
    thicket_core::io::project::save(h.state().editor.doc(), &path).unwrap();
    let loaded = thicket_core::io::project::load(&path).unwrap();
    assert_eq!(loaded.tree_params_of(id), Some(&params));
    let mut h = harness(loaded);
    h.get_by_label("Edit tree").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().krs.tree.as_ref().map(|t| &t.1), Some(&params));
    assert!(h.query_by_label("Start from the default tree").is_none());
    // Undo after a rebuild in the reopened builder returns the saved parameters to it.
    let mut p2 = params.clone();
    p2.widths[0] *= 0.5;
    h.state_mut().editor.build_tree(id, &p2).unwrap();
    h.state_mut().editor.end_interaction();
    h.run_steps(1);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(2);
    assert_eq!(h.state().krs.tree.as_ref().map(|t| &t.1), Some(&params));
}

#[test]
fn the_cpu_preview_halves_its_resolution_while_orbiting_and_refines_to_full_when_still() {
    let mut h = harness(rigged_figure(5));
    // Half resolution whatever the frames cost (the adaptive budget is tested below).
    h.state_mut().view.motion_budget_ms = None;
    settle_preview(&mut h);
    let rect = h.state().view.last_rect;
    let full = [rect.width().round() as u32, rect.height().round() as u32];
    let (_, shown) = h
        .state()
        .view
        .cpu_preview()
        .stats()
        .expect("a preview was shown");
    assert_eq!(
        shown, full,
        "a still view renders at the view's full resolution"
    );

    // Orbit: while the camera keeps moving the preview renders half the pixels per side.
    let c = rect.center();
    h.hover_at(c);
    h.step();
    h.drag_at(c);
    h.step();
    let mut draft = None;
    for k in 1..=6 {
        h.hover_at(c + egui::vec2(12.0 * k as f32, 0.0));
        h.step();
        draft = draft.or(h.state().view.cpu_preview().in_flight());
    }
    let draft = draft.expect("orbiting started a preview render");
    assert!(
        draft[0].abs_diff(full[0] / 2) <= 1 && draft[1].abs_diff(full[1] / 2) <= 1,
        "{draft:?} is not half of {full:?}"
    );
    h.drop_at(c + egui::vec2(72.0, 0.0));
    // Still again: the next renders refine to full resolution.
    settle_preview(&mut h);
    let (_, shown) = h.state().view.cpu_preview().stats().unwrap();
    assert_eq!(shown, full);
}

#[test]
fn a_krs_edit_previews_at_the_scale_that_fits_the_motion_budget_then_refines() {
    use egui::accesskit::Role;
    use thicket::ui::view::moving_scale;
    // The view's full size now (the side panel's width follows its text, so measure each time).
    let full = |h: &Harness<'static, EditorApp>| {
        let rect = h.state().view.last_rect;
        [rect.width().round() as u32, rect.height().round() as u32]
    };
    // Edits a KRS parameter from a still view and returns the view's full size and the size of
    // the render the edit started.
    let edit = |h: &mut Harness<'static, EditorApp>, amplitude: f64| {
        // Still first: the last frame is a full one, which the scale is estimated from.
        settle_preview(h);
        let (_, shown) = h
            .state()
            .view
            .cpu_preview()
            .stats()
            .expect("a preview was shown");
        assert_eq!(shown, full(h), "a still view renders at full resolution");
        h.get_by_role_and_label(Role::SpinButton, "Amplitude")
            .set_value_accesskit(amplitude);
        let mut started = None;
        for _ in 0..3 {
            h.step();
            started = started.or(h
                .state()
                .view
                .cpu_preview()
                .in_flight()
                .map(|s| (full(h), s)));
        }
        started.expect("the edit started a preview render")
    };
    let mut h = harness(coral_doc());
    h.state_mut().view.renderer = thicket::ui::view::ViewRenderer::Cpu;
    h.get_by_label("Noise warp").click_accesskit();
    h.run_steps(2);

    // A budget the last frame's time per pixel cannot meet at half: a quarter of the view.
    h.state_mut().view.motion_budget_ms = Some(1e-6);
    let (f, quarter) = edit(&mut h, 0.2);
    assert!(
        quarter[0].abs_diff(f[0] / 4) <= 1 && quarter[1].abs_diff(f[1] / 4) <= 1,
        "{quarter:?} is not a quarter of {f:?}"
    );
    // A budget met at half: half, as without a budget.
    h.state_mut().view.motion_budget_ms = Some(1e9);
    let (f, half) = edit(&mut h, 0.25);
    assert!(
        half[0].abs_diff(f[0] / 2) <= 1 && half[1].abs_diff(f[1] / 2) <= 1,
        "{half:?} is not half of {f:?}"
    );
    // The default budget: the scale the last (full, still) frame's cost gives.
    let budget = thicket::ui::view::PREVIEW_MOTION_BUDGET_MS;
    h.state_mut().view.motion_budget_ms = Some(budget);
    settle_preview(&mut h);
    let (ms, [w, hh]) = h.state().view.cpu_preview().stats().unwrap();
    let (f, drawn) = edit(&mut h, 0.3);
    let full_px = f64::from(f[0]) * f64::from(f[1]);
    let expected = moving_scale(Some((ms, u64::from(w) * u64::from(hh))), full_px, budget);
    assert!(
        drawn[0].abs_diff((f[0] as f32 * expected).round() as u32) <= 1,
        "{drawn:?} at scale {expected} of {f:?} (the last frame took {ms:.1} ms)"
    );
    // Still again: full resolution.
    settle_preview(&mut h);
    assert_eq!(h.state().view.cpu_preview().stats().unwrap().1, full(&h));
}

#[test]
fn a_supersampled_preview_refines_at_one_sample_first_then_at_all_of_them() {
    use egui::accesskit::Role;
    let mut doc = coral_doc();
    doc.quality.supersample = 2;
    let mut h = harness(doc);
    h.state_mut().view.renderer = thicket::ui::view::ViewRenderer::Cpu;
    settle_preview(&mut h);
    let full = |h: &Harness<'static, EditorApp>| {
        let rect = h.state().view.last_rect;
        [rect.width().round() as u32, rect.height().round() as u32]
    };
    let shown = |h: &Harness<'static, EditorApp>| {
        let (_, size) = h
            .state()
            .view
            .cpu_preview()
            .stats()
            .expect("a preview was shown");
        (size, h.state().view.cpu_preview().supersample().unwrap())
    };
    assert_eq!(
        shown(&h),
        (full(&h), 2),
        "a still view ends at all its samples"
    );
    // An edit: moving frames at one sample, then the full size at one, then at two per side.
    h.get_by_label("Noise warp").click_accesskit();
    h.run_steps(2);
    h.get_by_role_and_label(Role::SpinButton, "Amplitude")
        .set_value_accesskit(0.2);
    h.step();
    let mut seen = Vec::new();
    for _ in 0..8 {
        h.state_mut().view.wait_for_cpu_preview();
        h.step();
        let s = shown(&h);
        if seen.last() != Some(&s) {
            seen.push(s);
        }
        if s == (full(&h), 2) {
            break;
        }
    }
    let f = full(&h);
    let one = seen.iter().position(|s| *s == (f, 1));
    let two = seen.iter().position(|s| *s == (f, 2));
    assert!(
        matches!((one, two), (Some(a), Some(b)) if a < b),
        "shown after the edit: {seen:?} (full {f:?})"
    );
    assert!(
        seen.iter().all(|(size, k)| *k == 1 || *size == f),
        "smaller frames draw one sample: {seen:?}"
    );
}

#[test]
fn applying_a_krs_preset_frames_the_result() {
    // The coral framed, then the forest preset applied over it: a much larger object, which
    // the view must show whole (the coral used to sit behind the gizmo, out of frame).
    let mut doc = Document::default();
    doc.add(
        "Coral",
        ObjectKind::Krs(thicket_core::krs::presets::coral()),
    );
    doc.quality.shadows = false;
    if let Some((lo, hi)) = doc.bounds() {
        doc.camera.frame(lo, hi);
    }
    let mut h = harness(doc);
    let before = h.state().editor.doc().camera;
    let forest = thicket_core::krs::presets::all()
        .iter()
        .position(|(n, _)| *n == "forest")
        .expect("a forest preset");
    h.state_mut().krs.preset = forest;
    h.run_steps(1);
    h.get_by_label("Apply preset").click();
    h.run_steps(2);
    let ed = &h.state().editor;
    let (lo, hi) = ed.doc().objects[0].world_bounds().expect("bounds");
    assert_ne!(
        view_of(ed.doc().camera),
        view_of(before),
        "the camera reframed"
    );
    let rect = h.state().view.last_rect;
    let cam = thicket_core::render::Camera::from_orbit(
        &ed.doc().camera,
        rect.width() as u32,
        rect.height() as u32,
    );
    // A KRS object's box is its bounding ball's: the ball's outline must be in view (the
    // points of the ball farthest to the sides of and above and below its centre on screen).
    let (centre, radius) = ((lo + hi) * 0.5, (hi.x - lo.x) * 0.5);
    let camera = ed.doc().camera;
    let forward = (camera.target - camera.eye()).normalize_or_zero();
    let right = forward.cross(Vec3::Y).normalize_or_zero();
    let up = right.cross(forward);
    for d in [right, -right, up, -up] {
        let p = centre + d * radius;
        let s = cam.world_to_screen(p);
        assert!(
            (0.0..=rect.width()).contains(&s.x) && (0.0..=rect.height()).contains(&s.y),
            "the forest's ball reaches {p}, at {s}, outside the view"
        );
    }
}

#[test]
fn a_joint_picked_in_the_view_scrolls_into_the_joint_list() {
    let mut h = harness(rigged_figure(5));
    let id = h.state().editor.doc().objects[0].id;
    let rig = h.state().editor.rig(id).expect("rigged").clone();
    let last = rig.skeleton.len() - 1;
    let name = rig.skeleton.joints[last].name.clone();
    assert!(!name.is_empty(), "RiggedFigure names its joints");
    let row_top = |h: &Harness<'static, EditorApp>| {
        h.query_all_by_label(&name)
            .map(|n| n.rect().min.y)
            .fold(f32::INFINITY, f32::min)
    };
    let before = row_top(&h);
    // The list holds about ten rows: the last joint starts below its visible part.
    let first_row = h
        .query_all_by_label(&rig.skeleton.joints[0].name)
        .map(|n| n.rect().min.y)
        .fold(f32::INFINITY, f32::min);
    assert!(before - first_row > 220.0, "{before} vs {first_row}");
    // Picking a joint as the view's joint dots do: the list scrolls to its row.
    h.state_mut().pose.joint = Some(thicket::ui::pose::JointRef {
        object: id,
        joint: last,
    });
    h.run_steps(3);
    let after = row_top(&h);
    assert!(
        after - first_row < 220.0 && after < before,
        "the row went from {before} to {after} (list top {first_row})"
    );
}

#[test]
fn edit_distortion_and_texturing_refuse_bad_values_undo_redo() {
    use egui::accesskit::Role;
    let mut h = harness(coral_doc());
    let id = h.state().editor.doc().objects[0].id;
    let original = h.state().editor.krs(id).unwrap().clone();
    let steps = h.state().editor.history().undo_len();
    let set = |h: &mut Harness<'static, EditorApp>, label: &str, v: f64| {
        h.get_by_role_and_label(Role::SpinButton, label)
            .set_value_accesskit(v);
        h.run_steps(2);
    };

    // Warp off, then on again from the defaults, then amplitude and frequency typed in: the
    // Lipschitz bound and the step cost follow.
    h.get_by_label("No warp").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().editor.krs(id).unwrap().distortion, None);
    assert!(
        h.query_by_role_and_label(Role::SpinButton, "Amplitude")
            .is_none()
    );
    h.get_by_label("Noise warp").click_accesskit();
    h.run_steps(2);
    set(&mut h, "Amplitude", 0.3);
    set(&mut h, "Frequency", 2.0);
    set(&mut h, "Seed", 9.0);
    let d = h
        .state()
        .editor
        .krs(id)
        .unwrap()
        .distortion
        .expect("warped");
    assert_eq!((d.amplitude, d.frequency, d.seed), (0.3, 2.0, 9));
    h.get_by_label("L = 6.400");
    h.get_by_label_contains("steps 16% as long, up to 6.40×");
    // A negative amplitude is refused by core: the document keeps 0.3 and the panel says why.
    set(&mut h, "Amplitude", -1.0);
    assert_eq!(h.state().editor.krs(id).unwrap().distortion, Some(d));
    h.get_by_label_contains("amplitude -1 must be finite and ≥ 0");

    // Texturing: a triplanar checker, scale, contrast and sharpness; a contrast over 1 is
    // refused.
    h.get_by_label("Triplanar").click_accesskit();
    h.run_steps(2);
    h.get_by_label("Checker").click_accesskit();
    h.run_steps(2);
    set(&mut h, "Scale", 2.5);
    set(&mut h, "Contrast", 0.8);
    set(&mut h, "Sharpness", 12.0);
    let t = h.state().editor.krs(id).unwrap().texturing;
    assert_eq!(
        (t.mode, t.pattern, t.scale, t.contrast, t.sharpness),
        (
            thicket_core::krs::TextureMode::Triplanar,
            thicket_core::krs::Pattern::Checker,
            2.5,
            0.8,
            12.0
        )
    );
    set(&mut h, "Contrast", 1.5);
    assert_eq!(h.state().editor.krs(id).unwrap().texturing, t);
    h.get_by_label_contains("1.5 is outside 0..=1");
    // Scroll the inspector to the new sections for the snapshot (the refusal stays above).
    h.get_by_role_and_label(Role::SpinButton, "Sharpness")
        .scroll_to_me();
    h.run_steps(2);
    settle_preview(&mut h);
    snapshot(&mut h, "krs_distortion_texturing_edited");

    // Every step undone gives the preset back; redone, the edit.
    let after = h.state().editor.krs(id).unwrap().clone();
    let n = h.state().editor.history().undo_len() - steps;
    assert!(
        n >= 2,
        "the warp and the texturing are undoable ({n} steps)"
    );
    press_undo(&mut h, n, false);
    assert_eq!(h.state().editor.krs(id).unwrap(), &original);
    press_undo(&mut h, n, true);
    assert_eq!(h.state().editor.krs(id).unwrap(), &after);
}

#[test]
fn empty_zones_are_added_removed_and_undone_in_the_krs_editor() {
    let mut h = harness(coral_doc());
    let id = h.state().editor.doc().objects[0].id;
    let zones =
        |h: &Harness<'static, EditorApp>| h.state().editor.krs(id).unwrap().empty_zones.clone();
    assert!(zones(&h).is_empty());
    let steps = h.state().editor.history().undo_len();
    h.get_by_label("Add zone").click_accesskit();
    h.run_steps(2);
    let added = zones(&h);
    assert_eq!(added.len(), 1, "one zone");
    // At the coral's bounding-ball centre, a quarter of its radius.
    let k = h.state().editor.doc().objects[0].krs_in_world().unwrap();
    let (c, r) = k.bounding_sphere_object().unwrap();
    let t = k.world_from_object;
    assert!((added[0].centre - t.transform_point(c)).length() < 1e-4);
    assert!((added[0].radius - 0.25 * r * t.scale).abs() < 1e-4);
    h.get_by_label("Z0");
    assert_eq!(h.state().editor.history().undo_len(), steps + 1);
    h.get_by_label("Remove").click_accesskit();
    h.run_steps(2);
    assert!(zones(&h).is_empty(), "removed");
    press_undo(&mut h, 1, false);
    assert_eq!(zones(&h), added, "undo brings the zone back");
    press_undo(&mut h, 1, false);
    assert!(zones(&h).is_empty(), "and before it, none");
    press_undo(&mut h, 2, true);
    assert!(zones(&h).is_empty(), "redo: added, then removed");
}

/// An animated MagicaVoxel file (three models, no scene graph: frames of 2, 3 and 4 voxels),
/// imported as the editor imports it.
fn animated_vox_doc() -> Document {
    let bytes = common::animated_vox_bytes();
    let scene = thicket_core::io::vox::import_vox_bytes(
        &bytes,
        std::path::Path::new("walk.vox"),
        &thicket_core::io::vox::VoxImportOptions::default(),
    )
    .unwrap();
    let mut doc = Document::default();
    scene.add_to(&mut doc);
    let (lo, hi) = doc.bounds().unwrap();
    doc.camera.frame(lo, hi);
    doc
}

#[test]
fn the_timeline_plays_an_animated_vox_one_frame_at_a_time() {
    let mut h = harness(animated_vox_doc());
    let id = h.state().editor.doc().objects[0].id;
    let shown = |h: &Harness<'static, EditorApp>| h.state().editor.frames(id).unwrap().shown;
    let leaves = |h: &Harness<'static, EditorApp>| match &h.state().editor.object(id).unwrap().kind
    {
        ObjectKind::Voxels(v) => v.svo.leaf_count(),
        _ => 0,
    };
    h.get_by_label("frame 1 / 3 at 10 fps");
    assert_eq!((shown(&h), leaves(&h)), (0, 2));
    let steps = h.state().editor.history().undo_len();
    h.get_by_label("Play").click();
    // kittest's clock advances 0.25 s per frame: the first playing frame starts the clock,
    // the next is at 0.25 s, frame 2 of 0.1 s frames.
    h.run_steps(2);
    assert_eq!((shown(&h), leaves(&h)), (2, 4));
    h.get_by_label("frame 3 / 3 at 10 fps");
    h.run_steps(1);
    // Past the end the sequence loops; whatever the frame, it is the one at the playhead and
    // the only one drawn.
    let seq = h.state().editor.frames(id).unwrap().clone();
    assert!(seq.time_secs < seq.duration_secs());
    assert_eq!(shown(&h), seq.frame_at(seq.time_secs));
    assert_eq!(leaves(&h), [2, 3, 4][shown(&h)]);
    h.get_by_label("Pause").click();
    h.run_steps(1);
    assert!(!h.state().pose.playing);
    assert_eq!(
        h.state().editor.history().undo_len(),
        steps,
        "playing is not an edit"
    );
    h.get_by_label("Start").click();
    h.run_steps(1);
    assert_eq!((shown(&h), leaves(&h)), (0, 2));
}

/// The CPU preview keeps its shadow maps across a sculpt stroke and redraws only the texels
/// the stroke changed (the patched map equals a fresh one: core's `patch_tests`); the
/// Performance window says so. An edit it cannot describe by a box (a move) draws them whole.
#[test]
fn the_preview_redraws_only_the_shadow_texels_a_stroke_changed() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/house.thicket.json"
    );
    let doc = thicket_core::io::project::load(std::path::Path::new(path)).expect("house");
    let mut h = harness(doc);
    settle_preview(&mut h);
    // The first render of new content keeps no map; after an orbit step the maps are kept.
    let mut cam = h.state().editor.doc().camera;
    cam.yaw_deg += 2.0;
    h.state_mut().editor.set_camera(cam);
    settle_preview(&mut h);
    cam.yaw_deg += 2.0;
    h.state_mut().editor.set_camera(cam);
    settle_preview(&mut h);
    let kept = h.state().view.cpu_preview().shadows().expect("a render");
    assert_eq!((kept.reused, kept.patched), (1, 0), "{kept:?}");

    let id = h.state().editor.doc().objects[0].id;
    let center = h.state().editor.voxel_center(id).expect("voxels");
    // The first dab along the box's diagonal that changes voxels.
    h.state_mut().editor.begin_stroke();
    let changed = [1.0f32, 1.2, 0.8, 1.4, 0.6, 1.6, 0.4]
        .into_iter()
        .find_map(|t| {
            let brush = thicket_core::sculpt::Brush {
                radius: 3.0,
                ..Default::default()
            };
            h.state_mut()
                .editor
                .sculpt_dab(id, &brush, center * t, center)
                .expect("a dab")
        });
    assert!(changed.is_some(), "a dab changed voxels");
    h.state_mut().editor.end_interaction();
    // The first render after the dab (low resolution: the content moved) patches the map.
    h.run_steps(1);
    h.state_mut().view.wait_for_cpu_preview();
    h.run_steps(1);
    let patched = h.state().view.cpu_preview().shadows().expect("a render");
    eprintln!("after a dab: {patched:?} (kept before: {kept:?})");
    assert_eq!((patched.patched, patched.reused), (1, 0), "{patched:?}");
    assert!(patched.texels_patched > 0, "{patched:?}");
    // The full-resolution frame after it uses the patched map as it is.
    settle_preview(&mut h);
    let refined = h.state().view.cpu_preview().shadows().expect("a render");
    assert_eq!((refined.patched, refined.reused), (0, 1), "{refined:?}");

    // Undoing the stroke is a change of the same box (the change feed records it so): the
    // maps are patched again, not drawn whole.
    assert!(h.state_mut().editor.undo());
    h.run_steps(1);
    h.state_mut().view.wait_for_cpu_preview();
    h.run_steps(1);
    let undone = h.state().view.cpu_preview().shadows().expect("a render");
    eprintln!("after undo: {undone:?}");
    assert_eq!((undone.patched, undone.reused), (1, 0), "{undone:?}");
    assert!(undone.texels_patched > 0, "{undone:?}");
    settle_preview(&mut h);

    // A move is no voxel region: the maps are drawn whole.
    let mut t = h.state().editor.doc().objects[0].transform;
    t.translation.x += 0.5;
    h.state_mut().editor.set_transform(id, t).expect("a move");
    h.state_mut().editor.end_interaction();
    settle_preview(&mut h);
    let moved = h.state().view.cpu_preview().shadows().expect("a render");
    eprintln!("after a move: {moved:?}");
    assert_eq!((moved.patched, moved.reused), (0, 0), "{moved:?}");
}

/// The voxel coordinates of a voxel model's leaves.
fn leaves_of(h: &Harness<'static, EditorApp>, id: u64) -> std::collections::HashSet<glam::UVec3> {
    let mut out = std::collections::HashSet::new();
    if let Some(ObjectKind::Voxels(v)) = h.state().editor.object(id).map(|o| &o.kind) {
        v.svo.for_each_leaf(|c, _| {
            out.insert(c);
        });
    }
    out
}

#[test]
fn the_brush_adds_where_a_posed_figure_is_drawn_not_at_its_bind_pose() {
    // A ray cast in a rigged model's voxel grid finds its bind pose, which the clip moves away
    // from where the figure is drawn: the brush must act on the voxel drawn under the pointer.
    let mut doc = rigged_figure(7);
    let id = doc.objects[0].id;
    if let ObjectKind::Voxels(v) = &mut doc.objects[0].kind {
        let rig = v.rig.as_mut().expect("rigged");
        rig.playback.clip = Some(0);
        rig.playback.time_secs = 0.9;
    }
    let mut h = harness(doc);
    settle_preview(&mut h);
    h.key_press(egui::Key::S);
    h.run_steps(1);
    {
        let sculpt = &mut h.state_mut().sculpt;
        assert!(sculpt.active);
        sculpt.tool = thicket::ui::voxel_tools::ToolKind::Brush;
        sculpt.brush.op = thicket_core::sculpt::BrushOp::Add;
        sculpt.brush.radius = 1.0;
    }
    h.run_steps(1);
    let rect = h.state().view.last_rect;
    let camera = h.state().editor.doc().camera;
    let eye = camera.eye();
    // A pixel of the drawn figure where a ray cast in the model's voxel grid (its bind pose)
    // finds none of it, or a voxel far from the one the posed pick finds.
    let (voxel_from_world, svo) = match h.state().editor.object(id) {
        Some(o) => match &o.kind {
            ObjectKind::Voxels(v) => (
                (o.transform.matrix() * v.object_from_voxel()).inverse(),
                v.svo.clone(),
            ),
            _ => unreachable!("a voxel model"),
        },
        None => unreachable!("the figure"),
    };
    let mut chosen = None;
    'search: for j in 0..(rect.height() / 6.0) as i32 {
        for i in 0..(rect.width() / 6.0) as i32 {
            let p = rect.min + egui::vec2(6.0 * i as f32 + 3.0, 6.0 * j as f32 + 3.0);
            let editor = &h.state().editor;
            // The preview draws the figure there.
            if h.state()
                .view
                .cpu_preview()
                .hit(editor, rect, p)
                .map(|hit| hit.0)
                != Some(id)
            {
                continue;
            }
            let ndc = glam::Vec2::new(
                (p.x - rect.left()) / rect.width() * 2.0 - 1.0,
                1.0 - (p.y - rect.top()) / rect.height() * 2.0,
            );
            let Some((_, dir)) =
                thicket::editor::ray_through(camera.clip_from_world(rect.aspect_ratio()), ndc)
            else {
                continue;
            };
            let Some(posed) = editor.pick_voxel(eye, dir).filter(|pk| pk.object == id) else {
                continue;
            };
            let bind = svo.raycast(
                voxel_from_world.transform_point3(eye).as_dvec3(),
                voxel_from_world.transform_vector3(dir).as_dvec3(),
                f64::INFINITY,
            );
            // An Add dab fills the empty cell in front of the face hit: one inside the grid.
            let front = posed.voxel.as_ivec3() + posed.normal;
            let extent = 1i32 << svo.depth();
            let room = front.cmpge(glam::IVec3::ZERO).all()
                && front.cmplt(glam::IVec3::splat(extent)).all()
                && svo.get(front.as_uvec3()).is_none();
            if room && bind.is_none_or(|b| b.coord.as_vec3().distance(posed.voxel.as_vec3()) > 6.0)
            {
                chosen = Some((p, posed));
                break 'search;
            }
        }
    }
    let (p, posed) = chosen.expect("the pose moves part of the figure off its bind pose");
    // The posed ray cast finds what the renderer drew at that pixel (its node, give or take a
    // voxel of stretch and LOD).
    let (_, node) = h
        .state()
        .view
        .cpu_preview()
        .hit(&h.state().editor, rect, p)
        .expect("the figure is drawn there");
    let drawn = h
        .state()
        .editor
        .node_center(id, node)
        .expect("a node of the figure");
    assert!(
        drawn.distance(posed.voxel.as_vec3() + 0.5) <= 3.0,
        "picked {} where the preview draws {drawn}",
        posed.voxel
    );
    let before = leaves_of(&h, id);
    let steps = h.state().editor.history().undo_len();
    h.hover_at(p);
    h.step();
    h.drag_at(p);
    h.step();
    h.drop_at(p);
    h.run_steps(2);
    let after = leaves_of(&h, id);
    let added: Vec<_> = after.difference(&before).copied().collect();
    assert!(!added.is_empty(), "the dab added voxels");
    assert!(before.is_subset(&after), "an Add dab removes nothing");
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");
    // In front of the drawn voxel's face, within the brush's reach.
    let target = posed.voxel.as_vec3() + 0.5 + posed.normal.as_vec3();
    for c in &added {
        let d = (c.as_vec3() + 0.5).distance(target);
        assert!(
            d <= 1.0 + 1.5,
            "voxel {c} added {d} voxels from the dab at {target}"
        );
    }
}

/// During playback the CPU preview's image lags the playhead by its render time: the skeleton
/// is drawn posed as that image, not as the playhead, so the bones stay inside the limbs the
/// image shows; once the preview catches up, the skeleton is the playhead's pose again.
#[test]
fn the_skeleton_is_drawn_with_the_pose_of_the_image_shown() {
    let path = std::path::Path::new("../projects/critter.thicket.json");
    let doc = thicket::files::load_document(path).expect("the sample loads");
    let mut h = harness(doc);
    h.state_mut().view.renderer = thicket::ui::view::ViewRenderer::Cpu;
    settle_preview(&mut h);
    let id = h.state().editor.doc().objects[0].id;
    let positions = |f: &thicket::editor::JointFrames| -> Vec<Vec3> {
        (0..f.world_from_joint.len())
            .filter_map(|j| f.position(j))
            .collect()
    };
    let painted = |h: &Harness<'static, EditorApp>| {
        h.state()
            .pose
            .painted
            .iter()
            .find(|(o, _)| *o == id)
            .map(|(_, p)| p.clone())
            .expect("the skeleton is drawn")
    };
    let editor_pose =
        |h: &Harness<'static, EditorApp>| positions(&h.state().editor.joint_frames(id).unwrap());
    let image_pose = |h: &Harness<'static, EditorApp>| {
        let doc = h
            .state()
            .view
            .shown_pose_document(true)
            .expect("the image's document");
        positions(&thicket::editor::joint_frames_in(&doc, id).unwrap())
    };
    assert_eq!(
        painted(&h),
        editor_pose(&h),
        "still: the image is the playhead's"
    );
    h.state_mut().pose.step_every_frame = true;
    h.get_by_label("Play").click();
    let mut lagging = 0;
    for _ in 0..6 {
        // A frame: the playhead moves on, the preview's next image is still being drawn.
        h.run_steps(1);
        assert_eq!(
            painted(&h),
            image_pose(&h),
            "the skeleton is the image's pose"
        );
        if painted(&h) != editor_pose(&h) {
            lagging += 1;
        }
    }
    assert!(lagging > 0, "the image lagged the playhead in some frame");
    h.get_by_label("Pause").click();
    settle_preview(&mut h);
    assert_eq!(
        painted(&h),
        editor_pose(&h),
        "caught up: the playhead's pose"
    );
}

/// F3's Performance overlay shows the CPU preview's time per stage and its KRS rays when the
/// CPU preview draws the view, as it shows the GPU's per pass.
#[test]
fn the_performance_overlay_shows_the_cpu_preview_per_stage() {
    let path = std::path::Path::new("../projects/tree.thicket.json");
    let doc = thicket::files::load_document(path).expect("the sample loads");
    let mut h = harness(doc);
    h.state_mut().view.renderer = thicket::ui::view::ViewRenderer::Cpu;
    settle_preview(&mut h);
    h.key_press(egui::Key::F3);
    h.run_steps(2);
    h.get_by_label("Performance");
    let stats = h
        .state()
        .view
        .cpu_preview()
        .frame_stats()
        .expect("a render's statistics")
        .clone();
    assert!(stats.times.krs_ms > 0.0 && stats.krs.rays > 0, "{stats:?}");
    for stage in [
        "Shadow maps",
        "Octree traversal",
        "Splats",
        "Triangles",
        "KRS sphere tracing",
        "Resolve",
        "Shade",
        "Frame",
    ] {
        h.get_by_label(stage);
    }
    // The KRS pass's time, as the overlay prints it, and its rays.
    let krs_ms = format!("{:.3}", stats.times.krs_ms);
    assert!(h.query_all_by_label(&krs_ms).count() >= 1, "{krs_ms}");
    h.get_by_label_contains(&format!(
        "KRS: {} rays",
        thicket::files::thousands(stats.krs.rays)
    ));
}

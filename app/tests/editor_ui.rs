//! The real editor UI driven headlessly with egui_kittest (no GPU, no window): the outliner
//! lists the objects, clicking selects, the inspector shows real values, and undo/redo work
//! through the Edit menu.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use glam::{UVec3, Vec3};
use thicket::editor::{Editor, Selection};
use thicket::ui::EditorApp;
use thicket_core::scene::{Document, ObjectKind, VoxelModel};
use thicket_core::svo::{Svo, Voxel};

fn app_with_two_objects() -> EditorApp {
    let mut doc = Document::default();
    for (name, n) in [("Rock", 4u32), ("Tree", 7)] {
        let mut svo = Svo::new(4, false).unwrap();
        for x in 0..n {
            svo.set(UVec3::new(x, 0, 0), Voxel::new([90, 90, 90, 255], Vec3::Y))
                .unwrap();
        }
        doc.add(
            name,
            ObjectKind::Voxels(VoxelModel {
                svo,
                ..VoxelModel::default()
            }),
        );
    }
    EditorApp::new(Editor::new(doc, None))
}

fn harness(app: EditorApp) -> Harness<'static, EditorApp> {
    let mut h = Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    h
}

/// The outliner row of an object (the outliner is drawn before the inspector heading).
fn outliner_row<'h>(h: &'h Harness<'static, EditorApp>, name: &'h str) -> egui_kittest::Node<'h> {
    h.query_all_by_label(name).next().expect("an outliner row")
}

#[test]
fn clicking_the_outliner_selects_and_the_inspector_shows_counts() {
    let mut h = harness(app_with_two_objects());
    // Both objects are listed with their voxel counts.
    // The outliner is drawn before the inspector, so its row is the first match.
    assert!(h.query_all_by_label("Rock").count() >= 1);
    h.get_by_label("7 vox");
    outliner_row(&h, "Tree").click();
    h.run_steps(2);
    let tree_id = h.state().editor.doc().objects[1].id;
    assert_eq!(h.state().editor.selection, Some(Selection::Object(tree_id)));
    // The inspector heading and the real voxel count of the selection.
    assert!(
        h.query_all_by_label("Tree").count() >= 2,
        "outliner row + inspector heading"
    );
    // Depth 4 octree: the inspector shows the real value.
    h.get_by_label("4 (16³)");
}

#[test]
fn delete_then_undo_through_the_menus() {
    let mut h = harness(app_with_two_objects());
    outliner_row(&h, "Rock").click();
    h.run_steps(2);
    h.get_by_label("Edit").click();
    h.run_steps(2);
    // Menu buttons carry their shortcut in the label ("Delete Del").
    h.get_by_label_contains("Delete").click();
    h.run_steps(2);
    assert_eq!(h.state().editor.doc().objects.len(), 1);
    assert_eq!(h.query_all_by_label("Rock").count(), 0);
    h.get_by_label("Edit").click();
    h.run_steps(2);
    h.get_by_label_contains("Undo").click();
    h.run_steps(2);
    assert_eq!(h.state().editor.doc().objects.len(), 2);
    assert_eq!(h.state().editor.doc().objects[0].name, "Rock");
    assert!(h.query_all_by_label("Rock").count() >= 1);
}

#[test]
fn lights_are_added_and_deleted_from_the_outliner_and_undone_through_the_menu() {
    let mut h = harness(app_with_two_objects());
    assert_eq!(h.state().editor.doc().lights.len(), 1);
    h.get_by_label("Add light").click();
    h.run_steps(2);
    // The new light is listed, selected and shown in the inspector.
    assert_eq!(h.state().editor.doc().lights.len(), 2);
    assert_eq!(h.state().editor.selection, Some(Selection::Light(1)));
    assert!(
        h.query_all_by_label("Light: Light 2").count() >= 2,
        "outliner row + inspector heading"
    );
    // Delete (the key) removes the selected light.
    h.key_press(egui::Key::Delete);
    h.run_steps(2);
    assert_eq!(h.state().editor.doc().lights.len(), 1);
    assert_eq!(h.query_all_by_label("Light: Light 2").count(), 0);
    assert_eq!(h.state().editor.doc().objects.len(), 2, "no object deleted");
    h.get_by_label("Edit").click();
    h.run_steps(2);
    h.get_by_label_contains("Undo").click();
    h.run_steps(2);
    assert_eq!(h.state().editor.doc().lights.len(), 2);
    // Edit > Delete removes a selected light as it removes a selected object.
    h.get_by_label("Light: Light 2").click();
    h.run_steps(2);
    assert_eq!(h.state().editor.selection, Some(Selection::Light(1)));
    h.get_by_label("Edit").click();
    h.run_steps(2);
    h.get_by_label_contains("Delete").click();
    h.run_steps(2);
    assert_eq!(h.state().editor.doc().lights.len(), 1);
    assert_eq!(h.state().editor.doc().objects.len(), 2, "no object deleted");
}

#[test]
fn opening_a_broken_file_keeps_the_document_and_shows_the_error() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("broken.thicket.json");
    std::fs::write(&bad, "{ not json").unwrap();
    let mut h = harness(app_with_two_objects());
    let ctx = h.ctx.clone();
    h.state_mut().request_open(bad);
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    assert_eq!(
        h.state().editor.doc().objects.len(),
        2,
        "current document kept"
    );
    let msg = h.state().error_dialog.clone().expect("an error dialog");
    assert!(msg.contains("broken.thicket.json"), "{msg}");
    h.get_by_label("Could not complete the operation");
    h.get_by_label("OK").click();
    h.run_steps(2);
    assert!(h.state().error_dialog.is_none());
}

#[test]
fn autosave_goes_to_the_recovery_file_and_is_offered_on_the_next_start() {
    let dir = tempfile::tempdir().unwrap();
    let mut app = app_with_two_objects();
    app.recovery_dir = dir.path().to_path_buf();
    let rock = app.editor.doc().objects[0].id;
    app.editor.rename(rock, "Boulder").unwrap();
    app.autosave_now();
    app.wait_for_autosave()
        .expect("ran")
        .expect("autosave wrote");

    // The next start finds it and offers it in a dialog.
    let mut next = EditorApp::default();
    next.recovery_dir = dir.path().to_path_buf();
    next.check_recovery();
    let mut h = harness(next);
    h.get_by_label("Recover unsaved work?");
    h.get_by_label("Recover").click();
    h.run_steps(2);
    let app = h.state();
    assert!(app.recovery.is_none());
    assert_eq!(app.editor.doc().objects[0].name, "Boulder");
    assert!(app.editor.is_dirty(), "recovered work is unsaved");

    // Discard deletes it.
    let mut again = EditorApp::default();
    again.recovery_dir = dir.path().to_path_buf();
    again.check_recovery();
    assert!(again.recovery.is_some());
    again.discard_recovery();
    again.check_recovery();
    assert!(again.recovery.is_none());
}

#[test]
fn enhance_runs_as_a_job_and_cancel_keeps_the_document() {
    let mut app = app_with_two_objects();
    let mut svo = Svo::new(4, false).unwrap();
    for x in 2..8 {
        for y in 2..8 {
            for z in 2..8 {
                svo.set(UVec3::new(x, y, z), Voxel::new([90, 90, 90, 255], Vec3::Y))
                    .unwrap();
            }
        }
    }
    app.editor.add_object(
        "Block",
        ObjectKind::Voxels(VoxelModel {
            svo,
            ..VoxelModel::default()
        }),
    );
    let mut h = harness(app);
    let ctx = h.ctx.clone();
    h.state_mut().start_enhance(2);
    assert!(h.state().job_running());
    // Cancel at once (the worker may finish a tiny job before a frame could show the button):
    // its result is dropped whenever it arrives.
    h.state_mut().cancel_job(&ctx);
    std::thread::sleep(std::time::Duration::from_millis(200));
    h.run_steps(2);
    assert!(!h.state().job_running());
    assert_eq!(
        h.state().editor.doc().objects.len(),
        3,
        "cancelled: nothing added"
    );

    // Over the memory budget: refused before a job starts, with the estimate in the dialog.
    h.state_mut().memory_budget = thicket_core::budget::MemoryBudget::given(64 << 10);
    h.state_mut().start_enhance(2);
    assert!(!h.state().job_running(), "no job over the budget");
    let said = h
        .state()
        .error_dialog
        .clone()
        .expect("the refusal is shown");
    assert!(
        said.contains("x2 into about ")
            && said.contains("over the limit of 64.0 KiB")
            && said.ends_with("use a smaller factor"),
        "{said}"
    );
    h.state_mut().error_dialog = None;
    h.state_mut().memory_budget = thicket_core::budget::MemoryBudget::given(1 << 30);

    // Run to completion: a new enhanced object with more, smaller voxels.
    h.state_mut().start_enhance(2);
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(1);
    let doc = h.state().editor.doc();
    assert_eq!(doc.objects.len(), 4);
    assert_eq!(doc.objects[3].name, "Block enhanced");
    match (&doc.objects[2].kind, &doc.objects[3].kind) {
        (ObjectKind::Voxels(src), ObjectKind::Voxels(fine)) => {
            assert_eq!(fine.voxel_size, src.voxel_size / 2.0);
            assert!(fine.svo.leaf_count() > src.svo.leaf_count());
        }
        _ => panic!("voxel models"),
    }
}

#[test]
fn gltf_export_window_exports_the_selection_on_a_worker_thread() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tree.glb");
    let mut app = app_with_two_objects();
    app.native_dialogs = false;
    let mut h = harness(app);
    let ctx = h.ctx.clone();
    outliner_row(&h, "Tree").click();
    h.run_steps(2);
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Export glTF...").click();
    h.run_steps(2);
    assert!(h.state().gltf_export.open);
    // The KRS split: automatic by default, a level when unticked.
    assert_eq!(h.state().gltf_export.options.instance_level, None);
    h.get_by_label("Automatic").click();
    h.run_steps(2);
    assert_eq!(h.state().gltf_export.options.instance_level, Some(0));
    h.get_by_label("Automatic").click();
    h.run_steps(2);
    assert_eq!(h.state().gltf_export.options.instance_level, None);
    h.get_by_label("Smooth").click();
    h.get_by_label("Selected object only").click();
    h.run_steps(2);
    assert_eq!(
        h.state().gltf_export.options.mode,
        thicket_core::io::gltf_export::ExportMode::Smooth
    );
    assert!(h.state().gltf_export.selected_only);
    h.get_by_label("Export...").click();
    // The click, then the prompt's first (invisible, sizing) frame, then the prompt.
    h.run_steps(3);
    // No native dialog here: the path prompt asks for the file, named after the (untitled)
    // project.
    h.get_by_label("Export glTF (.glb or .gltf)");
    assert!(
        h.query_all_by_value("untitled.glb").next().is_some(),
        "an untitled project exports as untitled.glb"
    );
    let options = h.state().gltf_export.options_for(Some("Tree"));
    assert_eq!(
        options.mode,
        thicket_core::io::gltf_export::ExportMode::Smooth
    );
    assert_eq!(options.object.as_deref(), Some("Tree"));

    // What the prompt's OK starts: the job, then its toast.
    h.state_mut().start_export_gltf(path.clone());
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    let bytes = std::fs::read(&path).expect("the export was written");
    assert_eq!(&bytes[..4], b"glTF", "a GLB file");
    let (gltf_doc, _, _) = gltf::import(&path).expect("the file loads");
    let names: Vec<_> = gltf_doc
        .nodes()
        .filter_map(|n| n.name().map(str::to_owned))
        .collect();
    assert_eq!(names, ["Tree"], "only the selection: no lights or camera");
    // The toast and the status bar.
    assert!(
        h.query_all_by_label_contains("Exported 1 object(s)")
            .count()
            >= 1
    );
}

#[test]
fn an_enhanced_model_follows_a_sculpt_stroke_and_undo() {
    let mut app = app_with_two_objects();
    app.autosave_secs = 0;
    let mut svo = Svo::new(4, false).unwrap();
    for x in 2..10 {
        for y in 2..8 {
            for z in 2..10 {
                svo.set(UVec3::new(x, y, z), Voxel::new([90, 140, 90, 255], Vec3::Y))
                    .unwrap();
            }
        }
    }
    let block = app.editor.add_object(
        "Block",
        ObjectKind::Voxels(VoxelModel {
            svo,
            ..VoxelModel::default()
        }),
    );
    app.editor.frame_selection();
    let mut h = harness(app);
    let ctx = h.ctx.clone();
    // The inspector's Detail enhancement section: settings, then Enhance (a job).
    h.get_by_label("Detail enhancement").click();
    h.run_steps(3);
    h.get_by_label("Subdivide");
    h.get_by_label("Enhance").click();
    h.run_steps(1);
    assert!(h.state().job_running());
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(3);
    let settings = {
        let doc = h.state().editor.doc();
        let link = doc.enhancement_of(block).expect("linked");
        assert!(
            !h.state().editor.object(block).unwrap().visible,
            "source hidden"
        );
        assert_eq!(doc.objects.last().unwrap().name, "Block enhanced");
        link.settings.clone()
    };
    // The enhancement is selected; its section points at the source.
    h.get_by_label_contains("Enhancement of Block");
    h.get_by_label("Select source").click();
    h.run_steps(2);
    h.get_by_label_contains("updated while sculpting");

    // Sculpt a stroke through the view on the (hidden) coarse block: S, Remove, drag.
    h.key_press(egui::Key::S);
    h.run_steps(1);
    h.get_by_label("Remove").click();
    h.run_steps(1);
    let proj =
        thicket::ui::view::Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
    let center = proj.to_screen(Vec3::new(6.0, 5.0, 6.0)).expect("on screen");
    let steps = h.state().editor.history().undo_len();
    h.hover_at(center);
    h.step();
    h.drag_at(center);
    h.step();
    for k in 1..=4 {
        h.hover_at(center + egui::vec2(6.0 * k as f32, 0.0));
        h.step();
    }
    h.drop_at(center + egui::vec2(24.0, 0.0));
    h.run_steps(3);
    let ed = &h.state().editor;
    assert_eq!(ed.history().undo_len(), steps + 1, "one step per stroke");
    let coarse = match &ed.object(block).unwrap().kind {
        ObjectKind::Voxels(v) => v.svo.clone(),
        _ => unreachable!(),
    };
    assert!(
        coarse.leaf_count() < 8 * 6 * 8,
        "the stroke carved the block"
    );
    let target = ed.doc().enhancement_of(block).unwrap().target;
    let fine = match &ed.object(target).unwrap().kind {
        ObjectKind::Voxels(v) => v.svo.clone(),
        _ => unreachable!(),
    };
    let fresh = thicket_core::enhance::enhance(&coarse, &settings).unwrap();
    assert_eq!(fine, fresh, "the fine model equals a fresh enhancement");
    // The inspector reports the incremental update.
    h.get_by_label_contains("Last update:");

    // Edit -> Undo restores both models.
    h.key_press(egui::Key::Escape);
    h.get_by_label("Edit").click();
    h.run_steps(2);
    h.get_by_label_contains("Undo").click();
    h.run_steps(2);
    let ed = &h.state().editor;
    let (coarse, fine) = match (
        &ed.object(block).unwrap().kind,
        &ed.object(target).unwrap().kind,
    ) {
        (ObjectKind::Voxels(c), ObjectKind::Voxels(f)) => (c.svo.clone(), f.svo.clone()),
        _ => unreachable!(),
    };
    assert_eq!(coarse.leaf_count(), 8 * 6 * 8);
    assert_eq!(
        fine,
        thicket_core::enhance::enhance(&coarse, &settings).unwrap()
    );
}

/// A primary-button drag from `from` by `by` (an orbit with the Navigate tool).
fn drag_in_view(h: &mut Harness<'static, EditorApp>, from: egui::Pos2, by: egui::Vec2) {
    h.hover_at(from);
    h.step();
    h.drag_at(from);
    h.step();
    h.hover_at(from + by);
    h.step();
    h.drop_at(from + by);
    h.run_steps(2);
}

#[test]
fn orthographic_views_by_key_and_menu_and_orbiting_returns_to_perspective() {
    let mut h = harness(app_with_two_objects());
    let cam = |h: &Harness<'static, EditorApp>| h.state().editor.doc().camera;
    assert!(!cam(&h).orthographic);
    assert_eq!(thicket::ui::view::view_name(&cam(&h)), "User perspective");

    // 5 toggles the projection, with clip planes that hold the whole scene.
    h.key_press(egui::Key::Num5);
    h.run_steps(2);
    assert!(cam(&h).orthographic);
    let (lo, hi) = h.state().editor.doc().bounds().expect("bounds");
    let c = cam(&h);
    let forward = (c.target - c.eye()).normalize_or_zero();
    for p in [lo, hi] {
        let d = (p - c.eye()).dot(forward);
        assert!(c.near < d && d < c.far, "{d} outside {}..{}", c.near, c.far);
    }
    h.key_press(egui::Key::Num5);
    h.run_steps(2);
    assert!(!cam(&h).orthographic);

    // An axis view is orthographic and says so; orbiting away returns to perspective.
    h.key_press(egui::Key::Num1);
    h.run_steps(2);
    assert!(cam(&h).orthographic);
    assert_eq!((cam(&h).yaw_deg, cam(&h).pitch_deg), (0.0, 0.0));
    assert_eq!(thicket::ui::view::view_name(&cam(&h)), "Front orthographic");
    let c = h.state().view.last_rect.center();
    drag_in_view(&mut h, c, egui::vec2(40.0, 0.0));
    assert!(cam(&h).yaw_deg != 0.0, "the drag orbited");
    assert!(
        !cam(&h).orthographic,
        "orbiting left the axis view's orthographic projection"
    );
    assert_eq!(thicket::ui::view::view_name(&cam(&h)), "User perspective");

    // The View menu's checkbox sets it for good: orbiting keeps it.
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label("Orthographic (5)").click();
    h.run_steps(2);
    assert!(cam(&h).orthographic);
    h.key_press(egui::Key::Escape);
    h.run_steps(2);
    drag_in_view(&mut h, c, egui::vec2(0.0, 30.0));
    assert!(
        cam(&h).orthographic,
        "a chosen orthographic view stays orthographic"
    );
    // Saved in the project's camera.
    let json = serde_json::to_string(&h.state().editor.doc().camera).unwrap();
    assert!(json.contains("\"orthographic\":true"), "{json}");
}

#[test]
fn bracket_keys_step_the_brush_by_one_voxel() {
    let mut h = harness(app_with_two_objects());
    h.state_mut().sculpt.brush.radius = 2.0;
    h.key_press(egui::Key::CloseBracket);
    h.run_steps(2);
    assert_eq!(h.state().sculpt.brush.radius, 3.0);
    h.key_press(egui::Key::OpenBracket);
    h.key_press(egui::Key::OpenBracket);
    h.run_steps(2);
    assert_eq!(h.state().sculpt.brush.radius, 1.0);
    h.key_press_modifiers(egui::Modifiers::SHIFT, egui::Key::CloseBracket);
    h.run_steps(2);
    assert_eq!(h.state().sculpt.brush.radius, 2.0);
}

/// `n` presses of `key` delivered in one frame, as a fast burst (or a stalled frame) delivers them.
fn presses_in_one_frame(
    h: &mut Harness<'static, EditorApp>,
    modifiers: egui::Modifiers,
    key: egui::Key,
    n: usize,
) {
    for _ in 0..n {
        h.input_mut().events.push(egui::Event::Key {
            key,
            physical_key: None,
            pressed: true,
            repeat: false,
            modifiers,
        });
    }
    h.step();
}

#[test]
fn every_key_press_in_one_frame_steps_once() {
    let mut h = harness(app_with_two_objects());
    // `[` three times in one frame: three voxels smaller, not one.
    h.state_mut().sculpt.brush.radius = 5.0;
    presses_in_one_frame(&mut h, egui::Modifiers::NONE, egui::Key::OpenBracket, 3);
    assert_eq!(h.state().sculpt.brush.radius, 2.0);
    presses_in_one_frame(&mut h, egui::Modifiers::NONE, egui::Key::CloseBracket, 3);
    assert_eq!(h.state().sculpt.brush.radius, 5.0);

    // Copy the Rock's four voxels (x 0..4 on the floor's first row) and paste: it floats at 0.
    let rock = h.state().editor.doc().objects[0].id;
    let ed = &mut h.state_mut().editor;
    ed.selection = Some(Selection::Object(rock));
    assert_eq!(ed.select_all_voxels(rock), Ok(4));
    assert_eq!(ed.copy_voxels(), Ok(4));
    h.state_mut().sculpt.active = true;
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::V);
    h.run_steps(1);
    let at = |h: &Harness<'static, EditorApp>| h.state().editor.floating().map(|f| f.at);
    assert_eq!(at(&h), Some(glam::IVec3::ZERO), "the paste floats");
    presses_in_one_frame(&mut h, egui::Modifiers::NONE, egui::Key::ArrowDown, 3);
    assert_eq!(
        at(&h),
        Some(glam::IVec3::new(0, 0, 3)),
        "three rows along +Z"
    );
    h.key_press(egui::Key::Enter);
    h.run_steps(2);
    assert!(h.state().editor.floating().is_none(), "Enter placed it");

    // The placed copy is the selection: three presses move it three rows, three Ctrl+Z in one
    // frame undo the three moves.
    let rows = |h: &Harness<'static, EditorApp>| -> Vec<u32> {
        let ObjectKind::Voxels(v) = &h.state().editor.doc().objects[0].kind else {
            unreachable!()
        };
        let mut z: Vec<u32> = v.svo.leaves().iter().map(|(c, _)| c.z).collect();
        z.sort_unstable();
        z.dedup();
        z
    };
    assert_eq!(rows(&h), [0, 3]);
    presses_in_one_frame(&mut h, egui::Modifiers::NONE, egui::Key::ArrowDown, 3);
    assert_eq!(rows(&h), [0, 6], "the selection moved three rows");
    presses_in_one_frame(&mut h, egui::Modifiers::COMMAND, egui::Key::Z, 3);
    assert_eq!(rows(&h), [0, 3], "three undos, one per press");
}

/// File → Save As (Ctrl+Shift+S) on an untitled project, then `text` typed over the proposed
/// name in the path field.
fn save_as_typing(h: &mut Harness<'static, EditorApp>, text: &str) {
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::S,
    );
    h.run_steps(3);
    // The text input (its first match; the inner text run carries the value too).
    h.query_all_by_value("untitled.thicket.json")
        .next()
        .expect("the path field")
        .focus();
    h.run_steps(1);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    h.query_all_by_value("untitled.thicket.json")
        .next()
        .expect("the path field")
        .type_text(text);
    h.run_steps(2);
}

#[test]
fn the_path_entry_accepts_enter_and_cancels_on_escape() {
    let mut app = app_with_two_objects();
    app.native_dialogs = false;
    let mut h = harness(app);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("typed.thicket.json");
    // File → Save As (Ctrl+Shift+S) asks for the path; Esc closes the entry, saving nothing.
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::S,
    );
    h.run_steps(3);
    h.get_by_label("Save as");
    h.key_press(egui::Key::Escape);
    h.run_steps(3);
    assert!(
        h.query_by_label("Save as").is_none(),
        "Esc closed the entry"
    );
    assert!(h.state().editor.path().is_none());

    // Typed path + Enter saves there (no click on OK).
    save_as_typing(&mut h, &path.display().to_string());
    h.key_press(egui::Key::Enter);
    h.run_steps(4);
    assert!(
        h.query_by_label("Save as").is_none(),
        "Enter closed the entry"
    );
    assert_eq!(h.state().editor.path(), Some(path.as_path()));
    assert!(path.is_file(), "Enter saved the project to the typed path");
}

/// The editor on the Rock and Tree project saved as `dir/house.thicket.json`, path entry on.
fn saved_house(dir: &std::path::Path) -> Harness<'static, EditorApp> {
    let house = dir.join("house.thicket.json");
    let app = app_with_two_objects();
    thicket::files::save_project(app.editor.doc(), &house).expect("the project saves");
    let mut app = EditorApp::new(Editor::new(app.editor.doc().clone(), Some(house)));
    app.native_dialogs = false;
    app.autosave_secs = 0;
    harness(app)
}

#[test]
fn ctrl_a_in_the_path_entry_selects_its_text_not_the_voxels() {
    let mut app = app_with_two_objects();
    app.native_dialogs = false;
    let mut h = harness(app);
    // With the voxel tools and a voxel model selected, Ctrl+A selects every voxel...
    let rock = h.state().editor.doc().objects[0].id;
    h.state_mut().editor.selection = Some(Selection::Object(rock));
    h.state_mut().sculpt.active = true;
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    h.run_steps(1);
    let selected = |h: &Harness<'static, EditorApp>| {
        h.state()
            .editor
            .voxel_selection()
            .map(|s| s.cells.iter().count())
    };
    assert_eq!(selected(&h), Some(4));
    h.state_mut().editor.clear_voxel_selection();
    // ...but in the path entry it selects the field's text: typing replaces all of it.
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::S,
    );
    h.run_steps(3);
    assert!(
        h.query_all_by_value("untitled.thicket.json")
            .next()
            .expect("the path field")
            .is_focused(),
        "the entry's field has the keyboard"
    );
    // End drops the selection the entry opens with, so only Ctrl+A can select the text again.
    h.key_press(egui::Key::End);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    h.event(egui::Event::Text("mushroom.thicket.json".into()));
    h.run_steps(2);
    assert!(
        h.query_all_by_value("mushroom.thicket.json")
            .next()
            .is_some(),
        "the typed name replaced the field's text"
    );
    assert_eq!(selected(&h), None, "no voxel was selected");
}

#[test]
fn an_absolute_path_typed_after_the_prefilled_folder_opens_that_file() {
    let home = tempfile::tempdir().unwrap();
    let elsewhere = tempfile::tempdir().unwrap();
    let mut h = saved_house(home.path());
    let other = elsewhere.path().join("other.thicket.json");
    thicket::files::save_project(&Document::default(), &other).unwrap();
    let typed = other.display().to_string();
    let prefill = format!("{}/", home.path().display());
    // Open starts in the project's folder with the folder selected: typing replaces it.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::O);
    h.run_steps(3);
    h.query_all_by_value(&prefill)
        .next()
        .expect("the field starts in the project's folder");
    h.event(egui::Event::Text(typed.clone()));
    h.run_steps(2);
    h.query_all_by_value(&typed)
        .next()
        .expect("the typed path replaced the selected folder");
    h.key_press(egui::Key::Escape);
    h.run_steps(2);
    // Typed (or pasted) after the folder, the absolute path wins over the folder.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::O);
    h.run_steps(3);
    h.key_press(egui::Key::End);
    h.event(egui::Event::Text(typed.clone()));
    h.run_steps(2);
    h.query_all_by_value(&format!("{prefill}{typed}"))
        .next()
        .expect("the path follows the folder in the field");
    h.key_press(egui::Key::Enter);
    h.run_steps(2);
    let ctx = h.ctx.clone();
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    assert_eq!(h.state().editor.path(), Some(other.as_path()));
    assert!(
        h.state().editor.doc().objects.is_empty(),
        "the other project"
    );
}

#[test]
fn exports_are_named_after_the_project() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = saved_house(dir.path());
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Export .vox...").click();
    h.run_steps(3);
    let vox = dir.path().join("house.vox").display().to_string();
    h.query_all_by_value(&vox)
        .next()
        .expect("Export .vox proposes house.vox beside the project");
    h.key_press(egui::Key::Escape);
    h.run_steps(2);
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Export glTF...").click();
    h.run_steps(2);
    h.get_by_label("Export...").click();
    h.run_steps(3);
    let glb = dir.path().join("house.glb").display().to_string();
    h.query_all_by_value(&glb)
        .next()
        .expect("Export glTF proposes house.glb beside the project");
}

#[test]
fn esc_closes_an_open_menu_before_it_changes_the_tool() {
    let mut h = harness(app_with_two_objects());
    h.key_press(egui::Key::S);
    h.run_steps(1);
    assert!(h.state().sculpt.active, "S chose the brush");
    h.get_by_label("File").click();
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("Save As").is_some(),
        "the menu is open"
    );
    h.key_press(egui::Key::Escape);
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("Save As").is_none(),
        "Esc closed the menu"
    );
    assert!(h.state().sculpt.active, "and left the tool as it was");
    h.key_press(egui::Key::Escape);
    h.run_steps(2);
    assert!(
        !h.state().sculpt.active,
        "the next Esc goes back to navigating"
    );
}

#[test]
fn the_path_entry_browses_folders_and_keeps_the_typed_file_name() {
    let mut app = app_with_two_objects();
    app.native_dialogs = false;
    let mut h = harness(app);
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    std::fs::write(dir.path().join("old.thicket.json"), b"{}").unwrap();
    std::fs::write(dir.path().join("notes.txt"), b"not a project").unwrap();
    // Type a path in the folder: the list shows its sub-folder and its projects, not other files.
    let typed = dir.path().join("mine.thicket.json").display().to_string();
    save_as_typing(&mut h, &typed);
    h.get_by_label("sub/");
    assert!(
        h.query_all_by_label_contains("old.thicket.json")
            .next()
            .is_some(),
        "the folder's project is listed"
    );
    assert!(
        h.query_all_by_label_contains("notes.txt").next().is_none(),
        "files a project cannot be saved as are left out"
    );
    // A click on the sub-folder descends into it and keeps the typed name; OK saves there.
    h.get_by_label("sub/").click();
    h.run_steps(2);
    let expected = dir.path().join("sub").join("mine.thicket.json");
    h.query_all_by_value(&expected.display().to_string())
        .next()
        .expect("the field holds the folder and the typed name");
    assert!(
        h.query_all_by_label_contains("old.thicket.json")
            .next()
            .is_none(),
        "the list follows the field into the sub-folder"
    );
    h.get_by_label("OK").click();
    h.run_steps(3);
    assert!(h.query_by_label("Save as").is_none());
    assert_eq!(h.state().editor.path(), Some(expected.as_path()));
    assert!(expected.is_file(), "saved into the chosen folder");
}

#[test]
fn the_open_entry_lists_recent_files_and_a_double_click_opens_one() {
    let dir = tempfile::tempdir().unwrap();
    let saved = dir.path().join("recent.thicket.json");
    let mut app = app_with_two_objects();
    app.native_dialogs = false;
    thicket::files::save_project(app.editor.doc(), &saved).expect("the project saves");
    app.editor
        .push_recent(dir.path().join("deleted.thicket.json"));
    app.editor.push_recent(saved.clone());
    // kittest runs one frame per queued event, each `step_dt` long: at 1/60 s a click's
    // three events stay well inside egui's 0.3 s double-click time (the default 1/4 s does not).
    let mut h = Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .with_step_dt(1.0 / 60.0)
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::O);
    h.run_steps(3);
    h.get_by_label("Recent");
    let shown = saved.display().to_string();
    assert!(
        h.query_all_by_label(&shown).next().is_some(),
        "the saved project is a recent file"
    );
    assert!(
        h.query_all_by_label_contains("deleted.thicket.json")
            .next()
            .is_none(),
        "a recent file that no longer exists is not offered"
    );
    // A double-click.
    let row = h.query_all_by_label(&shown).next().unwrap();
    row.click();
    row.click();
    h.step();
    h.run_steps(2);
    assert!(
        h.query_by_label("Recent").is_none(),
        "the double-click accepted the entry"
    );
    let ctx = h.ctx.clone();
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    assert_eq!(h.state().editor.path(), Some(saved.as_path()));
    assert_eq!(h.state().editor.doc().objects.len(), 2);
}

#[test]
fn the_tool_bar_does_not_move_when_the_brush_size_gains_digits() {
    let mut h = harness(app_with_two_objects());
    h.state_mut()
        .sculpt
        .choose(thicket::ui::voxel_tools::ToolKind::Brush);
    h.state_mut().sculpt.brush.radius = 0.5;
    h.run_steps(2);
    let strength_at = |h: &Harness<'static, EditorApp>| h.get_by_label("Strength").rect();
    let before = strength_at(&h);
    // 0.5 → 12 → 256 voxels: one, two and three integer digits.
    for (radius, presses) in [(12.0_f32, 12), (256.0, 0)] {
        for _ in 0..presses {
            h.key_press(egui::Key::CloseBracket);
            h.run_steps(1);
        }
        if presses == 0 {
            h.state_mut().sculpt.brush.radius = radius;
        }
        h.run_steps(2);
        assert_eq!(h.state().sculpt.brush.radius, radius);
        assert_eq!(
            strength_at(&h),
            before,
            "the fields after the size stay where they were at radius {radius}"
        );
    }
}

#[test]
fn the_render_menu_marks_the_active_preset_or_custom() {
    use egui_kittest::kittest::NodeT as _;
    use thicket_core::quality::{Quality, QualityPreset};
    let mut h = harness(EditorApp::new(Editor::new(Document::default(), None)));
    let open_menu = |h: &mut Harness<'static, EditorApp>| {
        h.get_by_label("Render").click();
        h.run_steps(2);
    };
    let checked = |h: &Harness<'static, EditorApp>, label: &str| {
        h.get_by_label(label).accesskit_node().toggled() == Some(egui::accesskit::Toggled::True)
    };
    open_menu(&mut h);
    assert!(checked(&h, "Balanced"), "a new document is balanced");
    assert!(!checked(&h, "Draft") && !checked(&h, "Final"));
    assert!(h.query_by_label("Custom").is_none());
    h.get_by_label("Draft").click();
    h.run_steps(2);
    assert_eq!(
        h.state().editor.doc().quality,
        Quality::preset(QualityPreset::Draft)
    );
    h.key_press(egui::Key::Escape);
    h.run_steps(1);
    // A knob edited away from every preset: the menu says Custom, no preset is marked.
    let mut q = Quality::preset(QualityPreset::Draft);
    q.lod_pixel_threshold = 1.7;
    h.state_mut().editor.set_quality(q).expect("valid quality");
    open_menu(&mut h);
    assert!(checked(&h, "Custom"));
    assert!(!checked(&h, "Draft") && !checked(&h, "Balanced") && !checked(&h, "Final"));
}

#[test]
fn an_import_lists_what_it_left_out_in_the_import_report() {
    // One triangle with a morph target and a camera, written as .gltf + .bin.
    let dir = tempfile::tempdir().expect("temp dir");
    let floats: [f32; 18] = [
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, // positions
        0.0, 0.0, 0.5, 0.0, 0.0, 0.5, 0.0, 0.0, 0.5, // the morph target's offsets
    ];
    let bin: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    std::fs::write(dir.path().join("tri.bin"), &bin).expect("write bin");
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "buffers": [{"uri": "tri.bin", "byteLength": bin.len()}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 36}],
        "accessors": [
            {"bufferView": 0, "type": "VEC3", "componentType": 5126, "count": 3,
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "type": "VEC3", "componentType": 5126, "count": 3}],
        "meshes": [{"name": "Face", "primitives": [{"attributes": {"POSITION": 0}, "targets": [{"POSITION": 1}]}]}],
        "cameras": [{"name": "Shot", "type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "Key", "type": "directional", "color": [1.0, 0.5, 0.5]},
            {"type": "point"}]}},
        "extensionsUsed": ["KHR_lights_punctual"],
        "nodes": [{"mesh": 0}, {"camera": 0},
            {"extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"extensions": {"KHR_lights_punctual": {"light": 1}}}],
        "scenes": [{"nodes": [0, 1, 2, 3]}]
    });
    let path = dir.path().join("face.gltf");
    std::fs::write(&path, serde_json::to_vec(&gltf).expect("json")).expect("write gltf");

    let mut h = harness(EditorApp::new(Editor::new(Document::default(), None)));
    let ctx = h.ctx.clone();
    h.state_mut().start_import(path);
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    assert_eq!(
        h.state().editor.doc().objects.len(),
        1,
        "the triangle imported"
    );
    let lines = h
        .state()
        .import_report
        .clone()
        .expect("an import report")
        .lines;
    // The morph target, the camera, the lights, and that File → Import keeps the view.
    assert_eq!(lines.len(), 4, "{lines:#?}");
    h.get_by_label("Import report");
    h.get_by_label_contains("face.gltf was imported");
    h.get_by_label_contains("1 morph target(s) on 1 mesh(es) (\"Face\" ×1)");
    h.get_by_label_contains("1 camera(s): the first imported as the document camera (\"Shot\")");
    h.get_by_label_contains("lights: 1 directional imported, 1 point/spot not imported");
    h.get_by_label_contains("camera not applied: File > Import keeps your view");
    // The directional light joins the scene's sun without a second shadow.
    let lights = &h.state().editor.doc().lights;
    assert_eq!(lights.len(), 2, "{lights:?}");
    assert!(lights[0].casts_shadows && !lights[1].casts_shadows);
    assert_eq!(lights[1].name, "Key");
    h.get_by_label("OK").click();
    h.run_steps(2);
    assert!(h.state().import_report.is_none(), "OK closes the report");
    assert!(h.query_by_label("Import report").is_none());
}

#[test]
fn an_obj_without_its_texture_is_imported_again_with_one_from_the_import_report() {
    // Spot ships as an OBJ with UVs and a PNG, but no .mtl naming it.
    let dir = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/static/spot"
    );
    let obj = std::path::Path::new(dir).join("spot_triangulated.obj");
    let mut h = harness(EditorApp::new(Editor::new(Document::default(), None)));
    let ctx = h.ctx.clone();
    h.state_mut().start_import(obj.clone());
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    let colours = |h: &Harness<'static, EditorApp>| {
        let o = h.state().editor.doc().objects.last().expect("the import");
        let ObjectKind::Mesh(m) = &o.kind else {
            panic!("an OBJ imports as a mesh object")
        };
        m.model
            .materials
            .iter()
            .filter(|m| m.base_color_texture.is_some())
            .count()
    };
    assert_eq!(colours(&h), 0, "imported untextured");
    h.get_by_label_contains("names no texture");
    // A texture typed into the report (relative to the OBJ's folder) imports it again with it.
    h.query_by_label("Import again with it")
        .expect("the button")
        .click();
    h.run_steps(1);
    assert!(
        h.state().import_report.is_some(),
        "the button is disabled until a texture is named"
    );
    // The report's field (the tool bar has a hex colour field too).
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Texture")
        .focus();
    h.run_steps(1);
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Texture")
        .type_text("spot_texture.png");
    h.run_steps(1);
    h.get_by_label("Import again with it").click();
    h.run_steps(1);
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    assert_eq!(
        h.state().editor.doc().objects.len(),
        1,
        "the untextured import was replaced"
    );
    assert_eq!(colours(&h), 1, "the texture is on the imported material");
    assert!(h.state().import_report.is_none(), "nothing left out now");
}

#[test]
fn an_import_lands_on_the_ground_beside_the_scene_scaled_to_it_and_framed() {
    // Kenney's rock (0.785 units) into the 64-unit house: it used to land at the origin inside
    // the house at its own scale, out of sight.
    let house = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/house.thicket.json"
    );
    let doc = thicket_core::io::project::load(std::path::Path::new(house)).expect("house loads");
    let (scene_lo, scene_hi) = doc.bounds().expect("the house has bounds");
    let scene_size = (scene_hi - scene_lo).length();
    let mut h = harness(EditorApp::new(Editor::new(doc, None)));
    let rock = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/static/kenney_rock_largeA.glb"
    );
    let ctx = h.ctx.clone();
    h.state_mut().start_import(rock.into());
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    let bounds = |h: &Harness<'static, EditorApp>| {
        let o = h.state().editor.doc().objects.last().expect("the import");
        o.world_bounds().expect("the rock has bounds")
    };
    let (lo, hi) = bounds(&h);
    let size = (hi - lo).length();
    assert_eq!(h.state().editor.doc().objects.len(), 2);
    assert!(
        h.state().import_report.is_none(),
        "the rock leaves nothing out: {:?}",
        h.state().import_report
    );
    // Scaled to a quarter of the scene, standing on its ground, outside the house's footprint.
    assert!(
        (size / scene_size - 0.25).abs() < 0.01,
        "{size} against {scene_size}"
    );
    assert!((lo.y - scene_lo.y).abs() < 1e-3 * size, "{lo} {scene_lo}");
    let apart = hi.x < scene_lo.x || lo.x > scene_hi.x || hi.z < scene_lo.z || lo.z > scene_hi.z;
    assert!(
        apart,
        "the rock {lo}..{hi} overlaps the house {scene_lo}..{scene_hi}"
    );
    // Framed: every corner of its box is in front of the camera and inside the view.
    let rect = h.state().view.last_rect;
    let cam = thicket_core::render::Camera::from_orbit(
        &h.state().editor.doc().camera,
        rect.width() as u32,
        rect.height() as u32,
    );
    for c in thicket_core::scene::box_corners(lo, hi) {
        let s = cam.world_to_screen(c);
        assert!(
            (0.0..=rect.width()).contains(&s.x)
                && (0.0..=rect.height()).contains(&s.y)
                && (0.0..=1.0).contains(&s.z),
            "corner {c} lands at {s} outside the {}×{} view",
            rect.width(),
            rect.height()
        );
    }
    // The status bar offers the rock's own size back, as one undoable step.
    h.get_by_label_contains("Reset scale (×").click();
    h.run_steps(2);
    let (rlo, rhi) = bounds(&h);
    let own = thicket::files::load_document(std::path::Path::new(rock))
        .expect("the rock loads")
        .bounds()
        .expect("bounds");
    let own_size = (own.1 - own.0).length();
    assert!(((rhi - rlo).length() / own_size - 1.0).abs() < 1e-3);
    assert!(
        (rlo.y - scene_lo.y).abs() < 1e-3,
        "still on the ground: {rlo}"
    );
    assert!(h.query_by_label_contains("Reset scale (×").is_none());
    h.state_mut().editor.undo();
    let (ulo, uhi) = bounds(&h);
    assert!(((uhi - ulo).length() - size).abs() < 1e-3 * size);
}

/// F1's shortcut sheet at 1280×720: it lists every row of the binding tables (in a scroll area,
/// so it never runs off the screen) and its search field filters them by key or action.
#[test]
fn the_shortcut_sheet_lists_every_key_and_searches() {
    let mut h = Harness::builder()
        .with_size(egui::vec2(1280.0, 720.0))
        .build_ui_state(
            |ui, app: &mut EditorApp| app.ui_root(ui),
            app_with_two_objects(),
        );
    h.run_steps(2);
    h.key_press(egui::Key::F1);
    h.run_steps(3);
    h.snapshot_options(
        "shortcut_sheet_720",
        &egui_kittest::SnapshotOptions::new().max_failed_pixels(200),
    );
    // The sheet is the binding table the handlers read, then the mouse gestures: every bound
    // key is listed with what it does.
    let all = thicket::ui::shortcut_rows("");
    assert_eq!(
        all.len(),
        thicket::ui::BINDINGS.len() + thicket::ui::GESTURES.len()
    );
    assert!(thicket::ui::BINDINGS.len() > 50, "{all:?}");
    for b in thicket::ui::BINDINGS {
        let keys = thicket::ui::keys_text(b);
        assert!(
            h.query_all_by_label(&keys).next().is_some(),
            "{keys:?} is listed"
        );
        assert!(
            h.query_all_by_label(b.what).next().is_some(),
            "{:?} is listed",
            b.what
        );
    }
    for (keys, what) in thicket::ui::GESTURES {
        assert!(h.query_all_by_label(keys).next().is_some(), "{keys:?}");
        assert!(h.query_all_by_label(what).next().is_some(), "{what:?}");
    }
    // Search "undo": the undo row stays, F1's own row ("This list") goes.
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Search")
        .click();
    h.run_steps(1);
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Search")
        .type_text("undo");
    h.run_steps(3);
    assert!(h.query_all_by_label("Undo").next().is_some());
    assert!(h.query_by_label("This list").is_none());
    assert!(
        thicket::ui::shortcut_rows("UNDO").iter().all(|(k, w)| {
            k.to_lowercase().contains("undo") || w.to_lowercase().contains("undo")
        })
    );
}

//! A voxel model built from nothing in the real editor UI (egui_kittest, no GPU): File → New
//! project, then only the voxel tools — box, line, extrude, flood fill, select, copy / paste /
//! move, rotate, palette replace — then save, reopen, and compare the voxel count and a hash of
//! every voxel with the editor's.

use std::hash::{Hash, Hasher};

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use glam::{UVec3, Vec3};
use thicket::editor::Editor;
use thicket::ui::EditorApp;
use thicket::ui::view::Projector;
use thicket_core::scene::{Document, ObjectKind};

const SIZE: egui::Vec2 = egui::vec2(1200.0, 800.0);

fn harness() -> Harness<'static, EditorApp> {
    harness_with(Editor::new(Document::default(), None))
}

fn harness_with(editor: Editor) -> Harness<'static, EditorApp> {
    harness_sized(editor, SIZE)
}

fn harness_sized(editor: Editor, size: egui::Vec2) -> Harness<'static, EditorApp> {
    let mut app = EditorApp::new(editor);
    app.autosave_secs = 0;
    app.native_dialogs = false;
    let mut h = Harness::builder()
        .with_size(size)
        // 20 frames a second, so two clicks a frame apart make a double-click (0.3 s).
        .with_step_dt(1.0 / 20.0)
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    h
}

fn model_id(h: &Harness<'static, EditorApp>) -> u64 {
    h.state().editor.doc().objects[0].id
}

fn leaves(h: &Harness<'static, EditorApp>) -> Vec<(UVec3, thicket_core::svo::Voxel)> {
    match &h.state().editor.doc().objects[0].kind {
        ObjectKind::Voxels(v) => v.svo.leaves(),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => unreachable!(),
    }
}

fn count_color(h: &Harness<'static, EditorApp>, color: [u8; 4]) -> usize {
    leaves(h).iter().filter(|(_, v)| v.color == color).count()
}

fn hash_of(leaves: &[(UVec3, thicket_core::svo::Voxel)]) -> u64 {
    let mut s = std::collections::hash_map::DefaultHasher::new();
    for (c, v) in leaves {
        c.to_array().hash(&mut s);
        v.color.hash(&mut s);
        v.material.hash(&mut s);
    }
    s.finish()
}

/// The view point of a voxel-space point of the model.
fn screen(h: &Harness<'static, EditorApp>, p: Vec3) -> egui::Pos2 {
    let ed = &h.state().editor;
    let o = &ed.doc().objects[0];
    let ObjectKind::Voxels(v) = &o.kind else {
        unreachable!()
    };
    let world = (o.transform.matrix() * v.object_from_voxel()).transform_point3(p);
    Projector::new(ed.doc().camera, h.state().view.last_rect)
        .to_screen(world)
        .expect("in front of the camera")
}

/// A press at `a`, moves to `b`, a release at `b`.
fn drag(h: &mut Harness<'static, EditorApp>, a: egui::Pos2, b: egui::Pos2) {
    h.hover_at(a);
    h.step();
    h.drag_at(a);
    h.step();
    for k in 1..=4 {
        h.hover_at(a + (b - a) * (k as f32 / 4.0));
        h.step();
    }
    h.drop_at(b);
    h.run_steps(2);
}

fn click(h: &mut Harness<'static, EditorApp>, p: egui::Pos2) {
    drag(h, p, p);
}

#[test]
fn a_model_built_from_nothing_with_the_voxel_tools_saves_and_reopens_the_same() {
    let mut h = harness();
    // File → New project opens the New voxel model dialog; 16³ voxels of 0.25 m, empty.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::N);
    h.run_steps(2);
    assert!(h.state().new_model.open, "the New voxel model dialog opens");
    h.state_mut().new_model.spec.size = UVec3::splat(16);
    h.state_mut().new_model.spec.voxel_size = 0.25;
    h.run_steps(1);
    h.get_by_label("Create").click();
    h.run_steps(3);
    assert_eq!(h.state().editor.doc().objects.len(), 1);
    let id = model_id(&h);
    assert_eq!(h.state().editor.volume_of(id), Some(UVec3::splat(16)));
    assert!(leaves(&h).is_empty());
    // Looking down at the floor from above-front, so every tool below aims at known cells.
    let mut camera = h.state().editor.doc().camera;
    camera.yaw_deg = 20.0;
    camera.pitch_deg = 55.0;
    h.state_mut().editor.set_camera(camera);
    h.run_steps(2);
    let white = h.state().sculpt.brush.color;

    // Box: a 4×5 rectangle on the empty floor, height 1 (the commit click stays on the corner).
    h.key_press(egui::Key::B);
    h.run_steps(1);
    let (a, b) = (
        screen(&h, Vec3::new(2.5, 0.5, 2.5)),
        screen(&h, Vec3::new(5.5, 0.5, 6.5)),
    );
    drag(&mut h, a, b);
    click(&mut h, b);
    assert_eq!(leaves(&h).len(), 20, "a 4×1×5 box");
    let steps = h.state().editor.history().undo_len();

    // Line: five voxels along X on the floor.
    h.key_press(egui::Key::L);
    h.run_steps(1);
    let (a, b) = (
        screen(&h, Vec3::new(8.5, 0.5, 10.5)),
        screen(&h, Vec3::new(12.5, 0.5, 10.5)),
    );
    drag(&mut h, a, b);
    assert_eq!(leaves(&h).len(), 25, "a 5-voxel line");
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");

    // Extrude: pull the box's top face up by two layers.
    h.key_press(egui::Key::U);
    h.run_steps(1);
    let (a, b) = (
        screen(&h, Vec3::new(3.5, 1.0, 4.5)),
        screen(&h, Vec3::new(3.5, 3.0, 4.5)),
    );
    drag(&mut h, a, b);
    assert_eq!(leaves(&h).len(), 65, "the 20-voxel face pulled out by 2");

    // Flood fill in Paint mode: the box and its extrusion (one connected colour) turn red,
    // the line (not connected) stays.
    let red = [200, 40, 40, 255];
    h.key_press(egui::Key::P);
    h.key_press(egui::Key::C);
    h.run_steps(1);
    h.state_mut().sculpt.brush.color = red;
    let p = screen(&h, Vec3::new(3.5, 3.0, 4.5));
    click(&mut h, p);
    assert_eq!(count_color(&h, red), 60);
    assert_eq!(count_color(&h, white), 5);

    // Select by colour (a click), copy, paste, move 8 voxels along +X, place.
    h.key_press(egui::Key::M);
    h.run_steps(1);
    let p = screen(&h, Vec3::new(3.5, 3.0, 4.5));
    click(&mut h, p);
    assert_eq!(
        h.state().editor.voxel_selection().map(|s| s.cells.len()),
        Some(60)
    );
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::C);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::V);
    h.run_steps(1);
    assert!(h.state().editor.floating().is_some(), "the paste floats");
    for _ in 0..8 {
        h.key_press(egui::Key::ArrowRight);
    }
    h.key_press(egui::Key::Enter);
    h.run_steps(2);
    assert!(h.state().editor.floating().is_none());
    assert_eq!(leaves(&h).len(), 125);
    assert_eq!(count_color(&h, red), 120);

    // Rotate the pasted copy (now the selection) a quarter turn about Y through the menu.
    let before_rotate: Vec<UVec3> = h
        .state()
        .editor
        .voxel_selection()
        .unwrap()
        .cells
        .iter()
        .collect();
    // The menu bar comes before the tool bar's Select tool.
    h.query_all_by_label("Select")
        .next()
        .expect("the Select menu")
        .click();
    h.run_steps(2);
    h.get_by_label("Y 90°").click();
    h.run_steps(2);
    let after_rotate: Vec<UVec3> = h
        .state()
        .editor
        .voxel_selection()
        .unwrap()
        .cells
        .iter()
        .collect();
    assert_eq!(after_rotate.len(), 60);
    assert_ne!(before_rotate, after_rotate, "the copy turned");
    assert_eq!(leaves(&h).len(), 125);
    let size = |c: &[UVec3]| {
        let lo = c.iter().fold(UVec3::MAX, |a, p| a.min(*p));
        let hi = c.iter().fold(UVec3::ZERO, |a, p| a.max(*p));
        hi - lo + 1
    };
    assert_eq!(size(&before_rotate), UVec3::new(4, 3, 5));
    assert_eq!(size(&after_rotate), UVec3::new(5, 3, 4), "X and Z swap");
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::A,
    );
    h.run_steps(1);
    assert!(h.state().editor.voxel_selection().is_none());

    // Palette: the model's colours are listed; double-click red, choose blue, replace.
    h.state_mut().palette.open = true;
    h.run_steps(2);
    // A double-click: two clicks a frame apart.
    for _ in 0..2 {
        h.get_by_role_and_label(egui::accesskit::Role::Button, "#c82828")
            .click();
        h.step();
    }
    h.run_steps(2);
    // What the colour button of the replace row sets (its popup is a colour wheel).
    assert!(
        h.state_mut().palette.set_replacement([40, 40, 200, 255]),
        "editing red"
    );
    h.run_steps(1);
    h.get_by_label("Replace everywhere").click();
    h.run_steps(2);
    assert_eq!(count_color(&h, red), 0);
    assert_eq!(count_color(&h, [40, 40, 200, 255]), 120);

    // Save, reopen: the same voxels.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("built.thicket.json");
    let ctx = h.ctx.clone();
    assert!(h.state_mut().save_to(&ctx, path.clone()));
    let saved = leaves(&h);
    let doc = thicket::files::load_document(&path).expect("the saved project loads");
    let ObjectKind::Voxels(v) = &doc.objects[0].kind else {
        panic!("a voxel model")
    };
    let reopened = v.svo.leaves();
    assert_eq!(reopened.len(), 125);
    assert_eq!(hash_of(&reopened), hash_of(&saved));
    assert_eq!(v.volume, Some(UVec3::splat(16)), "the volume is saved");

    // Every step undoes: back to the empty model.
    while h.state().editor.history().undo_len() > 1 {
        h.state_mut().editor.undo();
    }
    assert!(
        leaves(&h).is_empty(),
        "undo of every tool edit restores the empty model"
    );
}

/// Three edits with the voxel tools, then Edit → History: the window lists them by name, a
/// click on the first goes back to exactly the document two undos give (the later steps stay
/// listed), and a click on the last goes forward to the document of all three.
#[test]
fn history_lists_the_steps_and_a_click_is_that_many_undos() {
    use glam::IVec3;
    use thicket::editor::NewModelSpec;
    use thicket_core::sculpt::shapes::{Ink, Mirror, ShapeOp};
    let three_edits = || {
        let mut ed = Editor::new(Document::default(), None);
        let id = ed
            .add_voxel_model(&NewModelSpec {
                name: "Crate".into(),
                size: UVec3::splat(8),
                ..NewModelSpec::default()
            })
            .unwrap();
        let ink = Ink {
            color: [200, 40, 40, 255],
            material: 0,
        };
        ed.shape_box(
            id,
            IVec3::ZERO,
            IVec3::new(3, 1, 3),
            ShapeOp::Add,
            ink,
            Mirror::default(),
        )
        .unwrap();
        let cells = [IVec3::new(0, 1, 0), IVec3::new(1, 1, 0)];
        let blue = Ink {
            color: [40, 40, 200, 255],
            material: 0,
        };
        ed.shape_cells(id, &cells, ShapeOp::Paint, blue, Mirror::default(), false)
            .unwrap();
        ed
    };
    // What the history covers (the view moves the camera's clip planes, which no step holds).
    let content = |ed: &Editor| (ed.doc().objects.clone(), ed.doc().lights.clone());
    let all_three = content(&three_edits());
    let mut undone = three_edits();
    assert!(undone.undo() && undone.undo());
    let first_only = content(&undone);
    assert_ne!(first_only, all_three);

    let mut h = harness_with(three_edits());
    assert_eq!(content(&h.state().editor), all_three);
    h.query_all_by_label("Edit")
        .next()
        .expect("the Edit menu")
        .click();
    h.run_steps(2);
    h.get_by_label("History…").click();
    h.run_steps(2);
    assert!(h.state().show_history, "Edit → History opens the window");
    for step in ["1. Add Crate", "2. Add box", "3. Paint voxels"] {
        assert!(h.query_by_label(step).is_some(), "History lists {step:?}");
    }
    h.get_by_label("1. Add Crate").click();
    h.run_steps(2);
    assert_eq!(
        content(&h.state().editor),
        first_only,
        "going back to the first step is two undos"
    );
    assert_eq!(h.state().editor.history().undo_len(), 1);
    assert_eq!(h.state().editor.history().redo_len(), 2);
    // The undone steps stay listed, to go forward to.
    h.get_by_label("3. Paint voxels").click();
    h.run_steps(2);
    assert_eq!(
        content(&h.state().editor),
        all_three,
        "forward again is two redos"
    );
    assert_eq!(h.state().editor.history().redo_len(), 0);
    // Start is the document before every step: no objects.
    h.get_by_label("Start").click();
    h.run_steps(2);
    assert!(h.state().editor.doc().objects.is_empty());
    assert_eq!(h.state().editor.history().undo_len(), 0);
}

/// The tool bar at 1280×720 (a laptop screen): its swatches are the selected model's own
/// colours, most used first, and they are at exactly the same places whichever tool is chosen,
/// on one row with the tools (nothing wraps); the hex field sets the colour and refuses other
/// text with a message; the 256-colour grid and a swatch pick colours.
#[test]
fn tool_bar_swatches_stay_put_and_hex_and_grid_set_the_colour() {
    use egui::accesskit::Role;
    use egui_kittest::kittest::NodeT as _;
    use glam::IVec3;
    use thicket::editor::NewModelSpec;
    use thicket::ui::voxel_tools::ToolKind;
    use thicket_core::sculpt::shapes::{Ink, Mirror, ShapeOp};
    let mut ed = Editor::new(Document::default(), None);
    let id = ed
        .add_voxel_model(&NewModelSpec {
            size: UVec3::splat(16),
            ..NewModelSpec::default()
        })
        .unwrap();
    let ink = |c: [u8; 3]| Ink {
        color: [c[0], c[1], c[2], 255],
        material: 0,
    };
    // 16 red voxels and 2 blue ones on top.
    ed.shape_box(
        id,
        IVec3::ZERO,
        IVec3::new(3, 0, 3),
        ShapeOp::Add,
        ink([200, 40, 40]),
        Mirror::default(),
    )
    .unwrap();
    let cells = [IVec3::new(0, 1, 0), IVec3::new(1, 1, 0)];
    ed.shape_cells(
        id,
        &cells,
        ShapeOp::Add,
        ink([40, 40, 200]),
        Mirror::default(),
        false,
    )
    .unwrap();
    let mut h = harness_sized(ed, egui::vec2(1280.0, 720.0));
    h.run_steps(2);

    let swatches = |h: &Harness<'static, EditorApp>| -> Vec<(String, egui::Rect)> {
        h.query_all_by_label_contains("Swatch ")
            .map(|n| (n.accesskit_node().label().unwrap_or_default(), n.rect()))
            .collect()
    };
    let navigate = swatches(&h);
    // The model's two colours, then the twelve starter colours.
    assert_eq!(navigate.len(), 14, "{navigate:?}");
    assert_eq!(
        navigate[0].0, "Swatch 1: #c82828",
        "the most used colour first"
    );
    assert_eq!(navigate[1].0, "Swatch 2: #2828c8");
    // The tool bar's Navigate (the first: the View menu has one too).
    let row = h.query_all_by_label("Navigate").next().unwrap().rect();
    assert!(row.top() < 60.0, "{row:?}");
    let mut modes: Vec<(String, Vec<(String, egui::Rect)>)> = Vec::new();
    for (tool, label, _) in ToolKind::ALL {
        h.state_mut().sculpt.choose(tool);
        h.run_steps(2);
        modes.push((label.to_owned(), swatches(&h)));
    }
    h.state_mut().sculpt.choose(ToolKind::Brush);
    h.state_mut().sculpt.stretch_paint = true;
    h.run_steps(2);
    modes.push(("Stretch paint".into(), swatches(&h)));
    h.state_mut().sculpt.stretch_paint = false;
    h.run_steps(1);
    for (mode, list) in &modes {
        assert_eq!(list, &navigate, "the swatches do not move with {mode}");
    }
    for (name, r) in &navigate {
        assert!(
            r.center().y > row.top() && r.center().y < row.bottom(),
            "{name} {r:?} is on the tools' row {row:?}"
        );
    }
    let last = navigate.last().unwrap().1;
    assert!(last.right() <= 1280.0, "the row fits: {last:?}");
    // The view settled, so the snapshot does not catch a preview half done.
    for _ in 0..4 {
        h.state_mut().view.wait_for_cpu_preview();
        h.run_steps(1);
    }
    h.snapshot_options(
        "tool_bar_1280",
        &egui_kittest::SnapshotOptions::new().max_failed_pixels(200),
    );

    // Hex entry: a colour is set, anything else is refused with a message.
    let type_hex = |h: &mut Harness<'static, EditorApp>, text: &str| {
        h.get_by_role_and_label(Role::TextInput, "Hex").focus();
        h.run_steps(1);
        h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
        h.get_by_role_and_label(Role::TextInput, "Hex")
            .type_text(text);
        h.run_steps(1);
        h.key_press(egui::Key::Enter);
        h.run_steps(2);
    };
    type_hex(&mut h, "#3366CC");
    assert_eq!(h.state().sculpt.brush.color, [0x33, 0x66, 0xcc, 255]);
    assert!(h.query_by_label_contains("is not a colour").is_none());
    type_hex(&mut h, "#3366C");
    assert_eq!(
        h.state().sculpt.brush.color,
        [0x33, 0x66, 0xcc, 255],
        "five digits are refused"
    );
    assert!(
        h.query_by_label_contains("\"#3366C\" is not a colour")
            .is_some(),
        "the refusal is shown"
    );
    // A swatch picks its colour (and the refusal goes).
    h.get_by_label("Swatch 2: #2828c8").click();
    h.run_steps(2);
    assert_eq!(h.state().sculpt.brush.color, [40, 40, 200, 255]);
    assert!(h.query_by_label_contains("is not a colour").is_none());
    // The grid (the default one: the model has no palette) picks its cell's colour.
    h.get_by_label("256…").click();
    h.run_steps(2);
    h.get_by_label("Grid 43: #ccccff").click();
    h.run_steps(2);
    assert_eq!(h.state().sculpt.brush.color, [204, 204, 255, 255]);
    assert!(
        h.query_by_label("Grid 43: #ccccff").is_none(),
        "a pick closes the grid"
    );
}

/// The ground grid, the world axes and the volume box are drawn only where no voxel is in front
/// of them: a ground line running under a solid 2 m cube is shown in front of it, hidden under
/// and behind it, and shown whole once the cube is hidden. The same split serves the CPU preview
/// and the GPU viewport (the overlays are painted over either).
#[test]
fn overlay_lines_are_hidden_behind_voxels() {
    use thicket::editor::NewModelSpec;
    use thicket::ui::view::{behind_voxels, unhidden_parts};
    use thicket_core::sculpt::model_ops::InitialFill;
    let mut ed = Editor::new(Document::default(), None);
    let id = ed
        .add_voxel_model(&NewModelSpec {
            size: UVec3::splat(8),
            voxel_size: 0.25,
            fill: InitialFill::SolidBox,
            ..NewModelSpec::default()
        })
        .unwrap();
    let mut camera = ed.doc().camera;
    camera.yaw_deg = 0.0;
    camera.pitch_deg = 45.0;
    camera.orthographic = false;
    ed.set_camera(camera);
    let camera = ed.doc().camera;
    let rect = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(800.0, 600.0));
    let proj = Projector::new(camera, rect);
    // The cube's footprint centre on the ground, and the way the camera looks along the ground.
    let c = Vec3::new(camera.target.x, 0.0, camera.target.z);
    let eye = camera.eye();
    let f = Vec3::new(camera.target.x - eye.x, 0.0, camera.target.z - eye.z).normalize_or_zero();
    let (a, b) = (c - f * 1.5, c + f * 8.0);
    assert!(
        proj.to_screen(a).is_some(),
        "the line starts in front of the camera"
    );
    assert!(
        !behind_voxels(&proj, &ed, a),
        "the ground in front of the cube shows"
    );
    assert!(
        behind_voxels(&proj, &ed, c),
        "the ground under the cube is hidden"
    );
    assert!(
        behind_voxels(&proj, &ed, c + f * 1.5),
        "the ground just behind the cube is hidden"
    );
    assert!(!behind_voxels(&proj, &ed, b), "the ground far behind shows");
    let on_line = |p: Vec3| (p - a).dot(f);
    let parts = unhidden_parts(&proj, &ed, a, b);
    assert_eq!(parts.len(), 2, "in front and far behind: {parts:?}");
    assert_eq!(parts[0].0, a);
    // The front part ends at the cube's front face (1 m before its centre), to a few cm.
    assert!(
        (on_line(parts[0].1) - 0.5).abs() < 0.05,
        "{}",
        on_line(parts[0].1)
    );
    assert!(on_line(parts[1].0) > 3.0 && parts[1].1 == b, "{parts:?}");
    // A world axis through the cube, drawn from its centre upward: hidden inside, shown above.
    let up = unhidden_parts(&proj, &ed, c, c + Vec3::Y * 4.0);
    assert_eq!(up.len(), 1, "{up:?}");
    assert!(up[0].0.y > 1.9, "{up:?}");
    // Hidden models hide nothing.
    ed.set_visible(id, false).unwrap();
    assert_eq!(unhidden_parts(&proj, &ed, a, b), vec![(a, b)]);
}

/// A model made with the tools, exported to .vox, opened and exported again by Goxel (under
/// Xvfb, as an artist's second tool would), comes back with the same voxel count.
#[test]
fn a_model_made_with_the_tools_round_trips_through_goxel() {
    use glam::IVec3;
    use thicket::editor::NewModelSpec;
    use thicket_core::sculpt::shapes::{Ink, Mirror, ShapeOp};
    let mut ed = Editor::default();
    let id = ed
        .add_voxel_model(&NewModelSpec {
            size: UVec3::new(20, 12, 16),
            ..NewModelSpec::default()
        })
        .unwrap();
    let ink = |c: [u8; 3]| Ink {
        color: [c[0], c[1], c[2], 255],
        material: 0,
    };
    ed.shape_box(
        id,
        IVec3::ZERO,
        IVec3::new(9, 2, 7),
        ShapeOp::Add,
        ink([180, 120, 60]),
        Mirror::default(),
    )
    .unwrap();
    let line: Vec<IVec3> =
        thicket_core::sculpt::shapes::line_cells(IVec3::new(0, 3, 0), IVec3::new(9, 11, 7));
    ed.shape_cells(
        id,
        &line,
        ShapeOp::Add,
        ink([40, 160, 60]),
        Mirror {
            axes: [true, false, false],
        },
        false,
    )
    .unwrap();
    ed.extrude_face(id, UVec3::new(4, 2, 4), IVec3::Y, 1)
        .unwrap();
    let ObjectKind::Voxels(v) = &ed.object(id).unwrap().kind else {
        unreachable!()
    };
    let count = v.svo.leaf_count();
    assert!(count > 300, "{count}");
    let dir = tempfile::tempdir().unwrap();
    let ours = dir.path().join("made.vox");
    let theirs = dir.path().join("goxel.vox");
    thicket_core::io::vox::export_vox(&ed.doc().objects, &ours).unwrap();
    let out = std::process::Command::new("timeout")
        .args(["120", "xvfb-run", "-a", "goxel"])
        .arg(&ours)
        .arg("--export")
        .arg(&theirs)
        .output()
        .expect("goxel and xvfb-run are installed by scripts/install-deps.sh");
    assert!(
        out.status.success(),
        "goxel failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let back = thicket_core::io::vox::import_vox(&theirs).expect("Goxel's file loads");
    assert_eq!(back.voxel_count(), count, "Goxel keeps every voxel");
    let ours_again = thicket_core::io::vox::import_vox(&ours).unwrap();
    assert_eq!(ours_again.voxel_count(), count);
}

/// Model → Voxelize mesh on an imported OBJ gives exactly the voxels `thicket import` makes at
/// the same depth, in one undo step that hides the mesh and selects the voxel model.
#[test]
fn voxelize_mesh_in_the_editor_gives_the_voxels_thicket_import_gives() {
    let spot = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/static/spot/spot_triangulated.obj"
    );
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("spot.thicket.json");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_thicket"))
        .args(["import", spot, "--depth", "5", "-o", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cli = thicket_core::io::project::load(&out).unwrap();
    let ObjectKind::Voxels(expected) = &cli.objects[0].kind else {
        panic!("a voxel model");
    };

    let (doc, _, _) = thicket::files::load_document_imported(
        std::path::Path::new(spot),
        &thicket::files::MeshOptions::default(),
    )
    .unwrap();
    let mut h = harness_sized(Editor::new(doc, None), egui::vec2(1280.0, 800.0));
    let mesh = h.state().editor.doc().objects[0].id;
    h.state_mut().editor.selection = Some(thicket::editor::Selection::Object(mesh));
    h.state_mut().voxelize.depth = 5;
    h.run_steps(1);
    let steps = h.state().editor.history().undo_len();
    h.get_by_label("Model").click();
    h.run_steps(2);
    h.get_by_label_contains("Voxelize mesh");
    h.get_by_label("Voxelize").click();
    h.run_steps(1);
    let ctx = h.ctx.clone();
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    let doc = h.state().editor.doc();
    assert_eq!(doc.objects.len(), 2);
    let made = &doc.objects[1];
    assert_eq!(made.name, "spot_triangulated voxels");
    let ObjectKind::Voxels(v) = &made.kind else {
        panic!("a voxel model");
    };
    assert!(
        expected.svo.leaf_count() > 1_000,
        "{}",
        expected.svo.leaf_count()
    );
    assert_eq!(v.svo.leaves(), expected.svo.leaves(), "the same voxels");
    assert_eq!(
        (v.voxel_size, v.origin),
        (expected.voxel_size, expected.origin)
    );
    assert!(!doc.objects[0].visible, "the mesh is hidden");
    assert_eq!(
        h.state().editor.selection,
        Some(thicket::editor::Selection::Object(made.id))
    );
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");
    assert!(h.state_mut().editor.undo());
    assert_eq!(h.state().editor.doc().objects.len(), 1);
    assert!(h.state().editor.doc().objects[0].visible);
}

/// A paste moved past the volume's edge shows the voxels it would lose in red and a line that
/// says so; Shift+Enter grows the canvas and keeps every voxel (the model stays where it is in
/// the world), one undo step; past the low edge too. Snapshot looked at.
#[test]
fn a_paste_past_the_edge_marks_its_clipped_voxels_and_grow_keeps_them() {
    let (mut ed, id) = boxes_model("Crate", 8, &[(glam::IVec3::ZERO, glam::IVec3::splat(3))]);
    ed.selection = Some(thicket::editor::Selection::Object(id));
    ed.frame_selection();
    // Back off so the paste beside the block shows too.
    let mut camera = ed.doc().camera;
    camera.distance *= 2.5;
    camera.target.x += 0.6;
    ed.set_camera(camera);
    let cells: Vec<UVec3> = leaves_of(&ed).iter().map(|l| l.0).collect();
    assert_eq!(cells.len(), 64);
    ed.select_voxels(
        id,
        thicket_core::sculpt::select::VoxelSelection::from_cells(cells.iter().copied()),
        thicket::editor::SelectMode::Replace,
    )
    .unwrap();
    let world = |ed: &Editor, c: UVec3| {
        let o = &ed.doc().objects[0];
        let ObjectKind::Voxels(v) = &o.kind else {
            unreachable!()
        };
        (o.transform.matrix() * v.object_from_voxel()).transform_point3(c.as_vec3())
    };
    let corner = world(&ed, UVec3::ZERO);
    let mut h = harness_with(ed);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::C);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::V);
    h.run_steps(1);
    for _ in 0..6 {
        h.key_press(egui::Key::ArrowRight);
    }
    h.run_steps(2);
    // The pasted block spans x 6..=9 of an 8-wide volume: two columns of 16 are outside.
    assert_eq!(h.state().editor.floating_outside(), 32);
    for _ in 0..4 {
        h.state_mut().view.wait_for_cpu_preview();
        h.run_steps(1);
    }
    h.try_snapshot_options(
        "paste_clipped",
        &egui_kittest::SnapshotOptions::new().max_failed_pixels(200),
    )
    .unwrap();
    let steps = h.state().editor.history().undo_len();
    h.key_press_modifiers(egui::Modifiers::SHIFT, egui::Key::Enter);
    h.run_steps(2);
    assert!(h.state().editor.floating().is_none());
    assert_eq!(leaves(&h).len(), 128, "every voxel kept");
    assert_eq!(h.state().editor.volume_of(id), Some(UVec3::new(10, 8, 8)));
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "one step");
    assert!((world(&h.state().editor, UVec3::ZERO) - corner).length() < 1e-5);

    // Past the low edge: the canvas grows below, the original block keeps its world place.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::V);
    h.run_steps(1);
    for _ in 0..12 {
        h.key_press(egui::Key::ArrowLeft);
    }
    h.run_steps(1);
    let outside = h.state().editor.floating_outside();
    assert!(outside > 0, "{outside}");
    h.key_press_modifiers(egui::Modifiers::SHIFT, egui::Key::Enter);
    h.run_steps(2);
    assert_eq!(leaves(&h).len(), 192);
    let size = h.state().editor.volume_of(id).unwrap();
    assert!(size.x > 10, "{size}");
    let shift = size.x - 10;
    let moved = world(&h.state().editor, UVec3::new(shift, 0, 0));
    assert!((moved - corner).length() < 1e-5, "{moved} vs {corner}");

    // A plain Enter still drops what is outside (and says so in the status line).
    assert!(h.state_mut().editor.undo() && h.state_mut().editor.undo());
    assert_eq!(leaves(&h).len(), 64);
    assert_eq!(h.state().editor.volume_of(id), Some(UVec3::splat(8)));
}

/// A new empty `size`³ model of 0.25 m voxels named `name`, with the inclusive boxes added.
fn boxes_model(name: &str, size: u32, boxes: &[(glam::IVec3, glam::IVec3)]) -> (Editor, u64) {
    use thicket_core::sculpt::{Ink, Mirror, ShapeOp};
    let mut ed = Editor::default();
    let id = ed
        .add_voxel_model(&thicket::editor::NewModelSpec {
            name: name.into(),
            size: UVec3::splat(size),
            voxel_size: 0.25,
            fill: thicket_core::sculpt::model_ops::InitialFill::Empty,
            ..thicket::editor::NewModelSpec::default()
        })
        .unwrap();
    let ink = Ink {
        color: [200, 40, 40, 255],
        material: 0,
    };
    for &(a, b) in boxes {
        ed.shape_box(id, a, b, ShapeOp::Add, ink, Mirror::default())
            .unwrap();
    }
    (ed, id)
}

fn leaves_of(ed: &Editor) -> Vec<(UVec3, thicket_core::svo::Voxel)> {
    match &ed.doc().objects[0].kind {
        ObjectKind::Voxels(v) => v.svo.leaves(),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => unreachable!(),
    }
}

/// Ctrl+V with the pointer over the model starts the paste on the face there; a drag that
/// grabs the floating paste slides it by whole voxels (the view does not orbit), then Enter
/// places it.
#[test]
fn a_paste_lands_at_the_pointer_and_drags_by_whole_voxels() {
    // A 16×1×16 floor and a 2×2×2 block on it, selected and copied.
    let (mut ed, id) = boxes_model(
        "Slab",
        16,
        &[
            (glam::IVec3::ZERO, glam::IVec3::new(15, 0, 15)),
            (glam::IVec3::new(1, 1, 1), glam::IVec3::new(2, 2, 2)),
        ],
    );
    let block: Vec<UVec3> = leaves_of(&ed)
        .iter()
        .map(|l| l.0)
        .filter(|c| c.y >= 1)
        .collect();
    assert_eq!(block.len(), 8);
    ed.select_voxels(
        id,
        thicket_core::sculpt::select::VoxelSelection::from_cells(block.iter().copied()),
        thicket::editor::SelectMode::Replace,
    )
    .unwrap();
    ed.copy_voxels().unwrap();
    // Look straight down (top view, orthographic): voxel x goes right, z goes down the screen.
    ed.selection = Some(thicket::editor::Selection::Object(id));
    let mut camera = ed.doc().camera;
    camera.orthographic = true;
    camera.yaw_deg = 0.0;
    camera.pitch_deg = 89.0;
    ed.set_camera(camera);
    ed.frame_selection();
    let mut h = harness_with(ed);
    h.run_steps(2);
    // Over the floor cell (10, 0, 10): the paste's bottom lands on (10, 1, 10), centred across.
    let over = screen(&h, Vec3::new(10.5, 1.0, 10.5));
    h.hover_at(over);
    h.run_steps(2);
    assert_eq!(
        h.state().view.paste_target,
        Some((id, glam::IVec3::new(10, 1, 10)))
    );
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::V);
    h.run_steps(1);
    let at = h.state().editor.floating().expect("floating").at;
    assert_eq!(at, glam::IVec3::new(9, 1, 9));
    // Grab it at its top and drag three voxels along +x (to the right).
    let camera_before = h.state().editor.doc().camera;
    let grab = screen(&h, Vec3::new(10.0, 3.0, 10.0));
    let to = screen(&h, Vec3::new(13.0, 3.0, 10.0));
    drag(&mut h, grab, to);
    assert_eq!(
        h.state().editor.floating().expect("still floating").at,
        glam::IVec3::new(12, 1, 9)
    );
    assert_eq!(
        h.state().editor.doc().camera,
        camera_before,
        "the view did not orbit"
    );
    h.key_press(egui::Key::Enter);
    h.run_steps(2);
    assert!(h.state().editor.floating().is_none());
    assert_eq!(leaves(&h).len(), 256 + 8 + 8);
    let placed: Vec<UVec3> = leaves(&h)
        .iter()
        .map(|l| l.0)
        .filter(|c| c.y >= 1 && c.x >= 12)
        .collect();
    assert_eq!(placed.len(), 8, "{placed:?}");
}

/// With the Select tool, a drag that starts on a selected voxel moves the selection by whole
/// voxels (it floats while dragged, the view does not orbit) and the release writes it there:
/// one undo step, "Move voxels", that puts it back. A click on it moves nothing.
#[test]
fn the_select_tool_drags_a_selection_to_move_it_in_one_undo_step() {
    let (mut ed, id) = boxes_model(
        "Slab",
        16,
        &[
            (glam::IVec3::ZERO, glam::IVec3::new(15, 0, 15)),
            (glam::IVec3::new(1, 1, 1), glam::IVec3::new(2, 2, 2)),
        ],
    );
    let block: Vec<UVec3> = leaves_of(&ed)
        .iter()
        .map(|l| l.0)
        .filter(|c| c.y >= 1)
        .collect();
    ed.select_voxels(
        id,
        thicket_core::sculpt::select::VoxelSelection::from_cells(block.iter().copied()),
        thicket::editor::SelectMode::Replace,
    )
    .unwrap();
    ed.selection = Some(thicket::editor::Selection::Object(id));
    let mut camera = ed.doc().camera;
    camera.orthographic = true;
    camera.yaw_deg = 0.0;
    camera.pitch_deg = 89.0;
    ed.set_camera(camera);
    ed.frame_selection();
    let mut h = harness_with(ed);
    h.state_mut()
        .sculpt
        .choose(thicket::ui::voxel_tools::ToolKind::Select);
    h.run_steps(2);
    let before = hash_of(&leaves(&h));
    let steps = h.state().editor.history().undo_len();
    // A click on the selection: nothing moves, no step.
    let top = screen(&h, Vec3::new(2.0, 3.0, 2.0));
    click(&mut h, top);
    assert_eq!(hash_of(&leaves(&h)), before);
    assert_eq!(h.state().editor.history().undo_len(), steps);
    // Grab the block's top and drag it four voxels along +x.
    let camera_before = h.state().editor.doc().camera;
    let to = screen(&h, Vec3::new(6.0, 3.0, 2.0));
    drag(&mut h, top, to);
    let ed = &h.state().editor;
    assert!(ed.floating().is_none(), "written on release");
    assert_eq!(ed.doc().camera, camera_before, "the view did not orbit");
    let moved: Vec<UVec3> = leaves(&h)
        .iter()
        .map(|l| l.0)
        .filter(|c| c.y >= 1)
        .collect();
    let mut want: Vec<UVec3> = block.iter().map(|c| *c + UVec3::new(4, 0, 0)).collect();
    want.sort_by_key(|c| (c.x, c.y, c.z));
    let mut got = moved.clone();
    got.sort_by_key(|c| (c.x, c.y, c.z));
    assert_eq!(got, want, "the block moved four voxels along x");
    assert_eq!(leaves(&h).len(), 256 + 8);
    assert_eq!(
        ed.voxel_selection().map(|s| s.cells.len()),
        Some(8),
        "the moved voxels stay selected"
    );
    let (labels, _) = ed.history().labels();
    assert_eq!(labels.last(), Some(&"Move voxels"));
    assert_eq!(ed.history().undo_len(), steps + 1, "one step");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(2);
    assert_eq!(hash_of(&leaves(&h)), before, "undo puts it back");
}

/// A turn that would push selected voxels off the canvas asks first: Cancel changes nothing,
/// "Grow the canvas" keeps every voxel (resize and turn one undo step); an arrow at the edge
/// moves nothing and says why.
#[test]
fn a_turn_past_the_canvas_edge_asks_and_grows_and_an_arrow_at_the_edge_keeps_every_voxel() {
    // A bar 2 wide and 6 long along z against the x = 0 wall of an 8³ canvas.
    let (mut ed, id) = boxes_model(
        "Bar",
        8,
        &[(glam::IVec3::new(0, 0, 0), glam::IVec3::new(1, 0, 5))],
    );
    ed.select_all_voxels(id).unwrap();
    ed.selection = Some(thicket::editor::Selection::Object(id));
    let turn = thicket_core::sculpt::select::SelTransform::Rotate {
        axis: 1,
        quarter_turns: 1,
    };
    let (outside, lo, _) = ed.transform_outside(turn).expect("a selection");
    assert!(outside > 0 && lo.x < 0, "{outside} {lo}");
    let mut h = harness_with(ed);
    let before = hash_of(&leaves(&h));
    let steps = h.state().editor.history().undo_len();
    h.query_all_by_label("Select")
        .next()
        .expect("the Select menu")
        .click();
    h.run_steps(2);
    h.get_by_label("Y 90°").click();
    h.run_steps(2);
    assert!(
        h.query_by_label(&format!(
            "{outside} voxel(s) would land outside the canvas and be lost."
        ))
        .is_some(),
        "the turn asks first"
    );
    h.get_by_label("Cancel").click();
    h.run_steps(2);
    assert_eq!(hash_of(&leaves(&h)), before, "cancel changes nothing");
    assert_eq!(h.state().editor.history().undo_len(), steps);
    h.query_all_by_label("Select")
        .next()
        .expect("the Select menu")
        .click();
    h.run_steps(2);
    h.get_by_label("Y 90°").click();
    h.run_steps(2);
    h.get_by_label("Grow the canvas").click();
    h.run_steps(2);
    let ed = &h.state().editor;
    assert_eq!(leaves(&h).len(), 12, "every voxel kept");
    let size = ed.volume_of(id).expect("model");
    assert!(size.x > 8, "the canvas grew: {size}");
    assert_eq!(ed.history().undo_len(), steps + 1, "one step");
    // The turned bar lies along x now.
    let xs: std::collections::BTreeSet<u32> = leaves(&h).iter().map(|l| l.0.x).collect();
    assert_eq!(xs.len(), 6, "{xs:?}");
    // At the canvas's low x wall an arrow toward it moves nothing and says so.
    let after = hash_of(&leaves(&h));
    let low = leaves(&h).iter().map(|l| l.0.x).min().unwrap();
    assert_eq!(low, 0, "the grown canvas starts at the bar");
    h.key_press(egui::Key::ArrowLeft);
    h.run_steps(2);
    assert_eq!(hash_of(&leaves(&h)), after, "nothing dropped");
    assert_eq!(h.state().editor.history().undo_len(), steps + 1, "no step");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(2);
    assert_eq!(
        hash_of(&leaves(&h)),
        before,
        "one undo puts the bar and canvas back"
    );
    assert_eq!(h.state().editor.volume_of(id), Some(UVec3::splat(8)));
}

/// File → Export .vox with a mesh in the scene says, before the file is chosen, that the mesh
/// would be left out, and offers to voxelize it: the voxel model it makes is the one `thicket
/// import` makes at that depth, the export's file prompt follows, and the written file holds
/// both voxel models. "Export without them" goes straight to the prompt; Cancel does nothing.
#[test]
fn export_vox_with_a_mesh_in_the_scene_reports_it_and_can_voxelize_it() {
    use thicket_core::sculpt::model_ops::InitialFill;
    let spot = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/static/spot/spot_triangulated.obj"
    );
    let (doc, _, _) = thicket::files::load_document_imported(
        std::path::Path::new(spot),
        &thicket::files::MeshOptions::default(),
    )
    .unwrap();
    let ObjectKind::Mesh(mesh) = &doc.objects[0].kind else {
        panic!("a mesh object");
    };
    let settings = thicket_core::voxelize::VoxelizeSettings {
        resolution: thicket_core::voxelize::Resolution::Depth(5),
        ..thicket_core::voxelize::VoxelizeSettings::default()
    };
    let expected = thicket_core::voxelize::voxelize(&mesh.model, &settings, &|_| true).unwrap();
    let mut ed = Editor::new(doc, None);
    ed.add_voxel_model(&thicket::editor::NewModelSpec {
        name: "Slab".into(),
        size: UVec3::new(6, 4, 6),
        // The spot's voxel size, so the .vox grid holds both at one cell per voxel.
        voxel_size: expected.voxel_size,
        fill: InitialFill::GroundSlab { height: 1 },
        ..thicket::editor::NewModelSpec::default()
    })
    .unwrap();
    let mut h = harness_sized(ed, egui::vec2(1280.0, 800.0));
    let open_offer = |h: &mut Harness<'static, EditorApp>| {
        h.get_by_label("File").click();
        h.run_steps(2);
        h.get_by_label("Export .vox...").click();
        h.run_steps(2);
    };
    open_offer(&mut h);
    h.get_by_label_contains("1 mesh object(s) would be left out: \"spot_triangulated\"");
    h.get_by_label("Cancel").click();
    h.run_steps(2);
    assert!(h.state().vox_export.offer.is_none());
    assert_eq!(
        h.state().editor.doc().objects.len(),
        2,
        "Cancel changes nothing"
    );

    open_offer(&mut h);
    h.get_by_label("Export without them").click();
    h.run_steps(4);
    h.get_by_label("Export MagicaVoxel (.vox)");
    h.get_by_label("Cancel").click();
    h.run_steps(2);

    open_offer(&mut h);
    h.state_mut().voxelize.depth = 5;
    h.run_steps(1);
    h.get_by_label("Voxelize the meshes, then export").click();
    h.run_steps(1);
    let ctx = h.ctx.clone();
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(4);
    let doc = h.state().editor.doc();
    let made = doc
        .objects
        .iter()
        .find(|o| o.name == "spot_triangulated voxels")
        .expect("the mesh voxelized");
    let ObjectKind::Voxels(v) = &made.kind else {
        panic!("a voxel model");
    };
    assert!(expected.svo.leaf_count() > 1_000);
    assert_eq!(
        v.svo.leaves(),
        expected.svo.leaves(),
        "thicket import's voxels"
    );
    // The export's file prompt follows; the file holds both voxel models.
    h.get_by_label("Export MagicaVoxel (.vox)");
    h.get_by_label("Cancel").click();
    h.run_steps(2);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("both.vox");
    h.state_mut().start_export_vox(out.clone());
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    let back = thicket_core::io::vox::import_vox(&out).unwrap();
    assert_eq!(
        back.voxel_count(),
        expected.svo.leaf_count() + 36,
        "the slab's 36 voxels and the voxelized mesh"
    );
}

/// The main layout with each tool (and Navigate) at a laptop's 1280×720 and a desktop's
/// 1600×1000: the tool bar stays on one row, the swatches keep their places, the view keeps its
/// size whatever the tool, and a snapshot of each is kept (looked at).
#[test]
fn the_main_layout_with_each_tool_at_1280x720_and_1600x1000() {
    use thicket::editor::NewModelSpec;
    use thicket::ui::voxel_tools::ToolKind;
    use thicket_core::sculpt::model_ops::InitialFill;
    let mut results = egui_kittest::SnapshotResults::new();
    for (w, h_px) in [(1280.0, 720.0), (1600.0, 1000.0)] {
        let mut ed = Editor::new(Document::default(), None);
        let id = ed
            .add_voxel_model(&NewModelSpec {
                name: "Block".into(),
                size: UVec3::new(12, 6, 12),
                fill: InitialFill::GroundSlab { height: 3 },
                color: [150, 110, 70, 255],
                ..NewModelSpec::default()
            })
            .unwrap();
        ed.selection = Some(thicket::editor::Selection::Object(id));
        ed.frame_selection();
        let mut h = harness_sized(ed, egui::vec2(w, h_px));
        h.run_steps(2);
        let layout = |h: &Harness<'static, EditorApp>| -> Vec<egui::Rect> {
            h.query_all_by_label_contains("Swatch ")
                .map(|n| n.rect())
                .collect()
        };
        let mut first: Option<Vec<egui::Rect>> = None;
        let mut states: Vec<(String, Option<ToolKind>)> = vec![("navigate".into(), None)];
        states.extend(
            ToolKind::ALL
                .iter()
                .map(|(t, label, _)| (label.to_lowercase(), Some(*t))),
        );
        for (name, tool) in states {
            match tool {
                Some(t) => h.state_mut().sculpt.choose(t),
                None => h.state_mut().sculpt.active = false,
            }
            h.run_steps(2);
            for _ in 0..4 {
                h.state_mut().view.wait_for_cpu_preview();
                h.run_steps(1);
            }
            let swatches = layout(&h);
            assert!(!swatches.is_empty());
            assert!(
                swatches.iter().all(|r| r.right() <= w),
                "{name} at {w}: the tool bar fits"
            );
            match &first {
                None => first = Some(swatches),
                Some(f) => assert_eq!(&swatches, f, "{name} at {w}: the swatches stay put"),
            }
            results.add(h.try_snapshot_options(
                format!("layout_{w}x{h_px}_{name}"),
                &egui_kittest::SnapshotOptions::new().max_failed_pixels(400),
            ));
        }
    }
    results.unwrap();
}

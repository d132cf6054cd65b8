//! Grow forest on the real app, driven by egui_kittest: the tree sample's tree grown into a
//! forest from the inspector's Forest section, a slider step regrowing it live as one undo step,
//! undo removing it; snapshots of the section, looked at.

mod common;

use egui::accesskit::Role;
use egui_kittest::kittest::Queryable as _;
use egui_kittest::{Harness, SnapshotOptions};
use thicket::editor::{Editor, Selection};
use thicket::ui::EditorApp;
use thicket_core::scene::{Document, ObjectKind};

const SIZE: egui::Vec2 = egui::vec2(1100.0, 760.0);

fn harness(doc: Document) -> Harness<'static, EditorApp> {
    let mut app = EditorApp::new(Editor::new(doc, None));
    app.autosave_secs = 0;
    app.native_dialogs = false;
    let mut h = Harness::builder()
        .with_size(SIZE)
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    h
}

fn tree_sample() -> Document {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../projects/tree.thicket.json");
    let mut doc = thicket_core::io::project::load(std::path::Path::new(path)).expect("sample");
    // The preview's shadows and AO are not what this test looks at.
    doc.quality.shadows = false;
    doc.quality.ao_samples = 0;
    doc
}

fn settle_preview(h: &mut Harness<'static, EditorApp>) {
    for _ in 0..4 {
        h.state_mut().view.wait_for_cpu_preview();
        h.run_steps(1);
    }
}

fn press_undo(h: &mut Harness<'static, EditorApp>) {
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(2);
}

/// Trees the document's forests place (kernel instances of the grown objects over the tree's).
fn trees_placed(doc: &Document) -> u128 {
    let krs = |id: u64| match &doc.objects.iter().find(|o| o.id == id).unwrap().kind {
        ObjectKind::Krs(k) => k.instance_count(),
        _ => panic!("KRS"),
    };
    doc.forests
        .iter()
        .map(|l| l.objects.iter().map(|&o| krs(o)).sum::<u128>() / krs(l.sources[0]))
        .sum()
}

#[test]
fn grow_a_forest_from_the_tree_sample_regrow_it_with_a_slider_and_undo() {
    let mut h = harness(tree_sample());
    let tree = h.state().editor.doc().objects[0].id;
    h.state_mut().editor.selection = Some(Selection::Object(tree));
    h.run_steps(2);
    h.get_by_label("Forest").click_accesskit();
    h.run_steps(2);
    settle_preview(&mut h);
    h.snapshot_options(
        "forest_panel_before",
        &SnapshotOptions::new().max_failed_pixels(200),
    );
    let content = h.state().editor.content_key();
    h.get_by_label("Grow forest").click_accesskit();
    h.run_steps(2);
    let ed = &h.state().editor;
    assert_eq!(ed.doc().forests.len(), 1, "a forest stands");
    assert_eq!(trees_placed(ed.doc()), 64, "8 × 8 trees by default");
    let link = ed.doc().forests[0].clone();
    assert!(!ed.object(tree).unwrap().visible, "the tree is hidden");
    assert_eq!(
        ed.selection,
        Some(Selection::Object(link.objects[0])),
        "the forest is selected"
    );
    assert_ne!(ed.content_key(), content, "the preview redraws");
    // Framed on the grid (about 73 × 73 from the tree at the origin), not the tree alone.
    let camera = ed.doc().camera;
    assert!(
        camera.target.x > 20.0 && camera.target.z > 20.0 && camera.distance > 50.0,
        "{camera:?}"
    );
    settle_preview(&mut h);
    h.snapshot_options(
        "forest_panel_grown",
        &SnapshotOptions::new().max_failed_pixels(200),
    );

    // One step of the "Trees along x" slider (the first slider of the section): 16 × 8.
    let sliders: Vec<_> = h.get_all_by_role(Role::Slider).collect();
    assert!(sliders.len() >= 2, "the trees sliders");
    sliders[0].focus();
    h.run_steps(1);
    h.key_press(egui::Key::ArrowRight);
    h.run_steps(2);
    let ed = &h.state().editor;
    assert_eq!(ed.doc().forests[0].params.trees, [16, 8]);
    assert_eq!(trees_placed(ed.doc()), 128, "regrown live");
    assert_eq!(
        ed.doc().forests[0].objects,
        link.objects,
        "the grown object keeps its id"
    );

    // Undo: back to 8 × 8; undo again: no forest, the tree shown.
    // (Esc gives the slider's keyboard focus back to the editor's shortcuts.)
    h.key_press(egui::Key::Escape);
    h.run_steps(1);
    press_undo(&mut h);
    assert_eq!(trees_placed(h.state().editor.doc()), 64);
    press_undo(&mut h);
    let ed = &h.state().editor;
    assert!(ed.doc().forests.is_empty(), "undo removes the forest");
    assert!(ed.object(link.objects[0]).is_none());
    assert!(ed.object(tree).unwrap().visible, "the tree is back");
}

#[test]
fn a_rock_has_no_forest_section_and_a_union_with_one_is_refused() {
    let mut doc = tree_sample();
    let rock = doc.add(
        "Rock",
        ObjectKind::Krs(thicket_core::krs::presets::battered_rock(2)),
    );
    let tree = doc.objects[0].id;
    let mut h = harness(doc);
    h.state_mut().editor.selection = Some(Selection::Object(rock));
    h.run_steps(2);
    assert!(
        h.query_by_label("Grow forest").is_none() && h.query_by_label("Forest").is_none(),
        "the rock is not a tree"
    );
    let before = h.state().editor.doc().clone();
    let err = h
        .state_mut()
        .editor
        .grow_forest(
            &[tree, rock],
            None,
            &thicket_core::krs::forest::ForestParams {
                trees: [4, 4],
                ..Default::default()
            },
        )
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("\"Rock\" is not a tree the tree builder made"),
        "{err}"
    );
    assert_eq!(h.state().editor.doc(), &before, "nothing changed");
}

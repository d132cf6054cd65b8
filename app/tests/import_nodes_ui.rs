//! File → Import of a glTF scene in the real editor (egui_kittest): one object per node, and
//! the Import report's checklist of nodes that imports the file again with the checked ones.
//! The snapshot (the report over the imported scene, CPU preview) is in `tests/snapshots/`.

mod common;

use egui::accesskit::Role;
use egui_kittest::kittest::Queryable as _;
use egui_kittest::wgpu::WgpuTestRenderer;
use egui_kittest::{Harness, SnapshotOptions};
use thicket::editor::Editor;
use thicket::ui::EditorApp;
use thicket_core::scene::{Document, ObjectKind};

fn names(h: &Harness<'static, EditorApp>) -> Vec<String> {
    h.state()
        .editor
        .doc()
        .objects
        .iter()
        .map(|o| o.name.clone())
        .collect()
}

#[test]
fn a_scene_imports_one_object_per_node_and_the_report_picks_nodes() {
    let dir = tempfile::tempdir().expect("temp dir");
    common::write_node_scene(dir.path());
    // The toast and the status bar show the imported path: a relative one keeps the snapshot
    // the same in every run (this file's only test, so changing the directory is safe).
    std::env::set_current_dir(dir.path()).expect("cd");
    let path = std::path::PathBuf::from("scene.gltf");
    let mut app = EditorApp::new(Editor::new(Document::default(), None));
    app.autosave_secs = 0;
    app.native_dialogs = false;
    let mut h = Harness::builder()
        .with_size(egui::vec2(1000.0, 640.0))
        .renderer(WgpuTestRenderer::new())
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    let ctx = h.ctx.clone();
    h.state_mut().start_import(path);
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(3);
    assert_eq!(names(&h), ["Cube", "Slab", "Ground"]);
    // File → Import keeps meshes as meshes; each is placed by its node (the parent's scale 2
    // is on the cube's transform; the editor's fit-to-scene adds nothing to an empty scene).
    let cube = h.state().editor.doc().object_by_name("Cube").expect("cube");
    assert!(matches!(cube.kind, ObjectKind::Mesh(_)));
    assert!(
        (cube.transform.scale.x - 2.0).abs() < 1e-4,
        "{:?}",
        cube.transform
    );
    let report = h.state().import_report.clone().expect("an import report");
    assert_eq!(
        report.nodes,
        [
            ("Cube".to_owned(), true),
            ("Slab".to_owned(), true),
            ("Ground".to_owned(), true)
        ]
    );
    h.get_by_label("Import report");
    h.get_by_label("Nodes (one object each):");
    // Let the CPU preview catch up, so its image and caption are the final ones.
    for _ in 0..4 {
        h.state_mut().view.wait_for_cpu_preview();
        h.run_steps(1);
    }
    h.snapshot_options(
        "import_node_checklist",
        &SnapshotOptions::new()
            .max_failed_pixels(200)
            .output_path(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/snapshots")),
    );

    // Uncheck the slab and the ground, import again: only the cube, replacing the three.
    // The outliner lists the objects under the same names: the checkboxes are asked for by role.
    h.get_by_role_and_label(Role::CheckBox, "Slab").click();
    h.get_by_role_and_label(Role::CheckBox, "Ground").click();
    h.run_steps(1);
    h.get_by_label("Import again with these").click();
    h.run_steps(1);
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    assert_eq!(names(&h), ["Cube"]);
    let report = h
        .state()
        .import_report
        .clone()
        .expect("the checklist again");
    assert_eq!(
        report.nodes,
        [
            ("Cube".to_owned(), true),
            ("Slab".to_owned(), false),
            ("Ground".to_owned(), false)
        ]
    );
    // With nothing checked the button does nothing.
    h.get_by_label("None").click();
    h.run_steps(1);
    h.get_by_label("Import again with these").click();
    h.run_steps(2);
    assert!(h.state().import_report.is_some());
    assert_eq!(names(&h), ["Cube"]);
    h.get_by_label("OK").click();
    h.run_steps(2);
    assert!(h.state().import_report.is_none());
}

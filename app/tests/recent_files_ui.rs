//! Recent files are stored absolute: one opened by a relative path from folder A is still the
//! same file from folder B (the editor started again elsewhere). File → Recent greys out a file
//! that is gone and offers to remove it.
//!
//! A test binary of its own: it changes the process's working folder, which tests running
//! beside it on other threads would see.

use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};
use thicket::editor::Editor;
use thicket::ui::EditorApp;
use thicket_core::scene::Document;

#[test]
fn a_recent_file_opened_by_a_relative_path_stays_valid_from_another_folder() {
    let folder_a = tempfile::tempdir().unwrap();
    let folder_b = tempfile::tempdir().unwrap();
    // As the system names the folder (the working folder is reported with links resolved).
    let folder_a_path = folder_a.path().canonicalize().unwrap();
    let house = folder_a_path.join("house.thicket.json");
    thicket::files::save_project(&Document::default(), &house).unwrap();
    let gone = folder_a_path.join("gone.thicket.json");

    let mut app = EditorApp::new(Editor::new(Document::default(), None));
    app.autosave_secs = 0;
    app.native_dialogs = false;
    std::env::set_current_dir(folder_a.path()).unwrap();
    app.editor.push_recent("gone.thicket.json".into());
    app.editor.push_recent("house.thicket.json".into());
    // The list as it is persisted between runs, read back from another folder.
    std::env::set_current_dir(folder_b.path()).unwrap();
    assert_eq!(app.editor.recent, [house.clone(), gone.clone()]);
    assert!(
        app.editor.recent[0].is_file(),
        "still names the file from B"
    );

    let mut h = Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Recent").click();
    h.run_steps(2);
    let row = |h: &Harness<'static, EditorApp>, p: &std::path::Path| {
        h.get_by_label(&p.display().to_string())
            .accesskit_node()
            .is_disabled()
    };
    assert!(!row(&h, &house), "an existing file can be opened");
    assert!(row(&h, &gone), "a missing file is greyed out");
    h.get_by_label("Remove from list").click();
    h.run_steps(2);
    assert_eq!(
        h.state().editor.recent,
        std::slice::from_ref(&house),
        "removed from the list"
    );
    assert!(h.query_by_label(&gone.display().to_string()).is_none());

    // The click closed the menu: open it again and pick the file.
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Recent").click();
    h.run_steps(2);
    h.get_by_label(&house.display().to_string()).click();
    h.run_steps(2);
    let ctx = h.ctx.clone();
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(2);
    assert_eq!(h.state().editor.path(), Some(house.as_path()));
}

//! The Trade-off panel driven headlessly with egui_kittest: opened from the View menu, it runs
//! a small sweep of the current view as a background job, plots it, and a click on a point
//! makes that setting the document's quality (one undo step).

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use thicket::editor::Editor;
use thicket::ui::EditorApp;
use thicket::ui::tradeoff::CostAxis;

fn mixed_sample() -> EditorApp {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/mixed.thicket.json");
    let doc = thicket::files::load_document(&path).unwrap();
    let mut app = EditorApp::new(Editor::new(doc, Some(path)));
    // The UI tests must not touch the user's recovery folder or depend on it.
    app.autosave_secs = 0;
    app.native_dialogs = false;
    app
}

fn harness(app: EditorApp) -> Harness<'static, EditorApp> {
    let mut h = Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    h
}

#[test]
fn tradeoff_panel_sweeps_the_view_and_a_click_applies_a_point() {
    let mut h = harness(mixed_sample());
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label("Trade-off").click();
    h.run_steps(2);
    assert!(h.state().tradeoff.open);
    h.get_by_label("No sweep yet.");
    // A tiny sweep: 32 px, the LOD and shadow-filter knobs, work on the x axis (deterministic
    // positions).
    {
        let panel = &mut h.state_mut().tradeoff;
        panel.size_px = 32;
        panel.axis = CostAxis::Work;
        for (k, on) in &mut panel.knobs {
            *on = k.name == "lod_pixel_threshold" || k.name == "shadow_pcf_radius";
        }
    }
    h.run_steps(1);
    // Knobs read as the inspector names them, not as identifiers.
    h.get_by_label("LOD threshold px");
    h.get_by_label("Shadow map");
    assert!(h.query_by_label("lod_pixel_threshold").is_none());
    let before = h.state().editor.doc().quality.clone();
    h.get_by_label("Run sweep").click();
    h.run_steps(1);
    assert!(
        h.state().job_running(),
        "the sweep runs as a background job"
    );
    let ctx = h.ctx.clone();
    h.state_mut().wait_for_job(&ctx);
    h.run_steps(3);
    assert_eq!(
        h.state().editor.doc().quality,
        before,
        "sweeping changes nothing"
    );
    let report = h.state().tradeoff.report().expect("a report").clone();
    // The view's aspect ratio at 32 px on its longest edge.
    assert_eq!(report.width.max(report.height), 32);
    let aspect = h.state().view.last_rect.aspect_ratio();
    let measured = report.width as f32 / report.height as f32;
    assert!(
        (measured - aspect).abs() < 0.05,
        "{}x{} for a view of aspect {aspect}",
        report.width,
        report.height
    );
    // 3 presets (balanced merged with the base), lod 0.5 / 2 / 4 / 8 and pcf 0 / 2 / 3.
    assert!(report.points.len() >= 8, "{}", report.points.len());
    assert!(report.points.iter().any(|p| p.on_work_front));

    // Click the point with the largest error (the coarsest LOD): its setting is applied.
    let (i, target) = report
        .points
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.error.rmse.total_cmp(&b.1.error.rmse))
        .unwrap();
    assert_ne!(target.setting.quality, before);
    let pos = h.state().tradeoff.point_screen_pos(i).expect("drawn");
    h.hover_at(pos);
    h.run_steps(1);
    h.drag_at(pos);
    h.run_steps(1);
    h.drop_at(pos);
    h.run_steps(2);
    assert_eq!(h.state().tradeoff.applied(), Some(i));
    assert_eq!(h.state().editor.doc().quality, target.setting.quality);
    assert!(h.state().editor.is_dirty());
    // One undo step brings the previous quality back.
    assert!(h.state_mut().editor.undo());
    assert_eq!(h.state().editor.doc().quality, before);
}

#[test]
fn a_cancelled_sweep_keeps_the_last_report_and_the_document() {
    let mut app = mixed_sample();
    app.tradeoff.size_px = 24;
    let ctx = egui::Context::default();
    app.start_tradeoff_sweep();
    assert!(app.job_running());
    app.cancel_job(&ctx);
    assert!(!app.job_running());
    assert!(app.tradeoff.report().is_none());
    assert!(!app.editor.is_dirty());
}

#[test]
fn a_sweep_over_the_memory_budget_is_refused_before_its_job_starts() {
    let mut app = mixed_sample();
    app.tradeoff.size_px = 256;
    app.memory_budget = thicket_core::budget::MemoryBudget::given(256 << 10);
    app.start_tradeoff_sweep();
    assert!(!app.job_running(), "no job over the budget");
    let said = app.error_dialog.clone().expect("the refusal is shown");
    assert!(
        said.starts_with("Trade-off sweep at 256 x ")
            && said.contains("over the limit of 256.0 KiB")
            && said.ends_with("use a smaller sweep size"),
        "{said}"
    );
    // Within the budget the same sweep starts.
    app.error_dialog = None;
    app.memory_budget = thicket_core::budget::MemoryBudget::given(1 << 30);
    app.start_tradeoff_sweep();
    assert!(app.job_running());
    app.cancel_job(&egui::Context::default());
}

#[test]
fn by_default_the_sweep_measures_at_the_views_own_size() {
    let mut app = mixed_sample();
    // Before the view is drawn its size is not known: the editor's usual 800 x 800.
    assert_eq!(app.tradeoff.size_px, thicket::ui::tradeoff::VIEW_SIZE);
    assert_eq!(
        app.tradeoff.image_size(app.view.render_size_px()),
        (800, 800)
    );
    app.tradeoff.size_px = thicket::ui::tradeoff::VIEW_SIZE;
    let h = harness(app);
    let view = h.state().view.render_size_px();
    assert!(view.x > 100.0 && view.y > 100.0, "{view:?}");
    let job = h.state().tradeoff.job(&h.state().editor, view);
    assert_eq!(
        (job.width, job.height),
        (view.x.round() as u32, view.y.round() as u32)
    );
    // A chosen edge keeps the view's aspect ratio.
    let mut panel = thicket::ui::tradeoff::TradeoffPanel::default();
    panel.size_px = 64;
    let (w, hgt) = panel.image_size(view);
    assert_eq!(w.max(hgt), 64);
}

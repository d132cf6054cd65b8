//! The real editor with its GPU viewport, driven by egui_kittest on the wgpu software adapter
//! (lavapipe here and in CI): open each sample project, click through the panels by label,
//! navigate, sculpt a stroke in the view, undo and redo it, and snapshot the window including
//! the rendered viewport.
//!
//! Snapshots live in `tests/snapshots/`; on a mismatch egui_kittest writes `NAME.new.png` and
//! `NAME.diff.png` beside them (`UPDATE_SNAPSHOTS=1` accepts the new images).

use std::path::PathBuf;

use egui_kittest::kittest::Queryable as _;
use egui_kittest::wgpu::{WgpuTestRenderer, create_render_state};
use egui_kittest::{Harness, SnapshotOptions};
use thicket::editor::{Editor, Selection};
use thicket::preview::viewport::ViewportLink;
use thicket::ui::EditorApp;
use thicket::ui::view::ViewRenderer;
use thicket_core::scene::ObjectKind;

/// Small enough to keep software rendering quick, large enough for every panel.
const SIZE: egui::Vec2 = egui::vec2(1100.0, 700.0);

fn sample(name: &str) -> PathBuf {
    // Relative, so the path shown in the status bar (and the snapshots) is the same in every
    // checkout.
    PathBuf::from(format!("../projects/{name}.thicket.json"))
}

/// The app on a sample, with the GPU viewport installed on a fresh software device.
fn gpu_harness(name: &str) -> (Harness<'static, EditorApp>, ViewportLink) {
    gpu_harness_with(name, 1.0, ViewRenderer::Gpu)
}

/// [`gpu_harness`] with the view rendered at `render_scale` of its pixels from the first frame.
fn gpu_harness_scaled(
    name: &str,
    render_scale: f32,
) -> (Harness<'static, EditorApp>, ViewportLink) {
    gpu_harness_with(name, render_scale, ViewRenderer::Gpu)
}

/// The editor on a sample with the GPU viewport attached, drawn by `renderer` (the tests of the
/// GPU viewport choose GPU: in Auto a software adapter, such as CI's lavapipe, hands the view
/// to the CPU preview).
fn gpu_harness_with(
    name: &str,
    render_scale: f32,
    renderer: ViewRenderer,
) -> (Harness<'static, EditorApp>, ViewportLink) {
    let render_state = create_render_state(
        thicket::preview::viewport::wgpu_setup(),
        egui_wgpu::RendererOptions::PREDICTABLE,
    );
    let link = thicket::preview::viewport::install(&render_state);
    let path = sample(name);
    let mut doc = thicket::files::load_document(&path).expect("the sample loads");
    // Shadow maps are the slow part on a software rasteriser (the 2048² shadow splats take
    // seconds on lavapipe): these tests check the editor, not shadows.
    doc.quality.shadows = false;
    let mut app = EditorApp::new(Editor::new(doc, Some(path)));
    // The UI tests must not touch the user's recovery folder or depend on it.
    app.autosave_secs = 0;
    app.native_dialogs = false;
    app.attach_gpu(link.clone());
    app.view.render_scale = render_scale;
    app.view.renderer = renderer;
    let mut h = Harness::builder()
        .with_size(SIZE)
        .renderer(WgpuTestRenderer::from_render_state(render_state))
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    (h, link)
}

fn view_center(h: &Harness<'static, EditorApp>) -> egui::Pos2 {
    h.state().view.last_rect.center()
}

/// Standard deviation of the luminance inside the view rectangle: a flat background is ~0.
fn view_contrast(image: &image::RgbaImage, rect: egui::Rect) -> f64 {
    let mut n = 0.0;
    let (mut sum, mut sum2) = (0.0, 0.0);
    for y in (rect.top() as u32 + 30)..(rect.bottom() as u32).min(image.height()) {
        for x in (rect.left() as u32)..(rect.right() as u32).min(image.width()) {
            let p = image.get_pixel(x, y);
            let l = f64::from(p[0]) * 0.3 + f64::from(p[1]) * 0.59 + f64::from(p[2]) * 0.11;
            n += 1.0;
            sum += l;
            sum2 += l * l;
        }
    }
    let mean = sum / n;
    (sum2 / n - mean * mean).max(0.0).sqrt()
}

fn snapshot(h: &mut Harness<'static, EditorApp>, name: &str) {
    // Software rasterisation is deterministic, but allow a few pixels of driver variation.
    h.snapshot_options(name, &SnapshotOptions::new().max_failed_pixels(200));
}

/// Opens a sample, checks the view shows it, that idle frames do not render and that an orbit
/// renders once, and snapshots the window.
fn sample_opens_renders_once_and_rerenders_only_on_change(name: &str) {
    {
        let (mut h, link) = gpu_harness(name);
        let image = h.render().expect("render");
        let s = link.lock().clone();
        assert!(s.error.is_none(), "{name}: {:?}", s.error);
        assert_eq!(s.frames_rendered, 1, "{name}");
        assert!(s.stats.as_ref().is_some_and(|st| st.splats > 0), "{name}");
        // Figures for the report (not asserted: the machine is shared and noisy).
        eprintln!(
            "{name}: viewport render {:.1} ms at {} x {} px on {}",
            s.last_render_ms, s.size_px[0], s.size_px[1], s.adapter
        );
        if let Some(st) = &s.stats {
            eprintln!(
                "{name}: passes {:?}, total {:.1} ms",
                st.pass_ms, st.total_ms
            );
        }
        let rect = h.state().view.last_rect;
        assert!(
            view_contrast(&image, rect) > 5.0,
            "{name}: the viewport shows the scene, not a flat background"
        );
        snapshot(&mut h, &format!("sample_{name}"));

        // Nothing changed: the next frames composite the same image without rendering.
        h.run_steps(3);
        h.render().expect("render");
        assert_eq!(
            link.lock().frames_rendered,
            1,
            "{name}: idle frames do not render"
        );

        // Orbit with a drag: the camera changes and the view renders again.
        let c = view_center(&h);
        let yaw = h.state().editor.doc().camera.yaw_deg;
        h.drag_at(c);
        h.step();
        h.hover_at(c + egui::vec2(60.0, 0.0));
        h.step();
        h.drop_at(c + egui::vec2(60.0, 0.0));
        h.run_steps(2);
        assert_ne!(h.state().editor.doc().camera.yaw_deg, yaw, "{name}: orbit");
        assert!(!h.state().editor.is_dirty(), "orbiting is not editing");
        h.render().expect("render");
        assert_eq!(
            link.lock().frames_rendered,
            2,
            "{name}: one render after the orbit"
        );
        eprintln!(
            "{name}: after the orbit {:.1} ms; first frame uploaded {:?}",
            link.lock().last_render_ms,
            s.last_upload
        );
        // Only the camera moved: the scene on the GPU is reused as it is.
        let upload = link.lock().last_upload.expect("an upload record");
        assert!(
            !upload.full && upload.bytes == 0,
            "{name}: an orbit uploads nothing: {upload:?}"
        );
    }
}

#[test]
fn house_opens_renders_once_and_rerenders_only_on_change() {
    sample_opens_renders_once_and_rerenders_only_on_change("house");
}

#[test]
fn mixed_opens_renders_once_and_rerenders_only_on_change() {
    sample_opens_renders_once_and_rerenders_only_on_change("mixed");
}

#[test]
fn forest_draws_its_krs_on_the_gpu() {
    // KRS documents no longer fall back to the CPU preview: the GPU viewport sphere-traces the
    // forest (33M kernel instances). A quarter of the view's pixels keeps lavapipe quick.
    let (mut h, link) = gpu_harness_scaled("forest", 0.25);
    let image = h.render().expect("render");
    let s = link.lock().clone();
    assert!(s.error.is_none(), "{:?}", s.error);
    assert_eq!(s.frames_rendered, 1);
    let st = s.stats.as_ref().expect("GPU frame statistics");
    assert!(st.krs.rays > 0 && st.krs.hits > 0, "{:?}", st.krs);
    eprintln!(
        "forest: viewport render {:.1} ms at {} x {} px on {}; KRS {:?}",
        s.last_render_ms, s.size_px[0], s.size_px[1], s.adapter, st.krs
    );
    let rect = h.state().view.last_rect;
    assert!(
        view_contrast(&image, rect) > 5.0,
        "the viewport shows the forest, not a flat background"
    );
    snapshot(&mut h, "sample_forest");
    // The perf overlay reports the KRS pass's rays and steps per ray.
    h.key_press(egui::Key::F3);
    h.run_steps(3);
    h.get_by_label_contains("steps per ray");
}

#[test]
fn panels_sculpt_stroke_undo_redo_and_snapshot() {
    let (mut h, link) = gpu_harness("house");

    // View menu: axis view and the perf overlay, by label.
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label_contains("Front").click();
    h.run_steps(2);
    let cam = h.state().editor.doc().camera;
    assert_eq!((cam.yaw_deg, cam.pitch_deg), (0.0, 0.0));
    h.key_press(egui::Key::F3);
    h.run_steps(2);
    h.get_by_label("Performance");
    h.key_press(egui::Key::F3);
    h.run_steps(2);

    // Render menu: the draft preset is one undoable edit.
    h.get_by_label("Render").click();
    h.run_steps(2);
    h.get_by_label("Draft").click();
    h.run_steps(2);
    assert!(h.state().editor.is_dirty());
    h.key_press(egui::Key::Escape);
    h.run_steps(1);

    // The outliner selects the house model.
    let house_id = h
        .state()
        .editor
        .doc()
        .objects
        .iter()
        .find(|o| matches!(o.kind, ObjectKind::Voxels(_)))
        .expect("a voxel model")
        .id;
    let house_name = h.state().editor.object(house_id).unwrap().name.clone();
    h.query_all_by_label(&house_name)
        .next()
        .expect("an outliner row")
        .click();
    h.run_steps(2);
    assert_eq!(
        h.state().editor.selection,
        Some(Selection::Object(house_id))
    );
    h.key_press(egui::Key::F);
    h.run_steps(2);

    // Sculpt tool from the tool bar, Remove, bigger brush.
    h.get_by_label("Brush").click();
    h.run_steps(1);
    h.get_by_label("Remove").click();
    h.run_steps(1);
    h.state_mut().sculpt.brush.radius = 3.0;
    let leaves =
        |h: &Harness<'static, EditorApp>| match &h.state().editor.object(house_id).unwrap().kind {
            ObjectKind::Voxels(v) => v.svo.leaf_count(),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => unreachable!(),
        };
    let before = leaves(&h);
    let steps_before = h.state().editor.history().undo_len();
    h.render().expect("render");
    let rendered_before = link.lock().frames_rendered;

    // A stroke across the middle of the view.
    let c = view_center(&h);
    h.hover_at(c);
    h.step();
    h.drag_at(c);
    h.step();
    for k in 1..=6 {
        h.hover_at(c + egui::vec2(8.0 * k as f32, 0.0));
        h.step();
    }
    // The dab is visible in the next frame: the view renders with the edited document. Only
    // the stroke's region is uploaded (the snapshot below, made with whole-scene uploads,
    // checks that the image is the same).
    let region_uploads = link.lock().region_uploads;
    h.render().expect("render");
    assert!(link.lock().frames_rendered > rendered_before);
    let upload = link.lock().last_upload.expect("an upload");
    assert!(
        !upload.full,
        "the stroke uploaded its region only: {upload:?}"
    );
    assert_eq!(link.lock().region_uploads, region_uploads + 1);
    eprintln!(
        "stroke frame uploaded {upload:?}, rendered in {:.1} ms",
        link.lock().last_render_ms
    );
    h.drop_at(c + egui::vec2(48.0, 0.0));
    h.run_steps(2);
    let after = leaves(&h);
    assert!(
        after < before,
        "the stroke removed voxels: {before} -> {after}"
    );
    assert_eq!(
        h.state().editor.history().undo_len(),
        steps_before + 1,
        "one undo step per stroke"
    );
    snapshot(&mut h, "house_after_stroke");

    // Undo and redo through the Edit menu.
    h.get_by_label("Edit").click();
    h.run_steps(2);
    h.get_by_label_contains("Undo").click();
    h.run_steps(2);
    assert_eq!(leaves(&h), before);
    // The undo is the stroke's box again (the change feed records it): uploaded as a region.
    let region_uploads = link.lock().region_uploads;
    h.render().expect("render");
    let upload = link.lock().last_upload.expect("an upload");
    assert!(
        !upload.full,
        "the undo uploaded its region only: {upload:?}"
    );
    assert_eq!(link.lock().region_uploads, region_uploads + 1);
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::Z,
    );
    h.run_steps(2);
    assert_eq!(leaves(&h), after);
    assert!(link.lock().error.is_none());
}

#[test]
fn rigged_sample_draws_on_the_gpu_and_scrubbing_uploads_only_joints() {
    // A rigged model no longer sends the view to the CPU preview: the GPU skins it. Moving
    // the playhead redraws once, uploading only the 19 joint matrices; the hole / bloat overlay
    // (computed from the CPU preview's image) still switches the view to the CPU preview.
    let (mut h, link) = gpu_harness("cesiumman");
    h.render().expect("render");
    assert!(
        !h.state().view.uses_cpu(&h.state().editor),
        "the rigged sample is drawn by the GPU"
    );
    let s = link.lock().clone();
    assert!(s.error.is_none(), "{:?}", s.error);
    assert_eq!(s.frames_rendered, 1);
    assert!(s.stats.as_ref().is_some_and(|st| st.splats > 0));
    let id = h
        .state()
        .editor
        .doc()
        .objects
        .iter()
        .find(|o| matches!(&o.kind, thicket_core::scene::ObjectKind::Voxels(v) if v.rig.is_some()))
        .expect("the rigged model")
        .id;
    let mut playback = h.state().editor.rig(id).expect("rigged").playback;
    playback.time_secs += 0.4;
    h.state_mut()
        .editor
        .set_playback(id, playback)
        .expect("playback");
    h.run_steps(2);
    h.render().expect("render");
    let s = link.lock().clone();
    assert!(s.error.is_none(), "{:?}", s.error);
    assert_eq!(s.frames_rendered, 2, "one render after the time change");
    let upload = s.last_upload.expect("an upload record");
    assert!(
        !upload.full
            && !upload.skin_data
            && upload.bytes == 19 * 64
            && upload.joint_bytes == 19 * 64,
        "a new clip time uploads only the joint matrices: {upload:?}"
    );

    // Turning a joint with the pose tool is an undoable edit of the rig, not of voxels: the
    // view redraws once and, again, uploads only the joint matrices.
    h.state_mut()
        .editor
        .rotate_joint(id, 1, None, glam::Quat::from_rotation_z(0.5))
        .expect("pose edit");
    h.state_mut().editor.end_interaction();
    h.run_steps(2);
    h.render().expect("render");
    let s = link.lock().clone();
    assert!(s.error.is_none(), "{:?}", s.error);
    assert_eq!(s.frames_rendered, 3, "one render after the pose edit");
    let upload = s.last_upload.expect("an upload record");
    assert!(
        !upload.full && upload.bytes == 19 * 64 && upload.joint_bytes == 19 * 64,
        "a pose edit uploads only the joint matrices: {upload:?}"
    );
    // Undo is another kind of change: uploaded in full (correct, not minimal).
    assert!(h.state_mut().editor.undo());
    h.run_steps(2);
    h.render().expect("render");
    assert_eq!(link.lock().frames_rendered, 4);

    // In Auto the hole / bloat overlay hands the view to the CPU preview, whatever the adapter.
    h.state_mut().view.renderer = ViewRenderer::Auto;
    let software = link.lock().software;
    h.state_mut().view.show_holes = true;
    assert!(h.state().view.uses_cpu(&h.state().editor));
    // So do the stretch heat map and stretch painting (they read the preview's image and ids).
    h.state_mut().view.show_holes = false;
    assert_eq!(h.state().view.uses_cpu(&h.state().editor), software);
    h.state_mut().view.show_stretch = true;
    assert!(h.state().view.uses_cpu(&h.state().editor));
}

#[test]
fn auto_draws_with_the_cpu_preview_when_the_gpu_is_a_software_rasteriser() {
    // Lavapipe runs the GPU renderer's shaders on the CPU, 11 to 113× slower than the CPU
    // preview on the samples (BENCHMARKS.md), so Auto hands it the view; a hardware adapter
    // keeps it. CI has lavapipe, so there the first branch runs.
    let (mut h, link) = gpu_harness_with("house", 1.0, ViewRenderer::Auto);
    let (software, adapter) = {
        let status = link.lock();
        (status.software, status.adapter.clone())
    };
    assert_eq!(
        adapter.to_lowercase().contains("llvmpipe"),
        software,
        "lavapipe is the software adapter: {adapter}"
    );
    assert_eq!(h.state().view.uses_cpu(&h.state().editor), software);
    for _ in 0..4 {
        h.state_mut().view.wait_for_cpu_preview();
        h.run_steps(1);
    }
    h.render().expect("render");
    let (cpu_frames, gpu_frames) = (
        h.state().view.cpu_preview().renders(),
        link.lock().frames_rendered,
    );
    if software {
        assert!(
            cpu_frames >= 1 && gpu_frames == 0,
            "{cpu_frames} CPU, {gpu_frames} GPU"
        );
    } else {
        assert!(
            cpu_frames == 0 && gpu_frames >= 1,
            "{cpu_frames} CPU, {gpu_frames} GPU"
        );
    }
    // Choosing GPU draws with it even on a software adapter.
    h.state_mut().view.renderer = ViewRenderer::Gpu;
    h.run_steps(2);
    h.render().expect("render");
    assert!(!h.state().view.uses_cpu(&h.state().editor));
    assert!(link.lock().frames_rendered >= 1);
    assert!(link.lock().error.is_none(), "{:?}", link.lock().error);
}

#[test]
fn forest_export_window_offers_the_krs_instancing_options() {
    let (mut h, _link) = gpu_harness_scaled("forest", 0.25);
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Export glTF...").click();
    h.run_steps(3);
    // Every option of `thicket export` that a forest needs is in the window.
    for label in [
        "Automatic",
        "Around the objects",
        "Lights and camera",
        "Triangle budget",
        "Most instances",
    ] {
        h.get_by_label_contains(label);
    }
    // A chosen level and a patch show their fields.
    h.get_by_label("Automatic").click();
    h.get_by_label("Around the objects").click();
    h.run_steps(3);
    assert_eq!(h.state().gltf_export.options.instance_level, Some(0));
    assert!(h.state().gltf_export.options.bounds.is_some());
    // The placements' form, with its consequence said before the file is written.
    h.get_by_label(
        "Viewers without EXT_mesh_gpu_instancing refuse the file (Blender 3.4 among them)",
    );
    h.get_by_label("A node each").click();
    h.run_steps(2);
    assert_eq!(
        h.state().gltf_export.options.instancing,
        thicket_core::io::gltf_export::Instancing::Nodes
    );
    h.get_by_label("Every viewer opens it; no levels of detail for the placed copies");
    snapshot(&mut h, "export_gltf_forest");
}

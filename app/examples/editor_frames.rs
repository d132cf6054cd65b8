//! Measures the editor's frame (issue #8: "UI + viewport frame ≤ 16 ms for the sample projects
//! on a real GPU; report lavapipe figures too"): the real app with its GPU viewport, driven by
//! egui_kittest on whatever wgpu adapter this machine has, orbiting the camera a little every
//! frame so the viewport renders each time.
//!
//! A frame is timed from the start of the UI pass to the end of the GPU work it submitted:
//! `Harness::step` (input, layout) then `Harness::render`, which runs the viewport's paint
//! callback (upload and scene render), tessellates and draws the UI with egui-wgpu, and reads
//! the window image back (kittest has no window to present to: the read-back, 4 bytes per
//! window pixel, stands in for the present), then a blocking `device.poll`.
//!
//! `cargo run --release -p thicket --example editor_frames -- [FRAMES] [WIDTHxHEIGHT] [PROJECT…]`
//! (defaults: 10 frames, 1280x800, every project in `projects/`) prints per project the median
//! and fastest frame, the median viewport render time the viewport itself measured, the
//! viewport's size and the adapter.

use std::path::{Path, PathBuf};
use std::time::Instant;

use egui_kittest::Harness;
use egui_kittest::wgpu::{WgpuTestRenderer, create_render_state};
use thicket::editor::Editor;
use thicket::ui::EditorApp;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn parse_size(s: &str) -> anyhow::Result<egui::Vec2> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| anyhow::anyhow!("size {s:?}: expected WIDTHxHEIGHT"))?;
    Ok(egui::vec2(w.parse()?, h.parse()?))
}

fn measure(path: &Path, frames: usize, size: egui::Vec2) -> anyhow::Result<()> {
    let render_state = create_render_state(
        thicket::preview::viewport::wgpu_setup(),
        egui_wgpu::RendererOptions::PREDICTABLE,
    );
    let device = render_state.device.clone();
    let link = thicket::preview::viewport::install(&render_state);
    let doc = thicket::files::load_document(path)?;
    let mut app = EditorApp::new(Editor::new(doc, Some(path.to_path_buf())));
    app.autosave_secs = 0;
    app.native_dialogs = false;
    app.attach_gpu(link.clone());
    // This measures the GPU viewport: in Auto a software adapter would hand the view to the
    // CPU preview.
    app.view.renderer = thicket::ui::view::ViewRenderer::Gpu;
    let mut h = Harness::builder()
        .with_size(size)
        .renderer(WgpuTestRenderer::from_render_state(render_state))
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    // Windows appear on the second frame; the first render uploads the scene.
    for _ in 0..3 {
        h.step();
        h.render().map_err(|e| anyhow::anyhow!(e))?;
        device.poll(wgpu::PollType::wait_indefinitely())?;
    }
    let (mut frame_ms, mut view_ms) = (Vec::new(), Vec::new());
    let rendered_before = link.lock().frames_rendered;
    for _ in 0..frames {
        let mut cam = h.state().editor.doc().camera;
        cam.yaw_deg += 2.0;
        h.state_mut().editor.set_camera(cam);
        let t0 = Instant::now();
        h.step();
        h.render().map_err(|e| anyhow::anyhow!(e))?;
        device.poll(wgpu::PollType::wait_indefinitely())?;
        frame_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        view_ms.push(link.lock().last_render_ms);
    }
    let status = link.lock();
    if let Some(e) = &status.error {
        anyhow::bail!("{}: the viewport failed: {e}", path.display());
    }
    let rendered = status.frames_rendered - rendered_before;
    println!(
        "{:<28} frame median {:>9.1} ms, fastest {:>9.1} ms; viewport render median {:>9.1} ms; \
         {} of {frames} frames rendered; viewport {}x{}; {}",
        path.file_name().unwrap_or_default().to_string_lossy(),
        median(frame_ms.clone()),
        frame_ms.iter().copied().fold(f64::INFINITY, f64::min),
        median(view_ms),
        rendered,
        status.size_px[0],
        status.size_px[1],
        status.adapter,
    );
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let frames: usize = args.next().map_or(Ok(10), |s| s.parse())?;
    let size = parse_size(&args.next().unwrap_or_else(|| "1280x800".into()))?;
    let mut projects: Vec<PathBuf> = args.map(PathBuf::from).collect();
    if projects.is_empty() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects");
        for e in std::fs::read_dir(&dir)? {
            let p = e?.path();
            if p.to_string_lossy().ends_with(".thicket.json") {
                projects.push(p);
            }
        }
        projects.sort();
    }
    for p in &projects {
        measure(p, frames.max(1), size)?;
    }
    Ok(())
}

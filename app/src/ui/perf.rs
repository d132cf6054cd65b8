//! The performance overlay (F3): frame-time graph, the renderer's per-pass GPU times, nodes
//! per octree level, splats, KRS steps per ray, and memory per object.

use std::collections::VecDeque;

use egui_plot::{Legend, Line, Plot, PlotPoints};

use crate::editor::Editor;
use crate::files::{human_bytes, object_info, thousands};
use crate::preview::viewport::ViewportLink;

/// Frames kept in the graph.
const HISTORY: usize = 300;

/// Object names and bytes, for one document content key.
type MemoryRows = ((u64, u64), Vec<(String, u64)>);

/// The overlay's state.
#[derive(Default)]
pub struct PerfOverlay {
    /// Whether the overlay window is open.
    pub open: bool,
    /// Milliseconds the UI code took per frame (CPU).
    ui_ms: VecDeque<f64>,
    /// Milliseconds the viewport's last render took, per frame it rendered.
    render_ms: VecDeque<(u64, f64)>,
    frame: u64,
    last_rendered: u64,
    /// Memory by object for one content key (summaries visit every voxel).
    memory: Option<MemoryRows>,
}

impl PerfOverlay {
    /// Records one frame's UI time and whether the viewport rendered since the last frame.
    pub fn record(&mut self, ui_ms: f64, link: Option<&ViewportLink>) {
        self.frame += 1;
        push_bounded(&mut self.ui_ms, ui_ms);
        if let Some(link) = link {
            let s = link.lock();
            if s.frames_rendered != self.last_rendered {
                self.last_rendered = s.frames_rendered;
                push_bounded(&mut self.render_ms, (self.frame, s.last_render_ms));
            }
        }
    }

    /// Draws the overlay window when open.
    pub fn ui(
        &mut self,
        ctx: &egui::Context,
        editor: &Editor,
        link: Option<&ViewportLink>,
        cpu_preview: Option<CpuPreviewFigures<'_>>,
    ) {
        if !self.open {
            return;
        }
        let mut open = self.open;
        egui::Window::new("Performance")
            .open(&mut open)
            .default_width(420.0)
            .default_pos(egui::pos2(300.0, 80.0))
            .show(ctx, |ui| {
                if let Some(cpu) = cpu_preview {
                    cpu_preview_ui(ui, &cpu);
                }
                self.contents_ui(ui, editor, link);
            });
        self.open = open;
    }

    fn contents_ui(&mut self, ui: &mut egui::Ui, editor: &Editor, link: Option<&ViewportLink>) {
        let first = self.frame.saturating_sub(self.ui_ms.len() as u64);
        let ui_points: PlotPoints<'_> = self
            .ui_ms
            .iter()
            .enumerate()
            .map(|(i, &ms)| [(first + i as u64) as f64, ms])
            .collect();
        let render_points: PlotPoints<'_> = self
            .render_ms
            .iter()
            .filter(|(f, _)| *f >= first)
            .map(|&(f, ms)| [f as f64, ms])
            .collect();
        let last_ui = self.ui_ms.back().copied().unwrap_or(0.0);
        ui.label(format!(
            "UI {last_ui:.2} ms per frame (CPU). The viewport renders only when the camera, \
             the document or the settings change."
        ));
        Plot::new("frame_times")
            .height(140.0)
            .legend(Legend::default())
            .allow_scroll(false)
            .y_axis_label("ms")
            .include_y(0.0)
            .show(ui, |plot| {
                plot.line(Line::new("UI (CPU)", ui_points));
                plot.line(Line::new("Viewport render", render_points));
            });

        ui.separator();
        match link {
            None => {
                ui.label("No GPU renderer in this window.");
            }
            Some(link) => {
                let s = link.lock().clone();
                ui.label(format!("Adapter: {}", s.adapter));
                if s.frames_rendered == 0 {
                    // Nothing below would be measured: say so instead of showing zeros.
                    ui.weak(
                        "The GPU renderer has drawn no frame in this window yet (the CPU preview \
                         draws the view), so there are no GPU figures.",
                    );
                    return self.memory_ui(ui, editor);
                }
                ui.label(format!(
                    "Frames rendered {} / composited {}; last render {:.1} ms at {} x {} px",
                    s.frames_rendered,
                    s.frames_painted,
                    s.last_render_ms,
                    s.size_px[0],
                    s.size_px[1]
                ));
                if let Some(up) = s.last_upload {
                    let grown = if up.grown {
                        format!(
                            " (pools grown: {} copied on the GPU)",
                            human_bytes(up.copied_bytes)
                        )
                    } else {
                        String::new()
                    };
                    ui.label(format!(
                        "Last upload: {} in {} write(s){}{grown}; {} region-only uploads",
                        human_bytes(up.bytes),
                        up.writes,
                        if up.full { " (whole scene)" } else { "" },
                        s.region_uploads
                    ));
                }
                if let Some(stats) = &s.stats {
                    ui.label(format!(
                        "Splats {} ({} exact cubes)   triangles {}   splat path {:?}   queue \
                         overflow {}",
                        thousands(stats.splats),
                        thousands(stats.levels.iter().map(|l| l.cubes).sum()),
                        thousands(stats.triangles),
                        stats.atomic_path,
                        stats.queue_overflow
                    ));
                    ui.label(format!(
                        "Splat pixels {} (of them {} in exact cubes, one ray–box test each)",
                        thousands(stats.splat_pixels),
                        thousands(stats.cube_pixels)
                    ));
                    let k = &stats.krs;
                    if k.rays > 0 {
                        ui.label(format!(
                            "KRS: {} rays, {} hits, {:.1} steps per ray (most {}), {} ran out of \
                             steps; {} shadow rays, {} AO evaluations",
                            thousands(k.rays),
                            thousands(k.hits),
                            k.steps_per_ray(),
                            k.max_steps,
                            thousands(k.exhausted),
                            thousands(k.shadow_rays),
                            thousands(k.ao_evals)
                        ));
                    }
                    if stats.pass_ms.is_empty() {
                        ui.weak("GPU time per pass: this adapter has no timestamp queries.");
                    } else {
                        egui::Grid::new("pass_ms").striped(true).show(ui, |ui| {
                            ui.strong("Pass");
                            ui.strong("GPU ms");
                            ui.end_row();
                            for (name, ms) in &stats.pass_ms {
                                ui.label(*name);
                                ui.label(format!("{ms:.3}"));
                                ui.end_row();
                            }
                        });
                    }
                    ui.collapsing("Nodes per level (view)", |ui| {
                        level_grid_ui(ui, "levels", &stats.levels);
                    });
                    if !stats.shadow_levels.is_empty() {
                        ui.collapsing("Nodes per level (shadow maps, all lights)", |ui| {
                            level_grid_ui(ui, "shadow_levels", &stats.shadow_levels);
                        });
                    }
                }
            }
        }
        self.memory_ui(ui, editor);
    }

    /// Memory per object and of the undo history.
    fn memory_ui(&mut self, ui: &mut egui::Ui, editor: &Editor) {
        ui.separator();
        let key = editor.content_key();
        if self.memory.as_ref().is_none_or(|(k, _)| *k != key) {
            let rows = editor
                .doc()
                .objects
                .iter()
                .map(|o| (o.name.clone(), object_info(o).memory.total_bytes))
                .collect();
            self.memory = Some((key, rows));
        }
        ui.collapsing("Memory per object", |ui| {
            egui::Grid::new("memory").striped(true).show(ui, |ui| {
                ui.strong("Object");
                ui.strong("Memory");
                ui.end_row();
                if let Some((_, rows)) = &self.memory {
                    for (name, bytes) in rows {
                        ui.label(name);
                        ui.label(human_bytes(*bytes));
                        ui.end_row();
                    }
                }
                ui.label("Undo history");
                ui.label(human_bytes(editor.history().undo_bytes() as u64));
                ui.end_row();
            });
        });
    }
}

/// What the Performance overlay shows of the CPU preview when it draws the view.
#[derive(Debug, Clone)]
pub struct CpuPreviewFigures<'a> {
    /// Wall-clock milliseconds of the last render (on the preview's worker thread).
    pub ms: f64,
    /// Its size in pixels.
    pub size_px: [u32; 2],
    /// What its shadow pass did with the kept maps.
    pub shadows: super::view::ShadowWork,
    /// Its statistics: time per stage, nodes per level, KRS rays.
    pub stats: Option<&'a thicket_core::render::FrameStats>,
    /// Why the CPU preview draws the view.
    pub why: &'a str,
}

/// The CPU preview's figures: the last render, its time per stage, its KRS rays and its nodes
/// per level, as the GPU's are shown below.
fn cpu_preview_ui(ui: &mut egui::Ui, cpu: &CpuPreviewFigures<'_>) {
    let [w, h] = cpu.size_px;
    ui.label(format!(
        "The CPU preview draws the view ({}): last render {:.1} ms at {w} x {h} px",
        cpu.why, cpu.ms
    ));
    ui.label(shadow_work_text(&cpu.shadows));
    let Some(stats) = cpu.stats else { return };
    let t = &stats.times;
    egui::Grid::new("cpu_stage_ms")
        .striped(true)
        .show(ui, |ui| {
            ui.strong("Stage");
            ui.strong("CPU ms");
            ui.end_row();
            for (name, ms) in [
                ("Shadow maps", t.shadow_ms),
                ("Octree traversal", t.traversal_ms),
                ("Splats", t.splat_ms),
                ("Triangles", t.triangles_ms),
                ("KRS sphere tracing", t.krs_ms),
                ("Resolve", t.resolve_ms),
                ("Shade", t.shade_ms),
                ("Frame", t.total_ms),
            ] {
                ui.label(name);
                ui.label(format!("{ms:.3}"));
                ui.end_row();
            }
        });
    if stats.krs.rays > 0 {
        ui.label(krs_text(&stats.krs));
    }
    ui.collapsing("Nodes per level (CPU view)", |ui| {
        level_grid_ui(ui, "cpu_levels", &stats.levels);
    });
    ui.separator();
}

/// A CPU frame's KRS sphere tracing in one line.
fn krs_text(k: &thicket_core::render::KrsStats) -> String {
    format!(
        "KRS: {} rays, {} hits, {:.1} steps per ray (+ {} in tile cones), {} ran out of steps; \
         {} shadow rays, {} AO evaluations",
        thousands(k.rays),
        thousands(k.hits),
        k.steps as f64 / k.rays.max(1) as f64,
        thousands(k.tile_steps),
        thousands(k.exhausted),
        thousands(k.shadow_rays),
        thousands(k.ao_evals)
    )
}

fn push_bounded<T>(q: &mut VecDeque<T>, v: T) {
    if q.len() == HISTORY {
        q.pop_front();
    }
    q.push_back(v);
}

/// Per-level traversal counters (levels nothing visited are left out).
fn level_grid_ui(ui: &mut egui::Ui, id: &str, levels: &[thicket_core::render::LevelStats]) {
    egui::Grid::new(id).striped(true).show(ui, |ui| {
        for h in ["Level", "Visited", "Split", "Splatted", "Cubes", "Culled"] {
            ui.strong(h);
        }
        ui.end_row();
        for (i, l) in levels.iter().enumerate() {
            if l.visited == 0 {
                continue;
            }
            ui.label(i.to_string());
            ui.label(thousands(l.visited));
            ui.label(thousands(l.split));
            ui.label(thousands(l.splatted));
            ui.label(thousands(l.cubes));
            ui.label(thousands(l.frustum_culled));
            ui.end_row();
        }
    });
}

/// One line on what the CPU preview's shadow pass did with its kept maps.
fn shadow_work_text(s: &super::view::ShadowWork) -> String {
    let mut parts = Vec::new();
    if s.reused > 0 {
        parts.push(format!(
            "{} kept as they were (no light, caster or quality change)",
            s.reused
        ));
    }
    if s.patched > 0 {
        parts.push(format!(
            "{} redrawn only where the edit changed them ({} texels)",
            s.patched, s.texels_patched
        ));
    }
    if parts.is_empty() {
        parts.push("drawn whole".into());
    }
    format!("Shadow maps {:.1} ms: {}", s.ms, parts.join(", "))
}

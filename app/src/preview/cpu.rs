//! The CPU preview: core's reference renderer on a worker thread, one render at a time (the
//! newest document, camera and size win), at a reduced resolution while what it draws keeps
//! changing and refined to full resolution and the document's supersampling once still. It
//! keeps its frame buffers and shadow maps between renders (patched after voxel edits read
//! from the editor's change feed), and the shown image's object labels, node ids and depth for
//! picking, the selection outline, the analysis overlays and hiding overlay lines.

use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use glam::Vec3;
use thicket_core::measure::skin::Silhouette;
use thicket_core::scene::{Document, ObjectKind, OrbitCamera};

use super::analysis::{
    StretchStats, hole_legend_ui, hole_overlay, stretch_legend_ui, stretch_overlay,
};
use super::frame_depth::FrameDepth;
use super::{
    PREVIEW_STILL, PreviewSettings, RenderKey, Snapshot, preview_content_hash, render_key,
};
use crate::editor::{Editor, Redo, RegionChain, Selection, VoxelRegion};

/// Linear fraction of the view's pixels the CPU preview renders while what it draws keeps
/// changing (an orbit, a stroke, playback, a KRS parameter dragged: a quarter of the pixels
/// keeps it interactive on a laptop CPU), unless that would miss the motion budget (see
/// [`moving_scale`]); once still for [`PREVIEW_STILL`] it refines to the full resolution
/// setting.
pub const CPU_PREVIEW_SCALE: f32 = 0.5;

/// The least linear fraction a moving CPU preview frame drops to when half resolution would miss
/// its budget (a sixteenth of the pixels: a KRS forest still reads as one).
pub const CPU_PREVIEW_MIN_SCALE: f32 = 0.25;

/// The default time budget of one CPU preview frame while what it draws keeps changing: an edit
/// shows within it (issue 26: a KRS parameter edit in the next preview frame within 100 ms).
pub const PREVIEW_MOTION_BUDGET_MS: f64 = 100.0;

/// The linear scale of a CPU preview frame drawn while the view keeps changing: half the view's
/// resolution, or less when the last frame's time per sample (`last`: its milliseconds and the
/// samples it drew, pixels times supersampling) says half, at one sample per pixel, would take
/// longer than `budget_ms` at `full_px` pixels; never under
/// [`CPU_PREVIEW_MIN_SCALE`]. Time is taken as proportional to pixels (the KRS trace, shading
/// and splatting of a pixel-size cut all are); the scale is rounded down to sixteenths so that
/// noise in the measured time does not change the frame size every frame.
#[must_use]
pub fn moving_scale(last: Option<(f64, u64)>, full_px: f64, budget_ms: f64) -> f32 {
    let Some((ms, px)) = last.filter(|&(ms, px)| ms.is_finite() && ms > 0.0 && px > 0) else {
        return CPU_PREVIEW_SCALE;
    };
    if !(full_px.is_finite() && full_px > 0.0) {
        return CPU_PREVIEW_SCALE;
    }
    if !(budget_ms.is_finite() && budget_ms > 0.0) {
        return CPU_PREVIEW_MIN_SCALE;
    }
    let per_px = ms / px as f64;
    // Scale s draws s² of the pixels: s = √(budget / full-size time).
    let fit = (budget_ms / (per_px * full_px)).sqrt();
    let fit = ((fit * 16.0).floor() / 16.0) as f32;
    fit.clamp(CPU_PREVIEW_MIN_SCALE, CPU_PREVIEW_SCALE)
}

/// What decides a CPU preview image.
#[derive(Debug, Clone, PartialEq)]
struct PreviewKey {
    content: (u64, u64),
    animation: u64,
    camera: OrbitCamera,
    size_px: [u32; 2],
    /// Samples per pixel side ([`thicket_core::quality::Quality::supersample`]): the
    /// document's for a still frame, 1 while the view keeps changing.
    supersample: u32,
    holes: bool,
    stretch: bool,
}

/// A finished preview frame.
struct PreviewFrame {
    image: egui::ColorImage,
    /// Object label per pixel (1-based document index, 0 for the background).
    labels: Vec<u32>,
    /// Node id per pixel (`(level << 32) | index`, see `PixelId::node`).
    nodes: Vec<u64>,
    /// NDC depth per pixel, for hiding overlay lines ([`FrameDepth`]).
    depth: Arc<[f32]>,
    ms: f64,
    /// The render's statistics (stage times, nodes per level, KRS rays).
    stats: thicket_core::render::FrameStats,
    /// The hole / bloat overlay and its counts, when asked for and a rigged model shows.
    holes: Option<(egui::ColorImage, Silhouette)>,
    /// The stretch heat map and its statistics, when asked for and a rigged model shows.
    stretch: Option<(egui::ColorImage, StretchStats)>,
}

/// What a CPU preview render's shadow pass did with the kept maps.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ShadowWork {
    /// Shadow pass milliseconds.
    pub ms: f64,
    /// Maps kept from an earlier render unchanged (only the camera or the render size changed since).
    pub reused: u32,
    /// Maps kept and drawn again only where voxel edits changed them.
    pub patched: u32,
    /// Texels those patches drew.
    pub texels_patched: u64,
}

impl ShadowWork {
    fn of(stats: &thicket_core::render::FrameStats) -> Self {
        Self {
            ms: stats.times.shadow_ms,
            reused: stats.shadow_maps_reused,
            patched: stats.shadow_maps_patched,
            texels_patched: stats.shadow_texels_patched,
        }
    }
}

type PreviewResult = Result<PreviewFrame, String>;

/// The CPU preview: one render at a time on a worker thread; the newest key wins.
#[derive(Default)]
pub struct CpuPreview {
    shown: Option<PreviewKey>,
    /// What the preview last saw drawn (camera, content and animation keys) and when it
    /// changed (`None`: still, e.g. at start).
    motion: Option<((OrbitCamera, RenderKey), Instant)>,
    /// The weight heat map of the shown image: for which render, object and joint.
    weights: Option<((u64, u64, usize), egui::TextureHandle)>,
    texture: Option<egui::TextureHandle>,
    job: Option<(PreviewKey, mpsc::Receiver<PreviewResult>)>,
    /// The document the running job draws.
    job_doc: Option<Arc<Document>>,
    ready: Option<(PreviewKey, PreviewResult)>,
    /// The document the shown image was drawn from: overlays that follow the pose (the
    /// skeleton) are drawn from it, so they match the image while it lags the playhead.
    shown_doc: Option<Arc<Document>>,
    error: Option<String>,
    last_ms: f64,
    /// The last render's statistics, for the Performance overlay (its shadow work too).
    last_stats: Option<thicket_core::render::FrameStats>,
    renders: u64,
    /// Object labels of the shown image, row by row.
    labels: Vec<u32>,
    /// Node ids of the shown image, row by row.
    nodes: Vec<u64>,
    /// The shown image's depth.
    depth: Option<FrameDepth>,
    /// The selection outline drawn from `labels`: for which render and label, and whether it
    /// is drawn (not when it would be clutter, see [`outline_is_clutter`]).
    outline: Option<((u64, u32), egui::TextureHandle, bool)>,
    /// The hole / bloat overlay of the shown image and its counts.
    holes: Option<(egui::TextureHandle, Silhouette)>,
    /// The stretch heat map of the shown image and its statistics.
    stretch: Option<(egui::TextureHandle, StretchStats)>,
    /// The renderer (its frame buffers) and the shadow maps kept while only the camera moves
    /// (one render at a time uses them).
    renderer: Arc<Mutex<PreviewRenderer>>,
    /// Voxel edits since the last render started, for its shadow maps to redraw only where
    /// they changed (see [`shadow_change`]).
    changes: RegionChain,
}

/// What the CPU preview keeps from one render to the next.
struct PreviewRenderer {
    /// Frame buffers, queues and shadow-map targets, reused while the view size holds.
    renderer: thicket_core::render::Renderer,
    /// Shadow maps kept while only the camera moves, and patched after voxel edits.
    shadows: thicket_core::render::ShadowCache,
}

impl Default for PreviewRenderer {
    fn default() -> Self {
        Self {
            renderer: thicket_core::render::Renderer::default(),
            // The low-resolution frames of a motion use the full-resolution frames' maps (and
            // patch them after an edit) instead of drawing coarser ones in turn with them.
            shadows: thicket_core::render::ShadowCache::new().with_max_finer(
                thicket_core::render::SHADOW_CACHE_MAX_FINER / CPU_PREVIEW_MIN_SCALE,
            ),
        }
    }
}

/// Outline colour of the selection.
pub(crate) const SELECTION_COLOR: egui::Color32 = egui::Color32::from_rgb(255, 170, 60);

/// An image that is transparent except on the border pixels of the region labelled `label`
/// (pixels of the region with a 4-neighbour outside it or on the image edge), and how many
/// border pixels it has.
fn outline_image(labels: &[u32], size: [usize; 2], label: u32) -> (egui::ColorImage, usize) {
    let [w, h] = size;
    let mut image = egui::ColorImage::filled(size, egui::Color32::TRANSPARENT);
    let mut count = 0;
    let at = |x: usize, y: usize| labels.get(y * w + x).copied().unwrap_or(0);
    for y in 0..h {
        for x in 0..w {
            if at(x, y) != label {
                continue;
            }
            let edge = x == 0
                || y == 0
                || x + 1 == w
                || y + 1 == h
                || at(x - 1, y) != label
                || at(x + 1, y) != label
                || at(x, y - 1) != label
                || at(x, y + 1) != label;
            if edge {
                image.pixels[y * w + x] = SELECTION_COLOR;
                count += 1;
            }
        }
    }
    (image, count)
}

/// Above this share of the view's pixels, a selection's border is no longer an outline but a
/// texture over the object (a forest's thousands of trees, grass): the selection box is drawn
/// instead. One compact model's border is well under 1 % (a 350-px-wide blob in a 700 × 700
/// view: about 0.3 %).
const OUTLINE_CLUTTER_SHARE: f64 = 0.02;

/// Whether an outline of `border_px` pixels in an image of `size` would clutter the view.
fn outline_is_clutter(border_px: usize, size: [usize; 2]) -> bool {
    border_px as f64 > OUTLINE_CLUTTER_SHARE * (size[0] * size[1]) as f64
}

/// Pixels of an image size.
fn pixels(size: [u32; 2]) -> u64 {
    u64::from(size[0]) * u64::from(size[1])
}

/// Samples a preview render draws: its pixels times its samples per pixel.
fn samples_drawn(key: &PreviewKey) -> u64 {
    pixels(key.size_px) * u64::from(key.supersample).pow(2)
}

/// A voxel region as a change of the preview's content inside a world box: a rigid model's
/// changed voxels, through its transform (an empty box: nothing drawn changed). `None` when the
/// model is gone.
fn shadow_change(
    doc: &Document,
    animation: u64,
    r: &VoxelRegion,
) -> Option<thicket_core::render::ContentChange> {
    let (lo, hi) = if r.is_empty() {
        (Vec3::ONE, Vec3::ZERO)
    } else {
        let o = doc.objects.iter().find(|o| o.id == r.object)?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return None;
        };
        let m = o.transform.matrix() * v.object_from_voxel();
        let (a, b) = (r.lo.as_vec3(), (r.hi + 1).as_vec3());
        (0..8).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), k| {
            let p = m.transform_point3(Vec3::select(
                glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0),
                b,
                a,
            ));
            (lo.min(p), hi.max(p))
        })
    };
    Some(thicket_core::render::ContentChange {
        from: preview_content_hash((r.from, animation)),
        to: preview_content_hash((r.to, animation)),
        lo,
        hi,
    })
}

/// What the CPU preview shows, for the view's corner text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CpuStatus<'a> {
    /// The last render failed.
    Error(&'a str),
    /// An image of this size and samples per pixel side; `refining`: a render with more
    /// samples is running.
    Shown {
        /// Pixels drawn.
        size_px: [u32; 2],
        /// Samples per pixel side.
        supersample: u32,
        /// More samples are on their way.
        refining: bool,
    },
    /// Nothing shown yet.
    Rendering,
}

impl CpuPreview {
    /// What it shows.
    #[must_use]
    pub fn status(&self) -> CpuStatus<'_> {
        match (&self.error, &self.shown) {
            (Some(e), _) => CpuStatus::Error(e),
            (None, Some(k)) => CpuStatus::Shown {
                size_px: k.size_px,
                supersample: k.supersample,
                refining: self
                    .job
                    .as_ref()
                    .is_some_and(|(j, _)| samples_drawn(j) > samples_drawn(k)),
            },
            (None, None) => CpuStatus::Rendering,
        }
    }

    /// Shows the CPU preview in `rect` (starting a render when the document, camera or size
    /// changed) with the analysis overlays `settings` ask for; returns whether the selection's
    /// outline was drawn from its pixels.
    pub fn show(
        &mut self,
        ui: &egui::Ui,
        rect: egui::Rect,
        editor: &Editor,
        snapshot: &mut Snapshot,
        settings: &PreviewSettings,
    ) -> bool {
        let ppp = ui.ctx().pixels_per_point();
        // Voxel edits since the last frame, for the shadow maps to patch; one that cannot be
        // described breaks the chain (the maps are drawn whole).
        let doc = editor.doc();
        self.changes
            .read_until_taken(editor.changes(), |c| Redo::for_shadow_maps(doc, c));
        // Low resolution while what is drawn keeps changing (an orbit, a stroke, playback); the
        // full resolution setting once it has been still for a moment. A drag that changes
        // nothing drawn (placing a box, a selection) keeps the full image.
        let drawn = (editor.doc().camera, render_key(editor));
        let now = Instant::now();
        let moved_at = match self.motion {
            Some((d, t)) if d == drawn => Some(t),
            Some(_) => Some(now),
            None if self
                .shown
                .as_ref()
                .is_some_and(|k| k.camera != drawn.0 || (k.content, k.animation) != drawn.1) =>
            {
                Some(now)
            }
            None => None,
        };
        self.motion = moved_at.map(|t| (drawn, t));
        let moving = moved_at.is_some_and(|t| now - t < PREVIEW_STILL);
        if moving {
            ui.ctx().request_repaint_after(PREVIEW_STILL);
        }
        let full = rect.size() * ppp * settings.render_scale;
        let scale = match (moving, settings.motion_budget_ms) {
            (false, _) => 1.0,
            (true, None) => CPU_PREVIEW_SCALE,
            (true, Some(budget)) => {
                // Time per sample of the last frame: a still frame may have drawn several
                // samples per pixel; a moving one draws one.
                let last = self
                    .shown
                    .as_ref()
                    .filter(|_| self.renders > 0)
                    .map(|k| (self.last_ms, samples_drawn(k)));
                moving_scale(last, f64::from(full.x) * f64::from(full.y), budget)
            }
        };
        let size = full * scale;
        let size_px = [
            (size.x.round() as u32).clamp(1, 4096),
            (size.y.round() as u32).clamp(1, 4096),
        ];
        let mut key = PreviewKey {
            content: editor.content_key(),
            animation: editor.animation_key(),
            camera: editor.doc().camera,
            size_px,
            supersample: 1,
            holes: settings.holes,
            stretch: settings.stretch,
        };
        // A still view with supersampling refines in two steps: the full resolution at one
        // sample per pixel first (quick and sharp), then all the samples (Render → Final draws
        // 9 per pixel), so the full-size image never waits for them.
        let samples = thicket_core::render::supersample_factor(
            size_px[0],
            size_px[1],
            editor.doc().quality.supersample,
        );
        if !moving
            && samples > 1
            && self.shown.as_ref().is_some_and(|s| {
                PreviewKey {
                    supersample: 1,
                    ..s.clone()
                } == key
            })
        {
            key.supersample = samples;
        }
        if let Some((k, rx)) = &self.job {
            match rx.try_recv() {
                Ok(result) => {
                    self.ready = Some((k.clone(), result));
                    self.job = None;
                }
                Err(mpsc::TryRecvError::Empty) => {
                    ui.ctx().request_repaint_after(Duration::from_millis(30));
                }
                Err(mpsc::TryRecvError::Disconnected) => {
                    self.ready = Some((k.clone(), Err("the preview worker stopped".into())));
                    self.job = None;
                }
            }
        }
        if let Some((k, result)) = self.ready.take() {
            self.shown_doc = self.job_doc.take();
            match result {
                Ok(PreviewFrame {
                    image,
                    labels,
                    nodes,
                    depth,
                    ms,
                    stats,
                    holes,
                    stretch,
                }) => {
                    self.last_stats = Some(stats);
                    self.depth = Some(FrameDepth::new(
                        k.content,
                        k.animation,
                        k.camera,
                        [image.size[0] as u32, image.size[1] as u32],
                        depth,
                    ));
                    self.labels = labels;
                    self.nodes = nodes;
                    self.stretch = stretch.map(|(overlay, stats)| {
                        let t = ui.ctx().load_texture(
                            "stretch_overlay",
                            overlay,
                            egui::TextureOptions::NEAREST,
                        );
                        (t, stats)
                    });
                    self.holes = holes.map(|(overlay, counts)| {
                        let t = ui.ctx().load_texture(
                            "hole_overlay",
                            overlay,
                            egui::TextureOptions::NEAREST,
                        );
                        (t, counts)
                    });
                    match &mut self.texture {
                        Some(t) => t.set(image, egui::TextureOptions::LINEAR),
                        None => {
                            self.texture = Some(ui.ctx().load_texture(
                                "cpu_preview",
                                image,
                                egui::TextureOptions::LINEAR,
                            ));
                        }
                    }
                    self.last_ms = ms;
                    self.renders += 1;
                    self.error = None;
                }
                Err(e) => {
                    log::warn!("CPU preview: {e}");
                    self.depth = None;
                    self.error = Some(e);
                }
            }
            self.shown = Some(k);
        }
        // One render at a time; when it lands, the newest key starts the next.
        if self.job.is_none() && self.shown.as_ref() != Some(&key) {
            let doc = snapshot.of(editor);
            let job_doc = Arc::clone(&doc);
            // The snapshot's key: it changes whenever the content or the playhead does.
            let content_key = preview_content_hash(render_key(editor));
            let changes: Vec<_> = self
                .changes
                .take()
                .iter()
                .map_while(|r| shadow_change(&doc, editor.animation_key(), r))
                .collect();
            let kept = Arc::clone(&self.renderer);
            let (tx, rx) = mpsc::channel();
            let request = thicket_core::render::View {
                width: size_px[0],
                height: size_px[1],
                camera: Some(key.camera),
                quality: thicket_core::quality::Quality {
                    supersample: key.supersample,
                    ..doc.quality.clone()
                },
            };
            let holes = key.holes;
            let stretch = key.stretch;
            std::thread::spawn(move || {
                let t0 = Instant::now();
                // A panicked render left nothing half-written that matters: a map is stored
                // whole or not at all.
                let mut kept = kept
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                let PreviewRenderer { renderer, shadows } = &mut *kept;
                for c in changes {
                    shadows.note_change(c);
                }
                let result = renderer
                    .render_document_cached(&doc, &request, shadows, content_key)
                    .map(|frame| {
                        let (image, buffers) = (frame.image, frame.buffers);
                        let stats = frame.stats.clone();
                        let size = [image.width as usize, image.height as usize];
                        let color = egui::ColorImage::from_rgba_unmultiplied(size, &image.pixels);
                        let labels = buffers.ids.iter().map(|id| id.object).collect();
                        let nodes = buffers.ids.iter().map(|id| id.node).collect();
                        let depth = buffers.depth.as_slice().into();
                        let stretch = if stretch {
                            stretch_overlay(&doc, &request, &buffers.ids, size)
                        } else {
                            None
                        };
                        let ms = t0.elapsed().as_secs_f64() * 1e3;
                        PreviewFrame {
                            image: color,
                            labels,
                            nodes,
                            depth,
                            ms,
                            stats,
                            holes: if holes {
                                hole_overlay(&doc, &request)
                            } else {
                                None
                            },
                            stretch,
                        }
                    })
                    .map_err(|e| e.to_string());
                // The view may be gone (window closed): nothing to hand back then.
                let _ = tx.send(result);
            });
            self.job = Some((key, rx));
            self.job_doc = Some(job_doc);
            ui.ctx().request_repaint_after(Duration::from_millis(30));
        }
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        if let Some(t) = &self.texture {
            ui.painter_at(rect)
                .image(t.id(), rect, uv, egui::Color32::WHITE);
        }
        // The outline first: the diagnostic overlays are drawn above it (holes at the
        // silhouette would otherwise hide under the orange line).
        let outlined = match self.selection_outline(ui, editor) {
            Some(t) => {
                ui.painter_at(rect).image(t, rect, uv, egui::Color32::WHITE);
                true
            }
            None => false,
        };
        if settings.holes
            && let Some((t, _)) = &self.holes
        {
            ui.painter_at(rect)
                .image(t.id(), rect, uv, egui::Color32::WHITE);
            hole_legend_ui(ui, rect);
        }
        if settings.stretch
            && let Some((t, stats)) = &self.stretch
        {
            ui.painter_at(rect)
                .image(t.id(), rect, uv, egui::Color32::WHITE);
            stretch_legend_ui(ui, rect, *stats);
        }
        if let Some(t) = self.weight_heat_map(ui, editor, settings) {
            ui.painter_at(rect).image(t, rect, uv, egui::Color32::WHITE);
        }
        outlined
    }

    /// The selected joint's weight heat map over the shown preview, when asked for and the
    /// preview shows the current document (its labels are document indices).
    fn weight_heat_map(
        &mut self,
        ui: &egui::Ui,
        editor: &Editor,
        settings: &PreviewSettings,
    ) -> Option<egui::TextureId> {
        let (id, joint) = settings.weights?;
        let shown = self.shown.as_ref()?;
        if shown.content != editor.content_key() || self.error.is_some() {
            return None;
        }
        let key = (self.renders, id, joint);
        if self.weights.as_ref().is_none_or(|(k, _)| *k != key) {
            let size = [shown.size_px[0] as usize, shown.size_px[1] as usize];
            let image = super::analysis::weight_overlay(
                editor.doc(),
                &self.labels,
                &self.nodes,
                size,
                id,
                joint,
            )?;
            let t = ui
                .ctx()
                .load_texture("weight_overlay", image, egui::TextureOptions::NEAREST);
            self.weights = Some((key, t));
        }
        self.weights.as_ref().map(|(_, t)| t.id())
    }

    /// The selection's outline from the shown preview's object labels, when the preview shows
    /// the current document (labels are document indices).
    fn selection_outline(&mut self, ui: &egui::Ui, editor: &Editor) -> Option<egui::TextureId> {
        let shown = self.shown.as_ref()?;
        if shown.content != editor.content_key() || self.error.is_some() {
            return None;
        }
        let Some(Selection::Object(id)) = editor.selection else {
            return None;
        };
        let label = editor.doc().objects.iter().position(|o| o.id == id)? as u32 + 1;
        let size = [shown.size_px[0] as usize, shown.size_px[1] as usize];
        if self.labels.len() != size[0] * size[1] {
            return None;
        }
        let key = (self.renders, label);
        if self.outline.as_ref().is_none_or(|(k, _, _)| *k != key) {
            let (image, border_px) = outline_image(&self.labels, size, label);
            let shown = !outline_is_clutter(border_px, size);
            match &mut self.outline {
                Some((k, t, s)) => {
                    t.set(image, egui::TextureOptions::NEAREST);
                    *k = key;
                    *s = shown;
                }
                None => {
                    let t = ui.ctx().load_texture(
                        "selection_outline",
                        image,
                        egui::TextureOptions::NEAREST,
                    );
                    self.outline = Some((key, t, shown));
                }
            }
        }
        self.outline
            .as_ref()
            .filter(|(_, _, shown)| *shown)
            .map(|(_, t, _)| t.id())
    }

    /// The rigged voxel model and the node id the shown CPU preview draws at `pos` (a point in
    /// `rect`, the view), when the preview shows the current document's objects.
    #[must_use]
    pub fn hit(&self, editor: &Editor, rect: egui::Rect, pos: egui::Pos2) -> Option<(u64, u64)> {
        let shown = self.shown.as_ref()?;
        // Labels are document indices: only valid while the object list is the same one.
        if shown.content.0 != editor.content_key().0 || !rect.contains(pos) {
            return None;
        }
        let [w, h] = shown.size_px;
        let x = (((pos.x - rect.left()) / rect.width()) * w as f32) as usize;
        let y = (((pos.y - rect.top()) / rect.height()) * h as f32) as usize;
        let i = y.min(h as usize - 1) * w as usize + x.min(w as usize - 1);
        let label = *self.labels.get(i)?;
        let node = *self.nodes.get(i)?;
        let o = editor.doc().objects.get((label as usize).checked_sub(1)?)?;
        match &o.kind {
            ObjectKind::Voxels(v) if v.rig.is_some() => Some((o.id, node)),
            _ => None,
        }
    }

    /// The document the shown image was drawn from: the skeleton overlay is
    /// drawn posed as it, so bones stay inside the limbs of the image while the preview lags
    /// playback (or a joint drag, or the object's keyed motion). `None` while the preview
    /// shows an error; the skeleton then shows the editor's pose.
    #[must_use]
    pub fn shown_document(&self) -> Option<Arc<Document>> {
        (self.error.is_none() && self.shown.is_some())
            .then(|| self.shown_doc.clone())
            .flatten()
    }

    /// Waits for the CPU preview render in flight, if any (tests; the UI polls instead). Its
    /// image is shown from the next frame, and the camera counts as still from now on, so the
    /// next frames refine it to full resolution whatever the test's timing.
    pub fn wait(&mut self) {
        self.motion = None;
        if let Some((key, rx)) = self.job.take() {
            let result = rx
                .recv()
                .unwrap_or_else(|_| Err("the preview worker stopped".to_owned()));
            self.ready = Some((key, result));
        }
    }

    /// CPU preview renders finished so far (tests and the perf overlay).
    #[must_use]
    pub fn renders(&self) -> u64 {
        self.renders
    }

    /// Stretch-factor statistics of the shown CPU preview (with [`PreviewSettings::stretch`]).
    #[must_use]
    pub fn stretch_stats(&self) -> Option<StretchStats> {
        self.stretch.as_ref().map(|(_, s)| *s)
    }

    /// Hole and bloat counts of the shown CPU preview (with [`PreviewSettings::holes`]).
    #[must_use]
    pub fn hole_counts(&self) -> Option<Silhouette> {
        self.holes.as_ref().map(|(_, c)| *c)
    }

    /// Wall-clock milliseconds of the last CPU preview render, and its size in pixels.
    #[must_use]
    pub fn stats(&self) -> Option<(f64, [u32; 2])> {
        let size = self.shown.as_ref()?.size_px;
        (self.renders > 0).then_some((self.last_ms, size))
    }

    /// Samples per pixel side of the shown CPU preview image (1 while moving, then the
    /// document's supersampling once refined).
    #[must_use]
    pub fn supersample(&self) -> Option<u32> {
        self.shown.as_ref().map(|k| k.supersample)
    }

    /// The last CPU preview render's statistics: time per stage, nodes per level, KRS rays.
    #[must_use]
    pub fn frame_stats(&self) -> Option<&thicket_core::render::FrameStats> {
        self.last_stats.as_ref()
    }

    /// What the last CPU preview render's shadow pass did with the kept maps.
    #[must_use]
    pub fn shadows(&self) -> Option<ShadowWork> {
        self.last_stats.as_ref().map(ShadowWork::of)
    }

    /// The size of the CPU preview render in flight, if any (tests: low resolution while the
    /// camera moves).
    #[must_use]
    pub fn in_flight(&self) -> Option<[u32; 2]> {
        self.job.as_ref().map(|(k, _)| k.size_px)
    }

    /// The shown image's depth (drawn from its own camera, which lags an orbit).
    #[must_use]
    pub fn shown_depth(&self) -> Option<FrameDepth> {
        self.depth.clone()
    }

    /// Drops the frame buffers and shadow maps (up to 64 MiB each at the final preset's 4096²)
    /// while the GPU draws; a render still running holds the lock and they go next time.
    pub fn release_buffers(&self) {
        if let Ok(mut kept) = self.renderer.try_lock() {
            *kept = PreviewRenderer::default();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_moving_preview_drops_below_half_only_when_half_would_miss_the_budget() {
        let full = 600.0 * 708.0;
        // The tree at 600×708 in a debug build: ~2 µs per pixel, 850 ms whole, 212 ms at half.
        let slow = Some((850.0, 600 * 708));
        let s = moving_scale(slow, full, 100.0);
        assert!((CPU_PREVIEW_MIN_SCALE..0.5).contains(&s), "{s}");
        // The scale found meets the budget by the same estimate, and a sixteenth more would not.
        let at = |s: f64| 850.0 * s * s;
        assert!(
            at(f64::from(s)) <= 100.0 && at(f64::from(s) + 1.0 / 16.0) > 100.0,
            "{s}"
        );
        // A cheap frame keeps half (not more: the still frame refines anyway).
        assert_eq!(moving_scale(Some((20.0, 600 * 708)), full, 100.0), 0.5);
        // Measured on a quarter-size frame, the same per-pixel cost gives the same answer.
        assert_eq!(
            moving_scale(Some((850.0 / 16.0, 150 * 177)), full, 100.0),
            s
        );
        // Far over budget: never under the floor.
        assert_eq!(
            moving_scale(Some((1e6, 1)), full, 100.0),
            CPU_PREVIEW_MIN_SCALE
        );
    }

    #[test]
    fn a_moving_preview_without_a_usable_measurement_draws_half() {
        let full = 640.0 * 480.0;
        for last in [
            None,
            Some((0.0, 1000)),
            Some((f64::NAN, 1000)),
            Some((f64::INFINITY, 1000)),
            Some((-5.0, 1000)),
            Some((50.0, 0)),
        ] {
            assert_eq!(moving_scale(last, full, 100.0), 0.5, "{last:?}");
        }
        for full in [0.0, -1.0, f64::NAN] {
            assert_eq!(moving_scale(Some((50.0, 1000)), full, 100.0), 0.5, "{full}");
        }
        // A budget of nothing (or not a number) asks for the least.
        for budget in [0.0, -1.0, f64::NAN] {
            assert_eq!(
                moving_scale(Some((50.0, 1000)), full, budget),
                CPU_PREVIEW_MIN_SCALE
            );
        }
    }

    #[test]
    fn the_outline_is_the_border_of_the_selected_label_only() {
        // A 3x3 block of label 2 inside a 5x5 image of label 1 (another object).
        let mut labels = vec![1u32; 25];
        for y in 1..4 {
            for x in 1..4 {
                labels[y * 5 + x] = 2;
            }
        }
        let (image, border_px) = outline_image(&labels, [5, 5], 2);
        assert_eq!(border_px, 8);
        let lit: Vec<(usize, usize)> = (0..25)
            .filter(|&i| image.pixels[i] == SELECTION_COLOR)
            .map(|i| (i % 5, i / 5))
            .collect();
        assert_eq!(
            lit.len(),
            8,
            "the ring of the block, not its centre: {lit:?}"
        );
        assert!(!lit.contains(&(2, 2)));
        assert!(lit.iter().all(|&(x, y)| labels[y * 5 + x] == 2));
    }

    #[test]
    fn a_forest_of_small_parts_is_boxed_not_outlined() {
        use super::outline_is_clutter;
        let size = [200, 200];
        // One 100 x 100 block: a compact model (396 border pixels, 1 % of the view).
        let mut one = vec![0u32; 200 * 200];
        for y in 50..150 {
            for x in 50..150 {
                one[y * 200 + x] = 1;
            }
        }
        let (_, border) = outline_image(&one, size, 1);
        assert_eq!(border, 396);
        assert!(!outline_is_clutter(border, size));
        // The same area as 400 separate 5 x 5 "trees" on a 10-px grid: 16 border pixels each.
        let mut forest = vec![0u32; 200 * 200];
        for ty in 0..20 {
            for tx in 0..20 {
                for y in 0..5 {
                    for x in 0..5 {
                        forest[(ty * 10 + y) * 200 + tx * 10 + x] = 1;
                    }
                }
            }
        }
        let (_, border) = outline_image(&forest, size, 1);
        assert_eq!(border, 400 * 16);
        assert!(outline_is_clutter(border, size));
    }
}

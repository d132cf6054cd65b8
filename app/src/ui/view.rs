//! The central 3D view: the GPU image through [`crate::viewport`], camera navigation (orbit,
//! pan, zoom with mouse and trackpad; axis views; frame selection), overlays (ground grid,
//! world axes, the selected object's outline box, the brush preview, skeletons and the pose
//! gizmo, KRS mirror planes) and sculpt strokes.
//!
//! The GPU renderer draws rigid and skinned voxels, meshes and KRS objects. Core's CPU
//! reference renderer draws the view on a worker thread (the CPU preview) for a rigged model
//! while the hole / bloat overlay, the stretch heat map or stretch painting is on (they read
//! that image), when the viewport's GPU adapter is a software rasteriser (lavapipe: slower than
//! the CPU preview), and when no GPU is attached (the plain UI tests). Render -> Viewport renderer
//! chooses.

use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use glam::{Vec2, Vec3};
use thicket_core::scene::{Document, Object, ObjectKind, OrbitCamera, transform_bounds};

use super::krs_panel::{KrsPanel, paint_mirrors, paint_route, paint_zones, pick_mirror};
use super::overlay_lines::{OverlayDepth, grid};
pub use super::overlay_lines::{behind_voxels, unhidden_parts, unhidden_parts_by};
use super::pose::PoseTool;
pub use super::projector::{AxisView, Projector};
use super::sculpt::SculptTool;
use super::voxel_tools::{ToolKind, paint_volume};
use crate::editor::{
    Editor, Redo, RegionChain, Selection, SurfacePick, VoxelPick, VoxelRegion, ray_through,
};
use crate::viewport::{FrameDepth, FrameKey, ViewportCallback, ViewportLink, paint_callback};

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

/// How long what the CPU preview draws must stay the same before it refines to full
/// resolution.
pub const PREVIEW_STILL: Duration = Duration::from_millis(150);

/// Which renderer draws the view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewRenderer {
    /// The GPU when one is attached and is not a software rasteriser, except while a rigged
    /// model shows the hole / bloat overlay, the stretch heat map or is stretch-painted;
    /// otherwise the CPU preview.
    Auto,
    /// Always the GPU renderer when one is attached (no hole / bloat overlay, heat map or
    /// stretch painting).
    Gpu,
    /// Always core's CPU reference renderer on a worker thread.
    Cpu,
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

/// Silhouette counts of the rigged models in the view against their skinned reference
/// surfaces ([`thicket_core::measure::skin::reference_surface`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HoleCounts {
    /// Pixels inside the skinned meshes' silhouettes.
    pub mesh_pixels: u64,
    /// Mesh pixels no voxel covers.
    pub holes: u64,
    /// Voxel pixels outside the meshes.
    pub bloat: u64,
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
    holes: Option<(egui::ColorImage, HoleCounts)>,
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

/// Stretch factors of the rigged-model pixels of the shown CPU preview (the heat map's).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StretchStats {
    /// Pixels of rigged models.
    pub pixels: u64,
    /// Smallest factor seen.
    pub min: f32,
    /// Mean factor over the pixels.
    pub mean: f32,
    /// Largest factor seen.
    pub max: f32,
}

/// Factor at the blue end of the heat map's scale.
pub const STRETCH_SCALE_MIN: f32 = 0.5;
/// Factor at the red end of the heat map's scale.
pub const STRETCH_SCALE_MAX: f32 = 2.5;

type PreviewResult = Result<PreviewFrame, String>;

/// The CPU preview: one render at a time on a worker thread; the newest key wins.
#[derive(Default)]
struct CpuPreview {
    shown: Option<PreviewKey>,
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
    holes: Option<(egui::TextureHandle, HoleCounts)>,
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
const SELECTION_COLOR: egui::Color32 = egui::Color32::from_rgb(255, 170, 60);

/// Hole overlay colours, chosen against the selection outline's orange and against models'
/// own colours (skin tones, blue textures): magenta where the skinned mesh shows and no voxel
/// does, yellow where voxels cover more.
const HOLE_COLOR: egui::Color32 = egui::Color32::from_rgb(255, 0, 255);
const BLOAT_COLOR: egui::Color32 = egui::Color32::from_rgb(255, 230, 0);

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

/// Minimum and maximum corners.
type Aabb = (Vec3, Vec3);

/// What a renderer draws: the document's content key and its animation key.
type RenderKey = ((u64, u64), u64);

/// What the renderers draw of the editor's document: its content and its playheads (the camera
/// is not in it: orbiting draws the same document).
fn render_key(editor: &Editor) -> RenderKey {
    (editor.content_key(), editor.animation_key())
}

/// Samples per pixel side the GPU view draws with the document's `supersample` when what it
/// draws last changed at `moved_at`: one while that is under [`PREVIEW_STILL`] ago (a moving
/// frame, as the CPU preview's), else the document's.
fn gpu_view_supersample(moved_at: Option<Instant>, now: Instant, supersample: u32) -> u32 {
    if moved_at.is_some_and(|t| now.saturating_duration_since(t) < PREVIEW_STILL) {
        1
    } else {
        supersample
    }
}

/// The content key the CPU preview gives its shadow cache for a render key.
fn preview_content_hash(key: RenderKey) -> u64 {
    let mut h = std::hash::DefaultHasher::new();
    key.hash(&mut h);
    h.finish()
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

/// Degrees of orbit per dragged point.
const ORBIT_DEG_PER_POINT: f32 = 0.4;

/// The view's state.
pub struct View {
    /// Draw the ground grid and world axes.
    pub show_grid: bool,
    /// Draw every object's bounding box (the selection's is always drawn).
    pub show_bounds: bool,
    /// Fraction of the view's pixels the renderer draws (lower is faster on slow adapters).
    pub render_scale: f32,
    /// The CPU preview's time budget per frame while what it draws keeps changing: it draws at
    /// half resolution, or lower down to a quarter when its last frame says half would take
    /// longer ([`moving_scale`]). `None`: always half.
    pub motion_budget_ms: Option<f64>,
    /// Which renderer draws the view.
    pub renderer: ViewRenderer,
    /// Overlay the CPU preview with the hole (magenta) and bloat (yellow) pixels of rigged models
    /// against their skinned source meshes.
    pub show_holes: bool,
    /// Overlay the CPU preview with a heat map of each rigged-model pixel's stretch factor
    /// (its splat's size against the unstretched voxel's), with a colour legend.
    pub show_stretch: bool,
    /// The sculpt tool paints stretch overrides this frame (it aims with the CPU preview).
    stretch_painting: bool,
    /// Show (object, joint)'s weights as a heat map over the CPU preview (the Rig section's
    /// Show weights, and while weights are painted); set every frame.
    pub show_weights: Option<(u64, usize)>,
    /// The weight heat map of the shown preview: for which render, object and joint.
    weights: Option<((u64, u64, usize), egui::TextureHandle)>,
    gpu: Option<ViewportLink>,
    /// The document as the renderer sees it, for one content and animation key (cloned when
    /// either changes).
    snapshot: Option<(RenderKey, Arc<Document>)>,
    cpu: CpuPreview,
    /// What the CPU preview last saw drawn (camera, content and animation keys) and when it
    /// changed (`None`: still, e.g. at start).
    preview_motion: Option<((OrbitCamera, RenderKey), Instant)>,
    /// What the GPU view last saw drawn (camera, content and animation keys) and when it
    /// changed: while that is under [`PREVIEW_STILL`] ago it draws one sample per pixel.
    gpu_motion: Option<((OrbitCamera, RenderKey), Option<Instant>)>,
    /// Voxel edits since the GPU may last have uploaded (see [`ViewportCallback::regions`]).
    regions: RegionChain,
    /// Object-space bounds by object id, for one content key (bounds visit every voxel).
    bounds_cache: (RenderKey, HashMap<u64, Option<Aabb>>),
    /// The empty cell in front of the voxel face under the pointer (model, voxel
    /// coordinates): where Ctrl+V starts a paste.
    pub paste_target: Option<(u64, glam::IVec3)>,
    /// The last view rectangle (for tests that aim at it).
    pub last_rect: egui::Rect,
    /// Physical pixels per point when the view was last drawn.
    last_pixels_per_point: f32,
    /// What the last click in the view hit (drawn as a dot and its normal until the next
    /// click), with the document generation it was made in.
    pub last_click: Option<(u64, SurfacePick)>,
    /// An axis view turned the camera orthographic (Blender's auto perspective): orbiting
    /// away from it turns perspective back on.
    auto_ortho: bool,
    /// The ground grid's, world axes' and volume box's lines split where voxels hide them.
    overlay_depth: OverlayDepth,
    /// The size in pixels the GPU view last asked for (a depth read back at another size is
    /// of an older frame: the view was resized).
    gpu_size_px: [u32; 2],
}

impl Default for View {
    fn default() -> Self {
        Self {
            show_grid: true,
            show_bounds: false,
            render_scale: 1.0,
            motion_budget_ms: Some(PREVIEW_MOTION_BUDGET_MS),
            renderer: ViewRenderer::Auto,
            show_holes: false,
            stretch_painting: false,
            show_weights: None,
            weights: None,
            show_stretch: false,
            gpu: None,
            snapshot: None,
            cpu: CpuPreview::default(),
            preview_motion: None,
            gpu_motion: None,
            regions: RegionChain::default(),
            bounds_cache: (((u64::MAX, u64::MAX), u64::MAX), HashMap::new()),
            auto_ortho: false,
            last_rect: egui::Rect::NOTHING,
            paste_target: None,
            last_pixels_per_point: 1.0,
            last_click: None,
            overlay_depth: OverlayDepth::default(),
            gpu_size_px: [0, 0],
        }
    }
}

impl View {
    /// Connects the GPU viewport.
    pub fn attach_gpu(&mut self, link: ViewportLink) {
        self.gpu = Some(link);
    }

    /// The GPU viewport's link, when one is attached.
    #[must_use]
    pub fn gpu(&self) -> Option<&ViewportLink> {
        self.gpu.as_ref()
    }

    /// Entries for the View menu.
    pub fn menu_ui(&mut self, ui: &mut egui::Ui, editor: &mut Editor) {
        ui.checkbox(&mut self.show_grid, "Ground grid")
            .on_hover_text("Draw the ground grid and the world axes (hidden behind voxels)");
        ui.checkbox(&mut self.show_bounds, "All bounding boxes")
            .on_hover_text("Draw every object's bounding box (the selection's is always drawn)");
        ui.checkbox(&mut self.show_holes, "Hole / bloat overlay")
            .on_hover_text(
                "CPU preview of rigged models: magenta where the skinned reference surface shows but no voxel does (holes), yellow where voxels cover more (bloat); the reference is the imported source mesh, or for a model rigged here its own skinned surface (what Export glTF writes); drawn above the selection outline, with a legend",
            );
        ui.checkbox(&mut self.show_stretch, "Stretch heat map")
            .on_hover_text(
                "CPU preview of rigged models: colour each pixel by its voxel's stretch factor this frame (blue 0.5, green 1, red 2.5 and more), with a legend",
            );
        ui.separator();
        let mut ortho = editor.doc().camera.orthographic;
        if ui
            .add(egui::Checkbox::new(&mut ortho, "Orthographic (5)"))
            .on_hover_text(format!(
                "Parallel projection: voxels line up on screen, sizes do not shrink with \
                     distance (key {} toggles)",
                super::keys::shortcut(super::keys::Act::ToggleOrtho)
            ))
            .changed()
        {
            self.set_orthographic(editor, ortho);
        }
        ui.label("Axis views (orthographic)");
        for (view, label) in AxisView::ALL {
            let key = super::keys::shortcut(super::keys::Act::View(view));
            if ui
                .add(egui::Button::new(label).shortcut_text(key))
                .on_hover_text(format!(
                    "Look at the scene from the {} in an orthographic view (orbiting returns to perspective)",
                    label.to_lowercase()
                ))
                .clicked()
            {
                self.axis_view(editor, view);
            }
        }
    }

    /// Switches between perspective and orthographic projection, keeping the framing (and
    /// fitting the clip planes to the scene, which differ between the two).
    pub fn set_orthographic(&mut self, editor: &mut Editor, orthographic: bool) {
        let mut camera = editor.doc().camera;
        camera.orthographic = orthographic;
        self.auto_ortho = false;
        self.fit_clip(editor, &mut camera);
        editor.set_camera(camera);
    }

    /// Looks along an axis in an orthographic view (remembered, so that orbiting away from it
    /// returns to perspective, as Blender's auto perspective does).
    pub fn axis_view(&mut self, editor: &mut Editor, view: AxisView) {
        let mut camera = editor.doc().camera;
        (camera.yaw_deg, camera.pitch_deg) = view.angles();
        if !camera.orthographic {
            camera.orthographic = true;
            self.auto_ortho = true;
        }
        self.fit_clip(editor, &mut camera);
        editor.set_camera(camera);
    }

    /// Empties the per-object bounds cache when the content or a playhead changed (posed
    /// bounds follow the playhead).
    fn refresh_bounds_cache(&mut self, editor: &Editor) {
        let key = render_key(editor);
        if self.bounds_cache.0 != key {
            self.bounds_cache = (key, HashMap::new());
        }
    }

    /// An object's local bounds, from the cache ([`View::refresh_bounds_cache`] first).
    fn cached_bounds(&mut self, o: &Object) -> Option<Aabb> {
        *self
            .bounds_cache
            .1
            .entry(o.id)
            .or_insert_with(|| local_bounds(o))
    }

    /// World bounds of every visible object (from the per-object cache).
    fn scene_bounds(&mut self, editor: &Editor) -> Option<Aabb> {
        self.refresh_bounds_cache(editor);
        editor
            .doc()
            .objects
            .iter()
            .filter(|o| o.visible)
            .filter_map(|o| {
                let (lo, hi) = self.cached_bounds(o)?;
                Some(transform_bounds(&o.transform.matrix(), lo, hi))
            })
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
            .filter(|(lo, hi)| lo.is_finite() && hi.is_finite())
    }

    /// Near and far planes that follow the camera: around the scene's bounds as seen from the
    /// eye (`OrbitCamera::fit_clip`), so a close camera draws the wall in front of it and an
    /// orthographic view shows the whole scene along its axis. An empty scene keeps a range
    /// around the target.
    fn fit_clip(&mut self, editor: &Editor, camera: &mut OrbitCamera) {
        match self.scene_bounds(editor) {
            Some((lo, hi)) => camera.fit_clip(lo, hi),
            None => {
                camera.far = camera.far.max(camera.distance * 4.0);
                camera.near = if camera.orthographic {
                    -camera.distance * 4.0
                } else {
                    camera.near.min(camera.distance * 0.5).max(1e-4)
                };
            }
        }
    }

    /// Entries for the Render menu.
    pub fn render_menu_ui(&mut self, ui: &mut egui::Ui) {
        ui.label("Viewport renderer");
        ui.horizontal(|ui| {
            for (mode, label, tip) in [
                (ViewRenderer::Auto, "Auto", "The GPU; the CPU preview while a rigged model shows the hole / bloat overlay, the stretch heat map or is stretch-painted (they read its image), and when the GPU adapter is a software rasteriser such as lavapipe (the CPU preview is faster)"),
                (ViewRenderer::Gpu, "GPU", "Always the GPU renderer (no hole / bloat overlay, heat map or stretch painting)"),
                (ViewRenderer::Cpu, "CPU preview", "Always core's CPU reference renderer, on a worker thread"),
            ] {
                ui.selectable_value(&mut self.renderer, mode, label)
                    .on_hover_text(tip);
            }
        });
        ui.label("Viewport resolution");
        ui.horizontal(|ui| {
            for (scale, label) in [(1.0_f32, "100%"), (0.5, "50%"), (0.25, "25%")] {
                ui.selectable_value(&mut self.render_scale, scale, label)
                    .on_hover_text(
                        "Render the view at this fraction of its pixels (faster on slow GPUs)",
                    );
            }
        });
        let mut adaptive = self.motion_budget_ms.is_some();
        if ui
            .checkbox(
                &mut adaptive,
                format!("CPU preview: keep moving frames under {PREVIEW_MOTION_BUDGET_MS:.0} ms"),
            )
            .on_hover_text(
                "While the view keeps changing (an orbit, a stroke, a slider dragged) the CPU \
                 preview draws half the view's resolution; with this on it goes down to a \
                 quarter when its last frame says half would take longer than the budget. \
                 Still views always refine to the full resolution.",
            )
            .changed()
        {
            self.motion_budget_ms = adaptive.then_some(PREVIEW_MOTION_BUDGET_MS);
        }
    }

    /// Draws the view, handles navigation, sculpting and the pose gizmo.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        editor: &mut Editor,
        sculpt: &mut SculptTool,
        pose: &mut PoseTool,
        krs: &mut KrsPanel,
    ) {
        let rect = ui.available_rect_before_wrap();
        self.last_rect = rect;
        self.last_pixels_per_point = ui.ctx().pixels_per_point();
        if rect.height() > 0.0 {
            editor.view_aspect = rect.width() / rect.height();
        }
        // Stretch painting aims with the CPU preview's pixel ids (the posed model as drawn).
        self.stretch_painting = sculpt.active && sculpt.stretch_paint;
        let weight_painting = !sculpt.active && super::rig_panel::paints_now(editor, pose);
        self.show_weights = match (editor.selection, pose.joint) {
            (Some(Selection::Object(id)), Some(j))
                if j.object == id && (pose.rig.show_weights || weight_painting) =>
            {
                Some((id, j.joint))
            }
            _ => None,
        };
        // No tooltip over the view (it would cover the scene); the hint is in the corner text.
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        let aspect = rect.aspect_ratio().max(1e-3);

        // Where the pointer points in the scene (for the brush and for picking). A perspective
        // ray starts at the eye, not on the near plane: the planes are fitted to the bounded
        // objects, and an unbounded KRS object (terrain) may lie nearer than the near plane, which
        // would put the ray's start inside it.
        let pointer_ray = response.hover_pos().and_then(|p| {
            let ndc = Vec2::new(
                (p.x - rect.left()) / rect.width() * 2.0 - 1.0,
                1.0 - (p.y - rect.top()) / rect.height() * 2.0,
            );
            let camera = editor.doc().camera;
            ray_through(camera.clip_from_world(aspect), ndc).map(|(o, d)| {
                if camera.orthographic {
                    (o, d)
                } else {
                    (camera.eye(), d)
                }
            })
        });
        // The brush's target (a KRS surface too, for the selected voxel model's brush); other
        // tools only need the voxel.
        let brush = sculpt.active && sculpt.tool == ToolKind::Brush;
        let hover_pick = pointer_ray.and_then(|(o, d)| {
            if brush {
                editor.pick_brush(o, d, sculpt.brush_onto(editor))
            } else {
                editor.pick_voxel(o, d)
            }
        });

        let proj = Projector::new(editor.doc().camera, rect);
        // The cell a paste lands on when it starts at the pointer (Ctrl+V).
        self.paste_target = hover_pick
            .as_ref()
            .map(|p| (p.object, p.voxel.as_ivec3() + p.normal));
        let select_tool = sculpt.active && sculpt.tool == super::voxel_tools::ToolKind::Select;
        let paste_drag = sculpt
            .voxel
            .drag_paste(&response, editor, pointer_ray, select_tool);
        let gizmo = paste_drag
            || (!sculpt.active
                && (pose.interact(ui, &response, editor, &proj)
                    || krs.interact(ui, &response, editor, &proj)));
        let navigating = self.navigate(
            ui,
            &response,
            editor,
            sculpt.active || weight_painting,
            gizmo,
            rect,
        );
        let rigged = !sculpt.active
            && !navigating
            && !gizmo
            && super::rig_panel::view_input(
                &response,
                editor,
                pose,
                &proj,
                pointer_ray,
                hover_pick.as_ref(),
            );
        if rigged {
            // Placed a joint or painted weights.
        } else if sculpt.active && !navigating && sculpt.stretch_paint {
            let hit = response
                .hover_pos()
                .and_then(|p| self.preview_hit(editor, rect, p));
            sculpt.handle_stretch(&response, editor, hit);
        } else if sculpt.active && !navigating && !paste_drag {
            sculpt.handle_tools(&response, editor, pointer_ray, hover_pick, &proj);
        } else if response.clicked() && !gizmo {
            // Click to select a joint (its dot) or what is under the pointer (or nothing).
            let joint = response
                .interact_pointer_pos()
                .and_then(|p| pose.pick_joint(editor, &proj, p));
            let mirror = response
                .interact_pointer_pos()
                .and_then(|p| pick_mirror(editor, krs, &proj, p));
            if let Some(j) = joint {
                editor.selection = Some(Selection::Object(j.object));
                pose.joint = Some(j);
            } else if let Some(m) = mirror {
                // The selected KRS object stays selected; its plane is highlighted.
                krs.mirror = Some(m);
            } else {
                // Voxels, meshes and KRS objects: the nearest surface under the pointer.
                let pick = pointer_ray.and_then(|(o, d)| editor.pick(o, d));
                editor.selection = pick.map(|p| Selection::Object(p.object));
                self.last_click = pick.map(|p| (editor.generation(), p));
            }
        }

        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, srgb_color(editor.doc().background));
        let cpu = self.uses_cpu(editor);
        let volume = sculpt.active && sculpt.tool != ToolKind::Brush;
        let silhouette = if cpu {
            self.cpu_image(ui, rect, editor)
        } else {
            self.gpu_image(ui, rect, editor, self.show_grid || volume);
            // The preview's shadow maps (up to 64 MiB each at the final preset's 4096²) and
            // frame buffers are of no use while the GPU draws; a render still running holds
            // the lock and they go on the next frame.
            if let Ok(mut kept) = self.cpu.renderer.try_lock() {
                *kept = PreviewRenderer::default();
            }
            false
        };

        let proj = Projector::new(editor.doc().camera, rect);
        let camera = proj.camera;
        let line = |a: Vec3, b: Vec3, stroke: egui::Stroke| {
            if let Some(seg) = proj.segment(a, b) {
                painter.line_segment(seg, stroke);
            }
        };
        let to_screen = |p: Vec3| proj.to_screen(p);
        {
            // The grid, the axes and the volume box go behind what is drawn in front of them.
            let frame = self.shown_depth(editor, cpu);
            let depth = std::cell::RefCell::new(std::mem::take(&mut self.overlay_depth));
            let unhidden = |a: Vec3, b: Vec3, stroke: egui::Stroke| {
                for &(p, q) in depth
                    .borrow_mut()
                    .parts(&proj, editor, frame.as_ref(), a, b)
                {
                    line(p, q, stroke);
                }
            };
            if self.show_grid {
                grid(&camera, &unhidden);
            }
            if volume {
                paint_volume(editor, &unhidden);
            }
            self.overlay_depth = depth.into_inner();
        }
        self.outlines(editor, &line, &to_screen, &painter, silhouette);
        sculpt.voxel.paint(
            sculpt.tool,
            &painter,
            &proj,
            editor,
            pointer_ray,
            sculpt.active && !sculpt.stretch_paint,
        );
        paint_mirrors(&painter, editor, krs, &proj);
        paint_zones(&painter, editor, krs, &proj);
        paint_route(&painter, editor, krs, &proj);
        let shown = self.shown_pose_document(cpu);
        pose.paint(&painter, editor, shown.as_deref(), &proj);
        if let Some((generation, pick)) = self.last_click
            && generation == editor.generation()
        {
            paint_click(&painter, &proj, &pick);
        }
        if sculpt.active
            && !sculpt.stretch_paint
            && sculpt.tool == ToolKind::Brush
            && let Some(pick) = hover_pick
        {
            brush_preview(&painter, &to_screen, &camera, &pick, sculpt);
        }
        if sculpt.active
            && sculpt.stretch_paint
            && let Some(pos) = response.hover_pos()
        {
            self.stretch_brush_preview(&painter, editor, &proj, rect, pos, sculpt);
        }
        let tool = sculpt.active.then_some((sculpt.tool, sculpt.stretch_paint));
        self.status_text(ui, rect, editor, tool, cpu);
    }

    /// Whether the CPU preview draws the view (see [`ViewRenderer`]).
    #[must_use]
    pub fn uses_cpu(&self, editor: &Editor) -> bool {
        self.cpu_reason(editor).is_some()
    }

    /// Why the CPU preview draws the view, or `None` when the GPU does.
    /// Why the CPU preview draws the view, for the performance window ("chosen" when it is
    /// not the reason of `View::cpu_reason`'s cases, e.g. a test that forces it).
    #[must_use]
    pub fn cpu_reason_text(&self, editor: &Editor) -> &'static str {
        self.cpu_reason(editor).unwrap_or("chosen")
    }

    fn cpu_reason(&self, editor: &Editor) -> Option<&'static str> {
        let Some(gpu) = &self.gpu else {
            return Some("no GPU renderer in this window");
        };
        match self.renderer {
            ViewRenderer::Cpu => Some("chosen in Render > Viewport renderer"),
            ViewRenderer::Gpu => None,
            // The GPU draws voxels (rigid and skinned), meshes and KRS; the hole / bloat
            // overlay, the stretch heat map and stretch painting read the CPU preview's image
            // and pixel ids, so a rigged model falls back to it for them.
            ViewRenderer::Auto
                if (self.show_holes
                    || self.show_stretch
                    || self.stretch_painting
                    || self.show_weights.is_some())
                    && has_rig(editor.doc()) =>
            {
                Some("the hole / bloat overlay, heat maps and stretch painting read its image")
            }
            ViewRenderer::Auto if gpu.lock().software => {
                Some("Auto: the GPU adapter is a software rasteriser, slower than this")
            }
            ViewRenderer::Auto => None,
        }
    }

    /// CPU preview renders finished so far (tests and the perf overlay).
    #[must_use]
    pub fn cpu_renders(&self) -> u64 {
        self.cpu.renders
    }

    /// The rigged voxel model and the node id the shown CPU preview draws at `pos` (a point in
    /// `rect`, the view), when the preview shows the current document's objects.
    #[must_use]
    pub fn preview_hit(
        &self,
        editor: &Editor,
        rect: egui::Rect,
        pos: egui::Pos2,
    ) -> Option<(u64, u64)> {
        let shown = self.cpu.shown.as_ref()?;
        // Labels are document indices: only valid while the object list is the same one.
        if shown.content.0 != editor.content_key().0 || !rect.contains(pos) {
            return None;
        }
        let [w, h] = shown.size_px;
        let x = (((pos.x - rect.left()) / rect.width()) * w as f32) as usize;
        let y = (((pos.y - rect.top()) / rect.height()) * h as f32) as usize;
        let i = y.min(h as usize - 1) * w as usize + x.min(w as usize - 1);
        let label = *self.cpu.labels.get(i)?;
        let node = *self.cpu.nodes.get(i)?;
        let o = editor.doc().objects.get((label as usize).checked_sub(1)?)?;
        match &o.kind {
            ObjectKind::Voxels(v) if v.rig.is_some() => Some((o.id, node)),
            _ => None,
        }
    }

    /// The stretch brush over the rigged model under the pointer: a circle of the brush's
    /// radius (sized at the node's bind-pose place, which the pose moves but hardly scales),
    /// in the heat map's colour of the factor it paints (grey when erasing).
    fn stretch_brush_preview(
        &self,
        painter: &egui::Painter,
        editor: &Editor,
        proj: &Projector,
        rect: egui::Rect,
        pos: egui::Pos2,
        sculpt: &SculptTool,
    ) {
        let Some((id, node)) = self.preview_hit(editor, rect, pos) else {
            return;
        };
        let (Some(o), Some(c)) = (editor.object(id), editor.node_center(id, node)) else {
            return;
        };
        let ObjectKind::Voxels(v) = &o.kind else {
            return;
        };
        let world_from_voxel = o.transform.matrix() * v.object_from_voxel();
        let p = world_from_voxel.transform_point3(c);
        let voxel_world = world_from_voxel
            .transform_vector3(Vec3::X)
            .length()
            .max(1e-9);
        let radius_px = sculpt.brush.radius * voxel_world / proj.world_per_point(p).max(1e-9);
        let color = if sculpt.stretch_erase {
            egui::Color32::from_gray(200)
        } else {
            stretch_color(sculpt.stretch_factor)
        };
        painter.circle_stroke(
            pos,
            radius_px.clamp(2.0, 400.0),
            egui::Stroke::new(2.0, color),
        );
    }

    /// Stretch-factor statistics of the shown CPU preview (with [`View::show_stretch`]).
    #[must_use]
    pub fn stretch_stats(&self) -> Option<StretchStats> {
        self.cpu.stretch.as_ref().map(|(_, s)| *s)
    }

    /// Hole and bloat counts of the shown CPU preview (with [`View::show_holes`]).
    #[must_use]
    pub fn hole_counts(&self) -> Option<HoleCounts> {
        self.cpu.holes.as_ref().map(|(_, c)| *c)
    }

    /// The size in pixels the view renders at (its last rectangle, the display's scale and the
    /// render scale): what the Trade-off sweep measures by default. Not finite before the view
    /// was first drawn.
    #[must_use]
    pub fn render_size_px(&self) -> egui::Vec2 {
        self.last_rect.size() * self.last_pixels_per_point * self.render_scale
    }

    /// Wall-clock milliseconds of the last CPU preview render, and its size in pixels.
    #[must_use]
    pub fn cpu_preview_stats(&self) -> Option<(f64, [u32; 2])> {
        let size = self.cpu.shown.as_ref()?.size_px;
        (self.cpu.renders > 0).then_some((self.cpu.last_ms, size))
    }

    /// Samples per pixel side of the shown CPU preview image (1 while moving, then the
    /// document's supersampling once refined).
    #[must_use]
    pub fn cpu_preview_supersample(&self) -> Option<u32> {
        self.cpu.shown.as_ref().map(|k| k.supersample)
    }

    /// The last CPU preview render's statistics: time per stage, nodes per level, KRS rays.
    #[must_use]
    pub fn cpu_preview_frame_stats(&self) -> Option<&thicket_core::render::FrameStats> {
        self.cpu.last_stats.as_ref()
    }

    /// What the last CPU preview render's shadow pass did with the kept maps.
    #[must_use]
    pub fn cpu_preview_shadows(&self) -> Option<ShadowWork> {
        self.cpu.last_stats.as_ref().map(ShadowWork::of)
    }

    /// The size of the CPU preview render in flight, if any (tests: low resolution while the
    /// camera moves).
    #[must_use]
    pub fn cpu_preview_in_flight(&self) -> Option<[u32; 2]> {
        self.cpu.job.as_ref().map(|(k, _)| k.size_px)
    }

    /// Waits for the CPU preview render in flight, if any (tests; the UI polls instead). Its
    /// image is shown from the next frame, and the camera counts as still from now on, so the
    /// next frames refine it to full resolution whatever the test's timing.
    pub fn wait_for_cpu_preview(&mut self) {
        self.preview_motion = None;
        if let Some((key, rx)) = self.cpu.job.take() {
            let result = rx
                .recv()
                .unwrap_or_else(|_| Err("the preview worker stopped".to_owned()));
            self.cpu.ready = Some((key, result));
        }
    }

    fn snapshot(&mut self, editor: &Editor) -> Arc<Document> {
        let key = render_key(editor);
        match &self.snapshot {
            Some((k, doc)) if *k == key => Arc::clone(doc),
            _ => {
                // The renderer reads the document after this frame's UI (in `prepare`, or on
                // the preview's worker): it gets its own copy, made only when the content
                // changed (a dab, an edit, undo, a new playhead time).
                let doc = Arc::new(editor.doc().clone());
                self.snapshot = Some((key, Arc::clone(&doc)));
                doc
            }
        }
    }

    /// Shows the CPU preview (starting a render when the document, camera or size changed);
    /// returns whether the selection's outline was drawn from its pixels.
    fn cpu_image(&mut self, ui: &egui::Ui, rect: egui::Rect, editor: &mut Editor) -> bool {
        let ppp = ui.ctx().pixels_per_point();
        // Voxel edits since the last frame, for the shadow maps to patch; one that cannot be
        // described breaks the chain (the maps are drawn whole).
        let doc = editor.doc();
        self.cpu
            .changes
            .read(editor.changes(), |c| Redo::for_shadow_maps(doc, c));
        // Low resolution while what is drawn keeps changing (an orbit, a stroke, playback); the
        // full resolution setting once it has been still for a moment. A drag that changes
        // nothing drawn (placing a box, a selection) keeps the full image.
        let drawn = (editor.doc().camera, render_key(editor));
        let now = Instant::now();
        let moved_at =
            match self.preview_motion {
                Some((d, t)) if d == drawn => Some(t),
                Some(_) => Some(now),
                None if self.cpu.shown.as_ref().is_some_and(|k| {
                    k.camera != drawn.0 || (k.content, k.animation) != drawn.1
                }) =>
                {
                    Some(now)
                }
                None => None,
            };
        self.preview_motion = moved_at.map(|t| (drawn, t));
        let moving = moved_at.is_some_and(|t| now - t < PREVIEW_STILL);
        if moving {
            ui.ctx().request_repaint_after(PREVIEW_STILL);
        }
        let full = rect.size() * ppp * self.render_scale;
        let scale = match (moving, self.motion_budget_ms) {
            (false, _) => 1.0,
            (true, None) => CPU_PREVIEW_SCALE,
            (true, Some(budget)) => {
                // Time per sample of the last frame: a still frame may have drawn several
                // samples per pixel; a moving one draws one.
                let last = self
                    .cpu
                    .shown
                    .as_ref()
                    .filter(|_| self.cpu.renders > 0)
                    .map(|k| (self.cpu.last_ms, samples_drawn(k)));
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
            holes: self.show_holes,
            stretch: self.show_stretch,
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
            && self.cpu.shown.as_ref().is_some_and(|s| {
                PreviewKey {
                    supersample: 1,
                    ..s.clone()
                } == key
            })
        {
            key.supersample = samples;
        }
        if let Some((k, rx)) = &self.cpu.job {
            match rx.try_recv() {
                Ok(result) => {
                    self.cpu.ready = Some((k.clone(), result));
                    self.cpu.job = None;
                }
                Err(mpsc::TryRecvError::Empty) => {
                    ui.ctx().request_repaint_after(Duration::from_millis(30));
                }
                Err(mpsc::TryRecvError::Disconnected) => {
                    self.cpu.ready = Some((k.clone(), Err("the preview worker stopped".into())));
                    self.cpu.job = None;
                }
            }
        }
        if let Some((k, result)) = self.cpu.ready.take() {
            self.cpu.shown_doc = self.cpu.job_doc.take();
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
                    self.cpu.last_stats = Some(stats);
                    self.cpu.depth = Some(FrameDepth::new(
                        k.content,
                        k.animation,
                        k.camera,
                        [image.size[0] as u32, image.size[1] as u32],
                        depth,
                    ));
                    self.cpu.labels = labels;
                    self.cpu.nodes = nodes;
                    self.cpu.stretch = stretch.map(|(overlay, stats)| {
                        let t = ui.ctx().load_texture(
                            "stretch_overlay",
                            overlay,
                            egui::TextureOptions::NEAREST,
                        );
                        (t, stats)
                    });
                    self.cpu.holes = holes.map(|(overlay, counts)| {
                        let t = ui.ctx().load_texture(
                            "hole_overlay",
                            overlay,
                            egui::TextureOptions::NEAREST,
                        );
                        (t, counts)
                    });
                    match &mut self.cpu.texture {
                        Some(t) => t.set(image, egui::TextureOptions::LINEAR),
                        None => {
                            self.cpu.texture = Some(ui.ctx().load_texture(
                                "cpu_preview",
                                image,
                                egui::TextureOptions::LINEAR,
                            ));
                        }
                    }
                    self.cpu.last_ms = ms;
                    self.cpu.renders += 1;
                    self.cpu.error = None;
                }
                Err(e) => {
                    log::warn!("CPU preview: {e}");
                    self.cpu.depth = None;
                    self.cpu.error = Some(e);
                }
            }
            self.cpu.shown = Some(k);
        }
        // One render at a time; when it lands, the newest key starts the next.
        if self.cpu.job.is_none() && self.cpu.shown.as_ref() != Some(&key) {
            let doc = self.snapshot(editor);
            let job_doc = Arc::clone(&doc);
            // The snapshot's key: it changes whenever the content or the playhead does.
            let content_key = preview_content_hash(render_key(editor));
            let changes: Vec<_> = self
                .cpu
                .changes
                .take()
                .iter()
                .map_while(|r| shadow_change(&doc, editor.animation_key(), r))
                .collect();
            let kept = Arc::clone(&self.cpu.renderer);
            let (tx, rx) = mpsc::channel();
            let request = thicket_core::render::RenderRequest {
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
            self.cpu.job = Some((key, rx));
            self.cpu.job_doc = Some(job_doc);
            ui.ctx().request_repaint_after(Duration::from_millis(30));
        }
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        if let Some(t) = &self.cpu.texture {
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
        if self.show_holes
            && let Some((t, _)) = &self.cpu.holes
        {
            ui.painter_at(rect)
                .image(t.id(), rect, uv, egui::Color32::WHITE);
            hole_legend_ui(ui, rect);
        }
        if self.show_stretch
            && let Some((t, stats)) = &self.cpu.stretch
        {
            ui.painter_at(rect)
                .image(t.id(), rect, uv, egui::Color32::WHITE);
            stretch_legend_ui(ui, rect, *stats);
        }
        if let Some(t) = self.weight_heat_map(ui, editor) {
            ui.painter_at(rect).image(t, rect, uv, egui::Color32::WHITE);
        }
        outlined
    }

    /// The selected joint's weight heat map over the shown preview, when asked for and the
    /// preview shows the current document (its labels are document indices).
    fn weight_heat_map(&mut self, ui: &egui::Ui, editor: &Editor) -> Option<egui::TextureId> {
        let (id, joint) = self.show_weights?;
        let shown = self.cpu.shown.as_ref()?;
        if shown.content != editor.content_key() || self.cpu.error.is_some() {
            return None;
        }
        let key = (self.cpu.renders, id, joint);
        if self.weights.as_ref().is_none_or(|(k, _)| *k != key) {
            let size = [shown.size_px[0] as usize, shown.size_px[1] as usize];
            let image = super::rig_panel::weight_overlay(
                editor.doc(),
                &self.cpu.labels,
                &self.cpu.nodes,
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
        let shown = self.cpu.shown.as_ref()?;
        if shown.content != editor.content_key() || self.cpu.error.is_some() {
            return None;
        }
        let Some(Selection::Object(id)) = editor.selection else {
            return None;
        };
        let label = editor.doc().objects.iter().position(|o| o.id == id)? as u32 + 1;
        let size = [shown.size_px[0] as usize, shown.size_px[1] as usize];
        if self.cpu.labels.len() != size[0] * size[1] {
            return None;
        }
        let key = (self.cpu.renders, label);
        if self.cpu.outline.as_ref().is_none_or(|(k, _, _)| *k != key) {
            let (image, border_px) = outline_image(&self.cpu.labels, size, label);
            let shown = !outline_is_clutter(border_px, size);
            match &mut self.cpu.outline {
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
                    self.cpu.outline = Some((key, t, shown));
                }
            }
        }
        self.cpu
            .outline
            .as_ref()
            .filter(|(_, _, shown)| *shown)
            .map(|(_, t, _)| t.id())
    }

    /// Orbit / pan / zoom. Returns whether the pointer is navigating (not sculpting).
    fn navigate(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        editor: &mut Editor,
        sculpting: bool,
        gizmo: bool,
        rect: egui::Rect,
    ) -> bool {
        let mut camera = editor.doc().camera;
        let (modifiers, middle, secondary, primary) = ui.input(|i| {
            (
                i.modifiers,
                i.pointer.middle_down(),
                i.pointer.secondary_down(),
                i.pointer.primary_down(),
            )
        });
        // With the sculpt tool the primary button sculpts; Alt turns it back into orbit. A drag
        // that grabbed the pose gizmo moves the joint, not the camera.
        let primary_navigates = !gizmo && (!sculpting || modifiers.alt);
        let navigating =
            response.dragged() && (middle || secondary || (primary && primary_navigates));
        if navigating {
            let d = response.drag_delta();
            if modifiers.shift || secondary {
                pan(&mut camera, d, rect.height());
            } else if d != egui::Vec2::ZERO {
                camera.yaw_deg = (camera.yaw_deg - d.x * ORBIT_DEG_PER_POINT).rem_euclid(360.0);
                camera.pitch_deg =
                    (camera.pitch_deg + d.y * ORBIT_DEG_PER_POINT).clamp(-90.0, 90.0);
                self.leave_auto_ortho(&mut camera);
            }
        }
        if response.hovered() {
            // Mouse wheels report lines: zoom. Trackpads report points: two fingers orbit
            // (Shift: pan) and pinch zooms, as in other 3D tools.
            let (wheel_lines, trackpad_points, pinch) = ui.input(|i| {
                let mut lines = 0.0_f32;
                let mut points = egui::Vec2::ZERO;
                for e in &i.raw.events {
                    if let egui::Event::MouseWheel {
                        unit,
                        delta,
                        modifiers,
                        ..
                    } = e
                    {
                        if modifiers.command {
                            continue; // reported as zoom_delta below
                        }
                        match unit {
                            egui::MouseWheelUnit::Point => points += *delta,
                            egui::MouseWheelUnit::Line => lines += delta.y,
                            egui::MouseWheelUnit::Page => lines += delta.y * 10.0,
                        }
                    }
                }
                (lines, points, i.zoom_delta())
            });
            let mut zoom = (-wheel_lines * 0.12).exp() / pinch.max(1e-3);
            if trackpad_points != egui::Vec2::ZERO {
                if modifiers.shift {
                    pan(&mut camera, trackpad_points, rect.height());
                } else if modifiers.alt {
                    zoom *= (-trackpad_points.y * 0.004).exp();
                } else {
                    camera.yaw_deg = (camera.yaw_deg - trackpad_points.x * ORBIT_DEG_PER_POINT)
                        .rem_euclid(360.0);
                    camera.pitch_deg = (camera.pitch_deg - trackpad_points.y * ORBIT_DEG_PER_POINT)
                        .clamp(-90.0, 90.0);
                    self.leave_auto_ortho(&mut camera);
                }
            }
            if (zoom - 1.0).abs() > 1e-6 {
                camera.distance = (camera.distance * zoom).clamp(1e-3, 1e6);
            }
        }
        // The clip planes follow the eye and the scene (cached bounds: cheap per frame).
        self.fit_clip(editor, &mut camera);
        editor.set_camera(camera);
        navigating
    }

    /// Orbiting out of an axis view that switched to orthographic returns to perspective.
    fn leave_auto_ortho(&mut self, camera: &mut OrbitCamera) {
        if self.auto_ortho {
            camera.orthographic = false;
            self.auto_ortho = false;
        }
    }

    /// The document the CPU preview's shown image was drawn from: the skeleton overlay is
    /// drawn posed as it, so bones stay inside the limbs of the image while the preview lags
    /// playback (or a joint drag, or the object's keyed motion). `None` with the GPU viewport
    /// (it draws the current document in the same frame) and while the preview shows an
    /// error; the skeleton then shows the editor's pose.
    #[must_use]
    pub fn shown_pose_document(&self, cpu: bool) -> Option<Arc<Document>> {
        (cpu && self.cpu.error.is_none() && self.cpu.shown.is_some())
            .then(|| self.cpu.shown_doc.clone())
            .flatten()
    }

    /// The depth of the frame shown, when it shows the editor's scene (content and pose):
    /// the CPU preview's image (drawn from its own camera, which lags an orbit by the time a
    /// preview render takes, as the image itself does), or the GPU viewport's once read back
    /// for the current camera and view size. `None` while the frame
    /// shows an older scene (a stroke in progress); the overlays then test voxels by rays.
    #[must_use]
    pub fn shown_depth(&self, editor: &Editor, cpu: bool) -> Option<FrameDepth> {
        let camera = editor.doc().camera;
        let frame = if cpu {
            self.cpu.depth.clone()
        } else {
            self.gpu
                .as_ref()
                .and_then(|link| link.lock().depth.clone())
                .filter(|d| d.camera == camera && [d.width, d.height] == self.gpu_size_px)
        };
        frame.filter(|d| d.content == editor.content_key() && d.animation == editor.animation_key())
    }

    fn gpu_image(
        &mut self,
        ui: &egui::Ui,
        rect: egui::Rect,
        editor: &mut Editor,
        want_depth: bool,
    ) {
        let Some(link) = self.gpu.clone() else {
            return;
        };
        let key = editor.content_key();
        // Voxel edits since the last frame extend the chain the renderer may upload from;
        // anything else breaks it. `prepare` may not run every frame, so the chain is kept
        // (bounded) until the document changes in another way.
        let doc = editor.doc();
        self.regions
            .read(editor.changes(), |c| Redo::for_upload(doc, c));
        let regions = self.regions.ending_at(key).to_vec();
        // Supersampling only once the view is still, as the CPU preview: a moving frame draws
        // one sample per pixel, and the still frame follows PREVIEW_STILL later.
        let drawn = (editor.doc().camera, render_key(editor));
        let now = Instant::now();
        let moved_at = match self.gpu_motion {
            Some((d, t)) if d == drawn => t,
            Some(_) => Some(now),
            None => None,
        };
        self.gpu_motion = Some((drawn, moved_at));
        let supersample = gpu_view_supersample(moved_at, now, editor.doc().quality.supersample);
        if supersample != editor.doc().quality.supersample {
            ui.ctx().request_repaint_after(PREVIEW_STILL);
        }
        let doc = self.snapshot(editor);
        let ppp = ui.ctx().pixels_per_point();
        let size = rect.size() * ppp * self.render_scale;
        let size_px = [
            (size.x.round() as u32).max(1),
            (size.y.round() as u32).max(1),
        ];
        let key = FrameKey {
            content: key,
            animation: editor.animation_key(),
            camera: editor.doc().camera,
            size_px,
            supersample,
        };
        // The depth is read on the frame after the one that drew it: one more paint when
        // the view stands still (once per frame key; none when the GPU renderer failed).
        let waiting = {
            let status = link.lock();
            status.error.is_none() && status.depth_read.as_ref() != Some(&key)
        };
        if want_depth && waiting {
            ui.ctx().request_repaint_after(PREVIEW_STILL);
        }
        self.gpu_size_px = size_px;
        ui.painter().add(paint_callback(
            rect,
            ViewportCallback {
                key,
                doc,
                regions,
                want_depth,
            },
        ));
    }

    fn outlines(
        &mut self,
        editor: &Editor,
        line: &impl Fn(Vec3, Vec3, egui::Stroke),
        to_screen: &impl Fn(Vec3) -> Option<egui::Pos2>,
        painter: &egui::Painter,
        silhouette: bool,
    ) {
        self.refresh_bounds_cache(editor);
        for o in &editor.doc().objects {
            let selected = editor.selection == Some(Selection::Object(o.id));
            if !o.visible || !(selected || self.show_bounds) {
                continue;
            }
            let Some((lo, hi)) = self.cached_bounds(o) else {
                continue;
            };
            let stroke = if selected {
                egui::Stroke::new(2.0, SELECTION_COLOR)
            } else {
                egui::Stroke::new(1.0, egui::Color32::from_gray(200))
            };
            // With the CPU preview the selection is outlined from its pixels instead; the box
            // stays for the GPU view (its object ids are not read back) and "All bounding boxes".
            if !(selected && silhouette) || self.show_bounds {
                oriented_box_lines(o, lo, hi, stroke, line);
            }
            if let Some(p) = to_screen(o.transform.matrix().transform_point3(hi)) {
                painter.text(
                    p,
                    egui::Align2::LEFT_BOTTOM,
                    &o.name,
                    egui::FontId::proportional(12.0),
                    stroke.color,
                );
            }
        }
    }

    fn status_text(
        &self,
        ui: &egui::Ui,
        rect: egui::Rect,
        editor: &Editor,
        tool: Option<(ToolKind, bool)>,
        cpu: bool,
    ) {
        let painter = ui.painter_at(rect);
        let origin = rect.left_top() + egui::vec2(8.0, 8.0);
        let weak = ui.visuals().weak_text_color();
        let font = egui::FontId::proportional(12.0);
        let hint = nav_hint(tool, has_rig(editor.doc()));
        let view_name = view_name(&editor.doc().camera);
        if cpu {
            let (text, color) = match (&self.cpu.error, &self.cpu.shown) {
                (Some(e), _) => (
                    format!("CPU preview: {e}\nThe document is still editable and saveable."),
                    ui.visuals().error_fg_color,
                ),
                (None, Some(k)) => (
                    format!(
                        "{view_name}   CPU preview {} x {} px{}{} ({}){}\n{hint}",
                        k.size_px[0],
                        k.size_px[1],
                        if k.supersample > 1 {
                            format!(", {0}×{0} samples", k.supersample)
                        } else {
                            String::new()
                        },
                        if self
                            .cpu
                            .job
                            .as_ref()
                            .is_some_and(|(j, _)| samples_drawn(j) > samples_drawn(k))
                        {
                            ", refining"
                        } else {
                            ""
                        },
                        self.cpu_reason_text(editor),
                        match (self.show_holes, self.hole_counts()) {
                            (true, Some(c)) => format!(
                                "\nHoles {} px ({:.2} % of the mesh), bloat {} px (magenta / yellow)",
                                c.holes,
                                100.0 * c.holes as f64 / c.mesh_pixels.max(1) as f64,
                                c.bloat
                            ),
                            (true, None) =>
                                "\nHole overlay: no rigged model in the view".to_owned(),
                            (false, _) => String::new(),
                        },
                    ),
                    egui::Color32::from_gray(220),
                ),
                (None, None) => (
                    "Rendering (CPU preview)...".to_owned(),
                    egui::Color32::from_gray(220),
                ),
            };
            let galley = painter.layout_no_wrap(text, font, color);
            let backdrop = egui::Rect::from_min_size(origin, galley.size()).expand(4.0);
            painter.rect_filled(backdrop, 3.0, egui::Color32::from_black_alpha(140));
            painter.galley(origin, galley, weak);
            return;
        }
        let Some(link) = &self.gpu else {
            painter.text(
                origin,
                egui::Align2::LEFT_TOP,
                "No GPU renderer in this window: overlays only (`thicket render` draws the scene)",
                font,
                weak,
            );
            return;
        };
        let status = link.lock();
        if let Some(err) = &status.error {
            painter.text(
                origin,
                egui::Align2::LEFT_TOP,
                format!("Viewport: {err}\nThe document is still editable and saveable."),
                font,
                ui.visuals().error_fg_color,
            );
            return;
        }
        let c = editor.doc().camera;
        let text = match &status.stats {
            // Timings are in the performance overlay (F3): this line stays stable for snapshots.
            Some(s) => format!(
                "{view_name}   {} x {} px, {} splats   yaw {:.0} pitch {:.0} dist {:.2}",
                status.size_px[0],
                status.size_px[1],
                crate::files::thousands(s.splats),
                c.yaw_deg,
                c.pitch_deg,
                c.distance
            ),
            None => "Rendering...".to_owned(),
        };
        let text = format!("{text}\n{hint}");
        let galley = painter.layout_no_wrap(text, font, egui::Color32::from_gray(220));
        let backdrop = egui::Rect::from_min_size(origin, galley.size()).expand(4.0);
        painter.rect_filled(backdrop, 3.0, egui::Color32::from_black_alpha(140));
        painter.galley(origin, galley, weak);
    }
}

/// Renders every visible rigged voxel model alone and its skinned reference surface alone with the
/// preview's camera and compares the silhouettes (as `thicket skin-report` does): magenta where
/// the mesh shows and no voxel does (holes), yellow where voxels cover more (bloat). Occluders
/// are left out on purpose: they would hide holes.
fn hole_overlay(
    doc: &Document,
    req: &thicket_core::render::RenderRequest,
) -> Option<(egui::ColorImage, HoleCounts)> {
    use thicket_core::render::{
        Camera, MeshInstance, RenderScene, VoxelInstance, document_deforms, render_scene,
    };
    let (w, h) = (req.width as usize, req.height as usize);
    let cam = Camera::from_orbit(&req.camera.unwrap_or(doc.camera), req.width, req.height);
    let quality = thicket_core::quality::Quality {
        shadows: false,
        ao_samples: 0,
        ..req.quality.clone()
    };
    let deforms = document_deforms(doc, &quality);
    let mut mesh_cov = vec![false; w * h];
    let mut voxel_cov = vec![false; w * h];
    let mut any = false;
    for (o, d) in doc.objects.iter().zip(&deforms) {
        let (ObjectKind::Voxels(v), Some(d)) = (&o.kind, d) else {
            continue;
        };
        let Some(rig) = v.rig.as_ref().filter(|_| o.visible) else {
            continue;
        };
        let Some((reference, _)) = thicket_core::measure::skin::reference_surface(v) else {
            continue;
        };
        let skinning = rig.current_skinning();
        let mesh = thicket_core::mesh::MeshModel {
            parts: reference
                .parts
                .iter()
                .map(|p| thicket_core::skin::lbs::skin_mesh(&skinning, p))
                .collect(),
            materials: reference.materials.clone(),
        };
        let scene = |voxels: Vec<VoxelInstance<'_>>, meshes: Vec<MeshInstance<'_>>| {
            let s = RenderScene {
                voxels,
                meshes,
                lights: &doc.lights,
                ambient: doc.ambient,
                background: doc.background,
            };
            render_scene(&s, &cam, &quality)
                .ok()
                .map(|(_, fb, _)| fb.coverage())
        };
        let mesh_only = scene(
            Vec::new(),
            vec![MeshInstance {
                model: &mesh,
                world_from_object: o.transform.matrix(),
                casts_shadows: false,
                label: 1,
            }],
        )?;
        let voxels_only = scene(
            vec![VoxelInstance {
                svo: &v.svo,
                deform: d.as_ref(),
                casts_shadows: false,
                label: 1,
            }],
            Vec::new(),
        )?;
        for (acc, c) in mesh_cov.iter_mut().zip(mesh_only) {
            *acc |= c;
        }
        for (acc, c) in voxel_cov.iter_mut().zip(voxels_only) {
            *acc |= c;
        }
        any = true;
    }
    if !any {
        return None;
    }
    let mut counts = HoleCounts::default();
    let mut image = egui::ColorImage::filled([w, h], egui::Color32::TRANSPARENT);
    for (i, (&m, &v)) in mesh_cov.iter().zip(&voxel_cov).enumerate() {
        counts.mesh_pixels += u64::from(m);
        if m && !v {
            counts.holes += 1;
            image.pixels[i] = HOLE_COLOR;
        } else if v && !m {
            counts.bloat += 1;
            image.pixels[i] = egui::Color32::from_rgba_unmultiplied(
                BLOAT_COLOR.r(),
                BLOAT_COLOR.g(),
                BLOAT_COLOR.b(),
                170,
            );
        }
    }
    Some((image, counts))
}

/// Whether a visible voxel model has a rig (the hole / bloat overlay needs the CPU preview).
/// The view corner's navigation hint for the active tool.
fn nav_hint(tool: Option<(ToolKind, bool)>, rigged: bool) -> String {
    use super::keys::{Act, shortcut};
    // Keys from the binding table, so the hint names the keys that act.
    let frame = shortcut(Act::Frame);
    let stats = shortcut(Act::Perf);
    let what = match tool {
        Some((_, true)) => "Drag: paint stretch",
        Some((ToolKind::Brush, false)) => "Drag: brush",
        Some((ToolKind::Voxel, false)) => "Click / drag: voxels",
        Some((ToolKind::Box, false)) => "Drag: box, move: height, click: commit",
        Some((ToolKind::Line, false)) => "Drag: line",
        Some((ToolKind::Extrude, false)) => "Drag a face: extrude",
        Some((ToolKind::Fill, false)) => "Click: fill",
        Some((ToolKind::Select, false)) => {
            "Drag: select (on the selection: move it)   Click: colour"
        }
        None if rigged => {
            return format!(
                "Drag: orbit   Click a joint dot: pose   Shift/right-drag: pan   {frame}: frame   \
                 {stats}: stats"
            );
        }
        None => {
            let brush = shortcut(Act::Tool(ToolKind::Brush));
            return format!(
                "Drag: orbit   Shift/right-drag: pan   Scroll: zoom   {frame}: frame   \
                 {brush}: brush   {stats}: stats"
            );
        }
    };
    let navigate = shortcut(Act::Escape);
    format!("{what}   Alt/middle-drag: orbit   Shift: pan   Scroll: zoom   {navigate}: navigate")
}

/// "Front orthographic", "User perspective", …: which axis view (if the camera looks along
/// one) and which projection, as Blender names its views.
#[must_use]
pub fn view_name(camera: &OrbitCamera) -> String {
    let axis = AxisView::ALL.iter().find(|(v, _)| {
        let (yaw, pitch) = v.angles();
        let dy = (camera.yaw_deg - yaw).rem_euclid(360.0);
        // Top and bottom views look along Y whatever the yaw.
        (camera.pitch_deg - pitch).abs() < 1e-3
            && (pitch.abs() == 90.0 || dy.min(360.0 - dy) < 1e-3)
    });
    let projection = if camera.orthographic {
        "orthographic"
    } else {
        "perspective"
    };
    format!("{} {projection}", axis.map_or("User", |(_, label)| *label))
}

fn has_rig(doc: &Document) -> bool {
    doc.objects
        .iter()
        .filter(|o| o.visible)
        .any(|o| matches!(&o.kind, ObjectKind::Voxels(v) if v.rig.is_some()))
}

/// Moves the target in the view plane by a drag of `d` points in a view `height` points tall.
fn pan(camera: &mut OrbitCamera, d: egui::Vec2, height: f32) {
    let eye = camera.eye();
    let forward = (camera.target - eye).normalize_or_zero();
    let up_hint = if camera.pitch_deg.abs() > 89.9 {
        Vec3::Z
    } else {
        Vec3::Y
    };
    let right = forward.cross(up_hint).normalize_or_zero();
    let up = right.cross(forward);
    let world_per_point =
        2.0 * camera.distance * (camera.fov_y_deg.to_radians() * 0.5).tan() / height.max(1.0);
    camera.target += (-right * d.x + up * d.y) * world_per_point;
}

fn local_bounds(o: &Object) -> Option<Aabb> {
    match &o.kind {
        // A rigged model is drawn posed (skinned into its skeleton's space).
        ObjectKind::Voxels(v) => v.posed_bounds(),
        ObjectKind::Mesh(m) => m.model.bounds(),
        // The KRS's own placement is inside its bounding ball; callers apply the object's
        // transform on top, which is what `KrsObject::world_from_object` sits under.
        ObjectKind::Krs(k) => {
            let (c, r) = k.bounding_sphere_object()?;
            let t = k.world_from_object;
            let c = t.transform_point(c);
            let r = r * t.scale + k.distortion.map_or(0.0, |d| d.max_displacement() * t.scale);
            Some((c - Vec3::splat(r), c + Vec3::splat(r)))
        }
    }
}

fn srgb_color(linear: Vec3) -> egui::Color32 {
    let c = |v: f32| (thicket_core::mesh::linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8;
    egui::Color32::from_rgb(c(linear.x), c(linear.y), c(linear.z))
}

/// The object-space box drawn through the object's transform (so it turns with the object).
fn oriented_box_lines(
    o: &Object,
    lo: Vec3,
    hi: Vec3,
    stroke: egui::Stroke,
    line: &impl Fn(Vec3, Vec3, egui::Stroke),
) {
    let m = o.transform.matrix();
    let corner = |k: u32| {
        m.transform_point3(Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        ))
    };
    for k in 0..8u32 {
        for bit in [1u32, 2, 4] {
            if k & bit == 0 {
                line(corner(k), corner(k | bit), stroke);
            }
        }
    }
}

/// The last click's surface point and normal: a dot and a line a tenth of the eye distance
/// long (so it reads at any zoom and foreshortens with the surface).
fn paint_click(painter: &egui::Painter, proj: &Projector, pick: &SurfacePick) {
    let p = pick.point_in_world;
    let Some(c) = proj.to_screen(p) else {
        return;
    };
    let length = 0.1 * proj.camera.eye().distance(p).max(proj.camera.near);
    let color = egui::Color32::from_rgb(255, 200, 40);
    if let Some(seg) = proj.segment(p, p + pick.normal_in_world * length) {
        painter.line_segment(seg, egui::Stroke::new(3.0, egui::Color32::BLACK));
        painter.line_segment(seg, egui::Stroke::new(1.5, color));
    }
    painter.circle_filled(c, 4.0, color);
    painter.circle_stroke(c, 4.0, egui::Stroke::new(1.0, egui::Color32::BLACK));
}

/// The brush footprint at the picked point: a circle of the brush radius facing the camera,
/// and the face normal.
fn brush_preview(
    painter: &egui::Painter,
    to_screen: &impl Fn(Vec3) -> Option<egui::Pos2>,
    camera: &OrbitCamera,
    pick: &VoxelPick,
    sculpt: &SculptTool,
) {
    let center = pick.point_in_world;
    let radius_world = sculpt.brush.radius * pick.voxel_size_world;
    let forward = (camera.target - camera.eye()).normalize_or_zero();
    let right = forward.cross(Vec3::Y).try_normalize().unwrap_or(Vec3::X);
    let (Some(c), Some(edge)) = (to_screen(center), to_screen(center + right * radius_world))
    else {
        return;
    };
    let r = c.distance(edge).max(2.0);
    let color = egui::Color32::from_rgba_unmultiplied(
        sculpt.brush.color[0],
        sculpt.brush.color[1],
        sculpt.brush.color[2],
        255,
    );
    match sculpt.brush.shape {
        thicket_core::sculpt::BrushShape::Sphere => {
            painter.circle_stroke(c, r, egui::Stroke::new(1.5, egui::Color32::WHITE));
            painter.circle_stroke(c, r + 1.5, egui::Stroke::new(1.0, color));
        }
        thicket_core::sculpt::BrushShape::Cube => {
            let rr = egui::Rect::from_center_size(c, egui::vec2(2.0 * r, 2.0 * r));
            painter.rect_stroke(
                rr,
                0.0,
                egui::Stroke::new(1.5, egui::Color32::WHITE),
                egui::StrokeKind::Middle,
            );
        }
    }
    if let Some(n) = to_screen(center + pick.normal.as_vec3() * radius_world) {
        painter.line_segment([c, n], egui::Stroke::new(1.0, color));
    }
}

/// Heat-map colour of a stretch factor: blue at [`STRETCH_SCALE_MIN`], green at 1, yellow,
/// red at [`STRETCH_SCALE_MAX`] and above.
#[must_use]
pub fn stretch_color(factor: f32) -> egui::Color32 {
    let stops: [(f32, [u8; 3]); 4] = [
        (STRETCH_SCALE_MIN, [40, 90, 255]),
        (1.0, [40, 200, 80]),
        (1.75, [250, 220, 40]),
        (STRETCH_SCALE_MAX, [240, 40, 30]),
    ];
    let f = if factor.is_finite() {
        factor
    } else {
        STRETCH_SCALE_MAX
    };
    let f = f.clamp(STRETCH_SCALE_MIN, STRETCH_SCALE_MAX);
    let k = stops
        .windows(2)
        .position(|w| f <= w[1].0)
        .unwrap_or(stops.len() - 2);
    let ((a, ca), (b, cb)) = (stops[k], stops[k + 1]);
    let t = ((f - a) / (b - a)).clamp(0.0, 1.0);
    let mix =
        |i: usize| (f32::from(ca[i]) + t * (f32::from(cb[i]) - f32::from(ca[i]))).round() as u8;
    egui::Color32::from_rgb(mix(0), mix(1), mix(2))
}

/// The stretch factor of every node of rigged model `v` that the preview shows, by its pixel
/// id: the size of the node's splat this frame (strategy, multiplier, overrides) over the size
/// of the same node placed with no stretch. Both are the renderer's own `NodeDeform`.
fn node_stretch_factors(
    o: &thicket_core::scene::Object,
    v: &thicket_core::scene::VoxelModel,
    quality: &thicket_core::quality::Quality,
    wanted: &std::collections::HashSet<u64>,
) -> HashMap<u64, f32> {
    use thicket_core::deform::{NodeDeform as _, NodeInfo};
    use thicket_core::skin::{SkinDeform, StretchStrategy};
    let mut out = HashMap::new();
    let Some(rig) = &v.rig else {
        return out;
    };
    let settings = thicket_core::render::effective_stretch(rig, quality);
    let deform = |s| thicket_core::render::skin_deform(o, v, rig, quality).with_settings(s);
    let actual = deform(settings);
    let no_overrides = thicket_core::skin::StretchOverrides::default();
    let plain = {
        let mut s = settings;
        s.strategy = StretchStrategy::Off;
        s.multiplier = 1.0;
        // Overrides are part of the stretch: the reference ignores them.
        SkinDeform::new(
            o.transform.matrix(),
            v.object_from_voxel(),
            &rig.skinning_at(rig.playback.clip, rig.playback.time_secs),
            s,
            &no_overrides,
            rig.tables(&v.svo),
        )
    };
    // Half extent of a splat's world box along its largest axis.
    let extent = |d: thicket_core::deform::DeformedNode| {
        let m = d.half_axes_world;
        let rows = m.x_axis.abs() + m.y_axis.abs() + m.z_axis.abs();
        rows.max_element()
    };
    if v.svo.is_empty() {
        return out;
    }
    let mut stack = vec![v.svo.root()];
    while let Some(node) = stack.pop() {
        let id = (u64::from(node.level) << 32) | u64::from(node.index);
        if wanted.contains(&id) {
            let info = NodeInfo { svo: &v.svo, node };
            let base = extent(plain.deform(&info));
            let f = if base > 0.0 {
                extent(actual.deform(&info)) / base
            } else {
                1.0
            };
            out.insert(id, f);
        }
        if !v.svo.is_leaf(&node) {
            stack.extend((0..8).filter_map(|k| v.svo.child(&node, k)));
        }
    }
    out
}

/// The stretch heat map of a preview frame: each pixel of a visible rigged model coloured by
/// its node's stretch factor (see [`node_stretch_factors`]); other pixels transparent.
fn stretch_overlay(
    doc: &Document,
    req: &thicket_core::render::RenderRequest,
    ids: &[thicket_core::render::PixelId],
    size: [usize; 2],
) -> Option<(egui::ColorImage, StretchStats)> {
    let mut wanted: HashMap<u32, std::collections::HashSet<u64>> = HashMap::new();
    for id in ids {
        let Some(o) = (id.object as usize)
            .checked_sub(1)
            .and_then(|i| doc.objects.get(i))
        else {
            continue;
        };
        if let ObjectKind::Voxels(v) = &o.kind
            && v.rig.is_some()
        {
            wanted.entry(id.object).or_default().insert(id.node);
        }
    }
    if wanted.is_empty() {
        return None;
    }
    let factors: HashMap<u32, HashMap<u64, f32>> = wanted
        .iter()
        .filter_map(|(&label, nodes)| {
            let o = &doc.objects[label as usize - 1];
            let ObjectKind::Voxels(v) = &o.kind else {
                return None;
            };
            Some((label, node_stretch_factors(o, v, &req.quality, nodes)))
        })
        .collect();
    let mut image = egui::ColorImage::filled(size, egui::Color32::TRANSPARENT);
    let mut stats = StretchStats {
        min: f32::INFINITY,
        max: f32::NEG_INFINITY,
        ..StretchStats::default()
    };
    let mut sum = 0.0f64;
    for (px, id) in image.pixels.iter_mut().zip(ids) {
        let Some(f) = factors.get(&id.object).and_then(|m| m.get(&id.node)) else {
            continue;
        };
        let c = stretch_color(*f);
        *px = egui::Color32::from_rgba_unmultiplied(c.r(), c.g(), c.b(), 200);
        stats.pixels += 1;
        stats.min = stats.min.min(*f);
        stats.max = stats.max.max(*f);
        sum += f64::from(*f);
    }
    if stats.pixels == 0 {
        return None;
    }
    stats.mean = (sum / stats.pixels as f64) as f32;
    Some((image, stats))
}

/// The heat map's colour legend in the view's lower left corner, with the frame's range.
/// The hole overlay's legend, at the view's bottom right (the stretch legend sits at its
/// bottom left).
fn hole_legend_ui(ui: &egui::Ui, rect: egui::Rect) {
    let painter = ui.painter_at(rect);
    let font = egui::FontId::proportional(11.0);
    let rows = [
        (HOLE_COLOR, "Hole: mesh shows, no voxel"),
        (BLOAT_COLOR, "Bloat: voxel beyond the mesh"),
    ];
    let width = 190.0;
    let origin = rect.right_bottom() + egui::vec2(-width - 12.0, -52.0);
    let backdrop = egui::Rect::from_min_size(origin, egui::vec2(width, 42.0));
    painter.rect_filled(backdrop, 3.0, egui::Color32::from_black_alpha(160));
    for (i, (color, text)) in rows.into_iter().enumerate() {
        let y = origin.y + 8.0 + 16.0 * i as f32;
        let swatch =
            egui::Rect::from_min_size(egui::pos2(origin.x + 8.0, y), egui::vec2(12.0, 12.0));
        painter.rect_filled(swatch, 2.0, color);
        painter.text(
            egui::pos2(swatch.max.x + 6.0, y + 6.0),
            egui::Align2::LEFT_CENTER,
            text,
            font.clone(),
            egui::Color32::from_gray(220),
        );
    }
}

fn stretch_legend_ui(ui: &egui::Ui, rect: egui::Rect, stats: StretchStats) {
    let painter = ui.painter_at(rect);
    let bar = egui::Rect::from_min_size(
        rect.left_bottom() + egui::vec2(12.0, -58.0),
        egui::vec2(180.0, 12.0),
    );
    let backdrop = egui::Rect::from_min_max(
        bar.min - egui::vec2(6.0, 22.0),
        bar.max + egui::vec2(84.0, 26.0),
    );
    painter.rect_filled(backdrop, 3.0, egui::Color32::from_black_alpha(160));
    let steps = 36;
    for i in 0..steps {
        let t0 = i as f32 / steps as f32;
        let t1 = (i + 1) as f32 / steps as f32;
        let f = STRETCH_SCALE_MIN + (t0 + t1) * 0.5 * (STRETCH_SCALE_MAX - STRETCH_SCALE_MIN);
        let r = egui::Rect::from_min_max(
            egui::pos2(bar.min.x + t0 * bar.width(), bar.min.y),
            egui::pos2(bar.min.x + t1 * bar.width(), bar.max.y),
        );
        painter.rect_filled(r, 0.0, stretch_color(f));
    }
    let font = egui::FontId::proportional(11.0);
    let text = egui::Color32::from_gray(220);
    painter.text(
        bar.left_top() - egui::vec2(0.0, 4.0),
        egui::Align2::LEFT_BOTTOM,
        "Stretch factor",
        font.clone(),
        text,
    );
    for f in [STRETCH_SCALE_MIN, 1.0, 2.0, STRETCH_SCALE_MAX] {
        let x = bar.min.x
            + (f - STRETCH_SCALE_MIN) / (STRETCH_SCALE_MAX - STRETCH_SCALE_MIN) * bar.width();
        painter.text(
            egui::pos2(x, bar.max.y + 2.0),
            egui::Align2::CENTER_TOP,
            format!("{f:.1}"),
            font.clone(),
            text,
        );
    }
    painter.text(
        egui::pos2(bar.max.x + 18.0, bar.center().y),
        egui::Align2::LEFT_CENTER,
        format!(
            "min {:.2}\nmean {:.2}\nmax {:.2}",
            stats.min, stats.mean, stats.max
        ),
        font,
        text,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gpu_view_draws_one_sample_while_moving_and_the_documents_when_still() {
        let t0 = Instant::now();
        let soon = t0 + PREVIEW_STILL / 2;
        let later = t0 + PREVIEW_STILL;
        // Never moved (just opened), or still for PREVIEW_STILL: the document's samples.
        assert_eq!(gpu_view_supersample(None, t0, 3), 3);
        assert_eq!(gpu_view_supersample(Some(t0), later, 3), 3);
        // Moved this frame or a moment ago: one sample.
        assert_eq!(gpu_view_supersample(Some(t0), t0, 3), 1);
        assert_eq!(gpu_view_supersample(Some(t0), soon, 3), 1);
        assert_eq!(gpu_view_supersample(Some(t0), soon, 1), 1);
    }

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
    fn a_segment_reaching_behind_the_eye_keeps_its_part_in_front() {
        let camera = OrbitCamera {
            target: Vec3::ZERO,
            yaw_deg: 0.0,
            pitch_deg: 0.0,
            distance: 5.0,
            ..OrbitCamera::default()
        };
        let proj = Projector::new(
            camera,
            egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(400.0, 300.0)),
        );
        // From 1 unit in front of the target to 10 units behind the eye (eye at z = 5).
        let (front, behind) = (Vec3::new(1.0, 0.5, 1.0), Vec3::new(1.0, 0.5, 15.0));
        assert!(proj.to_screen(behind).is_none());
        let [a, b] = proj
            .segment(front, behind)
            .expect("the part in front is drawn");
        assert_eq!(a, proj.to_screen(front).unwrap());
        assert!(
            b.x.is_finite() && b.y.is_finite() && b.x > a.x,
            "{a:?} {b:?}"
        );
        assert_eq!(proj.segment(behind, behind + Vec3::Z), None, "all behind");
        // Wholly in front: the plain projection.
        let p = Vec3::new(-1.0, 0.0, 0.0);
        assert_eq!(
            proj.segment(front, p),
            Some([proj.to_screen(front).unwrap(), proj.to_screen(p).unwrap()])
        );
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
    fn the_view_corner_names_what_a_drag_does_with_each_tool() {
        use super::{ToolKind, nav_hint};
        let hints: Vec<String> = ToolKind::ALL
            .iter()
            .map(|(t, _, _)| nav_hint(Some((*t, false)), false))
            .collect();
        // Each tool says something of its own, and none says the generic "sculpt".
        for (i, h) in hints.iter().enumerate() {
            assert!(!h.contains("sculpt"), "{h}");
            assert!(h.ends_with("Esc: navigate"), "{h}");
            assert!(hints[..i].iter().all(|o| o != h), "{h} repeated");
        }
        assert!(nav_hint(Some((ToolKind::Box, false)), false).starts_with("Drag: box"));
        assert!(nav_hint(Some((ToolKind::Brush, true)), true).starts_with("Drag: paint stretch"));
        assert!(nav_hint(None, true).contains("Click a joint dot: pose"));
        assert!(!nav_hint(None, false).contains("joint"));
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

    #[test]
    fn stretch_colours_run_blue_green_red_and_clamp() {
        use super::{STRETCH_SCALE_MAX, STRETCH_SCALE_MIN, stretch_color};
        let blue = stretch_color(STRETCH_SCALE_MIN);
        let green = stretch_color(1.0);
        let red = stretch_color(STRETCH_SCALE_MAX);
        assert!(blue.b() > blue.r() && blue.b() > blue.g());
        assert!(green.g() > green.r() && green.g() > green.b());
        assert!(red.r() > red.g() && red.r() > red.b());
        assert_eq!(stretch_color(0.01), blue);
        assert_eq!(stretch_color(99.0), red);
        assert_eq!(stretch_color(f32::NAN), red);
        // Between stops the colour moves monotonically toward the next one.
        assert!(stretch_color(1.4).r() > green.r());
    }
}

//! The central 3D view: the GPU image through [`crate::preview::viewport`], camera navigation (orbit,
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
use std::sync::Arc;

use glam::{Vec2, Vec3};
use thicket_core::scene::{Document, Object, ObjectKind, OrbitCamera, transform_bounds};

use super::krs_panel::{KrsPanel, paint_mirrors, paint_route, paint_zones, pick_mirror};
use super::overlay_lines::{OverlayDepth, grid};
pub use super::overlay_lines::{behind_voxels, unhidden_parts, unhidden_parts_by};
use super::pose::PoseTool;
pub use super::projector::{AxisView, Projector};
use super::sculpt::SculptTool;
use super::voxel_tools::{ToolKind, paint_volume};
use crate::editor::{Editor, Selection, SurfacePick, VoxelPick, ray_through};
use crate::preview::cpu::{CpuStatus, SELECTION_COLOR};
use crate::preview::frame_depth::FrameDepth;
use crate::preview::viewport::ViewportLink;
use crate::preview::{CpuPreview, Preview, PreviewSettings, RenderKey, render_key};
pub use crate::preview::{PREVIEW_MOTION_BUDGET_MS, ShadowWork, moving_scale};

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

/// Minimum and maximum corners.
type Aabb = (Vec3, Vec3);

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
    /// The image: the GPU view or the CPU preview.
    preview: Preview,
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
            show_stretch: false,
            preview: Preview::default(),
            bounds_cache: (((u64::MAX, u64::MAX), u64::MAX), HashMap::new()),
            auto_ortho: false,
            last_rect: egui::Rect::NOTHING,
            paste_target: None,
            last_pixels_per_point: 1.0,
            last_click: None,
            overlay_depth: OverlayDepth::default(),
        }
    }
}

impl View {
    /// Connects the GPU viewport.
    pub fn attach_gpu(&mut self, link: ViewportLink) {
        self.preview.gpu.attach(link);
    }

    /// The GPU viewport's link, when one is attached.
    #[must_use]
    pub fn gpu(&self) -> Option<&ViewportLink> {
        self.preview.gpu.link()
    }

    /// The CPU preview (its last render's statistics, the shown image's counts).
    #[must_use]
    pub fn cpu_preview(&self) -> &CpuPreview {
        &self.preview.cpu
    }

    /// Waits for the CPU preview render in flight, if any (tests; the UI polls instead); see
    /// [`CpuPreview::wait`].
    pub fn wait_for_cpu_preview(&mut self) {
        self.preview.cpu.wait();
    }

    /// The depth of the frame shown (see [`Preview::shown_depth`]).
    #[must_use]
    pub fn shown_depth(&self, editor: &Editor, cpu: bool) -> Option<FrameDepth> {
        self.preview.shown_depth(editor, cpu)
    }

    /// The document the shown image was drawn from (see [`Preview::shown_pose_document`]).
    #[must_use]
    pub fn shown_pose_document(&self, cpu: bool) -> Option<Arc<Document>> {
        self.preview.shown_pose_document(cpu)
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
                .and_then(|p| self.preview.cpu.hit(editor, rect, p));
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
        let settings = PreviewSettings {
            render_scale: self.render_scale,
            motion_budget_ms: self.motion_budget_ms,
            holes: self.show_holes,
            stretch: self.show_stretch,
            weights: self.show_weights,
            want_depth: self.show_grid || volume,
        };
        let silhouette = self.preview.show(ui, rect, editor, cpu, &settings);

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
            let frame = self.preview.shown_depth(editor, cpu);
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
        let shown = self.preview.shown_pose_document(cpu);
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
        let Some(gpu) = self.preview.gpu.link() else {
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
        let Some((id, node)) = self.preview.cpu.hit(editor, rect, pos) else {
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
            crate::preview::analysis::stretch_color(sculpt.stretch_factor)
        };
        painter.circle_stroke(
            pos,
            radius_px.clamp(2.0, 400.0),
            egui::Stroke::new(2.0, color),
        );
    }

    /// The size in pixels the view renders at (its last rectangle, the display's scale and the
    /// render scale): what the Trade-off sweep measures by default. Not finite before the view
    /// was first drawn.
    #[must_use]
    pub fn render_size_px(&self) -> egui::Vec2 {
        self.last_rect.size() * self.last_pixels_per_point * self.render_scale
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
            let (text, color) = match self.preview.cpu.status() {
                CpuStatus::Error(e) => (
                    format!("CPU preview: {e}\nThe document is still editable and saveable."),
                    ui.visuals().error_fg_color,
                ),
                CpuStatus::Shown {
                    size_px,
                    supersample,
                    refining,
                } => (
                    format!(
                        "{view_name}   CPU preview {} x {} px{}{} ({}){}\n{hint}",
                        size_px[0],
                        size_px[1],
                        if supersample > 1 {
                            format!(", {supersample}×{supersample} samples")
                        } else {
                            String::new()
                        },
                        if refining { ", refining" } else { "" },
                        self.cpu_reason_text(editor),
                        match (self.show_holes, self.preview.cpu.hole_counts()) {
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
                CpuStatus::Rendering => (
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
        let Some(link) = self.preview.gpu.link() else {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}

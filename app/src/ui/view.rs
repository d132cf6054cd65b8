//! The central 3D view: the GPU image through [`crate::viewport`], camera navigation (orbit,
//! pan, zoom with mouse and trackpad; axis views; frame selection), overlays (ground grid,
//! world axes, the selected object's outline box, the brush preview) and sculpt strokes.
//!
//! Without a GPU (no wgpu render state, as in the plain UI tests) the view still navigates and
//! draws the overlays, and says that no renderer is attached.

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Vec2, Vec3};
use thicket_core::scene::{Document, Object, ObjectKind, OrbitCamera};

use super::sculpt::SculptTool;
use crate::editor::{Editor, Selection, VoxelPick, ray_through};
use crate::viewport::{FrameKey, ViewportCallback, ViewportLink, paint_callback};

/// Minimum and maximum corners.
type Aabb = (Vec3, Vec3);

/// Degrees of orbit per dragged point.
const ORBIT_DEG_PER_POINT: f32 = 0.4;

/// A named axis view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisView {
    /// Looking along -Z (from +Z).
    Front,
    /// Looking along +Z.
    Back,
    /// Looking along -X (from +X).
    Right,
    /// Looking along +X.
    Left,
    /// Looking down.
    Top,
    /// Looking up.
    Bottom,
}

impl AxisView {
    /// All views with their menu labels and keys.
    pub const ALL: [(AxisView, &'static str, &'static str); 6] = [
        (AxisView::Front, "Front", "1"),
        (AxisView::Back, "Back", "Ctrl+1"),
        (AxisView::Right, "Right", "3"),
        (AxisView::Left, "Left", "Ctrl+3"),
        (AxisView::Top, "Top", "7"),
        (AxisView::Bottom, "Bottom", "Ctrl+7"),
    ];

    /// (yaw, pitch) in degrees.
    #[must_use]
    pub fn angles(self) -> (f32, f32) {
        match self {
            AxisView::Front => (0.0, 0.0),
            AxisView::Back => (180.0, 0.0),
            AxisView::Right => (90.0, 0.0),
            AxisView::Left => (270.0, 0.0),
            AxisView::Top => (0.0, 90.0),
            AxisView::Bottom => (0.0, -90.0),
        }
    }
}

/// The view's state.
pub struct View {
    /// Draw the ground grid and world axes.
    pub show_grid: bool,
    /// Draw every object's bounding box (the selection's is always drawn).
    pub show_bounds: bool,
    /// Fraction of the view's pixels the renderer draws (lower is faster on slow adapters).
    pub render_scale: f32,
    gpu: Option<ViewportLink>,
    /// The document as the renderer sees it, for one content key (cloned when it changes).
    snapshot: Option<((u64, u64), Arc<Document>)>,
    /// Object-space bounds by object id, for one content key (bounds visit every voxel).
    bounds_cache: ((u64, u64), HashMap<u64, Option<Aabb>>),
    /// The last view rectangle (for tests that aim at it).
    pub last_rect: egui::Rect,
}

impl Default for View {
    fn default() -> Self {
        Self {
            show_grid: true,
            show_bounds: false,
            render_scale: 1.0,
            gpu: None,
            snapshot: None,
            bounds_cache: ((u64::MAX, u64::MAX), HashMap::new()),
            last_rect: egui::Rect::NOTHING,
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
            .on_hover_text("Draw the ground grid and the world axes over the view");
        ui.checkbox(&mut self.show_bounds, "All bounding boxes")
            .on_hover_text("Draw every object's bounding box (the selection's is always drawn)");
        ui.separator();
        ui.label("Axis views");
        for (view, label, key) in AxisView::ALL {
            if ui
                .add(egui::Button::new(label).shortcut_text(key))
                .on_hover_text(format!(
                    "Look at the scene from the {}",
                    label.to_lowercase()
                ))
                .clicked()
            {
                set_axis_view(editor, view);
            }
        }
    }

    /// Entries for the Render menu.
    pub fn render_menu_ui(&mut self, ui: &mut egui::Ui) {
        ui.label("Viewport resolution");
        ui.horizontal(|ui| {
            for (scale, label) in [(1.0_f32, "100%"), (0.5, "50%"), (0.25, "25%")] {
                ui.selectable_value(&mut self.render_scale, scale, label)
                    .on_hover_text(
                        "Render the view at this fraction of its pixels (faster on slow GPUs)",
                    );
            }
        });
    }

    /// Draws the view, handles navigation and sculpting.
    pub fn ui(&mut self, ui: &mut egui::Ui, editor: &mut Editor, sculpt: &mut SculptTool) {
        let rect = ui.available_rect_before_wrap();
        self.last_rect = rect;
        // No tooltip over the view (it would cover the scene); the hint is in the corner text.
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        let aspect = rect.aspect_ratio().max(1e-3);

        // Where the pointer points in the scene (for the brush and for picking).
        let pointer_ray = response.hover_pos().and_then(|p| {
            let ndc = Vec2::new(
                (p.x - rect.left()) / rect.width() * 2.0 - 1.0,
                1.0 - (p.y - rect.top()) / rect.height() * 2.0,
            );
            ray_through(editor.doc().camera.clip_from_world(aspect), ndc)
        });
        let hover_pick = pointer_ray.and_then(|(o, d)| editor.pick_voxel(o, d));

        let navigating = self.navigate(ui, &response, editor, sculpt.active, rect);
        if sculpt.active && !navigating {
            sculpt.handle(&response, editor, hover_pick);
        } else if response.clicked() {
            // Click to select what is under the pointer (or nothing).
            editor.selection = hover_pick.map(|p| Selection::Object(p.object));
        }

        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, srgb_color(editor.doc().background));
        self.gpu_image(ui, rect, editor);

        let camera = editor.doc().camera;
        let clip_from_world = camera.clip_from_world(aspect);
        let to_screen = |p: Vec3| -> Option<egui::Pos2> {
            let clip = clip_from_world * p.extend(1.0);
            if clip.w <= camera.near * 0.5 {
                return None;
            }
            let ndc = clip.truncate() / clip.w;
            Some(egui::pos2(
                rect.left() + (ndc.x * 0.5 + 0.5) * rect.width(),
                rect.top() + (0.5 - ndc.y * 0.5) * rect.height(),
            ))
        };
        let line = |a: Vec3, b: Vec3, stroke: egui::Stroke| {
            if let (Some(pa), Some(pb)) = (to_screen(a), to_screen(b)) {
                painter.line_segment([pa, pb], stroke);
            }
        };
        if self.show_grid {
            grid(&camera, &line);
        }
        self.outlines(editor, &line, &to_screen, &painter);
        if sculpt.active
            && let Some(pick) = hover_pick
        {
            brush_preview(&painter, &to_screen, &camera, &pick, sculpt);
        }
        self.status_text(ui, rect, editor, sculpt.active);
    }

    /// Orbit / pan / zoom. Returns whether the pointer is navigating (not sculpting).
    fn navigate(
        &self,
        ui: &egui::Ui,
        response: &egui::Response,
        editor: &mut Editor,
        sculpting: bool,
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
        // With the sculpt tool the primary button sculpts; Alt turns it back into orbit.
        let primary_navigates = !sculpting || modifiers.alt;
        let navigating =
            response.dragged() && (middle || secondary || (primary && primary_navigates));
        if navigating {
            let d = response.drag_delta();
            if modifiers.shift || secondary {
                pan(&mut camera, d, rect.height());
            } else {
                camera.yaw_deg = (camera.yaw_deg - d.x * ORBIT_DEG_PER_POINT).rem_euclid(360.0);
                camera.pitch_deg =
                    (camera.pitch_deg + d.y * ORBIT_DEG_PER_POINT).clamp(-90.0, 90.0);
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
                }
            }
            if (zoom - 1.0).abs() > 1e-6 {
                camera.distance = (camera.distance * zoom).clamp(1e-3, 1e6);
                // Keep the clip range around what is being looked at.
                camera.far = camera.far.max(camera.distance * 4.0);
                camera.near = camera.near.min(camera.distance * 0.5).max(1e-4);
            }
        }
        editor.set_camera(camera);
        navigating
    }

    fn gpu_image(&mut self, ui: &egui::Ui, rect: egui::Rect, editor: &Editor) {
        if self.gpu.is_none() {
            return;
        }
        let key = editor.content_key();
        if self.snapshot.as_ref().is_none_or(|(k, _)| *k != key) {
            // The renderer reads the document in `prepare`, after this frame's UI: it gets its
            // own copy, made only when the content changed (a dab, an edit, undo).
            self.snapshot = Some((key, Arc::new(editor.doc().clone())));
        }
        let Some((_, doc)) = &self.snapshot else {
            return;
        };
        let ppp = ui.ctx().pixels_per_point();
        let size = rect.size() * ppp * self.render_scale;
        let size_px = [
            (size.x.round() as u32).max(1),
            (size.y.round() as u32).max(1),
        ];
        ui.painter().add(paint_callback(
            rect,
            ViewportCallback {
                key: FrameKey {
                    content: key,
                    camera: editor.doc().camera,
                    size_px,
                },
                doc: Arc::clone(doc),
            },
        ));
    }

    fn outlines(
        &mut self,
        editor: &Editor,
        line: &impl Fn(Vec3, Vec3, egui::Stroke),
        to_screen: &impl Fn(Vec3) -> Option<egui::Pos2>,
        painter: &egui::Painter,
    ) {
        if self.bounds_cache.0 != editor.content_key() {
            self.bounds_cache = (editor.content_key(), HashMap::new());
        }
        for o in &editor.doc().objects {
            let selected = editor.selection == Some(Selection::Object(o.id));
            if !o.visible || !(selected || self.show_bounds) {
                continue;
            }
            let local = *self
                .bounds_cache
                .1
                .entry(o.id)
                .or_insert_with(|| local_bounds(o));
            let Some((lo, hi)) = local else { continue };
            let stroke = if selected {
                egui::Stroke::new(2.0, egui::Color32::from_rgb(255, 170, 60))
            } else {
                egui::Stroke::new(1.0, egui::Color32::from_gray(200))
            };
            oriented_box_lines(o, lo, hi, stroke, line);
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

    fn status_text(&self, ui: &egui::Ui, rect: egui::Rect, editor: &Editor, sculpt_active: bool) {
        let painter = ui.painter_at(rect);
        let origin = rect.left_top() + egui::vec2(8.0, 8.0);
        let weak = ui.visuals().weak_text_color();
        let font = egui::FontId::proportional(12.0);
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
        let hint = if sculpt_active {
            "Drag: sculpt   Alt/middle-drag: orbit   Shift: pan   Scroll: zoom   Esc: navigate"
        } else {
            "Drag: orbit   Shift/right-drag: pan   Scroll: zoom   F: frame   S: sculpt   F3: stats"
        };
        let text = match &status.stats {
            // Timings are in the performance overlay (F3): this line stays stable for snapshots.
            Some(s) => format!(
                "{} x {} px, {} splats   yaw {:.0} pitch {:.0} dist {:.2}",
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

/// Points the camera along an axis, keeping target and distance.
pub fn set_axis_view(editor: &mut Editor, view: AxisView) {
    let mut camera = editor.doc().camera;
    (camera.yaw_deg, camera.pitch_deg) = view.angles();
    editor.set_camera(camera);
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
        ObjectKind::Voxels(v) => v.bounds(),
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

/// A ground grid on y = 0 around the camera target, spaced by a power of ten that suits the
/// viewing distance, and the world axes.
fn grid(camera: &OrbitCamera, line: &impl Fn(Vec3, Vec3, egui::Stroke)) {
    let spacing = 10f32.powf((camera.distance * 0.2).max(1e-6).log10().floor());
    let n = 10i32;
    let cx = (camera.target.x / spacing).round() * spacing;
    let cz = (camera.target.z / spacing).round() * spacing;
    let stroke = egui::Stroke::new(1.0, egui::Color32::from_white_alpha(28));
    let half = n as f32 * spacing;
    for i in -n..=n {
        let o = i as f32 * spacing;
        line(
            Vec3::new(cx + o, 0.0, cz - half),
            Vec3::new(cx + o, 0.0, cz + half),
            stroke,
        );
        line(
            Vec3::new(cx - half, 0.0, cz + o),
            Vec3::new(cx + half, 0.0, cz + o),
            stroke,
        );
    }
    let axis_len = spacing * 2.0;
    for (dir, color) in [
        (Vec3::X, egui::Color32::from_rgb(220, 70, 70)),
        (Vec3::Y, egui::Color32::from_rgb(70, 200, 70)),
        (Vec3::Z, egui::Color32::from_rgb(70, 120, 230)),
    ] {
        line(Vec3::ZERO, dir * axis_len, egui::Stroke::new(2.0, color));
    }
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

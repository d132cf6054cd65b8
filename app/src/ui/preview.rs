//! The central view. The GPU viewport and the CPU reference render are not in this build yet,
//! so the view draws what it can from the document itself: a ground grid, the world axes and
//! every object's world bounding box through the document's camera, with orbit (drag),
//! zoom (scroll) and frame (F) acting on that camera; and a summary of the scene.

use std::collections::HashMap;

use glam::Vec3;
use thicket_core::scene::{Object, ObjectKind, OrbitCamera};

use crate::editor::{Editor, Selection};

/// Minimum and maximum corners.
type Aabb = (Vec3, Vec3);

/// View options.
#[derive(Debug)]
pub struct Preview {
    show_bounds: bool,
    show_grid: bool,
    /// Object-space bounds by object id, for one document content (bounds visit every voxel).
    bounds_cache: ((u64, u64), HashMap<u64, Option<Aabb>>),
}

impl Default for Preview {
    fn default() -> Self {
        Self {
            show_bounds: true,
            show_grid: true,
            bounds_cache: ((u64::MAX, u64::MAX), HashMap::new()),
        }
    }
}

/// Degrees of orbit per dragged point.
const ORBIT_DEG_PER_POINT: f32 = 0.4;

impl Preview {
    /// Entries for the Render menu.
    pub fn menu_ui(&mut self, ui: &mut egui::Ui) {
        ui.checkbox(&mut self.show_bounds, "Bounding boxes")
            .on_hover_text("Draw each object's world bounding box in the view");
        ui.checkbox(&mut self.show_grid, "Ground grid")
            .on_hover_text("Draw the ground grid and the world axes");
    }

    /// Draws the view and applies orbit / zoom to the document camera.
    pub fn ui(&mut self, ui: &mut egui::Ui, editor: &mut Editor) {
        let rect = ui.available_rect_before_wrap();
        let response = ui
            .allocate_rect(rect, egui::Sense::click_and_drag())
            .on_hover_text("Drag to orbit, scroll to zoom, F to frame the selection");
        let mut camera = editor.doc().camera;
        if response.dragged() {
            let d = response.drag_delta();
            camera.yaw_deg = (camera.yaw_deg - d.x * ORBIT_DEG_PER_POINT).rem_euclid(360.0);
            camera.pitch_deg = (camera.pitch_deg + d.y * ORBIT_DEG_PER_POINT).clamp(-89.0, 89.0);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                camera.distance = (camera.distance * (-scroll * 0.002).exp()).clamp(1e-3, 1e6);
                // Keep the clip range around what is being looked at.
                camera.far = camera.far.max(camera.distance * 4.0);
                camera.near = camera.near.min(camera.distance * 0.5).max(1e-4);
            }
        }
        editor.set_camera(camera);

        let painter = ui.painter_at(rect);
        let bg = editor.doc().background;
        painter.rect_filled(rect, 0.0, srgb_color(bg));
        let camera = editor.doc().camera;
        let clip_from_world = camera.clip_from_world(rect.aspect_ratio().max(1e-3));
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
        if self.show_bounds {
            if self.bounds_cache.0 != editor.content_key() {
                self.bounds_cache = (editor.content_key(), HashMap::new());
            }
            for o in &editor.doc().objects {
                if !o.visible {
                    continue;
                }
                let local = *self
                    .bounds_cache
                    .1
                    .entry(o.id)
                    .or_insert_with(|| local_bounds(o));
                let Some((lo, hi)) = local.map(|(lo, hi)| world_box(o, lo, hi)) else {
                    continue;
                };
                let selected = editor.selection == Some(Selection::Object(o.id));
                let stroke = if selected {
                    egui::Stroke::new(2.0, egui::Color32::from_rgb(255, 170, 60))
                } else {
                    egui::Stroke::new(1.0, egui::Color32::from_gray(200))
                };
                box_lines(lo, hi, stroke, &line);
                if let Some(p) = to_screen(hi) {
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
        self.summary_ui(ui, rect, editor);
    }

    fn summary_ui(&self, ui: &mut egui::Ui, rect: egui::Rect, editor: &Editor) {
        let c = editor.doc().camera;
        let text = format!(
            "Preview: bounds and grid (the rendered viewport is being connected; meanwhile `thicket render` draws it)\n\
             camera yaw {:.1}°, pitch {:.1}°, distance {:.3}, target {:.2} {:.2} {:.2}",
            c.yaw_deg, c.pitch_deg, c.distance, c.target.x, c.target.y, c.target.z
        );
        ui.painter_at(rect).text(
            rect.left_top() + egui::vec2(8.0, 8.0),
            egui::Align2::LEFT_TOP,
            text,
            egui::FontId::proportional(12.0),
            ui.visuals().weak_text_color(),
        );
    }
}

fn local_bounds(o: &Object) -> Option<(Vec3, Vec3)> {
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

/// The world-space box around an object-space box.
fn world_box(o: &Object, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
    let m = o.transform.matrix();
    let mut out = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for k in 0..8u32 {
        let c = Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let p = m.transform_point3(c);
        out = (out.0.min(p), out.1.max(p));
    }
    out
}

fn srgb_color(linear: Vec3) -> egui::Color32 {
    let c = |v: f32| (thicket_core::mesh::linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8;
    egui::Color32::from_rgb(c(linear.x), c(linear.y), c(linear.z))
}

fn box_lines(lo: Vec3, hi: Vec3, stroke: egui::Stroke, line: &impl Fn(Vec3, Vec3, egui::Stroke)) {
    let corner = |k: u32| {
        Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        )
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
    let stroke = egui::Stroke::new(1.0, egui::Color32::from_gray(70));
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

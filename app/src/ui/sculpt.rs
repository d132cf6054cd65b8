//! The sculpt tool: brush settings in the tool bar and continuous strokes in the view.
//!
//! A stroke starts when the primary button goes down on a voxel model and ends when it goes
//! up; its dabs are one undo step. Dabs are spaced along the pointer's path at a fraction of
//! the brush radius, so a fast drag leaves a continuous trail.

use glam::Vec3;
use thicket_core::sculpt::{Brush, BrushOp, BrushShape, MAX_RADIUS};

use crate::editor::{Editor, Selection, VoxelPick};

/// Distance between dabs along a stroke, as a fraction of the brush radius.
const DAB_SPACING: f32 = 0.5;

/// Most dabs one frame may add (a huge jump of the pointer must not stall the UI).
const MAX_DABS_PER_FRAME: usize = 64;

/// The default palette (sRGB).
pub const PALETTE: [[u8; 4]; 12] = [
    [200, 200, 200, 255],
    [90, 90, 90, 255],
    [30, 30, 30, 255],
    [176, 58, 46, 255],
    [230, 126, 34, 255],
    [241, 196, 15, 255],
    [88, 141, 56, 255],
    [39, 95, 60, 255],
    [52, 152, 219, 255],
    [41, 64, 140, 255],
    [125, 80, 50, 255],
    [222, 184, 135, 255],
];

#[derive(Debug, Clone, Copy)]
struct Stroke {
    object: u64,
    symmetry_center: Vec3,
    last_center: Vec3,
}

/// The sculpt tool's settings and the stroke in progress.
#[derive(Debug, Clone)]
pub struct SculptTool {
    /// Whether the tool is active (otherwise the primary button orbits).
    pub active: bool,
    /// The brush.
    pub brush: Brush,
    stroke: Option<Stroke>,
    /// The last refused dab, shown in the tool bar.
    pub error: Option<String>,
    /// Paint per-voxel stretch overrides of rigged models instead of sculpting.
    pub stretch_paint: bool,
    /// The override factor the stretch brush paints.
    pub stretch_factor: f32,
    /// The stretch brush erases overrides instead.
    pub stretch_erase: bool,
    /// The stretch stroke in progress: object and the last node painted.
    stretch_stroke: Option<(u64, u64)>,
}

impl Default for SculptTool {
    fn default() -> Self {
        Self {
            active: false,
            brush: Brush {
                radius: 2.0,
                ..Brush::default()
            },
            stroke: None,
            error: None,
            stretch_paint: false,
            stretch_factor: 2.0,
            stretch_erase: false,
            stretch_stroke: None,
        }
    }
}

impl SculptTool {
    /// Whether a stroke is in progress.
    #[must_use]
    pub fn stroking(&self) -> bool {
        self.stroke.is_some()
    }

    /// Starts, continues or ends a stroke from the view's pointer response and the voxel under
    /// the pointer.
    pub fn handle(
        &mut self,
        response: &egui::Response,
        editor: &mut Editor,
        pick: Option<VoxelPick>,
    ) {
        let down = response.is_pointer_button_down_on()
            && response.ctx.input(|i| i.pointer.primary_down());
        if !down {
            self.stroke = None;
            return;
        }
        let Some(pick) = pick else { return };
        let target = pick.dab_center(self.brush.op);
        match self.stroke {
            None => {
                editor.begin_stroke();
                editor.selection = Some(Selection::Object(pick.object));
                let symmetry_center = editor.voxel_center(pick.object).unwrap_or(target);
                self.stroke = Some(Stroke {
                    object: pick.object,
                    symmetry_center,
                    last_center: target,
                });
                self.dab(editor, pick.object, target, symmetry_center);
            }
            Some(mut s) if s.object == pick.object => {
                // Dabs at even spacing from the last dab to the pointer.
                let step = (self.brush.radius * DAB_SPACING).max(0.5);
                let dist = s.last_center.distance(target);
                let n = ((dist / step).floor() as usize).min(MAX_DABS_PER_FRAME);
                for k in 1..=n {
                    let c = s
                        .last_center
                        .lerp(target, (k as f32 * step / dist).min(1.0));
                    self.dab(editor, s.object, c, s.symmetry_center);
                    s.last_center = c;
                }
                self.stroke = Some(s);
            }
            // The pointer moved onto another object: the stroke stays on its own object.
            Some(_) => {}
        }
    }

    /// Starts, continues or ends a stretch-paint stroke from the view's pointer response and
    /// what the preview shows under the pointer: a rigged object and the node id of its pixel
    /// (so the brush lands where the posed model is drawn). One undo step per stroke.
    pub fn handle_stretch(
        &mut self,
        response: &egui::Response,
        editor: &mut Editor,
        hit: Option<(u64, u64)>,
    ) {
        let down = response.is_pointer_button_down_on()
            && response.ctx.input(|i| i.pointer.primary_down());
        if !down {
            self.stretch_stroke = None;
            return;
        }
        let Some((object, node)) = hit else { return };
        match self.stretch_stroke {
            None => {
                editor.begin_stroke();
                editor.selection = Some(Selection::Object(object));
            }
            Some((o, last)) if o == object && last != node => {}
            // Same node again, or another object: the stroke stays where it is.
            Some(_) => return,
        }
        self.stretch_stroke = Some((object, node));
        let Some(center) = editor.node_center(object, node) else {
            return;
        };
        let factor = (!self.stretch_erase).then_some(self.stretch_factor);
        match editor.paint_stretch(object, center, self.brush.radius, factor) {
            Ok(_) => self.error = None,
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    fn dab(&mut self, editor: &mut Editor, object: u64, center: Vec3, symmetry_center: Vec3) {
        match editor.sculpt_dab(object, &self.brush, center, symmetry_center) {
            Ok(_) => self.error = None,
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// The tool bar: tool choice and, with the sculpt tool, the brush settings.
    pub fn toolbar_ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal_wrapped(|ui| {
            ui.selectable_value(&mut self.active, false, "Navigate")
                .on_hover_text("Drag orbits, Shift+drag pans, scroll zooms (Esc)");
            ui.selectable_value(&mut self.active, true, "Sculpt")
                .on_hover_text("Drag on a voxel model to sculpt it (S); Alt+drag orbits");
            if !self.active {
                return;
            }
            ui.separator();
            for (op, label, tip) in [
                (BrushOp::Add, "Add", "Fill voxels in front of the surface"),
                (BrushOp::Remove, "Remove", "Carve voxels away"),
                (BrushOp::Paint, "Paint", "Blend the colour of solid voxels toward the brush colour"),
                (BrushOp::Smooth, "Smooth", "Remove lone voxels and fill small gaps"),
            ] {
                if ui
                    .selectable_label(!self.stretch_paint && self.brush.op == op, label)
                    .on_hover_text(tip)
                    .clicked()
                {
                    self.brush.op = op;
                    self.stretch_paint = false;
                }
            }
            if ui
                .selectable_label(self.stretch_paint, "Stretch paint")
                .on_hover_text(
                    "Paint per-voxel stretch overrides on a rigged model where the view shows it (CPU preview); one undo step per stroke, saved with the project",
                )
                .clicked()
            {
                self.stretch_paint = true;
            }
            ui.separator();
            if self.stretch_paint {
                ui.label("Size");
                ui.add(
                    egui::DragValue::new(&mut self.brush.radius)
                        .range(0.5..=MAX_RADIUS.min(64.0))
                        .speed(0.1)
                        .suffix(" vox"),
                )
                .on_hover_text("Stretch brush radius in voxels ([ and ] change it)");
                ui.label("Factor");
                ui.add_enabled(
                    !self.stretch_erase,
                    egui::DragValue::new(&mut self.stretch_factor)
                        .range(1.0 / 64.0..=crate::editor::MAX_STRETCH_OVERRIDE)
                        .speed(0.01),
                )
                .on_hover_text(
                    "Stretch factor painted into each voxel (replaces the strategy's factor there; steps of 1/64, up to 3.98)",
                );
                ui.toggle_value(&mut self.stretch_erase, "Erase")
                    .on_hover_text("Remove painted overrides: the strategy's factor applies again");
                if let Some(e) = &self.error {
                    ui.colored_label(ui.visuals().error_fg_color, e);
                }
                return;
            }
            ui.selectable_value(&mut self.brush.shape, BrushShape::Sphere, "Sphere")
                .on_hover_text("Round brush");
            ui.selectable_value(&mut self.brush.shape, BrushShape::Cube, "Cube")
                .on_hover_text("Square brush");
            ui.separator();
            ui.label("Size");
            ui.add(
                egui::DragValue::new(&mut self.brush.radius)
                    .range(0.5..=MAX_RADIUS)
                    .speed(0.1)
                    .suffix(" vox"),
            )
            .on_hover_text("Brush radius in voxels ([ and ] change it)");
            ui.label("Strength");
            ui.add(
                egui::DragValue::new(&mut self.brush.strength)
                    .range(0.0..=1.0)
                    .speed(0.01),
            )
            .on_hover_text("Paint: how far the colour moves toward the brush colour per dab; Smooth: how aggressively");
            ui.separator();
            let mut c = egui::Color32::from_rgba_unmultiplied(
                self.brush.color[0],
                self.brush.color[1],
                self.brush.color[2],
                255,
            );
            if ui
                .color_edit_button_srgba(&mut c)
                .on_hover_text("Brush colour (Add and Paint)")
                .changed()
            {
                self.brush.color = [c.r(), c.g(), c.b(), 255];
            }
            for (i, p) in PALETTE.iter().enumerate() {
                let color = egui::Color32::from_rgb(p[0], p[1], p[2]);
                let selected = self.brush.color == *p;
                let (rect, resp) =
                    ui.allocate_exact_size(egui::vec2(14.0, 14.0), egui::Sense::click());
                ui.painter().rect_filled(rect, 2.0, color);
                if selected {
                    ui.painter().rect_stroke(
                        rect,
                        2.0,
                        egui::Stroke::new(2.0, egui::Color32::WHITE),
                        egui::StrokeKind::Outside,
                    );
                }
                if resp
                    .on_hover_text(format!("Palette colour {}", i + 1))
                    .clicked()
                {
                    self.brush.color = *p;
                }
            }
            ui.separator();
            // Wrap the whole group to the next row when it does not fit, instead of leaving
            // an axis behind (about the label and three toggles).
            let row_left = ui.max_rect().right() - ui.cursor().min.x;
            if row_left < 4.0 * ui.spacing().interact_size.x {
                ui.end_row();
            }
            ui.label("Mirror");
            for (axis, label) in ["X", "Y", "Z"].into_iter().enumerate() {
                ui.toggle_value(&mut self.brush.symmetry[axis], label)
                    .on_hover_text(format!(
                        "Mirror each dab across the model's centre along {label}"
                    ));
            }
            if let Some(e) = &self.error {
                ui.colored_label(ui.visuals().error_fg_color, e);
            }
        });
    }
}

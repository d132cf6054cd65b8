//! The sculpt tool: brush settings in the tool bar and continuous strokes in the view.
//!
//! A stroke starts when the primary button goes down on a voxel model and ends when it goes
//! up; its dabs are one undo step. Dabs are spaced along the pointer's path at a fraction of
//! the brush radius, so a fast drag leaves a continuous trail. Where a KRS object is nearer
//! than any voxel, the brush aims at its surface and places voxels of the selected voxel model
//! there ([`Editor::pick_brush`]).

use glam::Vec3;
use thicket_core::sculpt::shapes::{Ink, Mirror, ShapeOp};
use thicket_core::sculpt::{Brush, BrushOp, BrushShape, MAX_RADIUS};

use super::voxel_tools::{ClickSelect, ToolKind, VoxelTools};
use crate::editor::{Editor, Selection, VoxelPick};

/// The brush radius after `[` (`grow` false) or `]` (`grow` true): whole voxels, one voxel per
/// press (Shift: halve / double), from a single voxel (radius 0.5) up to [`MAX_RADIUS`].
#[must_use]
pub fn step_brush_radius(radius: f32, grow: bool, double: bool) -> f32 {
    let r = if !radius.is_finite() { 0.5 } else { radius };
    let next = match (grow, double) {
        (true, false) => r.floor() + 1.0,
        (false, false) => r.ceil() - 1.0,
        (true, true) => (r.max(0.5) * 2.0).round(),
        (false, true) => (r * 0.5).round(),
    };
    next.clamp(0.5, MAX_RADIUS)
}

/// Distance between dabs along a stroke, as a fraction of the brush radius.
const DAB_SPACING: f32 = 0.5;

/// Most dabs one frame may add (a huge jump of the pointer must not stall the UI).
const MAX_DABS_PER_FRAME: usize = 64;

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
    /// Which voxel tool the primary button uses while active.
    pub tool: ToolKind,
    /// The shape and select tools' settings and gesture.
    pub voxel: VoxelTools,
    /// The brush (its colour, material and mirror axes are shared by every tool).
    pub brush: Brush,
    stroke: Option<Stroke>,
    /// The last refused dab, shown in the tool bar.
    pub error: Option<String>,
    /// What the last tool edit did (the status bar shows it).
    pub status: Option<String>,
    /// Paint per-voxel stretch overrides of rigged models instead of sculpting.
    pub stretch_paint: bool,
    /// The override factor the stretch brush paints.
    pub stretch_factor: f32,
    /// The stretch brush erases overrides instead.
    pub stretch_erase: bool,
    /// The stretch stroke in progress: object and the last node painted.
    stretch_stroke: Option<(u64, u64)>,
    /// The colour controls of the tool bar.
    colors: super::palette::ColorBar,
}

impl Default for SculptTool {
    fn default() -> Self {
        Self {
            active: false,
            tool: ToolKind::Brush,
            voxel: VoxelTools::default(),
            brush: Brush {
                radius: 2.0,
                ..Brush::default()
            },
            stroke: None,
            error: None,
            status: None,
            stretch_paint: false,
            stretch_factor: 2.0,
            stretch_erase: false,
            stretch_stroke: None,
            colors: super::palette::ColorBar::default(),
        }
    }
}

impl SculptTool {
    /// Whether a stroke is in progress.
    #[must_use]
    pub fn stroking(&self) -> bool {
        self.stroke.is_some()
    }

    /// The ink of the shape tools: the brush colour and material.
    #[must_use]
    pub fn ink(&self) -> Ink {
        Ink {
            color: self.brush.color,
            material: self.brush.material,
        }
    }

    /// The mirror axes, for the shape tools (across the model's volume centre).
    #[must_use]
    pub fn mirror(&self) -> Mirror {
        Mirror {
            axes: self.brush.symmetry,
        }
    }

    /// Chooses a tool and activates it (the tool bar and the tool keys).
    pub fn choose(&mut self, tool: ToolKind) {
        self.active = true;
        self.stretch_paint = false;
        self.voxel.cancel();
        self.tool = tool;
    }

    /// Sets the operation of the current tool: for the brush its op, for the shape tools Add,
    /// Remove or Paint.
    pub fn set_op(&mut self, op: ShapeOp) {
        self.stretch_paint = false;
        if self.tool == ToolKind::Brush {
            self.brush.op = match op {
                ShapeOp::Add => BrushOp::Add,
                ShapeOp::Remove => BrushOp::Remove,
                ShapeOp::Paint => BrushOp::Paint,
            };
        } else {
            self.voxel.op = op;
        }
    }

    /// One line for the status bar: tool, mode and mirror axes.
    #[must_use]
    pub fn state_line(&self) -> String {
        if !self.active {
            return "Navigate".into();
        }
        if self.stretch_paint {
            return "Stretch paint".into();
        }
        let op = if self.tool == ToolKind::Brush {
            format!("{:?}", self.brush.op)
        } else {
            format!("{:?}", self.voxel.op)
        };
        let mirror: String = ["X", "Y", "Z"]
            .iter()
            .zip(self.brush.symmetry)
            .filter(|(_, on)| *on)
            .map(|(a, _)| *a)
            .collect();
        let mirror = if mirror.is_empty() {
            String::new()
        } else {
            format!(" · mirror {mirror}")
        };
        match self.tool {
            ToolKind::Select => "Select".into(),
            ToolKind::Brush => format!(
                "Brush {:?} · {op} · {:.1} vox{mirror}",
                self.brush.shape, self.brush.radius
            ),
            t => format!("{} · {op}{mirror}", t.label()),
        }
    }

    /// Runs the active tool for this frame: Alt+click picks the colour under the pointer (the
    /// eyedropper), the brush strokes at `brush_pick` (the target the view found for its brush
    /// preview this frame, [`Editor::pick_brush`]), the other tools run their gestures.
    pub fn handle_tools(
        &mut self,
        response: &egui::Response,
        editor: &mut Editor,
        ray: Option<(Vec3, Vec3)>,
        brush_pick: Option<VoxelPick>,
        proj: &super::projector::Projector,
    ) {
        let alt_click = response.clicked() && response.ctx.input(|i| i.modifiers.alt);
        if alt_click {
            if let Some(color) = ray
                .and_then(|(o, d)| editor.pick_voxel(o, d))
                .and_then(|p| editor.voxel_at(p.object, p.voxel))
                .map(|v| v.color)
            {
                self.brush.color = color;
                self.status = Some(format!(
                    "Picked colour #{:02x}{:02x}{:02x}",
                    color[0], color[1], color[2]
                ));
            }
            return;
        }
        if self.tool == ToolKind::Brush {
            self.handle(response, editor, brush_pick);
            return;
        }
        let input = super::voxel_tools::ToolInput {
            response,
            ray,
            proj,
            ink: self.ink(),
            mirror: self.mirror(),
        };
        match self.voxel.handle(self.tool, &input, editor) {
            Some(Ok(m)) => {
                self.error = None;
                self.status = Some(m);
            }
            Some(Err(e)) => self.error = Some(e),
            None => {}
        }
    }

    /// The voxel model whose voxels the brush places where the pointer is over a KRS surface
    /// (nearer than any voxel): the model of the stroke in progress, else the selected voxel
    /// model. `None` (no voxel model selected): the brush reaches voxels only.
    #[must_use]
    pub fn brush_onto(&self, editor: &Editor) -> Option<u64> {
        if let Some(s) = &self.stroke {
            return Some(s.object);
        }
        match editor.selection {
            Some(Selection::Object(id))
                if editor.object(id).is_some_and(|o| {
                    matches!(o.kind, thicket_core::scene::ObjectKind::Voxels(_))
                }) =>
            {
                Some(id)
            }
            _ => None,
        }
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

    /// The tool bar in two rows. The first never changes with the tool, so nothing in it
    /// moves: the tools and the colour (button, hex entry, 256-colour grid and the selected
    /// model's own colours as swatches). The second starts with the mirror axes, then the
    /// chosen tool's options and the last refusal.
    pub fn toolbar_ui(&mut self, ui: &mut egui::Ui, editor: &Editor) {
        // Wrapped only in a window too narrow for it (under about 950 points), the same for
        // every tool.
        ui.horizontal_wrapped(|ui| {
            if ui
                .selectable_label(!self.active, "Navigate")
                .on_hover_text("Drag orbits, Shift+drag pans, scroll zooms (Esc)")
                .clicked()
            {
                self.active = false;
                self.voxel.cancel();
            }
            for (tool, label, tip) in ToolKind::ALL {
                let key = super::keys::shortcut(super::keys::Act::Tool(tool));
                if ui
                    .selectable_label(self.active && self.tool == tool, label)
                    .on_hover_text(format!("{tip} ({key}); Alt+drag orbits"))
                    .clicked()
                {
                    self.choose(tool);
                }
            }
            ui.separator();
            self.colors.bar_ui(ui, editor, &mut self.brush.color);
        });
        ui.horizontal_wrapped(|ui| {
            self.mirror_ui(ui);
            ui.separator();
            self.options_ui(ui);
            if let Some(e) = &self.colors.hex_error {
                ui.colored_label(ui.visuals().error_fg_color, e);
            }
        });
    }

    /// The chosen tool's options (the tool bar's second row) and its last refusal.
    fn options_ui(&mut self, ui: &mut egui::Ui) {
        if !self.active {
            ui.weak("Navigate: drag orbits, Shift+drag pans, scroll zooms; choose a tool to edit");
            return;
        }
        if self.tool == ToolKind::Select {
            ui.toggle_value(&mut self.voxel.select_through, "Through")
                .on_hover_text(
                    "The rectangle selects every voxel inside it, not only the visible surface",
                );
            ui.label("Click:");
            ui.selectable_value(&mut self.voxel.click_select, ClickSelect::Color, "Colour")
                .on_hover_text("A click selects every voxel of the clicked colour");
            ui.selectable_value(
                &mut self.voxel.click_select,
                ClickSelect::Connected,
                "Connected",
            )
            .on_hover_text("A click selects the clicked voxel's connected part of its colour");
            ui.weak("Shift adds, Ctrl removes · Select menu: copy, paste, flip, rotate");
        } else if self.tool != ToolKind::Brush {
            for (op, label, tip) in [
                (
                    ShapeOp::Add,
                    "Add",
                    "Add voxels in front of the face under the pointer, or on the volume's floor and walls (A)",
                ),
                (
                    ShapeOp::Remove,
                    "Remove",
                    "Remove the voxels the tool covers (D)",
                ),
                (
                    ShapeOp::Paint,
                    "Paint",
                    "Recolour the voxels the tool covers (C)",
                ),
            ] {
                if ui
                    .selectable_label(self.voxel.op == op, label)
                    .on_hover_text(tip)
                    .clicked()
                {
                    self.voxel.op = op;
                }
            }
            if self.tool == ToolKind::Fill {
                ui.separator();
                ui.toggle_value(&mut self.voxel.fill_plane_only, "Plane only")
                    .on_hover_text(
                        "Fill only the clicked voxel's layer (the plane of the face clicked)",
                    );
            }
        } else {
            self.brush_options_ui(ui);
        }
        if let Some(e) = &self.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
    }

    /// The brush's operation, shape, size and strength, or the stretch brush's settings.
    fn brush_options_ui(&mut self, ui: &mut egui::Ui) {
        for (op, label, tip) in [
            (
                BrushOp::Add,
                "Add",
                "Fill voxels in front of the surface (A)",
            ),
            (BrushOp::Remove, "Remove", "Carve voxels away (D)"),
            (
                BrushOp::Paint,
                "Paint",
                "Blend the colour of solid voxels toward the brush colour (C)",
            ),
            (
                BrushOp::Smooth,
                "Smooth",
                "Remove lone voxels and fill small gaps",
            ),
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
            fixed_width(
                ui,
                "64.0 vox",
                egui::DragValue::new(&mut self.brush.radius)
                    .range(0.5..=MAX_RADIUS.min(64.0))
                    .speed(0.1)
                    .fixed_decimals(1)
                    .suffix(" vox"),
            )
            .on_hover_text("Stretch brush radius in voxels ([ and ] step one voxel)");
            ui.label("Factor");
            ui.add_enabled_ui(!self.stretch_erase, |ui| {
                fixed_width(
                    ui,
                    "3.984",
                    egui::DragValue::new(&mut self.stretch_factor)
                        .range(1.0 / 64.0..=crate::editor::MAX_STRETCH_OVERRIDE)
                        .speed(0.01)
                        .fixed_decimals(3),
                )
            })
            .inner
            .on_hover_text(
                "Stretch factor painted into each voxel (replaces the strategy's factor there; steps of 1/64, up to 3.98)",
            );
            ui.toggle_value(&mut self.stretch_erase, "Erase")
                .on_hover_text("Remove painted overrides: the strategy's factor applies again");
            return;
        }
        ui.selectable_value(&mut self.brush.shape, BrushShape::Sphere, "Sphere")
            .on_hover_text("Round brush");
        ui.selectable_value(&mut self.brush.shape, BrushShape::Cube, "Cube")
            .on_hover_text("Square brush");
        ui.separator();
        ui.label("Size");
        fixed_width(
            ui,
            "256.0 vox",
            egui::DragValue::new(&mut self.brush.radius)
                .range(0.5..=MAX_RADIUS)
                .speed(0.1)
                .fixed_decimals(1)
                .suffix(" vox"),
        )
        .on_hover_text(
            "Brush radius in voxels ([ and ] step one voxel, Shift+[ / Shift+] halve / double)",
        );
        ui.label("Strength");
        fixed_width(
            ui,
            "1.00",
            egui::DragValue::new(&mut self.brush.strength)
                .range(0.0..=1.0)
                .speed(0.01)
                .fixed_decimals(2),
        )
        .on_hover_text("Paint: how far the colour moves toward the brush colour per dab; Smooth: how aggressively");
    }

    /// The mirror toggles.
    fn mirror_ui(&mut self, ui: &mut egui::Ui) {
        ui.label("Mirror");
        let across = if self.tool == ToolKind::Brush {
            "the model's centre"
        } else {
            "the centre of the model's volume"
        };
        for (axis, label) in ["X", "Y", "Z"].into_iter().enumerate() {
            ui.toggle_value(&mut self.brush.symmetry[axis], label)
                .on_hover_text(format!(
                    "Mirror each edit across {across} along {label} (Shift+{label})"
                ));
        }
    }
}

/// A tool-bar number field as wide as its widest value `widest` (its range's end, formatted as
/// the field shows it), so the toggles after it do not move while the value changes
/// its number of digits.
fn fixed_width(ui: &mut egui::Ui, widest: &str, field: egui::DragValue<'_>) -> egui::Response {
    let font = egui::TextStyle::Button.resolve(ui.style());
    let text = ui
        .painter()
        .layout_no_wrap(widest.to_owned(), font, egui::Color32::WHITE)
        .size()
        .x;
    let width = text + 2.0 * ui.spacing().button_padding.x;
    ui.add_sized([width, ui.spacing().interact_size.y], field)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn brush_keys_step_whole_voxels_and_stay_in_range() {
        assert_eq!(step_brush_radius(2.0, true, false), 3.0);
        assert_eq!(step_brush_radius(3.0, false, false), 2.0);
        // A fractional radius (typed in) snaps to the next whole voxel either way.
        assert_eq!(step_brush_radius(2.4, true, false), 3.0);
        assert_eq!(step_brush_radius(2.4, false, false), 2.0);
        // One voxel is the smallest brush; the core limit the largest.
        assert_eq!(step_brush_radius(1.0, false, false), 0.5);
        assert_eq!(step_brush_radius(0.5, false, false), 0.5);
        assert_eq!(step_brush_radius(0.5, true, false), 1.0);
        assert_eq!(step_brush_radius(MAX_RADIUS, true, false), MAX_RADIUS);
        assert_eq!(step_brush_radius(MAX_RADIUS, true, true), MAX_RADIUS);
        // Shift doubles and halves.
        assert_eq!(step_brush_radius(3.0, true, true), 6.0);
        assert_eq!(step_brush_radius(6.0, false, true), 3.0);
        assert_eq!(step_brush_radius(f32::NAN, true, false), 1.0);
        // Ten presses up then ten down come back to where they started.
        let mut r = 2.0;
        for _ in 0..10 {
            r = step_brush_radius(r, true, false);
        }
        assert_eq!(r, 12.0);
        for _ in 0..10 {
            r = step_brush_radius(r, false, false);
        }
        assert_eq!(r, 2.0);
    }
}

//! The Select and Model menus and the voxel tools' keys: selection commands (all, none,
//! invert, grow, shrink, copy, cut, paste, delete, fill, flip, rotate, crop, to new object) and
//! whole-model operations (resize canvas, shift, mirror, hollow, fill interior).

use glam::{IVec3, UVec3};
use thicket_core::sculpt::model_ops::Anchor;
use thicket_core::sculpt::select::SelTransform;
use thicket_core::sculpt::shapes::ShapeOp;

use super::EditorApp;
use super::keys::{Act, pressed, presses, shortcut};
use super::shortcuts::consume_escape;
use super::voxel_tools::ToolKind;
use crate::editor::jobs::Job;
use crate::editor::{CommandError, ModelOp, ToolOutcome};
use crate::files;

/// Model → Resize canvas's fields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CanvasForm {
    /// The new extent.
    pub size: UVec3,
    /// Which side stays put, per axis.
    pub anchor: [Anchor; 3],
    /// Model → Hollow's shell thickness.
    pub shell: u32,
    /// The model the size was taken from (refreshed when another is selected).
    pub object: Option<u64>,
}

impl Default for CanvasForm {
    fn default() -> Self {
        Self {
            size: UVec3::splat(32),
            anchor: [Anchor::Center, Anchor::Min, Anchor::Center],
            shell: 1,
            object: None,
        }
    }
}

/// Model → Voxelize mesh's fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VoxelizeForm {
    /// Octree depth: 2^depth voxels along the mesh's longest side.
    pub depth: u8,
    /// Fill closed meshes (else the surface only).
    pub solid: bool,
}

impl VoxelizeForm {
    /// The voxelizer's settings for this form: `thicket import --depth` (and `--solid`).
    #[must_use]
    pub fn settings(&self) -> thicket_core::voxelize::VoxelizeSettings {
        thicket_core::voxelize::VoxelizeSettings {
            resolution: thicket_core::voxelize::Resolution::Depth(self.depth),
            mode: if self.solid {
                thicket_core::voxelize::Mode::Solid
            } else {
                thicket_core::voxelize::Mode::Surface
            },
            ..thicket_core::voxelize::VoxelizeSettings::default()
        }
    }
}

impl Default for VoxelizeForm {
    fn default() -> Self {
        // `thicket import`'s default depth.
        Self {
            depth: 7,
            solid: false,
        }
    }
}

impl EditorApp {
    /// Shows a command's outcome in the status bar (errors as a toast).
    fn report_voxels(
        &mut self,
        ctx: &egui::Context,
        what: &str,
        r: Result<ToolOutcome, CommandError>,
    ) {
        match r {
            Ok(o) => {
                let m = o.message(what);
                self.sculpt.status = Some(m.clone());
                self.status = m;
            }
            Err(e) => self.toast(ctx, e.to_string(), true),
        }
    }

    /// A flip or turn of the selected voxels: done at once when every voxel stays on the
    /// canvas (or the canvas grows for pastes), else the artist chooses first
    /// ([`EditorApp::transform_prompt`]).
    fn transform_checked(&mut self, ctx: &egui::Context, t: SelTransform, what: &'static str) {
        let outside = self.editor.transform_outside(t).map_or(0, |o| o.0);
        if outside == 0 {
            let r = self.editor.transform_selected_voxels(t);
            self.report_voxels(ctx, what, r);
        } else if self.sculpt.voxel.grow_canvas_on_paste {
            let r = self.editor.transform_selected_voxels_growing(t);
            self.report_voxels(ctx, what, r);
        } else {
            self.pending_transform = Some((t, what, outside));
        }
    }

    /// The choice a flip or turn that would push voxels off the canvas waits for: grow the
    /// canvas to keep them, clip them, or cancel.
    pub(super) fn transform_prompt(&mut self, ctx: &egui::Context) {
        let Some((t, what, outside)) = self.pending_transform else {
            return;
        };
        let mut choice = None;
        egui::Window::new(format!("{what} selected voxels"))
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_CENTER, egui::Vec2::ZERO)
            .show(ctx, |ui| {
                ui.label(format!(
                    "{outside} voxel(s) would land outside the canvas and be lost."
                ));
                ui.horizontal(|ui| {
                    if ui
                        .button("Grow the canvas")
                        .on_hover_text(
                            "Grow the volume just enough to keep every voxel (the model keeps its place); one undo step",
                        )
                        .clicked()
                    {
                        choice = Some(true);
                    }
                    if ui
                        .button(format!("{what} and clip"))
                        .on_hover_text("Drop the voxels that land outside")
                        .clicked()
                    {
                        choice = Some(false);
                    }
                    if ui.button("Cancel").clicked() {
                        self.pending_transform = None;
                    }
                });
            });
        if let Some(grow) = choice {
            self.pending_transform = None;
            let r = if grow {
                self.editor.transform_selected_voxels_growing(t)
            } else {
                self.editor.transform_selected_voxels(t)
            };
            self.report_voxels(ctx, what, r);
        }
    }

    fn report_count(&mut self, ctx: &egui::Context, what: &str, r: Result<usize, CommandError>) {
        match r {
            Ok(n) => self.status = format!("{what}: {n} voxels"),
            Err(e) => self.toast(ctx, e.to_string(), true),
        }
    }

    /// Paste into the selected voxel model (or the one the clipboard came from).
    pub fn paste_voxels(&mut self, ctx: &egui::Context) {
        let Some(id) = self
            .editor
            .selected_voxel_model()
            .or_else(|| self.editor.voxel_selection().map(|s| s.object))
        else {
            self.toast(ctx, "select a voxel model to paste into", true);
            return;
        };
        // At the pointer when it is over the model (the paste sits on the face there), else
        // where the voxels were copied from.
        let started = match self.view.paste_target {
            Some((object, cell)) if object == id => self.editor.start_paste_at(id, cell),
            _ => self.editor.start_paste(id),
        };
        match started {
            Ok(()) => {
                self.status = "Pasting: drag it or use the arrow keys and PageUp / PageDown, \
                               Enter places it, Esc cancels"
                    .into();
            }
            Err(e) => self.toast(ctx, e.to_string(), true),
        }
    }

    /// The Select menu.
    pub(super) fn select_menu_ui(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        let model = self.editor.selected_voxel_model();
        let has_sel = self.editor.voxel_selection().is_some();
        let has_clip = self.editor.clipboard().is_some();
        let item = |ui: &mut egui::Ui, enabled: bool, label: &str, key: String, tip: &str| {
            ui.add_enabled(enabled, egui::Button::new(label).shortcut_text(key))
                .on_hover_text(tip)
                .clicked()
        };
        if item(
            ui,
            true,
            "Select tool",
            shortcut(Act::Tool(ToolKind::Select)),
            "Drag a rectangle in the view; click a colour",
        ) {
            self.sculpt.choose(ToolKind::Select);
        }
        ui.separator();
        if item(
            ui,
            model.is_some(),
            "All",
            shortcut(Act::SelectAll),
            "Every voxel of the selected model",
        ) && let Some(id) = model
        {
            let r = self.editor.select_all_voxels(id);
            self.report_count(&ctx, "Selected", r);
        }
        if item(
            ui,
            has_sel,
            "None",
            shortcut(Act::SelectNone),
            "Clear the voxel selection",
        ) {
            self.editor.clear_voxel_selection();
        }
        if item(
            ui,
            model.is_some(),
            "Invert",
            shortcut(Act::InvertSelection),
            "Select the other voxels",
        ) {
            let r = self.editor.invert_voxel_selection();
            self.report_count(&ctx, "Selected", r);
        }
        if item(
            ui,
            has_sel,
            "Grow",
            String::new(),
            "Add the solid voxels next to the selection",
        ) {
            let r = self.editor.grow_voxel_selection(true);
            self.report_count(&ctx, "Selected", r);
        }
        if item(
            ui,
            has_sel,
            "Shrink",
            String::new(),
            "Drop the selection's outer layer",
        ) {
            let r = self.editor.grow_voxel_selection(false);
            self.report_count(&ctx, "Selected", r);
        }
        ui.separator();
        if item(
            ui,
            has_sel,
            "Copy",
            shortcut(Act::Copy),
            "Copy the selected voxels",
        ) {
            let r = self.editor.copy_voxels();
            self.report_count(&ctx, "Copied", r);
        }
        if item(
            ui,
            has_sel,
            "Cut",
            shortcut(Act::Cut),
            "Copy, then delete the selected voxels",
        ) {
            let r = self.editor.cut_voxels();
            self.report_voxels(&ctx, "Cut", r);
        }
        if item(
            ui,
            has_clip && model.is_some(),
            "Paste",
            shortcut(Act::Paste),
            "Paste the copied voxels as a floating selection (Ctrl+V: at the pointer when it is over the model): drag it or use the arrow keys, Enter places it",
        ) {
            self.paste_voxels(&ctx);
        }
        if item(
            ui,
            has_sel,
            "Delete",
            shortcut(Act::Delete),
            "Delete the selected voxels",
        ) {
            let r = self.editor.delete_selected_voxels();
            self.report_voxels(&ctx, "Delete", r);
        }
        if item(
            ui,
            has_sel,
            "Fill with colour",
            String::new(),
            "Paint the selected voxels with the tool colour",
        ) {
            let ink = self.sculpt.ink();
            let r = self.editor.fill_selected_voxels(ink);
            self.report_voxels(&ctx, "Fill", r);
        }
        ui.separator();
        ui.horizontal(|ui| {
            ui.label("Flip");
            for (axis, label) in ["X", "Y", "Z"].into_iter().enumerate() {
                if ui
                    .add_enabled(has_sel, egui::Button::new(label))
                    .on_hover_text(format!("Mirror the selected voxels along {label} in place"))
                    .clicked()
                {
                    self.transform_checked(&ctx, SelTransform::Flip(axis), "Flip");
                }
            }
        });
        ui.horizontal(|ui| {
            ui.label("Rotate");
            for (axis, label) in ["X", "Y", "Z"].into_iter().enumerate() {
                if ui
                    .add_enabled(has_sel, egui::Button::new(format!("{label} 90°")))
                    .on_hover_text(format!(
                        "Turn the selected voxels a quarter turn about {label} (counter-clockwise looking down +{label})"
                    ))
                    .clicked()
                {
                    let t = SelTransform::Rotate {
                        axis,
                        quarter_turns: 1,
                    };
                    self.transform_checked(&ctx, t, "Rotate");
                }
            }
        });
        ui.separator();
        if item(
            ui,
            has_sel,
            "Crop model to selection",
            String::new(),
            "Delete every voxel outside the selection",
        ) {
            let r = self.editor.crop_to_selection();
            self.report_voxels(&ctx, "Crop", r);
        }
        if item(
            ui,
            has_sel,
            "Selection to new object",
            String::new(),
            "Copy the selected voxels into a new voxel model at the same place",
        ) {
            match self.editor.selection_to_new_object() {
                Ok(_) => self.status = "Selection copied to a new object".into(),
                Err(e) => self.toast(&ctx, e.to_string(), true),
            }
        }
    }

    /// The Model menu (whole-model operations on the selected voxel model).
    /// Model → Voxelize mesh, shown when a mesh object is selected: depth, surface or solid,
    /// the estimate, and Voxelize (a job with progress and Cancel; the voxel object replaces
    /// the shown mesh, one undo step). Returns whether a mesh is selected.
    fn voxelize_mesh_ui(&mut self, ui: &mut egui::Ui) -> bool {
        let Some(o) = self.editor.selected_object() else {
            return false;
        };
        let thicket_core::scene::ObjectKind::Mesh(m) = &o.kind else {
            return false;
        };
        let (id, name) = (o.id, o.name.clone());
        ui.label(format!("Voxelize mesh {name:?}"));
        ui.horizontal(|ui| {
            ui.label("Depth");
            ui.add(egui::DragValue::new(&mut self.voxelize.depth).range(2..=11))
                .on_hover_text(
                    "2^depth voxels along the mesh's longest side (thicket import --depth)",
                );
            ui.selectable_value(&mut self.voxelize.solid, false, "Surface")
                .on_hover_text("Voxels where the surface is (the inside stays empty)");
            ui.selectable_value(&mut self.voxelize.solid, true, "Solid")
                .on_hover_text(
                    "Fill closed meshes (an open one falls back to its surface, and says so)",
                );
        });
        let settings = self.voxelize.settings();
        let estimate = thicket_core::voxelize::estimate(&m.model, &settings);
        match &estimate {
            Ok(e) => ui.weak(format!(
                "about {} voxels, {} MiB at most",
                files::thousands((e.surface_voxels + e.interior_voxels).round() as u64),
                e.peak_bytes >> 20
            )),
            Err(e) => ui.colored_label(ui.visuals().error_fg_color, e.to_string()),
        };
        let busy = self.job.is_some();
        if ui
            .add_enabled(estimate.is_ok() && !busy, egui::Button::new("Voxelize"))
            .on_hover_text("A voxel model of this mesh, as `thicket import` makes it at this depth; the mesh is hidden (one undo step)")
            .clicked()
        {
            let model = m.model.clone();
            self.job = Some(Job::voxelize_mesh(
                id,
                &name,
                model,
                settings,
                self.memory_budget,
            ));
            ui.close();
        }
        true
    }

    pub(super) fn model_menu_ui(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        if ui
            .add(egui::Button::new("Add voxel model…").shortcut_text(shortcut(Act::AddModel)))
            .on_hover_text("A new, empty (or filled) voxel model standing where the view looks")
            .clicked()
        {
            self.new_model.show(&self.editor);
            ui.close();
        }
        ui.checkbox(&mut self.palette.open, "Palette panel")
            .on_hover_text("The model's palette and colours: pick, edit, replace, load, save");
        ui.checkbox(
            &mut self.sculpt.voxel.grow_canvas_on_paste,
            "Grow the canvas for pastes",
        )
        .on_hover_text(
            "Enter grows the volume to hold a paste that reaches outside it (off: Enter drops \
             what is outside, Shift+Enter grows)",
        );
        ui.separator();
        if self.voxelize_mesh_ui(ui) {
            return;
        }
        let Some(id) = self.editor.selected_voxel_model() else {
            ui.weak("Select a voxel model (or a mesh, to voxelize it) for the operations below");
            return;
        };
        let size = self.editor.volume_of(id).unwrap_or(UVec3::ONE);
        if self.canvas.object != Some(id) {
            self.canvas.size = size;
            self.canvas.object = Some(id);
        }
        ui.label(format!("Volume {}×{}×{} voxels", size.x, size.y, size.z));
        ui.menu_button("Resize canvas", |ui| {
            let mut s = self.canvas.size.to_array();
            for (i, (v, axis)) in s.iter_mut().zip(["X", "Y", "Z"]).enumerate() {
                ui.horizontal(|ui| {
                    ui.add(
                        egui::DragValue::new(v)
                            .range(1..=crate::editor::MAX_EXTENT)
                            .prefix(format!("{axis} ")),
                    );
                    for (a, label) in [(Anchor::Min, "min"), (Anchor::Center, "centre"), (Anchor::Max, "max")] {
                        ui.selectable_value(&mut self.canvas.anchor[i], a, label)
                            .on_hover_text(format!("Keep the {label} side of {axis} where it is"));
                    }
                });
            }
            self.canvas.size = UVec3::from_array(s);
            if ui
                .button("Resize")
                .on_hover_text("Grow or shrink the volume; voxels outside the new volume are removed (undoable)")
                .clicked()
            {
                match self.editor.resize_canvas(id, self.canvas.size, self.canvas.anchor) {
                    Ok(dropped) => {
                        self.status = format!("Canvas resized; {dropped} voxels fell outside");
                    }
                    Err(e) => self.toast(&ctx, e.to_string(), true),
                }
                ui.close();
            }
        });
        ui.horizontal(|ui| {
            ui.label("Shift content");
            for (label, by) in [
                ("−X", IVec3::NEG_X),
                ("+X", IVec3::X),
                ("−Y", IVec3::NEG_Y),
                ("+Y", IVec3::Y),
                ("−Z", IVec3::NEG_Z),
                ("+Z", IVec3::Z),
            ] {
                if ui
                    .button(label)
                    .on_hover_text("Move every voxel one step, wrapping round the volume")
                    .clicked()
                {
                    let r = self.editor.model_op(
                        id,
                        ModelOp::Shift {
                            offset: by,
                            wrap: true,
                        },
                    );
                    self.report_voxels(&ctx, "Shift", r);
                }
            }
        });
        ui.horizontal(|ui| {
            ui.label("Mirror model");
            for (axis, label) in ["X", "Y", "Z"].into_iter().enumerate() {
                if ui
                    .button(label)
                    .on_hover_text(format!(
                        "Mirror the whole model across the volume's centre along {label}"
                    ))
                    .clicked()
                {
                    let r = self.editor.model_op(id, ModelOp::Mirror(axis));
                    self.report_voxels(&ctx, "Mirror", r);
                }
            }
        });
        ui.horizontal(|ui| {
            if ui
                .button("Hollow")
                .on_hover_text("Keep a shell this many voxels thick and remove the inside")
                .clicked()
            {
                let r = self.editor.model_op(id, ModelOp::Hollow(self.canvas.shell));
                self.report_voxels(&ctx, "Hollow", r);
            }
            ui.add(
                egui::DragValue::new(&mut self.canvas.shell)
                    .range(1..=64)
                    .suffix(" vox"),
            );
        });
        if ui
            .button("Fill interior")
            .on_hover_text("Fill the enclosed empty cells (with the neighbouring colours)")
            .clicked()
        {
            let r = self.editor.model_op(id, ModelOp::FillInterior(None));
            self.report_voxels(&ctx, "Fill interior", r);
        }
    }

    /// The voxel tools' keys. Runs before the object keys so Delete, arrows and Esc act on the
    /// voxel selection and the floating paste first.
    pub(super) fn voxel_shortcuts(&mut self, ctx: &egui::Context) {
        if self.keyboard_taken(ctx) {
            return;
        }
        if pressed(ctx, Act::AddModel) {
            self.new_model.show(&self.editor);
        }
        if pressed(ctx, Act::SelectNone) {
            self.editor.clear_voxel_selection();
        }
        if pressed(ctx, Act::InvertSelection) {
            let r = self.editor.invert_voxel_selection();
            self.report_count(ctx, "Selected", r);
        }
        if self.sculpt.active
            && let Some(id) = self.editor.selected_voxel_model()
            && pressed(ctx, Act::SelectAll)
        {
            let r = self.editor.select_all_voxels(id);
            self.report_count(ctx, "Selected", r);
        }
        // Copy / cut / paste of voxels when the voxel tools are in use.
        let voxel_mode = self.sculpt.active || self.editor.voxel_selection().is_some();
        if voxel_mode && self.editor.voxel_selection().is_some() {
            if pressed(ctx, Act::Copy) {
                let r = self.editor.copy_voxels();
                self.report_count(ctx, "Copied", r);
            }
            if pressed(ctx, Act::Cut) {
                let r = self.editor.cut_voxels();
                self.report_voxels(ctx, "Cut", r);
            }
        }
        if voxel_mode && self.editor.clipboard().is_some() && pressed(ctx, Act::Paste) {
            self.paste_voxels(ctx);
        }
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let moves = [
            IVec3::NEG_X,
            IVec3::X,
            IVec3::NEG_Z,
            IVec3::Z,
            IVec3::Y,
            IVec3::NEG_Y,
        ];
        // Every press moves one voxel, also when a burst of presses lands in one frame.
        if self.editor.floating().is_some() {
            for by in moves {
                for _ in 0..presses(ctx, Act::Move(by)) {
                    self.editor.move_floating(by);
                }
            }
            let grow = pressed(ctx, Act::PlacePasteGrowing)
                || (self.sculpt.voxel.grow_canvas_on_paste && pressed(ctx, Act::PlacePaste));
            if grow {
                let r = self.editor.commit_floating_growing();
                self.report_voxels(ctx, "Paste", r);
            } else if pressed(ctx, Act::PlacePaste) {
                let r = self.editor.commit_floating();
                self.report_voxels(ctx, "Paste", r);
            }
            if consume_escape(ctx) {
                self.editor.cancel_floating();
                self.status = "Paste cancelled".into();
            }
        } else if self.editor.voxel_selection().is_some() {
            for by in moves {
                for _ in 0..presses(ctx, Act::Move(by)) {
                    let t = SelTransform::Move(by);
                    let outside = self.editor.transform_outside(t).map_or(0, |o| o.0);
                    if outside == 0 {
                        let r = self.editor.transform_selected_voxels(t);
                        self.report_voxels(ctx, "Move", r);
                    } else if self.sculpt.voxel.grow_canvas_on_paste {
                        let r = self.editor.transform_selected_voxels_growing(t);
                        self.report_voxels(ctx, "Move (canvas grown)", r);
                    } else {
                        // An arrow at the canvas edge never drops voxels.
                        self.toast(
                            ctx,
                            format!(
                                "Not moved: {outside} voxel(s) would leave the canvas (turn on Model menu: Grow the canvas for pastes to grow it instead, or resize it)"
                            ),
                            false,
                        );
                    }
                }
            }
            if pressed(ctx, Act::Delete) {
                let r = self.editor.delete_selected_voxels();
                self.report_voxels(ctx, "Delete", r);
            }
        }
        if self.sculpt.voxel.busy() && consume_escape(ctx) {
            self.sculpt.voxel.cancel();
        }
        for (tool, _, _) in ToolKind::ALL {
            if pressed(ctx, Act::Tool(tool)) {
                self.sculpt.choose(tool);
            }
        }
        if self.sculpt.active {
            for (act, op) in [
                (Act::AddMode, ShapeOp::Add),
                (Act::RemoveMode, ShapeOp::Remove),
                (Act::PaintMode, ShapeOp::Paint),
            ] {
                if pressed(ctx, act) {
                    self.sculpt.set_op(op);
                }
            }
            for axis in 0..3 {
                if pressed(ctx, Act::Mirror(axis)) {
                    self.sculpt.brush.symmetry[axis] = !self.sculpt.brush.symmetry[axis];
                }
            }
        }
    }
}

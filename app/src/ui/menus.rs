//! The menu bar, one function per menu. (Select and Model are in `voxel_menus`.)

use super::keys::{Act, shortcut};
use super::path_prompt::{PathPurpose, readable_list};
use super::{EditorApp, PRESETS, native_dialogs_available};
use crate::editor::Selection;
use thicket_core::quality::Quality;

impl EditorApp {
    /// The menu bar: one function per menu (Select and Model are in `voxel_menus`).
    pub(super) fn menu_bar(&mut self, ui: &mut egui::Ui) {
        let busy = self.job.is_some();
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| self.file_menu_ui(ui, busy));
            ui.menu_button("Edit", |ui| self.edit_menu_ui(ui, busy));
            ui.menu_button("Select", |ui| self.select_menu_ui(ui));
            ui.menu_button("Model", |ui| self.model_menu_ui(ui));
            ui.menu_button("View", |ui| self.view_menu_ui(ui));
            ui.menu_button("Render", |ui| self.render_menu_ui(ui));
            ui.menu_button("Help", |ui| self.help_menu_ui(ui));
        });
    }

    /// File: new, open, recent, save, import, export, dialogs and autosave, quit.
    fn file_menu_ui(&mut self, ui: &mut egui::Ui, busy: bool) {
        if ui
            .add_enabled(
                !busy,
                egui::Button::new("New project…").shortcut_text(shortcut(Act::New)),
            )
            .on_hover_text("Start a new project with a new voxel model (Cancel: an empty project)")
            .clicked()
        {
            self.request_new();
        }
        if ui
            .add_enabled(
                !busy,
                egui::Button::new("Open…").shortcut_text(shortcut(Act::Open)),
            )
            .on_hover_text("Open a project (.thicket.json) or a model to start a new project from")
            .clicked()
        {
            self.ask_path(PathPurpose::Open);
        }
        ui.menu_button("Recent", |ui| {
            if self.editor.recent.is_empty() {
                ui.weak("No recent files");
            }
            let mut chosen = None;
            let mut forget = None;
            for path in &self.editor.recent {
                let label = path.display().to_string();
                // A file moved or deleted since (or a relative entry from an older version)
                // stays listed, greyed, until it is removed here.
                if path.is_file() {
                    if ui.add_enabled(!busy, egui::Button::new(label)).clicked() {
                        chosen = Some(path.clone());
                    }
                    continue;
                }
                ui.horizontal(|ui| {
                    ui.add_enabled(false, egui::Button::new(label))
                        .on_disabled_hover_text(
                            "No such file any more (moved, renamed or deleted)",
                        );
                    if ui
                        .small_button("Remove from list")
                        .on_hover_text("Take this file off the list")
                        .clicked()
                    {
                        forget = Some(path.clone());
                    }
                });
            }
            if let Some(path) = forget {
                self.editor.remove_recent(&path);
            }
            if let Some(path) = chosen {
                self.request_open(path);
            }
        });
        ui.separator();
        if ui
            .add(egui::Button::new("Save").shortcut_text(shortcut(Act::Save)))
            .on_hover_text("Save the project (atomically: the previous save stays readable until this one is complete)")
            .clicked()
        {
            let ctx = ui.ctx().clone();
            self.save(&ctx);
        }
        if ui
            .add(egui::Button::new("Save As…").shortcut_text(shortcut(Act::SaveAs)))
            .on_hover_text("Save the project under a new name")
            .clicked()
        {
            self.ask_path(PathPurpose::SaveAs);
        }
        ui.separator();
        if ui
            .add_enabled(
                !busy,
                egui::Button::new("Import…").shortcut_text(shortcut(Act::Import)),
            )
            .on_hover_text(format!(
                "Add the objects of another file to this project ({})",
                readable_list()
            ))
            .clicked()
        {
            self.ask_path(PathPurpose::Import);
        }
        if ui
            .add_enabled(!busy, egui::Button::new("Export .vox..."))
            .on_hover_text(
                "Write the visible voxel models as a MagicaVoxel file (on a worker thread); \
                 meshes in the scene can be voxelized first",
            )
            .clicked()
        {
            self.request_export_vox();
        }
        if ui
            .add_enabled(!busy, egui::Button::new("Export glTF..."))
            .on_hover_text("Write the scene, or the selected object, as .glb or .gltf: cubes, smooth surfaces, KRS meshes or instances, skinned characters with their clips")
            .clicked()
        {
            self.gltf_export.open = true;
            ui.close();
        }
        ui.separator();
        if native_dialogs_available() {
            ui.checkbox(&mut self.native_dialogs, "Native file dialogs")
                .on_hover_text("Use the desktop's file dialogs (xdg portal or zenity) when available; otherwise a path entry");
        } else {
            ui.add_enabled(false, egui::Checkbox::new(&mut false, "Native file dialogs"))
                .on_disabled_hover_text("No desktop file dialog can open here (no D-Bus session for the xdg portal, no zenity on PATH): files are named in a path entry");
        }
        ui.horizontal(|ui| {
            ui.label("Autosave");
            for (secs, label) in [(0, "Off"), (60, "1 min"), (120, "2 min"), (300, "5 min")] {
                ui.selectable_value(&mut self.autosave_secs, secs, label)
                    .on_hover_text(format!(
                        "Write unsaved work to a recovery file in {} (never over your file)",
                        self.recovery_dir.display()
                    ));
            }
        });
        ui.separator();
        if ui
            .button("Quit")
            .on_hover_text("Close the editor")
            .clicked()
        {
            ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }

    /// Edit: undo/redo, duplicate, add KRS presets, enhance, delete, drop, add model or light.
    fn edit_menu_ui(&mut self, ui: &mut egui::Ui, busy: bool) {
        let h = self.editor.history();
        let (can_undo, can_redo) = (h.undo_len() > 0, h.redo_len() > 0);
        if ui
            .add_enabled(
                can_undo,
                egui::Button::new("Undo").shortcut_text(shortcut(Act::Undo)),
            )
            .on_hover_text("Undo the last edit")
            .clicked()
        {
            self.editor.undo();
        }
        if ui
            .add_enabled(
                can_redo,
                egui::Button::new("Redo").shortcut_text(shortcut(Act::Redo)),
            )
            .on_hover_text("Redo the last undone edit")
            .clicked()
        {
            self.editor.redo();
        }
        if ui
            .button("History…")
            .on_hover_text("The undo steps by name: click one to go back or forward to it")
            .clicked()
        {
            self.show_history = true;
            ui.close();
        }
        ui.separator();
        let selected = match self.editor.selection {
            Some(Selection::Object(id)) => Some(id),
            _ => None,
        };
        if ui
            .add_enabled(
                selected.is_some(),
                egui::Button::new("Duplicate").shortcut_text(shortcut(Act::Duplicate)),
            )
            .on_hover_text("Copy the selected object")
            .clicked()
            && let Some(id) = selected
        {
            let _ = self.editor.duplicate(id);
        }
        ui.menu_button("Add KRS object", |ui| {
            for (name, krs) in thicket_core::krs::presets::all() {
                if ui
                    .button(name)
                    .on_hover_text(
                        "Add this procedural KRS preset as a new object beside the scene and frame it (edit it in the inspector)",
                    )
                    .clicked()
                {
                    let label = format!("KRS {name}");
                    let params = thicket_core::krs::presets::builder_params(name);
                    self.editor.add_krs_object(&label, krs, params);
                    ui.close();
                }
            }
        });
        ui.menu_button("Enhance detail", |ui| {
            for factor in [2u32, 4, 8] {
                if ui
                    .add_enabled(selected.is_some() && !busy, egui::Button::new(format!("x{factor}")))
                    .on_hover_text("Add a detail-enhanced copy of the selected voxel model (worker thread, cancellable)")
                    .clicked()
                {
                    self.start_enhance(factor);
                }
            }
        });
        let selected_light = match self.editor.selection {
            Some(Selection::Light(i)) => Some(i),
            _ => None,
        };
        if ui
            .add_enabled(
                selected.is_some() || selected_light.is_some(),
                egui::Button::new("Delete").shortcut_text(shortcut(Act::Delete)),
            )
            .on_hover_text("Delete the selected object or light (undoable)")
            .clicked()
        {
            if let Some(id) = selected {
                let _ = self.editor.delete(id);
            } else if let Some(i) = selected_light {
                let _ = self.editor.delete_light(i);
            }
        }
        if ui
            .add_enabled(selected.is_some(), egui::Button::new("Drop to surface").shortcut_text(shortcut(Act::Drop)))
            .on_hover_text("Move the selected object straight down until it rests on the voxels, mesh or KRS surface below it (undoable)")
            .clicked()
        {
            self.drop_selected(ui.ctx());
        }
        if ui
            .add(egui::Button::new("Add voxel model…").shortcut_text(shortcut(Act::AddModel)))
            .on_hover_text(
                "A new voxel model standing where the view looks: extent, voxel size, initial fill",
            )
            .clicked()
        {
            self.new_model.show(&self.editor);
            ui.close();
        }
        if ui
            .button("Add light")
            .on_hover_text("Add a directional light that casts shadows (undoable)")
            .clicked()
        {
            let light = self.editor.new_light();
            let _ = self.editor.add_light(light);
        }
    }

    /// View: panels, framing, overlays, the view's own options, UI scale.
    fn view_menu_ui(&mut self, ui: &mut egui::Ui) {
        ui.checkbox(&mut self.show_outliner, "Outliner")
            .on_hover_text("Show the list of objects and lights");
        ui.checkbox(&mut self.show_inspector, "Inspector")
            .on_hover_text("Show the properties of the selection");
        ui.separator();
        if ui
            .add(egui::Button::new("Frame selection").shortcut_text(shortcut(Act::Frame)))
            .on_hover_text("Point the camera at the selection, or at everything")
            .clicked()
        {
            self.editor.frame_selection();
        }
        ui.checkbox(&mut self.perf.open, "Performance overlay (F3)")
            .on_hover_text("Frame times, GPU time per pass, nodes per level, memory");
        ui.checkbox(&mut self.tradeoff.open, "Trade-off")
            .on_hover_text(
                "Measure time against error for each quality setting on this view, and pick one",
            );
        ui.separator();
        self.view.menu_ui(ui, &mut self.editor);
        ui.separator();
        ui.label("UI scale");
        ui.horizontal(|ui| {
            for zoom in [1.0_f32, 1.25, 1.5, 2.0] {
                if ui
                    .button(format!("{}%", (zoom * 100.0).round()))
                    .on_hover_text("Scale the whole interface (for high-DPI screens)")
                    .clicked()
                {
                    ui.ctx().set_zoom_factor(zoom);
                }
            }
        });
    }

    /// Render: the quality preset and the view's renderer options.
    fn render_menu_ui(&mut self, ui: &mut egui::Ui) {
        ui.label("Quality preset");
        let current = &self.editor.doc().quality;
        let active = PRESETS
            .iter()
            .position(|(_, p, _)| *current == Quality::preset(*p));
        for (i, (label, preset, tip)) in PRESETS.iter().enumerate() {
            if ui
                .radio(active == Some(i), *label)
                .on_hover_text(*tip)
                .clicked()
            {
                self.editor.apply_quality_preset(*preset);
            }
        }
        if active.is_none() {
            ui.add_enabled(false, egui::RadioButton::new(true, "Custom"))
                .on_disabled_hover_text(
                    "The knobs differ from every preset (edited in the inspector's Render \
                 quality section); choosing a preset replaces them",
                );
        }
        ui.separator();
        self.view.render_menu_ui(ui);
    }

    /// Help: shortcuts and about.
    fn help_menu_ui(&mut self, ui: &mut egui::Ui) {
        if ui
            .add(egui::Button::new("Keyboard shortcuts").shortcut_text(shortcut(Act::Help)))
            .clicked()
        {
            self.show_shortcuts = true;
        }
        if ui.button("About Thicket").clicked() {
            self.show_about = true;
        }
    }
}

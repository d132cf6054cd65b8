//! The editor's windows and notices: recovery, unsaved changes, errors, shortcuts, about,
//! the path entry, the import report and toasts.

use std::path::PathBuf;
use std::time::Duration;

use super::EditorApp;
use super::keys;
use super::path_prompt::{PathPurpose, PromptOutcome};
use crate::files;

impl EditorApp {
    pub(super) fn dialogs(&mut self, ctx: &egui::Context) {
        if let Some(r) = self.recovery.clone() {
            let mut choice = None;
            egui::Modal::new(egui::Id::unique("recovery_dialog")).show(ctx, |ui| {
                ui.heading("Recover unsaved work?");
                let what = r.meta.original.as_ref().map_or_else(
                    || "an untitled project".to_owned(),
                    |p| p.display().to_string(),
                );
                let age = std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_secs())
                    .saturating_sub(r.meta.saved_unix_secs);
                ui.label(format!(
                    "The editor stopped before saving {what}. An autosave from {} ago is in {}.",
                    human_age(age),
                    r.path.display()
                ));
                ui.horizontal(|ui| {
                    if ui
                        .button("Recover")
                        .on_hover_text("Open the autosaved work (save it to keep it)")
                        .clicked()
                    {
                        choice = Some(true);
                    }
                    if ui
                        .button("Discard")
                        .on_hover_text("Delete the autosave and continue")
                        .clicked()
                    {
                        choice = Some(false);
                    }
                });
            });
            match choice {
                Some(true) => self.recover(),
                Some(false) => self.discard_recovery(),
                None => {}
            }
        }
        self.import_report_ui(ctx);
        if let Some(message) = self.error_dialog.clone() {
            egui::Modal::new(egui::Id::unique("error_dialog")).show(ctx, |ui| {
                ui.heading("Could not complete the operation");
                ui.label(message);
                ui.add_space(8.0);
                if ui.button("OK").clicked() {
                    self.error_dialog = None;
                }
            });
        }
        if let Some(pending) = self.pending.clone()
            && self.prompt.is_none()
        {
            let mut decision = None;
            egui::Modal::new(egui::Id::unique("unsaved_dialog")).show(ctx, |ui| {
                ui.heading("Unsaved changes");
                ui.label(format!(
                    "Save the changes to {} first?",
                    self.editor.path().map_or_else(
                        || "the untitled project".to_owned(),
                        |p| p.display().to_string()
                    )
                ));
                ui.horizontal(|ui| {
                    if ui
                        .button("Save")
                        .on_hover_text("Save, then continue")
                        .clicked()
                    {
                        decision = Some(1);
                    }
                    if ui
                        .button("Don't save")
                        .on_hover_text("Discard the changes and continue")
                        .clicked()
                    {
                        decision = Some(2);
                    }
                    if ui
                        .button("Cancel")
                        .on_hover_text("Go back to editing")
                        .clicked()
                    {
                        decision = Some(0);
                    }
                });
            });
            match decision {
                Some(0) => self.pending = None,
                // Untitled: Save asks for a path and the pending action waits for that save.
                Some(1) if self.save(ctx) => {
                    self.pending = None;
                    self.resolve_pending(ctx, pending);
                }
                Some(2) => {
                    self.pending = None;
                    self.resolve_pending(ctx, pending);
                }
                _ => {}
            }
        }
        if let Some(mut prompt) = self.prompt.take() {
            let (accepted, keep) = match prompt.ui(ctx, &self.editor.recent) {
                PromptOutcome::Open => (None, true),
                PromptOutcome::Accept(path) => (Some(path), false),
                PromptOutcome::Cancel => (None, false),
            };
            if let Some(path) = accepted {
                let purpose = prompt.purpose;
                self.accept_path(ctx, purpose, path);
                // A Save As that finished lets a waiting Quit / New / Open go on.
                if purpose == PathPurpose::SaveAs
                    && !self.editor.is_dirty()
                    && let Some(pending) = self.pending.take()
                {
                    self.resolve_pending(ctx, pending);
                }
            } else if keep {
                self.prompt = Some(prompt);
            }
        }
        let selected = self.editor.selected_object().map(|o| o.name.clone());
        // Rigged models posed by hand: the export writes clips, not overrides.
        let posed: Vec<(u64, String, usize)> = if self.gltf_export.open {
            self.editor
                .doc()
                .objects
                .iter()
                .filter_map(|o| {
                    let n = self.editor.rig(o.id)?.pose_overrides.len();
                    (n > 0 && o.visible).then(|| (o.id, o.name.clone(), n))
                })
                .collect()
        } else {
            Vec::new()
        };
        if self
            .gltf_export
            .ui(ctx, selected.as_deref(), self.job.is_some(), &posed)
        {
            self.ask_path(PathPurpose::ExportGltf);
        }
        if std::mem::take(&mut self.gltf_export.bake_request) {
            let mut keyed = 0;
            for (id, name, _) in &posed {
                match self.editor.bake_pose(*id) {
                    Ok(n) => keyed += n,
                    Err(e) => self.error_dialog = Some(format!("{name}: {e}")),
                }
            }
            self.status = format!("Baked the pose of {keyed} joint(s) into the playing clip");
        }
        self.transform_prompt(ctx);
        self.vox_export_offer(ctx);
        if self.show_shortcuts {
            // Never taller than the window (the list is longer than a 720-pixel screen): it
            // scrolls, and the search field filters it by key or action.
            let max_height = (ctx.content_rect().height() - 120.0).max(120.0);
            let search = &mut self.shortcut_search;
            egui::Window::new("Keyboard shortcuts")
                .open(&mut self.show_shortcuts)
                .resizable(false)
                .max_height(max_height)
                .show(ctx, |ui| {
                    ui.horizontal(|ui| {
                        let label = ui.label("Search");
                        ui.add(
                            egui::TextEdit::singleline(search)
                                .hint_text("a key or an action")
                                .desired_width(220.0),
                        )
                        .labelled_by(label.id);
                    });
                    let rows = shortcut_rows(search);
                    if rows.is_empty() {
                        ui.weak("No shortcut matches.");
                    }
                    egui::ScrollArea::vertical()
                        .max_height(max_height - 40.0)
                        .show(ui, |ui| {
                            egui::Grid::new("shortcuts").striped(true).show(ui, |ui| {
                                for (keys, what) in rows {
                                    ui.strong(keys);
                                    ui.label(what);
                                    ui.end_row();
                                }
                            });
                        });
                });
        }
        if self.show_about {
            egui::Window::new("About Thicket")
                .open(&mut self.show_about)
                .show(ctx, |ui| {
                    ui.label(format!("Thicket {}", env!("CARGO_PKG_VERSION")));
                    ui.label("Voxel sculpting, skinning and procedural trees.");
                });
        }
    }

    /// Replaces the objects the reported import placed with a new import of the same file
    /// with `options`, and closes the report.
    fn import_again(&mut self, options: files::MeshOptions) {
        let Some(report) = self.import_report.take() else {
            return;
        };
        for id in report.placed {
            // An object deleted since is simply gone already.
            let _ = self.editor.delete(id);
        }
        self.start_import_with(report.path, options);
    }

    /// The Import report window: what the last import left out, one bullet per kind; for an
    /// OBJ that names no texture a Texture field that imports it again with one; for a glTF
    /// scene of several nodes a checklist of its nodes that imports it again with those.
    pub(super) fn import_report_ui(&mut self, ctx: &egui::Context) {
        let Some(report) = self.import_report.as_mut() else {
            return;
        };
        let mut open = true;
        let mut ok = false;
        let mut again = false;
        let mut again_with_nodes = false;
        let mut again_at_depth = false;
        let needs_texture = report.lines.iter().any(|l| l == files::OBJ_NO_TEXTURE);
        egui::Window::new("Import report")
            .open(&mut open)
            .collapsible(false)
            .resizable(true)
            .default_width(460.0)
            .show(ctx, |ui| {
                let name = report.path.file_name().map_or_else(
                    || report.path.display().to_string(),
                    |n| n.to_string_lossy().into_owned(),
                );
                if report.lines.is_empty() {
                    ui.label(format!("{name} was imported."));
                } else {
                    ui.label(format!(
                        "{name} was imported. What became of what it holds beyond its meshes:"
                    ));
                    ui.add_space(4.0);
                    egui::ScrollArea::vertical()
                        .id_salt("import_report_lines")
                        .max_height(240.0)
                        .show(ui, |ui| {
                            for line in &report.lines {
                                ui.label(format!("• {line}"));
                            }
                        });
                }
                if report.nodes.len() > 1 {
                    again_with_nodes = import_nodes_ui(ui, &mut report.nodes);
                }
                if let Some(depth) = report.skinned_depth.as_mut() {
                    ui.add_space(6.0);
                    ui.horizontal(|ui| {
                        let label = ui.label("Depth");
                        ui.add(
                            egui::DragValue::new(depth).range(crate::editor::jobs::SKINNED_DEPTHS),
                        )
                        .labelled_by(label.id)
                        .on_hover_text(
                            "Octree depth of the skinned model: 2^depth voxels along its longest \
                             side (thicket import --depth); each step up is 8 times the voxels",
                        );
                        again_at_depth = ui
                            .button("Import again at this depth")
                            .on_hover_text("Replaces the object just imported")
                            .clicked();
                    });
                }
                if needs_texture {
                    ui.add_space(6.0);
                    ui.horizontal(|ui| {
                        let label = ui.label("Texture");
                        ui.add(
                            egui::TextEdit::singleline(&mut report.texture)
                                .hint_text("path to a PNG or JPEG")
                                .desired_width(240.0),
                        )
                        .labelled_by(label.id)
                        .on_hover_text(
                            "A base-colour texture for the OBJ's untextured parts; a relative \
                             path is relative to the OBJ's folder",
                        );
                        again = ui
                            .add_enabled(
                                !report.texture.trim().is_empty(),
                                egui::Button::new("Import again with it"),
                            )
                            .on_hover_text("Replaces the objects just imported")
                            .clicked();
                    });
                }
                ui.add_space(6.0);
                ok = ui.button("OK").clicked();
            });
        if again {
            let texture = PathBuf::from(report.texture.trim());
            let texture = if texture.is_relative() {
                report
                    .path
                    .parent()
                    .map_or(texture.clone(), |d| d.join(&texture))
            } else {
                texture
            };
            self.import_again(files::MeshOptions {
                texture: Some(texture),
                ..files::MeshOptions::default()
            });
        } else if again_at_depth {
            let depth = report.skinned_depth;
            self.import_again(files::MeshOptions {
                skinned_depth: depth,
                ..files::MeshOptions::default()
            });
        } else if again_with_nodes {
            let picked = report
                .nodes
                .iter()
                .filter(|(_, on)| *on)
                .map(|(n, _)| n.clone())
                .collect();
            self.import_again(files::MeshOptions {
                nodes: Some(picked),
                ..files::MeshOptions::default()
            });
        } else if !open || ok {
            self.import_report = None;
        }
    }

    pub(super) fn toasts_ui(&mut self, ctx: &egui::Context) {
        let now = ctx.input(|i| i.time);
        self.toasts.retain(|t| t.until_secs > now);
        if self.toasts.is_empty() {
            return;
        }
        egui::Area::new(egui::Id::unique("toasts"))
            .anchor(egui::Align2::RIGHT_BOTTOM, egui::vec2(-12.0, -36.0))
            .show(ctx, |ui| {
                for t in &self.toasts {
                    egui::Frame::popup(ui.style()).show(ui, |ui| {
                        if t.is_error {
                            ui.colored_label(ui.visuals().error_fg_color, &t.text);
                        } else {
                            ui.label(&t.text);
                        }
                    });
                }
            });
        ctx.request_repaint_after(Duration::from_millis(250));
    }
}

/// The Import report's checklist of a glTF scene's nodes (one object each); true when
/// "Import again with these" was clicked (enabled while at least one node is checked).
fn import_nodes_ui(ui: &mut egui::Ui, nodes: &mut [(String, bool)]) -> bool {
    ui.add_space(6.0);
    ui.label("Nodes (one object each):");
    egui::ScrollArea::vertical()
        .id_salt("import_report_nodes")
        .max_height(200.0)
        .show(ui, |ui| {
            for (name, on) in nodes.iter_mut() {
                ui.checkbox(on, name.as_str());
            }
        });
    ui.horizontal(|ui| {
        if ui.small_button("All").clicked() {
            nodes.iter_mut().for_each(|(_, on)| *on = true);
        }
        if ui.small_button("None").clicked() {
            nodes.iter_mut().for_each(|(_, on)| *on = false);
        }
        ui.add_enabled(
            nodes.iter().any(|(_, on)| *on),
            egui::Button::new("Import again with these"),
        )
        .on_hover_text("Replaces the objects just imported with the checked nodes")
        .clicked()
    })
    .inner
}

fn human_age(secs: u64) -> String {
    match secs {
        0..=59 => format!("{secs} s"),
        60..=3599 => format!("{} min", secs / 60),
        3600..=86_399 => format!("{} h", secs / 3600),
        _ => format!("{} days", secs / 86_400),
    }
}

/// The rows of the shortcut sheet whose keys or action contain `search` (any case; all rows for
/// an empty search): the binding table ([`super::keys::BINDINGS`], the keys the handlers
/// bind), then what the mouse and trackpad do.
#[must_use]
pub fn shortcut_rows(search: &str) -> Vec<(String, &'static str)> {
    let needle = search.trim().to_lowercase();
    keys::BINDINGS
        .iter()
        .map(|b| (keys::keys_text(b), b.what))
        .chain(keys::GESTURES.iter().map(|&(k, w)| (k.to_owned(), w)))
        .filter(|(keys, what)| {
            needle.is_empty()
                || keys.to_lowercase().contains(&needle)
                || what.to_lowercase().contains(&needle)
        })
        .collect()
}

//! The outliner: objects (with kind, counts and visibility) and lights; selection, rename,
//! duplicate, delete; adding and deleting lights.

use thicket_core::scene::{Object, ObjectKind};

use crate::editor::{Editor, Selection};
use crate::files::thousands;

/// UI-only state of the outliner (the inline rename field).
#[derive(Debug, Default)]
pub struct OutlinerState {
    renaming: Option<(u64, String)>,
    focus_pending: bool,
}

impl OutlinerState {
    /// Starts renaming object `id` in place.
    pub fn start_rename(&mut self, editor: &Editor, id: u64) {
        if let Some(o) = editor.object(id) {
            self.renaming = Some((id, o.name.clone()));
            self.focus_pending = true;
        }
    }
}

/// A kind icon and a count for a row.
fn kind_summary(o: &Object) -> (&'static str, String, String) {
    match &o.kind {
        ObjectKind::Voxels(v) => (
            "VOX",
            format!("{} vox", thousands(v.svo.leaf_count())),
            "Voxel model (sparse voxel octree)".to_owned(),
        ),
        ObjectKind::Mesh(m) => (
            "MESH",
            format!("{} tri", thousands(m.model.triangle_count() as u64)),
            "Triangle mesh".to_owned(),
        ),
        ObjectKind::Krs(k) => (
            "KRS",
            format!("{} inst", crate::files::thousands_u128(k.instance_count())),
            "Kernel-reflection sequence (procedural kernel instances)".to_owned(),
        ),
    }
}

fn kind_color(icon: &str) -> egui::Color32 {
    if icon == "VOX" {
        egui::Color32::from_rgb(120, 190, 255)
    } else if icon == "KRS" {
        egui::Color32::from_rgb(140, 210, 120)
    } else {
        egui::Color32::from_rgb(230, 180, 100)
    }
}

enum RowAction {
    Select,
    Visible(bool),
    Rename,
    CommitRename(String),
    CancelRename,
    Duplicate,
    Delete,
    Frame,
}

/// What the lights section asked for (applied after drawing, as the object rows' actions).
enum LightAction {
    Add,
    Select(usize),
    Delete(usize),
}

/// Draws the outliner.
pub fn outliner_ui(
    ui: &mut egui::Ui,
    editor: &mut Editor,
    state: &mut OutlinerState,
    status: &mut String,
) {
    ui.heading("Outliner");
    ui.separator();
    let mut actions: Vec<(u64, RowAction)> = Vec::new();
    let mut light_actions: Vec<LightAction> = Vec::new();
    egui::ScrollArea::vertical().show(ui, |ui| {
        if editor.doc().objects.is_empty() {
            ui.weak("No objects. Use File > Import… to add a model.");
        }
        for o in &editor.doc().objects {
            let selected = editor.selection == Some(Selection::Object(o.id));
            ui.horizontal(|ui| {
                let mut visible = o.visible;
                if ui
                    .checkbox(&mut visible, "")
                    .on_hover_text("Visible (H)")
                    .changed()
                {
                    actions.push((o.id, RowAction::Visible(visible)));
                }
                let (icon, count, kind_tip) = kind_summary(o);
                ui.label(
                    egui::RichText::new(icon)
                        .small()
                        .monospace()
                        .color(kind_color(icon)),
                )
                .on_hover_text(kind_tip.clone());
                match &mut state.renaming {
                    Some((id, text)) if *id == o.id => {
                        let edit = ui.add(egui::TextEdit::singleline(text).desired_width(120.0));
                        if state.focus_pending {
                            edit.request_focus();
                            state.focus_pending = false;
                        }
                        if ui.input(|i| i.key_pressed(egui::Key::Escape)) {
                            actions.push((o.id, RowAction::CancelRename));
                        } else if edit.lost_focus() {
                            actions.push((o.id, RowAction::CommitRename(text.clone())));
                        }
                    }
                    _ => {
                        let row = ui.selectable_label(selected, &o.name).on_hover_text(
                            "Click to select, double-click to rename, right-click for more",
                        );
                        if row.clicked() {
                            actions.push((o.id, RowAction::Select));
                        }
                        if row.double_clicked() {
                            actions.push((o.id, RowAction::Rename));
                        }
                        row.context_menu(|ui| {
                            if ui.button("Rename").on_hover_text("F2").clicked() {
                                actions.push((o.id, RowAction::Rename));
                                ui.close();
                            }
                            if ui.button("Duplicate").on_hover_text("Ctrl+D").clicked() {
                                actions.push((o.id, RowAction::Duplicate));
                                ui.close();
                            }
                            if ui.button("Frame").on_hover_text("F").clicked() {
                                actions.push((o.id, RowAction::Frame));
                                ui.close();
                            }
                            if ui.button("Delete").on_hover_text("Delete").clicked() {
                                actions.push((o.id, RowAction::Delete));
                                ui.close();
                            }
                        });
                    }
                }
                ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                    if ui
                        .small_button("Del")
                        .on_hover_text(format!("Delete {:?} (undoable)", o.name))
                        .clicked()
                    {
                        actions.push((o.id, RowAction::Delete));
                    }
                    if ui
                        .small_button("Dup")
                        .on_hover_text(format!("Duplicate {:?}", o.name))
                        .clicked()
                    {
                        actions.push((o.id, RowAction::Duplicate));
                    }
                    // Only when it fits: in a narrow panel it would run under the name.
                    if ui.available_width() >= count.len() as f32 * 7.0 + 4.0 {
                        ui.weak(count).on_hover_text(kind_tip);
                    }
                });
            });
        }
        ui.add_space(8.0);
        ui.horizontal(|ui| {
            ui.label(egui::RichText::new("Lights").strong());
            ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                if ui
                    .small_button("Add light")
                    .on_hover_text(
                        "Add a directional light that casts shadows, from a side the others \
                         do not light (undoable)",
                    )
                    .clicked()
                {
                    light_actions.push(LightAction::Add);
                }
            });
        });
        let lights: Vec<String> = editor.doc().lights.iter().map(|l| l.name.clone()).collect();
        if lights.is_empty() {
            ui.weak("No lights: only the ambient light shows. Add light adds one.");
        }
        for (i, name) in lights.iter().enumerate() {
            let selected = editor.selection == Some(Selection::Light(i));
            ui.horizontal(|ui| {
                let row = ui
                    .selectable_label(selected, format!("Light: {name}"))
                    .on_hover_text("Directional light: select to edit, right-click for more");
                if row.clicked() {
                    light_actions.push(LightAction::Select(i));
                }
                row.context_menu(|ui| {
                    if ui.button("Delete light").on_hover_text("Delete").clicked() {
                        light_actions.push(LightAction::Delete(i));
                        ui.close();
                    }
                });
                ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                    if ui
                        .small_button("Del")
                        .on_hover_text(format!("Delete light {name:?} (undoable)"))
                        .clicked()
                    {
                        light_actions.push(LightAction::Delete(i));
                    }
                });
            });
        }
    });

    for action in light_actions {
        let result = match action {
            LightAction::Add => editor.add_light(editor.new_light()).map(|_| ()),
            LightAction::Select(i) => {
                editor.selection = Some(Selection::Light(i));
                Ok(())
            }
            LightAction::Delete(i) => editor.delete_light(i),
        };
        if let Err(e) = result {
            *status = e.to_string();
        }
    }

    for (id, action) in actions {
        let result = match action {
            RowAction::Select => {
                editor.selection = Some(Selection::Object(id));
                Ok(())
            }
            RowAction::Visible(v) => editor.set_visible(id, v),
            RowAction::Rename => {
                state.start_rename(editor, id);
                Ok(())
            }
            RowAction::CommitRename(name) => {
                state.renaming = None;
                editor.rename(id, &name)
            }
            RowAction::CancelRename => {
                state.renaming = None;
                Ok(())
            }
            RowAction::Duplicate => editor.duplicate(id).map(|_| ()),
            RowAction::Delete => editor.delete(id),
            RowAction::Frame => {
                editor.selection = Some(Selection::Object(id));
                editor.frame_selection();
                Ok(())
            }
        };
        if let Err(e) = result {
            *status = e.to_string();
        }
    }
}

//! The Palette panel: the selected model's palette and the colours its voxels use (with
//! counts). A click picks the colour for Add and Paint, a double-click edits it and replaces it
//! everywhere in the model (inside the voxel selection when there is one); palettes load from
//! and save to `.gpl`, `.png` strips and (loading) `.vox` files.

use thicket_core::scene::ObjectKind;
use thicket_core::sculpt::palette::model_colors;

use crate::editor::Editor;
use crate::files::thousands;

/// A colour being edited: which one, and its new value.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Editing {
    from: [u8; 4],
    to: [u8; 4],
}

/// A model's colours with their voxel counts, for one object and content key.
type ColorCache = ((u64, (u64, u64)), Vec<([u8; 4], u64)>);

/// The panel's state.
#[derive(Debug, Default)]
pub struct PalettePanel {
    /// Whether the window is open.
    pub open: bool,
    /// The model colours, cached for one object and content key.
    colors: Option<ColorCache>,
    editing: Option<Editing>,
    /// The last message (a replace, a load or an error).
    pub message: Option<(String, bool)>,
}

/// What the panel asks the app to do (file prompts live in the app).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PaletteRequest {
    /// Ask for a palette file to load into the selected model.
    Load,
    /// Ask where to save the selected model's palette.
    Save,
}

fn swatch(ui: &mut egui::Ui, c: [u8; 4], selected: bool) -> egui::Response {
    let (rect, resp) = ui.allocate_exact_size(egui::vec2(18.0, 18.0), egui::Sense::click());
    // Named by its hex value for screen readers (and the UI tests).
    resp.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Button, true, hex(c)));
    ui.painter()
        .rect_filled(rect, 2.0, egui::Color32::from_rgb(c[0], c[1], c[2]));
    if selected {
        ui.painter().rect_stroke(
            rect,
            2.0,
            egui::Stroke::new(2.0, egui::Color32::WHITE),
            egui::StrokeKind::Outside,
        );
    }
    resp
}

fn hex(c: [u8; 4]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

impl PalettePanel {
    /// Draws the window. `color` is the tools' current colour (a click sets it). Returns a file
    /// request for the app.
    pub fn ui(
        &mut self,
        ctx: &egui::Context,
        editor: &mut Editor,
        color: &mut [u8; 4],
    ) -> Option<PaletteRequest> {
        if !self.open {
            return None;
        }
        let mut request = None;
        let mut open = true;
        egui::Window::new("Palette")
            .open(&mut open)
            .default_width(260.0)
            .show(ctx, |ui| {
                let Some(id) = editor.selected_voxel_model() else {
                    ui.weak("Select a voxel model to see its colours.");
                    return;
                };
                let key = (id, editor.content_key());
                if self.colors.as_ref().is_none_or(|c| c.0 != key) {
                    let list = match editor.object(id).map(|o| &o.kind) {
                        Some(ObjectKind::Voxels(v)) => model_colors(&v.svo),
                        _ => Vec::new(),
                    };
                    self.colors = Some((key, list));
                }
                let palette = match editor.object(id).map(|o| &o.kind) {
                    Some(ObjectKind::Voxels(v)) => v.palette.clone(),
                    _ => Vec::new(),
                };
                ui.horizontal(|ui| {
                    if ui
                        .button("Load…")
                        .on_hover_text("Load a palette (.gpl, a .png strip, or a .vox file's palette) into this model")
                        .clicked()
                    {
                        request = Some(PaletteRequest::Load);
                    }
                    if ui
                        .add_enabled(!palette.is_empty(), egui::Button::new("Save…"))
                        .on_hover_text("Save this model's palette as .gpl or a .png strip")
                        .clicked()
                    {
                        request = Some(PaletteRequest::Save);
                    }
                    if ui
                        .button("From model")
                        .on_hover_text("Make the model's colours (most used first) its palette")
                        .clicked()
                    {
                        let colors: Vec<[u8; 4]> = self
                            .colors
                            .as_ref()
                            .map(|c| c.1.iter().take(256).map(|e| e.0).collect())
                            .unwrap_or_default();
                        self.report(editor.set_palette(id, colors).map(|()| "Palette set from the model's colours".into()));
                    }
                    if ui
                        .add_enabled(palette.len() < 256 && !palette.contains(color), egui::Button::new("Add colour"))
                        .on_hover_text("Add the current colour to the palette")
                        .clicked()
                    {
                        let mut p = palette.clone();
                        p.push(*color);
                        self.report(editor.set_palette(id, p).map(|()| "Colour added".into()));
                    }
                });
                if !palette.is_empty() {
                    ui.label(format!("Palette ({} colours)", palette.len()));
                    ui.horizontal_wrapped(|ui| {
                        ui.spacing_mut().item_spacing = egui::vec2(2.0, 2.0);
                        for (i, c) in palette.iter().enumerate() {
                            let r = swatch(ui, *c, *c == *color)
                                .on_hover_text(format!("{} {} (double-click to edit)", i + 1, hex(*c)));
                            if r.double_clicked() {
                                self.editing = Some(Editing { from: *c, to: *c });
                            } else if r.clicked() {
                                *color = *c;
                            }
                        }
                    });
                }
                let used = self.colors.as_ref().map(|c| c.1.clone()).unwrap_or_default();
                ui.separator();
                ui.label(format!("Colours in the model ({})", used.len()));
                egui::ScrollArea::vertical().max_height(220.0).show(ui, |ui| {
                    for (c, n) in &used {
                        ui.horizontal(|ui| {
                            let r = swatch(ui, *c, *c == *color)
                                .on_hover_text("Click: use this colour · double-click: replace it everywhere");
                            if r.double_clicked() {
                                self.editing = Some(Editing { from: *c, to: *c });
                            } else if r.clicked() {
                                *color = *c;
                            }
                            ui.monospace(hex(*c));
                            ui.weak(format!("{} voxels", thousands(*n)));
                        });
                    }
                });
                if let Some(mut e) = self.editing {
                    ui.separator();
                    ui.horizontal(|ui| {
                        ui.label(format!("Replace {} with", hex(e.from)));
                        let mut c = egui::Color32::from_rgb(e.to[0], e.to[1], e.to[2]);
                        if ui.color_edit_button_srgba(&mut c).changed() {
                            e.to = [c.r(), c.g(), c.b(), 255];
                        }
                    });
                    ui.horizontal(|ui| {
                        let scope = if editor.voxel_selection().is_some_and(|s| s.object == id) {
                            "in the selection"
                        } else {
                            "everywhere"
                        };
                        if ui.button(format!("Replace {scope}")).clicked() {
                            let r = editor.replace_color(id, e.from, e.to);
                            self.report(r.map(|o| o.message("Replace colour")));
                            self.editing = None;
                            *color = e.to;
                        } else if ui.button("Cancel").clicked() {
                            self.editing = None;
                        } else {
                            self.editing = Some(e);
                        }
                    });
                }
                if let Some((m, err)) = &self.message {
                    if *err {
                        ui.colored_label(ui.visuals().error_fg_color, m);
                    } else {
                        ui.weak(m);
                    }
                }
            });
        if !open {
            self.open = false;
        }
        request
    }

    /// Sets the colour the colour being edited is replaced with (what the replace row's colour
    /// button sets); false when no colour is being edited.
    pub fn set_replacement(&mut self, to: [u8; 4]) -> bool {
        match &mut self.editing {
            Some(e) => {
                e.to = to;
                true
            }
            None => false,
        }
    }

    fn report(&mut self, r: Result<String, crate::editor::CommandError>) {
        self.message = Some(match r {
            Ok(m) => (m, false),
            Err(e) => (e.to_string(), true),
        });
    }
}

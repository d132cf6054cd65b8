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

/// `#rrggbb` of a colour (alpha left out).
#[must_use]
pub fn hex(c: [u8; 4]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// The opaque colour of `#RRGGBB` text (the `#` optional, either case, spaces around
/// ignored); `None` for anything else.
#[must_use]
pub fn parse_hex(text: &str) -> Option<[u8; 4]> {
    let t = text.trim();
    let t = t.strip_prefix('#').unwrap_or(t);
    if t.len() != 6 || !t.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let byte = |i: usize| u8::from_str_radix(&t[i..i + 2], 16).ok();
    Some([byte(0)?, byte(2)?, byte(4)?, 255])
}

/// The 256-colour grid of a model without a palette, laid out like MagicaVoxel's default: the
/// 6×6×6 web-safe cube from white to black, then ramps of red, green, blue and grey.
#[must_use]
pub fn default_grid() -> Vec<[u8; 4]> {
    let mut out = Vec::with_capacity(256);
    for r in (0..6u8).rev() {
        for g in (0..6u8).rev() {
            for b in (0..6u8).rev() {
                out.push([r * 51, g * 51, b * 51, 255]);
            }
        }
    }
    // The shades between the cube's steps of 51.
    let ramp = [238u8, 221, 187, 170, 136, 119, 85, 68, 34, 17];
    for channel in 0..4 {
        for v in ramp {
            out.push(match channel {
                0 => [v, 0, 0, 255],
                1 => [0, v, 0, 255],
                2 => [0, 0, v, 255],
                _ => [v, v, v, 255],
            });
        }
    }
    out
}

/// Most swatches the tool bar shows.
pub const SWATCHES: usize = 16;

/// Colours a model without colours of its own offers (sRGB).
const STARTER_COLORS: [[u8; 4]; 12] = [
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

/// Where a swatch's colour comes from (its tooltip).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SwatchSource {
    /// Used by this many voxels of the model.
    Used(u64),
    /// In the model's palette, unused.
    Palette,
    /// A starter colour (the model has fewer colours than swatches).
    Starter,
}

/// Swatches for one object and content key (`None`: no voxel model selected).
type SwatchCache = (Option<(u64, (u64, u64))>, Vec<([u8; 4], SwatchSource)>);

/// The tool bar's colour controls: the colour button, `#RRGGBB` entry, the 256-colour grid and
/// the swatches of the selected model's own colours. Their place in the bar never depends on
/// the tool.
#[derive(Debug, Clone, Default)]
pub struct ColorBar {
    /// The swatches, cached.
    swatches: Option<SwatchCache>,
    /// The hex field's text.
    hex_text: String,
    /// The colour the hex field last showed (when the colour changes elsewhere it follows).
    hex_shown: Option<[u8; 4]>,
    /// Why the typed text was refused.
    pub hex_error: Option<String>,
}

impl ColorBar {
    /// The swatches: the model's colours most used first, then its unused palette entries,
    /// then starter colours, [`SWATCHES`] in all. Recounted when the model changes, but not
    /// while a button is down (a stroke changes it every frame).
    fn swatches(&mut self, ui: &egui::Ui, editor: &Editor) -> Vec<([u8; 4], SwatchSource)> {
        let id = editor.selected_voxel_model();
        let key = id.map(|id| (id, editor.content_key()));
        let stale = self.swatches.as_ref().is_none_or(|s| s.0 != key);
        let stroking = ui.input(|i| i.pointer.any_down()) && self.swatches.is_some();
        if stale && !stroking {
            let mut list: Vec<([u8; 4], SwatchSource)> = Vec::with_capacity(SWATCHES);
            if let Some(ObjectKind::Voxels(v)) =
                id.and_then(|id| editor.object(id)).map(|o| &o.kind)
            {
                list.extend(
                    model_colors(&v.svo)
                        .into_iter()
                        .take(SWATCHES)
                        .map(|(c, n)| (c, SwatchSource::Used(n))),
                );
                for c in &v.palette {
                    if list.len() < SWATCHES && !list.iter().any(|e| e.0 == *c) {
                        list.push((*c, SwatchSource::Palette));
                    }
                }
            }
            for c in STARTER_COLORS {
                if list.len() < SWATCHES && !list.iter().any(|e| e.0 == c) {
                    list.push((c, SwatchSource::Starter));
                }
            }
            self.swatches = Some((key, list));
        }
        self.swatches
            .as_ref()
            .map(|s| s.1.clone())
            .unwrap_or_default()
    }

    /// The colour controls in one row; `color` is the tools' colour. The grid shows the
    /// selected model's palette, else [`default_grid`].
    pub fn bar_ui(&mut self, ui: &mut egui::Ui, editor: &Editor, color: &mut [u8; 4]) {
        let mut c = egui::Color32::from_rgb(color[0], color[1], color[2]);
        if ui
            .color_edit_button_srgba(&mut c)
            .on_hover_text("Colour of Add and Paint (Alt+click in the view picks one)")
            .changed()
        {
            *color = [c.r(), c.g(), c.b(), 255];
        }
        self.hex_ui(ui, color);
        self.grid_ui(ui, editor, color);
        ui.scope(|ui| {
            ui.spacing_mut().item_spacing.x = 3.0;
            let swatches = self.swatches(ui, editor);
            for i in 0..SWATCHES {
                let (rect, resp) =
                    ui.allocate_exact_size(egui::vec2(14.0, 14.0), egui::Sense::click());
                let Some(&(c, source)) = swatches.get(i) else {
                    // An empty slot keeps the controls after the swatches in place.
                    continue;
                };
                resp.widget_info(|| {
                    egui::WidgetInfo::labeled(
                        egui::Role::Button,
                        true,
                        format!("Swatch {}: {}", i + 1, hex(c)),
                    )
                });
                ui.painter()
                    .rect_filled(rect, 2.0, egui::Color32::from_rgb(c[0], c[1], c[2]));
                if *color == c {
                    ui.painter().rect_stroke(
                        rect,
                        2.0,
                        egui::Stroke::new(2.0, egui::Color32::WHITE),
                        egui::StrokeKind::Outside,
                    );
                }
                let tip = match source {
                    SwatchSource::Used(n) => {
                        format!("{} · {} voxels of the model", hex(c), thousands(n))
                    }
                    SwatchSource::Palette => format!("{} · in the model's palette", hex(c)),
                    SwatchSource::Starter => format!("{} · a starter colour", hex(c)),
                };
                if resp.on_hover_text(tip).clicked() {
                    *color = c;
                }
            }
        });
    }

    /// The `#RRGGBB` field: Enter (or leaving it) sets the colour; other text is refused with
    /// [`ColorBar::hex_error`], shown in the tool bar.
    fn hex_ui(&mut self, ui: &mut egui::Ui, color: &mut [u8; 4]) {
        let label = ui.label("Hex");
        let id = ui.make_persistent_id("hex colour");
        let focused = ui.memory(|m| m.has_focus(id));
        if !focused && self.hex_shown != Some(*color) {
            self.hex_text = hex(*color);
            self.hex_shown = Some(*color);
            self.hex_error = None;
        }
        let r = ui
            .add(
                egui::TextEdit::singleline(&mut self.hex_text)
                    .id(id)
                    .font(egui::TextStyle::Monospace)
                    .char_limit(9)
                    .desired_width(
                        ui.fonts_mut(|f| {
                            f.glyph_width(&egui::TextStyle::Monospace.resolve(ui.style()), '0')
                        }) * 9.0,
                    )
                    .hint_text("#RRGGBB"),
            )
            .labelled_by(label.id)
            .on_hover_text("The colour as #RRGGBB (six hex digits); Enter sets it");
        if r.lost_focus() {
            match parse_hex(&self.hex_text) {
                Some(c) => {
                    *color = c;
                    self.hex_text = hex(c);
                    self.hex_shown = Some(c);
                    self.hex_error = None;
                }
                None => {
                    self.hex_error = Some(format!(
                        "{:?} is not a colour: type #RRGGBB (six hex digits)",
                        self.hex_text.trim()
                    ));
                }
            }
        }
    }

    /// The 256-colour grid in a popup: a click picks the colour.
    fn grid_ui(&mut self, ui: &mut egui::Ui, editor: &Editor, color: &mut [u8; 4]) {
        let palette = match editor
            .selected_voxel_model()
            .and_then(|id| editor.object(id))
            .map(|o| &o.kind)
        {
            Some(ObjectKind::Voxels(v)) if !v.palette.is_empty() => Some(v.palette.clone()),
            _ => None,
        };
        let r = ui.menu_button("256…", |ui| {
            ui.label(if palette.is_some() {
                "The model's palette"
            } else {
                "Default palette (the model has none)"
            });
            let cells = palette.clone().unwrap_or_else(default_grid);
            // 16 columns of 14-point cells a point apart, laid out by hand so every cell's
            // place is fixed from the first frame.
            const CELL: f32 = 14.0;
            const STEP: f32 = CELL + 1.0;
            let rows = cells.len().div_ceil(16);
            let (area, _) = ui.allocate_exact_size(
                egui::vec2(16.0 * STEP, rows as f32 * STEP),
                egui::Sense::hover(),
            );
            for (i, c) in cells.iter().enumerate() {
                let min = area.min + egui::vec2((i % 16) as f32, (i / 16) as f32) * STEP;
                let rect = egui::Rect::from_min_size(min, egui::vec2(CELL, CELL));
                let resp = ui.interact(
                    rect,
                    ui.make_persistent_id(("grid cell", i)),
                    egui::Sense::click(),
                );
                resp.widget_info(|| {
                    egui::WidgetInfo::labeled(
                        egui::Role::Button,
                        true,
                        format!("Grid {}: {}", i + 1, hex(*c)),
                    )
                });
                ui.painter()
                    .rect_filled(rect, 1.0, egui::Color32::from_rgb(c[0], c[1], c[2]));
                if *color == *c {
                    ui.painter().rect_stroke(
                        rect,
                        1.0,
                        egui::Stroke::new(2.0, egui::Color32::WHITE),
                        egui::StrokeKind::Inside,
                    );
                }
                if resp.on_hover_text(hex(*c)).clicked() {
                    *color = *c;
                    ui.close();
                }
            }
        });
        r.response.on_hover_text(
            "Pick from a grid of 256 colours: the model's palette, or the default one",
        );
    }
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

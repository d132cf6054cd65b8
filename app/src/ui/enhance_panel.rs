//! The inspector's Detail enhancement section: per-model settings (method, factor, thresholds,
//! probes, colour, lighting). Enhancing links the model to a new object holding the fine model;
//! from then on every stroke on the coarse model re-enhances only the region it touched.

use thicket_core::enhance::{ColorMode, EnhanceSettings, Method, ThresholdPattern};

use crate::editor::{Editor, Selection};
use crate::files::thousands;

/// UI state of the section: the settings being edited (applied by Enhance / Re-enhance) and
/// the request the app turns into a background job.
#[derive(Debug, Default)]
pub struct EnhancePanel {
    /// Settings being edited, for which model.
    draft: Option<(u64, EnhanceSettings)>,
    /// Enhance this model with these settings (taken by the app after the frame).
    pub request: Option<(u64, EnhanceSettings)>,
    /// Why the last command was refused.
    pub error: Option<String>,
}

/// Draws the Detail enhancement section for voxel model `id`.
pub fn enhance_ui(ui: &mut egui::Ui, editor: &mut Editor, panel: &mut EnhancePanel, id: u64) {
    if let Some(link) = editor.doc().enhancement_into(id).cloned() {
        egui::CollapsingHeader::new("Detail enhancement")
            .default_open(true)
            .show(ui, |ui| {
                let name = editor
                    .object(link.source)
                    .map_or_else(|| format!("id {}", link.source), |o| o.name.clone());
                ui.label(format!("Enhancement of {name}, x{}", link.settings.factor))
                    .on_hover_text(
                        "This model follows its coarse source: sculpt the source (strokes in the \
                         view go to it) and this one is re-enhanced where the stroke touched",
                    );
                if ui
                    .button("Select source")
                    .on_hover_text("Select the coarse model to change the settings")
                    .clicked()
                {
                    editor.selection = Some(Selection::Object(link.source));
                }
            });
        return;
    }
    let stored = editor.doc().enhancement_of(id).cloned();
    egui::CollapsingHeader::new("Detail enhancement")
        .default_open(stored.is_some())
        .show(ui, |ui| {
            if panel.draft.as_ref().is_none_or(|(d, _)| *d != id) {
                let s = stored
                    .as_ref()
                    .map(|l| l.settings.clone())
                    .unwrap_or_default();
                panel.draft = Some((id, s));
            }
            let Some((_, draft)) = panel.draft.as_mut() else {
                return;
            };
            settings_ui(ui, draft);
            let check = draft.validate();
            if let Err(e) = &check {
                ui.colored_label(ui.visuals().error_fg_color, format!("Refused: {e}"));
            }
            let draft = draft.clone();
            match &stored {
                None => {
                    if ui
                        .add_enabled(check.is_ok(), egui::Button::new("Enhance"))
                        .on_hover_text(
                            "Add the enhanced model as a new object and hide this one; strokes \
                             on this model then re-enhance only the region they touch (background \
                             job, cancellable, undoable)",
                        )
                        .clicked()
                    {
                        panel.request = Some((id, draft));
                    }
                }
                Some(link) => {
                    let target = editor
                        .object(link.target)
                        .map_or_else(|| "(deleted)".to_owned(), |o| o.name.clone());
                    ui.label(format!("Linked to {target}: updated while sculpting"))
                        .on_hover_text(
                            "After every dab, undo and redo the fine model is re-enhanced \
                             around the voxels that changed; the result equals enhancing the \
                             whole model again",
                        );
                    ui.horizontal(|ui| {
                        if ui
                            .add_enabled(
                                check.is_ok() && draft != link.settings,
                                egui::Button::new("Re-enhance"),
                            )
                            .on_hover_text(
                                "Enhance the whole model again with the changed settings \
                                 (background job; one undo step)",
                            )
                            .clicked()
                        {
                            panel.request = Some((id, draft.clone()));
                        }
                        if ui
                            .button("Revert settings")
                            .on_hover_text("Show the settings the enhancement was made with")
                            .clicked()
                        {
                            panel.draft = Some((id, link.settings.clone()));
                        }
                        if ui
                            .button("Unlink")
                            .on_hover_text(
                                "Stop updating the enhanced model (both models stay; undoable)",
                            )
                            .clicked()
                        {
                            panel.error =
                                editor.unlink_enhancement(id).err().map(|e| e.to_string());
                        }
                    });
                    if let Some(u) = editor.last_enhance_update().filter(|u| u.source == id) {
                        ui.weak(format!(
                            "Last update: {} cells, {} fine voxels written, {:.1} ms{}",
                            thousands(u.cells),
                            thousands(u.fine_changes as u64),
                            u.millis,
                            if u.rebuilt { " (rebuilt first)" } else { "" }
                        ))
                        .on_hover_text(
                            "The last incremental re-enhancement: coarse cells recomputed and \
                             fine voxels that changed",
                        );
                    }
                }
            }
            if let Some(e) = editor.enhance_error.as_ref().or(panel.error.as_ref()) {
                ui.colored_label(ui.visuals().error_fg_color, e);
            }
        });
}

/// The typed editors of one settings value.
fn settings_ui(ui: &mut egui::Ui, s: &mut EnhanceSettings) {
    egui::Grid::new("enhance_settings")
        .num_columns(2)
        .striped(true)
        .show(ui, |ui| {
            ui.label("Method").on_hover_text(
                "Recursive subdivision (powers of two, voxel-count thresholds) or direct \
                 resampling (any factor, probe-fraction thresholds)",
            );
            ui.horizontal(|ui| {
                let before = s.method;
                ui.selectable_value(&mut s.method, Method::Subdivide, "Subdivide")
                    .on_hover_text("Each voxel becomes 2x2x2 fragments, repeated (paper section 2)");
                ui.selectable_value(&mut s.method, Method::Resample, "Resample")
                    .on_hover_text("A stored random probe pattern decides each fragment (section 3)");
                if s.method != before && s.method == Method::Subdivide {
                    s.factor = s.factor.next_power_of_two().min(64);
                }
            });
            ui.end_row();
            ui.label("Factor")
                .on_hover_text("Fragments per voxel edge (subdivision: 2, 4, 8, 16, ...)");
            ui.add(egui::DragValue::new(&mut s.factor).range(1..=64).speed(0.1))
                .on_hover_text("Fragments per voxel edge, 1..=64");
            ui.end_row();
            let pattern = match s.method {
                Method::Subdivide => &mut s.subdivide.threshold,
                Method::Resample => &mut s.resample.threshold,
            };
            let (speed, max, tip) = match s.method {
                Method::Subdivide => (
                    0.05,
                    4.0,
                    "Solid neighbours (of the voxel and its three toward the fragment) needed, 1..=4",
                ),
                Method::Resample => (
                    0.01,
                    1.0,
                    "Fraction of probes that must land in solid voxels",
                ),
            };
            ui.label("Strata").on_hover_text(
                "Alternate the threshold with the fragment's altitude (even / odd layers)",
            );
            let mut strata = matches!(pattern, ThresholdPattern::Alternating { .. });
            if ui
                .checkbox(&mut strata, "")
                .on_hover_text("Alternate the threshold by altitude (the paper's 3/4 strata)")
                .changed()
            {
                let (even, _) = pattern.for_material(None);
                *pattern = if strata {
                    ThresholdPattern::Alternating { even, odd: even }
                } else {
                    ThresholdPattern::Constant { value: even }
                };
            }
            ui.end_row();
            match pattern {
                ThresholdPattern::Constant { value } => {
                    ui.label("Threshold").on_hover_text(tip);
                    ui.add(egui::DragValue::new(value).range(0.0..=max).speed(speed))
                        .on_hover_text(tip);
                    ui.end_row();
                }
                ThresholdPattern::Alternating { even, odd } => {
                    ui.label("Threshold even / odd").on_hover_text(tip);
                    ui.horizontal(|ui| {
                        ui.add(egui::DragValue::new(even).range(0.0..=max).speed(speed))
                            .on_hover_text("Threshold at even altitude");
                        ui.add(egui::DragValue::new(odd).range(0.0..=max).speed(speed))
                            .on_hover_text("Threshold at odd altitude");
                    });
                    ui.end_row();
                }
                ThresholdPattern::PerMaterial { default, materials } => {
                    ui.label("Threshold (other materials)").on_hover_text(tip);
                    ui.add(egui::DragValue::new(default).range(0.0..=max).speed(speed))
                        .on_hover_text(format!(
                            "{tip}; {} material(s) have their own threshold (set in the project file)",
                            materials.len()
                        ));
                    ui.end_row();
                }
            }
            if s.method == Method::Resample {
                let r = &mut s.resample;
                ui.label("Probes").on_hover_text("Probes per fragment");
                ui.add(egui::DragValue::new(&mut r.probe_count).range(1..=4096))
                    .on_hover_text("Probes per fragment, 1..=4096");
                ui.end_row();
                ui.label("Spread").on_hover_text("Probe offsets reach this many coarse voxels");
                ui.add(
                    egui::DragValue::new(&mut r.spread)
                        .range(0.0..=8.0)
                        .speed(0.01),
                )
                .on_hover_text("Probe spread in coarse voxels, 0..=8");
                ui.end_row();
                ui.label("Seed").on_hover_text("Seed of the stored probe pattern");
                ui.add(egui::DragValue::new(&mut r.seed))
                    .on_hover_text("Seed of the stored probe pattern");
                ui.end_row();
            }
            ui.label("Colour").on_hover_text(
                "How fragments take the colour of the voxels of their majority material",
            );
            ui.horizontal(|ui| {
                ui.selectable_value(&mut s.color, ColorMode::Blend, "Blend")
                    .on_hover_text("Weighted average of the contributing voxels");
                ui.selectable_value(&mut s.color, ColorMode::Nearest, "Nearest")
                    .on_hover_text("The strongest contributing voxel's colour");
            });
            ui.end_row();
            ui.label("Lighting").on_hover_text(
                "Bake random-walk (snowflake) sun and sky lighting into the fragment colours",
            );
            ui.checkbox(&mut s.lighting.enabled, "")
                .on_hover_text("Bake sun and sky lighting (slower: particles per fragment)");
            ui.end_row();
        });
}

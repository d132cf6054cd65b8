//! The inspector's Grow forest section (§7.2): repeat the selected tree over an area by more
//! reflections with empty kernel sets, optionally on a KRS terrain that shares them, or mixed
//! with other trees so no tree stands beside its own mirror image (§5). Once a forest stands,
//! every change regrows it live (a slider drag is one undo step).

use thicket_core::krs::KrsScene;
use thicket_core::krs::forest::{ForestParams, MAX_WARP_PRODUCT, check_params};
use thicket_core::scene::ObjectKind;

use crate::editor::{Editor, ForestReport, Selection};
use crate::files::thousands;

/// UI state: the settings being edited for a tree, and the last result.
#[derive(Debug, Default)]
pub struct ForestPanel {
    /// The first tree and the settings, trees mixed in and terrain being edited.
    draft: Option<Draft>,
    /// What the last growth placed.
    pub report: Option<ForestReport>,
    /// Why the last growth was refused.
    pub error: Option<String>,
}

#[derive(Debug, Clone, PartialEq)]
struct Draft {
    tree: u64,
    params: ForestParams,
    union: Vec<u64>,
    terrain: Option<u64>,
}

/// Levels (powers of two) along an axis for `count` trees with `stride` cells per object.
fn levels_of(count: u32, stride: u32) -> u32 {
    (count / stride.max(1)).max(1).ilog2()
}

/// A fresh draft for tree `id`: 8 × 8 trees 2.4 bounding radii apart (crowns just clear).
fn fresh(editor: &Editor, id: u64) -> Draft {
    let radius = editor
        .object(id)
        .and_then(thicket_core::scene::Object::krs_in_world)
        .and_then(|k| KrsScene { objects: vec![k] }.prepare().ok())
        .and_then(|s| s.objects[0].bound_world)
        .map_or(5.0, |(_, r)| r);
    let side = (8.0 * 2.4 * radius).round().max(1.0);
    Draft {
        tree: id,
        params: ForestParams {
            area: [side, side],
            ..ForestParams::default()
        },
        union: Vec::new(),
        terrain: None,
    }
}

/// Draws the Grow forest section for KRS object `id` (a tree the builder made, or part of a
/// forest).
pub fn forest_ui(ui: &mut egui::Ui, editor: &mut Editor, panel: &mut ForestPanel, id: u64) {
    let link = editor.forest_of(id).cloned();
    let is_tree = editor.tree_params(id).is_some();
    if link.is_none() && !is_tree {
        return;
    }
    if let Some(l) = &link
        && l.terrain == Some(id)
    {
        ui.weak(format!(
            "This terrain carries a forest's reflections after its own {}: select the forest to change it",
            l.terrain_mirrors
        ));
        return;
    }
    egui::CollapsingHeader::new("Forest")
        .default_open(link.is_some())
        .show(ui, |ui| {
            let first = link.as_ref().map_or(id, |l| l.sources[0]);
            let stored = link.as_ref().map(|l| Draft {
                tree: l.sources[0],
                params: l.params,
                union: l.sources[1..].to_vec(),
                terrain: l.terrain,
            });
            if panel.draft.as_ref().is_none_or(|d| d.tree != first) {
                panel.draft = Some(stored.clone().unwrap_or_else(|| fresh(editor, first)));
                panel.report = None;
                panel.error = None;
            }
            // Undo / redo change the stored settings under an open panel: follow them.
            if let Some(s) = &stored
                && !editor_dragging(ui)
                && panel.draft.as_ref() != Some(s)
            {
                panel.draft = Some(s.clone());
            }
            let Some(draft) = panel.draft.as_mut() else {
                return;
            };
            ui.label(
                "Repeat the tree over an area by more reflections with empty kernel sets \
                 (KRS paper §7.2); neighbours are its mirror images unless you mix in other trees.",
            );
            let before = draft.clone();
            let (changed, released) = settings_ui(ui, editor, draft, first);
            let kinds = 1 + draft.union.len();
            let check = check_params(&draft.params, kinds);
            if let Err(e) = &check {
                ui.colored_label(ui.visuals().error_fg_color, format!("Refused: {e}"));
            }
            let draft = draft.clone();
            let sources: Vec<u64> = std::iter::once(draft.tree)
                .chain(draft.union.iter().copied())
                .collect();
            let grow = |editor: &mut Editor, panel: &mut ForestPanel| match editor.grow_forest(
                &sources,
                draft.terrain,
                &draft.params,
            ) {
                Ok(r) => {
                    panel.report = Some(r);
                    panel.error = None;
                }
                Err(e) => panel.error = Some(e.to_string()),
            };
            match &link {
                None => {
                    if ui
                        .add_enabled(check.is_ok(), egui::Button::new("Grow forest"))
                        .on_hover_text(
                            "Add the forest as new objects and hide the tree (its first cell \
                             draws it); the settings then regrow it live (undoable)",
                        )
                        .clicked()
                    {
                        editor.end_interaction();
                        grow(editor, panel);
                        editor.end_interaction();
                        if panel.error.is_none()
                            && let Some(grown) = editor
                                .forest_of(first)
                                .and_then(|l| l.objects.first().copied())
                        {
                            editor.selection = Some(Selection::Object(grown));
                            editor.frame_forest(grown);
                        }
                    }
                }
                Some(_) => {
                    if changed && before != draft && check.is_ok() {
                        grow(editor, panel);
                    }
                    if released {
                        editor.end_interaction();
                    }
                    ui.horizontal(|ui| {
                        if ui
                            .button("Regrow")
                            .on_hover_text(
                                "Grow again from the trees as they are now (after editing a tree \
                                 in the builder)",
                            )
                            .clicked()
                        {
                            editor.end_interaction();
                            grow(editor, panel);
                            editor.end_interaction();
                        }
                        if ui
                            .button("Remove forest")
                            .on_hover_text(
                                "Delete the grown objects, show the trees again and give the \
                                 terrain back its own reflections (undoable)",
                            )
                            .clicked()
                        {
                            panel.error = editor.remove_forest(id).err().map(|e| e.to_string());
                            editor.selection = Some(Selection::Object(first));
                        }
                    });
                }
            }
            if let Some(e) = &panel.error {
                ui.colored_label(ui.visuals().error_fg_color, format!("Refused: {e}"));
            }
            if let (Some(r), Some(_)) = (&panel.report, &link) {
                let mut text = format!(
                    "{} trees, {:.2} × {:.2} apart",
                    thousands(r.total),
                    r.spacing[0],
                    r.spacing[1]
                );
                if r.crowns_overlap {
                    text.push_str("; crowns wider than the spacing meet between the trees");
                }
                ui.weak(text);
            }
        });
}

/// Whether a pointer drag is under way (the panel does not reload stored settings then).
fn editor_dragging(ui: &egui::Ui) -> bool {
    ui.ctx().dragged_id().is_some()
}

/// The settings rows; returns (something changed, a drag or an edit ended this frame).
fn settings_ui(ui: &mut egui::Ui, editor: &Editor, d: &mut Draft, first: u64) -> (bool, bool) {
    let mut changed = false;
    let mut released = false;
    let mut track = |r: &egui::Response| {
        changed |= r.changed();
        released |= r.drag_stopped() || r.lost_focus();
    };
    let kinds = 1 + d.union.len() as u32;
    let stride = if kinds > 1 { [kinds, 2] } else { [1, 1] };
    egui::Grid::new("forest_settings")
        .num_columns(2)
        .striped(true)
        .show(ui, |ui| {
            for (axis, i) in [("x", 0usize), ("z", 1)] {
                ui.label(format!("Trees along {axis}")).on_hover_text(
                    "Each reflection level doubles the trees along its axis; a mix of K trees \
                     takes K (along x) or 2 (along z) times a power of two",
                );
                let mut levels = levels_of(d.params.trees[i], stride[i]);
                let s = stride[i];
                let r = ui.add(
                    egui::Slider::new(&mut levels, 0..=12)
                        .custom_formatter(move |v, _| thousands(u64::from(s) << (v as u32)))
                        .custom_parser(move |t| {
                            let n: f64 = t.trim().replace(',', "").parse().ok()?;
                            Some((n / f64::from(s)).max(1.0).log2().round())
                        }),
                );
                track(&r);
                d.params.trees[i] = s << levels;
                ui.end_row();
            }
            for (axis, i) in [("x", 0usize), ("z", 1)] {
                ui.label(format!("Area along {axis}"))
                    .on_hover_text("Extent of the forest in world units; spacing = area / trees");
                let r = ui.add(
                    egui::DragValue::new(&mut d.params.area[i])
                        .speed(1.0)
                        .range(0.1..=1.0e6),
                );
                track(&r);
                ui.end_row();
            }
            ui.label("Spacing");
            ui.weak(format!(
                "{:.2} × {:.2}",
                d.params.area[0] / d.params.trees[0] as f32,
                d.params.area[1] / d.params.trees[1] as f32
            ));
            ui.end_row();
            ui.label("Jitter").on_hover_text(
                "Largest turn of a mirror off its axis (radians): rows stop lining up (§5)",
            );
            track(&ui.add(egui::Slider::new(&mut d.params.jitter, 0.0..=0.5)));
            ui.end_row();
            ui.label("Spread")
                .on_hover_text("Largest change of a gap between trees, as a share of the spacing");
            track(&ui.add(egui::Slider::new(&mut d.params.spread, 0.0..=0.45)));
            ui.end_row();
            ui.label("Tilt").on_hover_text(
                "Largest tilt of a mirror out of the vertical (radians), on a terrain only: the \
                 ground rises and falls and the trees lean with it",
            );
            track(&ui.add_enabled(
                d.terrain.is_some(),
                egui::Slider::new(&mut d.params.tilt, 0.0..=0.3),
            ));
            ui.end_row();
            ui.label("Warp").on_hover_text(
                "Amplitude of a Lipschitz warp that bends every tree differently (world units; \
                 rays take up to 1 + 9 × warp × frequency times as many steps)",
            );
            let most = MAX_WARP_PRODUCT / d.params.warp_frequency.max(1e-3);
            track(&ui.add(egui::Slider::new(&mut d.params.warp, 0.0..=most.min(10.0))));
            ui.end_row();
            ui.label("Warp frequency")
                .on_hover_text("Cycles of the warp per world unit");
            track(&ui.add(egui::Slider::new(&mut d.params.warp_frequency, 0.01..=2.0)));
            ui.end_row();
            ui.label("Seed")
                .on_hover_text("Another seed, another draw of the mirrors");
            track(&ui.add(egui::DragValue::new(&mut d.params.seed)));
            ui.end_row();
        });
    // Other trees to mix in, and a terrain to stand on.
    let trees: Vec<(u64, String)> = editor
        .doc()
        .objects
        .iter()
        .filter(|o| o.id != first && editor.tree_params(o.id).is_some())
        .filter(|o| {
            editor
                .forest_of(o.id)
                .is_none_or(|l| l.sources.contains(&o.id))
        })
        .map(|o| (o.id, o.name.clone()))
        .collect();
    ui.label("Mix in trees").on_hover_text(
        "A union of different trees (§5): each stands between others, never beside its own \
         mirror image. Not on a terrain (each tree needs its own reflections)",
    );
    if trees.is_empty() {
        ui.weak("No other tree the builder made is in the scene.");
    }
    for (tid, name) in &trees {
        let mut on = d.union.contains(tid);
        if ui.checkbox(&mut on, name).changed() {
            if on {
                d.union.push(*tid);
            } else {
                d.union.retain(|t| t != tid);
            }
            // Counts follow the new stride: keep the levels.
            let k = 1 + d.union.len() as u32;
            let (old, new) = (stride, if k > 1 { [k, 2] } else { [1, 1] });
            for i in 0..2 {
                d.params.trees[i] = new[i] << levels_of(d.params.trees[i], old[i]);
            }
            changed = true;
            released = true;
        }
    }
    let grounds: Vec<(u64, String)> = editor
        .doc()
        .objects
        .iter()
        .filter(|o| matches!(o.kind, ObjectKind::Krs(_)))
        .filter(|o| o.id != first && editor.tree_params(o.id).is_none())
        .filter(|o| {
            editor
                .forest_of(o.id)
                .is_none_or(|l| l.terrain == Some(o.id))
        })
        .map(|o| (o.id, o.name.clone()))
        .collect();
    ui.horizontal(|ui| {
        ui.label("Stand on").on_hover_text(
            "A KRS terrain takes the forest's reflections after its own, so every trunk stands \
             on the ground, on slopes too",
        );
        let name = |t: Option<u64>| {
            t.and_then(|t| grounds.iter().find(|(g, _)| *g == t))
                .map_or("flat ground".to_owned(), |(_, n)| n.clone())
        };
        let before = d.terrain;
        egui::ComboBox::from_id_salt("forest_terrain")
            .selected_text(name(d.terrain))
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut d.terrain, None, "flat ground");
                for (g, n) in &grounds {
                    ui.selectable_value(&mut d.terrain, Some(*g), n);
                }
            });
        if d.terrain != before {
            changed = true;
            released = true;
        }
    });
    (changed, released)
}

//! The inspector's Rig section for voxel models: skeleton authoring in the rest pose (Place
//! joints in the view, templates, rename, reparent, move, mirror, delete), binding (automatic
//! weights on a worker with progress and Cancel), weight painting with the selected joint's
//! weights shown as a heat map, and clips. The editor does the work (`editor::rig`).

use glam::Vec3;
use thicket_core::skin::BindMethod;

use super::pose::PoseTool;
pub use super::rig_setup::{RigSetup, WeightMode};
use crate::editor::{Editor, SkeletonTemplate};

fn note(tool: &mut PoseTool, r: Result<(), crate::editor::CommandError>) {
    tool.rig.error = r.err().map(|e| e.to_string());
}

/// The Rig section of the inspector for voxel model `id`.
pub fn rig_setup_ui(ui: &mut egui::Ui, editor: &mut Editor, tool: &mut PoseTool, id: u64) {
    // Open for a model without a skeleton (where rigging starts); a rigged model opens on Pose.
    egui::CollapsingHeader::new("Rig")
        .default_open(editor.rig(id).is_none())
        .show(ui, |ui| {
            if let Some(e) = &tool.rig.error {
                ui.colored_label(ui.visuals().error_fg_color, format!("Refused: {e}"));
            }
            let rig = editor.rig(id).cloned();
            let joints = rig.as_ref().map_or(0, |r| r.skeleton.len());
            ui.horizontal_wrapped(|ui| {
                ui.toggle_value(&mut tool.rig.placing, "Place joints")
                    .on_hover_text(
                        "Click on the model: a joint lands at the middle of its thickness under \
                         the pointer, as a child of the selected joint (successive clicks chain \
                         bones). Click a joint's dot to branch from it. Drag the selected \
                         joint's arrows (the model's X, Y, Z) to move it in the rest pose.",
                    );
                ui.label("Template:");
                for t in SkeletonTemplate::ALL {
                    if ui
                        .button(t.label())
                        .on_hover_text(format!(
                            "Replace the skeleton with a {} fitted to the model's bounds \
                             (undoable)",
                            t.label().to_lowercase()
                        ))
                        .clicked()
                    {
                        let r = editor.apply_skeleton_template(id, t);
                        note(tool, r);
                    }
                }
            });
            if tool.rig.placing {
                ui.weak(if joints == 0 {
                    "Click on the model to place the root joint."
                } else {
                    "Click on the model to add a joint under the selected one (yellow)."
                });
            }
            let Some(rig) = rig else {
                ui.weak("No skeleton: place joints on the model or start from a template.");
                return;
            };
            if let Some(sel) = tool.valid_joint(editor).filter(|s| s.object == id) {
                joint_setup_ui(ui, editor, tool, id, sel.joint);
            } else {
                ui.weak(format!(
                    "{joints} joint(s). Select one (in the Pose list or by its dot) to edit it."
                ));
            }
            ui.separator();
            bind_ui(ui, editor, tool, id, &rig);
            ui.separator();
            weights_ui(ui, tool, &rig);
            ui.separator();
            clips_ui(ui, editor, tool, id, &rig);
        });
}

fn joint_setup_ui(ui: &mut egui::Ui, editor: &mut Editor, tool: &mut PoseTool, id: u64, j: usize) {
    let Ok(spec) = editor.skeleton_spec(id) else {
        return;
    };
    let Some(joint) = spec.joints.get(j).cloned() else {
        return;
    };
    ui.horizontal(|ui| {
        ui.label("Joint");
        // The text being typed is kept while the field has the keyboard; otherwise the field
        // shows the joint's name as it is now (after an undo, another selection, a delete).
        let mut text = match &tool.rig.name_edit {
            Some((k, t)) if *k == (id, j) => t.clone(),
            _ => joint.name.clone(),
        };
        let r = ui.add(egui::TextEdit::singleline(&mut text).desired_width(120.0));
        if r.lost_focus() {
            if text != joint.name {
                let res = editor.rename_joint(id, j, &text);
                note(tool, res);
            }
            tool.rig.name_edit = None;
        } else if r.has_focus() {
            tool.rig.name_edit = Some(((id, j), text));
        }
    });
    ui.horizontal(|ui| {
        ui.label("Parent");
        // A joint's own subtree is not offered as its parent.
        let below = spec.subtree(j);
        let current = joint
            .parent
            .clone()
            .unwrap_or_else(|| "(none: a root)".into());
        let mut choice: Option<Option<usize>> = None;
        egui::ComboBox::from_id_salt("joint_parent")
            .selected_text(current)
            .show_ui(ui, |ui| {
                if ui
                    .selectable_label(joint.parent.is_none(), "(none: a root)")
                    .clicked()
                {
                    choice = Some(None);
                }
                for (k, other) in spec.joints.iter().enumerate() {
                    if below.contains(&k) {
                        continue;
                    }
                    let on = joint.parent.as_deref() == Some(other.name.as_str());
                    if ui.selectable_label(on, &other.name).clicked() {
                        choice = Some(Some(k));
                    }
                }
            });
        if let Some(parent) = choice {
            match editor.reparent_joint(id, j, parent) {
                Ok(k) => {
                    tool.select_joint(id, k);
                    tool.rig.error = None;
                }
                Err(e) => tool.rig.error = Some(e.to_string()),
            }
        }
    });
    ui.horizontal(|ui| {
        ui.label("Rest position");
        let mut p = Vec3::from(joint.position);
        let mut changed = false;
        let mut stopped = false;
        for (axis, label) in ["x", "y", "z"].iter().enumerate() {
            let r = ui.add(
                egui::DragValue::new(&mut p[axis])
                    .speed(0.01)
                    .prefix(format!("{label} ")),
            );
            changed |= r.changed();
            stopped |= r.drag_stopped() || r.lost_focus();
        }
        if changed {
            let r = editor.move_joint(id, j, p);
            note(tool, r);
        }
        if stopped {
            editor.end_interaction();
        }
    })
    .response
    .on_hover_text("Where the joint stands in the rest pose, in the model's own units");
    ui.horizontal(|ui| {
        if ui
            .button("Mirror chain")
            .on_hover_text(
                "Copy this joint and the chain below it across the model's X centre, naming \
                 the copies .R for .L (and back)",
            )
            .clicked()
        {
            match editor.mirror_chain(id, j) {
                Ok(copy) => {
                    tool.select_joint(id, copy);
                    tool.rig.error = None;
                }
                Err(e) => tool.rig.error = Some(e.to_string()),
            }
        }
        if ui
            .button("Delete joint")
            .on_hover_text("Remove the joint; its children move to its parent, its weight too")
            .clicked()
        {
            let r = editor.delete_joint(id, j);
            note(tool, r);
            tool.joint = None;
        }
    });
}

fn bind_ui(
    ui: &mut egui::Ui,
    editor: &Editor,
    tool: &mut PoseTool,
    id: u64,
    rig: &thicket_core::skin::Rig,
) {
    let skinned = matches!(
        editor.object(id).map(|o| &o.kind),
        Some(thicket_core::scene::ObjectKind::Voxels(v)) if v.svo.has_skin()
    );
    let imported = rig.reference_mesh.is_some();
    let state = match (&rig.binding, skinned) {
        (None, true) if imported => "Weights: imported with the model.".to_owned(),
        (None, _) | (_, false) => {
            "Weights: none yet (the model follows its root). Bind computes them.".to_owned()
        }
        (Some(b), true) if rig.weights_stale() => format!(
            "Weights: {} binding of an earlier skeleton (joints changed since): bind again, or \
             keep them as they are.",
            b.method.name()
        ),
        (Some(b), true) => format!("Weights: {} binding of this skeleton.", b.method.name()),
    };
    ui.label(state);
    ui.horizontal(|ui| {
        egui::ComboBox::from_id_salt("bind_method")
            .selected_text(tool.rig.method.name())
            .show_ui(ui, |ui| {
                for (m, tip) in [
                    (
                        BindMethod::Geodesic,
                        "Distances through the model's voxels: limbs resting on the body take \
                         nothing from it",
                    ),
                    (
                        BindMethod::Envelope,
                        "Straight-line distances (weights leak across gaps)",
                    ),
                    (
                        BindMethod::Rigid,
                        "One joint per voxel, for blocky characters",
                    ),
                ] {
                    ui.selectable_value(&mut tool.rig.method, m, m.name())
                        .on_hover_text(tip);
                }
            });
        if ui
            .button("Bind")
            .on_hover_text(
                "Compute every voxel's weights (at most four joints each) from the skeleton, \
                 with progress and Cancel; one undo step",
            )
            .clicked()
        {
            tool.rig.bind_request = Some((id, tool.rig.method));
        }
    });
    if let Some(r) = &tool.rig_report {
        ui.weak(r);
    }
}

fn weights_ui(ui: &mut egui::Ui, tool: &mut PoseTool, rig: &thicket_core::skin::Rig) {
    let joint = tool
        .joint
        .and_then(|j| rig.skeleton.joints.get(j.joint))
        .map(|j| j.name.clone());
    ui.horizontal(|ui| {
        ui.checkbox(&mut tool.rig.show_weights, "Show weights")
            .on_hover_text(
                "Colour the model by the selected joint's weight (blue 0 to red 1); drawn by the \
                 CPU preview",
            );
        ui.toggle_value(&mut tool.rig.painting, "Paint weights")
            .on_hover_text(
                "Drag on the model to paint the selected joint's weight; the other joints are \
                 renormalised. One undo step per stroke.",
            );
    });
    if tool.rig.painting {
        ui.horizontal(|ui| {
            ui.selectable_value(&mut tool.rig.mode, WeightMode::Add, "Add");
            ui.selectable_value(&mut tool.rig.mode, WeightMode::Subtract, "Subtract");
            ui.selectable_value(&mut tool.rig.mode, WeightMode::Smooth, "Smooth");
        });
        ui.add(egui::Slider::new(&mut tool.rig.radius, 0.5..=32.0).text("radius (voxels)"));
        ui.add(egui::Slider::new(&mut tool.rig.strength, 0.05..=1.0).text("strength"));
    }
    if tool.rig.painting || tool.rig.show_weights {
        ui.weak(match joint {
            Some(name) => format!("Joint {name:?}"),
            None => "Select a joint to paint or show its weights".into(),
        });
    }
}

fn clips_ui(
    ui: &mut egui::Ui,
    editor: &mut Editor,
    tool: &mut PoseTool,
    id: u64,
    rig: &thicket_core::skin::Rig,
) {
    ui.label(format!("Clips: {}", rig.clips.len()));
    let mut action: Option<Result<(), crate::editor::CommandError>> = None;
    for (i, c) in rig.clips.iter().enumerate() {
        let playing = rig.playback.clip == Some(i);
        ui.horizontal(|ui| {
            // The field being typed in keeps its text; the others show the clip's name.
            let mut text = match &tool.rig.clip_edit {
                Some((k, t)) if *k == i => t.clone(),
                _ => c.name.clone(),
            };
            let r = ui.add(egui::TextEdit::singleline(&mut text).desired_width(90.0));
            if r.lost_focus() {
                if text != c.name {
                    action = Some(editor.rename_clip(id, i, &text));
                }
                tool.rig.clip_edit = None;
            } else if r.has_focus() {
                tool.rig.clip_edit = Some((i, text));
            }
            let mut length = c.duration_secs;
            let r = ui
                .add(
                    egui::DragValue::new(&mut length)
                        .range(0.05..=3600.0)
                        .speed(0.05)
                        .suffix(" s"),
                )
                .on_hover_text("The clip's length (never shorter than its last key)");
            if r.changed() {
                // A drag is one undo step.
                let merge = Some(crate::editor::MergeKey::Rig(id));
                action = Some(editor.set_clip_length_merged(id, i, length, merge));
            }
            if r.drag_stopped() || r.lost_focus() {
                editor.end_interaction();
            }
            if ui
                .selectable_label(playing, if playing { "Playing" } else { "Play it" })
                .on_hover_text("Make this the clip the timeline plays")
                .clicked()
                && !playing
            {
                let mut p = rig.playback;
                p.clip = Some(i);
                p.time_secs = 0.0;
                action = Some(editor.set_playback(id, p));
            }
            if ui
                .small_button("Duplicate")
                .on_hover_text("Copy the clip (to vary it)")
                .clicked()
            {
                action = Some(editor.duplicate_clip(id, i).map(|_| ()));
            }
            if ui
                .small_button("Delete")
                .on_hover_text("Remove the clip (undoable)")
                .clicked()
            {
                action = Some(editor.delete_clip(id, i));
                tool.rig.clip_edit = None;
            }
        });
    }
    if let Some(r) = action {
        note(tool, r);
    }
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut tool.rig.clip_name).desired_width(90.0));
        ui.add(
            egui::DragValue::new(&mut tool.rig.clip_length)
                .range(0.05..=600.0)
                .speed(0.05)
                .suffix(" s"),
        );
        if ui
            .button("New clip")
            .on_hover_text(
                "Add an empty clip of this length and play it; pose joints and press Set key \
                 on the timeline (or turn on Auto-key)",
            )
            .clicked()
        {
            let name = tool.rig.clip_name.trim().to_owned();
            let r = editor.new_clip(id, &name, tool.rig.clip_length).map(|_| ());
            note(tool, r);
        }
    });
}

/// Whether left drags in the view paint weights now (the view does not orbit on them then).
#[must_use]
pub fn paints_now(editor: &Editor, tool: &PoseTool) -> bool {
    tool.rig.painting
        && editor.selected_voxel_model().is_some_and(|id| {
            editor.rig(id).is_some() && tool.joint.is_some_and(|j| j.object == id)
        })
}

/// Place joints (a click) and paint weights (a drag) in the view. `pointer_ray` is the world
/// ray under the pointer, `pick` the voxel there. Returns whether the input was used.
pub fn view_input(
    response: &egui::Response,
    editor: &mut Editor,
    tool: &mut PoseTool,
    proj: &super::projector::Projector,
    pointer_ray: Option<(Vec3, Vec3)>,
    pick: Option<&crate::editor::VoxelPick>,
) -> bool {
    let Some(id) = editor.selected_voxel_model() else {
        return false;
    };
    if paints_now(editor, tool) {
        let down = response.is_pointer_button_down_on() || response.clicked();
        if down && let (Some(p), Some(j)) = (pick.filter(|p| p.object == id), tool.joint) {
            let (amount, smooth) = match tool.rig.mode {
                WeightMode::Add => (tool.rig.strength, false),
                WeightMode::Subtract => (-tool.rig.strength, false),
                WeightMode::Smooth => (0.0, true),
            };
            let centre = p.voxel.as_vec3() + 0.5;
            let r = editor
                .paint_weights(id, j.joint, centre, tool.rig.radius, amount, smooth)
                .map(|_| ());
            note(tool, r);
        }
        if response.drag_stopped() || response.clicked() {
            editor.end_interaction();
        }
        return true;
    }
    if tool.rig.placing && response.clicked() {
        let hit = response
            .interact_pointer_pos()
            .and_then(|p| tool.pick_joint(editor, proj, p))
            .filter(|j| j.object == id);
        if let Some(j) = hit {
            tool.select_joint(id, j.joint);
            return true;
        }
        let Some((o, d)) = pointer_ray else {
            return true;
        };
        let Some(at) = editor.mid_thickness(id, o, d) else {
            tool.rig.error = Some("click on the model to place a joint".into());
            return true;
        };
        let parent = tool
            .valid_joint(editor)
            .filter(|j| j.object == id)
            .map(|j| j.joint);
        match editor.add_joint(id, parent, at, None) {
            Ok(k) => {
                tool.select_joint(id, k);
                tool.rig.error = None;
            }
            Err(e) => tool.rig.error = Some(e.to_string()),
        }
        return true;
    }
    false
}

//! The inspector: the selection's real values. Transforms and lights are edited through
//! validated commands (a refused value leaves the document unchanged and shows why); the
//! quality knobs have a draft / balanced / final preset row.

use glam::{EulerRot, Quat, Vec3};
use thicket_core::quality::{KNOB_SPECS, KnobKind, KnobSpec, Quality, QualityPreset};
use thicket_core::scene::{Light, Object, ObjectKind, Transform};
use thicket_core::skin::StretchStrategy;

use super::krs_panel::{KrsPanel, krs_inspector_ui};
use super::pose::{PoseTool, rig_inspector_ui};
use crate::editor::{Editor, Selection};
use crate::files::{ObjectInfo, human_bytes, object_info, thousands};

/// UI-only state: the last refusal message and a cache of the selected object's summary
/// (bounds and memory statistics visit every voxel, so they are not recomputed every frame).
#[derive(Debug, Default)]
pub struct InspectorState {
    /// Why the last edit was refused, shown under the field.
    pub error: Option<String>,
    cache: Option<(CacheKey, ObjectInfo)>,
    /// The Detail enhancement section.
    pub enhance: super::enhance_panel::EnhancePanel,
    /// The Grow forest section.
    pub forest: super::forest_panel::ForestPanel,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct CacheKey {
    content: (u64, u64),
    id: u64,
}

/// Draws the inspector.
pub fn inspector_ui(
    ui: &mut egui::Ui,
    editor: &mut Editor,
    state: &mut InspectorState,
    pose: &mut PoseTool,
    krs: &mut KrsPanel,
) {
    ui.heading("Inspector");
    ui.separator();
    egui::ScrollArea::vertical().show(ui, |ui| {
        match editor.selection {
            Some(Selection::Object(id)) => {
                if let Some(object) = editor.object(id).cloned() {
                    object_ui(ui, editor, state, &object);
                    if matches!(object.kind, ObjectKind::Voxels(_)) {
                        super::enhance_panel::enhance_ui(ui, editor, &mut state.enhance, id);
                    }
                    if matches!(object.kind, ObjectKind::Voxels(_)) {
                        super::rig_panel::rig_setup_ui(ui, editor, pose, id);
                    }
                    match &object.kind {
                        ObjectKind::Voxels(v) if v.rig.is_some() => {
                            rig_inspector_ui(ui, editor, pose, id);
                        }
                        ObjectKind::Krs(_) => {
                            super::forest_panel::forest_ui(ui, editor, &mut state.forest, id);
                            krs_inspector_ui(ui, editor, krs, id);
                        }
                        ObjectKind::Voxels(_) | ObjectKind::Mesh(_) => {}
                    }
                }
            }
            Some(Selection::Light(i)) => {
                if let Some(light) = editor.doc().lights.get(i).cloned() {
                    light_ui(ui, editor, state, i, light);
                }
            }
            None => {
                ui.weak("Nothing selected. Click an object or a light in the outliner.");
            }
        }
        if let Some(e) = &state.error {
            ui.colored_label(ui.visuals().error_fg_color, format!("Refused: {e}"));
        }
        ui.add_space(8.0);
        egui::CollapsingHeader::new("Render quality")
            .default_open(false)
            .show(ui, |ui| quality_ui(ui, editor, state));
    });
}

fn cached_info<'a>(editor: &Editor, state: &'a mut InspectorState, o: &Object) -> &'a ObjectInfo {
    let key = CacheKey {
        content: editor.content_key(),
        id: o.id,
    };
    if state.cache.as_ref().is_none_or(|(k, _)| *k != key) {
        state.cache = Some((key, object_info(o)));
    }
    let (_, info) = state.cache.get_or_insert_with(|| (key, object_info(o)));
    info
}

fn row(ui: &mut egui::Ui, label: &str, value: impl Into<egui::WidgetText>, tip: &str) {
    ui.label(label).on_hover_text(tip);
    ui.label(value);
    ui.end_row();
}

fn object_ui(ui: &mut egui::Ui, editor: &mut Editor, state: &mut InspectorState, o: &Object) {
    ui.label(egui::RichText::new(&o.name).heading());
    ui.weak(format!("{} · id {}", o.kind_name(), o.id));
    ui.add_space(4.0);

    egui::CollapsingHeader::new("Transform")
        .default_open(true)
        .show(ui, |ui| transform_ui(ui, editor, state, o));

    let info = cached_info(editor, state, o).clone();
    egui::CollapsingHeader::new(match o.kind {
        ObjectKind::Voxels(_) => "Voxels",
        ObjectKind::Mesh(_) => "Mesh",
        ObjectKind::Krs(_) => "KRS",
    })
    .default_open(true)
    .show(ui, |ui| {
        egui::Grid::new("object_stats")
            .num_columns(2)
            .striped(true)
            .show(ui, |ui| match &o.kind {
                ObjectKind::Voxels(v) => {
                    row(ui, "Voxels", thousands(info.voxels.unwrap_or(0)), "Solid leaf voxels");
                    row(
                        ui,
                        "Depth",
                        format!("{} ({}³)", v.svo.depth(), v.svo.extent()),
                        "Octree levels below the root; the grid is 2^depth voxels per axis",
                    );
                    if let Some(d) = info.dimensions_voxels {
                        row(
                            ui,
                            "Extent",
                            format!("{} × {} × {} voxels", d[0], d[1], d[2]),
                            "Bounding box of the solid voxels",
                        );
                    }
                    row(
                        ui,
                        "Voxel size",
                        format!("{}", v.voxel_size),
                        "Edge of one voxel in object units",
                    );
                    row(
                        ui,
                        "Origin",
                        format!("{:.3} {:.3} {:.3}", v.origin.x, v.origin.y, v.origin.z),
                        "Object-space position of voxel (0,0,0)",
                    );
                    if let Some(bpv) = info.bytes_per_voxel {
                        row(
                            ui,
                            "Bytes / voxel",
                            format!("{bpv:.2}"),
                            "Whole octree (nodes, LOD and leaf attributes, free slots) per solid voxel",
                        );
                    }
                    row(
                        ui,
                        "Memory",
                        human_bytes(info.memory.total_bytes),
                        &format!(
                            "{} structure + {} leaf attributes + {} free slots",
                            human_bytes(info.memory.structure_bytes),
                            human_bytes(info.memory.payload_bytes),
                            human_bytes(info.memory.free_bytes)
                        ),
                    );
                    if info.memory.tiles > 0 {
                        row(
                            ui,
                            "Tiles",
                            format!(
                                "{} ({} voxels)",
                                thousands(info.memory.tiles),
                                thousands(info.memory.tile_voxels)
                            ),
                            "Full regions of one voxel value stored once (their voxels cost no memory of their own)",
                        );
                    }
                    if info.memory.interior_voxels > 0 {
                        row(
                            ui,
                            "Interior",
                            format!("{} voxels", thousands(info.memory.interior_voxels)),
                            "Enclosed voxels of a solid: never seen, so they store no colour; a carve that opens them shows the nearest surface's",
                        );
                    }
                    row(
                        ui,
                        "Skin weights",
                        if v.svo.has_skin() { "yes" } else { "no" },
                        "Whether voxels carry bone indices and weights",
                    );
                    if !v.material_names.is_empty() {
                        row(
                            ui,
                            "Materials",
                            v.material_names.join(", "),
                            "Named materials from the source file",
                        );
                    }
                }
                ObjectKind::Mesh(m) => {
                    row(ui, "Triangles", thousands(m.model.triangle_count() as u64), "");
                    row(ui, "Vertices", thousands(m.model.vertex_count() as u64), "");
                    row(ui, "Parts", m.model.parts.len().to_string(), "Triangle lists");
                    let names: Vec<&str> =
                        m.model.materials.iter().map(|mat| mat.name.as_str()).collect();
                    row(
                        ui,
                        "Materials",
                        format!("{} {}", names.len(), names.join(", ")),
                        "Material table",
                    );
                    row(
                        ui,
                        "Memory",
                        human_bytes(info.memory.total_bytes),
                        &format!(
                            "{} vertex and index arrays + {} textures",
                            human_bytes(info.memory.payload_bytes),
                            human_bytes(info.memory.texture_bytes)
                        ),
                    );
                }
                ObjectKind::Krs(k) => {
                    row(
                        ui,
                        "Instances",
                        crate::files::thousands_u128(k.instance_count()),
                        "Kernel instances: sum over non-empty kernel sets K_j of 2^(n-j)",
                    );
                    row(ui, "Mirrors", k.mirrors.len().to_string(), "Reflection levels n");
                    let kinds: Vec<&str> = k
                        .kernels
                        .iter()
                        .filter(|kernel| !kernel.is_empty())
                        .map(thicket_core::krs::Kernel::kind_name)
                        .collect();
                    row(
                        ui,
                        "Kernels",
                        format!("{} of {}", kinds.len(), k.kernels.len()),
                        &kinds.join(", "),
                    );
                    row(
                        ui,
                        "Distortion",
                        if k.distortion.is_some() { "yes" } else { "no" },
                        "Lipschitz-bounded noise warp hiding the symmetry",
                    );
                }
            });
        if let Some(size) = info.world_size {
            ui.weak(format!(
                "World size {:.3} × {:.3} × {:.3}",
                size[0], size[1], size[2]
            ));
        }
    });
}

/// Three DragValues for a vector; returns whether any changed.
fn vec3_ui(ui: &mut egui::Ui, v: &mut Vec3, speed: f64, tip: &str) -> bool {
    let mut changed = false;
    ui.horizontal(|ui| {
        for (axis, c) in ["x", "y", "z"].iter().zip([&mut v.x, &mut v.y, &mut v.z]) {
            changed |= ui
                .add(
                    egui::DragValue::new(c)
                        .speed(speed)
                        .prefix(format!("{axis} ")),
                )
                .on_hover_text(tip)
                .changed();
        }
    });
    changed
}

fn transform_ui(ui: &mut egui::Ui, editor: &mut Editor, state: &mut InspectorState, o: &Object) {
    let mut t = o.transform;
    let (ry, rx, rz) = t.rotation.to_euler(EulerRot::YXZ);
    let mut euler_deg = Vec3::new(rx.to_degrees(), ry.to_degrees(), rz.to_degrees());
    let mut changed = false;
    egui::Grid::new("transform").num_columns(2).show(ui, |ui| {
        ui.label("Position");
        changed |= vec3_ui(
            ui,
            &mut t.translation,
            0.01,
            "World-space translation; drag or type a number",
        );
        ui.end_row();
        ui.label("Rotation °");
        let rot_changed = vec3_ui(
            ui,
            &mut euler_deg,
            0.5,
            "Rotation in degrees about X, Y, Z (applied Y, X, Z)",
        );
        if rot_changed {
            t.rotation = Quat::from_euler(
                EulerRot::YXZ,
                euler_deg.y.to_radians(),
                euler_deg.x.to_radians(),
                euler_deg.z.to_radians(),
            );
            changed = true;
        }
        ui.end_row();
        ui.label("Scale");
        changed |= vec3_ui(
            ui,
            &mut t.scale,
            0.01,
            "Per-axis scale: finite and non-zero",
        );
        ui.end_row();
    });
    if ui
        .small_button("Reset")
        .on_hover_text("Identity transform (undoable)")
        .clicked()
    {
        t = Transform::default();
        changed = true;
    }
    if changed {
        state.error = editor.set_transform(o.id, t).err().map(|e| e.to_string());
    }
    motion_keys_ui(ui, editor, state, o.id);
}

/// Keys of the object's own transform (rigid per-object animation) at its playhead: the
/// rig's for a rigged model, else the object's motion timeline.
fn motion_keys_ui(ui: &mut egui::Ui, editor: &mut Editor, state: &mut InspectorState, id: u64) {
    let keys = editor.object_key_times(id);
    let (t, _) = editor.motion_clock(id);
    let on_key = keys
        .iter()
        .any(|k| (k - t).abs() < crate::editor::KEY_EPSILON_SECS);
    ui.horizontal(|ui| {
        if ui
            .small_button("Key transform")
            .on_hover_text(format!(
                "Store the position, rotation and scale at the playhead ({t:.2} s) as a key: the object then moves between its keys when the timeline plays (exported as a glTF node animation)"
            ))
            .clicked()
        {
            state.error = editor.set_object_key(id).err().map(|e| e.to_string());
        }
        if ui
            .add_enabled(on_key, egui::Button::new("Clear key").small())
            .on_hover_text("Remove the transform key at the playhead")
            .clicked()
        {
            state.error = editor.delete_object_key(id).err().map(|e| e.to_string());
        }
        ui.weak(match keys.len() {
            0 => "no keys".to_owned(),
            n => format!("{n} key(s)"),
        })
        .on_hover_text(
            keys.iter()
                .map(|k| format!("{k:.2} s"))
                .collect::<Vec<_>>()
                .join(", "),
        );
    });
}

fn light_ui(
    ui: &mut egui::Ui,
    editor: &mut Editor,
    state: &mut InspectorState,
    index: usize,
    mut light: Light,
) {
    ui.label(egui::RichText::new(format!("Light: {}", light.name)).heading());
    ui.weak("Directional light");
    let mut changed = false;
    egui::Grid::new("light").num_columns(2).show(ui, |ui| {
        ui.label("Direction");
        changed |= vec3_ui(
            ui,
            &mut light.direction,
            0.01,
            "Direction the light travels (from the light toward the scene); must be non-zero",
        );
        ui.end_row();
        ui.label("Colour");
        let mut rgb = light.color.to_array();
        if ui
            .color_edit_button_rgb(&mut rgb)
            .on_hover_text("Linear RGB colour")
            .changed()
        {
            light.color = Vec3::from_array(rgb);
            changed = true;
        }
        ui.end_row();
        ui.label("Intensity");
        changed |= ui
            .add(
                egui::DragValue::new(&mut light.intensity)
                    .speed(0.01)
                    .range(0.0..=1000.0),
            )
            .on_hover_text("Multiplier on the colour (0 or more)")
            .changed();
        ui.end_row();
        ui.label("Shadows");
        changed |= ui
            .checkbox(&mut light.casts_shadows, "")
            .on_hover_text("Whether this light casts shadows")
            .changed();
        ui.end_row();
    });
    if changed {
        state.error = editor.set_light(index, light).err().map(|e| e.to_string());
    }
}

fn quality_ui(ui: &mut egui::Ui, editor: &mut Editor, state: &mut InspectorState) {
    ui.horizontal(|ui| {
        for (label, preset, tip) in [
            ("Draft", QualityPreset::Draft, "Fastest preview"),
            ("Balanced", QualityPreset::Balanced, "The editor default"),
            (
                "Final",
                QualityPreset::Final,
                "Offline renders and references",
            ),
        ] {
            let active = editor.doc().quality == Quality::preset(preset);
            if ui
                .selectable_label(active, label)
                .on_hover_text(tip)
                .clicked()
            {
                editor.apply_quality_preset(preset);
            }
        }
    });
    let mut q = editor.doc().quality.clone();
    let mut changed = false;
    egui::Grid::new("quality")
        .num_columns(2)
        .striped(true)
        .show(ui, |ui| {
            // One row per knob from the knob table: numbers first, then switches (the
            // stretch strategy's choice last, below).
            let mut row = |ui: &mut egui::Ui, spec: &KnobSpec, q: &mut Quality| {
                let response = match spec.kind {
                    KnobKind::F32 {
                        get_mut, min, max, ..
                    } => Some(
                        ui.add(
                            egui::DragValue::new(get_mut(q))
                                .speed(0.01)
                                .range(min..=max),
                        ),
                    ),
                    KnobKind::U32 {
                        get_mut, min, max, ..
                    } => Some(ui.add(egui::DragValue::new(get_mut(q)).range(min..=max))),
                    KnobKind::Bool { get_mut, .. } => Some(ui.checkbox(get_mut(q), "")),
                    KnobKind::StretchStrategy { .. } => None,
                };
                if let Some(r) = response {
                    changed |= r.on_hover_text(spec.doc).changed();
                }
            };
            let order = |k: &KnobKind| match k {
                KnobKind::F32 { .. } => 0,
                KnobKind::U32 { .. } => 1,
                KnobKind::Bool { .. } => 2,
                KnobKind::StretchStrategy { .. } => 3,
            };
            for group in 0..3 {
                for spec in KNOB_SPECS.iter().filter(|k| order(&k.kind) == group) {
                    ui.label(spec.label).on_hover_text(spec.doc);
                    row(ui, spec, &mut q);
                    ui.end_row();
                }
            }
            let Some(strategy) = KNOB_SPECS.iter().find(|k| order(&k.kind) == 3) else {
                return;
            };
            let tip = strategy.doc;
            ui.label(strategy.label).on_hover_text(tip);
            let name = |s: Option<StretchStrategy>| match s {
                None => "Per model",
                Some(StretchStrategy::Off) => "Off",
                Some(StretchStrategy::Thesis) => "Thesis",
                Some(StretchStrategy::Corners) => "Corners",
                Some(StretchStrategy::Adaptive) => "Adaptive",
            };
            egui::ComboBox::from_id_salt("quality_stretch_strategy")
                .selected_text(name(q.stretch_strategy))
                .show_ui(ui, |ui| {
                    for s in [
                        None,
                        Some(StretchStrategy::Off),
                        Some(StretchStrategy::Thesis),
                        Some(StretchStrategy::Corners),
                        Some(StretchStrategy::Adaptive),
                    ] {
                        changed |= ui
                            .selectable_value(&mut q.stretch_strategy, s, name(s))
                            .changed();
                    }
                })
                .response
                .on_hover_text(tip);
            ui.end_row();
        });
    if changed {
        state.error = editor.set_quality(q).err().map(|e| e.to_string());
    }
}

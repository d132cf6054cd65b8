//! The KRS editor in the inspector: presets, the kernel list with typed parameter editors and
//! the mirror-plane list. Every change goes through [`Editor::set_krs`] (core's validation: a
//! refused value leaves the document unchanged and the message says which field and why); a
//! drag is one undo step. The mirror planes are drawn over the view as outlined quads.

use glam::{EulerRot, Quat, Vec3};
use thicket_core::krs::{
    BoxKernel, CapsuleKernel, Kernel, Material, MirrorPlane, PlaneKernel, SphereKernel,
    TorusKernel, TreeParams, presets,
};

use super::pose::distance_to_polyline;
use super::view::Projector;
use crate::editor::{Editor, Selection};

/// What the preset picker was matched against: the object id and the document's content key.
type PickerKey = (u64, (u64, u64));

/// UI state of the KRS editor.
#[derive(Debug, Default)]
pub struct KrsPanel {
    /// The mirror plane highlighted in the view.
    pub mirror: Option<usize>,
    /// Whether the inspector shows the KRS editor this frame (reset before the inspector is
    /// drawn): mirror planes, their gizmo and the tree route are drawn and picked only then,
    /// so they do not clutter the view of a KRS object that is not being edited.
    pub editor_open: bool,
    /// The preset picked in the combo box (an index into `krs::presets::all()`).
    pub preset: usize,
    /// Preset names from core (read once).
    names: Vec<&'static str>,
    /// The object and content the picker was last matched against (see
    /// [`krs_inspector_ui`]), and whether the object then equalled no preset.
    synced: Option<(PickerKey, bool)>,
    /// Why the last change was refused.
    pub error: Option<String>,
    /// A mirror-gizmo drag in progress.
    drag: Option<MirrorDrag>,
    /// Tree-builder parameters and the KRS object they build (None: the builder is closed).
    pub tree: Option<(u64, TreeParams)>,
    /// A tree-builder handle drag in progress: (handle index, its KRS-space position at the
    /// start, where the pointer started). Indices below the route's length are route points;
    /// `route.len() + k − 1` is the normal handle of the fork at `route[k]`.
    tree_drag: Option<(usize, Vec3, egui::Pos2)>,
}

const KINDS: [(&str, &str); 7] = [
    (
        "Empty",
        "No geometry at this level (an extra reflection only)",
    ),
    ("Sphere", "A ball"),
    ("InfinitePlane", "A half-space (rock and terrain)"),
    ("Capsule", "A segment swept by a ball"),
    ("RoundedBox", "An oriented box with rounded edges"),
    ("TorusSegment", "A torus segment with flat ends"),
    (
        "ToroidalCapsule",
        "A torus segment with capping spheres: the branch kernel",
    ),
];

fn default_kernel(kind: &str, material: Material) -> Kernel {
    match kind {
        "Sphere" => Kernel::Sphere(SphereKernel {
            material,
            ..SphereKernel::default()
        }),
        "InfinitePlane" => Kernel::InfinitePlane(PlaneKernel {
            material,
            ..PlaneKernel::default()
        }),
        "Capsule" => Kernel::Capsule(CapsuleKernel {
            material,
            ..CapsuleKernel::default()
        }),
        "RoundedBox" => Kernel::RoundedBox(BoxKernel {
            material,
            ..BoxKernel::default()
        }),
        "TorusSegment" => Kernel::TorusSegment(TorusKernel {
            material,
            ..TorusKernel::default()
        }),
        "ToroidalCapsule" => Kernel::ToroidalCapsule(TorusKernel {
            material,
            ..TorusKernel::default()
        }),
        _ => Kernel::Empty,
    }
}

/// A grid row of three DragValues; returns whether one changed.
fn vec3_row(ui: &mut egui::Ui, label: &str, v: &mut Vec3, speed: f64, tip: &str) -> bool {
    ui.label(label).on_hover_text(tip);
    let changed = ui.horizontal(|ui| vec3_fields(ui, v, speed, "", tip)).inner;
    ui.end_row();
    changed
}

/// Three DragValues for `v` in the current row, prefixed `{prefix}x`, `{prefix}y`, `{prefix}z`;
/// returns whether one changed.
fn vec3_fields(ui: &mut egui::Ui, v: &mut Vec3, speed: f64, prefix: &str, tip: &str) -> bool {
    let mut changed = false;
    for (axis, c) in ["x", "y", "z"].iter().zip([&mut v.x, &mut v.y, &mut v.z]) {
        changed |= ui
            .add(
                egui::DragValue::new(c)
                    .speed(speed)
                    .max_decimals(4)
                    .prefix(format!("{prefix}{axis} ")),
            )
            .on_hover_text(tip)
            .changed();
    }
    changed
}

/// A grid row of one DragValue limited to `range`; returns whether it changed.
fn f32_row(
    ui: &mut egui::Ui,
    label: &str,
    v: &mut f32,
    speed: f64,
    range: std::ops::RangeInclusive<f32>,
    tip: &str,
) -> bool {
    ui.label(label).on_hover_text(tip);
    let changed = ui
        .add(
            egui::DragValue::new(v)
                .speed(speed)
                .max_decimals(4)
                .range(range),
        )
        .on_hover_text(tip)
        .changed();
    ui.end_row();
    changed
}

/// A grid row of a label and a DragValue named by it (for screen readers and tests), with no
/// range: core's validation says what is out of range. Returns whether the value changed.
fn labelled_row<N: egui::emath::Numeric>(
    ui: &mut egui::Ui,
    label: &str,
    v: &mut N,
    speed: f64,
    tip: &str,
) -> bool {
    let name = ui.label(label).on_hover_text(tip);
    let changed = ui
        .add(egui::DragValue::new(v).speed(speed).max_decimals(4))
        .labelled_by(name.id)
        .on_hover_text(tip)
        .changed();
    ui.end_row();
    changed
}

/// The distortion editor: kind (none or the noise warp), amplitude, frequency, seed, and what
/// the warp costs: its Lipschitz bound L divides every distance estimate, so sphere-tracing steps
/// shrink to 1/L and a ray takes up to L times the evaluations.
fn distortion_ui(ui: &mut egui::Ui, k: &mut thicket_core::krs::KrsObject, id: u64) -> bool {
    let mut changed = false;
    ui.strong("Distortion").on_hover_text(
        "A smooth noise warp of object space that hides the mirror symmetry (paper §5.2)",
    );
    egui::Grid::new(("krs_distortion", id))
        .num_columns(2)
        .show(ui, |ui| {
            ui.label("Kind").on_hover_text("Whether space is warped");
            ui.horizontal(|ui| {
                let on = k.distortion.is_some();
                if ui
                    .selectable_label(!on, "No warp")
                    .on_hover_text("Exact distances: the fastest to trace")
                    .clicked()
                    && on
                {
                    k.distortion = None;
                    changed = true;
                }
                if ui
                    .selectable_label(on, "Noise warp")
                    .on_hover_text("p + A·noise(f·p): each component of the noise in [−1, 1]")
                    .clicked()
                    && !on
                {
                    k.distortion = Some(thicket_core::krs::Distortion::default());
                    changed = true;
                }
            });
            ui.end_row();
            if let Some(d) = &mut k.distortion {
                changed |= labelled_row(
                    ui,
                    "Amplitude",
                    &mut d.amplitude,
                    0.001,
                    "Largest displacement A per axis, in object units (≥ 0)",
                );
                changed |= labelled_row(
                    ui,
                    "Frequency",
                    &mut d.frequency,
                    0.01,
                    "Noise lattice cells per object unit f (≥ 0)",
                );
                changed |= labelled_row(ui, "Seed", &mut d.seed, 1.0, "Which noise field");
                let lipschitz = d.lipschitz_bound();
                let tip = "Distance estimates are divided by L = 1 + 9·A·f (the warp's Lipschitz bound) to stay safe for sphere tracing";
                ui.label("Lipschitz bound").on_hover_text(tip);
                ui.label(format!("L = {lipschitz:.3}")).on_hover_text(tip);
                ui.end_row();
                let tip = "Each sphere-tracing step is 1/L of the undistorted one, so a ray takes up to L times the distance evaluations";
                ui.label("Step cost").on_hover_text(tip);
                ui.label(format!(
                    "steps {:.0}% as long, up to {lipschitz:.2}× the evaluations",
                    100.0 / lipschitz
                ))
                .on_hover_text(tip);
                ui.end_row();
            }
        });
    changed
}

/// The texturing editor: mode, pattern, scale, contrast and triplanar sharpness (the colours
/// are the kernels' materials, edited with each kernel).
fn texturing_ui(ui: &mut egui::Ui, t: &mut thicket_core::krs::Texturing, id: u64) -> bool {
    use thicket_core::krs::{Pattern, TextureMode};
    let mut changed = false;
    ui.strong("Texturing")
        .on_hover_text("A procedural pattern over each kernel's colour (paper §6.2)");
    egui::Grid::new(("krs_texturing", id))
        .num_columns(2)
        .show(ui, |ui| {
            ui.label("Mode").on_hover_text("Which coordinates the pattern follows");
            ui.horizontal(|ui| {
                for (mode, name, tip) in [
                    (TextureMode::None, "Plain", "The kernels' colours only"),
                    (
                        TextureMode::Triplanar,
                        "Triplanar",
                        "Projected along X, Y and Z in object space: no repetition between instances (rock, terrain)",
                    ),
                    (
                        TextureMode::KernelParam,
                        "Along kernels",
                        "Along and around each kernel (branches): the same on every instance",
                    ),
                ] {
                    changed |= ui
                        .selectable_value(&mut t.mode, mode, name)
                        .on_hover_text(tip)
                        .changed();
                }
            });
            ui.end_row();
            ui.label("Pattern").on_hover_text("The procedural pattern");
            ui.horizontal(|ui| {
                for (pattern, name, tip) in [
                    (Pattern::Checker, "Checker", "Lighter and darker squares"),
                    (Pattern::Bark, "Bark", "Streaks of value noise"),
                ] {
                    changed |= ui
                        .selectable_value(&mut t.pattern, pattern, name)
                        .on_hover_text(tip)
                        .changed();
                }
            });
            ui.end_row();
            changed |= labelled_row(
                ui,
                "Scale",
                &mut t.scale,
                0.01,
                "Pattern cells per object unit (within ±1e6)",
            );
            changed |= labelled_row(
                ui,
                "Contrast",
                &mut t.contrast,
                0.01,
                "How far the pattern moves the colour, 0..1",
            );
            changed |= labelled_row(
                ui,
                "Sharpness",
                &mut t.sharpness,
                0.1,
                "Triplanar blend exponent, 0..64: higher gives sharper seams between projections",
            );
            ui.label("Colours").on_hover_text("Each kernel's material");
            ui.weak("each kernel's material, under Kernels");
            ui.end_row();
        });
    changed
}

/// Where "Add zone" puts a new empty zone: the centre of the object's world bounding ball, a
/// quarter of its radius (the origin and radius 1 for an unbounded object).
fn zone_hint(editor: &Editor, id: u64) -> (Vec3, f32) {
    editor
        .object(id)
        .and_then(thicket_core::scene::Object::krs_in_world)
        .and_then(|k| {
            let (c, r) = k.bounding_sphere_object()?;
            let t = k.world_from_object;
            Some((t.transform_point(c), 0.25 * r * t.scale))
        })
        .filter(|(c, r)| c.is_finite() && r.is_finite() && *r > 0.0)
        .unwrap_or((Vec3::ZERO, 1.0))
}

/// The empty zones: world-space balls inside which this object's geometry is removed (paper
/// §6.4), each with its centre and radius, removable; "Add zone" adds one at `hint`.
fn empty_zones_ui(
    ui: &mut egui::Ui,
    k: &mut thicket_core::krs::KrsObject,
    id: u64,
    hint: (Vec3, f32),
) -> bool {
    let mut changed = false;
    ui.strong("Empty zones").on_hover_text(
        "World-space balls inside which this object's geometry is removed (paper §6.4): a \
         clearing in a forest, room for rigid-body instances. Drawn in the view as circles.",
    );
    if k.empty_zones.is_empty() {
        ui.weak("None: the whole object is drawn");
    }
    // Drags move by about 1 % of the object's size per point.
    let speed = 0.01 * f64::from(hint.1.max(0.01));
    let mut remove = None;
    egui::Grid::new(("krs_zones", id))
        .num_columns(3)
        .striped(true)
        .show(ui, |ui| {
            for (i, z) in k.empty_zones.iter_mut().enumerate() {
                ui.label(format!("Z{i}"));
                ui.horizontal(|ui| {
                    changed |= vec3_fields(ui, &mut z.centre, speed, "", "Centre in world space");
                    changed |= ui
                        .add(
                            egui::DragValue::new(&mut z.radius)
                                .speed(speed)
                                .max_decimals(4)
                                .prefix("r "),
                        )
                        .on_hover_text("Radius in world units (≥ 0)")
                        .changed();
                });
                if ui
                    .small_button("Remove")
                    .on_hover_text("Remove this zone")
                    .clicked()
                {
                    remove = Some(i);
                }
                ui.end_row();
            }
        });
    if let Some(i) = remove {
        k.empty_zones.remove(i);
        changed = true;
    }
    if ui
        .button("Add zone")
        .on_hover_text(
            "A zone at the centre of the object's bounding ball, a quarter of its radius",
        )
        .clicked()
    {
        k.empty_zones.push(thicket_core::krs::EmptyZone {
            centre: hint.0,
            radius: hint.1,
        });
        changed = true;
    }
    changed
}

/// Draws the selected KRS object's empty zones as circles (the ball's outline as seen from the
/// eye), while the KRS editor is open.
pub fn paint_zones(painter: &egui::Painter, editor: &Editor, panel: &KrsPanel, proj: &Projector) {
    if !panel.editor_open {
        return;
    }
    let Some(Selection::Object(id)) = editor.selection else {
        return;
    };
    let Some(k) = editor.krs(id) else {
        return;
    };
    let eye = proj.camera.eye();
    let color = egui::Color32::from_rgb(255, 140, 90);
    for (i, z) in k.empty_zones.iter().enumerate() {
        let toward = z.centre - eye;
        let right = toward.cross(Vec3::Y).normalize_or(Vec3::X);
        let (Some(c), Some(edge)) = (
            proj.to_screen(z.centre),
            proj.to_screen(z.centre + right * z.radius),
        ) else {
            continue;
        };
        let r = c.distance(edge);
        if !(r.is_finite() && r > 0.5) {
            continue;
        }
        painter.circle_stroke(c, r, egui::Stroke::new(1.5, color));
        painter.text(
            c + egui::vec2(r * 0.7, -r * 0.7),
            egui::Align2::LEFT_BOTTOM,
            format!("Z{i}"),
            egui::FontId::proportional(11.0),
            color,
        );
    }
}

fn material_rows(ui: &mut egui::Ui, m: &mut Material) -> bool {
    ui.label("Colour").on_hover_text("Linear RGB albedo");
    let mut rgb = m.colour.to_array();
    let mut changed = ui
        .color_edit_button_rgb(&mut rgb)
        .on_hover_text("Linear RGB albedo of this kernel")
        .changed();
    if changed {
        m.colour = Vec3::from_array(rgb);
    }
    ui.end_row();
    ui.label("Material id")
        .on_hover_text("Index in the renderer's material table");
    changed |= ui
        .add(egui::DragValue::new(&mut m.id).range(0..=255))
        .on_hover_text("Index in the renderer's material table")
        .changed();
    ui.end_row();
    changed
}

fn torus_rows(ui: &mut egui::Ui, k: &mut TorusKernel) -> bool {
    let mut c = vec3_row(ui, "Centre", &mut k.centre, 0.01, "Centre of the torus");
    c |= vec3_row(
        ui,
        "Axis",
        &mut k.axis,
        0.01,
        "Axis of the torus (non-zero; normalised when accepted)",
    );
    c |= vec3_row(
        ui,
        "Start direction",
        &mut k.start_dir,
        0.01,
        "Where the arc starts: must not be parallel to the axis",
    );
    c |= f32_row(
        ui,
        "Major radius",
        &mut k.major_radius,
        0.005,
        0.0..=1.0e4,
        "Radius of the arc (0 or more)",
    );
    c |= f32_row(
        ui,
        "Minor radius",
        &mut k.minor_radius,
        0.002,
        0.0..=1.0e4,
        "Radius of the tube (0 or more)",
    );
    let mut sweep_deg = k.sweep_radians.to_degrees();
    if f32_row(
        ui,
        "Sweep deg",
        &mut sweep_deg,
        0.5,
        0.0..=360.0,
        "Angle the arc covers, 0 to 360 degrees",
    ) {
        k.sweep_radians = sweep_deg.to_radians().min(std::f32::consts::TAU);
        c = true;
    }
    c |= material_rows(ui, &mut k.material);
    c
}

/// Parameter rows of one kernel; returns whether a value changed.
fn kernel_rows(ui: &mut egui::Ui, kernel: &mut Kernel) -> bool {
    match kernel {
        Kernel::Empty => {
            ui.weak("No parameters");
            ui.end_row();
            false
        }
        Kernel::Sphere(k) => {
            let mut c = vec3_row(ui, "Centre", &mut k.centre, 0.01, "Centre of the ball");
            c |= f32_row(
                ui,
                "Radius",
                &mut k.radius,
                0.005,
                0.0..=1.0e4,
                "Radius of the ball (0 or more)",
            );
            c | material_rows(ui, &mut k.material)
        }
        Kernel::InfinitePlane(k) => {
            let mut c = vec3_row(
                ui,
                "Normal",
                &mut k.normal,
                0.01,
                "Outward normal (non-zero; normalised when accepted)",
            );
            c |= f32_row(
                ui,
                "Offset",
                &mut k.offset,
                0.01,
                -1.0e5..=1.0e5,
                "The solid is normal . p <= offset",
            );
            c | material_rows(ui, &mut k.material)
        }
        Kernel::Capsule(k) => {
            let mut c = vec3_row(ui, "Start", &mut k.start, 0.01, "First end of the segment");
            c |= vec3_row(ui, "End", &mut k.end, 0.01, "Second end of the segment");
            c |= f32_row(
                ui,
                "Radius",
                &mut k.radius,
                0.002,
                0.0..=1.0e4,
                "Radius of the swept ball (0 or more)",
            );
            c | material_rows(ui, &mut k.material)
        }
        Kernel::RoundedBox(k) => {
            let mut c = vec3_row(ui, "Centre", &mut k.centre, 0.01, "Centre of the box");
            let (y, x, z) = k.rotation.to_euler(EulerRot::YXZ);
            let mut e = Vec3::new(x, y, z) * 180.0 / std::f32::consts::PI;
            if vec3_row(
                ui,
                "Rotation deg",
                &mut e,
                0.5,
                "Orientation as X, Y, Z Euler angles in degrees (applied Y, X, Z)",
            ) {
                let r = e * std::f32::consts::PI / 180.0;
                k.rotation = Quat::from_euler(EulerRot::YXZ, r.y, r.x, r.z);
                c = true;
            }
            c |= vec3_row(
                ui,
                "Half extents",
                &mut k.half_extents,
                0.005,
                "Half the box's size per axis (0 or more)",
            );
            c |= f32_row(
                ui,
                "Rounding",
                &mut k.rounding,
                0.002,
                0.0..=1.0e4,
                "Edge rounding radius: at most the smallest half extent",
            );
            c | material_rows(ui, &mut k.material)
        }
        Kernel::TorusSegment(k) | Kernel::ToroidalCapsule(k) => torus_rows(ui, k),
    }
}

/// The KRS section of the inspector for object `id`.
pub fn krs_inspector_ui(ui: &mut egui::Ui, editor: &mut Editor, panel: &mut KrsPanel, id: u64) {
    let Some(current) = editor.krs(id).cloned() else {
        return;
    };
    if panel.names.is_empty() {
        panel.names = presets::all().into_iter().map(|(n, _)| n).collect();
    }
    // The picker shows what the object is: the preset it equals, or "custom" once edited. Matched
    // when the selection or the content changes, not every frame.
    let key = (id, editor.content_key());
    if panel.synced.is_none_or(|(k, _)| k != key) {
        let matched = presets::all().iter().position(|(_, p)| *p == current);
        if let Some(i) = matched {
            panel.preset = i;
        }
        panel.synced = Some((key, matched.is_none()));
    }
    let custom = panel.synced.is_some_and(|(_, c)| c);
    let mut k = current.clone();
    let mut changed = false;
    let header = egui::CollapsingHeader::new("KRS editor")
        .default_open(true)
        .show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.label("Preset")
                    .on_hover_text("Core's ready-made KRS objects");
                let selected = if custom {
                    "custom"
                } else {
                    panel.names.get(panel.preset).copied().unwrap_or("")
                };
                egui::ComboBox::from_id_salt("krs_preset")
                    .selected_text(selected)
                    .show_ui(ui, |ui| {
                        for (i, name) in panel.names.iter().enumerate() {
                            if ui
                                .selectable_label(!custom && panel.preset == i, *name)
                                .on_hover_text("Pick this preset, then Apply")
                                .clicked()
                            {
                                panel.preset = i;
                                if let Some((_, c)) = &mut panel.synced {
                                    *c = false;
                                }
                            }
                        }
                    })
                    .response
                    .on_hover_text("Core's ready-made KRS objects");
                if ui
                    .add_enabled(!custom, egui::Button::new("Apply preset"))
                    .on_hover_text(
                        "Replace this object's kernels and mirrors with the preset (undoable)",
                    )
                    .on_disabled_hover_text("Pick a preset first: this object is custom")
                    .clicked()
                    && let Some(name) = panel.names.get(panel.preset).copied()
                {
                    panel.error = editor
                        .apply_krs_preset(id, name)
                        .err()
                        .map(|e| e.to_string());
                    // A preset can be any size (a coral, a forest): show all of it.
                    if panel.error.is_none() {
                        editor.frame_selection();
                    }
                }
            });
            if let Some(e) = &panel.error {
                ui.colored_label(ui.visuals().error_fg_color, format!("Refused: {e}"));
            }
            ui.weak(format!(
                "{} kernels, {} mirror planes, {} instances",
                k.kernels.len(),
                k.mirrors.len(),
                crate::files::thousands_u128(k.instance_count())
            ));

            ui.separator();
            ui.strong("Kernels")
                .on_hover_text("K0..Kn: kernel K_i is reached after folding by mirrors n-1..i");
            for (i, kernel) in k.kernels.iter_mut().enumerate() {
                egui::CollapsingHeader::new(format!("K{i}: {}", kernel.kind_name()))
                    .id_salt(("krs_kernel", id, i))
                    .default_open(false)
                    .show(ui, |ui| {
                        egui::Grid::new(("krs_kernel_grid", i))
                            .num_columns(2)
                            .show(ui, |ui| {
                                ui.label("Kind").on_hover_text("The kernel's shape");
                                let kind = kernel.kind_name();
                                egui::ComboBox::from_id_salt(("krs_kind", i))
                                    .selected_text(kind)
                                    .show_ui(ui, |ui| {
                                        for (name, tip) in KINDS {
                                            if ui
                                                .selectable_label(kind == name, name)
                                                .on_hover_text(tip)
                                                .clicked()
                                                && kind != name
                                            {
                                                let m =
                                                    kernel.material().copied().unwrap_or_default();
                                                *kernel = default_kernel(name, m);
                                                changed = true;
                                            }
                                        }
                                    })
                                    .response
                                    .on_hover_text(
                                        "The kernel's shape (a new kind starts from its defaults)",
                                    );
                                ui.end_row();
                                changed |= kernel_rows(ui, kernel);
                            });
                    });
            }

            ui.separator();
            ui.strong("Mirror planes").on_hover_text(
                "R0..R(n-1): normal . p = offset; points on the normal's side are folded over",
            );
            egui::Grid::new("krs_mirrors")
                .num_columns(3)
                .striped(true)
                .show(ui, |ui| {
                    for (i, m) in k.mirrors.iter_mut().enumerate() {
                        if ui
                            .selectable_label(panel.mirror == Some(i), format!("R{i}"))
                            .on_hover_text("Highlight this plane in the view")
                            .clicked()
                        {
                            panel.mirror = (panel.mirror != Some(i)).then_some(i);
                        }
                        ui.horizontal(|ui| {
                            changed |= vec3_fields(
                                ui,
                                &mut m.normal,
                                0.01,
                                "n",
                                "Plane normal: non-zero, normalised when accepted",
                            );
                        });
                        changed |= ui
                            .add(
                                egui::DragValue::new(&mut m.offset)
                                    .speed(0.01)
                                    .max_decimals(4)
                                    .prefix("c "),
                            )
                            .on_hover_text("Offset of the plane along its normal")
                            .changed();
                        ui.end_row();
                    }
                });
            ui.horizontal(|ui| {
                if ui
                    .button("Add level")
                    .on_hover_text(
                        "Add a mirror plane (through the origin, normal +X) and an empty kernel",
                    )
                    .clicked()
                {
                    k.mirrors.push(MirrorPlane::default());
                    k.kernels.push(Kernel::Empty);
                    changed = true;
                }
                if ui
                    .add_enabled(
                        !k.mirrors.is_empty(),
                        egui::Button::new("Remove last level"),
                    )
                    .on_hover_text("Remove the last mirror plane and the last kernel")
                    .clicked()
                {
                    k.mirrors.pop();
                    k.kernels.pop();
                    changed = true;
                }
            });
            ui.separator();
            changed |= distortion_ui(ui, &mut k, id);
            ui.separator();
            changed |= texturing_ui(ui, &mut k.texturing, id);
            ui.separator();
            changed |= empty_zones_ui(ui, &mut k, id, zone_hint(editor, id));
            ui.separator();
            tree_builder_ui(ui, editor, panel, id);
        });
    panel.editor_open = header.body_returned.is_some();
    if changed && k != current {
        // A structural change (kind, level) is its own step; value drags merge while they last.
        panel.error = editor.set_krs(id, &k).err().map(|e| e.to_string());
    }
    if panel
        .mirror
        .is_some_and(|m| m >= editor.krs(id).map_or(0, |k| k.mirrors.len()))
    {
        panel.mirror = None;
    }
}

/// The selected KRS object's mirror planes on the screen: a quad per plane through the centre
/// of the object's bounding ball, as large as the ball; none while the KRS editor is closed.
#[must_use]
pub fn mirror_quads(
    editor: &Editor,
    panel: &KrsPanel,
    proj: &Projector,
) -> Vec<(usize, Vec<egui::Pos2>)> {
    if !panel.editor_open {
        return Vec::new();
    }
    let Some(Selection::Object(id)) = editor.selection else {
        return Vec::new();
    };
    let Some(k) = editor
        .object(id)
        .filter(|o| o.visible)
        .and_then(thicket_core::scene::Object::krs_in_world)
    else {
        return Vec::new();
    };
    let (centre, radius) = k.bounding_sphere_object().unwrap_or((Vec3::ZERO, 1.0));
    let t = k.world_from_object;
    // The bounding ball of a tree is loose (reflections can reach far): keep the quads within
    // a part of the view so they do not hide what they cut.
    let radius = radius
        .min(proj.camera.distance * 0.4 / t.scale.max(1e-12))
        .clamp(1e-3, 1e4);
    let mut out = Vec::new();
    for (i, m) in k.mirrors.iter().enumerate() {
        let Some(n) = m.normal.try_normalize() else {
            continue;
        };
        let on_plane = centre - n * (n.dot(centre) - m.offset);
        let (u, v) = n.any_orthonormal_pair();
        let corners: Option<Vec<egui::Pos2>> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .iter()
            .map(|(a, b)| proj.to_screen(t.transform_point(on_plane + (u * *a + v * *b) * radius)))
            .collect();
        if let Some(corners) = corners {
            out.push((i, corners));
        }
    }
    out
}

/// The mirror plane of the selected KRS object whose outline passes under `pointer`.
#[must_use]
pub fn pick_mirror(
    editor: &Editor,
    panel: &KrsPanel,
    proj: &Projector,
    pointer: egui::Pos2,
) -> Option<usize> {
    mirror_quads(editor, panel, proj)
        .into_iter()
        .map(|(i, mut q)| {
            q.push(q[0]);
            (distance_to_polyline(pointer, &q), i)
        })
        .filter(|(d, _)| *d <= MIRROR_GRAB_PX)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, i)| i)
}

/// Draws the mirror planes of the selected KRS object as outlined quads (the highlighted one
/// brighter and filled, with its gizmo), sized by the object's bounding ball.
pub fn paint_mirrors(painter: &egui::Painter, editor: &Editor, panel: &KrsPanel, proj: &Projector) {
    for (i, mut corners) in mirror_quads(editor, panel, proj) {
        let highlighted = panel.mirror == Some(i);
        let color = if highlighted {
            egui::Color32::from_rgb(120, 220, 255)
        } else {
            egui::Color32::from_rgba_unmultiplied(120, 200, 255, 110)
        };
        if highlighted {
            painter.add(egui::Shape::convex_polygon(
                corners.clone(),
                egui::Color32::from_rgba_unmultiplied(120, 220, 255, 30),
                egui::Stroke::NONE,
            ));
        }
        let label_at = corners[2];
        corners.push(corners[0]);
        painter.add(egui::Shape::line(
            corners,
            egui::Stroke::new(if highlighted { 2.5 } else { 1.0 }, color),
        ));
        painter.text(
            label_at,
            egui::Align2::LEFT_BOTTOM,
            format!("R{i}"),
            egui::FontId::proportional(11.0),
            color,
        );
    }
    let active = panel.drag.map(|d| d.handle);
    for h in panel.mirror_handles(editor, proj) {
        let color = match h.handle {
            MirrorHandle::Offset => egui::Color32::from_rgb(255, 230, 90),
            MirrorHandle::Tilt(0) => egui::Color32::from_rgb(240, 120, 200),
            MirrorHandle::Tilt(_) => egui::Color32::from_rgb(150, 230, 120),
        };
        let width = if active == Some(h.handle) { 3.5 } else { 2.0 };
        if h.handle == MirrorHandle::Offset
            && let (Some(a), Some(b)) = (h.points.first(), h.points.last())
        {
            let dir = (*b - *a).normalized();
            let side = egui::vec2(-dir.y, dir.x) * 5.0;
            painter.add(egui::Shape::convex_polygon(
                vec![*b + dir * 10.0, *b + side, *b - side],
                color,
                egui::Stroke::NONE,
            ));
        }
        painter.add(egui::Shape::line(h.points, egui::Stroke::new(width, color)));
    }
}

/// Gizmo size in view points (arrow length, ring radius).
const MIRROR_GIZMO_PX: f32 = 60.0;
/// How close (points) the pointer must be to a handle to grab it.
const MIRROR_GRAB_PX: f32 = 8.0;

/// A handle of the mirror-plane gizmo.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MirrorHandle {
    /// The arrow along the normal: moves the plane (its offset).
    Offset,
    /// A ring about one of the plane's two in-plane axes: tilts the plane about its centre.
    Tilt(usize),
}

/// A handle as drawn: what it does and its polyline on the screen.
#[derive(Debug, Clone)]
pub struct MirrorHandleShape {
    /// What the handle does.
    pub handle: MirrorHandle,
    /// The polyline (arrow: from the plane's centre to the tip).
    pub points: Vec<egui::Pos2>,
}

/// The highlighted plane of the selected KRS object: its KRS-space centre and basis, and the
/// KRS's placement in the world.
struct MirrorFrame {
    id: u64,
    index: usize,
    plane: MirrorPlane,
    centre: Vec3,
    axes: [Vec3; 2],
    world: thicket_core::krs::Similarity,
}

impl MirrorFrame {
    fn of(editor: &Editor, panel: &KrsPanel) -> Option<Self> {
        if !panel.editor_open {
            return None;
        }
        let Some(Selection::Object(id)) = editor.selection else {
            return None;
        };
        let index = panel.mirror?;
        let world = editor.object(id).filter(|o| o.visible)?.krs_in_world()?;
        let plane = *world.mirrors.get(index)?;
        let n = plane.normal.try_normalize()?;
        let (centre, _) = world.bounding_sphere_object().unwrap_or((Vec3::ZERO, 1.0));
        let (u, v) = n.any_orthonormal_pair();
        Some(Self {
            id,
            index,
            plane: MirrorPlane { normal: n, ..plane },
            centre: centre - n * (n.dot(centre) - plane.offset),
            axes: [u, v],
            world: world.world_from_object,
        })
    }

    fn dir_world(&self, v: Vec3) -> Vec3 {
        self.world.rotation * v
    }
}

/// A mirror-gizmo drag in progress (measured from where it started).
#[derive(Debug, Clone, Copy)]
struct MirrorDrag {
    id: u64,
    index: usize,
    handle: MirrorHandle,
    base: MirrorPlane,
    centre: Vec3,
    axes: [Vec3; 2],
    start: egui::Pos2,
    center_px: egui::Pos2,
    sign: f32,
    arrow_px: egui::Vec2,
    /// KRS-space length of the arrow.
    arrow_krs: f32,
}

impl KrsPanel {
    /// The highlighted mirror plane's gizmo handles on the screen (empty when no plane of the
    /// selected KRS object is highlighted).
    #[must_use]
    pub fn mirror_handles(&self, editor: &Editor, proj: &Projector) -> Vec<MirrorHandleShape> {
        let Some(f) = MirrorFrame::of(editor, self) else {
            return Vec::new();
        };
        let p = f.world.transform_point(f.centre);
        let size = MIRROR_GIZMO_PX * proj.world_per_point(p);
        let n = f.dir_world(f.plane.normal);
        let mut out = Vec::new();
        if let (Some(a), Some(b)) = (proj.to_screen(p), proj.to_screen(p + n * size)) {
            out.push(MirrorHandleShape {
                handle: MirrorHandle::Offset,
                points: vec![a, b],
            });
        }
        for k in 0..2 {
            // The ring about in-plane axis k lies in the plane of the other axis and the normal.
            let other = f.dir_world(f.axes[1 - k]);
            let points: Option<Vec<egui::Pos2>> = (0..=48)
                .map(|i| {
                    let t = i as f32 / 48.0 * std::f32::consts::TAU;
                    proj.to_screen(p + size * (t.cos() * other + t.sin() * n))
                })
                .collect();
            if let Some(points) = points {
                out.push(MirrorHandleShape {
                    handle: MirrorHandle::Tilt(k),
                    points,
                });
            }
        }
        out
    }

    /// Whether a mirror-gizmo drag is in progress.
    #[must_use]
    pub fn dragging(&self) -> bool {
        self.drag.is_some()
    }

    /// Handles the mirror-plane gizmo: the arrow moves the plane along its normal, the rings
    /// tilt it about its centre; a drag is one undo step. Returns whether the gizmo owns the
    /// pointer this frame.
    pub fn interact(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        editor: &mut Editor,
        proj: &Projector,
    ) -> bool {
        if self.drag.is_none() && self.interact_route(ui, response, editor, proj) {
            return true;
        }
        if response.drag_started_by(egui::PointerButton::Primary)
            && !ui.input(|i| i.modifiers.alt || i.modifiers.shift)
            && let Some(start) = ui.input(|i| i.pointer.press_origin())
            && let Some(f) = MirrorFrame::of(editor, self)
        {
            let grabbed = self
                .mirror_handles(editor, proj)
                .into_iter()
                .map(|h| (distance_to_polyline(start, &h.points), h))
                .filter(|(d, _)| *d <= MIRROR_GRAB_PX)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let p = f.world.transform_point(f.centre);
            if let Some((_, h)) = grabbed
                && let Some(center_px) = proj.to_screen(p)
            {
                let sign = match h.handle {
                    MirrorHandle::Tilt(k)
                        if f.dir_world(f.axes[k]).dot(proj.toward_eye(p)) < 0.0 =>
                    {
                        -1.0
                    }
                    _ => 1.0,
                };
                let size = MIRROR_GIZMO_PX * proj.world_per_point(p);
                let arrow_px = h.points.last().map_or(egui::Vec2::ZERO, |e| *e - center_px);
                editor.end_interaction();
                self.drag = Some(MirrorDrag {
                    id: f.id,
                    index: f.index,
                    handle: h.handle,
                    base: f.plane,
                    centre: f.centre,
                    axes: f.axes,
                    start,
                    center_px,
                    sign,
                    arrow_px,
                    arrow_krs: size / f.world.scale.max(1e-12),
                });
            }
        }
        let Some(d) = self.drag else {
            return false;
        };
        if !ui.input(|i| i.pointer.primary_down()) {
            self.drag = None;
            return true;
        }
        let (Some(pointer), Some(mut k)) = (
            ui.input(|i| i.pointer.interact_pos()),
            editor.krs(d.id).cloned(),
        ) else {
            return true;
        };
        let Some(slot) = k.mirrors.get_mut(d.index) else {
            self.drag = None;
            return true;
        };
        *slot = match d.handle {
            MirrorHandle::Offset => {
                let len2 = d.arrow_px.length_sq();
                if len2 < 1.0 {
                    return true;
                }
                let along = (pointer - d.start).dot(d.arrow_px) / len2;
                MirrorPlane {
                    normal: d.base.normal,
                    offset: d.base.offset + along * d.arrow_krs,
                }
            }
            MirrorHandle::Tilt(axis) => {
                let mut screen = (pointer - d.center_px).angle() - (d.start - d.center_px).angle();
                if screen > std::f32::consts::PI {
                    screen -= std::f32::consts::TAU;
                } else if screen < -std::f32::consts::PI {
                    screen += std::f32::consts::TAU;
                }
                // Screen y points down: a counter-clockwise turn lowers the angle.
                let theta = -screen * d.sign;
                let normal = Quat::from_axis_angle(d.axes[axis], theta) * d.base.normal;
                // Tilt about the plane's centre: the plane keeps passing through it.
                MirrorPlane {
                    normal,
                    offset: normal.dot(d.centre),
                }
            }
        };
        self.error = editor.set_krs(d.id, &k).err().map(|e| e.to_string());
        true
    }
}

/// The tree builder (paper section 7.2): fork positions along one route, a bend (control point)
/// and a width per branch, the leaf. Every change rebuilds the object (a drag is one undo step);
/// the fork positions can also be dragged in the view.
fn tree_builder_ui(ui: &mut egui::Ui, editor: &mut Editor, panel: &mut KrsPanel, id: u64) {
    // The document holds the parameters the object was built from (saved, undoable): an open
    // builder shows them, so undo / redo and reopening a saved tree continue from there.
    if let Some(stored) = editor.tree_params(id)
        && let Some((t, p)) = panel.tree.as_mut()
        && *t == id
        && p != stored
    {
        p.clone_from(stored);
    }
    let open = panel.tree.as_ref().is_some_and(|(t, _)| *t == id);
    ui.horizontal(|ui| {
        ui.strong("Tree builder")
            .on_hover_text("Build this object as a tree from fork positions, bends and widths");
        if !open
            && let Some(stored) = editor.tree_params(id).cloned()
            && ui
                .button("Edit tree")
                .on_hover_text(
                    "Open the builder with the parameters this tree was built from (saved with the project)",
                )
                .clicked()
        {
            panel.tree = Some((id, stored));
            return;
        }
        if !open
            && ui
                .button("Start from the default tree")
                .on_hover_text(
                    "Open the builder with the default parameters and rebuild this object from them (undoable)",
                )
                .clicked()
        {
            let params = TreeParams::default();
            editor.end_interaction();
            panel.error = editor.build_tree(id, &params).err().map(|e| e.to_string());
            editor.end_interaction();
            if panel.error.is_none() {
                editor.frame_selection();
            }
            panel.tree = Some((id, params));
        }
        if open
            && ui
                .button("Close builder")
                .on_hover_text("Hide the builder and its handles (the object keeps its shape)")
                .clicked()
        {
            panel.tree = None;
        }
    });
    let Some((_, params)) = panel.tree.as_ref().filter(|(t, _)| *t == id) else {
        return;
    };
    let mut p = params.clone();
    let mut changed = false;
    let branches = p.route.len().saturating_sub(1);
    egui::Grid::new("tree_builder")
        .num_columns(2)
        .striped(true)
        .show(ui, |ui| {
            for i in 0..p.route.len() {
                let label = if i == 0 {
                    "Trunk base".to_owned()
                } else if i == branches {
                    "Twig tip".to_owned()
                } else {
                    format!("Fork {i}")
                };
                changed |= vec3_row(
                    ui,
                    &label,
                    &mut p.route[i],
                    0.01,
                    "Position along the route from trunk base to twig tip (also draggable in the view)",
                );
            }
            for k in 1..branches {
                // The normal in use (the default one until edited), as `fork_mirror` orients it.
                let mut n = p.fork_mirror(k).normal;
                if vec3_row(
                    ui,
                    &format!("Fork {k} normal"),
                    &mut n,
                    0.01,
                    "Normal of the reflection plane at this fork (also draggable in the view: \
                     the handle at the end of the line from the fork); the sign is chosen so \
                     the branch leaving the fork is kept",
                ) {
                    set_fork_normal(&mut p, k, n);
                    changed = true;
                }
            }
            for b in 0..branches {
                if p.bends.len() <= b {
                    p.bends.resize(b + 1, Vec3::ZERO);
                }
                changed |= vec3_row(
                    ui,
                    &format!("Bend {b}"),
                    &mut p.bends[b],
                    0.005,
                    "Offset of the branch's control point from its chord midpoint (0: straight)",
                );
                if p.widths.len() <= b {
                    let last = p.widths.last().copied().unwrap_or(0.05);
                    p.widths.resize(b + 1, last);
                }
                changed |= f32_row(
                    ui,
                    &format!("Width {b}"),
                    &mut p.widths[b],
                    0.002,
                    0.0..=100.0,
                    "Branch radius (0 or more)",
                );
            }
            if let Some(leaf) = p.leaf.as_mut() {
                changed |= f32_row(
                    ui,
                    "Leaf radius",
                    &mut leaf.radius,
                    0.002,
                    0.0..=100.0,
                    "Radius of the leaf ball at the twig tip",
                );
            }
        });
    ui.horizontal(|ui| {
        if ui
            .button("Add fork")
            .on_hover_text("Extend the route by a shorter branch beyond the twig tip")
            .clicked()
        {
            let n = p.route.len();
            let last = p.route[n - 1];
            let dir = if n >= 2 {
                last - p.route[n - 2]
            } else {
                Vec3::Y
            };
            p.route.push(last + dir * 0.7);
            changed = true;
        }
        if ui
            .add_enabled(p.route.len() > 2, egui::Button::new("Remove fork"))
            .on_hover_text("Remove the twig tip (the route keeps at least two points)")
            .clicked()
        {
            p.route.pop();
            changed = true;
        }
        if ui
            .add_enabled(
                !p.fork_normals.is_empty(),
                egui::Button::new("Default fork planes"),
            )
            .on_hover_text(
                "Forget the edited fork normals: every fork plane goes back to the symmetric Y fork",
            )
            .clicked()
        {
            p.fork_normals.clear();
            changed = true;
        }
    });
    if changed {
        match editor.build_tree(id, &p) {
            Ok(()) => {
                panel.error = None;
                panel.tree = Some((id, p));
            }
            Err(e) => panel.error = Some(e.to_string()),
        }
    }
}

/// Stores `normal` for the fork at `route[k]`; the other forks keep theirs (zero: the default).
fn set_fork_normal(p: &mut TreeParams, k: usize, normal: Vec3) {
    if p.fork_normals.len() < k {
        p.fork_normals.resize(k, Vec3::ZERO);
    }
    p.fork_normals[k - 1] = normal;
}

/// The KRS-space end of the fork normal handle at `route[k]` (1 ≤ k < route.len() − 1): half
/// the incoming branch's length along the plane's normal.
fn fork_normal_tip(p: &TreeParams, k: usize) -> Vec3 {
    let len = 0.5 * (p.route[k] - p.route[k - 1]).length().max(0.1);
    p.route[k] + p.fork_mirror(k).normal * len
}

impl KrsPanel {
    /// The tree builder's fork normal handles on the screen: (fork point, handle end) per fork
    /// `route[1..len − 1]`, when the builder is open for the selected object.
    #[must_use]
    pub fn fork_normal_points(
        &self,
        editor: &Editor,
        proj: &Projector,
    ) -> Vec<(Option<egui::Pos2>, Option<egui::Pos2>)> {
        let route = self.route_points(editor, proj);
        let (Some(Selection::Object(id)), Some((_, params))) = (editor.selection, &self.tree)
        else {
            return Vec::new();
        };
        let Some(world) = editor
            .object(id)
            .and_then(thicket_core::scene::Object::krs_in_world)
        else {
            return Vec::new();
        };
        if route.len() < 3 {
            return Vec::new();
        }
        (1..params.route.len() - 1)
            .map(|k| {
                let tip = fork_normal_tip(params, k);
                (
                    route[k],
                    proj.to_screen(world.world_from_object.transform_point(tip)),
                )
            })
            .collect()
    }

    /// The tree builder's route points on the screen, when the builder is open for the
    /// selected object.
    #[must_use]
    pub fn route_points(&self, editor: &Editor, proj: &Projector) -> Vec<Option<egui::Pos2>> {
        if !self.editor_open {
            return Vec::new();
        }
        let Some(Selection::Object(id)) = editor.selection else {
            return Vec::new();
        };
        let Some((_, params)) = self.tree.as_ref().filter(|(t, _)| *t == id) else {
            return Vec::new();
        };
        let Some(world) = editor
            .object(id)
            .and_then(thicket_core::scene::Object::krs_in_world)
        else {
            return Vec::new();
        };
        params
            .route
            .iter()
            .map(|p| proj.to_screen(world.world_from_object.transform_point(*p)))
            .collect()
    }

    /// Drags a route point of the open tree builder in the view plane; returns whether it owns
    /// the pointer this frame.
    fn interact_route(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        editor: &mut Editor,
        proj: &Projector,
    ) -> bool {
        let Some(Selection::Object(id)) = editor.selection else {
            self.tree_drag = None;
            return false;
        };
        if response.drag_started_by(egui::PointerButton::Primary)
            && !ui.input(|i| i.modifiers.alt || i.modifiers.shift)
            && let Some(start) = ui.input(|i| i.pointer.press_origin())
        {
            let route = self.route_points(editor, proj);
            let tips = self.fork_normal_points(editor, proj);
            let grabbed = route
                .iter()
                .copied()
                .chain(tips.iter().map(|(_, tip)| *tip))
                .enumerate()
                .filter_map(|(i, s)| s.map(|s| (s.distance(start), i)))
                .filter(|(d, _)| *d <= MIRROR_GRAB_PX)
                // Route points win a tie with a normal handle drawn over them.
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            if let Some((_, i)) = grabbed
                && let Some((_, params)) = self.tree.as_ref()
            {
                let n = params.route.len();
                let base = if i < n {
                    params.route[i]
                } else {
                    fork_normal_tip(params, i - n + 1)
                };
                editor.end_interaction();
                self.tree_drag = Some((i, base, start));
            }
        }
        let Some((index, base, start)) = self.tree_drag else {
            return false;
        };
        if !ui.input(|i| i.pointer.primary_down()) {
            self.tree_drag = None;
            return true;
        }
        let (Some(pointer), Some(world)) = (
            ui.input(|i| i.pointer.interact_pos()),
            editor
                .object(id)
                .and_then(thicket_core::scene::Object::krs_in_world),
        ) else {
            return true;
        };
        let Some((_, params)) = self.tree.as_ref() else {
            self.tree_drag = None;
            return true;
        };
        // Move in the plane facing the camera through the point's position at the start.
        let t = world.world_from_object;
        let p_world = t.transform_point(base);
        let eye = proj.eye();
        let forward = (proj.camera.target - eye).normalize_or_zero();
        let right = forward.cross(Vec3::Y).try_normalize().unwrap_or(Vec3::X);
        let up = right.cross(forward);
        let d = pointer - start;
        let delta_world = (right * d.x - up * d.y) * proj.world_per_point(p_world);
        let delta = t.rotation.inverse() * delta_world / t.scale.max(1e-12);
        let mut p = params.clone();
        let n = p.route.len();
        if index < n {
            p.route[index] = base + delta;
        } else if (1..n.saturating_sub(1)).contains(&(index - n + 1)) {
            // A fork normal handle: the plane turns to face the handle's new end.
            let k = index - n + 1;
            if let Some(normal) = (base + delta - p.route[k]).try_normalize() {
                set_fork_normal(&mut p, k, normal);
            }
        }
        match editor.build_tree(id, &p) {
            Ok(()) => {
                self.error = None;
                self.tree = Some((id, p));
            }
            Err(e) => self.error = Some(e.to_string()),
        }
        true
    }
}

/// Draws the open tree builder's route: the fork positions as handles joined by lines.
pub fn paint_route(painter: &egui::Painter, editor: &Editor, panel: &KrsPanel, proj: &Projector) {
    let points = panel.route_points(editor, proj);
    let color = egui::Color32::from_rgb(255, 240, 160);
    for w in points.windows(2) {
        if let (Some(a), Some(b)) = (w[0], w[1]) {
            painter.line_segment([a, b], egui::Stroke::new(1.5, color));
        }
    }
    let dragged = panel.tree_drag.map(|(i, _, _)| i);
    // Fork plane normals: a line from each fork to its handle.
    let normal_color = egui::Color32::from_rgb(120, 220, 255);
    for (k, (fork, tip)) in panel.fork_normal_points(editor, proj).iter().enumerate() {
        if let (Some(a), Some(b)) = (fork, tip) {
            painter.line_segment([*a, *b], egui::Stroke::new(1.5, normal_color));
            let r = if dragged == Some(points.len() + k) {
                5.0
            } else {
                3.5
            };
            painter.circle(
                *b,
                r,
                egui::Color32::from_rgb(20, 60, 90),
                egui::Stroke::new(1.5, normal_color),
            );
        }
    }
    for (i, p) in points.iter().enumerate() {
        if let Some(p) = p {
            let r = if dragged == Some(i) { 6.0 } else { 4.5 };
            painter.circle(
                *p,
                r,
                egui::Color32::from_rgb(90, 60, 30),
                egui::Stroke::new(1.5, color),
            );
        }
    }
}

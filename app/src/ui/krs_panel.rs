//! The KRS editor in the inspector: presets, the kernel list with typed parameter editors and
//! the mirror-plane list. Every change goes through [`Editor::set_krs`] (core's validation: a
//! refused value leaves the document unchanged and the message says which field and why); a
//! drag is one undo step. The planes of the level being edited are drawn over the view, clipped
//! to the object's bounding box and fading with distance; the highlighted one has a gizmo.

use glam::{EulerRot, Quat, Vec3};
use thicket_core::krs::{
    BoxKernel, CapsuleKernel, Kernel, Material, MirrorPlane, PlaneKernel, SphereKernel,
    TorusKernel, TreeParams, presets,
};

use super::pose::distance_to_polyline;
use super::projector::Projector;
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
    /// The kernels K_i whose entries are open in the KRS editor this frame: their planes R_i
    /// are drawn with the highlighted one (see [`KrsPanel::edited_mirrors`]).
    pub open_kernels: Vec<usize>,
    /// The object for which "Start from the default tree" waits for Replace or Cancel.
    confirm_default_tree: Option<u64>,
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

/// A grid row of three DragValues for the unit vector `v` (see [`unit_vec3_fields`]); returns
/// whether one changed.
fn unit_vec3_row(ui: &mut egui::Ui, label: &str, v: &mut Vec3, tip: &str) -> bool {
    ui.label(label).on_hover_text(tip);
    let changed = ui.horizontal(|ui| unit_vec3_fields(ui, v, "", tip)).inner;
    ui.end_row();
    changed
}

/// Three DragValues for a unit vector `v` (a normal or an axis, which the document stores
/// normalised), prefixed `{prefix}x`, `{prefix}y`, `{prefix}z`. Typed text stays as typed until
/// Enter or until the field loses focus (normalising on every keystroke turned a typed 0.2
/// into 0.2839 and moved another component); then, as after a drag, the edited component keeps
/// its value and the other two are scaled to make the length 1 ([`with_component`]). Returns
/// whether `v` changed.
fn unit_vec3_fields(ui: &mut egui::Ui, v: &mut Vec3, prefix: &str, tip: &str) -> bool {
    let before = *v;
    let mut changed = false;
    for (axis, name) in ["x", "y", "z"].iter().enumerate() {
        let mut c = before[axis];
        if ui
            .add(
                egui::DragValue::new(&mut c)
                    .speed(0.01)
                    .max_decimals(4)
                    .range(-1.0..=1.0)
                    .clamp_existing_to_range(false)
                    .update_while_editing(false)
                    .prefix(format!("{prefix}{name} ")),
            )
            .on_hover_text(tip)
            .changed()
        {
            *v = with_component(before, axis, c);
            changed = true;
        }
    }
    changed
}

/// The unit vector with component `axis` equal to `value` (clamped to −1..1) and the other two
/// scaled from `v`'s to make the length 1; when `v` has nothing off that axis, the rest goes to
/// the next axis (x → y → z → x).
#[must_use]
pub fn with_component(v: Vec3, axis: usize, value: f32) -> Vec3 {
    let value = if value.is_finite() {
        value.clamp(-1.0, 1.0)
    } else {
        v[axis]
    };
    let mut rest = v;
    rest[axis] = 0.0;
    let left = (1.0 - value * value).max(0.0).sqrt();
    let mut out = match rest.try_normalize() {
        Some(r) => r * left,
        None => {
            let mut r = Vec3::ZERO;
            r[(axis + 1) % 3] = left;
            r
        }
    };
    out[axis] = value;
    out
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
    c |= unit_vec3_row(
        ui,
        "Axis",
        &mut k.axis,
        "Axis of the torus (unit length: a typed component is kept, the others follow)",
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
            let mut c = unit_vec3_row(
                ui,
                "Normal",
                &mut k.normal,
                "Outward normal (unit length: a typed component is kept, the others follow)",
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
            panel.open_kernels.clear();
            for (i, kernel) in k.kernels.iter_mut().enumerate() {
                let entry = egui::CollapsingHeader::new(format!("K{i}: {}", kernel.kind_name()))
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
                if entry.body_returned.is_some() {
                    panel.open_kernels.push(i);
                }
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
                            changed |= unit_vec3_fields(
                                ui,
                                &mut m.normal,
                                "n",
                                "Plane normal (unit length): a typed component is kept and the \
                                 other two follow when you press Enter or leave the field",
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

/// A mirror plane as drawn over the view: the plane clipped to the object's bounding box, its
/// outline cut into short segments whose opacity fades with distance from the camera.
#[derive(Debug, Clone)]
pub struct MirrorOutline {
    /// Which mirror (R index).
    pub index: usize,
    /// The outline's visible segments in view points, each with its opacity factor (1 at the
    /// part nearest the camera, [`FAR_ALPHA`] at the farthest).
    pub segments: Vec<([egui::Pos2; 2], f32)>,
    /// The clipped polygon's corners in view points, when all are in front of the camera (the
    /// highlighted plane is filled).
    pub polygon: Option<Vec<egui::Pos2>>,
}

/// Opacity factor of the part of a plane's outline farthest from the camera.
pub const FAR_ALPHA: f32 = 0.25;
/// Segments per polygon edge: the fade changes along an edge.
const OUTLINE_PIECES: usize = 8;

/// The opacity factor of an outline point `distance` from the eye when the outline's points lie
/// `near..far` from it: 1 nearest, [`FAR_ALPHA`] farthest, so the near side of a plane reads
/// in front of the far side and far planes do not cover what is near.
#[must_use]
pub fn fade_alpha(distance: f32, near: f32, far: f32) -> f32 {
    let t = if far > near {
        ((distance - near) / (far - near)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    1.0 - (1.0 - FAR_ALPHA) * t
}

/// The polygon where the plane `normal · p = offset` cuts the box `lo..hi`, its corners in
/// order around it; empty when the plane misses the box.
#[must_use]
pub fn plane_in_box(normal: Vec3, offset: f32, lo: Vec3, hi: Vec3) -> Vec<Vec3> {
    let corners = thicket_core::scene::box_corners(lo, hi);
    let side = corners.map(|c| normal.dot(c) - offset);
    let mut points: Vec<Vec3> = Vec::new();
    // The 12 edges join corners whose indices differ in one bit.
    for a in 0..8 {
        for bit in [1, 2, 4] {
            let b = a | bit;
            if b == a {
                continue;
            }
            let (da, db) = (side[a], side[b]);
            if (da <= 0.0) != (db <= 0.0) {
                let t = da / (da - db);
                let p = corners[a].lerp(corners[b], t);
                if points.iter().all(|q| q.distance_squared(p) > 1e-12) {
                    points.push(p);
                }
            }
        }
    }
    if points.len() < 3 {
        return Vec::new();
    }
    let centre = points.iter().copied().sum::<Vec3>() / points.len() as f32;
    let (u, v) = normal.normalize_or(Vec3::Y).any_orthonormal_pair();
    points.sort_by(|a, b| {
        let (pa, pb) = (*a - centre, *b - centre);
        pa.dot(v)
            .atan2(pa.dot(u))
            .total_cmp(&pb.dot(v).atan2(pb.dot(u)))
    });
    points
}

/// The KRS-space box the selected object's planes are clipped to: the box of its bounding
/// ball (a ball at the origin, a part of the view across, for an object without one: half
/// spaces).
fn plane_box(k: &thicket_core::krs::KrsObject, proj: &Projector) -> (Vec3, Vec3) {
    let (centre, radius) = k.bounding_sphere_object().unwrap_or_else(|| {
        let t = k.world_from_object;
        (Vec3::ZERO, proj.camera.distance * 0.4 / t.scale.max(1e-12))
    });
    let radius = radius.clamp(1e-3, 1e7);
    (centre - Vec3::splat(radius), centre + Vec3::splat(radius))
}

impl KrsPanel {
    /// The mirror planes being edited, which alone are drawn and picked: the highlighted one
    /// and the plane R_i of every kernel K_i whose entry is open in the KRS editor (the level
    /// that plane reflects). None while the KRS editor is closed.
    #[must_use]
    pub fn edited_mirrors(&self) -> Vec<usize> {
        if !self.editor_open {
            return Vec::new();
        }
        let mut out: Vec<usize> = self.mirror.into_iter().collect();
        for &i in &self.open_kernels {
            if !out.contains(&i) {
                out.push(i);
            }
        }
        out
    }
}

/// The selected KRS object's planes being edited ([`KrsPanel::edited_mirrors`]) on the screen,
/// each clipped to the object's bounding box; a plane that misses the box has none.
#[must_use]
pub fn mirror_outlines(editor: &Editor, panel: &KrsPanel, proj: &Projector) -> Vec<MirrorOutline> {
    let edited = panel.edited_mirrors();
    if edited.is_empty() {
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
    let (lo, hi) = plane_box(&k, proj);
    let t = k.world_from_object;
    let eye = proj.eye();
    let mut out = Vec::new();
    for i in edited {
        let Some(m) = k.mirrors.get(i) else {
            continue;
        };
        let polygon = plane_in_box(m.normal, m.offset, lo, hi);
        if polygon.is_empty() {
            continue;
        }
        let world: Vec<Vec3> = polygon.iter().map(|p| t.transform_point(*p)).collect();
        let (near, far) = world
            .iter()
            .map(|p| p.distance(eye))
            .fold((f32::INFINITY, 0.0f32), |(a, b), d| (a.min(d), b.max(d)));
        let mut segments = Vec::new();
        for (j, a) in world.iter().enumerate() {
            let b = world[(j + 1) % world.len()];
            for s in 0..OUTLINE_PIECES {
                let (pa, pb) = (
                    a.lerp(b, s as f32 / OUTLINE_PIECES as f32),
                    a.lerp(b, (s + 1) as f32 / OUTLINE_PIECES as f32),
                );
                if let Some(seg) = proj.segment(pa, pb) {
                    let alpha = fade_alpha(pa.lerp(pb, 0.5).distance(eye), near, far);
                    segments.push((seg, alpha));
                }
            }
        }
        let polygon: Option<Vec<egui::Pos2>> = world.iter().map(|p| proj.to_screen(*p)).collect();
        out.push(MirrorOutline {
            index: i,
            segments,
            polygon,
        });
    }
    out
}

/// The drawn mirror plane of the selected KRS object whose outline passes under `pointer`.
#[must_use]
pub fn pick_mirror(
    editor: &Editor,
    panel: &KrsPanel,
    proj: &Projector,
    pointer: egui::Pos2,
) -> Option<usize> {
    mirror_outlines(editor, panel, proj)
        .into_iter()
        .filter_map(|o| {
            let d = o
                .segments
                .iter()
                .map(|(s, _)| distance_to_polyline(pointer, s))
                .fold(f32::INFINITY, f32::min);
            (d <= MIRROR_GRAB_PX).then_some((d, o.index))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, i)| i)
}

/// Draws the selected KRS object's planes being edited, clipped to its bounding box and
/// fading with distance (the highlighted one brighter and filled, with its gizmo).
pub fn paint_mirrors(painter: &egui::Painter, editor: &Editor, panel: &KrsPanel, proj: &Projector) {
    for o in mirror_outlines(editor, panel, proj) {
        let highlighted = panel.mirror == Some(o.index);
        let (rgb, alpha, width) = if highlighted {
            ([120, 220, 255], 255.0, 2.5)
        } else {
            ([120, 200, 255], 170.0, 1.5)
        };
        let color = |f: f32| {
            egui::Color32::from_rgba_unmultiplied(rgb[0], rgb[1], rgb[2], (alpha * f) as u8)
        };
        if highlighted && let Some(polygon) = &o.polygon {
            painter.add(egui::Shape::convex_polygon(
                polygon.clone(),
                egui::Color32::from_rgba_unmultiplied(120, 220, 255, 24),
                egui::Stroke::NONE,
            ));
        }
        for (seg, f) in &o.segments {
            painter.line_segment(*seg, egui::Stroke::new(width, color(*f)));
        }
        // The label at the outline's nearest (most opaque) point in the view.
        let view = painter.clip_rect().shrink(12.0);
        if let Some((seg, _)) = o
            .segments
            .iter()
            .filter(|(s, _)| view.contains(s[0]))
            .max_by(|a, b| a.1.total_cmp(&b.1))
        {
            painter.text(
                seg[0],
                egui::Align2::LEFT_BOTTOM,
                format!("R{}", o.index),
                egui::FontId::proportional(11.0),
                color(1.0),
            );
        }
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

/// Gizmo size in view points (ring radius).
const MIRROR_GIZMO_PX: f32 = 60.0;
/// How close (points) the pointer must be to a handle to grab it.
pub const MIRROR_GRAB_PX: f32 = 8.0;
/// Gap in view points between the farthest point of the rings and the arrow's start: more than
/// twice the grab tolerance, so no point is within reach of both.
const ARROW_GAP_PX: f32 = 2.5 * MIRROR_GRAB_PX;
/// Length of the arrow in view points.
const ARROW_PX: f32 = 40.0;

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
    /// The polyline (arrow: from its start, beyond the rings, to its tip).
    pub points: Vec<egui::Pos2>,
    /// Arrow: how far the view moves the plane's centre when the plane moves one gizmo size
    /// (the ring radius in world units) along its normal (at least a quarter of the ring
    /// radius, for a normal pointing at the camera); zero for a ring.
    pub along_px: egui::Vec2,
}

/// The handle a press at `at` grabs: the arrow when it is within reach (it wins over a ring),
/// else the nearest ring within reach.
#[must_use]
pub fn grab_handle(handles: &[MirrorHandleShape], at: egui::Pos2) -> Option<&MirrorHandleShape> {
    let reach = |h: &&MirrorHandleShape| distance_to_polyline(at, &h.points);
    let near = |h: &&MirrorHandleShape| reach(h) <= MIRROR_GRAB_PX;
    handles
        .iter()
        .filter(near)
        .find(|h| h.handle == MirrorHandle::Offset)
        .or_else(|| {
            handles
                .iter()
                .filter(near)
                .min_by(|a, b| reach(a).total_cmp(&reach(b)))
        })
}

/// The highlighted plane of the selected KRS object: its KRS-space centre (the middle of the
/// plane as drawn, clipped to the object's box) and basis, and the KRS's placement in the world.
struct MirrorFrame {
    id: u64,
    index: usize,
    plane: MirrorPlane,
    centre: Vec3,
    axes: [Vec3; 2],
    world: thicket_core::krs::Similarity,
}

impl MirrorFrame {
    fn of(editor: &Editor, panel: &KrsPanel, proj: &Projector) -> Option<Self> {
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
        let plane = MirrorPlane {
            normal: n,
            offset: plane.offset / plane.normal.length(),
        };
        let (lo, hi) = plane_box(&world, proj);
        let polygon = plane_in_box(plane.normal, plane.offset, lo, hi);
        let centre = if polygon.is_empty() {
            let c = 0.5 * (lo + hi);
            c - n * (n.dot(c) - plane.offset)
        } else {
            polygon.iter().copied().sum::<Vec3>() / polygon.len() as f32
        };
        let (u, v) = n.any_orthonormal_pair();
        Some(Self {
            id,
            index,
            plane,
            centre,
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
    /// The arrow's [`MirrorHandleShape::along_px`].
    arrow_px: egui::Vec2,
    /// KRS-space length of one gizmo size.
    arrow_krs: f32,
}

impl KrsPanel {
    /// The highlighted mirror plane's gizmo handles on the screen (empty when no plane of the
    /// selected KRS object is highlighted): two rings around the plane's centre and, beyond
    /// them along the normal's direction on the screen, the arrow.
    #[must_use]
    pub fn mirror_handles(&self, editor: &Editor, proj: &Projector) -> Vec<MirrorHandleShape> {
        let Some(f) = MirrorFrame::of(editor, self, proj) else {
            return Vec::new();
        };
        let p = f.world.transform_point(f.centre);
        let Some(centre_px) = proj.to_screen(p) else {
            return Vec::new();
        };
        let size = MIRROR_GIZMO_PX * proj.world_per_point(p);
        let n = f.dir_world(f.plane.normal);
        let mut rings = Vec::new();
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
                rings.push(MirrorHandleShape {
                    handle: MirrorHandle::Tilt(k),
                    points,
                    along_px: egui::Vec2::ZERO,
                });
            }
        }
        // The arrow starts beyond the rings' farthest point on the screen, so it never lies
        // on a ring, whatever the view (a ring seen edge-on is a line through the centre, and
        // a normal facing the camera would put an arrow from the centre inside the rings).
        let ring_px = rings
            .iter()
            .flat_map(|r| &r.points)
            .map(|q| q.distance(centre_px))
            .fold(MIRROR_GIZMO_PX, f32::max);
        let normal_px = proj
            .to_screen(p + n * size)
            .map_or(egui::Vec2::ZERO, |tip| tip - centre_px);
        let dir = if normal_px.length() > 1e-3 {
            normal_px.normalized()
        } else {
            -egui::Vec2::Y
        };
        let start = centre_px + dir * (ring_px + ARROW_GAP_PX);
        let mut out = vec![MirrorHandleShape {
            handle: MirrorHandle::Offset,
            points: vec![start, start + dir * ARROW_PX],
            along_px: dir * normal_px.length().max(0.25 * MIRROR_GIZMO_PX),
        }];
        out.extend(rings);
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
            && let Some(f) = MirrorFrame::of(editor, self, proj)
        {
            let handles = self.mirror_handles(editor, proj);
            let p = f.world.transform_point(f.centre);
            if let Some(h) = grab_handle(&handles, start)
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
                let arrow_px = h.along_px;
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
    // What the builder would open: the parameters stored with the object, or those of the
    // builder preset whose kernels and mirrors it has (a tree made before they were stored).
    let adoptable = if open {
        None
    } else {
        editor.tree_params(id).cloned().or_else(|| {
            let k = editor.krs(id)?;
            presets::builder_presets()
                .into_iter()
                .find_map(|(_, params)| {
                    let built = params.build().ok()?;
                    same_shape(&built, k).then_some(params)
                })
        })
    };
    ui.horizontal(|ui| {
        ui.strong("Tree builder")
            .on_hover_text("Build this object as a tree from fork positions, bends and widths");
        if let Some(params) = adoptable.clone()
            && ui
                .button("Edit tree")
                .on_hover_text(
                    "Open the builder with the parameters this tree was built from (saved with the project)",
                )
                .clicked()
        {
            panel.tree = Some((id, params));
            panel.confirm_default_tree = None;
            return;
        }
        if !open
            && ui
                .button("Start from the default tree")
                .on_hover_text(
                    "Replace this object with the default tree and open the builder (asks first; undoable)",
                )
                .clicked()
        {
            panel.confirm_default_tree = Some(id);
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
    let open = panel.tree.as_ref().is_some_and(|(t, _)| *t == id);
    if !open && adoptable.is_none() {
        ui.weak("Not built by the tree builder: its kernels are not a branch route");
    }
    if !open && panel.confirm_default_tree == Some(id) {
        ui.horizontal(|ui| {
            ui.label("Replace this object with the default tree?");
            if ui
                .button("Replace")
                .on_hover_text("Rebuild this object as the default tree (undoable)")
                .clicked()
            {
                panel.confirm_default_tree = None;
                let params = TreeParams::default();
                editor.end_interaction();
                panel.error = editor.build_tree(id, &params).err().map(|e| e.to_string());
                editor.end_interaction();
                if panel.error.is_none() {
                    editor.frame_selection();
                }
                panel.tree = Some((id, params));
            }
            if ui
                .button("Cancel")
                .on_hover_text("Keep this object as it is")
                .clicked()
            {
                panel.confirm_default_tree = None;
            }
        });
    }
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

/// Whether `a` and `b` have the same kernels and mirrors up to rounding: every edit stores the
/// validated copy, whose normalisation moves the last bits of normals and directions each time.
fn same_shape(a: &thicket_core::krs::KrsObject, b: &thicket_core::krs::KrsObject) -> bool {
    fn near(a: &serde_json::Value, b: &serde_json::Value) -> bool {
        use serde_json::Value;
        match (a, b) {
            (Value::Number(x), Value::Number(y)) => match (x.as_f64(), y.as_f64()) {
                (Some(x), Some(y)) => (x - y).abs() <= 1e-5 * x.abs().max(1.0),
                _ => x == y,
            },
            (Value::Array(x), Value::Array(y)) => {
                x.len() == y.len() && x.iter().zip(y).all(|(x, y)| near(x, y))
            }
            (Value::Object(x), Value::Object(y)) => {
                x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| near(v, w)))
            }
            _ => a == b,
        }
    }
    let parts = |o: &thicket_core::krs::KrsObject| {
        serde_json::to_value((&o.kernels, &o.mirrors)).unwrap_or_default()
    };
    a.kernels.len() == b.kernels.len()
        && a.mirrors.len() == b.mirrors.len()
        && near(&parts(a), &parts(b))
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

#[cfg(test)]
mod tests {
    use super::*;
    use thicket_core::scene::{Document, ObjectKind, OrbitCamera};

    /// The distance between segments `a` and `b` (0 when they cross).
    fn segment_distance(a: [egui::Pos2; 2], b: [egui::Pos2; 2]) -> f32 {
        let cross = |o: egui::Pos2, p: egui::Pos2, q: egui::Pos2| {
            (p - o).x * (q - o).y - (p - o).y * (q - o).x
        };
        let (d1, d2) = (cross(a[0], a[1], b[0]), cross(a[0], a[1], b[1]));
        let (d3, d4) = (cross(b[0], b[1], a[0]), cross(b[0], b[1], a[1]));
        if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
            return 0.0;
        }
        [
            distance_to_polyline(a[0], &b),
            distance_to_polyline(a[1], &b),
            distance_to_polyline(b[0], &a),
            distance_to_polyline(b[1], &a),
        ]
        .into_iter()
        .fold(f32::INFINITY, f32::min)
    }

    fn polyline_distance(a: &[egui::Pos2], b: &[egui::Pos2]) -> f32 {
        a.windows(2)
            .flat_map(|s| {
                b.windows(2)
                    .map(move |t| segment_distance([s[0], s[1]], [t[0], t[1]]))
            })
            .fold(f32::INFINITY, f32::min)
    }

    #[test]
    fn the_plane_gizmo_arrow_stays_out_of_reach_of_its_rings_from_every_view() {
        let mut doc = Document::default();
        doc.add("Coral", ObjectKind::Krs(presets::coral()));
        let mut editor = Editor::new(doc, None);
        let id = editor.doc().objects[0].id;
        editor.selection = Some(Selection::Object(id));
        let k = editor.krs(id).unwrap().clone();
        let (centre, radius) = k.bounding_sphere_object().unwrap();
        let rect = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(800.0, 600.0));
        let mut panel = KrsPanel {
            editor_open: true,
            ..KrsPanel::default()
        };
        let (mut views, mut closest) = (0, f32::INFINITY);
        for mirror in 0..k.mirrors.len() {
            panel.mirror = Some(mirror);
            for orthographic in [false, true] {
                for yaw in (0..360).step_by(10) {
                    for pitch in (-85..=85).step_by(5) {
                        let camera = OrbitCamera {
                            target: centre,
                            yaw_deg: yaw as f32,
                            pitch_deg: pitch as f32,
                            distance: 4.0 * radius,
                            orthographic,
                            ..OrbitCamera::default()
                        };
                        let proj = Projector::new(camera, rect);
                        let handles = panel.mirror_handles(&editor, &proj);
                        let arrow = handles
                            .iter()
                            .find(|h| h.handle == MirrorHandle::Offset)
                            .expect("an arrow");
                        let rings: Vec<_> = handles
                            .iter()
                            .filter(|h| matches!(h.handle, MirrorHandle::Tilt(_)))
                            .collect();
                        assert_eq!(rings.len(), 2);
                        for ring in rings {
                            let d = polyline_distance(&arrow.points, &ring.points);
                            closest = closest.min(d);
                            assert!(
                                d > MIRROR_GRAB_PX,
                                "R{mirror} yaw {yaw} pitch {pitch} ortho {orthographic}: the \
                                 arrow is {d} points from {:?}",
                                ring.handle
                            );
                        }
                        views += 1;
                    }
                }
            }
        }
        assert!(views > 1000, "{views} views");
        eprintln!("{views} views, closest {closest:.1} points");
    }

    #[test]
    fn a_press_in_reach_of_the_arrow_and_a_ring_grabs_the_arrow() {
        let line = |a: (f32, f32), b: (f32, f32)| vec![egui::pos2(a.0, a.1), egui::pos2(b.0, b.1)];
        let handles = [
            MirrorHandleShape {
                handle: MirrorHandle::Tilt(0),
                points: line((0.0, 0.0), (100.0, 0.0)),
                along_px: egui::Vec2::ZERO,
            },
            MirrorHandleShape {
                handle: MirrorHandle::Offset,
                points: line((0.0, 6.0), (100.0, 6.0)),
                along_px: egui::vec2(0.0, 60.0),
            },
        ];
        // Nearer the ring, within reach of both: the arrow wins.
        let at = egui::pos2(50.0, 1.0);
        assert_eq!(
            grab_handle(&handles, at).unwrap().handle,
            MirrorHandle::Offset
        );
        // Out of the arrow's reach: the ring.
        let at = egui::pos2(50.0, -5.0);
        assert_eq!(
            grab_handle(&handles, at).unwrap().handle,
            MirrorHandle::Tilt(0)
        );
        assert!(grab_handle(&handles, egui::pos2(50.0, 40.0)).is_none());
    }

    #[test]
    fn a_typed_component_is_kept_and_the_others_make_the_length_one() {
        let v = Vec3::new(0.6, 0.8, 0.0);
        let w = with_component(v, 0, 0.2);
        assert_eq!(w.x, 0.2);
        assert!((w.length() - 1.0).abs() < 1e-6, "{w}");
        // The others keep their proportions.
        assert!((w.y / w.length() - (1.0 - 0.04f32).sqrt()).abs() < 1e-6 && w.z == 0.0);
        // Nothing off the axis: the rest goes to the next axis.
        assert_eq!(with_component(Vec3::X, 0, 0.6), Vec3::new(0.6, 0.8, 0.0));
        assert_eq!(with_component(Vec3::Z, 2, 0.0), Vec3::X);
        // Beyond ±1: clamped; the others vanish.
        assert_eq!(with_component(v, 1, -3.0), Vec3::new(0.0, -1.0, 0.0));
    }

    #[test]
    fn a_plane_is_clipped_to_the_box_and_fades_away_from_the_eye() {
        let (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
        // Through the centre along an axis: the square cross-section.
        let square = plane_in_box(Vec3::Y, 0.0, lo, hi);
        assert_eq!(square.len(), 4);
        assert!(
            square
                .iter()
                .all(|p| p.y == 0.0 && p.x.abs() == 1.0 && p.z.abs() == 1.0)
        );
        // Perpendicular to a diagonal through the centre: a hexagon inside the box.
        let hexagon = plane_in_box(Vec3::ONE.normalize_or_zero(), 0.0, lo, hi);
        assert_eq!(hexagon.len(), 6);
        assert!(hexagon.iter().all(|p| p.abs().max_element() <= 1.0 + 1e-6));
        // In order around the polygon: consecutive corners share a face of the box.
        for (i, a) in hexagon.iter().enumerate() {
            let b = hexagon[(i + 1) % 6];
            let shared = (0..3).any(|k| (a[k] - b[k]).abs() < 1e-6 && a[k].abs() > 1.0 - 1e-6);
            assert!(shared, "{a} -> {b}");
        }
        // Outside the box: nothing.
        assert!(plane_in_box(Vec3::X, 1.5, lo, hi).is_empty());
        assert_eq!(fade_alpha(2.0, 2.0, 6.0), 1.0);
        assert_eq!(fade_alpha(6.0, 2.0, 6.0), FAR_ALPHA);
        assert!(fade_alpha(3.0, 2.0, 6.0) > fade_alpha(5.0, 2.0, 6.0));
    }
}

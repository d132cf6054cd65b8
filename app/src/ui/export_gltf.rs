//! File → Export glTF: the options of `thicket export` in a window; the export itself runs on a
//! worker thread with progress and Cancel (`EditorApp::start_export_gltf`), calling the same
//! `core::io::gltf_export::export_gltf` as the CLI.

use thicket_core::io::gltf_export::{ColorMode, ExportMode, GltfExportOptions};

/// Smallest and largest KRS meshing resolution offered (cells along the longest side).
const RESOLUTION_RANGE: std::ops::RangeInclusive<u32> = 16..=1024;

/// Smallest and largest whole-export triangle budget offered (the largest: about 2.5 GiB of
/// GLB, under the format's 4 GiB limit).
const TRIANGLE_BUDGET_RANGE: std::ops::RangeInclusive<u64> = 1_000..=(1 << 26);

/// Largest KRS reflection level offered for the prototype/placement split.
const MAX_INSTANCE_LEVEL: usize = 32;

/// A ticked checkbox for an option left to the exporter (`None`); unticking it sets `manual`.
fn automatic<T>(ui: &mut egui::Ui, value: &mut Option<T>, label: &str, hint: &str, manual: T) {
    let mut auto = value.is_none();
    if ui.checkbox(&mut auto, label).on_hover_text(hint).changed() {
        *value = if auto { None } else { Some(manual) };
    }
}

/// The one line the Export dialog says about a placement choice before the file is written.
#[must_use]
pub fn instancing_consequence(choice: thicket_core::io::gltf_export::Instancing) -> &'static str {
    use thicket_core::io::gltf_export::Instancing;
    match choice {
        Instancing::Gpu => {
            "Viewers without EXT_mesh_gpu_instancing refuse the file (Blender 3.4 among them)"
        }
        Instancing::Nodes => "Every viewer opens it; no levels of detail for the placed copies",
        Instancing::Auto => {
            "A node each for a small forest (every viewer); GPU instancing for a large one"
        }
        Instancing::Flatten => {
            "Every copy baked into plain meshes (any tool); large, within the triangle limit"
        }
    }
}

/// The KRS rows of the options grid: where the prototype ends, and the ground patch.
fn krs_rows(ui: &mut egui::Ui, options: &mut GltfExportOptions) {
    ui.label("KRS instancing");
    ui.horizontal(|ui| {
        automatic(
            ui,
            &mut options.instance_level,
            "Automatic",
            "Mesh one tree (the kernels and the mirrors that build it) and place it with the \
             mirrors above it that carry no kernels: the deepest such level is chosen per object",
            0,
        );
        if let Some(level) = &mut options.instance_level {
            ui.add(
                egui::DragValue::new(level)
                    .range(0..=MAX_INSTANCE_LEVEL)
                    .prefix("level "),
            )
            .on_hover_text(
                "Reflection level where the prototype ends: mirrors above it become instance \
                 placements. 0: every mirror places copies of the bare kernels; past the \
                 object's mirrors: one mesh, no instancing.",
            );
        }
    });
    ui.end_row();
    ui.label("Most instances");
    ui.add(
        egui::DragValue::new(&mut options.max_instances)
            .range(1..=(1usize << 24))
            .speed(1000.0),
    )
    .on_hover_text("Per KRS object: an export that would place more copies is refused");
    ui.end_row();
    ui.label("Placements as");
    ui.vertical(|ui| {
        ui.horizontal(|ui| {
            use thicket_core::io::gltf_export::Instancing;
            ui.radio_value(&mut options.instancing, Instancing::Gpu, "GPU instancing")
                .on_hover_text("EXT_mesh_gpu_instancing: compact and fast to draw");
            ui.radio_value(&mut options.instancing, Instancing::Nodes, "A node each")
                .on_hover_text("One node per placement sharing the mesh: every glTF reader");
            ui.radio_value(&mut options.instancing, Instancing::Auto, "By count")
                .on_hover_text("A node each up to 4,096 placements, else GPU instancing");
            ui.radio_value(&mut options.instancing, Instancing::Flatten, "Flatten")
                .on_hover_text(
                    "No instancing: every placement's copy written as plain triangles, for \
                     tools without instancing (refused past the triangle limit)",
                );
        });
        ui.weak(instancing_consequence(options.instancing));
    });
    ui.end_row();
    ui.label("Ground patch");
    ui.horizontal(|ui| {
        automatic(
            ui,
            &mut options.bounds,
            "Around the objects",
            "Unbounded KRS objects (ground plane, terrain) are written as a patch: by default \
             the area the other objects cover plus a margin",
            [-50.0, -50.0, 50.0, 50.0],
        );
        if let Some(b) = &mut options.bounds {
            for (i, label) in ["min x ", "min z ", "max x ", "max z "].iter().enumerate() {
                ui.add(egui::DragValue::new(&mut b[i]).prefix(*label).suffix(" m"));
            }
            // Keep min < max (the exporter refuses an empty patch).
            b[2] = b[2].max(b[0] + 0.01);
            b[3] = b[3].max(b[1] + 0.01);
        }
    });
    ui.end_row();
}

/// The export window's state; it keeps its settings between exports.
#[derive(Debug, Clone, Default)]
pub struct GltfExportPanel {
    /// Whether the window is shown.
    pub open: bool,
    /// What is exported and how.
    pub options: GltfExportOptions,
    /// Export only the selected object (else every visible one).
    pub selected_only: bool,
    /// "Bake the pose into the clip" was pressed: the caller keys every posed joint.
    pub bake_request: bool,
}

impl GltfExportPanel {
    /// The options for an export, with the selection applied (`selected`: the selected
    /// object's name, if any).
    #[must_use]
    pub fn options_for(&self, selected: Option<&str>) -> GltfExportOptions {
        let mut o = self.options.clone();
        o.object = if self.selected_only {
            selected.map(str::to_owned)
        } else {
            None
        };
        // Like Blender's "Selected objects": a one-object export is that object alone.
        o.lights_and_camera &= o.object.is_none();
        o
    }

    /// Draws the window. Returns true when the user pressed "Export..." (the caller asks for
    /// the path, then starts the job).
    /// `posed`: the visible rigged models whose pose overrides are not keyed (id, name, count).
    pub fn ui(
        &mut self,
        ctx: &egui::Context,
        selected: Option<&str>,
        busy: bool,
        posed: &[(u64, String, usize)],
    ) -> bool {
        if !self.open {
            return false;
        }
        let mut go = false;
        let mut open = self.open;
        egui::Window::new("Export glTF")
            .open(&mut open)
            .resizable(false)
            .show(ctx, |ui| {
                egui::Grid::new("gltf_export")
                    .num_columns(2)
                    .show(ui, |ui| {
                        ui.label("Voxel models as");
                        ui.horizontal(|ui| {
                            ui.radio_value(&mut self.options.mode, ExportMode::Cubes, "Cubes")
                                .on_hover_text(
                                    "Exact blocks: faces between solid and empty voxels, merged \
                                 into quads. Rigged models keep their skeleton, weights and \
                                 clips. KRS objects: one prototype mesh (a tree) drawn once per \
                                 placement (EXT_mesh_gpu_instancing).",
                                );
                            ui.radio_value(&mut self.options.mode, ExportMode::Smooth, "Smooth")
                                .on_hover_text(
                                    "A smooth closed surface through the voxel centres (rigged \
                                 models as their bind pose, without the skeleton)",
                                );
                            ui.radio_value(
                                &mut self.options.mode,
                                ExportMode::Instances,
                                "Instances",
                            )
                            .on_hover_text(
                                "KRS objects as one small mesh per kernel drawn once per kernel \
                             instance (EXT_mesh_gpu_instancing): exact kernels, but far more \
                             instances than Cubes; voxel models as cubes",
                            );
                        });
                        ui.end_row();
                        ui.label("KRS resolution");
                        ui.add(
                            egui::DragValue::new(&mut self.options.resolution)
                                .range(RESOLUTION_RANGE)
                                .suffix(" cells"),
                        )
                        .on_hover_text(
                            "KRS distance-field meshing: cells along the longest side of each KRS \
                         object. Doubling it gives about 4x the triangles.",
                        );
                        ui.end_row();
                        krs_rows(ui, &mut self.options);
                        ui.label("Levels of detail");
                        ui.add(egui::DragValue::new(&mut self.options.lod_levels).range(0..=6))
                            .on_hover_text(
                                "Coarser copies written as MSFT_lod levels, each at half the \
                             resolution of the one before: static voxel models (cubes mode, needs \
                             vertex colours) and KRS meshes (the distance field meshed again; a \
                             level that would lose the shape's outline is left out). Instanced \
                             KRS prototypes (a forest's tree) get 3 levels and an impostor \
                             whatever this says, in cells of placements",
                            );
                        ui.end_row();
                        ui.label("Colours");
                        ui.horizontal(|ui| {
                            ui.radio_value(
                                &mut self.options.colors,
                                ColorMode::VertexColors,
                                "Vertex colours",
                            )
                            .on_hover_text("COLOR_0 per vertex");
                            ui.radio_value(
                                &mut self.options.colors,
                                ColorMode::PaletteTexture,
                                "Palette texture",
                            )
                            .on_hover_text("A PNG palette with one texel per colour, and UVs");
                        });
                        ui.end_row();
                        ui.label("Objects");
                        ui.add_enabled(
                            selected.is_some(),
                            egui::Checkbox::new(&mut self.selected_only, "Selected object only"),
                        )
                        .on_hover_text(
                            "Export only the selected object (hidden or not); otherwise every \
                         visible object",
                        );
                        ui.end_row();
                        let one_object = self.selected_only && selected.is_some();
                        ui.label("");
                        ui.add_enabled(
                            !one_object,
                            egui::Checkbox::new(
                                &mut self.options.lights_and_camera,
                                "Lights and camera",
                            ),
                        )
                        .on_hover_text(
                            "Write the scene's sun lights (KHR_lights_punctual) and the view \
                         camera as nodes; a selected-object export writes that object alone",
                        );
                        ui.end_row();
                        ui.label("Triangle budget");
                        ui.add(
                            egui::DragValue::new(&mut self.options.max_triangles)
                                .range(TRIANGLE_BUDGET_RANGE)
                                .speed(10_000.0),
                        )
                        .on_hover_text(
                            "An export with more triangles than this is refused before it is \
                         built, with the count in the message",
                        );
                        ui.end_row();
                    });
                ui.separator();
                let what = match (self.selected_only, selected) {
                    (true, Some(name)) => format!("Exports {name:?}"),
                    _ => "Exports every visible object".to_owned(),
                };
                ui.label(what);
                if !posed.is_empty() {
                    let names: Vec<String> = posed
                        .iter()
                        .map(|(_, name, n)| format!("{name:?} ({n} joint(s))"))
                        .collect();
                    ui.colored_label(
                        ui.visuals().warn_fg_color,
                        format!(
                            "Posed but not keyed: {}. The file carries clips, not the pose: \
                             bake it, or it is lost.",
                            names.join(", ")
                        ),
                    );
                    if ui
                        .button("Bake the pose into the clip")
                        .on_hover_text(
                            "Key every posed joint at the playhead of the playing clip (a new \
                             \"Pose\" clip on the rest pose), one undo step",
                        )
                        .clicked()
                    {
                        self.bake_request = true;
                    }
                }
                if ui
                    .add_enabled(!busy, egui::Button::new("Export..."))
                    .on_hover_text("Choose a .glb or .gltf file and export on a worker thread")
                    .clicked()
                {
                    go = true;
                }
            });
        self.open = open;
        go
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selected_only_applies_only_with_a_selection() {
        let mut p = GltfExportPanel {
            selected_only: true,
            ..GltfExportPanel::default()
        };
        assert_eq!(p.options_for(Some("Tree")).object.as_deref(), Some("Tree"));
        assert_eq!(p.options_for(None).object, None);
        p.selected_only = false;
        assert_eq!(p.options_for(Some("Tree")).object, None);
    }

    #[test]
    fn a_one_object_export_leaves_the_lights_and_camera_out() {
        let mut p = GltfExportPanel {
            selected_only: true,
            ..GltfExportPanel::default()
        };
        assert!(!p.options_for(Some("Tree")).lights_and_camera);
        assert!(
            p.options_for(None).lights_and_camera,
            "no selection: the whole scene"
        );
        p.selected_only = false;
        assert!(p.options_for(Some("Tree")).lights_and_camera);
        p.options.lights_and_camera = false;
        assert!(!p.options_for(None).lights_and_camera, "the user's choice");
    }
}

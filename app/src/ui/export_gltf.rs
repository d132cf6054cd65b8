//! File → Export glTF: the options of `thicket export` in a window; the export itself runs on a
//! worker thread with progress and Cancel (`EditorApp::start_export_gltf`), calling the same
//! `core::io::gltf_export::export_gltf` as the CLI.

use thicket_core::io::gltf_export::{ColorMode, ExportMode, GltfExportOptions};

/// Smallest and largest KRS meshing resolution offered (cells along the longest side).
const RESOLUTION_RANGE: std::ops::RangeInclusive<u32> = 16..=1024;

/// The export window's state; it keeps its settings between exports.
#[derive(Debug, Clone, Default)]
pub struct GltfExportPanel {
    /// Whether the window is shown.
    pub open: bool,
    /// What is exported and how.
    pub options: GltfExportOptions,
    /// Export only the selected object (else every visible one).
    pub selected_only: bool,
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
        o
    }

    /// Draws the window. Returns true when the user pressed "Export..." (the caller asks for
    /// the path, then starts the job).
    pub fn ui(&mut self, ctx: &egui::Context, selected: Option<&str>, busy: bool) -> bool {
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
                                 clips.",
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
                                "KRS objects as one mesh per kernel drawn once per kernel instance \
                             (EXT_mesh_gpu_instancing); voxel models as cubes",
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
                        ui.label("Levels of detail");
                        ui.add(egui::DragValue::new(&mut self.options.lod_levels).range(0..=6))
                            .on_hover_text(
                                "Cubes mode: coarser copies of each static voxel model (MSFT_lod), \
                             each at half the resolution of the one before; needs vertex colours",
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
                    });
                ui.separator();
                let what = match (self.selected_only, selected) {
                    (true, Some(name)) => format!("Exports {name:?}"),
                    _ => "Exports every visible object".to_owned(),
                };
                ui.label(what);
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
}

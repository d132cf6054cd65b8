//! The New voxel model dialog (File → New project, Edit → Add voxel model): name, extent per
//! axis, voxel size and initial fill; the limits are checked before the dialog closes.

use glam::UVec3;
use thicket_core::sculpt::model_ops::InitialFill;

use crate::editor::{Editor, MAX_EXTENT, NewModelSpec};

/// The initial fills the dialog offers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FillChoice {
    Empty,
    Slab,
    Solid,
}

/// The dialog's state.
#[derive(Debug, Clone)]
pub struct NewModelDialog {
    /// Whether the window is open.
    pub open: bool,
    /// The request being edited.
    pub spec: NewModelSpec,
    fill: FillChoice,
    slab_height: u32,
    /// Why the last OK was refused.
    pub error: Option<String>,
}

impl Default for NewModelDialog {
    fn default() -> Self {
        Self {
            open: false,
            spec: NewModelSpec::default(),
            fill: FillChoice::Empty,
            slab_height: 1,
            error: None,
        }
    }
}

impl NewModelDialog {
    /// Opens the dialog with a fresh name.
    pub fn show(&mut self, editor: &Editor) {
        self.open = true;
        self.error = None;
        let n = editor
            .doc()
            .objects
            .iter()
            .filter(|o| o.name.starts_with("Model"))
            .count();
        self.spec.name = if n == 0 {
            "Model".into()
        } else {
            format!("Model {}", n + 1)
        };
    }

    fn fill(&self) -> InitialFill {
        match self.fill {
            FillChoice::Empty => InitialFill::Empty,
            FillChoice::Slab => InitialFill::GroundSlab {
                height: self.slab_height.max(1),
            },
            FillChoice::Solid => InitialFill::SolidBox,
        }
    }

    /// Draws the window; on Create adds the model to `editor`. Returns the new id.
    pub fn ui(&mut self, ctx: &egui::Context, editor: &mut Editor) -> Option<u64> {
        if !self.open {
            return None;
        }
        let mut created = None;
        let mut open = true;
        egui::Window::new("New voxel model")
            .collapsible(false)
            .resizable(false)
            .open(&mut open)
            .show(ctx, |ui| {
                egui::Grid::new("new_model_grid")
                    .num_columns(2)
                    .show(ui, |ui| {
                        ui.label("Name");
                        ui.text_edit_singleline(&mut self.spec.name);
                        ui.end_row();
                        ui.label("Extent (voxels)");
                        ui.horizontal(|ui| {
                            let mut s = self.spec.size.to_array();
                            for (v, axis) in s.iter_mut().zip(["X", "Y", "Z"]) {
                                ui.add(
                                    egui::DragValue::new(v)
                                        .range(1..=MAX_EXTENT)
                                        .prefix(format!("{axis} "))
                                        .speed(1.0),
                                )
                                .on_hover_text(format!(
                                    "Voxels along {axis}: 1 to {MAX_EXTENT} (the octree's limit, 2^21)"
                                ));
                            }
                            self.spec.size = UVec3::from_array(s);
                        });
                        ui.end_row();
                        ui.label("Voxel size");
                        ui.add(
                            egui::DragValue::new(&mut self.spec.voxel_size)
                                .range(1e-4..=100.0)
                                .speed(0.01)
                                .suffix(" m"),
                        )
                        .on_hover_text("Edge of one voxel in metres");
                        ui.end_row();
                        ui.label("Fill");
                        ui.horizontal(|ui| {
                            ui.selectable_value(&mut self.fill, FillChoice::Empty, "Empty")
                                .on_hover_text("Start with no voxels: place the first on the volume's floor");
                            ui.selectable_value(&mut self.fill, FillChoice::Slab, "Ground slab")
                                .on_hover_text("A slab of this many voxels on the volume's floor");
                            if self.fill == FillChoice::Slab {
                                ui.add(
                                    egui::DragValue::new(&mut self.slab_height)
                                        .range(1..=self.spec.size.y.max(1))
                                        .suffix(" vox"),
                                );
                            }
                            ui.selectable_value(&mut self.fill, FillChoice::Solid, "Solid box")
                                .on_hover_text("The whole volume solid (carve it)");
                        });
                        ui.end_row();
                        ui.label("Colour");
                        let mut c = egui::Color32::from_rgb(
                            self.spec.color[0],
                            self.spec.color[1],
                            self.spec.color[2],
                        );
                        if ui.color_edit_button_srgba(&mut c).changed() {
                            self.spec.color = [c.r(), c.g(), c.b(), 255];
                        }
                        ui.end_row();
                    });
                let world = self.spec.size.as_vec3() * self.spec.voxel_size;
                ui.weak(format!(
                    "{:.2} × {:.2} × {:.2} m, standing on the ground where the view looks",
                    world.x, world.y, world.z
                ));
                if let Some(e) = &self.error {
                    ui.colored_label(ui.visuals().error_fg_color, e);
                }
                ui.horizontal(|ui| {
                    if ui.button("Create").clicked() {
                        let spec = NewModelSpec {
                            fill: self.fill(),
                            ..self.spec.clone()
                        };
                        match editor.add_voxel_model(&spec) {
                            Ok(id) => {
                                created = Some(id);
                                self.open = false;
                            }
                            Err(e) => self.error = Some(e.to_string()),
                        }
                    }
                    if ui.button("Cancel").clicked() {
                        self.open = false;
                    }
                });
            });
        if !open {
            self.open = false;
        }
        created
    }
}

//! File → Export .vox when the scene holds objects a `.vox` file cannot: the artist is told
//! which before choosing a file, and may voxelize the meshes first (at a chosen depth, surface
//! or solid, each a Voxelize mesh job with progress and Cancel), then the export goes on.

use super::EditorApp;
use super::path_prompt::PathPurpose;
use crate::editor::jobs::Job;
use thicket_core::scene::ObjectKind;

/// The Export .vox offer and the meshes still to voxelize before the export.
#[derive(Debug, Default)]
pub struct VoxExportFlow {
    /// The offer's window, while open: the visible meshes (id, name) and KRS objects (names)
    /// the export would leave out.
    pub offer: Option<LeftOut>,
    /// Meshes queued to voxelize before the export (the running job's is not in it).
    queue: Vec<u64>,
    /// Whether the export's file prompt opens once the queue has run.
    export_after: bool,
}

/// What a `.vox` export would leave out of the document.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LeftOut {
    /// Visible mesh objects, id and name.
    pub meshes: Vec<(u64, String)>,
    /// Visible KRS objects, by name.
    pub krs: Vec<String>,
}

impl LeftOut {
    /// The visible objects of `doc` that are not voxel models.
    #[must_use]
    pub fn of(doc: &thicket_core::scene::Document) -> Self {
        let mut out = Self::default();
        for o in doc.objects.iter().filter(|o| o.visible) {
            match &o.kind {
                ObjectKind::Mesh(_) => out.meshes.push((o.id, o.name.clone())),
                ObjectKind::Krs(_) => out.krs.push(o.name.clone()),
                ObjectKind::Voxels(_) => {}
            }
        }
        out
    }

    fn is_empty(&self) -> bool {
        self.meshes.is_empty() && self.krs.is_empty()
    }
}

/// Names as a short list: `"a", "b" and 3 more`.
fn names(list: &[String]) -> String {
    const SHOWN: usize = 4;
    let shown: Vec<String> = list.iter().take(SHOWN).map(|n| format!("{n:?}")).collect();
    match list.len().saturating_sub(SHOWN) {
        0 => shown.join(", "),
        more => format!("{} and {more} more", shown.join(", ")),
    }
}

impl EditorApp {
    /// File → Export .vox: straight to the file prompt when every visible object is a voxel
    /// model, else the offer first.
    pub fn request_export_vox(&mut self) {
        let left_out = LeftOut::of(self.editor.doc());
        if left_out.is_empty() {
            self.ask_path(PathPurpose::ExportVox);
        } else {
            self.vox_export.offer = Some(left_out);
        }
    }

    /// The offer's window: what would be left out, the voxelize settings, and the choices.
    pub(super) fn vox_export_offer(&mut self, ctx: &egui::Context) {
        let Some(left_out) = self.vox_export.offer.clone() else {
            return;
        };
        let mut choice = None;
        egui::Window::new("Export .vox")
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_CENTER, egui::Vec2::ZERO)
            .show(ctx, |ui| {
                ui.label("A .vox file holds voxel models only.");
                if !left_out.meshes.is_empty() {
                    let meshes: Vec<String> = left_out.meshes.iter().map(|m| m.1.clone()).collect();
                    ui.label(format!(
                        "{} mesh object(s) would be left out: {}.",
                        meshes.len(),
                        names(&meshes)
                    ));
                }
                if !left_out.krs.is_empty() {
                    ui.label(format!(
                        "{} KRS object(s) would be left out: {} (Export glTF writes them).",
                        left_out.krs.len(),
                        names(&left_out.krs)
                    ));
                }
                if !left_out.meshes.is_empty() {
                    ui.separator();
                    ui.horizontal(|ui| {
                        ui.label("Voxelize at depth");
                        ui.add(egui::DragValue::new(&mut self.voxelize.depth).range(2..=11))
                            .on_hover_text(
                                "2^depth voxels along each mesh's longest side (thicket import \
                                 --depth)",
                            );
                        ui.selectable_value(&mut self.voxelize.solid, false, "Surface");
                        ui.selectable_value(&mut self.voxelize.solid, true, "Solid")
                            .on_hover_text("Fill closed meshes");
                    });
                }
                ui.horizontal(|ui| {
                    if !left_out.meshes.is_empty()
                        && ui
                            .button("Voxelize the meshes, then export")
                            .on_hover_text(
                                "Each mesh becomes a voxel model \"NAME voxels\" (the mesh is \
                                 hidden; one undo step each), then choose the file",
                            )
                            .clicked()
                    {
                        choice = Some(true);
                    }
                    if ui
                        .button("Export without them")
                        .on_hover_text("Write the visible voxel models only")
                        .clicked()
                    {
                        choice = Some(false);
                    }
                    if ui.button("Cancel").clicked() {
                        self.vox_export.offer = None;
                    }
                });
            });
        match choice {
            Some(true) => {
                self.vox_export.offer = None;
                self.vox_export.queue = left_out.meshes.iter().map(|m| m.0).collect();
                self.vox_export.export_after = true;
                self.voxelize_next_for_export();
            }
            Some(false) => {
                self.vox_export.offer = None;
                self.ask_path(PathPurpose::ExportVox);
            }
            None => {}
        }
    }

    /// Starts the next queued mesh's Voxelize mesh job; with none left, opens the export's
    /// file prompt. Called when the offer is accepted and after each voxelize job is placed.
    pub(super) fn voxelize_next_for_export(&mut self) {
        if self.job.is_some() {
            return;
        }
        while let Some(id) = self.vox_export.queue.first().copied() {
            self.vox_export.queue.remove(0);
            let Some(o) = self.editor.object(id) else {
                continue;
            };
            let ObjectKind::Mesh(m) = &o.kind else {
                continue;
            };
            let settings = self.voxelize.settings();
            self.job = Some(Job::voxelize_mesh(
                id,
                &o.name.clone(),
                m.model.clone(),
                settings,
                self.memory_budget,
            ));
            return;
        }
        if std::mem::take(&mut self.vox_export.export_after) {
            self.ask_path(PathPurpose::ExportVox);
        }
    }

    /// A voxelize job for the export failed or was cancelled: the rest is not started and no
    /// file prompt opens (the error says why).
    pub(super) fn stop_export_voxelizing(&mut self) {
        self.vox_export.queue.clear();
        self.vox_export.export_after = false;
    }
}

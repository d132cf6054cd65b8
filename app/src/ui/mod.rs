//! The eframe app: menu bar, outliner, inspector, status bar and the central preview.
//!
//! [`EditorApp::ui_root`] draws the whole window into a [`egui::Ui`]; eframe calls it through
//! [`eframe::App::ui`] and tests call it through `egui_kittest` without a window.

mod dialogs;
pub mod dope_sheet;
pub use dialogs::shortcut_rows;
mod enhance_panel;
pub mod export_gltf;
mod forest_panel;
mod history;
mod inspector;
pub mod keys;
pub mod krs_panel;
mod menus;
mod new_model;
mod outliner;
pub mod overlay_lines;
mod palette;
mod path_prompt;
mod perf;
pub mod pose;
pub mod projector;
pub mod rig_panel;
pub mod rig_setup;
pub mod sculpt;
mod shortcuts;
pub mod tradeoff;
pub mod view;
pub mod vox_export;
mod voxel_menus;
pub mod voxel_tools;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use thicket_core::quality::QualityPreset;
use thicket_core::scene::Document;

use crate::editor::autosave::{self, AutosaveTimer, Recovery};
use crate::editor::jobs::{EnhanceNotApplied, Enhanced, Job, JobResult, Poll, Worker};
use crate::editor::{Editor, Selection};
use crate::files::{self, FileKind, thousands};
use path_prompt::{PathPrompt, PathPurpose};

/// A short-lived notice in the corner.
#[derive(Debug, Clone)]
struct Toast {
    text: String,
    is_error: bool,
    until_secs: f64,
}

/// An action waiting for the unsaved-changes prompt.
#[derive(Debug, Clone, PartialEq)]
enum Pending {
    New,
    Open(PathBuf),
    Quit,
}

pub use crate::editor::jobs::{IMPORT_KEEPS_VIEW, ImportReport};
pub use keys::{Act, BINDINGS, Binding, GESTURES, keys_text};

/// A native dialog running on its own thread.
struct NativeDialog {
    purpose: PathPurpose,
    result: Worker<Option<PathBuf>>,
}

/// The editor window's state: the [`Editor`] plus everything only the UI needs.
pub struct EditorApp {
    /// The document state and its commands.
    pub editor: Editor,
    toasts: Vec<Toast>,
    /// The last import, while its fit-to-scene scale can still be reset from the status bar.
    import_offer: Option<crate::editor::ImportPlacement>,
    /// An error shown in a dialog until dismissed (for example a file that would not open).
    pub error_dialog: Option<String>,
    /// The most memory one background job may need (`MemoryBudget::for_this_machine`: the
    /// smallest of half of physical memory and the process's address-space and cgroup limits;
    /// an enhancement estimated over it is refused before it starts).
    pub memory_budget: thicket_core::budget::MemoryBudget,
    /// What the last import left out, shown in the Import report window until closed
    /// (`None`: nothing was left out).
    pub import_report: Option<ImportReport>,
    prompt: Option<PathPrompt>,
    pending: Option<Pending>,
    allow_close: bool,
    job: Option<Job>,
    dialog: Option<NativeDialog>,
    /// Use the desktop's file dialogs (xdg portal or zenity) when there are any.
    pub native_dialogs: bool,
    /// Autosave interval in seconds (0: off).
    pub autosave_secs: u32,
    /// Where recovery files go.
    pub recovery_dir: PathBuf,
    autosave: AutosaveTimer,
    /// A recovery file found at start-up, offered until recovered or discarded.
    pub recovery: Option<Recovery>,
    show_shortcuts: bool,
    /// A flip or turn of the selected voxels that would push some outside the canvas, waiting
    /// for the artist's choice (grow, clip or cancel): the transform, what it is called and
    /// how many voxels.
    pending_transform: Option<(
        thicket_core::sculpt::select::SelTransform,
        &'static str,
        usize,
    )>,
    /// Whether the Edit → History window is open.
    pub show_history: bool,
    /// The shortcut sheet's search text.
    shortcut_search: String,
    show_about: bool,
    show_outliner: bool,
    show_inspector: bool,
    outliner: outliner::OutlinerState,
    inspector: inspector::InspectorState,
    /// The 3D view.
    pub view: view::View,
    /// The sculpt tool and its brush.
    pub sculpt: sculpt::SculptTool,
    /// The pose tool (joint selection, gizmo, timeline).
    pub pose: pose::PoseTool,
    /// The KRS editor's state.
    pub krs: krs_panel::KrsPanel,
    perf: perf::PerfOverlay,
    /// File → Export glTF's window and settings.
    pub gltf_export: export_gltf::GltfExportPanel,
    /// The Trade-off panel (View menu).
    pub tradeoff: tradeoff::TradeoffPanel,
    /// Last status-bar message.
    status: String,
    /// The New voxel model dialog.
    pub new_model: new_model::NewModelDialog,
    /// The Palette panel.
    pub palette: palette::PalettePanel,
    canvas: voxel_menus::CanvasForm,
    /// Model → Voxelize mesh's fields.
    pub voxelize: voxel_menus::VoxelizeForm,
    /// File → Export .vox's offer to voxelize the meshes it would leave out, and its queue.
    pub vox_export: vox_export::VoxExportFlow,
}

impl Default for EditorApp {
    fn default() -> Self {
        Self::new(Editor::default())
    }
}

impl EditorApp {
    /// An app around an editor.
    #[must_use]
    pub fn new(editor: Editor) -> Self {
        Self {
            editor,
            toasts: Vec::new(),
            import_offer: None,
            error_dialog: None,
            memory_budget: thicket_core::budget::MemoryBudget::for_this_machine(),
            import_report: None,
            prompt: None,
            pending: None,
            allow_close: false,
            job: None,
            dialog: None,
            native_dialogs: true,
            autosave_secs: autosave::DEFAULT_AUTOSAVE_SECS,
            recovery_dir: autosave::recovery_dir(),
            autosave: AutosaveTimer::default(),
            recovery: None,
            show_shortcuts: false,
            pending_transform: None,
            show_history: false,
            shortcut_search: String::new(),
            show_about: false,
            show_outliner: true,
            show_inspector: true,
            outliner: outliner::OutlinerState::default(),
            inspector: inspector::InspectorState::default(),
            view: view::View::default(),
            sculpt: sculpt::SculptTool::default(),
            pose: pose::PoseTool::default(),
            krs: krs_panel::KrsPanel::default(),
            perf: perf::PerfOverlay::default(),
            gltf_export: export_gltf::GltfExportPanel::default(),
            tradeoff: tradeoff::TradeoffPanel::default(),
            status: String::from("Ready"),
            new_model: new_model::NewModelDialog::default(),
            palette: palette::PalettePanel::default(),
            canvas: voxel_menus::CanvasForm::default(),
            voxelize: voxel_menus::VoxelizeForm::default(),
            vox_export: vox_export::VoxExportFlow::default(),
        }
    }

    /// Opens `path` (or the first sample project when `None`), or an empty document if that
    /// fails; a failure is shown in the error dialog.
    #[must_use]
    pub fn open_startup(path: Option<PathBuf>) -> Self {
        let mut app = Self::default();
        let Some(path) = path.or_else(files::default_project) else {
            app.status = "No project given and no sample in projects/: empty document".into();
            return app;
        };
        match files::load_document(&path) {
            // Before the first frame: the enhancers are built here rather than by a dab.
            Ok(doc) => app.install_document(crate::editor::PreparedDocument::new(doc, None), &path),
            Err(e) => app.error_dialog = Some(crate::cli::error_line(&e)),
        }
        app
    }

    fn install_document(&mut self, doc: crate::editor::PreparedDocument, path: &Path) {
        // Only projects are saved back to where they came from; a model opened directly becomes
        // an untitled project so Save cannot overwrite the .glb / .vox.
        let project_path =
            (FileKind::from_path(path) == Some(FileKind::Project)).then(|| path.to_path_buf());
        self.editor.replace_document_prepared(doc, project_path);
        self.import_offer = None;
        self.editor.push_recent(path.to_path_buf());
        self.status = format!("Opened {}", path.display());
    }

    /// Edit → Drop to surface: moves the selected object down onto what is below it and says
    /// how far, or why not.
    fn drop_selected(&mut self, ctx: &egui::Context) {
        let Some(Selection::Object(id)) = self.editor.selection else {
            self.toast(
                ctx,
                "Select an object to drop onto the surface below it",
                true,
            );
            return;
        };
        let name = |ed: &Editor, id| ed.object(id).map(|o| o.name.clone()).unwrap_or_default();
        match self.editor.drop_to_surface(id) {
            Ok(landing) => {
                let text = format!(
                    "Dropped {} by {:.3} onto {}",
                    name(&self.editor, id),
                    landing.distance,
                    name(&self.editor, landing.onto)
                );
                self.toast(ctx, text, false);
            }
            Err(e) => self.toast(ctx, format!("Not dropped: {e}"), true),
        }
    }

    fn toast(&mut self, ctx: &egui::Context, text: impl Into<String>, is_error: bool) {
        let text = text.into();
        if is_error {
            log::warn!("{text}");
        }
        self.status.clone_from(&text);
        let now = ctx.input(|i| i.time);
        self.toasts.push(Toast {
            text,
            is_error,
            until_secs: now + if is_error { 8.0 } else { 3.0 },
        });
    }

    // ---------------------------------------------------------------- file commands

    /// File → New (asks about unsaved changes first).
    pub fn request_new(&mut self) {
        if self.editor.is_dirty() {
            self.pending = Some(Pending::New);
        } else {
            self.do_new();
        }
    }

    fn do_new(&mut self) {
        self.editor.replace_document(Document::default(), None);
        self.import_offer = None;
        self.status = "New project".into();
        // A new project starts with its first voxel model (Cancel leaves it empty).
        self.new_model.show(&self.editor);
    }

    /// File → Open a path (asks about unsaved changes first). Loads on a worker thread.
    pub fn request_open(&mut self, path: PathBuf) {
        if self.editor.is_dirty() {
            self.pending = Some(Pending::Open(path));
        } else {
            self.start_open(path);
        }
    }

    fn start_open(&mut self, path: PathBuf) {
        self.job = Some(Job::open(path));
    }

    /// File → Import: adds the objects of any supported file to the document. A glTF file
    /// with a skin becomes a rigged voxel model (voxelized in its bind pose, with its skeleton
    /// and clips, ready to pose); other files load as `thicket open` reads them.
    pub fn start_import(&mut self, path: PathBuf) {
        self.start_import_with(path, files::MeshOptions::default());
    }

    /// [`Self::start_import`] with mesh options (an OBJ's texture).
    pub fn start_import_with(&mut self, path: PathBuf, options: files::MeshOptions) {
        self.job = Some(Job::import(path, options));
    }

    /// Edit → Enhance detail: enhances the selected voxel model (paper 001) by `factor` with
    /// its stored settings (the defaults for a model not enhanced yet).
    pub fn start_enhance(&mut self, factor: u32) {
        let Some(o) = self.editor.selected_object() else {
            self.status = "Select a voxel model to enhance".into();
            return;
        };
        // The enhancement itself is selected: enhance its source.
        let id = self
            .editor
            .doc()
            .enhancement_into(o.id)
            .map_or(o.id, |l| l.source);
        let mut settings = self
            .editor
            .doc()
            .enhancement_of(id)
            .map(|l| l.settings.clone())
            .unwrap_or_default();
        settings.factor = factor;
        self.start_enhance_with(id, settings);
    }

    /// Enhances voxel model `source` with `settings` on a worker thread, with progress and
    /// Cancel. The result is linked to the model (a new object, the model hidden), or replaces
    /// its linked enhancement; strokes then keep it up to date.
    pub fn start_enhance_with(
        &mut self,
        source: u64,
        settings: thicket_core::enhance::EnhanceSettings,
    ) {
        let Some(o) = self.editor.object(source) else {
            self.status = "Select a voxel model to enhance".into();
            return;
        };
        let thicket_core::scene::ObjectKind::Voxels(v) = &o.kind else {
            self.status = format!("{:?} is not a voxel model", o.name);
            return;
        };
        // Refused before the job starts when the estimate is over the memory budget.
        if let Ok(e) = thicket_core::enhance::estimate(&v.svo, &settings)
            && let Err(over) = self.memory_budget.check(
                &format!(
                    "Enhancing {:?} x{} into about {} voxels",
                    o.name,
                    settings.factor,
                    thousands(e.fine_voxels)
                ),
                e.peak_bytes,
                "use a smaller factor",
            )
        {
            self.error_dialog = Some(over.to_string());
            return;
        }
        let (name, model) = (o.name.clone(), v.clone());
        self.job = Some(Job::enhance(source, name, model, settings));
    }

    /// Binds voxel model `id` to its skeleton with `method` on a worker thread, with progress
    /// and Cancel; the result is one undo step.
    pub fn start_bind(&mut self, id: u64, method: thicket_core::skin::BindMethod) {
        let Some(o) = self.editor.object(id) else {
            return;
        };
        let thicket_core::scene::ObjectKind::Voxels(v) = &o.kind else {
            self.status = format!("{:?} is not a voxel model", o.name);
            return;
        };
        if v.rig.is_none() {
            self.pose.rig.error = Some("add joints (or a template) before binding".into());
            return;
        }
        let (name, model) = (o.name.clone(), v.clone());
        self.job = Some(Job::bind(id, &name, model, method));
    }

    /// File → Export .vox: the visible voxel models, on a worker thread.
    pub fn start_export_vox(&mut self, path: PathBuf) {
        let objects = self.editor.doc().objects.clone();
        self.job = Some(Job::export_vox(objects, path));
    }

    /// File → Export glTF: the document with the export window's settings, on a worker thread
    /// with progress and Cancel (the same code as `thicket export`).
    pub fn start_export_gltf(&mut self, path: PathBuf) {
        let doc = self.editor.doc().clone();
        let selected = self.editor.selected_object().map(|o| o.name.clone());
        let mut options = self.gltf_export.options_for(selected.as_deref());
        // The memory budget bounds the triangles as `thicket export` does, before meshing.
        match thicket_core::io::gltf_export::triangle_limit_for_memory(
            &doc,
            &options,
            self.memory_budget.limit_bytes,
        ) {
            Some(limit) => options.max_triangles = limit,
            None => {
                self.error_dialog = Some(format!(
                    "Exporting the voxel models would need more memory than the limit of {} ({})",
                    thicket_core::budget::human(self.memory_budget.limit_bytes),
                    self.memory_budget.source
                ));
                return;
            }
        }
        self.job = Some(Job::export_gltf(doc, path, options));
    }

    /// View → Trade-off → Run sweep: the panel's sweep of the current view on a worker thread,
    /// with progress and Cancel.
    pub fn start_tradeoff_sweep(&mut self) {
        let job = self.tradeoff.job(&self.editor, self.view.render_size_px());
        self.spawn_sweep(job);
    }

    fn spawn_sweep(&mut self, job: tradeoff::SweepJob) {
        let label = format!("Trade-off sweep at {} x {} px", job.width, job.height);
        // Refused before the job starts when the estimate is over the memory budget; a sweep
        // the core would refuse for its settings starts and reports that error as before.
        if let Ok(bytes) = thicket_core::measure::estimate_sweep_peak_bytes(
            &job.doc,
            job.width,
            job.height,
            &job.settings,
        ) && let Err(over) = self
            .memory_budget
            .check(&label, bytes, "use a smaller sweep size")
        {
            self.error_dialog = Some(over.to_string());
            return;
        }
        self.job = Some(Job::sweep(label, job));
    }

    /// Cancels the running job: its result is dropped and the document stays as it is; jobs
    /// that check the flag (enhancement) stop early.
    pub fn cancel_job(&mut self, ctx: &egui::Context) {
        if let Some(job) = self.job.take() {
            job.cancel();
            self.toast(ctx, format!("Cancelled: {}", job.label), false);
        }
        // A cancelled voxelize cancels the rest of File → Export .vox's queue too.
        self.stop_export_voxelizing();
    }

    /// Whether a background job is running.
    #[must_use]
    pub fn job_running(&self) -> bool {
        self.job.is_some()
    }

    /// Waits for the running job (tests; the UI polls instead).
    pub fn wait_for_job(&mut self, ctx: &egui::Context) {
        if let Some(job) = self.job.take()
            && let Some(result) = job.wait()
        {
            self.finish_job(ctx, result);
        }
    }

    fn poll_job(&mut self, ctx: &egui::Context) {
        let Some(job) = &self.job else { return };
        match job.poll() {
            Poll::Ready(result) => {
                self.job = None;
                self.finish_job(ctx, result);
            }
            Poll::Running => {
                ctx.request_repaint_after(Duration::from_millis(50));
            }
            Poll::Lost => {
                self.job = None;
                self.toast(ctx, "The background job stopped unexpectedly", true);
            }
        }
    }

    fn finish_job(&mut self, ctx: &egui::Context, result: JobResult) {
        match result {
            JobResult::Opened(path, Ok(doc)) => self.install_document(doc, &path),
            JobResult::Imported(path, Ok(imported)) => {
                let from = path.display().to_string();
                let done = self.editor.finish_import(path, imported);
                let placed = done.placement;
                let n = placed.ids.len();
                let scaled = if placed.scale == 1.0 {
                    String::new()
                } else {
                    format!(
                        "; scaled ×{} to the scene (Reset scale in the status bar)",
                        short_number(placed.scale)
                    )
                };
                self.toast(
                    ctx,
                    format!(
                        "Imported {n} object(s) from {from}, placed beside the scene and framed{scaled}"
                    ),
                    false,
                );
                self.import_offer = (placed.scale != 1.0).then_some(placed);
                self.import_report = done.report;
            }
            JobResult::Enhanced(job) => self.finish_enhance(ctx, *job),
            JobResult::Bound(job) => {
                let crate::editor::jobs::Bound { id, source, result } = *job;
                match result.and_then(|bound| self.editor.finish_bind(id, &source, bound)) {
                    Ok(report) => {
                        let text = format!(
                            "Bound {} voxels ({}){}",
                            crate::files::thousands(report.voxels),
                            report.method.name(),
                            crate::cli::rig::bind_notes(&report)
                        );
                        self.pose.rig_report = Some(text.clone());
                        self.toast(ctx, text, false);
                    }
                    Err(e) => self.error_dialog = Some(format!("Binding: {e}")),
                }
            }
            JobResult::MeshVoxelized(job) => {
                let crate::editor::jobs::MeshVoxelized { id, source, result } = *job;
                let placed = result
                    .map_err(|e| format!("{e:#}"))
                    .and_then(|(model, note)| {
                        let voxels = model.svo.leaf_count();
                        self.editor
                            .finish_voxelize(id, &source, model)
                            .map(|_| (voxels, note))
                            .map_err(|e| e.to_string())
                    });
                match placed {
                    Ok((voxels, note)) => {
                        let text = format!(
                            "Voxelized into {} voxels{}",
                            files::thousands(voxels),
                            if note.is_empty() {
                                String::new()
                            } else {
                                format!(" ({note})")
                            }
                        );
                        self.toast(ctx, text, !note.is_empty());
                    }
                    Err(e) => {
                        self.stop_export_voxelizing();
                        self.error_dialog = Some(format!("Voxelize mesh: {e}"));
                    }
                }
                // File → Export .vox's queue: the next mesh, or the file prompt.
                self.voxelize_next_for_export();
            }
            JobResult::Exported(Ok(text)) => self.toast(ctx, text, false),
            JobResult::Swept(revision, Ok(report)) => {
                let n = report.points.len();
                self.tradeoff.set_report(report, revision);
                self.toast(
                    ctx,
                    format!("Trade-off sweep: {n} settings measured"),
                    false,
                );
            }
            JobResult::Swept(_, Err(e)) => self.error_dialog = Some(crate::cli::error_line(&e)),
            JobResult::Exported(Err(e)) => {
                self.error_dialog = Some(crate::cli::error_line(&e));
            }
            JobResult::Opened(_, Err(e)) | JobResult::Imported(_, Err(e)) => {
                // The current document is untouched.
                self.error_dialog = Some(crate::cli::error_line(&e));
                self.status = "Could not open the file; the current document is unchanged".into();
            }
        }
    }

    fn finish_enhance(&mut self, ctx: &egui::Context, job: Enhanced) {
        match self.editor.finish_enhancement(job) {
            Ok((name, voxels)) => self.toast(
                ctx,
                format!("Enhanced {name}: {} voxels", thousands(voxels)),
                false,
            ),
            Err(EnhanceNotApplied::Failed(e)) => {
                self.error_dialog = Some(crate::cli::error_line(&e));
            }
            Err(EnhanceNotApplied::Removed(name)) => {
                self.toast(ctx, format!("{name} was removed while enhancing"), true);
            }
            Err(EnhanceNotApplied::Changed(name)) => self.toast(
                ctx,
                format!("{name} changed while enhancing: enhance it again"),
                true,
            ),
            Err(EnhanceNotApplied::Refused(e)) => self.error_dialog = Some(e.to_string()),
        }
    }

    /// File → Save: to the current path, or asks for one. Returns whether it saved.
    pub fn save(&mut self, ctx: &egui::Context) -> bool {
        match self.editor.path().map(Path::to_path_buf) {
            Some(path) => self.save_to(ctx, path),
            None => {
                self.prompt = Some(PathPrompt::new(
                    PathPurpose::SaveAs,
                    "untitled.thicket.json".into(),
                ));
                false
            }
        }
    }

    /// Saves to `path` (a `.thicket.json` name is enforced). Returns whether it saved.
    pub fn save_to(&mut self, ctx: &egui::Context, path: PathBuf) -> bool {
        let path = with_project_extension(path);
        match files::save_project(self.editor.doc(), &path) {
            Ok(()) => {
                self.editor.mark_saved(path.clone());
                // The user's file now holds the work: the recovery file is stale.
                if !self.autosave.is_writing() {
                    autosave::discard_recovery(&self.recovery_dir);
                }
                self.toast(ctx, format!("Saved {}", path.display()), false);
                true
            }
            Err(e) => {
                self.error_dialog = Some(crate::cli::error_line(&e));
                false
            }
        }
    }

    fn resolve_pending(&mut self, ctx: &egui::Context, pending: Pending) {
        match pending {
            Pending::New => self.do_new(),
            Pending::Open(path) => self.start_open(path),
            Pending::Quit => {
                self.allow_close = true;
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
    }

    fn ask_path(&mut self, purpose: PathPurpose) {
        if self.native_dialogs && self.dialog.is_none() && native_dialogs_available() {
            self.open_native_dialog(purpose);
            return;
        }
        let text = match purpose {
            PathPurpose::SaveAs => self.editor.path().map_or_else(
                || "untitled.thicket.json".into(),
                |p| p.display().to_string(),
            ),
            PathPurpose::ExportVox => self.export_path("vox").display().to_string(),
            PathPurpose::ExportGltf => self.export_path("glb").display().to_string(),
            PathPurpose::SavePalette => "palette.gpl".into(),
            // Open, import, load: the browse list starts in the project's folder.
            _ => self
                .editor
                .path()
                .and_then(Path::parent)
                .filter(|d| !d.as_os_str().is_empty())
                .map_or_else(String::new, |d| format!("{}/", d.display())),
        };
        self.prompt = Some(PathPrompt::new(purpose, text));
    }

    /// Where an export goes unless the user says otherwise: the project's name with the
    /// export's extension, beside the project (`/p/house.thicket.json` → `/p/house.vox`);
    /// `untitled.vox` before the project has a file.
    fn export_path(&self, extension: &str) -> PathBuf {
        let project = self.editor.path();
        let stem = project.map_or_else(|| "untitled".to_owned(), files::object_name_for);
        let name = format!("{stem}.{extension}");
        match project.and_then(Path::parent) {
            Some(dir) if !dir.as_os_str().is_empty() => dir.join(name),
            _ => PathBuf::from(name),
        }
    }

    /// A desktop file dialog on its own thread (it blocks until the user answers).
    fn open_native_dialog(&mut self, purpose: PathPurpose) {
        let start_dir = self
            .editor
            .path()
            .and_then(Path::parent)
            .map(Path::to_path_buf);
        let file_name = |extension: &str| {
            let path = self.export_path(extension);
            path.file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        };
        let (vox_name, glb_name) = (file_name("vox"), file_name("glb"));
        let result = Worker::spawn(move || {
            let mut d = rfd::FileDialog::new().set_title(purpose.title());
            if let Some(dir) = start_dir {
                d = d.set_directory(dir);
            }
            match purpose {
                PathPurpose::Open | PathPurpose::Import => {
                    for (label, exts) in files::readable_extensions() {
                        d = d.add_filter(label, exts);
                    }
                    d.pick_file()
                }
                PathPurpose::SaveAs => d
                    .add_filter("Thicket project", &["json"])
                    .set_file_name("untitled.thicket.json")
                    .save_file(),
                PathPurpose::ExportVox => d
                    .add_filter("MagicaVoxel", &["vox"])
                    .set_file_name(vox_name)
                    .save_file(),
                PathPurpose::ExportGltf => d
                    .add_filter("glTF", &["glb", "gltf"])
                    .set_file_name(glb_name)
                    .save_file(),
                PathPurpose::LoadPalette => {
                    d.add_filter("Palette", &["gpl", "png", "vox"]).pick_file()
                }
                PathPurpose::SavePalette => d
                    .add_filter("Palette", &["gpl", "png"])
                    .set_file_name("palette.gpl")
                    .save_file(),
            }
        });
        self.dialog = Some(NativeDialog { purpose, result });
    }

    fn poll_dialog(&mut self, ctx: &egui::Context) {
        let Some(d) = &self.dialog else { return };
        match d.result.poll() {
            Poll::Ready(Some(path)) => {
                let purpose = d.purpose;
                self.dialog = None;
                self.accept_path(ctx, purpose, path);
            }
            Poll::Ready(None) | Poll::Lost => self.dialog = None,
            Poll::Running => ctx.request_repaint_after(Duration::from_millis(100)),
        }
    }

    /// Autosaves to the recovery folder when the interval has passed and the document changed
    /// since the last autosave; the write runs on a worker thread.
    fn autosave_tick(&mut self, ctx: &egui::Context) {
        let tick = self.autosave.tick(
            &self.editor,
            self.autosave_secs,
            &self.recovery_dir,
            Instant::now(),
        );
        match tick.finished {
            Some(Ok(())) => self.status = "Autosaved to the recovery file".into(),
            Some(Err(e)) => self.toast(
                ctx,
                format!("Autosave failed: {}", crate::cli::error_line(&e)),
                true,
            ),
            None => {}
        }
        if let Some(wait) = tick.wake_after {
            ctx.request_repaint_after(wait);
        }
    }

    /// Starts an autosave now (also used by tests). The document is copied for the worker.
    pub fn autosave_now(&mut self) {
        self.autosave.start(&self.editor, &self.recovery_dir);
    }

    /// Waits for a running autosave (tests).
    pub fn wait_for_autosave(&mut self) -> Option<anyhow::Result<()>> {
        self.autosave.wait()
    }

    /// Looks for a recovery file from an earlier session (offered in a dialog).
    pub fn check_recovery(&mut self) {
        self.recovery = autosave::find_recovery(&self.recovery_dir);
    }

    /// Opens the recovery file as the document (unsaved, under its original path).
    pub fn recover(&mut self) {
        let Some(r) = self.recovery.take() else {
            return;
        };
        match files::load_document(&r.path) {
            Ok(doc) => {
                // Linked models' enhancers are built with the load (as Open does), so the first
                // dab on the recovered work updates incrementally.
                let prepared = crate::editor::PreparedDocument::new(doc, None);
                self.editor
                    .replace_document_prepared(prepared, r.meta.original.clone());
                self.editor.mark_modified();
                self.status = "Recovered the autosaved work: save it to keep it".into();
            }
            Err(e) => {
                self.error_dialog = Some(format!(
                    "The recovery file could not be read: {}",
                    crate::cli::error_line(&e)
                ));
            }
        }
    }

    /// Deletes the recovery file.
    pub fn discard_recovery(&mut self) {
        self.recovery = None;
        autosave::discard_recovery(&self.recovery_dir);
    }

    fn accept_path(&mut self, ctx: &egui::Context, purpose: PathPurpose, path: PathBuf) {
        match purpose {
            PathPurpose::Open => self.request_open(path),
            PathPurpose::Import => self.start_import(path),
            PathPurpose::SaveAs => {
                self.save_to(ctx, path);
            }
            PathPurpose::ExportVox => self.start_export_vox(path),
            PathPurpose::ExportGltf => self.start_export_gltf(path),
            PathPurpose::LoadPalette => self.load_palette(ctx, &path),
            PathPurpose::SavePalette => self.save_palette(ctx, &path),
        }
    }

    fn load_palette(&mut self, ctx: &egui::Context, path: &Path) {
        let Some(id) = self.editor.selected_voxel_model() else {
            self.toast(ctx, "select a voxel model to load a palette into", true);
            return;
        };
        match thicket_core::sculpt::palette::load_palette(path) {
            Ok(colors) => {
                let n = colors.len();
                match self.editor.set_palette(id, colors) {
                    Ok(()) => self.toast(
                        ctx,
                        format!("Loaded {n} colours from {}", path.display()),
                        false,
                    ),
                    Err(e) => self.toast(ctx, e.to_string(), true),
                }
            }
            Err(e) => self.toast(ctx, e.to_string(), true),
        }
    }

    fn save_palette(&mut self, ctx: &egui::Context, path: &Path) {
        let colors = match self.editor.selected_object().map(|o| &o.kind) {
            Some(thicket_core::scene::ObjectKind::Voxels(v)) => v.palette.clone(),
            _ => Vec::new(),
        };
        match thicket_core::sculpt::palette::save_palette(path, &colors) {
            Ok(()) => self.toast(
                ctx,
                format!("Saved {} colours to {}", colors.len(), path.display()),
                false,
            ),
            Err(e) => self.toast(ctx, e.to_string(), true),
        }
    }

    // ---------------------------------------------------------------- frame

    /// Draws the whole editor into `ui` (the root of the window, or a test harness).
    pub fn ui_root(&mut self, ui: &mut egui::Ui) {
        let started = std::time::Instant::now();
        let ctx = ui.ctx().clone();
        self.poll_job(&ctx);
        self.poll_dialog(&ctx);
        self.autosave_tick(&ctx);
        self.handle_dropped_files(&ctx);
        self.voxel_shortcuts(&ctx);
        self.handle_shortcuts(&ctx);
        self.handle_close_request(&ctx);

        egui::Panel::top("menu_bar").show(ui, |ui| self.menu_bar(ui));
        egui::Panel::top("tool_bar").show(ui, |ui| self.sculpt.toolbar_ui(ui, &self.editor));
        egui::Panel::bottom("status_bar").show(ui, |ui| self.status_bar(ui));
        if let Some(id) = pose::timeline_target(&self.editor) {
            egui::Panel::bottom("timeline").show(ui, |ui| {
                pose::timeline_ui(ui, &mut self.editor, &mut self.pose, id);
            });
        } else {
            self.pose.playing = false;
        }
        if self.show_outliner {
            egui::Panel::left("outliner")
                .resizable(true)
                .default_size(260.0)
                .show(ui, |ui| {
                    outliner::outliner_ui(
                        ui,
                        &mut self.editor,
                        &mut self.outliner,
                        &mut self.status,
                    );
                });
        }
        // Set again by the inspector's KRS editor when it is shown this frame.
        self.krs.editor_open = false;
        if self.show_inspector {
            egui::Panel::right("inspector")
                .resizable(true)
                .default_size(320.0)
                .show(ui, |ui| {
                    inspector::inspector_ui(
                        ui,
                        &mut self.editor,
                        &mut self.inspector,
                        &mut self.pose,
                        &mut self.krs,
                    );
                });
            if let Some((id, settings)) = self.inspector.enhance.request.take() {
                self.start_enhance_with(id, settings);
            }
            if let Some((id, method)) = self.pose.rig.bind_request.take() {
                self.start_bind(id, method);
            }
        }
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| {
                self.view.ui(
                    ui,
                    &mut self.editor,
                    &mut self.sculpt,
                    &mut self.pose,
                    &mut self.krs,
                );
            });

        self.dialogs(&ctx);
        self.history_window(&ctx);
        if self.new_model.ui(&ctx, &mut self.editor).is_some() {
            self.sculpt.choose(voxel_tools::ToolKind::Voxel);
            self.status =
                "New voxel model: the Voxel and Box tools place voxels on its floor".into();
        }
        match self
            .palette
            .ui(&ctx, &mut self.editor, &mut self.sculpt.brush.color)
        {
            Some(palette::PaletteRequest::Load) => self.ask_path(PathPurpose::LoadPalette),
            Some(palette::PaletteRequest::Save) => self.ask_path(PathPurpose::SavePalette),
            None => {}
        }
        self.toasts_ui(&ctx);
        self.perf.ui(
            &ctx,
            &self.editor,
            self.view.gpu(),
            self.view
                .cpu_preview()
                .stats()
                .filter(|_| self.view.uses_cpu(&self.editor))
                .map(|(ms, size_px)| perf::CpuPreviewFigures {
                    ms,
                    size_px,
                    shadows: self.view.cpu_preview().shadows().unwrap_or_default(),
                    stats: self.view.cpu_preview().frame_stats(),
                    why: self.view.cpu_reason_text(&self.editor),
                }),
        );
        self.tradeoff_ui(&ctx);
        ctx.send_viewport_cmd(egui::ViewportCommand::Title(self.editor.title()));

        // A drag (slider, DragValue) is one undo step: the step closes when the pointer is up.
        if !ctx.input(|i| i.pointer.any_down()) {
            self.editor.end_interaction();
        }
        self.perf
            .record(started.elapsed().as_secs_f64() * 1e3, self.view.gpu());
    }

    fn tradeoff_ui(&mut self, ctx: &egui::Context) {
        let running = self.job.as_ref().filter(|j| j.sweep).map(Job::fraction);
        let action = self.tradeoff.ui(
            ctx,
            &self.editor,
            self.view.render_size_px(),
            running,
            self.job.is_some(),
        );
        match action {
            Some(tradeoff::PanelAction::Run(job)) => self.spawn_sweep(*job),
            Some(tradeoff::PanelAction::Cancel) => self.cancel_job(ctx),
            Some(tradeoff::PanelAction::Apply(quality, label)) => {
                // Its own undo step, never merged with a slider drag before or after.
                self.editor.end_interaction();
                match self.editor.set_quality(*quality) {
                    Ok(()) => self.toast(ctx, format!("Quality set to: {label}"), false),
                    Err(e) => self.toast(ctx, format!("Quality not changed: {e}"), true),
                }
                self.editor.end_interaction();
            }
            None => {}
        }
    }

    /// Connects the GPU viewport (see [`crate::preview::viewport::install`]).
    pub fn attach_gpu(&mut self, link: crate::preview::viewport::ViewportLink) {
        self.view.attach_gpu(link);
    }

    fn handle_dropped_files(&mut self, ctx: &egui::Context) {
        let dropped: Vec<PathBuf> = ctx.input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .collect()
        });
        for path in dropped {
            // A project replaces the document; a model is imported into it.
            if FileKind::from_path(&path) == Some(FileKind::Project) {
                self.request_open(path);
            } else {
                self.start_import(path);
            }
        }
    }

    fn handle_close_request(&mut self, ctx: &egui::Context) {
        if ctx.input(|i| i.viewport().close_requested())
            && self.editor.is_dirty()
            && !self.allow_close
        {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.pending = Some(Pending::Quit);
        }
    }

    // ---------------------------------------------------------------- panels

    fn status_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let mut cancel = false;
            if let Some(job) = &self.job {
                match job.fraction() {
                    Some(f) => {
                        ui.add(
                            egui::ProgressBar::new(f)
                                .desired_width(140.0)
                                .show_percentage(),
                        );
                    }
                    None => {
                        ui.spinner();
                    }
                }
                ui.label(&job.label);
                cancel = ui
                    .button("Cancel")
                    .on_hover_text("Stop the job; the document stays as it is")
                    .clicked();
                ui.separator();
            }
            if cancel {
                let ctx = ui.ctx().clone();
                self.cancel_job(&ctx);
            }
            let doc = self.editor.doc();
            let voxels: u64 = doc
                .objects
                .iter()
                .filter_map(|o| match &o.kind {
                    thicket_core::scene::ObjectKind::Voxels(v) => Some(v.svo.leaf_count()),
                    thicket_core::scene::ObjectKind::Mesh(_)
                    | thicket_core::scene::ObjectKind::Krs(_) => None,
                })
                .sum();
            let triangles: usize = doc
                .objects
                .iter()
                .filter_map(|o| match &o.kind {
                    thicket_core::scene::ObjectKind::Mesh(m) => Some(m.model.triangle_count()),
                    thicket_core::scene::ObjectKind::Voxels(_)
                    | thicket_core::scene::ObjectKind::Krs(_) => None,
                })
                .sum();
            let file = self
                .editor
                .path()
                .map_or_else(|| "untitled".to_owned(), |p| p.display().to_string());
            ui.label(file).on_hover_text("The project file");
            if self.editor.is_dirty() {
                ui.colored_label(ui.visuals().warn_fg_color, "* unsaved")
                    .on_hover_text("There are changes since the last save");
            }
            ui.separator();
            ui.label(format!(
                "{} objects · {} voxels · {} triangles",
                doc.objects.len(),
                thousands(voxels),
                thousands(triangles as u64)
            ));
            ui.separator();
            ui.label(format!(
                "undo {} / redo {}",
                self.editor.history().undo_len(),
                self.editor.history().redo_len()
            ))
            .on_hover_text("Steps in the undo and redo history");
            ui.separator();
            ui.label(self.sculpt.state_line())
                .on_hover_text("The active tool, its mode and mirror axes");
            if let Some(s) = self.editor.voxel_selection() {
                ui.separator();
                ui.colored_label(
                    egui::Color32::from_rgb(255, 200, 40),
                    format!("{} voxels selected", thousands(s.cells.len() as u64)),
                );
            }
            if let Some(offer) = self.import_offer.clone() {
                ui.separator();
                if ui
                    .button(format!("Reset scale (×{})", short_number(offer.scale)))
                    .on_hover_text(
                        "The last import was scaled to fit the scene; give it back its own size \
                         (undoable)",
                    )
                    .clicked()
                {
                    self.import_offer = None;
                    if let Err(e) = offer.reset_scale(&mut self.editor) {
                        let ctx = ui.ctx().clone();
                        self.toast(&ctx, format!("Reset scale: {e}"), true);
                    }
                }
            }
            ui.separator();
            ui.weak(&self.status);
        });
    }
}

const PRESETS: &[(&str, QualityPreset, &str)] = &[
    (
        "Draft",
        QualityPreset::Draft,
        "Fastest preview: coarse LOD, no AO, small shadow maps",
    ),
    ("Balanced", QualityPreset::Balanced, "The editor default"),
    (
        "Final",
        QualityPreset::Final,
        "Offline quality: fine LOD, soft shadows, more AO samples",
    ),
];

/// `foo` → `foo.thicket.json`; `foo.thicket.json` unchanged.
fn with_project_extension(path: PathBuf) -> PathBuf {
    if FileKind::from_path(&path) == Some(FileKind::Project) {
        path
    } else {
        let mut s = path.into_os_string();
        s.push(".thicket.json");
        PathBuf::from(s)
    }
}

impl eframe::App for EditorApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.ui_root(ui);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        eframe::set_value(storage, RECENT_KEY, &self.editor.recent);
        eframe::set_value(storage, AUTOSAVE_KEY, &self.autosave_secs);
        eframe::set_value(storage, NATIVE_DIALOGS_KEY, &self.native_dialogs);
    }

    fn on_exit(&mut self) {
        // A clean exit (saved, or the user chose not to save) leaves nothing to recover.
        if !self.editor.is_dirty() || self.allow_close {
            let _ = self.wait_for_autosave();
            autosave::discard_recovery(&self.recovery_dir);
        }
    }
}

const AUTOSAVE_KEY: &str = "thicket.autosave_secs";
const NATIVE_DIALOGS_KEY: &str = "thicket.native_dialogs";

/// Whether a desktop file dialog can appear: an xdg portal needs a D-Bus session; zenity is
/// rfd's own fallback. Without either, rfd would return "cancelled" at once.
fn native_dialogs_available() -> bool {
    let dbus = std::env::var_os("DBUS_SESSION_BUS_ADDRESS").is_some_and(|v| !v.is_empty());
    let zenity = std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|d| d.join("zenity").is_file()));
    dbus || zenity
}

const RECENT_KEY: &str = "thicket.recent_files";

/// Opens the editor window (blocks until it is closed).
///
/// # Errors
/// When no window can be created (no display, no GPU adapter).
pub fn run_editor(project: Option<PathBuf>) -> anyhow::Result<()> {
    let options = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        wgpu_options: egui_wgpu::WgpuConfiguration {
            wgpu_setup: crate::preview::viewport::wgpu_setup(),
            ..Default::default()
        },
        viewport: egui::ViewportBuilder::default()
            .with_title("Thicket")
            .with_inner_size([1280.0, 800.0])
            .with_min_inner_size([640.0, 400.0])
            .with_drag_and_drop(true),
        ..Default::default()
    };
    eframe::run_native(
        "Thicket",
        options,
        Box::new(move |cc| {
            cc.egui_ctx.set_theme(egui::Theme::Dark);
            let mut app = EditorApp::open_startup(project);
            if let Some(rs) = cc.wgpu_render_state.as_ref() {
                app.attach_gpu(crate::preview::viewport::install(rs));
            }
            if let Some(storage) = cc.storage
                && let Some(recent) = eframe::get_value::<Vec<PathBuf>>(storage, RECENT_KEY)
            {
                let current = std::mem::take(&mut app.editor.recent);
                app.editor.recent = recent;
                for p in current.into_iter().rev() {
                    app.editor.push_recent(p);
                }
            }
            if let Some(storage) = cc.storage {
                if let Some(secs) = eframe::get_value::<u32>(storage, AUTOSAVE_KEY) {
                    app.autosave_secs = secs;
                }
                if let Some(native) = eframe::get_value::<bool>(storage, NATIVE_DIALOGS_KEY) {
                    app.native_dialogs = native;
                }
            }
            app.check_recovery();
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the editor window: {e}"))
}

/// A scale factor with about four significant digits (`81.53`, `0.01227`).
fn short_number(v: f32) -> String {
    let digits = (3 - v.abs().log10().floor() as i32).clamp(0, 8) as usize;
    format!("{v:.digits$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An editor holding a small voxel slab linked to its 4x enhancement, and the slab's id.
    fn linked_slab() -> (Editor, u64) {
        use glam::{UVec3, Vec3};
        use thicket_core::scene::{ObjectKind, VoxelModel};
        let mut svo = thicket_core::svo::Svo::new(4, false).unwrap();
        for x in 1..14 {
            for z in 1..14 {
                for y in 0..3 + (x + z) % 3 {
                    let v = thicket_core::svo::Voxel::new([90, 140, 60, 255], Vec3::Y);
                    svo.set(UVec3::new(x, y, z), v).unwrap();
                }
            }
        }
        let model = VoxelModel {
            svo,
            ..VoxelModel::default()
        };
        let settings = thicket_core::enhance::EnhanceSettings {
            factor: 4,
            ..Default::default()
        };
        let (fine, _) = model
            .enhanced(&settings, thicket_core::enhance::Control::default())
            .unwrap();
        let mut ed = Editor::default();
        let id = ed.add_object("Slab", ObjectKind::Voxels(model));
        ed.add_enhancement(id, settings, fine, None).unwrap();
        (ed, id)
    }

    /// A dab on the slab: it must re-enhance incrementally, with no full enhancement.
    fn assert_first_dab_is_incremental(app: &mut EditorApp, id: u64) {
        let brush = thicket_core::sculpt::Brush::default();
        app.editor.begin_stroke();
        let changed = app
            .editor
            .sculpt_dab(id, &brush, glam::Vec3::new(6.5, 4.5, 6.5), glam::Vec3::ZERO)
            .unwrap();
        assert!(changed.is_some(), "the dab changed voxels");
        let update = app
            .editor
            .last_enhance_update()
            .expect("the dab re-enhanced");
        assert!(update.fine_changes > 0 && !update.rebuilt);
        assert_eq!(app.editor.enhancer_rebuilds(), 0);
    }

    /// Open (the job, as File -> Open runs it) builds a linked model's enhancer on the worker
    /// thread: the first dab after it updates incrementally, with no full enhancement on the
    /// UI thread.
    #[test]
    fn the_first_dab_after_open_does_not_rebuild_the_enhancer() {
        let (ed, id) = linked_slab();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("linked.thicket.json");
        files::save_project(ed.doc(), &path).unwrap();

        let ctx = egui::Context::default();
        let mut app = EditorApp::default();
        app.request_open(path);
        app.wait_for_job(&ctx);
        assert!(app.error_dialog.is_none(), "{:?}", app.error_dialog);
        assert_first_dab_is_incremental(&mut app, id);
    }

    /// Recovering autosaved work prepares the enhancers as Open does.
    #[test]
    fn the_first_dab_after_recovery_does_not_rebuild_the_enhancer() {
        let (ed, id) = linked_slab();
        let dir = tempfile::tempdir().unwrap();
        autosave::write_recovery(dir.path(), ed.doc(), None).unwrap();
        let mut app = EditorApp {
            recovery_dir: dir.path().to_path_buf(),
            ..EditorApp::default()
        };
        app.check_recovery();
        assert!(app.recovery.is_some(), "the recovery file is found");
        app.recover();
        assert!(app.error_dialog.is_none(), "{:?}", app.error_dialog);
        assert!(app.editor.is_dirty(), "recovered work is unsaved");
        assert_first_dab_is_incremental(&mut app, id);
    }

    #[test]
    fn project_extension_is_added_once() {
        assert_eq!(
            with_project_extension("a/b".into()),
            PathBuf::from("a/b.thicket.json")
        );
        assert_eq!(
            with_project_extension("a/b.thicket.json".into()),
            PathBuf::from("a/b.thicket.json")
        );
    }
}

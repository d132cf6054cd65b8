//! The editor's background work, without egui: a worker thread's pending result
//! ([`Worker`]), the one long job at a time with progress and Cancel ([`Job`]: open, import,
//! enhance, export, Trade-off sweep), what each job hands back ([`JobResult`]), and what the
//! editor does with a finished import or enhancement ([`Editor::finish_import`],
//! [`Editor::finish_enhancement`]). The UI starts jobs, polls them once a frame and turns the
//! outcomes into toasts and dialogs.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, mpsc};

use anyhow::Context as _;
use thicket_core::enhance::{Control, EnhanceSettings, Enhancer};
use thicket_core::io::GltfView;
use thicket_core::measure::{SweepReport, SweepSettings};
use thicket_core::scene::{Document, Object, ObjectKind, VoxelModel};
use thicket_core::svo::Svo;

use super::{CommandError, Editor, ImportPlacement};
use crate::files::{self, FileKind, thousands};

/// Where a worker's result is.
#[derive(Debug)]
pub enum Poll<T> {
    /// The worker finished with this.
    Ready(T),
    /// Still working.
    Running,
    /// The worker ended without a result (it panicked).
    Lost,
}

/// A result computed on its own thread, collected by polling (the UI never blocks on it).
#[derive(Debug)]
pub struct Worker<T> {
    rx: mpsc::Receiver<T>,
}

impl<T: Send + 'static> Worker<T> {
    /// Runs `work` on a new thread.
    pub fn spawn(work: impl FnOnce() -> T + Send + 'static) -> Self {
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            // The receiver is gone when the result is no longer wanted (a cancelled job).
            let _ = tx.send(work());
        });
        Self { rx }
    }

    /// The result when it is there, without waiting.
    pub fn poll(&self) -> Poll<T> {
        match self.rx.try_recv() {
            Ok(r) => Poll::Ready(r),
            Err(mpsc::TryRecvError::Empty) => Poll::Running,
            Err(mpsc::TryRecvError::Disconnected) => Poll::Lost,
        }
    }

    /// Waits for the result (tests and exit; `None` when the worker ended without one).
    pub fn wait(self) -> Option<T> {
        self.rx.recv().ok()
    }
}

/// What a .vox export left out, by name and why (" ; left out: …"), or nothing: a .vox holds
/// voxel models only, and only the visible ones are written.
#[must_use]
pub fn vox_left_out(objects: &[Object], skipped: &[String]) -> String {
    if skipped.is_empty() {
        return String::new();
    }
    let why: Vec<String> = skipped
        .iter()
        .map(|name| {
            let reason = match objects.iter().find(|o| &o.name == name) {
                Some(o) if !o.visible => "hidden",
                Some(o) => match &o.kind {
                    ObjectKind::Mesh(_) => {
                        "a mesh: .vox holds voxels only; Model > Voxelize mesh makes a voxel model of it"
                    }
                    ObjectKind::Krs(_) => "a KRS object: .vox holds voxels only",
                    ObjectKind::Voxels(_) => "empty",
                },
                None => "not exported",
            };
            format!("{name:?} ({reason})")
        })
        .collect();
    format!("; left out: {}", why.join(", "))
}

/// What a background job hands back.
pub enum JobResult {
    /// A project read on the worker thread, with its linked models' enhancers built there.
    Opened(PathBuf, anyhow::Result<super::PreparedDocument>),
    /// An imported file's document and what the import left out of it.
    Imported(PathBuf, anyhow::Result<Imported>),
    /// An enhancement of a voxel object.
    Enhanced(Box<Enhanced>),
    /// An export's one-line summary.
    Exported(anyhow::Result<String>),
    /// A Trade-off sweep of the editor at a revision.
    Swept(u64, anyhow::Result<SweepReport>),
    /// A binding of a voxel model to its skeleton.
    Bound(Box<Bound>),
    /// A mesh object voxelized (Model → Voxelize mesh).
    MeshVoxelized(Box<MeshVoxelized>),
}

/// What a Voxelize mesh job hands back: the mesh object, the mesh it voxelized (to check
/// nothing changed meanwhile) and the voxel model.
pub struct MeshVoxelized {
    /// The mesh object's id.
    pub id: u64,
    /// The mesh as it was when the job started.
    pub source: thicket_core::mesh::MeshModel,
    /// The voxel model, with the voxelizer's note on a solid fill that fell back to the
    /// surface (empty otherwise).
    pub result: anyhow::Result<(VoxelModel, String)>,
}

/// What a binding job hands back: the object, the model it bound (to check nothing changed
/// meanwhile) and the bound octree with its report.
pub struct Bound {
    /// The object id.
    pub id: u64,
    /// The model as it was when the job started.
    pub source: VoxelModel,
    /// The result.
    pub result: Result<
        (
            Svo,
            thicket_core::skin::BindReport,
            thicket_core::skin::BindMethod,
        ),
        CommandError,
    >,
}

/// What File → Import read, before it is placed in the document.
pub struct Imported {
    /// The file's objects.
    pub doc: Document,
    /// What the import left out (one line per kind).
    pub left_out: Vec<String>,
    /// The file's view: its lights are added, its camera is not applied.
    pub view: GltfView,
    /// For a static glTF scene, the names of its nodes with meshes (the report's checklist).
    pub node_names: Vec<String>,
    /// For a skinned glTF, the octree depth it was voxelized at.
    pub skinned_depth: Option<u8>,
}

/// What an enhancement job hands back: source id, source name, the settings, the coarse
/// octree it was made from, and the fine model with the enhancer that made it.
pub struct Enhanced {
    source: u64,
    name: String,
    settings: EnhanceSettings,
    coarse: Svo,
    result: anyhow::Result<(VoxelModel, Enhancer)>,
}

/// A sweep to run: a copy of the document (the user keeps editing meanwhile), the image size
/// and the settings.
#[derive(Debug, Clone)]
pub struct SweepJob {
    /// The document as it was when the sweep started, with its camera (the current view).
    pub doc: Document,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// What to render.
    pub settings: SweepSettings,
    /// The editor revision the sweep describes.
    pub revision: u64,
}

/// A background job: a worker thread, its progress and its cancel flag.
pub struct Job {
    /// What it is doing, for the status bar ("Importing foo.glb").
    pub label: String,
    worker: Worker<JobResult>,
    /// Fraction done as `f32` bits; NaN while the job cannot tell.
    progress: Arc<AtomicU32>,
    cancel: Arc<AtomicBool>,
    /// A Trade-off sweep (its panel shows the progress and a Cancel button too).
    pub sweep: bool,
}

impl Job {
    /// Runs `work` on a worker thread; it gets the progress and cancel handles.
    fn spawn(
        label: String,
        work: impl FnOnce(&AtomicU32, &AtomicBool) -> JobResult + Send + 'static,
    ) -> Self {
        let progress = Arc::new(AtomicU32::new(f32::NAN.to_bits()));
        let cancel = Arc::new(AtomicBool::new(false));
        let (p, c) = (Arc::clone(&progress), Arc::clone(&cancel));
        Self {
            label,
            worker: Worker::spawn(move || work(&p, &c)),
            progress,
            cancel,
            sweep: false,
        }
    }

    /// The fraction done, when the job can tell.
    #[must_use]
    pub fn fraction(&self) -> Option<f32> {
        let f = f32::from_bits(self.progress.load(Ordering::Relaxed));
        f.is_finite().then_some(f.clamp(0.0, 1.0))
    }

    /// Asks the job to stop (jobs that check the flag stop early; the result is dropped
    /// with the job).
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// The result when it is there.
    #[must_use]
    pub fn poll(&self) -> Poll<JobResult> {
        self.worker.poll()
    }

    /// Waits for the result.
    #[must_use]
    pub fn wait(self) -> Option<JobResult> {
        self.worker.wait()
    }

    /// Reads a project (or any supported file) as the new document.
    #[must_use]
    pub fn open(path: PathBuf) -> Self {
        let label = format!("Opening {}", path.display());
        Self::spawn(label, move |_, cancel| {
            // Linked models' enhancers are built here too, so the first dab after Open updates
            // incrementally instead of stalling the UI thread on a full enhancement.
            let result = files::load_document(&path)
                .map(|doc| super::PreparedDocument::new(doc, Some(cancel)));
            JobResult::Opened(path, result)
        })
    }

    /// Reads a file's objects to import (see [`import_document`]).
    #[must_use]
    pub fn import(path: PathBuf, options: files::MeshOptions) -> Self {
        let label = format!("Importing {}", path.display());
        Self::spawn(label, move |progress, cancel| {
            let result = import_document(&path, &options, progress, cancel);
            JobResult::Imported(path, result)
        })
    }

    /// Enhances `model` (object `source`, named `name`) with `settings`, with progress and
    /// Cancel.
    #[must_use]
    pub fn enhance(
        source: u64,
        name: String,
        model: VoxelModel,
        settings: EnhanceSettings,
    ) -> Self {
        let label = format!("Enhancing {name} x{}", settings.factor);
        Self::spawn(label, move |progress, cancel| {
            let report = |f: f32| progress.store(f.to_bits(), Ordering::Relaxed);
            let control = Control {
                progress: Some(&report),
                cancel: Some(cancel),
            };
            let result = Enhancer::with_control(&model.svo, &settings, control)
                .map(|e| (model.with_enhanced(e.fine().clone(), settings.factor), e))
                .map_err(anyhow::Error::from);
            JobResult::Enhanced(Box::new(Enhanced {
                source,
                name,
                settings,
                coarse: model.svo,
                result,
            }))
        })
    }

    /// Binds voxel model `model` (object `id`, named `name`) to its skeleton with `method`,
    /// with progress and Cancel; [`Editor::finish_bind`] applies the result.
    #[must_use]
    pub fn bind(
        id: u64,
        name: &str,
        model: VoxelModel,
        method: thicket_core::skin::BindMethod,
    ) -> Self {
        let label = format!("Binding {name} ({})", method.name());
        Self::spawn(label, move |progress, cancel| {
            let report = |f: f32| progress.store(f.to_bits(), Ordering::Relaxed);
            let control = thicket_core::skin::bind::BindControl {
                progress: Some(&report),
                cancel: Some(cancel),
            };
            let result = super::bind_job(&model, method, control);
            JobResult::Bound(Box::new(Bound {
                id,
                source: model,
                result,
            }))
        })
    }

    /// Voxelizes mesh `model` (object `id`, named `name`) with `settings`, as `thicket import`
    /// does, after checking the estimate against `budget`; progress and Cancel. [`Editor::finish_voxelize`] places the result.
    #[must_use]
    pub fn voxelize_mesh(
        id: u64,
        name: &str,
        model: thicket_core::mesh::MeshModel,
        settings: thicket_core::voxelize::VoxelizeSettings,
        budget: thicket_core::budget::MemoryBudget,
    ) -> Self {
        let label = format!("Voxelizing {name}");
        let name = name.to_owned();
        Self::spawn(label, move |progress, cancel| {
            let result = voxelize_mesh(&name, &model, &settings, budget, progress, cancel);
            JobResult::MeshVoxelized(Box::new(MeshVoxelized {
                id,
                source: model,
                result,
            }))
        })
    }

    /// Writes the visible voxel models of `objects` to a `.vox` file.
    #[must_use]
    pub fn export_vox(objects: Vec<Object>, path: PathBuf) -> Self {
        let label = format!("Exporting {}", path.display());
        Self::spawn(label, move |_, _| {
            let result = thicket_core::io::vox::export_vox(&objects, &path)
                .map(|r| {
                    let mut text = format!(
                        "Exported {} voxels in {} model(s) to {}",
                        thousands(r.voxels),
                        r.models,
                        path.display()
                    );
                    text.push_str(&vox_left_out(&objects, &r.skipped));
                    text
                })
                .map_err(anyhow::Error::from);
            JobResult::Exported(result)
        })
    }

    /// Writes `doc` as glTF with `options`, with progress and Cancel (the same code as
    /// `thicket export`).
    #[must_use]
    pub fn export_gltf(
        doc: Document,
        path: PathBuf,
        options: thicket_core::io::gltf_export::GltfExportOptions,
    ) -> Self {
        let label = format!("Exporting {}", path.display());
        Self::spawn(label, move |progress, cancel| {
            let report = |f: f32| {
                progress.store(f.to_bits(), Ordering::Relaxed);
                !cancel.load(Ordering::Relaxed)
            };
            let result = thicket_core::io::gltf_export::export_gltf(&doc, &path, &options, &report)
                .map(|r| {
                    format!(
                        "Exported {} object(s), {} triangles, to {}",
                        r.objects,
                        thousands(r.triangles),
                        path.display()
                    )
                })
                .map_err(anyhow::Error::from);
            JobResult::Exported(result)
        })
    }

    /// Runs a Trade-off sweep, with progress and Cancel.
    #[must_use]
    pub fn sweep(label: String, job: SweepJob) -> Self {
        let mut spawned = Self::spawn(label, move |progress, cancel| {
            let report = thicket_core::measure::sweep_document_with_cancel(
                &job.doc,
                job.width,
                job.height,
                &job.settings,
                |done, total, _| {
                    let f = done as f32 / total.max(1) as f32;
                    progress.store(f.to_bits(), Ordering::Relaxed);
                },
                cancel,
            )
            .map_err(anyhow::Error::from);
            JobResult::Swept(job.revision, report)
        });
        spawned.sweep = true;
        spawned
    }
}

/// The work of [`Job::voxelize_mesh`].
fn voxelize_mesh(
    name: &str,
    model: &thicket_core::mesh::MeshModel,
    settings: &thicket_core::voxelize::VoxelizeSettings,
    budget: thicket_core::budget::MemoryBudget,
    progress: &AtomicU32,
    cancel: &AtomicBool,
) -> anyhow::Result<(VoxelModel, String)> {
    if let Ok(e) = thicket_core::voxelize::estimate(model, settings) {
        budget.check(
            &format!(
                "{name}: voxelizing about {} voxels",
                files::thousands((e.surface_voxels + e.interior_voxels).round() as u64)
            ),
            e.peak_bytes,
            "choose a smaller depth",
        )?;
    }
    let v = thicket_core::voxelize::voxelize(model, settings, &|f| {
        progress.store(f.clamp(0.0, 1.0).to_bits(), Ordering::Relaxed);
        !cancel.load(Ordering::Relaxed)
    })
    .with_context(|| format!("{name}: voxelizing"))?;
    let note = if v.stats.solid_fell_back {
        format!(
            "the mesh is open ({} voxel column(s) enter it without leaving): Solid needs a \
             closed mesh, so only its surface was voxelized",
            files::thousands(v.stats.open_columns)
        )
    } else {
        String::new()
    };
    Ok((files::voxel_model(v, model), note))
}

/// The import report's line for a file with a camera imported into an existing scene.
pub const IMPORT_KEEPS_VIEW: &str = "camera not applied: File > Import keeps your view; it is \
     used when the file is opened or imported from the command line";

/// Octree depth of a skinned glTF imported into the editor (as `thicket import` by default).
pub const SKINNED_IMPORT_DEPTH: u8 = 7;

/// The depths the Import report offers for a skinned glTF.
pub const SKINNED_DEPTHS: std::ops::RangeInclusive<u8> = 3..=10;

/// Reads `path` for File → Import: a skinned glTF is voxelized with its rig (progress and
/// cancel from the job), a static glTF becomes one mesh object per node
/// ([`files::load_gltf_objects`], with its node names for the report's checklist), anything
/// else goes through [`files::load_document`].
///
/// # Errors
/// The file cannot be read or voxelized, or makes an invalid document.
pub fn import_document(
    path: &Path,
    options: &files::MeshOptions,
    progress: &AtomicU32,
    cancel: &AtomicBool,
) -> anyhow::Result<Imported> {
    files::check_options(path, options)?;
    let is_gltf = FileKind::from_path(path) == Some(FileKind::Gltf);
    let skinned = if is_gltf {
        files::load_skinned(path)?
    } else {
        None
    };
    let imported = |(doc, left_out, view, node_names)| Imported {
        doc,
        left_out,
        view,
        node_names,
        skinned_depth: None,
    };
    let Some(skinned) = skinned else {
        if is_gltf {
            return files::load_gltf_objects(path, options).map(imported);
        }
        return files::load_document_imported(path, options)
            .map(|(doc, notes, view)| imported((doc, notes, view, Vec::new())));
    };
    let depth = options.skinned_depth.unwrap_or(SKINNED_IMPORT_DEPTH);
    if !SKINNED_DEPTHS.contains(&depth) {
        anyhow::bail!(
            "{}: depth {depth} is not within {}..={}",
            path.display(),
            SKINNED_DEPTHS.start(),
            SKINNED_DEPTHS.end()
        );
    }
    let settings = thicket_core::voxelize::VoxelizeSettings {
        resolution: thicket_core::voxelize::Resolution::Depth(depth),
        ..Default::default()
    };
    let v = thicket_core::io::voxelize_skinned(&skinned, &settings, &|f| {
        progress.store(f.clamp(0.0, 1.0).to_bits(), Ordering::Relaxed);
        !cancel.load(Ordering::Relaxed)
    })
    .with_context(|| format!("{}: voxelizing the skinned mesh", path.display()))?;
    let mut doc = Document::default();
    doc.add(files::object_name_for(path), ObjectKind::Voxels(v.model));
    doc.validate()
        .with_context(|| format!("{}: invalid document", path.display()))?;
    Ok(Imported {
        skinned_depth: Some(depth),
        ..imported((doc, skinned.warnings, skinned.view, Vec::new()))
    })
}

/// What an import left out of its file (shown in the Import report window until closed).
#[derive(Debug, Clone, PartialEq)]
pub struct ImportReport {
    /// The imported file.
    pub path: PathBuf,
    /// One line per kind of feature left out.
    pub lines: Vec<String>,
    /// The objects the import added (an import again with a texture replaces them).
    pub placed: Vec<u64>,
    /// The Texture field's text.
    pub texture: String,
    /// A glTF scene's nodes with meshes, in scene order, each with whether it is (to be)
    /// imported: the checklist that imports the file again with other nodes. Empty for other
    /// files and for skinned glTF (one skinned object).
    pub nodes: Vec<(String, bool)>,
    /// For a skinned glTF: the depth field's value (it was imported at this depth).
    pub skinned_depth: Option<u8>,
}

/// A finished import, placed in the document.
pub struct ImportDone {
    /// Where the objects went and how they were scaled.
    pub placement: ImportPlacement,
    /// What was left out, when anything was or the file has nodes to choose from.
    pub report: Option<ImportReport>,
}

/// Why a finished enhancement was not linked (the UI shows each differently).
pub enum EnhanceNotApplied {
    /// The job failed.
    Failed(anyhow::Error),
    /// The source model (named) was removed while the job ran.
    Removed(String),
    /// The source model (named) was edited while the job ran: its result is stale.
    Changed(String),
    /// The editor refused the result.
    Refused(CommandError),
}

impl Editor {
    /// Places an import's objects beside the scene (framed, scaled to fit), adds the file's
    /// lights, and says what was left out. Each node's object is named after it: a node is
    /// checked in the report when it was imported.
    pub fn finish_import(&mut self, path: PathBuf, imported: Imported) -> ImportDone {
        let Imported {
            doc,
            mut left_out,
            view,
            node_names,
            skinned_depth,
        } = imported;
        let nodes: Vec<(String, bool)> = node_names
            .into_iter()
            .map(|n| {
                let picked = doc.objects.iter().any(|o| o.name == n);
                (n, picked)
            })
            .collect();
        let placement = self.import_objects(doc);
        // Directions only: the placement's move and uniform scale leave them as is.
        let lights = view.lights_beside(&self.doc().lights);
        self.import_lights(lights);
        if view.camera.is_some() {
            left_out.push(IMPORT_KEEPS_VIEW.to_owned());
        }
        if let Some(d) = skinned_depth {
            left_out.insert(
                0,
                format!(
                    "skinned: voxelized at depth {d} ({} voxels along its longest side); \
                     choose another depth below to import it again",
                    1u32 << d
                ),
            );
        }
        let report = (!left_out.is_empty() || nodes.len() > 1).then(|| ImportReport {
            path,
            lines: left_out,
            placed: placement.ids.clone(),
            texture: String::new(),
            nodes,
            skinned_depth,
        });
        ImportDone { placement, report }
    }

    /// Links a finished enhancement to its source model (a new object, the model hidden), or
    /// replaces the source's linked enhancement. Returns the source's name and the fine
    /// model's voxel count.
    ///
    /// # Errors
    /// The job failed, the source was removed or edited meanwhile (strokes made while the job
    /// ran are not in its result), or the editor refused the result.
    pub fn finish_enhancement(
        &mut self,
        job: Enhanced,
    ) -> Result<(String, u64), EnhanceNotApplied> {
        let Enhanced {
            source,
            name,
            settings,
            coarse,
            result,
        } = job;
        let (fine, enhancer) = result.map_err(EnhanceNotApplied::Failed)?;
        let current = match self.object(source).map(|o| &o.kind) {
            Some(ObjectKind::Voxels(v)) => &v.svo,
            _ => return Err(EnhanceNotApplied::Removed(name)),
        };
        if *current != coarse {
            return Err(EnhanceNotApplied::Changed(name));
        }
        let voxels = fine.svo.leaf_count();
        let linked = self
            .doc()
            .enhancement_of(source)
            .is_some_and(|l| self.object(l.target).is_some());
        let result = if linked {
            self.replace_enhancement(source, settings, fine, Some(enhancer))
        } else {
            self.add_enhancement(source, settings, fine, Some(enhancer))
                .map(|_| ())
        };
        result.map_err(EnhanceNotApplied::Refused)?;
        Ok((name, voxels))
    }
}

impl Editor {
    /// Places a finished Voxelize mesh job: a voxel object "NAME voxels" where the mesh object
    /// is (its transform and keyed transforms), selected, with the mesh hidden; one undo step.
    /// Refused when the mesh changed (or went) while the job ran. Returns the new object's id.
    ///
    /// # Errors
    /// The mesh object is gone or its mesh changed.
    pub fn finish_voxelize(
        &mut self,
        id: u64,
        source: &thicket_core::mesh::MeshModel,
        model: VoxelModel,
    ) -> Result<u64, CommandError> {
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        if !matches!(&o.kind, ObjectKind::Mesh(m) if &m.model == source) {
            return Err(CommandError::Invalid(format!(
                "{:?} changed while it was voxelized: voxelize it again",
                o.name
            )));
        }
        let new_id = super::next_id(&self.doc);
        let object = Object {
            id: new_id,
            name: format!("{} voxels", o.name),
            visible: true,
            transform: o.transform,
            kind: ObjectKind::Voxels(model),
            motion: o.motion.clone(),
        };
        let label = format!("Voxelize {}", o.name);
        let index = self.index_of(id)? + 1;
        self.history.seal();
        self.apply_named(
            super::Edit::Group(vec![
                super::Edit::Insert {
                    index,
                    object: Box::new(object),
                },
                super::Edit::SetVisible { id, visible: false },
            ]),
            None,
            label,
        );
        self.history.seal();
        self.selection = Some(super::Selection::Object(new_id));
        Ok(new_id)
    }
}

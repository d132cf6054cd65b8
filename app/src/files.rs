//! Opening any supported file as a [`Document`], and summarising a document for `thicket info`
//! and the editor's inspector.
//!
//! Every loader in `thicket_core::io` names the file in its errors already; this module adds
//! the file name only where it would otherwise be missing (unknown extensions).

use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};
use serde::Serialize;
use thicket_core::io::GltfView;
use thicket_core::mesh::MeshModel;
use thicket_core::scene::{Document, Object, ObjectKind};

/// The file formats Thicket reads, by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum FileKind {
    /// `NAME.thicket.json` (+ its payload `NAME.thicket.HASH.bin`).
    Project,
    /// MagicaVoxel `.vox`.
    Vox,
    /// glTF 2.0, `.gltf` or `.glb`.
    Gltf,
    /// Wavefront `.obj`.
    Obj,
}

impl FileKind {
    /// The kind a path's extension names, if Thicket knows it.
    #[must_use]
    pub fn from_path(path: &Path) -> Option<Self> {
        let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
        if name.ends_with(".thicket.json") {
            return Some(Self::Project);
        }
        let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
        match ext.as_str() {
            "vox" => Some(Self::Vox),
            "gltf" | "glb" => Some(Self::Gltf),
            "obj" => Some(Self::Obj),
            _ => None,
        }
    }

    /// A short name for listings and `--json`.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::Project => "thicket project",
            Self::Vox => "MagicaVoxel .vox",
            Self::Gltf => "glTF 2.0",
            Self::Obj => "Wavefront OBJ",
        }
    }

    /// Whether this build can read the format (the loaders land one by one).
    #[must_use]
    pub fn is_readable(self) -> bool {
        matches!(self, Self::Project | Self::Vox | Self::Gltf | Self::Obj)
    }
}

/// File-dialog filters for formats this build can open or import.
#[must_use]
pub fn readable_extensions() -> Vec<(&'static str, &'static [&'static str])> {
    let all: [(FileKind, &'static [&'static str]); 4] = [
        (FileKind::Project, &["json"]),
        (FileKind::Vox, &["vox"]),
        (FileKind::Gltf, &["glb", "gltf"]),
        (FileKind::Obj, &["obj"]),
    ];
    all.into_iter()
        .filter(|(k, _)| k.is_readable())
        .map(|(k, e)| (k.label(), e))
        .collect()
}

fn kind_of(path: &Path) -> anyhow::Result<FileKind> {
    match FileKind::from_path(path) {
        Some(k) if k.is_readable() => Ok(k),
        Some(k) => bail!(
            "{}: {} files are not supported by this build yet",
            path.display(),
            k.label()
        ),
        None => bail!(
            "{}: unknown file type (expected .thicket.json, .vox, .glb, .gltf or .obj)",
            path.display()
        ),
    }
}

/// Reads a mesh file (glTF or OBJ).
///
/// # Errors
/// The loader's message, which names the file and the problem.
pub fn load_mesh(path: &Path) -> anyhow::Result<MeshModel> {
    Ok(load_mesh_reported(path)?.0)
}

/// [`load_mesh`], plus one line per kind of feature the file holds that the model leaves out
/// (glTF morph targets, animation, extra UV sets, other texture maps, point and spot lights,
/// unsupported extensions; see `thicket_core::io::import_gltf_reported`) and what became of its
/// cameras and directional lights, for the caller to show. Empty when there is nothing to say.
///
/// # Errors
/// As [`load_mesh`].
pub fn load_mesh_reported(path: &Path) -> anyhow::Result<(MeshModel, Vec<String>)> {
    load_mesh_reported_with(path, &MeshOptions::default())
}

/// How to read a mesh file.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MeshOptions {
    /// A base-colour texture (PNG or JPEG) for the parts of an OBJ whose material names none:
    /// for files shipped without their `.mtl`. Refused for other formats, whose materials
    /// carry their textures.
    pub texture: Option<PathBuf>,
    /// glTF only: the names of the nodes to import, each as its own object (`None`: every
    /// node with a mesh). Honoured by [`load_gltf_objects`].
    pub nodes: Option<Vec<String>>,
    /// A skinned glTF's octree depth in the editor's import (`None`: 7, as `thicket import`).
    pub skinned_depth: Option<u8>,
    /// The memory reading the file may fill, estimated before the work: a mesh's vertices
    /// with every instance of an instanced glTF mesh counted, a `.vox` file's voxels with every
    /// scene-graph copy counted, a project's decoded payload (`--memory-limit`; `None`: the
    /// machine's default, [`thicket_core::budget::MemoryBudget::for_this_machine`]).
    pub memory_limit: Option<u64>,
}

/// [`load_mesh_reported`] with options. An OBJ that has texture coordinates but names no
/// texture (and was given none) is reported too: it imports in flat material colours.
///
/// # Errors
/// As [`load_mesh`]; a texture for a file that is not an OBJ, or one that cannot be read.
pub fn load_mesh_reported_with(
    path: &Path,
    options: &MeshOptions,
) -> anyhow::Result<(MeshModel, Vec<String>)> {
    load_mesh_imported(path, options).map(|i| (i.model, i.notes))
}

/// A mesh file as read: the model, the report's lines and the file's view.
#[derive(Debug, Clone)]
pub struct MeshImport {
    /// The meshes, in the file's world space.
    pub model: MeshModel,
    /// As [`load_mesh_reported_with`]'s lines, with what became of the file's cameras and
    /// lights.
    pub notes: Vec<String>,
    /// A glTF file's first camera and directional lights (empty for an OBJ).
    pub view: GltfView,
    /// A glTF file's nodes with triangles, over `model`'s parts (empty for an OBJ); each
    /// instance of an `EXT_mesh_gpu_instancing` node is one.
    pub nodes: Vec<thicket_core::io::GltfNode>,
    /// The instances a glTF file's `EXT_mesh_gpu_instancing` nodes place (zero otherwise).
    pub instancing: thicket_core::io::InstanceCounts,
}

/// The limits a mesh file is read with: the defaults, within the memory budget (one source
/// for the import and `info`'s count, so both refuse the same files).
fn mesh_limits(memory_limit: Option<u64>) -> thicket_core::io::ImportLimits {
    thicket_core::io::ImportLimits {
        memory: memory_budget(memory_limit),
        ..thicket_core::io::ImportLimits::default()
    }
}

/// [`load_mesh_reported_with`], plus a glTF file's camera and directional lights.
///
/// # Errors
/// As [`load_mesh_reported_with`].
pub fn load_mesh_imported(path: &Path, options: &MeshOptions) -> anyhow::Result<MeshImport> {
    let kind = kind_of(path)?;
    check_options(path, options)?;
    let limits = mesh_limits(options.memory_limit);
    let (model, notes) = match kind {
        FileKind::Gltf => {
            let i = thicket_core::io::import_gltf_imported(path, &limits)?;
            return Ok(MeshImport {
                model: i.model,
                notes: i.report,
                view: i.view,
                nodes: i.nodes,
                instancing: i.instancing,
            });
        }
        FileKind::Obj => {
            let obj = thicket_core::io::ObjOptions {
                default_texture: options.texture.clone(),
            };
            let model = thicket_core::io::obj::import_obj_with(path, &obj, &limits)?;
            let notes = if obj_lacks_texture(&model) {
                vec![OBJ_NO_TEXTURE.to_owned()]
            } else {
                Vec::new()
            };
            (model, notes)
        }
        other => bail!("{}: a {} is not a mesh file", path.display(), other.label()),
    };
    Ok(MeshImport {
        model,
        notes,
        view: GltfView::default(),
        nodes: Vec::new(),
        instancing: thicket_core::io::InstanceCounts::default(),
    })
}

/// Refuses options the file at `path` cannot take: a texture for anything but an OBJ (other
/// formats name their own textures).
///
/// # Errors
/// A message naming the texture and the file.
pub fn check_options(path: &Path, options: &MeshOptions) -> anyhow::Result<()> {
    if let Some(t) = &options.texture
        && FileKind::from_path(path) != Some(FileKind::Obj)
    {
        bail!(
            "--texture {}: only an OBJ file takes a texture; {} names its own",
            t.display(),
            path.display()
        );
    }
    if options.nodes.is_some() && FileKind::from_path(path) != Some(FileKind::Gltf) {
        bail!(
            "--node: {} is not a glTF file; only glTF scenes have nodes to pick",
            path.display()
        );
    }
    Ok(())
}

/// A static glTF scene for File → Import: one mesh object per node with a mesh (only the
/// nodes `options.nodes` names, when it names any), each placed by its node's world transform
/// as far as an object transform can hold it (see `thicket_core::io::gltf_nodes`), plus the
/// report's lines, the file's view (applied to the document) and the names of all its nodes
/// with meshes, in scene order, for a checklist.
///
/// # Errors
/// As [`load_mesh_imported`]; a picked name that is no node's, listing the names there are.
pub fn load_gltf_objects(
    path: &Path,
    options: &MeshOptions,
) -> anyhow::Result<(Document, Vec<String>, GltfView, Vec<String>)> {
    let import = load_mesh_imported(path, options)?;
    let objects = thicket_core::io::gltf_nodes::node_objects(
        &import.model,
        &import.nodes,
        options.nodes.as_deref(),
    )
    .with_context(|| format!("{}", path.display()))?;
    let mut doc = Document::default();
    for o in objects {
        doc.add(
            o.name,
            ObjectKind::Mesh(thicket_core::scene::MeshObject {
                model: o.model,
                casts_shadows: true,
            }),
        );
        if let Some(added) = doc.objects.last_mut() {
            added.transform = o.transform;
        }
    }
    if let Some((lo, hi)) = doc.bounds() {
        doc.camera.frame(lo, hi);
    }
    import.view.apply_to_new_document(&mut doc);
    doc.validate()
        .with_context(|| format!("{}: invalid document", path.display()))?;
    let names = import.nodes.iter().map(|n| n.name.clone()).collect();
    Ok((doc, import.notes, import.view, names))
}

/// The import report's line for an OBJ with texture coordinates that names no texture.
pub const OBJ_NO_TEXTURE: &str = "the OBJ has texture coordinates but names no texture (no \
     material library, or no map_Kd in it): imported in flat material colours; give one with \
     --texture PATH, or with Texture in the editor's Import report";

/// Whether an imported OBJ has texture coordinates on a part whose material has no texture.
fn obj_lacks_texture(model: &MeshModel) -> bool {
    model.parts.iter().any(|p| {
        !p.uvs.is_empty()
            && model
                .materials
                .get(p.material)
                .is_none_or(|m| m.base_color_texture.is_none())
    })
}

/// Reads the skin of a glTF file: `Ok(None)` when the file is not glTF or has no skinned mesh,
/// an error when it has one that cannot be read.
///
/// # Errors
/// The skinned importer's message, naming the file and the problem.
pub fn load_skinned(path: &Path) -> anyhow::Result<Option<thicket_core::io::SkinnedImport>> {
    if kind_of(path)? != FileKind::Gltf {
        return Ok(None);
    }
    match thicket_core::io::import_skinned(path) {
        Ok(s) => Ok(Some(s)),
        Err(thicket_core::skin::SkinError::NoSkin { .. }) => Ok(None),
        Err(e) => {
            // A file the static reader refuses too is broken as a file, skin or not: say
            // that, as the static import would, not that its skin failed.
            let limits = thicket_core::io::ImportLimits::default();
            if let Err(file_error) = thicket_core::io::import_gltf_reported(path, &limits) {
                return Err(file_error.into());
            }
            // One line naming the file once: the skin error's own text starts with the path
            // (most variants), which the sentence already gives.
            let shown = path.display().to_string();
            let text = e.to_string();
            let detail = text
                .strip_prefix(&shown)
                .and_then(|t| t.strip_prefix(": "))
                .unwrap_or(&text);
            bail!(
                "{shown}: the file has a skin that cannot be imported: {detail} (use --no-skin \
                 to import it as a static model)"
            )
        }
    }
}

/// Opens any supported file as a document: a project as it is, a mesh file as one mesh object,
/// a `.vox` file as its voxel objects. The result is validated.
///
/// # Errors
/// A message naming the file and what is wrong with it.
pub fn load_document(path: &Path) -> anyhow::Result<Document> {
    let (doc, _, notes, _) = load_document_noted(path, &MeshOptions::default())?;
    for line in &notes {
        log::warn!("{}: {line}", path.display());
    }
    Ok(doc)
}

/// [`load_document`] within a memory budget (`--memory-limit`; `None`: the machine's
/// default), estimated before the work as [`MeshOptions::memory_limit`] says.
///
/// # Errors
/// See [`load_document`]; a file over the budget is refused with the estimate and the limit.
pub fn load_document_within(path: &Path, memory_limit: Option<u64>) -> anyhow::Result<Document> {
    let options = MeshOptions {
        memory_limit,
        ..MeshOptions::default()
    };
    let (doc, _, notes, _) = load_document_noted(path, &options)?;
    for line in &notes {
        log::warn!("{}: {line}", path.display());
    }
    Ok(doc)
}

/// The memory budget of a request: `--memory-limit`, else the machine's default (the smallest
/// of half of physical memory and the process's address-space and cgroup limits).
#[must_use]
pub fn memory_budget(limit: Option<u64>) -> thicket_core::budget::MemoryBudget {
    limit.map_or_else(
        thicket_core::budget::MemoryBudget::for_this_machine,
        thicket_core::budget::MemoryBudget::given,
    )
}

/// What a source file held beyond the document (for `info`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct SourceCounts {
    /// Models stored in a `.vox` file (before the scene graph places them).
    pub stored_models: Option<usize>,
    /// Voxels stored in a `.vox` file's models (each model once).
    pub stored_voxels: Option<u64>,
    /// A glTF file's nodes with `EXT_mesh_gpu_instancing` (when it has any).
    pub instanced_nodes: Option<u64>,
    /// The instances they place, each expanded into the document's mesh.
    pub instances: Option<u64>,
}

/// [`load_document`], plus counts only the source format knows.
///
/// # Errors
/// See [`load_document`].
pub fn load_document_with_source(path: &Path) -> anyhow::Result<(Document, SourceCounts)> {
    load_document_noted(path, &MeshOptions::default()).map(|(doc, counts, _, _)| (doc, counts))
}

/// [`load_document`] with mesh options, plus the lines of [`load_mesh_reported_with`] for a
/// mesh file (what the document leaves out of it; empty for projects and `.vox` files).
///
/// # Errors
/// See [`load_document`].
pub fn load_document_reported(
    path: &Path,
    options: &MeshOptions,
) -> anyhow::Result<(Document, Vec<String>)> {
    load_document_imported(path, options).map(|(doc, notes, _)| (doc, notes))
}

/// [`load_document_reported`], plus a glTF file's view (already applied to the document: its
/// camera and, when it has any, its directional lights replace the defaults), for File →
/// Import, which takes the file's lights but keeps the editor's view.
///
/// # Errors
/// See [`load_document`].
pub fn load_document_imported(
    path: &Path,
    options: &MeshOptions,
) -> anyhow::Result<(Document, Vec<String>, GltfView)> {
    load_document_noted(path, options).map(|(doc, _, notes, view)| (doc, notes, view))
}

fn load_document_noted(
    path: &Path,
    options: &MeshOptions,
) -> anyhow::Result<(Document, SourceCounts, Vec<String>, GltfView)> {
    let mut counts = SourceCounts::default();
    let mut notes = Vec::new();
    let mut view = GltfView::default();
    let kind = kind_of(path)?;
    check_options(path, options)?;
    let budget = memory_budget(options.memory_limit);
    let doc = match kind {
        FileKind::Project => thicket_core::io::project::load_within(path, &budget)?,
        FileKind::Gltf | FileKind::Obj => {
            let import = load_mesh_imported(path, options)?;
            if import.instancing.instances > 0 {
                counts.instanced_nodes = Some(import.instancing.nodes);
                counts.instances = Some(import.instancing.instances);
            }
            notes = import.notes;
            view = import.view;
            let mut doc = document_from_mesh(&object_name_for(path), import.model);
            view.apply_to_new_document(&mut doc);
            doc
        }
        FileKind::Vox => {
            let options = thicket_core::io::vox::VoxImportOptions {
                memory: budget,
                ..thicket_core::io::vox::VoxImportOptions::default()
            };
            let scene = thicket_core::io::vox::import_vox_with(path, &options)?;
            counts.stored_models = Some(scene.model_count);
            counts.stored_voxels = Some(scene.stored_voxels);
            let mut doc = Document::default();
            scene.add_to(&mut doc);
            if let Some((lo, hi)) = doc.bounds() {
                doc.camera.frame(lo, hi);
            }
            doc
        }
    };
    doc.validate()
        .with_context(|| format!("{}: invalid document", path.display()))?;
    Ok((doc, counts, notes, view))
}

/// Saves a project atomically (the previous save stays readable until the new one is whole).
///
/// # Errors
/// The saver's message, naming the file.
pub fn save_project(doc: &Document, path: &Path) -> anyhow::Result<()> {
    Ok(thicket_core::io::project::save(doc, path)?)
}

/// `path` as the file system names it: canonical when it exists, else its canonical folder
/// joined with its name (an output is usually not there yet), else as given.
fn resolved(path: &Path) -> PathBuf {
    if let Ok(p) = std::fs::canonicalize(path) {
        return p;
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    match (std::fs::canonicalize(parent), path.file_name()) {
        (Ok(dir), Some(name)) => dir.join(name),
        _ => path.to_path_buf(),
    }
}

/// Refuses an output path that names the input or, for a project, the payload `.bin` the
/// input's JSON reads: a write there would replace what the command is reading, and a failed
/// run would leave neither (issue 45). Symbolic links and `./` spellings count as the same
/// file.
///
/// # Errors
/// One line naming the output and what it would overwrite.
pub fn refuse_overwriting_input(input: &Path, output: &Path) -> anyhow::Result<()> {
    let out = resolved(output);
    let is_project = FileKind::from_path(input) == Some(FileKind::Project);
    if out == resolved(input) {
        bail!(
            "{}: the output is the input {}; write to another file (-o) so the original stays \
             as it was",
            output.display(),
            if is_project { "project" } else { "file" }
        );
    }
    if is_project && out == resolved(&thicket_core::io::project::bin_path_for(input)) {
        bail!(
            "{}: the output is the payload of the input project {}; write to another file (-o) \
             so the project stays loadable",
            output.display(),
            input.display()
        );
    }
    Ok(())
}

/// Writes `path` through a temporary sibling (`NAME.tmp`): `write` fills the temporary, which
/// is then renamed over `path`. On any failure the temporary is removed, so a failed write
/// leaves neither a partial `path` nor a stray `.tmp`.
///
/// # Errors
/// `write`'s error, or the rename's, naming `path`.
pub fn write_through_temporary(
    path: &Path,
    write: impl FnOnce(&Path) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let result = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path)
            .with_context(|| format!("{}: cannot write the file", path.display()))
    });
    if result.is_err() {
        // Best effort: the error that matters is the one returned.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `image` as a PNG at `path` through a temporary sibling (see
/// [`write_through_temporary`]).
///
/// # Errors
/// The encoder or the file system, in one line naming `path`.
pub fn write_png(image: &thicket_core::render::RgbaImage, path: &Path) -> anyhow::Result<()> {
    write_through_temporary(path, |tmp| {
        image.save_png(tmp).map_err(|e| {
            anyhow::anyhow!("{}: cannot write the PNG: {}", path.display(), e.detail())
        })
    })
}

/// A document holding one mesh object (framed by the camera).
#[must_use]
pub fn document_from_mesh(name: &str, model: MeshModel) -> Document {
    let mut doc = Document::default();
    doc.add(
        name,
        ObjectKind::Mesh(thicket_core::scene::MeshObject {
            model,
            casts_shadows: true,
        }),
    );
    if let Some((lo, hi)) = doc.bounds() {
        doc.camera.frame(lo, hi);
    }
    doc
}

/// A static voxel model of a voxelized mesh, with the mesh's material names (`thicket import`
/// and the editor's Voxelize mesh make the same one).
#[must_use]
pub fn voxel_model(
    v: thicket_core::voxelize::Voxelized,
    mesh: &thicket_core::mesh::MeshModel,
) -> thicket_core::scene::VoxelModel {
    thicket_core::scene::VoxelModel {
        svo: v.svo,
        voxel_size: v.voxel_size,
        origin: v.origin,
        material_names: mesh.materials.iter().map(|m| m.name.clone()).collect(),
        rig: None,
        volume: None,
        palette: Vec::new(),
        frames: None,
    }
}

/// An object name from a file name: `models/Box.glb` → `Box`, `a/tree.thicket.json` → `tree`.
#[must_use]
pub fn object_name_for(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem = name
        .strip_suffix(".thicket.json")
        .map(str::to_owned)
        .or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .unwrap_or_default();
    if stem.is_empty() {
        "Object".to_owned()
    } else {
        stem
    }
}

/// Memory an object holds, by part, in bytes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct MemoryInfo {
    /// Internal octree nodes with their LOD attributes (0 for meshes).
    pub structure_bytes: u64,
    /// Leaf voxel attributes, or mesh vertex and index arrays.
    pub payload_bytes: u64,
    /// Texture pixels (meshes).
    pub texture_bytes: u64,
    /// Allocated but unused slots left by edits (voxels).
    pub free_bytes: u64,
    /// Everything.
    pub total_bytes: u64,
    /// Tiles: full regions of equal voxels stored once, as one internal node (voxels).
    pub tiles: u64,
    /// Voxels those tiles stand for, with no storage of their own.
    pub tile_voxels: u64,
    /// Interior voxels: enclosed, attributes found when an edit exposes them (a solid
    /// import's inside).
    pub interior_voxels: u64,
}

/// One object of a document, as `thicket info` reports it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObjectInfo {
    /// Stable id in the document.
    pub id: u64,
    /// Display name.
    pub name: String,
    /// `voxels` or `mesh`.
    pub kind: &'static str,
    /// Hidden objects are not rendered.
    pub visible: bool,
    /// Solid voxels (of the shown frame, for a frame sequence).
    pub voxels: Option<u64>,
    /// A frame sequence's solid voxels per frame (an animated `.vox`); `None` for still
    /// models. Omitted from the JSON when `None`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_voxels: Option<Vec<u64>>,
    /// Octree depth (levels below the root).
    pub depth: Option<u8>,
    /// Octree extent in voxels per axis (`2^depth`).
    pub extent: Option<u32>,
    /// Size of the solid voxels' bounding box, in voxels.
    pub dimensions_voxels: Option<[u32; 3]>,
    /// Edge of one voxel in object units.
    pub voxel_size: Option<f32>,
    /// Bytes per solid voxel over the whole octree (nodes, attributes, free slots).
    pub bytes_per_voxel: Option<f64>,
    /// Triangles (meshes).
    pub triangles: Option<usize>,
    /// Vertices (meshes).
    pub vertices: Option<usize>,
    /// Materials (meshes) or named voxel materials.
    pub materials: usize,
    /// Size of the world-space bounding box.
    pub world_size: Option<[f32; 3]>,
    /// Memory by part.
    pub memory: MemoryInfo,
    /// Kernel-reflection-sequence objects.
    pub krs: Option<KrsInfo>,
    /// A voxel model's solid bounds in its own space (before the object's transform): where a
    /// skeleton's joint positions are given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bounds_min: Option<[f32; 3]>,
    /// See [`ObjectInfo::bounds_min`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bounds_max: Option<[f32; 3]>,
    /// A rigged voxel model's joints, parents first.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joints: Option<Vec<JointInfo>>,
}

/// One joint of a rigged voxel model, as `thicket info` reports it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointInfo {
    /// The joint's name.
    pub name: String,
    /// Its parent's name.
    pub parent: Option<String>,
    /// Where it stands in the bind pose, in the model's own space.
    pub position: [f32; 3],
    /// Voxels that have this joint as their strongest influence.
    pub dominant_voxels: u64,
}

/// The joints of a rigged model with the voxels each dominates.
fn joint_info(v: &thicket_core::scene::VoxelModel) -> Option<Vec<JointInfo>> {
    let rig = v.rig.as_ref()?;
    let dominant = thicket_core::skin::bind::dominant_joints(&v.svo, rig.skeleton.len());
    let spec = thicket_core::skin::SkeletonSpec::of_skeleton(&rig.skeleton);
    Some(
        spec.joints
            .into_iter()
            .zip(dominant)
            .map(|(j, dominant_voxels)| JointInfo {
                name: j.name,
                parent: j.parent,
                position: j.position,
                dominant_voxels,
            })
            .collect(),
    )
}

/// What `thicket info` says about a KRS object.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KrsInfo {
    /// Mirror planes (reflection levels n).
    pub mirrors: usize,
    /// Kernel sets K0..Kn, empty ones included (n + 1).
    pub kernel_sets: usize,
    /// Kinds of the non-empty kernel sets, finest level first.
    pub kernels: Vec<&'static str>,
    /// Kernel instances, sum over non-empty K_j of 2^(n-j) (saturating).
    pub kernel_instances: u128,
    /// Whether a Lipschitz-bounded distortion warps it.
    pub distorted: bool,
    /// Carved-out empty zones.
    pub empty_zones: usize,
}

/// A document summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DocumentInfo {
    /// The file it came from.
    pub file: String,
    /// Its format.
    pub format: &'static str,
    /// Every object, in outliner order.
    pub objects: Vec<ObjectInfo>,
    /// Number of lights.
    pub lights: usize,
    /// Solid voxels over all objects.
    pub total_voxels: u64,
    /// Triangles over all objects.
    pub total_triangles: usize,
    /// Bytes over all objects.
    pub total_bytes: u64,
    /// Size of the world-space bounding box of the visible objects.
    pub world_size: Option<[f32; 3]>,
    /// Counts from the source file (stored `.vox` models and voxels before instancing).
    pub source: SourceCounts,
    /// For a glTF file too large to import with the memory budget (an exported forest's
    /// instances expanded): what it holds, counted from the file without building it. The
    /// object list is empty then.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub counted: Option<thicket_core::io::GltfCount>,
}

fn mesh_memory(model: &MeshModel) -> MemoryInfo {
    let mut payload = 0usize;
    for p in &model.parts {
        payload += p.positions.len() * 12
            + p.normals.len() * 12
            + p.uvs.len() * 8
            + p.colors.len() * 16
            + p.joints.len() * 8
            + p.weights.len() * 16
            + p.indices.len() * 4;
    }
    let texture: usize = model
        .materials
        .iter()
        .filter_map(|m| m.base_color_texture.as_ref())
        .map(|t| t.rgba8.len())
        .sum();
    MemoryInfo {
        structure_bytes: 0,
        payload_bytes: payload as u64,
        texture_bytes: texture as u64,
        free_bytes: 0,
        total_bytes: (payload + texture) as u64,
        ..MemoryInfo::default()
    }
}

/// Summarises one object.
#[must_use]
pub fn object_info(o: &Object) -> ObjectInfo {
    let world_size = o.world_bounds().map(|(lo, hi)| (hi - lo).to_array());
    let mut info = ObjectInfo {
        id: o.id,
        name: o.name.clone(),
        kind: o.kind_name(),
        visible: o.visible,
        voxels: None,
        frame_voxels: None,
        depth: None,
        extent: None,
        dimensions_voxels: None,
        voxel_size: None,
        bytes_per_voxel: None,
        triangles: None,
        vertices: None,
        materials: 0,
        world_size,
        memory: MemoryInfo::default(),
        krs: None,
        bounds_min: None,
        bounds_max: None,
        joints: None,
    };
    match &o.kind {
        ObjectKind::Voxels(v) => {
            let stats = v.svo.memory_stats();
            info.voxels = Some(v.svo.leaf_count());
            info.frame_voxels = v.frames.as_ref().map(|_| {
                (0..v.frame_count())
                    .filter_map(|i| v.frame(i))
                    .map(|(svo, _)| svo.leaf_count())
                    .collect()
            });
            info.depth = Some(v.svo.depth());
            info.extent = Some(v.svo.extent());
            info.dimensions_voxels = v.svo.bounds().map(|(lo, hi)| (hi - lo + 1).to_array());
            info.voxel_size = Some(v.voxel_size);
            info.bytes_per_voxel = (stats.leaves > 0).then_some(stats.bytes_per_leaf);
            info.materials = v.material_names.len();
            if let Some((lo, hi)) = v.bounds() {
                info.bounds_min = Some(lo.to_array());
                info.bounds_max = Some(hi.to_array());
            }
            info.joints = joint_info(v);
            let live = stats.inner_bytes + stats.leaf_bytes;
            info.memory = MemoryInfo {
                structure_bytes: stats.inner_bytes,
                payload_bytes: stats.leaf_bytes,
                texture_bytes: 0,
                free_bytes: stats.total_bytes.saturating_sub(live),
                total_bytes: stats.total_bytes,
                tiles: stats.tiles,
                tile_voxels: stats.tile_voxels,
                interior_voxels: v.svo.interior_voxels(),
            };
        }
        ObjectKind::Mesh(m) => {
            info.triangles = Some(m.model.triangle_count());
            info.vertices = Some(m.model.vertex_count());
            info.materials = m.model.materials.len();
            info.memory = mesh_memory(&m.model);
        }
        ObjectKind::Krs(k) => {
            let kernels: Vec<&'static str> = k
                .kernels
                .iter()
                .filter(|kernel| !kernel.is_empty())
                .map(thicket_core::krs::Kernel::kind_name)
                .collect();
            let bytes = (std::mem::size_of_val(k.kernels.as_slice())
                + std::mem::size_of_val(k.mirrors.as_slice())
                + std::mem::size_of_val(k.empty_zones.as_slice())) as u64;
            info.memory = MemoryInfo {
                payload_bytes: bytes,
                total_bytes: bytes,
                ..MemoryInfo::default()
            };
            info.krs = Some(KrsInfo {
                mirrors: k.mirrors.len(),
                kernel_sets: k.kernels.len(),
                kernels,
                kernel_instances: k.instance_count(),
                distorted: k.distortion.is_some(),
                empty_zones: k.empty_zones.len(),
            });
        }
    }
    info
}

/// Summarises a document read from `file`.
#[must_use]
pub fn document_info(doc: &Document, file: &Path, format: FileKind) -> DocumentInfo {
    let objects: Vec<ObjectInfo> = doc.objects.iter().map(object_info).collect();
    DocumentInfo {
        file: file.display().to_string(),
        format: format.label(),
        total_voxels: objects.iter().filter_map(|o| o.voxels).sum(),
        total_triangles: objects.iter().filter_map(|o| o.triangles).sum(),
        total_bytes: objects.iter().map(|o| o.memory.total_bytes).sum(),
        lights: doc.lights.len(),
        world_size: doc.bounds().map(|(lo, hi)| (hi - lo).to_array()),
        source: SourceCounts::default(),
        counted: None,
        objects,
    }
}

/// Reads any supported file and summarises it.
///
/// # Errors
/// See [`load_document`].
pub fn info(path: &Path, memory_limit: Option<u64>) -> anyhow::Result<DocumentInfo> {
    let kind = kind_of(path)?;
    let options = MeshOptions {
        memory_limit,
        ..MeshOptions::default()
    };
    match load_document_noted(path, &options) {
        Ok((doc, source, _, _)) => Ok(DocumentInfo {
            source,
            ..document_info(&doc, path, kind)
        }),
        Err(e)
            if kind == FileKind::Gltf
                && matches!(
                    e.downcast_ref::<thicket_core::io::IoError>(),
                    Some(thicket_core::io::IoError::TooLarge { .. })
                ) =>
        {
            // Too large to build: count what the file holds instead.
            let count = thicket_core::io::count_gltf(path, &mesh_limits(memory_limit))?;
            if count.refused.is_none() {
                // Refused for a reason the count does not see: the import's own words.
                return Err(e);
            }
            Ok(DocumentInfo {
                source: SourceCounts {
                    instanced_nodes: (count.instances > 0).then_some(count.instanced_nodes),
                    instances: (count.instances > 0).then_some(count.instances),
                    ..SourceCounts::default()
                },
                counted: Some(count),
                ..document_info(&Document::default(), path, kind)
            })
        }
        Err(e) => Err(e),
    }
}

pub use thicket_core::budget::{thousands, thousands_u128};

/// Bytes in a human unit: `1.5 MiB`.
#[must_use]
pub fn human_bytes(bytes: u64) -> String {
    thicket_core::budget::human(bytes)
}

/// The default project the editor opens: the first `*.thicket.json` (by name) in a `projects/`
/// folder beside the executable's workspace or the current directory.
#[must_use]
pub fn default_project() -> Option<PathBuf> {
    let mut roots: Vec<PathBuf> = Vec::new();
    if let Ok(cwd) = std::env::current_dir() {
        roots.push(cwd);
    }
    // target/<profile>/thicket → the workspace is three levels up.
    if let Ok(exe) = std::env::current_exe() {
        roots.extend(exe.ancestors().skip(1).take(4).map(Path::to_path_buf));
    }
    roots.push(PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/..")));
    for root in roots {
        let dir = root.join("projects");
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut found: Vec<PathBuf> = entries
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| FileKind::from_path(p) == Some(FileKind::Project))
            .collect();
        found.sort();
        if let Some(first) = found.into_iter().next() {
            return Some(first);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_by_extension() {
        assert_eq!(
            FileKind::from_path(Path::new("a/b.thicket.json")),
            Some(FileKind::Project)
        );
        assert_eq!(
            FileKind::from_path(Path::new("x.GLB")),
            Some(FileKind::Gltf)
        );
        assert_eq!(FileKind::from_path(Path::new("x.vox")), Some(FileKind::Vox));
        assert_eq!(FileKind::from_path(Path::new("x.json")), None);
        assert_eq!(FileKind::from_path(Path::new("noext")), None);
    }

    #[test]
    fn names_from_files() {
        assert_eq!(object_name_for(Path::new("m/Box.glb")), "Box");
        assert_eq!(object_name_for(Path::new("tree.thicket.json")), "tree");
        assert_eq!(object_name_for(Path::new("")), "Object");
    }

    #[test]
    fn number_formatting() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(180_202), "180,202");
        assert_eq!(thousands(1_234_567), "1,234,567");
        assert_eq!(human_bytes(12), "12 B");
        assert_eq!(human_bytes(1536), "1.5 KiB");
    }

    #[test]
    fn voxel_object_info_counts() {
        use thicket_core::scene::VoxelModel;
        use thicket_core::svo::{Svo, Voxel};
        let mut svo = Svo::new(4, false).unwrap();
        for x in 0..3 {
            svo.set(
                glam::UVec3::new(x, 1, 2),
                Voxel::new([255, 0, 0, 255], glam::Vec3::Y),
            )
            .unwrap();
        }
        let mut doc = Document::default();
        doc.add(
            "row",
            ObjectKind::Voxels(VoxelModel {
                svo,
                ..VoxelModel::default()
            }),
        );
        let info = document_info(&doc, Path::new("x.thicket.json"), FileKind::Project);
        let o = &info.objects[0];
        assert_eq!(o.voxels, Some(3));
        assert_eq!(o.dimensions_voxels, Some([3, 1, 1]));
        assert_eq!(o.extent, Some(16));
        assert!(o.bytes_per_voxel.unwrap() > 0.0);
        assert_eq!(info.total_voxels, 3);
        assert!(info.total_bytes > 0);
    }
}

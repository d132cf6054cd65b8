//! glTF 2.0 export (`.glb`, or `.gltf` with a `.bin` beside it) of a document's objects.
//!
//! | object | `Cubes` mode | `Smooth` mode |
//! |---|---|---|
//! | voxel model | faces between solid voxels and outside air (never toward a sealed cavity), greedy-merged per (colour, material, corner weights) into quads ([`greedy`]); a rigged model's corners carry one weight set each, so the skinned surface stays closed | a closed surface through the voxel centres, relaxed ([`fields::mesh_voxels_smooth`]) |
//! | triangle mesh | written as it is (positions, normals, UVs, colours, material colour and texture) | same |
//! | KRS | a closed mesh of the distance field at [`GltfExportOptions::resolution`] ([`fields::mesh_krs`]) | same |
//!
//! Colours go out as `COLOR_0` (linear, unsigned-short normalised) or, with
//! [`ColorMode::PaletteTexture`], as UVs into a palette image with one texel per distinct
//! colour (nearest filtering). Each object is a node with its transform; each material id of a
//! voxel model is a glTF material named after it. Conventions: right-handed, +Y up, the
//! document's units as metres.
//!
//! Files are written to a temporary sibling, synced and renamed over the target, so a failed
//! export (or a crash) never leaves a partial file. Sizes are checked before the big
//! allocations: the exposed faces are counted before any quad is built, KRS surface blocks
//! before any cell is marched.

pub mod fields;
pub mod greedy;
pub mod impostor;
pub mod instances;
pub mod iso;
mod writer;

#[cfg(test)]
mod skin_tests;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod watertight_tests;

use std::collections::HashMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3, Vec4};
use serde::{Deserialize, Serialize};

use crate::mesh::{MeshModel, Texture, srgb_to_linear};
use crate::scene::{Document, Object, ObjectKind, VoxelModel};
pub use fields::{
    ColoredMesh, FieldError, MAX_RESOLUTION, krs_region, mesh_distance_field, mesh_krs,
};
pub use impostor::{IMPOSTOR_TEXELS, Impostor, krs_impostor};
pub use instances::{InstanceTransform, KernelInstances, MIN_CELLS_ACROSS, krs_instances};
pub use writer::{
    ExportCamera, ExportLight, ExportMaterial, ExportNode, ExportPrimitive, ExportScene, ExportSkin,
};

/// How voxel models become triangles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ExportMode {
    /// Faces between solid voxels and outside air, greedy-merged into quads: exact blocks.
    #[default]
    Cubes,
    /// A smooth closed surface through the voxel centres.
    Smooth,
    /// KRS objects as one mesh per kernel drawn once per kernel instance
    /// (`EXT_mesh_gpu_instancing`); voxel models as in `Cubes`.
    Instances,
}

/// How colours are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ColorMode {
    /// `COLOR_0` vertex colours.
    #[default]
    VertexColors,
    /// A palette texture (one texel per distinct colour) and UVs; no vertex colours.
    PaletteTexture,
}

/// File layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum GltfFormat {
    /// One binary `.glb` file.
    Glb,
    /// A `.gltf` JSON file and a `.bin` buffer beside it (same stem).
    Gltf,
}

impl GltfFormat {
    /// The format a path's extension names (`.glb` or `.gltf`, any case).
    #[must_use]
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "glb" => Some(Self::Glb),
            "gltf" => Some(Self::Gltf),
            _ => None,
        }
    }
}

/// How placements of an instanced KRS object are written.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Instancing {
    /// `EXT_mesh_gpu_instancing`: one node, the placements as accessors. Compact and fast to
    /// draw; a reader without the extension must refuse the file (Blender 3.4 does).
    #[default]
    Gpu,
    /// One child node per placement sharing the mesh: every glTF reader draws it (Blender
    /// makes linked duplicates); levels of detail are left out for those nodes.
    Nodes,
    /// `Nodes` up to [`AUTO_INSTANCE_NODES`] placements in the file, else `Gpu`.
    Auto,
    /// No instancing at all: every placement's copy baked into plain meshes (one per cell
    /// node), for tools that read neither extension nor shared meshes well. Refused before
    /// any copy is made when the copies would pass the triangle limit.
    Flatten,
}

/// Most placements [`Instancing::Auto`] writes as nodes.
pub const AUTO_INSTANCE_NODES: usize = 4096;

/// Most placements [`Instancing::Nodes`] writes (a node each); more are refused.
pub const MAX_INSTANCE_NODES: usize = 1 << 18;

/// Settings of [`export_gltf`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GltfExportOptions {
    /// Voxel meshing.
    pub mode: ExportMode,
    /// Vertex colours or a palette texture.
    pub colors: ColorMode,
    /// Export only the object with this name (hidden or not); `None`: every visible object.
    pub object: Option<String>,
    /// KRS meshing: cells along the longest side of the object's region.
    pub resolution: u32,
    /// Smooth mode: rounds of relaxation.
    pub smoothing: u32,
    /// Instances mode: cells across each kernel's bounding ball (at least; a thin kernel gets
    /// enough for [`MIN_CELLS_ACROSS`] cells across its section).
    pub kernel_resolution: u32,
    /// Most instances one KRS object may have: copies of its prototype (default modes) or of
    /// its kernels (`Instances` mode).
    pub max_instances: usize,
    /// KRS objects: the reflection level where the prototype ends and placement mirrors begin
    /// (see [`KrsObject::prototype`](crate::krs::KrsObject::prototype)); `None`: chosen per
    /// object ([`PreparedObject::auto_placement_level`](crate::krs::PreparedObject)), a level
    /// past an object's mirrors: no instancing for it.
    pub instance_level: Option<usize>,
    /// Unbounded KRS objects (a ground plane, a terrain) are written as the patch
    /// `[min_x, min_z, max_x, max_z]` of this; `None`: the area the other exported objects
    /// cover plus a margin ([`PATCH_MARGIN`]).
    pub bounds: Option<[f32; 4]>,
    /// Write the document's lights (`KHR_lights_punctual`) and its camera.
    pub lights_and_camera: bool,
    /// How placements of instanced KRS objects are written.
    pub instancing: Instancing,
    /// Refuse (before building it) an export with more triangles than this.
    pub max_triangles: u64,
    /// Coarser levels of detail (`MSFT_lod`), each at half the resolution of the one before,
    /// added per static voxel model in `Cubes` mode (the octree one level up, averaged
    /// attributes) and per bounded KRS mesh or instanced prototype in `Cubes` and `Smooth`
    /// modes (the distance field meshed at `resolution / 2^k`, down to
    /// [`MIN_LOD_RESOLUTION`]). 0: none. Needs vertex colours; rigged models get none (their
    /// weights would need a skin per level), and neither do patches of unbounded objects.
    /// Instanced KRS prototypes take [`GltfExportOptions::instanced_lod_levels`] instead.
    pub lod_levels: u8,
    /// Coarser levels of detail of instanced KRS prototypes (a forest's tree), as
    /// `lod_levels` does them, plus the impostor with [`GltfExportOptions::impostor`]. On by
    /// default: a forest drawn with full trees only is not interactive in any viewer.
    pub instanced_lod_levels: u8,
    /// Add an impostor ([`impostor::krs_impostor`]: crossed textured quads) as the coarsest
    /// level of an instanced prototype that has levels of detail.
    pub impostor: bool,
    /// Cells an instanced prototype's placements are split into (a grid over their x-z
    /// extent; each cell a node with its own placements, so a viewer can cull and choose a
    /// level per cell); `None`: [`auto_cell_count`] of the placements.
    pub cells: Option<u32>,
}

impl Default for GltfExportOptions {
    fn default() -> Self {
        Self {
            mode: ExportMode::Cubes,
            colors: ColorMode::VertexColors,
            object: None,
            resolution: 256,
            smoothing: 4,
            kernel_resolution: 24,
            max_instances: 1 << 20,
            instance_level: None,
            bounds: None,
            lights_and_camera: true,
            instancing: Instancing::Gpu,
            // 2^26 triangles: about 2.5 GiB of GLB, under the format's 4 GiB limit.
            max_triangles: 1 << 26,
            lod_levels: 0,
            instanced_lod_levels: 3,
            impostor: true,
            cells: None,
        }
    }
}

/// Peak heap per triangle written of voxel models exported as cubes: greedy quads with
/// their faces, colours and normals, then welding's table of equal vertices. Measured with a
/// counting allocator (`the_export_estimate_holds_the_measured_peak`): up to 410 bytes a
/// triangle past the fixed part (CesiumMan).
pub const EXPORT_BYTES_PER_CUBES_TRIANGLE: u64 = 480;

/// Peak heap per triangle written of smooth surfaces and KRS meshes (the distance field's
/// surface cells, the mesh, welding): 81-125 bytes measured.
pub const EXPORT_BYTES_PER_SMOOTH_TRIANGLE: u64 = 160;

/// Peak heap per triangle of exporting `doc` with `options`: the cubes figure when voxel
/// models are written as cubes, else the smooth one (smooth voxels, KRS and mesh objects).
#[must_use]
pub fn export_triangle_bytes(doc: &Document, options: &GltfExportOptions) -> u64 {
    let cubes = matches!(options.mode, ExportMode::Cubes | ExportMode::Instances)
        && exported(doc, options).any(|o| matches!(o.kind, ObjectKind::Voxels(_)));
    if cubes {
        EXPORT_BYTES_PER_CUBES_TRIANGLE
    } else {
        EXPORT_BYTES_PER_SMOOTH_TRIANGLE
    }
}

/// The objects an export with `options` writes: the named one, or every visible one.
fn exported<'a>(
    doc: &'a Document,
    options: &'a GltfExportOptions,
) -> impl Iterator<Item = &'a Object> + 'a {
    doc.objects.iter().filter(|o| match &options.object {
        Some(name) => o.name == *name,
        None => o.visible,
    })
}

/// Peak heap of an export per voxel of the exported voxel models, on top of the triangles: the
/// exposed-face pass walks every voxel but a static solid's enclosed interior tiles
/// ([`Svo::voxels_but_enclosed`](crate::svo::Svo::voxels_but_enclosed)); 37 bytes each
/// measured on the house, whose 180,202 voxels become 2,586 triangles.
pub const EXPORT_BYTES_PER_VOXEL: u64 = 40;

/// The fixed part of an export's memory: [`EXPORT_BYTES_PER_VOXEL`] for every voxel of the
/// objects `options` exports, plus 1 MiB. The triangles add [`export_triangle_bytes`] each.
#[must_use]
pub fn export_fixed_bytes(doc: &Document, options: &GltfExportOptions) -> u64 {
    let voxels: u64 = exported(doc, options)
        .filter_map(|o| match &o.kind {
            // A static solid's enclosed interior tiles are not walked (`greedy`, `fields`).
            ObjectKind::Voxels(v) if v.svo.has_skin() => Some(v.svo.leaf_count()),
            ObjectKind::Voxels(v) => Some(v.svo.voxels_but_enclosed()),
            _ => None,
        })
        .sum();
    voxels
        .saturating_mul(EXPORT_BYTES_PER_VOXEL)
        .saturating_add(1 << 20)
}

/// The most triangles an export may write within `budget_bytes` of memory:
/// `(budget − fixed) / export_triangle_bytes`, at most `options.max_triangles`; `None`
/// when the fixed part alone is over the budget.
#[must_use]
pub fn triangle_limit_for_memory(
    doc: &Document,
    options: &GltfExportOptions,
    budget_bytes: u64,
) -> Option<u64> {
    let fixed = export_fixed_bytes(doc, options);
    (fixed <= budget_bytes).then(|| {
        ((budget_bytes - fixed) / export_triangle_bytes(doc, options)).min(options.max_triangles)
    })
}

/// Placements per cell [`auto_cell_count`] aims at.
pub const PLACEMENTS_PER_CELL: u64 = 512;

/// Most cells [`auto_cell_count`] chooses (a node, or a plain and a mirrored one, per cell).
pub const MAX_AUTO_CELLS: u32 = 256;

/// Cells for `placements` instances: one per [`PLACEMENTS_PER_CELL`], 1 to
/// [`MAX_AUTO_CELLS`]. The forest's 131,072 trees make 256 cells of about 512.
#[must_use]
pub fn auto_cell_count(placements: u64) -> u32 {
    (placements / PLACEMENTS_PER_CELL).clamp(1, u64::from(MAX_AUTO_CELLS)) as u32
}

/// What an export wrote.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GltfExportReport {
    /// Objects written.
    pub objects: usize,
    /// Triangles written.
    pub triangles: u64,
    /// Vertices written.
    pub vertices: u64,
    /// Bytes written (all files).
    pub bytes: u64,
    /// Files written (the `.gltf` and `.bin`, or the `.glb`).
    pub files: Vec<PathBuf>,
    /// Per voxel object in `Cubes` (and `Instances`) mode: its faces and quads.
    pub voxel_faces: Vec<VoxelFaces>,
    /// Names of objects left out (hidden, empty).
    pub skipped: Vec<String>,
    /// KRS objects written as a prototype mesh drawn once per placement.
    pub instanced: Vec<KrsInstancing>,
    /// Unbounded KRS objects written as a finite patch: (name, min corner, max corner).
    pub patches: Vec<(String, Vec3, Vec3)>,
    /// Objects written with coarser levels of detail (`MSFT_lod`).
    pub levels_of_detail: Vec<LevelsOfDetail>,
    /// Lights written (`KHR_lights_punctual`).
    pub lights: usize,
    /// Whether the document's camera was written.
    pub camera: bool,
    /// How placements were written ([`Instancing::Gpu`], [`Instancing::Nodes`] or
    /// [`Instancing::Flatten`]), with their
    /// count; `None` when nothing was instanced.
    pub placements: Option<(Instancing, usize)>,
    /// Objects written with their keyed transforms as a node animation.
    pub animated: Vec<String>,
    /// Objects whose keyed transforms were not written, with why.
    pub motion_left_out: Vec<(String, String)>,
}

/// The cube surface of one voxel object: unit faces and the quads they merged into.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct VoxelFaces {
    /// The object.
    pub object: String,
    /// Unit faces that look outside: what is written (two triangles each, before merging).
    pub exposed: u64,
    /// Unit faces that look into a sealed cavity (empty voxels enclosed by solid ones, such as
    /// the inside of a surface-voxelized import): never written.
    pub sealed: u64,
    /// Quads after greedy merging (two triangles each).
    pub quads: u64,
}

/// How a KRS object was instanced: its prototype (reflection levels `0..=level`) meshed once,
/// and drawn at each of its placements.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct KrsInstancing {
    /// The object.
    pub object: String,
    /// The reflection level where the prototype ends.
    pub level: usize,
    /// Placements in all (`2^(mirrors − level)`).
    pub instances: u64,
    /// Of them, mirrored ones (drawn with the mirrored prototype mesh).
    pub mirrored: u64,
    /// Triangles of the prototype mesh (the mirrored one has as many).
    pub prototype_triangles: u64,
    /// Grid cells the placements were split into (columns along x, rows along z); each cell
    /// is a node with its placements (two: plain and mirrored).
    pub cells: [u32; 2],
    /// Instance nodes written (cells with plain placements plus cells with mirrored ones).
    pub cell_nodes: u32,
    /// Whether the coarsest level of detail is an impostor (crossed textured quads).
    pub impostor: bool,
}

/// The levels of detail one object was written with.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LevelsOfDetail {
    /// The object.
    pub object: String,
    /// Triangles of the full mesh, then of each coarser level, finest first (of one copy: an
    /// instanced prototype's mirrored mesh has as many).
    pub triangles: Vec<u64>,
}

impl LevelsOfDetail {
    /// The levels of `node` (none when it has no coarser ones).
    fn of(object: &str, node: &ExportNode) -> Option<Self> {
        let count = |prims: &[ExportPrimitive]| -> u64 {
            prims.iter().map(|p| p.indices.len() as u64 / 3).sum()
        };
        (!node.lods.is_empty()).then(|| Self {
            object: object.to_owned(),
            triangles: std::iter::once(count(&node.primitives))
                .chain(node.lods.iter().map(|l| count(l)))
                .collect(),
        })
    }
}

/// Margin around the other objects' area that an unbounded object's patch adds on each side,
/// as a fraction of that area's larger side (at least one unit).
pub const PATCH_MARGIN: f32 = 0.1;

/// Why an export failed. Nothing is left on disk when it does.
#[derive(Debug, thiserror::Error)]
pub enum GltfExportError {
    /// Nothing to export: no visible object with geometry, an unknown or empty object.
    #[error("{}: nothing to export: {detail}", path.display())]
    NothingToExport {
        /// The target file.
        path: PathBuf,
        /// Why.
        detail: String,
    },
    /// An object cannot be exported as it is.
    #[error("{}: object {object:?}: {detail}", path.display())]
    Object {
        /// The target file.
        path: PathBuf,
        /// The object.
        object: String,
        /// What is wrong.
        detail: String,
    },
    /// The export would be too large (checked before allocating).
    #[error("{}: too large: {detail}", path.display())]
    TooLarge {
        /// The target file.
        path: PathBuf,
        /// What and the limit.
        detail: String,
    },
    /// The path does not name a `.glb` or `.gltf` file.
    #[error("{}: unsupported: {detail}", path.display())]
    Unsupported {
        /// The target file.
        path: PathBuf,
        /// What.
        detail: String,
    },
    /// The operating system refused.
    #[error("{}: {action}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done.
        action: &'static str,
        /// Its error.
        #[source]
        source: std::io::Error,
    },
    /// The progress callback asked to stop.
    #[error("{}: export cancelled", path.display())]
    Cancelled {
        /// The target file.
        path: PathBuf,
    },
}

/// Exports `doc` to `path` (`.glb` or `.gltf`, by extension).
///
/// `progress(fraction)` is called now and then from the calling thread; returning `false`
/// cancels. The report says what was written.
///
/// # Errors
/// [`GltfExportError`]; on any error no file is created or changed.
pub fn export_gltf(
    doc: &Document,
    path: &Path,
    options: &GltfExportOptions,
    progress: &dyn Fn(f32) -> bool,
) -> Result<GltfExportReport, GltfExportError> {
    let format = GltfFormat::from_path(path).ok_or_else(|| GltfExportError::Unsupported {
        path: path.to_owned(),
        detail: "the file name must end in .glb or .gltf".to_owned(),
    })?;
    let (scene, mut report) = build_scene(doc, path, options, &|f| progress(f * 0.9))?;
    let files = write_scene(&scene, path, format)?;
    report.bytes = files.iter().map(|f| f.1).sum();
    report.files = files.into_iter().map(|f| f.0).collect();
    progress(1.0);
    Ok(report)
}

/// Encodes an [`ExportScene`] as GLB bytes (for tests and in-memory use).
///
/// # Errors
/// [`GltfExportError::TooLarge`] past glTF's 32-bit sizes, [`GltfExportError::Object`] for
/// inconsistent primitives; `path` only names the target in messages.
pub fn encode_glb(scene: &ExportScene, path: &Path) -> Result<Vec<u8>, GltfExportError> {
    let encoded = writer::encode(scene, None, generator()).map_err(|e| encode_error(path, e))?;
    writer::glb(&encoded).map_err(|e| encode_error(path, e))
}

fn generator() -> &'static str {
    concat!("Thicket ", env!("CARGO_PKG_VERSION"))
}

fn encode_error(path: &Path, e: writer::EncodeError) -> GltfExportError {
    match e {
        writer::EncodeError::TooLarge(detail) => GltfExportError::TooLarge {
            path: path.to_owned(),
            detail,
        },
        writer::EncodeError::Invalid(detail) | writer::EncodeError::Encoding(detail) => {
            GltfExportError::Object {
                path: path.to_owned(),
                object: String::new(),
                detail,
            }
        }
    }
}

/// Writes the scene; returns each file written with its size.
fn write_scene(
    scene: &ExportScene,
    path: &Path,
    format: GltfFormat,
) -> Result<Vec<(PathBuf, u64)>, GltfExportError> {
    match format {
        GltfFormat::Glb => {
            let bytes = encode_glb(scene, path)?;
            write_atomic(path, &[(path, &bytes)])?;
            Ok(vec![(path.to_owned(), bytes.len() as u64)])
        }
        GltfFormat::Gltf => {
            let bin_path = path.with_extension("bin");
            let bin_name = bin_path
                .file_name()
                .and_then(|n| n.to_str())
                .ok_or_else(|| GltfExportError::Unsupported {
                    path: path.to_owned(),
                    detail: "the file name is not valid UTF-8".to_owned(),
                })?
                .to_owned();
            // The URI is relative to the .gltf; percent-encode what a URI cannot hold.
            let uri: String = bin_name
                .bytes()
                .map(|b| match b {
                    b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => {
                        char::from(b).to_string()
                    }
                    _ => format!("%{b:02X}"),
                })
                .collect();
            let encoded = writer::encode(scene, Some(&uri), generator())
                .map_err(|e| encode_error(path, e))?;
            let mut files: Vec<(&Path, &[u8])> = Vec::new();
            if !encoded.bin.is_empty() {
                files.push((&bin_path, &encoded.bin));
            }
            files.push((path, &encoded.json));
            write_atomic(path, &files)?;
            Ok(files
                .iter()
                .map(|(p, b)| (p.to_path_buf(), b.len() as u64))
                .collect())
        }
    }
}

/// Writes each `(file, bytes)` to a temporary sibling, syncs them all, then renames them into
/// place in order (the `.bin` before the `.gltf` that names it) and syncs the directory. On any
/// failure before the renames every temporary file is removed and no target is touched. A
/// target that is a folder is refused before the first rename (its rename would fail after the
/// `.bin`'s); should a later rename still fail, the files this call already renamed into place
/// are removed too, so a failed export leaves no `.bin` without its `.gltf`.
fn write_atomic(target: &Path, files: &[(&Path, &[u8])]) -> Result<(), GltfExportError> {
    let io = |path: &Path, action, source| GltfExportError::Io {
        path: path.to_owned(),
        action,
        source,
    };
    let dir = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let tmp_of = |p: &Path| {
        let name = p
            .file_name()
            .map_or_else(|| "export".into(), |n| n.to_string_lossy().into_owned());
        dir.join(format!(".{name}.tmp-{}", std::process::id()))
    };
    let mut written: Vec<PathBuf> = Vec::new();
    let mut renamed: Vec<PathBuf> = Vec::new();
    let result = (|| {
        for (p, bytes) in files {
            let tmp = tmp_of(p);
            let mut f =
                std::fs::File::create(&tmp).map_err(|e| io(p, "creating the temporary file", e))?;
            written.push(tmp.clone());
            f.write_all(bytes)
                .map_err(|e| io(p, "writing the temporary file", e))?;
            f.sync_all()
                .map_err(|e| io(p, "syncing the temporary file", e))?;
        }
        for (p, _) in files {
            if std::fs::symlink_metadata(p).is_ok_and(|m| m.is_dir()) {
                return Err(io(
                    p,
                    "replacing the target",
                    std::io::Error::new(std::io::ErrorKind::IsADirectory, "it is a folder"),
                ));
            }
        }
        for (p, _) in files {
            std::fs::rename(tmp_of(p), p).map_err(|e| io(p, "renaming the temporary file", e))?;
            renamed.push(p.to_path_buf());
        }
        Ok(())
    })();
    if result.is_err() {
        // Best effort: the error that matters is the one returned.
        for file in written.iter().chain(&renamed) {
            let _ = std::fs::remove_file(file);
        }
        return result;
    }
    if let Ok(d) = std::fs::File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Builds the scene to write: one node per exported object.
///
/// # Errors
/// See [`export_gltf`]; `path` only names the target in messages.
pub fn build_scene(
    doc: &Document,
    path: &Path,
    options: &GltfExportOptions,
    progress: &dyn Fn(f32) -> bool,
) -> Result<(ExportScene, GltfExportReport), GltfExportError> {
    let mut report = GltfExportReport::default();
    let chosen: Vec<&Object> = match &options.object {
        Some(name) => {
            let o = doc
                .object_by_name(name)
                .ok_or_else(|| GltfExportError::NothingToExport {
                    path: path.to_owned(),
                    detail: format!(
                        "no object named {name:?}; the document has: {}",
                        doc.objects
                            .iter()
                            .map(|o| format!("{:?}", o.name))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                })?;
            vec![o]
        }
        None => {
            let (shown, hidden): (Vec<&Object>, Vec<&Object>) =
                doc.objects.iter().partition(|o| o.visible);
            report.skipped = hidden.iter().map(|o| o.name.clone()).collect();
            shown
        }
    };
    if options.lod_levels > 0 && options.colors == ColorMode::PaletteTexture {
        return Err(GltfExportError::Unsupported {
            path: path.to_owned(),
            detail: "levels of detail need vertex colours, not a palette texture".to_owned(),
        });
    }
    let mut out = SceneBuilder {
        scene: ExportScene::default(),
        materials: HashMap::new(),
        palette: Palette::default(),
        options,
    };
    let mut budget = options.max_triangles;
    let total = chosen.len().max(1) as f32;
    let mut unbounded: Vec<(&Object, crate::krs::PreparedObject)> = Vec::new();
    for (i, o) in chosen.iter().enumerate() {
        let object_error = |detail: String| GltfExportError::Object {
            path: path.to_owned(),
            object: o.name.clone(),
            detail,
        };
        o.transform
            .validate(&o.name)
            .map_err(|e| object_error(e.to_string()))?;
        let node = match &o.kind {
            ObjectKind::Voxels(v) => {
                if v.svo.is_empty() {
                    if options.object.is_some() {
                        return Err(GltfExportError::NothingToExport {
                            path: path.to_owned(),
                            detail: format!("object {:?} has no voxels", o.name),
                        });
                    }
                    report.skipped.push(o.name.clone());
                    continue;
                }
                if !(v.voxel_size.is_finite() && v.voxel_size > 0.0 && v.origin.is_finite()) {
                    return Err(object_error(format!(
                        "voxel size {} and origin {} must be finite (size positive)",
                        v.voxel_size, v.origin
                    )));
                }
                out.voxel_node(o, v, path, &mut budget, &mut report)?
            }
            ObjectKind::Mesh(m) => {
                if m.model.parts.iter().all(|p| p.indices.is_empty()) {
                    if options.object.is_some() {
                        return Err(GltfExportError::NothingToExport {
                            path: path.to_owned(),
                            detail: format!("object {:?} has no triangles", o.name),
                        });
                    }
                    report.skipped.push(o.name.clone());
                    continue;
                }
                m.model
                    .validate()
                    .map_err(|(part, e)| object_error(format!("mesh part {part}: {e}")))?;
                let tris = m
                    .model
                    .parts
                    .iter()
                    .map(|p| p.triangle_count() as u64)
                    .sum();
                charge(&mut budget, tris, options, path, &o.name)?;
                out.mesh_node(o, &m.model)
            }
            ObjectKind::Krs(_) => {
                // Meshed in world space (the object's transform composed with the KRS's own
                // placement); its nodes carry the identity transform.
                let krs = o.krs_in_world().ok_or_else(|| {
                    object_error("a KRS object's scale must be uniform and positive".to_owned())
                })?;
                let prepared = crate::krs::KrsScene { objects: vec![krs] }
                    .prepare()
                    .map_err(|e| object_error(e.to_string()))?;
                let object = prepared.objects.into_iter().next().ok_or_else(|| {
                    object_error("the KRS object could not be prepared".to_owned())
                })?;
                if o.motion.is_some() {
                    report.motion_left_out.push((
                        o.name.clone(),
                        "a KRS object is meshed in world space at its current placement".to_owned(),
                    ));
                }
                if object.bound_world.is_none()
                    && matches!(fields::krs_region(&object), Err(FieldError::Unbounded(_)))
                {
                    // A ground: written once the other objects say how much of it to cut.
                    unbounded.push((o, object));
                    continue;
                }
                let krs_options = GltfExportOptions {
                    max_triangles: budget,
                    ..options.clone()
                };
                let first = out.scene.nodes.len();
                let (tris, instancing) =
                    add_krs_object(&mut out.scene, &o.name, &object, &krs_options, &|_| true)
                        .map_err(|e| field_error(path, &o.name, &e))?;
                report.levels_of_detail.extend(
                    out.scene
                        .nodes
                        .get(first)
                        .and_then(|n| LevelsOfDetail::of(&o.name, n)),
                );
                charge(&mut budget, tris, options, path, &o.name)?;
                report.instanced.extend(instancing);
                report.objects += 1;
                if !progress((i + 1) as f32 / total) {
                    return Err(GltfExportError::Cancelled {
                        path: path.to_owned(),
                    });
                }
                continue;
            }
        };
        report
            .levels_of_detail
            .extend(LevelsOfDetail::of(&o.name, &node));
        let mut node = node;
        if let Some(m) = &o.motion {
            if node.lods.is_empty() {
                node.motion = Some(m.clip.clone());
                report.animated.push(o.name.clone());
            } else {
                report.motion_left_out.push((
                    o.name.clone(),
                    "its levels of detail are separate nodes that would not follow".to_owned(),
                ));
            }
        }
        out.scene.nodes.push(node);
        report.objects += 1;
        if !progress((i + 1) as f32 / total) {
            return Err(GltfExportError::Cancelled {
                path: path.to_owned(),
            });
        }
    }
    if !unbounded.is_empty() {
        let (xz_lo, xz_hi, y_top) = patch_area(&out.scene, options, path, &unbounded[0].0.name)?;
        for (o, object) in unbounded {
            let (lo, hi) =
                fields::krs_patch_region(&object, xz_lo, xz_hi, y_top, options.resolution)
                    .map_err(|e| field_error(path, &o.name, &e))?;
            let krs_options = GltfExportOptions {
                max_triangles: budget,
                ..options.clone()
            };
            let tris = add_krs_patch(
                &mut out.scene,
                &o.name,
                &object,
                lo,
                hi,
                &krs_options,
                &|_| true,
            )
            .map_err(|e| field_error(path, &o.name, &e))?;
            charge(&mut budget, tris, options, path, &o.name)?;
            report.patches.push((o.name.clone(), lo, hi));
            report.objects += 1;
        }
    }
    if out.scene.nodes.is_empty() {
        return Err(GltfExportError::NothingToExport {
            path: path.to_owned(),
            detail: if doc.objects.is_empty() {
                "the document has no objects".to_owned()
            } else {
                format!(
                    "every object is hidden or empty ({})",
                    report.skipped.join(", ")
                )
            },
        });
    }
    let placements: usize = out.scene.nodes.iter().map(|n| n.instances.len()).sum();
    if placements > 0 && options.instancing == Instancing::Flatten {
        flatten_instances(&mut out.scene, options.max_triangles).map_err(|detail| {
            GltfExportError::TooLarge {
                path: path.to_owned(),
                detail,
            }
        })?;
        // The copies are plain meshes now: no levels of detail, no impostor.
        let instanced = &report.instanced;
        report
            .levels_of_detail
            .retain(|l| !instanced.iter().any(|k| k.object == l.object));
        report.placements = Some((Instancing::Flatten, placements));
    } else if placements > 0 {
        let nodes = match options.instancing {
            Instancing::Gpu | Instancing::Flatten => false,
            Instancing::Nodes => true,
            Instancing::Auto => placements <= AUTO_INSTANCE_NODES,
        };
        if nodes && placements > MAX_INSTANCE_NODES {
            return Err(GltfExportError::Unsupported {
                path: path.to_owned(),
                detail: format!(
                    "{placements} placements would be {placements} nodes (at most \
                     {MAX_INSTANCE_NODES}): write them with EXT_mesh_gpu_instancing \
                     (--instancing gpu), or export fewer (a smaller forest, --object)"
                ),
            });
        }
        out.scene.instance_nodes = nodes;
        if nodes {
            // MSFT_lod would need level nodes per placement: instanced nodes keep their full
            // mesh only.
            for n in out
                .scene
                .nodes
                .iter_mut()
                .filter(|n| !n.instances.is_empty())
            {
                n.lods.clear();
            }
            let instanced = &report.instanced;
            report
                .levels_of_detail
                .retain(|l| !instanced.iter().any(|k| k.object == l.object));
        }
        report.placements = Some((
            if nodes {
                Instancing::Nodes
            } else {
                Instancing::Gpu
            },
            placements,
        ));
    }
    if options.lights_and_camera {
        out.scene.lights = doc
            .lights
            .iter()
            .filter(|l| l.validate().is_ok())
            .map(|l| ExportLight {
                name: l.name.clone(),
                direction: l.direction,
                color: l.color,
                intensity: l.intensity,
            })
            .collect();
        report.lights = out.scene.lights.len();
        let c = &doc.camera;
        if c.validate().is_ok() {
            let world_from_view = c.view_from_world().inverse();
            let (_, rotation, _) = world_from_view.to_scale_rotation_translation();
            // glTF's near plane is a distance in front of the camera node: an orthographic
            // view whose near plane lies behind its eye is written from a point pulled back
            // along the view axis (the same parallel view).
            let pull = if c.orthographic {
                (1e-3 * c.distance - c.near).max(0.0)
            } else {
                0.0
            };
            let back = (c.eye() - c.target).normalize_or_zero();
            out.scene.camera = Some(ExportCamera {
                name: "camera".to_owned(),
                eye: c.eye() + back * pull,
                rotation,
                yfov_radians: c.fov_y_deg.to_radians(),
                znear: c.near + pull,
                zfar: c.far + pull,
                ortho_half_height: c.orthographic.then(|| c.ortho_half_height()),
            });
            report.camera = true;
        }
    }
    out.finish_palette();
    out.scene.weld();
    report.triangles = out.scene.triangle_count();
    report.vertices = out.scene.vertex_count();
    Ok((out.scene, report))
}

/// Bakes every node's placements into its own primitives ([`Instancing::Flatten`]): each
/// placement's copy of the node's mesh (or of the mesh it draws from another node) moved by
/// the placement, merged per primitive; the node's placements and levels of detail go. The
/// triangles of all copies are counted against `max_triangles` before any is made.
///
/// # Errors
/// The count and the limit, with what would lower it.
fn flatten_instances(scene: &mut ExportScene, max_triangles: u64) -> Result<(), String> {
    // The primitives node `i` draws: its own, or those of the node it shares a mesh with.
    let drawn = |scene: &ExportScene, i: usize| -> usize { scene.nodes[i].mesh_from.unwrap_or(i) };
    let total = scene
        .nodes
        .iter()
        .enumerate()
        .fold(0u64, |total, (i, node)| {
            let tris: u64 = scene.nodes[drawn(scene, i)]
                .primitives
                .iter()
                .map(|p| p.indices.len() as u64 / 3)
                .sum();
            total.saturating_add(tris.saturating_mul(node.instances.len().max(1) as u64))
        });
    if total > max_triangles {
        return Err(format!(
            "flattening writes every placement's copy: {} triangles, over the limit of {}; \
             export fewer placements (a higher --instance-level), a coarser mesh \
             (--resolution), or keep the placements instanced (--instancing nodes or gpu)",
            crate::budget::thousands(total),
            crate::budget::thousands(max_triangles)
        ));
    }
    let sources: Vec<Option<Vec<ExportPrimitive>>> = (0..scene.nodes.len())
        .map(|i| {
            (!scene.nodes[i].instances.is_empty())
                .then(|| scene.nodes[drawn(scene, i)].primitives.clone())
        })
        .collect();
    // Nodes drawing a flattened node's mesh get their own copy of the plain mesh first.
    for i in 0..scene.nodes.len() {
        if let Some(j) = scene.nodes[i].mesh_from
            && sources[j].is_some()
            && sources[i].is_none()
        {
            scene.nodes[i].primitives = sources[j].clone().unwrap_or_default();
            scene.nodes[i].mesh_from = None;
        }
    }
    for (i, prims) in sources.into_iter().enumerate() {
        let Some(prims) = prims else {
            continue;
        };
        let node = &mut scene.nodes[i];
        let placements = std::mem::take(&mut node.instances);
        node.primitives = prims
            .iter()
            .map(|p| {
                let mut out = ExportPrimitive {
                    material: p.material,
                    ..ExportPrimitive::default()
                };
                for t in &placements {
                    let base = out.positions.len() as u32;
                    out.positions
                        .extend(p.positions.iter().map(|&v| t.transform_point(v)));
                    out.normals.extend(
                        p.normals
                            .iter()
                            .map(|&n| (t.rotation * n).normalize_or_zero()),
                    );
                    out.colors.extend_from_slice(&p.colors);
                    out.uvs.extend_from_slice(&p.uvs);
                    out.skin.extend_from_slice(&p.skin);
                    out.indices.extend(p.indices.iter().map(|&k| base + k));
                }
                out
            })
            .collect();
        node.lods.clear();
        node.mesh_from = None;
    }
    Ok(())
}

/// The (x, z) area an unbounded object's patch covers and a height above the scene:
/// `options.bounds`, or the exported nodes' area plus [`PATCH_MARGIN`].
fn patch_area(
    scene: &ExportScene,
    options: &GltfExportOptions,
    path: &Path,
    object: &str,
) -> Result<(Vec2, Vec2, f32), GltfExportError> {
    let mut lo = Vec3::INFINITY;
    let mut hi = Vec3::NEG_INFINITY;
    for b in scene.nodes.iter().filter_map(|n| node_bounds(scene, n)) {
        lo = lo.min(b.0);
        hi = hi.max(b.1);
    }
    let y_top = if hi.y.is_finite() { hi.y } else { 0.0 };
    if let Some([x0, z0, x1, z1]) = options.bounds {
        if !([x0, z0, x1, z1].iter().all(|v| v.is_finite()) && x0 < x1 && z0 < z1) {
            return Err(GltfExportError::Unsupported {
                path: path.to_owned(),
                detail: format!(
                    "patch bounds {x0},{z0},{x1},{z1} (--bounds MINX,MINZ,MAXX,MAXZ) must be \
                     finite with MINX < MAXX and MINZ < MAXZ"
                ),
            });
        }
        return Ok((Vec2::new(x0, z0), Vec2::new(x1, z1), y_top));
    }
    if !lo.cmple(hi).all() {
        return Err(GltfExportError::Object {
            path: path.to_owned(),
            object: object.to_owned(),
            detail: "it is unbounded (a ground plane or terrain) and no other exported object \
                     says how much of it to write; give the patch with --bounds \
                     MINX,MINZ,MAXX,MAXZ"
                .to_owned(),
        });
    }
    let (lo, hi) = (Vec2::new(lo.x, lo.z), Vec2::new(hi.x, hi.z));
    let margin = Vec2::splat(((hi - lo).max_element() * PATCH_MARGIN).max(1.0));
    Ok((lo - margin, hi + margin, y_top))
}

/// Takes `n` triangles from the budget or refuses with the limit in the message.
fn charge(
    budget: &mut u64,
    n: u64,
    options: &GltfExportOptions,
    path: &Path,
    object: &str,
) -> Result<(), GltfExportError> {
    if n > *budget {
        return Err(GltfExportError::TooLarge {
            path: path.to_owned(),
            detail: format!(
                "object {object:?} needs {n} triangles; the export may have at most {} in all \
                 (raise it with --max-triangles, or lower --resolution)",
                options.max_triangles
            ),
        });
    }
    *budget -= n;
    Ok(())
}

/// sRGB RGBA8 → linear RGBA.
pub(crate) fn linear(c: [u8; 4]) -> Vec4 {
    Vec4::new(
        srgb_to_linear(f32::from(c[0]) / 255.0),
        srgb_to_linear(f32::from(c[1]) / 255.0),
        srgb_to_linear(f32::from(c[2]) / 255.0),
        f32::from(c[3]) / 255.0,
    )
}

/// Distinct colours of a palette texture; UVs are filled in once every colour is known.
#[derive(Default)]
struct Palette {
    index: HashMap<[u8; 4], u32>,
    colors: Vec<[u8; 4]>,
    /// (node, primitive, per-vertex palette index) to turn into UVs at the end.
    pending: Vec<(usize, usize, Vec<u32>)>,
    material_ids: Vec<usize>,
}

impl Palette {
    fn add(&mut self, c: [u8; 4]) -> u32 {
        *self.index.entry(c).or_insert_with(|| {
            self.colors.push(c);
            (self.colors.len() - 1) as u32
        })
    }

    /// Texture width: up to 256 texels a row.
    fn width(&self) -> u32 {
        (self.colors.len() as u32).clamp(1, 256)
    }

    fn texture(&self) -> Texture {
        let w = self.width();
        let h = (self.colors.len() as u32).div_ceil(w).max(1);
        let mut rgba8 = vec![255u8; (w * h * 4) as usize];
        for (i, c) in self.colors.iter().enumerate() {
            rgba8[i * 4..i * 4 + 4].copy_from_slice(c);
        }
        Texture {
            width: w,
            height: h,
            rgba8,
        }
    }

    /// The centre of texel `i`, so nearest filtering reads exactly that colour.
    fn uv(&self, i: u32) -> Vec2 {
        let w = self.width();
        let h = (self.colors.len() as u32).div_ceil(w).max(1);
        Vec2::new(
            ((i % w) as f32 + 0.5) / w as f32,
            ((i / w) as f32 + 0.5) / h as f32,
        )
    }
}

struct SceneBuilder<'o> {
    scene: ExportScene,
    /// (material name, palette-textured) → index, so objects share materials by name.
    materials: HashMap<(String, bool), usize>,
    palette: Palette,
    options: &'o GltfExportOptions,
}

impl SceneBuilder<'_> {
    fn material(
        &mut self,
        name: &str,
        palette: bool,
        make: impl FnOnce() -> ExportMaterial,
    ) -> usize {
        let key = (name.to_owned(), palette);
        if let Some(&i) = self.materials.get(&key) {
            return i;
        }
        let i = self.scene.materials.len();
        let mut m = make();
        m.name = name.to_owned();
        self.scene.materials.push(m);
        self.materials.insert(key, i);
        if palette {
            self.palette.material_ids.push(i);
        }
        i
    }

    /// The glTF material for a voxel material id.
    fn voxel_material(&mut self, v: &VoxelModel, id: u8) -> usize {
        let name = v
            .material_names
            .get(usize::from(id))
            .filter(|n| !n.is_empty())
            .cloned()
            .unwrap_or_else(|| format!("voxel material {id}"));
        let palette = self.options.colors == ColorMode::PaletteTexture;
        self.material(&name, palette, || ExportMaterial {
            nearest: palette,
            ..ExportMaterial::default()
        })
    }

    fn voxel_node(
        &mut self,
        o: &Object,
        v: &VoxelModel,
        path: &Path,
        budget: &mut u64,
        report: &mut GltfExportReport,
    ) -> Result<ExportNode, GltfExportError> {
        let to_object = |p: Vec3| v.origin + p * v.voxel_size;
        // Per material id: (positions, normals, colours).
        let mut by_material: Vec<(u8, ExportPrimitive, Vec<u32>)> = Vec::new();
        let prim_for = |id: u8, by_material: &mut Vec<(u8, ExportPrimitive, Vec<u32>)>| {
            if let Some(i) = by_material.iter().position(|e| e.0 == id) {
                i
            } else {
                by_material.push((id, ExportPrimitive::default(), Vec::new()));
                by_material.len() - 1
            }
        };
        match self.options.mode {
            ExportMode::Cubes | ExportMode::Instances => {
                // Count first: refuses a huge model before any face list is built.
                let faces = greedy::count_faces(&v.svo);
                charge(
                    &mut { *budget },
                    faces.exposed.saturating_mul(2),
                    self.options,
                    path,
                    &o.name,
                )?;
                let quads = greedy::greedy_quads(&v.svo);
                let tris = quads.len() as u64 * 2;
                charge(budget, tris, self.options, path, &o.name)?;
                report.voxel_faces.push(VoxelFaces {
                    object: o.name.clone(),
                    exposed: faces.exposed,
                    sealed: faces.sealed,
                    quads: quads.len() as u64,
                });
                for q in &quads {
                    let i = prim_for(q.key.1, &mut by_material);
                    let (_, prim, pal) = &mut by_material[i];
                    let base = prim.positions.len() as u32;
                    // No NORMAL: readers compute the flat normals cube faces have (the glTF
                    // specification requires it), so quads of one colour share corners across
                    // the faces' edges too (`ExportPrimitive::weld`).
                    prim.positions.extend(q.corners().map(to_object));
                    if v.rig.is_some() {
                        // One weight set per lattice corner: every vertex at a position agrees.
                        prim.skin.extend(q.corner_skins());
                    }
                    match self.options.colors {
                        ColorMode::VertexColors => prim.colors.extend([linear(q.key.0); 4]),
                        ColorMode::PaletteTexture => {
                            let p = self.palette.add(q.key.0);
                            pal.extend([p; 4]);
                        }
                    }
                    prim.indices
                        .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
                }
            }
            ExportMode::Smooth => {
                let mesh = fields::mesh_voxels_smooth(&v.svo, self.options.smoothing, *budget)
                    .map_err(|e| field_error(path, &o.name, &e))?;
                charge(
                    budget,
                    mesh.triangle_count() as u64,
                    self.options,
                    path,
                    &o.name,
                )?;
                // Smooth surfaces blend across materials; one primitive, material of the first
                // voxel's id.
                let id = v.svo.first_voxel().map_or(0, |l| l.material);
                let i = prim_for(id, &mut by_material);
                let (_, prim, pal) = &mut by_material[i];
                prim.positions = mesh.positions.iter().map(|&p| to_object(p)).collect();
                prim.normals = mesh.normals;
                prim.indices = mesh.indices;
                match self.options.colors {
                    ColorMode::VertexColors => prim.colors = mesh.colors,
                    ColorMode::PaletteTexture => {
                        for c in &mesh.colors {
                            let s = |x: f32| (crate::mesh::linear_to_srgb(x) * 255.0).round() as u8;
                            let p = self.palette.add([
                                s(c.x),
                                s(c.y),
                                s(c.z),
                                (c.w * 255.0).round() as u8,
                            ]);
                            pal.push(p);
                        }
                    }
                }
            }
        }
        by_material.sort_by_key(|e| e.0);
        let node_index = self.scene.nodes.len();
        let mut primitives = Vec::with_capacity(by_material.len());
        for (pi, (id, mut prim, pal)) in by_material.into_iter().enumerate() {
            prim.material = self.voxel_material(v, id);
            if !pal.is_empty() {
                self.palette.pending.push((node_index, pi, pal));
            }
            primitives.push(prim);
        }
        // Cube corners carry the merged weights of the voxels meeting there (see `greedy`); a
        // smooth surface has no voxel corners to weight, so it is exported as the bind pose
        // without a skeleton.
        let skin = match (&v.rig, self.options.mode) {
            (Some(rig), ExportMode::Cubes | ExportMode::Instances) => Some(ExportSkin {
                skeleton: rig.skeleton.clone(),
                clips: rig.clips.clone(),
            }),
            _ => None,
        };
        let mut lods = Vec::new();
        if self.options.mode == ExportMode::Cubes && v.rig.is_none() {
            for k in 1..=self.options.lod_levels.min(v.svo.depth().saturating_sub(1)) {
                let coarse = v.svo.coarsened(k).map_err(|e| GltfExportError::Object {
                    path: path.to_owned(),
                    object: o.name.clone(),
                    detail: format!("level of detail {k}: {e}"),
                })?;
                let size = v.voxel_size * f32::from(1u16 << k);
                let quads = greedy::greedy_quads(&coarse);
                charge(budget, quads.len() as u64 * 2, self.options, path, &o.name)?;
                let mut level: Vec<(u8, ExportPrimitive)> = Vec::new();
                for q in &quads {
                    let i = match level.iter().position(|e| e.0 == q.key.1) {
                        Some(i) => i,
                        None => {
                            level.push((q.key.1, ExportPrimitive::default()));
                            level.len() - 1
                        }
                    };
                    let prim = &mut level[i].1;
                    let base = prim.positions.len() as u32;
                    prim.positions
                        .extend(q.corners().map(|c| v.origin + c * size));
                    prim.colors.extend([linear(q.key.0); 4]);
                    prim.indices
                        .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
                }
                level.sort_by_key(|e| e.0);
                let mut prims = Vec::with_capacity(level.len());
                for (id, mut prim) in level {
                    prim.material = self.voxel_material(v, id);
                    prims.push(prim);
                }
                lods.push(prims);
            }
        }
        Ok(ExportNode {
            name: o.name.clone(),
            transform: o.transform,
            primitives,
            instances: Vec::new(),
            skin,
            lods,
            mesh_from: None,
            motion: None,
        })
    }

    fn mesh_node(&mut self, o: &Object, model: &MeshModel) -> ExportNode {
        let mut primitives = Vec::with_capacity(model.parts.len());
        for part in &model.parts {
            if part.indices.is_empty() {
                continue;
            }
            let src = model.materials.get(part.material);
            let name = src
                .map(|m| m.name.clone())
                .filter(|n| !n.is_empty())
                .unwrap_or_else(|| format!("{} material {}", o.name, part.material));
            // An open mesh (a ground plane) should be visible from below as it is in the editor.
            let material = self.material(&name, false, || ExportMaterial {
                base_color: src.map_or(Vec4::ONE, |m| m.base_color),
                texture: src.and_then(|m| m.base_color_texture.clone()),
                nearest: false,
                double_sided: true,
                ..ExportMaterial::default()
            });
            let has_texture = src.is_some_and(|m| m.base_color_texture.is_some());
            primitives.push(ExportPrimitive {
                positions: part.positions.clone(),
                normals: part.normals.clone(),
                colors: part.colors.clone(),
                // UVs only matter with a texture; without one they are dead weight.
                uvs: if has_texture {
                    part.uvs.clone()
                } else {
                    Vec::new()
                },
                indices: part.indices.clone(),
                material,
                skin: Vec::new(),
            });
        }
        ExportNode {
            name: o.name.clone(),
            transform: o.transform,
            primitives,
            ..ExportNode::default()
        }
    }

    /// Turns pending palette indices into UVs and gives palette materials the texture.
    fn finish_palette(&mut self) {
        if self.palette.colors.is_empty() {
            return;
        }
        let texture = self.palette.texture();
        for &m in &self.palette.material_ids {
            self.scene.materials[m].texture = Some(texture.clone());
        }
        for (node, prim, indices) in std::mem::take(&mut self.palette.pending) {
            let uvs = indices.iter().map(|&i| self.palette.uv(i)).collect();
            self.scene.nodes[node].primitives[prim].uvs = uvs;
        }
    }
}

fn field_error(path: &Path, object: &str, e: &FieldError) -> GltfExportError {
    match e {
        FieldError::TooManyTriangles { .. } => GltfExportError::TooLarge {
            path: path.to_owned(),
            detail: format!("object {object:?}: {e}"),
        },
        FieldError::Empty => GltfExportError::NothingToExport {
            path: path.to_owned(),
            detail: format!("object {object:?}: {e}"),
        },
        FieldError::Cancelled => GltfExportError::Cancelled {
            path: path.to_owned(),
        },
        FieldError::TooManyInstances { .. } => GltfExportError::TooLarge {
            path: path.to_owned(),
            detail: format!("object {object:?}: {e}"),
        },
        FieldError::BadResolution(_)
        | FieldError::Unbounded(_)
        | FieldError::BadInstanceLevel(_)
        | FieldError::Impostor(_) => GltfExportError::Object {
            path: path.to_owned(),
            object: object.to_owned(),
            detail: e.to_string(),
        },
    }
}

/// Adds a KRS object (in world space: its nodes get the identity transform) to `scene`, and
/// returns the triangles added (each mesh once per node that draws it, levels of detail
/// included; instancing multiplies them on screen only) and, when it was instanced, how.
///
/// In `Cubes` and `Smooth` modes the object's reflection sequence is split at a level `K`
/// (`options.instance_level`, or [`PreparedObject::auto_placement_level`](crate::krs::PreparedObject::auto_placement_level)): the prototype
/// (kernels `0..=K`, mirrors `0..K`) is meshed once in object space ([`mesh_krs`] at
/// `options.resolution` cells along its longest side), and the 2^(n−K) compositions of the
/// placement mirrors `K..n` become `EXT_mesh_gpu_instancing` transforms. That extension's TRS
/// has a unit quaternion and no way to mirror, so mirrored placements draw a second mesh, the
/// prototype reflected by x → −x with its winding reversed ([`instances::mirrored_x`]). With
/// no placement mirrors (or a distortion or empty zones, which act on the whole object) the
/// object is one distance-field mesh. With `options.lod_levels` the mesh (every copy of an
/// instanced prototype, with the same placements) gets coarser `MSFT_lod` levels: the field
/// meshed again at half the resolution per level ([`MIN_LOD_RESOLUTION`] and the triangle
/// budget bound them). In `Instances` mode each kernel is a mesh drawn once
/// per kernel instance ([`krs_instances`]); distorted objects fall back to one mesh.
///
/// # Errors
/// [`FieldError`] from the meshers, [`FieldError::TooManyInstances`] past
/// `options.max_instances`, [`FieldError::BadInstanceLevel`] for a level below
/// [`KrsObject::lowest_placement_level`](crate::krs::KrsObject::lowest_placement_level).
pub fn add_krs_object(
    scene: &mut ExportScene,
    name: &str,
    object: &crate::krs::PreparedObject,
    options: &GltfExportOptions,
    progress: &dyn Fn(f32) -> bool,
) -> Result<(u64, Option<KrsInstancing>), FieldError> {
    let material = scene.materials.len();
    scene.materials.push(ExportMaterial {
        name: name.to_owned(),
        ..ExportMaterial::default()
    });
    let to_primitive = |m: ColoredMesh| ExportPrimitive {
        positions: m.positions,
        normals: m.normals,
        colors: m.colors,
        uvs: Vec::new(),
        indices: m.indices,
        material,
        skin: Vec::new(),
    };
    let o = &object.object;
    let n = o.mirrors.len();
    let per_copy = o.distortion.is_none() && o.empty_zones.is_empty();
    if options.mode == ExportMode::Instances && per_copy {
        let kernels = krs_instances(object, options.kernel_resolution, options.max_instances)?;
        let mut tris = 0u64;
        for k in kernels {
            for (suffix, mesh, transforms) in [
                ("", k.mesh, k.transforms),
                (" mirrored", k.mirrored_mesh, k.mirrored_transforms),
            ] {
                if transforms.is_empty() {
                    continue;
                }
                tris += mesh.triangle_count() as u64;
                scene.nodes.push(ExportNode {
                    name: format!("{name} kernel {}{suffix}", k.kernel),
                    primitives: vec![to_primitive(mesh)],
                    instances: transforms,
                    ..ExportNode::default()
                });
            }
        }
        progress(1.0);
        return Ok((tris, None));
    }
    let level = match options.instance_level {
        Some(k) => {
            let lowest = o.lowest_placement_level();
            if k < lowest {
                return Err(FieldError::BadInstanceLevel(format!(
                    "KRS object {:?}: instance level {k} (--instance-level) is below its lowest \
                     placement level {lowest}: kernel {lowest} is not empty, so mirror {k} \
                     does more than place copies; use a level from {lowest} to {n}",
                    o.name
                )));
            }
            k.min(n)
        }
        None => object.auto_placement_level(),
    };
    if level >= n || !per_copy {
        let mesh = mesh_krs(object, options.resolution, options.max_triangles, progress)?;
        let mut tris = mesh.triangle_count() as u64;
        let lods = krs_lods(object, options, &mesh, options.max_triangles - tris, 1)?;
        tris += lods.iter().map(|m| m.triangle_count() as u64).sum::<u64>();
        scene.nodes.push(ExportNode {
            name: name.to_owned(),
            primitives: vec![to_primitive(mesh)],
            lods: lods.into_iter().map(|m| vec![to_primitive(m)]).collect(),
            ..ExportNode::default()
        });
        return Ok((tris, None));
    }
    let count = o.placement_count(level);
    if count > options.max_instances as u128 {
        return Err(FieldError::TooManyInstances {
            count,
            limit: options.max_instances as u64,
            what: format!(
                "KRS object {:?}: copies of its prototype (levels 0..={level})",
                o.name
            ),
        });
    }
    let prototype = crate::krs::KrsScene {
        objects: vec![o.prototype(level)],
    }
    .prepare()
    .map_err(|e| FieldError::Unbounded(e.to_string()))?;
    let mut plain = Vec::new();
    let mut flipped = Vec::new();
    for xf in object.placements(level, options.max_instances) {
        let (trs, mirrored) = instances::proper_trs(&xf);
        if mirrored {
            flipped.push(trs);
        } else {
            plain.push(trs);
        }
    }
    // Every mesh is written once per copy: the plain and the mirrored one.
    let copies = (u64::from(!plain.is_empty()) + u64::from(!flipped.is_empty())).max(1);
    let prototype = &prototype.objects[0];
    let mesh = mesh_krs(
        prototype,
        options.resolution,
        options.max_triangles / copies,
        progress,
    )?;
    let proto_tris = mesh.triangle_count() as u64;
    let lod_options = GltfExportOptions {
        lod_levels: options.instanced_lod_levels,
        ..options.clone()
    };
    let lods = krs_lods(
        prototype,
        &lod_options,
        &mesh,
        options.max_triangles - copies * proto_tris,
        copies,
    )?;
    let (mesh_lo, mesh_hi) = mesh_bounds(&mesh);
    let impostor = if options.impostor && options.instanced_lod_levels > 0 {
        let impostor = impostor::krs_impostor(
            &prototype.object,
            mesh_lo,
            mesh_hi,
            impostor::IMPOSTOR_TEXELS,
        )
        .map_err(FieldError::Impostor)?;
        let material = scene.materials.len();
        scene.materials.push(ExportMaterial {
            name: format!("{name} impostor"),
            texture: Some(impostor.texture.clone()),
            alpha_cutoff: Some(0.5),
            no_mipmaps: true,
            ..ExportMaterial::default()
        });
        Some((impostor, material))
    } else {
        None
    };
    let impostor_primitive = |i: &impostor::Impostor, material: usize| ExportPrimitive {
        positions: i.positions.clone(),
        normals: i.normals.clone(),
        colors: Vec::new(),
        uvs: i.uvs.clone(),
        indices: i.indices.clone(),
        material,
        skin: Vec::new(),
    };
    let mirrored_mesh = instances::mirrored_x(&mesh);
    let mut plain_lods: Vec<Vec<ExportPrimitive>> =
        lods.iter().map(|m| vec![to_primitive(m.clone())]).collect();
    let mut mirrored_lods: Vec<Vec<ExportPrimitive>> = lods
        .iter()
        .map(|m| vec![to_primitive(instances::mirrored_x(m))])
        .collect();
    let mut lod_tris: u64 = lods.iter().map(|m| m.triangle_count() as u64).sum();
    if let Some((i, material)) = &impostor {
        plain_lods.push(vec![impostor_primitive(i, *material)]);
        mirrored_lods.push(vec![impostor_primitive(&i.mirrored_x(), *material)]);
        lod_tris += i.triangle_count() as u64;
    }
    // Cells: a grid over where the prototype's centre lands, each placement in exactly one.
    let centre = (mesh_lo + mesh_hi) * 0.5;
    let spot = |t: &InstanceTransform, mirrored: bool| {
        t.transform_point(if mirrored {
            centre * Vec3::new(-1.0, 1.0, 1.0)
        } else {
            centre
        })
    };
    let spots: Vec<Vec3> = plain
        .iter()
        .map(|t| spot(t, false))
        .chain(flipped.iter().map(|t| spot(t, true)))
        .collect();
    let grid = CellGrid::over(
        &spots,
        options
            .cells
            .unwrap_or_else(|| auto_cell_count(spots.len() as u64)),
    );
    let cell_count = (grid.columns * grid.rows) as usize;
    let mut plain_cells: Vec<Vec<InstanceTransform>> = vec![Vec::new(); cell_count];
    let mut mirrored_cells: Vec<Vec<InstanceTransform>> = vec![Vec::new(); cell_count];
    for (t, s) in plain.iter().zip(&spots) {
        plain_cells[grid.cell_of(*s)].push(*t);
    }
    for (t, s) in flipped.iter().zip(&spots[plain.len()..]) {
        mirrored_cells[grid.cell_of(*s)].push(*t);
    }
    let mut report = KrsInstancing {
        object: name.to_owned(),
        level,
        instances: (plain.len() + flipped.len()) as u64,
        mirrored: flipped.len() as u64,
        prototype_triangles: proto_tris,
        cells: [grid.columns, grid.rows],
        cell_nodes: 0,
        impostor: impostor.is_some(),
    };
    let mut tris = 0;
    for (suffix, mesh, lods, cells) in [
        ("", mesh, plain_lods, plain_cells),
        (" mirrored", mirrored_mesh, mirrored_lods, mirrored_cells),
    ] {
        // The first cell with placements writes the mesh and its levels; the others draw it.
        let mut source: Option<usize> = None;
        let mut mesh = Some(mesh);
        let mut lods = Some(lods);
        for (c, transforms) in cells.into_iter().enumerate() {
            if transforms.is_empty() {
                continue;
            }
            let node_name = if cell_count == 1 {
                format!("{name}{suffix}")
            } else {
                let (column, row) = (c as u32 % grid.columns, c as u32 / grid.columns);
                format!("{name} cell {column},{row}{suffix}")
            };
            report.cell_nodes += 1;
            match source {
                Some(first) => scene.nodes.push(ExportNode {
                    name: node_name,
                    instances: transforms,
                    mesh_from: Some(first),
                    ..ExportNode::default()
                }),
                None => {
                    tris += proto_tris + lod_tris;
                    source = Some(scene.nodes.len());
                    scene.nodes.push(ExportNode {
                        name: node_name,
                        primitives: mesh.take().map(to_primitive).into_iter().collect(),
                        instances: transforms,
                        lods: lods.take().unwrap_or_default(),
                        ..ExportNode::default()
                    });
                }
            }
        }
    }
    Ok((tris, Some(report)))
}

/// A grid of cells over the x-z extent of points, about as square as the extent allows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellGrid {
    /// The extent's corner (x, z).
    pub lo: Vec2,
    /// The extent's size (x, z), each at least a tiny positive length.
    pub size: Vec2,
    /// Cells along x.
    pub columns: u32,
    /// Cells along z.
    pub rows: u32,
}

impl CellGrid {
    /// About `cells` cells (at least 1) over the x-z extent of `points`: columns and rows in
    /// the ratio of the extent's sides.
    #[must_use]
    pub fn over(points: &[Vec3], cells: u32) -> Self {
        let (mut lo, mut hi) = (Vec2::INFINITY, Vec2::NEG_INFINITY);
        for p in points {
            lo = lo.min(Vec2::new(p.x, p.z));
            hi = hi.max(Vec2::new(p.x, p.z));
        }
        if !lo.cmple(hi).all() {
            (lo, hi) = (Vec2::ZERO, Vec2::ZERO);
        }
        let size = (hi - lo).max(Vec2::splat(1e-6));
        let cells = cells.max(1) as f32;
        let columns = (cells * size.x / size.y).sqrt().round().clamp(1.0, cells);
        let rows = (cells / columns).round().max(1.0);
        Self {
            lo,
            size,
            columns: columns as u32,
            rows: rows as u32,
        }
    }

    /// The cell (row-major: `row * columns + column`) that holds `p` (clamped to the grid).
    #[must_use]
    pub fn cell_of(&self, p: Vec3) -> usize {
        let f = (Vec2::new(p.x, p.z) - self.lo) / self.size;
        let column = ((f.x * self.columns as f32) as u32).min(self.columns - 1);
        let row = ((f.y * self.rows as f32) as u32).min(self.rows - 1);
        (row * self.columns + column) as usize
    }
}

/// Coarsest resolution a KRS level of detail is meshed at (cells along its region's longest
/// side); coarser levels would be blobs.
pub const MIN_LOD_RESOLUTION: u32 = 8;

/// The coarser levels of detail of a KRS mesh (`full`, meshed at `options.resolution`): level
/// k is the distance field meshed again at `resolution / 2^k` cells, for k = 1 ..=
/// `options.lod_levels`. Each level is written `copies` times and must fit what is left of the
/// triangle budget (`budget`), or the export is refused. The levels stop early, before a level
/// under [`MIN_LOD_RESOLUTION`] cells, an empty one (the object thinner than a cell), one with
/// no fewer triangles than the level before it, or one whose box strays from the full mesh's
/// by more than its own cell (it lost a branch tip thinner than a cell, so the silhouette
/// would jump when a viewer switches to it).
///
/// # Errors
/// [`FieldError`] from the mesher; [`FieldError::TooManyTriangles`] names the level.
fn krs_lods(
    object: &crate::krs::PreparedObject,
    options: &GltfExportOptions,
    full: &ColoredMesh,
    mut budget: u64,
    copies: u64,
) -> Result<Vec<ColoredMesh>, FieldError> {
    let mut lods: Vec<ColoredMesh> = Vec::new();
    if options.lod_levels == 0 {
        return Ok(lods);
    }
    let (region_lo, region_hi) = krs_region(object)?;
    let full_box = mesh_bounds(full);
    for k in 1..=u32::from(options.lod_levels) {
        let resolution = options.resolution >> k.min(31);
        if resolution < MIN_LOD_RESOLUTION {
            break;
        }
        let mesh = mesh_krs(object, resolution, budget / copies.max(1), &|_| true).map_err(
            |e| match e {
                FieldError::TooManyTriangles { limit, what } => FieldError::TooManyTriangles {
                    limit,
                    what: format!("level of detail {k} at resolution {resolution}: {what}"),
                },
                e => e,
            },
        )?;
        let finer = lods.last().unwrap_or(full).triangle_count();
        if mesh.indices.is_empty() || mesh.triangle_count() >= finer {
            break;
        }
        let cell = (region_hi - region_lo).max_element() / resolution as f32;
        let (lo, hi) = mesh_bounds(&mesh);
        if (lo - full_box.0)
            .abs()
            .max((hi - full_box.1).abs())
            .max_element()
            > cell
        {
            break;
        }
        budget -= copies * mesh.triangle_count() as u64;
        lods.push(mesh);
    }
    Ok(lods)
}

/// The box of a mesh's vertices (inverted when it has none).
fn mesh_bounds(mesh: &ColoredMesh) -> (Vec3, Vec3) {
    mesh.positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        })
}

/// Adds an unbounded KRS object as the open patch of its surface inside `lo..hi`
/// ([`fields::mesh_krs_patch`] at `options.resolution` cells along the longest side), with a
/// double-sided material (the patch is seen from below at its edges). Returns the triangles.
///
/// # Errors
/// [`FieldError`] from the mesher.
pub fn add_krs_patch(
    scene: &mut ExportScene,
    name: &str,
    object: &crate::krs::PreparedObject,
    lo: Vec3,
    hi: Vec3,
    options: &GltfExportOptions,
    progress: &dyn Fn(f32) -> bool,
) -> Result<u64, FieldError> {
    let mesh = fields::mesh_krs_patch(
        object,
        lo,
        hi,
        options.resolution,
        options.max_triangles,
        progress,
    )?;
    let material = scene.materials.len();
    scene.materials.push(ExportMaterial {
        name: name.to_owned(),
        double_sided: true,
        ..ExportMaterial::default()
    });
    let tris = mesh.triangle_count() as u64;
    scene.nodes.push(ExportNode {
        name: name.to_owned(),
        primitives: vec![ExportPrimitive {
            positions: mesh.positions,
            normals: mesh.normals,
            colors: mesh.colors,
            uvs: Vec::new(),
            indices: mesh.indices,
            material,
            skin: Vec::new(),
        }],
        ..ExportNode::default()
    });
    Ok(tris)
}

/// World-space box of what a node draws (every instance, through the node's transform; the
/// mesh of the node it draws with `mesh_from`).
fn node_bounds(scene: &ExportScene, node: &ExportNode) -> Option<(Vec3, Vec3)> {
    let mut lo = Vec3::INFINITY;
    let mut hi = Vec3::NEG_INFINITY;
    let primitives = match node.mesh_from {
        Some(j) => &scene.nodes.get(j)?.primitives,
        None => &node.primitives,
    };
    for p in primitives.iter().flat_map(|p| &p.positions) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if !(lo.cmple(hi).all()) {
        return None;
    }
    let corners = |lo: Vec3, hi: Vec3| {
        (0..8).map(move |k| {
            Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        })
    };
    if !node.instances.is_empty() {
        let (mut ilo, mut ihi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for t in &node.instances {
            for c in corners(lo, hi) {
                let p = t.transform_point(c);
                ilo = ilo.min(p);
                ihi = ihi.max(p);
            }
        }
        (lo, hi) = (ilo, ihi);
    }
    let m = node.transform.matrix();
    let (mut wlo, mut whi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for c in corners(lo, hi) {
        let p = m.transform_point3(c);
        wlo = wlo.min(p);
        whi = whi.max(p);
    }
    Some((wlo, whi))
}

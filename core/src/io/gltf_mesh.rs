//! glTF 2.0 (`.gltf` and `.glb`) → [`MeshModel`].
//!
//! What is read: every node of the default scene (or, without scenes, every root node) with
//! its accumulated transform; every triangle primitive (lists, strips and fans; points and lines
//! are skipped with a warning), indexed or not; `POSITION`, `NORMAL` (flat normals when absent,
//! as the specification asks: a vertex between faces facing different ways is split), the
//! base-colour texture's UV set (normally `TEXCOORD_0`), `COLOR_0`, `JOINTS_0` and `WEIGHTS_0`;
//! materials' base colour factor, base-colour texture (PNG or JPEG, from a `.glb` buffer view, a
//! data URI or a file beside the `.gltf`) decoded to RGBA8, and the `KHR_materials_unlit` flag.
//!
//! **Skinned primitives** (on a node with a `skin`) keep `JOINTS_0`/`WEIGHTS_0` and are left in
//! bind-pose mesh space: glTF ignores the transform of the node a skinned mesh is attached to
//! (the joints place it), so applying it would move the mesh twice once skinning runs.
//!
//! Robustness: the `gltf` crate is used only to deserialize the JSON. The GLB container, the
//! buffers and every accessor are read here, and every declared offset, stride and count is
//! checked against the bytes actually present, with checked arithmetic, before anything is read
//! or allocated; index values are checked against the vertex count; the node graph is walked
//! without recursion and refuses cycles. Declared sizes are bounded by [`ImportLimits`]. No
//! input makes this module panic (see the fuzz test in [`crate::io`]).

use std::borrow::Cow;
use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::path::Path;

use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use gltf::json;
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use super::error::{ImportLimits, IoError, read_file_limited};
use super::gltf_instancing::SceneSize;
use crate::mesh::{Material, MeshModel, Texture, TriangleMesh};

/// Required extensions this importer honours (any other required extension is an error;
/// unknown *optional* extensions are ignored, as the glTF specification asks).
const SUPPORTED_REQUIRED_EXTENSIONS: &[&str] = &[
    "KHR_materials_unlit",
    "KHR_mesh_quantization",
    super::gltf_instancing::INSTANCING,
];

/// Imports a `.gltf` or `.glb` file. External buffers and images are resolved relative to the
/// file's directory.
///
/// # Errors
/// An [`IoError`] naming the file and what is wrong in it (never a panic).
pub fn import_gltf(path: &Path) -> Result<MeshModel, IoError> {
    import_gltf_with(path, &ImportLimits::default())
}

/// [`import_gltf`] with explicit size limits.
///
/// # Errors
/// See [`import_gltf`]; declared sizes over `limits` give [`IoError::TooLarge`].
pub fn import_gltf_with(path: &Path, limits: &ImportLimits) -> Result<MeshModel, IoError> {
    let (model, dropped) = import_gltf_reported(path, limits)?;
    for line in &dropped {
        log::warn!("{}: {line}", path.display());
    }
    Ok(model)
}

/// [`import_gltf_with`], plus one line for each kind of feature the file holds that the import
/// leaves out (morph targets, animation, extra UV sets, texture maps other than base colour,
/// point and spot lights, unsupported extensions, points and lines) and what became of its
/// cameras and directional lights (see [`import_gltf_imported`]), for the caller to show.
///
/// # Errors
/// See [`import_gltf`].
pub fn import_gltf_reported(
    path: &Path,
    limits: &ImportLimits,
) -> Result<(MeshModel, Vec<String>), IoError> {
    import_gltf_imported(path, limits).map(|i| (i.model, i.report))
}

/// What [`import_gltf_imported`] reads from a file.
#[derive(Debug, Clone)]
pub struct GltfImport {
    /// The meshes, in world space.
    pub model: MeshModel,
    /// One line per kind of feature the import leaves out or changes (see
    /// [`import_gltf_reported`]), and what it did with the file's cameras and lights.
    pub report: Vec<String>,
    /// The file's first camera and its directional lights, for a document made from it.
    pub view: super::gltf_view::GltfView,
    /// The scene's nodes that have triangles, in scene order, each with the parts of
    /// [`Self::model`] it holds (see [`super::gltf_nodes`] for turning them into objects).
    /// Each instance a node places with `EXT_mesh_gpu_instancing` is a node of its own here,
    /// named "NAME i" as `thicket export --instancing nodes` names it.
    pub nodes: Vec<GltfNode>,
    /// The scene's nodes with `EXT_mesh_gpu_instancing` and the instances they place (each
    /// expanded into [`Self::model`]); zero for a file without the extension.
    pub instancing: InstanceCounts,
}

/// How many instances a file's `EXT_mesh_gpu_instancing` nodes place.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InstanceCounts {
    /// Nodes of the scene that have the extension (and a mesh).
    pub nodes: u64,
    /// The instances they place, over all of them.
    pub instances: u64,
}

/// One node of the scene that has triangles.
#[derive(Debug, Clone, PartialEq)]
pub struct GltfNode {
    /// Its index in the file's `nodes`.
    pub index: usize,
    /// The node's name, else its mesh's, else `node N`.
    pub name: String,
    /// The node's world transform (its ancestors' composed with its own).
    pub world_from_node: Mat4,
    /// Its parts in [`GltfImport::model`] (already in world space, or in bind-pose mesh space
    /// when `skinned`).
    pub parts: std::ops::Range<usize>,
    /// Whether the node has a skin (its parts ignore `world_from_node`, as glTF says).
    pub skinned: bool,
}

/// A scene node with a mesh, as planned before anything is built: its index, its world
/// transform and, with `EXT_mesh_gpu_instancing`, its instance transforms.
type PlannedNode = (usize, Mat4, Option<Vec<Mat4>>);

/// One mesh a counted glTF scene draws ([`GltfCount`]).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct CountedMesh {
    /// Its index in the file's `meshes`.
    pub index: usize,
    /// Its name in the file (empty without one).
    pub name: String,
    /// Triangles of one copy (an upper bound for strips and fans).
    pub triangles: u64,
    /// Vertices of one copy.
    pub vertices: u64,
    /// Scene nodes that draw it.
    pub nodes: u64,
    /// Copies the scene draws: one per plain node, one per instance of an instanced node.
    pub copies: u64,
}

/// What a glTF file's scene would build, counted from its checked accessors without building
/// anything: how `thicket info` reports a file too large to import (a forest exported with
/// `EXT_mesh_gpu_instancing` places billions of triangles from a few megabytes).
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct GltfCount {
    /// The meshes the scene draws, by index.
    pub meshes: Vec<CountedMesh>,
    /// Vertices over every copy, as the file holds them.
    pub vertices: u64,
    /// At most this many more an import makes: the copies split off where it computes flat
    /// normals for primitives without `NORMAL` (Thicket's cube exports have none).
    pub flat_normal_vertices: u64,
    /// Triangles over every copy (an upper bound, as [`CountedMesh::triangles`]).
    pub triangles: u64,
    /// Bytes an import would build.
    pub bytes: u64,
    /// Scene nodes with `EXT_mesh_gpu_instancing`.
    pub instanced_nodes: u64,
    /// The instances they place.
    pub instances: u64,
    /// Why importing the file would be refused with these limits (the figures and the
    /// limit), `None` when it imports.
    pub refused: Option<String>,
    /// What an import leaves out or changes (the import report's lines, less the view's).
    pub report: Vec<String>,
}

/// Counts what importing `path` would build, every instance included, without building it:
/// the file, its buffers and its instance transforms are read and checked as the import checks
/// them; no vertex, index or image is decoded.
///
/// # Errors
/// An [`IoError`] for a file that cannot be read or is malformed; a scene over `limits` is
/// not an error here ([`GltfCount::refused`] says why an import would refuse it).
pub fn count_gltf(path: &Path, limits: &ImportLimits) -> Result<GltfCount, IoError> {
    let bytes = read_file_limited(path, limits)?;
    Importer::of_file(path, limits).count(&bytes)
}

/// [`count_gltf`] on a file's bytes (external buffers are not read; the fuzz tests).
#[cfg(test)]
pub(crate) fn count_gltf_slice(
    bytes: &[u8],
    name: &Path,
    limits: &ImportLimits,
) -> Result<GltfCount, IoError> {
    Importer {
        path: name,
        base_dir: None,
        limits,
    }
    .count(bytes)
}

/// [`import_gltf_reported`], plus the file's camera and directional lights.
///
/// # Errors
/// See [`import_gltf`].
pub fn import_gltf_imported(path: &Path, limits: &ImportLimits) -> Result<GltfImport, IoError> {
    let bytes = read_file_limited(path, limits)?;
    Importer::of_file(path, limits).run_imported(&bytes)
}

/// [`import_gltf_imported`] on bytes named `name` in messages, with no base folder (external
/// files are refused). For tests: the report and the nodes of bytes built in memory.
///
/// # Errors
/// See [`import_gltf`].
#[cfg(test)]
pub(crate) fn import_gltf_slice_imported(
    bytes: &[u8],
    name: &Path,
    limits: &ImportLimits,
) -> Result<GltfImport, IoError> {
    Importer {
        path: name,
        base_dir: None,
        limits,
    }
    .run_imported(bytes)
}

/// Imports glTF or GLB bytes. External (non-data) URIs are resolved against `base_dir`; with
/// `None` they are refused, so untrusted bytes never make the importer touch the file system.
/// Errors name the file `<memory>`.
///
/// # Errors
/// See [`import_gltf`].
pub fn import_gltf_slice(bytes: &[u8], base_dir: Option<&Path>) -> Result<MeshModel, IoError> {
    import_gltf_slice_with(
        bytes,
        base_dir,
        Path::new("<memory>"),
        &ImportLimits::default(),
    )
}

/// [`import_gltf_slice`] with the name used in error messages and explicit limits.
///
/// # Errors
/// See [`import_gltf`].
pub fn import_gltf_slice_with(
    bytes: &[u8],
    base_dir: Option<&Path>,
    name: &Path,
    limits: &ImportLimits,
) -> Result<MeshModel, IoError> {
    Importer {
        path: name,
        base_dir,
        limits,
    }
    .run(bytes)
}

/// A glTF file opened by the hardened reader, for importers that need more than meshes (the
/// skinned importer): the JSON (deserialized only, never through gltf-json's validation), the
/// buffers checked against their declared lengths, and checked accessor, primitive, material
/// and scene reads. External files are confined to `base_dir` and read within the limits.
pub(crate) struct OpenedGltf<'a> {
    importer: Importer<'a>,
    /// The deserialized JSON; every index in it must be looked up with `get`.
    pub(crate) root: json::Root,
    buffers: Vec<Cow<'a, [u8]>>,
    budget: Budget,
}

/// Opens `bytes` (a `.glb` or `.gltf`) named `path` in messages.
///
/// # Errors
/// An [`IoError`] for a broken container, JSON, buffer or required extension.
pub(crate) fn open_gltf<'a>(
    bytes: &'a [u8],
    path: &'a Path,
    base_dir: Option<&'a Path>,
    limits: &'a ImportLimits,
) -> Result<OpenedGltf<'a>, IoError> {
    let importer = Importer {
        path,
        base_dir,
        limits,
    };
    let container = importer.split_container(bytes)?;
    let root = importer.parse_root(container.json)?;
    let buffers = importer.load_buffers(&root, container.bin)?;
    Ok(OpenedGltf {
        importer,
        root,
        buffers,
        budget: Budget {
            vertices: 0,
            indices: 0,
        },
    })
}

impl OpenedGltf<'_> {
    /// [`IoError::Invalid`] on this file.
    pub(crate) fn invalid(&self, detail: impl Into<String>) -> IoError {
        self.importer.invalid(detail)
    }

    /// Accessor `index` as flat floats (`count × components`, normalised integers as the
    /// accessor says), and its component count. `types` and `components` list what is allowed.
    pub(crate) fn floats(
        &self,
        index: usize,
        what: &str,
        types: &[Type],
        components: &[ComponentType],
    ) -> Result<(Vec<f32>, usize), IoError> {
        let data =
            self.importer
                .accessor(&self.root, &self.buffers, index, what, types, components)?;
        let out = (0..data.count)
            .flat_map(|i| (0..data.dims).map(move |c| (i, c)))
            .map(|(i, c)| data.component(i, c))
            .collect();
        Ok((out, data.dims))
    }

    /// One primitive of mesh `mesh_index` as a triangle list in mesh space (`None` for points
    /// and lines), counted against the vertex and index limits.
    pub(crate) fn primitive(
        &mut self,
        mesh_index: usize,
        prim_index: usize,
    ) -> Result<Option<TriangleMesh>, IoError> {
        let mesh = self
            .root
            .meshes
            .get(mesh_index)
            .ok_or_else(|| self.invalid(format!("mesh {mesh_index} does not exist")))?;
        let Some(primitive) = mesh.primitives.get(prim_index) else {
            return Ok(None);
        };
        let mesh_name = mesh
            .name
            .as_deref()
            .map_or_else(|| format!("{mesh_index}"), |n| format!("'{n}'"));
        self.importer.read_primitive(
            &self.root,
            &self.buffers,
            &mesh_name,
            prim_index,
            primitive,
            &mut self.budget,
        )
    }

    /// The materials in file order (textures decoded within the limits).
    pub(crate) fn materials(&self) -> Result<Vec<Material>, IoError> {
        self.importer.load_materials(&self.root, &self.buffers)
    }

    /// The default scene's nodes (or every root's) with their world transforms, each once.
    pub(crate) fn scene_nodes(&self) -> Result<Vec<(usize, Mat4)>, IoError> {
        self.importer.scene_nodes(&self.root)
    }

    /// Node `index`'s local transform (checked finite, rotation normalised).
    pub(crate) fn local_transform(&self, index: usize) -> Result<Mat4, IoError> {
        let node = self
            .root
            .nodes
            .get(index)
            .ok_or_else(|| self.invalid(format!("node {index} does not exist")))?;
        self.importer.local_transform(node, index)
    }
}

/// One import: where messages point, where external files live, and the limits.
pub(super) struct Importer<'a> {
    pub(super) path: &'a Path,
    base_dir: Option<&'a Path>,
    pub(super) limits: &'a ImportLimits,
}

/// The two parts of a GLB container (or a plain JSON file, `bin` = `None`).
struct Container<'b> {
    json: &'b [u8],
    bin: Option<&'b [u8]>,
}

/// A typed view of one accessor's bytes, already bounds-checked: element `i` starts at
/// `i * stride` in `bytes`, and `bytes` holds all `count` elements.
pub(super) struct AccessorData<'b> {
    bytes: &'b [u8],
    stride: usize,
    pub(super) count: usize,
    pub(super) component: ComponentType,
    pub(super) dims: usize,
    pub(super) normalized: bool,
}

impl AccessorData<'_> {
    /// Component `c` of element `i` as a float, normalised when the accessor says so.
    /// Bounds were checked when the view was made; `get` keeps this panic-free regardless.
    pub(super) fn component(&self, i: usize, c: usize) -> f32 {
        let size = self.component.size();
        let at = i * self.stride + c * size;
        let Some(b) = self.bytes.get(at..at + size) else {
            return 0.0;
        };
        match self.component {
            ComponentType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            ComponentType::U8 => {
                let v = f32::from(b[0]);
                if self.normalized { v / 255.0 } else { v }
            }
            ComponentType::I8 => {
                let v = f32::from(b[0] as i8);
                if self.normalized {
                    (v / 127.0).max(-1.0)
                } else {
                    v
                }
            }
            ComponentType::U16 => {
                let v = f32::from(u16::from_le_bytes([b[0], b[1]]));
                if self.normalized { v / 65535.0 } else { v }
            }
            ComponentType::I16 => {
                let v = f32::from(i16::from_le_bytes([b[0], b[1]]));
                if self.normalized {
                    (v / 32767.0).max(-1.0)
                } else {
                    v
                }
            }
            ComponentType::U32 => {
                let v = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32;
                if self.normalized {
                    v / 4_294_967_295.0
                } else {
                    v
                }
            }
        }
    }

    /// Component `c` of element `i` as an unsigned integer (indices, joints).
    fn integer(&self, i: usize, c: usize) -> u32 {
        let size = self.component.size();
        let at = i * self.stride + c * size;
        let Some(b) = self.bytes.get(at..at + size) else {
            return u32::MAX;
        };
        match self.component {
            ComponentType::U8 => u32::from(b[0]),
            ComponentType::U16 => u32::from(u16::from_le_bytes([b[0], b[1]])),
            ComponentType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            // Signed and float components are refused before this is called.
            _ => u32::MAX,
        }
    }
}

/// Which accessor is being read, for messages: "accessor 3 (POSITION of mesh 'Body'
/// primitive 0)".
fn describe(accessor: usize, role: &str, mesh_name: &str, primitive: usize) -> String {
    format!("accessor {accessor} ({role} of mesh {mesh_name} primitive {primitive})")
}

fn type_dims(t: Type) -> usize {
    match t {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 | Type::Mat2 => 4,
        Type::Mat3 => 9,
        Type::Mat4 => 16,
    }
}

fn type_name(t: Type) -> &'static str {
    match t {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

fn component_name(c: ComponentType) -> &'static str {
    match c {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

impl<'a> Importer<'a> {
    pub(super) fn invalid(&self, detail: impl Into<String>) -> IoError {
        IoError::invalid(self.path, detail)
    }

    /// The model; what the file holds that it leaves out is logged as warnings.
    fn run(&self, bytes: &[u8]) -> Result<MeshModel, IoError> {
        let import = self.run_imported(bytes)?;
        for line in &import.report {
            log::warn!("{}: {line}", self.path.display());
        }
        Ok(import.model)
    }

    /// The importer of the file at `path`: external buffers and images resolve beside it.
    fn of_file(path: &'a Path, limits: &'a ImportLimits) -> Self {
        Self {
            path,
            base_dir: Some(path.parent().unwrap_or_else(|| Path::new("."))),
            limits,
        }
    }

    /// What the scene's mesh nodes will build, every instance counted from the checked
    /// accessor counts (nothing is built), and the nodes in scene order with their world
    /// transforms and instance transforms.
    fn plan_scene(
        &self,
        root: &json::Root,
        buffers: &[Cow<'_, [u8]>],
        scene_nodes: Vec<(usize, Mat4)>,
    ) -> Result<(SceneSize, Vec<PlannedNode>), IoError> {
        let mut size = SceneSize::default();
        let mut planned: Vec<PlannedNode> = Vec::new();
        for (node_index, world_from_node) in scene_nodes {
            let Some(node) = root.nodes.get(node_index) else {
                continue;
            };
            let Some(mesh_index) = node.mesh.map(|m| m.value()) else {
                continue;
            };
            let instances = self.node_instances(root, buffers, node_index, node)?;
            let copies = instances.as_ref().map_or(1, |v| v.len() as u64);
            if instances.is_some() {
                size.instanced_nodes += 1;
                size.instances = size.instances.saturating_add(copies);
            }
            self.count_mesh(root, buffers, mesh_index, copies, &mut size)?;
            planned.push((node_index, world_from_node, instances));
        }
        Ok((size, planned))
    }

    /// [`count_gltf`] on the file's bytes.
    fn count(&self, bytes: &[u8]) -> Result<GltfCount, IoError> {
        let container = self.split_container(bytes)?;
        let root = self.parse_root(container.json)?;
        let mut report =
            super::gltf_report::dropped_features(&root, super::gltf_report::Reader::Static);
        let scene_nodes = self.scene_nodes(&root)?;
        let buffers = self.load_buffers(&root, container.bin)?;
        let (size, planned) = self.plan_scene(&root, &buffers, scene_nodes)?;
        report.extend(super::gltf_instancing::instancing_note(&size));
        let mut meshes: Vec<CountedMesh> = Vec::new();
        for (node_index, _, instances) in &planned {
            let Some(mesh_index) = root.nodes.get(*node_index).and_then(|n| n.mesh) else {
                continue;
            };
            let mesh_index = mesh_index.value();
            let copies = instances.as_ref().map_or(1, |v| v.len() as u64);
            let at = match meshes.iter().position(|m| m.index == mesh_index) {
                Some(at) => at,
                None => {
                    let mut one = SceneSize::default();
                    self.count_mesh(&root, &buffers, mesh_index, 1, &mut one)?;
                    meshes.push(CountedMesh {
                        index: mesh_index,
                        name: root
                            .meshes
                            .get(mesh_index)
                            .and_then(|m| m.name.clone())
                            .unwrap_or_default(),
                        triangles: one.triangles(),
                        vertices: one.vertices,
                        nodes: 0,
                        copies: 0,
                    });
                    meshes.len() - 1
                }
            };
            meshes[at].nodes += 1;
            meshes[at].copies = meshes[at].copies.saturating_add(copies);
        }
        meshes.sort_by_key(|m| m.index);
        Ok(GltfCount {
            meshes,
            vertices: size.vertices,
            flat_normal_vertices: size.flat_normal_vertices,
            triangles: size.triangles(),
            bytes: size.bytes,
            instanced_nodes: size.instanced_nodes,
            instances: size.instances,
            refused: self.check_scene_size(&size).err().map(|e| match e {
                IoError::TooLarge { detail, .. } => detail,
                other => other.to_string(),
            }),
            report,
        })
    }

    /// The model, what the file holds that it leaves out ([`super::gltf_report`]) and its
    /// view ([`super::gltf_view`]).
    fn run_imported(&self, bytes: &[u8]) -> Result<GltfImport, IoError> {
        let container = self.split_container(bytes)?;
        let root = self.parse_root(container.json)?;
        let mut dropped =
            super::gltf_report::dropped_features(&root, super::gltf_report::Reader::Static);
        let scene_nodes = self.scene_nodes(&root)?;
        let (view, view_lines) = super::gltf_view::read_view(&root, &scene_nodes);
        dropped.extend(view_lines);
        let buffers = self.load_buffers(&root, container.bin)?;
        let mut model = MeshModel {
            parts: Vec::new(),
            materials: self.load_materials(&root, &buffers)?,
        };
        // Primitives without a material share one default material appended at the end.
        let default_material = model.materials.len();
        let mut used_default = false;
        let mut budget = Budget {
            vertices: 0,
            indices: 0,
        };
        // Count everything the import will build, every instance included, before building
        // any of it: a small file that places a mesh a million times is refused here.
        let (size, planned) = self.plan_scene(&root, &buffers, scene_nodes)?;
        self.check_scene_size(&size)?;
        dropped.extend(super::gltf_instancing::instancing_note(&size));

        let mut cache: HashMap<(usize, usize), Option<TriangleMesh>> = HashMap::new();
        let mut nodes = Vec::new();

        for (node_index, world_from_node, instances) in planned {
            let Some(node) = root.nodes.get(node_index) else {
                continue;
            };
            let Some(mesh_index) = node.mesh.map(|m| m.value()) else {
                continue;
            };
            let mesh = root.meshes.get(mesh_index).ok_or_else(|| {
                self.invalid(format!(
                    "node {node_index} refers to mesh {mesh_index}, which does not exist"
                ))
            })?;
            let skin_joints = match node.skin {
                Some(skin) => Some(
                    root.skins
                        .get(skin.value())
                        .ok_or_else(|| {
                            self.invalid(format!(
                                "node {node_index} refers to skin {}, which does not exist",
                                skin.value()
                            ))
                        })?
                        .joints
                        .len(),
                ),
                None => None,
            };
            let mesh_name = mesh
                .name
                .as_deref()
                .map_or_else(|| format!("{mesh_index}"), |n| format!("'{n}'"));
            let node_name = node
                .name
                .clone()
                .or_else(|| mesh.name.clone())
                .unwrap_or_else(|| format!("node {node_index}"));
            // Each instance is a copy of the node's mesh, named as the exporter names the node
            // it writes for that placement with `--instancing nodes` ("NAME i").
            let copies: Vec<(Mat4, String)> = match instances {
                None => vec![(world_from_node, node_name)],
                Some(instances) => instances
                    .iter()
                    .enumerate()
                    .map(|(i, node_from_instance)| {
                        (
                            world_from_node * *node_from_instance,
                            format!("{node_name} {i}"),
                        )
                    })
                    .collect(),
            };
            for (world_from_copy, name) in copies {
                let first_part = model.parts.len();
                for (prim_index, primitive) in mesh.primitives.iter().enumerate() {
                    let key = (mesh_index, prim_index);
                    let template = match cache.entry(key) {
                        Entry::Vacant(slot) => slot.insert(self.read_primitive(
                            &root,
                            &buffers,
                            &mesh_name,
                            prim_index,
                            primitive,
                            &mut budget,
                        )?),
                        Entry::Occupied(slot) => {
                            if let Some(part) = slot.get() {
                                // A second copy of the same primitive costs memory like the
                                // first.
                                budget.charge(self, part.positions.len(), part.indices.len())?;
                            }
                            slot.into_mut()
                        }
                    };
                    let Some(template) = template else {
                        continue;
                    };
                    let mut part = template.clone();
                    if let Some(joint_count) = skin_joints
                        && let Some(j) = part
                            .joints
                            .iter()
                            .flatten()
                            .find(|&&j| usize::from(j) >= joint_count)
                    {
                        return Err(self.invalid(format!(
                            "mesh {mesh_name} primitive {prim_index}: JOINTS_0 value {j} is past the {joint_count} joints of the node's skin"
                        )));
                    }
                    if skin_joints.is_none() {
                        part.transform(world_from_copy);
                    }
                    part.material = match primitive.material {
                        Some(m) if m.value() < default_material => m.value(),
                        Some(m) => {
                            return Err(self.invalid(format!(
                                "mesh {mesh_name} primitive {prim_index} refers to material {}, which does not exist",
                                m.value()
                            )));
                        }
                        None => {
                            used_default = true;
                            default_material
                        }
                    };
                    model.parts.push(part);
                }
                if model.parts.len() > first_part {
                    nodes.push(GltfNode {
                        index: node_index,
                        name,
                        world_from_node: world_from_copy,
                        parts: first_part..model.parts.len(),
                        skinned: skin_joints.is_some(),
                    });
                }
            }
        }
        if used_default {
            model.materials.push(Material {
                name: "default".to_owned(),
                ..Material::default()
            });
        }
        if let Err((part, e)) = model.validate() {
            return Err(self.invalid(format!("part {part}: {e}")));
        }
        Ok(GltfImport {
            model,
            report: dropped,
            view,
            nodes,
            instancing: InstanceCounts {
                nodes: size.instanced_nodes,
                instances: size.instances,
            },
        })
    }

    /// The JSON, deserialized only, with its required extensions checked.
    fn parse_root(&self, json_bytes: &[u8]) -> Result<json::Root, IoError> {
        let root = json::Root::from_slice(json_bytes)
            .map_err(|e| IoError::parse(self.path, format!("glTF JSON: {e}")))?;
        for ext in &root.extensions_required {
            if !SUPPORTED_REQUIRED_EXTENSIONS.contains(&ext.as_str()) {
                return Err(IoError::unsupported(
                    self.path,
                    format!(
                        "the file requires glTF extension {ext}, which Thicket does not implement"
                    ),
                ));
            }
        }
        Ok(root)
    }

    /// Splits a GLB container into its JSON and BIN chunks (checking every length against the
    /// bytes present), or passes JSON through.
    fn split_container<'b>(&self, bytes: &'b [u8]) -> Result<Container<'b>, IoError> {
        if bytes.is_empty() {
            return Err(IoError::truncated(self.path, "the file is empty"));
        }
        if !bytes.starts_with(b"glTF") {
            // serde_json refuses a UTF-8 byte-order mark, which some exporters write.
            let json = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
            if json.iter().copied().find(|b| !b.is_ascii_whitespace()) == Some(b'{') {
                return Ok(Container { json, bin: None });
            }
            let head: Vec<String> = bytes.iter().take(4).map(|b| format!("{b:02x}")).collect();
            return Err(IoError::parse(
                self.path,
                format!(
                    "not a glTF file: it starts with bytes {} (expected the GLB magic 'glTF' or a JSON object)",
                    head.join(" ")
                ),
            ));
        }
        let u32_at = |at: usize| -> Option<u32> {
            bytes
                .get(at..at + 4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        };
        let (Some(version), Some(length)) = (u32_at(4), u32_at(8)) else {
            return Err(IoError::truncated(
                self.path,
                format!("GLB header needs 12 bytes, the file has {}", bytes.len()),
            ));
        };
        if version != 2 {
            return Err(IoError::unsupported(
                self.path,
                format!("GLB version {version} (only version 2 is supported)"),
            ));
        }
        let length = length as usize;
        if length > bytes.len() {
            return Err(IoError::truncated(
                self.path,
                format!(
                    "GLB header declares {length} bytes but the file has {}",
                    bytes.len()
                ),
            ));
        }
        if length < 12 {
            return Err(self.invalid(format!(
                "GLB header declares a total length of {length} bytes, less than the header"
            )));
        }
        let bytes = &bytes[..length];
        let mut at = 12usize;
        let mut json: Option<&[u8]> = None;
        let mut bin: Option<&[u8]> = None;
        let mut chunk_index = 0;
        while at < bytes.len() {
            let (Some(chunk_len), Some(chunk_type)) = (u32_at(at), u32_at(at + 4)) else {
                return Err(IoError::truncated(
                    self.path,
                    format!("GLB chunk {chunk_index} header at byte {at} is cut off"),
                ));
            };
            let start = at + 8;
            let end = start.checked_add(chunk_len as usize).filter(|&e| e <= bytes.len()).ok_or_else(|| {
                IoError::truncated(
                    self.path,
                    format!(
                        "GLB chunk {chunk_index} at byte {at} declares {chunk_len} bytes but only {} remain",
                        bytes.len().saturating_sub(start)
                    ),
                )
            })?;
            let data = &bytes[start..end];
            match (chunk_index, &chunk_type.to_le_bytes()) {
                (0, b"JSON") => json = Some(data),
                (0, _) => return Err(self.invalid("the first GLB chunk is not JSON")),
                (1, b"BIN\0") => bin = Some(data),
                // Unknown chunks are skipped, as the specification asks.
                _ => {}
            }
            chunk_index += 1;
            // Chunks are 4-byte aligned; a missing final pad is tolerated.
            at = end.saturating_add(3) & !3;
        }
        let json =
            json.ok_or_else(|| IoError::truncated(self.path, "the GLB has no JSON chunk"))?;
        Ok(Container { json, bin })
    }

    /// Every buffer's bytes, each checked to hold at least its declared `byteLength` and cut to
    /// exactly that length.
    fn load_buffers<'b>(
        &self,
        root: &json::Root,
        bin: Option<&'b [u8]>,
    ) -> Result<Vec<Cow<'b, [u8]>>, IoError> {
        let mut out = Vec::with_capacity(root.buffers.len());
        for (i, buffer) in root.buffers.iter().enumerate() {
            let declared = buffer.byte_length.0;
            let data: Cow<'b, [u8]> = match buffer.uri.as_deref() {
                None => {
                    let Some(bin) = bin.filter(|_| i == 0) else {
                        return Err(self.invalid(format!(
                            "buffer {i} has no URI and is not the GLB binary chunk (only buffer 0 of a .glb may omit its URI)"
                        )));
                    };
                    Cow::Borrowed(bin)
                }
                Some(uri) => Cow::Owned(self.load_uri(uri, &format!("buffer {i}"))?),
            };
            if (data.len() as u64) < declared {
                return Err(IoError::truncated(
                    self.path,
                    format!(
                        "buffer {i} declares byteLength {declared} but its data has {} bytes",
                        data.len()
                    ),
                ));
            }
            let declared = declared as usize;
            out.push(match data {
                Cow::Borrowed(b) => Cow::Borrowed(&b[..declared]),
                Cow::Owned(mut v) => {
                    v.truncate(declared);
                    Cow::Owned(v)
                }
            });
        }
        Ok(out)
    }

    /// The bytes behind a URI: a base64 data URI or a file relative to the glTF's directory.
    fn load_uri(&self, uri: &str, what: &str) -> Result<Vec<u8>, IoError> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((header, payload)) = rest.split_once(',') else {
                return Err(self.invalid(format!("{what}: data URI has no ','")));
            };
            if !header.ends_with(";base64") {
                return Err(IoError::unsupported(
                    self.path,
                    format!("{what}: data URI is not base64-encoded"),
                ));
            }
            return decode_base64(payload).map_err(|at| {
                self.invalid(format!("{what}: bad base64 in data URI at character {at}"))
            });
        }
        if uri.contains("://") {
            return Err(IoError::unsupported(
                self.path,
                format!("{what}: URI '{uri}' is not a relative file path"),
            ));
        }
        let Some(base_dir) = self.base_dir else {
            return Err(IoError::unsupported(
                self.path,
                format!(
                    "{what}: refers to external file '{uri}' but the glTF was loaded from memory"
                ),
            ));
        };
        let relative = percent_decode(uri)
            .ok_or_else(|| self.invalid(format!("{what}: bad percent-encoding in URI '{uri}'")))?;
        super::confine::read_reference(base_dir, &relative, self.limits.max_file_bytes)
            .map_err(|e| e.into_io_error(self.path, &format!("{what}: URI")))
    }

    /// glTF materials in file order.
    fn load_materials(
        &self,
        root: &json::Root,
        buffers: &[Cow<'_, [u8]>],
    ) -> Result<Vec<Material>, IoError> {
        let mut images: HashMap<usize, Texture> = HashMap::new();
        let mut out = Vec::with_capacity(root.materials.len());
        for (i, m) in root.materials.iter().enumerate() {
            let factor = Vec4::from_array(m.pbr_metallic_roughness.base_color_factor.0);
            if !factor.is_finite() {
                return Err(self.invalid(format!("material {i}: baseColorFactor is not finite")));
            }
            let texture = match &m.pbr_metallic_roughness.base_color_texture {
                None => None,
                Some(info) => {
                    let tex = root.textures.get(info.index.value()).ok_or_else(|| {
                        self.invalid(format!(
                            "material {i}: base-colour texture {} does not exist",
                            info.index.value()
                        ))
                    })?;
                    let image = tex.source.value();
                    if let Some(t) = images.get(&image) {
                        Some(t.clone())
                    } else {
                        let t = self.load_image(root, buffers, image)?;
                        images.insert(image, t.clone());
                        Some(t)
                    }
                }
            };
            let unlit = m.extensions.as_ref().is_some_and(|e| e.unlit.is_some());
            out.push(Material {
                name: m.name.clone().unwrap_or_else(|| format!("material {i}")),
                base_color: factor,
                base_color_texture: texture,
                unlit,
            });
        }
        Ok(out)
    }

    /// Decodes image `index` (PNG or JPEG) to RGBA8 within the texture limit.
    fn load_image(
        &self,
        root: &json::Root,
        buffers: &[Cow<'_, [u8]>],
        index: usize,
    ) -> Result<Texture, IoError> {
        let what = format!("image {index}");
        let image = root
            .images
            .get(index)
            .ok_or_else(|| self.invalid(format!("{what} does not exist")))?;
        let encoded: Cow<'_, [u8]> = match (&image.uri, image.buffer_view) {
            (Some(uri), _) => Cow::Owned(self.load_uri(uri, &what)?),
            (None, Some(view)) => {
                Cow::Borrowed(self.view_bytes(root, buffers, view.value(), &what)?)
            }
            (None, None) => {
                return Err(self.invalid(format!("{what} has neither a URI nor a buffer view")));
            }
        };
        decode_texture(&encoded, self.limits).map_err(|e| match e {
            TextureError::TooLarge(d) => IoError::too_large(self.path, format!("{what}: {d}")),
            TextureError::Decode(d) => self.invalid(format!("{what}: {d}")),
        })
    }

    /// The bytes of buffer view `index`, checked against its buffer.
    fn view_bytes<'b>(
        &self,
        root: &json::Root,
        buffers: &'b [Cow<'_, [u8]>],
        index: usize,
        what: &str,
    ) -> Result<&'b [u8], IoError> {
        let view = root
            .buffer_views
            .get(index)
            .ok_or_else(|| self.invalid(format!("{what}: buffer view {index} does not exist")))?;
        let buffer_index = view.buffer.value();
        let buffer = buffers.get(buffer_index).ok_or_else(|| {
            self.invalid(format!(
                "{what}: buffer view {index} refers to buffer {buffer_index}, which does not exist"
            ))
        })?;
        let offset = view.byte_offset.map_or(0, |o| o.0);
        let length = view.byte_length.0;
        let end = offset.checked_add(length).filter(|&e| e <= buffer.len() as u64).ok_or_else(|| {
            self.invalid(format!(
                "{what}: buffer view {index} (offset {offset} + length {length}) runs past the {} bytes of buffer {buffer_index}",
                buffer.len()
            ))
        })?;
        Ok(&buffer[offset as usize..end as usize])
    }

    /// Checks accessor `index` against its buffer view and returns its data. `allowed` lists the
    /// accepted (type, component) pairs.
    pub(super) fn accessor<'b>(
        &self,
        root: &json::Root,
        buffers: &'b [Cow<'_, [u8]>],
        index: usize,
        what: &str,
        types: &[Type],
        components: &[ComponentType],
    ) -> Result<AccessorData<'b>, IoError> {
        let acc = root
            .accessors
            .get(index)
            .ok_or_else(|| self.invalid(format!("{what} does not exist")))?;
        if acc.sparse.is_some() {
            return Err(IoError::unsupported(
                self.path,
                format!("{what} is a sparse accessor"),
            ));
        }
        let (Checked::Valid(ty), Checked::Valid(component)) = (acc.type_, acc.component_type)
        else {
            return Err(self.invalid(format!("{what} has an invalid type or componentType")));
        };
        let component = component.0;
        if !types.contains(&ty) || !components.contains(&component) {
            return Err(self.invalid(format!(
                "{what} is {} of {}, which is not allowed here",
                type_name(ty),
                component_name(component)
            )));
        }
        let count = acc.count.0;
        let cap = self.limits.max_vertices.max(self.limits.max_indices);
        if count > cap {
            return Err(IoError::too_large(
                self.path,
                format!("{what}: count {count} exceeds the limit of {cap}"),
            ));
        }
        let dims = type_dims(ty);
        let element = (dims * component.size()) as u64;
        let Some(view_index) = acc.buffer_view.map(|v| v.value()) else {
            return Err(IoError::unsupported(
                self.path,
                format!("{what} has no buffer view"),
            ));
        };
        let bytes = self.view_bytes(root, buffers, view_index, what)?;
        // view_bytes has checked that the view exists.
        let byte_stride = root
            .buffer_views
            .get(view_index)
            .and_then(|v| v.byte_stride);
        let stride = match byte_stride {
            Some(s) => {
                let s = s.0 as u64;
                if s < element || s > 252 || !s.is_multiple_of(4) {
                    return Err(self.invalid(format!(
                        "{what}: buffer view {view_index} byteStride {s} is invalid for {element}-byte elements"
                    )));
                }
                s
            }
            None => element,
        };
        let offset = acc.byte_offset.map_or(0, |o| o.0);
        if count == 0 {
            return Err(self.invalid(format!(
                "{what}: count is 0; glTF requires at least one element"
            )));
        }
        // offset + stride * (count - 1) + element ≤ view length, without overflow.
        let needed = stride
            .checked_mul(count - 1)
            .and_then(|s| s.checked_add(element))
            .and_then(|s| s.checked_add(offset));
        match needed {
            Some(n) if n <= bytes.len() as u64 => Ok(AccessorData {
                bytes: &bytes[offset as usize..n as usize],
                stride: stride as usize,
                count: count as usize,
                component,
                dims,
                normalized: acc.normalized,
            }),
            _ => Err(self.invalid(format!(
                "{what}: count {count} × stride {stride} from offset {offset} exceeds buffer view {view_index} length {}",
                bytes.len()
            ))),
        }
    }

    /// The nodes to import with their world transforms: the default scene's (or scene 0's)
    /// trees, or every root node when the file has no scenes. Iterative, and each node is
    /// visited once, so cycles and shared children are errors rather than hangs.
    fn scene_nodes(&self, root: &json::Root) -> Result<Vec<(usize, Mat4)>, IoError> {
        let node_count = root.nodes.len();
        let roots: Vec<usize> = if root.scenes.is_empty() {
            let mut is_child = vec![false; node_count];
            for node in &root.nodes {
                for c in node.children.iter().flatten() {
                    if let Some(flag) = is_child.get_mut(c.value()) {
                        *flag = true;
                    }
                }
            }
            (0..node_count).filter(|&i| !is_child[i]).collect()
        } else {
            let scene_index = root.scene.map_or(0, |s| s.value());
            let scene = root.scenes.get(scene_index).ok_or_else(|| {
                self.invalid(format!("default scene {scene_index} does not exist"))
            })?;
            scene.nodes.iter().map(json::Index::value).collect()
        };
        let mut visited = vec![false; node_count];
        let mut out = Vec::new();
        let mut stack: Vec<(usize, Mat4)> = roots
            .into_iter()
            .rev()
            .map(|n| (n, Mat4::IDENTITY))
            .collect();
        while let Some((index, parent_from_world)) = stack.pop() {
            let node = root.nodes.get(index).ok_or_else(|| {
                self.invalid(format!(
                    "scene refers to node {index}, which does not exist"
                ))
            })?;
            if std::mem::replace(&mut visited[index], true) {
                return Err(self.invalid(format!(
                    "node {index} is reached twice (a cycle, or a node with two parents)"
                )));
            }
            let world_from_node = parent_from_world * self.local_transform(node, index)?;
            out.push((index, world_from_node));
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), world_from_node));
            }
        }
        Ok(out)
    }

    /// A node's `matrix` or translation × rotation × scale.
    fn local_transform(&self, node: &json::Node, index: usize) -> Result<Mat4, IoError> {
        let m = if let Some(matrix) = node.matrix {
            Mat4::from_cols_array(&matrix)
        } else {
            let t = Vec3::from_array(node.translation.unwrap_or([0.0; 3]));
            let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
            let s = Vec3::from_array(node.scale.unwrap_or([1.0; 3]));
            let q = Quat::from_array(r);
            let len = q.length();
            if !(len.is_finite() && len > 1e-6) {
                return Err(self.invalid(format!(
                    "node {index}: rotation {r:?} is not a unit quaternion"
                )));
            }
            Mat4::from_scale_rotation_translation(s, q / len, t)
        };
        if !m.is_finite() {
            return Err(self.invalid(format!("node {index}: transform has non-finite values")));
        }
        Ok(m)
    }

    /// One primitive as a triangle list in mesh space, or `None` for points and lines.
    fn read_primitive(
        &self,
        root: &json::Root,
        buffers: &[Cow<'_, [u8]>],
        mesh_name: &str,
        prim_index: usize,
        primitive: &json::mesh::Primitive,
        budget: &mut Budget,
    ) -> Result<Option<TriangleMesh>, IoError> {
        let mode = match primitive.mode {
            Checked::Valid(m) => m,
            Checked::Invalid => {
                return Err(self.invalid(format!(
                    "mesh {mesh_name} primitive {prim_index}: invalid mode"
                )));
            }
        };
        if matches!(
            mode,
            Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
        ) {
            log::warn!(
                "{}: mesh {mesh_name} primitive {prim_index} is {mode:?}, not triangles; skipped",
                self.path.display()
            );
            return Ok(None);
        }
        let attr = |s: Semantic| {
            primitive
                .attributes
                .get(&Checked::Valid(s))
                .map(json::Index::value)
        };
        let what = |index: usize, role: &str| describe(index, role, mesh_name, prim_index);
        let float_like = [
            ComponentType::F32,
            ComponentType::U8,
            ComponentType::I8,
            ComponentType::U16,
            ComponentType::I16,
        ];

        let Some(pos_index) = attr(Semantic::Positions) else {
            return Err(self.invalid(format!(
                "mesh {mesh_name} primitive {prim_index} has no POSITION"
            )));
        };
        let pos = self.accessor(
            root,
            buffers,
            pos_index,
            &what(pos_index, "POSITION"),
            &[Type::Vec3],
            &float_like,
        )?;
        let vertex_count = pos.count;
        // Index count is charged below, once it is known.
        budget.charge(self, vertex_count, 0)?;
        let mut part = TriangleMesh {
            positions: read_vec3(&pos),
            ..TriangleMesh::default()
        };

        let same_count = |data: &AccessorData<'_>, what: String| -> Result<(), IoError> {
            if data.count == vertex_count {
                Ok(())
            } else {
                Err(self.invalid(format!(
                    "{what}: count {} differs from POSITION count {vertex_count}",
                    data.count
                )))
            }
        };
        if let Some(i) = attr(Semantic::Normals) {
            let w = what(i, "NORMAL");
            let data = self.accessor(root, buffers, i, &w, &[Type::Vec3], &float_like)?;
            same_count(&data, w)?;
            part.normals = read_vec3(&data);
        }
        let material_uv_set = primitive
            .material
            .and_then(|m| root.materials.get(m.value()))
            .and_then(|m| m.pbr_metallic_roughness.base_color_texture.as_ref())
            .map_or(0, |info| info.tex_coord);
        if let Some(i) = attr(Semantic::TexCoords(material_uv_set)) {
            let w = what(i, &format!("TEXCOORD_{material_uv_set}"));
            let data = self.accessor(
                root,
                buffers,
                i,
                &w,
                &[Type::Vec2],
                &[ComponentType::F32, ComponentType::U8, ComponentType::U16],
            )?;
            same_count(&data, w)?;
            part.uvs = (0..data.count)
                .map(|v| Vec2::new(data.component(v, 0), data.component(v, 1)))
                .collect();
        }
        if let Some(i) = attr(Semantic::Colors(0)) {
            let w = what(i, "COLOR_0");
            let data = self.accessor(
                root,
                buffers,
                i,
                &w,
                &[Type::Vec3, Type::Vec4],
                &[ComponentType::F32, ComponentType::U8, ComponentType::U16],
            )?;
            same_count(&data, w)?;
            part.colors = (0..data.count)
                .map(|v| {
                    let a = if data.dims == 4 {
                        data.component(v, 3)
                    } else {
                        1.0
                    };
                    Vec4::new(
                        data.component(v, 0),
                        data.component(v, 1),
                        data.component(v, 2),
                        a,
                    )
                })
                .collect();
        }
        if let Some(i) = attr(Semantic::Joints(0)) {
            let w = what(i, "JOINTS_0");
            let data = self.accessor(
                root,
                buffers,
                i,
                &w,
                &[Type::Vec4],
                &[ComponentType::U8, ComponentType::U16],
            )?;
            same_count(&data, w)?;
            // Both allowed component types fit u16.
            part.joints = (0..data.count)
                .map(|v| std::array::from_fn(|c| data.integer(v, c) as u16))
                .collect();
        }
        if let Some(i) = attr(Semantic::Weights(0)) {
            let w = what(i, "WEIGHTS_0");
            let data = self.accessor(
                root,
                buffers,
                i,
                &w,
                &[Type::Vec4],
                &[ComponentType::F32, ComponentType::U8, ComponentType::U16],
            )?;
            same_count(&data, w)?;
            part.weights = (0..data.count)
                .map(|v| std::array::from_fn(|c| data.component(v, c)))
                .collect();
        }

        // Vertex order as drawn: the index list, or 0..n.
        let order: Vec<u32> = match primitive.indices.map(|i| i.value()) {
            Some(i) => {
                let w = what(i, "indices");
                let data = self.accessor(
                    root,
                    buffers,
                    i,
                    &w,
                    &[Type::Scalar],
                    &[ComponentType::U8, ComponentType::U16, ComponentType::U32],
                )?;
                budget.charge(self, 0, data.count)?;
                let mut order = Vec::with_capacity(data.count);
                for k in 0..data.count {
                    let v = data.integer(k, 0);
                    if v as usize >= vertex_count {
                        return Err(self.invalid(format!("{w}: index {v} at position {k} is not below the vertex count {vertex_count}")));
                    }
                    order.push(v);
                }
                order
            }
            None => {
                budget.charge(self, 0, vertex_count)?;
                // vertex_count ≤ max_vertices, which the limits keep within u32.
                (0..vertex_count).map(|v| v as u32).collect()
            }
        };
        part.indices = match mode {
            Mode::Triangles => {
                if !order.len().is_multiple_of(3) {
                    return Err(self.invalid(format!(
                        "mesh {mesh_name} primitive {prim_index}: {} vertices is not a whole number of triangles",
                        order.len()
                    )));
                }
                order
            }
            Mode::TriangleStrip => strip_to_list(&order),
            Mode::TriangleFan => fan_to_list(&order),
            Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => Vec::new(),
        };
        if part.normals.is_empty() {
            // The glTF specification: "When normals are not specified, client
            // implementations MUST calculate flat normals." (Blender and three.js do.)
            part.compute_flat_normals();
        }
        Ok(Some(part))
    }
}

/// Running totals of what the import will allocate, checked against the limits.
struct Budget {
    vertices: u64,
    indices: u64,
}

impl Budget {
    fn charge(
        &mut self,
        importer: &Importer<'_>,
        vertices: usize,
        indices: usize,
    ) -> Result<(), IoError> {
        self.vertices = self.vertices.saturating_add(vertices as u64);
        self.indices = self.indices.saturating_add(indices as u64);
        let l = importer.limits;
        // Indices are u32, so whatever the limits say, vertices must fit in one.
        let max_vertices = l.max_vertices.min(u64::from(u32::MAX));
        if self.vertices > max_vertices {
            return Err(IoError::too_large(
                importer.path,
                format!(
                    "the scene has at least {} vertices; the limit is {max_vertices}",
                    self.vertices
                ),
            ));
        }
        if self.indices > l.max_indices {
            return Err(IoError::too_large(
                importer.path,
                format!(
                    "the scene has at least {} indices; the limit is {}",
                    self.indices, l.max_indices
                ),
            ));
        }
        Ok(())
    }
}

fn read_vec3(data: &AccessorData<'_>) -> Vec<Vec3> {
    (0..data.count)
        .map(|v| {
            Vec3::new(
                data.component(v, 0),
                data.component(v, 1),
                data.component(v, 2),
            )
        })
        .collect()
}

/// glTF triangle strip → list: triangle i is (i, i+1, i+2) for even i and (i, i+2, i+1) for odd
/// i, so all keep the first triangle's winding. Degenerate triangles (used to join strips) are
/// dropped.
fn strip_to_list(order: &[u32]) -> Vec<u32> {
    let mut out = Vec::with_capacity(order.len().saturating_sub(2) * 3);
    for (i, w) in order.windows(3).enumerate() {
        let tri = if i % 2 == 0 {
            [w[0], w[1], w[2]]
        } else {
            [w[0], w[2], w[1]]
        };
        if tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] {
            out.extend_from_slice(&tri);
        }
    }
    out
}

/// glTF triangle fan → list: triangle i is (i+1, i+2, 0).
fn fan_to_list(order: &[u32]) -> Vec<u32> {
    let Some((&first, rest)) = order.split_first() else {
        return Vec::new();
    };
    let mut out = Vec::with_capacity(rest.len().saturating_sub(1) * 3);
    for w in rest.windows(2) {
        out.extend_from_slice(&[w[0], w[1], first]);
    }
    out
}

/// Why a texture could not be decoded.
pub(crate) enum TextureError {
    /// Its declared size is over the limit.
    TooLarge(String),
    /// The bytes are not a PNG or JPEG we can read.
    Decode(String),
}

/// PNG or JPEG bytes → RGBA8 texture, refusing images whose header declares more than
/// `limits.max_texture_bytes` of RGBA8 before decoding the pixels.
pub(crate) fn decode_texture(
    encoded: &[u8],
    limits: &ImportLimits,
) -> Result<Texture, TextureError> {
    crate::mesh::check_png_chunks(encoded).map_err(TextureError::Decode)?;
    let reader = image::ImageReader::new(std::io::Cursor::new(encoded))
        .with_guessed_format()
        .map_err(|e| TextureError::Decode(e.to_string()))?;
    match reader.format() {
        Some(image::ImageFormat::Png | image::ImageFormat::Jpeg) => {}
        Some(other) => {
            return Err(TextureError::Decode(format!(
                "the image is {}, not PNG or JPEG",
                other.extensions_str().first().map_or_else(
                    || "of another format".to_owned(),
                    |x| x.to_ascii_uppercase()
                )
            )));
        }
        None => {
            return Err(TextureError::Decode(
                "unknown image format (expected PNG or JPEG)".to_owned(),
            ));
        }
    }
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| TextureError::Decode(crate::mesh::image_error_text(&e)))?;
    let rgba_bytes = u64::from(w) * u64::from(h) * 4;
    if rgba_bytes > limits.max_texture_bytes {
        return Err(TextureError::TooLarge(format!(
            "{w}×{h} pixels need {rgba_bytes} bytes as RGBA8; the limit is {}",
            limits.max_texture_bytes
        )));
    }
    let mut reader = image::ImageReader::new(std::io::Cursor::new(encoded))
        .with_guessed_format()
        .map_err(|e| TextureError::Decode(e.to_string()))?;
    let mut image_limits = image::Limits::default();
    // The decoder's own working memory on top of the RGBA8 result.
    image_limits.max_alloc = Some(limits.max_texture_bytes.saturating_mul(2));
    reader.limits(image_limits);
    let decoded =
        crate::mesh::decode_contained(|| reader.decode()).map_err(TextureError::Decode)?;
    let rgba = decoded.to_rgba8();
    let (width, height) = rgba.dimensions();
    Ok(Texture {
        width,
        height,
        rgba8: rgba.into_raw(),
    })
}

/// Standard base64 (with or without padding; whitespace ignored). The error is the position of
/// the first bad character.
pub(crate) fn decode_base64(text: &str) -> Result<Vec<u8>, usize> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let mut acc: u32 = 0;
    let mut bits = 0u32;
    let mut padding = false;
    for (at, c) in text.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => {
                padding = true;
                continue;
            }
            c if c.is_ascii_whitespace() => continue,
            _ => return Err(at),
        };
        if padding {
            return Err(at);
        }
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// `%XX` escapes in a relative URI → a path string; `None` for a malformed escape or non-UTF-8.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use serde_json::{Value, json};
    use std::path::PathBuf;

    /// A small textured, vertex-coloured, indexed GLB with a strip, a node hierarchy and an
    /// unlit material: a fuzz seed that reaches every reader in this module.
    pub(crate) fn textured_glb() -> Vec<u8> {
        textured_glb_with(&png_2x1())
    }

    /// [`textured_glb`] with `png` (any bytes: the image fuzz target puts mutated PNGs and
    /// JPEGs here) as its embedded image.
    pub(crate) fn textured_glb_with(png: &[u8]) -> Vec<u8> {
        let mut doc = Doc::default();
        let pos = doc.floats(&QUAD, "VEC3", 3);
        let uv = doc.floats(&[0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0], "VEC2", 2);
        let colors = doc.accessor(
            &[
                255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 128, 255, 255, 255, 0,
            ],
            "VEC4",
            5121,
            4,
        );
        let joints = doc.accessor(
            &[0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0],
            "VEC4",
            5121,
            4,
        );
        let weights = doc.floats(
            &[
                1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0,
            ],
            "VEC4",
            4,
        );
        let indices = doc.accessor(&[0, 0, 1, 0, 3, 0, 2, 0], "SCALAR", 5123, 4);
        doc.accessors[colors]["normalized"] = json!(true);
        doc.accessor(png, "SCALAR", 5121, png.len());
        let image_view = doc.views.len() - 1;
        doc.accessors.pop();
        doc.glb(json!({
            "extensionsUsed": ["KHR_materials_unlit"],
            "scene": 0,
            "scenes": [{"nodes": [0, 2]}],
            "nodes": [
                {"children": [1], "translation": [1.0, 2.0, 3.0], "rotation": [0.0, 0.6, 0.0, 0.8]},
                {"mesh": 0, "scale": [2.0, 2.0, 2.0]},
                {"mesh": 0, "skin": 0, "matrix": [1.0,0.0,0.0,0.0, 0.0,1.0,0.0,0.0, 0.0,0.0,1.0,0.0, 0.0,0.0,0.0,1.0]}
            ],
            "skins": [{"joints": [0, 1]}],
            "meshes": [{"name": "Quad", "primitives": [
                {"attributes": {"POSITION": pos, "TEXCOORD_0": uv, "COLOR_0": colors, "JOINTS_0": joints, "WEIGHTS_0": weights},
                 "indices": indices, "mode": 5, "material": 0},
                {"attributes": {"POSITION": pos}, "mode": 6}
            ]}],
            "materials": [{"name": "glow", "extensions": {"KHR_materials_unlit": {}},
                "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0}],
            "images": [{"bufferView": image_view, "mimeType": "image/png"}]
        }))
    }

    #[test]
    fn the_textured_fuzz_seed_imports() {
        let model = import_gltf_slice(&textured_glb(), None).expect("seed");
        // Two nodes × two primitives; the skinned instance stays in mesh space.
        assert_eq!(model.parts.len(), 4);
        assert_eq!(model.triangle_count(), 8);
        assert!(model.materials[0].unlit && model.materials[0].base_color_texture.is_some());
        assert_eq!(
            model.parts[2].positions[..],
            QUAD.chunks(3).map(Vec3::from_slice).collect::<Vec<_>>()[..]
        );
        assert_eq!(model.parts[0].joints.len(), 4);
    }

    fn asset(relative: &str) -> PathBuf {
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/assets/")).join(relative)
    }

    /// The JSON of a .gltf or .glb, parsed independently of the importer, to cross-check counts.
    fn file_json(path: &Path) -> Value {
        let bytes = std::fs::read(path).expect("asset");
        let json = if bytes.starts_with(b"glTF") {
            let len = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]) as usize;
            &bytes[20..20 + len]
        } else {
            &bytes[..]
        };
        serde_json::from_slice(json).expect("json")
    }

    fn accessor_count(json: &Value, index: &Value) -> usize {
        let i = index.as_u64().expect("index") as usize;
        json["accessors"][i]["count"].as_u64().expect("count") as usize
    }

    /// Counts from the file: per primitive (vertex count, triangle count).
    fn declared_counts(json: &Value) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for mesh in json["meshes"].as_array().expect("meshes") {
            for p in mesh["primitives"].as_array().expect("primitives") {
                let v = accessor_count(json, &p["attributes"]["POSITION"]);
                let i = if p["indices"].is_null() {
                    v
                } else {
                    accessor_count(json, &p["indices"])
                };
                out.push((v, i / 3));
            }
        }
        out
    }

    fn check_counts(model: &MeshModel, path: &Path) {
        let declared = declared_counts(&file_json(path));
        let found: Vec<(usize, usize)> = model
            .parts
            .iter()
            .map(|p| (p.positions.len(), p.triangle_count()))
            .collect();
        assert_eq!(found, declared, "{}", path.display());
        assert!(model.validate().is_ok());
        for part in &model.parts {
            assert_eq!(part.normals.len(), part.positions.len());
        }
    }

    /// Edges of a closed, consistently oriented surface: each directed edge once, and its
    /// reverse also present.
    fn is_watertight(part: &TriangleMesh) -> bool {
        let mut edges = std::collections::HashSet::new();
        for t in 0..part.triangle_count() {
            let [a, b, c] = part.triangle(t);
            for e in [(a, b), (b, c), (c, a)] {
                if !edges.insert(e) {
                    return false;
                }
            }
        }
        edges.iter().all(|&(a, b)| edges.contains(&(b, a)))
    }

    #[test]
    fn box_glb_is_a_unit_cube_with_its_material() {
        let path = asset("static/Box.glb");
        let model = import_gltf(&path).expect("Box.glb");
        check_counts(&model, &path);
        assert_eq!((model.vertex_count(), model.triangle_count()), (24, 12));
        let volume: f64 = model.parts.iter().map(TriangleMesh::signed_volume).sum();
        assert!((volume - 1.0).abs() < 1e-5, "volume {volume}");
        assert_eq!(model.materials.len(), 1);
        assert_eq!(model.materials[0].name, "Red");
        assert!(
            (model.materials[0].base_color - Vec4::new(0.8, 0.0, 0.0, 1.0))
                .abs()
                .max_element()
                < 1e-6
        );
        assert!(!model.materials[0].unlit);
        let (lo, hi) = model.bounds().expect("bounds");
        assert!(
            (lo + Vec3::splat(0.5)).abs().max_element() < 1e-6
                && (hi - Vec3::splat(0.5)).abs().max_element() < 1e-6
        );
    }

    #[test]
    fn bevy_torus_has_uvs_and_its_node_rotation() {
        let path = asset("static/bevy_torus.gltf");
        let model = import_gltf(&path).expect("torus");
        check_counts(&model, &path);
        assert_eq!((model.vertex_count(), model.triangle_count()), (1666, 3072));
        assert_eq!(model.parts[0].uvs.len(), 1666);
        // No material in the file: one default material.
        assert_eq!(model.materials.len(), 1);
        // The node turns the mesh 90° about X: the file's Y extent (POSITION min/max) becomes Z.
        let json = file_json(&path);
        let acc = &json["accessors"][0];
        let file_y = acc["max"][1].as_f64().expect("max") - acc["min"][1].as_f64().expect("min");
        let (lo, hi) = model.bounds().expect("bounds");
        assert!(
            ((hi.z - lo.z) as f64 - file_y).abs() < 1e-4,
            "{lo} {hi} {file_y}"
        );
        assert!(model.parts[0].signed_volume() > 0.0);
    }

    #[test]
    fn kenney_rock_has_two_materials_and_its_node_translation() {
        let path = asset("static/kenney_rock_largeA.glb");
        let model = import_gltf(&path).expect("rock");
        check_counts(&model, &path);
        assert_eq!(model.triangle_count(), 71 + 9);
        assert_eq!(model.materials.len(), 2);
        assert_eq!((model.parts[0].material, model.parts[1].material), (0, 1));
        let (dirt, grass) = (&model.materials[0], &model.materials[1]);
        assert_eq!((dirt.name.as_str(), grass.name.as_str()), ("dirt", "grass"));
        assert!(
            (dirt.base_color - Vec4::new(0.886_274_5, 0.513_725_5, 0.341_176_48, 1.0))
                .abs()
                .max_element()
                < 1e-6
        );
        assert!(
            (grass.base_color - Vec4::new(0.172_549, 0.847_058_83, 0.721_568_64, 1.0))
                .abs()
                .max_element()
                < 1e-6
        );
        // extensionsUsed lists KHR_materials_unlit but neither material carries it.
        assert!(!dirt.unlit && !grass.unlit);
        // Node translation (0, -0.05, 0) applied; the file's POSITION min y is -2.9e-16.
        let (lo, _) = model.bounds().expect("bounds");
        assert!((lo.y + 0.05).abs() < 1e-6, "{lo}");
    }

    /// The Spot GLB has no `NORMAL`: the reader computes flat normals, as the glTF
    /// specification asks (Blender and three.js shade it faceted too), splitting its 2,930
    /// shared vertices where faces meet; by position it is as watertight as before.
    #[test]
    fn spot_glb_is_watertight_with_computed_flat_normals() {
        let path = asset("static/spot/spot_triangulated.derived.glb");
        let model = import_gltf(&path).expect("spot");
        assert!(model.validate().is_ok());
        assert_eq!(model.triangle_count(), 5856);
        let part = &model.parts[0];
        assert_eq!(part.normals.len(), part.positions.len());
        // A smooth mesh's triangles face different ways: its vertices are split.
        assert!(model.vertex_count() > 2 * 2930, "{}", model.vertex_count());
        let mut by_position: HashMap<[u32; 3], u32> = HashMap::new();
        let welded = TriangleMesh {
            indices: part
                .indices
                .iter()
                .map(|&i| {
                    let p = part.positions[i as usize].to_array().map(f32::to_bits);
                    let next = by_position.len() as u32;
                    *by_position.entry(p).or_insert(next)
                })
                .collect(),
            positions: vec![Vec3::ZERO; 2930],
            ..TriangleMesh::default()
        };
        assert_eq!(by_position.len(), 2930, "the file's vertices, by position");
        assert!(is_watertight(&welded));
        assert!(part.signed_volume() > 0.0);
        for t in 0..part.triangle_count() {
            let [a, b, c] = part.triangle(t);
            let face = (part.positions[b] - part.positions[a])
                .cross(part.positions[c] - part.positions[a])
                .normalize_or_zero();
            for v in [a, b, c] {
                assert!(part.normals[v].dot(face) > 0.9999, "triangle {t}");
            }
        }
    }

    /// Flat normals keep the vertices that faces facing the same way share: a cube of 8
    /// shared corners becomes 24 vertices (4 a face), its 12 triangles unchanged.
    #[test]
    fn flat_normals_split_only_where_faces_turn() {
        let mut cube = crate::mesh::unit_cube();
        let shared: Vec<Vec3> = {
            let mut p = cube.positions.clone();
            p.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
            p.dedup();
            p
        };
        assert_eq!(shared.len(), 8, "the cube shares its corners");
        let triangles = cube.indices.clone();
        cube.normals.clear();
        cube.compute_flat_normals();
        assert_eq!(cube.positions.len(), 24);
        assert_eq!(cube.normals.len(), 24);
        assert_eq!(cube.triangle_count(), 12);
        for t in 0..12 {
            let [a, b, c] = cube.triangle(t);
            let n = cube.normals[a];
            assert!(
                n == cube.normals[b] && n == cube.normals[c],
                "one normal a face"
            );
            assert_eq!(n.abs().max_element(), 1.0, "an axis: {n}");
            // Same corners as before, in the same order.
            let old: Vec<Vec3> = triangles[3 * t..3 * t + 3]
                .iter()
                .map(|&i| crate::mesh::unit_cube().positions[i as usize])
                .collect();
            assert_eq!(
                old,
                [cube.positions[a], cube.positions[b], cube.positions[c]]
            );
        }
    }

    #[test]
    fn cesium_man_is_textured_skinned_and_left_in_mesh_space() {
        let path = asset("skinned/CesiumMan.glb");
        let model = import_gltf(&path).expect("CesiumMan");
        check_counts(&model, &path);
        assert_eq!((model.vertex_count(), model.triangle_count()), (3273, 4672));
        let part = &model.parts[0];
        assert_eq!(
            (part.joints.len(), part.weights.len(), part.uvs.len()),
            (3273, 3273, 3273)
        );
        assert!(part.joints.iter().flatten().all(|&j| j < 19));
        assert!(
            part.weights
                .iter()
                .all(|w| (w.iter().sum::<f32>() - 1.0).abs() < 1e-3)
        );
        let texture = model.materials[0]
            .base_color_texture
            .as_ref()
            .expect("texture");
        assert!(
            texture.width > 0
                && texture.rgba8.len() == (texture.width * texture.height * 4) as usize
        );
        // Skinned: positions are the file's POSITION values, not moved by the Z_UP node.
        let json = file_json(&path);
        let acc = &json["accessors"][3];
        let (lo, hi) = model.bounds().expect("bounds");
        for k in 0..3 {
            assert!((f64::from(lo[k]) - acc["min"][k].as_f64().expect("min")).abs() < 1e-5);
            assert!((f64::from(hi[k]) - acc["max"][k].as_f64().expect("max")).abs() < 1e-5);
        }
    }

    #[test]
    fn rigged_figure_and_simple_skin_keep_joints() {
        let path = asset("skinned/RiggedFigure.glb");
        let model = import_gltf(&path).expect("RiggedFigure");
        check_counts(&model, &path);
        assert_eq!((model.vertex_count(), model.triangle_count()), (370, 256));
        assert!(model.parts[0].joints.iter().flatten().all(|&j| j < 19));

        let path = asset("skinned/SimpleSkin.gltf");
        let model = import_gltf(&path).expect("SimpleSkin");
        check_counts(&model, &path);
        assert_eq!((model.vertex_count(), model.triangle_count()), (10, 8));
        let part = &model.parts[0];
        assert_eq!((part.joints.len(), part.weights.len()), (10, 10));
        assert!(part.joints.iter().flatten().all(|&j| j < 2));
        assert!(
            part.weights
                .iter()
                .all(|w| (w.iter().sum::<f32>() - 1.0).abs() < 1e-6)
        );
    }

    // ---- hand-built files ----

    fn base64(bytes: &[u8]) -> String {
        const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut s = String::new();
        for chunk in bytes.chunks(3) {
            let n = chunk
                .iter()
                .enumerate()
                .fold(0u32, |acc, (i, &b)| acc | u32::from(b) << (16 - 8 * i));
            for i in 0..4 {
                if i <= chunk.len() {
                    s.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
                } else {
                    s.push('=');
                }
            }
        }
        s
    }

    /// A glTF document under construction: one binary buffer, views and accessors.
    #[derive(Default)]
    pub(crate) struct Doc {
        pub(crate) bin: Vec<u8>,
        pub(crate) views: Vec<Value>,
        pub(crate) accessors: Vec<Value>,
    }

    impl Doc {
        pub(crate) fn accessor(
            &mut self,
            bytes: &[u8],
            ty: &str,
            component: u32,
            count: usize,
        ) -> usize {
            while !self.bin.len().is_multiple_of(4) {
                self.bin.push(0);
            }
            self.views.push(
                json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}),
            );
            self.bin.extend_from_slice(bytes);
            self.accessors.push(json!({"bufferView": self.views.len() - 1, "type": ty, "componentType": component, "count": count}));
            self.accessors.len() - 1
        }

        pub(crate) fn floats(&mut self, values: &[f32], ty: &str, dims: usize) -> usize {
            let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
            self.accessor(&bytes, ty, 5126, values.len() / dims)
        }

        /// The document as .gltf JSON with the buffer in a data URI.
        pub(crate) fn gltf(&self, mut root: Value) -> Vec<u8> {
            root["asset"] = json!({"version": "2.0"});
            root["buffers"] = json!([{"byteLength": self.bin.len(), "uri": format!("data:application/octet-stream;base64,{}", base64(&self.bin))}]);
            root["bufferViews"] = Value::Array(self.views.clone());
            root["accessors"] = Value::Array(self.accessors.clone());
            serde_json::to_vec(&root).expect("json")
        }

        /// The document as .glb.
        pub(crate) fn glb(&self, mut root: Value) -> Vec<u8> {
            root["asset"] = json!({"version": "2.0"});
            root["buffers"] = json!([{"byteLength": self.bin.len()}]);
            root["bufferViews"] = Value::Array(self.views.clone());
            root["accessors"] = Value::Array(self.accessors.clone());
            let mut json = serde_json::to_vec(&root).expect("json");
            while !json.len().is_multiple_of(4) {
                json.push(b' ');
            }
            let mut bin = self.bin.clone();
            while !bin.len().is_multiple_of(4) {
                bin.push(0);
            }
            let mut out = Vec::new();
            out.extend_from_slice(b"glTF");
            out.extend_from_slice(&2u32.to_le_bytes());
            out.extend_from_slice(&((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
            out.extend_from_slice(&(json.len() as u32).to_le_bytes());
            out.extend_from_slice(b"JSON");
            out.extend_from_slice(&json);
            out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
            out.extend_from_slice(b"BIN\0");
            out.extend_from_slice(&bin);
            out
        }
    }

    /// A unit quad (4 vertices) in the z = 0 plane.
    pub(crate) const QUAD: [f32; 12] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];

    fn png_2x1() -> Vec<u8> {
        let img =
            image::RgbaImage::from_raw(2, 1, vec![255, 0, 0, 255, 0, 0, 255, 255]).expect("image");
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png)
            .expect("png");
        out.into_inner()
    }

    #[test]
    fn strips_fans_u8_indices_non_indexed_and_vertex_colours() {
        let mut doc = Doc::default();
        let pos = doc.floats(&QUAD, "VEC3", 3);
        let strip = doc.accessor(&[0, 1, 3, 2], "SCALAR", 5121, 4);
        let colors = doc.accessor(
            &[
                255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 128, 255, 255, 255, 0,
            ],
            "VEC4",
            5121,
            4,
        );
        let mut acc = doc.accessors.clone();
        acc[colors]["normalized"] = json!(true);
        doc.accessors = acc;
        let bytes = doc.gltf(json!({
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [
                {"attributes": {"POSITION": pos, "COLOR_0": colors}, "indices": strip, "mode": 5},
                {"attributes": {"POSITION": pos}, "mode": 6},
                {"attributes": {"POSITION": pos}, "mode": 4, "indices": strip},
                {"attributes": {"POSITION": pos}, "mode": 1}
            ]}]
        }));
        // Triangles mode with 4 indices is not whole triangles.
        let err = import_gltf_slice(&bytes, None).expect_err("4 indices in triangles mode");
        assert!(
            err.to_string().contains("not a whole number of triangles"),
            "{err}"
        );

        let bytes = doc.gltf(json!({
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [
                {"attributes": {"POSITION": pos, "COLOR_0": colors}, "indices": strip, "mode": 5},
                {"attributes": {"POSITION": pos}, "mode": 6},
                {"attributes": {"POSITION": pos}, "mode": 1}
            ]}]
        }));
        // No scenes: root nodes are imported.
        let model = import_gltf_slice(&bytes, None).expect("strips");
        assert_eq!(model.parts.len(), 2, "the line primitive is skipped");
        let (strip_part, fan_part) = (&model.parts[0], &model.parts[1]);
        assert_eq!(strip_part.indices, vec![0, 1, 3, 1, 2, 3]);
        assert_eq!(fan_part.indices, vec![1, 2, 0, 2, 3, 0]);
        for part in &model.parts {
            // Both cover the unit square, front faces toward +z.
            assert!((part.area() - 1.0).abs() < 1e-6);
            assert!(part.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
        }
        assert_eq!(strip_part.colors[1], Vec4::new(0.0, 1.0, 0.0, 1.0));
        assert!((strip_part.colors[2].w - 128.0 / 255.0).abs() < 1e-6);
        assert!(fan_part.colors.is_empty());
    }

    #[test]
    fn unlit_materials_and_textures_from_glb_data_uri_and_file() {
        let png = png_2x1();
        let mut doc = Doc::default();
        let pos = doc.floats(&QUAD[..9], "VEC3", 3);
        let uv = doc.floats(&[0.25, 0.5, 0.75, 0.5, 0.75, 0.5], "VEC2", 2);
        doc.accessor(&png, "SCALAR", 5121, png.len());
        let image_view = doc.views.len() - 1;
        doc.accessors.pop();
        let root = |image: Value| {
            json!({
                "extensionsUsed": ["KHR_materials_unlit", "EXT_something_optional"],
                "extensionsRequired": ["KHR_materials_unlit"],
                "scene": 0,
                "scenes": [{"nodes": [0]}],
                "nodes": [{"mesh": 0, "translation": [0.0, 0.0, 5.0]}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": 0}]}],
                "materials": [{"name": "glow", "extensions": {"KHR_materials_unlit": {}},
                    "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "baseColorTexture": {"index": 0}}}],
                "textures": [{"source": 0}],
                "images": [image]
            })
        };
        let check = |model: &MeshModel| {
            let m = &model.materials[0];
            assert!(m.unlit);
            assert_eq!(m.name, "glow");
            let t = m.base_color_texture.as_ref().expect("texture");
            assert_eq!((t.width, t.height), (2, 1));
            assert_eq!(t.rgba8, vec![255, 0, 0, 255, 0, 0, 255, 255]);
            // Left texel red, right texel blue; texture × factor 0.5.
            let c = model.surface_color(&model.parts[0], 0, Vec3::new(1.0, 0.0, 0.0));
            assert!(
                (c - Vec4::new(0.5, 0.0, 0.0, 1.0)).abs().max_element() < 1e-6,
                "{c}"
            );
            assert!((model.parts[0].positions[0].z - 5.0).abs() < 1e-6);
        };
        // Embedded in the GLB binary chunk.
        let glb = doc.glb(root(
            json!({"bufferView": image_view, "mimeType": "image/png"}),
        ));
        check(&import_gltf_slice(&glb, None).expect("glb"));
        // Data URI.
        let gltf = doc.gltf(root(
            json!({"uri": format!("data:image/png;base64,{}", base64(&png))}),
        ));
        check(&import_gltf_slice(&gltf, None).expect("data uri"));
        // External file beside the .gltf (percent-encoded name).
        let dir = tempfile::tempdir().expect("temp dir");
        std::fs::write(dir.path().join("my tex.png"), &png).expect("write");
        let gltf = doc.gltf(root(json!({"uri": "my%20tex.png"})));
        let path = dir.path().join("scene.gltf");
        std::fs::write(&path, &gltf).expect("write");
        check(&import_gltf(&path).expect("external image"));
        // From memory, external files are refused rather than read.
        let err = import_gltf_slice(&gltf, None).expect_err("no base dir");
        assert!(matches!(err, IoError::Unsupported { .. }), "{err}");
        assert!(err.to_string().contains("my%20tex.png"), "{err}");
    }

    #[test]
    fn required_unknown_extensions_are_refused_optional_ones_ignored() {
        let mut doc = Doc::default();
        let pos = doc.floats(&QUAD[..9], "VEC3", 3);
        let root = |required: &[&str]| {
            json!({"extensionsUsed": ["KHR_draco_mesh_compression"], "extensionsRequired": required,
                "nodes": [{"mesh": 0}], "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]})
        };
        assert!(import_gltf_slice(&doc.gltf(root(&[])), None).is_ok());
        let err = import_gltf_slice(&doc.gltf(root(&["KHR_draco_mesh_compression"])), None)
            .expect_err("draco");
        assert!(matches!(err, IoError::Unsupported { .. }));
        assert!(
            err.to_string().contains("KHR_draco_mesh_compression"),
            "{err}"
        );
    }

    /// The import report of `bytes` read by the static reader.
    fn report_of(bytes: &[u8]) -> Vec<String> {
        Importer {
            path: Path::new("case.gltf"),
            base_dir: None,
            limits: &ImportLimits::default(),
        }
        .run_imported(bytes)
        .expect("imports")
        .report
    }

    #[test]
    fn features_left_out_are_reported_not_dropped_silently() {
        let mut doc = Doc::default();
        let pos = doc.floats(&QUAD[..9], "VEC3", 3);
        let uv = doc.floats(&[0.0, 0.0, 1.0, 0.0, 1.0, 1.0], "VEC2", 2);
        let morph = doc.floats(&[0.0, 0.0, 0.5, 0.0, 0.0, 0.5, 0.0, 0.0, 0.5], "VEC3", 3);
        let times = doc.floats(&[0.0, 1.0], "SCALAR", 1);
        let weights = doc.floats(&[0.0, 1.0], "SCALAR", 1);
        let png = format!("data:image/png;base64,{}", base64(&png_2x1()));
        let plain = json!({"nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}}]}]});
        assert_eq!(report_of(&doc.gltf(plain)), Vec::<String>::new());

        let full = json!({
            "extensionsUsed": ["KHR_texture_transform", "KHR_lights_punctual"],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point"}, {"type": "directional"}]}},
            "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0, 0, 3]}],
            "cameras": [{"name": "Shot", "type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
            "images": [{"uri": png}], "textures": [{"source": 0}],
            "materials": [{"normalTexture": {"index": 0},
                "pbrMetallicRoughness": {"metallicRoughnessTexture": {"index": 0}}}],
            "meshes": [{"name": "Face", "weights": [0.0], "primitives": [{
                "attributes": {"POSITION": pos, "TEXCOORD_0": uv, "TEXCOORD_1": uv},
                "targets": [{"POSITION": morph}], "material": 0}]}],
            "animations": [{"name": "Smile", "samplers": [{"input": times, "output": weights}],
                "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]}]
        });
        let report = report_of(&doc.gltf(full));
        let has = |words: &[&str]| {
            report
                .iter()
                .any(|line| words.iter().all(|w| line.contains(w)))
        };
        assert!(has(&["1 morph target(s)", "\"Face\""]), "{report:#?}");
        assert!(has(&["1 animation(s)", "\"Smile\""]), "{report:#?}");
        assert!(has(&["TEXCOORD_1 on 1 primitive(s)"]), "{report:#?}");
        assert!(has(&["normal ×1", "metallic-roughness ×1"]), "{report:#?}");
        assert!(has(&["1 camera(s)", "\"Shot\""]), "{report:#?}");
        // The point light is reported; the directional one is placed by no node.
        assert!(
            has(&[
                "lights: 0 directional imported, 1 point/spot not imported",
                "1 directional not placed"
            ]),
            "{report:#?}"
        );
        assert!(
            has(&["not supported", "KHR_texture_transform"]),
            "{report:#?}"
        );
        assert_eq!(report.len(), 7, "one line per kind: {report:#?}");
    }

    #[test]
    fn graph_errors_cycles_missing_references_and_bad_indices() {
        let mut doc = Doc::default();
        let pos = doc.floats(&QUAD[..9], "VEC3", 3);
        let bad_index = doc.accessor(&[0, 1, 7], "SCALAR", 5121, 3);
        let cases: Vec<(Value, &str)> = vec![
            (
                json!({"scenes": [{"nodes": [0]}], "nodes": [{"children": [1]}, {"children": [0]}]}),
                "node 0 is reached twice",
            ),
            (
                json!({"scenes": [{"nodes": [0]}], "nodes": [{"children": [1, 1]}, {}]}),
                "node 1 is reached twice",
            ),
            (
                json!({"scenes": [{"nodes": [3]}], "nodes": []}),
                "node 3, which does not exist",
            ),
            (
                json!({"scene": 2, "scenes": [{"nodes": []}]}),
                "default scene 2",
            ),
            (
                json!({"nodes": [{"mesh": 4}]}),
                "mesh 4, which does not exist",
            ),
            (
                json!({"nodes": [{"mesh": 0}], "meshes": [{"name": "Body", "primitives": [{"attributes": {"POSITION": 9}}]}]}),
                "accessor 9 (POSITION of mesh 'Body' primitive 0) does not exist",
            ),
            (
                json!({"nodes": [{"mesh": 0}], "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": bad_index}]}]}),
                "index 7 at position 2 is not below the vertex count 3",
            ),
            (
                json!({"nodes": [{"mesh": 0}], "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "material": 0}]}]}),
                "material 0, which does not exist",
            ),
            (
                json!({"nodes": [{"mesh": 0, "rotation": [0.0, 0.0, 0.0, 0.0]}], "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]}),
                "not a unit quaternion",
            ),
            // Positions beyond ±1e18 would overflow squared distances (cameras, bounds): the
            // file is refused, naming the vertex, instead of a broken camera later.
            (
                json!({"nodes": [{"mesh": 0, "scale": [1e30, 1e30, 1e30], "matrix": [1e30,0,0,0, 0,1e30,0,0, 0,0,1e30,0, 0,0,0,1]}],
                    "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}],
                    "accessors_extra": 0}),
                "vertex 1 lies at [1e30, 0.0, 0.0], beyond ±1e18 units",
            ),
            (
                json!({"nodes": [{"mesh": 0, "matrix": [1e15,0,0,0, 0,1e15,0,0, 0,0,1e15,0, 0,0,0,1]}],
                    "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}],
                    "accessors_extra": 0}),
                "",
            ),
        ];
        for (root, expected) in cases {
            let result = import_gltf_slice(&doc.gltf(root.clone()), None);
            if expected.is_empty() {
                // Large transforms within the range are fine.
                assert!(result.is_ok(), "{root}: {result:?}");
                continue;
            }
            let err = result.expect_err(expected);
            assert!(err.to_string().starts_with("<memory>: "), "{err}");
            assert!(
                err.to_string().contains(expected),
                "expected '{expected}' in '{err}'"
            );
        }
    }

    // ---- the must-show bad inputs ----

    #[test]
    fn empty_truncated_and_wrong_magic_files_are_clear_errors() {
        let dir = tempfile::tempdir().expect("temp dir");
        let write = |name: &str, bytes: &[u8]| {
            let p = dir.path().join(name);
            std::fs::write(&p, bytes).expect("write");
            p
        };
        let empty = write("empty.glb", &[]);
        let err = import_gltf(&empty).expect_err("empty");
        assert!(
            matches!(err, IoError::Truncated { .. }) && err.to_string().contains("empty.glb"),
            "{err}"
        );
        assert!(err.to_string().contains("empty"), "{err}");

        let boxed = std::fs::read(asset("static/Box.glb")).expect("Box.glb");
        for cut in [5, 12, 19, 100, boxed.len() / 2, boxed.len() - 1] {
            let p = write("cut.glb", &boxed[..cut]);
            let err = import_gltf(&p).expect_err("truncated");
            assert!(err.to_string().contains("cut.glb"), "{err}");
            assert!(
                matches!(err, IoError::Truncated { .. }),
                "cut at {cut}: {err}"
            );
        }
        let mut wrong = boxed.clone();
        wrong[..4].copy_from_slice(b"glTX");
        let p = write("wrong_magic.glb", &wrong);
        let err = import_gltf(&p).expect_err("magic");
        assert!(matches!(err, IoError::Parse { .. }), "{err}");
        assert!(
            err.to_string().contains("wrong_magic.glb") && err.to_string().contains("67 6c 54 58"),
            "{err}"
        );

        let mut version = boxed.clone();
        version[4] = 1;
        let err = import_gltf_slice(&version, None).expect_err("version");
        assert!(err.to_string().contains("GLB version 1"), "{err}");
        let mut short = boxed;
        short[8..12].copy_from_slice(&3u32.to_le_bytes());
        let err = import_gltf_slice(&short, None).expect_err("length < header");
        assert!(err.to_string().contains("less than the header"), "{err}");
    }

    #[test]
    fn accessor_count_past_its_buffer_names_the_accessor() {
        let dir = tempfile::tempdir().expect("temp dir");
        let mut json = file_json(&asset("skinned/SimpleSkin.gltf"));
        json["accessors"][1]["count"] = json!(4000);
        let path = dir.path().join("SimpleSkin_bad_count.gltf");
        std::fs::write(&path, serde_json::to_vec(&json).expect("json")).expect("write");
        let err = import_gltf(&path).expect_err("count past buffer");
        let text = err.to_string();
        assert!(matches!(err, IoError::Invalid { .. }), "{text}");
        assert!(text.contains("SimpleSkin_bad_count.gltf"), "{text}");
        assert!(
            text.contains("accessor 1 (POSITION of mesh 0 primitive 0): count 4000"),
            "{text}"
        );
        assert!(text.contains("exceeds buffer view 1 length 120"), "{text}");

        // Buffer view past its buffer; buffer shorter than declared; count over the limits.
        let mut json = file_json(&asset("skinned/SimpleSkin.gltf"));
        json["bufferViews"][1]["byteLength"] = json!(1000);
        let err =
            import_gltf_slice(&serde_json::to_vec(&json).expect("json"), None).expect_err("view");
        assert!(
            err.to_string()
                .contains("runs past the 168 bytes of buffer 0"),
            "{err}"
        );
        let mut json = file_json(&asset("skinned/SimpleSkin.gltf"));
        json["buffers"][0]["byteLength"] = json!(1u64 << 40);
        let err =
            import_gltf_slice(&serde_json::to_vec(&json).expect("json"), None).expect_err("buffer");
        assert!(
            matches!(err, IoError::Truncated { .. })
                && err
                    .to_string()
                    .contains("buffer 0 declares byteLength 1099511627776"),
            "{err}"
        );
        let mut json = file_json(&asset("skinned/SimpleSkin.gltf"));
        json["accessors"][1]["count"] = json!(1u64 << 40);
        let err = import_gltf_slice(&serde_json::to_vec(&json).expect("json"), None)
            .expect_err("huge count");
        assert!(matches!(err, IoError::TooLarge { .. }), "{err}");
        let mut json = file_json(&asset("skinned/SimpleSkin.gltf"));
        json["bufferViews"][2]["byteStride"] = json!(4);
        let err =
            import_gltf_slice(&serde_json::to_vec(&json).expect("json"), None).expect_err("stride");
        assert!(
            err.to_string()
                .contains("byteStride 4 is invalid for 8-byte elements"),
            "{err}"
        );
    }

    #[test]
    fn instancing_counts_against_the_vertex_limit() {
        let mut doc = Doc::default();
        let pos = doc.floats(&QUAD[..9], "VEC3", 3);
        let nodes: Vec<Value> = (0..100).map(|_| json!({"mesh": 0})).collect();
        let bytes = doc.gltf(json!({"nodes": nodes, "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]}));
        let model = import_gltf_slice(&bytes, None).expect("100 instances");
        assert_eq!(model.vertex_count(), 300);
        let limits = ImportLimits {
            max_vertices: 299,
            ..ImportLimits::default()
        };
        let err = import_gltf_slice_with(&bytes, None, Path::new("many.gltf"), &limits)
            .expect_err("limit");
        assert!(
            matches!(err, IoError::TooLarge { .. }) && err.to_string().contains("limit is 299"),
            "{err}"
        );
    }

    #[test]
    fn base64_and_percent_decoding() {
        for len in 0..20u8 {
            let data: Vec<u8> = (0..len).map(|i| i.wrapping_mul(37)).collect();
            assert_eq!(decode_base64(&base64(&data)), Ok(data));
        }
        assert_eq!(decode_base64("QUJD\nRA=="), Ok(b"ABCD".to_vec()));
        assert_eq!(decode_base64("QU*J"), Err(2));
        assert_eq!(decode_base64("QQ==QQ"), Err(4));
        assert_eq!(
            percent_decode("a%20b%2Fc.bin").as_deref(),
            Some("a b/c.bin")
        );
        assert_eq!(percent_decode("bad%2"), None);
        assert_eq!(percent_decode("bad%zz"), None);
    }
}

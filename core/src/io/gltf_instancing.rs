//! `EXT_mesh_gpu_instancing` and `MSFT_lod` for the glTF reader, and the up-front count of
//! what an import will build.
//!
//! **Instancing.** A node with `EXT_mesh_gpu_instancing` draws its mesh once per instance, at
//! `world_from_node × T × R × S` of the instance (the extension's `TRANSLATION`, `ROTATION`
//! and `SCALE` accessors; a missing one is the identity). The reader expands each instance
//! into its own copy of the mesh. Accessors are checked as the extension's specification
//! says: `TRANSLATION` and `SCALE` are float `VEC3`, `ROTATION` a float or normalised byte or
//! short `VEC4`, all of one count; every value is finite and every rotation a non-zero
//! quaternion (normalised here).
//!
//! **Levels of detail.** `MSFT_lod` lists coarser alternatives of a node as other nodes. The
//! reader keeps the node itself, the finest level; level nodes outside the scene are never
//! read (Thicket's exporter writes them so), and [`level_of_detail_note`] says so.
//!
//! **Counting first.** [`SceneSize`] adds up the vertices, indices and bytes the import will
//! build, every instance counted, from the checked accessor counts, before any mesh is read:
//! a small file that places a mesh millions of times is refused at once with the figures,
//! never expanded until an allocation fails.

use std::borrow::Cow;

use glam::{Mat4, Quat, Vec3};
use gltf::json;
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use super::error::IoError;
use super::gltf_mesh::Importer;
use crate::budget::thousands;

/// The extension that draws a node's mesh once per instance.
pub(crate) const INSTANCING: &str = "EXT_mesh_gpu_instancing";

/// The extension that lists a node's coarser levels of detail.
pub(crate) const LOD: &str = "MSFT_lod";

/// Vertex bytes every imported vertex costs: position and normal (computed when absent).
const BASE_VERTEX_BYTES: u64 = 24;

/// The accessor indices a node's `EXT_mesh_gpu_instancing` names (at least one).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct InstanceAttributes {
    translation: Option<usize>,
    rotation: Option<usize>,
    scale: Option<usize>,
}

/// The object of extension `name` on `node`, if it has one.
fn extension<'n>(node: &'n json::Node, name: &str) -> Option<&'n json::Value> {
    node.extensions.as_ref().and_then(|e| e.others.get(name))
}

/// Whether `node` has `EXT_mesh_gpu_instancing`.
pub(crate) fn is_instanced(node: &json::Node) -> bool {
    extension(node, INSTANCING).is_some()
}

/// The accessors `node`'s instancing extension names, `None` without the extension, or what
/// is wrong with the extension object.
fn instance_attributes(node: &json::Node) -> Result<Option<InstanceAttributes>, String> {
    let Some(ext) = extension(node, INSTANCING) else {
        return Ok(None);
    };
    let Some(attributes) = ext.get("attributes").and_then(json::Value::as_object) else {
        return Err("has no \"attributes\" object".to_owned());
    };
    let index = |name: &str| -> Result<Option<usize>, String> {
        match attributes.get(name) {
            None => Ok(None),
            Some(v) => v
                .as_u64()
                .and_then(|i| usize::try_from(i).ok())
                .map(Some)
                .ok_or_else(|| format!("attribute {name} is {v}, not an accessor index")),
        }
    };
    let found = InstanceAttributes {
        translation: index("TRANSLATION")?,
        rotation: index("ROTATION")?,
        scale: index("SCALE")?,
    };
    if found.translation.is_none() && found.rotation.is_none() && found.scale.is_none() {
        // Application attributes (`_ID`) alone place nothing.
        return Err("has none of TRANSLATION, ROTATION and SCALE".to_owned());
    }
    Ok(Some(found))
}

/// What an import will build, every instance counted: checked before anything is built.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct SceneSize {
    /// Vertices over all parts, as the file holds them.
    pub(crate) vertices: u64,
    /// At most this many more: the copies of vertices split where the reader computes flat
    /// normals for a primitive without `NORMAL` (one per triangle corner at worst).
    pub(crate) flat_normal_vertices: u64,
    /// Triangle-list indices over all parts (an upper bound for strips and fans).
    pub(crate) indices: u64,
    /// Bytes of vertex attributes and indices: the parts, plus one template per primitive.
    pub(crate) bytes: u64,
    /// Nodes with `EXT_mesh_gpu_instancing` among the scene's nodes with meshes.
    pub(crate) instanced_nodes: u64,
    /// The instances those nodes place.
    pub(crate) instances: u64,
}

impl SceneSize {
    /// Triangles over all parts (an upper bound, as `indices`).
    pub(crate) fn triangles(&self) -> u64 {
        self.indices / 3
    }
}

impl Importer<'_> {
    /// The instance transforms (`T × R × S`, each checked) of node `node_index`, or `None`
    /// when it has no `EXT_mesh_gpu_instancing`.
    pub(super) fn node_instances(
        &self,
        root: &json::Root,
        buffers: &[Cow<'_, [u8]>],
        node_index: usize,
        node: &json::Node,
    ) -> Result<Option<Vec<Mat4>>, IoError> {
        let attributes = instance_attributes(node)
            .map_err(|e| self.invalid(format!("node {node_index}: {INSTANCING} {e}")))?;
        let Some(attributes) = attributes else {
            return Ok(None);
        };
        if node.skin.is_some() {
            return Err(IoError::unsupported(
                self.path,
                format!(
                    "node {node_index} is skinned and has {INSTANCING}: its joints place its \
                     mesh, so instances of it cannot be placed"
                ),
            ));
        }
        let what = |accessor: usize, role: &str| {
            format!("accessor {accessor} ({role} of node {node_index}'s {INSTANCING})")
        };
        let mut count: Option<(usize, &str)> = None;
        let mut read = |index: Option<usize>,
                        role: &'static str,
                        ty: Type,
                        components: &[ComponentType]|
         -> Result<Option<Vec<f32>>, IoError> {
            let Some(index) = index else {
                return Ok(None);
            };
            let w = what(index, role);
            let data = self.accessor(root, buffers, index, &w, &[ty], components)?;
            // The specification allows integer rotations only as normalised values.
            if data.component != ComponentType::F32 && !data.normalized {
                return Err(self.invalid(format!("{w}: integer components must be normalized")));
            }
            match count {
                Some((n, first)) if n != data.count => {
                    return Err(self.invalid(format!(
                        "{w}: count {} differs from {first} count {n}",
                        data.count
                    )));
                }
                Some(_) => {}
                None => count = Some((data.count, role)),
            }
            let mut values = Vec::with_capacity(data.count * data.dims);
            for i in 0..data.count {
                let start = values.len();
                values.extend((0..data.dims).map(|c| data.component(i, c)));
                if let Some(bad) = values[start..].iter().find(|v| !v.is_finite()) {
                    return Err(self.invalid(format!("{w}: instance {i} has the value {bad}")));
                }
            }
            Ok(Some(values))
        };
        let float_only = [ComponentType::F32];
        let translations = read(
            attributes.translation,
            "TRANSLATION",
            Type::Vec3,
            &float_only,
        )?;
        let rotations = read(
            attributes.rotation,
            "ROTATION",
            Type::Vec4,
            &[ComponentType::F32, ComponentType::I8, ComponentType::I16],
        )?;
        let scales = read(attributes.scale, "SCALE", Type::Vec3, &float_only)?;
        let n = count.map_or(0, |(n, _)| n);
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let t = translations
                .as_deref()
                .map_or(Vec3::ZERO, |v| Vec3::from_slice(&v[i * 3..i * 3 + 3]));
            let s = scales
                .as_deref()
                .map_or(Vec3::ONE, |v| Vec3::from_slice(&v[i * 3..i * 3 + 3]));
            let r = match rotations.as_deref() {
                None => Quat::IDENTITY,
                Some(v) => {
                    let q = Quat::from_slice(&v[i * 4..i * 4 + 4]);
                    let len = q.length();
                    if !(len.is_finite() && len > 1e-6) {
                        let index = attributes.rotation.unwrap_or_default();
                        return Err(self.invalid(format!(
                            "{}: instance {i} rotation {:?} is not a unit quaternion",
                            what(index, "ROTATION"),
                            q.to_array()
                        )));
                    }
                    q / len
                }
            };
            out.push(Mat4::from_scale_rotation_translation(s, r, t));
        }
        Ok(Some(out))
    }

    /// Adds what `copies` copies of `mesh_index`'s primitives will build to `size`, from the
    /// checked accessor counts (the accessors' bytes are not read).
    pub(super) fn count_mesh(
        &self,
        root: &json::Root,
        buffers: &[Cow<'_, [u8]>],
        mesh_index: usize,
        copies: u64,
        size: &mut SceneSize,
    ) -> Result<(), IoError> {
        let Some(mesh) = root.meshes.get(mesh_index) else {
            // The read that follows names the missing mesh.
            return Ok(());
        };
        let mesh_name = mesh
            .name
            .as_deref()
            .map_or_else(|| format!("{mesh_index}"), |n| format!("'{n}'"));
        for (prim_index, primitive) in mesh.primitives.iter().enumerate() {
            let Checked::Valid(mode) = primitive.mode else {
                continue;
            };
            if matches!(
                mode,
                Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
            ) {
                continue;
            }
            let attr = |s: Semantic| {
                primitive
                    .attributes
                    .get(&Checked::Valid(s))
                    .map(json::Index::value)
            };
            let Some(pos_index) = attr(Semantic::Positions) else {
                continue;
            };
            let what = |index: usize, role: &str| {
                format!("accessor {index} ({role} of mesh {mesh_name} primitive {prim_index})")
            };
            let any = [
                ComponentType::F32,
                ComponentType::U8,
                ComponentType::I8,
                ComponentType::U16,
                ComponentType::I16,
                ComponentType::U32,
            ];
            let vertices = self
                .accessor(
                    root,
                    buffers,
                    pos_index,
                    &what(pos_index, "POSITION"),
                    &[Type::Vec3],
                    &any,
                )?
                .count as u64;
            let drawn = match primitive.indices.map(|i| i.value()) {
                Some(i) => {
                    self.accessor(root, buffers, i, &what(i, "indices"), &[Type::Scalar], &any)?
                        .count as u64
                }
                None => vertices,
            };
            let indices = match mode {
                Mode::TriangleStrip | Mode::TriangleFan => drawn.saturating_sub(2) * 3,
                _ => drawn,
            };
            // Without NORMAL the reader computes flat normals, splitting a vertex where the
            // faces around it turn: at most one more vertex per triangle corner.
            let split = if attr(Semantic::Normals).is_none() {
                indices
            } else {
                0
            };
            let mut vertex_bytes = BASE_VERTEX_BYTES;
            if primitive
                .attributes
                .keys()
                .any(|k| matches!(k, Checked::Valid(Semantic::TexCoords(_))))
            {
                vertex_bytes += 8;
            }
            if attr(Semantic::Colors(0)).is_some() {
                vertex_bytes += 16;
            }
            if attr(Semantic::Joints(0)).is_some() {
                vertex_bytes += 8 + 16;
            }
            let one = vertices
                .saturating_add(split)
                .saturating_mul(vertex_bytes)
                .saturating_add(indices.saturating_mul(4));
            size.vertices = size
                .vertices
                .saturating_add(vertices.saturating_mul(copies));
            size.flat_normal_vertices = size
                .flat_normal_vertices
                .saturating_add(split.saturating_mul(copies));
            size.indices = size.indices.saturating_add(indices.saturating_mul(copies));
            // The copies, plus the template they are cloned from.
            size.bytes = size
                .bytes
                .saturating_add(one.saturating_mul(copies.saturating_add(1)));
        }
        Ok(())
    }

    /// Refuses a scene over the limits, with its figures and where they come from.
    pub(super) fn check_scene_size(&self, size: &SceneSize) -> Result<(), IoError> {
        let l = self.limits;
        let scene = if size.instances > 0 {
            format!(
                "the scene with its {} instance(s) expanded ({INSTANCING} on {} node(s))",
                thousands(size.instances),
                thousands(size.instanced_nodes)
            )
        } else {
            "the scene".to_owned()
        };
        let advice = if size.instances > 0 {
            "export fewer placements (thicket export --instance-level) or coarser meshes \
             (--resolution)"
        } else {
            "import a smaller file"
        };
        // Indices are u32, so whatever the limits say, vertices must fit in one.
        let max_vertices = l.max_vertices.min(u64::from(u32::MAX));
        let built = size.vertices.saturating_add(size.flat_normal_vertices);
        if built > max_vertices {
            let split = if size.flat_normal_vertices > 0 {
                format!(
                    " (up to {} with the copies flat normals split off, for primitives \
                     without NORMAL)",
                    thousands(built)
                )
            } else {
                String::new()
            };
            return Err(IoError::too_large(
                self.path,
                format!(
                    "{scene} has {} vertices{split}; the limit is {} vertices: {advice}",
                    thousands(size.vertices),
                    thousands(max_vertices)
                ),
            ));
        }
        if size.indices > l.max_indices {
            return Err(IoError::too_large(
                self.path,
                format!(
                    "{scene} has up to {} triangles ({} indices); the limit is {} indices: \
                     {advice}",
                    thousands(size.triangles()),
                    thousands(size.indices),
                    thousands(l.max_indices)
                ),
            ));
        }
        let what = format!("{scene}, {} triangles,", thousands(size.triangles()));
        let advice = format!("{advice}, or raise the limit with --memory-limit");
        l.memory
            .check(&what, size.bytes, &advice)
            .map_err(|e| IoError::too_large(self.path, e.to_string()))
    }
}

/// The report's line for the instances a file places, `None` when it places none.
pub(crate) fn instancing_note(size: &SceneSize) -> Option<String> {
    (size.instances > 0).then(|| {
        format!(
            "{INSTANCING}: {} node(s) place {} instance(s) of their meshes, each imported as \
             its own copy ({} triangles in all)",
            thousands(size.instanced_nodes),
            thousands(size.instances),
            thousands(size.triangles())
        )
    })
}

/// The report's line for `MSFT_lod`: how many nodes list levels and how many level nodes
/// were left out; `None` when no node lists any.
pub(crate) fn level_of_detail_note(root: &json::Root) -> Option<String> {
    let mut nodes = 0u64;
    let mut levels = 0u64;
    for node in &root.nodes {
        if let Some(ids) = extension(node, LOD)
            .and_then(|e| e.get("ids"))
            .and_then(json::Value::as_array)
        {
            nodes += 1;
            levels += ids.len() as u64;
        }
    }
    (nodes > 0).then(|| {
        format!(
            "{LOD}: {nodes} node(s) list {levels} coarser level(s) of detail; the finest \
             level (the node's own mesh) is imported, the coarser levels are not"
        )
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use std::path::Path;

    use glam::{Mat4, Quat, Vec3};
    use serde_json::{Value, json};

    use crate::io::error::{ImportLimits, IoError};
    use crate::io::gltf_mesh::import_gltf_slice_imported;
    use crate::io::gltf_mesh::tests::{Doc, QUAD};

    /// The three instances of [`instanced`]: plain, turned 90° about Z and doubled, mirrored.
    fn instance_transforms() -> [(Vec3, Quat, Vec3); 3] {
        [
            (Vec3::ZERO, Quat::IDENTITY, Vec3::ONE),
            (
                Vec3::new(0.0, 5.0, 0.0),
                Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
                Vec3::splat(2.0),
            ),
            (
                Vec3::new(0.0, 0.0, -3.0),
                Quat::IDENTITY,
                Vec3::new(-1.0, 1.0, 1.0),
            ),
        ]
    }

    /// The node of [`instanced`]: at (10, 0, 0), turned 90° about Y.
    fn world_from_node() -> Mat4 {
        Mat4::from_rotation_translation(
            Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
            Vec3::new(10.0, 0.0, 0.0),
        )
    }

    /// A triangle drawn by node "Trees" at its three instances and by node "Plain" once, as
    /// the document and the root JSON (which tests change before writing it).
    fn instanced() -> (Doc, Value) {
        let mut doc = Doc::default();
        let pos = doc.floats(&QUAD[..9], "VEC3", 3);
        let instances = instance_transforms();
        let t: Vec<f32> = instances.iter().flat_map(|i| i.0.to_array()).collect();
        let r: Vec<f32> = instances.iter().flat_map(|i| i.1.to_array()).collect();
        let s: Vec<f32> = instances.iter().flat_map(|i| i.2.to_array()).collect();
        let t = doc.floats(&t, "VEC3", 3);
        let r = doc.floats(&r, "VEC4", 4);
        let s = doc.floats(&s, "VEC3", 3);
        let q = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let root = json!({
            "extensionsUsed": ["EXT_mesh_gpu_instancing"],
            "extensionsRequired": ["EXT_mesh_gpu_instancing"],
            "scenes": [{"nodes": [0, 1]}],
            "nodes": [
                {"name": "Trees", "mesh": 0, "translation": [10.0, 0.0, 0.0],
                 "rotation": q.to_array(),
                 "extensions": {"EXT_mesh_gpu_instancing": {"attributes":
                    {"TRANSLATION": t, "ROTATION": r, "SCALE": s, "_ID": t}}}},
                {"name": "Plain", "mesh": 0}
            ],
            "meshes": [{"name": "Tri", "primitives": [{"attributes": {"POSITION": pos}}]}]
        });
        (doc, root)
    }

    fn import(bytes: &[u8]) -> Result<crate::io::GltfImport, IoError> {
        import_gltf_slice_imported(bytes, Path::new("inst.glb"), &ImportLimits::default())
    }

    /// A refusal said in one line, naming the file, of the expected kind and saying `says`.
    fn assert_refused(result: Result<crate::io::GltfImport, IoError>, kind: &str, says: &str) {
        let err = result.expect_err(says);
        let text = err.to_string();
        assert!(text.starts_with("inst.glb: "), "{text}");
        assert!(!text.contains('\n'), "one line: {text}");
        let found = match err {
            IoError::Invalid { .. } => "invalid",
            IoError::TooLarge { .. } => "too large",
            IoError::Unsupported { .. } => "unsupported",
            _ => "other",
        };
        assert_eq!(found, kind, "{text}");
        assert!(text.contains(says), "{text}");
    }

    #[test]
    fn each_instance_is_the_mesh_at_node_times_instance() {
        let (doc, root) = instanced();
        let import = import(&doc.glb(root)).expect("instanced file");
        assert_eq!(import.instancing.nodes, 1);
        assert_eq!(import.instancing.instances, 3);
        assert_eq!(
            import.model.parts.len(),
            4,
            "3 instances and the plain node"
        );
        let names: Vec<&str> = import.nodes.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(names, ["Trees 0", "Trees 1", "Trees 2", "Plain"]);
        let triangle: Vec<Vec3> = QUAD[..9].chunks(3).map(Vec3::from_slice).collect();
        for (k, (t, r, s)) in instance_transforms().into_iter().enumerate() {
            let world = world_from_node() * Mat4::from_scale_rotation_translation(s, r, t);
            let node = &import.nodes[k];
            assert!(node.world_from_node.abs_diff_eq(world, 1e-5), "{k}");
            let part = &import.model.parts[node.parts.start];
            for (got, p) in part.positions.iter().zip(&triangle) {
                let want = world.transform_point3(*p);
                assert!(got.distance(want) < 1e-5, "instance {k}: {got} != {want}");
            }
            // The mirrored instance is re-wound: its faces still face along their normals.
            let [a, b, c] = part.triangle(0);
            let face = (part.positions[b] - part.positions[a])
                .cross(part.positions[c] - part.positions[a]);
            assert!(
                face.dot(part.normals[a]) > 0.0,
                "instance {k} faces outward"
            );
        }
        assert!(
            import
                .report
                .iter()
                .any(|l| l.contains("1 node(s) place 3 instance(s)")),
            "{:?}",
            import.report
        );
        assert!(!import.report.iter().any(|l| l.contains("not supported")));
    }

    /// `count_gltf` counts what the import builds, mesh by mesh, without building it, and
    /// still counts a file whose import the limits refuse (saying why).
    #[test]
    fn the_count_equals_the_import_and_survives_a_refusal() {
        let (doc, root) = instanced();
        let bytes = doc.glb(root);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("inst.glb");
        std::fs::write(&path, &bytes).unwrap();
        let import = crate::io::import_gltf_imported(&path, &ImportLimits::default()).unwrap();
        let count = crate::io::count_gltf(&path, &ImportLimits::default()).unwrap();
        let triangles: usize = import.model.parts.iter().map(|p| p.indices.len() / 3).sum();
        let vertices: usize = import.model.parts.iter().map(|p| p.positions.len()).sum();
        assert_eq!(count.triangles, triangles as u64);
        assert_eq!(count.vertices, vertices as u64);
        assert_eq!((count.instanced_nodes, count.instances), (1, 3));
        assert_eq!(count.refused, None);
        assert_eq!(count.meshes.len(), 1);
        let tri = &count.meshes[0];
        assert_eq!(
            (
                tri.name.as_str(),
                tri.triangles,
                tri.vertices,
                tri.nodes,
                tri.copies
            ),
            ("Tri", 1, 3, 2, 4),
            "one triangle drawn by the instanced node's 3 instances and the plain node"
        );
        assert!(
            count
                .report
                .iter()
                .any(|l| l.contains("place 3 instance(s)"))
        );
        // Limits that refuse the import: the count is the same and says why.
        let tight = ImportLimits {
            max_vertices: 11,
            ..ImportLimits::default()
        };
        let refused = crate::io::import_gltf_imported(&path, &tight).expect_err("over 11");
        assert!(matches!(refused, IoError::TooLarge { .. }), "{refused}");
        let counted = crate::io::count_gltf(&path, &tight).unwrap();
        let why = counted.refused.clone().expect("refused");
        // The triangle has no NORMAL: flat normals may split each of its 12 corners off.
        assert!(
            why.contains("has 12 vertices (up to 24 with the copies flat normals split off"),
            "{why}"
        );
        assert_eq!(count.flat_normal_vertices, 12);
        assert_eq!(
            CountedWithoutWhy::of(&counted),
            CountedWithoutWhy::of(&count)
        );
        // A malformed file is still an error, not a count.
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        assert!(crate::io::count_gltf(&path, &ImportLimits::default()).is_err());
    }

    /// A count less its refusal, to compare counts made under different limits.
    #[derive(Debug, PartialEq, Eq)]
    struct CountedWithoutWhy(crate::io::GltfCount);

    impl CountedWithoutWhy {
        fn of(c: &crate::io::GltfCount) -> Self {
            Self(crate::io::GltfCount {
                refused: None,
                ..c.clone()
            })
        }
    }

    #[test]
    fn normalised_short_and_byte_rotations_read_as_the_float_ones() {
        let (doc, root) = instanced();
        let float = import(&doc.glb(root)).expect("float rotations");
        for (component, scale, size) in [(5122u32, 32767.0f32, 2usize), (5120, 127.0, 1)] {
            let (mut doc, mut root) = instanced();
            let bytes: Vec<u8> = instance_transforms()
                .iter()
                .flat_map(|i| i.1.to_array())
                .flat_map(|v| {
                    let q = (v * scale).round() as i16;
                    q.to_le_bytes()[..size].to_vec()
                })
                .collect();
            // VEC4 of bytes is 4 bytes a element: no padding needed.
            let r = doc.accessor(&bytes, "VEC4", component, 3);
            root["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["ROTATION"] =
                json!(r);
            let plain = doc.glb(root.clone());
            assert_refused(import(&plain), "invalid", "must be normalized");
            doc.accessors[r]["normalized"] = json!(true);
            let quantized = import(&doc.glb(root)).expect("normalised rotations");
            for (a, b) in float.model.parts.iter().zip(&quantized.model.parts) {
                for (p, q) in a.positions.iter().zip(&b.positions) {
                    assert!(p.distance(*q) < 0.05, "{component}: {p} vs {q}");
                }
            }
        }
    }

    #[test]
    fn bad_instancing_accessors_are_refused_in_one_line() {
        let attr = |root: &mut Value, name: &str, v: Value| {
            root["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"][name] = v;
        };
        // A count that differs from the others'.
        let (mut doc, mut root) = instanced();
        let s = doc.floats(&[1.0; 6], "VEC3", 3);
        attr(&mut root, "SCALE", json!(s));
        assert_refused(
            import(&doc.glb(root)),
            "invalid",
            &format!(
                "accessor {s} (SCALE of node 0's EXT_mesh_gpu_instancing): count 2 differs from TRANSLATION count 3"
            ),
        );
        // Non-finite values.
        for (name, bad) in [("TRANSLATION", f32::NAN), ("SCALE", f32::INFINITY)] {
            let (mut doc, mut root) = instanced();
            let a = doc.floats(&[0.0, 0.0, 0.0, 1.0, bad, 1.0, 1.0, 1.0, 1.0], "VEC3", 3);
            attr(&mut root, name, json!(a));
            assert_refused(
                import(&doc.glb(root)),
                "invalid",
                &format!("{name} of node 0's EXT_mesh_gpu_instancing): instance 1 has the value"),
            );
        }
        let (mut doc, mut root) = instanced();
        let r = doc.floats(
            &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            "VEC4",
            4,
        );
        attr(&mut root, "ROTATION", json!(r));
        assert_refused(
            import(&doc.glb(root)),
            "invalid",
            "instance 1 rotation [0.0, 0.0, 0.0, 0.0] is not a unit quaternion",
        );
        // Component types and types the extension does not allow.
        let (mut doc, mut root) = instanced();
        let s = doc.accessor(&[1, 0, 1, 0, 1, 0, 0, 0].repeat(3), "VEC3", 5123, 3);
        attr(&mut root, "SCALE", json!(s));
        assert_refused(
            import(&doc.glb(root)),
            "invalid",
            "SCALE of node 0's EXT_mesh_gpu_instancing) is VEC3 of UNSIGNED_SHORT, which is not allowed here",
        );
        let (mut doc, mut root) = instanced();
        let t = doc.floats(&[0.0; 12], "VEC4", 4);
        attr(&mut root, "TRANSLATION", json!(t));
        assert_refused(
            import(&doc.glb(root)),
            "invalid",
            "is VEC4 of FLOAT, which is not allowed here",
        );
        // References and the extension object itself.
        let (doc, mut root) = instanced();
        attr(&mut root, "TRANSLATION", json!(99));
        assert_refused(
            import(&doc.glb(root)),
            "invalid",
            "accessor 99 (TRANSLATION of node 0's EXT_mesh_gpu_instancing) does not exist",
        );
        let (doc, mut root) = instanced();
        attr(&mut root, "ROTATION", json!("first"));
        assert_refused(
            import(&doc.glb(root)),
            "invalid",
            "attribute ROTATION is \"first\", not an accessor index",
        );
        let (doc, mut root) = instanced();
        root["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"] =
            json!({"attributes": {"_ID": 1}});
        assert_refused(
            import(&doc.glb(root)),
            "invalid",
            "node 0: EXT_mesh_gpu_instancing has none of TRANSLATION, ROTATION and SCALE",
        );
        let (doc, mut root) = instanced();
        root["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"] = json!({});
        assert_refused(
            import(&doc.glb(root)),
            "invalid",
            "EXT_mesh_gpu_instancing has no \"attributes\" object",
        );
        // A skinned node's joints place it: instances of it have no meaning.
        let (doc, mut root) = instanced();
        root["nodes"][0]["skin"] = json!(0);
        root["skins"] = json!([{"joints": [1]}]);
        assert_refused(
            import(&doc.glb(root)),
            "unsupported",
            "node 0 is skinned and has EXT_mesh_gpu_instancing",
        );
    }

    /// A file of `vertices` vertices (a triangle list) drawn at `instances` translations.
    fn amplifying(vertices: usize, instances: usize) -> Vec<u8> {
        let mut doc = Doc::default();
        let positions: Vec<f32> = (0..vertices * 3).map(|i| (i % 7) as f32).collect();
        let pos = doc.floats(&positions, "VEC3", 3);
        let offsets: Vec<f32> = (0..instances * 3).map(|i| i as f32).collect();
        let t = doc.floats(&offsets, "VEC3", 3);
        doc.glb(json!({
            "extensionsUsed": ["EXT_mesh_gpu_instancing"],
            "extensionsRequired": ["EXT_mesh_gpu_instancing"],
            "nodes": [{"mesh": 0, "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": t}}}}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]
        }))
    }

    /// A small file whose scene draws one mesh from many nodes (no extension): every node's
    /// copy is counted before the first is built, so 65,553 nodes × 4,095 vertices (just past
    /// the 2^28 limit) are refused holding little more than the file, and a memory budget
    /// refuses a smaller amplification the vertex limit allows.
    #[test]
    fn many_nodes_sharing_a_mesh_are_counted_before_they_are_expanded() {
        let file = |nodes: usize| {
            let mut doc = Doc::default();
            let positions: Vec<f32> = (0..4095 * 3).map(|i| (i % 11) as f32).collect();
            let pos = doc.floats(&positions, "VEC3", 3);
            let children: Vec<usize> = (1..=nodes).collect();
            let mut all = vec![json!({"children": children})];
            all.extend((0..nodes).map(|i| json!({"mesh": 0, "translation": [i as f32, 0.0, 0.0]})));
            doc.glb(json!({
                "scenes": [{"nodes": [0]}],
                "nodes": all,
                "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]
            }))
        };
        let big = file(65_553);
        assert!(big.len() < 4 << 20, "a small file: {} bytes", big.len());
        let (result, peak) = crate::io::fuzz::peak_heap_bytes(|| {
            import_gltf_slice_imported(&big, Path::new("nodes.glb"), &ImportLimits::default())
        });
        let e = result.expect_err("over the vertex limit").to_string();
        assert!(
            e.starts_with("nodes.glb: too large") && e.contains("268,439,535 vertices"),
            "{e}"
        );
        assert!(peak < 64 << 20, "refused holding {peak} bytes");
        // 1,024 copies (4.2 M vertices) fit the vertex limit; a 64 MiB budget refuses them.
        let small = file(1024);
        let tight = ImportLimits {
            memory: crate::budget::MemoryBudget::given(64 << 20),
            ..ImportLimits::default()
        };
        let e = import_gltf_slice_imported(&small, Path::new("nodes.glb"), &tight)
            .expect_err("over the memory budget")
            .to_string();
        assert!(e.contains("memory") && e.contains("64.0 MiB"), "{e}");
        let roomy = ImportLimits::default();
        let model = import_gltf_slice_imported(&small, Path::new("nodes.glb"), &roomy)
            .expect("within the default budget")
            .model;
        assert_eq!(model.vertex_count(), 1024 * 4095);
    }

    #[test]
    fn instances_over_the_limits_are_refused_before_they_are_expanded() {
        // Within the vertex limit, the count is exact: 300 vertices, and as the triangle has
        // no NORMAL, up to 300 more where flat normals split them (none here: one triangle).
        let bytes = amplifying(3, 100);
        let limits = ImportLimits {
            max_vertices: 599,
            ..ImportLimits::default()
        };
        let err = import_gltf_slice_imported(&bytes, Path::new("inst.glb"), &limits)
            .expect_err("up to 600 vertices");
        assert_eq!(
            err.to_string(),
            "inst.glb: too large: the scene with its 100 instance(s) expanded \
             (EXT_mesh_gpu_instancing on 1 node(s)) has 300 vertices (up to 600 with the copies \
             flat normals split off, for primitives without NORMAL); the limit is 599 vertices: \
             export fewer placements (thicket export --instance-level) or coarser meshes \
             (--resolution)"
        );
        assert_eq!(
            import_gltf_slice_imported(
                &bytes,
                Path::new("inst.glb"),
                &ImportLimits {
                    max_vertices: 600,
                    ..limits
                }
            )
            .expect("at the limit")
            .model
            .vertex_count(),
            300
        );
        // A 480 KB file that would expand to 4 × 10^8 vertices (about 13 GB): refused having
        // allocated a few times the file, never the expansion.
        let bytes = amplifying(19_998, 20_000);
        let (result, peak) = crate::io::fuzz::peak_heap_bytes(|| import(&bytes));
        assert_refused(
            result,
            "too large",
            "has 399,960,000 vertices (up to 799,920,000 with the copies flat normals split \
             off, for primitives without NORMAL); the limit is 268,435,456 vertices",
        );
        assert!(
            peak < 4 * bytes.len() as u64 + (1 << 20),
            "peak {peak} for {} bytes",
            bytes.len()
        );
        // Within the counts but over the memory budget: 9 × 10^6 vertices, about 250 MB.
        let bytes = amplifying(3_000, 3_000);
        let limits = ImportLimits {
            memory: crate::budget::MemoryBudget::given(64 << 20),
            ..ImportLimits::default()
        };
        let (result, peak) = crate::io::fuzz::peak_heap_bytes(|| {
            import_gltf_slice_imported(&bytes, Path::new("inst.glb"), &limits)
        });
        assert_refused(
            result,
            "too large",
            "the scene with its 3,000 instance(s) expanded (EXT_mesh_gpu_instancing on 1 node(s)), \
             3,000,000 triangles, would need about",
        );
        assert!(
            peak < 4 * bytes.len() as u64 + (1 << 20),
            "peak {peak} for {} bytes",
            bytes.len()
        );
    }

    /// A GLB as Thicket's exporter writes a forest cell: a mesh drawn at instances, with a
    /// coarser `MSFT_lod` level outside the scene carrying the same placements. A fuzz seed.
    pub(crate) fn instanced_lod_glb() -> Vec<u8> {
        let mut doc = Doc::default();
        let pos = doc.floats(&QUAD, "VEC3", 3);
        let indices = doc.accessor(&[0, 0, 1, 0, 2, 0, 0, 0, 2, 0, 3, 0], "SCALAR", 5123, 6);
        let coarse = doc.floats(&QUAD[..9], "VEC3", 3);
        let t = doc.floats(&[0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0, 0.0, 4.0], "VEC3", 3);
        let r = doc.floats(
            &[0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            "VEC4",
            4,
        );
        let s = doc.floats(&[1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0], "VEC3", 3);
        let instancing = json!({"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": t, "ROTATION": r, "SCALE": s}}});
        let mut full = instancing.clone();
        full["MSFT_lod"] = json!({"ids": [1]});
        doc.glb(json!({
            "extensionsUsed": ["EXT_mesh_gpu_instancing", "MSFT_lod"],
            "extensionsRequired": ["EXT_mesh_gpu_instancing"],
            "scene": 0,
            "scenes": [{"nodes": [0]}],
            "nodes": [
                {"name": "Forest cell 0,0", "mesh": 0, "extensions": full,
                 "extras": {"MSFT_screencoverage": [0.5, 0.0]}},
                {"name": "Forest cell 0,0 LOD1", "mesh": 1, "extensions": instancing}
            ],
            "meshes": [
                {"name": "Tree", "primitives": [{"attributes": {"POSITION": pos}, "indices": indices}]},
                {"name": "Tree LOD1", "primitives": [{"attributes": {"POSITION": coarse}}]}
            ]
        }))
    }

    #[test]
    fn the_finest_level_is_read_and_the_coarser_ones_are_said_to_be_left_out() {
        let import = import(&instanced_lod_glb()).expect("seed");
        // Three instances of the two-triangle quad; the one-triangle level is not read.
        assert_eq!(import.model.parts.len(), 3);
        assert_eq!(import.model.triangle_count(), 6);
        assert!(
            import.report.iter().any(|l| l
                == "MSFT_lod: 1 node(s) list 1 coarser level(s) of detail; the finest level \
                    (the node's own mesh) is imported, the coarser levels are not"),
            "{:?}",
            import.report
        );
        let names: Vec<&str> = import.nodes.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "Forest cell 0,0 0",
                "Forest cell 0,0 1",
                "Forest cell 0,0 2"
            ]
        );
    }
}

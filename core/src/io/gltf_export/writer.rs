//! [`ExportScene`] → glTF 2.0 JSON (built with `gltf::json`'s types, never by string) and one
//! binary buffer; packed as `.glb` or written as `.gltf` + `.bin`.

use std::collections::BTreeMap;

use glam::{Mat4, Vec2, Vec3, Vec4};
use gltf::json;
use gltf::json::accessor::{ComponentType, GenericComponentType, Type};
use gltf::json::validation::{Checked, USize64};

use super::instances::InstanceTransform;
use crate::mesh::Texture;
use crate::scene::Transform;
use crate::skin::{AnimationClip, Interpolation, Property, Skeleton};
use crate::svo::Skin4;

/// One triangle list ready to write, in its node's space.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExportPrimitive {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit normals (same length as `positions`) or empty.
    pub normals: Vec<Vec3>,
    /// Linear RGBA vertex colours (same length) or empty.
    pub colors: Vec<Vec4>,
    /// Texture coordinates, (0, 0) = the image's top-left (same length) or empty.
    pub uvs: Vec<Vec2>,
    /// Three indices per triangle, counter-clockwise front faces.
    pub indices: Vec<u32>,
    /// Index into [`ExportScene::materials`].
    pub material: usize,
    /// Per-vertex joints and weights (same length) for a node with a [`ExportNode::skin`], or
    /// empty. Written as `JOINTS_0` (unsigned byte) and `WEIGHTS_0` (normalised unsigned byte).
    pub skin: Vec<Skin4>,
}

/// A material: base colour factor and optional base-colour texture.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportMaterial {
    /// Display name.
    pub name: String,
    /// Linear RGBA factor.
    pub base_color: Vec4,
    /// Base-colour texture (sRGB RGBA8).
    pub texture: Option<Texture>,
    /// Sample the texture with nearest filtering (palette textures: one texel per colour).
    pub nearest: bool,
    /// Render both sides (open meshes such as a ground plane).
    pub double_sided: bool,
    /// Sample the texture without mipmaps (linear filtering of the full image): an
    /// alpha-tested impostor's averaged mipmaps lose the thin leaves under the cut-off, so a
    /// distant crown would thin to its branches.
    pub no_mipmaps: bool,
    /// Alpha-tested (`alphaMode` `MASK`): texels whose alpha is under this are not drawn (an
    /// impostor's cut-out). `None`: opaque.
    pub alpha_cutoff: Option<f32>,
}

impl Default for ExportMaterial {
    fn default() -> Self {
        Self {
            name: String::new(),
            base_color: Vec4::ONE,
            texture: None,
            nearest: false,
            double_sided: false,
            no_mipmaps: false,
            alpha_cutoff: None,
        }
    }
}

/// A node: a name, its transform and its triangle lists (none: an empty node).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExportNode {
    /// Display name.
    pub name: String,
    /// `parent_from_node`.
    pub transform: Transform,
    /// The mesh's primitives.
    pub primitives: Vec<ExportPrimitive>,
    /// With any entries, the mesh is drawn once per entry (`EXT_mesh_gpu_instancing`), each
    /// placement applied before the node's transform.
    pub instances: Vec<InstanceTransform>,
    /// With a skin, the mesh is skinned: its vertices are in bind space and move with the
    /// skeleton, which is written under a node carrying [`ExportNode::transform`].
    pub skin: Option<ExportSkin>,
    /// Coarser levels of detail of the mesh, finest first, written as `MSFT_lod` alternatives
    /// (each level for half the screen coverage of the one before). A viewer without the
    /// extension shows the full mesh.
    pub lods: Vec<Vec<ExportPrimitive>>,
    /// Draw the mesh and the levels of detail of the scene node with this index (an earlier
    /// node) instead of primitives of its own: the cells of an instanced forest share one tree
    /// mesh and its levels, each with its own placements. `primitives` and `lods` stay empty.
    pub mesh_from: Option<usize>,
    /// Keyed placements (rigid per-object animation): channels on joint 0 animate the node
    /// that carries [`ExportNode::transform`] (a skinned node's skeleton root), written as a
    /// glTF animation named "`name` motion".
    pub motion: Option<AnimationClip>,
}

/// A skeleton and its animation clips, for a skinned node (see [`ExportNode::skin`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExportSkin {
    /// Joints in topological order; [`ExportPrimitive::skin`] joint bytes index it.
    pub skeleton: Skeleton,
    /// Clips, written as glTF animations targeting the joint nodes.
    pub clips: Vec<AnimationClip>,
}

/// A directional light (`KHR_lights_punctual`), shining along `direction`.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportLight {
    /// Display name.
    pub name: String,
    /// Direction the light travels (from the light toward the scene); non-zero.
    pub direction: Vec3,
    /// Linear RGB colour.
    pub color: Vec3,
    /// Illuminance in lux (the document's intensity multiplier as it is).
    pub intensity: f32,
}

/// A camera at `eye`, looking along −Z of `rotation` with +Y of it up: perspective, or
/// orthographic when `ortho_half_height` is set.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportCamera {
    /// Display name.
    pub name: String,
    /// Position in the world.
    pub eye: Vec3,
    /// `world_from_camera` rotation.
    pub rotation: glam::Quat,
    /// Vertical field of view in radians.
    pub yfov_radians: f32,
    /// Near clip distance.
    pub znear: f32,
    /// Far clip distance.
    pub zfar: f32,
    /// Half the view height in world units of an orthographic camera (glTF `ymag`; `xmag` is
    /// written equal, since the glTF specification leaves the aspect ratio to the viewport).
    pub ortho_half_height: Option<f32>,
}

/// Everything one glTF file holds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExportScene {
    /// Root nodes, in order.
    pub nodes: Vec<ExportNode>,
    /// Materials the primitives index.
    pub materials: Vec<ExportMaterial>,
    /// Directional lights, each written as a node.
    pub lights: Vec<ExportLight>,
    /// The view camera, written as a node.
    pub camera: Option<ExportCamera>,
    /// Write a node's placements ([`ExportNode::instances`]) as one child node each, sharing
    /// the mesh, which every glTF reader understands, instead of `EXT_mesh_gpu_instancing`
    /// (which readers without the extension must refuse). Levels of detail are not written
    /// for such nodes: `MSFT_lod` would need level nodes per placement.
    pub instance_nodes: bool,
}

impl ExportPrimitive {
    /// Shares vertices whose every attribute is equal (position, normal, colour, texture
    /// coordinate, joints and weights, bit for bit) and drops vertices no triangle uses: each
    /// is written once, in the order the triangles first use them, and the indices point at it. Positions do not move, so no T-junction appears or goes and the skinned export's
    /// corner rule holds; greedy quads of one colour and normal that meet at a corner share it.
    pub fn weld(&mut self) {
        use std::collections::HashMap;
        let n = self.positions.len();
        let key = |i: usize| {
            let mut k = [0u32; 14];
            let bits = |v: f32| v.to_bits();
            let p = self.positions[i];
            k[..3].copy_from_slice(&[bits(p.x), bits(p.y), bits(p.z)]);
            if let Some(v) = self.normals.get(i) {
                k[3..6].copy_from_slice(&[bits(v.x), bits(v.y), bits(v.z)]);
            }
            if let Some(c) = self.colors.get(i) {
                k[6..10].copy_from_slice(&[bits(c.x), bits(c.y), bits(c.z), bits(c.w)]);
            }
            if let Some(t) = self.uvs.get(i) {
                k[10..12].copy_from_slice(&[bits(t.x), bits(t.y)]);
            }
            if let Some(s) = self.skin.get(i) {
                k[12] = u32::from_le_bytes(s.joints);
                k[13] = u32::from_le_bytes(s.weights);
            }
            k
        };
        let mut first: HashMap<[u32; 14], u32> = HashMap::with_capacity(n);
        let mut remap = vec![u32::MAX; n];
        let mut kept = Vec::with_capacity(n);
        for index in &mut self.indices {
            let i = *index as usize;
            // An index past the vertices stays as it is: the encoder refuses the primitive.
            if i >= n {
                continue;
            }
            if remap[i] == u32::MAX {
                let next = kept.len() as u32;
                let at = *first.entry(key(i)).or_insert(next);
                if at == next {
                    kept.push(i);
                }
                remap[i] = at;
            }
            *index = remap[i];
        }
        drop(first);
        fn pick<T: Copy>(v: &mut Vec<T>, kept: &[usize]) {
            if !v.is_empty() {
                *v = kept.iter().map(|&i| v[i]).collect();
            }
        }
        pick(&mut self.positions, &kept);
        pick(&mut self.normals, &kept);
        pick(&mut self.colors, &kept);
        pick(&mut self.uvs, &kept);
        pick(&mut self.skin, &kept);
    }
}

impl ExportScene {
    /// Shares equal vertices in every primitive and level of detail ([`ExportPrimitive::weld`]).
    pub fn weld(&mut self) {
        for node in &mut self.nodes {
            for p in node
                .primitives
                .iter_mut()
                .chain(node.lods.iter_mut().flatten())
            {
                p.weld();
            }
        }
    }

    /// Total triangles.
    #[must_use]
    pub fn triangle_count(&self) -> u64 {
        self.primitives().map(|p| p.indices.len() as u64 / 3).sum()
    }

    /// Total vertices.
    #[must_use]
    pub fn vertex_count(&self) -> u64 {
        self.primitives().map(|p| p.positions.len() as u64).sum()
    }

    fn primitives(&self) -> impl Iterator<Item = &ExportPrimitive> {
        self.nodes.iter().flat_map(|n| n.primitives.iter())
    }
}

/// The encoded file(s).
pub(crate) struct Encoded {
    /// The glTF JSON.
    pub(crate) json: Vec<u8>,
    /// The binary buffer.
    pub(crate) bin: Vec<u8>,
}

/// Why a scene cannot be encoded.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum EncodeError {
    /// Too big for glTF's 32-bit lengths or the GLB container.
    TooLarge(String),
    /// A primitive's arrays disagree, or a value is not finite.
    Invalid(String),
    /// PNG encoding or JSON serialization failed.
    Encoding(String),
}

/// Builds the glTF: `bin_uri` is `None` for GLB (buffer 0 is the GLB binary chunk) or the
/// file name of the `.bin` beside a `.gltf`.
pub(crate) fn encode(
    scene: &ExportScene,
    bin_uri: Option<&str>,
    generator: &str,
) -> Result<Encoded, EncodeError> {
    let mut b = Builder::default();
    b.root.asset = json::Asset {
        generator: Some(generator.to_owned()),
        ..json::Asset::default()
    };
    let materials: Vec<json::Index<json::Material>> = scene
        .materials
        .iter()
        .map(|m| b.material(m))
        .collect::<Result<_, _>>()?;
    let mut node_indices = Vec::with_capacity(scene.nodes.len());
    // Per node: its mesh and its levels' meshes, for the nodes that share them (`mesh_from`).
    let mut written: Vec<Option<Meshes>> = Vec::with_capacity(scene.nodes.len());
    for (ni, node) in scene.nodes.iter().enumerate() {
        let shared = match node.mesh_from {
            Some(j) => {
                let source = written.get(j).and_then(Option::as_ref).ok_or_else(|| {
                    EncodeError::Invalid(format!(
                        "node {:?} draws the mesh of node {j}, which is not an earlier node \
                         with a mesh",
                        node.name
                    ))
                })?;
                if !node.primitives.is_empty() || !node.lods.is_empty() || node.skin.is_some() {
                    return Err(EncodeError::Invalid(format!(
                        "node {:?} draws node {j}'s mesh and has primitives, levels or a skin \
                         of its own",
                        node.name
                    )));
                }
                Some(source.clone())
            }
            None => None,
        };
        let mesh = if let Some(s) = &shared {
            Some(s.mesh)
        } else if node.primitives.iter().any(|p| !p.indices.is_empty()) {
            let mut prims = Vec::new();
            for (pi, p) in node.primitives.iter().enumerate() {
                if p.indices.is_empty() {
                    continue;
                }
                let what = format!("node {:?} primitive {pi}", node.name);
                let material = *materials.get(p.material).ok_or_else(|| {
                    EncodeError::Invalid(format!("{what}: material {} is missing", p.material))
                })?;
                prims.push(b.primitive(p, material, &what)?);
            }
            Some(b.root.push(json::Mesh {
                extensions: None,
                extras: None,
                name: Some(node.name.clone()),
                primitives: prims,
                weights: None,
            }))
        } else {
            None
        };
        if let Some(skin) = &node.skin {
            let (root, skin_index) = b.skin(skin, &node.name, &node.transform)?;
            if let Some(motion) = &node.motion {
                b.motion(motion, root.value() as u32, &node.name)?;
            }
            node_indices.push(root);
            // A skinned mesh's node transform is ignored (glTF 2.0 §3.7.3.3): it sits at the
            // root, untransformed, and the skeleton's root node carries the placement.
            node_indices.push(b.root.push(json::Node {
                mesh,
                skin: Some(skin_index),
                name: Some(node.name.clone()),
                ..json::Node::default()
            }));
            written.push(None);
            continue;
        }
        let t = &node.transform;
        let trs_is_identity = *t == Transform::default();
        // A node per placement (portable instancing): the node carries only the placement
        // children, which draw the mesh; no levels.
        let (node_mesh, children, extensions, extras) = if scene.instance_nodes
            && !node.instances.is_empty()
            && let Some(mesh) = mesh
        {
            let children = b.instance_nodes(node, mesh)?;
            written.push(Some(Meshes {
                mesh,
                levels: Vec::new(),
            }));
            (None, Some(children), None, None)
        } else {
            let instancing = if node.instances.is_empty() || mesh.is_none() {
                None
            } else {
                Some(b.instancing(&node.instances)?)
            };
            let mut extensions = instancing.clone();
            let mut extras = None;
            let levels = match (shared, mesh) {
                (Some(s), _) => s.levels,
                (None, Some(_)) if !node.lods.is_empty() => b.level_meshes(node, &materials)?,
                _ => Vec::new(),
            };
            if !levels.is_empty() {
                // A level replaces the whole node, so an instanced node's levels carry its
                // placements too (the same accessors).
                let (lod, coverage) = b.lod_nodes(node, &levels, instancing.as_ref())?;
                extensions
                    .get_or_insert_with(Default::default)
                    .others
                    .extend(lod.others);
                extras = coverage;
            }
            written.push(mesh.map(|mesh| Meshes { mesh, levels }));
            (mesh, None, extensions, extras)
        };
        let index = b.root.push(json::Node {
            extensions,
            mesh: node_mesh,
            children,
            name: Some(if node.name.is_empty() {
                format!("node {ni}")
            } else {
                node.name.clone()
            }),
            translation: (!trs_is_identity).then(|| t.translation.to_array()),
            rotation: (!trs_is_identity)
                .then(|| json::scene::UnitQuaternion(unit_quat(t.rotation).to_array())),
            scale: (!trs_is_identity).then(|| t.scale.to_array()),
            extras,
            ..json::Node::default()
        });
        node_indices.push(index);
        if let Some(motion) = &node.motion {
            b.motion(motion, index.value() as u32, &node.name)?;
        }
    }
    if !scene.lights.is_empty() {
        node_indices.extend(b.lights(&scene.lights)?);
    }
    if let Some(c) = &scene.camera {
        node_indices.push(b.camera(c)?);
    }
    let scene_index = b.root.push(json::Scene {
        extensions: None,
        extras: None,
        name: Some("Scene".to_owned()),
        nodes: node_indices,
    });
    b.root.scene = Some(scene_index);
    b.finish(bin_uri)
}

/// A written mesh and its coarser levels' meshes, for nodes that share them.
#[derive(Clone)]
struct Meshes {
    mesh: json::Index<json::Mesh>,
    levels: Vec<json::Index<json::Mesh>>,
}

#[derive(Default)]
struct Builder {
    root: json::Root,
    bin: Vec<u8>,
    sampler_linear: Option<json::Index<json::texture::Sampler>>,
    sampler_nearest: Option<json::Index<json::texture::Sampler>>,
    sampler_no_mipmaps: Option<json::Index<json::texture::Sampler>>,
}

fn too_large(what: &str) -> EncodeError {
    EncodeError::TooLarge(format!(
        "{what}: the binary buffer would pass glTF's 4 GiB limit"
    ))
}

/// A voxel skin as glTF wants it: weights summing to exactly 255 (the empty skin becomes the
/// root joint, as the renderer blends it), and joint 0 in every slot of weight zero, so no
/// joint index repeats among the used slots.
fn gltf_skin(s: Skin4) -> ([u8; 4], [u8; 4]) {
    if s.weights.iter().map(|&w| u32::from(w)).sum::<u32>() != 255 {
        return (Skin4::ROOT.joints, Skin4::ROOT.weights);
    }
    let mut joints = s.joints;
    for (j, w) in joints.iter_mut().zip(s.weights) {
        if w == 0 {
            *j = 0;
        }
    }
    (joints, s.weights)
}

/// `q` normalised, or the identity when it cannot be (glTF requires unit quaternions).
pub(crate) fn unit_quat(q: glam::Quat) -> glam::Quat {
    glam::Quat::from_vec4(Vec4::from(q).normalize_or(Vec4::W))
}

/// The extension that draws a node's mesh once per instance.
const INSTANCING: &str = "EXT_mesh_gpu_instancing";

/// The extension for lights.
const LIGHTS: &str = "KHR_lights_punctual";

/// The extension that lists a node's coarser levels of detail.
const LOD: &str = "MSFT_lod";

impl Builder {
    /// Writes directional lights (`KHR_lights_punctual`, a light shines along its node's −Z)
    /// and returns their nodes.
    fn lights(
        &mut self,
        lights: &[ExportLight],
    ) -> Result<Vec<json::Index<json::Node>>, EncodeError> {
        let mut defs = Vec::with_capacity(lights.len());
        let mut nodes = Vec::with_capacity(lights.len());
        for (i, l) in lights.iter().enumerate() {
            let dir = l.direction.normalize_or_zero();
            if dir == Vec3::ZERO
                || !l.color.is_finite()
                || !(l.intensity.is_finite() && l.intensity >= 0.0)
            {
                return Err(EncodeError::Invalid(format!(
                    "light {:?}: direction must be non-zero and colour and intensity finite",
                    l.name
                )));
            }
            defs.push(serde_json::json!({
                "name": l.name,
                "type": "directional",
                "color": l.color.max(Vec3::ZERO).to_array(),
                "intensity": l.intensity,
            }));
            let rotation = unit_quat(glam::Quat::from_rotation_arc(Vec3::NEG_Z, dir));
            let mut ext = json::extensions::scene::Node::default();
            ext.others
                .insert(LIGHTS.to_owned(), serde_json::json!({ "light": i }));
            nodes.push(self.root.push(json::Node {
                name: Some(if l.name.is_empty() {
                    format!("light {i}")
                } else {
                    l.name.clone()
                }),
                rotation: Some(json::scene::UnitQuaternion(rotation.to_array())),
                extensions: Some(ext),
                ..json::Node::default()
            }));
        }
        self.root
            .extensions
            .get_or_insert_with(Default::default)
            .others
            .insert(LIGHTS.to_owned(), serde_json::json!({ "lights": defs }));
        if !self.root.extensions_used.iter().any(|e| e == LIGHTS) {
            self.root.extensions_used.push(LIGHTS.to_owned());
        }
        Ok(nodes)
    }

    /// Writes the camera and its node.
    fn camera(&mut self, c: &ExportCamera) -> Result<json::Index<json::Node>, EncodeError> {
        let valid = c.eye.is_finite()
            && c.rotation.is_finite()
            && c.yfov_radians.is_finite()
            && c.yfov_radians > 0.0
            && c.znear.is_finite()
            && c.znear > 0.0
            && c.zfar.is_finite()
            && c.zfar > c.znear
            && c.ortho_half_height.is_none_or(|m| m.is_finite() && m > 0.0);
        if !valid {
            return Err(EncodeError::Invalid(format!(
                "camera {:?}: needs a finite position and rotation, a positive field of view \
                 and 0 < near < far",
                c.name
            )));
        }
        let (orthographic, perspective, kind) = match c.ortho_half_height {
            Some(mag) => (
                Some(json::camera::Orthographic {
                    xmag: mag,
                    ymag: mag,
                    zfar: c.zfar,
                    znear: c.znear,
                    extensions: None,
                    extras: None,
                }),
                None,
                json::camera::Type::Orthographic,
            ),
            None => (
                None,
                Some(json::camera::Perspective {
                    aspect_ratio: None,
                    yfov: c.yfov_radians,
                    zfar: Some(c.zfar),
                    znear: c.znear,
                    extensions: None,
                    extras: None,
                }),
                json::camera::Type::Perspective,
            ),
        };
        let camera = self.root.push(json::Camera {
            name: Some(c.name.clone()),
            orthographic,
            perspective,
            type_: Checked::Valid(kind),
            extensions: None,
            extras: None,
        });
        Ok(self.root.push(json::Node {
            camera: Some(camera),
            name: Some(c.name.clone()),
            translation: Some(c.eye.to_array()),
            rotation: Some(json::scene::UnitQuaternion(
                unit_quat(c.rotation).to_array(),
            )),
            ..json::Node::default()
        }))
    }

    /// One node per placement of `node`, each drawing `mesh` with the placement's transform
    /// (for [`ExportScene::instance_nodes`]).
    fn instance_nodes(
        &mut self,
        node: &ExportNode,
        mesh: json::Index<json::Mesh>,
    ) -> Result<Vec<json::Index<json::Node>>, EncodeError> {
        node.instances
            .iter()
            .enumerate()
            .map(|(i, t)| {
                if !(t.translation.is_finite() && t.rotation.is_finite() && t.scale.is_finite()) {
                    return Err(EncodeError::Invalid(format!(
                        "node {:?}: placement {i} has a non-finite transform",
                        node.name
                    )));
                }
                Ok(self.root.push(json::Node {
                    mesh: Some(mesh),
                    name: Some(format!("{} {i}", node.name)),
                    translation: Some(t.translation.to_array()),
                    rotation: Some(json::scene::UnitQuaternion(
                        unit_quat(t.rotation).to_array(),
                    )),
                    scale: Some(t.scale.to_array()),
                    ..json::Node::default()
                }))
            })
            .collect()
    }

    /// The node extension object for `EXT_mesh_gpu_instancing`: TRANSLATION, ROTATION and
    /// SCALE accessors (float), one element per instance.
    fn instancing(
        &mut self,
        instances: &[InstanceTransform],
    ) -> Result<json::extensions::scene::Node, EncodeError> {
        if let Some(i) = instances.iter().position(|t| {
            !(t.translation.is_finite() && t.rotation.is_finite() && t.scale.is_finite())
        }) {
            return Err(EncodeError::Invalid(format!(
                "instance {i} has a non-finite transform"
            )));
        }
        let t: Vec<f32> = instances
            .iter()
            .flat_map(|t| t.translation.to_array())
            .collect();
        let r: Vec<f32> = instances
            .iter()
            .flat_map(|t| unit_quat(t.rotation).to_array())
            .collect();
        let s: Vec<f32> = instances.iter().flat_map(|t| t.scale.to_array()).collect();
        let mut map = serde_json::Map::new();
        for (name, data, dims, type_) in [
            ("TRANSLATION", &t, 3, Type::Vec3),
            ("ROTATION", &r, 4, Type::Vec4),
            ("SCALE", &s, 3, Type::Vec3),
        ] {
            // Instance attributes are not vertex data: no buffer-view target.
            let view = self.view(bytemuck::cast_slice(data), None)?;
            let acc = self.accessor(
                view,
                data.len() / dims,
                ComponentType::F32,
                type_,
                false,
                None,
            );
            map.insert(name.to_owned(), json::Value::from(acc.value() as u64));
        }
        let mut ext = serde_json::Map::new();
        ext.insert("attributes".to_owned(), json::Value::Object(map));
        if !self.root.extensions_used.iter().any(|e| e == INSTANCING) {
            self.root.extensions_used.push(INSTANCING.to_owned());
            // Without the extension a viewer would draw one instance at the origin: wrong, so
            // it must refuse instead.
            self.root.extensions_required.push(INSTANCING.to_owned());
        }
        let mut node = json::extensions::scene::Node::default();
        node.others
            .insert(INSTANCING.to_owned(), json::Value::Object(ext));
        Ok(node)
    }

    /// Writes the meshes of `node`'s coarser levels of detail, finest first.
    fn level_meshes(
        &mut self,
        node: &ExportNode,
        materials: &[json::Index<json::Material>],
    ) -> Result<Vec<json::Index<json::Mesh>>, EncodeError> {
        let mut meshes = Vec::with_capacity(node.lods.len());
        for (k, prims) in node.lods.iter().enumerate() {
            let mut out = Vec::new();
            for (pi, p) in prims.iter().enumerate() {
                if p.indices.is_empty() {
                    continue;
                }
                let what = format!("node {:?} LOD {} primitive {pi}", node.name, k + 1);
                let material = *materials.get(p.material).ok_or_else(|| {
                    EncodeError::Invalid(format!("{what}: material {} is missing", p.material))
                })?;
                out.push(self.primitive(p, material, &what)?);
            }
            meshes.push(self.root.push(json::Mesh {
                extensions: None,
                extras: None,
                name: Some(format!("{} LOD{}", node.name, k + 1)),
                primitives: out,
                weights: None,
            }));
        }
        Ok(meshes)
    }

    /// Writes one node per level mesh, outside the scene (with `node`'s transform, and its
    /// `instancing` extension when it has one), and returns the `MSFT_lod` extension that lists
    /// them and the node extras with `MSFT_screencoverage` (1/2, 1/4, ... of the screen, then 0
    /// for the coarsest).
    fn lod_nodes(
        &mut self,
        node: &ExportNode,
        levels: &[json::Index<json::Mesh>],
        instancing: Option<&json::extensions::scene::Node>,
    ) -> Result<(json::extensions::scene::Node, json::Extras), EncodeError> {
        let mut ids = Vec::new();
        for (k, &mesh) in levels.iter().enumerate() {
            let t = &node.transform;
            let id = self.root.push(json::Node {
                mesh: Some(mesh),
                name: Some(format!("{} LOD{}", node.name, k + 1)),
                translation: Some(t.translation.to_array()),
                rotation: Some(json::scene::UnitQuaternion(
                    unit_quat(t.rotation).to_array(),
                )),
                scale: Some(t.scale.to_array()),
                extensions: instancing.cloned(),
                ..json::Node::default()
            });
            ids.push(json::Value::from(id.value() as u64));
        }
        if !self.root.extensions_used.iter().any(|e| e == LOD) {
            self.root.extensions_used.push(LOD.to_owned());
        }
        let mut ext = serde_json::Map::new();
        ext.insert("ids".to_owned(), json::Value::Array(ids));
        let mut n = json::extensions::scene::Node::default();
        n.others.insert(LOD.to_owned(), json::Value::Object(ext));
        let coverage: Vec<f64> = (1..=levels.len())
            .map(|k| 0.5f64.powi(k as i32))
            .chain(std::iter::once(0.0))
            .collect();
        let extras = serde_json::value::to_raw_value(&serde_json::json!({
            "MSFT_screencoverage": coverage
        }))
        .map_err(|e| EncodeError::Encoding(format!("node {:?} LOD extras: {e}", node.name)))?;
        Ok((n, Some(extras)))
    }

    /// Writes a skeleton as nodes under a root node placed by `placement`, its skin and its
    /// clips as animations. Returns the root node and the skin.
    fn skin(
        &mut self,
        skin: &ExportSkin,
        name: &str,
        placement: &Transform,
    ) -> Result<(json::Index<json::Node>, json::Index<json::Skin>), EncodeError> {
        let joints = &skin.skeleton.joints;
        if joints.is_empty() {
            return Err(EncodeError::Invalid(format!(
                "skinned node {name:?} has no joints"
            )));
        }
        // Node indices are assigned in push order, so children can be listed up front: joint
        // i gets `first + i`, its attachment node (when its parent frame is not the identity)
        // follows the joints.
        let first = self.root.nodes.len() as u32;
        let attachments: Vec<Option<u32>> = {
            let mut next = first + joints.len() as u32;
            joints
                .iter()
                .map(|j| {
                    (j.parent_from_attachment != Mat4::IDENTITY).then(|| {
                        next += 1;
                        next - 1
                    })
                })
                .collect()
        };
        let entry = |i: usize| attachments[i].unwrap_or(first + i as u32);
        let mut children: Vec<Vec<json::Index<json::Node>>> = vec![Vec::new(); joints.len()];
        let mut roots = Vec::new();
        for (i, j) in joints.iter().enumerate() {
            match j.parent {
                Some(p) if p < i => children[p].push(json::Index::new(entry(i))),
                _ => roots.push(json::Index::new(entry(i))),
            }
        }
        for (i, j) in joints.iter().enumerate() {
            let r = &j.rest;
            if !r.is_finite() {
                return Err(EncodeError::Invalid(format!(
                    "skinned node {name:?}: joint {:?} has a non-finite rest pose",
                    j.name
                )));
            }
            self.root.push(json::Node {
                name: Some(j.name.clone()),
                translation: Some(r.translation.to_array()),
                rotation: Some(json::scene::UnitQuaternion(
                    unit_quat(r.rotation).to_array(),
                )),
                scale: Some(r.scale.to_array()),
                children: (!children[i].is_empty()).then(|| std::mem::take(&mut children[i])),
                ..json::Node::default()
            });
        }
        for (i, j) in joints.iter().enumerate() {
            if attachments[i].is_none() {
                continue;
            }
            let (scale, rotation, translation) =
                j.parent_from_attachment.to_scale_rotation_translation();
            self.root.push(json::Node {
                name: Some(format!("{} attachment", j.name)),
                translation: Some(translation.to_array()),
                rotation: Some(json::scene::UnitQuaternion(unit_quat(rotation).to_array())),
                scale: Some(scale.to_array()),
                children: Some(vec![json::Index::new(first + i as u32)]),
                ..json::Node::default()
            });
        }
        let t = placement;
        let root = self.root.push(json::Node {
            name: Some(format!("{name} skeleton")),
            translation: Some(t.translation.to_array()),
            rotation: Some(json::scene::UnitQuaternion(
                unit_quat(t.rotation).to_array(),
            )),
            scale: Some(t.scale.to_array()),
            children: Some(roots),
            ..json::Node::default()
        });
        let ibm: Vec<f32> = joints
            .iter()
            .flat_map(|j| j.inverse_bind.to_cols_array())
            .collect();
        let view = self.view(bytemuck::cast_slice(&ibm), None)?;
        let ibm = self.accessor(
            view,
            joints.len(),
            ComponentType::F32,
            Type::Mat4,
            false,
            None,
        );
        let skin_index = self.root.push(json::Skin {
            extensions: None,
            extras: None,
            inverse_bind_matrices: Some(ibm),
            joints: (0..joints.len() as u32)
                .map(|i| json::Index::new(first + i))
                .collect(),
            name: Some(name.to_owned()),
            skeleton: Some(root),
        });
        for clip in &skin.clips {
            self.animation(clip, first, joints.len(), name)?;
        }
        Ok((root, skin_index))
    }

    /// A node's keyed placements as the animation "`name` motion" targeting node `node`.
    fn motion(&mut self, motion: &AnimationClip, node: u32, name: &str) -> Result<(), EncodeError> {
        let clip = AnimationClip {
            name: format!("{name} motion"),
            ..motion.clone()
        };
        self.animation(&clip, node, 1, name)
    }

    /// One clip as a glTF animation: a sampler per channel (key times with bounds, values as
    /// stored, rotations normalised), targeting joint node `first + joint`.
    fn animation(
        &mut self,
        clip: &AnimationClip,
        first: u32,
        joint_count: usize,
        name: &str,
    ) -> Result<(), EncodeError> {
        let mut channels = Vec::new();
        let mut samplers = Vec::new();
        for (ci, ch) in clip.channels.iter().enumerate() {
            let what = || format!("skinned node {name:?}, clip {:?}, channel {ci}", clip.name);
            let cubic = ch.interpolation == Interpolation::CubicSpline;
            let per_key = if cubic { 3 } else { 1 };
            if ch.joint >= joint_count
                || ch.times.is_empty()
                || ch.values.len() != ch.times.len() * per_key
                || !ch.times.iter().all(|t| t.is_finite())
                || !ch.values.iter().all(|v| v.is_finite())
            {
                return Err(EncodeError::Invalid(format!(
                    "{}: joint {}, {} keys, {} values",
                    what(),
                    ch.joint,
                    ch.times.len(),
                    ch.values.len()
                )));
            }
            // Animation data is not vertex data: no buffer-view target. Inputs need bounds.
            let view = self.view(bytemuck::cast_slice(&ch.times), None)?;
            let (lo, hi) = ch
                .times
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &t| {
                    (a.min(t), b.max(t))
                });
            let input = self.accessor(
                view,
                ch.times.len(),
                ComponentType::F32,
                Type::Scalar,
                false,
                Some((vec![lo], vec![hi])),
            );
            let rotation = ch.property == Property::Rotation;
            let values: Vec<f32> = ch
                .values
                .iter()
                .enumerate()
                .flat_map(|(k, v)| {
                    // Tangents of a cubic spline are not quaternions; key values are.
                    let is_value = !cubic || k % 3 == 1;
                    if rotation {
                        let v = if is_value {
                            Vec4::from(unit_quat(glam::Quat::from_vec4(*v)))
                        } else {
                            *v
                        };
                        v.to_array().to_vec()
                    } else {
                        v.truncate().to_array().to_vec()
                    }
                })
                .collect();
            let (dims, type_) = if rotation {
                (4, Type::Vec4)
            } else {
                (3, Type::Vec3)
            };
            let view = self.view(bytemuck::cast_slice(&values), None)?;
            let output = self.accessor(
                view,
                values.len() / dims,
                ComponentType::F32,
                type_,
                false,
                None,
            );
            let sampler = json::Index::new(samplers.len() as u32);
            samplers.push(json::animation::Sampler {
                extensions: None,
                extras: None,
                input,
                interpolation: Checked::Valid(match ch.interpolation {
                    Interpolation::Step => json::animation::Interpolation::Step,
                    Interpolation::Linear => json::animation::Interpolation::Linear,
                    Interpolation::CubicSpline => json::animation::Interpolation::CubicSpline,
                }),
                output,
            });
            channels.push(json::animation::Channel {
                sampler,
                target: json::animation::Target {
                    extensions: None,
                    extras: None,
                    node: json::Index::new(first + ch.joint as u32),
                    path: Checked::Valid(match ch.property {
                        Property::Translation => json::animation::Property::Translation,
                        Property::Rotation => json::animation::Property::Rotation,
                        Property::Scale => json::animation::Property::Scale,
                    }),
                },
                extensions: None,
                extras: None,
            });
        }
        if channels.is_empty() {
            return Ok(());
        }
        self.root.push(json::Animation {
            extensions: None,
            extras: None,
            channels,
            name: Some(clip.name.clone()),
            samplers,
        });
        Ok(())
    }

    /// Appends `bytes` (4-byte aligned) as a buffer view.
    fn view(
        &mut self,
        bytes: &[u8],
        target: Option<json::buffer::Target>,
    ) -> Result<json::Index<json::buffer::View>, EncodeError> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        if (offset as u64).saturating_add(bytes.len() as u64) > u64::from(u32::MAX) - 64 {
            return Err(too_large("buffer view"));
        }
        self.bin.extend_from_slice(bytes);
        Ok(self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Checked::Valid),
            extensions: None,
            extras: None,
        }))
    }

    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        component: ComponentType,
        type_: Type,
        normalized: bool,
        min_max: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
        let (min, max) = min_max.map_or((None, None), |(lo, hi)| {
            (Some(json::Value::from(lo)), Some(json::Value::from(hi)))
        });
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: Some(USize64(0)),
            count: USize64::from(count),
            component_type: Checked::Valid(GenericComponentType(component)),
            extensions: None,
            extras: None,
            type_: Checked::Valid(type_),
            min,
            max,
            name: None,
            normalized,
            sparse: None,
        })
    }

    fn floats(
        &mut self,
        data: &[f32],
        dims: usize,
        type_: Type,
        with_bounds: bool,
    ) -> Result<json::Index<json::Accessor>, EncodeError> {
        check_floats(data, dims)?;
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let view = self.view(bytes, Some(json::buffer::Target::ArrayBuffer))?;
        let bounds = with_bounds.then(|| {
            let mut lo = vec![f32::INFINITY; dims];
            let mut hi = vec![f32::NEG_INFINITY; dims];
            for e in data.chunks_exact(dims) {
                for c in 0..dims {
                    lo[c] = lo[c].min(e[c]);
                    hi[c] = hi[c].max(e[c]);
                }
            }
            (lo, hi)
        });
        Ok(self.accessor(
            view,
            data.len() / dims,
            ComponentType::F32,
            type_,
            false,
            bounds,
        ))
    }

    fn primitive(
        &mut self,
        p: &ExportPrimitive,
        material: json::Index<json::Material>,
        what: &str,
    ) -> Result<json::mesh::Primitive, EncodeError> {
        let n = p.positions.len();
        for (name, len) in [
            ("normals", p.normals.len()),
            ("colours", p.colors.len()),
            ("uvs", p.uvs.len()),
        ] {
            if len != 0 && len != n {
                return Err(EncodeError::Invalid(format!(
                    "{what}: {len} {name} for {n} vertices"
                )));
            }
        }
        if !p.indices.len().is_multiple_of(3) {
            return Err(EncodeError::Invalid(format!(
                "{what}: {} indices is not a whole number of triangles",
                p.indices.len()
            )));
        }
        if let Some(&i) = p.indices.iter().find(|&&i| i as usize >= n) {
            return Err(EncodeError::Invalid(format!(
                "{what}: index {i} is past the {n} vertices"
            )));
        }
        if let Some(i) = p.positions.iter().position(|v| !v.is_finite()) {
            return Err(EncodeError::Invalid(format!(
                "{what}: vertex {i} has a non-finite position"
            )));
        }
        let mut attributes = BTreeMap::new();
        let positions: Vec<f32> = p.positions.iter().flat_map(|v| v.to_array()).collect();
        let pos = self.floats(&positions, 3, Type::Vec3, true)?;
        attributes.insert(Checked::Valid(json::mesh::Semantic::Positions), pos);
        if !p.normals.is_empty() {
            // The validator wants unit normals; a zero or broken one becomes +Y.
            let normals: Vec<f32> = p
                .normals
                .iter()
                .flat_map(|v| v.try_normalize().unwrap_or(Vec3::Y).to_array())
                .collect();
            let acc = self.floats(&normals, 3, Type::Vec3, false)?;
            attributes.insert(Checked::Valid(json::mesh::Semantic::Normals), acc);
        }
        if !p.uvs.is_empty() {
            let uvs: Vec<f32> = p
                .uvs
                .iter()
                .flat_map(|v| {
                    if v.is_finite() {
                        v.to_array()
                    } else {
                        [0.0; 2]
                    }
                })
                .collect();
            let acc = self.floats(&uvs, 2, Type::Vec2, false)?;
            attributes.insert(Checked::Valid(json::mesh::Semantic::TexCoords(0)), acc);
        }
        if !p.colors.is_empty() {
            // Unsigned-short normalised RGBA: 8 bytes a vertex (4-byte aligned, as vertex
            // attributes must be), 1/65535 precision in linear space, which 8-bit sRGB needs.
            let colors: Vec<u16> = p
                .colors
                .iter()
                .flat_map(|c| {
                    c.to_array().map(|x| {
                        let x = if x.is_finite() {
                            x.clamp(0.0, 1.0)
                        } else {
                            1.0
                        };
                        (x * 65535.0).round() as u16
                    })
                })
                .collect();
            let view = self.view(
                bytemuck::cast_slice(&colors),
                Some(json::buffer::Target::ArrayBuffer),
            )?;
            let acc = self.accessor(view, n, ComponentType::U16, Type::Vec4, true, None);
            attributes.insert(Checked::Valid(json::mesh::Semantic::Colors(0)), acc);
        }
        if !p.skin.is_empty() {
            if p.skin.len() != n {
                return Err(EncodeError::Invalid(format!(
                    "{what}: {} skins for {n} vertices",
                    p.skin.len()
                )));
            }
            let (joints, weights): (Vec<[u8; 4]>, Vec<[u8; 4]>) =
                p.skin.iter().map(|s| gltf_skin(*s)).unzip();
            let view = self.view(
                bytemuck::cast_slice(&joints),
                Some(json::buffer::Target::ArrayBuffer),
            )?;
            let acc = self.accessor(view, n, ComponentType::U8, Type::Vec4, false, None);
            attributes.insert(Checked::Valid(json::mesh::Semantic::Joints(0)), acc);
            let view = self.view(
                bytemuck::cast_slice(&weights),
                Some(json::buffer::Target::ArrayBuffer),
            )?;
            let acc = self.accessor(view, n, ComponentType::U8, Type::Vec4, true, None);
            attributes.insert(Checked::Valid(json::mesh::Semantic::Weights(0)), acc);
        }
        let (index_bytes, component): (Vec<u8>, ComponentType) = if n <= usize::from(u16::MAX) {
            let v: Vec<u16> = p.indices.iter().map(|&i| i as u16).collect();
            (bytemuck::cast_slice(&v).to_vec(), ComponentType::U16)
        } else {
            (
                bytemuck::cast_slice(&p.indices).to_vec(),
                ComponentType::U32,
            )
        };
        let view = self.view(&index_bytes, Some(json::buffer::Target::ElementArrayBuffer))?;
        let indices = self.accessor(view, p.indices.len(), component, Type::Scalar, false, None);
        Ok(json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: None,
            indices: Some(indices),
            material: Some(material),
            mode: Checked::Valid(json::mesh::Mode::Triangles),
            targets: None,
        })
    }

    fn material(&mut self, m: &ExportMaterial) -> Result<json::Index<json::Material>, EncodeError> {
        let base_color_texture = match &m.texture {
            Some(tex) => Some(json::texture::Info {
                index: self.texture(tex, m.nearest, m.no_mipmaps, &m.name)?,
                tex_coord: 0,
                extensions: None,
                extras: None,
            }),
            None => None,
        };
        let c = m.base_color.to_array().map(|x| {
            if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                1.0
            }
        });
        let (alpha_mode, alpha_cutoff) = match m.alpha_cutoff {
            Some(c) if c.is_finite() => (
                json::material::AlphaMode::Mask,
                Some(json::material::AlphaCutoff(c.clamp(0.0, 1.0))),
            ),
            _ => (json::material::AlphaMode::Opaque, None),
        };
        Ok(self.root.push(json::Material {
            name: Some(m.name.clone()),
            double_sided: m.double_sided,
            alpha_mode: Checked::Valid(alpha_mode),
            alpha_cutoff,
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor(c),
                base_color_texture,
                // Voxel art and KRS colours are matte albedo, not metal.
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(1.0),
                ..json::material::PbrMetallicRoughness::default()
            },
            ..json::Material::default()
        }))
    }

    fn texture(
        &mut self,
        tex: &Texture,
        nearest: bool,
        no_mipmaps: bool,
        name: &str,
    ) -> Result<json::Index<json::Texture>, EncodeError> {
        let expected = u64::from(tex.width) * u64::from(tex.height) * 4;
        if tex.width == 0 || tex.height == 0 || tex.rgba8.len() as u64 != expected {
            return Err(EncodeError::Invalid(format!(
                "texture of {name:?}: {}×{} with {} bytes",
                tex.width,
                tex.height,
                tex.rgba8.len()
            )));
        }
        let mut png = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut png),
            &tex.rgba8,
            tex.width,
            tex.height,
            image::ExtendedColorType::Rgba8,
        )
        .map_err(|e| EncodeError::Encoding(format!("PNG for {name:?}: {e}")))?;
        let view = self.view(&png, None)?;
        let image = self.root.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType("image/png".to_owned())),
            name: Some(name.to_owned()),
            uri: None,
            extensions: None,
            extras: None,
        });
        let sampler = self.sampler(nearest, no_mipmaps);
        Ok(self.root.push(json::Texture {
            name: Some(name.to_owned()),
            sampler: Some(sampler),
            source: image,
            extensions: None,
            extras: None,
        }))
    }

    fn sampler(&mut self, nearest: bool, no_mipmaps: bool) -> json::Index<json::texture::Sampler> {
        use json::texture::{MagFilter, MinFilter, Sampler, WrappingMode};
        let cached = if nearest {
            self.sampler_nearest
        } else if no_mipmaps {
            self.sampler_no_mipmaps
        } else {
            self.sampler_linear
        };
        if let Some(s) = cached {
            return s;
        }
        let sampler = if nearest {
            Sampler {
                mag_filter: Some(Checked::Valid(MagFilter::Nearest)),
                min_filter: Some(Checked::Valid(MinFilter::Nearest)),
                wrap_s: Checked::Valid(WrappingMode::ClampToEdge),
                wrap_t: Checked::Valid(WrappingMode::ClampToEdge),
                ..Sampler::default()
            }
        } else if no_mipmaps {
            Sampler {
                mag_filter: Some(Checked::Valid(MagFilter::Linear)),
                min_filter: Some(Checked::Valid(MinFilter::Linear)),
                wrap_s: Checked::Valid(WrappingMode::ClampToEdge),
                wrap_t: Checked::Valid(WrappingMode::ClampToEdge),
                ..Sampler::default()
            }
        } else {
            Sampler::default()
        };
        let index = Some(self.root.push(sampler));
        if nearest {
            self.sampler_nearest = index;
        } else if no_mipmaps {
            self.sampler_no_mipmaps = index;
        } else {
            self.sampler_linear = index;
        }
        self.sampler(nearest, no_mipmaps)
    }

    fn finish(mut self, bin_uri: Option<&str>) -> Result<Encoded, EncodeError> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        if !self.bin.is_empty() {
            self.root.push(json::Buffer {
                byte_length: USize64::from(self.bin.len()),
                name: None,
                uri: bin_uri.map(str::to_owned),
                extensions: None,
                extras: None,
            });
        }
        let json = self
            .root
            .to_vec()
            .map_err(|e| EncodeError::Encoding(format!("glTF JSON: {e}")))?;
        // Read back as a reader will: a non-finite float was written as `null`.
        let value: serde_json::Value = serde_json::from_slice(&json)
            .map_err(|e| EncodeError::Encoding(format!("glTF JSON: {e}")))?;
        check_json_numbers(&value, &mut String::new())?;
        Ok(Encoded {
            json,
            bin: self.bin,
        })
    }
}

/// The largest number the writer puts in a float accessor or the JSON: what the glTF reader
/// accepts for a position ([`crate::mesh::MAX_POSITION`]), so Thicket reads every file it writes.
const MAX_WRITTEN: f32 = crate::mesh::MAX_POSITION;

/// Every value of a float accessor finite and within ±[`MAX_WRITTEN`]: `NaN` or infinity would
/// make an invalid file, a larger value one that readers refuse.
fn check_floats(data: &[f32], dims: usize) -> Result<(), EncodeError> {
    match data
        .iter()
        .position(|v| !(v.is_finite() && v.abs() <= MAX_WRITTEN))
    {
        None => Ok(()),
        Some(i) => Err(EncodeError::Invalid(format!(
            "element {} of a {dims}-component float attribute is {}, which glTF readers refuse \
             (values must be finite and within ±{MAX_WRITTEN:e})",
            i / dims.max(1),
            data[i]
        ))),
    }
}

/// Every number in the JSON finite and within ±[`MAX_WRITTEN`], and no `null` where a number
/// was meant: serde writes a non-finite float as `null`, which makes the file invalid glTF.
/// `path` is the JSON path so far, for the message (`nodes[3].translation[0]`).
fn check_json_numbers(value: &serde_json::Value, path: &mut String) -> Result<(), EncodeError> {
    use serde_json::Value;
    let refuse = |path: &str, what: String| {
        Err(EncodeError::Invalid(format!(
            "the glTF JSON would hold {what} at {path}, which glTF readers refuse (numbers must \
             be finite and within ±{MAX_WRITTEN:e}); the scene has a value out of range there"
        )))
    };
    match value {
        Value::Null => return refuse(path, "null (a NaN or infinite value)".to_owned()),
        Value::Number(n) => {
            if let Some(f) = n.as_f64()
                && !(f.is_finite() && f.abs() <= f64::from(MAX_WRITTEN))
                // Byte lengths and offsets are integers well below 1e18; only floats matter.
                && !n.is_u64()
            {
                return refuse(path, f.to_string());
            }
        }
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                let len = path.len();
                path.push_str(&format!("[{i}]"));
                check_json_numbers(item, path)?;
                path.truncate(len);
            }
        }
        Value::Object(fields) => {
            for (key, item) in fields {
                let len = path.len();
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(key);
                check_json_numbers(item, path)?;
                path.truncate(len);
            }
        }
        Value::Bool(_) | Value::String(_) => {}
    }
    Ok(())
}

/// Packs JSON and binary chunks into a GLB container (both padded to 4 bytes: JSON with
/// spaces, binary with zeros, as the specification asks).
pub(crate) fn glb(encoded: &Encoded) -> Result<Vec<u8>, EncodeError> {
    let pad = |n: usize| (4 - n % 4) % 4;
    let json_len = encoded.json.len() + pad(encoded.json.len());
    let bin_len = encoded.bin.len() + pad(encoded.bin.len());
    let bin_chunk = if bin_len > 0 { 8 + bin_len } else { 0 };
    let total = 12 + 8 + json_len + bin_chunk;
    let total32 = u32::try_from(total).map_err(|_| too_large("GLB file"))?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&encoded.json);
    out.resize(out.len() + pad(encoded.json.len()), b' ');
    if bin_len > 0 {
        out.extend_from_slice(&(bin_len as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&encoded.bin);
        out.resize(out.len() + pad(encoded.bin.len()), 0);
    }
    Ok(out)
}

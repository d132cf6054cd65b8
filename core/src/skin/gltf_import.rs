//! Import of skinned glTF: the skin's joint hierarchy (with non-joint ancestors), inverse bind
//! matrices, skinned meshes with JOINTS_0 / WEIGHTS_0 and every animation clip.
//!
//! Accessors are decoded here from bounds-checked byte slices rather than through the `gltf`
//! crate's readers, whose iterators assume a well-formed file (some of their checks are debug
//! assertions): a broken file must give an error naming the file and the accessor.

use std::path::Path;

use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};

use super::SkinError;
use super::clip::{AnimationClip, Channel, Interpolation, Property};
use super::lbs::{WeightRepair, repair_mesh_weights};
use super::skeleton::{Joint, Skeleton, Transform};
use crate::mesh::{Material, MeshModel, Texture, TriangleMesh};

/// What [`import_skinned`] returns.
#[derive(Debug, Clone, Default)]
pub struct SkinnedImport {
    /// The skin's joints in topological order (vertex joint indices and clip channels are
    /// remapped to this order).
    pub skeleton: Skeleton,
    /// Every animation of the file that targets the skin's joints.
    pub clips: Vec<AnimationClip>,
    /// Every mesh bound to the skin, in bind-pose mesh space (the skinned node's own transform
    /// is ignored, as glTF requires), with per-vertex joints and repaired weights.
    pub mesh: MeshModel,
    /// What was repaired in the vertex weights.
    pub weight_repair: WeightRepair,
    /// Things skipped or repaired, one human-readable line each (also logged as warnings).
    pub warnings: Vec<String>,
    /// World transform of the first node carrying the skinned mesh, for reference only: glTF
    /// skinning ignores it. In files like RiggedFigure and CesiumMan, whose inverse bind
    /// matrices were made without the Z-up node above the skeleton, the rest pose skins the
    /// bind-pose vertices to exactly `world_from_skinned_node · v`.
    pub world_from_skinned_node: Mat4,
}

/// Imports the first skin of a `.gltf` / `.glb` file (the first node in the scene that has a
/// mesh and a skin decides which), its meshes and all animation clips.
///
/// # Errors
/// [`SkinError`] naming the file and the problem; never panics on a broken file.
pub fn import_skinned(path: impl AsRef<Path>) -> Result<SkinnedImport, SkinError> {
    let path = path.as_ref();
    let label = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| SkinError::Io {
        path: label.clone(),
        source,
    })?;
    import_impl(&bytes, path.parent(), &label)
}

/// [`import_skinned`] from bytes; external (non-embedded) buffers cannot be resolved.
///
/// # Errors
/// As [`import_skinned`], with `label` standing for the file name in messages.
pub fn import_skinned_slice(bytes: &[u8], label: &str) -> Result<SkinnedImport, SkinError> {
    import_impl(bytes, None, label)
}

fn import_impl(bytes: &[u8], base: Option<&Path>, label: &str) -> Result<SkinnedImport, SkinError> {
    let gltf_err = |source| SkinError::Gltf {
        path: label.to_owned(),
        source,
    };
    let gltf::Gltf {
        document: doc,
        blob,
    } = gltf::Gltf::from_slice(bytes).map_err(gltf_err)?;
    let buffers = gltf::import_buffers(&doc, base, blob).map_err(gltf_err)?;
    let cx = Ctx {
        label,
        buffers: &buffers,
    };
    let mut warnings = Vec::new();

    // Node hierarchy: parent links, and which nodes the scene reaches.
    let node_count = doc.nodes().count();
    let mut parent_of = vec![None; node_count];
    for node in doc.nodes() {
        for child in node.children() {
            if parent_of[child.index()].is_some() {
                return Err(cx.invalid(format!("node {} has more than one parent", child.index())));
            }
            parent_of[child.index()] = Some(node.index());
        }
    }
    let roots: Vec<usize> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().map(|n| n.index()).collect(),
        None => (0..node_count)
            .filter(|&i| parent_of[i].is_none())
            .collect(),
    };
    let mut in_scene = vec![false; node_count];
    let mut stack = roots.clone();
    while let Some(n) = stack.pop() {
        if std::mem::replace(&mut in_scene[n], true) {
            return Err(cx.invalid(format!(
                "node {n} is reached twice: the node hierarchy has a cycle"
            )));
        }
        if let Some(node) = doc.nodes().nth(n) {
            stack.extend(node.children().map(|c| c.index()));
        }
    }
    let nodes: Vec<gltf::Node<'_>> = doc.nodes().collect();
    let local_matrix = |n: usize| Mat4::from_cols_array_2d(&nodes[n].transform().matrix());

    // The skin: the first scene node with a mesh and a skin.
    let Some((skin_node, skin)) = nodes
        .iter()
        .filter(|n| in_scene[n.index()] && n.mesh().is_some())
        .find_map(|n| n.skin().map(|s| (n.index(), s)))
    else {
        return Err(SkinError::NoSkin {
            path: label.to_owned(),
        });
    };
    let mut world_from_skinned_node = local_matrix(skin_node);
    let mut cur = parent_of[skin_node];
    while let Some(a) = cur {
        world_from_skinned_node = local_matrix(a) * world_from_skinned_node;
        cur = parent_of[a];
    }
    let skin_nodes: Vec<usize> = skin.joints().map(|n| n.index()).collect();
    if skin_nodes.is_empty() {
        return Err(cx.invalid(format!("skin {} has no joints", skin.index())));
    }
    if skin_nodes.len() > usize::from(u16::MAX) {
        return Err(cx.invalid(format!(
            "skin {} has {} joints; at most 65535 fit",
            skin.index(),
            skin_nodes.len()
        )));
    }
    let mut joint_of_node = vec![None; node_count];
    for (j, &n) in skin_nodes.iter().enumerate() {
        if joint_of_node[n].replace(j).is_some() {
            return Err(cx.invalid(format!("skin {} lists node {n} twice", skin.index())));
        }
    }
    let inverse_binds: Vec<Mat4> = match skin.inverse_bind_matrices() {
        Some(acc) => {
            let what = format!("inverse bind matrices of skin {}", skin.index());
            let flat = cx.read(&acc, &what, Dimensions::Mat4, &[DataType::F32])?;
            let mats: Vec<Mat4> = flat.chunks_exact(16).map(Mat4::from_cols_slice).collect();
            if mats.len() < skin_nodes.len() {
                return Err(cx.invalid(format!(
                    "{what}: {} matrices for {} joints",
                    mats.len(),
                    skin_nodes.len()
                )));
            }
            mats
        }
        None => vec![Mat4::IDENTITY; skin_nodes.len()],
    };

    // Joints: parent = nearest ancestor that is a joint; the non-joint nodes on the way (and
    // above a root joint, up to the scene root) go into `parent_from_attachment`.
    let mut joints = Vec::with_capacity(skin_nodes.len());
    for (j, &n) in skin_nodes.iter().enumerate() {
        let mut attachment = Mat4::IDENTITY;
        let mut parent = None;
        let mut cur = parent_of[n];
        let mut steps = 0;
        while let Some(a) = cur {
            if let Some(pj) = joint_of_node[a] {
                parent = Some(pj);
                break;
            }
            attachment = local_matrix(a) * attachment;
            cur = parent_of[a];
            steps += 1;
            if steps > node_count {
                return Err(cx.invalid(format!("the ancestors of node {n} form a cycle")));
            }
        }
        let (scale, rotation, translation) = match nodes[n].transform() {
            gltf::scene::Transform::Decomposed {
                translation,
                rotation,
                scale,
            } => (
                Vec3::from(scale),
                Quat::from_array(rotation),
                Vec3::from(translation),
            ),
            m @ gltf::scene::Transform::Matrix { .. } => {
                Mat4::from_cols_array_2d(&m.matrix()).to_scale_rotation_translation()
            }
        };
        joints.push(Joint {
            name: nodes[n]
                .name()
                .map_or_else(|| format!("node {n}"), str::to_owned),
            parent,
            rest: Transform {
                translation,
                rotation,
                scale,
            },
            inverse_bind: inverse_binds[j],
            parent_from_attachment: attachment,
        });
    }
    let (skeleton, new_from_old) =
        Skeleton::new(joints).map_err(|e| cx.invalid(format!("skin {}: {e}", skin.index())))?;

    // Meshes bound to this skin.
    let images = match gltf::import_images(&doc, base, &buffers) {
        Ok(images) => images,
        Err(e) => {
            warnings.push(format!("images not loaded ({e}); textures are left out"));
            Vec::new()
        }
    };
    let mut model = MeshModel {
        parts: Vec::new(),
        materials: import_materials(&doc, &images, &mut warnings),
    };
    let default_material = model.materials.len();
    let mut needs_default_material = false;
    for node in nodes.iter().filter(|n| in_scene[n.index()]) {
        let Some(mesh) = node.mesh() else { continue };
        match node.skin() {
            Some(s) if s.index() == skin.index() => {}
            Some(s) => {
                warnings.push(format!(
                    "node {} uses skin {}, only skin {} is imported",
                    node.index(),
                    s.index(),
                    skin.index()
                ));
                continue;
            }
            None => {
                warnings.push(format!(
                    "node {} has a mesh without a skin; left out",
                    node.index()
                ));
                continue;
            }
        }
        for prim in mesh.primitives() {
            let where_ = format!("mesh {} primitive {}", mesh.index(), prim.index());
            if prim.mode() != gltf::mesh::Mode::Triangles {
                warnings.push(format!(
                    "{where_}: mode {:?} is not triangles; left out",
                    prim.mode()
                ));
                continue;
            }
            let mut part = read_primitive(&cx, &prim, &where_, &new_from_old)?;
            part.material = prim.material().index().unwrap_or_else(|| {
                needs_default_material = true;
                default_material
            });
            part.validate()
                .map_err(|e| cx.invalid(format!("{where_}: {e}")))?;
            model.parts.push(part);
        }
    }
    if needs_default_material {
        model.materials.push(Material::default());
    }
    if model.parts.is_empty() {
        return Err(cx.invalid(format!(
            "no triangle primitive is bound to skin {}",
            skin.index()
        )));
    }
    let mut weight_repair = WeightRepair::default();
    for part in &mut model.parts {
        weight_repair.add(&repair_mesh_weights(part, skeleton.len()));
    }
    if weight_repair.total() > 0 {
        warnings.push(format!("vertex weights repaired: {weight_repair:?}"));
    }

    // Animations.
    let mut clips = Vec::new();
    for anim in doc.animations() {
        let name = anim
            .name()
            .map_or_else(|| format!("animation {}", anim.index()), str::to_owned);
        let mut clip = AnimationClip {
            name: name.clone(),
            duration_secs: 0.0,
            channels: Vec::new(),
        };
        let mut skipped = 0usize;
        for ch in anim.channels() {
            let node = ch.target().node().index();
            let property = match ch.target().property() {
                gltf::animation::Property::Translation => Property::Translation,
                gltf::animation::Property::Rotation => Property::Rotation,
                gltf::animation::Property::Scale => Property::Scale,
                gltf::animation::Property::MorphTargetWeights => {
                    skipped += 1;
                    continue;
                }
            };
            let Some(old_joint) = joint_of_node[node] else {
                skipped += 1;
                continue;
            };
            let sampler = ch.sampler();
            let interpolation = match sampler.interpolation() {
                gltf::animation::Interpolation::Step => Interpolation::Step,
                gltf::animation::Interpolation::Linear => Interpolation::Linear,
                gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
            };
            let what = format!("{name:?} channel {}", ch.index());
            let times = cx.read(
                &sampler.input(),
                &format!("{what} key times"),
                Dimensions::Scalar,
                &[DataType::F32],
            )?;
            let out = sampler.output();
            let values: Vec<Vec4> = match property {
                Property::Rotation => {
                    let types = [
                        DataType::F32,
                        DataType::I8,
                        DataType::U8,
                        DataType::I16,
                        DataType::U16,
                    ];
                    cx.read(&out, &format!("{what} rotations"), Dimensions::Vec4, &types)?
                        .chunks_exact(4)
                        .map(Vec4::from_slice)
                        .collect()
                }
                Property::Translation | Property::Scale => cx
                    .read(
                        &out,
                        &format!("{what} values"),
                        Dimensions::Vec3,
                        &[DataType::F32],
                    )?
                    .chunks_exact(3)
                    .map(|c| Vec3::from_slice(c).extend(0.0))
                    .collect(),
            };
            let channel = Channel {
                joint: new_from_old[old_joint],
                property,
                interpolation,
                times,
                values,
            };
            channel.check(skeleton.len()).map_err(|problem| {
                cx.invalid(format!("animation {what} (node {node}): {problem}"))
            })?;
            clip.channels.push(channel);
        }
        if skipped > 0 {
            warnings.push(format!(
                "animation {name:?}: {skipped} channel(s) target non-joint nodes or morph weights; ignored"
            ));
        }
        if clip.channels.is_empty() {
            continue;
        }
        clip.duration_secs = clip.last_key_time();
        clips.push(clip);
    }
    for w in &warnings {
        log::warn!("{label}: {w}");
    }
    Ok(SkinnedImport {
        skeleton,
        clips,
        mesh: model,
        weight_repair,
        warnings,
        world_from_skinned_node,
    })
}

fn import_materials(
    doc: &gltf::Document,
    images: &[gltf::image::Data],
    warnings: &mut Vec<String>,
) -> Vec<Material> {
    doc.materials()
        .enumerate()
        .map(|(i, m)| {
            let pbr = m.pbr_metallic_roughness();
            let base_color_texture = pbr.base_color_texture().and_then(|info| {
                let image = info.texture().source().index();
                let tex = images.get(image).and_then(to_rgba8);
                if tex.is_none() && !images.is_empty() {
                    warnings.push(format!(
                        "material {i}: base colour image {image} has an unsupported format"
                    ));
                }
                tex
            });
            Material {
                name: m.name().unwrap_or_default().to_owned(),
                base_color: Vec4::from(pbr.base_color_factor()),
                base_color_texture,
                unlit: m.unlit(),
            }
        })
        .collect()
}

fn to_rgba8(img: &gltf::image::Data) -> Option<Texture> {
    use gltf::image::Format;
    let px = (img.width as usize).checked_mul(img.height as usize)?;
    let rgba8 = match img.format {
        Format::R8G8B8A8 if img.pixels.len() >= px * 4 => img.pixels[..px * 4].to_vec(),
        Format::R8G8B8 if img.pixels.len() >= px * 3 => img.pixels[..px * 3]
            .chunks_exact(3)
            .flat_map(|c| [c[0], c[1], c[2], 255])
            .collect(),
        Format::R8 if img.pixels.len() >= px => img.pixels[..px]
            .iter()
            .flat_map(|&g| [g, g, g, 255])
            .collect(),
        _ => return None,
    };
    Some(Texture {
        width: img.width,
        height: img.height,
        rgba8,
    })
}

fn read_primitive(
    cx: &Ctx<'_>,
    prim: &gltf::Primitive<'_>,
    where_: &str,
    new_from_old: &[usize],
) -> Result<TriangleMesh, SkinError> {
    use gltf::Semantic;
    let attr = |s: &Semantic| prim.get(s);
    let Some(pos_acc) = attr(&Semantic::Positions) else {
        return Err(cx.invalid(format!("{where_} has no POSITION")));
    };
    let positions: Vec<Vec3> = cx
        .read(
            &pos_acc,
            &format!("{where_} POSITION"),
            Dimensions::Vec3,
            &[DataType::F32],
        )?
        .chunks_exact(3)
        .map(Vec3::from_slice)
        .collect();
    let n = positions.len();
    let same_count = |v: &[f32], per: usize, name: &str| -> Result<(), SkinError> {
        if v.len() == n * per {
            Ok(())
        } else {
            Err(cx.invalid(format!(
                "{where_} {name} has {} entries but POSITION has {n}",
                v.len() / per
            )))
        }
    };
    let mut mesh = TriangleMesh {
        positions,
        ..TriangleMesh::default()
    };
    if let Some(acc) = attr(&Semantic::Normals) {
        let v = cx.read(
            &acc,
            &format!("{where_} NORMAL"),
            Dimensions::Vec3,
            &[DataType::F32],
        )?;
        same_count(&v, 3, "NORMAL")?;
        mesh.normals = v
            .chunks_exact(3)
            .map(|c| Vec3::from_slice(c).normalize_or_zero())
            .collect();
    }
    if let Some(acc) = attr(&Semantic::TexCoords(0)) {
        let v = cx.read(
            &acc,
            &format!("{where_} TEXCOORD_0"),
            Dimensions::Vec2,
            &[DataType::F32, DataType::U8, DataType::U16],
        )?;
        same_count(&v, 2, "TEXCOORD_0")?;
        mesh.uvs = v.chunks_exact(2).map(Vec2::from_slice).collect();
    }
    match (attr(&Semantic::Joints(0)), attr(&Semantic::Weights(0))) {
        (Some(ja), Some(wa)) => {
            let j = cx.read_u32(
                &ja,
                &format!("{where_} JOINTS_0"),
                Dimensions::Vec4,
                &[DataType::U8, DataType::U16],
            )?;
            if j.len() != n * 4 {
                return Err(cx.invalid(format!(
                    "{where_} JOINTS_0 has {} entries but POSITION has {n}",
                    j.len() / 4
                )));
            }
            let w = cx.read(
                &wa,
                &format!("{where_} WEIGHTS_0"),
                Dimensions::Vec4,
                &[DataType::F32, DataType::U8, DataType::U16],
            )?;
            same_count(&w, 4, "WEIGHTS_0")?;
            mesh.joints = j
                .chunks_exact(4)
                // An index past the skin stays past it, so weight repair can zero its weight.
                .map(|c| {
                    std::array::from_fn(|k| {
                        new_from_old
                            .get(c[k] as usize)
                            .map_or(u16::MAX, |&x| x as u16)
                    })
                })
                .collect();
            mesh.weights = w
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect();
        }
        (None, None) => {}
        _ => return Err(cx.invalid(format!("{where_} has only one of JOINTS_0 and WEIGHTS_0"))),
    }
    mesh.indices = match prim.indices() {
        Some(acc) => cx.read_u32(
            &acc,
            &format!("{where_} indices"),
            Dimensions::Scalar,
            &[DataType::U8, DataType::U16, DataType::U32],
        )?,
        None => (0..n as u32).collect(),
    };
    Ok(mesh)
}

struct Ctx<'a> {
    label: &'a str,
    buffers: &'a [gltf::buffer::Data],
}

impl Ctx<'_> {
    fn invalid(&self, problem: String) -> SkinError {
        SkinError::Invalid {
            path: self.label.to_owned(),
            problem,
        }
    }

    /// Decodes an accessor into flat `f32`s (`count × components`). Integer types decode as
    /// their value, or as unorm / snorm when the accessor is `normalized`. Every size is checked
    /// against the buffer before anything is read or allocated.
    fn read(
        &self,
        acc: &gltf::Accessor<'_>,
        what: &str,
        dims: Dimensions,
        types: &[DataType],
    ) -> Result<Vec<f32>, SkinError> {
        let normalized = acc.normalized();
        self.read_with(acc, what, dims, types, |dt, b| {
            decode_f32(dt, b, normalized)
        })
    }

    /// Decodes an integer accessor (indices, joints) exactly.
    fn read_u32(
        &self,
        acc: &gltf::Accessor<'_>,
        what: &str,
        dims: Dimensions,
        types: &[DataType],
    ) -> Result<Vec<u32>, SkinError> {
        self.read_with(acc, what, dims, types, decode_u32)
    }

    fn read_with<T: Default + Clone>(
        &self,
        acc: &gltf::Accessor<'_>,
        what: &str,
        dims: Dimensions,
        types: &[DataType],
        decode: impl Fn(DataType, &[u8]) -> T,
    ) -> Result<Vec<T>, SkinError> {
        let bad = |p: String| self.invalid(format!("{what} (accessor {}): {p}", acc.index()));
        if acc.dimensions() != dims {
            return Err(bad(format!(
                "type is {:?}, expected {dims:?}",
                acc.dimensions()
            )));
        }
        let dt = acc.data_type();
        if !types.contains(&dt) {
            return Err(bad(format!(
                "component type {dt:?} is not one of {types:?}"
            )));
        }
        if acc.sparse().is_some() {
            return Err(bad("sparse accessors are not supported here".into()));
        }
        let comps = dims.multiplicity();
        let comp_size = dt.size();
        let elem_size = comps * comp_size;
        let count = acc.count();
        if count == 0 {
            return Err(bad("count is 0; glTF requires at least one element".into()));
        }
        let Some(view) = acc.view() else {
            // No buffer view: all zeros by the spec; the count is bounded only by the JSON, so
            // cap it instead of trusting it.
            if count > 1 << 24 {
                return Err(bad(format!("{count} elements without a buffer view")));
            }
            return Ok(vec![T::default(); count * comps]);
        };
        let buffer = self
            .buffers
            .get(view.buffer().index())
            .ok_or_else(|| bad(format!("buffer {} is missing", view.buffer().index())))?;
        let view_end = view.offset().checked_add(view.length());
        let view_bytes = view_end
            .and_then(|end| buffer.0.get(view.offset()..end))
            .ok_or_else(|| {
                bad(format!(
                    "buffer view {} (offset {}, length {}) runs past its buffer of {} bytes",
                    view.index(),
                    view.offset(),
                    view.length(),
                    buffer.0.len()
                ))
            })?;
        let stride = view.stride().unwrap_or(elem_size);
        if stride < elem_size {
            return Err(bad(format!(
                "byte stride {stride} is smaller than the element size {elem_size}"
            )));
        }
        let needed = (count - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(acc.offset()))
            .and_then(|x| x.checked_add(elem_size));
        let bytes = needed.and_then(|end| view_bytes.get(acc.offset()..end)).ok_or_else(|| {
            bad(format!(
                "{count} elements of {elem_size} bytes (stride {stride}, offset {}) do not fit in buffer view {} of {} bytes",
                acc.offset(),
                view.index(),
                view_bytes.len()
            ))
        })?;
        let mut out = Vec::with_capacity(count * comps);
        for e in 0..count {
            let elem = &bytes[e * stride..e * stride + elem_size];
            out.extend(elem.chunks_exact(comp_size).map(|c| decode(dt, c)));
        }
        Ok(out)
    }
}

fn decode_u32(dt: DataType, b: &[u8]) -> u32 {
    match dt {
        DataType::U8 => u32::from(b[0]),
        DataType::U16 => u32::from(u16::from_le_bytes([b[0], b[1]])),
        DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        // Only unsigned types are requested for integer data.
        DataType::I8 | DataType::I16 | DataType::F32 => 0,
    }
}

fn decode_f32(dt: DataType, b: &[u8], normalized: bool) -> f32 {
    let (value, max) = match dt {
        DataType::F32 => return f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        DataType::I8 => (f32::from(i8::from_le_bytes([b[0]])), 127.0),
        DataType::U8 => (f32::from(b[0]), 255.0),
        DataType::I16 => (f32::from(i16::from_le_bytes([b[0], b[1]])), 32767.0),
        DataType::U16 => (f32::from(u16::from_le_bytes([b[0], b[1]])), 65535.0),
        DataType::U32 => (
            u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            4_294_967_295.0,
        ),
    };
    if normalized {
        (value / max).max(-1.0)
    } else {
        value
    }
}

//! Import of skinned glTF: the skin's joint hierarchy (with non-joint ancestors), inverse bind
//! matrices, skinned meshes with JOINTS_0 / WEIGHTS_0 and every animation clip.
//!
//! Built on the hardened reader of [`crate::io::gltf_mesh`]: the JSON is only deserialized
//! (never run through gltf-json's validation, which can panic), the container, buffers,
//! accessors, primitives and images are read there with every size checked against the bytes
//! present and the [`ImportLimits`], external files are confined to the file's folder, and
//! every index in the JSON is looked up with a check. A broken file gives an error naming the
//! file and what is wrong; nothing panics.

use std::path::Path;

use glam::{Mat4, Quat, Vec3, Vec4};
use gltf::json;
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;

use crate::io::gltf_mesh::{OpenedGltf, open_gltf};
use crate::io::{ImportLimits, IoError};
use crate::mesh::{Material, MeshModel};
use crate::skin::SkinError;
use crate::skin::clip::{AnimationClip, Channel, Interpolation, Property};
use crate::skin::lbs::{WeightRepair, repair_mesh_weights};
use crate::skin::skeleton::{Joint, Skeleton, Transform};

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
    /// Things skipped, repaired or left out of the import (see `io::import_gltf_reported`),
    /// one human-readable line each, for the caller to show (they are not logged).
    pub warnings: Vec<String>,
    /// The file's first camera and its directional lights (see `io::GltfView`), in the
    /// file's world space.
    pub view: crate::io::GltfView,
    /// World transform of the first node carrying the skinned mesh, for reference only: glTF
    /// skinning ignores it. In files like RiggedFigure and CesiumMan, whose inverse bind
    /// matrices were made without the Z-up node above the skeleton, the rest pose skins the
    /// bind-pose vertices to exactly `world_from_skinned_node · v`.
    pub world_from_skinned_node: Mat4,
}

/// Imports the first skin of a `.gltf` / `.glb` file (the first node in the scene that has a
/// mesh and a skin decides which), its meshes and all animation clips, within the default
/// [`ImportLimits`].
///
/// # Errors
/// [`SkinError`] naming the file and the problem; never panics on a broken file.
pub fn import_skinned(path: impl AsRef<Path>) -> Result<SkinnedImport, SkinError> {
    import_skinned_with(path.as_ref(), &ImportLimits::default())
}

/// [`import_skinned`] with explicit limits.
///
/// # Errors
/// As [`import_skinned`]; declared sizes over `limits` are refused before allocating.
pub fn import_skinned_with(path: &Path, limits: &ImportLimits) -> Result<SkinnedImport, SkinError> {
    let label = path.display().to_string();
    let bytes = crate::io::error::read_file_limited(path, limits).map_err(skin_error)?;
    let base = path.parent().unwrap_or_else(|| Path::new("."));
    let file = open_gltf(&bytes, path, Some(base), limits).map_err(skin_error)?;
    import_impl(file, &label)
}

/// [`import_skinned`] from bytes; external (non-embedded) buffers and images are refused, so
/// the bytes never make the importer touch the file system.
///
/// # Errors
/// As [`import_skinned`], with `label` standing for the file name in messages.
pub fn import_skinned_slice(bytes: &[u8], label: &str) -> Result<SkinnedImport, SkinError> {
    let limits = ImportLimits::default();
    let file = open_gltf(bytes, Path::new(label), None, &limits).map_err(skin_error)?;
    import_impl(file, label)
}

/// The reader's error as a [`SkinError`], its message unchanged.
fn skin_error(e: IoError) -> SkinError {
    let path = e.path().display().to_string();
    match e {
        IoError::Io { source, .. } => SkinError::Io { path, source },
        other => {
            let text = other.to_string();
            let problem = text
                .strip_prefix(&format!("{path}: "))
                .unwrap_or(&text)
                .to_owned();
            SkinError::Invalid { path, problem }
        }
    }
}

/// `index` checked against a table of `len`, for "X refers to Y n, which does not exist".
fn checked(index: usize, len: usize, what: impl FnOnce() -> String) -> Result<usize, String> {
    if index < len {
        Ok(index)
    } else {
        Err(format!("{}, which does not exist", what()))
    }
}

#[allow(clippy::too_many_lines)]
fn import_impl(mut file: OpenedGltf<'_>, label: &str) -> Result<SkinnedImport, SkinError> {
    let invalid = |problem: String| SkinError::Invalid {
        path: label.to_owned(),
        problem,
    };
    let mut warnings = Vec::new();

    // Node hierarchy: parent links (every child index checked), and which nodes the scene
    // reaches with their world transforms (a cycle or a node reached twice is an error).
    let node_count = file.root.nodes.len();
    let mut parent_of = vec![None; node_count];
    for (n, node) in file.root.nodes.iter().enumerate() {
        for child in node.children.iter().flatten() {
            let c = checked(child.value(), node_count, || {
                format!("node {n} has child {}", child.value())
            })
            .map_err(invalid)?;
            if parent_of[c].replace(n).is_some() {
                return Err(invalid(format!("node {c} has more than one parent")));
            }
        }
    }
    let scene = file.scene_nodes().map_err(skin_error)?;
    let mut world_of: Vec<Option<Mat4>> = vec![None; node_count];
    for &(n, m) in &scene {
        if let Some(w) = world_of.get_mut(n) {
            *w = Some(m);
        }
    }
    let in_scene = |n: usize| world_of.get(n).is_some_and(Option::is_some);

    // The skin: the first scene node (in file order) with a mesh and a skin.
    let Some((skin_node, skin_index)) = (0..node_count)
        .filter(|&n| in_scene(n) && file.root.nodes[n].mesh.is_some())
        .find_map(|n| file.root.nodes[n].skin.map(|s| (n, s.value())))
    else {
        return Err(SkinError::NoSkin {
            path: label.to_owned(),
        });
    };
    let world_from_skinned_node = world_of[skin_node].unwrap_or(Mat4::IDENTITY);
    let skin = file.root.skins.get(skin_index).ok_or_else(|| {
        invalid(format!(
            "node {skin_node} refers to skin {skin_index}, which does not exist"
        ))
    })?;
    let skin_nodes = skin
        .joints
        .iter()
        .map(|j| {
            checked(j.value(), node_count, || {
                format!("skin {skin_index} lists joint node {}", j.value())
            })
        })
        .collect::<Result<Vec<usize>, String>>()
        .map_err(invalid)?;
    let inverse_bind_accessor = skin.inverse_bind_matrices.map(|a| a.value());
    if skin_nodes.is_empty() {
        return Err(invalid(format!("skin {skin_index} has no joints")));
    }
    if skin_nodes.len() > usize::from(u16::MAX) {
        return Err(invalid(format!(
            "skin {skin_index} has {} joints; at most 65535 fit",
            skin_nodes.len()
        )));
    }
    let mut joint_of_node = vec![None; node_count];
    for (j, &n) in skin_nodes.iter().enumerate() {
        if joint_of_node[n].replace(j).is_some() {
            return Err(invalid(format!("skin {skin_index} lists node {n} twice")));
        }
    }
    let inverse_binds: Vec<Mat4> = match inverse_bind_accessor {
        Some(acc) => {
            let what = format!("inverse bind matrices of skin {skin_index} (accessor {acc})");
            let (flat, _) = file
                .floats(acc, &what, &[Type::Mat4], &[ComponentType::F32])
                .map_err(skin_error)?;
            let mats: Vec<Mat4> = flat.chunks_exact(16).map(Mat4::from_cols_slice).collect();
            if mats.len() < skin_nodes.len() {
                return Err(invalid(format!(
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
            attachment = file.local_transform(a).map_err(skin_error)? * attachment;
            cur = parent_of[a];
            steps += 1;
            if steps > node_count {
                return Err(invalid(format!("the ancestors of node {n} form a cycle")));
            }
        }
        // Checks the node's transform (finite, a usable rotation) before taking it apart.
        let local = file.local_transform(n).map_err(skin_error)?;
        let node = &file.root.nodes[n];
        let (scale, rotation, translation) = if node.matrix.is_some() {
            local.to_scale_rotation_translation()
        } else {
            (
                Vec3::from_array(node.scale.unwrap_or([1.0; 3])),
                Quat::from_array(node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0)),
                Vec3::from_array(node.translation.unwrap_or([0.0; 3])),
            )
        };
        joints.push(Joint {
            name: node.name.clone().unwrap_or_else(|| format!("node {n}")),
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
        Skeleton::new(joints).map_err(|e| invalid(format!("skin {skin_index}: {e}")))?;

    // Meshes bound to this skin, read by the hardened primitive reader.
    let mut model = MeshModel {
        parts: Vec::new(),
        materials: file.materials().map_err(skin_error)?,
    };
    let default_material = model.materials.len();
    let mut needs_default_material = false;
    for n in (0..node_count).filter(|&n| in_scene(n)) {
        let node = &file.root.nodes[n];
        let Some(mesh_index) = node.mesh.map(|m| m.value()) else {
            continue;
        };
        match node.skin.map(|s| s.value()) {
            Some(_) if super::gltf_instancing::is_instanced(node) => {
                return Err(invalid(format!(
                    "node {n} is skinned and has {}: its joints place its mesh, so instances \
                     of it cannot be placed",
                    super::gltf_instancing::INSTANCING
                )));
            }
            Some(s) if s == skin_index => {}
            Some(s) => {
                warnings.push(format!(
                    "node {n} uses skin {s}, only skin {skin_index} is imported"
                ));
                continue;
            }
            None => {
                warnings.push(format!("node {n} has a mesh without a skin; left out"));
                continue;
            }
        }
        let mesh = file.root.meshes.get(mesh_index).ok_or_else(|| {
            invalid(format!(
                "node {n} refers to mesh {mesh_index}, which does not exist"
            ))
        })?;
        let materials: Vec<Option<usize>> = mesh
            .primitives
            .iter()
            .map(|p| p.material.map(|m| m.value()))
            .collect();
        for (prim_index, material) in materials.into_iter().enumerate() {
            let where_ = format!("mesh {mesh_index} primitive {prim_index}");
            let Some(mut part) = file.primitive(mesh_index, prim_index).map_err(skin_error)? else {
                warnings.push(format!("{where_}: not triangles; left out"));
                continue;
            };
            match (part.joints.is_empty(), part.weights.is_empty()) {
                (false, false) | (true, true) => {}
                _ => {
                    return Err(invalid(format!(
                        "{where_} has only one of JOINTS_0 and WEIGHTS_0"
                    )));
                }
            }
            // An index past the skin stays past it, so weight repair can zero its weight.
            for j in part.joints.iter_mut().flatten() {
                *j = new_from_old
                    .get(usize::from(*j))
                    .map_or(u16::MAX, |&x| u16::try_from(x).unwrap_or(u16::MAX));
            }
            part.material = match material {
                Some(m) if m < default_material => m,
                Some(m) => {
                    return Err(invalid(format!(
                        "{where_} refers to material {m}, which does not exist"
                    )));
                }
                None => {
                    needs_default_material = true;
                    default_material
                }
            };
            part.validate()
                .map_err(|e| invalid(format!("{where_}: {e}")))?;
            model.parts.push(part);
        }
    }
    if needs_default_material {
        model.materials.push(Material::default());
    }
    if model.parts.is_empty() {
        return Err(invalid(format!(
            "no triangle primitive is bound to skin {skin_index}"
        )));
    }
    let mut weight_repair = WeightRepair::default();
    for part in &mut model.parts {
        weight_repair.add(&repair_mesh_weights(part, skeleton.len()));
    }
    if weight_repair.total() > 0 {
        warnings.push(format!("vertex weights repaired: {weight_repair}"));
    }

    let clips = read_clips(
        &file,
        &joint_of_node,
        &new_from_old,
        skeleton.len(),
        label,
        &mut warnings,
    )?;
    warnings.extend(crate::io::gltf_report::dropped_features(
        &file.root,
        crate::io::gltf_report::Reader::Skinned,
    ));
    let (view, view_lines) = crate::io::gltf_view::read_view(&file.root, &scene);
    warnings.extend(view_lines);
    // Not logged here: the caller shows them (the CLI prints them, the editor's import
    // report lists them), so each is printed once.
    Ok(SkinnedImport {
        skeleton,
        clips,
        mesh: model,
        weight_repair,
        warnings,
        view,
        world_from_skinned_node,
    })
}

/// Every animation's channels that target the skin's joints, each checked (target node,
/// sampler and accessors exist and agree).
fn read_clips(
    file: &OpenedGltf<'_>,
    joint_of_node: &[Option<usize>],
    new_from_old: &[usize],
    joint_count: usize,
    label: &str,
    warnings: &mut Vec<String>,
) -> Result<Vec<AnimationClip>, SkinError> {
    let invalid = |problem: String| SkinError::Invalid {
        path: label.to_owned(),
        problem,
    };
    let mut clips = Vec::new();
    for (a, anim) in file.root.animations.iter().enumerate() {
        let name = anim
            .name
            .clone()
            .unwrap_or_else(|| format!("animation {a}"));
        let mut clip = AnimationClip {
            name: name.clone(),
            duration_secs: 0.0,
            channels: Vec::new(),
            ..AnimationClip::default()
        };
        let mut skipped = 0usize;
        for (c, ch) in anim.channels.iter().enumerate() {
            let what = format!("{name:?} channel {c}");
            let node = ch.target.node.value();
            let Some(&joint) = joint_of_node.get(node) else {
                return Err(invalid(format!(
                    "animation {what} targets node {node}, which does not exist"
                )));
            };
            let property = match ch.target.path {
                Checked::Valid(json::animation::Property::Translation) => Property::Translation,
                Checked::Valid(json::animation::Property::Rotation) => Property::Rotation,
                Checked::Valid(json::animation::Property::Scale) => Property::Scale,
                Checked::Valid(json::animation::Property::MorphTargetWeights) => {
                    skipped += 1;
                    continue;
                }
                Checked::Invalid => {
                    return Err(invalid(format!("animation {what}: invalid target path")));
                }
            };
            let Some(old_joint) = joint else {
                skipped += 1;
                continue;
            };
            let s = ch.sampler.value();
            let sampler = anim.samplers.get(s).ok_or_else(|| {
                invalid(format!(
                    "animation {what} refers to sampler {s}, which does not exist"
                ))
            })?;
            let interpolation = match sampler.interpolation {
                Checked::Valid(json::animation::Interpolation::Step) => Interpolation::Step,
                Checked::Valid(json::animation::Interpolation::Linear) => Interpolation::Linear,
                Checked::Valid(json::animation::Interpolation::CubicSpline) => {
                    Interpolation::CubicSpline
                }
                Checked::Invalid => {
                    return Err(invalid(format!("animation {what}: invalid interpolation")));
                }
            };
            let (times, _) = file
                .floats(
                    sampler.input.value(),
                    &format!("{what} key times (accessor {})", sampler.input.value()),
                    &[Type::Scalar],
                    &[ComponentType::F32],
                )
                .map_err(skin_error)?;
            let out = sampler.output.value();
            let values: Vec<Vec4> = match property {
                Property::Rotation => file
                    .floats(
                        out,
                        &format!("{what} rotations (accessor {out})"),
                        &[Type::Vec4],
                        &[
                            ComponentType::F32,
                            ComponentType::I8,
                            ComponentType::U8,
                            ComponentType::I16,
                            ComponentType::U16,
                        ],
                    )
                    .map_err(skin_error)?
                    .0
                    .chunks_exact(4)
                    .map(Vec4::from_slice)
                    .collect(),
                Property::Translation | Property::Scale => file
                    .floats(
                        out,
                        &format!("{what} values (accessor {out})"),
                        &[Type::Vec3],
                        &[ComponentType::F32],
                    )
                    .map_err(skin_error)?
                    .0
                    .chunks_exact(3)
                    .map(|c| Vec3::from_slice(c).extend(0.0))
                    .collect(),
            };
            let channel = Channel {
                joint: new_from_old.get(old_joint).copied().unwrap_or(usize::MAX),
                property,
                interpolation,
                times,
                values,
            };
            channel
                .check(joint_count)
                .map_err(|problem| invalid(format!("animation {what} (node {node}): {problem}")))?;
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
    Ok(clips)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    fn simple_skin() -> Value {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../shared/assets/skinned/SimpleSkin.gltf"
        );
        serde_json::from_slice(&std::fs::read(path).expect("SimpleSkin")).expect("JSON")
    }

    fn import_value(v: &Value) -> Result<SkinnedImport, SkinError> {
        import_skinned_slice(&serde_json::to_vec(v).unwrap(), "case.gltf")
    }

    #[test]
    fn the_reported_panics_are_errors() {
        assert!(import_value(&simple_skin()).is_ok());
        // A huge bufferView offset and length (panicked inside gltf::import_images).
        let mut v = simple_skin();
        v["bufferViews"][0]["byteOffset"] = (u64::MAX / 2).into();
        v["bufferViews"][0]["byteLength"] = (u64::MAX / 2).into();
        let e = import_value(&v).unwrap_err().to_string();
        assert!(
            e.starts_with("case.gltf: ") && e.contains("buffer view 0"),
            "{e}"
        );
        // An animation channel whose target node does not exist (an unwrap).
        let mut v = simple_skin();
        v["animations"][0]["channels"][0]["target"]["node"] = 99.into();
        let e = import_value(&v).unwrap_err().to_string();
        assert!(e.contains("node 99, which does not exist"), "{e}");
        // A sampler that does not exist.
        let mut v = simple_skin();
        v["animations"][0]["channels"][0]["sampler"] = 7.into();
        let e = import_value(&v).unwrap_err().to_string();
        assert!(e.contains("sampler 7, which does not exist"), "{e}");
        // Accessors removed from the JSON (panicked in gltf-json's validation).
        let mut v = simple_skin();
        v.as_object_mut().unwrap().remove("accessors");
        let e = import_value(&v).unwrap_err().to_string();
        assert!(
            e.starts_with("case.gltf: ") && e.contains("does not exist"),
            "{e}"
        );
        // A skin joint that is not a node.
        let mut v = simple_skin();
        v["skins"][0]["joints"][0] = 40.into();
        let e = import_value(&v).unwrap_err().to_string();
        assert!(e.contains("joint node 40, which does not exist"), "{e}");
    }

    /// SimpleSkin in `dir/inner/s.gltf` with buffer 0 read from `uri`; buffer 0's bytes are
    /// also in `dir/outside.bin` (so a refusal is about the path, not the content) and
    /// `dir/inner/b0.bin`.
    fn with_uri(dir: &Path, uri: &str) -> std::path::PathBuf {
        let mut v = simple_skin();
        let data = v["buffers"][0]["uri"].as_str().unwrap().to_owned();
        let b64 = data.split_once(',').unwrap().1;
        let bytes = crate::io::gltf_mesh::decode_base64(b64).unwrap();
        let inner = dir.join("inner");
        let _ = std::fs::create_dir(&inner);
        std::fs::write(dir.join("outside.bin"), &bytes).unwrap();
        std::fs::write(inner.join("b0.bin"), &bytes).unwrap();
        v["buffers"][0]["uri"] = uri.into();
        let path = inner.join("s.gltf");
        std::fs::write(&path, serde_json::to_vec(&v).unwrap()).unwrap();
        path
    }

    fn refused(dir: &Path, uri: &str, rule: &str) {
        let path = with_uri(dir, uri);
        let e = import_skinned(&path).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{}: ", path.display())) && e.contains(rule),
            "{uri}: {e}"
        );
    }

    #[test]
    fn uris_inside_the_folder_are_read() {
        let dir = tempfile::tempdir().unwrap();
        assert!(import_skinned(with_uri(dir.path(), "b0.bin")).is_ok());
        assert!(import_skinned(with_uri(dir.path(), "./b0.bin")).is_ok());
    }

    #[test]
    fn absolute_uris_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let abs = dir.path().join("outside.bin");
        refused(dir.path(), abs.to_str().unwrap(), "absolute");
        refused(dir.path(), "", "empty");
    }

    #[test]
    fn dot_dot_uris_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        refused(dir.path(), "../outside.bin", "'..'");
        refused(dir.path(), "%2E%2E/outside.bin", "'..'");
    }

    #[cfg(unix)]
    #[test]
    fn device_file_uris_fail_fast() {
        let dir = tempfile::tempdir().unwrap();
        refused(dir.path(), "/dev/zero", "absolute");
        // The same device through a link in the folder.
        let path = with_uri(dir.path(), "zero.bin");
        std::os::unix::fs::symlink("/dev/zero", path.with_file_name("zero.bin")).unwrap();
        assert!(import_skinned(&path).is_err());
        // And the static importer refuses it the same way.
        let e = crate::io::import_gltf(&path).unwrap_err().to_string();
        assert!(e.contains("symbolic link"), "{e}");
    }

    #[cfg(unix)]
    #[test]
    fn symlink_uris_out_of_the_folder_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = with_uri(dir.path(), "link.bin");
        std::os::unix::fs::symlink(
            dir.path().join("outside.bin"),
            path.with_file_name("link.bin"),
        )
        .unwrap();
        let e = import_skinned(&path).unwrap_err().to_string();
        assert!(e.contains("symbolic link"), "{e}");
    }
}

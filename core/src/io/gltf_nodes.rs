//! A glTF scene's nodes as objects: which object transform each node's mesh gets, the mesh in
//! that object's space, and which nodes are huge flat planes (ground, water) best kept as
//! meshes rather than voxelized.
//!
//! **Placement.** An object's transform is translation, rotation and per-axis scale; a node's
//! world transform may also shear (a rotated child of a non-uniformly scaled parent). Each node
//! gets the most of its world transform the object can hold while its voxels stay cubes:
//! - a rotation and a uniform positive scale ([`Placement::Node`]): the object transform *is*
//!   the node's world transform, and the mesh stays in the node's own space;
//! - a non-uniform or mirroring scale without shear ([`Placement::ScaleBaked`]): translation and
//!   rotation go to the transform and the scale is baked into the mesh (a stretched transform
//!   would stretch the voxels into boxes);
//! - a shear ([`Placement::WorldBaked`]): the identity, with the mesh in world space.
//!
//! A skinned node ([`Placement::Skinned`]) keeps its bind-pose mesh space and the identity:
//! its joints place it, not its node.

use glam::{Mat4, Vec3};

#[cfg(doc)]
use super::gltf_mesh::GltfImport;
use super::gltf_mesh::GltfNode;
use crate::mesh::{MeshModel, TriangleMesh};
use crate::scene::Transform;

/// A node is flat when its thinnest extent (in its object's space) is at most this fraction of
/// its middle one.
pub const FLAT_RATIO: f32 = 0.01;

/// A flat node is a huge plane when its longest world extent is at least this many times the
/// longest world extent of the rest of the scene together (see `mark_huge_flat_planes`).
pub const HUGE_RATIO: f32 = 4.0;

/// How a node's world transform became its object's (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Placement {
    /// Object transform = the node's world transform; the mesh in the node's space.
    Node,
    /// Translation and rotation kept; the node's non-uniform (or mirroring) scale baked into
    /// the mesh.
    ScaleBaked,
    /// The node's world transform shears: identity transform, mesh in world space.
    WorldBaked,
    /// A skinned node: identity transform, mesh in bind-pose mesh space.
    Skinned,
}

/// One node of the scene, ready to become an object.
#[derive(Debug, Clone)]
pub struct NodeObject {
    /// The node's name (see [`super::GltfNode::name`]).
    pub name: String,
    /// Its index in the file's `nodes`.
    pub node: usize,
    /// `world_from_object`.
    pub transform: Transform,
    /// The node's triangles in object space, with only the materials they use.
    pub model: MeshModel,
    /// How `transform` was chosen.
    pub placement: Placement,
    /// World units per object unit: the uniform scale `transform` holds (1 when it holds none).
    /// A voxel size in world units is this many times smaller in object units.
    pub world_per_object_unit: f32,
    /// World-space bounds of the node's triangles (mesh space for a skinned node).
    pub world_bounds: (Vec3, Vec3),
    /// A huge flat plane (ground, water; see [`FLAT_RATIO`] and [`HUGE_RATIO`]).
    pub huge_flat_plane: bool,
}

/// Names given to pick nodes that the file does not have.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("no node named {} (the nodes with meshes are {})", quoted(.missing), quoted(.available))]
pub struct UnknownNodes {
    /// The names not found.
    pub missing: Vec<String>,
    /// The names of the nodes that have meshes, in scene order.
    pub available: Vec<String>,
}

fn quoted(names: &[String]) -> String {
    if names.is_empty() {
        return "none".to_owned();
    }
    names
        .iter()
        .map(|n| format!("{n:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The object transform for a node with world transform `world_from_node`, how it was chosen,
/// and the uniform scale it holds (see the module docs).
#[must_use]
pub fn placement(world_from_node: Mat4) -> (Transform, Placement, f32) {
    let (scale, rotation, translation) = world_from_node.to_scale_rotation_translation();
    let rotation = rotation.normalize();
    let recomposed = Mat4::from_scale_rotation_translation(scale, rotation, translation);
    let size = world_from_node
        .to_cols_array()
        .iter()
        .fold(1.0f32, |m, v| m.max(v.abs()));
    let shears = world_from_node
        .to_cols_array()
        .iter()
        .zip(recomposed.to_cols_array())
        .any(|(a, b)| (a - b).abs() > 1e-4 * size);
    let finite = scale.is_finite() && rotation.is_finite() && translation.is_finite();
    if shears || !finite || scale.abs().min_element() < 1e-12 {
        return (Transform::default(), Placement::WorldBaked, 1.0);
    }
    let s = scale.x;
    if s > 0.0 && (scale - Vec3::splat(s)).abs().max_element() <= 1e-5 * s {
        let transform = Transform {
            translation,
            rotation,
            scale: Vec3::splat(s),
        };
        return (transform, Placement::Node, s);
    }
    let transform = Transform {
        translation,
        rotation,
        scale: Vec3::ONE,
    };
    (transform, Placement::ScaleBaked, 1.0)
}

/// An import's nodes (`nodes` over `model`, as [`GltfImport`] holds them) as objects, in scene
/// order; with `pick`, only the nodes with those names (every node of a name, when several
/// share it). Whether a node is a huge flat plane is judged against the whole scene, picked
/// or not.
///
/// # Errors
/// [`UnknownNodes`] when a picked name is no node's.
pub fn node_objects(
    model: &MeshModel,
    nodes: &[GltfNode],
    pick: Option<&[String]>,
) -> Result<Vec<NodeObject>, UnknownNodes> {
    if let Some(pick) = pick {
        let missing: Vec<String> = pick
            .iter()
            .filter(|name| !nodes.iter().any(|n| &n.name == *name))
            .cloned()
            .collect();
        if !missing.is_empty() {
            return Err(UnknownNodes {
                missing,
                available: nodes.iter().map(|n| n.name.clone()).collect(),
            });
        }
    }
    let mut all: Vec<NodeObject> = nodes
        .iter()
        .filter_map(|node| {
            let parts = model.parts.get(node.parts.clone())?;
            let world_bounds =
                crate::mesh::bounds_of(parts.iter().flat_map(|p| p.positions.iter().copied()))?;
            let (transform, placement, world_per_object_unit) = if node.skinned {
                (Transform::default(), Placement::Skinned, 1.0)
            } else {
                placement(node.world_from_node)
            };
            let object_from_world = transform.matrix().inverse();
            let object_model = with_used_materials(model, parts, |part| {
                if placement != Placement::Skinned && placement != Placement::WorldBaked {
                    part.transform(object_from_world);
                }
            });
            Some(NodeObject {
                name: node.name.clone(),
                node: node.index,
                transform,
                model: object_model,
                placement,
                world_per_object_unit,
                world_bounds,
                huge_flat_plane: false,
            })
        })
        .collect();
    mark_huge_flat_planes(&mut all);
    if let Some(pick) = pick {
        all.retain(|o| pick.contains(&o.name));
    }
    Ok(all)
}

/// `parts` (of `source`) with `place` applied, and only the materials they use, renumbered.
fn with_used_materials(
    source: &MeshModel,
    parts: &[TriangleMesh],
    place: impl Fn(&mut TriangleMesh),
) -> MeshModel {
    let mut model = MeshModel::default();
    let mut renumbered = vec![usize::MAX; source.materials.len()];
    for part in parts {
        let mut part = part.clone();
        place(&mut part);
        if let Some(slot) = renumbered.get_mut(part.material) {
            if *slot == usize::MAX {
                *slot = model.materials.len();
                model
                    .materials
                    .push(source.materials[part.material].clone());
            }
            part.material = *slot;
        }
        model.parts.push(part);
    }
    model
}

/// Whether bounds with extents `extent` (in the object's space) are flat (see [`FLAT_RATIO`]).
#[must_use]
pub fn is_flat(extent: Vec3) -> bool {
    let mut e = extent.abs().to_array();
    e.sort_by(f32::total_cmp);
    e[1] > 0.0 && e[0] <= FLAT_RATIO * e[1]
}

/// Sets [`NodeObject::huge_flat_plane`] on the flat nodes much larger than the rest: the
/// other nodes except flat ones at least half as large (so a ground and a water plane of the
/// same size do not hide each other, while small flat parts — leaves, cards — count as the
/// rest). A flat node with no such rest is not flagged.
fn mark_huge_flat_planes(objects: &mut [NodeObject]) {
    let flat: Vec<bool> = objects
        .iter()
        .map(|o| o.model.bounds().is_some_and(|(lo, hi)| is_flat(hi - lo)))
        .collect();
    let size: Vec<f32> = objects
        .iter()
        .map(|o| (o.world_bounds.1 - o.world_bounds.0).max_element())
        .collect();
    let huge: Vec<bool> = (0..objects.len())
        .map(|i| {
            if !flat[i] {
                return false;
            }
            let rest = (0..objects.len())
                .filter(|&j| j != i && !(flat[j] && size[j] >= 0.5 * size[i]))
                .map(|j| objects[j].world_bounds)
                .reduce(|(alo, ahi), (blo, bhi)| (alo.min(blo), ahi.max(bhi)));
            rest.is_some_and(|(lo, hi)| size[i] >= HUGE_RATIO * (hi - lo).max_element())
        })
        .collect();
    for (o, h) in objects.iter_mut().zip(huge) {
        o.huge_flat_plane = h;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn placement_keeps_what_the_transform_can_hold() {
        let r = Quat::from_rotation_y(0.7);
        let t = Vec3::new(1.0, 2.0, 3.0);
        let (tr, p, s) = placement(Mat4::from_scale_rotation_translation(
            Vec3::splat(2.0),
            r,
            t,
        ));
        assert_eq!((p, s), (Placement::Node, 2.0));
        assert!(tr.rotation.abs_diff_eq(r, 1e-6) && tr.translation.abs_diff_eq(t, 1e-6));
        let (tr, p, s) = placement(Mat4::from_scale_rotation_translation(
            Vec3::new(1.0, 3.0, 1.0),
            r,
            t,
        ));
        assert_eq!((p, s, tr.scale), (Placement::ScaleBaked, 1.0, Vec3::ONE));
        assert!(tr.rotation.abs_diff_eq(r, 1e-6));
        // A rotated child of a non-uniformly scaled parent shears.
        let shear = Mat4::from_scale(Vec3::new(1.0, 4.0, 1.0)) * Mat4::from_rotation_z(0.6);
        assert_eq!(placement(shear).1, Placement::WorldBaked);
    }

    fn part(positions: Vec<Vec3>, material: usize) -> TriangleMesh {
        TriangleMesh {
            indices: (0..positions.len() as u32).collect(),
            positions,
            material,
            ..TriangleMesh::default()
        }
    }

    fn node(index: usize, name: &str, world_from_node: Mat4) -> GltfNode {
        GltfNode {
            index,
            name: name.to_owned(),
            world_from_node,
            parts: index..index + 1,
            skinned: false,
        }
    }

    #[test]
    fn nodes_get_their_own_space_materials_and_plane_flags() {
        let materials = (0..3)
            .map(|i| crate::mesh::Material {
                name: format!("m{i}"),
                ..crate::mesh::Material::default()
            })
            .collect();
        // World-space parts, as the reader leaves them: a small triangle moved by its node, and
        // a 100 x 100 ground two orders of magnitude larger.
        let at = Mat4::from_translation(Vec3::new(3.0, 0.0, 0.0));
        let local = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let model = MeshModel {
            parts: vec![
                part(local.iter().map(|&p| at.transform_point3(p)).collect(), 2),
                part(
                    vec![
                        Vec3::new(-50.0, 0.0, -50.0),
                        Vec3::new(50.0, 0.0, -50.0),
                        Vec3::new(0.0, 0.0, 50.0),
                    ],
                    0,
                ),
            ],
            materials,
        };
        let nodes = [node(0, "Leaf", at), node(1, "Ground", Mat4::IDENTITY)];
        let objects = node_objects(&model, &nodes, None).unwrap();
        let leaf = &objects[0];
        assert_eq!(leaf.transform.translation, Vec3::new(3.0, 0.0, 0.0));
        assert!(leaf.model.parts[0].positions[1].abs_diff_eq(Vec3::X, 1e-6));
        assert_eq!(leaf.model.materials.len(), 1);
        assert_eq!(leaf.model.materials[0].name, "m2");
        assert_eq!(leaf.model.parts[0].material, 0);
        // The leaf is flat too (a triangle), but not larger than the rest.
        assert!(!leaf.huge_flat_plane);
        assert!(objects[1].huge_flat_plane);
        // Picked alone, the ground is still judged against the whole scene.
        let picked = node_objects(&model, &nodes, Some(&["Ground".to_owned()])).unwrap();
        assert_eq!(picked.len(), 1);
        assert!(picked[0].huge_flat_plane);
        let err = node_objects(&model, &nodes, Some(&["Tree".to_owned()])).unwrap_err();
        assert_eq!(
            err.to_string(),
            r#"no node named "Tree" (the nodes with meshes are "Leaf", "Ground")"#
        );
    }

    #[test]
    fn flatness_is_relative_to_the_middle_extent() {
        assert!(is_flat(Vec3::new(100.0, 0.5, 100.0)));
        assert!(is_flat(Vec3::new(100.0, 0.0, 3.0)));
        assert!(!is_flat(Vec3::new(100.0, 2.0, 100.0)));
        assert!(!is_flat(Vec3::new(100.0, 0.0, 0.0)));
    }
}

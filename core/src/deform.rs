//! The per-node transform hook (paper §3.1): every octree node is placed in the world
//! independently, at the moment the traversal computes its screen position. The octree itself is
//! never touched.
//!
//! [`RigidDeform`] is `world_from_object * object_from_voxel`. Skinning implements
//! [`NodeDeform`] with per-node linear-blend skinning and a stretch factor, and plugs into
//! [`crate::render::VoxelInstance`] in the same place.

use glam::{Affine3A, Mat3, Mat4, UVec3, Vec3};

use crate::svo::{NodeRef, Svo, Voxel};

/// What the hook is told about a node. The voxel attributes are fetched lazily (a rigid hook
/// never needs them; a skinning hook reads [`Voxel::skin`]).
#[derive(Clone, Copy)]
pub struct NodeInfo<'a> {
    /// The octree the node belongs to.
    pub svo: &'a Svo,
    /// The node: level, pool index, minimum corner in voxel coordinates.
    pub node: NodeRef,
}

impl NodeInfo<'_> {
    /// Edge length in voxels.
    #[inline]
    #[must_use]
    pub fn size_voxels(&self) -> u32 {
        self.svo.node_size(self.node.level)
    }

    /// Centre in voxel coordinates (voxel `c` spans `[c, c+1)`).
    #[inline]
    #[must_use]
    pub fn center_voxel(&self) -> Vec3 {
        self.node.origin.as_vec3() + Vec3::splat(0.5 * self.size_voxels() as f32)
    }

    /// The node's colour and octahedral normal (see [`Svo::node_color_and_normal`]).
    #[inline]
    #[must_use]
    pub fn color_and_normal(&self) -> ([u8; 4], u16) {
        self.svo.node_color_and_normal(&self.node)
    }

    /// The node's skin weights alone (one read of the skin pool; the default skin for an
    /// octree without skin), for deformers that need nothing else.
    #[inline]
    #[must_use]
    pub fn skin(&self) -> crate::svo::Skin4 {
        self.svo.node_skin(&self.node)
    }

    /// The node's attributes (a leaf's own or an internal node's LOD average, incl. skin).
    #[inline]
    #[must_use]
    pub fn voxel(&self) -> Voxel {
        self.svo.node_voxel(&self.node)
    }
}

/// Where a deformed node is drawn: a world-space parallelepiped (centre ± the three half-axes).
/// An axis-aligned world box has a diagonal `half_axes_world`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeformedNode {
    /// Centre in world space.
    pub center_world: Vec3,
    /// Columns: the box's three half-edge vectors in world space (already scaled by any
    /// stretch factor).
    pub half_axes_world: Mat3,
}

/// Places octree nodes in the world. Called once per visited node per frame, from many threads.
pub trait NodeDeform: Sync {
    /// World-space box of a node.
    fn deform(&self, node: &NodeInfo<'_>) -> DeformedNode;

    /// A node's normal (voxel space, unit) in world space (unit or zero).
    fn normal_to_world(&self, node: &NodeInfo<'_>, normal_voxel: Vec3) -> Vec3;

    /// A world box containing every *leaf* below the node as drawn, and the centre of every
    /// descendant, when [`Self::deform`]'s box does not (skinning: an internal node's splat
    /// does not contain its descendants once bones bend). It need not contain the node's own
    /// box: callers join the two (and the traversal adds the pixel-sized margin by which a
    /// descendant drawn at LOD may reach past it), so culling stays conservative; LOD and
    /// splatting use [`Self::deform`]. `None`: the node's own box bounds its subtree.
    fn subtree_bounds(&self, _node: &NodeInfo<'_>) -> Option<DeformedNode> {
        None
    }

    /// `Some(world_from_voxel)` when every node undergoes the same affine map. The traversal
    /// then folds it into the camera once per object instead of calling [`Self::deform`] per
    /// node; results are identical up to float rounding.
    fn uniform_affine(&self) -> Option<Affine3A> {
        None
    }
}

/// A rigid (affine) object transform: `world_from_object * object_from_voxel`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidDeform {
    /// `world_from_voxel`.
    pub world_from_voxel: Affine3A,
    normal_world_from_voxel: Mat3,
}

impl RigidDeform {
    /// From `world_from_voxel` (= `world_from_object * object_from_voxel`).
    #[must_use]
    pub fn new(world_from_voxel: Mat4) -> Self {
        let world_from_voxel = Affine3A::from_mat4(world_from_voxel);
        Self {
            world_from_voxel,
            normal_world_from_voxel: Mat3::from(world_from_voxel.matrix3).inverse().transpose(),
        }
    }
}

impl NodeDeform for RigidDeform {
    fn deform(&self, node: &NodeInfo<'_>) -> DeformedNode {
        let half = 0.5 * node.size_voxels() as f32;
        DeformedNode {
            center_world: self.world_from_voxel.transform_point3(node.center_voxel()),
            half_axes_world: Mat3::from(self.world_from_voxel.matrix3) * half,
        }
    }

    fn normal_to_world(&self, _node: &NodeInfo<'_>, normal_voxel: Vec3) -> Vec3 {
        (self.normal_world_from_voxel * normal_voxel).normalize_or_zero()
    }

    fn uniform_affine(&self) -> Option<Affine3A> {
        Some(self.world_from_voxel)
    }
}

/// Convenience for tests and callers with a node handle but no [`NodeInfo`].
#[must_use]
pub fn node_info(svo: &Svo, level: u8, index: u32, origin: UVec3) -> NodeInfo<'_> {
    NodeInfo {
        svo,
        node: NodeRef {
            level,
            index,
            origin,
        },
    }
}

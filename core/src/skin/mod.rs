//! Skeletons, poses, animation clips, linear-blend skinning, per-node skin weights and
//! stretch factors for animated sparse voxel octrees (ASVO, Bautembach 2011, §3, §3.3, §6,
//! §8.1.3).
//!
//! Everything here is plain functions over plain data so the renderers can call it per octree
//! node when they compute the node's screen position (paper §3.1): the octree is never touched.
//!
//! | module | what |
//! |---|---|
//! | [`skeleton`] | [`Skeleton`], [`Joint`], [`Transform`], [`Pose`], manual overrides, forward kinematics |
//! | [`clip`] | [`AnimationClip`] and its channels; STEP / LINEAR (slerp) / CUBICSPLINE sampling |
//! | [`ik`] | two-bone inverse kinematics (the posing aid for limbs) |
//! | [`keys`] | dope-sheet key edits: move, delete, copy / paste, interpolation, frame snapping |
//! | [`deform`] | [`SkinDeform`]: the renderers' per-node skinning hook, stretch boxes, culling bounds |
//! | [`lbs`] | linear-blend skinning of points and normals, weight repair |
//! | [`stretch`] | stretch-factor strategies (`Thesis`, `Corners`, `Adaptive`) |
//! | [`rig`] | [`Rig`]: a voxel model's skeleton, clips, playback, pose overrides, stretch settings |
//! | [`author`] | skeletons from joint positions and clips from Euler keys (`thicket rig` / `animate` formats) |
//! | [`mod@bind`] | automatic weights on the voxels: geodesic, envelope, rigid |
//! | [`paint`] | weight-paint dabs (add, subtract, smooth) |
//!
//! Elsewhere, because they build documents or read files (layers above the document, see
//! `docs/architecture.md`): reading skins and animations from glTF ([`crate::io::gltf_skinned`]),
//! skinned glTF → skinned voxel model ([`crate::io::skinned_voxels`]), baking the shown pose
//! into a rigid model ([`crate::scene::bake`]), and measuring holes and bloat against the
//! source mesh with its synthetic bending cylinder ([`crate::measure::skin`]).
//!
//! Spaces: a skinned mesh's vertices are in *bind-pose mesh space*; the skinning matrix of a
//! joint is `world_from_joint * joint_from_bind` (the inverse bind matrix), so a skinned
//! vertex lands in *skeleton world space* (the glTF scene's world space, including every
//! ancestor node above the joints). As in glTF, the transform of the node that carries the
//! skinned mesh is ignored. See `docs/skinning.md`.

pub mod author;
pub mod bind;
pub mod clip;
pub mod deform;
pub mod ik;
pub mod keys;
pub mod lbs;
pub mod paint;
pub mod rig;
pub mod skeleton;
pub mod stretch;

/// The per-node skin (four byte joints, unorm8 weights summing to 255) lives with the octree;
/// see [`Skin4`] for why there is only one representation.
pub use crate::svo::{MAX_SKIN_JOINTS, Skin4};
pub use author::{ClipSpec, JointSpec, KeySpec, SkeletonSpec};
pub use bind::{BindMethod, BindReport, bind};
pub use clip::{AnimationClip, Channel, Interpolation, Property, Wrap};
pub use deform::{SkinDeform, SkinTables};
pub use keys::{CopiedKey, KeyRef};
pub use lbs::{
    WeightRepair, repair_mesh_weights, repair_weights, skin_normal, skin_point, skin_points,
};
pub use rig::{Playback, Rig, StretchOverrides};
pub use skeleton::{Joint, JointMatrices, JointOverride, OverrideMode, Pose, Skeleton, Transform};
pub use stretch::{SplatBox, StretchSettings, StretchStrategy};

/// Why a skeleton, clip or skinned file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SkinError {
    /// The file could not be read.
    #[error("{path}: cannot read file: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The glTF parser or buffer loader rejected the file.
    #[error("{path}: not a valid glTF file: {source}")]
    Gltf {
        /// The file.
        path: String,
        /// The parser's error.
        source: gltf::Error,
    },
    /// The glTF file parsed but its content is inconsistent (bad accessor, missing data, …).
    #[error("{path}: {problem}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong and where (names the accessor, node or animation).
        problem: String,
    },
    /// The file has no skin to import.
    #[error("{path}: no skinned mesh (no node has both a mesh and a skin)")]
    NoSkin {
        /// The file.
        path: String,
    },
    /// A joint's parent index points past the joint list.
    #[error("joint {joint} ({name:?}) has parent {parent} but there are only {count} joints")]
    ParentOutOfRange {
        /// The joint's index.
        joint: usize,
        /// The joint's name.
        name: String,
        /// The bad parent index.
        parent: usize,
        /// Number of joints.
        count: usize,
    },
    /// The parent links form a cycle, so there is no root to start forward kinematics from.
    #[error("joint {joint} ({name:?}) is part of a parent cycle; a skeleton must be a forest")]
    Cycle {
        /// A joint on the cycle.
        joint: usize,
        /// Its name.
        name: String,
    },
    /// A joint's parent comes after it in the list (a skeleton from a file that was not built by
    /// [`Skeleton::new`], which sorts).
    #[error(
        "joint {joint} ({name:?}) comes before its parent {parent}; rebuild with Skeleton::new to sort"
    )]
    NotTopological {
        /// The joint's index.
        joint: usize,
        /// Its name.
        name: String,
        /// The parent's index.
        parent: usize,
    },
    /// A transform or matrix holds NaN or infinity.
    #[error("joint {joint} ({name:?}) has a non-finite {what}")]
    NonFiniteJoint {
        /// The joint's index.
        joint: usize,
        /// Its name.
        name: String,
        /// Which field (`rest translation`, `inverse bind matrix`, …).
        what: &'static str,
    },
    /// The bind-pose mesh could not be voxelized.
    #[error("voxelizing the bind-pose mesh: {source}")]
    Voxelize {
        /// The voxelizer's error.
        source: crate::voxelize::VoxelizeError,
    },
    /// A voxel model's rig (skeleton, clips, playback, overrides, settings) is inconsistent.
    #[error("skin: {problem}")]
    Rig {
        /// What is wrong and where.
        problem: String,
    },
    /// The user cancelled a long operation (binding).
    #[error("cancelled")]
    Cancelled,
    /// A clip's channel is malformed.
    #[error("clip {clip:?}, channel {channel}: {problem}")]
    BadChannel {
        /// The clip's name.
        clip: String,
        /// The channel's index.
        channel: usize,
        /// What is wrong.
        problem: String,
    },
}

#[cfg(test)]
mod bind_tests;
#[cfg(test)]
pub(crate) mod deform_tests;
#[cfg(test)]
mod tests;

//! Thicket's core: the document and every algorithm, with no GPU or UI dependency.
//!
//! | module | owns |
//! |---|---|
//! | [`svo`] | the sparse voxel octree |
//! | [`mesh`] | triangle meshes shared by importers, voxelizer, skinning and renderers |
//! | [`voxelize`] | triangle meshes → SVO |
//! | [`sculpt`] | brushes as octree edits with undo deltas |
//! | [`skin`] | skeletons, poses, clips, per-node skinning, stretch factors |
//! | [`enhance`] | voxel detail enhancement |
//! | [`krs`] | kernel-reflection sequences |
//! | [`render`] | CPU reference renderers |
//! | [`scene`] | the document |
//! | [`io`] | project files, glTF, OBJ, .vox, PNG |
//! | [`measure`] | image error metrics and quality sweeps |

// Habits made checks (clippy runs with -D warnings): every public item documented, and no
// unwrap/expect outside tests (bad input is an error, never a panic).
#![warn(missing_docs)]
#![cfg_attr(not(test), warn(clippy::unwrap_used, clippy::expect_used))]

pub mod budget;
pub mod enhance;
pub mod io;
pub mod krs;
pub mod measure;
pub mod mesh;
pub mod render;
pub mod scene;
pub mod sculpt;
pub mod skin;
pub mod svo;
pub mod voxelize;

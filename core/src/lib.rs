//! Thicket's core: the document and every algorithm, with no GPU or UI dependency.
//!
//! Modules from the lowest layer up: a module uses only modules above it in this table, never
//! one on its own line or below (`docs/architecture.md`; `tests/layers.rs` checks it).
//!
//! | layer | module | owns |
//! |---|---|---|
//! | 0 | [`mesh`], [`krs`], [`budget`] | triangle meshes; kernel-reflection sequences; memory budgets |
//! | 1 | [`svo`] | the sparse voxel octree |
//! | 2 | [`deform`], [`voxelize`], [`enhance`] | the per-node transform hook; meshes → SVO; voxel detail enhancement |
//! | 3 | [`skin`] | skeletons, poses, clips, rigs, per-node skinning, stretch factors |
//! | 4 | [`quality`] | the renderers' quality knobs and presets |
//! | 5 | [`scene`] | the document |
//! | 6 | [`render`] | CPU reference renderers (documents → images) |
//! | 7 | [`io`] | project files, glTF (static and skinned), OBJ, .vox, PNG |
//! | 8 | [`measure`], [`sculpt`] | image metrics, sweeps, skinning metrics; brushes and voxel tools |

// Habits made checks (clippy runs with -D warnings): every public item documented, and no
// unwrap/expect outside tests (bad input is an error, never a panic).
#![warn(missing_docs)]
#![cfg_attr(not(test), warn(clippy::unwrap_used, clippy::expect_used))]

pub mod budget;
pub mod deform;
pub mod enhance;
pub mod io;
pub mod krs;
pub mod measure;
pub mod mesh;
pub mod quality;
pub mod render;
pub mod scene;
pub mod sculpt;
pub mod skin;
pub mod svo;
pub mod voxelize;

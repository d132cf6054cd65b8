//! File formats: project files, glTF, OBJ, MagicaVoxel .vox, PNG.
//!
//! Every loader returns an error naming the file and what is wrong and where, checks declared
//! sizes before allocating, and never panics on bad input.

pub mod project;

pub mod confine;

// Mesh importers and the shared error type (glTF, OBJ).
pub mod error;
#[cfg(test)]
pub(crate) mod fuzz;
pub mod gltf_export;
mod gltf_instancing;
pub mod gltf_mesh;
pub mod gltf_nodes;
pub(crate) mod gltf_report;
pub mod gltf_skinned;
pub mod gltf_view;
pub mod obj;
#[cfg(test)]
mod round_trip_tests;
pub mod skinned_voxels;

pub use error::{ImportLimits, IoError};
pub use gltf_mesh::{
    CountedMesh, GltfCount, GltfImport, GltfNode, InstanceCounts, count_gltf, import_gltf,
    import_gltf_imported, import_gltf_reported, import_gltf_slice,
};
pub use gltf_skinned::{SkinnedImport, import_skinned, import_skinned_slice, import_skinned_with};
pub use gltf_view::{GltfCamera, GltfView};
pub use obj::{ObjOptions, import_obj};
pub use skinned_voxels::{SkinnedVoxels, voxelize_skinned};

pub mod vox;

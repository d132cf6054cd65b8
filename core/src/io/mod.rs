//! `io` (work in progress).

// Mesh importers and the shared error type (glTF, OBJ).
pub mod error;
#[cfg(test)]
pub(crate) mod fuzz;
pub mod gltf_mesh;
pub mod obj;

pub use error::{ImportLimits, IoError};
pub use gltf_mesh::{import_gltf, import_gltf_slice};
pub use obj::{ObjOptions, import_obj};

//! MagicaVoxel `.vox` import and export.
//!
//! # Import
//! [`import_vox`] reads every model of a file (versions 150 and 200, and legacy files without a
//! scene graph) with the `dot_vox` crate, applies the scene graph (`nTRN` translation and
//! rotation, `nGRP`, `nSHP`) and returns one [`Object`] per shape instance; an animation
//! (several models without a scene graph, or `_f` keyframes) is one object with a
//! [`FrameSequence`](crate::scene::FrameSequence). Before `dot_vox` sees
//! the bytes, `chunks::validate` walks the RIFF-like chunk structure itself: `dot_vox` answers
//! a malformed file with a vague string (or, for a bad rotation byte, a panic), and silently
//! drops chunks it cannot parse, which would shift model and node indices. After validation
//! every declared size is known to lie inside the file, so nothing is allocated from an
//! unchecked count.
//!
//! # Axes
//! MagicaVoxel is Z-up, right-handed; Thicket is Y-up, right-handed. A MagicaVoxel point
//! `(x, y, z)` becomes `(x, z, -y)` (a −90° turn about +X, no mirror). A voxel cell `[m, m+1)`
//! therefore becomes the cell whose minimum corner is `(m.x, m.z, -m.y - 1)`; export applies the
//! exact inverse, so positions round-trip bit for bit.
//!
//! # Placement
//! A shape's voxel `v` (model of size `s`, pivot `p = floor(s / 2)`) has its centre at
//! `R · (v + ½ − p) + T` where `R`, `T` are the accumulated `nTRN` rotation (a signed
//! permutation) and translation from the root. Rotations are baked into the voxel coordinates
//! (they map the grid onto itself exactly, and mirrored rotations need no negative scale), so
//! each object's [`Transform`](crate::scene::Transform) is a pure translation: the instance's
//! pivot `T` in Y-up world units, with the voxels offset by [`VoxelModel::origin`].
//!
//! # Export
//! [`export_vox`] writes the visible voxel objects; see `docs/vox.md`.

mod chunks;
mod export;
#[cfg(test)]
mod frame_tests;
mod import;
#[cfg(test)]
mod instance_tests;
#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

pub use export::{
    VOX_EXPORT_BYTES_PER_CELL, VoxExportEstimate, VoxExportOptions, VoxExportReport,
    estimate_vox_export, export_vox, export_vox_bytes, export_vox_with,
};
pub use import::{
    VOX_IMPORT_BYTES_PER_VOXEL, VoxImportOptions, VoxScene, estimate_vox_import, import_vox,
    import_vox_bytes, import_vox_with,
};

#[allow(unused_imports, reason = "named in the module docs")]
use crate::scene::{Object, VoxelModel};

/// Largest model edge MagicaVoxel accepts, in voxels.
pub const MAX_MODEL_EDGE: u32 = 256;

/// Largest `.vox` file read, in bytes (a full 256³ model is 64 MiB; this leaves room for many).
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// Default cap on the voxels an import creates, after instancing (each instance owns its
/// voxels). A file whose scene graph would create more is refused before anything is built.
pub const DEFAULT_MAX_VOXELS: u64 = 1 << 25;

/// Most shape instances one import creates.
pub const MAX_INSTANCES: usize = 1 << 16;

/// Most frames one animated shape may have (a frame index `_f` is below it).
pub const MAX_FRAMES: u32 = 4096;

/// Largest voxel coordinate magnitude a `.vox` scene may place: world positions stay exact in
/// `f32` up to 2^24. The importer refuses voxels beyond it and the exporter refuses to write
/// them, so every file Thicket writes, Thicket reads.
pub const MAX_COORD: i64 = 1 << 24;

/// Deepest scene graph followed (MagicaVoxel nests a few levels; cycles hit this limit).
pub const MAX_SCENE_DEPTH: usize = 64;

/// Why a `.vox` file could not be read or written. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum VoxError {
    /// The operating system refused a read or write.
    #[error("{}: {action} failed: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("reading", "writing the temporary file", ...).
        action: &'static str,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The file does not start with the `VOX ` magic.
    #[error(
        "{}: not a MagicaVoxel file: it starts with {found}, a .vox file starts with \"VOX \"",
        path.display()
    )]
    NotVox {
        /// The file.
        path: PathBuf,
        /// The first bytes, escaped.
        found: String,
    },
    /// The chunk structure or a chunk's content is wrong.
    #[error("{}: {at}: {detail}", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// Where ("chunk XYZI of model 3 at byte 1204").
        at: String,
        /// What is wrong.
        detail: String,
    },
    /// The scene graph references something missing, loops, or places voxels out of range.
    #[error("{}: scene graph node {node}: {detail}", path.display())]
    Scene {
        /// The file.
        path: PathBuf,
        /// The node id.
        node: u32,
        /// What is wrong.
        detail: String,
    },
    /// The file would create more than a budget allows.
    #[error("{}: too large: {detail}", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Which budget and by how much.
        detail: String,
    },
    /// `dot_vox` rejected or panicked on input this module had validated (a bug here or there).
    #[error("{}: the .vox parser failed on a file that passed validation: {detail}", path.display())]
    Parser {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        detail: String,
    },
    /// An object could not be exported.
    #[error("{}: object {object:?}: {detail}", path.display())]
    Object {
        /// The file being written.
        path: PathBuf,
        /// The object's name.
        object: String,
        /// What is wrong.
        detail: String,
    },
    /// Export was given no visible, non-empty voxel object.
    #[error(
        "{}: nothing to export: no visible voxel object has voxels (nothing was written)",
        path.display()
    )]
    NothingToExport {
        /// The file that was not written.
        path: PathBuf,
    },
}

fn malformed(path: &Path, at: impl Into<String>, detail: impl Into<String>) -> VoxError {
    VoxError::Malformed {
        path: path.to_owned(),
        at: at.into(),
        detail: detail.into(),
    }
}

fn scene_error(path: &Path, node: u32, detail: impl Into<String>) -> VoxError {
    VoxError::Scene {
        path: path.to_owned(),
        node,
        detail: detail.into(),
    }
}

/// A signed permutation matrix as integer rows: `out[r] = sum_c m[r][c] * in[c]`.
pub(crate) type IMat3 = [[i64; 3]; 3];

pub(crate) const IDENTITY: IMat3 = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

pub(crate) fn imat_mul(a: &IMat3, b: &IMat3) -> IMat3 {
    let mut out = [[0; 3]; 3];
    for (r, row) in out.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[r][k] * b[k][c]).sum();
        }
    }
    out
}

pub(crate) fn imat_apply(m: &IMat3, v: [i64; 3]) -> [i64; 3] {
    [0, 1, 2].map(|r| m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2])
}

/// Decodes MagicaVoxel's packed rotation byte (`_r`): bits 0–1 and 2–3 give the column of the
/// non-zero entry in rows 0 and 1 (row 2 takes the remaining column), bits 4–6 the signs of
/// rows 0–2. `None` when the two columns coincide or one is 3 (`dot_vox` would panic on these).
#[must_use]
pub(crate) fn decode_rotation(byte: u8) -> Option<IMat3> {
    let c0 = usize::from(byte & 3);
    let c1 = usize::from((byte >> 2) & 3);
    if c0 == 3 || c1 == 3 || c0 == c1 {
        return None;
    }
    let c2 = 3 - c0 - c1;
    let sign = |bit: u8| if byte & (1 << bit) == 0 { 1 } else { -1 };
    let mut m = [[0; 3]; 3];
    m[0][c0] = sign(4);
    m[1][c1] = sign(5);
    m[2][c2] = sign(6);
    Some(m)
}

/// MagicaVoxel (Z-up) cell → Thicket (Y-up) cell: the cell `[m, m+1)` maps to `[y, y+1)` with
/// `y = (m.x, m.z, -m.y - 1)`.
#[must_use]
pub(crate) fn yup_cell_from_mv(m: [i64; 3]) -> [i64; 3] {
    [m[0], m[2], -m[1] - 1]
}

/// Inverse of [`yup_cell_from_mv`].
#[must_use]
pub(crate) fn mv_cell_from_yup(y: [i64; 3]) -> [i64; 3] {
    [y[0], -y[2] - 1, y[1]]
}

/// MagicaVoxel (Z-up) point or direction → Thicket (Y-up).
#[must_use]
pub(crate) fn yup_from_mv(v: [i64; 3]) -> [i64; 3] {
    [v[0], v[2], -v[1]]
}

//! `io` (work in progress).
/// MagicaVoxel `.vox` import (models, scene graph, palette, materials) and export.
pub mod vox;

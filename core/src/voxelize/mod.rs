//! `voxelize` (work in progress).

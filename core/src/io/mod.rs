//! File formats: project files, glTF, OBJ, MagicaVoxel .vox, PNG.
//!
//! Every loader returns an error naming the file and what is wrong and where, checks declared
//! sizes before allocating, and never panics on bad input.

pub mod project;

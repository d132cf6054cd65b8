//! CPU reference renderers.

pub mod quality;

pub use quality::{Quality, QualityError, QualityPreset};

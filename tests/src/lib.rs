//! Shared helpers for Thicket's cross-crate tests, and the sample-project builder.

pub mod samples;

use std::path::PathBuf;

/// The repository root.
#[must_use]
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `../shared/assets` beside the repository (CI has it there too).
#[must_use]
pub fn shared_assets() -> PathBuf {
    repo_root().join("../shared/assets")
}

/// A file under `../shared/assets`.
#[must_use]
pub fn asset(relative: &str) -> PathBuf {
    shared_assets().join(relative)
}

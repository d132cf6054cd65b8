//! The error type shared by every loader in [`crate::io`], and the size limits loaders enforce
//! before they allocate.
//!
//! Every variant carries the path of the file (or a stand-in such as `<memory>` for byte slices)
//! and a `detail` that says what is wrong and where, so a message can be shown to the user as it
//! is: `Box.glb: invalid: accessor 3 (POSITION of mesh 'Body' primitive 0): …`.

use std::path::{Path, PathBuf};

use crate::budget::MemoryBudget;

/// Why a file could not be loaded (or saved).
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The operating system refused a read or write.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The file is empty or ends before the data it declares.
    #[error("{}: truncated: {detail}", path.display())]
    Truncated {
        /// The file.
        path: PathBuf,
        /// What was expected and what was found.
        detail: String,
    },
    /// The file's syntax cannot be read (bad JSON, bad text, wrong magic number).
    #[error("{}: cannot parse: {detail}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong and where (line, byte offset, field).
        detail: String,
    },
    /// The file parses but its content is inconsistent (an index past its array, a count
    /// larger than its buffer, a non-finite number).
    #[error("{}: invalid: {detail}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong and where.
        detail: String,
    },
    /// The file declares more data than the loader's [`ImportLimits`] allow; refused before
    /// allocating.
    #[error("{}: too large: {detail}", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// The declared size and the limit.
        detail: String,
    },
    /// The file uses a feature Thicket does not implement (a required extension, a
    /// compression scheme, an encoding).
    #[error("{}: unsupported: {detail}", path.display())]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// The feature.
        detail: String,
    },
}

impl IoError {
    /// An operating-system error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }

    /// [`IoError::Truncated`] on `path`.
    pub fn truncated(path: impl Into<PathBuf>, detail: impl Into<String>) -> Self {
        Self::Truncated {
            path: path.into(),
            detail: detail.into(),
        }
    }

    /// [`IoError::Parse`] on `path`.
    pub fn parse(path: impl Into<PathBuf>, detail: impl Into<String>) -> Self {
        Self::Parse {
            path: path.into(),
            detail: detail.into(),
        }
    }

    /// [`IoError::Invalid`] on `path`.
    pub fn invalid(path: impl Into<PathBuf>, detail: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.into(),
            detail: detail.into(),
        }
    }

    /// [`IoError::TooLarge`] on `path`.
    pub fn too_large(path: impl Into<PathBuf>, detail: impl Into<String>) -> Self {
        Self::TooLarge {
            path: path.into(),
            detail: detail.into(),
        }
    }

    /// [`IoError::Unsupported`] on `path`.
    pub fn unsupported(path: impl Into<PathBuf>, detail: impl Into<String>) -> Self {
        Self::Unsupported {
            path: path.into(),
            detail: detail.into(),
        }
    }

    /// The file the error is about.
    #[must_use]
    pub fn path(&self) -> &Path {
        match self {
            Self::Io { path, .. }
            | Self::Truncated { path, .. }
            | Self::Parse { path, .. }
            | Self::Invalid { path, .. }
            | Self::TooLarge { path, .. }
            | Self::Unsupported { path, .. } => path,
        }
    }
}

/// Upper bounds a loader checks declared sizes against before allocating, so a file that
/// claims billions of elements is refused with [`IoError::TooLarge`] instead of exhausting
/// memory. The defaults admit any model an editor can reasonably hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImportLimits {
    /// Largest file (and external buffer or image file) read, in bytes.
    pub max_file_bytes: u64,
    /// Most vertices over all parts of one import (instanced meshes count once per instance).
    pub max_vertices: u64,
    /// Most triangle-list indices over all parts of one import.
    pub max_indices: u64,
    /// Most bytes of decoded RGBA8 texture for one image.
    pub max_texture_bytes: u64,
    /// The memory the meshes of one import may fill (vertex attributes and indices, every
    /// instance of an instanced mesh counted), estimated from the declared counts before any
    /// mesh is built: a small file that places a mesh a million times is refused, not
    /// expanded. By default half of this machine's physical memory (`--memory-limit` sets it).
    pub memory: MemoryBudget,
}

impl Default for ImportLimits {
    fn default() -> Self {
        Self {
            max_file_bytes: 4 << 30,
            max_vertices: 1 << 28,
            max_indices: 3 << 28,
            // 8192 × 8192 RGBA8.
            max_texture_bytes: 256 << 20,
            memory: MemoryBudget::for_this_machine(),
        }
    }
}

/// Reads a whole file, at most `limits.max_file_bytes` of it (decided by reading, not by the
/// size the file reports, so a device or a growing file cannot exhaust memory); only regular
/// files are read.
///
/// # Errors
/// [`IoError::Io`] when the file cannot be opened or read, [`IoError::TooLarge`] when it is
/// larger than `limits.max_file_bytes`, [`IoError::Invalid`] for a device, pipe or folder.
pub fn read_file_limited(path: &Path, limits: &ImportLimits) -> Result<Vec<u8>, IoError> {
    super::confine::read_capped(path, limits.max_file_bytes)
        .map_err(|e| e.into_io_error(path, "file"))
}

impl super::confine::RefError {
    /// The error to report for a reference `what` (e.g. "buffer 0") made by the file
    /// `referrer`: a refusal is [`IoError::Invalid`] on the referrer, a missing file
    /// [`IoError::Io`] on that file.
    #[must_use]
    pub fn into_io_error(self, referrer: &Path, what: &str) -> IoError {
        use super::confine::RefError;
        match self {
            RefError::Refused(why) => IoError::invalid(referrer, format!("{what}: {why}")),
            RefError::Io(path, e) => IoError::io(path, e),
            RefError::TooLarge(path, limit) => IoError::too_large(
                path,
                format!("more than {limit} bytes; the limit is {limit} bytes"),
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_file_and_the_problem() {
        let e = IoError::invalid(
            "dir/model.gltf",
            "accessor 3 (POSITION of mesh 'Body' primitive 0): count too big",
        );
        assert_eq!(
            e.to_string(),
            "dir/model.gltf: invalid: accessor 3 (POSITION of mesh 'Body' primitive 0): count too big"
        );
        assert_eq!(e.path(), Path::new("dir/model.gltf"));
        let missing = read_file_limited(
            Path::new("/nonexistent/thicket/x.glb"),
            &ImportLimits::default(),
        );
        let err = missing.expect_err("a missing file must be an error");
        assert!(matches!(err, IoError::Io { .. }));
        assert!(
            err.to_string().starts_with("/nonexistent/thicket/x.glb: "),
            "{err}"
        );
    }

    #[test]
    fn oversized_files_are_refused_before_reading() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("big.bin");
        std::fs::write(&path, vec![0u8; 100]).expect("write");
        let limits = ImportLimits {
            max_file_bytes: 99,
            ..ImportLimits::default()
        };
        let err = read_file_limited(&path, &limits).expect_err("over the limit");
        assert!(matches!(err, IoError::TooLarge { .. }), "{err}");
        assert!(err.to_string().contains("99 bytes"), "{err}");
        let ok = read_file_limited(
            &path,
            &ImportLimits {
                max_file_bytes: 100,
                ..limits
            },
        )
        .expect("at the limit");
        assert_eq!(ok.len(), 100);
    }
}

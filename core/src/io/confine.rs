//! Confined file references: the files a file names (glTF buffer and image URIs, OBJ `mtllib`
//! and `map_Kd`, a project's `.bin`) are read only from inside the referencing file's folder.
//!
//! A reference must be a relative path (no root, no drive), must not climb out of the folder
//! with `..`, must not leave it through a symbolic link, and must name a regular file (not a
//! device, pipe or folder). It is then read through [`read_capped`], which stops at the limit
//! whatever size the file reports, so `/dev/zero` or a growing file cannot exhaust memory.

use std::fs::{self, File};
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// Why a reference was not followed.
#[derive(Debug)]
pub enum RefError {
    /// The reference breaks a confinement rule (the text says which).
    Refused(String),
    /// The file does not exist or cannot be opened.
    Io(PathBuf, std::io::Error),
    /// The file holds more than the limit.
    TooLarge(PathBuf, u64),
}

/// Resolves `reference`, written in a file in `base_dir`, to the real path of a regular file
/// inside `base_dir`.
///
/// # Errors
/// [`RefError::Refused`] naming the rule broken, [`RefError::Io`] when the file is missing.
pub fn resolve(base_dir: &Path, reference: &str) -> Result<PathBuf, RefError> {
    let refused = |why: &str| Err(RefError::Refused(format!("'{reference}' {why}")));
    if reference.is_empty() {
        return Err(RefError::Refused("the file reference is empty".into()));
    }
    if reference.contains('\0') {
        return refused("contains a NUL character");
    }
    let rel = Path::new(reference);
    // A leading `\` or a drive letter is absolute on Windows, where a file may have come from.
    let windows_absolute =
        reference.starts_with('\\') || (reference.len() >= 2 && reference.as_bytes()[1] == b':');
    if rel.has_root() || rel.is_absolute() || windows_absolute {
        return refused(
            "is an absolute path; only paths relative to the file's folder are followed",
        );
    }
    let mut depth = 0usize;
    for c in rel.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir if depth > 0 => depth -= 1,
            Component::ParentDir => {
                return refused("climbs out of the file's folder with '..'");
            }
            Component::RootDir | Component::Prefix(_) => {
                return refused("is an absolute path");
            }
        }
    }
    let joined = base_dir.join(rel);
    let base = fs::canonicalize(if base_dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        base_dir
    })
    .map_err(|e| RefError::Io(base_dir.to_owned(), e))?;
    let real = fs::canonicalize(&joined).map_err(|e| RefError::Io(joined.clone(), e))?;
    if !real.starts_with(&base) {
        return refused("leads out of the file's folder through a symbolic link");
    }
    let meta = fs::metadata(&real).map_err(|e| RefError::Io(joined.clone(), e))?;
    if !meta.is_file() {
        return refused("is not a regular file (a device, pipe or folder)");
    }
    Ok(real)
}

/// Reads at most `limit` bytes of `path`: more than that is [`RefError::TooLarge`], decided by
/// reading (at most `limit + 1` bytes), not by the size the file reports. Refuses anything but
/// a regular file before opening it, so a pipe cannot block the read.
///
/// # Errors
/// [`RefError::Io`], [`RefError::TooLarge`], or [`RefError::Refused`] for a non-regular file.
pub fn read_capped(path: &Path, limit: u64) -> Result<Vec<u8>, RefError> {
    let meta = fs::metadata(path).map_err(|e| RefError::Io(path.to_owned(), e))?;
    if !meta.is_file() {
        return Err(RefError::Refused(format!(
            "'{}' is not a regular file (a device, pipe or folder)",
            path.display()
        )));
    }
    if meta.len() > limit {
        return Err(RefError::TooLarge(path.to_owned(), limit));
    }
    let file = File::open(path).map_err(|e| RefError::Io(path.to_owned(), e))?;
    // The reported length only sizes the buffer; the read itself is what is bounded.
    let mut out = Vec::with_capacity(usize::try_from(meta.len()).unwrap_or(0));
    file.take(limit.saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|e| RefError::Io(path.to_owned(), e))?;
    if out.len() as u64 > limit {
        return Err(RefError::TooLarge(path.to_owned(), limit));
    }
    Ok(out)
}

/// [`resolve`] then [`read_capped`].
///
/// # Errors
/// As [`resolve`] and [`read_capped`].
pub fn read_reference(base_dir: &Path, reference: &str, limit: u64) -> Result<Vec<u8>, RefError> {
    read_capped(&resolve(base_dir, reference)?, limit)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder() -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let inner = dir.path().join("models");
        fs::create_dir(&inner).unwrap();
        fs::write(inner.join("ok.bin"), b"inside").unwrap();
        fs::write(dir.path().join("secret.txt"), b"outside").unwrap();
        (dir, inner)
    }

    fn refused(r: Result<Vec<u8>, RefError>) -> String {
        match r {
            Err(RefError::Refused(why)) => why,
            other => panic!("expected a refusal, got {other:?}"),
        }
    }

    #[test]
    fn relative_references_inside_the_folder_are_read() {
        let (_d, inner) = folder();
        fs::create_dir(inner.join("x")).unwrap();
        assert_eq!(read_reference(&inner, "ok.bin", 100).unwrap(), b"inside");
        assert_eq!(
            read_reference(&inner, "./x/../ok.bin", 100).unwrap(),
            b"inside"
        );
        assert!(matches!(
            read_reference(&inner, "missing.bin", 100),
            Err(RefError::Io(_, e)) if e.kind() == std::io::ErrorKind::NotFound
        ));
    }

    #[test]
    fn absolute_references_are_refused() {
        let (d, inner) = folder();
        let abs = d.path().join("secret.txt");
        let why = refused(read_reference(&inner, abs.to_str().unwrap(), 100));
        assert!(why.contains("absolute"), "{why}");
        assert!(refused(read_reference(&inner, "C:\\Windows\\win.ini", 100)).contains("absolute"));
        assert!(refused(read_reference(&inner, "", 100)).contains("empty"));
    }

    #[test]
    fn dot_dot_escapes_are_refused() {
        let (_d, inner) = folder();
        let why = refused(read_reference(&inner, "../secret.txt", 100));
        assert!(why.contains("'..'"), "{why}");
        assert!(refused(read_reference(&inner, "a/../../secret.txt", 100)).contains("'..'"));
    }

    #[cfg(unix)]
    #[test]
    fn device_files_are_refused_and_never_read_past_the_limit() {
        let (_d, inner) = folder();
        // The file: `/dev/zero` reports length 0 and never ends.
        let why = refused(read_reference(&inner, "/dev/zero", 1 << 20));
        assert!(why.contains("absolute"), "{why}");
        // Read directly, it is refused as a device before any byte is read.
        let why = refused(read_capped(Path::new("/dev/zero"), 1 << 20));
        assert!(why.contains("not a regular file"), "{why}");
        // A device reached through a link inside the folder is refused too.
        std::os::unix::fs::symlink("/dev/zero", inner.join("zero.bin")).unwrap();
        assert!(matches!(
            read_reference(&inner, "zero.bin", 1 << 20),
            Err(RefError::Refused(_))
        ));
        // A pipe in the folder would block a plain read; it is refused without opening it.
        let made = std::process::Command::new("mkfifo")
            .arg(inner.join("pipe.bin"))
            .status()
            .is_ok_and(|s| s.success());
        if made {
            let why = refused(read_reference(&inner, "pipe.bin", 100));
            assert!(why.contains("not a regular file"), "{why}");
        }
        // A regular file over the limit is refused by what is read.
        fs::write(inner.join("big.bin"), vec![7u8; 101]).unwrap();
        assert!(matches!(
            read_reference(&inner, "big.bin", 100),
            Err(RefError::TooLarge(_, 100))
        ));
        assert_eq!(read_reference(&inner, "big.bin", 101).unwrap().len(), 101);
    }

    #[cfg(unix)]
    #[test]
    fn symlinks_out_of_the_folder_are_refused() {
        let (d, inner) = folder();
        std::os::unix::fs::symlink(d.path().join("secret.txt"), inner.join("link.bin")).unwrap();
        let why = refused(read_reference(&inner, "link.bin", 100));
        assert!(why.contains("symbolic link"), "{why}");
        std::os::unix::fs::symlink(d.path(), inner.join("up")).unwrap();
        assert!(refused(read_reference(&inner, "up/secret.txt", 100)).contains("symbolic link"));
        // A link that stays inside is fine.
        std::os::unix::fs::symlink(inner.join("ok.bin"), inner.join("alias.bin")).unwrap();
        assert_eq!(read_reference(&inner, "alias.bin", 100).unwrap(), b"inside");
    }
}

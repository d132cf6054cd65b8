//! The crash-safe save: payloads go to a new, never-before-used `.bin` name, the JSON is
//! renamed over the old one, and only then are files the old JSON needed removed. No step ever
//! renames over, truncates or removes a file the JSON on disk refers to, so any sequence of
//! crashes (or failed writes) leaves the previous or the new save loadable.
//!
//! Every file-system mutation goes through [`SaveFs`], so the crash test can stop a save at
//! each write, sync and rename in turn.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

use super::{ProjectError, with_suffix};

/// The file-system operations a save performs, each a point where the process may die.
pub(crate) trait SaveFs {
    /// Creates (or truncates) `path` and writes `bytes` into it, unsynced.
    fn write(&mut self, path: &Path, bytes: &[u8]) -> io::Result<()>;
    /// Makes `path`'s content durable.
    fn sync_file(&mut self, path: &Path) -> io::Result<()>;
    /// Atomically renames `from` to `to`, replacing `to`.
    fn rename(&mut self, from: &Path, to: &Path) -> io::Result<()>;
    /// Makes the renames and creations in `dir` durable.
    fn sync_dir(&mut self, dir: &Path) -> io::Result<()>;
    /// Removes `path`.
    fn remove(&mut self, path: &Path) -> io::Result<()>;
}

/// The real file system.
pub(crate) struct RealFs;

impl SaveFs for RealFs {
    fn write(&mut self, path: &Path, bytes: &[u8]) -> io::Result<()> {
        File::create(path)?.write_all(bytes)
    }
    fn sync_file(&mut self, path: &Path) -> io::Result<()> {
        OpenOptions::new().write(true).open(path)?.sync_all()
    }
    fn rename(&mut self, from: &Path, to: &Path) -> io::Result<()> {
        fs::rename(from, to)
    }
    fn sync_dir(&mut self, dir: &Path) -> io::Result<()> {
        // Some platforms cannot open a directory (Windows) or refuse to sync one; there the
        // rename's own ordering is all we get, and refusing to save would help nobody.
        match File::open(dir).and_then(|d| d.sync_all()) {
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::PermissionDenied
                        | io::ErrorKind::Unsupported
                        | io::ErrorKind::InvalidInput
                ) =>
            {
                Ok(())
            }
            other => other,
        }
    }
    fn remove(&mut self, path: &Path) -> io::Result<()> {
        fs::remove_file(path)
    }
}

/// `NAME.thicket` for `NAME.thicket.json`: the prefix of every file the project owns.
pub(super) fn stem_of(json_path: &Path) -> String {
    let name = json_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    name.strip_suffix(".json").unwrap_or(&name).to_owned()
}

/// Whether `name` is a payload file (or a temporary of one) that a save of the project with
/// this `stem` writes: `STEM.bin`, `STEM.bin.prev`, `STEM.bin.tmp` (older saves) and
/// `STEM.<8 hex>[-N].bin[.tmp]` (content-named saves).
fn is_payload_file(stem: &str, name: &str) -> bool {
    let Some(rest) = name.strip_prefix(stem).and_then(|r| r.strip_prefix('.')) else {
        return false;
    };
    if matches!(rest, "bin" | "bin.prev" | "bin.tmp") {
        return true;
    }
    let rest = rest.strip_suffix(".tmp").unwrap_or(rest);
    let Some(tag) = rest.strip_suffix(".bin") else {
        return false;
    };
    let (hex, n) = tag.split_once('-').unwrap_or((tag, "0"));
    hex.len() == 8
        && hex.bytes().all(|b| b.is_ascii_hexdigit())
        && !n.is_empty()
        && n.bytes().all(|b| b.is_ascii_digit())
}

/// Whether the file at `path` holds exactly `bytes` (read with a cap, so a stray huge file
/// costs nothing).
fn holds_exactly(path: &Path, bytes: &[u8]) -> bool {
    let Ok(meta) = fs::symlink_metadata(path) else {
        return false;
    };
    if !meta.is_file() || meta.len() != bytes.len() as u64 {
        return false;
    }
    let mut found = Vec::with_capacity(bytes.len());
    File::open(path)
        .and_then(|f| f.take(bytes.len() as u64 + 1).read_to_end(&mut found))
        .is_ok()
        && found == bytes
}

/// The `.bin` name for these payload bytes: `STEM.<crc32>.bin`, or `STEM.<crc32>-N.bin` when
/// that name is taken by other bytes. Returns the name and whether a file of that name
/// already holds exactly these bytes (an unchanged re-save, or the retry of a save that died
/// before its JSON rename). A name that exists with other content is never reused, so the
/// save cannot touch a payload the JSON on disk refers to.
fn pick_bin_name(dir: &Path, stem: &str, bin: &[u8]) -> Option<(String, bool)> {
    let crc = crc32fast::hash(bin);
    for n in 0..=u32::MAX {
        let name = if n == 0 {
            format!("{stem}.{crc:08x}.bin")
        } else {
            format!("{stem}.{crc:08x}-{n}.bin")
        };
        let path = dir.join(&name);
        if holds_exactly(&path, bin) {
            return Some((name, true));
        }
        if fs::symlink_metadata(&path).is_err() {
            return Some((name, false));
        }
    }
    None
}

/// The payload name a save of `bin` into `json_path`'s directory will use.
///
/// # Errors
/// [`ProjectError::Payload`] when every candidate name is taken (four billion files).
pub(super) fn bin_name_for(json_path: &Path, bin: &[u8]) -> Result<(String, bool), ProjectError> {
    pick_bin_name(dir_of(json_path), &stem_of(json_path), bin).ok_or_else(|| {
        ProjectError::Payload {
            path: json_path.to_owned(),
            detail: "no free payload file name beside the project".into(),
        }
    })
}

/// `json_path`'s directory (`.` for a bare file name).
pub(super) fn dir_of(json_path: &Path) -> &Path {
    json_path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Writes an encoded project (see the module docs). `bin` is `None` for a project without
/// payloads; `bin_name` is from [`bin_name_for`].
pub(crate) fn write_project(
    fs_ops: &mut dyn SaveFs,
    json_path: &Path,
    json: &[u8],
    bin: Option<(&[u8], &str, bool)>,
) -> Result<(), ProjectError> {
    let dir = dir_of(json_path);
    let stem = stem_of(json_path);
    let json_tmp = with_suffix(json_path, ".tmp");
    // Errors name the project the caller named, with the step: a temporary's name means
    // nothing to the user, and nothing of it is left.
    let failed = |step: &'static str| {
        move |source| ProjectError::Save {
            path: json_path.to_owned(),
            step,
            source,
        }
    };
    // 1. The payload under its new name: written to a temporary, synced, renamed into place.
    // The name was free, so nothing the JSON on disk refers to is touched.
    let mut created: Option<PathBuf> = None;
    let mut bin_tmp: Option<PathBuf> = None;
    let result = (|| -> Result<(), ProjectError> {
        if let Some((bytes, name, exists)) = bin {
            let path = dir.join(name);
            if exists {
                // Same bytes already there (perhaps from a save that died before its JSON
                // rename, never synced): make sure they are durable.
                fs_ops
                    .sync_file(&path)
                    .map_err(failed("syncing the payload"))?;
            } else {
                let tmp = with_suffix(&path, ".tmp");
                bin_tmp = Some(tmp.clone());
                fs_ops
                    .write(&tmp, bytes)
                    .map_err(failed("writing the payload"))?;
                fs_ops
                    .sync_file(&tmp)
                    .map_err(failed("syncing the payload"))?;
                fs_ops
                    .rename(&tmp, &path)
                    .map_err(failed("naming the payload"))?;
                bin_tmp = None;
                created = Some(path);
            }
            fs_ops.sync_dir(dir).map_err(failed("syncing the folder"))?;
        }
        // 2. The JSON, through a synced temporary, renamed over the old one: the commit point.
        fs_ops
            .write(&json_tmp, json)
            .map_err(failed("writing the project"))?;
        fs_ops
            .sync_file(&json_tmp)
            .map_err(failed("syncing the project"))?;
        fs_ops
            .rename(&json_tmp, json_path)
            .map_err(failed("replacing the project file"))?;
        Ok(())
    })();
    if let Err(e) = result {
        // The old JSON is still the one on disk and does not refer to anything this save
        // created (its names were free), so those files can go.
        let _ = fs_ops.remove(&json_tmp);
        for p in bin_tmp.iter().chain(&created) {
            let _ = fs_ops.remove(p);
        }
        return Err(e);
    }
    // 3. Only once the new JSON is durable may the files the old one needed go; if the
    // directory cannot be synced they stay (the next save removes them).
    if fs_ops.sync_dir(dir).is_err() {
        return Ok(());
    }
    let keep = bin.map(|(_, name, _)| name);
    if let Ok(entries) = fs::read_dir(dir) {
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            // `a.thicket.0badf00d.bin` might also be the old-style payload of a project
            // called `a.thicket.0badf00d.json`; such a file is left alone.
            let other_project = name
                .strip_suffix(".bin")
                .is_some_and(|s| dir.join(format!("{s}.json")).exists());
            if Some(name.as_str()) != keep && is_payload_file(&stem, &name) && !other_project {
                let _ = fs_ops.remove(&entry.path());
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payload_file_names_are_recognised_exactly() {
        let stem = "a.thicket";
        for yes in [
            "a.thicket.bin",
            "a.thicket.bin.prev",
            "a.thicket.bin.tmp",
            "a.thicket.0badf00d.bin",
            "a.thicket.0badf00d-12.bin",
            "a.thicket.0badf00d.bin.tmp",
        ] {
            assert!(is_payload_file(stem, yes), "{yes}");
        }
        for no in [
            "a.thicket.json",
            "b.thicket.bin",
            "a.thicket.x.thicket.bin",
            "a.thicket.0badf00.bin",
            "a.thicket.0badf00d-.bin",
            "a.thicket.0badf00g.bin",
            "a.thicketbin",
            "a.thicket.mine.bin",
        ] {
            assert!(!is_payload_file(stem, no), "{no}");
        }
    }
}

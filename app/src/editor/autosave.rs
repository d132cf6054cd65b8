//! Autosave to a recovery project beside the user's files (never over them), and finding it on
//! the next start.
//!
//! The recovery project is written with the same atomic save as File → Save (temporary
//! sibling, sync, rename), so whatever moment the process dies, the previous recovery file
//! stays loadable. A small `recovery.meta.json` written after it says which file the work
//! belonged to; it is informative only: a missing or stale one never hides the recovery
//! project itself.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};
use thicket_core::scene::Document;

use super::Editor;
use super::jobs::{Poll, Worker};

/// Default autosave interval.
pub const DEFAULT_AUTOSAVE_SECS: u32 = 120;

/// File name of the recovery project inside the recovery folder.
pub const RECOVERY_FILE: &str = "recovery.thicket.json";
const META_FILE: &str = "recovery.meta.json";

/// What the recovery folder holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default)]
pub struct RecoveryMeta {
    /// The project the unsaved work belonged to (`None`: untitled).
    pub original: Option<PathBuf>,
    /// Seconds since the Unix epoch when it was written.
    pub saved_unix_secs: u64,
}

/// A recovery project found on start-up.
#[derive(Debug, Clone, PartialEq)]
pub struct Recovery {
    /// The recovery project file.
    pub path: PathBuf,
    /// What the meta file says (default when it is missing or unreadable).
    pub meta: RecoveryMeta,
}

/// The recovery folder: `$THICKET_RECOVERY_DIR`, else `$XDG_DATA_HOME/thicket/recovery`, else
/// `~/.local/share/thicket/recovery`, else a folder in the temporary directory.
#[must_use]
pub fn recovery_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("THICKET_RECOVERY_DIR") {
        return PathBuf::from(d);
    }
    if let Some(d) = std::env::var_os("XDG_DATA_HOME").filter(|d| !d.is_empty()) {
        return PathBuf::from(d).join("thicket").join("recovery");
    }
    if let Some(h) = std::env::var_os("HOME").filter(|d| !d.is_empty()) {
        return PathBuf::from(h).join(".local/share/thicket/recovery");
    }
    std::env::temp_dir().join("thicket-recovery")
}

/// Writes `doc` as the recovery project in `dir` (atomically), then the meta file.
///
/// # Errors
/// The folder cannot be created or the save fails (the previous recovery file is kept).
pub fn write_recovery(dir: &Path, doc: &Document, original: Option<&Path>) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create the recovery folder {}: {e}", dir.display()))?;
    crate::files::save_project(doc, &dir.join(RECOVERY_FILE))?;
    let meta = RecoveryMeta {
        original: original.map(Path::to_path_buf),
        saved_unix_secs: SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs()),
    };
    let meta_path = dir.join(META_FILE);
    let text = serde_json::to_vec_pretty(&meta)?;
    crate::files::write_through_temporary(&meta_path, |tmp| {
        std::fs::write(tmp, text)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", meta_path.display()))
    })
}

/// The recovery project in `dir`, if there is one.
#[must_use]
pub fn find_recovery(dir: &Path) -> Option<Recovery> {
    let path = dir.join(RECOVERY_FILE);
    if !path.is_file() {
        return None;
    }
    let meta = std::fs::read(dir.join(META_FILE))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
        .unwrap_or_default();
    Some(Recovery { path, meta })
}

/// Removes the recovery project (after a save, a clean exit, or when the user discards it).
pub fn discard_recovery(dir: &Path) {
    for name in [
        RECOVERY_FILE.to_owned(),
        RECOVERY_FILE.replace(".json", ".bin"),
        format!("{}.prev", RECOVERY_FILE.replace(".json", ".bin")),
        META_FILE.to_owned(),
    ] {
        let _ = std::fs::remove_file(dir.join(name));
    }
}

/// The autosave timer: when the next autosave is due, which content the last one wrote, and
/// the write running on a worker thread.
#[derive(Debug, Default)]
pub struct AutosaveTimer {
    due: Option<Instant>,
    saved_key: Option<(u64, u64)>,
    write: Option<Worker<anyhow::Result<()>>>,
}

/// What one [`AutosaveTimer::tick`] saw.
#[derive(Debug, Default)]
pub struct AutosaveTick {
    /// A write finished since the last tick: how it went.
    pub finished: Option<anyhow::Result<()>>,
    /// Tick again after this long (the next autosave is due then).
    pub wake_after: Option<Duration>,
}

impl AutosaveTimer {
    /// Collects a finished write, then autosaves to `dir` when `interval_secs` (0: off) have
    /// passed and the document changed since the last autosave. While a write runs nothing
    /// else happens.
    pub fn tick(
        &mut self,
        editor: &Editor,
        interval_secs: u32,
        dir: &Path,
        now: Instant,
    ) -> AutosaveTick {
        let mut tick = AutosaveTick::default();
        if let Some(write) = &self.write {
            match write.poll() {
                Poll::Ready(r) => {
                    self.write = None;
                    tick.finished = Some(r);
                }
                Poll::Lost => self.write = None,
                Poll::Running => return tick,
            }
        }
        if interval_secs == 0 {
            self.due = None;
            return tick;
        }
        let interval = Duration::from_secs(u64::from(interval_secs));
        let due = *self.due.get_or_insert(now + interval);
        if now < due {
            tick.wake_after = Some(due - now);
            return tick;
        }
        self.due = Some(now + interval);
        if editor.is_dirty() && self.saved_key != Some(editor.content_key()) {
            self.start(editor, dir);
        }
        tick
    }

    /// Starts an autosave of `editor`'s document to `dir` now; the document is copied for the
    /// worker.
    pub fn start(&mut self, editor: &Editor, dir: &Path) {
        let doc = editor.doc().clone();
        let original = editor.path().map(Path::to_path_buf);
        let dir = dir.to_path_buf();
        self.saved_key = Some(editor.content_key());
        self.write = Some(Worker::spawn(move || {
            write_recovery(&dir, &doc, original.as_deref())
        }));
    }

    /// Whether a write is running.
    #[must_use]
    pub fn is_writing(&self) -> bool {
        self.write.is_some()
    }

    /// Waits for a running write (tests and exit).
    pub fn wait(&mut self) -> Option<anyhow::Result<()>> {
        self.write.take().and_then(Worker::wait)
    }
}

//! `kill -9` during a save and during an autosave leaves the user's file and the last recovery
//! file loadable.
//!
//! The test runs itself as a child process (the same test binary, with an environment variable
//! saying which loop to run). The child saves in a tight loop and prints a line after each
//! completed write; the parent kills it with SIGKILL at staggered moments, then loads both
//! files. The house sample's 2.7 MB payload makes each write long enough that kills land
//! inside writes as well as between them.

use std::io::{BufRead as _, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use thicket::editor::autosave::{RECOVERY_FILE, find_recovery, write_recovery};
use thicket::files::{load_document, save_project};

const MODE_VAR: &str = "THICKET_CRASH_CHILD";
const DIR_VAR: &str = "THICKET_CRASH_DIR";

fn house() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/house.thicket.json")
}

/// The child: write forever (until killed), alternating the content so every write differs.
fn child(mode: &str, dir: &Path) -> ! {
    let mut doc = load_document(&house()).expect("the house sample loads");
    let user = dir.join("user.thicket.json");
    let mut n = 0u64;
    loop {
        n += 1;
        doc.objects[0].name = format!("edit {n}");
        match mode {
            "save" => save_project(&doc, &user).expect("save"),
            _ => write_recovery(dir, &doc, Some(&user)).expect("autosave"),
        }
        println!("wrote {n}");
    }
}

fn kill_during(mode: &str, dir: &Path, delay: Duration) {
    let mut c = Command::new(std::env::current_exe().expect("test binary"))
        .args([
            "--exact",
            "kill_9_during_save_and_autosave_leaves_files_loadable",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(MODE_VAR, mode)
        .env(DIR_VAR, dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn the child");
    // Wait for the first completed write, so there is a previous version to fall back to,
    // then kill at a staggered moment inside the following writes.
    let stdout = c.stdout.take().expect("piped");
    let mut lines = BufReader::new(stdout).lines();
    loop {
        match lines.next() {
            Some(Ok(l)) if l.starts_with("wrote ") => break,
            Some(_) => {}
            None => panic!("the child ended before its first write"),
        }
    }
    std::thread::sleep(delay);
    c.kill().expect("SIGKILL");
    c.wait().expect("reaped");
}

#[test]
fn kill_9_during_save_and_autosave_leaves_files_loadable() {
    if let Some(mode) = std::env::var_os(MODE_VAR) {
        let dir = PathBuf::from(std::env::var_os(DIR_VAR).expect("dir"));
        child(&mode.to_string_lossy(), &dir);
    }
    let original = load_document(&house()).expect("house");
    let expected = original.objects.len();
    let mut interrupted = 0;
    for (round, mode) in ["save", "autosave", "save", "autosave", "save", "autosave"]
        .into_iter()
        .enumerate()
    {
        let dir = tempfile::tempdir().expect("temp dir");
        // Staggered: some kills land early in a write, some late, some between writes.
        let delay = Duration::from_millis(5 + 37 * round as u64);
        let user = dir.path().join("user.thicket.json");
        save_project(&original, &user).expect("the user's file");
        kill_during(mode, dir.path(), delay);
        // A temporary sibling left behind means the kill landed inside a write.
        interrupted += std::fs::read_dir(dir.path())
            .expect("listable")
            .filter_map(Result::ok)
            .any(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            as usize;
        let mut files = vec![user.clone()];
        if mode == "autosave" {
            let r = find_recovery(dir.path()).expect("a recovery file is found");
            assert_eq!(r.path, dir.path().join(RECOVERY_FILE));
            assert_eq!(r.meta.original.as_deref(), Some(user.as_path()));
            files.push(r.path);
        }
        for file in files {
            let doc = load_document(&file).unwrap_or_else(|e| {
                panic!(
                    "round {round} ({mode}): {} does not load: {e:#}",
                    file.display()
                )
            });
            assert_eq!(doc.objects.len(), expected, "round {round} ({mode})");
            if file == user && mode == "autosave" {
                assert_eq!(doc, original, "autosave never writes the user's file");
            } else {
                assert!(
                    doc.objects[0].name.starts_with("edit "),
                    "round {round} ({mode}): a completed write's content"
                );
            }
        }
    }
    eprintln!("{interrupted} of 6 kills landed inside a write");
}

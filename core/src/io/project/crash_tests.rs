//! The crash test: saves stopped at every file-system operation (killed, or the operation
//! failing), two and three saves in a row, and after each the project must load as the old or
//! the new content, byte for byte.

use std::io;
use std::path::Path;

use super::save::{RealFs, SaveFs};
use super::*;
use crate::scene::{Document, ObjectKind, VoxelModel};
use crate::svo::{Svo, Voxel};
use glam::UVec3;

/// How a save is stopped at its chosen operation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    /// The process dies: that operation and every later one never happen. A write dies half
    /// way, leaving a partial file.
    Kill,
    /// That operation fails (a full disk, a refused rename); the save goes on to clean up.
    Fail,
}

/// A [`SaveFs`] that stops the save at operation `at` (counting from 0).
struct FaultFs {
    at: Option<usize>,
    fault: Fault,
    done: usize,
    dead: bool,
}

impl FaultFs {
    fn new(at: Option<usize>, fault: Fault) -> Self {
        Self {
            at,
            fault,
            done: 0,
            dead: false,
        }
    }

    /// Whether the current operation is stopped (and the process, for a kill, dead).
    fn stop(&mut self) -> bool {
        if self.dead {
            return true;
        }
        let hit = self.at == Some(self.done);
        self.done += 1;
        if hit && self.fault == Fault::Kill {
            self.dead = true;
        }
        hit
    }
}

fn injected() -> io::Error {
    io::Error::other("injected fault")
}

impl SaveFs for FaultFs {
    fn write(&mut self, path: &Path, bytes: &[u8]) -> io::Result<()> {
        let was_dead = self.dead;
        if self.stop() {
            if !was_dead {
                // Dies (or the disk fills) half way through the write.
                RealFs.write(path, &bytes[..bytes.len() / 2])?;
            }
            return Err(injected());
        }
        RealFs.write(path, bytes)
    }
    fn sync_file(&mut self, _path: &Path) -> io::Result<()> {
        // No power loss is modelled, so a sync only needs to be a point where the save stops
        // (and skipping the real fsync keeps thousands of saves fast).
        if self.stop() {
            return Err(injected());
        }
        Ok(())
    }
    fn rename(&mut self, from: &Path, to: &Path) -> io::Result<()> {
        if self.stop() {
            return Err(injected());
        }
        RealFs.rename(from, to)
    }
    fn sync_dir(&mut self, _dir: &Path) -> io::Result<()> {
        if self.stop() {
            return Err(injected());
        }
        Ok(())
    }
    fn remove(&mut self, path: &Path) -> io::Result<()> {
        if self.stop() {
            return Err(injected());
        }
        RealFs.remove(path)
    }
}

/// A small document whose payload depends on `seed` (a few voxels and a light).
fn doc(seed: u32) -> Document {
    let mut svo = Svo::new(3, false).unwrap();
    for i in 0..(3 + seed % 4) {
        let c = UVec3::new(i, (i * seed) % 8, (seed + i) % 8);
        svo.set(c, Voxel::new([seed as u8, i as u8, 7, 255], glam::Vec3::Y))
            .unwrap();
    }
    let mut d = Document::default();
    d.add(
        "Model",
        ObjectKind::Voxels(VoxelModel {
            svo,
            ..VoxelModel::default()
        }),
    );
    d.quality.lod_pixel_threshold = 1.0 + seed as f32 / 8.0;
    d
}

/// The content of a document as a save writes it: its JSON (without the payload file name,
/// which depends on what else is in the folder) and its payload bytes.
fn content(d: &Document) -> Vec<u8> {
    let (mut bin, payloads) = encode_payloads(d);
    let mut out = serde_json::to_vec(&ProjectFile {
        document: Document {
            format_version: FORMAT_VERSION,
            ..d.clone()
        },
        bin: None,
        payloads,
    })
    .unwrap();
    out.append(&mut bin);
    out
}

/// How many operations a clean save of `d` over the project in `dir` performs.
fn ops_of_save(d: &Document, seq_before: &[Document]) -> usize {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.thicket.json");
    for b in seq_before {
        save_with(b, &path, &mut FaultFs::new(None, Fault::Kill)).unwrap();
    }
    let mut f = FaultFs::new(None, Fault::Kill);
    save_with(d, &path, &mut f).unwrap();
    f.done
}

/// Runs one sequence: a clean save of `docs[0]`, then each later document saved with its
/// fault; after each save the project must load as what was on disk before or the new
/// document. Finally a clean save must succeed and leave only its two files.
fn run_sequence(docs: &[Document], faults: &[(Option<usize>, Fault)]) -> Result<(), String> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.thicket.json");
    // Clean saves here skip the real fsyncs too (FaultFs without a fault), which keeps the
    // tens of thousands of saves below fast; `save` itself is tested elsewhere.
    let clean = |d: &Document| save_with(d, &path, &mut FaultFs::new(None, Fault::Kill));
    clean(&docs[0]).unwrap();
    let mut on_disk = content(&docs[0]);
    for (step, (d, &(at, fault))) in docs[1..].iter().zip(faults).enumerate() {
        let mut f = FaultFs::new(at, fault);
        let saved = save_with(d, &path, &mut f).is_ok();
        let loaded = load(&path).map_err(|e| format!("step {step}: does not load: {e}"))?;
        let now = content(&loaded);
        let new = content(d);
        if now != on_disk && now != new {
            return Err(format!(
                "step {step}: loads as neither the old nor the new content"
            ));
        }
        if saved && now != new {
            return Err(format!(
                "step {step}: the save succeeded but the old content loads"
            ));
        }
        if !saved && fault == Fault::Fail && now != on_disk {
            // A failed save reports the failure, so the user must still have the old content.
            return Err(format!("step {step}: a failed save replaced the content"));
        }
        on_disk = now;
    }
    let last = doc(99);
    clean(&last).map_err(|e| format!("the clean save after the faults: {e}"))?;
    if content(&load(&path).unwrap()) != content(&last) {
        return Err("the clean save after the faults does not load back".into());
    }
    let files = fs::read_dir(dir.path()).unwrap().count();
    if files != 2 {
        return Err(format!(
            "{files} files are left after a clean save, expected 2"
        ));
    }
    Ok(())
}

/// Every fault point of a save whose clean run takes `ops` operations (kills, and failures
/// when `fail`), plus no fault.
fn points(ops: usize, fail: bool) -> Vec<(Option<usize>, Fault)> {
    let mut v = vec![(None, Fault::Kill)];
    for at in 0..ops {
        v.push((Some(at), Fault::Kill));
        if fail {
            v.push((Some(at), Fault::Fail));
        }
    }
    v
}

/// Runs every combination of fault points over `depth` saves after the first.
fn check_all(docs: &[Document], depth: usize, fail: bool) {
    // Every save in the sequences below performs at most this many operations (the first
    // save after a crash may also remove orphans; an extra point past the end is no fault).
    let ops = (1..docs.len())
        .map(|i| ops_of_save(&docs[i], &docs[..i]))
        .max()
        .unwrap()
        + 2;
    let pts = points(ops, fail);
    let mut failures = Vec::new();
    let mut runs = 0usize;
    let mut seq = vec![0usize; depth];
    loop {
        let faults: Vec<_> = seq.iter().map(|&i| pts[i]).collect();
        runs += 1;
        if let Err(e) = run_sequence(&docs[..=depth], &faults) {
            failures.push(format!("{faults:?}: {e}"));
        }
        // Next combination (odometer).
        let mut k = 0;
        while k < depth {
            seq[k] += 1;
            if seq[k] < pts.len() {
                break;
            }
            seq[k] = 0;
            k += 1;
        }
        if k == depth {
            break;
        }
    }
    assert!(runs >= pts.len().pow(depth as u32));
    assert!(
        failures.is_empty(),
        "{} of {runs} fault sequences lost the project, first: {:?}",
        failures.len(),
        &failures[..failures.len().min(5)]
    );
}

#[test]
fn a_save_stops_anywhere_and_the_project_still_loads() {
    // Also checks the premise: a save has several operations to stop at.
    assert!(ops_of_save(&doc(2), &[doc(1)]) >= 8);
    check_all(&[doc(1), doc(2)], 1, true);
}

#[test]
fn two_crashed_saves_in_a_row_lose_nothing() {
    // Different contents, and the same content saved again after a crash (what a user does),
    // and a save with no payloads at all in between.
    check_all(&[doc(1), doc(2), doc(3)], 2, true);
    check_all(&[doc(1), doc(2), doc(2)], 2, true);
    check_all(&[doc(1), Document::default(), doc(3)], 2, true);
}

#[test]
fn three_crashed_saves_in_a_row_lose_nothing() {
    // Every combination of three kills. With failures mixed in too the product is about 8×
    // larger (minutes in a debug build): THICKET_CRASH_FULL=1 runs it.
    let full = std::env::var_os("THICKET_CRASH_FULL").is_some();
    check_all(&[doc(1), doc(2), doc(2), doc(3)], 3, full);
    check_all(&[doc(1), doc(2), Document::default(), doc(3)], 3, full);
}

//! Project files: `NAME.thicket.json` (the document's parameters, human-readable) plus, when the
//! document holds voxel or mesh data, `NAME.thicket.bin` beside it with the binary payloads.
//! KRS objects are parametric: kernels, mirrors and transform live in the JSON, with no payload.
//!
//! The JSON carries `format_version`, every struct is `#[serde(default)]`, and each payload is
//! addressed by offset and length with a CRC-32; the JSON also records the length and CRC-32 of
//! the whole `.bin`, so a `.bin` that does not belong to the JSON is detected.
//!
//! # Crash-safe saves
//! The payloads go to a file named after their content, `NAME.thicket.<crc32>.bin` (with a
//! `-N` suffix if another file already has that name), which the JSON names in `bin.file`:
//! 1. write `<new>.bin.tmp`, sync it, rename it to `<new>.bin` (a name no file had, so the
//!    payload the JSON on disk needs is never renamed over), sync the directory;
//! 2. write `NAME.thicket.json.tmp`, sync it, rename it over the JSON: the commit point;
//! 3. sync the directory, then remove the payload files the old JSON needed (and orphans of
//!    earlier crashed saves).
//!
//! Whatever moment the process dies, and however many saves in a row die, the JSON on disk is
//! complete (old or new) and the `.bin` it names is whole. A save that fails (a full disk)
//! removes what it created and leaves the previous save as it was. Re-saving unchanged
//! payloads reuses their file. Older projects, whose payload is `NAME.thicket.bin` (or
//! `NAME.thicket.bin.prev` after a crash of the older save), still load; the next save
//! moves them to the new naming.

use std::fs;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3, Vec4};
use serde::{Deserialize, Serialize};

use crate::budget::MemoryBudget;
use crate::mesh::{Material, MeshModel, Texture, TriangleMesh};
use crate::scene::{Document, FORMAT_VERSION, ObjectKind, SceneError};
use crate::skin::{AnimationClip, Channel, Interpolation, Property, Rig, StretchOverrides};
use crate::svo::{INTERIOR_NORMAL, Skin4, Svo, Voxel, morton_decode, morton_encode};

/// Largest project JSON we read (the JSON holds parameters only; payloads are in the `.bin`).
const MAX_JSON_BYTES: u64 = 256 << 20;
/// Largest `.bin` we read.
const MAX_BIN_BYTES: u64 = 16 << 30;

/// Why a project could not be loaded or saved.
#[derive(Debug, thiserror::Error)]
pub enum ProjectError {
    /// The file system refused.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// A save failed: the file system refused a step. Nothing the save created is left
    /// behind and the previous save is untouched; `path` is the project named by the caller
    /// (not a temporary file).
    #[error("{path}: cannot save ({step}): {source}")]
    Save {
        /// The project file being saved.
        path: PathBuf,
        /// The step that failed, e.g. "writing the payload".
        step: &'static str,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The JSON does not parse (with its line and column).
    #[error("{path}: line {line}, column {column}: {message}")]
    Json {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the parser said.
        message: String,
    },
    /// Written by a newer version of Thicket.
    #[error(
        "{path}: format_version {found} is newer than this build supports ({supported}); update Thicket"
    )]
    Version {
        /// The file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Newest version this build reads.
        supported: u32,
    },
    /// A binary payload is missing, out of range, corrupt, or fails its checksum.
    #[error("{path}: {detail}")]
    Payload {
        /// The file.
        path: PathBuf,
        /// What and where.
        detail: String,
    },
    /// A file larger than we are willing to read.
    #[error("{path}: {bytes} bytes is larger than the {limit}-byte limit for this kind of file")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// Loading it would need more memory than the budget allows (estimated before reading).
    #[error("{path}: {source}")]
    OverBudget {
        /// The project file.
        path: PathBuf,
        /// The estimate, the limit and where the limit comes from.
        source: crate::budget::OverBudget,
    },
    /// The document parses but holds values a renderer must not see.
    #[error("{path}: {source}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is invalid.
        #[source]
        source: SceneError,
    },
}

/// Where a payload lives in the `.bin`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
struct PayloadRef {
    /// The object it belongs to.
    object_id: u64,
    /// Byte offset in the `.bin`.
    offset: u64,
    /// Byte length.
    length: u64,
    /// CRC-32 of those bytes.
    crc32: u32,
    /// Which payload of the object: empty for the main one (octree or mesh), `"skin"` for a
    /// skinned voxel model's clips and per-voxel stretch overrides. Omitted when empty, so
    /// files without skin are unchanged.
    #[serde(skip_serializing_if = "String::is_empty")]
    part: String,
}

/// [`PayloadRef::part`] of a skinned voxel model's clip and override payload.
const SKIN_PART: &str = "skin";

/// [`PayloadRef::part`] of a frame sequence's frames (format version 2).
const FRAMES_PART: &str = "frames";

/// Identity of the whole `.bin` the JSON was saved with.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
struct BinRef {
    /// File name, relative to the JSON.
    file: String,
    /// Byte length.
    length: u64,
    /// CRC-32 of the whole file.
    crc32: u32,
}

#[derive(Serialize, Deserialize, Default)]
#[serde(default)]
struct ProjectFile {
    #[serde(flatten)]
    document: Document,
    bin: Option<BinRef>,
    payloads: Vec<PayloadRef>,
}

/// The payload file the project JSON at `json_path` refers to, as saved: its `bin.file` when
/// the JSON can be read and names one, otherwise the old-style `NAME.thicket.bin` beside it.
#[must_use]
pub fn bin_path_for(json_path: &Path) -> PathBuf {
    #[derive(Deserialize)]
    struct BinOnly {
        bin: Option<BinRef>,
    }
    fs::read(json_path)
        .ok()
        .and_then(|t| serde_json::from_slice::<BinOnly>(&t).ok())
        .and_then(|f| f.bin)
        .filter(|b| !b.file.is_empty() && !b.file.contains(['/', '\\']))
        .map_or_else(
            || legacy_bin_path(json_path),
            |b| json_path.with_file_name(b.file),
        )
}

/// The payload name older saves used: `a.thicket.json` → `a.thicket.bin`.
fn legacy_bin_path(json_path: &Path) -> PathBuf {
    json_path.with_file_name(format!("{}.bin", save::stem_of(json_path)))
}

fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

/// Saves a project crash-safely (see the module docs). Validates the document first, so what
/// is written always loads.
///
/// # Errors
/// [`ProjectError::Invalid`] for a document that does not validate, [`ProjectError::Save`] when
/// the file system refuses; the previous save is untouched in both cases.
pub fn save(doc: &Document, json_path: &Path) -> Result<(), ProjectError> {
    save_with(doc, json_path, &mut save::RealFs)
}

/// [`save`] through the given file-system operations (the crash test injects faults).
pub(crate) fn save_with(
    doc: &Document,
    json_path: &Path,
    fs_ops: &mut dyn save::SaveFs,
) -> Result<(), ProjectError> {
    doc.validate().map_err(|source| ProjectError::Invalid {
        path: json_path.to_owned(),
        source,
    })?;
    check_voxel_total(doc).map_err(|detail| ProjectError::Payload {
        path: json_path.to_owned(),
        detail: format!("not saved: {detail}"),
    })?;
    let (bin, payloads) = encode_payloads(doc);
    let bin_name = if payloads.is_empty() {
        None
    } else {
        Some(save::bin_name_for(json_path, &bin)?)
    };
    let file = ProjectFile {
        document: Document {
            format_version: FORMAT_VERSION,
            ..doc.clone()
        },
        bin: bin_name.as_ref().map(|(name, _)| BinRef {
            file: name.clone(),
            length: bin.len() as u64,
            crc32: crc32fast::hash(&bin),
        }),
        payloads,
    };
    let json = serde_json::to_vec_pretty(&file).map_err(|e| ProjectError::Payload {
        path: json_path.to_owned(),
        detail: format!("cannot encode the document: {e}"),
    })?;
    save::write_project(
        fs_ops,
        json_path,
        &json,
        bin_name
            .as_ref()
            .map(|(name, exists)| (bin.as_slice(), name.as_str(), *exists)),
    )
}

/// Every object's payloads, concatenated, with where each one lies.
fn encode_payloads(doc: &Document) -> (Vec<u8>, Vec<PayloadRef>) {
    let mut bin = Vec::new();
    let mut payloads = Vec::new();
    // Appends what `encode` writes as one payload of object `id`.
    let mut push = |id: u64, part: &str, encode: &dyn Fn(&mut Vec<u8>)| {
        let start = bin.len();
        encode(&mut bin);
        let bytes = &bin[start..];
        payloads.push(PayloadRef {
            object_id: id,
            offset: start as u64,
            length: bytes.len() as u64,
            crc32: crc32fast::hash(bytes),
            part: part.to_owned(),
        });
    };
    for o in &doc.objects {
        match &o.kind {
            ObjectKind::Voxels(v) => {
                push(o.id, "", &|bin| encode_svo(&v.svo, bin));
                if let Some(frames) = &v.frames {
                    push(o.id, FRAMES_PART, &|bin| encode_frames(frames, bin));
                }
                if let Some(rig) = &v.rig {
                    push(o.id, SKIN_PART, &|bin| encode_skin(rig, bin));
                }
            }
            ObjectKind::Mesh(m) => push(o.id, "", &|bin| encode_mesh(&m.model, bin)),
            // Parametric: everything is in the JSON.
            ObjectKind::Krs(_) => {}
        }
    }
    (bin, payloads)
}

/// Reads a payload file beside the project, confined like every file reference (a regular
/// file inside the project's folder, not reached through a link that leads out), at most
/// [`MAX_BIN_BYTES`].
fn read_bin_file(path: &Path, json_path: &Path) -> Result<Vec<u8>, ProjectError> {
    use crate::io::confine::{RefError, read_reference};
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    read_reference(save::dir_of(json_path), &name, MAX_BIN_BYTES).map_err(|e| match e {
        RefError::Refused(detail) => ProjectError::Payload {
            path: json_path.to_owned(),
            detail: format!("bin file {detail}"),
        },
        RefError::Io(_, source) => ProjectError::Io {
            path: path.to_owned(),
            source,
        },
        RefError::TooLarge(_, limit) => ProjectError::TooLarge {
            path: path.to_owned(),
            bytes: limit + 1,
            limit,
        },
    })
}

/// Reads the project JSON: a regular file, at most `limit` bytes, decided by reading.
fn read_capped(path: &Path, limit: u64) -> Result<Vec<u8>, ProjectError> {
    use crate::io::confine::RefError;
    crate::io::confine::read_capped(path, limit).map_err(|e| match e {
        RefError::Refused(detail) => ProjectError::Payload {
            path: path.to_owned(),
            detail,
        },
        RefError::Io(_, source) => ProjectError::Io {
            path: path.to_owned(),
            source,
        },
        RefError::TooLarge(_, limit) => ProjectError::TooLarge {
            path: path.to_owned(),
            bytes: limit + 1,
            limit,
        },
    })
}

/// Loads a project saved by [`save`].
///
/// # Errors
/// A [`ProjectError`] naming the file and what is wrong; never panics on bad input.
pub fn load(json_path: &Path) -> Result<Document, ProjectError> {
    load_within(json_path, &MemoryBudget::for_this_machine())
}

/// Peak heap of loading a project, per byte of its JSON and `.bin` (the JSON parsed, the `.bin`
/// read whole, its octrees decoded and built). Measured with a counting allocator on the
/// samples: 1.9 (mixed) to 5.2 (house, terrain) bytes per file byte; the test
/// `the_load_estimate_covers_the_samples` keeps the estimate above every measured peak.
pub const LOAD_BYTES_PER_FILE_BYTE: u64 = 6;

/// The estimated peak memory of loading a project whose JSON and `.bin` have these sizes.
#[must_use]
pub fn estimate_load_bytes(json_bytes: u64, bin_bytes: u64) -> u64 {
    json_bytes
        .saturating_add(bin_bytes)
        .saturating_mul(LOAD_BYTES_PER_FILE_BYTE)
        .saturating_add(256 << 10)
}

/// [`load`] refused before the work when its estimated peak memory
/// ([`estimate_load_bytes`]: the JSON's size on disk, then the `.bin` length the JSON declares,
/// before the `.bin` is read) is over `budget`.
///
/// # Errors
/// As [`load`], and [`ProjectError::OverBudget`].
pub fn load_within(json_path: &Path, budget: &MemoryBudget) -> Result<Document, ProjectError> {
    let over = |source| ProjectError::OverBudget {
        path: json_path.to_owned(),
        source,
    };
    let what = "loading the project";
    let advice = "raise the limit with --memory-limit, or open it on a machine with more memory";
    if let Ok(meta) = std::fs::metadata(json_path) {
        budget
            .check(what, estimate_load_bytes(meta.len(), 0), advice)
            .map_err(over)?;
    }
    let text = read_capped(json_path, MAX_JSON_BYTES)?;
    load_from_parts(json_path, &text, |bin_ref| {
        budget
            .check(
                what,
                estimate_load_bytes(text.len() as u64, bin_ref.length),
                advice,
            )
            .map_err(over)?;
        let primary = json_path.with_file_name(&bin_ref.file);
        if bin_ref.file.contains(['/', '\\']) || bin_ref.file.is_empty() {
            return Err(ProjectError::Payload {
                path: json_path.to_owned(),
                detail: format!(
                    "bin file name {:?} must be a plain file name beside the project",
                    bin_ref.file
                ),
            });
        }
        let mut last_err = None;
        for candidate in [primary.clone(), with_suffix(&primary, ".prev")] {
            match read_bin_file(&candidate, json_path) {
                Ok(bytes)
                    if bytes.len() as u64 == bin_ref.length
                        && crc32fast::hash(&bytes) == bin_ref.crc32 =>
                {
                    return Ok(bytes);
                }
                Ok(bytes) => {
                    last_err.get_or_insert(ProjectError::Payload {
                        path: candidate,
                        detail: format!(
                            "does not belong to this project: {} bytes with CRC-32 {:08x}, the project expects {} bytes with CRC-32 {:08x}",
                            bytes.len(),
                            crc32fast::hash(&bytes),
                            bin_ref.length,
                            bin_ref.crc32
                        ),
                    });
                }
                Err(e) => {
                    last_err.get_or_insert(e);
                }
            }
        }
        Err(last_err.unwrap_or(ProjectError::Payload {
            path: primary,
            detail: "missing".into(),
        }))
    })
}

/// serde_json's message without the position it appends (the error names line and column
/// already), and what to write instead of the non-numbers JSON has no syntax for.
fn json_message(e: &serde_json::Error, text: &[u8]) -> String {
    let full = e.to_string();
    let suffix = format!(" at line {} column {}", e.line(), e.column());
    let message = full.strip_suffix(&suffix).unwrap_or(&full).to_owned();
    // The column counts characters from 1 and points at (or just past) the offending token.
    let line = text
        .split(|&b| b == b'\n')
        .nth(e.line().saturating_sub(1))
        .unwrap_or_default();
    let from = line.get(e.column().saturating_sub(1)..).unwrap_or_default();
    let token = from.trim_ascii_start();
    let non_number = ["NaN", "Infinity", "-Infinity", "inf", "-inf", "nan"]
        .into_iter()
        .find(|t| token.starts_with(t.as_bytes()));
    match non_number {
        Some(t) => format!("{message}: {t} is not a JSON number (a value must be finite)"),
        None => message,
    }
}

/// Parses a project from its JSON bytes; `read_bin` supplies the `.bin` (checked against the
/// [`BinRef`]). Separate from [`load`] so fuzzing needs no files.
fn load_from_parts(
    json_path: &Path,
    text: &[u8],
    read_bin: impl FnOnce(&BinRef) -> Result<Vec<u8>, ProjectError>,
) -> Result<Document, ProjectError> {
    let file: ProjectFile = serde_json::from_slice(text).map_err(|e| ProjectError::Json {
        path: json_path.to_owned(),
        line: e.line(),
        column: e.column(),
        message: json_message(&e, text),
    })?;
    let mut doc = file.document;
    if doc.format_version > FORMAT_VERSION {
        return Err(ProjectError::Version {
            path: json_path.to_owned(),
            found: doc.format_version,
            supported: FORMAT_VERSION,
        });
    }
    // Migration: a version-1 document is a version-2 document without frame sequences, a
    // version-2 one a version-3 one whose payloads are `SVO1`, and a version-3 one a version-4
    // one whose payloads are `SVO2` (`decode_svo` reads all three, mapping their normal codes
    // to this build's), so nothing changes but the number; the document in memory is always
    // the current format.
    doc.format_version = FORMAT_VERSION;
    let payload_err = |detail: String| ProjectError::Payload {
        path: json_path.to_owned(),
        detail,
    };
    check_object_graph(&doc, &file.payloads).map_err(payload_err)?;
    let bin = match &file.bin {
        Some(r) => read_bin(r)?,
        None => Vec::new(),
    };
    let bin_name = file.bin.as_ref().map_or(String::new(), |b| b.file.clone());
    let payload = |what: &str, id: u64, part: &str| -> Result<&[u8], ProjectError> {
        let p = file
            .payloads
            .iter()
            .find(|p| p.object_id == id && p.part == part)
            .ok_or_else(|| {
                let which = if part.is_empty() {
                    String::new()
                } else {
                    format!("{part} ")
                };
                payload_err(format!("{what} has no {which}payload in {bin_name:?}"))
            })?;
        let end = p
            .offset
            .checked_add(p.length)
            .filter(|&e| e <= bin.len() as u64)
            .ok_or_else(|| {
                payload_err(format!(
                    "{what}: payload at offset {} length {} lies outside {bin_name:?} ({} bytes)",
                    p.offset,
                    p.length,
                    bin.len()
                ))
            })?;
        let bytes = &bin[p.offset as usize..end as usize];
        let crc = crc32fast::hash(bytes);
        if crc != p.crc32 {
            return Err(payload_err(format!(
                "{what}: payload checksum mismatch in {bin_name:?} (expected {:08x}, found {crc:08x}); the file is corrupt",
                p.crc32
            )));
        }
        Ok(bytes)
    };
    for o in &mut doc.objects {
        if matches!(o.kind, ObjectKind::Krs(_)) {
            // Parametric: nothing in the `.bin`.
            continue;
        }
        let what = format!("object {:?} (id {})", o.name, o.id);
        let bytes = payload(&what, o.id, "")?;
        match &mut o.kind {
            ObjectKind::Voxels(v) => {
                v.svo = decode_svo(bytes)
                    .map_err(|d| payload_err(format!("{what}: voxel payload: {d}")))?;
                if let Some(frames) = &mut v.frames {
                    let bytes = payload(&what, o.id, FRAMES_PART)?;
                    frames.frames = decode_frames(bytes)
                        .map_err(|d| payload_err(format!("{what}: frames payload: {d}")))?;
                }
                if let Some(rig) = &mut v.rig {
                    let bytes = payload(&what, o.id, SKIN_PART)?;
                    decode_skin(bytes, rig)
                        .map_err(|d| payload_err(format!("{what}: skin payload: {d}")))?;
                    // Clip and skeleton consistency first, so the weight check below can
                    // trust the joint count and its message is about the weights.
                    rig.validate()
                        .map_err(|e| payload_err(format!("{what}: {e}")))?;
                    crate::skin::rig::check_weights(&v.svo, rig.skeleton.len())
                        .map_err(|e| payload_err(format!("{what}: {e}")))?;
                }
            }
            ObjectKind::Mesh(m) => {
                m.model = decode_mesh(bytes)
                    .map_err(|d| payload_err(format!("{what}: mesh payload: {d}")))?;
            }
            ObjectKind::Krs(_) => {}
        }
    }
    check_voxel_total(&doc).map_err(payload_err)?;
    doc.validate().map_err(|source| ProjectError::Invalid {
        path: json_path.to_owned(),
        source,
    })?;
    Ok(doc)
}

/// The object graph checked before anything is read or decoded, so the work of a load is
/// bounded by the size of its files: object ids are unique, each (object, part) has at most one
/// payload, and the payloads the objects use do not overlap in the `.bin` (a save never shares
/// one; a file whose objects all point at one payload would otherwise decode it once per
/// object). Together with each decoder checking its counts against its own bytes, the decoded
/// total is bounded by a fixed multiple of the `.bin`'s length.
fn check_object_graph(doc: &Document, payloads: &[PayloadRef]) -> Result<(), String> {
    let mut ids = std::collections::HashMap::with_capacity(doc.objects.len());
    for (i, o) in doc.objects.iter().enumerate() {
        if let Some(first) = ids.insert(o.id, i) {
            return Err(format!(
                "objects {first} and {i} both have id {}; ids must be unique",
                o.id
            ));
        }
    }
    let mut seen = std::collections::HashSet::with_capacity(payloads.len());
    let mut used: Vec<(u64, u64, usize)> = Vec::new();
    for (k, p) in payloads.iter().enumerate() {
        if !seen.insert((p.object_id, p.part.as_str())) {
            return Err(format!(
                "payload {k}: object id {} has two {} payloads",
                p.object_id,
                if p.part.is_empty() { "main" } else { &p.part }
            ));
        }
        if ids.contains_key(&p.object_id) && p.length > 0 {
            used.push((p.offset, p.offset.saturating_add(p.length), k));
        }
    }
    used.sort_unstable();
    for w in used.windows(2) {
        let ((_, end_a, a), (start_b, _, b)) = (w[0], w[1]);
        if start_b < end_a {
            return Err(format!(
                "payloads {a} (object {}) and {b} (object {}) overlap in the .bin; each object's payload must be its own",
                payloads[a].object_id, payloads[b].object_id
            ));
        }
    }
    Ok(())
}

// ---- binary encoding -------------------------------------------------------------------------

/// The first octree payload: every voxel, one record each.
const SVO_MAGIC: &[u8; 4] = b"SVO1";
/// The octree payload with tiles, before interior voxels existed: a record may carry the
/// interior mark's normal code as a plain −Z normal.
const SVO2_MAGIC: &[u8; 4] = b"SVO2";
/// The octree payload with tiles and interior voxels ([`encode_svo`]; the layout of `SVO2`).
const SVO3_MAGIC: &[u8; 4] = b"SVO3";

/// Most voxels a project may stand for, every model and frame together (2^31): a few tiles can
/// stand for more than any file could list, and tools that visit every voxel (exports) must
/// still finish. Loading and saving both refuse more.
pub const MAX_DOCUMENT_VOXELS: u64 = 1 << 31;

/// The voxels of every model and frame of `doc`; an error past [`MAX_DOCUMENT_VOXELS`].
fn check_voxel_total(doc: &Document) -> Result<u64, String> {
    let mut total = 0u64;
    for o in &doc.objects {
        if let ObjectKind::Voxels(v) = &o.kind {
            let frames = (0..v.frame_count()).filter_map(|i| v.frame(i));
            for (svo, _) in frames {
                total = total.saturating_add(svo.leaf_count());
            }
        }
    }
    if total > MAX_DOCUMENT_VOXELS {
        return Err(format!(
            "its models hold {total} voxels, more than the {MAX_DOCUMENT_VOXELS} a project may \
             (tools that visit every voxel, such as exports, would not finish)"
        ));
    }
    Ok(total)
}
const MESH_MAGIC: &[u8; 4] = b"MSH1";
/// The skin payload; `SKN2` adds each clip's frame rate after its duration. `SKN1` (no frame
/// rate: clips get the default) is still read.
const SKIN_MAGIC: &[u8; 4] = b"SKN2";
const SKIN_MAGIC_V1: &[u8; 4] = b"SKN1";

/// Little-endian reader that checks every length before reading or allocating.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| {
                format!(
                    "truncated: needs {n} bytes at offset {} but only {} remain",
                    self.at,
                    self.bytes.len() - self.at
                )
            })?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn u16(&mut self) -> Result<u16, String> {
        Ok(u16::from_le_bytes(
            self.take(2)?.try_into().unwrap_or_default(),
        ))
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().unwrap_or_default(),
        ))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or_default(),
        ))
    }
    fn f32(&mut self) -> Result<f32, String> {
        Ok(f32::from_bits(self.u32()?))
    }
    fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }
    /// A count of elements of `elem` bytes each, refused if more than the bytes left could hold.
    fn count(&mut self, elem: usize, what: &str) -> Result<usize, String> {
        let n = self.u32()? as usize;
        if n.saturating_mul(elem) > self.remaining() {
            return Err(format!(
                "{what}: declares {n} entries but only {} bytes remain",
                self.remaining()
            ));
        }
        Ok(n)
    }
    fn floats<const N: usize>(&mut self, n: usize) -> Result<Vec<[f32; N]>, String> {
        (0..n)
            .map(|_| {
                (0..N)
                    .map(|_| self.f32())
                    .collect::<Result<Vec<_>, _>>()
                    .map(|v| std::array::from_fn(|i| v[i]))
            })
            .collect()
    }
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_f32s(out: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

fn put_len(out: &mut Vec<u8>, n: usize) {
    put_u32(out, u32::try_from(n).unwrap_or(u32::MAX));
}

/// Canonical octree payload (`SVO2`): header (magic, depth, skin flag, two zero bytes, the
/// number of voxels, the number of runs), then every stored run in Morton order
/// ([`Svo::for_each_run`]): its origin's Morton code, its height (0: one voxel; h: a tile of
/// `2^h` voxels a side) and its attributes. A solid's interior costs one record per tile, so
/// the file follows the surface.
fn encode_svo(svo: &Svo, out: &mut Vec<u8>) {
    out.extend_from_slice(SVO3_MAGIC);
    out.push(svo.depth());
    out.push(u8::from(svo.has_skin()));
    out.extend_from_slice(&[0, 0]);
    out.extend_from_slice(&svo.leaf_count().to_le_bytes());
    let count_at = out.len();
    out.extend_from_slice(&0u64.to_le_bytes());
    let mut runs = 0u64;
    svo.for_each_run(|c, height, v| {
        runs += 1;
        out.extend_from_slice(&morton_encode(c).to_le_bytes());
        out.push(height);
        put_voxel(out, &v, svo.has_skin());
    });
    out[count_at..count_at + 8].copy_from_slice(&runs.to_le_bytes());
}

fn put_voxel(out: &mut Vec<u8>, v: &Voxel, skin: bool) {
    out.extend_from_slice(&v.color);
    out.extend_from_slice(&v.normal.to_le_bytes());
    out.push(v.material);
    if skin {
        out.extend_from_slice(&v.skin.joints);
        out.extend_from_slice(&v.skin.weights);
    }
}

const FRAMES_MAGIC: &[u8; 4] = b"FRM1";

/// Frame payload: magic, frame count, then per frame its origin (3 × f32), the length of its
/// octree payload (u64) and that payload. The shown frame's slot is an empty octree.
fn encode_frames(frames: &crate::scene::FrameSequence, out: &mut Vec<u8>) {
    out.extend_from_slice(FRAMES_MAGIC);
    put_len(out, frames.frames.len());
    for f in &frames.frames {
        put_f32s(out, &f.origin.to_array());
        let mut svo = Vec::new();
        encode_svo(&f.svo, &mut svo);
        out.extend_from_slice(&(svo.len() as u64).to_le_bytes());
        out.extend_from_slice(&svo);
    }
}

fn decode_frames(bytes: &[u8]) -> Result<Vec<crate::scene::VoxelFrame>, String> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(4)? != FRAMES_MAGIC {
        return Err("bad magic (expected FRM1)".into());
    }
    // Each frame takes at least its origin, its length and an octree header (12 + 8 + 16).
    let n = r.count(36, "frame count")?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let [x, y, z] = [r.f32()?, r.f32()?, r.f32()?];
        let len = r.u64()?;
        let len = usize::try_from(len)
            .ok()
            .filter(|&l| l <= r.remaining())
            .ok_or_else(|| {
                format!(
                    "frame {i}: declares {len} bytes but {} remain",
                    r.remaining()
                )
            })?;
        let svo = decode_svo(r.take(len)?).map_err(|e| format!("frame {i}: {e}"))?;
        out.push(crate::scene::VoxelFrame {
            svo,
            origin: Vec3::new(x, y, z),
        });
    }
    if r.remaining() != 0 {
        return Err(format!("{} bytes after the last frame", r.remaining()));
    }
    Ok(out)
}

fn decode_svo(bytes: &[u8]) -> Result<Svo, String> {
    let mut r = Reader { bytes, at: 0 };
    let magic = r.take(4)?;
    let (runs, legacy) = match magic {
        m if m == SVO_MAGIC => (false, true),
        m if m == SVO2_MAGIC => (true, true),
        m if m == SVO3_MAGIC => (true, false),
        _ => return Err("bad magic (expected SVO1, SVO2 or SVO3)".into()),
    };
    let depth = r.u8()?;
    let has_skin = match r.u8()? {
        0 => false,
        1 => true,
        other => return Err(format!("skin flag {other} is not 0 or 1")),
    };
    r.take(2)?;
    let voxels = r.u64()?;
    let count = if runs { r.u64()? } else { voxels };
    let record = 8 + u64::from(runs) + 4 + 2 + 1 + if has_skin { 8 } else { 0 };
    if count.checked_mul(record) != Some(r.remaining() as u64) {
        return Err(format!(
            "declares {count} records of {record} bytes but {} bytes follow",
            r.remaining()
        ));
    }
    // Checks the depth before anything is allocated.
    let mut svo = Svo::new(depth, has_skin).map_err(|e| e.to_string())?;
    let limit = 1u64 << (3 * u32::from(depth));
    // Leaves and tiles, in Morton order (checked below).
    let mut stored = Vec::new();
    // End (exclusive) of the last run's Morton range.
    let mut end = 0u64;
    let mut total = 0u64;
    for i in 0..count {
        let code = r.u64()?;
        let height = if runs { r.u8()? } else { 0 };
        let span = (height <= depth).then(|| 1u64 << (3 * u32::from(height)));
        let Some(span) = span.filter(|s| code % s == 0) else {
            return Err(format!(
                "record {i}: a run of height {height} at code {code} is not a node of the \
                 depth-{depth} octree"
            ));
        };
        if code >= limit || (i > 0 && code < end) {
            return Err(format!(
                "record {i}: code {code} is out of order, overlaps the run before it or lies \
                 outside the depth-{depth} octree"
            ));
        }
        end = code + span;
        total += span;
        if total > MAX_DOCUMENT_VOXELS {
            return Err(format!(
                "record {i}: the runs so far hold {total} voxels, more than the \
                 {MAX_DOCUMENT_VOXELS} a project may hold (tools that visit every voxel, such as \
                 exports, would not finish)"
            ));
        }
        let color: [u8; 4] = r.take(4)?.try_into().unwrap_or_default();
        let mut normal = r.u16()?;
        if legacy && normal == INTERIOR_NORMAL {
            // Written before the interior mark: the same −Z normal under its other code.
            normal = 0xffff;
        }
        let material = r.u8()?;
        let skin = if has_skin {
            let joints: [u8; 4] = r.take(4)?.try_into().unwrap_or_default();
            let weights: [u8; 4] = r.take(4)?.try_into().unwrap_or_default();
            Skin4 { joints, weights }
        } else {
            Skin4::default()
        };
        let v = Voxel {
            color,
            normal,
            material,
            skin,
        };
        if normal == INTERIOR_NORMAL && !v.is_interior() {
            return Err(format!(
                "record {i}: carries the interior mark's normal code with colour {color:?} (an \
                 interior voxel has no colour)"
            ));
        }
        if height > 0 && !svo.tile_value_ok(&v) {
            return Err(format!(
                "record {i}: a tile of height {height} holds a value this octree cannot store \
                 as a tile (one whose eight copies do not average to itself, or in a skinned \
                 octree one that is not interior)"
            ));
        }
        stored.push((morton_decode(code), height, v));
    }
    if total != voxels {
        return Err(format!(
            "declares {voxels} voxels but its runs hold {total}"
        ));
    }
    if !stored.is_empty() {
        svo = Svo::from_runs(depth, has_skin, stored).map_err(|e| e.to_string())?;
    }
    if let Some(p) = svo.exposed_interior() {
        return Err(format!(
            "interior voxel ({}, {}, {}) has an empty face neighbour (interior voxels must be \
             enclosed: nothing would draw it)",
            p.x, p.y, p.z
        ));
    }
    Ok(svo)
}

/// A skinned voxel model's clips (key arrays) and per-voxel stretch overrides; the skeleton and
/// settings are in the JSON.
fn encode_skin(rig: &Rig, out: &mut Vec<u8>) {
    out.extend_from_slice(SKIN_MAGIC);
    put_len(out, rig.clips.len());
    for c in &rig.clips {
        put_len(out, c.name.len());
        out.extend_from_slice(c.name.as_bytes());
        put_f32s(out, &[c.duration_secs, c.frame_rate]);
        put_len(out, c.channels.len());
        for ch in &c.channels {
            put_len(out, ch.joint);
            out.push(match ch.property {
                Property::Translation => 0,
                Property::Rotation => 1,
                Property::Scale => 2,
            });
            out.push(match ch.interpolation {
                Interpolation::Step => 0,
                Interpolation::Linear => 1,
                Interpolation::CubicSpline => 2,
            });
            out.extend_from_slice(&[0, 0]);
            put_len(out, ch.times.len());
            put_f32s(out, &ch.times);
            put_len(out, ch.values.len());
            ch.values.iter().for_each(|v| put_f32s(out, &v.to_array()));
        }
    }
    let entries = rig.stretch_overrides.entries();
    put_len(out, entries.len());
    for &(code, byte) in entries {
        out.extend_from_slice(&code.to_le_bytes());
        out.push(byte);
    }
    match &rig.reference_mesh {
        Some(m) => {
            out.push(1);
            encode_mesh(m, out);
        }
        None => out.push(0),
    }
}

/// Reads [`encode_skin`]'s payload into `rig` (clips and overrides). Structural checks only;
/// the caller validates the clips against the skeleton.
fn decode_skin(bytes: &[u8], rig: &mut Rig) -> Result<(), String> {
    let mut r = Reader { bytes, at: 0 };
    let with_frame_rate = match r.take(4)? {
        m if m == SKIN_MAGIC => true,
        m if m == SKIN_MAGIC_V1 => false,
        _ => return Err("bad magic (expected SKN2 or SKN1)".into()),
    };
    let n_clips = r.count(12, "clip table")?;
    let mut clips = Vec::with_capacity(n_clips);
    for i in 0..n_clips {
        let len = r.count(1, "clip name")?;
        let name = String::from_utf8(r.take(len)?.to_vec())
            .map_err(|_| format!("clip {i}: name is not UTF-8"))?;
        let duration_secs = r.f32()?;
        let frame_rate = if with_frame_rate {
            r.f32()?
        } else {
            crate::skin::keys::DEFAULT_FRAME_RATE
        };
        let n_channels = r.count(16, "channel table")?;
        let mut channels = Vec::with_capacity(n_channels);
        for k in 0..n_channels {
            let joint = r.u32()? as usize;
            let property = match r.u8()? {
                0 => Property::Translation,
                1 => Property::Rotation,
                2 => Property::Scale,
                b => {
                    return Err(format!(
                        "clip {i} ({name:?}), channel {k}: property {b} is not 0, 1 or 2"
                    ));
                }
            };
            let interpolation = match r.u8()? {
                0 => Interpolation::Step,
                1 => Interpolation::Linear,
                2 => Interpolation::CubicSpline,
                b => {
                    return Err(format!(
                        "clip {i} ({name:?}), channel {k}: interpolation {b} is not 0, 1 or 2"
                    ));
                }
            };
            r.take(2)?;
            let n = r.count(4, "key times")?;
            let times = (0..n).map(|_| r.f32()).collect::<Result<Vec<_>, _>>()?;
            let n = r.count(16, "key values")?;
            let values = r
                .floats::<4>(n)?
                .into_iter()
                .map(Vec4::from_array)
                .collect();
            channels.push(Channel {
                joint,
                property,
                interpolation,
                times,
                values,
            });
        }
        clips.push(AnimationClip {
            name,
            duration_secs,
            channels,
            frame_rate,
        });
    }
    let n = r.count(9, "stretch overrides")?;
    let mut entries = Vec::with_capacity(n);
    for _ in 0..n {
        entries.push((r.u64()?, r.u8()?));
    }
    let reference_mesh = match r.u8()? {
        0 if r.remaining() == 0 => None,
        0 => {
            return Err(format!(
                "{} unexpected bytes after the stretch overrides",
                r.remaining()
            ));
        }
        1 => Some(decode_mesh(&bytes[r.at..]).map_err(|e| format!("reference mesh: {e}"))?),
        b => return Err(format!("reference-mesh flag {b} is not 0 or 1")),
    };
    rig.reference_mesh = reference_mesh;
    rig.clips = clips;
    rig.stretch_overrides = StretchOverrides::from_sorted(entries)?;
    Ok(())
}

fn encode_mesh(model: &MeshModel, out: &mut Vec<u8>) {
    out.extend_from_slice(MESH_MAGIC);
    put_len(out, model.materials.len());
    for m in &model.materials {
        put_len(out, m.name.len());
        out.extend_from_slice(m.name.as_bytes());
        put_f32s(out, &m.base_color.to_array());
        out.push(u8::from(m.unlit));
        match &m.base_color_texture {
            Some(t) => {
                out.push(1);
                put_u32(out, t.width);
                put_u32(out, t.height);
                put_len(out, t.rgba8.len());
                out.extend_from_slice(&t.rgba8);
            }
            None => out.push(0),
        }
    }
    put_len(out, model.parts.len());
    for p in &model.parts {
        put_len(out, p.material);
        put_len(out, p.positions.len());
        p.positions
            .iter()
            .for_each(|v| put_f32s(out, &v.to_array()));
        put_len(out, p.normals.len());
        p.normals.iter().for_each(|v| put_f32s(out, &v.to_array()));
        put_len(out, p.uvs.len());
        p.uvs.iter().for_each(|v| put_f32s(out, &v.to_array()));
        put_len(out, p.colors.len());
        p.colors.iter().for_each(|v| put_f32s(out, &v.to_array()));
        put_len(out, p.joints.len());
        for j in &p.joints {
            j.iter()
                .for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
        }
        put_len(out, p.weights.len());
        p.weights.iter().for_each(|w| put_f32s(out, w));
        put_len(out, p.indices.len());
        p.indices.iter().for_each(|&i| put_u32(out, i));
    }
}

fn decode_mesh(bytes: &[u8]) -> Result<MeshModel, String> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(4)? != MESH_MAGIC {
        return Err("bad magic (expected MSH1)".into());
    }
    let mut model = MeshModel::default();
    let n_materials = r.count(22, "material table")?;
    for i in 0..n_materials {
        let name_len = r.count(1, "material name")?;
        let name = String::from_utf8(r.take(name_len)?.to_vec())
            .map_err(|_| format!("material {i}: name is not UTF-8"))?;
        let c = r.floats::<4>(1)?[0];
        let unlit = r.u8()? != 0;
        let base_color_texture = match r.u8()? {
            0 => None,
            _ => {
                let (width, height) = (r.u32()?, r.u32()?);
                let len = r.count(1, "texture")?;
                if u64::from(width) * u64::from(height) * 4 != len as u64 {
                    return Err(format!(
                        "material {i}: texture {width}x{height} does not match its {len} bytes"
                    ));
                }
                Some(Texture {
                    width,
                    height,
                    rgba8: r.take(len)?.to_vec(),
                })
            }
        };
        model.materials.push(Material {
            name,
            base_color: Vec4::from_array(c),
            base_color_texture,
            unlit,
        });
    }
    let n_parts = r.count(32, "part table")?;
    for _ in 0..n_parts {
        let material = r.u32()? as usize;
        let n = r.count(12, "positions")?;
        let positions = r
            .floats::<3>(n)?
            .into_iter()
            .map(Vec3::from_array)
            .collect();
        let n = r.count(12, "normals")?;
        let normals = r
            .floats::<3>(n)?
            .into_iter()
            .map(Vec3::from_array)
            .collect();
        let n = r.count(8, "uvs")?;
        let uvs = r
            .floats::<2>(n)?
            .into_iter()
            .map(Vec2::from_array)
            .collect();
        let n = r.count(16, "colors")?;
        let colors = r
            .floats::<4>(n)?
            .into_iter()
            .map(Vec4::from_array)
            .collect();
        let n = r.count(8, "joints")?;
        let joints = (0..n)
            .map(|_| Ok([r.u16()?, r.u16()?, r.u16()?, r.u16()?]))
            .collect::<Result<Vec<_>, String>>()?;
        let n = r.count(16, "weights")?;
        let weights = r.floats::<4>(n)?;
        let n = r.count(4, "indices")?;
        let indices = (0..n).map(|_| r.u32()).collect::<Result<Vec<_>, _>>()?;
        model.parts.push(TriangleMesh {
            positions,
            normals,
            uvs,
            colors,
            joints,
            weights,
            indices,
            material,
        });
    }
    if r.remaining() != 0 {
        return Err(format!(
            "{} unexpected bytes after the last part",
            r.remaining()
        ));
    }
    model
        .validate()
        .map_err(|(part, e)| format!("part {part}: {e}"))?;
    Ok(model)
}

#[cfg(test)]
mod crash_tests;
mod save;
#[cfg(test)]
mod tests;

//! The `.vox` chunk structure: a validator that runs before `dot_vox` and a writer for export.
//!
//! A file is `"VOX "`, a `u32` version, then one `MAIN` chunk whose children are the content.
//! Every chunk is `id[4]`, `content_bytes: u32`, `children_bytes: u32`, content, children
//! (little-endian). Dictionaries are `count: u32` then `count` pairs of strings, each
//! `len: u32` + bytes.

use std::collections::HashMap;
use std::path::Path;

use super::{MAX_MODEL_EDGE, VoxError, malformed};

/// What the validator learnt that `dot_vox` does not keep.
#[derive(Debug, Default)]
pub(crate) struct Layout {
    /// Model sizes in file order (`SIZE` of each `XYZI`).
    pub(crate) model_sizes: Vec<[u32; 3]>,
    /// Voxels declared by all `XYZI` chunks.
    pub(crate) total_voxels: u64,
    /// Scene node id → index in file order (= index in `dot_vox`'s `scenes`).
    pub(crate) node_index: HashMap<u32, usize>,
    /// Node ids in file order.
    pub(crate) node_ids: Vec<u32>,
    /// Whether an `RGBA` chunk was present.
    pub(crate) has_palette: bool,
    /// Number of `MATL` chunks.
    pub(crate) materials: usize,
    /// Number of `LAYR` chunks.
    pub(crate) layers: usize,
}

/// A bounds-checked little-endian reader over one chunk's content.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn u32(&mut self, what: &str) -> Result<u32, String> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], String> {
        if n > self.remaining() {
            return Err(format!(
                "{what} needs {n} bytes at offset {} but only {} remain",
                self.pos,
                self.remaining()
            ));
        }
        let out = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    fn string(&mut self, what: &str) -> Result<&'a str, String> {
        let len = self.u32(what)? as usize;
        let b = self.take(len, what)?;
        std::str::from_utf8(b).map_err(|_| format!("{what} is not UTF-8 text"))
    }

    /// Checks a dictionary's structure; returns the value of `key` if present.
    fn dict(&mut self, what: &str, key: &str) -> Result<Option<&'a str>, String> {
        let n = self.u32(what)? as usize;
        // Each entry is at least two empty strings (8 bytes).
        if n > self.remaining() / 8 {
            return Err(format!(
                "{what} declares {n} entries but only {} bytes remain",
                self.remaining()
            ));
        }
        let mut found = None;
        for i in 0..n {
            // Context strings are built only on failure: validation runs on every import.
            let k = self
                .string("key")
                .map_err(|e| format!("{what} entry {i}: {e}"))?;
            let v = self
                .string("value")
                .map_err(|e| format!("{what} entry {i}: {e}"))?;
            if k == key {
                found = Some(v);
            }
        }
        Ok(found)
    }

    /// A `count: u32` of items at least `min_item_bytes` long each, checked against what remains.
    fn count(&mut self, what: &str, min_item_bytes: usize) -> Result<usize, String> {
        let n = self.u32(what)? as usize;
        if n > self.remaining() / min_item_bytes {
            return Err(format!(
                "{what} declares {n} items of at least {min_item_bytes} bytes but only {} bytes remain",
                self.remaining()
            ));
        }
        Ok(n)
    }
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Escapes up to `n` bytes for an error message.
pub(crate) fn escape_prefix(bytes: &[u8], n: usize) -> String {
    let shown = &bytes[..bytes.len().min(n)];
    format!("\"{}\"", shown.escape_ascii())
}

/// Walks the whole chunk structure and every chunk `dot_vox` will interpret, checking each
/// declared size against the bytes that remain, model sizes against [`MAX_MODEL_EDGE`], voxel
/// coordinates against their model's size, and node ids for uniqueness.
pub(crate) fn validate(bytes: &[u8], path: &Path) -> Result<Layout, VoxError> {
    if bytes.is_empty() {
        return Err(malformed(path, "file", "the file is empty (0 bytes)"));
    }
    if bytes.len() < 4 || &bytes[..4] != b"VOX " {
        if b"VOX ".starts_with(bytes) {
            return Err(malformed(
                path,
                "header",
                format!(
                    "the file ends after {} bytes, inside the magic",
                    bytes.len()
                ),
            ));
        }
        return Err(VoxError::NotVox {
            path: path.to_owned(),
            found: escape_prefix(bytes, 8),
        });
    }
    if bytes.len() < 20 {
        return Err(malformed(
            path,
            "header",
            format!(
                "the file is {} bytes; the header and MAIN chunk header need 20",
                bytes.len()
            ),
        ));
    }
    if &bytes[8..12] != b"MAIN" {
        return Err(malformed(
            path,
            "chunk at byte 8",
            format!(
                "expected the MAIN chunk, found {}",
                escape_prefix(&bytes[8..12], 4)
            ),
        ));
    }
    let main_content = le_u32(bytes, 12) as usize;
    let main_children = le_u32(bytes, 16) as usize;
    let after_header = bytes.len() - 20;
    if main_content > after_header || main_children > after_header - main_content {
        return Err(malformed(
            path,
            "MAIN chunk at byte 8",
            format!(
                "declares {main_content} content bytes and {main_children} children bytes but \
                 only {after_header} bytes follow its header (truncated or inflated)"
            ),
        ));
    }
    let start = 20 + main_content;
    walk_children(bytes, start, start + main_children, path)
}

fn walk_children(bytes: &[u8], start: usize, end: usize, path: &Path) -> Result<Layout, VoxError> {
    let mut layout = Layout::default();
    let mut current_size: Option<[u32; 3]> = None;
    let mut pos = start;
    while pos < end {
        let left = end - pos;
        if left < 12 {
            return Err(malformed(
                path,
                format!("chunk header at byte {pos}"),
                format!("needs 12 bytes but MAIN's children end {left} bytes later (truncated)"),
            ));
        }
        let id_bytes = &bytes[pos..pos + 4];
        if !id_bytes.iter().all(|b| b.is_ascii_graphic() || *b == b' ') {
            return Err(malformed(
                path,
                format!("chunk header at byte {pos}"),
                format!(
                    "chunk id {} is not text (corrupt structure)",
                    escape_prefix(id_bytes, 4)
                ),
            ));
        }
        let id = std::str::from_utf8(id_bytes).unwrap_or("????");
        let content_len = le_u32(bytes, pos + 4) as usize;
        let children_len = le_u32(bytes, pos + 8) as usize;
        let body = left - 12;
        let model = layout.model_sizes.len();
        let at = match id {
            "SIZE" | "XYZI" => format!("chunk {id} of model {model} at byte {pos}"),
            _ => format!("chunk {id} at byte {pos}"),
        };
        if content_len > body || children_len > body - content_len {
            return Err(malformed(
                path,
                at,
                format!(
                    "declares {content_len} content bytes and {children_len} children bytes but \
                     only {body} bytes remain in MAIN (truncated or inflated)"
                ),
            ));
        }
        let content = &bytes[pos + 12..pos + 12 + content_len];
        let known = matches!(
            id,
            "SIZE" | "XYZI" | "RGBA" | "MATL" | "nTRN" | "nGRP" | "nSHP" | "LAYR"
        );
        if known && children_len != 0 {
            // dot_vox would turn such a chunk into "unknown" and drop it silently.
            return Err(malformed(
                path,
                at,
                format!("has {children_len} children bytes; this chunk type has none"),
            ));
        }
        if !known && children_len != 0 {
            // dot_vox parses unknown chunks' children recursively: deep nesting in a small
            // file would overflow the stack (an abort, which `catch_unwind` cannot stop).
            let children = &bytes[pos + 12 + content_len..pos + 12 + content_len + children_len];
            nesting_within(children, 1).map_err(|detail| malformed(path, &at, detail))?;
        }
        let mut c = Cursor::new(content);
        let checked: Result<(), String> = match id {
            "MAIN" => Err("a second MAIN chunk inside MAIN".into()),
            "SIZE" => c.take(12, "SIZE content").and_then(|_| {
                let s = [le_u32(content, 0), le_u32(content, 4), le_u32(content, 8)];
                if s.iter().any(|&e| e == 0 || e > MAX_MODEL_EDGE) {
                    Err(format!(
                        "model size {} × {} × {} is outside 1..={MAX_MODEL_EDGE} per axis",
                        s[0], s[1], s[2]
                    ))
                } else {
                    current_size = Some(s);
                    Ok(())
                }
            }),
            "XYZI" => check_xyzi(&mut c, current_size).map(|(size, n)| {
                layout.model_sizes.push(size);
                layout.total_voxels += n;
            }),
            "RGBA" => {
                layout.has_palette = true;
                if content.len() == 1024 {
                    Ok(())
                } else {
                    Err(format!(
                        "the palette is {} bytes; it must be 256 colours × 4 bytes = 1024",
                        content.len()
                    ))
                }
            }
            "MATL" => {
                layout.materials += 1;
                c.u32("material id")
                    .and_then(|_| c.dict("material properties", "_type"))
                    .map(|_| ())
            }
            "LAYR" => {
                layout.layers += 1;
                c.u32("layer id")
                    .and_then(|_| c.dict("layer attributes", ""))
                    .and_then(|_| c.u32("layer reserved field"))
                    .map(|_| ())
            }
            "nTRN" | "nGRP" | "nSHP" => check_node(id, &mut c).and_then(|node_id| {
                let index = layout.node_ids.len();
                if layout.node_index.insert(node_id, index).is_some() {
                    Err(format!("node id {node_id} is used twice"))
                } else {
                    layout.node_ids.push(node_id);
                    Ok(())
                }
            }),
            _ => Ok(()),
        };
        checked.map_err(|detail| malformed(path, at, detail))?;
        pos += 12 + content_len + children_len;
    }
    Ok(layout)
}

/// Deepest nesting of chunks inside MAIN's children that is accepted (MagicaVoxel writes none).
const MAX_NESTING: usize = 4;

/// Checks that chunks nested in `children` (as dot_vox will parse them) stay within
/// [`MAX_NESTING`] levels. Malformed nested chunks are fine: dot_vox stops at them.
fn nesting_within(children: &[u8], depth: usize) -> Result<(), String> {
    if depth > MAX_NESTING {
        return Err(format!(
            "chunks are nested more than {MAX_NESTING} levels deep"
        ));
    }
    let mut pos = 0;
    while children.len() - pos >= 12 {
        let content = le_u32(children, pos + 4) as usize;
        let nested = le_u32(children, pos + 8) as usize;
        let body = children.len() - pos - 12;
        if content > body || nested > body - content {
            break;
        }
        if nested != 0 {
            let start = pos + 12 + content;
            nesting_within(&children[start..start + nested], depth + 1)?;
        }
        pos += 12 + content + nested;
    }
    Ok(())
}

/// Checks an `XYZI` chunk; returns the size it uses and its voxel count.
fn check_xyzi(c: &mut Cursor<'_>, size: Option<[u32; 3]>) -> Result<([u32; 3], u64), String> {
    let size = size.ok_or("XYZI comes before any SIZE chunk")?;
    let n = c.u32("voxel count")? as usize;
    if n > c.remaining() / 4 {
        return Err(format!(
            "declares {n} voxels but only {} bytes remain (room for {})",
            c.remaining(),
            c.remaining() / 4
        ));
    }
    let data = c.take(n * 4, "voxels")?;
    for (i, v) in data.chunks_exact(4).enumerate() {
        if u32::from(v[0]) >= size[0] || u32::from(v[1]) >= size[1] || u32::from(v[2]) >= size[2] {
            return Err(format!(
                "voxel {i} at ({}, {}, {}) lies outside the model's size {} × {} × {}",
                v[0], v[1], v[2], size[0], size[1], size[2]
            ));
        }
    }
    Ok((size, n as u64))
}

/// Checks a scene node's structure; returns its id.
fn check_node(id: &str, c: &mut Cursor<'_>) -> Result<u32, String> {
    let node_id = c.u32("node id")?;
    check_node_body(id, c).map_err(|e| format!("node {node_id}: {e}"))?;
    Ok(node_id)
}

fn check_node_body(id: &str, c: &mut Cursor<'_>) -> Result<(), String> {
    c.dict("attributes", "")?;
    match id {
        "nTRN" => {
            c.u32("child id")?;
            c.u32("reserved id")?;
            c.u32("layer id")?;
            let frames = c.count("frame count", 4)?;
            if frames == 0 {
                return Err("a transform needs at least one frame".into());
            }
            for f in 0..frames {
                let rotation = c
                    .dict("frame", "_r")
                    .map_err(|e| format!("frame {f}: {e}"))?;
                if let Some(r) = rotation {
                    let byte: u8 = r
                        .trim()
                        .parse()
                        .map_err(|_| format!("frame {f}: rotation _r {r:?} is not a byte"))?;
                    if super::decode_rotation(byte).is_none() {
                        return Err(format!(
                            "frame {f}: rotation _r {byte} is not a signed permutation"
                        ));
                    }
                }
            }
            // `_t` is re-read (and its syntax checked) when the graph is applied.
        }
        "nGRP" => {
            let n = c.count("child count", 4)?;
            c.take(n * 4, "children")?;
        }
        _ => {
            let n = c.count("model count", 8)?;
            if n == 0 {
                return Err("a shape needs at least one model".into());
            }
            for m in 0..n {
                c.u32("model id")?;
                c.dict("model attributes", "")
                    .map_err(|e| format!("model {m}: {e}"))?;
            }
        }
    }
    Ok(())
}

/// Appends one chunk (no children).
pub(crate) fn write_chunk(out: &mut Vec<u8>, id: &[u8; 4], content: &[u8]) {
    out.extend_from_slice(id);
    out.extend_from_slice(&(content.len() as u32).to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(content);
}

/// Appends a string (`len: u32` + bytes).
pub(crate) fn write_string(out: &mut Vec<u8>, s: &str) {
    out.extend_from_slice(&(s.len() as u32).to_le_bytes());
    out.extend_from_slice(s.as_bytes());
}

/// Appends a dictionary in the given (deterministic) order.
pub(crate) fn write_dict(out: &mut Vec<u8>, entries: &[(&str, &str)]) {
    out.extend_from_slice(&(entries.len() as u32).to_le_bytes());
    for (k, v) in entries {
        write_string(out, k);
        write_string(out, v);
    }
}

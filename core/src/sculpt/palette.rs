//! Palettes: a model's colours, colour replacement, and palette files (GIMP `.gpl`, PNG strips,
//! the `RGBA` chunk of a MagicaVoxel `.vox`).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::Cursor;
use std::path::Path;

use super::shapes::{Mask, ToolEdit};
use crate::svo::{Svo, Voxel};

/// Most entries a palette file may hold.
pub const MAX_PALETTE_ENTRIES: usize = 4096;

/// Largest palette file read (a `.vox` carries its models too).
pub const MAX_PALETTE_FILE_BYTES: u64 = 256 << 20;

/// Why a palette could not be read or written.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PaletteError {
    /// A `.gpl` line that is not what the format allows.
    #[error("{file}: line {line}: {detail}")]
    Gpl {
        /// The file (or `(text)`).
        file: String,
        /// 1-based line number.
        line: usize,
        /// What was expected and what was found.
        detail: String,
    },
    /// Bytes that are not a usable palette image or `.vox`.
    #[error("{file}: {detail}")]
    Binary {
        /// The file (or `(bytes)`).
        file: String,
        /// What is wrong, with the byte offset where it is known.
        detail: String,
    },
    /// Reading or writing the file failed.
    #[error("{file}: {detail}")]
    Io {
        /// The file.
        file: String,
        /// The OS error.
        detail: String,
    },
    /// A file extension that is not a palette format.
    #[error("{file}: unknown palette format; expected a .gpl, .png or .vox file ({action})")]
    UnknownFormat {
        /// The file.
        file: String,
        /// "load" or "save" (saving supports .gpl and .png).
        action: &'static str,
    },
}

impl PaletteError {
    fn with_file(self, path: &Path) -> Self {
        let f = path.display().to_string();
        match self {
            Self::Gpl { line, detail, .. } => Self::Gpl {
                file: f,
                line,
                detail,
            },
            Self::Binary { detail, .. } => Self::Binary { file: f, detail },
            Self::Io { detail, .. } => Self::Io { file: f, detail },
            Self::UnknownFormat { action, .. } => Self::UnknownFormat { file: f, action },
        }
    }
}

fn binary(detail: impl Into<String>) -> PaletteError {
    PaletteError::Binary {
        file: "(bytes)".into(),
        detail: detail.into(),
    }
}

/// Distinct colours of the model with their voxel counts: most used first, then by colour.
#[must_use]
pub fn model_colors(svo: &Svo) -> Vec<([u8; 4], u64)> {
    let mut counts: HashMap<[u8; 4], u64> = HashMap::new();
    // A tile counts all its voxels at once (the palette panel runs this after each edit).
    // Interior voxels have no colour of their own (they show their nearest surface's).
    svo.for_each_run(|_, height, v| {
        if !v.is_interior() {
            *counts.entry(v.color).or_insert(0) += 1 << (3 * u32::from(height));
        }
    });
    let mut out: Vec<([u8; 4], u64)> = counts.into_iter().collect();
    out.sort_unstable_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    out
}

/// Recolours every voxel of colour `from` (RGBA) to `to`; with a mask only selected voxels.
/// Interior voxels are never recoloured (they take their colour when exposed).
/// Normals and occupancy are untouched.
pub fn replace_color(svo: &mut Svo, from: [u8; 4], to: [u8; 4], mask: Mask) -> ToolEdit {
    let mut edit = ToolEdit::default();
    if from == to {
        return edit;
    }
    let (lo, hi) = match mask {
        Some(sel) => match sel.bounds() {
            Some(b) => b,
            None => return edit,
        },
        None => (glam::UVec3::ZERO, glam::UVec3::splat(svo.extent() - 1)),
    };
    let r = svo.edit_existing(lo, hi, |c, v| {
        Some(if v.color == from && mask.is_none_or(|s| s.contains(c)) {
            Voxel { color: to, ..v }
        } else {
            v
        })
    });
    if let Ok(r) = r {
        edit.absorb(r);
    }
    edit
}

/// Parses a GIMP palette: the `GIMP Palette` header, optional `Name:`, `Columns:` and
/// `Channels: RGBA` lines, `#` comments, then one colour per line (`r g b`, or `r g b a` with
/// `Channels: RGBA`, each 0–255, optionally followed by a name). Alpha is 255 without it.
///
/// # Errors
/// [`PaletteError::Gpl`] naming the first bad line and what it expected.
pub fn parse_gpl(text: &str) -> Result<Vec<[u8; 4]>, PaletteError> {
    let err = |line: usize, detail: String| PaletteError::Gpl {
        file: "(text)".into(),
        line,
        detail,
    };
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
    let header = lines.by_ref().find(|(_, l)| !l.trim().is_empty());
    match header {
        Some((_, l)) if l.trim_start_matches('\u{feff}').trim() == "GIMP Palette" => {}
        Some((n, l)) => {
            return Err(err(
                n,
                format!("expected the header \"GIMP Palette\", found {:?}", clip(l)),
            ));
        }
        None => {
            return Err(err(
                1,
                "empty file; expected the header \"GIMP Palette\"".into(),
            ));
        }
    }
    let mut channels = 3;
    let mut out = Vec::new();
    for (n, raw) in lines {
        let l = raw.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        if let Some(v) = l.strip_prefix("Channels:") {
            channels = match v.trim() {
                "RGB" => 3,
                "RGBA" => 4,
                other => {
                    return Err(err(
                        n,
                        format!("expected Channels: RGB or RGBA, found {other:?}"),
                    ));
                }
            };
            continue;
        }
        if l.starts_with("Name:") || l.starts_with("Columns:") {
            continue;
        }
        let mut words = l.split_whitespace();
        let mut c = [0u8, 0, 0, 255];
        for (k, ch) in ["red", "green", "blue", "alpha"][..channels]
            .iter()
            .enumerate()
        {
            let w = words.next().ok_or_else(|| {
                err(
                    n,
                    format!(
                        "expected {channels} numbers 0-255 ({}), found only {k} in {:?}",
                        if channels == 4 {
                            "red green blue alpha"
                        } else {
                            "red green blue"
                        },
                        clip(l)
                    ),
                )
            })?;
            c[k] = w.parse::<u8>().map_err(|_| {
                err(
                    n,
                    format!("{ch} must be a whole number 0-255, found {:?}", clip(w)),
                )
            })?;
        }
        if out.len() == MAX_PALETTE_ENTRIES {
            return Err(err(
                n,
                format!("more than {MAX_PALETTE_ENTRIES} colours; split the palette"),
            ));
        }
        out.push(c);
    }
    Ok(out)
}

/// At most 40 characters of `s`, for error messages.
fn clip(s: &str) -> String {
    s.chars().take(40).collect()
}

/// A GIMP palette of `colors` named `name` (line breaks removed); `Channels: RGBA` with a
/// fourth column when any colour is not opaque.
#[must_use]
pub fn write_gpl(name: &str, colors: &[[u8; 4]]) -> String {
    let name: String = name.chars().filter(|c| !c.is_control()).collect();
    let rgba = colors.iter().any(|c| c[3] != 255);
    let mut s = format!("GIMP Palette\nName: {name}\nColumns: 16\n");
    if rgba {
        s.push_str("Channels: RGBA\n");
    }
    s.push_str("#\n");
    for c in colors {
        let _ = write!(s, "{:3} {:3} {:3}", c[0], c[1], c[2]);
        if rgba {
            let _ = write!(s, " {:3}", c[3]);
        }
        let _ = writeln!(s, "\t#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
    }
    s
}

/// Colours of a palette PNG: each pixel of the first row (MagicaVoxel's 256×1 strips), at most
/// 256 entries; images up to 256×256 pixels.
///
/// # Errors
/// [`PaletteError::Binary`]: not a PNG (naming the bytes found), undecodable, or too large.
pub fn palette_from_png(bytes: &[u8]) -> Result<Vec<[u8; 4]>, PaletteError> {
    const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
    if bytes.len() < 8 || bytes[..8] != SIGNATURE {
        let n = bytes.len().min(8);
        return Err(binary(format!(
            "not a PNG file: bytes 0..{n} are {:02x?}, a PNG starts with {SIGNATURE:02x?}",
            &bytes[..n]
        )));
    }
    crate::mesh::check_png_chunks(bytes).map_err(binary)?;
    let mut reader = image::ImageReader::with_format(Cursor::new(bytes), image::ImageFormat::Png);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(256);
    limits.max_image_height = Some(256);
    limits.max_alloc = Some(16 << 20);
    reader.limits(limits);
    let img = crate::mesh::decode_contained(|| reader.decode())
        .map_err(|e| {
            binary(format!(
                "cannot decode the PNG (at most 256×256 pixels): {e}"
            ))
        })?
        .to_rgba8();
    Ok((0..img.width()).map(|x| img.get_pixel(x, 0).0).collect())
}

/// An N×1 RGBA PNG strip of `colors` (an empty palette gives one transparent pixel, since a PNG
/// cannot be zero pixels wide).
#[must_use]
pub fn palette_to_png(colors: &[[u8; 4]]) -> Vec<u8> {
    let strip: Vec<[u8; 4]> = if colors.is_empty() {
        vec![[0; 4]]
    } else {
        colors.to_vec()
    };
    let img =
        image::RgbaImage::from_fn(strip.len() as u32, 1, |x, _| image::Rgba(strip[x as usize]));
    let mut out = Cursor::new(Vec::new());
    // Encoding an in-memory RGBA8 image cannot fail short of running out of memory.
    let _ = img.write_to(&mut out, image::ImageFormat::Png);
    out.into_inner()
}

/// The 255 usable colours of a `.vox` file's `RGBA` chunk (entry `i` is colour index `i + 1`;
/// MagicaVoxel's default palette when the file has none), read through the hardened `.vox`
/// importer so a hostile file cannot get past its checks.
///
/// # Errors
/// [`PaletteError::Binary`] with the importer's message (which names the byte offset).
pub fn palette_from_vox(bytes: &[u8]) -> Result<Vec<[u8; 4]>, PaletteError> {
    let scene = crate::io::vox::import_vox_bytes(
        bytes,
        Path::new("(bytes)"),
        &crate::io::vox::VoxImportOptions::default(),
    )
    .map_err(|e| binary(e.to_string()))?;
    Ok(scene.palette)
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Reads a palette file by extension: `.gpl`, `.png` or `.vox`.
///
/// # Errors
/// Any [`PaletteError`], naming `path`.
pub fn load_palette(path: &Path) -> Result<Vec<[u8; 4]>, PaletteError> {
    let ext = extension(path);
    if !matches!(ext.as_str(), "gpl" | "png" | "vox") {
        return Err(PaletteError::UnknownFormat {
            file: path.display().to_string(),
            action: "load",
        });
    }
    let io = |e: std::io::Error| PaletteError::Io {
        file: path.display().to_string(),
        detail: e.to_string(),
    };
    let len = std::fs::metadata(path).map_err(io)?.len();
    if len > MAX_PALETTE_FILE_BYTES {
        return Err(PaletteError::Binary {
            file: path.display().to_string(),
            detail: format!("{len} bytes; a palette file may be at most {MAX_PALETTE_FILE_BYTES}"),
        });
    }
    let bytes = std::fs::read(path).map_err(io)?;
    let r = match ext.as_str() {
        "gpl" => match std::str::from_utf8(&bytes) {
            Ok(text) => parse_gpl(text),
            Err(e) => Err(binary(format!(
                "not UTF-8 text: invalid byte at offset {}",
                e.valid_up_to()
            ))),
        },
        "png" => palette_from_png(&bytes),
        _ => palette_from_vox(&bytes),
    };
    r.map_err(|e| e.with_file(path))
}

/// Writes `colors` as a `.gpl` (named after the file) or `.png` strip, by extension.
///
/// # Errors
/// [`PaletteError::UnknownFormat`] for other extensions, [`PaletteError::Io`].
pub fn save_palette(path: &Path, colors: &[[u8; 4]]) -> Result<(), PaletteError> {
    let bytes = match extension(path).as_str() {
        "gpl" => {
            let name = path
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("palette");
            write_gpl(name, colors).into_bytes()
        }
        "png" => palette_to_png(colors),
        _ => {
            return Err(PaletteError::UnknownFormat {
                file: path.display().to_string(),
                action: "save",
            });
        }
    };
    std::fs::write(path, bytes).map_err(|e| PaletteError::Io {
        file: path.display().to_string(),
        detail: e.to_string(),
    })
}

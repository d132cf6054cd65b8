//! Triangle meshes shared by the importers, the voxelizer, skinning and the renderers.
//!
//! A [`MeshModel`] is what an importer produces: triangle lists ([`TriangleMesh`], one per glTF
//! primitive or OBJ group) that index into a shared material table. Vertex attributes are
//! parallel arrays; an optional attribute is an empty `Vec`, never a vector of defaults, so a
//! mesh only stores what the source file had.

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use serde::{Deserialize, Serialize};

/// Largest coordinate a mesh position may have: cameras, bounds and voxelization square and sum
/// distances in f32, which stays finite up to about 1.8e19 (the same bound as
/// [`crate::scene::MAX_KRS_MAGNITUDE`]).
pub const MAX_POSITION: f32 = 1e18;

/// Why a mesh cannot be used as it is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The index list is not a whole number of triangles.
    #[error("index count {0} is not a multiple of 3")]
    RaggedIndices(usize),
    /// An index points past the vertex arrays.
    #[error("index {index} at position {at} is out of range for {vertices} vertices")]
    IndexOutOfRange {
        /// The offending index value.
        index: u32,
        /// Its position in the index list.
        at: usize,
        /// Number of vertices.
        vertices: usize,
    },
    /// An optional attribute array has a different length from `positions`.
    #[error("attribute {name} has {len} entries but there are {vertices} vertices")]
    AttributeLength {
        /// Attribute name (`normals`, `uvs`, …).
        name: &'static str,
        /// Its length.
        len: usize,
        /// Number of vertices.
        vertices: usize,
    },
    /// A position is NaN or infinite.
    #[error("vertex {0} has a non-finite position")]
    NonFinite(usize),
    /// A position is so far from the origin that squared distances would overflow f32.
    #[error(
        "vertex {vertex} lies at {position:?}, beyond ±{MAX_POSITION:e} units where squared distances overflow; scale the model down before importing"
    )]
    TooFar {
        /// The vertex.
        vertex: usize,
        /// Its position.
        position: [f32; 3],
    },
    /// The material index is past the material table.
    #[error("material index {index} is out of range for {count} materials")]
    MaterialOutOfRange {
        /// The index.
        index: usize,
        /// Number of materials.
        count: usize,
    },
}

/// An RGBA8 image in sRGB, for base-colour textures.
#[derive(Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Texture {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height * 4` bytes, rows top to bottom, sRGB-encoded RGBA.
    pub rgba8: Vec<u8>,
}

impl std::fmt::Debug for Texture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Texture({}x{})", self.width, self.height)
    }
}

/// sRGB-encoded channel (0–1) to linear.
#[must_use]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// [`srgb_to_linear`] of an 8-bit channel (`v / 255`), from a 256-entry table: octree merges
/// and the enhancer convert every child colour, and `powf` dominated them. Same values as the
/// function, so results do not change.
#[must_use]
pub fn srgb_byte_to_linear(v: u8) -> f32 {
    static TABLE: std::sync::LazyLock<[f32; 256]> =
        std::sync::LazyLock::new(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)));
    TABLE[usize::from(v)]
}

/// `round(linear_to_srgb(c) * 255)` without `powf`: a binary search over the 255 linear values
/// halfway between sRGB bytes. May differ from the `powf` route by one where `c` lies within
/// float rounding of a midpoint; every byte round-trips through [`srgb_byte_to_linear`]. NaN
/// maps to 0.
#[must_use]
pub fn linear_to_srgb_byte(c: f32) -> u8 {
    static MIDPOINTS: std::sync::LazyLock<[f32; 255]> = std::sync::LazyLock::new(|| {
        std::array::from_fn(|i| srgb_to_linear((i as f32 + 0.5) / 255.0))
    });
    if c.is_nan() {
        return 0;
    }
    MIDPOINTS.partition_point(|&m| m <= c) as u8
}

/// Linear channel (0–1) to sRGB-encoded.
#[must_use]
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

impl Texture {
    /// Whether it has texels to sample: a non-empty size with at least the bytes it says
    /// ([`Texture::sample_linear`] returns white for any other).
    #[must_use]
    pub fn is_sampleable(&self) -> bool {
        // In u64: width × height × 4 overflows u32 for sizes a hand-built texture can claim.
        self.width > 0
            && self.height > 0
            && self.rgba8.len() as u64 >= u64::from(self.width) * u64::from(self.height) * 4
    }

    /// Bilinear sample with repeat wrapping, returned as linear RGBA. UV (0,0) is the top-left
    /// corner of the image, as in glTF; texel centres lie at half-integer texel coordinates.
    /// White for an empty texture, one with fewer bytes than its size says, or a non-finite
    /// UV. The GPU renderer's resolve pass (`shaders/resolve.wgsl`) repeats this arithmetic.
    #[must_use]
    pub fn sample_linear(&self, uv: Vec2) -> Vec4 {
        if !self.is_sampleable() {
            return Vec4::ONE;
        }
        let u = uv.x - uv.x.floor();
        let v = uv.y - uv.y.floor();
        if !u.is_finite() || !v.is_finite() {
            return Vec4::ONE;
        }
        let x = u * self.width as f32 - 0.5;
        let y = v * self.height as f32 - 0.5;
        let x0 = x.floor();
        let y0 = y.floor();
        let fx = x - x0;
        let fy = y - y0;
        let texel = |xi: i64, yi: i64| -> Vec4 {
            let xi = xi.rem_euclid(i64::from(self.width)) as usize;
            let yi = yi.rem_euclid(i64::from(self.height)) as usize;
            let o = (yi * self.width as usize + xi) * 4;
            let p = &self.rgba8[o..o + 4];
            Vec4::new(
                srgb_to_linear(f32::from(p[0]) / 255.0),
                srgb_to_linear(f32::from(p[1]) / 255.0),
                srgb_to_linear(f32::from(p[2]) / 255.0),
                f32::from(p[3]) / 255.0,
            )
        };
        let (xi, yi) = (x0 as i64, y0 as i64);
        let top = texel(xi, yi).lerp(texel(xi + 1, yi), fx);
        let bottom = texel(xi, yi + 1).lerp(texel(xi + 1, yi + 1), fx);
        top.lerp(bottom, fy)
    }
}

/// A surface material, reduced to what voxels and previews use.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Material {
    /// Display name.
    pub name: String,
    /// Linear RGBA base colour factor.
    pub base_color: Vec4,
    /// Optional base-colour texture, multiplied with `base_color`.
    pub base_color_texture: Option<Texture>,
    /// `KHR_materials_unlit`: shade with the base colour alone.
    pub unlit: bool,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            name: String::new(),
            base_color: Vec4::ONE,
            base_color_texture: None,
            unlit: false,
        }
    }
}

/// One triangle list with optional per-vertex attributes.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex normals, or empty.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates (set 0), or empty.
    pub uvs: Vec<Vec2>,
    /// Per-vertex linear RGBA colours, or empty.
    pub colors: Vec<Vec4>,
    /// Per-vertex joint indices (skin joint table), or empty.
    pub joints: Vec<[u16; 4]>,
    /// Per-vertex joint weights, or empty.
    pub weights: Vec<[f32; 4]>,
    /// Triangle list: three indices per triangle, counter-clockwise front faces.
    pub indices: Vec<u32>,
    /// Index into the owning [`MeshModel::materials`].
    pub material: usize,
}

impl TriangleMesh {
    /// Number of triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The three vertex indices of triangle `t`.
    #[must_use]
    pub fn triangle(&self, t: usize) -> [usize; 3] {
        let i = &self.indices[t * 3..t * 3 + 3];
        [i[0] as usize, i[1] as usize, i[2] as usize]
    }

    /// Checks index ranges, attribute lengths and finiteness.
    ///
    /// # Errors
    /// The first problem found.
    pub fn validate(&self) -> Result<(), MeshError> {
        let n = self.positions.len();
        if !self.indices.len().is_multiple_of(3) {
            return Err(MeshError::RaggedIndices(self.indices.len()));
        }
        for (at, &index) in self.indices.iter().enumerate() {
            if index as usize >= n {
                return Err(MeshError::IndexOutOfRange {
                    index,
                    at,
                    vertices: n,
                });
            }
        }
        let lens: [(&'static str, usize); 5] = [
            ("normals", self.normals.len()),
            ("uvs", self.uvs.len()),
            ("colors", self.colors.len()),
            ("joints", self.joints.len()),
            ("weights", self.weights.len()),
        ];
        for (name, len) in lens {
            if len != 0 && len != n {
                return Err(MeshError::AttributeLength {
                    name,
                    len,
                    vertices: n,
                });
            }
        }
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFinite(i));
        }
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| p.abs().max_element() > MAX_POSITION)
        {
            return Err(MeshError::TooFar {
                vertex: i,
                position: self.positions[i].to_array(),
            });
        }
        Ok(())
    }

    /// Axis-aligned bounds of the positions; `None` when there are none.
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        bounds_of(self.positions.iter().copied())
    }

    /// Area-weighted vertex normals from the triangles (replaces `normals`). Degenerate
    /// triangles contribute nothing; vertices with no area get +Y.
    pub fn compute_normals(&mut self) {
        let mut acc = vec![Vec3::ZERO; self.positions.len()];
        for t in 0..self.triangle_count() {
            let [a, b, c] = self.triangle(t);
            let n = (self.positions[b] - self.positions[a])
                .cross(self.positions[c] - self.positions[a]);
            if n.is_finite() {
                acc[a] += n;
                acc[b] += n;
                acc[c] += n;
            }
        }
        self.normals = acc
            .into_iter()
            .map(|n| n.try_normalize().unwrap_or(Vec3::Y))
            .collect();
    }

    /// Flat normals, as glTF asks of a reader when a primitive has no `NORMAL`: every corner
    /// gets its triangle's face normal, and a vertex whose triangles face different ways is
    /// split: the first way keeps the vertex, each other way gets a copy appended (its other
    /// attributes copied). Triangles that face the same way (to 1e-4) keep sharing their
    /// vertices, so a mesh of flat faces, such as Thicket's cube export, gains copies only where
    /// faces meet at an edge, and a mesh whose vertices each lie on one face keeps its vertices
    /// as they are. Degenerate triangles and vertices no triangle uses take +Y. Replaces
    /// `normals`; positions and triangles are unchanged. At most one vertex per triangle corner
    /// is added (what the glTF reader's up-front count allows for). Indices must be in range
    /// and every non-empty attribute as long as `positions` ([`TriangleMesh::validate`];
    /// readers check both first); a triangle with an index out of range is left as it is.
    pub fn compute_flat_normals(&mut self) {
        use std::collections::HashMap;
        let n = self.positions.len();
        let mut normals = vec![Vec3::Y; n];
        // The way each vertex faces first, and the copies made for other ways.
        let mut first: Vec<Option<[i32; 3]>> = vec![None; n];
        let mut copies: HashMap<(u32, [i32; 3]), u32> = HashMap::new();
        let mut source: Vec<usize> = Vec::new();
        for t in 0..self.triangle_count() {
            let [a, b, c] = self.triangle(t);
            if a >= n || b >= n || c >= n {
                continue;
            }
            let face = (self.positions[b] - self.positions[a])
                .cross(self.positions[c] - self.positions[a])
                .try_normalize()
                .unwrap_or(Vec3::Y);
            let way = (face * 1e4).round().as_ivec3().to_array();
            for at in 3 * t..3 * t + 3 {
                let v = self.indices[at];
                match first[v as usize] {
                    None => {
                        first[v as usize] = Some(way);
                        normals[v as usize] = face;
                    }
                    Some(w) if w == way => {}
                    Some(_) => {
                        let next = (n + source.len()) as u32;
                        let copy = *copies.entry((v, way)).or_insert(next);
                        if copy == next {
                            source.push(v as usize);
                            normals.push(face);
                        }
                        self.indices[at] = copy;
                    }
                }
            }
        }
        fn extend<T: Copy>(v: &mut Vec<T>, source: &[usize]) {
            if !v.is_empty() {
                let copies: Vec<T> = source.iter().map(|&i| v[i]).collect();
                v.extend(copies);
            }
        }
        extend(&mut self.positions, &source);
        extend(&mut self.uvs, &source);
        extend(&mut self.colors, &source);
        extend(&mut self.joints, &source);
        extend(&mut self.weights, &source);
        self.normals = normals;
    }

    /// Applies `world_from_mesh` to positions and its inverse transpose to normals.
    pub fn transform(&mut self, world_from_mesh: Mat4) {
        for p in &mut self.positions {
            *p = world_from_mesh.transform_point3(*p);
        }
        let normal_matrix = Mat3::from_mat4(world_from_mesh).inverse().transpose();
        let mirrored = world_from_mesh.determinant() < 0.0;
        for n in &mut self.normals {
            *n = (normal_matrix * *n).try_normalize().unwrap_or(Vec3::Y);
        }
        if mirrored {
            // A mirroring transform turns counter-clockwise triangles clockwise.
            for tri in self.indices.chunks_exact_mut(3) {
                tri.swap(1, 2);
            }
        }
    }

    /// Total surface area.
    #[must_use]
    pub fn area(&self) -> f64 {
        (0..self.triangle_count())
            .map(|t| {
                let [a, b, c] = self.triangle(t);
                let n = (self.positions[b] - self.positions[a])
                    .cross(self.positions[c] - self.positions[a]);
                f64::from(n.length()) * 0.5
            })
            .sum()
    }

    /// Signed volume enclosed (positive for outward-facing closed meshes).
    #[must_use]
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangle_count())
            .map(|t| {
                let [a, b, c] = self.triangle(t);
                let (a, b, c) = (
                    self.positions[a].as_dvec3(),
                    self.positions[b].as_dvec3(),
                    self.positions[c].as_dvec3(),
                );
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }
}

/// A set of triangle lists and their materials: what an importer returns.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MeshModel {
    /// Triangle lists, already placed in model space by their node transforms (skinned parts are
    /// left in bind-pose mesh space, as glTF skinning ignores the skinned node's transform).
    pub parts: Vec<TriangleMesh>,
    /// Material table indexed by [`TriangleMesh::material`].
    pub materials: Vec<Material>,
}

impl MeshModel {
    /// Total triangles over all parts.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.parts.iter().map(TriangleMesh::triangle_count).sum()
    }

    /// Total vertices over all parts.
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.parts.iter().map(|p| p.positions.len()).sum()
    }

    /// Bounds over all parts.
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        bounds_of(self.parts.iter().flat_map(|p| p.positions.iter().copied()))
    }

    /// Validates every part and its material index.
    ///
    /// # Errors
    /// The first problem found, with the part's index.
    pub fn validate(&self) -> Result<(), (usize, MeshError)> {
        for (i, part) in self.parts.iter().enumerate() {
            part.validate().map_err(|e| (i, e))?;
            if !self.materials.is_empty() && part.material >= self.materials.len() {
                return Err((
                    i,
                    MeshError::MaterialOutOfRange {
                        index: part.material,
                        count: self.materials.len(),
                    },
                ));
            }
        }
        Ok(())
    }

    /// The material of a part, or the default white material.
    #[must_use]
    pub fn material_of(&self, part: &TriangleMesh) -> Material {
        self.materials
            .get(part.material)
            .cloned()
            .unwrap_or_default()
    }

    /// Linear RGBA colour of a surface point: material factor × texture × vertex colour, the
    /// per-vertex values interpolated with barycentric weights `bary` over triangle `t`.
    #[must_use]
    pub fn surface_color(&self, part: &TriangleMesh, t: usize, bary: Vec3) -> Vec4 {
        let [a, b, c] = part.triangle(t);
        let mut color = self
            .materials
            .get(part.material)
            .map_or(Vec4::ONE, |m| m.base_color);
        if let Some(tex) = self
            .materials
            .get(part.material)
            .and_then(|m| m.base_color_texture.as_ref())
            && !part.uvs.is_empty()
        {
            let uv = part.uvs[a] * bary.x + part.uvs[b] * bary.y + part.uvs[c] * bary.z;
            color *= tex.sample_linear(uv);
        }
        if !part.colors.is_empty() {
            color *= part.colors[a] * bary.x + part.colors[b] * bary.y + part.colors[c] * bary.z;
        }
        color
    }
}

pub(crate) fn bounds_of(points: impl Iterator<Item = Vec3>) -> Option<(Vec3, Vec3)> {
    points.fold(None, |acc, p| match acc {
        None => Some((p, p)),
        Some((lo, hi)) => Some((lo.min(p), hi.max(p))),
    })
}

/// A unit cube centred at the origin, 12 triangles, outward faces (for tests and previews).
#[must_use]
pub fn unit_cube() -> TriangleMesh {
    let p = [
        Vec3::new(-0.5, -0.5, -0.5),
        Vec3::new(0.5, -0.5, -0.5),
        Vec3::new(0.5, 0.5, -0.5),
        Vec3::new(-0.5, 0.5, -0.5),
        Vec3::new(-0.5, -0.5, 0.5),
        Vec3::new(0.5, -0.5, 0.5),
        Vec3::new(0.5, 0.5, 0.5),
        Vec3::new(-0.5, 0.5, 0.5),
    ];
    let indices = vec![
        0, 2, 1, 0, 3, 2, // -z
        4, 5, 6, 4, 6, 7, // +z
        0, 1, 5, 0, 5, 4, // -y
        3, 7, 6, 3, 6, 2, // +y
        0, 4, 7, 0, 7, 3, // -x
        1, 2, 6, 1, 6, 5, // +x
    ];
    let mut mesh = TriangleMesh {
        positions: p.to_vec(),
        indices,
        ..TriangleMesh::default()
    };
    mesh.compute_normals();
    mesh
}

/// Checks what the `png` decoder trusts in a PNG's chunks: its palette (`PLTE`) must hold whole
/// RGB entries (3 to 768 bytes, a multiple of 3). The decoder panics on a partial entry instead
/// of refusing it, so every path that decodes a PNG (textures, palettes, reference images)
/// checks first. Bytes that are not a PNG, or end early, pass: the decoder reports those.
///
/// # Errors
/// Where the palette chunk is and what is wrong with it.
pub fn check_png_chunks(bytes: &[u8]) -> Result<(), String> {
    const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
    if bytes.len() < 8 || bytes[..8] != SIGNATURE {
        return Ok(());
    }
    let mut at = 8usize;
    while let Some(head) = bytes.get(at..at + 8) {
        let len = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as usize;
        let kind = &head[4..8];
        if kind == b"PLTE" && !(len.is_multiple_of(3) && (3..=768).contains(&len)) {
            return Err(format!(
                "the PNG's palette (PLTE chunk at byte {at}) is {len} bytes: a palette is 1 to \
                 256 whole RGB entries (3 to 768 bytes, a multiple of 3)"
            ));
        }
        if kind == b"IEND" {
            break;
        }
        // Length, type, data and CRC.
        at = match at.checked_add(12).and_then(|a| a.checked_add(len)) {
            Some(next) => next,
            None => break,
        };
    }
    Ok(())
}

/// Runs an image decode with a panic in the decoder contained: the checks before decoding
/// ([`check_png_chunks`], the header's size against the limit) cover every panic the fuzz
/// targets have found, and should a decoder still panic on a file nobody has tried, the image
/// is refused with a message in words instead of taking the command or the editor down.
///
/// # Errors
/// The decoder's error in words ([`image_error_text`]), or that the decoder failed inside.
pub fn decode_contained<T>(
    decode: impl FnOnce() -> Result<T, image::ImageError>,
) -> Result<T, String> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(decode)) {
        Ok(Ok(t)) => Ok(t),
        Ok(Err(e)) => Err(image_error_text(&e)),
        Err(_) => Err(
            "the image decoder failed on this file (the data is damaged in a way it does not \
             check); re-save the image in an image editor"
                .to_owned(),
        ),
    }
}

/// An image decoder's or encoder's error in words a user can read. The `png` crate writes some
/// errors with Rust debug text (`CRC error … while decoding ChunkType { type: IDAT, critical:
/// true, … } chunk`); every message that reaches the user goes through here, so the kind of
/// failure comes first and the decoder's detail follows with such structures reduced to their
/// names (`… while decoding IDAT chunk`).
#[must_use]
pub fn image_error_text(e: &image::ImageError) -> String {
    use image::ImageError as E;
    use image::error::ImageFormatHint;
    let name = |hint: &ImageFormatHint| match hint {
        ImageFormatHint::Exact(f) => f
            .extensions_str()
            .first()
            .map_or_else(|| "image".to_owned(), |x| x.to_ascii_uppercase()),
        _ => "image".to_owned(),
    };
    let with_detail = |what: String, detail: Option<String>| match detail {
        Some(d) if !d.is_empty() => format!("{what} ({d})"),
        _ => what,
    };
    let cause = |e: &dyn std::error::Error| e.source().map(|s| plain_words(&s.to_string()));
    match e {
        E::IoError(io) => io.to_string(),
        E::Limits(_) => "the image needs more memory than the decoder may use".to_owned(),
        E::Decoding(d) => with_detail(
            format!(
                "the {} data is damaged or cut short",
                name(&d.format_hint())
            ),
            cause(d),
        ),
        E::Encoding(en) => with_detail(
            format!("the {} encoder failed", name(&en.format_hint())),
            cause(en),
        ),
        E::Unsupported(u) => format!(
            "the image uses something the decoder does not support: {}",
            plain_words(&u.to_string())
        ),
        E::Parameter(p) => plain_words(&p.to_string()),
    }
}

/// `text` with Rust debug structures reduced to words: `ChunkType { type: IDAT, critical: true }`
/// becomes `IDAT` (the `type` field, else the structure's name) and `Some(x)` becomes `x`.
fn plain_words(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(open) = rest.find('{') {
        let before = &rest[..open];
        let close = rest[open..]
            .char_indices()
            .scan(0i32, |depth, (i, c)| {
                *depth += match c {
                    '{' => 1,
                    '}' => -1,
                    _ => 0,
                };
                Some((i, *depth))
            })
            .find(|&(_, depth)| depth == 0)
            .map(|(i, _)| open + i);
        let Some(close) = close else {
            out.push_str(before);
            rest = &rest[open + 1..];
            continue;
        };
        let inner = &rest[open + 1..close];
        let head = before.trim_end();
        let ident_start = head
            .rfind(|c: char| !(c.is_alphanumeric() || c == '_'))
            .map_or(0, |i| i + 1);
        let ident = &head[ident_start..];
        let field = inner.split(',').find_map(|f| {
            let (k, v) = f.split_once(':')?;
            (k.trim() == "type").then(|| v.trim().to_owned())
        });
        out.push_str(&head[..ident_start]);
        out.push_str(field.as_deref().unwrap_or(ident));
        rest = &rest[close + 1..];
    }
    out.push_str(rest);
    let mut text = out.replace('}', "");
    while let Some(at) = text.find("Some(") {
        let inner_start = at + "Some(".len();
        match text[inner_start..].find(')') {
            Some(end) => {
                let inner = text[inner_start..inner_start + end].to_owned();
                text.replace_range(at..=inner_start + end, &inner);
            }
            None => text.replace_range(at..inner_start, ""),
        }
    }
    text
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A 2×2 8-bit indexed PNG with `palette` as its PLTE chunk (pixels use indices 0, 200, 255
    /// and 7), CRCs and zlib checksum correct.
    pub(crate) fn indexed_png(palette: &[u8]) -> Vec<u8> {
        fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
            let mut out = (data.len() as u32).to_be_bytes().to_vec();
            out.extend_from_slice(kind);
            out.extend_from_slice(data);
            let mut h = crc32fast::Hasher::new();
            h.update(kind);
            h.update(data);
            out.extend_from_slice(&h.finalize().to_be_bytes());
            out
        }
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        let mut ihdr = 2u32.to_be_bytes().to_vec();
        ihdr.extend_from_slice(&2u32.to_be_bytes());
        ihdr.extend_from_slice(&[8, 3, 0, 0, 0]);
        png.extend(chunk(b"IHDR", &ihdr));
        png.extend(chunk(b"PLTE", palette));
        // Two rows: filter byte 0, then two indices; one stored zlib block.
        let raw = [0u8, 0, 200, 0, 255, 7];
        let mut z = vec![
            0x78,
            0x01,
            0x01,
            raw.len() as u8,
            0,
            !(raw.len() as u8),
            0xff,
        ];
        z.extend_from_slice(&raw);
        let (mut a, mut b) = (1u32, 0u32);
        for &x in &raw {
            a = (a + u32::from(x)) % 65521;
            b = (b + a) % 65521;
        }
        z.extend_from_slice(&((b << 16) | a).to_be_bytes());
        png.extend(chunk(b"IDAT", &z));
        png.extend(chunk(b"IEND", &[]));
        png
    }

    /// A decoder that panics is contained: the image is refused in words, nothing unwinds
    /// further; a decoder error keeps its own words.
    #[test]
    fn a_panicking_decoder_refuses_the_image_instead_of_crashing() {
        let e = decode_contained::<()>(|| panic!("index out of bounds in a decoder")).unwrap_err();
        assert!(
            e.starts_with("the image decoder failed on this file"),
            "{e}"
        );
        let e =
            decode_contained(|| image::load_from_memory(b"\x89PNG\r\n\x1a\nshort")).unwrap_err();
        assert!(e.contains("end of file") && !e.contains("ChunkType"), "{e}");
        let png = indexed_png(&[1, 2, 3]);
        assert!(decode_contained(|| image::load_from_memory(&png)).is_ok());
    }

    #[test]
    fn png_palettes_of_partial_entries_are_refused_before_decoding() {
        // 4 bytes (a partial second entry) panicked inside `png` 0.18; 1..=256 whole entries
        // pass and decode; the other malformed lengths are the decoder's own errors.
        for (palette, refused) in [
            (vec![1u8, 2, 3, 4], true),
            (vec![1, 2, 3, 4, 5], true),
            (vec![9; 770], true),
            (vec![1, 2, 3], false),
            (vec![7; 768], false),
        ] {
            let png = indexed_png(&palette);
            let checked = check_png_chunks(&png);
            assert_eq!(
                checked.is_err(),
                refused,
                "{} bytes: {checked:?}",
                palette.len()
            );
            if !refused {
                let img = image::load_from_memory(&png).expect("decodes");
                assert_eq!((img.width(), img.height()), (2, 2));
            }
        }
        // Not a PNG, or cut short: left to the decoder.
        assert!(check_png_chunks(b"GIF89a").is_ok());
        let png = indexed_png(&[1, 2, 3, 4]);
        assert!(check_png_chunks(&png[..30]).is_ok());
        // Signature, IHDR (25 bytes), then the PLTE chunk's 8-byte header at byte 33.
        assert!(
            check_png_chunks(&png[..41]).is_err(),
            "the PLTE header is enough"
        );
        assert!(check_png_chunks(&png[..40]).is_ok());
    }

    #[test]
    fn image_errors_read_as_words_without_debug_text() {
        // The IDAT chunk's CRC (the 4 bytes before the 12-byte IEND chunk) broken: `png`
        // describes the chunk with its debug text.
        let mut png = indexed_png(&[1, 2, 3]);
        let at = png.len() - 13;
        png[at] ^= 0xff;
        let raw = image::load_from_memory(&png).expect_err("a broken CRC");
        let text = image_error_text(&raw);
        assert!(text.starts_with("the PNG data is damaged"), "{text}");
        assert!(text.contains("IDAT"), "names the chunk: {text}");
        for debug in ["{", "}", "ChunkType", "Some(", "critical"] {
            assert!(!text.contains(debug), "{debug:?} in {text}");
        }
        assert_eq!(
            plain_words(
                "Chunk length wrong: ChunkType { type: fdAT, critical: false, private: true, \
                 reserved: false, safecopy: false } at Some(12)"
            ),
            "Chunk length wrong: fdAT at 12"
        );
        assert_eq!(plain_words("a Limits { max: 3 } b"), "a Limits b");
        assert_eq!(plain_words("open { never closed"), "open  never closed");
        let io = image::ImageError::IoError(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            "No such file or directory",
        ));
        assert_eq!(image_error_text(&io), "No such file or directory");
    }

    #[test]
    fn srgb_byte_tables_match_the_transfer_functions() {
        for b in 0..=255u8 {
            assert_eq!(srgb_byte_to_linear(b), srgb_to_linear(f32::from(b) / 255.0));
            assert_eq!(linear_to_srgb_byte(srgb_byte_to_linear(b)), b);
        }
        // Against the powf route on a fine sweep: equal but for float ties at midpoints.
        let mut differing = 0;
        for i in 0..=100_000 {
            let c = i as f32 / 100_000.0;
            let exact = (linear_to_srgb(c) * 255.0).round() as i32;
            let fast = i32::from(linear_to_srgb_byte(c));
            assert!((exact - fast).abs() <= 1, "{c}: {exact} vs {fast}");
            differing += i32::from(exact != fast);
        }
        assert!(differing < 20, "{differing} of 100001 differ");
        assert_eq!(linear_to_srgb_byte(-1.0), 0);
        assert_eq!(linear_to_srgb_byte(2.0), 255);
        assert_eq!(linear_to_srgb_byte(f32::NAN), 0);
        assert_eq!(linear_to_srgb_byte(f32::INFINITY), 255);
    }

    #[test]
    fn cube_is_closed_with_unit_volume() {
        let cube = unit_cube();
        assert!(cube.validate().is_ok());
        assert!((cube.signed_volume() - 1.0).abs() < 1e-9);
        assert!((cube.area() - 6.0).abs() < 1e-9);
    }

    #[test]
    fn mirroring_transform_keeps_volume_positive() {
        let mut cube = unit_cube();
        cube.transform(Mat4::from_scale(Vec3::new(-2.0, 1.0, 1.0)));
        assert!((cube.signed_volume() - 2.0).abs() < 1e-6);
    }

    #[test]
    fn validation_reports_out_of_range_index() {
        let mut cube = unit_cube();
        cube.indices[5] = 99;
        assert_eq!(
            cube.validate(),
            Err(MeshError::IndexOutOfRange {
                index: 99,
                at: 5,
                vertices: 8
            })
        );
    }

    #[test]
    fn texture_sampling_at_the_extremes() {
        let one = Texture {
            width: 1,
            height: 1,
            rgba8: vec![255, 128, 0, 51],
        };
        let expected = Vec4::new(1.0, srgb_byte_to_linear(128), 0.0, 0.2);
        // A 1×1 texture is its texel everywhere: wrapping, far outside [0, 1], at 2^24 where
        // no fraction is left, and at the largest finite coordinate.
        for uv in [
            Vec2::ZERO,
            Vec2::new(0.5, 0.5),
            Vec2::new(-3.7, 12.25),
            Vec2::splat(16_777_216.0),
            Vec2::new(f32::MAX, -f32::MAX),
        ] {
            assert!(one.sample_linear(uv).abs_diff_eq(expected, 1e-6), "{uv}");
        }
        // Non-finite coordinates, an empty texture, or fewer bytes than the size says: white.
        for uv in [Vec2::new(f32::INFINITY, 0.0), Vec2::new(0.0, f32::NAN)] {
            assert_eq!(one.sample_linear(uv), Vec4::ONE);
        }
        assert_eq!(Texture::default().sample_linear(Vec2::ZERO), Vec4::ONE);
        let overflowing = Texture {
            width: 1 << 16,
            height: 1 << 16,
            rgba8: vec![0; 16],
        };
        assert_eq!(overflowing.sample_linear(Vec2::ZERO), Vec4::ONE);
        // Two texels, black and white: a texel centre is exact, the edge between them (and
        // the wrap-around at u = 0, which meets the last texel) is the mean.
        let two = Texture {
            width: 2,
            height: 1,
            rgba8: vec![0, 0, 0, 255, 255, 255, 255, 255],
        };
        assert_eq!(
            two.sample_linear(Vec2::new(0.25, 0.5)),
            Vec4::new(0.0, 0.0, 0.0, 1.0)
        );
        assert_eq!(two.sample_linear(Vec2::new(0.75, 0.5)), Vec4::ONE);
        for u in [0.5, 0.0, 1.0, -1.0, 7.0] {
            let mid = two.sample_linear(Vec2::new(u, 0.5));
            assert!(
                mid.abs_diff_eq(Vec4::new(0.5, 0.5, 0.5, 1.0), 1e-6),
                "{u}: {mid}"
            );
        }
        // Repeat: a whole period away samples the same value.
        let uv = Vec2::new(0.3, 0.8);
        let shifted = two.sample_linear(uv + Vec2::new(-5.0, 3.0));
        assert!(two.sample_linear(uv).abs_diff_eq(shifted, 1e-5));
    }

    #[test]
    fn srgb_round_trip() {
        for i in 0..=255 {
            let c = f32::from(i as u8) / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5);
        }
    }
}

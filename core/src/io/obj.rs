//! Wavefront OBJ (+ MTL) → [`MeshModel`], parsed by `tobj`.
//!
//! Faces are triangulated (fans) and re-indexed to one index per vertex; points and lines are
//! dropped. Each OBJ object/group × material becomes one part. Materials give the diffuse
//! colour `Kd` (with dissolve `d` as alpha) and the diffuse map `map_Kd`, loaded relative to
//! the `.obj`. Missing normals are computed. OBJ texture coordinates have their origin at the
//! bottom-left of the image; they are flipped (`v → 1 − v`) to the glTF convention that
//! [`crate::mesh::Texture`] uses. A missing `.mtl` or texture file is a warning (OBJ files often
//! name files from their author's machine); a texture that is present but cannot be decoded is
//! an error.
//!
//! Robustness: `tobj` can index out of bounds (and panic) on face indices far outside the
//! vertex arrays, and on colour lines with fewer than three values in an MTL file, so both
//! files are scanned first and such input is refused with the line number.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3, Vec4};

use super::error::{ImportLimits, IoError, read_file_limited};
use super::gltf_mesh::{TextureError, decode_texture};
use crate::mesh::{Material, MeshModel, Texture, TriangleMesh};

/// Reads a file named by an OBJ or MTL (relative to the OBJ): `Ok(None)` when it does not exist.
pub type SideFiles<'f> = dyn Fn(&str) -> Result<Option<Vec<u8>>, IoError> + 'f;

/// OBJ import settings.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ObjOptions {
    /// A diffuse texture for parts whose material has no `map_Kd` (or that have no material):
    /// for OBJ files distributed with a texture but without an `.mtl`, such as Keenan Crane's
    /// Spot. A relative path is relative to the current directory.
    pub default_texture: Option<PathBuf>,
}

/// Imports an `.obj` file with its material library and textures.
///
/// # Errors
/// An [`IoError`] naming the file and the line that is wrong (never a panic).
pub fn import_obj(path: &Path) -> Result<MeshModel, IoError> {
    import_obj_with(path, &ObjOptions::default(), &ImportLimits::default())
}

/// [`import_obj`] with options and limits.
///
/// # Errors
/// See [`import_obj`].
pub fn import_obj_with(
    path: &Path,
    options: &ObjOptions,
    limits: &ImportLimits,
) -> Result<MeshModel, IoError> {
    let bytes = read_file_limited(path, limits)?;
    let base_dir = path
        .parent()
        .unwrap_or_else(|| Path::new("."))
        .to_path_buf();
    let files = move |relative: &str| -> Result<Option<Vec<u8>>, IoError> {
        use super::confine::{RefError, read_reference};
        match read_reference(&base_dir, relative, limits.max_file_bytes) {
            Ok(b) => Ok(Some(b)),
            Err(RefError::Io(_, e)) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            // OBJ files often name files on their author's machine (absolute paths): a
            // reference outside the OBJ's folder is not followed, like a missing file.
            Err(RefError::Refused(why)) => {
                log::warn!("{}: not read: {why}", path.display());
                Ok(None)
            }
            Err(e) => Err(e.into_io_error(path, "referenced file")),
        }
    };
    import_obj_slice_with(&bytes, &files, path, options, limits)
}

/// Imports OBJ bytes. `files` returns the bytes of a file named in the OBJ or MTL (`mtllib`,
/// `map_Kd`), relative to the OBJ, or `None` when it does not exist; pass `&|_| Ok(None)` to
/// keep the importer off the file system. `name` is the path used in error messages.
///
/// # Errors
/// See [`import_obj`].
pub fn import_obj_slice_with(
    bytes: &[u8],
    files: &SideFiles<'_>,
    name: &Path,
    options: &ObjOptions,
    limits: &ImportLimits,
) -> Result<MeshModel, IoError> {
    if bytes.len() as u64 > limits.max_file_bytes {
        return Err(IoError::too_large(
            name,
            format!(
                "file is {} bytes; the limit is {} bytes",
                bytes.len(),
                limits.max_file_bytes
            ),
        ));
    }
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(IoError::truncated(name, "the file is empty"));
    }
    let text = utf8(bytes, name)?;
    check_faces(text, name)?;

    // tobj's material callback cannot return our error, so the first one is kept here.
    let material_error: RefCell<Option<IoError>> = RefCell::new(None);
    let load_mtl = |mtl: &Path| -> tobj::MTLLoadResult {
        let relative = mtl.to_string_lossy();
        let fail = |e: IoError| {
            material_error.borrow_mut().get_or_insert(e);
            Err(tobj::LoadError::MaterialParseError)
        };
        let mtl_bytes = match files(&relative) {
            Ok(Some(b)) => b,
            Ok(None) => {
                log::warn!(
                    "{}: material library '{relative}' not found; using default materials",
                    name.display()
                );
                return Err(tobj::LoadError::OpenFileFailed);
            }
            Err(e) => return fail(e),
        };
        let mtl_name = name.with_file_name(mtl);
        let mtl_text =
            match utf8(&mtl_bytes, &mtl_name).and_then(|t| check_mtl(t, &mtl_name).map(|()| t)) {
                Ok(t) => t,
                Err(e) => return fail(e),
            };
        tobj::load_mtl_buf(&mut std::io::Cursor::new(mtl_text.as_bytes()))
    };
    let load_options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let loaded = tobj::load_obj_buf(
        &mut std::io::Cursor::new(text.as_bytes()),
        &load_options,
        load_mtl,
    );
    if let Some(e) = material_error.into_inner() {
        return Err(e);
    }
    let (models, materials) = loaded.map_err(|e| IoError::parse(name, format!("OBJ: {e}")))?;
    let materials = materials.unwrap_or_else(|e| {
        if e != tobj::LoadError::OpenFileFailed {
            log::warn!(
                "{}: material library not loaded ({e}); using default materials",
                name.display()
            );
        }
        Vec::new()
    });

    let default_texture = match &options.default_texture {
        Some(path) => {
            let encoded = read_file_limited(path, limits)?;
            Some(decode(&encoded, path, limits)?)
        }
        None => None,
    };
    let mut out = MeshModel::default();
    for m in &materials {
        let [r, g, b] = m.diffuse.unwrap_or([1.0; 3]);
        let alpha = m.dissolve.unwrap_or(1.0);
        let base_color = Vec4::new(r, g, b, alpha);
        if !base_color.is_finite() {
            return Err(IoError::invalid(
                name,
                format!("material '{}': Kd or d is not finite", m.name),
            ));
        }
        let texture = match m
            .diffuse_texture
            .as_deref()
            .map(str::trim)
            .filter(|t| !t.is_empty())
        {
            Some(map) => load_map(map, files, name, limits)?,
            None => None,
        };
        out.materials.push(Material {
            name: m.name.clone(),
            base_color,
            base_color_texture: texture.or_else(|| default_texture.clone()),
            unlit: false,
        });
    }
    let default_material = out.materials.len();
    let mut used_default = false;
    let mut total_vertices: u64 = 0;
    for model in models {
        let mesh = model.mesh;
        if mesh.indices.is_empty() {
            continue;
        }
        let vertex_count = mesh.positions.len() / 3;
        total_vertices += vertex_count as u64;
        if total_vertices > limits.max_vertices {
            return Err(IoError::too_large(
                name,
                format!(
                    "at least {total_vertices} vertices; the limit is {}",
                    limits.max_vertices
                ),
            ));
        }
        let positions: Vec<Vec3> = mesh
            .positions
            .chunks_exact(3)
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect();
        let normals: Vec<Vec3> = if mesh.normals.len() == vertex_count * 3 {
            mesh.normals
                .chunks_exact(3)
                .map(|n| Vec3::new(n[0], n[1], n[2]))
                .collect()
        } else {
            if !mesh.normals.is_empty() {
                log::warn!(
                    "{}: object '{}' has normals on only some faces; recomputing",
                    name.display(),
                    model.name
                );
            }
            Vec::new()
        };
        let uvs: Vec<Vec2> = if mesh.texcoords.len() == vertex_count * 2 {
            mesh.texcoords
                .chunks_exact(2)
                .map(|t| Vec2::new(t[0], 1.0 - t[1]))
                .collect()
        } else {
            if !mesh.texcoords.is_empty() {
                log::warn!(
                    "{}: object '{}' has UVs on only some faces; dropping them",
                    name.display(),
                    model.name
                );
            }
            Vec::new()
        };
        let colors: Vec<Vec4> = if mesh.vertex_color.len() == vertex_count * 3 {
            mesh.vertex_color
                .chunks_exact(3)
                .map(|c| Vec4::new(c[0], c[1], c[2], 1.0))
                .collect()
        } else {
            Vec::new()
        };
        let material = match mesh.material_id {
            Some(m) if m < default_material => m,
            _ => {
                used_default = true;
                default_material
            }
        };
        let mut part = TriangleMesh {
            positions,
            normals,
            uvs,
            colors,
            indices: mesh.indices,
            material,
            ..TriangleMesh::default()
        };
        // Checked before compute_normals, which indexes positions by these indices.
        if let Err(e) = part.validate() {
            return Err(IoError::invalid(
                name,
                format!("object '{}': {e}", model.name),
            ));
        }
        if part.normals.is_empty() {
            part.compute_normals();
        }
        out.parts.push(part);
    }
    if used_default {
        out.materials.push(Material {
            name: "default".to_owned(),
            base_color_texture: default_texture,
            ..Material::default()
        });
    }
    if out.parts.is_empty() {
        return Err(IoError::invalid(name, "the file has no faces"));
    }
    Ok(out)
}

fn utf8<'b>(bytes: &'b [u8], name: &Path) -> Result<&'b str, IoError> {
    std::str::from_utf8(bytes).map_err(|e| {
        let at = e.valid_up_to();
        let line = bytes[..at].iter().filter(|&&b| b == b'\n').count() + 1;
        IoError::parse(
            name,
            format!("not UTF-8 text: bad byte at offset {at} (line {line})"),
        )
    })
}

/// Checks every face index against the vertex, texture-coordinate and normal counts, as tobj
/// would resolve it (1-based, or negative = relative to the elements defined so far).
fn check_faces(text: &str, name: &Path) -> Result<(), IoError> {
    let mut totals = [0usize; 3];
    for line in text.lines() {
        match line.split_whitespace().next() {
            Some("v") => totals[0] += 1,
            Some("vt") => totals[1] += 1,
            Some("vn") => totals[2] += 1,
            _ => {}
        }
    }
    const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    const PLURALS: [&str; 3] = ["vertices", "texture coordinates", "normals"];
    let mut so_far = [0usize; 3];
    for (line_index, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => so_far[0] += 1,
            Some("vt") => so_far[1] += 1,
            Some("vn") => so_far[2] += 1,
            Some("f" | "l") => {
                let line_number = line_index + 1;
                for word in words {
                    if word.split('/').count() > 3 {
                        return Err(IoError::parse(
                            name,
                            format!(
                                "line {line_number}: face vertex '{word}' has more than three indices"
                            ),
                        ));
                    }
                    for (kind, part) in word.split('/').enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        // At most three parts, checked above.
                        let (Some(&total), Some(&before)) = (totals.get(kind), so_far.get(kind))
                        else {
                            continue;
                        };
                        let Ok(index) = part.parse::<i64>() else {
                            return Err(IoError::parse(
                                name,
                                format!("line {line_number}: bad face index '{part}'"),
                            ));
                        };
                        let valid = match index {
                            i if i > 0 => (i as u64) <= total as u64,
                            i if i < 0 => i.unsigned_abs() <= before as u64,
                            _ => false,
                        };
                        if !valid {
                            return Err(IoError::invalid(
                                name,
                                format!(
                                    "line {line_number}: face refers to {} {index}, but the file has {total} {}{}",
                                    KINDS[kind],
                                    PLURALS[kind],
                                    if index < 0 {
                                        format!(" ({before} before this line)")
                                    } else {
                                        String::new()
                                    }
                                ),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// tobj expects three numbers after `Ka`/`Kd`/`Ks`/`Ke` and panics on fewer.
fn check_mtl(text: &str, name: &Path) -> Result<(), IoError> {
    for (line_index, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if let Some(key @ ("Ka" | "Kd" | "Ks" | "Ke")) = words.next()
            && words.count() < 3
        {
            return Err(IoError::parse(
                name,
                format!("line {}: {key} needs three numbers", line_index + 1),
            ));
        }
    }
    Ok(())
}

/// A `map_Kd` value (which may carry options such as `-s 1 1 1` before the file name).
fn load_map(
    map: &str,
    files: &SideFiles<'_>,
    name: &Path,
    limits: &ImportLimits,
) -> Result<Option<Texture>, IoError> {
    let mut encoded = files(map)?;
    if encoded.is_none()
        && map.starts_with('-')
        && let Some(last) = map.split_whitespace().last()
    {
        encoded = files(last)?;
    }
    let Some(encoded) = encoded else {
        log::warn!(
            "{}: texture '{map}' not found; the material keeps its colour",
            name.display()
        );
        return Ok(None);
    };
    decode(&encoded, &name.with_file_name(map), limits).map(Some)
}

fn decode(encoded: &[u8], path: &Path, limits: &ImportLimits) -> Result<Texture, IoError> {
    decode_texture(encoded, limits).map_err(|e| match e {
        TextureError::TooLarge(d) => IoError::too_large(path, d),
        TextureError::Decode(d) => IoError::invalid(path, format!("texture: {d}")),
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn asset(relative: &str) -> PathBuf {
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/assets/")).join(relative)
    }

    /// A 2×1 PNG: red, blue.
    pub(crate) fn png_2x1() -> Vec<u8> {
        let img =
            image::RgbaImage::from_raw(2, 1, vec![255, 0, 0, 255, 0, 0, 255, 255]).expect("image");
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png)
            .expect("png");
        out.into_inner()
    }

    /// A cube of quads in two materials, with UVs on one face, a pentagon, and negative indices.
    pub(crate) const CUBE_OBJ: &str = "# test cube
mtllib cube.mtl
o cube
v -0.5 -0.5 -0.5
v 0.5 -0.5 -0.5
v 0.5 0.5 -0.5
v -0.5 0.5 -0.5
v -0.5 -0.5 0.5
v 0.5 -0.5 0.5
v 0.5 0.5 0.5
v -0.5 0.5 0.5
vt 0.25 0.0
vt 0.75 0.0
vt 0.75 1.0
vt 0.25 1.0
usemtl red
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
usemtl painted
f 4 8 7 3
f -8 -4 -1 -5
f 2/1 3/2 7/3 6/4
";

    pub(crate) const CUBE_MTL: &str = "newmtl red
Kd 1 0 0
newmtl painted
Kd 0.5 0.5 0.5
d 0.5
map_Kd tex.png
";

    /// Side files for [`CUBE_OBJ`] from memory.
    pub(crate) fn cube_files(mtl: &[u8]) -> impl Fn(&str) -> Result<Option<Vec<u8>>, IoError> + '_ {
        cube_files_with(mtl, png_2x1())
    }

    /// [`cube_files`] with `texture` (any bytes) as the `map_Kd` image.
    pub(crate) fn cube_files_with(
        mtl: &[u8],
        texture: Vec<u8>,
    ) -> impl Fn(&str) -> Result<Option<Vec<u8>>, IoError> + '_ {
        move |name: &str| {
            Ok(match name {
                "cube.mtl" => Some(mtl.to_vec()),
                "tex.png" => Some(texture.clone()),
                _ => None,
            })
        }
    }

    fn cube(obj: &str, mtl: &str) -> Result<MeshModel, IoError> {
        import_obj_slice_with(
            obj.as_bytes(),
            &cube_files(mtl.as_bytes()),
            Path::new("cube.obj"),
            &ObjOptions::default(),
            &ImportLimits::default(),
        )
    }

    #[test]
    fn spot_imports_with_its_texture() {
        let options = ObjOptions {
            default_texture: Some(asset("static/spot/spot_texture.png")),
        };
        let model = import_obj_with(
            &asset("static/spot/spot_triangulated.obj"),
            &options,
            &ImportLimits::default(),
        )
        .expect("spot");
        assert_eq!(model.triangle_count(), 5856);
        // One vertex per distinct (position, uv) pair in the file's faces.
        assert_eq!(model.vertex_count(), 3225);
        let part = &model.parts[0];
        assert_eq!((part.uvs.len(), part.normals.len()), (3225, 3225));
        let texture = model.materials[part.material]
            .base_color_texture
            .as_ref()
            .expect("texture");
        assert_eq!((texture.width, texture.height), (1024, 1024));
        assert!(part.signed_volume() > 0.0);
        // Same surface as the derived .glb.
        let glb = super::super::gltf_mesh::import_gltf(&asset(
            "static/spot/spot_triangulated.derived.glb",
        ))
        .expect("glb");
        assert!((glb.parts[0].signed_volume() - part.signed_volume()).abs() < 1e-5);
        // Without the option, Spot has no texture (no .mtl) and still imports.
        let plain = import_obj(&asset("static/spot/spot_triangulated.obj")).expect("plain");
        assert!(
            plain
                .materials
                .iter()
                .all(|m| m.base_color_texture.is_none())
        );
    }

    #[test]
    fn materials_textures_polygons_and_relative_indices() {
        let model = cube(CUBE_OBJ, CUBE_MTL).expect("cube");
        assert_eq!(model.triangle_count(), 12);
        assert_eq!(model.parts.len(), 2);
        let volume: f64 = model.parts.iter().map(TriangleMesh::signed_volume).sum();
        assert!((volume - 1.0).abs() < 1e-6, "{volume}");
        assert_eq!(model.materials.len(), 2);
        assert_eq!(model.materials[0].base_color, Vec4::new(1.0, 0.0, 0.0, 1.0));
        let painted = &model.materials[1];
        assert_eq!(painted.base_color, Vec4::new(0.5, 0.5, 0.5, 0.5));
        assert_eq!(
            painted
                .base_color_texture
                .as_ref()
                .map(|t| (t.width, t.height)),
            Some((2, 1))
        );
        // UVs exist on one face only, so they are dropped for that part (warned), never misaligned.
        assert!(
            model
                .parts
                .iter()
                .all(|p| p.uvs.is_empty() || p.uvs.len() == p.positions.len())
        );
    }

    #[test]
    fn uvs_are_flipped_to_the_gltf_convention() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 0.25\nf 1/1 2/2 3/3\n";
        let model = cube(obj, "").expect("triangle");
        assert_eq!(
            model.parts[0].uvs,
            vec![
                Vec2::new(0.0, 1.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(0.0, 0.75)
            ]
        );
        assert_eq!(model.materials.len(), 1, "default material");
    }

    #[test]
    fn bad_obj_input_is_a_clear_error() {
        let dir = tempfile::tempdir().expect("temp dir");
        let bad = dir.path().join("bad_index.obj");
        std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 99\n").expect("write");
        let err = import_obj(&bad).expect_err("index out of range");
        let text = err.to_string();
        assert!(matches!(err, IoError::Invalid { .. }), "{text}");
        assert!(
            text.contains("bad_index.obj") && text.contains("line 5") && text.contains("vertex 99"),
            "{text}"
        );
        assert!(text.contains("but the file has 3 vertices"), "{text}");

        let empty = dir.path().join("empty.obj");
        std::fs::write(&empty, "").expect("write");
        let err = import_obj(&empty).expect_err("empty");
        assert!(
            matches!(err, IoError::Truncated { .. }) && err.to_string().contains("empty.obj"),
            "{err}"
        );

        let cases: [(&str, &str); 7] = [
            ("v 0 0 0\nf 1 1 -2\n", "vertex -2"),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "vertex 0"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/9 2 3\n",
                "texture coordinate 9",
            ),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//-1 2 3\n", "normal -1"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n",
                "more than three indices",
            ),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "bad face index 'x'"),
            ("v 0 0\n", "OBJ: position parse error"),
        ];
        for (obj, expected) in cases {
            let err = cube(obj, "").expect_err(expected);
            assert!(err.to_string().starts_with("cube.obj: "), "{err}");
            assert!(
                err.to_string().contains(expected),
                "expected '{expected}' in '{err}'"
            );
        }
        let err = import_obj_slice_with(
            b"v 0 0 0\n\xff\n",
            &|_| Ok(None),
            Path::new("x.obj"),
            &ObjOptions::default(),
            &ImportLimits::default(),
        )
        .expect_err("utf8");
        assert!(
            err.to_string()
                .contains("not UTF-8 text: bad byte at offset 8 (line 2)"),
            "{err}"
        );
        let err = cube("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "").expect_err("no faces");
        assert!(err.to_string().contains("no faces"), "{err}");
    }

    #[test]
    fn bad_mtl_and_texture_input_is_a_clear_error() {
        // tobj would panic on a colour with two values; the scan refuses it with the line.
        let err = cube(CUBE_OBJ, "newmtl red\nKd 1 0\n").expect_err("short Kd");
        assert!(
            err.to_string()
                .contains("cube.mtl: cannot parse: line 2: Kd needs three numbers"),
            "{err}"
        );
        // The cube with `texture` as its tex.png.
        let with_texture = |texture: &[u8]| {
            let files = |name: &str| -> Result<Option<Vec<u8>>, IoError> {
                Ok(match name {
                    "cube.mtl" => Some(CUBE_MTL.as_bytes().to_vec()),
                    "tex.png" => Some(texture.to_vec()),
                    _ => None,
                })
            };
            import_obj_slice_with(
                CUBE_OBJ.as_bytes(),
                &files,
                Path::new("cube.obj"),
                &ObjOptions::default(),
                &ImportLimits::default(),
            )
        };
        // A texture that is present but corrupt is an error naming the texture.
        let err = with_texture(b"\x89PNG\r\n\x1a\nnot really").expect_err("corrupt png");
        assert!(
            err.to_string().starts_with("tex.png: invalid: texture:"),
            "{err}"
        );
        // An indexed PNG whose palette ends in a partial entry (the `png` decoder panics on it):
        // refused with where the palette is, no panic.
        let partial = crate::mesh::tests::indexed_png(&[10, 20, 30, 40]);
        let err = with_texture(&partial).expect_err("partial palette");
        assert!(
            err.to_string().contains("tex.png: invalid: texture:")
                && err
                    .to_string()
                    .contains("palette (PLTE chunk at byte 33) is 4 bytes"),
            "{err}"
        );
        // A missing .mtl or texture is only a warning.
        let model = import_obj_slice_with(
            CUBE_OBJ.as_bytes(),
            &|_| Ok(None),
            Path::new("cube.obj"),
            &ObjOptions::default(),
            &ImportLimits::default(),
        )
        .expect("missing side files");
        assert_eq!(model.triangle_count(), 12);
        assert!(
            model
                .materials
                .iter()
                .all(|m| m.base_color_texture.is_none())
        );
        // Over the texture limit before decoding.
        let limits = ImportLimits {
            max_texture_bytes: 7,
            ..ImportLimits::default()
        };
        let err = import_obj_slice_with(
            CUBE_OBJ.as_bytes(),
            &cube_files(CUBE_MTL.as_bytes()),
            Path::new("cube.obj"),
            &ObjOptions::default(),
            &limits,
        )
        .expect_err("texture limit");
        assert!(
            matches!(err, IoError::TooLarge { .. })
                && err.to_string().contains("2×1 pixels need 8 bytes"),
            "{err}"
        );
    }
}

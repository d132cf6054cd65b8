//! Every WGSL file under `shaders/` parses and validates with naga after its imports are
//! composed, with no GPU: a broken shader fails CI on any machine.

use std::path::{Path, PathBuf};

use thicket::gpu::{gpu_data, shaders};

fn wgsl_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let entries = std::fs::read_dir(dir).expect("shaders/ is readable");
    for e in entries {
        let p = e.expect("directory entry").path();
        if p.is_dir() {
            wgsl_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "wgsl") {
            out.push(p);
        }
    }
}

fn validate(path: &str) -> Result<(), String> {
    let src = shaders::compose(path).map_err(|e| e.to_string())?;
    let module = naga::front::wgsl::parse_str(&src)
        .map_err(|e| format!("{path}: parse error:\n{}", e.emit_to_string(&src)))?;
    let mut caps = naga::valid::Capabilities::default();
    if shaders::needs_int64(path) {
        caps |= naga::valid::Capabilities::SHADER_INT64
            | naga::valid::Capabilities::SHADER_INT64_ATOMIC_MIN_MAX;
    }
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
        .validate(&module)
        .map_err(|e| format!("{path}: validation error:\n{}", e.emit_to_string(&src)))?;
    Ok(())
}

#[test]
fn every_wgsl_file_is_embedded_and_validates() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders");
    let mut files = Vec::new();
    wgsl_files(&root, &mut files);
    assert!(files.len() >= 10, "found only {files:?}");
    let mut failures = Vec::new();
    for f in &files {
        let rel = f
            .strip_prefix(&root)
            .expect("under shaders/")
            .to_string_lossy()
            .replace('\\', "/");
        let on_disk = std::fs::read_to_string(f).expect("readable");
        match shaders::source(&rel) {
            Ok(embedded) => assert_eq!(embedded, on_disk, "{rel}: embedded copy is stale"),
            Err(e) => failures.push(format!(
                "{rel}: not embedded in gpu::shaders::SOURCES ({e})"
            )),
        }
        if let Err(e) = validate(&rel) {
            failures.push(e);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn int64_modules_fail_without_the_capability() {
    // The capability gate is real: a 64-bit module must not validate on a device without it,
    // so the renderer's `needs_int64` split is necessary.
    let src = shaders::compose("asvo_splat64.wgsl").expect("composes");
    let module = naga::front::wgsl::parse_str(&src).expect("parses");
    let r = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module);
    assert!(r.is_err());
}

#[test]
fn unknown_imports_are_errors() {
    assert!(shaders::compose("no_such_file.wgsl").is_err());
}

/// Size and field offsets (by name) of struct `name` as naga lays it out in `path`.
fn wgsl_struct(path: &str, name: &str) -> (u32, Vec<(String, u32)>) {
    let src = shaders::compose(path).expect("composes");
    let module = naga::front::wgsl::parse_str(&src).expect("parses");
    module
        .types
        .iter()
        .find_map(|(_, t)| match (&t.name, &t.inner) {
            (Some(n), naga::TypeInner::Struct { members, span }) if n == name => Some((
                *span,
                members
                    .iter()
                    .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                    .collect(),
            )),
            _ => None,
        })
        .unwrap_or_else(|| panic!("{path}: no struct {name}"))
}

fn offset_of(fields: &[(String, u32)], name: &str) -> u32 {
    fields
        .iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no field {name}"))
        .1
}

#[test]
fn shade_pass_structs_match_their_rust_twins() {
    // The shade pass reads lights and shadow maps from storage buffers the renderer fills with
    // `gpu_data` structs: the WGSL layout must be the Rust one, field for field.
    use thicket::gpu::gpu_data::{LightGpu, ShadingUniform, ShadowMapGpu, ViewUniform};
    let (size, fields) = wgsl_struct("shade.wgsl", "LightGpu");
    assert_eq!(size as usize, size_of::<LightGpu>());
    assert_eq!(
        offset_of(&fields, "shadow_map") as usize,
        std::mem::offset_of!(LightGpu, shadow_map)
    );
    assert_eq!(
        offset_of(&fields, "color") as usize,
        std::mem::offset_of!(LightGpu, color)
    );
    let (size, fields) = wgsl_struct("shade.wgsl", "ShadowMap");
    assert_eq!(size as usize, size_of::<ShadowMapGpu>());
    assert_eq!(
        offset_of(&fields, "key_word_offset") as usize,
        std::mem::offset_of!(ShadowMapGpu, key_word_offset)
    );
    let (size, _) = wgsl_struct("shade.wgsl", "View");
    assert_eq!(size as usize, size_of::<ViewUniform>());
    let (size, fields) = wgsl_struct("shade.wgsl", "Shading");
    assert_eq!(size as usize, size_of::<ShadingUniform>());
    assert_eq!(
        offset_of(&fields, "ao_kernel") as usize,
        std::mem::offset_of!(ShadingUniform, ao_kernel)
    );
}

/// The value of `const NAME: u32` in a composed module.
fn u32_constant(path: &str, name: &str) -> u32 {
    let src = shaders::compose(path).expect("composes");
    let module = naga::front::wgsl::parse_str(&src).expect("parses");
    let (_, c) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("{path}: no constant {name}"));
    match module.global_expressions[c.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => v,
        ref e => panic!("{path}: {name} is {e:?}, not a u32 literal"),
    }
}

#[test]
fn triangle_and_texture_layouts_match_gpu_data() {
    // The size assertions in gpu_data pin the Rust side; these pin the WGSL side to it.
    for path in ["mesh32.wgsl", "mesh64.wgsl", "resolve.wgsl"] {
        assert_eq!(
            u32_constant(path, "TRI_STRIDE") as usize,
            gpu_data::TRI_VEC4S,
            "{path}"
        );
    }
    assert_eq!(
        u32_constant("resolve.wgsl", "TEXTURE_LUT_WORDS") as usize,
        gpu_data::TEXTURE_LUT_WORDS
    );
    assert_eq!(
        u32_constant("resolve.wgsl", "TEXTURE_ENTRY_WORDS") as usize,
        gpu_data::TEXTURE_ENTRY_WORDS
    );
}

#[test]
fn id_bits_and_counter_layout_match_gpu_data_and_core() {
    // Voxel ids carry an exact cube's face in their low bits on both renderers.
    assert_eq!(gpu_data::FACE_BITS, thicket_core::render::FACE_BITS);
    for path in ["asvo_splat32.wgsl", "asvo_splat64.wgsl", "resolve.wgsl"] {
        assert_eq!(
            u32_constant(path, "FACE_BITS"),
            gpu_data::FACE_BITS,
            "{path}"
        );
        assert_eq!(
            u32_constant(path, "FACE_MASK"),
            (1 << gpu_data::FACE_BITS) - 1
        );
        assert_eq!(
            u32_constant(path, "MESH_ID_FLAG"),
            gpu_data::MESH_ID_FLAG,
            "{path}"
        );
    }
    for path in ["asvo_splat32.wgsl", "asvo_splat64.wgsl"] {
        for (name, value) in [
            ("STATS_PER_LEVEL", gpu_data::STATS_PER_LEVEL),
            ("STATS_START", gpu_data::STATS_START),
            ("SPLAT_PIXEL_COUNTERS", gpu_data::SPLAT_PIXEL_COUNTERS),
            ("CUBE_PIXEL_COUNTERS", gpu_data::CUBE_PIXEL_COUNTERS),
            ("OVERFLOW_COUNTER", gpu_data::OVERFLOW_COUNTER),
        ] {
            assert_eq!(u32_constant(path, name), value, "{path}: {name}");
        }
    }
}

//! One source of truth for what Rust and WGSL share (issue 24):
//! - every `Pod` struct the renderer uploads is laid out by naga, from the composed WGSL, the
//!   way `gpu_data` lays it out in Rust (size, field boundaries, and the offset of every field
//!   both sides name alike);
//! - the shared constants (and the code enums' values) are generated from
//!   `gpu_data::wgsl_constants` into every composed shader, and a shader that keeps its own
//!   copy does not compile.
//!
//! Each check is shown to fail on a WGSL source edited in memory on one side only.

use thicket::gpu::gpu_data::{
    self, ClearParams, KrsFrameUniform, KrsKernelGpu, KrsKernelKind, KrsObjectGpu, KrsPattern,
    KrsTextureMode, LightGpu, NodeParams, ObjectInfo, ResolveChunk, ShadingUniform, ShadowMapGpu,
    SkinParams, SkinStrategy, ViewUniform,
};
use thicket::gpu::shaders;

/// A Rust struct's layout: size and (name, offset, size) of each field.
struct RustLayout {
    rust: &'static str,
    size: usize,
    fields: Vec<(&'static str, usize, usize)>,
}

fn field_size<T, F>(_: fn(&T) -> &F) -> usize {
    size_of::<F>()
}

macro_rules! layout {
    ($t:ty { $($f:ident),* $(,)? }) => {
        RustLayout {
            rust: stringify!($t),
            size: size_of::<$t>(),
            fields: vec![$((
                stringify!($f),
                std::mem::offset_of!($t, $f),
                field_size::<$t, _>(|x: &$t| &x.$f),
            )),*],
        }
    };
}

/// (WGSL struct, the shader composed to find it, the Rust twin): every shared struct.
fn shared_structs() -> Vec<(&'static str, &'static str, RustLayout)> {
    vec![
        (
            "View",
            "shade.wgsl",
            layout!(ViewUniform {
                view_from_world,
                clip_from_world,
                world_from_view,
                size,
                perspective,
                write_mode,
                fx,
                fy,
                near,
                far,
                lod_pixel_threshold,
                occlusion,
                tiles_x,
                cube_pixel_threshold,
            }),
        ),
        (
            "NodeParams",
            "asvo_splat32.wgsl",
            layout!(NodeParams {
                linear,
                translation_edge,
                half_extent_unit,
                level,
                node_size,
                leaf_level,
                queue_capacity,
                inner_base,
                leaf_base,
                attr_inner_base,
                attr_leaf_base,
                stats_base,
                pad,
                skin,
            }),
        ),
        (
            "SkinParams",
            "asvo_splat32.wgsl",
            layout!(SkinParams {
                joint_base,
                joint_count,
                strategy,
                flags,
                inner_skin,
                leaf_skin,
                inner_corners,
                leaf_corners,
                subtree_ranges,
                subtree_joints,
                overrides,
                pad,
                multiplier,
                min_factor,
                max_factor,
                grow,
            }),
        ),
        (
            "ObjectInfo",
            "resolve.wgsl",
            layout!(ObjectInfo {
                normal_from_voxel,
                skin_attr,
                skin
            }),
        ),
        (
            "LightGpu",
            "shade.wgsl",
            layout!(LightGpu {
                to_light,
                shadow_map,
                color
            }),
        ),
        (
            "ShadowMap",
            "shade.wgsl",
            layout!(ShadowMapGpu {
                view,
                key_word_offset,
                pad
            }),
        ),
        (
            "Shading",
            "shade.wgsl",
            layout!(ShadingUniform {
                ambient,
                background,
                light_count,
                pcf_radius,
                receiver_px,
                ao_count,
                ao_radius,
                krs_stride,
                pad,
                ao_kernel,
            }),
        ),
        (
            "ClearParams",
            "clear.wgsl",
            layout!(ClearParams { count, pad }),
        ),
        (
            "ResolveChunk",
            "resolve.wgsl",
            layout!(ResolveChunk {
                attr_start,
                attr_end,
                others,
                pad
            }),
        ),
        (
            "KrsObject",
            "krs_trace.wgsl",
            layout!(KrsObjectGpu {
                inv_rotation,
                rotation,
                translation_scale,
                bound,
                first_mirror,
                mirror_count,
                first_kernel,
                first_zone,
                zone_count,
                flags,
                texture_mode,
                pattern,
                inv_scale,
                lipschitz,
                amplitude,
                frequency,
                seed,
                tex_scale,
                tex_contrast,
                tex_sharpness,
            }),
        ),
        (
            "KrsKernel",
            "krs_trace.wgsl",
            layout!(KrsKernelGpu {
                kind,
                colour,
                params
            }),
        ),
        (
            "KrsFrame",
            "krs_trace.wgsl",
            layout!(KrsFrameUniform {
                eps_scale,
                pixel_cone,
                min_epsilon,
                max_steps,
                over_relaxation,
                grid_q0,
                grid_t0,
                grid_log_step,
                grid_u0,
                object_count,
                light_count,
                light_base,
                flags,
                ao_samples,
                ao_spacing,
                receiver_px,
                stride,
                smoothing_px,
                soft_k,
                pad,
            }),
        ),
    ]
}

/// A WGSL struct's size and (name, offset, size) of each member.
type WgslLayout = (u32, Vec<(String, u32, u32)>);

/// Size and (name, offset, size) of each member of struct `name` as naga lays it out in `src`.
fn wgsl_layout(src: &str, name: &str) -> Result<WgslLayout, String> {
    let module = naga::front::wgsl::parse_str(src).map_err(|e| e.emit_to_string(src))?;
    let gctx = module.to_ctx();
    module
        .types
        .iter()
        .find_map(|(_, t)| match (&t.name, &t.inner) {
            (Some(n), naga::TypeInner::Struct { members, span }) if n == name => Some((
                *span,
                members
                    .iter()
                    .map(|m| {
                        let size = module.types[m.ty].inner.size(gctx);
                        (m.name.clone().unwrap_or_default(), m.offset, size)
                    })
                    .collect(),
            )),
            _ => None,
        })
        .ok_or_else(|| format!("no struct {name}"))
}

/// Whether WGSL struct `wgsl` in `src` has `rust`'s layout: the same size; every WGSL member
/// inside one Rust field (a Rust matrix may be WGSL rows, a Rust padding array WGSL words);
/// a WGSL member starting at every Rust field; and a field both sides name alike at the same
/// offset.
fn check(src: &str, wgsl: &str, rust: &RustLayout) -> Result<(), String> {
    let (span, members) = wgsl_layout(src, wgsl)?;
    let who = format!("WGSL {wgsl} / Rust {}", rust.rust);
    if span as usize != rust.size {
        return Err(format!(
            "{who}: {span} bytes in WGSL, {} in Rust",
            rust.size
        ));
    }
    for (name, offset, size) in &members {
        let (offset, size) = (*offset as usize, *size as usize);
        let inside = rust
            .fields
            .iter()
            .any(|&(_, o, s)| o <= offset && offset + size <= o + s);
        if !inside {
            return Err(format!(
                "{who}: WGSL member {name} (bytes {offset}..{}) crosses a Rust field boundary",
                offset + size
            ));
        }
    }
    for &(name, offset, _) in &rust.fields {
        if !members.iter().any(|(_, o, _)| *o as usize == offset) {
            return Err(format!(
                "{who}: no WGSL member starts where Rust field {name} does ({offset})"
            ));
        }
        if let Some((_, o, _)) = members.iter().find(|(n, _, _)| n == name)
            && *o as usize != offset
        {
            return Err(format!(
                "{who}: field {name} at {o} in WGSL, {offset} in Rust"
            ));
        }
    }
    Ok(())
}

#[test]
fn every_shared_struct_has_the_rust_layout() {
    let mut failures = Vec::new();
    for (wgsl, file, rust) in shared_structs() {
        // The table lists every Rust field: `Pod` structs have no padding, so the fields'
        // sizes add up to the struct's exactly when none is missing.
        let listed: usize = rust.fields.iter().map(|f| f.2).sum();
        assert_eq!(listed, rust.size, "{}: the table misses a field", rust.rust);
        let src = shaders::compose(file).expect("composes");
        if let Err(e) = check(&src, wgsl, &rust) {
            failures.push(e);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

fn view_layout() -> RustLayout {
    shared_structs()
        .into_iter()
        .find(|(w, _, _)| *w == "View")
        .expect("View is shared")
        .2
}

#[test]
fn a_field_changed_in_wgsl_only_fails_the_check() {
    let src = shaders::compose("shade.wgsl").expect("composes");
    let rust = view_layout();
    assert_eq!(check(&src, "View", &rust), Ok(()), "the control passes");
    let edits = [
        // A field added on one side.
        ("    fx: f32,\n", "    fx: f32,\n    extra: f32,\n"),
        // A field's type changed (and with it the size of the struct).
        ("    occlusion: u32,\n", "    occlusion: vec2<u32>,\n"),
        // Two fields swapped: the size and boundaries stay, the names move.
        (
            "    near: f32,\n    far: f32,\n",
            "    far: f32,\n    near: f32,\n",
        ),
    ];
    for (from, to) in edits {
        assert!(src.contains(from), "the View struct has {from:?}");
        let edited = src.replacen(from, to, 1);
        let r = check(&edited, "View", &rust);
        assert!(r.is_err(), "editing {from:?} went unnoticed");
        eprintln!("{from:?} → {to:?}: {}", r.unwrap_err());
    }
}

#[test]
fn a_field_changed_in_rust_only_fails_the_check() {
    let src = shaders::compose("shade.wgsl").expect("composes");
    let mut rust = view_layout();
    // As if `fx` had become an `[f32; 2]` in Rust (everything after it moves by 4 bytes).
    let i = rust.fields.iter().position(|f| f.0 == "fx").expect("fx");
    rust.fields[i].2 = 8;
    for f in &mut rust.fields[i + 1..] {
        f.1 += 4;
    }
    rust.size += 4;
    assert!(check(&src, "View", &rust).is_err());
}

/// `const NAME: u32` values of a composed module.
fn u32_constants(src: &str) -> Vec<(String, u32)> {
    let module = naga::front::wgsl::parse_str(src).expect("parses");
    module
        .constants
        .iter()
        .filter_map(|(_, c)| match module.global_expressions[c.init] {
            naga::Expression::Literal(naga::Literal::U32(v)) => Some((c.name.clone()?, v)),
            _ => None,
        })
        .collect()
}

#[test]
fn shared_constants_are_generated_into_every_shader() {
    let generated = gpu_data::constants_wgsl();
    for (path, _) in shaders::SOURCES {
        if path.starts_with("common/") {
            continue;
        }
        let src = shaders::compose(path).expect("composes");
        assert!(src.contains(&generated), "{path}: no generated constants");
        let consts = u32_constants(&src);
        for (name, value) in gpu_data::wgsl_constants() {
            let found: Vec<u32> = consts
                .iter()
                .filter(|(n, _)| n == name)
                .map(|(_, v)| *v)
                .collect();
            assert_eq!(found, [value], "{path}: {name}");
        }
    }
    // Spot checks against the Rust constants themselves.
    let consts = u32_constants(&shaders::compose("clear.wgsl").expect("composes"));
    for (name, value) in [
        ("MAX_LEVELS", gpu_data::MAX_LEVELS),
        ("KRS_COUNTERS", gpu_data::KRS_COUNTERS),
        ("TRI_STRIDE", gpu_data::TRI_VEC4S as u32),
        ("NO_SHADOW_MAP", u32::MAX),
        ("SKIN_RIGID", SkinStrategy::Rigid.code()),
        ("SKIN_ADAPTIVE", SkinStrategy::Adaptive.code()),
        ("SKIN_HAS_OVERRIDES", gpu_data::SKIN_HAS_OVERRIDES),
        ("KRS_EMPTY", KrsKernelKind::Empty.code()),
        (
            "KRS_TOROIDAL_CAPSULE",
            KrsKernelKind::ToroidalCapsule.code(),
        ),
        (
            "KRS_TEXTURE_KERNEL_PARAM",
            KrsTextureMode::KernelParam.code(),
        ),
        ("KRS_PATTERN_BARK", KrsPattern::Bark.code()),
    ] {
        assert!(consts.contains(&(name.to_owned(), value)), "{name}");
    }
}

#[test]
fn a_shader_keeping_its_own_copy_of_a_shared_constant_fails() {
    // A WGSL-side copy cannot drift from the Rust value: it does not compile at all.
    let src = shaders::compose("clear.wgsl").expect("composes");
    assert!(
        naga::front::wgsl::parse_str(&src).is_ok(),
        "the control parses"
    );
    let with_copy = format!("{src}\nconst MAX_LEVELS: u32 = 33u;\n");
    assert!(naga::front::wgsl::parse_str(&with_copy).is_err());
}

#[test]
fn generated_constant_names_are_unique() {
    // A name in both `WGSL_CONSTANTS` and a code enum's table would be declared twice.
    let mut names: Vec<&str> = gpu_data::wgsl_constants().iter().map(|c| c.0).collect();
    let all = names.len();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), all);
    // Every code enum is in: its variants' count (the macro lists each variant once).
    assert_eq!(all, gpu_data::WGSL_CONSTANTS.len() + 5 + 7 + 3 + 2);
}

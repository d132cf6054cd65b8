//! WGSL sources, embedded at build time, and their composition.
//!
//! WGSL has no include mechanism, so a file names what it needs with `// #import path` lines
//! (paths relative to `shaders/`); [`compose`] prepends every import once, depth first. Entry
//! modules are the files at the top of `shaders/`; `shaders/common/` holds shared structs and
//! functions. Before everything, [`compose`] puts the generated [`GENERATED`] file: the
//! constants Rust and WGSL share, written from `gpu_data::WGSL_CONSTANTS`. The `gpu_shaders`
//! test validates every file with naga after composition; `gpu_layout` checks the shared
//! structs' layouts against `gpu_data`.

use super::GpuError;

macro_rules! shader {
    ($path:literal) => {
        (
            $path,
            include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../shaders/", $path)),
        )
    };
}

/// Every WGSL file under `shaders/`: (path relative to `shaders/`, source).
pub const SOURCES: &[(&str, &str)] = &[
    shader!("common/types.wgsl"),
    shader!("common/asvo.wgsl"),
    shader!("common/mesh.wgsl"),
    shader!("common/skin.wgsl"),
    shader!("asvo_queue.wgsl"),
    shader!("asvo_splat64.wgsl"),
    shader!("asvo_splat32.wgsl"),
    shader!("clear.wgsl"),
    shader!("hiz.wgsl"),
    shader!("mesh64.wgsl"),
    shader!("mesh32.wgsl"),
    shader!("resolve.wgsl"),
    shader!("shade.wgsl"),
    shader!("krs_trace.wgsl"),
    shader!("supersample.wgsl"),
    shader!("viewport_blit.wgsl"),
];

/// Whether a module needs 64-bit integer atomics (`SHADER_INT64` and
/// `SHADER_INT64_ATOMIC_MIN_MAX`): only then may it be compiled.
#[must_use]
pub fn needs_int64(path: &str) -> bool {
    path.ends_with("64.wgsl")
}

/// The source of one file, without its imports.
///
/// # Errors
/// [`GpuError::Shader`] when no such file is embedded.
pub fn source(path: &str) -> Result<&'static str, GpuError> {
    SOURCES
        .iter()
        .find(|(p, _)| *p == path)
        .map(|(_, s)| *s)
        .ok_or_else(|| GpuError::Shader(format!("no embedded shader {path:?}")))
}

/// The name of the generated constants file [`compose`] puts before every shader.
pub const GENERATED: &str = "constants.wgsl";

/// A file with the generated constants and its imports prepended (each once, dependencies
/// first).
///
/// # Errors
/// [`GpuError::Shader`] for an unknown file or an import cycle.
pub fn compose(path: &str) -> Result<String, GpuError> {
    let mut done: Vec<&str> = Vec::new();
    let mut out = format!("// ---- {GENERATED} ----\n");
    out.push_str(&super::gpu_data::constants_wgsl());
    visit(path, &mut Vec::new(), &mut done, &mut out)?;
    Ok(out)
}

fn visit<'a>(
    path: &'a str,
    stack: &mut Vec<&'a str>,
    done: &mut Vec<&'a str>,
    out: &mut String,
) -> Result<(), GpuError> {
    if done.contains(&path) {
        return Ok(());
    }
    if stack.contains(&path) {
        return Err(GpuError::Shader(format!(
            "import cycle: {} -> {path}",
            stack.join(" -> ")
        )));
    }
    let (key, src) = SOURCES
        .iter()
        .find(|(p, _)| *p == path)
        .ok_or_else(|| GpuError::Shader(format!("no embedded shader {path:?}")))?;
    stack.push(key);
    for line in src.lines() {
        if let Some(dep) = line.trim().strip_prefix("// #import ") {
            let dep = dep.trim();
            let dep_key = SOURCES
                .iter()
                .map(|(p, _)| *p)
                .find(|p| *p == dep)
                .ok_or_else(|| GpuError::Shader(format!("{path}: unknown import {dep:?}")))?;
            visit(dep_key, stack, done, out)?;
        }
    }
    stack.pop();
    out.push_str(&format!("// ---- {key} ----\n"));
    out.push_str(src);
    out.push('\n');
    done.push(key);
    Ok(())
}

//! What the GPU parity test files share: the device, the sample projects, and the CPU/GPU
//! comparison with its images written on failure.

use std::path::{Path, PathBuf};

use thicket::gpu::{GBuffer, GpuContext, GpuFrameStats, RenderTarget, Renderer, read_rgba8};
use thicket_core::measure::image::{Parity, Tolerance, difference_image, parity};
use thicket_core::quality::Quality;
use thicket_core::render::{FrameBuffers, RgbaImage};
use thicket_core::scene::{Document, OrbitCamera};

/// Relative view-depth agreement.
pub const DEPTH_TOLERANCE: f32 = 2e-3;

/// A headless device on whatever adapter is present (lavapipe in CI).
pub fn context() -> GpuContext {
    let ctx = GpuContext::new_headless(wgpu::PowerPreference::HighPerformance)
        .expect("a GPU adapter (install mesa-vulkan-drivers for lavapipe)");
    eprintln!("adapter: {}", ctx.describe());
    ctx
}

/// A sample project from `projects/`.
pub fn project(name: &str) -> Document {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../projects")
        .join(format!("{name}.thicket.json"));
    thicket::files::load_document(&path).expect("sample project loads")
}

/// One GPU frame of `doc` from its camera with `r`: the image, the G-buffer and the counters
/// (no uncaptured GPU error allowed).
pub fn gpu_frame(
    ctx: &GpuContext,
    r: &mut Renderer,
    doc: &Document,
    size: (u32, u32),
    quality: &Quality,
) -> (RgbaImage, GBuffer, GpuFrameStats) {
    let target = RenderTarget::new(&ctx.device, size.0, size.1).expect("target");
    let stats = r
        .render(
            &ctx.device,
            &ctx.queue,
            doc,
            &target.view(&doc.camera, quality),
            &target,
        )
        .expect("GPU frame");
    let img = RgbaImage {
        width: size.0,
        height: size.1,
        pixels: read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback"),
    };
    let g = r.read_gbuffer(&ctx.device, &ctx.queue).expect("G-buffer");
    assert!(ctx.errors.take().is_none(), "uncaptured GPU error");
    (img, g, stats)
}

/// NDC depth to view depth for a perspective camera (what both renderers store is NDC).
pub fn view_depth(cam: &OrbitCamera, ndc: f32) -> f32 {
    // The image size does not enter the depth mapping.
    thicket_core::render::Camera::from_orbit(cam, 1, 1).view_depth(ndc)
}

/// Compares a CPU frame (image and buffers) with a GPU frame (image and G-buffer) under
/// [`Tolerance::GPU_PARITY`] and [`DEPTH_TOLERANCE`]; on a mismatch writes the two images and
/// their difference to `$TMP/<dir>/<name>-{cpu,gpu,difference}.png` and panics saying where.
pub fn cpu_gpu_parity(
    dir: &str,
    name: &str,
    cam: &OrbitCamera,
    (cpu, fb): (&RgbaImage, &FrameBuffers),
    (gpu, g): (&RgbaImage, &GBuffer),
) -> Parity {
    let depth_cpu: Vec<Option<f32>> = fb
        .ids
        .iter()
        .zip(&fb.depth)
        .map(|(id, &d)| (id.object != 0).then(|| view_depth(cam, d)))
        .collect();
    let depth_gpu: Vec<Option<f32>> = g
        .depth
        .iter()
        .map(|&d| d.is_finite().then(|| view_depth(cam, d)))
        .collect();
    let p = parity(
        cpu,
        gpu,
        &depth_cpu,
        &depth_gpu,
        Tolerance::GPU_PARITY,
        DEPTH_TOLERANCE,
    )
    .expect("same size");
    if !p.within(Tolerance::GPU_PARITY) {
        let dir: PathBuf = std::env::temp_dir().join(dir);
        let _ = std::fs::create_dir_all(&dir);
        let _ = cpu.save_png(dir.join(format!("{name}-cpu.png")));
        let _ = gpu.save_png(dir.join(format!("{name}-gpu.png")));
        if let Ok(d) = difference_image(cpu, gpu, Tolerance::GPU_PARITY.channel) {
            let _ = d.save_png(dir.join(format!("{name}-difference.png")));
        }
        panic!(
            "{name}: GPU differs from the CPU reference: {p:?}; images in {}",
            dir.display()
        );
    }
    p
}

/// Reads `target` (a frame drawn after an incremental upload), renders `doc` into it again
/// with a fresh renderer (a full upload) and asserts that both images are identical; returns
/// the full-upload image (RGBA8 bytes).
pub fn assert_same_as_full_upload(
    ctx: &GpuContext,
    doc: &Document,
    quality: &Quality,
    target: &RenderTarget,
) -> Vec<u8> {
    let incremental = read_rgba8(&ctx.device, &ctx.queue, target).expect("readback");
    let mut fresh = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    fresh
        .render(
            &ctx.device,
            &ctx.queue,
            doc,
            &target.view(&doc.camera, quality),
            target,
        )
        .expect("full frame");
    let full = read_rgba8(&ctx.device, &ctx.queue, target).expect("readback");
    assert!(
        incremental == full,
        "the frame after an incremental upload differs from a full upload"
    );
    full
}

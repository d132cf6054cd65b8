//! Supersampling on the GPU (`Quality::supersample`, `gpu/passes/supersample.rs`) against the
//! CPU reference renderer's: at the final preset (3 × 3 samples per pixel) the GPU image must
//! change from its one-sample image and match the CPU's supersampled image under the one
//! parity tolerance (`Tolerance::GPU_PARITY`) the other parity tests use; the G-buffer read
//! back is the one the CPU keeps (the sample nearest each pixel's centre), depth included.
//! On failure the CPU, GPU and difference images are written to the system temp directory.

use thicket::gpu::{GpuContext, Renderer};
use thicket_core::quality::{Quality, QualityPreset};
use thicket_core::render::{View, render_document};
use thicket_core::scene::{Document, ObjectKind};

mod common;
use common::gpu::{context, cpu_gpu_parity, gpu_frame, project};

/// Pixels whose RGB differs between two same-size RGBA8 images.
fn changed_pixels(a: &[u8], b: &[u8]) -> usize {
    assert_eq!(a.len(), b.len());
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(p, q)| p[..3] != q[..3])
        .count()
}

/// `doc` at the final preset on both renderers: the GPU frame at `supersample` 3 differs from
/// its `supersample` 1 frame in at least 2 % of the pixels, and matches the CPU's 3 × 3 frame.
fn final_preset_matches(ctx: &GpuContext, name: &str, doc: &Document, size: (u32, u32)) {
    let fin = Quality::preset(QualityPreset::Final);
    assert_eq!(fin.supersample, 3, "the final preset draws 3 × 3 samples");
    let one = Quality {
        supersample: 1,
        ..fin.clone()
    };
    let req = View {
        width: size.0,
        height: size.1,
        camera: Some(doc.camera),
        quality: fin.clone(),
    };
    let (cpu, fb, _) = render_document(doc, &req).expect("CPU frame");
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let (gpu1, _, _) = gpu_frame(ctx, &mut r, doc, size, &one);
    let (gpu3, g3, stats3) = gpu_frame(ctx, &mut r, doc, size, &fin);
    let changed = changed_pixels(&gpu1.pixels, &gpu3.pixels);
    let pixels = (size.0 * size.1) as usize;
    eprintln!("{name}: supersample 3 changed {changed} of {pixels} GPU pixels");
    assert!(
        changed * 50 >= pixels,
        "{name}: supersample 3 changed only {changed} of {pixels} pixels of the GPU frame"
    );
    assert_eq!(
        (g3.width, g3.height),
        size,
        "{name}: the G-buffer at the image's size"
    );
    let p = cpu_gpu_parity(
        "thicket-gpu-supersample",
        name,
        &doc.camera,
        (&cpu, &fb),
        (&gpu3, &g3),
    );
    eprintln!("{name} (final, 3 × 3): {p:?}; GPU {:?}", stats3.splats);
    assert!(p.both_covered > 0, "{name}: nothing drawn");
    // A frame at one sample after the supersampled one is the one-sample frame again (the
    // samples target is not read).
    let (again, _, _) = gpu_frame(ctx, &mut r, doc, size, &one);
    assert_eq!(again.pixels, gpu1.pixels, "{name}: back to one sample");
}

#[test]
fn house_at_the_final_preset_matches_the_cpu_supersampled_frame() {
    let ctx = context();
    final_preset_matches(&ctx, "house", &project("house"), (96, 80));
}

#[test]
fn tree_at_the_final_preset_matches_the_cpu_supersampled_frame() {
    let ctx = context();
    final_preset_matches(&ctx, "tree", &project("tree"), (96, 96));
}

#[test]
fn cesiumman_at_the_final_preset_matches_the_cpu_supersampled_frame() {
    let ctx = context();
    let mut doc = project("cesiumman");
    for o in &mut doc.objects {
        if let ObjectKind::Voxels(v) = &mut o.kind
            && let Some(rig) = &mut v.rig
        {
            rig.playback.time_secs = 0.5;
        }
    }
    final_preset_matches(&ctx, "cesiumman", &doc, (128, 128));
}

//! Voxel pools split across storage bindings: a device created with a lowered
//! `max_storage_buffer_binding_size` (legal in wgpu, and validated by it like a real one) must
//! draw a scene whose pools exceed one binding exactly as a device with the adapter's limit does,
//! refuse an object too large for a binding by name, and upload only an edit's ranges into the
//! chunk that holds the edited object. Runs on whatever adapter is present (lavapipe in CI).

use glam::{UVec3, Vec3};
use thicket::gpu::{GpuContext, GpuError, Renderer, voxel_pool_bytes};
use thicket_core::render::{View, render_document, scenes};
use thicket_core::scene::{Document, ObjectKind};
use thicket_core::svo::{Svo, Voxel};

mod common;
use common::gpu::{context, cpu_gpu_parity, gpu_frame};

const SIZE: (u32, u32) = (80, 64);

/// The mixed sample scene (sphere, cube, ground, one shadow-casting sun) plus three copies of
/// its sphere around it: four voxel objects of equal pool size.
fn four_spheres() -> Document {
    let mut doc = scenes::mixed_document(6).expect("scene");
    let sphere = doc
        .objects
        .iter()
        .find(|o| matches!(o.kind, ObjectKind::Voxels(_)))
        .cloned()
        .expect("the sphere");
    for (i, offset) in [
        Vec3::new(-1.1, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -1.2),
        Vec3::new(-1.0, 0.0, -1.3),
    ]
    .into_iter()
    .enumerate()
    {
        let id = doc.add(format!("Sphere {}", i + 2), sphere.kind.clone());
        if let Some(o) = doc.objects.iter_mut().find(|o| o.id == id) {
            o.transform = sphere.transform;
            o.transform.translation += offset;
        }
    }
    doc
}

fn svo_of<'a>(doc: &'a mut Document, name: &str) -> (u64, &'a mut Svo) {
    let o = doc
        .objects
        .iter_mut()
        .find(|o| o.name == name)
        .expect("object");
    match &mut o.kind {
        ObjectKind::Voxels(v) => (o.id, &mut v.svo),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => panic!("{name} is not voxels"),
    }
}

/// A binding limit that holds two of the spheres' pools but not all four (so the four go into
/// two chunks), and the G-buffer of a `SIZE` frame.
fn two_sphere_limit(doc: &Document) -> u64 {
    let pools: Vec<(u64, u64)> = doc
        .objects
        .iter()
        .filter_map(|o| match &o.kind {
            ObjectKind::Voxels(v) => Some(voxel_pool_bytes(&v.svo)),
            _ => None,
        })
        .collect();
    assert_eq!(pools.len(), 4);
    let attr = pools[0].1;
    let limit = 2 * attr + 256;
    let total: u64 = pools.iter().map(|p| p.1).sum();
    assert!(limit < total, "the limit must split the pools");
    assert!(
        limit >= u64::from(SIZE.0 * SIZE.1) * 16,
        "the G-buffer fits"
    );
    limit
}

fn low_limit_context(limit: u64) -> GpuContext {
    let ctx = GpuContext::new_headless_with_binding_limit(
        wgpu::PowerPreference::HighPerformance,
        Some(limit),
    )
    .expect("a GPU adapter (install mesa-vulkan-drivers for lavapipe)");
    assert_eq!(
        ctx.device.limits().max_storage_buffer_binding_size,
        limit,
        "the device took the lowered limit"
    );
    ctx
}

#[test]
fn pools_split_across_bindings_draw_as_one_binding_does() {
    let doc = four_spheres();
    let limit = two_sphere_limit(&doc);
    let normal = context();
    let low = low_limit_context(limit);
    let q = doc.quality.clone();
    let req = View {
        width: SIZE.0,
        height: SIZE.1,
        camera: Some(doc.camera),
        quality: q.clone(),
    };
    let (cpu, fb, _) = render_document(&doc, &req).expect("CPU frame");
    for two_pass in [false, true] {
        let mut one = Renderer::new(&normal.device, &normal.queue).expect("renderer");
        one.set_force_two_pass(two_pass);
        let (img_one, g_one, s_one) = gpu_frame(&normal, &mut one, &doc, SIZE, &q);
        assert_eq!(one.pool_chunks(), 1);
        let mut split = Renderer::new(&low.device, &low.queue).expect("renderer");
        split.set_force_two_pass(two_pass);
        let (img_split, g_split, s_split) = gpu_frame(&low, &mut split, &doc, SIZE, &q);
        assert_eq!(split.pool_chunks(), 2, "two spheres per chunk");
        assert_eq!(s_split.queue_overflow, 0);
        assert!(s_split.splats > 0 && s_split.splats == s_one.splats);
        assert!(
            img_split.pixels == img_one.pixels,
            "two-pass {two_pass}: the split scene's image differs from one binding's"
        );
        assert!(
            g_split == g_one,
            "two-pass {two_pass}: the split scene's G-buffer differs from one binding's"
        );
        let p = cpu_gpu_parity(
            "thicket-gpu-chunks",
            if two_pass { "split-32" } else { "split-64" },
            &doc.camera,
            (&cpu, &fb),
            (&img_split, &g_split),
        );
        assert!(p.both_covered > 0, "nothing drawn");
    }
}

#[test]
fn an_object_over_the_binding_limit_is_refused_by_name() {
    let mut doc = four_spheres();
    let limit = two_sphere_limit(&doc);
    // A finer sphere whose attribute pool alone is over the limit.
    let big = scenes::sphere_document(7, 0.9).expect("scene");
    let big = big.objects[0].kind.clone();
    if let ObjectKind::Voxels(v) = &big {
        assert!(voxel_pool_bytes(&v.svo).1 > limit);
    }
    doc.add("Big sphere", big);
    let ctx = low_limit_context(limit);
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let err = r.upload_document(&ctx.device, &doc).expect_err("too large");
    assert!(
        matches!(&err, GpuError::ObjectTooLarge { object, what: "attribute pool", limit: l, .. }
            if object == "Big sphere" && *l == limit),
        "{err:?}"
    );
    assert!(err.to_string().contains("Big sphere"), "{err}");
}

#[test]
fn an_edit_in_the_second_chunk_uploads_only_its_ranges() {
    let mut doc = four_spheres();
    let ctx = low_limit_context(two_sphere_limit(&doc));
    let q = doc.quality.clone();
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let (before, _, first) = gpu_frame(&ctx, &mut r, &doc, SIZE, &q);
    assert!(first.upload.full);
    assert_eq!(r.pool_chunks(), 2);
    // Paint the top of the last sphere (chunk 1) in place: pool lengths stay, so only the
    // announced region tells the renderer what changed.
    let (id, svo) = svo_of(&mut doc, "Sphere 4");
    let edit = svo
        .edit_existing(UVec3::new(0, 36, 0), UVec3::new(63, 63, 63), |_, v| {
            Some(Voxel {
                color: [30, 200, 60, 255],
                ..v
            })
        })
        .expect("edit");
    let (lo, hi) = edit.changed.expect("voxels changed");
    let up = r
        .update_voxel_region(&ctx.device, &ctx.queue, &doc, id, lo, hi)
        .expect("update");
    assert!(!up.full, "{up:?}");
    assert!(
        up.bytes > 0 && up.bytes * 4 < first.upload.bytes,
        "{up:?} vs a full upload of {} bytes",
        first.upload.bytes
    );
    let mut fresh = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let (full, full_g, _) = gpu_frame(&ctx, &mut fresh, &doc, SIZE, &q);
    assert!(before.pixels != full.pixels, "the paint is visible");
    assert_uploaded_frame_is(&ctx, &mut r, &doc, (&full, &full_g));
}

/// Draws `doc` with what `r` has uploaded (which must need no upload) and checks the image and
/// G-buffer equal `fresh`, a full upload's.
fn assert_uploaded_frame_is(
    ctx: &GpuContext,
    r: &mut Renderer,
    doc: &Document,
    fresh: (&thicket_core::render::RgbaImage, &thicket::gpu::GBuffer),
) {
    let target = thicket::gpu::RenderTarget::new(&ctx.device, SIZE.0, SIZE.1).expect("target");
    let stats = r
        .render_uploaded(
            &ctx.device,
            &ctx.queue,
            doc,
            &target.view(&doc.camera, &doc.quality),
            &target,
        )
        .expect("frame");
    assert!(!stats.upload.full && stats.upload.bytes == 0, "{stats:?}");
    assert_eq!(
        stats.queue_overflow, 0,
        "an overflowing frame is not reproducible"
    );
    let inc = thicket::gpu::read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    let inc_g = r.read_gbuffer(&ctx.device, &ctx.queue).expect("G-buffer");
    assert!(
        inc == fresh.0.pixels,
        "the uploaded scene draws unlike a full upload"
    );
    assert!(&inc_g == fresh.1, "G-buffers differ");
    assert!(ctx.errors.take().is_none());
}

#[test]
fn a_pool_that_outgrows_its_room_moves_chunks_without_a_full_upload() {
    let mut doc = four_spheres();
    let limit = two_sphere_limit(&doc);
    let ctx = low_limit_context(limit);
    let q = doc.quality.clone();
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let (before, _, first) = gpu_frame(&ctx, &mut r, &doc, SIZE, &q);
    assert!(first.upload.full);
    assert_eq!(r.pool_chunks(), 2);
    // Fill a slab through the second sphere (chunk 0, after the first): more nodes than its
    // pools' spare room (but few enough for this small binding limit's traversal queues), so
    // they need larger buffers, and chunk 0 can no longer hold both.
    let (id, svo) = svo_of(&mut doc, "Sphere 2");
    let edit = svo
        .edit_region(UVec3::new(8, 30, 8), UVec3::new(55, 33, 55), |_, _| {
            Some(Voxel::new([200, 40, 40, 255], Vec3::Y))
        })
        .expect("edit");
    let (lo, hi) = edit.changed.expect("voxels changed");
    let up = r
        .update_voxel_region(&ctx.device, &ctx.queue, &doc, id, lo, hi)
        .expect("update");
    assert!(!up.full && up.grown, "{up:?}");
    assert_eq!(
        r.pool_chunks(),
        3,
        "the grown sphere moved to a chunk of its own"
    );
    // Every other sphere's nodes were already on the GPU: they are copied there, not sent.
    let mut fresh = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let (full, full_g, full_stats) = gpu_frame(&ctx, &mut fresh, &doc, SIZE, &q);
    // Overflowing queues drop nodes in whatever order the atomics run: no exact comparison.
    assert_eq!(full_stats.queue_overflow, 0, "the slab fits the queues");
    assert!(
        up.copied_bytes > 0 && up.bytes + up.copied_bytes <= full_stats.upload.bytes,
        "{up:?} vs a full upload of {:?}",
        full_stats.upload
    );
    assert!(before.pixels != full.pixels, "the slab is visible");
    assert_uploaded_frame_is(&ctx, &mut r, &doc, (&full, &full_g));
}

//! GPU renderer against the CPU reference renderer (`thicket_core::render::render_document`),
//! frame by frame: the sample projects and synthetic scenes, both splat paths. One tolerance
//! (`Tolerance::GPU_PARITY`, in `thicket_core::measure::image`) for every scene: at least 99 %
//! of pixels within a few 8-bit steps, the same coverage, the same depth.
//!
//! On failure the three images (CPU, GPU, difference) are written to the system temp directory
//! and named in the message. Runs on whatever adapter is present (lavapipe in CI); never skipped.

use glam::{Quat, Vec3};
use thicket::gpu::{GpuContext, RenderTarget, Renderer, read_rgba8};
use thicket_core::measure::image::{Parity, Tolerance};
use thicket_core::quality::Quality;
use thicket_core::render::{RgbaImage, View, render_document, scenes};
use thicket_core::scene::{Document, Light, ObjectKind};
use thicket_core::skin::StretchStrategy;

mod common;
use common::gpu::{assert_same_as_full_upload, context, cpu_gpu_parity, gpu_frame, project};

struct Comparison {
    parity: Parity,
    splats_cpu: u64,
    splats_gpu: u64,
}

/// Renders `doc` on the CPU and on the GPU (the 64-bit path when the adapter has it, unless
/// `two_pass`), compares them and writes the images on failure.
fn compare(
    ctx: &GpuContext,
    name: &str,
    doc: &Document,
    size: (u32, u32),
    quality: &Quality,
    two_pass: bool,
) -> Comparison {
    let cam = doc.camera;
    let req = View {
        width: size.0,
        height: size.1,
        camera: Some(cam),
        quality: quality.clone(),
    };
    let (cpu, fb, cpu_stats) = render_document(doc, &req).expect("CPU frame");
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    r.set_force_two_pass(two_pass);
    let (gpu, g, stats) = gpu_frame(ctx, &mut r, doc, size, quality);
    let path = if two_pass {
        "two-pass 32-bit"
    } else {
        "64-bit"
    };
    let stem = format!("{name}-{}", if two_pass { "32" } else { "64" });
    let p = cpu_gpu_parity("thicket-gpu-parity", &stem, &cam, (&cpu, &fb), (&gpu, &g));
    eprintln!(
        "{name} ({path}): {p:?}; splats CPU {} GPU {}",
        cpu_stats.splats(),
        stats.splats
    );
    Comparison {
        parity: p,
        splats_cpu: cpu_stats.splats(),
        splats_gpu: stats.splats,
    }
}

fn both_paths(ctx: &GpuContext, name: &str, doc: &Document, size: (u32, u32), q: &Quality) {
    let key64 = Renderer::new(&ctx.device, &ctx.queue)
        .expect("renderer")
        .capabilities()
        .int64_atomics;
    assert!(
        key64,
        "this adapter has no SHADER_INT64_ATOMIC_MIN_MAX: the 64-bit path cannot be tested here"
    );
    for two_pass in [false, true] {
        let c = compare(ctx, name, doc, size, q, two_pass);
        // Same LOD decisions on both sides: the splat counts agree (occlusion culling on the
        // CPU only removes hidden nodes, so the GPU may splat a few more).
        assert!(c.parity.both_covered > 0, "{name}: nothing drawn");
        assert!(
            c.splats_gpu >= c.splats_cpu,
            "{name}: GPU {} splats < CPU {}",
            c.splats_gpu,
            c.splats_cpu
        );
    }
}

#[test]
fn house_sample_matches_the_cpu_reference() {
    let ctx = context();
    let doc = project("house");
    both_paths(&ctx, "house", &doc, (96, 80), &doc.quality.clone());
}

#[test]
fn mixed_sample_matches_the_cpu_reference() {
    let ctx = context();
    let doc = project("mixed");
    both_paths(&ctx, "mixed", &doc, (96, 80), &doc.quality.clone());
}

#[test]
fn terrain_sample_matches_the_cpu_reference() {
    // The enhanced terrain (the fine model detail enhancement made from the coarse one) under
    // the low sun that makes its terraces cast shadows.
    let ctx = context();
    let doc = project("terrain");
    both_paths(&ctx, "terrain", &doc, (96, 80), &doc.quality.clone());
}

/// `doc` seen through an orthographic camera with its clip planes fitted to the scene (as the
/// editor's 5 key and axis views do).
fn orthographic(mut doc: Document) -> Document {
    doc.camera.orthographic = true;
    let (lo, hi) = doc.bounds().expect("a scene with bounds");
    doc.camera.fit_clip(lo, hi);
    doc
}

#[test]
fn house_sample_in_an_orthographic_view_matches_the_cpu_reference() {
    let ctx = context();
    let doc = orthographic(project("house"));
    both_paths(&ctx, "house-ortho", &doc, (96, 80), &doc.quality.clone());
}

#[test]
fn exact_cubes_up_close_match_the_cpu_reference() {
    // A wall of the house seen obliquely from a few voxels away: its leaves are tens of pixels
    // wide, so both renderers draw them as exact cubes (per-pixel depth, face normals) and
    // shadow them through maps drawn the same way.
    let ctx = context();
    let mut doc = project("house");
    doc.camera = scenes::house_close_up(&doc).expect("the house has bounds");
    both_paths(
        &ctx,
        "house-close-up",
        &doc,
        (640, 480),
        &doc.quality.clone(),
    );
}

#[test]
fn synthetic_mixed_scene_in_an_orthographic_view_matches_the_cpu_reference() {
    // Meshes (two-sided lighting towards the view axis) and voxels, shadows, specular.
    let ctx = context();
    let doc = orthographic(scenes::mixed_document(7).expect("scene"));
    both_paths(
        &ctx,
        "synthetic-mixed-ortho",
        &doc,
        (112, 96),
        &Quality::default(),
    );
}

#[test]
fn synthetic_mixed_scene_matches_the_cpu_reference() {
    // Voxel sphere, rotated and scaled mesh cube, ground: meshes and voxels occluding and
    // shadowing each other, PCF 2, 4 AO samples (the presets ship AO off or at 16).
    let ctx = context();
    let doc = scenes::mixed_document(7).expect("scene");
    let q = Quality {
        shadow_pcf_radius: 2,
        ao_samples: 4,
        ..Quality::default()
    };
    both_paths(&ctx, "synthetic-mixed", &doc, (112, 96), &q);
}

#[test]
fn rotated_voxels_without_shadows_match_the_cpu_reference() {
    // A voxel object under a rotation and non-uniform scale, close enough that the LOD stops
    // above the leaves, and a coarse LOD threshold (splats several pixels wide).
    let ctx = context();
    let mut doc = scenes::sphere_document(7, 0.8).expect("scene");
    if let Some(o) = doc.objects.first_mut() {
        o.transform.rotation = Quat::from_euler(glam::EulerRot::YXZ, 0.6, 0.3, 0.1);
        o.transform.scale = Vec3::new(1.0, 0.7, 1.2);
    }
    doc.camera.distance = 3.0;
    let q = Quality {
        shadows: false,
        lod_pixel_threshold: 3.0,
        ..Quality::default()
    };
    both_paths(&ctx, "rotated-sphere", &doc, (80, 80), &q);
}

#[test]
fn ambient_occlusion_darkens_on_the_gpu_as_on_the_cpu() {
    // AO on the GPU is not a no-op that happens to agree: without it the same frame differs,
    // only ever brighter (it scales the ambient term alone); with another sample count (8,
    // another kernel than the synthetic parity scene's 4) both renderers still agree on both paths.
    let ctx = context();
    let doc = scenes::mixed_document(7).expect("scene");
    let size = (112, 96);
    let gpu_image = |q: &Quality| {
        let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
        let target = RenderTarget::new(&ctx.device, size.0, size.1).expect("target");
        r.render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, q),
            &target,
        )
        .expect("GPU frame");
        read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback")
    };
    let with = Quality {
        ao_samples: 8,
        ..Quality::default()
    };
    let without = Quality {
        ao_samples: 0,
        ..Quality::default()
    };
    let (a, b) = (gpu_image(&with), gpu_image(&without));
    let mut darker = 0;
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        assert!(
            pa.iter().zip(pb).all(|(x, y)| x <= y),
            "AO brightened a pixel: {pa:?} vs {pb:?} without AO"
        );
        if pa != pb {
            darker += 1;
        }
    }
    let pixels = size.0 * size.1;
    assert!(
        darker * 100 >= pixels,
        "AO darkened only {darker} of {pixels} pixels"
    );
    eprintln!("AO darkened {darker} of {pixels} pixels");
    both_paths(&ctx, "synthetic-mixed-ao8", &doc, size, &with);
}

/// The mixed sample (voxel model, rock mesh, ground) with a second shadow-casting light, low
/// and from the side (its shadows fall to the left of the model, the sun's behind it), casting
/// when `casts`; the camera zoomed in (16 degrees) so the shadows cover several percent of a
/// small test image.
fn mixed_with_second_light(casts: bool) -> Document {
    let mut doc = project("mixed");
    assert_eq!(doc.lights.len(), 1, "the mixed sample has one light");
    doc.camera.fov_y_deg = 16.0;
    doc.lights.push(Light {
        name: "Side".into(),
        direction: Vec3::new(-1.0, -0.5, 0.0),
        color: Vec3::new(1.0, 0.85, 0.7),
        intensity: 0.8,
        casts_shadows: casts,
    });
    doc
}

#[test]
fn two_shadow_casting_lights_match_the_cpu_reference() {
    // Every shadow-casting light gets its own map on the GPU, fit, sized, drawn and filtered
    // as the CPU's: the frame agrees on both splat paths.
    let ctx = context();
    let doc = mixed_with_second_light(true);
    both_paths(
        &ctx,
        "mixed-two-lights",
        &doc,
        (96, 80),
        &doc.quality.clone(),
    );
}

/// Pixels of `a` darker than in `b` (some channel by more than the parity tolerance), and
/// whether any pixel of `a` is brighter than in `b` at all.
fn darker_pixels(a: &RgbaImage, b: &RgbaImage) -> (Vec<bool>, bool) {
    let mut brighter = false;
    let darker = a
        .pixels
        .chunks_exact(4)
        .zip(b.pixels.chunks_exact(4))
        .map(|(pa, pb)| {
            brighter |= pa.iter().zip(pb).any(|(x, y)| x > y);
            pa.iter().zip(pb).any(|(x, y)| {
                i32::from(*y) - i32::from(*x) > i32::from(Tolerance::GPU_PARITY.channel)
            })
        })
        .collect();
    (darker, brighter)
}

#[test]
fn the_second_light_shadows_through_its_own_map() {
    // Turning the second light's shadows on must darken, on the GPU, the pixels its own map
    // shadows, where the CPU darkens them: a renderer that mapped only the first light would
    // leave the frame unchanged. Its map is also drawn: the shadow traversal (summed over
    // maps, as the CPU counts it) visits more nodes.
    let ctx = context();
    let size = (96, 80);
    let (on, off) = (
        mixed_with_second_light(true),
        mixed_with_second_light(false),
    );
    let q = on.quality.clone();
    let cpu = |doc: &Document| {
        let req = View {
            width: size.0,
            height: size.1,
            camera: Some(doc.camera),
            quality: q.clone(),
        };
        render_document(doc, &req).expect("CPU frame")
    };
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let (gpu_on, _, stats_on) = gpu_frame(&ctx, &mut r, &on, size, &q);
    let (gpu_off, _, stats_off) = gpu_frame(&ctx, &mut r, &off, size, &q);
    let ((cpu_on, _, cpu_stats_on), (cpu_off, _, cpu_stats_off)) = (cpu(&on), cpu(&off));
    let (gpu_dark, gpu_brighter) = darker_pixels(&gpu_on, &gpu_off);
    let (cpu_dark, cpu_brighter) = darker_pixels(&cpu_on, &cpu_off);
    assert!(!gpu_brighter, "a shadow map brightened a GPU pixel");
    assert!(!cpu_brighter, "a shadow map brightened a CPU pixel");
    let count = |m: &[bool]| m.iter().filter(|&&d| d).count();
    let pixels = (size.0 * size.1) as usize;
    let disagree = gpu_dark
        .iter()
        .zip(&cpu_dark)
        .filter(|(a, b)| a != b)
        .count();
    eprintln!(
        "light 2's shadow darkens {} GPU and {} CPU pixels of {pixels}; {disagree} disagree",
        count(&gpu_dark),
        count(&cpu_dark)
    );
    assert!(
        count(&cpu_dark) * 50 >= pixels,
        "the CPU darkens only {} pixels: the test scene does not exercise light 2's shadow",
        count(&cpu_dark)
    );
    assert!(
        count(&gpu_dark) * 50 >= pixels,
        "the GPU darkens only {} pixels with light 2's shadow on",
        count(&gpu_dark)
    );
    // Shadow edges may fall a pixel apart (the parity tolerance allows 1 % of pixels to
    // differ); the shadowed regions are the same.
    assert!(
        disagree * 100 <= pixels,
        "{disagree} pixels are shadowed by light 2 on one renderer only"
    );
    let visited = |l: &[thicket_core::render::LevelStats]| l.iter().map(|l| l.visited).sum::<u64>();
    let (g_on, g_off) = (
        visited(&stats_on.shadow_levels),
        visited(&stats_off.shadow_levels),
    );
    let (c_on, c_off) = (
        visited(&cpu_stats_on.shadow_levels),
        visited(&cpu_stats_off.shadow_levels),
    );
    eprintln!("shadow nodes visited: GPU {g_off} -> {g_on}, CPU {c_off} -> {c_on}");
    assert!(g_on > g_off && c_on > c_off);
}

/// The cesiumman sample (19 joints, walk clip, `Adaptive` stretch) at `time_secs` of its clip.
fn cesiumman_at(time_secs: f32) -> Document {
    let mut doc = project("cesiumman");
    let mut rigs = 0;
    for o in &mut doc.objects {
        if let ObjectKind::Voxels(v) = &mut o.kind
            && let Some(rig) = &mut v.rig
        {
            rig.playback.time_secs = time_secs;
            rigs += 1;
        }
    }
    assert_eq!(rigs, 1, "cesiumman has one rigged model");
    doc
}

fn rig_mut(doc: &mut Document) -> &mut thicket_core::skin::Rig {
    doc.objects
        .iter_mut()
        .find_map(|o| match &mut o.kind {
            ObjectKind::Voxels(v) => v.rig.as_mut(),
            _ => None,
        })
        .expect("a rigged model")
}

/// Linear-blend skinning per node on the GPU (Adaptive stretch, culling boxes, skinned
/// normals, posed shadow-map bounds) against the CPU's `SkinDeform` at one pose of the walk,
/// on both splat paths.
fn skinned_cesiumman_matches_at(t: f32) {
    let ctx = context();
    let doc = cesiumman_at(t);
    both_paths(
        &ctx,
        &format!("cesiumman-t{t}"),
        &doc,
        (128, 128),
        &doc.quality.clone(),
    );
}

#[test]
fn a_skinned_model_shadows_through_every_lights_map() {
    // The posed model is traversed into each light's map with its skinning (the second light
    // low from the side, so its shadow falls apart from the sun's), on both splat paths.
    let ctx = context();
    let mut doc = cesiumman_at(0.5);
    doc.lights.push(Light {
        name: "Side".into(),
        direction: Vec3::new(1.0, -0.5, 0.3),
        intensity: 0.7,
        ..Light::default()
    });
    both_paths(
        &ctx,
        "cesiumman-two-lights",
        &doc,
        (96, 96),
        &doc.quality.clone(),
    );
}

#[test]
fn skinned_cesiumman_matches_the_cpu_reference_at_0s() {
    skinned_cesiumman_matches_at(0.0);
}

#[test]
fn skinned_cesiumman_matches_the_cpu_reference_at_0_5s() {
    skinned_cesiumman_matches_at(0.5);
}

#[test]
fn skinned_cesiumman_matches_the_cpu_reference_at_1_1s() {
    skinned_cesiumman_matches_at(1.1);
}

#[test]
fn every_stretch_strategy_and_overrides_match_the_cpu_reference() {
    // The strategies the sample does not use, and per-voxel artist overrides (which replace
    // the strategy's factor), at a pose where joints bend. Different strategies draw
    // different images (checked), and the GPU follows each.
    let ctx = context();
    let base = cesiumman_at(0.5);
    let size = (96, 96);
    let mut images = Vec::new();
    for (name, strategy, overrides) in [
        ("off", StretchStrategy::Off, false),
        ("thesis", StretchStrategy::Thesis, false),
        ("corners", StretchStrategy::Corners, true),
    ] {
        let mut doc = base.clone();
        let rig = rig_mut(&mut doc);
        rig.stretch.strategy = strategy;
        if overrides {
            // A stripe of leaves drawn at 3x: every 7th leaf along the model.
            let svo = doc
                .objects
                .iter()
                .find_map(|o| match &o.kind {
                    ObjectKind::Voxels(v) => Some(v.svo.clone()),
                    _ => None,
                })
                .expect("voxels");
            let mut n = 0u32;
            let rig = rig_mut(&mut doc);
            svo.for_each_leaf(|c, _| {
                n += 1;
                if n.is_multiple_of(7) {
                    rig.stretch_overrides
                        .set(c, thicket_core::skin::stretch::encode_override(3.0));
                }
            });
            assert!(!rig.stretch_overrides.is_empty());
        }
        let c = compare(
            &ctx,
            &format!("cesiumman-{name}"),
            &doc,
            size,
            &doc.quality,
            false,
        );
        assert!(c.parity.both_covered > 0);
        compare(
            &ctx,
            &format!("cesiumman-{name}"),
            &doc,
            size,
            &doc.quality,
            true,
        );
        let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
        images.push(gpu_frame(&ctx, &mut r, &doc, size, &doc.quality).0.pixels);
    }
    assert_ne!(images[0], images[1], "Off and Thesis drew the same image");
    assert_ne!(
        images[1], images[2],
        "Thesis and Corners drew the same image"
    );
}

#[test]
fn the_quality_strategy_override_matches_the_cpu_reference() {
    // `Quality::stretch_strategy` overrides the model's own (Adaptive) for the whole frame:
    // the GPU follows it (Thesis needs no corner weights, so the skin data is rebuilt without
    // them), matching the CPU, and draws what the model set to Thesis itself draws.
    let ctx = context();
    let doc = cesiumman_at(0.5);
    let size = (96, 96);
    let q = Quality {
        stretch_strategy: Some(StretchStrategy::Thesis),
        ..doc.quality.clone()
    };
    for two_pass in [false, true] {
        compare(&ctx, "cesiumman-override", &doc, size, &q, two_pass);
    }
    let gpu_image = |doc: &Document, q: &Quality| {
        let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
        gpu_frame(&ctx, &mut r, doc, size, q).0.pixels
    };
    let mut own = doc.clone();
    rig_mut(&mut own).stretch.strategy = StretchStrategy::Thesis;
    assert_eq!(gpu_image(&doc, &q), gpu_image(&own, &own.quality));
    assert_ne!(gpu_image(&doc, &q), gpu_image(&doc, &doc.quality));
}

#[test]
fn a_new_clip_time_uploads_only_the_joint_matrices() {
    // After the first frame, moving the clip time re-uploads nothing but the 19 joint
    // matrices, and the frame equals a fresh full upload at that time; the same time again
    // uploads nothing.
    let ctx = context();
    let mut doc = cesiumman_at(0.0);
    let size = (64, 64);
    let q = doc.quality.clone();
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let target = RenderTarget::new(&ctx.device, size.0, size.1).expect("target");
    let first = r
        .render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("first frame");
    assert!(first.upload.full && first.upload.skin_data);
    let joints = rig_mut(&mut doc).skeleton.joints.len() as u64;
    assert_eq!(joints, 19);
    assert_eq!(first.upload.joint_bytes, joints * 64);
    rig_mut(&mut doc).playback.time_secs = 0.7;
    let moved = r
        .render_uploaded(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("moved frame");
    assert!(
        !moved.upload.full && !moved.upload.skin_data,
        "{:?}",
        moved.upload
    );
    assert_eq!(moved.upload.joint_bytes, joints * 64);
    assert_eq!(moved.upload.bytes, joints * 64, "{:?}", moved.upload);
    assert_eq!(moved.upload.writes, 1);
    let incremental = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    let same = r
        .render_uploaded(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("same frame");
    assert_eq!(same.upload.bytes, 0, "{:?}", same.upload);
    let mut fresh = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    fresh
        .render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("full frame");
    let full = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    let first_image = {
        let d0 = cesiumman_at(0.0);
        fresh
            .render(
                &ctx.device,
                &ctx.queue,
                &d0,
                &target.view(&d0.camera, &q),
                &target,
            )
            .expect("t = 0 frame");
        read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback")
    };
    let differing = |a: &[u8], b: &[u8]| {
        a.chunks_exact(4)
            .zip(b.chunks_exact(4))
            .filter(|(x, y)| x != y)
            .count()
    };
    assert_eq!(
        differing(&incremental, &full),
        0,
        "pixels where the incremental pose upload differs from a full upload"
    );
    assert!(
        differing(&full, &first_image) > 0,
        "the pose change did not show"
    );

    // Switching from Adaptive to Thesis drops the corner weights (a skin-data rebuild, smaller),
    // and the frame still equals a fresh full upload.
    rig_mut(&mut doc).stretch.strategy = StretchStrategy::Thesis;
    let switched = r
        .render_uploaded(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("switched frame");
    assert!(
        switched.upload.skin_data && !switched.upload.full,
        "{:?}",
        switched.upload
    );
    assert!(
        switched.upload.bytes < first.upload.bytes,
        "{:?} vs {:?}",
        switched.upload,
        first.upload
    );
    eprintln!(
        "uploads: first frame (pools + Adaptive skin data + joints) {:?}; Thesis skin data {:?}",
        first.upload, switched.upload
    );
    let thesis = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    fresh
        .render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("full frame");
    let thesis_full = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    assert_eq!(differing(&thesis, &thesis_full), 0);
}

#[test]
fn sculpting_a_rigged_model_rebuilds_its_skin_data_and_matches_a_full_upload() {
    // An edit of a rigged model's voxels uploads the changed node ranges and rebuilds the skin
    // data (node weights, corner weights and subtree joints follow the new pools); the frame
    // equals a fresh full upload and shows the cut.
    let ctx = context();
    let mut doc = cesiumman_at(0.5);
    let size = (64, 64);
    let q = doc.quality.clone();
    let target = RenderTarget::new(&ctx.device, size.0, size.1).expect("target");
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    r.render(
        &ctx.device,
        &ctx.queue,
        &doc,
        &target.view(&doc.camera, &q),
        &target,
    )
    .expect("first frame");
    let before = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    let (id, svo) = doc
        .objects
        .iter_mut()
        .find_map(|o| match &mut o.kind {
            ObjectKind::Voxels(v) if v.rig.is_some() => Some((o.id, &mut v.svo)),
            _ => None,
        })
        .expect("the rigged model");
    // A slab through the torso removed.
    let edit = svo
        .edit_region(
            glam::UVec3::new(0, 110, 0),
            glam::UVec3::new(63, 125, 255),
            |_, _| None,
        )
        .expect("edit");
    let (lo, hi) = edit.changed.expect("voxels removed");
    let up = r
        .update_voxel_region(&ctx.device, &ctx.queue, &doc, id, lo, hi)
        .expect("region upload");
    assert!(!up.full, "{up:?}");
    let s = r
        .render_uploaded(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("edited frame");
    assert!(s.upload.skin_data && !s.upload.full, "{:?}", s.upload);
    let full = assert_same_as_full_upload(&ctx, &doc, &q, &target);
    assert!(before != full, "the cut does not show");
    assert!(ctx.errors.take().is_none());
}

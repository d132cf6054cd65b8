//! The GPU KRS pass (`shaders/krs_trace.wgsl`) against the CPU reference renderer on the KRS
//! sample projects and on a scene where KRS, voxels and meshes occlude each other. Same
//! tolerance as `gpu_parity.rs` (`Tolerance::GPU_PARITY`: at least 99 % of pixels within
//! 3/255, the same coverage, the same depth); never loosened. On failure the CPU, GPU and
//! difference images are written to the system temp directory and named in the message.

use glam::{Quat, Vec3};
use thicket::gpu::{GpuContext, GpuFrameStats, Renderer};
use thicket_core::krs::{
    BoxKernel, CapsuleKernel, Distortion, EmptyZone, Kernel, KrsObject, Material, MirrorPlane,
    Pattern, PlaneKernel, Similarity, SphereKernel, TextureMode, Texturing, TorusKernel,
};
use thicket_core::measure::image::Parity;
use thicket_core::quality::Quality;
use thicket_core::render::{View, render_document, scenes};
use thicket_core::scene::{Document, Light, ObjectKind};

mod common;
use common::gpu::{context, cpu_gpu_parity, gpu_frame, project};

/// Renders `doc` on both renderers and asserts parity; returns the comparison and the GPU
/// frame's statistics.
fn compare(
    ctx: &GpuContext,
    name: &str,
    doc: &Document,
    size: (u32, u32),
) -> (Parity, GpuFrameStats, Renderer) {
    let quality = doc.quality.clone();
    let cam = doc.camera;
    let req = View {
        width: size.0,
        height: size.1,
        camera: Some(cam),
        quality: quality.clone(),
    };
    let t0 = std::time::Instant::now();
    let (cpu, fb, cpu_stats) = render_document(doc, &req).expect("CPU frame");
    let t1 = std::time::Instant::now();
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let t2 = std::time::Instant::now();
    let (gpu, g, stats) = gpu_frame(ctx, &mut r, doc, size, &quality);
    eprintln!(
        "{name}: CPU frame {:.0} ms, renderer {:.0} ms, GPU frame {:.0} ms (incl. readback)",
        (t1 - t0).as_secs_f64() * 1e3,
        (t2 - t1).as_secs_f64() * 1e3,
        t2.elapsed().as_secs_f64() * 1e3
    );
    eprintln!(
        "{name}:\n  CPU KRS: rays {} hits {} steps {} ({:.1}/ray) exhausted {}\n  GPU KRS: {:?} ({:.1}/ray)",
        cpu_stats.krs.rays,
        cpu_stats.krs.hits,
        cpu_stats.krs.steps,
        cpu_stats.krs.steps as f64 / cpu_stats.krs.rays.max(1) as f64,
        cpu_stats.krs.exhausted,
        stats.krs,
        stats.krs.steps_per_ray(),
    );
    let p = cpu_gpu_parity("thicket-gpu-krs", name, &cam, (&cpu, &fb), (&gpu, &g));
    eprintln!("{name}: {p:?}");
    // The KRS pass did the drawing: it traced rays and hit, as the CPU's did.
    assert!(
        stats.krs.rays > 0 && stats.krs.hits > 0,
        "{name}: {:?}",
        stats.krs
    );
    assert!(cpu_stats.krs.hits > 0, "{name}: the CPU drew no KRS");
    assert!(p.both_covered > 0, "{name}: nothing drawn");
    (p, stats, r)
}

#[test]
fn tree_sample_matches_the_cpu_reference() {
    let ctx = context();
    compare(&ctx, "tree", &project("tree"), (96, 96));
}

#[test]
fn tree_sample_in_an_orthographic_view_matches_the_cpu_reference() {
    // Parallel rays from the near plane (behind the eye when the planes are fitted).
    let ctx = context();
    let mut doc = project("tree");
    doc.camera.orthographic = true;
    let (lo, hi) = doc.bounds().expect("the tree has bounds");
    doc.camera.fit_clip(lo, hi);
    compare(&ctx, "tree-ortho", &doc, (96, 96));
}

#[test]
fn rock_sample_matches_the_cpu_reference() {
    // Battered rocks: 14 reflection levels of planar kernels, distorted (Lipschitz-bounded
    // warp, Algorithm 2 through it) and triplanar-textured.
    let ctx = context();
    compare(&ctx, "rock", &project("rock"), (96, 96));
}

#[test]
fn grassland_coral_and_woodland_samples_match_the_cpu_reference() {
    // KRS terrain sharing its reflections with grass (about a million blades), a distorted
    // coral reef (terrain and corals warped alike) and a forest of 2^14 trees; Algorithm 2
    // through the warp on the coral and its floor.
    let ctx = context();
    for name in ["grassland", "coral", "woodland"] {
        compare(&ctx, name, &project(name), (96, 96));
    }
}

#[test]
fn ambient_occlusion_on_krs_matches_the_cpu_reference() {
    // The samples ship AO off (balanced); with 8 samples both renderers take the screen AO
    // radius from the bounded KRS balls too (the rock is KRS only), skip KRS surfaces as
    // screen occluders (the KRS distance AO counts them), and weigh the distance samples by
    // their height over the reach. The AO must show (the CPU image changes) and the GPU
    // follow it.
    let ctx = context();
    for name in ["tree", "rock"] {
        let mut doc = project(name);
        doc.quality.ao_samples = 8;
        let (_, stats, _) = compare(&ctx, &format!("{name}-ao8"), &doc, (96, 96));
        assert!(stats.krs.ao_evals > 0, "{name}: {:?}", stats.krs);
        let cpu = |ao: u32| {
            let mut q = doc.quality.clone();
            q.ao_samples = ao;
            let req = thicket_core::render::View {
                width: 96,
                height: 96,
                camera: None,
                quality: q,
            };
            thicket_core::render::render_document(&doc, &req)
                .expect("CPU frame")
                .0
        };
        assert_ne!(cpu(8), cpu(0), "{name}: AO changed nothing on the CPU");
    }
}

#[test]
fn forest_sample_matches_the_cpu_reference() {
    // 33M kernel instances, mirrors thousands of units out: the f32 folding must hold.
    let ctx = context();
    let (_, stats, _) = compare(&ctx, "forest", &project("forest"), (96, 96));
    assert!(stats.krs.max_steps > 0 && stats.krs.max_steps <= 160);
}

#[test]
fn forest_far_from_the_origin_matches_in_f32() {
    // The GPU folds in f32 (the CPU in f64): close to trees 2,000 units out, where an f32
    // fold loses the most (ulp 1.2e-4 per level, 24 levels) and the pixel-cone epsilon is
    // smallest (a few centimetres at 12 units), the images must still agree.
    let ctx = context();
    let mut doc = project("forest");
    doc.camera.target = Vec3::new(2000.0, 3.0, -1900.0);
    doc.camera.distance = 12.0;
    doc.camera.pitch_deg = 10.0;
    let (p, stats, _) = compare(&ctx, "forest-far", &doc, (80, 80));
    assert!(
        stats.krs.hits * 2 > u64::from(p.total as u32),
        "the view is mostly KRS: {:?}",
        stats.krs
    );
}

/// Every kernel kind (rotated rounded box, torus segments with sweeps above and below π,
/// sphere, half-space ground, a distorted toroidal capsule), mirrors, an empty zone, both
/// texture modes and patterns, a rotated and scaled object, two lights, soft shadows.
fn every_kernel_kind() -> Document {
    let mut doc = Document::default();
    let m = |r: f32, g: f32, b: f32| Material::new(Vec3::new(r, g, b), 0);
    let torus = |centre: Vec3, axis: Vec3, sweep: f32, major: f32, minor: f32| TorusKernel {
        centre,
        axis,
        start_dir: Vec3::X,
        major_radius: major,
        minor_radius: minor,
        sweep_radians: sweep,
        material: m(0.8, 0.5, 0.2),
    };
    let shapes = KrsObject {
        name: "shapes".into(),
        kernels: vec![
            Kernel::RoundedBox(BoxKernel {
                centre: Vec3::new(0.6, 0.35, 0.0),
                rotation: Quat::from_euler(glam::EulerRot::YXZ, 0.4, 0.3, 0.2),
                half_extents: Vec3::new(0.25, 0.2, 0.3),
                rounding: 0.05,
                material: m(0.7, 0.2, 0.2),
            }),
            Kernel::TorusSegment(torus(Vec3::new(0.0, 0.6, 0.0), Vec3::Z, 4.0, 0.45, 0.08)),
            Kernel::TorusSegment(torus(
                Vec3::new(-0.5, 0.35, 0.3),
                Vec3::new(0.2, 1.0, 0.1),
                1.2,
                0.4,
                0.1,
            )),
            Kernel::Sphere(SphereKernel {
                centre: Vec3::new(0.0, 1.0, 0.4),
                radius: 0.2,
                material: m(0.2, 0.6, 0.3),
            }),
            Kernel::InfinitePlane(PlaneKernel {
                normal: Vec3::Y,
                offset: 0.0,
                material: m(0.6, 0.6, 0.55),
            }),
        ],
        mirrors: vec![
            MirrorPlane::new(Vec3::new(1.0, 0.0, 0.3), 0.1),
            MirrorPlane::new(Vec3::Z, 0.2),
            MirrorPlane::new(Vec3::new(1.0, 0.0, -1.0), 0.5),
            MirrorPlane::new(Vec3::new(0.3, 1.0, 0.0), 1.5),
        ],
        texturing: Texturing {
            mode: TextureMode::Triplanar,
            pattern: Pattern::Checker,
            scale: 6.0,
            ..Texturing::default()
        },
        empty_zones: vec![EmptyZone {
            centre: Vec3::new(0.6, 0.45, 0.0),
            radius: 0.15,
        }],
        ..KrsObject::default()
    };
    let branch = KrsObject {
        name: "branch".into(),
        kernels: vec![
            Kernel::ToroidalCapsule(torus(Vec3::new(0.0, 0.0, 0.0), Vec3::Z, 2.0, 0.5, 0.12)),
            Kernel::Capsule(CapsuleKernel {
                start: Vec3::new(0.0, -0.5, 0.0),
                end: Vec3::new(0.3, 0.6, 0.2),
                radius: 0.1,
                material: m(0.4, 0.3, 0.7),
            }),
        ],
        mirrors: vec![MirrorPlane::new(Vec3::new(1.0, 0.2, 0.0), 0.2)],
        world_from_object: Similarity {
            translation: Vec3::new(-0.2, 0.7, -0.8),
            rotation: Quat::from_rotation_x(0.5),
            scale: 0.8,
        },
        distortion: Some(Distortion {
            amplitude: 0.04,
            frequency: 3.0,
            seed: 7,
        }),
        texturing: Texturing {
            mode: TextureMode::KernelParam,
            pattern: Pattern::Bark,
            ..Texturing::default()
        },
        ..KrsObject::default()
    };
    doc.add("shapes", ObjectKind::Krs(shapes));
    let id = doc.add("branch", ObjectKind::Krs(branch));
    if let Some(o) = doc.objects.iter_mut().find(|o| o.id == id) {
        o.transform.translation = Vec3::new(0.1, 0.0, 0.0);
        o.transform.scale = Vec3::splat(1.2);
    }
    doc.lights = vec![
        Light {
            direction: Vec3::new(-0.4, -1.0, -0.3),
            casts_shadows: true,
            ..Light::default()
        },
        Light {
            direction: Vec3::new(0.6, -0.5, 0.4),
            intensity: 0.4,
            casts_shadows: false,
            ..Light::default()
        },
    ];
    doc.camera.target = Vec3::new(0.0, 0.4, 0.0);
    doc.camera.distance = 3.5;
    doc.camera.pitch_deg = 25.0;
    doc.camera.yaw_deg = 30.0;
    doc.quality = Quality {
        krs_soft_shadows: true,
        ..Quality::default()
    };
    doc
}

#[test]
fn every_kernel_kind_matches_the_cpu_reference() {
    let ctx = context();
    compare(&ctx, "every-kernel", &every_kernel_kind(), (96, 80));
}

/// A KRS (a sphere and a capsule, the capsule mirrored) placed across the voxel sphere, the
/// mesh cube and the ground of the synthetic mixed scene.
fn mixed_with_krs() -> Document {
    let mut doc = scenes::mixed_document(6).expect("scene");
    let blue = Material::new(Vec3::new(0.15, 0.3, 0.8), 1);
    let krs = KrsObject {
        name: "crossing".into(),
        kernels: vec![
            Kernel::Capsule(CapsuleKernel {
                start: Vec3::new(-0.9, 0.35, 0.25),
                end: Vec3::new(0.2, 0.8, 0.3),
                radius: 0.14,
                material: blue,
            }),
            Kernel::Sphere(SphereKernel {
                centre: Vec3::new(-0.55, 0.45, 0.75),
                radius: 0.3,
                material: Material::new(Vec3::new(0.2, 0.7, 0.3), 2),
            }),
        ],
        mirrors: vec![MirrorPlane::new(Vec3::new(1.0, 0.0, 0.2), 0.35)],
        world_from_object: Similarity::default(),
        ..KrsObject::default()
    };
    doc.add("KRS", ObjectKind::Krs(krs));
    doc.quality = Quality::default();
    doc
}

#[test]
fn krs_voxels_and_meshes_occlude_each_other_as_on_the_cpu() {
    let ctx = context();
    let doc = mixed_with_krs();
    let size = (96, 80);
    let (_, _, mut r) = compare(&ctx, "mixed-krs", &doc, size);

    // The same frame with only the KRS, and with everything but the KRS: in the full frame
    // the KRS must win some pixels that the others cover and lose some that it covers.
    let mut only = |keep_krs: bool| {
        let mut d = doc.clone();
        for o in &mut d.objects {
            o.visible = matches!(o.kind, ObjectKind::Krs(_)) == keep_krs;
        }
        gpu_frame(&ctx, &mut r, &d, size, &d.quality.clone()).1
    };
    let (krs, rest) = (only(true), only(false));
    let (_, all, _) = gpu_frame(&ctx, &mut r, &doc, size, &doc.quality.clone());
    let (mut krs_in_front, mut krs_behind) = (0, 0);
    for i in 0..all.depth.len() {
        let (a, k, r) = (all.depth[i], krs.depth[i], rest.depth[i]);
        if !(k.is_finite() && r.is_finite()) {
            continue;
        }
        if k < r && a == k {
            krs_in_front += 1;
        }
        if r < k && a == r {
            krs_behind += 1;
        }
        assert!(
            a == k.min(r),
            "pixel {i}: depth {a} is not the nearer of {k} and {r}"
        );
    }
    eprintln!("KRS in front on {krs_in_front} pixels, behind on {krs_behind}");
    // The two-pass 32-bit splat path leaves the same G-buffer for the KRS pass to trace into.
    r.set_force_two_pass(true);
    let (_, all32, _) = gpu_frame(&ctx, &mut r, &doc, size, &doc.quality.clone());
    assert_eq!(all32.depth, all.depth, "two-pass path: other depths");
    assert_eq!(all32.normal, all.normal, "two-pass path: other normals");
    assert!(
        krs_in_front > 20,
        "KRS in front on only {krs_in_front} pixels"
    );
    assert!(krs_behind > 20, "KRS behind on only {krs_behind} pixels");
}

//! GPU renderer tests on whatever adapter is present (lavapipe in CI): never skipped — no
//! adapter is a failure.

use glam::{Mat3, UVec3, Vec3, Vec4};
use thicket::gpu::{
    AtomicPath, GpuContext, GpuError, GpuFrameStats, RenderTarget, Renderer, read_rgba8,
};
use thicket_core::mesh::{Material, MeshModel, TriangleMesh, unit_cube};
use thicket_core::quality::Quality;
use thicket_core::scene::{Document, MeshObject, ObjectKind, OrbitCamera, Transform, VoxelModel};
use thicket_core::svo::{Svo, Voxel};

const SPHERE_RGB: [u8; 3] = [200, 80, 40];

fn context() -> GpuContext {
    let ctx = GpuContext::new_headless(wgpu::PowerPreference::HighPerformance)
        .expect("a GPU adapter (install mesa-vulkan-drivers for lavapipe)");
    eprintln!("adapter: {}", ctx.describe());
    ctx
}

/// A one-voxel-thick sphere shell in a `2^depth` grid, scaled to radius `0.9` world units at
/// the origin.
fn sphere_model(depth: u8) -> VoxelModel {
    let n = 1u32 << depth;
    let c = Vec3::splat(n as f32 * 0.5);
    let r = n as f32 * 0.45;
    let svo = Svo::from_fn(
        depth,
        false,
        |origin, size| {
            let lo = origin.as_vec3();
            let hi = lo + Vec3::splat(size as f32);
            let nearest = c.clamp(lo, hi).distance(c);
            let farthest = (c - lo).abs().max((c - hi).abs()).length();
            nearest <= r + 1.0 && farthest >= r - 1.0
        },
        |v: UVec3| {
            let p = v.as_vec3() + 0.5 - c;
            ((p.length() - r).abs() <= 0.87).then(|| {
                Voxel::new(
                    [SPHERE_RGB[0], SPHERE_RGB[1], SPHERE_RGB[2], 255],
                    p.normalize_or_zero(),
                )
            })
        },
    )
    .expect("valid depth");
    VoxelModel {
        svo,
        voxel_size: 2.0 / n as f32,
        origin: Vec3::splat(-1.0),
        ..VoxelModel::default()
    }
}

fn camera() -> OrbitCamera {
    OrbitCamera {
        target: Vec3::ZERO,
        yaw_deg: 30.0,
        pitch_deg: 20.0,
        distance: 4.0,
        fov_y_deg: 45.0,
        near: 0.1,
        far: 20.0,
        orthographic: false,
    }
}

fn sphere_doc(depth: u8) -> Document {
    let mut doc = Document::default();
    doc.add("sphere", ObjectKind::Voxels(sphere_model(depth)));
    doc.camera = camera();
    doc
}

fn plane(size: f32, y: f32, color: Vec4) -> MeshModel {
    let h = size * 0.5;
    MeshModel {
        parts: vec![TriangleMesh {
            positions: vec![
                Vec3::new(-h, y, -h),
                Vec3::new(h, y, -h),
                Vec3::new(h, y, h),
                Vec3::new(-h, y, h),
            ],
            normals: vec![Vec3::Y; 4],
            indices: vec![0, 2, 1, 0, 3, 2],
            ..TriangleMesh::default()
        }],
        materials: vec![Material {
            base_color: color,
            ..Material::default()
        }],
    }
}

struct Frame {
    rgba: Vec<u8>,
    gbuffer: thicket::gpu::GBuffer,
    stats: GpuFrameStats,
}

fn render(
    ctx: &GpuContext,
    doc: &Document,
    size: u32,
    quality: &Quality,
    force_two_pass: bool,
) -> Frame {
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    r.set_force_two_pass(force_two_pass);
    let target = RenderTarget::new(&ctx.device, size, size).expect("target");
    let stats = r
        .render(
            &ctx.device,
            &ctx.queue,
            doc,
            &target.view(&doc.camera, quality),
            &target,
        )
        .expect("frame renders");
    let rgba = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    let gbuffer = r.read_gbuffer(&ctx.device, &ctx.queue).expect("gbuffer");
    assert!(ctx.errors.take().is_none(), "uncaptured GPU error");
    Frame {
        rgba,
        gbuffer,
        stats,
    }
}

/// Distance from the sphere centre (origin) to the ray through a pixel centre, and the
/// distance along the ray to the centre's foot point.
fn ray_distance(cam: &OrbitCamera, size: u32, x: u32, y: u32) -> (f32, f32) {
    let f = 0.5 * size as f32 / (0.5 * cam.fov_y_deg.to_radians()).tan();
    let dir_view = Vec3::new(
        (x as f32 + 0.5 - 0.5 * size as f32) / f,
        (0.5 * size as f32 - y as f32 - 0.5) / f,
        -1.0,
    );
    let world_from_view = cam.view_from_world().inverse();
    let dir = (Mat3::from_mat4(world_from_view) * dir_view).normalize_or_zero();
    let eye = cam.eye();
    let to_c = -eye;
    let along = to_c.dot(dir);
    ((to_c - dir * along).length(), along)
}

#[test]
fn adapter_and_atomic_path_are_reported() {
    let ctx = context();
    let r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let caps = r.capabilities();
    eprintln!(
        "int64 atomics: {}, timestamps: {}",
        caps.int64_atomics, caps.timestamps
    );
    assert_eq!(
        r.atomic_path(),
        if caps.int64_atomics {
            AtomicPath::Key64
        } else {
            AtomicPath::TwoPass32
        }
    );
    assert!(ctx.errors.take().is_none());
}

#[test]
fn sphere_silhouette_matches_the_analytic_projection() {
    let ctx = context();
    let doc = sphere_doc(7);
    let size = 128;
    let q = Quality::default();
    let frame = render(&ctx, &doc, size, &q, false);
    let cam = doc.camera;
    let f = 0.5 * size as f32 / (0.5 * cam.fov_y_deg.to_radians()).tan();
    let voxel = 2.0 / 128.0;
    let (r_in, r_out) = (0.9 - voxel, 0.9 + voxel);
    let (mut inside, mut outside, mut wrong) = (0, 0, Vec::new());
    for y in 0..size {
        for x in 0..size {
            let (d, along) = ray_distance(&cam, size, x, y);
            let px = along / f; // world size of a pixel at the sphere's distance
            let covered = frame.gbuffer.depth[(y * size + x) as usize].is_finite();
            if d < r_in - 1.0 * px {
                inside += 1;
                if !covered {
                    wrong.push((x, y, d));
                }
            } else if d > r_out + 1.0 * px {
                outside += 1;
                if covered {
                    wrong.push((x, y, d));
                }
            }
        }
    }
    assert!(inside > 3000 && outside > 3000, "{inside} {outside}");
    assert!(
        wrong.is_empty(),
        "{} pixels disagree: {:?}",
        wrong.len(),
        &wrong[..wrong.len().min(10)]
    );
    // Every covered pixel: finite depth in 0..1, unit normal, the sphere's albedo.
    let albedo = Vec3::new(
        thicket_core::mesh::srgb_to_linear(f32::from(SPHERE_RGB[0]) / 255.0),
        thicket_core::mesh::srgb_to_linear(f32::from(SPHERE_RGB[1]) / 255.0),
        thicket_core::mesh::srgb_to_linear(f32::from(SPHERE_RGB[2]) / 255.0),
    );
    for i in 0..(size * size) as usize {
        let d = frame.gbuffer.depth[i];
        if d.is_finite() {
            assert!((0.0..=1.0).contains(&d), "depth {d}");
            let n = frame.gbuffer.normal[i];
            assert!((n.length() - 1.0).abs() < 2e-3, "normal {n}");
            assert!((frame.gbuffer.albedo[i] - albedo).abs().max_element() < 2e-3);
        }
    }
    assert!(frame.stats.splats > 0);
    assert_eq!(frame.stats.queue_overflow, 0);
}

#[test]
fn depth_agrees_with_the_analytic_sphere() {
    // Where the view ray hits the sphere squarely, the splat depth is the near-side surface:
    // within a voxel (plus a pixel's footprint) of the ray/sphere intersection.
    let ctx = context();
    let doc = sphere_doc(7);
    let size = 96;
    let frame = render(&ctx, &doc, size, &Quality::default(), false);
    let cam = doc.camera;
    let (near, far) = (cam.near, cam.far);
    let view_depth = |ndc: f32| near / (1.0 - ndc * (far - near) / far);
    let mut checked = 0;
    for y in 0..size {
        for x in 0..size {
            let (d, along) = ray_distance(&cam, size, x, y);
            if d > 0.6 {
                continue;
            }
            let t_hit = along - (0.9f32 * 0.9 - d * d).sqrt();
            // View depth = t · cos(angle to the optical axis).
            let (dx, dy) = (
                (x as f32 + 0.5 - 0.5 * size as f32),
                (0.5 * size as f32 - y as f32 - 0.5),
            );
            let f = 0.5 * size as f32 / (0.5 * cam.fov_y_deg.to_radians()).tan();
            let cos = f / (dx * dx + dy * dy + f * f).sqrt();
            let expect = t_hit * cos;
            let got = view_depth(frame.gbuffer.depth[(y * size + x) as usize]);
            assert!(
                (got - expect).abs() < 0.05,
                "pixel {x},{y}: {got} vs {expect}"
            );
            checked += 1;
        }
    }
    assert!(checked > 500, "{checked}");
}

#[test]
fn both_atomic_paths_give_the_same_image() {
    let ctx = context();
    let mut doc = sphere_doc(7);
    let mut cube = unit_cube();
    cube.colors = vec![Vec4::new(0.1, 0.2, 0.9, 1.0); cube.positions.len()];
    doc.add(
        "cube",
        ObjectKind::Mesh(MeshObject {
            model: MeshModel {
                parts: vec![cube],
                materials: Vec::new(),
            },
            casts_shadows: true,
        }),
    );
    if let Some(o) = doc.objects.last_mut() {
        o.transform = Transform {
            translation: Vec3::new(0.5, 0.2, 0.9),
            ..Transform::default()
        };
    }
    let q = Quality::default();
    let two_pass = render(&ctx, &doc, 96, &q, true);
    assert_eq!(two_pass.stats.atomic_path, AtomicPath::TwoPass32);
    let r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    if r.capabilities().int64_atomics {
        let key64 = render(&ctx, &doc, 96, &q, false);
        assert_eq!(key64.stats.atomic_path, AtomicPath::Key64);
        assert_eq!(key64.stats.levels, two_pass.stats.levels);
        assert!(key64.rgba == two_pass.rgba, "images differ");
        assert!(key64.gbuffer == two_pass.gbuffer, "G-buffers differ");
    } else {
        panic!(
            "this adapter has no SHADER_INT64_ATOMIC_MIN_MAX: the 64-bit path cannot be tested here"
        );
    }
}

/// A square plate one voxel thick lying in the first voxel layer (y = 0), covering the middle
/// eighth of the octree in x and z: the same shape at any depth (its nodes at a level up to the
/// shallower depth are the same boxes), `(2^depth / 8)^2` leaves.
fn plate_model(depth: u8) -> VoxelModel {
    let n = 1u32 << depth;
    let (lo, hi) = (n / 2 - n / 16, n / 2 + n / 16);
    let svo = Svo::from_fn(
        depth,
        false,
        |origin, size| {
            origin.y == 0
                && origin.x < hi
                && origin.x + size > lo
                && origin.z < hi
                && origin.z + size > lo
        },
        |v: UVec3| {
            let c = (v.x + v.z) / (n / 64).max(1);
            (v.y == 0 && (lo..hi).contains(&v.x) && (lo..hi).contains(&v.z)).then(|| {
                Voxel::new(
                    [if c.is_multiple_of(2) { 220 } else { 60 }, 120, 90, 255],
                    Vec3::Y,
                )
            })
        },
    )
    .expect("valid depth");
    VoxelModel {
        svo,
        voxel_size: 2.0 / n as f32,
        origin: Vec3::splat(-1.0),
        ..VoxelModel::default()
    }
}

#[test]
fn splat_count_is_resolution_bound() {
    // Paper Fig. 3 on the GPU: the same plate at depth 9 (4,096 leaves) and depth 12 (262,144
    // leaves), seen obliquely with depth-9 voxels below half a pixel: the LOD stops at the
    // pixels, above the leaves of both, so both draw the same splats (within 10 %) whatever the
    // model's resolution.
    let ctx = context();
    let q = Quality {
        shadows: false,
        ..Quality::default()
    };
    let splats = |depth: u8| {
        let mut doc = Document::default();
        doc.add("plate", ObjectKind::Voxels(plate_model(depth)));
        doc.camera = OrbitCamera {
            target: Vec3::new(0.0, -1.0, 0.0),
            pitch_deg: 35.0,
            distance: 1.6,
            ..OrbitCamera::default()
        };
        let f = render(&ctx, &doc, 160, &q, false);
        assert_eq!(f.stats.queue_overflow, 0);
        let covered = f.gbuffer.depth.iter().filter(|d| d.is_finite()).count();
        (f.stats.splats as f64, f.stats.levels.len(), covered)
    };
    let (s9, l9, c9) = splats(9);
    let (s12, l12, c12) = splats(12);
    eprintln!(
        "depth 9: {s9} splats, {l9} levels, {c9} px; depth 12: {s12} splats, {l12} levels, {c12} px"
    );
    assert!(c9 > 300, "the plate covers {c9} pixels");
    // The depth-12 traversal went no deeper than the depth-9 one, and both drew far fewer
    // splats than the depth-9 plate has leaves (4,096): the LOD stopped at the pixels.
    assert_eq!(l12, l9);
    assert!(s9 < 0.5 * 4096.0, "{s9}");
    assert!(
        (s12 / s9 - 1.0).abs() <= 0.10,
        "depth 9: {s9}, depth 12: {s12}"
    );
}

#[test]
fn splat_count_of_a_sphere_follows_pixels_not_voxels() {
    // The same sphere at 8x the voxel resolution (depth 9 vs 6) draws about as many splats.
    let ctx = context();
    let q = Quality::default();
    let mut doc_lo = sphere_doc(6);
    let mut doc_hi = sphere_doc(9);
    // A small image so that depth-6 leaves are already below one pixel.
    for d in [&mut doc_lo, &mut doc_hi] {
        d.camera.distance = 6.0;
    }
    let lo = render(&ctx, &doc_lo, 40, &q, false).stats.splats as f64;
    let hi = render(&ctx, &doc_hi, 40, &q, false).stats.splats as f64;
    eprintln!("splats depth 6: {lo}, depth 9: {hi}");
    assert!(lo > 100.0);
    assert!(
        (hi / lo - 1.0).abs() <= 0.10,
        "depth 6: {lo}, depth 9: {hi}"
    );
}

fn svo_mut(doc: &mut Document) -> &mut Svo {
    match &mut doc.objects[0].kind {
        ObjectKind::Voxels(v) => &mut v.svo,
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => unreachable!("the first object is voxels"),
    }
}

#[test]
fn incremental_upload_equals_a_full_upload() {
    use thicket_core::svo::Voxel;
    let ctx = context();
    let q = Quality::default();
    let mut doc = sphere_doc(6);
    let id = doc.objects[0].id;
    let size = 64;
    let target = RenderTarget::new(&ctx.device, size, size).expect("target");
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let first = r
        .render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("frame");
    assert!(first.upload.full);
    let full_bytes = first.upload.bytes;
    let image = |r: &mut Renderer, incremental: bool, doc: &Document| {
        let stats = if incremental {
            r.render_uploaded(
                &ctx.device,
                &ctx.queue,
                doc,
                &target.view(&doc.camera, &q),
                &target,
            )
        } else {
            r.render(
                &ctx.device,
                &ctx.queue,
                doc,
                &target.view(&doc.camera, &q),
                &target,
            )
        }
        .expect("frame");
        let rgba = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
        let g = r.read_gbuffer(&ctx.device, &ctx.queue).expect("gbuffer");
        (rgba, g, stats)
    };

    // 1. Paint in place: the pools keep their lengths, so only the announced region can tell
    // the renderer what changed.
    let (lo, hi) = (UVec3::new(0, 24, 32), UVec3::new(63, 63, 63));
    let edit = svo_mut(&mut doc)
        .edit_existing(lo, hi, |_, v| {
            Some(Voxel {
                color: [30, 200, 60, 255],
                ..v
            })
        })
        .expect("edit");
    let (clo, chi) = edit.changed.expect("voxels changed");
    let (stale, _, _) = image(&mut r, true, &doc);
    let up = r
        .update_voxel_region(&ctx.device, &ctx.queue, &doc, id, clo, chi)
        .expect("update");
    assert!(!up.full, "{up:?}");
    assert!(
        up.bytes > 0 && up.bytes < full_bytes / 2,
        "{up:?} vs {full_bytes}"
    );
    let (inc, inc_g, inc_stats) = image(&mut r, true, &doc);
    assert!(!inc_stats.upload.full);
    let mut fresh = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let (full, full_g, _) = image(&mut fresh, false, &doc);
    assert!(
        stale != full,
        "the paint is visible (else this test proves nothing)"
    );
    assert!(
        inc == full,
        "image after the incremental upload differs from a full upload"
    );
    assert!(inc_g == full_g, "G-buffers differ");

    // 2. A brush-sized add and remove: child blocks move (reusing freed blocks), pools grow
    // within their reserved room. 3. A huge edit outgrows the room: the pools get larger
    // buffers filled from the old ones on the GPU, still no full upload, same result.
    let edits = [
        (
            UVec3::new(10, 30, 40),
            UVec3::new(30, 45, 63),
            14,
            62,
            false,
        ),
        (UVec3::new(0, 0, 0), UVec3::new(63, 63, 63), 8, 40, true),
    ];
    for (lo, hi, cut_x, slab_z, expect_grown) in edits {
        let edit = svo_mut(&mut doc)
            .edit_region(lo, hi, |c, old| {
                if c.x < cut_x {
                    None
                } else if c.z >= slab_z {
                    // Varied, so the slab is stored voxel by voxel (one colour would be tiles
                    // and never outgrow the pools).
                    Some(Voxel::new([240, 240, (c.x * 4) as u8, 255], Vec3::Z))
                } else {
                    old
                }
            })
            .expect("edit");
        let (clo, chi) = edit.changed.expect("voxels changed");
        let up = r
            .update_voxel_region(&ctx.device, &ctx.queue, &doc, id, clo, chi)
            .expect("update");
        assert!(!up.full, "{up:?}");
        assert_eq!(up.grown, expect_grown, "{up:?}");
        assert_eq!(up.copied_bytes > 0, expect_grown, "{up:?}");
        let (inc, inc_g, inc_stats) = image(&mut r, true, &doc);
        assert!(!inc_stats.upload.full, "{:?}", inc_stats.upload);
        let mut fresh = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
        let (full, full_g, full_stats) = image(&mut fresh, false, &doc);
        // What was already on the GPU is copied there, not sent again.
        assert!(
            up.bytes < full_stats.upload.bytes,
            "{up:?} vs a full upload of {:?}",
            full_stats.upload
        );
        assert!(
            inc == full,
            "after add/remove {lo}..{hi}: incremental differs from full"
        );
        assert!(
            inc_g == full_g,
            "after add/remove {lo}..{hi}: G-buffers differ"
        );
    }
    assert!(ctx.errors.take().is_none());
}

#[test]
fn counters_arrive_asynchronously_and_match_a_waiting_frame() {
    let ctx = context();
    let doc = mixed_doc(true, true);
    let q = Quality::default();
    let target = RenderTarget::new(&ctx.device, 64, 64).expect("target");
    let mut waiting = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let expect = waiting
        .render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("frame");
    assert_eq!(expect.counters_frame, Some(expect.frame));

    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    r.set_async_readback(true);
    let mut last_frame = 0;
    for _ in 0..3 {
        let s = r
            .render_uploaded(
                &ctx.device,
                &ctx.queue,
                &doc,
                &target.view(&doc.camera, &q),
                &target,
            )
            .expect("frame");
        // Counters, when present, come from this or an earlier frame, never a later one.
        assert!(s.counters_frame.is_none_or(|f| f <= s.frame), "{s:?}");
        last_frame = s.frame;
    }
    assert_eq!(last_frame, 3);
    // Poll (never blocking) until the last frame's counters arrive.
    let start = std::time::Instant::now();
    let got = loop {
        if let Some(s) = r.poll_counters(&ctx.device).expect("poll")
            && s.counters_frame == Some(last_frame)
        {
            break s;
        }
        assert!(
            start.elapsed().as_secs() < 30,
            "counters of frame {last_frame} never arrived"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    };
    assert_eq!(got.levels, expect.levels);
    assert_eq!(got.shadow_levels, expect.shadow_levels);
    assert_eq!(got.splats, expect.splats);
    assert!(got.splats > 0);
    assert!(ctx.errors.take().is_none());
}

fn mixed_doc(with_sphere: bool, with_cube: bool) -> Document {
    let mut doc = Document {
        camera: camera(),
        ..Document::default()
    };
    if with_sphere {
        doc.add("sphere", ObjectKind::Voxels(sphere_model(7)));
    }
    doc.add(
        "ground",
        ObjectKind::Mesh(MeshObject {
            model: plane(6.0, -0.9, Vec4::new(0.5, 0.5, 0.5, 1.0)),
            casts_shadows: true,
        }),
    );
    if with_cube {
        let mut cube = unit_cube();
        cube.colors = vec![Vec4::new(0.1, 0.2, 0.9, 1.0); cube.positions.len()];
        doc.add(
            "cube",
            ObjectKind::Mesh(MeshObject {
                model: MeshModel {
                    parts: vec![cube],
                    materials: Vec::new(),
                },
                casts_shadows: true,
            }),
        );
        if let Some(o) = doc.objects.last_mut() {
            o.transform = Transform {
                translation: Vec3::new(0.6, 0.1, 1.0),
                ..Transform::default()
            };
        }
    }
    doc
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Surface {
    Empty,
    Sphere,
    Ground,
    Cube,
}

fn classify(g: &thicket::gpu::GBuffer) -> Vec<Surface> {
    (0..g.depth.len())
        .map(|i| {
            if !g.depth[i].is_finite() {
                return Surface::Empty;
            }
            let a = g.albedo[i];
            if a.z > 0.7 {
                Surface::Cube
            } else if (a.x - a.y).abs() < 0.01 {
                Surface::Ground
            } else {
                Surface::Sphere
            }
        })
        .collect()
}

#[test]
fn meshes_and_voxels_occlude_each_other_and_cast_shadows() {
    let ctx = context();
    let q = Quality::default();
    let size = 128;
    let full = render(&ctx, &mixed_doc(true, true), size, &q, false);
    let no_cube = render(&ctx, &mixed_doc(true, false), size, &q, false);
    let ground_only = render(&ctx, &mixed_doc(false, false), size, &q, false);
    let (f, nc, g) = (
        classify(&full.gbuffer),
        classify(&no_cube.gbuffer),
        classify(&ground_only.gbuffer),
    );
    let n = f.len();
    let count = |v: &[Surface], s: Surface| v.iter().filter(|&&x| x == s).count();
    for (name, v) in [("full", &f), ("no cube", &nc), ("ground only", &g)] {
        eprintln!(
            "{name}: empty {} sphere {} ground {} cube {}",
            count(v, Surface::Empty),
            count(v, Surface::Sphere),
            count(v, Surface::Ground),
            count(v, Surface::Cube)
        );
    }
    // Mesh in front of voxels.
    let cube_over_sphere = (0..n)
        .filter(|&i| f[i] == Surface::Cube && nc[i] == Surface::Sphere)
        .count();
    // Voxels in front of a mesh.
    let sphere_over_ground = (0..n)
        .filter(|&i| nc[i] == Surface::Sphere && g[i] == Surface::Ground)
        .count();
    assert!(cube_over_sphere > 50, "{cube_over_sphere}");
    assert!(sphere_over_ground > 500, "{sphere_over_ground}");
    // The ground is flat and lit by one directional light: without shadows its brightness is
    // nearly uniform; with shadows the sphere darkens part of it.
    let luminance = |rgba: &[u8], i: usize| u32::from(rgba[4 * i]) + u32::from(rgba[4 * i + 1]);
    let ground_px: Vec<usize> = (0..n).filter(|&i| nc[i] == Surface::Ground).collect();
    let lit = ground_px
        .iter()
        .map(|&i| luminance(&no_cube.rgba, i))
        .max()
        .unwrap_or(0);
    let shadowed = ground_px
        .iter()
        .filter(|&&i| luminance(&no_cube.rgba, i) * 10 < lit * 6)
        .count();
    assert!(shadowed > 100, "shadowed ground pixels: {shadowed}");
    let mut q_off = q.clone();
    q_off.shadows = false;
    let unshadowed = render(&ctx, &mixed_doc(true, false), size, &q_off, false);
    let dark = ground_px
        .iter()
        .filter(|&&i| luminance(&unshadowed.rgba, i) * 10 < lit * 6)
        .count();
    assert_eq!(dark, 0);
    assert!(full.stats.shadow_levels.iter().any(|l| l.splatted > 0));
    assert_eq!(full.stats.triangles, 14);
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let ctx = context();
    assert!(matches!(
        RenderTarget::new(&ctx.device, 0, 16),
        Err(GpuError::BadSize { .. })
    ));
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let target = RenderTarget::new(&ctx.device, 8, 8).expect("target");
    let doc = sphere_doc(4);
    let q = Quality {
        lod_pixel_threshold: f32::NAN,
        ..Quality::default()
    };
    assert!(matches!(
        r.render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target
        ),
        Err(GpuError::InvalidQuality(_))
    ));
    let mut cam = doc.camera;
    cam.near = -1.0;
    assert!(matches!(
        r.render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&cam, &Quality::default()),
            &target
        ),
        Err(GpuError::InvalidDocument(_))
    ));
    // An empty document renders the background.
    let empty = Document::default();
    let stats = r
        .render(
            &ctx.device,
            &ctx.queue,
            &empty,
            &target.view(&empty.camera, &Quality::default()),
            &target,
        )
        .expect("empty frame");
    assert_eq!(stats.splats, 0);
    let img = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    assert!(img.chunks(4).all(|p| p == &img[..4]));
    assert!(ctx.errors.take().is_none());
}

#[test]
fn render_document_to_image_works_headless() {
    let doc = sphere_doc(6);
    let (img, stats) =
        thicket::gpu::render_document_to_image(&doc, &thicket_core::render::View::new(64, 48))
            .expect("frame");
    assert_eq!(img.len(), 64 * 48 * 4);
    assert!(stats.splats > 0);
    assert!(stats.total_ms > 0.0);
}

/// Both renderers take a document and a view: the GPU draws the view's camera (or the
/// document's) and refuses a target of another size than the view's.
#[test]
fn the_gpu_renders_a_view_of_its_targets_size() {
    let ctx = context();
    let doc = sphere_doc(6);
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let target = RenderTarget::new(&ctx.device, 64, 48).expect("target");
    let wrong = thicket_core::render::View::new(48, 64);
    let err = r
        .render(&ctx.device, &ctx.queue, &doc, &wrong, &target)
        .expect_err("a view of another size");
    assert_eq!(
        err.to_string(),
        "the view is 48×64 pixels but its target 64×48"
    );
    // No camera: the document's, the same image as naming it.
    let own = thicket_core::render::View::new(64, 48);
    r.render(&ctx.device, &ctx.queue, &doc, &own, &target)
        .expect("frame");
    let a = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    r.render(
        &ctx.device,
        &ctx.queue,
        &doc,
        &target.view(&doc.camera, &own.quality),
        &target,
    )
    .expect("frame");
    let b = read_rgba8(&ctx.device, &ctx.queue, &target).expect("readback");
    assert_eq!(a, b);
    assert!(a.chunks(4).any(|p| p != &a[..4]), "the sphere is drawn");
    assert!(ctx.errors.take().is_none());
}

/// `thicket bench`'s splat-bandwidth measurement on this adapter: it runs, gives positive
/// finite figures (no timing bounds: the machine is shared), and its byte count is the one the
/// frame's own counters give, for a scene with a mesh in the key buffer (which the measurement
/// must redraw before each timed voxel pass) and occlusion culling on.
#[test]
fn splat_bandwidth_is_measured_with_the_frames_byte_count() {
    use thicket::gpu::splat_bw::{OcclusionWork, splat_pass_bytes};
    let ctx = context();
    let doc = mixed_doc(true, true);
    let quality = Quality::default();
    assert!(
        quality.occlusion_culling,
        "the default culls occluded nodes"
    );
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let target = RenderTarget::new(&ctx.device, 96, 80).expect("target");
    let measured = r.measure_splat_bandwidth(
        &ctx.device,
        &ctx.queue,
        &doc,
        &target.view(&doc.camera, &quality),
        &target,
        2,
    );
    if r.atomic_path() != AtomicPath::Key64 {
        let e = measured.expect_err("only the 64-bit path is measured");
        assert!(e.to_string().contains("64-bit"), "{e}");
        return;
    }
    let (frame, bw) = measured.expect("measurement runs");
    assert!(ctx.errors.take().is_none(), "uncaptured GPU error");
    eprintln!("{bw:#?}");
    // The timed pass did the frame's work: same counters, every splat at least one pixel.
    assert_eq!(bw.levels, frame.levels);
    assert_eq!(bw.splat_pixels, frame.splat_pixels);
    assert!(frame.splats > 0 && frame.splat_pixels >= frame.splats);
    // One occlusion-tile build before each level of the one voxel object (the sphere, depth 7).
    let occlusion = OcclusionWork {
        builds: 8,
        width: 96,
        height: 80,
    };
    assert_eq!(bw.occlusion, occlusion);
    let expected = splat_pass_bytes(&frame.levels, frame.splat_pixels, occlusion);
    assert_eq!(bw.bytes, expected);
    assert_eq!(bw.total_bytes, expected.total());
    assert!(expected.key_atomics > 0 && expected.queue_reads > 0 && expected.inner_reads > 0);
    assert_eq!(bw.repeats, 2);
    for (name, v) in [
        ("splat wall ms", bw.splat_wall_ms),
        ("copy wall ms", bw.copy_wall_ms),
        ("splat GB/s", bw.splat_gb_per_s),
        ("copy GB/s", bw.copy_gb_per_s),
        ("ratio", bw.ratio),
    ] {
        assert!(v.is_finite() && v > 0.0, "{name} = {v}");
    }
    for v in [bw.splat_timestamp_ms, bw.copy_timestamp_ms]
        .into_iter()
        .flatten()
    {
        assert!(v.is_finite() && v >= 0.0, "{v}");
    }
    if ctx.adapter.get_info().device_type == wgpu::DeviceType::Cpu {
        assert_eq!(
            bw.timing, "wall clock",
            "a CPU device's timestamps are not used"
        );
    }
    // The measurement leaves nothing behind: the next plain frame counts the same.
    let again = r
        .render_uploaded(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &quality),
            &target,
        )
        .expect("frame");
    assert_eq!(again.levels, frame.levels);
    assert_eq!(again.splat_pixels, frame.splat_pixels);
}

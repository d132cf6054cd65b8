//! The extremes suite: every subsystem driven at its numerical edges from one place — octree
//! depth 21, cameras 1e6 away and 1e-4 from a surface, KRS with 64 reflections, radii 1e-7 and
//! 1e6, coincident and antiparallel mirrors, grazing rays, 180° joints and degenerate weights,
//! enhancement factor 64, images of 1×1 and 8192×8192 pixels. Each test asserts no NaN or
//! infinity, no panic, results within the bound it states, and memory within the limit it
//! states. Many of these edges also have unit tests inside core; this file is the one place that
//! shows them all through the public API.

use glam::{DVec3, Mat4, Quat, UVec3, Vec3};
use thicket_core::enhance::{
    EnhanceSettings, Enhancer, Method, SubdivideSettings, ThresholdPattern,
};
use thicket_core::krs::{
    Kernel, KrsObject, KrsScene, MirrorPlane, SphereKernel, TraceHit, TraceSettings, trace,
};
use thicket_core::render::{View, render_document, scenes};
use thicket_core::scene::{Document, ObjectKind, OrbitCamera, VoxelModel};
use thicket_core::skin::{Joint, Pose, Skeleton, Transform, lbs};
use thicket_core::svo::{MAX_DEPTH, Svo, Voxel};

fn voxel() -> Voxel {
    Voxel::new([200, 120, 40, 255], Vec3::Y)
}

fn all_finite(values: &[f32]) -> bool {
    values.iter().all(|v| v.is_finite())
}

// ------------------------------------------------------------------------------ octree

#[test]
fn octree_depth_21_with_coordinates_near_2_pow_21() {
    let top = (1u32 << 21) - 1;
    let corners = [
        UVec3::ZERO,
        UVec3::splat(top),
        UVec3::new(top, 0, top - 1),
        UVec3::splat(1 << 20),
    ];
    let svo = Svo::from_voxels(
        MAX_DEPTH,
        false,
        corners.iter().map(|&c| (c, voxel())).collect::<Vec<_>>(),
    )
    .unwrap();
    assert_eq!((svo.depth(), svo.extent()), (21, 1 << 21));
    assert_eq!(svo.leaf_count(), corners.len() as u64);
    for c in corners {
        assert!(svo.get(c).is_some(), "{c}");
    }
    // Neighbours of the far corner are empty and exact (no rounding onto a neighbour).
    assert!(svo.get(UVec3::new(top - 1, top, top)).is_none());
    // Memory follows the 4 voxels, not the 2^63-voxel volume: at most one inner node per level
    // per voxel.
    let mem = svo.memory_stats();
    assert!(
        mem.inner_nodes <= 4 * 21 && mem.total_bytes < 16 * 1024,
        "{mem:?}"
    );
    // Out of range is an error, not a panic or a wrap-around.
    let mut edit = svo.clone();
    assert!(edit.set(UVec3::new(1 << 21, 0, 0), voxel()).is_err());
    assert!(Svo::new(MAX_DEPTH + 1, false).is_err());
    // A ray from far outside hits the far corner voxel exactly, in f64: it enters the voxel's
    // top face plane at t = 1e6 - 1 (t in units of the direction's length).
    let origin = DVec3::splat(f64::from(top) + 1e6);
    let hit = svo
        .raycast(origin, DVec3::splat(-1.0), f64::INFINITY)
        .expect("hits the corner voxel");
    assert_eq!(hit.coord, UVec3::splat(top));
    assert!((hit.t - (1e6 - 1.0)).abs() < 1e-6, "{}", hit.t);
}

#[test]
fn depth_21_model_renders_without_nan() {
    let top = (1u32 << 21) - 1;
    let svo = Svo::from_voxels(
        MAX_DEPTH,
        false,
        [UVec3::ZERO, UVec3::splat(top), UVec3::splat(1 << 20)]
            .into_iter()
            .map(|c| (c, voxel()))
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let mut doc = Document::default();
    doc.add(
        "deep",
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: 1e-3,
            origin: Vec3::splat(-1048.576),
            material_names: Vec::new(),
            rig: None,
            volume: None,
            palette: Vec::new(),
            frames: None,
        }),
    );
    let (lo, hi) = doc.bounds().unwrap();
    doc.camera.frame(lo, hi);
    let (img, fb, stats) = render_document(&doc, &View::new(64, 64)).unwrap();
    assert!(all_finite(&fb.depth) && fb.depth.iter().all(|d| (0.0..=1.0).contains(d)));
    assert!(fb.normal.iter().all(|n| n.is_finite()));
    assert_eq!(img.pixels.len(), 64 * 64 * 4);
    // Three voxels a millimetre wide in a 2 km box: a handful of pixels at most (LOD splats of
    // whole subtrees can cover a few), never the whole image.
    assert!(stats.covered_pixels <= 64, "{}", stats.covered_pixels);
}

// ------------------------------------------------------------------------------ camera

fn sphere_doc() -> Document {
    // A voxel sphere shell of radius 0.4 at the origin.
    scenes::sphere_document(6, 0.4).unwrap()
}

#[test]
fn camera_a_million_units_away() {
    let doc = sphere_doc();
    let camera = OrbitCamera {
        distance: 1e6,
        near: 1e5,
        far: 4e6,
        ..doc.camera
    };
    let req = View {
        camera: Some(camera),
        ..View::new(64, 64)
    };
    let (img, fb, stats) = render_document(&doc, &req).unwrap();
    assert!(all_finite(&fb.depth) && fb.normal.iter().all(|n| n.is_finite()));
    assert_eq!(img.pixels.len(), 64 * 64 * 4);
    // The sphere (0.8 wide) spans 1e-6 of the view: at most one pixel.
    assert!(stats.covered_pixels <= 1, "{}", stats.covered_pixels);
    // Zoomed in (narrow field of view) the same distance still finds it: one splat at least.
    let zoom = OrbitCamera {
        fov_y_deg: 0.2,
        ..camera
    };
    let (_, fb, stats) = render_document(
        &doc,
        &View {
            camera: Some(zoom),
            ..View::new(64, 64)
        },
    )
    .unwrap();
    assert!(all_finite(&fb.depth));
    assert!(stats.covered_pixels >= 1 && stats.covered_pixels < 64 * 64);
}

#[test]
fn camera_a_ten_thousandth_from_the_surface() {
    let doc = sphere_doc();
    let (lo, hi) = doc.bounds().unwrap();
    let radius = 0.5 * (hi.x - lo.x);
    let view = OrbitCamera {
        target: Vec3::ZERO,
        distance: 1.0,
        ..doc.camera
    };
    let outward = view.eye().normalize_or_zero();
    let camera = OrbitCamera {
        target: outward * radius,
        distance: 1e-4,
        near: 1e-5,
        far: 10.0,
        ..view
    };
    let req = View {
        camera: Some(camera),
        ..View::new(48, 48)
    };
    let (img, fb, stats) = render_document(&doc, &req).unwrap();
    assert!(all_finite(&fb.depth) && fb.depth.iter().all(|d| (0.0..=1.0).contains(d)));
    assert!(fb.normal.iter().all(|n| n.is_finite()));
    assert_eq!(img.pixels.len(), 48 * 48 * 4);
    // The surface fills the view from this close.
    let n = u64::from(48u32 * 48);
    assert!(
        stats.covered_pixels * 2 > n,
        "{} of {n}",
        stats.covered_pixels
    );
}

// ------------------------------------------------------------------------------ KRS

fn prepared(objects: Vec<KrsObject>) -> thicket_core::krs::PreparedScene {
    KrsScene { objects }.prepare().unwrap()
}

fn hit_ok(h: &TraceHit) -> bool {
    h.t.is_finite() && h.position.is_finite() && h.normal.is_finite()
}

fn ball(centre: Vec3, radius: f32) -> Kernel {
    Kernel::Sphere(SphereKernel {
        centre,
        radius,
        ..Default::default()
    })
}

/// Rays through a `w×h` grid of a pinhole camera looking from `eye` at the origin.
fn rays(eye: Vec3, w: usize, h: usize) -> Vec<Vec3> {
    let forward = (-eye).normalize_or_zero();
    let right = forward.cross(Vec3::Y).normalize_or_zero();
    let up = right.cross(forward);
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let u = (x as f32 + 0.5) / w as f32 * 2.0 - 1.0;
            let v = (y as f32 + 0.5) / h as f32 * 2.0 - 1.0;
            out.push((forward + 0.5 * (u * right + v * up)).normalize_or_zero());
        }
    }
    out
}

/// Largest |f(a) - f(b)| / |a - b| over random pairs: a distance bound must stay ≤ 1.
fn lipschitz(f: impl Fn(Vec3) -> f32, pairs: usize) -> f32 {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut rnd = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 * 6.0 - 3.0
    };
    let mut l = 0.0f32;
    for _ in 0..pairs {
        let a = Vec3::new(rnd(), rnd(), rnd());
        let b = a + Vec3::new(rnd(), rnd(), rnd()) * 0.05;
        let d = (a - b).length();
        if d > 1e-4 {
            l = l.max((f(a) - f(b)).abs() / d);
        }
    }
    l
}

#[test]
fn krs_with_64_reflections() {
    // 64 mirrors near the origin with spread-out normals; a ball across all of them, so part
    // of it survives every fold and stays visible.
    let mut kernels = vec![ball(Vec3::ZERO, 0.5)];
    let mut mirrors = Vec::new();
    for i in 0..64 {
        let a = i as f32 * 2.399_963; // golden angle: normals spread over the sphere
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / 64.0;
        let r = (1.0 - z * z).sqrt();
        mirrors.push(MirrorPlane::new(
            Vec3::new(r * a.cos(), r * a.sin(), z),
            0.05,
        ));
        kernels.push(Kernel::Empty);
    }
    let obj = KrsObject {
        kernels,
        mirrors,
        ..Default::default()
    };
    // 2^64 instances of K0: counted without overflow.
    assert!(obj.instance_count() >= 1 << 64);
    let scene = prepared(vec![obj]);
    let l = lipschitz(|p| scene.distance(p), 2000);
    assert!(l <= 1.0 + 1e-3, "distance bound broken: Lipschitz {l}");
    let eye = Vec3::new(0.0, 0.0, 6.0);
    let s = TraceSettings {
        pixel_cone_ratio: 1.0 / 16.0,
        max_steps: 1000,
        ..Default::default()
    };
    let hits: Vec<TraceHit> = rays(eye, 16, 16)
        .iter()
        .map(|d| trace(&scene, eye, *d, &s))
        .collect();
    assert!(hits.iter().all(hit_ok));
    assert!(hits.iter().any(|h| h.hit));
}

#[test]
fn krs_radii_1e_minus_7_and_1e6() {
    let tiny = prepared(vec![KrsObject {
        kernels: vec![ball(Vec3::ZERO, 1e-7)],
        ..Default::default()
    }]);
    let exact = TraceSettings {
        pixel_cone_ratio: 0.0,
        min_epsilon: 1e-9,
        ..Default::default()
    };
    let h = trace(&tiny, Vec3::new(0.0, 0.0, 1.0), Vec3::NEG_Z, &exact);
    // Within 1e-6 of the true hit at t = 1 - 1e-7 (f32 at 1.0 resolves 6e-8).
    assert!(h.hit && hit_ok(&h) && (h.t - 1.0).abs() < 1e-6, "{h:?}");
    let huge = prepared(vec![KrsObject {
        kernels: vec![ball(Vec3::ZERO, 1e6)],
        ..Default::default()
    }]);
    let h = trace(
        &huge,
        Vec3::new(0.0, 0.0, 3e6),
        Vec3::NEG_Z,
        &TraceSettings {
            max_distance: 1e7,
            min_epsilon: 1e-2,
            pixel_cone_ratio: 0.0,
            ..Default::default()
        },
    );
    // Hit at t = 2e6 within one unit (f32 spacing at 2e6 is 0.125).
    assert!(h.hit && hit_ok(&h) && (h.t - 2e6).abs() < 1.0, "{h:?}");
    // Camera 1e6 away from a unit ball, straight at it and just past it.
    let unit = prepared(vec![KrsObject::default()]);
    let far = TraceSettings {
        pixel_cone_ratio: 1e-9,
        min_epsilon: 1e-4,
        max_distance: 1e7,
        ..Default::default()
    };
    let h = trace(&unit, Vec3::new(1e6, 0.0, 0.0), Vec3::NEG_X, &far);
    assert!(
        h.hit && (h.t - (1e6 - 1.0)).abs() < 0.5 && h.steps < 20,
        "{h:?}"
    );
    let miss = trace(
        &unit,
        Vec3::new(1e6, 0.0, 0.0),
        Vec3::new(-1.0, 1e-5, 0.0).normalize_or_zero(),
        &far,
    );
    assert!(!miss.hit && hit_ok(&miss), "{miss:?}");
}

#[test]
fn krs_coincident_and_antiparallel_mirrors_and_grazing_rays() {
    let k = ball(Vec3::new(-1.0, 0.3, 0.0), 0.5);
    let m = MirrorPlane::new(Vec3::X, 0.0);
    let single = KrsObject {
        kernels: vec![k, Kernel::Empty],
        mirrors: vec![m],
        ..Default::default()
    };
    let coincident = KrsObject {
        kernels: vec![k, Kernel::Empty, Kernel::Empty],
        mirrors: vec![m, m],
        ..Default::default()
    };
    let anti = KrsObject {
        kernels: vec![k, Kernel::Empty, Kernel::Empty],
        mirrors: vec![MirrorPlane::new(Vec3::NEG_X, 0.0), m],
        ..Default::default()
    };
    for i in 0..400 {
        let t = i as f32 * 0.731;
        let p = Vec3::new(t.sin() * 3.0, (t * 1.3).cos() * 3.0, (t * 0.7).sin() * 3.0);
        // A repeated mirror adds nothing (exactly).
        assert_eq!(coincident.distance_object(p), single.distance_object(p));
        let d = anti.distance_object(p);
        assert!(d.is_finite() && d >= anti.distance_brute_force(p) - 1e-6);
    }
    let eye = Vec3::new(0.0, 0.0, 6.0);
    for (visible, obj) in [(true, coincident), (false, anti)] {
        let scene = prepared(vec![obj]);
        assert!(lipschitz(|p| scene.distance(p), 1000) <= 1.0 + 1e-3);
        let hits: Vec<TraceHit> = rays(eye, 10, 10)
            .iter()
            .map(|d| trace(&scene, eye, *d, &TraceSettings::default()))
            .collect();
        assert!(hits.iter().all(hit_ok));
        // Antiparallel mirrors fold everything to x ≥ 0 and clip the ball (at x < 0) away.
        assert_eq!(hits.iter().any(|h| h.hit), visible);
    }
    // Grazing rays: along a plane at heights down to 1e-7, and tangent to a unit ball.
    let plane = prepared(vec![KrsObject {
        kernels: vec![Kernel::InfinitePlane(Default::default())],
        ..Default::default()
    }]);
    for height in [0.0f32, 1e-7, 1e-3, 0.5] {
        let g = trace(
            &plane,
            Vec3::new(0.0, height, 0.0),
            Vec3::new(1.0, -1e-7, 0.0).normalize_or_zero(),
            &TraceSettings::default(),
        );
        assert!(hit_ok(&g), "{height}: {g:?}");
    }
    let unit = prepared(vec![KrsObject::default()]);
    for offset in [0.999_999f32, 1.0, 1.000_001] {
        let g = trace(
            &unit,
            Vec3::new(-5.0, offset, 0.0),
            Vec3::X,
            &TraceSettings {
                max_steps: 100_000,
                ..Default::default()
            },
        );
        // Tangent rays converge or leave; they never run out of steps.
        assert!(hit_ok(&g) && !g.exhausted, "{offset}: {g:?}");
    }
}

// ------------------------------------------------------------------------------ skinning

fn joint(name: &str, parent: Option<usize>, translation: Vec3) -> Joint {
    Joint {
        name: name.into(),
        parent,
        rest: Transform {
            translation,
            ..Transform::IDENTITY
        },
        inverse_bind: Mat4::from_translation(-translation),
        ..Joint::default()
    }
}

#[test]
fn skinning_with_180_degree_joints_and_degenerate_weights() {
    let sk = Skeleton::new(vec![
        joint("root", None, Vec3::ZERO),
        joint("tip", Some(0), Vec3::Y),
    ])
    .unwrap()
    .0;
    let mut pose = Pose::rest(&sk);
    pose.locals[1].rotation = Quat::from_rotation_x(std::f32::consts::PI);
    let skinning = sk.skinning_matrices(&pose);
    assert!(skinning.iter().all(Mat4::is_finite));
    // One unit above the tip folds to one unit below it (exact to 1e-5).
    let p = lbs::skin_point(
        &skinning,
        [1, 0, 0, 0],
        [1.0, 0.0, 0.0, 0.0],
        Vec3::new(0.0, 2.0, 0.0),
    );
    assert!(p.abs_diff_eq(Vec3::ZERO, 1e-5), "{p}");
    // Half-and-half across the 180° joint collapses the linear part; normals stay unit.
    let n = lbs::skin_normal(&skinning, [0, 1, 0, 0], [0.5, 0.5, 0.0, 0.0], Vec3::Z);
    assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-5, "{n}");
    // Degenerate weights: all zero, NaN, negative, out of range joints → repaired to a valid,
    // normalised set, and skinning with the result is finite.
    for (mut j, mut w) in [
        ([0u16, 1, 0, 0], [0.0f32, 0.0, 0.0, 0.0]),
        ([0, 1, 0, 0], [f32::NAN, 0.5, 0.0, 0.0]),
        ([0, 1, 0, 0], [-1.0, 2.0, 0.0, 0.0]),
        ([7, 9, 0, 0], [0.5, 0.5, 0.0, 0.0]),
        ([0, 1, 0, 0], [f32::INFINITY, f32::INFINITY, 0.0, 0.0]),
        ([0, 1, 0, 0], [1e-30, 1e-30, 0.0, 0.0]),
    ] {
        let repair = lbs::repair_weights(&mut j, &mut w, sk.len());
        let sum: f32 = w.iter().sum();
        assert!(
            all_finite(&w) && (sum - 1.0).abs() < 1e-5,
            "{w:?} after {repair:?}"
        );
        assert!(j.iter().all(|&k| usize::from(k) < sk.len()));
        let q = lbs::skin_point(&skinning, j, w, Vec3::new(0.3, 1.5, -0.2));
        assert!(q.is_finite());
    }
}

// ------------------------------------------------------------------------------ enhancement

#[test]
fn enhancement_factor_64() {
    // An L-shaped slab 3×2×4 voxels in a 4³ map.
    let mut voxels = Vec::new();
    for z in 0..4 {
        for y in 0..2 {
            for x in 0..3 {
                voxels.push((UVec3::new(x, y, z), voxel()));
            }
        }
    }
    let map = Svo::from_voxels(2, false, voxels).unwrap();
    let settings = EnhanceSettings {
        method: Method::Subdivide,
        factor: 64,
        subdivide: SubdivideSettings {
            threshold: ThresholdPattern::Constant { value: 2.0 },
        },
        ..EnhanceSettings::default()
    };
    let e = Enhancer::new(&map, &settings).unwrap();
    // 4 × 64 = 256 = 2^8 fragments per edge.
    assert_eq!(e.fine().depth(), 8);
    // Only the surface is enhanced: fragments stay within the surface shell of the coarse
    // slab (its area in fragment faces: 2·(3·2 + 3·4 + 2·4) coarse faces × 64² × a few layers),
    // far below the 24 × 64³ = 6.3 M a solid fill would give.
    let n = e.fine().leaf_count();
    let surface_faces = 2 * (3 * 2 + 3 * 4 + 2 * 4) as u64 * 64 * 64;
    assert!(n > 0 && n <= 4 * surface_faces, "{n} fragments");
    for (p, v) in e.fine().leaves().into_iter().take(10_000) {
        assert!(p.max_element() < 256 && v.normal_vec().is_finite());
    }
    // 65 is refused with an error naming the factor.
    let err = Enhancer::new(
        &map,
        &EnhanceSettings {
            factor: 65,
            method: Method::Resample,
            ..settings
        },
    )
    .err()
    .expect("65 is out of range");
    assert!(err.to_string().contains("factor"), "{err}");
}

// ------------------------------------------------------------------------------ images

#[test]
fn one_by_one_image() {
    let doc = scenes::mixed_document(5).unwrap();
    let (img, fb, _) = render_document(&doc, &View::new(1, 1)).unwrap();
    assert_eq!((img.width, img.height, img.pixels.len()), (1, 1, 4));
    assert!(all_finite(&fb.depth) && (0.0..=1.0).contains(&fb.depth[0]));
    // The centre of the framed scene is the object.
    assert_ne!(fb.ids[0].object, 0);
    assert!(render_document(&doc, &View::new(0, 1)).is_err());
}

/// Peak resident memory of this process in bytes (Linux), for the memory limit below.
fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Bytes per pixel the CPU renderer may hold at its peak: the packed depth+id target (8), the
/// G-buffer (depth 4, id 16, normal 12, albedo 12) and the image (4) are alive together while
/// shading: 56, rounded up to 64 for allocator slack.
const MAX_BYTES_PER_PIXEL: u64 = 64;

#[test]
fn image_8192_by_8192_of_a_tiny_scene() {
    let doc = scenes::sphere_document(4, 0.4).unwrap();
    let (w, h) = (8192u32, 8192u32);
    let pixels = u64::from(w) * u64::from(h);
    let (img, fb, stats) = render_document(&doc, &View::new(w, h)).unwrap();
    assert_eq!(img.pixels.len() as u64, pixels * 4);
    // Retained buffers within the stated bytes per pixel.
    let retained = (img.pixels.capacity()
        + fb.depth.capacity() * 4
        + fb.ids.capacity() * std::mem::size_of_val(&fb.ids[0])
        + fb.normal.capacity() * 12
        + fb.albedo.capacity() * 12) as u64;
    assert!(retained <= pixels * MAX_BYTES_PER_PIXEL, "{retained} bytes");
    // Peak memory of the whole process (other tests in this binary are small) within the same
    // bound plus 512 MiB for everything else.
    if let Some(peak) = peak_rss_bytes() {
        assert!(
            peak <= pixels * MAX_BYTES_PER_PIXEL + (512 << 20),
            "peak RSS {} MiB",
            peak >> 20
        );
    }
    // The sphere is framed: about a quarter of the view, the rest background.
    let covered = stats.covered_pixels as f64 / pixels as f64;
    assert!((0.05..0.6).contains(&covered), "{covered}");
    // Spot checks rather than a 67 M-element scan of every buffer (seconds in a debug build).
    for i in (0..fb.depth.len()).step_by(4099) {
        assert!(fb.depth[i].is_finite() && fb.normal[i].is_finite());
    }
}

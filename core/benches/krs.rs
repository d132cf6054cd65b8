//! KRS benchmarks: Algorithm 1 cost per level (n = 8 → 32), brute force vs Algorithm 1 at
//! n = 12, primary-ray throughput on the tree preset (64×64 rays) with and without
//! over-relaxation and tile starts; frame time of a fixed view of the forest as n grows
//! (8 → 32), a whole frame sphere-traced with Algorithm 1 vs brute force at the largest n brute
//! force finishes, and 800×800 frames of the tree and forest samples on 2 threads (primary rays
//! per second); the simple rock against the battered rock at 800×800 with shadows (steps per
//! ray printed), and an edit of the tree's builder parameters up to a prepared scene. Step
//! counts (over-relaxation and tile gains, identical hit masks) are printed to stderr before
//! the timings.
//!
//! `cargo bench --workspace --bench krs -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use thicket_core::krs::{
    Kernel, KrsObject, KrsScene, MirrorPlane, PreparedScene, SphereKernel, TorusKernel,
    TraceSettings, presets, tile_cone, tile_start_distance, trace,
};
use thicket_core::quality::Quality;
use thicket_core::render::{View, render_document};
use thicket_core::scene::{Document, ObjectKind, OrbitCamera};

fn unit(rng: &mut Pcg32) -> Vec3 {
    Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .normalize_or(Vec3::X)
}

/// A compact KRS with `n` mirrors; `complex` uses toroidal capsules at every level, otherwise
/// spheres at every level.
fn krs(n: usize, complex: bool) -> KrsObject {
    let mut rng = Pcg32::seed_from_u64(n as u64);
    let mut kernels = Vec::new();
    let mut mirrors = Vec::new();
    for i in 0..=n {
        let c = unit(&mut rng) * rng.random_range(0.0..1.5);
        kernels.push(if complex {
            let axis = unit(&mut rng);
            Kernel::ToroidalCapsule(TorusKernel {
                centre: c,
                axis,
                start_dir: axis.any_orthonormal_vector(),
                major_radius: 0.4,
                minor_radius: 0.05,
                sweep_radians: 1.5,
                ..Default::default()
            })
        } else {
            Kernel::Sphere(SphereKernel {
                centre: c,
                radius: 0.1,
                ..Default::default()
            })
        });
        if i < n {
            mirrors.push(MirrorPlane::new(
                unit(&mut rng),
                rng.random_range(-0.5..0.5),
            ));
        }
    }
    KrsObject {
        kernels,
        mirrors,
        ..KrsObject::default()
    }
}

fn points(count: usize) -> Vec<Vec3> {
    let mut rng = Pcg32::seed_from_u64(1);
    (0..count)
        .map(|_| unit(&mut rng) * rng.random_range(0.0..3.0))
        .collect()
}

fn distance_per_level(c: &mut Criterion) {
    let pts = points(1024);
    let mut group = c.benchmark_group("krs_distance");
    group.throughput(Throughput::Elements(pts.len() as u64));
    for complex in [false, true] {
        for n in [8usize, 16, 24, 32] {
            let obj = krs(n, complex).validated(0).expect("valid");
            let name = if complex {
                "toroidal_capsules"
            } else {
                "spheres"
            };
            group.bench_with_input(BenchmarkId::new(name, n), &obj, |b, obj| {
                b.iter(|| {
                    pts.iter()
                        .map(|p| obj.distance_object(*p))
                        .fold(0.0f32, |a, d| a + d)
                });
            });
        }
    }
    group.finish();
}

fn brute_vs_algorithm1(c: &mut Criterion) {
    let pts = points(64);
    let obj = krs(12, false).validated(0).expect("valid");
    let mut group = c.benchmark_group("krs_n12");
    group.throughput(Throughput::Elements(pts.len() as u64));
    group.bench_function("algorithm1", |b| {
        b.iter(|| {
            pts.iter()
                .map(|p| obj.distance_object(*p))
                .fold(0.0f32, |a, d| a + d)
        });
    });
    group.bench_function("brute_force", |b| {
        b.iter(|| {
            pts.iter()
                .map(|p| obj.distance_brute_force(*p))
                .fold(0.0f32, |a, d| a + d)
        });
    });
    group.finish();
}

/// 64×64 primary rays of a pinhole camera; the epsilon is that of an 800×800 frame.
fn rays(eye: Vec3, target: Vec3) -> (Vec<Vec3>, f32) {
    let fwd = (target - eye).normalize_or(Vec3::NEG_Z);
    let right = fwd.cross(Vec3::Y).normalize_or(Vec3::X);
    let up = right.cross(fwd);
    let half = 0.45f32.tan();
    let n = 64;
    let dirs = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f32, (i / n) as f32);
            let u = ((x + 0.5) / n as f32 * 2.0 - 1.0) * half;
            let v = (1.0 - (y + 0.5) / n as f32 * 2.0) * half;
            (fwd + right * u + up * v).normalize_or(fwd)
        })
        .collect();
    (dirs, 2.0 * half / 800.0)
}

fn render(scene: &PreparedScene, eye: Vec3, dirs: &[Vec3], s: &TraceSettings, tiles: bool) -> u32 {
    let n = 64usize;
    let tile = 8usize;
    let mut hits = 0;
    for ty in (0..n).step_by(tile) {
        for tx in (0..n).step_by(tile) {
            let idx: Vec<usize> = (ty..ty + tile)
                .flat_map(|y| (tx..tx + tile).map(move |x| y * n + x))
                .collect();
            let settings = if tiles {
                let corners = [
                    idx[0],
                    idx[tile - 1],
                    idx[idx.len() - tile],
                    idx[idx.len() - 1],
                ];
                let corner_dirs: Vec<Vec3> = corners.iter().map(|&i| dirs[i]).collect();
                let (axis, half) = tile_cone(&corner_dirs);
                TraceSettings {
                    start_distance: tile_start_distance(scene, eye, axis, half, s),
                    ..*s
                }
            } else {
                *s
            };
            for &i in &idx {
                hits += u32::from(trace(scene, eye, dirs[i], &settings).hit);
            }
        }
    }
    hits
}

fn tracer(c: &mut Criterion) {
    let views = [
        (
            "tree",
            KrsScene {
                objects: vec![presets::tree()],
            },
            Vec3::new(7.0, 3.5, 7.0),
            Vec3::new(0.8, 3.8, 0.3),
        ),
        (
            "forest",
            presets::forest_scene(),
            Vec3::new(-8.0, 4.0, -8.0),
            Vec3::new(40.0, 1.0, 35.0),
        ),
    ];
    let mut group = c.benchmark_group("krs_trace_64x64");
    group.throughput(Throughput::Elements(64 * 64));
    for (name, scene, eye, target) in views {
        let scene = scene.prepare().expect("valid preset");
        let (dirs, cone) = rays(eye, target);
        let plain = TraceSettings {
            pixel_cone_ratio: cone,
            max_steps: 1000,
            max_distance: 500.0,
            ..Default::default()
        };
        let relaxed = TraceSettings {
            over_relaxation: 1.6,
            ..plain
        };
        for (label, s, tiles) in [
            ("plain", plain, false),
            ("relaxed", relaxed, false),
            ("tiles", plain, true),
            ("relaxed_tiles", relaxed, true),
        ] {
            group.bench_function(BenchmarkId::new(name, label), |b| {
                b.iter(|| black_box(render(&scene, eye, &dirs, &s, tiles)));
            });
        }
    }
    group.finish();
}

/// The fixed view of the growing forest: from outside the forest's first corner, looking in.
const FOREST_EYE: Vec3 = Vec3::new(-8.0, 4.0, -8.0);
const FOREST_TARGET: Vec3 = Vec3::new(40.0, 1.0, 35.0);

/// The default tree has this many mirrors; the forest adds reflections on top.
fn tree_levels() -> usize {
    presets::tree().mirrors.len()
}

/// Plain sphere tracing of `dirs` from `eye` with any distance function (the same loop for
/// Algorithm 1 and brute force, so only the distance differs). Returns the hit mask.
fn sphere_trace_frame(
    dist: &dyn Fn(Vec3) -> f32,
    eye: Vec3,
    dirs: &[Vec3],
    cone: f32,
) -> Vec<bool> {
    dirs.iter()
        .map(|&d| {
            let mut t = 0.0f32;
            for _ in 0..256 {
                let r = dist(eye + d * t);
                if r < cone * t.max(1.0) {
                    return true;
                }
                t += r;
                if t > 200.0 {
                    break;
                }
            }
            false
        })
        .collect()
}

fn frame_levels(c: &mut Criterion) {
    let (dirs, cone) = rays(FOREST_EYE, FOREST_TARGET);
    let settings = TraceSettings {
        pixel_cone_ratio: cone,
        max_steps: 1000,
        max_distance: 500.0,
        ..Default::default()
    };
    let mut group = c.benchmark_group("krs_frame_64x64_forest_levels");
    group.throughput(Throughput::Elements(dirs.len() as u64));
    let base = tree_levels();
    for n in [8usize, 12, 16, 20, 24, 28, 32] {
        let obj = presets::forest_with_mirrors(n.saturating_sub(base));
        let levels = obj.mirrors.len();
        let scene = KrsScene { objects: vec![obj] }
            .prepare()
            .expect("valid preset");
        let (hits, steps) = dirs.iter().fold((0u32, 0u64), |(h, s), &d| {
            let r = trace(&scene, FOREST_EYE, d, &settings);
            (h + u32::from(r.hit), s + u64::from(r.steps))
        });
        eprintln!(
            "forest n = {levels}: {hits} hits, {steps} steps over {} rays",
            dirs.len()
        );
        group.bench_with_input(BenchmarkId::from_parameter(levels), &scene, |b, scene| {
            b.iter(|| {
                dirs.iter()
                    .map(|&d| u32::from(trace(scene, FOREST_EYE, d, &settings).hit))
                    .sum::<u32>()
            });
        });
    }
    group.finish();
}

fn frame_brute_force(c: &mut Criterion) {
    // 32×32 rays of the forest view at n = 12 (2^12 trees' worth of reflections would be too
    // many for brute force per step; 12 levels is 8191 kernel evaluations per distance).
    let (all_dirs, cone) = rays(FOREST_EYE, FOREST_TARGET);
    let dirs: Vec<Vec3> = all_dirs
        .iter()
        .enumerate()
        .filter(|(i, _)| (i % 64) % 2 == 0 && (i / 64) % 2 == 0)
        .map(|(_, d)| *d)
        .collect();
    let n = 12usize;
    let obj = presets::forest_with_mirrors(n.saturating_sub(tree_levels()))
        .validated(0)
        .expect("valid preset");
    let alg1 = |p: Vec3| obj.distance_object(p);
    let brute = |p: Vec3| obj.distance_brute_force(p);
    let a = sphere_trace_frame(&alg1, FOREST_EYE, &dirs, cone);
    let b = sphere_trace_frame(&brute, FOREST_EYE, &dirs, cone);
    let same = a.iter().zip(&b).filter(|(x, y)| x == y).count();
    eprintln!(
        "forest n = {}: Algorithm 1 and brute force agree on {same} of {} hit-mask pixels ({} hits)",
        obj.mirrors.len(),
        dirs.len(),
        a.iter().filter(|h| **h).count()
    );
    let mut group = c.benchmark_group("krs_frame_32x32_n12");
    group.sample_size(10);
    group.throughput(Throughput::Elements(dirs.len() as u64));
    group.bench_function("algorithm1", |bch| {
        bch.iter(|| black_box(sphere_trace_frame(&alg1, FOREST_EYE, &dirs, cone)));
    });
    group.bench_function("brute_force", |bch| {
        bch.iter(|| black_box(sphere_trace_frame(&brute, FOREST_EYE, &dirs, cone)));
    });
    group.finish();
}

/// Steps spent on the 64×64 views with and without over-relaxation (several ω) and tiles, and
/// whether the hit masks are identical. Printed, not timed: step counts are exact.
fn step_report() {
    let views = [
        (
            "tree",
            KrsScene {
                objects: vec![presets::tree()],
            },
            Vec3::new(7.0, 3.5, 7.0),
            Vec3::new(0.8, 3.8, 0.3),
        ),
        ("forest", presets::forest_scene(), FOREST_EYE, FOREST_TARGET),
    ];
    for (name, scene, eye, target) in views {
        let scene = scene.prepare().expect("valid preset");
        let (dirs, cone) = rays(eye, target);
        let plain = TraceSettings {
            pixel_cone_ratio: cone,
            max_steps: 1000,
            max_distance: 500.0,
            ..Default::default()
        };
        // A miss's t is where that march stopped (path-dependent); only hits have a canonical t.
        let run = |s: &TraceSettings| -> (Vec<Option<u32>>, u64) {
            let mut steps = 0u64;
            let hits = dirs
                .iter()
                .map(|&d| {
                    let r = trace(&scene, eye, d, s);
                    steps += u64::from(r.steps);
                    r.hit.then_some(r.t.to_bits())
                })
                .collect();
            (hits, steps)
        };
        let (mask0, steps0) = run(&plain);
        for omega in [1.2f32, 1.4, 1.5, 1.6, 1.8, 1.9] {
            let (mask, steps) = run(&TraceSettings {
                over_relaxation: omega,
                ..plain
            });
            eprintln!(
                "{name}: over-relaxation {omega}: {steps} steps vs {steps0} plain ({:.1}% fewer), hit mask and t identical: {}",
                100.0 * (1.0 - steps as f64 / steps0 as f64),
                mask == mask0
            );
        }
    }
}

fn report_then_trace(c: &mut Criterion) {
    step_report();
    tracer(c);
}

/// 800×800 frames of the sample views through the renderer on a 2-thread pool: KRS pass time
/// and primary rays per second, tiles on and off (shadows and AO off, so only primary rays).
fn frames_800(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a 2-thread pool");
    let mut tree = Document::default();
    tree.add("Tree", ObjectKind::Krs(presets::tree()));
    tree.camera = OrbitCamera {
        target: Vec3::new(0.0, 2.6, 0.0),
        yaw_deg: 30.0,
        pitch_deg: 12.0,
        distance: 11.0,
        near: 0.1,
        far: 100.0,
        ..OrbitCamera::default()
    };
    let mut forest = Document::default();
    for o in presets::forest_scene().objects {
        forest.add(o.name.clone(), ObjectKind::Krs(o));
    }
    forest.camera = OrbitCamera {
        target: Vec3::new(40.0, 2.0, 40.0),
        yaw_deg: 225.0,
        pitch_deg: 14.0,
        distance: 70.0,
        near: 0.5,
        far: 4000.0,
        ..OrbitCamera::default()
    };
    let mut group = c.benchmark_group("krs_frame_800x800_2threads");
    group.sample_size(10);
    group.throughput(Throughput::Elements(800 * 800));
    for (name, doc) in [("tree", &tree), ("forest", &forest)] {
        for tiles in [false, true] {
            let req = View {
                quality: Quality {
                    shadows: false,
                    ao_samples: 0,
                    krs_tile_acceleration: tiles,
                    ..Quality::default()
                },
                ..View::new(800, 800)
            };
            if let Ok((_, fb, st)) = pool.install(|| render_document(doc, &req)) {
                eprintln!(
                    "{name} 800x800 tiles={tiles}: {} rays, {} hits, {} steps + {} tile steps, {} exhausted, KRS pass {:.0} ms ({:.2} M primary rays/s), covered {}",
                    st.krs.rays,
                    st.krs.hits,
                    st.krs.steps,
                    st.krs.tile_steps,
                    st.krs.exhausted,
                    st.times.krs_ms,
                    st.krs.rays as f64 / st.times.krs_ms / 1e3,
                    fb.covered_pixels()
                );
            }
            let label = if tiles { "tiles" } else { "no_tiles" };
            group.bench_function(BenchmarkId::new(name, label), |b| {
                b.iter(|| pool.install(|| black_box(render_document(doc, &req).is_ok())));
            });
        }
    }
    group.finish();
}

/// The simple rock against the battered rock (issue 26), one rock alone seen from 3.2 units at
/// 800×800 with the default quality (shadows on): steps per primary and per shadow ray (exact)
/// printed, the frame timed.
fn rocks_800(c: &mut Criterion) {
    let mut group = c.benchmark_group("krs_rock_800x800");
    group.sample_size(10);
    group.throughput(Throughput::Elements(800 * 800));
    for (name, rock) in [
        ("simple", presets::rock()),
        ("battered", presets::battered_rock(5)),
    ] {
        let mut doc = Document::default();
        doc.add("Rock", ObjectKind::Krs(rock));
        doc.camera = OrbitCamera {
            target: Vec3::new(0.0, 0.55, 0.0),
            yaw_deg: 20.0,
            pitch_deg: 20.0,
            distance: 3.2,
            near: 0.05,
            far: 100.0,
            ..OrbitCamera::default()
        };
        let req = View::new(800, 800);
        if let Ok((_, _, st)) = render_document(&doc, &req) {
            eprintln!(
                "{name} rock 800x800: {} rays, {} hits, {:.2} steps per ray, {} exhausted, {:.2} shadow steps per shadow ray, KRS pass {:.0} ms",
                st.krs.rays,
                st.krs.hits,
                st.krs.steps as f64 / st.krs.rays.max(1) as f64,
                st.krs.exhausted,
                st.krs.shadow_steps as f64 / st.krs.shadow_rays.max(1) as f64,
                st.times.krs_ms,
            );
        }
        group.bench_function(name, |b| {
            b.iter(|| black_box(render_document(&doc, &req).is_ok()));
        });
    }
    group.finish();
}

/// An edit of the tree sample's parameters up to what the preview draws: rebuild the KRS from
/// `TreeParams` and prepare it (validation, inverse transform, bounds). The next preview frame
/// (`thicket bench projects/tree.thicket.json`) comes on top.
fn tree_edit(c: &mut Criterion) {
    let mut group = c.benchmark_group("krs_tree_edit");
    let mut params = thicket_core::krs::TreeParams::default();
    let mut k = 0u32;
    group.bench_function("rebuild_and_prepare", |b| {
        b.iter(|| {
            // A different width each time, as a drag in the builder makes it.
            k = k.wrapping_add(1);
            params.widths[0] = 0.2 + 1e-5 * (k % 1000) as f32;
            let object = params.build().expect("valid parameters");
            black_box(
                KrsScene {
                    objects: vec![object],
                }
                .prepare()
                .is_ok(),
            )
        });
    });
    group.finish();
}

/// Growing or regrowing the woodland's 2^14-tree forest on its terrain (what a Forest slider
/// release does: plan the mirrors, write the objects), and that plus the first preview frame
/// at the editor's reduced size (half of a 589×709 view).
fn forest_regrow(c: &mut Criterion) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/woodland.thicket.json"
    );
    let Ok(base) = thicket_core::io::project::load(std::path::Path::new(path)) else {
        eprintln!("forest_regrow: {path} not found");
        return;
    };
    let link = base.forests[0].clone();
    let mut group = c.benchmark_group("krs_forest_regrow");
    group.sample_size(10);
    let mut seed = 0u64;
    let mut regrow = |doc: &mut thicket_core::scene::Document| {
        seed += 1;
        let params = thicket_core::krs::forest::ForestParams {
            seed,
            ..link.params
        };
        let plan = doc
            .plan_forest(&link.sources, link.terrain, &params)
            .expect("regrows");
        doc.apply_forest(plan);
    };
    group.bench_function("plan_and_apply_2^14", |b| {
        let mut doc = base.clone();
        b.iter(|| {
            regrow(&mut doc);
            black_box(doc.forests.len())
        });
    });
    let req = View::new(294, 354);
    group.bench_function("regrow_and_preview_294x354", |b| {
        let mut doc = base.clone();
        b.iter(|| {
            regrow(&mut doc);
            black_box(render_document(&doc, &req).is_ok())
        });
    });
    // The quarter-size frame a moving preview drops to, without shadows.
    let mut quality = base.quality.clone();
    quality.shadows = false;
    let quarter = View {
        quality,
        ..View::new(147, 177)
    };
    group.bench_function("regrow_and_preview_147x177_unshadowed", |b| {
        let mut doc = base.clone();
        b.iter(|| {
            regrow(&mut doc);
            black_box(render_document(&doc, &quarter).is_ok())
        });
    });
    group.finish();
}

criterion_group!(
    benches,
    distance_per_level,
    brute_vs_algorithm1,
    report_then_trace,
    frame_levels,
    frame_brute_force,
    frames_800,
    rocks_800,
    tree_edit,
    forest_regrow
);
criterion_main!(benches);

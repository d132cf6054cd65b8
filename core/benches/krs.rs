//! KRS benchmarks: Algorithm 1 cost per level (n = 8 → 32), brute force vs Algorithm 1 at
//! n = 12, and primary-ray throughput on the tree preset (64×64 rays) with and without
//! over-relaxation and tile starts.
//!
//! `cargo bench -p thicket-core --bench krs -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use thicket_core::krs::{
    Kernel, KrsObject, KrsScene, MirrorPlane, PreparedScene, SphereKernel, TorusKernel,
    TraceSettings, presets, tile_cone, tile_start_distance, trace,
};

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

criterion_group!(benches, distance_per_level, brute_vs_algorithm1, tracer);
criterion_main!(benches);

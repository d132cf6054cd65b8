//! Voxelization benchmarks: CesiumMan.glb and a ~3000-triangle sphere at 512³ (surface), point
//! queries per second on the result, and a radius-8 sphere-brush region edit on a depth-10 and a
//! depth-16 octree holding the same surface (the edit's cost should follow the edit, not the
//! model).
//!
//! `cargo bench -p thicket-core --bench voxelize`

use std::f32::consts::{PI, TAU};
use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{UVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use thicket_core::mesh::{MeshModel, TriangleMesh};
use thicket_core::svo::{Svo, Voxel};
use thicket_core::voxelize::{Mode, Resolution, VoxelizeSettings, Voxelized, voxelize};

const CESIUM_MAN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/assets/skinned/CesiumMan.glb"
);

/// A UV sphere: 40 × 40 gives 3,120 triangles.
fn uv_sphere(stacks: u32, slices: u32) -> MeshModel {
    let mut positions = Vec::new();
    for i in 0..=stacks {
        let theta = PI * i as f32 / stacks as f32;
        for j in 0..slices {
            let phi = TAU * j as f32 / slices as f32;
            positions.push(Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ));
        }
    }
    let at = |i: u32, j: u32| i * slices + j % slices;
    let mut indices = Vec::new();
    for i in 0..stacks {
        for j in 0..slices {
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
            if i != 0 {
                indices.extend([a, b, c]);
            }
            if i + 1 != stacks {
                indices.extend([b, d, c]);
            }
        }
    }
    let mut mesh = TriangleMesh {
        positions,
        indices,
        ..TriangleMesh::default()
    };
    mesh.compute_normals();
    MeshModel {
        parts: vec![mesh],
        materials: Vec::new(),
    }
}

fn surface(resolution: Resolution, padding: u32) -> VoxelizeSettings {
    VoxelizeSettings {
        resolution,
        mode: Mode::Surface,
        padding,
        ..VoxelizeSettings::default()
    }
}

fn run(model: &MeshModel, settings: &VoxelizeSettings) -> Voxelized {
    voxelize(model, settings, &|_| true).unwrap_or_else(|e| panic!("voxelize: {e}"))
}

fn bench_voxelize(c: &mut Criterion) {
    let mut group = c.benchmark_group("voxelize_512_surface");
    group.sample_size(10);
    let sphere = uv_sphere(40, 40);
    let mut models = vec![("sphere_3120_tris", sphere)];
    match thicket_core::io::import_gltf(std::path::Path::new(CESIUM_MAN)) {
        Ok(m) => models.push(("cesium_man", m)),
        Err(e) => eprintln!("CesiumMan.glb not benchmarked: {e}"),
    }
    let settings = surface(Resolution::Depth(9), 0);
    for (name, model) in &models {
        let v = run(model, &settings);
        eprintln!(
            "{name}: {} triangles → {} voxels ({} overlaps), {:.2} bytes/voxel",
            v.stats.triangles,
            v.stats.voxels,
            v.stats.overlaps,
            v.svo.memory_stats().bytes_per_leaf
        );
        group.bench_function(*name, |b| b.iter(|| run(black_box(model), &settings)));
    }
    group.finish();

    // Point queries on the CesiumMan result (or the sphere's if it is missing).
    let (name, model) = models
        .last()
        .unwrap_or_else(|| unreachable!("sphere is always present"));
    let v = run(model, &settings);
    let (lo, hi) = v.svo.bounds().unwrap_or((UVec3::ZERO, UVec3::ZERO));
    let leaves: Vec<UVec3> = v.svo.leaves().into_iter().map(|(c, _)| c).collect();
    let mut rng = Pcg64::seed_from_u64(7);
    const N: usize = 1 << 16;
    let in_box: Vec<UVec3> = (0..N)
        .map(|_| {
            UVec3::new(
                rng.random_range(lo.x..=hi.x),
                rng.random_range(lo.y..=hi.y),
                rng.random_range(lo.z..=hi.z),
            )
        })
        .collect();
    let hits: Vec<UVec3> = (0..N)
        .map(|_| leaves[rng.random_range(0..leaves.len())])
        .collect();
    let hit_rate = in_box.iter().filter(|&&c| v.svo.get(c).is_some()).count() as f64 / N as f64;
    eprintln!(
        "{name}: random in-bounds queries hit {:.1} %",
        hit_rate * 100.0
    );
    let mut group = c.benchmark_group(format!("svo_get_{name}_512"));
    group.throughput(Throughput::Elements(N as u64));
    for (label, queries) in [("random_in_bounds", &in_box), ("random_solid", &hits)] {
        group.bench_function(label, |b| {
            b.iter(|| {
                let mut found = 0u32;
                for &q in queries {
                    found += u32::from(v.svo.get(black_box(q)).is_some());
                }
                found
            });
        });
    }
    group.finish();
}

/// Radius-8 sphere brush centred on a solid voxel: fills the ball, as a sculpt "add" dab.
fn brush_edit(svo: &mut Svo, centre: UVec3) -> thicket_core::svo::EditResult {
    let r = 8u32;
    let lo = centre.saturating_sub(UVec3::splat(r));
    let hi = centre + UVec3::splat(r);
    let paint = Voxel::new([200, 60, 30, 255], Vec3::Y);
    svo.edit_region(lo, hi, |c, old| {
        let d = c.as_ivec3() - centre.as_ivec3();
        if d.length_squared() <= (r * r) as i32 {
            Some(paint)
        } else {
            old
        }
    })
    .unwrap_or_else(|e| panic!("edit: {e}"))
}

fn bench_edit(c: &mut Criterion) {
    let sphere = uv_sphere(40, 40);
    // Same voxel size and surface in both (960 voxels across); padding alone makes the octrees
    // depth 10 and depth 16, and leaves room for the whole brush ball outside the surface.
    let voxel_size = 2.0 / 960.0;
    let padded = |depth: u32| {
        surface(
            Resolution::VoxelSize(voxel_size),
            ((1u32 << depth) - 960) / 2,
        )
    };
    let shallow = run(&sphere, &padded(10));
    let deep = run(&sphere, &padded(16));
    let mut group = c.benchmark_group("edit_sphere_r8");
    for (name, mut v) in [("depth10", shallow), ("depth16", deep)] {
        let centre = v
            .voxel_of(Vec3::new(1.0, 0.0, 0.0) - Vec3::X * v.voxel_size * 0.5)
            .unwrap_or_else(|| panic!("surface point outside the grid"));
        assert!(
            v.svo.get(centre).is_some(),
            "{name}: brush centre not solid"
        );
        let probe = brush_edit(&mut v.svo, centre);
        eprintln!(
            "{name}: depth {}, {} voxels, edit changes {} voxels",
            v.svo.depth(),
            v.svo.leaf_count(),
            probe.delta.entries.len()
        );
        v.svo.apply_delta(&probe.delta);
        group.bench_function(name, |b| {
            b.iter_custom(|iters| {
                let mut timed = Duration::ZERO;
                for _ in 0..iters {
                    let start = Instant::now();
                    let r = brush_edit(&mut v.svo, black_box(centre));
                    timed += start.elapsed();
                    // Undo outside the timing so every iteration edits the same octree.
                    v.svo.apply_delta(&r.delta);
                }
                timed
            });
        });
    }
    group.finish();
}

criterion_group!(benches, bench_voxelize, bench_edit);
criterion_main!(benches);

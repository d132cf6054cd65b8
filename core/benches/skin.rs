//! Skinning benchmarks: linear-blend skinning throughput (1M points, 4 weights, one thread),
//! clip sampling + forward kinematics for CesiumMan, and the per-node cost of each stretch
//! strategy.
//!
//! `cargo bench -p thicket-core --bench skin`

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{Mat4, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use thicket_core::io::import_skinned;
use thicket_core::skin::stretch::{VoxelSkinInput, skinned_splat};
use thicket_core::skin::{
    JointMatrices, Pose, Skin4, StretchSettings, StretchStrategy, Wrap, skin_points,
};

const CESIUM_MAN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/assets/skinned/CesiumMan.glb"
);

/// 19 random rigid-ish skinning matrices, like a character's.
fn random_skinning(rng: &mut Pcg64) -> Vec<Mat4> {
    (0..19)
        .map(|_| {
            let axis = Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
            let rot = Quat::from_axis_angle(
                axis.try_normalize().unwrap_or(Vec3::Y),
                rng.random::<f32>() * 3.0,
            );
            Mat4::from_rotation_translation(
                rot,
                Vec3::new(rng.random(), rng.random(), rng.random()),
            )
        })
        .collect()
}

fn random_skin(rng: &mut Pcg64) -> ([u16; 4], [f32; 4]) {
    let joints = [0u16; 4].map(|_| rng.random_range(0..19));
    let raw: [f32; 4] = [0.0f32; 4].map(|_| rng.random::<f32>());
    let sum: f32 = raw.iter().sum();
    (joints, raw.map(|w| w / sum))
}

fn bench_lbs(c: &mut Criterion) {
    const N: usize = 1_000_000;
    let mut rng = Pcg64::seed_from_u64(7);
    let skinning = random_skinning(&mut rng);
    let mut joints = Vec::with_capacity(N);
    let mut weights = Vec::with_capacity(N);
    let mut positions = Vec::with_capacity(N);
    for _ in 0..N {
        let (j, w) = random_skin(&mut rng);
        joints.push(j);
        weights.push(w);
        positions.push(Vec3::new(rng.random(), rng.random(), rng.random()));
    }
    let mut out = vec![Vec3::ZERO; N];
    let mut g = c.benchmark_group("lbs");
    g.throughput(Throughput::Elements(N as u64));
    g.sample_size(20);
    g.bench_function("skin_points_1M_4_weights", |b| {
        b.iter(|| {
            skin_points(&skinning, &joints, &weights, &positions, &mut out);
            black_box(&out);
        });
    });
    g.finish();
}

fn bench_sampling(c: &mut Criterion) {
    let import = import_skinned(CESIUM_MAN).expect("CesiumMan imports");
    let clip = &import.clips[0];
    let sk = &import.skeleton;
    let mut pose = Pose::rest(sk);
    let mut matrices = JointMatrices::default();
    let mut t = 0.0f32;
    let mut g = c.benchmark_group("clip");
    g.bench_function("cesium_man_sample", |b| {
        b.iter(|| {
            t += 0.013;
            clip.sample_into(t, Wrap::Loop, sk, &mut pose);
            black_box(&pose);
        });
    });
    g.bench_function("cesium_man_sample_and_fk", |b| {
        b.iter(|| {
            t += 0.013;
            clip.sample_into(t, Wrap::Loop, sk, &mut pose);
            sk.compute_matrices(&pose, &mut matrices);
            black_box(&matrices);
        });
    });
    g.finish();
}

fn bench_stretch(c: &mut Criterion) {
    const N: usize = 100_000;
    let mut rng = Pcg64::seed_from_u64(11);
    let skinning = random_skinning(&mut rng);
    let nodes: Vec<(Vec3, Skin4, [Skin4; 8])> = (0..N)
        .map(|_| {
            let center = Vec3::new(rng.random(), rng.random(), rng.random());
            let mut skin = || {
                let (j, w) = random_skin(&mut rng);
                Skin4::from_vertex(j, w)
            };
            let own = skin();
            let corners = std::array::from_fn(|_| skin());
            (center, own, corners)
        })
        .collect();
    let mut g = c.benchmark_group("stretch_100k_nodes");
    g.throughput(Throughput::Elements(N as u64));
    g.sample_size(20);
    for strategy in [
        StretchStrategy::Off,
        StretchStrategy::Thesis,
        StretchStrategy::Corners,
        StretchStrategy::Adaptive,
    ] {
        let settings = StretchSettings {
            strategy,
            ..StretchSettings::default()
        };
        for with_corners in [false, true] {
            if !with_corners && strategy == StretchStrategy::Corners {
                continue; // falls back to Thesis
            }
            let name = format!(
                "{strategy:?}{}",
                if with_corners { "_corner_weights" } else { "" }
            );
            g.bench_function(name, |b| {
                b.iter(|| {
                    let mut acc = Vec3::ZERO;
                    for (center, skin, corners) in &nodes {
                        let input = VoxelSkinInput {
                            center: *center,
                            half_size: 0.01,
                            skin: *skin,
                            corner_skins: with_corners.then_some(corners),
                            override_code: 0,
                        };
                        let s = skinned_splat(&settings, &skinning, &input);
                        acc += s.center + s.half_extent;
                    }
                    black_box(acc)
                });
            });
        }
    }
    g.finish();
}

/// A whole CPU frame of voxelized CesiumMan (depth 8, 800×800, shadows off), static (rigid
/// transform) against skinned mid-stride with each strategy, same model and view: the paper's
/// claim is that skinning is nearly free because node positions are computed anyway.
fn bench_frames(c: &mut Criterion) {
    use thicket_core::render::{View, render_document};
    use thicket_core::scene::{Document, ObjectKind};
    use thicket_core::voxelize::{Resolution, VoxelizeSettings};
    let import = import_skinned(CESIUM_MAN).expect("CesiumMan imports");
    let v = thicket_core::io::voxelize_skinned(
        &import,
        &VoxelizeSettings {
            resolution: Resolution::Depth(8),
            ..VoxelizeSettings::default()
        },
        &|_| true,
    )
    .expect("voxelizes");
    let mut skinned = Document::default();
    skinned.add("CesiumMan", ObjectKind::Voxels(v.model));
    if let Some((lo, hi)) = skinned.bounds() {
        skinned.camera.frame(lo, hi);
    }
    let mut rigid = skinned.clone();
    if let ObjectKind::Voxels(m) = &mut rigid.objects[0].kind {
        m.rig = None;
    }
    // The static model shows the bind pose; orient it as the skinned one (the rig's Z-up root).
    rigid.objects[0].transform.rotation = glam::Quat::from_mat4(&import.world_from_skinned_node);
    let mut req = View::new(800, 800);
    req.quality.shadows = false;
    let mut g = c.benchmark_group("frame_cesium_man_800");
    g.sample_size(10);
    g.bench_function("static", |b| {
        b.iter(|| black_box(render_document(&rigid, &req).expect("renders").2));
    });
    for strategy in [
        StretchStrategy::Off,
        StretchStrategy::Thesis,
        StretchStrategy::Corners,
        StretchStrategy::Adaptive,
    ] {
        let mut doc = skinned.clone();
        if let ObjectKind::Voxels(m) = &mut doc.objects[0].kind
            && let Some(rig) = m.rig.as_mut()
        {
            rig.playback.time_secs = 0.5;
            rig.stretch.strategy = strategy;
        }
        g.bench_function(format!("skinned_{strategy:?}"), |b| {
            b.iter(|| black_box(render_document(&doc, &req).expect("renders").2));
        });
    }
    g.finish();
}

criterion_group!(
    benches,
    bench_lbs,
    bench_sampling,
    bench_stretch,
    bench_frames
);
criterion_main!(benches);

//! Native rigging benchmarks: geodesic (and envelope, rigid) binding of a solid voxel figure of
//! about 10^6 voxels to a 24-joint skeleton, and one weight-paint dab of radius 8.
//!
//! `cargo bench -p thicket-core --bench bind` (goals: geodesic ≤ 3 s in a release build on two
//! cores; a dab ≤ 16 ms).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{UVec3, Vec3};
use thicket_core::skin::bind::{BindControl, BindMethod, bind};
use thicket_core::skin::paint::weight_dab;
use thicket_core::skin::{JointSpec, Skeleton, SkeletonSpec};
use thicket_core::svo::{Svo, Voxel};

/// A solid figure of boxes at `s` voxels per unit: legs, torso, arms a voxel clear of it, head.
/// At s = 12 it has about 1.1 million voxels.
fn figure(s: u32) -> Svo {
    let boxes: [([u32; 3], [u32; 3]); 6] = [
        ([2, 0, 2], [5, 9, 5]),    // leg R
        ([7, 0, 2], [10, 9, 5]),   // leg L
        ([1, 9, 1], [11, 17, 6]),  // torso
        ([0, 8, 2], [1, 16, 4]),   // arm R (one unit thick, beside the torso)
        ([11, 8, 2], [12, 16, 4]), // arm L
        ([4, 17, 1], [8, 21, 5]),  // head
    ];
    let mut voxels = Vec::new();
    for (lo, hi) in boxes {
        for z in lo[2] * s..hi[2] * s {
            for y in lo[1] * s..hi[1] * s {
                for x in lo[0] * s..hi[0] * s {
                    // A voxel-wide gap between the arms and the torso.
                    let gap = (x == s || x == 11 * s - 1) && y >= 9 * s;
                    if !gap {
                        voxels.push((
                            UVec3::new(x, y, z),
                            Voxel::new([200, 120, 90, 255], Vec3::Y),
                        ));
                    }
                }
            }
        }
    }
    Svo::from_voxels(9, false, voxels).expect("figure")
}

/// 24 joints in units (×s for voxels): a spine of 7, two arms of 4, two legs of 4, a root.
fn skeleton(s: u32) -> Skeleton {
    let u = s as f32;
    let mut joints = Vec::new();
    let mut add = |name: &str, parent: Option<&str>, p: [f32; 3]| {
        joints.push(JointSpec {
            name: name.into(),
            parent: parent.map(Into::into),
            position: p.map(|v| v * u),
        });
    };
    add("root", None, [6.0, 8.5, 3.5]);
    add("hip", Some("root"), [6.0, 9.5, 3.5]);
    add("spine1", Some("hip"), [6.0, 11.0, 3.5]);
    add("spine2", Some("spine1"), [6.0, 13.0, 3.5]);
    add("chest", Some("spine2"), [6.0, 15.0, 3.5]);
    add("neck", Some("chest"), [6.0, 17.0, 3.0]);
    add("head", Some("neck"), [6.0, 18.5, 3.0]);
    add("head.end", Some("head"), [6.0, 20.5, 3.0]);
    for (side, x) in [("R", 0.5f32), ("L", 11.5)] {
        let inner = if side == "R" { 2.0 } else { 10.0 };
        add(
            &format!("clavicle.{side}"),
            Some("chest"),
            [inner, 15.5, 3.0],
        );
        add(
            &format!("arm.{side}"),
            Some(&format!("clavicle.{side}")),
            [x, 15.5, 3.0],
        );
        add(
            &format!("forearm.{side}"),
            Some(&format!("arm.{side}")),
            [x, 12.0, 3.0],
        );
        add(
            &format!("hand.{side}"),
            Some(&format!("forearm.{side}")),
            [x, 8.5, 3.0],
        );
    }
    for (side, x) in [("R", 3.5f32), ("L", 8.5)] {
        add(&format!("thigh.{side}"), Some("root"), [x, 8.5, 3.5]);
        add(
            &format!("shin.{side}"),
            Some(&format!("thigh.{side}")),
            [x, 4.5, 3.5],
        );
        add(
            &format!("foot.{side}"),
            Some(&format!("shin.{side}")),
            [x, 1.0, 3.5],
        );
        add(
            &format!("toe.{side}"),
            Some(&format!("foot.{side}")),
            [x, 0.5, 4.5],
        );
    }
    assert_eq!(joints.len(), 24);
    SkeletonSpec { joints }.to_skeleton(None).expect("skeleton")
}

fn bench_bind(c: &mut Criterion) {
    let s = 12;
    let svo = figure(s);
    let skeleton = skeleton(s);
    eprintln!(
        "figure: {} voxels, {} joints",
        svo.leaf_count(),
        skeleton.len()
    );
    let mut group = c.benchmark_group("bind_1M_voxels_24_joints");
    group.sample_size(10);
    for method in BindMethod::ALL {
        group.bench_function(method.name(), |b| {
            b.iter(|| {
                bind(
                    black_box(&svo),
                    Vec3::ZERO,
                    1.0,
                    &skeleton,
                    method,
                    BindControl::default(),
                )
                .expect("binds")
            });
        });
    }
    group.finish();
    let (bound, report) = bind(
        &svo,
        Vec3::ZERO,
        1.0,
        &skeleton,
        BindMethod::Geodesic,
        BindControl::default(),
    )
    .expect("binds");
    eprintln!("{report:?}");
    // A dab of radius 8 on the right thigh, adding the hip's weight.
    let centre = Vec3::new(3.5, 6.0, 3.5) * s as f32;
    c.bench_function("weight_dab_radius_8", |b| {
        b.iter(|| weight_dab(black_box(&bound), 1, centre, 8.0, 0.5, false));
    });
    c.bench_function("weight_dab_radius_8_smooth", |b| {
        b.iter(|| weight_dab(black_box(&bound), 1, centre, 8.0, 0.0, true));
    });
}

criterion_group!(benches, bench_bind);
criterion_main!(benches);

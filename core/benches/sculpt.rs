//! Voxel tool benchmarks: a 10^6-voxel box add and its undo, a 10^6-voxel paste and recolour,
//! and flood fill and colour replacement over an 847,872-voxel one-colour block (96×96×92 in a
//! 128³ model). Goals: box, fill and paste of 10^6 and their undo within 100 ms, the flood
//! within 200 ms (release, 2 cores).
//!
//! The `tiles` group runs the box, its undo, a recolour and a sphere carve on tiled and on
//! voxel-by-voxel octrees side by side.
//!
//! `cargo bench -p thicket-core --bench sculpt -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use glam::{IVec3, UVec3};
use thicket_core::sculpt::{
    Ink, Mirror, ShapeOp, apply_box, copy, fill, flood_region, paste, replace_color, select_box,
};
use thicket_core::svo::Svo;

const INK: Ink = Ink {
    color: [200, 120, 40, 255],
    material: 0,
};
const OTHER: Ink = Ink {
    color: [20, 120, 240, 255],
    material: 0,
};

/// A 128³ model (depth 7) with a solid box from `lo` to `hi`.
fn model_with_box(lo: IVec3, hi: IVec3) -> Svo {
    let mut svo = Svo::new(7, false).expect("depth 7");
    let size = UVec3::splat(128);
    apply_box(
        &mut svo,
        size,
        lo,
        hi,
        ShapeOp::Add,
        INK,
        Mirror::default(),
        None,
    );
    svo
}

fn million(c: &mut Criterion) {
    let size = UVec3::splat(128);
    let (lo, hi) = (IVec3::splat(10), IVec3::splat(109));
    let empty = Svo::new(7, false).expect("depth 7");
    let mut g = c.benchmark_group("tools_1M");
    g.throughput(Throughput::Elements(1_000_000));
    g.sample_size(10);
    g.bench_function("box_add", |b| {
        b.iter_batched(
            || empty.clone(),
            |mut svo| {
                let e = apply_box(
                    &mut svo,
                    size,
                    lo,
                    hi,
                    ShapeOp::Add,
                    INK,
                    Mirror::default(),
                    None,
                );
                black_box((svo, e))
            },
            BatchSize::LargeInput,
        );
    });
    let mut added = empty.clone();
    let edit = apply_box(
        &mut added,
        size,
        lo,
        hi,
        ShapeOp::Add,
        INK,
        Mirror::default(),
        None,
    );
    assert_eq!(added.leaf_count(), 1_000_000);
    g.bench_function("box_add_undo", |b| {
        b.iter_batched(
            || added.clone(),
            |mut svo| {
                let redo = svo.apply_delta(&edit.delta);
                black_box((svo, redo))
            },
            BatchSize::LargeInput,
        );
    });
    let sel = select_box(&added, lo.as_uvec3(), hi.as_uvec3());
    let clip = copy(&added, &sel);
    g.bench_function("paste", |b| {
        b.iter_batched(
            || empty.clone(),
            |mut svo| {
                let e = paste(&mut svo, size, &clip, IVec3::splat(5), false);
                black_box((svo, e))
            },
            BatchSize::LargeInput,
        );
    });
    g.bench_function("fill_selection", |b| {
        b.iter_batched(
            || added.clone(),
            |mut svo| {
                let e = fill(&mut svo, &sel, OTHER);
                black_box((svo, e))
            },
            BatchSize::LargeInput,
        );
    });
    g.finish();
}

fn region(c: &mut Criterion) {
    let size = UVec3::splat(128);
    let svo = model_with_box(IVec3::new(16, 16, 18), IVec3::new(111, 111, 109));
    assert_eq!(svo.leaf_count(), 96 * 96 * 92);
    let mut g = c.benchmark_group("tools_848k");
    g.throughput(Throughput::Elements(svo.leaf_count()));
    g.sample_size(10);
    g.bench_function("flood_region", |b| {
        b.iter(|| {
            let r = flood_region(&svo, size, UVec3::splat(60), None);
            assert_eq!(r.len(), 847_872);
            black_box(r)
        });
    });
    g.bench_function("replace_color", |b| {
        b.iter_batched(
            || svo.clone(),
            |mut s| {
                let e = replace_color(&mut s, INK.color, OTHER.color, None);
                black_box((s, e))
            },
            BatchSize::LargeInput,
        );
    });
    g.finish();
}

/// Tiles against voxel-by-voxel storage (issue 43), side by side in one run: the 10^6 box add
/// and its undo, its recolour, and a sphere of radius 32 carved out of it (the bar: a
/// carve into a tiled solid within 1.5× of the same carve voxel by voxel).
fn tiles(c: &mut Criterion) {
    let size = UVec3::splat(128);
    let (lo, hi) = (IVec3::splat(10), IVec3::splat(109));
    let mut g = c.benchmark_group("tiles");
    g.sample_size(10);
    for (storage, empty) in [
        ("tiled", Svo::new(7, false).expect("depth 7")),
        (
            "voxel_by_voxel",
            Svo::new(7, false).expect("depth 7").without_tiles(),
        ),
    ] {
        let add = |svo: &mut Svo| {
            apply_box(
                svo,
                size,
                lo,
                hi,
                ShapeOp::Add,
                INK,
                Mirror::default(),
                None,
            )
        };
        g.bench_function(format!("box_add_1M/{storage}"), |b| {
            b.iter_batched(
                || empty.clone(),
                |mut svo| {
                    let e = add(&mut svo);
                    black_box((svo, e))
                },
                BatchSize::LargeInput,
            );
        });
        let mut added = empty.clone();
        let edit = add(&mut added);
        g.bench_function(format!("box_add_1M_undo/{storage}"), |b| {
            b.iter_batched(
                || added.clone(),
                |mut svo| {
                    let redo = svo.apply_delta(&edit.delta);
                    black_box((svo, redo))
                },
                BatchSize::LargeInput,
            );
        });
        let sel = select_box(&added, lo.as_uvec3(), hi.as_uvec3());
        g.bench_function(format!("recolour_1M/{storage}"), |b| {
            b.iter_batched(
                || added.clone(),
                |mut svo| {
                    let e = fill(&mut svo, &sel, OTHER);
                    black_box((svo, e))
                },
                BatchSize::LargeInput,
            );
        });
        let centre = glam::Vec3::splat(60.0);
        g.bench_function(format!("carve_sphere_r32/{storage}"), |b| {
            b.iter_batched(
                || added.clone(),
                |mut svo| {
                    let e = svo
                        .edit_existing(UVec3::splat(28), UVec3::splat(92), |c, v| {
                            (c.as_vec3().distance(centre) > 32.0).then_some(v)
                        })
                        .expect("inside");
                    black_box((svo, e))
                },
                BatchSize::LargeInput,
            );
        });
    }
    g.finish();
}

criterion_group!(benches, million, region, tiles);
criterion_main!(benches);

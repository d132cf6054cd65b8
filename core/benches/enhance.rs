//! Voxel detail enhancement on the 64³ sample terrain: full enhancement at 8× and 16× (work
//! follows the surface, so 16× should cost about 4× of 8×), resampling at 8×, and
//! re-enhancement after a single-voxel edit against the full 16× run.
//!
//! Run: `cargo bench -p thicket-core --bench enhance` (set `RAYON_NUM_THREADS=2` for the
//! 2-core figures). Fragments per second are printed once per configuration.

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::UVec3;
use thicket_core::enhance::{
    EnhanceSettings, Enhancer, Method, SubdivideSettings, ThresholdPattern, sample_terrain,
};
use thicket_core::svo::Svo;

fn subdivide(factor: u32) -> EnhanceSettings {
    EnhanceSettings {
        method: Method::Subdivide,
        factor,
        subdivide: SubdivideSettings {
            threshold: ThresholdPattern::Alternating {
                even: 3.0,
                odd: 4.0,
            },
        },
        ..EnhanceSettings::default()
    }
}

fn resample(factor: u32) -> EnhanceSettings {
    EnhanceSettings {
        method: Method::Resample,
        factor,
        ..EnhanceSettings::default()
    }
}

fn report(name: &str, terrain: &Svo, s: &EnhanceSettings) {
    let start = Instant::now();
    let e = Enhancer::new(terrain, s).expect("valid settings");
    let secs = start.elapsed().as_secs_f64();
    let st = e.stats();
    println!(
        "{name}: {} fragments in {:.3} s = {:.2} M fragments/s; candidates {}, with fragments {}, \
         coarse surface {}, cache hit rate {:.3} ({} entries)",
        st.fragments,
        secs,
        st.fragments as f64 / secs / 1e6,
        st.candidate_cells,
        st.cells_with_fragments,
        st.coarse_surface_voxels,
        st.cache_hit_rate(),
        st.cache_entries,
    );
}

fn full(c: &mut Criterion) {
    let terrain = sample_terrain(64, 1).expect("terrain");
    let mut g = c.benchmark_group("enhance_full");
    g.sample_size(10);
    for (name, s) in [
        ("subdivide_8x", subdivide(8)),
        ("subdivide_16x", subdivide(16)),
        ("resample_8x", resample(8)),
        ("resample_16x", resample(16)),
    ] {
        report(name, &terrain, &s);
        g.bench_function(name, |b| {
            b.iter(|| black_box(Enhancer::new(&terrain, &s).expect("valid")));
        });
    }
    g.finish();
}

fn single_edit(c: &mut Criterion) {
    let terrain = sample_terrain(64, 1).expect("terrain");
    let mut g = c.benchmark_group("enhance_edit");
    for (name, s) in [
        ("subdivide_16x", subdivide(16)),
        ("resample_16x", resample(16)),
    ] {
        let mut map = terrain.clone();
        let mut e = Enhancer::new(&map, &s).expect("valid");
        // Toggle a surface voxel in the middle of the map back and forth.
        let top = (0..64)
            .rev()
            .find(|&y| map.get(UVec3::new(32, y, 32)).is_some())
            .unwrap_or(0);
        let p = UVec3::new(32, top + 1, 32);
        let v = map.get(UVec3::new(32, top, 32)).unwrap_or_default();
        let mut on = false;
        g.bench_function(name, |b| {
            b.iter(|| {
                on = !on;
                let r = map
                    .edit_region(p, p, |_, _| on.then_some(v))
                    .expect("inside");
                e.update(&map, &r).expect("update");
                black_box(e.fine().leaf_count())
            });
        });
    }
    g.finish();
}

criterion_group!(benches, full, single_edit);
criterion_main!(benches);

//! Project loading and what its validation costs (issue 22: validation and budgets add ≤ 2 %
//! to loading the sample projects). `load/NAME` is `io::project::load` of a sample: reading the
//! JSON and the `.bin`, the object-graph check, checksums, decoding, the rig and weight checks
//! and `Document::validate`; `validate/NAME` is the checks that run on decoded data alone
//! (`Document::validate`, and `skin::rig::check_weights` for rigged models), on the loaded
//! document. The ratio of the two is the validation's share of a load.
//!
//! `cargo bench -p thicket-core --bench load -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use thicket_core::io::project;
use thicket_core::scene::{Document, ObjectKind};

fn checks(doc: &Document) {
    doc.validate().expect("a sample is valid");
    for o in &doc.objects {
        if let ObjectKind::Voxels(v) = &o.kind
            && let Some(rig) = &v.rig
        {
            thicket_core::skin::rig::check_weights(&v.svo, rig.skeleton.len())
                .expect("a sample's weights are valid");
        }
    }
}

fn benches(c: &mut Criterion) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects");
    let mut g = c.benchmark_group("load");
    g.sample_size(10);
    for name in ["house", "mixed", "terrain", "cesiumman", "tree", "forest"] {
        let path = dir.join(format!("{name}.thicket.json"));
        let Ok(doc) = project::load(&path) else {
            eprintln!("{name}: not loadable here, skipped");
            continue;
        };
        g.bench_function(format!("load/{name}"), |b| {
            b.iter(|| black_box(project::load(&path).map(|d| d.objects.len())));
        });
        g.bench_function(format!("validate/{name}"), |b| {
            b.iter(|| checks(black_box(&doc)));
        });
    }
    g.finish();
}

criterion_group!(load_benches, benches);
criterion_main!(load_benches);

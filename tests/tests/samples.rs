//! The committed sample projects load, validate, and equal a fresh build from the assets.

use thicket_core::io::project;
use thicket_tests::samples::{SAMPLES, build};

#[test]
fn samples_are_reproducible() {
    for name in SAMPLES {
        let path = thicket_tests::repo_root()
            .join("projects")
            .join(format!("{name}.thicket.json"));
        let loaded = project::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let fresh = build(name).unwrap();
        assert!(
            loaded == fresh,
            "projects/{name} differs from a fresh build: run `cargo run -p thicket-tests --bin make-samples`"
        );
    }
}

#[test]
fn house_has_the_exact_voxel_count() {
    let doc = build("house").unwrap();
    let voxels: u64 = doc
        .objects
        .iter()
        .map(|o| match &o.kind {
            thicket_core::scene::ObjectKind::Voxels(v) => v.svo.leaf_count(),
            _ => 0,
        })
        .sum();
    assert_eq!(voxels, 180_202);
}

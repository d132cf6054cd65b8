//! glTF export benchmarks: export time per sample project and mode (the file sizes are printed
//! once), greedy meshing against the per-face count, and KRS meshing of the tree and rock
//! presets at resolutions 128, 256 and 512 (work follows the surface: about 4× per doubling).
//!
//! `cargo bench -p thicket-core --bench export -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{Criterion, criterion_group, criterion_main};
use thicket_core::io::gltf_export::{
    ColorMode, ExportMode, GltfExportOptions, build_scene, encode_glb, greedy, mesh_krs,
};
use thicket_core::io::project;
use thicket_core::krs::{KrsScene, presets};
use thicket_core::scene::ObjectKind;

// Not forest and rock: their KRS grounds are unbounded (a half-space terrain), which the
// distance-field mesher refuses with an error; `thicket export --object` exports their parts.
const SAMPLES: [&str; 5] = ["house", "mixed", "terrain", "cesiumman", "tree"];

fn sample(name: &str) -> thicket_core::scene::Document {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../projects")
        .join(format!("{name}.thicket.json"));
    project::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

fn export_samples(c: &mut Criterion) {
    let mut group = c.benchmark_group("export_sample");
    group.sample_size(10);
    for name in SAMPLES {
        let doc = sample(name);
        for (label, mode, colors) in [
            ("cubes", ExportMode::Cubes, ColorMode::VertexColors),
            (
                "cubes_palette",
                ExportMode::Cubes,
                ColorMode::PaletteTexture,
            ),
            ("smooth", ExportMode::Smooth, ColorMode::VertexColors),
        ] {
            let options = GltfExportOptions {
                mode,
                colors,
                ..GltfExportOptions::default()
            };
            let path = PathBuf::from(format!("{name}-{label}.glb"));
            let run = || {
                let (scene, report) = build_scene(&doc, &path, &options, &|_| true).unwrap();
                (encode_glb(&scene, &path).unwrap(), report)
            };
            let (bytes, report) = run();
            println!(
                "{name} {label}: {} triangles, {} vertices, {} bytes of GLB",
                report.triangles,
                report.vertices,
                bytes.len()
            );
            group.bench_function(format!("{name}/{label}"), |b| b.iter(|| black_box(run())));
        }
    }
    group.finish();

    // Greedy meshing against one quad per exposed face, on the house.
    let doc = sample("house");
    for o in &doc.objects {
        if let ObjectKind::Voxels(v) = &o.kind {
            let faces = greedy::count_exposed_faces(&v.svo);
            let quads = greedy::greedy_quads(&v.svo).len();
            println!(
                "{}: {faces} exposed faces = {} triangles per face; greedy {quads} quads = {} \
                 triangles ({:.2}x fewer)",
                o.name,
                faces * 2,
                quads * 2,
                faces as f64 / quads as f64
            );
        }
    }
}

fn krs_meshing(c: &mut Criterion) {
    let mut group = c.benchmark_group("krs_mesh");
    group.sample_size(10);
    for (name, object) in [("tree", presets::tree()), ("rock", presets::rock())] {
        let scene = KrsScene {
            objects: vec![object],
        }
        .prepare()
        .unwrap();
        let o = &scene.objects[0];
        for resolution in [128u32, 256, 512] {
            let mesh = mesh_krs(o, resolution, 1 << 28, &|_| true).unwrap();
            println!(
                "{name} at {resolution}: {} triangles, {} vertices",
                mesh.triangle_count(),
                mesh.positions.len()
            );
            group.bench_function(format!("{name}/{resolution}"), |b| {
                b.iter(|| black_box(mesh_krs(o, resolution, 1 << 28, &|_| true).unwrap()));
            });
        }
    }
    group.finish();
}

criterion_group!(benches, export_samples, krs_meshing);
criterion_main!(benches);

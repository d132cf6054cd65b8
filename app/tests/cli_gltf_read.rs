//! Thicket reads its own glTF exports (issue 42): every KRS sample exported with
//! `--instancing gpu` (`EXT_mesh_gpu_instancing`, with `MSFT_lod` levels on the instanced
//! prototypes) and with `--instancing nodes` reads back through `thicket info` and the core
//! reader with the same triangles, every instance expanded; `thicket import` voxelizes it; and
//! an export too large to expand is refused in one line.

use std::path::{Path, PathBuf};

use serde_json::Value;

mod common;
use common::{stderr, stdout, thicket};

fn sample(name: &str) -> String {
    format!(
        "{}/../projects/{name}.thicket.json",
        env!("CARGO_MANIFEST_DIR")
    )
}

fn glb_json(path: &Path) -> Value {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[0..4], b"glTF", "{}", path.display());
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&bytes[20..20 + len]).unwrap()
}

fn index(v: &Value) -> usize {
    usize::try_from(v.as_u64().expect("an index")).unwrap()
}

/// Triangles the file draws, read from its JSON alone: every node of the scene (children
/// included) times the instances its `EXT_mesh_gpu_instancing` places. Level-of-detail nodes
/// lie outside the scene and do not count. Every primitive is an indexed triangle list, as the
/// exporter writes them.
fn drawn_triangles(json: &Value) -> (u64, u64) {
    let accessor_count = |a: &Value| json["accessors"][index(a)]["count"].as_u64().unwrap();
    let mut triangles = 0;
    let mut instances = 0;
    let mut stack: Vec<usize> = json["scenes"][0]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(index)
        .collect();
    while let Some(n) = stack.pop() {
        let node = &json["nodes"][n];
        stack.extend(node["children"].as_array().into_iter().flatten().map(index));
        let Some(mesh) = node["mesh"].as_u64() else {
            continue;
        };
        let attributes = &node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
        let copies = attributes["TRANSLATION"]
            .as_u64()
            .map_or(1, |_| accessor_count(&attributes["TRANSLATION"]));
        if attributes.is_object() {
            instances += copies;
        }
        for p in json["meshes"][mesh as usize]["primitives"]
            .as_array()
            .unwrap()
        {
            assert_eq!(p["mode"].as_u64().unwrap_or(4), 4, "triangle lists");
            triangles += copies * accessor_count(&p["indices"]) / 3;
        }
    }
    (triangles, instances)
}

/// `thicket export SAMPLE` at resolution 32 with `--instancing MODE` into `dir`.
fn export(dir: &Path, name: &str, mode: &str, extra: &[&str]) -> PathBuf {
    let out = dir.join(format!("{name}-{mode}.glb"));
    let project = sample(name);
    let mut args = vec![
        "export",
        project.as_str(),
        "-o",
        out.to_str().unwrap(),
        "--resolution",
        "32",
        "--instancing",
        mode,
    ];
    args.extend_from_slice(extra);
    let o = thicket(&args);
    assert!(o.status.success(), "{name} {mode}: {}", stderr(&o));
    out
}

/// `thicket info --json` of `file`.
fn info(file: &Path) -> Value {
    let o = thicket(&["info", "--json", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}: {}", file.display(), stderr(&o));
    serde_json::from_str(&stdout(&o)).unwrap()
}

/// Every KRS sample exports with either kind of placements and reads back with the same
/// triangles: `thicket info` and the core reader agree with each other and with what the
/// file's own JSON draws, and the gpu file's instances are all expanded.
#[test]
fn every_krs_sample_export_reads_back_with_the_same_triangles_in_both_modes() {
    let dir = tempfile::tempdir().unwrap();
    // The forest's and woodland's placements split at a level that keeps the expanded scene
    // small (1,024 and 2,048 trees); the terrains under meshes alone need a patch.
    let samples: [(&str, &[&str], u64); 6] = [
        ("tree", &[], 0),
        ("rock", &[], 0),
        ("grassland", &["--bounds=-20,-20,20,20"], 0),
        ("coral", &["--bounds=-20,-20,20,20"], 0),
        ("forest", &["--instance-level", "14"], 1_024),
        ("woodland", &["--instance-level", "10"], 2_048),
    ];
    let mut figures = Vec::new();
    for (name, extra, placements) in samples {
        let mut per_mode = Vec::new();
        for mode in ["gpu", "nodes"] {
            let file = export(dir.path(), name, mode, extra);
            let json = glb_json(&file);
            let (drawn, instances) = drawn_triangles(&json);
            let uses = |ext: &str| {
                json["extensionsUsed"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .any(|e| e == ext)
            };
            if mode == "gpu" {
                assert_eq!(instances, placements, "{name}");
                // The instanced prototypes carry levels of detail the reader leaves out.
                assert_eq!(uses("MSFT_lod"), placements > 0, "{name}");
            } else {
                assert_eq!(instances, 0, "{name}");
                assert!(!uses("EXT_mesh_gpu_instancing"), "{name}");
            }
            let report = info(&file);
            let info_triangles = report["total_triangles"].as_u64().unwrap();
            let source = &report["source"];
            assert_eq!(
                source["instances"].as_u64(),
                (instances > 0).then_some(instances),
                "{name} {mode}: {source}"
            );
            let core = thicket_core::io::import_gltf_imported(
                &file,
                &thicket_core::io::ImportLimits::default(),
            )
            .unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(core.instancing.instances, instances, "{name} {mode}");
            let core_triangles = core.model.triangle_count() as u64;
            assert_eq!(info_triangles, drawn, "{name} {mode}: info vs the JSON");
            assert_eq!(core_triangles, drawn, "{name} {mode}: core vs the JSON");
            per_mode.push(drawn);
        }
        assert_eq!(per_mode[0], per_mode[1], "{name}: gpu vs nodes");
        assert!(per_mode[0] > 100, "{name}: {per_mode:?}");
        figures.push(format!("{name} {}", per_mode[0]));
    }
    eprintln!("triangles read back (both modes): {}", figures.join(", "));
}

/// `thicket import` of an instanced forest export makes the objects an export with a node per
/// placement makes (one per tree, named alike, with the same voxels), or one grid with
/// `--merge`; the instances count against `--memory-limit` before anything is built.
#[test]
fn import_of_an_instanced_export_matches_the_node_per_placement_one() {
    let dir = tempfile::tempdir().unwrap();
    let extra = ["--instance-level", "14"];
    let mut objects = Vec::new();
    for mode in ["gpu", "nodes"] {
        let file = export(dir.path(), "forest", mode, &extra);
        let out = dir.path().join(format!("forest-{mode}.thicket.json"));
        let o = thicket(&[
            "import",
            file.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--depth",
            "5",
        ]);
        assert!(o.status.success(), "{mode}: {}", stderr(&o));
        let doc = thicket_core::io::project::load(&out).unwrap();
        let mut seen: Vec<(String, u64)> = doc
            .objects
            .iter()
            .map(|o| {
                let voxels = match &o.kind {
                    thicket_core::scene::ObjectKind::Voxels(v) => v.svo.leaf_count(),
                    _ => 0,
                };
                (o.name.clone(), voxels)
            })
            .collect();
        seen.sort();
        objects.push(seen);
    }
    // 1,024 trees and the ground.
    assert_eq!(objects[0].len(), 1_025);
    assert_eq!(objects[0], objects[1], "gpu and nodes import alike");
    assert!(objects[0].iter().any(|(n, _)| n == "Forest cell 0,0 0"));

    let gpu = dir.path().join("forest-gpu.glb");
    let merged = dir.path().join("merged.thicket.json");
    let o = thicket(&[
        "import",
        gpu.to_str().unwrap(),
        "-o",
        merged.to_str().unwrap(),
        "--merge",
        "--depth",
        "7",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("wrote"), "{}", stdout(&o));
    assert!(
        stdout(&o).contains("EXT_mesh_gpu_instancing: 4 node(s) place 1,024 instance(s)"),
        "{}",
        stdout(&o)
    );
    let doc = thicket_core::io::project::load(&merged).unwrap();
    assert_eq!(doc.objects.len(), 1);

    let o = thicket(&[
        "import",
        gpu.to_str().unwrap(),
        "-o",
        dir.path().join("x.thicket.json").to_str().unwrap(),
        "--memory-limit",
        "1M",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("error: ")
            && err.contains(
                "forest-gpu.glb: too large: the scene with its 1,024 instance(s) expanded"
            )
            && err.contains("over the limit of 1.0 MiB (--memory-limit)"),
        "{err}"
    );
    assert!(!dir.path().join("x.thicket.json").exists());
}

/// The forest with all of its 131,072 trees as placements would expand far past the import
/// limits even at resolution 32: `thicket import` refuses it at once, in one line naming the
/// file, the instances and the limit, and `thicket info` counts it instead of building it.
#[test]
fn an_export_too_large_to_expand_is_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let file = export(dir.path(), "forest", "gpu", &[]);
    let out = dir.path().join("x.thicket.json");
    let o = thicket(&[
        "import",
        file.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        err.starts_with("error: ")
            && err.contains(
                "forest-gpu.glb: too large: the scene with its 131,072 instance(s) expanded"
            )
            && err.contains("the limit is 805,306,368 indices"),
        "{err}"
    );
    assert!(!out.exists());
    let counted = &info(&file)["counted"];
    assert_eq!(counted["instances"].as_u64(), Some(131_072));
    let json = glb_json(&file);
    assert_eq!(
        counted["triangles"].as_u64(),
        Some(drawn_triangles(&json).0),
        "the count equals what the file's JSON draws"
    );
    assert!(
        counted["refused"]
            .as_str()
            .is_some_and(|r| r.contains("the limit is 805,306,368 indices")),
        "{counted}"
    );
}

//! Blender as a test client: Thicket's glTF exports imported headless by Debian's Blender 3.4
//! (`tests/blender/inspect_gltf.py`), checked for what an artist sees there: objects, meshes,
//! triangles equal to the export report, materials and colour attributes, lights and camera;
//! for skinned files the armature's bones, every clip as an action with its frame range, and
//! the mesh posed by Blender's own skinning at three frames of every action with no shared
//! position separating; for a forest its placements as linked duplicates (`--instancing
//! nodes`), and the `gpu` file refused by Blender 3.4 for the reason it gives.
//!
//! Blender is installed by `scripts/install-deps.sh` (with python3-numpy, which its glTF
//! importer needs); these tests fail, saying so, where it is missing.

use std::path::{Path, PathBuf};
use std::process::Command;

use thicket_core::io::gltf_export::{
    ExportMode, GltfExportOptions, GltfExportReport, Instancing, export_gltf,
};
use thicket_core::io::project;
use thicket_core::scene::{Document, ObjectKind};
use thicket_tests::repo_root;

/// What Blender saw, as `inspect_gltf.py` writes it.
fn inspect(glb: &Path) -> serde_json::Value {
    let script = repo_root().join("tests/blender/inspect_gltf.py");
    let json = glb.with_extension("json");
    let out = Command::new("blender")
        .args([
            "-b",
            "--factory-startup",
            "--python-exit-code",
            "1",
            "--python",
        ])
        .arg(&script)
        .arg("--")
        .arg(glb)
        .arg(&json)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run blender ({e}): scripts/install-deps.sh installs Debian's blender \
                 and python3-numpy, which these tests need"
            )
        });
    assert!(
        out.status.success(),
        "blender failed on {}: {}",
        glb.display(),
        String::from_utf8_lossy(&out.stdout)
    );
    serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap()
}

fn sample(name: &str) -> Document {
    project::load(&repo_root().join(format!("projects/{name}.thicket.json"))).unwrap()
}

/// Exports `doc` to `dir/name.glb`.
fn export(
    doc: &Document,
    dir: &Path,
    name: &str,
    options: &GltfExportOptions,
) -> (PathBuf, GltfExportReport) {
    let path = dir.join(format!("{name}.glb"));
    let report = export_gltf(doc, &path, options, &|_| true).unwrap();
    (path, report)
}

fn count(v: &serde_json::Value, key: &str) -> u64 {
    v[key].as_u64().unwrap_or_else(|| panic!("{key} in {v}"))
}

/// The static samples import with every triangle and vertex of the export, one mesh object
/// per exported object, their material and vertex colours, the light and the camera.
#[test]
fn static_samples_import_in_blender_as_exported() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["house", "mixed", "terrain", "rock", "tree"] {
        let options = GltfExportOptions {
            resolution: 64,
            ..GltfExportOptions::default()
        };
        let (glb, report) = export(&sample(name), dir.path(), name, &options);
        let seen = inspect(&glb);
        assert!(seen.get("error").is_none(), "{name}: {seen}");
        assert!(report.triangles > 500, "{name}: {report:?}");
        assert_eq!(count(&seen, "mesh_triangles"), report.triangles, "{name}");
        assert_eq!(count(&seen, "object_triangles"), report.triangles, "{name}");
        // The export writes each distinct vertex once (welded), so Blender, which merges
        // vertices whose attributes are all equal, has as many.
        assert_eq!(count(&seen, "vertices"), report.vertices, "{name}");
        assert_eq!(
            seen["objects"]["MESH"].as_u64(),
            Some(report.objects as u64),
            "{name}: {seen}"
        );
        assert!(count(&seen, "materials") >= 1, "{name}: {seen}");
        assert!(count(&seen, "color_attributes") >= 1, "{name}: {seen}");
        assert_eq!(count(&seen, "lights"), report.lights as u64, "{name}");
        assert_eq!(count(&seen, "cameras"), u64::from(report.camera), "{name}");
    }
}

/// CesiumMan (imported, skinned on voxels) and the critter (rigged and animated in Thicket):
/// Blender builds the armature with every joint, one action per clip over its frames, and its
/// own skinning of the exported mesh keeps every shared position together at the start,
/// middle and end of every action.
#[test]
fn skinned_exports_pose_in_blender_without_cracks() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["cesiumman", "critter"] {
        let doc = sample(name);
        let rig = doc
            .objects
            .iter()
            .find_map(|o| match &o.kind {
                ObjectKind::Voxels(v) => v.rig.as_ref(),
                _ => None,
            })
            .expect("a rigged model");
        let (glb, report) = export(&doc, dir.path(), name, &GltfExportOptions::default());
        let seen = inspect(&glb);
        assert!(seen.get("error").is_none(), "{name}: {seen}");
        assert_eq!(count(&seen, "mesh_triangles"), report.triangles, "{name}");
        // Blender makes a bone of every joint and of every attachment node (the node the
        // exporter writes between a joint and its parent when the source file had one there).
        let attachments = rig
            .skeleton
            .joints
            .iter()
            .filter(|j| j.parent_from_attachment != glam::Mat4::IDENTITY)
            .count();
        assert_eq!(
            seen["bones"],
            serde_json::json!([rig.skeleton.joints.len() + attachments]),
            "{name}"
        );
        // One action per clip, and one for the object's own keyed motion when it has one.
        let actions = seen["actions"].as_object().unwrap();
        assert_eq!(
            actions.len(),
            rig.clips.len() + report.animated.len(),
            "{name}: {actions:?}"
        );
        for clip in &rig.clips {
            let (_, range) = actions
                .iter()
                .find(|(a, _)| a.starts_with(&format!("{}_", clip.name)))
                .unwrap_or_else(|| panic!("{name}: no action for clip {:?}", clip.name));
            // Blender at its default 24 frames per second, frames from the keys' times.
            let frames = range[1].as_f64().unwrap() - range[0].as_f64().unwrap();
            let expected = f64::from(clip.duration_secs) * 24.0;
            assert!(
                (frames - expected).abs() <= 1.5,
                "{name} {:?}: {frames} frames for {expected}",
                clip.name
            );
        }
        let gaps = seen["skin_gaps"].as_array().unwrap();
        assert_eq!(gaps.len(), 3 * actions.len(), "{name}: {gaps:?}");
        for g in gaps {
            // Positions held by several vertices (where colours differ: corners of one colour
            // are one welded vertex, which cannot crack): 230 on the critter, thousands on
            // CesiumMan; enough that the check is not vacuous.
            assert!(count(g, "shared") > 200, "{name}: {g}");
            assert_eq!(g["max_gap"].as_f64(), Some(0.0), "{name}: a crack {g}");
        }
    }
}

/// The forest with `--instancing nodes`: every placement a linked duplicate of the prototype
/// (or its mirrored copy) in Blender; with `--flatten`, plain meshes holding every copy; with
/// `gpu`, Blender 3.4 refuses the file and says why, as the export's own report warns.
#[test]
fn a_forest_imports_as_linked_duplicates_and_gpu_instancing_is_refused_by_blender_3_4() {
    let dir = tempfile::tempdir().unwrap();
    let doc = sample("forest");
    let options = GltfExportOptions {
        mode: ExportMode::Cubes,
        resolution: 32,
        // 1,024 placements: what CI can import in seconds (the default split, 131,072
        // placements, takes Blender about five minutes).
        instance_level: Some(14),
        instancing: Instancing::Nodes,
        ..GltfExportOptions::default()
    };
    let (glb, report) = export(&doc, dir.path(), "forest-nodes", &options);
    let (mode, placements) = report.placements.expect("instanced");
    assert_eq!((mode, placements), (Instancing::Nodes, 1024));
    let seen = inspect(&glb);
    assert!(seen.get("error").is_none(), "{seen}");
    assert_eq!(count(&seen, "mesh_triangles"), report.triangles);
    let others = report.objects as u64 - report.instanced.len() as u64;
    assert_eq!(
        seen["objects"]["MESH"].as_u64(),
        Some(placements as u64 + others),
        "{seen}"
    );
    // The prototype, its mirrored copy and the other objects' meshes, each stored once.
    assert_eq!(count(&seen, "meshes"), 2 + others, "{seen}");
    assert_eq!(
        count(&seen, "linked_duplicates"),
        placements as u64 - 2,
        "{seen}"
    );
    // Triangles drawn: the prototype at each placement, plus the other objects once.
    let proto = report.instanced[0].prototype_triangles;
    assert_eq!(report.instanced.len(), 1);
    assert_eq!(
        count(&seen, "object_triangles"),
        proto * placements as u64 + (report.triangles - 2 * proto),
        "{seen}"
    );

    // --flatten: plain meshes only (no shared mesh, no extension), every copy's triangles.
    let flat = GltfExportOptions {
        instancing: Instancing::Flatten,
        ..options.clone()
    };
    let (glb, flat_report) = export(&doc, dir.path(), "forest-flat", &flat);
    let seen = inspect(&glb);
    assert!(seen.get("error").is_none(), "{seen}");
    assert_eq!(count(&seen, "linked_duplicates"), 0, "{seen}");
    assert_eq!(
        count(&seen, "object_triangles"),
        flat_report.triangles,
        "{seen}"
    );
    assert_eq!(
        flat_report.triangles,
        proto * placements as u64 + (report.triangles - 2 * proto)
    );

    let gpu = GltfExportOptions {
        instancing: Instancing::Gpu,
        ..options
    };
    let (glb, _) = export(&doc, dir.path(), "forest-gpu", &gpu);
    let seen = inspect(&glb);
    assert_eq!(
        seen["error"].as_str().map(str::trim),
        Some("Error: Extension EXT_mesh_gpu_instancing is not available on this addon version"),
        "{seen}"
    );
}

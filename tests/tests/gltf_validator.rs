//! Every file exported from every sample project passes the Khronos glTF-Validator (npm
//! `gltf-validator`, installed by `scripts/install-deps.sh` into `tools/gltf-validator`) with
//! zero errors and no warnings about weights or accessor data: the node script fails on those.

use std::path::Path;
use std::process::Command;

use thicket_core::io::gltf_export::{ColorMode, ExportMode, GltfExportOptions, export_gltf};
use thicket_core::io::project;
use thicket_core::scene::ObjectKind;
use thicket_tests::samples::SAMPLES;

fn validate(dir: &Path) -> String {
    let tool = thicket_tests::repo_root().join("tools/gltf-validator");
    assert!(
        tool.join("node_modules/gltf-validator/package.json")
            .exists(),
        "the glTF-Validator is not installed: run scripts/install-deps.sh (it runs `npm ci` in \
         tools/gltf-validator)"
    );
    let out = Command::new("node")
        .arg(tool.join("validate.mjs"))
        .arg(dir)
        .output()
        .expect("node runs (scripts/install-deps.sh installs it)");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "the glTF-Validator refused an export:\n{text}"
    );
    text
}

#[test]
fn every_sample_export_passes_the_khronos_validator() {
    let dir = tempfile::tempdir().unwrap();
    let mut written = 0;
    for name in SAMPLES {
        let path = thicket_tests::repo_root()
            .join("projects")
            .join(format!("{name}.thicket.json"));
        let doc = project::load(&path).unwrap_or_else(|e| panic!("{e}"));
        // The KRS samples are exported below, object by object, at test-sized resolutions.
        if doc
            .objects
            .iter()
            .any(|o| matches!(o.kind, ObjectKind::Krs(_)))
        {
            continue;
        }
        let forms = [
            ("cubes.glb", ExportMode::Cubes, ColorMode::VertexColors, 0),
            (
                "palette.gltf",
                ExportMode::Cubes,
                ColorMode::PaletteTexture,
                0,
            ),
            ("smooth.glb", ExportMode::Smooth, ColorMode::VertexColors, 0),
            // Two coarser levels of detail (MSFT_lod).
            ("lod.glb", ExportMode::Cubes, ColorMode::VertexColors, 2),
        ];
        for (suffix, mode, colors, lod_levels) in forms {
            // Smooth meshing of the 180k-voxel house takes seconds in a debug build; the
            // character sample covers smooth mode.
            if name == "house" && mode == ExportMode::Smooth {
                continue;
            }
            let out = dir.path().join(format!("{name}-{suffix}"));
            let options = GltfExportOptions {
                mode,
                colors,
                lod_levels,
                ..GltfExportOptions::default()
            };
            export_gltf(&doc, &out, &options, &|_| true).unwrap_or_else(|e| panic!("{e}"));
            written += 1;
        }
    }
    // Every sample with the default options, as `thicket export SAMPLE -o SAMPLE.glb` writes
    // it: KRS objects instanced as prototype × placements where they repeat (the forest's
    // 2^17 trees), unbounded ones (ground planes, the rock sample's terrain) as a patch under
    // the rest, distorted rocks meshed through their warp, the lights and the camera.
    for name in SAMPLES {
        let path = thicket_tests::repo_root()
            .join("projects")
            .join(format!("{name}.thicket.json"));
        let doc = project::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let out = dir.path().join(format!("{name}-default.glb"));
        let report = export_gltf(&doc, &out, &GltfExportOptions::default(), &|_| true)
            .unwrap_or_else(|e| panic!("{name} with default options: {e}"));
        let visible = doc.objects.iter().filter(|o| o.visible).count();
        assert_eq!(report.objects, visible, "{name}: every visible object");
        // Thicket reads its own export back: `thicket info`'s count, and the import where
        // the expanded scene fits the limits (the forest's 2^17 trees and the woodland's 2^14
        // do not: counted only).
        let limits = thicket_core::io::ImportLimits::default();
        let count = thicket_core::io::count_gltf(&out, &limits)
            .unwrap_or_else(|e| panic!("{name}: the count reads the export: {e}"));
        println!(
            "{name}: read back {} triangles, {} vertices{}",
            count.triangles,
            count.vertices,
            if count.refused.is_some() {
                " (counted, too large to import)"
            } else {
                ""
            }
        );
        match &count.refused {
            None => {
                let import = thicket_core::io::import_gltf_imported(&out, &limits)
                    .unwrap_or_else(|e| panic!("{name}: the import reads the export: {e}"));
                let triangles: usize = import.model.parts.iter().map(|p| p.indices.len() / 3).sum();
                assert_eq!(triangles as u64, count.triangles, "{name}");
                // Cubes carry no NORMAL: the reader splits vertices for flat normals, within
                // the bound the count allowed for.
                let vertices = import.model.vertex_count() as u64;
                assert!(
                    vertices >= count.vertices
                        && vertices <= count.vertices + count.flat_normal_vertices,
                    "{name}: {vertices} vertices read, {} in the file + up to {}",
                    count.vertices,
                    count.flat_normal_vertices
                );
                assert_eq!(
                    count.triangles, report.triangles,
                    "{name}: read back as written"
                );
            }
            Some(why) => assert!(
                ["forest", "woodland"].contains(&name) && count.instances > 10_000,
                "{name}: refused: {why}"
            ),
        }
        assert!(report.triangles > 100, "{name}: {report:?}");
        assert!(report.camera && report.lights == doc.lights.len(), "{name}");
        match name {
            "forest" => {
                let [trees] = &report.instanced[..] else {
                    panic!("forest: one instanced object: {:?}", report.instanced);
                };
                assert_eq!(trees.instances, 1 << 17, "one copy per tree");
                assert_eq!(trees.mirrored, 1 << 16);
                assert_eq!(report.patches.len(), 1, "the ground plane");
            }
            "rock" => assert_eq!(report.patches.len(), 1, "the terrain under the rocks"),
            _ => {}
        }
        written += 1;
    }
    // Levels of detail (MSFT_lod) of KRS meshes, at a test-sized resolution: the forest's
    // instanced tree (each level a node with the same placements, the mirrored copy too) and
    // the tree sample's mesh.
    for name in ["forest", "tree"] {
        let path = thicket_tests::repo_root()
            .join("projects")
            .join(format!("{name}.thicket.json"));
        let doc = project::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let out = dir.path().join(format!("{name}-lod.glb"));
        let options = GltfExportOptions {
            resolution: 128,
            lod_levels: 3,
            ..GltfExportOptions::default()
        };
        let report = export_gltf(&doc, &out, &options, &|_| true)
            .unwrap_or_else(|e| panic!("{name} with levels of detail: {e}"));
        let [levels] = &report.levels_of_detail[..] else {
            panic!("{name}: one KRS object with levels: {report:?}");
        };
        // 64 and 32 cells; at 16 the crown's outer twigs vanish (its box shrinks by more than
        // a cell), which ends the levels (docs/export.md).
        println!("{name}: levels of detail {:?}", levels.triangles);
        assert!(levels.triangles.len() >= 3, "{name}: {levels:?}");
        assert!(
            levels.triangles.windows(2).all(|w| w[1] < w[0]),
            "{name}: each level coarser: {levels:?}"
        );
        written += 1;
    }
    // Portable instancing: the forest with a node per placement and no extension, as Blender
    // 3.4 can import it; a prototype of 2^7 trees (instance level 14) keeps the file small.
    {
        let path = thicket_tests::repo_root().join("projects/forest.thicket.json");
        let doc = project::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let out = dir.path().join("forest-nodes.glb");
        let options = GltfExportOptions {
            resolution: 96,
            instance_level: Some(14),
            instancing: thicket_core::io::gltf_export::Instancing::Nodes,
            ..GltfExportOptions::default()
        };
        let report = export_gltf(&doc, &out, &options, &|_| true)
            .unwrap_or_else(|e| panic!("forest with a node per placement: {e}"));
        println!("forest-nodes: {:?}", report.placements);
        assert_eq!(
            report.placements,
            Some((thicket_core::io::gltf_export::Instancing::Nodes, 1 << 10))
        );
        let (gltf, _, _) = gltf::import(&out).unwrap();
        assert!(gltf.extensions_required().next().is_none());
        assert_eq!(
            gltf.nodes()
                .filter(|n| n.mesh().is_some() && n.name().is_some_and(|m| m.starts_with("Forest")))
                .count(),
            1 << 10
        );
        written += 1;
    }
    let report = validate(dir.path());
    assert!(
        report.contains(&format!("{written} of {written} files pass")),
        "{report}"
    );
}

//! Every file exported from every sample project passes the Khronos glTF-Validator (npm
//! `gltf-validator`, installed by `scripts/install-deps.sh` into `tools/gltf-validator`) with
//! zero errors and no warnings about weights or accessor data: the node script fails on those.

use std::path::Path;
use std::process::Command;

use thicket_core::io::gltf_export::{
    ColorMode, ExportMode, ExportScene, GltfExportOptions, add_krs_object, encode_glb, export_gltf,
};
use thicket_core::io::project;
use thicket_core::krs::{KrsScene, presets};
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
        let forms = [
            ("cubes.glb", ExportMode::Cubes, ColorMode::VertexColors),
            ("palette.gltf", ExportMode::Cubes, ColorMode::PaletteTexture),
            ("smooth.glb", ExportMode::Smooth, ColorMode::VertexColors),
        ];
        for (suffix, mode, colors) in forms {
            // Smooth meshing of the 180k-voxel house takes seconds in a debug build; the
            // character sample covers smooth mode.
            if name == "house" && mode == ExportMode::Smooth {
                continue;
            }
            let out = dir.path().join(format!("{name}-{suffix}"));
            let options = GltfExportOptions {
                mode,
                colors,
                ..GltfExportOptions::default()
            };
            export_gltf(&doc, &out, &options, &|_| true).unwrap_or_else(|e| panic!("{e}"));
            written += 1;
        }
    }
    // KRS objects (tree and rock presets) as they will be exported from documents: the
    // distance-field mesh, and the tree's kernels instanced (the rock's half-spaces cannot be).
    for (name, object, mode) in [
        ("rock", presets::rock(), ExportMode::Cubes),
        ("tree-instances", presets::tree(), ExportMode::Instances),
    ] {
        let prepared = KrsScene {
            objects: vec![object],
        }
        .prepare()
        .unwrap();
        let options = GltfExportOptions {
            mode,
            resolution: 48,
            ..GltfExportOptions::default()
        };
        let mut export = ExportScene::default();
        add_krs_object(&mut export, name, &prepared.objects[0], &options, &|_| true).unwrap();
        let out = dir.path().join(format!("krs-{name}.glb"));
        std::fs::write(&out, encode_glb(&export, &out).unwrap()).unwrap();
        written += 1;
    }
    let report = validate(dir.path());
    assert!(
        report.contains(&format!("{written} of {written} files pass")),
        "{report}"
    );
}

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
    // KRS sample documents through the same export path: the tree sample (KRS tree on a mesh
    // ground) as a distance-field mesh and with its kernels instanced, one rock of the rock
    // sample (its terrain is a folded half-space: unbounded, no closed mesh). The forest's
    // 33 million instances are over the instance limit and its distance field is kilometres
    // wide, so it has no export in this test.
    for (name, object, mode, resolution) in [
        ("tree", None, ExportMode::Cubes, 96),
        ("tree", None, ExportMode::Instances, 96),
        ("rock", Some("Rock 1"), ExportMode::Cubes, 48),
    ] {
        let path = thicket_tests::repo_root()
            .join("projects")
            .join(format!("{name}.thicket.json"));
        let doc = project::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let out = dir.path().join(format!("krs-{name}-{mode:?}.glb"));
        let options = GltfExportOptions {
            mode,
            resolution,
            object: object.map(str::to_owned),
            ..GltfExportOptions::default()
        };
        let report = export_gltf(&doc, &out, &options, &|_| true)
            .unwrap_or_else(|e| panic!("{name} {mode:?}: {e}"));
        assert!(report.triangles > 100, "{name} {mode:?}: {report:?}");
        written += 1;
    }
    let report = validate(dir.path());
    assert!(
        report.contains(&format!("{written} of {written} files pass")),
        "{report}"
    );
}

//! Cross-module round trips on real assets.

use thicket_core::io::{import_gltf, project};
use thicket_core::scene::{Document, ObjectKind, VoxelModel};
use thicket_core::voxelize::{Mode, Resolution, VoxelizeSettings, voxelize};
use thicket_tests::asset;

/// glTF → SVO → project → load gives back the identical document (skin weights included).
#[test]
fn gltf_to_svo_to_project_and_back_is_identical() {
    for (file, mode) in [
        ("skinned/CesiumMan.glb", Mode::Surface),
        ("static/Box.glb", Mode::Solid),
    ] {
        let model = import_gltf(&asset(file)).unwrap();
        let settings = VoxelizeSettings {
            resolution: Resolution::Depth(6),
            mode,
            ..VoxelizeSettings::default()
        };
        let v = voxelize(&model, &settings, &|_| true).unwrap();
        assert!(v.svo.leaf_count() > 0);
        let mut doc = Document::default();
        doc.add(
            file,
            ObjectKind::Voxels(VoxelModel {
                svo: v.svo,
                voxel_size: v.voxel_size,
                origin: v.origin,
                material_names: vec![],
                rig: None,
                volume: None,
                palette: Vec::new(),
                frames: None,
            }),
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rt.thicket.json");
        project::save(&doc, &path).unwrap();
        let loaded = project::load(&path).unwrap();
        assert!(
            loaded == doc,
            "{file} changed on the way through the project file"
        );
    }
}

//! Skinned voxel export and levels of detail (issue 9): the exported CesiumMan voxels, skinned on
//! the CPU from the file's own joints, weights, inverse bind matrices, joint hierarchy and
//! animation, land where the editor's skinned voxel corners are, at 10 times of the walk. (That
//! the posed surface stays closed is `watertight_tests`.)

use std::collections::HashMap;

use glam::{Mat4, Quat, UVec3, Vec3};

use super::{ExportMode, GltfExportOptions, export_gltf};
use crate::io::import_skinned;
use crate::scene::{Document, ObjectKind, Transform};
use crate::skin::{Rig, Skin4, SkinTables};

const CESIUM_MAN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/assets/skinned/CesiumMan.glb"
);

/// `Σ wₖ · skinning[jₖ]`.
fn blend(skinning: &[Mat4], influences: impl Iterator<Item = (usize, f32)>) -> Mat4 {
    let mut m = Mat4::ZERO;
    for (j, w) in influences {
        m += skinning[j] * w;
    }
    m
}

fn skinned_cesium_man(depth: u8) -> Document {
    let mut doc = crate::skin::deform_tests::skinned_doc(CESIUM_MAN, depth);
    // A placement, so the skeleton's root node has a transform to carry.
    doc.objects[0].transform = Transform {
        translation: Vec3::new(1.0, -2.0, 0.5),
        rotation: Quat::from_rotation_y(0.7),
        scale: Vec3::splat(1.5),
    };
    doc
}

#[test]
fn exported_skinned_voxels_walk_exactly_like_the_editors_voxel_corners() {
    let doc = skinned_cesium_man(6);
    let object = &doc.objects[0];
    let ObjectKind::Voxels(model) = &object.kind else {
        panic!("a voxel model")
    };
    let rig = model.rig.as_ref().expect("skinned");
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("cesium-man-voxels.glb");
    let report =
        export_gltf(&doc, &path, &GltfExportOptions::default(), &|_| true).expect("exports");
    assert!(report.triangles > 1000, "{report:?}");

    let back = import_skinned(&path).expect("the export imports as a skinned file");
    assert_eq!(back.skeleton.len(), rig.skeleton.len());
    assert_eq!(back.clips.len(), rig.clips.len());
    // Nothing repaired or skipped; the export's camera and sun are imported, said once each.
    let (view, other): (Vec<&String>, Vec<&String>) = back
        .warnings
        .iter()
        .partition(|w| w.contains("camera(s)") || w.starts_with("lights:"));
    assert!(other.is_empty(), "{other:?}");
    assert_eq!(view.len(), 2, "{:?}", back.warnings);
    assert!(
        view[0].starts_with("1 camera(s): the first imported as the document camera"),
        "{view:?}"
    );
    assert!(
        view[1].starts_with("lights: 1 directional imported, 0 point/spot not imported"),
        "{view:?}"
    );
    // In the file's world space, where the skinned voxels are posed.
    let camera = back.view.camera.expect("the export's camera");
    assert!(camera.eye.abs_diff_eq(doc.camera.eye(), 1e-4), "{camera:?}");
    let [sun] = &back.view.lights[..] else {
        panic!("the export's sun: {:?}", back.view.lights);
    };
    let direction = doc.lights[0].direction.normalize_or_zero();
    assert!(sun.direction.dot(direction) > 1.0 - 1e-5, "{sun:?}");
    let back_rig = Rig::new(back.skeleton.clone(), back.clips.clone());

    // The editor's corner weights (what its `Corners` stretch strategy skins), by lattice point.
    let tables = SkinTables::build(&model.svo);
    let mut corner_skins: HashMap<UVec3, Skin4> = HashMap::new();
    let mut stack = vec![model.svo.root()];
    while let Some(n) = stack.pop() {
        if model.svo.is_leaf(&n) {
            for (k, s) in tables
                .leaf_corner_skins(n.index)
                .expect("a leaf of the octree")
                .iter()
                .enumerate()
            {
                let k = k as u32;
                corner_skins.insert(n.origin + UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1), *s);
            }
        } else {
            stack.extend((0..8).filter_map(|k| model.svo.child(&n, k)));
        }
    }

    let world_from_object = object.transform.matrix();
    let duration = rig.clips[0].duration_secs;
    let mut vertices = 0usize;
    let mut worst = 0.0f32;
    for k in 0..10 {
        let t = duration * k as f32 / 10.0;
        let ours = rig.skinning_at(Some(0), t);
        let theirs = back_rig.skinning_at(Some(0), t);
        for part in &back.mesh.parts {
            assert_eq!(part.joints.len(), part.positions.len());
            for (i, &v) in part.positions.iter().enumerate() {
                let lattice = ((v - model.origin) / model.voxel_size).round();
                let s = corner_skins
                    .get(&UVec3::new(
                        lattice.x as u32,
                        lattice.y as u32,
                        lattice.z as u32,
                    ))
                    .expect("every exported vertex is a corner of a voxel");
                let editor = world_from_object
                    * blend(
                        &ours,
                        (0..4).map(|k| (usize::from(s.joints[k]), f32::from(s.weights[k]) / 255.0)),
                    );
                let file = blend(
                    &theirs,
                    (0..4).map(|k| (usize::from(part.joints[i][k]), part.weights[i][k])),
                );
                let d = file
                    .transform_point3(v)
                    .distance(editor.transform_point3(v));
                worst = worst.max(d);
                vertices += 1;
            }
        }
    }
    eprintln!("{vertices} vertex samples, worst distance {worst:e}");
    assert!(vertices > 10_000, "{vertices}");
    // The model is about 2.3 units tall once placed; f32 round-off is ~1e-6 of that.
    assert!(worst < 1e-4, "worst vertex distance {worst}");
}

#[test]
fn smooth_export_of_a_skinned_model_is_a_static_bind_pose() {
    let doc = skinned_cesium_man(5);
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("smooth.glb");
    let options = GltfExportOptions {
        mode: ExportMode::Smooth,
        ..GltfExportOptions::default()
    };
    export_gltf(&doc, &path, &options, &|_| true).expect("exports");
    let e = import_skinned(&path).expect_err("no skin in a smooth export");
    assert!(e.to_string().contains("skin"), "{e}");
}

#[test]
fn lod_levels_are_coarser_msft_lod_alternatives() {
    use crate::io::vox::import_vox;
    let house = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/vox/mmmm/obj_house4.vox"
    );
    let scene = import_vox(std::path::Path::new(house)).expect("the house imports");
    let mut doc = Document::default();
    for o in scene.objects {
        doc.add(&o.name, o.kind);
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("house-lod.glb");
    let options = GltfExportOptions {
        lod_levels: 2,
        ..GltfExportOptions::default()
    };
    export_gltf(&doc, &path, &options, &|_| true).expect("exports");
    let (g, _, _) = gltf::import(&path).expect("loads");
    assert!(g.extensions_used().any(|e| e == "MSFT_lod"));
    let triangles = |n: &gltf::Node<'_>| -> usize {
        n.mesh().map_or(0, |m| {
            m.primitives()
                .map(|p| p.indices().map_or(0, |a| a.count() / 3))
                .sum()
        })
    };
    let scene_roots: Vec<usize> = g
        .default_scene()
        .expect("a scene")
        .nodes()
        .map(|n| n.index())
        .collect();
    // Lights and the camera are roots without a mesh.
    for root in g
        .nodes()
        .filter(|n| scene_roots.contains(&n.index()) && n.mesh().is_some())
    {
        let full = triangles(&root);
        let lod = root
            .extensions()
            .and_then(|e| e.get("MSFT_lod"))
            .expect("every voxel model lists its levels");
        let ids: Vec<usize> = lod["ids"]
            .as_array()
            .expect("ids")
            .iter()
            .map(|v| v.as_u64().expect("index") as usize)
            .collect();
        assert_eq!(ids.len(), 2);
        let mut previous = full;
        for id in ids {
            assert!(
                !scene_roots.contains(&id),
                "levels are not drawn by the scene"
            );
            let level = g.nodes().nth(id).expect("the level node");
            let t = triangles(&level);
            assert!(t > 0 && t < previous, "{t} vs {previous}");
            previous = t;
        }
    }
    // Palette textures cannot carry levels: refused before anything is written.
    let options = GltfExportOptions {
        lod_levels: 1,
        colors: super::ColorMode::PaletteTexture,
        ..GltfExportOptions::default()
    };
    let bad = dir.path().join("refused.glb");
    let e = export_gltf(&doc, &bad, &options, &|_| true).expect_err("refused");
    assert!(e.to_string().contains("vertex colours"), "{e}");
    assert!(!bad.exists());
}

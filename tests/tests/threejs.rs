//! Exported files loaded by three.js's own GLTFLoader (npm `three`, pinned in
//! `tools/threejs-check`, installed by `scripts/install-deps.sh`) in node: what three.js draws is
//! what the export says it wrote, and mirrored placements show their outside.

use std::path::Path;
use std::process::Command;

use glam::{Quat, Vec3};
use serde_json::Value;
use thicket_core::io::gltf_export::{
    ExportNode, ExportScene, GltfExportOptions, add_krs_object, encode_glb, export_gltf,
};
use thicket_core::io::project;
use thicket_core::krs::{Kernel, KrsObject, KrsScene, Material, MirrorPlane, SphereKernel};
use thicket_core::scene::{Document, ObjectKind, Transform};

/// Runs `tools/threejs-check/inspect.mjs` on `file` and returns its JSON report.
fn inspect(file: &Path, faces: bool) -> Value {
    let tool = thicket_tests::repo_root().join("tools/threejs-check");
    assert!(
        tool.join("node_modules/three/package.json").exists(),
        "three.js is not installed: run scripts/install-deps.sh (it runs `npm ci` in \
         tools/threejs-check)"
    );
    let mut command = Command::new("node");
    command.arg(tool.join("inspect.mjs")).arg(file);
    if faces {
        command.arg("--faces");
    }
    let out = command
        .output()
        .expect("node runs (scripts/install-deps.sh installs it)");
    assert!(
        out.status.success(),
        "three.js could not load {}:\n{}{}",
        file.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "inspect.mjs printed no JSON ({e}):\n{}",
            String::from_utf8_lossy(&out.stdout)
        )
    })
}

fn u(v: &Value) -> u64 {
    v.as_u64()
        .unwrap_or_else(|| panic!("{v} is not a whole number"))
}

/// The forest with default flags, as `thicket export projects/forest.thicket.json -o f.glb`
/// writes it: three.js makes an InstancedMesh per cell of the tree and of its mirrored copy,
/// and draws exactly the placements the export reports, none of them through a mirroring
/// matrix. Without MSFT_lod (three.js's GLTFLoader alone) every tree is the full mesh; with
/// the plugin of `tools/threejs-check/msft-lod.mjs`, from the file's camera, each tree is drawn
/// at the level its screen coverage asks for: the same instances, a small fraction of the
/// triangles.
#[test]
fn threejs_draws_the_forest_instances_the_export_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let doc = project::load(&thicket_tests::repo_root().join("projects/forest.thicket.json"))
        .unwrap_or_else(|e| panic!("{e}"));
    let out = dir.path().join("forest.glb");
    let report = export_gltf(&doc, &out, &GltfExportOptions::default(), &|_| true)
        .unwrap_or_else(|e| panic!("{e}"));
    let [trees] = &report.instanced[..] else {
        panic!("one instanced object: {:?}", report.instanced);
    };
    let [levels] = &report.levels_of_detail[..] else {
        panic!("the tree's levels of detail: {report:?}");
    };
    assert!(trees.impostor, "{trees:?}");
    let three = inspect(&out, false);
    let mut summary = three.clone();
    summary["instanced"] = Value::from(three["instanced"].as_array().unwrap().len());
    println!("{summary}");
    assert_eq!(
        u(&three["instancedMeshes"]),
        u64::from(trees.cell_nodes),
        "a tree and a mirrored tree mesh per cell"
    );
    assert!(trees.cell_nodes > 100, "{trees:?}");
    assert_eq!(u(&three["instances"]), trees.instances);
    assert_eq!(trees.instances, 1 << 17);
    assert_eq!(
        u(&three["meshes"]),
        report.patches.len() as u64,
        "the ground"
    );
    let meshes = three["instanced"].as_array().unwrap();
    let mirrored: u64 = meshes
        .iter()
        .filter(|m| m["name"].as_str().unwrap().ends_with("mirrored"))
        .map(|m| u(&m["count"]))
        .sum();
    assert_eq!(mirrored, trees.mirrored);
    for m in meshes {
        assert_eq!(u(&m["trianglesPerInstance"]), trees.prototype_triangles);
        assert_eq!(u(&m["negativeDeterminant"]), 0, "{m}");
    }
    // The report counts each written mesh once: both prototype copies and the ground.
    let ground = report.triangles - 2 * trees.prototype_triangles;
    let full = trees.prototype_triangles * trees.instances + ground;
    assert_eq!(u(&three["trianglesPerFrame"]), full);

    // With the MSFT_lod plugin: one CellLOD per cell node, the export's levels (the impostor
    // last), every instance drawn at exactly one level, and far fewer triangles.
    let lod = &three["lod"];
    assert_eq!(lod["camera"], "file");
    assert_eq!(u(&lod["lods"]), u64::from(trees.cell_nodes));
    let per_level: Vec<u64> = lod["trianglesPerLevel"]
        .as_array()
        .unwrap()
        .iter()
        .map(u)
        .collect();
    assert_eq!(per_level, levels.triangles);
    let drawn: Vec<u64> = lod["instancesPerLevel"]
        .as_array()
        .unwrap()
        .iter()
        .map(u)
        .collect();
    assert_eq!(drawn.iter().sum::<u64>(), trees.instances, "{drawn:?}");
    assert!(
        drawn.last().unwrap() * 2 > trees.instances,
        "most trees are far: the impostor: {drawn:?}"
    );
    assert!(
        drawn[..drawn.len() - 1].iter().sum::<u64>() > 0,
        "near trees are meshes: {drawn:?}"
    );
    let with_lod = u(&lod["trianglesPerFrame"]);
    let expected: u64 = drawn
        .iter()
        .zip(&per_level)
        .map(|(n, t)| n * t)
        .sum::<u64>()
        + ground;
    assert_eq!(with_lod, expected);
    assert!(
        with_lod * 1000 < full,
        "{with_lod} triangles with levels of detail against {full} without"
    );
    assert!(u(&lod["visibleTrianglesPerFrame"]) <= with_lod);
}

/// One sphere and its mirror image: a KRS object whose one mirror has an empty kernel, so it
/// exports as a prototype drawn twice, once reflected.
fn mirrored_pair() -> Document {
    let material = Material::new(Vec3::new(0.6, 0.4, 0.2), 1);
    let object = KrsObject {
        name: "pair".to_owned(),
        kernels: vec![
            Kernel::Sphere(SphereKernel {
                centre: Vec3::new(0.4, 0.5, -0.2),
                radius: 0.8,
                material,
            }),
            Kernel::Empty,
        ],
        mirrors: vec![MirrorPlane::new(Vec3::new(1.0, 0.2, 0.1), 2.0)],
        ..KrsObject::default()
    };
    let mut doc = Document::default();
    let id = doc.add("Pair", ObjectKind::Krs(object));
    let o = doc.objects.iter_mut().find(|o| o.id == id).unwrap();
    o.transform = Transform {
        translation: Vec3::new(1.0, 2.0, -3.0),
        rotation: Quat::from_rotation_y(0.6) * Quat::from_rotation_x(0.3),
        scale: Vec3::splat(1.5),
    };
    doc
}

/// three.js's InstancedMesh keeps the winding of the object for every instance: a mirroring
/// instance matrix would turn its faces inside out (back faces outward, culled, lit from the
/// inside). The export draws mirrored placements with a reflected, re-wound prototype and a
/// proper transform, so both spheres show their outside; a naive file with the mirror in the
/// instance matrix shows, in the same check, every face of the mirrored sphere inside out.
#[test]
fn threejs_draws_mirrored_instances_with_outward_faces() {
    let dir = tempfile::tempdir().unwrap();
    let doc = mirrored_pair();
    let out = dir.path().join("pair.glb");
    // 48 cells across the sphere: thousands of triangles, checked in a second.
    let options = GltfExportOptions {
        resolution: 48,
        ..GltfExportOptions::default()
    };
    let report = export_gltf(&doc, &out, &options, &|_| true).unwrap_or_else(|e| panic!("{e}"));
    let [pair] = &report.instanced[..] else {
        panic!("instanced: {report:?}");
    };
    assert_eq!((pair.instances, pair.mirrored), (2, 1));
    let three = inspect(&out, true);
    println!("{three}");
    assert_eq!(u(&three["instances"]), 2);
    let meshes = three["instanced"].as_array().unwrap();
    assert_eq!(meshes.len(), 2, "the sphere and its mirrored copy");
    for m in meshes {
        assert_eq!(u(&m["negativeDeterminant"]), 0, "{m}");
        let proper = &m["faces"]["positive"];
        assert_eq!(u(&proper["instances"]), 1, "{m}");
        assert!(u(&proper["triangles"]) > 1000, "{m}");
        assert_eq!(u(&proper["inwardFaces"]), 0, "{m}");
        assert_eq!(u(&proper["shadingDisagrees"]), 0, "{m}");
    }

    // The same placements with the mirror left in the second instance's matrix (its scale's x
    // negated, drawing the unreflected mesh: the same points in the world).
    let world = doc.objects[0].krs_in_world().unwrap();
    let prepared = KrsScene {
        objects: vec![world],
    }
    .prepare()
    .unwrap();
    let mut scene = ExportScene::default();
    add_krs_object(&mut scene, "pair", &prepared.objects[0], &options, &|_| {
        true
    })
    .unwrap();
    let [plain, mirrored] = &scene.nodes[..] else {
        panic!("two nodes");
    };
    let mut mirroring = mirrored.instances[0];
    mirroring.scale.x = -mirroring.scale.x;
    let naive = ExportScene {
        nodes: vec![ExportNode {
            name: "naive".to_owned(),
            primitives: plain.primitives.clone(),
            instances: vec![plain.instances[0], mirroring],
            ..ExportNode::default()
        }],
        materials: scene.materials.clone(),
        ..ExportScene::default()
    };
    let naive_path = dir.path().join("naive.glb");
    std::fs::write(&naive_path, encode_glb(&naive, &naive_path).unwrap()).unwrap();
    let three = inspect(&naive_path, true);
    let [m] = &three["instanced"].as_array().unwrap()[..] else {
        panic!("one instanced mesh: {three}");
    };
    assert_eq!(u(&m["negativeDeterminant"]), 1, "{m}");
    let flipped = &m["faces"]["negative"];
    let tris = u(&flipped["triangles"]);
    assert!(tris > 1000, "{m}");
    assert_eq!(u(&flipped["inwardFaces"]), tris, "inside out: {m}");
    assert_eq!(
        u(&flipped["shadingDisagrees"]),
        tris,
        "lit from inside: {m}"
    );
    assert_eq!(u(&m["faces"]["positive"]["inwardFaces"]), 0, "{m}");
}

/// The critter sample (a voxel character rigged in Thicket: its own skeleton, geodesic weights
/// and a keyed walk) exported as a skinned glTF: three.js reads every joint by name, the same
/// joint indices and weights per vertex as the file holds, and the clip's exact duration.
#[test]
fn threejs_reads_a_native_rigs_joints_weights_and_clip_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let doc = project::load(&thicket_tests::repo_root().join("projects/critter.thicket.json"))
        .unwrap_or_else(|e| panic!("{e}"));
    let out = dir.path().join("critter.glb");
    export_gltf(&doc, &out, &GltfExportOptions::default(), &|_| true)
        .unwrap_or_else(|e| panic!("{e}"));
    // What the file holds, read with the gltf crate.
    let (gltf, buffers, _) = gltf::import(&out).unwrap();
    let skin = gltf.skins().next().expect("a skin");
    let names: Vec<String> = skin
        .joints()
        .map(|n| n.name().unwrap_or_default().to_owned())
        .collect();
    let ObjectKind::Voxels(v) = &doc.objects[0].kind else {
        panic!("the critter is a voxel model");
    };
    let rig = v.rig.as_ref().unwrap();
    let expected: Vec<String> = rig.skeleton.joints.iter().map(|j| j.name.clone()).collect();
    assert_eq!(names, expected, "every joint, in order, by name");
    let (mut vertices, mut joint_sum, mut weight_sum) = (0u64, 0u64, 0f64);
    for mesh in gltf.meshes() {
        for prim in mesh.primitives() {
            let reader = prim.reader(|b| Some(&buffers[b.index()]));
            let Some(joints) = reader.read_joints(0) else {
                continue;
            };
            for j in joints.into_u16() {
                vertices += 1;
                joint_sum += j.iter().map(|&k| u64::from(k)).sum::<u64>();
            }
            for w in reader.read_weights(0).unwrap().into_f32() {
                weight_sum += w.iter().map(|&x| f64::from(x)).sum::<f64>();
            }
        }
    }
    let durations: Vec<(String, f64)> = gltf
        .animations()
        .map(|a| {
            let end = a
                .channels()
                .map(|c| {
                    let r = c.reader(|b| Some(&buffers[b.index()]));
                    r.read_inputs().unwrap().fold(0f32, f32::max)
                })
                .fold(0f32, f32::max);
            (a.name().unwrap_or_default().to_owned(), f64::from(end))
        })
        .collect();
    assert_eq!(
        durations,
        [("walk".to_owned(), 1.0), ("Critter motion".to_owned(), 1.0)]
    );

    let three = inspect(&out, false);
    let [skinned] = three["skinned"].as_array().unwrap().as_slice() else {
        panic!("one skinned mesh: {}", three["skinned"]);
    };
    let bones: Vec<String> = skinned["bones"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b.as_str().unwrap().to_owned())
        .collect();
    // three.js names nodes through PropertyBinding.sanitizeNodeName (whitespace to '_', the
    // reserved '[', ']', '.', ':' and '/' removed), as it does for Blender's "leg.L" files: the
    // tracks are named the same way, so the clip still drives them.
    let sanitized: Vec<String> = expected
        .iter()
        .map(|n| {
            n.chars()
                .filter(|c| !"[].:/".contains(*c))
                .map(|c| if c.is_whitespace() { '_' } else { c })
                .collect()
        })
        .collect();
    assert_eq!(bones, sanitized);
    assert_eq!(u(&skinned["vertices"]), vertices);
    assert_eq!(u(&skinned["jointIndexSum"]), joint_sum);
    let w = skinned["weightSum"].as_f64().unwrap();
    assert!(
        (w - weight_sum).abs() <= 1e-6 * weight_sum,
        "three.js weights {w} vs the file's {weight_sum}"
    );
    assert!(
        (weight_sum - vertices as f64).abs() < 1e-2 * vertices as f64,
        "weights sum to 1"
    );
    let [clip, motion] = three["animations"].as_array().unwrap().as_slice() else {
        panic!("a clip and the object's motion: {}", three["animations"]);
    };
    assert_eq!(clip["name"], "walk");
    assert_eq!(clip["duration"].as_f64().unwrap(), 1.0);
    assert!(u(&clip["tracks"]) >= 9, "{clip}");
    // The keyed object transform, played by three.js on the skeleton's root node: about Y
    // only, facing front at 0, 0.5 and 1 s, turned +8° at 0.25 s and -8° at 0.75 s.
    assert_eq!(motion["name"], "Critter motion");
    assert_eq!(motion["duration"].as_f64().unwrap(), 1.0);
    let rotation = motion["sampled"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["name"].as_str().unwrap().ends_with(".quaternion"))
        .unwrap_or_else(|| panic!("a rotation track: {motion}"));
    let q = |k: usize| -> Vec<f64> {
        rotation["values"][k]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    for (k, deg) in [(0, 0.0f64), (1, 8.0), (2, 0.0), (3, -8.0), (4, 0.0)] {
        let v = q(k);
        let half = (deg / 2.0).to_radians();
        assert!(
            v[0].abs() < 1e-6 && v[2].abs() < 1e-6,
            "about Y only: {v:?}"
        );
        assert!(
            (v[1] - half.sin()).abs() < 1e-5 && (v[3] - half.cos()).abs() < 1e-5,
            "{deg}° at {k}/4 s: {v:?}"
        );
    }
}

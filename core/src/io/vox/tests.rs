use std::collections::{BTreeMap, HashMap};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{Quat, UVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use super::chunks::{write_chunk, write_dict};
use super::import::world_cells;
use super::*;
use crate::scene::{Object, ObjectKind, Transform, VoxelModel};
use crate::svo::{Svo, Voxel, decode_normal};

fn asset(rel: &str) -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/vox/"
    ))
    .join(rel)
}

const HOUSE: &str = "mmmm/obj_house4.vox";
const ARMY: &str = "mmmm/chr_army1.vox";
const SCENE: &str = "opengametools/test_multiple_model_scene.vox";
const PLACEHOLDER: &str = "dot_vox/placeholder.vox";
const AXES: &str = "dot_vox/axes.vox";
const METAL: &str = "dot_vox/metal-material.vox";
const NOT_VOX: &str = "dot_vox/not_a.vox";

/// Every voxel of every visible object in Y-up world cells, sorted.
fn world_set(objects: &[Object]) -> Vec<([i64; 3], [u8; 4])> {
    let mut out: Vec<([i64; 3], [u8; 4])> = objects
        .iter()
        .flat_map(|o| world_cells(o).into_iter().map(|(c, v)| (c, v.color)))
        .collect();
    out.sort_unstable();
    out
}

fn voxels_of(o: &Object) -> &VoxelModel {
    match &o.kind {
        ObjectKind::Voxels(v) => v,
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => panic!("{} is not a voxel object", o.name),
    }
}

#[test]
fn exact_counts_on_real_files() {
    let house = import_vox(&asset(HOUSE)).unwrap();
    assert_eq!(house.voxel_count(), 180_202);
    assert_eq!(house.stored_voxels, 180_202);
    assert_eq!(house.objects.len(), 1);
    let army = import_vox(&asset(ARMY)).unwrap();
    assert_eq!(army.voxel_count(), 341);
    let path = asset(SCENE);
    let scene = import_vox(&path).unwrap();
    assert_eq!(scene.model_count, 41);
    assert_eq!(scene.stored_voxels, 6_053);
    // The scene graph places those 41 models 104 times; count the instances independently.
    let raw = dot_vox::load(path.to_str().unwrap()).unwrap();
    let dot_vox::SceneNode::Group { children, .. } = &raw.scenes[1] else {
        panic!("node 1 is not the top group")
    };
    let mut placed = 0u64;
    for &c in children {
        let dot_vox::SceneNode::Transform { child, .. } = &raw.scenes[c as usize] else {
            panic!("group child {c} is not a transform")
        };
        let dot_vox::SceneNode::Shape { models, .. } = &raw.scenes[*child as usize] else {
            panic!("transform {c} does not hold a shape")
        };
        placed += raw.models[models[0].model_id as usize].voxels.len() as u64;
    }
    assert_eq!(scene.objects.len(), children.len());
    assert_eq!(scene.objects.len(), 104);
    assert_eq!(scene.voxel_count(), placed);
    let placeholder = import_vox(&asset(PLACEHOLDER)).unwrap();
    assert_eq!(placeholder.voxel_count(), 4);
}

#[test]
fn legacy_files_place_one_object_per_model_at_the_origin() {
    // chr_army1 has no scene graph: voxel (x, y, z) must land on Y-up cell (x, z, -y - 1).
    let path = asset(ARMY);
    let raw = dot_vox::load(path.to_str().unwrap()).unwrap();
    assert!(raw.scenes.is_empty());
    let scene = import_vox(&path).unwrap();
    assert_eq!(scene.objects.len(), 1);
    assert_eq!(scene.objects[0].transform, Transform::default());
    let mut expected: Vec<([i64; 3], [u8; 4])> = raw.models[0]
        .voxels
        .iter()
        .map(|v| {
            let c = raw.palette[usize::from(v.i)];
            (
                [i64::from(v.x), i64::from(v.z), -i64::from(v.y) - 1],
                [c.r, c.g, c.b, c.a],
            )
        })
        .collect();
    expected.sort_unstable();
    assert_eq!(world_set(&scene.objects), expected);
}

/// Reads `_t` of the transform above each shape straight from dot_vox's node list (an
/// independent walk: root nTRN → nGRP → nTRN → nSHP, which is this file's layout).
fn shape_translations(raw: &dot_vox::DotVoxData) -> Vec<(u32, [i64; 3])> {
    use dot_vox::SceneNode;
    let mut out = Vec::new();
    let SceneNode::Transform { child, .. } = &raw.scenes[0] else {
        panic!("root is not a transform")
    };
    let SceneNode::Group { children, .. } = &raw.scenes[*child as usize] else {
        panic!("root's child is not a group")
    };
    for &c in children {
        let SceneNode::Transform { frames, child, .. } = &raw.scenes[c as usize] else {
            continue;
        };
        let SceneNode::Shape { models, .. } = &raw.scenes[*child as usize] else {
            continue;
        };
        let t = frames[0]
            .position()
            .map_or([0; 3], |p| [i64::from(p.x), i64::from(p.y), i64::from(p.z)]);
        let has_r = frames[0].attributes.contains_key("_r");
        if !has_r {
            out.push((models[0].model_id, t));
        }
    }
    out
}

#[test]
fn scene_objects_are_placed_by_their_transforms() {
    let path = asset(SCENE);
    let raw = dot_vox::load(path.to_str().unwrap()).unwrap();
    let scene = import_vox(&path).unwrap();
    let unrotated = shape_translations(&raw);
    assert!(unrotated.len() >= 2, "{unrotated:?}");
    let mut checked = 0;
    for (model_id, t) in unrotated.iter().take(4) {
        // The object's translation is the pivot: MagicaVoxel (x, y, z) → Y-up (x, z, -y).
        let want = Vec3::new(t[0] as f32, t[2] as f32, -t[1] as f32);
        let o = scene
            .objects
            .iter()
            .find(|o| o.transform.translation == want)
            .unwrap_or_else(|| panic!("no object at {want} for model {model_id}"));
        // And every voxel sits at pivot + (v - floor(size / 2)), converted to Y-up.
        let m = &raw.models[*model_id as usize];
        let p = [m.size.x / 2, m.size.y / 2, m.size.z / 2].map(i64::from);
        let mut expected: Vec<([i64; 3], [u8; 4])> = m
            .voxels
            .iter()
            .map(|v| {
                let mv = [
                    t[0] + i64::from(v.x) - p[0],
                    t[1] + i64::from(v.y) - p[1],
                    t[2] + i64::from(v.z) - p[2],
                ];
                let c = raw.palette[usize::from(v.i)];
                ([mv[0], mv[2], -mv[1] - 1], [c.r, c.g, c.b, c.a])
            })
            .collect();
        expected.sort_unstable();
        assert_eq!(
            world_set(std::slice::from_ref(o)),
            expected,
            "model {model_id}"
        );
        checked += 1;
    }
    assert!(checked >= 2);
}

#[test]
fn axes_scene_graph_instances_models_and_nests_groups() {
    let path = asset(AXES);
    let raw = dot_vox::load(path.to_str().unwrap()).unwrap();
    let scene = import_vox(&path).unwrap();
    let shapes = raw
        .scenes
        .iter()
        .filter(|n| matches!(n, dot_vox::SceneNode::Shape { .. }))
        .count();
    // Every shape node reachable from the root becomes one object; models are reused.
    assert_eq!(scene.objects.len(), shapes, "{}", scene.objects.len());
    assert!(scene.objects.len() > scene.model_count);
    let mut per_model: HashMap<u64, usize> = HashMap::new();
    for o in &scene.objects {
        *per_model.entry(voxels_of(o).svo.leaf_count()).or_default() += 1;
    }
    assert!(per_model.values().any(|&n| n >= 2), "{per_model:?}");
    // Instances share nothing: editing one leaves its twin unchanged.
    let mut objects = scene.objects.clone();
    let count = voxels_of(&objects[1]).svo.leaf_count();
    let twin = (0..objects.len())
        .find(|&k| {
            k != 0
                && voxels_of(&objects[k]).svo.leaf_count()
                    == voxels_of(&objects[0]).svo.leaf_count()
        })
        .unwrap_or(1);
    let before = voxels_of(&objects[twin]).svo.clone();
    if let ObjectKind::Voxels(v) = &mut objects[0].kind {
        let (c, _) = v.svo.leaves()[0];
        v.svo.remove(c).unwrap();
    }
    assert_eq!(voxels_of(&objects[twin]).svo, before);
    assert!(count > 0);
    // Instances of the same model are placed apart (group translations accumulate).
    let mut positions: Vec<[i64; 3]> = scene
        .objects
        .iter()
        .map(|o| o.transform.translation.to_array().map(|c| c as i64))
        .collect();
    positions.sort_unstable();
    positions.dedup();
    assert!(positions.len() > 1);
}

#[test]
fn metal_material_names_are_kept() {
    let path = asset(METAL);
    let scene = import_vox(&path).unwrap();
    assert_eq!(scene.material_names[0], "diffuse");
    let metal = scene
        .material_names
        .iter()
        .position(|n| n == "metal")
        .unwrap_or_else(|| panic!("{:?}", scene.material_names));
    let used: Vec<u8> = scene
        .objects
        .iter()
        .flat_map(|o| {
            voxels_of(o)
                .svo
                .leaves()
                .into_iter()
                .map(|(_, v)| v.material)
        })
        .collect();
    assert!(used.contains(&(metal as u8)), "{used:?}");
    // Cross-check with dot_vox: the voxel's palette index i uses MATL id i + 1.
    let raw = dot_vox::load(path.to_str().unwrap()).unwrap();
    let metal_voxels = raw.models[0]
        .voxels
        .iter()
        .filter(|v| {
            raw.materials
                .iter()
                .find(|m| m.id == u32::from(v.i) + 1)
                .and_then(dot_vox::Material::material_type)
                == Some("_metal")
        })
        .count();
    assert_eq!(
        used.iter().filter(|&&m| m == metal as u8).count(),
        metal_voxels
    );
    for o in &scene.objects {
        assert_eq!(voxels_of(o).material_names, scene.material_names);
    }
}

#[test]
fn rotation_bytes_match_dot_vox_and_are_signed_permutations() {
    let mut valid = 0;
    for byte in 0..=127u8 {
        let Some(m) = decode_rotation(byte) else {
            continue;
        };
        valid += 1;
        let cols = dot_vox::Rotation::from_byte(byte).to_cols_array_2d();
        for (r, row) in m.iter().enumerate() {
            for (c, &v) in row.iter().enumerate() {
                assert_eq!(v as f32, cols[c][r], "byte {byte} row {r} col {c}");
            }
            assert_eq!(row.iter().map(|v| v.abs()).sum::<i64>(), 1);
        }
    }
    assert_eq!(valid, 48);
    assert!(decode_rotation(0b0000).is_none() && decode_rotation(0b0011).is_none());
    assert_eq!(decode_rotation(4), Some(IDENTITY));
}

#[test]
fn axis_conversion_is_a_proper_rotation_and_round_trips_cells() {
    let x = yup_from_mv([1, 0, 0]);
    let y = yup_from_mv([0, 1, 0]);
    let z = yup_from_mv([0, 0, 1]);
    assert_eq!(z, [0, 1, 0], "MagicaVoxel up becomes +Y");
    // det = x · (y × z) = +1: no mirror.
    let cross = [
        y[1] * z[2] - y[2] * z[1],
        y[2] * z[0] - y[0] * z[2],
        y[0] * z[1] - y[1] * z[0],
    ];
    assert_eq!(x[0] * cross[0] + x[1] * cross[1] + x[2] * cross[2], 1);
    for c in [[0, 0, 0], [255, -3, 7], [-(1 << 24), 1 << 24, 5]] {
        assert_eq!(mv_cell_from_yup(yup_cell_from_mv(c)), c);
    }
}

/// A model object with the given voxels at the origin.
fn object(name: &str, voxels: Vec<(UVec3, Voxel)>, depth: u8) -> Object {
    Object {
        name: name.into(),
        kind: ObjectKind::Voxels(VoxelModel {
            svo: Svo::from_voxels(depth, false, voxels).unwrap(),
            ..VoxelModel::default()
        }),
        ..Object::default()
    }
}

fn solid(color: [u8; 4]) -> Voxel {
    Voxel {
        color,
        ..Voxel::default()
    }
}

#[test]
fn normals_point_out_of_the_surface_and_interior_is_up() {
    let cube: Vec<(UVec3, Voxel)> = (0..27)
        .map(|i| {
            (
                UVec3::new(i % 3, (i / 3) % 3, i / 9),
                solid([200, 10, 10, 255]),
            )
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.vox");
    export_vox(&[object("cube", cube, 2)], &path).unwrap();
    let back = import_vox(&path).unwrap();
    let cells = world_cells(&back.objects[0]);
    let lo = cells
        .iter()
        .fold([i64::MAX; 3], |m, (c, _)| [0, 1, 2].map(|a| m[a].min(c[a])));
    for (c, v) in &cells {
        let rel = [0, 1, 2].map(|a| c[a] - lo[a] - 1);
        let n = decode_normal(v.normal);
        let want = if rel == [0; 3] {
            Vec3::Y
        } else {
            Vec3::new(rel[0] as f32, rel[1] as f32, rel[2] as f32).normalize_or_zero()
        };
        assert!(n.dot(want) > 0.999, "cell {rel:?}: normal {n}, want {want}");
    }
}

fn round_trip(rel: &str) {
    let path = asset(rel);
    let first = import_vox(&path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rt.vox");
    let report = export_vox(&first.objects, &out).unwrap();
    assert!(report.exact_colors, "{report:?}");
    let second = import_vox(&out).unwrap();
    let visible: Vec<Object> = first
        .objects
        .iter()
        .filter(|o| o.visible)
        .cloned()
        .collect();
    let (a, b) = (world_set(&visible), world_set(&second.objects));
    assert_eq!(a.len(), b.len(), "{rel}");
    assert!(a == b, "{rel}: positions or colours changed");
    // Materials survive by name.
    let names = |s: &VoxScene| -> BTreeMap<[i64; 3], String> {
        s.objects
            .iter()
            .filter(|o| o.visible)
            .flat_map(|o| {
                let v = voxels_of(o);
                world_cells(o)
                    .into_iter()
                    .map(|(c, vox)| (c, v.material_names[usize::from(vox.material)].clone()))
            })
            .collect()
    };
    assert_eq!(names(&first), names(&second), "{rel}");
}

#[test]
fn round_trip_preserves_every_voxel_and_colour() {
    for rel in [ARMY, SCENE, AXES, METAL, PLACEHOLDER, HOUSE] {
        round_trip(rel);
    }
}

#[test]
fn models_larger_than_256_split_and_round_trip() {
    let voxels: Vec<(UVec3, Voxel)> = (0..300u32)
        .flat_map(|x| {
            (0..10u32).flat_map(move |y| {
                (0..10u32).map(move |z| {
                    // 7 × 10 × 2 = 140 colours: the palette stays exact.
                    let c = [(x % 7 * 30) as u8, (y * 20) as u8, (z % 2 * 99) as u8, 255];
                    (UVec3::new(x, y, z), solid(c))
                })
            })
        })
        .collect();
    let mut o = object("long", voxels, 9);
    o.transform.translation = Vec3::new(-7.0, 3.0, 12.0);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("long.vox");
    let report = export_vox(std::slice::from_ref(&o), &path).unwrap();
    assert_eq!(report.models, 2);
    assert_eq!(report.voxels, 30_000);
    assert!(report.exact_colors);
    let back = import_vox(&path).unwrap();
    assert_eq!(back.objects.len(), 2);
    for b in &back.objects {
        let (lo, hi) = voxels_of(b).svo.bounds().unwrap();
        assert!((hi - lo).max_element() < 256);
    }
    assert_eq!(world_set(&back.objects), world_set(&[o]));
}

#[test]
fn rotated_and_scaled_objects_export_on_the_grid() {
    // A quarter turn about Y maps the grid onto itself; a 2× scale fills 8 cells per voxel.
    let voxels = vec![
        (UVec3::new(0, 0, 0), solid([1, 2, 3, 255])),
        (UVec3::new(1, 0, 0), solid([4, 5, 6, 255])),
    ];
    let mut turned = object("turned", voxels.clone(), 1);
    turned.transform.rotation = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
    let back = bytes_round_trip(&[turned]);
    let cells: Vec<[i64; 3]> = back.iter().map(|e| e.0).collect();
    // x → -z under +90° about Y: cells [0,1)→(-1,0] and [1,2)→(-2,-1] along z.
    assert_eq!(cells, vec![[0, 0, -2], [0, 0, -1]]);
    let mut big = object("big", voxels, 1);
    big.transform.scale = Vec3::splat(2.0);
    let (_, report) = export_vox_bytes(
        &[big],
        Path::new("big.vox"),
        &VoxExportOptions {
            grid_unit: Some(1.0),
            ..VoxExportOptions::default()
        },
    )
    .unwrap();
    assert_eq!(report.voxels, 16);
}

fn bytes_round_trip(objects: &[Object]) -> Vec<([i64; 3], [u8; 4])> {
    let (bytes, _) =
        export_vox_bytes(objects, Path::new("mem.vox"), &VoxExportOptions::default()).unwrap();
    let scene =
        import_vox_bytes(&bytes, Path::new("mem.vox"), &VoxImportOptions::default()).unwrap();
    world_set(&scene.objects)
}

#[test]
fn more_than_255_colours_are_quantised_deterministically() {
    let voxels: Vec<(UVec3, Voxel)> = (0..4096u32)
        .map(|i| {
            let c = [
                (i % 16 * 17) as u8,
                (i / 16 % 16 * 17) as u8,
                (i / 256 * 17) as u8,
                255,
            ];
            (UVec3::new(i % 16, i / 16 % 16, i / 256), solid(c))
        })
        .collect();
    let o = object("rainbow", voxels, 4);
    let opts = VoxExportOptions::default();
    let (a, report) =
        export_vox_bytes(std::slice::from_ref(&o), Path::new("q.vox"), &opts).unwrap();
    let (b, _) = export_vox_bytes(std::slice::from_ref(&o), Path::new("q.vox"), &opts).unwrap();
    assert_eq!(a, b, "export is deterministic");
    assert!(!report.exact_colors);
    assert_eq!(report.distinct_colors, 4096);
    assert_eq!(report.palette_colors, 255);
    // 16 levels per channel into 255 boxes ≈ 6.3 levels per channel: error well under 64.
    assert!(report.max_channel_error <= 40, "{report:?}");
    let back = import_vox_bytes(&a, Path::new("q.vox"), &VoxImportOptions::default()).unwrap();
    let orig = world_set(&[o]);
    let got = world_set(&back.objects);
    assert_eq!(orig.len(), got.len());
    for (x, y) in orig.iter().zip(&got) {
        assert_eq!(x.0, y.0);
        let err = (0..4).map(|c| x.1[c].abs_diff(y.1[c])).max().unwrap_or(0);
        assert!(err <= report.max_channel_error);
    }
    // Exactly 255 colours stay exact.
    let voxels: Vec<(UVec3, Voxel)> = (0..255u32)
        .map(|i| {
            (
                UVec3::new(i % 16, i / 16, 0),
                solid([i as u8, 0, 255 - i as u8, 255]),
            )
        })
        .collect();
    let (_, report) =
        export_vox_bytes(&[object("p", voxels, 4)], Path::new("p.vox"), &opts).unwrap();
    assert!(report.exact_colors && report.palette_colors == 255);
}

fn read(rel: &str) -> Vec<u8> {
    std::fs::read(asset(rel)).unwrap()
}

fn err_text(bytes: &[u8], name: &str) -> String {
    import_vox_bytes(bytes, Path::new(name), &VoxImportOptions::default())
        .unwrap_err()
        .to_string()
}

#[test]
fn not_a_vox_and_empty_files_give_clear_errors() {
    let path = asset(NOT_VOX);
    let e = import_vox(&path).unwrap_err();
    assert!(matches!(e, VoxError::NotVox { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("not_a.vox") && msg.contains("not a MagicaVoxel file"),
        "{msg}"
    );
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.vox");
    std::fs::write(&empty, b"").unwrap();
    let msg = import_vox(&empty).unwrap_err().to_string();
    assert!(msg.contains("empty.vox") && msg.contains("empty"), "{msg}");
    let missing = dir.path().join("missing.vox");
    let msg = import_vox(&missing).unwrap_err().to_string();
    assert!(
        msg.contains("missing.vox") && msg.contains("reading"),
        "{msg}"
    );
}

#[test]
fn every_truncation_of_a_small_file_is_an_error_naming_the_file() {
    let bytes = read(ARMY);
    for len in 0..bytes.len() {
        let msg = err_text(&bytes[..len], "army.vox");
        assert!(msg.starts_with("army.vox: "), "prefix {len}: {msg}");
    }
    assert!(import_vox_bytes(&bytes, Path::new("army.vox"), &VoxImportOptions::default()).is_ok());
    // The larger files: every prefix up to 64 bytes, then every 61st (cut chunks of all kinds).
    for rel in [PLACEHOLDER, METAL, AXES, SCENE] {
        let bytes = read(rel);
        for len in (0..64).chain((64..bytes.len()).step_by(61)) {
            let msg = err_text(&bytes[..len], rel);
            assert!(msg.starts_with(rel), "{rel} prefix {len}: {msg}");
        }
    }
}

/// Byte offset of the first chunk with this id inside MAIN.
fn chunk_offset(bytes: &[u8], id: &[u8; 4]) -> usize {
    let mut pos = 20;
    loop {
        if &bytes[pos..pos + 4] == id {
            return pos;
        }
        let n = u32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize;
        let m = u32::from_le_bytes(bytes[pos + 8..pos + 12].try_into().unwrap()) as usize;
        pos += 12 + n + m;
    }
}

#[test]
fn inflated_counts_are_refused_with_where_and_what() {
    let bytes = read(ARMY);
    let xyzi = chunk_offset(&bytes, b"XYZI");
    let mut b = bytes.clone();
    b[xyzi + 12..xyzi + 16].copy_from_slice(&1_000_000u32.to_le_bytes());
    let msg = err_text(&b, "army.vox");
    assert!(
        msg.contains("chunk XYZI of model 0") && msg.contains("declares 1000000 voxels"),
        "{msg}"
    );
    let size = chunk_offset(&bytes, b"SIZE");
    let mut b = bytes.clone();
    b[size + 12..size + 16].copy_from_slice(&1000u32.to_le_bytes());
    let msg = err_text(&b, "army.vox");
    assert!(
        msg.contains("chunk SIZE of model 0") && msg.contains("1000 ×"),
        "{msg}"
    );
    // A smaller SIZE than the voxels need.
    let mut b = bytes.clone();
    b[size + 12..size + 16].copy_from_slice(&1u32.to_le_bytes());
    let msg = err_text(&b, "army.vox");
    assert!(msg.contains("lies outside the model's size"), "{msg}");
    // Chunk and MAIN sizes beyond the file.
    let mut b = bytes.clone();
    b[xyzi + 4..xyzi + 8].copy_from_slice(&u32::MAX.to_le_bytes());
    let msg = err_text(&b, "army.vox");
    assert!(
        msg.contains("truncated or inflated") && msg.contains("XYZI"),
        "{msg}"
    );
    let mut b = bytes.clone();
    b[16..20].copy_from_slice(&u32::MAX.to_le_bytes());
    let msg = err_text(&b, "army.vox");
    assert!(
        msg.contains("MAIN") && msg.contains("truncated or inflated"),
        "{msg}"
    );
    // A voxel budget smaller than the file.
    let e = import_vox_bytes(
        &bytes,
        Path::new("army.vox"),
        &VoxImportOptions {
            max_voxels: 100,
            ..VoxImportOptions::default()
        },
    )
    .unwrap_err();
    assert!(matches!(e, VoxError::TooLarge { .. }), "{e}");
}

/// A hand-built file: one 2³ model and the given scene chunks.
fn file_with_scene(scene: &[u8]) -> Vec<u8> {
    let mut main = Vec::new();
    let mut size = Vec::new();
    for s in [2u32, 2, 2] {
        size.extend_from_slice(&s.to_le_bytes());
    }
    write_chunk(&mut main, b"SIZE", &size);
    let mut xyzi = 2u32.to_le_bytes().to_vec();
    xyzi.extend_from_slice(&[0, 0, 0, 1, 1, 1, 1, 2]);
    write_chunk(&mut main, b"XYZI", &xyzi);
    main.extend_from_slice(scene);
    let mut out = b"VOX ".to_vec();
    out.extend_from_slice(&150u32.to_le_bytes());
    out.extend_from_slice(b"MAIN");
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(main.len() as u32).to_le_bytes());
    out.extend_from_slice(&main);
    out
}

fn transform_chunk(out: &mut Vec<u8>, id: u32, child: u32, attrs: &[(&str, &str)]) {
    let mut c = id.to_le_bytes().to_vec();
    write_dict(&mut c, &[]);
    c.extend_from_slice(&child.to_le_bytes());
    c.extend_from_slice(&u32::MAX.to_le_bytes());
    c.extend_from_slice(&0u32.to_le_bytes());
    c.extend_from_slice(&1u32.to_le_bytes());
    write_dict(&mut c, attrs);
    write_chunk(out, b"nTRN", &c);
}

fn group_chunk(out: &mut Vec<u8>, id: u32, children: &[u32]) {
    let mut c = id.to_le_bytes().to_vec();
    write_dict(&mut c, &[]);
    c.extend_from_slice(&(children.len() as u32).to_le_bytes());
    for ch in children {
        c.extend_from_slice(&ch.to_le_bytes());
    }
    write_chunk(out, b"nGRP", &c);
}

fn shape_chunk(out: &mut Vec<u8>, id: u32, model: u32) {
    let mut c = id.to_le_bytes().to_vec();
    write_dict(&mut c, &[]);
    c.extend_from_slice(&1u32.to_le_bytes());
    c.extend_from_slice(&model.to_le_bytes());
    write_dict(&mut c, &[]);
    write_chunk(out, b"nSHP", &c);
}

#[test]
fn rotated_instances_are_baked_exactly() {
    // _r = 0b0010001: row 0 takes +y, row 1 takes -... decode and compare by hand.
    let mut s = Vec::new();
    transform_chunk(&mut s, 0, 1, &[]);
    group_chunk(&mut s, 1, &[2, 4]);
    transform_chunk(&mut s, 2, 3, &[("_t", "10 0 0")]);
    shape_chunk(&mut s, 3, 0);
    // 90° about Z: x' = -y, y' = x (rows: [0,-1,0],[1,0,0],[0,0,1]) = columns 1,0 with row 0
    // negative: byte = 1 | (0 << 2) | (1 << 4).
    let r = 1 | (1 << 4);
    let rs = r.to_string();
    transform_chunk(&mut s, 4, 5, &[("_t", "-10 0 0"), ("_r", &rs)]);
    shape_chunk(&mut s, 5, 0);
    let bytes = file_with_scene(&s);
    let scene =
        import_vox_bytes(&bytes, Path::new("rot.vox"), &VoxImportOptions::default()).unwrap();
    assert_eq!(scene.objects.len(), 2);
    // Unrotated: pivot (1,1,1); voxel (0,0,0) → MV cell (9,-1,-1); (1,1,1) → (10,0,0).
    let a = world_set(&scene.objects[..1]);
    let to_yup = |m: [i64; 3]| yup_cell_from_mv(m);
    let mut want_a = vec![to_yup([9, -1, -1]), to_yup([10, 0, 0])];
    want_a.sort_unstable();
    assert_eq!(a.iter().map(|e| e.0).collect::<Vec<_>>(), want_a);
    // Rotated: centre offset (v + ½ − 1) = (−½,−½,−½) → (½,−½,−½) → min cell (−10,−1,−1);
    // (½,½,½) → (−½,½,½) → (−11,0,0).
    let b = world_set(&scene.objects[1..]);
    let mut want_b = vec![to_yup([-10, -1, -1]), to_yup([-11, 0, 0])];
    want_b.sort_unstable();
    assert_eq!(b.iter().map(|e| e.0).collect::<Vec<_>>(), want_b);
    assert_eq!(
        scene.objects[1].transform.translation,
        Vec3::new(-10.0, 0.0, 0.0)
    );
}

#[test]
fn broken_scene_graphs_are_errors() {
    // A group that contains itself.
    let mut s = Vec::new();
    transform_chunk(&mut s, 0, 1, &[]);
    group_chunk(&mut s, 1, &[1]);
    let msg = err_text(&file_with_scene(&s), "cycle.vox");
    assert!(
        msg.contains("cycle.vox") && msg.contains("deeper than"),
        "{msg}"
    );
    // A child that does not exist.
    let mut s = Vec::new();
    transform_chunk(&mut s, 0, 7, &[]);
    let msg = err_text(&file_with_scene(&s), "dangling.vox");
    assert!(msg.contains("node 7, which does not exist"), "{msg}");
    // A shape using a model that does not exist.
    let mut s = Vec::new();
    transform_chunk(&mut s, 0, 1, &[]);
    shape_chunk(&mut s, 1, 3);
    let msg = err_text(&file_with_scene(&s), "model.vox");
    assert!(msg.contains("uses model 3"), "{msg}");
    // A rotation byte dot_vox would panic on, and a bad translation.
    for (key, value, want) in [
        ("_r", "15", "not a signed permutation"),
        ("_t", "1 x 2", "not three integers"),
    ] {
        let mut s = Vec::new();
        transform_chunk(&mut s, 0, 1, &[(key, value)]);
        shape_chunk(&mut s, 1, 0);
        let msg = err_text(&file_with_scene(&s), "attr.vox");
        assert!(msg.contains(want), "{msg}");
    }
    // A binary tree of groups 40 deep would place 2^40 instances: refused, not attempted.
    let mut s = Vec::new();
    transform_chunk(&mut s, 0, 100, &[]);
    for level in 0..40u32 {
        group_chunk(&mut s, 100 + level, &[100 + level + 1, 100 + level + 1]);
    }
    group_chunk(&mut s, 140, &[141]);
    shape_chunk(&mut s, 141, 0);
    let e = import_vox_bytes(
        &file_with_scene(&s),
        Path::new("bomb.vox"),
        &VoxImportOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, VoxError::TooLarge { .. }), "{e}");
    // A duplicate node id.
    let mut s = Vec::new();
    transform_chunk(&mut s, 0, 1, &[]);
    shape_chunk(&mut s, 0, 0);
    let msg = err_text(&file_with_scene(&s), "dup.vox");
    assert!(msg.contains("used twice"), "{msg}");
}

#[test]
fn deeply_nested_chunks_are_refused_without_recursing() {
    // 20,000 unknown chunks each holding the next: dot_vox would recurse once per level.
    let levels = 20_000usize;
    let mut inner: Vec<u8> = Vec::with_capacity(levels * 12);
    for k in 0..levels {
        inner.extend_from_slice(b"ABCD");
        inner.extend_from_slice(&0u32.to_le_bytes());
        inner.extend_from_slice(&(((levels - k - 1) * 12) as u32).to_le_bytes());
    }
    let msg = err_text(&file_with_scene(&inner), "deep.vox");
    assert!(
        msg.contains("deep.vox") && msg.contains("nested more than"),
        "{msg}"
    );
    // A little nesting (as some tools write) is accepted.
    let mut two = b"ABCD".to_vec();
    two.extend_from_slice(&0u32.to_le_bytes());
    two.extend_from_slice(&12u32.to_le_bytes());
    two.extend_from_slice(b"EFGH");
    two.extend_from_slice(&[0; 8]);
    let ok = import_vox_bytes(
        &file_with_scene(&two),
        Path::new("two.vox"),
        &VoxImportOptions::default(),
    )
    .unwrap();
    assert_eq!(ok.voxel_count(), 2);
}

#[test]
fn failed_exports_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("out.vox");
    let listing = || {
        let mut v: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    // Nothing to export.
    let e = export_vox(&[], &target).unwrap_err();
    assert!(matches!(e, VoxError::NothingToExport { .. }) && e.to_string().contains("out.vox"));
    assert!(listing().is_empty());
    // A NaN transform: error naming the object; an existing file is left as it was.
    std::fs::write(&target, b"old").unwrap();
    let mut bad = object("Bad", vec![(UVec3::ZERO, solid([1, 1, 1, 255]))], 1);
    bad.transform.translation.x = f32::NAN;
    let msg = export_vox(&[bad], &target).unwrap_err().to_string();
    assert!(
        msg.contains("out.vox") && msg.contains("Bad") && msg.contains("translation"),
        "{msg}"
    );
    assert_eq!(std::fs::read(&target).unwrap(), b"old");
    // A budget overflow from a huge scale.
    let mut huge = object("Huge", vec![(UVec3::ZERO, solid([1, 1, 1, 255]))], 1);
    huge.transform.scale = Vec3::splat(1000.0);
    let e = export_vox_with(
        &[huge],
        &target,
        &VoxExportOptions {
            grid_unit: Some(1.0),
            max_voxels: 1 << 20,
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("more than"), "{e}");
    assert_eq!(std::fs::read(&target).unwrap(), b"old");
    assert_eq!(listing(), vec!["out.vox".to_owned()]);
    // An unwritable directory: an I/O error, no temporary file left behind.
    let missing = dir.path().join("no/such/dir/out.vox");
    let ok = object("Ok", vec![(UVec3::ZERO, solid([1, 1, 1, 255]))], 1);
    let e = export_vox(std::slice::from_ref(&ok), &missing).unwrap_err();
    assert!(matches!(e, VoxError::Io { .. }), "{e}");
    assert_eq!(listing(), vec!["out.vox".to_owned()]);
    // And a good export replaces the file.
    export_vox(&[ok], &target).unwrap();
    assert_eq!(&std::fs::read(&target).unwrap()[..4], b"VOX ");
    assert_eq!(listing(), vec!["out.vox".to_owned()]);
}

#[test]
fn hidden_and_mesh_objects_are_skipped() {
    let mut hidden = object("hidden", vec![(UVec3::ZERO, solid([9, 9, 9, 255]))], 1);
    hidden.visible = false;
    let shown = object("shown", vec![(UVec3::ONE, solid([8, 8, 8, 255]))], 1);
    let mesh = Object {
        name: "mesh".into(),
        kind: ObjectKind::Mesh(crate::scene::MeshObject::default()),
        ..Object::default()
    };
    let (_, report) = export_vox_bytes(
        &[hidden, shown, mesh],
        Path::new("s.vox"),
        &VoxExportOptions::default(),
    )
    .unwrap();
    assert_eq!(report.voxels, 1);
    assert_eq!(report.skipped, vec!["hidden".to_owned(), "mesh".to_owned()]);
}

/// Offsets of every chunk header (and the MAIN header) in a valid file.
fn header_offsets(bytes: &[u8]) -> Vec<usize> {
    let mut out = vec![8];
    let mut pos = 20;
    while pos + 12 <= bytes.len() {
        out.push(pos);
        let n = u32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize;
        let m = u32::from_le_bytes(bytes[pos + 8..pos + 12].try_into().unwrap()) as usize;
        pos += 12 + n + m;
    }
    out
}

/// One mutation: byte flips, a truncation, an inflated u32 in a chunk header or at the start of
/// a chunk's content (where counts live), or several at once.
fn mutate(rng: &mut Pcg64, original: &[u8], headers: &[usize]) -> Vec<u8> {
    let mut b = original.to_vec();
    let inflate = |rng: &mut Pcg64, b: &mut Vec<u8>| {
        let h = headers[rng.random_range(0..headers.len())];
        // +4 content size, +8 children size, +12.. the first content words (counts, ids).
        let at = h + [4, 8, 12, 16, 20, 24][rng.random_range(0..6)];
        if at + 4 > b.len() {
            return;
        }
        let old = u32::from_le_bytes(b[at..at + 4].try_into().unwrap_or([0; 4]));
        let new = match rng.random_range(0..6) {
            0 => u32::MAX,
            1 => 0x7fff_ffff,
            2 => old.wrapping_mul(2).wrapping_add(1),
            3 => old.wrapping_add(1),
            4 => old.wrapping_sub(1),
            _ => rng.random(),
        };
        b[at..at + 4].copy_from_slice(&new.to_le_bytes());
    };
    let flip = |rng: &mut Pcg64, b: &mut Vec<u8>| {
        for _ in 0..rng.random_range(1..=8) {
            if b.is_empty() {
                return;
            }
            let i = rng.random_range(0..b.len());
            if rng.random_bool(0.5) {
                b[i] ^= 1 << rng.random_range(0..8);
            } else {
                b[i] = rng.random();
            }
        }
    };
    match rng.random_range(0..5) {
        0 => flip(rng, &mut b),
        1 => b.truncate(rng.random_range(0..original.len())),
        2 => inflate(rng, &mut b),
        3 => {
            inflate(rng, &mut b);
            flip(rng, &mut b);
        }
        _ => {
            flip(rng, &mut b);
            let keep = rng.random_range(original.len() / 2..=original.len());
            b.truncate(keep);
        }
    }
    b
}

/// Runs `cases` mutated files (spread over the small real files) through the importer; returns
/// (ok, errors, panics).
fn fuzz(cases: u64, seed: u64) -> (u64, u64, u64) {
    let mut files: Vec<(String, Vec<u8>)> = [ARMY, PLACEHOLDER, METAL, AXES, SCENE]
        .iter()
        .map(|r| ((*r).to_owned(), read(r)))
        .collect();
    // Animations (frames without a scene graph; `_f` keys in nTRN frames and nSHP models).
    files.push((
        "legacy-anim.vox".into(),
        super::frame_tests::legacy_animation(),
    ));
    files.push((
        "keyed-anim.vox".into(),
        super::frame_tests::keyframed_animation(),
    ));
    let headers: Vec<Vec<usize>> = files.iter().map(|f| header_offsets(&f.1)).collect();
    let mut rng = Pcg64::seed_from_u64(seed);
    let options = VoxImportOptions {
        max_voxels: 1 << 20,
        ..VoxImportOptions::default()
    };
    let (mut ok, mut err, mut panics) = (0, 0, 0);
    let mut slowest = std::time::Duration::ZERO;
    let start = Instant::now();
    for case in 0..cases {
        if case > 0 && case % 100_000 == 0 {
            eprintln!(
                "vox fuzz: {case} cases, {panics} panics, {:.0} s",
                start.elapsed().as_secs_f64()
            );
        }
        let k = (case % files.len() as u64) as usize;
        let data = mutate(&mut rng, &files[k].1, &headers[k]);
        let name = Path::new(&files[k].0);
        let began = Instant::now();
        let outcome = catch_unwind(AssertUnwindSafe(|| import_vox_bytes(&data, name, &options)));
        slowest = slowest.max(began.elapsed());
        match outcome {
            Ok(Ok(_)) => ok += 1,
            Ok(Err(e)) => {
                let msg = e.to_string();
                assert!(msg.starts_with(&files[k].0), "case {case}: {msg}");
                err += 1;
            }
            Err(_) => {
                panics += 1;
                let dump = std::env::temp_dir().join(format!("thicket-vox-fuzz-panic-{case}.vox"));
                let _ = std::fs::write(&dump, &data);
                eprintln!(
                    "case {case} ({}) panicked; input saved to {}",
                    files[k].0,
                    dump.display()
                );
            }
        }
    }
    eprintln!("vox fuzz: slowest case {:.3} s", slowest.as_secs_f64());
    (ok, err, panics)
}

#[test]
fn fuzzed_real_files_never_panic() {
    // THICKET_FUZZ_CASES raises the count for long runs (run those in release mode).
    let cases: u64 = std::env::var("THICKET_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000);
    let seed: u64 = std::env::var("THICKET_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x7ac0);
    let start = Instant::now();
    let (ok, err, panics) = fuzz(cases, seed);
    eprintln!(
        "vox fuzz: {cases} cases, {ok} loaded, {err} refused, {panics} panics, {:.1} s",
        start.elapsed().as_secs_f64()
    );
    assert_eq!(ok + err + panics, cases);
    assert_eq!(panics, 0);
    // The mutations must actually break files (and leave some loadable).
    assert!(err > cases / 4 && ok > 0, "ok {ok}, err {err}");
}

#[test]
fn the_export_estimate_counts_the_cells_before_any_is_built() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("e.vox");
    // Two voxels scaled 4x next to one at scale 1: the grid unit is the small voxel, so each
    // large voxel fills 4 x 4 x 4 cells.
    let mut big = object(
        "Big",
        vec![
            (UVec3::ZERO, solid([200, 0, 0, 255])),
            (UVec3::X, solid([0, 200, 0, 255])),
        ],
        1,
    );
    big.transform.scale = Vec3::splat(4.0);
    big.transform.translation = Vec3::new(10.0, 0.0, 0.0);
    let small = object("Small", vec![(UVec3::ZERO, solid([0, 0, 200, 255]))], 1);
    let objects = [big, small];
    let e = estimate_vox_export(&objects, &path, &VoxExportOptions::default()).unwrap();
    assert_eq!(e.cells, 2 * 64 + 1);
    assert!((e.grid_unit - 1.0).abs() < 1e-9, "{e:?}");
    assert_eq!(
        e.peak_bytes,
        e.cells * VOX_EXPORT_BYTES_PER_CELL + (1 << 20)
    );
    let report = export_vox(&objects, &path).unwrap();
    assert_eq!(report.voxels, e.cells, "the estimate is the count written");
    // A larger grid unit: the small voxel still fills one cell, a large one 2 x 2 x 2.
    let coarse = VoxExportOptions {
        grid_unit: Some(2.0),
        ..VoxExportOptions::default()
    };
    assert_eq!(
        estimate_vox_export(&objects, &path, &coarse).unwrap().cells,
        2 * 8 + 1
    );
    // Over the limit: refused before any cell is built, saying how many and the limit.
    std::fs::remove_file(&path).unwrap();
    let tight = VoxExportOptions {
        max_voxels: 100,
        ..VoxExportOptions::default()
    };
    let msg = export_vox_with(&objects, &path, &tight)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("about 129 voxels") && msg.contains("the limit of 100"),
        "{msg}"
    );
    assert!(!path.exists());
}

/// The exporter writes only what the importer reads: a model placed so far from the origin
/// that its voxels pass ±2^24 is refused with the object named (before, its `_t` fitted 32 bits
/// and the file was written, then refused on reading); one just inside round-trips exactly.
#[test]
fn export_refuses_positions_the_importer_refuses() {
    let voxels = vec![(UVec3::new(0, 0, 0), solid([1, 2, 3, 255]))];
    let mut near = object("near", voxels.clone(), 1);
    let inside = (MAX_COORD - 512) as f32;
    near.transform.translation = Vec3::new(inside, 0.0, 0.0);
    let back = bytes_round_trip(std::slice::from_ref(&near));
    assert_eq!(back.len(), 1);
    assert_eq!(back[0].0[0], MAX_COORD - 512);

    let mut far = object("far", voxels, 1);
    far.transform.translation = Vec3::new(0.0, 0.0, -((MAX_COORD * 4) as f32));
    let e = export_vox_bytes(&[far], Path::new("far.vox"), &VoxExportOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("far.vox") && e.contains("far") && e.contains("16777216"),
        "{e}"
    );
}

/// The import's memory is estimated from the voxels the scene graph places before any model is
/// built: the estimate covers the measured peak of every sample file (and is within 4× of it
/// plus 1 MiB, so it does not refuse what fits), and a budget below it refuses the file naming
/// the instances and the limit, having allocated little.
#[test]
fn import_memory_is_estimated_before_building() {
    let mut checked = 0;
    for rel in [ARMY, PLACEHOLDER, METAL, AXES, SCENE, "mmmm/obj_house4.vox"] {
        let bytes = read(rel);
        let name = Path::new(rel);
        let (scene, peak) = crate::io::fuzz::peak_heap_bytes(|| {
            import_vox_bytes(&bytes, name, &VoxImportOptions::default()).unwrap()
        });
        let placed: u64 = scene
            .objects
            .iter()
            .map(|o| {
                let v = voxels_of(o);
                v.svo.leaf_count()
                    + v.frames
                        .as_ref()
                        .map_or(0, |f| f.frames.iter().map(|fr| fr.svo.leaf_count()).sum())
            })
            .sum();
        drop(scene);
        let estimate = estimate_vox_import(placed, bytes.len() as u64);
        eprintln!("{rel}: {placed} voxels, peak {peak}, estimate {estimate}");
        assert!(estimate >= peak, "{rel}: estimate {estimate} < peak {peak}");
        assert!(
            estimate <= 4 * peak + (1 << 20),
            "{rel}: {estimate} vs {peak}"
        );
        if placed > 10_000 {
            let tight = VoxImportOptions {
                memory: crate::budget::MemoryBudget::given(estimate / 2),
                ..VoxImportOptions::default()
            };
            let (result, refused_peak) =
                crate::io::fuzz::peak_heap_bytes(|| import_vox_bytes(&bytes, name, &tight));
            let e = result.unwrap_err().to_string();
            assert!(
                e.contains("instance(s) holding") && e.contains("memory"),
                "{e}"
            );
            assert!(refused_peak < peak, "{rel}: {refused_peak} of {peak} held");
            checked += 1;
        }
    }
    assert!(checked >= 2, "only {checked} files large enough");
}

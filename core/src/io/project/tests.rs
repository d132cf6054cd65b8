use glam::{Quat, UVec3, Vec2, Vec3, Vec4};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};

use super::*;
use crate::mesh::unit_cube;
use crate::scene::{Light, MeshObject, Transform, VoxelModel};

fn sample_doc(seed: u64, skin: bool) -> Document {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut doc = Document::default();
    let voxels: Vec<(UVec3, Voxel)> = (0..rng.random_range(0..300))
        .map(|_| {
            let c = UVec3::new(
                rng.random_range(0..64),
                rng.random_range(0..64),
                rng.random_range(0..64),
            );
            let mut v = Voxel::new(
                rng.random(),
                Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5,
            );
            v.material = rng.random_range(0..4);
            if skin {
                v.skin = Skin4::from_influences(&[
                    (rng.random_range(0..20), rng.random()),
                    (rng.random_range(0..20), rng.random()),
                ]);
            }
            (c, v)
        })
        .collect();
    let svo = Svo::from_voxels(6, skin, voxels).unwrap();
    doc.add(
        "Model",
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: rng.random_range(0.01..1.0),
            origin: Vec3::new(rng.random(), -1.0, 2.5),
            material_names: vec!["stone".into()],
            rig: None,
            volume: None,
            palette: Vec::new(),
            frames: None,
        }),
    );
    let mut cube = unit_cube();
    cube.uvs = cube.positions.iter().map(|p| Vec2::new(p.x, p.y)).collect();
    cube.colors = cube
        .positions
        .iter()
        .map(|p| Vec4::new(p.x, p.y, p.z, 1.0).abs())
        .collect();
    let mut model = MeshModel {
        parts: vec![cube],
        materials: vec![Material {
            name: "grey".into(),
            base_color: Vec4::new(0.5, 0.5, 0.5, 1.0),
            base_color_texture: Some(Texture {
                width: 2,
                height: 1,
                rgba8: vec![1, 2, 3, 4, 5, 6, 7, 8],
            }),
            unlit: true,
        }],
    };
    if skin {
        model.parts[0].joints = vec![[0, 1, 2, 3]; 8];
        model.parts[0].weights = vec![[0.25; 4]; 8];
    }
    doc.add(
        "Ground",
        ObjectKind::Mesh(MeshObject {
            model,
            casts_shadows: false,
        }),
    );
    doc.objects[1].transform = Transform {
        translation: Vec3::new(1.0, 2.0, 3.0),
        rotation: Quat::from_rotation_y(rng.random()),
        scale: Vec3::new(2.0, 0.1, 2.0),
    };
    doc.objects[1].visible = seed.is_multiple_of(2);
    doc.lights.push(Light {
        name: "Fill".into(),
        intensity: 0.3,
        ..Light::default()
    });
    doc.quality.lod_pixel_threshold = rng.random_range(0.5..4.0);
    doc
}

#[test]
fn save_then_load_is_identical_and_names_bin() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.thicket.json");
    let doc = sample_doc(1, true);
    save(&doc, &path).unwrap();
    // The payload file is named in the JSON and is the only file beside it.
    let bin = bin_path_for(&path);
    assert!(bin.exists(), "{}", bin.display());
    assert_ne!(bin, legacy_bin_path(&path));
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);
    assert_eq!(load(&path).unwrap(), doc);
    // A document with no payloads writes no .bin.
    let empty = Document::default();
    let p2 = dir.path().join("empty.thicket.json");
    save(&empty, &p2).unwrap();
    assert!(!bin_path_for(&p2).exists());
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 3);
    assert_eq!(load(&p2).unwrap(), empty);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn round_trip_property(seed in any::<u64>(), skin in any::<bool>()) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.thicket.json");
        let doc = sample_doc(seed, skin);
        save(&doc, &path).unwrap();
        prop_assert_eq!(load(&path).unwrap(), doc);
    }
}

#[test]
fn wrong_checksum_is_reported_with_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.thicket.json");
    save(&sample_doc(3, false), &path).unwrap();
    let bin = bin_path_for(&path);
    let mut bytes = fs::read(&bin).unwrap();
    let n = bytes.len();
    bytes[n / 2] ^= 0x40;
    fs::write(&bin, &bytes).unwrap();
    let e = load(&path).unwrap_err().to_string();
    let name = bin.file_name().unwrap().to_string_lossy().into_owned();
    assert!(e.contains(&name) && e.contains("CRC-32"), "{e}");
}

#[test]
fn a_corrupt_payload_with_a_matching_file_checksum_is_still_caught() {
    // Rewrite the JSON so the whole-file CRC matches a tampered .bin: the per-payload CRC catches it.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.thicket.json");
    save(&sample_doc(4, false), &path).unwrap();
    let bin_path = bin_path_for(&path);
    let mut bin = fs::read(&bin_path).unwrap();
    bin[20] ^= 1;
    fs::write(&bin_path, &bin).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    json["bin"]["crc32"] = crc32fast::hash(&bin).into();
    fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let e = load(&path).unwrap_err().to_string();
    assert!(
        e.contains("checksum mismatch") && e.contains("Model"),
        "{e}"
    );
}

#[test]
fn nan_in_a_transform_is_refused_with_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("n.thicket.json");
    save(&Document::default(), &path).unwrap();
    let text = r#"{"format_version":1,"objects":[{"id":1,"name":"x","kind":{"type":"Mesh"},
      "transform":{"translation":[NaN,0,0]}}]}"#;
    fs::write(&path, text).unwrap();
    let e = load(&path).unwrap_err();
    assert!(matches!(e, ProjectError::Json { line: 2, .. }), "{e}");
    // null (what serde_json writes for NaN) is refused too.
    fs::write(&path, text.replace("NaN", "null")).unwrap();
    assert!(
        load(&path)
            .unwrap_err()
            .to_string()
            .contains("n.thicket.json")
    );
    // 1e39 overflows f32: refused, never turned into an infinite translation.
    fs::write(&path, text.replace("NaN", "1e39")).unwrap();
    assert!(load(&path).is_err());
}

#[test]
fn newer_versions_and_missing_payloads_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v.thicket.json");
    fs::write(&path, r#"{"format_version": 999}"#).unwrap();
    assert!(
        load(&path)
            .unwrap_err()
            .to_string()
            .contains("format_version 999")
    );
    fs::write(
        &path,
        r#"{"objects":[{"id":7,"name":"lost","kind":{"type":"Voxels"}}]}"#,
    )
    .unwrap();
    let e = load(&path).unwrap_err().to_string();
    assert!(e.contains("lost") && e.contains("no payload"), "{e}");
    fs::write(&path, "").unwrap();
    assert!(matches!(
        load(&path).unwrap_err(),
        ProjectError::Json { .. }
    ));
    assert!(matches!(
        load(&dir.path().join("missing.json")).unwrap_err(),
        ProjectError::Io { .. }
    ));
}

#[test]
fn invalid_documents_are_not_saved() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.thicket.json");
    let mut doc = sample_doc(5, false);
    doc.objects[0].transform.scale = Vec3::ZERO;
    assert!(matches!(
        save(&doc, &path),
        Err(ProjectError::Invalid { .. })
    ));
    assert!(!path.exists());
    assert!(
        fs::read_dir(dir.path()).unwrap().next().is_none(),
        "nothing written"
    );
}

/// Rewrites a fresh save into the layout older versions wrote: the payload in
/// `NAME.thicket.bin`, named so in the JSON.
fn make_legacy(path: &Path) {
    let bin = bin_path_for(path);
    let legacy = legacy_bin_path(path);
    fs::rename(&bin, &legacy).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&fs::read(path).unwrap()).unwrap();
    json["bin"]["file"] = legacy
        .file_name()
        .unwrap()
        .to_string_lossy()
        .into_owned()
        .into();
    fs::write(path, serde_json::to_vec_pretty(&json).unwrap()).unwrap();
}

#[test]
fn old_style_projects_and_their_crash_states_still_load() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.thicket.json");
    let old = sample_doc(6, false);
    save(&old, &path).unwrap();
    make_legacy(&path);
    assert_eq!(load(&path).unwrap(), old);
    // The older save's crash state after its first rename: the old payload in `.bin.prev`, the
    // new one in `.bin`, the old JSON.
    let new = sample_doc(7, false);
    let other = dir.path().join("other.thicket.json");
    save(&new, &other).unwrap();
    let bin = legacy_bin_path(&path);
    fs::rename(&bin, with_suffix(&bin, ".prev")).unwrap();
    fs::copy(bin_path_for(&other), &bin).unwrap();
    assert_eq!(load(&path).unwrap(), old);
    // And after that save's first rename only (no `.bin` at all).
    fs::remove_file(&bin).unwrap();
    assert_eq!(load(&path).unwrap(), old);
    // Saving over an old-style project moves it to the new naming and removes the old files,
    // but not the other project's.
    save(&new, &path).unwrap();
    assert_eq!(load(&path).unwrap(), new);
    assert!(!bin.exists() && !with_suffix(&bin, ".prev").exists());
    let mut names: Vec<String> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names.len(), 4, "{names:?}");
    assert_eq!(load(&other).unwrap(), new);
}

/// A rigid model whose inside is tiles: a solid box of one colour with a shell of many.
fn solid_block() -> Svo {
    let mut voxels = Vec::new();
    for z in 3..29u32 {
        for y in 3..29u32 {
            for x in 3..29u32 {
                let shell = [x, y, z].iter().any(|&a| a == 3 || a == 28);
                let v = if shell {
                    Voxel::new([x as u8 * 9, y as u8 * 9, z as u8 * 9, 255], Vec3::Y)
                } else {
                    Voxel::new([90, 60, 30, 255], Vec3::Z)
                };
                voxels.push((UVec3::new(x, y, z), v));
            }
        }
    }
    Svo::from_voxels(5, false, voxels).unwrap()
}

/// The version-2 octree payload (`SVO1`): every voxel, one record each.
fn encode_svo1(svo: &Svo) -> Vec<u8> {
    let mut out = b"SVO1".to_vec();
    out.push(svo.depth());
    out.push(u8::from(svo.has_skin()));
    out.extend_from_slice(&[0, 0]);
    out.extend_from_slice(&svo.leaf_count().to_le_bytes());
    svo.for_each_leaf(|c, v| {
        out.extend_from_slice(&crate::svo::morton_encode(c).to_le_bytes());
        put_voxel(&mut out, &v, svo.has_skin());
    });
    out
}

#[test]
fn tiled_payloads_follow_the_surface_and_older_payloads_still_load() {
    let svo = solid_block();
    assert!(svo.tile_count() > 0);
    let mut tiled = Vec::new();
    encode_svo(&svo, &mut tiled);
    let flat = encode_svo1(&svo);
    let back = decode_svo(&tiled).unwrap();
    assert_eq!(back, svo);
    assert_eq!(back.tile_count(), svo.tile_count());
    assert_eq!(back.memory_stats(), svo.memory_stats());
    // The same voxels from the older payload: equal, and tiled in memory as well.
    let old = decode_svo(&flat).unwrap();
    assert_eq!(old, svo);
    assert_eq!(old.tile_count(), svo.tile_count());
    // 26³ voxels of which the 24³ inside are one colour: the file holds the shell.
    assert!(
        tiled.len() * 3 < flat.len(),
        "{} bytes tiled against {} one voxel a record",
        tiled.len(),
        flat.len()
    );
    // A skinned surface keeps its voxels one by one and round-trips too.
    let doc = sample_doc(5, true);
    let ObjectKind::Voxels(v) = &doc.objects[0].kind else {
        unreachable!("the sample's first object is voxels")
    };
    let mut bytes = Vec::new();
    encode_svo(&v.svo, &mut bytes);
    assert_eq!(decode_svo(&bytes).unwrap(), v.svo);
}

#[test]
fn a_skinned_solids_interior_tiles_round_trip_and_a_coloured_skinned_tile_is_refused() {
    let doc = crate::render::scenes::rigid_solid_figure();
    let ObjectKind::Voxels(v) = &doc.objects[0].kind else {
        unreachable!("the figure is voxels")
    };
    let svo = &v.svo;
    assert!(
        svo.has_skin() && svo.tile_count() > 100,
        "{}",
        svo.tile_count()
    );
    let mut bytes = Vec::new();
    encode_svo(svo, &mut bytes);
    let back = decode_svo(&bytes).unwrap();
    assert_eq!(&back, svo);
    assert_eq!(back.tile_count(), svo.tile_count());
    assert_eq!(back.memory_stats(), svo.memory_stats());
    // Smaller than one record a voxel.
    let flat = encode_svo1(svo);
    assert!(
        bytes.len() < flat.len(),
        "{} >= {}",
        bytes.len(),
        flat.len()
    );
    // A skinned record is code 8, height 1, colour 4, normal 2, material 1, skin 8 = 24 bytes
    // after the 24-byte header. A tile given a colour (a drawn tile) is refused: skinned
    // octrees tile only their interior.
    let runs = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
    let record = |i: usize| 24 + 24 * i;
    let tile = (0..runs).find(|&i| bytes[record(i) + 8] > 0).unwrap();
    let mut b = bytes.clone();
    let at = record(tile) + 9;
    let (color, normal) = ([200, 40, 40, 255], crate::svo::encode_normal(Vec3::Y));
    b[at..at + 4].copy_from_slice(&color);
    b[at + 4..at + 6].copy_from_slice(&normal.to_le_bytes());
    let e = decode_svo(&b).unwrap_err();
    assert!(
        e.contains(&format!("record {tile}:")) && e.contains("cannot store"),
        "{e}"
    );
    // Refused for being drawn, not for its value: the same record is a tile a rigid octree
    // stores, and the skinned octree stores its weights in a tile when it is interior.
    let drawn = Voxel {
        color,
        normal,
        ..Voxel::default()
    };
    assert!(Svo::new(svo.depth(), false).unwrap().tile_value_ok(&drawn));
    let mut skin = None;
    svo.for_each_run(|_, height, v| {
        if height > 0 && skin.is_none() {
            skin = Some(v.skin);
        }
    });
    let skin = skin.expect("a tile");
    assert!(!svo.tile_value_ok(&Voxel { skin, ..drawn }));
    assert!(svo.tile_value_ok(&Voxel {
        skin,
        ..Voxel::INTERIOR
    }));
}

#[test]
fn tiles_a_file_lists_apart_are_joined_where_they_fill_a_node() {
    // Eight tiles of height 1 filling the 4³ corner node, listed one by one (a writer need not
    // join them): loaded, they are one tile of height 2, equal to the same voxels built.
    let v = Voxel::new([10, 200, 30, 255], Vec3::Z);
    let mut b = b"SVO2".to_vec();
    b.extend_from_slice(&[4, 0, 0, 0]);
    b.extend_from_slice(&64u64.to_le_bytes());
    b.extend_from_slice(&8u64.to_le_bytes());
    for k in 0..8u64 {
        b.extend_from_slice(&(8 * k).to_le_bytes());
        b.push(1);
        put_voxel(&mut b, &v, false);
    }
    let svo = decode_svo(&b).unwrap();
    assert_eq!(svo.tile_count(), 1);
    assert_eq!(svo.leaf_count(), 64);
    let built =
        Svo::from_voxels(4, false, (0..64).map(|m| (crate::svo::morton_decode(m), v))).unwrap();
    assert_eq!(svo, built);
    assert_eq!(svo.memory_stats(), built.memory_stats());
}

#[test]
fn bad_tile_records_are_refused_with_their_reason() {
    let svo = solid_block();
    let mut good = Vec::new();
    encode_svo(&svo, &mut good);
    // Header: magic 4, depth, skin, 2 zero bytes, voxels u64, runs u64 = 24 bytes; a rigid
    // record is code u64, height u8, colour 4, normal 2, material 1 = 16 bytes.
    let record = |i: usize| 24 + 16 * i;
    let runs = u64::from_le_bytes(good[16..24].try_into().unwrap()) as usize;
    let tile = (0..runs).find(|&i| good[record(i) + 8] > 0).unwrap();
    let expect = |bytes: &[u8], needle: &str| {
        let e = decode_svo(bytes).unwrap_err();
        assert!(e.contains(needle), "{e}");
    };
    // A tile whose origin is not a node of its height.
    let mut b = good.clone();
    b[record(tile)] += 1;
    expect(&b, "is not a node");
    // A height above the octree's depth.
    let mut b = good.clone();
    b[record(tile) + 8] = 6;
    expect(&b, "is not a node");
    // Runs out of order (overlapping).
    let mut b = good.clone();
    let (a, c) = (record(tile), record(tile + 1));
    let first: Vec<u8> = b[a..a + 16].to_vec();
    let second: Vec<u8> = b[c..c + 16].to_vec();
    b[a..a + 16].copy_from_slice(&second);
    b[c..c + 16].copy_from_slice(&first);
    expect(&b, "out of order");
    // A voxel count that the runs do not add up to.
    let mut b = good.clone();
    b[8] ^= 1;
    expect(&b, "its runs hold");
    // A tile value eight copies of which do not average to itself (an octahedral normal code
    // that decoding and encoding again does not give back).
    let v = svo.get(UVec3::splat(10)).unwrap();
    let bad = (0..=u16::MAX)
        .find(|&n| !svo.tile_value_ok(&Voxel { normal: n, ..v }))
        .expect("some normal code is not its own average");
    let mut b = good.clone();
    let at = record(tile) + 9 + 4;
    b[at..at + 2].copy_from_slice(&bad.to_le_bytes());
    expect(&b, "cannot store");
    // More voxels than a model may hold: one tile of the whole depth-21 octree.
    let mut b = b"SVO2".to_vec();
    b.extend_from_slice(&[21, 0, 0, 0]);
    b.extend_from_slice(&(1u64 << 63).to_le_bytes());
    b.extend_from_slice(&1u64.to_le_bytes());
    b.extend_from_slice(&0u64.to_le_bytes());
    b.push(21);
    b.extend_from_slice(&[1, 2, 3, 255, 0, 0, 0]);
    expect(&b, "more than");
    assert!(decode_svo(&good).is_ok());
}

#[test]
fn projects_standing_for_more_voxels_than_tools_can_visit_are_neither_saved_nor_loaded() {
    // Two models of 2^30 + 2^27 voxels each (a tile of height 10 and one of height 9): each
    // under the cap, together over it.
    let v = Voxel::new([10, 200, 30, 255], Vec3::Z);
    let mut doc = Document::default();
    for name in ["a", "b"] {
        let mut svo = Svo::new(11, false).unwrap();
        svo.put_tile(UVec3::ZERO, 10, v);
        svo.put_tile(UVec3::new(1024, 0, 0), 9, v);
        assert_eq!(svo.leaf_count(), (1 << 30) + (1 << 27));
        doc.add(
            name,
            ObjectKind::Voxels(VoxelModel {
                svo,
                ..VoxelModel::default()
            }),
        );
    }
    let e = check_voxel_total(&doc).unwrap_err();
    assert!(e.contains("more than the 2147483648"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.thicket.json");
    let e = save(&doc, &path).unwrap_err().to_string();
    assert!(e.contains("not saved") && e.contains("voxels"), "{e}");
    assert!(!path.exists(), "nothing is written");
    // One model alone is saved and loads back, its tiles stored once.
    doc.objects.truncate(1);
    save(&doc, &path).unwrap();
    assert!(fs::metadata(bin_path_for(&path)).unwrap().len() < 1024);
    assert_eq!(load(&path).unwrap(), doc);
}

/// Mutated tiled payloads fed to the decoder itself (the loader's checksums would refuse most
/// of them before it): no panic, memory bounded by the input, and what is accepted is a
/// consistent octree.
#[test]
fn mutated_tiled_payloads_never_panic() {
    let mut good = Vec::new();
    encode_svo(&solid_block(), &mut good);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(43);
    let cases = crate::io::fuzz::cases_from_env(3_000);
    let (mut accepted, mut refused, mut max_peak) = (0u64, 0u64, 0u64);
    for case in 0..cases {
        let mut b = good.clone();
        match rng.random_range(0..4) {
            0 => {
                for _ in 0..rng.random_range(1..4) {
                    let i = rng.random_range(0..b.len());
                    b[i] ^= 1 << rng.random_range(0..8);
                }
            }
            1 => {
                // A height byte of a record: taller, shorter or out of range.
                let runs = (b.len() - 24) / 16;
                let i = 24 + 16 * rng.random_range(0..runs) + 8;
                b[i] = rng.random_range(0..24);
            }
            2 => b.truncate(rng.random_range(0..b.len())),
            _ => {
                // A code of a record moved to another node.
                let runs = (b.len() - 24) / 16;
                let i = 24 + 16 * rng.random_range(0..runs);
                let code: u64 = rng.random_range(0..1 << 15);
                b[i..i + 8].copy_from_slice(&code.to_le_bytes());
            }
        }
        let (result, peak) = crate::io::fuzz::peak_heap_bytes(|| {
            std::panic::catch_unwind(|| {
                decode_svo(&b).map(|svo| {
                    let mut sum = 0u64;
                    svo.for_each_run(|_, h, _| sum += 1 << (3 * u32::from(h)));
                    (svo.leaf_count(), sum, svo.memory_stats().leaves)
                })
            })
        });
        max_peak = max_peak.max(peak);
        match result {
            Ok(Ok((count, sum, stats))) => {
                assert_eq!(
                    (count, stats),
                    (sum, sum),
                    "case {case}: inconsistent counts"
                );
                accepted += 1;
            }
            Ok(Err(_)) => refused += 1,
            Err(_) => panic!("case {case}: the decoder panicked"),
        }
    }
    eprintln!(
        "tiled payload fuzz: {cases} cases, {accepted} accepted, {refused} refused, max peak {max_peak} B"
    );
    assert!(
        refused > 0 && accepted > 0,
        "{accepted} accepted, {refused} refused"
    );
    assert!(
        max_peak < 64 * good.len() as u64 + (1 << 20),
        "peak {max_peak} B"
    );
}

#[test]
fn mutated_project_files_never_panic() {
    let mut doc = sample_doc(8, true);
    doc.add(
        "Block",
        ObjectKind::Voxels(VoxelModel {
            svo: solid_block(),
            ..VoxelModel::default()
        }),
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.thicket.json");
    save(&doc, &path).unwrap();
    let json = fs::read(&path).unwrap();
    let bin = fs::read(bin_path_for(&path)).unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(42);
    // THICKET_FUZZ_CASES raises the count for long runs (in release, see io::fuzz).
    let cases = crate::io::fuzz::cases_from_env(10_000);
    let start = std::time::Instant::now();
    let (mut accepted, mut refused) = (0u64, 0u64);
    let mut panics: Vec<u64> = Vec::new();
    let mut max_peak = 0u64;
    let mut slowest = std::time::Duration::ZERO;
    for case in 0..cases {
        let (mut j, mut b) = (json.clone(), bin.clone());
        let target = if case % 2 == 0 { &mut j } else { &mut b };
        match rng.random_range(0..4) {
            0 => {
                for _ in 0..rng.random_range(1..6) {
                    let i = rng.random_range(0..target.len());
                    target[i] ^= 1 << rng.random_range(0..8);
                }
            }
            1 => target.truncate(rng.random_range(0..target.len())),
            2 => {
                // Inflate a little-endian u32/u64 count somewhere.
                let i = rng.random_range(0..target.len().saturating_sub(4).max(1));
                let end = (i + 4).min(target.len());
                target[i..end].fill(0xff);
            }
            _ => {
                let i = rng.random_range(0..target.len());
                target.insert(i, b"0123456789{}[],:\"-e"[rng.random_range(0..19)]);
            }
        }
        let bin_for_case = b.clone();
        let began = std::time::Instant::now();
        // The loader proper (JSON, checksums, payloads), and the payload decoder fed the raw
        // mutated bytes directly (past the checksum, so its own checks run).
        let (result, peak) = crate::io::fuzz::peak_heap_bytes(|| {
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                let loaded = load_from_parts(&path, &j, |_| Ok(bin_for_case.clone())).is_ok();
                let _ = decode_svo(&b);
                loaded
            }))
        });
        max_peak = max_peak.max(peak);
        slowest = slowest.max(began.elapsed());
        match result {
            Ok(true) => accepted += 1,
            Ok(false) => refused += 1,
            Err(_) => panics.push(case),
        }
    }
    eprintln!(
        "project fuzz: {cases} cases: {accepted} accepted, {refused} refused, {} panics, \
         max peak heap per case {max_peak} bytes, slowest case {:.3} s, {:.1} s",
        panics.len(),
        slowest.as_secs_f64(),
        start.elapsed().as_secs_f64()
    );
    // Declared sizes are checked before allocating: no case may hold much more than its input.
    let input = (json.len() + bin.len()) as u64;
    assert!(
        max_peak < 64 * input + (16 << 20),
        "a case held {max_peak} bytes for {input} bytes of input"
    );
    assert!(
        panics.is_empty(),
        "{} cases panicked, first {:?}",
        panics.len(),
        &panics[..panics.len().min(10)]
    );
    assert!(refused > 0, "the mutations never reached an error path");
}

/// A document with KRS objects (tree, rock with distortion and texturing, forest) beside a voxel
/// object, so payload and parametric objects mix.
fn krs_doc() -> Document {
    use crate::krs::presets;
    let mut doc = sample_doc(11, false);
    let tree = doc.add("Tree", ObjectKind::Krs(presets::tree()));
    doc.add("Rock", ObjectKind::Krs(presets::rock()));
    doc.add("Forest", ObjectKind::Krs(presets::forest()));
    let o = doc.objects.iter_mut().find(|o| o.id == tree).unwrap();
    o.transform = Transform {
        translation: Vec3::new(3.0, 0.0, -1.0),
        rotation: Quat::from_rotation_y(0.7),
        scale: Vec3::splat(1.5),
    };
    doc
}

#[test]
fn krs_objects_round_trip_as_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("k.thicket.json");
    let doc = krs_doc();
    save(&doc, &path).unwrap();
    assert_eq!(load(&path).unwrap(), doc);
    // Parametric: kernels and mirrors are readable JSON, and only payload objects are in the
    // .bin's payload table.
    let json: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    let forest = &json["objects"][4]["kind"];
    assert_eq!(forest["type"], "Krs");
    assert_eq!(
        forest["mirrors"].as_array().unwrap().len(),
        crate::krs::presets::forest().mirrors.len()
    );
    assert!(forest["kernels"][1]["kind"].is_string());
    assert_eq!(json["payloads"].as_array().unwrap().len(), 2);

    // A document of KRS objects only writes no .bin at all.
    let mut only = Document::default();
    only.add("Rock", ObjectKind::Krs(crate::krs::presets::rock()));
    let p2 = dir.path().join("only.thicket.json");
    save(&only, &p2).unwrap();
    assert!(!bin_path_for(&p2).exists());
    assert_eq!(load(&p2).unwrap(), only);

    // Missing fields take their defaults (#[serde(default)] on every KRS struct).
    fs::write(
        &p2,
        r#"{"objects":[{"id":1,"name":"ball","kind":{"type":"Krs",
            "kernels":[{"kind":"Sphere","radius":0.5}]}}]}"#,
    )
    .unwrap();
    let doc = load(&p2).unwrap();
    let ObjectKind::Krs(k) = &doc.objects[0].kind else {
        panic!("not a KRS object")
    };
    assert!(k.mirrors.is_empty() && k.instance_count() == 1);
}

#[test]
fn bad_krs_values_are_refused_with_what_and_where() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.thicket.json");
    let cases = [
        // zero-length mirror normal
        (
            r#"{"kernels":[{"kind":"Empty"},{"kind":"Sphere"}],
                "mirrors":[{"normal":[0,0,0],"offset":1}]}"#,
            &["Stump", "mirror 0", "zero length"][..],
        ),
        // negative radius
        (
            r#"{"kernels":[{"kind":"Capsule","radius":-0.1}]}"#,
            &["Stump", "kernel 0", "radius", "-0.1"][..],
        ),
        // kernel count does not match the mirrors
        (
            r#"{"kernels":[{"kind":"Sphere"}],"mirrors":[{"normal":[1,0,0]}]}"#,
            &["Stump", "1 kernels and 1 mirrors"][..],
        ),
        // torus sweep out of range
        (
            r#"{"kernels":[{"kind":"ToroidalCapsule","sweep_radians":7.5}]}"#,
            &["Stump", "sweep_radians"][..],
        ),
        // zero scale of the KRS's own transform
        (
            r#"{"kernels":[{"kind":"Sphere"}],"world_from_object":{"scale":0}}"#,
            &["Stump", "scale"][..],
        ),
        // negative distortion amplitude
        (
            r#"{"kernels":[{"kind":"Sphere"}],"distortion":{"amplitude":-1}}"#,
            &["Stump", "distortion", "amplitude"][..],
        ),
        // unknown kernel kind: a JSON error with line and column
        (
            r#"{"kernels":[{"kind":"Teapot"}]}"#,
            &["bad.thicket.json", "Teapot"][..],
        ),
    ];
    for (krs, expect) in cases {
        let text = format!(
            r#"{{"objects":[{{"id":1,"name":"Stump","kind":{{"type":"Krs",{}}}]}}"#,
            &krs[1..]
        );
        fs::write(&path, text).unwrap();
        let e = load(&path).unwrap_err().to_string();
        for word in expect {
            assert!(e.contains(word), "{word:?} missing from: {e}");
        }
    }
    // A non-uniform object scale is refused (distance estimates need a similarity), on load
    // and on save.
    let mut doc = Document::default();
    doc.add("Tree", ObjectKind::Krs(crate::krs::presets::tree()));
    doc.objects[0].transform.scale = Vec3::new(1.0, 2.0, 1.0);
    let e = save(&doc, &path).unwrap_err().to_string();
    assert!(e.contains("Tree") && e.contains("uniform"), "{e}");
}

// ---------------------------------------------------------------- skinned voxel models

/// A three-joint chain with two clips, playback state, pose and stretch overrides, over a
/// column of voxels weighted to the joints.
fn skinned_doc() -> Document {
    use crate::skin::{
        AnimationClip, Channel, Interpolation, Joint, JointOverride, OverrideMode, Playback,
        Property, Rig, Skeleton, StretchSettings, StretchStrategy, Transform as JointTransform,
        Wrap,
    };
    let joints = (0..3)
        .map(|i| Joint {
            name: format!("bone{i}"),
            parent: (i > 0).then(|| i - 1),
            rest: JointTransform {
                translation: Vec3::new(0.0, if i == 0 { 0.0 } else { 1.0 }, 0.0),
                ..JointTransform::IDENTITY
            },
            inverse_bind: glam::Mat4::from_translation(Vec3::new(0.0, -(i as f32), 0.0)),
            ..Joint::default()
        })
        .collect();
    let (skeleton, _) = Skeleton::new(joints).unwrap();
    let walk = AnimationClip {
        name: "walk".into(),
        duration_secs: 2.0,
        channels: vec![
            Channel {
                joint: 1,
                property: Property::Rotation,
                interpolation: Interpolation::Linear,
                times: vec![0.0, 1.0, 2.0],
                values: vec![
                    Vec4::new(0.0, 0.0, 0.0, 1.0),
                    Vec4::new(0.0, 0.0, 0.38, 0.92),
                    Vec4::new(0.0, 0.0, 0.0, 1.0),
                ],
            },
            Channel {
                joint: 2,
                property: Property::Translation,
                interpolation: Interpolation::CubicSpline,
                times: vec![0.0, 2.0],
                values: vec![Vec4::ZERO, Vec4::Y, Vec4::X, Vec4::ZERO, Vec4::Y, Vec4::Z],
            },
        ],
        frame_rate: 30.0,
    };
    let wave = AnimationClip {
        name: "wave".into(),
        duration_secs: 0.5,
        channels: vec![Channel {
            joint: 2,
            property: Property::Scale,
            interpolation: Interpolation::Step,
            times: vec![0.0, 0.5],
            values: vec![Vec4::ONE, Vec4::splat(2.0)],
        }],
        frame_rate: 12.0,
    };
    let voxels: Vec<(UVec3, Voxel)> = (0..24u32)
        .map(|y| {
            let mut v = Voxel::new([200, 100, 50, 255], Vec3::X);
            let t = y as f32 / 8.0;
            let j = (t as u16).min(2);
            v.skin = Skin4::from_influences(&[(j, 1.0 - t.fract()), ((j + 1).min(2), t.fract())]);
            (UVec3::new(3, y, 4), v)
        })
        .collect();
    let svo = Svo::from_voxels(5, true, voxels).unwrap();
    let mut rig = Rig::new(skeleton, vec![walk, wave]);
    rig.playback = Playback {
        clip: Some(1),
        time_secs: 0.25,
        wrap: Wrap::Clamp,
    };
    rig.pose_overrides = vec![JointOverride {
        joint: 2,
        rotation: Some(Quat::from_rotation_x(0.5)),
        translation: None,
        mode: OverrideMode::Relative,
        scale: Some(Vec3::new(1.0, 1.5, 1.0)),
    }];
    rig.stretch = StretchSettings {
        strategy: StretchStrategy::Adaptive,
        multiplier: 1.25,
        ..StretchSettings::default()
    };
    rig.stretch_overrides.set(UVec3::new(3, 5, 4), 128);
    rig.stretch_overrides.set(UVec3::new(3, 1, 4), 70);
    let mut reference = unit_cube();
    reference.joints = vec![[0, 1, 2, 0]; reference.positions.len()];
    reference.weights = vec![[0.5, 0.25, 0.25, 0.0]; reference.positions.len()];
    rig.reference_mesh = Some(MeshModel {
        parts: vec![reference],
        materials: Vec::new(),
    });
    let mut doc = Document::default();
    doc.add(
        "Figure",
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: 1.0 / 8.0,
            rig: Some(rig),
            ..VoxelModel::default()
        }),
    );
    doc
}

fn rig_of(doc: &Document) -> &crate::skin::Rig {
    match &doc.objects[0].kind {
        ObjectKind::Voxels(v) => v.rig.as_ref().expect("rig"),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => panic!("not voxels"),
    }
}

/// A skin payload written before clips had a frame rate (`SKN1`) loads, every clip at the
/// default rate and otherwise equal.
#[test]
fn skin_payloads_without_frame_rates_still_load() {
    let doc = skinned_doc();
    let rig = rig_of(&doc);
    let mut v2 = Vec::new();
    encode_skin(rig, &mut v2);
    assert_eq!(&v2[..4], b"SKN2");
    // SKN1: the same bytes without the f32 after each clip's duration.
    let mut v1 = b"SKN1".to_vec();
    let mut at = 4;
    v1.extend_from_slice(&v2[at..at + 4]);
    at += 4;
    for c in &rig.clips {
        let head = 4 + c.name.len() + 4;
        v1.extend_from_slice(&v2[at..at + head]);
        at += head + 4;
        // The channel table: a count, then per channel joint, property, interpolation, two
        // pad bytes, and the counted times and values.
        let body_end = 4 + c
            .channels
            .iter()
            .map(|ch| 4 + 4 + 4 + 4 * ch.times.len() + 4 + 16 * ch.values.len())
            .sum::<usize>();
        v1.extend_from_slice(&v2[at..at + body_end]);
        at += body_end;
    }
    v1.extend_from_slice(&v2[at..]);
    let mut read = crate::skin::Rig::default();
    decode_skin(&v1, &mut read).unwrap();
    assert_eq!(read.clips.len(), rig.clips.len());
    for (a, b) in read.clips.iter().zip(&rig.clips) {
        assert_eq!(a.frame_rate, crate::skin::keys::DEFAULT_FRAME_RATE);
        assert_eq!(
            crate::skin::AnimationClip {
                frame_rate: b.frame_rate,
                ..a.clone()
            },
            *b
        );
    }
    assert_eq!(read.reference_mesh, rig.reference_mesh);
    // And the current format keeps each clip's own rate.
    let mut read = crate::skin::Rig::default();
    decode_skin(&v2, &mut read).unwrap();
    assert_eq!(
        read.clips.iter().map(|c| c.frame_rate).collect::<Vec<_>>(),
        [30.0, 12.0]
    );
}

#[test]
fn skinned_models_round_trip_with_clips_playback_and_overrides() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rig.thicket.json");
    let doc = skinned_doc();
    save(&doc, &path).unwrap();
    let loaded = load(&path).unwrap();
    assert_eq!(loaded, doc);
    let rig = rig_of(&loaded);
    assert_eq!(rig.clips.len(), 2);
    assert_eq!(rig.stretch_overrides.get(UVec3::new(3, 5, 4)), 128);
    assert_eq!(rig.reference_mesh.as_ref().map(|m| m.parts.len()), Some(1));
    // The JSON is readable: joint names and the strategy are there, key arrays are not.
    let text = fs::read_to_string(&path).unwrap();
    assert!(
        text.contains("bone2") && text.contains("Adaptive"),
        "{text}"
    );
    assert!(text.contains(r#""part": "skin""#), "{text}");
    // A file without skin writes no part field (older readers see exactly what they know).
    let plain = dir.path().join("plain.thicket.json");
    save(&sample_doc(2, true), &plain).unwrap();
    assert!(!fs::read_to_string(&plain).unwrap().contains("part"));
}

/// Saves [`skinned_doc`], lets `edit` change the JSON, returns the load error.
fn load_error_after(edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.thicket.json");
    save(&skinned_doc(), &path).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    edit(&mut json);
    fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    load(&path).unwrap_err().to_string()
}

#[test]
fn bad_skin_values_are_clear_errors() {
    let rig = |j: &mut serde_json::Value| j["objects"][0]["kind"]["rig"].clone();
    let e = load_error_after(|j| {
        j["objects"][0]["kind"]["rig"]["playback"]["clip"] = 5.into();
    });
    assert!(e.contains("Figure") && e.contains("playback.clip 5"), "{e}");
    let e = load_error_after(|j| {
        j["objects"][0]["kind"]["rig"]["stretch"]["multiplier"] = (-1.0).into();
    });
    assert!(e.contains("multiplier -1"), "{e}");
    let e = load_error_after(|j| {
        j["objects"][0]["kind"]["rig"]["pose_overrides"][0]["joint"] = 9.into();
    });
    assert!(e.contains("pose override 0 targets joint 9"), "{e}");
    let e = load_error_after(|j| {
        j["objects"][0]["kind"]["rig"]["stretch"]["strategy"] = "Sideways".into();
    });
    assert!(e.contains("Sideways") && e.contains("line"), "{e}");
    // A skeleton cut to two joints: the clips (and voxels) that use joint 2 are named.
    let e = load_error_after(|j| {
        let mut r = rig(j);
        r["skeleton"]["joints"].as_array_mut().unwrap().pop();
        j["objects"][0]["kind"]["rig"] = r;
    });
    assert!(e.contains("Figure") && e.contains("joint 2"), "{e}");
    // The skin payload dropped from the table.
    let e = load_error_after(|j| {
        j["payloads"]
            .as_array_mut()
            .unwrap()
            .retain(|p| p.get("part").is_none());
    });
    assert!(e.contains("Figure") && e.contains("no skin payload"), "{e}");
}

#[test]
fn voxels_weighted_to_missing_joints_are_refused() {
    // Clips that only use joints 0 and 1, but a voxel weighted to joint 2 of a 2-joint skeleton.
    let mut doc = skinned_doc();
    let ObjectKind::Voxels(v) = &mut doc.objects[0].kind else {
        unreachable!()
    };
    let rig = v.rig.as_mut().unwrap();
    rig.clips.clear();
    rig.playback.clip = None;
    rig.pose_overrides.clear();
    rig.reference_mesh = None;
    rig.skeleton.joints.pop();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.thicket.json");
    // Saving validates the rig but not every voxel (that is a load-time scan).
    save(&doc, &path).unwrap();
    let e = load(&path).unwrap_err().to_string();
    assert!(
        e.contains("weighted to joint 2") && e.contains("2 joints"),
        "{e}"
    );
}

#[test]
fn a_corrupt_skin_payload_is_caught() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.thicket.json");
    save(&skinned_doc(), &path).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    let skin = json["payloads"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["part"] == "skin")
        .unwrap()
        .clone();
    let bin_path = bin_path_for(&path);
    let mut bin = fs::read(&bin_path).unwrap();
    let at = skin["offset"].as_u64().unwrap() as usize + 6;
    bin[at] ^= 0x10;
    fs::write(&bin_path, &bin).unwrap();
    let e = load(&path).unwrap_err().to_string();
    assert!(e.contains("CRC-32") || e.contains("checksum"), "{e}");
}

#[test]
fn stretch_overrides_set_get_and_refuse_disorder() {
    use crate::skin::StretchOverrides;
    let mut o = StretchOverrides::default();
    assert_eq!(o.set(UVec3::new(1, 2, 3), 90), 0);
    assert_eq!(o.set(UVec3::new(1, 2, 3), 100), 90);
    assert_eq!(o.get(UVec3::new(1, 2, 3)), 100);
    assert_eq!(o.get(UVec3::new(3, 2, 1)), 0);
    assert_eq!(o.set(UVec3::new(1, 2, 3), 0), 100);
    assert!(o.is_empty());
    assert!(StretchOverrides::from_sorted(vec![(5, 1), (5, 2)]).is_err());
    assert!(StretchOverrides::from_sorted(vec![(5, 1), (4, 2)]).is_err());
    assert!(StretchOverrides::from_sorted(vec![(5, 0)]).is_err());
}

#[test]
fn enhancement_links_and_tree_parameters_round_trip_and_old_files_load() {
    use crate::enhance::{EnhanceSettings, Method};
    use crate::scene::{EnhancementLink, TreeBuilderLink};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("links.thicket.json");
    let mut doc = krs_doc();
    // Validation does not look at the objects' kinds (a link to a deleted object is ignored).
    let voxels = [doc.objects[0].id, doc.objects[1].id];
    let tree = doc.object_by_name("Tree").unwrap().id;
    let mut params = crate::krs::TreeParams::default();
    params.widths[0] *= 1.25;
    doc.enhancements.push(EnhancementLink {
        source: voxels[0],
        target: voxels[1],
        settings: EnhanceSettings {
            method: Method::Resample,
            factor: 3,
            ..EnhanceSettings::default()
        },
    });
    doc.tree_builders.push(TreeBuilderLink {
        object: tree,
        params: params.clone(),
    });
    save(&doc, &path).unwrap();
    let back = load(&path).unwrap();
    assert_eq!(back, doc);
    assert_eq!(back.enhancement_of(voxels[0]).unwrap().settings.factor, 3);
    assert_eq!(back.enhancement_into(voxels[1]).unwrap().source, voxels[0]);
    assert_eq!(back.tree_params_of(tree), Some(&params));

    // A file written before the fields existed loads with none; one without links writes none.
    let mut json: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    let obj = json.as_object_mut().unwrap();
    obj.remove("enhancements");
    obj.remove("tree_builders");
    fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let old = load(&path).unwrap();
    assert!(old.enhancements.is_empty() && old.tree_builders.is_empty());
    save(&old, &path).unwrap();
    let text = fs::read_to_string(&path).unwrap();
    assert!(!text.contains("enhancements") && !text.contains("tree_builders"));

    // Bad settings are refused naming the link and the field.
    let mut bad = doc.clone();
    bad.enhancements[0].settings.method = Method::Subdivide;
    save(&doc, &path).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    json["enhancements"][0]["settings"]["method"] = "subdivide".into();
    fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let e = load(&path).unwrap_err().to_string();
    assert!(
        e.contains("enhancement of object id") && e.contains("factor"),
        "{e}"
    );
    assert!(bad.validate().is_err());
    let mut json: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    json["enhancements"][0]["settings"]["method"] = "resample".into();
    json["tree_builders"][0]["params"]["route"] = serde_json::json!([[0.0, 0.0, 0.0]]);
    fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let e = load(&path).unwrap_err().to_string();
    assert!(
        e.contains("tree_builders") && e.contains("KRS object id"),
        "{e}"
    );
}

#[test]
fn the_sample_projects_load_and_round_trip_through_the_new_save() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects");
    let mut loaded = 0;
    for entry in fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if !path.to_string_lossy().ends_with(".thicket.json") {
            continue;
        }
        let doc = load(&path).unwrap_or_else(|e| panic!("{e}"));
        loaded += 1;
        // Small ones also go through a save (new naming) and back.
        if fs::metadata(bin_path_for(&path)).map_or(0, |m| m.len()) < 1 << 20 {
            let tmp = tempfile::tempdir().unwrap();
            let copy = tmp.path().join(path.file_name().unwrap());
            save(&doc, &copy).unwrap();
            assert_eq!(load(&copy).unwrap(), doc, "{}", path.display());
        }
    }
    assert!(loaded >= 5, "only {loaded} sample projects found");
}

/// A saved one-object project's JSON with `n` copies of the object, all pointing at its one
/// payload; `same_id` keeps the copies' id.
fn amplified(n: usize, same_id: bool) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("amp.thicket.json");
    let mut doc = Document::default();
    doc.add("Model", sample_doc(5, false).objects[0].kind.clone());
    save(&doc, &path).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    let object = json["objects"][0].clone();
    let payload = json["payloads"][0].clone();
    let (mut objects, mut payloads) = (Vec::new(), Vec::new());
    for i in 0..n {
        let id = if same_id { 1 } else { 1000 + i as u64 };
        let mut o = object.clone();
        o["id"] = id.into();
        objects.push(o);
        let mut p = payload.clone();
        p["object_id"] = id.into();
        payloads.push(p);
    }
    json["objects"] = objects.into();
    json["payloads"] = payloads.into();
    fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    (dir, path)
}

#[test]
fn objects_sharing_one_payload_are_refused_before_decoding() {
    let (dir, path) = amplified(1000, false);
    let input: u64 = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().metadata().unwrap().len())
        .sum();
    let (result, peak) = crate::io::fuzz::peak_heap_bytes(|| load(&path));
    let e = result.unwrap_err().to_string();
    assert!(
        e.contains("overlap") && e.contains("amp.thicket.json"),
        "{e}"
    );
    // The project's own rule: peak memory ≤ 64 × input + 16 MiB.
    assert!(peak < 64 * input + (16 << 20), "{peak} bytes for {input}");
    // Repeated ids are refused before any payload is read.
    let (_d, path) = amplified(1000, true);
    let (result, peak) = crate::io::fuzz::peak_heap_bytes(|| load(&path));
    let e = result.unwrap_err().to_string();
    assert!(e.contains("both have id 1"), "{e}");
    assert!(peak < 64 * input + (16 << 20), "{peak} bytes for {input}");
    // One copy is fine.
    let (_d, path) = amplified(1, false);
    assert_eq!(load(&path).unwrap().objects.len(), 1);
}

#[cfg(unix)]
#[test]
fn a_bin_reached_through_a_link_out_of_the_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let inner = dir.path().join("inner");
    fs::create_dir(&inner).unwrap();
    let path = inner.join("l.thicket.json");
    save(&sample_doc(9, false), &path).unwrap();
    let bin = bin_path_for(&path);
    let outside = dir.path().join("elsewhere.bin");
    fs::rename(&bin, &outside).unwrap();
    std::os::unix::fs::symlink(&outside, &bin).unwrap();
    let e = load(&path).unwrap_err().to_string();
    assert!(
        e.contains("symbolic link") && e.contains("l.thicket.json"),
        "{e}"
    );
}

/// The project loader fed structurally mutated object graphs: objects duplicated (same or new
/// ids), payload entries duplicated, pointed at other objects' payloads or at overlapping
/// ranges, on top of the byte mutations of `mutated_project_files_never_panic`. No case may
/// panic or hold more than the project's memory rule (64 × input + 16 MiB).
#[test]
fn structurally_mutated_projects_never_panic_or_amplify() {
    let doc = sample_doc(12, true);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("g.thicket.json");
    save(&doc, &path).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    let bin = fs::read(bin_path_for(&path)).unwrap();
    let cases = crate::io::fuzz::cases_from_env(10_000);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(0x6A4F);
    let (mut accepted, mut refused, mut max_peak, mut max_input) = (0u64, 0u64, 0u64, 0u64);
    let mut panics = Vec::new();
    let mut slowest = std::time::Duration::ZERO;
    let start = std::time::Instant::now();
    for case in 0..cases {
        let mut j = json.clone();
        for _ in 0..rng.random_range(1..4) {
            let objects = j["objects"].as_array().unwrap().clone();
            let payloads = j["payloads"].as_array().unwrap().clone();
            match rng.random_range(0..5) {
                0 if !objects.is_empty() => {
                    // Many copies of one object, with fresh or repeated ids.
                    let o = objects[rng.random_range(0..objects.len())].clone();
                    let same = rng.random_bool(0.5);
                    let mut all = objects.clone();
                    let mut ps = payloads.clone();
                    for k in 0..rng.random_range(1..300u64) {
                        let mut c = o.clone();
                        if !same {
                            c["id"] = (5000 + k).into();
                            for p in payloads.iter().filter(|p| p["object_id"] == o["id"]) {
                                let mut p = p.clone();
                                p["object_id"] = (5000 + k).into();
                                ps.push(p);
                            }
                        }
                        all.push(c);
                    }
                    j["objects"] = all.into();
                    j["payloads"] = ps.into();
                }
                1 if !payloads.is_empty() => {
                    // One payload entry duplicated.
                    let mut ps = payloads.clone();
                    ps.push(payloads[rng.random_range(0..payloads.len())].clone());
                    j["payloads"] = ps.into();
                }
                2 if payloads.len() > 1 => {
                    // One object pointed at another's bytes.
                    let (a, b) = (
                        rng.random_range(0..payloads.len()),
                        rng.random_range(0..payloads.len()),
                    );
                    j["payloads"][a]["offset"] = payloads[b]["offset"].clone();
                    j["payloads"][a]["length"] = payloads[b]["length"].clone();
                    j["payloads"][a]["crc32"] = payloads[b]["crc32"].clone();
                }
                3 if !payloads.is_empty() => {
                    // A range shifted or stretched.
                    let a = rng.random_range(0..payloads.len());
                    let off = payloads[a]["offset"].as_u64().unwrap();
                    j["payloads"][a]["offset"] =
                        off.saturating_add_signed(rng.random_range(-64..64)).into();
                }
                _ => {
                    // An object dropped.
                    let mut all = objects.clone();
                    if !all.is_empty() {
                        all.remove(rng.random_range(0..all.len()));
                    }
                    j["objects"] = all.into();
                }
            }
        }
        let text = serde_json::to_vec(&j).unwrap();
        let input = (text.len() + bin.len()) as u64;
        max_input = max_input.max(input);
        let began = std::time::Instant::now();
        let (outcome, peak) = crate::io::fuzz::peak_heap_bytes(|| {
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                load_from_parts(&path, &text, |_| Ok(bin.clone())).is_ok()
            }))
        });
        assert!(
            peak < 64 * input + (16 << 20),
            "case {case}: {peak} bytes for {input} bytes of input"
        );
        max_peak = max_peak.max(peak);
        slowest = slowest.max(began.elapsed());
        match outcome {
            Ok(true) => accepted += 1,
            Ok(false) => refused += 1,
            Err(_) => panics.push(case),
        }
    }
    eprintln!(
        "project graph fuzz: {cases} cases: {accepted} accepted, {refused} refused, {} panics, \
         max peak heap {max_peak} bytes (largest input {max_input}), slowest case {:.3} s, \
         {:.1} s",
        panics.len(),
        slowest.as_secs_f64(),
        start.elapsed().as_secs_f64()
    );
    assert!(
        panics.is_empty(),
        "cases panicked: {:?}",
        &panics[..panics.len().min(10)]
    );
    assert!(
        accepted > 0 && refused > cases / 10,
        "{accepted} accepted, {refused} refused"
    );
}

/// A document with one frame sequence of three frames (1, 2 and 3 voxels, different origins),
/// showing frame 1.
fn frames_doc() -> Document {
    use crate::scene::{FrameSequence, VoxelFrame};
    let frame = |n: u32, origin: Vec3| VoxelFrame {
        svo: Svo::from_voxels(
            2,
            false,
            (0..n).map(|x| {
                (
                    UVec3::new(x, 0, 0),
                    Voxel::new([10 * x as u8, 200, 30, 255], Vec3::Y),
                )
            }),
        )
        .unwrap(),
        origin,
    };
    let mut model = VoxelModel {
        svo: frame(1, Vec3::ZERO).svo,
        frames: Some(FrameSequence {
            frame_secs: 0.125,
            frames: vec![
                VoxelFrame::default(),
                frame(2, Vec3::new(1.0, 0.0, 0.0)),
                frame(3, Vec3::new(0.0, -2.0, 0.0)),
            ],
            ..FrameSequence::default()
        }),
        ..VoxelModel::default()
    };
    assert!(model.set_frame_time(0.2));
    let mut doc = Document::default();
    doc.add("walk", ObjectKind::Voxels(model));
    doc
}

#[test]
fn frame_sequences_save_and_load_with_every_frame() {
    let doc = frames_doc();
    doc.validate().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("anim.thicket.json");
    save(&doc, &path).unwrap();
    let text = fs::read_to_string(&path).unwrap();
    assert!(
        text.contains(&format!("\"format_version\": {FORMAT_VERSION}")),
        "{text}"
    );
    assert!(text.contains("\"part\": \"frames\""), "{text}");
    let back = load(&path).unwrap();
    assert_eq!(back, doc);
    let ObjectKind::Voxels(v) = &back.objects[0].kind else {
        panic!("voxels")
    };
    let seq = v.frames.as_ref().unwrap();
    assert_eq!((seq.shown, seq.frame_secs, v.frame_count()), (1, 0.125, 3));
    let counts: Vec<u64> = (0..3).map(|i| v.frame(i).unwrap().0.leaf_count()).collect();
    assert_eq!(counts, [1, 2, 3]);
    assert_eq!(v.frame(2).unwrap().1, Vec3::new(0.0, -2.0, 0.0));

    // A JSON that names frames but has no frames payload is refused by name.
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["payloads"]
        .as_array_mut()
        .unwrap()
        .retain(|p| p["part"] != "frames");
    fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let e = load(&path).unwrap_err().to_string();
    assert!(
        e.contains("\"walk\"") && e.contains("no frames payload"),
        "{e}"
    );
}

#[test]
fn version_1_projects_load_and_save_as_the_current_version() {
    // A version-1 file is a current file without frames (its payloads SVO1, which still load):
    // set the version back and load it.
    let doc = sample_doc(3, false);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.thicket.json");
    save(&doc, &path).unwrap();
    let text = fs::read_to_string(&path).unwrap();
    let old = text.replace(
        &format!("\"format_version\": {FORMAT_VERSION}"),
        "\"format_version\": 1",
    );
    assert_ne!(old, text);
    fs::write(&path, &old).unwrap();
    let loaded = load(&path).unwrap();
    // Migrated on load: the document in memory is the current version.
    assert_eq!(loaded.format_version, FORMAT_VERSION);
    assert!(loaded.objects.iter().all(|o| match &o.kind {
        ObjectKind::Voxels(v) => v.frames.is_none(),
        _ => true,
    }));
    assert_eq!(loaded, doc);
    save(&loaded, &path).unwrap();
    assert!(
        fs::read_to_string(&path)
            .unwrap()
            .contains(&format!("\"format_version\": {FORMAT_VERSION}"))
    );
}

#[test]
fn broken_frame_sequences_do_not_validate() {
    let base = frames_doc();
    let edit = |f: &dyn Fn(&mut VoxelModel)| {
        let mut d = base.clone();
        if let ObjectKind::Voxels(v) = &mut d.objects[0].kind {
            f(v);
        }
        d.validate().unwrap_err().to_string()
    };
    let e = edit(&|v| v.frames.as_mut().unwrap().frame_secs = 0.0);
    assert!(e.contains("frame_secs"), "{e}");
    let e = edit(&|v| v.frames.as_mut().unwrap().shown = 7);
    assert!(e.contains("frame 7 of 3"), "{e}");
    let e = edit(&|v| {
        let seq = v.frames.as_mut().unwrap();
        seq.frames[seq.shown].svo = v.svo.clone();
    });
    assert!(e.contains("slot must be empty"), "{e}");
    let e = edit(&|v| v.frames.as_mut().unwrap().frames.clear());
    assert!(e.contains("at least one frame"), "{e}");
    let e = edit(&|v| v.rig = Some(crate::skin::Rig::default()));
    assert!(
        e.contains("skinned model cannot also be a frame sequence"),
        "{e}"
    );
}

#[test]
fn mutated_frame_payloads_never_panic() {
    let doc = frames_doc();
    let mut bin = Vec::new();
    let ObjectKind::Voxels(v) = &doc.objects[0].kind else {
        panic!("voxels")
    };
    encode_frames(v.frames.as_ref().unwrap(), &mut bin);
    assert_eq!(
        decode_frames(&bin).unwrap(),
        v.frames.as_ref().unwrap().frames
    );
    let mut rng = rand_pcg::Pcg64::seed_from_u64(23);
    let cases = crate::io::fuzz::cases_from_env(10_000);
    let (mut ok, mut refused) = (0u64, 0u64);
    let mut slowest = std::time::Duration::ZERO;
    for _ in 0..cases {
        let mut b = bin.clone();
        match rng.random_range(0..3) {
            0 => {
                for _ in 0..rng.random_range(1..4) {
                    let i = rng.random_range(0..b.len());
                    b[i] ^= 1 << rng.random_range(0..8);
                }
            }
            1 => b.truncate(rng.random_range(0..b.len())),
            _ => {
                let i = rng.random_range(0..b.len() - 4);
                b[i..i + 4].fill(0xff);
            }
        }
        let began = std::time::Instant::now();
        let (result, peak) = crate::io::fuzz::peak_heap_bytes(|| {
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| decode_frames(&b).is_ok()))
        });
        slowest = slowest.max(began.elapsed());
        assert!(peak < 1 << 20, "a case held {peak} bytes");
        match result {
            Ok(true) => ok += 1,
            Ok(false) => refused += 1,
            Err(_) => panic!("decode_frames panicked"),
        }
    }
    eprintln!(
        "frames fuzz: {cases} cases: {ok} decoded, {refused} refused, slowest case {:.3} s",
        slowest.as_secs_f64()
    );
    assert!(refused > cases / 2 && ok > 0, "ok {ok}, refused {refused}");
}

/// The load estimate is above the measured peak heap of loading every sample with a `.bin`
/// or KRS content, and not so far above that it refuses projects that would fit (at most
/// twice the peak plus 1 MiB); a budget below the estimate refuses the load before the `.bin`
/// is read, naming the file and the limit.
#[test]
fn the_load_estimate_covers_the_samples() {
    let dir = std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../projects"));
    let (mut checked, mut large) = (0, 0);
    for name in [
        "cesiumman",
        "critter",
        "house",
        "mixed",
        "terrain",
        "tree",
        "woodland",
    ] {
        let path = dir.join(format!("{name}.thicket.json"));
        let json = fs::metadata(&path).unwrap().len();
        let bin: u64 = fs::read_dir(&dir)
            .unwrap()
            .filter_map(Result::ok)
            .filter(|e| {
                let n = e.file_name().to_string_lossy().into_owned();
                n.starts_with(&format!("{name}.thicket.")) && n.ends_with(".bin")
            })
            .map(|e| e.metadata().unwrap().len())
            .sum();
        let (doc, peak) = crate::io::fuzz::peak_heap_bytes(|| load(&path).unwrap());
        drop(doc);
        let estimate = estimate_load_bytes(json, bin);
        assert!(
            estimate >= peak,
            "{name}: estimate {estimate} < peak {peak}"
        );
        assert!(
            estimate <= 2 * peak + (1 << 20),
            "{name}: estimate {estimate} is far above the peak {peak}"
        );
        checked += 1;
        if bin > 0 {
            // Refused between the JSON and the .bin: the JSON fits, the whole does not.
            let budget = crate::budget::MemoryBudget::given(estimate_load_bytes(json, 0) + 1);
            let (result, refused_peak) =
                crate::io::fuzz::peak_heap_bytes(|| load_within(&path, &budget));
            let e = result.unwrap_err().to_string();
            assert!(
                e.contains(&format!("{name}.thicket.json")) && e.contains("memory"),
                "{e}"
            );
            // The JSON was parsed, the .bin never read: for the large payloads (cesiumman,
            // house, terrain) that is less than half the .bin.
            if bin > 1 << 20 {
                large += 1;
                assert!(refused_peak < bin / 2, "{name}: {refused_peak} bytes held");
            }
        }
        // The same sample saved by this build (tiled payloads, a smaller `.bin` for the house):
        // the estimate still covers what loading it takes.
        let doc = load(&path).unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let saved = tmp.path().join(format!("{name}.thicket.json"));
        save(&doc, &saved).unwrap();
        drop(doc);
        let had_bin = bin > 0;
        let json = fs::metadata(&saved).unwrap().len();
        let bin = fs::metadata(bin_path_for(&saved)).map_or(0, |m| m.len());
        assert_eq!(
            bin > 0,
            had_bin,
            "{name}: a payload saved where there was one"
        );
        let (doc, peak) = crate::io::fuzz::peak_heap_bytes(|| load(&saved).unwrap());
        drop(doc);
        let estimate = estimate_load_bytes(json, bin);
        assert!(
            estimate >= peak,
            "{name} as saved now: estimate {estimate} < peak {peak}"
        );
    }
    assert_eq!((checked, large), (7, 3));
}

#[test]
fn a_solid_with_an_interior_round_trips_and_an_exposed_interior_is_refused() {
    let doc = crate::render::scenes::ball(crate::render::scenes::BallInside::Interior);
    let ObjectKind::Voxels(model) = &doc.objects[0].kind else {
        unreachable!("the ball is voxels")
    };
    let svo = &model.svo;
    assert!(svo.may_have_interior() && svo.exposed_interior().is_none());
    let mut bytes = Vec::new();
    encode_svo(svo, &mut bytes);
    let back = decode_svo(&bytes).unwrap();
    assert_eq!(&back, svo);
    assert_eq!(back.tile_count(), svo.tile_count());
    assert!(back.tile_count() > 20);
    let expect = |svo: &Svo, needle: &str| {
        let mut bytes = Vec::new();
        encode_svo(svo, &mut bytes);
        let e = decode_svo(&bytes).unwrap_err();
        assert!(e.contains(needle), "{e}");
    };
    // One interior voxel alone, and one on the octree's boundary inside a full block.
    let lone = Svo::from_voxels(3, false, [(UVec3::new(3, 4, 5), Voxel::INTERIOR)]).unwrap();
    expect(
        &lone,
        "interior voxel (3, 4, 5) has an empty face neighbour",
    );
    let edge = Svo::from_voxels(
        2,
        false,
        (0..64u32).map(|i| {
            let c = UVec3::new(i % 4, i / 4 % 4, i / 16);
            let v = if c == UVec3::ZERO {
                Voxel::INTERIOR
            } else {
                Voxel::new([9, 9, 9, 255], Vec3::X)
            };
            (c, v)
        }),
    )
    .unwrap();
    expect(&edge, "interior voxel (0, 0, 0)");
    // A colour with the interior mark's normal code.
    let odd = Voxel {
        color: [1, 2, 3, 255],
        ..Voxel::INTERIOR
    };
    let mut bytes = Vec::new();
    encode_svo(
        &Svo::from_voxels(3, false, [(UVec3::ONE, odd)]).unwrap(),
        &mut bytes,
    );
    let e = decode_svo(&bytes).unwrap_err();
    assert!(e.contains("interior mark's normal code"), "{e}");
    // Written before the mark (SVO2): the code is the −Z normal it decodes to, even with no
    // colour, and an exposed voxel with it is an ordinary voxel.
    for color in [[1, 2, 3, 255], [0; 4]] {
        let v = Voxel {
            color,
            ..Voxel::INTERIOR
        };
        let mut bytes = Vec::new();
        encode_svo(
            &Svo::from_voxels(3, false, [(UVec3::ONE, v)]).unwrap(),
            &mut bytes,
        );
        bytes[..4].copy_from_slice(b"SVO2");
        let back = decode_svo(&bytes).unwrap();
        let got = back.get(UVec3::ONE).unwrap();
        assert_eq!(got.normal, 0xffff);
        assert_eq!(got.color, color);
        assert!(!got.is_interior() && !back.may_have_interior());
        assert_eq!(got.normal_vec(), Vec3::NEG_Z);
    }
}

//! Instancing on export: a model placed several times is written once.

use std::path::{Path, PathBuf};

use super::chunks::{write_chunk, write_dict};
use super::import::world_cells;
use super::*;
use crate::scene::Object;

fn asset(rel: &str) -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/vox/"
    ))
    .join(rel)
}

/// Chunk ids under MAIN, in file order.
pub(super) fn chunk_ids(bytes: &[u8]) -> Vec<String> {
    let mut out = Vec::new();
    let mut pos = 20;
    while pos + 12 <= bytes.len() {
        out.push(String::from_utf8_lossy(&bytes[pos..pos + 4]).into_owned());
        let n = u32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize;
        let m = u32::from_le_bytes(bytes[pos + 8..pos + 12].try_into().unwrap()) as usize;
        pos += 12 + n + m;
    }
    out
}

pub(super) fn count(ids: &[String], id: &str) -> usize {
    ids.iter().filter(|i| *i == id).count()
}

/// Every voxel of the visible objects in Y-up world cells with its colour, sorted.
pub(super) fn world_set(objects: &[Object]) -> Vec<([i64; 3], [u8; 4])> {
    let mut out: Vec<([i64; 3], [u8; 4])> = objects
        .iter()
        .filter(|o| o.visible)
        .flat_map(|o| world_cells(o).into_iter().map(|(c, v)| (c, v.color)))
        .collect();
    out.sort_unstable();
    out
}

/// `VOX ` 150 with MAIN holding `main`.
pub(super) fn wrap_main(main: &[u8]) -> Vec<u8> {
    let mut out = b"VOX ".to_vec();
    out.extend_from_slice(&150u32.to_le_bytes());
    out.extend_from_slice(b"MAIN");
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(main.len() as u32).to_le_bytes());
    out.extend_from_slice(main);
    out
}

/// A SIZE + XYZI pair.
pub(super) fn model_chunks(out: &mut Vec<u8>, size: [u32; 3], voxels: &[[u8; 4]]) {
    let mut s = Vec::new();
    for e in size {
        s.extend_from_slice(&e.to_le_bytes());
    }
    write_chunk(out, b"SIZE", &s);
    let mut xyzi = (voxels.len() as u32).to_le_bytes().to_vec();
    for v in voxels {
        xyzi.extend_from_slice(v);
    }
    write_chunk(out, b"XYZI", &xyzi);
}

/// An nTRN with the given frame dictionaries.
pub(super) fn transform(out: &mut Vec<u8>, id: u32, child: u32, frames: &[&[(&str, &str)]]) {
    let mut c = id.to_le_bytes().to_vec();
    write_dict(&mut c, &[]);
    c.extend_from_slice(&child.to_le_bytes());
    c.extend_from_slice(&u32::MAX.to_le_bytes());
    c.extend_from_slice(&0u32.to_le_bytes());
    c.extend_from_slice(&(frames.len() as u32).to_le_bytes());
    for f in frames {
        write_dict(&mut c, f);
    }
    write_chunk(out, b"nTRN", &c);
}

pub(super) fn group(out: &mut Vec<u8>, id: u32, children: &[u32]) {
    let mut c = id.to_le_bytes().to_vec();
    write_dict(&mut c, &[]);
    c.extend_from_slice(&(children.len() as u32).to_le_bytes());
    for ch in children {
        c.extend_from_slice(&ch.to_le_bytes());
    }
    write_chunk(out, b"nGRP", &c);
}

/// An nSHP listing `(model, attributes)`.
pub(super) fn shape(out: &mut Vec<u8>, id: u32, models: &[(u32, &[(&str, &str)])]) {
    let mut c = id.to_le_bytes().to_vec();
    write_dict(&mut c, &[]);
    c.extend_from_slice(&(models.len() as u32).to_le_bytes());
    for (m, attrs) in models {
        c.extend_from_slice(&m.to_le_bytes());
        write_dict(&mut c, attrs);
    }
    write_chunk(out, b"nSHP", &c);
}

fn import(bytes: &[u8]) -> VoxScene {
    import_vox_bytes(bytes, Path::new("mem.vox"), &VoxImportOptions::default()).unwrap()
}

fn export(objects: &[Object]) -> (Vec<u8>, VoxExportReport) {
    export_vox_bytes(objects, Path::new("out.vox"), &VoxExportOptions::default()).unwrap()
}

#[test]
fn a_model_placed_three_times_is_written_once() {
    // An L of 4 voxels in 3 colours (no symmetry), placed twice unturned and once turned 90°
    // about Z and mirrored in X.
    let mut main = Vec::new();
    model_chunks(
        &mut main,
        [3, 2, 2],
        &[[0, 0, 0, 1], [1, 0, 0, 2], [2, 0, 0, 2], [0, 1, 1, 3]],
    );
    transform(&mut main, 0, 1, &[&[]]);
    group(&mut main, 1, &[2, 4, 6]);
    transform(&mut main, 2, 3, &[&[("_t", "0 0 0")]]);
    shape(&mut main, 3, &[(0, &[])]);
    transform(&mut main, 4, 5, &[&[("_t", "10 -4 7")]]);
    shape(&mut main, 5, &[(0, &[])]);
    // Rows [0,-1,0], [1,0,0], [0,0,-1]: columns 1, 0; signs of rows 0 and 2.
    let r = (1 | (1 << 4) | (1 << 6)).to_string();
    transform(&mut main, 6, 7, &[&[("_t", "-20 3 1"), ("_r", &r)]]);
    shape(&mut main, 7, &[(0, &[])]);
    let file = wrap_main(&main);
    let first = import(&file);
    assert_eq!(first.objects.len(), 3);
    assert_eq!(first.model_count, 1);

    let (bytes, report) = export(&first.objects);
    let ids = chunk_ids(&bytes);
    assert_eq!(count(&ids, "XYZI"), 1, "{ids:?}");
    assert_eq!(count(&ids, "nSHP"), 3, "{ids:?}");
    assert_eq!(
        (report.models, report.placements, report.voxels),
        (1, 3, 12)
    );
    let second = import(&bytes);
    assert_eq!(second.model_count, 1);
    assert_eq!(second.stored_voxels, 4);
    assert_eq!(second.voxel_count(), 12);
    assert_eq!(world_set(&second.objects), world_set(&first.objects));
}

/// Distinct shapes among `models` (`[x, y, z, index]` each) under the 48 grid rotations, by
/// brute force: each model turned every way, normalised and compared with every earlier one.
fn distinct_under_rotation(models: &[Vec<[u8; 4]>]) -> usize {
    let turned = |m: &[[u8; 4]], byte: u8| -> Vec<[u8; 4]> {
        let r = decode_rotation(byte).unwrap();
        let pts: Vec<([i64; 3], u8)> = m
            .iter()
            .map(|v| (imat_apply(&r, [0, 1, 2].map(|a| i64::from(v[a]))), v[3]))
            .collect();
        let min = pts.iter().fold([i64::MAX; 3], |acc, (p, _)| {
            [0, 1, 2].map(|a| acc[a].min(p[a]))
        });
        let mut out: Vec<[u8; 4]> = pts
            .iter()
            .map(|(p, i)| [0, 1, 2, 3].map(|a| if a == 3 { *i } else { (p[a] - min[a]) as u8 }))
            .collect();
        out.sort_unstable();
        out
    };
    let rotations: Vec<u8> = (0u8..128)
        .filter(|&b| decode_rotation(b).is_some())
        .collect();
    assert_eq!(rotations.len(), 48);
    let mut kept: Vec<Vec<[u8; 4]>> = Vec::new();
    for m in models {
        let forms: Vec<Vec<[u8; 4]>> = rotations.iter().map(|&b| turned(m, b)).collect();
        if !kept.iter().any(|k| forms.contains(k)) {
            kept.push(turned(m, 4));
        }
    }
    kept.len()
}

#[test]
fn the_corpus_scene_is_written_with_each_shape_once() {
    let path = asset("opengametools/test_multiple_model_scene.vox");
    let first = import_vox(&path).unwrap();
    assert_eq!((first.model_count, first.objects.len()), (41, 104));
    assert_eq!(first.stored_voxels, 6_053);
    // The file itself stores some shapes twice (turned or mirrored copies): its 41 models hold
    // 35 distinct shapes, counted here straight from dot_vox.
    let raw = dot_vox::load(path.to_str().unwrap()).unwrap();
    let models: Vec<Vec<[u8; 4]>> = raw
        .models
        .iter()
        .map(|m| m.voxels.iter().map(|v| [v.x, v.y, v.z, v.i]).collect())
        .collect();
    assert_eq!(distinct_under_rotation(&models), 35);

    let (bytes, report) = export(&first.objects);
    let ids = chunk_ids(&bytes);
    let visible = first.objects.iter().filter(|o| o.visible).count();
    assert_eq!(count(&ids, "XYZI"), 35, "{report:?}");
    assert_eq!(count(&ids, "nSHP"), visible);
    assert_eq!((report.models, report.placements), (35, visible));
    assert_eq!(report.voxels, first.voxel_count());
    let second = import(&bytes);
    assert_eq!(second.model_count, 35);
    assert_eq!(second.objects.len(), visible);
    assert_eq!(second.voxel_count(), first.voxel_count());
    assert_eq!(world_set(&second.objects), world_set(&first.objects));
    // Exporting the re-import writes the same models again (nothing drifts).
    let (again, report2) = export(&second.objects);
    assert_eq!(report2.models, 35);
    assert_eq!(import(&again).stored_voxels, second.stored_voxels);
}

#[test]
fn distinct_and_mirror_image_models_stay_apart_where_they_differ() {
    // Two models with the same voxel count, edges and colours but different shapes are two
    // models; a colour change makes a copy a model of its own too.
    let mut main = Vec::new();
    model_chunks(&mut main, [2, 2, 1], &[[0, 0, 0, 1], [1, 1, 0, 1]]);
    model_chunks(&mut main, [2, 2, 1], &[[0, 0, 0, 1], [1, 0, 0, 1]]);
    model_chunks(&mut main, [2, 2, 1], &[[0, 0, 0, 2], [1, 1, 0, 1]]);
    transform(&mut main, 0, 1, &[&[]]);
    group(&mut main, 1, &[2, 4, 6]);
    transform(&mut main, 2, 3, &[&[("_t", "0 0 0")]]);
    shape(&mut main, 3, &[(0, &[])]);
    transform(&mut main, 4, 5, &[&[("_t", "5 0 0")]]);
    shape(&mut main, 5, &[(1, &[])]);
    transform(&mut main, 6, 7, &[&[("_t", "9 0 0")]]);
    shape(&mut main, 7, &[(2, &[])]);
    let first = import(&wrap_main(&main));
    let (bytes, report) = export(&first.objects);
    assert_eq!(report.models, 3);
    assert_eq!(
        world_set(&import(&bytes).objects),
        world_set(&first.objects)
    );
}

#[test]
fn corpus_files_keep_their_model_counts() {
    // (file, models, stored voxels, placements): unchanged by import → export → import.
    for (rel, models, stored, placed) in [
        ("dot_vox/axes.vox", 4, 4_372, 10),
        ("mmmm/obj_house4.vox", 1, 180_202, 1),
        ("mmmm/chr_army1.vox", 1, 341, 1),
        ("dot_vox/placeholder.vox", 1, 4, 1),
        ("dot_vox/metal-material.vox", 1, 20, 1),
    ] {
        let first = import_vox(&asset(rel)).unwrap();
        assert_eq!(
            (first.model_count, first.stored_voxels, first.objects.len()),
            (models, stored, placed),
            "{rel}"
        );
        let (bytes, report) = export(&first.objects);
        assert_eq!(
            (report.models, report.placements),
            (models, placed),
            "{rel}"
        );
        let second = import(&bytes);
        assert_eq!(
            (
                second.model_count,
                second.stored_voxels,
                second.objects.len()
            ),
            (models, stored, placed),
            "{rel}"
        );
        assert_eq!(
            world_set(&second.objects),
            world_set(&first.objects),
            "{rel}"
        );
    }
}

#[test]
fn many_similar_shapes_are_told_apart_and_copies_found() {
    use glam::{UVec3, Vec3};
    use rand::{Rng, SeedableRng};

    use crate::scene::{ObjectKind, Transform, VoxelModel};
    use crate::svo::{Svo, Voxel};
    // 120 random 12-voxel shapes in one colour (same count, often the same edges), each placed
    // once as drawn and once mirrored in x: 120 distinct shapes (barring symmetric draws,
    // counted by brute force), 240 placements.
    let mut rng = rand_pcg::Pcg64::seed_from_u64(6);
    let mut objects = Vec::new();
    let mut shapes: Vec<Vec<[u8; 4]>> = Vec::new();
    for k in 0..120u32 {
        let mut cells: Vec<[u8; 3]> = Vec::new();
        while cells.len() < 12 {
            let c = [0, 1, 2].map(|_| rng.random_range(0..4u8));
            if !cells.contains(&c) {
                cells.push(c);
            }
        }
        shapes.push(cells.iter().map(|c| [c[0], c[1], c[2], 1]).collect());
        for mirrored in [false, true] {
            let voxels = cells.iter().map(|c| {
                let x = if mirrored { 3 - c[0] } else { c[0] };
                (
                    UVec3::new(u32::from(x), u32::from(c[1]), u32::from(c[2])),
                    Voxel::new([90, 160, 220, 255], Vec3::Y),
                )
            });
            objects.push(Object {
                id: u64::from(2 * k) + u64::from(mirrored) + 1,
                name: format!("shape {k}{}", if mirrored { " mirrored" } else { "" }),
                transform: Transform {
                    translation: Vec3::new(10.0 * k as f32, 0.0, if mirrored { 10.0 } else { 0.0 }),
                    ..Transform::default()
                },
                kind: ObjectKind::Voxels(VoxelModel {
                    svo: Svo::from_voxels(2, false, voxels).unwrap(),
                    ..VoxelModel::default()
                }),
                ..Object::default()
            });
        }
    }
    // Through the axis change the shapes stay the same up to a turn, so the file holds as
    // many models as there are distinct shapes.
    let distinct = distinct_under_rotation(&shapes);
    let (bytes, report) = export(&objects);
    assert_eq!((report.models, report.placements), (distinct, 240));
    let back = import(&bytes);
    assert_eq!(back.model_count, distinct);
    assert_eq!(world_set(&back.objects), world_set(&objects));
}

/// A file of a few kilobytes whose scene graph places one 16³ model 4,096 times (two levels of
/// 64 transforms sharing their child) would become 16.8 M voxels: the import estimates that
/// from the graph and refuses it under its memory budget before building any model, holding
/// little more than the file; with a budget that fits, the same file imports every copy.
#[test]
fn a_scene_graph_that_multiplies_a_model_is_refused_before_building() {
    let full: Vec<[u8; 4]> = (0..16u8)
        .flat_map(|x| (0..16u8).flat_map(move |y| (0..16u8).map(move |z| [x, y, z, 1])))
        .collect();
    let mut main = Vec::new();
    model_chunks(&mut main, [16, 16, 16], &full);
    transform(&mut main, 0, 1, &[&[]]);
    let outer: Vec<u32> = (2..66).collect();
    group(&mut main, 1, &outer);
    for (k, id) in outer.iter().enumerate() {
        let t = format!("{} 0 0", 32 * k);
        transform(&mut main, *id, 66, &[&[("_t", t.as_str())]]);
    }
    let inner: Vec<u32> = (67..131).collect();
    group(&mut main, 66, &inner);
    for (k, id) in inner.iter().enumerate() {
        let t = format!("0 {} 0", 32 * k);
        transform(&mut main, *id, 131, &[&[("_t", t.as_str())]]);
    }
    shape(&mut main, 131, &[(0, &[])]);
    let file = wrap_main(&main);
    assert!(file.len() < 40_000, "a small file: {} bytes", file.len());
    let tight = VoxImportOptions {
        memory: crate::budget::MemoryBudget::given(64 << 20),
        ..VoxImportOptions::default()
    };
    let (result, peak) =
        crate::io::fuzz::peak_heap_bytes(|| import_vox_bytes(&file, Path::new("many.vox"), &tight));
    let e = result.unwrap_err().to_string();
    assert!(
        e.starts_with("many.vox")
            && e.contains("4096 instance(s) holding 16,777,216 voxels")
            && e.contains("over the limit of 64.0 MiB"),
        "{e}"
    );
    assert!(peak < 8 << 20, "refused holding {peak} bytes");
    // A model placed 64 times (one level) fits the same budget and imports every copy.
    let mut one_level = Vec::new();
    model_chunks(&mut one_level, [16, 16, 16], &full);
    transform(&mut one_level, 0, 1, &[&[]]);
    group(&mut one_level, 1, &outer);
    for (k, id) in outer.iter().enumerate() {
        let t = format!("{} 0 0", 32 * k);
        transform(&mut one_level, *id, 66, &[&[("_t", t.as_str())]]);
    }
    shape(&mut one_level, 66, &[(0, &[])]);
    let scene = import_vox_bytes(&wrap_main(&one_level), Path::new("few.vox"), &tight).unwrap();
    assert_eq!(scene.objects.len(), 64);
}

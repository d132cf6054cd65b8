//! What tiles save on real models (issue 43): for each voxel object of the given projects and
//! MagicaVoxel files, its memory stored voxel by voxel and with tiles, the tiles and the voxels
//! they stand for, the octree payload written voxel by voxel (`SVO1`, 15 bytes a voxel, 23 with
//! skin, plus a 16-byte header) and the whole `.bin` this build saves (tiled `SVO2` payloads,
//! meshes and rigs included).
//!
//! `cargo run -p thicket-core --example tile_memory -- projects/house.thicket.json
//! ../shared/assets/vox/mmmm/obj_house4.vox …`

use std::path::Path;

use thicket_core::io::project;
use thicket_core::io::vox::import_vox;
use thicket_core::scene::{Document, ObjectKind};

fn main() {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        eprintln!("usage: tile_memory FILE.thicket.json|FILE.vox …");
        std::process::exit(2);
    }
    println!(
        "| model | voxels | tiles (voxels they stand for) | memory voxel by voxel | with tiles | \
         ratio | payload voxel by voxel | tiled payload |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for p in &paths {
        let path = Path::new(p);
        let doc = if p.ends_with(".vox") {
            match import_vox(path) {
                Ok(scene) => {
                    let mut d = Document::default();
                    scene.add_to(&mut d);
                    d
                }
                Err(e) => {
                    eprintln!("{p}: {e}");
                    continue;
                }
            }
        } else {
            match project::load(path) {
                Ok(d) => d,
                Err(e) => {
                    eprintln!("{p}: {e}");
                    continue;
                }
            }
        };
        let payload = saved_payload_bytes(&doc);
        // Summed over the file's voxel objects.
        let (mut voxels, mut tiles, mut tile_voxels) = (0u64, 0u64, 0u64);
        let (mut flat_bytes, mut tiled_bytes, mut flat_payload) = (0u64, 0u64, 0u64);
        let mut objects = 0;
        for o in &doc.objects {
            let ObjectKind::Voxels(v) = &o.kind else {
                continue;
            };
            objects += 1;
            let tiled = v.svo.memory_stats();
            let flat = v.svo.clone().without_tiles().memory_stats();
            let record = 15 + if v.svo.has_skin() { 8 } else { 0 };
            voxels += tiled.leaves;
            tiles += tiled.tiles;
            tile_voxels += tiled.tile_voxels;
            flat_bytes += flat.total_bytes;
            tiled_bytes += tiled.total_bytes;
            flat_payload += 16 + record * tiled.leaves;
        }
        let kib = |b: u64| b as f64 / 1024.0;
        println!(
            "| {} ({objects} voxel objects) | {voxels} | {tiles} ({tile_voxels}) | {:.1} KiB | {:.1} \
             KiB | {:.2} | {:.1} KiB | {} |",
            path.file_name()
                .map_or(p.clone(), |n| n.to_string_lossy().into_owned()),
            kib(flat_bytes),
            kib(tiled_bytes),
            tiled_bytes as f64 / flat_bytes.max(1) as f64,
            kib(flat_payload),
            payload.map_or("(not saved)".into(), |b| format!("{:.1} KiB", kib(b))),
        );
    }
}

/// The `.bin` size of the document saved by this build (every payload, tiled), if it saves.
fn saved_payload_bytes(doc: &Document) -> Option<u64> {
    let dir = std::env::temp_dir().join(format!("tile_memory_{}", std::process::id()));
    std::fs::create_dir_all(&dir).ok()?;
    let json = dir.join("m.thicket.json");
    project::save(doc, &json).ok()?;
    let bin = project::bin_path_for(&json);
    let bytes = std::fs::metadata(&bin).ok()?.len();
    let _ = std::fs::remove_dir_all(&dir);
    Some(bytes)
}

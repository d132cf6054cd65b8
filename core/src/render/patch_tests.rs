//! Shadow maps patched after an edit ([`ShadowCache::note_change`]): the patched map equals a
//! freshly drawn map of the edited scene texel for texel, its traversal visits fewer nodes,
//! and a chain that does not lead to the frame's content redraws whole maps.

use glam::UVec3;

use super::*;
use crate::scene::ObjectKind;

fn house() -> Document {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/house.thicket.json");
    crate::io::project::load(&path).expect("the house sample")
}

fn request(doc: &Document, quality: &Quality) -> View {
    View {
        width: 200,
        height: 160,
        camera: Some(doc.camera),
        quality: quality.clone(),
    }
}

/// Edits the first voxel object of `doc` where the light sees it, inside its own bounds (so
/// the scene's box, and with it the light's camera, stays as it was): takes two layers off
/// the top of the columns around three quarters of the way across, and stacks a block on the
/// top of the columns a quarter of the way across. Returns the edited document and the world
/// box of the edit.
fn edit(doc: &Document) -> (Document, Vec<(Vec3, Vec3)>) {
    let mut edited = doc.clone();
    let o = edited
        .objects
        .iter_mut()
        .find(|o| matches!(o.kind, ObjectKind::Voxels(_)))
        .expect("a voxel object");
    let world_from_object = o.transform.matrix();
    let ObjectKind::Voxels(v) = &mut o.kind else {
        unreachable!("found above")
    };
    let (lo, hi) = v.svo.bounds().expect("voxels");
    let sample = v.svo.leaves()[0].1;
    let top = |svo: &crate::svo::Svo, x: u32, z: u32| {
        (lo.y..=hi.y)
            .rev()
            .find(|&y| svo.get(UVec3::new(x, y, z)).is_some())
    };
    // Voxel boxes of the three parts of the edit.
    let mut parts = [(hi, lo); 3];
    let mut changed = 0;
    let (qx, qz) = (lo.x + (hi.x - lo.x) / 4, lo.z + (hi.z - lo.z) / 4);
    let (rx, rz) = (lo.x + 3 * (hi.x - lo.x) / 4, lo.z + 3 * (hi.z - lo.z) / 4);
    for dz in 0..5 {
        for dx in 0..5 {
            let (x, z) = (rx + dx, rz + dz);
            if let Some(y) = top(&v.svo, x, z) {
                for y in y.saturating_sub(1)..=y {
                    let c = UVec3::new(x, y, z);
                    changed += usize::from(v.svo.remove(c).expect("inside").is_some());
                    parts[0] = (parts[0].0.min(c), parts[0].1.max(c));
                }
            }
            let (x, z) = (qx + dx, qz + dz);
            if let Some(y) = top(&v.svo, x, z) {
                for y in y + 1..(y + 4).min(hi.y) {
                    let c = UVec3::new(x, y, z);
                    changed += usize::from(v.svo.set(c, sample).expect("inside").is_none());
                    parts[1] = (parts[1].0.min(c), parts[1].1.max(c));
                }
            }
        }
    }
    // A block floating in the air at the top corner of the bounds: at a coarse LOD it makes
    // a node appear whose splat is much wider than the block.
    for z in lo.z..lo.z + 2 {
        for y in hi.y - 1..=hi.y {
            for x in lo.x..lo.x + 2 {
                let c = UVec3::new(x, y, z);
                assert!(v.svo.get(c).is_none(), "the corner is air");
                v.svo.set(c, sample).expect("inside");
                changed += 1;
                parts[2] = (parts[2].0.min(c), parts[2].1.max(c));
            }
        }
    }
    assert!(changed > 20, "the edit changes voxels ({changed})");
    assert_eq!(v.svo.bounds(), Some((lo, hi)), "the edit keeps the bounds");
    let m = world_from_object * v.object_from_voxel();
    let boxes = parts
        .iter()
        .map(|&(a, b)| {
            let (a, b) = (
                m.transform_point3(a.as_vec3()),
                m.transform_point3((b + 1).as_vec3()),
            );
            (a.min(b), a.max(b))
        })
        .collect();
    (edited, boxes)
}

/// Notes the edit's parts as a chain of changes from content `from` to `to`.
fn note(cache: &mut ShadowCache, boxes: &[(Vec3, Vec3)], from: u64, to: u64) {
    for (i, &(lo, hi)) in boxes.iter().enumerate() {
        let step = |k: usize| match k {
            0 => from,
            k if k == boxes.len() => to,
            k => 1000 + k as u64,
        };
        cache.note_change(ContentChange {
            from: step(i),
            to: step(i + 1),
            lo,
            hi,
        });
    }
}

/// Renders `doc` twice with a fresh cache under `key`, so that it holds full maps; returns it.
fn primed(doc: &Document, req: &View, key: u64) -> ShadowCache {
    let mut cache = ShadowCache::new();
    for _ in 0..2 {
        render_document_cached(doc, req, &mut cache, key).expect("renders");
    }
    assert!(!cache.is_empty(), "the second frame keeps its maps");
    cache
}

fn map(cache: &ShadowCache) -> &shade::ShadowMap {
    cache.maps[0].as_deref().expect("a kept map")
}

fn shadow_visits(stats: &FrameStats) -> u64 {
    stats.shadow_levels.iter().map(|l| l.visited).sum()
}

/// At the house's own quality, at a coarse one (a 128² map with 3-texel LOD splats) and a
/// blocky one (24-texel splats, where a whole node can vanish well beyond the edit's box): the patched map equals a map drawn afresh
/// for the edited house, bit for bit, so does the image; it changed where the edit is; the
/// patch drew a part of the map and visited fewer shadow nodes than a full draw.
#[test]
fn a_patched_shadow_map_equals_a_freshly_drawn_one() {
    let house = house();
    let (edited, boxes) = edit(&house);
    let coarse = Quality {
        shadow_map_size: 128,
        lod_pixel_threshold: 3.0,
        ..house.quality.clone()
    };
    // 24-texel splats: wider than the patch's 8-texel tiles, so the margin decides.
    let blocky = Quality {
        shadow_map_size: 256,
        lod_pixel_threshold: 24.0,
        ..house.quality.clone()
    };
    for quality in [house.quality.clone(), coarse, blocky] {
        let req = request(&house, &quality);
        let mut cache = primed(&house, &req, 1);
        let before = map(&cache).depth.clone();

        note(&mut cache, &boxes, 1, 2);
        let (image, _, stats) =
            render_document_cached(&edited, &req, &mut cache, 2).expect("renders");
        assert_eq!(
            (stats.shadow_maps_patched, stats.shadow_maps_reused),
            (1, 0)
        );

        let mut fresh = primed(&edited, &req, 2);
        let (fresh_image, _, fresh_stats) =
            render_document_cached(&edited, &req, &mut fresh, 2).expect("renders");
        assert_eq!(
            fresh_stats.shadow_maps_reused, 1,
            "the fresh cache's map is reused"
        );
        let (patched, drawn) = (map(&cache), map(&fresh));
        assert_eq!(patched.cam, drawn.cam, "the same light camera");
        let differing = patched
            .depth
            .iter()
            .zip(&drawn.depth)
            .filter(|(a, b)| a.to_bits() != b.to_bits())
            .count();
        assert_eq!(
            differing, 0,
            "texels of the patched map that differ from a fresh one"
        );
        assert_eq!(patched.bounds, drawn.bounds, "tile bounds");
        assert!(
            image.pixels == fresh_image.pixels,
            "the image equals the fresh cache's"
        );

        let changed = before
            .iter()
            .zip(&patched.depth)
            .filter(|(a, b)| a.to_bits() != b.to_bits())
            .count();
        let total = patched.depth.len() as u64;
        assert!(changed > 0, "the edit changed the map");
        assert!(
            stats.shadow_texels_patched >= changed as u64
                && stats.shadow_texels_patched < total / 2,
            "patched {} texels of {total} ({changed} changed)",
            stats.shadow_texels_patched
        );
        // A full draw of the same map, for the traversal it costs.
        let mut full = primed(&edited, &req, 3);
        full.note_change(ContentChange {
            from: 3,
            to: 4,
            lo: Vec3::splat(-1e6),
            hi: Vec3::splat(1e6),
        });
        let (_, _, whole) = render_document_cached(&edited, &req, &mut full, 4).expect("renders");
        assert_eq!(
            whole.shadow_texels_patched, total,
            "a box over everything patches all"
        );
        // Figures for the note (no timing assert): visits and shadow pass time, side by side.
        eprintln!(
            "map {}²: patch {} texels, {} visits, {:.1} ms; whole {} visits, {:.1} ms",
            patched.cam.width,
            stats.shadow_texels_patched,
            shadow_visits(&stats),
            stats.times.shadow_ms,
            shadow_visits(&whole),
            whole.times.shadow_ms
        );
        assert!(
            shadow_visits(&stats) < shadow_visits(&whole),
            "patch visited {} shadow nodes, a whole map {}",
            shadow_visits(&stats),
            shadow_visits(&whole)
        );
    }
}

/// The chain: two notes in a row patch at once, a frame of the middle content patches up to
/// it and keeps the rest; a note that does not start at the chain's end, or with a box that is
/// not finite, drops the maps (the next frames draw them whole, as without notes); a note
/// before any map is kept is ignored.
#[test]
fn only_a_chain_of_noted_changes_reaching_the_frame_patches() {
    let house = house();
    let (edited, boxes) = edit(&house);
    let (lo, hi) = boxes
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &(lo, hi)| {
            (a.min(lo), b.max(hi))
        });
    let req = request(&house, &house.quality);
    let change = |from, to| ContentChange { from, to, lo, hi };

    let mut cache = primed(&house, &req, 1);
    cache.note_change(change(1, 2));
    cache.note_change(change(2, 3));
    let (_, _, st) = render_document_cached(&edited, &req, &mut cache, 2).expect("renders");
    assert_eq!(st.shadow_maps_patched, 1, "the middle of the chain");
    let (_, _, st) = render_document_cached(&edited, &req, &mut cache, 3).expect("renders");
    assert_eq!(st.shadow_maps_patched, 1, "its end");
    let (_, _, st) = render_document_cached(&edited, &req, &mut cache, 3).expect("renders");
    assert_eq!((st.shadow_maps_patched, st.shadow_maps_reused), (0, 1));

    cache.note_change(change(7, 8));
    assert!(cache.is_empty(), "a broken chain drops the maps");
    let (_, _, st) = render_document_cached(&edited, &req, &mut cache, 8).expect("renders");
    assert_eq!((st.shadow_maps_patched, st.shadow_maps_reused), (0, 0));

    let mut cache = primed(&house, &req, 1);
    cache.note_change(ContentChange {
        hi: Vec3::new(f32::NAN, 0.0, 0.0),
        ..change(1, 2)
    });
    assert!(cache.is_empty(), "a box that is not finite drops the maps");

    let mut empty = ShadowCache::new();
    empty.note_change(change(1, 2));
    assert!(empty.changes.is_empty() && empty.is_empty());

    // An empty box (nothing drawn changed) patches no texel and keeps the map.
    let mut cache = primed(&house, &req, 1);
    cache.note_change(ContentChange {
        lo: Vec3::ONE,
        hi: Vec3::ZERO,
        ..change(1, 2)
    });
    let (_, _, st) = render_document_cached(&house, &req, &mut cache, 2).expect("renders");
    assert_eq!((st.shadow_maps_patched, st.shadow_texels_patched), (1, 0));
}

/// The texel box of a world box: inside the map, widened by the margin, `None` when it misses
/// or is empty, the whole map when a corner does not project.
#[test]
fn box_texels_clamp_widen_and_miss() {
    let cam = shade::fit_light_camera(
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::splat(-1.0),
        Vec3::splat(1.0),
        64,
        1e-6,
    )
    .expect("a light camera");
    assert_eq!((cam.width, cam.height), (64, 64));
    let all = box_texels(&cam, Vec3::splat(-10.0), Vec3::splat(10.0), 0.0).expect("covers");
    assert_eq!(all, [0, 0, 63, 63]);
    let small = box_texels(&cam, Vec3::splat(-0.05), Vec3::splat(0.05), 0.0).expect("centre");
    let wide = box_texels(&cam, Vec3::splat(-0.05), Vec3::splat(0.05), 4.0).expect("centre");
    assert!(small[0] > 20 && small[2] < 44, "{small:?}");
    assert_eq!([wide[0] + 4, wide[1] + 4, wide[2] - 4, wide[3] - 4], small);
    assert_eq!(
        box_texels(
            &cam,
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(6.0, 0.0, 0.0),
            1.0
        ),
        None
    );
    assert_eq!(box_texels(&cam, Vec3::ONE, Vec3::ZERO, 1.0), None);
}

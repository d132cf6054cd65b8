//! Picking through distance queries on the real app, driven by egui_kittest: a click on a KRS
//! tree and on a mesh selects each (with the clicked point and its normal drawn), a click on
//! nothing clears both; Object → Drop to surface (End) lands a voxel model on KRS terrain
//! within one voxel of the surface the query sees, in one undo step; the sculpt brush over KRS
//! terrain places voxels of the selected voxel model on the surface (one undo step).
//!
//! No GPU viewport is attached: the view draws with core's CPU preview renderer.

mod common;

use egui_kittest::kittest::Queryable as _;
use egui_kittest::{Harness, SnapshotOptions};
use glam::{UVec3, Vec3};
use thicket::editor::{Editor, PickKind, Selection};
use thicket::ui::EditorApp;
use thicket::ui::view::Projector;
use thicket_core::krs::{KrsScene, PreparedScene, presets};
use thicket_core::mesh::{MeshModel, TriangleMesh};
use thicket_core::scene::{Document, MeshObject, ObjectKind, Transform, VoxelModel};
use thicket_core::svo::{Svo, Voxel};

const SIZE: egui::Vec2 = egui::vec2(1100.0, 720.0);

fn harness(doc: Document) -> Harness<'static, EditorApp> {
    common::ui_harness(Editor::new(doc, None), SIZE)
}

/// The closed cube −1..1 as 12 triangles.
fn cube_mesh() -> ObjectKind {
    let positions: Vec<Vec3> = (0..8)
        .map(|k| {
            Vec3::new(
                if k & 1 == 0 { -1.0 } else { 1.0 },
                if k & 2 == 0 { -1.0 } else { 1.0 },
                if k & 4 == 0 { -1.0 } else { 1.0 },
            )
        })
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    ObjectKind::Mesh(MeshObject {
        model: MeshModel {
            parts: vec![TriangleMesh {
                positions,
                indices: quads
                    .iter()
                    .flat_map(|q| [q[0], q[1], q[2], q[0], q[2], q[3]])
                    .collect(),
                ..TriangleMesh::default()
            }],
            materials: vec![Default::default()],
        },
        casts_shadows: true,
    })
}

fn prepared(doc: &Document, id: u64) -> PreparedScene {
    let o = doc.objects.iter().find(|o| o.id == id).unwrap();
    KrsScene {
        objects: vec![o.krs_in_world().unwrap()],
    }
    .prepare()
    .unwrap()
}

/// A point of the KRS surface straight below `from`, by plain sphere tracing on the query's
/// distance (independent of the editor's picking).
fn surface_below(scene: &PreparedScene, from: Vec3) -> Vec3 {
    let mut p = from;
    for _ in 0..4096 {
        let d = scene.query(p).unwrap().distance;
        if d < 1e-4 {
            return p;
        }
        p.y -= d;
    }
    panic!("no surface below {from}");
}

#[test]
fn a_click_selects_a_krs_tree_or_a_mesh_and_marks_the_point_and_normal() {
    let mut doc = Document::default();
    doc.quality.shadows = false;
    let tree = doc.add("Tree", ObjectKind::Krs(presets::tree()));
    let cube = doc.add("Cube", cube_mesh());
    let (tlo, thi) = doc.objects[0].world_bounds().expect("a bounded tree");
    let r = (thi.x - tlo.x) * 0.5;
    doc.objects[1].transform = Transform {
        translation: Vec3::new((tlo.x + thi.x) * 0.5 + r + 2.0, tlo.y + 1.0, 0.0),
        ..Transform::default()
    };
    doc.camera.yaw_deg = 0.0;
    doc.camera.pitch_deg = 10.0;
    let (lo, hi) = doc.bounds().unwrap();
    doc.camera.frame(lo, hi);
    let mut h = harness(doc);
    common::settle_preview(&mut h);
    // Opening selects the first object: start from nothing selected.
    h.state_mut().editor.selection = None;
    h.run_steps(1);

    let rect = h.state().view.last_rect;
    let proj = Projector::new(h.state().editor.doc().camera, rect);
    // A point on the trunk, found by the query alone: the first surface below the middle of
    // the tree's ball, seen from the camera in front of it.
    let scene = prepared(h.state().editor.doc(), tree);
    let centre = (tlo + thi) * 0.5;
    let on_tree = surface_below(&scene, Vec3::new(centre.x, thi.y, centre.z));
    common::click_at(&mut h, proj.to_screen(on_tree).unwrap());
    let ed = &h.state().editor;
    assert_eq!(ed.selection, Some(Selection::Object(tree)));
    let (_, pick) = h.state().view.last_click.expect("the click is kept");
    assert_eq!((pick.object, pick.kind), (tree, PickKind::Krs));
    let q = scene.query(pick.point_in_world).unwrap();
    assert!(
        q.distance.abs() <= 1e-4 * pick.t,
        "the marked point is {} from the tree's surface",
        q.distance
    );
    assert!(pick.normal_in_world.dot(q.normal) > 0.99);
    common::settle_preview(&mut h);
    h.snapshot_options(
        "pick_krs_tree_marked",
        &SnapshotOptions::new().max_failed_pixels(200),
    );

    // The cube's centre: the ray through it meets the face toward the camera (+Z).
    let centre = h.state().editor.object(cube).unwrap().transform.translation;
    common::click_at(&mut h, proj.to_screen(centre).unwrap());
    assert_eq!(h.state().editor.selection, Some(Selection::Object(cube)));
    let (_, pick) = h.state().view.last_click.unwrap();
    assert_eq!((pick.object, pick.kind), (cube, PickKind::Mesh));
    assert!(
        (pick.point_in_world.z - 1.0).abs() < 1e-4,
        "{}",
        pick.point_in_world
    );
    assert!(pick.normal_in_world.distance(Vec3::Z) < 1e-5);

    // The sky: nothing selected, no mark.
    common::click_at(&mut h, rect.left_top() + egui::vec2(5.0, 5.0));
    assert_eq!(h.state().editor.selection, None);
    assert_eq!(h.state().view.last_click, None);
}

#[test]
fn drop_to_surface_lands_a_voxel_model_on_krs_terrain_within_a_voxel() {
    let voxel = 0.25;
    let mut svo = Svo::new(4, false).unwrap();
    for x in 0..6 {
        for y in 0..3 {
            for z in 0..6 {
                svo.set(UVec3::new(x, y, z), Voxel::new([200, 60, 60, 255], Vec3::Y))
                    .unwrap();
            }
        }
    }
    let mut doc = Document::default();
    doc.quality.shadows = false;
    let terrain = doc.add("Terrain", ObjectKind::Krs(presets::terrain()));
    let block = doc.add(
        "Block",
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: voxel,
            ..VoxelModel::default()
        }),
    );
    doc.objects[1].transform.translation = Vec3::new(3.0, 25.0, -2.0);
    doc.camera.target = Vec3::new(3.0, 10.0, -2.0);
    doc.camera.distance = 60.0;
    let mut h = harness(doc);
    h.state_mut().editor.selection = Some(Selection::Object(block));
    h.run_steps(1);
    let steps = h.state().editor.history().undo_len();
    h.key_press(egui::Key::End);
    h.run_steps(2);
    let ed = &h.state().editor;
    assert_eq!(ed.history().undo_len(), steps + 1, "one undo step");
    assert!(
        h.query_all_by_label_contains("Dropped Block by")
            .next()
            .is_some(),
        "the status says what moved"
    );
    // The bottom face, corner to corner: its closest point rests on the terrain within a
    // voxel.
    let scene = prepared(ed.doc(), terrain);
    let t = ed.object(block).unwrap().transform.translation;
    assert!(t.y < 25.0 - 1.0, "it moved down (now at {})", t.y);
    let gaps: Vec<f32> = (0..=24)
        .flat_map(|i| (0..=24).map(move |k| (i, k)))
        .map(|(i, k)| {
            let p = t + Vec3::new(i as f32, 0.0, k as f32) * (6.0 * voxel / 24.0);
            scene.query(p).unwrap().distance
        })
        .collect();
    let lowest = gaps.iter().copied().fold(f32::INFINITY, f32::min);
    assert!(
        lowest.abs() <= voxel,
        "the block's bottom is {lowest} from the terrain at its closest"
    );
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(1);
    let back = h
        .state()
        .editor
        .object(block)
        .unwrap()
        .transform
        .translation;
    assert_eq!(back, Vec3::new(3.0, 25.0, -2.0), "undo puts it back");
}

#[test]
fn the_brush_places_voxels_of_the_selected_model_on_krs_terrain_in_one_undo_step() {
    let voxel = 0.25;
    // A 32³ grid (8 units) with one voxel in its bottom corner, under the ground.
    let mut svo = Svo::new(5, false).unwrap();
    svo.set(UVec3::ZERO, Voxel::new([200, 60, 60, 255], Vec3::Y))
        .unwrap();
    let mut doc = Document::default();
    doc.quality.shadows = false;
    let terrain = doc.add("Terrain", ObjectKind::Krs(presets::terrain()));
    let block = doc.add(
        "Block",
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: voxel,
            ..VoxelModel::default()
        }),
    );
    // The grid is centred on a point of the terrain's surface, seen from above at an angle.
    let scene = prepared(&doc, terrain);
    let ground = surface_below(&scene, Vec3::new(0.3, 60.0, 0.2));
    doc.objects[1].transform.translation = ground - Vec3::splat(4.0);
    doc.camera.target = ground;
    doc.camera.yaw_deg = 20.0;
    doc.camera.pitch_deg = 45.0;
    doc.camera.distance = 10.0;
    let mut h = harness(doc);
    let proj = Projector::new(h.state().editor.doc().camera, h.state().view.last_rect);
    let at = proj.to_screen(ground).expect("the ground point is in view");
    // What the brush aims at there: the terrain, nearer than any voxel.
    let eye = proj.eye();
    let hit = h
        .state()
        .editor
        .pick(eye, ground - eye)
        .expect("the ray meets the terrain");
    assert_eq!((hit.object, hit.kind), (terrain, PickKind::Krs));
    let leaves =
        |h: &Harness<'static, EditorApp>| match &h.state().editor.object(block).unwrap().kind {
            ObjectKind::Voxels(v) => v.svo.leaves(),
            _ => unreachable!(),
        };
    let before = leaves(&h);

    // With the terrain selected (no voxel model to place), the brush over it does nothing.
    h.state_mut().editor.selection = Some(Selection::Object(terrain));
    h.state_mut()
        .sculpt
        .choose(thicket::ui::voxel_tools::ToolKind::Brush);
    h.state_mut().sculpt.brush.radius = 1.0;
    h.run_steps(1);
    let steps = h.state().editor.history().undo_len();
    common::click_at(&mut h, at);
    assert_eq!(
        leaves(&h),
        before,
        "no voxel model selected: nothing placed"
    );
    assert_eq!(h.state().editor.history().undo_len(), steps);

    // With the block selected, a click on the terrain places the block's voxels there.
    h.state_mut().editor.selection = Some(Selection::Object(block));
    h.run_steps(1);
    common::click_at(&mut h, at);
    let after = leaves(&h);
    let added: Vec<Vec3> = after
        .iter()
        .filter(|(c, _)| !before.iter().any(|(b, _)| b == c))
        .map(|(c, _)| ground - Vec3::splat(4.0) + (c.as_vec3() + 0.5) * voxel)
        .collect();
    assert!(!added.is_empty(), "the brush placed voxels");
    assert_eq!(
        after.len(),
        before.len() + added.len(),
        "nothing was removed"
    );
    assert_eq!(
        h.state().editor.history().undo_len(),
        steps + 1,
        "one undo step"
    );
    assert_eq!(
        h.state().editor.selection,
        Some(Selection::Object(block)),
        "the block stays selected"
    );
    // On the surface: every new voxel's centre within the brush (radius 1 voxel) of a dab one
    // voxel out from the point hit, and at least one within a voxel of the terrain's surface.
    for c in &added {
        assert!(
            c.distance(hit.point_in_world) <= 2.5 * voxel * 3f32.sqrt(),
            "voxel at {c} is far from the point hit {}",
            hit.point_in_world
        );
    }
    let nearest = added
        .iter()
        .map(|c| scene.query(*c).unwrap().distance.abs())
        .fold(f32::INFINITY, f32::min);
    assert!(
        nearest <= voxel,
        "the nearest new voxel is {nearest} from the terrain"
    );
    assert!(
        added
            .iter()
            .any(|c| scene.query(*c).unwrap().distance > 0.0),
        "voxels stand on the ground, not only in it"
    );
    common::settle_preview(&mut h);
    h.snapshot_options(
        "brush_on_krs_terrain",
        &SnapshotOptions::new().max_failed_pixels(200),
    );

    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(1);
    assert_eq!(leaves(&h), before, "undo removes them");
}

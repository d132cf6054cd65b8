//! Picks at the extremes (empty scenes, grazing rays, rays starting inside, far away) and
//! dropping onto voxels, meshes and KRS ground.

use glam::{Quat, UVec3, Vec3};
use thicket_core::krs::{
    Distortion, Kernel, KrsObject, KrsScene, PlaneKernel, SphereKernel, presets,
};
use thicket_core::mesh::{MeshModel, TriangleMesh};
use thicket_core::scene::{MeshObject, ObjectKind, Transform, VoxelModel};
use thicket_core::svo::{Svo, Voxel};

use super::{PICK_TRACE, PickKind};
use crate::editor::Editor;

fn voxels(size: UVec3) -> ObjectKind {
    let mut svo = Svo::new(4, false).unwrap();
    for x in 0..size.x {
        for y in 0..size.y {
            for z in 0..size.z {
                svo.set(UVec3::new(x, y, z), Voxel::new([90, 90, 90, 255], Vec3::Y))
                    .unwrap();
            }
        }
    }
    ObjectKind::Voxels(VoxelModel {
        svo,
        ..VoxelModel::default()
    })
}

fn mesh(positions: Vec<Vec3>, indices: Vec<u32>) -> ObjectKind {
    ObjectKind::Mesh(MeshObject {
        model: MeshModel {
            parts: vec![TriangleMesh {
                positions,
                indices,
                ..TriangleMesh::default()
            }],
            materials: vec![Default::default()],
        },
        casts_shadows: true,
    })
}

/// The square −1..1 in the XZ plane at y = 0, as two triangles.
fn square() -> ObjectKind {
    mesh(
        vec![
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(-1.0, 0.0, 1.0),
        ],
        vec![0, 2, 1, 0, 3, 2],
    )
}

/// The closed cube −1..1 (12 triangles, outward faces): core's unit cube scaled by 2.
fn cube() -> ObjectKind {
    let m = thicket_core::mesh::unit_cube();
    mesh(m.positions.iter().map(|p| *p * 2.0).collect(), m.indices)
}

fn ball(radius: f32) -> ObjectKind {
    ObjectKind::Krs(KrsObject {
        kernels: vec![Kernel::Sphere(SphereKernel {
            centre: Vec3::ZERO,
            radius,
            ..SphereKernel::default()
        })],
        ..KrsObject::default()
    })
}

/// The half-space y ≤ 0 as a KRS object (the ground of the samples).
fn ground() -> ObjectKind {
    ObjectKind::Krs(KrsObject {
        kernels: vec![Kernel::InfinitePlane(PlaneKernel {
            normal: Vec3::Y,
            offset: 0.0,
            ..PlaneKernel::default()
        })],
        ..KrsObject::default()
    })
}

fn moved(ed: &mut Editor, id: u64, translation: Vec3, scale: f32) {
    let t = Transform {
        translation,
        rotation: Quat::IDENTITY,
        scale: Vec3::splat(scale),
    };
    ed.set_transform(id, t).unwrap();
}

#[test]
fn an_empty_scene_picks_nothing() {
    let ed = Editor::default();
    assert_eq!(ed.pick(Vec3::ZERO, Vec3::NEG_Y), None);
    assert_eq!(ed.pick(Vec3::splat(1e30), Vec3::X), None);
    // A zero or non-finite direction, or a non-finite origin, is no ray at all.
    let mut ed = Editor::default();
    ed.add_object("Ground", ground());
    assert_eq!(ed.pick(Vec3::Y, Vec3::ZERO), None);
    assert_eq!(ed.pick(Vec3::Y, Vec3::NAN), None);
    assert_eq!(ed.pick(Vec3::new(f32::NAN, 1.0, 0.0), Vec3::NEG_Y), None);
}

#[test]
fn a_mesh_is_hit_on_its_nearest_triangle_with_a_normal_facing_the_ray() {
    let mut ed = Editor::default();
    let id = ed.add_object("Square", square());
    moved(&mut ed, id, Vec3::new(10.0, 2.0, 0.0), 3.0);
    let down = ed
        .pick(Vec3::new(11.0, 12.0, 1.0), Vec3::NEG_Y)
        .expect("hit");
    assert_eq!((down.object, down.kind), (id, PickKind::Mesh));
    assert!((down.t - 10.0).abs() < 1e-5, "t = {}", down.t);
    assert!(down.point_in_world.distance(Vec3::new(11.0, 2.0, 1.0)) < 1e-5);
    assert!(down.normal_in_world.distance(Vec3::Y) < 1e-6);
    // From below, the same square faces the other way.
    let up = ed.pick(Vec3::new(11.0, -5.0, 1.0), Vec3::Y).expect("hit");
    assert!(up.normal_in_world.distance(Vec3::NEG_Y) < 1e-6);
    // Outside the scaled square (half-size 3): a miss.
    assert_eq!(ed.pick(Vec3::new(13.5, 12.0, 0.0), Vec3::NEG_Y), None);
    // Pointing away.
    assert_eq!(ed.pick(Vec3::new(11.0, 12.0, 1.0), Vec3::Y), None);
    // Hidden objects are not picked.
    ed.set_visible(id, false).unwrap();
    assert_eq!(ed.pick(Vec3::new(11.0, 12.0, 1.0), Vec3::NEG_Y), None);
}

#[test]
fn a_grazing_ray_in_a_mesh_plane_misses_and_one_just_tilted_hits() {
    let mut ed = Editor::default();
    let id = ed.add_object("Square", square());
    // In the plane, through the square's middle and along its diagonal edge.
    assert_eq!(ed.pick(Vec3::new(-5.0, 0.0, 0.0), Vec3::X), None);
    assert_eq!(
        ed.pick(Vec3::new(-5.0, 0.0, -5.0), Vec3::new(1.0, 0.0, 1.0)),
        None
    );
    // One part in a thousand downward, from half a thousandth above the plane: it crosses the
    // plane half a unit on, at x = −0.5.
    let dir = Vec3::new(1.0, -1e-3, 0.0); // `pick` normalises it.
    let origin = Vec3::new(-1.0, 1e-3 * 0.5, 0.2);
    let hit = ed.pick(origin, dir).expect("a just-tilted ray hits");
    assert_eq!(hit.object, id);
    assert!(hit.point_in_world.y.abs() < 1e-6, "{}", hit.point_in_world);
    assert!(
        (hit.point_in_world.x + 0.5).abs() < 1e-3,
        "{}",
        hit.point_in_world
    );
}

#[test]
fn a_ray_from_inside_a_closed_mesh_hits_the_wall_in_front_facing_back() {
    let mut ed = Editor::default();
    let id = ed.add_object("Cube", cube());
    let hit = ed
        .pick(Vec3::new(0.0, 0.2, 0.3), Vec3::X)
        .expect("inside hit");
    assert_eq!(hit.object, id);
    assert!((hit.t - 1.0).abs() < 1e-6, "t = {}", hit.t);
    assert!(hit.normal_in_world.distance(Vec3::NEG_X) < 1e-6);
    // From outside, the near wall (not the far one) at t = 4.
    let hit = ed.pick(Vec3::new(-5.0, 0.2, 0.3), Vec3::X).expect("hit");
    assert!((hit.t - 4.0).abs() < 1e-6, "t = {}", hit.t);
    assert!(hit.normal_in_world.distance(Vec3::NEG_X) < 1e-6);
}

#[test]
fn far_away_rays_land_on_meshes_and_krs_within_their_tolerance() {
    let mut ed = Editor::default();
    let square = ed.add_object("Square", square());
    let far = 1e6_f32;
    let hit = ed.pick(Vec3::new(0.5, far, 0.5), Vec3::NEG_Y).expect("hit");
    assert_eq!(hit.object, square);
    // f32 holds 1e6 to 1/16: the f64 intersection keeps the hit to that.
    assert!((hit.t - far).abs() <= 0.0625, "t = {}", hit.t);

    let mut ed = Editor::default();
    let ball = ed.add_object("Ball", ball(1.0));
    let hit = ed.pick(Vec3::new(0.0, 0.0, far), Vec3::NEG_Z).expect("hit");
    assert_eq!((hit.object, hit.kind), (ball, PickKind::Krs));
    // The tracer stops within its relative epsilon (a tenth of a pixel) of the surface.
    let eps = PICK_TRACE.pixel_cone_ratio * far;
    assert!((hit.t - (far - 1.0)).abs() <= eps, "t = {}", hit.t);
    assert!(hit.normal_in_world.distance(Vec3::Z) < 1e-3);
    // Passing the ball a thousand units off: well outside the epsilon, a miss.
    assert_eq!(ed.pick(Vec3::new(1000.0, 0.0, far), Vec3::NEG_Z), None);
    // From 1e30 (beyond f32 squares): no panic, no NaN, a hit or a clean miss on the ball.
    if let Some(p) = ed.pick(Vec3::new(0.0, 0.0, 1e30), Vec3::NEG_Z) {
        assert!(p.t.is_finite() && p.point_in_world.is_finite());
    }
}

#[test]
fn krs_picks_respect_transform_grazing_and_starting_inside() {
    let mut ed = Editor::default();
    let id = ed.add_object("Ball", ball(1.0));
    moved(&mut ed, id, Vec3::new(5.0, 0.0, 0.0), 2.0);
    let hit = ed
        .pick(Vec3::new(5.0, 10.0, 0.0), Vec3::NEG_Y)
        .expect("hit");
    assert_eq!((hit.object, hit.kind), (id, PickKind::Krs));
    // The scaled ball's top is at y = 2.
    assert!(
        (hit.t - 8.0).abs() <= PICK_TRACE.pixel_cone_ratio * 8.0,
        "t = {}",
        hit.t
    );
    assert!(hit.normal_in_world.distance(Vec3::Y) < 1e-3);
    // Starting inside: a hit where the ray starts.
    let inside = ed.pick(Vec3::new(5.5, 0.0, 0.0), Vec3::X).expect("inside");
    assert_eq!(inside.t, 0.0);
    // Tangent to the top (y = 2): touches; a twentieth of a unit above: misses.
    let tangent = ed
        .pick(Vec3::new(-10.0, 2.0, 0.0), Vec3::X)
        .expect("tangent");
    assert!(
        (tangent.point_in_world.x - 5.0).abs() < 0.5,
        "{}",
        tangent.point_in_world
    );
    assert_eq!(ed.pick(Vec3::new(-10.0, 2.05, 0.0), Vec3::X), None);
}

#[test]
fn a_distorted_krs_pick_lands_on_the_surface_the_query_sees() {
    let mut ed = Editor::default();
    let mut coral = presets::coral();
    coral.distortion = Some(Distortion {
        amplitude: 0.2,
        frequency: 2.0,
        seed: 7,
    });
    let id = ed.add_object("Coral", ObjectKind::Krs(coral));
    let o = ed.object(id).unwrap();
    let (lo, hi) = o.world_bounds().expect("bounded");
    let scene = KrsScene {
        objects: vec![o.krs_in_world().unwrap()],
    }
    .prepare()
    .unwrap();
    let mut hits = 0;
    for k in 0..81 {
        let f = |j: usize| (j as f32 + 0.5) / 9.0;
        let x = lo.x + (hi.x - lo.x) * f(k % 9);
        let z = lo.z + (hi.z - lo.z) * f(k / 9);
        let origin = Vec3::new(x, hi.y + 1.0, z);
        let Some(p) = ed.pick(origin, Vec3::NEG_Y) else {
            // A miss must be one: no point sampled along the ray is inside the coral.
            let len = hi.y - lo.y + 2.0;
            let inside = (0..4000)
                .map(|i| origin + Vec3::NEG_Y * (len * i as f32 / 4000.0))
                .find(|&p| scene.distance(p) < 0.0);
            assert_eq!(inside, None, "the ray from {origin} missed");
            continue;
        };
        hits += 1;
        let q = scene.query(p.point_in_world).unwrap();
        let eps = PICK_TRACE.pixel_cone_ratio * p.t;
        assert!(
            q.distance.abs() <= eps,
            "{} from the surface at {}",
            q.distance,
            p.point_in_world
        );
    }
    // The coral is sparse seen from above: 6 of these 81 rays meet it.
    assert!(hits >= 4, "only {hits} of 81 rays hit the coral");
}

#[test]
fn the_nearest_of_voxels_meshes_and_krs_wins() {
    let mut ed = Editor::default();
    let slab = ed.add_object("Slab", voxels(UVec3::new(8, 4, 8)));
    let square = ed.add_object("Square", square());
    moved(&mut ed, square, Vec3::new(4.0, 6.0, 4.0), 1.0);
    let ball = ed.add_object("Ball", ball(1.0));
    moved(&mut ed, ball, Vec3::new(4.0, 10.0, 4.0), 1.0);
    let from = Vec3::new(4.2, 20.0, 4.2);
    assert_eq!(ed.pick(from, Vec3::NEG_Y).unwrap().object, ball);
    ed.set_visible(ball, false).unwrap();
    assert_eq!(ed.pick(from, Vec3::NEG_Y).unwrap().object, square);
    ed.set_visible(square, false).unwrap();
    let v = ed.pick(from, Vec3::NEG_Y).unwrap();
    assert_eq!((v.object, v.kind), (slab, PickKind::Voxels));
    assert!((v.t - 16.0).abs() < 1e-4);
    assert!(v.normal_in_world.distance(Vec3::Y) < 1e-6);
}

#[test]
fn drop_to_surface_lands_on_krs_ground_voxels_and_meshes_in_one_undo_step() {
    let mut ed = Editor::default();
    ed.add_object("Ground", ground());
    let cube = ed.add_object("Cube", voxels(UVec3::new(2, 2, 2)));
    moved(&mut ed, cube, Vec3::new(0.3, 17.25, -0.4), 1.0);
    let steps = ed.history().undo_len();
    let landing = ed.drop_to_surface(cube).unwrap();
    assert!((landing.distance - 17.25).abs() <= PICK_TRACE.pixel_cone_ratio * 17.25);
    let bottom = ed.object(cube).unwrap().world_bounds().unwrap().0.y;
    assert!(bottom.abs() < 1e-2, "the cube's bottom is at {bottom}");
    assert_eq!(ed.history().undo_len(), steps + 1, "one undo step");
    ed.undo();
    assert_eq!(ed.object(cube).unwrap().transform.translation.y, 17.25);
    ed.redo();
    // Already resting: it moves by no more than the tracer's tolerance, and that is no error.
    let again = ed.drop_to_surface(cube).unwrap();
    assert!(again.distance.abs() < 1e-2, "{}", again.distance);

    // Onto a voxel slab (top at y = 4) standing on the ground, and onto a mesh above that.
    let slab = ed.add_object("Slab", voxels(UVec3::new(8, 4, 8)));
    moved(&mut ed, cube, Vec3::new(2.0, 20.0, 2.0), 1.0);
    assert_eq!(ed.drop_to_surface(cube).unwrap().onto, slab);
    assert!((ed.object(cube).unwrap().transform.translation.y - 4.0).abs() < 1e-4);
    let square = ed.add_object("Square", square());
    moved(&mut ed, square, Vec3::new(1.0, 9.0, 1.0), 1.0);
    moved(&mut ed, cube, Vec3::new(0.5, 30.0, 0.5), 1.0);
    assert_eq!(ed.drop_to_surface(cube).unwrap().onto, square);
    assert!((ed.object(cube).unwrap().transform.translation.y - 9.0).abs() < 1e-4);
}

#[test]
fn drop_to_surface_with_nothing_below_says_so_and_changes_nothing() {
    let mut ed = Editor::default();
    let cube = ed.add_object("Cube", voxels(UVec3::new(2, 2, 2)));
    let other = ed.add_object("Far", voxels(UVec3::new(2, 2, 2)));
    moved(&mut ed, other, Vec3::new(100.0, 0.0, 0.0), 1.0);
    let before = ed.doc().clone();
    let steps = ed.history().undo_len();
    let err = ed.drop_to_surface(cube).unwrap_err().to_string();
    assert!(err.contains("nothing below"), "{err}");
    assert_eq!(*ed.doc(), before);
    assert_eq!(ed.history().undo_len(), steps);
    // Unbounded terrain has no lowest point to drop.
    let ground = ed.add_object("Ground", ground());
    let err = ed.drop_to_surface(ground).unwrap_err().to_string();
    assert!(err.contains("no bounds"), "{err}");
}

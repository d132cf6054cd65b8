//! `thicket import` of glTF scenes as objects: one object per node with a mesh, placed by the
//! node's world transform, checked voxel by voxel against the file's world-space triangles.

mod common;

use std::path::{Path, PathBuf};

use common::{stderr, stdout, thicket, write_node_scene as write_scene};
use glam::{Mat4, Quat, Vec3};
use thicket_core::scene::{Document, Object, ObjectKind};

const ASSETS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/assets");

/// `thicket import INPUT -o DIR/out.thicket.json EXTRA…`: its output text and the project.
fn import(dir: &Path, input: &Path, extra: &[&str]) -> (String, Document) {
    let out = dir.join("out.thicket.json");
    let _ = std::fs::remove_file(&out);
    let mut args = vec![
        "import",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = thicket(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc = thicket_core::io::project::load(&out).unwrap();
    (stdout(&o), doc)
}

/// The file's triangles in world space, as the merged import reads them.
fn world_triangles(input: &Path) -> Vec<[Vec3; 3]> {
    let model = thicket_core::io::import_gltf(input).unwrap();
    model
        .parts
        .iter()
        .flat_map(|p| (0..p.triangle_count()).map(|t| p.triangle(t).map(|i| p.positions[i])))
        .collect()
}

fn point_triangle_distance(p: Vec3, [a, b, c]: [Vec3; 3]) -> f32 {
    // Ericson, Real-Time Collision Detection, 5.1.5.
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return p.distance(a);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return p.distance(b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return p.distance(a + ab * (d1 / (d1 - d3)));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return p.distance(c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return p.distance(a + ac * (d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return p.distance(b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let denom = 1.0 / (va + vb + vc);
    p.distance(a + ab * (vb * denom) + ac * (vc * denom))
}

/// Every voxel of a surface-voxelized `object`, placed in the world by its transform, has a
/// triangle of `triangles` within half its world diagonal (it touches one), and the voxels'
/// world bounds hold the triangles' to within a voxel. Returns the voxel's world edge.
fn assert_voxels_on(object: &Object, triangles: &[[Vec3; 3]]) -> f32 {
    let ObjectKind::Voxels(v) = &object.kind else {
        panic!("{} is a {}", object.name, object.kind_name());
    };
    let world_from_voxel = object.transform.matrix() * v.object_from_voxel();
    let edge = world_from_voxel.transform_vector3(Vec3::X).length();
    assert!(v.svo.leaf_count() > 0, "{} has no voxels", object.name);
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    v.svo.for_each_leaf(|c, _| {
        let centre = world_from_voxel.transform_point3(c.as_vec3() + 0.5);
        let nearest = triangles
            .iter()
            .map(|&t| point_triangle_distance(centre, t))
            .fold(f32::MAX, f32::min);
        assert!(
            nearest <= edge * 0.87 + 1e-4,
            "{}: voxel {c} at {centre} is {nearest} from the nearest triangle (voxel {edge})",
            object.name
        );
        lo = lo.min(centre);
        hi = hi.max(centre);
    });
    let (tlo, thi) = triangles.iter().flatten().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(a, b), &p| (a.min(p), b.max(p)),
    );
    assert!(
        lo.abs_diff_eq(tlo, edge) && hi.abs_diff_eq(thi, edge),
        "{}: voxel centres span {lo}..{hi}, the triangles {tlo}..{thi} (voxel {edge})",
        object.name
    );
    edge
}

fn longest_voxels(object: &Object) -> u32 {
    let ObjectKind::Voxels(v) = &object.kind else {
        panic!("{} is a {}", object.name, object.kind_name());
    };
    let (lo, hi) = v.svo.bounds().unwrap();
    (hi - lo).max_element() + 1
}

#[test]
fn bevy_torus_is_one_object_placed_by_its_node_rotation() {
    let dir = tempfile::tempdir().unwrap();
    let input = PathBuf::from(format!("{ASSETS}/static/bevy_torus.gltf"));
    let (out, doc) = import(dir.path(), &input, &["--depth", "5"]);
    assert_eq!(doc.objects.len(), 1, "{out}");
    let torus = &doc.objects[0];
    assert_eq!(torus.name, "Torus.001");
    // The file's node turns the torus 90 degrees about x; the object keeps that turn.
    let turn = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    assert!(
        torus.transform.rotation.abs_diff_eq(turn, 1e-5),
        "{:?}",
        torus.transform
    );
    assert!(torus.transform.scale.abs_diff_eq(Vec3::ONE, 1e-5));
    assert_eq!(longest_voxels(torus), 32);
    assert_voxels_on(torus, &world_triangles(&input));
    assert!(out.contains("placed by the node's transform"), "{out}");
}

#[test]
fn box_is_its_child_node_placed_by_the_parents_matrix() {
    let dir = tempfile::tempdir().unwrap();
    let input = PathBuf::from(format!("{ASSETS}/static/Box.glb"));
    let (out, doc) = import(dir.path(), &input, &["--depth", "4"]);
    assert_eq!(doc.objects.len(), 1, "{out}");
    let cube = &doc.objects[0];
    // The root node's matrix turns y-up into z-up: -90 degrees about x.
    let turn = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    assert!(
        cube.transform.rotation.abs_diff_eq(turn, 1e-5)
            || cube.transform.rotation.abs_diff_eq(-turn, 1e-5),
        "{:?}",
        cube.transform
    );
    assert_eq!(longest_voxels(cube), 16);
    assert_voxels_on(cube, &world_triangles(&input));
}

#[test]
fn cesium_man_stays_one_skinned_object() {
    let dir = tempfile::tempdir().unwrap();
    let input = PathBuf::from(format!("{ASSETS}/skinned/CesiumMan.glb"));
    let (out, doc) = import(dir.path(), &input, &["--depth", "5"]);
    assert_eq!(doc.objects.len(), 1, "{out}");
    let ObjectKind::Voxels(v) = &doc.objects[0].kind else {
        panic!("not voxels");
    };
    assert!(v.rig.is_some() && v.svo.has_skin());
    assert!(out.contains("imported as one skinned object"), "{out}");
    // Its joints place it: the object's transform stays the identity.
    assert_eq!(
        doc.objects[0].transform,
        thicket_core::scene::Transform::default()
    );
    // Nodes cannot be picked from a skinned import; the message says how.
    let o = thicket(&[
        "import",
        input.to_str().unwrap(),
        "-o",
        dir.path().join("x.thicket.json").to_str().unwrap(),
        "--node",
        "Cesium_Man",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("add --no-skin"), "{}", stderr(&o));
}

/// The scene's triangles of one node, in world space (the parent's and the node's transforms
/// applied here, independently of the importer).
fn node_triangles(name: &str) -> Vec<[Vec3; 3]> {
    let parent = Mat4::from_scale_rotation_translation(
        Vec3::splat(2.0),
        Quat::from_rotation_y(30f32.to_radians()),
        Vec3::new(5.0, 0.0, -2.0),
    );
    let cube = || {
        let corner = |i: usize| {
            Vec3::new(
                (i & 1) as f32 - 0.5,
                ((i >> 1) & 1) as f32 - 0.5,
                ((i >> 2) & 1) as f32 - 0.5,
            )
        };
        // Each face as two triangles over its four corners (the surface is what matters).
        let faces: [[usize; 4]; 6] = [
            [0, 1, 3, 2],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 3, 7, 5],
        ];
        faces
            .iter()
            .flat_map(|f| {
                [
                    [corner(f[0]), corner(f[1]), corner(f[2])],
                    [corner(f[0]), corner(f[2]), corner(f[3])],
                ]
            })
            .collect::<Vec<_>>()
    };
    let (local, triangles) = match name {
        "Cube" => (
            Mat4::from_rotation_translation(
                Quat::from_rotation_x(45f32.to_radians()),
                Vec3::new(1.0, 1.0, 0.0),
            ),
            cube(),
        ),
        "Slab" => (
            Mat4::from_scale_rotation_translation(
                Vec3::new(3.0, 1.0, 1.0),
                Quat::IDENTITY,
                Vec3::new(-2.0, 0.5, 0.0),
            ),
            cube(),
        ),
        _ => unreachable!("{name}"),
    };
    let world = parent * local;
    triangles
        .into_iter()
        .map(|t| t.map(|p| world.transform_point3(p)))
        .collect()
}

fn object<'a>(doc: &'a Document, name: &str) -> &'a Object {
    doc.object_by_name(name)
        .unwrap_or_else(|| panic!("no object {name}"))
}

#[test]
fn a_scene_becomes_one_object_per_node_in_its_world_place() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_scene(dir.path());
    let (out, doc) = import(dir.path(), &input, &["--depth", "4"]);
    let names: Vec<&str> = doc.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["Cube", "Slab", "Ground"], "{out}");

    // Cube: the whole world transform (turn, scale 2, tilt, moves) is the object's.
    let cube = object(&doc, "Cube");
    let world_from_cube = Mat4::from_scale_rotation_translation(
        Vec3::splat(2.0),
        Quat::from_rotation_y(30f32.to_radians()),
        Vec3::new(5.0, 0.0, -2.0),
    ) * Mat4::from_rotation_translation(
        Quat::from_rotation_x(45f32.to_radians()),
        Vec3::new(1.0, 1.0, 0.0),
    );
    assert!(
        cube.transform.matrix().abs_diff_eq(world_from_cube, 1e-4),
        "{:?}",
        cube.transform
    );
    assert_eq!(longest_voxels(cube), 16, "each node at its own --depth");
    let cube_edge = assert_voxels_on(cube, &node_triangles("Cube"));
    // 16 voxels across the cube's world edge of 2.
    assert!((cube_edge - 2.0 / 16.0).abs() < 1e-5, "{cube_edge}");

    // Slab: the parent's turn and the move are the object's; the 3x stretch is in its voxels,
    // which stay cubes.
    let slab = object(&doc, "Slab");
    assert!(slab.transform.scale.abs_diff_eq(Vec3::ONE, 1e-6));
    assert!(
        slab.transform
            .rotation
            .abs_diff_eq(Quat::from_rotation_y(30f32.to_radians()), 1e-5)
    );
    assert_eq!(longest_voxels(slab), 16);
    assert_voxels_on(slab, &node_triangles("Slab"));
    assert!(out.contains("object \"Slab\""), "{out}");
    assert!(out.contains("its scale baked in"), "{out}");

    // Ground: a mesh object, with a warning, placed where the file puts it.
    let ground = object(&doc, "Ground");
    let ObjectKind::Mesh(m) = &ground.kind else {
        panic!("the ground was voxelized: {out}");
    };
    assert_eq!(
        out.matches("warning: node \"Ground\" is a huge flat plane")
            .count(),
        1,
        "{out}"
    );
    let (lo, hi) = ground.world_bounds().unwrap();
    let plane_world = (Mat4::from_scale_rotation_translation(
        Vec3::splat(2.0),
        Quat::from_rotation_y(30f32.to_radians()),
        Vec3::new(5.0, 0.0, -2.0),
    ) * Mat4::from_translation(Vec3::new(0.0, -1.0, 0.0)))
    .transform_point3(Vec3::ZERO);
    assert!((lo.y - plane_world.y).abs() < 1e-3 && (hi.y - plane_world.y).abs() < 1e-3);
    assert!(
        (0.5 * (lo + hi)).abs_diff_eq(plane_world, 1e-2),
        "{lo} {hi}"
    );
    assert_eq!(m.model.triangle_count(), 2);

    // Asked to, the plane is voxelized like any node.
    let (_, doc) = import(dir.path(), &input, &["--depth", "4", "--voxelize-planes"]);
    assert!(matches!(object(&doc, "Ground").kind, ObjectKind::Voxels(_)));
}

#[test]
fn a_shared_voxel_size_is_in_world_units() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_scene(dir.path());
    let (out, doc) = import(dir.path(), &input, &["--voxel-size", "0.25"]);
    for name in ["Cube", "Slab"] {
        let edge = assert_voxels_on(object(&doc, name), &node_triangles(name));
        assert!((edge - 0.25).abs() < 1e-5, "{name}: {edge}\n{out}");
    }
}

#[test]
fn node_picks_nodes_and_merge_gives_one_grid() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_scene(dir.path());
    let (out, doc) = import(dir.path(), &input, &["--depth", "4", "--node", "Cube"]);
    assert_eq!(doc.objects.len(), 1, "{out}");
    assert_voxels_on(object(&doc, "Cube"), &node_triangles("Cube"));
    assert!(!out.contains("huge flat plane"), "{out}");
    let (_, doc) = import(
        dir.path(),
        &input,
        &["--depth", "4", "--node", "Slab", "--node", "Cube"],
    );
    assert_eq!(doc.objects.len(), 2);

    // A name the scene does not have: refused, listing the ones it has.
    let o = thicket(&[
        "import",
        input.to_str().unwrap(),
        "-o",
        dir.path().join("x.thicket.json").to_str().unwrap(),
        "--node",
        "Tree",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains(
            r#"no node named "Tree" (the nodes with meshes are "Cube", "Slab", "Ground")"#
        ),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("x.thicket.json").exists());
    // Only glTF scenes have nodes.
    let o = thicket(&[
        "import",
        &format!("{ASSETS}/static/spot/spot_triangulated.obj"),
        "-o",
        dir.path().join("x.thicket.json").to_str().unwrap(),
        "--node",
        "spot",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("is not a glTF file; only glTF scenes have nodes to pick"),
        "{}",
        stderr(&o)
    );

    // --merge: the old single grid over the whole scene, at the world's identity.
    let (out, doc) = import(dir.path(), &input, &["--depth", "6", "--merge"]);
    assert_eq!(doc.objects.len(), 1, "{out}");
    let merged = &doc.objects[0];
    assert_eq!(merged.transform, thicket_core::scene::Transform::default());
    // The plane (about 546 units across in the world) sets the grid: one voxel is wider than
    // the whole cube (2 units).
    let ObjectKind::Voxels(v) = &merged.kind else {
        panic!("not voxels");
    };
    assert!(v.voxel_size > 8.0, "{}", v.voxel_size);
    assert!(!out.contains("huge flat plane"), "{out}");
}

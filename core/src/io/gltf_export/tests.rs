use std::collections::{BTreeSet, HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use super::greedy::{count_exposed_faces, greedy_quads};
use super::iso::edge_use;
use super::*;
use crate::krs::{KrsScene, presets};
use crate::scene::{Document, ObjectKind, VoxelModel};
use crate::svo::{Svo, Voxel};
use crate::voxelize::{Mode, Resolution, VoxelizeSettings, voxelize};

const NO_PROGRESS: &dyn Fn(f32) -> bool = &|_| true;

fn house_path() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/vox/mmmm/obj_house4.vox"
    ))
}

fn doc_with(name: &str, svo: Svo, voxel_size: f32, origin: Vec3) -> Document {
    let mut doc = Document::default();
    doc.add(
        name,
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size,
            origin,
            material_names: vec!["stone".into(), "moss".into()],
            rig: None,
            volume: None,
            palette: Vec::new(),
            frames: None,
        }),
    );
    doc
}

/// A random blob: a union of boxes, with a few colours and two materials.
fn blob(seed: u64, depth: u8, boxes: usize) -> Svo {
    let mut rng = Pcg64::seed_from_u64(seed);
    let extent = 1u32 << depth;
    let colors = [[200, 30, 30, 255], [20, 180, 40, 255], [30, 40, 220, 255]];
    let mut voxels = Vec::new();
    for _ in 0..boxes {
        let lo = UVec3::new(
            rng.random_range(1..extent - 4),
            rng.random_range(1..extent - 4),
            rng.random_range(1..extent - 4),
        );
        // At least 2 voxels thick: the solid voxelizer keeps the surface voxels of parts
        // thinner than about 1.7 voxels (so thin parts never vanish), which would add a layer
        // to one-voxel walls in the round trip below.
        let size = UVec3::new(
            rng.random_range(2..5),
            rng.random_range(2..5),
            rng.random_range(2..5),
        );
        let color = colors[rng.random_range(0..colors.len())];
        let material = rng.random_range(0..2u8);
        for z in lo.z..(lo.z + size.z).min(extent) {
            for y in lo.y..(lo.y + size.y).min(extent) {
                for x in lo.x..(lo.x + size.x).min(extent) {
                    let mut v = Voxel::new(color, Vec3::Y);
                    v.material = material;
                    voxels.push((UVec3::new(x, y, z), v));
                }
            }
        }
    }
    Svo::from_voxels(depth, false, voxels).unwrap()
}

/// Exposed unit faces by brute force over a hash set: (voxel, axis, positive).
fn brute_faces(svo: &Svo) -> BTreeSet<([u32; 3], u8, bool)> {
    let solid: HashSet<UVec3> = svo.leaves().into_iter().map(|l| l.0).collect();
    let mut out = BTreeSet::new();
    for &c in &solid {
        for axis in 0..3u8 {
            for positive in [false, true] {
                let mut n = c.as_ivec3();
                n[usize::from(axis)] += if positive { 1 } else { -1 };
                if n.min_element() < 0 || !solid.contains(&n.as_uvec3()) {
                    out.insert((c.to_array(), axis, positive));
                }
            }
        }
    }
    out
}

#[test]
fn greedy_quads_cover_exactly_the_exposed_faces_with_their_colours() {
    for seed in 0..6 {
        let svo = blob(seed, 5, 12);
        let expected = brute_faces(&svo);
        assert_eq!(count_exposed_faces(&svo), expected.len() as u64);
        let quads = greedy_quads(&svo);
        let mut covered = BTreeSet::new();
        for q in &quads {
            let a = usize::from(q.axis);
            for dv in 0..q.height {
                for du in 0..q.width {
                    let mut c = [0u32; 3];
                    c[(a + 1) % 3] = q.u + du;
                    c[(a + 2) % 3] = q.v + dv;
                    c[a] = if q.positive { q.layer - 1 } else { q.layer };
                    let v = svo
                        .get(UVec3::from_array(c))
                        .expect("a quad covers a solid voxel");
                    assert_eq!((v.color, v.material), q.key, "quad mixes colours");
                    assert!(
                        covered.insert((c, q.axis, q.positive)),
                        "two quads cover {c:?}"
                    );
                }
            }
            // Corners wind counter-clockwise around the outward normal.
            let p = q.corners();
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            assert!(n.dot(q.normal()) > 0.0, "{q:?}");
        }
        assert_eq!(covered, expected, "seed {seed}");
        assert!(quads.len() < expected.len(), "merging merged something");
    }
}

#[test]
fn one_voxel_is_six_quads_and_a_uniform_box_too() {
    let mut svo = Svo::new(4, false).unwrap();
    svo.set(UVec3::new(3, 4, 5), Voxel::new([1, 2, 3, 255], Vec3::Y))
        .unwrap();
    assert_eq!(greedy_quads(&svo).len(), 6);
    let cube = Svo::from_voxels(
        4,
        false,
        (0..125).map(|i| {
            (
                UVec3::new(i % 5, (i / 5) % 5, i / 25),
                Voxel::new([9, 9, 9, 255], Vec3::Y),
            )
        }),
    )
    .unwrap();
    assert_eq!(count_exposed_faces(&cube), 150);
    assert_eq!(greedy_quads(&cube).len(), 6);
}

/// The voxel set back from a glTF file: import with the gltf crate, voxelize solid at the
/// export's voxel size, shift to the original grid.
fn reimport(path: &Path, voxel_size: f32, lo: UVec3) -> BTreeSet<([u32; 3], [u8; 4])> {
    let model = crate::io::import_gltf(path).unwrap();
    let settings = VoxelizeSettings {
        resolution: Resolution::VoxelSize(voxel_size),
        mode: Mode::Solid,
        ..VoxelizeSettings::default()
    };
    let v = voxelize(&model, &settings, NO_PROGRESS).unwrap();
    v.svo
        .leaves()
        .into_iter()
        .map(|(c, vox)| ((c + lo).to_array(), vox.color))
        .collect()
}

#[test]
fn export_import_voxelize_reproduces_the_voxel_set() {
    let dir = tempfile::tempdir().unwrap();
    for (seed, ext, colors) in [
        (1, "glb", ColorMode::VertexColors),
        (2, "gltf", ColorMode::VertexColors),
    ] {
        let svo = blob(seed, 5, 10);
        let expected: BTreeSet<([u32; 3], [u8; 4])> = svo
            .leaves()
            .into_iter()
            .map(|(c, v)| (c.to_array(), v.color))
            .collect();
        let (lo, _) = svo.bounds().unwrap();
        // Grid origin at the model's minimum corner: the voxelizer puts its grid there too.
        let voxel_size = 0.25;
        let doc = doc_with("blob", svo, voxel_size, Vec3::ZERO);
        let path = dir.path().join(format!("blob{seed}.{ext}"));
        let options = GltfExportOptions {
            colors,
            ..GltfExportOptions::default()
        };
        let report = export_gltf(&doc, &path, &options, NO_PROGRESS).unwrap();
        assert_eq!(report.objects, 1);
        let got = reimport(&path, voxel_size, lo);
        let coords = |set: &BTreeSet<([u32; 3], [u8; 4])>| -> BTreeSet<[u32; 3]> {
            set.iter().map(|e| e.0).collect()
        };
        let (want, have) = (coords(&expected), coords(&got));
        let lost: Vec<_> = want.difference(&have).take(5).collect();
        let gained: Vec<_> = have.difference(&want).take(5).collect();
        assert!(
            lost.is_empty() && gained.is_empty(),
            "seed {seed} {ext} {colors:?}: {} vs {} voxels; lost {lost:?}, gained {gained:?}",
            want.len(),
            have.len()
        );
    }
}

#[test]
fn house_greedy_mesh_has_far_fewer_triangles_than_per_face_cubes() {
    let scene = crate::io::vox::import_vox(&house_path()).unwrap();
    let ObjectKind::Voxels(v) = &scene.objects[0].kind else {
        panic!("the house is voxels")
    };
    let per_face = count_exposed_faces(&v.svo) * 2;
    let greedy = greedy_quads(&v.svo).len() as u64 * 2;
    assert!(
        greedy * 3 <= per_face,
        "greedy {greedy} triangles vs {per_face} per face"
    );
}

#[test]
fn gltf_writes_a_bin_beside_it_and_the_crate_reads_both_forms() {
    let dir = tempfile::tempdir().unwrap();
    let doc = doc_with("b", blob(7, 4, 4), 1.0, Vec3::new(1.0, 2.0, 3.0));
    let gltf_path = dir.path().join("my model.gltf");
    let report = export_gltf(&doc, &gltf_path, &GltfExportOptions::default(), NO_PROGRESS).unwrap();
    assert_eq!(report.files.len(), 2);
    assert!(dir.path().join("my model.bin").exists());
    let (gltf, buffers, _) = gltf::import(&gltf_path).unwrap();
    assert_eq!(buffers.len(), 1);
    let tris: usize = gltf
        .meshes()
        .flat_map(|m| m.primitives())
        .map(|p| p.indices().unwrap().count() / 3)
        .sum();
    assert_eq!(tris as u64, report.triangles);
    let glb_path = dir.path().join("m.glb");
    export_gltf(&doc, &glb_path, &GltfExportOptions::default(), NO_PROGRESS).unwrap();
    let (glb, _, _) = gltf::import(&glb_path).unwrap();
    let prim = glb.meshes().next().unwrap().primitives().next().unwrap();
    assert!(prim.get(&gltf::Semantic::Colors(0)).is_some());
    // Cubes carry no NORMAL: readers compute the faces' flat normals.
    assert!(prim.get(&gltf::Semantic::Normals).is_none());
    // Nothing but the outputs is left in the folder.
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["m.glb", "my model.bin", "my model.gltf"]);
}

fn assert_nothing_written(dir: &Path) {
    let left: Vec<_> = std::fs::read_dir(dir).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn bad_exports_fail_clearly_and_leave_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.glb");
    // An empty object, asked for by name; and a document with only empty objects.
    let empty = doc_with("Nothing", Svo::new(4, false).unwrap(), 1.0, Vec3::ZERO);
    let options = GltfExportOptions {
        object: Some("Nothing".into()),
        ..GltfExportOptions::default()
    };
    let e = export_gltf(&empty, &out, &options, NO_PROGRESS).unwrap_err();
    assert!(matches!(e, GltfExportError::NothingToExport { .. }), "{e}");
    assert!(
        e.to_string().contains("Nothing") && e.to_string().contains("out.glb"),
        "{e}"
    );
    let e = export_gltf(&empty, &out, &GltfExportOptions::default(), NO_PROGRESS).unwrap_err();
    assert!(e.to_string().contains("hidden or empty"), "{e}");
    // An unknown object name lists the real ones.
    let doc = doc_with("Rock", blob(1, 4, 3), 1.0, Vec3::ZERO);
    let options = GltfExportOptions {
        object: Some("Tree".into()),
        ..GltfExportOptions::default()
    };
    let e = export_gltf(&doc, &out, &options, NO_PROGRESS).unwrap_err();
    assert!(e.to_string().contains("\"Rock\""), "{e}");
    // Too many triangles: refused before the faces are built.
    let options = GltfExportOptions {
        max_triangles: 10,
        ..GltfExportOptions::default()
    };
    let e = export_gltf(&doc, &out, &options, NO_PROGRESS).unwrap_err();
    assert!(matches!(e, GltfExportError::TooLarge { .. }), "{e}");
    assert!(
        e.to_string().contains("--max-triangles") && e.to_string().contains("at most 10"),
        "{e}"
    );
    // Wrong extension.
    let e = export_gltf(
        &doc,
        &dir.path().join("x.obj"),
        &GltfExportOptions::default(),
        NO_PROGRESS,
    )
    .unwrap_err();
    assert!(e.to_string().contains(".glb or .gltf"), "{e}");
    assert_nothing_written(dir.path());
    // An unwritable place: a folder that does not exist, and a folder in place of the file.
    let e = export_gltf(
        &doc,
        &dir.path().join("no/such/dir/x.glb"),
        &GltfExportOptions::default(),
        NO_PROGRESS,
    )
    .unwrap_err();
    assert!(matches!(e, GltfExportError::Io { .. }), "{e}");
    std::fs::create_dir(dir.path().join("taken.glb")).unwrap();
    let e = export_gltf(
        &doc,
        &dir.path().join("taken.glb"),
        &GltfExportOptions::default(),
        NO_PROGRESS,
    )
    .unwrap_err();
    assert!(e.to_string().contains("taken.glb"), "{e}");
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["taken.glb"], "no temporary file is left behind");
    // A failing export leaves an existing file as it was.
    let keep = dir.path().join("keep.glb");
    std::fs::write(&keep, b"old").unwrap();
    let options = GltfExportOptions {
        max_triangles: 10,
        ..GltfExportOptions::default()
    };
    export_gltf(&doc, &keep, &options, NO_PROGRESS).unwrap_err();
    assert_eq!(std::fs::read(&keep).unwrap(), b"old");
}

#[test]
fn a_model_2_pow_21_voxels_wide_exports_exactly_or_is_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let far = (1u32 << 21) - 1;
    // Two voxels at opposite corners of a depth-21 octree: the sparse mesher costs 12 quads.
    let svo = Svo::from_voxels(
        21,
        false,
        [UVec3::ZERO, UVec3::splat(far)].map(|c| (c, Voxel::new([5, 6, 7, 255], Vec3::Y))),
    )
    .unwrap();
    let doc = doc_with("wide", svo, 1.0, Vec3::ZERO);
    let path = dir.path().join("wide.glb");
    let report = export_gltf(&doc, &path, &GltfExportOptions::default(), NO_PROGRESS).unwrap();
    assert_eq!(report.triangles, 24);
    let model = crate::io::import_gltf(&path).unwrap();
    let (lo, hi) = model.bounds().unwrap();
    assert_eq!(lo, Vec3::ZERO);
    // 2^21 is exact in f32: the far corner lands exactly.
    assert_eq!(hi, Vec3::splat((1u32 << 21) as f32));
    // A full 2^21-wide slab cannot be built in a test, but its face count is what the limit
    // checks first: a 64×64 wall over a 10-triangle limit is refused without building quads.
    let wall = Svo::from_voxels(
        21,
        false,
        (0..64 * 64).map(|i| {
            (
                UVec3::new(far - i % 64, i / 64, 0),
                Voxel::new([1, 1, 1, 255], Vec3::Y),
            )
        }),
    )
    .unwrap();
    let doc = doc_with("wall", wall, 1.0, Vec3::ZERO);
    let options = GltfExportOptions {
        max_triangles: 10,
        ..GltfExportOptions::default()
    };
    let out = dir.path().join("wall.glb");
    let e = export_gltf(&doc, &out, &options, NO_PROGRESS).unwrap_err();
    assert!(e.to_string().contains("wall"), "{e}");
    assert!(!out.exists());
    // KRS meshing at a 2^21 resolution is refused up front.
    let scene = KrsScene {
        objects: vec![presets::tree()],
    }
    .prepare()
    .unwrap();
    let e = mesh_krs(&scene.objects[0], 1 << 21, 1 << 26, NO_PROGRESS).unwrap_err();
    assert_eq!(e, FieldError::BadResolution(1 << 21));
}

/// Every undirected edge is used by exactly two triangles, once in each direction.
fn assert_watertight(indices: &[u32], what: &str) {
    assert!(!indices.is_empty(), "{what}: empty mesh");
    let (edges, repeated) = edge_use(indices);
    let bad: Vec<_> = edges.iter().filter(|e| *e.1 != 2).take(5).collect();
    assert!(
        bad.is_empty(),
        "{what}: edges not shared by two triangles: {bad:?}"
    );
    assert_eq!(repeated, 0, "{what}: inconsistent winding");
}

#[test]
fn krs_mesh_of_the_rock_is_watertight() {
    for (name, object, resolution) in [("rock", presets::rock(), 48)] {
        let scene = KrsScene {
            objects: vec![object],
        }
        .prepare()
        .unwrap();
        let o = &scene.objects[0];
        let mesh = mesh_krs(o, resolution, 1 << 24, NO_PROGRESS).unwrap();
        assert_watertight(&mesh.indices, name);
        // Vertices lie on the surface to within a cell.
        let (lo, hi) = krs_region(o).unwrap();
        let cell = (hi - lo).max_element() / resolution as f32;
        let worst = mesh
            .positions
            .iter()
            .map(|&p| o.distance_world(p).abs())
            .fold(0.0f32, f32::max);
        assert!(
            worst < cell,
            "{name}: vertex {worst} from the surface, cell {cell}"
        );
        // Outward winding: the normal of each triangle agrees with the field's normal.
        let mut agree = 0usize;
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| mesh.positions[i as usize]);
            let n = (b - a).cross(c - a);
            let field = mesh.normals[t[0] as usize];
            if n.dot(field) > 0.0 {
                agree += 1;
            }
        }
        let total = mesh.triangle_count();
        assert!(
            agree * 10 >= total * 9,
            "{name}: {agree} of {total} triangles face out"
        );
    }
}

/// A KRS object in a document exports through `export_gltf` (the CLI's path) as a non-empty
/// closed mesh in world space, placed by the object's transform. The tree preset at resolution
/// 96 used to come out empty: the whole-circle bounds of its gently bent branches (major radii
/// in the tens) swelled the object's bounding ball, the mesher's region, until its cells were
/// wider than the trunk.
#[test]
fn krs_tree_in_a_document_exports_a_watertight_mesh() {
    let mut doc = Document::default();
    let id = doc.add("Tree", ObjectKind::Krs(presets::tree()));
    let transform = crate::scene::Transform {
        translation: Vec3::new(5.0, 0.0, -3.0),
        rotation: glam::Quat::from_rotation_y(0.7),
        scale: Vec3::splat(2.0),
    };
    doc.objects
        .iter_mut()
        .find(|o| o.id == id)
        .unwrap()
        .transform = transform;
    let world = doc.objects[0].krs_in_world().unwrap();
    let prepared = KrsScene {
        objects: vec![world],
    }
    .prepare()
    .unwrap();
    let o = &prepared.objects[0];
    let resolution = 96;
    let (lo, hi) = krs_region(o).unwrap();
    let cell = (hi - lo).max_element() / resolution as f32;
    // The trunk (the route's first branch, the last kernel) is at least two cells wide.
    let trunk = match o.object.kernels.last().unwrap() {
        crate::krs::Kernel::Capsule(k) => k.radius,
        crate::krs::Kernel::ToroidalCapsule(k) | crate::krs::Kernel::TorusSegment(k) => {
            k.minor_radius
        }
        other => panic!("the trunk is a branch kernel, not {other:?}"),
    } * o.object.world_from_object.scale;
    assert!(
        trunk > cell,
        "trunk {trunk} vs cell {cell}: the region is far larger than the tree"
    );

    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tree.glb");
    let options = GltfExportOptions {
        resolution,
        ..GltfExportOptions::default()
    };
    let report = export_gltf(&doc, &out, &options, NO_PROGRESS).unwrap();
    assert_eq!(report.objects, 1);
    let (gltf, buffers, _) = gltf::import(&out).unwrap();
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for prim in gltf.meshes().flat_map(|m| m.primitives()) {
        let reader = prim.reader(|b| Some(&buffers[b.index()]));
        let base = positions.len() as u32;
        positions.extend(reader.read_positions().unwrap().map(Vec3::from));
        indices.extend(reader.read_indices().unwrap().into_u32().map(|i| i + base));
    }
    assert_eq!(indices.len() as u64 / 3, report.triangles);
    assert!(report.triangles > 1000, "{} triangles", report.triangles);
    assert_watertight(&indices, "exported tree");
    // In world space, on the placed tree: every vertex within a cell of its surface, and the
    // mesh spans the trunk base (at the translation) to near the crown's top.
    let worst = positions
        .iter()
        .map(|&p| o.distance_world(p).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < cell, "vertex {worst} from the surface, cell {cell}");
    let (mlo, mhi) = positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(a, b), &p| (a.min(p), b.max(p)),
    );
    // The trunk's capsule ends in a half ball below the route's first point.
    assert!(
        (mlo.y - (transform.translation.y - trunk)).abs() < 2.0 * cell,
        "base at {}",
        mlo.y
    );
    assert!(
        mhi.y - mlo.y > 0.5 * (hi.y - lo.y),
        "{mlo}..{mhi} in {lo}..{hi}"
    );
}

#[test]
fn krs_meshing_visits_only_cells_near_the_surface() {
    let scene = KrsScene {
        objects: vec![presets::rock()],
    }
    .prepare()
    .unwrap();
    let o = &scene.objects[0];
    let coarse = mesh_krs(o, 32, 1 << 24, NO_PROGRESS).unwrap();
    let fine = mesh_krs(o, 64, 1 << 24, NO_PROGRESS).unwrap();
    // Surface work: doubling the resolution multiplies triangles by about 4, not 8.
    let ratio = fine.triangle_count() as f64 / coarse.triangle_count() as f64;
    assert!((3.0..5.5).contains(&ratio), "ratio {ratio}");
}

#[test]
fn smooth_voxel_surface_is_watertight_and_keeps_thin_parts() {
    // A blob plus a one-voxel-thick wall and a lone voxel.
    let mut svo = blob(5, 5, 8);
    for y in 0..6 {
        for z in 0..6 {
            svo.set(UVec3::new(30, y, z), Voxel::new([1, 2, 3, 255], Vec3::X))
                .unwrap();
        }
    }
    svo.set(UVec3::new(0, 31, 0), Voxel::new([1, 2, 3, 255], Vec3::X))
        .unwrap();
    let mesh = fields::mesh_voxels_smooth(&svo, 4, 1 << 24).unwrap();
    assert_watertight(&mesh.indices, "smooth");
    // Every voxel centre is inside the surface: a ray to +x from each centre crosses it an odd
    // number of times (checked for the thin wall and the lone voxel).
    for c in [UVec3::new(30, 2, 2), UVec3::new(0, 31, 0)] {
        let p = c.as_vec3() + 0.5 + Vec3::new(0.0, 0.013, 0.007);
        let mut crossings = 0;
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, cc] = [t[0], t[1], t[2]].map(|i| mesh.positions[i as usize]);
            if ray_hits_triangle(p, Vec3::X, a, b, cc) {
                crossings += 1;
            }
        }
        assert_eq!(crossings % 2, 1, "voxel {c} is inside the smooth surface");
    }
}

/// Möller–Trumbore, for the inside test above.
fn ray_hits_triangle(o: Vec3, d: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-9 {
        return false;
    }
    let s = o - a;
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    let t = e2.dot(q) / det;
    (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && t > 0.0
}

#[test]
fn mesh_objects_and_smooth_mode_export_and_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = doc_with("blob", blob(9, 4, 5), 0.5, Vec3::ZERO);
    let quad = crate::mesh::TriangleMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z],
        normals: vec![Vec3::Y; 4],
        indices: vec![0, 2, 1, 0, 3, 2],
        ..Default::default()
    };
    doc.add(
        "Ground",
        ObjectKind::Mesh(crate::scene::MeshObject {
            model: crate::mesh::MeshModel {
                parts: vec![quad],
                materials: vec![crate::mesh::Material::default()],
            },
            casts_shadows: false,
        }),
    );
    doc.objects[1].transform.translation = Vec3::new(0.0, -1.0, 0.0);
    let path = dir.path().join("smooth.glb");
    let options = GltfExportOptions {
        mode: ExportMode::Smooth,
        ..GltfExportOptions::default()
    };
    let report = export_gltf(&doc, &path, &options, NO_PROGRESS).unwrap();
    assert_eq!(report.objects, 2);
    let model = crate::io::import_gltf(&path).unwrap();
    let tris: usize = model.parts.iter().map(|p| p.triangle_count()).sum();
    assert_eq!(tris as u64, report.triangles);
    // The ground keeps its transform: its vertices come back at y = -1.
    assert!(
        model
            .parts
            .iter()
            .any(|p| p.triangle_count() == 2 && p.positions.iter().all(|v| v.y == -1.0))
    );
}

/// Share of triangles whose winding normal agrees with the stored vertex normal.
fn outward_share(mesh: &ColoredMesh) -> f64 {
    let agree = mesh
        .indices
        .chunks_exact(3)
        .filter(|t| {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| mesh.positions[i as usize]);
            (b - a).cross(c - a).dot(mesh.normals[t[0] as usize]) > 0.0
        })
        .count();
    agree as f64 / mesh.triangle_count().max(1) as f64
}

#[test]
fn krs_instances_place_every_kernel_instance_without_mirroring_transforms() {
    let prepared = KrsScene {
        objects: vec![presets::tree()],
    }
    .prepare()
    .unwrap();
    let o = &prepared.objects[0];
    let kernels = krs_instances(o, 12, 1 << 20).unwrap();
    let total: usize = kernels
        .iter()
        .map(|k| k.transforms.len() + k.mirrored_transforms.len())
        .sum();
    assert_eq!(total as u128, o.object.instance_count());
    assert!(kernels.iter().any(|k| !k.mirrored_transforms.is_empty()));
    // Every kernel meshes closed, the thinnest twig too (a kernel thinner than a cell of the
    // 12-cell box used to mesh empty: thin kernels get MIN_CELLS_ACROSS cells across), and
    // the mirrored copies wind outward too.
    let non_empty = o.object.kernels.iter().filter(|k| !k.is_empty()).count();
    assert_eq!(kernels.len(), non_empty);
    for k in &kernels {
        assert_watertight(&k.mesh.indices, "kernel mesh");
        assert_watertight(&k.mirrored_mesh.indices, "mirrored kernel mesh");
        assert!(outward_share(&k.mesh) > 0.9);
        assert!(
            outward_share(&k.mirrored_mesh) > 0.9,
            "mirrored winding flipped"
        );
    }
    let flip = Vec3::new(-1.0, 1.0, 1.0);
    for inst in o.instances(1 << 20) {
        let (trs, mirrored) = super::instances::proper_trs(&inst.world_from_kernel);
        assert_eq!(mirrored, inst.mirrored);
        assert!(trs.scale.min_element() > 0.0);
        for p in [Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(0.3, -0.2, 0.5)] {
            let q = if mirrored { p * flip } else { p };
            let a = trs.transform_point(q);
            let b = inst.world_from_kernel.transform_point3(p);
            assert!((a - b).length() < 1e-4, "{a} vs {b}");
        }
    }
    // Half-spaces cannot be instanced: a clear error, not an empty file.
    let rock = KrsScene {
        objects: vec![presets::rock()],
    }
    .prepare()
    .unwrap();
    let e = krs_instances(&rock.objects[0], 12, 1 << 20).unwrap_err();
    assert!(e.to_string().contains("cubes mode"), "{e}");
    // The instance count is checked before any instance is enumerated.
    let e = krs_instances(o, 12, 10).unwrap_err();
    assert!(matches!(e, FieldError::TooManyInstances { .. }), "{e}");
}

/// World positions of a node's mesh drawn by one of its instances.
fn instance_world(node: &ExportNode, i: usize) -> Vec<Vec3> {
    let t = node.instances[i];
    node.primitives[0]
        .positions
        .iter()
        .map(|&p| t.transform_point(p))
        .collect()
}

fn aabb(points: impl IntoIterator<Item = Vec3>) -> (Vec3, Vec3) {
    points
        .into_iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        })
}

#[test]
fn forest_is_one_tree_prototype_placed_where_the_krs_puts_its_trees() {
    let mut forest = presets::forest_with_mirrors(3);
    forest.world_from_object = crate::krs::Similarity {
        translation: Vec3::new(3.0, -1.0, 2.0),
        rotation: glam::Quat::from_rotation_y(0.7),
        scale: 1.5,
    };
    let prepared = KrsScene {
        objects: vec![forest],
    }
    .prepare()
    .unwrap();
    let o = &prepared.objects[0];
    let n = o.object.mirrors.len();
    let level = o.auto_placement_level();
    assert_eq!(level, n - 3, "the three forest mirrors place trees");
    assert_eq!(level, o.object.lowest_placement_level());
    let mut scene = ExportScene::default();
    // The placements alone: no levels of detail (they are checked below).
    let options = GltfExportOptions {
        resolution: 48,
        instanced_lod_levels: 0,
        ..GltfExportOptions::default()
    };
    let (tris, instancing) =
        add_krs_object(&mut scene, "forest", o, &options, NO_PROGRESS).unwrap();
    let instancing = instancing.expect("instanced");
    assert_eq!(instancing.instances, 8);
    assert_eq!(instancing.mirrored, 4);
    assert_eq!(scene.nodes.len(), 2, "one tree mesh and its mirrored copy");
    assert_eq!(tris, 2 * instancing.prototype_triangles);
    assert!(instancing.prototype_triangles > 1000);
    // The trunk (the prototype's top kernel) of every tree the KRS enumerates is where some
    // exported instance puts the prototype's trunk, one for one.
    let crate::krs::KernelBound::Sphere(trunk, _) = o.object.kernels[level].bound() else {
        panic!("the trunk is bounded");
    };
    let flip = Vec3::new(-1.0, 1.0, 1.0);
    let mut exported: Vec<Vec3> = Vec::new();
    for node in &scene.nodes {
        let mirrored = node.name.ends_with("mirrored");
        for t in &node.instances {
            exported.push(t.transform_point(if mirrored { trunk * flip } else { trunk }));
        }
    }
    let trunks: Vec<Vec3> = o
        .instances(1 << 20)
        .iter()
        .filter(|i| i.kernel == level)
        .map(|i| i.world_from_kernel.transform_point3(trunk))
        .collect();
    assert_eq!(trunks.len(), 8);
    for t in &trunks {
        let matches = exported.iter().filter(|e| e.distance(*t) < 1e-3).count();
        assert_eq!(matches, 1, "trunk at {t}: {exported:?}");
    }
    // Bounds: the prototype mesh's box through every instance against the KRS object's own
    // kernel-instance balls (which contain the surface) and its own distance-field mesh.
    let (lo, hi) = aabb(
        scene
            .nodes
            .iter()
            .flat_map(|node| (0..node.instances.len()).flat_map(move |i| instance_world(node, i))),
    );
    let (klo, khi) = aabb(o.instances(1 << 20).iter().flat_map(|i| {
        let crate::krs::KernelBound::Sphere(c, r) = o.object.kernels[i.kernel].bound() else {
            return Vec::new();
        };
        let c = i.world_from_kernel.transform_point3(c);
        let r = r * 1.5;
        vec![c - Vec3::splat(r), c + Vec3::splat(r)]
    }));
    let proto_box = aabb(scene.nodes[0].primitives[0].positions.iter().copied());
    let cell = 1.5 * (proto_box.1 - proto_box.0).max_element() / 48.0;
    assert!(
        lo.cmpge(klo - cell).all() && hi.cmple(khi + cell).all(),
        "instances {lo}..{hi} outside the kernel instances' balls {klo}..{khi}"
    );
    let (rlo, rhi) = fields::krs_region(o).unwrap();
    let resolution = ((rhi - rlo).max_element() / cell).ceil() as u32;
    let whole = mesh_krs(o, resolution, u64::MAX, NO_PROGRESS).unwrap();
    let (wlo, whi) = aabb(whole.positions.iter().copied());
    assert!(
        (lo - wlo).abs().max_element() < 2.0 * cell && (hi - whi).abs().max_element() < 2.0 * cell,
        "instanced {lo}..{hi} vs the whole object's mesh {wlo}..{whi} (cell {cell})"
    );
}

#[test]
fn mirrored_placement_draws_outward_faces_on_the_krs_surface() {
    let material = crate::krs::Material::new(Vec3::new(0.5, 0.3, 0.2), 1);
    let object = crate::krs::KrsObject {
        name: "pair".to_owned(),
        kernels: vec![
            crate::krs::Kernel::Capsule(crate::krs::CapsuleKernel {
                start: Vec3::ZERO,
                end: Vec3::new(1.0, 1.0, 0.5),
                radius: 0.3,
                material,
            }),
            crate::krs::Kernel::Empty,
        ],
        mirrors: vec![crate::krs::MirrorPlane::new(Vec3::new(1.0, 0.2, 0.1), 2.0)],
        world_from_object: crate::krs::Similarity {
            translation: Vec3::new(0.0, 1.0, 0.0),
            rotation: glam::Quat::from_rotation_x(0.4),
            scale: 2.0,
        },
        ..crate::krs::KrsObject::default()
    };
    let prepared = KrsScene {
        objects: vec![object],
    }
    .prepare()
    .unwrap();
    let o = &prepared.objects[0];
    let mut scene = ExportScene::default();
    let options = GltfExportOptions {
        resolution: 32,
        ..GltfExportOptions::default()
    };
    let (_, instancing) = add_krs_object(&mut scene, "pair", o, &options, NO_PROGRESS).unwrap();
    assert_eq!(instancing.unwrap().level, 0);
    assert_eq!(scene.nodes.len(), 2);
    let plain = &scene.nodes[0];
    let mirrored = &scene.nodes[1];
    assert_eq!((plain.instances.len(), mirrored.instances.len()), (1, 1));
    let cell = 2.0 * 1.8 / 32.0;
    for node in [plain, mirrored] {
        let t = node.instances[0];
        assert!(t.scale.min_element() > 0.0, "no instance transform mirrors");
        let world = instance_world(node, 0);
        let prim = &node.primitives[0];
        let mut outward = 0;
        let mut on_surface = 0;
        for tri in prim.indices.chunks_exact(3) {
            let [a, b, c] = [tri[0], tri[1], tri[2]].map(|i| world[i as usize]);
            let centre = (a + b + c) / 3.0;
            let (sample, krs_normal) = o.sample_world(centre);
            if sample.distance.abs() < cell {
                on_surface += 1;
            }
            let face = (b - a).cross(c - a);
            let vertex_normal = t.rotation * prim.normals[tri[0] as usize];
            if face.dot(krs_normal) > 0.0 && vertex_normal.dot(krs_normal) > 0.5 {
                outward += 1;
            }
        }
        let count = prim.indices.len() / 3;
        assert!(count > 200, "{}: {count} triangles", node.name);
        assert!(
            on_surface as f64 > 0.99 * count as f64,
            "{}: {on_surface} of {count} triangles on the KRS surface",
            node.name
        );
        assert!(
            outward as f64 > 0.97 * count as f64,
            "{}: {outward} of {count} triangles wound and lit outward",
            node.name
        );
    }
    // The mirrored copy is the one past the mirror plane.
    let m = o.object.mirrors[0];
    let side = |node: &ExportNode| {
        let (lo, hi) = aabb(instance_world(node, 0));
        m.signed_distance(o.object_from_world((lo + hi) * 0.5))
    };
    assert!(side(plain) < 0.0 && side(mirrored) > 0.0);
}

#[test]
fn placement_split_keeps_mirrors_that_clip_and_refuses_levels_below_kernels() {
    let material = crate::krs::Material::new(Vec3::ONE, 1);
    // The ball crosses the mirror: Algorithm 1 clips it there, so a copy would not match.
    let object = crate::krs::KrsObject {
        name: "clipped".to_owned(),
        kernels: vec![
            crate::krs::Kernel::Sphere(crate::krs::SphereKernel {
                centre: Vec3::new(1.5, 0.0, 0.0),
                radius: 1.0,
                material,
            }),
            crate::krs::Kernel::Empty,
        ],
        mirrors: vec![crate::krs::MirrorPlane::new(Vec3::X, 2.0)],
        ..crate::krs::KrsObject::default()
    };
    let clipped = KrsScene {
        objects: vec![object.clone()],
    }
    .prepare()
    .unwrap();
    assert_eq!(clipped.objects[0].object.lowest_placement_level(), 0);
    assert_eq!(clipped.objects[0].auto_placement_level(), 1);
    let mut scene = ExportScene::default();
    let options = GltfExportOptions {
        resolution: 24,
        ..GltfExportOptions::default()
    };
    let (_, inst) =
        add_krs_object(&mut scene, "c", &clipped.objects[0], &options, NO_PROGRESS).unwrap();
    assert!(inst.is_none(), "one mesh");
    assert!(scene.nodes[0].instances.is_empty());
    // A forest's tree levels carry kernels: they cannot be placements.
    let forest = KrsScene {
        objects: vec![presets::forest_with_mirrors(2)],
    }
    .prepare()
    .unwrap();
    let lowest = forest.objects[0].object.lowest_placement_level();
    let e = add_krs_object(
        &mut ExportScene::default(),
        "f",
        &forest.objects[0],
        &GltfExportOptions {
            instance_level: Some(lowest - 1),
            ..options.clone()
        },
        NO_PROGRESS,
    )
    .unwrap_err();
    assert!(matches!(e, FieldError::BadInstanceLevel(_)), "{e}");
    assert!(e.to_string().contains("--instance-level"), "{e}");
    // Too many placements: the figure and the flag in the message.
    let e = add_krs_object(
        &mut ExportScene::default(),
        "f",
        &forest.objects[0],
        &GltfExportOptions {
            max_instances: 3,
            ..options
        },
        NO_PROGRESS,
    )
    .unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("4 instances") && text.contains("--max-instances"),
        "{text}"
    );
}

#[test]
fn unbounded_ground_is_written_as_a_patch_under_the_other_objects() {
    let mut doc = Document::default();
    let mut tree = presets::tree();
    tree.world_from_object.translation = Vec3::new(10.0, 0.0, -4.0);
    doc.add("tree", ObjectKind::Krs(tree));
    let ground = crate::krs::KrsObject {
        name: "ground".to_owned(),
        kernels: vec![crate::krs::Kernel::InfinitePlane(crate::krs::PlaneKernel {
            normal: Vec3::Y,
            offset: 0.5,
            material: crate::krs::Material::new(Vec3::new(0.3, 0.4, 0.2), 2),
        })],
        ..crate::krs::KrsObject::default()
    };
    doc.add("ground", ObjectKind::Krs(ground.clone()));
    let options = GltfExportOptions {
        resolution: 32,
        ..GltfExportOptions::default()
    };
    let (scene, report) = build_scene(&doc, Path::new("g.glb"), &options, NO_PROGRESS).unwrap();
    assert_eq!(report.patches.len(), 1);
    let (name, lo, hi) = &report.patches[0];
    assert_eq!(name, "ground");
    let tree_box = node_bounds(&scene, &scene.nodes[0]).unwrap();
    let span = tree_box.1 - tree_box.0;
    let margin = (span.x.max(span.z) * PATCH_MARGIN).max(1.0);
    assert!(
        (lo.x - (tree_box.0.x - margin)).abs() < 1e-3,
        "{lo} {tree_box:?}"
    );
    assert!(
        (hi.z - (tree_box.1.z + margin)).abs() < 1e-3,
        "{hi} {tree_box:?}"
    );
    let patch = scene.nodes.iter().find(|n| n.name == "ground").unwrap();
    let prim = &patch.primitives[0];
    let cell = (*hi - *lo).max_element() / 32.0;
    let (plo, phi) = aabb(prim.positions.iter().copied());
    // Only the plane's surface: flat at y = 0.5, facing up, covering the patch to a cell.
    assert!((plo.y - 0.5).abs() < 0.1 * cell && (phi.y - 0.5).abs() < 0.1 * cell);
    assert!((plo.x - lo.x).abs() < 1.5 * cell && (phi.z - hi.z).abs() < 1.5 * cell);
    for t in prim.indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| prim.positions[i as usize]);
        assert!((b - a).cross(c - a).y > 0.0, "a patch triangle faces down");
    }
    // Explicit bounds win; an unbounded object alone needs them.
    let bounds = GltfExportOptions {
        bounds: Some([-2.0, -3.0, 4.0, 5.0]),
        ..options.clone()
    };
    let (_, report) = build_scene(&doc, Path::new("g.glb"), &bounds, NO_PROGRESS).unwrap();
    let (_, lo, hi) = &report.patches[0];
    assert_eq!((lo.x, lo.z, hi.x, hi.z), (-2.0, -3.0, 4.0, 5.0));
    let mut alone = Document::default();
    alone.add("ground", ObjectKind::Krs(ground));
    let e = build_scene(&alone, Path::new("g.glb"), &options, NO_PROGRESS).unwrap_err();
    assert!(e.to_string().contains("--bounds"), "{e}");
    let (_, report) = build_scene(&alone, Path::new("g.glb"), &bounds, NO_PROGRESS).unwrap();
    assert_eq!(report.patches.len(), 1);
}

#[test]
fn an_orthographic_view_exports_an_orthographic_camera_with_a_near_plane_in_front() {
    let mut svo = Svo::new(3, false).unwrap();
    svo.set(UVec3::new(1, 2, 3), Voxel::new([90, 90, 90, 255], Vec3::Y))
        .unwrap();
    let mut doc = doc_with("cube", svo, 0.5, Vec3::ZERO);
    doc.camera.orthographic = true;
    doc.camera.near = -6.0;
    doc.camera.far = 9.0;
    doc.camera.distance = 3.0;
    let (eye, hh) = (doc.camera.eye(), doc.camera.ortho_half_height());
    let back = (eye - doc.camera.target).normalize_or_zero();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ortho.glb");
    let report = export_gltf(&doc, &out, &GltfExportOptions::default(), NO_PROGRESS).unwrap();
    assert!(report.camera);
    let (gltf, _, _) = gltf::import(&out).unwrap();
    let node = gltf.nodes().find(|n| n.camera().is_some()).unwrap();
    let camera = node.camera().unwrap();
    let gltf::camera::Projection::Orthographic(o) = camera.projection() else {
        panic!("a perspective camera for an orthographic view");
    };
    assert!((o.ymag() - hh).abs() < 1e-5 && (o.xmag() - hh).abs() < 1e-5);
    // The planes keep their place in the world: the node is pulled back along the view axis
    // until the near plane lies in front of it (glTF's znear is a distance, at least 0).
    assert!(o.znear() >= 0.0, "{}", o.znear());
    let (t, _, _) = node.transform().decomposed();
    let pulled = (Vec3::from(t) - eye).dot(back);
    assert!((pulled - (o.znear() + 6.0)).abs() < 1e-4, "{pulled}");
    assert!(((o.zfar() - pulled) - 9.0).abs() < 1e-4);
}

/// Triangles of a level's primitives.
fn level_triangles(prims: &[ExportPrimitive]) -> usize {
    prims.iter().map(|p| p.indices.len() / 3).sum()
}

/// Every level of detail of a KRS mesh is closed, wound outward, strictly coarser than the
/// one before, on the surface (`distance`, in the node's space) to within its own cell, and
/// spans the same box as the full mesh to within that cell.
fn assert_krs_levels(
    node: &ExportNode,
    distance: &dyn Fn(Vec3) -> f32,
    region: (Vec3, Vec3),
    resolution: u32,
    levels: usize,
) {
    assert_eq!(node.lods.len(), levels, "{}: levels", node.name);
    let (flo, fhi) = aabb(node.primitives[0].positions.iter().copied());
    let mut finer = level_triangles(&node.primitives);
    for (k, level) in node.lods.iter().enumerate() {
        let what = format!("{} level {}", node.name, k + 1);
        let [prim] = &level[..] else {
            panic!("{what}: one primitive");
        };
        assert_watertight(&prim.indices, &what);
        // Closed and consistently wound (above), so a positive enclosed volume means every
        // component faces outward as a whole (a reflected copy that kept its winding would
        // enclose a negative one).
        let volume: f64 = prim
            .indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| prim.positions[i as usize].as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        assert!(volume > 0.0, "{what}: wound inward (volume {volume})");
        let tris = prim.indices.len() / 3;
        assert!(
            tris > 0 && tris < finer,
            "{what}: {tris} triangles after {finer}"
        );
        finer = tris;
        let cell = (region.1 - region.0).max_element() / (resolution >> (k + 1)) as f32;
        let worst = prim
            .positions
            .iter()
            .map(|&p| distance(p).abs())
            .fold(0.0f32, f32::max);
        assert!(
            worst < cell,
            "{what}: a vertex {worst} from the surface, cell {cell}"
        );
        let (lo, hi) = aabb(prim.positions.iter().copied());
        let off = (lo - flo).abs().max((hi - fhi).abs()).max_element();
        assert!(
            off <= cell,
            "{what}: box {lo}..{hi} vs the full mesh's {flo}..{fhi}: {off} apart, cell {cell}"
        );
    }
}

#[test]
fn krs_levels_of_detail_are_coarser_closed_and_carry_the_placements() {
    // Four trees: the prototype tree and its mirrored copy, each with coarser levels.
    let prepared = KrsScene {
        objects: vec![presets::forest_with_mirrors(2)],
    }
    .prepare()
    .unwrap();
    let o = &prepared.objects[0];
    let level = o.auto_placement_level();
    let resolution = 96;
    // The mesh levels (the impostor is checked in `forest_cells_...`).
    let options = GltfExportOptions {
        resolution,
        instanced_lod_levels: 3,
        impostor: false,
        ..GltfExportOptions::default()
    };
    let mut scene = ExportScene::default();
    let (tris, instancing) =
        add_krs_object(&mut scene, "forest", o, &options, NO_PROGRESS).unwrap();
    let instancing = instancing.expect("instanced");
    assert_eq!((instancing.instances, instancing.mirrored), (4, 2));
    let [plain, mirrored] = &scene.nodes[..] else {
        panic!("a plain and a mirrored prototype node");
    };
    let prototype = KrsScene {
        objects: vec![o.object.prototype(level)],
    }
    .prepare()
    .unwrap();
    let tree = &prototype.objects[0];
    let region = krs_region(tree).unwrap();
    // 96 → 48 → 24 cells; at 12 the outer twigs (thinner than a cell) vanish and the crown's
    // box shrinks by two cells, so that level and any after it are left out.
    assert_krs_levels(plain, &|p| tree.distance_world(p), region, resolution, 2);
    // The mirrored node's levels are the plain node's reflected (x → −x).
    let flip = Vec3::new(-1.0, 1.0, 1.0);
    let mirrored_region = aabb([region.0 * flip, region.1 * flip]);
    assert_krs_levels(
        mirrored,
        &|p| tree.distance_world(p * flip),
        mirrored_region,
        resolution,
        2,
    );
    let twelve = mesh_krs(tree, 12, u64::MAX, NO_PROGRESS).unwrap();
    let (lo, hi) = aabb(twelve.positions.iter().copied());
    let (flo, fhi) = aabb(plain.primitives[0].positions.iter().copied());
    let cell = (region.1 - region.0).max_element() / 12.0;
    assert!(
        (lo - flo).abs().max((hi - fhi).abs()).max_element() > cell,
        "the level at 12 cells keeps the box: it should have been written"
    );
    let all: usize = scene
        .nodes
        .iter()
        .map(|n| {
            level_triangles(&n.primitives)
                + n.lods.iter().map(|l| level_triangles(l)).sum::<usize>()
        })
        .sum();
    assert_eq!(tris, all as u64, "every level counts against the budget");

    // In the file each level is a node outside the scene that carries the very placements of
    // the full node (a level replaces the whole node), with one screen coverage per level.
    let glb = encode_glb(&scene, Path::new("forest.glb")).unwrap();
    // The GLB's JSON chunk: its length at byte 12, its bytes from byte 20.
    let root = glb_json(&glb);
    let nodes = root["nodes"].as_array().unwrap();
    let in_scene: Vec<u64> = root["scenes"][0]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert_eq!(in_scene.len(), 2);
    for &i in &in_scene {
        let node = &nodes[i as usize];
        let placements = &node["extensions"]["EXT_mesh_gpu_instancing"];
        assert!(placements["attributes"]["TRANSLATION"].is_u64(), "{node}");
        let ids = node["extensions"]["MSFT_lod"]["ids"].as_array().unwrap();
        assert_eq!(ids.len(), 2);
        assert_eq!(
            node["extras"]["MSFT_screencoverage"],
            serde_json::json!([0.5, 0.25, 0.0])
        );
        for id in ids {
            let id = id.as_u64().unwrap();
            assert!(!in_scene.contains(&id), "a level is not drawn by itself");
            let lod = &nodes[id as usize];
            assert_eq!(&lod["extensions"]["EXT_mesh_gpu_instancing"], placements);
            assert!(lod["mesh"].is_u64());
        }
    }
    assert!(
        root["extensionsUsed"]
            .as_array()
            .unwrap()
            .contains(&serde_json::json!("MSFT_lod"))
    );

    // The budget covers every level: enough for the full meshes alone is refused, naming the
    // level and the flag.
    let e = add_krs_object(
        &mut ExportScene::default(),
        "forest",
        o,
        &GltfExportOptions {
            max_triangles: 2 * instancing.prototype_triangles + 10,
            ..options.clone()
        },
        NO_PROGRESS,
    )
    .unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("level of detail 1") && text.contains("--max-triangles"),
        "{text}"
    );

    // A non-instanced KRS object (the rock) gets levels the same way; levels stop at
    // MIN_LOD_RESOLUTION cells (48 → 24 → 12, not 6).
    let rock = KrsScene {
        objects: vec![presets::rock()],
    }
    .prepare()
    .unwrap();
    let mut scene = ExportScene::default();
    let (_, instancing) = add_krs_object(
        &mut scene,
        "rock",
        &rock.objects[0],
        &GltfExportOptions {
            resolution: 48,
            lod_levels: 4,
            ..GltfExportOptions::default()
        },
        NO_PROGRESS,
    )
    .unwrap();
    assert!(instancing.is_none());
    assert_eq!(scene.nodes.len(), 1);
    assert!(scene.nodes[0].instances.is_empty());
    let rock = &rock.objects[0];
    assert_krs_levels(
        &scene.nodes[0],
        &|p| rock.distance_world(p),
        krs_region(rock).unwrap(),
        48,
        2,
    );
}

/// The instance transforms of `nodes` whose names end (or not) in "mirrored", as exact bit
/// patterns in a canonical order, to compare as multisets.
fn placements_of<'a>(
    nodes: impl IntoIterator<Item = &'a ExportNode>,
    mirrored: bool,
) -> Vec<[u32; 10]> {
    let mut out: Vec<[u32; 10]> = nodes
        .into_iter()
        .filter(|n| n.name.ends_with("mirrored") == mirrored)
        .flat_map(|n| &n.instances)
        .map(|t| {
            let v = [
                t.translation.x,
                t.translation.y,
                t.translation.z,
                t.rotation.x,
                t.rotation.y,
                t.rotation.z,
                t.rotation.w,
                t.scale.x,
                t.scale.y,
                t.scale.z,
            ];
            v.map(f32::to_bits)
        })
        .collect();
    out.sort_unstable();
    out
}

#[test]
fn forest_cells_partition_the_placements_and_share_the_levels() {
    // 64 trees, half of them mirrored.
    let prepared = KrsScene {
        objects: vec![presets::forest_with_mirrors(6)],
    }
    .prepare()
    .unwrap();
    let o = &prepared.objects[0];
    // 48 cells, and a level at 24 (which keeps the crown's box).
    let base = GltfExportOptions {
        resolution: 48,
        instanced_lod_levels: 1,
        ..GltfExportOptions::default()
    };
    // One cell: a plain and a mirrored node, as before cells.
    let mut single = ExportScene::default();
    let one = GltfExportOptions {
        cells: Some(1),
        ..base.clone()
    };
    let (single_tris, single_report) =
        add_krs_object(&mut single, "forest", o, &one, NO_PROGRESS).unwrap();
    let single_report = single_report.expect("instanced");
    assert_eq!((single_report.instances, single_report.mirrored), (64, 32));
    assert_eq!(single.nodes.len(), 2);
    assert_eq!((single_report.cells, single_report.cell_nodes), ([1, 1], 2));

    let mut scene = ExportScene::default();
    let options = GltfExportOptions {
        cells: Some(16),
        ..base.clone()
    };
    let (tris, report) = add_krs_object(&mut scene, "forest", o, &options, NO_PROGRESS).unwrap();
    let report = report.expect("instanced");
    assert!(report.impostor);
    assert_eq!(report.cells[0] * report.cells[1], 16, "{report:?}");
    assert_eq!(report.cell_nodes as usize, scene.nodes.len());
    assert!(scene.nodes.len() > 2, "the trees spread over several cells");
    // The meshes are written once, whatever the cells: the same triangles.
    assert_eq!(tris, single_tris);
    // Every placement in exactly one cell, with the very transform it had in one node.
    for mirrored in [false, true] {
        assert_eq!(
            placements_of(&scene.nodes, mirrored),
            placements_of(&single.nodes, mirrored),
            "mirrored: {mirrored}"
        );
    }
    assert_eq!(
        scene
            .nodes
            .iter()
            .map(|n| n.instances.len() as u64)
            .sum::<u64>(),
        report.instances
    );
    // No instance transform mirrors; each cell's trees stand in that cell of the grid (their
    // centres, as the grid was laid over them).
    let proto_box = aabb(scene.nodes[0].primitives[0].positions.iter().copied());
    let centre = (proto_box.0 + proto_box.1) * 0.5;
    let flip = Vec3::new(-1.0, 1.0, 1.0);
    let spot = |n: &ExportNode, t: &InstanceTransform| {
        t.transform_point(if n.name.ends_with("mirrored") {
            centre * flip
        } else {
            centre
        })
    };
    let spots: Vec<Vec3> = scene
        .nodes
        .iter()
        .flat_map(|n| n.instances.iter().map(move |t| spot(n, t)))
        .collect();
    let grid = CellGrid::over(&spots, 16);
    assert_eq!([grid.columns, grid.rows], report.cells);
    let mut cells_seen = HashSet::new();
    for n in &scene.nodes {
        assert!(!n.instances.is_empty(), "no empty cell is written");
        let cells: HashSet<usize> = n
            .instances
            .iter()
            .map(|t| grid.cell_of(spot(n, t)))
            .collect();
        assert_eq!(cells.len(), 1, "{}: one cell", n.name);
        assert!(
            cells_seen.insert((cells.into_iter().next(), n.name.ends_with("mirrored"))),
            "{}: one node per cell and copy",
            n.name
        );
        assert!(n.instances.iter().all(|t| t.scale.min_element() > 0.0));
    }
    // The first node of each copy writes the mesh and its levels (a mesh level and the
    // impostor); every other node draws that node's.
    let first_plain = scene
        .nodes
        .iter()
        .position(|n| !n.name.ends_with("mirrored"))
        .unwrap();
    let first_mirrored = scene
        .nodes
        .iter()
        .position(|n| n.name.ends_with("mirrored"))
        .unwrap();
    for (i, n) in scene.nodes.iter().enumerate() {
        let first = if n.name.ends_with("mirrored") {
            first_mirrored
        } else {
            first_plain
        };
        if i == first {
            assert_eq!(n.mesh_from, None);
            assert_eq!(n.primitives.len(), 1);
            assert_eq!(n.lods.len(), 2, "one mesh level and the impostor");
        } else {
            assert_eq!(n.mesh_from, Some(first), "{}", n.name);
            assert!(n.primitives.is_empty() && n.lods.is_empty(), "{}", n.name);
        }
    }

    // In the file: every cell node draws the shared full mesh and lists, through MSFT_lod,
    // level nodes outside the scene that draw the shared level meshes with the cell's own
    // placements; the coarsest is the impostor, an alpha-tested textured material.
    let glb = encode_glb(&scene, Path::new("forest.glb")).unwrap();
    let root = glb_json(&glb);
    let nodes = root["nodes"].as_array().unwrap();
    let in_scene = scene_node_indices(&root);
    assert_eq!(in_scene.len(), scene.nodes.len());
    assert_eq!(
        root["meshes"].as_array().unwrap().len(),
        6,
        "two copies of three levels, written once"
    );
    let mut meshes_of: HashMap<bool, HashSet<Vec<u64>>> = HashMap::new();
    let mut instances = 0;
    for (&i, n) in in_scene.iter().zip(&scene.nodes) {
        let node = &nodes[i];
        let placements = &node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
        let count =
            root["accessors"][placements["TRANSLATION"].as_u64().unwrap() as usize]["count"]
                .as_u64()
                .unwrap();
        assert_eq!(count as usize, n.instances.len());
        instances += count;
        let ids = node["extensions"]["MSFT_lod"]["ids"].as_array().unwrap();
        assert_eq!(
            node["extras"]["MSFT_screencoverage"],
            serde_json::json!([0.5, 0.25, 0.0])
        );
        let mut meshes = vec![node["mesh"].as_u64().unwrap()];
        for id in ids {
            let id = id.as_u64().unwrap() as usize;
            assert!(!in_scene.contains(&id));
            let lod = &nodes[id];
            assert_eq!(
                &lod["extensions"]["EXT_mesh_gpu_instancing"]["attributes"],
                placements
            );
            meshes.push(lod["mesh"].as_u64().unwrap());
        }
        meshes_of
            .entry(n.name.ends_with("mirrored"))
            .or_default()
            .insert(meshes);
    }
    assert_eq!(instances, 64);
    for (mirrored, sets) in &meshes_of {
        assert_eq!(
            sets.len(),
            1,
            "mirrored {mirrored}: one set of meshes: {sets:?}"
        );
    }
    let impostor_mesh = meshes_of[&false].iter().next().unwrap()[2] as usize;
    let material = &root["materials"][root["meshes"][impostor_mesh]["primitives"][0]["material"]
        .as_u64()
        .unwrap() as usize];
    assert_eq!(material["alphaMode"], "MASK", "{material}");
    assert!(material["pbrMetallicRoughness"]["baseColorTexture"].is_object());
    assert_eq!(
        root["images"].as_array().unwrap().len(),
        1,
        "one impostor texture"
    );

    // Portable instancing: the same scene with a node per placement. No extension is needed;
    // every placement is a child node drawing its copy's one shared mesh with the placement's
    // transform, exactly as the accessors above held it.
    let mut portable = scene.clone();
    portable.instance_nodes = true;
    let glb = encode_glb(&portable, Path::new("forest.glb")).unwrap();
    let root = glb_json(&glb);
    let used = root["extensionsUsed"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    assert!(
        !used.iter().any(|e| e == "EXT_mesh_gpu_instancing"),
        "{used:?}"
    );
    assert!(
        root["extensionsRequired"].is_null(),
        "{}",
        root["extensionsRequired"]
    );
    let nodes = root["nodes"].as_array().unwrap();
    let in_scene = scene_node_indices(&root);
    assert_eq!(in_scene.len(), portable.nodes.len());
    assert_eq!(
        root["meshes"].as_array().unwrap().len(),
        2,
        "one mesh per copy"
    );
    let mut children = 0;
    for (&i, n) in in_scene.iter().zip(&portable.nodes) {
        let kids = nodes[i]["children"].as_array().unwrap();
        assert_eq!(kids.len(), n.instances.len(), "{}", n.name);
        for (k, t) in kids.iter().zip(&n.instances) {
            let child = &nodes[k.as_u64().unwrap() as usize];
            let v = |key: &str| -> Vec<f32> {
                child[key]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap() as f32)
                    .collect()
            };
            assert_eq!(v("translation"), t.translation.to_array());
            assert_eq!(v("scale"), t.scale.to_array());
            let q = glam::Quat::from_slice(&v("rotation"));
            assert!(q.angle_between(t.rotation) < 1e-5);
            assert!(child["mesh"].is_u64());
            children += 1;
        }
    }
    assert_eq!(children, 64);
    // The gltf crate reads it as a plain scene.
    let path = std::env::temp_dir().join(format!("thicket-portable-{}.glb", std::process::id()));
    std::fs::write(&path, &glb).unwrap();
    let (doc, _, _) = gltf::import(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(doc.nodes().filter(|n| n.mesh().is_some()).count(), 64);
}

/// The JSON chunk of a GLB.
fn glb_json(glb: &[u8]) -> serde_json::Value {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&glb[20..20 + json_len]).unwrap()
}

/// The node indices of a glTF's first scene.
fn scene_node_indices(root: &serde_json::Value) -> Vec<usize> {
    root["scenes"][0]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as usize)
        .collect()
}

#[test]
fn impostor_shows_the_prototype_from_the_side() {
    let tree = KrsScene {
        objects: vec![presets::tree()],
    }
    .prepare()
    .unwrap();
    let mesh = mesh_krs(&tree.objects[0], 32, u64::MAX, NO_PROGRESS).unwrap();
    let (lo, hi) = aabb(mesh.positions.iter().copied());
    let texels = 64;
    let imp = krs_impostor(&tree.objects[0].object, lo, hi, texels).unwrap();
    assert_eq!(
        (imp.texture.width, imp.texture.height),
        (2 * texels, texels)
    );
    assert_eq!(imp.triangle_count(), 8, "two squares, back to back");
    // The quads stand in the prototype's box (widened to a square) and their texture is
    // covered where the tree is: some texels, not all, in each view.
    let (qlo, qhi) = aabb(imp.positions.iter().copied());
    let half = 0.5 * (hi - lo).max_element() * 1.05;
    let centre = (lo + hi) * 0.5;
    assert!(
        qlo.cmpge(centre - Vec3::splat(half)).all() && qhi.cmple(centre + Vec3::splat(half)).all()
    );
    for view in 0..2 {
        let covered = (0..texels)
            .flat_map(|y| (0..texels).map(move |x| (y * 2 * texels + view * texels + x) as usize))
            .filter(|&i| imp.texture.rgba8[4 * i + 3] == 255)
            .count();
        let all = (texels * texels) as usize;
        assert!(
            covered > all / 20 && covered < all * 9 / 10,
            "view {view}: {covered} of {all}"
        );
    }
    // Right way up: the lowest covered row of each view is the trunk's foot, in the middle
    // half (a picture upside down would have the crown's wide edge there).
    for view in 0..2 {
        let covered_in_row = |y: u32| -> Vec<u32> {
            (0..texels)
                .filter(|&x| {
                    imp.texture.rgba8[4 * (y * 2 * texels + view * texels + x) as usize + 3] == 255
                })
                .collect()
        };
        let foot = (0..texels)
            .rev()
            .map(covered_in_row)
            .find(|row| !row.is_empty())
            .unwrap();
        assert!(
            foot.iter().all(|&x| x > texels / 4 && x < 3 * texels / 4)
                && foot.len() < texels as usize / 4,
            "view {view}: the lowest covered texels {foot:?}"
        );
    }
    // The mirrored impostor is the same quads reflected, showing the same texels.
    let m = imp.mirrored_x();
    assert_eq!(m.uvs, imp.uvs);
    assert!(
        m.positions
            .iter()
            .zip(&imp.positions)
            .all(|(a, b)| a.x == -b.x && (a.y, a.z) == (b.y, b.z))
    );
}

#[test]
fn impostor_texels_show_what_lies_behind_them_on_the_quads() {
    // A leaning capsule whose top end is toward +x and +z: on the square facing +z (the first
    // view) the top end is right of the middle, on the square facing +x (the second, whose
    // texture runs toward −z) left of it. Each covered texel of a view, put on its square,
    // must lie within the capsule's radius of its axis seen along that view.
    let (start, end, radius) = (Vec3::ZERO, Vec3::new(1.0, 1.0, 0.5), 0.1);
    let object = crate::krs::KrsObject {
        name: "lean".to_owned(),
        kernels: vec![crate::krs::Kernel::Capsule(crate::krs::CapsuleKernel {
            start,
            end,
            radius,
            material: crate::krs::Material::new(Vec3::new(0.5, 0.3, 0.2), 1),
        })],
        ..crate::krs::KrsObject::default()
    };
    let lo = start.min(end) - Vec3::splat(radius);
    let hi = start.max(end) + Vec3::splat(radius);
    let texels = 64;
    let imp = krs_impostor(&object, lo, hi, texels).unwrap();
    for view in 0..2u32 {
        // The square of this view: vertices 4·view .. 4·view + 4, texture coordinates with it.
        let q = &imp.positions[4 * view as usize..4 * view as usize + 4];
        let uv = &imp.uvs[4 * view as usize..4 * view as usize + 4];
        // Bilinear map from the texture to the square (its corners are (u0, v1), (u1, v1),
        // (u1, v0), (u0, v0) for corners 0..4).
        let at = |u: f32, v: f32| {
            let s = (u - uv[0].x) / (uv[1].x - uv[0].x);
            let t = (v - uv[0].y) / (uv[3].y - uv[0].y);
            q[0] + (q[1] - q[0]) * s + (q[3] - q[0]) * t
        };
        // Distance from a point to the capsule's axis, ignoring depth along the view.
        let drop = if view == 0 {
            Vec3::new(1.0, 1.0, 0.0)
        } else {
            Vec3::new(0.0, 1.0, 1.0)
        };
        let axis_distance = |p: Vec3| {
            let (a, b, p) = (start * drop, end * drop, p * drop);
            let h = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            (p - (a + (b - a) * h)).length()
        };
        let texel = (hi - lo).max_element() / texels as f32;
        let mut covered = 0;
        for y in 0..texels {
            for x in 0..texels {
                let i = (y * 2 * texels + view * texels + x) as usize;
                if imp.texture.rgba8[4 * i + 3] != 255 {
                    continue;
                }
                covered += 1;
                let u = (view * texels + x) as f32 + 0.5;
                let p = at(u / (2 * texels) as f32, (y as f32 + 0.5) / texels as f32);
                assert!(
                    axis_distance(p) < radius + 2.0 * texel,
                    "view {view}: texel ({x}, {y}) lands at {p}, off the capsule"
                );
            }
        }
        assert!(covered > 50, "view {view}: {covered} texels");
    }
}

/// The writer checks its output against the reader's limits: a non-finite number anywhere in
/// the JSON (serde would write `null`, invalid glTF) or a number beyond ±1e18 is
/// refused naming where it is, and the unchanged scene still encodes and reads back.
#[test]
fn the_writer_refuses_what_readers_refuse() {
    let mut svo = Svo::new(2, false).unwrap();
    svo.set(UVec3::new(1, 1, 1), Voxel::new([200, 10, 10, 255], Vec3::Y))
        .unwrap();
    let doc = doc_with("Dot", svo, 1.0, Vec3::ZERO);
    let path = Path::new("dot.glb");
    let (scene, _) = build_scene(&doc, path, &GltfExportOptions::default(), NO_PROGRESS).unwrap();
    let glb = encode_glb(&scene, path).unwrap();
    crate::io::gltf_mesh::import_gltf_slice(&glb, None).expect("a valid scene reads back");

    let mut nan = scene.clone();
    nan.nodes[0].transform.translation.y = f32::NAN;
    let e = encode_glb(&nan, path).unwrap_err().to_string();
    assert!(
        e.contains("null") && e.contains("nodes[0].translation[1]"),
        "{e}"
    );

    let mut far = scene.clone();
    far.nodes[0].transform.translation.x = 3e18;
    let e = encode_glb(&far, path).unwrap_err().to_string();
    assert!(
        e.contains("nodes[0].translation[0]") && e.contains("1e18"),
        "{e}"
    );

    let mut huge = scene;
    huge.nodes[0].primitives[0].positions[2].z = 5e18;
    let e = encode_glb(&huge, path).unwrap_err().to_string();
    assert!(e.contains("element 2") && e.contains("1e18"), "{e}");
}

/// The export's memory estimate (`export_fixed_bytes` + `export_triangle_bytes` per
/// triangle written) holds the measured peak of exporting four samples in both modes, and is
/// not more than 4 × the peak plus 1 MiB, so a budget derived from it does not refuse what fits.
#[test]
fn the_export_estimate_holds_the_measured_peak() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../projects");
    let mut checked = 0;
    for name in ["house", "cesiumman", "tree", "mixed"] {
        let doc =
            crate::io::project::load(Path::new(&format!("{dir}/{name}.thicket.json"))).unwrap();
        for mode in [ExportMode::Cubes, ExportMode::Smooth] {
            let tmp = tempfile::tempdir().unwrap();
            let out = tmp.path().join("x.glb");
            let options = GltfExportOptions {
                mode,
                resolution: 128,
                ..GltfExportOptions::default()
            };
            let (report, peak) = crate::io::fuzz::peak_heap_bytes(|| {
                export_gltf(&doc, &out, &options, NO_PROGRESS).unwrap()
            });
            let fixed = export_fixed_bytes(&doc, &options);
            let estimate = fixed + export_triangle_bytes(&doc, &options) * report.triangles;
            eprintln!(
                "{name} {mode:?}: {} triangles, peak {peak}, {:.0} bytes a triangle past the \
                 fixed part",
                report.triangles,
                peak.saturating_sub(fixed) as f64 / report.triangles as f64
            );
            assert!(
                estimate >= peak,
                "{name} {mode:?}: estimate {estimate} < peak {peak} ({} triangles)",
                report.triangles
            );
            assert!(
                estimate <= 4 * peak + (1 << 20),
                "{name} {mode:?}: estimate {estimate} far above peak {peak}"
            );
            // The limit a budget of that peak allows never refuses this export.
            let limit = triangle_limit_for_memory(&doc, &options, estimate).unwrap();
            assert!(limit >= report.triangles, "{name} {mode:?}");
            checked += 1;
        }
    }
    assert_eq!(checked, 8);
}

/// One vertex per triangle corner, or none for an absent attribute.
fn expand<T: Copy>(v: &[T], indices: &[u32]) -> Vec<T> {
    if v.is_empty() {
        return Vec::new();
    }
    indices.iter().map(|&i| v[i as usize]).collect()
}

/// Welding shares equal vertices without moving a triangle: each exported primitive, expanded
/// to one vertex per triangle corner and welded again, has the same corners (position, normal,
/// colour, texture coordinate, weights, bit for bit) in the same triangles, and exactly one
/// vertex per distinct corner: as many as the export wrote.
#[test]
fn welding_shares_equal_vertices_and_keeps_every_triangle() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../projects");
    let corners = |p: &ExportPrimitive| -> Vec<[u32; 14]> {
        p.indices
            .iter()
            .map(|&i| {
                let i = i as usize;
                let v = p.positions[i];
                let n = p.normals.get(i).copied().unwrap_or_default();
                let c = p.colors.get(i).copied().unwrap_or_default();
                let t = p.uvs.get(i).copied().unwrap_or_default();
                let s = p.skin.get(i).copied().unwrap_or_default();
                [
                    v.x.to_bits(),
                    v.y.to_bits(),
                    v.z.to_bits(),
                    n.x.to_bits(),
                    n.y.to_bits(),
                    n.z.to_bits(),
                    c.x.to_bits(),
                    c.y.to_bits(),
                    c.z.to_bits(),
                    c.w.to_bits(),
                    t.x.to_bits(),
                    t.y.to_bits(),
                    u32::from_le_bytes(s.joints),
                    u32::from_le_bytes(s.weights),
                ]
            })
            .collect()
    };
    let mut shared = 0;
    for (name, mode) in [
        ("house", ExportMode::Cubes),
        ("critter", ExportMode::Cubes),
        ("mixed", ExportMode::Cubes),
        ("tree", ExportMode::Smooth),
    ] {
        let doc =
            crate::io::project::load(Path::new(&format!("{dir}/{name}.thicket.json"))).unwrap();
        let options = GltfExportOptions {
            mode,
            resolution: 64,
            ..GltfExportOptions::default()
        };
        let (scene, _) = build_scene(&doc, Path::new("x.glb"), &options, NO_PROGRESS).unwrap();
        for p in scene.nodes.iter().flat_map(|n| &n.primitives) {
            let mut flat = ExportPrimitive {
                positions: expand(&p.positions, &p.indices),
                normals: expand(&p.normals, &p.indices),
                colors: expand(&p.colors, &p.indices),
                uvs: expand(&p.uvs, &p.indices),
                skin: expand(&p.skin, &p.indices),
                indices: (0..p.indices.len() as u32).collect(),
                material: p.material,
            };
            let before = corners(&flat);
            flat.weld();
            assert_eq!(
                corners(&flat),
                before,
                "{name}: the triangles are unchanged"
            );
            let distinct: std::collections::HashSet<[u32; 14]> = before.iter().copied().collect();
            assert_eq!(
                flat.positions.len(),
                distinct.len(),
                "{name}: one vertex per corner"
            );
            assert_eq!(
                p.positions.len(),
                distinct.len(),
                "{name}: as the export wrote"
            );
            shared += before.len() - distinct.len();
        }
    }
    assert!(shared > 10_000, "corners shared: {shared}");
}

/// `Instancing::Flatten` bakes every placement into plain meshes: the file has no instancing
/// extension and no shared meshes, its triangles are the prototype's at every placement plus
/// the rest, Thicket's reader reads exactly those, and the mirrored copies keep their outward
/// winding (the mesh is as closed as the instanced one: same triangle count read back). An
/// export whose copies pass the triangle limit is refused before any copy is made.
#[test]
fn flatten_bakes_every_placement_into_plain_meshes() {
    let doc = crate::io::project::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/forest.thicket.json"
    )))
    .unwrap();
    let options = GltfExportOptions {
        resolution: 32,
        instance_level: Some(14),
        instancing: Instancing::Flatten,
        ..GltfExportOptions::default()
    };
    let (scene, report) = build_scene(&doc, Path::new("flat.glb"), &options, NO_PROGRESS).unwrap();
    assert!(
        scene
            .nodes
            .iter()
            .all(|n| n.instances.is_empty() && n.mesh_from.is_none())
    );
    assert!(scene.nodes.iter().all(|n| n.lods.is_empty()));
    assert_eq!(report.placements, Some((Instancing::Flatten, 1024)));
    let k = &report.instanced[0];
    assert_eq!(
        report.triangles,
        k.prototype_triangles * k.instances
            + scene
                .nodes
                .iter()
                .filter(|n| n.name.contains("Ground"))
                .map(|n| n
                    .primitives
                    .iter()
                    .map(|p| p.indices.len() as u64 / 3)
                    .sum::<u64>())
                .sum::<u64>(),
        "{report:?}"
    );
    let glb = encode_glb(&scene, Path::new("flat.glb")).unwrap();
    let root = glb_json(&glb);
    assert!(
        root.get("extensionsUsed")
            .is_none_or(|e| !e.to_string().contains("EXT_mesh_gpu_instancing"))
    );
    let back = crate::io::gltf_mesh::import_gltf_slice(&glb, None).unwrap();
    assert_eq!(back.triangle_count() as u64, report.triangles);

    let tight = GltfExportOptions {
        max_triangles: report.triangles - 1,
        ..options
    };
    let e = build_scene(&doc, Path::new("flat.glb"), &tight, NO_PROGRESS)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("flattening writes every placement's copy")
            && e.contains(&crate::budget::thousands(report.triangles)),
        "{e}"
    );
}

#[test]
fn a_smooth_solid_takes_its_surface_colours_where_an_interior_voxel_ends_an_edge() {
    // A solid whose enclosed inside is the interior mark (no colour): where a marching edge
    // runs from an interior voxel to an empty one (across a diagonal of the staircase), the
    // vertex takes the colour exposing that voxel would give, its nearest surface voxel's. The
    // reference settles every interior voxel to that colour first: same occupancy, same mesh,
    // so the colours must be equal vertex for vertex.
    let doc = crate::render::scenes::ball(crate::render::scenes::BallInside::Interior);
    let ObjectKind::Voxels(model) = &doc.objects[0].kind else {
        panic!("a voxel ball");
    };
    let svo = &model.svo;
    let mut settled = Vec::new();
    let mut interior = 0;
    svo.for_each_leaf(|c, v| {
        if v.is_interior() {
            interior += 1;
            settled.push((c, svo.nearest_surface(c).unwrap().1));
        } else {
            settled.push((c, v));
        }
    });
    assert!(interior > 10_000, "{interior} interior voxels");
    let reference = Svo::from_voxels(svo.depth(), false, settled).unwrap();
    let (a, b) = (
        fields::mesh_voxels_smooth(svo, 2, u64::MAX).unwrap(),
        fields::mesh_voxels_smooth(&reference, 2, u64::MAX).unwrap(),
    );
    assert_eq!(a.indices, b.indices);
    assert_eq!(a.positions, b.positions);
    // None has the mark's transparent black.
    assert!(
        a.colors.iter().all(|c| c.w > 0.5),
        "a vertex took the interior mark's colour"
    );
    assert!(a.colors == b.colors, "vertex colours differ");
}

#[test]
fn left_out_interior_tiles_are_counted_as_solid_not_as_cavities() {
    // The face report of a solid is the same tiled or voxel by voxel: faces toward an enclosed
    // interior tile (left out of the mesher's lists) are toward solid voxels, not a cavity.
    let doc = crate::render::scenes::ball(crate::render::scenes::BallInside::Interior);
    let (flat, tiled, tiles) = crate::render::scenes::without_and_with_tiles(&doc);
    assert!(tiles > 20, "{tiles} tiles");
    let svo = |d: &Document| match &d.objects[0].kind {
        ObjectKind::Voxels(m) => m.svo.clone(),
        _ => panic!("a voxel ball"),
    };
    let (a, b) = (
        super::greedy::count_faces(&svo(&flat)),
        super::greedy::count_faces(&svo(&tiled)),
    );
    assert_eq!(a, b);
    assert!(a.exposed > 1_000 && a.sealed == 0, "{a:?}");
    // A small case: a 6³ solid box whose 4³ inside is interior, eight 2³ tiles.
    let mut voxels = Vec::new();
    for z in 1..=6u32 {
        for y in 1..=6u32 {
            for x in 1..=6u32 {
                let inside = [x, y, z].iter().all(|v| (2..=5).contains(v));
                let v = if inside {
                    Voxel::INTERIOR
                } else {
                    Voxel::new([200, 10, 10, 255], Vec3::Y)
                };
                voxels.push((UVec3::new(x, y, z), v));
            }
        }
    }
    let boxed = Svo::from_voxels(3, false, voxels).unwrap().with_tiles();
    assert_eq!(boxed.tile_count(), 8);
    let counts = super::greedy::count_faces(&boxed);
    assert_eq!(counts.sealed, 0, "{counts:?}");
    assert_eq!(
        counts,
        super::greedy::count_faces(&boxed.clone().without_tiles())
    );
}

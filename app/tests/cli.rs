//! Runs the real `thicket` binary: help, `info` on projects, and bad input (exit code ≠ 0, a
//! message naming the file, nothing written).

use std::path::{Path, PathBuf};
use std::process::Output;

use glam::{UVec3, Vec3};
use thicket_core::scene::{Document, ObjectKind, VoxelModel};
use thicket_core::svo::{Svo, Voxel};

mod common;
use common::{stderr, stdout, thicket};

const ASSETS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/assets");

/// Asserts a clean failure: non-zero exit, one `error:` line naming the file, no panic.
fn assert_fails_naming(o: &Output, file: &Path) {
    let err = stderr(o);
    assert!(!o.status.success(), "expected failure, got success: {err}");
    assert_eq!(o.status.code(), Some(1), "exit code 1, not a crash: {err}");
    assert!(err.starts_with("error: "), "{err}");
    let name = file.file_name().unwrap().to_string_lossy();
    assert!(err.contains(name.as_ref()), "message names {name}: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// The message of a clean refusal: exit code 1 (not a crash) and exactly one line.
fn one_error_line(o: &Output) -> String {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "said once: {err}");
    err
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

/// A project with two voxel objects (3 and 10 voxels) and its path.
fn sample_project(dir: &Path) -> PathBuf {
    let mut doc = Document::default();
    for (name, n) in [("row", 3u32), ("long", 10)] {
        let mut svo = Svo::new(5, false).unwrap();
        for x in 0..n {
            svo.set(UVec3::new(x, 2, 1), Voxel::new([10, 200, 30, 255], Vec3::Y))
                .unwrap();
        }
        doc.add(
            name,
            ObjectKind::Voxels(VoxelModel {
                svo,
                voxel_size: 0.5,
                ..VoxelModel::default()
            }),
        );
    }
    let path = dir.join("two.thicket.json");
    thicket_core::io::project::save(&doc, &path).unwrap();
    path
}

#[test]
fn help_lists_the_commands() {
    let o = thicket(&["--help"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("info"), "{out}");
    assert!(out.contains("PROJECT"), "{out}");
    let o = thicket(&["info", "--help"]);
    assert!(o.status.success());
    assert!(stdout(&o).contains("--json") && stdout(&o).contains("--memory"));
}

#[test]
fn unknown_subcommand_or_flag_is_a_usage_error() {
    let o = thicket(&["info", "--no-such-flag", "x.vox"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--no-such-flag"));
}

#[test]
fn info_on_a_project_reports_counts_and_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let path = sample_project(dir.path());
    let o = thicket(&["info", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("2 object(s), 13 voxels"), "{text}");
    assert!(
        text.contains("\"row\"") && text.contains("3 voxels"),
        "{text}"
    );
    assert!(text.contains("10 × 1 × 1 voxels"), "{text}");
    assert!(text.contains("bytes/voxel"), "{text}");

    let o = thicket(&["info", "--json", "--memory", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json["total_voxels"], 13);
    assert_eq!(json["objects"][1]["name"], "long");
    assert_eq!(json["objects"][1]["voxels"], 10);
    assert_eq!(
        json["objects"][1]["dimensions_voxels"],
        serde_json::json!([10, 1, 1])
    );
    assert_eq!(json["objects"][0]["depth"], 5);
    let bpv = json["objects"][0]["bytes_per_voxel"].as_f64().unwrap();
    assert!(bpv > 0.0 && bpv.is_finite(), "{bpv}");
    let total = json["objects"][0]["memory"]["total_bytes"]
        .as_u64()
        .unwrap();
    assert!(total > 0);
    // World size: 10 voxels of 0.5 along x.
    let wx = json["objects"][1]["world_size"][0].as_f64().unwrap();
    assert!((wx - 5.0).abs() < 1e-5, "{wx}");

    let o = thicket(&["info", "--memory", path.to_str().unwrap()]);
    assert!(stdout(&o).contains("memory:"), "{}", stdout(&o));
}

/// `info --memory` names the tiles of a model with solid walls and the voxels they stand for,
/// in words and in JSON.
#[test]
fn info_reports_the_tiles_of_the_house() {
    let house = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/house.thicket.json"
    );
    let o = thicket(&["info", "--memory", house]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(
        text.contains("tiles: 4,108 stand for 141,840 voxels stored once each"),
        "{text}"
    );
    let o = thicket(&["info", "--json", "--memory", house]);
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let memory = &json["objects"][0]["memory"];
    assert_eq!(memory["tiles"], 4108);
    assert_eq!(memory["tile_voxels"], 141_840);
    assert_eq!(json["objects"][0]["voxels"], 180_202);
}

#[test]
fn missing_file_fails_naming_it() {
    let o = thicket(&["info", "/nonexistent/dir/ghost.thicket.json"]);
    assert_fails_naming(&o, Path::new("ghost.thicket.json"));
}

#[test]
fn unknown_extension_fails_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("notes.txt");
    std::fs::write(&p, "hello").unwrap();
    let o = thicket(&["info", p.to_str().unwrap()]);
    assert_fails_naming(&o, &p);
}

#[test]
fn not_a_vox_fails_naming_it() {
    let p = PathBuf::from(format!("{ASSETS}/vox/dot_vox/not_a.vox"));
    assert!(p.exists(), "asset missing: {}", p.display());
    let o = thicket(&["info", p.to_str().unwrap()]);
    assert_fails_naming(&o, &p);
}

#[test]
fn garbage_and_corrupt_projects_fail_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let garbage = dir.path().join("garbage.thicket.json");
    std::fs::write(&garbage, b"\x00\x01 this is not json {").unwrap();
    let o = thicket(&["info", garbage.to_str().unwrap()]);
    assert_fails_naming(&o, &garbage);

    let empty = dir.path().join("empty.thicket.json");
    std::fs::write(&empty, b"").unwrap();
    assert_fails_naming(&thicket(&["info", empty.to_str().unwrap()]), &empty);

    // A real project whose .bin is damaged: the checksum catches it.
    let path = sample_project(dir.path());
    let bin = thicket_core::io::project::bin_path_for(&path);
    let mut bytes = std::fs::read(&bin).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0xff;
    std::fs::write(&bin, &bytes).unwrap();
    let o = thicket(&["info", path.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("two.thicket"), "{}", stderr(&o));

    // NaN in a transform.
    let nan = dir.path().join("nan.thicket.json");
    std::fs::write(
        &nan,
        r#"{"format_version":1,"objects":[{"id":1,"name":"bad","transform":{"translation":[NaN,0,0]},"kind":{"type":"Mesh"}}]}"#,
    )
    .unwrap();
    assert_fails_naming(&thicket(&["info", nan.to_str().unwrap()]), &nan);
}

#[test]
fn failing_info_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let garbage = dir.path().join("g.thicket.json");
    std::fs::write(&garbage, "{").unwrap();
    let before = files_in(dir.path());
    let o = thicket(&["info", "--json", garbage.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stdout(&o).is_empty(), "no partial report on stdout");
    assert_eq!(files_in(dir.path()), before);
}

#[test]
fn info_on_mesh_files_matches_the_importer() {
    for (rel, triangles) in [
        ("static/Box.glb", Some(12usize)),
        ("static/spot/spot_triangulated.obj", None),
        ("skinned/CesiumMan.glb", None),
    ] {
        let path = PathBuf::from(format!("{ASSETS}/{rel}"));
        let model = if rel.ends_with(".obj") {
            thicket_core::io::import_obj(&path).unwrap()
        } else {
            thicket_core::io::import_gltf(&path).unwrap()
        };
        let o = thicket(&["info", "--json", path.to_str().unwrap()]);
        assert!(o.status.success(), "{rel}: {}", stderr(&o));
        let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        let obj = &json["objects"][0];
        assert_eq!(obj["kind"], "mesh", "{rel}");
        assert_eq!(
            obj["triangles"].as_u64(),
            Some(model.triangle_count() as u64),
            "{rel}"
        );
        assert_eq!(
            obj["vertices"].as_u64(),
            Some(model.vertex_count() as u64),
            "{rel}"
        );
        assert_eq!(
            json["total_triangles"].as_u64(),
            Some(model.triangle_count() as u64)
        );
        if let Some(t) = triangles {
            assert_eq!(model.triangle_count(), t, "{rel}");
        }
        assert!(json["total_bytes"].as_u64().unwrap() > 0);
    }
    let o = thicket(&["info", &format!("{ASSETS}/static/Box.glb")]);
    assert!(stdout(&o).contains("12 triangles"), "{}", stdout(&o));
}

#[test]
fn truncated_glb_fails_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(format!("{ASSETS}/static/Box.glb")).unwrap();
    let p = dir.path().join("cut.glb");
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    assert_fails_naming(&thicket(&["info", p.to_str().unwrap()]), &p);
    let empty = dir.path().join("empty.obj");
    std::fs::write(&empty, b"").unwrap();
    let o = thicket(&["info", empty.to_str().unwrap()]);
    // An empty OBJ is either an empty mesh or refused; never a crash.
    assert!(o.status.code().is_some(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"));
}

fn info_json(path: &str) -> serde_json::Value {
    let o = thicket(&["info", "--json", path]);
    assert!(o.status.success(), "{path}: {}", stderr(&o));
    serde_json::from_str(&stdout(&o)).unwrap()
}

#[test]
fn info_on_vox_files_reports_exact_counts() {
    let house = info_json(&format!("{ASSETS}/vox/mmmm/obj_house4.vox"));
    assert_eq!(house["total_voxels"], 180_202);
    let army = info_json(&format!("{ASSETS}/vox/mmmm/chr_army1.vox"));
    assert_eq!(army["total_voxels"], 341);
    let scene = info_json(&format!(
        "{ASSETS}/vox/opengametools/test_multiple_model_scene.vox"
    ));
    assert_eq!(scene["source"]["stored_voxels"], 6_053);
    assert_eq!(scene["source"]["stored_models"], 41);
    let o = thicket(&["info", &format!("{ASSETS}/vox/mmmm/obj_house4.vox")]);
    assert!(stdout(&o).contains("180,202 voxels"), "{}", stdout(&o));
}

#[test]
fn export_vox_round_trips_the_voxel_count() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("house.vox");
    let o = thicket(&[
        "export-vox",
        &format!("{ASSETS}/vox/mmmm/chr_army1.vox"),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("341 voxels"), "{}", stdout(&o));
    assert_eq!(info_json(out.to_str().unwrap())["total_voxels"], 341);

    // A project saved by the library exports too.
    let project = sample_project(dir.path());
    let out2 = dir.path().join("two.vox");
    let o = thicket(&[
        "export-vox",
        project.to_str().unwrap(),
        "-o",
        out2.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(info_json(out2.to_str().unwrap())["total_voxels"], 13);
}

#[test]
fn failing_export_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let garbage = dir.path().join("bad.thicket.json");
    std::fs::write(&garbage, "[1,2").unwrap();
    let out = dir.path().join("out.vox");
    let o = thicket(&[
        "export-vox",
        garbage.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_fails_naming(&o, &garbage);
    assert!(!out.exists());
    assert_eq!(files_in(dir.path()), vec![garbage.clone()]);

    let not_vox = format!("{ASSETS}/vox/dot_vox/not_a.vox");
    let o = thicket(&["export-vox", &not_vox, "-o", out.to_str().unwrap()]);
    assert_fails_naming(&o, Path::new(&not_vox));
    assert!(!out.exists());
}

/// `thicket import INPUT -o PROJECT --depth 5 EXTRA…`, which must succeed.
fn import_at_depth_5(input: &str, project: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "import",
        input,
        "-o",
        project.to_str().unwrap(),
        "--depth",
        "5",
    ];
    args.extend_from_slice(extra);
    let o = thicket(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    o
}

#[test]
fn import_says_once_what_it_leaves_out() {
    let dir = tempfile::tempdir().unwrap();
    let project = dir.path().join("man.thicket.json");
    let input = format!("{ASSETS}/skinned/CesiumMan.glb");
    let run = |extra: &[&str]| {
        let o = import_at_depth_5(&input, &project, extra);
        format!("{}{}", stdout(&o), stderr(&o))
    };
    // As a static mesh its walk cycle is left out: said once, with the clip's channel count.
    let out = run(&["--no-skin"]);
    let line = "1 animation(s) with 57 channel(s) (\"animation 0\"): not imported";
    assert_eq!(out.matches(line).count(), 1, "{out}");
    // With its skin the animation is imported: nothing is left out.
    let out = run(&[]);
    assert!(!out.contains("not imported"), "{out}");
    // A closed mesh fills; an open one (SimpleSkin is a flat strip) keeps its surface, saying
    // so once.
    assert!(!run(&["--solid"]).contains("the mesh is open"));
    let o = thicket(&[
        "import",
        &format!("{ASSETS}/skinned/SimpleSkin.gltf"),
        "-o",
        project.to_str().unwrap(),
        "--solid",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = format!("{}{}", stdout(&o), stderr(&o));
    assert_eq!(out.matches("warning: the mesh is open").count(), 1, "{out}");
}

#[test]
fn import_of_an_exported_glb_keeps_its_camera_and_lights() {
    let dir = tempfile::tempdir().unwrap();
    // A 4×3×2 block of half-unit voxels, seen from a known camera framed on it, and two
    // lights.
    let mut doc = Document::default();
    let mut svo = Svo::new(3, false).unwrap();
    for (x, y, z) in (0..4).flat_map(|x| (0..3).flat_map(move |y| (0..2).map(move |z| (x, y, z)))) {
        svo.set(UVec3::new(x, y, z), Voxel::new([200, 90, 40, 255], Vec3::Y))
            .unwrap();
    }
    doc.add(
        "block",
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: 0.5,
            origin: Vec3::new(2.0, 0.0, -1.0),
            ..VoxelModel::default()
        }),
    );
    doc.camera.yaw_deg = 120.0;
    doc.camera.pitch_deg = 35.0;
    doc.camera.fov_y_deg = 40.0;
    let (lo, hi) = doc.bounds().unwrap();
    doc.camera.frame(lo, hi);
    doc.lights = vec![
        thicket_core::scene::Light {
            name: "Sun".into(),
            direction: Vec3::new(0.3, -1.0, 0.2),
            color: Vec3::new(1.0, 0.9, 0.8),
            intensity: 3.0,
            casts_shadows: true,
        },
        thicket_core::scene::Light {
            name: "Rim".into(),
            direction: Vec3::new(-0.5, 0.1, 1.0),
            color: Vec3::new(0.2, 0.4, 1.0),
            intensity: 0.5,
            casts_shadows: false,
        },
    ];
    let project = dir.path().join("lit.thicket.json");
    thicket_core::io::project::save(&doc, &project).unwrap();
    let glb = dir.path().join("lit.glb");
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        glb.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));

    let back_path = dir.path().join("back.thicket.json");
    let o = thicket(&[
        "import",
        glb.to_str().unwrap(),
        "-o",
        back_path.to_str().unwrap(),
        "--voxel-size",
        "0.5",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = format!("{}{}", stdout(&o), stderr(&o));
    let said = |s: &str| out.matches(s).count();
    assert_eq!(
        said("1 camera(s): the first imported as the document camera"),
        1,
        "{out}"
    );
    assert_eq!(
        said("lights: 2 directional imported, 0 point/spot not imported"),
        1,
        "{out}"
    );
    assert!(
        !out.contains("not applied") && !out.contains("roll"),
        "{out}"
    );

    let back = thicket_core::io::project::load(&back_path).unwrap();
    let (a, b) = (doc.camera, back.camera);
    let near = |x: f32, y: f32, tolerance: f32| (x - y).abs() <= tolerance;
    assert!(!b.orthographic);
    assert!(near(a.yaw_deg, b.yaw_deg, 1e-3), "{a:?} {b:?}");
    assert!(near(a.pitch_deg, b.pitch_deg, 1e-3), "{a:?} {b:?}");
    assert!(near(a.fov_y_deg, b.fov_y_deg, 1e-4), "{a:?} {b:?}");
    assert!(a.eye().abs_diff_eq(b.eye(), 1e-4), "{a:?} {b:?}");
    // The target is the re-voxelized block's centre on the view axis: within half a voxel.
    assert!(a.target.abs_diff_eq(b.target, 0.25), "{a:?} {b:?}");
    assert!(
        near(a.near, b.near, 1e-4) && near(a.far, b.far, 1e-3),
        "{a:?} {b:?}"
    );
    assert_eq!(back.lights.len(), 2, "{:?}", back.lights);
    for (x, y) in doc.lights.iter().zip(&back.lights) {
        assert_eq!((&x.name, x.casts_shadows), (&y.name, y.casts_shadows));
        assert!(
            x.direction.normalize_or_zero().dot(y.direction) > 1.0 - 1e-5,
            "{x:?} {y:?}"
        );
        assert!(x.color.abs_diff_eq(y.color, 1e-6), "{x:?} {y:?}");
        assert!(near(x.intensity, y.intensity, 1e-6), "{x:?} {y:?}");
    }

    // Opening the .glb as a document applies the same view to its mesh.
    let opened = thicket::files::load_document(&glb).unwrap();
    assert!(opened.camera.eye().abs_diff_eq(a.eye(), 1e-4));
    assert!(opened.camera.target.abs_diff_eq(a.target, 1e-3));
    assert_eq!(opened.lights, back.lights);
}

#[test]
fn import_names_a_texture_for_an_obj_shipped_without_its_mtl() {
    let dir = tempfile::tempdir().unwrap();
    let project = dir.path().join("spot.thicket.json");
    let obj = format!("{ASSETS}/static/spot/spot_triangulated.obj");
    let png = format!("{ASSETS}/static/spot/spot_texture.png");
    let colours = |extra: &[&str]| {
        let o = import_at_depth_5(&obj, &project, extra);
        let doc = thicket_core::io::project::load(&project).unwrap();
        let thicket_core::scene::ObjectKind::Voxels(v) = &doc.objects[0].kind else {
            panic!("voxels")
        };
        // Every voxel's colour, those of tiles included.
        let seen = thicket_core::sculpt::model_colors(&v.svo);
        (seen.len(), stdout(&o))
    };
    let (flat, out) = colours(&[]);
    assert_eq!(flat, 1, "without a texture Spot is one flat colour");
    assert_eq!(out.matches("names no texture").count(), 1, "{out}");
    let (textured, out) = colours(&["--texture", &png]);
    assert!(textured > 20, "{textured} colours from the texture");
    assert!(!out.contains("names no texture"), "{out}");
    // A glTF names its own textures: refused, saying why.
    let o = thicket(&[
        "import",
        &format!("{ASSETS}/static/Box.glb"),
        "-o",
        project.to_str().unwrap(),
        "--texture",
        &png,
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("only an OBJ file takes a texture"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn import_a_solid_box_then_render_it() {
    let dir = tempfile::tempdir().unwrap();
    let project = dir.path().join("box.thicket.json");
    let input = format!("{ASSETS}/static/Box.glb");
    let o = thicket(&[
        "import",
        &input,
        "-o",
        project.to_str().unwrap(),
        "--voxel-size",
        "0.015625",
        "--solid",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Box.glb is a unit cube: solid at 1/64 gives 64³ voxels (volume 1).
    assert!(stdout(&o).contains("262,144 voxels"), "{}", stdout(&o));
    // Its inside, every voxel enclosed on six faces (62³), is the interior mark: a few tiles.
    let o = thicket(&["info", "--memory", project.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("interior: 238,328 voxels enclosed"), "{text}");
    let o = thicket(&["info", "--json", "--memory", project.to_str().unwrap()]);
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let memory = &json["objects"][0]["memory"];
    assert_eq!(memory["interior_voxels"], 238_328);
    assert!(memory["tiles"].as_u64().unwrap() > 0, "{memory}");
    // Under 2 bytes for each of its 262,144 voxels (measured 487,468 bytes, 1.86; voxel by
    // voxel a rigid model takes about 9): its 23,816 shell voxels, the layer of interior leaves
    // beside them and 6,224 tiles for the rest.
    assert!(
        memory["total_bytes"].as_u64().unwrap() < 2 * 262_144,
        "{memory}"
    );
    let png = dir.path().join("box.png");
    let o = thicket(&[
        "render",
        project.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--size",
        "64x48",
        "--stats",
        "--quality",
        "shadow_map_size=256",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (64, 48));
    assert!(stdout(&o).contains("\"levels\""));
}

/// `render --stats` reports the visible repetition of the image it wrote (KRS symmetry
/// hiding, issue 26): the measure of `thicket_core::krs::repetition` on that PNG.
#[test]
fn render_stats_report_the_visible_repetition_of_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let project = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/woodland.thicket.json"
    );
    let png = dir.path().join("woodland.png");
    let o = thicket(&[
        "render",
        project,
        "-o",
        png.to_str().unwrap(),
        "--size",
        "96x96",
        "--stats",
        "--quality",
        "shadow_map_size=256",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let json: serde_json::Value =
        serde_json::from_str(&out[out.find('{').expect("statistics")..]).unwrap();
    let r = &json["repetition"];
    let score = r["score"].as_f64().expect("a score");
    let (t, m) = (
        r["translation"].as_f64().unwrap(),
        r["mirror"].as_f64().unwrap(),
    );
    assert!((score - t.max(m)).abs() < 1e-6, "{r}");
    // The written image measures the same.
    let img = thicket_core::render::RgbaImage::load_png(&png).unwrap();
    let again =
        thicket_core::krs::repetition::visible_repetition(&img.pixels, img.width, img.height);
    assert!(
        (f64::from(again.score()) - score).abs() < 1e-6,
        "{again:?} vs {r}"
    );
    assert!(score > 0.05 && score < 1.0, "{r}");
}

#[test]
fn render_refuses_bad_arguments_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let project = sample_project(dir.path());
    let png = dir.path().join("out.png");
    for extra in [
        &["--size", "0x10"][..],
        &["--size", "abc"],
        &["--quality", "lod_pixel_threshold=NaN"],
        &["--quality", "nope=1"],
        &["--camera", "1,2"],
    ] {
        let mut args = vec![
            "render",
            project.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = thicket(&args);
        assert!(!o.status.success(), "{extra:?} should fail");
        assert!(!png.exists(), "{extra:?} wrote a file");
    }
}

#[test]
fn info_reports_krs_objects() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = Document::default();
    doc.add(
        "Forest",
        ObjectKind::Krs(thicket_core::krs::presets::forest()),
    );
    doc.add("Rock", ObjectKind::Krs(thicket_core::krs::presets::rock()));
    let path = dir.path().join("krs.thicket.json");
    thicket_core::io::project::save(&doc, &path).unwrap();

    let o = thicket(&["info", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("\"Forest\" (krs)"), "{text}");
    assert!(text.contains("33,423,360 kernel instances"), "{text}");
    assert!(text.contains("ToroidalCapsule"), "{text}");
    assert!(text.contains("distorted"), "{text}");

    let o = thicket(&["info", "--json", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let forest = &json["objects"][0]["krs"];
    assert_eq!(forest["kernel_instances"], 33_423_360);
    assert_eq!(
        forest["mirrors"].as_u64().unwrap() + 1,
        forest["kernel_sets"].as_u64().unwrap()
    );
    let rock = &json["objects"][1]["krs"];
    assert_eq!(rock["mirrors"], 6);
    assert_eq!(rock["kernels"].as_array().unwrap().len(), 4);
    assert_eq!(rock["distorted"], true);
}

/// A project with a coarse 16³ voxel hill ("hill", 0.5 units per voxel) and a mesh ("cube").
fn enhance_project(dir: &Path) -> PathBuf {
    let mut doc = Document::default();
    let mut svo = Svo::new(4, false).unwrap();
    for z in 0..16u32 {
        for x in 0..16u32 {
            let h = 3 + (x * 7 + z * 3) % 5;
            for y in 0..h {
                let mut v = Voxel::new([120, 90 + y as u8 * 10, 40, 255], Vec3::Y);
                v.material = u8::from(y + 1 == h);
                svo.set(UVec3::new(x, y, z), v).unwrap();
            }
        }
    }
    doc.add(
        "hill",
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: 0.5,
            ..VoxelModel::default()
        }),
    );
    doc.add(
        "cube",
        ObjectKind::Mesh(thicket_core::scene::MeshObject {
            model: thicket_core::mesh::MeshModel {
                parts: vec![thicket_core::mesh::unit_cube()],
                materials: vec![thicket_core::mesh::Material::default()],
            },
            casts_shadows: true,
        }),
    );
    let path = dir.join("hill.thicket.json");
    thicket_core::io::project::save(&doc, &path).unwrap();
    path
}

fn voxel_model<'a>(
    doc: &'a Document,
    name: &str,
) -> (&'a thicket_core::scene::Object, &'a VoxelModel) {
    let o = doc
        .object_by_name(name)
        .unwrap_or_else(|| panic!("no object {name:?}"));
    match &o.kind {
        ObjectKind::Voxels(v) => (o, v),
        ObjectKind::Mesh(_) => panic!("{name:?} is a mesh"),
        ObjectKind::Krs(_) => panic!("{name:?} is a KRS object"),
    }
}

#[test]
fn enhance_adds_the_fine_object_and_hides_the_coarse_one() {
    use thicket_core::enhance::{EnhanceSettings, ThresholdPattern, enhance};
    let dir = tempfile::tempdir().unwrap();
    let project = enhance_project(dir.path());
    let out = dir.path().join("fine.thicket.json");
    let o = thicket(&[
        "enhance",
        project.to_str().unwrap(),
        "--object",
        "hill",
        "--factor",
        "4",
        "--strata",
        "3,4",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("\"hill (enhanced)\""), "{}", stdout(&o));
    let doc = thicket_core::io::project::load(&out).unwrap();
    let source = thicket_core::io::project::load(&project).unwrap();
    let (coarse_obj, coarse) = voxel_model(&doc, "hill");
    assert!(!coarse_obj.visible, "the coarse original is hidden");
    assert_eq!(coarse.svo, voxel_model(&source, "hill").1.svo);
    let (fine_obj, fine) = voxel_model(&doc, "hill (enhanced)");
    assert!(fine_obj.visible);
    assert_eq!(fine.voxel_size, 0.125);
    // The CLI writes exactly what the library computes for the same settings.
    let settings = EnhanceSettings {
        factor: 4,
        subdivide: thicket_core::enhance::SubdivideSettings {
            threshold: ThresholdPattern::Alternating {
                even: 3.0,
                odd: 4.0,
            },
        },
        ..EnhanceSettings::default()
    };
    let expected = enhance(&coarse.svo, &settings).unwrap();
    assert!(expected.leaf_count() > 0);
    assert!(
        fine.svo == expected,
        "CLI output differs from core::enhance"
    );
    assert_eq!(doc.objects.len(), 3, "hill, cube and the enhanced hill");
    // The link the editor uses to keep the fine model in step with strokes.
    let link = doc.enhancement_of(coarse_obj.id).expect("a link");
    assert_eq!(link.target, fine_obj.id);
    assert_eq!(link.settings, settings);

    // Enhancing the result again with other settings replaces "hill (enhanced)", and
    // --replace swaps the object in place.
    let out2 = dir.path().join("again.thicket.json");
    let o = thicket(&[
        "enhance",
        out.to_str().unwrap(),
        "--object",
        "hill",
        "--method",
        "resample",
        "--factor",
        "3",
        "--probes",
        "8",
        "--spread",
        "0.75",
        "--seed",
        "5",
        "--lighting",
        "--particles",
        "2",
        "-o",
        out2.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc2 = thicket_core::io::project::load(&out2).unwrap();
    assert_eq!(doc2.objects.len(), 3);
    let (_, fine2) = voxel_model(&doc2, "hill (enhanced)");
    assert!((fine2.voxel_size - 0.5 / 3.0).abs() < 1e-7);
    assert_ne!(fine2.svo, fine.svo);
    assert_eq!(doc2.enhancements.len(), 1, "the link was replaced");
    assert_eq!(doc2.enhancements[0].settings.factor, 3);

    let out3 = dir.path().join("replaced.thicket.json");
    let o = thicket(&[
        "enhance",
        project.to_str().unwrap(),
        "--object",
        "hill",
        "--factor",
        "2",
        "--replace",
        "-o",
        out3.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc3 = thicket_core::io::project::load(&out3).unwrap();
    assert_eq!(doc3.objects.len(), 2);
    let (obj3, fine3) = voxel_model(&doc3, "hill");
    assert!(obj3.visible);
    assert_eq!(obj3.id, voxel_model(&source, "hill").0.id);
    assert_eq!(fine3.svo.depth(), 5);
    assert!(doc3.enhancements.is_empty());
}

#[test]
fn enhance_refuses_bad_arguments_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let project = enhance_project(dir.path());
    let out = dir.path().join("out.thicket.json");
    let p = project.to_str().unwrap();
    for (extra, says) in [
        (
            &["--object", "ghost", "--factor", "4"][..],
            "no object named \"ghost\"",
        ),
        (
            &["--object", "cube", "--factor", "4"][..],
            "not a voxel object",
        ),
        (&["--object", "hill", "--factor", "3"][..], "power of two"),
        (&["--object", "hill", "--factor", "0"][..], "factor"),
        (
            &["--object", "hill", "--method", "resample", "--factor", "65"][..],
            "factor",
        ),
        (
            &["--object", "hill", "--factor", "4", "--probes", "8"][..],
            "--probes",
        ),
        (
            &["--object", "hill", "--factor", "4", "--threshold", "2.5"][..],
            "whole voxel count",
        ),
        (
            &["--object", "hill", "--factor", "4", "--strata", "3"][..],
            "--strata",
        ),
        (
            &[
                "--object",
                "hill",
                "--factor",
                "4",
                "--material-threshold",
                "x=2",
            ][..],
            "--material-threshold",
        ),
        (
            &[
                "--object",
                "hill",
                "--method",
                "resample",
                "--factor",
                "4",
                "--spread=-1",
            ][..],
            "spread",
        ),
        (
            &[
                "--object",
                "hill",
                "--factor",
                "4",
                "--lighting",
                "--sun",
                "0,0,0",
            ][..],
            "sun_direction",
        ),
    ] {
        let mut args = vec!["enhance", p, "-o", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = thicket(&args);
        assert_fails_naming(&o, &project);
        assert!(stderr(&o).contains(says), "{extra:?}: {}", stderr(&o));
        assert!(!out.exists(), "{extra:?} wrote a file");
    }
    let o = thicket(&[
        "enhance",
        "/nonexistent/ghost.thicket.json",
        "--object",
        "a",
        "--factor",
        "2",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_fails_naming(&o, Path::new("ghost.thicket.json"));
}

#[test]
fn export_writes_glb_and_gltf_that_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let project = sample_project(dir.path());
    let glb = dir.path().join("two.glb");
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        glb.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Two rows of 3 and 10 voxels: each is one box, 6 quads, after greedy merging.
    let out = stdout(&o);
    assert!(out.contains("2 object(s), 24 triangles"), "{out}");
    assert!(
        out.contains("14 exposed faces merged into 6 quads"),
        "{out}"
    );
    let info = info_json(glb.to_str().unwrap());
    assert_eq!(info["total_triangles"], 24, "{info}");

    // .gltf + .bin, one object, smooth mode, palette texture.
    let gltf = dir.path().join("long.gltf");
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        gltf.to_str().unwrap(),
        "--object",
        "long",
        "--mode",
        "smooth",
        "--palette-texture",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("long.bin").exists());
    let info = info_json(gltf.to_str().unwrap());
    assert_eq!(info["objects"].as_array().unwrap().len(), 1, "{info}");
    assert!(info["total_triangles"].as_u64().unwrap() > 24, "{info}");
    // One object is that object alone (no camera, no lights), unless asked for.
    let json = |path: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    };
    let alone = json(&gltf);
    assert!(alone.get("cameras").is_none(), "{alone}");
    assert!(
        !alone.to_string().contains("KHR_lights_punctual"),
        "{alone}"
    );
    let with = dir.path().join("long_lit.gltf");
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        with.to_str().unwrap(),
        "--object",
        "long",
        "--lights-camera",
        "on",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let lit = json(&with);
    assert_eq!(lit["cameras"].as_array().map(Vec::len), Some(1), "{lit}");
}

#[test]
fn failing_gltf_export_names_the_problem_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let project = sample_project(dir.path());
    let before = files_in(dir.path());
    // Unknown object: the message lists the real ones.
    let out = dir.path().join("x.glb");
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--object",
        "Tree",
    ]);
    assert_fails_naming(&o, &out);
    assert!(stderr(&o).contains("\"row\""), "{}", stderr(&o));
    // A folder that does not exist.
    let nowhere = dir.path().join("missing").join("x.glb");
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        nowhere.to_str().unwrap(),
    ]);
    assert_fails_naming(&o, &nowhere);
    // Not a glTF name, and a resolution out of range.
    let obj = dir.path().join("x.obj");
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        obj.to_str().unwrap(),
    ]);
    assert_fails_naming(&o, &obj);
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--resolution",
        "2097152",
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("--resolution 2097152"),
        "{}",
        stderr(&o)
    );
    assert_eq!(files_in(dir.path()), before);
}

#[test]
fn render_turntable_orbits_the_camera_over_numbered_frames() {
    let dir = tempfile::tempdir().unwrap();
    let project = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/mixed.thicket.json"
    );
    let out = dir.path().join("spin.png");
    let o = thicket(&[
        "render",
        project,
        "-o",
        out.to_str().unwrap(),
        "--size",
        "48x48",
        "--turntable",
        "3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let frames: Vec<Vec<u8>> = (0..3)
        .map(|i| {
            let p = dir.path().join(format!("spin_{i:03}.png"));
            image::open(&p)
                .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
                .to_rgba8()
                .into_raw()
        })
        .collect();
    assert_eq!(files_in(dir.path()).len(), 3, "only the frames");
    // Each step turns the camera by 120 degrees: every frame differs from the others.
    assert_ne!(frames[0], frames[1]);
    assert_ne!(frames[1], frames[2]);
    assert_ne!(frames[0], frames[2]);

    let o = thicket(&[
        "render",
        project,
        "-o",
        dir.path().join("none.png").to_str().unwrap(),
        "--turntable",
        "0",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--turntable 0"), "{}", stderr(&o));
    assert_eq!(files_in(dir.path()).len(), 3, "nothing written");
}

/// The JSON chunk of a .glb file (the chunk right after the 12-byte header).
fn glb_json(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[0..4], b"glTF", "{}", path.display());
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    assert_eq!(&bytes[16..20], b"JSON");
    serde_json::from_slice(&bytes[20..20 + len]).unwrap()
}

/// A KRS tree exports from the CLI as a closed distance-field mesh (at a resolution where it
/// used to come out empty) and, with `--mode instances`, as one mesh per kernel drawn once per
/// kernel instance through EXT_mesh_gpu_instancing.
#[test]
fn krs_objects_export_as_a_mesh_and_as_instances() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = Document::default();
    let tree = thicket_core::krs::presets::tree();
    let instances = tree.instance_count();
    doc.add("Tree", ObjectKind::Krs(tree));
    let project = dir.path().join("tree.thicket.json");
    thicket_core::io::project::save(&doc, &project).unwrap();

    let mesh = dir.path().join("tree-mesh.glb");
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        mesh.to_str().unwrap(),
        "--resolution",
        "96",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json = glb_json(&mesh);
    assert_eq!(json["meshes"].as_array().unwrap().len(), 1, "{json}");
    let position = &json["meshes"][0]["primitives"][0]["attributes"]["POSITION"];
    let vertices = json["accessors"][position.as_u64().unwrap() as usize]["count"]
        .as_u64()
        .unwrap();
    assert!(vertices > 1000, "{vertices} vertices");

    let inst = dir.path().join("tree-instances.glb");
    let o = thicket(&[
        "export",
        project.to_str().unwrap(),
        "-o",
        inst.to_str().unwrap(),
        "--mode",
        "instances",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json = glb_json(&inst);
    let used: Vec<&str> = json["extensionsUsed"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    assert!(used.contains(&"EXT_mesh_gpu_instancing"), "{json}");
    // Every kernel instance is drawn exactly once: the instance TRANSLATION accessors of all
    // nodes add up to the KRS's instance count.
    let drawn: u64 = json["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|n| {
            n["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["TRANSLATION"].as_u64()
        })
        .map(|a| json["accessors"][a as usize]["count"].as_u64().unwrap())
        .sum();
    assert_eq!(u128::from(drawn), instances);
}

#[test]
fn new_writes_a_project_with_one_model_and_refuses_bad_extents() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fresh.thicket.json");
    let o = thicket(&[
        "new",
        out.to_str().unwrap(),
        "--extent",
        "40,12,30",
        "--voxel-size",
        "0.05",
        "--fill",
        "slab",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("40×12×30"), "{}", stdout(&o));
    let doc = thicket::files::load_document(&out).unwrap();
    let ObjectKind::Voxels(v) = &doc.objects[0].kind else {
        panic!("a voxel model")
    };
    assert_eq!(v.volume, Some(UVec3::new(40, 12, 30)));
    assert_eq!(v.svo.leaf_count(), 40 * 30, "a one-voxel slab");
    assert!((v.voxel_size - 0.05).abs() < 1e-7);
    // The model stands on the ground.
    let (lo, _) = doc.objects[0].world_bounds().unwrap();
    assert!(lo.y.abs() < 1e-6, "{lo}");
    // Beyond the octree limit, and malformed extents: refused, nothing written.
    for (extent, expect) in [
        ("3000000,4,4", "2^21"),
        ("4,4", "X,Y,Z"),
        ("4,x,4", "whole number"),
    ] {
        let bad = dir.path().join("bad.thicket.json");
        let o = thicket(&["new", bad.to_str().unwrap(), "--extent", extent]);
        assert!(!o.status.success());
        assert!(stderr(&o).contains(expect), "{extent}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"));
        assert!(!bad.exists());
    }
}

#[test]
fn a_close_render_camera_does_not_clip_the_front_of_the_model() {
    // The house seen from 35 units: the project's near plane (68.9) would cut its front away.
    let dir = tempfile::tempdir().unwrap();
    let project = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/house.thicket.json"
    );
    let near = dir.path().join("near.png");
    let o = thicket(&[
        "render",
        project,
        "-o",
        near.to_str().unwrap(),
        "--size",
        "96x96",
        "--camera",
        "35,15,75",
        "--quality",
        "shadows=false",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&near).unwrap().to_rgba8();
    // The centre of the image shows the house, not the background.
    let doc = thicket::files::load_document(Path::new(project)).unwrap();
    let bg = doc.background;
    let bg = [
        i32::from(thicket_core::mesh::linear_to_srgb_byte(bg.x)),
        i32::from(thicket_core::mesh::linear_to_srgb_byte(bg.y)),
        i32::from(thicket_core::mesh::linear_to_srgb_byte(bg.z)),
    ];
    let mut model_pixels = 0;
    for y in 32..64 {
        for x in 32..64 {
            let p = img.get_pixel(x, y);
            let d: i32 = (0..3).map(|i| (i32::from(p[i]) - bg[i]).abs()).sum();
            if d > 12 {
                model_pixels += 1;
            }
        }
    }
    assert!(
        model_pixels > 900,
        "the house fills the centre: {model_pixels} of 1024"
    );
    // And nothing of the scene lies in front of the near plane or beyond the far plane.
    let (_, camera) = thicket::cli::view_options(&doc, &[], Some(&"35,15,75".to_string())).unwrap();
    let (lo, hi) = doc.bounds().unwrap();
    let eye = camera.eye();
    let nearest = (eye.clamp(lo, hi) - eye).length();
    let farthest = (0..8)
        .map(|i| {
            let c = Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            (c - eye).length()
        })
        .fold(0.0f32, f32::max);
    assert!(nearest > 1.0, "the eye is outside the house: {nearest}");
    assert!(
        camera.near > 0.0 && camera.near <= nearest && camera.far >= farthest,
        "clip {}..{} must enclose the scene at {nearest}..{farthest}",
        camera.near,
        camera.far
    );
}

#[test]
fn a_render_over_the_memory_limit_is_refused_at_once_with_its_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let project = sample_project(dir.path());
    let out = dir.path().join("big.png");
    let run = |size: &str, limit: &str| {
        thicket(&[
            "render",
            project.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--size",
            size,
            "--memory-limit",
            limit,
        ])
    };
    // 16384² would need tens of GiB: refused before the frame is allocated, in one line.
    let o = run("16384x16384", "1G");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.starts_with("error: rendering 16384x16384 would need about ")
            && err.contains(
                "GiB of memory, over the limit of 1.0 GiB (--memory-limit): lower --size"
            ),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "said once: {err}");
    assert!(!out.exists(), "nothing written");
    // A small frame fits the same limit and renders.
    let o = run("64x64", "1G");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.is_file());
    // The CPU bench renders the same frames: refused the same way.
    let o = thicket(&[
        "bench",
        project.to_str().unwrap(),
        "--size",
        "16384x16384",
        "--frames",
        "1",
        "--memory-limit",
        "1G",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.starts_with("error: rendering 16384x16384 would need about "),
        "{err}"
    );
    // A limit that is no size is refused by the parser, naming what was expected.
    let o = run("64x64", "lots");
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("expected a size such as 512M"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn a_tradeoff_sweep_over_the_memory_limit_is_refused_before_it_renders() {
    let dir = tempfile::tempdir().unwrap();
    let project = sample_project(dir.path());
    let out = dir.path().join("sweep");
    let run = |size: &str, limit: &str| {
        thicket(&[
            "tradeoff",
            project.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--size",
            size,
            "--knob",
            "lod_pixel_threshold=1,4",
            "--no-presets",
            "--frames",
            "1",
            "--memory-limit",
            limit,
        ])
    };
    let o = run("4096x4096", "256M");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.starts_with("error: ")
            && err.contains(": sweeping at 4096x4096 would need about ")
            && err.contains("over the limit of 256.0 MiB (--memory-limit): lower --size"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "said once: {err}");
    assert!(!out.exists(), "nothing written");
    // A small sweep fits the same limit and writes its report.
    let o = run("32x32", "256M");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.join("report.json").is_file());
}

/// Every bad input is said once, on one line, naming the input and what is wrong: no cause
/// repeated by its wrapper, no blame on the output, no parser position said twice.
#[test]
fn bad_input_is_said_once_naming_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("empty-uri.gltf"),
        r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"","byteLength":4}]}"#,
    )
    .unwrap();
    std::fs::write(
        d.join("far.obj"),
        "v 0 0 0\nv 1e30 0 0\nv 0 1e30 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(d.join("nan.thicket.json"), "{\"format_version\": NaN}").unwrap();
    let out = d.join("out.thicket.json");
    let out_s = out.to_str().unwrap();
    let p = |name: &str| d.join(name).to_str().unwrap().to_owned();
    /// Arguments, the file the message names, what it says, what it must not say.
    type Case<'a> = (Vec<String>, &'a str, &'a [&'a str], &'a [&'a str]);
    let cases: [Case<'_>; 4] = [
        (
            vec!["info".into(), p("missing.vox")],
            "missing.vox",
            &["No such file"],
            &[],
        ),
        (
            vec![
                "import".into(),
                p("empty-uri.gltf"),
                "-o".into(),
                out_s.into(),
            ],
            "empty-uri.gltf",
            &["the file reference is empty"],
            &["skin"],
        ),
        (
            vec!["import".into(), p("far.obj"), "-o".into(), out_s.into()],
            "far.obj",
            &["beyond ±1e18 units"],
            &["camera", "out.thicket.json"],
        ),
        (
            vec!["info".into(), p("nan.thicket.json")],
            "nan.thicket.json",
            &["line 1, column 20", "NaN is not a JSON number"],
            &["at line 1 column 20"],
        ),
    ];
    for (args, names, says, not) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = thicket(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{args:?}: one line: {err}"
        );
        assert!(
            err.starts_with("error: ") && err.contains(names),
            "{args:?}: {err}"
        );
        for s in says {
            assert!(err.contains(s), "{args:?} says {s:?}: {err}");
        }
        for s in not {
            assert!(!err.contains(s), "{args:?} does not say {s:?}: {err}");
        }
        // No part of the message twice (a wrapper repeating its cause).
        let parts: Vec<&str> = err
            .trim_end()
            .split(": ")
            .filter(|s| s.len() >= 12)
            .collect();
        for (i, part) in parts.iter().enumerate() {
            assert!(
                !parts[..i].contains(part),
                "{args:?}: {part:?} said twice: {err}"
            );
        }
        assert!(!out.exists(), "{args:?}: nothing written");
    }
}

#[test]
fn an_import_over_the_memory_limit_is_refused_before_it_voxelizes() {
    let dir = tempfile::tempdir().unwrap();
    let spot = format!("{ASSETS}/static/spot/spot_triangulated.obj");
    let out = dir.path().join("spot.thicket.json");
    let import = |extra: &[&str]| {
        let mut args = vec!["import", spot.as_str(), "-o", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        thicket(&args)
    };
    // Depth 12 solid: billions of interior voxels, refused from the mesh alone.
    let o = import(&["--depth", "12", "--solid", "--memory-limit", "8G"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("spot_triangulated.obj: voxelizing about ")
            && err.contains(
                "TiB of memory, over the limit of 8.0 GiB (--memory-limit): use a smaller --depth"
            ),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
    // The same mesh at depth 6 fits a 64 MiB limit and imports.
    let o = import(&["--depth", "6", "--memory-limit", "64M"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.is_file());
}

#[test]
fn an_enhancement_over_the_memory_limit_is_refused_before_it_starts() {
    let dir = tempfile::tempdir().unwrap();
    let project = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/house.thicket.json"
    );
    let out = dir.path().join("fine.thicket.json");
    let enhance = |factor: &str| {
        thicket(&[
            "enhance",
            project,
            "--object",
            "model 0",
            "--method",
            "subdivide",
            "--factor",
            factor,
            "--memory-limit",
            "100M",
            "-o",
            out.to_str().unwrap(),
        ])
    };
    let o = enhance("8");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("enhancing object \"model 0\" x8 into about ")
            && err.contains("over the limit of 100.0 MiB (--memory-limit): use a smaller --factor"),
        "{err}"
    );
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(!out.exists());
    let o = enhance("2");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.is_file());
}

/// [`common::animated_vox_bytes`] written to `path`.
fn animated_vox(path: &Path) {
    std::fs::write(path, common::animated_vox_bytes()).unwrap();
}

#[test]
fn animated_vox_is_one_object_that_exports_as_frames_and_renders_one_frame_per_time() {
    let dir = tempfile::tempdir().unwrap();
    let anim = dir.path().join("walk.vox");
    animated_vox(&anim);
    let info = info_json(anim.to_str().unwrap());
    assert_eq!(info["objects"].as_array().unwrap().len(), 1);
    assert_eq!(
        info["objects"][0]["frame_voxels"],
        serde_json::json!([2, 3, 4])
    );
    let o = thicket(&["info", anim.to_str().unwrap()]);
    assert!(
        stdout(&o).contains("3 frames (voxels per frame: 2, 3, 4)"),
        "{}",
        stdout(&o)
    );

    let out = dir.path().join("again.vox");
    let o = thicket(&[
        "export-vox",
        anim.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("9 voxels in 3 model(s) placed 1 time(s)"),
        "{}",
        stdout(&o)
    );
    let again = info_json(out.to_str().unwrap());
    assert_eq!(
        again["objects"][0]["frame_voxels"],
        serde_json::json!([2, 3, 4])
    );

    // --time picks the frame: 0.1 s per frame, looping after 0.3 s.
    let render = |t: &str| {
        let png = dir.path().join(format!("t{t}.png"));
        let o = thicket(&[
            "render",
            anim.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--size",
            "48x48",
            "--time",
            t,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        image::open(&png).unwrap().to_rgba8().into_raw()
    };
    let (f0, f1, f2, wrapped) = (render("0"), render("0.15"), render("0.25"), render("0.35"));
    assert!(f0 != f1 && f1 != f2 && f0 != f2);
    assert_eq!(wrapped, f0);
    // A still file has nothing to play.
    let o = thicket(&[
        "render",
        &format!("{ASSETS}/vox/mmmm/chr_army1.vox"),
        "-o",
        dir.path().join("army.png").to_str().unwrap(),
        "--time",
        "1",
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("no skinned model, frame sequence or keyed transform"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn skin_report_measures_the_bending_cylinder() {
    let o = thicket(&[
        "skin-report",
        "--cylinder",
        "7",
        "--frames",
        "2",
        "--size",
        "256x256",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let holes = |strategy: &str| {
        r["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|row| row["settings"]["strategy"] == strategy)
            .unwrap_or_else(|| panic!("{strategy} measured"))["posed"]["holes"]
            .as_u64()
            .unwrap()
    };
    // The figures of docs/skinning.md: the bent elbow opens 5,336 hole px without stretch,
    // Corners closes every one.
    assert_eq!(holes("Off"), 5_336);
    assert_eq!(holes("Corners"), 0);
    assert_eq!(r["rows"][0]["views"].as_array().unwrap().len(), 6);
    // Neither a project nor the cylinder: a usage error, no panic.
    let o = thicket(&["skin-report"]);
    assert!(!o.status.success());
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
}

#[test]
fn a_bad_option_value_is_reported_once_with_status_1() {
    // --size, --camera and --quality are typed values: clap refuses a bad one while reading the
    // command line, before any file is opened, with the flag and the reason on one line.
    let dir = tempfile::tempdir().unwrap();
    let project = sample_project(dir.path());
    let png = dir.path().join("out.png");
    let p = project.to_str().unwrap();
    let o_path = png.to_str().unwrap();
    for (extra, says) in [
        (["--size", "12"], "expected WIDTHxHEIGHT"),
        (["--camera", "NaN,0,5"], "must be finite"),
        (["--quality", "nope=1"], "lod_pixel_threshold"),
        (["--quality", "lod_pixel_threshold=65"], "0.05..=64"),
    ] {
        let mut args = vec!["render", p, "-o", o_path];
        args.extend_from_slice(&extra);
        let o = thicket(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{extra:?}: {err}");
        assert_eq!(err.matches(extra[0]).count(), 1, "said once: {err}");
        assert_eq!(err.matches("error:").count(), 1, "said once: {err}");
        assert!(err.contains(says), "{extra:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!png.exists(), "{extra:?} wrote a file");
    }
    // The same parser serves every command that takes a size.
    let o = thicket(&["skin-report", p, "--size", "8x"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("--size"), "{}", stderr(&o));
    // --help still succeeds; an unknown flag is still clap's usage error.
    let o = thicket(&["render", "--help"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("[default: 800x800]"), "{}", stdout(&o));
    let o = thicket(&["render", p, "-o", o_path, "--no-such-flag"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// `--instancing nodes` writes the forest's placements as plain nodes and says so; the
/// default says which readers refuse the extension.
#[test]
fn export_instancing_nodes_writes_a_node_per_placement_and_says_which_readers_need_what() {
    let dir = tempfile::tempdir().unwrap();
    let forest = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/forest.thicket.json"
    );
    let glb = dir.path().join("forest.glb");
    let run = |instancing: &str| {
        thicket(&[
            "export",
            forest,
            "-o",
            glb.to_str().unwrap(),
            "--resolution",
            "64",
            "--instance-level",
            "14",
            "--instancing",
            instancing,
        ])
    };
    let o = run("nodes");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("1,024 placements written as a node each"),
        "{}",
        stdout(&o)
    );
    let (gltf, _, _) = gltf::import(&glb).unwrap();
    assert!(
        gltf.extensions_used()
            .all(|e| e != "EXT_mesh_gpu_instancing")
    );
    let o = run("gpu");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("1,024 placements written with EXT_mesh_gpu_instancing"),
        "{}",
        stdout(&o)
    );
    // auto: 1,024 is few enough for nodes.
    let o = run("auto");
    assert!(
        stdout(&o).contains("written as a node each"),
        "{}",
        stdout(&o)
    );
}

/// `thicket info` on the default forest's export, in both instancing modes, reports what the
/// file holds, counted without expanding its 131,072 placements (44.5 billion triangles), and
/// says why an import refuses it; `thicket import` refuses it in one line.
#[test]
fn info_counts_an_exported_forest_too_large_to_import() {
    let dir = tempfile::tempdir().unwrap();
    let forest = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/forest.thicket.json"
    );
    for instancing in ["gpu", "nodes"] {
        let glb = dir.path().join(format!("forest-{instancing}.glb"));
        let glb_arg = glb.to_str().unwrap();
        let o = thicket(&["export", forest, "-o", glb_arg, "--instancing", instancing]);
        assert!(o.status.success(), "{}", stderr(&o));
        let o = thicket(&["info", glb_arg]);
        assert!(o.status.success(), "{instancing}: {}", stderr(&o));
        let text = stdout(&o);
        assert!(
            text.contains("counted from the file, not built: 44,525,498,368 triangles"),
            "{instancing}: {text}"
        );
        assert!(
            text.contains("not imported: ") && text.contains("the limit is 268,435,456 vertices"),
            "{instancing}: {text}"
        );
        let o = thicket(&["info", glb_arg, "--json"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        let counted = &json["counted"];
        let meshes = counted["meshes"].as_array().unwrap();
        // Two cell meshes (the tree and its mirror image) drawn 65,536 times each, the ground once.
        let copies: Vec<u64> = meshes
            .iter()
            .map(|m| m["copies"].as_u64().unwrap())
            .collect();
        assert_eq!(copies, [65_536, 65_536, 1], "{instancing}");
        let sum: u64 = meshes
            .iter()
            .map(|m| m["triangles"].as_u64().unwrap() * m["copies"].as_u64().unwrap())
            .sum();
        assert_eq!(counted["triangles"].as_u64(), Some(sum), "{instancing}");
        let (nodes, instances) = if instancing == "gpu" {
            (504, 131_072)
        } else {
            (0, 0)
        };
        assert_eq!(
            counted["instanced_nodes"].as_u64(),
            Some(nodes),
            "{instancing}"
        );
        assert_eq!(
            counted["instances"].as_u64(),
            Some(instances),
            "{instancing}"
        );
        assert_eq!(json["objects"].as_array().map(Vec::len), Some(0));
        let out = dir.path().join("forest.thicket.json");
        let o = thicket(&["import", glb_arg, "-o", out.to_str().unwrap()]);
        assert!(one_error_line(&o).contains("too large"), "{}", stderr(&o));
        assert!(!out.exists());
    }
}

/// A project with three trees from the builder (their parameters saved with them), a KRS
/// terrain and a rock (a KRS object the builder did not make).
fn forest_project(dir: &Path) -> PathBuf {
    use thicket_core::krs::{Material, TreeParams, presets};
    use thicket_core::scene::TreeBuilderLink;
    let mut doc = Document::default();
    for (k, name) in ["Oak", "Birch", "Pine"].into_iter().enumerate() {
        let mut params = TreeParams::default();
        params.widths[0] = 0.2 + 0.03 * k as f32;
        params.route[1].y += 0.3 * k as f32;
        let id = doc.add(name, ObjectKind::Krs(params.build().unwrap()));
        doc.tree_builders
            .push(TreeBuilderLink { object: id, params });
    }
    doc.add(
        "Terrain",
        ObjectKind::Krs(presets::folded_ground(Material::default(), 4, 5.0, 1)),
    );
    doc.add("Rock", ObjectKind::Krs(presets::battered_rock(3)));
    let path = dir.join("trees.thicket.json");
    thicket_core::io::project::save(&doc, &path).unwrap();
    path
}

#[test]
fn forest_grows_trees_on_terrain_and_as_a_union() {
    let dir = tempfile::tempdir().unwrap();
    let project = forest_project(dir.path());
    let out = dir.path().join("forest.thicket.json");
    let o = thicket(&[
        "forest",
        project.to_str().unwrap(),
        "--object",
        "Oak",
        "--trees",
        "16x16",
        "--area",
        "160,160",
        "--on",
        "Terrain",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("256 trees placed"), "{}", stdout(&o));
    let doc = thicket_core::io::project::load(&out).unwrap();
    let by_name = |n: &str| doc.objects.iter().find(|o| o.name == n).unwrap();
    let krs = |n: &str| match &by_name(n).kind {
        ObjectKind::Krs(k) => k.clone(),
        _ => panic!("{n} is KRS"),
    };
    assert_eq!(doc.forests.len(), 1);
    assert!(
        !by_name("Oak").visible,
        "the tree is hidden under its forest"
    );
    assert_eq!(
        krs("Oak forest").instance_count(),
        krs("Oak").instance_count() * 256
    );
    // The terrain keeps its 4 folds and shares the forest's 8 reflections.
    let terrain = krs("Terrain");
    assert_eq!(terrain.mirrors.len(), 4 + 8);
    assert_eq!(doc.forests[0].terrain_mirrors, 4);
    assert_eq!(
        terrain.mirrors[4..],
        krs("Oak forest").mirrors[krs("Oak").mirrors.len()..]
    );

    // A union of three trees: 2 objects per tree.
    let union = dir.path().join("union.thicket.json");
    let o = thicket(&[
        "forest",
        project.to_str().unwrap(),
        "--object",
        "Oak",
        "--object",
        "Birch",
        "--object",
        "Pine",
        "--trees",
        "12x8",
        "--area",
        "96,64",
        "-o",
        union.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("96 trees placed") && stdout(&o).contains("in 6 object(s)"),
        "{}",
        stdout(&o)
    );
    let doc = thicket_core::io::project::load(&union).unwrap();
    assert_eq!(doc.forests[0].objects.len(), 6);
}

#[test]
fn forest_refuses_bad_input_once_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let project = forest_project(dir.path());
    let out = dir.path().join("forest.thicket.json");
    let run = |extra: &[&str]| {
        let mut args = vec!["forest", project.to_str().unwrap()];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", out.to_str().unwrap()]);
        thicket(&args)
    };
    for (extra, says) in [
        (
            &["--object", "Rock", "--trees", "4x4", "--area", "40,40"][..],
            "\"Rock\" is not a tree the tree builder made",
        ),
        (
            &["--object", "Oak", "--trees", "3x4", "--area", "40,40"],
            "3 trees along x: one tree fills the grid by reflections",
        ),
        (
            &["--object", "Oak", "--trees", "4x4", "--area", "0,40"],
            "area x must be a positive length",
        ),
        (
            &["--object", "Oak", "--trees", "4x4", "--area", "NaN,40"],
            "area x must be a positive length",
        ),
        (
            &[
                "--object",
                "Oak",
                "--trees",
                "1048576x2097152",
                "--area",
                "40,40",
            ],
            "41 reflection levels",
        ),
        (
            &[
                "--object", "Oak", "--object", "Birch", "--trees", "4x4", "--area", "40,40",
                "--on", "Terrain",
            ],
            "cannot stand on a KRS terrain",
        ),
        (
            &[
                "--object", "Oak", "--object", "Rock", "--trees", "4x4", "--area", "40,40",
            ],
            "\"Rock\" is not a tree",
        ),
        (
            &["--object", "Elm", "--trees", "4x4", "--area", "40,40"],
            "no object named \"Elm\"",
        ),
    ] {
        let o = run(extra);
        assert_fails_naming(&o, &project);
        let err = stderr(&o);
        assert!(err.contains(says), "{extra:?}: {err}");
        assert_eq!(err.lines().count(), 1, "said once: {err}");
        assert!(!out.exists(), "{extra:?} wrote nothing");
    }
}

/// Every file in `dir` (not recursing) with its bytes, by name.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p.file_name().unwrap().to_string_lossy().into_owned(), bytes)
        })
        .collect();
    v.sort();
    v
}

/// Asserts a refusal in one line that names `output` and says what it would overwrite.
fn assert_refused_naming(o: &Output, output: &str, what: &str) {
    let err = one_error_line(o);
    assert!(err.starts_with(&format!("error: {output}: ")), "{err}");
    assert!(err.contains(what), "{what:?} in {err}");
}

#[test]
fn outputs_never_overwrite_the_input_project_or_its_payload() {
    let dir = tempfile::tempdir().unwrap();
    let project = sample_project(dir.path());
    let p = project.to_str().unwrap().to_owned();
    let bin = thicket_core::io::project::bin_path_for(&project);
    assert!(bin.is_file() && bin != project);
    let b = bin.to_str().unwrap().to_owned();
    // Another spelling of the same file, and a link to it.
    let dotted = format!(
        "{}/./{}",
        dir.path().display(),
        project.file_name().unwrap().to_string_lossy()
    );
    let link = dir.path().join("link.thicket.json");
    std::os::unix::fs::symlink(&project, &link).unwrap();
    let l = link.to_str().unwrap().to_owned();
    let before = snapshot(dir.path());
    let input = "the output is the input project";
    let payload = "the output is the payload of the input project";
    let cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (vec!["render", &p, "--size", "8x8", "-o", &p], &p, input),
        (
            vec!["render", &p, "--size", "8x8", "-o", &dotted],
            &dotted,
            input,
        ),
        (vec!["render", &p, "--size", "8x8", "-o", &l], &l, input),
        (vec!["render", &p, "--size", "8x8", "-o", &b], &b, payload),
        (vec!["export-vox", &p, "-o", &p], &p, input),
        (vec!["export-vox", &p, "-o", &b], &b, payload),
        (vec!["export", &p, "-o", &b], &b, payload),
        (
            vec!["enhance", &p, "--object", "row", "--factor", "2", "-o", &p],
            &p,
            input,
        ),
    ];
    for (args, output, what) in &cases {
        let o = thicket(args);
        assert_refused_naming(&o, output, what);
        assert!(
            stderr(&o).contains(&*p) || *what == input,
            "the payload refusal names the project: {}",
            stderr(&o)
        );
        assert_eq!(snapshot(dir.path()), before, "{args:?} changed the folder");
    }
    // A .gltf brings OUT.bin beside it: refused when that is the project's payload (here a
    // project whose JSON names its payload `scene.bin`).
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&project).unwrap()).unwrap();
    json["bin"]["file"] = "scene.bin".into();
    let renamed = dir.path().join("renamed.thicket.json");
    std::fs::write(&renamed, serde_json::to_vec(&json).unwrap()).unwrap();
    std::fs::copy(&bin, dir.path().join("scene.bin")).unwrap();
    assert!(
        thicket(&["info", renamed.to_str().unwrap()])
            .status
            .success()
    );
    let gltf = dir.path().join("scene.gltf");
    let before = snapshot(dir.path());
    let o = thicket(&[
        "export",
        renamed.to_str().unwrap(),
        "-o",
        gltf.to_str().unwrap(),
    ]);
    assert_refused_naming(
        &o,
        &dir.path().join("scene.bin").display().to_string(),
        payload,
    );
    assert_eq!(snapshot(dir.path()), before);
    // A file imported onto itself.
    let vox = dir.path().join("m.vox");
    assert!(
        thicket(&["export-vox", &p, "-o", vox.to_str().unwrap()])
            .status
            .success()
    );
    let before = snapshot(dir.path());
    let v = vox.to_str().unwrap();
    let o = thicket(&["import", v, "-o", v]);
    assert_refused_naming(&o, v, "the output is the input file");
    assert_eq!(snapshot(dir.path()), before);
}

/// The names in `dir` a failed write may have left: temporaries and half-written payloads.
fn leftovers(dir: &Path, expected: &[&str]) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !expected.contains(&n.as_str()))
        .collect()
}

#[test]
fn failed_writes_remove_their_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let project = sample_project(dir.path());
    let p = project.to_str().unwrap().to_owned();
    let out = tempfile::tempdir().unwrap();
    // A folder where the output should be (the temporary is written, the rename fails) and a
    // plain file where its folder should be (nothing can be created).
    let taken = |name: &str| {
        let path = out.path().join(name);
        std::fs::create_dir(&path).unwrap();
        std::fs::write(path.join("keep"), b"x").unwrap();
        path.to_str().unwrap().to_owned()
    };
    std::fs::write(out.path().join("afile"), b"x").unwrap();
    let under_file = |name: &str| format!("{}/afile/{name}", out.path().display());
    let vox = dir.path().join("m.vox");
    assert!(
        thicket(&["export-vox", &p, "-o", vox.to_str().unwrap()])
            .status
            .success()
    );
    let v = vox.to_str().unwrap().to_owned();
    let bin_name = thicket_core::io::project::bin_path_for(&project)
        .file_name()
        .unwrap()
        .to_string_lossy()
        .into_owned();
    let cases: Vec<(Vec<String>, String)> = vec![
        (
            vec!["render".into(), p.clone(), "--size".into(), "8x8".into()],
            taken("r.png"),
        ),
        (
            vec!["render".into(), p.clone(), "--size".into(), "8x8".into()],
            under_file("r.png"),
        ),
        (vec!["export-vox".into(), p.clone()], taken("e.vox")),
        (vec!["export-vox".into(), p.clone()], under_file("e.vox")),
        (vec!["export".into(), p.clone()], taken("g.glb")),
        (vec!["export".into(), p.clone()], taken("g.gltf")),
        (vec!["export".into(), p.clone()], under_file("g.gltf")),
        (vec!["import".into(), v.clone()], taken("i.thicket.json")),
        (
            vec!["import".into(), v.clone()],
            under_file("i.thicket.json"),
        ),
        (
            vec![
                "enhance".into(),
                p.clone(),
                "--object".into(),
                "row".into(),
                "--factor".into(),
                "2".into(),
            ],
            taken("f.thicket.json"),
        ),
    ];
    let names = [
        "afile",
        "r.png",
        "e.vox",
        "g.glb",
        "g.gltf",
        "i.thicket.json",
        "f.thicket.json",
    ];
    for (args, output) in &cases {
        let mut args: Vec<&str> = args.iter().map(String::as_str).collect();
        args.extend(["-o", output.as_str()]);
        let o = thicket(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: one line: {err}");
        let name = Path::new(output).file_name().unwrap().to_string_lossy();
        // A .gltf's buffer is written first: its failure names OUT.bin.
        let bin_of_gltf = name.replace(".gltf", ".bin");
        assert!(
            err.contains(name.as_ref()) || err.contains(&bin_of_gltf),
            "{args:?}: names {name}: {err}"
        );
        assert!(
            !err.contains(".tmp-")
                && !err
                    .split_whitespace()
                    .any(|w| w.trim_end_matches(':').ends_with(".tmp")),
            "{args:?}: names the output, not a temporary: {err}"
        );
        assert_eq!(
            leftovers(out.path(), &names),
            Vec::<String>::new(),
            "{args:?}"
        );
        assert_eq!(
            leftovers(dir.path(), &["two.thicket.json", &bin_name, "m.vox"]),
            Vec::<String>::new(),
            "{args:?}"
        );
    }
    // The folders standing in for outputs hold only what they held.
    for name in [
        "r.png",
        "e.vox",
        "g.glb",
        "g.gltf",
        "i.thicket.json",
        "f.thicket.json",
    ] {
        assert_eq!(
            leftovers(&out.path().join(name), &["keep"]),
            Vec::<String>::new(),
            "{name}"
        );
    }
}

/// Asserts `text` carries no Rust debug output.
fn assert_no_debug_text(text: &str) {
    for debug in ["{", "}", "ChunkType", "Some(", "OrbitCamera", "Vec3("] {
        assert!(!text.contains(debug), "{debug:?} in {text}");
    }
}

#[test]
fn a_damaged_texture_is_refused_in_words_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("tex.png");
    thicket_core::render::RgbaImage {
        width: 2,
        height: 2,
        pixels: vec![200; 16],
    }
    .save_png(&png)
    .unwrap();
    // The IDAT chunk's CRC (just before the 12-byte IEND chunk) broken.
    let mut bytes = std::fs::read(&png).unwrap();
    let at = bytes.len() - 13;
    bytes[at] ^= 0xff;
    std::fs::write(&png, bytes).unwrap();
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl red\nKd 1 0 0\nmap_Kd tex.png\n",
    )
    .unwrap();
    let obj = dir.path().join("tri.obj");
    std::fs::write(
        &obj,
        "mtllib m.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n",
    )
    .unwrap();
    let o = thicket(&["info", obj.to_str().unwrap()]);
    let err = one_error_line(&o);
    assert_eq!(
        err.matches("tex.png").count(),
        1,
        "names the texture once: {err}"
    );
    assert!(err.contains("the PNG data is damaged"), "{err}");
    assert!(err.contains("IDAT"), "names the chunk: {err}");
    assert_no_debug_text(&err);
}

#[test]
fn an_unusable_camera_names_the_field_and_what_set_it() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("out.png");
    // --camera on a project with no voxels: the far plane follows the distance, 4 x 1e38.
    let empty = dir.path().join("empty.thicket.json");
    assert!(thicket(&["new", empty.to_str().unwrap()]).status.success());
    let o = thicket(&[
        "render",
        empty.to_str().unwrap(),
        "--camera",
        "0,0,1e38",
        "-o",
        png.to_str().unwrap(),
    ]);
    let err = one_error_line(&o);
    assert!(
        err.starts_with("error: --camera 0,0,1e38: it makes camera.far invalid: inf must be"),
        "the option, not a file, is blamed: {err}"
    );
    assert!(
        !err.contains("empty.thicket.json") && !err.contains("out.png"),
        "{err}"
    );
    assert_no_debug_text(&err);
    assert!(!png.exists());
    // A project whose own camera is unusable: the project, the field and its value.
    let project = sample_project(dir.path());
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&project).unwrap()).unwrap();
    json["camera"]["fov_y_deg"] = 500.0.into();
    std::fs::write(&project, serde_json::to_vec(&json).unwrap()).unwrap();
    let o = thicket(&[
        "render",
        project.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
    ]);
    let err = one_error_line(&o);
    assert!(
        err.starts_with(&format!("error: {}: ", project.display())),
        "{err}"
    );
    assert!(
        err.contains("camera.fov_y_deg of document is invalid: 500 must be between 0.1 and 179"),
        "{err}"
    );
    assert_eq!(err.matches("two.thicket.json").count(), 1, "{err}");
    assert_no_debug_text(&err);
    assert!(!png.exists());
}

#[test]
fn a_skin_that_cannot_be_imported_names_the_file_once() {
    let dir = tempfile::tempdir().unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(
        &std::fs::read(format!("{ASSETS}/skinned/SimpleSkin.gltf")).unwrap(),
    )
    .unwrap();
    // The static reader takes the file; the skinned one refuses a joint listed twice.
    json["skins"][0]["joints"] = serde_json::json!([1, 1]);
    let gltf = dir.path().join("twice.gltf");
    std::fs::write(&gltf, serde_json::to_vec(&json).unwrap()).unwrap();
    let out = dir.path().join("out.thicket.json");
    let o = thicket(&[
        "import",
        gltf.to_str().unwrap(),
        "--depth",
        "4",
        "-o",
        out.to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(
        err.trim_end(),
        format!(
            "error: {}: the file has a skin that cannot be imported: skin 0 lists node 1 twice \
             (use --no-skin to import it as a static model)",
            gltf.display()
        )
    );
    assert_eq!(err.matches("twice.gltf").count(), 1, "{err}");
    assert!(!out.exists());
}

#[test]
fn a_project_with_more_lights_than_the_maximum_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let project = sample_project(dir.path());
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&project).unwrap()).unwrap();
    let sun = json["lights"][0].clone();
    json["lights"] = serde_json::Value::Array(vec![sun; thicket_core::scene::MAX_LIGHTS + 1]);
    std::fs::write(&project, serde_json::to_vec(&json).unwrap()).unwrap();
    let png = dir.path().join("out.png");
    let o = thicket(&[
        "render",
        project.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
    ]);
    let err = one_error_line(&o);
    assert!(
        err.starts_with(&format!("error: {}: ", project.display())),
        "{err}"
    );
    assert!(
        err.contains("257 lights, more than the 256 a document may have"),
        "{err}"
    );
    assert!(!png.exists());
}

#[test]
fn export_vox_refuses_early_advising_only_options_that_exist() {
    let dir = tempfile::tempdir().unwrap();
    // One voxel at scale 1 sets the grid unit; one scaled 400x would fill 400^3 = 64 M cells,
    // over the .vox export's 2^25.
    let mut doc = Document::default();
    for (name, scale, x) in [("fine", 1.0, 0.0), ("coarse", 400.0, 10.0)] {
        let mut svo = Svo::new(2, false).unwrap();
        svo.set(UVec3::ZERO, Voxel::new([10, 200, 30, 255], Vec3::Y))
            .unwrap();
        doc.add(
            name,
            ObjectKind::Voxels(VoxelModel {
                svo,
                voxel_size: 0.5,
                ..VoxelModel::default()
            }),
        );
        let o = doc.objects.last_mut().unwrap();
        o.transform.scale = Vec3::splat(scale);
        o.transform.translation.x = x;
    }
    let project = dir.path().join("scaled.thicket.json");
    thicket_core::io::project::save(&doc, &project).unwrap();
    let p = project.to_str().unwrap();
    let out = dir.path().join("out.vox");
    let o_path = out.to_str().unwrap();
    let help = stdout(&thicket(&["export-vox", "--help"]));
    let exists = |option: &str| {
        help.contains(&format!("{option} ")) || help.contains(&format!("{option}\n"))
    };
    let o = thicket(&["export-vox", p, "-o", o_path]);
    let err = one_error_line(&o);
    assert!(
        err.starts_with(&format!(
            "error: {p}: the export would write about 64,000,001 .vox voxels"
        )),
        "{err}"
    );
    assert!(err.contains("more than the limit of 33,554,432"), "{err}");
    let advised: Vec<&str> = err
        .split_whitespace()
        .filter(|w| w.starts_with("--"))
        .collect();
    assert!(!advised.is_empty(), "{err}");
    for option in &advised {
        assert!(
            exists(option),
            "{option} is not an export-vox option: {err}"
        );
    }
    assert!(!out.exists());
    // The unit it suggests brings the count under the limit: the next check, the memory
    // budget (kept tiny so nothing is built), is the one that refuses.
    let suggested = err
        .split("about ")
        .last()
        .and_then(|t| t.split_whitespace().next())
        .unwrap();
    let o = thicket(&[
        "export-vox",
        p,
        "-o",
        o_path,
        "--grid-unit",
        suggested,
        "--memory-limit",
        "1M",
    ]);
    let err = stderr(&o);
    assert!(
        err.contains(".vox voxels would need about") && err.contains("(--memory-limit)"),
        "--grid-unit {suggested}: {err}"
    );
    assert!(!out.exists());
    // Under the cell limit but over a memory limit: refused with the estimate, advising
    // options that exist.
    let o = thicket(&[
        "export-vox",
        p,
        "-o",
        o_path,
        "--grid-unit",
        "2",
        "--memory-limit",
        "1M",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("exporting about 1,000,001 .vox voxels would need about"),
        "{err}"
    );
    assert!(
        err.contains("over the limit of 1.0 MiB (--memory-limit)"),
        "{err}"
    );
    for option in err.split_whitespace().filter(|w| w.starts_with("--")) {
        let option = option.trim_end_matches([',', ')', ':']);
        assert!(
            exists(option),
            "{option} is not an export-vox option: {err}"
        );
    }
    assert!(!out.exists());
    let o = thicket(&["export-vox", p, "-o", o_path, "--grid-unit", "0"]);
    assert!(
        stderr(&o).contains("--grid-unit 0: give a positive length"),
        "{}",
        stderr(&o)
    );
}

/// `info`, `export` and `skin-report` take `--memory-limit` and refuse before the work: the
/// house project (2.7 MB payload) and the house .vox (180,202 voxels) are refused under 4 MiB
/// with the estimate and the limit, in one line naming the file, and read under the default.
#[test]
fn info_export_and_skin_report_refuse_over_the_memory_limit_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    let project = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/house.thicket.json"
    );
    let vox = format!("{ASSETS}/vox/mmmm/obj_house4.vox");
    let glb = dir.path().join("house.glb");
    let refused = |o: &Output, file: &str, what: &str| {
        let err = one_error_line(o);
        assert!(
            err.starts_with("error: ")
                && err.contains(file)
                && err.contains(what)
                && err.contains("over the limit of 4.0 MiB (--memory-limit)"),
            "{err}"
        );
        assert_eq!(err.matches(file).count(), 1, "the file named once: {err}");
    };
    let o = thicket(&["info", project, "--memory-limit", "4M"]);
    refused(
        &o,
        "house.thicket.json",
        "loading the project would need about",
    );
    let o = thicket(&["info", &vox, "--memory-limit", "4M"]);
    refused(
        &o,
        "obj_house4.vox",
        "holding 180,202 voxels would need about",
    );
    let o = thicket(&[
        "export",
        project,
        "-o",
        glb.to_str().unwrap(),
        "--memory-limit",
        "4M",
    ]);
    refused(&o, "house.thicket.json", "loading the project");
    assert!(!glb.exists(), "nothing written");
    let o = thicket(&["skin-report", project, "--memory-limit", "4M"]);
    refused(&o, "house.thicket.json", "loading the project");
    // Every command that reads a file reads it within its budget.
    let png = dir.path().join("house.png");
    let o = thicket(&[
        "render",
        project,
        "-o",
        png.to_str().unwrap(),
        "--memory-limit",
        "4M",
    ]);
    refused(&o, "house.thicket.json", "loading the project");
    let imported = dir.path().join("house.thicket.json");
    let o = thicket(&[
        "import",
        &vox,
        "-o",
        imported.to_str().unwrap(),
        "--memory-limit",
        "4M",
    ]);
    refused(
        &o,
        "obj_house4.vox",
        "holding 180,202 voxels would need about",
    );
    assert!(!png.exists() && !imported.exists(), "nothing written");
    // The same files within the default budget.
    for file in [project, vox.as_str()] {
        let o = thicket(&["info", file]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stdout(&o).contains("voxels"), "{}", stdout(&o));
    }
    // export turns the budget into a triangle limit checked before meshing: the tree's
    // smooth mesh at resolution 512 does not fit 64 MiB, and the message says why.
    let tree = concat!(env!("CARGO_MANIFEST_DIR"), "/../projects/tree.thicket.json");
    let o = thicket(&[
        "export",
        tree,
        "-o",
        glb.to_str().unwrap(),
        "--mode",
        "smooth",
        "--resolution",
        "512",
        "--memory-limit",
        "64M",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("triangles here because each needs about 160 bytes")
            && err.contains("memory limit is 64.0 MiB (--memory-limit)")
            && !err.contains("--max-triangles"),
        "{err}"
    );
    assert!(!glb.exists(), "nothing written");
    // skin-report also estimates its frame: a project that loads, at a size that does not fit.
    let o = thicket(&[
        "skin-report",
        "--cylinder",
        "4",
        "--size",
        "16384x16384",
        "--memory-limit",
        "256M",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.starts_with("error: rendering 16384x16384 would need about "),
        "{err}"
    );
}

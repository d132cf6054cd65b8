//! `thicket rig`, `thicket animate` and `thicket info --joints` on a model made with `thicket
//! new`: the skeleton binds, the clip plays (renders at two times differ, the leg moves and the
//! body does not), and every bad input is one clear error naming the file and the joint, with
//! nothing written.

use std::path::{Path, PathBuf};

use thicket_core::scene::ObjectKind;

mod common;
use common::{stderr, stdout, thicket};

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `thicket new` of a solid 8×32×8 bar of 0.1 m voxels: own-space bounds (-0.4, 0, -0.4) ..
/// (0.4, 3.2, 0.4).
fn new_bar(dir: &Path) -> PathBuf {
    let p = dir.join("bar.thicket.json");
    let o = thicket(&[
        "new",
        path_str(&p),
        "--extent",
        "8,32,8",
        "--voxel-size",
        "0.1",
        "--fill",
        "solid",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    p
}

const SKELETON: &str = r#"{"joints": [
  {"name": "base", "parent": null, "position": [0.0, 0.2, 0.0]},
  {"name": "mid", "parent": "base", "position": [0.0, 1.6, 0.0]},
  {"name": "top", "parent": "mid", "position": [0.0, 3.0, 0.0]}
]}"#;

const CLIP: &str = r#"{"name": "bend", "length": 1.0, "loop": true, "keys": [
  {"joint": "mid", "time": 0.0, "rotation_deg": [0, 0, 0]},
  {"joint": "mid", "time": 0.5, "rotation_deg": [0, 0, 60]},
  {"joint": "mid", "time": 1.0, "rotation_deg": [0, 0, 0]}
]}"#;

/// `thicket rig BAR --object Model --skeleton SKEL -o OUT`.
fn rig(bar: &Path, skel: &Path, out: &Path) -> std::process::Output {
    thicket(&[
        "rig",
        path_str(bar),
        "--object",
        "Model",
        "--skeleton",
        path_str(skel),
        "-o",
        path_str(out),
    ])
}

/// `thicket render PROJECT -o OUT --size SIZE --time T EXTRA...`: the image's RGBA bytes.
fn render_at(project: &Path, out: &Path, size: &str, t: &str, extra: &[&str]) -> Vec<u8> {
    let mut args = vec![
        "render",
        path_str(project),
        "-o",
        path_str(out),
        "--size",
        size,
        "--time",
        t,
    ];
    args.extend_from_slice(extra);
    let o = thicket(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    image::open(out).unwrap().to_rgba8().into_raw()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn rig_animate_and_info_make_a_bar_bend() {
    let dir = tempfile::tempdir().unwrap();
    let bar = new_bar(dir.path());
    let skel = write(dir.path(), "skel.json", SKELETON);
    let clip = write(dir.path(), "bend.json", CLIP);
    let rigged = dir.path().join("rigged.thicket.json");
    let o = rig(&bar, &skel, &rigged);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("rigged with 3 joints, geodesic binding of 2,048 voxels"),
        "{}",
        stdout(&o)
    );
    let animated = dir.path().join("animated.thicket.json");
    let o = thicket(&[
        "animate",
        path_str(&rigged),
        "--object",
        "Model",
        "--clip",
        path_str(&clip),
        "-o",
        path_str(&animated),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("plays clip \"bend\""), "{}", stdout(&o));

    // info --joints: each joint and the voxels it dominates, summing to every voxel.
    let o = thicket(&["info", "--joints", path_str(&animated)]);
    let text = stdout(&o);
    assert!(text.contains("skeleton: 3 joint(s)"), "{text}");
    assert!(
        text.contains("\"mid\" (child of \"base\") at [0.0000, 1.6000, 0.0000]"),
        "{text}"
    );
    let o = thicket(&["info", "--json", path_str(&animated)]);
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let model = &json["objects"][0];
    assert_eq!(model["bounds_min"], serde_json::json!([-0.4, 0.0, -0.4]));
    assert_eq!(model["bounds_max"], serde_json::json!([0.4, 3.2, 0.4]));
    let joints = model["joints"].as_array().unwrap();
    let dominated: u64 = joints
        .iter()
        .map(|j| j["dominant_voxels"].as_u64().unwrap())
        .sum();
    assert_eq!(dominated, 2048);
    assert!(
        joints
            .iter()
            .all(|j| j["dominant_voxels"].as_u64().unwrap() > 0)
    );

    // Rendered at 0 s and 0.5 s: different images.
    let (a, b) = (
        render_at(
            &animated,
            &dir.path().join("a.png"),
            "96x96",
            "0",
            &["--clip", "bend"],
        ),
        render_at(
            &animated,
            &dir.path().join("b.png"),
            "96x96",
            "0.5",
            &["--clip", "bend"],
        ),
    );
    let changed = a.chunks(4).zip(b.chunks(4)).filter(|(x, y)| x != y).count();
    assert!(
        changed > 200,
        "only {changed} pixels changed between 0 s and 0.5 s"
    );

    // The document: the top voxel moves, the base voxel stays.
    let doc = thicket_core::io::project::load(&animated).unwrap();
    let ObjectKind::Voxels(v) = &doc.objects[0].kind else {
        panic!("a voxel model");
    };
    let rig = v.rig.as_ref().unwrap();
    let m = rig.skinning_at(Some(0), 0.5);
    let skinned = |c: glam::UVec3| {
        let p = v.object_from_voxel().transform_point3(c.as_vec3() + 0.5);
        let s = v.svo.get(c).unwrap().skin;
        s.influences().fold(glam::Vec3::ZERO, |acc, (j, w)| {
            acc + m[usize::from(j)].transform_point3(p) * w
        }) - p
    };
    assert!(skinned(glam::UVec3::new(4, 0, 4)).length() < 1e-4);
    assert!(skinned(glam::UVec3::new(4, 31, 4)).length() > 1.0);

    // skin-report measures the native rig against its own skinned surface: at rest the voxels
    // cover exactly its pixels; bent, the smooth geodesic weights open no hole at this size
    // (the core test bends a rigidly split cylinder to see holes open).
    let o = thicket(&[
        "skin-report",
        path_str(&animated),
        "--frames",
        "2",
        "--views",
        "2",
        "--size",
        "64x64",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(r["reference"], "own_surface");
    let strategy = |name: &str| {
        r["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|row| row["settings"]["strategy"] == name)
            .unwrap()
            .clone()
    };
    let (off, corners) = (strategy("Off"), strategy("Corners"));
    assert!(off["rest"]["mesh_pixels"].as_u64().unwrap() > 100, "{off}");
    assert_eq!(off["rest"]["holes"], 0, "{off}");
    assert_eq!(off["rest"]["bloat"], 0, "{off}");
    assert_eq!(
        off["rest"]["voxel_pixels"], off["rest"]["mesh_pixels"],
        "{off}"
    );
    // The bent frame is measured: its silhouette is not the straight bar's.
    let frames = off["views"][0]["frames"].as_array().unwrap();
    assert_ne!(frames[0]["mesh_pixels"], frames[1]["mesh_pixels"], "{off}");
    assert!(corners["posed"]["mesh_pixels"].as_u64().unwrap() > 100);
    assert_eq!(corners["posed"]["holes"], 0, "{corners}");
    let o = thicket(&["skin-report", path_str(&animated), "--size", "32x32"]);
    assert!(
        stdout(&o).contains("against its own skinned surface"),
        "{}",
        stdout(&o)
    );

    // A pose set by hand and not keyed: the export says it is not in the file.
    let mut posed = doc.clone();
    if let ObjectKind::Voxels(v) = &mut posed.objects[0].kind {
        v.rig
            .as_mut()
            .unwrap()
            .pose_overrides
            .push(thicket_core::skin::JointOverride {
                joint: 1,
                rotation: Some(glam::Quat::from_rotation_z(0.5)),
                ..thicket_core::skin::JointOverride::default()
            });
    }
    let posed_path = dir.path().join("posed.thicket.json");
    thicket_core::io::project::save(&posed, &posed_path).unwrap();
    let glb = dir.path().join("posed.glb");
    let o = thicket(&["export", path_str(&posed_path), "-o", path_str(&glb)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("the pose overrides of 1 joint(s) are not keyed"),
        "{}",
        stdout(&o)
    );
    let o = thicket(&["export", path_str(&animated), "-o", path_str(&glb)]);
    assert!(!stdout(&o).contains("not keyed"), "{}", stdout(&o));
}

#[test]
fn bad_skeletons_and_clips_are_one_clear_error_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let bar = new_bar(dir.path());
    let before = files_in(dir.path());
    let rig_with = |name: &str, text: &str, needle: &str| {
        let skel = write(dir.path(), name, text);
        let out = dir.path().join("out.thicket.json");
        let o = thicket(&[
            "rig",
            path_str(&bar),
            "--object",
            "Model",
            "--skeleton",
            path_str(&skel),
            "-o",
            path_str(&out),
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(
            err.starts_with("error: ") && err.lines().count() == 1,
            "{err}"
        );
        assert!(err.contains(name), "{err} names {name}");
        assert!(err.contains(needle), "{err} should say {needle:?}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "{name}: nothing is written");
        std::fs::remove_file(&skel).unwrap();
    };
    let joint = |name: &str, parent: &str, p: &str| {
        format!(r#"{{"name": "{name}", "parent": {parent}, "position": {p}}}"#)
    };
    let skel = |joints: &[String]| format!(r#"{{"joints": [{}]}}"#, joints.join(","));
    rig_with(
        "cycle.json",
        &skel(&[
            joint("a", r#""b""#, "[0, 1, 0]"),
            joint("b", r#""a""#, "[0, 2, 0]"),
        ]),
        "cycle",
    );
    rig_with(
        "unknown.json",
        &skel(&[joint("a", r#""ghost""#, "[0, 1, 0]")]),
        "\"ghost\"",
    );
    rig_with(
        "twice.json",
        &skel(&[
            joint("a", "null", "[0, 1, 0]"),
            joint("a", "null", "[0, 2, 0]"),
        ]),
        "named twice",
    );
    rig_with(
        "far.json",
        &skel(&[joint("far", "null", "[0, 90, 0]")]),
        "\"far\"",
    );
    // JSON has no NaN: a number too large for f32 is read as infinity or refused.
    rig_with(
        "nan.json",
        &skel(&[joint("nan", "null", "[1e60, 1, 0]")]),
        "nan",
    );
    rig_with("empty.json", r#"{"joints": []}"#, "no joints");
    let many: Vec<String> = (0..300)
        .map(|i| joint(&format!("j{i}"), "null", "[0, 1, 0]"))
        .collect();
    rig_with("many.json", &skel(&many), "at most 256");
    rig_with(
        "broken.json",
        r#"{"joints": [ {"name": "#,
        "not a valid skeleton",
    );

    // A clip on a model without a skeleton, and bad clips on a rigged one.
    let clip = write(dir.path(), "bend.json", CLIP);
    let out = dir.path().join("out.thicket.json");
    let o = thicket(&[
        "animate",
        path_str(&bar),
        "--object",
        "Model",
        "--clip",
        path_str(&clip),
        "-o",
        path_str(&out),
    ]);
    assert!(stderr(&o).contains("has no skeleton"), "{}", stderr(&o));
    assert!(!out.exists());
    let skel = write(dir.path(), "skel.json", SKELETON);
    let rigged = dir.path().join("rigged.thicket.json");
    let o = rig(&bar, &skel, &rigged);
    assert!(o.status.success(), "{}", stderr(&o));
    for (name, text, needle) in [
        (
            "late.json",
            r#"{"name": "x", "length": 1, "keys": [{"joint": "mid", "time": 2, "rotation_deg": [0, 0, 1]}]}"#,
            "0..=1",
        ),
        (
            "who.json",
            r#"{"name": "x", "length": 1, "keys": [{"joint": "elbow", "time": 0, "rotation_deg": [0, 0, 1]}]}"#,
            "\"elbow\"",
        ),
        (
            "nokeys.json",
            r#"{"name": "x", "length": 1, "keys": []}"#,
            "no keys",
        ),
    ] {
        let clip = write(dir.path(), name, text);
        let o = thicket(&[
            "animate",
            path_str(&rigged),
            "--object",
            "Model",
            "--clip",
            path_str(&clip),
            "-o",
            path_str(&out),
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(name) && err.contains(needle), "{err}");
        assert!(!out.exists());
    }
    // The output may not be the input.
    let o = thicket(&[
        "animate",
        path_str(&rigged),
        "--object",
        "Model",
        "--clip",
        path_str(&clip),
        "-o",
        path_str(&rigged),
    ]);
    assert!(
        stderr(&o).contains("the output is the input"),
        "{}",
        stderr(&o)
    );
    let after: Vec<String> = files_in(dir.path())
        .into_iter()
        .filter(|f| !f.ends_with(".json") || f.contains("thicket"))
        .collect();
    assert!(
        after
            .iter()
            .all(|f| before.contains(f) || f.starts_with("rigged.")),
        "stray files: {after:?} (before {before:?})"
    );
}

/// Keyed object transforms on the command line: `render --time` moves the object (two times,
/// two images; with no rig or frame sequence the time is still accepted), and `export` writes
/// them as a node animation and says so.
#[test]
fn keyed_object_transforms_render_at_a_time_and_export() {
    let dir = tempfile::tempdir().unwrap();
    let bar = new_bar(dir.path());
    let mut doc = thicket_core::io::project::load(&bar).unwrap();
    let mut motion = thicket_core::scene::ObjectMotion::default();
    motion.set_key(0.0, &thicket_core::scene::Transform::default());
    motion.set_key(
        1.0,
        &thicket_core::scene::Transform {
            translation: glam::Vec3::new(1.5, 0.0, 0.0),
            ..thicket_core::scene::Transform::default()
        },
    );
    doc.objects[0].motion = Some(motion);
    let moving = dir.path().join("moving.thicket.json");
    thicket_core::io::project::save(&doc, &moving).unwrap();
    let (a, b) = (
        render_at(&moving, &dir.path().join("a.png"), "64x64", "0", &[]),
        render_at(&moving, &dir.path().join("b.png"), "64x64", "1", &[]),
    );
    let changed = a.chunks(4).zip(b.chunks(4)).filter(|(x, y)| x != y).count();
    assert!(
        changed > 100,
        "only {changed} pixels changed between 0 s and 1 s"
    );
    let glb = dir.path().join("moving.glb");
    let o = thicket(&["export", path_str(&moving), "-o", path_str(&glb)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("keyed transforms written as node animations: Model"),
        "{}",
        stdout(&o)
    );
    let (gltf, _, _) = gltf::import(&glb).unwrap();
    let names: Vec<&str> = gltf.animations().filter_map(|a| a.name()).collect();
    assert_eq!(names, ["Model motion"]);
}

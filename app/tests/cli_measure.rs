//! `thicket tradeoff` on a small project: the report, the CSV and the plot are written and
//! agree; bad knobs fail naming the knob and write nothing. `thicket info --memory` reports
//! memory per object that follows the surface.

use std::path::{Path, PathBuf};

mod common;
use common::thicket;

/// A small voxel sphere over a ground plane with a shadow-casting sun.
fn small_project(dir: &Path) -> PathBuf {
    let doc = thicket_core::render::scenes::mixed_document(5).unwrap();
    let path = dir.join("small.thicket.json");
    thicket_core::io::project::save(&doc, &path).unwrap();
    path
}

#[test]
fn tradeoff_writes_report_csv_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let project = small_project(dir.path());
    let out = dir.path().join("out");
    let o = thicket(&[
        "tradeoff",
        project.to_str().unwrap(),
        "--knob",
        "lod_pixel_threshold=1,4,16",
        "--knob",
        "shadow_pcf_radius=0,2",
        "--size",
        "40x32",
        "--frames",
        "2",
        "-o",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let report = &json["report"];
    assert_eq!(
        (report["width"].as_u64(), report["height"].as_u64()),
        (Some(40), Some(32))
    );
    let points = report["points"].as_array().unwrap();
    // 3 presets + (base merged with balanced, lod 1 and pcf 1) + lod 4, lod 16, pcf 0, pcf 2.
    assert!(points.len() >= 6, "{}", points.len());
    for p in points {
        assert_eq!(p["times_ms"].as_array().unwrap().len(), 2);
        let rmse = p["error"]["rmse"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&rmse));
    }
    let on_front = |key: &str| points.iter().filter(|p| p[key] == true).count();
    assert!(on_front("on_work_front") >= 1 && on_front("on_time_front") >= 1);
    // The coarsest LOD has more coverage error than the finest measured setting.
    let find = |label: &str| {
        points
            .iter()
            .find(|p| p["setting"]["label"].as_str().unwrap().contains(label))
            .unwrap()
    };
    assert!(
        find("lod_pixel_threshold=16")["error"]["rmse"].as_f64()
            > find("preset final")["error"]["rmse"].as_f64()
    );
    let csv = std::fs::read_to_string(out.join("report.csv")).unwrap();
    assert_eq!(csv.lines().count(), points.len() + 1);
    assert!(csv.starts_with("label,changes,preset,time_ms,work,rmse"));
    let png = image::open(out.join("tradeoff.png")).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (1200, 520));
    // Drawn, not blank: red front markers and dark text/axes are present.
    let red = png
        .pixels()
        .filter(|p| p[0] > 200 && p[1] < 60 && p[2] < 60)
        .count();
    let dark = png
        .pixels()
        .filter(|p| p[0] < 80 && p[1] < 80 && p[2] < 80)
        .count();
    assert!(red > 50 && dark > 500, "red {red}, dark {dark}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("report.json") && stdout.contains("preset draft"),
        "{stdout}"
    );
}

#[test]
fn tradeoff_refuses_bad_knobs_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let project = small_project(dir.path());
    for (knob, names) in [
        ("no_such_knob=1,2", "no_such_knob"),
        ("lod_pixel_threshold=1,NaN", "lod_pixel_threshold=NaN"),
        ("lod_pixel_threshold", "NAME=V1,V2"),
    ] {
        let out = dir.path().join("bad");
        let o = thicket(&[
            "tradeoff",
            project.to_str().unwrap(),
            "--knob",
            knob,
            "--size",
            "16x16",
            "-o",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(names) && !err.contains("panicked"), "{err}");
        assert!(!out.exists(), "nothing written for {knob}");
    }
}

/// A project with one voxel sphere shell of octree depth `depth`.
fn sphere_project(dir: &Path, depth: u8) -> PathBuf {
    let doc = thicket_core::render::scenes::sphere_document(depth, 0.8).unwrap();
    let path = dir.join(format!("sphere{depth}.thicket.json"));
    thicket_core::io::project::save(&doc, &path).unwrap();
    path
}

#[test]
fn info_memory_per_object_follows_the_surface() {
    let dir = tempfile::tempdir().unwrap();
    let total = |depth: u8| {
        let path = sphere_project(dir.path(), depth);
        let o = thicket(&["info", "--json", "--memory", path.to_str().unwrap()]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let objects = json["objects"].as_array().unwrap();
        assert_eq!(objects.len(), 1);
        objects[0]["memory"]["total_bytes"].as_u64().unwrap()
    };
    // Doubling the resolution of a surface multiplies its memory by about 4, not 8.
    let (a, b) = (total(6), total(7));
    let ratio = b as f64 / a as f64;
    assert!((3.3..4.7).contains(&ratio), "{a} -> {b} bytes: x{ratio:.2}");
    let text = thicket(&[
        "info",
        "--memory",
        sphere_project(dir.path(), 5).to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("memory:"));
}

#[test]
fn tradeoff_sweeps_the_stretch_strategy_of_a_skinned_sample() {
    // The strategy is a quality knob that overrides every model's own: "model" keeps the
    // sample's (Adaptive), so it equals "adaptive"; "off" (voxels keep their size) opens holes.
    // 200², not smaller: at 96² CesiumMan's voxels are smaller than a pixel, and against the
    // 4×4-sample reference "off" opened no hole there (2026-12-05: 0 and 0; at 200², 31 and 2).
    let dir = tempfile::tempdir().unwrap();
    let project = Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/cesiumman.thicket.json");
    let out = dir.path().join("out");
    let o = thicket(&[
        "tradeoff",
        project.to_str().unwrap(),
        "--knob",
        "stretch_strategy=model,off,adaptive",
        "--no-presets",
        "--size",
        "200x200",
        "--frames",
        "1",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let points = json["report"]["points"].as_array().unwrap();
    let point = |label: &str| {
        points
            .iter()
            .find(|p| p["setting"]["label"].as_str().unwrap().ends_with(label))
            .unwrap_or_else(|| panic!("no point {label}"))
    };
    let (model, off, adaptive) = (
        point("stretch_strategy=model"),
        point("stretch_strategy=off"),
        point("stretch_strategy=adaptive"),
    );
    assert_eq!(model["error"], adaptive["error"]);
    assert_eq!(model["work"], adaptive["work"]);
    assert!(
        off["error"]["holes"].as_u64().unwrap() > adaptive["error"]["holes"].as_u64().unwrap(),
        "off {} vs adaptive {}",
        off["error"],
        adaptive["error"]
    );
    // A bad strategy name is refused, naming the knob.
    let o = thicket(&[
        "tradeoff",
        project.to_str().unwrap(),
        "--knob",
        "stretch_strategy=wide",
        "-o",
        dir.path().join("bad").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("stretch_strategy"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn tradeoff_drops_a_knob_with_no_effect_and_reports_time_spreads() {
    // A sphere and no shadow-casting light: the shadow map's size cannot change the image.
    let dir = tempfile::tempdir().unwrap();
    let mut doc = thicket_core::render::scenes::sphere_document(5, 0.4).unwrap();
    for l in &mut doc.lights {
        l.casts_shadows = false;
    }
    let project = dir.path().join("shadowless.thicket.json");
    thicket_core::io::project::save(&doc, &project).unwrap();
    let out = dir.path().join("out");
    let o = thicket(&[
        "tradeoff",
        project.to_str().unwrap(),
        "--knob",
        "shadow_map_size=256,4096",
        "--knob",
        "lod_pixel_threshold=1,8",
        "--size",
        "40x40",
        "--frames",
        "3",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("shadow_map_size: no effect at this size")
            && stdout.contains("lod_pixel_threshold: 2 different images"),
        "{stdout}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let report = &json["report"];
    let knobs = report["knobs"].as_array().unwrap();
    let knob = |name: &str| knobs.iter().find(|k| k["name"] == name).unwrap();
    assert_eq!(knob("shadow_map_size")["dropped"], true);
    assert_eq!(knob("lod_pixel_threshold")["dropped"], false);
    let points = report["points"].as_array().unwrap();
    let labels: Vec<&str> = points
        .iter()
        .map(|p| p["setting"]["label"].as_str().unwrap())
        .collect();
    assert!(
        !labels.iter().any(|l| l.contains("shadow_map_size=")),
        "{labels:?}"
    );
    assert!(labels.iter().any(|l| l.contains("lod_pixel_threshold=8")));
    for p in points {
        let (lo, mid, hi) = (
            p["time_min_ms"].as_f64().unwrap(),
            p["time_ms"].as_f64().unwrap(),
            p["time_max_ms"].as_f64().unwrap(),
        );
        assert!(lo <= mid && mid <= hi, "{lo} {mid} {hi}");
    }
    let csv = std::fs::read_to_string(out.join("report.csv")).unwrap();
    assert!(
        csv.lines()
            .next()
            .unwrap()
            .ends_with("time_min_ms,time_max_ms")
    );
    // Where the presets sit: their order is stated and each is placed on or off the front.
    assert!(
        stdout.contains("presets: work draft < balanced < final: ")
            && stdout.contains("  final: ")
            && stdout.contains("work front"),
        "{stdout}"
    );
    // The default size is the editor's 800x800 view.
    let help = thicket(&["tradeoff", "--help"]);
    assert!(String::from_utf8_lossy(&help.stdout).contains("[default: 800x800]"));
}

#[test]
fn bench_no_rig_times_the_shown_pose_as_a_rigid_model() {
    // `--no-rig` bakes CesiumMan mid-stride into a rigid model: the static reference for the
    // cost of skinning. Both frames see the figure from the same camera; the baked one has no
    // skinned nodes, so its traversal visits no node twice for skinning and draws splats.
    let project = Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/cesiumman.thicket.json");
    let bench = |extra: &[&str]| {
        let mut args = vec![
            "bench",
            project.to_str().unwrap(),
            "--time",
            "0.5",
            "--frames",
            "1",
            "--size",
            "96x96",
            "--json",
        ];
        args.extend_from_slice(extra);
        let o = thicket(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        json["runs"][0].clone()
    };
    let (skinned, rigid) = (bench(&[]), bench(&["--no-rig"]));
    let splats = |r: &serde_json::Value| r["splats"].as_u64().unwrap();
    assert!(splats(&skinned) > 100, "{skinned}");
    assert!(splats(&rigid) > 100, "{rigid}");
    // Same pose, same view: the two figures cover about the same pixels.
    let ratio = splats(&rigid) as f64 / splats(&skinned) as f64;
    assert!((0.5..2.0).contains(&ratio), "splats {ratio}");
    // A project without a skinned model is refused, not silently timed as it is.
    let dir = tempfile::tempdir().unwrap();
    let o = thicket(&[
        "bench",
        small_project(dir.path()).to_str().unwrap(),
        "--no-rig",
        "--frames",
        "1",
        "--size",
        "16x16",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--no-rig: the project has no skinned model"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

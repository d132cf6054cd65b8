//! `thicket render --gpu` and `thicket bench` through the real binary (GPU runs use whatever
//! adapter is present: lavapipe in CI).

use std::path::{Path, PathBuf};

mod common;
use common::{stderr, stdout, thicket};

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../projects")
        .join(format!("{name}.thicket.json"))
}

#[test]
fn render_gpu_writes_the_same_picture_as_the_cpu() {
    let dir = tempfile::tempdir().unwrap();
    let project = sample("mixed");
    let (gpu_png, cpu_png) = (dir.path().join("gpu.png"), dir.path().join("cpu.png"));
    let o = thicket(&[
        "render",
        "--gpu",
        project.to_str().unwrap(),
        "-o",
        gpu_png.to_str().unwrap(),
        "--size",
        "72x56",
        "--stats",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("wrote") && out.contains("72x56"), "{out}");
    let json: serde_json::Value =
        serde_json::from_str(&out[out.find('{').expect("stats JSON")..]).expect("JSON");
    assert!(json["splats"].as_u64().unwrap() > 0, "{json}");
    assert!(!json["levels"].as_array().unwrap().is_empty());
    let o = thicket(&[
        "render",
        project.to_str().unwrap(),
        "-o",
        cpu_png.to_str().unwrap(),
        "--size",
        "72x56",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let gpu = thicket_core::render::RgbaImage::load_png(&gpu_png).unwrap();
    let cpu = thicket_core::render::RgbaImage::load_png(&cpu_png).unwrap();
    assert_eq!((gpu.width, gpu.height), (72, 56));
    let tol = thicket_core::measure::image::Tolerance::GPU_PARITY;
    let differing = thicket_core::measure::image::count_differing(&gpu, &cpu, tol.channel).unwrap();
    assert!(
        differing as f64 <= tol.max_differing_fraction * f64::from(72 * 56),
        "{differing} pixels differ"
    );
}

#[test]
fn render_gpu_supersample_changes_the_picture_and_matches_the_cpu() {
    // `--quality supersample=3` on the GPU: not the one-sample bytes, and the CPU's 3 × 3
    // picture within the parity tolerance.
    let dir = tempfile::tempdir().unwrap();
    let project = sample("house");
    let render = |name: &str, gpu: bool, k: &str| {
        let png = dir.path().join(name);
        let mut args = vec![
            "render",
            project.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--size",
            "72x56",
            "--quality",
            k,
        ];
        if gpu {
            args.push("--gpu");
        }
        let o = thicket(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        png
    };
    let gpu1 = render("gpu1.png", true, "supersample=1");
    let gpu3 = render("gpu3.png", true, "supersample=3");
    let cpu3 = render("cpu3.png", false, "supersample=3");
    assert_ne!(
        std::fs::read(&gpu1).unwrap(),
        std::fs::read(&gpu3).unwrap(),
        "supersample=3 wrote the one-sample picture"
    );
    let gpu = thicket_core::render::RgbaImage::load_png(&gpu3).unwrap();
    let cpu = thicket_core::render::RgbaImage::load_png(&cpu3).unwrap();
    let one = thicket_core::render::RgbaImage::load_png(&gpu1).unwrap();
    let tol = thicket_core::measure::image::Tolerance::GPU_PARITY;
    let count = |a, b| thicket_core::measure::image::count_differing(a, b, tol.channel).unwrap();
    let (vs_cpu, vs_one) = (count(&gpu, &cpu), count(&gpu, &one));
    assert!(
        vs_cpu as f64 <= tol.max_differing_fraction * f64::from(72 * 56),
        "{vs_cpu} pixels differ from the CPU's 3 × 3 picture"
    );
    // Supersampling moves far more pixels than the tolerance lets differ.
    assert!(
        vs_one as f64 > 10.0 * tol.max_differing_fraction * f64::from(72 * 56),
        "only {vs_one} pixels moved from one sample to 3 × 3"
    );
}

#[test]
fn render_gpu_bad_size_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    let o = thicket(&[
        "render",
        "--gpu",
        sample("house").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "0x10",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("house.thicket.json"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"));
    assert!(!out.exists());
}

fn bench_json(args: &[&str]) -> serde_json::Value {
    let o = thicket(args);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_str(&stdout(&o)).expect("bench prints JSON")
}

#[test]
fn bench_gpu_and_cpu_report_times_and_counters() {
    let project = sample("mixed");
    let p = project.to_str().unwrap();
    let j = bench_json(&[
        "bench",
        "--compare",
        p,
        "--frames",
        "2",
        "--size",
        "48x40",
        "--json",
    ]);
    let runs = j["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 2);
    for (run, name) in runs.iter().zip(["cpu", "gpu"]) {
        assert_eq!(run["renderer"], name);
        assert_eq!(run["frames"], 2);
        assert_eq!(run["width"], 48);
        assert!(run["mean_ms"].as_f64().unwrap() > 0.0, "{run}");
        assert!(run["fps"].as_f64().unwrap() > 0.0, "{run}");
        assert!(run["splats"].as_u64().unwrap() > 0, "{run}");
        let levels = run["levels"].as_array().unwrap();
        assert!(levels.len() > 3, "{run}");
        // Level 0 is the root of each voxel object: one node visited, split.
        assert_eq!(levels[0]["visited"], 1, "{run}");
        assert!(!run["pass_ms"].as_array().unwrap().is_empty(), "{run}");
        // The sample's sun casts: its map's traversal is reported (summed over lights).
        assert!(run["shadow"]["splatted"].as_u64().unwrap() > 0, "{run}");
    }
    assert!(j["cpu_over_gpu_frame_time"].as_f64().unwrap() > 0.0);
    // The splat-bandwidth measurement (64-bit path): bytes and figures, none on the CPU run.
    assert!(runs[0]["splat_bandwidth"].is_null());
    let bw = &runs[1]["splat_bandwidth"];
    if runs[1]["atomic_path"] == "Key64" {
        assert!(bw["total_bytes"].as_u64().unwrap() > 0, "{bw}");
        for key in ["splat_gb_per_s", "copy_gb_per_s", "ratio"] {
            let v = bw[key].as_f64().unwrap();
            assert!(v.is_finite() && v > 0.0, "{key}: {bw}");
        }
    } else {
        assert!(bw.is_null(), "{bw}");
    }
    // Same LOD decisions: the level-by-level splat counts of both renderers are close (the CPU
    // occlusion-culls hidden nodes; the GPU does not).
    let (c, g) = (
        runs[0]["splats"].as_u64().unwrap(),
        runs[1]["splats"].as_u64().unwrap(),
    );
    assert!(g >= c, "GPU {g} < CPU {c}");

    let o = thicket(&["bench", "--gpu", p, "--frames", "1", "--size", "32x32"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(
        text.contains("gpu renderer on") && text.contains("fps"),
        "{text}"
    );
    assert!(
        text.contains("voxels") || text.contains("not available"),
        "{text}"
    );
    assert!(
        text.contains("splat bandwidth") || text.contains("TwoPass32"),
        "{text}"
    );
    assert!(text.contains("shadow maps (all lights)"), "{text}");
}

#[test]
fn bench_orbit_turns_the_camera_and_the_cpu_reuses_its_shadow_maps() {
    let project = sample("mixed");
    let p = project.to_str().unwrap();
    let j = bench_json(&[
        "bench",
        "--compare",
        p,
        "--frames",
        "4",
        "--size",
        "48x40",
        "--orbit",
        "2",
        "--json",
    ]);
    let runs = j["runs"].as_array().expect("runs");
    for run in runs {
        assert_eq!(run["orbit_deg"], 2.0, "{run}");
    }
    // The CPU keeps the sun's map while only the camera turns (the GPU renders its own).
    assert_eq!(runs[0]["renderer"], "cpu");
    let reused = runs[0]["shadow_maps_reused"].as_u64().unwrap();
    assert!((1..=4).contains(&reused), "{}", runs[0]);
    // Its shadow traversal is reported from the frame that drew the map.
    assert!(
        runs[0]["shadow"]["splatted"].as_u64().unwrap() > 0,
        "{}",
        runs[0]
    );
    assert_eq!(runs[1]["shadow_maps_reused"], 0);
    // Without --orbit nothing is cached: every frame renders its map.
    let j = bench_json(&["bench", p, "--frames", "2", "--size", "48x40", "--json"]);
    assert_eq!(j["runs"][0]["shadow_maps_reused"], 0);
    assert!(j["runs"][0]["shadow"]["splatted"].as_u64().unwrap() > 0);
    let o = thicket(&[
        "bench", p, "--frames", "2", "--size", "48x40", "--orbit", "-3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("orbit: yaw -3° a frame; shadow maps reused"),
        "{}",
        stdout(&o)
    );
}

#[test]
fn bench_bad_arguments_fail_cleanly() {
    let p = sample("mixed");
    let o = thicket(&["bench", p.to_str().unwrap(), "--frames", "0"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("--frames"), "{}", stderr(&o));
    let o = thicket(&["bench", "--gpu", "/nonexistent/ghost.thicket.json"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("ghost.thicket.json"), "{}", stderr(&o));
    let o = thicket(&["bench", p.to_str().unwrap(), "--size", "12"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--size"), "{}", stderr(&o));
    let o = thicket(&["bench", p.to_str().unwrap(), "--orbit", "inf"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--orbit"), "{}", stderr(&o));
}

#[test]
fn tradeoff_gpu_measures_gpu_frames_against_the_cpu_reference() {
    // The same sweep on both renderers: the GPU points are measured against the CPU reference
    // image, and the GPU matches the CPU renderer (parity), so each point's error agrees; the
    // work comes from the GPU's own counters.
    let dir = tempfile::tempdir().unwrap();
    let project = sample("mixed");
    let sweep = |gpu: bool| {
        let out = dir.path().join(if gpu { "gpu" } else { "cpu" });
        let mut args = vec![
            "tradeoff",
            project.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--size",
            "64x48",
            "--frames",
            "1",
            "--no-presets",
            "--knob",
            "shadow_pcf_radius=0,2",
            "--knob",
            "lod_pixel_threshold=1,4",
        ];
        if gpu {
            args.push("--gpu");
        }
        let o = thicket(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(
            stdout(&o).contains(if gpu { "GPU renderer" } else { "CPU renderer" }),
            "{}",
            stdout(&o)
        );
        assert!(out.join("tradeoff.png").is_file());
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        assert_eq!(json["renderer"], if gpu { "gpu" } else { "cpu" });
        json["report"]["points"].as_array().unwrap().clone()
    };
    let (cpu, gpu) = (sweep(false), sweep(true));
    assert_eq!(cpu.len(), 4);
    assert_eq!(cpu.len(), gpu.len());
    for (c, g) in cpu.iter().zip(&gpu) {
        assert_eq!(c["setting"]["label"], g["setting"]["label"]);
        let (ce, ge) = (
            c["error"]["rmse"].as_f64().unwrap(),
            g["error"]["rmse"].as_f64().unwrap(),
        );
        assert!(
            (ce - ge).abs() < 2e-3,
            "{}: CPU {ce} GPU {ge}",
            c["setting"]["label"]
        );
        assert!(g["work"].as_u64().unwrap() > 0);
    }
    // The knob moves the GPU's error the way it moves the CPU's: LOD 4 is worse than the base
    // (balanced, LOD 1; a knob value equal to the base is merged into its point).
    let rmse = |label: &str| {
        gpu.iter()
            .find(|p| p["setting"]["label"].as_str().unwrap().starts_with(label))
            .and_then(|p| p["error"]["rmse"].as_f64())
            .unwrap()
    };
    assert!(rmse("lod_pixel_threshold=4") > rmse("base"));
}

#[test]
fn bench_gpu_times_the_skinned_sample_at_a_given_clip_time() {
    // The rigged sample is skinned on the GPU: `--time` poses it (other times give other
    // splat counts), and a time for a document without a rig is refused.
    let project = sample("cesiumman");
    let p = project.to_str().unwrap();
    let splats_at = |t: &str| {
        let j = bench_json(&[
            "bench", "--gpu", p, "--time", t, "--frames", "1", "--size", "48x48", "--json",
        ]);
        let run = &j["runs"][0];
        assert_eq!(run["renderer"], "gpu", "{j}");
        run["splats"].as_u64().expect("splats")
    };
    let (a, b) = (splats_at("0"), splats_at("1.1"));
    assert!(a > 0 && b > 0);
    assert_ne!(a, b, "two poses drew the same number of splats");
    let o = thicket(&[
        "bench",
        "--gpu",
        sample("mixed").to_str().unwrap(),
        "--time",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("no skinned model"), "{}", stderr(&o));
}

//! The shipped draft / balanced / final presets lie on the measured Pareto front of every
//! sample project (a fresh sweep at small size, issue 10).
//!
//! Dominance is judged on (work, RMSE), not on time: work (`measure::work_units`: octree nodes
//! visited for the view and shadow maps, triangles rasterised, KRS distance evaluations, shadow
//! and AO taps) is counted by the renderer and is the same on every run, while wall time on the
//! shared 2-core CI machine moves by tens of percent between runs, so a time-based front would
//! make this test flaky. RMSE is deterministic too (the CPU renderer resolves depth ties by id,
//! whatever the thread order). The `thicket tradeoff` report shows both fronts.
//!
//! 128×128, not smaller: at 64×64 the LOD's geometric error drowns the shading knobs (AO, PCF)
//! and their measured effect is noise.
//!
//! The same sweeps (rendered once for both tests) hold the trade monotonic: every knob moved
//! one step towards quality from balanced must not raise the error on any sample, except the
//! pairs in `RISES`, each with its measured reason (docs/rendering.md "Presets").

use std::sync::OnceLock;

use thicket_core::io::project;
use thicket_core::measure::sweep::WORK_DOMINANCE;
use thicket_core::measure::{KnobValues, SweepReport, SweepSettings, sweep_document};
use thicket_core::quality::{Quality, QualityPreset};
use thicket_tests::samples::SAMPLES;

/// Every knob the presets differ in, one at a time around balanced, each on both sides of the
/// balanced value, its values listed from the cheap end towards quality (the reference's side).
const KNOBS: [&str; 7] = [
    "lod_pixel_threshold=4,2,1,0.5",
    "shadow_pcf_radius=0,1,2",
    "shadow_map_size=512,1024,2048,4096",
    "ao_samples=0,8,16",
    "krs_epsilon_scale=1,0.5,0.25",
    "krs_max_steps=96,160,400",
    "supersample=1,2,3",
];

/// One sweep per sample project at 128×128, shared by the tests of this file (rendered once).
fn sweeps() -> &'static [(&'static str, SweepReport)] {
    static SWEEPS: OnceLock<Vec<(&'static str, SweepReport)>> = OnceLock::new();
    SWEEPS.get_or_init(|| {
        let settings = SweepSettings {
            knobs: KNOBS.map(|k| KnobValues::parse(k).unwrap()).to_vec(),
            repeats: 1,
            ..SweepSettings::default()
        };
        SAMPLES
            .iter()
            .map(|&name| {
                let path = thicket_tests::repo_root()
                    .join("projects")
                    .join(format!("{name}.thicket.json"));
                let doc = project::load(&path).unwrap_or_else(|e| panic!("{e}"));
                let report = sweep_document(&doc, 128, 128, &settings, |_, _, _| {}).unwrap();
                (name, report)
            })
            .collect()
    })
}

#[test]
fn presets_are_on_the_work_error_front_of_every_sample() {
    for (name, report) in sweeps() {
        for preset in [
            QualityPreset::Draft,
            QualityPreset::Balanced,
            QualityPreset::Final,
        ] {
            let p = report.preset_point(preset).unwrap();
            let dominating: Vec<String> = report
                .points
                .iter()
                .filter(|q| {
                    WORK_DOMINANCE
                        .dominates((q.work as f64, q.error.rmse), (p.work as f64, p.error.rmse))
                })
                .map(|q| {
                    format!(
                        "{} (work {}, rmse {:.5})",
                        q.setting.label, q.work, q.error.rmse
                    )
                })
                .collect();
            assert!(
                p.on_work_front && dominating.is_empty(),
                "{name}: preset {preset:?} (work {}, rmse {:.5}) is dominated by {dominating:?}",
                p.work,
                p.error.rmse
            );
        }
        // The presets are ordered: more work buys less error.
        let [d, b, f] = [
            QualityPreset::Draft,
            QualityPreset::Balanced,
            QualityPreset::Final,
        ]
        .map(|p| report.preset_point(p).unwrap());
        assert!(
            d.work < b.work && b.work < f.work,
            "{name}: work {} / {} / {}",
            d.work,
            b.work,
            f.work
        );
        assert!(
            d.error.rmse > b.error.rmse && b.error.rmse > f.error.rmse,
            "{name}: rmse {} / {} / {}",
            d.error.rmse,
            b.error.rmse,
            f.error.rmse
        );
    }
}

/// (sample, knob, why): one-knob moves towards quality that raise the error on that sample,
/// with the measured reason (docs/rendering.md "Presets"). Every other move must not raise it;
/// each listed pair must still rise (a fixed one leaves the list).
const RISES: &[(&str, &str, &str)] = &[
    // The KRS samples' sub-pixel detail (blades, leaves, twigs) is drawn whole at one sample
    // per pixel with balanced's 0.5 px cone epsilon, so the frame without AO is already darker
    // than the 4 × 4 reference (grassland's mean luminance −0.040, tree's −0.013) and AO's
    // darkening (−0.014, −0.001; about what it does at the reference's sampling) adds to it.
    // At the reference's sampling (4 × 4, epsilon 0.125) AO lowers the error on all five KRS
    // samples.
    (
        "tree",
        "ao_samples",
        "AO adds to the one-sample KRS coverage's darkening",
    ),
    (
        "forest",
        "ao_samples",
        "AO adds to the one-sample KRS coverage's darkening",
    ),
    (
        "grassland",
        "ao_samples",
        "AO adds to the one-sample KRS coverage's darkening",
    ),
    (
        "woodland",
        "ao_samples",
        "AO adds to the one-sample KRS coverage's darkening",
    ),
    // +0.00013 (0.3 %) at 0 → 8: AO moves the terrain's mean luminance by −0.0007 and its
    // pixels by 0.003 RMS, a tenth of the frame's geometric error (0.040); not traced further.
    (
        "terrain",
        "ao_samples",
        "AO's effect is a tenth of the LOD error; not traced",
    ),
    // PCF counts texels: 2 texels of balanced's 2048² map blur four times wider than the
    // reference's 2 texels of 8192².
    (
        "mixed",
        "shadow_pcf_radius",
        "PCF radius in texels of a 4x coarser map",
    ),
    // 25 grazing rays run out of steps at 96 (misses); at 160 three of them end within the
    // 0.5 px cone of the coral's silhouette, pixels the reference leaves empty (bloat 276 → 279).
    (
        "coral",
        "krs_max_steps",
        "more steps reach cone-epsilon hits at the silhouette",
    ),
];

#[test]
fn every_knob_moved_towards_quality_does_not_raise_the_error() {
    let mut unexpected = Vec::new();
    let mut seen = Vec::new();
    for (name, report) in sweeps() {
        let base = Quality::default();
        for spec in KNOBS {
            let knob = KnobValues::parse(spec).unwrap();
            // The points of this knob, cheap end first; a knob with no effect at this size was
            // dropped from the report (every value drew the same image: nothing can rise).
            let errors: Vec<(String, f64)> = knob
                .values
                .iter()
                .filter_map(|v| {
                    let mut q = base.clone();
                    q.set(&knob.name, v).unwrap();
                    let p = report.points.iter().find(|p| p.setting.quality == q)?;
                    Some((v.clone(), p.error.rmse))
                })
                .collect();
            for pair in errors.windows(2) {
                let ((from, e0), (to, e1)) = (&pair[0], &pair[1]);
                if e1 > e0 {
                    let line = format!(
                        "{name}: {} {from} → {to}: rmse {e0:.5} → {e1:.5}",
                        knob.name
                    );
                    eprintln!("{line}");
                    if RISES.iter().any(|(s, k, _)| s == name && *k == knob.name) {
                        seen.push((*name, knob.name.clone()));
                    } else {
                        unexpected.push(line);
                    }
                }
            }
        }
    }
    assert!(
        unexpected.is_empty(),
        "error rose towards quality:\n{}",
        unexpected.join("\n")
    );
    let stale: Vec<_> = RISES
        .iter()
        .filter(|(s, k, _)| !seen.iter().any(|(s2, k2)| s2 == s && k2 == k))
        .collect();
    assert!(
        stale.is_empty(),
        "listed rises that no longer rise: {stale:?}"
    );
}

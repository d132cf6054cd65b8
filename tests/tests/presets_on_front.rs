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

use thicket_core::io::project;
use thicket_core::measure::sweep::WORK_DOMINANCE;
use thicket_core::measure::{KnobValues, SweepSettings, sweep_document};
use thicket_core::quality::QualityPreset;
use thicket_tests::samples::SAMPLES;

#[test]
fn presets_are_on_the_work_error_front_of_every_sample() {
    // Every knob the presets differ in, one at a time around balanced, each on both sides of
    // the balanced value.
    let knobs = [
        "lod_pixel_threshold=0.5,1,2,4",
        "shadow_pcf_radius=0,1,2",
        "shadow_map_size=512,1024,4096",
        "ao_samples=0,8,16",
        "krs_epsilon_scale=0.25,0.5,1",
        "krs_max_steps=96,160,400",
        "supersample=1,2,3",
    ]
    .map(|k| KnobValues::parse(k).unwrap());
    let settings = SweepSettings {
        knobs: knobs.to_vec(),
        repeats: 1,
        ..SweepSettings::default()
    };
    for name in SAMPLES {
        let path = thicket_tests::repo_root()
            .join("projects")
            .join(format!("{name}.thicket.json"));
        let doc = project::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let report = sweep_document(&doc, 128, 128, &settings, |_, _, _| {}).unwrap();
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

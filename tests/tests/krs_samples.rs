//! The KRS sample projects (tree, forest, rock on KRS terrain) render like their golden images,
//! the KRS drawn by sphere tracing into the depth buffer it shares with meshes. On a mismatch
//! the helper writes `-actual.png` and `-difference.png` beside the golden; `THICKET_BLESS=1`
//! rewrites the goldens after an intended change.

use thicket_core::io::project;
use thicket_core::measure::image::{Tolerance, assert_images_match};
use thicket_core::render::{RenderRequest, RgbaImage, render_document};
use thicket_core::scene::ObjectKind;
use thicket_tests::samples::SAMPLES;

/// Small enough for a debug build on 2 cores (the 800×800 renders are in docs/images).
const SIZE: u32 = 160;

/// Loads the committed project (so the golden checks what `thicket render` reads), renders it
/// at `SIZE`² with the project's own camera and quality (a smaller shadow map aside) and
/// returns the image, the KRS kernel instances in the document and the covered pixels.
fn render_sample(name: &str) -> (RgbaImage, u128, usize) {
    assert!(SAMPLES.contains(&name), "{name} is a sample");
    let path = thicket_tests::repo_root()
        .join("projects")
        .join(format!("{name}.thicket.json"));
    let doc = project::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let instances = doc
        .objects
        .iter()
        .map(|o| match &o.kind {
            ObjectKind::Krs(k) => k.instance_count(),
            _ => 0,
        })
        .sum();
    let mut quality = doc.quality.clone();
    quality.shadow_map_size = 512;
    let (img, fb, stats) = render_document(
        &doc,
        &RenderRequest {
            quality,
            ..RenderRequest::new(SIZE, SIZE)
        },
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"));
    eprintln!(
        "{name}: {} KRS hits of {} rays, {} steps, {} covered pixels",
        stats.krs.hits,
        stats.krs.rays,
        stats.krs.steps,
        fb.covered_pixels()
    );
    // The KRS is in view: a good share of the frame is KRS, not only the ground mesh.
    assert!(
        stats.krs.hits as usize > (SIZE * SIZE / 20) as usize,
        "{name}: {:?}",
        stats.krs
    );
    assert!(
        fb.normal.iter().all(|n| n.is_finite()),
        "{name}: NaN normal"
    );
    (img, instances, fb.covered_pixels())
}

fn golden(name: &str) -> std::path::PathBuf {
    thicket_tests::repo_root()
        .join("tests/golden")
        .join(format!("krs_{name}.png"))
}

#[test]
fn tree_sample_matches_its_golden() {
    let (img, instances, _) = render_sample("tree");
    // The default tree preset: 255 kernel instances (branches and leaves).
    assert_eq!(instances, 255);
    assert_images_match(&img, golden("tree"), Tolerance::CPU_GOLDEN);
}

#[test]
fn forest_sample_matches_its_golden() {
    let (img, instances, covered) = render_sample("forest");
    assert!(instances >= 1 << 24, "{instances}");
    // Ground and trees up to the horizon: the sky is only the top of the frame.
    assert!(covered > (SIZE * SIZE / 2) as usize, "{covered}");
    assert_images_match(&img, golden("forest"), Tolerance::CPU_GOLDEN);
}

#[test]
fn rock_sample_matches_its_golden() {
    let (img, _, covered) = render_sample("rock");
    assert!(covered > (SIZE * SIZE / 2) as usize, "{covered}");
    assert_images_match(&img, golden("rock"), Tolerance::CPU_GOLDEN);
}

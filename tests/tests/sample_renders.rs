//! Golden images of the sample projects (`projects/*.thicket.json`) from the CPU reference
//! renderer, at 256×256 with the project's own camera and default quality. On a mismatch the
//! helper writes `-actual.png` and `-difference.png` beside the golden; `THICKET_BLESS=1`
//! rewrites the goldens after an intended change.

use thicket_core::io::project;
use thicket_core::measure::image::{Tolerance, assert_images_match};
use thicket_core::render::{View, render_document};
use thicket_tests::samples::SAMPLES;

fn render_sample(name: &str) {
    let root = thicket_tests::repo_root();
    let doc = project::load(&root.join("projects").join(format!("{name}.thicket.json")))
        .unwrap_or_else(|e| panic!("{e}"));
    let (img, fb, stats) =
        render_document(&doc, &View::new(256, 256)).unwrap_or_else(|e| panic!("{name}: {e}"));
    // Not a blank frame: a good part of the image shows the scene (mixed covers about 17 %).
    assert!(
        fb.covered_pixels() > 256 * 256 / 10,
        "{name}: only {} pixels covered ({stats:?})",
        fb.covered_pixels()
    );
    assert_images_match(
        &img,
        root.join("tests/golden").join(format!("sample_{name}.png")),
        Tolerance::CPU_GOLDEN,
    );
}

#[test]
fn golden_house() {
    assert!(SAMPLES.contains(&"house"));
    render_sample("house");
}

#[test]
fn golden_mixed() {
    assert!(SAMPLES.contains(&"mixed"));
    render_sample("mixed");
}

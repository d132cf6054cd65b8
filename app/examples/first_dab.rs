//! Measures the first sculpt dab after opening a project whose voxel model has a
//! detail-enhancement link (issue #8, "a brush dab is visible in the next frame"), both ways:
//!
//! - before: the document is installed as it was read, and the dab builds the model's
//!   enhancer in full on the calling (UI) thread;
//! - after: the open job builds the enhancers on its worker thread
//!   ([`PreparedDocument::new`]), and the dab only updates incrementally.
//!
//! `cargo run -p thicket --example first_dab -- projects/terrain.thicket.json [REPEATS]`
//! prints the times (milliseconds, median of REPEATS, default 3) and the rebuild counts.

use std::time::Instant;

use glam::Vec3;
use thicket::editor::{Editor, PreparedDocument};
use thicket_core::scene::ObjectKind;
use thicket_core::sculpt::{Brush, BrushOp};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .ok_or_else(|| anyhow::anyhow!("usage: first_dab PROJECT.thicket.json [REPEATS]"))?;
    let repeats: usize = args.next().map_or(Ok(3), |r| r.parse())?;
    let doc = thicket::files::load_document(std::path::Path::new(&path))?;
    let link = doc
        .enhancements
        .first()
        .cloned()
        .ok_or_else(|| anyhow::anyhow!("{path}: no enhancement link"))?;
    let Some(ObjectKind::Voxels(coarse)) = doc
        .objects
        .iter()
        .find(|o| o.id == link.source)
        .map(|o| &o.kind)
    else {
        anyhow::bail!("{path}: the linked source is not a voxel model");
    };
    // A dab that surely changes voxels: remove around the highest solid voxel.
    let top = coarse
        .svo
        .leaves()
        .into_iter()
        .map(|(p, _)| p)
        .max_by_key(|p| (p.y, std::cmp::Reverse((p.x, p.z))))
        .ok_or_else(|| anyhow::anyhow!("{path}: the linked model is empty"))?;
    let center = top.as_vec3() + 0.5;
    let brush = Brush {
        op: BrushOp::Remove,
        radius: 2.0,
        ..Brush::default()
    };
    let (mut before, mut prepare, mut after) = (Vec::new(), Vec::new(), Vec::new());
    let (mut rebuilds_before, mut rebuilds_after) = (0, 0);
    for _ in 0..repeats.max(1) {
        let mut ed = Editor::default();
        ed.replace_document(doc.clone(), None);
        ed.begin_stroke();
        let t = Instant::now();
        ed.sculpt_dab(link.source, &brush, center, Vec3::ZERO)?;
        before.push(t.elapsed().as_secs_f64() * 1e3);
        rebuilds_before = ed.enhancer_rebuilds();

        let t = Instant::now();
        let prepared = PreparedDocument::new(doc.clone(), None);
        prepare.push(t.elapsed().as_secs_f64() * 1e3);
        let mut ed = Editor::default();
        ed.replace_document_prepared(prepared, None);
        ed.begin_stroke();
        let t = Instant::now();
        ed.sculpt_dab(link.source, &brush, center, Vec3::ZERO)?;
        after.push(t.elapsed().as_secs_f64() * 1e3);
        rebuilds_after = ed.enhancer_rebuilds();
    }
    println!(
        "{path}: first dab (remove, radius 2, at voxel {top}) on the UI thread, median of {} runs",
        repeats.max(1)
    );
    println!(
        "  before (enhancer built by the dab): {:.1} ms, {rebuilds_before} full build(s)",
        median(before)
    );
    println!(
        "  after (built by the open job's worker): {:.1} ms, {rebuilds_after} full build(s); \
         the worker's extra open time {:.1} ms",
        median(after),
        median(prepare)
    );
    Ok(())
}

//! How much of an orbiting frame the previous frame already holds: renders a project at its
//! camera and turned by a yaw step, reprojects every surface pixel of the first frame into
//! the second (its world point through the new camera, nearest point per pixel) and counts
//! the second frame's pixels whose surface the first frame saw (same object, view depth
//! within 1 % or one pixel footprint). It measures the design that would reuse the image
//! rather than the cut (BENCHMARKS.md "What a kept cut could save while orbiting"): the
//! pixels left over are what such a frame must still splat and shade.
//!
//! `cargo run --release -p thicket-core --example reprojection_reuse -- PROJECT [SIZE]
//! [YAW_STEP_DEG]` (defaults 800 and 2).

use thicket_core::render::{Camera, View, render_document};

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next() else {
        eprintln!("usage: reprojection_reuse PROJECT [SIZE] [YAW_STEP_DEG]");
        std::process::exit(2);
    };
    let size: u32 = args
        .next()
        .map_or(800, |s| s.parse().expect("a size in pixels"));
    let step: f32 = args
        .next()
        .map_or(2.0, |s| s.parse().expect("a yaw step in degrees"));
    let doc = match thicket_core::io::project::load(std::path::Path::new(&path)) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("{path}: {e}");
            std::process::exit(1);
        }
    };
    let mut turned = doc.camera;
    turned.yaw_deg += step;
    let frame = |camera| {
        let view = View {
            width: size,
            height: size,
            camera: Some(camera),
            quality: doc.quality.clone(),
        };
        render_document(&doc, &view).expect("a frame")
    };
    let (_, a, _) = frame(doc.camera);
    let (_, b, _) = frame(turned);
    let cam_a = Camera::from_orbit(&doc.camera, size, size);
    let cam_b = Camera::from_orbit(&turned, size, size);
    let n = (size * size) as usize;
    // Nearest reprojected sample per pixel of the second frame: (view depth, object).
    let mut held: Vec<Option<(f32, u32)>> = vec![None; n];
    for i in 0..n {
        if a.ids[i].object == 0 {
            continue;
        }
        let (x, y) = (
            (i as u32 % size) as f32 + 0.5,
            (i as u32 / size) as f32 + 0.5,
        );
        let world = cam_a.unproject(x, y, a.depth[i]);
        let s = cam_b.world_to_screen(world);
        if !(s.x >= 0.0 && s.y >= 0.0 && s.x < size as f32 && s.y < size as f32) {
            continue;
        }
        let j = s.y as usize * size as usize + s.x as usize;
        let d = cam_b.view_depth(s.z);
        if held[j].is_none_or(|(h, _)| d < h) {
            held[j] = Some((d, a.ids[i].object));
        }
    }
    let (mut surface, mut reused, mut missing, mut other) = (0u64, 0u64, 0u64, 0u64);
    for ((id, &depth), held) in b.ids.iter().zip(&b.depth).zip(&held) {
        if id.object == 0 {
            continue;
        }
        surface += 1;
        let d = cam_b.view_depth(depth);
        match *held {
            None => missing += 1,
            Some((h, object)) => {
                let tolerance = (0.01 * d).max(cam_b.pixel_world_size(d));
                if object == id.object && (h - d).abs() <= tolerance {
                    reused += 1;
                } else {
                    other += 1;
                }
            }
        }
    }
    let pct = |k: u64| 100.0 * k as f64 / surface.max(1) as f64;
    println!(
        "{path} at {size}x{size}, yaw +{step} deg: {surface} surface pixels; {reused} ({:.1} %) \
         hold the surface the previous frame saw there; {missing} ({:.1} %) got no \
         reprojected sample; {other} ({:.1} %) got another surface",
        pct(reused),
        pct(missing),
        pct(other)
    );
}

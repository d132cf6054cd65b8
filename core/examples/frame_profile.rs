//! Renders the render bench's near 3M-voxel 800×800 frame `N` times (default 10) at a preset,
//! printing each frame's image hash, counts and stage times: a fixed workload for profilers
//! (`perf record`, `valgrind --tool=callgrind`) without criterion's own work in the profile,
//! and a check that a speed change kept the image (the hash). With `orbit`, the
//! camera turns 2° a frame and shadow maps come from a [`ShadowCache`], as in the editor's CPU
//! preview; with `edit`, the content key changes every frame, as while sculpting there. With
//! `FRAME_PROFILE_LEVELS` set, the first frame's per-level counts are printed too.
//!
//! `cargo run --release -p thicket-core --example frame_profile -- [draft|balanced|final] [N]
//! [orbit|edit]`

use thicket_core::render::scenes::{sphere_shell, voxel_object};
use thicket_core::render::{
    Quality, QualityPreset, RenderRequest, ShadowCache, render_document, render_document_cached,
};
use thicket_core::scene::{Document, OrbitCamera};

fn main() {
    let mut args = std::env::args().skip(1);
    let preset = match args.next().as_deref() {
        Some("draft") => QualityPreset::Draft,
        Some("final") => QualityPreset::Final,
        Some("balanced") | None => QualityPreset::Balanced,
        Some(other) => {
            eprintln!("unknown preset {other:?}: use draft, balanced or final");
            std::process::exit(2);
        }
    };
    let frames: usize = match args.next().map(|s| s.parse()) {
        None => 10,
        Some(Ok(n)) => n,
        Some(Err(e)) => {
            eprintln!("frame count: {e}");
            std::process::exit(2);
        }
    };
    // The bench's ~3M-voxel sphere shell (radius 0.36 of a depth-11 octree) in its near view.
    let svo = match sphere_shell(11, 0.36) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let mut doc = Document::default();
    doc.add("Sphere", voxel_object(svo, 1.0 / 0.36));
    // `edit`: the content key changes every frame, as while sculpting in the CPU preview.
    let (orbit, edit) = match args.next().as_deref() {
        None => (false, false),
        Some("orbit") => (true, false),
        Some("edit") => (false, true),
        Some(other) => {
            eprintln!("unknown mode {other:?}: the third argument can be orbit or edit");
            std::process::exit(2);
        }
    };
    let mut req = RenderRequest {
        width: 800,
        height: 800,
        camera: Some(OrbitCamera {
            distance: 4.0,
            ..OrbitCamera::default()
        }),
        quality: Quality::preset(preset),
    };
    let mut cache = ShadowCache::new();
    for i in 0..frames {
        let result = if orbit {
            if let Some(c) = req.camera.as_mut() {
                c.yaw_deg += 2.0;
            }
            render_document_cached(&doc, &req, &mut cache, 0)
        } else if edit {
            render_document_cached(&doc, &req, &mut cache, i as u64)
        } else {
            render_document(&doc, &req)
        };
        match result {
            Ok((img, fb, st)) => {
                if std::env::var_os("FRAME_PROFILE_LEVELS").is_some() && i == 0 {
                    for (name, levels) in [("view", &st.levels), ("shadow", &st.shadow_levels)] {
                        for (l, s) in levels.iter().enumerate() {
                            eprintln!("{name} level {l}: {s:?}");
                        }
                    }
                }
                eprintln!(
                    "frame {i}: image hash {:016x}, {} covered px, {} visited, {} splats (view); {} visited, {} splats \
                 (shadow, {} maps reused); {:?}",
                    image_hash(&img.pixels),
                    fb.covered_pixels(),
                    st.nodes_visited(),
                    st.splats(),
                    st.shadow_levels.iter().map(|l| l.visited).sum::<u64>(),
                    st.shadow_levels.iter().map(|l| l.splatted).sum::<u64>(),
                    st.shadow_maps_reused,
                    st.times
                );
            }
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        }
    }
}

/// FNV-1a of the image bytes: equal hashes before and after a change show it kept the image.
fn image_hash(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

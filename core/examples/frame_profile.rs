//! Renders the render bench's near 3M-voxel 800×800 frame `N` times (default 10) at a preset,
//! printing each frame's image hash, counts and stage times: a fixed workload for profilers
//! (`perf record`, `valgrind --tool=callgrind`) without criterion's own work in the profile,
//! and a check that a speed change kept the image (the hash). With `orbit`, the
//! camera turns 2° a frame and shadow maps come from a [`ShadowCache`], as in the editor's CPU
//! preview; with `edit`, the content key changes every frame, as while sculpting there. With
//! `FRAME_PROFILE_LEVELS` set, the first frame's per-level counts are printed too. With
//! `FRAME_PROFILE_REUSE` set, every frame is drawn by one [`Renderer`] (its buffers kept, as
//! `thicket bench` and the editor's preview do) instead of the free functions' fresh buffers:
//! run it under `/usr/bin/time` to compare page faults and kernel time.
//!
//! `cargo run --release -p thicket-core --example frame_profile -- [draft|balanced|final] [N]
//! [orbit|edit]`

use thicket_core::quality::{Quality, QualityPreset};
use thicket_core::render::scenes::{sphere_shell, voxel_object};
use thicket_core::render::{
    FrameBuffers, FrameStats, RenderError, Renderer, RgbaImage, ShadowCache, View, render_document,
    render_document_cached,
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
    let mut req = View {
        width: 800,
        height: 800,
        camera: Some(OrbitCamera {
            distance: 4.0,
            ..OrbitCamera::default()
        }),
        quality: Quality::preset(preset),
    };
    let mut cache = ShadowCache::new();
    let mut renderer = std::env::var_os("FRAME_PROFILE_REUSE").map(|_| Renderer::new());
    for i in 0..frames {
        if orbit && let Some(c) = req.camera.as_mut() {
            c.yaw_deg += 2.0;
        }
        let key = if edit {
            Some(i as u64)
        } else {
            orbit.then_some(0)
        };
        let result = draw(&doc, &req, key, &mut cache, renderer.as_mut());
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

/// One frame, with a shadow cache when there is a content key, by `renderer` when there is one
/// (its frame borrowed) or the free functions.
fn draw<'a>(
    doc: &Document,
    req: &View,
    key: Option<u64>,
    cache: &mut ShadowCache,
    renderer: Option<&'a mut Renderer>,
) -> Result<Drawn<'a>, RenderError> {
    match (renderer, key) {
        (Some(r), Some(k)) => r.render_document_cached(doc, req, cache, k).map(borrowed),
        (Some(r), None) => r.render_document(doc, req).map(borrowed),
        (None, Some(k)) => render_document_cached(doc, req, cache, k).map(owned),
        (None, None) => render_document(doc, req).map(owned),
    }
}

type Out<'a, T> = std::borrow::Cow<'a, T>;
/// A frame's image, G-buffer and counters, owned or borrowed from a renderer.
type Drawn<'a> = (
    Out<'a, RgbaImage>,
    Out<'a, FrameBuffers>,
    Out<'a, FrameStats>,
);

fn borrowed(f: thicket_core::render::Frame<'_>) -> Drawn<'_> {
    (
        Out::Borrowed(f.image),
        Out::Borrowed(f.buffers),
        Out::Borrowed(f.stats),
    )
}

fn owned<'a>((img, fb, st): (RgbaImage, FrameBuffers, FrameStats)) -> Drawn<'a> {
    (Out::Owned(img), Out::Owned(fb), Out::Owned(st))
}

/// FNV-1a of the image bytes: equal hashes before and after a change show it kept the image.
fn image_hash(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

//! The kept-state [`Renderer`]: frames equal the free functions' bit for bit whatever it drew
//! before, and a frame of a size and scene it has seen makes no heap allocation.

use super::scenes::mixed_document;
use super::*;
use crate::io::fuzz::heap_allocations;
use crate::quality::QualityPreset;
use crate::scene::OrbitCamera;

fn house() -> Document {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/house.thicket.json");
    crate::io::project::load(&path).expect("the house sample")
}

/// `doc`'s camera turned by `yaw_deg`, at a size, with a quality.
fn orbit(
    doc: &Document,
    yaw_deg: f32,
    width: u32,
    height: u32,
    quality: &Quality,
) -> RenderRequest {
    RenderRequest {
        width,
        height,
        camera: Some(OrbitCamera {
            yaw_deg: doc.camera.yaw_deg + yaw_deg,
            ..doc.camera
        }),
        quality: quality.clone(),
    }
}

/// A one-thread pool: the counting allocator counts per thread, and rayon runs the work of
/// `install` on the pool's thread, so every allocation of the frame is seen.
fn one_thread_pool() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool")
}

/// A renderer reused over an orbit, across sizes (larger, smaller, larger again), with and
/// without a shadow cache, draws every frame exactly as a fresh render of the same request:
/// image, G-buffer and counters (times aside).
#[test]
fn a_reused_renderer_draws_every_frame_as_a_fresh_render() {
    let house = house();
    let mixed = mixed_document(7).expect("mixed scene");
    let final_q = Quality::preset(QualityPreset::Final);
    let mut r = Renderer::new();
    let mut cached = Renderer::new();
    let mut cache = ShadowCache::new();
    let mut fresh_cache = ShadowCache::new();
    let mut frames = 0;
    for (content_key, (doc, quality)) in [
        (&house, house.quality.clone()),
        (&mixed, Quality::default()),
        (&mixed, final_q),
    ]
    .into_iter()
    .enumerate()
    {
        let content_key = content_key as u64;
        for (step, (w, h)) in [(96, 80), (160, 120), (64, 48), (160, 120)]
            .into_iter()
            .enumerate()
        {
            let req = orbit(doc, 7.0 * step as f32, w, h, &quality);
            let (img, fb, stats) = render_document(doc, &req).expect("fresh frame");
            let f = r.render_document(doc, &req).expect("reused frame");
            assert!(*f.image == img, "image differs at step {step} ({w}x{h})");
            assert!(*f.buffers == fb, "G-buffer differs at step {step}");
            let same_counts = FrameStats {
                times: stats.times,
                ..f.stats.clone()
            };
            assert_eq!(same_counts, stats, "counters differ at step {step}");
            // The shadow cache's maps in place: the same frames as a fresh renderer with its
            // own cache that went through the same requests.
            let (img, fb, _) = render_document_cached(doc, &req, &mut fresh_cache, content_key)
                .expect("fresh cached");
            let f = cached
                .render_document_cached(doc, &req, &mut cache, content_key)
                .expect("reused cached");
            assert!(*f.image == img, "cached image differs at step {step}");
            assert!(*f.buffers == fb, "cached G-buffer differs at step {step}");
            frames += 1;
        }
    }
    assert_eq!(frames, 12);
}

/// Once a renderer has drawn an orbit, drawing it again allocates nothing: no buffer, queue,
/// table, shadow map or list of the frame is made afresh (the house: rigid voxels, a shadow
/// casting sun; the mixed scene adds meshes). The free function, which makes its buffers per
/// frame, is counted too, so the test can tell.
#[test]
fn a_steady_state_orbit_frame_makes_no_heap_allocation() {
    let house = house();
    let mixed = mixed_document(7).expect("mixed scene");
    let pool = one_thread_pool();
    for (name, doc, quality) in [
        ("house", &house, house.quality.clone()),
        ("mixed", &mixed, Quality::default()),
        ("mixed final", &mixed, Quality::preset(QualityPreset::Final)),
    ] {
        let reqs: Vec<RenderRequest> = (0..4)
            .map(|step| orbit(doc, 2.0 * step as f32, 200, 150, &quality))
            .collect();
        pool.install(|| {
            let mut r = Renderer::new();
            let mut cached = Renderer::new();
            let mut cache = ShadowCache::new();
            for lap in 0..2 {
                for (step, req) in reqs.iter().enumerate() {
                    let (splats, plain) =
                        heap_allocations(|| r.render_document(doc, req).map(|f| f.stats.splats()));
                    let (reused, with_cache) = heap_allocations(|| {
                        cached
                            .render_document_cached(doc, req, &mut cache, 1)
                            .map(|f| f.stats.shadow_maps_reused)
                    });
                    assert!(splats.expect("frame") > 0);
                    reused.expect("cached frame");
                    if lap == 1 {
                        assert_eq!(plain, 0, "{name}: step {step} of the second lap allocated");
                        assert_eq!(
                            with_cache, 0,
                            "{name}: cached step {step} of the second lap allocated"
                        );
                    }
                }
            }
            let (frame, fresh) = heap_allocations(|| render_document(doc, &reqs[0]).map(|_| ()));
            frame.expect("fresh frame");
            assert!(
                fresh > 10,
                "{name}: a fresh frame made only {fresh} allocations"
            );
        });
    }
}

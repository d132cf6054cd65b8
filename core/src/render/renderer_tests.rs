//! The kept-state [`Renderer`]: frames equal the free functions' bit for bit whatever it drew
//! before, and a frame of a size and scene it has seen makes no heap allocation.

use super::scenes::mixed_document;
use super::*;
use crate::io::fuzz::heap_allocations;
use crate::quality::QualityPreset;
use crate::scene::OrbitCamera;

/// A sample project of the repository by name.
fn sample(name: &str) -> Document {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(format!("../projects/{name}.thicket.json"));
    crate::io::project::load(&path).expect("a sample project")
}

fn house() -> Document {
    sample("house")
}

/// `doc`'s camera turned by `yaw_deg`, at a size, with a quality.
fn orbit(doc: &Document, yaw_deg: f32, width: u32, height: u32, quality: &Quality) -> View {
    View {
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
    // KRS: the prepared scene is kept while the document's KRS objects are unchanged, so the
    // tree is followed by itself moved and by itself with a mirror moved, and the forest with
    // its capsules' ends at z = 0.0 by the same with z = -0.0 (equal under `==`, yet the
    // bark's texture frame turns with the sign).
    let (tree, forest, cesium) = (sample("tree"), sample("forest"), sample("cesiumman"));
    let edit_krs =
        |base: &Document, edit: &dyn Fn(&mut crate::scene::Object, &mut crate::krs::KrsObject)| {
            let mut doc = base.clone();
            for o in &mut doc.objects {
                let mut kind = std::mem::replace(
                    &mut o.kind,
                    crate::scene::ObjectKind::Mesh(Default::default()),
                );
                if let crate::scene::ObjectKind::Krs(k) = &mut kind {
                    edit(o, k);
                }
                o.kind = kind;
            }
            doc
        };
    let moved = edit_krs(&tree, &|o, _| o.transform.translation.x += 0.4);
    let bent = edit_krs(&tree, &|_, k| k.mirrors[0].offset += 0.05);
    let capsules_at = |z: f32| {
        edit_krs(&forest, &|_, k| {
            for kernel in &mut k.kernels {
                if let crate::krs::Kernel::Capsule(c) = kernel {
                    c.start.z = 0.0;
                    c.end.z = z;
                }
            }
        })
    };
    let (plus_zero, minus_zero) = (capsules_at(0.0), capsules_at(-0.0));
    let probe = orbit(&forest, 0.0, 160, 120, &forest.quality);
    assert_ne!(
        render_document(&plus_zero, &probe).expect("+0").0,
        render_document(&minus_zero, &probe).expect("-0").0,
        "the sign of a zero no longer shows: this case tests nothing"
    );
    let mut frames = 0;
    for (content_key, (doc, quality)) in [
        (&house, house.quality.clone()),
        (&mixed, Quality::default()),
        (&mixed, final_q),
        (&tree, tree.quality.clone()),
        (&moved, tree.quality.clone()),
        (&bent, tree.quality.clone()),
        (&forest, forest.quality.clone()),
        (&plus_zero, forest.quality.clone()),
        (&minus_zero, forest.quality.clone()),
        (&cesium, cesium.quality.clone()),
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
    assert_eq!(frames, 40);
}

/// Once a renderer has drawn an orbit, drawing it again allocates nothing: no buffer, queue,
/// table, shadow map or list of the frame is made afresh (the house: rigid voxels, a shadow
/// casting sun; the mixed scene adds meshes). The free function, which makes its buffers per
/// frame, is counted too, so the test can tell.
#[test]
fn a_steady_state_orbit_frame_makes_no_heap_allocation() {
    let house = house();
    let mixed = mixed_document(7).expect("mixed scene");
    // A skinned character, a KRS tree with its tree builder, and a KRS forest on KRS ground:
    // their poses, prepared KRS scenes and per-pixel KRS records are kept too.
    let (cesium, tree, forest) = (sample("cesiumman"), sample("tree"), sample("forest"));
    let pool = one_thread_pool();
    for (name, doc, quality) in [
        ("house", &house, house.quality.clone()),
        ("mixed", &mixed, Quality::default()),
        ("mixed final", &mixed, Quality::preset(QualityPreset::Final)),
        ("cesiumman", &cesium, cesium.quality.clone()),
        ("tree", &tree, tree.quality.clone()),
        ("forest", &forest, forest.quality.clone()),
    ] {
        let reqs: Vec<View> = (0..4)
            .map(|step| orbit(doc, 2.0 * step as f32, 200, 150, &quality))
            .collect();
        pool.install(|| {
            let mut r = Renderer::new();
            let mut cached = Renderer::new();
            let mut cache = ShadowCache::new();
            for lap in 0..2 {
                for (step, req) in reqs.iter().enumerate() {
                    let (covered, plain) = heap_allocations(|| {
                        r.render_document(doc, req).map(|f| f.stats.covered_pixels)
                    });
                    let (reused, with_cache) = heap_allocations(|| {
                        cached
                            .render_document_cached(doc, req, &mut cache, 1)
                            .map(|f| f.stats.shadow_maps_reused)
                    });
                    assert!(covered.expect("frame") > 1000, "{name}: drew nothing");
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

#[test]
fn a_playback_frame_of_a_skinned_character_makes_no_heap_allocation() {
    // Each step is another instant of the clip: a new pose, sampled into kept buffers.
    let docs: Vec<Document> = (0..4)
        .map(|step| {
            let mut doc = sample("cesiumman");
            for o in &mut doc.objects {
                if let crate::scene::ObjectKind::Voxels(v) = &mut o.kind
                    && let Some(rig) = &mut v.rig
                {
                    rig.playback.time_secs = 0.2 * step as f32;
                }
            }
            doc
        })
        .collect();
    let pool = one_thread_pool();
    pool.install(|| {
        let mut r = Renderer::new();
        let mut last = None;
        for lap in 0..2 {
            for (step, doc) in docs.iter().enumerate() {
                let req = orbit(doc, 0.0, 200, 150, &doc.quality);
                let (hash, n) = heap_allocations(|| {
                    r.render_document(doc, &req)
                        .map(|f| f.image.pixels.iter().map(|&b| u64::from(b)).sum::<u64>())
                });
                let hash = hash.expect("frame");
                if lap == 1 {
                    assert_eq!(n, 0, "step {step} of the second lap allocated");
                }
                // The poses differ: so do the images.
                if step > 0 {
                    assert_ne!(Some(hash), last, "step {step} drew the previous pose");
                }
                last = Some(hash);
            }
        }
    });
}

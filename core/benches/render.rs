//! CPU reference renderer benchmarks (issue 3): frame time at 800×800 for a ~3M-voxel surface
//! model with shading and shadows; resolution-bound LOD (depth 9 vs depth 12, same view); LOD
//! vs splatting every leaf.
//!
//! `cargo bench -p thicket-core --bench render -- --warm-up-time 1 --measurement-time 5`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use thicket_core::quality::{Quality, QualityPreset};
use thicket_core::render::scenes::{sphere_shell, voxel_object};
use thicket_core::render::{Renderer, ShadowCache, View, render_document, render_document_cached};
use thicket_core::scene::{Document, OrbitCamera};

/// A sphere shell of world radius 1 whose voxel radius is `fraction` of half the octree.
fn sphere_doc(depth: u8, fraction: f32) -> Document {
    let svo = sphere_shell(depth, fraction).expect("depth in range");
    let mut doc = Document::default();
    doc.add("Sphere", voxel_object(svo, 1.0 / fraction));
    doc
}

fn request(distance: f32, quality: Quality) -> View {
    View {
        width: 800,
        height: 800,
        camera: Some(OrbitCamera {
            distance,
            ..OrbitCamera::default()
        }),
        quality,
    }
}

fn report(name: &str, doc: &Document, req: &View) {
    if let Ok((_, fb, st)) = render_document(doc, req) {
        let leaves = doc
            .objects
            .iter()
            .map(|o| match &o.kind {
                thicket_core::scene::ObjectKind::Voxels(v) => v.svo.leaf_count(),
                thicket_core::scene::ObjectKind::Mesh(_)
                | thicket_core::scene::ObjectKind::Krs(_) => 0,
            })
            .sum::<u64>();
        eprintln!(
            "{name}: {leaves} voxels, {} covered px, {} visited, {} splats, {} occlusion-culled, \
             times {:?}",
            fb.covered_pixels(),
            st.nodes_visited(),
            st.splats(),
            st.totals().occlusion_culled,
            st.times
        );
        for (name, levels) in [("view", &st.levels), ("shadow", &st.shadow_levels)] {
            for (l, s) in levels.iter().enumerate().filter(|(_, s)| s.visited > 0) {
                eprintln!(
                    "  {name} level {l:2}: {:8} visited {:8} split {:8} splatted {:8} occluded \
                     {:8} frustum",
                    s.visited, s.split, s.splatted, s.occlusion_culled, s.frustum_culled
                );
            }
        }
    }
}

fn benches(c: &mut Criterion) {
    // ~3M voxels: radius 0.36 × 1024 ≈ 369 voxels in a depth-11 octree.
    let big = sphere_doc(11, 0.36);
    // Near view: the sphere spans about 480 px; far view: about 75 px.
    let near = 4.0;
    let far = 26.0;
    let shaded = Quality::default();
    let no_shadows = Quality {
        shadows: false,
        ..Quality::default()
    };

    // Balanced ships AO off (measured: docs/rendering.md "Presets"); final's 16 samples.
    let ao16 = Quality {
        ao_samples: 16,
        ..Quality::default()
    };
    let mut g = c.benchmark_group("frame_800");
    g.sample_size(10);
    // The draft preset (LOD 2 px, 1024 shadow map, no PCF): the editor's fast setting.
    let draft_preset = Quality::preset(QualityPreset::Draft);
    for (name, q) in [
        ("shadows", &shaded),
        ("draft", &draft_preset),
        ("shadows_ao16", &ao16),
        ("no_shadows", &no_shadows),
    ] {
        let req = request(near, q.clone());
        report(&format!("frame_800/{name}"), &big, &req);
        g.bench_function(name, |b| b.iter(|| black_box(render_document(&big, &req))));
    }
    let draft = Quality {
        shadow_map_size: 1024,
        ..Quality::default()
    };
    let req = request(near, draft);
    report("frame_800/shadows_1024", &big, &req);
    g.bench_function("shadows_1024", |b| {
        b.iter(|| black_box(render_document(&big, &req)));
    });
    // Orbiting as the editor's CPU preview does: the camera turns 2° a frame around the model,
    // without and with a shadow cache (its maps serve while only the camera moves).
    for (name, q) in [("balanced", &shaded), ("draft", &draft_preset)] {
        let orbit = |yaw: f32| View {
            camera: Some(OrbitCamera {
                distance: near,
                yaw_deg: yaw,
                ..OrbitCamera::default()
            }),
            ..request(near, q.clone())
        };
        let mut yaw = 0.0;
        g.bench_function(format!("orbit_{name}"), |b| {
            b.iter(|| {
                yaw += 2.0;
                black_box(render_document(&big, &orbit(yaw)))
            });
        });
        let mut cache = ShadowCache::new();
        let (mut frames, mut reused) = (0u32, 0u32);
        g.bench_function(format!("orbit_{name}_shadow_cache"), |b| {
            b.iter(|| {
                yaw += 2.0;
                let r = render_document_cached(&big, &orbit(yaw), &mut cache, 0);
                if let Ok((_, _, st)) = &r {
                    frames += 1;
                    reused += st.shadow_maps_reused;
                }
                black_box(r)
            });
        });
        eprintln!(
            "frame_800/orbit_{name}_shadow_cache: {reused} of {frames} frames reused the map"
        );
    }
    g.finish();

    // Resolution bound: the same shape (radius 0.18 of the octree) at depth 9 (≈46k voxels) and
    // depth 12 (≈3M), far enough that depth-9 voxels are below a pixel.
    let mut g = c.benchmark_group("resolution_bound");
    g.sample_size(10);
    for depth in [9u8, 12] {
        let doc = sphere_doc(depth, 0.18);
        let req = request(far, shaded.clone());
        report(&format!("resolution_bound/depth{depth}"), &doc, &req);
        g.bench_function(format!("depth{depth}"), |b| {
            b.iter(|| black_box(render_document(&doc, &req)));
        });
    }
    g.finish();

    // LOD vs every leaf: the 3M model in the far view (voxels about 0.1 px).
    let mut g = c.benchmark_group("lod");
    g.sample_size(10);
    let leaves = Quality {
        lod_pixel_threshold: 0.05,
        ..no_shadows.clone()
    };
    for (name, q) in [("lod", &no_shadows), ("every_leaf", &leaves)] {
        let req = request(far, q.clone());
        report(&format!("lod/{name}"), &big, &req);
        g.bench_function(name, |b| b.iter(|| black_box(render_document(&big, &req))));
    }
    g.finish();

    // Exact cubes (Quality::cube_pixel_threshold) against the paper's rectangles: the house
    // sample at 800×600 from a few voxels off its wall (leaves tens of pixels wide) and from
    // the project's own camera (a few pixels each), balanced otherwise.
    let house_path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/house.thicket.json");
    if let Ok(house) = thicket_core::io::project::load(&house_path) {
        let mut g = c.benchmark_group("exact_cubes");
        g.sample_size(10);
        let close = thicket_core::render::scenes::house_close_up(&house).expect("bounds");
        let rects = Quality {
            cube_pixel_threshold: 1e6,
            ..Quality::default()
        };
        for (view, cam) in [("close_up", close), ("project_view", house.camera)] {
            for (name, q) in [("cubes", Quality::default()), ("rectangles", rects.clone())] {
                let req = View {
                    width: 800,
                    height: 600,
                    camera: Some(cam),
                    quality: q,
                };
                if let Ok((_, _, st)) = render_document(&house, &req) {
                    eprintln!(
                        "exact_cubes/{view}_{name}: {} splats ({} cubes), {} rectangle px, {}                          cube px, {} shadow cube px",
                        st.splats(),
                        st.totals().cubes,
                        st.rect_pixels,
                        st.cube_pixels,
                        st.shadow_cube_pixels
                    );
                }
                g.bench_function(format!("{view}_{name}"), |b| {
                    b.iter(|| black_box(render_document(&house, &req)));
                });
            }
        }
        g.finish();

        // Issue 43: the house with its uniform regions as tiles (as loaded) and voxel by voxel,
        // side by side: both visit the same nodes, so the frames should cost the same.
        let mut g = c.benchmark_group("tiles");
        g.sample_size(10);
        let mut flat = house.clone();
        for o in &mut flat.objects {
            if let thicket_core::scene::ObjectKind::Voxels(v) = &mut o.kind {
                v.svo = std::mem::take(&mut v.svo).without_tiles();
            }
        }
        let req = View {
            width: 800,
            height: 600,
            camera: Some(house.camera),
            quality: Quality::default(),
        };
        for (name, doc) in [("house_tiled", &house), ("house_voxel_by_voxel", &flat)] {
            g.bench_function(name, |b| b.iter(|| black_box(render_document(doc, &req))));
        }
        g.finish();

        // Issue 25: a frame that keeps its buffers. The house (octree depth 6, a small model
        // whose frame was dominated by making its buffers) from its project camera at 800×800
        // with its own quality, and the near 3M-voxel sphere balanced: each drawn by the free
        // function (a fresh renderer per frame: every buffer made and page-faulted again) and
        // by one `Renderer` reused frame after frame.
        let mut g = c.benchmark_group("reuse");
        g.sample_size(10);
        let house_req = View {
            width: 800,
            height: 800,
            camera: Some(house.camera),
            quality: house.quality.clone(),
        };
        let sphere_req = request(near, shaded.clone());
        for (name, doc, req) in [
            ("house_800", &house, &house_req),
            ("sphere_near_800", &big, &sphere_req),
        ] {
            g.bench_function(format!("{name}_fresh"), |b| {
                b.iter(|| black_box(render_document(doc, req).is_ok()));
            });
            let mut renderer = Renderer::new();
            g.bench_function(format!("{name}_reused"), |b| {
                b.iter(|| black_box(renderer.render_document(doc, req).is_ok()));
            });
        }
        g.finish();

        // The editor's refined CPU preview frame (issue 27: within 300 ms of the camera
        // stopping, 150 ms of which is the stillness wait): the house from its project camera
        // with the document's own quality, at the view size a 1280×800 window leaves between
        // the default outliner and inspector (605×725 px, read from the view corner under
        // Xvfb), and at the whole window's size.
        let mut g = c.benchmark_group("preview_refine");
        g.sample_size(10);
        for (name, [width, height]) in [
            ("view_605x725", [605, 725]),
            ("window_1280x800", [1280, 800]),
        ] {
            let req = View {
                width,
                height,
                camera: Some(house.camera),
                quality: house.quality.clone(),
            };
            g.bench_function(name, |b| {
                b.iter(|| black_box(render_document(&house, &req)));
            });
        }
        g.finish();
    }
}

criterion_group!(render_benches, benches);
criterion_main!(render_benches);

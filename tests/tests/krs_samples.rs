//! The KRS sample projects (tree, forest, battered rocks on KRS terrain, grassland, coral reef,
//! woodland on KRS terrain) render like their golden images,
//! the KRS drawn by sphere tracing into the depth buffer it shares with meshes. On a mismatch
//! the helper writes `-actual.png` and `-difference.png` beside the golden; `THICKET_BLESS=1`
//! rewrites the goldens after an intended change.

use thicket_core::io::project;
use thicket_core::krs::{Kernel, KrsObject, KrsScene, TextureMode};
use thicket_core::measure::image::{Tolerance, assert_images_match};
use thicket_core::render::{RgbaImage, View, render_document};
use thicket_core::scene::{Document, ObjectKind};
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
        &View {
            quality,
            ..View::new(SIZE, SIZE)
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
    // Three battered rocks (§7.1): planar kernels only, at least 12 reflection levels, a
    // distortion and triplanar texture, each from its own seed (no two alike).
    let doc = load("rock");
    let rocks: Vec<&KrsObject> = krs_objects(&doc)
        .into_iter()
        .filter(|k| k.name == "battered rock")
        .collect();
    assert_eq!(rocks.len(), 3);
    for r in &rocks {
        assert!(r.mirrors.len() >= 12, "{} levels", r.mirrors.len());
        assert!(
            r.kernels
                .iter()
                .all(|k| matches!(k, Kernel::InfinitePlane(_) | Kernel::Empty))
        );
        assert!(r.distortion.is_some_and(|d| d.amplitude > 0.0));
        assert_eq!(r.texturing.mode, TextureMode::Triplanar);
    }
    assert!(rocks[0].mirrors != rocks[1].mirrors && rocks[1].mirrors != rocks[2].mirrors);
    assert_images_match(&img, golden("rock"), Tolerance::CPU_GOLDEN);
}

fn load(name: &str) -> Document {
    let path = thicket_tests::repo_root()
        .join("projects")
        .join(format!("{name}.thicket.json"));
    project::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// The shown KRS objects (a forest's tree stays in the project, hidden).
fn krs_objects(doc: &Document) -> Vec<&KrsObject> {
    doc.objects
        .iter()
        .filter(|o| o.visible)
        .filter_map(|o| match &o.kind {
            ObjectKind::Krs(k) => Some(k),
            _ => None,
        })
        .collect()
}

/// The scattered piece of an `on_terrain` sample stands on the terrain: the foot (object-space
/// origin, where the presets root their trunk or stem) of every copy made by the reflections the
/// terrain shares is within `tolerance` of the terrain's surface (Algorithm 1 of the terrain
/// there, before the warp, which moves both alike), on every slope. Returns how many copies
/// were checked.
fn stands_on_terrain(name: &str, limit: usize, tolerance: f32) -> usize {
    let doc = load(name);
    let objects: Vec<KrsObject> = krs_objects(&doc).into_iter().cloned().collect();
    assert_eq!(objects.len(), 2, "{name}: terrain and piece");
    let scene = KrsScene { objects }.prepare().expect("valid");
    let (terrain, piece) = (&scene.objects[0], &scene.objects[1]);
    let shared = terrain
        .object
        .mirrors
        .iter()
        .rev()
        .zip(piece.object.mirrors.iter().rev())
        .take_while(|(a, b)| a == b)
        .count();
    assert!(shared > 0, "{name}: the terrain shares the piece's mirrors");
    let first_shared = piece.object.mirrors.len() - shared;
    // The copies of the foot: the origin reflected by every shared mirror.
    let mut feet = vec![glam::DVec3::ZERO];
    for m in &piece.object.mirrors[first_shared..] {
        let n = m.normal.as_dvec3();
        let images: Vec<_> = feet
            .iter()
            .map(|p| *p - 2.0 * (n.dot(*p) - f64::from(m.offset)) * n)
            .collect();
        feet.extend(images);
    }
    let (mut checked, mut worst, mut heights) = (0, 0.0f32, (f32::INFINITY, f32::NEG_INFINITY));
    for foot in feet.iter().take(limit) {
        let foot = foot.as_vec3();
        let d = terrain
            .object
            .distance_object(terrain.object_from_world(foot));
        worst = worst.max(d.abs());
        heights = (heights.0.min(foot.y), heights.1.max(foot.y));
        checked += 1;
    }
    eprintln!("{name}: {checked} feet, worst {worst}, heights {heights:?}");
    assert!(
        worst <= tolerance,
        "{name}: a foot is {worst} from the terrain"
    );
    // Not a flat floor: the feet stand at different heights.
    assert!(heights.1 - heights.0 > 0.1, "{name}: heights {heights:?}");
    checked
}

#[test]
fn grassland_sample_matches_its_golden_and_every_tuft_stands_on_the_terrain() {
    let (img, instances, covered) = render_sample("grassland");
    // 4,096 tufts of 256 blades (plus the short ones): about a million kernel instances.
    assert!(instances >= 1 << 20, "{instances}");
    assert!(covered > (SIZE * SIZE * 9 / 10) as usize, "{covered}");
    assert_eq!(stands_on_terrain("grassland", 1 << 16, 1e-3), 4096);
    assert_images_match(&img, golden("grassland"), Tolerance::CPU_GOLDEN);
}

#[test]
fn coral_sample_matches_its_golden_and_every_coral_stands_on_the_floor() {
    let (img, instances, covered) = render_sample("coral");
    assert!(instances > 1000, "{instances}");
    assert!(covered > (SIZE * SIZE / 2) as usize, "{covered}");
    assert_eq!(stands_on_terrain("coral", 1 << 12, 1e-3), 32);
    assert_images_match(&img, golden("coral"), Tolerance::CPU_GOLDEN);
}

#[test]
fn woodland_sample_matches_its_golden() {
    let (img, instances, covered) = render_sample("woodland");
    assert!(instances >= 1 << 22, "{instances}");
    assert!(covered > (SIZE * SIZE * 3 / 4) as usize, "{covered}");
    // Every one of the 16,384 trees (their trunks are the coarsest kernel).
    assert_eq!(stands_on_terrain("woodland", 1 << 22, 2e-3), 1 << 14);
    assert_images_match(&img, golden("woodland"), Tolerance::CPU_GOLDEN);
}

/// The new samples export (`thicket export` builds the same scene): a battered rock as a closed
/// mesh (its half-space kernels close into a bounded solid, so the exporter finds its box), the
/// woodland's trees as one prototype placed once per copy; the distorted reef as one mesh (a
/// warp is no isometry, so its copies differ and cannot be instances) and the meadow too (its
/// tufts overlap, so the shared mirrors clip them and a copied prototype would not be what
/// Algorithm 1 draws); each terrain as a patch under them.
#[test]
fn the_new_samples_export_where_bounded() {
    use std::path::Path;
    use thicket_core::io::gltf_export::{GltfExportOptions, build_scene};
    let options = GltfExportOptions {
        resolution: 40,
        kernel_resolution: 12,
        instanced_lod_levels: 0,
        impostor: false,
        ..GltfExportOptions::default()
    };
    // Instanced placements do not size a terrain's patch (the exporter asks for --bounds when
    // nothing else is exported), so the scattered samples give one.
    let go_in = |doc: &Document, object: Option<&str>, bounds: Option<[f32; 4]>| {
        build_scene(
            doc,
            Path::new("sample.glb"),
            &GltfExportOptions {
                object: object.map(str::to_owned),
                bounds,
                ..options.clone()
            },
            &|_| true,
        )
        .unwrap_or_else(|e| panic!("{object:?}: {e}"))
    };
    let go = |doc: &Document, object: Option<&str>| go_in(doc, object, None);
    // The rock: a mesh within the rock's reach of where it stands.
    let rock_doc = load("rock");
    let (scene, report) = go(&rock_doc, Some("Rock 1"));
    assert!(report.triangles > 500, "{report:?}");
    let at = rock_doc
        .object_by_name("Rock 1")
        .expect("rock 1")
        .transform
        .translation;
    for p in scene.nodes[0].primitives.iter().flat_map(|p| &p.positions) {
        assert!(p.distance(at) < 3.0, "{p} far from the rock at {at}");
    }
    // The woodland: the tree instanced, the terrain a patch.
    let bounds = Some([-20.0, -20.0, 20.0, 20.0]);
    for name in ["coral", "grassland"] {
        let (_, report) = go_in(&load(name), None, bounds);
        assert!(report.instanced.is_empty(), "{report:?}");
        assert!(report.objects == 2 && report.triangles > 5000, "{report:?}");
        assert!(report.patches.iter().any(|(n, _, _)| n == "Terrain"));
    }
    let (_, report) = go_in(&load("woodland"), None, bounds);
    let inst = report
        .instanced
        .iter()
        .find(|i| i.object == "Forest")
        .unwrap_or_else(|| panic!("the forest is instanced: {report:?}"));
    // One placement per tree: the 14 shared reflections place them (level 7: the tree's own
    // seven levels are the prototype).
    assert_eq!(inst.instances, 1 << 14, "{inst:?}");
    assert!(inst.prototype_triangles > 100, "{inst:?}");
    assert!(
        report
            .patches
            .iter()
            .any(|(n, lo, hi)| n == "Terrain" && hi.x > lo.x),
        "{:?}",
        report.patches
    );
}

/// Renders `doc` at 128² (a smaller shadow map) and measures its visible repetition.
fn repetition_of(doc: &Document) -> thicket_core::krs::repetition::Repetition {
    let mut quality = doc.quality.clone();
    quality.shadow_map_size = 512;
    let (img, _, _) = render_document(
        doc,
        &View {
            quality,
            ..View::new(128, 128)
        },
    )
    .expect("frame");
    thicket_core::krs::repetition::visible_repetition(&img.pixels, img.width, img.height)
}

/// Symmetry hiding measured (§5, issue 26 item 4): the woodland regrown from its tree with its
/// reflections aligned (mirrors exactly along x and z, regular gaps, flat ground) and as
/// shipped (jittered azimuths and tilts, varied gaps), with and without a warp, the forest and
/// the terrain alone; `thicket render --stats` reports the same measure for any project. The
/// aligned forest is a lattice of identical trees and must measure clearly higher than the
/// jittered one.
#[test]
fn jittered_mirrors_measure_less_visible_repetition_than_aligned_ones() {
    use thicket_tests::samples::woodland_forest;
    let base = load("woodland");
    let tree = base.object_by_name("Tree").expect("the tree").id;
    let terrain = base.object_by_name("Terrain").expect("the terrain").id;
    let measure = |aligned: bool, warped: bool, terrain_only: bool| {
        let mut params = woodland_forest();
        if aligned {
            params.jitter = 0.0;
            params.spread = 0.0;
            params.tilt = 0.0;
        }
        if warped {
            params.warp = 0.2;
            params.warp_frequency = 0.5;
        }
        let mut doc = base.clone();
        let plan = doc
            .plan_forest(&[tree], Some(terrain), &params)
            .expect("regrows");
        doc.apply_forest(plan);
        if let Some(o) = doc.objects.iter_mut().find(|o| o.name == "Forest") {
            o.visible = !terrain_only;
        }
        repetition_of(&doc)
    };
    let mut forest = Vec::new();
    for (what, terrain_only) in [("forest", false), ("terrain", true)] {
        for (aligned, warped) in [(true, false), (false, false), (true, true), (false, true)] {
            let r = measure(aligned, warped, terrain_only);
            eprintln!(
                "{what:8} {:9} {:10}: translation {:.3} mirror {:.3} score {:.3}",
                if aligned { "aligned" } else { "jittered" },
                if warped { "warped" } else { "not warped" },
                r.translation,
                r.mirror,
                r.score()
            );
            if !terrain_only {
                forest.push(r.score());
            }
        }
    }
    let (aligned, jittered) = (forest[0], forest[1]);
    assert!(
        aligned > 0.4 && aligned > 1.5 * jittered,
        "aligned {aligned} jittered {jittered}"
    );
}

/// Three different trees from the builder (parameters saved with them) added to `doc`.
fn three_builder_trees(doc: &mut Document) -> Vec<u64> {
    use thicket_core::krs::TreeParams;
    let mut trees = Vec::new();
    for k in 0..3 {
        // Taller or shorter trunks, wider or narrower crowns, forks turned differently.
        let mut params = TreeParams {
            route: thicket_core::krs::spiral_route(
                &[
                    1.8 + 0.5 * k as f32,
                    1.3,
                    1.0 - 0.15 * k as f32,
                    0.8,
                    0.6,
                    0.45,
                    0.35,
                ],
                1.1 + 0.25 * k as f32,
                0.5 + 0.2 * k as f32,
            ),
            ..TreeParams::default()
        };
        params.widths[0] = 0.16 + 0.05 * k as f32;
        let id = doc.add(
            format!("Tree {k}"),
            ObjectKind::Krs(params.build().expect("a tree")),
        );
        doc.tree_builders
            .push(thicket_core::scene::TreeBuilderLink { object: id, params });
        trees.push(id);
    }
    trees
}

/// The paper's other symmetry hiding (§5): "when, in a forest, there are three completely
/// different trees between the two that are mirror images of each other, symmetry is
/// undetected". A union of three different trees from the builder, grown over the same grid
/// with the same mirror draws, measures less visible repetition than one of them alone.
#[test]
fn a_union_of_three_trees_measures_less_visible_repetition_than_one_tree() {
    use thicket_core::krs::forest::ForestParams;
    let base = load("woodland");
    let mut doc = Document {
        objects: Vec::new(),
        forests: Vec::new(),
        tree_builders: Vec::new(),
        ..base.clone()
    };
    let trees = three_builder_trees(&mut doc);
    doc.add(
        "Ground",
        ObjectKind::Krs(thicket_core::krs::presets::folded_ground(
            thicket_core::krs::Material::new(glam::Vec3::new(0.33, 0.38, 0.2), 5),
            0,
            1.0,
            0,
        )),
    );
    let s = 8.8;
    let grow = |sources: &[u64], trees: [u32; 2], aligned: bool| {
        let mut d = doc.clone();
        let mut params = ForestParams {
            trees,
            area: [s * trees[0] as f32, s * trees[1] as f32],
            ..thicket_tests::samples::woodland_forest()
        };
        if aligned {
            params.jitter = 0.0;
            params.spread = 0.0;
        }
        let plan = d.plan_forest(sources, None, &params).expect("grows");
        d.apply_forest(plan);
        repetition_of(&d)
    };
    // Aligned: the lattice in plain view, what the union alone must hide.
    let single = grow(&trees[..1], [32, 32], true);
    let union = grow(&trees, [24, 32], true);
    // Jittered as the woodland ships (printed for the record: the jitter already hides most).
    let single_j = grow(&trees[..1], [32, 32], false);
    let union_j = grow(&trees, [24, 32], false);
    eprintln!(
        "aligned: one tree {:.3}, three trees {:.3}; jittered: one tree {:.3}, three trees {:.3}",
        single.score(),
        union.score(),
        single_j.score(),
        union_j.score()
    );
    assert!(
        union.score() < 0.8 * single.score(),
        "one tree {single:?}, three trees {union:?}"
    );
}

/// A grown union exports as the sample forest does: each of its objects (two per tree) as one
/// prototype placed once per copy, so the file holds every tree of the grid.
#[test]
fn a_union_forest_exports_each_tree_instanced() {
    use std::path::Path;
    use thicket_core::io::gltf_export::{GltfExportOptions, build_scene};
    use thicket_core::krs::forest::ForestParams;
    let mut doc = Document::default();
    let trees = three_builder_trees(&mut doc);
    let plan = doc
        .plan_forest(
            &trees,
            None,
            &ForestParams {
                trees: [12, 8],
                area: [96.0, 64.0],
                ..ForestParams::default()
            },
        )
        .expect("grows");
    let grown = doc.apply_forest(plan);
    let (_, report) = build_scene(
        &doc,
        Path::new("union.glb"),
        &GltfExportOptions {
            resolution: 40,
            kernel_resolution: 12,
            instanced_lod_levels: 0,
            impostor: false,
            ..GltfExportOptions::default()
        },
        &|_| true,
    )
    .expect("exports");
    assert_eq!(report.instanced.len(), 6, "{report:?}");
    for id in grown {
        let name = &doc.objects.iter().find(|o| o.id == id).expect("grown").name;
        let inst = report
            .instanced
            .iter()
            .find(|i| &i.object == name)
            .unwrap_or_else(|| panic!("{name} is instanced: {report:?}"));
        assert_eq!(inst.instances, 16, "{inst:?}");
    }
    // The hidden trees are not exported.
    assert_eq!(report.objects, 6, "{report:?}");
}

//! The CPU renderer draws a tiled octree exactly as the leaf-only octree holding the same
//! voxels: the same image, G-buffer depths and traversal counts, on the samples and on a solid.

use super::*;
use crate::quality::QualityPreset;

fn sample(name: &str) -> Document {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../projects")
        .join(format!("{name}.thicket.json"));
    crate::io::project::load(&path).expect("a sample project")
}

/// CesiumMan voxelized solid at depth 7, mid-stride, boxes from their skinned corners.
fn solid_cesium_man() -> Document {
    let mut doc = crate::skin::deform_tests::skinned_doc_in(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../shared/assets/skinned/CesiumMan.glb"
        ),
        7,
        crate::voxelize::Mode::Solid,
    );
    if let Some(crate::scene::ObjectKind::Voxels(v)) = doc.objects.first_mut().map(|o| &mut o.kind)
        && let Some(rig) = &mut v.rig
    {
        rig.playback.time_secs = 0.6;
        rig.stretch.strategy = crate::skin::StretchStrategy::Corners;
    }
    doc
}

#[test]
fn a_tiled_octree_renders_as_its_leaf_only_octree() {
    let mut docs: Vec<(String, Document)> = ["house", "mixed", "terrain", "tree"]
        .iter()
        .map(|n| (n.to_string(), sample(n)))
        .collect();
    docs.push(("solid ball".into(), scenes::solid_ball()));
    docs.push((
        "interior ball".into(),
        scenes::ball(scenes::BallInside::Interior),
    ));
    // Skinned and posed: its limbs' insides are interior tiles carrying their joint's weights.
    docs.push(("rigid solid figure".into(), scenes::rigid_solid_figure()));
    // Skinned with smooth weights: its interior tiles border voxels of other weights, so the
    // shell's corners merge a tile's weights with theirs.
    docs.push(("solid CesiumMan".into(), solid_cesium_man()));
    for (name, doc) in docs {
        let (doc, tiled_doc, tiles) = scenes::without_and_with_tiles(&doc);
        // Surface-only samples (terrain) may have none; the house's walls and the ball do.
        if name == "house" || name.ends_with("ball") || name.ends_with("figure") {
            assert!(tiles > 50, "{name}: {tiles} tiles");
        }
        if name == "solid CesiumMan" {
            assert!(tiles > 20, "{name}: {tiles} tiles");
        }
        for quality in [
            Quality::preset(QualityPreset::Draft),
            Quality::preset(QualityPreset::Balanced),
        ] {
            let view = View {
                width: 160,
                height: 120,
                camera: None,
                quality,
            };
            let (a, fa, sa) = render_document(&doc, &view).unwrap();
            let (b, fb, sb) = render_document(&tiled_doc, &view).unwrap();
            assert!(a == b, "{name}: the images differ");
            assert_eq!(fa.depth, fb.depth, "{name}: depths differ");
            assert_eq!(
                (sa.nodes_visited(), sa.splats()),
                (sb.nodes_visited(), sb.splats()),
                "{name}: traversal differs"
            );
        }
    }
}

#[test]
fn interior_nodes_are_never_visited_and_a_solid_draws_as_its_shell() {
    use scenes::BallInside;
    let solid = scenes::ball(BallInside::Interior);
    let shell = scenes::ball(BallInside::Hollow);
    let (flat, tiled, tiles) = scenes::without_and_with_tiles(&solid);
    assert!(tiles > 20, "{tiles} tiles");
    for quality in [
        Quality::preset(QualityPreset::Draft),
        Quality::preset(QualityPreset::Balanced),
    ] {
        let view = View {
            width: 160,
            height: 120,
            camera: None,
            quality,
        };
        let (a, fa, sa) = render_document(&tiled, &view).unwrap();
        let (b, fb, sb) = render_document(&flat, &view).unwrap();
        let (c, fc, sc) = render_document(&shell, &view).unwrap();
        assert!(a == b, "tiled and voxel by voxel differ");
        assert_eq!(fa.depth, fb.depth);
        assert_eq!(sa.nodes_visited(), sb.nodes_visited());
        // What is drawn is the shell: the same pixels and depths.
        let differ = a
            .pixels
            .chunks(4)
            .zip(c.pixels.chunks(4))
            .filter(|(p, q)| p != q)
            .count();
        eprintln!(
            "solid {} nodes, {} splats; shell {} nodes, {} splats; {differ} pixels differ",
            sa.nodes_visited(),
            sa.splats(),
            sc.nodes_visited(),
            sc.splats()
        );
        assert_eq!(differ, 0, "pixels of the solid differ from its shell's");
        assert_eq!(fa.depth, fc.depth);
        // Without the interior mark (the same ball filled with one colour) every solid node
        // at the cut is visited.
        let (_, _, sd) = render_document(&scenes::solid_ball(), &view).unwrap();
        eprintln!("coloured solid {} nodes", sd.nodes_visited());
        // Interior children are never queued, leaves included: the solid visits exactly its
        // shell's nodes (5,670 at draft against the coloured solid's 23,021).
        assert_eq!(
            (sa.nodes_visited(), sa.splats()),
            (sc.nodes_visited(), sc.splats()),
            "solid against its shell"
        );
        assert!(
            sa.nodes_visited() * 2 <= sd.nodes_visited(),
            "solid with interior visits {} nodes, coloured {}",
            sa.nodes_visited(),
            sd.nodes_visited()
        );
    }
}

#[test]
fn no_pixel_of_a_solid_import_shows_an_interior_voxel() {
    // Spot voxelized solid: its enclosed inside is the interior mark (no colour). Splats are
    // conservative rectangles, so a voxel just behind the shell could win a pixel at a grazing
    // angle if it were drawn; none may show (its albedo would be black).
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/assets/static/spot/spot_triangulated.obj");
    let mesh = crate::io::import_obj(&path).expect("Spot");
    let settings = crate::voxelize::VoxelizeSettings {
        resolution: crate::voxelize::Resolution::Depth(7),
        mode: crate::voxelize::Mode::Solid,
        ..crate::voxelize::VoxelizeSettings::default()
    };
    let v = crate::voxelize::voxelize(&mesh, &settings, &|_| true).expect("voxelize");
    assert!(v.stats.interior_marked > 100_000, "{:?}", v.stats);
    let mut doc = Document::default();
    doc.add(
        "Spot",
        crate::scene::ObjectKind::Voxels(crate::scene::VoxelModel {
            svo: v.svo,
            voxel_size: v.voxel_size,
            origin: v.origin,
            ..crate::scene::VoxelModel::default()
        }),
    );
    let mut black = 0;
    for (yaw, pitch) in [(20.0f32, 10.0f32), (120.0, -25.0), (-70.0, 50.0)] {
        let mut cam = doc.camera;
        cam.yaw_deg = yaw;
        cam.pitch_deg = pitch;
        cam.frame(v.origin, v.origin + Vec3::splat(128.0 * v.voxel_size));
        for quality in [
            Quality::preset(QualityPreset::Draft),
            Quality::preset(QualityPreset::Balanced),
        ] {
            let view = View {
                width: 400,
                height: 400,
                camera: Some(cam),
                quality,
            };
            let (_, f, _) = render_document(&doc, &view).unwrap();
            black += f
                .depth
                .iter()
                .zip(&f.albedo)
                .filter(|(d, a)| **d < 1.0 && **a == Vec3::ZERO)
                .count();
        }
    }
    assert_eq!(black, 0, "pixels showing an interior voxel");
}

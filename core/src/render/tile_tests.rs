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

#[test]
fn a_tiled_octree_renders_as_its_leaf_only_octree() {
    let mut docs: Vec<(String, Document)> = ["house", "mixed", "terrain", "tree"]
        .iter()
        .map(|n| (n.to_string(), sample(n)))
        .collect();
    docs.push(("solid ball".into(), scenes::solid_ball()));
    for (name, doc) in docs {
        let (doc, tiled_doc, tiles) = scenes::without_and_with_tiles(&doc);
        // Surface-only samples (terrain) may have none; the house's walls and the ball do.
        if name == "house" || name == "solid ball" {
            assert!(tiles > 50, "{name}: {tiles} tiles");
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

use std::collections::HashMap;

use glam::{Quat, Vec3};

use super::*;
use crate::krs::presets;
use crate::krs::{Material, TreeParams};

/// The default tree and its trunk base (object space).
fn tree() -> (KrsObject, Vec3) {
    let params = TreeParams::default();
    (presets::tree(), params.route[0])
}

fn flat(params: ForestParams) -> ForestParams {
    ForestParams {
        jitter: 0.0,
        spread: 0.0,
        ..params
    }
}

/// Where every trunk of a grown object stands: the trunk kernel's (the last kernel of the tree
/// before growing) instances mapped through their reflections, with whether each is mirrored.
fn trunk_feet(g: &GrownTree, tree: &ForestTree<'_>) -> Vec<(Vec3, bool)> {
    let trunk = tree.object.kernels.len() - 1;
    let placement = Similarity {
        translation: tree.placement.translation + g.translation,
        ..tree.placement
    };
    let prepared = prepare_one(placed(&g.object, placement), 0).expect("valid");
    prepared
        .instances(1 << 20)
        .into_iter()
        .filter(|i| i.kernel == trunk)
        // The kernel's own space is the tree's object space (the instance adds the reflections
        // and the placement).
        .map(|i| (i.world_from_kernel.transform_point3(tree.base), i.mirrored))
        .collect()
}

#[test]
fn one_tree_grows_into_exactly_its_grid_of_trees() {
    let (object, base) = tree();
    let t = ForestTree {
        object: &object,
        placement: Similarity {
            translation: Vec3::new(3.0, 1.0, -2.0),
            ..Similarity::default()
        },
        base,
    };
    let params = flat(ForestParams {
        trees: [8, 4],
        area: [64.0, 32.0],
        ..ForestParams::default()
    });
    let forest = grow_forest(&[t], &params, None).expect("grows");
    assert_eq!(forest.trees.len(), 1);
    assert_eq!(forest.total, 32);
    assert_eq!(forest.spacing, [8.0, 8.0]);
    assert_eq!(
        forest.trees[0].translation,
        Vec3::ZERO,
        "the first tree stays"
    );
    assert_eq!(
        forest.trees[0].object.instance_count(),
        object.instance_count() * 32
    );
    let feet = trunk_feet(&forest.trees[0], &t);
    assert_eq!(feet.len(), 32);
    let origin = Vec3::new(3.0, 1.0, -2.0) + base;
    for i in 0..8 {
        for j in 0..4 {
            let want = origin + Vec3::new(8.0 * i as f32, 0.0, 8.0 * j as f32);
            let n = feet.iter().filter(|(f, _)| f.distance(want) < 1e-3).count();
            assert_eq!(n, 1, "one trunk at cell ({i}, {j}) = {want}: {feet:?}");
        }
    }
    // Neighbours are mirror images of each other: the parity of i + j.
    for (f, mirrored) in &feet {
        let d = *f - origin;
        let parity = ((d.x / 8.0).round() as i32 + (d.z / 8.0).round() as i32) % 2 == 1;
        assert_eq!(*mirrored, parity, "{f}");
    }
}

#[test]
fn jittered_forests_keep_every_tree_in_its_own_cell() {
    let (object, base) = tree();
    let t = ForestTree {
        object: &object,
        placement: Similarity::default(),
        base,
    };
    let params = ForestParams {
        trees: [16, 16],
        area: [160.0, 160.0],
        jitter: 0.08,
        spread: 0.3,
        ..ForestParams::default()
    };
    let forest = grow_forest(&[t], &params, None).expect("grows");
    let feet = trunk_feet(&forest.trees[0], &t);
    assert_eq!(feet.len(), 256);
    // Distinct trees, none closer than half the spacing (the spread moves a gap by at most 30 %
    // of it), all on flat ground.
    let mut nearest = f32::INFINITY;
    for (a, (fa, _)) in feet.iter().enumerate() {
        assert!((fa.y - base.y).abs() < 1e-3, "no tilt on flat ground: {fa}");
        for (fb, _) in &feet[a + 1..] {
            nearest = nearest.min(fa.distance(*fb));
        }
    }
    assert!(nearest > 0.5 * 10.0, "nearest trunks {nearest} apart");
    // The same parameters give the same forest; another seed another one.
    assert_eq!(grow_forest(&[t], &params, None).expect("grows"), forest);
    let other = grow_forest(&[t], &ForestParams { seed: 7, ..params }, None).expect("grows");
    assert_ne!(
        other.trees[0].object.mirrors,
        forest.trees[0].object.mirrors
    );
}

#[test]
fn a_rotated_scaled_tree_grows_the_same_world_grid() {
    let (object, base) = tree();
    let placement = Similarity {
        translation: Vec3::new(-5.0, 0.0, 4.0),
        rotation: Quat::from_rotation_y(0.7),
        scale: 2.0,
    };
    let t = ForestTree {
        object: &object,
        placement,
        base,
    };
    let params = flat(ForestParams {
        trees: [4, 4],
        area: [80.0, 80.0],
        ..ForestParams::default()
    });
    let forest = grow_forest(&[t], &params, None).expect("grows");
    let feet = trunk_feet(&forest.trees[0], &t);
    assert_eq!(feet.len(), 16);
    let origin = placement.transform_point(base);
    for i in 0..4 {
        for j in 0..4 {
            let want = origin + Vec3::new(20.0 * i as f32, 0.0, 20.0 * j as f32);
            assert!(
                feet.iter().any(|(f, _)| f.distance(want) < 1e-3),
                "a trunk at {want}: {feet:?}"
            );
        }
    }
}

#[test]
fn every_trunk_stands_on_the_terrain_it_shares_mirrors_with() {
    let (object, base) = tree();
    let ground = presets::folded_ground(Material::new(Vec3::new(0.3, 0.4, 0.2), 5), 5, 5.0, 3);
    let t = ForestTree {
        object: &object,
        placement: Similarity::default(),
        base,
    };
    let g = ForestGround {
        object: &ground,
        placement: Similarity::default(),
    };
    let params = ForestParams {
        trees: [16, 8],
        area: [160.0, 80.0],
        tilt: 0.06,
        ..ForestParams::default()
    };
    let forest = grow_forest(&[t], &params, Some(g)).expect("grows");
    let terrain = forest.ground.as_ref().expect("terrain");
    // The terrain keeps its own folds and takes the forest's as its coarsest levels.
    assert_eq!(terrain.mirrors[..5], ground.mirrors[..]);
    assert_eq!(
        terrain.mirrors[5..],
        forest.trees[0].object.mirrors[object.mirrors.len()..]
    );
    let terrain = prepare_one(terrain.clone(), 0).expect("valid");
    let feet = trunk_feet(&forest.trees[0], &t);
    assert_eq!(feet.len(), 128);
    let (mut worst, mut low, mut high) = (0.0f32, f32::INFINITY, f32::NEG_INFINITY);
    for (f, _) in &feet {
        worst = worst.max(terrain.distance_world(*f).abs());
        low = low.min(f.y);
        high = high.max(f.y);
    }
    assert!(worst < 2e-3, "a trunk base is {worst} from the terrain");
    assert!(
        high - low > 0.5,
        "tilted folds: the ground rises and falls ({low}..{high})"
    );
    // The first trunk was moved onto the surface under it.
    let h = ground_height(&terrain, base.x, base.z, 50.0).expect("ground");
    assert!((forest.trees[0].translation.y - (h - base.y)).abs() < 1e-3);
}

/// On the placement lattice: (cell x, cell z) → (tree, mirrored) for every trunk of a forest
/// grown flat from `trees`.
fn lattice(trees: &[ForestTree<'_>], params: &ForestParams) -> HashMap<(i32, i32), (usize, bool)> {
    let forest = grow_forest(trees, params, None).expect("grows");
    let origin = trees[0].placement.transform_point(trees[0].base);
    let mut cells = HashMap::new();
    for g in &forest.trees {
        for (f, mirrored) in trunk_feet(g, &trees[g.source]) {
            let d = (f - origin) / Vec3::new(forest.spacing[0], 1.0, forest.spacing[1]);
            let cell = (d.x.round() as i32, d.z.round() as i32);
            assert!(
                (d.x - cell.0 as f32).abs() < 1e-3 && (d.z - cell.1 as f32).abs() < 1e-3,
                "{f} is on the grid"
            );
            assert!(
                cells.insert(cell, (g.source, mirrored)).is_none(),
                "one tree per cell {cell:?}"
            );
        }
    }
    assert_eq!(cells.len() as u64, forest.total);
    cells
}

/// Pairs of cells sharing an edge that hold the same tree; and of those, mirror images.
fn same_tree_neighbours(cells: &HashMap<(i32, i32), (usize, bool)>) -> (usize, usize) {
    let (mut same, mut mirrored) = (0, 0);
    for (&(x, z), &(t, m)) in cells {
        for n in [(x + 1, z), (x, z + 1)] {
            if let Some(&(t2, m2)) = cells.get(&n)
                && t2 == t
            {
                same += 1;
                if m2 != m {
                    mirrored += 1;
                }
            }
        }
    }
    (same, mirrored)
}

/// Three different trees from the builder.
fn three_trees() -> Vec<(KrsObject, Vec3)> {
    (0..3)
        .map(|k| {
            let p = TreeParams {
                route: crate::krs::tree::spiral_route(
                    &[2.0 + 0.3 * k as f32, 1.2, 0.9, 0.7, 0.5, 0.4, 0.3],
                    1.2 + 0.2 * k as f32,
                    0.6,
                ),
                ..TreeParams::default()
            };
            (p.build().expect("tree"), p.route[0])
        })
        .collect()
}

#[test]
fn a_union_of_three_trees_has_no_neighbouring_mirror_images() {
    let shapes = three_trees();
    let trees: Vec<ForestTree<'_>> = shapes
        .iter()
        .enumerate()
        .map(|(k, (object, base))| ForestTree {
            object,
            // Wherever the artist left them: the grower moves them into their cells.
            placement: Similarity {
                translation: Vec3::new(10.0 * k as f32, 0.0, -3.0 * k as f32),
                ..Similarity::default()
            },
            base: *base,
        })
        .collect();
    let params = flat(ForestParams {
        trees: [12, 8],
        area: [96.0, 64.0],
        ..ForestParams::default()
    });
    let union = lattice(&trees, &params);
    assert_eq!(union.len(), 96);
    assert_eq!(same_tree_neighbours(&union), (0, 0));
    // Every tree is used alike.
    for t in 0..3 {
        assert_eq!(union.values().filter(|(s, _)| *s == t).count(), 32);
    }
    // Along x, two other trees stand between two copies of one.
    for (&(x, z), &(t, _)) in &union {
        for dx in 1..3 {
            if let Some(&(t2, _)) = union.get(&(x + dx, z)) {
                assert_ne!(t2, t, "cells ({x},{z}) and ({},{z})", x + dx);
            }
        }
    }
    // One tree: every neighbour is its mirror image (8 × 8 cells: 112 edges).
    let single = lattice(
        &trees[..1],
        &flat(ForestParams {
            trees: [8, 8],
            area: [64.0, 64.0],
            ..ForestParams::default()
        }),
    );
    assert_eq!(same_tree_neighbours(&single), (112, 112));
}

#[test]
fn bad_forests_are_refused_with_the_reason() {
    let (object, base) = tree();
    let t = ForestTree {
        object: &object,
        placement: Similarity::default(),
        base,
    };
    let grow = |params: ForestParams| grow_forest(&[t], &params, None).unwrap_err().to_string();
    let ok = ForestParams::default();
    let zero = grow(ForestParams {
        area: [0.0, 10.0],
        ..ok
    });
    assert!(zero.contains("area x must be a positive"), "{zero}");
    assert!(
        grow(ForestParams {
            area: [10.0, f32::NAN],
            ..ok
        })
        .contains("area z")
    );
    assert!(
        grow(ForestParams {
            trees: [3, 4],
            ..ok
        })
        .contains("power of two")
    );
    assert!(
        grow(ForestParams {
            trees: [0, 4],
            ..ok
        })
        .contains("0 trees along x")
    );
    let huge = grow(ForestParams {
        trees: [1 << 21, 1 << 20],
        ..ok
    });
    assert!(huge.contains("41 reflection levels"), "{huge}");
    assert!(grow(ForestParams { jitter: 2.0, ..ok }).contains("jitter"));
    assert!(
        grow(ForestParams {
            warp: 2.0,
            warp_frequency: 1.0,
            ..ok
        })
        .contains("warp ×")
    );
    // A union counts in multiples of its kinds.
    let three = grow_forest(&[t, t, t], &ok, None).unwrap_err().to_string();
    assert!(
        three.contains("3 times a power of two (3, 6, 12"),
        "{three}"
    );
    // A union on a terrain.
    let ground = presets::folded_ground(Material::default(), 0, 1.0, 0);
    let g = ForestGround {
        object: &ground,
        placement: Similarity::default(),
    };
    let union = grow_forest(
        &[t, t],
        &ForestParams {
            trees: [4, 4],
            ..ok
        },
        Some(g),
    )
    .unwrap_err();
    assert!(matches!(union, ForestError::UnionOnTerrain { kinds: 2 }));
    // More levels than a KRS may have.
    let mut deep = object.clone();
    deep.mirrors
        .resize(MAX_KRS_LEVELS - 3, MirrorPlane::new(Vec3::X, 100.0));
    deep.kernels.resize(deep.mirrors.len() + 1, Kernel::Empty);
    let deep = ForestTree { object: &deep, ..t };
    assert!(matches!(
        grow_forest(&[deep], &ok, None),
        Err(ForestError::KrsLimit { tree: 0, .. })
    ));
    assert_eq!(grow_forest(&[], &ok, None), Err(ForestError::NoTrees));
}

/// Numerical extremes: a million trees over a 100 km square. The trunk bases are found by the
/// distance field (Algorithm 1 folds in f64): the far corners' trees are where the grid puts
/// them, and the ground between them is empty.
#[test]
fn a_million_trees_over_a_hundred_kilometres_stay_on_their_grid() {
    let (object, base) = tree();
    let t = ForestTree {
        object: &object,
        placement: Similarity::default(),
        base,
    };
    let params = flat(ForestParams {
        trees: [1024, 1024],
        area: [100_000.0, 100_000.0],
        ..ForestParams::default()
    });
    let forest = grow_forest(&[t], &params, None).expect("grows");
    assert_eq!(forest.total, 1 << 20);
    let grown = prepare_one(forest.trees[0].object.clone(), 0).expect("valid");
    let s = forest.spacing[0];
    for (i, j) in [(0u32, 0u32), (1023, 0), (0, 1023), (1023, 1023), (517, 300)] {
        let foot = base + Vec3::new(s * i as f32, 0.0, s * j as f32);
        // Inside the trunk a little above its base; empty space half a cell away.
        let inside = grown.distance_world(foot + Vec3::Y * 0.3);
        let between = grown.distance_world(foot + Vec3::new(0.5 * s, 0.3, 0.5 * s));
        assert!(inside < 0.0, "cell ({i}, {j}): {inside}");
        assert!(between > 1.0, "cell ({i}, {j}) gap: {between}");
    }
}

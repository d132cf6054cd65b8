//! Tiles are exact: a tiled octree and a leaf-only one fed the same edits hold the same voxels,
//! the same node attributes and give the same undo deltas, and the tiled one stays fully
//! collapsed and counts its memory right.

use glam::{DVec3, UVec3, Vec3};
use proptest::prelude::*;

use super::*;

/// A solid ball of radius `r` in a `2^depth` octree: one colour inside, a shell of varying
/// colours on its surface (so some regions tile and some do not); with `skin`, weights by half
/// (x below or above the centre) and an interior inside, as a rigged solid holds it (a skinned
/// octree tiles only its interior).
fn ball(depth: u8, r: f32, skin: bool) -> Vec<(UVec3, Voxel)> {
    let e = 1u32 << depth;
    let c = e as f32 / 2.0;
    let mut out = Vec::new();
    for z in 0..e {
        for y in 0..e {
            for x in 0..e {
                let p = Vec3::new(x as f32, y as f32, z as f32) + 0.5 - c;
                let d = p.length();
                if d > r {
                    continue;
                }
                let mut v = if d > r - 1.5 {
                    Voxel::new([(x * 8 % 256) as u8, (y * 8 % 256) as u8, 40, 255], p)
                } else if skin {
                    Voxel::INTERIOR
                } else {
                    Voxel::new([200, 180, 20, 255], Vec3::Z)
                };
                if skin {
                    v.skin = Skin4::from_influences(&[(u16::from(p.x > 0.0), 1.0)]);
                }
                out.push((UVec3::new(x, y, z), v));
            }
        }
    }
    out
}

pub(super) fn paint(k: u32, skin: bool) -> Voxel {
    let mut v = Voxel::new([k as u8 * 50, 90, 200, 255], Vec3::X);
    if skin {
        v.skin = Skin4::from_influences(&[(k as u16 % 3, 1.0)]);
    }
    v
}

/// What a walk of the stored nodes finds: (inner nodes, stored leaves, tiles, voxels of tiles).
fn walk_counts(svo: &Svo) -> (u64, u64, u64, u64) {
    let (mut inner, mut leaves, mut tiles, mut tile_voxels) = (0, 0, 0, 0);
    if svo.is_empty() {
        return (1, 0, 0, 0);
    }
    let mut stack = vec![svo.root()];
    while let Some(n) = stack.pop() {
        if svo.is_leaf(&n) {
            leaves += 1;
            continue;
        }
        inner += 1;
        if svo.is_tile(&n) {
            tiles += 1;
            tile_voxels += u64::from(svo.node_size(n.level)).pow(3);
            continue;
        }
        stack.extend((0..8).filter_map(|k| svo.child(&n, k)));
    }
    (inner, leaves, tiles, tile_voxels)
}

/// No stored node has eight equal children that could be one tile, and the counters match a
/// walk of the tree.
pub(super) fn assert_collapsed_and_counted(svo: &Svo) {
    let (inner, leaves, tiles, tile_voxels) = walk_counts(svo);
    let m = svo.memory_stats();
    assert_eq!(
        (
            m.inner_nodes,
            m.leaves - m.tile_voxels,
            m.tiles,
            m.tile_voxels
        ),
        (inner, leaves, tiles, tile_voxels),
        "counters against a walk"
    );
    let mut stack = vec![svo.root()];
    while let Some(n) = stack.pop() {
        if svo.is_leaf(&n) || svo.is_tile(&n) {
            continue;
        }
        let kids: Vec<NodeRef> = (0..8).filter_map(|k| svo.child(&n, k)).collect();
        if kids.len() == 8 && kids.iter().all(|c| svo.is_leaf(c) || svo.is_tile(c)) {
            let v: [Voxel; 8] = std::array::from_fn(|j| svo.node_voxel(&kids[j]));
            assert!(
                !svo.can_tile(&v),
                "node at {:?} level {} should be a tile",
                n.origin,
                n.level
            );
        }
        stack.extend(kids);
    }
}

#[test]
fn a_solid_ball_keeps_its_voxels_and_attributes_as_tiles() {
    for skin in [false, true] {
        let leaf_only = Svo::from_voxels(6, skin, ball(6, 27.0, skin))
            .unwrap()
            .without_tiles();
        let tiled = leaf_only.clone().with_tiles();
        assert!(tiled.tile_count() > 100, "{} tiles", tiled.tile_count());
        assert_eq!(tiled, leaf_only);
        assert_eq!(tiled.leaves(), leaf_only.leaves());
        assert_eq!(tiled.leaf_count(), leaf_only.leaf_count());
        assert_eq!(tiled.bounds(), leaf_only.bounds());
        assert_collapsed_and_counted(&tiled);
        let (a, b) = (tiled.memory_stats(), leaf_only.memory_stats());
        assert!(
            a.total_bytes * 3 < b.total_bytes,
            "tiled {} B against {} B",
            a.total_bytes,
            b.total_bytes
        );
        // Every node the renderers could stop at carries the same attributes.
        let mut nodes_a = Vec::new();
        tiled.traverse(Vec3::new(0.3, -0.5, 0.8), |n| {
            nodes_a.push((n.level, n.origin, tiled.node_voxel(n)));
            true
        });
        let mut nodes_b = Vec::new();
        leaf_only.traverse(Vec3::new(0.3, -0.5, 0.8), |n| {
            nodes_b.push((n.level, n.origin, leaf_only.node_voxel(n)));
            true
        });
        assert_eq!(nodes_a, nodes_b);
        let back = tiled.clone().without_tiles();
        assert_eq!(back.tile_count(), 0);
        assert_eq!(back, leaf_only);
        assert_eq!(back.inner_masks(), leaf_only.inner_masks());
        assert_eq!(back.leaf_colors().len(), leaf_only.leaf_colors().len());
    }
}

#[test]
fn carving_one_voxel_from_a_full_octree_splits_only_its_path() {
    let depth = 7;
    let v = paint(1, false);
    let e = 1u32 << depth;
    let mut svo = Svo::new(depth, false).unwrap().with_tiles();
    let r = svo
        .edit_region(UVec3::ZERO, UVec3::splat(e - 1), |_, _| Some(v))
        .unwrap();
    assert_eq!(r.delta.entries.len(), (e * e * e) as usize);
    assert_eq!((svo.tile_count(), svo.inner_count()), (1, 1));
    assert_eq!(svo.leaf_count(), u64::from(e).pow(3));
    assert_eq!(svo.memory_stats().leaf_bytes, 0);
    // Writing what a tile already holds changes nothing and leaves it whole, by every path.
    let same = svo.apply_changes([(UVec3::new(5, 6, 7), Some(v))]).unwrap();
    assert!(same.delta.is_empty());
    let same = svo
        .edit_region(UVec3::ONE, UVec3::splat(9), |_, old| old)
        .unwrap();
    assert!(same.delta.is_empty());
    svo.paint(UVec3::splat(3), v.color).unwrap();
    assert_eq!((svo.tile_count(), svo.inner_count()), (1, 1));
    let hole = UVec3::new(77, 3, 100);
    assert_eq!(svo.remove(hole).unwrap(), Some(v));
    assert_eq!(svo.get(hole), None);
    assert_eq!(svo.get(hole + UVec3::X), Some(v));
    let d = u64::from(depth);
    // Each level below the root has the split node's eight children: seven tiles and the one
    // split further; the last split leaves seven leaves.
    assert_eq!(svo.inner_count(), 1 + 8 * (d - 1));
    assert_eq!(svo.tile_count(), 7 * (d - 1));
    assert_eq!(
        svo.memory_stats().leaves - svo.memory_stats().tile_voxels,
        7
    );
    assert_collapsed_and_counted(&svo);
    svo.set(hole, v).unwrap();
    assert_eq!((svo.tile_count(), svo.inner_count()), (1, 1));
    assert_collapsed_and_counted(&svo);
    // At the deepest octree, a voxel in a full corner reads through one tile.
    let mut deep = Svo::new(MAX_DEPTH, false).unwrap().with_tiles();
    let far = UVec3::splat((1 << MAX_DEPTH) - 1);
    deep.edit_region(far - 7, far, |_, _| Some(v)).unwrap();
    assert_eq!(deep.tile_count(), 1);
    assert_eq!(deep.get(far - 3), Some(v));
    assert_eq!(deep.get(far - 8), None);
    assert_eq!(deep.bounds(), Some((far - 7, far)));
}

#[test]
fn a_value_whose_average_differs_from_itself_is_not_tiled() {
    // Joints listed lighter first: the average of eight copies reorders them.
    let v = Voxel {
        skin: Skin4 {
            joints: [5, 2, 0, 0],
            weights: [100, 155, 0, 0],
        },
        ..paint(0, false)
    };
    let mut tiled = Svo::new(3, true).unwrap().with_tiles();
    let mut leaf_only = Svo::new(3, true).unwrap().without_tiles();
    for svo in [&mut tiled, &mut leaf_only] {
        svo.edit_region(UVec3::ZERO, UVec3::splat(7), |_, _| Some(v))
            .unwrap();
    }
    assert_eq!(tiled.tile_count(), 0);
    assert_eq!(tiled, leaf_only);
}

#[test]
fn rays_and_boxes_read_tiles_as_their_voxels() {
    let leaf_only = Svo::from_voxels(6, false, ball(6, 25.0, false))
        .unwrap()
        .without_tiles();
    let tiled = leaf_only.clone().with_tiles();
    for (o, d) in [
        (DVec3::new(-5.0, 31.2, 30.7), DVec3::new(1.0, 0.01, 0.02)),
        (DVec3::new(32.5, 32.5, 32.5), DVec3::new(0.2, -1.0, 0.3)),
        (DVec3::new(70.0, 70.0, 70.0), DVec3::new(-1.0, -1.0, -1.0)),
        (DVec3::new(0.0, 0.0, 0.0), DVec3::new(0.0, 0.0, 1.0)),
    ] {
        assert_eq!(tiled.raycast(o, d, 1e9), leaf_only.raycast(o, d, 1e9));
    }
    let (lo, hi) = (UVec3::new(10, 20, 5), UVec3::new(40, 33, 60));
    let mut a = Vec::new();
    tiled.for_each_leaf_in(lo, hi, |c, v| a.push((c, v)));
    let mut b = Vec::new();
    leaf_only.for_each_leaf_in(lo, hi, |c, v| b.push((c, v)));
    assert_eq!(a, b);
    assert!(a.len() > 10_000);
    assert_eq!(tiled.coarsened(2).unwrap(), leaf_only.coarsened(2).unwrap());
}

/// One edit of the sequences below.
#[derive(Debug, Clone)]
pub(super) enum Op {
    /// Fill a box with one value (tiles form).
    Fill(UVec3, UVec3, u32),
    /// Carve a box.
    Carve(UVec3, UVec3),
    /// Recolour the solid voxels of a box by position (tiles split).
    Paint(UVec3, UVec3, u32),
    /// Set or clear scattered voxels in one pass.
    Scatter(Vec<(UVec3, bool)>, u32),
    /// Undo the last edit still undoable.
    Undo,
}

pub(super) fn arb_box() -> impl Strategy<Value = (UVec3, UVec3)> {
    (0u32..32, 0u32..32, 0u32..32, 0u32..20, 0u32..20, 0u32..20).prop_map(
        |(x, y, z, dx, dy, dz)| {
            let lo = UVec3::new(x, y, z);
            (lo, (lo + UVec3::new(dx, dy, dz)).min(UVec3::splat(31)))
        },
    )
}

pub(super) fn arb_op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (arb_box(), 0u32..3).prop_map(|((lo, hi), k)| Op::Fill(lo, hi, k)),
        arb_box().prop_map(|(lo, hi)| Op::Carve(lo, hi)),
        (arb_box(), 0u32..4).prop_map(|((lo, hi), k)| Op::Paint(lo, hi, k)),
        (
            proptest::collection::vec(((0u32..32, 0u32..32, 0u32..32), any::<bool>()), 1..40),
            0u32..3
        )
            .prop_map(|(v, k)| Op::Scatter(
                v.into_iter()
                    .map(|((x, y, z), s)| (UVec3::new(x, y, z), s))
                    .collect(),
                k
            )),
        Just(Op::Undo),
    ]
}

pub(super) fn apply(svo: &mut Svo, op: &Op, undo: &mut Vec<UndoDelta>, skin: bool) -> EditResult {
    match op {
        Op::Fill(lo, hi, k) => svo.edit_region(*lo, *hi, |_, _| Some(paint(*k, skin))),
        Op::Carve(lo, hi) => svo.edit_existing(*lo, *hi, |_, _| None),
        Op::Paint(lo, hi, k) => svo.edit_existing(*lo, *hi, |c, v| {
            Some(Voxel {
                color: [(c.x + c.y + *k) as u8 % 3 * 60, 1, 2, 255],
                ..v
            })
        }),
        Op::Scatter(items, k) => {
            svo.apply_changes(items.iter().map(|&(c, s)| (c, s.then(|| paint(*k, skin)))))
        }
        Op::Undo => {
            return EditResult {
                changed: None,
                delta: undo
                    .pop()
                    .map_or_else(UndoDelta::default, |d| svo.apply_delta(&d)),
            };
        }
    }
    .inspect(|r| undo.push(r.delta.clone()))
    .unwrap_or_default()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// Property: the same edits on a tiled and a leaf-only octree give equal octrees (voxels and
    /// every node's attributes), equal undo deltas and changed boxes after every step; the tiled
    /// one stays collapsed, and undoing everything restores the start exactly.
    #[test]
    fn tiled_and_leaf_only_octrees_agree_through_any_edits(
        ops in proptest::collection::vec(arb_op(), 1..10),
        skin in any::<bool>(),
    ) {
        let start = Svo::from_voxels(5, skin, ball(5, 13.0, skin)).unwrap();
        let mut leaf_only = start.clone().without_tiles();
        let mut tiled = start.clone().with_tiles();
        let (mut undo_a, mut undo_b) = (Vec::new(), Vec::new());
        for op in &ops {
            let a = apply(&mut tiled, op, &mut undo_a, skin);
            let b = apply(&mut leaf_only, op, &mut undo_b, skin);
            prop_assert_eq!(&a, &b, "{:?}", op);
            prop_assert_eq!(&tiled, &leaf_only, "{:?}", op);
            prop_assert_eq!(tiled.leaf_count(), leaf_only.leaf_count());
            assert_collapsed_and_counted(&tiled);
        }
        prop_assert_eq!(tiled.leaves(), leaf_only.leaves());
        let mut packed = tiled.clone();
        packed.compact();
        prop_assert_eq!(&packed, &leaf_only);
        assert_collapsed_and_counted(&packed);
        while let Some(d) = undo_a.pop() {
            tiled.apply_delta(&d);
        }
        prop_assert_eq!(&tiled, &start);
        assert_collapsed_and_counted(&tiled);
    }
}

/// Random runs of a depth-`depth` octree: each node is left empty, made a tile or a leaf, or
/// split, by a hash of `seed` and its place; values from a few colours and the interior mark,
/// so that some neighbours collapse into bigger tiles and some do not.
fn random_runs(depth: u8, seed: u64) -> Vec<(UVec3, u8, Voxel)> {
    fn visit(origin: UVec3, h: u8, seed: u64, out: &mut Vec<(UVec3, u8, Voxel)>) {
        let code = super::morton_encode(origin) ^ (u64::from(h) << 58);
        let r = (code ^ seed)
            .wrapping_mul(0x9e37_79b9_7f4a_7c15)
            .rotate_left(29)
            .wrapping_mul(0xbf58_476d_1ce4_e5b9)
            >> 40;
        let value = match r % 5 {
            0 => Voxel::INTERIOR,
            k => Voxel::new([k as u8 * 60, 20, 200, 255], Vec3::Z),
        };
        match (r >> 4) % 8 {
            0 | 1 => {}
            2 | 3 if h > 0 => out.push((origin, h, value)),
            _ if h == 0 => out.push((origin, 0, value)),
            _ => {
                for k in 0..8 {
                    visit(origin + octant_offset(k, 1 << (h - 1)), h - 1, seed, out);
                }
            }
        }
    }
    let mut out = Vec::new();
    visit(UVec3::ZERO, depth, seed, &mut out);
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Property: building from runs in one pass equals building the leaves and putting each
    /// tile in along its path: the same voxels, node attributes, counts and node layout.
    #[test]
    fn building_from_runs_equals_putting_each_tile_in(depth in 1u8..6, seed in any::<u64>()) {
        let runs = random_runs(depth, seed);
        let fast = Svo::from_runs(depth, false, runs.clone()).unwrap();
        let mut slow = Svo::from_voxels(
            depth,
            false,
            runs.iter().filter(|r| r.1 == 0).map(|r| (r.0, r.2)),
        )
        .unwrap();
        for &(origin, h, v) in runs.iter().filter(|r| r.1 > 0) {
            slow.put_tile(origin, h, v);
        }
        slow.compact();
        prop_assert_eq!(&fast, &slow);
        prop_assert_eq!(
            (fast.leaf_count(), fast.tile_count(), fast.inner_count()),
            (slow.leaf_count(), slow.tile_count(), slow.inner_count())
        );
        prop_assert_eq!(&fast.inner_mask, &slow.inner_mask);
        prop_assert_eq!(&fast.inner_first, &slow.inner_first);
        prop_assert_eq!(&fast.inner_attr.color, &slow.inner_attr.color);
        prop_assert_eq!(&fast.inner_attr.normal, &slow.inner_attr.normal);
        prop_assert_eq!(&fast.leaf_attr.color, &slow.leaf_attr.color);
        prop_assert_eq!(fast.may_have_interior(), slow.may_have_interior());
        assert_collapsed_and_counted(&fast);
    }
}

#[test]
fn a_root_tile_and_no_runs_build_from_runs() {
    let v = Voxel::new([9, 9, 9, 255], Vec3::Z);
    let whole = Svo::from_runs(4, false, [(UVec3::ZERO, 4, v)]).unwrap();
    assert_eq!((whole.tile_count(), whole.leaf_count()), (1, 4096));
    assert_eq!(whole.get(UVec3::new(15, 3, 7)), Some(v));
    let empty = Svo::from_runs(4, false, []).unwrap();
    assert!(empty.is_empty());
    assert_eq!(
        Svo::from_runs(4, false, [(UVec3::new(16, 0, 0), 0, v)]),
        Err(SvoError::OutOfBounds {
            coord: [16, 0, 0],
            extent: 16
        })
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Property: `voxels_in` counts what `for_each_leaf_in` visits, a tile's part of the box at
    /// once, on a tiled ball and boxes anywhere (partly or wholly outside the octree too).
    #[test]
    fn voxels_in_a_box_count_what_a_walk_of_the_box_visits(
        a in (0u32..40, 0u32..40, 0u32..40),
        b in (0u32..40, 0u32..40, 0u32..40),
    ) {
        let svo = Svo::from_voxels(5, false, ball(5, 13.0, false)).unwrap();
        prop_assert!(svo.tile_count() > 0);
        let (a, b) = (UVec3::new(a.0, a.1, a.2), UVec3::new(b.0, b.1, b.2));
        let (lo, hi) = (a.min(b), a.max(b));
        let mut walked = 0u64;
        svo.for_each_leaf_in(lo, hi, |_, _| walked += 1);
        prop_assert_eq!(svo.voxels_in(lo, hi), walked);
        prop_assert_eq!(svo.voxels_in(hi, lo), u64::from(hi == lo) * walked);
    }
}

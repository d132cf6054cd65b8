use glam::{DVec3, IVec3, UVec3, Vec3};
use proptest::prelude::*;

use super::*;

fn vox(r: u8, g: u8) -> Voxel {
    Voxel::new(
        [r, g, 7, 255],
        Vec3::new(f32::from(r) - 128.0, f32::from(g) - 100.0, 3.0),
    )
}

/// A hollow sphere shell of radius `r` voxels centred in a `2^depth` octree.
fn shell(depth: u8, r: f32) -> Vec<(UVec3, Voxel)> {
    let c = (1u32 << (depth - 1)) as f32;
    let lo = (c - r - 1.0).max(0.0) as u32;
    let hi = (c + r + 1.0) as u32;
    let mut out = Vec::new();
    for z in lo..=hi {
        for y in lo..=hi {
            for x in lo..=hi {
                let p = Vec3::new(x as f32, y as f32, z as f32) + 0.5 - c;
                if (p.length() - r).abs() <= 0.87 {
                    out.push((UVec3::new(x, y, z), vox(x as u8, y as u8)));
                }
            }
        }
    }
    out
}

#[test]
fn morton_round_trip_at_extremes() {
    for c in [
        UVec3::ZERO,
        UVec3::splat((1 << 21) - 1),
        UVec3::new(1, 2, 3),
        UVec3::new(2_097_151, 0, 1_048_576),
    ] {
        assert_eq!(morton_decode(morton_encode(c)), c);
    }
    assert_eq!(morton_encode(UVec3::new(1, 0, 0)), 1);
    assert_eq!(morton_encode(UVec3::new(0, 1, 0)), 2);
    assert_eq!(morton_encode(UVec3::new(0, 0, 1)), 4);
}

#[test]
fn normal_encoding_error_is_small() {
    let mut worst = 0.0f32;
    for i in 0..2000 {
        let a = i as f32 * 2.399_963;
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / 2000.0;
        let r = (1.0 - z * z).sqrt();
        let n = Vec3::new(r * a.cos(), r * a.sin(), z);
        let d = decode_normal(encode_normal(n));
        worst = worst.max(n.dot(d).clamp(-1.0, 1.0).acos().to_degrees());
    }
    assert!(worst < 1.6, "worst octahedral error {worst}°");
    assert_eq!(
        decode_normal(encode_normal(Vec3::ZERO)),
        decode_normal(encode_normal(Vec3::Z))
    );
    assert!(decode_normal(encode_normal(Vec3::NAN)).is_finite());
}

#[test]
fn skin_weights_normalise_to_255() {
    let s = Skin4::from_influences(&[
        (3, 0.2),
        (1, 0.3),
        (7, 0.0),
        (2, -1.0),
        (9, 0.1),
        (4, 0.25),
        (5, 0.15),
    ]);
    assert_eq!(s.weights.iter().map(|&w| u32::from(w)).sum::<u32>(), 255);
    assert_eq!(s.joints, [1, 4, 3, 5]);
    assert!(Skin4::from_influences(&[(0, 0.0), (1, f32::NAN)]).is_empty());
}

#[test]
fn build_then_get_every_voxel() {
    let voxels = shell(6, 20.0);
    let svo = Svo::from_voxels(6, false, voxels.clone()).unwrap();
    assert_eq!(svo.leaf_count(), voxels.len() as u64);
    for (c, v) in &voxels {
        assert_eq!(svo.get(*c), Some(*v));
    }
    assert_eq!(svo.get(UVec3::splat(32)), None, "shell interior is empty");
    let mut sorted = voxels.clone();
    sorted.sort_by_key(|e| morton_encode(e.0));
    assert_eq!(svo.leaves(), sorted);
}

#[test]
fn duplicates_last_wins_and_bounds_are_checked() {
    let svo =
        Svo::from_voxels(3, false, [(UVec3::ONE, vox(1, 1)), (UVec3::ONE, vox(2, 2))]).unwrap();
    assert_eq!(svo.get(UVec3::ONE), Some(vox(2, 2)));
    assert_eq!(svo.leaf_count(), 1);
    assert!(matches!(
        Svo::from_voxels(3, false, [(UVec3::new(8, 0, 0), vox(0, 0))]),
        Err(SvoError::OutOfBounds { .. })
    ));
    assert!(matches!(Svo::new(0, false), Err(SvoError::BadDepth(0))));
    assert!(matches!(Svo::new(22, false), Err(SvoError::BadDepth(22))));
}

#[test]
fn depth_21_set_get_near_the_far_corner() {
    let mut svo = Svo::new(MAX_DEPTH, false).unwrap();
    let far = UVec3::splat((1 << 21) - 1);
    let coords = [
        far,
        far - UVec3::X,
        UVec3::new(0, (1 << 21) - 1, 12345),
        UVec3::ZERO,
    ];
    for (i, &c) in coords.iter().enumerate() {
        svo.set(c, vox(i as u8, 1)).unwrap();
    }
    for (i, &c) in coords.iter().enumerate() {
        assert_eq!(svo.get(c), Some(vox(i as u8, 1)));
    }
    assert_eq!(svo.get(far - UVec3::Y), None);
    assert!(svo.set(UVec3::new(1 << 21, 0, 0), vox(0, 0)).is_err());
    let hit = svo
        .raycast(
            DVec3::new(2_097_151.5, 2_097_151.5, -10.0),
            DVec3::Z,
            f64::INFINITY,
        )
        .unwrap();
    assert_eq!(hit.coord, far);
    assert_eq!(hit.normal, IVec3::new(0, 0, -1));
    assert!((hit.t - (2_097_151.0 + 10.0)).abs() < 1e-6);
}

#[test]
fn internal_nodes_average_children() {
    let a = Voxel::new([255, 0, 0, 255], Vec3::X);
    let b = Voxel::new([0, 0, 255, 255], Vec3::Y);
    let svo = Svo::from_voxels(1, false, [(UVec3::ZERO, a), (UVec3::X, b)]).unwrap();
    let root = svo.node_voxel(&svo.root());
    // Linear average of pure red and pure blue is 0.5, which is 188 in sRGB.
    assert_eq!(root.color, [188, 0, 188, 255]);
    let n = root.normal_vec();
    assert!((n - Vec3::new(1.0, 1.0, 0.0).normalize_or_zero()).length() < 0.03);
}

#[test]
fn edits_match_a_fresh_build_and_undo_restores() {
    let voxels = shell(5, 10.0);
    let original = Svo::from_voxels(5, false, voxels).unwrap();
    let mut svo = original.clone();
    let r = svo
        .edit_region(UVec3::splat(10), UVec3::splat(20), |c, old| {
            if (c.x + c.y + c.z) % 3 == 0 {
                Some(vox(c.x as u8, 9))
            } else {
                old.filter(|_| c.x % 2 == 0)
            }
        })
        .unwrap();
    assert!(!r.delta.is_empty());
    let (lo, hi) = r.changed.unwrap();
    assert!(lo.cmpge(UVec3::splat(10)).all() && hi.cmple(UVec3::splat(20)).all());
    let fresh = Svo::from_voxels(5, false, svo.leaves()).unwrap();
    assert_eq!(
        svo, fresh,
        "edited tree equals the tree built from its voxels"
    );
    let redo = svo.apply_delta(&r.delta);
    assert_eq!(svo, original);
    svo.apply_delta(&redo);
    assert_eq!(svo, fresh);
}

#[test]
fn removing_everything_frees_the_tree() {
    let voxels = shell(5, 9.0);
    let mut svo = Svo::from_voxels(5, false, voxels).unwrap();
    svo.edit_existing(UVec3::ZERO, UVec3::splat(31), |_, _| None)
        .unwrap();
    assert!(svo.is_empty());
    assert_eq!(svo.inner_count(), 1);
    assert_eq!(svo, Svo::new(5, false).unwrap());
    assert!(svo.memory_stats().free_slots > 0);
    svo.compact();
    assert_eq!(svo.memory_stats().free_slots, 0);
}

#[test]
fn paint_and_remove_single_voxels() {
    let mut svo = Svo::new(4, false).unwrap();
    assert!(!svo.paint(UVec3::ONE, [1, 2, 3, 4]).unwrap());
    svo.set(UVec3::ONE, vox(5, 5)).unwrap();
    assert!(svo.paint(UVec3::ONE, [1, 2, 3, 4]).unwrap());
    assert_eq!(svo.get(UVec3::ONE).unwrap().color, [1, 2, 3, 4]);
    assert_eq!(
        svo.remove(UVec3::ONE).unwrap().map(|v| v.color),
        Some([1, 2, 3, 4])
    );
    assert_eq!(svo.remove(UVec3::ONE).unwrap(), None);
    assert!(svo.is_empty());
}

#[test]
fn skin_is_stored_and_merged_only_with_skin() {
    let skin = Skin4::from_influences(&[(2, 1.0)]);
    let v = Voxel { skin, ..vox(1, 1) };
    let with = Svo::from_voxels(2, true, [(UVec3::ZERO, v)]).unwrap();
    assert_eq!(with.get(UVec3::ZERO).unwrap().skin, skin);
    assert_eq!(with.node_voxel(&with.root()).skin, skin);
    let without = Svo::from_voxels(2, false, [(UVec3::ZERO, v)]).unwrap();
    assert!(without.get(UVec3::ZERO).unwrap().skin.is_empty());
}

#[test]
fn raycast_finds_the_nearest_voxel_and_its_face() {
    let voxels = shell(6, 20.0);
    let svo = Svo::from_voxels(6, false, voxels.clone()).unwrap();
    for dir in [
        DVec3::X,
        DVec3::NEG_X,
        DVec3::Y,
        DVec3::new(0.3, -0.2, 1.0),
        DVec3::new(-1.0, -1.0, -1.0),
    ] {
        let origin = DVec3::splat(32.2) - dir.normalize_or_zero() * 60.0;
        let hit = svo
            .raycast(origin, dir, f64::INFINITY)
            .expect("ray through the centre hits the shell");
        // Brute force: the smallest entry t over all voxels.
        let mut best = f64::INFINITY;
        for (c, _) in &voxels {
            let lo = c.as_dvec3();
            let (enter, exit, _) = query::tests_slab(origin, dir.recip(), lo, lo + 1.0);
            if enter <= exit && exit >= 0.0 {
                best = best.min(enter.max(0.0));
            }
        }
        assert!(
            (hit.t - best).abs() < 1e-9,
            "dir {dir}: {} vs {best}",
            hit.t
        );
        assert_eq!(hit.normal.as_dvec3().dot(dir).signum(), -1.0);
    }
    assert!(
        svo.raycast(DVec3::new(-5.0, -5.0, -5.0), DVec3::NEG_X, f64::INFINITY)
            .is_none()
    );
    assert!(svo.raycast(DVec3::ZERO, DVec3::ZERO, 1.0).is_none());
    assert!(svo.raycast(DVec3::NAN, DVec3::X, 1.0).is_none());
}

#[test]
fn traversal_is_front_to_back_and_respects_the_predicate() {
    let svo = Svo::from_voxels(
        3,
        false,
        (0..8).map(|i| (UVec3::new(i, i, i), vox(i as u8, 0))),
    )
    .unwrap();
    let mut order = Vec::new();
    svo.traverse(Vec3::new(-1.0, -1.0, -1.0), |n| {
        if svo.is_leaf(n) {
            order.push(n.origin.x);
        }
        true
    });
    assert_eq!(order, vec![7, 6, 5, 4, 3, 2, 1, 0]);
    let mut visited = 0;
    svo.traverse(Vec3::X, |n| {
        visited += 1;
        n.level < 1
    });
    assert_eq!(visited, 1 + 2, "root and its two occupied children");
}

#[test]
fn surface_models_stay_under_12_bytes_per_voxel() {
    let svo = Svo::from_voxels(7, false, shell(7, 50.0)).unwrap();
    let stats = svo.memory_stats();
    assert!(stats.bytes_per_leaf <= 12.0, "{stats:?}");
    assert_eq!(stats.free_slots, 0);
}

#[test]
fn from_fn_prunes_and_matches_from_voxels() {
    let voxels = shell(6, 20.0);
    let set: std::collections::HashMap<UVec3, Voxel> = voxels.iter().copied().collect();
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let svo = Svo::from_fn(
        6,
        false,
        |o, s| {
            let c = Vec3::splat(32.0);
            let closest = c.clamp(o.as_vec3(), (o + UVec3::splat(s)).as_vec3());
            let far = (o.as_vec3() + s as f32 * 0.5 - c).abs() + s as f32 * 0.5;
            (closest - c).length() <= 21.0 && far.length() >= 19.0
        },
        |c| {
            calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            set.get(&c).copied()
        },
    )
    .unwrap();
    assert_eq!(svo, Svo::from_voxels(6, false, voxels).unwrap());
    assert!(
        calls.into_inner() < 64 * 64 * 64 / 4,
        "pruning keeps work near the surface"
    );
}

fn arb_edit() -> impl Strategy<Value = (UVec3, UVec3, u8, u32)> {
    (
        0u32..32,
        0u32..32,
        0u32..32,
        0u32..6,
        0u32..6,
        0u32..6,
        0u8..4,
        any::<u32>(),
    )
        .prop_map(|(x, y, z, dx, dy, dz, kind, seed)| {
            (
                UVec3::new(x, y, z),
                UVec3::new((x + dx).min(31), (y + dy).min(31), (z + dz).min(31)),
                kind,
                seed,
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Property: any sequence of region edits, undone in reverse, restores the octree exactly;
    /// and the edited octree always equals a fresh build of its voxels.
    #[test]
    fn undo_restores_exactly(edits in proptest::collection::vec(arb_edit(), 1..12)) {
        let original = Svo::from_voxels(5, true, shell(5, 9.0).into_iter().map(|(c, v)| {
            (c, Voxel { skin: Skin4::from_influences(&[(c.x as u16 % 5, 0.7), (3, 0.3)]), ..v })
        })).unwrap();
        let mut svo = original.clone();
        let mut deltas = Vec::new();
        for (lo, hi, kind, seed) in edits {
            let r = svo.edit_region(lo, hi, |c, old| {
                let h = ((c.x * 73) ^ (c.y * 19) ^ (c.z * 7) ^ seed) % 5;
                match kind {
                    0 => Some(Voxel { skin: Skin4::from_influences(&[(h as u16, 1.0)]), ..vox(h as u8, 3) }),
                    1 => None,
                    2 => old.map(|v| Voxel { color: [h as u8, 1, 2, 255], ..v }),
                    _ => if h < 2 { None } else { old.or(Some(vox(9, h as u8))) },
                }
            }).unwrap();
            deltas.push(r.delta);
        }
        prop_assert_eq!(&svo, &Svo::from_voxels(5, true, svo.leaves()).unwrap());
        for d in deltas.iter().rev() {
            svo.apply_delta(d);
        }
        prop_assert_eq!(svo, original);
    }
}

#[test]
fn child_rank_counts_the_children_before_each_octant() {
    for mask in 0..=255u8 {
        for k in 0..8u8 {
            let below = (0..k).filter(|&j| mask & (1 << j) != 0).count() as u32;
            assert_eq!(child_rank(mask, k), below, "mask {mask:#010b}, octant {k}");
        }
    }
}

/// `edit_region` with the callback's values, written instead through the generic sorted path
/// (`apply_changes`): the reference for the bottom-up build of missing subtrees.
fn edit_via_apply_changes(
    svo: &mut Svo,
    lo: UVec3,
    hi: UVec3,
    f: impl Fn(UVec3, Option<Voxel>) -> Option<Voxel>,
) -> EditResult {
    let hi = hi.min(UVec3::splat(svo.extent() - 1));
    let mut changes = Vec::new();
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let c = UVec3::new(x, y, z);
                changes.push((c, f(c, svo.get(c))));
            }
        }
    }
    svo.apply_changes(changes).unwrap()
}

/// Both paths from the same start: same tree (structure, leaf and internal attributes), same
/// counts, same undo entries in the same (Morton) order, same changed box; undo restores.
fn assert_edit_matches_generic(
    start: &Svo,
    lo: UVec3,
    hi: UVec3,
    f: impl Fn(UVec3, Option<Voxel>) -> Option<Voxel>,
) {
    let mut fast = start.clone();
    let r = fast.edit_region(lo, hi, &f).unwrap();
    let mut generic = start.clone();
    let g = edit_via_apply_changes(&mut generic, lo, hi, &f);
    assert_eq!(fast, generic);
    assert_eq!(fast.leaf_count(), generic.leaf_count());
    assert_eq!(fast.inner_count(), generic.inner_count());
    assert_eq!(fast.leaves(), generic.leaves());
    assert_eq!(r.changed, g.changed);
    assert_eq!(r.delta, g.delta);
    assert_eq!(
        fast,
        Svo::from_voxels(fast.depth(), fast.has_skin(), fast.leaves()).unwrap()
    );
    let mut undone = fast.clone();
    undone.apply_delta(&r.delta);
    assert_eq!(&undone, start);
    assert_eq!(undone.leaves(), start.leaves());
}

#[test]
fn building_missing_subtrees_matches_the_generic_path() {
    let uniform = Voxel::new([200, 120, 40, 255], Vec3::Y);
    let skinned = |c: UVec3| Voxel {
        skin: Skin4::from_influences(&[(c.x as u16 % 3, 0.6), (4, 0.4)]),
        ..uniform
    };
    for has_skin in [false, true] {
        let empty = Svo::new(5, has_skin).unwrap();
        let shell = Svo::from_voxels(5, has_skin, shell(5, 9.0)).unwrap();
        for start in [&empty, &shell] {
            // A uniform solid (whole uniform subtrees), one clipped at the far faces, a
            // patterned one, and one that fills only empty cells.
            assert_edit_matches_generic(start, UVec3::splat(3), UVec3::splat(28), |_, _| {
                Some(uniform)
            });
            assert_edit_matches_generic(start, UVec3::new(17, 0, 9), UVec3::splat(40), |c, _| {
                Some(skinned(c))
            });
            assert_edit_matches_generic(start, UVec3::ZERO, UVec3::splat(31), |c, old| {
                if (c.x ^ c.y ^ c.z) % 3 == 0 {
                    Some(vox(c.x as u8, c.z as u8))
                } else {
                    old
                }
            });
            assert_edit_matches_generic(
                start,
                UVec3::new(2, 5, 1),
                UVec3::new(30, 26, 19),
                |c, old| old.or(Some(skinned(c))),
            );
        }
    }
    // Depth 21: a box against the far corner, and a single voxel at it.
    let max = (1u32 << MAX_DEPTH) - 1;
    let deep = Svo::from_voxels(MAX_DEPTH, false, [(UVec3::splat(max - 3), vox(1, 2))]).unwrap();
    assert_edit_matches_generic(&deep, UVec3::splat(max - 9), UVec3::splat(max), |_, _| {
        Some(uniform)
    });
    assert_edit_matches_generic(&deep, UVec3::splat(max), UVec3::splat(max), |_, _| {
        Some(vox(3, 4))
    });
    assert_edit_matches_generic(
        &Svo::new(MAX_DEPTH, true).unwrap(),
        UVec3::new(0, max - 5, 0),
        UVec3::new(12, max, 7),
        |c, _| Some(skinned(c)),
    );
}

#[test]
fn applying_a_sorted_delta_in_place_matches_the_sorting_path() {
    let start = Svo::from_voxels(5, true, shell(5, 9.0)).unwrap();
    let mut edited = start.clone();
    let r = edited
        .edit_region(UVec3::new(3, 0, 5), UVec3::splat(31), |c, old| {
            if (c.x + 2 * c.y + c.z) % 4 == 0 {
                None
            } else {
                old.or(Some(vox(c.z as u8, 1)))
            }
        })
        .unwrap();
    assert!(edited.is_sorted_unique_stored(&r.delta.entries));
    // Reversed, the same entries go through the sorting path.
    let reversed = UndoDelta {
        entries: r.delta.entries.iter().rev().copied().collect(),
    };
    assert!(!edited.is_sorted_unique_stored(&reversed.entries));
    let (mut fast, mut sorted) = (edited.clone(), edited.clone());
    let redo_fast = fast.apply_delta(&r.delta);
    let redo_sorted = sorted.apply_delta(&reversed);
    assert_eq!(fast, start);
    assert_eq!(sorted, start);
    assert_eq!(fast.leaves(), start.leaves());
    assert_eq!(redo_fast, redo_sorted);
    // Redo (also sorted) restores the edit.
    fast.apply_delta(&redo_fast);
    assert_eq!(fast, edited);
    // Unstored skin in a skinless octree, or a coordinate outside, takes the checked path.
    let plain = Svo::new(4, false).unwrap();
    let skinned = Voxel {
        skin: Skin4::ROOT,
        ..vox(1, 1)
    };
    assert!(!plain.is_sorted_unique_stored(&[(UVec3::ONE, Some(skinned))]));
    assert!(!plain.is_sorted_unique_stored(&[(UVec3::splat(16), None)]));
    let mut p = plain.clone();
    p.apply_delta(&UndoDelta {
        entries: vec![
            (UVec3::ONE, Some(skinned)),
            (UVec3::splat(16), Some(skinned)),
        ],
    });
    assert_eq!(p.get(UVec3::ONE), Some(vox(1, 1)));
    assert_eq!(p.leaf_count(), 1);
}

#[test]
fn overlapping_octants_match_a_per_octant_box_test() {
    let mut rng = 0x9e37_79b9_u32;
    let mut next = |m: u32| {
        rng ^= rng << 13;
        rng ^= rng >> 17;
        rng ^= rng << 5;
        rng % m
    };
    for half in [1u32, 2, 4, 8, 1 << 20] {
        for _ in 0..2000 {
            let origin = UVec3::new(next(4), next(4), next(4)) * 2 * half;
            let span = 8 * half + 2;
            let a = UVec3::new(next(span), next(span), next(span));
            let b = UVec3::new(next(span), next(span), next(span));
            let (lo, hi) = (a.min(b), a.max(b));
            let mut expected = 0u8;
            for k in 0..8u8 {
                let c_lo = origin + octant_offset(k, half);
                let c_hi = c_lo + UVec3::splat(half - 1);
                if c_lo.cmple(hi).all() && c_hi.cmpge(lo).all() {
                    expected |= 1 << k;
                }
            }
            assert_eq!(Svo::overlapping(origin, half, lo, hi), expected);
        }
    }
}

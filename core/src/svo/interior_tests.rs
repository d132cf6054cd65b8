//! Interior voxels follow their rule exactly: after any edit, every voxel an edit exposed holds
//! what a brute-force search for its nearest non-interior voxel gives, no interior voxel is left
//! exposed, tiled and voxel-by-voxel octrees agree, and undo restores the interior.

use std::collections::HashMap;

use glam::{IVec3, UVec3, Vec3};
use proptest::prelude::*;

use super::tile_tests::{Op, apply, arb_op, assert_collapsed_and_counted, paint};
use super::*;

/// A solid ball of radius `r` in a `2^depth` octree: voxels with all six face neighbours in the
/// ball are interior, the others a shell of colours and normals varying by position.
pub(super) fn solid_ball(depth: u8, r: f32) -> Vec<(UVec3, Voxel)> {
    let e = 1i32 << depth;
    let c = e as f32 / 2.0;
    let inside = |p: IVec3| {
        p.cmpge(IVec3::ZERO).all()
            && p.cmplt(IVec3::splat(e)).all()
            && (p.as_vec3() + 0.5 - c).length() <= r
    };
    let mut out = Vec::new();
    for z in 0..e {
        for y in 0..e {
            for x in 0..e {
                let p = IVec3::new(x, y, z);
                if !inside(p) {
                    continue;
                }
                let enclosed = FACE_NEIGHBOURS.iter().all(|&f| inside(p + f));
                let v = if enclosed {
                    Voxel::INTERIOR
                } else {
                    Voxel::new(
                        [(x * 8 % 256) as u8, (y * 8 % 256) as u8, (z * 5) as u8, 255],
                        p.as_vec3() + 0.5 - c,
                    )
                };
                out.push((p.as_uvec3(), v));
            }
        }
    }
    out
}

type Model = HashMap<UVec3, Voxel>;

/// The rule by brute force: every interior voxel of `after` with an empty face neighbour (or on
/// the boundary) takes the value of the nearest non-interior voxel among `after`'s and those
/// `before` held that `after` removed or made interior (distance, then Morton code).
fn reveal_by_brute_force(before: &Model, after: &mut Model, extent: i32) {
    let open = |m: &Model, p: UVec3| {
        FACE_NEIGHBOURS.iter().any(|&f| {
            let q = p.as_ivec3() + f;
            q.cmplt(IVec3::ZERO).any()
                || q.cmpge(IVec3::splat(extent)).any()
                || !m.contains_key(&q.as_uvec3())
        })
    };
    let exposed: Vec<UVec3> = after
        .iter()
        .filter(|(p, v)| v.is_interior() && open(after, **p))
        .map(|(p, _)| *p)
        .collect();
    if exposed.is_empty() {
        return;
    }
    let mut candidates: Vec<(UVec3, Voxel)> = after
        .iter()
        .filter(|(_, v)| !v.is_interior())
        .map(|(p, v)| (*p, *v))
        .collect();
    candidates.extend(
        before
            .iter()
            .filter(|(p, v)| !v.is_interior() && after.get(p).is_none_or(Voxel::is_interior))
            .map(|(p, v)| (*p, *v)),
    );
    let resolved: Vec<(UVec3, Voxel)> = exposed
        .iter()
        .map(|&p| {
            let best = candidates
                .iter()
                .min_by_key(|(q, _)| {
                    let d = p.as_ivec3() - q.as_ivec3();
                    (d.length_squared(), morton_encode(*q))
                })
                .expect("something to reveal from");
            (p, best.1)
        })
        .collect();
    after.extend(resolved);
}

/// `op` on the model, as the octree's tools define it.
fn apply_model(m: &mut Model, op: &Op, undo: &mut Vec<Model>, extent: i32) {
    let before = m.clone();
    let in_box = |p: UVec3, lo: UVec3, hi: UVec3| p.cmpge(lo).all() && p.cmple(hi).all();
    match op {
        Op::Fill(lo, hi, k) => {
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        m.insert(UVec3::new(x, y, z), paint(*k, false));
                    }
                }
            }
        }
        Op::Carve(lo, hi) => m.retain(|p, _| !in_box(*p, *lo, *hi)),
        Op::Paint(lo, hi, k) => {
            for (c, v) in m.iter_mut() {
                if in_box(*c, *lo, *hi) && !v.is_interior() {
                    v.color = [(c.x + c.y + *k) as u8 % 3 * 60, 1, 2, 255];
                }
            }
        }
        Op::Scatter(items, k) => {
            for &(c, s) in items {
                if s {
                    m.insert(c, paint(*k, false));
                } else {
                    m.remove(&c);
                }
            }
        }
        Op::Undo => {
            if let Some(prev) = undo.pop() {
                *m = prev;
            }
            return;
        }
    }
    reveal_by_brute_force(&before, m, extent);
    undo.push(before);
}

fn model_of(svo: &Svo) -> Model {
    svo.leaves().into_iter().collect()
}

/// No interior voxel has an empty face neighbour or lies on the boundary.
fn assert_enclosed(svo: &Svo) {
    let e = svo.extent() as i32;
    for (p, v) in svo.leaves() {
        if !v.is_interior() {
            continue;
        }
        for f in FACE_NEIGHBOURS {
            let q = p.as_ivec3() + f;
            assert!(
                q.cmpge(IVec3::ZERO).all() && q.cmplt(IVec3::splat(e)).all(),
                "interior voxel {p} on the boundary"
            );
            assert!(
                svo.get(q.as_uvec3()).is_some(),
                "interior voxel {p} open toward {q}"
            );
        }
    }
}

#[test]
fn the_interior_mark_is_no_normal_a_surface_can_have() {
    assert_ne!(
        encode_normal(decode_normal(INTERIOR_NORMAL)),
        INTERIOR_NORMAL
    );
    for i in 0..4000 {
        let t = i as f32 * 0.618_034;
        let z = (i as f32 / 2000.0) - 1.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let n = Vec3::new(
            r * (t * std::f32::consts::TAU).cos(),
            r * (t * std::f32::consts::TAU).sin(),
            z,
        );
        assert_ne!(encode_normal(n), INTERIOR_NORMAL, "{n}");
    }
    for n in [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ] {
        assert_ne!(encode_normal(n), INTERIOR_NORMAL, "{n}");
    }
    // Around −Z, where the four corners of the octahedral square meet (one of them is the
    // mark), in every quadrant and down to the smallest tilts.
    for sx in [-1.0f32, 1.0] {
        for sy in [-1.0f32, 1.0] {
            for k in 0..200 {
                let t = 1e-7 * 1.1f32.powi(k);
                let n = Vec3::new(sx * t, sy * t * 0.7, -1.0);
                assert_ne!(encode_normal(n), INTERIOR_NORMAL, "{n}");
            }
        }
    }
    assert!(Voxel::INTERIOR.is_interior());
    assert!(!Voxel::default().is_interior());
}

#[test]
fn interior_children_are_left_out_of_the_average() {
    let red = Voxel::new([200, 10, 10, 255], Vec3::X);
    let blue = Voxel::new([10, 10, 200, 255], Vec3::Y);
    let plain = |v: &[Voxel]| voxel::merge(v.iter().map(|v| (v.color, v.normal, v.material)), None);
    let mut mixed = vec![red, blue];
    mixed.extend([Voxel::INTERIOR; 6]);
    assert_eq!(plain(&mixed), plain(&[red, blue]));
    assert_eq!(plain(&[Voxel::INTERIOR; 8]), Voxel::INTERIOR);
    assert_eq!(plain(&[Voxel::INTERIOR; 3]), Voxel::INTERIOR);
    // A solid ball's inside is a few tiles of the mark; its root averages the shell alone.
    let ball = solid_ball(6, 27.0);
    let shell: Vec<(UVec3, Voxel)> = ball
        .iter()
        .copied()
        .filter(|e| !e.1.is_interior())
        .collect();
    let solid = Svo::from_voxels(6, false, ball.iter().copied()).unwrap();
    let hollow = Svo::from_voxels(6, false, shell).unwrap();
    assert_eq!(
        solid.node_voxel(&solid.root()),
        hollow.node_voxel(&hollow.root())
    );
    assert!(solid.may_have_interior() && !hollow.may_have_interior());
    let (m, h) = (solid.memory_stats(), hollow.memory_stats());
    assert!(m.tile_voxels > 50_000, "{m:?}");
    assert!(
        (m.total_bytes as f64) < 2.0 * h.total_bytes as f64,
        "solid {} B against its shell's {} B",
        m.total_bytes,
        h.total_bytes
    );
    assert_enclosed(&solid);
}

#[test]
fn a_carve_reveals_the_nearest_shell_voxel_and_undo_puts_the_interior_back() {
    let ball = solid_ball(6, 27.0);
    for tiled in [true, false] {
        let start = if tiled {
            Svo::from_voxels(6, false, ball.iter().copied())
                .unwrap()
                .with_tiles()
        } else {
            Svo::from_voxels(6, false, ball.iter().copied())
                .unwrap()
                .without_tiles()
        };
        let mut svo = start.clone();
        let before = model_of(&svo);
        // A sphere of radius 12 carved around a point on the ball's surface.
        let centre = Vec3::new(32.0 + 27.0, 32.0, 32.0);
        let r = svo
            .edit_existing(UVec3::new(40, 18, 18), UVec3::new(63, 46, 46), |c, v| {
                ((c.as_vec3() + 0.5 - centre).length() > 12.0).then_some(v)
            })
            .unwrap();
        let mut expect = before.clone();
        expect.retain(|c, _| (c.as_vec3() + 0.5 - centre).length() > 12.0);
        reveal_by_brute_force(&before, &mut expect, 64);
        let got = model_of(&svo);
        let revealed = got
            .iter()
            .filter(|(p, v)| before.get(p).is_some_and(Voxel::is_interior) && !v.is_interior())
            .count();
        assert!(revealed > 300, "{revealed} voxels revealed");
        assert_eq!(got, expect, "tiled: {tiled}");
        assert_enclosed(&svo);
        // Revealed voxels are in the undo delta and the changed box.
        let (lo, hi) = r.changed.unwrap();
        for (p, v) in &got {
            if before.get(p) != Some(v) {
                assert!(
                    p.cmpge(lo).all() && p.cmple(hi).all(),
                    "{p} outside the changed box"
                );
                assert!(
                    r.delta.entries.iter().any(|e| e.0 == *p),
                    "{p} not in the delta"
                );
            }
        }
        let redo = svo.apply_delta(&r.delta);
        assert_eq!(svo, start);
        assert_eq!(svo.tile_count(), start.tile_count());
        svo.apply_delta(&redo);
        assert_eq!(model_of(&svo), expect);
        // Recolouring keeps what it reads: an interior voxel has no colour, so it stays interior
        // (and the recoloured surface is what later reveals take).
        let tiles = svo.tile_count();
        let r = svo
            .edit_existing(UVec3::splat(20), UVec3::splat(40), |_, v| {
                Some(Voxel {
                    color: [255, 0, 0, 255],
                    ..v
                })
            })
            .unwrap();
        assert!(
            r.delta.is_empty(),
            "{} voxels changed",
            r.delta.entries.len()
        );
        assert_eq!(svo.tile_count(), tiles);
        // Writing a whole value over interior voxels stores it.
        let v = paint(2, false);
        svo.set(UVec3::splat(32), v).unwrap();
        assert_eq!(svo.get(UVec3::splat(32)), Some(v));
        assert_enclosed(&svo);
    }
}

#[test]
fn the_nearest_surface_search_agrees_with_brute_force() {
    let ball = solid_ball(5, 13.0);
    let svo = Svo::from_voxels(5, false, ball.iter().copied()).unwrap();
    let shell: Vec<&(UVec3, Voxel)> = ball.iter().filter(|e| !e.1.is_interior()).collect();
    for p in [
        UVec3::splat(16),
        UVec3::new(3, 16, 16),
        UVec3::new(0, 0, 0),
        UVec3::new(31, 2, 17),
        UVec3::new(16, 16, 5),
        UVec3::new(20, 11, 14),
    ] {
        let want = shell
            .iter()
            .min_by_key(|(q, _)| {
                let d = p.as_ivec3() - q.as_ivec3();
                (d.length_squared(), morton_encode(*q))
            })
            .map(|e| (e.0, e.1));
        assert_eq!(svo.nearest_surface(p), want, "{p}");
        assert_eq!(svo.clone().without_tiles().nearest_surface(p), want, "{p}");
    }
    assert_eq!(
        Svo::new(5, false).unwrap().nearest_surface(UVec3::ONE),
        None
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    /// Property: on a solid with an interior, any edits leave the octree equal to the rule
    /// applied by brute force, with no interior voxel exposed; tiled and voxel-by-voxel octrees
    /// agree step by step; undoing everything restores the start.
    #[test]
    fn edits_into_a_solid_reveal_exactly_what_the_rule_says(
        ops in proptest::collection::vec(arb_op(), 1..8),
    ) {
        let start = Svo::from_voxels(5, false, solid_ball(5, 13.0)).unwrap();
        let mut tiled = start.clone().with_tiles();
        let mut leaf_only = start.clone().without_tiles();
        let mut model = model_of(&start);
        let (mut undo_a, mut undo_b, mut undo_m) = (Vec::new(), Vec::new(), Vec::new());
        for op in &ops {
            let a = apply(&mut tiled, op, &mut undo_a, false);
            let b = apply(&mut leaf_only, op, &mut undo_b, false);
            apply_model(&mut model, op, &mut undo_m, 32);
            prop_assert_eq!(&a, &b, "{:?}", op);
            prop_assert_eq!(&tiled, &leaf_only, "{:?}", op);
            prop_assert!(model_of(&tiled) == model, "{:?}: octree differs from the rule", op);
            assert_enclosed(&tiled);
            assert_collapsed_and_counted(&tiled);
        }
        while let Some(d) = undo_a.pop() {
            tiled.apply_delta(&d);
        }
        prop_assert_eq!(&tiled, &start);
        prop_assert_eq!(tiled.tile_count(), start.clone().with_tiles().tile_count());
    }
}

/// Checks [`Svo::for_each_voxel_but_enclosed`] on `svo` against brute force: the visited
/// voxels and the skipped ranges' voxels are every voxel once, each visited with its value;
/// every skipped voxel is interior with six solid face neighbours; and the count agrees.
/// Returns how many voxels were skipped.
fn check_enclosed_walk(svo: &Svo) -> u64 {
    let all = model_of(svo);
    let mut seen: HashMap<UVec3, Voxel> = HashMap::new();
    let ranges = svo.for_each_voxel_but_enclosed(|c, v| {
        assert!(seen.insert(c, v).is_none(), "{c} visited twice");
    });
    assert!(
        ranges.ranges().windows(2).all(|w| w[0].1 <= w[1].0),
        "ranges sorted, apart"
    );
    let mut skipped = 0u64;
    for &(first, end) in ranges.ranges() {
        for code in first..end {
            let c = super::morton_decode(code);
            let v = all.get(&c).copied();
            assert!(v.is_some_and(|v| v.is_interior()), "{c} skipped but {v:?}");
            for f in FACE_NEIGHBOURS {
                let q = c.as_ivec3() + f;
                assert!(
                    q.min_element() >= 0 && all.contains_key(&q.as_uvec3()),
                    "{c} skipped beside an empty {q}"
                );
            }
            assert!(!seen.contains_key(&c), "{c} both visited and skipped");
            skipped += 1;
        }
    }
    assert_eq!(
        seen.len() as u64 + skipped,
        all.len() as u64,
        "every voxel once"
    );
    assert!(
        seen.iter().all(|(c, v)| all.get(c) == Some(v)),
        "values as stored"
    );
    assert_eq!(svo.voxels_but_enclosed(), seen.len() as u64);
    skipped
}

#[test]
fn a_solids_enclosed_interior_tiles_are_left_out_of_its_walk_and_nothing_else() {
    let solid = Svo::from_voxels(5, false, solid_ball(5, 13.0))
        .unwrap()
        .with_tiles();
    assert!(solid.tile_count() > 20);
    let skipped = check_enclosed_walk(&solid);
    assert!(skipped > 4_000, "{skipped} voxels skipped");
    // Voxel by voxel: no tiles, nothing skipped.
    assert_eq!(check_enclosed_walk(&solid.clone().without_tiles()), 0);
    // An interior tile with empty neighbours (a file may hold one; edits never leave one) is
    // walked voxel by voxel, as is a tile at the octree's edge.
    for origin in [UVec3::new(8, 8, 8), UVec3::ZERO, UVec3::new(24, 0, 8)] {
        let lone = Svo::from_runs(5, false, [(origin, 3, Voxel::INTERIOR)]).unwrap();
        assert_eq!(lone.tile_count(), 1);
        assert_eq!(check_enclosed_walk(&lone), 0, "{origin}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    /// Property: after any edits into a solid (carves, fills, paint, undo-able), the walk that
    /// leaves out enclosed interior tiles leaves out only enclosed interior voxels and visits
    /// every other voxel once; `box_is_solid` says what testing each voxel says.
    #[test]
    fn the_walk_skips_only_enclosed_interior_and_boxes_are_solid_as_their_voxels(
        ops in proptest::collection::vec(arb_op(), 0..6),
        boxes in proptest::collection::vec(((0u32..34, 0u32..34, 0u32..34), (0u32..12, 0u32..12, 0u32..12)), 1..24),
    ) {
        let mut svo = Svo::from_voxels(5, false, solid_ball(5, 13.0)).unwrap().with_tiles();
        let mut undo = Vec::new();
        for op in &ops {
            apply(&mut svo, op, &mut undo, false);
        }
        check_enclosed_walk(&svo);
        let all = model_of(&svo);
        for ((x, y, z), (dx, dy, dz)) in boxes {
            let (lo, hi) = (UVec3::new(x, y, z), UVec3::new(x + dx, y + dy, z + dz));
            let brute = hi.cmplt(UVec3::splat(32)).all()
                && (lo.z..=hi.z).all(|z| {
                    (lo.y..=hi.y).all(|y| (lo.x..=hi.x).all(|x| all.contains_key(&UVec3::new(x, y, z))))
                });
            prop_assert_eq!(svo.box_is_solid(lo, hi), brute, "{} {}", lo, hi);
        }
    }
}

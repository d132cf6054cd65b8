//! The dense commit's fast paths against the generic ones they replace, on small grids: the
//! bit-mask normal estimate with its all-solid shortcut against the per-neighbour estimator,
//! and box writes against the hash path (per-voxel `get`, `normal_from`, `apply_changes`).

use glam::{I64Vec3, UVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use super::normal_from;
use super::shapes::{
    Grid, NEW, Normals, OLD, WRITE, commit, commit_boxes, commit_shifted, commit_sparse,
    dense_normals, shifted_in_volume,
};
use super::tool_tests::{assert_normals_estimated, leaf_hash, undo_restores};
use crate::svo::{MAX_DEPTH, Svo, Voxel, encode_normal};

/// The estimate `commit_dense` made before the fast path: dilate the flips one cell by
/// scanning every cell, then run `normal_from` over grid lookups.
fn reference_normals(g: &Grid, flags: &[u8], normals: Normals) -> Vec<Option<u16>> {
    let cells = g.cells() as usize;
    let flipped = |k: usize| (flags[k] & OLD != 0) != (flags[k] & NEW != 0);
    (0..cells)
        .map(|k| {
            let f = flags[k];
            let c = g.coord(k);
            let dirty = flipped(k)
                || super::neighbour_dirs()
                    .iter()
                    .any(|&(o, _)| g.neighbour(c, o).is_some_and(flipped));
            if !dirty || f & NEW == 0 || (normals == Normals::Others && f & WRITE != 0) {
                return None;
            }
            let n = normal_from(|o| g.neighbour(c, o).is_some_and(|j| flags[j] & NEW != 0));
            Some(encode_normal(n))
        })
        .collect()
}

#[test]
fn dense_normals_match_the_per_neighbour_estimate() {
    let mut rng = Pcg64::seed_from_u64(19);
    for case in 0..300 {
        let dim = UVec3::new(
            rng.random_range(1..9),
            rng.random_range(1..9),
            rng.random_range(1..9),
        );
        let g = Grid::new(UVec3::splat(3), UVec3::splat(3) + dim - 1);
        // Mostly-solid grids exercise the all-solid shortcut, sparse ones the mask path.
        let solid_p = [0.2, 0.6, 0.97][case % 3];
        let flags: Vec<u8> = (0..g.cells())
            .map(|_| {
                let old = rng.random_bool(solid_p);
                let new = if rng.random_bool(0.1) { !old } else { old };
                (u8::from(old) * OLD)
                    | (u8::from(new) * NEW)
                    | (u8::from(old != new || rng.random_bool(0.2)) * WRITE)
            })
            .collect();
        for normals in [Normals::All, Normals::Others] {
            assert_eq!(
                dense_normals(&g, &flags, normals),
                reference_normals(&g, &flags, normals),
                "case {case}, {dim}, {normals:?}"
            );
        }
    }
    // A solid block whose inside has every neighbour: the shortcut's estimate.
    let g = Grid::new(UVec3::ZERO, UVec3::splat(6));
    let flags = vec![NEW | WRITE; g.cells() as usize];
    let out = dense_normals(&g, &flags, Normals::All);
    assert_eq!(out, reference_normals(&g, &flags, Normals::All));
    assert_eq!(
        out[g.idx(UVec3::splat(3))],
        Some(encode_normal(normal_from(|_| true)))
    );
}

fn ink(c: u8) -> Voxel {
    Voxel::new([c, 200 - c, 40, 255], Vec3::Y)
}

/// Scattered voxels of a few colours with arbitrary normals (so re-estimation shows).
fn scattered(depth: u8, n: usize, seed: u64) -> Svo {
    let mut rng = Pcg64::seed_from_u64(seed);
    let e = 1u32 << depth;
    let voxels: Vec<(UVec3, Voxel)> = (0..n)
        .map(|_| {
            let c = UVec3::new(
                rng.random_range(0..e),
                rng.random_range(0..e),
                rng.random_range(0..e),
            );
            (c, Voxel::new([9, 9, 9, 255], Vec3::X))
        })
        .collect();
    Svo::from_voxels(depth, false, voxels).unwrap()
}

/// `commit_boxes` (dense path, no cell list) against the hash path over the listed cells.
fn assert_boxes_match_generic(start: &Svo, boxes: &[(UVec3, UVec3)], only_into_empty: bool) {
    let v = ink(70);
    let mut fast = start.clone();
    let e = commit_boxes(&mut fast, boxes, v, only_into_empty, Normals::All, 3);
    let mut cells = Vec::new();
    for (l, h) in boxes {
        for z in l.z..=h.z {
            for y in l.y..=h.y {
                for x in l.x..=h.x {
                    cells.push((UVec3::new(x, y, z), Some(v)));
                }
            }
        }
    }
    let mut generic = start.clone();
    let r = commit_sparse(&mut generic, cells.clone(), only_into_empty, Normals::All);
    assert!(fast == generic, "{boxes:?}: same octree as the hash path");
    assert_eq!(leaf_hash(&fast), leaf_hash(&generic), "{boxes:?}");
    assert_eq!(e.changed, r.changed);
    assert_eq!(e.clipped, 3);
    let (mut a, mut b) = (e.delta.entries.clone(), r.delta.entries.clone());
    a.sort_by_key(|x| crate::svo::morton_encode(x.0));
    b.sort_by_key(|x| crate::svo::morton_encode(x.0));
    assert_eq!(a, b, "{boxes:?}: same undo entries");
    // The listed cells through the dense list path agree too.
    let mut listed = start.clone();
    let l = commit(&mut listed, cells, only_into_empty, Normals::All, 3);
    assert!(listed == fast);
    assert_eq!(l.delta, e.delta);
    undo_restores(fast, start, &e.delta);
}

#[test]
fn box_writes_match_the_generic_path() {
    for start in [Svo::new(5, false).unwrap(), scattered(5, 600, 4)] {
        let u = UVec3::new;
        for only_into_empty in [true, false] {
            for boxes in [
                vec![(u(4, 5, 6), u(20, 11, 27))],
                // Against every face of the volume, so the grid is clipped there.
                vec![(u(0, 0, 0), u(31, 31, 31))],
                vec![(u(0, 3, 0), u(6, 31, 31))],
                // Mirrored copies: overlapping and apart.
                vec![
                    (u(10, 10, 10), u(18, 14, 12)),
                    (u(13, 10, 10), u(21, 14, 12)),
                ],
                vec![(u(1, 1, 1), u(3, 2, 2)), (u(28, 1, 1), u(30, 2, 2))],
                vec![(u(7, 7, 7), u(7, 7, 7))],
            ] {
                assert_boxes_match_generic(&start, &boxes, only_into_empty);
            }
        }
    }
    let mut solid = Svo::new(4, false).unwrap();
    commit_boxes(
        &mut solid,
        &[(UVec3::ZERO, UVec3::splat(15))],
        ink(3),
        true,
        Normals::All,
        0,
    );
    assert_normals_estimated(&solid);
    // Depth 21: boxes at the far corner and at the origin.
    let max = (1u32 << MAX_DEPTH) - 1;
    let deep = Svo::from_voxels(MAX_DEPTH, false, [(UVec3::splat(max - 2), ink(1))]).unwrap();
    assert_boxes_match_generic(&deep, &[(UVec3::splat(max - 6), UVec3::splat(max))], true);
    assert_boxes_match_generic(
        &deep,
        &[(UVec3::new(0, max - 4, 0), UVec3::new(5, max, 3))],
        false,
    );
}

/// `commit_shifted` (dense path, no cell list) against the hash path over the listed cells.
fn assert_shifted_matches_generic(start: &Svo, voxels: &[(UVec3, Voxel)], at: I64Vec3) {
    let size = UVec3::splat(start.extent());
    for only_into_empty in [true, false] {
        let mut fast = start.clone();
        let e = commit_shifted(&mut fast, voxels, at, size, only_into_empty, Normals::All);
        let cells: Vec<_> = voxels
            .iter()
            .filter_map(|(r, v)| shifted_in_volume(at, *r, size).map(|c| (c, Some(*v))))
            .collect();
        let clipped = (voxels.len() - cells.len()) as u64;
        assert_eq!(e.clipped, clipped);
        let mut generic = start.clone();
        let r = commit_sparse(&mut generic, cells.clone(), only_into_empty, Normals::All);
        assert!(fast == generic, "at {at}: same octree as the hash path");
        assert_eq!(leaf_hash(&fast), leaf_hash(&generic), "at {at}");
        assert_eq!(e.changed, r.changed);
        let (mut a, mut b) = (e.delta.entries.clone(), r.delta.entries.clone());
        a.sort_by_key(|x| crate::svo::morton_encode(x.0));
        b.sort_by_key(|x| crate::svo::morton_encode(x.0));
        assert_eq!(a, b, "at {at}: same undo entries");
        let mut listed = start.clone();
        let l = commit(&mut listed, cells, only_into_empty, Normals::All, clipped);
        assert!(listed == fast);
        assert_eq!(l.delta, e.delta);
        undo_restores(fast, start, &e.delta);
    }
}

#[test]
fn shifted_writes_match_the_generic_path() {
    // A clipboard of varied voxels with holes, listed in Morton order of its own cells.
    let mut rng = Pcg64::seed_from_u64(7);
    let mut clip: Vec<(UVec3, Voxel)> = Vec::new();
    for m in 0..(10u64 * 10 * 10 * 8) {
        let r = crate::svo::morton_decode(m);
        if r.max_element() < 10 && rng.random_bool(0.8) {
            clip.push((r, ink(rng.random_range(0..200))));
        }
    }
    for start in [Svo::new(5, false).unwrap(), scattered(5, 600, 5)] {
        for at in [
            I64Vec3::new(4, 9, 13),
            // Hanging out of the volume on the low and the high side.
            I64Vec3::new(-3, 0, -7),
            I64Vec3::new(25, 28, 22),
            I64Vec3::new(-40, 0, 0),
        ] {
            assert_shifted_matches_generic(&start, &clip, at);
        }
    }
    // Depth 21: against the far corner.
    let max = i64::from((1u32 << MAX_DEPTH) - 1);
    let deep = Svo::from_voxels(
        MAX_DEPTH,
        false,
        [(UVec3::splat((1 << MAX_DEPTH) - 4), ink(1))],
    )
    .unwrap();
    assert_shifted_matches_generic(&deep, &clip, I64Vec3::splat(max - 6));
}

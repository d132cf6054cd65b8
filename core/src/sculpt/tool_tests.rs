//! Exact-set tests of the voxel tools (shapes, selections, model operations, palettes).

use std::collections::BTreeSet;
use std::hash::{Hash, Hasher};

use glam::{IVec3, Mat4, UVec3, Vec2, Vec3};

use super::estimate_normal;
use super::select::*;
use super::shapes::{
    Ink, Mirror, ShapeOp, ToolError, apply_box, apply_cells, extrude, extrude_cells,
};
use super::shapes::{face_region, flood_region, line_cells};
use crate::svo::{Svo, Voxel, encode_normal};

pub(super) const RED: Ink = Ink {
    color: [255, 0, 0, 255],
    material: 0,
};
pub(super) const BLUE: Ink = Ink {
    color: [0, 0, 255, 255],
    material: 1,
};

pub(super) fn cells(svo: &Svo) -> BTreeSet<[u32; 3]> {
    svo.leaves().iter().map(|(c, _)| c.to_array()).collect()
}

pub(super) fn box_set(lo: [u32; 3], hi: [u32; 3]) -> BTreeSet<[u32; 3]> {
    let mut s = BTreeSet::new();
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                s.insert([x, y, z]);
            }
        }
    }
    s
}

pub(super) fn leaf_hash(svo: &Svo) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for (c, v) in svo.leaves() {
        c.to_array().hash(&mut h);
        v.hash(&mut h);
    }
    h.finish()
}

/// Every voxel's normal is what the brushes' estimator gives for the final occupancy.
pub(super) fn assert_normals_estimated(svo: &Svo) {
    for (c, v) in svo.leaves() {
        assert_eq!(
            v.normal,
            encode_normal(estimate_normal(svo, c)),
            "normal of {c} is stale"
        );
    }
}

pub(super) fn undo_restores(mut svo: Svo, before: &Svo, delta: &crate::svo::UndoDelta) {
    let hash = leaf_hash(before);
    svo.apply_delta(delta);
    assert!(svo == *before, "undo restores the octree");
    assert_eq!(leaf_hash(&svo), hash);
}

const NO_MIRROR: Mirror = Mirror { axes: [false; 3] };

fn add_box(svo: &mut Svo, lo: [i32; 3], hi: [i32; 3], ink: Ink) -> super::ToolEdit {
    let size = UVec3::splat(svo.extent());
    apply_box(
        svo,
        size,
        IVec3::from_array(lo),
        IVec3::from_array(hi),
        ShapeOp::Add,
        ink,
        NO_MIRROR,
        None,
    )
}

#[test]
fn box_3x4x5_is_exactly_60_voxels_and_undoes() {
    let mut svo = Svo::new(4, false).unwrap();
    let empty = svo.clone();
    // Corners in reverse order on one axis.
    let e = add_box(&mut svo, [2, 6, 4], [4, 3, 8], RED);
    assert_eq!(svo.leaf_count(), 60);
    assert_eq!(cells(&svo), box_set([2, 3, 4], [4, 6, 8]));
    assert_eq!(e.changed, Some((UVec3::new(2, 3, 4), UVec3::new(4, 6, 8))));
    assert_eq!(e.clipped, 0);
    assert!(svo.leaves().iter().all(|(_, v)| v.color == RED.color));
    assert_normals_estimated(&svo);
    // A corner voxel's normal points out of the corner.
    let n = svo.get(UVec3::new(2, 3, 4)).unwrap().normal_vec();
    assert!(n.x < -0.4 && n.y < -0.4 && n.z < -0.4, "{n}");
    undo_restores(svo, &empty, &e.delta);
}

#[test]
fn box_add_keeps_existing_voxels_and_renormals_neighbours() {
    let mut svo = Svo::new(4, false).unwrap();
    add_box(&mut svo, [0, 0, 0], [7, 0, 7], BLUE);
    let before = svo.clone();
    let e = add_box(&mut svo, [2, 0, 2], [4, 2, 4], RED);
    // The floor cells inside the box stay blue; only the 2 layers above are new.
    assert_eq!(svo.get(UVec3::new(3, 0, 3)).unwrap().color, BLUE.color);
    assert_eq!(svo.get(UVec3::new(3, 1, 3)).unwrap().color, RED.color);
    assert_eq!(svo.leaf_count(), 64 + 18);
    assert_normals_estimated(&svo);
    undo_restores(svo, &before, &e.delta);
}

/// Parametric DDA sampled at every step of the driving axis, in floating point, rounding half
/// up: an implementation independent of the integer one under test.
fn dda_reference(a: IVec3, b: IVec3) -> Vec<IVec3> {
    let d = (b - a).as_dvec3();
    let n = (b - a).abs().max_element();
    if n == 0 {
        return vec![a];
    }
    (0..=n)
        .map(|k| {
            let p = a.as_dvec3() + d * f64::from(k) / f64::from(n);
            IVec3::new(
                (p.x + 0.5).floor() as i32,
                (p.y + 0.5).floor() as i32,
                (p.z + 0.5).floor() as i32,
            )
        })
        .collect()
}

/// Classic integer 3D Bresenham (error terms per minor axis); agrees with the line wherever no
/// rounding tie occurs.
fn bresenham(a: IVec3, b: IVec3) -> Vec<IVec3> {
    let d = (b - a).abs();
    let s = (b - a).signum();
    let major = if d.x >= d.y && d.x >= d.z {
        0
    } else if d.y >= d.z {
        1
    } else {
        2
    };
    let n = d[major];
    let mut p = a;
    let mut err = [0i32; 3];
    for ax in 0..3 {
        err[ax] = 2 * d[ax] - n;
    }
    let mut out = vec![p];
    for _ in 0..n {
        p[major] += s[major];
        for ax in 0..3 {
            if ax == major {
                continue;
            }
            if err[ax] > 0 {
                p[ax] += s[ax];
                err[ax] -= 2 * n;
            }
            err[ax] += 2 * d[ax];
        }
        out.push(p);
    }
    out
}

#[test]
fn lines_match_references_in_every_octant() {
    let base = [
        (7, 3, 5),
        (3, 7, 5),
        (5, 3, 7),
        (6, 6, 6),
        (4, 1, 0),
        (0, 0, 9),
        (8, 4, 2),
    ];
    let a = IVec3::new(10, -4, 3);
    for (x, y, z) in base {
        for signs in 0..8 {
            let sx = if signs & 1 != 0 { -1 } else { 1 };
            let sy = if signs & 2 != 0 { -1 } else { 1 };
            let sz = if signs & 4 != 0 { -1 } else { 1 };
            let b = a + IVec3::new(x * sx, y * sy, z * sz);
            let line = line_cells(a, b);
            assert_eq!(line, dda_reference(a, b), "{a} -> {b}");
            let n = (b - a).abs().max_element();
            assert_eq!(line.len() as i32, n + 1);
            assert_eq!((line[0], line[line.len() - 1]), (a, b));
            for w in line.windows(2) {
                assert_eq!((w[1] - w[0]).abs().max_element(), 1, "26-connected");
            }
            let mut back = line_cells(b, a);
            back.reverse();
            assert_eq!(back, line, "symmetric {a} <-> {b}");
        }
    }
    // Lines with odd lengths on every axis have no ties: the classic algorithm agrees.
    for b in [
        IVec3::new(17, 3, 5),
        IVec3::new(-17, 5, -3),
        IVec3::new(3, -17, 7),
    ] {
        assert_eq!(line_cells(a, a + b), bresenham(a, a + b), "{b}");
    }
    assert_eq!(line_cells(a, a), vec![a]);
}

#[test]
fn lines_apply_with_clipping() {
    let mut svo = Svo::new(4, false).unwrap();
    let size = UVec3::new(10, 10, 10);
    let line = line_cells(IVec3::new(-3, 0, 0), IVec3::new(12, 5, 5));
    let e = apply_cells(&mut svo, size, &line, ShapeOp::Add, RED, NO_MIRROR, None);
    let inside: BTreeSet<[u32; 3]> = line
        .iter()
        .filter(|c| c.min_element() >= 0 && c.max_element() < 10)
        .map(|c| c.as_uvec3().to_array())
        .collect();
    assert_eq!(cells(&svo), inside);
    assert_eq!(e.clipped, (line.len() - inside.len()) as u64);
    assert!(e.clipped >= 5);
}

/// A 6×6×1 slab: left half red, right half blue, plus a red voxel on top of the blue half.
fn two_colour_slab() -> Svo {
    let mut v = Vec::new();
    for z in 0..6 {
        for x in 0..6 {
            let ink = if x < 3 { RED } else { BLUE };
            v.push((UVec3::new(x, 0, z), Voxel::new(ink.color, Vec3::Y)));
        }
    }
    v.push((UVec3::new(4, 1, 2), Voxel::new(RED.color, Vec3::Y)));
    v.push((UVec3::new(1, 1, 1), Voxel::new(RED.color, Vec3::Y)));
    Svo::from_voxels(4, false, v).unwrap()
}

#[test]
fn flood_stops_at_colour_borders_and_respects_plane() {
    let svo = two_colour_slab();
    let size = UVec3::splat(16);
    let red: BTreeSet<[u32; 3]> = flood_region(&svo, size, UVec3::new(0, 0, 0), None)
        .iter()
        .map(|c| c.to_array())
        .collect();
    let mut expect = box_set([0, 0, 0], [2, 0, 5]);
    expect.insert([1, 1, 1]);
    assert_eq!(
        red, expect,
        "the red voxel on the blue half is not connected"
    );
    let plane: BTreeSet<[u32; 3]> = flood_region(&svo, size, UVec3::new(0, 0, 0), Some(1))
        .iter()
        .map(|c| c.to_array())
        .collect();
    assert_eq!(plane, box_set([0, 0, 0], [2, 0, 5]));
    let blue = flood_region(&svo, size, UVec3::new(5, 0, 5), None);
    assert_eq!(blue.len(), 18);
    assert!(flood_region(&svo, size, UVec3::new(9, 9, 9), None).is_empty());
    // A material change is a border too.
    let mut svo2 = svo.clone();
    svo2.set(
        UVec3::new(1, 0, 3),
        Voxel {
            material: 4,
            ..Voxel::new(RED.color, Vec3::Y)
        },
    )
    .unwrap();
    assert_eq!(flood_region(&svo2, size, UVec3::ZERO, Some(1)).len(), 17);
    // The volume limits the flood.
    assert_eq!(
        flood_region(&svo, UVec3::new(2, 16, 16), UVec3::ZERO, Some(1)).len(),
        12
    );
}

/// Floor at y = 0 for x < 4 and a step at y = 0..=1 for x in 4..8, z in 0..8.
fn stepped() -> Svo {
    let mut v = Vec::new();
    for z in 0..8 {
        for x in 0..8 {
            v.push((UVec3::new(x, 0, z), Voxel::new(RED.color, Vec3::Y)));
            if x >= 4 {
                v.push((UVec3::new(x, 1, z), Voxel::new(RED.color, Vec3::Y)));
            }
        }
    }
    estimated(Svo::from_voxels(4, false, v).unwrap())
}

fn set_of(c: &[UVec3]) -> BTreeSet<[u32; 3]> {
    c.iter().map(|c| c.to_array()).collect()
}

#[test]
fn face_region_on_a_stepped_surface() {
    let svo = stepped();
    let size = UVec3::splat(16);
    let low = face_region(&svo, size, UVec3::new(1, 0, 1), IVec3::Y);
    assert_eq!(set_of(&low), box_set([0, 0, 0], [3, 0, 7]));
    let high = face_region(&svo, size, UVec3::new(5, 1, 1), IVec3::Y);
    assert_eq!(set_of(&high), box_set([4, 1, 0], [7, 1, 7]));
    assert!(
        face_region(&svo, size, UVec3::new(5, 0, 1), IVec3::Y).is_empty(),
        "covered"
    );
    // The riser: x = 3 faces +X only at y = 0, where x = 4 is solid: covered.
    assert!(face_region(&svo, size, UVec3::new(3, 0, 1), IVec3::X).is_empty());
    let riser = face_region(&svo, size, UVec3::new(4, 1, 1), IVec3::NEG_X);
    assert_eq!(set_of(&riser), box_set([4, 1, 0], [4, 1, 7]));
    // The bottom faces the outside of the volume.
    let bottom = face_region(&svo, size, UVec3::new(4, 0, 1), IVec3::NEG_Y);
    assert_eq!(bottom.len(), 64);
    assert!(face_region(&svo, size, UVec3::new(9, 9, 9), IVec3::Y).is_empty());
    assert!(face_region(&svo, size, UVec3::new(1, 0, 1), IVec3::new(1, 1, 0)).is_empty());
}

#[test]
fn extrude_plus_two_and_minus_one_are_exact() {
    let mut svo = stepped();
    let size = UVec3::splat(16);
    let before = svo.clone();
    let face = face_region(&svo, size, UVec3::new(1, 0, 1), IVec3::Y);
    let planned: BTreeSet<[u32; 3]> = extrude_cells(&face, IVec3::Y, 2)
        .iter()
        .map(|c| c.as_uvec3().to_array())
        .collect();
    assert_eq!(planned, box_set([0, 1, 0], [3, 2, 7]));
    let e = extrude(&mut svo, size, &face, IVec3::Y, 2, None);
    let mut expect = cells(&before);
    expect.extend(box_set([0, 1, 0], [3, 2, 7]));
    assert_eq!(cells(&svo), expect);
    assert_normals_estimated(&svo);
    undo_restores(svo.clone(), &before, &e.delta);

    let mut svo = before.clone();
    let face = face_region(&svo, size, UVec3::new(5, 1, 1), IVec3::Y);
    let e = extrude(&mut svo, size, &face, IVec3::Y, -1, None);
    let mut expect = cells(&before);
    for c in box_set([4, 1, 0], [7, 1, 7]) {
        expect.remove(&c);
    }
    assert_eq!(cells(&svo), expect);
    undo_restores(svo, &before, &e.delta);

    // Copies attributes of the face voxel; clipped at the volume's top.
    let mut svo = before.clone();
    let face = face_region(&svo, size, UVec3::new(5, 1, 1), IVec3::Y);
    let e = extrude(&mut svo, UVec3::new(16, 3, 16), &face, IVec3::Y, 3, None);
    assert_eq!(e.clipped, 32 * 2);
    assert_eq!(svo.get(UVec3::new(5, 2, 1)).unwrap().color, RED.color);
    let unchanged = extrude(&mut svo, size, &face, IVec3::Y, 0, None);
    assert!(unchanged.changed.is_none());
    assert!(matches!(
        extrude(&mut svo, size, &face, IVec3::new(0, 2, 0), 1, None).refused,
        Some(ToolError::BadNormal(_))
    ));
}

/// An asymmetric shape with odd and even bounds: a 3×2×4 block of distinct colours, minus
/// three cells.
fn asymmetric(origin: UVec3) -> Svo {
    let mut v = Vec::new();
    for z in 0..4u32 {
        for y in 0..2u32 {
            for x in 0..3u32 {
                if (x, y, z) == (0, 1, 3) || (x, y, z) == (2, 0, 0) || (x, y, z) == (1, 1, 2) {
                    continue;
                }
                let color = [x as u8 * 80, y as u8 * 120, z as u8 * 60, 255];
                v.push((origin + UVec3::new(x, y, z), Voxel::new(color, Vec3::Y)));
            }
        }
    }
    estimated(Svo::from_voxels(5, false, v).unwrap())
}

/// The octree with every normal estimated from its occupancy, so tests can check that edits
/// keep them consistent.
pub(super) fn estimated(mut svo: Svo) -> Svo {
    let normals: Vec<_> = svo
        .leaves()
        .iter()
        .map(|(c, v)| {
            (
                *c,
                Some(Voxel {
                    normal: encode_normal(estimate_normal(&svo, *c)),
                    ..*v
                }),
            )
        })
        .collect();
    svo.apply_changes(normals).unwrap();
    svo
}

fn colours(svo: &Svo) -> Vec<(UVec3, [u8; 4])> {
    svo.leaves().iter().map(|(c, v)| (*c, v.color)).collect()
}

#[test]
fn rotate_four_times_and_flip_twice_are_identity() {
    let size = UVec3::splat(32);
    for axis in 0..3 {
        let mut svo = asymmetric(UVec3::new(10, 11, 9));
        let original = svo.clone();
        let mut sel = invert(&svo, &VoxelSelection::default()).expect("under the listing limit");
        let (lo, hi) = sel.bounds().unwrap();
        let pivot = rotation_pivot(lo, hi, axis);
        let mut deltas = Vec::new();
        for turn in 0..4 {
            let (e, next) = transform_selection(
                &mut svo,
                size,
                &sel,
                SelTransform::Rotate {
                    axis,
                    quarter_turns: 1,
                },
                pivot,
            );
            assert_eq!(e.clipped, 0);
            assert_eq!(next.len(), sel.len());
            assert_eq!(cells(&svo), set_of(&next.iter().collect::<Vec<_>>()));
            if turn == 0 {
                assert_ne!(colours(&svo), colours(&original));
                let (nlo, nhi) = next.bounds().unwrap();
                let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
                assert_eq!(nhi[u] - nlo[u], hi[w] - lo[w], "extents swap");
                assert_eq!(nhi[w] - nlo[w], hi[u] - lo[u]);
            }
            deltas.push(e.delta);
            sel = next;
        }
        assert_eq!(colours(&svo), colours(&original), "axis {axis}");
        for (c, v) in svo.leaves() {
            let (a, b) = (v.normal_vec(), original.get(c).unwrap().normal_vec());
            // Four octahedral re-encodings (about 1.4° each at worst).
            assert!(a.dot(b) > 0.99, "normal at {c}: {a} vs {b}");
        }
        // Undo all four turns.
        for d in deltas.iter().rev() {
            svo.apply_delta(d);
        }
        assert!(svo == original);
    }
    // -1 turn undoes +1 turn.
    let mut svo = asymmetric(UVec3::new(10, 11, 9));
    let original = svo.clone();
    let sel = invert(&svo, &VoxelSelection::default()).expect("under the listing limit");
    let (lo, hi) = sel.bounds().unwrap();
    let p = rotation_pivot(lo, hi, 1);
    let (_, s1) = transform_selection(
        &mut svo,
        size,
        &sel,
        SelTransform::Rotate {
            axis: 1,
            quarter_turns: 1,
        },
        p,
    );
    transform_selection(
        &mut svo,
        size,
        &s1,
        SelTransform::Rotate {
            axis: 1,
            quarter_turns: -1,
        },
        p,
    );
    assert_eq!(colours(&svo), colours(&original));

    for axis in 0..3 {
        let mut svo = asymmetric(UVec3::new(10, 11, 9));
        let sel = invert(&svo, &VoxelSelection::default()).expect("under the listing limit");
        let (_, s1) =
            transform_selection(&mut svo, size, &sel, SelTransform::Flip(axis), IVec3::ZERO);
        assert_eq!(s1.bounds(), sel.bounds(), "flip stays in its bounds");
        assert_ne!(colours(&svo), colours(&original));
        transform_selection(&mut svo, size, &s1, SelTransform::Flip(axis), IVec3::ZERO);
        assert_eq!(colours(&svo), colours(&original));
    }
}

#[test]
fn rotation_is_right_handed() {
    // About Z a quarter turn takes +X to +Y.
    let mut svo = Svo::new(4, false).unwrap();
    svo.set(UVec3::new(5, 5, 5), Voxel::new(RED.color, Vec3::Y))
        .unwrap();
    svo.set(UVec3::new(6, 5, 5), Voxel::new(BLUE.color, Vec3::X))
        .unwrap();
    let sel = invert(&svo, &VoxelSelection::default()).expect("under the listing limit");
    let pivot = IVec3::new(11, 11, 11); // centre of cell (5,5,5)
    transform_selection(
        &mut svo,
        UVec3::splat(16),
        &sel,
        SelTransform::Rotate {
            axis: 2,
            quarter_turns: 1,
        },
        pivot,
    );
    assert_eq!(svo.get(UVec3::new(5, 6, 5)).unwrap().color, BLUE.color);
    assert_eq!(svo.get(UVec3::new(5, 5, 5)).unwrap().color, RED.color);
    assert_eq!(svo.leaf_count(), 2);
    assert_eq!(
        rotation_pivot(UVec3::ZERO, UVec3::new(2, 1, 0), 2),
        IVec3::new(3, 3, 1)
    );
    assert_eq!(
        rotation_pivot(UVec3::ZERO, UVec3::new(2, 2, 0), 2),
        IVec3::new(3, 3, 1)
    );
}

#[test]
fn move_clips_and_paste_is_a_shifted_copy() {
    let size = UVec3::splat(32);
    let mut svo = asymmetric(UVec3::new(10, 11, 9));
    let original = svo.clone();
    let sel = invert(&svo, &VoxelSelection::default()).expect("under the listing limit");
    let clip = copy(&svo, &sel);
    assert_eq!(clip.voxels.len(), 21);
    assert_eq!(clip.size, UVec3::new(3, 2, 4));
    let at = IVec3::new(2, 20, 1);
    let e = paste(&mut svo, size, &clip, at, false);
    assert_eq!(e.clipped, 0);
    let (lo, _) = sel.bounds().unwrap();
    for (c, v) in original.leaves() {
        let p = (c.as_ivec3() - lo.as_ivec3() + at).as_uvec3();
        assert_eq!(svo.get(p).unwrap().color, v.color, "shifted copy at {p}");
        assert_eq!(svo.get(c).unwrap().color, v.color, "source kept");
    }
    assert_eq!(svo.leaf_count(), 42);
    let planned: BTreeSet<[u32; 3]> = paste_cells(&clip, at)
        .iter()
        .map(|c| c.as_uvec3().to_array())
        .collect();
    assert_eq!(planned.len(), 21);
    assert!(
        planned
            .iter()
            .all(|c| svo.get(UVec3::from_array(*c)).is_some())
    );
    assert_normals_estimated(&svo);
    undo_restores(svo.clone(), &original, &e.delta);

    // Hanging out of the volume: the outside part is counted.
    let mut svo2 = original.clone();
    let e = paste(&mut svo2, size, &clip, IVec3::new(-1, 30, 0), false);
    let outside = paste_cells(&clip, IVec3::new(-1, 30, 0))
        .iter()
        .filter(|c| c.min_element() < 0 || c.max_element() >= 32)
        .count();
    assert!(outside > 0);
    assert_eq!(e.clipped, outside as u64);
    assert_eq!(svo2.leaf_count(), 21 + 21 - outside as u64);

    // Over-empty-only keeps what is there.
    let mut svo3 = original.clone();
    let recoloured = Clipboard {
        voxels: clip
            .voxels
            .iter()
            .map(|(r, v)| {
                (
                    *r,
                    Voxel {
                        color: [1, 2, 3, 255],
                        ..*v
                    },
                )
            })
            .collect(),
        ..clip.clone()
    };
    let e = paste(&mut svo3, size, &recoloured, lo.as_ivec3(), true);
    assert!(e.changed.is_none());
    paste(&mut svo3, size, &recoloured, lo.as_ivec3(), false);
    assert!(svo3.leaves().iter().all(|(_, v)| v.color == [1, 2, 3, 255]));

    // Move by +X 25: cells beyond 32 are clipped and counted.
    let mut svo4 = original.clone();
    let (e, moved) = transform_selection(
        &mut svo4,
        size,
        &sel,
        SelTransform::Move(IVec3::new(20, 0, 0)),
        IVec3::ZERO,
    );
    // x = 10..12 → 30..32: the x = 12 column (2 + ... cells) falls out.
    let dropped = original
        .leaves()
        .iter()
        .filter(|(c, _)| c.x + 20 >= 32)
        .count() as u64;
    assert_eq!(e.clipped, dropped);
    assert_eq!(moved.len() as u64, 21 - dropped);
    assert_eq!(svo4.leaf_count(), 21 - dropped);
    undo_restores(svo4, &original, &e.delta);
}

#[test]
fn select_in_rect_orthographic_and_perspective() {
    let mut svo = Svo::new(6, false).unwrap();
    add_box(&mut svo, [6, 6, 6], [9, 9, 9], RED);
    let size = UVec3::splat(64);
    // Orthographic, looking down -Z: ndc x = (x - 8) / 8.
    let ortho = Mat4::orthographic_rh(0.0, 16.0, 0.0, 16.0, -100.0, 100.0);
    let sel = select_in_rect(&svo, size, ortho, Vec2::new(-1.0, -1.0), Vec2::ZERO, None)
        .expect("under the listing limit");
    assert_eq!(
        set_of(&sel.iter().collect::<Vec<_>>()),
        box_set([6, 6, 6], [7, 7, 9])
    );
    let front = select_in_rect(
        &svo,
        size,
        ortho,
        Vec2::ZERO,
        Vec2::new(-1.0, -1.0),
        Some(SurfaceView::Direction(Vec3::NEG_Z)),
    )
    .expect("under the listing limit");
    assert_eq!(
        set_of(&front.iter().collect::<Vec<_>>()),
        box_set([6, 6, 9], [7, 7, 9])
    );

    // Behind the perspective camera below: projects into the rectangle unless w > 0 is asked.
    svo.set(UVec3::new(7, 7, 50), Voxel::new(BLUE.color, Vec3::Y))
        .unwrap();
    let eye = Vec3::new(8.0, 8.0, 40.0);
    let view = Mat4::look_at_rh(eye, eye - Vec3::Z, Vec3::Y);
    let proj = Mat4::perspective_rh(std::f32::consts::FRAC_PI_2, 1.0, 0.1, 100.0);
    let clip = proj * view;
    let sel = select_in_rect(&svo, size, clip, Vec2::ZERO, Vec2::ONE, None)
        .expect("under the listing limit");
    assert_eq!(
        set_of(&sel.iter().collect::<Vec<_>>()),
        box_set([8, 8, 6], [9, 9, 9])
    );
    let visible = select_in_rect(
        &svo,
        size,
        clip,
        Vec2::ZERO,
        Vec2::ONE,
        Some(SurfaceView::Eye(eye)),
    )
    .expect("under the listing limit");
    assert_eq!(
        set_of(&visible.iter().collect::<Vec<_>>()),
        box_set([8, 8, 9], [9, 9, 9])
    );
    assert!(
        select_in_rect(&svo, size, Mat4::NAN, Vec2::splat(-1.0), Vec2::ONE, None)
            .expect("under the listing limit")
            .is_empty()
    );
}

#[test]
fn grow_shrink_invert_and_set_algebra() {
    let mut svo = Svo::new(4, false).unwrap();
    add_box(&mut svo, [0, 0, 0], [4, 4, 4], RED);
    let core = select_box(&svo, UVec3::splat(1), UVec3::splat(3));
    assert_eq!(core.len(), 27);
    let grown = grow(&svo, &core);
    // 27 + 6 faces of 9.
    assert_eq!(grown.len(), 27 + 54);
    assert!(grown.contains(UVec3::new(0, 2, 2)) && !grown.contains(UVec3::new(0, 0, 0)));
    let shrunk = shrink(&core);
    assert_eq!(shrunk.iter().collect::<Vec<_>>(), vec![UVec3::splat(2)]);
    assert_eq!(
        shrink(&grown),
        core,
        "the caps go, every core cell keeps its 6 neighbours"
    );
    let inv = invert(&svo, &core).expect("under the listing limit");
    assert_eq!(inv.len(), 125 - 27);
    assert_eq!(inv.union(&core).len(), 125);
    assert_eq!(inv.intersection(&core).len(), 0);
    assert_eq!(grown.difference(&core).len(), 54);
    assert_eq!(
        select_color(&svo, RED.color)
            .expect("under the listing limit")
            .len(),
        125
    );
    assert!(
        select_color(&svo, BLUE.color)
            .expect("under the listing limit")
            .is_empty()
    );
    // The cursor answers like contains for forward, repeated and backward queries.
    let mut cursor = core.cursor();
    let mut queries: Vec<UVec3> = box_set([0; 3], [4; 3])
        .iter()
        .map(|c| UVec3::from_array(*c))
        .collect();
    queries.sort_by_key(|&c| crate::svo::morton_encode(c));
    let back: Vec<UVec3> = queries.iter().rev().copied().collect();
    for &q in queries
        .iter()
        .chain(&back)
        .chain(&queries[..5])
        .chain(&queries[..5])
    {
        assert_eq!(cursor.contains(q), core.contains(q), "{q}");
    }
    let from = VoxelSelection::from_cells([UVec3::ONE, UVec3::ZERO, UVec3::ONE]);
    assert_eq!(from.len(), 2);
    assert_eq!(from.bounds(), Some((UVec3::ZERO, UVec3::ONE)));
    // Connected selection ignores a detached voxel and, with colour, another colour.
    svo.set(UVec3::new(9, 9, 9), Voxel::new(RED.color, Vec3::Y))
        .unwrap();
    svo.paint(UVec3::new(4, 4, 4), BLUE.color).unwrap();
    assert_eq!(
        select_connected(&svo, UVec3::ZERO, false)
            .expect("under the listing limit")
            .len(),
        125
    );
    assert_eq!(
        select_connected(&svo, UVec3::ZERO, true)
            .expect("under the listing limit")
            .len(),
        124
    );
    assert!(
        select_connected(&svo, UVec3::new(8, 8, 8), false)
            .expect("under the listing limit")
            .is_empty()
    );
}

#[test]
fn delete_fill_crop_and_undo() {
    let mut svo = Svo::new(4, false).unwrap();
    add_box(&mut svo, [0, 0, 0], [4, 4, 4], RED);
    let before = svo.clone();
    let core = select_box(&svo, UVec3::splat(1), UVec3::splat(3));
    let e = fill(&mut svo, &core, BLUE);
    assert_eq!(
        select_color(&svo, BLUE.color).expect("under the listing limit"),
        core
    );
    assert_eq!(svo.get(UVec3::splat(2)).unwrap().material, 1);
    undo_restores(svo.clone(), &before, &e.delta);
    let mut svo = before.clone();
    let e = delete(&mut svo, &core);
    assert_eq!(svo.leaf_count(), 125 - 27);
    assert_normals_estimated(&svo);
    undo_restores(svo, &before, &e.delta);
    let mut svo = before.clone();
    let e = crop_to(&mut svo, &core);
    assert_eq!(cells(&svo), box_set([1, 1, 1], [3, 3, 3]));
    assert_normals_estimated(&svo);
    undo_restores(svo, &before, &e.delta);
}

#[test]
fn mask_limits_paint_remove_and_add() {
    let mut svo = Svo::new(4, false).unwrap();
    add_box(&mut svo, [0, 0, 0], [5, 0, 5], RED);
    let before = svo.clone();
    let sel = select_box(&svo, UVec3::new(1, 0, 1), UVec3::new(2, 0, 2))
        .union(&VoxelSelection::from_cells([UVec3::new(5, 0, 5)]));
    let size = UVec3::splat(16);
    let all = (IVec3::ZERO, IVec3::splat(15));
    let e = apply_box(
        &mut svo,
        size,
        all.0,
        all.1,
        ShapeOp::Paint,
        BLUE,
        NO_MIRROR,
        Some(&sel),
    );
    assert_eq!(
        select_color(&svo, BLUE.color).expect("under the listing limit"),
        sel
    );
    undo_restores(svo.clone(), &before, &e.delta);
    let line = line_cells(IVec3::new(0, 0, 0), IVec3::new(5, 0, 5));
    let mut svo = before.clone();
    apply_cells(
        &mut svo,
        size,
        &line,
        ShapeOp::Remove,
        RED,
        NO_MIRROR,
        Some(&sel),
    );
    // The diagonal crosses the selection at (1,0,1), (2,0,2), (5,0,5).
    assert_eq!(svo.leaf_count(), 36 - 3);
    assert!(svo.get(UVec3::new(3, 0, 3)).is_some() && svo.get(UVec3::new(2, 0, 2)).is_none());
    let mut svo = before.clone();
    let sel = sel.union(&VoxelSelection::from_cells([UVec3::new(1, 1, 1)]));
    apply_box(
        &mut svo,
        size,
        IVec3::new(0, 1, 0),
        IVec3::new(9, 1, 9),
        ShapeOp::Add,
        BLUE,
        NO_MIRROR,
        Some(&sel),
    );
    // Add fills the selection's bounding box (1..=5 on x and z) only.
    assert_eq!(svo.leaf_count(), 36 + 25);
    let empty = VoxelSelection::default();
    let e = apply_box(
        &mut svo,
        size,
        all.0,
        all.1,
        ShapeOp::Add,
        BLUE,
        NO_MIRROR,
        Some(&empty),
    );
    assert!(e.changed.is_none());
}

#[test]
fn mirror_on_odd_and_even_volumes() {
    for (n, cell, images) in [
        (7u32, 1, vec![1u32, 5]),
        (7, 3, vec![3]),
        (8, 3, vec![3, 4]),
        (8, 0, vec![0, 7]),
    ] {
        let mut svo = Svo::new(3, false).unwrap();
        let size = UVec3::new(n, 8, 8);
        let e = apply_cells(
            &mut svo,
            size,
            &[IVec3::new(cell, 2, 1)],
            ShapeOp::Add,
            RED,
            Mirror {
                axes: [true, false, true],
            },
            None,
        );
        let mut expect = BTreeSet::new();
        for x in &images {
            expect.insert([*x, 2, 1]);
            expect.insert([*x, 2, 6]);
        }
        assert_eq!(cells(&svo), expect, "volume {n}, cell {cell}");
        undo_restores(svo, &Svo::new(3, false).unwrap(), &e.delta);
    }
    // A mirrored box.
    let mut svo = Svo::new(4, false).unwrap();
    let size = UVec3::new(9, 16, 16);
    apply_box(
        &mut svo,
        size,
        IVec3::new(0, 0, 0),
        IVec3::new(1, 0, 0),
        ShapeOp::Add,
        RED,
        Mirror {
            axes: [true, false, false],
        },
        None,
    );
    assert_eq!(
        cells(&svo),
        [[0, 0, 0], [1, 0, 0], [7, 0, 0], [8, 0, 0]]
            .into_iter()
            .collect()
    );
}

#[test]
fn edits_at_the_octree_extremes_never_panic() {
    let mut svo = Svo::new(21, false).unwrap();
    let e = 1i32 << 21;
    let size = UVec3::splat(1 << 21);
    let near = IVec3::splat(e - 3);
    let r = apply_box(
        &mut svo,
        size,
        near,
        IVec3::splat(i32::MAX),
        ShapeOp::Add,
        RED,
        NO_MIRROR,
        None,
    );
    assert_eq!(svo.leaf_count(), 27);
    assert_eq!(r.clipped, u64::MAX, "(2^31 - 2^21 + 3)^3 - 27 saturates");
    assert_eq!(
        r.changed,
        Some((UVec3::splat((1 << 21) - 3), UVec3::splat((1 << 21) - 1)))
    );
    assert_normals_estimated(&svo);
    // Entirely outside: counted, nothing changes.
    let r = apply_box(
        &mut svo,
        size,
        IVec3::splat(i32::MIN),
        IVec3::splat(i32::MIN + 5),
        ShapeOp::Add,
        RED,
        NO_MIRROR,
        None,
    );
    assert_eq!((r.clipped, r.changed), (216, None));
    // The whole volume is refused, naming the limit.
    let r = apply_box(
        &mut svo,
        size,
        IVec3::splat(i32::MIN),
        IVec3::splat(i32::MAX),
        ShapeOp::Add,
        RED,
        NO_MIRROR,
        None,
    );
    assert!(matches!(r.refused, Some(ToolError::TooManyCells { .. })));
    assert!(r.refused.unwrap().to_string().contains("33554432"));
    assert_eq!(svo.leaf_count(), 27);
    // Remove and paint over everything walk only the solid voxels.
    let before = svo.clone();
    let r = apply_box(
        &mut svo,
        size,
        IVec3::splat(i32::MIN),
        IVec3::splat(i32::MAX),
        ShapeOp::Paint,
        BLUE,
        NO_MIRROR,
        None,
    );
    assert_eq!(
        select_color(&svo, BLUE.color)
            .expect("under the listing limit")
            .len(),
        27
    );
    undo_restores(svo.clone(), &before, &r.delta);
    let mut svo = before.clone();
    let r = apply_box(
        &mut svo,
        size,
        IVec3::splat(i32::MIN),
        IVec3::splat(i32::MAX),
        ShapeOp::Remove,
        BLUE,
        NO_MIRROR,
        None,
    );
    assert!(svo.is_empty());
    undo_restores(svo.clone(), &before, &r.delta);
    // A line through the whole i32 range keeps its in-volume part.
    let line = line_cells(IVec3::splat(i32::MIN), IVec3::splat(i32::MAX));
    assert!(line.contains(&IVec3::ZERO) && line.contains(&IVec3::splat(e - 1)));
    assert!(line.len() <= (e as usize) + 2);
    let mut svo = Svo::new(21, false).unwrap();
    let corner = [
        IVec3::splat(e - 1),
        IVec3::new(e, e - 1, e - 1),
        IVec3::new(-1, 0, 0),
    ];
    let r = apply_cells(
        &mut svo,
        size,
        &corner,
        ShapeOp::Add,
        RED,
        Mirror { axes: [true; 3] },
        None,
    );
    assert_eq!(r.clipped, 2);
    assert_eq!(
        svo.leaf_count(),
        8,
        "the corner voxel and its 7 mirror images"
    );
    assert!(svo.get(UVec3::ZERO).is_some());
    assert_eq!(flood_region(&svo, size, UVec3::ZERO, None).len(), 1);
    assert_eq!(
        face_region(&svo, size, UVec3::splat((1 << 21) - 1), IVec3::X).len(),
        1
    );
    let far = extrude(
        &mut svo,
        size,
        &[UVec3::splat((1 << 21) - 1)],
        IVec3::X,
        i32::MAX,
        None,
    );
    assert!(far.refused.is_some() || far.clipped > 0);
    let r = extrude(
        &mut svo,
        size,
        &[UVec3::splat((1 << 21) - 1)],
        IVec3::X,
        5,
        None,
    );
    assert_eq!((r.clipped, r.changed), (5, None));
    let sel = select_box(&svo, UVec3::ZERO, UVec3::MAX);
    assert_eq!(sel.len(), 8);
    let clip = copy(&svo, &sel);
    let r = paste(&mut svo, size, &clip, IVec3::splat(i32::MAX), false);
    assert_eq!(r.clipped, 8);
    let r = paste(&mut svo, size, &clip, IVec3::splat(i32::MIN), false);
    assert_eq!(r.clipped, 8);
    assert_eq!(paste_cells(&clip, IVec3::splat(i32::MAX)).len(), 8);
    let (r, moved) = transform_selection(
        &mut svo,
        size,
        &sel,
        SelTransform::Move(IVec3::splat(i32::MAX)),
        IVec3::ZERO,
    );
    assert_eq!((r.clipped, moved.len()), (8, 0));
    assert!(svo.is_empty());
}

#[test]
fn added_voxels_take_skin_from_neighbours() {
    let skin = crate::svo::Skin4::from_influences(&[(3, 1.0)]);
    let mut svo = Svo::from_voxels(
        4,
        true,
        [(
            UVec3::new(8, 8, 8),
            Voxel {
                skin,
                ..Voxel::new([1, 2, 3, 255], Vec3::Y)
            },
        )],
    )
    .unwrap();
    add_box(&mut svo, [9, 8, 8], [10, 8, 8], RED);
    assert_eq!(svo.get(UVec3::new(9, 8, 8)).unwrap().skin, skin);
    assert_eq!(svo.get(UVec3::new(10, 8, 8)).unwrap().skin, skin);
}

#[test]
fn sparse_and_dense_commits_agree() {
    // A long thin diagonal line uses the hashed commit; the same cells in a small model the
    // grid. Both must leave the same voxels and normals.
    let line = line_cells(IVec3::new(0, 0, 0), IVec3::new(200, 150, 100));
    let mut sparse = Svo::new(8, false).unwrap();
    add_box(&mut sparse, [0, 0, 0], [3, 3, 3], BLUE);
    let before = sparse.clone();
    let mut dense = sparse.clone();
    let e = apply_cells(
        &mut sparse,
        UVec3::splat(256),
        &line,
        ShapeOp::Add,
        RED,
        NO_MIRROR,
        None,
    );
    for chunk in line.chunks(8) {
        apply_cells(
            &mut dense,
            UVec3::splat(256),
            chunk,
            ShapeOp::Add,
            RED,
            NO_MIRROR,
            None,
        );
    }
    assert!(sparse == dense);
    assert_normals_estimated(&sparse);
    undo_restores(sparse, &before, &e.delta);
}

// ---- model operations ----

use super::model_ops::{
    Anchor, InitialFill, depth_for, fill_interior, hollow, mirror_model, new_model, resize_canvas,
    shift_content,
};
use super::palette::{
    load_palette, model_colors, palette_from_png, palette_from_vox, palette_to_png, parse_gpl,
    replace_color, save_palette, write_gpl,
};

fn cube(lo: u32, hi: u32, depth: u8) -> Svo {
    let mut svo = Svo::new(depth, false).unwrap();
    let (l, h) = (lo as i32, hi as i32);
    add_box(&mut svo, [l, l, l], [h, h, h], RED);
    svo
}

#[test]
fn hollow_keeps_an_exact_shell() {
    let before = cube(2, 9, 4);
    let size = UVec3::splat(16);
    for (shell, inner_lo, inner_hi) in [(1, 3, 8), (2, 4, 7), (0, 3, 8)] {
        let mut svo = before.clone();
        let e = hollow(&mut svo, size, shell);
        let mut expect = box_set([2; 3], [9; 3]);
        for c in box_set([inner_lo; 3], [inner_hi; 3]) {
            expect.remove(&c);
        }
        assert_eq!(cells(&svo), expect, "shell {shell}");
        assert_normals_estimated(&svo);
        undo_restores(svo, &before, &e.delta);
    }
    // The volume's outside counts as empty: a cube filling the volume is hollowed too.
    let mut svo = cube(0, 3, 2);
    hollow(&mut svo, UVec3::splat(4), 1);
    assert_eq!(svo.leaf_count(), 64 - 8);
    // A volume cut through the cube: the cut face is a surface.
    let mut svo = before.clone();
    hollow(&mut svo, UVec3::new(6, 16, 16), 1);
    assert!(
        svo.get(UVec3::new(5, 5, 5)).is_some(),
        "on the volume's face x = 5"
    );
    assert!(svo.get(UVec3::new(4, 5, 5)).is_none());
    assert!(
        svo.get(UVec3::new(7, 5, 5)).is_some(),
        "outside the volume: untouched"
    );
}

#[test]
fn fill_interior_fills_closed_cavities_only() {
    let mut closed = cube(2, 7, 4);
    hollow(&mut closed, UVec3::splat(16), 1);
    assert_eq!(closed.leaf_count(), 216 - 64);
    let walls = closed.clone();
    let e = fill_interior(&mut closed, UVec3::splat(16), None);
    assert_eq!(cells(&closed), box_set([2; 3], [7; 3]));
    assert!(closed.leaves().iter().all(|(_, v)| v.color == RED.color));
    assert_normals_estimated(&closed);
    undo_restores(closed, &walls, &e.delta);
    let mut inked = walls.clone();
    fill_interior(&mut inked, UVec3::splat(16), Some(BLUE));
    assert_eq!(
        select_color(&inked, BLUE.color)
            .expect("under the listing limit")
            .len(),
        64
    );
    assert_eq!(
        select_color(&inked, BLUE.color)
            .expect("under the listing limit")
            .bounds(),
        Some((UVec3::splat(3), UVec3::splat(6)))
    );
    // A hole in one wall opens the cavity.
    let mut open = walls.clone();
    open.remove(UVec3::new(4, 7, 4)).unwrap();
    let e = fill_interior(&mut open, UVec3::splat(16), None);
    assert!(e.changed.is_none());
    assert_eq!(open.leaf_count(), 216 - 64 - 1);
    // A box touching the volume's faces is still closed.
    let mut edge = cube(0, 5, 3);
    hollow(&mut edge, UVec3::splat(6), 1);
    fill_interior(&mut edge, UVec3::splat(6), None);
    assert_eq!(edge.leaf_count(), 216);
}

#[test]
fn resize_canvas_anchors_offsets_and_drops() {
    let mut svo = Svo::new(4, false).unwrap();
    for c in [[0, 0, 0], [9, 9, 9], [5, 5, 5]] {
        svo.set(UVec3::from_array(c), Voxel::new(RED.color, Vec3::Y))
            .unwrap();
    }
    let size = UVec3::splat(10);
    let grow = resize_canvas(
        &svo,
        size,
        UVec3::splat(14),
        [Anchor::Min, Anchor::Center, Anchor::Max],
    )
    .unwrap();
    assert_eq!(grow.offset, IVec3::new(0, 2, 4));
    assert_eq!(grow.dropped, 0);
    assert_eq!(grow.svo.depth(), 4);
    assert_eq!(
        cells(&grow.svo),
        [[0, 2, 4], [9, 11, 13], [5, 7, 9]].into_iter().collect()
    );
    let shrink = resize_canvas(&svo, size, UVec3::splat(7), [Anchor::Center; 3]).unwrap();
    assert_eq!((shrink.offset, shrink.dropped), (IVec3::splat(-2), 2));
    assert_eq!(cells(&shrink.svo), [[3, 3, 3]].into_iter().collect());
    assert_eq!(shrink.svo.depth(), 3);
    let max = resize_canvas(&svo, size, UVec3::splat(7), [Anchor::Max; 3]).unwrap();
    assert_eq!((max.offset, max.dropped), (IVec3::splat(-3), 1));
    let min = resize_canvas(&svo, size, UVec3::new(7, 20, 3), [Anchor::Min; 3]).unwrap();
    assert_eq!(
        (min.offset, min.dropped, min.svo.depth()),
        (IVec3::ZERO, 2, 5)
    );
    let big = resize_canvas(&svo, size, UVec3::new(1 << 21, 4, 4), [Anchor::Min; 3]).unwrap();
    assert_eq!(big.svo.depth(), 21);
    let err = resize_canvas(
        &svo,
        size,
        UVec3::new((1 << 21) + 1, 4, 4),
        [Anchor::Min; 3],
    )
    .unwrap_err();
    assert!(matches!(err, ToolError::ExtentTooLarge { .. }));
    assert!(err.to_string().contains("2^21 = 2097152"), "{err}");
    assert!(matches!(
        resize_canvas(&svo, size, UVec3::new(0, 4, 4), [Anchor::Min; 3]),
        Err(ToolError::EmptySize { .. })
    ));
    for (s, d) in [(1, 1), (2, 1), (3, 2), (16, 4), (17, 5), (1 << 21, 21)] {
        assert_eq!(depth_for(UVec3::new(1, s, 1)).unwrap(), d, "{s}");
    }
}

#[test]
fn shift_and_mirror_model() {
    let mut svo = Svo::new(3, false).unwrap();
    let size = UVec3::new(7, 8, 8);
    for c in [[6, 0, 0], [1, 2, 3], [3, 1, 1]] {
        svo.set(UVec3::from_array(c), Voxel::new(RED.color, Vec3::Y))
            .unwrap();
    }
    let before = svo.clone();
    let e = shift_content(&mut svo, size, IVec3::new(1, 0, 0), true);
    assert_eq!(
        cells(&svo),
        [[0, 0, 0], [2, 2, 3], [4, 1, 1]].into_iter().collect()
    );
    assert_eq!(e.clipped, 0);
    undo_restores(svo.clone(), &before, &e.delta);
    let mut svo = before.clone();
    let e = shift_content(&mut svo, size, IVec3::new(1, -2, 0), false);
    assert_eq!(cells(&svo), [[2, 0, 3]].into_iter().collect());
    assert_eq!(e.clipped, 2);
    undo_restores(svo, &before, &e.delta);
    // Odd volume: 1 ↔ 5, the centre 3 stays; even volume: 3 ↔ 4.
    let mut svo = before.clone();
    let e = mirror_model(&mut svo, size, 0);
    assert_eq!(
        cells(&svo),
        [[0, 0, 0], [5, 2, 3], [3, 1, 1]].into_iter().collect()
    );
    undo_restores(svo.clone(), &before, &e.delta);
    mirror_model(&mut svo, size, 0);
    assert_eq!(cells(&svo), cells(&before));
    let mut svo = before.clone();
    mirror_model(&mut svo, UVec3::splat(8), 1);
    assert_eq!(
        cells(&svo),
        [[6, 7, 0], [1, 5, 3], [3, 6, 1]].into_iter().collect()
    );
    assert!(mirror_model(&mut svo, size, 3).changed.is_none());
}

#[test]
fn new_models() {
    let svo = new_model(UVec3::new(3, 4, 5), InitialFill::SolidBox, RED).unwrap();
    assert_eq!(cells(&svo), box_set([0; 3], [2, 3, 4]));
    assert_eq!(svo.depth(), 3);
    assert_normals_estimated(&svo);
    let slab = new_model(UVec3::splat(8), InitialFill::GroundSlab { height: 2 }, BLUE).unwrap();
    assert_eq!(cells(&slab), box_set([0; 3], [7, 1, 7]));
    assert_eq!(slab.get(UVec3::ZERO).unwrap().material, 1);
    let empty = new_model(UVec3::new(100, 5, 5), InitialFill::Empty, RED).unwrap();
    assert!(empty.is_empty() && empty.depth() == 7);
    let huge = new_model(UVec3::splat(1 << 21), InitialFill::SolidBox, RED).unwrap_err();
    assert!(matches!(huge, ToolError::TooManyCells { .. }));
    assert!(new_model(UVec3::splat(1 << 21), InitialFill::Empty, RED).is_ok());
    assert!(new_model(UVec3::new(5, 0, 5), InitialFill::Empty, RED).is_err());
}

// ---- palettes ----

#[test]
fn model_colours_and_replace_colour() {
    let mut svo = Svo::new(4, false).unwrap();
    add_box(&mut svo, [0, 0, 0], [3, 0, 0], RED);
    add_box(&mut svo, [0, 1, 0], [5, 1, 0], BLUE);
    svo.set(UVec3::new(0, 5, 0), Voxel::new([9, 9, 9, 255], Vec3::Y))
        .unwrap();
    assert_eq!(
        model_colors(&svo),
        vec![(BLUE.color, 6), (RED.color, 4), ([9, 9, 9, 255], 1)]
    );
    let before = svo.clone();
    let e = replace_color(&mut svo, RED.color, [1, 1, 1, 255], None);
    assert_eq!(
        select_color(&svo, [1, 1, 1, 255])
            .expect("under the listing limit")
            .len(),
        4
    );
    assert!(
        select_color(&svo, RED.color)
            .expect("under the listing limit")
            .is_empty()
    );
    undo_restores(svo.clone(), &before, &e.delta);
    let mut svo = before.clone();
    let sel = VoxelSelection::from_cells([UVec3::new(1, 0, 0), UVec3::new(1, 1, 0)]);
    replace_color(&mut svo, RED.color, [1, 1, 1, 255], Some(&sel));
    assert_eq!(
        select_color(&svo, [1, 1, 1, 255])
            .expect("under the listing limit")
            .iter()
            .collect::<Vec<_>>(),
        vec![UVec3::new(1, 0, 0)]
    );
    assert!(
        replace_color(&mut svo, BLUE.color, BLUE.color, None)
            .changed
            .is_none()
    );
}

fn sample_palette() -> Vec<[u8; 4]> {
    (0..256u32)
        .map(|i| [(i * 7) as u8, (i * 13 + 5) as u8, (255 - i) as u8, 255])
        .collect()
}

#[test]
fn gpl_round_trip_and_errors() {
    let colors = sample_palette();
    let text = write_gpl("test\nname", &colors);
    assert!(text.starts_with("GIMP Palette\nName: testname\n"));
    assert_eq!(parse_gpl(&text).unwrap(), colors);
    let mut with_alpha = colors.clone();
    with_alpha[3][3] = 17;
    assert_eq!(parse_gpl(&write_gpl("a", &with_alpha)).unwrap(), with_alpha);
    let gimp =
        "GIMP Palette\nName: Web\nColumns: 4\n# comment\n\n  0   0 255\tBlue\n255 128 0 Orange\n";
    assert_eq!(
        parse_gpl(gimp).unwrap(),
        vec![[0, 0, 255, 255], [255, 128, 0, 255]]
    );
    for (bad, line, says) in [
        ("JASC-PAL\n0100\n", 1, "GIMP Palette"),
        ("GIMP Palette\nName: x\n1 2 3\n4 5\n", 4, "found only 2"),
        ("GIMP Palette\n\n300 0 0\n", 3, "red must be"),
        ("GIMP Palette\n0 0 x\n", 2, "blue must be"),
        ("GIMP Palette\nChannels: CMYK\n", 2, "Channels"),
        ("", 1, "empty"),
    ] {
        let e = parse_gpl(bad).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains(&format!("line {line}:")) && msg.contains(says),
            "{bad:?}: {msg}"
        );
    }
}

#[test]
fn png_round_trip_and_errors() {
    let colors = sample_palette();
    let png = palette_to_png(&colors);
    assert_eq!(palette_from_png(&png).unwrap(), colors);
    let short = vec![[1, 2, 3, 4], [5, 6, 7, 8]];
    assert_eq!(palette_from_png(&palette_to_png(&short)).unwrap(), short);
    let e = palette_from_png(b"GIF89a-----").unwrap_err().to_string();
    assert!(e.contains("not a PNG") && e.contains("bytes 0..8"), "{e}");
    let mut truncated = png.clone();
    truncated.truncate(40);
    assert!(
        palette_from_png(&truncated)
            .unwrap_err()
            .to_string()
            .contains("decode")
    );
    // Wider than a palette strip may be.
    let wide = palette_to_png(&vec![[0; 4]; 300]);
    assert!(palette_from_png(&wide).is_err());
}

#[test]
fn palette_files_by_extension() {
    let dir = tempfile::tempdir().unwrap();
    let colors = sample_palette();
    for ext in ["gpl", "png"] {
        let p = dir.path().join(format!("pal.{ext}"));
        save_palette(&p, &colors).unwrap();
        assert_eq!(load_palette(&p).unwrap(), colors, "{ext}");
    }
    let bad = dir.path().join("broken.gpl");
    std::fs::write(&bad, "GIMP Palette\n1 2\n").unwrap();
    let e = load_palette(&bad).unwrap_err().to_string();
    assert!(e.contains("broken.gpl") && e.contains("line 2"), "{e}");
    assert!(
        load_palette(&dir.path().join("x.act"))
            .unwrap_err()
            .to_string()
            .contains(".gpl")
    );
    assert!(save_palette(&dir.path().join("x.vox"), &colors).is_err());
    assert!(
        load_palette(&dir.path().join("missing.png"))
            .unwrap_err()
            .to_string()
            .contains("missing.png")
    );
    let army = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/vox/mmmm/chr_army1.vox"
    );
    let from_file = load_palette(std::path::Path::new(army)).unwrap();
    assert_eq!(from_file.len(), 255);
    assert_eq!(
        palette_from_vox(&std::fs::read(army).unwrap()).unwrap(),
        from_file
    );
    assert!(
        palette_from_vox(b"VOX junk")
            .unwrap_err()
            .to_string()
            .contains("(bytes)")
    );
    let not_vox = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/assets/vox/dot_vox/not_a.vox"
    );
    assert!(load_palette(std::path::Path::new(not_vox)).is_err());
}

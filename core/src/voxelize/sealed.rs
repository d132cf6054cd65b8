//! A rigid solid's octree built straight from the grid's interior bits, following its surface: the
//! interior voxels enclosed on all six faces become the interior mark (`Voxel::INTERIOR`,
//! docs/svo.md "Interior") as maximal tiles found on a pyramid of "all enclosed" flags, so no
//! interior voxel is listed one by one and no feature transform runs. The few interior voxels
//! that are not enclosed take the attributes of their nearest surface voxel (a search among the
//! surface voxels, [`Svo::nearest_surface`]).
//!
//! [`build_reference`] lists every voxel instead and hands them to the octree builder; tests
//! hold the two equal.

use glam::UVec3;
use rayon::prelude::*;

use super::bits::{self, CellBits};
use crate::svo::{Svo, SvoError, Voxel, morton_decode, morton_encode};

/// Heap bytes per grid cell of [`build`]: the interior, kept-surface and enclosed bits, and
/// the pyramid's two bits a block (1/8 + 1/64 + … of them).
pub(crate) const BYTES_PER_CELL: f64 = (3.0 + 2.0 / 7.0) * bits::BYTES_PER_CELL;

/// How far (in voxels) an open interior cell's nearest surface voxel is looked for on the
/// grid's bits before the octree search takes over ([`build`]).
pub(crate) const NEAR_SEARCH_RADIUS: u32 = 3;

/// A stored run: origin, height (0 for a leaf) and value.
type Run = (UVec3, u8, Voxel);

/// Pyramid flag: every cell of the block is an enclosed interior cell inside the grid.
const ALL: u8 = 1;
/// Pyramid flag: some cell of the block is solid.
const ANY: u8 = 2;

/// What the build found.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct SolidCounts {
    /// Interior cells enclosed on all six faces: the interior mark.
    pub(crate) marked: u64,
}

/// The grid's cells as the build sees them: the interior (voted inside), the kept surface
/// voxels, and the interior cells enclosed on all six faces by solid cells (interior or kept).
struct Cells {
    inside: CellBits,
    kept: CellBits,
    sealed: CellBits,
}

impl Cells {
    fn solid(&self, c: UVec3) -> bool {
        self.inside.get(c) || self.kept.get(c)
    }

    /// The pyramid flags of cell `c` (inside the grid).
    fn flags(&self, c: UVec3) -> u8 {
        (u8::from(self.solid(c)) * ANY) | (u8::from(self.sealed.get(c)) * ALL)
    }

    /// Row `(y, z)`'s solid words (clear outside the grid), into `out`.
    fn solid_row(&self, y: u32, z: u32, out: &mut [u64]) {
        match (self.inside.row(y, z), self.kept.row(y, z)) {
            (Some(i), Some(k)) => {
                for ((o, i), k) in out.iter_mut().zip(i).zip(k) {
                    *o = i | k;
                }
            }
            _ => out.fill(0),
        }
    }
}

/// Marks the kept surface voxels and finds the enclosed interior cells, 64 cells at a time.
fn classify(inside: CellBits, surface: &[(UVec3, Voxel)]) -> Cells {
    let dims = inside.dims();
    let mut kept = CellBits::new(dims);
    for (c, _) in surface {
        if c.cmplt(dims).all() {
            kept.set(*c);
        }
    }
    let mut cells = Cells {
        sealed: CellBits::new(dims),
        inside,
        kept,
    };
    let mut sealed = std::mem::replace(&mut cells.sealed, CellBits::new(UVec3::ZERO));
    let n = cells.inside.row_words();
    sealed.par_rows_mut().for_each_init(
        || vec![0u64; 5 * n],
        |scratch, (y, z, words)| {
            if y == 0 || z == 0 || y + 1 == dims.y || z + 1 == dims.z {
                return;
            }
            let (here, around) = scratch.split_at_mut(n);
            cells.solid_row(y, z, here);
            let mut rows = around.chunks_exact_mut(n);
            for (dy, dz) in [(y - 1, z), (y + 1, z), (y, z - 1), (y, z + 1)] {
                if let Some(r) = rows.next() {
                    cells.solid_row(dy, dz, r);
                }
            }
            let (Some(inside), Some(kept)) = (cells.inside.row(y, z), cells.kept.row(y, z)) else {
                return;
            };
            for (w, out) in words.iter_mut().enumerate() {
                let (left, right) = bits::neighbours(here, w);
                let mut s = inside[w] & !kept[w] & left & right;
                for r in around.chunks_exact(n) {
                    s &= r[w];
                }
                *out = s;
            }
        },
    );
    cells.sealed = sealed;
    cells
}

/// The pyramid of `2^k` blocks for k = 1..=depth (`levels[k - 1]`): which blocks hold a solid
/// cell, and which are all enclosed interior cells inside the grid, as bits. Level 0 is the
/// cells themselves ([`Cells::flags`]).
fn pyramid(cells: &Cells, depth: u8) -> Vec<(CellBits, CellBits)> {
    let mut levels: Vec<(CellBits, CellBits)> = Vec::with_capacity(usize::from(depth));
    let dims = cells.inside.dims();
    let copy = |bits: &CellBits, y: u32, z: u32, out: &mut [u64]| {
        if let Some(r) = bits.row(y, z) {
            out.copy_from_slice(r);
        }
    };
    for k in 1..=depth {
        let level = match levels.last() {
            None => (
                bits::halve(dims, false, |y, z, out| cells.solid_row(y, z, out)),
                bits::halve(dims, true, |y, z, out| copy(&cells.sealed, y, z, out)),
            ),
            Some((any, all)) => (
                bits::halve(any.dims(), false, |y, z, out| copy(any, y, z, out)),
                bits::halve(all.dims(), true, |y, z, out| copy(all, y, z, out)),
            ),
        };
        debug_assert_eq!(level.0.dims(), (dims + (1 << k) - 1) >> k);
        levels.push(level);
    }
    levels
}

/// An iterator of a known number of items, so that its consumer allocates once.
struct Counted<I> {
    runs: I,
    left: usize,
}

impl<I: Iterator<Item = Run>> Iterator for Counted<I> {
    type Item = Run;

    fn next(&mut self) -> Option<Run> {
        let run = self.runs.next()?;
        self.left = self.left.saturating_sub(1);
        Some(run)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.left, Some(self.left))
    }
}

/// The octree of a rigid solid: `surface` (kept surface voxels with their attributes, Morton
/// order) and the `inside` cells (see [`bits::inside_bits`]), enclosed ones as the interior
/// mark. The others (open) take the attributes of their nearest surface voxel among `surface`
/// and `dropped` (those solid mode left out, lying outside the mesh; Morton order), by centre
/// distance with ties to the smaller Morton code: looked for on the surface voxels' bits within
/// `near_radius` voxels, where nearly all are, and by the octree search beyond.
///
/// # Errors
/// [`SvoError`] from the octree (a depth out of range).
pub(crate) fn build(
    depth: u8,
    inside: CellBits,
    surface: &[(UVec3, Voxel)],
    dropped: &[(UVec3, Voxel)],
    near_radius: u32,
) -> Result<(Svo, SolidCounts), SvoError> {
    let cells = classify(inside, surface);
    let levels = pyramid(&cells, depth);
    let flags = |k: u8, b: UVec3| {
        if k == 0 {
            return cells.flags(b);
        }
        let (any, all) = &levels[usize::from(k) - 1];
        (u8::from(any.get(b)) * ANY) | (u8::from(all.get(b)) * ALL)
    };
    // Depth-first in octant order, each subtree at level `split` on its own thread: runs come
    // out in Morton order, beside the surface's.
    let split = depth.min(2);
    let roots: Vec<UVec3> = (0..1u64 << (3 * u32::from(split)))
        .map(|code| morton_decode(code) << u32::from(depth - split))
        .collect();
    let mut parts: Vec<(Vec<Run>, Vec<usize>)> = roots
        .par_iter()
        .map(|&root| {
            let mut runs: Vec<Run> = Vec::new();
            let mut opens: Vec<usize> = Vec::new();
            let start = morton_encode(root);
            let mut next_surface = surface.partition_point(|s| morton_encode(s.0) < start);
            let mut stack: Vec<(UVec3, u8)> = vec![(root, depth - split)];
            while let Some((origin, k)) = stack.pop() {
                let f = flags(k, origin >> u32::from(k));
                if f & ANY == 0 {
                    continue;
                }
                if k > 0 && f & ALL != 0 {
                    runs.push((origin, k, Voxel::INTERIOR));
                    continue;
                }
                if k == 0 {
                    let code = morton_encode(origin);
                    while next_surface < surface.len()
                        && morton_encode(surface[next_surface].0) < code
                    {
                        next_surface += 1;
                    }
                    if surface.get(next_surface).is_some_and(|s| s.0 == origin) {
                        runs.push((origin, 0, surface[next_surface].1));
                        next_surface += 1;
                    } else if cells.sealed.get(origin) {
                        runs.push((origin, 0, Voxel::INTERIOR));
                    } else {
                        opens.push(runs.len());
                        runs.push((origin, 0, Voxel::default()));
                    }
                    continue;
                }
                let half = 1u32 << (k - 1);
                // Pushed last octant first, so octant 0 is visited first.
                for o in (0..8u32).rev() {
                    let c = origin + UVec3::new(o & 1, (o >> 1) & 1, o >> 2) * half;
                    stack.push((c, k - 1));
                }
            }
            (runs, opens)
        })
        .collect();
    let marked = cells.sealed.count_ones();
    drop(levels);
    // The enclosed bits are done with: their words become every surface voxel's bits, the
    // kept and the `dropped` ones, for the open cells' search.
    let Cells {
        inside,
        kept,
        sealed: mut seeds,
    } = cells;
    drop(inside);
    seeds.copy_from(&kept);
    drop(kept);
    for (c, _) in dropped {
        if c.cmplt(seeds.dims()).all() {
            seeds.set(*c);
        }
    }
    let far = std::sync::OnceLock::new();
    let attributes = |q: UVec3| {
        let code = morton_encode(q);
        [surface, dropped].into_iter().find_map(|list| {
            let i = list
                .binary_search_by_key(&code, |e| morton_encode(e.0))
                .ok()?;
            Some(list[i].1)
        })
    };
    let open = |c: UVec3| {
        let near = seeds.nearest_within(c, near_radius).and_then(attributes);
        near.or_else(|| {
            far.get_or_init(|| {
                Svo::from_voxels(depth, false, surface.iter().chain(dropped).copied()).ok()
            })
            .as_ref()?
            .nearest_surface(c)
            .map(|(_, v)| v)
        })
        .unwrap_or_default()
    };
    for (runs, opens) in &mut parts {
        let resolved: Vec<Voxel> = opens.par_iter().map(|&i| open(runs[i].0)).collect();
        for (&i, v) in opens.iter().zip(resolved) {
            runs[i].2 = v;
        }
    }
    drop(seeds);
    // The parts in order, not copied into one list; counted, so the build sizes its lists once.
    let count = parts.iter().map(|p| p.0.len()).sum();
    let runs = parts.into_iter().flat_map(|p| p.0);
    let svo = Svo::from_runs(depth, false, Counted { runs, left: count })?;
    Ok((svo, SolidCounts { marked }))
}

/// [`build`] the plain way: every solid cell listed, each tested for enclosure on its own and
/// each open one given its nearest surface voxel by the octree search, the octree builder
/// collapsing the interior into tiles. The same octree; for tests.
#[cfg(test)]
pub(crate) fn build_reference(
    depth: u8,
    inside: &CellBits,
    surface: &[(UVec3, Voxel)],
    dropped: &[(UVec3, Voxel)],
) -> Result<Svo, SvoError> {
    let dims = inside.dims();
    let kept: std::collections::HashMap<UVec3, Voxel> = surface.iter().copied().collect();
    let seeds = Svo::from_voxels(depth, false, surface.iter().chain(dropped).copied())?;
    let solid = |q: glam::IVec3| {
        q.cmpge(glam::IVec3::ZERO).all()
            && q.cmplt(dims.as_ivec3()).all()
            && (inside.get(q.as_uvec3()) || kept.contains_key(&q.as_uvec3()))
    };
    let mut all = Vec::new();
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                let c = UVec3::new(x, y, z);
                if let Some(v) = kept.get(&c) {
                    all.push((c, *v));
                } else if inside.get(c) {
                    let enclosed = crate::svo::FACE_NEIGHBOURS
                        .iter()
                        .all(|&f| solid(c.as_ivec3() + f));
                    let open = || seeds.nearest_surface(c).map_or(Voxel::default(), |s| s.1);
                    all.push((c, if enclosed { Voxel::INTERIOR } else { open() }));
                }
            }
        }
    }
    Svo::from_voxels(depth, false, all)
}

#[cfg(test)]
mod tests {
    use glam::{IVec3, Vec3};
    use proptest::prelude::*;

    use super::*;

    /// A grid of `dims` whose interior is the union of `balls` (centre, radius), with a kept
    /// surface voxel on some of the interior's boundary cells and on a few cells outside it,
    /// and (third) a few dropped surface voxels outside it.
    #[allow(clippy::type_complexity)]
    fn scene(
        dims: UVec3,
        balls: &[(Vec3, f32)],
        salt: u32,
    ) -> (CellBits, Vec<(UVec3, Voxel)>, Vec<(UVec3, Voxel)>) {
        let inside = |c: UVec3| {
            balls
                .iter()
                .any(|&(o, r)| (c.as_vec3() + 0.5 - o).length() <= r)
        };
        let mut votes = CellBits::new(dims);
        let (mut surface, mut dropped) = (Vec::new(), Vec::new());
        for z in 0..dims.z {
            for y in 0..dims.y {
                for x in 0..dims.x {
                    let c = UVec3::new(x, y, z);
                    let h = (x * 73 + y * 151 + z * 37 + salt).wrapping_mul(2_654_435_761) >> 24;
                    if inside(c) {
                        votes.set(c);
                        let edge = crate::svo::FACE_NEIGHBOURS.iter().any(|&f| {
                            let q = c.as_ivec3() + f;
                            q.cmplt(IVec3::ZERO).any()
                                || q.cmpge(dims.as_ivec3()).any()
                                || !inside(q.as_uvec3())
                        });
                        // Most boundary cells are surface; some are left as open interior.
                        if edge && !h.is_multiple_of(5) {
                            surface.push((c, Voxel::new([h as u8, 40, 90, 255], Vec3::X)));
                        }
                    } else if h.is_multiple_of(41) {
                        surface.push((c, Voxel::new([10, h as u8, 90, 255], Vec3::Y)));
                    } else if h.is_multiple_of(43) {
                        dropped.push((c, Voxel::new([90, h as u8, 10, 255], Vec3::NEG_Y)));
                    }
                }
            }
        }
        surface.sort_by_key(|e| morton_encode(e.0));
        dropped.sort_by_key(|e| morton_encode(e.0));
        (votes, surface, dropped)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// Property: the octree built from the bits (maximal interior tiles from the pyramid,
        /// open cells' nearest surface voxel on the bits within a radius, by the octree search
        /// beyond) equals the one built by listing every voxel, tile for tile.
        #[test]
        fn the_tiled_build_equals_listing_every_voxel(
            (dx, dy, dz) in (9u32..140, 9u32..40, 9u32..40),
            balls in proptest::collection::vec(((0f32..140.0, 0f32..40.0, 0f32..40.0), 2f32..30.0), 1..4),
            salt in 0u32..1000,
            near_radius in 1u32..4,
        ) {
            let dims = UVec3::new(dx, dy, dz);
            // Rows wider than one 64-cell word.
            let depth = 8;
            let balls: Vec<(Vec3, f32)> = balls.into_iter().map(|((x, y, z), r)| (Vec3::new(x, y, z), r)).collect();
            let (votes, surface, dropped) = scene(dims, &balls, salt);
            let (fast, counts) = build(depth, votes.clone(), &surface, &dropped, near_radius).unwrap();
            let slow = build_reference(depth, &votes, &surface, &dropped).unwrap();
            prop_assert_eq!(&fast, &slow);
            prop_assert_eq!(fast.tile_count(), slow.tile_count());
            prop_assert_eq!(fast.leaf_count(), slow.leaf_count());
            prop_assert_eq!(counts.marked, slow.interior_voxels());
            prop_assert_eq!(fast.exposed_interior(), None);
            let m = fast.memory_stats();
            prop_assert_eq!(m.total_bytes, { let mut s = slow.clone(); s.compact(); s.memory_stats().total_bytes });
        }
    }

    #[test]
    fn a_big_ball_is_a_few_tiles() {
        let dims = UVec3::new(60, 50, 64);
        let (votes, surface, dropped) = scene(dims, &[(Vec3::new(30.0, 25.0, 32.0), 24.0)], 7);
        let (svo, counts) = build(6, votes, &surface, &dropped, NEAR_SEARCH_RADIUS).unwrap();
        assert!(counts.marked > 40_000, "{counts:?}");
        assert!(svo.tile_count() > 100, "{} tiles", svo.tile_count());
        assert_eq!(svo.interior_voxels(), counts.marked);
        assert_eq!(svo.exposed_interior(), None);
    }
}

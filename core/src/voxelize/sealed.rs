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

/// Heap bytes per grid cell of [`build`] and its caller: the interior, kept-surface, enclosed
/// and all-surface (seeds) bits, and the pyramid of flags (1/8 + 1/64 + …).
pub(crate) const BYTES_PER_CELL: f64 = 4.0 * bits::BYTES_PER_CELL + 0.15;

/// How far (in voxels) an open interior cell's nearest surface voxel is looked for on the
/// grid's bits before the octree search takes over.
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

/// Level 1 of the pyramid: the flags of the 2×2×2 blocks (x fastest) and their dims, from the
/// cells' bits, 32 blocks at a time.
fn first_level(cells: &Cells) -> (UVec3, Vec<u8>) {
    const EVEN: u64 = 0x5555_5555_5555_5555;
    let dims = cells.inside.dims();
    let up = (dims + 1) / 2;
    let n = cells.inside.row_words();
    let ux = up.x as usize;
    let mut flags = vec![0u8; ux * up.y as usize * up.z as usize];
    flags.par_chunks_mut(ux.max(1)).enumerate().for_each_init(
        || vec![0u64; 3 * n],
        |scratch, (r, out)| {
            let (by, bz) = ((r % up.y as usize) as u32, (r / up.y as usize) as u32);
            let (any, rest) = scratch.split_at_mut(n);
            let (all, row) = rest.split_at_mut(n);
            any.fill(0);
            all.fill(u64::MAX);
            for (y, z) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (y, z) = (2 * by + y, 2 * bz + z);
                cells.solid_row(y, z, row);
                let sealed = cells.sealed.row(y, z);
                for w in 0..n {
                    any[w] |= row[w];
                    all[w] &= sealed.map_or(0, |s| s[w]);
                }
            }
            for (bx, o) in out.iter_mut().enumerate() {
                let (w, b) = (bx / 32, 2 * (bx % 32));
                let any = (any[w] | any[w] >> 1) & EVEN;
                let all = all[w] & all[w] >> 1 & EVEN;
                *o = (u8::from(any >> b & 1 == 1) * ANY) | (u8::from(all >> b & 1 == 1) * ALL);
            }
        },
    );
    (up, flags)
}

/// Flags of the `2^k` blocks for k = 1..=depth (`levels[k - 1]`, x fastest), with their dims.
/// Level 0 is read from the cells themselves ([`Cells::flags`]), not stored.
fn pyramid(cells: &Cells, depth: u8) -> Vec<(UVec3, Vec<u8>)> {
    let mut levels: Vec<(UVec3, Vec<u8>)> = Vec::with_capacity(usize::from(depth));
    if depth == 0 {
        return levels;
    }
    levels.push(first_level(cells));
    for _ in 2..=depth {
        let (d, below) = levels
            .last()
            .unwrap_or_else(|| unreachable!("level 1 is pushed"));
        let up = (*d + 1) / 2;
        let (ux, uy) = (up.x as usize, up.y as usize);
        let flags: Vec<u8> = (0..ux * uy * up.z as usize)
            .into_par_iter()
            .map(|i| {
                let b = UVec3::new(
                    (i % ux) as u32,
                    ((i / ux) % uy) as u32,
                    (i / (ux * uy)) as u32,
                );
                let (mut all, mut any) = (true, false);
                for o in 0..8u32 {
                    let c = b * 2 + UVec3::new(o & 1, (o >> 1) & 1, o >> 2);
                    if c.cmplt(*d).all() {
                        let f = below[c.x as usize
                            + d.x as usize * (c.y as usize + d.y as usize * c.z as usize)];
                        all &= f & ALL != 0;
                        any |= f & ANY != 0;
                    } else {
                        all = false;
                    }
                }
                (u8::from(all) * ALL) | (u8::from(any) * ANY)
            })
            .collect();
        levels.push((up, flags));
    }
    levels
}

/// The octree of a rigid solid: `surface` (kept surface voxels with their attributes, Morton
/// order) and the `inside` cells (see [`bits::inside_bits`]), enclosed ones as the interior
/// mark and the others `open(cell)`.
///
/// # Errors
/// [`SvoError`] from the octree (a depth out of range).
pub(crate) fn build(
    depth: u8,
    inside: CellBits,
    surface: &[(UVec3, Voxel)],
    open: impl Fn(UVec3) -> Voxel + Sync,
) -> Result<(Svo, SolidCounts), SvoError> {
    let dims = inside.dims();
    let cells = classify(inside, surface);
    let levels = pyramid(&cells, depth);
    let flags = |k: u8, b: UVec3| {
        if k == 0 {
            return if b.cmplt(dims).all() {
                cells.flags(b)
            } else {
                0
            };
        }
        let (d, f) = &levels[usize::from(k) - 1];
        if b.cmplt(*d).all() {
            f[b.x as usize + d.x as usize * (b.y as usize + d.y as usize * b.z as usize)]
        } else {
            0
        }
    };
    // Depth-first in octant order, each subtree at level `split` on its own thread: runs come
    // out in Morton order, beside the surface's.
    let split = depth.min(2);
    let roots: Vec<UVec3> = (0..1u64 << (3 * u32::from(split)))
        .map(|code| morton_decode(code) << u32::from(depth - split))
        .collect();
    let parts: Vec<(Vec<Run>, Vec<usize>)> = roots
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
    let mut runs: Vec<Run> = Vec::with_capacity(parts.iter().map(|p| p.0.len()).sum());
    let mut opens: Vec<usize> = Vec::new();
    for (r, o) in parts {
        opens.extend(o.into_iter().map(|i| i + runs.len()));
        runs.extend(r);
    }
    let resolved: Vec<Voxel> = opens.par_iter().map(|&i| open(runs[i].0)).collect();
    for (&i, v) in opens.iter().zip(resolved) {
        runs[i].2 = v;
    }
    let marked = cells.sealed.count_ones();
    drop(cells);
    let svo = Svo::from_runs(depth, false, runs)?;
    Ok((svo, SolidCounts { marked }))
}

/// [`build`] the plain way: every solid cell listed, each tested for enclosure on its own, the
/// octree builder collapsing the interior into tiles. The same octree; for tests.
#[cfg(test)]
pub(crate) fn build_reference(
    depth: u8,
    inside: &CellBits,
    surface: &[(UVec3, Voxel)],
    open: impl Fn(UVec3) -> Voxel,
) -> Result<Svo, SvoError> {
    let dims = inside.dims();
    let kept: std::collections::HashMap<UVec3, Voxel> = surface.iter().copied().collect();
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
                    all.push((c, if enclosed { Voxel::INTERIOR } else { open(c) }));
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
    /// surface voxel on some of the interior's boundary cells and on a few cells outside it.
    fn scene(dims: UVec3, balls: &[(Vec3, f32)], salt: u32) -> (CellBits, Vec<(UVec3, Voxel)>) {
        let inside = |c: UVec3| {
            balls
                .iter()
                .any(|&(o, r)| (c.as_vec3() + 0.5 - o).length() <= r)
        };
        let mut votes = CellBits::new(dims);
        let mut surface = Vec::new();
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
                    }
                }
            }
        }
        surface.sort_by_key(|e| morton_encode(e.0));
        (votes, surface)
    }

    fn open(c: UVec3) -> Voxel {
        Voxel::new(
            [(c.x * 9) as u8, (c.y * 9) as u8, (c.z * 9) as u8, 255],
            Vec3::Z,
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// Property: the octree built from the votes (maximal interior tiles from the pyramid)
        /// equals the one built by listing every voxel, tile for tile.
        #[test]
        fn the_tiled_build_equals_listing_every_voxel(
            (dx, dy, dz) in (9u32..140, 9u32..40, 9u32..40),
            balls in proptest::collection::vec(((0f32..140.0, 0f32..40.0, 0f32..40.0), 2f32..30.0), 1..4),
            salt in 0u32..1000,
        ) {
            let dims = UVec3::new(dx, dy, dz);
            // Rows wider than one 64-cell word.
            let depth = 8;
            let balls: Vec<(Vec3, f32)> = balls.into_iter().map(|((x, y, z), r)| (Vec3::new(x, y, z), r)).collect();
            let (votes, surface) = scene(dims, &balls, salt);
            let (fast, counts) = build(depth, votes.clone(), &surface, open).unwrap();
            let slow = build_reference(depth, &votes, &surface, open).unwrap();
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
        let (votes, surface) = scene(dims, &[(Vec3::new(30.0, 25.0, 32.0), 24.0)], 7);
        let (svo, counts) = build(6, votes, &surface, open).unwrap();
        assert!(counts.marked > 40_000, "{counts:?}");
        assert!(svo.tile_count() > 100, "{} tiles", svo.tile_count());
        assert_eq!(svo.interior_voxels(), counts.marked);
        assert_eq!(svo.exposed_interior(), None);
    }
}

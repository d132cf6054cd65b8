//! A rigid solid's octree built straight from the dense votes grid, following its surface: the
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

use super::dense::cell;
use crate::svo::{Svo, SvoError, Voxel, morton_encode};

/// Heap bytes per grid cell of [`build`] beside the votes' one: the enclosed bits (1/8) and the
/// pyramid (1/8 + 1/64 + …).
pub(crate) const BYTES_PER_CELL: f64 = 1.0 + 0.125 + 0.15;

/// Vote bit: a kept surface voxel is here (on top of `dense::SEED` and the low vote count).
const KEPT: u8 = 0x40;
/// The axes-vote count bits.
const COUNT: u8 = 0x3f;

/// Pyramid flag: every cell of the block is an enclosed interior cell inside the grid.
const ALL: u8 = 1;
/// Pyramid flag: some cell of the block is solid.
const ANY: u8 = 2;

/// Whether a cell with vote byte `v` is solid: a kept surface voxel or interior.
fn solid_vote(v: u8) -> bool {
    v & KEPT != 0 || v & COUNT >= 2
}

/// What the build found.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct SolidCounts {
    /// Interior cells enclosed on all six faces: the interior mark.
    pub(crate) marked: u64,
}

/// The grid's cells as the build sees them: the votes with [`KEPT`] set on kept surface
/// voxels, and which interior cells are enclosed (one bit a cell, rows padded to words).
struct Cells<'a> {
    dims: UVec3,
    votes: &'a [u8],
    row_words: usize,
    sealed: Vec<u64>,
}

impl Cells<'_> {
    fn solid_at(&self, i: usize) -> bool {
        solid_vote(self.votes[i])
    }

    /// The pyramid flags of cell `c` (inside the grid).
    fn flags(&self, c: UVec3) -> u8 {
        (u8::from(self.solid_at(cell(self.dims, c))) * ANY) | (u8::from(self.sealed(c)) * ALL)
    }

    fn sealed(&self, c: UVec3) -> bool {
        let (x, row) = (
            c.x as usize,
            c.y as usize + self.dims.y as usize * c.z as usize,
        );
        self.sealed[row * self.row_words + x / 64] >> (x % 64) & 1 == 1
    }
}

/// Marks kept surface voxels in `votes` and finds the enclosed interior cells.
fn classify<'a>(dims: UVec3, votes: &'a mut [u8], surface: &[(UVec3, Voxel)]) -> Cells<'a> {
    for (c, _) in surface {
        if c.cmplt(dims).all() {
            votes[cell(dims, *c)] |= KEPT;
        }
    }
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let row_words = nx.div_ceil(64);
    let mut sealed = vec![0u64; row_words * ny * nz];
    let votes: &'a [u8] = votes;
    let solid = |x: usize, y: usize, z: usize| solid_vote(votes[x + nx * (y + ny * z)]);
    sealed
        .par_chunks_mut(row_words)
        .enumerate()
        .for_each(|(row, words)| {
            let (y, z) = (row % ny, row / ny);
            if y == 0 || z == 0 || y + 1 == ny || z + 1 == nz {
                return;
            }
            for x in 1..nx.saturating_sub(1) {
                let v = votes[x + nx * row];
                let enclosed = v & KEPT == 0
                    && v & COUNT >= 2
                    && solid(x - 1, y, z)
                    && solid(x + 1, y, z)
                    && solid(x, y - 1, z)
                    && solid(x, y + 1, z)
                    && solid(x, y, z - 1)
                    && solid(x, y, z + 1);
                if enclosed {
                    words[x / 64] |= 1 << (x % 64);
                }
            }
        });
    Cells {
        dims,
        votes,
        row_words,
        sealed,
    }
}

/// Flags of the `2^k` blocks for k = 1..=depth (`levels[k - 1]`, x fastest), with their dims.
/// Level 0 is read from the cells themselves ([`Cells::flags`]), not stored.
fn pyramid(cells: &Cells<'_>, depth: u8) -> Vec<(UVec3, Vec<u8>)> {
    let mut levels: Vec<(UVec3, Vec<u8>)> = Vec::with_capacity(usize::from(depth));
    for k in 1..=depth {
        let d = if k == 1 {
            cells.dims
        } else {
            levels[usize::from(k) - 2].0
        };
        let up = (d + 1) / 2;
        let (ux, uy) = (up.x as usize, up.y as usize);
        let below = |c: UVec3| {
            if k == 1 {
                cells.flags(c)
            } else {
                let f = &levels[usize::from(k) - 2].1;
                f[c.x as usize + d.x as usize * (c.y as usize + d.y as usize * c.z as usize)]
            }
        };
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
                    if c.cmplt(d).all() {
                        let f = below(c);
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
/// order), the interior cells of `votes` (dense, see `dense`), enclosed ones as the interior
/// mark and the others `open(cell)`. `votes` gains [`KEPT`] bits.
///
/// # Errors
/// [`SvoError`] from the octree (a depth out of range).
pub(crate) fn build(
    depth: u8,
    dims: UVec3,
    votes: &mut [u8],
    surface: &[(UVec3, Voxel)],
    open: impl Fn(UVec3) -> Voxel + Sync,
) -> Result<(Svo, SolidCounts), SvoError> {
    let cells = classify(dims, votes, surface);
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
    // Depth-first in octant order: leaves come out in Morton order, beside the surface's.
    let mut leaves: Vec<(UVec3, Voxel)> = Vec::with_capacity(surface.len() * 2);
    let mut opens: Vec<usize> = Vec::new();
    let mut tiles: Vec<(UVec3, u8)> = Vec::new();
    let mut next_surface = 0usize;
    let mut stack: Vec<(UVec3, u8)> = vec![(UVec3::ZERO, depth)];
    while let Some((origin, k)) = stack.pop() {
        let f = flags(k, origin >> u32::from(k));
        if f & ANY == 0 {
            continue;
        }
        if k > 0 && f & ALL != 0 {
            tiles.push((origin, k));
            continue;
        }
        if k == 0 {
            let code = morton_encode(origin);
            while next_surface < surface.len() && morton_encode(surface[next_surface].0) < code {
                next_surface += 1;
            }
            if surface.get(next_surface).is_some_and(|s| s.0 == origin) {
                leaves.push(surface[next_surface]);
                next_surface += 1;
            } else if cells.sealed(origin) {
                leaves.push((origin, Voxel::INTERIOR));
            } else {
                opens.push(leaves.len());
                leaves.push((origin, Voxel::default()));
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
    let resolved: Vec<Voxel> = opens.par_iter().map(|&i| open(leaves[i].0)).collect();
    for (&i, v) in opens.iter().zip(resolved) {
        leaves[i].1 = v;
    }
    let marked = cells
        .sealed
        .par_iter()
        .map(|w| u64::from(w.count_ones()))
        .sum();
    let mut svo = Svo::from_voxels(depth, false, leaves)?;
    for &(origin, k) in &tiles {
        svo.put_tile(origin, k, Voxel::INTERIOR);
    }
    if !tiles.is_empty() {
        // Paths built tile by tile leave freed blocks behind.
        svo.compact();
    }
    Ok((svo, SolidCounts { marked }))
}

/// [`build`] the plain way: every solid cell listed, the octree builder collapsing the
/// interior into tiles. The same octree; for tests.
#[cfg(test)]
pub(crate) fn build_reference(
    depth: u8,
    dims: UVec3,
    votes: &mut [u8],
    surface: &[(UVec3, Voxel)],
    open: impl Fn(UVec3) -> Voxel,
) -> Result<Svo, SvoError> {
    let cells = classify(dims, votes, surface);
    let kept: std::collections::HashMap<UVec3, Voxel> = surface.iter().copied().collect();
    let mut all = Vec::new();
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                let c = UVec3::new(x, y, z);
                if let Some(v) = kept.get(&c) {
                    all.push((c, *v));
                } else if cells.solid_at(cell(dims, c)) {
                    all.push((
                        c,
                        if cells.sealed(c) {
                            Voxel::INTERIOR
                        } else {
                            open(c)
                        },
                    ));
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
    fn scene(dims: UVec3, balls: &[(Vec3, f32)], salt: u32) -> (Vec<u8>, Vec<(UVec3, Voxel)>) {
        let inside = |c: UVec3| {
            balls
                .iter()
                .any(|&(o, r)| (c.as_vec3() + 0.5 - o).length() <= r)
        };
        let mut votes = vec![0u8; (dims.x * dims.y * dims.z) as usize];
        let mut surface = Vec::new();
        for z in 0..dims.z {
            for y in 0..dims.y {
                for x in 0..dims.x {
                    let c = UVec3::new(x, y, z);
                    let h = (x * 73 + y * 151 + z * 37 + salt).wrapping_mul(2_654_435_761) >> 24;
                    if inside(c) {
                        votes[cell(dims, c)] = 2 + (h % 2) as u8;
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
            (dx, dy, dz) in (9u32..40, 9u32..40, 9u32..40),
            balls in proptest::collection::vec(((0f32..40.0, 0f32..40.0, 0f32..40.0), 2f32..15.0), 1..4),
            salt in 0u32..1000,
        ) {
            let dims = UVec3::new(dx, dy, dz);
            let depth = 6;
            let balls: Vec<(Vec3, f32)> = balls.into_iter().map(|((x, y, z), r)| (Vec3::new(x, y, z), r)).collect();
            let (votes, surface) = scene(dims, &balls, salt);
            let (mut a, mut b) = (votes.clone(), votes);
            let (fast, counts) = build(depth, dims, &mut a, &surface, open).unwrap();
            let slow = build_reference(depth, dims, &mut b, &surface, open).unwrap();
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
        let (mut votes, surface) = scene(dims, &[(Vec3::new(30.0, 25.0, 32.0), 24.0)], 7);
        let (svo, counts) = build(6, dims, &mut votes, &surface, open).unwrap();
        assert!(counts.marked > 40_000, "{counts:?}");
        assert!(svo.tile_count() > 100, "{} tiles", svo.tile_count());
        assert_eq!(svo.interior_voxels(), counts.marked);
        assert_eq!(svo.exposed_interior(), None);
    }
}

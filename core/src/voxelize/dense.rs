//! Interior fill on a dense grid, with each interior voxel taking the attributes of its
//! *nearest surface voxel*.
//!
//! The three axes' inside runs ([`super::fill::cast`]) are voted into one byte per grid cell
//! (interior where at least two axes say inside, as in [`super::fill::vote`]). The nearest
//! surface voxel of every cell is the exact Euclidean feature transform of the surface voxels
//! (the seeds), computed in three separable passes (x, then y, then z), each the lower envelope
//! of parabolas along one line (Felzenszwalb and Huttenlocher, "Distance Transforms of Sampled
//! Functions", 2012): linear in the grid's cells, no sort, no search. The interior is then read
//! out in Morton order (8³ bricks in Morton order, Morton order inside each), which is the
//! order the octree builder sorts into.
//!
//! It costs [`DENSE_BYTES_PER_CELL`] bytes per cell of the grid, so it is used up to
//! [`DENSE_MAX_CELLS`] cells; a larger grid falls back to the sparse fill, whose interior takes
//! the nearest of the crossings bounding it along the axes.

use glam::UVec3;
use rayon::prelude::*;

use super::fill::{Axis, AxisFill};
use crate::svo::morton_encode;

/// Bytes per grid cell: the votes (1) and the three passes' nearest indices (2 each).
pub(crate) const DENSE_BYTES_PER_CELL: u64 = 7;

/// Largest grid the dense fill takes (2^28 cells, 1.9 GB); beyond it the sparse fill runs.
pub(crate) const DENSE_MAX_CELLS: u64 = 1 << 28;

/// No seed on the line.
const NONE: u16 = u16::MAX;

/// Vote bit for "a surface voxel is here" (the low bits count the axes that say inside).
pub(crate) const SEED: u8 = 0x80;

/// The interior as a dense grid of votes, with each cell's nearest seed.
pub(crate) struct DenseFill {
    dims: UVec3,
    /// Per cell (x fastest, then y, then z): axes that say inside (low bits), [`SEED`].
    votes: Vec<u8>,
    /// Nearest seed's x along the cell's x row (index `x + X·(y + Y·z)`).
    fx: Vec<u16>,
    /// Nearest 2-D seed's y in the cell's z slice (index `y + Y·(x + X·z)`).
    fy: Vec<u16>,
    /// Nearest 3-D seed's z (index `z + Z·(y + Y·x)`).
    fz: Vec<u16>,
}

/// One byte per cell of `dims` (x fastest, then y, then z): how many of the three axes' inside
/// runs hold it (interior at two or more).
pub(crate) fn vote_grid(dims: UVec3, fills: &[AxisFill; 3]) -> Vec<u8> {
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let mut votes = vec![0u8; nx * ny * nz];
    if votes.is_empty() {
        return votes;
    }
    // In slabs of z, in parallel: a run along z is clipped to the slab; a run along x or y
    // lies at one z (`Axis::unturn`: x's turned y, y's turned x).
    let slab = nz.div_ceil(4 * rayon::current_num_threads()).max(1);
    votes
        .par_chunks_mut(nx * ny * slab)
        .enumerate()
        .for_each(|(s, out)| {
            let (z0, z1) = ((s * slab) as u32, ((s + 1) * slab).min(nz) as u32);
            let local = |c: UVec3| c.x as usize + nx * (c.y as usize + ny * (c.z - z0) as usize);
            for f in fills {
                for (x, y, lo, hi) in f.runs_in(dims) {
                    match f.axis {
                        Axis::Z => {
                            for k in lo.max(z0)..=hi.min(z1 - 1) {
                                out[local(UVec3::new(x, y, k))] += 1;
                            }
                        }
                        Axis::X | Axis::Y => {
                            let at = f.axis.unturn(UVec3::new(x, y, lo));
                            if at.z < z0 || at.z >= z1 {
                                continue;
                            }
                            for k in lo..=hi {
                                out[local(f.axis.unturn(UVec3::new(x, y, k)))] += 1;
                            }
                        }
                    }
                }
            }
        });
    votes
}

/// [`vote_grid`] one run at a time, on one thread: the reference the tests hold it to.
#[cfg(test)]
pub(crate) fn vote_grid_serial(dims: UVec3, fills: &[AxisFill; 3]) -> Vec<u8> {
    let cells = dims.x as usize * dims.y as usize * dims.z as usize;
    let mut votes = vec![0u8; cells];
    for f in fills {
        let turned = f.axis.turn_dims(dims);
        for iv in &f.runs {
            let x = (iv.column & 0x1f_ffff) as u32;
            let y = (iv.column >> 21) as u32;
            if x >= turned.x || y >= turned.y {
                continue;
            }
            for k in iv.k_lo..=iv.k_hi.min(turned.z.saturating_sub(1)) {
                votes[cell(dims, f.axis.unturn(UVec3::new(x, y, k)))] += 1;
            }
        }
    }
    votes
}

/// Whether cell `c` of a [`vote_grid`] of `dims` is interior (inside along at least two axes;
/// [`SEED`] set or not).
pub(crate) fn voted_inside(dims: UVec3, votes: &[u8], c: UVec3) -> bool {
    c.cmplt(dims).all() && (votes[cell(dims, c)] & !SEED) >= 2
}

/// Interior cells of a [`vote_grid`].
pub(crate) fn voted_count(votes: &[u8]) -> u64 {
    votes.par_iter().filter(|&&v| (v & !SEED) >= 2).count() as u64
}

/// Whether a grid of `dims` is small enough for the dense fill (every side must also fit the
/// 16-bit indices).
pub(crate) fn fits(dims: UVec3) -> bool {
    let cells = u64::from(dims.x) * u64::from(dims.y) * u64::from(dims.z);
    cells <= DENSE_MAX_CELLS && dims.max_element() < u32::from(NONE)
}

impl DenseFill {
    /// Votes the three axes' runs and computes every cell's nearest seed. `seeds` are the
    /// surface voxels' coordinates. The caller checks [`fits`] first.
    pub(crate) fn new(dims: UVec3, fills: &[AxisFill; 3], seeds: &[UVec3]) -> Self {
        let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
        let cells = nx * ny * nz;
        let mut votes = vote_grid(dims, fills);
        for s in seeds {
            if s.cmplt(dims).all() {
                votes[cell(dims, *s)] |= SEED;
            }
        }

        // Pass 1, along x: the nearest seed in the row.
        let mut fx = vec![NONE; cells];
        fx.par_chunks_mut(nx)
            .zip(votes.par_chunks(nx))
            .for_each(|(out, row)| {
                let mut last = NONE;
                for (x, v) in row.iter().enumerate() {
                    if v & SEED != 0 {
                        last = x as u16;
                    }
                    out[x] = last;
                }
                let mut next = NONE;
                for x in (0..nx).rev() {
                    if row[x] & SEED != 0 {
                        next = x as u16;
                    }
                    let take_next = next != NONE
                        && (out[x] == NONE || usize::from(next) - x < x - usize::from(out[x]));
                    if take_next {
                        out[x] = next;
                    }
                }
            });

        // Pass 2, along y in each z slice: the nearest seed of the slice.
        let mut fy = vec![NONE; cells];
        fy.par_chunks_mut(ny).enumerate().for_each_init(
            || Envelope::new(ny.max(nz)),
            |env, (j, out)| {
                let (x, z) = (j % nx, j / nx);
                env.solve(
                    ny,
                    |y| {
                        let s = fx[x + nx * (y + ny * z)];
                        (s != NONE).then(|| sq(x, usize::from(s)))
                    },
                    out,
                );
            },
        );

        // Pass 3, along z: the nearest seed. Lines in y order, so that neighbouring lines
        // read neighbouring entries of `fy` (y fastest there).
        let mut fz = vec![NONE; cells];
        fz.par_chunks_mut(nz).enumerate().for_each_init(
            || Envelope::new(ny.max(nz)),
            |env, (j, out)| {
                let (y, x) = (j % ny, j / ny);
                env.solve(
                    nz,
                    |z| {
                        let sy = fy[y + ny * (x + nx * z)];
                        if sy == NONE {
                            return None;
                        }
                        let sx = fx[x + nx * (usize::from(sy) + ny * z)];
                        Some(sq(x, usize::from(sx)) + sq(y, usize::from(sy)))
                    },
                    out,
                );
            },
        );
        Self {
            dims,
            votes,
            fx,
            fy,
            fz,
        }
    }

    /// Whether cell `c` is interior (inside along at least two axes).
    pub(crate) fn contains(&self, c: UVec3) -> bool {
        voted_inside(self.dims, &self.votes, c)
    }

    /// The surface voxel nearest cell `c` (`None` when there is no surface at all).
    pub(crate) fn nearest_seed(&self, c: UVec3) -> Option<UVec3> {
        let (nx, ny, nz) = (
            self.dims.x as usize,
            self.dims.y as usize,
            self.dims.z as usize,
        );
        let (x, y) = (c.x as usize, c.y as usize);
        let sz = self.fz[c.z as usize + nz * (y + ny * x)];
        if sz == NONE {
            return None;
        }
        let sz = usize::from(sz);
        let sy = usize::from(self.fy[y + ny * (x + nx * sz)]);
        let sx = self.fx[x + nx * (sy + ny * sz)];
        Some(UVec3::new(u32::from(sx), sy as u32, sz as u32))
    }

    /// Interior cells.
    pub(crate) fn len(&self) -> u64 {
        voted_count(&self.votes)
    }

    /// `each(cell, nearest surface voxel)` for every interior cell, in Morton order of the
    /// cells (8³ bricks in Morton order, Morton order inside each), keeping the `Some`s.
    pub(crate) fn interior<T: Send>(
        &self,
        each: impl Fn(UVec3, UVec3) -> Option<T> + Sync,
    ) -> Vec<T> {
        const B: u32 = 8;
        let bricks = (self.dims + UVec3::splat(B - 1)) / B;
        let mut order: Vec<(u64, UVec3)> = (0..bricks.z)
            .flat_map(|z| {
                (0..bricks.y).flat_map(move |y| {
                    (0..bricks.x).map(move |x| {
                        let b = UVec3::new(x, y, z);
                        (morton_encode(b), b)
                    })
                })
            })
            .collect();
        order.par_sort_unstable_by_key(|e| e.0);
        let mut local: Vec<(u64, UVec3)> = (0..B * B * B)
            .map(|i| {
                let c = UVec3::new(i % B, (i / B) % B, i / (B * B));
                (morton_encode(c), c)
            })
            .collect();
        local.sort_unstable_by_key(|e| e.0);
        let each = &each;
        let local = &local;
        order
            .par_iter()
            .flat_map_iter(|&(_, b)| {
                let base = b * B;
                local.iter().filter_map(move |&(_, l)| {
                    let c = base + l;
                    if !self.contains(c) {
                        return None;
                    }
                    self.nearest_seed(c).and_then(|s| each(c, s))
                })
            })
            .collect()
    }
}

/// Index of cell `c` in `votes` and `fx` (x fastest, then y, then z).
pub(crate) fn cell(dims: UVec3, c: UVec3) -> usize {
    c.x as usize + dims.x as usize * (c.y as usize + dims.y as usize * c.z as usize)
}

fn sq(a: usize, b: usize) -> u64 {
    let d = a.abs_diff(b) as u64;
    d * d
}

/// Lower envelope of the parabolas `(q − p)² + g(p)` over a line (scratch reused per thread).
struct Envelope {
    /// Sites of the envelope's parabolas.
    v: Vec<usize>,
    /// Their values `g(v)`.
    g: Vec<u64>,
    /// Where each parabola starts being the lowest.
    from: Vec<f64>,
}

impl Envelope {
    fn new(n: usize) -> Self {
        Self {
            v: Vec::with_capacity(n),
            g: Vec::with_capacity(n),
            from: Vec::with_capacity(n + 1),
        }
    }

    /// For every `q` in `0..n`, the site `p` minimising `(q − p)² + g(p)` over the sites with
    /// a value (`NONE` when none has one).
    fn solve(&mut self, n: usize, g: impl Fn(usize) -> Option<u64>, out: &mut [u16]) {
        self.v.clear();
        self.g.clear();
        self.from.clear();
        for p in 0..n {
            let Some(gp) = g(p) else { continue };
            // Exact in f64: values below 2^50, positions below 2^16.
            let hp = gp as f64 + (p * p) as f64;
            let mut s = f64::NEG_INFINITY;
            while let (Some(&v), Some(&gv)) = (self.v.last(), self.g.last()) {
                let hv = gv as f64 + (v * v) as f64;
                s = (hp - hv) / (2.0 * (p - v) as f64);
                if s <= self.from[self.from.len() - 1] {
                    self.v.pop();
                    self.g.pop();
                    self.from.pop();
                    s = f64::NEG_INFINITY;
                } else {
                    break;
                }
            }
            self.v.push(p);
            self.g.push(gp);
            self.from.push(s);
        }
        if self.v.is_empty() {
            out[..n].fill(NONE);
            return;
        }
        let mut k = 0;
        for (q, o) in out[..n].iter_mut().enumerate() {
            while k + 1 < self.v.len() && self.from[k + 1] < q as f64 {
                k += 1;
            }
            *o = self.v[k] as u16;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::fill::Axis;
    use super::*;

    /// The nearest seed by brute force (squared distance; ties by any).
    fn brute(seeds: &[UVec3], c: UVec3) -> u64 {
        seeds
            .iter()
            .map(|s| {
                let d = s.as_ivec3() - c.as_ivec3();
                d.length_squared() as u64
            })
            .min()
            .unwrap_or(u64::MAX)
    }

    fn d2(a: UVec3, b: UVec3) -> u64 {
        (a.as_ivec3() - b.as_ivec3()).length_squared() as u64
    }

    #[test]
    fn the_feature_transform_finds_the_nearest_seed_exactly() {
        // Random seeds in an uneven box, including its faces and corners; every cell's seed
        // is at the brute-force nearest distance.
        let dims = UVec3::new(23, 17, 29);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |m: u32| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % u64::from(m)) as u32
        };
        for count in [1usize, 2, 7, 60, 400] {
            let mut seeds: Vec<UVec3> = (0..count)
                .map(|_| UVec3::new(next(dims.x), next(dims.y), next(dims.z)))
                .collect();
            if count == 400 {
                seeds.push(UVec3::ZERO);
                seeds.push(dims - UVec3::ONE);
            }
            let empty = [
                AxisFill::empty(Axis::Z),
                AxisFill::empty(Axis::X),
                AxisFill::empty(Axis::Y),
            ];
            let f = DenseFill::new(dims, &empty, &seeds);
            for z in 0..dims.z {
                for y in 0..dims.y {
                    for x in 0..dims.x {
                        let c = UVec3::new(x, y, z);
                        let s = f.nearest_seed(c).expect("seeds exist");
                        assert!(seeds.contains(&s), "{s} is not a seed");
                        assert_eq!(d2(s, c), brute(&seeds, c), "{count} seeds, cell {c}");
                    }
                }
            }
        }
    }

    #[test]
    fn no_seed_gives_none_and_a_one_cell_grid_works() {
        let empty = [
            AxisFill::empty(Axis::Z),
            AxisFill::empty(Axis::X),
            AxisFill::empty(Axis::Y),
        ];
        let f = DenseFill::new(UVec3::new(4, 5, 6), &empty, &[]);
        assert_eq!(f.nearest_seed(UVec3::new(1, 2, 3)), None);
        assert!(f.interior(|c, _| Some(c)).is_empty());
        assert_eq!(f.len(), 0);
        let one = DenseFill::new(UVec3::ONE, &empty, &[UVec3::ZERO]);
        assert_eq!(one.nearest_seed(UVec3::ZERO), Some(UVec3::ZERO));
        assert!(!one.contains(UVec3::ZERO));
        assert!(
            !one.contains(UVec3::new(1, 0, 0)),
            "outside the grid is not interior"
        );
    }

    #[test]
    fn the_largest_sides_and_grids_are_refused_before_allocation() {
        assert!(fits(UVec3::new(512, 512, 512)));
        assert!(fits(UVec3::new(1 << 10, 1 << 9, 1 << 9)));
        assert!(!fits(UVec3::new(1 << 10, 1 << 10, 1 << 9)), "2^29 cells");
        assert!(
            !fits(UVec3::new(65_535, 1, 1)),
            "a side that needs the NONE index"
        );
        assert!(fits(UVec3::new(65_534, 1, 1)));
    }
}

#[cfg(test)]
mod vote_tests {
    use proptest::prelude::*;

    use super::super::fill::{Axis, AxisFill};
    use super::super::solid::ColumnRun;
    use super::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Property: the votes written in parallel by z slab equal those written run by run,
        /// for runs along every axis, clipped at the grid's far side or not.
        #[test]
        fn votes_by_slab_equal_votes_run_by_run(
            (dx, dy, dz) in (1u32..40, 1u32..40, 1u32..70),
            runs in proptest::collection::vec((0usize..3, 0u32..45, 0u32..45, 0u32..75, 0u32..30), 0..60),
        ) {
            let dims = UVec3::new(dx, dy, dz);
            let mut fills = [AxisFill::empty(Axis::Z), AxisFill::empty(Axis::X), AxisFill::empty(Axis::Y)];
            for (a, x, y, k, len) in runs {
                fills[a].runs.push(ColumnRun {
                    column: u64::from(y) << 21 | u64::from(x),
                    k_lo: k,
                    k_hi: k + len,
                });
            }
            prop_assert_eq!(vote_grid(dims, &fills), vote_grid_serial(dims, &fills));
        }
    }
}

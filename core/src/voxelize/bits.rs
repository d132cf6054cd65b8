//! One bit per cell of the solid import's grid, rows padded to whole 64-bit words, so that the
//! vote, the enclosure test and the first pyramid level of a rigid solid ([`super::sealed`]) run
//! 64 cells at a time. The interior is the majority of three axes' inside bits (at least two of
//! three, as [`super::dense::vote_grid`] counts them).

use glam::UVec3;
use rayon::prelude::*;

use super::fill::{Axis, AxisFill};

/// A grid of bits: cell `(x, y, z)` is bit `x % 64` of word `x / 64` of row `y + Y·z`.
#[derive(Clone, PartialEq, Eq)]
pub(crate) struct CellBits {
    dims: UVec3,
    row_words: usize,
    words: Vec<u64>,
}

impl std::fmt::Debug for CellBits {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CellBits")
            .field("dims", &self.dims)
            .field("ones", &self.count_ones())
            .finish_non_exhaustive()
    }
}

/// Bytes per grid cell of a [`CellBits`] (rows padding aside).
pub(crate) const BYTES_PER_CELL: f64 = 0.125;

/// Largest grid a rigid solid is built on from bits, counting each row padded to whole words
/// (2^30 cells: any grid of depth 10; about 0.41 bytes a cell in all, see
/// `sealed::BYTES_PER_CELL`).
pub(crate) const MAX_CELLS: u64 = 1 << 30;

/// Cells of a grid of `dims` with each row padded to whole words: what its bits cost.
pub(crate) fn padded_cells(dims: UVec3) -> u64 {
    u64::from(dims.x).div_ceil(64) * 64 * u64::from(dims.y) * u64::from(dims.z)
}

/// Whether a grid of `dims` is small enough for the bits of a rigid solid.
pub(crate) fn fits(dims: UVec3) -> bool {
    padded_cells(dims) <= MAX_CELLS
}

/// z slices a slab of [`inside_bits`] holds, and how many slabs it writes at once.
fn slabs(dims: UVec3) -> (usize, usize) {
    let nz = dims.z as usize;
    let slab = nz.div_ceil(4 * rayon::current_num_threads()).clamp(1, 64);
    (slab, nz.div_ceil(slab).min(rayon::current_num_threads()))
}

/// Heap bytes [`inside_bits`] holds for a moment beside its result: each slab in flight keeps
/// its y runs as columns and as rows (about twice its own bits) and one word of z bits a
/// column of the grid (whatever the slab's height).
pub(crate) fn inside_bits_scratch_bytes(dims: UVec3) -> u64 {
    let (slab, in_flight) = slabs(dims);
    let (nx, ny) = (u64::from(dims.x), u64::from(dims.y));
    let slab_words = nx.div_ceil(64) * ny * slab as u64;
    let column_words = nx * u64::from(dims.y).div_ceil(64) * slab as u64;
    in_flight as u64 * 8 * (nx * ny + slab_words + column_words)
}

impl CellBits {
    /// All clear.
    pub(crate) fn new(dims: UVec3) -> Self {
        let row_words = (dims.x as usize).div_ceil(64);
        Self {
            dims,
            row_words,
            words: vec![0; row_words * dims.y as usize * dims.z as usize],
        }
    }

    pub(crate) fn dims(&self) -> UVec3 {
        self.dims
    }

    /// Words per row.
    pub(crate) fn row_words(&self) -> usize {
        self.row_words
    }

    /// Whether cell `c` is set (false outside the grid).
    pub(crate) fn get(&self, c: UVec3) -> bool {
        c.cmplt(self.dims).all() && {
            let i = self.row_index(c.y, c.z) * self.row_words + c.x as usize / 64;
            self.words[i] >> (c.x % 64) & 1 == 1
        }
    }

    /// Makes these bits a copy of `other`'s (of the same dims), keeping this allocation.
    pub(crate) fn copy_from(&mut self, other: &CellBits) {
        debug_assert_eq!(self.dims, other.dims);
        self.words.copy_from_slice(&other.words);
    }

    /// Sets cell `c` (inside the grid).
    pub(crate) fn set(&mut self, c: UVec3) {
        let i = self.row_index(c.y, c.z) * self.row_words + c.x as usize / 64;
        self.words[i] |= 1 << (c.x % 64);
    }

    fn row_index(&self, y: u32, z: u32) -> usize {
        y as usize + self.dims.y as usize * z as usize
    }

    /// Row `(y, z)`'s words, or `None` outside the grid.
    pub(crate) fn row(&self, y: u32, z: u32) -> Option<&[u64]> {
        (y < self.dims.y && z < self.dims.z).then(|| {
            let r = self.row_index(y, z) * self.row_words;
            &self.words[r..r + self.row_words]
        })
    }

    /// Cells set.
    pub(crate) fn count_ones(&self) -> u64 {
        self.words
            .par_iter()
            .map(|w| u64::from(w.count_ones()))
            .sum()
    }

    /// Every row's words, mutably, with the row's `(y, z)`, in parallel.
    pub(crate) fn par_rows_mut(
        &mut self,
    ) -> impl IndexedParallelIterator<Item = (u32, u32, &mut [u64])> {
        let ny = self.dims.y.max(1);
        self.words
            .par_chunks_mut(self.row_words.max(1))
            .enumerate()
            .map(move |(r, w)| ((r as u32) % ny, (r as u32) / ny, w))
    }
}

impl CellBits {
    /// The set cell nearest `c` by centre distance (ties to the smaller Morton code) when one
    /// lies within distance `r_max` of it, else `None`: cubes of radius 1, 2, … `r_max` around
    /// `c` are read a row at a time, and a cube's nearest is the answer once its distance is at
    /// most the radius (every cell outside the cube is farther).
    pub(crate) fn nearest_within(&self, c: UVec3, r_max: u32) -> Option<UVec3> {
        let (ci, hi) = (c.as_ivec3(), self.dims.as_ivec3() - 1);
        for r in 1..=r_max as i32 {
            let lo = (ci - r).max(glam::IVec3::ZERO);
            let up = (ci + r).min(hi);
            let mut best: Option<(i32, u64, UVec3)> = None;
            for z in lo.z..=up.z {
                for y in lo.y..=up.y {
                    let row = self.row_index(y as u32, z as u32) * self.row_words;
                    let dyz = (y - ci.y).pow(2) + (z - ci.z).pow(2);
                    for w in (lo.x / 64)..=(up.x / 64) {
                        let base = w * 64;
                        let from = (lo.x - base).max(0);
                        let to = (up.x - base).min(63);
                        let mut bits = self.words[row + w as usize] >> from << from;
                        bits &= u64::MAX >> (63 - to);
                        while bits != 0 {
                            let x = base + bits.trailing_zeros() as i32;
                            bits &= bits - 1;
                            let q = UVec3::new(x as u32, y as u32, z as u32);
                            let key = (dyz + (x - ci.x).pow(2), crate::svo::morton_encode(q));
                            if best.is_none_or(|b| key < (b.0, b.1)) {
                                best = Some((key.0, key.1, q));
                            }
                        }
                    }
                }
            }
            if let Some((d2, _, q)) = best
                && d2 <= r * r
            {
                return Some(q);
            }
        }
        None
    }
}

/// The even bits of `w` (bits 0, 2, … 62) packed into its low 32 bits.
fn even_bits(w: u64) -> u64 {
    let mut x = w & 0x5555_5555_5555_5555;
    x = (x | x >> 1) & 0x3333_3333_3333_3333;
    x = (x | x >> 2) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | x >> 4) & 0x00ff_00ff_00ff_00ff;
    x = (x | x >> 8) & 0x0000_ffff_0000_ffff;
    (x | x >> 16) & 0x0000_0000_ffff_ffff
}

/// The 2×2×2 blocks of a grid of `dims` as bits, 32 blocks a word: with `all`, a block is set
/// when all eight of its cells are set and inside the grid; without, when any of its cells is
/// set. `row(y, z, out)` gives row `(y, z)` of the grid (its words, padding clear); rows outside
/// the grid are read clear.
pub(crate) fn halve(dims: UVec3, all: bool, row: impl Fn(u32, u32, &mut [u64]) + Sync) -> CellBits {
    let mut out = CellBits::new((dims + 1) / 2);
    let n = (dims.x as usize).div_ceil(64);
    out.par_rows_mut().for_each_init(
        || vec![0u64; 2 * n],
        |scratch, (by, bz, words)| {
            let (acc, read) = scratch.split_at_mut(n);
            acc.fill(if all { u64::MAX } else { 0 });
            for (dy, dz) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (y, z) = (2 * by + dy, 2 * bz + dz);
                if y < dims.y && z < dims.z {
                    row(y, z, read);
                } else {
                    read.fill(0);
                }
                for (a, r) in acc.iter_mut().zip(read.iter()) {
                    *a = if all { *a & r } else { *a | r };
                }
            }
            let pairs = |i: usize| {
                acc.get(i).map_or(0, |&a| {
                    even_bits(if all { a & (a >> 1) } else { a | (a >> 1) })
                })
            };
            for (w, o) in words.iter_mut().enumerate() {
                *o = pairs(2 * w) | (pairs(2 * w + 1) << 32);
            }
        },
    );
    out
}

/// Sets bits `lo..=hi` of a row.
fn set_span(row: &mut [u64], lo: u32, hi: u32) {
    let (w0, w1) = ((lo / 64) as usize, (hi / 64) as usize);
    let first = u64::MAX << (lo % 64);
    let last = u64::MAX >> (63 - hi % 64);
    if w0 == w1 {
        row[w0] |= first & last;
        return;
    }
    row[w0] |= first;
    for w in &mut row[w0 + 1..w1] {
        *w = u64::MAX;
    }
    row[w1] |= last;
}

/// The interior of three axes' inside runs: cells inside along at least two axes (the majority
/// of the three axes' bits, 64 cells a word). Written in parallel by slabs of at most 64 z
/// slices. Every axis's runs are set as word spans: along x in the rows themselves, along y in
/// columns of y bits and along z in one word of z bits a column, the last two turned into rows
/// by transposing 64 × 64 bit blocks.
pub(crate) fn inside_bits(dims: UVec3, fills: &[AxisFill; 3]) -> CellBits {
    let mut out = CellBits::new(dims);
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let row_words = out.row_words;
    if out.words.is_empty() {
        return out;
    }
    let (slab, _) = slabs(dims);
    // Words of a column of y bits.
    let col_words = ny.div_ceil(64);
    out.words
        .par_chunks_mut(row_words * ny * slab)
        .enumerate()
        .for_each(|(s, words)| {
            let (z0, z1) = ((s * slab) as u32, ((s + 1) * slab).min(nz) as u32);
            let h = (z1 - z0) as usize;
            let row = |y: usize, dz: usize| (y + ny * dz) * row_words;
            // Runs along y: slice dz, column x holds y bits (`col_words` words).
            let mut ys = vec![0u64; h * nx * col_words];
            // Runs along z: column (x, y) holds its slab's z bits in one word.
            let mut zs = vec![0u64; nx * ny];
            for f in fills {
                for (a, b, lo, hi) in f.runs_in(dims) {
                    match f.axis {
                        // Along x in row (y, z) = (a, b).
                        Axis::X => {
                            if (z0..z1).contains(&b) {
                                let r = row(a as usize, (b - z0) as usize);
                                set_span(&mut words[r..r + row_words], lo, hi);
                            }
                        }
                        // Along y in column (x, z) = (b, a).
                        Axis::Y => {
                            if (z0..z1).contains(&a) {
                                let c = ((a - z0) as usize * nx + b as usize) * col_words;
                                set_span(&mut ys[c..c + col_words], lo, hi);
                            }
                        }
                        // Along z in column (x, y) = (a, b).
                        Axis::Z => {
                            let (lo, hi) = (lo.max(z0), hi.min(z1 - 1));
                            if lo <= hi {
                                let c = a as usize + nx * b as usize;
                                set_span(&mut zs[c..=c], lo - z0, hi - z0);
                            }
                        }
                    }
                }
            }
            // The y runs as rows.
            let mut yx = vec![0u64; words.len()];
            let mut block = [0u64; 64];
            for dz in 0..h {
                for by in 0..col_words {
                    for bx in 0..row_words {
                        for (i, w) in block.iter_mut().enumerate() {
                            let x = bx * 64 + i;
                            *w = if x < nx {
                                ys[(dz * nx + x) * col_words + by]
                            } else {
                                0
                            };
                        }
                        transpose(&mut block);
                        let rows = ny.saturating_sub(by * 64);
                        for (j, &w) in block.iter().enumerate().take(rows) {
                            yx[row(by * 64 + j, dz) + bx] = w;
                        }
                    }
                }
            }
            drop(ys);
            // The z runs as rows, each word voted with its x and y words as it comes.
            for y in 0..ny {
                for bx in 0..row_words {
                    for (i, w) in block.iter_mut().enumerate() {
                        let x = bx * 64 + i;
                        *w = if x < nx { zs[x + nx * y] } else { 0 };
                    }
                    transpose(&mut block);
                    for (dz, &z) in block.iter().enumerate().take(h) {
                        let i = row(y, dz) + bx;
                        let (x, y) = (words[i], yx[i]);
                        words[i] = (x & y) | (x & z) | (y & z);
                    }
                }
            }
        });
    out
}

/// Transposes a 64 × 64 bit matrix in place: bit `j` of word `i` becomes bit `i` of word `j`
/// (the off-diagonal halves swapped, then their quarters, … down to single bits).
fn transpose(a: &mut [u64; 64]) {
    let mut j = 32;
    let mut m: u64 = 0x0000_0000_ffff_ffff;
    while j != 0 {
        for k in 0..64 {
            if k & j == 0 {
                let t = ((a[k] >> j) ^ a[k + j]) & m;
                a[k] ^= t << j;
                a[k + j] ^= t;
            }
        }
        j >>= 1;
        m ^= m << j;
    }
}

/// Cell bits shifted so that bit `x` holds cell `x - 1`'s (`down`) or cell `x + 1`'s (`up`),
/// across word boundaries; cells outside the row read clear.
pub(crate) fn neighbours(row: &[u64], w: usize) -> (u64, u64) {
    let down = (row[w] << 1) | w.checked_sub(1).map_or(0, |p| row[p] >> 63);
    let up = (row[w] >> 1) | row.get(w + 1).map_or(0, |n| n << 63);
    (down, up)
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::super::dense::{vote_grid_serial, voted_inside};
    use super::super::solid::ColumnRun;
    use super::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Property: the majority of the three axes' bits, written by slab, is the cells that the
        /// run-by-run byte votes count inside along two or more axes; rows and y columns wider
        /// than a word included.
        #[test]
        fn inside_bits_are_the_cells_voted_inside(
            (dx, dy, dz) in (1u32..140, 1u32..90, 1u32..70),
            runs in proptest::collection::vec((0usize..3, any::<u32>(), any::<u32>(), any::<u32>(), 0u32..140), 0..400),
            full in 0usize..4,
        ) {
            let dims = UVec3::new(dx, dy, dz);
            let mut fills = [AxisFill::empty(Axis::Z), AxisFill::empty(Axis::X), AxisFill::empty(Axis::Y)];
            // Runs in the grid (some clipped at its far side); one axis, when `full` < 3, inside
            // along every column, so that the interior is the union of the other two axes'.
            let mut taken: Vec<std::collections::HashSet<(u32, u32, u32)>> = vec![Default::default(); 3];
            let mut push = |a: usize, x: u32, y: u32, k_lo: u32, k_hi: u32| {
                let t = fills[a].axis.turn_dims(dims);
                // Runs of one axis never overlap in a column (a fill's runs do not); the full
                // axis has no other runs.
                if a != full && (k_lo..=k_hi.min(t.z - 1)).any(|k| !taken[a].insert((x, y, k))) {
                    return;
                }
                fills[a].runs.push(ColumnRun {
                    column: u64::from(y) << 21 | u64::from(x),
                    k_lo,
                    k_hi,
                });
            };
            if full < 3 {
                let t = [Axis::Z, Axis::X, Axis::Y][full].turn_dims(dims);
                for y in 0..t.y {
                    for x in 0..t.x {
                        push(full, x, y, 0, t.z - 1);
                    }
                }
            }
            for (a, x, y, k, len) in runs {
                if a == full {
                    continue;
                }
                let t = [Axis::Z, Axis::X, Axis::Y][a].turn_dims(dims);
                let k = k % t.z;
                push(a, x % t.x, y % t.y, k, k + len);
            }
            let votes = vote_grid_serial(dims, &fills);
            let bits = inside_bits(dims, &fills);
            let mut count = 0;
            for z in 0..dz {
                for y in 0..dy {
                    for x in 0..dx {
                        let c = UVec3::new(x, y, z);
                        prop_assert_eq!(bits.get(c), voted_inside(dims, &votes, c), "cell {}", c);
                        count += u64::from(bits.get(c));
                    }
                }
            }
            prop_assert_eq!(bits.count_ones(), count, "no bit set in a row's padding");
        }

        /// Property: a row's neighbour shifts read each cell's left and right neighbour.
        #[test]
        fn neighbour_shifts_read_the_cells_beside(row in proptest::collection::vec(any::<u64>(), 1..4)) {
            let n = row.len() * 64;
            let bit = |x: usize| row[x / 64] >> (x % 64) & 1 == 1;
            for w in 0..row.len() {
                let (down, up) = neighbours(&row, w);
                for b in 0..64 {
                    let x = w * 64 + b;
                    prop_assert_eq!(down >> b & 1 == 1, x > 0 && bit(x - 1));
                    prop_assert_eq!(up >> b & 1 == 1, x + 1 < n && bit(x + 1));
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Property: the nearest set cell within a radius is the brute-force nearest (centre
        /// distance, ties to the smaller Morton code) when that lies within the radius, and
        /// none otherwise; rows wider than a word and cells at the grid's faces included.
        #[test]
        fn the_nearest_set_cell_within_a_radius_is_the_brute_force_nearest(
            (dx, dy, dz) in (1u32..150, 1u32..12, 1u32..12),
            set in proptest::collection::vec((0u32..150, 0u32..12, 0u32..12), 0..40),
            probes in proptest::collection::vec((0u32..150, 0u32..12, 0u32..12), 1..20),
            r_max in 1u32..5,
        ) {
            let dims = UVec3::new(dx, dy, dz);
            let mut bits = CellBits::new(dims);
            let mut cells = Vec::new();
            for (x, y, z) in set {
                let c = UVec3::new(x % dx, y % dy, z % dz);
                bits.set(c);
                cells.push(c);
            }
            for (x, y, z) in probes {
                let c = UVec3::new(x % dx, y % dy, z % dz);
                let brute = cells
                    .iter()
                    .map(|&q| ((q.as_ivec3() - c.as_ivec3()).length_squared(), crate::svo::morton_encode(q), q))
                    .min_by_key(|b| (b.0, b.1));
                let want = brute.filter(|b| b.0 <= (r_max * r_max) as i32).map(|b| b.2);
                prop_assert_eq!(bits.nearest_within(c, r_max), want, "probe {}", c);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Property: a halved grid's block is set exactly when any (or, with `all`, every) one
        /// of its eight cells is set inside the grid, for odd sides and rows of several words.
        #[test]
        fn halving_takes_any_or_all_of_each_block(
            (dx, dy, dz) in (1u32..300, 1u32..9, 1u32..9),
            density in 0u32..4,
            seed in any::<u64>(),
        ) {
            let dims = UVec3::new(dx, dy, dz);
            let mut bits = CellBits::new(dims);
            for z in 0..dz {
                for y in 0..dy {
                    for x in 0..dx {
                        let h = (u64::from(x) << 20 ^ u64::from(y) << 10 ^ u64::from(z) ^ seed)
                            .wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 61;
                        // Dense grids too, so that whole blocks are set.
                        if h < 2 * u64::from(density) {
                            bits.set(UVec3::new(x, y, z));
                        }
                    }
                }
            }
            let row = |y: u32, z: u32, out: &mut [u64]| {
                out.copy_from_slice(bits.row(y, z).unwrap_or_else(|| unreachable!("in the grid")));
            };
            for all in [false, true] {
                let half = halve(dims, all, row);
                prop_assert_eq!(half.dims(), (dims + 1) / 2);
                let mut ones = 0;
                for z in 0..half.dims().z {
                    for y in 0..half.dims().y {
                        for x in 0..half.dims().x {
                            let b = UVec3::new(x, y, z);
                            let cells = (0..8u32).map(|o| b * 2 + UVec3::new(o & 1, (o >> 1) & 1, o >> 2));
                            let want = if all {
                                cells.into_iter().all(|c| bits.get(c))
                            } else {
                                cells.into_iter().any(|c| bits.get(c))
                            };
                            prop_assert_eq!(half.get(b), want, "block {} all {}", b, all);
                            ones += u64::from(want);
                        }
                    }
                }
                prop_assert_eq!(half.count_ones(), ones, "no bit set in a row's padding");
            }
        }
    }

    #[test]
    fn grids_are_measured_with_their_rows_padded_to_words() {
        assert_eq!(padded_cells(UVec3::new(1, 3, 5)), 64 * 15);
        assert_eq!(padded_cells(UVec3::new(65, 2, 2)), 128 * 4);
        assert!(fits(UVec3::splat(1024)), "any depth-10 grid");
        // 2^28 cells, but a word a cell: 8 bytes each.
        assert!(!fits(UVec3::new(1, 1 << 14, 1 << 14)));
        assert!(fits(UVec3::new(1 << 14, 1 << 14, 1)));
        let flat = UVec3::new(1 << 14, 1 << 14, 1);
        assert!(
            inside_bits_scratch_bytes(flat) >= 8 << 28,
            "a column word each: {}",
            inside_bits_scratch_bytes(flat)
        );
    }

    #[test]
    fn a_transposed_block_swaps_rows_and_columns() {
        let mut a = [0u64; 64];
        for (i, w) in a.iter_mut().enumerate() {
            *w = (i as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ (1 << i);
        }
        let before = a;
        transpose(&mut a);
        for (i, row) in before.iter().enumerate() {
            for (j, column) in a.iter().enumerate() {
                assert_eq!(column >> i & 1, row >> j & 1, "bit {j} of word {i}");
            }
        }
    }

    #[test]
    fn spans_set_exactly_their_bits() {
        for (lo, hi) in [(0, 0), (0, 63), (63, 64), (5, 200), (64, 127), (191, 191)] {
            let mut row = vec![0u64; 4];
            set_span(&mut row, lo, hi);
            for x in 0..256u32 {
                let on = row[(x / 64) as usize] >> (x % 64) & 1 == 1;
                assert_eq!(on, (lo..=hi).contains(&x), "span {lo}..={hi}, bit {x}");
            }
        }
    }
}

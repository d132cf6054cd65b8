//! Direct resampling (paper §3): one stored random pattern of probe offsets; a fragment is
//! solid when more than a threshold fraction of its probes, placed around its centre, land in
//! solid coarse voxels. Any integer factor.
//!
//! The probe pattern is turned into integer tables once (`tab[axis][probe * F + i]` = the
//! coarse cell offset probe `probe` reaches from fragment index `i` along `axis`), so a
//! fragment costs `count` table look-ups and no float work, and the dependency radius is read
//! off the tables exactly.
//!
//! Per §4.2, a cell's fragments depend only on the occupancy (and, for per-material
//! thresholds, the materials) of its probe footprint, so results are kept in a lazily filled
//! cache keyed by that configuration.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use glam::IVec3;
use rand::{RngCore, SeedableRng};
use rand_pcg::Pcg32;

use super::grid::{FastMap, Window};
use super::subdivide::Region;

/// A stored probe pattern for one factor.
#[derive(Debug, Clone)]
pub(crate) struct ProbePattern {
    pub(crate) factor: usize,
    pub(crate) count: usize,
    tab: [Vec<i32>; 3],
    /// Largest cell offset any probe reaches (the dependency radius of a cell's fragments).
    pub(crate) r: i32,
}

/// A uniform `f64` in `[0, 1)` from 53 random bits (independent of `rand`'s float sampling,
/// so the stored pattern never changes with a `rand` upgrade).
fn unit_f64(rng: &mut Pcg32) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

impl ProbePattern {
    pub(crate) fn new(count: usize, spread: f64, seed: u64, factor: usize) -> Self {
        let mut rng = Pcg32::seed_from_u64(seed);
        let offsets: Vec<[f64; 3]> = (0..count)
            .map(|_| std::array::from_fn(|_| (unit_f64(&mut rng) * 2.0 - 1.0) * spread))
            .collect();
        Self::from_offsets(&offsets, factor)
    }

    /// A pattern from explicit offsets (coarse voxels), for hand-made tests.
    pub(crate) fn from_offsets(offsets: &[[f64; 3]], factor: usize) -> Self {
        let count = offsets.len();
        let f = factor as f64;
        let mut r = 0;
        let tab: [Vec<i32>; 3] = std::array::from_fn(|a| {
            let mut t = Vec::with_capacity(count * factor);
            for o in offsets {
                for i in 0..factor {
                    let v = ((i as f64 + 0.5) / f + o[a]).floor() as i32;
                    r = r.max(v.abs());
                    t.push(v);
                }
            }
            t
        });
        Self {
            factor,
            count,
            tab,
            r,
        }
    }

    /// Cell offset reached by probe `j` from fragment index `i` along `axis`.
    #[inline]
    pub(crate) fn cell_offset(&self, axis: usize, j: usize, i: usize) -> i32 {
        self.tab[axis][j * self.factor + i]
    }

    /// Linear window-index tables for a window of side `side` centred on offset zero.
    pub(crate) fn linear_tables(&self, side: usize) -> [Vec<isize>; 3] {
        let s = side as isize;
        let mul = [1, s, s * s];
        std::array::from_fn(|a| self.tab[a].iter().map(|&v| v as isize * mul[a]).collect())
    }
}

/// Needs per material, by altitude parity: a fragment is solid when `hits > need`.
/// Index 256 holds the value used when the pattern has no per-material entry.
#[derive(Debug, Clone)]
pub(crate) struct Needs {
    pub(crate) even: Vec<u32>,
    pub(crate) odd: Vec<u32>,
    /// Whether the need depends on the material (the cache key then carries materials).
    pub(crate) per_material: bool,
    /// Whether even and odd differ (the key then carries the altitude parity when F is odd).
    pub(crate) alternating: bool,
}

/// Precomputed data for evaluating cells of one enhancement.
pub(crate) struct Resampler {
    pub(crate) pattern: ProbePattern,
    pub(crate) needs: Needs,
    lin: [Vec<isize>; 3],
}

impl Resampler {
    pub(crate) fn new(pattern: ProbePattern, needs: Needs) -> Self {
        // Callers gather windows of radius r + 1 (a cell and its neighbours' footprints).
        let lin = pattern.linear_tables((2 * pattern.r + 3) as usize);
        Self {
            pattern,
            needs,
            lin,
        }
    }

    /// Solid fragments of the cell at offset `d` of `win` (radius `win_r`), as an `F³`
    /// region. `cell_y` is the cell's absolute coarse y (for the altitude parity).
    pub(crate) fn cell(&self, win: &Window, d: IVec3, cell_y: i32) -> Region {
        let f = self.pattern.factor;
        let count = self.pattern.count;
        let centre = win.idx(d) as isize;
        let mut out = Region {
            w: f,
            rows: vec![0; f * f],
        };
        let mut tally: Vec<(u8, u32)> = Vec::with_capacity(8);
        for iz in 0..f {
            for iy in 0..f {
                let parity = ((i64::from(cell_y) * f as i64 + iy as i64) & 1) as usize;
                let mut row = 0u128;
                for ix in 0..f {
                    let mut hits = 0u32;
                    tally.clear();
                    for j in 0..count {
                        let k = j * f;
                        let idx = centre
                            + self.lin[0][k + ix]
                            + self.lin[1][k + iy]
                            + self.lin[2][k + iz];
                        let idx = idx as usize;
                        if win.occ[idx] {
                            hits += 1;
                            if self.needs.per_material {
                                let m = win.material[idx];
                                match tally.iter_mut().find(|e| e.0 == m) {
                                    Some(e) => e.1 += 1,
                                    None => tally.push((m, 1)),
                                }
                            }
                        }
                    }
                    if hits == 0 {
                        continue;
                    }
                    let m = if self.needs.per_material {
                        usize::from(majority(&tally))
                    } else {
                        256
                    };
                    let need = if parity == 0 {
                        self.needs.even[m]
                    } else {
                        self.needs.odd[m]
                    };
                    if hits > need {
                        row |= 1 << ix;
                    }
                }
                out.rows[iz * f + iy] = row;
            }
        }
        out
    }

    /// The §4.2 cache key of the cell at offset `d`: footprint occupancy, plus materials and
    /// altitude parity when the thresholds depend on them.
    pub(crate) fn key(&self, win: &Window, d: IVec3, cell_y: i32) -> Vec<u64> {
        let r = self.pattern.r;
        let mut key = Vec::with_capacity(4);
        let mut word = 0u64;
        let mut nbits = 0;
        let mut mats = Vec::new();
        for z in -r..=r {
            for y in -r..=r {
                for x in -r..=r {
                    let i = win.idx(d + IVec3::new(x, y, z));
                    if win.occ[i] {
                        word |= 1 << nbits;
                        if self.needs.per_material {
                            mats.push(win.material[i]);
                        }
                    }
                    nbits += 1;
                    if nbits == 64 {
                        key.push(word);
                        word = 0;
                        nbits = 0;
                    }
                }
            }
        }
        if nbits > 0 {
            key.push(word);
        }
        for chunk in mats.chunks(8) {
            key.push(chunk.iter().rev().fold(0u64, |a, &m| a << 8 | u64::from(m)));
        }
        if self.needs.alternating && self.pattern.factor % 2 == 1 {
            key.push(u64::from(cell_y & 1 == 1));
        }
        key
    }
}

/// Most common material; ties go to the lowest id, so the choice never depends on order.
pub(crate) fn majority(tally: &[(u8, u32)]) -> u8 {
    let mut best = (0u8, 0u32);
    for &(m, n) in tally {
        if n > best.1 || (n == best.1 && m < best.0) {
            best = (m, n);
        }
    }
    best.0
}

/// The lazily filled configuration cache of §4.2, shared by threads. Values are pure
/// functions of their keys, so which thread fills an entry never changes a result.
pub(crate) struct ConfigCache {
    map: Mutex<FastMap<Vec<u64>, Arc<Region>>>,
    /// Look-ups answered from the cache.
    pub(crate) hits: AtomicU64,
    /// Look-ups that evaluated the probes.
    pub(crate) misses: AtomicU64,
    /// Most entries kept; beyond it results are computed and not stored (memory bound).
    capacity: usize,
}

impl ConfigCache {
    pub(crate) fn new(capacity: usize) -> Self {
        Self {
            map: Mutex::new(FastMap::default()),
            hits: AtomicU64::new(0),
            misses: AtomicU64::new(0),
            capacity,
        }
    }

    /// Number of stored configurations.
    pub(crate) fn len(&self) -> usize {
        self.map.lock().map_or(0, |m| m.len())
    }

    pub(crate) fn get_or_compute(
        &self,
        key: Vec<u64>,
        compute: impl FnOnce() -> Region,
    ) -> Arc<Region> {
        if let Ok(map) = self.map.lock()
            && let Some(v) = map.get(&key)
        {
            self.hits.fetch_add(1, Ordering::Relaxed);
            return Arc::clone(v);
        }
        self.misses.fetch_add(1, Ordering::Relaxed);
        let v = Arc::new(compute());
        if let Ok(mut map) = self.map.lock()
            && map.len() < self.capacity
        {
            map.entry(key).or_insert_with(|| Arc::clone(&v));
        }
        v
    }
}

//! Voxel detail enhancement (Smith 2011): artists edit coarse voxels; fine, deterministic
//! fragments follow. See `docs/enhance.md` for the rules, the dependency radius and storage.
//!
//! * [`enhance`] turns a coarse [`Svo`] into a fine one; [`Enhancer`] keeps the state that lets
//!   [`Enhancer::update`] re-enhance only the window a coarse edit can influence, with a result
//!   equal, bit for bit, to a full recompute.
//! * Methods: recursive subdivision (§2, [`LUT`]) and direct resampling (§3).
//! * Surface only (§4.1): a coarse cell whose dependency window is uniform does no work, and
//!   the output stores only the *shell*: solid fragments with at least one empty face
//!   neighbour. The fine model is a surface shell like every other sparse model in Thicket;
//!   consumers that need "is this point inside?" ask [`Enhancer::is_solid_fine`], which answers
//!   from the coarse map where the fine model stores nothing.
//! * Beyond the paper: colour and material (§5), fragment normals, random-walk lighting (§4.4).
//!
//! Fine coordinates: fragment `i` (0..F per axis) of coarse voxel `c` is at `c * F + i`. The
//! fine octree has the smallest depth whose extent holds `extent * F` (for a power-of-two `F`
//! that is `depth + log2 F`); for other factors the cells beyond `extent * F` stay empty.

mod grid;
mod light;
mod resample;
mod settings;
mod subdivide;
mod terrain;

#[cfg(test)]
mod tests;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::{IVec3, UVec3, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::mesh::{linear_to_srgb_byte, srgb_byte_to_linear};
use crate::svo::{EditResult, MAX_DEPTH, MAX_LISTED_VOXELS, Svo, SvoError, Voxel, encode_normal};

use grid::{CoarseGrid, FastMap, Window, cell_key};
use resample::{ConfigCache, Needs, ProbePattern, Resampler};
pub use settings::{
    ColorMode, EnhanceSettings, LightingSettings, MAX_FACTOR, MAX_PROBES, MAX_SPREAD,
    MaterialThreshold, Method, ResampleSettings, SubdivideSettings, ThresholdPattern,
};
pub use subdivide::{CFG_CENTRE, LUT, rule_direct, subdivide_dense};
use subdivide::{CellThresholds, Region, subdivide_cell};
pub use terrain::{MAT_DIRT, MAT_GRASS, MAT_ROCK, sample_terrain};

/// Most configurations the resampling cache keeps (beyond it results are computed, not kept).
const CACHE_CAPACITY: usize = 1 << 16;

/// Cells handed to the thread pool between progress reports and cancel checks.
const CHUNK: usize = 512;

/// Why an enhancement was refused or stopped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EnhanceError {
    /// A setting is out of range.
    #[error("invalid enhancement setting `{field}`: {reason}")]
    Invalid {
        /// Dotted field name.
        field: &'static str,
        /// What is wrong and what is allowed.
        reason: String,
    },
    /// The fine octree would be deeper than the octree allows.
    #[error(
        "factor {factor} on a {extent}³ map needs a fine octree of depth {depth}, more than the \
         maximum {MAX_DEPTH}; use a smaller factor or split the map"
    )]
    TooDeep {
        /// The factor.
        factor: u32,
        /// Coarse voxels per axis.
        extent: u32,
        /// Depth it would need.
        depth: u32,
    },
    /// The coarse octree given to [`Enhancer::update`] is not the one it was built from.
    #[error("coarse map depth {got} differs from the enhancer's {expected}; rebuild the enhancer")]
    DepthMismatch {
        /// Depth at construction.
        expected: u8,
        /// Depth given now.
        got: u8,
    },
    /// The cancel flag was raised.
    #[error("enhancement cancelled")]
    Cancelled,
    /// An octree operation failed.
    #[error(transparent)]
    Svo(#[from] SvoError),
    /// The coarse map stands for more voxels than enhancement copies one by one
    /// ([`MAX_LISTED_VOXELS`]; a solid's inside is stored as tiles).
    #[error(
        "detail enhancement copies the coarse voxels one by one, and this model stands for {} \
         voxels, more than {}; enhance the model at a larger voxel size",
        crate::budget::thousands(*.voxels),
        crate::budget::thousands(*.limit)
    )]
    TooManyVoxels {
        /// Voxels the coarse map stands for.
        voxels: u64,
        /// [`MAX_LISTED_VOXELS`].
        limit: u64,
    },
}

/// [`EnhanceError::TooManyVoxels`] when `coarse` stands for more than [`MAX_LISTED_VOXELS`].
fn check_listable(coarse: &Svo) -> Result<(), EnhanceError> {
    match coarse.too_many_to_list() {
        Some(voxels) => Err(EnhanceError::TooManyVoxels {
            voxels,
            limit: MAX_LISTED_VOXELS,
        }),
        None => Ok(()),
    }
}

/// Progress reporting and cancellation for long runs.
#[derive(Clone, Copy, Default)]
pub struct Control<'a> {
    /// Called with the fraction done (0..=1) from the calling thread between chunks.
    pub progress: Option<&'a (dyn Fn(f32) + Sync)>,
    /// Checked between chunks; when set the run stops with [`EnhanceError::Cancelled`].
    pub cancel: Option<&'a AtomicBool>,
}

/// What a run did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct EnhanceStats {
    /// Coarse solid voxels with an empty face neighbour (the coarse surface).
    pub coarse_surface_voxels: u64,
    /// Cells near the surface that were examined.
    pub candidate_cells: u64,
    /// Candidates whose dependency window was uniform: no work, no storage.
    pub skipped_uniform: u64,
    /// Cells that produced fragments.
    pub cells_with_fragments: u64,
    /// Shell fragments produced (in this run: all for a full run, the window for an update).
    pub fragments: u64,
    /// Resampling cache look-ups answered from the cache (cumulative).
    pub cache_hits: u64,
    /// Resampling cache look-ups that evaluated probes (cumulative).
    pub cache_misses: u64,
    /// Configurations stored in the resampling cache.
    pub cache_entries: u64,
    /// Wall time of the run.
    pub seconds: f64,
}

impl EnhanceStats {
    /// Fraction of cache look-ups answered from the cache (0 when none).
    #[must_use]
    pub fn cache_hit_rate(&self) -> f64 {
        let n = self.cache_hits + self.cache_misses;
        if n == 0 {
            0.0
        } else {
            self.cache_hits as f64 / n as f64
        }
    }
}

/// Enhances `coarse` with `settings` into a new fine octree.
///
/// # Errors
/// See [`Enhancer::new`].
pub fn enhance(coarse: &Svo, settings: &EnhanceSettings) -> Result<Svo, EnhanceError> {
    Ok(Enhancer::new(coarse, settings)?.into_fine())
}

/// What [`crate::scene::VoxelModel::enhanced`] will produce and need, estimated from the coarse map's surface
/// before any fine voxel is made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnhanceEstimate {
    /// Coarse voxels with an empty face neighbour (what gets fragments).
    pub coarse_surface_voxels: u64,
    /// Fine voxels: [`FINE_PER_SURFACE_FACE`] × surface voxels × factor² (the fine surface
    /// follows the coarse one, one fine layer per face area).
    pub fine_voxels: u64,
    /// Peak heap bytes: [`ENHANCE_BYTES_PER_FINE_VOXEL`] per fine voxel plus 256 KiB.
    pub peak_bytes: u64,
}

/// Fine voxels per coarse surface voxel and per factor²: 1.05–1.21 measured on the house and
/// the terrain sample, both methods, factors 2–8 (`the_enhance_estimate_holds_the_measured_peak`).
pub const FINE_PER_SURFACE_FACE: f64 = 1.25;
/// Peak heap bytes per fine voxel (the fine octree, fragment lists and caches): 74–116 measured
/// on the same cases.
pub const ENHANCE_BYTES_PER_FINE_VOXEL: u64 = 130;

/// Estimates an enhancement of `coarse` with `settings` (see [`EnhanceEstimate`]); reads the
/// coarse map only.
///
/// # Errors
/// As [`Enhancer::new`] for bad settings, a fine octree deeper than [`MAX_DEPTH`] or too many
/// coarse voxels.
pub fn estimate(coarse: &Svo, settings: &EnhanceSettings) -> Result<EnhanceEstimate, EnhanceError> {
    let engine = Engine::new(settings, coarse.extent())?;
    check_listable(coarse)?;
    let grid = CoarseGrid::from_svo(coarse);
    let (surface, _) = candidates(&grid, engine.r_out);
    let f = f64::from(settings.factor);
    let fine = (surface as f64 * f * f * FINE_PER_SURFACE_FACE).ceil();
    Ok(EnhanceEstimate {
        coarse_surface_voxels: surface,
        fine_voxels: fine as u64,
        peak_bytes: (256u64 << 10)
            .saturating_add((fine * ENHANCE_BYTES_PER_FINE_VOXEL as f64) as u64),
    })
}

/// Fine occupancy of one coarse cell, for lighting and [`Enhancer::is_solid_fine`].
#[derive(Clone)]
enum CellState {
    Uniform(bool),
    Mixed(Arc<Region>),
}

enum Kind {
    /// `thresholds[material or 256 for empty][parity]`, counts 1..=4.
    Subdivide {
        k: u32,
        thresholds: Vec<[u8; 2]>,
    },
    Resample(Box<Resampler>),
}

/// Everything derived from the settings; shared read-only by the worker threads.
struct Engine {
    settings: EnhanceSettings,
    f: i32,
    fine_depth: u8,
    extent: i32,
    kind: Kind,
    cache: ConfigCache,
    /// Radius of the window one cell's *output* depends on (geometry, normals, colour).
    r_out: i32,
    /// Radius of the window one cell's *fragments* depend on.
    r_cell: i32,
    /// Radius an edit reaches: outputs to recompute lie within this of the edited box.
    r_edit: i32,
    light: Option<light::LightParams>,
    /// Fine occupancy per cell for lighting walks (pure values; invalidated by edits).
    memo: Mutex<FastMap<u64, CellState>>,
}

struct Scratch {
    win: Window,
    sub_win: Window,
    region: Region,
    contrib: Vec<(usize, f32)>,
    tally: Vec<(u8, f32)>,
}

impl Scratch {
    fn new() -> Self {
        Self {
            win: Window::default(),
            sub_win: Window::default(),
            region: Region::default(),
            contrib: Vec::new(),
            tally: Vec::new(),
        }
    }
}

fn ceil_log2(v: u64) -> u32 {
    if v <= 1 {
        0
    } else {
        64 - (v - 1).leading_zeros()
    }
}

impl Engine {
    fn new(settings: &EnhanceSettings, extent: u32) -> Result<Self, EnhanceError> {
        settings.validate()?;
        let f = settings.factor;
        let depth = ceil_log2(u64::from(extent) * u64::from(f)).max(1);
        if depth > u32::from(MAX_DEPTH) {
            return Err(EnhanceError::TooDeep {
                factor: f,
                extent,
                depth,
            });
        }
        let (kind, r_out, r_cell) = match settings.method {
            Method::Subdivide => {
                let thresholds = (0..=256)
                    .map(|m| {
                        let (e, o) = settings
                            .subdivide
                            .threshold
                            .for_material((m < 256).then_some(m as u8));
                        // 0 would fill all of space and > 4 erase everything: clamp (documented).
                        let c = |t: f32| (t as i64).clamp(1, 4) as u8;
                        [c(e), c(o)]
                    })
                    .collect();
                (
                    Kind::Subdivide {
                        k: f.trailing_zeros(),
                        thresholds,
                    },
                    1,
                    1,
                )
            }
            Method::Resample => {
                let r = &settings.resample;
                let pattern = ProbePattern::new(
                    r.probe_count as usize,
                    f64::from(r.spread),
                    r.seed,
                    f as usize,
                );
                let count = r.probe_count;
                // hits > need; need at most count - 1 so a fragment whose probes all hit is
                // solid (keeps uniform solid windows solid: surface-only stays exact).
                let need = |t: f32| {
                    ((f64::from(t) * f64::from(count)).floor() as u64).min(u64::from(count - 1))
                        as u32
                };
                let mut even = Vec::with_capacity(257);
                let mut odd = Vec::with_capacity(257);
                for m in 0..=256 {
                    let (e, o) = r.threshold.for_material((m < 256).then_some(m as u8));
                    even.push(need(e));
                    odd.push(need(o));
                }
                let needs = Needs {
                    alternating: even != odd,
                    per_material: matches!(r.threshold, ThresholdPattern::PerMaterial { .. }),
                    even,
                    odd,
                };
                let res = Resampler::new(pattern, needs);
                let rc = res.pattern.r;
                (Kind::Resample(Box::new(res)), rc + 1, rc)
            }
        };
        let light = settings
            .lighting
            .enabled
            .then(|| light::LightParams::new(&settings.lighting, f));
        let r_edit = match &light {
            Some(l) => r_out.max(l.reach_cells + r_cell),
            None => r_out,
        };
        Ok(Self {
            settings: settings.clone(),
            f: f as i32,
            fine_depth: depth as u8,
            extent: extent as i32,
            kind,
            cache: ConfigCache::new(CACHE_CAPACITY),
            r_out,
            r_cell,
            r_edit,
            light,
            memo: Mutex::new(FastMap::default()),
        })
    }

    fn cell_thresholds(thresholds: &[[u8; 2]], win: &Window) -> CellThresholds {
        std::array::from_fn(|i| {
            if win.occ[i] {
                thresholds[usize::from(win.material[i])]
            } else {
                thresholds[256]
            }
        })
    }

    /// Fragments of cell `c` (at window offset `d` of `win`) as an `F³` region. The window
    /// must be gathered with radius `r_out` around `c - d`.
    fn cell_fragments(&self, win: &Window, c: IVec3, d: IVec3, scratch: &mut Region) -> CellState {
        if !(c.cmpge(IVec3::ZERO).all() && c.cmplt(IVec3::splat(self.extent)).all()) {
            return CellState::Uniform(false);
        }
        if win.uniform_around(d, self.r_cell) {
            return CellState::Uniform(win.occ[win.idx(d)]);
        }
        match &self.kind {
            Kind::Subdivide { k, thresholds } => {
                // Subdivision windows have radius 1 = r_cell, so d is always zero here.
                let t = Self::cell_thresholds(thresholds, win);
                let e = subdivide_cell(win, c, *k, &t, self.extent, scratch);
                CellState::Mixed(Arc::new(crop(&e, self.f as usize)))
            }
            Kind::Resample(res) => {
                let key = res.key(win, d, c.y);
                CellState::Mixed(self.cache.get_or_compute(key, || res.cell(win, d, c.y)))
            }
        }
    }

    /// Fine occupancy state of cell `c` for the lighting oracle (memoised).
    fn oracle_cell(&self, c: IVec3, grid: &CoarseGrid, scratch: &mut Scratch) -> CellState {
        if !grid.inside(c) {
            return CellState::Uniform(false);
        }
        let key = cell_key(c);
        if let Ok(m) = self.memo.lock()
            && let Some(s) = m.get(&key)
        {
            return s.clone();
        }
        let r = match self.kind {
            Kind::Subdivide { .. } => 1,
            Kind::Resample(_) => self.r_out,
        };
        grid.gather(c, r, &mut scratch.sub_win);
        let s = self.cell_fragments(&scratch.sub_win, c, IVec3::ZERO, &mut scratch.region);
        if let Ok(mut m) = self.memo.lock() {
            m.insert(key, s.clone());
        }
        s
    }

    /// Extended region `(F+2)³` of cell `c` (one-fragment margin), from `scratch.win`.
    fn extended(&self, c: IVec3, scratch: &mut Scratch) -> Region {
        let f = self.f as usize;
        match &self.kind {
            Kind::Subdivide { k, thresholds } => {
                let t = Self::cell_thresholds(thresholds, &scratch.win);
                subdivide_cell(&scratch.win, c, *k, &t, self.extent, &mut scratch.region)
            }
            Kind::Resample(_) => {
                let w = f + 2;
                let mut cells: [Option<CellState>; 27] = std::array::from_fn(|_| None);
                let mut get = |d: IVec3, cells: &mut [Option<CellState>; 27]| -> CellState {
                    let i = ((d.z + 1) * 9 + (d.y + 1) * 3 + d.x + 1) as usize;
                    if cells[i].is_none() {
                        cells[i] =
                            Some(self.cell_fragments(&scratch.win, c + d, d, &mut scratch.region));
                    }
                    cells[i].clone().unwrap_or(CellState::Uniform(false))
                };
                let full = low(f);
                let mut e = Region {
                    w,
                    rows: vec![0; w * w],
                };
                let split = |v: usize| -> (i32, usize) {
                    if v == 0 {
                        (-1, f - 1)
                    } else if v == w - 1 {
                        (1, 0)
                    } else {
                        (0, v - 1)
                    }
                };
                let row_of = |s: &CellState, y: usize, z: usize| -> u128 {
                    match s {
                        CellState::Uniform(true) => full,
                        CellState::Uniform(false) => 0,
                        CellState::Mixed(r) => r.row(y, z),
                    }
                };
                for ez in 0..w {
                    let (dz, lz) = split(ez);
                    for ey in 0..w {
                        let (dy, ly) = split(ey);
                        let left = get(IVec3::new(-1, dy, dz), &mut cells);
                        let mid = get(IVec3::new(0, dy, dz), &mut cells);
                        let right = get(IVec3::new(1, dy, dz), &mut cells);
                        let row = (row_of(&left, ly, lz) >> (f - 1) & 1)
                            | row_of(&mid, ly, lz) << 1
                            | (row_of(&right, ly, lz) & 1) << (f + 1);
                        e.rows[ez * w + ey] = row;
                    }
                }
                e
            }
        }
    }

    /// The shell fragments of cell `c`, appended to `out`. Pure function of the coarse window
    /// of radius `r_out` (plus the lighting window when lighting is on).
    fn cell_output(
        &self,
        grid: &CoarseGrid,
        c: IVec3,
        scratch: &mut Scratch,
        out: &mut Vec<(UVec3, Voxel)>,
    ) -> bool {
        grid.gather(c, self.r_out, &mut scratch.win);
        if scratch.win.uniform() {
            return false;
        }
        let f = self.f as usize;
        let e = self.extended(c, scratch);
        let interior = low(f) << 1;
        let base = c * self.f;
        let before = out.len();
        for z in 1..=f {
            for y in 1..=f {
                let s = e.row(y, z);
                let all6 = (s >> 1)
                    & (s << 1)
                    & e.row(y - 1, z)
                    & e.row(y + 1, z)
                    & e.row(y, z - 1)
                    & e.row(y, z + 1);
                let mut shell = s & interior & !all6;
                while shell != 0 {
                    let x = shell.trailing_zeros() as usize;
                    shell &= shell - 1;
                    let local = IVec3::new(x as i32 - 1, y as i32 - 1, z as i32 - 1);
                    let p = base + local;
                    let n = normal_at(&e, x, y, z);
                    let (color, material) = self.fragment_color(local, scratch);
                    let color = match &self.light {
                        Some(l) => l.shade(self, grid, p, n, color, scratch),
                        None => color,
                    };
                    out.push((
                        p.as_uvec3(),
                        Voxel {
                            color,
                            normal: encode_normal(n),
                            material,
                            skin: Default::default(),
                        },
                    ));
                }
            }
        }
        out.len() > before
    }

    /// Colour and material of fragment `local` of cell `c` from its contributing voxels.
    fn fragment_color(&self, local: IVec3, scratch: &mut Scratch) -> ([u8; 4], u8) {
        let win = &scratch.win;
        let contrib = &mut scratch.contrib;
        contrib.clear();
        let f = self.f as f32;
        match &self.kind {
            Kind::Subdivide { .. } => {
                // Trilinear weights of the 2×2×2 nearest cell centres, solid cells only. Only
                // offsets within 1 of `u` per axis can weigh anything: two per axis, visited in
                // the same ascending order as a full 3×3×3 scan.
                let u = (local.as_vec3() + 0.5) / f - 0.5;
                let range = |v: f32| if v < 0.0 { -1..=0 } else { 0..=1 };
                for dz in range(u.z) {
                    for dy in range(u.y) {
                        for dx in range(u.x) {
                            let d = IVec3::new(dx, dy, dz);
                            let i = win.idx(d);
                            // Interior voxels are solid but have no colour to give.
                            if !win.occ[i] || win.interior[i] {
                                continue;
                            }
                            let t = (Vec3::ONE - (u - d.as_vec3()).abs()).max(Vec3::ZERO);
                            let wgt = t.x * t.y * t.z;
                            if wgt > 0.0 {
                                contrib.push((i, wgt));
                            }
                        }
                    }
                }
                if contrib.is_empty() {
                    // Grown from a diagonal neighbour: take the nearest solid cell.
                    let mut best: Option<(f32, usize)> = None;
                    for dz in -1..=1 {
                        for dy in -1..=1 {
                            for dx in -1..=1 {
                                let d = IVec3::new(dx, dy, dz);
                                let i = win.idx(d);
                                let dist = (u - d.as_vec3()).length_squared();
                                if win.occ[i] && !win.interior[i] && best.is_none_or(|b| dist < b.0)
                                {
                                    best = Some((dist, i));
                                }
                            }
                        }
                    }
                    if let Some((_, i)) = best {
                        contrib.push((i, 1.0));
                    }
                }
            }
            Kind::Resample(res) => {
                let pat = &res.pattern;
                for j in 0..pat.count {
                    let d = IVec3::new(
                        pat.cell_offset(0, j, local.x as usize),
                        pat.cell_offset(1, j, local.y as usize),
                        pat.cell_offset(2, j, local.z as usize),
                    );
                    let i = win.idx(d);
                    if win.occ[i] && !win.interior[i] {
                        match contrib.iter_mut().find(|e| e.0 == i) {
                            Some(e) => e.1 += 1.0,
                            None => contrib.push((i, 1.0)),
                        }
                    }
                }
            }
        }
        pick_color(win, contrib, &mut scratch.tally, self.settings.color)
    }
}

/// Majority material by weight (ties: lowest id), then that material's colour.
fn pick_color(
    win: &Window,
    contrib: &[(usize, f32)],
    tally: &mut Vec<(u8, f32)>,
    mode: ColorMode,
) -> ([u8; 4], u8) {
    if contrib.is_empty() {
        return ([255; 4], 0);
    }
    tally.clear();
    for &(i, w) in contrib {
        let m = win.material[i];
        match tally.iter_mut().find(|e| e.0 == m) {
            Some(e) => e.1 += w,
            None => tally.push((m, w)),
        }
    }
    let mut best = tally[0];
    for &e in &tally[1..] {
        if e.1 > best.1 || (e.1 == best.1 && e.0 < best.0) {
            best = e;
        }
    }
    let m = best.0;
    let color = match mode {
        ColorMode::Nearest => {
            let mut top: Option<(f32, usize)> = None;
            for &(i, w) in contrib {
                if win.material[i] == m && top.is_none_or(|t| w > t.0) {
                    top = Some((w, i));
                }
            }
            top.map_or([255; 4], |t| win.color[t.1])
        }
        ColorMode::Blend => {
            let mut acc = [0.0f32; 4];
            let mut total = 0.0f32;
            for &(i, w) in contrib {
                if win.material[i] != m {
                    continue;
                }
                let col = win.color[i];
                for ch in 0..3 {
                    acc[ch] += w * srgb_byte_to_linear(col[ch]);
                }
                acc[3] += w * f32::from(col[3]) / 255.0;
                total += w;
            }
            let to8 = |v: f32| linear_to_srgb_byte(v / total);
            [
                to8(acc[0]),
                to8(acc[1]),
                to8(acc[2]),
                ((acc[3] / total).clamp(0.0, 1.0) * 255.0).round() as u8,
            ]
        }
    };
    (color, m)
}

#[inline]
fn low(n: usize) -> u128 {
    if n >= 128 {
        u128::MAX
    } else {
        (1u128 << n) - 1
    }
}

/// Interior `F³` of an `(F+2)³` region.
fn crop(e: &Region, f: usize) -> Region {
    let mut r = Region {
        w: f,
        rows: vec![0; f * f],
    };
    for z in 0..f {
        for y in 0..f {
            r.rows[z * f + y] = (e.row(y + 1, z + 1) >> 1) & low(f);
        }
    }
    r
}

/// Outward normal from the occupancy of the 26 neighbours: minus the gradient of occupancy,
/// each neighbour weighted by `1 / |d|²`; falls back to the open face directions, then +Y.
/// Weights are kept as integers (`6 / |d|²`: 6, 3, 2), so the sum is exact and a fragment's
/// normal never depends on summation order; `x >= 1` (positions are in the margin-extended
/// region).
fn normal_at(e: &Region, x: usize, y: usize, z: usize) -> Vec3 {
    let mut g = IVec3::ZERO;
    for dz in -1i32..=1 {
        for dy in -1i32..=1 {
            // Bits 0, 1, 2 = dx -1, 0, +1.
            let bits = (e.row((y as i32 + dy) as usize, (z as i32 + dz) as usize) >> (x - 1)) & 7;
            if bits == 0 {
                continue;
            }
            let base = dy * dy + dz * dz;
            for (bit, dx) in [(0, -1i32), (1, 0), (2, 1)] {
                let n2 = base + dx * dx;
                if n2 != 0 && bits >> bit & 1 == 1 {
                    g += IVec3::new(dx, dy, dz) * (6 / n2);
                }
            }
        }
    }
    let open = |dx: i32, dy: i32, dz: i32| -> i32 {
        i32::from(!e.get(
            (x as i32 + dx) as usize,
            (y as i32 + dy) as usize,
            (z as i32 + dz) as usize,
        ))
    };
    (-g.as_vec3()).try_normalize().unwrap_or_else(|| {
        let o = IVec3::new(
            open(1, 0, 0) - open(-1, 0, 0),
            open(0, 1, 0) - open(0, -1, 0),
            open(0, 0, 1) - open(0, 0, -1),
        );
        o.as_vec3().try_normalize().unwrap_or(Vec3::Y)
    })
}

/// Enhancement state: the coarse map's copy, the fine octree and the caches that make
/// re-enhancement after an edit cheap (§4.2).
pub struct Enhancer {
    engine: Engine,
    grid: CoarseGrid,
    coarse_depth: u8,
    fine: Svo,
    stats: EnhanceStats,
}

impl Enhancer {
    /// Enhances `coarse` in full.
    ///
    /// # Errors
    /// [`EnhanceError::Invalid`] for bad settings, [`EnhanceError::TooDeep`] when the fine
    /// octree would exceed [`MAX_DEPTH`], [`EnhanceError::TooManyVoxels`] for a coarse map
    /// standing for more than [`MAX_LISTED_VOXELS`] voxels.
    pub fn new(coarse: &Svo, settings: &EnhanceSettings) -> Result<Self, EnhanceError> {
        Self::with_control(coarse, settings, Control::default())
    }

    /// [`Enhancer::new`] with progress reports and a cancel flag.
    ///
    /// # Errors
    /// As [`Enhancer::new`], plus [`EnhanceError::Cancelled`].
    pub fn with_control(
        coarse: &Svo,
        settings: &EnhanceSettings,
        control: Control<'_>,
    ) -> Result<Self, EnhanceError> {
        let start = Instant::now();
        let engine = Engine::new(settings, coarse.extent())?;
        check_listable(coarse)?;
        let grid = CoarseGrid::from_svo(coarse);
        let (surface, candidates) = candidates(&grid, engine.r_out);
        let mut stats = EnhanceStats {
            coarse_surface_voxels: surface,
            candidate_cells: candidates.len() as u64,
            ..EnhanceStats::default()
        };
        let mut voxels: Vec<(UVec3, Voxel)> = Vec::new();
        let mut with_fragments = 0u64;
        for (ci, chunk) in candidates.chunks(CHUNK).enumerate() {
            if control.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                return Err(EnhanceError::Cancelled);
            }
            let results: Vec<(bool, Vec<(UVec3, Voxel)>)> = chunk
                .par_iter()
                .map_init(Scratch::new, |scratch, &c| {
                    let mut out = Vec::new();
                    let any = engine.cell_output(&grid, c, scratch, &mut out);
                    (any, out)
                })
                .collect();
            for (any, out) in results {
                with_fragments += u64::from(any);
                voxels.extend(out);
            }
            if let Some(p) = control.progress {
                p(((ci + 1) * CHUNK).min(candidates.len()) as f32 / candidates.len() as f32);
            }
        }
        stats.cells_with_fragments = with_fragments;
        stats.fragments = voxels.len() as u64;
        let fine = Svo::from_voxels(engine.fine_depth, false, voxels)?;
        let mut e = Self {
            engine,
            grid,
            coarse_depth: coarse.depth(),
            fine,
            stats,
        };
        e.finish_stats(start);
        if let Some(p) = control.progress {
            p(1.0);
        }
        Ok(e)
    }

    fn finish_stats(&mut self, start: Instant) {
        self.stats.skipped_uniform = self
            .stats
            .candidate_cells
            .saturating_sub(self.stats.cells_with_fragments);
        self.stats.cache_hits = self.engine.cache.hits.load(Ordering::Relaxed);
        self.stats.cache_misses = self.engine.cache.misses.load(Ordering::Relaxed);
        self.stats.cache_entries = self.engine.cache.len() as u64;
        self.stats.seconds = start.elapsed().as_secs_f64();
    }

    /// The fine octree (a surface shell).
    #[must_use]
    pub fn fine(&self) -> &Svo {
        &self.fine
    }

    /// Takes the fine octree.
    #[must_use]
    pub fn into_fine(self) -> Svo {
        self.fine
    }

    /// The settings in use.
    #[must_use]
    pub fn settings(&self) -> &EnhanceSettings {
        &self.engine.settings
    }

    /// Statistics of the last full run or update.
    #[must_use]
    pub fn stats(&self) -> EnhanceStats {
        self.stats
    }

    /// Coarse voxels around an edited box whose fragments an edit can change: the edited
    /// box grown by this many voxels (rule, factor, probe spread and lighting reach).
    #[must_use]
    pub fn dependency_radius(&self) -> u32 {
        self.engine.r_edit as u32
    }

    /// Whether the fine point `p` is solid, interior included (the fine octree stores only the
    /// shell): from the coarse map where the cell's window is uniform, else from the rule.
    #[must_use]
    pub fn is_solid_fine(&self, p: UVec3) -> bool {
        let mut scratch = Scratch::new();
        let p = p.as_ivec3();
        let c = p / self.engine.f;
        match self.engine.oracle_cell(c, &self.grid, &mut scratch) {
            CellState::Uniform(b) => b,
            CellState::Mixed(r) => {
                let l = (p - c * self.engine.f).as_uvec3();
                r.get(l.x as usize, l.y as usize, l.z as usize)
            }
        }
    }

    /// Re-enhances after a coarse edit (the edit's result, applied to `coarse` already).
    ///
    /// # Errors
    /// See [`Enhancer::update_box`].
    pub fn update(&mut self, coarse: &Svo, edit: &EditResult) -> Result<(), EnhanceError> {
        match edit.changed {
            Some((lo, hi)) => self.update_box(coarse, lo, hi),
            None => Ok(()),
        }
    }

    /// Re-enhances after the coarse voxels in the inclusive box `lo..=hi` changed: only the
    /// cells within [`Enhancer::dependency_radius`] of the box are recomputed, and the fine
    /// octree is patched in place. The result equals a full recompute.
    ///
    /// # Errors
    /// [`EnhanceError::DepthMismatch`] when `coarse` is not the map this enhancer was built
    /// from; [`EnhanceError::Svo`] when the box lies outside it.
    pub fn update_box(&mut self, coarse: &Svo, lo: UVec3, hi: UVec3) -> Result<(), EnhanceError> {
        self.update_box_changes(coarse, lo, hi).map(|_| ())
    }

    /// [`Enhancer::update_box`], returning the fine voxels it wrote (`None`: removed), so a
    /// copy of the fine octree kept elsewhere (the editor's document) can be patched with the
    /// same few changes instead of being copied whole.
    ///
    /// # Errors
    /// As [`Enhancer::update_box`].
    pub fn update_box_changes(
        &mut self,
        coarse: &Svo,
        lo: UVec3,
        hi: UVec3,
    ) -> Result<Vec<(UVec3, Option<Voxel>)>, EnhanceError> {
        let start = Instant::now();
        if coarse.depth() != self.coarse_depth {
            return Err(EnhanceError::DepthMismatch {
                expected: self.coarse_depth,
                got: coarse.depth(),
            });
        }
        let ext = self.grid.extent;
        if lo.cmpge(UVec3::splat(ext as u32)).any() || lo.cmpgt(hi).any() {
            return Err(SvoError::OutOfBounds {
                coord: lo.to_array(),
                extent: ext as u32,
            }
            .into());
        }
        let hi = hi.min(UVec3::splat(ext as u32 - 1));
        self.grid.refresh(coarse, lo, hi);
        let (lo, hi) = (lo.as_ivec3(), hi.as_ivec3());
        // Lighting memo: cells whose fragments depend on the edited voxels.
        {
            let r = self.engine.r_out;
            if let Ok(mut memo) = self.engine.memo.lock() {
                for z in lo.z - r..=hi.z + r {
                    for y in lo.y - r..=hi.y + r {
                        for x in lo.x - r..=hi.x + r {
                            memo.remove(&cell_key(IVec3::new(x, y, z)));
                        }
                    }
                }
            }
        }
        let r = self.engine.r_edit;
        let alo = (lo - IVec3::splat(r)).max(IVec3::ZERO);
        let ahi = (hi + IVec3::splat(r)).min(IVec3::splat(ext - 1));
        let mut cells = Vec::new();
        for z in alo.z..=ahi.z {
            for y in alo.y..=ahi.y {
                for x in alo.x..=ahi.x {
                    cells.push(IVec3::new(x, y, z));
                }
            }
        }
        let engine = &self.engine;
        let grid = &self.grid;
        let results: Vec<(bool, Vec<(UVec3, Voxel)>)> = cells
            .par_iter()
            .map_init(Scratch::new, |scratch, &c| {
                let mut out = Vec::new();
                let any = engine.cell_output(grid, c, scratch, &mut out);
                (any, out)
            })
            .collect();
        let mut fresh: FastMap<u64, Voxel> = FastMap::default();
        let mut with_fragments = 0;
        for (any, out) in results {
            with_fragments += u64::from(any);
            for (p, v) in out {
                // `pack`, not `cell_key`: fine coordinates reach 2^21 - 1.
                fresh.insert(pack(p.as_ivec3()), v);
            }
        }
        let fragments = fresh.len() as u64;
        let f = self.engine.f;
        let fine_lo = (alo * f).as_uvec3();
        let fine_hi = ((ahi + IVec3::ONE) * f - IVec3::ONE).as_uvec3();
        // Write only what differs: most fragments in the window come out as they were, and each
        // write re-averages every internal node above it.
        let mut changes: Vec<(UVec3, Option<Voxel>)> = Vec::new();
        self.fine.for_each_leaf_in(fine_lo, fine_hi, |p, old| {
            match fresh.remove(&pack(p.as_ivec3())) {
                Some(v) if v == old => {}
                new => changes.push((p, new)),
            }
        });
        changes.extend(
            fresh
                .into_iter()
                .map(|(key, v)| (unpack(key).as_uvec3(), Some(v))),
        );
        self.fine.apply_changes(changes.iter().copied())?;
        self.stats = EnhanceStats {
            coarse_surface_voxels: self.stats.coarse_surface_voxels,
            candidate_cells: cells.len() as u64,
            cells_with_fragments: with_fragments,
            fragments,
            ..EnhanceStats::default()
        };
        self.finish_stats(start);
        Ok(changes)
    }
}

/// The coarse surface (solid voxels with an empty face neighbour or on the map's border) and
/// the candidate cells: the surface grown by `r` in every direction (a window of radius `r`
/// that is not uniform always holds a surface voxel), clipped to the map, sorted.
fn candidates(grid: &CoarseGrid, r: i32) -> (u64, Vec<IVec3>) {
    let faces = [
        IVec3::X,
        -IVec3::X,
        IVec3::Y,
        -IVec3::Y,
        IVec3::Z,
        -IVec3::Z,
    ];
    let mut surface: Vec<u64> = Vec::new();
    grid.for_each_solid(|p| {
        if faces.iter().any(|&d| !grid.solid(p + d)) {
            surface.push(pack(p));
        }
    });
    let n_surface = surface.len() as u64;
    let ext = grid.extent;
    let mut set = surface;
    set.sort_unstable();
    // Separable dilation: grow along x, then y, then z; each pass sorts and deduplicates.
    for axis in 0..3 {
        let mut next = Vec::with_capacity(set.len() * (2 * r as usize + 1));
        for &k in &set {
            let p = unpack(k);
            for o in -r..=r {
                let mut q = p;
                q[axis] += o;
                if (0..ext).contains(&q[axis]) {
                    next.push(pack(q));
                }
            }
        }
        next.sort_unstable();
        next.dedup();
        set = next;
    }
    (n_surface, set.into_iter().map(unpack).collect())
}

/// z-major packing (sorted order = z, y, x) of in-map coordinates.
fn pack(p: IVec3) -> u64 {
    (p.z as u64) << 42 | (p.y as u64) << 21 | p.x as u64
}

fn unpack(k: u64) -> IVec3 {
    IVec3::new(
        (k & 0x1f_ffff) as i32,
        ((k >> 21) & 0x1f_ffff) as i32,
        (k >> 42) as i32,
    )
}

/// Coarse voxels of `svo` that are solid and have an empty face neighbour (outside counts as
/// empty): the coarse surface that fragment counts are bounded by.
#[must_use]
pub fn coarse_surface_count(svo: &Svo) -> u64 {
    let grid = CoarseGrid::from_svo(svo);
    candidates(&grid, 0).0
}

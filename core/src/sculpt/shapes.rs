//! Shape tools for modelling from nothing: single cells, lines, boxes, flood and face regions,
//! push-pull extrusion. Every edit clips to the model's *volume* (`size` voxels from the
//! origin), mirrors across the volume's centre, honours a selection mask and returns one
//! [`ToolEdit`] whose delta undoes it, normals included.
//!
//! All occupancy-changing tools go through one commit step (`commit`): it works out the final
//! occupancy, re-estimates the normals of changed voxels and their 26 neighbours with the
//! brushes' estimator, and writes everything in a single octree pass. Large, dense edits use a
//! flat grid over the changed box (cost follows the box); small or scattered ones a hash map
//! (cost follows the change count).

use std::collections::{HashMap, HashSet};

use glam::{I64Vec3, IVec3, UVec3, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::select::VoxelSelection;
use super::{ALL_NEIGHBOURS, nearest_skin, normal_from, normal_from_mask, offset};
use crate::svo::{EditResult, MAX_DEPTH, Svo, UndoDelta, Voxel, encode_normal};

/// What a tool edit did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ToolEdit {
    /// Inclusive box of changed voxels, None when nothing changed.
    pub changed: Option<(UVec3, UVec3)>,
    /// Restores the state before the edit with [`Svo::apply_delta`] (one undo step).
    pub delta: UndoDelta,
    /// Cells the tool asked for that lay outside the volume and were dropped (saturating).
    pub clipped: u64,
    /// Why the edit was refused, if it was (nothing changed then): show it to the user.
    pub refused: Option<ToolError>,
}

impl ToolEdit {
    fn from_result(r: EditResult, clipped: u64) -> Self {
        Self {
            changed: r.changed,
            delta: r.delta,
            clipped,
            refused: None,
        }
    }

    pub(crate) fn refused(err: ToolError, clipped: u64) -> Self {
        Self {
            clipped,
            refused: Some(err),
            ..Self::default()
        }
    }

    /// Folds a later edit into this one: its undo entries go first so undo restores the
    /// state before both.
    pub(crate) fn absorb(&mut self, later: EditResult) {
        if let Some((lo, hi)) = later.changed {
            self.changed = Some(
                self.changed
                    .map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))),
            );
        }
        let mut entries = later.delta.entries;
        entries.append(&mut self.delta.entries);
        self.delta.entries = entries;
    }
}

/// Why a tool refused to run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ToolError {
    /// A volume axis longer than the octree allows.
    #[error(
        "a volume of {size:?} voxels is too large: at most 2^{MAX_DEPTH} = {limit} voxels per axis (octree MAX_DEPTH {MAX_DEPTH})"
    )]
    ExtentTooLarge {
        /// The requested size.
        size: [u32; 3],
        /// Voxels per axis allowed.
        limit: u32,
    },
    /// A volume with a zero-length axis.
    #[error("a volume of {size:?} voxels has an empty axis; every axis needs at least 1 voxel")]
    EmptySize {
        /// The requested size.
        size: [u32; 3],
    },
    /// An edit that would write more cells than one undo step may hold.
    #[error(
        "the edit would write {cells} voxels, more than the {limit} one step may change; edit a smaller region"
    )]
    TooManyCells {
        /// Cells requested (saturating).
        cells: u64,
        /// [`MAX_EDIT_CELLS`].
        limit: u64,
    },
    /// A region too large for a tool that needs a dense grid over it.
    #[error("{what} needs a grid over {cells} cells, more than its limit of {limit}")]
    RegionTooLarge {
        /// The tool.
        what: &'static str,
        /// Cells of its grid.
        cells: u64,
        /// The limit.
        limit: u64,
    },
    /// A face normal that is not one of the six unit axis vectors.
    #[error("face normal {0:?} is not a unit axis vector (±X, ±Y or ±Z)")]
    BadNormal([i32; 3]),
    /// A tool that goes through every voxel of the model one by one, on a model standing for
    /// more voxels than [`MAX_LISTED_VOXELS`] (a solid whose inside is stored once per tile).
    #[error(
        "{what} goes through the model's voxels one by one, and this model stands for {} \
         voxels, more than the {} it can go through; brushes, boxes and carving still work \
         (they follow what they touch), or use the model at a larger voxel size",
        crate::budget::thousands(*.voxels),
        crate::budget::thousands(*.limit)
    )]
    TooManyVoxels {
        /// The tool.
        what: &'static str,
        /// Voxels the model stands for.
        voxels: u64,
        /// [`MAX_LISTED_VOXELS`].
        limit: u64,
    },
}

/// Here: resize, shift and mirror the model, select all, by colour or connected, invert, crop
/// to the selection refuse ([`ToolError::TooManyVoxels`]); the tools whose work follows the
/// edit (brushes, boxes, carving) still work.
pub use crate::svo::MAX_LISTED_VOXELS;

/// [`ToolError::TooManyVoxels`] for `what` when `svo` stands for more than
/// [`MAX_LISTED_VOXELS`] voxels.
///
/// # Errors
/// As above.
pub fn check_listable(svo: &Svo, what: &'static str) -> Result<(), ToolError> {
    match svo.too_many_to_list() {
        Some(voxels) => Err(ToolError::TooManyVoxels {
            what,
            voxels,
            limit: MAX_LISTED_VOXELS,
        }),
        None => Ok(()),
    }
}

/// Most cells one edit may write (one undo step): 2^25, a 322³ box.
pub const MAX_EDIT_CELLS: u64 = 1 << 25;

/// The refused edit when `asked` cells exceed [`MAX_EDIT_CELLS`] (one undo step).
fn over_edit_limit(asked: u64, clipped: u64) -> Option<ToolEdit> {
    (asked > MAX_EDIT_CELLS).then(|| {
        ToolEdit::refused(
            ToolError::TooManyCells {
                cells: asked,
                limit: MAX_EDIT_CELLS,
            },
            clipped,
        )
    })
}

/// Largest flat grid (cells) a commit or flood builds; beyond it they fall back to hashing.
pub(crate) const DENSE_LIMIT: u64 = 1 << 26;

/// What a shape tool does to the cells it covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum ShapeOp {
    /// Fill empty cells with the ink (solid voxels stay as they are).
    #[default]
    Add,
    /// Empty solid cells.
    Remove,
    /// Set colour and material of solid cells to the ink's.
    Paint,
}

/// Colour and material for [`ShapeOp::Add`] and [`ShapeOp::Paint`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct Ink {
    /// sRGB RGBA.
    pub color: [u8; 4],
    /// Material id.
    pub material: u8,
}

impl Default for Ink {
    fn default() -> Self {
        Self {
            color: [200, 200, 200, 255],
            material: 0,
        }
    }
}

/// Mirror copies across the volume's centre: cell c on a mirrored axis a maps to `size[a]-1-c[a]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(default)]
pub struct Mirror {
    /// Mirror across X, Y, Z.
    pub axes: [bool; 3],
}

/// Restricts an edit: Paint/Remove touch only selected voxels; Add only cells inside the
/// selection's bounding box. None = no restriction.
pub type Mask<'a> = Option<&'a VoxelSelection>;

/// How a commit treats normals.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Normals {
    /// Leave every normal alone (occupancy does not change: paint).
    Keep,
    /// Re-estimate every solid voxel that changed or is next to an occupancy change.
    All,
    /// Like `All` but written voxels keep the normal they were written with (moved voxels
    /// whose normals were transformed with them).
    Others,
}

pub(super) const OLD: u8 = 1;
pub(super) const NEW: u8 = 2;
pub(super) const WRITE: u8 = 4;

/// A flat grid over an inclusive box, x fastest.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Grid {
    pub(crate) lo: UVec3,
    pub(crate) dim: UVec3,
}

impl Grid {
    pub(crate) fn new(lo: UVec3, hi: UVec3) -> Self {
        Self {
            lo,
            dim: hi - lo + 1,
        }
    }

    pub(crate) fn hi(&self) -> UVec3 {
        self.lo + self.dim - 1
    }

    pub(crate) fn cells(&self) -> u64 {
        box_cells(self.dim)
    }

    #[inline]
    pub(crate) fn idx(&self, c: UVec3) -> usize {
        let l = c - self.lo;
        ((l.z as usize * self.dim.y as usize) + l.y as usize) * self.dim.x as usize + l.x as usize
    }

    #[inline]
    pub(crate) fn coord(&self, i: usize) -> UVec3 {
        let (nx, ny) = (self.dim.x as usize, self.dim.y as usize);
        self.lo
            + UVec3::new(
                (i % nx) as u32,
                ((i / nx) % ny) as u32,
                (i / (nx * ny)) as u32,
            )
    }

    /// The index of `c + o` if it lies in the grid.
    #[inline]
    pub(crate) fn neighbour(&self, c: UVec3, o: IVec3) -> Option<usize> {
        let p = c.as_ivec3() + o - self.lo.as_ivec3();
        (p.min_element() >= 0 && p.cmplt(self.dim.as_ivec3()).all())
            .then(|| self.idx(self.lo + p.as_uvec3()))
    }
}

/// Cells of a box of `dim` (saturating).
pub(crate) fn box_cells(dim: UVec3) -> u64 {
    u64::from(dim.x)
        .saturating_mul(u64::from(dim.y))
        .saturating_mul(u64::from(dim.z))
}

/// The volume clamped to the octree.
pub(crate) fn clamp_size(svo: &Svo, size: UVec3) -> UVec3 {
    size.min(UVec3::splat(svo.extent()))
}

/// `c` as a cell of the volume, if it lies inside.
pub(crate) fn in_volume(c: IVec3, size: UVec3) -> Option<UVec3> {
    (c.min_element() >= 0 && c.as_uvec3().cmplt(size).all()).then(|| c.as_uvec3())
}

/// Re-estimated normals of a dense commit, per cell of `g` (`None`: leave the normal alone).
///
/// A cell gets one when it is solid after the edit, lies within one cell (Chebyshev) of a cell
/// whose occupancy flips, and is not excluded by `normals`. The estimate is
/// [`normal_from_mask`] of its 26-neighbourhood after the edit; neighbours outside the grid are
/// outside the octree (the grid reaches two cells past every change), so they count as empty.
///
/// The flags are copied into a grid with a one-cell empty border, so no lookup needs a bounds
/// check. Three separable passes (x, y, z) over that copy find, for every cell, whether its
/// 3×3×3 block is all solid (erosion) and whether it holds a flip (dilation). Cells deep inside
/// a solid, most of a large box, then take the one all-solid estimate without reading their
/// neighbours; the others read their 26-neighbour mask.
pub(super) fn dense_normals(g: &Grid, flags: &[u8], normals: Normals) -> Vec<Option<u16>> {
    const SOLID: u8 = 1;
    const FLIPS: u8 = 2;
    let (nx, ny, nz) = (g.dim.x as usize, g.dim.y as usize, g.dim.z as usize);
    let (px, py) = (nx + 2, ny + 2);
    let pxy = px * py;
    let mut padded = vec![0u8; pxy * (nz + 2)];
    for z in 0..nz {
        for y in 0..ny {
            let src = &flags[(z * ny + y) * nx..][..nx];
            let dst = &mut padded[(z + 1) * pxy + (y + 1) * px + 1..][..nx];
            for (d, &f) in dst.iter_mut().zip(src) {
                let (old, new) = (f & OLD != 0, f & NEW != 0);
                *d = (u8::from(new) * SOLID) | (u8::from(old != new) * FLIPS);
            }
        }
    }
    // Bit SOLID: the block along the axes done so far is all solid; bit FLIPS: it holds a flip.
    // Border cells stay empty and flip-free where the next pass reads them (see below), and
    // the first and last `stride` cells are border cells no later pass reads.
    let mut block = padded.clone();
    let mut next = vec![0u8; padded.len()];
    for stride in [1, px, pxy] {
        let len = block.len();
        for i in stride..len - stride {
            let (a, b, c) = (block[i - stride], block[i], block[i + stride]);
            next[i] = (a & b & c & SOLID) | ((a | b | c) & FLIPS);
        }
        std::mem::swap(&mut block, &mut next);
    }
    // Why the border is safe: a pass along one axis reads, for an interior cell, cells that are
    // interior along the axes already passed, whose values are exact; the border cells it
    // reads along its own axis are empty in `padded` and, having only empty, flip-free
    // neighbours along the earlier axes, still are.

    // Offsets of the 26 neighbours in `padded`, in `neighbour_dirs` order (the mask's bits).
    let mut offsets = [0isize; 26];
    for (o, &(d, _)) in offsets.iter_mut().zip(super::neighbour_dirs()) {
        *o = d.z as isize * pxy as isize + d.y as isize * px as isize + d.x as isize;
    }
    let full = encode_normal(normal_from_mask(ALL_NEIGHBOURS));
    let mut out = vec![None; nx * ny * nz];
    let (padded, block) = (&padded, &block);
    out.par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(z, slice)| {
            let mut cached: Option<(u32, u16)> = None;
            for y in 0..ny {
                let row = (z * ny + y) * nx;
                let prow = (z + 1) * pxy + (y + 1) * px + 1;
                for x in 0..nx {
                    let f = flags[row + x];
                    if f & NEW == 0 || (normals == Normals::Others && f & WRITE != 0) {
                        continue;
                    }
                    let p = prow + x;
                    let b = block[p];
                    if b & FLIPS == 0 {
                        continue;
                    }
                    if b & SOLID != 0 {
                        slice[y * nx + x] = Some(full);
                        continue;
                    }
                    let mut mask = 0u32;
                    for (i, &o) in offsets.iter().enumerate() {
                        mask |= u32::from(padded[p.wrapping_add_signed(o)] & SOLID) << i;
                    }
                    slice[y * nx + x] = Some(match cached {
                        Some((m, code)) if m == mask => code,
                        _ => {
                            let code = encode_normal(normal_from_mask(mask));
                            cached = Some((mask, code));
                            code
                        }
                    });
                }
            }
        });
    out
}

/// Applies `changes` (all inside the octree; later duplicates win) in one pass with
/// re-estimated normals per `normals`. `only_into_empty`: a `Some` change applies only where
/// the cell is empty before the edit.
pub(crate) fn commit(
    svo: &mut Svo,
    changes: Vec<(UVec3, Option<Voxel>)>,
    only_into_empty: bool,
    normals: Normals,
    clipped: u64,
) -> ToolEdit {
    let extent = svo.extent();
    let changes: Vec<(UVec3, Option<Voxel>)> = if changes.iter().all(|c| c.0.max_element() < extent)
    {
        changes
    } else {
        changes
            .into_iter()
            .filter(|c| c.0.max_element() < extent)
            .collect()
    };
    let Some(bounds) = cell_bounds(changes.iter().map(|c| c.0)) else {
        return ToolEdit {
            clipped,
            ..ToolEdit::default()
        };
    };
    let r = match dense_grid(svo, bounds, changes.len() as u64) {
        Some(g) => commit_dense(
            svo,
            Writes::List(&changes),
            only_into_empty,
            normals,
            g,
            bounds,
        ),
        None => commit_sparse(svo, changes, only_into_empty, normals),
    };
    ToolEdit::from_result(r, clipped)
}

/// [`commit`] of `voxel` written into every cell of `boxes` (inside the octree; they may
/// overlap), in that order: the same result as listing the cells, without the list when the
/// dense path takes it.
pub(crate) fn commit_boxes(
    svo: &mut Svo,
    boxes: &[(UVec3, UVec3)],
    voxel: Voxel,
    only_into_empty: bool,
    normals: Normals,
    clipped: u64,
) -> ToolEdit {
    let Some(bounds) = cell_bounds(boxes.iter().flat_map(|b| [b.0, b.1])) else {
        return ToolEdit {
            clipped,
            ..ToolEdit::default()
        };
    };
    let n = boxes
        .iter()
        .map(|(l, h)| box_cells(*h - *l + 1))
        .fold(0u64, u64::saturating_add);
    match dense_grid(svo, bounds, n) {
        Some(g) => {
            let r = commit_dense(
                svo,
                Writes::Boxes(boxes, voxel),
                only_into_empty,
                normals,
                g,
                bounds,
            );
            ToolEdit::from_result(r, clipped)
        }
        None => {
            let mut changes = Vec::with_capacity(n as usize);
            for (l, h) in boxes {
                for z in l.z..=h.z {
                    for y in l.y..=h.y {
                        for x in l.x..=h.x {
                            changes.push((UVec3::new(x, y, z), Some(voxel)));
                        }
                    }
                }
            }
            commit(svo, changes, only_into_empty, normals, clipped)
        }
    }
}

/// The grid a dense commit of `n` changes within `bounds` uses, or `None` when it would be
/// too large or too sparse (the hash path is cheaper then).
fn dense_grid(svo: &Svo, (lo, hi): (UVec3, UVec3), n: u64) -> Option<Grid> {
    let max = UVec3::splat(svo.extent() - 1);
    let g = Grid::new(lo.saturating_sub(UVec3::splat(2)), (hi + 2).min(max));
    (g.cells() <= DENSE_LIMIT && g.cells() <= 64 * n + (1 << 16)).then_some(g)
}

/// What a dense commit writes.
#[derive(Clone, Copy)]
enum Writes<'a> {
    /// `(cell, new value)`; later duplicates win.
    List(&'a [(UVec3, Option<Voxel>)]),
    /// One voxel into every cell of each box.
    Boxes(&'a [(UVec3, UVec3)], Voxel),
    /// Clipboard voxels at `at + offset`, those outside the volume `size` dropped.
    Shifted {
        voxels: &'a [(UVec3, Voxel)],
        at: I64Vec3,
        size: UVec3,
    },
}

/// [`commit`] of clipboard `voxels` written at `at + offset` (the ones outside the volume
/// `size`, already clamped to the octree, dropped and counted): the same result as listing the
/// cells inside in clipboard order, without the list when the dense path takes it.
pub(crate) fn commit_shifted(
    svo: &mut Svo,
    voxels: &[(UVec3, Voxel)],
    at: I64Vec3,
    size: UVec3,
    only_into_empty: bool,
    normals: Normals,
) -> ToolEdit {
    let mut clipped = 0u64;
    let mut n = 0u64;
    let mut bounds: Option<(UVec3, UVec3)> = None;
    for (r, _) in voxels {
        match shifted_in_volume(at, *r, size) {
            Some(c) => {
                n += 1;
                bounds = Some(bounds.map_or((c, c), |(lo, hi)| (lo.min(c), hi.max(c))));
            }
            None => clipped += 1,
        }
    }
    let Some(bounds) = bounds else {
        return ToolEdit {
            clipped,
            ..ToolEdit::default()
        };
    };
    match dense_grid(svo, bounds, n) {
        Some(g) => {
            let writes = Writes::Shifted { voxels, at, size };
            let r = commit_dense(svo, writes, only_into_empty, normals, g, bounds);
            ToolEdit::from_result(r, clipped)
        }
        None => {
            let changes = voxels
                .iter()
                .filter_map(|(r, v)| shifted_in_volume(at, *r, size).map(|c| (c, Some(*v))))
                .collect();
            commit(svo, changes, only_into_empty, normals, clipped)
        }
    }
}

fn commit_dense(
    svo: &mut Svo,
    writes: Writes<'_>,
    only_into_empty: bool,
    normals: Normals,
    g: Grid,
    (lo, hi): (UVec3, UVec3),
) -> EditResult {
    let (w_lo, w_hi) = if normals == Normals::Keep {
        (lo, hi)
    } else {
        (
            lo.saturating_sub(UVec3::ONE),
            (hi + 1).min(UVec3::splat(svo.extent() - 1)),
        )
    };
    let mut plan = BrickPlan::new(w_lo, w_hi);
    let cells = g.cells() as usize;
    let mut flags = vec![0u8; cells];
    svo.for_each_leaf_in(g.lo, g.hi(), |c, _| flags[g.idx(c)] = OLD | NEW);
    let mut mark = |i: usize, c: UVec3, solid: bool, slots: &mut Vec<u32>| {
        let k = g.idx(c);
        if only_into_empty && solid && flags[k] & OLD != 0 {
            return;
        }
        slots[plan.index(c)] = i as u32;
        flags[k] = (flags[k] & OLD) | WRITE | if solid { NEW } else { 0 };
    };
    let mut slots = Vec::new();
    match writes {
        Writes::List(changes) => {
            slots = vec![0; plan.cells.len()];
            for (i, (c, v)) in changes.iter().enumerate() {
                mark(i, *c, v.is_some(), &mut slots);
            }
        }
        Writes::Shifted { voxels, at, size } => {
            slots = vec![0; plan.cells.len()];
            for (i, (r, _)) in voxels.iter().enumerate() {
                if let Some(c) = shifted_in_volume(at, *r, size) {
                    mark(i, c, true, &mut slots);
                }
            }
        }
        Writes::Boxes(boxes, _) => {
            for (l, h) in boxes {
                for z in l.z..=h.z {
                    for y in l.y..=h.y {
                        let row = g.idx(UVec3::new(l.x, y, z));
                        for f in &mut flags[row..=row + (h.x - l.x) as usize] {
                            if !(only_into_empty && *f & OLD != 0) {
                                *f = (*f & OLD) | WRITE | NEW;
                            }
                        }
                    }
                }
            }
        }
    }
    plan.slots = slots;
    let norms: Vec<Option<u16>> = if normals == Normals::Keep {
        Vec::new()
    } else {
        dense_normals(&g, &flags, normals)
    };
    let (touched, written) = plan.fill(&g, &flags, &norms);
    drop((flags, norms));
    let r = svo.edit_region_reserving(w_lo, w_hi, (touched, written), |c, old| {
        let (cell, slot) = plan.get(c);
        let mut v = if cell & BrickPlan::WRITE != 0 {
            match writes {
                Writes::List(changes) => changes[slot as usize].1,
                Writes::Shifted { voxels, .. } => Some(voxels[slot as usize].1),
                Writes::Boxes(_, v) => Some(v),
            }
        } else {
            old
        };
        // Interior voxels have no normal until exposed (`svo::interior`).
        if cell & BrickPlan::NORMAL != 0
            && let Some(v) = v.as_mut()
            && !v.is_interior()
        {
            v.normal = cell as u16;
        }
        v
    });
    r.unwrap_or_default()
}

/// `at + r` when it lies inside the volume `size`.
#[inline]
pub(crate) fn shifted_in_volume(at: I64Vec3, r: UVec3, size: UVec3) -> Option<UVec3> {
    let p = at + r.as_i64vec3();
    (p.min_element() >= 0 && p.cmplt(size.as_i64vec3()).all()).then(|| p.as_uvec3())
}

/// What a dense commit writes into each cell of its write box, laid out for the octree pass.
///
/// The octree visits cells in Morton order; the flag grid is in scan order, so reading it there
/// misses the cache on nearly every cell. Here the box is cut into 8³ bricks aligned to the
/// octree's own 8³ nodes, each brick's cells stored in Morton order, so the pass reads each
/// brick front to back.
struct BrickPlan {
    /// The write box.
    w_lo: UVec3,
    w_hi: UVec3,
    /// First brick (brick coordinates) and bricks per axis.
    lo: UVec3,
    dim: UVec3,
    /// Per cell: [`Self::WRITE`], [`Self::NORMAL`] and the normal in the low 16 bits.
    cells: Vec<u32>,
    /// Per written cell, the index of its value in a listed or shifted commit (else empty).
    slots: Vec<u32>,
}

impl BrickPlan {
    const WRITE: u32 = 1 << 16;
    const NORMAL: u32 = 1 << 17;

    /// Bit `i` of a local coordinate spread to Morton bit `3 i`.
    const SPREAD: [u32; 8] = [0o0, 0o1, 0o10, 0o11, 0o100, 0o101, 0o110, 0o111];

    fn new(w_lo: UVec3, w_hi: UVec3) -> Self {
        let lo = w_lo >> 3u32;
        let dim = (w_hi >> 3u32) - lo + 1;
        Self {
            w_lo,
            w_hi,
            lo,
            dim,
            cells: vec![0u32; box_cells(dim) as usize * 512],
            slots: Vec::new(),
        }
    }

    /// Fills the packed cells from the commit's scan-order flags and normals; returns how many
    /// cells are written or get a normal, and how many are written.
    fn fill(&mut self, g: &Grid, flags: &[u8], norms: &[Option<u16>]) -> (usize, usize) {
        let mut local = [UVec3::ZERO; 512];
        for (m, l) in local.iter_mut().enumerate() {
            *l = crate::svo::morton_decode(m as u64);
        }
        let (lo, dim, w_lo, w_hi) = (self.lo, self.dim, self.w_lo, self.w_hi);
        self.cells
            .par_chunks_mut((dim.x * dim.y) as usize * 512)
            .enumerate()
            .map(|(bz, cells)| {
                let (mut touched, mut written) = (0, 0);
                for by in 0..dim.y {
                    for bx in 0..dim.x {
                        let b = (by * dim.x + bx) as usize * 512;
                        let origin = (lo + UVec3::new(bx, by, bz as u32)) << 3u32;
                        for (m, l) in local.iter().enumerate() {
                            let c = origin + *l;
                            if c.cmplt(w_lo).any() || c.cmpgt(w_hi).any() {
                                continue;
                            }
                            let k = g.idx(c);
                            let mut cell = if flags[k] & WRITE != 0 {
                                Self::WRITE
                            } else {
                                0
                            };
                            if let Some(Some(nrm)) = norms.get(k) {
                                cell |= Self::NORMAL | u32::from(*nrm);
                            }
                            cells[b + m] = cell;
                            touched += usize::from(cell != 0);
                            written += usize::from(cell & Self::WRITE != 0);
                        }
                    }
                }
                (touched, written)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// Index of cell `c` (inside the write box).
    #[inline]
    fn index(&self, c: UVec3) -> usize {
        let b = (c >> 3u32) - self.lo;
        let l = c & UVec3::splat(7);
        (((b.z * self.dim.y + b.y) * self.dim.x + b.x) as usize) << 9
            | (Self::SPREAD[l.x as usize]
                | Self::SPREAD[l.y as usize] << 1
                | Self::SPREAD[l.z as usize] << 2) as usize
    }

    /// The packed cell and its value slot (0 unless listed or shifted) at `c`, inside the
    /// write box.
    #[inline]
    fn get(&self, c: UVec3) -> (u32, u32) {
        let k = self.index(c);
        (self.cells[k], self.slots.get(k).copied().unwrap_or(0))
    }
}

pub(super) fn commit_sparse(
    svo: &mut Svo,
    changes: Vec<(UVec3, Option<Voxel>)>,
    only_into_empty: bool,
    normals: Normals,
) -> EditResult {
    let mut map: HashMap<UVec3, Option<Voxel>> = HashMap::with_capacity(changes.len());
    for (c, v) in changes {
        if only_into_empty && v.is_some() && svo.get(c).is_some() {
            continue;
        }
        map.insert(c, v);
    }
    let mut extra: Vec<(UVec3, Option<Voxel>)> = Vec::new();
    if normals != Normals::Keep {
        let extent = svo.extent();
        let solid_after = |c: UVec3| {
            map.get(&c)
                .map_or_else(|| svo.get(c).is_some(), Option::is_some)
        };
        let mut dirty: HashSet<UVec3> = HashSet::new();
        for (c, v) in &map {
            if v.is_some() != svo.get(*c).is_some() {
                for &(o, _) in super::neighbour_dirs() {
                    if let Some(p) = offset(*c, o).filter(|p| p.max_element() < extent) {
                        dirty.insert(p);
                    }
                }
                dirty.insert(*c);
            }
        }
        let mut updates: Vec<(UVec3, u16)> = Vec::new();
        for &d in &dirty {
            if !solid_after(d) || (normals == Normals::Others && map.contains_key(&d)) {
                continue;
            }
            let n = normal_from(|o| {
                offset(d, o).is_some_and(|p| p.max_element() < extent && solid_after(p))
            });
            updates.push((d, encode_normal(n)));
        }
        // Interior voxels have no normal until exposed (`svo::interior`).
        for (d, nrm) in updates {
            if let Some(Some(v)) = map.get_mut(&d) {
                if !v.is_interior() {
                    v.normal = nrm;
                }
            } else if let Some(old) = svo.get(d).filter(|v| !v.is_interior()) {
                extra.push((d, Some(Voxel { normal: nrm, ..old })));
            }
        }
    }
    svo.apply_changes(map.into_iter().chain(extra))
        .unwrap_or_default()
}

/// Inclusive bounds of a set of cells.
pub(crate) fn cell_bounds(cells: impl IntoIterator<Item = UVec3>) -> Option<(UVec3, UVec3)> {
    cells.into_iter().fold(None, |acc, c| {
        Some(acc.map_or((c, c), |(lo, hi): (UVec3, UVec3)| (lo.min(c), hi.max(c))))
    })
}

/// The mirror images of an in-volume cell (itself first; duplicates on the centre plane kept).
fn mirror_images(c: UVec3, size: UVec3, mirror: Mirror) -> impl Iterator<Item = UVec3> {
    let axes =
        u8::from(mirror.axes[0]) | u8::from(mirror.axes[1]) << 1 | u8::from(mirror.axes[2]) << 2;
    (0..8u8).filter(move |m| m & !axes == 0).map(move |m| {
        let mut p = c;
        for a in 0..3 {
            if m & (1 << a) != 0 {
                p[a] = size[a] - 1 - c[a];
            }
        }
        p
    })
}

fn mirror_count(mirror: Mirror) -> u64 {
    1 << mirror.axes.iter().filter(|&&a| a).count()
}

fn mask_allows(op: ShapeOp, mask: Mask, c: UVec3) -> bool {
    match mask {
        None => true,
        Some(sel) => match op {
            ShapeOp::Add => sel
                .bounds()
                .is_some_and(|(lo, hi)| c.cmpge(lo).all() && c.cmple(hi).all()),
            ShapeOp::Remove | ShapeOp::Paint => sel.contains(c),
        },
    }
}

fn ink_voxel(svo: &Svo, ink: Ink, c: UVec3) -> Voxel {
    Voxel {
        color: ink.color,
        normal: encode_normal(Vec3::Y),
        material: ink.material,
        // Skin is chosen from the state before the edit; empty cells only (solid ones stay).
        skin: if svo.has_skin() && svo.get(c).is_none() {
            nearest_skin(svo, c)
        } else {
            Default::default()
        },
    }
}

/// Applies `op` to in-volume `targets` (mirror images and mask already applied).
fn edit_targets(svo: &mut Svo, targets: &[UVec3], op: ShapeOp, ink: Ink, clipped: u64) -> ToolEdit {
    match op {
        ShapeOp::Add => {
            let changes = targets
                .iter()
                .map(|&c| (c, Some(ink_voxel(svo, ink, c))))
                .collect();
            commit(svo, changes, true, Normals::All, clipped)
        }
        ShapeOp::Remove => {
            let changes = targets.iter().map(|&c| (c, None)).collect();
            commit(svo, changes, false, Normals::All, clipped)
        }
        ShapeOp::Paint => {
            let changes = targets
                .iter()
                .filter_map(|&c| {
                    svo.get(c).map(|v| {
                        (
                            c,
                            Some(Voxel {
                                color: ink.color,
                                material: ink.material,
                                ..v
                            }),
                        )
                    })
                })
                .collect();
            commit(svo, changes, false, Normals::Keep, clipped)
        }
    }
}

/// The cells of a 3D line from `a` to `b`: both ends included, 26-connected, exactly
/// `max(|b-a|) + 1` cells, symmetric (`line_cells(a, b)` is `line_cells(b, a)` reversed).
///
/// Cell `k` along the driving axis is `a + floor(k·d/n + 1/2)` per axis (`d = b - a`,
/// `n = max|d|`): rounding half up is shift-invariant, which is what makes the line symmetric.
/// A line longer than [`MAX_EDIT_CELLS`] cells is cut to its part inside `[-1, 2^21]` per axis
/// (every cell any volume can hold, and one beyond), so absurd endpoints cannot exhaust memory.
#[must_use]
pub fn line_cells(a: IVec3, b: IVec3) -> Vec<IVec3> {
    let n = (b.as_i64vec3() - a.as_i64vec3()).abs().max_element();
    if (n as u64) < MAX_EDIT_CELLS {
        let mut out = Vec::with_capacity(n as usize + 1);
        for k in 0..=n {
            out.push(line_point(a, b, n, k));
        }
        return out;
    }
    line_cells_within(a, b, I64Vec3::NEG_ONE, I64Vec3::splat(1 << MAX_DEPTH)).0
}

/// Cell `k` (0..=n) of the line from `a` to `b` with `n = max|b - a|`.
fn line_point(a: IVec3, b: IVec3, n: i64, k: i64) -> IVec3 {
    if n == 0 {
        return a;
    }
    let step = |a: i32, b: i32| -> i32 {
        let d = i128::from(b) - i128::from(a);
        let num = 2 * i128::from(k) * d + i128::from(n);
        (i128::from(a) + num.div_euclid(2 * i128::from(n))) as i32
    };
    IVec3::new(step(a.x, b.x), step(a.y, b.y), step(a.z, b.z))
}

/// The part of the line from `a` to `b` inside the inclusive box `lo..=hi`, and how many of its
/// cells lie outside. Each coordinate is monotone along the line, so the inside part is one run
/// of `k`, found by bisection without visiting the cells outside.
pub(crate) fn line_cells_within(a: IVec3, b: IVec3, lo: I64Vec3, hi: I64Vec3) -> (Vec<IVec3>, u64) {
    let n = (b.as_i64vec3() - a.as_i64vec3()).abs().max_element();
    let inside = |k: i64| {
        let p = line_point(a, b, n, k).as_i64vec3();
        p.cmpge(lo).all() && p.cmple(hi).all()
    };
    let (mut k0, mut k1) = (0i64, n);
    for axis in 0..3 {
        let coord = |k: i64| i64::from(line_point(a, b, n, k)[axis]);
        let rising = b[axis] >= a[axis];
        // First k with coord >= lo (rising) / <= hi (falling), last k with coord <= hi / >= lo.
        let first = partition(0, n, |k| {
            if rising {
                coord(k) < lo[axis]
            } else {
                coord(k) > hi[axis]
            }
        });
        let last = partition(0, n, |k| {
            if rising {
                coord(k) <= hi[axis]
            } else {
                coord(k) >= lo[axis]
            }
        }) - 1;
        k0 = k0.max(first);
        k1 = k1.min(last);
    }
    let total = n as u64 + 1;
    if k0 > k1 || !inside(k0) {
        return (Vec::new(), total);
    }
    let len = (k1 - k0 + 1) as u64;
    if len > MAX_EDIT_CELLS {
        return (Vec::new(), total);
    }
    let cells = (k0..=k1).map(|k| line_point(a, b, n, k)).collect();
    (cells, total - len)
}

/// The first `k` in `lo..=hi` for which `pred` is false (`hi + 1` if none), for a predicate
/// that is true then false.
fn partition(lo: i64, hi: i64, pred: impl Fn(i64) -> bool) -> i64 {
    let (mut l, mut h) = (lo, hi + 1);
    while l < h {
        let m = l + (h - l) / 2;
        if pred(m) {
            l = m + 1;
        } else {
            h = m;
        }
    }
    l
}

/// Applies `op` to any set of cells (a voxel, a line, a freehand run): cells outside the volume
/// are dropped and counted, the rest mirrored and masked. Add fills only empty cells.
pub fn apply_cells(
    svo: &mut Svo,
    size: UVec3,
    cells: &[IVec3],
    op: ShapeOp,
    ink: Ink,
    mirror: Mirror,
    mask: Mask,
) -> ToolEdit {
    let size = clamp_size(svo, size);
    let mut clipped = 0u64;
    let mut inside = Vec::with_capacity(cells.len());
    for &c in cells {
        match in_volume(c, size) {
            Some(u) => inside.push(u),
            None => clipped += 1,
        }
    }
    let asked = (inside.len() as u64).saturating_mul(mirror_count(mirror));
    if let Some(refused) = over_edit_limit(asked, clipped) {
        return refused;
    }
    let targets: Vec<UVec3> = inside
        .iter()
        .flat_map(|&c| mirror_images(c, size, mirror))
        .filter(|&c| mask_allows(op, mask, c))
        .collect();
    edit_targets(svo, &targets, op, ink, clipped)
}

/// Applies `op` to the inclusive box between corners `a` and `b` (any order, any `i32`): the
/// part outside the volume is dropped and counted, the rest mirrored and masked.
#[allow(
    clippy::too_many_arguments,
    reason = "the editor's API contract: one call per tool use"
)]
pub fn apply_box(
    svo: &mut Svo,
    size: UVec3,
    a: IVec3,
    b: IVec3,
    op: ShapeOp,
    ink: Ink,
    mirror: Mirror,
    mask: Mask,
) -> ToolEdit {
    let size = clamp_size(svo, size);
    let (a, b) = (a.as_i64vec3(), b.as_i64vec3());
    let (lo, hi) = (a.min(b), a.max(b));
    let total = (hi - lo + 1)
        .to_array()
        .iter()
        .fold(1u128, |acc, &d| acc * d as u128);
    let mut clo = lo.max(I64Vec3::ZERO);
    let mut chi = hi.min(size.as_i64vec3() - 1);
    let inside_cells = if clo.cmpgt(chi).any() {
        0u128
    } else {
        (chi - clo + 1)
            .to_array()
            .iter()
            .fold(1u128, |acc, &d| acc * d as u128)
    };
    let clipped = u64::try_from(total - inside_cells).unwrap_or(u64::MAX);
    if inside_cells == 0 {
        return ToolEdit {
            clipped,
            ..ToolEdit::default()
        };
    }
    if op == ShapeOp::Add {
        // Add may only fill the mask's bounding box: cut the box to it up front.
        if let Some(sel) = mask {
            let Some((mlo, mhi)) = sel.bounds() else {
                return ToolEdit {
                    clipped,
                    ..ToolEdit::default()
                };
            };
            clo = clo.max(mlo.as_i64vec3());
            chi = chi.min(mhi.as_i64vec3());
            if clo.cmpgt(chi).any() {
                return ToolEdit {
                    clipped,
                    ..ToolEdit::default()
                };
            }
        }
    }
    let (blo, bhi) = (clo.as_uvec3(), chi.as_uvec3());
    // The mirrored boxes, each listed once.
    let mut boxes: Vec<(UVec3, UVec3)> = Vec::new();
    for (p, q) in mirror_images(blo, size, mirror).zip(mirror_images(bhi, size, mirror)) {
        let bx = (p.min(q), p.max(q));
        if !boxes.contains(&bx) {
            boxes.push(bx);
        }
    }
    // What the box writes, one undo entry each: Add, every cell; Remove and Paint, every solid
    // voxel in it (counted a tile at once, so a box over a solid's inside is refused, not
    // listed).
    let asked = boxes
        .iter()
        .map(|(l, h)| match op {
            ShapeOp::Add => box_cells(*h - *l + 1),
            ShapeOp::Remove | ShapeOp::Paint => svo.voxels_in(*l, *h),
        })
        .fold(0u64, u64::saturating_add);
    if let Some(refused) = over_edit_limit(asked, clipped) {
        return refused;
    }
    match op {
        ShapeOp::Add => {
            let base = Voxel {
                color: ink.color,
                normal: encode_normal(Vec3::Y),
                material: ink.material,
                skin: Default::default(),
            };
            if !svo.has_skin() {
                return commit_boxes(svo, &boxes, base, true, Normals::All, clipped);
            }
            let mut changes = Vec::with_capacity(asked as usize);
            for (l, h) in &boxes {
                for z in l.z..=h.z {
                    for y in l.y..=h.y {
                        for x in l.x..=h.x {
                            let c = UVec3::new(x, y, z);
                            changes.push((c, Some(ink_voxel(svo, ink, c))));
                        }
                    }
                }
            }
            commit(svo, changes, true, Normals::All, clipped)
        }
        ShapeOp::Remove => {
            // Only solid voxels can be removed: walk those, not the box.
            let mut changes = Vec::new();
            for (l, h) in &boxes {
                svo.for_each_leaf_in(*l, *h, |c, _| {
                    if mask_allows(op, mask, c) {
                        changes.push((c, None));
                    }
                });
            }
            commit(svo, changes, false, Normals::All, clipped)
        }
        ShapeOp::Paint => {
            let mut edit = ToolEdit {
                clipped,
                ..ToolEdit::default()
            };
            for (l, h) in &boxes {
                let r = svo.edit_existing(*l, *h, |c, v| {
                    Some(if mask_allows(op, mask, c) {
                        Voxel {
                            color: ink.color,
                            material: ink.material,
                            ..v
                        }
                    } else {
                        v
                    })
                });
                if let Ok(r) = r {
                    edit.absorb(r);
                }
            }
            edit
        }
    }
}

/// Solid voxels of the inclusive box `lo..=hi` 6-connected to `seed` through voxels that satisfy
/// `keep`, in z-y-x scan order (dense grid) or Morton order (hash fallback). Empty when the seed
/// fails `keep`.
pub(crate) fn flood_solid(
    svo: &Svo,
    lo: UVec3,
    hi: UVec3,
    seed: UVec3,
    keep: impl Fn(UVec3, &Voxel) -> bool,
) -> Vec<UVec3> {
    if seed.cmplt(lo).any() || seed.cmpgt(hi).any() {
        return Vec::new();
    }
    let g = Grid::new(lo, hi);
    if g.cells() <= DENSE_LIMIT {
        let mut m = vec![0u8; g.cells() as usize];
        svo.for_each_leaf_in(lo, hi, |c, v| {
            if keep(c, &v) {
                m[g.idx(c)] = 1;
            }
        });
        flood_grid(&g, &mut m, seed)
    } else {
        let ok = |c: UVec3| {
            c.cmpge(lo).all() && c.cmple(hi).all() && svo.get(c).is_some_and(|v| keep(c, &v))
        };
        flood_hashed(seed, ok)
    }
}

const FACES: [IVec3; 6] = [
    IVec3::NEG_X,
    IVec3::X,
    IVec3::NEG_Y,
    IVec3::Y,
    IVec3::NEG_Z,
    IVec3::Z,
];

/// Flood over a 0/1 grid (1 = passable) from `seed`; returns the reached cells in scan order.
pub(crate) fn flood_grid(g: &Grid, m: &mut [u8], seed: UVec3) -> Vec<UVec3> {
    let s = g.idx(seed);
    if m[s] != 1 {
        return Vec::new();
    }
    let (nx, ny) = (g.dim.x as usize, g.dim.y as usize);
    let nxy = nx * ny;
    let dim = [g.dim.x as usize, g.dim.y as usize, g.dim.z as usize];
    let strides = [1, nx, nxy];
    m[s] = 2;
    let mut stack = vec![s];
    let mut count = 0usize;
    while let Some(i) = stack.pop() {
        count += 1;
        let along = [i % nx, (i / nx) % ny, i / nxy];
        for a in 0..3 {
            if along[a] > 0 && m[i - strides[a]] == 1 {
                m[i - strides[a]] = 2;
                stack.push(i - strides[a]);
            }
            if along[a] + 1 < dim[a] && m[i + strides[a]] == 1 {
                m[i + strides[a]] = 2;
                stack.push(i + strides[a]);
            }
        }
    }
    let mut out = Vec::with_capacity(count);
    out.extend(
        m.iter()
            .enumerate()
            .filter(|e| *e.1 == 2)
            .map(|(i, _)| g.coord(i)),
    );
    out
}

/// Hash-based flood for regions too large for a grid; result in Morton order.
fn flood_hashed(seed: UVec3, ok: impl Fn(UVec3) -> bool) -> Vec<UVec3> {
    if !ok(seed) {
        return Vec::new();
    }
    let mut seen = HashSet::from([seed]);
    let mut stack = vec![seed];
    while let Some(c) = stack.pop() {
        for o in FACES {
            if let Some(p) = offset(c, o)
                && !seen.contains(&p)
                && ok(p)
            {
                seen.insert(p);
                stack.push(p);
            }
        }
    }
    let mut out: Vec<UVec3> = seen.into_iter().collect();
    out.sort_by_key(|&c| crate::svo::morton_encode(c));
    out
}

/// Solid voxels 6-connected to `seed` with exactly seed's colour (RGBA) and material, inside
/// the volume; `plane_axis` Some(a): only voxels with `c[a] == seed[a]`. Empty if seed is empty
/// or outside the volume. A flat grid over the model's bounds when it fits, hashing otherwise.
#[must_use]
pub fn flood_region(svo: &Svo, size: UVec3, seed: UVec3, plane_axis: Option<usize>) -> Vec<UVec3> {
    let size = clamp_size(svo, size);
    if seed.cmpge(size).any() {
        return Vec::new();
    }
    let Some(sv) = svo.get(seed) else {
        return Vec::new();
    };
    let Some((mut lo, mut hi)) = svo.bounds() else {
        return Vec::new();
    };
    hi = hi.min(size - 1);
    if let Some(a) = plane_axis.filter(|&a| a < 3) {
        lo[a] = seed[a];
        hi[a] = seed[a];
    }
    flood_solid(svo, lo, hi, seed, |_, v| {
        v.color == sv.color && v.material == sv.material
    })
}

/// The axis and sign of a unit axis vector.
pub(crate) fn unit_axis(normal: IVec3) -> Option<(usize, i32)> {
    let a = (0..3).find(|&a| normal[a] != 0)?;
    (normal.abs().element_sum() == 1).then_some((a, normal[a]))
}

/// The exposed face under the pointer: solid voxels in seed's plane (perpendicular to the
/// unit-axis `normal`), 6-connected within that plane, same colour as seed, whose neighbour at
/// `+normal` is empty or outside the volume. Empty if seed is empty or its face is covered (or
/// `normal` is not a unit axis vector).
#[must_use]
pub fn face_region(svo: &Svo, size: UVec3, seed: UVec3, normal: IVec3) -> Vec<UVec3> {
    let size = clamp_size(svo, size);
    let Some((axis, sign)) = unit_axis(normal) else {
        return Vec::new();
    };
    if seed.cmpge(size).any() {
        return Vec::new();
    }
    let Some(sv) = svo.get(seed) else {
        return Vec::new();
    };
    let Some((mut lo, mut hi)) = svo.bounds() else {
        return Vec::new();
    };
    hi = hi.min(size - 1);
    lo[axis] = seed[axis];
    hi[axis] = seed[axis];
    let front = i64::from(seed[axis]) + i64::from(sign);
    let front_inside = front >= 0 && front < i64::from(size[axis]);
    let g = Grid::new(lo, hi);
    if g.cells() <= DENSE_LIMIT {
        let mut m = vec![0u8; g.cells() as usize];
        svo.for_each_leaf_in(lo, hi, |c, v| {
            if v.color == sv.color {
                m[g.idx(c)] = 1;
            }
        });
        if front_inside {
            let (mut flo, mut fhi) = (lo, hi);
            flo[axis] = front as u32;
            fhi[axis] = front as u32;
            svo.for_each_leaf_in(flo, fhi, |c, _| {
                let mut p = c;
                p[axis] = seed[axis];
                m[g.idx(p)] = 0;
            });
        }
        flood_grid(&g, &mut m, seed)
    } else {
        let ok = |c: UVec3| {
            c.cmpge(lo).all()
                && c.cmple(hi).all()
                && svo.get(c).is_some_and(|v| v.color == sv.color)
                && (!front_inside || svo.get((c.as_ivec3() + normal).as_uvec3()).is_none())
        };
        flood_hashed(seed, ok)
    }
}

/// Cells push-pull covers: `distance > 0`: the `distance` layers in front of the face
/// (`c + k·normal`, `k = 1..=distance`); `distance < 0`: the face voxels and the layers behind
/// them (`c - k·normal`, `k = 0..|distance|`). Layer by layer, face order within a layer. The
/// distance is cut so the result holds at most [`MAX_EDIT_CELLS`] cells.
#[must_use]
pub fn extrude_cells(face: &[UVec3], normal: IVec3, distance: i32) -> Vec<IVec3> {
    if face.is_empty() || distance == 0 {
        return Vec::new();
    }
    let layers = (distance.unsigned_abs() as u64)
        .min(MAX_EDIT_CELLS / face.len() as u64)
        .min(1 << MAX_DEPTH) as i32;
    let ks: Box<dyn Iterator<Item = i32>> = if distance > 0 {
        Box::new(1..=layers)
    } else {
        Box::new((0..layers).map(|k| -k))
    };
    let mut out = Vec::with_capacity(face.len() * layers as usize);
    for k in ks {
        for &c in face {
            out.push(c.as_ivec3() + normal * k);
        }
    }
    out
}

/// Push-pull: positive `distance` adds layers in front of `face`, each cell copying the
/// attributes (colour, material, skin) of the face voxel it grows from, into empty cells only;
/// negative removes the face and the layers behind it; 0 changes nothing. Mask as for Add and
/// Remove.
pub fn extrude(
    svo: &mut Svo,
    size: UVec3,
    face: &[UVec3],
    normal: IVec3,
    distance: i32,
    mask: Mask,
) -> ToolEdit {
    if unit_axis(normal).is_none() {
        return ToolEdit::refused(ToolError::BadNormal(normal.to_array()), 0);
    }
    if face.is_empty() || distance == 0 {
        return ToolEdit::default();
    }
    let asked = (face.len() as u64).saturating_mul(u64::from(distance.unsigned_abs()));
    if let Some(refused) = over_edit_limit(asked, 0) {
        return refused;
    }
    let size = clamp_size(svo, size);
    let mut clipped = 0u64;
    let mut changes = Vec::with_capacity(asked as usize);
    if distance > 0 {
        for &f in face {
            let Some(v) = svo.get(f) else { continue };
            for k in 1..=distance {
                match in_volume(f.as_ivec3() + normal * k, size) {
                    Some(c) if mask_allows(ShapeOp::Add, mask, c) => changes.push((c, Some(v))),
                    Some(_) => {}
                    None => clipped += 1,
                }
            }
        }
        commit(svo, changes, true, Normals::All, clipped)
    } else {
        for &f in face {
            for k in 0..distance.unsigned_abs() as i32 {
                match in_volume(f.as_ivec3() - normal * k, size) {
                    Some(c) if mask_allows(ShapeOp::Remove, mask, c) => changes.push((c, None)),
                    Some(_) => {}
                    None => clipped += 1,
                }
            }
        }
        commit(svo, changes, false, Normals::All, clipped)
    }
}

//! Interior fill along three axes. Each axis casts one ray per voxel column (the grid rotated
//! cyclically so the axis becomes z, which keeps orientation and so the signs of entering and
//! leaving; see [`super::solid`]). A voxel is interior when at least two of the three axes say
//! its centre is inside, so a column that grazes a face or an edge cannot add or remove a run
//! on its own. An interior voxel takes the attributes of the nearest of the (up to six)
//! crossings that bound it along the three axes, not the end of one fixed column: in a long
//! body the nearest crossing is the flank beside it, not the nose or the tail.

use glam::{DVec3, UVec3};
use rayon::prelude::*;

use super::geometry::GridTriangle;
use super::solid::{self, Bounds, ColumnRun, Crossing, CrossingKey};
use super::surface::Budget;
use super::{FillRule, Triangles, VoxelizeError, for_triangles};
use crate::svo::{Voxel, morton_encode};

/// A ray axis of the interior fill.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Axis {
    Z,
    X,
    Y,
}

impl Axis {
    /// The three axes, z first (ties between equally near crossings go to the earlier axis).
    pub(crate) const ALL: [Axis; 3] = [Axis::Z, Axis::X, Axis::Y];

    /// Grid coordinates rotated cyclically so that this axis becomes z.
    fn turn(self, v: DVec3) -> DVec3 {
        match self {
            Axis::Z => v,
            Axis::X => DVec3::new(v.y, v.z, v.x),
            Axis::Y => DVec3::new(v.z, v.x, v.y),
        }
    }

    /// The grid's dimensions as [`Axis::turn`] sees them.
    pub(crate) fn turn_dims(self, d: UVec3) -> UVec3 {
        match self {
            Axis::Z => d,
            Axis::X => UVec3::new(d.y, d.z, d.x),
            Axis::Y => UVec3::new(d.z, d.x, d.y),
        }
    }

    /// The grid voxel of turned voxel `t` (the inverse of [`Axis::turn`]).
    pub(crate) fn unturn(self, t: UVec3) -> UVec3 {
        match self {
            Axis::Z => t,
            Axis::X => UVec3::new(t.z, t.x, t.y),
            Axis::Y => UVec3::new(t.y, t.z, t.x),
        }
    }
}

/// One axis's inside runs, and (when kept) its crossings sorted by column, then position,
/// with the two that bound each run.
pub(crate) struct AxisFill {
    pub(crate) axis: Axis,
    pub(crate) runs: Vec<ColumnRun>,
    /// Empty when only the runs were asked for.
    pub(crate) crossings: Vec<Crossing>,
    /// Per run, when the crossings are kept.
    pub(crate) bounds: Vec<Bounds>,
    /// Columns that do not close under the fill rule (the mesh is open along this axis).
    pub(crate) open_columns: u64,
}

/// What a fill keeps of its crossings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Keep {
    /// The inside runs only (a rigid solid's interior bits): each crossing cast as an 8-byte
    /// [`CrossingKey`]. Falls back to [`Keep::Crossings`] on a grid too large for the keys.
    Runs,
    /// The crossings too, with their triangles and barycentrics, for attributes.
    Crossings,
}

/// Casts `axis`'s column rays through every triangle and turns the crossings into inside runs.
///
/// # Errors
/// [`VoxelizeError::TooManyVoxels`] when the crossings exceed `limit`, or a cancel.
#[allow(
    clippy::too_many_arguments,
    reason = "the triangles, grid, axis, rule, what to keep, budget and progress range"
)]
pub(crate) fn cast(
    tris: &Triangles<'_>,
    dims: UVec3,
    axis: Axis,
    rule: FillRule,
    keep: Keep,
    limit: u64,
    progress: &dyn Fn(f32) -> bool,
    range: (f32, f32),
) -> Result<AxisFill, VoxelizeError> {
    let turned_dims = axis.turn_dims(dims);
    let budget = Budget::new(limit);
    let turn = |tri: &GridTriangle| {
        (axis != Axis::Z).then(|| GridTriangle::new(tri.v.map(|v| axis.turn(v))))
    };
    let over_budget = || VoxelizeError::TooManyVoxels {
        limit,
        what: "column crossings",
    };
    if keep == Keep::Runs && CrossingKey::fits(turned_dims) {
        let mut keys: Vec<u64> = for_triangles(tris, progress, range, |_, tri, out| {
            let turned = turn(tri);
            solid::emit_crossing_keys(turned.as_ref().unwrap_or(tri), turned_dims, &budget, out);
        })?;
        if budget.is_exceeded() {
            return Err(over_budget());
        }
        let (runs, open_columns) = solid::key_runs(&mut keys, turned_dims, rule);
        return Ok(AxisFill {
            axis,
            runs,
            crossings: Vec::new(),
            bounds: Vec::new(),
            open_columns,
        });
    }
    let mut crossings: Vec<Crossing> = for_triangles(tris, progress, range, |g, tri, out| {
        let turned = turn(tri);
        solid::emit_crossings(turned.as_ref().unwrap_or(tri), g, turned_dims, &budget, out);
    })?;
    if budget.is_exceeded() {
        return Err(over_budget());
    }
    let (runs, bounds, open_columns) = solid::intervals(&mut crossings, turned_dims.z, rule);
    Ok(AxisFill {
        axis,
        runs,
        crossings,
        bounds,
        open_columns,
    })
}

impl AxisFill {
    /// This axis's runs in a grid of `dims`, in turned coordinates ([`Axis::turn_dims`]):
    /// `(column x, column y, first, last)`, clipped at the grid's far side; runs whose column
    /// or start lies outside are left out.
    pub(crate) fn runs_in(&self, dims: UVec3) -> impl Iterator<Item = (u32, u32, u32, u32)> + '_ {
        let turned = self.axis.turn_dims(dims);
        let last = turned.z.saturating_sub(1);
        self.runs.iter().filter_map(move |iv| {
            let x = (iv.column & 0x1f_ffff) as u32;
            let y = (iv.column >> 21) as u32;
            (x < turned.x && y < turned.y && iv.k_lo <= last)
                .then(|| (x, y, iv.k_lo, iv.k_hi.min(last)))
        })
    }

    /// An axis with no crossings (tests).
    #[cfg(test)]
    pub(crate) fn empty(axis: Axis) -> Self {
        Self {
            axis,
            runs: Vec::new(),
            crossings: Vec::new(),
            bounds: Vec::new(),
            open_columns: 0,
        }
    }

    /// Voxels inside along this axis.
    pub(crate) fn inside_count(&self) -> u64 {
        self.runs
            .iter()
            .map(|iv| u64::from(iv.k_hi - iv.k_lo) + 1)
            .sum()
    }

    /// Every voxel inside along this axis, sorted by Morton code, with its distance to the
    /// nearer of the two crossings bounding its run and that crossing.
    fn inside(&self, slot: u32) -> Vec<Inside> {
        let mut out: Vec<Inside> = self
            .runs
            .par_iter()
            .zip(&self.bounds)
            .flat_map_iter(|(iv, b)| {
                let x = (iv.column & 0x1f_ffff) as u32;
                let y = (iv.column >> 21) as u32;
                (iv.k_lo..=iv.k_hi).map(move |k| {
                    let zc = f64::from(k) + 0.5;
                    let (before, after) = (zc - b.z_in, b.z_out - zc);
                    let (dist, crossing) = if before <= after {
                        (before, b.entry)
                    } else {
                        (after, b.exit)
                    };
                    Inside {
                        key: morton_encode(self.axis.unturn(UVec3::new(x, y, k))),
                        dist: dist as f32,
                        source: (slot << SLOT_SHIFT) | crossing as u32,
                    }
                })
            })
            .collect();
        out.par_sort_unstable_by_key(|r| r.key);
        out
    }
}

/// Bits of [`Inside::source`] that hold the crossing index; the axis's slot is above them.
const SLOT_SHIFT: u32 = 30;

/// A voxel inside along one axis.
#[derive(Debug, Clone, Copy)]
struct Inside {
    key: u64,
    dist: f32,
    /// Axis slot (0..3) above [`SLOT_SHIFT`], crossing index below.
    source: u32,
}

/// The interior: voxels inside along at least two of the three axes, sorted by Morton code,
/// each with the attributes of its nearest bounding crossing.
pub(crate) struct Interior {
    /// Morton codes, sorted.
    pub(crate) keys: Vec<u64>,
    /// Attributes, in the order of `keys`.
    pub(crate) voxels: Vec<Voxel>,
}

impl Interior {
    /// Whether voxel `c` is interior.
    pub(crate) fn contains(&self, c: UVec3) -> bool {
        self.keys.binary_search(&morton_encode(c)).is_ok()
    }
}

/// Votes the three axes' runs into the interior. `attributes(crossing)` gives a crossing's
/// attributes (called once per crossing of every axis).
///
/// # Errors
/// [`VoxelizeError::TooManyVoxels`] when the crossings are too many to index (2^30 per axis).
pub(crate) fn vote(
    fills: &[AxisFill; 3],
    attributes: impl Fn(&Crossing) -> Voxel + Sync,
) -> Result<Interior, VoxelizeError> {
    debug_assert!(
        fills.iter().all(|f| f.bounds.len() == f.runs.len()),
        "the sparse fill needs the crossings kept"
    );
    if fills.iter().any(|f| f.crossings.len() >= 1 << SLOT_SHIFT) {
        return Err(VoxelizeError::TooManyVoxels {
            limit: 1 << SLOT_SHIFT,
            what: "column crossings on one axis",
        });
    }
    let lists: Vec<Vec<Inside>> = (0u32..3).map(|s| fills[s as usize].inside(s)).collect();
    let mut cursor = [0usize; 3];
    let mut chosen: Vec<(u64, u32)> = Vec::with_capacity(lists[0].len());
    while let Some(key) = (0..3)
        .filter_map(|s| lists[s].get(cursor[s]).map(|r| r.key))
        .min()
    {
        let mut votes = 0;
        let mut best: Option<Inside> = None;
        for s in 0..3 {
            if let Some(&r) = lists[s].get(cursor[s])
                && r.key == key
            {
                votes += 1;
                cursor[s] += 1;
                if best.is_none_or(|b| r.dist < b.dist) {
                    best = Some(r);
                }
            }
        }
        if votes >= 2
            && let Some(b) = best
        {
            chosen.push((key, b.source));
        }
    }
    drop(lists);
    let attrs: Vec<Vec<Voxel>> = fills
        .iter()
        .map(|f| f.crossings.par_iter().map(&attributes).collect())
        .collect();
    let mask = (1u32 << SLOT_SHIFT) - 1;
    let voxels = chosen
        .par_iter()
        .map(|&(_, source)| attrs[(source >> SLOT_SHIFT) as usize][(source & mask) as usize])
        .collect();
    Ok(Interior {
        keys: chosen.into_iter().map(|(k, _)| k).collect(),
        voxels,
    })
}

//! Triangle meshes → sparse voxel octree: conservative surface voxelization, interior fill for
//! closed meshes, and attribute transfer (colour, normal, material, skin weights) by
//! barycentric interpolation at the closest point of the surface. See `docs/voxelize.md`.
//!
//! # Grid
//! The grid's voxel `(i, j, k)` spans `origin + [i, i + 1) × voxel_size` (and likewise for j,
//! k) in the mesh's object space, with `origin` the minimum corner of the bounding box of the
//! referenced vertices, less `padding` voxels. All predicates run in grid space in `f64`.
//!
//! # Determinism
//! Triangles are processed in parallel, but every candidate is keyed by a total order (Morton
//! code, then distance to the voxel centre, then triangle index) and sorted before use, so the
//! octree is identical whatever the thread count.

mod bits;
mod dense;
mod fill;
mod geometry;
mod sealed;
mod solid;
mod surface;

#[cfg(test)]
mod tests;

use glam::{DVec3, IVec3, UVec3, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::mesh::{MeshError, MeshModel, TriangleMesh, linear_to_srgb};
use crate::svo::{
    FACE_NEIGHBOURS, MAX_DEPTH, Skin4, Svo, SvoError, Voxel, encode_normal, morton_decode,
};
use geometry::GridTriangle;
use surface::{Budget, SurfaceRecord};

/// How fine the grid is.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Resolution {
    /// The longest side of the mesh's bounding box spans `2^n` voxels (`n` in 1..=21).
    Depth(u8),
    /// Edge length of one voxel in the mesh's units; the octree depth is the smallest that fits.
    VoxelSize(f32),
}

/// Which voxels are solid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Mode {
    /// Every voxel the surface touches (a conservative, gap-free shell).
    #[default]
    Surface,
    /// Voxels whose centre is inside the (closed) mesh, plus the surface voxels needed to keep
    /// sub-voxel-thin parts; see [`VoxelizeSettings::keep_outer_surface`].
    Solid,
}

/// Which column positions count as inside in [`Mode::Solid`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum FillRule {
    /// Inside where the winding number is non-zero: overlapping closed parts fill as a union.
    /// Needs consistently oriented triangles (either orientation).
    #[default]
    NonZero,
    /// Inside after an odd number of crossings: ignores orientation, but overlaps cancel.
    EvenOdd,
}

impl FillRule {
    /// Whether a point is inside after crossings whose signs sum to `winding`, `count` of them.
    pub(crate) fn inside(self, winding: i64, count: u64) -> bool {
        match self {
            FillRule::NonZero => winding != 0,
            FillRule::EvenOdd => count % 2 == 1,
        }
    }
}

/// Parameters of [`voxelize`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VoxelizeSettings {
    /// Grid resolution.
    pub resolution: Resolution,
    /// Surface only, or surface and interior.
    pub mode: Mode,
    /// Empty voxels added on every side of the bounding box (room to sculpt outward). With
    /// [`Resolution::Depth`] padding can make the octree one level deeper than `n`.
    pub padding: u32,
    /// Inside test for [`Mode::Solid`].
    pub fill_rule: FillRule,
    /// [`Mode::Solid`] only: also keep the surface voxels whose centre lies outside the mesh
    /// (the whole conservative shell). Off by default: those voxels add about half a voxel
    /// layer of volume; thin parts are kept either way.
    pub keep_outer_surface: bool,
    /// Refuse (with [`VoxelizeError::TooManyVoxels`]) rather than produce more voxels stored
    /// one by one than this: the surface, and a solid's interior where it is listed voxel by
    /// voxel (skinned solids, grids too large for the interior bits). A rigid solid whose
    /// interior goes through the bits is stored as its surface and interior tiles, and may
    /// stand for up to [`MAX_TILED_SOLID_VOXELS`] (or this, if larger). Working memory is
    /// about 16 bytes per voxel–triangle overlap, capped at 4× this.
    pub max_voxels: u64,
}

/// Most voxels a rigid solid's import may stand for when its interior is stored as tiles
/// (2^31, what a project holds): its memory and file follow its surface, which
/// [`VoxelizeSettings::max_voxels`] counts, and [`estimate`] gives the memory it needs.
pub const MAX_TILED_SOLID_VOXELS: u64 = 1 << 31;

impl Default for VoxelizeSettings {
    fn default() -> Self {
        Self {
            resolution: Resolution::Depth(8),
            mode: Mode::Surface,
            padding: 0,
            fill_rule: FillRule::NonZero,
            keep_outer_surface: false,
            max_voxels: 1 << 27,
        }
    }
}

/// Why a mesh could not be voxelized.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VoxelizeError {
    /// A part of the mesh is malformed (NaN position, index out of range, …).
    #[error("mesh part {part} is invalid: {source}")]
    InvalidMesh {
        /// Index into [`MeshModel::parts`].
        part: usize,
        /// The problem.
        source: MeshError,
    },
    /// `Resolution::Depth(n)` with `n` outside 1..=21.
    #[error("voxelization depth {0} is out of range (1..={MAX_DEPTH})")]
    BadDepth(u8),
    /// `Resolution::VoxelSize(s)` with `s` NaN, infinite, zero or negative.
    #[error("voxel size {0} must be finite and positive")]
    BadVoxelSize(f32),
    /// `max_voxels` is zero.
    #[error("max_voxels must be at least 1")]
    BadVoxelLimit,
    /// All referenced vertices coincide, so `Resolution::Depth` cannot derive a voxel size.
    #[error("the mesh has zero extent; give a voxel size instead of a depth")]
    ZeroExtent,
    /// The grid would be larger than 2^21 voxels along some axis.
    #[error(
        "the grid would be {voxels:.3e} voxels along {axis} (max {max}); use a larger voxel size \
         or less padding"
    )]
    GridTooLarge {
        /// `x`, `y` or `z`.
        axis: char,
        /// Voxels needed along that axis.
        voxels: f64,
        /// 2^21.
        max: u32,
    },
    /// The result would exceed [`VoxelizeSettings::max_voxels`].
    #[error(
        "voxelization would produce more than {limit} voxels ({what}); use a larger voxel size \
         (a smaller depth)"
    )]
    TooManyVoxels {
        /// The limit.
        limit: u64,
        /// What hit it.
        what: &'static str,
    },
    /// The progress callback asked to stop.
    #[error("voxelization cancelled")]
    Cancelled,
    /// The octree refused the result (should not happen: coordinates are clamped to the grid).
    #[error("octree build failed: {0}")]
    Svo(#[from] SvoError),
}

/// Where the grid lies, before any voxel is computed (cheap; lets a UI show the resulting size).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GridPlan {
    /// Object-space minimum corner of voxel (0, 0, 0).
    pub origin: Vec3,
    /// Voxel edge in object units.
    pub voxel_size: f32,
    /// Voxels per axis actually used (padding included).
    pub dims: [u32; 3],
    /// Octree depth (`2^depth >= max(dims)`).
    pub depth: u8,
}

/// Counts describing one voxelization.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct VoxelizeStats {
    /// Triangles in the model.
    pub triangles: u64,
    /// Zero-area or non-finite triangles skipped (they have no surface).
    pub degenerate_triangles: u64,
    /// Voxel–triangle overlaps found (≥ surface voxels: neighbouring triangles share voxels).
    pub overlaps: u64,
    /// Voxels the surface touches (before solid mode drops outer ones).
    pub surface_voxels: u64,
    /// Voxels whose centre is inside (solid mode).
    pub interior_voxels: u64,
    /// Solid voxels in the result.
    pub voxels: u64,
    /// [`Mode::Solid`] only: voxel columns (along x, y or z, through voxel centres) that enter
    /// the mesh and do not leave it: the mesh is open at this resolution. Counting stops at the
    /// first axis that has any.
    pub open_columns: u64,
    /// When [`Self::open_columns`] > 0: edges of the mesh (vertices welded by exact position
    /// over all parts) used by an odd number of triangles, to say where it is open. (Not the
    /// test itself: T-junctions, as in greedy-meshed exports, leave closed surfaces with such
    /// edges.)
    pub boundary_edges: u64,
    /// Solid mode was asked for but the mesh is open ([`Self::open_columns`] > 0): the result
    /// is its surface, exactly as [`Mode::Surface`] gives it.
    pub solid_fell_back: bool,
    /// Solid mode: interior voxels took the attributes of their nearest surface voxel (the
    /// dense fill, for grids up to 2^28 cells); `false`, those of the nearest crossing that
    /// bounds them along the three axes (the sparse fill of larger grids).
    #[serde(default)]
    pub interior_from_nearest_surface: bool,
    /// Solid mode: interior voxels enclosed on all six faces, stored as the interior mark
    /// ([`Voxel::INTERIOR`], attributes found when an edit exposes them).
    #[serde(default)]
    pub interior_marked: u64,
}

/// The result of [`voxelize`].
#[derive(Debug, Clone)]
pub struct Voxelized {
    /// The octree.
    pub svo: Svo,
    /// Voxel edge in object units.
    pub voxel_size: f32,
    /// Object-space minimum corner of voxel (0, 0, 0).
    pub origin: Vec3,
    /// Counts.
    pub stats: VoxelizeStats,
}

impl Voxelized {
    /// The voxel holding object-space point `p`, or `None` outside the octree.
    #[must_use]
    pub fn voxel_of(&self, p: Vec3) -> Option<UVec3> {
        // f64, exactly as the voxelizer maps vertices, so a point on a triangle maps to a voxel
        // the triangle marked.
        let g = (p.as_dvec3() - self.origin.as_dvec3()) / f64::from(self.voxel_size);
        let extent = f64::from(self.svo.extent());
        if !g.is_finite() || g.min_element() < 0.0 || g.max_element() >= extent {
            return None;
        }
        Some(g.floor().as_uvec3())
    }

    /// Object-space centre of voxel `c`.
    #[must_use]
    pub fn voxel_center(&self, c: UVec3) -> Vec3 {
        self.origin + (c.as_vec3() + 0.5) * self.voxel_size
    }
}

/// Bounds of the vertices the triangles use (unreferenced vertices do not widen the grid).
fn referenced_bounds(model: &MeshModel) -> Option<(DVec3, DVec3)> {
    let mut acc: Option<(DVec3, DVec3)> = None;
    for part in &model.parts {
        for &i in &part.indices {
            let p = part.positions[i as usize].as_dvec3();
            acc = Some(acc.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))));
        }
    }
    acc
}

/// Checks `settings` and works out the grid for `model` without voxelizing.
///
/// # Errors
/// [`VoxelizeError::InvalidMesh`], [`VoxelizeError::BadDepth`],
/// [`VoxelizeError::BadVoxelSize`], [`VoxelizeError::BadVoxelLimit`],
/// [`VoxelizeError::ZeroExtent`] or [`VoxelizeError::GridTooLarge`].
pub fn plan_grid(
    model: &MeshModel,
    settings: &VoxelizeSettings,
) -> Result<GridPlan, VoxelizeError> {
    model
        .validate()
        .map_err(|(part, source)| VoxelizeError::InvalidMesh { part, source })?;
    match settings.resolution {
        Resolution::Depth(n) if n == 0 || n > MAX_DEPTH => return Err(VoxelizeError::BadDepth(n)),
        Resolution::VoxelSize(s) if !s.is_finite() || s <= 0.0 => {
            return Err(VoxelizeError::BadVoxelSize(s));
        }
        _ => {}
    }
    if settings.max_voxels == 0 {
        return Err(VoxelizeError::BadVoxelLimit);
    }
    let max_axis = f64::from(1u32 << MAX_DEPTH);
    let pad = f64::from(settings.padding);
    let Some((lo, hi)) = referenced_bounds(model) else {
        // No triangles: an empty octree of the requested depth.
        let depth = match settings.resolution {
            Resolution::Depth(n) => n,
            Resolution::VoxelSize(_) => 1,
        };
        let voxel_size = match settings.resolution {
            Resolution::Depth(_) => 1.0,
            Resolution::VoxelSize(s) => s,
        };
        return Ok(GridPlan {
            origin: Vec3::ZERO,
            voxel_size,
            dims: [1; 3],
            depth,
        });
    };
    let size = hi - lo;
    let (voxel_size, cap) = match settings.resolution {
        Resolution::Depth(n) => {
            let longest = size.max_element();
            if longest <= 0.0 || !longest.is_finite() {
                return Err(VoxelizeError::ZeroExtent);
            }
            let cells = f64::from(1u32 << n);
            // Rounding must not turn the longest side's 2^n voxels into 2^n + 1.
            ((longest / cells) as f32, cells)
        }
        Resolution::VoxelSize(s) => (s, f64::INFINITY),
    };
    if voxel_size <= 0.0 || !voxel_size.is_finite() {
        // A depth-derived size can underflow for a microscopic mesh.
        return Err(VoxelizeError::BadVoxelSize(voxel_size));
    }
    let s = f64::from(voxel_size);
    let mut dims = [0u32; 3];
    for axis in 0..3 {
        let cells = (size[axis] / s).ceil().clamp(1.0, cap) + 2.0 * pad;
        // NaN cannot reach here (sizes are finite, the voxel size positive), but refuse it too.
        if cells.is_nan() || cells > max_axis {
            return Err(VoxelizeError::GridTooLarge {
                axis: ['x', 'y', 'z'][axis],
                voxels: cells,
                max: 1 << MAX_DEPTH,
            });
        }
        dims[axis] = cells as u32;
    }
    let longest = dims.iter().copied().max().unwrap_or(1).max(2);
    let depth = (32 - (longest - 1).leading_zeros()) as u8;
    let origin = lo - DVec3::splat(pad * s);
    Ok(GridPlan {
        origin: origin.as_vec3(),
        voxel_size,
        dims,
        depth,
    })
}

/// Flat triangle addressing: `offsets[p]` is the global index of part `p`'s first triangle.
struct Triangles<'a> {
    model: &'a MeshModel,
    offsets: Vec<u32>,
    origin: DVec3,
    voxel_size: f64,
}

impl Triangles<'_> {
    fn total(&self) -> u32 {
        self.offsets.last().copied().unwrap_or(0)
    }

    /// `(part, local triangle)` of global triangle `g`.
    fn locate(&self, g: u32) -> (usize, usize) {
        let part = self.offsets.partition_point(|&o| o <= g) - 1;
        (part, (g - self.offsets[part]) as usize)
    }

    fn grid(&self, g: u32) -> GridTriangle {
        let (part, t) = self.locate(g);
        let mesh = &self.model.parts[part];
        let idx = mesh.triangle(t);
        GridTriangle::new(
            idx.map(|i| (mesh.positions[i].as_dvec3() - self.origin) / self.voxel_size),
        )
    }
}

/// Runs `work` over all triangles in chunks, in parallel within a chunk, reporting progress
/// between chunks (the callback is not `Sync`, so it is only called from this thread).
fn for_triangles<R: Send>(
    tris: &Triangles<'_>,
    progress: &dyn Fn(f32) -> bool,
    (p0, p1): (f32, f32),
    work: impl Fn(u32, &GridTriangle, &mut Vec<R>) + Sync,
) -> Result<Vec<R>, VoxelizeError> {
    let total = tris.total();
    let chunk = (total / 32).max(1024);
    let mut out: Vec<R> = Vec::new();
    let mut start = 0u32;
    while start < total {
        let end = start.saturating_add(chunk).min(total);
        let parts: Vec<Vec<R>> = (start..end)
            .into_par_iter()
            .fold(Vec::new, |mut acc, g| {
                let tri = tris.grid(g);
                if !tri.is_degenerate() {
                    work(g, &tri, &mut acc);
                }
                acc
            })
            .collect();
        for p in parts {
            out.extend(p);
        }
        start = end;
        if !progress(p0 + (p1 - p0) * (start as f32 / total as f32)) {
            return Err(VoxelizeError::Cancelled);
        }
    }
    Ok(out)
}

/// The first global triangle index of each part, and the total at the end.
fn part_offsets(model: &MeshModel, settings: &VoxelizeSettings) -> Result<Vec<u32>, VoxelizeError> {
    let mut offsets = Vec::with_capacity(model.parts.len() + 1);
    let mut acc = 0u64;
    for part in &model.parts {
        offsets.push(acc as u32);
        acc += part.triangle_count() as u64;
    }
    if acc > u64::from(u32::MAX) {
        return Err(VoxelizeError::TooManyVoxels {
            limit: settings.max_voxels,
            what: "more than 2^32 triangles",
        });
    }
    offsets.push(acc as u32);
    Ok(offsets)
}

/// What a [`voxelize`] call will produce and need, estimated from the mesh alone in one pass
/// over its triangles, before anything grid-sized is allocated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelEstimate {
    /// Surface voxels: each triangle's area times its normal's L1 norm (a plane with unit
    /// normal `n` crosses about `|n|₁` voxel layers per unit of area), in voxels.
    pub surface_voxels: f64,
    /// [`Mode::Solid`]: the enclosed volume in voxels (divergence theorem; for an open mesh a
    /// guess, bounded by the grid). Zero for [`Mode::Surface`].
    pub interior_voxels: f64,
    /// Peak heap bytes of the voxelization: [`PEAK_BYTES_PER_VOXEL`] per estimated voxel plus
    /// [`PEAK_BYTES_FIXED`].
    pub peak_bytes: u64,
}

/// Heap bytes [`voxelize`] holds at its peak per voxel of its result (overlap records, surface
/// and interior voxel lists, column crossings and the octree being built). Measured with a
/// counting allocator at 71–166 bytes on Spot, the Bevy torus and the Kenney rock, and at
/// 75–114 bytes on the skinned CesiumMan and RiggedFigure (joints and weights per voxel), at
/// depths 6–8 in both modes (`the_voxelize_estimate_holds_the_measured_peak`).
pub const PEAK_BYTES_PER_VOXEL: u64 = 180;
/// Allocations that do not grow with the voxel count (triangle offsets, octree roots).
pub const PEAK_BYTES_FIXED: u64 = 256 << 10;

/// Estimates what [`voxelize`] with `settings` will produce and need (see [`VoxelEstimate`]),
/// without voxelizing.
///
/// # Errors
/// As [`plan_grid`] (empty or non-finite mesh, a grid over 2^21 voxels a side).
pub fn estimate(
    model: &MeshModel,
    settings: &VoxelizeSettings,
) -> Result<VoxelEstimate, VoxelizeError> {
    let plan = plan_grid(model, settings)?;
    let offsets = part_offsets(model, settings)?;
    let tris = Triangles {
        model,
        offsets,
        origin: plan.origin.as_dvec3(),
        voxel_size: f64::from(plan.voxel_size),
    };
    let (mut surface, mut volume) = (0.0f64, 0.0f64);
    for g in 0..tris.total() {
        let t = tris.grid(g);
        let n = t.normal;
        // |normal| is twice the area; |n|₁ / |n| layers per unit area.
        surface += 0.5 * (n.x.abs() + n.y.abs() + n.z.abs());
        volume += t.v[0].dot(t.v[1].cross(t.v[2])) / 6.0;
    }
    let grid = plan.dims.iter().map(|&d| f64::from(d)).product::<f64>();
    let interior = if settings.mode == Mode::Solid {
        volume.abs().min(grid)
    } else {
        0.0
    };
    let has_skin = model
        .parts
        .iter()
        .any(|p| !p.joints.is_empty() && !p.weights.is_empty());
    let dims = UVec3::from_array(plan.dims);
    let solid = settings.mode == Mode::Solid;
    // A rigid solid on the grid's bits lists no interior voxel (`sealed`): what grows with the
    // result is its surface, held about twice (the kept voxels, and the surface voxels'
    // attributes searched for the interior beside them), and the grid's bits and flags.
    let rigid_dense = solid && !has_skin && bits::fits(dims);
    let dense = solid && !rigid_dense && dense::fits(dims);
    let voxels = if rigid_dense {
        2.0 * surface.min(grid)
    } else {
        surface.min(grid) + interior
    };
    // The dense fill's grid (see `dense`), on top of the voxels.
    let dense_bytes = if rigid_dense {
        bits::padded_cells(dims) as f64 * sealed::BYTES_PER_CELL
            + bits::inside_bits_scratch_bytes(dims) as f64
    } else if dense {
        grid * dense::DENSE_BYTES_PER_CELL as f64
    } else {
        0.0
    };
    Ok(VoxelEstimate {
        surface_voxels: surface,
        interior_voxels: interior,
        peak_bytes: PEAK_BYTES_FIXED
            .saturating_add((voxels * PEAK_BYTES_PER_VOXEL as f64 + dense_bytes) as u64),
    })
}

/// Voxelizes `model` (in its object space) into an octree.
///
/// `progress(fraction)` is called from the calling thread now and then; returning `false`
/// cancels with [`VoxelizeError::Cancelled`]. An empty model gives an empty octree.
///
/// # Errors
/// Bad settings or mesh (see [`plan_grid`]), [`VoxelizeError::TooManyVoxels`] before large
/// allocations, [`VoxelizeError::Cancelled`].
pub fn voxelize(
    model: &MeshModel,
    settings: &VoxelizeSettings,
    progress: &dyn Fn(f32) -> bool,
) -> Result<Voxelized, VoxelizeError> {
    let plan = plan_grid(model, settings)?;
    let has_skin = model
        .parts
        .iter()
        .any(|p| !p.joints.is_empty() && !p.weights.is_empty());
    let offsets = part_offsets(model, settings)?;
    let acc = u64::from(offsets.last().copied().unwrap_or(0));
    let mut stats = VoxelizeStats {
        triangles: acc,
        ..VoxelizeStats::default()
    };
    let empty = |stats| -> Result<Voxelized, VoxelizeError> {
        Ok(Voxelized {
            svo: Svo::new(plan.depth, has_skin)?,
            voxel_size: plan.voxel_size,
            origin: plan.origin,
            stats,
        })
    };
    if acc == 0 {
        return empty(stats);
    }
    let s = f64::from(plan.voxel_size);
    let tris = Triangles {
        model,
        offsets,
        origin: plan.origin.as_dvec3(),
        voxel_size: s,
    };
    let dims = UVec3::from_array(plan.dims);

    // A flat triangle of area A touches at least A / √2 voxels (no plane cuts a unit cube in
    // more than √2), so this refuses hopeless requests before any allocation.
    let overlap_limit = settings.max_voxels.saturating_mul(4);
    let mut min_overlaps = 0.0f64;
    for g in 0..tris.total() {
        let t = tris.grid(g);
        if !t.is_degenerate() {
            min_overlaps += 0.5 * t.normal.length() / std::f64::consts::SQRT_2;
        } else {
            stats.degenerate_triangles += 1;
        }
    }
    if min_overlaps > overlap_limit as f64 {
        return Err(VoxelizeError::TooManyVoxels {
            limit: settings.max_voxels,
            what: "estimated from the surface area",
        });
    }
    if !progress(0.02) {
        return Err(VoxelizeError::Cancelled);
    }

    // Surface: all (voxel, triangle) overlaps, sorted so the nearest triangle comes first.
    let budget = Budget::new(overlap_limit);
    let mut records: Vec<SurfaceRecord> =
        for_triangles(&tris, progress, (0.02, 0.55), |g, tri, out| {
            surface::emit_triangle(tri, g, dims, &budget, out);
        })?;
    if budget.is_exceeded() {
        return Err(VoxelizeError::TooManyVoxels {
            limit: settings.max_voxels,
            what: "voxel–triangle overlaps",
        });
    }
    stats.overlaps = records.len() as u64;
    records.par_sort_unstable();
    records.dedup_by_key(|r| r.0);
    stats.surface_voxels = records.len() as u64;
    if stats.surface_voxels > settings.max_voxels {
        return Err(VoxelizeError::TooManyVoxels {
            limit: settings.max_voxels,
            what: "surface voxels",
        });
    }

    // Solid: column crossings along three axes → inside runs, voted into the interior. A
    // rigid solid's interior goes through the grid's bits into tiles when the grid fits them:
    // it may then stand for up to `MAX_TILED_SOLID_VOXELS`; one listed voxel by voxel answers
    // to `max_voxels`.
    let on_bits = !has_skin && bits::fits(dims);
    let inside_limit = if on_bits {
        settings.max_voxels.max(MAX_TILED_SOLID_VOXELS)
    } else {
        settings.max_voxels
    };
    let fills = if settings.mode == Mode::Solid {
        let mut fills = Vec::with_capacity(3);
        // An open mesh has no inside: filling it gives slabs, or the whole grid. It is open
        // at this resolution when a column along any axis enters it and does not leave (three
        // axes: a hole facing x is missed by every z column). Then only its surface is kept.
        let mut open = 0;
        // The interior bits and the dense transform need only the inside runs; the sparse
        // fill takes attributes from the crossings.
        let keep = if on_bits || dense::fits(dims) {
            fill::Keep::Runs
        } else {
            fill::Keep::Crossings
        };
        for (i, axis) in fill::Axis::ALL.into_iter().enumerate() {
            let from = 0.55 + 0.05 * i as f32;
            let f = fill::cast(
                &tris,
                dims,
                axis,
                settings.fill_rule,
                keep,
                overlap_limit,
                progress,
                (from, from + 0.05),
            )?;
            open += f.open_columns;
            if open > 0 {
                break;
            }
            // Refused before the runs are expanded into voxels.
            if f.inside_count().saturating_add(stats.surface_voxels) > inside_limit {
                return Err(VoxelizeError::TooManyVoxels {
                    limit: inside_limit,
                    what: "interior voxels",
                });
            }
            fills.push(f);
        }
        if open > 0 {
            stats.open_columns = open;
            stats.boundary_edges = boundary_edges(model);
            stats.solid_fell_back = true;
            None
        } else {
            <[fill::AxisFill; 3]>::try_from(fills).ok()
        }
    } else {
        None
    };
    // The dense fill when the grid is small enough: interior voxels take the attributes of
    // their nearest surface voxel. Otherwise the sparse fill: the nearest bounding crossing's.
    let interior = match fills {
        // A rigid solid needs no transform: its enclosed interior is the interior mark, and
        // the octree is built from the interior's bits (`sealed`).
        Some(fills) if on_bits => Some(Interior::Bits(bits::inside_bits(dims, &fills))),
        Some(fills) if dense::fits(dims) => {
            let seeds: Vec<UVec3> = records.par_iter().map(|r| morton_decode(r.0)).collect();
            Some(Interior::Dense(dense::DenseFill::new(dims, &fills, &seeds)))
        }
        Some(fills) => Some(Interior::Sparse(fill::vote(&fills, |c| {
            let (part, t) = tris.locate(c.gtri);
            transfer(model, &model.parts[part], t, c.bary, has_skin)
        })?)),
        None => None,
    };
    if let Some(inside) = &interior {
        stats.interior_voxels = inside.len();
        stats.interior_from_nearest_surface = !matches!(inside, Interior::Sparse(_));
        if stats.interior_voxels.saturating_add(stats.surface_voxels) > inside_limit {
            return Err(VoxelizeError::TooManyVoxels {
                limit: inside_limit,
                what: "interior voxels",
            });
        }
    }
    if !progress(0.75) {
        return Err(VoxelizeError::Cancelled);
    }

    // Attributes of each surface voxel from its nearest triangle, and whether it stays: in
    // solid mode one outside the mesh that an interior voxel already represents is dropped
    // (it still gives the interior its attributes).
    let keep_outer = settings.keep_outer_surface;
    let record_voxels: Vec<(Voxel, bool)> = records
        .par_iter()
        .map(|&(code, key)| {
            let coord = morton_decode(code);
            let g = surface::key_triangle(key);
            let tri = tris.grid(g);
            let centre = coord.as_dvec3() + DVec3::splat(0.5);
            let bary = tri.closest_barycentric(centre);
            let dropped = interior.as_ref().is_some_and(|inside| {
                !keep_outer
                    && !inside.contains(coord)
                    && represented_inside(inside, dims, centre, tri.point(bary), &tri)
            });
            let (part, t) = tris.locate(g);
            let voxel = transfer(model, &model.parts[part], t, bary, has_skin);
            (voxel, !dropped)
        })
        .collect();
    let surface_voxels: Vec<(UVec3, Voxel)> = records
        .par_iter()
        .zip(&record_voxels)
        .filter(|(_, (_, keep))| *keep)
        .map(|(&(code, _), &(voxel, _))| (morton_decode(code), voxel))
        .collect();
    if !progress(0.85) {
        return Err(VoxelizeError::Cancelled);
    }

    if let Some(Interior::Bits(inside)) = interior {
        // Interior voxels that are not enclosed take their nearest surface voxel's attributes,
        // among all the surface voxels (those solid mode dropped too), as the transform does:
        // found on the surface voxels' bits within a few voxels, where nearly all are, and by
        // the octree search beyond.
        let dropped: Vec<(UVec3, Voxel)> = records
            .iter()
            .zip(&record_voxels)
            .filter(|(_, (_, keep))| !keep)
            .map(|(r, (v, _))| (morton_decode(r.0), *v))
            .collect();
        drop(record_voxels);
        drop(records);
        if !progress(0.9) {
            return Err(VoxelizeError::Cancelled);
        }
        let (svo, counts) = sealed::build(
            plan.depth,
            inside,
            &surface_voxels,
            &dropped,
            sealed::NEAR_SEARCH_RADIUS,
        )?;
        stats.interior_marked = counts.marked;
        stats.voxels = svo.leaf_count();
        progress(1.0);
        return Ok(Voxelized {
            svo,
            voxel_size: plan.voxel_size,
            origin: plan.origin,
            stats,
        });
    }

    // An interior voxel enclosed on all six faces by voxels of the solid is stored as the
    // interior mark (`Voxel::INTERIOR`: its attributes are found when an edit exposes it, so
    // the inside is a few tiles); one that is not keeps the attributes found for it here.
    let surface_codes: Vec<u64> = surface_voxels
        .iter()
        .map(|e| crate::svo::morton_encode(e.0))
        .collect();
    let enclosed = |inside: &dyn Fn(UVec3) -> bool, c: UVec3| {
        FACE_NEIGHBOURS.iter().all(|&f| {
            let q = c.as_ivec3() + f;
            if q.cmplt(IVec3::ZERO).any() || q.as_uvec3().cmpge(dims).any() {
                return false;
            }
            let q = q.as_uvec3();
            inside(q)
                || surface_codes
                    .binary_search(&crate::svo::morton_encode(q))
                    .is_ok()
        })
    };
    let interior_voxels = match &interior {
        Some(Interior::Sparse(inside)) => inside
            .keys
            .par_iter()
            .zip(&inside.voxels)
            .map(|(&code, &v)| {
                let c = morton_decode(code);
                let sealed = enclosed(&|q| inside.contains(q), c);
                (c, if sealed { interior_with_skin(v) } else { v })
            })
            .collect(),
        Some(Interior::Bits(_)) => unreachable!("built above"),
        Some(Interior::Dense(inside)) => inside.interior(|c, seed| {
            let code = crate::svo::morton_encode(seed);
            let i = records.binary_search_by_key(&code, |r| r.0).ok()?;
            let v = record_voxels[i].0;
            if enclosed(&|q| inside.contains(q), c) {
                return Some((c, interior_with_skin(v)));
            }
            Some((c, v))
        }),
        None => Vec::new(),
    };
    stats.interior_marked = interior_voxels.iter().filter(|e| e.1.is_interior()).count() as u64;
    drop(interior);
    drop(surface_codes);
    drop(record_voxels);
    drop(records);
    if !progress(0.9) {
        return Err(VoxelizeError::Cancelled);
    }

    // Interior first: the octree builder keeps the later of duplicates, so a voxel that is both
    // interior and surface takes the surface's (nearest-triangle) attributes.
    let svo = Svo::from_voxels(
        plan.depth,
        has_skin,
        interior_voxels.into_iter().chain(surface_voxels),
    )?;
    stats.voxels = svo.leaf_count();
    progress(1.0);
    Ok(Voxelized {
        svo,
        voxel_size: plan.voxel_size,
        origin: plan.origin,
        stats,
    })
}

/// The interior mark carrying `v`'s skin: a skinned solid's interior leaves drawn beside its
/// shell move with it (`Voxel::is_interior` does not look at skin).
fn interior_with_skin(v: Voxel) -> Voxel {
    Voxel {
        skin: v.skin,
        ..Voxel::INTERIOR
    }
}

/// Edges used by an odd number of non-degenerate triangles, with vertices welded by exact
/// position over all parts (so UV seams and part boundaries that meet are closed). Zero for a
/// closed surface, including non-manifold ones whose edges join four faces.
#[must_use]
pub fn boundary_edges(model: &MeshModel) -> u64 {
    let key = |p: Vec3| (p + Vec3::ZERO).to_array().map(f32::to_bits);
    let mut ids: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    let mut edges: Vec<(u32, u32)> = Vec::new();
    for part in &model.parts {
        let welded: Vec<u32> = part
            .positions
            .iter()
            .map(|&p| {
                let next = ids.len() as u32;
                *ids.entry(key(p)).or_insert(next)
            })
            .collect();
        for t in 0..part.triangle_count() {
            let [a, b, c] = part
                .triangle(t)
                .map(|i| welded.get(i).copied().unwrap_or(u32::MAX));
            if a == b || b == c || a == c {
                continue;
            }
            for (u, v) in [(a, b), (b, c), (c, a)] {
                edges.push((u.min(v), u.max(v)));
            }
        }
    }
    edges.par_sort_unstable();
    let mut open = 0u64;
    let mut i = 0;
    while i < edges.len() {
        let j = edges[i..].partition_point(|e| *e == edges[i]) + i;
        if (j - i) % 2 == 1 {
            open += 1;
        }
        i = j;
    }
    open
}

/// Solid mode: a surface voxel whose centre is outside the mesh is dropped when the solid
/// beneath its nearest surface point is already interior voxels. The probe goes √3 voxels past
/// that point, away from the centre, so for a locally flat solid at least one voxel thick it
/// lands in a voxel whose centre is inside; for a part thinner than a voxel it passes through
/// and lands outside, and the voxel is kept so thin parts do not vanish or detach.
fn represented_inside(
    interior: &Interior,
    dims: UVec3,
    centre: DVec3,
    q: DVec3,
    tri: &GridTriangle,
) -> bool {
    let dir = (q - centre)
        .try_normalize()
        .or_else(|| (-tri.normal).try_normalize());
    let Some(dir) = dir else {
        return false;
    };
    let probe = (q + dir * 3f64.sqrt()).floor();
    if probe.min_element() < 0.0 || probe.cmpge(dims.as_dvec3()).any() {
        return false;
    }
    interior.contains(probe.as_uvec3())
}

/// The interior of a solid: the dense interior bits alone (a rigid solid, built by `sealed`), dense
/// with every cell's nearest surface voxel known (a skinned one), or sparse.
enum Interior {
    Bits(bits::CellBits),
    Dense(dense::DenseFill),
    Sparse(fill::Interior),
}

impl Interior {
    fn contains(&self, c: UVec3) -> bool {
        match self {
            Self::Bits(inside) => inside.get(c),
            Self::Dense(d) => d.contains(c),
            Self::Sparse(s) => s.contains(c),
        }
    }

    fn len(&self) -> u64 {
        match self {
            Self::Bits(inside) => inside.count_ones(),
            Self::Dense(d) => d.len(),
            Self::Sparse(s) => s.keys.len() as u64,
        }
    }
}

/// Attributes of the surface point with barycentric weights `bary` on triangle `t` of `part`:
/// colour (material factor × base-colour texture × vertex colour, stored sRGB), interpolated
/// vertex normal (or the face normal), material index clamped to 255, and the four strongest
/// interpolated joint influences when the part is skinned.
fn transfer(
    model: &MeshModel,
    part: &TriangleMesh,
    t: usize,
    bary: DVec3,
    has_skin: bool,
) -> Voxel {
    let b = bary.as_vec3();
    let linear = model.surface_color(part, t, b);
    let to8 = |c: f32| (linear_to_srgb(c) * 255.0).round() as u8;
    let color = [
        to8(linear.x),
        to8(linear.y),
        to8(linear.z),
        (linear.w.clamp(0.0, 1.0) * 255.0).round() as u8,
    ];
    let idx = part.triangle(t);
    let face = (part.positions[idx[1]] - part.positions[idx[0]])
        .cross(part.positions[idx[2]] - part.positions[idx[0]])
        .try_normalize();
    let normal = if part.normals.is_empty() {
        face
    } else {
        (part.normals[idx[0]] * b.x + part.normals[idx[1]] * b.y + part.normals[idx[2]] * b.z)
            .try_normalize()
            .or(face)
    }
    .unwrap_or(Vec3::Z);
    let skin = if has_skin && !part.joints.is_empty() && !part.weights.is_empty() {
        let mut influences = [(0u16, 0.0f32); 12];
        for (corner, (&vi, w)) in idx.iter().zip(b.to_array()).enumerate() {
            for slot in 0..4 {
                influences[corner * 4 + slot] = (part.joints[vi][slot], part.weights[vi][slot] * w);
            }
        }
        Skin4::from_influences(&influences)
    } else {
        Skin4::default()
    };
    Voxel {
        color,
        normal: encode_normal(normal),
        material: part.material.min(255) as u8,
        skin,
    }
}

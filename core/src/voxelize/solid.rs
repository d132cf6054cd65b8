//! Interior fill: one ray per (x, y) voxel column, through the column centre along +z. Each
//! triangle whose xy projection owns the column centre (top-left rule, see
//! [`super::geometry::point_in_ccw_triangle`]) gives a crossing; a crossing enters when the
//! triangle faces −z. A voxel is interior when its centre lies where the winding number (or the
//! crossing parity) says inside.

use glam::{DVec2, DVec3, UVec3};

use super::FillRule;
use super::geometry::{GridTriangle, point_in_ccw_triangle};
use super::surface::Budget;

/// Column key: `y << 21 | x`.
pub(crate) fn column_key(x: u32, y: u32) -> u64 {
    (u64::from(y) << 21) | u64::from(x)
}

/// Where a column ray crosses a triangle.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Crossing {
    pub(crate) column: u64,
    /// Grid-space z of the crossing.
    pub(crate) z: f64,
    pub(crate) gtri: u32,
    /// +1 entering (triangle faces −z), −1 leaving.
    pub(crate) sign: i8,
    /// Barycentric weights of the crossing point, in the triangle's own vertex order.
    pub(crate) bary: DVec3,
}

/// Appends the column crossings of `tri` to `out`. Returns false when the budget ran out.
pub(crate) fn emit_crossings(
    tri: &GridTriangle,
    gtri: u32,
    dims: UVec3,
    budget: &Budget,
    out: &mut Vec<Crossing>,
) -> bool {
    for_each_crossing(tri, dims, budget, |x, y, sign, bary| {
        out.push(Crossing {
            column: column_key(x, y),
            z: tri.point(bary).z,
            gtri,
            sign,
            bary,
        });
    })
}

/// Appends the column crossings of `tri` to `out` as [`CrossingKey`]s: what a rigid solid's
/// inside runs need (column, the first voxel centre at or past the crossing, sign), 8 bytes
/// instead of a 56-byte [`Crossing`]. Returns false when the budget ran out.
pub(crate) fn emit_crossing_keys(
    tri: &GridTriangle,
    dims: UVec3,
    budget: &Budget,
    out: &mut Vec<u64>,
) -> bool {
    for_each_crossing(tri, dims, budget, |x, y, sign, bary| {
        out.push(CrossingKey::new(x, y, tri.point(bary).z, sign, dims).0);
    })
}

/// Calls `f(x, y, sign, barycentrics)` for each column of `dims` whose centre the xy
/// projection of `tri` owns. Returns false when the budget ran out.
fn for_each_crossing(
    tri: &GridTriangle,
    dims: UVec3,
    budget: &Budget,
    mut f: impl FnMut(u32, u32, i8, DVec3),
) -> bool {
    if budget.is_exceeded() {
        return false;
    }
    let p = tri.v.map(|v| DVec2::new(v.x, v.y));
    // Projected signed area (= normal.z). Zero: the triangle is parallel to the rays and its
    // neighbours' shared edges account for the crossing.
    let area = tri.normal.z;
    if area == 0.0 || !area.is_finite() {
        return true;
    }
    // Counter-clockwise order for the top-left rule; `order` maps back to vertex indices.
    let order = if area > 0.0 { [0, 1, 2] } else { [0, 2, 1] };
    let ccw = order.map(|i| p[i]);
    let sign = if area < 0.0 { 1 } else { -1 };
    let min = tri.min();
    let max = tri.max();
    let x_lo = (min.x - 0.5).ceil().max(0.0);
    let x_hi = (max.x - 0.5).floor().min(f64::from(dims.x) - 1.0);
    let y_lo = (min.y - 0.5).ceil().max(0.0);
    let y_hi = (max.y - 0.5).floor().min(f64::from(dims.y) - 1.0);
    if x_lo > x_hi || y_lo > y_hi {
        return true;
    }
    for y in y_lo as u32..=y_hi as u32 {
        let mut row = 0u64;
        for x in x_lo as u32..=x_hi as u32 {
            let centre = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
            let Some(w_ccw) = point_in_ccw_triangle(ccw, centre) else {
                continue;
            };
            let mut bary = DVec3::ZERO;
            for (slot, &vi) in order.iter().enumerate() {
                bary[vi] = w_ccw[slot];
            }
            f(x, y, sign, bary);
            row += 1;
        }
        if !budget.charge(row) {
            return false;
        }
    }
    true
}

/// A crossing as one sortable word: `column << 32 | first << 1 | entering`, where the column
/// is `y · dims.x + x` and `first` the first voxel whose centre is at or past the crossing
/// (`⌈z − ½⌉` clamped to `0..=dims.z`). Whether a centre is inside depends only on the sum of
/// the signs (or the count) of the crossings at or before it, never on their order, so these
/// words give exactly the voxels the full crossings give, in a closed mesh; an open column's
/// unfinished run would depend on the order of crossings between two centres, and a rigid
/// solid with an open column is not filled. Holds for grids of at most 2^30 cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct CrossingKey(pub(crate) u64);

impl CrossingKey {
    /// Grids whose crossings fit a key: at most 2^30 columns and 2^30 voxels along them.
    pub(crate) fn fits(dims: UVec3) -> bool {
        u64::from(dims.x) * u64::from(dims.y) <= 1 << 30 && dims.z <= 1 << 30
    }

    fn new(x: u32, y: u32, z: f64, sign: i8, dims: UVec3) -> Self {
        let column = u64::from(y) * u64::from(dims.x) + u64::from(x);
        let first = (z - 0.5).ceil().clamp(0.0, f64::from(dims.z)) as u64;
        Self(column << 32 | first << 1 | u64::from(sign > 0))
    }

    fn column(self) -> u64 {
        self.0 >> 32
    }

    fn first(self) -> u32 {
        ((self.0 >> 1) & 0x7fff_ffff) as u32
    }

    fn sign(self) -> i64 {
        if self.0 & 1 == 1 { 1 } else { -1 }
    }
}

/// Sorts crossing keys and turns each column into inside runs (columns as [`column_key`]),
/// with the number of columns that do not close under `rule`. An open column's runs are left
/// out from its last entry on (see [`CrossingKey`]: callers fill no solid with one).
pub(crate) fn key_runs(keys: &mut [u64], dims: UVec3, rule: FillRule) -> (Vec<ColumnRun>, u64) {
    use rayon::prelude::*;
    keys.par_sort_unstable();
    let mut runs = Vec::new();
    let mut open_columns = 0;
    let mut i = 0;
    while i < keys.len() {
        let column = CrossingKey(keys[i]).column();
        let key = column_key(
            (column % u64::from(dims.x)) as u32,
            (column / u64::from(dims.x)) as u32,
        );
        let (mut winding, mut count) = (0i64, 0u64);
        let mut start: Option<u32> = None;
        while i < keys.len() && CrossingKey(keys[i]).column() == column {
            let k = CrossingKey(keys[i]);
            winding += k.sign();
            count += 1;
            match (start, rule.inside(winding, count)) {
                (None, true) => start = Some(k.first()),
                (Some(k_lo), false) => {
                    // Centres k_lo..first, clipped to the grid.
                    if k_lo < k.first() && k_lo < dims.z {
                        runs.push(ColumnRun {
                            column: key,
                            k_lo,
                            k_hi: k.first().min(dims.z) - 1,
                        });
                    }
                    start = None;
                }
                _ => {}
            }
            i += 1;
        }
        if start.is_some() {
            open_columns += 1;
        }
    }
    (runs, open_columns)
}

/// A run of interior voxels `k_lo..=k_hi` in one column ([`column_key`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ColumnRun {
    pub(crate) column: u64,
    pub(crate) k_lo: u32,
    pub(crate) k_hi: u32,
}

/// The crossings that bound a [`ColumnRun`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bounds {
    pub(crate) z_in: f64,
    pub(crate) z_out: f64,
    /// Indices into the sorted crossing list.
    pub(crate) entry: usize,
    pub(crate) exit: usize,
}

/// Sorts crossings (column, z, triangle — a total order, so the result does not depend on the
/// order threads produced them) and turns each column into inside runs and their bounding
/// crossings, with the number of columns that do not close under `rule` (a non-zero winding
/// number, or an odd number of crossings, after the last one). Such a column (an open mesh)
/// drops its unfinished run.
pub(crate) fn intervals(
    crossings: &mut [Crossing],
    dims_z: u32,
    rule: FillRule,
) -> (Vec<ColumnRun>, Vec<Bounds>, u64) {
    use rayon::prelude::*;
    crossings.par_sort_unstable_by(|a, b| {
        a.column
            .cmp(&b.column)
            .then(a.z.total_cmp(&b.z))
            .then(a.gtri.cmp(&b.gtri))
    });
    let (mut runs, mut bounds) = (Vec::new(), Vec::new());
    let mut open_columns = 0;
    let mut i = 0;
    while i < crossings.len() {
        let column = crossings[i].column;
        let mut winding = 0i64;
        let mut count = 0u64;
        let mut open: Option<usize> = None;
        while i < crossings.len() && crossings[i].column == column {
            winding += i64::from(crossings[i].sign);
            count += 1;
            let now = rule.inside(winding, count);
            match (open, now) {
                (None, true) => open = Some(i),
                (Some(entry), false) => {
                    let z_in = crossings[entry].z;
                    let z_out = crossings[i].z;
                    // Centres k + 0.5 in [z_in, z_out).
                    let k_lo = (z_in - 0.5).ceil().max(0.0);
                    let k_hi = ((z_out - 0.5).ceil() - 1.0).min(f64::from(dims_z) - 1.0);
                    if k_lo <= k_hi {
                        runs.push(ColumnRun {
                            column,
                            k_lo: k_lo as u32,
                            k_hi: k_hi as u32,
                        });
                        bounds.push(Bounds {
                            z_in,
                            z_out,
                            entry,
                            exit: i,
                        });
                    }
                    open = None;
                }
                _ => {}
            }
            i += 1;
        }
        if open.is_some() {
            open_columns += 1;
        }
    }
    (runs, bounds, open_columns)
}

//! Conservative surface voxelization of one triangle: every voxel whose closed box the triangle
//! meets (separating-axis test), visited column by column along the normal's dominant axis so
//! the work follows the triangle's area, not its bounding box.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::{DVec3, UVec3};

use super::geometry::GridTriangle;
use crate::svo::morton_encode;

/// A shared cap on how many records the parallel passes may produce, so a request that would
/// exhaust memory stops early instead of allocating.
pub(crate) struct Budget {
    used: AtomicU64,
    limit: u64,
    exceeded: AtomicBool,
}

impl Budget {
    pub(crate) fn new(limit: u64) -> Self {
        Self {
            used: AtomicU64::new(0),
            limit,
            exceeded: AtomicBool::new(false),
        }
    }

    /// Charges `n` records; false once the cap is passed (by anyone).
    pub(crate) fn charge(&self, n: u64) -> bool {
        if n == 0 {
            return !self.is_exceeded();
        }
        let before = self.used.fetch_add(n, Ordering::Relaxed);
        if before.saturating_add(n) > self.limit {
            self.exceeded.store(true, Ordering::Relaxed);
            return false;
        }
        true
    }

    pub(crate) fn is_exceeded(&self) -> bool {
        self.exceeded.load(Ordering::Relaxed)
    }
}

/// One (voxel, triangle) overlap: the voxel's Morton code and a key that orders candidates for
/// the same voxel: squared distance from the voxel centre to the triangle (f32 bits, which sort
/// like the value for non-negative numbers) in the high half, global triangle index in the low.
pub(crate) type SurfaceRecord = (u64, u64);

pub(crate) fn record_key(dist2: f64, gtri: u32) -> u64 {
    // Rounding to f32 can make near-equal distances tie; the triangle index then decides, so
    // the choice never depends on which thread produced which record.
    let d = (dist2 as f32).max(0.0);
    (u64::from(d.to_bits()) << 32) | u64::from(gtri)
}

pub(crate) fn key_triangle(key: u64) -> u32 {
    key as u32
}

/// Appends the overlaps of `tri` (global index `gtri`) with the `dims` grid to `out`.
/// Returns false when the budget ran out.
pub(crate) fn emit_triangle(
    tri: &GridTriangle,
    gtri: u32,
    dims: UVec3,
    budget: &Budget,
    out: &mut Vec<SurfaceRecord>,
) -> bool {
    if budget.is_exceeded() {
        return false;
    }
    let max_index = dims.as_dvec3() - DVec3::ONE;
    // Voxel ranges: the voxels holding a point of the triangle's bounding box under the
    // half-open rule (voxel i holds [i, i + 1)), clamped into the grid. Every point of the
    // triangle lies in such a voxel, so the closed-box test below leaves no gaps; a triangle
    // lying exactly on a grid plane marks one layer, not two.
    let lo = tri.min().floor().clamp(DVec3::ZERO, max_index);
    let hi = tri.max().floor().clamp(DVec3::ZERO, max_index);
    let n = tri.normal;
    let na = n.abs();
    let w_axis = if na.x >= na.y && na.x >= na.z {
        0
    } else if na.y >= na.z {
        1
    } else {
        2
    };
    let (u_axis, v_axis) = match w_axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let plane_d = n.dot(tri.v[0]);
    let nw = n[w_axis];
    let (nu, nv) = (n[u_axis], n[v_axis]);
    let (lo_w, hi_w) = (lo[w_axis] as i64, hi[w_axis] as i64);
    for iu in lo[u_axis] as i64..=hi[u_axis] as i64 {
        let mut column = 0u64;
        for iv in lo[v_axis] as i64..=hi[v_axis] as i64 {
            // The plane's w over this column's square is linear: its extremes are at corners.
            // Closed boxes [k, k + 1] meet [wmin, wmax] for k in ceil(wmin) - 1 ..= floor(wmax);
            // a little slack absorbs rounding and the exact test decides.
            let (mut wmin, mut wmax) = (f64::INFINITY, f64::NEG_INFINITY);
            for (du, dv) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                let w = (plane_d - nu * (iu as f64 + du) - nv * (iv as f64 + dv)) / nw;
                wmin = wmin.min(w);
                wmax = wmax.max(w);
            }
            const SLACK: f64 = 1e-6;
            let k_lo = if wmin.is_finite() {
                ((wmin - SLACK).ceil() as i64 - 1).max(lo_w)
            } else {
                lo_w
            };
            let k_hi = if wmax.is_finite() {
                ((wmax + SLACK).floor() as i64).min(hi_w)
            } else {
                hi_w
            };
            for iw in k_lo..=k_hi {
                let mut c = [0i64; 3];
                c[u_axis] = iu;
                c[v_axis] = iv;
                c[w_axis] = iw;
                let corner = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
                if !tri.overlaps_unit_box(corner) {
                    continue;
                }
                let centre = corner + DVec3::splat(0.5);
                let q = tri.point(tri.closest_barycentric(centre));
                let coord = UVec3::new(c[0] as u32, c[1] as u32, c[2] as u32);
                out.push((
                    morton_encode(coord),
                    record_key(q.distance_squared(centre), gtri),
                ));
                column += 1;
            }
        }
        if !budget.charge(column) {
            return false;
        }
    }
    true
}

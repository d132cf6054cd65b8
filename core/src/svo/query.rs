//! Read-only queries: front-to-back traversal with a caller's LOD predicate, and ray casting
//! (the editor's picking).

use glam::{DVec3, IVec3, UVec3, Vec3};

use super::{NodeRef, Svo, SvoError};

/// The order in which to visit the 8 children so nearer ones come first for a view direction
/// `dir` (from the eye into the scene): octant `k ^ flip` for `k = 0..8`, where `flip` sets the
/// bit of every axis along which `dir` is negative. Valid front-to-back for parallel
/// projection and for any ray; for perspective use the direction from the eye to the node.
#[must_use]
pub fn front_to_back_order(dir: Vec3) -> [u8; 8] {
    let flip = u8::from(dir.x < 0.0) | u8::from(dir.y < 0.0) << 1 | u8::from(dir.z < 0.0) << 2;
    std::array::from_fn(|k| k as u8 ^ flip)
}

/// The first voxel a ray hits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// The voxel's coordinate.
    pub coord: UVec3,
    /// Outward normal of the face the ray entered through (a unit axis vector).
    pub normal: IVec3,
    /// Ray parameter of the entry point (in units of the ray direction's length); 0 when the
    /// ray starts inside the voxel.
    pub t: f64,
}

/// Slab test of a ray against the box `[lo, hi]`: `(t_enter, t_exit, entry axis)`.
fn slab(origin: DVec3, inv_dir: DVec3, lo: DVec3, hi: DVec3) -> (f64, f64, usize) {
    let t0 = (lo - origin) * inv_dir;
    let t1 = (hi - origin) * inv_dir;
    let tmin = t0.min(t1);
    let tmax = t0.max(t1);
    // NaN from 0 * inf (ray in a slab plane) must not poison the interval: treat as unbounded.
    let clean = |v: f64, fallback: f64| if v.is_nan() { fallback } else { v };
    let tmin = DVec3::new(
        clean(tmin.x, f64::NEG_INFINITY),
        clean(tmin.y, f64::NEG_INFINITY),
        clean(tmin.z, f64::NEG_INFINITY),
    );
    let tmax = DVec3::new(
        clean(tmax.x, f64::INFINITY),
        clean(tmax.y, f64::INFINITY),
        clean(tmax.z, f64::INFINITY),
    );
    let enter = tmin.max_element();
    let axis = if enter == tmin.x {
        0
    } else if enter == tmin.y {
        1
    } else {
        2
    };
    (enter, tmax.min_element(), axis)
}

impl Svo {
    /// Depth-first traversal, children front-to-back for view direction `dir`.
    /// `visit(node)` returns whether to descend into the node's children. Internal nodes carry
    /// averaged attributes, so a caller that stops early can draw the node as one voxel.
    pub fn traverse(&self, dir: Vec3, mut visit: impl FnMut(&NodeRef) -> bool) {
        if self.is_empty() {
            return;
        }
        let order = front_to_back_order(dir);
        let mut stack = vec![self.root()];
        while let Some(node) = stack.pop() {
            if !visit(&node) || self.is_leaf(&node) {
                continue;
            }
            for &k in order.iter().rev() {
                if let Some(c) = self.child(&node, k) {
                    stack.push(c);
                }
            }
        }
    }

    /// A copy `levels` levels coarser: one voxel per node of this octree at depth
    /// `depth − levels`, carrying the node's averaged attributes (the LOD the renderer draws
    /// when it stops there). `levels = 0` copies the leaves.
    ///
    /// # Errors
    /// [`SvoError::BadDepth`] (depth 0) when `levels` is not below the depth.
    pub fn coarsened(&self, levels: u8) -> Result<Svo, SvoError> {
        let depth = self.depth();
        if levels >= depth {
            return Err(SvoError::BadDepth(0));
        }
        let target = depth - levels;
        let shift = u32::from(levels);
        let mut voxels = Vec::new();
        self.traverse(Vec3::Z, |n| {
            if n.level == target {
                voxels.push((n.origin >> shift, self.node_voxel(n)));
                return false;
            }
            true
        });
        Svo::from_voxels(target, self.has_skin(), voxels)
    }

    /// Casts a ray given in voxel coordinates (voxel `c` spans `[c, c + 1)`); returns the first
    /// solid voxel with `t <= max_t`. Computed in `f64` so depth-21 coordinates stay exact.
    #[must_use]
    pub fn raycast(&self, origin: DVec3, dir: DVec3, max_t: f64) -> Option<RayHit> {
        if self.is_empty() || !origin.is_finite() || !dir.is_finite() || dir.length_squared() == 0.0
        {
            return None;
        }
        let inv_dir = dir.recip();
        let order = front_to_back_order(dir.as_vec3());
        let mut stack = vec![self.root()];
        while let Some(node) = stack.pop() {
            let size = f64::from(self.node_size(node.level));
            let lo = node.origin.as_dvec3();
            let (enter, exit, axis) = slab(origin, inv_dir, lo, lo + size);
            if enter > exit || exit < 0.0 || enter > max_t {
                continue;
            }
            if self.is_leaf(&node) {
                let mut normal = IVec3::ZERO;
                let t = if enter > 0.0 {
                    normal[axis] = if dir[axis] > 0.0 { -1 } else { 1 };
                    enter
                } else {
                    let a = dir.abs();
                    let major = if a.x >= a.y && a.x >= a.z {
                        0
                    } else if a.y >= a.z {
                        1
                    } else {
                        2
                    };
                    normal[major] = if dir[major] > 0.0 { -1 } else { 1 };
                    0.0
                };
                return Some(RayHit {
                    coord: node.origin,
                    normal,
                    t,
                });
            }
            for &k in order.iter().rev() {
                if let Some(c) = self.child(&node, k) {
                    stack.push(c);
                }
            }
        }
        None
    }
}

#[cfg(test)]
pub(super) fn tests_slab(origin: DVec3, inv_dir: DVec3, lo: DVec3, hi: DVec3) -> (f64, f64, usize) {
    slab(origin, inv_dir, lo, hi)
}

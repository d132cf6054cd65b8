//! Interior voxels ([`Voxel::INTERIOR`]): solid voxels enclosed on all six faces whose
//! attributes are not stored. A solid import's inside is made of them, so it is a few tiles
//! instead of one leaf per voxel.
//!
//! The rule (docs/svo.md, "Interior"): an edit that leaves an interior voxel with an empty face
//! neighbour (or on the octree's boundary) gives it the attributes of the nearest voxel that is
//! not interior, among the voxels after the edit and those the edit removed; distance between
//! voxel centres, ties to the smaller Morton code. All voxels an edit exposes are resolved
//! against the octree as the edit left it (the exposed ones still interior), so the result does
//! not depend on their order. The resolved voxels are part of the edit's undo delta: undo puts
//! the interior back.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{IVec3, UVec3};

use super::{EditResult, NodeRef, Svo, Voxel, is_interior_value, morton_encode};

/// The six face neighbours' offsets (+x, −x, +y, −y, +z, −z): what "enclosed" looks at.
pub const FACE_NEIGHBOURS: [IVec3; 6] = [
    IVec3::X,
    IVec3::NEG_X,
    IVec3::Y,
    IVec3::NEG_Y,
    IVec3::Z,
    IVec3::NEG_Z,
];

/// What an exposed interior voxel shows when no voxel anywhere has attributes to give (a cut
/// wholly inside an interior): neutral grey, facing up.
const NOTHING_TO_SHOW: Voxel = Voxel {
    color: [128, 128, 128, 255],
    normal: 0x8080,
    material: 0,
    skin: super::Skin4 {
        joints: [0; 4],
        weights: [0; 4],
    },
};

/// Interior tiles enclosed on all six sides, as sorted Morton ranges `[first, end)`: what
/// [`Svo::for_each_voxel_but_enclosed`] left out. Every voxel in them is solid and interior.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct EnclosedTiles(Vec<(u64, u64)>);

impl EnclosedTiles {
    /// Whether voxel `c` lies in one of the tiles.
    #[must_use]
    pub fn contains(&self, c: UVec3) -> bool {
        let code = morton_encode(c);
        let t = self.0.partition_point(|r| r.1 <= code);
        self.0.get(t).is_some_and(|r| r.0 <= code)
    }

    /// Voxels in the tiles.
    #[must_use]
    pub fn voxels(&self) -> u64 {
        self.0.iter().map(|r| r.1 - r.0).sum()
    }

    /// The Morton ranges, sorted.
    #[must_use]
    pub fn ranges(&self) -> &[(u64, u64)] {
        &self.0
    }
}

/// A candidate of the nearest search: squared distance, then Morton code (the tie-break).
type Key = (u64, u64);

/// A node waiting in the nearest search: its distance bound, level, index and origin.
type Pending = Reverse<(u64, u8, u32, [u32; 3])>;

impl Svo {
    /// Whether every voxel of the box `lo..=hi` is solid (false for a box reaching past the
    /// octree). Work: the nodes the box's region touches, stopping at leaves and tiles.
    #[must_use]
    pub fn box_is_solid(&self, lo: UVec3, hi: UVec3) -> bool {
        if self.is_empty() || lo.cmpgt(hi).any() || hi.cmpge(UVec3::splat(self.extent())).any() {
            return false;
        }
        let mut stack = vec![self.root()];
        while let Some(node) = stack.pop() {
            if self.is_leaf(&node) || self.is_tile(&node) || node.in_tile() {
                continue;
            }
            let half = self.node_size(node.level + 1);
            for k in 0..8u8 {
                let o = node.origin
                    + UVec3::new(u32::from(k & 1), u32::from((k >> 1) & 1), u32::from(k >> 2))
                        * half;
                if (o + UVec3::splat(half - 1)).cmplt(lo).any() || o.cmpgt(hi).any() {
                    continue;
                }
                match self.child(&node, k) {
                    Some(c) => stack.push(c),
                    None => return false,
                }
            }
        }
        true
    }

    /// Calls `f(voxel, value)` for every voxel except those of interior tiles enclosed on all
    /// six sides (each face's neighbouring slab solid), and returns those tiles. No voxel of such a tile has an empty face neighbour, so a
    /// mesher that leaves them out sees sealed cavities there, which it never meshes: an
    /// export of a solid then walks its surface and its tiles, not its volume. Each interior
    /// tile costs six [`Self::box_is_solid`] queries; a tile beside an empty voxel (which a
    /// well-formed octree never has: edits expose such voxels) is walked voxel by voxel.
    pub fn for_each_voxel_but_enclosed(&self, mut f: impl FnMut(UVec3, Voxel)) -> EnclosedTiles {
        let mut enclosed = Vec::new();
        self.for_each_run(|origin, height, v| {
            if height == 0 {
                f(origin, v);
                return;
            }
            let size = 1u32 << height;
            let hi = origin + UVec3::splat(size - 1);
            if v.is_interior() && self.tile_is_enclosed(origin, hi) {
                let first = morton_encode(origin);
                enclosed.push((first, first + (1u64 << (3 * u32::from(height)))));
                return;
            }
            for z in origin.z..=hi.z {
                for y in origin.y..=hi.y {
                    for x in origin.x..=hi.x {
                        f(UVec3::new(x, y, z), v);
                    }
                }
            }
        });
        EnclosedTiles(enclosed)
    }

    /// How many voxels [`Self::for_each_voxel_but_enclosed`] visits: what an export of a
    /// static model walks.
    #[must_use]
    pub fn voxels_but_enclosed(&self) -> u64 {
        let enclosed = self.for_each_voxel_but_enclosed(|_, _| {}).voxels();
        self.leaf_count().saturating_sub(enclosed)
    }

    /// Whether the slab beside each of the six faces of the box `lo..=hi` is solid.
    fn tile_is_enclosed(&self, lo: UVec3, hi: UVec3) -> bool {
        (0..3).all(|axis| {
            let (mut below_lo, mut below_hi) = (lo, hi);
            let (mut above_lo, mut above_hi) = (lo, hi);
            if lo[axis] == 0 || hi[axis] + 1 >= self.extent() {
                return false;
            }
            below_lo[axis] = lo[axis] - 1;
            below_hi[axis] = lo[axis] - 1;
            above_lo[axis] = hi[axis] + 1;
            above_hi[axis] = hi[axis] + 1;
            self.box_is_solid(below_lo, below_hi) && self.box_is_solid(above_lo, above_hi)
        })
    }

    /// Whether this octree may hold interior voxels (one was written into it at some point).
    #[must_use]
    pub fn may_have_interior(&self) -> bool {
        self.leaf_attr.interior || self.inner_attr.interior
    }

    /// For each inner slot, the octants of its children that are interior (bit k: octant k;
    /// free slots and tiles 0): what the GPU traversal reads instead of the children's
    /// attributes to leave them unqueued. Empty when the octree has no interior voxels.
    #[must_use]
    pub fn interior_child_masks(&self) -> Vec<u8> {
        if !self.may_have_interior() || self.is_empty() {
            return Vec::new();
        }
        let mut out = vec![0u8; self.inner_mask.len()];
        let mut stack: Vec<(u32, u8)> = vec![(0, 0)];
        while let Some((i, level)) = stack.pop() {
            let iu = i as usize;
            let mask = self.inner_mask[iu];
            if mask == 0 {
                continue;
            }
            let first = self.inner_first[iu] as usize;
            let leaves = level + 1 == self.depth;
            let pool = if leaves {
                &self.leaf_attr
            } else {
                &self.inner_attr
            };
            let mut r = 0;
            for k in 0..8u8 {
                if mask & (1 << k) == 0 {
                    continue;
                }
                let c = first + r;
                r += 1;
                if is_interior_value(pool.color[c], pool.normal[c]) {
                    out[iu] |= 1 << k;
                } else if !leaves {
                    stack.push((c as u32, level + 1));
                }
            }
        }
        out
    }

    /// How many voxels are interior (counted by runs: a tile at once).
    #[must_use]
    pub fn interior_voxels(&self) -> u64 {
        let mut n = 0;
        if self.may_have_interior() {
            self.for_each_run(|_, height, v| {
                if v.is_interior() {
                    n += 1u64 << (3 * u32::from(height));
                }
            });
        }
        n
    }

    /// The voxel nearest to `p` that is not interior: its coordinate and value. Distance
    /// between voxel centres; among equally near voxels the smallest Morton code wins. `None`
    /// when every voxel is interior or the octree is empty.
    ///
    /// Best-first over the octree, skipping interior subtrees; a tile's nearest voxel is the
    /// clamp of `p` into its box (unique), so tiled and voxel-by-voxel octrees answer alike.
    #[must_use]
    pub fn nearest_surface(&self, p: UVec3) -> Option<(UVec3, Voxel)> {
        self.nearest_keyed(p).map(|(_, c, v)| (c, v))
    }

    fn nearest_keyed(&self, p: UVec3) -> Option<(Key, UVec3, Voxel)> {
        if self.is_empty() {
            return None;
        }
        let mut best: Option<(Key, UVec3, Voxel)> = None;
        let mut heap: BinaryHeap<Pending> = BinaryHeap::new();
        let root = self.root();
        heap.push(Reverse((0, root.level, root.index, root.origin.to_array())));
        while let Some(Reverse((bound, level, index, origin))) = heap.pop() {
            if best.as_ref().is_some_and(|b| bound > b.0.0) {
                break;
            }
            let node = NodeRef {
                level,
                index,
                origin: UVec3::from_array(origin),
            };
            let v = self.node_voxel(&node);
            if v.is_interior() {
                continue;
            }
            if self.is_leaf(&node) || self.is_tile(&node) || node.in_tile() {
                let size = self.node_size(level);
                let q = p.clamp(node.origin, node.origin + UVec3::splat(size - 1));
                let key = (dist2(p.as_ivec3(), q.as_ivec3()), morton_encode(q));
                if best.as_ref().is_none_or(|b| key < b.0) {
                    best = Some((key, q, v));
                }
                continue;
            }
            for k in 0..8 {
                if let Some(c) = self.child(&node, k) {
                    let size = self.node_size(c.level);
                    let q = p.clamp(c.origin, c.origin + UVec3::splat(size - 1));
                    heap.push(Reverse((
                        dist2(p.as_ivec3(), q.as_ivec3()),
                        c.level,
                        c.index,
                        c.origin.to_array(),
                    )));
                }
            }
        }
        best
    }

    /// Gives every exposed interior voxel (an empty face neighbour, or on the boundary) the
    /// attributes of its nearest voxel that is not interior, all resolved against the octree as
    /// it is (module docs): for octrees built rather than edited into shape (a crop, a
    /// selection made an object, a baked pose). Returns how many were exposed.
    pub fn settle_interior(&mut self) -> usize {
        self.settle_interior_from(None)
    }

    /// [`Self::settle_interior`] for an octree cut out of `source` (a crop, a selection made an
    /// object): voxel `c` here is `c + offset` there, and the source's voxels the cut left out
    /// count as removed by it (as the edit rule counts them), so a cut face shows what carving
    /// the same cut would.
    pub fn settle_interior_from(&mut self, source: Option<(&Svo, IVec3)>) -> usize {
        let exposed = self.all_exposed_interior();
        if exposed.is_empty() {
            return 0;
        }
        let resolved: Vec<(UVec3, Option<Voxel>)> = exposed
            .iter()
            .map(|&c| {
                let here = self.nearest_keyed(c).map(|(k, _, v)| (k, v));
                let there = source.and_then(|(s, offset)| {
                    let p = c.as_ivec3() + offset;
                    if p.cmplt(IVec3::ZERO).any() {
                        return None;
                    }
                    // Keyed in this octree's coordinates, so ties break alike.
                    s.nearest_keyed(p.as_uvec3()).map(|(_, q, v)| {
                        let q = q.as_ivec3() - offset;
                        let code = if q.cmpge(IVec3::ZERO).all() {
                            morton_encode(q.as_uvec3())
                        } else {
                            u64::MAX
                        };
                        ((dist2(c.as_ivec3(), q), code), v)
                    })
                });
                (c, Some(nearer(here, there)))
            })
            .collect();
        self.apply_sorted(0, 0, UVec3::ZERO, &resolved, None);
        exposed.len()
    }

    /// Every exposed interior voxel, in Morton order.
    fn all_exposed_interior(&self) -> Vec<UVec3> {
        let mut out = Vec::new();
        self.scan_exposed_interior(|p| {
            out.push(p);
            true
        });
        out.sort_unstable_by_key(|&p| morton_encode(p));
        out.dedup();
        out
    }

    /// The first interior voxel (in Morton order of the runs holding them) with an empty face
    /// neighbour or on the octree's boundary: one that breaks the rule that interior voxels
    /// are enclosed. `None` when every interior voxel is enclosed. Visits each interior run's
    /// six neighbouring slabs, so the cost follows the runs' surface, not their volume.
    #[must_use]
    pub fn exposed_interior(&self) -> Option<UVec3> {
        let mut found = None;
        self.scan_exposed_interior(|p| {
            found = Some(p);
            false
        });
        found
    }

    /// Calls `f` with exposed interior voxels (a voxel may come more than once, once per open
    /// face) until it returns `false`.
    fn scan_exposed_interior(&self, mut f: impl FnMut(UVec3) -> bool) {
        if !self.may_have_interior() {
            return;
        }
        let extent = self.extent();
        let mut done = false;
        self.for_each_run(|origin, height, v| {
            if done || !v.is_interior() {
                return;
            }
            let size = 1u32 << height;
            if height > 0 && self.tile_is_enclosed(origin, origin + UVec3::splat(size - 1)) {
                return;
            }
            for axis in 0..3 {
                let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
                for side in [false, true] {
                    for a in 0..size {
                        for b in 0..size {
                            let mut p = origin;
                            p[u] += a;
                            p[w] += b;
                            let mut q = p;
                            if side {
                                p[axis] += size - 1;
                                q[axis] = p[axis] + 1;
                            } else {
                                q[axis] = q[axis].wrapping_sub(1);
                            }
                            if (q[axis] >= extent || self.get(q).is_none()) && !f(p) {
                                done = true;
                                return;
                            }
                        }
                    }
                }
            }
        });
    }

    /// Resolves the interior voxels the edit in `result` exposed (module docs), adding them to
    /// its undo delta and changed box. Nothing to do in an octree without interior voxels.
    pub(super) fn reveal_exposed(&mut self, result: &mut EditResult) {
        if !self.may_have_interior() || result.delta.entries.is_empty() {
            return;
        }
        let extent = self.extent() as i32;
        let inside = |c: IVec3| c.cmpge(IVec3::ZERO).all() && c.cmplt(IVec3::splat(extent)).all();
        let mut exposed: Vec<(u64, UVec3)> = Vec::new();
        // Voxels the edit removed that were not interior: candidates too.
        let mut removed: Vec<(UVec3, Voxel)> = Vec::new();
        for &(p, old) in &result.delta.entries {
            let now = self.get(p);
            match now {
                None => {
                    for f in FACE_NEIGHBOURS {
                        let q = p.as_ivec3() + f;
                        if inside(q) && self.get(q.as_uvec3()).is_some_and(|v| v.is_interior()) {
                            exposed.push((morton_encode(q.as_uvec3()), q.as_uvec3()));
                        }
                    }
                }
                Some(v) if v.is_interior() => {
                    let open = FACE_NEIGHBOURS.iter().any(|&f| {
                        let q = p.as_ivec3() + f;
                        !inside(q) || self.get(q.as_uvec3()).is_none()
                    });
                    if open {
                        exposed.push((morton_encode(p), p));
                    }
                }
                Some(_) => {}
            }
            if let Some(o) = old
                && !o.is_interior()
                && now.is_none_or(|v| v.is_interior())
            {
                removed.push((p, o));
            }
        }
        if exposed.is_empty() {
            return;
        }
        exposed.sort_unstable_by_key(|e| e.0);
        exposed.dedup_by_key(|e| e.0);
        let gone = if removed.is_empty() {
            None
        } else {
            // A lookup structure only (tiles or not, the search answers alike).
            Svo::from_voxels(self.depth, self.has_skin, removed).ok()
        };
        let resolved: Vec<(UVec3, Option<Voxel>)> = exposed
            .iter()
            .map(|&(_, c)| {
                let here = self.nearest_keyed(c).map(|(k, _, v)| (k, v));
                let there = gone
                    .as_ref()
                    .and_then(|g| g.nearest_keyed(c))
                    .map(|(k, _, v)| (k, v));
                (c, Some(nearer(here, there)))
            })
            .collect();
        let mut more = EditResult::default();
        self.apply_sorted(0, 0, UVec3::ZERO, &resolved, Some(&mut more));
        merge_results(result, more);
    }
}

/// Adds `more` (a later edit) to `first`: the union of their changed boxes, and one undo entry
/// per voxel in Morton order, the earlier edit's kept where both list it (it holds the value
/// from before both).
fn merge_results(first: &mut EditResult, more: EditResult) {
    first.changed = match (first.changed, more.changed) {
        (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
        (a, b) => a.or(b),
    };
    if more.delta.entries.is_empty() {
        return;
    }
    let a = std::mem::take(&mut first.delta.entries);
    let b = more.delta.entries;
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < b.len() {
        let ka = a.get(i).map(|e| morton_encode(e.0));
        let kb = b.get(j).map(|e| morton_encode(e.0));
        match (ka, kb) {
            (Some(x), Some(y)) if x == y => {
                out.push(a[i]);
                i += 1;
                j += 1;
            }
            (Some(x), Some(y)) if y < x => {
                out.push(b[j]);
                j += 1;
            }
            (Some(_), _) => {
                out.push(a[i]);
                i += 1;
            }
            (None, _) => {
                out.push(b[j]);
                j += 1;
            }
        }
    }
    first.delta.entries = out;
}

/// Squared distance between two voxel coordinates.
fn dist2(a: IVec3, b: IVec3) -> u64 {
    let d = a.as_i64vec3() - b.as_i64vec3();
    (d.x * d.x + d.y * d.y + d.z * d.z) as u64
}

/// The value of the nearer of two keyed candidates (ties to `a`: their keys never tie, the
/// Morton code settles them), or [`NOTHING_TO_SHOW`] when there is neither: an exposed voxel
/// always has one where an edit exposed it (something was removed), a cut may not.
fn nearer(a: Option<(Key, Voxel)>, b: Option<(Key, Voxel)>) -> Voxel {
    match (a, b) {
        (Some(a), Some(b)) => {
            if b.0 < a.0 {
                b.1
            } else {
                a.1
            }
        }
        (Some(x), None) | (None, Some(x)) => x.1,
        (None, None) => NOTHING_TO_SHOW,
    }
}

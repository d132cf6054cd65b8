//! Tiles (OpenVDB's name): an inner node with no child block standing for a full region of
//! equal voxels. Splitting a tile on the way into an edit, collapsing eight equal children back
//! into one, and turning tiles on or off for a whole octree.
//!
//! A tile holds one attribute record, the value of each of its voxels, in its inner slot. That
//! record is also the tile's level-of-detail average, which is what the leaf-only octree would
//! hold there only when averaging eight copies of the value gives the value back (true of
//! every colour, of encoded normals and of canonical skins); values for which it is not stay
//! as explicit children, so a tiled and a leaf-only octree agree on every node's attributes.

use glam::UVec3;

use super::voxel::merge;
use super::{Attrs, Svo, TILE, Voxel};
#[cfg(test)]
use super::{child_rank, octant_offset};

impl Svo {
    /// This octree storing its full uniform regions as tiles, and keeping them so through
    /// edits. The voxels (and every node's attributes) are unchanged.
    #[must_use]
    pub fn with_tiles(mut self) -> Self {
        self.tiling = true;
        let before = self.tile_count;
        if !self.is_empty() {
            self.collapse_subtree(0, 0);
        }
        if self.tile_count != before {
            // The collapsed children's slots are free: drop them.
            self.repack();
        }
        self
    }

    /// This octree with every tile split into explicit nodes, and no new tiles made by edits
    /// (the voxel-by-voxel reference the tile tests compare against).
    #[must_use]
    pub fn without_tiles(mut self) -> Self {
        self.tiling = false;
        if self.tile_count > 0 {
            self.split_subtree(0, 0);
            self.repack();
        }
        self
    }

    /// Whether edits and builds store full uniform regions as tiles.
    #[must_use]
    pub fn tiling(&self) -> bool {
        self.tiling
    }

    /// Live tiles.
    #[must_use]
    pub fn tile_count(&self) -> u64 {
        self.tile_count
    }

    /// Calls `f(origin, height, voxel)` for every stored run of voxels, in Morton order: each
    /// leaf (height 0) and each tile (a cube of `2^height` voxels a side, all equal to `voxel`,
    /// whose Morton codes are one contiguous range from its origin's). What a file stores.
    pub fn for_each_run(&self, mut f: impl FnMut(UVec3, u8, Voxel)) {
        self.walk_morton(
            |n| self.is_leaf(n) || self.is_tile(n),
            |n| f(n.origin, self.depth - n.level, self.node_voxel(n)),
        );
    }

    /// Makes the empty cube of `2^height` voxels a side at `origin` (aligned to its size, with
    /// `1 <= height <= depth`) one tile of `voxel`, building the path to it; the caller has
    /// checked that nothing is stored there and that `voxel` may be a tile
    /// ([`Self::tile_value_ok`]). Building only: no undo record. The path-by-path reference
    /// that [`Self::from_runs`] is held to.
    #[cfg(test)]
    pub(crate) fn put_tile(&mut self, origin: UVec3, height: u8, voxel: Voxel) {
        let target = self.depth - height;
        // Counted first: a collapse on the way back up takes this tile with seven others.
        let voxels = 1u64 << (3 * u32::from(height));
        self.leaf_count += voxels;
        self.tile_voxels += voxels;
        self.tile_count += 1;
        let v = self.stored(voxel);
        self.put_tile_below(0, 0, UVec3::ZERO, (target, origin), v);
    }

    #[cfg(test)]
    fn put_tile_below(
        &mut self,
        level: u8,
        i: u32,
        at: UVec3,
        (target, origin): (u8, UVec3),
        v: Voxel,
    ) {
        let iu = i as usize;
        if level == target {
            self.inner_mask[iu] = 0;
            self.inner_first[iu] = TILE;
            self.inner_attr.set(iu, &v);
            return;
        }
        let half = self.node_size(level) / 2;
        let local = origin - at;
        let k = u8::from(local.x >= half)
            | u8::from(local.y >= half) << 1
            | u8::from(local.z >= half) << 2;
        let mask = self.inner_mask[iu];
        if mask & (1 << k) == 0 {
            // The child is new: an empty inner node, made a tile or given children below.
            self.rebuild_block(iu, false, mask | (1 << k));
            let slot = (self.inner_first[iu] + child_rank(mask | (1 << k), k)) as usize;
            self.inner_mask[slot] = 0;
            self.inner_first[slot] = 0;
            self.inner_count += 1;
        }
        let mask = self.inner_mask[iu];
        let slot = self.inner_first[iu] + child_rank(mask, k);
        self.put_tile_below(
            level + 1,
            slot,
            at + octant_offset(k, half),
            (target, origin),
            v,
        );
        self.update_inner_attrs(level, i);
        self.collapse(level, i);
    }

    /// A 1024³ octree holding one tile of 512³ voxels at the origin and one voxel beside it
    /// (at x = 512): [`super::MAX_LISTED_VOXELS`] + 1 voxels in two records, for the tests of
    /// the tools that refuse to list that many.
    #[cfg(test)]
    pub(crate) fn over_listing_limit(voxel: Voxel) -> Self {
        Self::from_runs(
            10,
            false,
            [(UVec3::ZERO, 9, voxel), (UVec3::new(512, 0, 0), 0, voxel)],
        )
        .unwrap_or_else(|e| unreachable!("two runs inside the octree: {e}"))
    }

    /// Whether `voxel` may be stored as a tile in this octree: tiling is on, eight copies of it
    /// average to itself, and in a skinned octree it is interior (what every tile this octree
    /// makes holds; see `tiles_value`).
    #[must_use]
    pub fn tile_value_ok(&self, voxel: &Voxel) -> bool {
        self.tiling && self.tiles_value(&self.stored(*voxel))
    }

    /// Whether inner slot `i` is a tile.
    #[inline]
    pub(super) fn is_tile_slot(&self, i: usize) -> bool {
        self.inner_mask[i] == 0 && self.inner_first[i] == TILE
    }

    /// Whether inner slot `i` holds anything: children or a tile.
    #[inline]
    pub(super) fn is_live_inner(&self, i: usize) -> bool {
        self.inner_mask[i] != 0 || self.inner_first[i] == TILE
    }

    /// Whether eight equal voxels `v` may be stored as a tile: tiling is on, they are equal,
    /// and their average is the value itself (so the tile's record is also the average a
    /// leaf-only octree would hold).
    pub(super) fn can_tile(&self, v: &[Voxel; 8]) -> bool {
        self.tiling && v.iter().all(|x| *x == v[0]) && self.tiles_value(&v[0])
    }

    /// Whether a region of voxels `v` may be one tile (tiling aside): eight copies of `v`
    /// average to `v` itself, and a skinned octree tiles only interior voxels. Interior nodes
    /// are never drawn, while the skinning tables and the GPU skin pass place a drawn node by
    /// its stored slot (its corner weights and subtree joints), which a tile's virtual nodes
    /// do not have; so in a skinned model the inside of a solid is stored once per tile,
    /// with the weight set its voxels share, and everything drawn stays explicit.
    pub(super) fn tiles_value(&self, v: &Voxel) -> bool {
        self.skin_allows_tile(v) && self.averages_to_itself(v)
    }

    /// The skin half of [`Self::tiles_value`]: without skin any value, with skin only the
    /// interior (for a caller that has the average already).
    #[inline]
    pub(super) fn skin_allows_tile(&self, v: &Voxel) -> bool {
        !self.has_skin || v.is_interior()
    }

    fn averages_to_itself(&self, v: &Voxel) -> bool {
        let skins = [v.skin; 8];
        let avg = merge(
            std::iter::repeat_n((v.color, v.normal, v.material), 8),
            self.has_skin.then_some(&skins[..]),
        );
        avg == *v
    }

    /// Replaces tile `i` (at `level`) by eight children holding its value: tiles, or leaves
    /// when they are at the leaf level. Returns `true` (for use in a condition).
    pub(super) fn split_tile(&mut self, level: u8, i: u32) -> bool {
        let iu = i as usize;
        debug_assert!(self.is_tile_slot(iu));
        let v = self.inner_attr.get(iu);
        let leaves = level + 1 == self.depth;
        let first = self.alloc_block(leaves, 8);
        let pool = if leaves {
            &mut self.leaf_attr
        } else {
            &mut self.inner_attr
        };
        for j in 0..8 {
            pool.set(first as usize + j, &v);
        }
        if leaves {
            self.tile_voxels -= 8;
        } else {
            for j in 0..8 {
                self.inner_mask[first as usize + j] = 0;
                self.inner_first[first as usize + j] = TILE;
            }
            self.inner_count += 8;
            self.tile_count += 8;
        }
        self.tile_count -= 1;
        self.inner_mask[iu] = 0xff;
        self.inner_first[iu] = first;
        true
    }

    /// Makes inner node `i` (at `level`) a tile when its eight children are equal leaves, or
    /// equal tiles; returns whether it did.
    pub(super) fn collapse(&mut self, level: u8, i: u32) -> bool {
        let iu = i as usize;
        if !self.tiling || self.inner_mask[iu] != 0xff {
            return false;
        }
        let first = self.inner_first[iu] as usize;
        let leaves = level + 1 == self.depth;
        let v = if leaves {
            let mut v = [Voxel::default(); 8];
            for (j, x) in v.iter_mut().enumerate() {
                *x = self.leaf_attr.get(first + j);
            }
            if !self.can_tile(&v) {
                return false;
            }
            v[0]
        } else {
            let v = self.inner_attr.get(first);
            if !(0..8).all(|j| self.is_tile_slot(first + j) && self.inner_attr.get(first + j) == v)
            {
                return false;
            }
            v
        };
        self.free_block(leaves, first as u32, 8);
        if leaves {
            self.tile_voxels += 8;
        } else {
            self.inner_count -= 8;
            self.tile_count -= 8;
        }
        self.tile_count += 1;
        self.inner_mask[iu] = 0;
        self.inner_first[iu] = TILE;
        self.inner_attr.set(iu, &v);
        true
    }

    /// Collapses every full uniform subtree below inner node `i`, bottom-up.
    fn collapse_subtree(&mut self, level: u8, i: u32) {
        let iu = i as usize;
        let mask = self.inner_mask[iu];
        if mask == 0 {
            return;
        }
        if level + 1 < self.depth {
            let first = self.inner_first[iu];
            for j in 0..mask.count_ones() {
                self.collapse_subtree(level + 1, first + j);
            }
        }
        self.collapse(level, i);
    }

    /// Splits every tile below (and at) inner node `i`.
    fn split_subtree(&mut self, level: u8, i: u32) {
        let iu = i as usize;
        if self.is_tile_slot(iu) {
            self.split_tile(level, i);
        }
        let mask = self.inner_mask[iu];
        if mask != 0 && level + 1 < self.depth {
            let first = self.inner_first[iu];
            for j in 0..mask.count_ones() {
                self.split_subtree(level + 1, first + j);
            }
        }
    }

    /// Rebuilds the pools tightly, breadth first (each node's children in one block, in octant
    /// order, as the edits keep them), dropping the slots that edits and collapses freed.
    pub(super) fn repack(&mut self) {
        let n_inner = self.inner_count as usize;
        let n_leaves = (self.leaf_count - self.tile_voxels) as usize;
        let mut mask = Vec::with_capacity(n_inner);
        let mut first = Vec::with_capacity(n_inner);
        let mut inner = Attrs::default();
        let mut leaf = Attrs::default();
        inner.push_empty(n_inner, self.has_skin);
        leaf.push_empty(n_leaves, self.has_skin);
        mask.push(self.inner_mask[0]);
        first.push(self.inner_first[0]);
        copy_attr(&self.inner_attr, 0, &mut inner, 0);
        // Breadth first: `queue[head..]` are the old inner slots, in new-slot order, whose
        // children are not yet copied.
        let mut queue: Vec<(u32, u8)> = vec![(0, 0)];
        let mut head = 0;
        let mut leaf_len = 0usize;
        while head < queue.len() {
            let (old, level) = queue[head];
            let new = head;
            head += 1;
            let m = self.inner_mask[old as usize];
            if m == 0 {
                continue;
            }
            let n = m.count_ones() as usize;
            let old_first = self.inner_first[old as usize] as usize;
            if level + 1 == self.depth {
                for j in 0..n {
                    copy_attr(&self.leaf_attr, old_first + j, &mut leaf, leaf_len + j);
                }
                first[new] = leaf_len as u32;
                leaf_len += n;
            } else {
                first[new] = mask.len() as u32;
                for j in 0..n {
                    let o = old_first + j;
                    copy_attr(&self.inner_attr, o, &mut inner, mask.len());
                    mask.push(self.inner_mask[o]);
                    first.push(self.inner_first[o]);
                    queue.push((o as u32, level + 1));
                }
            }
        }
        debug_assert_eq!(mask.len(), n_inner);
        debug_assert_eq!(leaf_len, n_leaves);
        self.inner_mask = mask;
        self.inner_first = first;
        self.inner_attr = inner;
        self.leaf_attr = leaf;
        self.inner_free = Default::default();
        self.leaf_free = Default::default();
    }
}

/// Copies slot `from` of `a` into slot `to` of `b` (both with or both without skin).
fn copy_attr(a: &Attrs, from: usize, b: &mut Attrs, to: usize) {
    b.set(to, &a.get(from));
}

//! The sparse voxel octree (ASVO paper §2, §4): integer coordinates, depth up to 21, children
//! stored together, leaf attributes in separate arrays, averaged attributes on internal nodes.
//!
//! # Layout
//! Nodes above the leaf level ("inner" nodes) live in one pool as two parallel arrays: an 8-bit
//! child mask and the index of the first child. A node's children are stored together, in octant
//! order, so child `k` of node `i` is `first_child[i] + popcount(mask[i] & ((1 << k) - 1))`.
//! The children of a node at level `depth - 1` are leaves and index the *leaf* pool, which has
//! no mask or child pointer at all: a leaf costs only its attributes. Attributes (colour,
//! normal, material, optional skin) are structure-of-arrays per pool, so a renderer that only
//! needs colours touches only colours.
//!
//! Octant `k` has bit 0 = +x half, bit 1 = +y half, bit 2 = +z half.
//!
//! # Edits
//! [`Svo::edit_region`] visits only the nodes that overlap the edited box, so the cost follows
//! the edit, not the model. When a node's child set changes its child block is moved to a block
//! of the right size (freed blocks are reused by size). Every edit returns an [`UndoDelta`] with
//! the previous value of each voxel it changed; applying it restores the octree exactly
//! ([`Svo`]'s `PartialEq` compares the logical tree: structure, leaf and internal attributes,
//! not pool layout). [`Svo::compact`] rebuilds the pools tightly.
//!
//! # Tiles
//! An octree built with tiles ([`Svo::with_tiles`]) stores a full, uniform region once: an
//! inner node with no child block (mask 0, first child [`TILE`]) whose attributes are those of
//! every voxel below it (OpenVDB's tiles). An edit inside a tile splits only the path to what
//! it edits, the new children starting with the tile's value, and the touched nodes collapse
//! back into tiles when their eight children are equal tiles or leaves. Traversal sees a tile's
//! voxels through virtual nodes ([`NodeRef::in_tile`]); equality, [`Svo::get`],
//! [`Svo::for_each_leaf`] and undo deltas are those of the voxels, so a tiled octree and a
//! leaf-only one holding the same voxels compare equal. See `docs/svo.md`.

mod build;
mod interior;
mod morton;
mod nearest;
mod query;
mod tile;
mod voxel;

#[cfg(test)]
mod interior_tests;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tile_tests;

pub use interior::{EnclosedTiles, FACE_NEIGHBOURS};
pub use morton::{morton_decode, morton_encode};
pub use nearest::NearestSurfaces;
pub use query::{RayHit, front_to_back_order};
pub use voxel::{
    INTERIOR_NORMAL, MAX_SKIN_JOINTS, Skin4, Voxel, decode_normal, encode_normal, is_interior_value,
};

use glam::UVec3;
use serde::{Deserialize, Serialize};

/// Deepest supported octree: 2^21 voxels per axis, so x, y, z fit in a 63-bit Morton code.
pub const MAX_DEPTH: u8 = 21;

/// Most voxels a tool that goes through every voxel of a model one by one will list: 2^27. A
/// model may stand for more ([`Svo::leaf_count`] counts the voxels its tiles stand for: a
/// solid's inside is stored once per tile); such tools refuse it, naming this limit, rather
/// than list it (the voxel tools that rebuild or select the whole model, detail enhancement,
/// rig binding).
pub const MAX_LISTED_VOXELS: u64 = 1 << 27;

/// Why an octree operation was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SvoError {
    /// Depth outside 1..=21.
    #[error("octree depth {0} is out of range (1..={MAX_DEPTH})")]
    BadDepth(u8),
    /// A coordinate outside the octree's extent.
    #[error("voxel coordinate {coord:?} is outside the {extent}³ octree")]
    OutOfBounds {
        /// The coordinate.
        coord: [u32; 3],
        /// Voxels per axis.
        extent: u32,
    },
}

/// Structure-of-arrays attributes of one node pool.
#[derive(Debug, Clone, Default)]
pub(crate) struct Attrs {
    pub(crate) color: Vec<[u8; 4]>,
    pub(crate) normal: Vec<u16>,
    pub(crate) material: Vec<u8>,
    /// Empty unless the octree carries skin weights.
    pub(crate) skin: Vec<Skin4>,
    /// Whether an interior value ([`Voxel::is_interior`]) was ever written here: edits look for
    /// the interior voxels they expose only in octrees that may have some.
    pub(crate) interior: bool,
}

impl Attrs {
    fn len(&self) -> usize {
        self.color.len()
    }

    fn push_empty(&mut self, n: usize, has_skin: bool) {
        let len = self.len() + n;
        self.color.resize(len, [0; 4]);
        self.normal.resize(len, 0);
        self.material.resize(len, 0);
        if has_skin {
            self.skin.resize(len, Skin4::default());
        }
    }

    fn get(&self, i: usize) -> Voxel {
        Voxel {
            color: self.color[i],
            normal: self.normal[i],
            material: self.material[i],
            skin: self.skin.get(i).copied().unwrap_or_default(),
        }
    }

    fn set(&mut self, i: usize, v: &Voxel) {
        self.interior |= v.is_interior();
        self.color[i] = v.color;
        self.normal[i] = v.normal;
        self.material[i] = v.material;
        if let Some(s) = self.skin.get_mut(i) {
            *s = v.skin;
        }
    }

    fn copy_within(&mut self, from: usize, to: usize) {
        self.color[to] = self.color[from];
        self.normal[to] = self.normal[from];
        self.material[to] = self.material[from];
        if !self.skin.is_empty() {
            self.skin[to] = self.skin[from];
        }
    }

    fn bytes_per_entry(&self) -> usize {
        4 + 2 + 1 + if self.skin.is_empty() { 0 } else { 8 }
    }
}

/// A node handle during traversal: its level (0 = root), its index in the pool of its level
/// kind (inner or leaf), and the voxel coordinate of its minimum corner.
///
/// A node strictly inside a tile has no storage of its own: its index is the tile's inner
/// index with [`IN_TILE`] set ([`NodeRef::in_tile`]), whatever its level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeRef {
    /// 0 at the root, `depth` at the leaves.
    pub level: u8,
    /// Index into the inner pool (level < depth) or the leaf pool (level == depth); for a node
    /// inside a tile, the tile's inner index with [`IN_TILE`] set.
    pub index: u32,
    /// Minimum corner in voxel coordinates.
    pub origin: UVec3,
}

impl NodeRef {
    /// Whether this node lies strictly inside a tile (it is then one of the tile's virtual
    /// nodes, and its index names the tile's inner slot, not a slot of its own).
    #[inline]
    #[must_use]
    pub fn in_tile(&self) -> bool {
        self.index & IN_TILE != 0
    }
}

/// `inner_first` of a tile: an inner node with no child block, standing for every voxel below it.
pub const TILE: u32 = u32::MAX;

/// Bit of [`NodeRef::index`] marking a virtual node inside a tile.
pub const IN_TILE: u32 = 1 << 31;

/// The old value of every voxel an edit changed; applying it undoes the edit.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UndoDelta {
    /// `(coordinate, value before the edit)`; `None` means the voxel was empty.
    pub entries: Vec<(UVec3, Option<Voxel>)>,
}

impl UndoDelta {
    /// True when the edit changed nothing.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Bytes this delta holds (for memory-bounded undo history).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.entries.capacity() * size_of::<(UVec3, Option<Voxel>)>()
    }
}

/// What an edit did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EditResult {
    /// Inclusive bounding box of the voxels that changed, or `None` if nothing changed.
    pub changed: Option<(UVec3, UVec3)>,
    /// Restores the previous state when applied with [`Svo::apply_delta`].
    pub delta: UndoDelta,
}

/// Memory used by an octree, by part.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct MemoryStats {
    /// Live internal nodes (tiles included).
    pub inner_nodes: u64,
    /// Solid voxels, those that tiles stand for included.
    pub leaves: u64,
    /// Tiles: internal nodes standing for a full region of equal voxels, stored once.
    #[serde(default)]
    pub tiles: u64,
    /// Voxels those tiles stand for (part of `leaves`, with no leaf storage of their own).
    #[serde(default)]
    pub tile_voxels: u64,
    /// Bytes of internal node structure (mask + child index) and their LOD attributes.
    pub inner_bytes: u64,
    /// Bytes of stored leaf attributes (voxels that tiles stand for cost none).
    pub leaf_bytes: u64,
    /// Allocated slots not holding a live node (freed by edits, reusable).
    pub free_slots: u64,
    /// Everything allocated, live or free.
    pub total_bytes: u64,
    /// `total_bytes / leaves`, voxels of tiles counted (0 for an empty octree).
    pub bytes_per_leaf: f64,
}

/// A sparse voxel octree. See the module documentation for the layout.
#[derive(Clone)]
pub struct Svo {
    depth: u8,
    has_skin: bool,
    inner_mask: Vec<u8>,
    inner_first: Vec<u32>,
    inner_attr: Attrs,
    leaf_attr: Attrs,
    /// Free blocks by size (index = block length 1..=8).
    inner_free: [Vec<u32>; 9],
    leaf_free: [Vec<u32>; 9],
    leaf_count: u64,
    inner_count: u64,
    /// Whether edits and builds store full uniform regions as tiles.
    tiling: bool,
    /// Live tiles (inner nodes standing for a full uniform region).
    tile_count: u64,
    /// Voxels those tiles stand for (counted in `leaf_count` too).
    tile_voxels: u64,
}

/// Number of children before octant `k` (`0..8`) in `mask`: the offset of child `k` in its
/// block.
///
/// A table lookup: the baseline x86-64 target has no `popcnt` instruction, so `count_ones`
/// compiles to a dozen bit operations, and the traversal ranks every child it queues.
#[inline]
#[must_use]
pub fn child_rank(mask: u8, k: u8) -> u32 {
    debug_assert!(k < 8, "octant {k} out of 0..8");
    u32::from(BITS_SET[usize::from(mask & ((1u16 << k) - 1) as u8)])
}

/// `BITS_SET[m]` is `m.count_ones()`.
const BITS_SET: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut m = 0;
    while m < 256 {
        t[m] = (m as u32).count_ones() as u8;
        m += 1;
    }
    t
};

/// Offset of octant `k`'s minimum corner from its parent's, for a child of edge `half`.
#[inline]
#[must_use]
pub fn octant_offset(k: u8, half: u32) -> UVec3 {
    UVec3::new(
        u32::from(k & 1),
        u32::from((k >> 1) & 1),
        u32::from((k >> 2) & 1),
    ) * half
}

impl Svo {
    /// An empty octree of `depth` levels below the root (`2^depth` voxels per axis).
    ///
    /// # Errors
    /// [`SvoError::BadDepth`] unless `1 <= depth <= 21`.
    pub fn new(depth: u8, has_skin: bool) -> Result<Self, SvoError> {
        if depth == 0 || depth > MAX_DEPTH {
            return Err(SvoError::BadDepth(depth));
        }
        let mut svo = Self {
            depth,
            has_skin,
            inner_mask: vec![0],
            inner_first: vec![0],
            inner_attr: Attrs::default(),
            leaf_attr: Attrs::default(),
            inner_free: Default::default(),
            leaf_free: Default::default(),
            leaf_count: 0,
            inner_count: 1,
            tiling: true,
            tile_count: 0,
            tile_voxels: 0,
        };
        svo.inner_attr.push_empty(1, has_skin);
        Ok(svo)
    }

    /// Levels below the root.
    #[must_use]
    pub fn depth(&self) -> u8 {
        self.depth
    }

    /// Voxels per axis (`2^depth`).
    #[must_use]
    pub fn extent(&self) -> u32 {
        1 << self.depth
    }

    /// Whether leaves carry skin weights.
    #[must_use]
    pub fn has_skin(&self) -> bool {
        self.has_skin
    }

    /// Number of solid voxels.
    #[must_use]
    pub fn leaf_count(&self) -> u64 {
        self.leaf_count
    }

    /// Number of live internal nodes (the root included).
    #[must_use]
    pub fn inner_count(&self) -> u64 {
        self.inner_count
    }

    /// True when no voxel is solid.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.leaf_count == 0
    }

    /// Edge length in voxels of a node at `level`.
    #[inline]
    #[must_use]
    pub fn node_size(&self, level: u8) -> u32 {
        1 << (self.depth - level)
    }

    /// The root node.
    #[must_use]
    pub fn root(&self) -> NodeRef {
        NodeRef {
            level: 0,
            index: 0,
            origin: UVec3::ZERO,
        }
    }

    /// Whether `node` is a leaf voxel.
    #[inline]
    #[must_use]
    pub fn is_leaf(&self, node: &NodeRef) -> bool {
        node.level == self.depth
    }

    /// Child mask of a node (0 for leaves, all eight for a tile and the nodes inside one).
    #[inline]
    #[must_use]
    pub fn child_mask(&self, node: &NodeRef) -> u8 {
        if self.is_leaf(node) {
            0
        } else if self.is_tile(node) {
            0xff
        } else {
            self.inner_mask[node.index as usize]
        }
    }

    /// Whether `node` is a tile or lies inside one: an inner node standing for a full region of
    /// voxels all equal to [`Self::node_voxel`].
    #[inline]
    #[must_use]
    pub fn is_tile(&self, node: &NodeRef) -> bool {
        !self.is_leaf(node) && (node.in_tile() || self.is_tile_slot(node.index as usize))
    }

    /// Child `k` of `node`, if present.
    #[inline]
    #[must_use]
    pub fn child(&self, node: &NodeRef, k: u8) -> Option<NodeRef> {
        if self.is_leaf(node) {
            return None;
        }
        let half = self.node_size(node.level) / 2;
        let origin = node.origin + octant_offset(k, half);
        let level = node.level + 1;
        if self.is_tile(node) {
            return Some(NodeRef {
                level,
                index: node.index | IN_TILE,
                origin,
            });
        }
        let mask = self.inner_mask[node.index as usize];
        if mask & (1 << k) == 0 {
            return None;
        }
        Some(NodeRef {
            level,
            index: self.inner_first[node.index as usize] + child_rank(mask, k),
            origin,
        })
    }

    /// The pool and slot holding `node`'s attributes: its own, or its tile's.
    #[inline]
    fn attrs_of(&self, node: &NodeRef) -> (&Attrs, usize) {
        if node.in_tile() {
            (&self.inner_attr, (node.index & !IN_TILE) as usize)
        } else if self.is_leaf(node) {
            (&self.leaf_attr, node.index as usize)
        } else {
            (&self.inner_attr, node.index as usize)
        }
    }

    /// Attributes of a node: a leaf's own, an internal node's average over its subtree, or, for
    /// a tile and the nodes inside it, the tile's value (the average of equal voxels).
    #[inline]
    #[must_use]
    pub fn node_voxel(&self, node: &NodeRef) -> Voxel {
        let (a, i) = self.attrs_of(node);
        a.get(i)
    }

    /// A node's colour (sRGB RGBA8) and octahedral normal, as [`Self::node_voxel`] gives them,
    /// without reading its other attributes (what a renderer's resolve needs).
    #[inline]
    #[must_use]
    pub fn node_color_and_normal(&self, node: &NodeRef) -> ([u8; 4], u16) {
        let (a, i) = self.attrs_of(node);
        (a.color[i], a.normal[i])
    }

    /// A node's skin weights alone, as [`Self::node_voxel`] gives them (the default skin for
    /// an octree without skin).
    #[inline]
    #[must_use]
    pub fn node_skin(&self, node: &NodeRef) -> Skin4 {
        let (a, i) = self.attrs_of(node);
        a.skin.get(i).copied().unwrap_or_default()
    }

    fn check(&self, c: UVec3) -> Result<(), SvoError> {
        if c.max_element() >= self.extent() {
            return Err(SvoError::OutOfBounds {
                coord: c.to_array(),
                extent: self.extent(),
            });
        }
        Ok(())
    }

    /// The voxel at `coord`, or `None` when empty or outside.
    #[must_use]
    pub fn get(&self, coord: UVec3) -> Option<Voxel> {
        if self.check(coord).is_err() {
            return None;
        }
        let mut node = self.root();
        while !self.is_leaf(&node) {
            if self.is_tile(&node) {
                return Some(self.node_voxel(&node));
            }
            let half = self.node_size(node.level) / 2;
            let local = coord - node.origin;
            let k = u8::from(local.x >= half)
                | u8::from(local.y >= half) << 1
                | u8::from(local.z >= half) << 2;
            node = self.child(&node, k)?;
        }
        Some(self.node_voxel(&node))
    }

    /// Sets one voxel; returns its previous value.
    ///
    /// # Errors
    /// [`SvoError::OutOfBounds`].
    pub fn set(&mut self, coord: UVec3, voxel: Voxel) -> Result<Option<Voxel>, SvoError> {
        let r = self.edit_region(coord, coord, |_, _| Some(voxel))?;
        Ok(r.delta
            .entries
            .iter()
            .find(|e| e.0 == coord)
            .map_or(Some(voxel), |e| e.1))
    }

    /// Removes one voxel; returns its previous value.
    ///
    /// # Errors
    /// [`SvoError::OutOfBounds`].
    pub fn remove(&mut self, coord: UVec3) -> Result<Option<Voxel>, SvoError> {
        let r = self.edit_existing(coord, coord, |_, _| None)?;
        Ok(r.delta
            .entries
            .iter()
            .find(|e| e.0 == coord)
            .and_then(|e| e.1))
    }

    /// Recolours one voxel if it is solid; returns whether it was.
    ///
    /// # Errors
    /// [`SvoError::OutOfBounds`].
    pub fn paint(&mut self, coord: UVec3, color: [u8; 4]) -> Result<bool, SvoError> {
        let mut found = false;
        self.edit_existing(coord, coord, |_, v| {
            found = true;
            Some(Voxel { color, ..v })
        })?;
        Ok(found)
    }

    /// Edits every voxel in the inclusive box `lo..=hi` (clamped to the octree):
    /// `f(coord, old) -> new`. Visits only nodes overlapping the box.
    ///
    /// # Errors
    /// [`SvoError::OutOfBounds`] when the box misses the octree entirely.
    pub fn edit_region(
        &mut self,
        lo: UVec3,
        hi: UVec3,
        mut f: impl FnMut(UVec3, Option<Voxel>) -> Option<Voxel>,
    ) -> Result<EditResult, SvoError> {
        self.edit_impl(lo, hi, true, &mut |c, old| f(c, old), EditResult::default())
    }

    /// [`Svo::edit_region`] for a caller that knows about how many voxels the edit changes and
    /// creates: room for `changes` undo entries and `new_leaves` leaves is reserved up front,
    /// so a large edit does not grow (and copy) them step by step. Same result.
    pub(crate) fn edit_region_reserving(
        &mut self,
        lo: UVec3,
        hi: UVec3,
        (changes, new_leaves): (usize, usize),
        mut f: impl FnMut(UVec3, Option<Voxel>) -> Option<Voxel>,
    ) -> Result<EditResult, SvoError> {
        // With tiles, a fill of one value mostly makes tiles (in a skinned octree only an
        // interior fill does): reserving a leaf per voxel would keep memory never used.
        let new_leaves = if self.tiling && !self.has_skin {
            0
        } else {
            new_leaves
        };
        let a = &mut self.leaf_attr;
        a.color.reserve(new_leaves);
        a.normal.reserve(new_leaves);
        a.material.reserve(new_leaves);
        if self.has_skin {
            a.skin.reserve(new_leaves);
        }
        let mut result = EditResult::default();
        result.delta.entries.reserve(changes);
        self.edit_impl(lo, hi, true, &mut |c, old| f(c, old), result)
    }

    /// Like [`Svo::edit_region`] but visits only voxels that are already solid (paint, remove,
    /// smooth): `f(coord, old) -> new`, `None` removes.
    ///
    /// # Errors
    /// [`SvoError::OutOfBounds`] when the box misses the octree entirely.
    pub fn edit_existing(
        &mut self,
        lo: UVec3,
        hi: UVec3,
        mut f: impl FnMut(UVec3, Voxel) -> Option<Voxel>,
    ) -> Result<EditResult, SvoError> {
        self.edit_impl(
            lo,
            hi,
            false,
            &mut |c, old| old.and_then(|v| f(c, v)),
            EditResult::default(),
        )
    }

    /// Applies an undo delta (entries outside the octree are skipped; for a coordinate listed
    /// twice the later entry wins); returns the delta that redoes what it undid. One pass over
    /// the touched paths ([`Svo::apply_changes`]), so undo costs what the edit did.
    pub fn apply_delta(&mut self, delta: &UndoDelta) -> UndoDelta {
        let extent = self.extent();
        // An edit's own delta is already what `apply_changes` would sort it into (inside,
        // Morton order, one entry per voxel, skin stored): apply it in place, without the
        // sorted copies.
        if !delta.entries.is_empty() && self.is_sorted_unique_stored(&delta.entries) {
            let mut result = EditResult::default();
            self.apply_sorted(0, 0, UVec3::ZERO, &delta.entries, Some(&mut result));
            return result.delta;
        }
        let entries = delta
            .entries
            .iter()
            .copied()
            .filter(|e| e.0.max_element() < extent);
        self.apply_changes_exact(entries)
            .map(|r| r.delta)
            .unwrap_or_default()
    }

    /// Whether `entries` are inside the octree, in strictly increasing Morton order, and hold
    /// only skin the octree stores: exactly what `apply_changes` hands `apply_sorted`.
    fn is_sorted_unique_stored(&self, entries: &[(UVec3, Option<Voxel>)]) -> bool {
        let extent = self.extent();
        let mut last = None;
        entries.iter().all(|(c, v)| {
            if c.max_element() >= extent
                || v.is_some_and(|v| !self.has_skin && v.skin != Skin4::default())
            {
                return false;
            }
            let code = morton_encode(*c);
            let ok = last.is_none_or(|l| l < code);
            last = Some(code);
            ok
        })
    }

    fn edit_impl(
        &mut self,
        lo: UVec3,
        hi: UVec3,
        create: bool,
        f: &mut dyn FnMut(UVec3, Option<Voxel>) -> Option<Voxel>,
        mut result: EditResult,
    ) -> Result<EditResult, SvoError> {
        let max = UVec3::splat(self.extent() - 1);
        if lo.cmpgt(max).any() || lo.cmpgt(hi).any() {
            return Err(SvoError::OutOfBounds {
                coord: lo.to_array(),
                extent: self.extent(),
            });
        }
        let hi = hi.min(max);
        // A value carrying the interior mark's normal is the mark (a recolour of an interior
        // voxel, `Voxel { color, ..old }`, leaves it interior: it has no colour to show).
        let mut marked =
            |c: UVec3, old: Option<Voxel>| f(c, old).map(|v| Self::still_interior(v, old));
        let mut ctx = EditCtx {
            lo,
            hi,
            create,
            f: &mut marked,
            result: &mut result,
            uniform: [None; MAX_DEPTH as usize + 1],
        };
        self.edit_inner(0, 0, UVec3::ZERO, &mut ctx);
        self.reveal_exposed(&mut result);
        Ok(result)
    }

    /// `v` written over `old`, or the interior mark when `v` is derived from it: it carries the
    /// mark's normal code, or it replaces an interior voxel keeping its (absent) colour, as a
    /// normal re-estimated or turned by a tool does. An interior voxel stays interior, keeping
    /// the skin written.
    #[inline]
    fn still_interior(v: Voxel, old: Option<Voxel>) -> Voxel {
        let from_old = old.is_some_and(|o| o.is_interior() && v.color == o.color);
        if v.normal == INTERIOR_NORMAL || from_old {
            Voxel {
                skin: v.skin,
                ..Voxel::INTERIOR
            }
        } else {
            v
        }
    }

    /// Strips skin weights the octree does not store, so comparisons see what is stored.
    #[inline]
    fn stored(&self, v: Voxel) -> Voxel {
        if self.has_skin {
            v
        } else {
            Voxel {
                skin: Skin4::default(),
                ..v
            }
        }
    }

    /// Octants of the node at `origin` (children of edge `half`) that overlap `lo..=hi`: per
    /// axis, which of the two halves overlap, then the octants whose halves all do.
    #[inline]
    fn overlapping(origin: UVec3, half: u32, lo: UVec3, hi: UVec3) -> u8 {
        // Octants in the low / high half along x, y, z (octant bit 0 = x, 1 = y, 2 = z).
        const HALVES: [[u8; 2]; 3] = [[0x55, 0xaa], [0x33, 0xcc], [0x0f, 0xf0]];
        let mut touched = 0xff;
        for a in 0..3 {
            let o = origin[a];
            let mut axis = 0;
            if o <= hi[a] && o + half > lo[a] {
                axis |= HALVES[a][0];
            }
            if o + half <= hi[a] && o + 2 * half > lo[a] {
                axis |= HALVES[a][1];
            }
            touched &= axis;
        }
        touched
    }

    /// Gives node `iu` the child set `mask` (freeing its block when empty).
    fn set_child_mask(&mut self, iu: usize, child_is_leaf: bool, mask: u8) {
        let old = self.inner_mask[iu];
        if mask == old {
            return;
        }
        if mask == 0 {
            self.free_block(child_is_leaf, self.inner_first[iu], old.count_ones());
            self.inner_mask[iu] = 0;
            self.inner_first[iu] = 0;
        } else {
            self.rebuild_block(iu, child_is_leaf, mask);
        }
    }

    /// Edits the subtree of inner node `i`; returns whether anything in it changed.
    ///
    /// The callback runs once per voxel of the box, in Morton order. Children that do not exist
    /// yet are built bottom-up as the callback creates voxels in them
    /// ([`Self::build_missing`]), and only where it does: a brush's empty corners cost callback
    /// calls, not nodes.
    fn edit_inner(&mut self, level: u8, i: u32, origin: UVec3, ctx: &mut EditCtx<'_, '_>) -> bool {
        let half = self.node_size(level) / 2;
        let split = self.is_tile_slot(i as usize)
            && Self::overlapping(origin, half, ctx.lo, ctx.hi) != 0
            && self.split_tile(level, i);
        let changed = self.edit_node(level, i, origin, ctx);
        if split || changed {
            self.collapse(level, i);
        }
        changed
    }

    /// [`Self::edit_inner`] on a node that is not a tile.
    fn edit_node(&mut self, level: u8, i: u32, origin: UVec3, ctx: &mut EditCtx<'_, '_>) -> bool {
        let iu = i as usize;
        let half = self.node_size(level) / 2;
        let child_is_leaf = level + 1 == self.depth;
        let old_mask = self.inner_mask[iu];
        let mut touched = Self::overlapping(origin, half, ctx.lo, ctx.hi);
        if !ctx.create {
            touched &= old_mask;
        }
        if touched == 0 {
            return false;
        }
        let old_first = self.inner_first[iu];
        let mut changed = false;
        let mut present = old_mask & !touched;
        if child_is_leaf {
            let mut new_values = [None; 8];
            for k in 0..8u8 {
                if touched & (1 << k) == 0 {
                    continue;
                }
                let c_origin = origin + octant_offset(k, half);
                let old = (old_mask & (1 << k) != 0).then(|| {
                    self.leaf_attr
                        .get((old_first + child_rank(old_mask, k)) as usize)
                });
                let new = (ctx.f)(c_origin, old).map(|v| self.stored(v));
                if new != old {
                    ctx.record(c_origin, old);
                    changed = true;
                    match (old.is_some(), new.is_some()) {
                        (false, true) => self.leaf_count += 1,
                        (true, false) => self.leaf_count -= 1,
                        _ => {}
                    }
                }
                if new.is_some() {
                    present |= 1 << k;
                }
                new_values[k as usize] = new;
            }
            if !changed {
                return false;
            }
            self.set_child_mask(iu, true, present);
            let first = self.inner_first[iu];
            for k in 0..8u8 {
                if let Some(v) = new_values[k as usize] {
                    self.leaf_attr
                        .set((first + child_rank(present, k)) as usize, &v);
                }
            }
        } else {
            // Missing children are built bottom-up where the callback creates a voxel, and
            // moved into this node's block once its new child set is known.
            let mut built: [Option<Built>; 8] = [None; 8];
            for k in 0..8u8 {
                if touched & (1 << k) == 0 {
                    continue;
                }
                let c_origin = origin + octant_offset(k, half);
                if old_mask & (1 << k) != 0 {
                    let slot = old_first + child_rank(old_mask, k);
                    changed |= self.edit_inner(level + 1, slot, c_origin, ctx);
                    if self.is_live_inner(slot as usize) {
                        present |= 1 << k;
                    } else {
                        self.inner_count -= 1;
                    }
                } else if let Some(b) = self.build_missing(level + 1, c_origin, ctx) {
                    built[k as usize] = Some(b);
                    present |= 1 << k;
                }
            }
            let any_built = built.iter().any(Option::is_some);
            if !changed && !any_built {
                return false;
            }
            self.set_child_mask(iu, false, present);
            let first = self.inner_first[iu];
            for k in 0..8u8 {
                if let Some(b) = built[k as usize] {
                    let slot = (first + child_rank(present, k)) as usize;
                    self.inner_mask[slot] = b.mask;
                    self.inner_first[slot] = b.first;
                    self.inner_attr.set(slot, &b.attrs);
                    self.inner_count += 1;
                }
            }
            changed = true;
        }
        if self.inner_mask[iu] != 0 {
            self.update_inner_attrs(level, i);
        }
        changed
    }

    /// Builds the box's part of a subtree that does not exist yet (every old value is empty),
    /// bottom-up: the callback runs over it in Morton order, each node's children are written
    /// into one block once they are known, and the node itself (mask, first child, averaged
    /// attributes) is returned for the caller to place; `None` when the callback created
    /// nothing there. Nodes whose eight children are equal take their average from
    /// `ctx.uniform` (the average is a function of the children alone), so the inside of a
    /// solid costs one merge per level.
    fn build_missing(
        &mut self,
        level: u8,
        origin: UVec3,
        ctx: &mut EditCtx<'_, '_>,
    ) -> Option<Built> {
        let half = self.node_size(level) / 2;
        let touched = Self::overlapping(origin, half, ctx.lo, ctx.hi);
        let mut mask = 0u8;
        if level + 1 == self.depth {
            let mut leaves = [Voxel::default(); 8];
            let mut n = 0;
            for k in 0..8u8 {
                if touched & (1 << k) == 0 {
                    continue;
                }
                let c_origin = origin + octant_offset(k, half);
                if let Some(v) = (ctx.f)(c_origin, None) {
                    ctx.record(c_origin, None);
                    leaves[n] = self.stored(v);
                    n += 1;
                    mask |= 1 << k;
                }
            }
            if n == 0 {
                return None;
            }
            // Eight equal voxels are a tile when their average (memoised for a uniform node, as
            // below) is the value itself: `Svo::can_tile` without a fresh merge per node.
            if n == 8
                && self.tiling
                && leaves.iter().all(|v| *v == leaves[0])
                && self.skin_allows_tile(&leaves[0])
                && self.merge_built(level, &leaves, ctx) == leaves[0]
            {
                self.leaf_count += 8;
                self.tile_count += 1;
                self.tile_voxels += 8;
                return Some(Built {
                    mask: 0,
                    first: TILE,
                    attrs: leaves[0],
                });
            }
            let first = self.alloc_block(true, n as u32);
            for (j, v) in leaves[..n].iter().enumerate() {
                self.leaf_attr.set(first as usize + j, v);
            }
            self.leaf_count += n as u64;
            let attrs = self.merge_built(level, &leaves[..n], ctx);
            return Some(Built { mask, first, attrs });
        }
        let mut children = [Built::default(); 8];
        let mut n = 0;
        for k in 0..8u8 {
            if touched & (1 << k) == 0 {
                continue;
            }
            let c_origin = origin + octant_offset(k, half);
            if let Some(b) = self.build_missing(level + 1, c_origin, ctx) {
                children[n] = b;
                n += 1;
                mask |= 1 << k;
            }
        }
        if n == 0 {
            return None;
        }
        if n == 8
            && self.tiling
            && children
                .iter()
                .all(|b| b.first == TILE && b.mask == 0 && b.attrs == children[0].attrs)
        {
            // Eight equal tiles are one: their own count gives way to the parent's.
            self.tile_count -= 7;
            return Some(Built {
                mask: 0,
                first: TILE,
                attrs: children[0].attrs,
            });
        }
        let first = self.alloc_block(false, n as u32);
        let mut attrs = [Voxel::default(); 8];
        for (j, b) in children[..n].iter().enumerate() {
            let slot = first as usize + j;
            self.inner_mask[slot] = b.mask;
            self.inner_first[slot] = b.first;
            self.inner_attr.set(slot, &b.attrs);
            attrs[j] = b.attrs;
        }
        self.inner_count += n as u64;
        let attrs = self.merge_built(level, &attrs[..n], ctx);
        Some(Built { mask, first, attrs })
    }

    /// The averaged attributes of a node at `level` with `children` (as stored), what
    /// [`Self::update_inner_attrs`] would compute from its block.
    fn merge_built(&self, level: u8, children: &[Voxel], ctx: &mut EditCtx<'_, '_>) -> Voxel {
        let merge = || {
            let mut skins = [Skin4::default(); 8];
            for (s, v) in skins.iter_mut().zip(children) {
                *s = v.skin;
            }
            voxel::merge(
                children.iter().map(|v| (v.color, v.normal, v.material)),
                self.has_skin.then_some(&skins[..children.len()]),
            )
        };
        if children.len() < 8 || children.iter().any(|v| *v != children[0]) {
            return merge();
        }
        let memo = &mut ctx.uniform[level as usize];
        match memo {
            Some((child, merged)) if *child == children[0] => *merged,
            _ => {
                let merged = merge();
                *memo = Some((children[0], merged));
                merged
            }
        }
    }

    /// Sets or removes many voxels in one pass: `changes` holds `(coordinate, new value)`,
    /// `None` removing. Only the paths to those voxels are visited and each internal node on
    /// them is re-averaged once, so the cost follows the number of changes, not the box they
    /// span (an incremental re-enhancement writes its few changed fragments this way). Later
    /// duplicates win. Returns the changed box and the undo delta (in Morton order).
    ///
    /// # Errors
    /// [`SvoError::OutOfBounds`] for the first coordinate outside; nothing is changed then.
    pub fn apply_changes(
        &mut self,
        changes: impl IntoIterator<Item = (UVec3, Option<Voxel>)>,
    ) -> Result<EditResult, SvoError> {
        let interior = self.may_have_interior();
        let changes: Vec<(UVec3, Option<Voxel>)> = changes
            .into_iter()
            .map(|(c, v)| {
                let v = v.map(|v| {
                    // Only a colourless value can be derived from an interior voxel.
                    let old = (interior && v.color == [0; 4])
                        .then(|| self.get(c))
                        .flatten();
                    Self::still_interior(v, old)
                });
                (c, v)
            })
            .collect();
        let mut result = self.apply_changes_exact(changes)?;
        self.reveal_exposed(&mut result);
        Ok(result)
    }

    /// [`Svo::apply_changes`] without resolving what it exposes: undo, which restores states
    /// exactly.
    fn apply_changes_exact(
        &mut self,
        changes: impl IntoIterator<Item = (UVec3, Option<Voxel>)>,
    ) -> Result<EditResult, SvoError> {
        let mut coded: Vec<(u64, UVec3, Option<Voxel>)> = Vec::new();
        for (c, v) in changes {
            self.check(c)?;
            coded.push((morton_encode(c), c, v.map(|v| self.stored(v))));
        }
        // Stable: among duplicates the input order survives, and the last one is kept.
        coded.sort_by_key(|e| e.0);
        let mut unique: Vec<(UVec3, Option<Voxel>)> = Vec::with_capacity(coded.len());
        let mut last_code = None;
        for (code, c, v) in coded {
            if last_code == Some(code) {
                if let Some(l) = unique.last_mut() {
                    *l = (c, v);
                }
            } else {
                unique.push((c, v));
                last_code = Some(code);
            }
        }
        let mut result = EditResult::default();
        if !unique.is_empty() {
            self.apply_sorted(0, 0, UVec3::ZERO, &unique, Some(&mut result));
        }
        Ok(result)
    }

    /// Applies `items` (Morton-sorted, unique, all inside the node, skin already stripped) to
    /// the subtree of inner node `i`; returns whether anything changed. Records undo entries
    /// into `record` when given.
    fn apply_sorted(
        &mut self,
        level: u8,
        i: u32,
        origin: UVec3,
        items: &[(UVec3, Option<Voxel>)],
        record: Option<&mut EditResult>,
    ) -> bool {
        let split = !items.is_empty() && self.is_tile_slot(i as usize) && self.split_tile(level, i);
        let changed = self.apply_sorted_node(level, i, origin, items, record);
        if split || changed {
            self.collapse(level, i);
        }
        changed
    }

    /// [`Self::apply_sorted`] on a node that is not a tile.
    fn apply_sorted_node(
        &mut self,
        level: u8,
        i: u32,
        origin: UVec3,
        items: &[(UVec3, Option<Voxel>)],
        mut record: Option<&mut EditResult>,
    ) -> bool {
        let iu = i as usize;
        let half = self.node_size(level) / 2;
        let shift = self.depth - level - 1;
        let child_is_leaf = level + 1 == self.depth;
        let octant = |c: UVec3| -> u8 {
            let b = (c >> u32::from(shift)) & UVec3::ONE;
            (b.x | b.y << 1 | b.z << 2) as u8
        };
        // Items are in Morton order, so each octant's items are one contiguous run.
        let mut runs: [(usize, usize); 8] = [(0, 0); 8];
        let mut start = 0;
        while start < items.len() {
            let k = octant(items[start].0);
            let mut end = start + 1;
            while end < items.len() && octant(items[end].0) == k {
                end += 1;
            }
            runs[k as usize] = (start, end);
            start = end;
        }
        let old_mask = self.inner_mask[iu];
        let old_first = self.inner_first[iu];
        let mut changed = false;
        if child_is_leaf {
            let mut present = old_mask;
            let mut new_values = [None; 8];
            for k in 0..8u8 {
                let (s, e) = runs[k as usize];
                if s == e {
                    continue;
                }
                let (c, new) = items[e - 1];
                let old = (old_mask & (1 << k) != 0).then(|| {
                    self.leaf_attr
                        .get((old_first + child_rank(old_mask, k)) as usize)
                });
                if new != old {
                    if let Some(r) = record.as_deref_mut() {
                        record_change(r, c, old);
                    }
                    changed = true;
                    match (old.is_some(), new.is_some()) {
                        (false, true) => self.leaf_count += 1,
                        (true, false) => self.leaf_count -= 1,
                        _ => {}
                    }
                }
                if new.is_some() {
                    present |= 1 << k;
                } else {
                    present &= !(1 << k);
                }
                new_values[k as usize] = new;
            }
            if !changed {
                return false;
            }
            self.set_child_mask(iu, true, present);
            let first = self.inner_first[iu];
            for k in 0..8u8 {
                if let Some(v) = new_values[k as usize] {
                    self.leaf_attr
                        .set((first + child_rank(present, k)) as usize, &v);
                }
            }
        } else {
            // Missing children that will hold a voxel are created before descending.
            let mut add = 0u8;
            for k in 0..8u8 {
                let (s, e) = runs[k as usize];
                if s < e && old_mask & (1 << k) == 0 && items[s..e].iter().any(|x| x.1.is_some()) {
                    add |= 1 << k;
                }
            }
            if add != 0 {
                self.set_child_mask(iu, false, old_mask | add);
                let first = self.inner_first[iu];
                for k in 0..8u8 {
                    if add & (1 << k) != 0 {
                        let slot = (first + child_rank(old_mask | add, k)) as usize;
                        self.inner_mask[slot] = 0;
                        self.inner_first[slot] = 0;
                        self.inner_count += 1;
                    }
                }
                changed = true;
            }
            let mask = old_mask | add;
            let first = self.inner_first[iu];
            let mut present = mask;
            for k in 0..8u8 {
                let (s, e) = runs[k as usize];
                if s == e || mask & (1 << k) == 0 {
                    continue;
                }
                let slot = first + child_rank(mask, k);
                let c_origin = origin + octant_offset(k, half);
                changed |= self.apply_sorted(
                    level + 1,
                    slot,
                    c_origin,
                    &items[s..e],
                    record.as_deref_mut(),
                );
                if !self.is_live_inner(slot as usize) {
                    present &= !(1 << k);
                    self.inner_count -= 1;
                }
            }
            if !changed {
                return false;
            }
            self.set_child_mask(iu, false, present);
        }
        if self.inner_mask[iu] != 0 {
            self.update_inner_attrs(level, i);
        }
        changed
    }

    /// The voxels this octree stands for when they are more than [`MAX_LISTED_VOXELS`], which
    /// a tool that lists voxels one by one then refuses; `None` otherwise.
    #[must_use]
    pub fn too_many_to_list(&self) -> Option<u64> {
        let voxels = self.leaf_count();
        (voxels > MAX_LISTED_VOXELS).then_some(voxels)
    }

    /// Solid voxels in the inclusive box `lo..=hi`, a tile counting the part of its cube in the
    /// box at once: the cost follows the stored nodes the box overlaps, not its volume (what a
    /// tool checks before listing them).
    #[must_use]
    pub fn voxels_in(&self, lo: UVec3, hi: UVec3) -> u64 {
        let hi = hi.min(UVec3::splat(self.extent() - 1));
        if lo.cmpgt(hi).any() || self.is_empty() {
            return 0;
        }
        let mut n = 0u64;
        let mut stack = vec![self.root()];
        while let Some(node) = stack.pop() {
            if self.is_leaf(&node) {
                n += 1;
                continue;
            }
            let size = self.node_size(node.level);
            if self.is_tile(&node) {
                let a = node.origin.max(lo);
                let b = (node.origin + UVec3::splat(size - 1)).min(hi);
                n += (b - a + UVec3::ONE).as_u64vec3().element_product();
                continue;
            }
            let touched = Self::overlapping(node.origin, size / 2, lo, hi) & self.child_mask(&node);
            stack.extend((0..8u8).filter_map(|k| {
                (touched & (1 << k) != 0)
                    .then(|| self.child(&node, k))
                    .flatten()
            }));
        }
        n
    }

    /// Calls `f(coord, voxel)` for every solid voxel in the inclusive box `lo..=hi`, in Morton
    /// order, visiting only nodes that overlap the box.
    pub fn for_each_leaf_in(&self, lo: UVec3, hi: UVec3, mut f: impl FnMut(UVec3, Voxel)) {
        if lo.cmpgt(hi).any() || self.is_empty() {
            return;
        }
        self.leaves_in(&self.root(), lo, hi, &mut f);
    }

    fn leaves_in(&self, node: &NodeRef, lo: UVec3, hi: UVec3, f: &mut impl FnMut(UVec3, Voxel)) {
        if self.is_leaf(node) {
            f(node.origin, self.node_voxel(node));
            return;
        }
        let half = self.node_size(node.level) / 2;
        let touched = Self::overlapping(node.origin, half, lo, hi) & self.child_mask(node);
        for k in 0..8u8 {
            if touched & (1 << k) != 0
                && let Some(child) = self.child(node, k)
            {
                self.leaves_in(&child, lo, hi, f);
            }
        }
    }

    /// Moves node `iu`'s children into a block laid out for `new_mask`. Children in both masks
    /// keep their data; new ones are left uninitialised for the caller to fill.
    fn rebuild_block(&mut self, iu: usize, child_is_leaf: bool, new_mask: u8) {
        let old_mask = self.inner_mask[iu];
        let old_first = self.inner_first[iu];
        let new_first = self.alloc_block(child_is_leaf, new_mask.count_ones());
        for k in 0..8u8 {
            if old_mask & new_mask & (1 << k) != 0 {
                let from = (old_first + child_rank(old_mask, k)) as usize;
                let to = (new_first + child_rank(new_mask, k)) as usize;
                if child_is_leaf {
                    self.leaf_attr.copy_within(from, to);
                } else {
                    self.inner_mask[to] = self.inner_mask[from];
                    self.inner_first[to] = self.inner_first[from];
                    self.inner_attr.copy_within(from, to);
                }
            }
        }
        if old_mask != 0 {
            self.free_block(child_is_leaf, old_first, old_mask.count_ones());
        }
        self.inner_mask[iu] = new_mask;
        self.inner_first[iu] = new_first;
    }

    fn alloc_block(&mut self, leaf: bool, n: u32) -> u32 {
        let free = if leaf {
            &mut self.leaf_free[n as usize]
        } else {
            &mut self.inner_free[n as usize]
        };
        if let Some(first) = free.pop() {
            return first;
        }
        if leaf {
            let first = self.leaf_attr.len() as u32;
            self.leaf_attr.push_empty(n as usize, self.has_skin);
            first
        } else {
            let first = self.inner_mask.len() as u32;
            self.inner_mask
                .resize(self.inner_mask.len() + n as usize, 0);
            self.inner_first
                .resize(self.inner_first.len() + n as usize, 0);
            self.inner_attr.push_empty(n as usize, self.has_skin);
            first
        }
    }

    fn free_block(&mut self, leaf: bool, first: u32, n: u32) {
        if n == 0 {
            return;
        }
        if leaf {
            self.leaf_free[n as usize].push(first);
        } else {
            self.inner_free[n as usize].push(first);
        }
    }

    /// Recomputes an internal node's LOD attributes from its children.
    fn update_inner_attrs(&mut self, level: u8, i: u32) {
        let iu = i as usize;
        let mask = self.inner_mask[iu];
        let first = self.inner_first[iu] as usize;
        let n = mask.count_ones() as usize;
        let pool = if level + 1 == self.depth {
            &self.leaf_attr
        } else {
            &self.inner_attr
        };
        let merged = voxel::merge(
            (first..first + n).map(|c| (pool.color[c], pool.normal[c], pool.material[c])),
            pool.skin.get(first..first + n),
        );
        self.inner_attr.set(iu, &merged);
    }

    /// Calls `f(coord, voxel)` for every solid voxel, in Morton order.
    pub fn for_each_leaf(&self, mut f: impl FnMut(UVec3, Voxel)) {
        self.walk_morton(|n| self.is_leaf(n), |n| f(n.origin, self.node_voxel(n)));
    }

    /// Visits the nodes where `stop` holds, in Morton order, descending everywhere else (into
    /// a tile's virtual nodes too).
    fn walk_morton(&self, stop: impl Fn(&NodeRef) -> bool, mut f: impl FnMut(&NodeRef)) {
        if self.is_empty() {
            return;
        }
        let mut stack = vec![(self.root(), 0u8)];
        while let Some((node, next_k)) = stack.pop() {
            if stop(&node) {
                f(&node);
                continue;
            }
            let mask = self.child_mask(&node);
            if let Some(k) = (next_k..8).find(|k| mask & (1 << k) != 0) {
                stack.push((node, k + 1));
                if let Some(child) = self.child(&node, k) {
                    stack.push((child, 0));
                }
            }
        }
    }

    /// The first solid voxel in Morton order, without visiting the others.
    #[must_use]
    pub fn first_voxel(&self) -> Option<Voxel> {
        let mut node = self.root();
        if self.is_empty() {
            return None;
        }
        while !self.is_leaf(&node) && !self.is_tile(&node) {
            let mask = self.child_mask(&node);
            node = self.child(&node, mask.trailing_zeros() as u8)?;
        }
        Some(self.node_voxel(&node))
    }

    /// Every solid voxel in Morton order.
    #[must_use]
    pub fn leaves(&self) -> Vec<(UVec3, Voxel)> {
        // Reserved up to 2^24 entries: tiles can stand for more voxels than memory holds, and
        // the caller should learn that from a failed growth, not an up-front reservation.
        let mut out = Vec::with_capacity(self.leaf_count.min(1 << 24) as usize);
        self.for_each_leaf(|c, v| out.push((c, v)));
        out
    }

    /// Inclusive bounds of the solid voxels, by descending only along occupied children.
    #[must_use]
    pub fn bounds(&self) -> Option<(UVec3, UVec3)> {
        if self.is_empty() {
            return None;
        }
        let mut lo = UVec3::MAX;
        let mut hi = UVec3::ZERO;
        // Every stored node is visited (a tile as its box); cheap next to anything that needs
        // bounds.
        self.walk_morton(
            |n| self.is_leaf(n) || self.is_tile(n),
            |n| {
                lo = lo.min(n.origin);
                hi = hi.max(n.origin + (self.node_size(n.level) - 1));
            },
        );
        Some((lo, hi))
    }

    /// Memory used, by part.
    #[must_use]
    pub fn memory_stats(&self) -> MemoryStats {
        let inner_slots = self.inner_mask.len() as u64;
        let leaf_slots = self.leaf_attr.len() as u64;
        let inner_entry = (1 + 4 + self.inner_attr.bytes_per_entry()) as u64;
        let leaf_entry = self.leaf_attr.bytes_per_entry() as u64;
        let total = inner_slots * inner_entry + leaf_slots * leaf_entry;
        let stored_leaves = self.leaf_count - self.tile_voxels;
        MemoryStats {
            inner_nodes: self.inner_count,
            leaves: self.leaf_count,
            tiles: self.tile_count,
            tile_voxels: self.tile_voxels,
            inner_bytes: self.inner_count * inner_entry,
            leaf_bytes: stored_leaves * leaf_entry,
            free_slots: (inner_slots - self.inner_count) + (leaf_slots - stored_leaves),
            total_bytes: total,
            bytes_per_leaf: if self.leaf_count == 0 {
                0.0
            } else {
                total as f64 / self.leaf_count as f64
            },
        }
    }

    /// Rebuilds the pools tightly in Morton order (drops free slots left by edits); tiles stay
    /// tiles, and tiling stays as it was.
    pub fn compact(&mut self) {
        self.repack();
    }

    /// Raw pools for GPU upload: inner child masks.
    #[must_use]
    pub fn inner_masks(&self) -> &[u8] {
        &self.inner_mask
    }

    /// Raw pools for GPU upload: inner first-child indices.
    #[must_use]
    pub fn inner_first_children(&self) -> &[u32] {
        &self.inner_first
    }

    /// Raw pools for GPU upload: inner LOD colours (sRGB RGBA8).
    #[must_use]
    pub fn inner_colors(&self) -> &[[u8; 4]] {
        &self.inner_attr.color
    }

    /// Raw pools for GPU upload: inner LOD normals (octahedral).
    #[must_use]
    pub fn inner_normals(&self) -> &[u16] {
        &self.inner_attr.normal
    }

    /// Raw pools for GPU upload: leaf colours (sRGB RGBA8).
    #[must_use]
    pub fn leaf_colors(&self) -> &[[u8; 4]] {
        &self.leaf_attr.color
    }

    /// Raw pools for GPU upload: leaf normals (octahedral).
    #[must_use]
    pub fn leaf_normals(&self) -> &[u16] {
        &self.leaf_attr.normal
    }

    /// Raw pools: inner merged skin weights (empty without skin).
    #[must_use]
    pub fn inner_skin(&self) -> &[Skin4] {
        &self.inner_attr.skin
    }

    /// Raw pools: leaf skin weights (empty without skin).
    #[must_use]
    pub fn leaf_skin(&self) -> &[Skin4] {
        &self.leaf_attr.skin
    }
}

impl std::fmt::Debug for Svo {
    /// A summary: the pools are far too large to print.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Svo")
            .field("depth", &self.depth)
            .field("has_skin", &self.has_skin)
            .field("leaves", &self.leaf_count)
            .field("inner_nodes", &self.inner_count)
            .finish_non_exhaustive()
    }
}

impl Default for Svo {
    /// An empty depth-1 octree.
    fn default() -> Self {
        Self::new(1, false).unwrap_or_else(|_| unreachable!("depth 1 is in range"))
    }
}

struct EditCtx<'a, 'f> {
    lo: UVec3,
    hi: UVec3,
    create: bool,
    f: &'a mut (dyn FnMut(UVec3, Option<Voxel>) -> Option<Voxel> + 'f),
    result: &'a mut EditResult,
    /// Per level, the last uniform node built (`Svo::build_missing`): its children's value and
    /// their average.
    uniform: [Option<(Voxel, Voxel)>; MAX_DEPTH as usize + 1],
}

/// A node built by `Svo::build_missing`, not yet placed in its parent's block.
#[derive(Debug, Clone, Copy, Default)]
struct Built {
    mask: u8,
    first: u32,
    attrs: Voxel,
}

impl EditCtx<'_, '_> {
    fn record(&mut self, coord: UVec3, old: Option<Voxel>) {
        record_change(self.result, coord, old);
    }
}

fn record_change(result: &mut EditResult, coord: UVec3, old: Option<Voxel>) {
    result.delta.entries.push((coord, old));
    result.changed = Some(match result.changed {
        None => (coord, coord),
        Some((lo, hi)) => (lo.min(coord), hi.max(coord)),
    });
}

impl PartialEq for Svo {
    /// Logical equality: same depth, skin flag, structure and attributes (leaf and internal),
    /// whatever the pool layout, and whether or not a region is stored as a tile (a tile equals
    /// the full subtree of equal voxels it stands for).
    fn eq(&self, other: &Self) -> bool {
        if self.depth != other.depth
            || self.has_skin != other.has_skin
            || self.leaf_count != other.leaf_count
        {
            return false;
        }
        let mut stack = vec![(self.root(), other.root())];
        while let Some((a, b)) = stack.pop() {
            if self.child_mask(&a) != other.child_mask(&b) {
                return false;
            }
            if (a.level > 0 || !self.is_empty()) && self.node_voxel(&a) != other.node_voxel(&b) {
                return false;
            }
            if self.is_tile(&a) && other.is_tile(&b) {
                // Two full regions of the same voxel.
                continue;
            }
            for k in 0..8 {
                if let (Some(ca), Some(cb)) = (self.child(&a, k), other.child(&b, k)) {
                    stack.push((ca, cb));
                }
            }
        }
        true
    }
}

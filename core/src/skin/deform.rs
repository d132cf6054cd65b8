//! Per-node linear-blend skinning for the renderers (ASVO paper §3.1): a [`SkinDeform`] places
//! every octree node it is asked about — leaf or internal — with the node's own (merged)
//! weights, at the moment the traversal computes its screen position. The octree is untouched.
//!
//! A node is drawn as its voxel cube carried by the node's blended matrix `Σ wᵢ Mᵢ` (rotating and
//! scaling with its bones), scaled about its skinned centre by the stretch factor `S` of the
//! chosen [`StretchStrategy`]:
//!
//! * `Off`: `S = 1`; `Thesis`: `S = min(2, W)` (paper §3.3);
//! * `Corners`: the world AABB of the eight corners skinned with their own weights (§8.1.3);
//! * `Adaptive`: the smallest `S` for which the drawn box contains those eight skinned corners
//!   (measured this frame, so `S = 1` wherever the neighbourhood moves rigidly, §6).
//!
//! Corner weights are derived once per octree ([`SkinTables`], cached on the [`Rig`]): a corner's
//! weights merge the weights of every leaf sharing that lattice point, so neighbouring voxels
//! agree on where their shared corners go — which is what closes the holes.
//!
//! Culling (paper §6): an internal node's splat box need not contain its descendants once bones
//! bend. [`NodeDeform::subtree_bounds`] gives a box that provably contains every leaf and every
//! descendant's centre: every descendant point skins to a convex combination of `Mⱼ p` over the
//! joints `j` used in the subtree, so the union of the node's bind box carried by each of those
//! joints bounds the subtree, padded only by what a stretch factor adds to a leaf. Frustum and
//! occlusion culling join it with the node's own box and the LOD margin of descendants drawn
//! coarser than a leaf (`render::asvo`); LOD and splatting use the splat box.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

use glam::{Mat3, Mat4, UVec3, Vec3, Vec4};
use rayon::prelude::*;

use super::lbs::{blend_matrix, normal_matrix, normal_through, skin_point, transform_normal};
use super::rig::{Rig, StretchOverrides};
use super::skeleton::{JointMatrices, Pose};
use super::stretch::{
    StretchSettings, StretchStrategy, containing_factor, decode_override, thesis_factor,
};
use crate::deform::{DeformedNode, NodeDeform, NodeInfo};
use crate::svo::{Skin4, Svo};

/// Derived per-octree data for skinned drawing: weights at every node's eight corners and the
/// joints used in every internal node's subtree. Built in one pass over the octree. Every
/// stored node gets what the leaf-only octree of the same voxels gives it: a tile (interior
/// voxels sharing one weight set, the only kind a skinned octree stores) counts as its voxels,
/// touching the lattice on its boundary with their number there.
#[derive(Debug, Clone, Default)]
pub struct SkinTables {
    /// Every distinct `(lattice point, weights)` a node corner is skinned from: a corner shared
    /// by neighbouring nodes is one entry, so a frame skins it once ([`SkinDeform`]).
    pub(crate) corner_points: Vec<(UVec3, Skin4)>,
    /// Per leaf-pool index: the entries of `corner_points` of its eight corners.
    pub(crate) leaf_corner_points: Vec<[u32; 8]>,
    /// Per inner-pool index: as `leaf_corner_points`.
    pub(crate) inner_corner_points: Vec<[u32; 8]>,
    /// Per inner-pool index: range into `joints`.
    inner_joint_range: Vec<(u32, u16)>,
    /// Sorted joint lists, concatenated.
    joints: Vec<u8>,
    /// Per entry of `joints`: the largest weight (unorm8) that joint has in any skin placing
    /// something in the subtree (own and corner weights of every node in it).
    joint_max_weights: Vec<u8>,
    /// What the tables were built from (see [`fingerprint`]).
    fingerprint: u64,
}

/// A cheap identity of an octree's structure and skin: CRC-32s of its masks, child links and
/// skin pools. Changes whenever an edit could change the tables.
fn fingerprint(svo: &Svo) -> u64 {
    let mut h = crc32fast::Hasher::new();
    h.update(&[svo.depth()]);
    h.update(svo.inner_masks());
    h.update(bytemuck::cast_slice(svo.inner_first_children()));
    let structure = h.finalize();
    // The pools as bytes: the same CRC as hashing each skin's joints then weights, without a
    // call per 4 bytes (this runs every frame).
    let mut h = crc32fast::Hasher::new();
    h.update(bytemuck::cast_slice(svo.leaf_skin()));
    h.update(bytemuck::cast_slice(svo.inner_skin()));
    (u64::from(structure) << 32) | u64::from(h.finalize())
}

impl SkinTables {
    /// Builds the tables for `svo` (empty tables for an octree without skin).
    #[must_use]
    pub fn build(svo: &Svo) -> Self {
        let mut t = Self {
            fingerprint: fingerprint(svo),
            ..Self::default()
        };
        if !svo.has_skin() || svo.is_empty() {
            return t;
        }
        // Lattice point → merged weights of the voxels touching it: every (point, voxel skin)
        // touch, sorted by point, then merged per point. Sorting a flat list is several times
        // cheaper than a hash map of lists, and the points come out in Morton order
        // (neighbouring nodes read neighbouring entries). A tile (interior voxels sharing one
        // weight set, `Svo::tiles_value`) touches only the points on its boundary, each once
        // with the number of its voxels there: its inner points merge eight copies of its own
        // weights, which is those weights, and are the corner of no stored node.
        let (leaf_skin, inner_skin) = (svo.leaf_skin(), svo.inner_skin());
        let mut touches: Vec<(u128, u64)> = Vec::with_capacity(leaf_skin.len() * 8);
        let mut stack = vec![svo.root()];
        while let Some(node) = stack.pop() {
            if svo.is_leaf(&node) {
                for k in 0..8u32 {
                    let p = node.origin + UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1);
                    touches.push((lattice_key(p), u64::from(node.index) * 8 + u64::from(k)));
                }
            } else if svo.is_tile(&node) {
                let size = svo.node_size(node.level);
                tile_boundary(node.origin, size, |p, voxels| {
                    touches.push((lattice_key(p), tile_touch(node.index, voxels)));
                });
            } else {
                stack.extend((0..8).filter_map(|k| svo.child(&node, k)));
            }
        }
        // Merging sums integer weights, so the order of a point's voxels does not matter.
        touches.sort_unstable_by_key(|e| e.0);
        t.leaf_corner_points = vec![[0; 8]; leaf_skin.len()];
        let mut merged: Vec<(UVec3, Skin4)> = Vec::new();
        let mut keys: Vec<u128> = Vec::new();
        // (tile's inner index, entry) for each point on a tile's boundary.
        let mut tile_points: Vec<(u32, u32)> = Vec::new();
        let mut skins: Vec<Skin4> = Vec::with_capacity(8);
        for group in touches.chunk_by(|a, b| a.0 == b.0) {
            skins.clear();
            for &(_, slot) in group {
                match tile_of_touch(slot) {
                    Some((tile, voxels)) => skins.extend(std::iter::repeat_n(
                        inner_skin.get(tile as usize).copied().unwrap_or_default(),
                        voxels,
                    )),
                    None => skins.extend(leaf_skin.get((slot / 8) as usize).copied()),
                }
            }
            let skin = Skin4::merge(&skins);
            let id = merged.len() as u32;
            for &(_, slot) in group {
                if let Some((tile, _)) = tile_of_touch(slot) {
                    tile_points.push((tile, id));
                } else if let Some(i) = t.leaf_corner_points.get_mut((slot / 8) as usize) {
                    i[(slot % 8) as usize] = id;
                }
            }
            keys.push(group[0].0);
            merged.push((lattice_point(group[0].0), skin));
        }
        tile_points.sort_unstable();
        let mut points = CornerPoints {
            keys,
            own: HashMap::new(),
            tile_points,
        };
        t.corner_points = merged;
        t.inner_corner_points = vec![[0; 8]; svo.inner_skin().len()];
        t.inner_joint_range = vec![(0, 0); svo.inner_skin().len()];
        // Post-order walk: children's joint sets are known before their parent's.
        let mut joints = Vec::new();
        walk(svo, svo.root(), &mut points, &mut t, &mut joints);
        t
    }

    /// The entries of [`Self::corner_points`] of a node's eight corners.
    fn corner_point_ids(&self, svo: &Svo, node: &crate::svo::NodeRef) -> Option<&[u32; 8]> {
        if svo.is_leaf(node) {
            self.leaf_corner_points.get(node.index as usize)
        } else {
            self.inner_corner_points.get(node.index as usize)
        }
    }

    /// The corner weights of leaf-pool index `index` ([`super::stretch::voxel_corners`] order);
    /// `None` past the table (an octree without skin has none). Stored once per lattice point
    /// and named by index per node, not eight copies per node.
    #[must_use]
    pub fn leaf_corner_skins(&self, index: u32) -> Option<[Skin4; 8]> {
        self.corner_skins(self.leaf_corner_points.get(index as usize)?)
    }

    /// The corner weights of inner-pool index `index` (as [`Self::leaf_corner_skins`]).
    #[must_use]
    pub fn inner_corner_skins(&self, index: u32) -> Option<[Skin4; 8]> {
        self.corner_skins(self.inner_corner_points.get(index as usize)?)
    }

    /// Leaf-pool entries of the corner tables (0 for an octree without skin).
    #[must_use]
    pub fn leaf_count(&self) -> usize {
        self.leaf_corner_points.len()
    }

    /// Inner-pool entries of the corner tables (0 for an octree without skin).
    #[must_use]
    pub fn inner_count(&self) -> usize {
        self.inner_corner_points.len()
    }

    fn corner_skins(&self, ids: &[u32; 8]) -> Option<[Skin4; 8]> {
        let mut out = [Skin4::default(); 8];
        for (o, &i) in out.iter_mut().zip(ids) {
            *o = self.corner_points.get(i as usize)?.1;
        }
        Some(out)
    }

    /// The joints used anywhere in inner node `index`'s subtree (sorted, unique; empty when
    /// unknown), from which [`SkinDeform`]'s culling box is built.
    #[must_use]
    pub fn subtree_joints(&self, index: u32) -> &[u8] {
        self.inner_joint_range
            .get(index as usize)
            .and_then(|&(start, len)| {
                self.joints
                    .get(start as usize..start as usize + usize::from(len))
            })
            .unwrap_or(&[])
    }

    /// [`Self::subtree_joints`] with each joint's largest weight (unorm8) in the subtree:
    /// `(joints, weights)`, equally long.
    #[must_use]
    pub fn subtree_joint_weights(&self, index: u32) -> (&[u8], &[u8]) {
        self.inner_joint_range
            .get(index as usize)
            .and_then(|&(start, len)| {
                let r = start as usize..start as usize + usize::from(len);
                Some((self.joints.get(r.clone())?, self.joint_max_weights.get(r)?))
            })
            .unwrap_or((&[], &[]))
    }
}

/// `(joint, weight)` of every influence a skin blends with: the empty skin follows joint 0
/// with full weight (see [`Skin4::blend_weights`]).
fn used_influences(skin: &Skin4) -> impl Iterator<Item = (u8, u8)> + '_ {
    let empty = skin.is_empty();
    (0..4)
        .filter(move |&i| !empty && skin.weights[i] > 0)
        .map(|i| (skin.joints[i], skin.weights[i]))
        .chain(empty.then_some((0, 255)))
}

/// Sorts the `(joint, weight)` pairs of `v[start..]` by joint and keeps each joint once, with
/// its largest weight.
fn merge_max(v: &mut Vec<(u8, u8)>, start: usize) {
    // The largest weight + 1 per joint (0: absent) and which joints are present: linear in the
    // pairs, where sorting them was most of building the tables.
    let mut best = [0u16; 256];
    let mut present = [0u64; 4];
    for &(j, w) in &v[start..] {
        let b = &mut best[usize::from(j)];
        *b = (*b).max(u16::from(w) + 1);
        present[usize::from(j >> 6)] |= 1 << (j & 63);
    }
    v.truncate(start);
    for (word, &bits) in present.iter().enumerate() {
        let mut bits = bits;
        while bits != 0 {
            let j = word * 64 + bits.trailing_zeros() as usize;
            bits &= bits - 1;
            v.push((j as u8, (best[j] - 1) as u8));
        }
    }
}

/// Where the corner points of [`SkinTables`] come from while it is built: the lattice points
/// touching leaves (merged weights, entry index) and the corners of internal nodes touching no
/// leaf, which move with the node's own weights.
struct CornerPoints {
    /// [`lattice_key`] of the lattice points touching leaves, sorted: entry `i` is
    /// `corner_points[i]`.
    keys: Vec<u128>,
    own: HashMap<(UVec3, Skin4), u32>,
    /// `(tile's inner index, entry)` of every lattice point on a tile's boundary, sorted.
    tile_points: Vec<(u32, u32)>,
}

/// Bit of a [`SkinTables::build`] touch marking a tile's voxels (the rest: their count at the
/// point above bit 32, the tile's inner index below); a leaf's touch is `index * 8 + corner`.
const TILE_TOUCH: u64 = 1 << 63;

fn tile_touch(tile: u32, voxels: usize) -> u64 {
    TILE_TOUCH | (voxels as u64) << 32 | u64::from(tile)
}

/// `(tile's inner index, voxels)` of a tile's touch; `None` for a leaf's.
fn tile_of_touch(slot: u64) -> Option<(u32, usize)> {
    (slot & TILE_TOUCH != 0).then_some((slot as u32, ((slot >> 32) & 0xff) as usize))
}

/// Calls `f(point, voxels)` for every lattice point on the boundary of the cube of `size`
/// voxels a side (`size >= 2`) at `origin`, with how many of the cube's voxels touch it: 1 at
/// a corner, 2 along an edge, 4 on a face. The cube's voxels touch each inner point eight
/// times.
fn tile_boundary(origin: UVec3, size: u32, mut f: impl FnMut(UVec3, usize)) {
    let on = |v: u32| v == 0 || v == size;
    let count = |v: u32| if on(v) { 1 } else { 2 };
    for x in 0..=size {
        for y in 0..=size {
            let all_z = on(x) || on(y);
            let step = if all_z { 1 } else { size };
            for z in (0..=size).step_by(step as usize) {
                f(origin + UVec3::new(x, y, z), count(x) * count(y) * count(z));
            }
        }
    }
}

/// A Morton-order key of a lattice point (coordinates up to 2²¹ inclusive, one bit more than a
/// voxel coordinate, so `svo::morton_encode` of the point itself could overflow).
fn lattice_key(p: UVec3) -> u128 {
    (u128::from(crate::svo::morton_encode(p >> 1)) << 3)
        | u128::from((p.x & 1) | ((p.y & 1) << 1) | ((p.z & 1) << 2))
}

/// The lattice point of a [`lattice_key`].
fn lattice_point(key: u128) -> UVec3 {
    let high = crate::svo::morton_decode((key >> 3) as u64);
    let low = key as u32;
    (high << 1) + UVec3::new(low & 1, (low >> 1) & 1, (low >> 2) & 1)
}

impl CornerPoints {
    /// The weights and the entry of `t.corner_points` of the corner at `p` of a node whose own
    /// weights are `own` (a new entry when it is new).
    fn at(&mut self, p: UVec3, own: Skin4, t: &mut SkinTables) -> (Skin4, u32) {
        if let Ok(i) = self.keys.binary_search(&lattice_key(p))
            && let Some(&(_, skin)) = t.corner_points.get(i)
        {
            return (skin, i as u32);
        }
        let id = *self.own.entry((p, own)).or_insert_with(|| {
            t.corner_points.push((p, own));
            (t.corner_points.len() - 1) as u32
        });
        (own, id)
    }
}

/// Fills the corner tables of `node`'s internal nodes (the leaves' are filled from the
/// lattice) and appends to `joints` the joints its subtree uses with their largest weights
/// (sorted by joint, unique). One buffer serves the whole walk: each call works on its own
/// tail of it.
fn walk(
    svo: &Svo,
    node: crate::svo::NodeRef,
    points: &mut CornerPoints,
    t: &mut SkinTables,
    joints: &mut Vec<(u8, u8)>,
) {
    let start = joints.len();
    let own = svo.node_voxel(&node).skin;
    joints.extend(used_influences(&own));
    // Own and corner weights: a node drawn at LOD by `Corners` is placed by its corners, and a
    // corner may touch leaves outside the subtree.
    if svo.is_leaf(&node) {
        if let Some(corners) = t.leaf_corner_skins(node.index) {
            joints.extend(corners.iter().flat_map(used_influences));
        }
        merge_max(joints, start);
        return;
    }
    let size = svo.node_size(node.level);
    let mut ids = [0u32; 8];
    let corners: [Skin4; 8] = std::array::from_fn(|k| {
        let b = k as u32;
        let p = node.origin + UVec3::new(b & 1, (b >> 1) & 1, (b >> 2) & 1) * size;
        // An internal node's corner may touch no leaf (its subtree is sparse there): it then
        // moves with the node's own weights.
        let (skin, id) = points.at(p, own, t);
        ids[k] = id;
        skin
    });
    joints.extend(corners.iter().flat_map(used_influences));
    if let Some(slot) = t.inner_corner_points.get_mut(node.index as usize) {
        *slot = ids;
    }
    if svo.is_tile(&node) {
        // A tile's voxels and the nodes between it and them are not stored, but their weights
        // count as a leaf-only subtree's would: their own are the tile's, and their corners
        // are the tile's inner points (the tile's weights again) and its boundary points.
        let at = points.tile_points.partition_point(|e| e.0 < node.index);
        for &(_, id) in points.tile_points[at..]
            .iter()
            .take_while(|e| e.0 == node.index)
        {
            if let Some((_, skin)) = t.corner_points.get(id as usize) {
                joints.extend(used_influences(skin));
            }
        }
    } else {
        for k in 0..8 {
            if let Some(child) = svo.child(&node, k) {
                walk(svo, child, points, t, joints);
            }
        }
    }
    merge_max(joints, start);
    let first = t.joints.len() as u32;
    t.joints.extend(joints[start..].iter().map(|&(j, _)| j));
    t.joint_max_weights
        .extend(joints[start..].iter().map(|&(_, w)| w));
    if let Some(slot) = t.inner_joint_range.get_mut(node.index as usize) {
        *slot = (first, (joints.len() - start) as u16);
    }
}

/// Cache of [`SkinTables`] on a [`Rig`]: derived data, rebuilt when the octree's fingerprint
/// changes. It also keeps the per-frame scratch of the last [`SkinDeform`] (see
/// `DeformScratch`), so frame after frame the deformer allocates nothing. Cloning gives an
/// empty cache and every cache compares equal, so a document's equality and undo snapshots
/// ignore it.
#[derive(Default)]
pub struct TablesCache {
    tables: Mutex<Option<Arc<SkinTables>>>,
    scratch: Mutex<Option<DeformScratch>>,
}

impl TablesCache {
    /// The tables for `svo`, built on first use and after any change to it.
    pub fn get(&self, svo: &Svo) -> Arc<SkinTables> {
        let fp = fingerprint(svo);
        let mut slot = self
            .tables
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(t) = slot.as_ref()
            && t.fingerprint == fp
        {
            return Arc::clone(t);
        }
        let t = Arc::new(SkinTables::build(svo));
        *slot = Some(Arc::clone(&t));
        t
    }

    /// The kept scratch (empty the first time, or while another deformer holds it).
    fn take_scratch(&self) -> DeformScratch {
        self.scratch
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .take()
            .unwrap_or_default()
    }

    fn put_scratch(&self, scratch: DeformScratch) {
        *self
            .scratch
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(scratch);
    }
}

/// What a [`SkinDeform`] computes once per frame and keeps for the traversals: the skinned
/// corner points, and a memo of every node's box. The view and shadow traversals of a frame
/// ask about most nodes (a node is placed again when it is drawn as an exact cube, and both
/// passes visit it), and placing a skinned node costs a blended matrix, eight corners and a
/// 3×3 inverse; the memo makes that once per node and frame.
///
/// The memo is lock-free and safe: a slot holds a node's box when its stamp equals this
/// frame's `epoch`. A writer stores the twelve floats, then the stamp (release); a reader
/// that sees the stamp (acquire) sees the floats. Two threads placing the same node
/// write the same bits, so a race costs only the repeated work.
#[derive(Default)]
struct DeformScratch {
    /// This frame's stamp (never 0, so fresh slots hold nothing).
    epoch: u32,
    /// Per node ([`SkinDeform::deform`] and the normal matrix): leaf-pool indices
    /// first, then inner-pool indices.
    memo: Vec<MemoSlot>,
    /// Per inner-pool index: [`SkinDeform::subtree_bounds`] (word 12 is 1 for `Some`).
    bounds_memo: Vec<MemoSlot>,
    /// [`SkinTables`]' corner points skinned for this pose (world space).
    corner_world: Vec<Vec3>,
    /// The pose's buffers: the sampled pose, its joint matrices, and (while a deformer holds
    /// this scratch, in its `world_from_voxel`) each joint's voxel-to-world matrix. Kept so a
    /// steady frame allocates nothing for its pose.
    pose: Pose,
    matrices: JointMatrices,
    joints: Vec<Mat4>,
}

/// One memo entry: a stamp and up to [`MEMO_WORDS`] floats.
#[derive(Default)]
struct MemoSlot {
    stamp: AtomicU32,
    bits: [AtomicU32; MEMO_WORDS],
}

/// A node's box (12 floats) and the normal matrix of its blended linear part (9,
/// [`normal_matrix`]).
const MEMO_WORDS: usize = 21;

impl DeformScratch {
    /// Starts a frame for octrees with `nodes` nodes, `inner` of them internal: a new stamp,
    /// so every slot is stale.
    fn start(&mut self, nodes: usize, inner: usize) {
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            // Wrapped after 4 billion frames: clear the stamps once.
            for s in self.memo.iter().chain(&self.bounds_memo) {
                s.stamp.store(0, Ordering::Relaxed);
            }
            self.epoch = 1;
        }
        if self.memo.len() < nodes {
            self.memo.resize_with(nodes, MemoSlot::default);
        }
        if self.bounds_memo.len() < inner {
            self.bounds_memo.resize_with(inner, MemoSlot::default);
        }
    }

    /// This frame's words `from..from + N` of a slot, if it has them.
    #[inline]
    fn get<const N: usize>(&self, memo: &[MemoSlot], slot: usize, from: usize) -> Option<[f32; N]> {
        let s = memo.get(slot)?;
        if s.stamp.load(Ordering::Acquire) != self.epoch {
            return None;
        }
        let words = s.bits.get(from..from + N)?;
        Some(std::array::from_fn(|i| {
            f32::from_bits(words[i].load(Ordering::Relaxed))
        }))
    }

    /// Stores this frame's values of a slot.
    #[inline]
    fn put(&self, memo: &[MemoSlot], slot: usize, values: &[f32; MEMO_WORDS]) {
        let Some(s) = memo.get(slot) else {
            return;
        };
        for (b, v) in s.bits.iter().zip(values) {
            b.store(v.to_bits(), Ordering::Relaxed);
        }
        s.stamp.store(self.epoch, Ordering::Release);
    }
}

/// A node's box and the normal matrix of its blended linear part as memo words.
fn node_words(d: &DeformedNode, normals: &Mat3) -> [f32; MEMO_WORDS] {
    let mut w = [0.0; MEMO_WORDS];
    w[..3].copy_from_slice(&d.center_world.to_array());
    w[3..12].copy_from_slice(&d.half_axes_world.to_cols_array());
    w[12..].copy_from_slice(&normals.to_cols_array());
    w
}

/// A subtree box (or none) as memo words: the box, then 1 or 0.
fn bounds_words(d: Option<&DeformedNode>) -> [f32; MEMO_WORDS] {
    let mut w = [0.0; MEMO_WORDS];
    if let Some(d) = d {
        w[..3].copy_from_slice(&d.center_world.to_array());
        w[3..12].copy_from_slice(&d.half_axes_world.to_cols_array());
        w[12] = 1.0;
    }
    w
}

fn box_of_words(w: &[f32]) -> DeformedNode {
    DeformedNode {
        center_world: Vec3::new(w[0], w[1], w[2]),
        half_axes_world: Mat3::from_cols_slice(&w[3..12]),
    }
}

impl Clone for TablesCache {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl PartialEq for TablesCache {
    fn eq(&self, _other: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for TablesCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("TablesCache")
    }
}

/// The skinning [`NodeDeform`]: places a skinned octree's nodes for one pose.
pub struct SkinDeform<'a> {
    /// `world_from_voxel` of each joint: `world_from_object · skinning[j] · object_from_voxel`,
    /// so a node's voxel-space centre skins straight into the world.
    world_from_voxel: Vec<Mat4>,
    settings: StretchSettings,
    overrides: &'a StretchOverrides,
    tables: Arc<SkinTables>,
    /// This frame's corner points and node memo; `corner_world` is filled only when the
    /// strategy reads corners. Skinning the shared lattice points once per frame, rather than
    /// the corners of every node asked about, skins each point once instead of up to eight
    /// times per traversal.
    scratch: DeformScratch,
    /// Where the scratch came from and goes back to when the deformer is dropped.
    pool: Option<&'a TablesCache>,
    /// Whether `scratch.corner_world` holds this pose's corner points (they depend on the
    /// pose only, so new settings keep them).
    corners_posed: bool,
}

/// `world_from_object · skinning[j] · object_from_voxel` per joint.
fn joints_world_from_voxel(
    world_from_object: Mat4,
    skinning: &[Mat4],
    object_from_voxel: Mat4,
) -> Vec<Mat4> {
    let mut out = Vec::with_capacity(skinning.len());
    joints_world_from_voxel_into(world_from_object, skinning, object_from_voxel, &mut out);
    out
}

/// [`joints_world_from_voxel`] into `out` (cleared first).
fn joints_world_from_voxel_into(
    world_from_object: Mat4,
    skinning: &[Mat4],
    object_from_voxel: Mat4,
    out: &mut Vec<Mat4>,
) {
    out.clear();
    out.extend(
        skinning
            .iter()
            .map(|s| world_from_object * *s * object_from_voxel),
    );
}

impl Drop for SkinDeform<'_> {
    fn drop(&mut self) {
        if let Some(pool) = self.pool {
            self.scratch.joints = std::mem::take(&mut self.world_from_voxel);
            pool.put_scratch(std::mem::take(&mut self.scratch));
        }
    }
}

impl<'a> SkinDeform<'a> {
    /// A deformer for `svo` skinned by `skinning` (`skinned_from_bind` per joint, from
    /// [`Rig::skinning_at`]), placed by `world_from_object`, voxel space mapping to bind space by
    /// `object_from_voxel`.
    #[must_use]
    pub fn new(
        world_from_object: Mat4,
        object_from_voxel: Mat4,
        skinning: &[Mat4],
        settings: StretchSettings,
        overrides: &'a StretchOverrides,
        tables: Arc<SkinTables>,
    ) -> Self {
        Self::with_scratch(
            joints_world_from_voxel(world_from_object, skinning, object_from_voxel),
            settings,
            overrides,
            tables,
            DeformScratch::default(),
            None,
        )
    }

    fn with_scratch(
        world_from_voxel: Vec<Mat4>,
        settings: StretchSettings,
        overrides: &'a StretchOverrides,
        tables: Arc<SkinTables>,
        scratch: DeformScratch,
        pool: Option<&'a TablesCache>,
    ) -> Self {
        Self {
            world_from_voxel,
            settings: StretchSettings::default(),
            overrides,
            tables,
            scratch,
            pool,
            corners_posed: false,
        }
        .with_settings(settings)
    }

    /// A deformer for a rigged model at `time_secs` of `clip` (its playback state otherwise).
    #[must_use]
    pub fn for_rig(
        rig: &'a Rig,
        svo: &Svo,
        world_from_object: Mat4,
        object_from_voxel: Mat4,
        clip: Option<usize>,
        time_secs: f32,
    ) -> Self {
        let mut scratch = rig.tables.take_scratch();
        rig.skinning_into(clip, time_secs, &mut scratch.pose, &mut scratch.matrices);
        let mut joints = std::mem::take(&mut scratch.joints);
        joints_world_from_voxel_into(
            world_from_object,
            &scratch.matrices.skinning,
            object_from_voxel,
            &mut joints,
        );
        Self::with_scratch(
            joints,
            rig.stretch,
            &rig.stretch_overrides,
            rig.tables(svo),
            scratch,
            Some(&rig.tables),
        )
    }

    /// The same deformer with other stretch settings (for comparing strategies on one pose).
    #[must_use]
    pub fn with_settings(mut self, settings: StretchSettings) -> Self {
        self.settings = settings.sanitized();
        // New settings place nodes differently: a new memo stamp.
        let t = &self.tables;
        self.scratch.start(
            t.leaf_corner_points.len() + t.inner_corner_points.len(),
            t.inner_corner_points.len(),
        );
        let reads_corners = matches!(
            self.settings.strategy,
            StretchStrategy::Corners | StretchStrategy::Adaptive
        );
        // The pose's corner points, once: a deformer made with one strategy and given another
        // (`for_rig(..).with_settings(..)`, as the renderers do) skins them once.
        if reads_corners && !self.corners_posed {
            let m = &self.world_from_voxel;
            t.corner_points
                .par_iter()
                .map(|&(p, skin)| {
                    skin_point(m, skin.joints_u16(), skin.blend_weights(), p.as_vec3())
                })
                .collect_into_vec(&mut self.scratch.corner_world);
            self.corners_posed = true;
        }
        self
    }

    /// The skinned corners of a node ([`super::stretch::voxel_corners`] order), when its
    /// corner points are known.
    #[inline]
    fn skinned_corners(&self, node: &NodeInfo<'_>) -> Option<[Vec3; 8]> {
        let ids = self.tables.corner_point_ids(node.svo, &node.node)?;
        let mut out = [Vec3::ZERO; 8];
        for (o, &i) in out.iter_mut().zip(ids) {
            *o = *self.scratch.corner_world.get(i as usize)?;
        }
        Some(out)
    }

    /// The splat box of a node and the blended linear part used for its normal.
    #[inline]
    fn place(&self, node: &NodeInfo<'_>) -> (DeformedNode, Mat3) {
        let skin = node.skin();
        let blended = blend_matrix(
            &self.world_from_voxel,
            skin.joints_u16(),
            skin.blend_weights(),
        );
        let linear = Mat3::from_mat4(blended);
        (self.stretched_box(node, &skin, &blended, linear), linear)
    }

    /// The splat box of a node with weights `skin`, blended matrix `blended` and its linear
    /// part `linear`.
    #[inline]
    fn stretched_box(
        &self,
        node: &NodeInfo<'_>,
        skin: &Skin4,
        blended: &Mat4,
        linear: Mat3,
    ) -> DeformedNode {
        let skin = *skin;
        let half = 0.5 * node.size_voxels() as f32;
        let c = node.center_voxel();
        let center = blended.transform_point3(c);
        let s = &self.settings;
        let bound = |f: f32| f.clamp(s.min_factor, s.max_factor);
        let override_code = if node.svo.is_leaf(&node.node) && !self.overrides.is_empty() {
            self.overrides.get(node.node.origin)
        } else {
            0
        };
        let scaled = |f: f32| DeformedNode {
            center_world: center,
            half_axes_world: linear * (f * half * s.multiplier),
        };
        if let Some(f) = decode_override(override_code) {
            return scaled(f);
        }
        let corners =
            if s.strategy == StretchStrategy::Corners || s.strategy == StretchStrategy::Adaptive {
                self.skinned_corners(node)
            } else {
                None
            };
        match (s.strategy, corners) {
            (StretchStrategy::Off, _) => scaled(1.0),
            (StretchStrategy::Thesis, _) | (_, None) => scaled(bound(thesis_factor(&skin))),
            (StretchStrategy::Corners, Some(cs)) => {
                let (lo, hi) = super::stretch::aabb(&cs);
                // Not capped by `max_factor`: the box is bounded by the pose itself (it lies in
                // the hull of the node's bind box carried by each of its corners' joints, as
                // `subtree_bounds` uses), and a cap in voxels reopens exactly the holes it is
                // there to close where one layer of voxels spans a sharp joint.
                let he = (hi - lo) * (0.5 * s.multiplier);
                let mid = (lo + hi) * 0.5;
                if !(he.is_finite() && mid.is_finite()) {
                    return scaled(bound(thesis_factor(&skin)));
                }
                DeformedNode {
                    center_world: mid,
                    half_axes_world: Mat3::from_diagonal(he),
                }
            }
            // The corners were skinned in world space; `linear` maps voxel to world, so `half`
            // is in voxels on both sides.
            (StretchStrategy::Adaptive, Some(cs)) => scaled(bound(
                containing_factor(&cs, half, center, linear)
                    .unwrap_or_else(|| thesis_factor(&skin)),
            )),
        }
    }
}

/// Longest column of a 3×3 matrix (the largest scale it applies to a voxel axis).
#[inline]
fn column_scale(m: Mat3) -> f32 {
    m.x_axis
        .length()
        .max(m.y_axis.length())
        .max(m.z_axis.length())
}

impl NodeDeform for SkinDeform<'_> {
    fn deform(&self, node: &NodeInfo<'_>) -> DeformedNode {
        let slot = self.memo_slot(node);
        let memo = &self.scratch.memo;
        if let Some(w) = self.scratch.get::<12>(memo, slot, 0) {
            return box_of_words(&w);
        }
        let (d, linear) = self.place(node);
        self.scratch
            .put(memo, slot, &node_words(&d, &normal_matrix(linear)));
        d
    }

    fn normal_to_world(&self, node: &NodeInfo<'_>, normal_voxel: Vec3) -> Vec3 {
        let linear = || {
            let skin = node.skin();
            Mat3::from_mat4(blend_matrix(
                &self.world_from_voxel,
                skin.joints_u16(),
                skin.blend_weights(),
            ))
        };
        // The node was placed this frame (it is on screen), so its normal matrix is in the
        // memo: one matrix–vector product per pixel instead of a blend and a cofactor.
        match self
            .scratch
            .get::<9>(&self.scratch.memo, self.memo_slot(node), 12)
        {
            Some(w) => normal_through(Mat3::from_cols_array(&w), linear, normal_voxel),
            None => transform_normal(linear(), normal_voxel),
        }
    }

    fn subtree_bounds(&self, node: &NodeInfo<'_>) -> Option<DeformedNode> {
        if node.svo.is_leaf(&node.node) {
            return None;
        }
        // Both traversals of a frame ask about most internal nodes.
        let memo = &self.scratch.bounds_memo;
        let slot = node.node.index as usize;
        if let Some(w) = self.scratch.get::<13>(memo, slot, 0) {
            return (w[12] != 0.0).then(|| box_of_words(&w));
        }
        let d = self.compute_subtree_bounds(node);
        self.scratch.put(memo, slot, &bounds_words(d.as_ref()));
        d
    }
}

impl SkinDeform<'_> {
    /// The memo slot of a node: leaf-pool indices first, then inner-pool indices.
    #[inline]
    fn memo_slot(&self, node: &NodeInfo<'_>) -> usize {
        if node.svo.is_leaf(&node.node) {
            node.node.index as usize
        } else {
            self.tables.leaf_corner_points.len() + node.node.index as usize
        }
    }

    /// [`NodeDeform::subtree_bounds`] without the memo.
    fn compute_subtree_bounds(&self, node: &NodeInfo<'_>) -> Option<DeformedNode> {
        if node.node.level + 1 == node.svo.depth() {
            return self.leaf_children_bounds(node);
        }
        let (joints, max_weights) = self.tables.subtree_joint_weights(node.node.index);
        if joints.is_empty() {
            return None;
        }
        let half = 0.5 * node.size_voxels() as f32;
        let c = Vec4::from((node.center_voxel(), 1.0));
        // Every point `p` of the subtree's bind box skins to a convex combination of `Mⱼ p`
        // over the subtree's joints (which include every corner weight's joint, see `walk`),
        // so the boxes `Mⱼ(node box)` bound every descendant's centre, every descendant's
        // skinned corner and every box drawn with factor 1 (the bind box under the blended
        // affine map). That hull is loose where a light weight ties the subtree to a joint
        // that moves far from the others, so a second bound uses the weights: with `r` the
        // heaviest joint, `Σ wⱼ Mⱼ p = M_r p + Σ_{j≠r} wⱼ (Mⱼ − M_r) p` with
        // `0 ≤ wⱼ ≤ w̄ⱼ` (the largest weight of `j` in the subtree). Both hold, so their
        // intersection does. Then a leaf drawn with factor `S > 1` reaches past its factor-1
        // box by `(S − 1) · ½ · |L|` per axis (`L = Σ w Mⱼ`, absolute rows); see
        // [`Self::leaf_stretch_bound`]. Larger descendants drawn at LOD are the traversal's
        // business (it knows their pixel size: `asvo::lod_margin`).
        let r = max_weights
            .iter()
            .enumerate()
            .max_by_key(|&(_, &w)| w)
            .map_or(0, |(i, _)| i);
        let m_r = *self.world_from_voxel.get(usize::from(joints[r]))?;
        let l_r = Mat3::from_mat4(m_r);
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        let r_centre = (m_r * c).truncate();
        let (mut wlo, mut whi) = (
            r_centre - abs_rows(l_r) * half,
            r_centre + abs_rows(l_r) * half,
        );
        // Largest absolute rows and column over the joints (bounds `|L|` of any blend).
        let mut rows_max = Vec3::ZERO;
        let mut column_max = 0.0f32;
        // How far a skinned corner may sit from the blended box's corner (see
        // `leaf_stretch_bound`), and how far any blend's linear part may be from `L_r`.
        let mut corner_drift = Vec3::ZERO;
        let mut linear_drift = 0.0f32;
        for (i, (&j, &w)) in joints.iter().zip(max_weights).enumerate() {
            let m = *self.world_from_voxel.get(usize::from(j))?;
            let linear = Mat3::from_mat4(m);
            let rows = abs_rows(linear);
            let centre = (m * c).truncate();
            lo = lo.min(centre - rows * half);
            hi = hi.max(centre + rows * half);
            rows_max = rows_max.max(rows);
            column_max = column_max.max(column_scale(linear));
            if i != r {
                let d = m - m_r;
                let dc = (d * c).truncate();
                let dh = abs_rows(Mat3::from_mat4(d)) * half;
                let w = f32::from(w) * (1.0 / 255.0);
                wlo += ((dc - dh) * w).min(Vec3::ZERO);
                whi += ((dc + dh) * w).max(Vec3::ZERO);
                corner_drift += (dc.abs() + dh) * w;
                linear_drift += w * frobenius(Mat3::from_mat4(d));
            }
        }
        lo = lo.max(wlo);
        hi = hi.min(whi);
        let stretch = self.leaf_stretch_bound(l_r, corner_drift.length(), linear_drift);
        let pad = if self.settings.strategy == StretchStrategy::Corners {
            // A `Corners` box is its corners' bounds, uncapped: they lie in `lo..hi` (each
            // corner is a blend of the joints above with at most their largest weights), and
            // the multiplier grows the box about its centre by at most `multiplier − 1` of
            // half that. Debug overrides draw `stretch` times the node instead.
            let grown =
                (hi - lo).max(Vec3::ZERO) * (0.5 * (self.settings.multiplier - 1.0).max(0.0));
            grown.max(rows_max.max(Vec3::splat(column_max)) * (0.5 * (stretch - 1.0).max(0.0)))
        } else {
            rows_max * (0.5 * (stretch - 1.0).max(0.0))
        };
        lo -= pad;
        hi += pad;
        (lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()).then(|| DeformedNode {
            center_world: (lo + hi) * 0.5,
            half_axes_world: Mat3::from_diagonal((hi - lo) * 0.5),
        })
    }
}

impl SkinDeform<'_> {
    /// The subtree bounds of a node whose children are leaves: the union of the leaves' drawn
    /// boxes and the node's centre, exactly. The joint bound of [`Self::compute_subtree_bounds`] holds for any
    /// subtree but is loose (the hull of the node's box under each of its joints, padded for
    /// stretch); here the leaves themselves are cheap to place (the memo keeps them for when
    /// they are drawn), and the tight box lets the traversals cull these nodes instead of
    /// their leaves one by one.
    fn leaf_children_bounds(&self, node: &NodeInfo<'_>) -> Option<DeformedNode> {
        // The node's own centre too: the bounds hold every descendant's centre, the node's
        // included (`Corners` centres a node's box on its corners, not its leaves).
        let own = self.deform(node).center_world;
        let mut lo = own;
        let mut hi = own;
        for k in 0..8 {
            if let Some(child) = node.svo.child(&node.node, k) {
                let d = self.deform(&NodeInfo {
                    svo: node.svo,
                    node: child,
                });
                let he = abs_rows(d.half_axes_world);
                lo = lo.min(d.center_world - he);
                hi = hi.max(d.center_world + he);
            }
        }
        (lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()).then(|| DeformedNode {
            center_world: (lo + hi) * 0.5,
            half_axes_world: Mat3::from_diagonal((hi - lo) * 0.5),
        })
    }

    /// The largest factor a leaf of a subtree may be drawn with (multiplier included), or for
    /// `Corners` the largest override factor (1 without overrides).
    ///
    /// `Adaptive` draws a leaf with the smallest factor whose box holds its eight corners
    /// skinned with their own weights, `f = maxₖ ‖L⁻¹ (pₖ − c)‖∞ / h` (`h = ½`). Corner `k`
    /// sits `δₖ = Σ_{j≠r} (wᵏⱼ − wⱼ)(Mⱼ − M_r) yₖ` from the blended box's corner (both weight
    /// sets sum to 1), so `|δₖ| ≤ corner_drift` (each `|wᵏⱼ − wⱼ| ≤ w̄ⱼ`), and
    /// `σ_min(L) ≥ σ_min(L_r) − Σ_{j≠r} w̄ⱼ ‖Mⱼ − M_r‖ =: σ`. Hence
    /// `f ≤ 1 + |δ| / (σ h)`. Where the blend may collapse (small `σ`) the bound is the
    /// strategy's clamp.
    fn leaf_stretch_bound(&self, l_r: Mat3, corner_drift: f32, linear_drift: f32) -> f32 {
        let s = &self.settings;
        let bound = |f: f32| f.clamp(s.min_factor, s.max_factor);
        let factor = match s.strategy {
            StretchStrategy::Off | StretchStrategy::Corners => 1.0,
            StretchStrategy::Thesis => bound(2.0),
            StretchStrategy::Adaptive => {
                // `σ_min(A) ≥ 1 / ‖A⁻¹‖_F`; `containing_factor` gives up (and the thesis
                // factor, at most 2, is used) only when `|det L| ≤ 1e-6 · scale³`, which
                // `σ > 0.02 · scale` rules out.
                let inv = l_r.inverse();
                let sigma = frobenius(inv).recip() - linear_drift;
                let scale = frobenius(l_r) + linear_drift;
                if sigma.is_finite() && sigma > 0.02 * scale {
                    // A relative margin for the rounding of `containing_factor`.
                    bound((1.0 + 2.0 * corner_drift / sigma) * (1.0 + 1e-4) + 1e-4)
                } else {
                    s.max_factor.max(bound(2.0))
                }
            }
        };
        let factor = if self.overrides.is_empty() {
            factor
        } else {
            factor.max(255.0 / 64.0)
        };
        if s.strategy == StretchStrategy::Corners {
            // The multiplier is applied by the caller, on the capped corner box.
            factor
        } else {
            factor * s.multiplier
        }
    }
}

/// Frobenius norm of a 3×3 matrix (an upper bound of its largest singular value).
#[inline]
fn frobenius(m: Mat3) -> f32 {
    (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared()).sqrt()
}

/// Half extents of the AABB of a parallelepiped with half-axes as columns.
#[inline]
fn abs_rows(axes: Mat3) -> Vec3 {
    Mat3::from_cols(axes.x_axis.abs(), axes.y_axis.abs(), axes.z_axis.abs()) * Vec3::ONE
}

#[cfg(test)]
mod lattice_key_tests {
    use super::*;

    #[test]
    fn lattice_keys_are_morton_codes_and_reach_the_far_corner_of_the_deepest_octree() {
        let far = 1u32 << crate::svo::MAX_DEPTH;
        for p in [
            UVec3::ZERO,
            UVec3::new(1, 0, 0),
            UVec3::new(5, 9, 3),
            UVec3::splat(far - 1),
            UVec3::new(far - 1, 7, 123_456),
        ] {
            assert_eq!(lattice_key(p), u128::from(crate::svo::morton_encode(p)));
            assert_eq!(lattice_point(lattice_key(p)), p);
        }
        // Lattice points of the deepest octree's last voxels lie one past its last coordinate:
        // distinct keys that round-trip and sort after every voxel's.
        for p in [
            UVec3::splat(far),
            UVec3::new(far, 0, 0),
            UVec3::new(0, far, far - 1),
        ] {
            assert_eq!(lattice_point(lattice_key(p)), p);
            assert!(lattice_key(p) > lattice_key(UVec3::splat(far - 1)) || p.x == 0);
        }
        assert_ne!(
            lattice_key(UVec3::new(far, 0, 0)),
            lattice_key(UVec3::new(0, 0, 0))
        );
    }
}

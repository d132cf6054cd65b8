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
//! bend. [`NodeDeform::subtree_bounds`] gives a box that provably does: every descendant point
//! skins to a convex combination of `Mⱼ p` over the joints `j` used in the subtree, so the union
//! of the node's bind box carried by each of those joints bounds the subtree. Frustum and
//! occlusion culling use it; LOD and splatting use the splat box.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use glam::{Mat3, Mat4, UVec3, Vec3, Vec4};

use super::lbs::{blend_matrix, skin_point, transform_normal};
use super::rig::{Rig, StretchOverrides};
use super::stretch::{
    StretchSettings, StretchStrategy, containing_factor, decode_override, thesis_factor,
};
use crate::render::{DeformedNode, NodeDeform, NodeInfo};
use crate::svo::{Skin4, Svo};

/// Derived per-octree data for skinned drawing: weights at every node's eight corners and the
/// joints used in every internal node's subtree. Built in one pass over the octree.
#[derive(Debug, Clone, Default)]
pub struct SkinTables {
    /// Corner weights per leaf-pool index (corners in `voxel_corners` order).
    leaf_corners: Vec<[Skin4; 8]>,
    /// Corner weights per inner-pool index.
    inner_corners: Vec<[Skin4; 8]>,
    /// Per inner-pool index: range into `joints`.
    inner_joint_range: Vec<(u32, u16)>,
    /// Sorted joint lists, concatenated.
    joints: Vec<u8>,
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
    let mut h = crc32fast::Hasher::new();
    for s in svo.leaf_skin().iter().chain(svo.inner_skin()) {
        h.update(&s.joints);
        h.update(&s.weights);
    }
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
        // Lattice point → merged weights of the leaves touching it.
        let mut lattice: HashMap<UVec3, Vec<Skin4>> = HashMap::new();
        svo.for_each_leaf(|c, v| {
            for k in 0..8u32 {
                let p = c + UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1);
                lattice.entry(p).or_default().push(v.skin);
            }
        });
        let merged: HashMap<UVec3, Skin4> = lattice
            .into_iter()
            .map(|(p, skins)| (p, Skin4::merge(&skins)))
            .collect();
        t.leaf_corners = vec![[Skin4::ROOT; 8]; svo.leaf_skin().len()];
        t.inner_corners = vec![[Skin4::ROOT; 8]; svo.inner_skin().len()];
        t.inner_joint_range = vec![(0, 0); svo.inner_skin().len()];
        // Post-order walk: children's joint sets are known before their parent's.
        walk(svo, svo.root(), &merged, &mut t);
        t
    }

    fn corners(&self, svo: &Svo, node: &crate::svo::NodeRef) -> Option<&[Skin4; 8]> {
        if svo.is_leaf(node) {
            self.leaf_corners.get(node.index as usize)
        } else {
            self.inner_corners.get(node.index as usize)
        }
    }

    /// Corner weights per leaf-pool index ([`super::stretch::voxel_corners`] order); empty for
    /// an octree without skin. For renderers that upload the tables (the GPU renderer).
    #[must_use]
    pub fn leaf_corner_skins(&self) -> &[[Skin4; 8]] {
        &self.leaf_corners
    }

    /// Corner weights per inner-pool index (as [`Self::leaf_corner_skins`]).
    #[must_use]
    pub fn inner_corner_skins(&self) -> &[[Skin4; 8]] {
        &self.inner_corners
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
}

/// Fills corner weights for `node`'s subtree and returns the joints it uses (sorted, unique).
fn walk(
    svo: &Svo,
    node: crate::svo::NodeRef,
    lattice: &HashMap<UVec3, Skin4>,
    t: &mut SkinTables,
) -> Vec<u8> {
    let size = svo.node_size(node.level);
    let own = svo.node_voxel(&node).skin;
    let corners: [Skin4; 8] = std::array::from_fn(|k| {
        let k = k as u32;
        let p = node.origin + UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1) * size;
        // An internal node's corner may touch no leaf (its subtree is sparse there): it then
        // moves with the node's own weights.
        lattice.get(&p).copied().unwrap_or(own)
    });
    if svo.is_leaf(&node) {
        if let Some(slot) = t.leaf_corners.get_mut(node.index as usize) {
            *slot = corners;
        }
        let mut j: Vec<u8> = own
            .influences()
            .map(|(j, _)| j as u8)
            .chain(
                corners
                    .iter()
                    .flat_map(|c| c.influences().map(|(j, _)| j as u8)),
            )
            .collect();
        j.sort_unstable();
        j.dedup();
        return j;
    }
    if let Some(slot) = t.inner_corners.get_mut(node.index as usize) {
        *slot = corners;
    }
    let mut joints: Vec<u8> = Vec::new();
    for k in 0..8 {
        if let Some(child) = svo.child(&node, k) {
            joints.extend(walk(svo, child, lattice, t));
        }
    }
    // The node's own corners too: a corner on the subtree's boundary merges leaves outside it,
    // and an uncapped `Corners` box of a descendant inner node follows those joints.
    joints.extend(
        std::iter::once(&own)
            .chain(corners.iter())
            .flat_map(|s| s.influences().map(|(j, _)| j as u8)),
    );
    joints.sort_unstable();
    joints.dedup();
    let start = t.joints.len() as u32;
    t.joints.extend_from_slice(&joints);
    if let Some(slot) = t.inner_joint_range.get_mut(node.index as usize) {
        *slot = (start, joints.len() as u16);
    }
    joints
}

/// Cache of [`SkinTables`] on a [`Rig`]: derived data, rebuilt when the octree's fingerprint
/// changes. Cloning gives an empty cache and every cache compares equal, so a document's
/// equality and undo snapshots ignore it.
#[derive(Default)]
pub struct TablesCache(Mutex<Option<Arc<SkinTables>>>);

impl TablesCache {
    /// The tables for `svo`, built on first use and after any change to it.
    pub fn get(&self, svo: &Svo) -> Arc<SkinTables> {
        let fp = fingerprint(svo);
        let mut slot = self
            .0
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
        let world_from_voxel = skinning
            .iter()
            .map(|s| world_from_object * *s * object_from_voxel)
            .collect();
        Self {
            world_from_voxel,
            settings: settings.sanitized(),
            overrides,
            tables,
        }
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
        Self::new(
            world_from_object,
            object_from_voxel,
            &rig.skinning_at(clip, time_secs),
            rig.stretch,
            &rig.stretch_overrides,
            rig.tables(svo),
        )
    }

    /// The same deformer with other stretch settings (for comparing strategies on one pose).
    #[must_use]
    pub fn with_settings(mut self, settings: StretchSettings) -> Self {
        self.settings = settings.sanitized();
        self
    }

    #[inline]
    fn skin_at(&self, skin: &Skin4, p: Vec3) -> Vec3 {
        skin_point(
            &self.world_from_voxel,
            skin.joints_u16(),
            skin.blend_weights(),
            p,
        )
    }

    /// The splat box of a node and the blended linear part used for its normal.
    #[inline]
    fn place(&self, node: &NodeInfo<'_>) -> DeformedNode {
        let skin = node.voxel().skin;
        let half = 0.5 * node.size_voxels() as f32;
        let c = node.center_voxel();
        let blended = blend_matrix(
            &self.world_from_voxel,
            skin.joints_u16(),
            skin.blend_weights(),
        );
        let center = blended.transform_point3(c);
        let linear = Mat3::from_mat4(blended);
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
        let corners = self.tables.corners(node.svo, &node.node);
        match (s.strategy, corners) {
            (StretchStrategy::Off, _) => scaled(1.0),
            (StretchStrategy::Thesis, _) | (_, None) => scaled(bound(thesis_factor(&skin))),
            (StretchStrategy::Corners, Some(cs)) => {
                let (lo, hi) = self.skinned_corner_bounds(c, half, cs);
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
            (StretchStrategy::Adaptive, Some(cs)) => scaled(bound(
                self.adaptive_factor(c, half, cs, center, linear, &skin),
            )),
        }
    }

    fn skinned_corner_bounds(&self, c: Vec3, half: f32, cs: &[Skin4; 8]) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for (k, skin) in cs.iter().enumerate() {
            let p = self.skin_at(skin, c + corner_offset(k) * half);
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (lo, hi)
    }

    /// [`containing_factor`] of a node this frame; the paper's `min(2, W)` when the blended
    /// frame has collapsed.
    fn adaptive_factor(
        &self,
        c: Vec3,
        half: f32,
        cs: &[Skin4; 8],
        center: Vec3,
        linear: Mat3,
        skin: &Skin4,
    ) -> f32 {
        let skinned: [Vec3; 8] =
            std::array::from_fn(|k| self.skin_at(&cs[k], c + corner_offset(k) * half));
        // The corners were skinned in world space; `linear` maps voxel to world, so `half` is
        // in voxels on both sides.
        containing_factor(&skinned, half, center, linear).unwrap_or_else(|| thesis_factor(skin))
    }
}

/// Sign pattern of corner `k` (x fastest): `(±1, ±1, ±1)`.
#[inline]
fn corner_offset(k: usize) -> Vec3 {
    let s = |bit: usize| if k & bit != 0 { 1.0 } else { -1.0 };
    Vec3::new(s(1), s(2), s(4))
}

impl NodeDeform for SkinDeform<'_> {
    fn deform(&self, node: &NodeInfo<'_>) -> DeformedNode {
        self.place(node)
    }

    fn normal_to_world(&self, node: &NodeInfo<'_>, normal_voxel: Vec3) -> Vec3 {
        let skin = node.voxel().skin;
        let m = blend_matrix(
            &self.world_from_voxel,
            skin.joints_u16(),
            skin.blend_weights(),
        );
        transform_normal(Mat3::from_mat4(m), normal_voxel)
    }

    fn subtree_bounds(&self, node: &NodeInfo<'_>) -> Option<DeformedNode> {
        if node.svo.is_leaf(&node.node) {
            return None;
        }
        let joints = self.tables.subtree_joints(node.node.index);
        if joints.is_empty() {
            return None;
        }
        let half = 0.5 * node.size_voxels() as f32;
        let c = Vec4::from((node.center_voxel(), 1.0));
        let splat = self.place(node);
        let splat_he = abs_rows(splat.half_axes_world);
        let mut lo = splat.center_world - splat_he;
        let mut hi = splat.center_world + splat_he;
        // A descendant's splat centre is a convex combination of `Mⱼ p` (p in the node's bind
        // box), so it lies in the hull of the boxes `Mⱼ(box)`. Its scalar-stretched extent is
        // at most `grow · h · |Σ w Mⱼ|` with `h <= half / 2` (a child or smaller) and
        // `grow` the largest factor any strategy or override may use; `Corners` boxes are
        // already inside the hull. Hence each joint's box is padded to `half · (1 + grow / 2)`.
        let largest_override = if self.overrides.is_empty() {
            0.0
        } else {
            255.0 / 64.0
        };
        let grow =
            self.settings.max_factor.max(1.0).max(largest_override) * self.settings.multiplier;
        let reach = half * (1.0 + 0.5 * grow);
        for &j in joints {
            let Some(m) = self.world_from_voxel.get(usize::from(j)) else {
                continue;
            };
            let centre = (*m * c).truncate();
            let he = abs_rows(Mat3::from_mat4(*m)) * reach;
            lo = lo.min(centre - he);
            hi = hi.max(centre + he);
        }
        (lo.is_finite() && hi.is_finite()).then(|| DeformedNode {
            center_world: (lo + hi) * 0.5,
            half_axes_world: Mat3::from_diagonal((hi - lo) * 0.5),
        })
    }
}

/// Half extents of the AABB of a parallelepiped with half-axes as columns.
#[inline]
fn abs_rows(axes: Mat3) -> Vec3 {
    Mat3::from_cols(axes.x_axis.abs(), axes.y_axis.abs(), axes.z_axis.abs()) * Vec3::ONE
}

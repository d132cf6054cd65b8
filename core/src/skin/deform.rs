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
use std::sync::{Arc, Mutex};

use glam::{Mat3, Mat4, UVec3, Vec3, Vec4};

use super::lbs::{blend_matrix, skin_point, transform_normal};
use super::rig::{Rig, StretchOverrides};
use super::stretch::{
    StretchSettings, StretchStrategy, containing_factor, decode_override, thesis_factor,
};
use crate::deform::{DeformedNode, NodeDeform, NodeInfo};
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

/// Sorts `(joint, weight)` pairs by joint and keeps each joint once, with its largest weight.
fn merge_max(v: &mut Vec<(u8, u8)>) {
    // By joint, the largest weight first: the first pair of each joint is the one kept.
    v.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(b.1.cmp(&a.1)));
    v.dedup_by_key(|p| p.0);
}

/// Fills corner weights for `node`'s subtree and returns the joints it uses with their largest
/// weights (sorted by joint, unique).
fn walk(
    svo: &Svo,
    node: crate::svo::NodeRef,
    lattice: &HashMap<UVec3, Skin4>,
    t: &mut SkinTables,
) -> Vec<(u8, u8)> {
    let size = svo.node_size(node.level);
    let own = svo.node_voxel(&node).skin;
    let corners: [Skin4; 8] = std::array::from_fn(|k| {
        let k = k as u32;
        let p = node.origin + UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1) * size;
        // An internal node's corner may touch no leaf (its subtree is sparse there): it then
        // moves with the node's own weights.
        lattice.get(&p).copied().unwrap_or(own)
    });
    // Own and corner weights: a node drawn at LOD by `Corners` is placed by its corners, and a
    // corner may touch leaves outside the subtree.
    let mut joints: Vec<(u8, u8)> = used_influences(&own)
        .chain(corners.iter().flat_map(used_influences))
        .collect();
    if svo.is_leaf(&node) {
        if let Some(slot) = t.leaf_corners.get_mut(node.index as usize) {
            *slot = corners;
        }
        merge_max(&mut joints);
        return joints;
    }
    if let Some(slot) = t.inner_corners.get_mut(node.index as usize) {
        *slot = corners;
    }
    for k in 0..8 {
        if let Some(child) = svo.child(&node, k) {
            joints.extend(walk(svo, child, lattice, t));
        }
    }
    merge_max(&mut joints);
    let start = t.joints.len() as u32;
    t.joints.extend(joints.iter().map(|&(j, _)| j));
    t.joint_max_weights.extend(joints.iter().map(|&(_, w)| w));
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

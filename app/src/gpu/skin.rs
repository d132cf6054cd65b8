//! Skinned voxel models on the GPU (ASVO paper §3.1, §3.3, §6, §8.1.3): what the traversal and
//! resolve passes need to place every node of a rigged model as the CPU reference's
//! `thicket_core::skin::SkinDeform` does.
//!
//! Two buffers, bound at group 0 slots 6 and 7 of both passes (`shaders/common/skin.wgsl`):
//!
//! * the skin data, built from the octree and its rig's derived tables and uploaded with the
//!   pools: per node its own weights (2 words), its eight corner weights (16 words; only under
//!   the `Corners` and `Adaptive` strategies, so switching to or from them rebuilds it), per
//!   inner node the joints used in its subtree (the culling box), per leaf the artist's
//!   stretch override byte;
//! * the joint matrices, `world_from_object · skinning[j] · object_from_voxel` per joint, the
//!   only upload when a pose, clip time or object transform changes.
//!
//! The per-object constants (offsets into the skin data, strategy, stretch settings) travel in
//! each dispatch's [`NodeParams::skin`](super::gpu_data::NodeParams) and the resolve's
//! [`ObjectInfo::skin`](super::gpu_data::ObjectInfo), rebuilt every frame (they are tiny).

use std::sync::Arc;

use glam::{Mat3, Mat4, Vec3};
use thicket_core::deform::{NodeDeform, NodeInfo};
use thicket_core::quality::Quality;
use thicket_core::scene::{Document, ObjectKind};
use thicket_core::skin::{Rig, Skin4, SkinDeform, SkinTables, StretchSettings, StretchStrategy};
use thicket_core::svo::{NodeRef, Svo};

use super::GpuError;
use super::gpu_data::{SKIN_HAS_CORNERS, SKIN_HAS_OVERRIDES, SkinParams, SkinStrategy};
use super::scene::{FrameObjects, SceneCache, UploadStats, object_of};

/// Bytes of one joint matrix.
const MATRIX_BYTES: u64 = 64;

/// A rigged object's place in the skin data (word offsets) and what it was built from.
#[derive(Clone)]
struct Layout {
    params: SkinParams,
    /// The rig's derived tables at build time (kept for the culling bounds).
    tables: Arc<SkinTables>,
    /// What the data depends on besides the pools (see [`signature`]).
    signature: (u32, u64, bool),
}

/// A rigged object as posed this frame: its skinning matrices, `world_from_object`,
/// `object_from_voxel` and effective stretch settings.
type Posed = (Vec<Mat4>, Mat4, Mat4, StretchSettings);

/// Skin data and joint matrices of the uploaded scene.
#[derive(Default)]
pub(super) struct SkinCache {
    /// Per entry of `SceneCache::voxels`: `None` for rigid objects.
    layouts: Vec<Option<Layout>>,
    /// Per pool chunk of the scene (`SceneCache::chunks`): the skin data of its rigged
    /// objects, whose offsets in `Layout::params` are local to their chunk's buffer.
    data_bufs: Vec<wgpu::Buffer>,
    joint_buf: Option<wgpu::Buffer>,
    /// The joint matrices last uploaded (to upload only on change).
    uploaded_joints: Vec<[f32; 16]>,
    /// World bounds of the rigged objects for `uploaded_joints` and the stretch settings.
    bounds: Option<(Vec3, Vec3)>,
    bounds_key: Vec<SkinParams>,
}

/// What one frame needs from [`SkinCache::prepare`].
pub(super) struct SkinFrame {
    /// Per entry of `SceneCache::voxels` (zeroed, strategy [`SkinStrategy::Rigid`], for rigid
    /// objects).
    pub(super) params: Vec<SkinParams>,
    /// The skin data per pool chunk (a small dummy for a chunk without rigged objects).
    pub(super) data_bufs: Vec<wgpu::Buffer>,
    /// The joint matrices (a small dummy when no object is rigged).
    pub(super) joint_buf: wgpu::Buffer,
    /// World bounds of the rigged objects as posed this frame.
    pub(super) bounds: Option<(Vec3, Vec3)>,
    /// What was uploaded.
    pub(super) upload: UploadStats,
}

fn strategy_code(s: StretchStrategy) -> u32 {
    match s {
        StretchStrategy::Off => SkinStrategy::Off,
        StretchStrategy::Thesis => SkinStrategy::Thesis,
        StretchStrategy::Corners => SkinStrategy::Corners,
        StretchStrategy::Adaptive => SkinStrategy::Adaptive,
    }
    .code()
}

fn skin_words(s: &Skin4) -> [u32; 2] {
    [u32::from_le_bytes(s.joints), u32::from_le_bytes(s.weights)]
}

fn rig_of(doc: &Document, id: u64) -> Option<(&Rig, &Svo, Mat4, Mat4)> {
    let o = object_of(doc, id)?;
    match &o.kind {
        ObjectKind::Voxels(v) => v
            .rig
            .as_ref()
            .map(|r| (r, &v.svo, o.transform.matrix(), v.object_from_voxel())),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
    }
}

/// The strategy a rig is drawn with: the quality's override (`Quality::stretch_strategy`) or
/// the rig's own, as `thicket_core::render::document_deforms` chooses.
fn strategy_of(rig: &Rig, quality: &Quality) -> StretchStrategy {
    thicket_core::render::effective_stretch(rig, quality).strategy
}

/// Whether the strategy reads corner weights (only `Corners` and `Adaptive` do: the others
/// skip 64 of the 72 bytes per node).
fn needs_corners(strategy: StretchStrategy) -> bool {
    matches!(
        strategy,
        StretchStrategy::Corners | StretchStrategy::Adaptive
    )
}

/// What the data depends on besides the pools (a change rebuilds it): joint count, the
/// overrides, whether corner weights are uploaded.
fn signature(rig: &Rig, quality: &Quality) -> (u32, u64, bool) {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    rig.stretch_overrides.entries().hash(&mut h);
    (
        rig.skeleton.joints.len() as u32,
        h.finish(),
        needs_corners(strategy_of(rig, quality)),
    )
}

/// Appends one rigged octree's sections to `data`; returns its parameters (offsets filled).
fn append_object(
    data: &mut Vec<u32>,
    svo: &Svo,
    rig: &Rig,
    tables: &SkinTables,
    quality: &Quality,
) -> SkinParams {
    let inner_len = svo.inner_masks().len();
    let leaf_len = svo.leaf_colors().len();
    let words = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    let mut p = SkinParams {
        strategy: SkinStrategy::Thesis.code(),
        ..SkinParams::default()
    };
    let node_skins = |data: &mut Vec<u32>, skins: &[Skin4], len: usize| {
        for i in 0..len {
            data.extend(skin_words(&skins.get(i).copied().unwrap_or_default()));
        }
    };
    p.inner_skin = words(data.len());
    node_skins(data, svo.inner_skin(), inner_len);
    p.leaf_skin = words(data.len());
    node_skins(data, svo.leaf_skin(), leaf_len);
    // The CPU uses corner weights only where the tables have them (an octree with skin), and
    // only the strategies that read them need them here.
    if needs_corners(strategy_of(rig, quality))
        && tables.inner_count() >= inner_len
        && tables.leaf_count() >= leaf_len
        && (inner_len + leaf_len) > 0
    {
        p.flags |= SKIN_HAS_CORNERS;
        let corners = |data: &mut Vec<u32>, of: &dyn Fn(u32) -> Option<[Skin4; 8]>, len: usize| {
            for i in 0..len {
                for s in &of(i as u32).unwrap_or_default() {
                    data.extend(skin_words(s));
                }
            }
        };
        p.inner_corners = words(data.len());
        corners(data, &|i| tables.inner_corner_skins(i), inner_len);
        p.leaf_corners = words(data.len());
        corners(data, &|i| tables.leaf_corner_skins(i), leaf_len);
    }
    let mut list: Vec<u32> = Vec::new();
    p.subtree_ranges = words(data.len());
    for i in 0..inner_len {
        let j = tables.subtree_joints(i as u32);
        data.extend([words(list.len()), words(j.len())]);
        list.extend(j.iter().map(|&j| u32::from(j)));
    }
    p.subtree_joints = words(data.len());
    data.extend(list);
    if !rig.stretch_overrides.is_empty() && leaf_len > 0 {
        p.flags |= SKIN_HAS_OVERRIDES;
        p.overrides = words(data.len());
        let mut bytes = vec![0u8; leaf_len.next_multiple_of(4)];
        if !svo.is_empty() {
            let mut stack: Vec<NodeRef> = vec![svo.root()];
            while let Some(n) = stack.pop() {
                if svo.is_leaf(&n) {
                    if let Some(b) = bytes.get_mut(n.index as usize) {
                        *b = rig.stretch_overrides.get(n.origin);
                    }
                    continue;
                }
                if svo.is_tile(&n) {
                    // Interior voxels (`Svo::tiles_value`): never drawn, no leaf slot.
                    continue;
                }
                stack.extend((0..8).filter_map(|k| svo.child(&n, k)));
            }
        }
        data.extend(
            bytes
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])),
        );
    }
    p
}

impl SkinCache {
    /// Forgets the skin data (the scene was uploaded again).
    pub(super) fn invalidate(&mut self) {
        *self = Self::default();
    }

    /// Makes the skin data follow `scene` (rebuilt when the pools were rewritten or a rig's
    /// joints or overrides changed), uploads the joint matrices when they changed, and returns
    /// the frame's per-object constants.
    pub(super) fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        scene: &mut SceneCache,
        quality: &Quality,
    ) -> Result<SkinFrame, GpuError> {
        let mut upload = UploadStats::default();
        let stale = scene.skin_stale
            || self.data_bufs.len() != scene.chunks.len()
            || self.layouts.len() != scene.voxels.len()
            || scene.voxels.iter().zip(&self.layouts).any(|(e, l)| {
                match (rig_of(doc, e.object_id), l) {
                    (None, None) => false,
                    (Some((rig, ..)), Some(l)) => signature(rig, quality) != l.signature,
                    _ => true,
                }
            });
        if stale {
            self.rebuild_data(device, doc, scene, quality, &mut upload)?;
        }

        // Joint matrices and per-object constants for this frame's poses and settings.
        let mut joints: Vec<[f32; 16]> = Vec::new();
        let mut params = Vec::with_capacity(scene.voxels.len());
        let mut skinning_of = Vec::with_capacity(scene.voxels.len());
        for (e, l) in scene.voxels.iter().zip(&self.layouts) {
            let (Some(l), Some((rig, _, world_from_object, object_from_voxel))) =
                (l, rig_of(doc, e.object_id))
            else {
                params.push(SkinParams::default());
                skinning_of.push(None);
                continue;
            };
            // As `thicket_core::render::document_deforms`: the rig's settings, the multiplier
            // scaled by the quality's, the quality's strategy override, sanitised as
            // `SkinDeform` does.
            let stretch = thicket_core::render::effective_stretch(rig, quality);
            let s = stretch.sanitized();
            let skinning = rig.skinning_at(rig.playback.clip, rig.playback.time_secs);
            let base = joints.len() as u32;
            joints.extend(
                skinning
                    .iter()
                    .map(|m| (world_from_object * *m * object_from_voxel).to_cols_array()),
            );
            let largest_override = if rig.stretch_overrides.is_empty() {
                0.0
            } else {
                255.0 / 64.0
            };
            params.push(SkinParams {
                joint_base: base,
                joint_count: skinning.len() as u32,
                strategy: strategy_code(s.strategy),
                multiplier: s.multiplier,
                min_factor: s.min_factor,
                max_factor: s.max_factor,
                grow: s.max_factor.max(1.0).max(largest_override) * s.multiplier,
                ..l.params
            });
            skinning_of.push(Some((
                skinning,
                world_from_object,
                object_from_voxel,
                stretch,
            )));
        }
        let joints_changed = joints != self.uploaded_joints || self.joint_buf.is_none();
        if joints_changed {
            self.upload_joints(device, queue, joints, &mut upload);
        }
        if joints_changed || self.bounds_key != params {
            self.update_bounds(doc, scene, &skinning_of, &params);
        }

        let data_bufs = self.data_bufs.clone();
        let joint_buf = self
            .joint_buf
            .clone()
            .ok_or_else(|| GpuError::Device("joint buffer missing".into()))?;
        Ok(SkinFrame {
            params,
            data_bufs,
            joint_buf,
            bounds: self.bounds,
            upload,
        })
    }

    /// Rebuilds the skin data of every rigged object, one buffer per pool chunk (the skin
    /// data follows the pools' split).
    fn rebuild_data(
        &mut self,
        device: &wgpu::Device,
        doc: &Document,
        scene: &mut SceneCache,
        quality: &Quality,
        upload: &mut UploadStats,
    ) -> Result<(), GpuError> {
        let mut data: Vec<Vec<u32>> = vec![Vec::new(); scene.chunks.len()];
        let mut layouts = Vec::with_capacity(scene.voxels.len());
        for e in &scene.voxels {
            let Some(chunk_data) = data.get_mut(e.chunk) else {
                return Err(GpuError::Device(
                    "voxel object outside the pool chunks".into(),
                ));
            };
            layouts.push(rig_of(doc, e.object_id).map(|(rig, svo, ..)| {
                let tables = rig.tables(svo);
                let params = append_object(chunk_data, svo, rig, &tables, quality);
                Layout {
                    params,
                    tables,
                    signature: signature(rig, quality),
                }
            }));
        }
        let limit = device.limits().max_storage_buffer_binding_size;
        let mut bytes = 0;
        for d in &data {
            let b = d.len() as u64 * 4;
            if b > limit {
                return Err(GpuError::TooLarge {
                    what: "skin data (of one pool chunk)",
                    bytes: b,
                    limit,
                });
            }
            bytes += b;
        }
        self.data_bufs = data
            .iter()
            .map(|d| super::scene::storage_init(device, "skin data", bytemuck::cast_slice(d)))
            .collect();
        self.layouts = layouts;
        self.uploaded_joints.clear();
        self.bounds_key.clear();
        scene.skin_stale = false;
        if self.layouts.iter().any(Option::is_some) {
            upload.bytes += bytes;
            upload.writes += 1;
            upload.skin_data = true;
        }
        Ok(())
    }

    /// Uploads this frame's joint matrices (into the joint buffer when they fit, else a new
    /// one).
    fn upload_joints(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        joints: Vec<[f32; 16]>,
        upload: &mut UploadStats,
    ) {
        let bytes = joints.len() as u64 * MATRIX_BYTES;
        let fits = self.joint_buf.as_ref().is_some_and(|b| b.size() >= bytes);
        if fits {
            if let Some(b) = &self.joint_buf
                && !joints.is_empty()
            {
                queue.write_buffer(b, 0, bytemuck::cast_slice(&joints));
            }
        } else {
            self.joint_buf = Some(super::scene::storage_init(
                device,
                "joints",
                bytemuck::cast_slice(&joints),
            ));
        }
        if !joints.is_empty() {
            upload.bytes += bytes;
            upload.joint_bytes += bytes;
            upload.writes += 1;
        }
        self.uploaded_joints = joints;
    }

    /// Bounds of the posed models (shadow map fit, ambient-occlusion radius), as the CPU's
    /// `voxel_bounds`, for this frame's poses (`skinning_of`, per entry of
    /// `SceneCache::voxels`) and settings (`params`).
    fn update_bounds(
        &mut self,
        doc: &Document,
        scene: &SceneCache,
        skinning_of: &[Option<Posed>],
        params: &[SkinParams],
    ) {
        let mut bounds: Option<(Vec3, Vec3)> = None;
        for ((e, l), sk) in scene.voxels.iter().zip(&self.layouts).zip(skinning_of) {
            let (Some(l), Some((skinning, w, o, stretch))) = (l, sk) else {
                continue;
            };
            let Some((rig, svo, ..)) = rig_of(doc, e.object_id) else {
                continue;
            };
            let deform = SkinDeform::new(
                *w,
                *o,
                skinning,
                *stretch,
                &rig.stretch_overrides,
                Arc::clone(&l.tables),
            );
            posed_bounds(svo, &deform, &mut bounds);
        }
        self.bounds = bounds;
        self.bounds_key.clear();
        self.bounds_key.extend_from_slice(params);
    }
}

/// World AABB of a skinned octree from its nodes a few levels down, with the culling box where
/// the deformer has one (the CPU reference's `voxel_bounds`).
fn posed_bounds(svo: &Svo, deform: &SkinDeform<'_>, out: &mut Option<(Vec3, Vec3)>) {
    if svo.is_empty() {
        return;
    }
    let stop = svo.depth().min(5);
    let mut stack = vec![svo.root()];
    while let Some(n) = stack.pop() {
        if n.level < stop {
            stack.extend((0..8).filter_map(|k| svo.child(&n, k)));
            continue;
        }
        let info = NodeInfo { svo, node: n };
        // The node's own box joined with its subtree box (which bounds the leaves only).
        for d in std::iter::once(deform.deform(&info)).chain(deform.subtree_bounds(&info)) {
            let a = d.half_axes_world;
            let he = Mat3::from_cols(a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs()) * Vec3::ONE;
            let (lo, hi) = (d.center_world - he, d.center_world + he);
            *out = Some(out.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
        }
    }
}

impl SkinFrame {
    /// Gives the resolve pass each rigged object's skinning constants (its normals turn with
    /// the node's blended matrix) and adds the posed bounds to the frame's.
    pub(super) fn apply(&self, scene: &SceneCache, frame: &mut FrameObjects) {
        for ((o, p), e) in frame
            .objects
            .iter_mut()
            .zip(&self.params)
            .zip(&scene.voxels)
        {
            if p.strategy != SkinStrategy::Rigid.code() {
                o.skin_attr = [1, e.attr_inner_base, e.attr_leaf_base, 0];
                o.skin = *p;
            }
        }
        if let Some((lo, hi)) = self.bounds {
            frame.bounds = Some(
                frame
                    .bounds
                    .map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))),
            );
        }
    }
}

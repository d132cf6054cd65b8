//! The skin of a voxel model as the document stores it: skeleton, animation clips, what is
//! playing and when, manual pose overrides, stretch settings and per-voxel stretch overrides.
//!
//! A [`Rig`] hangs off [`crate::scene::VoxelModel::rig`]. The octree's leaves carry
//! [`Skin4`](crate::svo::Skin4) weights whose joint indices point into [`Rig::skeleton`]; the
//! model's voxel space maps to the skeleton's *bind-pose mesh space* through
//! `VoxelModel::object_from_voxel`, and skinning maps that to the skinned object space (the
//! object's transform then places it in the world).
//!
//! In a project file the small parts (skeleton, playback, overrides, settings) are JSON; the clips'
//! key arrays and the per-voxel overrides are a checksummed binary payload in the `.bin`
//! (see `io::project`).

use glam::{Mat4, UVec3};
use serde::{Deserialize, Serialize};

use super::SkinError;
use super::clip::{AnimationClip, Wrap};
use super::deform::{SkinTables, TablesCache};
use super::skeleton::{JointMatrices, JointOverride, Pose, Skeleton};
use super::stretch::StretchSettings;
use crate::svo::{MAX_SKIN_JOINTS, morton_decode, morton_encode};

/// Which clip plays and where the playhead is.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Playback {
    /// Index into [`Rig::clips`]; `None` shows the rest (bind) pose plus overrides.
    pub clip: Option<usize>,
    /// Playhead in seconds.
    pub time_secs: f32,
    /// How times past the clip's end map into it (a walk cycle loops).
    pub wrap: Wrap,
}

impl Default for Playback {
    fn default() -> Self {
        Self {
            clip: None,
            time_secs: 0.0,
            wrap: Wrap::Loop,
        }
    }
}

/// Per-voxel stretch-factor overrides painted by an artist (paper §8.1.3: "manually refined and
/// stored per voxel"): leaf coordinate → override byte (see
/// [`super::stretch::decode_override`]). Sparse and sorted by Morton code, so a lookup is a
/// binary search and the data survives octree edits (an override on a removed voxel is simply
/// never looked up). Internal nodes drawn for LOD use the strategy's factor.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StretchOverrides {
    /// `(morton code of the leaf, override byte 1..=255)`, strictly increasing codes.
    entries: Vec<(u64, u8)>,
}

impl StretchOverrides {
    /// From `(morton code, byte)` pairs as stored in a file.
    ///
    /// # Errors
    /// A description of the first entry out of order, duplicated or with byte 0.
    pub fn from_sorted(entries: Vec<(u64, u8)>) -> Result<Self, String> {
        if let Some(i) = entries.iter().position(|e| e.1 == 0) {
            return Err(format!(
                "stretch override {i} has byte 0 (means no override)"
            ));
        }
        if let Some(i) = entries.windows(2).position(|w| w[1].0 <= w[0].0) {
            return Err(format!(
                "stretch override {} is out of order or duplicated (code {})",
                i + 1,
                entries[i + 1].0
            ));
        }
        Ok(Self { entries })
    }

    /// The override byte of the leaf at `coord` (0: none).
    #[inline]
    #[must_use]
    pub fn get(&self, coord: UVec3) -> u8 {
        if self.entries.is_empty() {
            return 0;
        }
        let code = morton_encode(coord);
        self.entries
            .binary_search_by_key(&code, |e| e.0)
            .map_or(0, |i| self.entries[i].1)
    }

    /// Sets (or with byte 0 clears) the override of the leaf at `coord`; returns the old byte.
    pub fn set(&mut self, coord: UVec3, code: u8) -> u8 {
        let key = morton_encode(coord);
        match self.entries.binary_search_by_key(&key, |e| e.0) {
            Ok(i) => {
                let old = self.entries[i].1;
                if code == 0 {
                    self.entries.remove(i);
                } else {
                    self.entries[i].1 = code;
                }
                old
            }
            Err(i) => {
                if code != 0 {
                    self.entries.insert(i, (key, code));
                }
                0
            }
        }
    }

    /// Number of voxels with an override.
    #[must_use]
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when no voxel has an override.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// `(leaf coordinate, byte)` in Morton order.
    pub fn iter(&self) -> impl Iterator<Item = (UVec3, u8)> + '_ {
        self.entries.iter().map(|&(c, b)| (morton_decode(c), b))
    }

    /// The raw `(morton code, byte)` entries (for the file format).
    #[must_use]
    pub fn entries(&self) -> &[(u64, u8)] {
        &self.entries
    }
}

/// What a native rig's weights were computed from (see [`Rig::binding`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Binding {
    /// How the weights were computed.
    pub method: crate::skin::bind::BindMethod,
    /// The skeleton they were computed for.
    pub skeleton: crate::skin::author::SkeletonSpec,
}

impl Rig {
    /// Whether the weights were computed for another skeleton than this one (joints moved,
    /// added, removed or renamed since [`Rig::binding`] was set). Imported weights are never
    /// stale.
    #[must_use]
    pub fn weights_stale(&self) -> bool {
        self.binding.as_ref().is_some_and(|b| {
            b.skeleton != crate::skin::author::SkeletonSpec::of_skeleton(&self.skeleton)
        })
    }
}

/// A voxel model's skeleton, clips and animation state (see the module docs).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Rig {
    /// Joints in topological order; [`Skin4`](crate::svo::Skin4) joint bytes index it, so it
    /// has at most [`MAX_SKIN_JOINTS`] joints.
    pub skeleton: Skeleton,
    /// Animation clips over [`Rig::skeleton`] (stored in the project's `.bin`).
    #[serde(skip)]
    pub clips: Vec<AnimationClip>,
    /// What plays and when.
    pub playback: Playback,
    /// Manual posing on top of the clip (or the rest pose), applied in order.
    pub pose_overrides: Vec<JointOverride>,
    /// How skinned voxels are enlarged to close holes.
    pub stretch: StretchSettings,
    /// Per-voxel stretch overrides (stored in the project's `.bin`).
    #[serde(skip)]
    pub stretch_overrides: StretchOverrides,
    /// The source triangle mesh in its bind pose (geometry, joints and weights; materials
    /// without textures), kept so holes and bloat can be measured against the same pose and an
    /// editor can overlay it. Stored in the project's `.bin`; `None` when unknown.
    #[serde(skip)]
    pub reference_mesh: Option<crate::mesh::MeshModel>,
    /// The skeleton (as joint positions) and method the voxels' weights were last computed
    /// for by [`crate::skin::bind()`]; `None` for imported weights or a skeleton never bound.
    /// An editor compares it with [`Rig::skeleton`] to tell the artist the weights are stale.
    pub binding: Option<Binding>,
    /// Derived drawing tables (corner weights, subtree joints), rebuilt when the octree
    /// changes; never saved, ignored by equality, empty in a clone.
    #[serde(skip)]
    pub tables: TablesCache,
}

impl Rig {
    /// A rig in the rest pose with default stretch settings, playing the first clip if any.
    #[must_use]
    pub fn new(skeleton: Skeleton, clips: Vec<AnimationClip>) -> Self {
        let playback = Playback {
            clip: (!clips.is_empty()).then_some(0),
            ..Playback::default()
        };
        Self {
            skeleton,
            clips,
            playback,
            ..Self::default()
        }
    }

    /// Checks everything a renderer or the sampler relies on: a valid skeleton of at most
    /// [`MAX_SKIN_JOINTS`] joints, valid clips, a playback clip that exists and a finite time,
    /// overrides on existing joints with finite values, and valid stretch settings.
    ///
    /// # Errors
    /// The first problem, naming the joint, clip, channel or setting.
    pub fn validate(&self) -> Result<(), SkinError> {
        let rig = |problem: String| SkinError::Rig { problem };
        let n = self.skeleton.len();
        if n > MAX_SKIN_JOINTS {
            return Err(rig(format!(
                "the skeleton has {n} joints; a skinned voxel model addresses at most \
                 {MAX_SKIN_JOINTS} (one byte per joint index)"
            )));
        }
        self.skeleton.validate()?;
        for c in &self.clips {
            c.validate(n)?;
        }
        if let Some(m) = &self.reference_mesh {
            m.validate()
                .map_err(|(part, e)| rig(format!("reference mesh part {part}: {e}")))?;
            let bad_joint = m
                .parts
                .iter()
                .flat_map(|p| &p.joints)
                .flatten()
                .find(|&&j| usize::from(j) >= n);
            if let Some(j) = bad_joint {
                return Err(rig(format!(
                    "reference mesh uses joint {j} but the skeleton has {n}"
                )));
            }
        }
        if let Some(c) = self.playback.clip
            && c >= self.clips.len()
        {
            return Err(rig(format!(
                "playback.clip {c} does not exist (the model has {} clip(s))",
                self.clips.len()
            )));
        }
        if !self.playback.time_secs.is_finite() {
            return Err(rig(format!(
                "playback.time_secs {} is not finite",
                self.playback.time_secs
            )));
        }
        for (i, o) in self.pose_overrides.iter().enumerate() {
            if o.joint >= n {
                return Err(rig(format!(
                    "pose override {i} targets joint {} but the skeleton has {n}",
                    o.joint
                )));
            }
            let finite = o.rotation.is_none_or(glam::Quat::is_finite)
                && o.translation.is_none_or(glam::Vec3::is_finite)
                && o.scale.is_none_or(glam::Vec3::is_finite);
            if !finite {
                return Err(rig(format!("pose override {i} has a non-finite value")));
            }
        }
        self.stretch
            .validate()
            .map_err(|e| rig(format!("stretch: {e}")))?;
        Ok(())
    }

    /// The drawing tables for `svo` (this rig's octree), from the cache.
    #[must_use]
    pub fn tables(&self, svo: &crate::svo::Svo) -> std::sync::Arc<SkinTables> {
        self.tables.get(svo)
    }

    /// Index of the clip with this name.
    #[must_use]
    pub fn clip_index(&self, name: &str) -> Option<usize> {
        self.clips.iter().position(|c| c.name == name)
    }

    /// The pose at `time_secs` of `clip` (`None`: the rest pose) with the manual overrides on
    /// top, written into `out`. A clip index out of range counts as `None`.
    pub fn pose_into(&self, clip: Option<usize>, time_secs: f32, out: &mut Pose) {
        match clip.and_then(|c| self.clips.get(c)) {
            Some(c) => c.sample_into(time_secs, self.playback.wrap, &self.skeleton, out),
            None => out.reset_to_rest(&self.skeleton),
        }
        // Validated rigs have no bad overrides; unvalidated ones are skipped, not applied.
        let _skipped = out.apply_overrides(&self.pose_overrides);
    }

    /// The pose the document shows: [`Rig::playback`]'s clip and time, plus overrides.
    #[must_use]
    pub fn current_pose(&self) -> Pose {
        let mut pose = Pose::default();
        self.pose_into(self.playback.clip, self.playback.time_secs, &mut pose);
        pose
    }

    /// Skinning matrices (`skinned_from_bind` per joint) at `time_secs` of `clip`.
    #[must_use]
    pub fn skinning_at(&self, clip: Option<usize>, time_secs: f32) -> Vec<Mat4> {
        let mut pose = Pose::default();
        let mut m = JointMatrices::default();
        self.skinning_into(clip, time_secs, &mut pose, &mut m);
        m.skinning
    }

    /// [`Rig::skinning_at`] into kept buffers: the pose sampled into `pose`, the matrices into
    /// `out` (`out.skinning` is the result). Allocates only while the buffers grow.
    pub fn skinning_into(
        &self,
        clip: Option<usize>,
        time_secs: f32,
        pose: &mut Pose,
        out: &mut JointMatrices,
    ) {
        self.pose_into(clip, time_secs, pose);
        self.skeleton.compute_matrices(pose, out);
    }

    /// Skinning matrices for the document's current playback state.
    #[must_use]
    pub fn current_skinning(&self) -> Vec<Mat4> {
        self.skinning_at(self.playback.clip, self.playback.time_secs)
    }
}

/// Object-space bounds of a skinned octree under `skinning`: the centres of the nodes
/// `min(depth, 7)` levels down (leaves of shallower trees), skinned with their merged weights
/// and padded by each node's half diagonal. Cheap (about 4⁷ surface nodes at most for a
/// surface model) and meant for framing cameras and fitting shadow maps, not for culling.
#[must_use]
pub fn posed_bounds(
    svo: &crate::svo::Svo,
    object_from_voxel: Mat4,
    skinning: &[Mat4],
) -> Option<(glam::Vec3, glam::Vec3)> {
    use glam::Vec3;
    if svo.is_empty() {
        return None;
    }
    let stop = svo.depth().min(7);
    let scale = object_from_voxel.x_axis.truncate().length();
    let mut out: Option<(Vec3, Vec3)> = None;
    let mut stack = vec![svo.root()];
    while let Some(n) = stack.pop() {
        if n.level < stop && !svo.is_leaf(&n) {
            stack.extend((0..8).filter_map(|k| svo.child(&n, k)));
            continue;
        }
        let size = svo.node_size(n.level) as f32;
        let center_voxel = n.origin.as_vec3() + Vec3::splat(0.5 * size);
        let bind = object_from_voxel.transform_point3(center_voxel);
        let skin = svo.node_voxel(&n).skin;
        let p = super::lbs::skin_point(skinning, skin.joints_u16(), skin.blend_weights(), bind);
        if !p.is_finite() {
            continue;
        }
        let pad = Vec3::splat(0.5 * size * scale * 3f32.sqrt());
        let (lo, hi) = (p - pad, p + pad);
        out = Some(out.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
    }
    out
}

/// Checks that every weighted joint of every node (leaf and internal) exists in a skeleton of
/// `joint_count` joints: a weight on a missing joint would silently drop out of the blend and
/// pull the voxel toward the origin. Run once on load and import, not per frame.
///
/// # Errors
/// [`SkinError::Rig`] naming the first bad voxel (leaf coordinate) and joint.
pub fn check_weights(svo: &crate::svo::Svo, joint_count: usize) -> Result<(), SkinError> {
    let bad = |s: &crate::svo::Skin4| {
        (0..4).find(|&k| s.weights[k] > 0 && usize::from(s.joints[k]) >= joint_count)
    };
    // The raw pools hold every live node's weights (and those of freed slots): when no entry
    // is bad, no node is, and the octree walk below (which names the voxel) is not needed.
    // That keeps the check at about 1 % of a rigged project's load instead of 13 %.
    if !svo
        .leaf_skin()
        .iter()
        .chain(svo.inner_skin())
        .any(|s| bad(s).is_some())
    {
        return Ok(());
    }
    let mut first: Option<(UVec3, u8)> = None;
    svo.for_each_leaf(|c, v| {
        if first.is_none()
            && let Some(k) = bad(&v.skin)
        {
            first = Some((c, v.skin.joints[k]));
        }
    });
    match first {
        Some((c, j)) => Err(SkinError::Rig {
            problem: format!(
                "voxel {c} is weighted to joint {j} but the skeleton has {joint_count} joints"
            ),
        }),
        None => {
            if let Some(s) = svo.inner_skin().iter().find(|s| bad(s).is_some()) {
                return Err(SkinError::Rig {
                    problem: format!(
                        "an internal node's merged weights use joint {:?} but the skeleton has {joint_count} joints",
                        s.joints
                    ),
                });
            }
            Ok(())
        }
    }
}

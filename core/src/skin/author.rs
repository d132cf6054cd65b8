//! Rigs authored for a voxel model made in Thicket: a skeleton from joint positions, and clips
//! from keys given as Euler angles relative to the rest pose (the `thicket rig` and
//! `thicket animate` formats, documented in `docs/skinning.md`).
//!
//! A native skeleton is placed in the model's own space (the space `VoxelModel::bounds`
//! reports, before the object's transform): each joint's rest frame is a pure translation to its
//! position, so its inverse bind matrix is the inverse translation and the rest pose skins every
//! voxel to where it already is.

use std::collections::HashMap;

use glam::{EulerRot, Mat4, Quat, Vec3, Vec4};
use serde::{Deserialize, Serialize};

use super::SkinError;
use super::clip::{AnimationClip, Channel, Interpolation, Property, Wrap};
use super::skeleton::{Joint, Skeleton, Transform};
use crate::svo::MAX_SKIN_JOINTS;

/// One joint of a [`SkeletonSpec`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    /// Unique name (`.L` / `.R` suffixes for mirrored chains).
    pub name: String,
    /// The parent joint's name; `null` for a root.
    pub parent: Option<String>,
    /// Where the joint is, in the model's own space.
    pub position: [f32; 3],
}

/// A skeleton as an artist or a script writes it: named joints at positions.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SkeletonSpec {
    /// The joints, in any order (parents need not come first).
    pub joints: Vec<JointSpec>,
}

/// How far outside the model's bounds a joint may stand, as a fraction of the bounds' largest
/// side. A joint beyond it is almost always a unit mistake (voxels instead of model units).
pub const JOINT_OUTSIDE_LIMIT: f32 = 0.5;

impl SkeletonSpec {
    /// The skeleton this spec describes, parents first. `bounds` (the model's own-space bounds)
    /// refuses joints far outside the model ([`JOINT_OUTSIDE_LIMIT`]).
    ///
    /// # Errors
    /// [`SkinError::Rig`] naming the joint: no joints, more than [`MAX_SKIN_JOINTS`], an empty
    /// or duplicate name, an unknown parent, a parent cycle, a non-finite position, or a joint
    /// far outside the model.
    pub fn to_skeleton(&self, bounds: Option<(Vec3, Vec3)>) -> Result<Skeleton, SkinError> {
        let rig = |problem: String| SkinError::Rig { problem };
        let n = self.joints.len();
        if n == 0 {
            return Err(rig("the skeleton has no joints".into()));
        }
        if n > MAX_SKIN_JOINTS {
            return Err(rig(format!(
                "the skeleton has {n} joints; a skinned voxel model (and its glTF export) carries \
                 at most {MAX_SKIN_JOINTS}"
            )));
        }
        let mut index: HashMap<&str, usize> = HashMap::with_capacity(n);
        for (i, j) in self.joints.iter().enumerate() {
            if j.name.trim().is_empty() {
                return Err(rig(format!("joint {i} has an empty name")));
            }
            if index.insert(j.name.as_str(), i).is_some() {
                return Err(rig(format!("joint {:?} is named twice", j.name)));
            }
            if !j.position.iter().all(|v| v.is_finite()) {
                return Err(rig(format!(
                    "joint {:?} has a non-finite position {:?}",
                    j.name, j.position
                )));
            }
        }
        if let Some((lo, hi)) = bounds {
            let reach = (hi - lo).max_element() * JOINT_OUTSIDE_LIMIT;
            for j in &self.joints {
                let p = Vec3::from(j.position);
                let outside = (lo - p).max(p - hi).max(Vec3::ZERO).length();
                if outside > reach {
                    return Err(rig(format!(
                        "joint {:?} at {:?} is {outside:.3} outside the model's bounds \
                         {:?}..{:?} (more than half the model's size: positions are in the \
                         model's own units, as `thicket info` reports its bounds)",
                        j.name,
                        j.position,
                        lo.to_array(),
                        hi.to_array()
                    )));
                }
            }
        }
        let mut parents = Vec::with_capacity(n);
        for j in &self.joints {
            let parent = match &j.parent {
                None => None,
                Some(p) => Some(*index.get(p.as_str()).ok_or_else(|| {
                    rig(format!(
                        "joint {:?} names parent {p:?}, which is not a joint",
                        j.name
                    ))
                })?),
            };
            parents.push(parent);
        }
        let joints: Vec<Joint> = self
            .joints
            .iter()
            .zip(&parents)
            .map(|(j, &parent)| {
                let p = Vec3::from(j.position);
                let parent_p = parent.map_or(Vec3::ZERO, |k| Vec3::from(self.joints[k].position));
                Joint {
                    name: j.name.clone(),
                    parent,
                    rest: Transform {
                        translation: p - parent_p,
                        ..Transform::IDENTITY
                    },
                    inverse_bind: Mat4::from_translation(-p),
                    parent_from_attachment: Mat4::IDENTITY,
                }
            })
            .collect();
        let (skeleton, _) = Skeleton::new(joints).map_err(|e| match e {
            SkinError::Cycle { name, .. } => rig(format!(
                "joint {name:?} is part of a parent cycle (a skeleton must be a tree)"
            )),
            other => other,
        })?;
        Ok(skeleton)
    }

    /// Joint `j` and every joint below it, `j` first.
    #[must_use]
    pub fn subtree(&self, j: usize) -> Vec<usize> {
        let mut out = vec![j];
        let mut k = 0;
        while k < out.len() {
            let name = &self.joints[out[k]].name;
            for (c, joint) in self.joints.iter().enumerate() {
                if joint.parent.as_ref() == Some(name) && !out.contains(&c) {
                    out.push(c);
                }
            }
            k += 1;
        }
        out
    }

    /// The spec of an existing skeleton: each joint at its bind-pose position (the inverse of
    /// its inverse bind matrix), for writing a model's rig back out or editing it.
    #[must_use]
    pub fn of_skeleton(skeleton: &Skeleton) -> Self {
        Self {
            joints: skeleton
                .joints
                .iter()
                .map(|j| JointSpec {
                    name: j.name.clone(),
                    parent: j.parent.map(|p| skeleton.joints[p].name.clone()),
                    // `+ 0.0` turns -0.0 into 0.0 (files and reports read better).
                    position: joint_bind_position(j).to_array().map(|v| v + 0.0),
                })
                .collect(),
        }
    }
}

/// The clips of `old` moved onto skeleton `new` by joint name: each channel keeps its keys and
/// addresses the joint of the same name; channels of joints `new` lacks are dropped (counted in
/// the second value). Clips left without channels are kept, empty.
#[must_use]
pub fn clips_by_name(
    old: &Skeleton,
    clips: &[AnimationClip],
    new: &Skeleton,
) -> (Vec<AnimationClip>, usize) {
    let mut dropped = 0;
    let moved = clips
        .iter()
        .map(|clip| AnimationClip {
            channels: clip
                .channels
                .iter()
                .filter_map(|c| {
                    let joint = old.joints.get(c.joint).and_then(|j| new.find(&j.name));
                    dropped += usize::from(joint.is_none());
                    Some(Channel {
                        joint: joint?,
                        ..c.clone()
                    })
                })
                .collect(),
            ..clip.clone()
        })
        .collect();
    (moved, dropped)
}

/// Where a joint stands in the bind pose, in the model's space: the origin of its frame,
/// `inverse(inverse_bind) · 0`. Non-invertible binds give the origin.
#[must_use]
pub fn joint_bind_position(joint: &Joint) -> Vec3 {
    let det = joint.inverse_bind.determinant();
    if det.is_finite() && det.abs() > f32::MIN_POSITIVE {
        joint.inverse_bind.inverse().w_axis.truncate()
    } else {
        Vec3::ZERO
    }
}

/// Interpolation of an authored clip's keys.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum KeyInterpolation {
    /// Hold each key until the next (glTF STEP).
    Step,
    /// Straight lines, shortest-path slerp for rotations (glTF LINEAR).
    #[default]
    Linear,
    /// Smooth curves through the keys (glTF CUBICSPLINE with Catmull-Rom tangents).
    Cubic,
}

/// One key of a [`ClipSpec`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeySpec {
    /// The joint's name.
    pub joint: String,
    /// Seconds from the clip's start, in `0..=length`.
    pub time: f32,
    /// Rotation relative to the rest pose as Euler degrees: X first, then Y, then Z, about the
    /// parent's axes (Blender's "XYZ Euler").
    #[serde(default)]
    pub rotation_deg: Option<[f32; 3]>,
    /// Translation relative to the rest position, in model units.
    #[serde(default)]
    pub translation: Option<[f32; 3]>,
}

/// A clip as an artist or a script writes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipSpec {
    /// The clip's name (a clip of the same name is replaced).
    pub name: String,
    /// Length in seconds.
    pub length: f32,
    /// How the keys are joined.
    #[serde(default)]
    pub interpolation: KeyInterpolation,
    /// Whether the clip repeats when played.
    #[serde(default, rename = "loop")]
    pub looping: bool,
    /// The keys, in any order.
    pub keys: Vec<KeySpec>,
    /// Frames per second the clip is edited at (keys snap to its frames in the editor); glTF
    /// stores seconds only. 24 when absent.
    #[serde(default = "default_frame_rate")]
    pub frame_rate: f32,
}

fn default_frame_rate() -> f32 {
    super::keys::DEFAULT_FRAME_RATE
}

/// One joint's key: time, rotation and translation relative to rest.
type JointKey = (f32, Option<Quat>, Option<Vec3>);

/// Longest clip accepted (seconds): an hour; beyond it a length is a unit mistake.
pub const MAX_CLIP_LENGTH_SECS: f32 = 3600.0;

impl ClipSpec {
    /// The clip over `skeleton`: per keyed joint a rotation channel (and a translation channel
    /// where translations are keyed), each with a key at 0 and at `length` (holding the nearest
    /// key's value) so every reader sees the clip's full length.
    ///
    /// # Errors
    /// [`SkinError::Rig`] naming the key: an empty name, a length that is not in
    /// `(0, MAX_CLIP_LENGTH_SECS]`, no keys, an unknown joint, a time outside the clip, a key
    /// with neither rotation nor translation, a non-finite value, or two keys of one joint at
    /// one time.
    pub fn to_clip(&self, skeleton: &Skeleton) -> Result<AnimationClip, SkinError> {
        let rig = |problem: String| SkinError::Rig { problem };
        if self.name.trim().is_empty() {
            return Err(rig("the clip has an empty name".into()));
        }
        if !(self.length.is_finite() && self.length > 0.0 && self.length <= MAX_CLIP_LENGTH_SECS) {
            return Err(rig(format!(
                "clip {:?}: length {} s must be a number in (0, {MAX_CLIP_LENGTH_SECS}]",
                self.name, self.length
            )));
        }
        if self.keys.is_empty() {
            return Err(rig(format!("clip {:?} has no keys", self.name)));
        }
        // Per joint: (time, rotation, translation) keys.
        let mut per_joint: Vec<Vec<JointKey>> = vec![Vec::new(); skeleton.len()];
        for (i, k) in self.keys.iter().enumerate() {
            let at = || {
                format!(
                    "clip {:?}, key {i} (joint {:?}, time {})",
                    self.name, k.joint, k.time
                )
            };
            let joint = skeleton
                .find(&k.joint)
                .ok_or_else(|| rig(format!("{}: the skeleton has no such joint", at())))?;
            if !(k.time.is_finite() && (0.0..=self.length).contains(&k.time)) {
                return Err(rig(format!(
                    "{}: the time must lie in 0..={} s",
                    at(),
                    self.length
                )));
            }
            if k.rotation_deg.is_none() && k.translation.is_none() {
                return Err(rig(format!(
                    "{}: give rotation_deg, translation or both",
                    at()
                )));
            }
            let finite = k
                .rotation_deg
                .is_none_or(|r| r.iter().all(|v| v.is_finite()))
                && k.translation
                    .is_none_or(|t| t.iter().all(|v| v.is_finite()));
            if !finite {
                return Err(rig(format!("{}: a value is not finite", at())));
            }
            if per_joint[joint].iter().any(|e| e.0 == k.time) {
                return Err(rig(format!(
                    "{}: the joint has two keys at this time",
                    at()
                )));
            }
            per_joint[joint].push((
                k.time,
                k.rotation_deg.map(euler_deg_to_quat),
                k.translation.map(Vec3::from),
            ));
        }
        let interpolation = match self.interpolation {
            KeyInterpolation::Step => Interpolation::Step,
            KeyInterpolation::Linear => Interpolation::Linear,
            KeyInterpolation::Cubic => Interpolation::CubicSpline,
        };
        let mut channels = Vec::new();
        for (joint, keys) in per_joint.iter_mut().enumerate() {
            if keys.is_empty() {
                continue;
            }
            keys.sort_by(|a, b| a.0.total_cmp(&b.0));
            let rest = &skeleton.joints[joint].rest;
            let rotations: Vec<(f32, Vec4)> = keys
                .iter()
                .filter_map(|&(t, r, _)| r.map(|q| (t, Vec4::from(rest.rotation * q))))
                .collect();
            let translations: Vec<(f32, Vec4)> = keys
                .iter()
                .filter_map(|&(t, _, tr)| tr.map(|v| (t, (rest.translation + v).extend(0.0))))
                .collect();
            for (property, keys) in [
                (Property::Rotation, rotations),
                (Property::Translation, translations),
            ] {
                if !keys.is_empty() {
                    channels.push(channel(joint, property, interpolation, keys, self.length));
                }
            }
        }
        let clip = AnimationClip {
            name: self.name.clone(),
            duration_secs: self.length,
            channels,
            frame_rate: self.frame_rate,
        };
        clip.validate(skeleton.len())?;
        Ok(clip)
    }

    /// The wrap mode this spec asks for when it is played.
    #[must_use]
    pub fn wrap(&self) -> Wrap {
        if self.looping {
            Wrap::Loop
        } else {
            Wrap::Clamp
        }
    }
}

/// Rotation of Euler degrees applied X first, then Y, then Z about fixed axes (`Rz·Ry·Rx`).
#[must_use]
pub fn euler_deg_to_quat(deg: [f32; 3]) -> Quat {
    let [x, y, z] = deg.map(f32::to_radians);
    Quat::from_euler(EulerRot::ZYX, z, y, x)
}

/// Inverse of [`euler_deg_to_quat`].
#[must_use]
pub fn quat_to_euler_deg(q: Quat) -> [f32; 3] {
    let (z, y, x) = q.to_euler(EulerRot::ZYX);
    [x, y, z].map(f32::to_degrees)
}

/// A channel through `keys` (sorted by time, unique) with end keys at 0 and `length` holding the
/// first and last values; cubic channels get Catmull-Rom tangents (zero at the ends).
fn channel(
    joint: usize,
    property: Property,
    interpolation: Interpolation,
    mut keys: Vec<(f32, Vec4)>,
    length: f32,
) -> Channel {
    if property == Property::Rotation {
        // Neighbouring quaternions in one hemisphere, so linear tangents follow the short path.
        for i in 1..keys.len() {
            if keys[i].1.dot(keys[i - 1].1) < 0.0 {
                keys[i].1 = -keys[i].1;
            }
        }
    }
    if let Some(&(t0, v0)) = keys.first()
        && t0 > 0.0
    {
        keys.insert(0, (0.0, v0));
    }
    if let Some(&(t1, v1)) = keys.last()
        && t1 < length
    {
        keys.push((length, v1));
    }
    let times: Vec<f32> = keys.iter().map(|k| k.0).collect();
    let values = if interpolation == Interpolation::CubicSpline {
        let n = keys.len();
        let mut values = Vec::with_capacity(3 * n);
        for i in 0..n {
            // Catmull-Rom slope in value per second; glTF tangents are scaled by the interval
            // when sampled, so they are stored per second.
            let slope = if i == 0 || i + 1 == n {
                Vec4::ZERO
            } else {
                let (ta, va) = keys[i - 1];
                let (tb, vb) = keys[i + 1];
                (vb - va) / (tb - ta).max(f32::EPSILON)
            };
            values.extend([slope, keys[i].1, slope]);
        }
        values
    } else {
        keys.iter().map(|k| k.1).collect()
    };
    Channel {
        joint,
        property,
        interpolation,
        times,
        values,
    }
}

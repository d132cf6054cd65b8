//! Skeletons, poses, manual overrides and forward kinematics.

use glam::{Mat4, Quat, Vec3};
use serde::{Deserialize, Serialize};

use super::SkinError;

/// A local translation–rotation–scale transform (applied scale, then rotation, then
/// translation, as in glTF).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Transform {
    /// Translation in the parent's space.
    pub translation: Vec3,
    /// Rotation; need not be unit length (it is normalised when used).
    pub rotation: Quat,
    /// Per-axis scale (0 is allowed: the joint collapses, nothing becomes NaN).
    pub scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Transform {
    /// No translation, rotation or scale.
    pub const IDENTITY: Self = Self {
        translation: Vec3::ZERO,
        rotation: Quat::IDENTITY,
        scale: Vec3::ONE,
    };

    /// `parent_from_local` as a matrix; the rotation is normalised first (a zero or
    /// non-finite quaternion counts as identity).
    #[must_use]
    pub fn to_mat4(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(
            self.scale,
            normalize_quat(self.rotation),
            self.translation,
        )
    }

    /// True when every component is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.translation.is_finite() && self.rotation.is_finite() && self.scale.is_finite()
    }
}

/// Normalises a quaternion; zero-length or non-finite input gives the identity, so a broken
/// key never turns a whole limb into NaN.
#[must_use]
pub fn normalize_quat(q: Quat) -> Quat {
    let len_sq = q.length_squared();
    if len_sq.is_finite() && len_sq > 1e-30 {
        q * len_sq.sqrt().recip()
    } else {
        Quat::IDENTITY
    }
}

/// One joint (bone) of a skeleton.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Joint {
    /// Display name (the glTF node name, or empty).
    pub name: String,
    /// Index of the parent joint; `None` for a root. After [`Skeleton::new`] the parent's index
    /// is always smaller than the joint's own.
    pub parent: Option<usize>,
    /// Rest (unanimated) local transform relative to the parent joint's frame.
    pub rest: Transform,
    /// `joint_from_bind`: takes a bind-pose mesh-space point into this joint's frame.
    pub inverse_bind: Mat4,
    /// Rest transforms of the non-joint nodes between the parent joint (or the scene root, for a
    /// root joint) and this joint, multiplied in order. glTF rigs often hang the skeleton under
    /// such nodes (RiggedFigure and CesiumMan have a Z-up matrix above their root joint); the
    /// joint world matrices must include them. Identity when there are none.
    pub parent_from_attachment: Mat4,
}

impl Default for Joint {
    fn default() -> Self {
        Self {
            name: String::new(),
            parent: None,
            rest: Transform::IDENTITY,
            inverse_bind: Mat4::IDENTITY,
            parent_from_attachment: Mat4::IDENTITY,
        }
    }
}

/// A joint hierarchy stored in topological order (every parent before its children), so forward
/// kinematics is one pass over the array.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Skeleton {
    /// Joints, parents first.
    pub joints: Vec<Joint>,
}

impl Skeleton {
    /// Builds a skeleton from joints in any order: validates parents and finiteness, rejects
    /// cycles and reorders the joints topologically (stable: joints already in order keep their
    /// indices). Returns the skeleton and `new_from_old`, the new index of each input joint, for
    /// remapping vertex joint indices and clip channels.
    ///
    /// # Errors
    /// [`SkinError::ParentOutOfRange`], [`SkinError::Cycle`] or [`SkinError::NonFiniteJoint`].
    pub fn new(joints: Vec<Joint>) -> Result<(Self, Vec<usize>), SkinError> {
        let count = joints.len();
        for (i, j) in joints.iter().enumerate() {
            if let Some(parent) = j.parent
                && parent >= count
            {
                return Err(SkinError::ParentOutOfRange {
                    joint: i,
                    name: j.name.clone(),
                    parent,
                    count,
                });
            }
            check_finite(i, j)?;
        }
        // Depth-first placement: a joint is placed after its parent chain. Visiting the input
        // in order keeps an already sorted skeleton unchanged.
        const UNSEEN: u8 = 0;
        const ON_PATH: u8 = 1;
        const PLACED: u8 = 2;
        let mut state = vec![UNSEEN; count];
        let mut new_from_old = vec![usize::MAX; count];
        let mut order = Vec::with_capacity(count);
        let mut path = Vec::new();
        for start in 0..count {
            let mut cur = start;
            // Walk up until a placed joint or a root, remembering the path.
            loop {
                match state[cur] {
                    PLACED => break,
                    ON_PATH => {
                        return Err(SkinError::Cycle {
                            joint: cur,
                            name: joints[cur].name.clone(),
                        });
                    }
                    _ => {}
                }
                state[cur] = ON_PATH;
                path.push(cur);
                match joints[cur].parent {
                    Some(p) => cur = p,
                    None => break,
                }
            }
            while let Some(j) = path.pop() {
                state[j] = PLACED;
                new_from_old[j] = order.len();
                order.push(j);
            }
        }
        let mut slots: Vec<Option<Joint>> = joints.into_iter().map(Some).collect();
        let mut sorted = Vec::with_capacity(count);
        for &old in &order {
            if let Some(mut j) = slots[old].take() {
                j.parent = j.parent.map(|p| new_from_old[p]);
                sorted.push(j);
            }
        }
        Ok((Self { joints: sorted }, new_from_old))
    }

    /// Checks the invariants [`Skeleton::new`] establishes (for skeletons loaded from a
    /// project file): parents before children, finite transforms.
    ///
    /// # Errors
    /// The first problem found: [`SkinError::Cycle`], [`SkinError::NotTopological`],
    /// [`SkinError::ParentOutOfRange`] or [`SkinError::NonFiniteJoint`].
    pub fn validate(&self) -> Result<(), SkinError> {
        let count = self.joints.len();
        for (i, j) in self.joints.iter().enumerate() {
            if let Some(parent) = j.parent {
                if parent >= count {
                    return Err(SkinError::ParentOutOfRange {
                        joint: i,
                        name: j.name.clone(),
                        parent,
                        count,
                    });
                }
                if parent >= i {
                    // Tell a real cycle from mere disorder.
                    Self::new(self.joints.clone())?;
                    return Err(SkinError::NotTopological {
                        joint: i,
                        name: j.name.clone(),
                        parent,
                    });
                }
            }
            check_finite(i, j)?;
        }
        Ok(())
    }

    /// Number of joints.
    #[must_use]
    pub fn len(&self) -> usize {
        self.joints.len()
    }

    /// True when there are no joints.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.joints.is_empty()
    }

    /// Index of the joint with this name.
    #[must_use]
    pub fn find(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Forward kinematics: fills `out.world_from_joint` and `out.skinning`
    /// (`world_from_joint * inverse_bind`) for `pose`. Joints missing from the pose use their
    /// rest transform. Reuses `out`'s allocations.
    pub fn compute_matrices(&self, pose: &Pose, out: &mut JointMatrices) {
        let n = self.joints.len();
        out.world_from_joint.clear();
        out.skinning.clear();
        out.world_from_joint.reserve(n);
        out.skinning.reserve(n);
        for (i, joint) in self.joints.iter().enumerate() {
            let local = pose.locals.get(i).unwrap_or(&joint.rest);
            let local = if local.is_finite() {
                local
            } else {
                &joint.rest
            };
            // Parents come first, so the parent's world matrix is already there; an index that
            // breaks the order (unvalidated data) is treated as a root instead of panicking.
            let parent_world = joint
                .parent
                .and_then(|p| {
                    if p < i {
                        out.world_from_joint.get(p).copied()
                    } else {
                        None
                    }
                })
                .unwrap_or(Mat4::IDENTITY);
            let mut world = parent_world * joint.parent_from_attachment * local.to_mat4();
            if !world.is_finite() {
                // Overflow from absurd scales: keep the parent frame rather than spread NaN.
                world = parent_world;
            }
            out.world_from_joint.push(world);
            out.skinning.push(world * joint.inverse_bind);
        }
    }

    /// Skinning matrices (`world_from_bind` per joint) for `pose`; allocates, see
    /// [`Skeleton::compute_matrices`] for the reusing form.
    #[must_use]
    pub fn skinning_matrices(&self, pose: &Pose) -> Vec<Mat4> {
        let mut m = JointMatrices::default();
        self.compute_matrices(pose, &mut m);
        m.skinning
    }
}

fn check_finite(i: usize, j: &Joint) -> Result<(), SkinError> {
    let bad = |what| SkinError::NonFiniteJoint {
        joint: i,
        name: j.name.clone(),
        what,
    };
    if !j.rest.translation.is_finite() {
        return Err(bad("rest translation"));
    }
    if !j.rest.rotation.is_finite() {
        return Err(bad("rest rotation"));
    }
    if !j.rest.scale.is_finite() {
        return Err(bad("rest scale"));
    }
    if !j.inverse_bind.is_finite() {
        return Err(bad("inverse bind matrix"));
    }
    if !j.parent_from_attachment.is_finite() {
        return Err(bad("attachment (non-joint ancestor) matrix"));
    }
    Ok(())
}

/// Per-joint matrices for one pose, reused from frame to frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointMatrices {
    /// `world_from_joint` per joint.
    pub world_from_joint: Vec<Mat4>,
    /// `world_from_bind = world_from_joint * inverse_bind` per joint: what skinning multiplies
    /// bind-pose mesh-space points by.
    pub skinning: Vec<Mat4>,
}

/// Local transforms of every joint at one instant.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Pose {
    /// One local transform per skeleton joint, in skeleton order.
    pub locals: Vec<Transform>,
}

impl Pose {
    /// The skeleton's rest pose (every joint at its rest transform). With glTF files this is
    /// normally the bind pose, in which skinning leaves vertices where they are.
    #[must_use]
    pub fn rest(skeleton: &Skeleton) -> Self {
        Self {
            locals: skeleton.joints.iter().map(|j| j.rest).collect(),
        }
    }

    /// Resets to the skeleton's rest pose, reusing the allocation.
    pub fn reset_to_rest(&mut self, skeleton: &Skeleton) {
        self.locals.clear();
        self.locals.extend(skeleton.joints.iter().map(|j| j.rest));
    }

    /// Layers manual per-joint overrides on top of this pose (a sampled clip or the rest pose).
    /// Overrides with an out-of-range joint or non-finite values are skipped; returns how many
    /// were skipped, so the caller can warn.
    pub fn apply_overrides(&mut self, overrides: &[JointOverride]) -> usize {
        let mut skipped = 0;
        for o in overrides {
            let finite = o.rotation.is_none_or(Quat::is_finite)
                && o.translation.is_none_or(Vec3::is_finite)
                && o.scale.is_none_or(Vec3::is_finite);
            let Some(local) = self.locals.get_mut(o.joint).filter(|_| finite) else {
                skipped += 1;
                continue;
            };
            match o.mode {
                OverrideMode::Replace => {
                    if let Some(r) = o.rotation {
                        local.rotation = normalize_quat(r);
                    }
                    if let Some(t) = o.translation {
                        local.translation = t;
                    }
                    if let Some(s) = o.scale {
                        local.scale = s;
                    }
                }
                OverrideMode::Relative => {
                    if let Some(r) = o.rotation {
                        // Rotate about the joint's own axes, after the clip's rotation.
                        local.rotation =
                            normalize_quat(normalize_quat(local.rotation) * normalize_quat(r));
                    }
                    if let Some(t) = o.translation {
                        local.translation += t;
                    }
                    if let Some(s) = o.scale {
                        local.scale *= s;
                    }
                }
            }
        }
        skipped
    }
}

/// How a [`JointOverride`] combines with the pose under it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum OverrideMode {
    /// The override's rotation / translation replace the clip's.
    #[default]
    Replace,
    /// The rotation is applied after the clip's (about the joint's own axes); the translation
    /// is added to the clip's.
    Relative,
}

/// A manual posing override for one joint (what the editor's pose tool stores).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct JointOverride {
    /// Skeleton joint index.
    pub joint: usize,
    /// Local rotation, if overridden.
    pub rotation: Option<Quat>,
    /// Local translation, if overridden.
    pub translation: Option<Vec3>,
    /// How it combines with the pose below.
    pub mode: OverrideMode,
    /// Local per-axis scale, if overridden (relative: multiplies the clip's). Omitted from the
    /// JSON when `None`, so files without it read and write as before.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<Vec3>,
}

impl Default for JointOverride {
    fn default() -> Self {
        Self {
            joint: 0,
            rotation: None,
            translation: None,
            mode: OverrideMode::Replace,
            scale: None,
        }
    }
}

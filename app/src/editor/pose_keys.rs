//! Pose keyframes: the selected joint's pose at the playhead is stored as keys in the playing
//! clip (rotation, translation and scale channels), or deleted from it; each is one undo
//! step. Scaling a joint with the gizmo is an override like rotating or moving it.

use glam::{Vec3, Vec4};
use thicket_core::skin::{AnimationClip, JointOverride, OverrideMode, Property};

use super::{CommandError, Edit, Editor};

pub use thicket_core::skin::keys::KEY_EPSILON_SECS;

/// Smallest per-axis joint scale a drag may set (a zero scale collapses the joint's voxels).
pub const MIN_JOINT_SCALE: f32 = 0.01;

impl Editor {
    /// The clip the playhead is on and the time a key set now gets (wrapped when looping).
    ///
    /// # Errors
    /// Unknown object or no rig.
    pub fn key_time(&self, id: u64) -> Result<(Option<usize>, f32), CommandError> {
        let rig = self.rig_or_err(id)?;
        let p = rig.playback;
        Ok(
            match p.clip.and_then(|c| rig.clips.get(c).map(|clip| (c, clip))) {
                // Held past the end, the playhead still names a time: keying there extends the
                // clip. Looping, it names the time inside the clip it shows.
                Some((c, clip)) => (
                    Some(c),
                    match p.wrap {
                        thicket_core::skin::Wrap::Clamp => p.time_secs.max(0.0),
                        thicket_core::skin::Wrap::Loop => clip.wrap_time(p.time_secs, p.wrap),
                    },
                ),
                None => (None, p.time_secs.max(0.0)),
            },
        )
    }

    /// Key times of `joint` in the clip the playhead is on (sorted, without repeats).
    #[must_use]
    pub fn joint_key_times(&self, id: u64, joint: usize) -> Vec<f32> {
        let Some(rig) = self.rig(id) else {
            return Vec::new();
        };
        let Some(clip) = rig.playback.clip.and_then(|c| rig.clips.get(c)) else {
            return Vec::new();
        };
        clip.joint_key_times(joint)
    }

    /// Stores `joint`'s current pose (clip, playhead and overrides) as keys of its rotation,
    /// translation and scale at the playhead, in the playing clip; on the rest pose a new clip
    /// "Pose" is added and starts playing. The joint's override is folded into the keys (so it
    /// is removed). One undo step.
    ///
    /// # Errors
    /// Unknown object, no rig or a joint out of range.
    pub fn set_joint_key(&mut self, id: u64, joint: usize) -> Result<(), CommandError> {
        self.set_joint_keys(id, &[joint])
    }

    /// Bakes the current pose of rigged model `id` into its playing clip (a new "Pose" clip on
    /// the rest pose): every joint with an override is keyed at the playhead, as Set key does,
    /// in one undo step. Returns how many joints were keyed (0: nothing was posed).
    ///
    /// # Errors
    /// Unknown object or no rig.
    pub fn bake_pose(&mut self, id: u64) -> Result<usize, CommandError> {
        let mut joints: Vec<usize> = self
            .rig_or_err(id)?
            .pose_overrides
            .iter()
            .map(|o| o.joint)
            .collect();
        joints.sort_unstable();
        joints.dedup();
        if !joints.is_empty() {
            self.set_joint_keys(id, &joints)?;
        }
        Ok(joints.len())
    }

    /// [`Editor::set_joint_key`] for several joints at once: one undo step.
    ///
    /// # Errors
    /// Unknown object, no rig or a joint out of range.
    pub fn set_joint_keys(&mut self, id: u64, joints: &[usize]) -> Result<(), CommandError> {
        let rig = self.rig_or_err(id)?;
        let n = rig.skeleton.len();
        if let Some(&joint) = joints.iter().find(|&&j| j >= n) {
            return Err(CommandError::Invalid(format!(
                "joint {joint} does not exist (the skeleton has {n})"
            )));
        }
        let pose = rig.current_pose();
        let (clip, t) = self.key_time(id)?;
        let rig = self.rig_or_err(id)?;
        let mut clips = rig.clips.clone();
        let index = clip.unwrap_or_else(|| {
            clips.push(AnimationClip {
                name: "Pose".into(),
                ..AnimationClip::default()
            });
            clips.len() - 1
        });
        let target = &mut clips[index];
        for &joint in joints {
            let local = pose.locals[joint];
            for (property, value) in [
                (Property::Rotation, Vec4::from(local.rotation.normalize())),
                (Property::Translation, local.translation.extend(0.0)),
                (Property::Scale, local.scale.extend(0.0)),
            ] {
                // The last channel of a property wins when sampling: key that one.
                target.channel_mut(joint, property).set_key(t, value);
            }
        }
        target.duration_secs = target.duration_secs.max(t);
        let overrides: Vec<JointOverride> = rig
            .pose_overrides
            .iter()
            .filter(|o| !joints.contains(&o.joint))
            .copied()
            .collect();
        let mut edits = vec![Edit::SetClips { id, clips }];
        if overrides != rig.pose_overrides {
            edits.push(Edit::SetPose { id, overrides });
        }
        self.history.seal();
        self.apply(Edit::Group(edits), None);
        self.history.seal();
        if clip.is_none() {
            let mut playback = self.rig_or_err(id)?.playback;
            playback.clip = Some(index);
            playback.time_secs = t;
            self.set_playback(id, playback)?;
        }
        Ok(())
    }

    /// Deletes `joint`'s keys at the playhead from the playing clip (channels left without
    /// keys are removed; the clip keeps its length). One undo step. Returns whether there was a
    /// key to delete.
    ///
    /// # Errors
    /// Unknown object or no rig.
    pub fn delete_joint_key(&mut self, id: u64, joint: usize) -> Result<bool, CommandError> {
        let (clip, t) = self.key_time(id)?;
        let Some(index) = clip else {
            return Ok(false);
        };
        let mut clips = self.rig_or_err(id)?.clips.clone();
        let deleted = clips[index].delete_keys(&[thicket_core::skin::KeyRef {
            joint,
            time_secs: t,
        }]);
        if deleted == 0 {
            return Ok(false);
        }
        self.history.seal();
        self.apply(Edit::SetClips { id, clips }, None);
        self.history.seal();
        Ok(true)
    }

    /// Scales `joint` per axis by `factor` on top of `base` (the override the drag started
    /// from; see [`Editor::rotate_joint`]). Each axis stays at least [`MIN_JOINT_SCALE`].
    ///
    /// # Errors
    /// As [`Editor::set_joint_override`], and a non-finite or non-positive factor.
    pub fn scale_joint(
        &mut self,
        id: u64,
        joint: usize,
        base: Option<JointOverride>,
        factor: Vec3,
    ) -> Result<(), CommandError> {
        if !factor.is_finite() || factor.min_element() <= 0.0 {
            return Err(CommandError::Invalid(format!(
                "a joint scale factor must be finite and positive, not {factor}"
            )));
        }
        let current = self
            .rig(id)
            .and_then(|r| r.current_pose().locals.get(joint).copied());
        let mut o = base.unwrap_or(JointOverride {
            joint,
            mode: OverrideMode::Relative,
            ..JointOverride::default()
        });
        let start = o.scale.unwrap_or(match o.mode {
            OverrideMode::Relative => Vec3::ONE,
            OverrideMode::Replace => current.map_or(Vec3::ONE, |l| l.scale),
        });
        o.scale = Some((start * factor).max(Vec3::splat(MIN_JOINT_SCALE)));
        self.set_joint_override(id, o)
    }
}

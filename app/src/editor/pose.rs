//! Posing rigged voxel models: joint overrides (undoable, one step per drag), the playback
//! state the timeline drives (saved with the document but, like the camera, not an edit) and
//! the stretch settings.

use glam::{Mat4, Quat, Vec3};
use thicket_core::scene::ObjectKind;
use thicket_core::skin::{
    JointMatrices, JointOverride, OverrideMode, Playback, Rig, StretchSettings,
};

use super::{Change, CommandError, Edit, Editor, MergeKey};

/// The joint frames of a rigged object in world space, for drawing and dragging.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointFrames {
    /// `world_from_joint` per joint, the object's transform included.
    pub world_from_joint: Vec<Mat4>,
    /// The frame a joint's local translation is expressed in (its parent's frame times the
    /// attachment above it), in world space.
    pub world_from_parent: Vec<Mat4>,
    /// Parent index per joint.
    pub parents: Vec<Option<usize>>,
    /// The object's transform: rest positions are in its own space.
    pub world_from_object: Mat4,
}

impl JointFrames {
    /// World position of joint `j`.
    #[must_use]
    pub fn position(&self, j: usize) -> Option<Vec3> {
        self.world_from_joint.get(j).map(|m| m.w_axis.truncate())
    }
}

/// The joint frames of rigged object `id` in `doc`, posed as `doc` stands (see
/// [`Editor::joint_frames`]; the view draws the skeleton from the document its image shows).
#[must_use]
pub fn joint_frames_in(doc: &thicket_core::scene::Document, id: u64) -> Option<JointFrames> {
    let o = doc.objects.iter().find(|o| o.id == id)?;
    let ObjectKind::Voxels(v) = &o.kind else {
        return None;
    };
    let rig = v.rig.as_ref()?;
    let world_from_object = o.transform.matrix();
    let mut m = JointMatrices::default();
    rig.skeleton.compute_matrices(&rig.current_pose(), &mut m);
    let joints = &rig.skeleton.joints;
    let world_from_joint: Vec<Mat4> = m
        .world_from_joint
        .iter()
        .map(|w| world_from_object * *w)
        .collect();
    let world_from_parent = joints
        .iter()
        .map(|j| {
            let parent = j
                .parent
                .and_then(|p| m.world_from_joint.get(p).copied())
                .unwrap_or(Mat4::IDENTITY);
            world_from_object * parent * j.parent_from_attachment
        })
        .collect();
    Some(JointFrames {
        world_from_joint,
        world_from_parent,
        parents: joints.iter().map(|j| j.parent).collect(),
        world_from_object,
    })
}

impl Editor {
    /// The rig of object `id`, when it is a rigged voxel model.
    #[must_use]
    pub fn rig(&self, id: u64) -> Option<&Rig> {
        match &self.object(id)?.kind {
            ObjectKind::Voxels(v) => v.rig.as_ref(),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
        }
    }

    pub(super) fn rig_or_err(&self, id: u64) -> Result<&Rig, CommandError> {
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        self.rig(id).ok_or_else(|| {
            CommandError::Invalid(format!(
                "{:?} has no skeleton: only rigged voxel models can be posed",
                o.name
            ))
        })
    }

    /// Changes whenever a rig's playback (clip or time) changes; with
    /// [`Editor::content_key`] it identifies what a renderer draws.
    #[must_use]
    pub fn animation_key(&self) -> u64 {
        self.anim_revision
    }

    /// The joint frames of object `id` as the document shows it now (clip, time, overrides).
    #[must_use]
    pub fn joint_frames(&self, id: u64) -> Option<JointFrames> {
        joint_frames_in(self.doc(), id)
    }

    /// The override of `joint` on object `id`, if any.
    #[must_use]
    pub fn joint_override(&self, id: u64, joint: usize) -> Option<JointOverride> {
        self.rig(id)?
            .pose_overrides
            .iter()
            .rev()
            .find(|o| o.joint == joint)
            .copied()
    }

    /// Sets the override of one joint (replacing any earlier override of that joint). Calls
    /// during one interaction (a gizmo or slider drag) merge into one undo step.
    ///
    /// # Errors
    /// Unknown object, no rig, a joint out of range, or a non-finite value.
    pub fn set_joint_override(&mut self, id: u64, o: JointOverride) -> Result<(), CommandError> {
        let rig = self.rig_or_err(id)?;
        let n = rig.skeleton.len();
        if o.joint >= n {
            return Err(CommandError::Invalid(format!(
                "joint {} does not exist (the skeleton has {n})",
                o.joint
            )));
        }
        let finite = o.rotation.is_none_or(Quat::is_finite)
            && o.rotation.is_none_or(|q| q.length_squared() > 1e-12)
            && o.translation.is_none_or(Vec3::is_finite);
        if !finite {
            return Err(CommandError::Invalid(format!(
                "joint {:?}: the rotation and translation must be finite (and the rotation non-zero)",
                rig.skeleton.joints[o.joint].name
            )));
        }
        let mut overrides: Vec<JointOverride> = rig
            .pose_overrides
            .iter()
            .filter(|x| x.joint != o.joint)
            .copied()
            .collect();
        overrides.push(o);
        if overrides != rig.pose_overrides {
            self.apply(Edit::SetPose { id, overrides }, Some(MergeKey::Pose(id)));
        }
        Ok(())
    }

    /// Poses the two bones above `end` (two-bone IK, [`thicket_core::skin::ik`]) so that `end`
    /// reaches `target_world`, the limb bending toward `pole_world` (`None`: the way it bends
    /// now). Its parent and grandparent get replacing overrides holding their solved rotation
    /// and their current translation and scale. Part of the current drag's undo step (as the
    /// gizmo's other drags). Returns whether the target was within reach.
    ///
    /// # Errors
    /// No rig; a joint without a parent and grandparent; a zero-length bone; non-finite input.
    pub fn pose_ik(
        &mut self,
        id: u64,
        end: usize,
        target_world: Vec3,
        pole_world: Option<Vec3>,
    ) -> Result<bool, CommandError> {
        let object_from_world = self
            .object(id)
            .ok_or(CommandError::NoObject(id))?
            .transform
            .matrix()
            .inverse();
        let rig = self.rig_or_err(id)?;
        let pose = rig.current_pose();
        let solution = thicket_core::skin::ik::two_bone_ik(
            &rig.skeleton,
            &pose,
            end,
            object_from_world.transform_point3(target_world),
            pole_world.map(|p| object_from_world.transform_point3(p)),
        )
        .map_err(|e| CommandError::Invalid(e.to_string()))?;
        for (joint, rotation) in [
            (solution.upper, solution.upper_rotation),
            (solution.mid, solution.mid_rotation),
        ] {
            let local = pose.locals[joint];
            self.set_joint_override(
                id,
                JointOverride {
                    joint,
                    rotation: Some(rotation),
                    translation: Some(local.translation),
                    mode: OverrideMode::Replace,
                    scale: Some(local.scale),
                },
            )?;
        }
        Ok(solution.reached)
    }

    /// Removes the override of one joint (`None`: of every joint) as one undo step.
    ///
    /// # Errors
    /// Unknown object or no rig.
    pub fn clear_pose(&mut self, id: u64, joint: Option<usize>) -> Result<(), CommandError> {
        let rig = self.rig_or_err(id)?;
        let overrides: Vec<JointOverride> = rig
            .pose_overrides
            .iter()
            .filter(|x| joint.is_some_and(|j| x.joint != j))
            .copied()
            .collect();
        if overrides != rig.pose_overrides {
            self.history.seal();
            self.apply(Edit::SetPose { id, overrides }, None);
        }
        Ok(())
    }

    /// Rotates `joint` by `delta` about its own axes on top of `base` (the override the drag
    /// started from, or none): the override becomes `base.rotation * delta` (relative overrides
    /// start from the identity, so they keep playing the clip underneath).
    ///
    /// # Errors
    /// As [`Editor::set_joint_override`].
    pub fn rotate_joint(
        &mut self,
        id: u64,
        joint: usize,
        base: Option<JointOverride>,
        delta: Quat,
    ) -> Result<(), CommandError> {
        let (mut o, current) = self.drag_start(id, joint, base);
        let start = o.rotation.unwrap_or(match o.mode {
            OverrideMode::Relative => Quat::IDENTITY,
            OverrideMode::Replace => current.map_or(Quat::IDENTITY, |l| l.rotation),
        });
        o.rotation = Some((start * delta).normalize());
        self.set_joint_override(id, o)
    }

    /// Moves `joint` by `delta` in its parent's frame on top of `base` (see
    /// [`Editor::rotate_joint`]).
    ///
    /// # Errors
    /// As [`Editor::set_joint_override`].
    pub fn translate_joint(
        &mut self,
        id: u64,
        joint: usize,
        base: Option<JointOverride>,
        delta: Vec3,
    ) -> Result<(), CommandError> {
        let (mut o, current) = self.drag_start(id, joint, base);
        let start = o.translation.unwrap_or(match o.mode {
            OverrideMode::Relative => Vec3::ZERO,
            OverrideMode::Replace => current.map_or(Vec3::ZERO, |l| l.translation),
        });
        o.translation = Some(start + delta);
        self.set_joint_override(id, o)
    }

    /// What a joint drag starts from: the override it began with (or a new relative one) and
    /// the joint's current local transform (for replacing overrides).
    fn drag_start(
        &self,
        id: u64,
        joint: usize,
        base: Option<JointOverride>,
    ) -> (JointOverride, Option<thicket_core::skin::Transform>) {
        let current = self
            .rig(id)
            .and_then(|r| r.current_pose().locals.get(joint).copied());
        let o = base.unwrap_or(JointOverride {
            joint,
            mode: OverrideMode::Relative,
            ..JointOverride::default()
        });
        (o, current)
    }

    /// Sets what plays and when. Like the camera this is saved with the document but is not an
    /// undoable edit and does not mark the document as changed (scrubbing is not editing).
    ///
    /// # Errors
    /// Unknown object, no rig, a clip that does not exist or a non-finite time.
    pub fn set_playback(&mut self, id: u64, playback: Playback) -> Result<(), CommandError> {
        let rig = self.rig_or_err(id)?;
        if let Some(c) = playback.clip
            && c >= rig.clips.len()
        {
            return Err(CommandError::Invalid(format!(
                "clip {c} does not exist (the model has {} clip(s))",
                rig.clips.len()
            )));
        }
        if !playback.time_secs.is_finite() {
            return Err(CommandError::Invalid(format!(
                "the time {} is not a number of seconds",
                playback.time_secs
            )));
        }
        if rig.playback == playback {
            return Ok(());
        }
        let index = self.index_of(id)?;
        if let ObjectKind::Voxels(v) = &mut self.doc.objects[index].kind
            && let Some(rig) = v.rig.as_mut()
        {
            rig.playback = playback;
            self.anim_revision += 1;
            self.record(self.content_key(), Change::Pose { object: id });
        }
        self.follow_motion(id);
        Ok(())
    }

    /// The frame sequence of voxel object `id` (an animated `.vox`), if it has one.
    #[must_use]
    pub fn frames(&self, id: u64) -> Option<&thicket_core::scene::FrameSequence> {
        match &self.object(id)?.kind {
            ObjectKind::Voxels(v) => v.frames.as_ref(),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
        }
    }

    /// Moves the playhead of frame sequence `id` and shows the frame there. Like
    /// [`Editor::set_playback`] it is saved with the document but is neither an undoable edit
    /// nor a change that marks the document (scrubbing is not editing); voxel edits remember
    /// their frame, so undo still writes the frame they were made on. A new shown frame swaps
    /// the object's octree, which renderers only see as a new content key: the generation
    /// changes and the next frame uploads the scene.
    ///
    /// # Errors
    /// Unknown object, an object without frames, or a non-finite time.
    pub fn set_frame_time(&mut self, id: u64, time_secs: f32) -> Result<(), CommandError> {
        if !time_secs.is_finite() {
            return Err(CommandError::Invalid(format!(
                "the time {time_secs} is not a number of seconds"
            )));
        }
        let index = self.index_of(id)?;
        let name = self.doc.objects[index].name.clone();
        let ObjectKind::Voxels(v) = &mut self.doc.objects[index].kind else {
            return Err(CommandError::Invalid(format!("{name:?} has no frames")));
        };
        if v.frames.as_ref().is_none_or(|f| f.time_secs == time_secs) {
            return if v.frames.is_some() {
                Ok(())
            } else {
                Err(CommandError::Invalid(format!("{name:?} has no frames")))
            };
        }
        let swapped = v.set_frame_time(time_secs);
        let before = self.content_key();
        self.anim_revision += 1;
        if swapped {
            self.generation += 1;
            self.record(
                before,
                Change::Voxels {
                    object: id,
                    region: None,
                },
            );
            // A live enhancer follows the octree it was built from: the next edit rebuilds it
            // from the frame now shown.
            self.drop_enhancers();
        } else {
            self.record(before, Change::Pose { object: id });
        }
        Ok(())
    }

    /// Sets the stretch settings of a rigged model after validating them; drags merge into one
    /// undo step.
    ///
    /// # Errors
    /// Unknown object, no rig, or a setting out of range (the message names it).
    pub fn set_stretch(&mut self, id: u64, stretch: StretchSettings) -> Result<(), CommandError> {
        let rig = self.rig_or_err(id)?;
        stretch
            .validate()
            .map_err(|e| CommandError::Invalid(format!("stretch: {e}")))?;
        if rig.stretch != stretch {
            self.apply(
                Edit::SetStretch { id, stretch },
                Some(MergeKey::Stretch(id)),
            );
        }
        Ok(())
    }
}

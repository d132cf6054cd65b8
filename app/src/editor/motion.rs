//! Rigid per-object animation in the editor: an object's transform keyed at the playhead
//! (`thicket_core::scene::ObjectMotion`), one undo step per key, and the playhead that moves
//! it. A rigged model's motion follows its rig's playhead (the timeline moves the figure and
//! its bones together); any other object has its own.

use thicket_core::scene::ObjectMotion;
use thicket_core::skin::{KeyRef, Wrap};

use super::{Change, CommandError, Edit, Editor};

impl Editor {
    /// The keyed transforms of object `id`, if any.
    #[must_use]
    pub fn motion(&self, id: u64) -> Option<&ObjectMotion> {
        self.object(id)?.motion.as_ref()
    }

    /// The clock of object `id`'s motion: its rig's playhead and wrap when it is a rigged
    /// voxel model, else the motion's own (0 s, looping, before it has one).
    #[must_use]
    pub fn motion_clock(&self, id: u64) -> (f32, Wrap) {
        self.object(id)
            .map_or((0.0, Wrap::Loop), thicket_core::scene::Object::motion_clock)
    }

    /// The time a key set now gets: the clock, wrapped into the motion when looping.
    fn motion_key_time(&self, id: u64) -> f32 {
        let (t, wrap) = self.motion_clock(id);
        match (wrap, self.motion(id)) {
            (Wrap::Loop, Some(m)) if m.clip.duration_secs > 0.0 => m.clip.wrap_time(t, wrap),
            _ => t.max(0.0),
        }
    }

    /// Keys object `id`'s current transform (translation, rotation, scale) at its playhead;
    /// the first key gives the object its motion. One undo step.
    ///
    /// # Errors
    /// Unknown object.
    pub fn set_object_key(&mut self, id: u64) -> Result<(), CommandError> {
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let t = self.motion_key_time(id);
        let mut motion = o.motion.clone().unwrap_or_else(|| ObjectMotion {
            time_secs: t,
            ..ObjectMotion::default()
        });
        motion.set_key(t, &o.transform);
        self.history.seal();
        self.apply_named(
            Edit::SetMotion {
                id,
                motion: Some(Box::new(motion)),
            },
            None,
            "Key transform".to_owned(),
        );
        self.history.seal();
        Ok(())
    }

    /// Deletes object `id`'s transform keys at its playhead (the last key removes the motion:
    /// the object stays where it is). One undo step; returns whether there was a key.
    ///
    /// # Errors
    /// Unknown object.
    pub fn delete_object_key(&mut self, id: u64) -> Result<bool, CommandError> {
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let Some(mut motion) = o.motion.clone() else {
            return Ok(false);
        };
        let t = self.motion_key_time(id);
        if motion.clip.delete_keys(&[KeyRef {
            joint: thicket_core::scene::motion::OBJECT_CHANNEL,
            time_secs: t,
        }]) == 0
        {
            return Ok(false);
        }
        let motion = (!motion.clip.channels.is_empty()).then(|| Box::new(motion));
        self.history.seal();
        self.apply_named(
            Edit::SetMotion { id, motion },
            None,
            "Clear transform key".to_owned(),
        );
        self.history.seal();
        Ok(true)
    }

    /// Key times of object `id`'s transform.
    #[must_use]
    pub fn object_key_times(&self, id: u64) -> Vec<f32> {
        self.motion(id).map_or_else(Vec::new, |m| {
            m.clip
                .joint_key_times(thicket_core::scene::motion::OBJECT_CHANNEL)
        })
    }

    /// Moves the playhead of an unrigged object's motion (a rigged model's follows
    /// [`Editor::set_playback`]) and puts the object where its keys say. Like the rig's
    /// playhead it is saved but is not an undoable edit.
    ///
    /// # Errors
    /// Unknown object, no motion, or a non-finite time.
    pub fn set_motion_time(
        &mut self,
        id: u64,
        time_secs: f32,
        wrap: Wrap,
    ) -> Result<(), CommandError> {
        if !time_secs.is_finite() {
            return Err(CommandError::Invalid(format!(
                "the time {time_secs} is not a number of seconds"
            )));
        }
        let index = self.index_of(id)?;
        let o = &mut self.doc.objects[index];
        let Some(m) = o.motion.as_mut() else {
            return Err(CommandError::Invalid(format!(
                "{:?} has no keyed transform",
                o.name
            )));
        };
        m.time_secs = time_secs;
        m.wrap = wrap;
        self.follow_motion(id);
        Ok(())
    }

    /// Puts object `id` where its motion says at its clock (after its playhead moved).
    pub(super) fn follow_motion(&mut self, id: u64) {
        let (t, wrap) = self.motion_clock(id);
        let Ok(index) = self.index_of(id) else { return };
        let o = &mut self.doc.objects[index];
        let Some(m) = &o.motion else { return };
        let at = m.transform_at(t, wrap, &o.transform);
        if at != o.transform && at.validate("the object").is_ok() {
            o.transform = at;
            // Content changed outside the history (as a frame sequence's shown frame): the
            // renderers see a new content key and take the object where it is now.
            let before = self.content_key();
            self.anim_revision += 1;
            self.generation += 1;
            self.record(before, Change::Content);
        }
    }
}

//! The dope sheet's edits on the playing clip of a rigged model: move, delete, copy / paste
//! keys, their joints' interpolation and the clip's frame rate. Each is one undo step; a drag
//! that moves keys is applied once, on release.

use thicket_core::skin::keys::FRAME_RATE_RANGE;
use thicket_core::skin::{AnimationClip, CopiedKey, Interpolation, KeyRef};

use super::{CommandError, Edit, Editor};

/// Copied keys with the names of their joints, so they paste onto the joints of that name in
/// any clip of any rig.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct KeyClipboard {
    /// The keys; `CopiedKey::joint` indexes `joint_names`.
    pub keys: Vec<CopiedKey>,
    /// Joint names of the rig they were copied from.
    pub joint_names: Vec<String>,
}

impl Editor {
    /// The playing clip of rigged model `id`.
    ///
    /// # Errors
    /// Unknown object, no rig, or the rest pose is shown (no clip plays).
    pub fn playing_clip(&self, id: u64) -> Result<(usize, &AnimationClip), CommandError> {
        let rig = self.rig_or_err(id)?;
        rig.playback
            .clip
            .and_then(|c| rig.clips.get(c).map(|clip| (c, clip)))
            .ok_or_else(|| {
                CommandError::Invalid("no clip plays: choose one on the timeline".into())
            })
    }

    /// Runs `f` on a copy of the playing clip and stores it as one undo step named `label`
    /// when it changed.
    fn edit_playing_clip<R>(
        &mut self,
        id: u64,
        label: &str,
        f: impl FnOnce(&mut AnimationClip) -> R,
    ) -> Result<R, CommandError> {
        let (index, _) = self.playing_clip(id)?;
        let mut clips = self.rig_or_err(id)?.clips.clone();
        let out = f(&mut clips[index]);
        if clips != self.rig_or_err(id)?.clips {
            self.history.seal();
            self.apply_named(Edit::SetClips { id, clips }, None, label.to_owned());
            self.history.seal();
        }
        Ok(out)
    }

    /// Moves `keys` of the playing clip by `dt` seconds (none before 0; a key dropped on one
    /// that did not move replaces it). Returns the keys where they are now.
    ///
    /// # Errors
    /// As [`Editor::playing_clip`].
    pub fn move_keys(
        &mut self,
        id: u64,
        keys: &[KeyRef],
        dt: f32,
    ) -> Result<Vec<KeyRef>, CommandError> {
        self.edit_playing_clip(id, "Move keys", |c| c.move_keys(keys, dt).0)
    }

    /// Deletes `keys` from the playing clip; returns how many channel keys went.
    ///
    /// # Errors
    /// As [`Editor::playing_clip`].
    pub fn delete_keys(&mut self, id: u64, keys: &[KeyRef]) -> Result<usize, CommandError> {
        self.edit_playing_clip(id, "Delete keys", |c| c.delete_keys(keys))
    }

    /// The values of `keys` in the playing clip, for [`Editor::paste_keys`].
    ///
    /// # Errors
    /// As [`Editor::playing_clip`].
    pub fn copy_keys(&self, id: u64, keys: &[KeyRef]) -> Result<KeyClipboard, CommandError> {
        let (_, clip) = self.playing_clip(id)?;
        let rig = self.rig_or_err(id)?;
        Ok(KeyClipboard {
            keys: clip.copy_keys(keys),
            joint_names: rig.skeleton.joints.iter().map(|j| j.name.clone()).collect(),
        })
    }

    /// Pastes copied keys into the playing clip from `at` seconds, each onto the joint of its
    /// name (keys of joints this rig lacks are left out). Returns the keys written.
    ///
    /// # Errors
    /// As [`Editor::playing_clip`]; a clipboard none of whose joints this rig has.
    pub fn paste_keys(
        &mut self,
        id: u64,
        clipboard: &KeyClipboard,
        at: f32,
    ) -> Result<Vec<KeyRef>, CommandError> {
        let names: Vec<String> = self
            .rig_or_err(id)?
            .skeleton
            .joints
            .iter()
            .map(|j| j.name.clone())
            .collect();
        let joint_of = |j: usize| {
            let name = clipboard.joint_names.get(j)?;
            names.iter().position(|n| n == name)
        };
        if !clipboard.keys.is_empty() && clipboard.keys.iter().all(|k| joint_of(k.joint).is_none())
        {
            return Err(CommandError::Invalid(
                "none of the copied keys' joints is in this rig".into(),
            ));
        }
        self.edit_playing_clip(id, "Paste keys", |c| {
            c.paste_keys(&clipboard.keys, at.max(0.0), joint_of)
        })
    }

    /// Sets the interpolation of every channel of `joints` in the playing clip (glTF keeps one
    /// per channel, so every key of those joints changes; keyed values stay).
    ///
    /// # Errors
    /// As [`Editor::playing_clip`].
    pub fn set_keys_interpolation(
        &mut self,
        id: u64,
        joints: &[usize],
        interpolation: Interpolation,
    ) -> Result<(), CommandError> {
        self.edit_playing_clip(id, "Key interpolation", |c| {
            c.set_interpolation(joints, interpolation);
        })
    }

    /// Sets clip `clip`'s frame rate (frames per second, within
    /// [`thicket_core::skin::keys::FRAME_RATE_RANGE`]); keys keep their times.
    ///
    /// # Errors
    /// No rig or clip; a rate out of range.
    pub fn set_clip_frame_rate(
        &mut self,
        id: u64,
        clip: usize,
        frame_rate: f32,
    ) -> Result<(), CommandError> {
        if !FRAME_RATE_RANGE.contains(&frame_rate) {
            return Err(CommandError::Invalid(format!(
                "frame rate {frame_rate}: must be within {}..={} frames per second",
                FRAME_RATE_RANGE.start(),
                FRAME_RATE_RANGE.end()
            )));
        }
        let mut clips = self.rig_or_err(id)?.clips.clone();
        let c = clips
            .get_mut(clip)
            .ok_or_else(|| CommandError::Invalid(format!("no clip {clip}")))?;
        if c.frame_rate == frame_rate {
            return Ok(());
        }
        c.frame_rate = frame_rate;
        self.history.seal();
        self.apply_named(
            Edit::SetClips { id, clips },
            None,
            "Clip frame rate".to_owned(),
        );
        self.history.seal();
        Ok(())
    }
}

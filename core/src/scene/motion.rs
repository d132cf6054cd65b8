//! Rigid per-object animation (ASVO thesis §3.2, the first row of its animation table): an
//! object's transform keyed over time. The keys are a [`crate::skin::AnimationClip`] whose
//! channels on joint 0 animate the object's own translation, rotation and scale, so keying,
//! sampling, the dope-sheet edits and the glTF export are the clips' own.
//!
//! The clock: a rigged voxel model's motion follows its rig's playhead (one timeline moves the
//! figure and its bones together); any other object has its own playhead here.

use glam::{Quat, Vec4};
use serde::{Deserialize, Serialize};

use super::Transform;
use crate::skin::skeleton::normalize_quat;
use crate::skin::{AnimationClip, Property, Wrap};

/// The joint index an object's own channels use.
pub const OBJECT_CHANNEL: usize = 0;

/// An object's keyed transform and, when no rig drives it, its playhead.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ObjectMotion {
    /// Keys of the object's translation, rotation and scale (channels on joint 0).
    pub clip: AnimationClip,
    /// Playhead in seconds (a rigged model's rig playhead overrides it).
    pub time_secs: f32,
    /// Loop or hold past the last key.
    pub wrap: Wrap,
}

impl ObjectMotion {
    /// The transform at `t` seconds: every keyed property sampled, the others from `base`.
    #[must_use]
    pub fn transform_at(&self, t: f32, wrap: Wrap, base: &Transform) -> Transform {
        let t = self.clip.wrap_time(t, wrap);
        let mut out = *base;
        for c in self
            .clip
            .channels
            .iter()
            .filter(|c| c.joint == OBJECT_CHANNEL)
        {
            let Some(v) = c.sample(t).filter(|v| v.is_finite()) else {
                continue;
            };
            match c.property {
                Property::Translation => out.translation = v.truncate(),
                Property::Rotation => out.rotation = normalize_quat(Quat::from_vec4(v)),
                Property::Scale => out.scale = v.truncate(),
            }
        }
        out
    }

    /// Keys `transform` at `t` seconds (translation, rotation and scale; an existing key there
    /// is replaced); the clip grows to hold it.
    pub fn set_key(&mut self, t: f32, transform: &Transform) {
        for (property, value) in [
            (Property::Translation, transform.translation.extend(0.0)),
            (
                Property::Rotation,
                Vec4::from(normalize_quat(transform.rotation)),
            ),
            (Property::Scale, transform.scale.extend(0.0)),
        ] {
            self.clip
                .channel_mut(OBJECT_CHANNEL, property)
                .set_key(t, value);
        }
        self.clip.duration_secs = self.clip.duration_secs.max(t);
    }

    /// Checks the keys (one joint: the object) and the playhead, and that every key is a
    /// transform the object may have (finite, scale non-zero).
    ///
    /// # Errors
    /// What is wrong, naming the channel or key.
    pub fn validate(&self) -> Result<(), String> {
        self.clip.validate(1).map_err(|e| e.to_string())?;
        if !self.time_secs.is_finite() {
            return Err(format!("the playhead {} is not finite", self.time_secs));
        }
        for c in &self.clip.channels {
            if c.property != Property::Scale {
                continue;
            }
            for k in 0..c.times.len() {
                if let Some(v) = c.key_value(k)
                    && v.truncate().abs().min_element() < 1e-12
                {
                    return Err(format!(
                        "scale key at {} s has a zero axis ({})",
                        c.times[k],
                        v.truncate()
                    ));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec3};

    use super::*;
    use crate::skin::{Channel, Interpolation};

    #[test]
    fn keyed_transforms_are_sampled_between_keys_and_held_outside() {
        let mut m = ObjectMotion::default();
        let a = Transform::default();
        let b = Transform {
            translation: Vec3::new(2.0, 0.0, -4.0),
            rotation: Quat::from_rotation_y(1.0),
            scale: Vec3::splat(2.0),
        };
        m.set_key(0.0, &a);
        m.set_key(2.0, &b);
        assert_eq!(m.clip.duration_secs, 2.0);
        m.validate().unwrap();
        let base = Transform {
            translation: Vec3::splat(9.0),
            ..Transform::default()
        };
        let mid = m.transform_at(1.0, Wrap::Clamp, &base);
        assert!((mid.translation - Vec3::new(1.0, 0.0, -2.0)).length() < 1e-5);
        assert!(mid.rotation.angle_between(Quat::from_rotation_y(0.5)) < 1e-4);
        assert!((mid.scale - Vec3::splat(1.5)).length() < 1e-5);
        let end = m.transform_at(5.0, Wrap::Clamp, &base);
        assert!((end.translation - b.translation).length() < 1e-6);
        // Looping, 3 s is 1 s.
        let looped = m.transform_at(3.0, Wrap::Loop, &base);
        assert!((looped.translation - mid.translation).length() < 1e-5);
        // Keying the same time again replaces the key.
        m.set_key(2.0, &a);
        assert_eq!(m.clip.joint_key_times(OBJECT_CHANNEL), [0.0, 2.0]);
        assert!(m.transform_at(2.0, Wrap::Clamp, &base).translation.length() < 1e-6);
    }

    #[test]
    fn only_keyed_properties_move_and_bad_keys_are_refused() {
        let mut m = ObjectMotion::default();
        m.clip.channels.push(Channel {
            joint: OBJECT_CHANNEL,
            property: Property::Translation,
            interpolation: Interpolation::Step,
            times: vec![0.0, 1.0],
            values: vec![Vec4::ZERO, Vec4::X],
        });
        m.clip.duration_secs = 1.0;
        let base = Transform {
            rotation: Quat::from_rotation_x(0.3),
            scale: Vec3::splat(3.0),
            ..Transform::default()
        };
        let t = m.transform_at(0.5, Wrap::Clamp, &base);
        assert_eq!(t.translation, Vec3::ZERO, "step holds");
        assert_eq!((t.rotation, t.scale), (base.rotation, base.scale));
        m.validate().unwrap();
        let mut bad = m.clone();
        bad.set_key(
            0.5,
            &Transform {
                scale: Vec3::new(1.0, 0.0, 1.0),
                ..Transform::default()
            },
        );
        assert!(bad.validate().unwrap_err().contains("zero axis"));
        let mut bad = m.clone();
        bad.clip.channels[0].joint = 1;
        assert!(bad.validate().is_err(), "one joint only: the object");
        let mut bad = m;
        bad.time_secs = f32::NAN;
        assert!(bad.validate().is_err());
    }
}

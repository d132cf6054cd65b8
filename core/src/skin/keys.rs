//! Key editing on clips, as a dope sheet sees them: a *key* is a joint at a time, standing for
//! every channel (rotation, translation, scale) of that joint with a key there. Moving, deleting,
//! copying and pasting act on all of them at once; interpolation is glTF's, one per channel, so
//! setting it changes every key of the joint's channels.
//!
//! Cubic-spline keys carry their tangents (`[in, value, out]`) wherever they move; a value
//! written into a cubic channel gets flat tangents, and a channel turned cubic gets Catmull-Rom
//! tangents from its neighbours (flat at the ends), so its curve passes through the same keys.

use glam::{Quat, Vec4};
use serde::{Deserialize, Serialize};

use super::clip::{AnimationClip, Channel, Interpolation, Property};

/// Keys closer than this (seconds) are the same key.
pub const KEY_EPSILON_SECS: f32 = 1e-3;

/// Frames per second a clip gets when nothing says otherwise (Blender's default scene rate).
pub const DEFAULT_FRAME_RATE: f32 = 24.0;

/// The frame rates a clip may have (frames per second).
pub const FRAME_RATE_RANGE: std::ops::RangeInclusive<f32> = 1.0..=240.0;

/// One joint's keys at one time (every channel of the joint keyed there).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KeyRef {
    /// Skeleton joint index.
    pub joint: usize,
    /// Key time in seconds.
    pub time_secs: f32,
}

/// A copied key: the values of its joint's channels at its time, relative to the first copied
/// key's time.
#[derive(Debug, Clone, PartialEq)]
pub struct CopiedKey {
    /// Skeleton joint index in the clip it was copied from.
    pub joint: usize,
    /// Seconds after the earliest copied key.
    pub offset_secs: f32,
    /// The keyed value of each property (rotations as `xyzw`), without tangents.
    pub values: Vec<(Property, Vec4)>,
}

impl Channel {
    /// The key at `t` (within [`KEY_EPSILON_SECS`]), if any.
    #[must_use]
    pub fn key_at(&self, t: f32) -> Option<usize> {
        self.times
            .iter()
            .position(|&x| (x - t).abs() < KEY_EPSILON_SECS)
    }

    /// The value (not the tangents) of key `k`.
    #[must_use]
    pub fn key_value(&self, k: usize) -> Option<Vec4> {
        let per_key = self.per_key();
        self.values
            .get(k * per_key + usize::from(per_key == 3))
            .copied()
    }

    /// Writes `value` at time `t`: replaces the key there or inserts one in order (a cubic key
    /// gets flat tangents). A rotation is flipped onto its neighbour's hemisphere so that
    /// interpolation takes the short way.
    pub fn set_key(&mut self, t: f32, value: Vec4) {
        let cubic = self.interpolation == Interpolation::CubicSpline;
        let value = if self.property == Property::Rotation {
            let near = self
                .times
                .iter()
                .position(|&x| x >= t)
                .or(self.times.len().checked_sub(1))
                .and_then(|k| self.key_value(k));
            match near {
                Some(v) if Quat::from_vec4(v).dot(Quat::from_vec4(value)) < 0.0 => -value,
                _ => value,
            }
        } else {
            value
        };
        match self.key_at(t) {
            Some(k) => {
                let i = if cubic { 3 * k + 1 } else { k };
                self.values[i] = value;
            }
            None => {
                let k = self.times.partition_point(|&x| x < t);
                self.times.insert(k, t);
                if cubic {
                    self.values
                        .splice(3 * k..3 * k, [Vec4::ZERO, value, Vec4::ZERO]);
                } else {
                    self.values.insert(k, value);
                }
            }
        }
    }

    /// Changes the interpolation, keeping every key's value: tangents are dropped, or computed
    /// as Catmull-Rom slopes (per second, flat at the ends) when turning cubic.
    pub fn set_interpolation(&mut self, interpolation: Interpolation) {
        if interpolation == self.interpolation {
            return;
        }
        let mut keys: Vec<Vec4> = (0..self.times.len())
            .filter_map(|k| self.key_value(k))
            .collect();
        self.interpolation = interpolation;
        if interpolation != Interpolation::CubicSpline {
            self.values = keys;
            return;
        }
        if self.property == Property::Rotation {
            for i in 1..keys.len() {
                if keys[i].dot(keys[i - 1]) < 0.0 {
                    keys[i] = -keys[i];
                }
            }
        }
        let n = keys.len();
        self.values = Vec::with_capacity(3 * n);
        for i in 0..n {
            let slope = if i == 0 || i + 1 == n {
                Vec4::ZERO
            } else {
                (keys[i + 1] - keys[i - 1])
                    / (self.times[i + 1] - self.times[i - 1]).max(f32::EPSILON)
            };
            self.values.extend([slope, keys[i], slope]);
        }
    }

    /// Key times and value chunks (one or three values each).
    fn take_keys(&mut self) -> Vec<(f32, Vec<Vec4>)> {
        let per_key = self.per_key();
        let values = std::mem::take(&mut self.values);
        std::mem::take(&mut self.times)
            .into_iter()
            .zip(values.chunks(per_key).map(<[Vec4]>::to_vec))
            .collect()
    }

    fn put_keys(&mut self, mut keys: Vec<(f32, Vec<Vec4>)>) {
        keys.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (t, v) in keys {
            self.times.push(t);
            self.values.extend(v);
        }
    }
}

impl AnimationClip {
    /// The channel that animates `property` of `joint` (the last one: it wins when sampled),
    /// added (linear, no keys) where there is none.
    pub fn channel_mut(&mut self, joint: usize, property: Property) -> &mut Channel {
        let i = match self
            .channels
            .iter()
            .rposition(|c| c.joint == joint && c.property == property)
        {
            Some(i) => i,
            None => {
                self.channels.push(Channel {
                    joint,
                    property,
                    interpolation: Interpolation::Linear,
                    times: Vec::new(),
                    values: Vec::new(),
                });
                self.channels.len() - 1
            }
        };
        &mut self.channels[i]
    }

    /// Key times of `joint` over all its channels (sorted, without repeats).
    #[must_use]
    pub fn joint_key_times(&self, joint: usize) -> Vec<f32> {
        let mut times: Vec<f32> = self
            .channels
            .iter()
            .filter(|c| c.joint == joint)
            .flat_map(|c| c.times.iter().copied())
            .collect();
        times.sort_by(f32::total_cmp);
        times.dedup_by(|a, b| (*a - *b).abs() < KEY_EPSILON_SECS);
        times
    }

    /// Every key of the clip, by joint then time.
    #[must_use]
    pub fn keys(&self) -> Vec<KeyRef> {
        let mut joints: Vec<usize> = self.channels.iter().map(|c| c.joint).collect();
        joints.sort_unstable();
        joints.dedup();
        joints
            .into_iter()
            .flat_map(|joint| {
                self.joint_key_times(joint)
                    .into_iter()
                    .map(move |time_secs| KeyRef { joint, time_secs })
            })
            .collect()
    }

    /// The interpolation of `joint`'s channels: `None` when it has none or they differ.
    #[must_use]
    pub fn joint_interpolation(&self, joint: usize) -> Option<Interpolation> {
        let mut it = self
            .channels
            .iter()
            .filter(|c| c.joint == joint)
            .map(|c| c.interpolation);
        let first = it.next()?;
        it.all(|i| i == first).then_some(first)
    }

    /// Deletes `keys` (channels left without keys are removed). Returns how many channel keys
    /// went. The length stays: a clip keeps the length the artist gave it.
    pub fn delete_keys(&mut self, keys: &[KeyRef]) -> usize {
        let mut deleted = 0;
        for c in &mut self.channels {
            let selected: Vec<f32> = selected_times(keys, c.joint);
            if selected.is_empty() {
                continue;
            }
            let before = c.times.len();
            let kept: Vec<_> = c
                .take_keys()
                .into_iter()
                .filter(|(t, _)| !near_any(*t, &selected))
                .collect();
            deleted += before - kept.len();
            c.put_keys(kept);
        }
        self.channels.retain(|c| !c.times.is_empty());
        deleted
    }

    /// Moves `keys` by `dt` seconds (held so that none goes before 0). A moved key landing on
    /// a key that did not move replaces it. The length grows to hold the last key. Returns the
    /// moved keys where they are now and the shift applied.
    pub fn move_keys(&mut self, keys: &[KeyRef], dt: f32) -> (Vec<KeyRef>, f32) {
        let earliest = keys
            .iter()
            .map(|k| k.time_secs)
            .fold(f32::INFINITY, f32::min);
        let dt = if dt.is_finite() && earliest.is_finite() {
            dt.max(-earliest)
        } else {
            0.0
        };
        if dt == 0.0 {
            return (keys.to_vec(), 0.0);
        }
        for c in &mut self.channels {
            let selected = selected_times(keys, c.joint);
            if selected.is_empty() {
                continue;
            }
            let (moved, kept): (Vec<_>, Vec<_>) = c
                .take_keys()
                .into_iter()
                .partition(|(t, _)| near_any(*t, &selected));
            let moved: Vec<_> = moved.into_iter().map(|(t, v)| (t + dt, v)).collect();
            let landed: Vec<f32> = moved.iter().map(|k| k.0).collect();
            let mut all: Vec<_> = kept
                .into_iter()
                .filter(|(t, _)| !near_any(*t, &landed))
                .collect();
            all.extend(moved);
            c.put_keys(all);
        }
        self.duration_secs = self.duration_secs.max(self.last_key_time());
        let moved = keys
            .iter()
            .map(|k| KeyRef {
                joint: k.joint,
                time_secs: k.time_secs + dt,
            })
            .collect();
        (moved, dt)
    }

    /// The values of `keys`, with times relative to the earliest of them.
    #[must_use]
    pub fn copy_keys(&self, keys: &[KeyRef]) -> Vec<CopiedKey> {
        let earliest = keys
            .iter()
            .map(|k| k.time_secs)
            .fold(f32::INFINITY, f32::min);
        keys.iter()
            .map(|k| CopiedKey {
                joint: k.joint,
                offset_secs: k.time_secs - earliest,
                values: self
                    .channels
                    .iter()
                    .filter(|c| c.joint == k.joint)
                    .filter_map(|c| {
                        let v = c.key_value(c.key_at(k.time_secs)?)?;
                        Some((c.property, v))
                    })
                    .collect(),
            })
            .collect()
    }

    /// Writes copied keys starting at `at` seconds onto joint `joint_of(copied.joint)` (keys
    /// whose joint maps to `None` are skipped), into the joint's last channel of each property
    /// (a linear one is added where there is none). The length grows to hold them. Returns the
    /// keys written.
    pub fn paste_keys(
        &mut self,
        copied: &[CopiedKey],
        at: f32,
        joint_of: impl Fn(usize) -> Option<usize>,
    ) -> Vec<KeyRef> {
        let mut written = Vec::new();
        for key in copied {
            let Some(joint) = joint_of(key.joint) else {
                continue;
            };
            let t = (at + key.offset_secs).max(0.0);
            for &(property, value) in &key.values {
                self.channel_mut(joint, property).set_key(t, value);
            }
            if !key.values.is_empty() {
                written.push(KeyRef {
                    joint,
                    time_secs: t,
                });
            }
        }
        self.duration_secs = self.duration_secs.max(self.last_key_time());
        written
    }

    /// Sets the interpolation of every channel of `joints` (see [`Channel::set_interpolation`]).
    pub fn set_interpolation(&mut self, joints: &[usize], interpolation: Interpolation) {
        for c in self
            .channels
            .iter_mut()
            .filter(|c| joints.contains(&c.joint))
        {
            c.set_interpolation(interpolation);
        }
    }

    /// `t` on the clip's frame grid (nearest frame).
    #[must_use]
    pub fn snap_to_frame(&self, t: f32) -> f32 {
        let fps = self.frame_rate;
        if fps > 0.0 && fps.is_finite() {
            (t * fps).round() / fps
        } else {
            t
        }
    }
}

fn selected_times(keys: &[KeyRef], joint: usize) -> Vec<f32> {
    keys.iter()
        .filter(|k| k.joint == joint)
        .map(|k| k.time_secs)
        .collect()
}

fn near_any(t: f32, times: &[f32]) -> bool {
    times.iter().any(|&x| (x - t).abs() < KEY_EPSILON_SECS)
}

#[cfg(test)]
mod tests;

//! Animation clips: keyframed joint channels and their sampling (glTF semantics).

use glam::{Quat, Vec3, Vec4};
use serde::{Deserialize, Serialize};

use super::SkinError;
use super::skeleton::{Pose, Skeleton, normalize_quat};

/// Which local property a channel animates.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Property {
    /// Translation (values are `xyz`, `w` unused).
    #[default]
    Translation,
    /// Rotation quaternion (`xyzw`).
    Rotation,
    /// Scale (values are `xyz`, `w` unused).
    Scale,
}

/// Keyframe interpolation (glTF `animation.sampler.interpolation`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Interpolation {
    /// Hold each key until the next.
    Step,
    /// Linear for vectors, shortest-path slerp for rotations.
    #[default]
    Linear,
    /// Cubic Hermite spline; every key stores in-tangent, value, out-tangent.
    CubicSpline,
}

/// What happens to times outside `[0, duration]`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Wrap {
    /// Hold the first / last key.
    #[default]
    Clamp,
    /// Repeat: `t` is taken modulo the clip's duration.
    Loop,
}

/// One animated property of one joint.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Channel {
    /// Skeleton joint index.
    pub joint: usize,
    /// The animated property.
    pub property: Property,
    /// Interpolation between keys.
    pub interpolation: Interpolation,
    /// Key times in seconds, non-decreasing.
    pub times: Vec<f32>,
    /// One value per key (`[in_tangent, value, out_tangent]` per key for
    /// [`Interpolation::CubicSpline`]). Vectors use `xyz`; rotations are `xyzw` quaternions,
    /// not necessarily unit length (they are normalised when sampled).
    pub values: Vec<Vec4>,
}

/// A named animation: channels over a skeleton's joints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AnimationClip {
    /// Display name.
    pub name: String,
    /// Length in seconds (at least the last key time over all channels).
    pub duration_secs: f32,
    /// Channels; where two animate the same property of the same joint, the later wins.
    pub channels: Vec<Channel>,
    /// Frames per second the clip is authored at: keys snap to its frames and the timeline
    /// counts them. glTF has no frame rate (its times are seconds), so it only guides editing.
    pub frame_rate: f32,
}

impl Default for AnimationClip {
    fn default() -> Self {
        Self {
            name: String::new(),
            duration_secs: 0.0,
            channels: Vec::new(),
            frame_rate: super::keys::DEFAULT_FRAME_RATE,
        }
    }
}

impl Channel {
    /// Values per key: `[in_tangent, value, out_tangent]` for a cubic spline, else one.
    pub(crate) fn per_key(&self) -> usize {
        if self.interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        }
    }

    /// Checks key times (finite, non-decreasing), value count and finiteness.
    ///
    /// # Errors
    /// A description of the first problem.
    pub fn check(&self, joint_count: usize) -> Result<(), String> {
        if self.joint >= joint_count {
            return Err(format!(
                "targets joint {} but the skeleton has {joint_count}",
                self.joint
            ));
        }
        if self.times.is_empty() {
            return Err("has no keys".into());
        }
        let per_key = self.per_key();
        if self.values.len() != self.times.len() * per_key {
            return Err(format!(
                "has {} key times but {} values ({per_key} per key expected for {:?})",
                self.times.len(),
                self.values.len(),
                self.interpolation
            ));
        }
        if let Some(i) = self.times.iter().position(|t| !t.is_finite()) {
            return Err(format!("key time {i} is not finite"));
        }
        if let Some(i) = self.times.windows(2).position(|w| w[1] < w[0]) {
            return Err(format!("key times decrease at key {}", i + 1));
        }
        if let Some(i) = self.values.iter().position(|v| !v.is_finite()) {
            return Err(format!("value {i} is not finite"));
        }
        Ok(())
    }

    /// The channel's value at time `t` (already wrapped/clamped by the caller; times outside
    /// the keys hold the end values). Rotations come back normalised. An empty or malformed
    /// channel returns `None` rather than panicking.
    #[must_use]
    pub fn sample(&self, t: f32) -> Option<Vec4> {
        let n = self.times.len();
        let cubic = self.interpolation == Interpolation::CubicSpline;
        let per_key = self.per_key();
        if n == 0 || self.values.len() < n * per_key {
            return None;
        }
        let value = |k: usize| self.values[k * per_key + usize::from(cubic)];
        let rotation = self.property == Property::Rotation;
        let finish = |v: Vec4| {
            if rotation {
                Vec4::from(normalize_quat(Quat::from_vec4(v)))
            } else {
                v
            }
        };
        // Index of the first key strictly after t.
        let next = self.times.partition_point(|&k| k <= t);
        if next == 0 {
            return Some(finish(value(0)));
        }
        if next >= n {
            return Some(finish(value(n - 1)));
        }
        let k = next - 1;
        let (t0, t1) = (self.times[k], self.times[next]);
        let dt = t1 - t0;
        let s = if dt > 0.0 {
            ((t - t0) / dt).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let out = match self.interpolation {
            Interpolation::Step => value(k),
            Interpolation::Linear => {
                if rotation {
                    Vec4::from(slerp_shortest(
                        Quat::from_vec4(value(k)),
                        Quat::from_vec4(value(next)),
                        s,
                    ))
                } else {
                    value(k).lerp(value(next), s)
                }
            }
            Interpolation::CubicSpline => {
                let out_tangent = self.values[k * 3 + 2];
                let in_tangent = self.values[next * 3];
                hermite(value(k), out_tangent * dt, value(next), in_tangent * dt, s)
            }
        };
        Some(finish(out))
    }
}

/// Cubic Hermite basis: `p0`, `m0` (out-tangent × key spacing), `p1`, `m1` (in-tangent × key
/// spacing) at `s` ∈ [0, 1] (glTF spec, Appendix C).
#[must_use]
pub fn hermite(p0: Vec4, m0: Vec4, p1: Vec4, m1: Vec4, s: f32) -> Vec4 {
    let s2 = s * s;
    let s3 = s2 * s;
    p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
        + m0 * (s3 - 2.0 * s2 + s)
        + p1 * (-2.0 * s3 + 3.0 * s2)
        + m1 * (s3 - s2)
}

/// Spherical linear interpolation along the shorter arc; inputs are normalised first and the
/// result is unit length. Falls back to normalised lerp when the rotations nearly coincide.
#[must_use]
pub fn slerp_shortest(a: Quat, b: Quat, s: f32) -> Quat {
    let a = normalize_quat(a);
    let mut b = normalize_quat(b);
    let mut dot = a.dot(b);
    if dot < 0.0 {
        // q and -q are the same rotation; take the one that is closer to `a`.
        b = -b;
        dot = -dot;
    }
    let dot = dot.min(1.0);
    if dot > 0.9995 {
        return normalize_quat(Quat::from_vec4(Vec4::from(a).lerp(Vec4::from(b), s)));
    }
    // atan2 keeps full precision near 0 and π, unlike acos.
    let theta = (1.0 - dot * dot).max(0.0).sqrt().atan2(dot);
    let sin_theta = theta.sin();
    let wa = ((1.0 - s) * theta).sin() / sin_theta;
    let wb = (s * theta).sin() / sin_theta;
    normalize_quat(Quat::from_vec4(Vec4::from(a) * wa + Vec4::from(b) * wb))
}

impl AnimationClip {
    /// Checks every channel against a skeleton of `joint_count` joints and the duration.
    ///
    /// # Errors
    /// [`SkinError::BadChannel`] naming the clip and channel.
    pub fn validate(&self, joint_count: usize) -> Result<(), SkinError> {
        for (i, c) in self.channels.iter().enumerate() {
            c.check(joint_count)
                .map_err(|problem| SkinError::BadChannel {
                    clip: self.name.clone(),
                    channel: i,
                    problem,
                })?;
        }
        if !super::keys::FRAME_RATE_RANGE.contains(&self.frame_rate) {
            return Err(SkinError::Rig {
                problem: format!(
                    "clip {:?}: frame rate {} is not within {}..={} frames per second",
                    self.name,
                    self.frame_rate,
                    super::keys::FRAME_RATE_RANGE.start(),
                    super::keys::FRAME_RATE_RANGE.end()
                ),
            });
        }
        if !self.duration_secs.is_finite() || self.duration_secs < 0.0 {
            return Err(SkinError::BadChannel {
                clip: self.name.clone(),
                channel: 0,
                problem: format!(
                    "duration {} s is not a finite non-negative number",
                    self.duration_secs
                ),
            });
        }
        Ok(())
    }

    /// The last key time over all channels (what glTF defines as the clip's length).
    #[must_use]
    pub fn last_key_time(&self) -> f32 {
        self.channels
            .iter()
            .filter_map(|c| c.times.last().copied())
            .filter(|t| t.is_finite())
            .fold(0.0, f32::max)
    }

    /// Maps `t` into the clip's time range.
    #[must_use]
    pub fn wrap_time(&self, t: f32, wrap: Wrap) -> f32 {
        let d = self.duration_secs;
        if !t.is_finite() {
            return 0.0;
        }
        match wrap {
            Wrap::Clamp => t.clamp(0.0, d.max(0.0)),
            Wrap::Loop if d > 0.0 => t.rem_euclid(d),
            Wrap::Loop => 0.0,
        }
    }

    /// The pose at time `t` (seconds, clamped to the clip): the skeleton's rest pose with every
    /// channel's value written over it.
    #[must_use]
    pub fn sample(&self, t: f32, skeleton: &Skeleton) -> Pose {
        let mut pose = Pose::default();
        self.sample_into(t, Wrap::Clamp, skeleton, &mut pose);
        pose
    }

    /// [`AnimationClip::sample`] with a wrap mode ([`Wrap::Loop`] for cycles like a walk).
    #[must_use]
    pub fn sample_wrapped(&self, t: f32, wrap: Wrap, skeleton: &Skeleton) -> Pose {
        let mut pose = Pose::default();
        self.sample_into(t, wrap, skeleton, &mut pose);
        pose
    }

    /// [`AnimationClip::sample`] with a wrap mode, writing into a reused pose.
    pub fn sample_into(&self, t: f32, wrap: Wrap, skeleton: &Skeleton, pose: &mut Pose) {
        pose.reset_to_rest(skeleton);
        let t = self.wrap_time(t, wrap);
        for c in &self.channels {
            let (Some(local), Some(v)) = (pose.locals.get_mut(c.joint), c.sample(t)) else {
                continue;
            };
            if !v.is_finite() {
                continue;
            }
            match c.property {
                Property::Translation => local.translation = Vec3::new(v.x, v.y, v.z),
                Property::Rotation => local.rotation = Quat::from_vec4(v),
                Property::Scale => local.scale = Vec3::new(v.x, v.y, v.z),
            }
        }
    }
}

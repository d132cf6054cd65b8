//! Two-bone inverse kinematics, the posing aid for limbs: the local rotations of a joint's
//! parent and grandparent that put the joint (a foot, a hand) on a target, the limb bending in
//! the plane through its root, the target and a pole (where the knee or elbow points).
//!
//! Analytic (the law of cosines), so it is exact and stable: a target out of reach stretches the
//! limb straight toward it, a target closer than the bones allow folds it as far as they go,
//! and a straight limb with no pole bends about an axis it already has. Only rotations change;
//! the bones keep their lengths. The result is plain local rotations, so a pose made with it
//! keys and exports like any other.

use glam::{Mat4, Quat, Vec3};

use super::skeleton::{JointMatrices, Pose, Skeleton, normalize_quat};

/// Why a two-bone chain cannot be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IkError {
    /// The end joint has no parent or grandparent.
    #[error("joint {0} needs a parent and a grandparent for two-bone IK")]
    NoChain(usize),
    /// The joint index is out of range.
    #[error("joint {0} does not exist")]
    NoJoint(usize),
    /// A bone of the chain has (almost) no length, so it has no direction to turn.
    #[error("a bone of the chain ending at joint {0} has no length")]
    ZeroLength(usize),
    /// The target or pole is not finite.
    #[error("the IK target and pole must be finite")]
    NotFinite,
}

/// The solved rotations of a two-bone chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoBoneSolution {
    /// The chain's root joint (the end's grandparent: a hip, a shoulder).
    pub upper: usize,
    /// The middle joint (the end's parent: a knee, an elbow).
    pub mid: usize,
    /// `upper`'s new local rotation.
    pub upper_rotation: Quat,
    /// `mid`'s new local rotation.
    pub mid_rotation: Quat,
    /// Whether the target was within reach (else the limb points at it, stretched or folded
    /// as far as it goes).
    pub reached: bool,
}

/// Solves the chain ending at `end` for `target` (skeleton world space, as
/// [`JointMatrices::world_from_joint`]): the end's grandparent and parent turn so that the end
/// lands on the target, bending toward `pole` (a world point; `None`: where the middle joint is
/// now, so the knee keeps bending the way it bends).
///
/// # Errors
/// [`IkError`]: no chain, a zero-length bone, a non-finite target or pole.
pub fn two_bone_ik(
    skeleton: &Skeleton,
    pose: &Pose,
    end: usize,
    target: Vec3,
    pole: Option<Vec3>,
) -> Result<TwoBoneSolution, IkError> {
    let joint = |j: usize| skeleton.joints.get(j).ok_or(IkError::NoJoint(j));
    let mid = joint(end)?.parent.ok_or(IkError::NoChain(end))?;
    let upper = joint(mid)?.parent.ok_or(IkError::NoChain(end))?;
    if !target.is_finite() || pole.is_some_and(|p| !p.is_finite()) {
        return Err(IkError::NotFinite);
    }
    let mut m = JointMatrices::default();
    skeleton.compute_matrices(pose, &mut m);
    let at = |j: usize| m.world_from_joint[j].w_axis.truncate();
    let (a_pos, b_pos, c_pos) = (at(upper), at(mid), at(end));
    let (a, b) = ((b_pos - a_pos).length(), (c_pos - b_pos).length());
    let scale = a + b;
    let floor = 1e-6 * scale.max(1e-30);
    if !(a > floor && b > floor && scale.is_finite()) {
        return Err(IkError::ZeroLength(end));
    }
    let to_target = target - a_pos;
    let dir = to_target
        .try_normalize()
        .or_else(|| (c_pos - a_pos).try_normalize())
        .unwrap_or(Vec3::Y);
    // Reach is held a hair inside the limits so the bend plane stays defined.
    let (lo, hi) = ((a - b).abs() + 1e-5 * scale, scale * (1.0 - 1e-6));
    let raw = to_target.length();
    let d = raw.clamp(lo, hi.max(lo));
    let reached = raw >= (a - b).abs() - 1e-4 * scale && raw <= scale * (1.0 + 1e-4);
    // The bend direction: the pole's offset from the root-target line; without a pole, the
    // knee keeps its hinge (the axis it bends about now, normal to the limb's plane), so it
    // bends the same way whatever the target; a straight limb hinges about the middle joint's
    // own X axis.
    let off_line = |p: Vec3, line: Vec3| {
        let v = p - a_pos;
        (v - line * v.dot(line)).try_normalize()
    };
    let hinge = || {
        let line = (c_pos - a_pos).try_normalize()?;
        let knee = off_line(b_pos, line)
            .map(|k| line.cross(k))
            .or_else(|| m.world_from_joint[mid].x_axis.truncate().try_normalize())?;
        knee.cross(dir).try_normalize()
    };
    let bend = match pole {
        Some(p) => off_line(p, dir).or_else(hinge),
        None => hinge(),
    }
    .unwrap_or_else(|| dir.any_orthonormal_vector());
    let x = (a * a - b * b + d * d) / (2.0 * d);
    let h = (a * a - x * x).max(0.0).sqrt();
    let b_new = a_pos + dir * x + bend * h;
    let c_new = a_pos + dir * d;

    // World rotations: the upper bone onto its new direction, then the lower one.
    let r1 = arc(b_pos - a_pos, b_new - a_pos);
    let c_after = b_new + r1 * (c_pos - b_pos);
    let r2 = arc(c_after - b_new, c_new - b_new);
    let frame_rotation = |j: usize| {
        let parent = skeleton.joints[j]
            .parent
            .map_or(Mat4::IDENTITY, |p| m.world_from_joint[p]);
        rotation_of(parent * skeleton.joints[j].parent_from_attachment)
    };
    let local = |j: usize| {
        pose.locals
            .get(j)
            .map_or(skeleton.joints[j].rest.rotation, |t| t.rotation)
    };
    let q_upper = frame_rotation(upper);
    let q_mid = frame_rotation(mid);
    let upper_rotation = normalize_quat(q_upper.inverse() * r1 * q_upper * local(upper));
    let mid_frame_after = r1 * q_mid;
    let mid_rotation = normalize_quat(mid_frame_after.inverse() * r2 * r1 * q_mid * local(mid));
    Ok(TwoBoneSolution {
        upper,
        mid,
        upper_rotation,
        mid_rotation,
        reached,
    })
}

/// The shortest rotation taking direction `from` to direction `to` (identity for a zero one).
fn arc(from: Vec3, to: Vec3) -> Quat {
    match (from.try_normalize(), to.try_normalize()) {
        (Some(f), Some(t)) => Quat::from_rotation_arc(f, t),
        _ => Quat::IDENTITY,
    }
}

/// The rotation of a frame that may carry scale.
fn rotation_of(m: Mat4) -> Quat {
    let (_, r, _) = m.to_scale_rotation_translation();
    if r.is_finite() {
        normalize_quat(r)
    } else {
        Quat::IDENTITY
    }
}

#[cfg(test)]
mod tests;

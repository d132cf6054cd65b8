//! Two-bone IK on a leg (hip, knee, foot, bent slightly forward): targets in reach are met
//! exactly with the bones' lengths kept and the knee on the pole's side; targets out of reach or
//! too close fold or stretch the leg as far as it goes toward them; parents that are rotated or
//! scaled, a straight leg and degenerate input do not break it.

use glam::{Quat, Vec3};

use super::*;
use crate::skin::author::{JointSpec, SkeletonSpec};

/// A root under the hip (so the hip has a moving parent), hip at y = 2, knee at y = 1 (z as
/// given), foot at y = 0.
fn leg(knee_z: f32) -> Skeleton {
    let j = |name: &str, parent: Option<&str>, p: [f32; 3]| JointSpec {
        name: name.into(),
        parent: parent.map(Into::into),
        position: p,
    };
    SkeletonSpec {
        joints: vec![
            j("root", None, [0.0, 2.5, 0.0]),
            j("hip", Some("root"), [0.0, 2.0, 0.0]),
            j("knee", Some("hip"), [0.0, 1.0, knee_z]),
            j("foot", Some("knee"), [0.0, 0.0, 0.0]),
        ],
    }
    .to_skeleton(None)
    .expect("a valid leg")
}

const FOOT: usize = 3;

/// The pose with the solution applied, and its world positions.
fn apply(s: &Skeleton, pose: &Pose, sol: &TwoBoneSolution) -> (Pose, Vec<Vec3>) {
    let mut p = pose.clone();
    p.locals[sol.upper].rotation = sol.upper_rotation;
    p.locals[sol.mid].rotation = sol.mid_rotation;
    let mut m = JointMatrices::default();
    s.compute_matrices(&p, &mut m);
    let at = m
        .world_from_joint
        .iter()
        .map(|w| w.w_axis.truncate())
        .collect();
    (p, at)
}

#[test]
fn a_target_in_reach_is_met_exactly_and_the_bones_keep_their_lengths() {
    let s = leg(0.1);
    let pose = Pose::rest(&s);
    let (_, rest) = apply(
        &s,
        &pose,
        &two_bone_ik(&s, &pose, FOOT, Vec3::ZERO, None).unwrap(),
    );
    let (thigh, shin) = ((rest[2] - rest[1]).length(), (rest[3] - rest[2]).length());
    for target in [
        Vec3::new(0.0, 0.5, 0.6),
        Vec3::new(0.7, 1.2, -0.3),
        Vec3::new(-0.2, 0.9, 0.0),
        Vec3::new(0.0, 2.0, 1.2),
    ] {
        let sol = two_bone_ik(&s, &pose, FOOT, target, None).unwrap();
        assert!(sol.reached, "{target}");
        assert_eq!((sol.upper, sol.mid), (1, 2));
        let (_, at) = apply(&s, &pose, &sol);
        assert!(
            (at[FOOT] - target).length() < 1e-4,
            "{target}: {}",
            at[FOOT]
        );
        assert!(((at[2] - at[1]).length() - thigh).abs() < 1e-4);
        assert!(((at[3] - at[2]).length() - shin).abs() < 1e-4);
        // The hip did not move: only rotations changed.
        assert!((at[1] - rest[1]).length() < 1e-5);
    }
}

#[test]
fn the_knee_bends_toward_the_pole_and_keeps_its_side_without_one() {
    let s = leg(0.1);
    let pose = Pose::rest(&s);
    let target = Vec3::new(0.0, 0.8, 0.0);
    // No pole: the knee stays in front (+z), where it was.
    let (_, at) = apply(
        &s,
        &pose,
        &two_bone_ik(&s, &pose, FOOT, target, None).unwrap(),
    );
    assert!(at[2].z > 0.3, "{}", at[2]);
    // ... and keeps its hinge wherever the target goes, forward and up included (the knee's
    // offset from the new hip-target line would point backward there).
    let hinge = |at: &[Vec3]| (at[2] - at[1]).cross(at[3] - at[2]).normalize_or_zero();
    let (_, rest) = apply(
        &s,
        &pose,
        &two_bone_ik(&s, &pose, FOOT, Vec3::ZERO, None).unwrap(),
    );
    for target in [Vec3::new(0.0, 1.2, 0.9), Vec3::new(0.3, 0.4, -0.6)] {
        let (_, at) = apply(
            &s,
            &pose,
            &two_bone_ik(&s, &pose, FOOT, target, None).unwrap(),
        );
        assert!((at[FOOT] - target).length() < 1e-4);
        // The hinge is the old one made perpendicular to the new hip-target line.
        let dir = (target - at[1]).normalize_or_zero();
        let (a, b) = (hinge(&rest), hinge(&at));
        let expected = (a - dir * a.dot(dir)).normalize_or_zero();
        assert!(
            expected.dot(b) > 0.9999,
            "{target}: hinge {a} -> {b}, expected {expected}"
        );
    }
    // A pole behind: the knee goes back; to the side: it goes sideways.
    let (_, at) = apply(
        &s,
        &pose,
        &two_bone_ik(&s, &pose, FOOT, target, Some(Vec3::new(0.0, 1.0, -5.0))).unwrap(),
    );
    assert!(at[2].z < -0.3, "{}", at[2]);
    assert!((at[FOOT] - target).length() < 1e-4);
    let (_, at) = apply(
        &s,
        &pose,
        &two_bone_ik(&s, &pose, FOOT, target, Some(Vec3::new(5.0, 1.0, 0.0))).unwrap(),
    );
    assert!(at[2].x > 0.3 && at[2].z.abs() < 1e-3, "{}", at[2]);
}

#[test]
fn out_of_reach_targets_stretch_or_fold_the_leg_toward_them() {
    let s = leg(0.1);
    let pose = Pose::rest(&s);
    // Far below: straight down, the foot as far as the bones reach.
    let far = Vec3::new(0.0, -10.0, 0.0);
    let sol = two_bone_ik(&s, &pose, FOOT, far, None).unwrap();
    assert!(!sol.reached);
    let (_, at) = apply(&s, &pose, &sol);
    let reach = (at[2] - at[1]).length() + (at[3] - at[2]).length();
    assert!(((at[FOOT] - at[1]).length() - reach).abs() < 1e-3 * reach);
    assert!((at[FOOT] - at[1]).normalize_or_zero().dot(Vec3::NEG_Y) > 0.9999);
    // At the hip itself: folded as far as it goes (|thigh - shin| from the hip), no NaN.
    let sol = two_bone_ik(&s, &pose, FOOT, Vec3::new(0.0, 2.0, 0.0), None).unwrap();
    let (_, at) = apply(&s, &pose, &sol);
    assert!(at.iter().all(|p| p.is_finite()));
    let fold = ((at[2] - at[1]).length() - (at[3] - at[2]).length()).abs();
    assert!(((at[FOOT] - at[1]).length() - fold).abs() < 1e-3);
}

#[test]
fn rotated_and_scaled_parents_and_a_straight_leg_still_solve() {
    // A straight leg (knee on the line): it bends about an axis it has; the target is met.
    let s = leg(0.0);
    let pose = Pose::rest(&s);
    let target = Vec3::new(0.0, 0.6, 0.3);
    let (_, at) = apply(
        &s,
        &pose,
        &two_bone_ik(&s, &pose, FOOT, target, None).unwrap(),
    );
    assert!((at[FOOT] - target).length() < 1e-4, "{}", at[FOOT]);
    // The root turned and scaled: the solution is in the hip's parent frame.
    let s = leg(0.1);
    let mut pose = Pose::rest(&s);
    pose.locals[0].rotation = Quat::from_euler(glam::EulerRot::XYZ, 0.4, -0.7, 0.2);
    pose.locals[0].scale = Vec3::splat(1.5);
    let target = {
        let mut m = JointMatrices::default();
        s.compute_matrices(&pose, &mut m);
        m.world_from_joint[1].w_axis.truncate() + Vec3::new(0.3, -1.5, 0.8)
    };
    let sol = two_bone_ik(&s, &pose, FOOT, target, None).unwrap();
    let (_, at) = apply(&s, &pose, &sol);
    assert!(
        (at[FOOT] - target).length() < 1e-3,
        "{} vs {target}",
        at[FOOT]
    );
}

#[test]
fn bad_chains_and_values_are_errors_not_panics() {
    let s = leg(0.1);
    let pose = Pose::rest(&s);
    assert_eq!(
        two_bone_ik(&s, &pose, 1, Vec3::ZERO, None),
        Err(IkError::NoChain(1))
    );
    assert_eq!(
        two_bone_ik(&s, &pose, 9, Vec3::ZERO, None),
        Err(IkError::NoJoint(9))
    );
    assert_eq!(
        two_bone_ik(&s, &pose, FOOT, Vec3::NAN, None),
        Err(IkError::NotFinite)
    );
    assert_eq!(
        two_bone_ik(&s, &pose, FOOT, Vec3::ZERO, Some(Vec3::INFINITY)),
        Err(IkError::NotFinite)
    );
    // A shin of no length has no direction to turn.
    let mut zero = Pose::rest(&s);
    zero.locals[FOOT].translation = Vec3::ZERO;
    assert_eq!(
        two_bone_ik(&s, &zero, FOOT, Vec3::ZERO, None),
        Err(IkError::ZeroLength(FOOT))
    );
    // Extreme scales: a millimetre leg and a kilometre one solve alike.
    for k in [1e-3f32, 1e3] {
        let mut p = Pose::rest(&s);
        p.locals[0].scale = Vec3::splat(k);
        let mut m = JointMatrices::default();
        s.compute_matrices(&p, &mut m);
        let hip = m.world_from_joint[1].w_axis.truncate();
        let target = hip + Vec3::new(0.0, -1.2, 0.9) * k;
        let sol = two_bone_ik(&s, &p, FOOT, target, None).unwrap();
        let (_, at) = apply(&s, &p, &sol);
        // Within the limb's scale, or the f32 resolution of where it is (the millimetre leg
        // hangs 2.5 units up: its coordinates resolve to about 2.4e-7).
        assert!(
            (at[FOOT] - target).length() < 1e-4 * k + 4.0 * f32::EPSILON * target.length(),
            "scale {k}: {} off",
            (at[FOOT] - target).length()
        );
    }
}

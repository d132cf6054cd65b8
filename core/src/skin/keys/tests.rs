//! Dope-sheet edits on a two-joint clip: values travel with their keys (tangents too), a key
//! dropped on another replaces it, nothing moves before 0, and interpolation changes keep every
//! keyed value.

use glam::{Quat, Vec4};

use super::*;

fn rot(deg: f32) -> Vec4 {
    Vec4::from(Quat::from_rotation_z(deg.to_radians()))
}

/// Joint 0: rotation and translation keyed at 0, 0.5 and 1 s; joint 1: a rotation at 0.5 s.
fn clip() -> AnimationClip {
    AnimationClip {
        name: "walk".into(),
        duration_secs: 1.0,
        channels: vec![
            Channel {
                joint: 0,
                property: Property::Rotation,
                interpolation: Interpolation::Linear,
                times: vec![0.0, 0.5, 1.0],
                values: vec![rot(0.0), rot(40.0), rot(10.0)],
            },
            Channel {
                joint: 0,
                property: Property::Translation,
                interpolation: Interpolation::Linear,
                times: vec![0.0, 0.5, 1.0],
                values: vec![Vec4::ZERO, Vec4::X, Vec4::Y],
            },
            Channel {
                joint: 1,
                property: Property::Rotation,
                interpolation: Interpolation::Linear,
                times: vec![0.5],
                values: vec![rot(-30.0)],
            },
        ],
        ..AnimationClip::default()
    }
}

fn key(joint: usize, time_secs: f32) -> KeyRef {
    KeyRef { joint, time_secs }
}

fn value(c: &AnimationClip, channel: usize, t: f32) -> Vec4 {
    c.channels[channel].sample(t).expect("keys")
}

#[test]
fn moving_a_key_carries_every_channel_value_and_leaves_other_joints() {
    let mut c = clip();
    let (moved, dt) = c.move_keys(&[key(0, 0.5)], 0.25);
    assert_eq!(dt, 0.25);
    assert_eq!(moved, [key(0, 0.75)]);
    assert_eq!(c.joint_key_times(0), [0.0, 0.75, 1.0]);
    assert!(value(&c, 0, 0.75).abs_diff_eq(rot(40.0), 1e-6));
    assert_eq!(value(&c, 1, 0.75), Vec4::X);
    // Joint 1's key at 0.5 did not move, and the length holds.
    assert_eq!(c.channels[2].times, [0.5]);
    assert_eq!(c.duration_secs, 1.0);
    // Past the end: the clip grows to hold it.
    c.move_keys(&[key(0, 1.0)], 1.0);
    assert_eq!(c.joint_key_times(0), [0.0, 0.75, 2.0]);
    assert_eq!(c.duration_secs, 2.0);
    c.validate(2).unwrap();
}

#[test]
fn a_key_dropped_on_another_replaces_it_and_nothing_goes_before_zero() {
    let mut c = clip();
    c.move_keys(&[key(0, 0.5)], 0.5);
    assert_eq!(c.joint_key_times(0), [0.0, 1.0]);
    assert!(value(&c, 0, 1.0).abs_diff_eq(rot(40.0), 1e-6));
    assert_eq!(value(&c, 1, 1.0), Vec4::X);
    // Dragged far left, the earliest selected key stops at 0 and the others keep their gaps.
    let mut c = clip();
    let (moved, dt) = c.move_keys(&[key(0, 0.5), key(0, 1.0)], -5.0);
    assert_eq!(dt, -0.5);
    assert_eq!(moved, [key(0, 0.0), key(0, 0.5)]);
    assert_eq!(c.joint_key_times(0), [0.0, 0.5]);
    assert!(value(&c, 0, 0.5).abs_diff_eq(rot(10.0), 1e-6));
    // Two selected keys swapping places do not eat each other.
    let mut c = clip();
    c.move_keys(&[key(0, 0.0), key(0, 0.5)], 0.5);
    assert_eq!(c.joint_key_times(0), [0.5, 1.0]);
    assert_eq!(value(&c, 1, 0.5), Vec4::ZERO);
    assert_eq!(value(&c, 1, 1.0), Vec4::X);
    // A non-finite shift does nothing.
    let mut c = clip();
    assert_eq!(c.move_keys(&[key(0, 0.5)], f32::NAN).1, 0.0);
    assert_eq!(c, clip());
}

#[test]
fn cubic_keys_move_with_their_tangents() {
    let mut c = clip();
    c.set_interpolation(&[0], Interpolation::CubicSpline);
    let before: Vec<Vec4> = c.channels[1].values[3..6].to_vec();
    assert_ne!(
        before[0],
        Vec4::ZERO,
        "Catmull-Rom tangent at the middle key"
    );
    c.move_keys(&[key(0, 0.5)], 0.2);
    assert_eq!(c.channels[1].times, [0.0, 0.7, 1.0]);
    assert_eq!(c.channels[1].values[3..6], before[..]);
    c.validate(2).unwrap();
}

#[test]
fn deleting_keys_removes_every_channel_there_and_keeps_the_length() {
    let mut c = clip();
    assert_eq!(c.delete_keys(&[key(0, 0.5), key(1, 0.5)]), 3);
    assert_eq!(c.joint_key_times(0), [0.0, 1.0]);
    assert!(c.joint_key_times(1).is_empty());
    assert_eq!(c.channels.len(), 2, "joint 1's emptied channel is gone");
    assert_eq!(c.duration_secs, 1.0);
    assert_eq!(c.delete_keys(&[key(0, 0.3)]), 0);
    c.validate(2).unwrap();
}

#[test]
fn copied_keys_paste_at_the_playhead_with_their_spacing_and_values() {
    let mut c = clip();
    let copied = c.copy_keys(&[key(0, 0.5), key(0, 1.0)]);
    assert_eq!(copied.len(), 2);
    assert_eq!(copied[1].offset_secs, 0.5);
    assert_eq!(copied[0].values.len(), 2);
    let written = c.paste_keys(&copied, 2.0, Some);
    assert_eq!(written, [key(0, 2.0), key(0, 2.5)]);
    assert_eq!(c.duration_secs, 2.5);
    for (t, was) in [(2.0, 0.5), (2.5, 1.0)] {
        assert!(value(&c, 0, t).abs_diff_eq(value(&clip(), 0, was), 1e-6));
        assert_eq!(value(&c, 1, t), value(&clip(), 1, was));
    }
    // Onto another joint: joint 1 gets a translation channel it did not have.
    let written = c.paste_keys(&copied[..1], 0.0, |_| Some(1));
    assert_eq!(written, [key(1, 0.0)]);
    let translation = c
        .channels
        .iter()
        .find(|ch| ch.joint == 1 && ch.property == Property::Translation)
        .expect("added");
    assert_eq!(translation.sample(0.0), Some(Vec4::X));
    // A joint that does not map is skipped.
    assert!(c.paste_keys(&copied, 0.0, |_| None).is_empty());
    c.validate(2).unwrap();
}

#[test]
fn interpolation_changes_keep_every_keyed_value() {
    let original = clip();
    let mut c = clip();
    for to in [
        Interpolation::CubicSpline,
        Interpolation::Step,
        Interpolation::CubicSpline,
        Interpolation::Linear,
    ] {
        c.set_interpolation(&[0], to);
        c.validate(2).unwrap();
        assert_eq!(c.joint_interpolation(0), Some(to));
        for t in [0.0, 0.5, 1.0] {
            for ch in 0..2 {
                assert!(
                    value(&c, ch, t).abs_diff_eq(value(&original, ch, t), 1e-6),
                    "{to:?} at {t}"
                );
            }
        }
    }
    assert_eq!(c, original, "back to linear: the same clip");
    // Step holds, cubic curves: between keys they differ from linear.
    let mut step = clip();
    step.set_interpolation(&[0], Interpolation::Step);
    assert_eq!(value(&step, 1, 0.4), Vec4::ZERO);
    let mut cubic = clip();
    cubic.set_interpolation(&[0], Interpolation::CubicSpline);
    let (l, s) = (value(&original, 1, 0.25), value(&cubic, 1, 0.25));
    assert!((l - s).length() > 1e-3, "{l} {s}");
    assert_eq!(original.joint_interpolation(5), None);
}

#[test]
fn keys_snap_to_the_frame_grid() {
    let mut c = clip();
    assert_eq!(c.frame_rate, DEFAULT_FRAME_RATE);
    assert_eq!(c.snap_to_frame(0.51), 0.5);
    c.frame_rate = 30.0;
    assert!((c.snap_to_frame(0.51) - 15.0 / 30.0).abs() < 1e-6);
    assert!((c.snap_to_frame(0.52) - 16.0 / 30.0).abs() < 1e-6);
    // Out-of-range rates are refused by validation.
    for bad in [0.0, -24.0, f32::NAN, 1000.0] {
        c.frame_rate = bad;
        assert!(c.validate(2).is_err(), "{bad}");
    }
}

#[test]
fn every_key_of_the_clip_is_listed_by_joint_then_time() {
    let c = clip();
    assert_eq!(
        c.keys(),
        [key(0, 0.0), key(0, 0.5), key(0, 1.0), key(1, 0.5)]
    );
}

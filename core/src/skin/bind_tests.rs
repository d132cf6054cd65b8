//! Tests of native rigs: skeleton and clip specs, and automatic binding on shapes made here.

use glam::{UVec3, Vec3};

use super::author::{ClipSpec, JointSpec, KeyInterpolation, KeySpec, SkeletonSpec};
use super::bind::{BindControl, BindMethod, bind};
use super::clip::Wrap;
use super::skeleton::Pose;
use super::{Skin4, SkinError};
use crate::svo::{Svo, Voxel};

fn solid(boxes: &[(UVec3, UVec3)]) -> Svo {
    let mut voxels = Vec::new();
    for &(lo, hi) in boxes {
        for z in lo.z..hi.z {
            for y in lo.y..hi.y {
                for x in lo.x..hi.x {
                    voxels.push((UVec3::new(x, y, z), Voxel::new([200, 80, 40, 255], Vec3::Y)));
                }
            }
        }
    }
    Svo::from_voxels(6, false, voxels).unwrap()
}

/// Binds `svo` (1-unit voxels at the origin) to `skeleton`.
fn bind_at_origin(
    svo: &Svo,
    skeleton: &super::Skeleton,
    method: BindMethod,
) -> (Svo, super::bind::BindReport) {
    bind(
        svo,
        Vec3::ZERO,
        1.0,
        skeleton,
        method,
        BindControl::default(),
    )
    .unwrap()
}

fn joint(name: &str, parent: Option<&str>, p: [f32; 3]) -> JointSpec {
    JointSpec {
        name: name.into(),
        parent: parent.map(Into::into),
        position: p,
    }
}

/// Weight of `joint` in a voxel's skin (0..=1).
fn weight(s: &Skin4, joint: usize) -> f32 {
    s.influences()
        .filter(|&(j, _)| usize::from(j) == joint)
        .map(|(_, w)| w)
        .sum()
}

fn skin_at(svo: &Svo, c: UVec3) -> Skin4 {
    svo.get(c).expect("a voxel").skin
}

/// An L-shaped bar 8 voxels thick: 48 along x, then 48 up y from its far end, with a bone
/// along the middle of each part.
fn bent_bar() -> (Svo, SkeletonSpec) {
    let svo = solid(&[
        (UVec3::new(0, 0, 0), UVec3::new(48, 8, 8)),
        (UVec3::new(40, 8, 0), UVec3::new(48, 56, 8)),
    ]);
    let spec = SkeletonSpec {
        joints: vec![
            joint("a", None, [0.0, 4.0, 4.0]),
            joint("b", Some("a"), [44.0, 4.0, 4.0]),
            joint("tip", Some("b"), [44.0, 56.0, 4.0]),
        ],
    };
    (svo, spec)
}

/// The outer surface's middle line through the corner: along the bottom face, then up the far
/// face.
fn outer_path() -> Vec<UVec3> {
    let mut path: Vec<UVec3> = (24..48).map(|x| UVec3::new(x, 0, 4)).collect();
    path.extend((1..32).map(|y| UVec3::new(47, y, 4)));
    path
}

#[test]
fn a_bent_two_bone_bar_is_rigid_away_from_the_joint_and_blends_smoothly_across_it() {
    let (svo, spec) = bent_bar();
    let skeleton = spec.to_skeleton(None).unwrap();
    let (bound, report) = bind_at_origin(&svo, &skeleton, BindMethod::Geodesic);
    assert_eq!(report.unreachable_voxels, 0);
    assert_eq!(report.cell_size, 1);
    assert_eq!(report.voxels, svo.leaf_count());
    // Far from the corner each bone owns its voxels entirely, through the whole thickness.
    for x in 2..26 {
        for y in 0..8 {
            let s = skin_at(&bound, UVec3::new(x, y, 4));
            assert_eq!(weight(&s, 0), 1.0, "({x}, {y}): {s:?}");
        }
    }
    for y in 24..44 {
        for x in 40..48 {
            let s = skin_at(&bound, UVec3::new(x, y, 4));
            assert!(weight(&s, 1) > 0.99, "({x}, {y}): {s:?}");
        }
    }
    // Along the outer surface through the corner the second bone's weight rises from 0 to 1
    // without a jump, through intermediate values.
    let w: Vec<f32> = outer_path()
        .iter()
        .map(|&c| weight(&skin_at(&bound, c), 1))
        .collect();
    assert!(w[0] == 0.0 && w[w.len() - 1] > 0.99, "{w:?}");
    let blended = w.iter().filter(|&&v| (0.1..0.9).contains(&v)).count();
    assert!(blended >= 6, "only {blended} blended voxels: {w:?}");
    let jump = w
        .windows(2)
        .map(|p| (p[1] - p[0]).abs())
        .fold(0.0, f32::max);
    assert!(jump < 0.2, "largest step {jump} along {w:?}");
    // Every voxel's bytes sum to 255 (leaves and merged inner nodes).
    bound.for_each_leaf(|c, v| {
        let sum: u32 = v.skin.weights.iter().map(|&b| u32::from(b)).sum();
        assert_eq!(sum, 255, "{c}: {:?}", v.skin);
    });
    for s in bound.inner_skin() {
        let sum: u32 = s.weights.iter().map(|&b| u32::from(b)).sum();
        assert_eq!(sum, 255, "inner {s:?}");
    }
    assert_eq!(report.dominant.iter().sum::<u64>(), svo.leaf_count());
    // The leaf joint at the bar's very end owns what lies beyond it: nothing here.
    assert!(
        report.dominant[0] > 0 && report.dominant[1] > 0,
        "{:?}",
        report.dominant
    );
    assert_eq!(report.dominant[2], 0, "{:?}", report.dominant);
}

/// A U whose arms stand one voxel beside a centre column, joined only at the base.
fn u_with_column() -> (Svo, SkeletonSpec) {
    let svo = solid(&[
        (UVec3::new(4, 0, 0), UVec3::new(28, 4, 4)),   // base
        (UVec3::new(9, 4, 0), UVec3::new(13, 40, 4)),  // left arm, x 9..13
        (UVec3::new(14, 4, 0), UVec3::new(18, 40, 4)), // column, x 14..18
        (UVec3::new(19, 4, 0), UVec3::new(23, 40, 4)), // right arm, x 19..23
    ]);
    let spec = SkeletonSpec {
        joints: vec![
            joint("root", None, [16.0, 2.0, 2.0]),
            joint("column", Some("root"), [16.0, 5.0, 2.0]),
            joint("column.end", Some("column"), [16.0, 40.0, 2.0]),
            joint("arm.L", Some("root"), [11.0, 5.0, 2.0]),
            joint("arm.L.end", Some("arm.L"), [11.0, 40.0, 2.0]),
            joint("arm.R", Some("root"), [21.0, 5.0, 2.0]),
            joint("arm.R.end", Some("arm.R"), [21.0, 40.0, 2.0]),
        ],
    };
    (svo, spec)
}

fn column_weight_on_arms(svo: &Svo, skeleton: &super::Skeleton) -> (f32, u32) {
    let column = [
        skeleton.find("column").unwrap(),
        skeleton.find("column.end").unwrap(),
    ];
    let (mut sum, mut voxels) = (0.0, 0);
    svo.for_each_leaf(|c, v| {
        let arm = (9..13).contains(&c.x) || (19..23).contains(&c.x);
        if arm && c.y >= 16 {
            let w: f32 = column.iter().map(|&j| weight(&v.skin, j)).sum();
            sum += w;
            voxels += u32::from(w >= 2.0 / 255.0);
        }
    });
    (sum, voxels)
}

#[test]
fn limbs_beside_a_column_take_no_weight_from_it_geodesically_but_do_by_envelope() {
    let (svo, spec) = u_with_column();
    let skeleton = spec.to_skeleton(None).unwrap();
    let run = |method| {
        bind(
            &svo,
            Vec3::ZERO,
            1.0,
            &skeleton,
            method,
            BindControl::default(),
        )
        .unwrap()
        .0
    };
    let geodesic = run(BindMethod::Geodesic);
    let envelope = run(BindMethod::Envelope);
    let (g, _) = column_weight_on_arms(&geodesic, &skeleton);
    let (e, e_voxels) = column_weight_on_arms(&envelope, &skeleton);
    assert_eq!(
        g, 0.0,
        "geodesic binding leaked the column's weight into the arms"
    );
    assert!(
        e > 1.0 && e_voxels > 50,
        "envelope: {e} over {e_voxels} voxels"
    );
    // Each arm belongs to its own chain.
    let l = skeleton.find("arm.L").unwrap();
    let s = skin_at(&geodesic, UVec3::new(10, 24, 2));
    assert!(weight(&s, l) > 0.97, "{s:?}");
}

#[test]
fn rigid_binding_gives_every_voxel_one_joint() {
    let (svo, spec) = u_with_column();
    let skeleton = spec.to_skeleton(None).unwrap();
    let (bound, report) = bind_at_origin(&svo, &skeleton, BindMethod::Rigid);
    let arm = skeleton.find("arm.L").unwrap();
    bound.for_each_leaf(|c, v| {
        assert_eq!(v.skin.weights, [255, 0, 0, 0], "{c}: {:?}", v.skin);
        if (9..13).contains(&c.x) && c.y >= 16 {
            assert_eq!(usize::from(v.skin.joints[0]), arm, "{c}");
        }
    });
    assert_eq!(report.dominant.iter().sum::<u64>(), svo.leaf_count());
}

#[test]
fn a_shell_is_bound_through_the_space_it_encloses_and_islands_fall_back() {
    // A hollow closed box (shell one voxel thick) with the bone inside, and a floating cube.
    let mut voxels = Vec::new();
    for z in 0..12u32 {
        for y in 0..30u32 {
            for x in 0..12u32 {
                let edge = [x, z].iter().any(|&v| v == 0 || v == 11) || y == 0 || y == 29;
                if edge {
                    voxels.push((UVec3::new(x, y, z), Voxel::new([9, 9, 9, 255], Vec3::Y)));
                }
            }
        }
    }
    for c in [UVec3::new(30, 40, 30), UVec3::new(31, 40, 30)] {
        voxels.push((c, Voxel::new([9, 9, 9, 255], Vec3::Y)));
    }
    let svo = Svo::from_voxels(6, false, voxels).unwrap();
    let skeleton = SkeletonSpec {
        joints: vec![
            joint("low", None, [6.0, 2.0, 6.0]),
            joint("high", Some("low"), [6.0, 15.0, 6.0]),
            joint("top", Some("high"), [6.0, 28.0, 6.0]),
        ],
    }
    .to_skeleton(None)
    .unwrap();
    let (bound, report) = bind_at_origin(&svo, &skeleton, BindMethod::Geodesic);
    assert_eq!(report.unreachable_voxels, 2, "{report:?}");
    // The shell's walls follow the bone inside: each wall voxel's strongest joint is the one
    // whose bone runs past it.
    let strongest = |c: UVec3| usize::from(skin_at(&bound, c).joints[0]);
    assert_eq!(strongest(UVec3::new(0, 6, 6)), 0);
    assert_eq!(strongest(UVec3::new(11, 21, 6)), 1);
    assert_eq!(strongest(UVec3::new(6, 29, 6)), 2);
    assert!(!skin_at(&bound, UVec3::new(30, 40, 30)).is_empty());
}

#[test]
fn the_rest_pose_of_a_native_rig_leaves_every_voxel_where_it_is() {
    let (_, spec) = bent_bar();
    let skeleton = spec.to_skeleton(None).unwrap();
    for m in skeleton.skinning_matrices(&Pose::rest(&skeleton)) {
        assert!(m.abs_diff_eq(glam::Mat4::IDENTITY, 1e-5), "{m}");
    }
    // Joint positions come back from the bind matrices.
    let back = SkeletonSpec::of_skeleton(&skeleton);
    assert_eq!(back.joints[2].position, [44.0, 56.0, 4.0]);
    assert_eq!(back.joints[2].parent.as_deref(), Some("b"));
}

#[test]
fn binding_can_be_cancelled() {
    let (svo, spec) = u_with_column();
    let skeleton = spec.to_skeleton(None).unwrap();
    let cancel = std::sync::atomic::AtomicBool::new(true);
    let err = bind(
        &svo,
        Vec3::ZERO,
        1.0,
        &skeleton,
        BindMethod::Geodesic,
        BindControl {
            progress: None,
            cancel: Some(&cancel),
        },
    )
    .unwrap_err();
    assert!(matches!(err, SkinError::Cancelled), "{err}");
}

#[test]
fn a_model_with_large_bounds_is_bound_on_coarser_cells_with_the_same_ownership() {
    // The bent bar plus one voxel 300 voxels away: the bounds hold more than MAX_GRID_CELLS
    // cells, so the volume is bound on 2-voxel cells.
    let (svo, spec) = bent_bar();
    let mut voxels = svo.leaves();
    voxels.push((UVec3::splat(299), Voxel::new([9, 9, 9, 255], Vec3::Y)));
    let svo = Svo::from_voxels(9, false, voxels).unwrap();
    let skeleton = spec.to_skeleton(None).unwrap();
    let (bound, report) = bind_at_origin(&svo, &skeleton, BindMethod::Geodesic);
    assert_eq!(report.cell_size, 2, "{report:?}");
    assert_eq!(report.unreachable_voxels, 1, "{report:?}");
    for x in 2..26 {
        assert!(
            weight(&skin_at(&bound, UVec3::new(x, 0, 4)), 0) > 0.99,
            "x = {x}"
        );
    }
    for y in 24..44 {
        assert!(
            weight(&skin_at(&bound, UVec3::new(47, y, 4)), 1) > 0.99,
            "y = {y}"
        );
    }
    let w: Vec<f32> = outer_path()
        .iter()
        .map(|&c| weight(&skin_at(&bound, c), 1))
        .collect();
    assert!(
        w.iter().filter(|&&v| (0.1..0.9).contains(&v)).count() >= 4,
        "{w:?}"
    );
}

#[test]
fn skeleton_specs_refuse_bad_input_naming_the_joint() {
    let bounds = Some((Vec3::ZERO, Vec3::splat(10.0)));
    let check = |joints: Vec<JointSpec>, needle: &str| {
        let err = SkeletonSpec { joints }.to_skeleton(bounds).unwrap_err();
        let text = err.to_string();
        assert!(text.contains(needle), "{text:?} should mention {needle:?}");
    };
    check(vec![], "no joints");
    check(
        vec![
            joint("a", Some("b"), [1.0; 3]),
            joint("b", Some("a"), [2.0; 3]),
        ],
        "cycle",
    );
    check(vec![joint("a", Some("nobody"), [1.0; 3])], "\"nobody\"");
    check(
        vec![joint("a", None, [1.0; 3]), joint("a", None, [2.0; 3])],
        "named twice",
    );
    check(vec![joint("far", None, [100.0, 1.0, 1.0])], "\"far\"");
    check(
        vec![joint("nan", None, [f32::NAN, 1.0, 1.0])],
        "non-finite position",
    );
    let many: Vec<JointSpec> = (0..300)
        .map(|i| joint(&format!("j{i}"), None, [1.0; 3]))
        .collect();
    check(many, "at most 256");
    // Just outside is fine (a joint at the tip of a tail).
    SkeletonSpec {
        joints: vec![joint("tip", None, [12.0, 5.0, 5.0])],
    }
    .to_skeleton(bounds)
    .unwrap();
}

fn wave_clip() -> ClipSpec {
    ClipSpec {
        name: "wave".into(),
        length: 1.0,
        interpolation: KeyInterpolation::Linear,
        looping: true,
        keys: vec![
            KeySpec {
                joint: "b".into(),
                time: 0.25,
                rotation_deg: Some([0.0, 0.0, 90.0]),
                translation: None,
            },
            KeySpec {
                joint: "b".into(),
                time: 0.75,
                rotation_deg: Some([0.0, 0.0, 0.0]),
                translation: Some([0.0, 1.0, 0.0]),
            },
        ],
        frame_rate: 24.0,
    }
}

#[test]
fn a_clip_spec_keys_rotations_relative_to_rest_and_spans_its_length() {
    let (_, spec) = bent_bar();
    let skeleton = spec.to_skeleton(None).unwrap();
    let clip = wave_clip().to_clip(&skeleton).unwrap();
    assert_eq!(wave_clip().wrap(), Wrap::Loop);
    assert_eq!(clip.duration_secs, 1.0);
    assert!(
        clip.channels
            .iter()
            .all(|c| c.times[0] == 0.0 && *c.times.last().unwrap() == 1.0)
    );
    let b = skeleton.find("b").unwrap();
    let pose = clip.sample(0.25, &skeleton);
    let expected = glam::Quat::from_rotation_z(90f32.to_radians());
    assert!(
        pose.locals[b].rotation.abs_diff_eq(expected, 1e-5),
        "{:?}",
        pose.locals[b]
    );
    // Held before the first key, interpolated half-way between keys.
    assert!(
        clip.sample(0.0, &skeleton).locals[b]
            .rotation
            .abs_diff_eq(expected, 1e-5)
    );
    let half = clip.sample(0.5, &skeleton).locals[b].rotation;
    assert!(half.abs_diff_eq(glam::Quat::from_rotation_z(45f32.to_radians()), 1e-4));
    // Translations are relative to the rest position.
    let rest = skeleton.joints[b].rest.translation;
    let t = clip.sample(1.0, &skeleton).locals[b].translation;
    assert!(t.abs_diff_eq(rest + Vec3::Y, 1e-5), "{t} vs {rest}");
    // The tip (a child of b) swings with it.
    let m = skeleton.skinning_matrices(&pose);
    // (The translation keyed at 0.75 s holds before it, as glTF clamps.)
    let tip = m[b].transform_point3(Vec3::new(44.0, 56.0, 4.0));
    assert!(
        tip.abs_diff_eq(Vec3::new(44.0 - 52.0, 5.0, 4.0), 1e-3),
        "{tip}"
    );
    // Euler degrees round-trip.
    let q = super::author::euler_deg_to_quat([10.0, -20.0, 30.0]);
    let back = super::author::quat_to_euler_deg(q);
    for (a, b) in back.iter().zip([10.0, -20.0, 30.0]) {
        assert!((a - b).abs() < 1e-3, "{back:?}");
    }
    // Cubic keys pass through their values.
    let mut cubic = wave_clip();
    cubic.interpolation = KeyInterpolation::Cubic;
    let clip = cubic.to_clip(&skeleton).unwrap();
    clip.validate(skeleton.len()).unwrap();
    let at = clip.sample(0.25, &skeleton).locals[b].rotation;
    assert!(at.abs_diff_eq(expected, 1e-4), "{at:?}");
}

#[test]
fn clip_specs_refuse_bad_input_naming_the_key() {
    let (_, spec) = bent_bar();
    let skeleton = spec.to_skeleton(None).unwrap();
    let check = |edit: &dyn Fn(&mut ClipSpec), needle: &str| {
        let mut c = wave_clip();
        edit(&mut c);
        let text = c.to_clip(&skeleton).unwrap_err().to_string();
        assert!(text.contains(needle), "{text:?} should mention {needle:?}");
    };
    check(&|c| c.keys[0].joint = "nobody".into(), "\"nobody\"");
    check(&|c| c.keys[1].time = 2.0, "0..=1");
    check(&|c| c.keys[1].time = f32::NAN, "time NaN");
    check(
        &|c| c.keys[0].rotation_deg = Some([f32::INFINITY, 0.0, 0.0]),
        "not finite",
    );
    check(&|c| c.keys[1].time = 0.25, "two keys");
    check(&|c| c.length = 0.0, "length");
    check(&|c| c.keys.clear(), "no keys");
    check(
        &|c| {
            c.keys[0].rotation_deg = None;
        },
        "give rotation_deg",
    );
}

#[test]
fn binding_a_model_standing_for_more_voxels_than_it_weighs_is_refused() {
    // One 512³ tile and a voxel: 2^27 + 1 voxels in two records; binding weighs each.
    let v = Voxel::new([90, 160, 60, 255], Vec3::Y);
    let svo = Svo::over_listing_limit(v);
    let skeleton = SkeletonSpec {
        joints: vec![JointSpec {
            name: "root".into(),
            parent: None,
            position: [256.0, 256.0, 256.0],
        }],
    }
    .to_skeleton(None)
    .unwrap();
    let Err(e) = bind(
        &svo,
        Vec3::ZERO,
        1.0,
        &skeleton,
        BindMethod::Rigid,
        BindControl::default(),
    ) else {
        panic!("bound a model standing for more voxels than binding lists");
    };
    let text = e.to_string();
    assert!(
        text.contains("134,217,729") && text.contains("larger voxel size"),
        "{text}"
    );
}

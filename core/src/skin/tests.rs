//! Tests for `skin`: real assets (SimpleSkin, RiggedFigure, CesiumMan), sampling, skinning,
//! node weights, stretch factors and numerical extremes.

use std::f32::consts::{FRAC_PI_2, PI};

use glam::{Mat3, Mat4, Quat, Vec3, Vec4};

use super::clip::{hermite, slerp_shortest};
use super::lbs::{blend_matrix, skin_mesh, transform_normal};
use super::stretch::{
    VoxelSkinInput, aabb, decode_override, encode_override, max_singular_value, skin_corners,
    skinned_splat, stretch_from_samples, thesis_factor, voxel_corners,
};
use super::*;
use crate::io::{SkinnedImport, import_skinned, import_skinned_slice, voxelize_skinned};

const SIMPLE_SKIN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/assets/skinned/SimpleSkin.gltf"
);
const RIGGED_FIGURE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/assets/skinned/RiggedFigure.glb"
);
const CESIUM_MAN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/assets/skinned/CesiumMan.glb"
);

fn skinned_positions(import: &SkinnedImport, clip: usize, t: f32) -> Vec<Vec3> {
    let pose = import.clips[clip].sample(t, &import.skeleton);
    let skinning = import.skeleton.skinning_matrices(&pose);
    let mut out = Vec::new();
    for part in &import.mesh.parts {
        let mut skinned = vec![Vec3::ZERO; part.positions.len()];
        skin_points(
            &skinning,
            &part.joints,
            &part.weights,
            &part.positions,
            &mut skinned,
        );
        out.extend(skinned);
    }
    out
}

fn assert_close(actual: Vec3, expected: Vec3, tol: f32, what: &str) {
    assert!(
        (actual - expected).abs().max_element() <= tol,
        "{what}: got {actual}, expected {expected} (±{tol})"
    );
}

// ---------------------------------------------------------------- real assets

#[test]
fn simple_skin_matches_expected_positions_at_one_second() {
    let import = import_skinned(SIMPLE_SKIN).expect("SimpleSkin imports");
    assert_eq!(import.skeleton.len(), 2);
    assert_eq!(import.clips.len(), 1);
    assert_eq!(import.mesh.vertex_count(), 10);
    assert!((import.clips[0].duration_secs - 5.5).abs() < 1e-6);
    let expected = [
        (-0.5, 0.0),
        (0.5, 0.0),
        (-0.25, 0.5),
        (0.5, 0.75),
        (-0.25, 0.75),
        (0.25, 1.25),
        (-0.5, 0.75),
        (-0.25, 1.5),
        (-1.0, 0.5),
        (-1.0, 1.5),
    ];
    let skinned = skinned_positions(&import, 0, 1.0);
    for (i, (&got, &(x, y))) in skinned.iter().zip(&expected).enumerate() {
        assert_close(
            got,
            Vec3::new(x, y, 0.0),
            1e-4,
            &format!("vertex {i} at t = 1 s"),
        );
    }
}

#[test]
fn simple_skin_matches_expected_top_vertices_at_half_second() {
    let import = import_skinned(SIMPLE_SKIN).expect("SimpleSkin imports");
    let skinned = skinned_positions(&import, 0, 0.5);
    assert_close(
        skinned[8],
        Vec3::new(-1.0608, 1.353, 0.0),
        1e-4,
        "vertex 8 at t = 0.5 s",
    );
    assert_close(
        skinned[9],
        Vec3::new(-0.3541, 2.0605, 0.0),
        1e-4,
        "vertex 9 at t = 0.5 s",
    );
    // The bottom row is bound to the unanimated root joint and must not move.
    assert_close(
        skinned[0],
        Vec3::new(-0.5, 0.0, 0.0),
        1e-6,
        "vertex 0 at t = 0.5 s",
    );
}

#[test]
fn simple_skin_rest_pose_is_identity_skinning() {
    let import = import_skinned(SIMPLE_SKIN).expect("SimpleSkin imports");
    let skinning = import
        .skeleton
        .skinning_matrices(&Pose::rest(&import.skeleton));
    for m in &skinning {
        assert!(
            m.abs_diff_eq(Mat4::IDENTITY, 1e-6),
            "rest skinning matrix {m}"
        );
    }
}

/// Max distance between skinned (rest pose) vertices and the bind-pose vertices placed by the
/// skinned node's world transform, and the bind bbox diagonal.
fn rest_pose_error(import: &SkinnedImport) -> (f32, f32) {
    let skinning = import
        .skeleton
        .skinning_matrices(&Pose::rest(&import.skeleton));
    let (lo, hi) = import.mesh.bounds().expect("has vertices");
    let mut err = 0.0f32;
    for part in &import.mesh.parts {
        let skinned = skin_mesh(&skinning, part);
        for (a, b) in skinned.positions.iter().zip(&part.positions) {
            err = err.max(a.distance(import.world_from_skinned_node.transform_point3(*b)));
        }
    }
    (err, (hi - lo).length())
}

fn check_animated_asset(import: &SkinnedImport, clip: usize, times: &[f32]) {
    // Bind pose placed in the world as the rest pose puts it (see `rest_pose_error`).
    let placed: Vec<Vec3> = import
        .mesh
        .parts
        .iter()
        .flat_map(|p| &p.positions)
        .map(|&v| import.world_from_skinned_node.transform_point3(v))
        .collect();
    let (lo, hi) = placed
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    let diag = (hi - lo).length();
    let centre = (lo + hi) * 0.5;
    let mut moved = 0.0f32;
    for &t in times {
        let skinned = skinned_positions(import, clip, t);
        for (p, bind) in skinned.iter().zip(&placed) {
            assert!(p.is_finite(), "non-finite skinned vertex at t = {t}");
            // A walking or waving figure stays within about its own size of where it stood.
            assert!(
                p.distance(centre) < diag * 1.5,
                "vertex {p} far outside the bind bbox at t = {t}"
            );
            moved = moved.max(p.distance(*bind));
        }
    }
    assert!(
        moved > diag * 0.01,
        "the clip should move some vertices (max move {moved}, diag {diag})"
    );
}

#[test]
fn rigged_figure_loads_with_hierarchy_above_the_root_joint() {
    let import = import_skinned(RIGGED_FIGURE).expect("RiggedFigure imports");
    assert_eq!(import.skeleton.len(), 19);
    assert_eq!(import.mesh.vertex_count(), 370);
    assert_eq!(import.clips.len(), 1);
    assert_eq!(import.clips[0].channels.len(), 57);
    assert!(
        (import.clips[0].duration_secs - 1.25).abs() < 1e-6,
        "{}",
        import.clips[0].duration_secs
    );
    // The root joint hangs under Z_UP (a matrix) and Armature: that must be in the attachment.
    let root = &import.skeleton.joints[0];
    assert_eq!(root.name, "torso_joint_1");
    assert!(root.parent.is_none());
    assert!(
        !root
            .parent_from_attachment
            .abs_diff_eq(Mat4::IDENTITY, 1e-3),
        "Z-up matrix above the root is kept"
    );
    // With the ancestors included, the rest pose stands the figure up (Z-up → Y-up) exactly as
    // the node tree above the mesh would; without them it would lie on its back.
    assert!(
        !import
            .world_from_skinned_node
            .abs_diff_eq(Mat4::IDENTITY, 1e-3)
    );
    let (err, diag) = rest_pose_error(&import);
    assert!(
        err < diag * 1e-3,
        "rest pose moves vertices by {err} (diag {diag})"
    );
    assert_eq!(import.weight_repair.all_zero, 0);
    check_animated_asset(&import, 0, &[0.0, 0.3, 0.625, 1.0, 1.25]);
}

#[test]
fn cesium_man_loads_with_texture_and_walk_cycle() {
    let import = import_skinned(CESIUM_MAN).expect("CesiumMan imports");
    assert_eq!(import.skeleton.len(), 19);
    assert_eq!(import.mesh.vertex_count(), 3273);
    assert_eq!(import.clips.len(), 1);
    assert!(
        (import.clips[0].duration_secs - 2.0).abs() < 1e-6,
        "{}",
        import.clips[0].duration_secs
    );
    let tex = import.mesh.materials[0]
        .base_color_texture
        .as_ref()
        .expect("CesiumMan has a base colour texture");
    assert!(tex.width > 0 && tex.rgba8.len() == (tex.width * tex.height * 4) as usize);
    assert!(import.mesh.parts[0].uvs.len() == 3273 && import.mesh.parts[0].normals.len() == 3273);
    let (err, diag) = rest_pose_error(&import);
    assert!(
        err < diag * 1e-3,
        "rest pose moves vertices by {err} (diag {diag})"
    );
    check_animated_asset(&import, 0, &[0.0, 0.5, 1.0, 1.5, 2.0]);
    // Skinned normals stay unit length.
    let pose = import.clips[0].sample(0.7, &import.skeleton);
    let skinned = skin_mesh(
        &import.skeleton.skinning_matrices(&pose),
        &import.mesh.parts[0],
    );
    assert!(
        skinned
            .normals
            .iter()
            .all(|n| (n.length() - 1.0).abs() < 1e-3)
    );
}

// ---------------------------------------------------------------- broken files

fn simple_skin_text() -> String {
    std::fs::read_to_string(SIMPLE_SKIN).expect("SimpleSkin readable")
}

#[test]
fn truncated_file_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let text = simple_skin_text();
    let path = dir.path().join("truncated.gltf");
    std::fs::write(&path, &text[..text.len() / 2]).expect("write");
    let err = import_skinned(&path).expect_err("truncated JSON must fail");
    assert!(err.to_string().contains("truncated.gltf"), "{err}");

    let glb = std::fs::read(CESIUM_MAN).expect("CesiumMan readable");
    for cut in [10, glb.len() / 3, glb.len() - 100] {
        assert!(
            import_skinned_slice(&glb[..cut], "cut.glb").is_err(),
            "GLB cut at {cut} must fail"
        );
    }
}

#[test]
fn inflated_accessor_count_is_an_error_naming_the_accessor() {
    let dir = tempfile::tempdir().expect("temp dir");
    // Accessor 2 (JOINTS_0) claims 1000 elements in a 320-byte view.
    let text = simple_skin_text().replacen(
        "\"count\" : 10,\n    \"type\" : \"VEC4\"",
        "\"count\" : 1000,\n    \"type\" : \"VEC4\"",
        1,
    );
    assert!(text.contains("\"count\" : 1000"), "the edit applied");
    let path = dir.path().join("inflated.gltf");
    std::fs::write(&path, text).expect("write");
    let err = import_skinned(&path).expect_err("inflated count must fail");
    let msg = err.to_string();
    assert!(
        msg.contains("inflated.gltf") && msg.contains("accessor 2"),
        "{msg}"
    );
}

#[test]
fn bad_inputs_never_panic() {
    let text = simple_skin_text();
    // Inflate every count, shrink every byteLength, point strides below element size.
    let variants = [
        text.replace("\"count\" : 10,", "\"count\" : 4000000000,"),
        text.replace(
            "\"byteLength\" : 320,\n    \"byteStride\" : 16",
            "\"byteLength\" : 320,\n    \"byteStride\" : 4",
        ),
        text.replace("\"count\" : 12,", "\"count\" : 13,"),
        text.replace("\"count\" : 24,", "\"count\" : 0,"),
        text.replace(
            "\"componentType\" : 5126,\n    \"count\" : 2,",
            "\"componentType\" : 5123,\n    \"count\" : 2,",
        ),
        text.replace("\"joints\" : [ 1, 2 ]", "\"joints\" : [ 1, 1 ]"),
        text.replace("\"children\" : [ 2 ]", "\"children\" : [ 1 ]"),
        text.replace("\"byteLength\" : 168", "\"byteLength\" : 999"),
    ];
    for (i, v) in variants.iter().enumerate() {
        assert!(
            import_skinned_slice(v.as_bytes(), "variant.gltf").is_err(),
            "variant {i} must fail"
        );
    }
    assert!(matches!(
        import_skinned("/nonexistent/file.glb"),
        Err(SkinError::Io { .. })
    ));
}

// ---------------------------------------------------------------- sampling

fn channel(
    property: Property,
    interpolation: Interpolation,
    times: Vec<f32>,
    values: Vec<Vec4>,
) -> Channel {
    Channel {
        joint: 0,
        property,
        interpolation,
        times,
        values,
    }
}

#[test]
fn cubic_spline_matches_hand_computed_hermite() {
    // Keys at t = 1 and t = 3 (dt = 2); value 1 → 5, out-tangent 2, in-tangent -1.
    let values = vec![
        Vec4::ZERO,
        Vec4::new(1.0, 0.0, 0.0, 0.0),
        Vec4::new(2.0, 0.0, 0.0, 0.0),
        Vec4::new(-1.0, 0.0, 0.0, 0.0),
        Vec4::new(5.0, 0.0, 0.0, 0.0),
        Vec4::ZERO,
    ];
    let c = channel(
        Property::Translation,
        Interpolation::CubicSpline,
        vec![1.0, 3.0],
        values,
    );
    // s = 0.25: h00 = 0.84375, h10 = 0.140625, h01 = 0.15625, h11 = -0.046875;
    // p = 0.84375·1 + 0.140625·(2·2) + 0.15625·5 + (-0.046875)·(-1·2) = 2.28125.
    let v = c.sample(1.5).expect("samples");
    assert!((v.x - 2.281_25).abs() < 1e-6, "{v}");
    assert!((c.sample(1.0).expect("samples").x - 1.0).abs() < 1e-6);
    assert!((c.sample(3.0).expect("samples").x - 5.0).abs() < 1e-6);
    assert!(
        (c.sample(-4.0).expect("samples").x - 1.0).abs() < 1e-6,
        "before the first key holds it"
    );
    let h = hermite(Vec4::ONE, Vec4::ZERO, Vec4::ONE, Vec4::ZERO, 0.37);
    assert!(
        (h - Vec4::ONE).abs().max_element() < 1e-6,
        "flat tangents between equal keys stay put"
    );
}

#[test]
fn cubic_spline_rotation_is_normalised() {
    let q0 = Quat::IDENTITY;
    let q1 = Quat::from_rotation_z(FRAC_PI_2);
    let values = vec![
        Vec4::ZERO,
        Vec4::from(q0),
        Vec4::ZERO,
        Vec4::ZERO,
        Vec4::from(q1),
        Vec4::ZERO,
    ];
    let c = channel(
        Property::Rotation,
        Interpolation::CubicSpline,
        vec![0.0, 1.0],
        values,
    );
    let v = c.sample(0.5).expect("samples");
    assert!((v.length() - 1.0).abs() < 1e-6, "{v}");
}

#[test]
fn step_holds_until_the_next_key() {
    let values = vec![
        Vec4::new(1.0, 0.0, 0.0, 0.0),
        Vec4::new(2.0, 0.0, 0.0, 0.0),
        Vec4::new(3.0, 0.0, 0.0, 0.0),
    ];
    let c = channel(
        Property::Scale,
        Interpolation::Step,
        vec![0.0, 1.0, 2.0],
        values,
    );
    assert_eq!(c.sample(0.999).map(|v| v.x), Some(1.0));
    assert_eq!(c.sample(1.0).map(|v| v.x), Some(2.0));
    assert_eq!(c.sample(1.5).map(|v| v.x), Some(2.0));
    assert_eq!(c.sample(9.0).map(|v| v.x), Some(3.0));
}

#[test]
fn linear_rotation_takes_the_shortest_path() {
    // 170° and -170° about Z are 20° apart; q and -q mixes must not go the long way round.
    let a = Quat::from_rotation_z(170f32.to_radians());
    let b = -Quat::from_rotation_z(-170f32.to_radians());
    let mid = slerp_shortest(a, b, 0.5);
    let expected = Quat::from_rotation_z(PI);
    assert!(mid.dot(expected).abs() > 1.0 - 1e-5, "{mid} vs {expected}");
    // Non-unit input is normalised; 180° apart still gives a unit, finite result.
    let half = slerp_shortest(Quat::IDENTITY * 3.0, Quat::from_rotation_x(PI), 0.5);
    assert!(half.is_finite() && (half.length() - 1.0).abs() < 1e-6);
    assert!((half.angle_between(Quat::IDENTITY) - FRAC_PI_2).abs() < 1e-4);
    // Identical and zero quaternions.
    assert!(slerp_shortest(a, a, 0.3).abs_diff_eq(a, 1e-6));
    assert_eq!(
        slerp_shortest(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0), Quat::IDENTITY, 0.5),
        Quat::IDENTITY
    );
}

#[test]
fn wrap_modes_clamp_and_loop() {
    let clip = AnimationClip {
        name: "c".into(),
        duration_secs: 2.0,
        ..AnimationClip::default()
    };
    assert_eq!(clip.wrap_time(5.0, Wrap::Clamp), 2.0);
    assert_eq!(clip.wrap_time(-1.0, Wrap::Clamp), 0.0);
    assert!((clip.wrap_time(5.0, Wrap::Loop) - 1.0).abs() < 1e-6);
    assert!((clip.wrap_time(-0.5, Wrap::Loop) - 1.5).abs() < 1e-6);
    assert_eq!(clip.wrap_time(f32::NAN, Wrap::Loop), 0.0);
    // Looping a real clip: one period later gives the same pose.
    let import = import_skinned(SIMPLE_SKIN).expect("imports");
    let c = &import.clips[0];
    let a = c.sample_wrapped(1.25, Wrap::Loop, &import.skeleton);
    let b = c.sample_wrapped(1.25 + 2.0 * c.duration_secs, Wrap::Loop, &import.skeleton);
    assert!(a.locals[1].rotation.abs_diff_eq(b.locals[1].rotation, 1e-5));
    let clamped = c.sample(100.0, &import.skeleton);
    assert_eq!(clamped, c.sample(c.duration_secs, &import.skeleton));
    let empty = AnimationClip::default();
    assert_eq!(empty.wrap_time(3.0, Wrap::Loop), 0.0);
}

#[test]
fn clip_validation_reports_bad_channels() {
    let mut clip = AnimationClip {
        name: "bad".into(),
        duration_secs: 1.0,
        channels: vec![channel(
            Property::Translation,
            Interpolation::CubicSpline,
            vec![0.0, 1.0],
            vec![Vec4::ZERO; 4],
        )],
        ..AnimationClip::default()
    };
    let err = clip
        .validate(1)
        .expect_err("cubic needs 3 values per key")
        .to_string();
    assert!(err.contains("bad") && err.contains("channel 0"), "{err}");
    clip.channels[0] = channel(
        Property::Translation,
        Interpolation::Linear,
        vec![1.0, 0.5],
        vec![Vec4::ZERO; 2],
    );
    assert!(clip.validate(1).is_err(), "decreasing times");
    clip.channels[0].times = vec![0.0, 1.0];
    assert!(clip.validate(0).is_err(), "joint out of range");
    assert!(clip.validate(1).is_ok());
    // Malformed channels sample to None instead of panicking.
    clip.channels[0].values.clear();
    assert_eq!(clip.channels[0].sample(0.5), None);
}

// ---------------------------------------------------------------- skeleton and pose

fn joint(name: &str, parent: Option<usize>, translation: Vec3) -> Joint {
    Joint {
        name: name.into(),
        parent,
        rest: Transform {
            translation,
            ..Transform::IDENTITY
        },
        inverse_bind: Mat4::from_translation(-translation),
        ..Joint::default()
    }
}

#[test]
fn skeleton_reorders_topologically_and_rejects_cycles() {
    // c's parent is b, b's parent is a, listed c, a, b.
    let joints = vec![
        joint("c", Some(2), Vec3::X),
        joint("a", None, Vec3::ZERO),
        joint("b", Some(1), Vec3::Y),
    ];
    let (sk, new_from_old) = Skeleton::new(joints).expect("valid forest");
    let names: Vec<&str> = sk.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(names, ["a", "b", "c"]);
    assert_eq!(new_from_old, [2, 0, 1]);
    assert_eq!(sk.joints[2].parent, Some(1));
    assert!(sk.validate().is_ok());

    let cycle = vec![
        joint("x", Some(1), Vec3::ZERO),
        joint("y", Some(0), Vec3::ZERO),
    ];
    let err = Skeleton::new(cycle).expect_err("cycle");
    assert!(matches!(err, SkinError::Cycle { .. }), "{err}");
    assert!(err.to_string().contains("cycle"));
    assert!(matches!(
        Skeleton::new(vec![joint("s", Some(0), Vec3::ZERO)]),
        Err(SkinError::Cycle { .. })
    ));
    assert!(matches!(
        Skeleton::new(vec![joint("p", Some(5), Vec3::ZERO)]),
        Err(SkinError::ParentOutOfRange { .. })
    ));
    let mut nan = joint("n", None, Vec3::ZERO);
    nan.rest.scale.y = f32::NAN;
    assert!(matches!(
        Skeleton::new(vec![nan]),
        Err(SkinError::NonFiniteJoint { .. })
    ));
    // An unsorted skeleton from a file fails validation.
    let unsorted = Skeleton {
        joints: vec![joint("c", Some(1), Vec3::X), joint("a", None, Vec3::ZERO)],
    };
    assert!(matches!(
        unsorted.validate(),
        Err(SkinError::NotTopological {
            joint: 0,
            parent: 1,
            ..
        })
    ));
    let looped = Skeleton {
        joints: vec![
            joint("x", Some(1), Vec3::X),
            joint("y", Some(0), Vec3::ZERO),
        ],
    };
    assert!(matches!(looped.validate(), Err(SkinError::Cycle { .. })));
}

fn chain() -> Skeleton {
    // Root at the origin, child one unit up: a two-bone arm along +Y.
    Skeleton::new(vec![
        joint("root", None, Vec3::ZERO),
        joint("tip", Some(0), Vec3::Y),
    ])
    .expect("valid")
    .0
}

#[test]
fn overrides_layer_on_the_rest_pose() {
    let sk = chain();
    let mut pose = Pose::rest(&sk);
    let skipped = pose.apply_overrides(&[
        JointOverride {
            joint: 0,
            rotation: Some(Quat::from_rotation_z(FRAC_PI_2) * 2.0),
            ..JointOverride::default()
        },
        JointOverride {
            joint: 1,
            translation: Some(Vec3::new(0.0, 1.0, 0.0)),
            mode: OverrideMode::Relative,
            ..JointOverride::default()
        },
        JointOverride {
            joint: 7,
            rotation: Some(Quat::IDENTITY),
            ..JointOverride::default()
        },
        JointOverride {
            joint: 0,
            translation: Some(Vec3::NAN),
            ..JointOverride::default()
        },
    ]);
    assert_eq!(skipped, 2);
    let mut m = JointMatrices::default();
    sk.compute_matrices(&pose, &mut m);
    // Tip: 2 units along +Y, rotated 90° about Z → (-2, 0, 0).
    let tip = m.world_from_joint[1].transform_point3(Vec3::ZERO);
    assert!(tip.abs_diff_eq(Vec3::new(-2.0, 0.0, 0.0), 1e-5), "{tip}");
    // Relative rotation composes with the pose below.
    let mut rel = pose.clone();
    rel.apply_overrides(&[JointOverride {
        joint: 0,
        rotation: Some(Quat::from_rotation_z(FRAC_PI_2)),
        mode: OverrideMode::Relative,
        ..JointOverride::default()
    }]);
    let tip = sk.skinning_matrices(&rel)[1].transform_point3(Vec3::Y);
    assert!(tip.abs_diff_eq(Vec3::new(0.0, -2.0, 0.0), 1e-5), "{tip}");
    // Scale: replace sets it, relative multiplies the pose's; the child moves with it; a
    // non-finite scale is skipped like the other values.
    let mut scaled = pose.clone();
    let skipped = scaled.apply_overrides(&[
        JointOverride {
            joint: 0,
            scale: Some(Vec3::new(1.0, 3.0, 1.0)),
            ..JointOverride::default()
        },
        JointOverride {
            joint: 0,
            scale: Some(Vec3::new(2.0, 0.5, 1.0)),
            mode: OverrideMode::Relative,
            ..JointOverride::default()
        },
        JointOverride {
            joint: 1,
            scale: Some(Vec3::NAN),
            ..JointOverride::default()
        },
    ]);
    assert_eq!(skipped, 1);
    assert_eq!(scaled.locals[0].scale, Vec3::new(2.0, 1.5, 1.0));
    let mut m = JointMatrices::default();
    sk.compute_matrices(&scaled, &mut m);
    let child = m.world_from_joint[1].transform_point3(Vec3::ZERO);
    let unscaled = {
        let mut m0 = JointMatrices::default();
        sk.compute_matrices(&pose, &mut m0);
        m0.world_from_joint[1].transform_point3(Vec3::ZERO)
    };
    assert!(
        (child.length() - 1.5 * unscaled.length()).abs() < 1e-4,
        "{child} vs {unscaled}"
    );
}

#[test]
fn serde_defaults_fill_missing_fields() {
    let sk: Skeleton = serde_json::from_str(r#"{"joints":[{"name":"a"}]}"#).expect("parses");
    assert_eq!(sk.joints[0].inverse_bind, Mat4::IDENTITY);
    assert_eq!(sk.joints[0].rest, Transform::IDENTITY);
    let clip: AnimationClip =
        serde_json::from_str(r#"{"channels":[{"times":[0.0]}]}"#).expect("parses");
    assert_eq!(clip.channels[0].interpolation, Interpolation::Linear);
    let s: StretchSettings = serde_json::from_str(r#"{"strategy":"Adaptive"}"#).expect("parses");
    assert_eq!(s.strategy, StretchStrategy::Adaptive);
    assert_eq!(s.multiplier, 1.0);
    let import = import_skinned(SIMPLE_SKIN).expect("imports");
    let json = serde_json::to_string(&(&import.skeleton, &import.clips)).expect("serialises");
    let back: (Skeleton, Vec<AnimationClip>) = serde_json::from_str(&json).expect("round trip");
    assert_eq!(back.0, import.skeleton);
    assert_eq!(back.1, import.clips);
}

// ---------------------------------------------------------------- extremes

fn all_finite(ms: &[Mat4]) -> bool {
    ms.iter().all(Mat4::is_finite)
}

#[test]
fn joint_rotated_180_degrees_stays_finite_and_exact() {
    let sk = chain();
    let mut pose = Pose::rest(&sk);
    pose.locals[1].rotation = Quat::from_rotation_x(PI);
    let skinning = sk.skinning_matrices(&pose);
    assert!(all_finite(&skinning));
    // A point one unit above the tip flips to one unit below it.
    let p = skin_point(
        &skinning,
        [1, 0, 0, 0],
        [1.0, 0.0, 0.0, 0.0],
        Vec3::new(0.0, 2.0, 0.0),
    );
    assert!(p.abs_diff_eq(Vec3::ZERO, 1e-5), "{p}");
    // Half-and-half blend across a 180° joint collapses the linear part (candy wrapper): the
    // normal must still be finite and unit.
    let n = skin_normal(&skinning, [0, 1, 0, 0], [0.5, 0.5, 0.0, 0.0], Vec3::Z);
    assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-5, "{n}");
    let q = skin_point(
        &skinning,
        [0, 1, 0, 0],
        [0.5, 0.5, 0.0, 0.0],
        Vec3::new(0.0, 1.5, 0.0),
    );
    assert!(q.is_finite());
}

#[test]
fn zero_length_bone_and_zero_scale_give_no_nan() {
    // Child at the same place as its parent (zero-length bone), scaled to 0.
    let sk = Skeleton::new(vec![
        joint("root", None, Vec3::ZERO),
        joint("tip", Some(0), Vec3::ZERO),
    ])
    .expect("ok")
    .0;
    let mut pose = Pose::rest(&sk);
    pose.locals[1].scale = Vec3::ZERO;
    pose.locals[1].rotation = Quat::from_rotation_y(1.0);
    let skinning = sk.skinning_matrices(&pose);
    assert!(all_finite(&skinning));
    let p = skin_point(
        &skinning,
        [1, 0, 0, 0],
        [1.0, 0.0, 0.0, 0.0],
        Vec3::new(0.3, 0.4, 0.5),
    );
    assert!(
        p.abs_diff_eq(Vec3::ZERO, 1e-6),
        "fully collapsed joint collapses its points: {p}"
    );
    for n in [Vec3::X, Vec3::Y, Vec3::Z, Vec3::ZERO] {
        let out = skin_normal(&skinning, [1, 0, 0, 0], [1.0, 0.0, 0.0, 0.0], n);
        assert!(out.is_finite(), "normal {n} → {out}");
        let blended = skin_normal(&skinning, [1, 0, 0, 0], [0.5, 0.5, 0.0, 0.0], n);
        assert!(blended.is_finite());
    }
    // Scale 0 on one axis: normals along that axis survive via the cofactor.
    let flat = Mat3::from_diagonal(Vec3::new(1.0, 0.0, 1.0));
    assert!(transform_normal(flat, Vec3::Y).abs_diff_eq(Vec3::Y, 1e-6));
    let sideways = transform_normal(flat, Vec3::X);
    assert!(sideways.is_finite() && (sideways.length() - 1.0).abs() < 1e-6);
    // Mirroring keeps outward normals outward.
    let mirror = Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0));
    assert!(transform_normal(mirror, Vec3::X).abs_diff_eq(-Vec3::X, 1e-6));
    // Non-uniform scale: the normal of the plane x + y = 0 stays perpendicular to it.
    let squash = Mat3::from_diagonal(Vec3::new(2.0, 0.5, 1.0));
    let n = transform_normal(squash, Vec3::new(1.0, 1.0, 0.0).normalize_or_zero());
    let tangent = squash * Vec3::new(1.0, -1.0, 0.0);
    assert!(n.dot(tangent).abs() < 1e-6);
    // Absurd scales overflow to infinity in the matrix product: FK keeps the parent frame.
    pose.locals[1].scale = Vec3::splat(1e30);
    pose.locals[0].scale = Vec3::splat(1e30);
    assert!(all_finite(&sk.skinning_matrices(&pose)));
}

#[test]
fn weight_repair_fixes_and_counts() {
    let mut j = [0, 1, 2, 3];
    let mut w = [-0.5, 0.5, 0.5, f32::NAN];
    let r = repair_weights(&mut j, &mut w, 4);
    assert_eq!((r.negative, r.non_finite, r.renormalised), (1, 1, 0));
    assert_eq!(w, [0.0, 0.5, 0.5, 0.0]);

    let mut w = [0.0; 4];
    let r = repair_weights(&mut j, &mut w, 4);
    assert_eq!(r.all_zero, 1);
    assert_eq!((j, w), ([0; 4], [1.0, 0.0, 0.0, 0.0]));

    let mut j = [1, 2, 0, 0];
    let mut w = [2.0, 2.0, 0.0, 0.0];
    let r = repair_weights(&mut j, &mut w, 4);
    assert_eq!(r.renormalised, 1);
    assert_eq!(w, [0.5, 0.5, 0.0, 0.0]);

    let mut j = [9, 1, 0, 0];
    let mut w = [0.5, 0.5, 0.0, 0.0];
    let r = repair_weights(&mut j, &mut w, 4);
    assert_eq!(r.out_of_range, 1);
    assert_eq!((j[0], w), (0, [0.0, 1.0, 0.0, 0.0]));
    assert_eq!(r.total(), 2, "out of range and renormalised");
    assert_eq!(
        r.to_string(),
        "1 vertex weighted on a joint the skeleton does not have (set to 0), 1 whose weights \
         did not sum to 1 (renormalised)"
    );
    let mut many = r;
    many.add(&WeightRepair {
        negative: 2,
        ..WeightRepair::default()
    });
    assert_eq!(
        many.to_string(),
        "2 vertices with a negative weight (set to 0), 1 weighted on a joint the skeleton does \
         not have (set to 0), 1 whose weights did not sum to 1 (renormalised)"
    );
    assert_eq!(WeightRepair::default().to_string(), "no vertex");

    // unorm8 rounding (sum 254/255) is fixed silently.
    let mut w = [127.0 / 255.0, 127.0 / 255.0, 0.0, 0.0];
    let r = repair_weights(&mut [0, 1, 0, 0], &mut w, 4);
    assert_eq!(r.total(), 0);
    assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);

    // Unrepaired garbage through skin_point: out-of-range joints are skipped, no panic.
    let p = skin_point(
        &[Mat4::IDENTITY],
        [5, 0, 0, 0],
        [1.0, 0.0, 0.0, 0.0],
        Vec3::ONE,
    );
    assert_eq!(p, Vec3::ZERO);
    assert_eq!(blend_matrix(&[], [0; 4], [1.0, 0.0, 0.0, 0.0]), Mat4::ZERO);
}

// ---------------------------------------------------------------- node skins

#[test]
fn node_skin_quantises_to_255_and_keeps_the_strongest() {
    let s = Skin4::from_influences(&[
        (3, 0.1),
        (5, 0.2),
        (3, 0.2),
        (7, 0.05),
        (9, 0.15),
        (11, 0.3),
    ]);
    // Joint 3: 0.3 (summed), 11: 0.3, 5: 0.2, 9: 0.15; joint 7 (0.05) is dropped.
    assert_eq!(s.joints, [3, 11, 5, 9]);
    assert_eq!(s.weights.iter().map(|&w| u32::from(w)).sum::<u32>(), 255);
    let expected = [0.3, 0.3, 0.2, 0.15].map(|w| w / 0.95 * 255.0);
    for (&got, want) in s.weights.iter().zip(expected) {
        assert!((f32::from(got) - want).abs() <= 1.0, "{s:?}");
    }
    assert!(Skin4::from_influences(&[(4, -1.0), (2, f32::NAN)]).is_empty());
    assert!(Skin4::from_influences(&[]).is_empty());
    let thirds = Skin4::from_vertex([1, 2, 3, 0], [1.0, 1.0, 1.0, 0.0]);
    assert_eq!(thirds.weights, [85, 85, 85, 0]);
    assert_eq!(thirds.nonzero_count(), 3);
    // Many distinct joints (more than the fixed accumulator holds).
    let many: Vec<(u16, f32)> = (0..100u16).map(|j| (j, f32::from(j))).collect();
    assert_eq!(Skin4::from_influences(&many).joints, [99, 98, 97, 96]);
    // Joints a byte cannot address are refused, never wrapped onto another joint.
    let wide = Skin4::from_influences(&[(300, 0.9), (2, 0.1)]);
    assert_eq!((wide.joints[0], wide.weights[0]), (2, 255));
    // The empty skin blends as the root; a real one as its weights.
    assert_eq!(Skin4::default().blend_weights(), [1.0, 0.0, 0.0, 0.0]);
    let w = thirds.blend_weights();
    assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6, "{w:?}");
}

#[test]
fn merge_sums_children_weights() {
    let a = Skin4 {
        joints: [1, 2, 0, 0],
        weights: [200, 55, 0, 0],
    };
    let b = Skin4 {
        joints: [2, 3, 0, 0],
        weights: [155, 100, 0, 0],
    };
    let m = Skin4::merge(&[a, b]);
    // Joint 2: 210, joint 1: 200, joint 3: 100 out of 510.
    assert_eq!(&m.joints[..3], &[2, 1, 3]);
    assert_eq!(m.weights.iter().map(|&w| u32::from(w)).sum::<u32>(), 255);
    assert_eq!(m.weights[3], 0);
    assert!(
        (i32::from(m.weights[0]) - 105).abs() <= 1 && (i32::from(m.weights[1]) - 100).abs() <= 1
    );
    assert!(Skin4::merge(&[]).is_empty());
    assert!(Skin4::merge(&[Skin4::default(), Skin4::default()]).is_empty());
    assert_eq!(
        Skin4::merge(&[a]),
        Skin4::from_vertex([1, 2, 0, 0], [200.0, 55.0, 0.0, 0.0])
    );
    // Five joints over eight children: the weakest is dropped, ties go to the lower joint.
    let kids: Vec<Skin4> = (0..8u8)
        .map(|i| Skin4 {
            joints: [i % 5, 0, 0, 0],
            weights: [255, 0, 0, 0],
        })
        .collect();
    let m = Skin4::merge(&kids);
    assert_eq!(
        m.joints,
        [0, 1, 2, 3],
        "joints 0–2 have two children each, 3 and 4 tie: 3 wins"
    );
}

// ---------------------------------------------------------------- stretch

#[test]
fn thesis_factor_follows_the_paper() {
    assert_eq!(
        thesis_factor(&Skin4 {
            joints: [0; 4],
            weights: [255, 0, 0, 0]
        }),
        1.0
    );
    assert_eq!(
        thesis_factor(&Skin4 {
            joints: [0, 1, 0, 0],
            weights: [200, 55, 0, 0]
        }),
        2.0
    );
    assert_eq!(
        thesis_factor(&Skin4 {
            joints: [0, 1, 2, 3],
            weights: [100, 55, 50, 50]
        }),
        2.0
    );
    assert_eq!(
        thesis_factor(&Skin4 {
            joints: [0; 4],
            weights: [0; 4]
        }),
        1.0,
        "no weights: 1, not 0"
    );
}

#[test]
fn singular_values_and_sample_stretch() {
    assert!((max_singular_value(Mat3::IDENTITY) - 1.0).abs() < 1e-6);
    let r = Mat3::from_quat(Quat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -2.0));
    assert!((max_singular_value(r) - 1.0).abs() < 1e-5);
    assert!(
        (max_singular_value(r * Mat3::from_diagonal(Vec3::new(1.0, 3.0, 0.5))) - 3.0).abs() < 1e-4
    );
    assert!(
        (max_singular_value(Mat3::from_cols(Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Z))
            - 1.618_034)
            .abs()
            < 1e-4
    );
    assert_eq!(max_singular_value(Mat3::ZERO), 0.0);
    assert!(max_singular_value(Mat3::from_diagonal(Vec3::splat(1e25))).is_finite());

    let bind = voxel_corners(Vec3::new(1.0, 2.0, 3.0), 0.5);
    let rotated: Vec<Vec3> = bind
        .iter()
        .map(|&p| Mat3::from_rotation_z(0.7) * p + Vec3::X)
        .collect();
    assert!(
        (stretch_from_samples(&bind, &rotated).expect("8 points") - 1.0).abs() < 1e-5,
        "rigid: S = 1"
    );
    let stretched: Vec<Vec3> = bind.iter().map(|&p| p * Vec3::new(1.0, 1.0, 2.5)).collect();
    assert!((stretch_from_samples(&bind, &stretched).expect("8 points") - 2.5).abs() < 1e-5);
    assert_eq!(stretch_from_samples(&bind[..1], &rotated[..1]), None);
    // The cube-specialised form agrees with the generic one on arbitrary deformations.
    let warped: [Vec3; 8] = std::array::from_fn(|k| {
        let p = bind[k];
        Vec3::new(p.x + 0.3 * p.y * p.y, p.y * 1.7, p.z - 0.2 * p.x)
    });
    let generic = stretch_from_samples(&bind, &warped).expect("8 points");
    let cube = stretch::stretch_from_corners(&warped, 0.5).expect("valid cube");
    assert!((generic - cube).abs() < 1e-4, "{generic} vs {cube}");
    assert_eq!(stretch::stretch_from_corners(&warped, 0.0), None);
    assert_eq!(
        stretch_from_samples(&[Vec3::ONE; 2], &[Vec3::ZERO, Vec3::X]),
        None,
        "coincident bind points"
    );
}

#[test]
fn override_codes_round_trip() {
    assert_eq!(decode_override(0), None);
    assert_eq!(decode_override(64), Some(1.0));
    assert_eq!(encode_override(1.5), 96);
    assert_eq!(encode_override(0.0), 0);
    assert_eq!(encode_override(f32::NAN), 0);
    assert_eq!(encode_override(100.0), 255);
    for code in 1..=255u8 {
        assert_eq!(encode_override(decode_override(code).expect("some")), code);
    }
}

/// A bent elbow: joint 1 rotates 90° about Z around the point (0, 1, 0).
fn elbow() -> (Vec<Mat4>, [Skin4; 8], Vec3, f32) {
    let sk = chain();
    let mut pose = Pose::rest(&sk);
    pose.locals[1].rotation = Quat::from_rotation_z(FRAC_PI_2);
    let skinning = sk.skinning_matrices(&pose);
    // A voxel straddling the joint: lower corners on joint 0, upper corners on joint 1.
    let centre = Vec3::new(0.1, 1.0, 0.0);
    let half = 0.05;
    let corner_skins = std::array::from_fn(|k| {
        if k & 2 == 0 {
            Skin4 {
                joints: [0; 4],
                weights: [255, 0, 0, 0],
            }
        } else {
            Skin4 {
                joints: [1, 0, 0, 0],
                weights: [255, 0, 0, 0],
            }
        }
    });
    (skinning, corner_skins, centre, half)
}

#[test]
fn splat_strategies_order_holes_and_bloat() {
    let (skinning, corner_skins, center, half) = elbow();
    let skin = Skin4 {
        joints: [0, 1, 0, 0],
        weights: [128, 127, 0, 0],
    };
    let input = VoxelSkinInput {
        center,
        half_size: half,
        skin,
        corner_skins: Some(&corner_skins),
        override_code: 0,
    };
    let splat = |strategy| {
        skinned_splat(
            &StretchSettings {
                strategy,
                ..StretchSettings::default()
            },
            &skinning,
            &input,
        )
    };
    let off = splat(StretchStrategy::Off);
    let thesis = splat(StretchStrategy::Thesis);
    let corners = splat(StretchStrategy::Corners);
    let adaptive = splat(StretchStrategy::Adaptive);
    assert_eq!(off.half_extent, Vec3::splat(half));
    assert_eq!(thesis.half_extent, Vec3::splat(2.0 * half));
    // Corners: the box holds all eight skinned corners.
    let skinned = skin_corners(&skinning, &voxel_corners(center, half), &corner_skins);
    let (lo, hi) = aabb(&skinned);
    assert!(
        corners.center.abs_diff_eq((lo + hi) * 0.5, 1e-6)
            && corners.half_extent.abs_diff_eq((hi - lo) * 0.5, 1e-6)
    );
    // Adaptive measures the stretch across the joint: more than 1, finite.
    assert!(
        adaptive.half_extent.x > half * 1.01 && adaptive.half_extent.is_finite(),
        "{adaptive:?}"
    );
    // Without corner data Corners falls back to Thesis and Adaptive to the blended linear part
    // (a 50/50 blend of two rotations shrinks, so min_factor = 1 holds it at 1).
    let bare = VoxelSkinInput {
        corner_skins: None,
        ..input
    };
    let settings = |strategy| StretchSettings {
        strategy,
        ..StretchSettings::default()
    };
    assert_eq!(
        skinned_splat(&settings(StretchStrategy::Corners), &skinning, &bare).half_extent,
        thesis.half_extent
    );
    assert_eq!(
        skinned_splat(&settings(StretchStrategy::Adaptive), &skinning, &bare).half_extent,
        Vec3::splat(half)
    );
    // Override replaces the strategy's factor; the multiplier scales everything.
    let painted = VoxelSkinInput {
        override_code: encode_override(3.0),
        ..input
    };
    let s = StretchSettings {
        strategy: StretchStrategy::Thesis,
        multiplier: 0.5,
        ..StretchSettings::default()
    };
    assert!(
        skinned_splat(&s, &skinning, &painted)
            .half_extent
            .abs_diff_eq(Vec3::splat(1.5 * half), 1e-6)
    );
    // Garbage settings are sanitised.
    let nan = StretchSettings {
        strategy: StretchStrategy::Adaptive,
        multiplier: f32::NAN,
        min_factor: -1.0,
        max_factor: f32::INFINITY,
    };
    assert!(
        skinned_splat(&nan, &skinning, &input)
            .half_extent
            .is_finite()
    );
}

#[test]
fn splats_stay_finite_with_a_collapsed_joint() {
    let sk = chain();
    let mut pose = Pose::rest(&sk);
    pose.locals[1].scale = Vec3::ZERO;
    let skinning = sk.skinning_matrices(&pose);
    let (_, corner_skins, center, half) = elbow();
    let input = VoxelSkinInput {
        center,
        half_size: half,
        skin: Skin4 {
            joints: [1, 0, 0, 0],
            weights: [255, 0, 0, 0],
        },
        corner_skins: Some(&corner_skins),
        override_code: 0,
    };
    for strategy in [
        StretchStrategy::Off,
        StretchStrategy::Thesis,
        StretchStrategy::Corners,
        StretchStrategy::Adaptive,
    ] {
        let s = StretchSettings {
            strategy,
            ..StretchSettings::default()
        };
        let b = skinned_splat(&s, &skinning, &input);
        assert!(
            b.center.is_finite() && b.half_extent.is_finite(),
            "{strategy:?}: {b:?}"
        );
        let bare = skinned_splat(
            &s,
            &skinning,
            &VoxelSkinInput {
                corner_skins: None,
                ..input
            },
        );
        assert!(
            bare.center.is_finite() && bare.half_extent.is_finite(),
            "{strategy:?}: {bare:?}"
        );
    }
}

#[test]
fn adaptive_is_one_under_rigid_motion_where_thesis_doubles() {
    let sk = chain();
    let mut pose = Pose::rest(&sk);
    pose.locals[0].rotation = Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.4);
    pose.locals[0].translation = Vec3::new(3.0, -1.0, 2.0);
    let skinning = sk.skinning_matrices(&pose);
    // Two non-zero weights on joints that move rigidly together.
    let skin = Skin4 {
        joints: [0, 1, 0, 0],
        weights: [128, 127, 0, 0],
    };
    let corners = [skin; 8];
    let input = VoxelSkinInput {
        center: Vec3::new(0.0, 0.5, 0.0),
        half_size: 0.05,
        skin,
        corner_skins: Some(&corners),
        override_code: 0,
    };
    let settings = |strategy| StretchSettings {
        strategy,
        min_factor: 0.0,
        ..StretchSettings::default()
    };
    let adaptive = skinned_splat(&settings(StretchStrategy::Adaptive), &skinning, &input);
    let thesis = skinned_splat(&settings(StretchStrategy::Thesis), &skinning, &input);
    assert!((adaptive.half_extent.x - 0.05).abs() < 1e-5, "{adaptive:?}");
    assert!((thesis.half_extent.x - 0.1).abs() < 1e-6);
    assert!(adaptive.center.abs_diff_eq(thesis.center, 1e-6));
    // Shrinking the skeleton by half: Adaptive follows (with min_factor 0), Thesis does not.
    pose.locals[0].scale = Vec3::splat(0.5);
    let skinning = sk.skinning_matrices(&pose);
    let adaptive = skinned_splat(&settings(StretchStrategy::Adaptive), &skinning, &input);
    assert!(
        (adaptive.half_extent.x - 0.025).abs() < 1e-5,
        "{adaptive:?}"
    );
}

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[((n >> (18 - 6 * k)) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// SimpleSkin with JOINTS_0 as u8 and WEIGHTS_0 as unorm8 or unorm16, in a new buffer.
fn simple_skin_quantised(weights_u16: bool) -> Vec<u8> {
    let reference = import_skinned(SIMPLE_SKIN).expect("imports");
    let part = &reference.mesh.parts[0];
    let mut bytes: Vec<u8> = part
        .joints
        .iter()
        .flat_map(|j| j.map(|x| x as u8))
        .collect();
    let joints_len = bytes.len();
    for w in &part.weights {
        for &x in w {
            if weights_u16 {
                bytes.extend(((x * 65535.0).round() as u16).to_le_bytes());
            } else {
                bytes.push((x * 255.0).round() as u8);
            }
        }
    }
    let mut doc: serde_json::Value = serde_json::from_str(&simple_skin_text()).expect("JSON");
    doc["buffers"]
        .as_array_mut()
        .expect("buffers")
        .push(serde_json::json!({
            "uri": format!("data:application/gltf-buffer;base64,{}", base64(&bytes)),
            "byteLength": bytes.len(),
        }));
    let views = doc["bufferViews"].as_array_mut().expect("views");
    views.push(serde_json::json!({ "buffer": 4, "byteLength": joints_len }));
    views.push(serde_json::json!({ "buffer": 4, "byteOffset": joints_len, "byteLength": bytes.len() - joints_len }));
    doc["accessors"][2] =
        serde_json::json!({ "bufferView": 5, "componentType": 5121, "count": 10, "type": "VEC4" });
    let weight_type = if weights_u16 { 5123 } else { 5121 };
    doc["accessors"][3] = serde_json::json!({ "bufferView": 6, "componentType": weight_type, "normalized": true, "count": 10, "type": "VEC4" });
    serde_json::to_vec(&doc).expect("serialises")
}

#[test]
fn u8_joints_and_unorm_weights_import() {
    let reference = import_skinned(SIMPLE_SKIN).expect("imports");
    let expected = skinned_positions(&reference, 0, 1.0);
    for (weights_u16, tol) in [(false, 5e-3), (true, 1e-4)] {
        let bytes = simple_skin_quantised(weights_u16);
        let import =
            import_skinned_slice(&bytes, "quantised.gltf").expect("quantised SimpleSkin imports");
        assert_eq!(import.mesh.parts[0].joints, reference.mesh.parts[0].joints);
        assert_eq!(
            import.weight_repair.total(),
            0,
            "quantisation alone is not a repair"
        );
        let got = skinned_positions(&import, 0, 1.0);
        for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
            assert_close(
                *g,
                *e,
                tol,
                &format!("vertex {i}, unorm{}", if weights_u16 { 16 } else { 8 }),
            );
        }
    }
}

// ---------------------------------------------------------------- skinned voxel models

#[test]
fn rigged_figure_voxelizes_with_normalised_weights_that_follow_the_mesh() {
    use crate::voxelize::{Resolution, VoxelizeSettings};
    let import = import_skinned(RIGGED_FIGURE).expect("RiggedFigure imports");
    let settings = VoxelizeSettings {
        resolution: Resolution::Depth(6),
        ..VoxelizeSettings::default()
    };
    let v = voxelize_skinned(&import, &settings, &|_| true).expect("voxelizes");
    let model = &v.model;
    let rig = model.rig.as_ref().expect("rig attached");
    assert_eq!(rig.skeleton.len(), 19);
    assert_eq!(rig.clips.len(), 1);
    assert_eq!(rig.playback.clip, Some(0));
    assert!(model.svo.has_skin() && model.svo.leaf_count() > 500);
    // Every leaf and internal node: weights sum to 255, joints exist, strongest first.
    let check = |s: &Skin4| {
        assert_eq!(
            s.weights.iter().map(|&w| u32::from(w)).sum::<u32>(),
            255,
            "{s:?}"
        );
        assert!(s.weights.windows(2).all(|w| w[0] >= w[1]), "{s:?}");
        assert!(s.influences().all(|(j, _)| usize::from(j) < 19), "{s:?}");
    };
    model.svo.for_each_leaf(|_, vx| check(&vx.skin));
    model.svo.inner_skin().iter().for_each(check);
    // In the rest pose every joint's skinning matrix is the skinned node's transform, so any
    // weights put a voxel exactly where the rigid model would be.
    let object_from_voxel = model.object_from_voxel();
    let rest = rig.skinning_at(None, 0.0);
    model.svo.for_each_leaf(|c, vx| {
        let centre = object_from_voxel.transform_point3(c.as_vec3() + 0.5);
        let p = lbs::skin_point(&rest, vx.skin.joints_u16(), vx.skin.blend_weights(), centre);
        let want = import.world_from_skinned_node.transform_point3(centre);
        assert!(
            p.distance(want) < 1e-3 * model.voxel_size,
            "voxel {c}: {p} vs {want}"
        );
    });
    // Animated: each voxel centre, skinned with its own weights, stays near the skinned mesh
    // surface (a surface voxel's centre starts within √3/2 voxel of it).
    for t in [0.3, 0.9] {
        let skinning = rig.skinning_at(Some(0), t);
        let mut tris: Vec<[Vec3; 3]> = Vec::new();
        for part in &import.mesh.parts {
            let mut skinned = vec![Vec3::ZERO; part.positions.len()];
            skin_points(
                &skinning,
                &part.joints,
                &part.weights,
                &part.positions,
                &mut skinned,
            );
            tris.extend(part.indices.chunks_exact(3).map(|i| {
                [
                    skinned[i[0] as usize],
                    skinned[i[1] as usize],
                    skinned[i[2] as usize],
                ]
            }));
        }
        let mut worst = 0.0f32;
        model.svo.for_each_leaf(|c, vx| {
            let centre = object_from_voxel.transform_point3(c.as_vec3() + 0.5);
            let p = lbs::skin_point(
                &skinning,
                vx.skin.joints_u16(),
                vx.skin.blend_weights(),
                centre,
            );
            let d = tris
                .iter()
                .map(|t| point_triangle_distance(p, t))
                .fold(f32::INFINITY, f32::min);
            worst = worst.max(d / model.voxel_size);
        });
        assert!(
            worst < 2.0,
            "t = {t}: a voxel lies {worst} voxels off the skinned surface"
        );
    }
}

/// Distance from `p` to a triangle (closest point by region, Ericson's "Real-Time Collision
/// Detection" §5.1.5).
fn point_triangle_distance(p: Vec3, [a, b, c]: &[Vec3; 3]) -> f32 {
    let (ab, ac, ap) = (*b - *a, *c - *a, p - *a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return p.distance(*a);
    }
    let bp = p - *b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return p.distance(*b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return p.distance(*a + ab * (d1 / (d1 - d3)));
    }
    let cp = p - *c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return p.distance(*c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return p.distance(*a + ac * (d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return p.distance(*b + (*c - *b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let denom = 1.0 / (va + vb + vc);
    if !denom.is_finite() {
        // Degenerate triangle: the nearest vertex.
        return p.distance(*a).min(p.distance(*b)).min(p.distance(*c));
    }
    p.distance(*a + ab * (vb * denom) + ac * (vc * denom))
}

#[test]
fn rig_pose_uses_playback_clip_time_and_overrides() {
    let import = import_skinned(RIGGED_FIGURE).expect("RiggedFigure imports");
    let mut rig = Rig::new(import.skeleton.clone(), import.clips.clone());
    rig.validate().expect("valid");
    let at = |rig: &Rig| rig.current_skinning();
    rig.playback.time_secs = 0.5;
    let sampled = import.clips[0].sample(0.5, &import.skeleton);
    assert_eq!(rig.current_pose(), sampled);
    // Looping: 0.5 + duration is the same pose.
    rig.playback.time_secs = 0.5 + import.clips[0].duration_secs;
    assert!(
        at(&rig)
            .iter()
            .zip(import.skeleton.skinning_matrices(&sampled))
            .all(|(a, b)| a.abs_diff_eq(b, 1e-4))
    );
    // No clip: the rest pose; an override on top moves only its subtree.
    rig.playback.clip = None;
    assert_eq!(rig.current_pose(), Pose::rest(&import.skeleton));
    rig.pose_overrides.push(JointOverride {
        joint: 5,
        rotation: Some(Quat::from_rotation_x(1.0)),
        ..JointOverride::default()
    });
    let posed = rig.current_pose();
    assert_ne!(posed.locals[5], Pose::rest(&import.skeleton).locals[5]);
    // Bad values are named.
    rig.playback.clip = Some(3);
    assert!(
        rig.validate()
            .unwrap_err()
            .to_string()
            .contains("playback.clip 3")
    );
    rig.playback.clip = None;
    rig.stretch.multiplier = f32::NAN;
    assert!(
        rig.validate()
            .unwrap_err()
            .to_string()
            .contains("multiplier")
    );
}

#[test]
fn skeletons_wider_than_a_byte_are_refused_for_voxels() {
    let joints: Vec<Joint> = (0..300)
        .map(|i| joint(&format!("j{i}"), (i > 0).then(|| i - 1), Vec3::Y))
        .collect();
    let import = SkinnedImport {
        skeleton: Skeleton::new(joints).expect("chain").0,
        ..SkinnedImport::default()
    };
    let e = voxelize_skinned(
        &import,
        &crate::voxelize::VoxelizeSettings::default(),
        &|_| true,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("300 joints") && e.contains("256"), "{e}");
}

#[test]
fn weights_on_missing_joints_are_found_and_named_live_or_not() {
    use crate::skin::rig::check_weights;
    use crate::svo::{Skin4, Svo, Voxel};
    let skin = |joint: u8| Skin4 {
        joints: [joint, 0, 0, 0],
        weights: [255, 0, 0, 0],
    };
    let voxel = |joint: u8| Voxel {
        skin: skin(joint),
        ..Voxel::new([200, 100, 50, 255], glam::Vec3::Y)
    };
    let mut svo = Svo::new(3, true).unwrap();
    for x in 0..4 {
        svo.set(glam::UVec3::new(x, 1, 2), voxel(1)).unwrap();
    }
    assert!(check_weights(&svo, 2).is_ok());
    // One leaf weighted to joint 5 of a 3-joint skeleton: named by its coordinate.
    svo.set(glam::UVec3::new(6, 1, 2), voxel(5)).unwrap();
    let e = check_weights(&svo, 3).unwrap_err().to_string();
    assert!(
        e.contains("is weighted to joint 5 but the skeleton has 3 joints"),
        "{e}"
    );
    assert!(e.contains("6"), "{e}");
    assert!(
        check_weights(&svo, 6).is_ok(),
        "joint 5 exists in a 6-joint skeleton"
    );
}

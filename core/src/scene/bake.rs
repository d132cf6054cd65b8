//! Baking a skinned voxel model's shown pose into a rigid one: the static reference that
//! skinning's cost is measured against (`thicket bench --no-rig`).

use glam::{UVec3, Vec3};

use super::VoxelModel;
use crate::svo::{MAX_DEPTH, Skin4, Svo, Voxel, decode_normal, encode_normal};

/// The model as its rig currently shows it, without the rig: every leaf's centre and normal
/// skinned with its own weights (the rig's playback clip, time and pose overrides), snapped
/// to a grid of the same voxel size placed at the posed bounds. Leaves that land in one cell
/// keep the last; where the pose stretches the surface apart the baked model has gaps (it
/// has no stretch). `None` for a model without a rig, an empty one, or a pose that throws a
/// leaf to a non-finite place or beyond the deepest octree.
#[must_use]
pub fn bake_shown_pose(model: &VoxelModel) -> Option<VoxelModel> {
    let rig = model.rig.as_ref()?;
    let skinning = rig.current_skinning();
    let object_from_voxel = model.object_from_voxel();
    let mut posed: Vec<(Vec3, Voxel)> = Vec::with_capacity(model.svo.leaf_count() as usize);
    let mut finite = true;
    model.svo.for_each_leaf(|c, v| {
        let (joints, weights) = (v.skin.joints_u16(), v.skin.blend_weights());
        let bind = object_from_voxel.transform_point3(c.as_vec3() + Vec3::splat(0.5));
        let p = crate::skin::lbs::skin_point(&skinning, joints, weights, bind);
        let n = crate::skin::lbs::skin_normal(&skinning, joints, weights, decode_normal(v.normal));
        finite &= p.is_finite();
        let voxel = if v.is_interior() {
            // No normal to pose; exposed ones are settled below.
            Voxel::INTERIOR
        } else {
            Voxel {
                normal: encode_normal(n),
                skin: Skin4::default(),
                ..v
            }
        };
        posed.push((p, voxel));
    });
    if !finite || posed.is_empty() {
        return None;
    }
    let size = model.voxel_size;
    let lo = posed
        .iter()
        .fold(Vec3::splat(f32::INFINITY), |a, (p, _)| a.min(*p));
    // Leaf centres sit at cell centres: the posed minimum is the centre of cell (0,0,0).
    let origin = lo - Vec3::splat(0.5 * size);
    // Interior voxels first: where one lands in a cell with a shell voxel, the shell's (the
    // later duplicate) is kept.
    let (inside, shell): (Vec<_>, Vec<_>) = posed.into_iter().partition(|(_, v)| v.is_interior());
    let cells: Vec<(UVec3, Voxel)> = inside
        .into_iter()
        .chain(shell)
        .map(|(p, v)| (((p - origin) / size).floor().max(Vec3::ZERO).as_uvec3(), v))
        .collect();
    let extent = cells.iter().map(|(c, _)| c.max_element()).max()? + 1;
    let depth = (1..=MAX_DEPTH).find(|&d| (1u64 << d) >= u64::from(extent))?;
    let mut svo = Svo::from_voxels(depth, false, cells).ok()?;
    // Where the pose pulled the surface apart, interior voxels show.
    svo.settle_interior();
    Some(VoxelModel {
        svo,
        voxel_size: size,
        origin,
        material_names: model.material_names.clone(),
        rig: None,
        volume: None,
        palette: model.palette.clone(),
        frames: None,
    })
}

#[cfg(test)]
mod tests {
    use glam::Quat;

    use super::*;
    use crate::skin::{Joint, JointOverride, OverrideMode, Rig, Skeleton};

    /// A 4×1×1 bar, the two left voxels bound to joint 0, the two right to joint 1.
    fn bar() -> VoxelModel {
        let (skeleton, _) = Skeleton::new(vec![
            Joint {
                name: "root".into(),
                ..Joint::default()
            },
            Joint {
                name: "tip".into(),
                parent: Some(0),
                ..Joint::default()
            },
        ])
        .expect("skeleton");
        let voxels = (0..4u32).map(|x| {
            (
                UVec3::new(x, 0, 0),
                Voxel {
                    color: [10 * x as u8, 0, 0, 255],
                    normal: encode_normal(Vec3::Y),
                    material: 0,
                    skin: Skin4::from_influences(&[(u16::from(x >= 2), 1.0)]),
                },
            )
        });
        VoxelModel {
            svo: Svo::from_voxels(3, true, voxels).expect("octree"),
            voxel_size: 1.0,
            origin: Vec3::ZERO,
            material_names: Vec::new(),
            rig: Some(Rig::new(skeleton, Vec::new())),
            volume: None,
            palette: Vec::new(),
            frames: None,
        }
    }

    fn leaves(m: &VoxelModel) -> Vec<(Vec3, Voxel)> {
        let mut out = Vec::new();
        let ofv = m.object_from_voxel();
        m.svo.for_each_leaf(|c, v| {
            out.push((ofv.transform_point3(c.as_vec3() + Vec3::splat(0.5)), v));
        });
        out.sort_by(|a, b| a.0.x.total_cmp(&b.0.x).then(a.0.y.total_cmp(&b.0.y)));
        out
    }

    #[test]
    fn the_rest_pose_bakes_to_the_same_voxels_without_weights() {
        let m = bar();
        let baked = bake_shown_pose(&m).expect("bakes");
        assert!(baked.rig.is_none());
        assert!(baked.svo.inner_skin().is_empty() && baked.svo.leaf_skin().is_empty());
        let (a, b) = (leaves(&m), leaves(&baked));
        assert_eq!(a.len(), 4);
        assert_eq!(b.len(), 4);
        for ((pa, va), (pb, vb)) in a.iter().zip(&b) {
            assert!(pa.distance(*pb) < 1e-5, "{pa} vs {pb}");
            assert_eq!(va.color, vb.color);
            assert_eq!(vb.skin, Skin4::default());
        }
    }

    #[test]
    fn a_posed_joint_moves_its_voxels_and_turns_their_normals() {
        let mut m = bar();
        // Turn the tip joint a quarter about Z at the origin: (x, 0.5) goes to (-0.5, x).
        let rig = m.rig.as_mut().expect("rig");
        rig.pose_overrides.push(JointOverride {
            joint: 1,
            mode: OverrideMode::Replace,
            translation: None,
            rotation: Some(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2)),
            scale: None,
        });
        let baked = bake_shown_pose(&m).expect("bakes");
        let got = leaves(&baked);
        assert_eq!(got.len(), 4);
        let turned: Vec<&(Vec3, Voxel)> = got.iter().filter(|(p, _)| p.x < 0.0).collect();
        assert_eq!(turned.len(), 2, "{got:?}");
        for (p, v) in turned {
            assert!((p.x + 0.5).abs() < 1e-4, "{p}");
            assert!(decode_normal(v.normal).dot(-Vec3::X) > 0.99);
        }
        // The voxels of joint 0 stay where they were.
        let kept: Vec<f32> = got
            .iter()
            .filter(|(p, _)| p.x > 0.0)
            .map(|(p, _)| p.x)
            .collect();
        assert_eq!(kept.len(), 2);
        assert!(
            (kept[0] - 0.5).abs() < 1e-4 && (kept[1] - 1.5).abs() < 1e-4,
            "{kept:?}"
        );
    }

    #[test]
    fn a_model_without_a_rig_does_not_bake() {
        let mut m = bar();
        m.rig = None;
        assert!(bake_shown_pose(&m).is_none());
    }
}

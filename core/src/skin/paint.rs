//! Weight painting on a skinned octree: one dab's changes, computed from the octree alone so an
//! editor applies them through its usual voxel-edit path (and undo restores them exactly).

use glam::{IVec3, UVec3, Vec3};

use crate::svo::{Skin4, Svo, Voxel};

/// The changes of one weight-paint dab of joint `joint` centred on `centre` (voxel space) with
/// `radius` voxels: `amount` in -1..=1 moves each voxel's weight toward 1 (positive) or 0
/// (negative) by that fraction times a smoothstep falloff; `smooth` moves it halfway toward the
/// mean of its 3×3×3 neighbours instead. The other joints are rescaled to fill the rest (see
/// [`with_joint_weight`]). Voxels that would change by less than half a byte are left out.
pub fn weight_dab(
    svo: &Svo,
    joint: usize,
    centre: Vec3,
    radius: f32,
    amount: f32,
    smooth: bool,
) -> Vec<(UVec3, Option<Voxel>)> {
    let r = radius.max(0.5);
    let lo = (centre - r).floor().max(Vec3::ZERO).as_uvec3();
    let hi = (centre + r).ceil().max(Vec3::ZERO).as_uvec3();
    let mut out = Vec::new();
    let j = joint as u16;
    svo.for_each_leaf_in(lo, hi, |c, v| {
        let d = (c.as_vec3() + 0.5 - centre).length();
        if d > r {
            return;
        }
        // Smooth falloff: 1 at the centre, 0 at the rim.
        let falloff = {
            let x = 1.0 - d / r;
            x * x * (3.0 - 2.0 * x)
        };
        // An empty skin follows joint 0 with its whole weight (as skinning and the heat map
        // read it).
        let own = |s: &Skin4| {
            if s.is_empty() {
                f32::from(u8::from(j == 0))
            } else {
                s.influences()
                    .filter(|&(k, _)| k == j)
                    .map(|(_, w)| w)
                    .sum::<f32>()
            }
        };
        let current = own(&v.skin);
        let target = if smooth {
            let mut sum = 0.0;
            let mut n: f32 = 0.0;
            for dz in -1i32..=1 {
                for dy in -1i32..=1 {
                    for dx in -1i32..=1 {
                        let q = c.as_ivec3() + IVec3::new(dx, dy, dz);
                        if q.cmplt(IVec3::ZERO).any() {
                            continue;
                        }
                        if let Some(nv) = svo.get(q.as_uvec3()) {
                            sum += own(&nv.skin);
                            n += 1.0;
                        }
                    }
                }
            }
            sum / n.max(1.0)
        } else if amount >= 0.0 {
            1.0
        } else {
            0.0
        };
        let strength = if smooth { 0.5 } else { amount.abs().min(1.0) } * falloff;
        let new_w = current + (target - current) * strength;
        if (new_w - current).abs() < 0.5 / 255.0 {
            return;
        }
        let skin = with_joint_weight(&v.skin, j, new_w.clamp(0.0, 1.0));
        if skin != v.skin {
            out.push((c, Some(Voxel { skin, ..v })));
        }
    });
    out
}

/// `skin` with `joint`'s weight set to `w`, the other joints scaled to fill `1 - w`; when no
/// other joint holds the voxel the remainder goes to joint 0 (the root, which an empty skin
/// follows), and joint 0 alone keeps the whole weight.
#[must_use]
pub fn with_joint_weight(skin: &Skin4, joint: u16, w: f32) -> Skin4 {
    let others: Vec<(u16, f32)> = skin.influences().filter(|&(k, _)| k != joint).collect();
    let rest: f32 = others.iter().map(|o| o.1).sum();
    let mut infl: Vec<(u16, f32)> = Vec::with_capacity(5);
    if w > 0.0 {
        infl.push((joint, w));
    }
    if rest > 0.0 {
        infl.extend(others.iter().map(|&(k, x)| (k, x / rest * (1.0 - w))));
    } else if w < 1.0 && joint != 0 {
        // No other joint holds the voxel: the rest stays on the root, as an empty skin does.
        infl.push((0, 1.0 - w));
    }
    Skin4::from_influences(&infl)
}

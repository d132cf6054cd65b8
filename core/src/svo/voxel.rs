//! Per-voxel attributes and how internal nodes average them.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::mesh::{linear_to_srgb, srgb_byte_to_linear};

/// Up to four joint influences, weights as unsigned normalised bytes summing to 255
/// (all zero: no skin).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Skin4 {
    /// Joint indices into the model's skeleton.
    pub joints: [u8; 4],
    /// Weights, `weight / 255`.
    pub weights: [u8; 4],
}

impl Skin4 {
    /// Keeps the four strongest of `(joint, weight)` influences and normalises them to sum to
    /// 255, giving the rounding remainder to the strongest. Negative, NaN and zero weights are
    /// dropped; all-zero input gives the empty skin. Ties break toward the lower joint index so
    /// the result does not depend on input order.
    #[must_use]
    pub fn from_influences(influences: &[(u16, f32)]) -> Self {
        let mut list: Vec<(u16, f32)> = Vec::with_capacity(influences.len());
        for &(j, w) in influences {
            if w.is_nan() || w <= 0.0 || !w.is_finite() || j > 255 {
                continue;
            }
            if let Some(e) = list.iter_mut().find(|e| e.0 == j) {
                e.1 += w;
            } else {
                list.push((j, w));
            }
        }
        list.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        list.truncate(4);
        let total: f32 = list.iter().map(|e| e.1).sum();
        if list.is_empty() || total.is_nan() || total <= 0.0 {
            return Self::default();
        }
        let mut skin = Self::default();
        let mut sum = 0u32;
        for (slot, &(j, w)) in list.iter().enumerate() {
            skin.joints[slot] = j as u8;
            let q = ((w / total) * 255.0).round().clamp(0.0, 255.0) as u32;
            skin.weights[slot] = q as u8;
            sum += q;
        }
        // Rounding can miss 255 by a few units; the strongest influence absorbs the difference.
        let fixed = (i64::from(skin.weights[0]) + 255 - i64::from(sum)).clamp(0, 255);
        skin.weights[0] = fixed as u8;
        skin
    }

    /// True when no joint influences the voxel.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.weights == [0; 4]
    }

    /// Influences as `(joint, weight 0..1)`, zero weights skipped.
    pub fn influences(&self) -> impl Iterator<Item = (u16, f32)> + '_ {
        (0..4).filter(|&i| self.weights[i] > 0).map(|i| {
            (
                u16::from(self.joints[i]),
                f32::from(self.weights[i]) / 255.0,
            )
        })
    }
}

/// The attributes of one voxel (or the averaged attributes of an internal node).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Voxel {
    /// sRGB-encoded RGBA.
    pub color: [u8; 4],
    /// Octahedral-encoded unit normal ([`encode_normal`]).
    pub normal: u16,
    /// Material id (index into the model's material table; 0 is the default).
    pub material: u8,
    /// Skin weights (stored only when the octree has skin).
    pub skin: Skin4,
}

impl Voxel {
    /// A voxel of the given colour and normal, material 0, no skin.
    #[must_use]
    pub fn new(color: [u8; 4], normal: Vec3) -> Self {
        Self {
            color,
            normal: encode_normal(normal),
            material: 0,
            skin: Skin4::default(),
        }
    }

    /// The decoded unit normal.
    #[must_use]
    pub fn normal_vec(&self) -> Vec3 {
        decode_normal(self.normal)
    }
}

fn oct_wrap(v: Vec2) -> Vec2 {
    let sign = Vec2::new(
        if v.x >= 0.0 { 1.0 } else { -1.0 },
        if v.y >= 0.0 { 1.0 } else { -1.0 },
    );
    (Vec2::ONE - Vec2::new(v.y, v.x).abs()) * sign
}

/// Octahedral encoding of a unit vector into 8+8 bits (max error about 1.4°). Zero or
/// non-finite vectors encode +Z.
#[must_use]
pub fn encode_normal(n: Vec3) -> u16 {
    let n = n.try_normalize().unwrap_or(Vec3::Z);
    let l1 = n.x.abs() + n.y.abs() + n.z.abs();
    let mut p = Vec2::new(n.x, n.y) / l1;
    if n.z < 0.0 {
        p = oct_wrap(p);
    }
    let q = ((p * 0.5 + 0.5) * 255.0)
        .round()
        .clamp(Vec2::ZERO, Vec2::splat(255.0));
    (q.x as u16) | ((q.y as u16) << 8)
}

/// Inverse of [`encode_normal`]; always a unit vector.
#[must_use]
pub fn decode_normal(e: u16) -> Vec3 {
    let p = Vec2::new(f32::from(e & 0xff), f32::from(e >> 8)) / 255.0 * 2.0 - 1.0;
    let z = 1.0 - p.x.abs() - p.y.abs();
    let xy = if z < 0.0 { oct_wrap(p) } else { p };
    Vec3::new(xy.x, xy.y, z).try_normalize().unwrap_or(Vec3::Z)
}

/// Averages children into an internal node's LOD attributes: colour averaged in linear space,
/// normals summed and renormalised, the most common material (ties: first child), skin weights
/// summed per joint and cut to the strongest four.
pub(crate) fn merge(
    children: impl Iterator<Item = ([u8; 4], u16, u8)>,
    skins: Option<&[Skin4]>,
) -> Voxel {
    let mut rgb = Vec3::ZERO;
    let mut alpha = 0.0f32;
    let mut normal = Vec3::ZERO;
    let mut materials = [(0u8, 0u8); 8];
    let mut n_materials = 0usize;
    let mut count = 0.0f32;
    for (color, n, m) in children {
        rgb += Vec3::new(
            srgb_byte_to_linear(color[0]),
            srgb_byte_to_linear(color[1]),
            srgb_byte_to_linear(color[2]),
        );
        alpha += f32::from(color[3]) / 255.0;
        normal += decode_normal(n);
        if let Some(e) = materials[..n_materials].iter_mut().find(|e| e.0 == m) {
            e.1 += 1;
        } else if n_materials < 8 {
            materials[n_materials] = (m, 1);
            n_materials += 1;
        }
        count += 1.0;
    }
    if count == 0.0 {
        return Voxel::default();
    }
    rgb /= count;
    alpha /= count;
    let to8 = |c: f32| (linear_to_srgb(c) * 255.0).round() as u8;
    let mut best = materials[0];
    for &e in &materials[1..n_materials] {
        if e.1 > best.1 {
            best = e;
        }
    }
    let skin = skins.map_or(Skin4::default(), |skins| {
        let mut acc: Vec<(u16, f32)> = Vec::with_capacity(32);
        for s in skins {
            acc.extend(s.influences());
        }
        Skin4::from_influences(&acc)
    });
    Voxel {
        color: [
            to8(rgb.x),
            to8(rgb.y),
            to8(rgb.z),
            (alpha.clamp(0.0, 1.0) * 255.0).round() as u8,
        ],
        normal: encode_normal(normal),
        material: best.0,
        skin,
    }
}

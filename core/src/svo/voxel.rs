//! Per-voxel attributes and how internal nodes average them.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::mesh::{linear_to_srgb, srgb_byte_to_linear};

/// Up to four joint influences of a voxel or octree node, strongest first, weights as unsigned
/// normalised bytes summing to exactly 255 (all zero: no skin). 8 bytes, two `u32` on a GPU.
///
/// This is Thicket's one per-node skin representation: the voxelizer writes it, internal nodes
/// merge it for LOD ([`Skin4::merge`]), project files store it, and `core::skin` and the
/// renderers skin with it. Joint indices are bytes, so a skinned voxel model addresses at most
/// [`MAX_SKIN_JOINTS`] joints; the skinned-glTF import refuses larger skeletons with an error
/// rather than dropping influences.
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    Eq,
    Hash,
    Serialize,
    Deserialize,
    bytemuck::Pod,
    bytemuck::Zeroable,
)]
#[repr(C)]
pub struct Skin4 {
    /// Joint indices into the model's skeleton.
    pub joints: [u8; 4],
    /// Weights, `weight / 255`.
    pub weights: [u8; 4],
}

/// Joints a [`Skin4`] can address (its joint indices are bytes).
pub const MAX_SKIN_JOINTS: usize = 256;

impl Skin4 {
    /// Fully bound to joint 0 (the root of a topologically sorted skeleton).
    pub const ROOT: Self = Self {
        joints: [0; 4],
        weights: [255, 0, 0, 0],
    };

    /// Keeps the four strongest of `(joint, weight)` influences (duplicates summed) and
    /// quantises them to sum to exactly 255 (largest remainder). Negative, NaN, infinite and
    /// zero weights, and joints above 255, are dropped; nothing left gives the empty skin.
    /// Ties break toward the lower joint index so the result does not depend on input order.
    #[must_use]
    pub fn from_influences(influences: &[(u16, f32)]) -> Self {
        let mut acc = Accumulator::default();
        for &(j, w) in influences {
            acc.add(j, w);
        }
        acc.finish()
    }

    /// From one vertex's (or surface point's) four joints and float weights.
    #[must_use]
    pub fn from_vertex(joints: [u16; 4], weights: [f32; 4]) -> Self {
        let mut acc = Accumulator::default();
        for k in 0..4 {
            acc.add(joints[k], weights[k]);
        }
        acc.finish()
    }

    /// Merges the skins of an internal node's children (or any set of nodes): sums each joint's
    /// weight, keeps the four strongest, renormalises. Empty skins contribute nothing; all
    /// empty gives the empty skin. Allocation-free for up to 32 distinct joints.
    #[must_use]
    pub fn merge(children: &[Self]) -> Self {
        let mut acc = Accumulator::default();
        for c in children {
            for k in 0..4 {
                acc.add(u16::from(c.joints[k]), f32::from(c.weights[k]));
            }
        }
        acc.finish()
    }

    /// True when no joint influences the voxel.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.weights == [0; 4]
    }

    /// Number of non-zero weights (the ASVO paper's W, §3.3).
    #[inline]
    #[must_use]
    pub fn nonzero_count(&self) -> u32 {
        self.weights.iter().filter(|&&w| w > 0).count() as u32
    }

    /// Joint indices widened for indexing matrix tables.
    #[inline]
    #[must_use]
    pub fn joints_u16(&self) -> [u16; 4] {
        self.joints.map(u16::from)
    }

    /// Weights as floats for blending (they sum to 1). The empty skin blends as full weight on
    /// joint 0, so a voxel without weights follows the character's root instead of collapsing
    /// to the origin.
    #[inline]
    #[must_use]
    pub fn blend_weights(&self) -> [f32; 4] {
        if self.is_empty() {
            [1.0, 0.0, 0.0, 0.0]
        } else {
            self.weights.map(|w| f32::from(w) * (1.0 / 255.0))
        }
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

/// Sums weights per joint without allocating for up to 32 distinct joints (8 children × 4),
/// spilling to a `Vec` beyond that.
struct Accumulator {
    fixed: [(u16, f32); 32],
    len: usize,
    spill: Vec<(u16, f32)>,
}

impl Default for Accumulator {
    fn default() -> Self {
        Self {
            fixed: [(0, 0.0); 32],
            len: 0,
            spill: Vec::new(),
        }
    }
}

impl Accumulator {
    fn add(&mut self, joint: u16, w: f32) {
        if !(w.is_finite() && w > 0.0) || usize::from(joint) >= MAX_SKIN_JOINTS {
            return;
        }
        if let Some(e) = self.fixed[..self.len].iter_mut().find(|e| e.0 == joint) {
            e.1 += w;
        } else if let Some(e) = self.spill.iter_mut().find(|e| e.0 == joint) {
            e.1 += w;
        } else if self.len < self.fixed.len() {
            self.fixed[self.len] = (joint, w);
            self.len += 1;
        } else {
            self.spill.push((joint, w));
        }
    }

    fn finish(self) -> Skin4 {
        let mut top = [(0u16, 0.0f32); 4];
        // Heavier first, lower joint first on ties.
        let better = |a: (u16, f32), b: (u16, f32)| a.1 > b.1 || (a.1 == b.1 && a.0 < b.0);
        for &(j, w) in self.fixed[..self.len].iter().chain(self.spill.iter()) {
            if !better((j, w), top[3]) {
                continue;
            }
            top[3] = (j, w);
            let mut k = 3;
            while k > 0 && better(top[k], top[k - 1]) {
                top.swap(k, k - 1);
                k -= 1;
            }
        }
        let sum: f32 = top.iter().map(|e| e.1).sum();
        if !(sum > 0.0 && sum.is_finite()) {
            return Skin4::default();
        }
        // Largest-remainder quantisation: floors, then the missing units go to the largest
        // remainders, so the bytes sum to exactly 255 and no weight is off by more than one.
        let scaled = top.map(|e| e.1 / sum * 255.0);
        let mut bytes = scaled.map(|s| s.floor().clamp(0.0, 255.0) as u8);
        let mut missing = 255 - bytes.iter().map(|&b| u32::from(b)).sum::<u32>().min(255);
        let mut order = [0usize, 1, 2, 3];
        order.sort_by(|&a, &b| {
            let ra = scaled[a] - scaled[a].floor();
            let rb = scaled[b] - scaled[b].floor();
            rb.total_cmp(&ra).then(a.cmp(&b))
        });
        for &k in order.iter().cycle().take(8) {
            if missing == 0 {
                break;
            }
            if top[k].1 > 0.0 && bytes[k] < 255 {
                bytes[k] += 1;
                missing -= 1;
            }
        }
        let mut joints = [0u8; 4];
        for k in 0..4 {
            if bytes[k] > 0 {
                // `add` refused joints above 255.
                joints[k] = top[k].0 as u8;
            }
        }
        Skin4 {
            joints,
            weights: bytes,
        }
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

/// Normal code of the interior mark: one [`encode_normal`] never produces (a corner of the
/// octahedral square: it decodes to −Z, which encodes as `0xffff`), so no surface voxel made
/// by this build carries it. Files written before the mark existed are mapped to `0xffff` on
/// load (`io::project`).
pub const INTERIOR_NORMAL: u16 = 0x00ff;

/// Whether a colour and normal code are the interior mark's.
#[inline]
#[must_use]
pub fn is_interior_value(color: [u8; 4], normal: u16) -> bool {
    normal == INTERIOR_NORMAL && color == [0; 4]
}

impl Voxel {
    /// An interior voxel: solid, enclosed on all six faces, with no attributes of its own
    /// until an edit exposes it; it then takes those of the nearest voxel that is not interior
    /// (the rule is in `docs/svo.md`, "Interior"). A solid import's inside is made of these, so
    /// it is stored as a few tiles; renderers skip interior nodes, which are never visible.
    pub const INTERIOR: Self = Self {
        color: [0; 4],
        normal: INTERIOR_NORMAL,
        material: 0,
        skin: Skin4 {
            joints: [0; 4],
            weights: [0; 4],
        },
    };

    /// Whether this is an interior voxel (colour and normal of [`Self::INTERIOR`]; its
    /// material and skin are not looked at).
    #[inline]
    #[must_use]
    pub fn is_interior(&self) -> bool {
        is_interior_value(self.color, self.normal)
    }

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
    let code = (q.x as u16) | ((q.y as u16) << 8);
    // The four corners of the square all decode to −Z; the interior mark keeps one of them,
    // the others give −Z as the one corner it encodes exactly.
    if code == INTERIOR_NORMAL {
        0xffff
    } else {
        code
    }
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
///
/// Interior children ([`Voxel::is_interior`]) are never seen, so they are left out of the
/// average (and of the skin); a node whose children are all interior is interior itself.
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
    let mut seen_skins = [Skin4::default(); 8];
    let mut n_seen = 0usize;
    let mut interior = 0usize;
    for (i, (color, n, m)) in children.enumerate() {
        if is_interior_value(color, n) {
            interior += 1;
            continue;
        }
        if let Some(s) = skins.and_then(|s| s.get(i))
            && n_seen < seen_skins.len()
        {
            seen_skins[n_seen] = *s;
            n_seen += 1;
        }
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
        return if interior > 0 {
            // Skinned interior nodes keep their children's joints, so posed bounds hold them.
            Voxel {
                skin: skins.map_or(Skin4::default(), Skin4::merge),
                ..Voxel::INTERIOR
            }
        } else {
            Voxel::default()
        };
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
    let skin = skins.map_or(Skin4::default(), |all| {
        if interior == 0 {
            Skin4::merge(all)
        } else {
            Skin4::merge(&seen_skins[..n_seen])
        }
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

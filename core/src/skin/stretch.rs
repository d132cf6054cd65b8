//! Stretch factors: how much a skinned voxel is enlarged so stretched regions show no holes.
//!
//! Skinning moves each voxel's centre independently (ASVO paper §3.1); where the surface
//! stretches, neighbouring voxels drift apart and holes open (§3.3, Fig. 5, Fig. 11). The
//! strategies here trade holes against bloat (voxels drawn larger than the surface) and time:
//!
//! | strategy | splat | cost per node | paper |
//! |---|---|---|---|
//! | [`StretchStrategy::Off`] | `S = 1` | one skinned point | §3.2 (rigid) |
//! | [`StretchStrategy::Thesis`] | `S = min(2, W)`, W = non-zero weights | one skinned point | §3.3 |
//! | [`StretchStrategy::Corners`] | AABB of the 8 skinned corners (not capped) | 8 skinned points | §8.1.3 |
//! | [`StretchStrategy::Adaptive`] | smallest `S` whose box holds the 8 skinned corners | 8 skinned points + a 3×3 inverse | §6, §8.1.3 |
//!
//! On top of every strategy: a per-voxel artist override (§8.1.3: "stretch factors could be
//! automatically computed, manually refined and stored per voxel") and a global multiplier.

use glam::{Mat3, Mat4, Vec3};
use serde::{Deserialize, Serialize};

use super::lbs::{blend_matrix, skin_point};
use crate::svo::Skin4;

/// How a skinned voxel's drawn size is chosen.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum StretchStrategy {
    /// `S = 1`: voxels keep their size (the paper's rigid case, §3.2). The baseline that
    /// shows the holes.
    Off,
    /// `S = min(2, W)` with W the number of the voxel's non-zero bone weights (paper §3.3).
    /// Static: voxels near joints are doubled whether or not the joint moves (paper §6).
    #[default]
    Thesis,
    /// Weights per voxel corner; the splat is the axis-aligned bounding box of the eight
    /// corners skinned with their own weights (paper §8.1.3), at the cost of oversized voxels
    /// and eight skinned points. Neighbours share corners, so their boxes leave no gap between
    /// each other. The box is not capped by [`StretchSettings::max_factor`]: it lies in the hull
    /// of the voxel's bind box carried by its corners' joints, so the pose bounds it, and a cap
    /// in voxels would reopen the holes where one layer of voxels spans a sharp joint (the
    /// bending cylinder's reach up to R/2, 25.6 half-voxels at depth 7).
    ///
    /// What it closes: every hole whose surface point lies in the box of the voxel there or of
    /// a neighbour — the lattice's deformation. Measured with `measure::skin` (6 views, 256²):
    /// 0 hole pixels on the 90° bending cylinder and none beyond the rest pose's on CesiumMan's
    /// walk. What it cannot close: surface the voxels' weights send elsewhere (a voxel keeps
    /// the four strongest weights, quantised, and one part's where two parts' faces meet:
    /// RiggedFigure), which the metric reports as misplaced (voxelization error).
    Corners,
    /// `S` from this frame's actual deformation around the voxel: the smallest factor for
    /// which the voxel, carried by its blended matrix, contains its eight corners skinned with
    /// their own weights (the corners it shares with its neighbours: "where its neighbours
    /// went"), see [`containing_factor`]. `S = 1` where nothing stretches, including rigid
    /// rotation; `S < 1` where the surface is compressed (bounded below by
    /// [`StretchSettings::min_factor`]). Without corner weights it falls back to the largest
    /// singular value of the blended 3×3 linear part, which sees bone scaling but not the
    /// stretch that comes from weights varying across a joint.
    Adaptive,
}

/// Stretch settings of one model (part of the render quality settings).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StretchSettings {
    /// The strategy.
    pub strategy: StretchStrategy,
    /// Global multiplier on the final size (1 = as computed).
    pub multiplier: f32,
    /// Lower bound on a scalar stretch factor (`Adaptive` may otherwise shrink compressed
    /// voxels; 1 keeps them at least their bind-pose size).
    pub min_factor: f32,
    /// Upper bound on a scalar stretch factor (`Thesis`, `Adaptive`, not `Corners`' box), so a
    /// wild pose cannot make one voxel cover the screen.
    pub max_factor: f32,
}

impl Default for StretchSettings {
    fn default() -> Self {
        Self {
            strategy: StretchStrategy::Thesis,
            multiplier: 1.0,
            min_factor: 1.0,
            max_factor: 4.0,
        }
    }
}

impl StretchSettings {
    /// Checks values read from a file or typed by a user: finite, `0 < multiplier <= 16`,
    /// `0 <= min_factor <= max_factor <= 16`.
    ///
    /// # Errors
    /// Which setting is out of range and why.
    pub fn validate(&self) -> Result<(), String> {
        let ok = |v: f32| v.is_finite() && (0.0..=16.0).contains(&v);
        if !(ok(self.multiplier) && self.multiplier > 0.0) {
            return Err(format!(
                "multiplier {} must be finite, above 0 and at most 16",
                self.multiplier
            ));
        }
        if !ok(self.min_factor) {
            return Err(format!(
                "min_factor {} must be finite, in 0..=16",
                self.min_factor
            ));
        }
        if !(ok(self.max_factor) && self.max_factor >= self.min_factor) {
            return Err(format!(
                "max_factor {} must be finite, at most 16 and at least min_factor {}",
                self.max_factor, self.min_factor
            ));
        }
        Ok(())
    }

    /// Replaces non-finite or out-of-range values with defaults / clamps (settings come from
    /// files and the UI).
    #[must_use]
    pub fn sanitized(self) -> Self {
        let d = Self::default();
        let fin = |v: f32, dflt: f32| if v.is_finite() && v >= 0.0 { v } else { dflt };
        let min_factor = fin(self.min_factor, d.min_factor);
        let max_factor = fin(self.max_factor, d.max_factor).max(min_factor);
        Self {
            strategy: self.strategy,
            multiplier: fin(self.multiplier, d.multiplier),
            min_factor,
            max_factor,
        }
    }
}

/// `S = min(2, W)`, W = number of non-zero weights (paper §3.3). A voxel without weights gets
/// 1, not the paper's theoretical 0 (§6), so it does not vanish.
#[inline]
#[must_use]
pub fn thesis_factor(skin: &Skin4) -> f32 {
    skin.nonzero_count().clamp(1, 2) as f32
}

/// [`thesis_factor`] for float weights.
#[inline]
#[must_use]
pub fn thesis_factor_f32(weights: [f32; 4]) -> f32 {
    weights.iter().filter(|&&w| w > 0.0).count().clamp(1, 2) as f32
}

/// The eight corners of the cube `center ± half_size`, in the order x fastest, then y, then z
/// (corner `k` has offset sign bits `k & 1`, `k & 2`, `k & 4`).
#[must_use]
pub fn voxel_corners(center: Vec3, half_size: f32) -> [Vec3; 8] {
    std::array::from_fn(|k| {
        let sign = |bit: usize| if k & bit != 0 { 1.0 } else { -1.0 };
        center + Vec3::new(sign(1), sign(2), sign(4)) * half_size
    })
}

/// Skins the eight corners with their own weights (paper §8.1.3).
#[must_use]
pub fn skin_corners(
    skinning: &[Mat4],
    corners: &[Vec3; 8],
    corner_skins: &[Skin4; 8],
) -> [Vec3; 8] {
    std::array::from_fn(|k| {
        skin_point(
            skinning,
            corner_skins[k].joints_u16(),
            corner_skins[k].blend_weights(),
            corners[k],
        )
    })
}

/// Axis-aligned bounds `(min, max)` of points.
#[must_use]
pub fn aabb(points: &[Vec3]) -> (Vec3, Vec3) {
    points.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    )
}

/// Largest ratio of skinned to bind-pose distance over all pairs of sample points — a local
/// estimate of how much the skinning map stretches (its Lipschitz constant around the voxel):
/// "where its neighbours went". Pairs closer than 1e-12 in the bind pose are skipped. `None`
/// with fewer than two usable points. Pure rotation gives 1.
#[must_use]
pub fn stretch_from_samples(bind: &[Vec3], skinned: &[Vec3]) -> Option<f32> {
    let n = bind.len().min(skinned.len());
    let mut best: Option<f32> = None;
    for i in 0..n {
        for j in i + 1..n {
            let before_sq = bind[i].distance_squared(bind[j]);
            if before_sq.is_finite() && before_sq > 1e-24 {
                let after_sq = skinned[i].distance_squared(skinned[j]);
                let ratio = (after_sq / before_sq).sqrt();
                if ratio.is_finite() {
                    best = Some(best.map_or(ratio, |b| b.max(ratio)));
                }
            }
        }
    }
    best
}

/// [`stretch_from_samples`] specialised to the eight corners of a cube of edge `2 · half_size`
/// in [`voxel_corners`] order: the bind distances are known (edge, face and body diagonals),
/// so the 28 pairs cost one squared distance each and a single square root at the end.
#[must_use]
pub fn stretch_from_corners(skinned: &[Vec3; 8], half_size: f32) -> Option<f32> {
    let edge_sq = 4.0 * half_size * half_size;
    if !(edge_sq.is_finite() && edge_sq > 1e-24) {
        return None;
    }
    // Pairs differing in one coordinate bit are edges (k = 1), two bits face diagonals (k = 2),
    // three bits body diagonals (k = 3): bind distance² = k · edge².
    let inv_k = [0.0, 1.0, 0.5, 1.0 / 3.0];
    let mut best_sq = 0.0f32;
    for i in 0..8usize {
        for j in i + 1..8 {
            let k = (i ^ j).count_ones() as usize;
            best_sq = best_sq.max(skinned[i].distance_squared(skinned[j]) * inv_k[k]);
        }
    }
    let ratio = (best_sq / edge_sq).sqrt();
    ratio.is_finite().then_some(ratio)
}

/// `Adaptive`'s factor: the smallest `S` for which the box `center ± linear · (S · half)` — the
/// voxel carried by its blended matrix and scaled about its skinned centre — contains the eight
/// corners skinned with their own weights (`skinned`, [`voxel_corners`] order):
/// `max ‖linear⁻¹ (p − center)‖∞ / half`. Exactly 1 under rigid motion; above 1 where the
/// weights change across the voxel and its neighbours pull its corners away; below 1 where the
/// surface is compressed. Neighbouring voxels share corners, so boxes that contain their
/// corners leave no gap between them. `None` when the blended frame has collapsed (a joint
/// scaled to 0) and cannot be inverted, or `half` is not positive.
#[must_use]
pub fn containing_factor(
    skinned: &[Vec3; 8],
    half: f32,
    center: Vec3,
    linear: Mat3,
) -> Option<f32> {
    let det = linear.determinant();
    let scale = linear
        .x_axis
        .length()
        .max(linear.y_axis.length())
        .max(linear.z_axis.length());
    if !(det.abs() > 1e-6 * scale * scale * scale && half > 0.0) {
        return None;
    }
    // `Mat3A` is glam's SIMD 3×3: the same products and sums in the same order as `Mat3`, so
    // the same bits in fewer instructions (this runs once per skinned node and frame).
    let inv = glam::Mat3A::from(linear.inverse());
    let center = glam::Vec3A::from(center);
    let mut worst = 0.0f32;
    for &p in skinned {
        worst = worst.max((inv * (glam::Vec3A::from(p) - center)).abs().max_element());
    }
    let f = worst / half;
    f.is_finite().then_some(f)
}

/// Largest singular value of a 3×3 matrix (the most it stretches any direction), from the
/// largest eigenvalue of `aᵀa` in closed form. Finite for finite input; 0 for the zero matrix.
#[must_use]
pub fn max_singular_value(a: Mat3) -> f32 {
    let b = a.transpose() * a;
    let (b00, b11, b22) = (b.x_axis.x, b.y_axis.y, b.z_axis.z);
    let (b01, b02, b12) = (b.y_axis.x, b.z_axis.x, b.z_axis.y);
    let q = (b00 + b11 + b22) / 3.0;
    let p1 = b01 * b01 + b02 * b02 + b12 * b12;
    let p2 = (b00 - q).powi(2) + (b11 - q).powi(2) + (b22 - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let lambda = if p <= q.abs() * 1e-7 || p == 0.0 {
        // Nearly a multiple of the identity: every eigenvalue is q.
        q
    } else {
        let c = (b - Mat3::from_diagonal(Vec3::splat(q))) * p.recip();
        let r = (c.determinant() * 0.5).clamp(-1.0, 1.0);
        q + 2.0 * p * (r.acos() / 3.0).cos()
    };
    let sigma = lambda.max(0.0).sqrt();
    if sigma.is_finite() {
        sigma
    } else {
        // Overflow: fall back to the largest column norm (a lower bound that stays finite
        // as long as the columns are).
        a.x_axis
            .length()
            .max(a.y_axis.length())
            .max(a.z_axis.length())
    }
}

/// `Adaptive` without sample points: the largest singular value of the blended 3×3 linear part
/// `Σ wᵢ Lᵢ`. Sees bone scale; blind to weight-gradient stretch (see [`StretchStrategy`]).
#[must_use]
pub fn blended_linear_factor(skinning: &[Mat4], skin: &Skin4) -> f32 {
    max_singular_value(Mat3::from_mat4(blend_matrix(
        skinning,
        skin.joints_u16(),
        skin.blend_weights(),
    )))
}

/// Per-voxel override byte: 0 = none, otherwise the stretch factor in 1/64 steps
/// (1/64 .. 3.98), so an editor can paint it into one byte per voxel.
#[inline]
#[must_use]
pub fn decode_override(code: u8) -> Option<f32> {
    (code != 0).then(|| f32::from(code) / 64.0)
}

/// Inverse of [`decode_override`]: rounds to the nearest step, clamps to 1..=255; a
/// non-finite or non-positive factor encodes as "no override".
#[must_use]
pub fn encode_override(factor: f32) -> u8 {
    if factor.is_finite() && factor > 0.0 {
        (factor * 64.0).round().clamp(1.0, 255.0) as u8
    } else {
        0
    }
}

/// Where and how large to draw one skinned voxel: an axis-aligned box in skeleton world space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplatBox {
    /// Centre.
    pub center: Vec3,
    /// Half extent per axis.
    pub half_extent: Vec3,
}

/// Per-node inputs of [`skinned_splat`]: the node's bind-pose box and skin data.
#[derive(Debug, Clone, Copy)]
pub struct VoxelSkinInput<'a> {
    /// Bind-pose mesh-space centre of the node.
    pub center: Vec3,
    /// Half the node's edge length in bind-pose mesh space.
    pub half_size: f32,
    /// The node's own (merged) weights.
    pub skin: Skin4,
    /// Weights at the node's eight corners ([`voxel_corners`] order), when the model has them;
    /// `Corners` and the sample-based `Adaptive` need them and fall back to `Thesis` / the
    /// blended-linear `Adaptive` without.
    pub corner_skins: Option<&'a [Skin4; 8]>,
    /// Per-voxel override byte ([`decode_override`]); 0 for none.
    pub override_code: u8,
}

/// The skinned splat of one node under `settings`: the centre skinned with the node's weights,
/// the half extent `S · half_size` (or the corner AABB for `Corners`), a per-voxel override
/// replacing the strategy's `S`, then the global multiplier. Always finite for finite input.
#[must_use]
pub fn skinned_splat(
    settings: &StretchSettings,
    skinning: &[Mat4],
    v: &VoxelSkinInput<'_>,
) -> SplatBox {
    let s = settings.sanitized();
    let bound = |f: f32| f.clamp(s.min_factor, s.max_factor);
    let center = skin_point(
        skinning,
        v.skin.joints_u16(),
        v.skin.blend_weights(),
        v.center,
    );
    let scalar = |f: f32| {
        let f = decode_override(v.override_code).unwrap_or_else(|| bound(f));
        SplatBox {
            center,
            half_extent: Vec3::splat(f * v.half_size * s.multiplier),
        }
    };
    match (s.strategy, v.corner_skins) {
        (StretchStrategy::Off, _) => scalar(1.0),
        (StretchStrategy::Thesis, _) | (StretchStrategy::Corners, None) => {
            scalar(thesis_factor(&v.skin))
        }
        (StretchStrategy::Corners, Some(cs)) => {
            if let Some(f) = decode_override(v.override_code) {
                return SplatBox {
                    center,
                    half_extent: Vec3::splat(f * v.half_size * s.multiplier),
                };
            }
            let skinned = skin_corners(skinning, &voxel_corners(v.center, v.half_size), cs);
            let (lo, hi) = aabb(&skinned);
            let mid = (lo + hi) * 0.5;
            // Not capped by `max_factor` (see `StretchStrategy::Corners`): the pose bounds it.
            let half = (hi - lo) * (0.5 * s.multiplier);
            if !(half.is_finite() && mid.is_finite()) {
                return scalar(thesis_factor(&v.skin));
            }
            SplatBox {
                center: mid,
                half_extent: half,
            }
        }
        (StretchStrategy::Adaptive, Some(cs)) => {
            let blended = blend_matrix(skinning, v.skin.joints_u16(), v.skin.blend_weights());
            let skinned = skin_corners(skinning, &voxel_corners(v.center, v.half_size), cs);
            let linear = Mat3::from_mat4(blended);
            // This API's box is a scalar cube in skinned space, so the factor measured in the
            // voxel's own (blended) frame is scaled by how much that frame grows.
            scalar(
                containing_factor(&skinned, v.half_size, center, linear).map_or_else(
                    || thesis_factor(&v.skin),
                    |f| f * max_singular_value(linear),
                ),
            )
        }
        (StretchStrategy::Adaptive, None) => scalar(blended_linear_factor(skinning, &v.skin)),
    }
}

//! Linear-blend skinning of points and normals, and repair of bad vertex weights.

use glam::{Mat3, Mat4, Vec3, Vec4};
use serde::{Deserialize, Serialize};

use crate::mesh::TriangleMesh;

/// `Σ wᵢ · skinning[jᵢ]`. Joint indices past the matrix table are skipped (their weight is
/// lost), so bad data never panics.
#[inline]
#[must_use]
pub fn blend_matrix(skinning: &[Mat4], joints: [u16; 4], weights: [f32; 4]) -> Mat4 {
    let mut m = Mat4::ZERO;
    for k in 0..4 {
        let w = weights[k];
        if w != 0.0
            && let Some(j) = skinning.get(usize::from(joints[k]))
        {
            m += *j * w;
        }
    }
    m
}

/// Skins a bind-pose mesh-space point: `Σ wᵢ · (skinning[jᵢ] · p)`. Weights are used as given
/// (repair them once at import with [`repair_weights`]).
#[inline]
#[must_use]
pub fn skin_point(skinning: &[Mat4], joints: [u16; 4], weights: [f32; 4], p: Vec3) -> Vec3 {
    let p4 = Vec4::new(p.x, p.y, p.z, 1.0);
    let mut acc = Vec4::ZERO;
    for k in 0..4 {
        let w = weights[k];
        if w != 0.0
            && let Some(j) = skinning.get(usize::from(joints[k]))
        {
            acc += (*j * p4) * w;
        }
    }
    Vec3::new(acc.x, acc.y, acc.z)
}

/// Transforms a normal by the linear part `a` of a (blended) skinning matrix: the cofactor
/// matrix `det(a) · a⁻ᵀ` keeps normals perpendicular under non-uniform scale without dividing by
/// the determinant, so a joint scaled to 0 gives a finite result. When the cofactor direction
/// vanishes too (the surface collapsed to a line or point) it falls back to `a · n`, then to
/// `n`. Never NaN for finite input; unit length unless the input was zero.
#[must_use]
pub fn transform_normal(a: Mat3, n: Vec3) -> Vec3 {
    normal_through(normal_matrix(a), || a, n)
}

/// The matrix [`transform_normal`] applies before normalising: the cofactor matrix of `a`,
/// negated when `det(a) < 0`. A renderer that transforms many normals by one `a` computes it
/// once and calls [`normal_through`].
#[must_use]
pub fn normal_matrix(a: Mat3) -> Mat3 {
    let cofactor = Mat3::from_cols(
        a.y_axis.cross(a.z_axis),
        a.z_axis.cross(a.x_axis),
        a.x_axis.cross(a.y_axis),
    );
    let det = a.x_axis.dot(cofactor.x_axis);
    // Multiplying by ±1 is exact, so this equals negating the transformed normal.
    if det < 0.0 { cofactor * -1.0 } else { cofactor }
}

/// [`transform_normal`] of `n` given `c = normal_matrix(a)`; `a` is asked for only when the
/// cofactor direction vanishes (a collapsed frame).
#[must_use]
pub fn normal_through(c: Mat3, a: impl FnOnce() -> Mat3, n: Vec3) -> Vec3 {
    (c * n)
        .try_normalize()
        .or_else(|| (a() * n).try_normalize())
        .unwrap_or_else(|| n.normalize_or_zero())
}

/// Skins a normal with the same weights as its vertex (see [`transform_normal`]).
#[must_use]
pub fn skin_normal(skinning: &[Mat4], joints: [u16; 4], weights: [f32; 4], n: Vec3) -> Vec3 {
    transform_normal(Mat3::from_mat4(blend_matrix(skinning, joints, weights)), n)
}

/// Skins many points: `out[i] = skin_point(.., joints[i], weights[i], positions[i])`. Stops at
/// the shortest of the four slices.
pub fn skin_points(
    skinning: &[Mat4],
    joints: &[[u16; 4]],
    weights: &[[f32; 4]],
    positions: &[Vec3],
    out: &mut [Vec3],
) {
    for (((o, &j), &w), &p) in out.iter_mut().zip(joints).zip(weights).zip(positions) {
        *o = skin_point(skinning, j, w, p);
    }
}

/// A skinned copy of `mesh` (positions and normals); a mesh without joints or weights is
/// returned unchanged.
#[must_use]
pub fn skin_mesh(skinning: &[Mat4], mesh: &TriangleMesh) -> TriangleMesh {
    let mut out = mesh.clone();
    let n = mesh.positions.len();
    if mesh.joints.len() != n || mesh.weights.len() != n {
        return out;
    }
    skin_points(
        skinning,
        &mesh.joints,
        &mesh.weights,
        &mesh.positions,
        &mut out.positions,
    );
    if mesh.normals.len() == n {
        for i in 0..n {
            out.normals[i] =
                skin_normal(skinning, mesh.joints[i], mesh.weights[i], mesh.normals[i]);
        }
    }
    out
}

/// Counts of weights repaired by [`repair_weights`] (each counts vertices, not slots).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct WeightRepair {
    /// Vertices with a negative weight (set to 0).
    pub negative: usize,
    /// Vertices with a NaN or infinite weight (set to 0).
    pub non_finite: usize,
    /// Vertices with a non-zero weight on a joint index past the skeleton (set to 0).
    pub out_of_range: usize,
    /// Vertices whose weights were all zero (given weight 1 on the root joint 0).
    pub all_zero: usize,
    /// Vertices whose weights summed to something other than 1 by more than 8-bit quantisation
    /// explains (renormalised). Small sums errors are renormalised silently.
    pub renormalised: usize,
}

/// In words, the causes that occurred: `3 vertices with a negative weight (set to 0), 1 with
/// no weight (bound to the root joint)`.
impl std::fmt::Display for WeightRepair {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let causes = [
            (self.negative, "with a negative weight (set to 0)"),
            (self.non_finite, "with a NaN or infinite weight (set to 0)"),
            (
                self.out_of_range,
                "weighted on a joint the skeleton does not have (set to 0)",
            ),
            (self.all_zero, "with no weight (bound to the root joint)"),
            (
                self.renormalised,
                "whose weights did not sum to 1 (renormalised)",
            ),
        ];
        let mut first = true;
        for (count, cause) in causes.into_iter().filter(|(n, _)| *n > 0) {
            if first {
                let noun = if count == 1 { "vertex" } else { "vertices" };
                write!(f, "{count} {noun} {cause}")?;
                first = false;
            } else {
                write!(f, ", {count} {cause}")?;
            }
        }
        if first {
            f.write_str("no vertex")?;
        }
        Ok(())
    }
}

impl WeightRepair {
    /// Vertices touched by any repair (a vertex may be counted under several causes).
    #[must_use]
    pub fn total(&self) -> usize {
        self.negative + self.non_finite + self.out_of_range + self.all_zero + self.renormalised
    }

    /// Adds another report's counts.
    pub fn add(&mut self, other: &Self) {
        self.negative += other.negative;
        self.non_finite += other.non_finite;
        self.out_of_range += other.out_of_range;
        self.all_zero += other.all_zero;
        self.renormalised += other.renormalised;
    }
}

/// Sum errors up to this size come from unorm8 weights (4 × ½ / 255) and are fixed silently.
const QUANTISATION_SUM_TOLERANCE: f32 = 0.01;

/// Repairs one vertex's weights in place: negative, non-finite and out-of-range weights become
/// 0; all-zero weights become weight 1 on joint 0 (the root after topological sorting, so such a
/// vertex follows the character rather than staying behind in the bind pose); the rest are
/// renormalised to sum to 1. `joint_count` 0 skips the range check.
pub fn repair_weights(
    joints: &mut [u16; 4],
    weights: &mut [f32; 4],
    joint_count: usize,
) -> WeightRepair {
    let mut r = WeightRepair::default();
    let (mut negative, mut non_finite, mut out_of_range) = (false, false, false);
    for k in 0..4 {
        let w = weights[k];
        if !w.is_finite() {
            non_finite = true;
            weights[k] = 0.0;
        } else if w < 0.0 {
            negative = true;
            weights[k] = 0.0;
        } else if w > 0.0 && joint_count > 0 && usize::from(joints[k]) >= joint_count {
            out_of_range = true;
            weights[k] = 0.0;
        }
        if weights[k] == 0.0 && joint_count > 0 && usize::from(joints[k]) >= joint_count {
            // Keep unused slots pointing at a valid joint so later passes can index blindly.
            joints[k] = 0;
        }
    }
    r.negative = usize::from(negative);
    r.non_finite = usize::from(non_finite);
    r.out_of_range = usize::from(out_of_range);
    let sum: f32 = weights.iter().sum();
    if sum <= 0.0 || !sum.is_finite() {
        r.all_zero = 1;
        *joints = [0; 4];
        *weights = [1.0, 0.0, 0.0, 0.0];
        return r;
    }
    if (sum - 1.0).abs() > QUANTISATION_SUM_TOLERANCE {
        r.renormalised = 1;
    }
    if sum != 1.0 {
        let inv = sum.recip();
        for w in weights.iter_mut() {
            *w *= inv;
        }
    }
    r
}

/// Repairs every vertex of a mesh (see [`repair_weights`]); a mesh without skin data is left
/// alone.
pub fn repair_mesh_weights(mesh: &mut TriangleMesh, joint_count: usize) -> WeightRepair {
    let mut total = WeightRepair::default();
    for (j, w) in mesh.joints.iter_mut().zip(mesh.weights.iter_mut()) {
        total.add(&repair_weights(j, w, joint_count));
    }
    total
}

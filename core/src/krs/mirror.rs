//! Mirror planes R_i: `normal · x − offset = 0` with a unit normal.

use glam::{Mat3, Vec3};
use serde::{Deserialize, Serialize};

/// A reflection plane `normal · x − offset = 0`. With a unit normal the left side is the signed
/// distance to the plane; Algorithm 1 folds points with a positive value onto the negative side.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MirrorPlane {
    /// Unit normal (validation normalises it, keeping the plane).
    pub normal: Vec3,
    /// Offset c along the normal.
    pub offset: f32,
}

impl Default for MirrorPlane {
    fn default() -> Self {
        Self {
            normal: Vec3::X,
            offset: 0.0,
        }
    }
}

impl MirrorPlane {
    /// A mirror with the given normal (normalised here; zero becomes +X) and offset.
    pub fn new(normal: Vec3, offset: f32) -> Self {
        Self {
            normal: normal.normalize_or(Vec3::X),
            offset,
        }
    }

    /// The mirror through `point` with the given normal.
    pub fn through(point: Vec3, normal: Vec3) -> Self {
        let normal = normal.normalize_or(Vec3::X);
        Self {
            normal,
            offset: normal.dot(point),
        }
    }

    /// Signed distance of `p` to the plane (positive on the side that gets folded).
    #[inline]
    pub fn signed_distance(&self, p: Vec3) -> f32 {
        self.normal.dot(p) - self.offset
    }

    /// The paper's R_i: reflection of a point.
    #[inline]
    pub fn reflect_point(&self, p: Vec3) -> Vec3 {
        p - 2.0 * self.signed_distance(p) * self.normal
    }

    /// The paper's M_i: reflection of a direction.
    #[inline]
    pub fn reflect_dir(&self, v: Vec3) -> Vec3 {
        v - 2.0 * self.normal.dot(v) * self.normal
    }

    /// Linear part of the reflection (Householder matrix, determinant −1).
    pub fn matrix(&self) -> Mat3 {
        let n = self.normal;
        Mat3::IDENTITY - 2.0 * Mat3::from_cols(n * n.x, n * n.y, n * n.z)
    }
}

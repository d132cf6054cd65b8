//! The tree builder (§7.2): intuitive parameters → a KRS with toroidal-capsule branches.
//!
//! The artist gives fork positions along one route from the trunk base to a twig tip. Branch
//! k runs from `route[k]` to `route[k+1]` (k = 0 is the trunk); a control point per branch bends
//! it into a circular arc (the torus of the toroidal capsule); a mirror through each fork point
//! doubles everything above the fork. Kernels are ordered twig first (the paper's K0 is the
//! finest detail): [leaf], twig, …, trunk, then empty kernels for forest reflections.

use std::f64::consts::TAU;

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::kernel::{CapsuleKernel, Kernel, Material, SphereKernel, TorusKernel};
use super::mirror::MirrorPlane;
use super::object::KrsObject;

/// A leaf (cluster) at the twig tip, doubled by one mirror through the tip.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LeafParams {
    /// Leaf ball radius.
    pub radius: f32,
    /// Leaf centre relative to the twig tip.
    pub offset: Vec3,
    /// Normal of the mirror through the tip that pairs the leaves.
    pub mirror_normal: Vec3,
    /// Leaf appearance.
    pub material: Material,
}

impl Default for LeafParams {
    fn default() -> Self {
        Self {
            radius: 0.12,
            offset: Vec3::new(0.12, 0.05, 0.0),
            mirror_normal: Vec3::X,
            material: Material::new(Vec3::new(0.12, 0.35, 0.08), 2),
        }
    }
}

/// Intuitive tree parameters (§7.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TreeParams {
    /// Fork positions along one route: trunk base first, twig tip last (≥ 2 points).
    pub route: Vec<Vec3>,
    /// Per branch (trunk first): offset of its control point from the chord midpoint; the arc
    /// through start, control point and end bends the branch. Missing entries are straight.
    pub bends: Vec<Vec3>,
    /// Per branch (trunk first): section radius. Missing entries copy the last one given.
    pub widths: Vec<f32>,
    /// Per fork (the fork at `route[k]` is entry k − 1): mirror normal, editable. The sign is
    /// chosen so the branch leaving the fork is on the kept (negative) side. Missing or zero
    /// entries get a default that turns by the golden angle per fork.
    pub fork_normals: Vec<Vec3>,
    /// Bark appearance.
    pub bark: Material,
    /// Optional leaf at the twig tip.
    pub leaf: Option<LeafParams>,
    /// Extra reflections after the trunk (with empty kernels) that multiply the whole tree:
    /// a forest.
    pub forest_mirrors: Vec<MirrorPlane>,
}

impl Default for TreeParams {
    fn default() -> Self {
        let lengths = [2.2, 1.3, 1.0, 0.8, 0.6, 0.45, 0.35];
        Self {
            route: spiral_route(&lengths, 1.45, 0.75),
            bends: vec![
                Vec3::new(0.06, 0.0, 0.0),
                Vec3::new(-0.08, 0.0, 0.04),
                Vec3::new(0.0, 0.05, -0.06),
                Vec3::new(0.04, 0.0, 0.04),
                Vec3::new(-0.03, 0.02, 0.0),
                Vec3::new(0.0, 0.0, 0.02),
                Vec3::ZERO,
            ],
            widths: vec![0.2, 0.12, 0.08, 0.055, 0.038, 0.026, 0.017],
            fork_normals: Vec::new(),
            bark: Material::new(Vec3::new(0.32, 0.22, 0.14), 1),
            leaf: Some(LeafParams::default()),
            forest_mirrors: Vec::new(),
        }
    }
}

/// A route whose branch k has length `lengths[k]`, leans from vertical by an angle growing
/// linearly from 0 (trunk) to `final_lean` radians, and turns by the golden angle in azimuth
/// per fork, so the forks spread around the trunk instead of lying in one plane.
pub fn spiral_route(lengths: &[f32], final_lean: f32, first_lean: f32) -> Vec<Vec3> {
    let mut p = Vec3::ZERO;
    let mut route = vec![p];
    let last = lengths.len().saturating_sub(1).max(1) as f32;
    for (k, &len) in lengths.iter().enumerate() {
        let lean = if k == 0 {
            0.0
        } else {
            first_lean + (final_lean - first_lean) * (k as f32 - 1.0) / last
        };
        let azimuth = GOLDEN_ANGLE * k as f32;
        let dir = Vec3::new(
            lean.sin() * azimuth.cos(),
            lean.cos(),
            lean.sin() * azimuth.sin(),
        );
        p += dir * len;
        route.push(p);
    }
    route
}

/// Why tree parameters cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TreeError {
    /// Fewer than two route points.
    #[error("tree route has {0} points; it needs at least 2 (trunk base and twig tip)")]
    TooFewPoints(usize),
    /// A parameter is NaN or ±∞.
    #[error("tree parameter `{field}` entry {index} is not finite")]
    NonFinite {
        /// Field name.
        field: &'static str,
        /// Entry index.
        index: usize,
    },
    /// A branch width is negative.
    #[error("tree branch {branch} has negative width {width}")]
    NegativeWidth {
        /// Branch index (trunk = 0).
        branch: usize,
        /// The width.
        width: f32,
    },
    /// Two consecutive route points coincide.
    #[error("tree branch {0} has zero length (its two route points coincide)")]
    ZeroLengthBranch(usize),
}

const GOLDEN_ANGLE: f32 = 2.399_963;

impl TreeParams {
    /// Number of branches on the route (route points − 1).
    pub fn branch_count(&self) -> usize {
        self.route.len().saturating_sub(1)
    }

    /// Whether [`TreeParams::build`] succeeds, with its error, without building the tree (a
    /// document's tree builders are validated with it on every frame).
    ///
    /// # Errors
    /// As [`TreeParams::build`].
    pub fn validate(&self) -> Result<(), TreeError> {
        if self.route.len() < 2 {
            return Err(TreeError::TooFewPoints(self.route.len()));
        }
        let finite = |field, v: &[Vec3]| {
            v.iter()
                .position(|p| !p.is_finite())
                .map_or(Ok(()), |index| Err(TreeError::NonFinite { field, index }))
        };
        finite("route", &self.route)?;
        finite("bends", &self.bends)?;
        finite("fork_normals", &self.fork_normals)?;
        for (branch, &width) in self.widths.iter().enumerate() {
            if !width.is_finite() {
                return Err(TreeError::NonFinite {
                    field: "widths",
                    index: branch,
                });
            }
            if width < 0.0 {
                return Err(TreeError::NegativeWidth { branch, width });
            }
        }
        for b in 0..self.branch_count() {
            if self.route[b].distance(self.route[b + 1]) <= 1e-6 * (1.0 + self.route[b].length()) {
                return Err(TreeError::ZeroLengthBranch(b));
            }
        }
        if let Some(leaf) = &self.leaf
            && !(leaf.radius.is_finite()
                && leaf.offset.is_finite()
                && leaf.mirror_normal.is_finite())
        {
            return Err(TreeError::NonFinite {
                field: "leaf",
                index: 0,
            });
        }
        Ok(())
    }

    fn width(&self, branch: usize) -> f32 {
        self.widths
            .get(branch)
            .or(self.widths.last())
            .copied()
            .unwrap_or(0.05)
    }

    /// The mirror at the fork `route[fork]` (1 ≤ fork < route.len() − 1), oriented so the
    /// branch leaving the fork lies on the negative side.
    pub fn fork_mirror(&self, fork: usize) -> MirrorPlane {
        let point = self.route[fork];
        let incoming = (point - self.route[fork - 1]).normalize_or(Vec3::Y);
        let outgoing = (self.route[fork + 1] - point).normalize_or(incoming);
        let given = self
            .fork_normals
            .get(fork - 1)
            .and_then(|n| n.try_normalize());
        // Default: the plane containing the incoming branch, facing the way the route turns,
        // so the reflected sibling leaves the fork symmetrically on the other side (a Y fork).
        let normal = given.unwrap_or_else(|| {
            let turn = outgoing - incoming * incoming.dot(outgoing);
            turn.try_normalize().unwrap_or_else(|| {
                let a = GOLDEN_ANGLE * fork as f32;
                let h = Vec3::new(a.cos(), 0.0, a.sin());
                (h - incoming * incoming.dot(h)).normalize_or(incoming.any_orthonormal_vector())
            })
        });
        let normal = if normal.dot(outgoing) > 0.0 {
            -normal
        } else {
            normal
        };
        MirrorPlane::through(point, normal)
    }

    /// The kernel of branch `b` (trunk = 0): a toroidal capsule through start, control point and
    /// end, or a capsule when the control point is (nearly) on the chord.
    pub fn branch_kernel(&self, b: usize) -> Kernel {
        let (a, e) = (self.route[b], self.route[b + 1]);
        let bend = self.bends.get(b).copied().unwrap_or(Vec3::ZERO);
        let radius = self.width(b);
        let material = self.bark;
        let straight = Kernel::Capsule(CapsuleKernel {
            start: a,
            end: e,
            radius,
            material,
        });
        if bend.length() <= 1e-4 * a.distance(e) {
            return straight;
        }
        let c = 0.5 * (a + e) + bend;
        match circle_through(a.as_dvec3(), c.as_dvec3(), e.as_dvec3()) {
            Some((centre, axis, start_dir, major, sweep)) => Kernel::ToroidalCapsule(TorusKernel {
                centre: centre.as_vec3(),
                axis: axis.as_vec3(),
                start_dir: start_dir.as_vec3(),
                major_radius: major as f32,
                minor_radius: radius,
                sweep_radians: sweep as f32,
                material,
            }),
            None => straight,
        }
    }

    /// Builds the KRS (not yet validated: [`KrsObject::validated`] or `KrsScene::prepare` does
    /// that).
    pub fn build(&self) -> Result<KrsObject, TreeError> {
        self.validate()?;
        let branches = self.branch_count();
        let mut kernels = Vec::new();
        let mut mirrors = Vec::new();
        if let Some(leaf) = &self.leaf {
            let tip = self.route[branches];
            let centre = tip + leaf.offset;
            kernels.push(Kernel::Sphere(SphereKernel {
                centre,
                radius: leaf.radius.max(0.0),
                material: leaf.material,
            }));
            let n = leaf.mirror_normal.normalize_or(Vec3::X);
            let n = if n.dot(leaf.offset) > 0.0 { -n } else { n };
            mirrors.push(MirrorPlane::through(tip, n));
        }
        for b in (0..branches).rev() {
            kernels.push(self.branch_kernel(b));
            if b > 0 {
                mirrors.push(self.fork_mirror(b));
            }
        }
        for m in &self.forest_mirrors {
            mirrors.push(*m);
            kernels.push(Kernel::Empty);
        }
        Ok(KrsObject {
            name: "tree".to_owned(),
            kernels,
            mirrors,
            ..KrsObject::default()
        })
    }
}

/// Circle through a → c → b: (centre, axis, unit start direction, radius, sweep from a to b in
/// the direction that passes c). `None` when the points are (nearly) collinear.
pub(crate) fn circle_through(
    a: DVec3,
    c: DVec3,
    b: DVec3,
) -> Option<(DVec3, DVec3, DVec3, f64, f64)> {
    let (u, v) = (a - c, b - c);
    let uxv = u.cross(v);
    let denom = 2.0 * uxv.length_squared();
    let scale = u.length_squared().max(v.length_squared());
    if denom <= 1e-12 * scale * scale {
        return None;
    }
    let centre = c + (u.length_squared() * v - v.length_squared() * u).cross(uxv) / denom;
    let axis = (c - a).cross(b - a).try_normalize()?;
    let radius = a.distance(centre);
    let start_dir = ((a - centre) / radius).try_normalize()?;
    let w = axis.cross(start_dir);
    let q = b - centre;
    let mut sweep = q.dot(w).atan2(q.dot(start_dir));
    if sweep < 0.0 {
        sweep += TAU;
    }
    Some((centre, axis, start_dir, radius, sweep))
}

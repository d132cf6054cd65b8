//! Kernel shapes: the solids that the mirrors multiply.
//!
//! Every kernel is given in its object's space and has an exact (or, for the torus segment,
//! conservative) signed distance with Lipschitz constant 1, which is what Algorithm 1 and the
//! sphere tracer rely on.

use std::f32::consts::TAU;

use glam::{Quat, Vec2, Vec3};
use serde::{Deserialize, Serialize};

/// Surface appearance of a kernel: linear RGB base colour and an id the renderer can map to
/// a richer material.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Material {
    /// Linear RGB albedo in [0, 1].
    pub colour: Vec3,
    /// Material id for the renderer's material table.
    pub id: u32,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            colour: Vec3::splat(0.6),
            id: 0,
        }
    }
}

impl Material {
    /// A material with the given linear RGB colour and id.
    pub fn new(colour: Vec3, id: u32) -> Self {
        Self { colour, id }
    }
}

/// A ball.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SphereKernel {
    /// Centre in object space.
    pub centre: Vec3,
    /// Radius (≥ 0).
    pub radius: f32,
    /// Appearance.
    pub material: Material,
}

impl Default for SphereKernel {
    fn default() -> Self {
        Self {
            centre: Vec3::ZERO,
            radius: 1.0,
            material: Material::default(),
        }
    }
}

/// A half-space: the solid is where `normal · p − offset ≤ 0` (the paper's "infinite plane").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PlaneKernel {
    /// Outward unit normal (normalised by validation).
    pub normal: Vec3,
    /// Signed offset of the plane along the normal.
    pub offset: f32,
    /// Appearance.
    pub material: Material,
}

impl Default for PlaneKernel {
    fn default() -> Self {
        Self {
            normal: Vec3::Y,
            offset: 0.0,
            material: Material::default(),
        }
    }
}

/// A segment swept by a ball.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CapsuleKernel {
    /// First end point.
    pub start: Vec3,
    /// Second end point.
    pub end: Vec3,
    /// Radius (≥ 0).
    pub radius: f32,
    /// Appearance.
    pub material: Material,
}

impl Default for CapsuleKernel {
    fn default() -> Self {
        Self {
            start: Vec3::ZERO,
            end: Vec3::Y,
            radius: 0.1,
            material: Material::default(),
        }
    }
}

/// An oriented box with rounded edges.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BoxKernel {
    /// Centre in object space.
    pub centre: Vec3,
    /// Rotation object_from_box (normalised by validation).
    pub rotation: Quat,
    /// Outer half extents, rounding included (each ≥ 0).
    pub half_extents: Vec3,
    /// Edge rounding radius, 0 ≤ rounding ≤ min(half_extents).
    pub rounding: f32,
    /// Appearance.
    pub material: Material,
}

impl Default for BoxKernel {
    fn default() -> Self {
        Self {
            centre: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            half_extents: Vec3::splat(0.5),
            rounding: 0.0,
            material: Material::default(),
        }
    }
}

/// A tube of radius `minor_radius` around a circular arc (shared by the torus segment with flat
/// ends and the toroidal capsule with spherical caps, the paper's branch kernel).
///
/// The arc lies in the plane through `centre` perpendicular to `axis`, starts at
/// `centre + major_radius · start_dir` and turns by `sweep_radians` counter-clockwise about
/// `axis`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TorusKernel {
    /// Centre of the generating circle.
    pub centre: Vec3,
    /// Unit axis of the circle (normalised by validation).
    pub axis: Vec3,
    /// Unit direction from the centre to the arc's start, perpendicular to `axis`
    /// (orthonormalised by validation).
    pub start_dir: Vec3,
    /// Radius of the generating circle (≥ 0).
    pub major_radius: f32,
    /// Tube (section) radius (≥ 0).
    pub minor_radius: f32,
    /// Arc angle in radians, in [0, 2π].
    pub sweep_radians: f32,
    /// Appearance.
    pub material: Material,
}

impl Default for TorusKernel {
    fn default() -> Self {
        Self {
            centre: Vec3::ZERO,
            axis: Vec3::Z,
            start_dir: Vec3::X,
            major_radius: 1.0,
            minor_radius: 0.1,
            sweep_radians: std::f32::consts::FRAC_PI_2,
            material: Material::default(),
        }
    }
}

/// One kernel set K_i of a KRS.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "kind")]
pub enum Kernel {
    /// No geometry at this level (used for extra reflections, e.g. forests).
    #[default]
    Empty,
    /// A ball.
    Sphere(SphereKernel),
    /// A half-space (planar kernel for rock and terrain, §7.1).
    InfinitePlane(PlaneKernel),
    /// A segment swept by a ball.
    Capsule(CapsuleKernel),
    /// An oriented rounded box.
    RoundedBox(BoxKernel),
    /// A torus segment with flat ends.
    TorusSegment(TorusKernel),
    /// A torus segment with two capping spheres: the branch kernel of §7.2.
    ToroidalCapsule(TorusKernel),
}

/// What is wrong with a kernel's parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KernelProblem {
    /// A field holds NaN or ±∞.
    #[error("field `{0}` is not finite")]
    NonFinite(&'static str),
    /// A radius or extent is negative.
    #[error("field `{field}` is {value}, it must be ≥ 0")]
    Negative {
        /// Field name.
        field: &'static str,
        /// Its value.
        value: f32,
    },
    /// A direction has (near-)zero length.
    #[error("direction `{0}` has zero length; give it a non-zero direction")]
    ZeroDirection(&'static str),
    /// The torus start direction is parallel to its axis.
    #[error("`start_dir` is parallel to `axis`; it must have a component perpendicular to it")]
    StartAlongAxis,
    /// The torus sweep is outside [0, 2π].
    #[error("`sweep_radians` is {0}, it must lie in [0, 2π]")]
    SweepOutOfRange(f32),
    /// Box rounding exceeds the smallest half extent.
    #[error("`rounding` {rounding} exceeds the smallest half extent {smallest}")]
    RoundingTooLarge {
        /// The rounding.
        rounding: f32,
        /// The smallest half extent.
        smallest: f32,
    },
}

/// A conservative bound of a kernel's solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KernelBound {
    /// The kernel has no points.
    Empty,
    /// The solid lies inside this ball (centre, radius).
    Sphere(Vec3, f32),
    /// The solid is unbounded (half-space).
    Unbounded,
}

/// Length below which a direction is treated as zero.
pub(crate) const MIN_DIRECTION_LENGTH: f32 = 1e-12;

fn finite3(v: Vec3, name: &'static str) -> Result<(), KernelProblem> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(KernelProblem::NonFinite(name))
    }
}

fn finite1(v: f32, name: &'static str) -> Result<(), KernelProblem> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(KernelProblem::NonFinite(name))
    }
}

fn non_negative(v: f32, name: &'static str) -> Result<(), KernelProblem> {
    finite1(v, name)?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(KernelProblem::Negative {
            field: name,
            value: v,
        })
    }
}

fn unit(v: Vec3, name: &'static str) -> Result<Vec3, KernelProblem> {
    finite3(v, name)?;
    // Scale first so tiny but valid directions (1e-20) normalise without underflow.
    let m = v.abs().max_element();
    if m < MIN_DIRECTION_LENGTH {
        return Err(KernelProblem::ZeroDirection(name));
    }
    (v / m)
        .try_normalize()
        .ok_or(KernelProblem::ZeroDirection(name))
}

fn validate_material(m: &Material) -> Result<(), KernelProblem> {
    finite3(m.colour, "material.colour")
}

/// Any unit vector perpendicular to `v` (unit), chosen without branching on a threshold that
/// could flip between neighbouring pixels.
pub(crate) fn any_perpendicular(v: Vec3) -> Vec3 {
    v.any_orthonormal_vector()
}

impl TorusKernel {
    fn validated(&self) -> Result<Self, KernelProblem> {
        finite3(self.centre, "centre")?;
        let axis = unit(self.axis, "axis")?;
        let start = unit(self.start_dir, "start_dir")?;
        let start_dir = (start - axis * axis.dot(start))
            .try_normalize()
            .ok_or(KernelProblem::StartAlongAxis)?;
        non_negative(self.major_radius, "major_radius")?;
        non_negative(self.minor_radius, "minor_radius")?;
        finite1(self.sweep_radians, "sweep_radians")?;
        if !(0.0..=TAU).contains(&self.sweep_radians) {
            return Err(KernelProblem::SweepOutOfRange(self.sweep_radians));
        }
        validate_material(&self.material)?;
        Ok(Self {
            axis,
            start_dir,
            ..*self
        })
    }

    /// In-plane basis: (start_dir, axis × start_dir).
    #[inline]
    fn basis(&self) -> (Vec3, Vec3) {
        (self.start_dir, self.axis.cross(self.start_dir))
    }

    /// Arc end point.
    pub fn end_point(&self) -> Vec3 {
        let (u, w) = self.basis();
        let (s, c) = self.sweep_radians.sin_cos();
        self.centre + self.major_radius * (c * u + s * w)
    }

    /// Arc start point.
    pub fn start_point(&self) -> Vec3 {
        self.centre + self.major_radius * self.start_dir
    }

    /// A ball containing the arc (the tube's centre line). For a sweep up to π it is the ball
    /// on the chord: a point at angle φ from the arc's middle is at squared distance
    /// R²(1 − 2 cos φ cos(s/2) + cos²(s/2)) ≤ R² sin²(s/2) from the chord's midpoint when
    /// |φ| ≤ s/2 ≤ π/2. A gently bent branch has a huge major radius, and the whole circle's
    /// ball (used for larger sweeps) would be far larger than the branch: it would swell the
    /// object's bounding ball, which clips rays and sets the export mesher's region.
    #[must_use]
    pub fn arc_bound(&self) -> (Vec3, f32) {
        let circle = (self.centre, self.major_radius);
        // Only a validated kernel has the orthonormal basis the chord formula relies on.
        let orthonormal = (self.axis.length() - 1.0).abs() < 1e-4
            && (self.start_dir.length() - 1.0).abs() < 1e-4
            && self.axis.dot(self.start_dir).abs() < 1e-4;
        if !orthonormal || self.sweep_radians.is_nan() || self.sweep_radians > std::f32::consts::PI
        {
            return circle;
        }
        let (a, b) = (self.start_point(), self.end_point());
        // f32 rounding of the end points grows with their magnitude.
        let slack =
            8.0 * f32::EPSILON * (self.major_radius + self.centre.abs().max_element() + 1.0);
        let chord = (0.5 * (a + b), 0.5 * a.distance(b) + slack);
        if chord.1 < circle.1 { chord } else { circle }
    }

    /// Closest point on the arc and its angle from the start, in [0, sweep].
    #[inline]
    fn closest_on_arc(&self, p: Vec3) -> (Vec3, f32) {
        let (u, w) = self.basis();
        let q = p - self.centre;
        let (x, y) = (q.dot(u), q.dot(w));
        let mut theta = y.atan2(x);
        if theta < 0.0 {
            theta += TAU;
        }
        if theta <= self.sweep_radians {
            let (s, c) = theta.sin_cos();
            return (self.centre + self.major_radius * (c * u + s * w), theta);
        }
        // Outside the arc's angular range the nearest arc point is an end point: distance to a
        // circle point grows with the angular gap.
        let a = self.start_point();
        let b = self.end_point();
        if p.distance_squared(a) <= p.distance_squared(b) {
            (a, 0.0)
        } else {
            (b, self.sweep_radians)
        }
    }

    /// Signed distance of the wedge of angles [0, sweep] (a lower bound for sweep ≤ π, exact
    /// outside for sweep > π) and its outward gradient.
    #[inline]
    fn wedge(&self, p: Vec3) -> (f32, Vec3) {
        let (u, w) = self.basis();
        let q = p - self.centre;
        let h0 = -q.dot(w);
        let (s, c) = self.sweep_radians.sin_cos();
        let tangent_end = -s * u + c * w;
        let h1 = q.dot(tangent_end);
        let use_first = if self.sweep_radians <= std::f32::consts::PI {
            h0 >= h1
        } else {
            h0 <= h1
        };
        if use_first {
            (h0, -w)
        } else {
            (h1, tangent_end)
        }
    }
}

impl Kernel {
    /// The variant's name as written in project files (`"Sphere"`, `"ToroidalCapsule"`, …).
    pub fn kind_name(&self) -> &'static str {
        match self {
            Kernel::Empty => "Empty",
            Kernel::Sphere(_) => "Sphere",
            Kernel::InfinitePlane(_) => "InfinitePlane",
            Kernel::Capsule(_) => "Capsule",
            Kernel::RoundedBox(_) => "RoundedBox",
            Kernel::TorusSegment(_) => "TorusSegment",
            Kernel::ToroidalCapsule(_) => "ToroidalCapsule",
        }
    }

    /// The kernel's material, `None` for [`Kernel::Empty`].
    pub fn material(&self) -> Option<&Material> {
        match self {
            Kernel::Empty => None,
            Kernel::Sphere(k) => Some(&k.material),
            Kernel::InfinitePlane(k) => Some(&k.material),
            Kernel::Capsule(k) => Some(&k.material),
            Kernel::RoundedBox(k) => Some(&k.material),
            Kernel::TorusSegment(k) | Kernel::ToroidalCapsule(k) => Some(&k.material),
        }
    }

    /// Whether the kernel has no geometry.
    pub fn is_empty(&self) -> bool {
        matches!(self, Kernel::Empty)
    }

    /// Checks every field and returns the kernel with its directions normalised.
    pub fn validated(&self) -> Result<Kernel, KernelProblem> {
        Ok(match self {
            Kernel::Empty => Kernel::Empty,
            Kernel::Sphere(k) => {
                finite3(k.centre, "centre")?;
                non_negative(k.radius, "radius")?;
                validate_material(&k.material)?;
                Kernel::Sphere(*k)
            }
            Kernel::InfinitePlane(k) => {
                finite3(k.normal, "normal")?;
                finite1(k.offset, "offset")?;
                let len = k.normal.length();
                let normal = unit(k.normal, "normal")?;
                validate_material(&k.material)?;
                // Keep the same plane: n·p = c with |n| ≠ 1 is (n/|n|)·p = c/|n|.
                let offset = if len.is_finite() && len > 0.0 {
                    k.offset / len
                } else {
                    k.offset
                };
                Kernel::InfinitePlane(PlaneKernel {
                    normal,
                    offset,
                    ..*k
                })
            }
            Kernel::Capsule(k) => {
                finite3(k.start, "start")?;
                finite3(k.end, "end")?;
                non_negative(k.radius, "radius")?;
                validate_material(&k.material)?;
                Kernel::Capsule(*k)
            }
            Kernel::RoundedBox(k) => {
                finite3(k.centre, "centre")?;
                if !k.rotation.is_finite() {
                    return Err(KernelProblem::NonFinite("rotation"));
                }
                let rotation =
                    normalized_quat(k.rotation).ok_or(KernelProblem::ZeroDirection("rotation"))?;
                finite3(k.half_extents, "half_extents")?;
                if k.half_extents.min_element() < 0.0 {
                    return Err(KernelProblem::Negative {
                        field: "half_extents",
                        value: k.half_extents.min_element(),
                    });
                }
                non_negative(k.rounding, "rounding")?;
                if k.rounding > k.half_extents.min_element() {
                    return Err(KernelProblem::RoundingTooLarge {
                        rounding: k.rounding,
                        smallest: k.half_extents.min_element(),
                    });
                }
                validate_material(&k.material)?;
                Kernel::RoundedBox(BoxKernel { rotation, ..*k })
            }
            Kernel::TorusSegment(k) => Kernel::TorusSegment(k.validated()?),
            Kernel::ToroidalCapsule(k) => Kernel::ToroidalCapsule(k.validated()?),
        })
    }

    /// Signed distance from `p` (object space) to the kernel; `f32::INFINITY` for `Empty`.
    #[inline]
    pub fn distance(&self, p: Vec3) -> f32 {
        match self {
            Kernel::Empty => f32::INFINITY,
            Kernel::Sphere(k) => p.distance(k.centre) - k.radius,
            Kernel::InfinitePlane(k) => k.normal.dot(p) - k.offset,
            Kernel::Capsule(k) => p.distance(closest_on_segment(p, k.start, k.end)) - k.radius,
            Kernel::RoundedBox(k) => {
                let q = k.rotation.inverse() * (p - k.centre);
                let e = q.abs() - k.half_extents + Vec3::splat(k.rounding);
                e.max(Vec3::ZERO).length() + e.max_element().min(0.0) - k.rounding
            }
            Kernel::ToroidalCapsule(k) => {
                let (c, _) = k.closest_on_arc(p);
                p.distance(c) - k.minor_radius
            }
            Kernel::TorusSegment(k) => {
                let (c, _) = k.closest_on_arc(p);
                let tube = p.distance(c) - k.minor_radius;
                tube.max(k.wedge(p).0)
            }
        }
    }

    /// Unit outward normal (gradient of [`Kernel::distance`]) at `p`; a fixed unit vector where
    /// the gradient is undefined (centre of a sphere, on an axis), never NaN.
    pub fn normal(&self, p: Vec3) -> Vec3 {
        let n = match self {
            Kernel::Empty => Vec3::Y,
            Kernel::Sphere(k) => p - k.centre,
            Kernel::InfinitePlane(k) => k.normal,
            Kernel::Capsule(k) => {
                let c = closest_on_segment(p, k.start, k.end);
                let n = p - c;
                if n.length_squared() > 0.0 {
                    n
                } else {
                    any_perpendicular((k.end - k.start).normalize_or(Vec3::Y))
                }
            }
            Kernel::RoundedBox(k) => {
                let q = k.rotation.inverse() * (p - k.centre);
                let e = q.abs() - k.half_extents + Vec3::splat(k.rounding);
                let local = if e.max_element() > 0.0 {
                    e.max(Vec3::ZERO) * q.signum()
                } else {
                    // Inside: the gradient is the axis of the nearest face.
                    let i = if e.x >= e.y && e.x >= e.z {
                        0
                    } else if e.y >= e.z {
                        1
                    } else {
                        2
                    };
                    let mut v = Vec3::ZERO;
                    v[i] = q[i].signum();
                    v
                };
                k.rotation * local
            }
            Kernel::ToroidalCapsule(k) => torus_tube_normal(k, p),
            Kernel::TorusSegment(k) => {
                let (c, _) = k.closest_on_arc(p);
                let tube = p.distance(c) - k.minor_radius;
                let (wedge, wedge_normal) = k.wedge(p);
                if wedge > tube {
                    wedge_normal
                } else {
                    torus_tube_normal(k, p)
                }
            }
        };
        n.normalize_or(Vec3::Y)
    }

    /// Kernel-parametrised coordinates (§6.2) in object-space length units: `x` runs along the
    /// kernel (arc length along a branch, segment parameter along a capsule, longitude on a
    /// sphere), `y` around it (arc length around the tube).
    pub fn param_coords(&self, p: Vec3) -> Vec2 {
        match self {
            Kernel::Empty => Vec2::ZERO,
            Kernel::Sphere(k) => {
                let q = (p - k.centre).normalize_or(Vec3::Y);
                Vec2::new(
                    q.z.atan2(q.x) * k.radius,
                    q.y.clamp(-1.0, 1.0).asin() * k.radius,
                )
            }
            Kernel::InfinitePlane(k) => {
                let u = any_perpendicular(k.normal);
                let v = k.normal.cross(u);
                Vec2::new(p.dot(u), p.dot(v))
            }
            Kernel::Capsule(k) => {
                let axis = (k.end - k.start).normalize_or(Vec3::Y);
                let u = any_perpendicular(axis);
                let v = axis.cross(u);
                let q = p - k.start;
                let around = q.dot(v).atan2(q.dot(u));
                Vec2::new(q.dot(axis), around * k.radius)
            }
            Kernel::RoundedBox(k) => {
                let q = k.rotation.inverse() * (p - k.centre);
                let a = q.abs() / k.half_extents.max(Vec3::splat(1e-30));
                // Project on the face whose axis dominates (box-mapped coordinates).
                if a.x >= a.y && a.x >= a.z {
                    Vec2::new(q.y, q.z)
                } else if a.y >= a.z {
                    Vec2::new(q.x, q.z)
                } else {
                    Vec2::new(q.x, q.y)
                }
            }
            Kernel::TorusSegment(k) | Kernel::ToroidalCapsule(k) => {
                let (c, theta) = k.closest_on_arc(p);
                let radial = (c - k.centre).normalize_or(k.start_dir);
                let q = p - c;
                let around = q.dot(k.axis).atan2(q.dot(radial));
                Vec2::new(theta * k.major_radius, around * k.minor_radius)
            }
        }
    }

    /// How far `p` is from a crease of the kernel's own distance field, measured as the gap
    /// between the two competing terms (∞ for kernels without creases outside the solid). The
    /// normal is undefined on a crease; tests of normals stay away from them.
    pub fn crease_gap(&self, p: Vec3) -> f32 {
        match self {
            Kernel::TorusSegment(k) => {
                let (c, _) = k.closest_on_arc(p);
                let tube = p.distance(c) - k.minor_radius;
                (tube - k.wedge(p).0).abs()
            }
            _ => f32::INFINITY,
        }
    }

    /// A ball containing the kernel's solid.
    pub fn bound(&self) -> KernelBound {
        match self {
            Kernel::Empty => KernelBound::Empty,
            Kernel::Sphere(k) => KernelBound::Sphere(k.centre, k.radius),
            Kernel::InfinitePlane(_) => KernelBound::Unbounded,
            Kernel::Capsule(k) => KernelBound::Sphere(
                0.5 * (k.start + k.end),
                0.5 * k.start.distance(k.end) + k.radius,
            ),
            Kernel::RoundedBox(k) => KernelBound::Sphere(k.centre, k.half_extents.length()),
            Kernel::TorusSegment(k) | Kernel::ToroidalCapsule(k) => {
                let (c, r) = k.arc_bound();
                KernelBound::Sphere(c, r + k.minor_radius)
            }
        }
    }
}

fn torus_tube_normal(k: &TorusKernel, p: Vec3) -> Vec3 {
    let (c, _) = k.closest_on_arc(p);
    let n = p - c;
    if n.length_squared() > 0.0 {
        n
    } else {
        // On the arc itself: any direction is a subgradient; use the radial one.
        (c - k.centre).normalize_or(k.start_dir)
    }
}

/// Closest point to `p` on segment `a`–`b` (a point segment when `a == b`).
#[inline]
pub(crate) fn closest_on_segment(p: Vec3, a: Vec3, b: Vec3) -> Vec3 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 <= 0.0 {
        return a;
    }
    let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
    a + ab * t
}

/// The unit quaternion of `q`, `None` when `q` has (near-)zero length.
pub(crate) fn normalized_quat(q: Quat) -> Option<Quat> {
    let v = glam::Vec4::from(q).try_normalize()?;
    Some(Quat::from_vec4(v))
}

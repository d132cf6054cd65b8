//! KRS objects and scenes: validation, Algorithm 1, the brute-force reference, normals (§6.1).

use glam::{DVec3, Mat3, Quat, Vec3};
use serde::{Deserialize, Serialize};

use super::distort::Distortion;
use super::kernel::{Kernel, KernelBound, KernelProblem, MIN_DIRECTION_LENGTH, Material};
use super::mirror::MirrorPlane;
use super::shade::Texturing;

/// A rigid transform with uniform scale: `world = translation + rotation · (scale · object)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Similarity {
    /// Translation in world units.
    pub translation: Vec3,
    /// Rotation world_from_object (normalised by validation).
    pub rotation: Quat,
    /// Uniform scale (> 0).
    pub scale: f32,
}

impl Default for Similarity {
    fn default() -> Self {
        Self {
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: 1.0,
        }
    }
}

impl Similarity {
    /// Maps an object-space point to world space.
    #[inline]
    pub fn transform_point(&self, p_object: Vec3) -> Vec3 {
        self.translation + self.rotation * (p_object * self.scale)
    }

    /// Maps a world-space point to object space.
    #[inline]
    pub fn inverse_transform_point(&self, p_world: Vec3) -> Vec3 {
        self.rotation.inverse() * (p_world - self.translation) / self.scale
    }
}

/// A world-space ball inside which an object's geometry is removed (§6.4), e.g. so a tree can be
/// replaced by rigid-body instances.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct EmptyZone {
    /// Centre in world space.
    pub centre: Vec3,
    /// Radius in world units (≥ 0).
    pub radius: f32,
}

impl Default for EmptyZone {
    fn default() -> Self {
        Self {
            centre: Vec3::ZERO,
            radius: 1.0,
        }
    }
}

/// A kernel-reflection sequence: kernels K0..Kn and mirrors R0..R(n−1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct KrsObject {
    /// Display name.
    pub name: String,
    /// Kernel sets K0..Kn (n + 1 of them; any may be [`Kernel::Empty`]).
    pub kernels: Vec<Kernel>,
    /// Mirror planes R0..R(n−1).
    pub mirrors: Vec<MirrorPlane>,
    /// Placement of the object in the world.
    pub world_from_object: Similarity,
    /// Optional Lipschitz-bounded warp hiding symmetry (§5.2).
    pub distortion: Option<Distortion>,
    /// How the surface colour is textured (§6.2).
    pub texturing: Texturing,
    /// Balls where the geometry is removed (§6.4).
    pub empty_zones: Vec<EmptyZone>,
}

impl Default for KrsObject {
    fn default() -> Self {
        Self {
            name: String::new(),
            kernels: vec![Kernel::Sphere(Default::default())],
            mirrors: Vec::new(),
            world_from_object: Similarity::default(),
            distortion: None,
            texturing: Texturing::default(),
            empty_zones: Vec::new(),
        }
    }
}

/// A union of KRS objects (a forest, a rock field, …).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct KrsScene {
    /// The objects.
    pub objects: Vec<KrsObject>,
}

/// Why a KRS cannot be traced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KrsError {
    /// Kernel and mirror counts do not fit `kernels = mirrors + 1`.
    #[error(
        "KRS object {object}: has {kernels} kernels and {mirrors} mirrors; it needs exactly one \
         kernel more than mirrors (use Empty kernels for levels without geometry)"
    )]
    KernelCount {
        /// Object index.
        object: usize,
        /// Number of kernels.
        kernels: usize,
        /// Number of mirrors.
        mirrors: usize,
    },
    /// A mirror normal has (near-)zero length.
    #[error(
        "KRS object {object}, mirror {mirror}: normal {normal:?} has zero length, so the plane is \
         undefined; give the mirror a non-zero normal"
    )]
    ZeroMirrorNormal {
        /// Object index.
        object: usize,
        /// Mirror index.
        mirror: usize,
        /// The normal as given.
        normal: Vec3,
    },
    /// A mirror holds NaN or ±∞.
    #[error("KRS object {object}, mirror {mirror}: normal or offset is not finite")]
    NonFiniteMirror {
        /// Object index.
        object: usize,
        /// Mirror index.
        mirror: usize,
    },
    /// A kernel parameter is invalid.
    #[error("KRS object {object}, kernel {kernel}: {problem}")]
    Kernel {
        /// Object index.
        object: usize,
        /// Kernel index.
        kernel: usize,
        /// What is wrong.
        #[source]
        problem: KernelProblem,
    },
    /// The object's transform is invalid.
    #[error("KRS object {object}: transform {reason}")]
    Transform {
        /// Object index.
        object: usize,
        /// What is wrong.
        reason: String,
    },
    /// An operation that needs a bounded object (scattering it) got an unbounded one.
    #[error(
        "KRS object {object} is unbounded (a half-space kernel reaches infinity); only bounded \
         pieces can be scattered: use sphere, capsule, torus or box kernels"
    )]
    Unbounded {
        /// Object index.
        object: usize,
    },
    /// The distortion parameters are invalid.
    #[error("KRS object {object}: distortion {reason}")]
    Distortion {
        /// Object index.
        object: usize,
        /// What is wrong.
        reason: String,
    },
    /// An empty zone is invalid.
    #[error("KRS object {object}, empty zone {zone}: centre and radius must be finite, radius ≥ 0")]
    EmptyZone {
        /// Object index.
        object: usize,
        /// Zone index.
        zone: usize,
    },
}

/// Algorithm 1 with the bookkeeping needed for shading: which kernel is nearest and how the
/// point was folded to reach it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Distance estimate in object space (`f32::INFINITY` when every kernel is empty).
    pub distance: f32,
    /// Index of the nearest kernel, `None` when every kernel is empty.
    pub kernel: Option<usize>,
    /// The folded point in kernel space (object space of the nearest kernel's instance).
    pub kernel_point: Vec3,
    /// Linear map from kernel-space to object-space directions: M_{j1}·…·M_{jk} over the
    /// reflections taken (§6.1). Normals map with it too (it is orthogonal).
    pub object_from_kernel: Mat3,
    /// Smallest |m·p − c| met while folding down to the nearest kernel's level: how close the
    /// point is to a mirror plane where the normal may jump.
    pub mirror_clearance: f32,
    /// Distance gap between the nearest and the second nearest kernel value.
    pub kernel_gap: f32,
}

impl KrsObject {
    /// Number of reflection levels n.
    pub fn levels(&self) -> usize {
        self.mirrors.len()
    }

    /// Checks the object and returns a copy with every normal and direction normalised.
    /// `index` only labels the error.
    pub fn validated(&self, index: usize) -> Result<KrsObject, KrsError> {
        self.clone().into_validated(index)
    }

    /// [`KrsObject::validated`] without the copy: checks the object and normalises its normals
    /// and directions in place.
    pub fn into_validated(self, index: usize) -> Result<KrsObject, KrsError> {
        let object = index;
        self.check_kernel_count(object)?;
        let mut out = self;
        for (mirror, m) in out.mirrors.iter_mut().enumerate() {
            *m = normalised_mirror(object, mirror, m)?;
        }
        for (kernel, k) in out.kernels.iter_mut().enumerate() {
            *k = validated_kernel(object, kernel, k)?;
        }
        out.world_from_object = validated_similarity(object, out.world_from_object)?;
        out.check_distortion_and_zones(object, |z| z)?;
        Ok(out)
    }

    /// Whether this object, placed with `world_from_object` and its empty zones moved by
    /// `place_zone`, passes [`KrsObject::into_validated`]: the same checks in the same order
    /// and the same error, without copying the object's lists (a frame validates its document
    /// without allocating).
    ///
    /// # Errors
    /// As [`KrsObject::into_validated`] of the placed copy.
    pub fn check_placed(
        &self,
        index: usize,
        world_from_object: Similarity,
        place_zone: impl Fn(EmptyZone) -> EmptyZone,
    ) -> Result<(), KrsError> {
        let object = index;
        self.check_kernel_count(object)?;
        for (mirror, m) in self.mirrors.iter().enumerate() {
            normalised_mirror(object, mirror, m)?;
        }
        for (kernel, k) in self.kernels.iter().enumerate() {
            validated_kernel(object, kernel, k)?;
        }
        validated_similarity(object, world_from_object)?;
        self.check_distortion_and_zones(object, place_zone)
    }

    fn check_kernel_count(&self, object: usize) -> Result<(), KrsError> {
        if self.kernels.len() == self.mirrors.len() + 1 {
            Ok(())
        } else {
            Err(KrsError::KernelCount {
                object,
                kernels: self.kernels.len(),
                mirrors: self.mirrors.len(),
            })
        }
    }

    fn check_distortion_and_zones(
        &self,
        object: usize,
        place_zone: impl Fn(EmptyZone) -> EmptyZone,
    ) -> Result<(), KrsError> {
        if let Some(d) = &self.distortion {
            d.validate()
                .map_err(|reason| KrsError::Distortion { object, reason })?;
        }
        for (zone, z) in self.empty_zones.iter().enumerate() {
            let z = place_zone(*z);
            if !(z.centre.is_finite() && z.radius.is_finite() && z.radius >= 0.0) {
                return Err(KrsError::EmptyZone { object, zone });
            }
        }
        Ok(())
    }

    /// Algorithm 1: distance estimate from `p` (object space, undistorted) to the KRS.
    ///
    /// Exact where kernel separation holds; otherwise the distance to the geometry clipped at
    /// the mirror planes (still 1-Lipschitz, so safe for sphere tracing).
    #[inline]
    pub fn distance_object(&self, p: Vec3) -> f32 {
        let n = self.mirrors.len();
        // Fold in f64: mirrors of a forest sit thousands of units out, and f32 folding there
        // loses ~1e-4 per level (enough to break the Lipschitz bound). Kernels stay f32: the
        // folded point is back near them.
        let mut p = p.as_dvec3();
        let mut d = self
            .kernels
            .get(n)
            .map_or(f32::INFINITY, |k| k.distance(p.as_vec3()));
        for (m, k) in self.mirrors.iter().zip(&self.kernels).rev() {
            let normal = m.normal.as_dvec3();
            let e = normal.dot(p) - m.offset as f64;
            if e > 0.0 {
                p -= (2.0 * e) * normal;
            }
            if !k.is_empty() {
                d = d.min(k.distance(p.as_vec3()));
            }
        }
        d
    }

    /// Algorithm 1 with the nearest kernel, its kernel-space point and the reflection product.
    pub fn sample_object(&self, p: Vec3) -> Sample {
        let n = self.mirrors.len();
        let mut p64 = p.as_dvec3();
        let mut frame = Mat3::IDENTITY;
        let mut clearance = f32::INFINITY;
        let mut best = Sample {
            distance: f32::INFINITY,
            kernel: None,
            kernel_point: p,
            object_from_kernel: frame,
            mirror_clearance: f32::INFINITY,
            kernel_gap: f32::INFINITY,
        };
        let mut second = f32::INFINITY;
        let mut consider = |i: usize, p: Vec3, frame: Mat3, clearance: f32, best: &mut Sample| {
            let Some(k) = self.kernels.get(i) else { return };
            if k.is_empty() {
                return;
            }
            let d = k.distance(p);
            if d < best.distance {
                second = best.distance;
                *best = Sample {
                    distance: d,
                    kernel: Some(i),
                    kernel_point: p,
                    object_from_kernel: frame,
                    mirror_clearance: clearance,
                    kernel_gap: 0.0,
                };
            } else if d < second {
                second = d;
            }
        };
        consider(n, p, frame, clearance, &mut best);
        for i in (0..n).rev() {
            let m = &self.mirrors[i];
            let normal = m.normal.as_dvec3();
            let e = normal.dot(p64) - m.offset as f64;
            clearance = clearance.min(e.abs() as f32);
            if e > 0.0 {
                p64 -= (2.0 * e) * normal;
                frame *= m.matrix();
            }
            consider(i, p64.as_vec3(), frame, clearance, &mut best);
        }
        best.kernel_gap = second - best.distance;
        best
    }

    /// Reference distance: the minimum over every instance of every kernel (2^(n+1) − 1
    /// kernel evaluations), i.e. the union of all instances without clipping. Only for tests and
    /// benchmarks with small n.
    pub fn distance_brute_force(&self, p: Vec3) -> f32 {
        self.brute_level(self.mirrors.len(), p.as_dvec3())
    }

    fn brute_level(&self, level: usize, p: DVec3) -> f32 {
        let own = self
            .kernels
            .get(level)
            .map_or(f32::INFINITY, |k| k.distance(p.as_vec3()));
        if level == 0 {
            return own;
        }
        let m = &self.mirrors[level - 1];
        let normal = m.normal.as_dvec3();
        let reflected = p - 2.0 * (normal.dot(p) - m.offset as f64) * normal;
        own.min(self.brute_level(level - 1, p))
            .min(self.brute_level(level - 1, reflected))
    }

    /// Number of kernel instances, Σ over non-empty K_j of 2^(n−j), saturating at `u128::MAX`.
    pub fn instance_count(&self) -> u128 {
        let n = self.mirrors.len();
        let mut total: u128 = 0;
        for (j, k) in self.kernels.iter().enumerate() {
            if k.is_empty() || j > n {
                continue;
            }
            let count = 1u128.checked_shl((n - j) as u32).unwrap_or(u128::MAX);
            let count = if n - j >= 128 { u128::MAX } else { count };
            total = total.saturating_add(count);
        }
        total
    }

    /// A ball in object space that contains every kernel instance (so also the clipped
    /// geometry), or `None` when a kernel is unbounded or every kernel is empty.
    pub fn bounding_sphere_object(&self) -> Option<(Vec3, f32)> {
        let mut acc: Option<(Vec3, f32)> = None;
        for level in 0..self.kernels.len() {
            if level > 0
                && let (Some((c, r)), Some(m)) = (acc, self.mirrors.get(level - 1))
            {
                let c2 = m.reflect_point(c);
                acc = Some((0.5 * (c + c2), 0.5 * c.distance(c2) + r));
            }
            match self.kernels[level].bound() {
                KernelBound::Empty => {}
                KernelBound::Unbounded => return None,
                KernelBound::Sphere(c, r) => acc = Some(merge_spheres(acc, (c, r))),
            }
        }
        acc
    }
}

/// Smallest simple ball containing two balls.
pub(crate) fn merge_spheres(a: Option<(Vec3, f32)>, b: (Vec3, f32)) -> (Vec3, f32) {
    let Some(a) = a else { return b };
    let d = a.0.distance(b.0);
    if d + b.1 <= a.1 {
        return a;
    }
    if d + a.1 <= b.1 {
        return b;
    }
    let r = 0.5 * (d + a.1 + b.1);
    let dir = (b.0 - a.0) / d.max(f32::MIN_POSITIVE);
    let c = a.0 + dir * (r - a.1);
    // Guard against rounding making the merged ball slightly too small.
    (c, r * (1.0 + 4.0 * f32::EPSILON))
}

/// A validated object with its transform inverted and its bound precomputed, ready to trace.
#[derive(Debug, Clone)]
pub struct PreparedObject {
    /// The validated object (normals normalised).
    pub object: KrsObject,
    inverse_rotation: Quat,
    inverse_scale: f32,
    /// Lipschitz bound of the warp (1 without distortion).
    pub lipschitz: f32,
    /// World-space bounding ball, `None` when unbounded.
    pub bound_world: Option<(Vec3, f32)>,
    /// True when every kernel is empty (nothing to trace).
    pub is_empty: bool,
}

/// A validated scene ready for tracing and queries.
#[derive(Debug, Clone, Default)]
pub struct PreparedScene {
    /// The objects.
    pub objects: Vec<PreparedObject>,
}

impl KrsScene {
    /// Validates every object and precomputes transforms and bounds.
    pub fn prepare(&self) -> Result<PreparedScene, KrsError> {
        let objects = self
            .objects
            .iter()
            .enumerate()
            .map(|(i, o)| PreparedObject::new(o.validated(i)?))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(PreparedScene { objects })
    }
}

/// Mirror `mirror` of object `object` with its normal of unit length and its offset scaled to
/// keep the plane; an error for a non-finite or vanishing normal.
fn normalised_mirror(
    object: usize,
    mirror: usize,
    m: &MirrorPlane,
) -> Result<MirrorPlane, KrsError> {
    if !m.normal.is_finite() || !m.offset.is_finite() {
        return Err(KrsError::NonFiniteMirror { object, mirror });
    }
    let scale = m.normal.abs().max_element();
    if scale < MIN_DIRECTION_LENGTH {
        return Err(KrsError::ZeroMirrorNormal {
            object,
            mirror,
            normal: m.normal,
        });
    }
    // Normalise in two stages so huge and tiny normals both work, keeping the plane.
    let scaled = m.normal / scale;
    let len = scaled.length();
    // `Vec3::try_normalize`, reusing the length it would compute again.
    let rcp = len.recip();
    if !(rcp.is_finite() && rcp > 0.0) {
        return Err(KrsError::ZeroMirrorNormal {
            object,
            mirror,
            normal: m.normal,
        });
    }
    let normal = scaled * rcp;
    let offset = m.offset / scale / len;
    if !offset.is_finite() {
        return Err(KrsError::NonFiniteMirror { object, mirror });
    }
    Ok(MirrorPlane { normal, offset })
}

/// Kernel `kernel` of object `object`, validated.
fn validated_kernel(object: usize, kernel: usize, k: &Kernel) -> Result<Kernel, KrsError> {
    k.validated().map_err(|problem| KrsError::Kernel {
        object,
        kernel,
        problem,
    })
}

/// An object's transform with its rotation normalised; an error unless it is finite with a
/// positive scale and a rotation of non-zero length.
fn validated_similarity(object: usize, t: Similarity) -> Result<Similarity, KrsError> {
    if !t.translation.is_finite() || !t.rotation.is_finite() || !t.scale.is_finite() {
        return Err(KrsError::Transform {
            object,
            reason: "is not finite".to_owned(),
        });
    }
    if t.scale <= 0.0 {
        return Err(KrsError::Transform {
            object,
            reason: format!("scale {} must be > 0", t.scale),
        });
    }
    let rotation =
        super::kernel::normalized_quat(t.rotation).ok_or_else(|| KrsError::Transform {
            object,
            reason: "rotation quaternion has zero length".to_owned(),
        })?;
    Ok(Similarity { rotation, ..t })
}

impl PreparedObject {
    /// Prepares an already validated object.
    fn new(object: KrsObject) -> Result<Self, KrsError> {
        let t = object.world_from_object;
        let lipschitz = object.distortion.map_or(1.0, |d| d.lipschitz_bound());
        let is_empty = object.kernels.iter().all(Kernel::is_empty);
        let bound_world = object.bounding_sphere_object().map(|(c, r)| {
            let grow = object.distortion.map_or(0.0, |d| d.max_displacement());
            (t.transform_point(c), (r + grow) * t.scale)
        });
        Ok(Self {
            inverse_rotation: t.rotation.inverse(),
            inverse_scale: 1.0 / t.scale,
            lipschitz,
            bound_world,
            is_empty,
            object,
        })
    }

    /// World point → object space.
    #[inline]
    pub fn object_from_world(&self, p_world: Vec3) -> Vec3 {
        self.inverse_rotation
            * (p_world - self.object.world_from_object.translation)
            * self.inverse_scale
    }

    /// World direction → object space (unit stays unit).
    #[inline]
    pub fn object_dir_from_world(&self, v_world: Vec3) -> Vec3 {
        self.inverse_rotation * v_world
    }

    /// Object direction → world space.
    #[inline]
    pub fn world_dir_from_object(&self, v_object: Vec3) -> Vec3 {
        self.object.world_from_object.rotation * v_object
    }

    /// Conservative world-space distance estimate (scale, distortion bound and empty zones
    /// applied). `f32::INFINITY` when the object is empty.
    #[inline]
    pub fn distance_world(&self, p_world: Vec3) -> f32 {
        let p = self.object_from_world(p_world);
        let q = match &self.object.distortion {
            Some(d) => d.warp(p),
            None => p,
        };
        let mut d =
            self.object.distance_object(q) * self.object.world_from_object.scale / self.lipschitz;
        for z in &self.object.empty_zones {
            // CSG subtraction: max(d, −ball) stays a lower bound of the distance.
            d = d.max(z.radius - p_world.distance(z.centre));
        }
        d
    }

    /// Algorithm 1 sample at a world point, with the world-space normal of the nearest kernel
    /// instance (mapped back through the reflections taken, §6.1, and through the warp's
    /// Jacobian when distorted).
    pub fn sample_world(&self, p_world: Vec3) -> (Sample, Vec3) {
        let p = self.object_from_world(p_world);
        let (q, warp) = match &self.object.distortion {
            Some(d) => (d.warp(p), Some(d)),
            None => (p, None),
        };
        let mut s = self.object.sample_object(q);
        s.distance *= self.object.world_from_object.scale / self.lipschitz;
        let Some(kernel) = s.kernel else {
            return (s, Vec3::Y);
        };
        let n_kernel = self.object.kernels[kernel].normal(s.kernel_point);
        let mut n_object = s.object_from_kernel * n_kernel;
        if let Some(w) = warp {
            // ∇(d∘w) = Jᵀ ∇d with J estimated by central differences of the smooth warp.
            let h = 1e-3 / w.frequency.max(1e-3);
            let jt_row = |axis: Vec3| (w.warp(p + axis * h) - w.warp(p - axis * h)) / (2.0 * h);
            let (jx, jy, jz) = (jt_row(Vec3::X), jt_row(Vec3::Y), jt_row(Vec3::Z));
            n_object = Vec3::new(jx.dot(n_object), jy.dot(n_object), jz.dot(n_object));
        }
        let mut n_world = self.world_dir_from_object(n_object).normalize_or(Vec3::Y);
        for z in &self.object.empty_zones {
            let carve = z.radius - p_world.distance(z.centre);
            if carve > s.distance {
                s.distance = carve;
                n_world = (z.centre - p_world).normalize_or(Vec3::Y);
            }
        }
        (s, n_world)
    }

    /// The material of a kernel (default for out-of-range or empty).
    pub fn material(&self, kernel: Option<usize>) -> Material {
        kernel
            .and_then(|k| self.object.kernels.get(k))
            .and_then(Kernel::material)
            .copied()
            .unwrap_or_default()
    }
}

impl PreparedScene {
    /// Conservative world-space distance to the union of all objects.
    #[inline]
    pub fn distance(&self, p_world: Vec3) -> f32 {
        let mut best = f32::INFINITY;
        for o in &self.objects {
            if let Some((c, r)) = o.bound_world {
                // The estimate is never below (ball distance)/Lipschitz, so an object whose
                // bound is already past the best cannot change the minimum: culling is exact.
                if (p_world.distance(c) - r) / o.lipschitz >= best {
                    continue;
                }
            }
            best = best.min(o.distance_world(p_world));
        }
        best
    }

    /// Index of the object nearest to `p_world` and its distance estimate.
    pub fn nearest_object(&self, p_world: Vec3) -> Option<(usize, f32)> {
        let mut best: Option<(usize, f32)> = None;
        for (i, o) in self.objects.iter().enumerate() {
            if let (Some((c, r)), Some((_, b))) = (o.bound_world, best)
                && (p_world.distance(c) - r) / o.lipschitz >= b
            {
                continue;
            }
            let d = o.distance_world(p_world);
            if d.is_finite() && best.is_none_or(|(_, b)| d < b) {
                best = Some((i, d));
            }
        }
        best
    }
}

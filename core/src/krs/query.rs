//! Queries for the rest of Thicket: distance + normal (collision, picking), bounding balls,
//! kernel-instance enumeration (export, rigid-body substitution in empty zones, §6.4).

use glam::{Affine3A, Mat3A, Vec3, Vec3A};
use rayon::prelude::*;

use super::kernel::{Kernel, KernelBound};
use super::object::{EmptyZone, KrsObject, PreparedObject, PreparedScene};

/// Distance and surface normal at a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceQuery {
    /// Conservative world-space distance (negative inside).
    pub distance: f32,
    /// World-space unit normal of the nearest kernel instance.
    pub normal: Vec3,
    /// Nearest object.
    pub object: usize,
    /// Nearest kernel in that object.
    pub kernel: Option<usize>,
}

/// One instance of one kernel: `kernel` placed by `world_from_kernel`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KernelInstance {
    /// Kernel index within the object.
    pub kernel: usize,
    /// World-from-kernel transform: the object's placement composed with the reflections of this
    /// instance. Kernel parameters are in object space, so this maps them to the world.
    pub world_from_kernel: Affine3A,
    /// Whether the instance is mirrored (determinant < 0: flip triangle winding on export).
    pub mirrored: bool,
}

impl PreparedScene {
    /// Distance and normal at `p_world` (for collision and picking). `None` for an empty scene.
    pub fn query(&self, p_world: Vec3) -> Option<SurfaceQuery> {
        let (object, _) = self.nearest_object(p_world)?;
        let (s, normal) = self.objects[object].sample_world(p_world);
        Some(SurfaceQuery {
            distance: s.distance,
            normal,
            object,
            kernel: s.kernel,
        })
    }
}

impl PreparedObject {
    /// Every instance of every non-empty kernel, at most `limit` of them (depth-first from the
    /// top level). Instances of a KRS number Σ 2^(n−j); use [`KrsObject::instance_count`] first.
    pub fn instances(&self, limit: usize) -> Vec<KernelInstance> {
        let t = self.object.world_from_object;
        let world_from_object = Affine3A::from_scale_rotation_translation(
            Vec3::splat(t.scale),
            t.rotation,
            t.translation,
        );
        let mut out = Vec::new();
        enumerate(
            &self.object,
            self.object.mirrors.len(),
            world_from_object,
            false,
            limit,
            &mut out,
            &|_, _| true,
        );
        out
    }

    /// Instances whose kernel bound touches `zone` (world space), at most `limit`: the pieces to
    /// rebuild as rigid bodies when the zone is carved out (§6.4). Subtrees whose bounding ball
    /// misses the zone are skipped, so the cost follows the zone, not the 2^n total.
    pub fn instances_in_zone(&self, zone: &EmptyZone, limit: usize) -> Vec<KernelInstance> {
        let t = self.object.world_from_object;
        let world_from_object = Affine3A::from_scale_rotation_translation(
            Vec3::splat(t.scale),
            t.rotation,
            t.translation,
        );
        let levels = level_bounds(&self.object);
        let mut out = Vec::new();
        let touches = |level: usize, xf: &Affine3A| match levels[level] {
            None => true,
            Some((c, r)) => {
                let c_world = xf.transform_point3(c);
                c_world.distance(zone.centre) <= r * t.scale + zone.radius
            }
        };
        enumerate(
            &self.object,
            self.object.mirrors.len(),
            world_from_object,
            false,
            limit,
            &mut out,
            &touches,
        );
        out
    }
}

/// Object-space bounding ball of each expansion level L_i (`None` when unbounded or empty).
fn level_bounds(obj: &KrsObject) -> Vec<Option<(Vec3, f32)>> {
    (0..obj.kernels.len())
        .map(|level| {
            let sub = KrsObject {
                kernels: obj.kernels[..=level].to_vec(),
                mirrors: obj.mirrors[..level].to_vec(),
                ..KrsObject::default()
            };
            sub.bounding_sphere_object()
        })
        .collect()
}

fn reflection_affine(m: &super::mirror::MirrorPlane) -> Affine3A {
    let mat = Mat3A::from(m.matrix());
    Affine3A {
        matrix3: mat,
        translation: Vec3A::from(2.0 * m.offset * m.normal),
    }
}

/// L_level = K_level ∪ L_(level−1) ∪ R_(level−1) L_(level−1), placed by `xf`.
fn enumerate(
    obj: &KrsObject,
    level: usize,
    xf: Affine3A,
    mirrored: bool,
    limit: usize,
    out: &mut Vec<KernelInstance>,
    keep: &dyn Fn(usize, &Affine3A) -> bool,
) {
    if out.len() >= limit || !keep(level, &xf) {
        return;
    }
    if let Some(k) = obj.kernels.get(level) {
        let visible = match k.bound() {
            KernelBound::Empty => false,
            _ => !matches!(k, Kernel::Empty),
        };
        if visible {
            out.push(KernelInstance {
                kernel: level,
                world_from_kernel: xf,
                mirrored,
            });
        }
    }
    if level == 0 {
        return;
    }
    let m = &obj.mirrors[level - 1];
    enumerate(obj, level - 1, xf, mirrored, limit, out, keep);
    enumerate(
        obj,
        level - 1,
        xf * reflection_affine(m),
        !mirrored,
        limit,
        out,
        keep,
    );
}

/// Most prototype kernel-instance balls [`PreparedObject::auto_placement_level`] tests against
/// the placement mirrors: past this the prototype is a large part of the object anyway, and the
/// test stops instancing there.
const MAX_SEPARATION_BALLS: usize = 1 << 16;

impl KrsObject {
    /// The lowest level `K` whose kernels above it (`K+1..=n`) are all empty: mirrors `K..n`
    /// only copy the geometry of levels `0..=K` (the forest's extra reflections). `n` (every
    /// mirror carries a kernel above it) when there is no such mirror.
    #[must_use]
    pub fn lowest_placement_level(&self) -> usize {
        let n = self.mirrors.len();
        (0..=n)
            .rev()
            .find(|&level| !self.kernels.get(level).is_none_or(Kernel::is_empty))
            .unwrap_or(0)
            .min(n)
    }

    /// Levels `0..=level` as an object of their own (kernels `0..=level`, mirrors `0..level`),
    /// in this object's object space (identity placement), with the same texturing and no
    /// distortion or empty zones: one copy of what the mirrors above `level` repeat.
    #[must_use]
    pub fn prototype(&self, level: usize) -> KrsObject {
        let level = level.min(self.mirrors.len());
        KrsObject {
            name: self.name.clone(),
            kernels: self.kernels[..=level].to_vec(),
            mirrors: self.mirrors[..level].to_vec(),
            texturing: self.texturing,
            ..KrsObject::default()
        }
    }

    /// Number of copies of [`KrsObject::prototype`]`(level)` the mirrors above `level` make:
    /// 2^(n − level), saturating.
    #[must_use]
    pub fn placement_count(&self, level: usize) -> u128 {
        let m = self.mirrors.len().saturating_sub(level);
        if m >= 128 { u128::MAX } else { 1u128 << m }
    }
}

impl PreparedObject {
    /// `world_from_prototype` of every copy of [`KrsObject::prototype`]`(level)`: the object's
    /// placement times each composition R_(n−1)^s · … · R_level^s of the mirrors above
    /// `level` (2^(n − level) of them, at most `limit`; check
    /// [`KrsObject::placement_count`] first). Half of them mirror (negative determinant).
    #[must_use]
    pub fn placements(&self, level: usize, limit: usize) -> Vec<Affine3A> {
        let t = self.object.world_from_object;
        let world_from_object = Affine3A::from_scale_rotation_translation(
            Vec3::splat(t.scale),
            t.rotation,
            t.translation,
        );
        let n = self.object.mirrors.len();
        let level = level.min(n);
        let mut out = vec![world_from_object];
        // Top mirror first: each mirror doubles the list, applied on the right (nearest the
        // prototype), as Algorithm 1 folds the top mirror first.
        for m in self.object.mirrors[level..n].iter().rev() {
            if out.len() >= limit {
                break;
            }
            let r = reflection_affine(m);
            let reflected: Vec<Affine3A> = out.iter().map(|xf| *xf * r).collect();
            out.extend(reflected);
        }
        out.truncate(limit);
        out
    }

    /// The deepest level at which instancing [`KrsObject::prototype`] by
    /// [`PreparedObject::placements`] draws what Algorithm 1 draws: at or above
    /// [`KrsObject::lowest_placement_level`], and each placement mirror keeps everything below
    /// it on its kept (negative) side, tested with the kernel instances' bounding balls (so
    /// Algorithm 1's clipping at that mirror removes nothing). `n` (no instancing) for objects
    /// with a distortion or empty zones (they act in object or world space, not per copy) and
    /// for prototypes with an unbounded kernel.
    #[must_use]
    pub fn auto_placement_level(&self) -> usize {
        let o = &self.object;
        let n = o.mirrors.len();
        if o.distortion.is_some() || !o.empty_zones.is_empty() {
            return n;
        }
        let mut level = o.lowest_placement_level();
        'levels: while level < n {
            // Balls of the prototype's kernel instances, in object space.
            let proto = o.prototype(level);
            if proto.instance_count() > MAX_SEPARATION_BALLS as u128 {
                return n;
            }
            let mut balls = Vec::new();
            let mut xfs = vec![Affine3A::IDENTITY];
            for inst in identity_instances(&proto, MAX_SEPARATION_BALLS) {
                match o.kernels[inst.kernel].bound() {
                    KernelBound::Sphere(c, r) => {
                        balls.push((inst.world_from_kernel.transform_point3(c), r));
                    }
                    KernelBound::Empty => {}
                    KernelBound::Unbounded => return n,
                }
            }
            // Copies below mirror i: the compositions of mirrors level..i, applied as
            // `placements` applies them (mirror i outermost).
            for (i, m) in o.mirrors.iter().enumerate().skip(level) {
                let tolerance = 1e-5 * (1.0 + m.offset.abs());
                let crosses = xfs.par_iter().any(|xf| {
                    balls
                        .iter()
                        .any(|&(c, r)| m.signed_distance(xf.transform_point3(c)) + r > tolerance)
                });
                if crosses {
                    // Mirror i clips what lies below it: it belongs to the prototype.
                    level = i + 1;
                    continue 'levels;
                }
                let r = reflection_affine(m);
                let reflected: Vec<Affine3A> = xfs.iter().map(|xf| r * *xf).collect();
                xfs.extend(reflected);
            }
            return level;
        }
        n
    }
}

/// Kernel instances of `obj` in its own object space.
fn identity_instances(obj: &KrsObject, limit: usize) -> Vec<KernelInstance> {
    let mut out = Vec::new();
    enumerate(
        obj,
        obj.mirrors.len(),
        Affine3A::IDENTITY,
        false,
        limit,
        &mut out,
        &|_, _| true,
    );
    out
}

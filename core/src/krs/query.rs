//! Queries for the rest of Thicket: distance + normal (collision, picking), bounding balls,
//! kernel-instance enumeration (export, rigid-body substitution in empty zones, §6.4).

use glam::{Affine3A, Mat3A, Vec3, Vec3A};

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

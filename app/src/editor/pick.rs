//! Picking what a ray meets — voxel models (octree ray cast), meshes (ray–triangle in f64) and
//! KRS objects (sphere tracing core's distance estimate, which already divides by the warp's
//! Lipschitz bound) — and dropping an object straight down onto whatever is below it with the
//! same queries.

use glam::{DVec3, IVec3, Mat4, Vec3};
use thicket_core::krs::{PreparedScene, TraceSettings, trace};
use thicket_core::mesh::MeshModel;
use thicket_core::scene::{Object, ObjectKind};

use super::{CommandError, Editor, VoxelPick};

/// What kind of object a pick hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PickKind {
    /// A voxel model.
    Voxels,
    /// A triangle mesh.
    Mesh,
    /// A KRS object.
    Krs,
}

/// The nearest surface a ray met.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePick {
    /// The object hit.
    pub object: u64,
    /// Its kind.
    pub kind: PickKind,
    /// Where, in world space.
    pub point_in_world: Vec3,
    /// World-space unit normal of the surface there (a mesh's facing the ray's origin; a KRS
    /// object's outward).
    pub normal_in_world: Vec3,
    /// Ray parameter of the hit (world units: the direction is normalised first).
    pub t: f32,
}

/// Which objects a cast considers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Among {
    /// Every visible object.
    Visible,
    /// Only this object, visible or not.
    Only(u64),
    /// Every visible object but this one.
    AllBut(u64),
}

impl Among {
    fn admits(self, o: &Object) -> bool {
        match self {
            Self::Visible => o.visible,
            Self::Only(id) => o.id == id,
            Self::AllBut(id) => o.visible && o.id != id,
        }
    }
}

/// Sphere-tracing settings for picks: stop within a ten-thousandth of the distance travelled
/// (a tenth of a pixel in the editor's view) and give up after 2048 evaluations (a ray that
/// grazes a surface for longer is reported as a miss).
const PICK_TRACE: TraceSettings = TraceSettings {
    eps_scale: 1.0,
    pixel_cone_ratio: 1e-4,
    min_epsilon: 1e-5,
    max_steps: 2048,
    max_distance: f32::INFINITY,
    over_relaxation: 1.0,
    start_distance: 0.0,
};

/// A mesh object ready for rays: its transforms and object-space bounds.
struct MeshTarget<'a> {
    id: u64,
    model: &'a MeshModel,
    object_from_world: Mat4,
    bounds: (Vec3, Vec3),
}

/// The meshes and KRS objects of one query, prepared once for many rays (voxel models need no
/// preparation: their octrees answer rays directly).
struct PickTargets<'a> {
    among: Among,
    meshes: Vec<MeshTarget<'a>>,
    krs: PreparedScene,
    krs_ids: Vec<u64>,
}

impl Editor {
    /// Casts a world-space ray against every visible voxel model, mesh and KRS object and
    /// returns the nearest hit. A ray that starts inside a KRS object hits it at `t = 0`.
    #[must_use]
    pub fn pick(&self, origin_in_world: Vec3, dir_in_world: Vec3) -> Option<SurfacePick> {
        self.pick_targets(Among::Visible)
            .cast(self, origin_in_world, dir_in_world)
    }

    fn pick_targets(&self, among: Among) -> PickTargets<'_> {
        let mut targets = PickTargets {
            among,
            meshes: Vec::new(),
            krs: PreparedScene::default(),
            krs_ids: Vec::new(),
        };
        for o in self.doc.objects.iter().filter(|o| among.admits(o)) {
            match &o.kind {
                ObjectKind::Voxels(_) => {}
                ObjectKind::Mesh(m) => {
                    let object_from_world = o.transform.matrix().inverse();
                    if let Some(bounds) = m.model.bounds()
                        && object_from_world.is_finite()
                    {
                        targets.meshes.push(MeshTarget {
                            id: o.id,
                            model: &m.model,
                            object_from_world,
                            bounds,
                        });
                    }
                }
                ObjectKind::Krs(_) => {
                    // One object at a time: an invalid one (refused by validation, so not in a
                    // saved document) must not hide the others.
                    let prepared = o.krs_in_world().and_then(|k| {
                        thicket_core::krs::KrsScene { objects: vec![k] }
                            .prepare()
                            .ok()
                    });
                    if let Some(p) = prepared {
                        targets.krs.objects.extend(p.objects);
                        targets.krs_ids.push(o.id);
                    }
                }
            }
        }
        targets
    }
}

impl PickTargets<'_> {
    fn cast(&self, editor: &Editor, origin: Vec3, dir: Vec3) -> Option<SurfacePick> {
        let dir = dir.try_normalize()?;
        if !origin.is_finite() {
            return None;
        }
        let mut best: Option<SurfacePick> = None;
        let mut consider = |p: SurfacePick| {
            if best.is_none_or(|b| p.t < b.t) {
                best = Some(p);
            }
        };
        let among = self.among;
        if let Some(v) = editor.pick_voxel_where(origin, dir, |o| match among {
            Among::Visible => editor.voxel_pickable(o),
            Among::Only(id) => o.id == id,
            Among::AllBut(id) => o.id != id && editor.voxel_pickable(o),
        }) {
            consider(SurfacePick {
                object: v.object,
                kind: PickKind::Voxels,
                point_in_world: v.point_in_world,
                normal_in_world: world_normal(v.voxel_from_world, v.normal.as_vec3(), dir),
                t: v.t,
            });
        }
        for m in &self.meshes {
            if let Some((t, n_object)) = ray_mesh(m, origin, dir) {
                consider(SurfacePick {
                    object: m.id,
                    kind: PickKind::Mesh,
                    point_in_world: origin + dir * t,
                    normal_in_world: world_normal(m.object_from_world, n_object, dir),
                    t,
                });
            }
        }
        if let Some(k) = ray_krs(&self.krs, origin, dir) {
            consider(SurfacePick {
                object: self.krs_ids[k.object],
                kind: PickKind::Krs,
                point_in_world: k.position,
                normal_in_world: k.normal,
                t: k.t,
            });
        }
        best
    }
}

/// A surface normal given in an object's space (`space_from_world` maps world points into it)
/// as a world-space unit normal (by the inverse transpose), turned to face the ray's origin.
fn world_normal(space_from_world: Mat4, n: Vec3, dir: Vec3) -> Vec3 {
    let n_world = space_from_world
        .transpose()
        .transform_vector3(n)
        .normalize_or(-dir);
    if n_world.dot(dir) > 0.0 {
        -n_world
    } else {
        n_world
    }
}

/// The nearest triangle of a mesh a unit world ray meets: its ray parameter (world units) and
/// the triangle's object-space geometric normal. Both faces count (meshes need not be closed).
fn ray_mesh(m: &MeshTarget<'_>, origin: Vec3, dir: Vec3) -> Option<(f32, Vec3)> {
    // The same parameter t in both spaces: the direction is transformed, not normalised.
    let o = m
        .object_from_world
        .as_dmat4()
        .transform_point3(origin.as_dvec3());
    let d = m
        .object_from_world
        .as_dmat4()
        .transform_vector3(dir.as_dvec3());
    let (lo, hi) = m.bounds;
    // The box only rejects rays early; a flat mesh's box is flat, so it is not clipped to.
    ray_box(o, d, lo.as_dvec3(), hi.as_dvec3())?;
    let mut best: Option<(f64, Vec3)> = None;
    for part in &m.model.parts {
        for tri in part.indices.chunks_exact(3) {
            let corner = |k: usize| part.positions.get(tri[k] as usize).map(|p| p.as_dvec3());
            let (Some(a), Some(b), Some(c)) = (corner(0), corner(1), corner(2)) else {
                continue;
            };
            let limit = best.map_or(f64::INFINITY, |(t, _)| t);
            if let Some(t) = ray_triangle(o, d, [a, b, c], 0.0, limit) {
                best = Some((t, (b - a).cross(c - a).as_vec3()));
            }
        }
    }
    best.map(|(t, n)| (t as f32, n))
}

/// Whether a ray meets the closed box `lo..hi` ahead of its origin (slab test).
fn ray_box(o: DVec3, d: DVec3, lo: DVec3, hi: DVec3) -> Option<()> {
    let inv = d.recip();
    let (a, b) = ((lo - o) * inv, (hi - o) * inv);
    // A zero direction component gives ±∞ (or NaN when the origin is on the slab's face:
    // `max`/`min` ignore NaN, which keeps such rays, as a conservative test should).
    let t_near = a.min(b).max_element();
    let t_far = a.max(b).min_element();
    (t_far >= t_near.max(0.0)).then_some(())
}

/// Möller–Trumbore in f64: the parameter in `[t_min, t_max)` where the ray meets the
/// triangle, `None` when it misses or runs parallel to the triangle's plane (a grazing ray
/// sees no area).
fn ray_triangle(o: DVec3, d: DVec3, [a, b, c]: [DVec3; 3], t_min: f64, t_max: f64) -> Option<f64> {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    // Relative to the edge and direction lengths, so the test does not depend on units.
    if det.abs() <= 1e-12 * e1.length() * e2.length() * d.length() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t >= t_min && t < t_max).then_some(t)
}

/// Sphere-traces a unit ray through the KRS objects with core's tracer.
fn ray_krs(scene: &PreparedScene, origin: Vec3, dir: Vec3) -> Option<thicket_core::krs::TraceHit> {
    if scene.objects.is_empty() {
        return None;
    }
    let hit = trace(scene, origin, dir, &PICK_TRACE);
    hit.hit.then_some(hit)
}

impl Editor {
    /// Where a sculpt brush aims along a world-space ray: the nearest voxel
    /// ([`Editor::pick_voxel`]), unless a visible KRS object is nearer (it hides the voxels
    /// behind it). Then the brush targets voxel model `onto` at the KRS surface point: the pick
    /// is `onto`'s voxel just inside the surface there, facing along the surface's normal (its
    /// dominant axis in the model's voxel grid), so an Add dab places a voxel of `onto` on the
    /// KRS surface. `None` when a KRS object is nearer and there is no `onto`, or the surface
    /// point lies outside `onto`'s voxel grid (nothing can be placed there).
    #[must_use]
    pub fn pick_brush(
        &self,
        origin_in_world: Vec3,
        dir_in_world: Vec3,
        onto: Option<u64>,
    ) -> Option<VoxelPick> {
        let voxel = self.pick_voxel(origin_in_world, dir_in_world);
        let dir = dir_in_world.try_normalize()?;
        if !origin_in_world.is_finite() {
            return voxel;
        }
        let mut targets = self.pick_targets(Among::Visible);
        // Only the KRS objects matter here: meshes are not brush targets.
        targets.meshes.clear();
        let Some(k) = ray_krs(&targets.krs, origin_in_world, dir) else {
            return voxel;
        };
        if voxel.is_some_and(|v| v.t <= k.t) {
            return voxel;
        }
        self.voxel_pick_at(onto?, k.position, k.normal, k.t)
    }

    /// A [`VoxelPick`] on voxel model `id` for a surface point and outward normal given in
    /// world space (see [`Editor::pick_brush`]).
    fn voxel_pick_at(&self, id: u64, point: Vec3, normal: Vec3, t: f32) -> Option<VoxelPick> {
        let o = self.object(id).filter(|o| self.voxel_pickable(o))?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return None;
        };
        let (world_from_voxel, voxel_from_world, size) = super::sculpt::voxel_frame(o, v)?;
        let p = voxel_from_world.transform_point3(point);
        // Normals map by the inverse transpose of voxel_from_world.
        let n = world_from_voxel.transpose().transform_vector3(normal);
        let axis = n.abs().max_position();
        let mut face = IVec3::ZERO;
        face[axis] = if n[axis] < 0.0 { -1 } else { 1 };
        let inside = (p - 0.5 * face.as_vec3()).floor();
        let extent = v.svo.extent() as f32;
        if !(inside.cmpge(Vec3::ZERO).all() && inside.cmplt(Vec3::splat(extent)).all()) {
            return None;
        }
        Some(VoxelPick {
            object: id,
            voxel: inside.as_uvec3(),
            normal: face,
            point_in_world: point,
            t,
            voxel_from_world,
            voxel_size_world: size,
        })
    }
}

/// How far [`Editor::drop_to_surface`] moved an object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Landing {
    /// World units moved down (0 when it already rests on something).
    pub distance: f32,
    /// The object it now rests on.
    pub onto: u64,
}

/// Columns per axis over an object's footprint that [`Editor::drop_to_surface`] probes: one per
/// voxel for voxel models, between these bounds.
const DROP_COLUMNS: (usize, usize) = (32, 64);

impl Editor {
    /// Moves object `id` straight down (−Y) until its lowest point rests on whatever visible
    /// object is below it (voxels, meshes or KRS, such as terrain); one undo step.
    ///
    /// Probes a grid of vertical lines over the object's footprint (one per voxel column for a
    /// voxel model, 32 to 64 per axis; 32 for meshes and KRS): on each, a ray up
    /// from under the object finds its lowest point, and a ray down from there the surface
    /// below; the object moves by the smallest gap. A line that starts inside another object
    /// (the object already sinks into it) counts as resting there: nothing moves.
    ///
    /// # Errors
    /// Unknown id, an object with no bounds (an unbounded KRS such as terrain), or nothing
    /// below it (the document is left unchanged).
    pub fn drop_to_surface(&mut self, id: u64) -> Result<Landing, CommandError> {
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let name = o.name.clone();
        let (lo, hi) = o.world_bounds().ok_or_else(|| {
            CommandError::Invalid(format!(
                "{name:?} has no bounds (empty, or unbounded like terrain): nothing to drop"
            ))
        })?;
        let columns = |extent: f32| {
            let per_voxel = match &o.kind {
                ObjectKind::Voxels(v) => {
                    let size = v.voxel_size * o.transform.scale.abs().min_element();
                    (extent / size).ceil()
                }
                ObjectKind::Mesh(_) | ObjectKind::Krs(_) => 0.0,
            };
            // `as` saturates a NaN or huge count; the clamp bounds it.
            (per_voxel as usize).clamp(DROP_COLUMNS.0, DROP_COLUMNS.1)
        };
        let (nx, nz) = (columns(hi.x - lo.x), columns(hi.z - lo.z));
        let itself = self.pick_targets(Among::Only(id));
        let others = self.pick_targets(Among::AllBut(id));
        let below = lo.y - (hi.y - lo.y) - 1.0;
        let mut best: Option<(f32, u64)> = None;
        let mut footprint_hit = false;
        for i in 0..nx {
            for k in 0..nz {
                let f = |j: usize, n: usize| (j as f32 + 0.5) / n as f32;
                let x = lo.x + (hi.x - lo.x) * f(i, nx);
                let z = lo.z + (hi.z - lo.z) * f(k, nz);
                let Some(bottom) = itself.cast(self, Vec3::new(x, below, z), Vec3::Y) else {
                    continue;
                };
                footprint_hit = true;
                let Some(ground) = others.cast(self, bottom.point_in_world, Vec3::NEG_Y) else {
                    continue;
                };
                if best.is_none_or(|(t, _)| ground.t < t) {
                    best = Some((ground.t, ground.object));
                }
            }
        }
        let Some((gap, onto)) = best else {
            return Err(CommandError::Invalid(if footprint_hit {
                format!("nothing below {name:?} to drop it onto")
            } else {
                format!("{name:?} has no surface to rest on anything")
            }));
        };
        let mut transform = o.transform;
        transform.translation.y -= gap;
        // Its own undo step, not merged with a transform drag before or after it.
        self.history.seal();
        self.set_transform(id, transform)?;
        self.history.seal();
        Ok(Landing {
            distance: gap,
            onto,
        })
    }
}

#[cfg(test)]
mod tests;

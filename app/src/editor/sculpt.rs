//! Picking voxels with the octree ray cast and sculpting them with brushes: one undo step per
//! stroke, holding only the voxels the stroke touched.

use glam::{IVec3, Mat4, UVec3, Vec3};
use thicket_core::scene::ObjectKind;
use thicket_core::sculpt::{Brush, BrushOp, apply_dab};

use super::{Change, CommandError, Edit, Editor, MergeKey};

/// What a ray hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelPick {
    /// The voxel object.
    pub object: u64,
    /// The solid voxel hit.
    pub voxel: UVec3,
    /// Outward normal of the face the ray entered through (unit axis).
    pub normal: IVec3,
    /// The hit point in world space.
    pub point_in_world: Vec3,
    /// Ray parameter of the hit (world units when the ray direction has length 1).
    pub t: f32,
    /// `voxel_from_world` of the object (for placing the brush).
    pub voxel_from_world: Mat4,
    /// World size of one voxel along its largest axis (for drawing the brush).
    pub voxel_size_world: f32,
}

impl VoxelPick {
    /// Where a dab of `op` goes, in voxel coordinates: for Add the empty neighbour in front of
    /// the face hit (so the surface grows toward the viewer), otherwise the voxel hit.
    #[must_use]
    pub fn dab_center(&self, op: BrushOp) -> Vec3 {
        let base = self.voxel.as_vec3() + 0.5;
        if op == BrushOp::Add {
            base + self.normal.as_vec3()
        } else {
            base
        }
    }
}

/// The nearest voxel of rigged model `v` (object `o`) hit by a world ray (unit `dir`) in the
/// pose its rig shows, nearer than `max_t`: `(t, voxel, outward face normal in voxel axes)`.
/// A pose moves the voxels away from their grid (the bind pose), where an octree ray cast would
/// look. Each voxel is the box the renderers draw for it (its cube carried by its blended
/// matrix, stretched as the document's quality says); the descent tests a node's subtree
/// bounds and visits only nodes the ray enters before the best hit so far.
fn posed_raycast(
    o: &thicket_core::scene::Object,
    v: &thicket_core::scene::VoxelModel,
    rig: &thicket_core::skin::Rig,
    quality: &thicket_core::quality::Quality,
    origin: Vec3,
    dir: Vec3,
    max_t: f32,
) -> Option<(f32, UVec3, IVec3)> {
    use thicket_core::deform::{DeformedNode, NodeDeform, NodeInfo};
    let svo = &v.svo;
    if svo.is_empty() {
        return None;
    }
    let deform = thicket_core::render::skin_deform(o, v, rig, quality);
    // Where the ray enters the box `d` (`None`: misses, or not before `max_t`), and the box
    // axis it enters through with the sign facing the ray.
    let enter = |d: &DeformedNode, max_t: f32| -> Option<(f32, IVec3)> {
        let inv = d.half_axes_world.inverse();
        let (o_l, d_l) = (inv * (origin - d.center_world), inv * dir);
        if !(o_l.is_finite() && d_l.is_finite()) {
            return None;
        }
        let (mut t0, mut t1, mut face) = (0.0f32, max_t, IVec3::ZERO);
        for k in 0..3 {
            if d_l[k] == 0.0 {
                if o_l[k].abs() > 1.0 {
                    return None;
                }
                continue;
            }
            let (a, b) = ((-1.0 - o_l[k]) / d_l[k], (1.0 - o_l[k]) / d_l[k]);
            let (near, far) = (a.min(b), a.max(b));
            if near > t0 {
                t0 = near;
                face = IVec3::ZERO;
                face[k] = if d_l[k] > 0.0 { -1 } else { 1 };
            }
            t1 = t1.min(far);
        }
        (t0 <= t1).then_some((t0, face))
    };
    let aabb = |d: &DeformedNode| {
        let a = d.half_axes_world;
        let he = glam::Mat3::from_cols(a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs()) * Vec3::ONE;
        (d.center_world - he, d.center_world + he)
    };
    let mut best: Option<(f32, UVec3, IVec3)> = None;
    let mut stack = vec![svo.root()];
    while let Some(n) = stack.pop() {
        let info = NodeInfo { svo, node: n };
        let limit = best.map_or(max_t, |b| b.0);
        let own = deform.deform(&info);
        if svo.is_leaf(&n) {
            if let Some((t, face)) = enter(&own, limit)
                && face != IVec3::ZERO
            {
                best = Some((t, n.origin, face));
            }
            continue;
        }
        // The node's own box joined with its subtree's, as an axis-aligned box.
        let (mut lo, mut hi) = aabb(&own);
        if let Some(sub) = deform.subtree_bounds(&info) {
            let (a, b) = aabb(&sub);
            lo = lo.min(a);
            hi = hi.max(b);
        }
        let cull = DeformedNode {
            center_world: (lo + hi) * 0.5,
            half_axes_world: glam::Mat3::from_diagonal(((hi - lo) * 0.5).max(Vec3::splat(1e-6))),
        };
        if enter(&cull, limit).is_some() {
            stack.extend((0..8).filter_map(|k| svo.child(&n, k)));
        }
    }
    best
}

/// Voxel model `v` of object `o` in the world: `world_from_voxel`, its inverse (`None` when
/// it has none) and the world size of a voxel (its largest side).
pub(super) fn voxel_frame(
    o: &thicket_core::scene::Object,
    v: &thicket_core::scene::VoxelModel,
) -> Option<(Mat4, Mat4, f32)> {
    let world_from_voxel = o.transform.matrix() * v.object_from_voxel();
    let voxel_from_world = world_from_voxel.inverse();
    if !voxel_from_world.is_finite() {
        return None;
    }
    let size = world_from_voxel
        .transform_vector3(Vec3::ONE)
        .abs()
        .max_element()
        .max(1e-9);
    Some((world_from_voxel, voxel_from_world, size))
}

impl Editor {
    /// Casts a world-space ray (unit direction) against every visible voxel object and returns
    /// the nearest solid voxel.
    #[must_use]
    pub fn pick_voxel(&self, origin_in_world: Vec3, dir_in_world: Vec3) -> Option<VoxelPick> {
        self.pick_voxel_where(origin_in_world, dir_in_world, |o| self.voxel_pickable(o))
    }

    /// Whether clicks and strokes reach voxel object `o`: visible, or the coarse model of a
    /// visible enhancement (an enhancement is derived from its coarse model: strokes go to the
    /// coarse model, hidden so the fine one shows, and the fine one follows).
    pub(crate) fn voxel_pickable(&self, o: &thicket_core::scene::Object) -> bool {
        if self.doc.enhancement_into(o.id).is_some() {
            return false;
        }
        o.visible
            || self
                .doc
                .enhancement_of(o.id)
                .and_then(|l| self.object(l.target))
                .is_some_and(|t| t.visible)
    }

    /// [`Editor::pick_voxel`] among the voxel objects `include` admits.
    pub(crate) fn pick_voxel_where(
        &self,
        origin_in_world: Vec3,
        dir_in_world: Vec3,
        include: impl Fn(&thicket_core::scene::Object) -> bool,
    ) -> Option<VoxelPick> {
        let dir = dir_in_world.try_normalize()?;
        let mut best: Option<VoxelPick> = None;
        for o in self.doc.objects.iter().filter(|o| include(o)) {
            let ObjectKind::Voxels(v) = &o.kind else {
                continue;
            };
            let Some((_, voxel_from_world, size)) = voxel_frame(o, v) else {
                continue;
            };
            let max_t = best.map_or(f32::INFINITY, |b| b.t);
            let hit = if let Some(rig) = &v.rig {
                // A rigged model is drawn in its pose: cast against the posed voxels.
                posed_raycast(o, v, rig, &self.doc.quality, origin_in_world, dir, max_t)
            } else {
                // Same parameter t in both spaces: the direction is transformed, not normalised.
                let origin_v = voxel_from_world.transform_point3(origin_in_world);
                let dir_v = voxel_from_world.transform_vector3(dir);
                v.svo
                    .raycast(origin_v.as_dvec3(), dir_v.as_dvec3(), f64::from(max_t))
                    .map(|h| (h.t as f32, h.coord, h.normal))
            };
            let Some((t, voxel, normal)) = hit else {
                continue;
            };
            if best.is_none_or(|b| t < b.t) {
                best = Some(VoxelPick {
                    object: o.id,
                    voxel,
                    normal,
                    point_in_world: origin_in_world + dir * t,
                    t,
                    voxel_from_world,
                    voxel_size_world: size,
                });
            }
        }
        best
    }

    /// Starts a sculpt stroke: the next dab begins a new undo step.
    pub fn begin_stroke(&mut self) {
        self.history.seal();
    }

    /// Applies one dab of `brush` to voxel object `id` at `center` (voxel coordinates), with
    /// symmetric copies mirrored across `symmetry_center`. The dabs of one stroke (until
    /// [`Editor::end_interaction`] or [`Editor::begin_stroke`]) are one undo step. Returns the
    /// inclusive box of changed voxels.
    ///
    /// # Errors
    /// Unknown id, an object that is not a voxel model, or a brush setting out of range.
    pub fn sculpt_dab(
        &mut self,
        id: u64,
        brush: &Brush,
        center: Vec3,
        symmetry_center: Vec3,
    ) -> Result<Option<(UVec3, UVec3)>, CommandError> {
        let index = self.index_of(id)?;
        if let Some(l) = self.doc.enhancement_into(id) {
            let source = self
                .object(l.source)
                .map_or("its source", |o| o.name.as_str());
            return Err(CommandError::Invalid(format!(
                "{:?} is the detail enhancement of {source:?} and follows it: sculpt \
                 {source:?}, or unlink the enhancement in the inspector to edit this one",
                self.doc.objects[index].name
            )));
        }
        // A linked enhancement is brought up to date before the dab, so the dab's update is
        // incremental.
        self.ensure_enhancer(id);
        let ObjectKind::Voxels(v) = &mut self.doc.objects[index].kind else {
            return Err(CommandError::Invalid(format!(
                "{:?} is not a voxel model: only voxel models can be sculpted",
                self.doc.objects[index].name
            )));
        };
        let frame = v.frames.as_ref().map_or(0, |f| f.shown);
        let dab = apply_dab(&mut v.svo, brush, center, symmetry_center)
            .map_err(|e| CommandError::Invalid(e.to_string()))?;
        if dab.delta.is_empty() {
            return Ok(None);
        }
        let before = self.content_key();
        self.history.push_named(
            Edit::Voxels {
                id,
                delta: dab.delta,
                frame,
            },
            Some(MergeKey::Stroke(id)),
            "Brush stroke".into(),
        );
        self.after_voxel_edit(before, id, dab.changed);
        Ok(dab.changed)
    }

    /// After a voxel edit of object `id` from content key `before` that changed the voxels in
    /// `changed` (inclusive bounds; `None`: unknown, the whole model): keeps a linked
    /// enhancement in step and records the change.
    pub(super) fn after_voxel_edit(
        &mut self,
        before: (u64, u64),
        id: u64,
        changed: Option<(UVec3, UVec3)>,
    ) {
        match changed {
            Some((lo, hi)) => self.after_voxel_write(before, id, lo, hi, true),
            None => self.record(
                before,
                Change::Voxels {
                    object: id,
                    region: None,
                },
            ),
        }
    }

    /// After the voxels `lo..=hi` of object `id` were written (a dab, an undo or a redo of
    /// one) from content key `before`: keeps a linked enhancement in step and records what
    /// changed: the written box (when `record_source`; an undo that recorded its step's change
    /// already, a step that was more than voxels or of a frame sequence, passes false) and the
    /// enhancement's box.
    pub(super) fn after_voxel_write(
        &mut self,
        before: (u64, u64),
        id: u64,
        lo: UVec3,
        hi: UVec3,
        record_source: bool,
    ) {
        let source = Change::Voxels {
            object: id,
            region: Some((lo, hi)),
        };
        let fine = match self.sync_enhancement(id, lo, hi) {
            Ok(f) => f,
            Err(e) => {
                // The enhancement may be half-written: all may have changed.
                self.enhance_error = Some(e.to_string());
                self.record(before, Change::Content);
                return;
            }
        };
        let mut from = before;
        if record_source {
            self.record(from, source);
            from = self.content_key();
        }
        let Some((fine_lo, fine_hi)) = fine else {
            return;
        };
        self.enhance_error = None;
        if let Some(target) = self.doc.enhancement_of(id).map(|l| l.target) {
            self.record(
                from,
                Change::Voxels {
                    object: target,
                    region: Some((fine_lo, fine_hi)),
                },
            );
        }
    }

    /// The centre of a voxel object's solid voxels in voxel coordinates (the symmetry centre
    /// of a stroke), or `None` for an empty or non-voxel object.
    #[must_use]
    pub fn voxel_center(&self, id: u64) -> Option<Vec3> {
        let o = self.object(id)?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return None;
        };
        let (lo, hi) = v.svo.bounds()?;
        Some((lo.as_vec3() + (hi + 1).as_vec3()) * 0.5)
    }
}

/// A world-space ray through a point of the view: `ndc` in [-1, 1]² (y up).
#[must_use]
pub fn ray_through(clip_from_world: Mat4, ndc: glam::Vec2) -> Option<(Vec3, Vec3)> {
    let world_from_clip = clip_from_world.inverse();
    // wgpu depth range 0..1: near plane at 0, a point at depth 0.5 is still in front.
    let near = world_from_clip.project_point3(ndc.extend(0.0));
    let far = world_from_clip.project_point3(ndc.extend(0.5));
    let dir = (far - near).try_normalize()?;
    near.is_finite().then_some((near, dir))
}

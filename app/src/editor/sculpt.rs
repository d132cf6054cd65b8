//! Picking voxels with the octree ray cast and sculpting them with brushes: one undo step per
//! stroke, holding only the voxels the stroke touched.

use glam::{IVec3, Mat4, UVec3, Vec3};
use thicket_core::scene::ObjectKind;
use thicket_core::sculpt::{Brush, BrushOp, apply_dab};

use super::{CommandError, Edit, Editor, MergeKey};

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
    /// Where a brush aims on a rigged model drawn in a pose: the voxel of the node a preview
    /// pixel shows (`node` as [`Editor::node_center`] takes it; a node drawn at LOD stands for
    /// the leaf nearest its centre), facing along its normal's dominant axis. A ray cast finds
    /// the bind-pose voxels, which a pose moves away from where they are drawn, so the preview's
    /// node ids are what the pointer is over. `point_in_world` is the voxel's centre in the
    /// shown pose and `t` its distance from `eye`. `None`: not a rigged voxel model, or no
    /// such node.
    #[must_use]
    pub fn posed_voxel_pick(&self, id: u64, node: u64, eye: Vec3) -> Option<VoxelPick> {
        let o = self.object(id).filter(|o| self.voxel_pickable(o))?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return None;
        };
        let rig = v.rig.as_ref()?;
        let svo = &v.svo;
        let (level, index) = ((node >> 32) as u8, node as u32);
        if svo.is_empty() || level > svo.depth() {
            return None;
        }
        let mut stack = vec![svo.root()];
        let mut found = None;
        while let Some(n) = stack.pop() {
            if n.level == level {
                if n.index == index {
                    found = Some(n);
                    break;
                }
                continue;
            }
            if !svo.is_leaf(&n) {
                stack.extend((0..8).filter_map(|k| svo.child(&n, k)));
            }
        }
        let mut n = found?;
        let center = |n: &thicket_core::svo::NodeRef| {
            n.origin.as_vec3() + 0.5 * svo.node_size(n.level) as f32
        };
        let target = center(&n);
        while !svo.is_leaf(&n) {
            n = (0..8).filter_map(|k| svo.child(&n, k)).min_by(|a, b| {
                center(a)
                    .distance_squared(target)
                    .total_cmp(&center(b).distance_squared(target))
            })?;
        }
        let voxel = svo.get(n.origin)?;
        let normal = thicket_core::svo::decode_normal(voxel.normal);
        let axis = normal.abs().max_position();
        let mut face = IVec3::ZERO;
        face[axis] = if normal[axis] < 0.0 { -1 } else { 1 };
        let (_, voxel_from_world, size) = voxel_frame(o, v)?;
        let skinning = rig.skinning_at(rig.playback.clip, rig.playback.time_secs);
        let posed = thicket_core::skin::skin_point(
            &skinning,
            voxel.skin.joints_u16(),
            voxel.skin.blend_weights(),
            v.object_from_voxel()
                .transform_point3(n.origin.as_vec3() + 0.5),
        );
        let point_in_world = o.transform.matrix().transform_point3(posed);
        Some(VoxelPick {
            object: id,
            voxel: n.origin,
            normal: face,
            point_in_world,
            t: point_in_world.distance(eye),
            voxel_from_world,
            voxel_size_world: size,
        })
    }

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
            // Same parameter t in both spaces: the direction is transformed, not normalised.
            let origin_v = voxel_from_world.transform_point3(origin_in_world);
            let dir_v = voxel_from_world.transform_vector3(dir);
            let max_t = best.map_or(f64::INFINITY, |b| f64::from(b.t));
            let Some(hit) = v.svo.raycast(origin_v.as_dvec3(), dir_v.as_dvec3(), max_t) else {
                continue;
            };
            let t = hit.t as f32;
            if best.is_none_or(|b| t < b.t) {
                best = Some(VoxelPick {
                    object: o.id,
                    voxel: hit.coord,
                    normal: hit.normal,
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
        self.history.push(
            Edit::Voxels {
                id,
                delta: dab.delta,
                frame,
            },
            Some(MergeKey::Stroke(id)),
        );
        self.revision += 1;
        if let Some((lo, hi)) = dab.changed {
            self.after_voxel_write(before, id, lo, hi);
        } else {
            // A delta without a region: no renderer may take the shortcut.
            self.voxel_region = None;
        }
        Ok(dab.changed)
    }

    /// After the voxels `lo..=hi` of object `id` were written (a dab, an undo or a redo of
    /// one): keeps a linked enhancement in step and records what a renderer must upload.
    pub(super) fn after_voxel_write(&mut self, before: (u64, u64), id: u64, lo: UVec3, hi: UVec3) {
        let fine = match self.sync_enhancement(id, lo, hi) {
            Ok(f) => f,
            Err(e) => {
                self.enhance_error = Some(e.to_string());
                self.voxel_region = None;
                return;
            }
        };
        let Some((fine_lo, fine_hi)) = fine else {
            self.note_voxel_edit(before, id, lo, hi);
            return;
        };
        self.enhance_error = None;
        let target = self.doc.enhancement_of(id).map(|l| l.target);
        let visible =
            |ed: &Self, id: Option<u64>| id.and_then(|id| ed.object(id)).is_some_and(|o| o.visible);
        // A renderer holds only visible objects: the region shortcut fits when just one of
        // the two changed objects is drawn.
        match (visible(self, Some(id)), visible(self, target)) {
            (true, true) => self.voxel_region = None,
            (false, true) => {
                if let Some(t) = target {
                    self.note_voxel_edit(before, t, fine_lo, fine_hi);
                }
            }
            _ => self.note_voxel_edit(before, id, lo, hi),
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

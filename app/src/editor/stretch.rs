//! Painting per-voxel stretch overrides of a rigged model (paper §8.1.3: factors "manually
//! refined and stored per voxel"): a spherical brush writes one override byte per leaf voxel;
//! a stroke is one undo step holding only the voxels it changed, with their old bytes.

use glam::{UVec3, Vec3};
use thicket_core::scene::ObjectKind;
use thicket_core::skin::stretch::{decode_override, encode_override};

use super::{CommandError, Edit, Editor, MergeKey};

/// Largest override factor one byte holds (255 / 64).
pub const MAX_STRETCH_OVERRIDE: f32 = 255.0 / 64.0;

impl Editor {
    /// Sets the stretch override of every leaf voxel of rigged model `id` within `radius`
    /// voxels of `center` (voxel coordinates) to `factor` (`None` erases the overrides). The
    /// dabs of one stroke (until [`Editor::end_interaction`] or [`Editor::begin_stroke`]) are
    /// one undo step. Returns how many voxels changed.
    ///
    /// # Errors
    /// Unknown id, a model without a rig, or a factor outside `1/64..=255/64` or a radius
    /// outside `0.5..=64` voxels.
    pub fn paint_stretch(
        &mut self,
        id: u64,
        center: Vec3,
        radius: f32,
        factor: Option<f32>,
    ) -> Result<usize, CommandError> {
        let index = self.index_of(id)?;
        let o = &self.doc.objects[index];
        let ObjectKind::Voxels(v) = &o.kind else {
            return Err(CommandError::Invalid(format!(
                "{:?} is not a voxel model: stretch overrides belong to rigged voxel models",
                o.name
            )));
        };
        let Some(rig) = &v.rig else {
            return Err(CommandError::Invalid(format!(
                "{:?} has no skeleton: stretch overrides belong to rigged voxel models",
                o.name
            )));
        };
        if !(radius.is_finite() && (0.5..=64.0).contains(&radius) && center.is_finite()) {
            return Err(CommandError::Invalid(format!(
                "stretch brush: radius {radius} must be in 0.5..=64 voxels"
            )));
        }
        let code = match factor {
            None => 0,
            Some(f) if f.is_finite() && (1.0 / 64.0..=MAX_STRETCH_OVERRIDE).contains(&f) => {
                encode_override(f)
            }
            Some(f) => {
                return Err(CommandError::Invalid(format!(
                    "stretch override {f} must be in {:.3}..={MAX_STRETCH_OVERRIDE:.2}",
                    1.0 / 64.0
                )));
            }
        };
        let ext = v.svo.extent();
        let lo = (center - radius).floor().max(Vec3::ZERO).as_uvec3();
        let hi = (center + radius)
            .floor()
            .as_uvec3()
            .min(UVec3::splat(ext - 1));
        let mut entries = Vec::new();
        if (center + radius).cmpge(Vec3::ZERO).all() && lo.cmple(hi).all() {
            v.svo.for_each_leaf_in(lo, hi, |p, _| {
                if (p.as_vec3() + 0.5).distance(center) <= radius
                    && rig.stretch_overrides.get(p) != code
                {
                    entries.push((p, code));
                }
            });
        }
        if entries.is_empty() {
            return Ok(0);
        }
        let n = entries.len();
        self.apply(
            Edit::StretchOverrides { id, entries },
            Some(MergeKey::StretchPaint(id)),
        );
        Ok(n)
    }

    /// Removes every painted stretch override of rigged model `id` (one undo step).
    ///
    /// # Errors
    /// Unknown id or a model without a rig.
    pub fn clear_stretch_overrides(&mut self, id: u64) -> Result<usize, CommandError> {
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let rig = match &o.kind {
            ObjectKind::Voxels(v) => v.rig.as_ref(),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
        }
        .ok_or_else(|| {
            CommandError::Invalid(format!(
                "{:?} has no skeleton: stretch overrides belong to rigged voxel models",
                o.name
            ))
        })?;
        let entries: Vec<(UVec3, u8)> = rig.stretch_overrides.iter().map(|(p, _)| (p, 0)).collect();
        let n = entries.len();
        if n > 0 {
            self.history.seal();
            self.apply(Edit::StretchOverrides { id, entries }, None);
            self.history.seal();
        }
        Ok(n)
    }

    /// The stretch override of a leaf voxel of rigged model `id` (`None`: none painted).
    #[must_use]
    pub fn stretch_override(&self, id: u64, voxel: UVec3) -> Option<f32> {
        match &self.object(id)?.kind {
            ObjectKind::Voxels(v) => decode_override(v.rig.as_ref()?.stretch_overrides.get(voxel)),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
        }
    }

    /// The centre (voxel coordinates) of the node a preview pixel shows: `node` is the
    /// renderer's pixel id, `(level << 32) | index in that level's pool`.
    #[must_use]
    pub fn node_center(&self, id: u64, node: u64) -> Option<Vec3> {
        let ObjectKind::Voxels(v) = &self.object(id)?.kind else {
            return None;
        };
        let (level, index) = ((node >> 32) as u8, node as u32);
        if v.svo.is_empty() || level > v.svo.depth() {
            return None;
        }
        // Depth-first down to the wanted level only.
        let mut stack = vec![v.svo.root()];
        while let Some(n) = stack.pop() {
            if n.level == level {
                if n.index == index {
                    let half = 0.5 * v.svo.node_size(level) as f32;
                    return Some(n.origin.as_vec3() + half);
                }
                continue;
            }
            if !v.svo.is_leaf(&n) {
                stack.extend((0..8).filter_map(|k| v.svo.child(&n, k)));
            }
        }
        None
    }
}

//! Sculpt brushes (add, remove, paint, smooth; sphere and cube; X/Y/Z symmetry) as octree edits
//! that return the changed region and one undo delta for the whole dab.
//!
//! Brush positions and radii are in voxel coordinates of the model (voxel `c` spans
//! `[c, c + 1)`), so a brush is independent of the model's placement in the scene.
//!
//! The everyday voxel tools live in the submodules (see docs/sculpt.md): [`shapes`] (lines,
//! boxes, flood and face regions, push-pull), [`select`] (selections, copy/paste, transforms),
//! [`model_ops`] (resize, shift, mirror, hollow, fill interior, new models) and [`palette`].

pub mod model_ops;
pub mod palette;
pub mod select;
pub mod shapes;

#[cfg(test)]
mod fast_path_tests;
#[cfg(test)]
mod tile_tests;
#[cfg(test)]
mod tool_tests;

pub use model_ops::{
    Anchor, InitialFill, Resized, depth_for, fill_interior, hollow, mirror_model, new_model,
    resize_canvas, shift_content,
};
pub use palette::{
    PaletteError, load_palette, model_colors, palette_from_png, palette_from_vox, palette_to_png,
    parse_gpl, replace_color, save_palette, write_gpl,
};
pub use select::{
    Clipboard, SelTransform, SurfaceView, VoxelSelection, copy, crop_to, delete, fill, grow,
    invert, paste, paste_cells, rotation_pivot, select_box, select_color, select_connected,
    select_in_rect, shrink, transform_selection,
};
pub use shapes::{
    Ink, MAX_EDIT_CELLS, MAX_LISTED_VOXELS, Mask, Mirror, ShapeOp, ToolEdit, ToolError, apply_box,
    apply_cells, check_listable, extrude, extrude_cells, face_region, flood_region, line_cells,
};

use std::collections::HashMap;
use std::sync::OnceLock;

use glam::{IVec3, UVec3, Vec3};
use serde::{Deserialize, Serialize};

use crate::mesh::{linear_to_srgb, srgb_to_linear};
use crate::svo::{EditResult, Skin4, Svo, UndoDelta, Voxel, encode_normal};

/// Brush footprint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum BrushShape {
    /// Voxels whose centre is within `radius` of the brush centre.
    #[default]
    Sphere,
    /// Voxels whose centre is within `radius` along every axis.
    Cube,
}

/// What a brush does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum BrushOp {
    /// Fill empty voxels with the brush colour and material.
    #[default]
    Add,
    /// Empty solid voxels.
    Remove,
    /// Blend solid voxels' colour toward the brush colour by `strength`.
    Paint,
    /// Majority filter: remove voxels with few solid neighbours, fill gaps with many.
    Smooth,
}

/// A brush and its settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Brush {
    /// Footprint.
    pub shape: BrushShape,
    /// Operation.
    pub op: BrushOp,
    /// Radius in voxels (0.5 = a single voxel).
    pub radius: f32,
    /// 0..1: paint blend factor; for smooth, how aggressive the majority filter is.
    pub strength: f32,
    /// sRGB RGBA colour for add and paint.
    pub color: [u8; 4],
    /// Material id for add.
    pub material: u8,
    /// Mirror each dab across the symmetry centre along X, Y, Z.
    pub symmetry: [bool; 3],
}

impl Default for Brush {
    fn default() -> Self {
        Self {
            shape: BrushShape::Sphere,
            op: BrushOp::Add,
            radius: 4.0,
            strength: 1.0,
            color: [200, 200, 200, 255],
            material: 0,
            symmetry: [false; 3],
        }
    }
}

/// Why a dab was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SculptError {
    /// A non-finite or out-of-range brush setting.
    #[error("brush {what} = {value} is invalid ({expected})")]
    BadBrush {
        /// Which setting.
        what: &'static str,
        /// Its value.
        value: f32,
        /// What is allowed.
        expected: &'static str,
    },
    /// A non-finite brush position.
    #[error("brush position {0} is not finite")]
    BadPosition(Vec3),
}

/// Largest brush radius in voxels: a dab visits O(radius³) voxels.
pub const MAX_RADIUS: f32 = 256.0;

impl Brush {
    /// Checks the settings.
    ///
    /// # Errors
    /// The first bad setting.
    pub fn validate(&self) -> Result<(), SculptError> {
        if !(self.radius.is_finite() && self.radius > 0.0 && self.radius <= MAX_RADIUS) {
            return Err(SculptError::BadBrush {
                what: "radius",
                value: self.radius,
                expected: "0 < radius <= 256 voxels",
            });
        }
        if !(self.strength.is_finite() && (0.0..=1.0).contains(&self.strength)) {
            return Err(SculptError::BadBrush {
                what: "strength",
                value: self.strength,
                expected: "0..=1",
            });
        }
        Ok(())
    }

    fn contains(&self, center: Vec3, voxel: UVec3) -> bool {
        let d = voxel.as_vec3() + 0.5 - center;
        match self.shape {
            BrushShape::Sphere => d.length_squared() <= self.radius * self.radius,
            BrushShape::Cube => d.abs().max_element() <= self.radius,
        }
    }
}

/// The result of one dab (all its symmetric copies together).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Dab {
    /// Inclusive box of changed voxels, if any changed.
    pub changed: Option<(UVec3, UVec3)>,
    /// Undoes the whole dab when applied with [`Svo::apply_delta`].
    pub delta: UndoDelta,
}

impl Dab {
    fn absorb(&mut self, r: EditResult) {
        if let Some((lo, hi)) = r.changed {
            self.changed = Some(
                self.changed
                    .map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))),
            );
        }
        // Later edits' old values must be restored first, so they go in front.
        let mut entries = r.delta.entries;
        entries.append(&mut self.delta.entries);
        self.delta.entries = entries;
    }
}

/// Outward normal from the occupancy of the 3×3×3 neighbourhood: the direction away from the
/// solid neighbours. Returns +Y for an isolated or fully surrounded voxel.
#[must_use]
pub fn estimate_normal(svo: &Svo, c: UVec3) -> Vec3 {
    normal_from(|o| offset(c, o).is_some_and(|n| svo.get(n).is_some()))
}

/// The 26 neighbour offsets (z, then y, then x from -1 to 1) with their unit directions.
pub(crate) fn neighbour_dirs() -> &'static [(IVec3, Vec3); 26] {
    static DIRS: OnceLock<[(IVec3, Vec3); 26]> = OnceLock::new();
    DIRS.get_or_init(|| {
        let mut out = [(IVec3::ZERO, Vec3::ZERO); 26];
        let mut i = 0;
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let o = IVec3::new(dx, dy, dz);
                    if o != IVec3::ZERO {
                        out[i] = (o, o.as_vec3().normalize_or_zero());
                        i += 1;
                    }
                }
            }
        }
        out
    })
}

/// [`estimate_normal`] over any occupancy: `solid(offset)` says whether the neighbour at
/// `offset` is solid. One definition so every tool's normals match the brushes' exactly.
pub(crate) fn normal_from(mut solid: impl FnMut(IVec3) -> bool) -> Vec3 {
    let mut mask = 0u32;
    for (i, &(o, _)) in neighbour_dirs().iter().enumerate() {
        if solid(o) {
            mask |= 1 << i;
        }
    }
    normal_from_mask(mask)
}

/// Every neighbour solid: the mask of a voxel deep inside a solid.
pub(crate) const ALL_NEIGHBOURS: u32 = (1 << 26) - 1;

/// [`normal_from`] of a neighbourhood given as a mask: bit `i` set when the neighbour at
/// `neighbour_dirs()[i]` is solid. The estimate depends on the occupancy only through this mask
/// (the same float operations in the same order), so callers may cache it by mask.
pub(crate) fn normal_from_mask(mask: u32) -> Vec3 {
    let mut acc = Vec3::ZERO;
    for (i, &(_, dir)) in neighbour_dirs().iter().enumerate() {
        if mask & (1 << i) != 0 {
            acc -= dir;
        }
    }
    acc.try_normalize().unwrap_or(Vec3::Y)
}

pub(crate) fn offset(c: UVec3, o: IVec3) -> Option<UVec3> {
    let p = c.as_ivec3() + o;
    (p.min_element() >= 0).then(|| p.as_uvec3())
}

fn solid_neighbours(svo: &Svo, c: UVec3) -> u32 {
    let mut n = 0;
    for dz in -1..=1 {
        for dy in -1..=1 {
            for dx in -1..=1 {
                let o = IVec3::new(dx, dy, dz);
                if o != IVec3::ZERO && offset(c, o).is_some_and(|p| svo.get(p).is_some()) {
                    n += 1;
                }
            }
        }
    }
    n
}

pub(crate) fn nearest_skin(svo: &Svo, c: UVec3) -> Skin4 {
    if !svo.has_skin() {
        return Skin4::default();
    }
    for r in 1..=3i32 {
        let mut best: Option<(i32, Skin4)> = None;
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    let o = IVec3::new(dx, dy, dz);
                    if let Some(v) = offset(c, o).and_then(|p| svo.get(p)) {
                        let d = o.length_squared();
                        if best.is_none_or(|b| d < b.0) {
                            best = Some((d, v.skin));
                        }
                    }
                }
            }
        }
        if let Some((_, s)) = best {
            return s;
        }
    }
    Skin4::default()
}

fn blend(a: [u8; 4], b: [u8; 4], t: f32) -> [u8; 4] {
    let mut out = [0u8; 4];
    for i in 0..3 {
        let (x, y) = (
            srgb_to_linear(f32::from(a[i]) / 255.0),
            srgb_to_linear(f32::from(b[i]) / 255.0),
        );
        out[i] = (linear_to_srgb(x + (y - x) * t) * 255.0).round() as u8;
    }
    out[3] = (f32::from(a[3]) + (f32::from(b[3]) - f32::from(a[3])) * t).round() as u8;
    out
}

/// Evaluates `f` over the inclusive box before an edit, keeping the `Some` results.
fn plan<T>(lo: UVec3, hi: UVec3, mut f: impl FnMut(UVec3) -> Option<T>) -> HashMap<UVec3, T> {
    let mut out = HashMap::new();
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let p = UVec3::new(x, y, z);
                if let Some(v) = f(p) {
                    out.insert(p, v);
                }
            }
        }
    }
    out
}

/// The dab centres after symmetry: the centre plus its mirror images across `symmetry_center`.
fn mirrored(brush: &Brush, center: Vec3, symmetry_center: Vec3) -> Vec<Vec3> {
    let mut centers = vec![center];
    for axis in 0..3 {
        if brush.symmetry[axis] {
            let copies: Vec<Vec3> = centers
                .iter()
                .map(|c| {
                    let mut m = *c;
                    m[axis] = 2.0 * symmetry_center[axis] - c[axis];
                    m
                })
                .collect();
            for m in copies {
                if !centers.iter().any(|c| (*c - m).length_squared() < 1e-6) {
                    centers.push(m);
                }
            }
        }
    }
    centers
}

/// Applies one dab of `brush` at `center` (voxel coordinates), with its symmetric copies
/// mirrored across `symmetry_center`. Normals of voxels on and next to the changed surface are
/// re-estimated. Returns the changed box and a single undo delta.
///
/// # Errors
/// Invalid brush settings or position; the octree is untouched then.
pub fn apply_dab(
    svo: &mut Svo,
    brush: &Brush,
    center: Vec3,
    symmetry_center: Vec3,
) -> Result<Dab, SculptError> {
    brush.validate()?;
    if !center.is_finite() || !symmetry_center.is_finite() {
        return Err(SculptError::BadPosition(if center.is_finite() {
            symmetry_center
        } else {
            center
        }));
    }
    let mut dab = Dab::default();
    let extent = svo.extent() as f32;
    for c in mirrored(brush, center, symmetry_center) {
        let lo_f = (c - brush.radius - 1.0).floor().max(Vec3::ZERO);
        let hi_f = (c + brush.radius + 1.0)
            .ceil()
            .min(Vec3::splat(extent - 1.0));
        if lo_f.cmpgt(hi_f).any() || hi_f.min_element() < 0.0 || lo_f.max_element() >= extent {
            continue;
        }
        let (lo, hi) = (lo_f.as_uvec3(), hi_f.as_uvec3());
        let r = match brush.op {
            BrushOp::Add => {
                // New voxels' attributes are chosen from the state before this dab.
                let planned = plan(lo, hi, |p| {
                    (brush.contains(c, p) && svo.get(p).is_none()).then(|| Voxel {
                        color: brush.color,
                        normal: encode_normal(Vec3::Y),
                        material: brush.material,
                        skin: nearest_skin(svo, p),
                    })
                });
                svo.edit_region(lo, hi, |p, old| planned.get(&p).copied().or(old))
            }
            BrushOp::Remove => {
                svo.edit_existing(lo, hi, |p, v| (!brush.contains(c, p)).then_some(v))
            }
            BrushOp::Paint => svo.edit_existing(lo, hi, |p, v| {
                Some(if brush.contains(c, p) {
                    Voxel {
                        color: blend(v.color, brush.color, brush.strength),
                        ..v
                    }
                } else {
                    v
                })
            }),
            BrushOp::Smooth => {
                // Decided from the state before the dab so the filter does not see its output.
                let keep_min = (4.0 + 6.0 * brush.strength).round() as u32; // of 26 neighbours
                let fill_min = (22.0 - 8.0 * brush.strength).round() as u32;
                let planned = plan(lo, hi, |p| {
                    if !brush.contains(c, p) {
                        return None;
                    }
                    let n = solid_neighbours(svo, p);
                    match svo.get(p) {
                        Some(_) if n < keep_min => Some(None),
                        None if n >= fill_min => {
                            let donor = [
                                IVec3::Y,
                                IVec3::NEG_Y,
                                IVec3::X,
                                IVec3::NEG_X,
                                IVec3::Z,
                                IVec3::NEG_Z,
                            ]
                            .iter()
                            .find_map(|&o| offset(p, o).and_then(|q| svo.get(q)));
                            donor.map(|d| {
                                Some(Voxel {
                                    skin: nearest_skin(svo, p),
                                    ..d
                                })
                            })
                        }
                        _ => None,
                    }
                });
                svo.edit_region(lo, hi, |p, old| planned.get(&p).copied().unwrap_or(old))
            }
        };
        // The box is clamped inside the octree above, so the edit cannot be out of bounds.
        if let Ok(r) = r {
            dab.absorb(r);
        }
    }
    if let Some((lo, hi)) = dab.changed
        && matches!(brush.op, BrushOp::Add | BrushOp::Remove | BrushOp::Smooth)
    {
        let max = UVec3::splat(svo.extent() - 1);
        let (nlo, nhi) = (lo.saturating_sub(UVec3::ONE), (hi + 1).min(max));
        let normals = plan(nlo, nhi, |p| {
            svo.get(p).map(|_| encode_normal(estimate_normal(svo, p)))
        });
        if let Ok(r) = svo.edit_existing(nlo, nhi, |p, v| {
            Some(Voxel {
                normal: normals.get(&p).copied().unwrap_or(v.normal),
                ..v
            })
        }) {
            dab.absorb(r);
        }
    }
    Ok(dab)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn floor(depth: u8) -> Svo {
        let e = 1u32 << depth;
        Svo::from_fn(
            depth,
            false,
            |o, _| o.y == 0,
            |c| (c.y == 0).then(|| Voxel::new([90, 90, 90, 255], Vec3::Y)),
        )
        .inspect(|s| assert_eq!(s.leaf_count(), u64::from(e * e)))
        .unwrap()
    }

    #[test]
    fn sphere_add_fills_the_ball_and_undo_restores() {
        let mut svo = Svo::new(5, false).unwrap();
        let before = svo.clone();
        let brush = Brush {
            radius: 5.0,
            ..Brush::default()
        };
        let dab = apply_dab(&mut svo, &brush, Vec3::splat(16.0), Vec3::splat(16.0)).unwrap();
        let count = svo.leaf_count() as f32;
        let ball = 4.0 / 3.0 * std::f32::consts::PI * 125.0;
        assert!((count - ball).abs() / ball < 0.1, "{count} vs {ball}");
        let (lo, hi) = dab.changed.unwrap();
        assert!(lo.cmpge(UVec3::splat(10)).all() && hi.cmple(UVec3::splat(21)).all());
        // Normals point away from the centre on the surface.
        let top = svo.get(UVec3::new(16, 20, 16)).unwrap();
        assert!(top.normal_vec().y > 0.7, "{}", top.normal_vec());
        svo.apply_delta(&dab.delta);
        assert_eq!(svo, before);
    }

    #[test]
    fn symmetry_mirrors_the_dab() {
        let mut svo = Svo::new(5, false).unwrap();
        let brush = Brush {
            radius: 2.0,
            symmetry: [true, false, true],
            ..Brush::default()
        };
        apply_dab(
            &mut svo,
            &brush,
            Vec3::new(8.0, 16.0, 10.0),
            Vec3::splat(16.0),
        )
        .unwrap();
        for c in [
            Vec3::new(8.0, 16.0, 10.0),
            Vec3::new(24.0, 16.0, 10.0),
            Vec3::new(8.0, 16.0, 22.0),
            Vec3::new(24.0, 16.0, 22.0),
        ] {
            assert!(svo.get((c - 0.5).as_uvec3()).is_some(), "{c}");
        }
        let leaves = svo.leaves();
        for (p, _) in &leaves {
            let m = UVec3::new(31 - p.x, p.y, p.z);
            assert!(svo.get(m).is_some(), "mirror of {p} missing");
        }
    }

    #[test]
    fn remove_paint_and_smooth_on_a_floor() {
        let mut svo = floor(5);
        let original = svo.clone();
        let paint = Brush {
            op: BrushOp::Paint,
            radius: 3.0,
            strength: 1.0,
            color: [255, 0, 0, 255],
            ..Brush::default()
        };
        let d1 = apply_dab(&mut svo, &paint, Vec3::new(16.0, 0.5, 16.0), Vec3::ZERO).unwrap();
        assert_eq!(
            svo.get(UVec3::new(16, 0, 16)).unwrap().color,
            [255, 0, 0, 255]
        );
        assert_eq!(
            svo.get(UVec3::new(2, 0, 2)).unwrap().color,
            [90, 90, 90, 255]
        );
        let half = Brush {
            strength: 0.5,
            color: [0, 0, 255, 255],
            ..paint.clone()
        };
        let d2 = apply_dab(&mut svo, &half, Vec3::new(16.0, 0.5, 16.0), Vec3::ZERO).unwrap();
        let c = svo.get(UVec3::new(16, 0, 16)).unwrap().color;
        assert!(c[0] > 100 && c[2] > 100, "{c:?}");
        let hole = Brush {
            op: BrushOp::Remove,
            radius: 2.0,
            ..Brush::default()
        };
        let d3 = apply_dab(&mut svo, &hole, Vec3::new(8.0, 0.5, 8.0), Vec3::ZERO).unwrap();
        assert!(svo.get(UVec3::new(8, 0, 8)).is_none());
        // A lone spike above the floor is removed by smoothing.
        let spike = UVec3::new(20, 3, 20);
        let d_spike = svo
            .edit_region(spike, spike, |_, _| {
                Some(Voxel::new([1, 1, 1, 255], Vec3::Y))
            })
            .unwrap();
        let smooth = Brush {
            op: BrushOp::Smooth,
            radius: 2.0,
            strength: 0.5,
            ..Brush::default()
        };
        let d4 = apply_dab(&mut svo, &smooth, Vec3::new(20.5, 3.5, 20.5), Vec3::ZERO).unwrap();
        assert!(svo.get(spike).is_none());
        for delta in [d4.delta, d_spike.delta, d3.delta, d2.delta, d1.delta] {
            svo.apply_delta(&delta);
        }
        assert!(svo == original, "undoing every dab restores the floor");
    }

    #[test]
    fn bad_brushes_and_far_away_dabs() {
        let mut svo = Svo::new(4, false).unwrap();
        for radius in [0.0, -1.0, f32::NAN, f32::INFINITY, 1e9] {
            let b = Brush {
                radius,
                ..Brush::default()
            };
            assert!(apply_dab(&mut svo, &b, Vec3::ONE, Vec3::ZERO).is_err());
        }
        assert!(apply_dab(&mut svo, &Brush::default(), Vec3::NAN, Vec3::ZERO).is_err());
        let d = apply_dab(&mut svo, &Brush::default(), Vec3::splat(-100.0), Vec3::ZERO).unwrap();
        assert!(d.changed.is_none() && svo.is_empty());
        // A dab hanging over the edge is clamped to the octree.
        apply_dab(
            &mut svo,
            &Brush {
                radius: 3.0,
                ..Brush::default()
            },
            Vec3::splat(15.5),
            Vec3::ZERO,
        )
        .unwrap();
        assert!(svo.get(UVec3::splat(15)).is_some());
    }

    #[test]
    fn added_voxels_inherit_skin_from_neighbours() {
        let skin = Skin4::from_influences(&[(3, 1.0)]);
        let mut svo = Svo::from_voxels(
            4,
            true,
            [(
                UVec3::new(8, 8, 8),
                Voxel {
                    skin,
                    ..Voxel::new([1, 2, 3, 255], Vec3::Y)
                },
            )],
        )
        .unwrap();
        apply_dab(
            &mut svo,
            &Brush {
                radius: 1.5,
                ..Brush::default()
            },
            Vec3::new(9.5, 8.5, 8.5),
            Vec3::ZERO,
        )
        .unwrap();
        assert_eq!(svo.get(UVec3::new(9, 8, 8)).unwrap().skin, skin);
    }
}

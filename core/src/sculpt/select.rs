//! Voxel selections (box, screen rectangle, colour, connected), their set algebra, and the edits
//! that act on them: delete, recolour, copy/paste, move/flip/rotate, crop.
//!
//! A selection is a sorted list of Morton codes, so membership is a binary search, union and
//! difference are merges, and iteration order is deterministic.

use glam::{I64Vec3, IVec3, Mat4, UVec3, Vec2, Vec3, Vec4};
use rayon::prelude::*;

use super::nearest_skin;
use super::shapes::{
    Ink, MAX_EDIT_CELLS, Normals, ToolEdit, ToolError, check_listable, clamp_size, commit,
    commit_shifted, flood_solid,
};
use crate::svo::{
    MAX_DEPTH, Svo, Voxel, decode_normal, encode_normal, morton_decode, morton_encode,
};

/// A set of voxel cells (deterministic order: sorted Morton codes inside).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct VoxelSelection {
    codes: Vec<u64>,
    bounds: Option<(UVec3, UVec3)>,
}

impl VoxelSelection {
    /// A selection of `cells` (duplicates merged). Cells beyond the octree limit of 2^21 per
    /// axis cannot be voxels and are dropped.
    pub fn from_cells(cells: impl IntoIterator<Item = UVec3>) -> Self {
        let limit = 1u32 << MAX_DEPTH;
        let mut codes: Vec<u64> = cells
            .into_iter()
            .filter(|c| c.max_element() < limit)
            .map(morton_encode)
            .collect();
        codes.par_sort_unstable();
        codes.dedup();
        Self::from_sorted(codes)
    }

    /// From sorted, unique Morton codes.
    fn from_sorted(codes: Vec<u64>) -> Self {
        let mut bounds: Option<(UVec3, UVec3)> = None;
        for &k in &codes {
            let c = morton_decode(k);
            bounds = Some(bounds.map_or((c, c), |(lo, hi)| (lo.min(c), hi.max(c))));
        }
        Self { codes, bounds }
    }

    /// Whether `c` is selected (a binary search).
    #[must_use]
    pub fn contains(&self, c: UVec3) -> bool {
        c.max_element() < 1 << MAX_DEPTH && self.codes.binary_search(&morton_encode(c)).is_ok()
    }

    /// Number of selected cells.
    #[must_use]
    pub fn len(&self) -> usize {
        self.codes.len()
    }

    /// True when nothing is selected.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.codes.is_empty()
    }

    /// The cells in Morton order.
    pub fn iter(&self) -> impl Iterator<Item = UVec3> + '_ {
        self.codes.iter().map(|&k| morton_decode(k))
    }

    /// Inclusive bounds of the cells, None when empty.
    #[must_use]
    pub fn bounds(&self) -> Option<(UVec3, UVec3)> {
        self.bounds
    }

    /// Cells in either selection.
    #[must_use]
    pub fn union(&self, other: &Self) -> Self {
        let (a, b) = (&self.codes, &other.codes);
        let mut out = Vec::with_capacity(a.len() + b.len());
        let (mut i, mut j) = (0, 0);
        while i < a.len() && j < b.len() {
            match a[i].cmp(&b[j]) {
                std::cmp::Ordering::Less => {
                    out.push(a[i]);
                    i += 1;
                }
                std::cmp::Ordering::Greater => {
                    out.push(b[j]);
                    j += 1;
                }
                std::cmp::Ordering::Equal => {
                    out.push(a[i]);
                    i += 1;
                    j += 1;
                }
            }
        }
        out.extend_from_slice(&a[i..]);
        out.extend_from_slice(&b[j..]);
        Self::from_sorted(out)
    }

    /// Cells in this selection and not in `other`.
    #[must_use]
    pub fn difference(&self, other: &Self) -> Self {
        let b = &other.codes;
        let mut j = 0;
        let mut out = Vec::with_capacity(self.codes.len());
        for &k in &self.codes {
            while j < b.len() && b[j] < k {
                j += 1;
            }
            if j >= b.len() || b[j] != k {
                out.push(k);
            }
        }
        Self::from_sorted(out)
    }

    /// A membership test that is cheapest for queries in Morton order (what octree walks
    /// give): a forward scan, with a binary search when a query goes backwards.
    pub(crate) fn cursor(&self) -> SelCursor<'_> {
        SelCursor {
            codes: &self.codes,
            next: 0,
        }
    }

    /// Cells in both selections.
    #[must_use]
    pub fn intersection(&self, other: &Self) -> Self {
        self.difference(&self.difference(other))
    }
}

/// See [`VoxelSelection::cursor`].
pub(crate) struct SelCursor<'a> {
    codes: &'a [u64],
    /// Index of the first code not below the last query.
    next: usize,
}

impl SelCursor<'_> {
    /// Whether `c` is selected.
    pub(crate) fn contains(&mut self, c: UVec3) -> bool {
        if c.max_element() >= 1 << MAX_DEPTH {
            return false;
        }
        let k = morton_encode(c);
        if self.next > 0 && self.codes[self.next - 1] >= k {
            self.next = self.codes.partition_point(|&x| x < k);
        } else {
            while self.next < self.codes.len() && self.codes[self.next] < k {
                self.next += 1;
            }
        }
        let hit = self.codes.get(self.next) == Some(&k);
        if hit {
            self.next += 1;
        }
        hit
    }
}

/// Solid voxels in the inclusive box between corners `a` and `b` (any order).
#[must_use]
pub fn select_box(svo: &Svo, a: UVec3, b: UVec3) -> VoxelSelection {
    let mut codes = Vec::new();
    // for_each_leaf_in walks in Morton order, so the codes come out sorted.
    svo.for_each_leaf_in(a.min(b), a.max(b), |c, _| codes.push(morton_encode(c)));
    VoxelSelection::from_sorted(codes)
}

/// Where [`select_in_rect`] looks from when it keeps only visible voxels (voxel space).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SurfaceView {
    /// A perspective camera's eye.
    Eye(Vec3),
    /// An orthographic camera's view direction (from the camera into the scene).
    Direction(Vec3),
}

/// Solid voxels of the volume whose centre projects inside the NDC rectangle (x,y in [-1,1], y
/// up) under `clip_from_voxel` (perspective or orthographic), in front of the camera (clip
/// `w > 0`). `surface_only`: only those visible from the camera (a ray cast from
/// `eye_in_voxel` — or, for an orthographic camera, along `view_dir_in_voxel` from far outside —
/// hits that voxel first). A non-finite matrix selects nothing.
///
/// # Errors
/// [`ToolError::TooManyVoxels`] past [`super::MAX_LISTED_VOXELS`]: every voxel of the volume
/// is projected.
pub fn select_in_rect(
    svo: &Svo,
    size: UVec3,
    clip_from_voxel: Mat4,
    ndc_min: Vec2,
    ndc_max: Vec2,
    surface_only: Option<SurfaceView>,
) -> Result<VoxelSelection, ToolError> {
    let size = clamp_size(svo, size);
    if size.min_element() == 0 || !clip_from_voxel.is_finite() {
        return Ok(VoxelSelection::default());
    }
    check_listable(svo, "Select (rectangle)")?;
    let (rmin, rmax) = (ndc_min.min(ndc_max), ndc_min.max(ndc_max));
    let mut cells = Vec::new();
    svo.for_each_leaf_in(UVec3::ZERO, size - 1, |c, _| cells.push(c));
    let far = f64::from(svo.extent()) * 4.0 + 16.0;
    let keep: Vec<u64> = cells
        .par_iter()
        .filter(|&&c| {
            let centre = c.as_vec3() + 0.5;
            let p = clip_from_voxel * Vec4::new(centre.x, centre.y, centre.z, 1.0);
            if p.w.is_nan() || p.w <= 0.0 {
                return false;
            }
            let ndc = Vec2::new(p.x, p.y) / p.w;
            if ndc.cmplt(rmin).any() || ndc.cmpgt(rmax).any() {
                return false;
            }
            let centre = centre.as_dvec3();
            let (origin, dir) = match surface_only {
                None => return true,
                Some(SurfaceView::Eye(e)) => (e.as_dvec3(), centre - e.as_dvec3()),
                Some(SurfaceView::Direction(d)) => {
                    let Some(d) = d.as_dvec3().try_normalize() else {
                        return false;
                    };
                    (centre - d * far, d)
                }
            };
            svo.raycast(origin, dir, f64::INFINITY)
                .is_some_and(|h| h.coord == c)
        })
        .map(|&c| morton_encode(c))
        .collect();
    Ok(VoxelSelection::from_sorted(keep))
}

/// Solid voxels of exactly `color` (RGBA).
///
/// # Errors
/// [`ToolError::TooManyVoxels`] past [`super::MAX_LISTED_VOXELS`].
pub fn select_color(svo: &Svo, color: [u8; 4]) -> Result<VoxelSelection, ToolError> {
    check_listable(svo, "Select by colour")?;
    let mut codes = Vec::new();
    svo.for_each_leaf(|c, v| {
        if v.color == color {
            codes.push(morton_encode(c));
        }
    });
    Ok(VoxelSelection::from_sorted(codes))
}

/// Solid voxels 6-connected to `seed`; `same_color`: only through voxels of seed's colour and
/// material. Empty when the seed is empty.
///
/// # Errors
/// [`ToolError::TooManyVoxels`] past [`super::MAX_LISTED_VOXELS`] (the flood may reach them
/// all).
pub fn select_connected(
    svo: &Svo,
    seed: UVec3,
    same_color: bool,
) -> Result<VoxelSelection, ToolError> {
    let Some(sv) = svo.get(seed) else {
        return Ok(VoxelSelection::default());
    };
    let Some((lo, hi)) = svo.bounds() else {
        return Ok(VoxelSelection::default());
    };
    check_listable(svo, "Select connected")?;
    let cells = flood_solid(svo, lo, hi, seed, |_, v| {
        !same_color || (v.color == sv.color && v.material == sv.material)
    });
    Ok(VoxelSelection::from_cells(cells))
}

/// Solid voxels not in `sel` (with an empty `sel`, every solid voxel: select all).
///
/// # Errors
/// [`ToolError::TooManyVoxels`] past [`super::MAX_LISTED_VOXELS`].
pub fn invert(svo: &Svo, sel: &VoxelSelection) -> Result<VoxelSelection, ToolError> {
    check_listable(svo, "Select all / Invert")?;
    let mut codes = Vec::new();
    svo.for_each_leaf(|c, _| {
        if !sel.contains(c) {
            codes.push(morton_encode(c));
        }
    });
    Ok(VoxelSelection::from_sorted(codes))
}

const FACES: [IVec3; 6] = [
    IVec3::NEG_X,
    IVec3::X,
    IVec3::NEG_Y,
    IVec3::Y,
    IVec3::NEG_Z,
    IVec3::Z,
];

fn face_neighbours(c: UVec3) -> impl Iterator<Item = UVec3> {
    FACES.into_iter().filter_map(move |o| {
        let p = c.as_ivec3() + o;
        (p.min_element() >= 0).then(|| p.as_uvec3())
    })
}

/// `sel` plus the solid 6-neighbours of its cells.
#[must_use]
pub fn grow(svo: &Svo, sel: &VoxelSelection) -> VoxelSelection {
    let added: Vec<UVec3> = sel
        .iter()
        .flat_map(face_neighbours)
        .filter(|&p| !sel.contains(p) && svo.get(p).is_some())
        .collect();
    sel.union(&VoxelSelection::from_cells(added))
}

/// `sel` minus its cells that have a 6-neighbour not in `sel` (the volume's outside counts as
/// not selected).
#[must_use]
pub fn shrink(sel: &VoxelSelection) -> VoxelSelection {
    let codes = sel
        .codes
        .iter()
        .copied()
        .filter(|&k| {
            let c = morton_decode(k).as_ivec3();
            FACES.iter().all(|&o| {
                let p = c + o;
                p.min_element() >= 0 && sel.contains(p.as_uvec3())
            })
        })
        .collect();
    VoxelSelection::from_sorted(codes)
}

/// Empties the selected voxels (normals of their neighbours re-estimated).
pub fn delete(svo: &mut Svo, sel: &VoxelSelection) -> ToolEdit {
    let changes = sel.iter().map(|c| (c, None)).collect();
    commit(svo, changes, false, Normals::All, 0)
}

/// Recolours the selected solid voxels with the ink's colour and material.
pub fn fill(svo: &mut Svo, sel: &VoxelSelection, ink: Ink) -> ToolEdit {
    let mut edit = ToolEdit::default();
    let Some((lo, hi)) = sel.bounds() else {
        return edit;
    };
    // The walk is in Morton order, so the cursor scans the selection once.
    let mut cursor = sel.cursor();
    if let Ok(r) = svo.edit_existing(lo, hi, |c, v| {
        Some(if cursor.contains(c) {
            Voxel {
                color: ink.color,
                material: ink.material,
                ..v
            }
        } else {
            v
        })
    }) {
        edit.absorb(r);
    }
    edit
}

/// Copied voxels relative to the copied selection's minimum corner.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Clipboard {
    /// `(offset from the selection's minimum corner, voxel)` in Morton order of the source.
    pub voxels: Vec<(UVec3, Voxel)>,
    /// The selection's bounding box size.
    pub size: UVec3,
    /// Whether the voxels carry skin weights.
    pub has_skin: bool,
}

/// The selected solid voxels, relative to the selection's minimum corner.
#[must_use]
pub fn copy(svo: &Svo, sel: &VoxelSelection) -> Clipboard {
    let Some((lo, hi)) = sel.bounds() else {
        return Clipboard {
            has_skin: svo.has_skin(),
            ..Clipboard::default()
        };
    };
    let mut voxels = Vec::new();
    svo.for_each_leaf_in(lo, hi, |c, v| {
        if sel.contains(c) {
            voxels.push((c - lo, v));
        }
    });
    Clipboard {
        voxels,
        size: hi - lo + 1,
        has_skin: svo.has_skin(),
    }
}

/// Where each clipboard voxel lands with the minimum corner at `at` (for the preview).
#[must_use]
pub fn paste_cells(clip: &Clipboard, at: IVec3) -> Vec<IVec3> {
    clip.voxels
        .iter()
        .map(|(r, _)| at.saturating_add(r.as_ivec3()))
        .collect()
}

fn shifted(at: IVec3, r: UVec3) -> I64Vec3 {
    at.as_i64vec3() + r.as_i64vec3()
}

fn i64_in_volume(p: I64Vec3, size: UVec3) -> Option<UVec3> {
    (p.min_element() >= 0 && p.cmplt(size.as_i64vec3()).all()).then(|| p.as_uvec3())
}

/// Writes the clipboard with its minimum corner at `at` (may be negative / hang out: clipped
/// and counted). `over_empty_only`: keep existing voxels (else replace). Normals of the pasted
/// voxels and their neighbours are re-estimated; a skinless clipboard pasted into a skinned
/// model takes skin from the nearest voxels.
pub fn paste(
    svo: &mut Svo,
    size: UVec3,
    clip: &Clipboard,
    at: IVec3,
    over_empty_only: bool,
) -> ToolEdit {
    if clip.voxels.len() as u64 > MAX_EDIT_CELLS {
        return ToolEdit {
            refused: Some(ToolError::TooManyCells {
                cells: clip.voxels.len() as u64,
                limit: MAX_EDIT_CELLS,
            }),
            ..ToolEdit::default()
        };
    }
    let size = clamp_size(svo, size);
    let mut clipped = 0u64;
    let borrow_skin = svo.has_skin() && !clip.has_skin;
    if !borrow_skin {
        return commit_shifted(
            svo,
            &clip.voxels,
            at.as_i64vec3(),
            size,
            over_empty_only,
            Normals::All,
        );
    }
    let mut changes = Vec::with_capacity(clip.voxels.len());
    for &(r, v) in &clip.voxels {
        match i64_in_volume(shifted(at, r), size) {
            Some(c) => {
                let v = if borrow_skin {
                    Voxel {
                        skin: nearest_skin(svo, c),
                        ..v
                    }
                } else {
                    v
                };
                changes.push((c, Some(v)));
            }
            None => clipped += 1,
        }
    }
    commit(svo, changes, over_empty_only, Normals::All, clipped)
}

/// A selection edit: move, mirror in place, or quarter-turn rotation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SelTransform {
    /// Translate by whole voxels.
    Move(IVec3),
    /// Mirror along an axis (0..3) about the selection's bounds.
    Flip(usize),
    /// Quarter turns about an axis (0..3) through the pivot.
    Rotate {
        /// 0 = X, 1 = Y, 2 = Z.
        axis: usize,
        /// Positive: counter-clockwise looking down +axis (right-handed).
        quarter_turns: i32,
    },
}

/// One right-handed quarter turn about `axis` (x→y for Z, y→z for X, z→x for Y).
fn quarter<T: Copy + std::ops::Neg<Output = T>>(v: [T; 3], axis: usize) -> [T; 3] {
    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut out = v;
    out[u] = -v[w];
    out[w] = v[u];
    out
}

/// Where [`transform_selection`] puts cell `c` of a selection spanning `lo..=hi`.
fn placement(lo: UVec3, hi: UVec3, t: SelTransform, pivot2: IVec3) -> impl Fn(UVec3) -> I64Vec3 {
    let (lo, hi) = (lo.as_i64vec3(), hi.as_i64vec3());
    move |c: UVec3| -> I64Vec3 {
        let c = c.as_i64vec3();
        match t {
            SelTransform::Move(d) => c + d.as_i64vec3(),
            SelTransform::Flip(a) => {
                let mut p = c;
                p[a] = lo[a] + hi[a] - c[a];
                p
            }
            SelTransform::Rotate {
                axis,
                quarter_turns,
            } => {
                let p2 = pivot2.as_i64vec3();
                let mut d = (c * 2 + 1 - p2).to_array();
                for _ in 0..quarter_turns.rem_euclid(4) {
                    d = quarter(d, axis);
                }
                (I64Vec3::from_array(d) + p2 - 1).div_euclid(I64Vec3::splat(2))
            }
        }
    }
}

/// Where [`transform_selection`] would put every cell of `sel` (before clipping to the
/// volume): the cells of a flip, move or quarter turn about `pivot2`, outside the volume or
/// not. Empty for an empty selection or a bad axis.
#[must_use]
pub fn transformed_cells(sel: &VoxelSelection, t: SelTransform, pivot2: IVec3) -> Vec<I64Vec3> {
    let Some((lo, hi)) = sel.bounds() else {
        return Vec::new();
    };
    let bad_axis = match t {
        SelTransform::Move(_) => false,
        SelTransform::Flip(a) | SelTransform::Rotate { axis: a, .. } => a >= 3,
    };
    if bad_axis {
        return Vec::new();
    }
    let place = placement(lo, hi, t, pivot2);
    sel.iter().map(place).collect()
}

/// Moves the selected voxels (cut + write transformed); returns the edit and the transformed
/// selection. Flip is about the selection's bounds (lo+hi-c): flip twice = identity. Rotate is
/// about `pivot2` (doubled coordinates, from [`rotation_pivot`]; keep it for successive turns of
/// the same selection), right-handed, positive = counter-clockwise looking down +axis; rotating
/// 4 times = identity exactly; cells leaving the volume are clipped and counted. Voxel normals
/// are rotated/flipped with the voxels; the neighbours' normals are re-estimated. An axis
/// outside 0..3 changes nothing.
pub fn transform_selection(
    svo: &mut Svo,
    size: UVec3,
    sel: &VoxelSelection,
    t: SelTransform,
    pivot2: IVec3,
) -> (ToolEdit, VoxelSelection) {
    let Some((lo, hi)) = sel.bounds() else {
        return (ToolEdit::default(), VoxelSelection::default());
    };
    let bad_axis = match t {
        SelTransform::Move(_) => false,
        SelTransform::Flip(a) | SelTransform::Rotate { axis: a, .. } => a >= 3,
    };
    if bad_axis {
        return (ToolEdit::default(), sel.clone());
    }
    let size = clamp_size(svo, size);
    let place = placement(lo, hi, t, pivot2);
    let turn = |n: Vec3| -> Vec3 {
        match t {
            SelTransform::Move(_) => n,
            SelTransform::Flip(a) => {
                let mut m = n;
                m[a] = -n[a];
                m
            }
            SelTransform::Rotate {
                axis,
                quarter_turns,
            } => {
                let mut d = n.to_array();
                for _ in 0..quarter_turns.rem_euclid(4) {
                    d = quarter(d, axis);
                }
                Vec3::from_array(d)
            }
        }
    };
    let mut moved = Vec::new();
    svo.for_each_leaf_in(lo, hi, |c, v| {
        if sel.contains(c) {
            moved.push((c, v));
        }
    });
    let mut clipped = 0u64;
    let mut changes: Vec<(UVec3, Option<Voxel>)> = moved.iter().map(|&(c, _)| (c, None)).collect();
    let mut new_cells = Vec::with_capacity(moved.len());
    for &(c, v) in &moved {
        match i64_in_volume(place(c), size) {
            Some(p) => {
                // An interior voxel has no normal to turn.
                let normal = if matches!(t, SelTransform::Move(_)) || v.is_interior() {
                    v.normal
                } else {
                    encode_normal(turn(decode_normal(v.normal)))
                };
                changes.push((p, Some(Voxel { normal, ..v })));
                new_cells.push(p);
            }
            None => clipped += 1,
        }
    }
    let edit = commit(svo, changes, false, Normals::Others, clipped);
    (edit, VoxelSelection::from_cells(new_cells))
}

/// Doubled-coordinate pivot for rotating `bounds` about `axis` that keeps voxel centres on
/// the grid (the bounds' centre, nudged by half a voxel on one axis when the parities differ).
#[must_use]
pub fn rotation_pivot(lo: UVec3, hi: UVec3, axis: usize) -> IVec3 {
    let mut p = (lo.min(hi) + lo.max(hi) + 1).as_ivec3();
    let axis = axis.min(2);
    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
    // A quarter turn maps doubled u to -(w - pw) + pu: that stays odd (a cell centre) only
    // when pu and pw have the same parity.
    if (p[u] - p[w]).rem_euclid(2) == 1 {
        p[w] += 1;
    }
    p
}

/// Deletes every solid voxel not in `sel` (refused past [`super::MAX_LISTED_VOXELS`]).
pub fn crop_to(svo: &mut Svo, sel: &VoxelSelection) -> ToolEdit {
    if let Err(e) = check_listable(svo, "Crop to selection") {
        return ToolEdit::refused(e, 0);
    }
    let mut changes = Vec::new();
    svo.for_each_leaf(|c, _| {
        if !sel.contains(c) {
            changes.push((c, None));
        }
    });
    commit(svo, changes, false, Normals::All, 0)
}

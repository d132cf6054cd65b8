//! Whole-model operations: new models, canvas resize, shift, mirror, hollow, fill interior.
//!
//! Resize and new models build a fresh octree (the editor keeps the old one for undo); the
//! others are ordinary tool edits with one undo delta.

use glam::{IVec3, UVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::nearest_skin;
use super::normal_from;
use super::shapes::{
    DENSE_LIMIT, Grid, Ink, MAX_EDIT_CELLS, Normals, ToolEdit, ToolError, box_cells,
    check_listable, clamp_size, commit,
};
use crate::svo::{MAX_DEPTH, Svo, Voxel, decode_normal, encode_normal};

/// Where the content stays when the canvas changes size, per axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Anchor {
    /// Content keeps its coordinates; the canvas grows or shrinks at the far side.
    #[default]
    Min,
    /// Content stays centred (an odd difference puts the extra voxel at the far side).
    Center,
    /// Content keeps its distance to the far side.
    Max,
}

/// A resized model.
#[derive(Debug, Clone)]
pub struct Resized {
    /// The new octree (deep enough for the new size).
    pub svo: Svo,
    /// Added to every voxel coordinate.
    pub offset: IVec3,
    /// Voxels that fell outside the new volume.
    pub dropped: u64,
}

/// Smallest octree depth whose extent holds `size` on every axis (at least 1).
///
/// # Errors
/// [`ToolError::EmptySize`] for a zero axis, [`ToolError::ExtentTooLarge`] beyond 2^21.
pub fn depth_for(size: UVec3) -> Result<u8, ToolError> {
    if size.min_element() == 0 {
        return Err(ToolError::EmptySize {
            size: size.to_array(),
        });
    }
    let limit = 1u32 << MAX_DEPTH;
    if size.max_element() > limit {
        return Err(ToolError::ExtentTooLarge {
            size: size.to_array(),
            limit,
        });
    }
    let m = size.max_element();
    Ok(((32 - (m - 1).leading_zeros()) as u8).max(1))
}

/// Grows/shrinks the volume to `new_size` about `anchor`: returns a new Svo (the smallest depth
/// holding `new_size`, up to MAX_DEPTH; error naming the limit beyond), the offset applied to
/// the content (`Center` rounds down), and how many voxels fell outside and were dropped.
/// Whole-model replacement (the editor keeps the old octree for undo).
///
/// # Errors
/// See [`depth_for`]; [`ToolError::TooManyVoxels`] past [`super::MAX_LISTED_VOXELS`].
pub fn resize_canvas(
    svo: &Svo,
    size: UVec3,
    new_size: UVec3,
    anchor: [Anchor; 3],
) -> Result<Resized, ToolError> {
    let depth = depth_for(new_size)?;
    check_listable(svo, "Resize canvas")?;
    let size = clamp_size(svo, size);
    let mut offset = IVec3::ZERO;
    for a in 0..3 {
        let diff = new_size[a] as i32 - size[a] as i32;
        offset[a] = match anchor[a] {
            Anchor::Min => 0,
            Anchor::Center => diff.div_euclid(2),
            Anchor::Max => diff,
        };
    }
    let mut dropped = 0u64;
    let mut kept = Vec::with_capacity(svo.leaf_count() as usize);
    svo.for_each_leaf(|c, v| {
        let p = c.as_ivec3() + offset;
        if p.min_element() >= 0 && p.as_uvec3().cmplt(new_size).all() {
            kept.push((p.as_uvec3(), v));
        } else {
            dropped += 1;
        }
    });
    // Every kept coordinate is inside new_size <= the new extent.
    let mut built =
        Svo::from_voxels(depth, svo.has_skin(), kept).map_err(|_| ToolError::ExtentTooLarge {
            size: new_size.to_array(),
            limit: 1 << MAX_DEPTH,
        })?;
    // The crop may cut through an interior: what it opens shows what carving it would.
    built.settle_interior_from(Some((svo, -offset)));
    Ok(Resized {
        svo: built,
        offset,
        dropped,
    })
}

/// Moves every voxel of the volume by `offset`; `wrap`: around the volume (a torus), else the
/// voxels leaving it are dropped and counted in `clipped`. Moved voxels keep their normals (a
/// rigid move); voxels next to what moved are re-estimated.
pub fn shift_content(svo: &mut Svo, size: UVec3, offset: IVec3, wrap: bool) -> ToolEdit {
    let size = clamp_size(svo, size);
    if size.min_element() == 0 {
        return ToolEdit::default();
    }
    if let Err(e) = check_listable(svo, "Shift content") {
        return ToolEdit::refused(e, 0);
    }
    let s = size.as_i64vec3();
    let mut clipped = 0u64;
    let mut moved = Vec::new();
    svo.for_each_leaf_in(UVec3::ZERO, size - 1, |c, v| moved.push((c, v)));
    let mut changes: Vec<(UVec3, Option<Voxel>)> = moved.iter().map(|&(c, _)| (c, None)).collect();
    for (c, v) in moved {
        let mut p = c.as_i64vec3() + offset.as_i64vec3();
        if wrap {
            p = p.rem_euclid(s);
        }
        if p.min_element() >= 0 && p.cmplt(s).all() {
            changes.push((p.as_uvec3(), Some(v)));
        } else {
            clipped += 1;
        }
    }
    commit(svo, changes, false, Normals::Others, clipped)
}

/// Mirrors the volume's content across its centre along `axis` (cell c → size-1-c); normals
/// flip with the voxels. An axis outside 0..3 changes nothing.
pub fn mirror_model(svo: &mut Svo, size: UVec3, axis: usize) -> ToolEdit {
    let size = clamp_size(svo, size);
    if axis >= 3 || size.min_element() == 0 {
        return ToolEdit::default();
    }
    if let Err(e) = check_listable(svo, "Mirror model") {
        return ToolEdit::refused(e, 0);
    }
    let mut moved = Vec::new();
    svo.for_each_leaf_in(UVec3::ZERO, size - 1, |c, v| moved.push((c, v)));
    let mut changes: Vec<(UVec3, Option<Voxel>)> = moved.iter().map(|&(c, _)| (c, None)).collect();
    for (c, v) in moved {
        let mut p = c;
        p[axis] = size[axis] - 1 - c[axis];
        if v.is_interior() {
            // No normal to mirror.
            changes.push((p, Some(v)));
            continue;
        }
        let mut n = decode_normal(v.normal);
        n[axis] = -n[axis];
        changes.push((
            p,
            Some(Voxel {
                normal: encode_normal(n),
                ..v
            }),
        ));
    }
    commit(svo, changes, false, Normals::Others, 0)
}

const FACES: [IVec3; 6] = [
    IVec3::NEG_X,
    IVec3::X,
    IVec3::NEG_Y,
    IVec3::Y,
    IVec3::NEG_Z,
    IVec3::Z,
];

/// The grid over the model's solid voxels inside the volume, with a 0/1 solid map.
fn solid_grid(
    svo: &Svo,
    size: UVec3,
    what: &'static str,
) -> Result<Option<(Grid, Vec<u8>)>, ToolError> {
    let size = clamp_size(svo, size);
    let Some((lo, hi)) = svo.bounds() else {
        return Ok(None);
    };
    if size.min_element() == 0 || lo.cmpge(size).any() {
        return Ok(None);
    }
    let g = Grid::new(lo, hi.min(size - 1));
    if g.cells() > DENSE_LIMIT {
        return Err(ToolError::RegionTooLarge {
            what,
            cells: g.cells(),
            limit: DENSE_LIMIT,
        });
    }
    let mut m = vec![0u8; g.cells() as usize];
    svo.for_each_leaf_in(g.lo, g.hi(), |c, _| m[g.idx(c)] = 1);
    Ok(Some((g, m)))
}

/// Keeps the voxels within `shell` (at least 1) 6-steps of an empty cell or the volume's
/// outside and removes the rest (normals of the new inner surface re-estimated).
pub fn hollow(svo: &mut Svo, size: UVec3, shell: u32) -> ToolEdit {
    let shell = shell.max(1);
    let (g, m) = match solid_grid(svo, size, "hollow") {
        Ok(Some(x)) => x,
        Ok(None) => return ToolEdit::default(),
        Err(e) => {
            return ToolEdit {
                refused: Some(e),
                ..ToolEdit::default()
            };
        }
    };
    // Cells outside the grid are empty or outside the volume: both count as empty here.
    let solid = |c: UVec3, o: IVec3| g.neighbour(c, o).is_some_and(|j| m[j] != 0);
    let mut dist = vec![0u32; m.len()];
    let mut frontier = Vec::new();
    for (i, &s) in m.iter().enumerate() {
        if s != 0 {
            let c = g.coord(i);
            if FACES.iter().any(|&o| !solid(c, o)) {
                dist[i] = 1;
                frontier.push(i);
            }
        }
    }
    for d in 2..=shell {
        let mut next = Vec::new();
        for &i in &frontier {
            let c = g.coord(i);
            for o in FACES {
                if let Some(j) = g.neighbour(c, o)
                    && m[j] != 0
                    && dist[j] == 0
                {
                    dist[j] = d;
                    next.push(j);
                }
            }
        }
        if next.is_empty() {
            break;
        }
        frontier = next;
    }
    let changes = (0..m.len())
        .filter(|&i| m[i] != 0 && dist[i] == 0)
        .map(|i| (g.coord(i), None))
        .collect();
    commit(svo, changes, false, Normals::All, 0)
}

/// Fills the empty cells not 6-connected to the outside of the volume (closed cavities); ink
/// None = the colour and material of the nearest solid voxel (spread from the cavity's walls).
pub fn fill_interior(svo: &mut Svo, size: UVec3, ink: Option<Ink>) -> ToolEdit {
    let (g, m) = match solid_grid(svo, size, "fill interior") {
        Ok(Some(x)) => x,
        Ok(None) => return ToolEdit::default(),
        Err(e) => {
            return ToolEdit {
                refused: Some(e),
                ..ToolEdit::default()
            };
        }
    };
    let cells = m.len();
    // Every empty cell outside the grid reaches the volume's outside (it lies beyond the
    // model's bounds along some axis and can walk straight to the volume's face along
    // another), so the outside seeps in through the grid's boundary.
    let mut outside = vec![false; cells];
    let mut stack = Vec::new();
    for i in 0..cells {
        let c = g.coord(i);
        if m[i] == 0 && FACES.iter().any(|&o| g.neighbour(c, o).is_none()) {
            outside[i] = true;
            stack.push(i);
        }
    }
    while let Some(i) = stack.pop() {
        let c = g.coord(i);
        for o in FACES {
            if let Some(j) = g.neighbour(c, o)
                && m[j] == 0
                && !outside[j]
            {
                outside[j] = true;
                stack.push(j);
            }
        }
    }
    let cavity = |i: usize| m[i] == 0 && !outside[i];
    let mut fill: Vec<Option<Voxel>> = vec![None; cells];
    match ink {
        Some(ink) => {
            for (i, f) in fill.iter_mut().enumerate() {
                if cavity(i) {
                    *f = Some(Voxel {
                        color: ink.color,
                        normal: encode_normal(Vec3::Y),
                        material: ink.material,
                        skin: nearest_skin(svo, g.coord(i)),
                    });
                }
            }
        }
        None => {
            // Breadth-first from the walls: each cell copies the voxel it was reached from.
            let mut frontier = Vec::new();
            for (i, f) in fill.iter_mut().enumerate() {
                if !cavity(i) {
                    continue;
                }
                let c = g.coord(i);
                let donor = FACES.iter().find_map(|&o| {
                    g.neighbour(c, o)
                        .filter(|&j| m[j] != 0)
                        .and_then(|j| svo.get(g.coord(j)))
                });
                if let Some(d) = donor {
                    *f = Some(Voxel {
                        skin: nearest_skin(svo, c),
                        ..d
                    });
                    frontier.push(i);
                }
            }
            while !frontier.is_empty() {
                let mut next = Vec::new();
                for &i in &frontier {
                    let c = g.coord(i);
                    for o in FACES {
                        if let Some(j) = g.neighbour(c, o)
                            && cavity(j)
                            && fill[j].is_none()
                        {
                            fill[j] = fill[i];
                            next.push(j);
                        }
                    }
                }
                frontier = next;
            }
        }
    }
    let changes = fill
        .iter()
        .enumerate()
        .filter_map(|(i, v)| v.map(|v| (g.coord(i), Some(v))))
        .collect();
    commit(svo, changes, true, Normals::All, 0)
}

/// A new model's initial content.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum InitialFill {
    /// Nothing.
    #[default]
    Empty,
    /// The bottom `height` layers (y < height) of the volume.
    GroundSlab {
        /// Layers.
        height: u32,
    },
    /// The whole volume.
    SolidBox,
}

/// A new model's octree: the smallest depth holding `size` (extent per axis up to 2^21), filled
/// with `ink` per `fill`, normals estimated from the fill's shape.
///
/// # Errors
/// See [`depth_for`]; [`ToolError::TooManyCells`] when the fill exceeds [`MAX_EDIT_CELLS`].
pub fn new_model(size: UVec3, fill: InitialFill, ink: Ink) -> Result<Svo, ToolError> {
    let depth = depth_for(size)?;
    let hi = match fill {
        InitialFill::Empty => return Svo::new(depth, false).map_err(|_| unreachable_depth(size)),
        InitialFill::GroundSlab { height } => {
            if height == 0 {
                return Svo::new(depth, false).map_err(|_| unreachable_depth(size));
            }
            UVec3::new(size.x, height.min(size.y), size.z)
        }
        InitialFill::SolidBox => size,
    };
    let cells = box_cells(hi);
    if cells > MAX_EDIT_CELLS {
        return Err(ToolError::TooManyCells {
            cells,
            limit: MAX_EDIT_CELLS,
        });
    }
    let inside = |p: IVec3| p.min_element() >= 0 && p.as_uvec3().cmplt(hi).all();
    Svo::from_fn(
        depth,
        false,
        |o, s| o.cmplt(hi).all() && s > 0,
        |c| {
            inside(c.as_ivec3()).then(|| Voxel {
                color: ink.color,
                normal: encode_normal(normal_from(|o| inside(c.as_ivec3() + o))),
                material: ink.material,
                skin: Default::default(),
            })
        },
    )
    .map_err(|_| unreachable_depth(size))
}

/// `depth_for` accepted the size, so the octree cannot refuse its depth; kept as an error
/// rather than a panic.
fn unreachable_depth(size: UVec3) -> ToolError {
    ToolError::ExtentTooLarge {
        size: size.to_array(),
        limit: 1 << MAX_DEPTH,
    }
}

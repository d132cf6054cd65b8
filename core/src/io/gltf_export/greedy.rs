//! Voxel model → quads: only faces between a solid and an empty voxel, merged greedily into
//! rectangles of one (colour, material, joint weights) per slice.
//!
//! Work and memory follow the exposed faces, never the model's bounding box: solid neighbours
//! are found by binary search in the octree's Morton-ordered leaf codes, and each slice is
//! merged from a hash map of its own faces. So a depth-21 model (2^21 voxels wide) costs what
//! its surface costs.

use std::collections::HashMap;

use glam::{UVec3, Vec3};

use crate::svo::{Skin4, Svo, morton_encode};

/// One exposed face: the voxel it belongs to faces empty space across `axis` in direction
/// `positive`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Face {
    /// Which slice: axis, direction and the plane's coordinate along the axis.
    slice: (u8, bool, u32),
    /// Position in the slice: coordinates along the slice's u and v axes.
    v: u32,
    u: u32,
    key: FaceKey,
    skin: Skin4,
}

/// What must match for two faces to merge: sRGB colour and material id.
pub type FaceKey = ([u8; 4], u8);

/// A merged rectangle on a voxel-grid plane, in voxel units.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Quad {
    /// 0 = x, 1 = y, 2 = z: the axis the quad faces along.
    pub axis: u8,
    /// Whether the outward normal is `+axis`.
    pub positive: bool,
    /// Plane coordinate along `axis` (voxel corner units).
    pub layer: u32,
    /// Minimum corner along the slice's u axis (`(axis + 1) % 3`).
    pub u: u32,
    /// Minimum corner along the slice's v axis (`(axis + 2) % 3`).
    pub v: u32,
    /// Extent along u, in voxels (≥ 1).
    pub width: u32,
    /// Extent along v, in voxels (≥ 1).
    pub height: u32,
    /// Colour and material shared by every face in the quad.
    pub key: FaceKey,
    /// Joint weights shared by every face in the quad (the empty skin for static models), so a
    /// skinned export moves each quad with exactly its voxels' blend.
    pub skin: Skin4,
}

impl Quad {
    /// The four corners in voxel units, counter-clockwise seen from outside (the side the
    /// normal points to), so glTF's front faces point out of the solid.
    #[must_use]
    pub fn corners(&self) -> [Vec3; 4] {
        let a = usize::from(self.axis);
        let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
        let at = |u: u32, v: u32| {
            let mut p = Vec3::ZERO;
            p[a] = self.layer as f32;
            p[ua] = u as f32;
            p[va] = v as f32;
            p
        };
        let (u0, v0) = (self.u, self.v);
        let (u1, v1) = (self.u + self.width, self.v + self.height);
        // e_u × e_v = e_axis for the cyclic (axis, u, v), so this order faces +axis.
        let ccw = [at(u0, v0), at(u1, v0), at(u1, v1), at(u0, v1)];
        if self.positive {
            ccw
        } else {
            [ccw[0], ccw[3], ccw[2], ccw[1]]
        }
    }

    /// Unit outward normal.
    #[must_use]
    pub fn normal(&self) -> Vec3 {
        let mut n = Vec3::ZERO;
        n[usize::from(self.axis)] = if self.positive { 1.0 } else { -1.0 };
        n
    }
}

/// Sorted Morton codes of the solid voxels: `contains` is a binary search.
struct Occupancy {
    codes: Vec<u64>,
    extent: u32,
}

impl Occupancy {
    fn new(svo: &Svo) -> Self {
        let mut codes = Vec::with_capacity(svo.leaf_count() as usize);
        svo.for_each_leaf(|c, _| codes.push(morton_encode(c)));
        // Leaves come in Morton order already; sorting keeps this correct if that changes.
        if !codes.is_sorted() {
            codes.sort_unstable();
        }
        Self {
            codes,
            extent: svo.extent(),
        }
    }

    /// Whether the neighbour of `c` one step along `axis` (`positive` or not) is solid.
    fn neighbour_solid(&self, c: UVec3, axis: usize, positive: bool) -> bool {
        let mut n = c;
        if positive {
            if n[axis] + 1 >= self.extent {
                return false;
            }
            n[axis] += 1;
        } else {
            if n[axis] == 0 {
                return false;
            }
            n[axis] -= 1;
        }
        self.codes.binary_search(&morton_encode(n)).is_ok()
    }
}

/// Number of faces between a solid and an empty voxel (what a per-face cube export writes,
/// two triangles each). Allocates only the sorted leaf codes.
#[must_use]
pub fn count_exposed_faces(svo: &Svo) -> u64 {
    let occ = Occupancy::new(svo);
    let mut n = 0u64;
    svo.for_each_leaf(|c, _| {
        for axis in 0..3 {
            for positive in [false, true] {
                if !occ.neighbour_solid(c, axis, positive) {
                    n += 1;
                }
            }
        }
    });
    n
}

/// Greedy meshing: the exposed faces of `svo` merged into the fewest rectangles this simple
/// scan finds (per slice, faces in (v, u) order; each unused face grows first along u, then
/// along v while the whole row matches). Only faces of equal (colour, material, skin) merge.
///
/// The caller should check [`count_exposed_faces`] against its limits first: this allocates
/// about 24 bytes per exposed face.
#[must_use]
pub fn greedy_quads(svo: &Svo) -> Vec<Quad> {
    let occ = Occupancy::new(svo);
    let mut faces: Vec<Face> = Vec::new();
    svo.for_each_leaf(|c, voxel| {
        let key = (voxel.color, voxel.material);
        for axis in 0..3usize {
            for positive in [false, true] {
                if occ.neighbour_solid(c, axis, positive) {
                    continue;
                }
                let layer = if positive { c[axis] + 1 } else { c[axis] };
                faces.push(Face {
                    slice: (axis as u8, positive, layer),
                    v: c[(axis + 2) % 3],
                    u: c[(axis + 1) % 3],
                    key,
                    skin: voxel.skin,
                });
            }
        }
    });
    drop(occ);
    faces.sort_unstable_by_key(|f| (f.slice, f.v, f.u));

    let mut quads = Vec::new();
    let mut start = 0;
    while start < faces.len() {
        let slice = faces[start].slice;
        let end = start + faces[start..].partition_point(|f| f.slice == slice);
        merge_slice(&faces[start..end], &mut quads);
        start = end;
    }
    quads
}

/// Greedy rectangles over one slice's faces (sorted by v, then u).
fn merge_slice(faces: &[Face], out: &mut Vec<Quad>) {
    let at: HashMap<(u32, u32), usize> = faces
        .iter()
        .enumerate()
        .map(|(i, f)| ((f.u, f.v), i))
        .collect();
    let mut used = vec![false; faces.len()];
    for i in 0..faces.len() {
        if used[i] {
            continue;
        }
        let f = faces[i];
        let free = |u: u32, v: u32, used: &[bool]| {
            at.get(&(u, v))
                .is_some_and(|&j| !used[j] && faces[j].key == f.key && faces[j].skin == f.skin)
        };
        let mut width = 1;
        while free(f.u + width, f.v, &used) {
            width += 1;
        }
        let mut height = 1;
        while (0..width).all(|du| free(f.u + du, f.v + height, &used)) {
            height += 1;
        }
        for dv in 0..height {
            for du in 0..width {
                if let Some(&j) = at.get(&(f.u + du, f.v + dv)) {
                    used[j] = true;
                }
            }
        }
        out.push(Quad {
            axis: f.slice.0,
            positive: f.slice.1,
            layer: f.slice.2,
            u: f.u,
            v: f.v,
            width,
            height,
            key: f.key,
            skin: f.skin,
        });
    }
}

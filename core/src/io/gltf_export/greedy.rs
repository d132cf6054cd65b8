//! Voxel model → quads: only the faces of solid voxels that look onto *outside* air, merged
//! greedily into rectangles per slice.
//!
//! * **Outside only.** A face toward a solid neighbour is never written, and neither is a face
//!   toward a sealed cavity: empty voxels that no six-connected path of empty voxels joins to
//!   the space around the model. A surface-voxelized import (the default for skinned glTF) is
//!   a closed shell around an empty inside; the inner walls of that shell can never be seen,
//!   would double the triangles, and when skinned could poke through the outer surface.
//! * **One weight set per corner.** On a skinned model every lattice corner of the surface gets
//!   the merged weights of all the solid voxels touching it ([`Skin4::merge`]: summed, the four
//!   strongest kept, renormalised; deterministic), the rule the renderer's `Corners` stretch
//!   strategy uses ([`SkinTables`](crate::skin::SkinTables)). Every vertex at one position then
//!   carries the same joints and weights, so the exported surface stays closed in any pose. A
//!   face carrying its voxel's own weights (as before issue 21) tore apart wherever neighbouring
//!   voxels differed.
//! * **Merges that keep the shape.** Faces merge only when they have the same colour and
//!   material and all four of their corners carry one and the same weight set. A merged quad then
//!   covers only lattice points with those weights, so skinning moves it as one rigid blend: its
//!   interior and edges land exactly where the unit faces would have, and a neighbour's vertex on
//!   its edge (a T-junction) lands on the skinned edge. Static models have no weights, so every
//!   face of one colour and material merges, as always.
//!
//! Work and memory follow the solid voxels and their surface, never the model's bounding box:
//! voxels are kept as sorted z-lists per (x, y) column, neighbours are binary searches, air is
//! classified per run of empty voxels between two solid ones in a column (union–find over the
//! runs that touch in neighbouring columns), and each slice is merged from a hash map of its own
//! faces. So a depth-21 model (2^21 voxels wide) costs what its voxels cost.

use std::collections::HashMap;
use std::ops::Range;

use glam::{UVec3, Vec3};

use crate::svo::{EnclosedTiles, Skin4, Svo};

/// One outward face: the voxel it belongs to faces outside air across `axis` in direction
/// `positive`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Face {
    /// Which slice: axis, direction and the plane's coordinate along the axis.
    slice: (u8, bool, u32),
    /// Position in the slice: coordinates along the slice's u and v axes.
    v: u32,
    u: u32,
    key: FaceKey,
    /// Weights at the face's lattice corners (u, v), (u + 1, v), (u + 1, v + 1), (u, v + 1).
    skins: [Skin4; 4],
}

impl Face {
    /// Whether all four corners carry the same weights (always, for a static model): only such
    /// faces can grow into a larger quad without changing the skinned shape.
    fn uniform(&self) -> bool {
        self.skins[1..].iter().all(|s| *s == self.skins[0])
    }
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
    /// Joint weights at the lattice corners (u, v), (u + w, v), (u + w, v + h), (u, v + h):
    /// the merged weights of the voxels touching each corner (the empty skin for static
    /// models). All four are equal whenever the quad is larger than one face.
    pub skins: [Skin4; 4],
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
        self.wound([at(u0, v0), at(u1, v0), at(u1, v1), at(u0, v1)])
    }

    /// The corners' weights in the order of [`Self::corners`].
    #[must_use]
    pub fn corner_skins(&self) -> [Skin4; 4] {
        self.wound(self.skins)
    }

    /// `ccw` (in (u, v) order, counter-clockwise around +axis) reordered to face outward.
    fn wound<T: Copy>(&self, ccw: [T; 4]) -> [T; 4] {
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

/// Faces of the solid voxels that look onto empty voxels, by where that empty voxel is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FaceCounts {
    /// Facing air joined to the space around the model: what the export writes.
    pub exposed: u64,
    /// Facing a sealed cavity (empty voxels enclosed by solid ones): left out.
    pub sealed: u64,
}

/// What lies across one face of a solid voxel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Across {
    Solid,
    /// Empty, and joined to the space around the model.
    Outside,
    /// Empty, inside a sealed cavity.
    Sealed,
}

/// The solid voxels as sorted z-lists per (x, y) column, with the empty runs between them
/// classified as outside air or sealed.
struct Solids {
    /// (x, y) of every column that holds a solid voxel, sorted.
    columns: Vec<(u32, u32)>,
    /// Column `i`'s voxels are `starts[i]..starts[i + 1]` in `zs` (and `skins`).
    starts: Vec<usize>,
    /// z of each solid voxel, ascending within a column.
    zs: Vec<u32>,
    /// Colour and material of each solid voxel.
    keys: Vec<FaceKey>,
    /// Weights of each solid voxel; empty for a model without skin.
    skins: Vec<Skin4>,
    /// `gap_outside[i]`: whether the empty run just above voxel `i` (up to the next solid voxel
    /// of its column) is joined to the outside. Unused where there is no such run.
    gap_outside: Vec<bool>,
    /// Enclosed interior tiles left out of the lists: solid, so a face toward one is toward a
    /// solid voxel, not a cavity.
    enclosed: EnclosedTiles,
    extent: u32,
}

/// Union–find with path halving: enough for one pass of unions then one of finds.
struct Sets(Vec<usize>);

impl Sets {
    fn find(&mut self, mut i: usize) -> usize {
        while self.0[i] != i {
            self.0[i] = self.0[self.0[i]];
            i = self.0[i];
        }
        i
    }

    fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            // The larger index wins, so the outside node (the last) stays a root.
            self.0[a.min(b)] = a.max(b);
        }
    }
}

impl Solids {
    fn new(svo: &Svo) -> Self {
        let with_skin = svo.has_skin();
        let mut voxels: Vec<(u32, u32, u32, FaceKey, Skin4)> = Vec::new();
        let push = |c: UVec3, v: crate::svo::Voxel| {
            voxels.push((c.x, c.y, c.z, (v.color, v.material), v.skin));
        };
        let enclosed = if with_skin {
            // Every voxel touching a corner gives it weights.
            svo.for_each_leaf(push);
            EnclosedTiles::default()
        } else {
            // A static solid's enclosed interior tiles write no face, and left out of the
            // lists they read as sealed cavities, which write none either: the same quads
            // from the surface alone ([`Self::for_each_face`] still calls them solid).
            svo.for_each_voxel_but_enclosed(push)
        };
        voxels.sort_unstable_by_key(|v| (v.0, v.1, v.2));
        let mut columns: Vec<(u32, u32)> = Vec::new();
        let mut starts = Vec::new();
        for (i, v) in voxels.iter().enumerate() {
            if columns.last() != Some(&(v.0, v.1)) {
                columns.push((v.0, v.1));
                starts.push(i);
            }
        }
        starts.push(voxels.len());
        let mut s = Self {
            columns,
            starts,
            zs: voxels.iter().map(|v| v.2).collect(),
            keys: voxels.iter().map(|v| v.3).collect(),
            skins: if with_skin {
                voxels.iter().map(|v| v.4).collect()
            } else {
                Vec::new()
            },
            gap_outside: Vec::new(),
            enclosed,
            extent: svo.extent(),
        };
        drop(voxels);
        s.classify_air();
        s
    }

    /// Voxel index range of column (x, y), if it holds any solid voxel.
    fn column(&self, x: u32, y: u32) -> Option<Range<usize>> {
        let i = self.columns.binary_search(&(x, y)).ok()?;
        Some(self.starts[i]..self.starts[i + 1])
    }

    /// The voxel ranges of the 3 × 3 columns around (x, y) (index `(dy + 1) * 3 + dx + 1`);
    /// `None` where a column is empty or past the grid's edge.
    fn neighbourhood(&self, x: u32, y: u32) -> Around {
        std::array::from_fn(|k| {
            let (dx, dy) = ((k % 3) as u32, (k / 3) as u32);
            let (nx, ny) = ((x + dx).checked_sub(1)?, (y + dy).checked_sub(1)?);
            if nx >= self.extent || ny >= self.extent {
                return None;
            }
            self.column(nx, ny)
        })
    }

    /// Fills `gap_outside`. The empty runs below a column's lowest and above its highest voxel
    /// reach the grid's edge, so they are outside; every other run is a node joined to the runs
    /// of the side columns it overlaps in z, or to the outside where a side column is empty or
    /// past the grid. Work: the runs and their overlaps, not the bounding box.
    fn classify_air(&mut self) {
        let outside = self.zs.len();
        let mut sets = Sets((0..=outside).collect());
        for (ci, &(x, y)) in self.columns.iter().enumerate() {
            let column = self.starts[ci]..self.starts[ci + 1];
            let around = self.neighbourhood(x, y);
            for i in column.start..column.end - 1 {
                let (a, b) = (self.zs[i] + 1, self.zs[i + 1]);
                if a == b {
                    continue;
                }
                // The run is z in a..b.
                for side in SIDES {
                    let Some(r) = around[side.2].clone() else {
                        sets.union(i, outside);
                        continue;
                    };
                    let zs = &self.zs[r.clone()];
                    // Runs of the side column: k = 0 below its first voxel, k = len above its
                    // last, else between voxels k − 1 and k.
                    let first = zs.partition_point(|&z| z < a);
                    let last = zs.partition_point(|&z| z < b);
                    for k in first..=last {
                        let lo = if k == 0 { 0 } else { zs[k - 1] + 1 };
                        let hi = zs.get(k).copied().unwrap_or(self.extent);
                        if lo.max(a) >= hi.min(b) {
                            continue;
                        }
                        if k == 0 || k == zs.len() {
                            sets.union(i, outside);
                        } else {
                            sets.union(i, r.start + k - 1);
                        }
                    }
                }
            }
        }
        let root = sets.find(outside);
        self.gap_outside = (0..outside).map(|i| sets.find(i) == root).collect();
    }

    /// What lies across the run of air above voxel `i` (its column's next voxel is not
    /// adjacent).
    fn gap(&self, i: usize) -> Across {
        if self.gap_outside[i] {
            Across::Outside
        } else {
            Across::Sealed
        }
    }

    /// Calls `f(voxel, index, axis, positive, across, around)` for all six faces of every
    /// solid voxel, column by column (`around`: [`Self::neighbourhood`] of its column).
    /// Neighbours along z are the column's own next entries; the neighbouring columns are found
    /// once per column and the side ones walked with a cursor (z only grows), so a face costs
    /// O(1) beyond eight binary searches per column.
    fn for_each_face(&self, mut f: impl FnMut(UVec3, usize, usize, bool, Across, &Around)) {
        // A "cavity" that is a left-out enclosed tile is solid.
        let mut f = |c: UVec3, i: usize, axis: usize, positive: bool, across, around: &Around| {
            let mut q = c;
            q[axis] = if positive {
                q[axis] + 1
            } else {
                q[axis].saturating_sub(1)
            };
            let across = if across == Across::Sealed && q != c && self.enclosed.contains(q) {
                Across::Solid
            } else {
                across
            };
            f(c, i, axis, positive, across, around);
        };
        for (ci, &(x, y)) in self.columns.iter().enumerate() {
            let r = self.starts[ci]..self.starts[ci + 1];
            let around = self.neighbourhood(x, y);
            let mut cursors = [0usize; 4];
            for i in r.clone() {
                let z = self.zs[i];
                let c = UVec3::new(x, y, z);
                let below = if i == r.start {
                    Across::Outside
                } else if self.zs[i - 1] + 1 == z {
                    Across::Solid
                } else {
                    self.gap(i - 1)
                };
                let above = if i + 1 == r.end {
                    Across::Outside
                } else if self.zs[i + 1] == z + 1 {
                    Across::Solid
                } else {
                    self.gap(i)
                };
                f(c, i, 2, false, below, &around);
                f(c, i, 2, true, above, &around);
                for (s, &(axis, positive, n)) in SIDES.iter().enumerate() {
                    let across = match &around[n] {
                        None => Across::Outside,
                        Some(sr) => {
                            let zs = &self.zs[sr.clone()];
                            let k = &mut cursors[s];
                            while *k < zs.len() && zs[*k] < z {
                                *k += 1;
                            }
                            if zs.get(*k) == Some(&z) {
                                Across::Solid
                            } else if *k == 0 || *k == zs.len() {
                                Across::Outside
                            } else {
                                self.gap(sr.start + *k - 1)
                            }
                        }
                    };
                    f(c, i, axis, positive, across, &around);
                }
            }
        }
    }

    /// The merged weights of the solid voxels touching lattice point `p` (up to eight), where
    /// `p` is a corner of a voxel in the column (x, y) whose neighbourhood `around` is.
    fn lattice_skin(&self, p: UVec3, (x, y): (u32, u32), around: &Around) -> Skin4 {
        let mut touching = [Skin4::default(); 8];
        let mut n = 0;
        for k in 0..4u32 {
            let (ex, ey) = (k & 1, k >> 1);
            // Column (p.x − ex, p.y − ey) is (x + dx − 1, y + dy − 1) with dx, dy in 0..=2.
            let (Some(dx), Some(dy)) =
                ((p.x + 1).checked_sub(x + ex), (p.y + 1).checked_sub(y + ey))
            else {
                continue;
            };
            let Some(r) = around.get((dy * 3 + dx) as usize).and_then(Clone::clone) else {
                continue;
            };
            let zs = &self.zs[r.clone()];
            for z in [p.z.checked_sub(1), Some(p.z)].into_iter().flatten() {
                if let Ok(k) = zs.binary_search(&z)
                    && let Some(&s) = self.skins.get(r.start + k)
                {
                    touching[n] = s;
                    n += 1;
                }
            }
        }
        Skin4::merge(&touching[..n])
    }
}

/// Voxel ranges of the 3 × 3 columns around one ([`Solids::neighbourhood`]).
type Around = [Option<Range<usize>>; 9];

/// The four side columns: (axis, positive, index in [`Around`]).
const SIDES: [(usize, bool, usize); 4] = [(0, false, 3), (0, true, 5), (1, false, 1), (1, true, 7)];

/// A multiplicative hash for grid coordinates: std's SipHash cost more than the rest of a
/// lattice-corner lookup, and these keys are not chosen by an attacker.
#[derive(Default, Clone, Copy)]
struct GridHash;

impl std::hash::BuildHasher for GridHash {
    type Hasher = GridHasher;

    fn build_hasher(&self) -> GridHasher {
        GridHasher(0)
    }
}

/// FxHash's mixing step over the key's words.
struct GridHasher(u64);

impl std::hash::Hasher for GridHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u32(u32::from(b));
        }
    }

    fn write_u32(&mut self, i: u32) {
        self.0 = (self.0.rotate_left(5) ^ u64::from(i)).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// Faces of the solid voxels toward empty voxels: those that look outside (what a per-face
/// cube export writes, two triangles each) and those that look into a sealed cavity (never
/// written). Allocates only the column index of the solid voxels.
#[must_use]
pub fn count_faces(svo: &Svo) -> FaceCounts {
    let mut n = FaceCounts::default();
    Solids::new(svo).for_each_face(|_, _, _, _, across, _| match across {
        Across::Outside => n.exposed += 1,
        Across::Sealed => n.sealed += 1,
        Across::Solid => {}
    });
    n
}

/// [`count_faces`]`.exposed`: the faces the export writes before merging.
#[must_use]
pub fn count_exposed_faces(svo: &Svo) -> u64 {
    count_faces(svo).exposed
}

/// Greedy meshing: the outward faces of `svo` merged into the fewest rectangles this simple
/// scan finds (per slice, faces in (v, u) order; each unused face grows first along u, then
/// along v while the whole row matches). Only faces of equal (colour, material) whose corners
/// all carry one weight set merge (see the module docs).
///
/// The caller should check [`count_faces`] against its limits first: this allocates about
/// 60 bytes per outward face.
#[must_use]
pub fn greedy_quads(svo: &Svo) -> Vec<Quad> {
    let solids = Solids::new(svo);
    let with_skin = svo.has_skin();
    // Each lattice corner is shared by up to 12 faces: merge its voxels' weights once.
    let mut lattice: HashMap<UVec3, Skin4, GridHash> = HashMap::default();
    let mut faces: Vec<Face> = Vec::new();
    solids.for_each_face(|c, i, axis, positive, across, around| {
        if across != Across::Outside {
            return;
        }
        let layer = if positive { c[axis] + 1 } else { c[axis] };
        let (ua, va) = ((axis + 1) % 3, (axis + 2) % 3);
        let skins = if with_skin {
            [(0, 0), (1, 0), (1, 1), (0, 1)].map(|(du, dv)| {
                let mut p = c;
                p[axis] = layer;
                p[ua] += du;
                p[va] += dv;
                *lattice
                    .entry(p)
                    .or_insert_with(|| solids.lattice_skin(p, (c.x, c.y), around))
            })
        } else {
            [Skin4::default(); 4]
        };
        faces.push(Face {
            slice: (axis as u8, positive, layer),
            v: c[va],
            u: c[ua],
            key: solids.keys[i],
            skins,
        });
    });
    drop(lattice);
    drop(solids);
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
    let at: HashMap<(u32, u32), usize, GridHash> = faces
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
        // A face whose corners disagree is skinned as its own two triangles: it stays 1 × 1.
        let grows = f.uniform();
        let free = |u: u32, v: u32, used: &[bool]| {
            grows
                && at.get(&(u, v)).is_some_and(|&j| {
                    let g = &faces[j];
                    !used[j] && g.key == f.key && g.uniform() && g.skins[0] == f.skins[0]
                })
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
            // Merged faces all carry `f`'s uniform weights, and so do the corners they cover.
            skins: f.skins,
        });
    }
}

//! Watertight iso-surfaces of sampled fields by marching tetrahedra over a sparse set of cells:
//! the KRS distance field (only cells near the surface are visited) and a smooth surface for
//! voxel models.
//!
//! # Why tetrahedra
//! Every cube is split into the six Kuhn tetrahedra around its main diagonal. The split is the
//! same in every cube, so neighbouring cubes cut their shared face along the same diagonal;
//! every tetrahedron face is then shared by exactly two tetrahedra, and the crossing segment on
//! it is an edge of exactly one triangle on each side. With the outermost lattice layer forced
//! outside, the mesh is closed and 2-manifold by construction: every edge belongs to exactly
//! two triangles, with opposite directions (consistent winding). Marching cubes needs face
//! disambiguation to get there; surface nets give non-manifold edges on ambiguous faces.
//!
//! Vertices are identified by their lattice edge (lower end point and a direction in
//! {0,1}³ \ 0: Kuhn edges only go "up"), so triangles from different cells share them exactly.

use glam::{DVec3, IVec3, Vec3};
use rayon::prelude::*;

/// Corner `k` of a unit cell is at offset (k & 1, k >> 1 & 1, k >> 2 & 1).
fn corner_offset(k: usize) -> IVec3 {
    IVec3::new((k & 1) as i32, ((k >> 1) & 1) as i32, ((k >> 2) & 1) as i32)
}

/// The six Kuhn tetrahedra of a cell, as corner indices: 0 → e_a → e_a + e_b → 7 for every
/// permutation (a, b, c) of the axes.
const KUHN: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// Largest lattice coordinate an edge key can hold (20 bits per axis).
pub const MAX_LATTICE: i32 = (1 << 20) - 1;

/// A lattice edge: lower end point (each coordinate in 0..=[`MAX_LATTICE`]) and direction bits.
fn edge_key(lower: IVec3, dir: usize) -> u64 {
    ((lower.x as u64) << 43) | ((lower.y as u64) << 23) | ((lower.z as u64) << 3) | dir as u64
}

/// The end points of an edge key.
#[must_use]
pub fn edge_ends(key: u64) -> (IVec3, IVec3) {
    let m = (1u64 << 20) - 1;
    let lower = IVec3::new(
        ((key >> 43) & m) as i32,
        ((key >> 23) & m) as i32,
        ((key >> 3) & m) as i32,
    );
    (lower, lower + corner_offset((key & 7) as usize))
}

/// An indexed triangle mesh in lattice coordinates.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IsoMesh {
    /// Vertex positions in lattice units (lattice point `p` is at `p`).
    pub positions: Vec<DVec3>,
    /// The lattice edge each vertex lies on ([`edge_ends`] decodes it).
    pub edges: Vec<u64>,
    /// Three indices per triangle, counter-clockwise seen from outside (positive values).
    pub indices: Vec<u32>,
}

impl IsoMesh {
    /// Number of triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// One triangle before vertices are shared: (edge key, position) per corner.
type LooseTriangle = [(u64, DVec3); 3];

/// Where the iso-surface crosses the edge between `a` (value `fa`) and `b` (value `fb`), which
/// have opposite signs. The parameter is kept 1% away from the ends so no triangle degenerates
/// when a sample is (nearly) zero; the surface moves by at most 1% of a cell.
fn crossing(a: IVec3, fa: f32, b: IVec3, fb: f32) -> DVec3 {
    let (fa, fb) = (f64::from(fa), f64::from(fb));
    let t = (fa / (fa - fb)).clamp(0.01, 0.99);
    let t = if t.is_nan() { 0.5 } else { t };
    a.as_dvec3() + (b - a).as_dvec3() * t
}

/// Marches the cells whose minimum corners are in `cells`; `values[c]` holds the 8 corner
/// values of cell `c` (negative = inside) in `corner_offset` order. Values of a lattice
/// point must be the same in every cell that has it.
///
/// # Panics
/// Never; cells outside `0..MAX_LATTICE` are skipped.
#[must_use]
pub fn march(cells: &[(IVec3, [f32; 8])]) -> IsoMesh {
    let loose: Vec<LooseTriangle> = cells
        .par_iter()
        .fold(Vec::new, |mut out, (cell, values)| {
            if cell.min_element() >= 0 && cell.max_element() < MAX_LATTICE {
                march_cell(*cell, values, &mut out);
            }
            out
        })
        .flatten_iter()
        .collect();
    share_vertices(&loose)
}

fn march_cell(cell: IVec3, values: &[f32; 8], out: &mut Vec<LooseTriangle>) {
    let inside = |k: usize| values[k] < 0.0;
    let all_in = (0..8).all(inside);
    let all_out = !(0..8).any(inside);
    if all_in || all_out {
        return;
    }
    for tet in &KUHN {
        let ins: Vec<usize> = tet.iter().copied().filter(|&k| inside(k)).collect();
        let outs: Vec<usize> = tet.iter().copied().filter(|&k| !inside(k)).collect();
        let vertex = |a: usize, b: usize| -> (u64, DVec3) {
            // Kuhn edges join corners whose offsets differ by a {0,1}³ vector; name the edge by
            // its lower end so both cells sharing it agree.
            let (lo, hi) = if a < b { (a, b) } else { (b, a) };
            let dir = hi & !lo;
            let (pa, pb) = (cell + corner_offset(a), cell + corner_offset(b));
            (
                edge_key(cell + corner_offset(lo), dir),
                crossing(pa, values[a], pb, values[b]),
            )
        };
        let point = |k: usize| (cell + corner_offset(k)).as_dvec3();
        match (ins.len(), outs.len()) {
            (1, 3) => {
                let i = ins[0];
                let tri = [vertex(i, outs[0]), vertex(i, outs[1]), vertex(i, outs[2])];
                out.push(oriented(tri, point(i), point(outs[0])));
            }
            (3, 1) => {
                let o = outs[0];
                let tri = [vertex(ins[0], o), vertex(ins[1], o), vertex(ins[2], o)];
                out.push(oriented(tri, point(ins[0]), point(o)));
            }
            (2, 2) => {
                let (i, j, k, l) = (ins[0], ins[1], outs[0], outs[1]);
                // ik → il → jl → jk is the crossing quad's boundary cycle.
                let (ik, il, jl, jk) = (vertex(i, k), vertex(i, l), vertex(j, l), vertex(j, k));
                out.push(oriented([ik, il, jl], point(i), point(k)));
                out.push(oriented([ik, jl, jk], point(i), point(k)));
            }
            _ => {}
        }
    }
}

/// Orders `tri` counter-clockwise seen from outside. Its plane cuts the segment from the
/// inside point `inner` to the outside point `outer` strictly between them (every triangle
/// here contains a crossing of such an edge and no tetrahedron is flat), so the sign of this
/// test never depends on rounding at a tie.
fn oriented(tri: LooseTriangle, inner: DVec3, outer: DVec3) -> LooseTriangle {
    let n = (tri[1].1 - tri[0].1).cross(tri[2].1 - tri[0].1);
    if n.dot(outer - inner) >= 0.0 {
        tri
    } else {
        [tri[0], tri[2], tri[1]]
    }
}

/// Merges vertices with the same lattice edge. Deterministic whatever the thread count: the
/// vertex list is sorted by edge key and triangles keep their cell order.
fn share_vertices(loose: &[LooseTriangle]) -> IsoMesh {
    let mut verts: Vec<(u64, DVec3)> = loose.iter().flatten().copied().collect();
    verts.par_sort_unstable_by_key(|v| v.0);
    verts.dedup_by_key(|v| v.0);
    let indices = loose
        .par_iter()
        .flat_map_iter(|tri| {
            tri.map(|(key, _)| verts.binary_search_by_key(&key, |v| v.0).unwrap_or(0) as u32)
        })
        .collect();
    IsoMesh {
        positions: verts.iter().map(|v| v.1).collect(),
        edges: verts.iter().map(|v| v.0).collect(),
        indices,
    }
}

/// Every edge of the mesh, undirected, with how many triangles use it; and the number of
/// directed edges used more than once (a winding inconsistency). For watertightness tests.
#[must_use]
pub fn edge_use(indices: &[u32]) -> (std::collections::HashMap<(u32, u32), u32>, usize) {
    let mut undirected = std::collections::HashMap::new();
    let mut directed = std::collections::HashMap::new();
    for t in indices.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *undirected.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
            *directed.entry((a, b)).or_insert(0u32) += 1;
        }
    }
    let repeated = directed.values().filter(|&&n| n > 1).count();
    (undirected, repeated)
}

/// Area-weighted vertex normals of a triangle mesh (unit, or +Y where undefined).
#[must_use]
pub fn vertex_normals(positions: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    let mut acc = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0] as usize, t[1] as usize, t[2] as usize];
        let n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        for i in [a, b, c] {
            acc[i] += n;
        }
    }
    acc.into_iter()
        .map(|n| n.try_normalize().unwrap_or(Vec3::Y))
        .collect()
}

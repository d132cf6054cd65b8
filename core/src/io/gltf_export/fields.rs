//! The fields [`super::iso::march`] meshes: the KRS distance field (cells found by pruning
//! whole blocks with the distance bound) and a voxel model's occupancy at voxel centres.

use glam::{DVec3, IVec3, UVec3, Vec2, Vec3, Vec4};
use rayon::prelude::*;

use super::iso::{IsoMesh, MAX_LATTICE, edge_ends, march, vertex_normals};
use crate::krs::PreparedObject;
use crate::mesh::srgb_to_linear;
use crate::svo::{Svo, morton_decode, morton_encode};

/// A mesh ready for export: positions, unit normals, linear RGBA colours, triangle indices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColoredMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals.
    pub normals: Vec<Vec3>,
    /// Linear RGBA vertex colours.
    pub colors: Vec<Vec4>,
    /// Three indices per triangle, counter-clockwise front faces.
    pub indices: Vec<u32>,
}

impl ColoredMesh {
    /// Number of triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// Why a field could not be meshed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FieldError {
    /// The resolution is outside what the mesher supports.
    #[error("resolution {0} is out of range (2..={MAX_RESOLUTION} cells along the longest side)")]
    BadResolution(u32),
    /// The object has no finite extent to mesh.
    #[error("{0}")]
    Unbounded(String),
    /// The object has no geometry.
    #[error("the object has no geometry (every kernel is empty)")]
    Empty,
    /// The mesh would exceed the triangle limit.
    #[error(
        "the mesh would have more than {limit} triangles ({what}); lower the resolution \
         (--resolution) or raise the limit (--max-triangles)"
    )]
    TooManyTriangles {
        /// The limit.
        limit: u64,
        /// What hit it.
        what: String,
    },
    /// More instances than the limit (checked before any is enumerated).
    #[error(
        "{what}: {count} instances, over the limit of {limit}; raise it (--max-instances) or \
         instance a larger prototype (a higher --instance-level)"
    )]
    TooManyInstances {
        /// Instances asked for.
        count: u128,
        /// The limit.
        limit: u64,
        /// What would have been instanced.
        what: String,
    },
    /// An instance level that does not split the object into prototype and placements.
    #[error("{0}")]
    BadInstanceLevel(String),
    /// The impostor of an instanced prototype could not be rendered.
    #[error("its impostor could not be rendered ({0}); export without one (--no-impostor)")]
    Impostor(String),
    /// The progress callback asked to stop.
    #[error("cancelled")]
    Cancelled,
}

/// Largest `resolution` for [`mesh_krs`]: lattice coordinates must fit the vertex keys, and
/// beyond this a surface mesh has billions of triangles anyway.
pub const MAX_RESOLUTION: u32 = 16_384;

/// Cells per side of the blocks the pruning stops at; each block then samples its corner
/// lattice once (5³ samples for 4³ cells instead of 8 per cell).
const LEAF_BLOCK: i32 = 4;

/// World-space box that holds the object's geometry: its bounding ball's box when it is
/// bounded; otherwise (half-space kernels, e.g. the rock) a box around the object's origin,
/// doubled until no surface comes within reach of its boundary (up to 2^12 times the object's
/// scale; an object still open at that size, such as a terrain, is an error).
///
/// # Errors
/// [`FieldError::Empty`] or [`FieldError::Unbounded`].
pub fn krs_region(object: &PreparedObject) -> Result<(Vec3, Vec3), FieldError> {
    if object.is_empty {
        return Err(FieldError::Empty);
    }
    if let Some((c, r)) = object.bound_world {
        return Ok((c - Vec3::splat(r), c + Vec3::splat(r)));
    }
    let t = object.object.world_from_object;
    let centre = t.translation;
    let mut half = t.scale;
    for _ in 0..12 {
        // Sample each face of the box on a 16×16 grid: the distance bound clears a ball of
        // radius d around each sample, so d > spacing·√2/2 clears the whole patch around it.
        let spacing = 2.0 * half / 16.0;
        let clear = spacing * 0.75;
        let mut open = false;
        'faces: for axis in 0..3 {
            for side in [-1.0f32, 1.0] {
                for i in 0..=16 {
                    for j in 0..=16 {
                        let mut p = Vec3::ZERO;
                        p[axis] = side * half;
                        p[(axis + 1) % 3] = -half + i as f32 * spacing;
                        p[(axis + 2) % 3] = -half + j as f32 * spacing;
                        if object.distance_world(centre + p) <= clear {
                            open = true;
                            break 'faces;
                        }
                    }
                }
            }
        }
        if !open {
            return Ok((centre - Vec3::splat(half), centre + Vec3::splat(half)));
        }
        half *= 2.0;
    }
    Err(FieldError::Unbounded(format!(
        "KRS object {:?} reaches past a box {} units wide around its origin (an unbounded \
         kernel such as a ground plane); it cannot be meshed as a closed surface",
        object.object.name,
        2.0 * half
    )))
}

/// A finite box of an unbounded KRS object (a ground plane, a terrain) to mesh as a patch:
/// `xz_lo..xz_hi` across, and vertically the heights the surface takes there, found by tracing
/// down a 65 × 65 grid of columns from above `y_top`, padded by 10 % of the height range and
/// two cells (`resolution` cells along the longest side) so the box cuts no column.
///
/// # Errors
/// [`FieldError::Empty`]; [`FieldError::Unbounded`] when the area is degenerate or some column
/// meets no surface (the object is not a ground under this area).
pub fn krs_patch_region(
    object: &PreparedObject,
    xz_lo: Vec2,
    xz_hi: Vec2,
    y_top: f32,
    resolution: u32,
) -> Result<(Vec3, Vec3), FieldError> {
    if object.is_empty {
        return Err(FieldError::Empty);
    }
    let size = xz_hi - xz_lo;
    if !(size.is_finite() && size.min_element() > 0.0 && y_top.is_finite()) {
        return Err(FieldError::Unbounded(format!(
            "KRS object {:?}: the patch {xz_lo}..{xz_hi} is empty or not finite",
            object.object.name
        )));
    }
    const COLUMNS: usize = 65;
    let span = size.max_element();
    // Start above every surface: a positive distance at the top of each column.
    let heights: Vec<Option<f32>> = (0..COLUMNS * COLUMNS)
        .into_par_iter()
        .map(|k| {
            let u = (k % COLUMNS) as f32 / (COLUMNS - 1) as f32;
            let v = (k / COLUMNS) as f32 / (COLUMNS - 1) as f32;
            let xz = xz_lo + size * Vec2::new(u, v);
            let mut top = y_top.max(0.0) + span;
            let at = |y: f32| object.distance_world(Vec3::new(xz.x, y, xz.y));
            for _ in 0..12 {
                if at(top) > 0.0 {
                    break;
                }
                top += 2.0 * span;
            }
            // Sphere trace down: the distance bound never steps through the surface.
            let floor = top - 4096.0 * span;
            let eps = span * 1e-6 + 1e-6;
            let mut y = top;
            for _ in 0..512 {
                let d = at(y);
                if d <= eps {
                    return Some(y);
                }
                y -= d.max(eps);
                if y < floor {
                    return None;
                }
            }
            // Slow convergence (a grazing surface): where it stopped is within reach of it.
            Some(y)
        })
        .collect();
    let mut lo_y = f32::INFINITY;
    let mut hi_y = f32::NEG_INFINITY;
    for h in &heights {
        let Some(h) = *h else {
            return Err(FieldError::Unbounded(format!(
                "KRS object {:?} has no surface below some of the patch {xz_lo}..{xz_hi}; \
                 it is not a ground there",
                object.object.name
            )));
        };
        lo_y = lo_y.min(h);
        hi_y = hi_y.max(h);
    }
    let cell = span / resolution.max(2) as f32;
    let pad = 0.1 * (hi_y - lo_y) + 2.0 * cell;
    Ok((
        Vec3::new(xz_lo.x, lo_y - pad, xz_lo.y),
        Vec3::new(xz_hi.x, hi_y + pad, xz_hi.y),
    ))
}

/// Meshes an unbounded KRS object inside the box `lo..hi` ([`krs_patch_region`]) at
/// `resolution` cells along its longest side, as an open surface: the mesher closes the cut
/// along the box, and those walls and the floor (triangles with a corner more than a quarter
/// cell from the surface) are dropped. Normals and colours as in [`mesh_krs`].
///
/// # Errors
/// As [`mesh_krs`]; [`FieldError::Empty`] when nothing of the surface is inside the box.
pub fn mesh_krs_patch(
    object: &PreparedObject,
    lo: Vec3,
    hi: Vec3,
    resolution: u32,
    max_triangles: u64,
    progress: &dyn Fn(f32) -> bool,
) -> Result<ColoredMesh, FieldError> {
    let distance = |p: Vec3| object.distance_world(p);
    let (positions, indices) =
        mesh_distance_field(&distance, lo, hi, resolution, max_triangles, &|f| {
            progress(f * 0.8)
        })?;
    let cell = (hi - lo).max_element() / resolution as f32;
    let kept: Vec<u32> = indices
        .par_chunks_exact(3)
        .filter(|t| {
            // A wall triangle has a corner on a lattice layer below the surface (about a cell
            // deep); the surface's own corners lie on it up to interpolation error.
            t.iter()
                .all(|&i| object.distance_world(positions[i as usize]).abs() <= 0.25 * cell)
        })
        .flat_map_iter(|t| t.iter().copied())
        .collect();
    // Keep only the vertices the surface uses.
    let mut remap = vec![u32::MAX; positions.len()];
    let mut used = Vec::new();
    let indices: Vec<u32> = kept
        .iter()
        .map(|&i| {
            if remap[i as usize] == u32::MAX {
                remap[i as usize] = used.len() as u32;
                used.push(positions[i as usize]);
            }
            remap[i as usize]
        })
        .collect();
    if indices.is_empty() {
        return Err(FieldError::Empty);
    }
    let (normals, colors): (Vec<Vec3>, Vec<Vec4>) = used
        .par_iter()
        .map(|&p| {
            let (sample, n) = object.sample_world(p);
            (n, object.material(sample.kernel).colour.extend(1.0))
        })
        .unzip();
    progress(1.0);
    Ok(ColoredMesh {
        positions: used,
        normals,
        colors,
        indices,
    })
}

/// Lattice ↔ world for a region meshed at a resolution: lattice point `p` is at
/// `origin + p · cell`. The outermost lattice layer (0 and `dims`) lies outside the region and
/// is forced outside, which closes the surface where the region cuts it.
#[derive(Debug, Clone, Copy)]
struct Lattice {
    origin: DVec3,
    cell: f64,
    dims: IVec3,
}

impl Lattice {
    fn new(lo: Vec3, hi: Vec3, resolution: u32) -> Self {
        let size = (hi - lo).as_dvec3();
        let cell = size.max_element().max(1e-12) / f64::from(resolution);
        // One cell of margin on each side so the forced-outside layer does not touch geometry.
        let cells = (size / cell).ceil().as_ivec3().max(IVec3::ONE) + 2;
        Self {
            origin: lo.as_dvec3() - DVec3::splat(cell),
            cell,
            dims: cells,
        }
    }

    fn world(&self, p: DVec3) -> Vec3 {
        (self.origin + p * self.cell).as_vec3()
    }

    fn on_boundary(&self, p: IVec3) -> bool {
        p.min_element() <= 0 || p.cmpge(self.dims).any()
    }
}

/// Meshes a KRS object's distance field at `resolution` cells along the longest side of its
/// region ([`krs_region`]) into a closed, consistently wound triangle mesh in world space
/// ([`mesh_distance_field`]). Normals are the KRS normals of the nearest kernel instance;
/// colours its material's.
///
/// # Errors
/// [`FieldError`]: bad resolution, empty or unbounded object, more than `max_triangles`
/// triangles (checked before the mesh is built), or cancelled by `progress`.
pub fn mesh_krs(
    object: &PreparedObject,
    resolution: u32,
    max_triangles: u64,
    progress: &dyn Fn(f32) -> bool,
) -> Result<ColoredMesh, FieldError> {
    if !(2..=MAX_RESOLUTION).contains(&resolution) {
        return Err(FieldError::BadResolution(resolution));
    }
    let (lo, hi) = krs_region(object)?;
    let distance = |p: Vec3| object.distance_world(p);
    let (positions, indices) =
        mesh_distance_field(&distance, lo, hi, resolution, max_triangles, &|f| {
            progress(f * 0.8)
        })?;
    let (normals, colors): (Vec<Vec3>, Vec<Vec4>) = positions
        .par_iter()
        .map(|&p| {
            let (sample, n) = object.sample_world(p);
            let c = object.material(sample.kernel).colour;
            (n, c.extend(1.0))
        })
        .unzip();
    progress(1.0);
    Ok(ColoredMesh {
        positions,
        normals,
        colors,
        indices,
    })
}

/// Meshes the zero set of `distance` (negative inside, 1-Lipschitz: |d(p) − d(q)| ≤ |p − q|)
/// inside the box `lo..hi` at `resolution` cells along its longest side. Returns positions and
/// triangle indices of a closed, consistently wound (counter-clockwise outside) mesh; where the
/// box cuts the surface the cut is closed along the box.
///
/// Only blocks the surface can cross are visited: a block whose centre is farther from the
/// surface than its half-diagonal cannot contain a sign change, so it is skipped whole. Work
/// therefore grows with the surface area in cells (about 4× per doubling of the resolution),
/// not the volume (8×).
///
/// # Errors
/// [`FieldError::BadResolution`], [`FieldError::TooManyTriangles`] (checked on the number of
/// surface blocks before any cell is marched), [`FieldError::Cancelled`].
pub fn mesh_distance_field(
    distance: &(dyn Fn(Vec3) -> f32 + Sync),
    lo: Vec3,
    hi: Vec3,
    resolution: u32,
    max_triangles: u64,
    progress: &dyn Fn(f32) -> bool,
) -> Result<(Vec<Vec3>, Vec<u32>), FieldError> {
    if !(2..=MAX_RESOLUTION).contains(&resolution) {
        return Err(FieldError::BadResolution(resolution));
    }
    let lattice = Lattice::new(lo, hi, resolution);
    let value = |p: IVec3| -> f32 {
        if lattice.on_boundary(p) {
            return lattice.cell as f32;
        }
        distance(lattice.world(p.as_dvec3()))
    };
    // Each surviving block holds at least a few surface cells; 2 triangles per block is a
    // floor, so this refuses hopeless requests while the list is still small.
    let block_limit = max_triangles / 2 + 1;
    let blocks = surface_blocks(&lattice, distance, block_limit)?;
    if !progress(0.3) {
        return Err(FieldError::Cancelled);
    }
    // Counted while they are made: once past the limit the remaining blocks are skipped, so
    // a hopeless request stops at about the limit's memory instead of collecting every cell.
    let cell_limit = max_triangles / 2 + 1;
    let made = std::sync::atomic::AtomicU64::new(0);
    let cells: Vec<(IVec3, [f32; 8])> = blocks
        .par_iter()
        .flat_map_iter(|&b| {
            if made.load(std::sync::atomic::Ordering::Relaxed) > cell_limit {
                return Vec::new();
            }
            let block: Vec<(IVec3, [f32; 8])> = block_cells(b, &lattice, &value);
            made.fetch_add(block.len() as u64, std::sync::atomic::Ordering::Relaxed);
            block
        })
        .collect();
    if made.into_inner() > cell_limit {
        return Err(FieldError::TooManyTriangles {
            limit: max_triangles,
            what: format!("more than {} surface cells", cell_limit),
        });
    }
    if !progress(0.6) {
        return Err(FieldError::Cancelled);
    }
    let iso = march(&cells);
    drop(cells);
    if iso.triangle_count() as u64 > max_triangles {
        return Err(FieldError::TooManyTriangles {
            limit: max_triangles,
            what: format!("{} triangles", iso.triangle_count()),
        });
    }
    progress(1.0);
    let positions = iso.positions.iter().map(|&p| lattice.world(p)).collect();
    Ok((positions, iso.indices))
}

/// Minimum corners of the leaf blocks the surface may cross, by recursive pruning from one
/// power-of-two block over the lattice.
fn surface_blocks(
    lattice: &Lattice,
    distance: &(dyn Fn(Vec3) -> f32 + Sync),
    block_limit: u64,
) -> Result<Vec<IVec3>, FieldError> {
    let extent = lattice.dims.max_element().max(LEAF_BLOCK) as u32;
    let root = extent.next_power_of_two() as i32;
    if root > MAX_LATTICE {
        return Err(FieldError::BadResolution(extent));
    }
    // Split the root into its 64 grandchildren and prune those in parallel.
    let mut starts = vec![(IVec3::ZERO, root)];
    while starts.len() < 64 && starts[0].1 > LEAF_BLOCK {
        starts = starts
            .into_iter()
            .flat_map(|(o, s)| {
                let h = s / 2;
                (0..8).map(move |k| {
                    let d = IVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1);
                    (o + d * h, h)
                })
            })
            .collect();
    }
    let count = std::sync::atomic::AtomicU64::new(0);
    let lists: Vec<Vec<IVec3>> = starts
        .par_iter()
        .map(|&(o, s)| {
            let mut out = Vec::new();
            let mut stack = vec![(o, s)];
            while let Some((o, s)) = stack.pop() {
                if o.cmpge(lattice.dims).any() {
                    continue;
                }
                if !block_may_cross(lattice, distance, o, s) {
                    continue;
                }
                if s <= LEAF_BLOCK {
                    out.push(o);
                    if count.fetch_add(1, std::sync::atomic::Ordering::Relaxed) > block_limit {
                        break;
                    }
                    continue;
                }
                let h = s / 2;
                for k in 0..8 {
                    let d = IVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1);
                    stack.push((o + d * h, h));
                }
            }
            out
        })
        .collect();
    let total = count.into_inner();
    if total > block_limit {
        return Err(FieldError::TooManyTriangles {
            limit: block_limit.saturating_sub(1).saturating_mul(2),
            what: format!("more than {total} surface blocks"),
        });
    }
    let mut blocks: Vec<IVec3> = lists.into_iter().flatten().collect();
    blocks.sort_unstable_by_key(|b| morton_encode(b.as_uvec3()));
    Ok(blocks)
}

/// Whether the surface may cross the block of `s` cells at `o` (corners included).
fn block_may_cross(
    lattice: &Lattice,
    distance: &(dyn Fn(Vec3) -> f32 + Sync),
    o: IVec3,
    s: i32,
) -> bool {
    let centre = lattice.world(o.as_dvec3() + f64::from(s) * 0.5);
    let half_diagonal = (f64::from(s) * lattice.cell * 0.5 * 3f64.sqrt()) as f32;
    let d = distance(centre);
    // A little slack for f32 rounding of the distance: pruning must never drop a crossing.
    let reach = half_diagonal * 1.001 + lattice.cell as f32 * 1e-3;
    if d > reach {
        return false;
    }
    // Deep inside: no crossing, unless the block touches the forced-outside boundary layer.
    let touches_boundary = o.min_element() <= 0 || (o + s).cmpge(lattice.dims).any();
    d >= -reach || touches_boundary
}

/// The cells of one leaf block that have a sign change, with their corner values (the block's
/// corner lattice is sampled once).
fn block_cells(
    o: IVec3,
    lattice: &Lattice,
    value: &(impl Fn(IVec3) -> f32 + Sync),
) -> Vec<(IVec3, [f32; 8])> {
    const N: i32 = LEAF_BLOCK + 1;
    let mut samples = [0.0f32; (N * N * N) as usize];
    let at = |p: IVec3| (p.x + N * (p.y + N * p.z)) as usize;
    for z in 0..N {
        for y in 0..N {
            for x in 0..N {
                let p = IVec3::new(x, y, z);
                samples[at(p)] = value(o + p);
            }
        }
    }
    let mut out = Vec::new();
    for z in 0..LEAF_BLOCK {
        for y in 0..LEAF_BLOCK {
            for x in 0..LEAF_BLOCK {
                let c = IVec3::new(x, y, z);
                if (o + c).cmpge(lattice.dims).any() {
                    continue;
                }
                let v: [f32; 8] = std::array::from_fn(|k| {
                    let d = IVec3::new((k & 1) as i32, ((k >> 1) & 1) as i32, (k >> 2) as i32);
                    samples[at(c + d)]
                });
                let inside = v.iter().filter(|&&f| f < 0.0).count();
                if inside != 0 && inside != 8 {
                    out.push((o + c, v));
                }
            }
        }
    }
    out
}

/// A smooth closed surface around a voxel model, in voxel units (voxel `c` spans
/// `[c, c + 1)`): marching tetrahedra over the occupancy at voxel centres (solid −1, empty +1),
/// so every voxel, even a lone one, keeps a closed surface; then `smoothing` rounds of
/// Laplacian relaxation, each vertex kept within half a voxel of its edge midpoint so features
/// one voxel thick survive. Colours are those of the solid voxel at each vertex's edge.
///
/// `max_triangles` is checked before the cells are marched.
///
/// # Errors
/// [`FieldError::TooManyTriangles`], [`FieldError::Empty`] or [`FieldError::BadResolution`]
/// (a model wider than the vertex keys hold, 2^20 − 2 voxels).
pub fn mesh_voxels_smooth(
    svo: &Svo,
    smoothing: u32,
    max_triangles: u64,
) -> Result<ColoredMesh, FieldError> {
    if svo.is_empty() {
        return Err(FieldError::Empty);
    }
    // (Morton code, colour, interior mark) of every voxel but those of enclosed interior
    // tiles, which are solid and interior (`enclosed`) and corner no cell the
    // surface crosses: every such cell has a solid corner with an empty face neighbour. So the
    // work follows the surface, not a solid's volume.
    let mut codes: Vec<(u64, [u8; 4], bool)> = Vec::new();
    let mut hi = UVec3::ZERO;
    let enclosed = svo.for_each_voxel_but_enclosed(|c, v| {
        codes.push((morton_encode(c), v.color, v.is_interior()));
        hi = hi.max(c);
    });
    // Lattice point p is voxel p − 1's centre; the shift leaves room for the empty layer below.
    if hi.max_element() + 2 >= MAX_LATTICE as u32 {
        return Err(FieldError::BadResolution(hi.max_element() + 1));
    }
    codes.sort_unstable_by_key(|e| e.0);
    // The voxel at lattice point p: its colour and whether it is interior.
    let solid_voxel = |p: IVec3| -> Option<([u8; 4], bool)> {
        let v = p - 1;
        if v.min_element() < 0 {
            return None;
        }
        let code = morton_encode(v.as_uvec3());
        if let Ok(i) = codes.binary_search_by_key(&code, |e| e.0) {
            return Some((codes[i].1, codes[i].2));
        }
        enclosed
            .contains(v.as_uvec3())
            .then_some((crate::svo::Voxel::INTERIOR.color, true))
    };
    let solid = |p: IVec3| solid_voxel(p).map(|v| v.0);
    // Every solid voxel touches the 8 cells that have its centre (lattice point c + 1) as a
    // corner: cells c .. c + 1.
    let bound = (codes.len() as u64).saturating_mul(16);
    if bound > max_triangles.saturating_mul(4) {
        return Err(FieldError::TooManyTriangles {
            limit: max_triangles,
            what: format!("{} voxels", codes.len()),
        });
    }
    let mut cell_ids: Vec<IVec3> = Vec::with_capacity(codes.len() * 8);
    for &(code, _, _) in &codes {
        let c = morton_decode(code).as_ivec3();
        for k in 0..8 {
            cell_ids.push(c + IVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1));
        }
    }
    cell_ids.par_sort_unstable_by_key(|c| morton_encode(c.as_uvec3()));
    cell_ids.dedup();
    let cells: Vec<(IVec3, [f32; 8])> = cell_ids
        .par_iter()
        .filter_map(|&c| {
            let v: [f32; 8] = std::array::from_fn(|k| {
                let d = IVec3::new((k & 1) as i32, ((k >> 1) & 1) as i32, (k >> 2) as i32);
                if solid(c + d).is_some() { -1.0 } else { 1.0 }
            });
            let inside = v.iter().filter(|&&f| f < 0.0).count();
            (inside != 0 && inside != 8).then_some((c, v))
        })
        .collect();
    drop(cell_ids);
    let iso: IsoMesh = march(&cells);
    if iso.triangle_count() as u64 > max_triangles {
        return Err(FieldError::TooManyTriangles {
            limit: max_triangles,
            what: format!("{} triangles", iso.triangle_count()),
        });
    }
    let anchors: Vec<DVec3> = iso.positions.clone();
    let mut pos = iso.positions.clone();
    relax(&mut pos, &anchors, &iso.indices, smoothing);
    // Lattice point p is the centre of voxel p − 1: world (voxel units) = p − 0.5.
    let positions: Vec<Vec3> = pos.iter().map(|p| (*p - 0.5).as_vec3()).collect();
    let normals = vertex_normals(&positions, &iso.indices);
    // A vertex takes its edge's solid voxel's colour; an interior voxel (a solid's enclosed
    // inside, which has none) the colour exposing it would give: its nearest surface voxel's.
    let colors = iso
        .edges
        .par_iter()
        .map(|&key| {
            let (a, b) = edge_ends(key);
            let c = match [a, b].into_iter().find_map(|p| Some((p, solid_voxel(p)?))) {
                Some((p, (_, true))) => svo
                    .nearest_surface((p - 1).as_uvec3())
                    .map_or([255; 4], |(_, v)| v.color),
                Some((_, (color, false))) => color,
                None => [255; 4],
            };
            Vec4::new(
                srgb_to_linear(f32::from(c[0]) / 255.0),
                srgb_to_linear(f32::from(c[1]) / 255.0),
                srgb_to_linear(f32::from(c[2]) / 255.0),
                f32::from(c[3]) / 255.0,
            )
        })
        .collect();
    Ok(ColoredMesh {
        positions,
        normals,
        colors,
        indices: iso.indices,
    })
}

/// Laplacian smoothing with each vertex clamped to a box of half a lattice unit around its
/// anchor (the edge midpoint it started at), so the surface stays within the voxels.
fn relax(pos: &mut [DVec3], anchors: &[DVec3], indices: &[u32], rounds: u32) {
    if rounds == 0 || pos.is_empty() {
        return;
    }
    let mut neighbours: Vec<(u32, u32)> = Vec::with_capacity(indices.len() * 2);
    for t in indices.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            neighbours.push((a, b));
            neighbours.push((b, a));
        }
    }
    neighbours.par_sort_unstable();
    neighbours.dedup();
    let mut first = vec![0usize; pos.len() + 1];
    for &(a, _) in &neighbours {
        first[a as usize + 1] += 1;
    }
    for i in 0..pos.len() {
        first[i + 1] += first[i];
    }
    for _ in 0..rounds {
        let next: Vec<DVec3> = (0..pos.len())
            .into_par_iter()
            .map(|i| {
                let ns = &neighbours[first[i]..first[i + 1]];
                if ns.is_empty() {
                    return pos[i];
                }
                let mean =
                    ns.iter().map(|&(_, b)| pos[b as usize]).sum::<DVec3>() / ns.len() as f64;
                let p = pos[i] + (mean - pos[i]) * 0.5;
                p.clamp(anchors[i] - 0.5, anchors[i] + 0.5)
            })
            .collect();
        pos.copy_from_slice(&next);
    }
}

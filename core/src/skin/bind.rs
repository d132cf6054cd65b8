//! Automatic skin weights computed on the voxels themselves: binding a skeleton to a voxel model
//! that has none (a character sculpted in Thicket), or re-binding one.
//!
//! Every joint owns the bone segments from its position to each child's; a joint without
//! children owns the continuation of its parent's bone beyond it, as long again (a root alone
//! owns the point where it stands). A voxel's distance to a joint is its distance to
//! the nearest of those segments, measured one of three ways ([`BindMethod`]):
//!
//! - **geodesic** (Dionne and de Lasa, "Geodesic Voxel Binding for Production Character
//!   Meshes", SCA 2013): through the model's volume only, so an arm resting beside the body
//!   takes nothing from the body's bones. The volume is the voxels plus the empty space they
//!   enclose (a shell import is filled, as the paper fills the mesh), on a grid of
//!   `cell_size`³ voxels per cell (1 unless the model's bounds exceed [`MAX_GRID_CELLS`]). The
//!   four nearest joints of every cell are found by one multi-source Dijkstra over the
//!   26-connected cells with a bucket queue (distances in 1/16 cell), seeded with the exact
//!   distance of every cell within three cells of a bone; a cell accepts at most
//!   four joints, which is exact: a joint among a cell's four nearest is among the four nearest
//!   of every cell on its shortest path there. A voxel adds the straight-line difference between
//!   its own centre and its cell's, so a coarse grid keeps fine gradients. Voxels no bone reaches
//!   (a floating island) fall back to envelope distances and are counted.
//! - **envelope**: straight-line distance, for comparison (and the islands above).
//! - **rigid**: the geodesically nearest joint alone, for blocky characters.
//!
//! Weights are `((d_min + ε) / (d_j + ε))^p` over the four nearest joints (ε half a voxel;
//! `p` = 4, rising where a voxel is farther from every bone than a quarter of the median bone
//! length, see `weigh`), those under 1/64 of the strongest dropped, normalised and quantised to [`Skin4`] (bytes summing to 255); inner nodes merge their
//! children's weights for LOD as for imported rigs.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::{IVec3, UVec3, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::SkinError;
use super::author::joint_bind_position;
use super::skeleton::Skeleton;
use crate::svo::{MAX_SKIN_JOINTS, Skin4, Svo, Voxel};

/// How voxel-to-joint distances are measured.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BindMethod {
    /// Through the model's volume (smooth weights; limbs that touch stay apart).
    #[default]
    Geodesic,
    /// Straight-line distance (smooth weights that leak across gaps).
    Envelope,
    /// One joint per voxel: the geodesically nearest.
    Rigid,
}

impl BindMethod {
    /// Every method, for menus and help.
    pub const ALL: [Self; 3] = [Self::Geodesic, Self::Envelope, Self::Rigid];

    /// The name used in files, on the command line and in menus.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Geodesic => "geodesic",
            Self::Envelope => "envelope",
            Self::Rigid => "rigid",
        }
    }
}

/// Most cells of the geodesic grid (bounds plus a one-cell border); larger models are bound
/// on cells of 2, 4, … voxels per side.
pub const MAX_GRID_CELLS: usize = 1 << 24;

/// Influences kept per voxel (what [`Skin4`] stores).
const K: usize = 4;
/// Falloff exponent of the weights.
const FALLOFF: f32 = 4.0;
/// Queue distances per cell.
const STEPS_PER_CELL: f32 = 16.0;
/// Cells within this many of a bone start at their exact distance to it (see `Grid::seeds`).
const SEED_RADIUS: i32 = 3;
/// Influences weaker than this fraction of the strongest are dropped (they would only spread
/// a limb's motion by a fraction of a voxel into a part it does not touch).
const MIN_RELATIVE_WEIGHT: f32 = 1.0 / 64.0;

/// What a binding did.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BindReport {
    /// The method used.
    pub method: BindMethod,
    /// Voxels bound.
    pub voxels: u64,
    /// Voxels no bone reached through the volume (bound by straight-line distance instead).
    pub unreachable_voxels: u64,
    /// Voxels per side of a geodesic cell (1: every voxel its own cell).
    pub cell_size: u32,
    /// Per joint, the voxels that have it as their strongest influence.
    pub dominant: Vec<u64>,
}

/// Progress and cancellation for [`bind`].
#[derive(Clone, Copy, Default)]
pub struct BindControl<'a> {
    /// Called with the fraction done (0..=1) from the calling thread.
    pub progress: Option<&'a (dyn Fn(f32) + Sync)>,
    /// Checked now and then; when set the binding stops with [`SkinError::Cancelled`].
    pub cancel: Option<&'a AtomicBool>,
}

impl BindControl<'_> {
    fn cancelled(&self) -> bool {
        self.cancel.is_some_and(|c| c.load(Ordering::Relaxed))
    }

    fn progress(&self, f: f32) {
        if let Some(p) = self.progress {
            p(f);
        }
    }
}

/// A joint's bone segments in voxel coordinates (voxel `c` spans `[c, c+1)`).
struct Bones {
    /// `segments[j]`: joint `j`'s segments; a joint without children continues its parent's.
    segments: Vec<Vec<(Vec3, Vec3)>>,
}

impl Bones {
    fn new(skeleton: &Skeleton, origin: Vec3, voxel_size: f32) -> Self {
        let at: Vec<Vec3> = skeleton
            .joints
            .iter()
            .map(|j| (joint_bind_position(j) - origin) / voxel_size)
            .collect();
        let mut segments: Vec<Vec<(Vec3, Vec3)>> = vec![Vec::new(); at.len()];
        for (c, j) in skeleton.joints.iter().enumerate() {
            if let Some(p) = j.parent {
                segments[p].push((at[p], at[c]));
            }
        }
        for (j, s) in segments.iter_mut().enumerate() {
            if s.is_empty() {
                // A joint without children carries what lies beyond it (a head, a hand, a
                // tail's tip): its bone continues its parent's, as long again, so voxels past it
                // are nearer to it than to the end of the parent's bone.
                let beyond = skeleton.joints[j]
                    .parent
                    .map_or(Vec3::ZERO, |p| at[j] - at[p]);
                s.push((at[j], at[j] + beyond));
            }
        }
        Self { segments }
    }

    /// A quarter of the median length of the bones (voxels), at least one voxel: how far from
    /// a bone a voxel still blends at the base falloff (see `weigh`).
    fn reach(&self) -> f32 {
        let mut lengths: Vec<f32> = self
            .segments
            .iter()
            .flatten()
            .map(|(a, b)| (*b - *a).length())
            .filter(|l| *l > 0.0)
            .collect();
        if lengths.is_empty() {
            return 1.0;
        }
        let mid = lengths.len() / 2;
        (0.25 * *lengths.select_nth_unstable_by(mid, f32::total_cmp).1).max(1.0)
    }

    fn distance(&self, joint: usize, p: Vec3) -> f32 {
        self.segments[joint]
            .iter()
            .map(|&(a, b)| segment_distance(p, a, b))
            .fold(f32::INFINITY, f32::min)
    }
}

/// Distance from `p` to the segment `a..b`.
#[must_use]
pub fn segment_distance(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).length()
}

/// Binds `skeleton` to the voxels of `svo` (placed by `origin` and `voxel_size`, the model's
/// own space, where the skeleton's bind pose lives) and returns the octree with skin weights
/// and what was done. Colours, normals and materials are unchanged.
///
/// # Errors
/// [`SkinError::Rig`] for an empty octree or skeleton, more than [`MAX_SKIN_JOINTS`] joints, a
/// model standing for more than [`crate::svo::MAX_LISTED_VOXELS`] voxels or a non-finite
/// placement; [`SkinError::Cancelled`] when cancelled.
pub fn bind(
    svo: &Svo,
    origin: Vec3,
    voxel_size: f32,
    skeleton: &Skeleton,
    method: BindMethod,
    control: BindControl<'_>,
) -> Result<(Svo, BindReport), SkinError> {
    let rig = |problem: String| SkinError::Rig { problem };
    if skeleton.is_empty() {
        return Err(rig("cannot bind: the skeleton has no joints".into()));
    }
    // Binding weighs every voxel one by one (and a skinned model stores every drawn voxel).
    if let Some(voxels) = svo.too_many_to_list() {
        return Err(rig(format!(
            "cannot bind: binding computes each voxel's weights one by one, and this model \
             stands for {} voxels, more than {}; bind the model at a larger voxel size",
            crate::budget::thousands(voxels),
            crate::budget::thousands(crate::svo::MAX_LISTED_VOXELS)
        )));
    }
    if skeleton.len() > MAX_SKIN_JOINTS {
        return Err(rig(format!(
            "cannot bind {} joints: a voxel model carries at most {MAX_SKIN_JOINTS}",
            skeleton.len()
        )));
    }
    if !(origin.is_finite() && voxel_size.is_finite() && voxel_size > 0.0) {
        return Err(rig(format!(
            "cannot bind: origin {origin} and voxel size {voxel_size} must be finite (size positive)"
        )));
    }
    let Some((lo, hi)) = svo.bounds() else {
        return Err(rig("cannot bind: the model has no voxels".into()));
    };
    let bones = Bones::new(skeleton, origin, voxel_size);
    if bones
        .segments
        .iter()
        .flatten()
        .any(|(a, b)| !(a.is_finite() && b.is_finite()))
    {
        return Err(rig("cannot bind: a joint's position is not finite".into()));
    }
    let leaves = svo.leaves();
    control.progress(0.0);
    let (skins, unreachable, cell_size) = match method {
        BindMethod::Envelope => {
            let near: Vec<Nearest> = leaves
                .par_iter()
                .map(|&(c, _)| envelope_nearest(&bones, c.as_vec3() + 0.5))
                .collect();
            (weigh(&near, bones.reach()), 0, 1)
        }
        BindMethod::Rigid => {
            let grid = Grid::new(&leaves, lo, hi);
            if control.cancelled() {
                return Err(SkinError::Cancelled);
            }
            let labels = grid.propagate(&bones, 1, control)?;
            let unreachable = std::sync::atomic::AtomicU64::new(0);
            let skins: Vec<Skin4> = leaves
                .par_iter()
                .map(|&(c, _)| {
                    let joint = grid.nearest_label(&labels, c).unwrap_or_else(|| {
                        unreachable.fetch_add(1, Ordering::Relaxed);
                        envelope_nearest(&bones, c.as_vec3() + 0.5).joints[0].0
                    });
                    Skin4::from_influences(&[(joint, 1.0)])
                })
                .collect();
            (skins, unreachable.into_inner(), grid.scale)
        }
        BindMethod::Geodesic => {
            let grid = Grid::new(&leaves, lo, hi);
            if control.cancelled() {
                return Err(SkinError::Cancelled);
            }
            let labels = grid.propagate(&bones, K, control)?;
            let unreachable = std::sync::atomic::AtomicU64::new(0);
            let near: Vec<Nearest> = leaves
                .par_iter()
                .map(|&(c, _)| {
                    grid.voxel_nearest(&labels, &bones, c).unwrap_or_else(|| {
                        unreachable.fetch_add(1, Ordering::Relaxed);
                        envelope_nearest(&bones, c.as_vec3() + 0.5)
                    })
                })
                .collect();
            (
                weigh(&near, bones.reach()),
                unreachable.into_inner(),
                grid.scale,
            )
        }
    };
    if control.cancelled() {
        return Err(SkinError::Cancelled);
    }
    let voxels = leaves.len() as u64;
    let bound = Svo::from_voxels(
        svo.depth(),
        true,
        leaves
            .into_iter()
            .zip(skins)
            .map(|((c, v), skin)| (c, Voxel { skin, ..v })),
    )
    .map_err(|e| rig(format!("rebuilding the octree: {e}")))?;
    let dominant = dominant_joints(&bound, skeleton.len());
    control.progress(1.0);
    Ok((
        bound,
        BindReport {
            method,
            voxels,
            unreachable_voxels: unreachable,
            cell_size,
            dominant,
        },
    ))
}

/// Per joint of a skeleton of `joints` joints, how many voxels of `svo` have it as their
/// strongest influence (an empty skin follows joint 0; joints past the skeleton are not
/// counted).
#[must_use]
pub fn dominant_joints(svo: &Svo, joints: usize) -> Vec<u64> {
    let mut dominant = vec![0u64; joints];
    svo.for_each_leaf(|_, v| {
        let s = v.skin;
        let j = if s.is_empty() {
            0
        } else {
            usize::from(s.joints[0])
        };
        if let Some(n) = dominant.get_mut(j) {
            *n += 1;
        }
    });
    dominant
}

/// A voxel's nearest joints (at most [`K`]) with their distances in voxels, nearest first.
#[derive(Debug, Clone, Copy, Default)]
struct Nearest {
    joints: [(u16, f32); K],
    count: u8,
}

impl Nearest {
    fn from_unsorted(cands: &mut [(u16, f32)]) -> Self {
        cands.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        let mut out = Self::default();
        for (slot, &c) in out.joints.iter_mut().zip(cands.iter()) {
            *slot = c;
            out.count += 1;
        }
        out
    }

    fn nearest(&self) -> Option<f32> {
        (self.count > 0).then_some(self.joints[0].1)
    }
}

/// Weights of every voxel from its nearest joints: `((d_min + ε) / (d_j + ε))^p`, with `p` =
/// [`FALLOFF`] for voxels within `reach` of a bone, rising in proportion to `d_min / reach`
/// beyond it. Near a joint on a limb the blend is as wide as the limb is thick; a part with no
/// bone of its own (a torso above a hip joint, with no spine) goes to its nearest bone instead
/// of a mix of every joint around it. `reach` is a quarter of the skeleton's median bone length
/// ([`Bones::reach`]).
fn weigh(near: &[Nearest], reach: f32) -> Vec<Skin4> {
    let eps = 0.5;
    let scale = reach.max(1.0) + eps;
    near.par_iter()
        .map(|n| {
            let Some(nearest) = n.nearest() else {
                return Skin4::default();
            };
            let p = FALLOFF * ((nearest + eps) / scale).max(1.0);
            let mut infl = [(0u16, 0f32); K];
            let mut kept = 0;
            for &(j, dj) in &n.joints[..usize::from(n.count)] {
                let w = ((nearest + eps) / (dj + eps)).powf(p);
                if w >= MIN_RELATIVE_WEIGHT {
                    infl[kept] = (j, w);
                    kept += 1;
                }
            }
            Skin4::from_influences(&infl[..kept])
        })
        .collect()
}

/// The four nearest joints of a point by straight-line distance.
fn envelope_nearest(bones: &Bones, p: Vec3) -> Nearest {
    let mut cands: Vec<(u16, f32)> = (0..bones.segments.len())
        .map(|j| (j as u16, bones.distance(j, p)))
        .collect();
    Nearest::from_unsorted(&mut cands)
}

/// The part of segment `a..b` inside the box `lo..hi` (`None` when it misses the box).
fn clip_segment(a: Vec3, b: Vec3, lo: Vec3, hi: Vec3) -> Option<(Vec3, Vec3)> {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    for i in 0..3 {
        if d[i].abs() < 1e-12 {
            if a[i] < lo[i] || a[i] > hi[i] {
                return None;
            }
        } else {
            let (ta, tb) = ((lo[i] - a[i]) / d[i], (hi[i] - a[i]) / d[i]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
    }
    (t0 <= t1).then(|| (a + d * t0, a + d * t1))
}

/// Cell states of the dense occupancy grid.
const EMPTY: u8 = 0;
const SOLID: u8 = 1;
const OUTSIDE: u8 = 2;
const NOT_DOMAIN: u32 = u32::MAX;

/// The model's volume on a dense grid of cells (`scale` voxels per side) with a one-cell border:
/// solid cells, the empty cells they enclose, and an index of those domain cells.
struct Grid {
    scale: u32,
    /// Voxel coordinate of cell (1, 1, 1)'s corner (cell (0, 0, 0) is border).
    lo: UVec3,
    dims: IVec3,
    /// Grid cell → domain index or [`NOT_DOMAIN`].
    index: Vec<u32>,
    /// Domain index → grid cell.
    cells: Vec<u32>,
}

/// The best distances found so far per cell (see `Grid::propagate`).
struct Tentative {
    count: Vec<u8>,
    joint: Vec<u8>,
    dist: Vec<u32>,
}

impl Tentative {
    /// The tentative distance of joint `j` at cell `d`.
    fn distance(&self, d: usize, j: u8) -> Option<u32> {
        let c = usize::from(self.count[d]);
        (0..c)
            .find(|&k| self.joint[d * K + k] == j)
            .map(|k| self.dist[d * K + k])
    }

    /// Offers joint `j` at distance `dist` to cell `d`; true when it improved the cell's
    /// tentative list (the caller then queues it).
    fn offer(&mut self, labels: &Labels, d: usize, j: u8, dist: u32, keep: usize) -> bool {
        let settled = usize::from(labels.count[d]);
        if settled >= keep || labels.joint[d * K..d * K + settled].contains(&j) {
            return false;
        }
        let c = usize::from(self.count[d]);
        let slots = d * K..d * K + c;
        if let Some(k) = self.joint[slots.clone()].iter().position(|&x| x == j) {
            let slot = d * K + k;
            if dist >= self.dist[slot] {
                return false;
            }
            self.dist[slot] = dist;
            return true;
        }
        if c < keep {
            self.joint[d * K + c] = j;
            self.dist[d * K + c] = dist;
            self.count[d] += 1;
            return true;
        }
        // Full: replace the worst entry whose joint has not settled here, if `j` beats it.
        let is_settled = |x: u8| labels.joint[d * K..d * K + settled].contains(&x);
        let worst = slots
            .filter(|&slot| !is_settled(self.joint[slot]))
            .max_by_key(|&slot| self.dist[slot]);
        match worst {
            Some(slot) if dist < self.dist[slot] => {
                self.joint[slot] = j;
                self.dist[slot] = dist;
                true
            }
            _ => false,
        }
    }
}

/// Labels of every domain cell: up to [`K`] `(joint, distance)` pairs, nearest first.
struct Labels {
    count: Vec<u8>,
    joint: Vec<u8>,
    dist: Vec<u32>,
}

impl Grid {
    fn new(leaves: &[(UVec3, Voxel)], lo: UVec3, hi: UVec3) -> Self {
        let size = hi - lo + 1;
        let mut scale = 1u32;
        let cells_at = |s: u32| {
            let d = (size + s - 1) / s + 2;
            d.x as usize * d.y as usize * d.z as usize
        };
        while cells_at(scale) > MAX_GRID_CELLS {
            scale *= 2;
        }
        let dims = ((size + scale - 1) / scale + 2).as_ivec3();
        let total = dims.x as usize * dims.y as usize * dims.z as usize;
        let mut state = vec![EMPTY; total];
        let flat = |c: IVec3| (c.x + dims.x * (c.y + dims.y * c.z)) as usize;
        for &(c, _) in leaves {
            let cell = ((c - lo) / scale).as_ivec3() + 1;
            state[flat(cell)] = SOLID;
        }
        // Flood the outside from the border (6-connected through empty cells); what stays
        // empty is enclosed.
        let mut stack = vec![0usize];
        state[0] = OUTSIDE;
        let strides = [1isize, dims.x as isize, (dims.x * dims.y) as isize];
        while let Some(i) = stack.pop() {
            let (x, y, z) = (
                i as i32 % dims.x,
                (i as i32 / dims.x) % dims.y,
                i as i32 / (dims.x * dims.y),
            );
            let at = [x, y, z];
            let lim = [dims.x, dims.y, dims.z];
            for axis in 0..3 {
                for dir in [-1i32, 1] {
                    let v = at[axis] + dir;
                    if v < 0 || v >= lim[axis] {
                        continue;
                    }
                    let n = (i as isize + dir as isize * strides[axis]) as usize;
                    if state[n] == EMPTY {
                        state[n] = OUTSIDE;
                        stack.push(n);
                    }
                }
            }
        }
        let mut index = vec![NOT_DOMAIN; total];
        let mut cells = Vec::new();
        for (i, s) in state.iter().enumerate() {
            if *s != OUTSIDE {
                index[i] = cells.len() as u32;
                cells.push(i as u32);
            }
        }
        Self {
            scale,
            lo,
            dims,
            index,
            cells,
        }
    }

    /// Grid cell of a voxel-space point (may be outside the grid).
    fn cell_of(&self, p: Vec3) -> Option<usize> {
        let c = ((p - self.lo.as_vec3()) / self.scale as f32)
            .floor()
            .as_ivec3()
            + 1;
        if c.cmplt(IVec3::ZERO).any() || c.cmpge(self.dims).any() {
            return None;
        }
        Some((c.x + self.dims.x * (c.y + self.dims.y * c.z)) as usize)
    }

    /// Centre of grid cell `i` in voxel space.
    fn centre(&self, i: usize) -> Vec3 {
        let i = i as i32;
        let c = IVec3::new(
            i % self.dims.x,
            (i / self.dims.x) % self.dims.y,
            i / (self.dims.x * self.dims.y),
        );
        self.lo.as_vec3() + ((c - 1).as_vec3() + 0.5) * self.scale as f32
    }

    /// Seeds per joint: the domain cells within [`SEED_RADIUS`] cells of its segments, at their
    /// straight-line distance (queue units), so the chamfer metric of the propagation only
    /// starts beyond that radius; a joint whose bones miss the volume seeds the nearest domain
    /// cell.
    fn seeds(&self, bones: &Bones) -> Vec<(u32, u32, u8)> {
        let scale = self.scale as f32;
        let units = STEPS_PER_CELL / scale;
        let reach = SEED_RADIUS as f32 * scale;
        let mut stamp = vec![0u16; self.cells.len()];
        let mut seeds = Vec::new();
        for (j, segs) in bones.segments.iter().enumerate() {
            let first = seeds.len();
            let mark = j as u16 + 1;
            // Only the part of a bone inside the grid (and the seed reach around it) can seed:
            // a bone reaching far outside the model is not walked step by step out there.
            let box_lo = self.lo.as_vec3() - reach - scale;
            let box_hi = self.lo.as_vec3() + self.dims.as_vec3() * scale + reach;
            for &(a, b) in segs {
                let Some((a, b)) = clip_segment(a, b, box_lo, box_hi) else {
                    continue;
                };
                let steps = ((b - a).length() / scale * 2.0).ceil().max(1.0) as usize;
                for s in 0..=steps {
                    let p = a.lerp(b, s as f32 / steps as f32);
                    let centre = ((p - self.lo.as_vec3()) / scale).floor().as_ivec3() + 1;
                    let r = SEED_RADIUS;
                    for dz in -r..=r {
                        for dy in -r..=r {
                            for dx in -r..=r {
                                let c = centre + IVec3::new(dx, dy, dz);
                                if c.cmplt(IVec3::ZERO).any() || c.cmpge(self.dims).any() {
                                    continue;
                                }
                                let cell = (c.x + self.dims.x * (c.y + self.dims.y * c.z)) as usize;
                                let d = self.index[cell];
                                if d == NOT_DOMAIN || stamp[d as usize] == mark {
                                    continue;
                                }
                                let dist = bones.distance(j, self.centre(cell));
                                if dist <= reach {
                                    stamp[d as usize] = mark;
                                    seeds.push(((dist * units).round() as u32, d, j as u8));
                                }
                            }
                        }
                    }
                }
            }
            if seeds.len() == first {
                let nearest = self
                    .cells
                    .iter()
                    .enumerate()
                    .map(|(d, &cell)| (d, bones.distance(j, self.centre(cell as usize))))
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                if let Some((d, dist)) = nearest {
                    seeds.push(((dist * units).round() as u32, d as u32, j as u8));
                }
            }
        }
        seeds.sort_unstable();
        seeds
    }

    /// Multi-source Dijkstra keeping the `keep` nearest joints of every domain cell.
    fn propagate(
        &self,
        bones: &Bones,
        keep: usize,
        control: BindControl<'_>,
    ) -> Result<Labels, SkinError> {
        let n = self.cells.len();
        let mut labels = Labels {
            count: vec![0; n],
            joint: vec![0; n * K],
            dist: vec![0; n * K],
        };
        let (dx, dxy) = (self.dims.x as isize, (self.dims.x * self.dims.y) as isize);
        let mut offsets = Vec::with_capacity(26);
        for z in -1isize..=1 {
            for y in -1isize..=1 {
                for x in -1isize..=1 {
                    let k = x.abs() + y.abs() + z.abs();
                    if k == 0 {
                        continue;
                    }
                    let w = (STEPS_PER_CELL * (k as f32).sqrt()).round() as u32;
                    offsets.push((x + y * dx + z * dxy, w));
                }
            }
        }
        const RING: usize = 64;
        let mut ring: Vec<Vec<u64>> = vec![Vec::new(); RING];
        // Tentative distances: per cell up to `keep` joints with the best distance found so
        // far. A joint enters only by beating the worst unsettled one (or a free slot): a joint
        // worse than `keep` others can never be among the cell's nearest, so it is never pushed.
        let mut tent = Tentative {
            count: vec![0; n],
            joint: vec![0; n * K],
            dist: vec![0; n * K],
        };
        let seeds = self.seeds(bones);
        let mut next_seed = 0;
        let mut pending = 0usize;
        let mut cur = seeds.first().map_or(0, |s| s.0);
        let mut scratch = Vec::new();
        let mut settled = 0usize;
        let target = (n * keep).max(1);
        let mut since_check = 0usize;
        loop {
            while next_seed < seeds.len() && seeds[next_seed].0 == cur {
                let (dist, d, j) = seeds[next_seed];
                if tent.offer(&labels, d as usize, j, dist, keep) {
                    ring[cur as usize % RING].push(u64::from(d) << 8 | u64::from(j));
                    pending += 1;
                }
                next_seed += 1;
            }
            if pending == 0 {
                match seeds.get(next_seed) {
                    Some(s) => {
                        cur = s.0;
                        continue;
                    }
                    None => break,
                }
            }
            std::mem::swap(&mut scratch, &mut ring[cur as usize % RING]);
            pending -= scratch.len();
            for &e in &scratch {
                let d = (e >> 8) as usize;
                let j = (e & 0xff) as u8;
                let c = usize::from(labels.count[d]);
                // Stale entries: the joint settled already, was improved, or was evicted.
                if c >= keep
                    || labels.joint[d * K..d * K + c].contains(&j)
                    || tent.distance(d, j) != Some(cur)
                {
                    continue;
                }
                labels.joint[d * K + c] = j;
                labels.dist[d * K + c] = cur;
                labels.count[d] += 1;
                settled += 1;
                let g = self.cells[d] as isize;
                for &(off, w) in &offsets {
                    let nd = self.index[(g + off) as usize];
                    if nd == NOT_DOMAIN {
                        continue;
                    }
                    if tent.offer(&labels, nd as usize, j, cur + w, keep) {
                        ring[(cur + w) as usize % RING].push(u64::from(nd) << 8 | u64::from(j));
                        pending += 1;
                    }
                }
            }
            since_check += scratch.len();
            scratch.clear();
            if since_check >= 1 << 16 {
                since_check = 0;
                if control.cancelled() {
                    return Err(SkinError::Cancelled);
                }
                control.progress(0.9 * settled as f32 / target as f32);
            }
            cur += 1;
        }
        Ok(labels)
    }

    /// A voxel's nearest joints from its cell's labels (`None` when no bone reached the
    /// cell), in voxels: the cell's geodesic distance plus the straight-line difference between
    /// the voxel's centre and the cell's, never below the straight-line distance.
    fn voxel_nearest(&self, labels: &Labels, bones: &Bones, c: UVec3) -> Option<Nearest> {
        let p = c.as_vec3() + 0.5;
        let cell = self.cell_of(p)?;
        let d = self.index[cell] as usize;
        let count = usize::from(labels.count[d]);
        if count == 0 {
            return None;
        }
        let centre = self.centre(cell);
        let to_voxels = self.scale as f32 / STEPS_PER_CELL;
        let mut cands = [(0u16, 0f32); K];
        for (k, slot) in cands.iter_mut().enumerate().take(count) {
            let j = usize::from(labels.joint[d * K + k]);
            let geodesic = labels.dist[d * K + k] as f32 * to_voxels;
            let own = bones.distance(j, p);
            let refined = if self.scale == 1 {
                geodesic.max(own)
            } else {
                (geodesic + own - bones.distance(j, centre)).max(own)
            };
            *slot = (j as u16, refined);
        }
        Some(Nearest::from_unsorted(&mut cands[..count]))
    }

    /// The geodesically nearest joint of a voxel's cell (`None` when no bone reached it).
    fn nearest_label(&self, labels: &Labels, c: UVec3) -> Option<u16> {
        let cell = self.cell_of(c.as_vec3() + 0.5)?;
        let d = self.index[cell] as usize;
        (labels.count[d] > 0).then(|| u16::from(labels.joint[d * K]))
    }
}

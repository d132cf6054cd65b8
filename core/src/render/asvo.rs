//! ASVO drawing (paper §4, Fig. 8): a queue-based breadth-first traversal, one octree level per
//! pass. Each node is placed in the world by its object's [`NodeDeform`] when its screen position
//! is computed, frustum- and occlusion-culled, then split (children go to the next pass in
//! front-to-back order, Fig. 10; leaves are classified at once by their parent) while its
//! projected edge exceeds the LOD threshold, otherwise splatted as the screen rectangle of its
//! projected box at the depth of its nearest point.
//!
//! Determinism: the queue is processed in chunks whose lengths depend only on what earlier
//! chunks wrote (see [`ChunkSizer`]), their results are concatenated in queue order, splat ids
//! follow that order, and depth+id is an atomic minimum — so the image does not depend on the
//! thread count (nor on the chunk lengths: culling drops only nodes that cannot win a pixel).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use glam::{Mat3, Vec3};
use rayon::prelude::*;

use super::buffers::{DepthTarget, pack_key};
use super::camera::Camera;
use super::sampled::SampledTexels;
use super::stats::LevelStats;
use crate::deform::{NodeDeform, NodeInfo};
use crate::svo::{
    IN_TILE, NodeRef, Svo, child_rank, front_to_back_order, is_interior_value, octant_offset,
};

/// One voxel object to draw.
#[derive(Clone, Copy)]
pub struct VoxelInstance<'a> {
    /// The octree.
    pub svo: &'a Svo,
    /// Places its nodes in the world (rigid transform, skinning, …).
    pub deform: &'a dyn NodeDeform,
    /// Whether it is drawn into shadow maps.
    pub casts_shadows: bool,
    /// Reported in [`super::PixelId::object`] (use 1-based; 0 means background).
    pub label: u32,
}

/// A queued node: which object, and where in its octree.
#[derive(Debug, Clone, Copy)]
pub(crate) struct QNode {
    pub(crate) obj: u32,
    pub(crate) node: NodeRef,
}

/// A splat waiting to be written: an inclusive pixel rectangle and its depth.
#[derive(Debug, Clone, Copy)]
struct Splat {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    ndc_depth: f32,
    /// Drawn as the node's exact box (see [`write_cube`]): its footprint exceeds
    /// [`PassSettings::cube_pixel_threshold`]. `ndc_depth` is then its nearest point's, a lower
    /// bound of every depth it writes.
    cube: bool,
}

/// Bits of a voxel id that carry the face a pixel of an exact cube shows (see
/// `face_code`); the splat index sits above them. 0: a splat, shaded with the node's normal.
pub const FACE_BITS: u32 = 3;
/// The largest splat index an id can carry (the mesh flag stays above it).
pub(crate) const MAX_SPLAT_INDEX: u32 = (super::MESH_ID_FLAG >> FACE_BITS) - 1;

/// The voxel-space normal of face code `code` (1..=6: +x, -x, +y, -y, +z, -z), `None` for 0
/// (a splat) and the unused 7.
#[must_use]
pub(crate) fn face_normal(code: u32) -> Option<Vec3> {
    let axis = match code {
        1 | 2 => Vec3::X,
        3 | 4 => Vec3::Y,
        5 | 6 => Vec3::Z,
        _ => return None,
    };
    Some(if code.is_multiple_of(2) { -axis } else { axis })
}

/// The face code of a box entered across axis `k` (0..3) while moving along `d_local` in the
/// box's own axes: the ray enters through the face it moves away from.
#[inline]
fn face_code(k: usize, d_local: f32) -> u32 {
    1 + 2 * k as u32 + u32::from(d_local > 0.0)
}

/// Per-object, per-camera constants of the rigid fast path.
#[derive(Clone, Copy)]
struct Fast {
    /// `view_from_voxel` linear part and translation.
    linear: Mat3,
    translation: Vec3,
    /// View-space AABB half extent of a node of edge 1 voxel (rows of |linear| summed / 2).
    half_extent_unit: Vec3,
    /// Longest world edge of a node of edge 1 voxel.
    edge_unit: f32,
    /// `view_from_voxel` for normals (inverse transpose of `linear`).
    normal_view: Mat3,
    /// `linear`'s inverse (exact cubes: view space to voxel axes).
    inv_linear: Mat3,
}

/// A traversal's queues, per-block tables and outputs, kept from one pass to the next (and
/// from frame to frame by [`super::Renderer`]) so that a pass allocates only while they grow.
#[derive(Default)]
pub(crate) struct VoxelScratch {
    fast: Vec<Option<Fast>>,
    queue: Vec<QNode>,
    next: Vec<QNode>,
    deferred: Vec<Deferred>,
    next_deferred: Vec<Deferred>,
    blocks: Vec<BlockOut>,
    bases: Vec<u64>,
    dirty: Vec<u32>,
    /// Output of the last pass: `refs[i]` is the node drawn with id `(id_base + i) <<
    /// FACE_BITS` (plus a face code in the low bits for pixels of exact cubes; empty when refs
    /// were not requested).
    pub(crate) refs: Vec<QNode>,
    /// Output of the last pass: counters per octree level (trailing empty levels dropped).
    pub(crate) levels: Vec<LevelStats>,
}

/// What a traversal produced besides the node references and level counters it leaves in its
/// [`VoxelScratch`].
pub(crate) struct VoxelPass {
    /// Pixels written by rectangle splats, and pixels tested by exact cubes (one ray–box test
    /// each), the two costs [`PassSettings::cube_pixel_threshold`] trades.
    pub(crate) rect_pixels: u64,
    pub(crate) cube_pixels: u64,
    pub(crate) traversal_ms: f64,
    pub(crate) splat_ms: f64,
}

/// Traversal settings.
pub(crate) struct PassSettings<'a> {
    pub(crate) lod_pixel_threshold: f32,
    /// A splat whose screen rectangle is wider or taller than this many pixels is drawn as its
    /// exact box ([`write_cube`]) instead of the rectangle.
    pub(crate) cube_pixel_threshold: f32,
    pub(crate) occlusion_culling: bool,
    /// First id to hand out (ids are `id_base + splat index`).
    pub(crate) id_base: u32,
    /// Keep the node of every splat (the view needs them to resolve; shadow maps do not).
    pub(crate) keep_refs: bool,
    /// Only objects with `casts_shadows`.
    pub(crate) shadow_casters_only: bool,
    /// A shadow map drawn for one frame: only nodes touching texels its shading reads (see
    /// [`SampledTexels`]); the others are culled with the frustum.
    pub(crate) sampled: Option<&'a SampledTexels>,
}

/// What classifying one node decided.
enum Action {
    Frustum,
    Occluded,
    /// Split; carries the node's view-space centre and axes for the child order.
    Split(Vec3, Mat3),
    Splat(Splat),
    /// Visible so far but facing away from the eye: decided again after the next pass (see
    /// [`Deferred`]). `split` tells what it wanted.
    Defer {
        rect: Splat,
        occ: [u32; 4],
        occ_depth: f32,
        split: bool,
    },
}

/// A back-facing node whose splat or split waits until the end of the next pass.
///
/// Why: breadth-first order draws a closed surface's far side first wherever its nodes are
/// smaller on screen than the near side's, because the near side is split one level further
/// and so drawn one pass later. Holding back-facing nodes (by their LOD normal) until the near
/// side's next level is in the depth buffer lets occlusion culling drop them (and, for a split,
/// their whole subtree). Only the order changes, never the set of visible fragments, since
/// culling is conservative.
#[derive(Debug, Clone, Copy)]
struct Deferred {
    q: QNode,
    rect: Splat,
    /// The occlusion-test rectangle (see [`overlapped_span`]).
    occ: [u32; 4],
    /// The occlusion test's depth: the splat's, or the nearest depth of a deformed node's
    /// subtree box (which may reach nearer than its splat).
    occ_depth: f32,
    split: bool,
}

/// One parallel block's output, kept across chunks and passes so its buffers are reused.
#[derive(Default)]
struct BlockOut {
    children: Vec<QNode>,
    splats: Vec<(Splat, QNode)>,
    deferred: Vec<Deferred>,
    dirty: Vec<u32>,
    stats: Vec<LevelStats>,
    local: LocalDepth,
    rect_pixels: u64,
    cube_pixels: u64,
}

impl BlockOut {
    fn clear(&mut self, levels: usize) {
        self.children.clear();
        self.splats.clear();
        self.deferred.clear();
        self.dirty.clear();
        self.stats.clear();
        self.stats.resize(levels, LevelStats::default());
        self.local.clear();
        self.rect_pixels = 0;
        self.cube_pixels = 0;
    }

    /// Queues a splat unless earlier splats of this block already cover every pixel of it at
    /// a depth no farther (see [`LocalDepth`]); returns whether it was queued.
    fn push_splat(&mut self, s: Splat, q: QNode, width: u32, cull: bool) -> bool {
        if cull && !self.local.record(&s, width) {
            return false;
        }
        let level = usize::from(q.node.level);
        self.stats[level].splatted += 1;
        self.stats[level].cubes += u64::from(s.cube);
        self.splats.push((s, q));
        true
    }
}

/// The nearest depth each pixel got from the splats queued so far in one block, for splats of
/// at most [`LocalDepth::MAX_PIXELS`] pixels (the LOD cut's sub-pixel nodes).
///
/// Why: siblings at the cut are queued next to each other, so they fall in the same block and
/// none sees the others in the occlusion tiles (those are refreshed between chunks). On a
/// closed surface two or three sub-pixel voxels of the shell's layers land on one pixel, and
/// all were drawn. A later splat whose every pixel already holds an earlier splat of the same
/// block at a nearer or equal depth cannot win any of them: depth is compared first, and at
/// equal depth the earlier splat has the lower id. So dropping it leaves the image identical,
/// and the decision depends only on the block's own order, not on threads.
#[derive(Default)]
struct LocalDepth {
    /// Open-addressed table of (pixel index + 1, depth); 0 marks an empty slot.
    slots: Vec<(u32, f32)>,
    /// Slots in use, to clear them.
    used: Vec<u32>,
}

impl LocalDepth {
    /// 8,192 slots: a block of 1,024 parents classifies up to 8,192 leaves (see `split_node`).
    const BITS: u32 = 13;
    const MAX_PIXELS: u32 = 4;

    fn clear(&mut self) {
        for &i in &self.used {
            self.slots[i as usize] = (0, 0.0);
        }
        self.used.clear();
    }

    /// The slot holding `pixel`, or the empty slot where it would go.
    #[inline]
    fn find(&self, pixel: u32) -> usize {
        let mask = (1usize << Self::BITS) - 1;
        let mut i = (pixel.wrapping_mul(0x9E37_79B9) >> (32 - Self::BITS)) as usize;
        loop {
            let (k, _) = self.slots[i];
            if k == 0 || k == pixel + 1 {
                return i;
            }
            i = (i + 1) & mask;
        }
    }

    /// Whether the table takes the splat into account: small enough, and room left (the table
    /// stays at most half full so probing stays short). Others always pass.
    #[inline]
    fn tracks(&self, s: &Splat) -> bool {
        (s.x1 - s.x0 + 1) * (s.y1 - s.y0 + 1) <= Self::MAX_PIXELS
            && self.used.len() + Self::MAX_PIXELS as usize <= (1 << (Self::BITS - 1))
    }

    /// Whether [`LocalDepth::record`] would refuse the splat (every pixel already holds a nearer
    /// or equal depth), without recording anything.
    fn hidden(&self, s: &Splat, width: u32) -> bool {
        if self.slots.is_empty() || !self.tracks(s) {
            return false;
        }
        for y in s.y0..=s.y1 {
            for x in s.x0..=s.x1 {
                let (k, d) = self.slots[self.find(y * width + x)];
                if k == 0 || d > s.ndc_depth {
                    return false;
                }
            }
        }
        true
    }

    /// Records the splat's pixels; false when every one of them already held a nearer or
    /// equal depth (then nothing is recorded). Large splats, and a full table, always pass, as
    /// do exact cubes (recorded nowhere: they need not cover their rectangle).
    fn record(&mut self, s: &Splat, width: u32) -> bool {
        if s.cube || !self.tracks(s) {
            return true;
        }
        if self.slots.is_empty() {
            self.slots = vec![(0, 0.0); 1 << Self::BITS];
        }
        if s.x0 == s.x1 && s.y0 == s.y1 {
            // Most splats at the cut: one lookup, then the same decision and update as below.
            let p = s.y0 * width + s.x0;
            let i = self.find(p);
            let (k, d) = self.slots[i];
            if k == 0 {
                self.slots[i] = (p + 1, s.ndc_depth);
                self.used.push(i as u32);
            } else if d > s.ndc_depth {
                self.slots[i].1 = s.ndc_depth;
            } else {
                return false;
            }
            return true;
        }
        // Look every pixel up once; keep where it was found for the update below.
        let mut found = [(0u32, usize::MAX); Self::MAX_PIXELS as usize];
        let mut n = 0;
        let mut hidden = true;
        for y in s.y0..=s.y1 {
            for x in s.x0..=s.x1 {
                let p = y * width + x;
                let i = self.find(p);
                let (k, d) = self.slots[i];
                if k == 0 || d > s.ndc_depth {
                    hidden = false;
                }
                found[n] = (p, if k == 0 { usize::MAX } else { i });
                n += 1;
            }
        }
        if hidden {
            return false;
        }
        for &(p, i) in &found[..n] {
            if i == usize::MAX {
                // Probed again: an earlier pixel of this splat may have taken the empty slot.
                let j = self.find(p);
                self.slots[j] = (p + 1, s.ndc_depth);
                self.used.push(j as u32);
            } else if s.ndc_depth < self.slots[i].1 {
                self.slots[i].1 = s.ndc_depth;
            }
        }
        true
    }
}

/// Bounds of a chunk's base length (the nodes of a chunk of pixel-sized splats, about 1/64 of
/// the image's pixels, which rarely overlaps itself): small enough that nodes late in a pass
/// are culled by splats from earlier in the same pass, large enough to keep threads busy.
/// [`ChunkSizer`] shortens chunks whose nodes write more pixels.
const MIN_CHUNK: usize = 1 << 8;
const MAX_CHUNK: usize = 1 << 16;
/// Nodes per parallel block within a chunk.
const BLOCK: usize = 1024;
/// The fewest nodes a chunk sized by [`ChunkSizer`] holds.
const MIN_SIZED_CHUNK: usize = 64;
/// The first chunk of a pass sized by [`ChunkSizer`].
const FIRST_SIZED_CHUNK: usize = 256;

/// Chunk lengths of one pass, sized by the pixels its nodes write.
///
/// Why: a chunk is meant to rarely overlap itself, so that nodes late in a pass are culled by
/// the occlusion tiles of earlier chunks. `chunk_len` nodes suit a cut of pixel-sized splats,
/// but a node of a near small model writes hundreds of pixels (the house's leaves are exact
/// cubes of about 60 pixels in the view and 300 texels in its shadow map, four or five per
/// queued parent): 18 k parents then wrote several times the whole shadow map before its tiles
/// were refreshed, so every hidden voxel of the interior was drawn, and nearly every pixel it
/// tested was rejected one by one. After each chunk the next one is sized so that it writes
/// about `chunk_len` pixels, as the previous one did per node.
///
/// The image does not depend on the chunking: a node is culled only when every pixel it could
/// write already holds a strictly nearer depth, or (in a block's [`LocalDepth`]) a nearer or
/// equal depth of a splat with a lower id, so only nodes that cannot win a pixel are dropped.
struct ChunkSizer {
    /// Nodes per chunk for one pixel per node, and the most per chunk.
    base: usize,
    next: usize,
}

impl ChunkSizer {
    fn new(base: usize, occlusion_culling: bool) -> Self {
        // Without occlusion culling there is nothing to refresh between chunks: one chunk.
        if !occlusion_culling {
            return Self {
                base: usize::MAX,
                next: usize::MAX,
            };
        }
        // A pass starts with a short chunk to measure what its nodes write.
        Self {
            base,
            next: base.min(FIRST_SIZED_CHUNK),
        }
    }

    fn len(&self) -> usize {
        self.next
    }

    /// Runs `chunk` over `items` cut into chunks of this sizer's lengths; `chunk` returns the
    /// pixels the chunk wrote.
    fn run<T>(mut self, items: &[T], mut chunk: impl FnMut(&[T]) -> u64) {
        let mut rest = items;
        while !rest.is_empty() {
            let (head, tail) = rest.split_at(self.len().min(rest.len()));
            let pixels = chunk(head);
            self.update(head.len(), pixels);
            rest = tail;
        }
    }

    /// After a chunk of `nodes` nodes wrote `pixels` pixels (rectangles and cubes).
    fn update(&mut self, nodes: usize, pixels: u64) {
        if self.base == usize::MAX || nodes == 0 {
            return;
        }
        if pixels == 0 {
            // Only splits and culls: nothing says what the next nodes write, so the chunk
            // grows (a pass of splits soon runs at full length) without jumping to the full
            // length in one step, where the next chunk could be all large cubes.
            self.next = self.next.saturating_mul(2).min(self.base);
            return;
        }
        let per_node = (pixels / nodes as u64).max(1);
        let len = (self.base as u64 / per_node) as usize;
        self.next = len.clamp(MIN_SIZED_CHUNK.min(self.base), self.base);
    }
}

/// Nodes per parallel block for a chunk of `len`: at most [`BLOCK`], and at least four blocks
/// when the chunk is small, so that short chunks still spread over the threads. (Not more:
/// each block culls with its own [`LocalDepth`], and eight blocks per chunk drew 1.5 % more
/// splats on the near 3M-voxel sphere.)
fn block_len(len: usize) -> usize {
    len.div_ceil(4).clamp(1, BLOCK)
}

/// Everything a chunk needs to read.
struct Ctx<'a, 'b> {
    objects: &'a [VoxelInstance<'b>],
    fast: &'a [Option<Fast>],
    cam: &'a Camera,
    view_rot: Mat3,
    settings: &'a PassSettings<'a>,
}

/// Draws voxel objects into `target`, with `scratch`'s buffers (its refs and levels are this
/// pass's on return).
pub(crate) fn draw_voxels(
    objects: &[VoxelInstance<'_>],
    cam: &Camera,
    target: &mut DepthTarget,
    settings: &PassSettings<'_>,
    scratch: &mut VoxelScratch,
) -> VoxelPass {
    let VoxelScratch {
        fast,
        queue,
        next,
        deferred,
        next_deferred,
        blocks,
        bases,
        dirty,
        refs,
        levels: level_stats,
    } = scratch;
    let view_rot = cam.view_rotation();
    fast.clear();
    fast.extend(objects.iter().map(|o| {
        o.deform.uniform_affine().map(|a| {
            let view_from_voxel = cam.view_from_world * glam::Mat4::from(a);
            let linear = Mat3::from_mat4(view_from_voxel);
            let abs = Mat3::from_cols(
                linear.x_axis.abs(),
                linear.y_axis.abs(),
                linear.z_axis.abs(),
            );
            let wl = Mat3::from(a.matrix3);
            Fast {
                linear,
                translation: view_from_voxel.w_axis.truncate(),
                half_extent_unit: abs * Vec3::splat(0.5),
                edge_unit: wl
                    .x_axis
                    .length()
                    .max(wl.y_axis.length())
                    .max(wl.z_axis.length()),
                normal_view: linear.inverse().transpose(),
                inv_linear: linear.inverse(),
            }
        })
    }));
    let ctx = Ctx {
        objects,
        fast: &fast[..],
        cam,
        view_rot,
        settings,
    };
    let levels = usize::from(crate::svo::MAX_DEPTH) + 1;

    queue.clear();
    queue.extend(
        objects
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                !o.svo.is_empty() && (!settings.shadow_casters_only || o.casts_shadows)
            })
            .map(|(i, o)| QNode {
                obj: i as u32,
                node: o.svo.root(),
            }),
    );
    refs.clear();
    level_stats.clear();
    level_stats.resize(levels, LevelStats::default());
    deferred.clear();

    let mut out = VoxelPass {
        rect_pixels: 0,
        cube_pixels: 0,
        traversal_ms: 0.0,
        splat_ms: 0.0,
    };
    let mut acc = Accum {
        out: &mut out,
        refs,
        levels: level_stats,
        bases,
        dirty,
    };
    let pixels = cam.width as usize * cam.height as usize;
    let chunk_len = (pixels / 64).clamp(MIN_CHUNK, MAX_CHUNK);
    let mut splat_count: u64 = 0;
    while !queue.is_empty() || !deferred.is_empty() {
        next.clear();
        next_deferred.clear();
        ChunkSizer::new(chunk_len, settings.occlusion_culling).run(queue, |chunk| {
            run_chunk(
                chunk,
                &ctx,
                target,
                blocks,
                levels,
                &mut splat_count,
                &mut acc,
                next,
                next_deferred,
                |q, t, b| classify_node(&ctx, q, t, b),
            )
        });
        // The previous pass's back-facing nodes, now that this pass's nodes are drawn.
        ChunkSizer::new(chunk_len, settings.occlusion_culling).run(deferred, |chunk| {
            run_chunk(
                chunk,
                &ctx,
                target,
                blocks,
                levels,
                &mut splat_count,
                &mut acc,
                next,
                next_deferred,
                |d, t, b| redecide(&ctx, d, t, b),
            )
        });
        std::mem::swap(queue, next);
        std::mem::swap(deferred, next_deferred);
    }
    while acc.levels.last().is_some_and(|l| l.visited == 0) {
        acc.levels.pop();
    }
    out
}

/// Where [`run_chunk`] adds what a chunk produced, and its scratch.
struct Accum<'a> {
    out: &'a mut VoxelPass,
    refs: &'a mut Vec<QNode>,
    levels: &'a mut Vec<LevelStats>,
    bases: &'a mut Vec<u64>,
    dirty: &'a mut Vec<u32>,
}

/// Classifies a chunk in parallel blocks, writes its splats (ids in chunk order), queues its
/// children and deferred nodes, and refreshes the occlusion tiles it dirtied. Returns the
/// pixels its splats covered (rectangles and cubes).
#[allow(
    clippy::too_many_arguments,
    reason = "the traversal's state, split out of one loop so the deferred pass shares it"
)]
fn run_chunk<T: Sync>(
    chunk: &[T],
    ctx: &Ctx<'_, '_>,
    target: &mut DepthTarget,
    blocks: &mut Vec<BlockOut>,
    levels: usize,
    splat_count: &mut u64,
    acc: &mut Accum<'_>,
    next: &mut Vec<QNode>,
    next_deferred: &mut Vec<Deferred>,
    per_item: impl Fn(&T, &DepthTarget, &mut BlockOut) + Sync,
) -> u64 {
    let t0 = Instant::now();
    let block = block_len(chunk.len());
    let n_blocks = chunk.len().div_ceil(block);
    if blocks.len() < n_blocks {
        blocks.resize_with(n_blocks, BlockOut::default);
    }
    let target_ref: &DepthTarget = target;
    chunk
        .par_chunks(block)
        .zip(blocks[..n_blocks].par_iter_mut())
        .for_each(|(items, b)| {
            b.clear(levels);
            for it in items {
                per_item(it, target_ref, b);
            }
        });
    let t1 = Instant::now();
    // Ids are positions in chunk order, so the image does not depend on the thread count.
    let bases = &mut *acc.bases;
    bases.clear();
    let mut base = u64::from(ctx.settings.id_base) + *splat_count;
    for b in &blocks[..n_blocks] {
        bases.push(base);
        base += b.splats.len() as u64;
    }
    *splat_count = base - u64::from(ctx.settings.id_base);
    blocks[..n_blocks]
        .par_iter_mut()
        .zip(bases.par_iter())
        .for_each(|(b, &base)| {
            let BlockOut {
                splats,
                dirty,
                rect_pixels,
                cube_pixels,
                ..
            } = b;
            for (i, (s, q)) in splats.iter().enumerate() {
                let index = (base + i as u64).min(u64::from(MAX_SPLAT_INDEX)) as u32;
                let id = index << FACE_BITS;
                let pixels = u64::from(s.x1 - s.x0 + 1) * u64::from(s.y1 - s.y0 + 1);
                if s.cube
                    && let Some(cube) = cube_in_view(ctx, q)
                {
                    write_cube(target_ref, ctx.cam, s, &cube, id, dirty);
                    *cube_pixels += pixels;
                } else {
                    let key = pack_key(s.ndc_depth, id);
                    target_ref.write_rect(s.x0, s.y0, s.x1, s.y1, key, dirty);
                    *rect_pixels += pixels;
                }
            }
        });
    let dirty = &mut *acc.dirty;
    dirty.clear();
    let out = &mut *acc.out;
    let mut written = 0;
    for b in &blocks[..n_blocks] {
        next.extend_from_slice(&b.children);
        next_deferred.extend_from_slice(&b.deferred);
        if ctx.settings.keep_refs {
            acc.refs.extend(b.splats.iter().map(|(_, q)| *q));
        }
        dirty.extend_from_slice(&b.dirty);
        out.rect_pixels += b.rect_pixels;
        out.cube_pixels += b.cube_pixels;
        written += b.rect_pixels + b.cube_pixels;
        for (a, s) in acc.levels.iter_mut().zip(&b.stats) {
            a.add(s);
        }
    }
    if ctx.settings.occlusion_culling {
        target.update_dirty(dirty);
    } else {
        target.clear_dirty(dirty);
    }
    let t2 = Instant::now();
    out.traversal_ms += (t1 - t0).as_secs_f64() * 1e3;
    out.splat_ms += (t2 - t1).as_secs_f64() * 1e3;
    written
}

/// First visit of a queued node.
#[inline]
fn classify_node(ctx: &Ctx<'_, '_>, q: &QNode, target: &DepthTarget, b: &mut BlockOut) {
    let st = &mut b.stats[usize::from(q.node.level)];
    st.visited += 1;
    let obj = &ctx.objects[q.obj as usize];
    match classify(
        obj,
        ctx.fast[q.obj as usize].as_ref(),
        q,
        ctx.cam,
        ctx.view_rot,
        target,
        ctx.settings,
    ) {
        Action::Frustum => st.frustum_culled += 1,
        Action::Occluded => st.occlusion_culled += 1,
        Action::Split(c, axes) => {
            st.split += 1;
            split_node(ctx, obj, q, c, axes, target, b);
        }
        Action::Splat(s) => {
            if !b.push_splat(s, *q, ctx.cam.width, ctx.settings.occlusion_culling) {
                b.stats[usize::from(q.node.level)].occlusion_culled += 1;
            }
        }
        Action::Defer {
            rect,
            occ,
            occ_depth,
            split,
        } => b.deferred.push(Deferred {
            q: *q,
            rect,
            occ,
            occ_depth,
            split,
        }),
    }
}

/// Second look at a deferred node: culled if the nearer surface now hides it, otherwise drawn
/// or split as first decided.
#[inline]
fn redecide(ctx: &Ctx<'_, '_>, d: &Deferred, target: &DepthTarget, b: &mut BlockOut) {
    let st = &mut b.stats[usize::from(d.q.node.level)];
    let [x0, y0, x1, y1] = d.occ;
    if ctx.settings.occlusion_culling && target.occluded(x0, y0, x1, y1, d.occ_depth) {
        st.occlusion_culled += 1;
    } else if d.split {
        st.split += 1;
        let obj = &ctx.objects[d.q.obj as usize];
        let (c, _, _, axes) = node_in_view(
            obj,
            ctx.fast[d.q.obj as usize].as_ref(),
            &d.q,
            ctx.cam,
            ctx.view_rot,
        );
        split_node(ctx, obj, &d.q, c, axes, target, b);
    } else if !b.push_splat(d.rect, d.q, ctx.cam.width, ctx.settings.occlusion_culling) {
        b.stats[usize::from(d.q.node.level)].occlusion_culled += 1;
    }
}

/// Splits a node: its children are queued for the next pass, except leaves, which are
/// classified at once.
///
/// Why: a leaf cannot split, so the next pass would only read it back to classify it. At the
/// cut of a near 3M-voxel frame three in four visited nodes are leaves (docs/rendering.md
/// "Traversal"); skipping their round trip through the queue saves its writes, reads and growth.
/// Culling stays conservative, so the visible surface is the same; what can change is which
/// hidden leaves get culled, and which splat wins an exact depth tie (ids are handed out in
/// chunk order, and a leaf's id now falls among its pass's coarser splats instead of after
/// them). The image still does not depend on the thread count.
#[inline]
fn split_node(
    ctx: &Ctx<'_, '_>,
    obj: &VoxelInstance<'_>,
    q: &QNode,
    c: Vec3,
    axes: Mat3,
    target: &DepthTarget,
    b: &mut BlockOut,
) {
    if q.node.level + 1 < obj.svo.depth() {
        push_children(obj, q, ctx.cam, c, axes, &mut b.children);
        return;
    }
    let mut leaves = [q.node; 8];
    let n = children_front_to_back(obj, q, ctx.cam, c, axes, &mut leaves);
    if let Some(f) = ctx.fast[q.obj as usize].as_ref() {
        classify_leaves(ctx, obj, f, q.obj, &leaves[..n], target, b);
        return;
    }
    for node in &leaves[..n] {
        classify_node(
            ctx,
            &QNode {
                obj: q.obj,
                node: *node,
            },
            target,
            b,
        );
    }
}

/// The leaves of one rigid parent, front to back: what [`classify_node`] decides for each, in
/// the same order and with the same results (the same arithmetic, so the same bits).
///
/// Why: three in four visited nodes of a near 3M-voxel frame are leaves (docs/rendering.md
/// "Traversal"). A leaf of a rigid object needs no deformer, subtree box, LOD test or split;
/// the generic path still paid for its checks, its per-node lookups and its decision enum.
/// Here the parent's object, level and statistics slot are looked up once.
#[inline]
fn classify_leaves(
    ctx: &Ctx<'_, '_>,
    obj: &VoxelInstance<'_>,
    f: &Fast,
    obj_index: u32,
    leaves: &[NodeRef],
    target: &DepthTarget,
    b: &mut BlockOut,
) {
    let Some(last) = leaves.last() else {
        return;
    };
    let settings = ctx.settings;
    let level = usize::from(last.level);
    b.stats[level].visited += leaves.len() as u64;
    for node in leaves {
        let q = QNode {
            obj: obj_index,
            node: *node,
        };
        // A leaf's centre is its origin plus half its edge of 1, transformed as `node_in_view`
        // does (same operations, same order: same bits); its half extent is
        // `half_extent_unit * 1.0`.
        let o = node.origin;
        let c = f.linear * Vec3::new(o.x as f32 + 0.5, o.y as f32 + 0.5, o.z as f32 + 0.5)
            + f.translation;
        let Some(fp) = footprint(c, f.half_extent_unit, ctx.cam) else {
            b.stats[level].frustum_culled += 1;
            continue;
        };
        // The block's own depth table first: it culls two in three leaves of a near frame
        // (the sub-pixel layers of a shell behind the nearest one), and a leaf whose every
        // pixel an earlier splat of the block holds at a nearer or equal depth cannot win any
        // of them whatever the tests below would decide (see [`LocalDepth`]).
        let rect = fp.splat(ctx.cam, settings.cube_pixel_threshold);
        if settings.occlusion_culling && b.local.hidden(&rect, ctx.cam.width) {
            b.stats[level].occlusion_culled += 1;
            continue;
        }
        let cull = settings.occlusion_culling && !fp.crosses_near;
        let occ = fp.touched(ctx.cam);
        if settings
            .sampled
            .is_some_and(|m| !m.any(occ[0], occ[1], occ[2], occ[3]))
        {
            b.stats[level].frustum_culled += 1;
            continue;
        }
        if cull && target.occluded(occ[0], occ[1], occ[2], occ[3], fp.ndc_depth) {
            b.stats[level].occlusion_culled += 1;
            continue;
        }
        if cull && faces_away(obj, f, &q, c, ctx.cam.perspective) {
            b.deferred.push(Deferred {
                q,
                rect,
                occ,
                occ_depth: fp.ndc_depth,
                split: false,
            });
            continue;
        }
        if !b.push_splat(rect, q, ctx.cam.width, settings.occlusion_culling) {
            b.stats[level].occlusion_culled += 1;
        }
    }
}

/// View-space centre and AABB half extents of a node, and its longest world edge.
#[inline]
fn node_in_view(
    obj: &VoxelInstance<'_>,
    fast: Option<&Fast>,
    q: &QNode,
    cam: &Camera,
    view_rot: Mat3,
) -> (Vec3, Vec3, f32, Mat3) {
    let size = obj.svo.node_size(q.node.level) as f32;
    if let Some(f) = fast {
        let center_voxel = q.node.origin.as_vec3() + Vec3::splat(0.5 * size);
        let c = f.linear * center_voxel + f.translation;
        (c, f.half_extent_unit * size, f.edge_unit * size, f.linear)
    } else {
        let info = NodeInfo {
            svo: obj.svo,
            node: q.node,
        };
        let d = obj.deform.deform(&info);
        let c = cam.view_from_world.transform_point3(d.center_world);
        let axes = view_rot * d.half_axes_world;
        let abs = Mat3::from_cols(axes.x_axis.abs(), axes.y_axis.abs(), axes.z_axis.abs());
        let edge = 2.0
            * d.half_axes_world
                .x_axis
                .length()
                .max(d.half_axes_world.y_axis.length())
                .max(d.half_axes_world.z_axis.length());
        (c, abs * Vec3::ONE, edge, axes)
    }
}

/// Screen-space footprint of a view-space box: its screen rectangle and the NDC depth of its
/// nearest point. `crosses_near` tells whether the box reaches in front of the near plane.
/// The pixel rectangles are computed only when asked for: most nodes are culled or split and
/// need one of them at most.
#[derive(Clone, Copy)]
struct Footprint {
    sx0: f32,
    sy0: f32,
    sx1: f32,
    sy1: f32,
    ndc_depth: f32,
    /// Nearest view depth, clamped to the near plane.
    d_near: f32,
    crosses_near: bool,
}

impl Footprint {
    /// Every pixel the rectangle touches (for conservative occlusion tests), inclusive.
    #[inline]
    fn touched(&self, cam: &Camera) -> [u32; 4] {
        let (x0, x1) = overlapped_span(self.sx0, self.sx1, cam.width);
        let (y0, y1) = overlapped_span(self.sy0, self.sy1, cam.height);
        [x0, y0, x1, y1]
    }

    /// The splat: pixels whose centres the rectangle covers (see [`pixel_span`]), drawn as the
    /// exact box when wider or taller than `cube_px` pixels.
    #[inline]
    fn splat(&self, cam: &Camera, cube_px: f32) -> Splat {
        let (x0, x1) = pixel_span(self.sx0, self.sx1, cam.width);
        let (y0, y1) = pixel_span(self.sy0, self.sy1, cam.height);
        Splat {
            x0,
            y0,
            x1,
            y1,
            ndc_depth: self.ndc_depth,
            cube: (self.sx1 - self.sx0).max(self.sy1 - self.sy0) > cube_px,
        }
    }
}

#[inline]
fn footprint(c: Vec3, he: Vec3, cam: &Camera) -> Option<Footprint> {
    let d = -c.z;
    let (d_near, d_far) = (d - he.z, d + he.z);
    if !(d_near.is_finite() && d_far.is_finite()) {
        return None;
    }
    let (near, far) = (cam.near, cam.far);
    if d_far <= near || d_near > far {
        return None;
    }
    let (w, h) = (cam.width as f32, cam.height as f32);
    let crosses_near = cam.perspective && d_near < near;
    let dn = d_near.max(near);
    let (x_lo, x_hi, y_lo, y_hi) = if cam.perspective {
        // Extremes of x/d over the box's view-space AABB lie at its nearest (clamped to the
        // near plane) or farthest depth.
        let (xl, xh, yl, yh) = (c.x - he.x, c.x + he.x, c.y - he.y, c.y + he.y);
        // Two divisions instead of eight per node. `0 < near <= dn <= d_far` (a perspective
        // camera's near plane is positive: `OrbitCamera::validate`), so `inv_n >= inv_f > 0`
        // and the sign of each edge picks its extreme: the same value as the min / max of both
        // products (multiplication is monotonic), with half the products.
        let (inv_n, inv_f) = (dn.recip(), d_far.recip());
        let lo = |v: f32| v * if v < 0.0 { inv_n } else { inv_f };
        let hi = |v: f32| v * if v < 0.0 { inv_f } else { inv_n };
        (lo(xl), hi(xh), lo(yl), hi(yh))
    } else {
        (c.x - he.x, c.x + he.x, c.y - he.y, c.y + he.y)
    };
    let sx0 = 0.5 * w + cam.fx * x_lo;
    let sx1 = 0.5 * w + cam.fx * x_hi;
    let sy0 = 0.5 * h - cam.fy * y_hi;
    let sy1 = 0.5 * h - cam.fy * y_lo;
    if sx1 < 0.0 || sy1 < 0.0 || sx0 > w || sy0 > h {
        return None;
    }
    Some(Footprint {
        sx0,
        sy0,
        sx1,
        sy1,
        ndc_depth: cam.ndc_depth(dn),
        d_near: dn,
        crosses_near,
    })
}

/// A node's box in view space for [`write_cube`]: view point `p` lies in the box when
/// `to_local * (p - center)` lies in `[-1, 1]³` (the node's own axes, scaled to its half edge).
struct CubeBox {
    center: Vec3,
    to_local: Mat3,
    /// Whether pixels carry the face they show (rigid objects). A deformed object's
    /// neighbouring boxes do not tile (each has its own blended transform and stretch), so
    /// their faces would shade the steps between them as dark dashes: its pixels keep the
    /// node's smooth normal, with the exact depth and outline all the same.
    faces: bool,
}

/// The box of a splat's node, placed as its footprint was (rigid: the object's transform;
/// otherwise its deformer's box). `None` when the box is degenerate (a zero scale): the splat
/// then keeps its rectangle.
fn cube_in_view(ctx: &Ctx<'_, '_>, q: &QNode) -> Option<CubeBox> {
    let obj = &ctx.objects[q.obj as usize];
    let size = obj.svo.node_size(q.node.level) as f32;
    let fast = ctx.fast[q.obj as usize].as_ref();
    // Placed as its footprint was; a deformed node's `axes` are its view-space half axes.
    let (center, _, _, axes) = node_in_view(obj, fast, q, ctx.cam, ctx.view_rot);
    let to_local = match fast {
        Some(f) => f.inv_linear * (2.0 / size),
        None => axes.inverse(),
    };
    let finite = to_local.to_cols_array().iter().all(|v| v.is_finite());
    (finite && center.is_finite()).then_some(CubeBox {
        center,
        to_local,
        faces: fast.is_some(),
    })
}

/// How far past its faces a cube's slabs reach, in half edges: neighbouring cubes are each
/// intersected in their own frame, and rounding must not open a crack between them (a
/// thousandth of a half edge is far below a pixel at any footprint drawn as a cube).
const CUBE_SLAB: f32 = 1.0 + 1e-3;

/// Draws a splat as its node's exact box: each pixel of the rectangle whose centre ray hits the
/// box gets the depth where it enters (the near plane where the box crosses it) and the face it
/// enters through in the id's low bits (see [`face_code`]), so edges are straight, depth is
/// true across the face, and shading can use the face normal.
///
/// The ray of a pixel in view space is `o + t·dir` with `dir.z = -1`, so `t` is the view depth
/// in both projections (perspective: `o = 0`, `dir = (x, y, -1)`; orthographic: `o = (x, y, 0)`).
fn write_cube(
    target: &DepthTarget,
    cam: &Camera,
    s: &Splat,
    cube: &CubeBox,
    id: u32,
    dirty: &mut Vec<u32>,
) {
    let m = cube.to_local;
    let (w, h) = (cam.width as f32, cam.height as f32);
    // No pixel of the cube is nearer than its nearest point, and its id bits only grow with the
    // face code: a pixel already holding a key at or below this one cannot be won, so its
    // ray–box test is skipped (most pixels of a front-to-back traversal; the final keys are
    // the same, since they only ever decrease).
    let floor_key = pack_key(s.ndc_depth, id);
    // Box-local ray: perspective `o = 0`, so `ol` is the same for every pixel and `dl` steps by
    // a constant along a row; orthographic `dir = -z`, so `dl` is constant and `ol` steps.
    let step = m.x_axis / cam.fx;
    let x0 = s.x0 as f32 + 0.5 - 0.5 * w;
    let row_ray = |y: u32| {
        let vy = (0.5 * h - (y as f32 + 0.5)) / cam.fy;
        if cam.perspective {
            (m * -cube.center, m * Vec3::new(x0 / cam.fx, vy, -1.0))
        } else {
            (
                m * (Vec3::new(x0 / cam.fx, vy, 0.0) - cube.center),
                -m.z_axis,
            )
        }
    };
    let width = cam.width as usize;
    let (xa, xb) = (s.x0 as usize, s.x1 as usize);
    for y in s.y0..=s.y1 {
        let row = y as usize * width;
        let keys = &target.keys[row + xa..=row + xb];
        // Most pixels of a front-to-back frame are rejected here (the house at 800×800: 26.8 M
        // of the 28.5 M pixels tested per frame, view and shadow map), so this loop is kept to
        // a load and a compare, and the row's ray is set up only once a pixel passes.
        let mut ray = None;
        let first = std::ptr::from_ref(&keys[0]).addr();
        for k in keys {
            if k.load(Ordering::Relaxed) > floor_key {
                let (ol_row, dl_row) = *ray.get_or_insert_with(|| row_ray(y));
                // The pixel's place in the row, from its address: no counter in the loop.
                let i = (std::ptr::from_ref(k).addr() - first) / std::mem::size_of::<AtomicU64>();
                let along = step * i as f32;
                let (ol, dl) = if cam.perspective {
                    (ol_row, dl_row + along)
                } else {
                    (ol_row + along, dl_row)
                };
                cube_pixel(k, cam, cube, ol, dl, id);
            }
        }
    }
    target.mark_dirty(s.x0, s.y0, s.x1, s.y1, dirty);
}

/// One pixel of [`write_cube`] that its floor key did not reject: the box-local ray `ol +
/// t·dl` enters the box at view depth `t`, written with the face it enters through.
#[inline]
fn cube_pixel(k: &AtomicU64, cam: &Camera, cube: &CubeBox, ol: Vec3, dl: Vec3, id: u32) {
    let Some((t, face)) = enter_box(ol, dl) else {
        return;
    };
    if t.1 < cam.near || t.0 > cam.far {
        return;
    }
    let (depth, face) = if t.0 < cam.near {
        (cam.near, 0)
    } else {
        (t.0, if cube.faces { face } else { 0 })
    };
    let key = pack_key(cam.ndc_depth(depth), id | face);
    if key < k.load(Ordering::Relaxed) {
        k.fetch_min(key, Ordering::Relaxed);
    }
}

/// Where the ray `o + t·d` (box-local) is inside `[-CUBE_SLAB, CUBE_SLAB]³`: `(t_enter,
/// t_exit)` and the face code it enters through, or `None` when it misses.
#[inline]
fn enter_box(o: Vec3, d: Vec3) -> Option<((f32, f32), u32)> {
    // Slabs of the three axes at once: an axis the ray runs parallel to (a zero component, an
    // infinite reciprocal) holds the whole ray or none of it.
    let inv = d.recip();
    let (a, b) = ((-CUBE_SLAB - o) * inv, (CUBE_SLAB - o) * inv);
    let (near, far) = (a.min(b), a.max(b));
    let (mut t0, mut t1, mut face) = (f32::NEG_INFINITY, f32::INFINITY, 0);
    for k in 0..3 {
        if d[k] == 0.0 {
            if o[k].abs() > CUBE_SLAB {
                return None;
            }
            continue;
        }
        if near[k] > t0 {
            t0 = near[k];
            face = face_code(k, d[k]);
        }
        t1 = t1.min(far[k]);
    }
    (t0 <= t1 && face != 0).then_some(((t0, t1), face))
}

#[inline]
fn classify(
    obj: &VoxelInstance<'_>,
    fast: Option<&Fast>,
    q: &QNode,
    cam: &Camera,
    view_rot: Mat3,
    target: &DepthTarget,
    settings: &PassSettings<'_>,
) -> Action {
    let (c, he, edge_world, axes_view) = node_in_view(obj, fast, q, cam, view_rot);
    let has_children = !obj.svo.is_leaf(&q.node);
    let info = NodeInfo {
        svo: obj.svo,
        node: q.node,
    };
    // Deformers whose internal-node boxes may not contain their subtree (skinning) give a
    // separate, conservative box for culling: the node's own box joined with its subtree's.
    let cull_box = if has_children && fast.is_none() {
        obj.deform.subtree_bounds(&info).map(|d| {
            let axes = view_rot * d.half_axes_world;
            let cc = cam.view_from_world.transform_point3(d.center_world);
            let mut che = Mat3::from_cols(axes.x_axis.abs(), axes.y_axis.abs(), axes.z_axis.abs())
                * Vec3::ONE;
            if q.node.level + 1 < obj.svo.depth() {
                che += Vec3::splat(lod_margin(cc, che, cam, settings.lod_pixel_threshold));
            }
            let lo = (cc - che).min(c - he);
            let hi = (cc + che).max(c + he);
            ((lo + hi) * 0.5, (hi - lo) * 0.5)
        })
    } else {
        None
    };
    let splat = footprint(c, he, cam);
    let cull = match cull_box {
        Some((cc, che)) => footprint(cc, che, cam),
        None => None,
    };
    let Some(cull_fp) = cull.or(splat) else {
        return Action::Frustum;
    };
    // The occlusion test covers every pixel the culling rectangle touches: a child's splat
    // may fall back to the pixel under its own centre, outside the parent's pixel span.
    let [x0, y0, x1, y1] = cull_fp.touched(cam);
    if settings.sampled.is_some_and(|m| !m.any(x0, y0, x1, y1)) {
        return Action::Frustum;
    }
    if settings.occlusion_culling
        && !cull_fp.crosses_near
        && target.occluded(x0, y0, x1, y1, cull_fp.ndc_depth)
    {
        return Action::Occluded;
    }
    let Some(fp) = splat else {
        // The node's own box is off screen but its subtree may not be.
        return Action::Split(c, axes_view);
    };
    let edge_px = if cam.perspective {
        edge_world * cam.fy / fp.d_near
    } else {
        edge_world * cam.fy.max(cam.fx)
    };
    let split = has_children && (fp.crosses_near || edge_px > settings.lod_pixel_threshold);
    if settings.occlusion_culling && !fp.crosses_near && !cull_fp.crosses_near {
        let away = match fast {
            Some(f) => faces_away(obj, f, q, c, cam.perspective),
            // A deformed node's LOD normal turned by its own (blended) transform.
            None => deformed_faces_away(obj, &info, view_rot, c, cam.perspective),
        };
        if away {
            return Action::Defer {
                rect: fp.splat(cam, settings.cube_pixel_threshold),
                occ: [x0, y0, x1, y1],
                occ_depth: cull_fp.ndc_depth,
                split,
            };
        }
    }
    if split {
        return Action::Split(c, axes_view);
    }
    Action::Splat(fp.splat(cam, settings.cube_pixel_threshold))
}

/// How far (world units, every axis) a descendant drawn at LOD may reach past the subtree box
/// of [`NodeDeform::subtree_bounds`] (which bounds the leaves and every descendant's centre): a
/// node drawn without splitting has a projected edge of at most `lod_px` pixels, and its box's
/// view-space half extent is at most 1.5 edges (three half axes). `cc`, `che`: the subtree box
/// in view space; a perspective node's edge in world units is at most `lod_px` times its
/// nearest depth (at most the box's farthest) over `fy`.
#[inline]
fn lod_margin(cc: Vec3, che: Vec3, cam: &Camera, lod_px: f32) -> f32 {
    // A huge threshold only makes the box huge (culling nothing), never infinite.
    let lod_px = lod_px.clamp(0.0, 1e6);
    let edge_world = if cam.perspective {
        lod_px * (-cc.z + che.z).max(cam.near) / cam.fy
    } else {
        lod_px / cam.fy.max(cam.fx)
    };
    1.5 * edge_world
}

/// [`faces_away`] for a deformed node: its LOD normal turned by the deformer (skinning: the
/// node's blended matrix). Only decides when a node is drawn (deferral), never whether.
#[inline]
fn deformed_faces_away(
    obj: &VoxelInstance<'_>,
    info: &NodeInfo<'_>,
    view_rot: Mat3,
    c_view: Vec3,
    perspective: bool,
) -> bool {
    let (_, e) = info.color_and_normal();
    let n_world = obj
        .deform
        .normal_to_world(info, crate::svo::decode_normal(e));
    let to_eye = if perspective { -c_view } else { Vec3::Z };
    (view_rot * n_world).dot(to_eye) < 0.0
}

/// Whether a node's LOD normal points away from the eye (rigid objects only: a deformed
/// node's normal would need its blended transform).
#[inline]
fn faces_away(
    obj: &VoxelInstance<'_>,
    f: &Fast,
    q: &QNode,
    c_view: Vec3,
    perspective: bool,
) -> bool {
    let e = obj.svo.node_color_and_normal(&q.node).1;
    // The octahedral decoding of `decode_normal` without its normalisation (a sign test).
    let (px, py) = (
        f32::from(e & 0xff) / 255.0 * 2.0 - 1.0,
        f32::from(e >> 8) / 255.0 * 2.0 - 1.0,
    );
    let z = 1.0 - px.abs() - py.abs();
    let (x, y) = if z < 0.0 {
        (
            (1.0 - py.abs()) * px.signum(),
            (1.0 - px.abs()) * py.signum(),
        )
    } else {
        (px, py)
    };
    let n_view = f.normal_view * Vec3::new(x, y, z);
    let to_eye = if perspective { -c_view } else { Vec3::Z };
    n_view.dot(to_eye) < 0.0
}

/// Every pixel that `[s0, s1]` touches, clamped to the image.
#[inline]
fn overlapped_span(s0: f32, s1: f32, n: u32) -> (u32, u32) {
    // Truncation towards zero, then clamping to `0..n`, equals flooring then clamping: the two
    // differ only on (-1, 0), which both clamp to 0. Integer clamps are cheaper than float
    // ones (no NaN handling; NaN truncates to 0 as the float clamp's `as u32` made it).
    let max = n as i32 - 1;
    (
        (s0 as i32).clamp(0, max) as u32,
        (s1 as i32).clamp(0, max) as u32,
    )
}

/// Pixels whose centres lie in `[s0, s1]`, or the pixel under the span's centre when none do
/// (so sub-pixel nodes never vanish), clamped to the image.
#[inline]
fn pixel_span(s0: f32, s1: f32, n: u32) -> (u32, u32) {
    let max = n as i32 - 1;
    let mut a = ceil_i32(s0 - 0.5);
    let mut b = floor_i32(s1 - 0.5);
    // A NaN end compares false in floats, so it never takes the fallback (as integer it is 0).
    if b < a && !s1.is_nan() {
        a = floor_i32(0.5 * (s0 + s1));
        b = a;
    }
    (a.clamp(0, max) as u32, b.clamp(0, max) as u32)
}

/// `x.floor()` as an integer for the screen coordinates of [`pixel_span`], inline instead of a
/// libm call and a second conversion (the traversal's hottest arithmetic). Exact for
/// |x| < 2^31; beyond that it saturates, and NaN gives 0: the result is only used clamped to
/// the image, where it lands on the same edge as the true floor would.
#[inline]
pub(crate) fn floor_i32(x: f32) -> i32 {
    // `x as i32` is the truncation, exactly representable as f32 when |x| < 2^31.
    let t = x as i32;
    if t as f32 > x { t.saturating_sub(1) } else { t }
}

/// `x.ceil()` as [`floor_i32`].
#[inline]
pub(crate) fn ceil_i32(x: f32) -> i32 {
    let t = x as i32;
    if (t as f32) < x {
        t.saturating_add(1)
    } else {
        t
    }
}

/// Queues a node's children, nearest octant first (Fig. 10).
#[inline]
fn push_children(
    obj: &VoxelInstance<'_>,
    q: &QNode,
    cam: &Camera,
    c: Vec3,
    axes_view: Mat3,
    out: &mut Vec<QNode>,
) {
    let mut children = [q.node; 8];
    let n = children_front_to_back(obj, q, cam, c, axes_view, &mut children);
    out.extend(children[..n].iter().map(|&node| QNode { obj: q.obj, node }));
}

/// Writes a node's children to `out`, nearest octant first (Fig. 10): the octant order follows
/// the direction from the eye to the node expressed along the node's own voxel axes. Returns
/// how many there are.
#[inline]
fn children_front_to_back(
    obj: &VoxelInstance<'_>,
    q: &QNode,
    cam: &Camera,
    c: Vec3,
    axes_view: Mat3,
    out: &mut [NodeRef; 8],
) -> usize {
    let dir_view = if cam.perspective { c } else { Vec3::NEG_Z };
    let dir_voxel = axes_view.transpose() * dir_view;
    let svo = obj.svo;
    let mask = svo.child_mask(&q.node);
    if mask == 0 {
        return 0;
    }
    let half = svo.node_size(q.node.level) / 2;
    let level = q.node.level + 1;
    if svo.is_tile(&q.node) {
        // A tile's eight children are its virtual nodes (`Svo::child`), all present.
        let index = q.node.index | IN_TILE;
        for (slot, k) in out.iter_mut().zip(front_to_back_order(dir_voxel)) {
            *slot = NodeRef {
                level,
                index,
                origin: q.node.origin + octant_offset(k, half),
            };
        }
        return 8;
    }
    // `Svo::child` for each octant, with the node's mask and first child read once.
    let first = svo.inner_first_children()[q.node.index as usize];
    // Interior children (every voxel below them enclosed, `Voxel::INTERIOR`) can never show,
    // and drawn as conservative splats one could win a pixel at the shell's edge: they are
    // not queued, leaves or inner nodes (the GPU reads the same from the parent's word).
    let interior = svo.may_have_interior();
    let (colors, normals) = if level < svo.depth() {
        (svo.inner_colors(), svo.inner_normals())
    } else {
        (svo.leaf_colors(), svo.leaf_normals())
    };
    let mut n = 0;
    for k in front_to_back_order(dir_voxel) {
        if mask & (1 << k) != 0 {
            let index = first + child_rank(mask, k);
            if interior && is_interior_value(colors[index as usize], normals[index as usize]) {
                continue;
            }
            out[n] = NodeRef {
                level,
                index,
                origin: q.node.origin + octant_offset(k, half),
            };
            n += 1;
        }
    }
    n
}

/// Grows `out` by the world boxes of `n`'s descendants at level `stop` (or `n`'s own at or
/// below it), visited depth first in octant order: recursion at most five deep, where a heap
/// stack cost a frame allocations.
fn grow_bounds(o: &VoxelInstance<'_>, n: NodeRef, stop: u8, out: &mut Option<(Vec3, Vec3)>) {
    if n.level < stop {
        for k in 0..8 {
            if let Some(c) = o.svo.child(&n, k) {
                grow_bounds(o, c, stop, out);
            }
        }
        return;
    }
    let info = NodeInfo {
        svo: o.svo,
        node: n,
    };
    // The node's own box joined with its subtree box where the deformer has one (skinning),
    // so no leaf sticks out.
    for d in std::iter::once(o.deform.deform(&info)).chain(o.deform.subtree_bounds(&info)) {
        let a = d.half_axes_world;
        let he = Mat3::from_cols(a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs()) * Vec3::ONE;
        let (lo, hi) = (d.center_world - he, d.center_world + he);
        *out = Some(out.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
    }
}

/// World-space AABB of the objects, from their nodes a few levels down (tight enough to fit a
/// shadow map, cheap whatever the model size).
pub(crate) fn voxel_bounds(
    objects: &[VoxelInstance<'_>],
    casters_only: bool,
) -> Option<(Vec3, Vec3)> {
    let mut out: Option<(Vec3, Vec3)> = None;
    for o in objects {
        if o.svo.is_empty() || (casters_only && !o.casts_shadows) {
            continue;
        }
        let stop = o.svo.depth().min(5);
        grow_bounds(o, o.svo.root(), stop, &mut out);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_shrink_as_their_nodes_write_more_pixels_and_stay_within_their_bounds() {
        let mut s = ChunkSizer::new(10_000, true);
        assert_eq!(s.len(), FIRST_SIZED_CHUNK);
        // A cut of pixel-sized splats: the full length.
        s.update(256, 200);
        assert_eq!(s.len(), 10_000);
        // Forty pixels a node: a quarter of the pixels' worth of nodes.
        s.update(10_000, 400_000);
        assert_eq!(s.len(), 250);
        // Exact cubes of hundreds of pixels: never fewer than the minimum.
        s.update(250, 250 * 900);
        assert_eq!(s.len(), MIN_SIZED_CHUNK);
        // Nothing written (splits and culls): the chunk doubles towards the full length.
        s.update(64, 0);
        assert_eq!(s.len(), 128);
        for _ in 0..10 {
            s.update(128, 0);
        }
        assert_eq!(s.len(), 10_000);
        // Small images: the minimum never exceeds the base.
        let mut small = ChunkSizer::new(32, true);
        assert_eq!(small.len(), 32);
        small.update(32, 32 * 1000);
        assert_eq!(small.len(), 32);
        // Without occlusion culling a pass is one chunk.
        let mut all = ChunkSizer::new(10_000, false);
        all.update(10, 10_000);
        assert_eq!(all.len(), usize::MAX);
        assert_eq!(block_len(10_000), BLOCK);
        assert_eq!(block_len(256), 64);
        assert_eq!(block_len(3), 1);
    }

    /// The inline roundings equal the library's `floor`/`ceil` converted with `as i32`
    /// (saturating, NaN to 0) for every class of float: one bit pattern in 251 of all 2^32
    /// (every exponent, both signs, NaNs and infinities), and every float within a few ulps
    /// of each integer from -70,000 to 70,000 and of the i32 limits.
    #[test]
    fn inline_floor_and_ceil_equal_the_library_for_every_float_class() {
        let check = |x: f32| {
            assert_eq!(
                floor_i32(x),
                x.floor() as i32,
                "floor {x:e} ({:#x})",
                x.to_bits()
            );
            assert_eq!(
                ceil_i32(x),
                x.ceil() as i32,
                "ceil {x:e} ({:#x})",
                x.to_bits()
            );
        };
        let mut bits = 0u64;
        while bits <= u64::from(u32::MAX) {
            check(f32::from_bits(bits as u32));
            bits += 251;
        }
        let near = |x: f32| {
            let b = x.to_bits();
            for d in 0..8 {
                check(f32::from_bits(b.wrapping_add(d)));
                check(f32::from_bits(b.wrapping_sub(d)));
            }
        };
        for i in -70_000..=70_000 {
            near(i as f32);
            near(i as f32 + 0.5);
        }
        for x in [
            2_147_483_648.0f32,
            -2_147_483_648.0,
            8_388_608.0,
            -8_388_608.0,
        ] {
            near(x);
        }
        check(f32::NAN);
        check(-f32::NAN);
        check(-0.0);
    }

    /// The integer spans equal their float definitions (floor and ceil, then clamped to the
    /// image) at the extremes: NaN, infinities, beyond `i32`, pixel edges and centres, ±0, and
    /// images of 1 to 16,384 pixels.
    #[test]
    fn spans_equal_their_float_definitions_at_the_extremes() {
        fn clamp_u32(v: f32, n: u32) -> u32 {
            v.clamp(0.0, n as f32 - 1.0) as u32
        }
        let overlapped =
            |s0: f32, s1: f32, n: u32| (clamp_u32(s0.floor(), n), clamp_u32(s1.floor(), n));
        let pixel = |s0: f32, s1: f32, n: u32| {
            let (mut a, mut b) = ((s0 - 0.5).ceil(), (s1 - 0.5).floor());
            if b < a {
                a = (0.5 * (s0 + s1)).floor();
                b = a;
            }
            (clamp_u32(a, n), clamp_u32(b, n))
        };
        let mut values = vec![
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            3e9,
            -3e9,
            2_147_483_648.0,
            -2_147_483_648.0,
            2_147_483_520.0,
            16_777_217.0,
            -0.0,
            0.0,
            1.0 - f32::EPSILON,
            1.0 + f32::EPSILON,
        ];
        for i in -4..=34 {
            let v = i as f32 * 0.25;
            values.extend([v, v + 1e-4, v - 1e-4]);
        }
        for n in [1u32, 2, 7, 800, 16_384] {
            let nf = n as f32;
            values.extend([nf - 0.5, nf, nf + 0.5, nf - 1.0, nf + 1e-3]);
        }
        for n in [1u32, 2, 7, 800, 16_384] {
            for &s0 in &values {
                for &s1 in &values {
                    assert_eq!(
                        overlapped_span(s0, s1, n),
                        overlapped(s0, s1, n),
                        "{s0} {s1} {n}"
                    );
                    assert_eq!(pixel_span(s0, s1, n), pixel(s0, s1, n), "{s0} {s1} {n}");
                }
            }
        }
    }
}

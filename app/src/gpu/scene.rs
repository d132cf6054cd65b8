//! The scene as the GPU holds it: every visible voxel object's node pools packed into inner
//! and attribute pools (each object with spare room so edits that grow its pools stay in
//! place), split into [`PoolChunk`]s of whole objects so each chunk's buffers fit one storage
//! binding, and world-space triangles. Uploaded once; afterwards an edit uploads only the
//! node ranges it changed ([`SceneCache::update_voxel_region`]), a transform change only the
//! small per-object data (and a mesh's triangles, never its textures).
//!
//! Mesh base-colour textures live in one storage buffer of `u32` words, uploaded with the scene:
//! [`TEXTURE_LUT_WORDS`] words of sRGB-byte → linear (the CPU's table, as f32 bits), then
//! [`TEXTURE_ENTRY_WORDS`] words per texture (first texel word, width, height, 0), then the
//! texels, one RGBA8 `u32` each, rows top to bottom. Equal textures are stored once.

use std::ops::Range;

use bytemuck::Zeroable;
use glam::{Mat3, Mat4, UVec3, Vec2, Vec3, Vec4};
use thicket_core::mesh::{MeshModel, Texture, srgb_byte_to_linear};
use thicket_core::scene::{Document, ObjectKind};
use thicket_core::svo::Svo;
use wgpu::util::DeviceExt;

use super::GpuError;
use super::gpu_data::{
    FACE_BITS, GpuTriangle, MAX_TEXTURES, MESH_ID_FLAG, NO_TEXTURE, ObjectInfo, QUEUE_ENTRY_BYTES,
    TEXTURE_ENTRY_WORDS, TEXTURE_LUT_WORDS,
};

/// What an upload wrote.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UploadStats {
    /// The whole scene was packed and uploaded (first frame, objects added, removed or hidden,
    /// a depth or texture change, or grown pools over the device's binding limit).
    pub full: bool,
    /// Of [`Self::bytes`], joint matrices of rigged objects (a pose or time change uploads
    /// only these).
    pub joint_bytes: u64,
    /// Rigged objects' per-node skin data was (re-)uploaded.
    pub skin_data: bool,
    /// Bytes written to GPU buffers.
    pub bytes: u64,
    /// Separate buffer writes.
    pub writes: u32,
    /// A pool outgrew its reserved room and the pools were given new, larger buffers, filled
    /// from the old ones on the GPU (no full upload).
    pub grown: bool,
    /// Bytes those GPU-side copies moved (not sent from the CPU, so not in [`Self::bytes`]).
    pub copied_bytes: u64,
}

impl UploadStats {
    /// Two uploads together (e.g. an edit's regions and the frame drawn after them).
    #[must_use]
    pub fn combined(self, o: Self) -> Self {
        Self {
            full: self.full || o.full,
            joint_bytes: self.joint_bytes + o.joint_bytes,
            skin_data: self.skin_data || o.skin_data,
            bytes: self.bytes + o.bytes,
            writes: self.writes + o.writes,
            grown: self.grown || o.grown,
            copied_bytes: self.copied_bytes + o.copied_bytes,
        }
    }
}

/// A voxel object's place in the packed pools.
pub(super) struct VoxelEntry {
    pub(super) object_id: u64,
    pub(super) depth: u8,
    /// The [`PoolChunk`] holding its pools.
    pub(super) chunk: usize,
    /// First slot of its inner pool in its chunk's inner buffer.
    pub(super) inner_base: u32,
    /// Slots reserved for its inner pool.
    inner_cap: u32,
    /// Slots of its inner pool at the last upload.
    pub(super) inner_len: u32,
    /// Attribute index of its inner node 0 (`attr_inner_base + inner_cap` is leaf 0), global
    /// over all chunks: the id its splats write.
    pub(super) attr_inner_base: u32,
    pub(super) attr_leaf_base: u32,
    leaf_cap: u32,
    pub(super) leaf_len: u32,
    /// Live nodes (inner + leaves): an upper bound on any level's queue.
    live_nodes: u64,
}

impl VoxelEntry {
    /// Bytes its reserved room takes: (inner node pool, attribute pool).
    fn pool_bytes(&self) -> (u64, u64) {
        let inner = u64::from(self.inner_cap);
        (inner * 8, (inner + u64::from(self.leaf_cap)) * 8)
    }
}

/// A mesh object's triangles in the triangle buffer.
struct MeshEntry {
    object_id: u64,
    world_from_object: Mat4,
    /// Per material of its model: the texture index its triangles carry ([`NO_TEXTURE`]:
    /// none), and the texture's shape when uploaded (so a changed texture forces an upload).
    textures: Vec<(f32, Option<TextureShape>)>,
}

/// What identifies an uploaded texture cheaply, without comparing its pixels every frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct TextureShape {
    width: u32,
    height: u32,
    bytes: usize,
}

fn texture_shapes(model: &MeshModel) -> Vec<Option<TextureShape>> {
    model
        .materials
        .iter()
        .map(|m| {
            m.base_color_texture
                .as_ref()
                .filter(|t| t.is_sampleable())
                .map(|t| TextureShape {
                    width: t.width,
                    height: t.height,
                    bytes: t.rgba8.len(),
                })
        })
        .collect()
}

/// The texture buffer's words (layout in the module docs) and, per visible mesh object in
/// document order, the texture index of each of its materials. Checks the buffer against
/// `limit` (bytes per binding) before allocating it.
fn pack_textures(doc: &Document, limit: u64) -> Result<(Vec<u32>, Vec<Vec<f32>>), GpuError> {
    let mut unique: Vec<&Texture> = Vec::new();
    let mut per_mesh = Vec::new();
    for o in doc.objects.iter().filter(|o| o.visible) {
        let ObjectKind::Mesh(m) = &o.kind else {
            continue;
        };
        let mut indices = Vec::with_capacity(m.model.materials.len());
        for mat in &m.model.materials {
            let Some(t) = mat
                .base_color_texture
                .as_ref()
                .filter(|t| t.is_sampleable())
            else {
                indices.push(NO_TEXTURE);
                continue;
            };
            // A duplicated object shares its texture: compare pixels only between textures of
            // the same shape.
            let i = match unique
                .iter()
                .position(|u| u.width == t.width && u.height == t.height && u.rgba8 == t.rgba8)
            {
                Some(i) => i,
                None => {
                    unique.push(t);
                    unique.len() - 1
                }
            };
            if i >= MAX_TEXTURES {
                return Err(GpuError::TooLarge {
                    what: "mesh texture count",
                    bytes: i as u64 + 1,
                    limit: MAX_TEXTURES as u64,
                });
            }
            indices.push(i as f32);
        }
        per_mesh.push(indices);
    }
    let header = TEXTURE_LUT_WORDS + TEXTURE_ENTRY_WORDS * unique.len();
    let texels: u64 = unique
        .iter()
        .map(|t| u64::from(t.width) * u64::from(t.height))
        .sum();
    let total = header as u64 + texels;
    // Word offsets are u32: a limit above 16 GiB still stops at what they can address.
    check_binding(
        "mesh texture buffer",
        total * 4,
        limit.min(u64::from(u32::MAX) * 4),
    )?;
    let mut words = Vec::with_capacity(total as usize);
    words.extend((0..=255u8).map(|b| srgb_byte_to_linear(b).to_bits()));
    let mut offset = header as u32;
    for t in &unique {
        words.extend_from_slice(&[offset, t.width, t.height, 0]);
        offset += t.width * t.height;
    }
    for t in &unique {
        let n = t.width as usize * t.height as usize * 4;
        words.extend(
            t.rgba8[..n]
                .chunks_exact(4)
                .map(|p| u32::from_le_bytes([p[0], p[1], p[2], p[3]])),
        );
    }
    Ok((words, per_mesh))
}

/// The visible objects, in document order, as (id, is voxel).
fn layout_of(doc: &Document) -> Vec<(u64, bool)> {
    doc.objects
        .iter()
        .filter(|o| o.visible)
        .filter_map(|o| match &o.kind {
            ObjectKind::Voxels(v) if !v.svo.is_empty() => Some((o.id, true)),
            ObjectKind::Voxels(_) => None,
            ObjectKind::Mesh(_) => Some((o.id, false)),
            // KRS objects have no pools: the KRS pass (`gpu::krs`) packs them every frame.
            ObjectKind::Krs(_) => None,
        })
        .collect()
}

/// Slots reserved for an object's pool: its length plus a quarter, so the edits of a sculpting
/// session (which add nodes and, moving child blocks, leave freed blocks behind) fill them in
/// place; an edit beyond that gives the pools larger buffers, copied from the old ones on the
/// GPU ([`SceneCache::grow_pools`]).
fn with_room(len: usize) -> u32 {
    (len + len / 4 + 256).min(u32::MAX as usize) as u32
}

/// An inner node's GPU word pair: first child, then the child mask with, in bits 8–15, which
/// of those children are interior (`Voxel::INTERIOR`: every voxel below them enclosed), so
/// the traversal never queues them (`shaders/common/asvo.wgsl`, `Svo::interior_child_masks`).
fn node_word(first: u32, mask: u8, interior_children: u8) -> [u32; 2] {
    [first, u32::from(mask) | u32::from(interior_children) << 8]
}

fn pack_attr(color: [u8; 4], normal: u16, obj: u32) -> [u32; 2] {
    [u32::from_le_bytes(color), u32::from(normal) | (obj << 16)]
}

/// Consecutive voxel objects whose pools share one inner and one attribute buffer, each under
/// the device's storage binding limit. Attribute indices (splat ids) stay global: the chunk
/// holds ids `attr_start..attr_end`.
pub(super) struct PoolChunk {
    pub(super) inner_buf: wgpu::Buffer,
    pub(super) attr_buf: wgpu::Buffer,
    /// Global attribute index of the buffer's first element.
    pub(super) attr_start: u32,
    /// One past the global attribute index of its last element.
    pub(super) attr_end: u32,
}

/// Bytes [`storage_init`] allocates for `bytes` of data.
fn padded(bytes: u64) -> u64 {
    bytes.max(256).next_multiple_of(16)
}

/// The chunk each object goes into: consecutive objects share a chunk while both its buffers
/// (as [`storage_init`] pads them) stay within `limit`. `sizes` are per object (inner pool
/// bytes, attribute pool bytes). Returns the chunk index per object, or the index of the first
/// object that does not fit a binding alone.
fn assign_chunks(sizes: &[(u64, u64)], limit: u64) -> Result<Vec<usize>, usize> {
    let mut out = Vec::with_capacity(sizes.len());
    let (mut chunk, mut inner, mut attr) = (0usize, 0u64, 0u64);
    for (i, &(oi, oa)) in sizes.iter().enumerate() {
        if padded(oi) > limit || padded(oa) > limit {
            return Err(i);
        }
        if i > 0 && (padded(inner + oi) > limit || padded(attr + oa) > limit) {
            chunk += 1;
            (inner, attr) = (0, 0);
        }
        inner += oi;
        attr += oa;
        out.push(chunk);
    }
    Ok(out)
}

/// Bytes a voxel octree's pools take on the GPU, spare room included: (inner node pool,
/// attribute pool). An object is drawable only when both fit one storage binding
/// (`max_storage_buffer_binding_size`); objects are grouped into chunks within that limit.
#[must_use]
pub fn voxel_pool_bytes(svo: &Svo) -> (u64, u64) {
    let inner = u64::from(with_room(svo.inner_masks().len()));
    let leaf = u64::from(with_room(svo.leaf_colors().len()));
    (inner * 8, (inner + leaf) * 8)
}

/// The uploaded scene: layout, CPU copies of what the incremental paths need, GPU buffers.
pub(super) struct SceneCache {
    layout: Vec<(u64, bool)>,
    pub(super) voxels: Vec<VoxelEntry>,
    meshes: Vec<MeshEntry>,
    /// The voxel pools, in chunks of whole objects (at least one, possibly empty).
    pub(super) chunks: Vec<PoolChunk>,
    pub(super) tri_buf: wgpu::Buffer,
    /// Mesh base-colour textures (layout in the module docs).
    pub(super) texture_buf: wgpu::Buffer,
    pub(super) caster_tris: u32,
    pub(super) tri_count: u32,
    /// Entries each traversal queue needs.
    pub(super) queue_capacity: u64,
    /// The most entries a queue may have: one storage binding's worth.
    queue_limit: u64,
    /// Node pools were rewritten since the skin data was last built (`skin::SkinCache`).
    pub(super) skin_stale: bool,
}

/// Per-frame data derived from the document's current transforms.
pub(super) struct FrameObjects {
    /// `world_from_voxel` per entry of [`SceneCache::voxels`].
    pub(super) world_from_voxel: Vec<Mat4>,
    pub(super) objects: Vec<ObjectInfo>,
    /// World bounds of everything drawn (for fitting the shadow maps).
    pub(super) bounds: Option<(Vec3, Vec3)>,
}

fn grow(b: &mut Option<(Vec3, Vec3)>, lo: Vec3, hi: Vec3) {
    *b = Some(b.map_or((lo, hi), |(a, c)| (a.min(lo), c.max(hi))));
}

/// World AABB of a voxel object from its nodes a few levels down (the CPU reference's
/// `voxel_bounds`).
fn voxel_world_bounds(svo: &Svo, world_from_voxel: Mat4, out: &mut Option<(Vec3, Vec3)>) {
    let stop = svo.depth().min(5);
    let lin = Mat3::from_mat4(world_from_voxel);
    let mut stack = vec![svo.root()];
    while let Some(n) = stack.pop() {
        if n.level < stop {
            stack.extend((0..8).filter_map(|k| svo.child(&n, k)));
            continue;
        }
        let half = 0.5 * svo.node_size(n.level) as f32;
        let c = world_from_voxel.transform_point3(n.origin.as_vec3() + Vec3::splat(half));
        let a = lin * half;
        let he = Mat3::from_cols(a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs()) * Vec3::ONE;
        grow(out, c - he, c + he);
    }
}

/// Triangles of the visible meshes in world space, casters first: (records, caster count,
/// entries). `textures` holds, per visible mesh object in document order, the texture index of
/// each material ([`pack_textures`]).
fn pack_triangles(
    doc: &Document,
    textures: &[Vec<f32>],
) -> (Vec<GpuTriangle>, u32, Vec<MeshEntry>) {
    let mut casters: Vec<GpuTriangle> = Vec::new();
    let mut others: Vec<GpuTriangle> = Vec::new();
    let mut entries = Vec::new();
    let meshes = doc
        .objects
        .iter()
        .filter(|o| o.visible)
        .filter_map(|o| match &o.kind {
            ObjectKind::Mesh(m) => Some((o, m)),
            _ => None,
        });
    for ((o, m), tex) in meshes.zip(textures) {
        let world_from_object = o.transform.matrix();
        entries.push(MeshEntry {
            object_id: o.id,
            world_from_object,
            textures: tex.iter().copied().zip(texture_shapes(&m.model)).collect(),
        });
        let normal_m = Mat3::from_mat4(world_from_object).inverse().transpose();
        let out = if m.casts_shadows {
            &mut casters
        } else {
            &mut others
        };
        for part in &m.model.parts {
            let base = m
                .model
                .materials
                .get(part.material)
                .map_or(Vec4::ONE, |mat| mat.base_color);
            // As `MeshModel::surface_color`: a texture needs texture coordinates.
            let texture = if part.uvs.is_empty() {
                NO_TEXTURE
            } else {
                tex.get(part.material).copied().unwrap_or(NO_TEXTURE)
            };
            for t in 0..part.triangle_count() {
                let idx = part.triangle(t);
                let mut rec = GpuTriangle::zeroed();
                let mut uv = [Vec2::ZERO; 3];
                for (k, &i) in idx.iter().enumerate() {
                    let pw = world_from_object
                        .transform_point3(part.positions.get(i).copied().unwrap_or_default());
                    rec.positions[k] = pw.extend(1.0).to_array();
                    rec.normals[k] = match part.normals.get(i) {
                        Some(n) => (normal_m * *n).extend(1.0).to_array(),
                        None => [0.0; 4],
                    };
                    let vc = part.colors.get(i).copied().unwrap_or(Vec4::ONE);
                    rec.colors[k] = (base * vc).to_array();
                    uv[k] = part.uvs.get(i).copied().unwrap_or_default();
                }
                rec.uv_ab = [uv[0].x, uv[0].y, uv[1].x, uv[1].y];
                rec.uv_c_texture = [uv[2].x, uv[2].y, texture, 0.0];
                out.push(rec);
            }
        }
    }
    let caster_tris = casters.len() as u32;
    casters.extend(others);
    (casters, caster_tris, entries)
}

/// The most entries a traversal queue of a device with binding limit `limit` may have.
fn queue_limit(limit: u64) -> u64 {
    (limit / QUEUE_ENTRY_BYTES).clamp(1, u64::from(u32::MAX))
}

fn check_binding(what: &'static str, bytes: u64, limit: u64) -> Result<(), GpuError> {
    if bytes > limit {
        return Err(GpuError::TooLarge { what, bytes, limit });
    }
    Ok(())
}

/// A zeroed storage buffer of `slots` 8-byte pool entries (padded as [`storage_init`] pads),
/// for pools filled by a GPU-side copy.
fn storage_empty(device: &wgpu::Device, label: &str, slots: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: padded(slots as u64 * 8),
        usage: STORAGE_USAGE,
        mapped_at_creation: false,
    })
}

/// Storage buffers are written by the queue and, when a pool grows, copied into a larger one.
const STORAGE_USAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
    .union(wgpu::BufferUsages::COPY_DST)
    .union(wgpu::BufferUsages::COPY_SRC);

/// A storage buffer holding `data` (at least 256 bytes, so empty scenes bind).
pub(super) fn storage_init(device: &wgpu::Device, label: &str, data: &[u8]) -> wgpu::Buffer {
    let mut contents = data.to_vec();
    contents.resize(contents.len().max(256).next_multiple_of(16), 0);
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &contents,
        usage: STORAGE_USAGE,
    })
}

/// The sorted, merged index ranges an edit of the box `lo..=hi` can have changed: every inner
/// node overlapping the box and the child block of each (children of a node are stored
/// together, and an edit that changes a node's child set moves its block, possibly into a
/// reused block anywhere in the pool — but always one its visited parent points to).
fn region_ranges(svo: &Svo, lo: UVec3, hi: UVec3) -> (Vec<Range<u32>>, Vec<Range<u32>>) {
    let firsts = svo.inner_first_children();
    let masks = svo.inner_masks();
    let (mut inner, mut leaf) = (Vec::new(), Vec::new());
    if masks.is_empty() {
        return (inner, leaf);
    }
    let mut stack = vec![svo.root()];
    while let Some(n) = stack.pop() {
        let i = n.index as usize;
        inner.push(n.index..n.index + 1);
        let mask = masks.get(i).copied().unwrap_or(0);
        let first = firsts.get(i).copied().unwrap_or(0);
        let block = first..first + mask.count_ones();
        if mask == 0 {
            continue;
        }
        if n.level + 1 == svo.depth() {
            leaf.push(block);
            continue;
        }
        inner.push(block);
        for k in 0..8 {
            if let Some(c) = svo.child(&n, k) {
                let size = svo.node_size(c.level);
                let c_hi = c.origin + UVec3::splat(size - 1);
                if c.origin.cmple(hi).all() && c_hi.cmpge(lo).all() {
                    stack.push(c);
                }
            }
        }
    }
    (merge_ranges(inner), merge_ranges(leaf))
}

/// Sorts ranges and merges those that overlap or lie within a few slots of each other (one
/// larger write is cheaper than many tiny ones).
fn merge_ranges(mut v: Vec<Range<u32>>) -> Vec<Range<u32>> {
    const GAP: u32 = 16;
    v.sort_by_key(|r| r.start);
    let mut out: Vec<Range<u32>> = Vec::with_capacity(v.len());
    for r in v.into_iter().filter(|r| !r.is_empty()) {
        match out.last_mut() {
            Some(last) if r.start <= last.end.saturating_add(GAP) => {
                last.end = last.end.max(r.end);
            }
            _ => out.push(r),
        }
    }
    out
}

impl SceneCache {
    /// Packs and uploads every visible object.
    pub(super) fn build(
        device: &wgpu::Device,
        doc: &Document,
        limits: &wgpu::Limits,
    ) -> Result<Self, GpuError> {
        let mut inner: Vec<[u32; 2]> = Vec::new();
        let mut attrs: Vec<[u32; 2]> = Vec::new();
        let mut voxels: Vec<VoxelEntry> = Vec::new();
        let mut names: Vec<String> = Vec::new();
        let mut queue_capacity = 1u64;
        for o in doc.objects.iter().filter(|o| o.visible) {
            let ObjectKind::Voxels(v) = &o.kind else {
                continue;
            };
            let svo = &v.svo;
            if svo.is_empty() {
                continue;
            }
            let obj = u32::try_from(voxels.len())
                .ok()
                .filter(|&i| i <= 0xffff)
                .ok_or(GpuError::TooLarge {
                    what: "voxel object count",
                    bytes: voxels.len() as u64,
                    limit: 0xffff,
                })?;
            let inner_len = svo.inner_masks().len();
            let leaf_len = svo.leaf_colors().len();
            let (inner_cap, leaf_cap) = (with_room(inner_len), with_room(leaf_len));
            let inner_base = inner.len();
            let interior = svo.interior_child_masks();
            inner.extend(
                svo.inner_first_children()
                    .iter()
                    .zip(svo.inner_masks())
                    .enumerate()
                    .map(|(k, (&f, &m))| node_word(f, m, interior.get(k).copied().unwrap_or(0))),
            );
            inner.resize(inner_base + inner_cap as usize, [0, 0]);
            let attr_inner_base = attrs.len();
            attrs.extend(
                svo.inner_colors()
                    .iter()
                    .zip(svo.inner_normals())
                    .map(|(&c, &n)| pack_attr(c, n, obj)),
            );
            attrs.resize(attr_inner_base + inner_cap as usize, [0, 0]);
            let attr_leaf_base = attrs.len();
            attrs.extend(
                svo.leaf_colors()
                    .iter()
                    .zip(svo.leaf_normals())
                    .map(|(&c, &n)| pack_attr(c, n, obj)),
            );
            attrs.resize(attr_leaf_base + leaf_cap as usize, [0, 0]);
            // Ids carry the face of an exact cube in their low bits, below the mesh flag.
            let id_limit = u64::from(MESH_ID_FLAG >> FACE_BITS);
            if attrs.len() as u64 >= id_limit || inner.len() > u32::MAX as usize {
                return Err(GpuError::TooLarge {
                    what: "voxel node ids",
                    bytes: attrs.len() as u64,
                    limit: id_limit,
                });
            }
            let live_nodes = svo.inner_count() + svo.leaf_count();
            queue_capacity = queue_capacity.max(live_nodes);
            names.push(o.name.clone());
            voxels.push(VoxelEntry {
                object_id: o.id,
                depth: svo.depth(),
                chunk: 0,
                inner_base: inner_base as u32,
                inner_cap,
                inner_len: inner_len as u32,
                attr_inner_base: attr_inner_base as u32,
                attr_leaf_base: attr_leaf_base as u32,
                leaf_cap,
                leaf_len: leaf_len as u32,
                live_nodes,
            });
        }
        let limit = limits.max_storage_buffer_binding_size;
        let chunks = chunk_pools(device, &mut voxels, &names, &inner, &attrs, limit)?;
        let (texture_words, textures) = pack_textures(doc, limit)?;
        let (tris, caster_tris, meshes) = pack_triangles(doc, &textures);
        check_binding(
            "triangle buffer",
            std::mem::size_of_val(tris.as_slice()) as u64,
            limit,
        )?;
        Ok(Self {
            layout: layout_of(doc),
            voxels,
            meshes,
            chunks,
            tri_buf: storage_init(device, "triangles", bytemuck::cast_slice(&tris)),
            texture_buf: storage_init(
                device,
                "mesh textures",
                bytemuck::cast_slice(&texture_words),
            ),
            caster_tris,
            tri_count: tris.len() as u32,
            queue_capacity: queue_capacity.clamp(1, queue_limit(limit)),
            queue_limit: queue_limit(limit),
            skin_stale: true,
        })
    }

    /// Bytes the scene's buffers hold.
    pub(super) fn bytes(&self) -> u64 {
        let pools: u64 = self
            .chunks
            .iter()
            .map(|c| c.inner_buf.size() + c.attr_buf.size())
            .sum();
        pools + self.tri_buf.size() + self.texture_buf.size()
    }

    /// Buffers a full upload writes.
    pub(super) fn buffer_count(&self) -> u32 {
        2 * self.chunks.len() as u32 + 2
    }

    /// Whether the document still has the uploaded layout: the same visible objects in the
    /// same order, each voxel pool at its uploaded depth, each mesh with textures of the
    /// uploaded shapes. Pools may have outgrown their room ([`Self::grow_pools`] makes room).
    fn same_layout(&self, doc: &Document) -> bool {
        if layout_of(doc) != self.layout {
            return false;
        }
        let textures_kept = self
            .meshes
            .iter()
            .all(|m| match object_of(doc, m.object_id) {
                Some(thicket_core::scene::Object {
                    kind: ObjectKind::Mesh(mesh),
                    ..
                }) => texture_shapes(&mesh.model)
                    .into_iter()
                    .eq(m.textures.iter().map(|&(_, shape)| shape)),
                _ => false,
            });
        textures_kept
            && self
                .voxels
                .iter()
                .all(|e| voxels_of(doc, e.object_id).is_some_and(|svo| svo.depth() == e.depth))
    }

    /// Makes the scene fit `doc`'s pools when it has the uploaded layout
    /// ([`Self::same_layout`]): a pool that outgrew its reserved room gets new, larger buffers
    /// ([`Self::grow_pools`]). `None` when the layout changed or the grown pools no longer fit
    /// the device's bindings (a full upload then packs, or refuses, the scene).
    fn fit(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
    ) -> Option<UploadStats> {
        if !self.same_layout(doc) {
            return None;
        }
        let within_room = self.voxels.iter().all(|e| {
            voxels_of(doc, e.object_id).is_some_and(|svo| {
                svo.inner_masks().len() <= e.inner_cap as usize
                    && svo.leaf_colors().len() <= e.leaf_cap as usize
            })
        });
        if within_room {
            return Some(UploadStats::default());
        }
        self.grow_pools(device, queue, doc)
    }

    /// Gives every pool that outgrew its room [`with_room`] slots for its new length, and lays
    /// out and chunks the pools again as [`Self::build`] would. The new buffers get the old
    /// ones' uploaded slots by a GPU-side copy, so nothing already on the GPU is sent again:
    /// the caller then writes only what changed (an edit's region or the grown pool), as it
    /// would have within the room. Returns the copy (in [`UploadStats::copied_bytes`]), or
    /// `None` when a grown object no longer fits one binding.
    fn grow_pools(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
    ) -> Option<UploadStats> {
        let limit = device.limits().max_storage_buffer_binding_size;
        let mut grown: Vec<VoxelEntry> = Vec::with_capacity(self.voxels.len());
        let (mut inner_at, mut attr_at) = (0u64, 0u64);
        for e in &self.voxels {
            let svo = voxels_of(doc, e.object_id)?;
            let need = |len: usize, cap: u32| {
                if len > cap as usize {
                    with_room(len)
                } else {
                    cap
                }
            };
            let inner_cap = need(svo.inner_masks().len(), e.inner_cap);
            let leaf_cap = need(svo.leaf_colors().len(), e.leaf_cap);
            let attr_inner_base = u32::try_from(attr_at).ok()?;
            grown.push(VoxelEntry {
                chunk: 0,
                inner_base: u32::try_from(inner_at).ok()?,
                inner_cap,
                attr_inner_base,
                attr_leaf_base: attr_inner_base.checked_add(inner_cap)?,
                leaf_cap,
                ..*e
            });
            inner_at += u64::from(inner_cap);
            attr_at += u64::from(inner_cap) + u64::from(leaf_cap);
        }
        if attr_at >= u64::from(MESH_ID_FLAG >> FACE_BITS) {
            return None;
        }
        let chunks: Vec<PoolChunk> = chunk_spans(&mut grown, limit)
            .ok()?
            .into_iter()
            .enumerate()
            .map(|(c, span)| {
                let label = |what: &str| format!("{what} (chunk {c})");
                PoolChunk {
                    inner_buf: storage_empty(device, &label("inner nodes"), span.inner.len()),
                    attr_buf: storage_empty(device, &label("attributes"), span.attr.len()),
                    attr_start: span.attr.start as u32,
                    attr_end: span.attr.end as u32,
                }
            })
            .collect();
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("grow voxel pools"),
        });
        let mut copied = 0u64;
        for (old, new) in self.voxels.iter().zip(&grown) {
            let (Some(from), Some(to)) = (self.chunks.get(old.chunk), chunks.get(new.chunk)) else {
                return None;
            };
            let attr_from = |base: u32| u64::from(base - from.attr_start) * 8;
            let attr_to = |base: u32| u64::from(base - to.attr_start) * 8;
            let inner_bytes = u64::from(old.inner_len) * 8;
            let leaf_bytes = u64::from(old.leaf_len) * 8;
            let copies = [
                (
                    &from.inner_buf,
                    u64::from(old.inner_base) * 8,
                    &to.inner_buf,
                    u64::from(new.inner_base) * 8,
                    inner_bytes,
                ),
                (
                    &from.attr_buf,
                    attr_from(old.attr_inner_base),
                    &to.attr_buf,
                    attr_to(new.attr_inner_base),
                    inner_bytes,
                ),
                (
                    &from.attr_buf,
                    attr_from(old.attr_leaf_base),
                    &to.attr_buf,
                    attr_to(new.attr_leaf_base),
                    leaf_bytes,
                ),
            ];
            for (src, src_at, dst, dst_at, bytes) in copies {
                if bytes > 0 {
                    enc.copy_buffer_to_buffer(src, src_at, dst, dst_at, bytes);
                    copied += bytes;
                }
            }
        }
        // Submitted now: writes queued before it (into the old buffers) land first, writes
        // queued after it (into the new ones) land after the copy.
        queue.submit(Some(enc.finish()));
        self.voxels = grown;
        self.chunks = chunks;
        self.skin_stale = true;
        Some(UploadStats {
            grown: true,
            copied_bytes: copied,
            ..UploadStats::default()
        })
    }

    /// Makes the GPU copy follow `doc` where that can be seen without an edit region: mesh
    /// transforms (re-packs the triangles) and voxel pools whose length changed (re-uploads
    /// that object). Returns `None` when the layout changed and a full upload is needed.
    pub(super) fn refresh(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
    ) -> Option<UploadStats> {
        let mut stats = self.fit(device, queue, doc)?;
        let meshes_moved = self.meshes.iter().any(|m| {
            object_of(doc, m.object_id).is_none_or(|o| o.transform.matrix() != m.world_from_object)
        });
        if meshes_moved {
            // The textures stay as uploaded (`fits` checked their shapes): re-pack the
            // triangles with the indices they were given.
            let textures: Vec<Vec<f32>> = self
                .meshes
                .iter()
                .map(|m| m.textures.iter().map(|&(i, _)| i).collect())
                .collect();
            let (tris, caster_tris, entries) = pack_triangles(doc, &textures);
            let bytes = std::mem::size_of_val(tris.as_slice()) as u64;
            if bytes > self.tri_buf.size() {
                return None;
            }
            queue.write_buffer(&self.tri_buf, 0, bytemuck::cast_slice(&tris));
            stats.bytes += bytes;
            stats.writes += 1;
            self.caster_tris = caster_tris;
            self.meshes = entries;
        }
        for i in 0..self.voxels.len() {
            let svo = voxels_of(doc, self.voxels[i].object_id)?;
            let e = &self.voxels[i];
            if svo.inner_masks().len() as u32 != e.inner_len
                || svo.leaf_colors().len() as u32 != e.leaf_len
            {
                let all_inner = 0..svo.inner_masks().len() as u32;
                let all_leaf = 0..svo.leaf_colors().len() as u32;
                let s = self.write_ranges(
                    queue,
                    i,
                    svo,
                    std::slice::from_ref(&all_inner),
                    std::slice::from_ref(&all_leaf),
                );
                stats.bytes += s.bytes;
                stats.writes += s.writes;
            }
        }
        Some(stats)
    }

    /// Uploads the node ranges an edit of the box `lo..=hi` (voxel coordinates, inclusive) in
    /// object `object_id` can have changed. `None` when the object is not in the uploaded
    /// scene or its pools outgrew their room (then a full upload is needed).
    pub(super) fn update_voxel_region(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        object_id: u64,
        lo: UVec3,
        hi: UVec3,
    ) -> Option<UploadStats> {
        let i = self.voxels.iter().position(|e| e.object_id == object_id)?;
        let grown = self.fit(device, queue, doc)?;
        let svo = voxels_of(doc, object_id)?;
        if lo.cmpgt(hi).any() {
            // An empty box: no voxel changed (e.g. a rig edit, which frames read anyway).
            return Some(grown);
        }
        let (inner, leaf) = region_ranges(svo, lo, hi);
        Some(grown.combined(self.write_ranges(queue, i, svo, &inner, &leaf)))
    }

    /// Writes the given inner and leaf slot ranges of entry `i` from `svo`.
    fn write_ranges(
        &mut self,
        queue: &wgpu::Queue,
        i: usize,
        svo: &Svo,
        inner: &[Range<u32>],
        leaf: &[Range<u32>],
    ) -> UploadStats {
        let obj = i as u32;
        self.skin_stale = true;
        let e = &mut self.voxels[i];
        let Some(chunk) = self.chunks.get(e.chunk) else {
            return UploadStats::default();
        };
        // Attribute indices are global; the chunk's buffer starts at `attr_start`.
        let attr_inner = u64::from(e.attr_inner_base - chunk.attr_start);
        let attr_leaf = u64::from(e.attr_leaf_base - chunk.attr_start);
        let mut stats = UploadStats::default();
        let firsts = svo.inner_first_children();
        let masks = svo.inner_masks();
        let (ic, inn) = (svo.inner_colors(), svo.inner_normals());
        let (lc, ln) = (svo.leaf_colors(), svo.leaf_normals());
        let interior = svo.interior_child_masks();
        for r in inner {
            let r = r.start as usize..(r.end as usize).min(masks.len());
            if r.is_empty() {
                continue;
            }
            let nodes: Vec<[u32; 2]> = r
                .clone()
                .map(|k| node_word(firsts[k], masks[k], interior.get(k).copied().unwrap_or(0)))
                .collect();
            let a: Vec<[u32; 2]> = r.clone().map(|k| pack_attr(ic[k], inn[k], obj)).collect();
            queue.write_buffer(
                &chunk.inner_buf,
                (u64::from(e.inner_base) + r.start as u64) * 8,
                bytemuck::cast_slice(&nodes),
            );
            queue.write_buffer(
                &chunk.attr_buf,
                (attr_inner + r.start as u64) * 8,
                bytemuck::cast_slice(&a),
            );
            stats.bytes += 16 * r.len() as u64;
            stats.writes += 2;
        }
        for r in leaf {
            let r = r.start as usize..(r.end as usize).min(lc.len());
            if r.is_empty() {
                continue;
            }
            let a: Vec<[u32; 2]> = r.clone().map(|k| pack_attr(lc[k], ln[k], obj)).collect();
            queue.write_buffer(
                &chunk.attr_buf,
                (attr_leaf + r.start as u64) * 8,
                bytemuck::cast_slice(&a),
            );
            stats.bytes += 8 * r.len() as u64;
            stats.writes += 1;
        }
        e.inner_len = masks.len() as u32;
        e.leaf_len = lc.len() as u32;
        e.live_nodes = svo.inner_count() + svo.leaf_count();
        self.queue_capacity = self
            .voxels
            .iter()
            .map(|v| v.live_nodes)
            .max()
            .unwrap_or(1)
            .clamp(1, self.queue_limit);
        stats
    }

    /// Transforms, normal matrices and bounds from the document's current state.
    pub(super) fn frame_objects(&self, doc: &Document) -> FrameObjects {
        let mut f = FrameObjects {
            world_from_voxel: Vec::with_capacity(self.voxels.len()),
            objects: Vec::with_capacity(self.voxels.len()),
            bounds: None,
        };
        for e in &self.voxels {
            let (m, svo) = match object_of(doc, e.object_id).map(|o| (o, &o.kind)) {
                Some((o, ObjectKind::Voxels(v))) => {
                    (o.transform.matrix() * v.object_from_voxel(), Some(&v.svo))
                }
                _ => (Mat4::IDENTITY, None),
            };
            let nm = Mat3::from_mat4(m).inverse().transpose();
            f.objects.push(ObjectInfo {
                normal_from_voxel: [
                    nm.x_axis.extend(0.0).to_array(),
                    nm.y_axis.extend(0.0).to_array(),
                    nm.z_axis.extend(0.0).to_array(),
                ],
                ..ObjectInfo::zeroed()
            });
            // A rigged object's bounds depend on its pose: `skin::SkinCache` adds them.
            if let Some(svo) = svo.filter(|_| !is_rigged(doc, e.object_id)) {
                voxel_world_bounds(svo, m, &mut f.bounds);
            }
            f.world_from_voxel.push(m);
        }
        for o in doc.objects.iter().filter(|o| o.visible) {
            if let ObjectKind::Mesh(m) = &o.kind {
                let w = o.transform.matrix();
                for part in &m.model.parts {
                    for t in 0..part.triangle_count() {
                        for i in part.triangle(t) {
                            let p = w.transform_point3(
                                part.positions.get(i).copied().unwrap_or_default(),
                            );
                            grow(&mut f.bounds, p, p);
                        }
                    }
                }
            }
        }
        f
    }
}

/// Splits the packed pools into [`PoolChunk`]s of whole objects (see [`assign_chunks`]), sets
/// each entry's chunk and makes its `inner_base` local to that chunk's buffer.
fn chunk_pools(
    device: &wgpu::Device,
    voxels: &mut [VoxelEntry],
    names: &[String],
    inner: &[[u32; 2]],
    attrs: &[[u32; 2]],
    limit: u64,
) -> Result<Vec<PoolChunk>, GpuError> {
    let spans = chunk_spans(voxels, limit).map_err(|i| {
        let (inner_bytes, attr_bytes) = voxels[i].pool_bytes();
        let (what, bytes) = if padded(attr_bytes) > limit {
            ("attribute pool", attr_bytes)
        } else {
            ("inner node pool", inner_bytes)
        };
        GpuError::ObjectTooLarge {
            object: names.get(i).cloned().unwrap_or_default(),
            what,
            bytes,
            limit,
        }
    })?;
    Ok(spans
        .into_iter()
        .enumerate()
        .map(|(c, span)| {
            let label = |what: &str| format!("{what} (chunk {c})");
            PoolChunk {
                inner_buf: storage_init(
                    device,
                    &label("inner nodes"),
                    bytemuck::cast_slice(&inner[span.inner]),
                ),
                attr_buf: storage_init(
                    device,
                    &label("attributes"),
                    bytemuck::cast_slice(&attrs[span.attr.clone()]),
                ),
                attr_start: span.attr.start as u32,
                attr_end: span.attr.end as u32,
            }
        })
        .collect())
}

/// The global slot ranges one [`PoolChunk`] holds: inner slots and attribute indices.
struct ChunkSpan {
    inner: Range<usize>,
    attr: Range<usize>,
}

/// Groups consecutive objects into chunks within `limit` ([`assign_chunks`], sized by their
/// reserved room), sets each entry's `chunk` and makes its `inner_base` relative to its chunk.
/// The entries' bases must be global and consecutive, as [`SceneCache::build`] and
/// [`SceneCache::grow_pools`] lay them out. `Err(i)`: object `i` alone exceeds a binding.
fn chunk_spans(voxels: &mut [VoxelEntry], limit: u64) -> Result<Vec<ChunkSpan>, usize> {
    let sizes: Vec<(u64, u64)> = voxels.iter().map(VoxelEntry::pool_bytes).collect();
    let of = assign_chunks(&sizes, limit)?;
    let count = of.last().map_or(1, |&c| c + 1);
    let mut spans = Vec::with_capacity(count);
    for c in 0..count {
        let members: Vec<usize> = (0..voxels.len()).filter(|&i| of[i] == c).collect();
        let span = match (members.first(), members.last()) {
            (Some(&a), Some(&b)) => {
                let (first, last) = (&voxels[a], &voxels[b]);
                ChunkSpan {
                    inner: first.inner_base as usize..(last.inner_base + last.inner_cap) as usize,
                    attr: first.attr_inner_base as usize
                        ..(last.attr_leaf_base + last.leaf_cap) as usize,
                }
            }
            _ => ChunkSpan {
                inner: 0..0,
                attr: 0..0,
            },
        };
        for &i in &members {
            voxels[i].chunk = c;
            voxels[i].inner_base -= span.inner.start as u32;
        }
        spans.push(span);
    }
    Ok(spans)
}

pub(super) fn object_of(doc: &Document, id: u64) -> Option<&thicket_core::scene::Object> {
    doc.objects.iter().find(|o| o.id == id)
}

fn is_rigged(doc: &Document, id: u64) -> bool {
    matches!(object_of(doc, id).map(|o| &o.kind), Some(ObjectKind::Voxels(v)) if v.rig.is_some())
}

fn voxels_of(doc: &Document, id: u64) -> Option<&Svo> {
    match &object_of(doc, id)?.kind {
        ObjectKind::Voxels(v) => Some(&v.svo),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured_doc(textures: &[Texture]) -> Document {
        use thicket_core::mesh::{Material, unit_cube};
        let mut doc = Document::default();
        for t in textures {
            let mut part = unit_cube();
            part.uvs = vec![Vec2::ZERO; part.positions.len()];
            doc.add(
                "Cube",
                ObjectKind::Mesh(thicket_core::scene::MeshObject {
                    model: MeshModel {
                        parts: vec![part],
                        materials: vec![Material {
                            base_color_texture: Some(t.clone()),
                            ..Material::default()
                        }],
                    },
                    casts_shadows: true,
                }),
            );
        }
        doc
    }

    fn solid(w: u32, h: u32, byte: u8) -> Texture {
        Texture {
            width: w,
            height: h,
            rgba8: vec![byte; (w * h * 4) as usize],
        }
    }

    #[test]
    fn textures_pack_once_each_after_the_srgb_table() {
        let (a, b) = (solid(3, 2, 7), solid(1, 1, 200));
        let mut short = solid(2, 2, 9);
        short.rgba8.pop();
        let doc = textured_doc(&[a.clone(), b, a, short, Texture::default()]);
        let (words, per_mesh) = pack_textures(&doc, u64::MAX).expect("fits");
        // The duplicate shares index 0; the short and the empty texture are none (white).
        assert_eq!(
            per_mesh,
            vec![
                vec![0.0],
                vec![1.0],
                vec![0.0],
                vec![NO_TEXTURE],
                vec![NO_TEXTURE]
            ]
        );
        assert_eq!(words[128], srgb_byte_to_linear(128).to_bits());
        let table = &words[TEXTURE_LUT_WORDS..TEXTURE_LUT_WORDS + 8];
        let first = (TEXTURE_LUT_WORDS + 8) as u32;
        assert_eq!(table, &[first, 3, 2, 0, first + 6, 1, 1, 0]);
        assert_eq!(words.len(), first as usize + 7);
        assert_eq!(words[first as usize], u32::from_le_bytes([7; 4]));
        assert_eq!(words[first as usize + 6], u32::from_le_bytes([200; 4]));
        // Triangles of a part without UVs carry no texture even when its material has one.
        let mut no_uvs = doc.clone();
        if let ObjectKind::Mesh(m) = &mut no_uvs.objects[1].kind {
            m.model.parts[0].uvs.clear();
        }
        let (tris, _, _) = pack_triangles(&no_uvs, &per_mesh);
        let texture_of = |t: &GpuTriangle| t.uv_c_texture[2];
        assert_eq!(texture_of(&tris[0]), 0.0);
        assert_eq!(texture_of(&tris[12]), NO_TEXTURE);
        assert_eq!(texture_of(&tris[24]), 0.0);
    }

    #[test]
    fn textures_over_the_binding_limit_are_a_clear_error() {
        let doc = textured_doc(&[solid(64, 64, 1)]);
        let bytes = ((TEXTURE_LUT_WORDS + TEXTURE_ENTRY_WORDS + 64 * 64) * 4) as u64;
        assert!(pack_textures(&doc, bytes).is_ok());
        let err = pack_textures(&doc, bytes - 1).expect_err("one byte over");
        assert!(
            matches!(err, GpuError::TooLarge { what: "mesh texture buffer", bytes: b, .. } if b == bytes),
            "{err}"
        );
        assert!(err.to_string().contains("mesh texture buffer"), "{err}");
    }

    #[test]
    fn chunks_hold_whole_objects_under_the_limit() {
        // Padded sizes: 256 bytes at least, so objects of 100 bytes take 256 alone.
        let sizes = [(96, 400), (96, 400), (96, 400), (96, 1000), (8, 16)];
        // 1024: two 400-byte attribute pools share a chunk, a third does not fit beside them.
        assert_eq!(assign_chunks(&sizes, 1024), Ok(vec![0, 0, 1, 2, 2]));
        // A limit above the total: one chunk, as an unsplit scene.
        assert_eq!(assign_chunks(&sizes, 1 << 20), Ok(vec![0; 5]));
        // The 1000-byte pool does not fit 999 bytes alone: object 3 is named.
        assert_eq!(assign_chunks(&sizes, 999), Err(3));
        // The inner pool counts too.
        assert_eq!(assign_chunks(&[(600, 16), (600, 16)], 1024), Ok(vec![0, 1]));
        assert_eq!(assign_chunks(&[], 1024), Ok(vec![]));
    }

    #[test]
    fn ranges_merge_when_close() {
        let m = merge_ranges(vec![10..12, 0..1, 13..20, 100..101, 1..3]);
        assert_eq!(m, vec![0..20, 100..101]);
        // One empty range (a struct literal: `vec![5..5]` reads like a mistaken `vec![5; 5]`).
        assert!(merge_ranges(vec![Range { start: 5, end: 5 }]).is_empty());
    }

    #[test]
    fn region_ranges_cover_the_path_and_the_changed_leaves() {
        let mut svo = Svo::new(4, false).expect("depth");
        for x in 0..16 {
            svo.set(
                UVec3::new(x, 3, 3),
                thicket_core::svo::Voxel::new([1, 2, 3, 255], Vec3::Y),
            )
            .expect("in bounds");
        }
        let (inner, leaf) = region_ranges(&svo, UVec3::new(15, 3, 3), UVec3::new(15, 3, 3));
        assert!(inner.iter().any(|r| r.contains(&0)), "root: {inner:?}");
        // The leaf at x = 15 is in one of the ranges.
        let mut found = false;
        svo.for_each_leaf(|_, _| {});
        let root = svo.root();
        let mut n = root;
        while n.level < svo.depth() {
            let half = svo.node_size(n.level) / 2;
            let p = UVec3::new(15, 3, 3) - n.origin;
            let k =
                u8::from(p.x >= half) | (u8::from(p.y >= half) << 1) | (u8::from(p.z >= half) << 2);
            n = svo.child(&n, k).expect("present");
        }
        for r in &leaf {
            found |= r.contains(&n.index);
        }
        assert!(found, "leaf {} in {leaf:?}", n.index);
        // A far box touches only the root's block, not all leaves.
        let total_leaf: u32 = leaf.iter().map(|r| r.end - r.start).sum();
        assert!(total_leaf < 16, "{leaf:?}");
    }
}

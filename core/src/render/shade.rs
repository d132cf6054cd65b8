//! Shadow maps, the resolve pass (depth + id → G-buffer) and deferred Phong shading.

use glam::{Mat3, Mat4, Vec3, Vec4Swizzles};
use rayon::prelude::*;

use super::MESH_ID_FLAG;
use super::asvo::{
    FACE_BITS, PassSettings, QNode, VoxelInstance, VoxelScratch, draw_voxels, face_normal,
    floor_i32,
};
use super::buffers::{DepthTarget, EMPTY_KEY, FrameBuffers, PixelId, RgbaImage, key_depth};
use super::camera::{Camera, Projection};
use super::krs::{KRS_ID_FLAG, KrsLighting, KrsPass};
use super::raster::{MeshInstance, WorldTriangle, draw_triangles};
use super::sampled::SampledTexels;
use super::stats::LevelStats;
use crate::deform::NodeInfo;
use crate::mesh::{linear_to_srgb, srgb_byte_to_linear};
use crate::quality::Quality;
use crate::scene::Light;
use crate::svo::decode_normal;

/// Edge in texels of the shadow map's bound tiles (see [`ShadowMap::bounds`]). Large against
/// the usual PCF windows (3×3, 5×5), so most windows lie in one tile and cost one read.
const SHADOW_TILE: i32 = 16;

/// What drawing a shadow map needs besides the map itself, kept between frames by
/// [`super::Renderer`]: the light's depth target and the traversal's queues.
#[derive(Default)]
pub(crate) struct ShadowBuffers {
    pub(crate) target: DepthTarget,
    pub(crate) voxels: VoxelScratch,
}

/// A directional light's depth map.
pub(crate) struct ShadowMap {
    pub(crate) cam: Camera,
    /// NDC depth per texel, `INFINITY` where nothing casts.
    pub(crate) depth: Vec<f32>,
    /// World size of one texel.
    pub(crate) texel_world: f32,
    /// Per `SHADOW_TILE`² block of texels, row by row: the nearest and the farthest depth in
    /// it. A PCF window whose receiver is nearer than every texel of the blocks it touches is
    /// wholly lit (farther than every texel: wholly shadowed), so it needs no taps: the filter
    /// costs only where a shadow edge is within its reach, and the result is exactly the full
    /// filter's.
    pub(super) bounds: Vec<(f32, f32)>,
    tiles_x: i32,
    /// Texels of exact cubes' rectangles drawn into the map (see `asvo::write_cube`).
    pub(crate) cube_pixels: u64,
}

/// An orthographic light view that tightly holds a box: what both the CPU reference and the
/// GPU renderer fit their shadow maps with, so their shadows agree.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightFit {
    /// `view_from_world`, re-centred on the box's footprint.
    pub view_from_world: Mat4,
    /// Half the edge of the square orthographic window (square so texels are square and one
    /// bias fits both axes).
    pub half_extent: f32,
    /// Near plane distance.
    pub near: f32,
    /// Far plane distance.
    pub far: f32,
}

/// Fits an orthographic view looking along `direction` around the box `lo..hi`; `None` when
/// the direction is zero or not finite.
#[must_use]
pub fn fit_light_view(direction: Vec3, lo: Vec3, hi: Vec3) -> Option<LightFit> {
    let dir = direction.try_normalize()?;
    let center = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-4);
    let up = if dir.y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
    let eye = center - dir * (2.0 * radius);
    let view = Mat4::look_at_rh(eye, center, up);
    let (mut vlo, mut vhi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for k in 0..8 {
        let c = Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let v = view.transform_point3(c);
        vlo = vlo.min(v);
        vhi = vhi.max(v);
    }
    // Re-centre the view on the box's footprint so the symmetric orthographic frustum wastes
    // no texels.
    let mid = (vlo + vhi) * 0.5;
    let shift = Mat4::from_translation(Vec3::new(-mid.x, -mid.y, 0.0));
    let half_extent = (0.5 * (vhi.x - vlo.x)).max(0.5 * (vhi.y - vlo.y)).max(1e-4) * 1.01;
    let margin = 0.01 * radius + 1e-4;
    Some(LightFit {
        view_from_world: shift * view,
        half_extent,
        near: -vhi.z - margin,
        far: -vlo.z + margin,
    })
}

/// An orthographic camera looking along `direction` whose image tightly holds the box, with at
/// most `max_size` texels per edge and texels no finer than `finest_texel_world` (finer texels
/// than the view can resolve only cost time: this keeps the shadow pass bound by the view's
/// resolution, like the view's own traversal). Public so the GPU renderer sizes its shadow map
/// with this very function. `None` when the direction is zero or not finite.
#[must_use]
pub fn fit_light_camera(
    direction: Vec3,
    lo: Vec3,
    hi: Vec3,
    max_size: u32,
    finest_texel_world: f32,
) -> Option<Camera> {
    let fit = fit_light_view(direction, lo, hi)?;
    let (half, near, far) = (fit.half_extent, fit.near, fit.far);
    let wanted = (2.0 * half / finest_texel_world.max(1e-30)).ceil();
    let size = if wanted.is_finite() {
        (wanted as u32).clamp(16, max_size.max(16))
    } else {
        max_size
    };
    Some(Camera::new(
        fit.view_from_world,
        Projection::Orthographic {
            half_width: half,
            half_height: half,
            near,
            far,
        },
        size,
        size,
    ))
}

impl ShadowMap {
    /// Renders casters from the light with the same traversal and rasteriser as the view.
    #[allow(
        clippy::too_many_arguments,
        reason = "the frame's parts and the renderer's kept buffers"
    )]
    pub(crate) fn render(
        cam: Camera,
        voxels: &[VoxelInstance<'_>],
        meshes: &[MeshInstance<'_>],
        tris: &[WorldTriangle],
        quality: &Quality,
        sampled: Option<&SampledTexels>,
        levels: &mut Vec<LevelStats>,
        buffers: &mut ShadowBuffers,
    ) -> Self {
        let mut map = Self::empty(cam);
        map.redraw(voxels, meshes, tris, quality, sampled, levels, buffers);
        map
    }

    /// A map of `cam` with nothing drawn (no texels: call [`Self::redraw`]).
    pub(crate) fn empty(cam: Camera) -> Self {
        Self {
            cam,
            depth: Vec::new(),
            texel_world: Self::texel_world(&cam),
            bounds: Vec::new(),
            tiles_x: 0,
            cube_pixels: 0,
        }
    }

    /// Draws the map again for its camera `cam` (set by the caller), keeping its own
    /// allocations and drawing into `buffers`' (a renderer keeps both between frames).
    #[allow(
        clippy::too_many_arguments,
        reason = "the frame's parts and the renderer's kept buffers"
    )]
    pub(crate) fn redraw(
        &mut self,
        voxels: &[VoxelInstance<'_>],
        meshes: &[MeshInstance<'_>],
        tris: &[WorldTriangle],
        quality: &Quality,
        sampled: Option<&SampledTexels>,
        levels: &mut Vec<LevelStats>,
        buffers: &mut ShadowBuffers,
    ) {
        let cam = self.cam;
        let pass = draw_casters(
            &cam, voxels, meshes, tris, quality, sampled, levels, buffers,
        );
        self.texel_world = Self::texel_world(&cam);
        self.depth.clear();
        let target = &buffers.target;
        self.depth.par_extend(
            (0..target.keys.len())
                .into_par_iter()
                .map(|i| key_depth(target.key(i))),
        );
        self.tiles_x = tile_bounds(
            &self.depth,
            cam.width as i32,
            cam.height as i32,
            sampled,
            &mut self.bounds,
        );
        self.cube_pixels = pass.cube_pixels;
    }

    /// Draws again only the texels of `region`'s tiles, keeping every other texel as it is:
    /// after an edit inside them, the rest of the map is still right. The casters are
    /// traversed as for a map read only there (see [`SampledTexels`]), so those texels get
    /// exactly what a full redraw gives them. Returns the texels drawn, or `None` (nothing
    /// changed) when the map holds no full drawing of its camera to patch.
    #[allow(
        clippy::too_many_arguments,
        reason = "the frame's parts and the renderer's kept buffers"
    )]
    pub(crate) fn redraw_region(
        &mut self,
        voxels: &[VoxelInstance<'_>],
        meshes: &[MeshInstance<'_>],
        tris: &[WorldTriangle],
        quality: &Quality,
        region: &SampledTexels,
        levels: &mut Vec<LevelStats>,
        buffers: &mut ShadowBuffers,
    ) -> Option<u64> {
        let cam = self.cam;
        let w = cam.width as usize;
        if self.depth.len() != w * cam.height as usize || !region.is_for(cam.width, cam.height) {
            return None;
        }
        let pass = draw_casters(
            &cam,
            voxels,
            meshes,
            tris,
            quality,
            Some(region),
            levels,
            buffers,
        );
        let target = &buffers.target;
        let drawn: u64 = self
            .depth
            .par_chunks_mut(w)
            .enumerate()
            .map(|(y, row)| {
                let mut n = 0;
                for (x, d) in row.iter_mut().enumerate() {
                    if region.is_read(x as u32, y as u32) {
                        *d = key_depth(target.key(y * w + x));
                        n += 1;
                    }
                }
                n
            })
            .sum();
        self.tiles_x = tile_bounds(
            &self.depth,
            cam.width as i32,
            cam.height as i32,
            None,
            &mut self.bounds,
        );
        self.cube_pixels = pass.cube_pixels;
        Some(drawn)
    }

    /// World size of one texel of a map seen through `cam`.
    fn texel_world(cam: &Camera) -> f32 {
        2.0 / cam.fy
    }

    /// Fraction of light reaching a world point (1 = lit), with a normal offset, a depth bias
    /// of a few texels plus the receiver's own splat size, and PCF; and the shadow-map reads it
    /// took (tile bounds and taps).
    fn visibility(
        &self,
        p_world: Vec3,
        n_world: Vec3,
        receiver_size_world: f32,
        pcf: i32,
    ) -> (f32, u32) {
        let (recv, ix, iy) = lookup(
            &self.cam,
            self.texel_world,
            p_world,
            n_world,
            receiver_size_world,
        );
        let (w, h) = (self.cam.width as i32, self.cam.height as i32);
        let mut reads = 0u32;
        if pcf > 0 {
            // The window's texels inside the map (taps outside count as lit).
            let Some([x0, y0, x1, y1]) = pcf_window(ix, iy, pcf, w, h) else {
                return (1.0, 0);
            };
            let (mut near, mut far) = (f32::INFINITY, f32::NEG_INFINITY);
            for ty in y0 / SHADOW_TILE..=y1 / SHADOW_TILE {
                for tx in x0 / SHADOW_TILE..=x1 / SHADOW_TILE {
                    let (lo, hi) = self.bounds[(ty * self.tiles_x + tx) as usize];
                    near = near.min(lo);
                    far = far.max(hi);
                    reads += 1;
                }
            }
            // The same comparison as each tap below, against the extremes of a superset of
            // the window's texels: the answer is the full filter's, exactly.
            if recv <= near {
                return (1.0, reads);
            }
            let inside = ix - pcf >= 0 && iy - pcf >= 0 && ix + pcf < w && iy + pcf < h;
            if inside && recv > far {
                return (0.0, reads);
            }
        }
        let mut lit = 0u32;
        let mut taps = 0u32;
        for dy in -pcf..=pcf {
            for dx in -pcf..=pcf {
                let (x, y) = (ix + dx, iy + dy);
                taps += 1;
                if x < 0 || y < 0 || x >= w || y >= h {
                    lit += 1;
                    continue;
                }
                if recv <= self.depth[(y * w + x) as usize] {
                    lit += 1;
                }
            }
        }
        (lit as f32 / taps as f32, reads + taps)
    }
}

/// Where a lookup of a shadow map seen through `cam` (texels of `texel_world`) lands: the
/// receiver's biased NDC depth and the texel at the centre of its PCF window.
#[inline]
fn lookup(
    cam: &Camera,
    texel_world: f32,
    p_world: Vec3,
    n_world: Vec3,
    receiver_size_world: f32,
) -> (f32, i32, i32) {
    // Splat depth is the nearest corner of a node, so a flat voxel surface is a staircase up
    // to one node deep in both maps: bias by both node sizes, and offset along the normal so
    // grazing receivers do not sample their own texel.
    let offset = n_world * (1.5 * texel_world);
    let q = cam.view_from_world.transform_point3(p_world + offset);
    let s = cam.project_view(q);
    let bias = 2.0 * texel_world + 1.5 * receiver_size_world;
    // `floor_i32` is `floor() as i32` exactly, inline: the baseline x86-64 target has no
    // rounding instruction, and the library `floorf` was called twice per lookup.
    (cam.ndc_depth(s.z - bias), floor_i32(s.x), floor_i32(s.y))
}

/// The PCF window of radius `pcf` around texel `(ix, iy)` clamped to a `w`×`h` map, as
/// inclusive `[x0, y0, x1, y1]`; `None` when it lies wholly outside (its taps all count as lit).
#[inline]
fn pcf_window(ix: i32, iy: i32, pcf: i32, w: i32, h: i32) -> Option<[i32; 4]> {
    let (x0, x1) = (
        ix.saturating_sub(pcf).max(0),
        ix.saturating_add(pcf).min(w - 1),
    );
    let (y0, y1) = (
        iy.saturating_sub(pcf).max(0),
        iy.saturating_add(pcf).min(h - 1),
    );
    (x0 <= x1 && y0 <= y1).then_some([x0, y0, x1, y1])
}

/// The texels the shading of `fb` will read from the map of light `light` seen through `cam`
/// (see [`SampledTexels`]): the PCF window of every covered pixel that may face the light
/// (`n·l > 0`; every KRS pixel, whose diffuse term is its own), clamped to the map.
pub(crate) fn sampled_texels(
    cam: &Camera,
    light: &Light,
    fb: &FrameBuffers,
    view: &Camera,
    krs_pixels: &[Option<super::krs::KrsPixel>],
    quality: &Quality,
    out: &mut SampledTexels,
) {
    let texel_world = ShadowMap::texel_world(cam);
    let l = -light.direction.normalize_or_zero();
    let pcf = quality.frame_settings().pcf_radius as i32;
    let (w, h) = (cam.width as i32, cam.height as i32);
    let windows = (0..fb.ids.len()).into_par_iter().filter_map(|i| {
        if fb.ids[i].object == 0 {
            return None;
        }
        let krs = krs_pixels.get(i).and_then(Option::as_ref);
        if krs.is_none() && fb.normal[i].dot(l) <= 0.0 {
            return None;
        }
        let (p, receiver) = shading_point(fb, view, krs, quality, i);
        let (_, ix, iy) = lookup(cam, texel_world, p, fb.normal[i], receiver);
        pcf_window(ix, iy, pcf, w, h).map(|r| r.map(|v| v as u32))
    });
    out.reset(cam.width, cam.height, windows);
}

/// The world point and receiver size pixel `i` of `fb` is shaded with: a KRS pixel keeps its
/// exact hit point, others come back from 32-bit NDC depth; the receiver is the pixel's world
/// size (times the LOD threshold when that is coarser), the staircase a splat may add.
#[inline]
fn shading_point(
    fb: &FrameBuffers,
    cam: &Camera,
    krs: Option<&super::krs::KrsPixel>,
    quality: &Quality,
    i: usize,
) -> (Vec3, f32) {
    let w = fb.width;
    let (x, y) = ((i as u32 % w) as f32 + 0.5, (i as u32 / w) as f32 + 0.5);
    let p = krs.map_or_else(|| cam.unproject(x, y, fb.depth[i]), |px| px.position);
    let receiver =
        cam.pixel_world_size(cam.view_depth(fb.depth[i])) * quality.frame_settings().receiver_px;
    (p, receiver)
}

/// Draws the casters into `buffers`' target from the light's camera `cam`: triangles, then
/// voxels, only where `sampled` says when given (other tiles hold the nearest depth).
#[allow(
    clippy::too_many_arguments,
    reason = "the frame's parts and the renderer's kept buffers"
)]
fn draw_casters(
    cam: &Camera,
    voxels: &[VoxelInstance<'_>],
    meshes: &[MeshInstance<'_>],
    tris: &[WorldTriangle],
    quality: &Quality,
    sampled: Option<&SampledTexels>,
    levels: &mut Vec<LevelStats>,
    buffers: &mut ShadowBuffers,
) -> super::asvo::VoxelPass {
    let target = &mut buffers.target;
    target.reset(cam.width, cam.height);
    let drawn = draw_triangles(tris, meshes, cam, target, true);
    // With no triangle drawn the tiles are already right (all empty).
    if drawn > 0 && quality.occlusion_culling {
        target.update_all_tiles();
    }
    if let Some(m) = sampled {
        // Texels no lookup reads hold the nearest depth there is: the occlusion test then
        // takes them as covered, so a node that also touches read texels is culled when
        // those are (it was kept because of texels nobody reads).
        target.fill_nearest(m.unread());
    }
    let pass = draw_voxels(
        voxels,
        cam,
        target,
        &PassSettings {
            lod_pixel_threshold: quality.lod_pixel_threshold,
            cube_pixel_threshold: quality.cube_pixel_threshold,
            occlusion_culling: quality.occlusion_culling,
            id_base: 0,
            keep_refs: false,
            shadow_casters_only: true,
            sampled,
        },
        &mut buffers.voxels,
    );
    super::stats::FrameStats::merge_levels(levels, &buffers.voxels.levels);
    pass
}

/// Nearest and farthest depth per `SHADOW_TILE`² block of a `w`×`h` depth map, and the number
/// of blocks per row. With `read`, only over the texels of tiles some lookup reads: still a
/// superset of every PCF window, so the early-outs stay exact, and the nearest-depth fill of
/// unread tiles does not hide the "wholly lit" answer of the blocks they share with read ones.
fn tile_bounds(
    depth: &[f32],
    w: i32,
    h: i32,
    read: Option<&SampledTexels>,
    bounds: &mut Vec<(f32, f32)>,
) -> i32 {
    let (tiles_x, tiles_y) = (
        (w + SHADOW_TILE - 1) / SHADOW_TILE,
        (h + SHADOW_TILE - 1) / SHADOW_TILE,
    );
    bounds.clear();
    bounds.par_extend((0..tiles_x * tiles_y).into_par_iter().map(|t| {
        let (tx, ty) = (t % tiles_x, t / tiles_x);
        let mut b = (f32::INFINITY, f32::NEG_INFINITY);
        for y in ty * SHADOW_TILE..((ty + 1) * SHADOW_TILE).min(h) {
            let row = (y * w) as usize;
            for x in tx * SHADOW_TILE..((tx + 1) * SHADOW_TILE).min(w) {
                if read.is_some_and(|m| !m.is_read(x as u32, y as u32)) {
                    continue;
                }
                let d = depth[row + x as usize];
                b = (b.0.min(d), b.1.max(d));
            }
        }
        b
    }));
    tiles_x
}

/// What the resolve writes for a drawn pixel: its id, world normal and linear albedo.
type Shaded = (PixelId, Vec3, Vec3);

/// Turns the target's packed keys into the G-buffer `fb` (its allocations kept; `normal_mats`
/// is scratch).
#[allow(
    clippy::too_many_arguments,
    reason = "one call site; the arguments are the frame's parts"
)]
pub(crate) fn resolve(
    target: &DepthTarget,
    cam: &Camera,
    voxels: &[VoxelInstance<'_>],
    refs: &[QNode],
    meshes: &[MeshInstance<'_>],
    tris: &[WorldTriangle],
    normal_mats: &mut Vec<Mat3>,
    fb: &mut FrameBuffers,
) {
    let (w, h) = (cam.width, cam.height);
    normal_mats.clear();
    normal_mats.extend(
        meshes
            .iter()
            .map(|m| Mat3::from_mat4(m.world_from_object).inverse().transpose()),
    );
    let normal_mats = &normal_mats[..];
    // What pixel `i` with a drawn key resolves to: depth, and the id, normal and albedo unless
    // they stay empty (KRS pixels, which `resolve_krs` fills).
    let pixel = |i: usize, key: u64| -> (f32, Option<Shaded>) {
        let d = key_depth(key);
        let raw = (key & 0xffff_ffff) as u32;
        if raw & KRS_ID_FLAG == KRS_ID_FLAG {
            // Filled by `resolve_krs` from the pass's own records.
            return (d, None);
        }
        if raw & MESH_ID_FLAG != 0 {
            let Some(t) = tris.get((raw & !MESH_ID_FLAG) as usize) else {
                return (d, None);
            };
            let m = &meshes[t.mesh as usize];
            let part = &m.model.parts[t.part as usize];
            let (x, y) = ((i as u32 % w) as f32 + 0.5, (i as u32 / w) as f32 + 0.5);
            let p = cam.unproject(x, y, d);
            let bary = barycentric(p, t.world);
            let color = m.model.surface_color(part, t.tri as usize, bary);
            let [a, b, c] = t.world;
            let face = (b - a).cross(c - a);
            let mut nw = if part.normals.is_empty() {
                face
            } else {
                let [ia, ib, ic] = part.triangle(t.tri as usize);
                normal_mats[t.mesh as usize]
                    * (part.normals[ia] * bary.x
                        + part.normals[ib] * bary.y
                        + part.normals[ic] * bary.z)
            }
            .normalize_or_zero();
            // Two-sided: light the side facing the viewer.
            if face.dot(cam.toward_eye(p)) < 0.0 {
                nw = -nw;
            }
            let id = PixelId {
                object: m.label,
                node: (u64::from(t.part) << 32) | u64::from(t.tri),
            };
            return (d, Some((id, nw, color.xyz())));
        }
        let Some(q) = refs.get((raw >> FACE_BITS) as usize) else {
            return (d, None);
        };
        let o = &voxels[q.obj as usize];
        let info = NodeInfo {
            svo: o.svo,
            node: q.node,
        };
        // Colour and normal only (the material and skin are not shaded): two reads of
        // the node's pools instead of four.
        let (color, normal) = info.color_and_normal();
        let id = PixelId {
            object: o.label,
            node: (u64::from(q.node.level) << 32) | u64::from(q.node.index),
        };
        let albedo = Vec3::new(
            srgb_byte_to_linear(color[0]),
            srgb_byte_to_linear(color[1]),
            srgb_byte_to_linear(color[2]),
        );
        // A pixel of an exact cube is shaded with the face it shows, a splat with the node's
        // (smooth, LOD-filtered) normal.
        let n_voxel =
            face_normal(raw & ((1 << FACE_BITS) - 1)).unwrap_or_else(|| decode_normal(normal));
        (
            d,
            Some((id, o.deform.normal_to_world(&info, n_voxel), albedo)),
        )
    };
    // Every buffer is filled in parallel with its background value, then each row writes only
    // its drawn pixels (a third of a near frame's), one rayon task per row. Collecting the four
    // buffers from one per-pixel iterator (`unzip`) took half the resolve's time with no pixel
    // drawn at all.
    let n = target.keys.len();
    fb.width = w;
    fb.height = h;
    let FrameBuffers {
        depth,
        ids,
        normal,
        albedo,
        ..
    } = fb;
    depth.clear();
    depth.par_extend(rayon::iter::repeat_n(1.0f32, n));
    ids.clear();
    ids.par_extend(rayon::iter::repeat_n(PixelId::default(), n));
    normal.clear();
    normal.par_extend(rayon::iter::repeat_n(Vec3::ZERO, n));
    albedo.clear();
    albedo.par_extend(rayon::iter::repeat_n(Vec3::ZERO, n));
    let row = (w as usize).max(1);
    target
        .keys
        .par_chunks(row)
        .zip(depth.par_chunks_mut(row))
        .zip(ids.par_chunks_mut(row))
        .zip(normal.par_chunks_mut(row))
        .zip(albedo.par_chunks_mut(row))
        .enumerate()
        .for_each(|(y, ((((k, d), id), nrm), alb))| {
            // A voxel pixel's id, normal and albedo depend only on the low half of its key (the
            // node and the face shown), and a splat covers runs of pixels in a row: the last
            // one is reused.
            let mut last: Option<(u32, Option<Shaded>)> = None;
            for x in 0..k.len() {
                let key = k[x].load(std::sync::atomic::Ordering::Relaxed);
                if key == EMPTY_KEY {
                    continue;
                }
                let raw = (key & 0xffff_ffff) as u32;
                let (depth, rest) = match last {
                    Some((r, rest)) if r == raw => (key_depth(key), rest),
                    _ => {
                        let (depth, rest) = pixel(y * row + x, key);
                        if raw & MESH_ID_FLAG == 0 {
                            last = Some((raw, rest));
                        }
                        (depth, rest)
                    }
                };
                d[x] = depth;
                if let Some((pid, nw, a)) = rest {
                    id[x] = pid;
                    nrm[x] = nw;
                    alb[x] = a;
                }
            }
        });
}

/// `(linear_to_srgb(c) * 255).round() as u8`, exactly, without `powf`: the byte is a monotonic
/// step function of `c`, so it is found from the first float at which each byte starts.
pub(crate) fn linear_to_srgb8(c: f32) -> u8 {
    struct Table {
        /// `starts[k]`: the smallest `c` in `0..=1` whose byte is at least `k` (`starts[0] = 0`).
        starts: [f32; 257],
        /// The byte at `i / BUCKETS`.
        bucket_byte: [u8; BUCKETS + 1],
    }
    const BUCKETS: usize = 4096;
    fn exact(c: f32) -> u8 {
        (linear_to_srgb(c) * 255.0).round() as u8
    }
    static TABLE: std::sync::LazyLock<Table> = std::sync::LazyLock::new(|| {
        let mut starts = [f32::INFINITY; 257];
        starts[0] = 0.0;
        for (k, start) in starts.iter_mut().enumerate().take(256).skip(1) {
            // Binary search over the bit patterns of 0..=1 (ordered like the values).
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            if exact(f32::from_bits(hi)) < k as u8 {
                continue;
            }
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if exact(f32::from_bits(mid)) >= k as u8 {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *start = f32::from_bits(lo);
        }
        let bucket_byte = std::array::from_fn(|i| exact(i as f32 / BUCKETS as f32));
        Table {
            starts,
            bucket_byte,
        }
    });
    if c.is_nan() || c <= 0.0 {
        // Zero, negatives and NaN all give 0, as `linear_to_srgb` clamps (NaN: `as u8` of NaN).
        return 0;
    }
    if c >= 1.0 {
        return 255;
    }
    let t = &*TABLE;
    // The byte at the bucket's lower edge, then at most a few steps up (the transfer function's
    // slope is at most 12.92 · 255 / 4096 < 1 byte per bucket).
    let mut b = t.bucket_byte[(c * BUCKETS as f32) as usize];
    while b < 255 && c >= t.starts[usize::from(b) + 1] {
        b += 1;
    }
    b
}

/// Fills the G-buffer of pixels the KRS won: object label, kernel as node, the §6.1 normal and
/// the textured albedo recorded when the ray hit.
pub(crate) fn resolve_krs(
    fb: &mut FrameBuffers,
    target: &DepthTarget,
    pass: &KrsPass,
    labels: &[u32],
) {
    if pass.pixels.is_empty() {
        // No KRS object was traced: no pixel can be the KRS's.
        return;
    }
    fb.ids
        .par_iter_mut()
        .zip(fb.normal.par_iter_mut())
        .zip(fb.albedo.par_iter_mut())
        .enumerate()
        .for_each(|(i, ((id, nrm), alb))| {
            let key = target.key(i);
            let raw = (key & 0xffff_ffff) as u32;
            if key == EMPTY_KEY || raw & KRS_ID_FLAG != KRS_ID_FLAG {
                return;
            }
            let Some(Some(px)) = pass.pixels.get(i) else {
                return;
            };
            *id = PixelId {
                object: labels.get(px.object as usize).copied().unwrap_or(0),
                node: u64::from(px.kernel),
            };
            *nrm = px.normal;
            *alb = px.albedo;
        });
}

/// Barycentric weights of `p` (on or near the triangle's plane), clamped into the triangle.
fn barycentric(p: Vec3, [a, b, c]: [Vec3; 3]) -> Vec3 {
    let n = (b - a).cross(c - a);
    let nn = n.length_squared();
    if nn <= 0.0 || !nn.is_finite() {
        return Vec3::new(1.0, 0.0, 0.0);
    }
    let wa = (b - p).cross(c - p).dot(n) / nn;
    let wb = (c - p).cross(a - p).dot(n) / nn;
    let bary = Vec3::new(wa, wb, 1.0 - wa - wb).max(Vec3::ZERO);
    let s = bary.x + bary.y + bary.z;
    if s > 0.0 {
        bary / s
    } else {
        Vec3::new(1.0, 0.0, 0.0)
    }
}

/// Scene lighting for the shading pass.
pub(crate) struct Lighting<'a> {
    pub(crate) lights: &'a [Light],
    /// One entry per light: which shadow map it is shaded with this frame.
    pub(crate) shadows: &'a [ShadowUse],
    /// One entry per light: the map a [`ShadowUse::Own`] light is shaded with.
    pub(crate) own_maps: &'a [Option<ShadowMap>],
    pub(crate) ambient: Vec3,
    pub(crate) background: Vec3,
    /// World radius of the ambient-occlusion samples (see [`AoKernel`]).
    pub(crate) ao_radius_world: f32,
    /// KRS shadow rays, AO and Algorithm 2 diffuse factors.
    pub(crate) krs: KrsLighting<'a>,
}

/// Which shadow map a light is shaded with in a frame.
#[derive(Default)]
pub(crate) enum ShadowUse {
    /// None (the light casts no shadow this frame).
    #[default]
    None,
    /// The map the renderer drew into its own slot for this light.
    Own,
    /// A map shared with a [`super::ShadowCache`].
    Cached(std::sync::Arc<ShadowMap>),
}

impl Lighting<'_> {
    /// The shadow map light `li` is shaded with, if any.
    fn shadow_map(&self, li: usize) -> Option<&ShadowMap> {
        match self.shadows.get(li)? {
            ShadowUse::None => None,
            ShadowUse::Own => self.own_maps.get(li)?.as_ref(),
            ShadowUse::Cached(m) => Some(m),
        }
    }
}

/// The shading pass's buffers, kept between frames by [`super::Renderer`].
#[derive(Default)]
pub(crate) struct ShadeScratch {
    /// Per light: the direction towards it and its colour times intensity.
    lights: Vec<(Vec3, Vec3)>,
    /// The AO kernel and the sample count and radius (bits) it was made for.
    ao: Option<(u32, u32, AoKernel)>,
}

/// Successive AO sample azimuths are this fraction of a turn apart (the golden angle).
const GOLDEN_TURN: f32 = 0.381_966;

/// The per-sample phases of the screen-space AO kernel (the part that does not depend on the
/// pixel): sample `i` of `count` has `[i / count, fract(i · golden turn),
/// fract((i + ½) · 0.618034)]` (elevation stratum start, azimuth phase, distance phase). The
/// GPU renderer uploads exactly these, and both renderers add the pixel's jitter with
/// [`ao_sample_offset`].
#[must_use]
pub fn ao_sample_phases(count: u32) -> Vec<[f32; 3]> {
    let n = count as f32;
    (0..count)
        .map(|i| {
            let fi = i as f32;
            [
                fi / n,
                (fi * GOLDEN_TURN).fract(),
                ((fi + 0.5) * 0.618_034).fract(),
            ]
        })
        .collect()
}

/// The screen-space AO jitter of pixel `pixel` (its index in the image drawn): three values in
/// [0, 1) for the elevation, the azimuth and the distance, from [`crate::krs::ao_jitter`] of
/// three seeds of its own (`3·pixel + 1 ..= 3·pixel + 3`).
#[must_use]
pub fn ao_pixel_jitter(pixel: u32) -> [f32; 3] {
    let seed = pixel.wrapping_mul(3);
    [1, 2, 3].map(|k| crate::krs::ao_jitter(seed.wrapping_add(k)))
}

/// A screen-space AO sample in the tangent frame of the shaded point (x, y along the tangents,
/// z along the normal), scaled by its distance: for the phases of sample i of `count`
/// ([`ao_sample_phases`]) and a pixel's jitter j, `u = i/count + j₀/count` (one sample per
/// stratum of u), `cos θ = √(1 − u)`, `sin θ = √u` (cosine-weighted), azimuth
/// `2π · fract(phase₁ + j₁)`, distance `r · (¼ + ¾ · fract(phase₂ + j₂))`. Each sample is then
/// distributed as the whole kernel's density over its stratum, so the estimate's expectation
/// does not depend on the count. The same arithmetic as `shade.wgsl`'s `ao_openness`.
#[must_use]
pub fn ao_sample_offset(phases: [f32; 3], count: u32, radius_world: f32, jitter: [f32; 3]) -> Vec3 {
    let u = (phases[0] + jitter[0] / count as f32).min(1.0);
    let cos_t = (1.0 - u).sqrt();
    let sin_t = u.sqrt();
    let phi = std::f32::consts::TAU * (phases[1] + jitter[1]).fract();
    let dist = radius_world * (0.25 + 0.75 * (phases[2] + jitter[2]).fract());
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t) * dist
}

/// Screen-space ambient occlusion from the resolved depth buffer (`quality.ao_samples`).
///
/// Why screen space: it treats voxels and meshes alike (both are in the one depth buffer), costs
/// a fixed number of depth reads per pixel whatever the scene, and a GPU renderer can do the
/// same reads. The estimate is the fraction of `n` points of the cosine-weighted hemisphere of
/// radius r (distances uniform in [¼, 1]·r) that the depth buffer occludes, with the points
/// drawn per pixel by stratified sampling (see [`ao_sample_offset`]), so its mean over pixels
/// is the same for every `n` and only its noise falls. See `docs/rendering.md` for the
/// occlusion test.
pub(crate) struct AoKernel {
    /// Per sample: its phases ([`ao_sample_phases`]).
    phases: Vec<[f32; 3]>,
    radius_world: f32,
}

impl AoKernel {
    pub(crate) fn new(count: u32, radius_world: f32) -> Self {
        // A zero radius (nothing with a size in the scene) would sample the shaded point itself:
        // no occlusion, so no samples and no cost.
        let count = if radius_world > 0.0 && radius_world.is_finite() {
            count
        } else {
            0
        };
        Self {
            phases: ao_sample_phases(count),
            radius_world,
        }
    }

    /// Fraction of samples not occluded (1 = open) at world point `p` with unit normal `n`.
    /// A sample is occluded when the depth buffer at its pixel holds a surface nearer the eye
    /// than the sample by more than `eps_world` (the voxel staircase: splats store a node's
    /// nearest depth) and by less than the radius (a far foreground object does not darken).
    /// Pixels for which `is_krs` holds are not occluders here: KRS geometry occludes through
    /// the KRS distance AO, which every pixel also gets (exact, and it sees off screen);
    /// counting it twice darkened everything near a KRS surface, and made the screen term
    /// flicker with the sub-pixel foliage of a tree.
    #[allow(
        clippy::too_many_arguments,
        reason = "frame buffers, camera, point, pixel, tolerance and the KRS mask"
    )]
    fn openness(
        &self,
        fb: &FrameBuffers,
        cam: &Camera,
        p: Vec3,
        n: Vec3,
        pixel: u32,
        eps_world: f32,
        is_krs: impl Fn(usize) -> bool,
    ) -> f32 {
        if self.phases.is_empty() || n == Vec3::ZERO {
            return 1.0;
        }
        let count = self.phases.len() as u32;
        let jitter = ao_pixel_jitter(pixel);
        let helper = if n.y.abs() < 0.99 { Vec3::Y } else { Vec3::X };
        let t = n.cross(helper).normalize_or_zero();
        let b = n.cross(t);
        let (w, h) = (cam.width as f32, cam.height as f32);
        let mut occluded = 0u32;
        for &phases in &self.phases {
            let s = ao_sample_offset(phases, count, self.radius_world, jitter);
            let q = p + t * s.x + b * s.y + n * s.z;
            let qv = cam.view_from_world.transform_point3(q);
            let d_q = -qv.z;
            if cam.perspective && d_q <= cam.near {
                continue;
            }
            let sp = cam.project_view(qv);
            if !(sp.x >= 0.0 && sp.y >= 0.0 && sp.x < w && sp.y < h) {
                continue;
            }
            let idx = sp.y as usize * fb.width as usize + sp.x as usize;
            if fb.ids[idx].object == 0 || is_krs(idx) {
                continue;
            }
            let gap = d_q - cam.view_depth(fb.depth[idx]);
            if gap > eps_world && gap < self.radius_world {
                occluded += 1;
            }
        }
        1.0 - occluded as f32 / count as f32
    }
}

/// What the shading pass counted.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ShadeCounts {
    pub(crate) shading: super::stats::ShadingStats,
    pub(crate) krs_shadow_steps: u64,
    pub(crate) krs_ao_evals: u64,
}

impl ShadeCounts {
    fn add(mut self, o: Self) -> Self {
        self.shading.shadow_taps += o.shading.shadow_taps;
        self.shading.ao_taps += o.shading.ao_taps;
        self.krs_shadow_steps += o.krs_shadow_steps;
        self.krs_ao_evals += o.krs_ao_evals;
        self
    }
}

/// Deferred Phong over the G-buffer; writes an sRGB image into `img` (its allocation kept)
/// and counts the lookups.
pub(crate) fn shade(
    fb: &FrameBuffers,
    cam: &Camera,
    lighting: &Lighting<'_>,
    quality: &Quality,
    img: &mut RgbaImage,
    scratch: &mut ShadeScratch,
) -> ShadeCounts {
    let w = fb.width;
    img.width = w;
    img.height = fb.height;
    img.pixels.clear();
    img.pixels.resize(w as usize * fb.height as usize * 4, 0);
    let pcf = quality.frame_settings().pcf_radius as i32;
    let to8 = linear_to_srgb8;
    let bg = [
        to8(lighting.background.x),
        to8(lighting.background.y),
        to8(lighting.background.z),
        255,
    ];
    let ao_key = (quality.ao_samples, lighting.ao_radius_world.to_bits());
    if scratch
        .ao
        .as_ref()
        .is_some_and(|(n, r, _)| (*n, *r) != ao_key)
    {
        scratch.ao = None;
    }
    let ShadeScratch { lights, ao } = scratch;
    let ao = &ao
        .get_or_insert_with(|| {
            let kernel = AoKernel::new(quality.ao_samples, lighting.ao_radius_world);
            (ao_key.0, ao_key.1, kernel)
        })
        .2;
    lights.clear();
    lights.extend(
        lighting
            .lights
            .iter()
            .map(|l| (-l.direction.normalize_or_zero(), l.color * l.intensity)),
    );
    let lights = &lights[..];
    let shade_pixel = |i: usize, out: &mut [u8], count: &mut ShadeCounts| {
        if fb.ids[i].object == 0 {
            out.copy_from_slice(&bg);
            return;
        }
        let krs_px = lighting.krs.pass.pixels.get(i).and_then(Option::as_ref);
        let (p, receiver) = shading_point(fb, cam, krs_px, quality, i);
        let n = fb.normal[i];
        let v = cam.toward_eye(p);
        // The AO staircase tolerance: the receiver term of the shadow bias.
        let krs_pixels = &lighting.krs.pass.pixels;
        let open = ao.openness(fb, cam, p, n, i as u32, 1.5 * receiver, |j| {
            krs_pixels.get(j).is_some_and(Option::is_some)
        });
        if n != Vec3::ZERO {
            count.shading.ao_taps += ao.phases.len() as u64;
        }
        let footprint = krs_px.map_or(receiver, |px| px.epsilon.max(receiver));
        // Screen-space AO (every surface in the depth buffer) times the KRS distance AO
        // (occlusion by KRS geometry, also outside the screen).
        let (krs_open, krs_evals) = lighting.krs.ambient(p, n, i as u32);
        count.krs_ao_evals += u64::from(krs_evals);
        let mut light = lighting.ambient * (open * krs_open);
        let mut spec = Vec3::ZERO;
        for (li, &(l, color)) in lights.iter().enumerate() {
            // Algorithm 2 replaces n·l on KRS pixels (smooth across mirror planes).
            let ndotl = lighting
                .krs
                .diffuse(i, li, lights.len())
                .unwrap_or_else(|| n.dot(l));
            if ndotl <= 0.0 {
                continue;
            }
            let mut vis = match lighting.shadow_map(li) {
                Some(sm) => {
                    let (vis, reads) = sm.visibility(p, n, receiver, pcf);
                    count.shading.shadow_taps += u64::from(reads);
                    vis
                }
                None => 1.0,
            };
            if vis > 0.0 && lighting.lights[li].casts_shadows {
                let (krs_vis, steps) = lighting.krs.shadow(p, n, l, footprint);
                count.krs_shadow_steps += u64::from(steps);
                vis *= krs_vis;
            }
            if vis <= 0.0 {
                continue;
            }
            light += color * (ndotl * vis);
            let half = (l + v).normalize_or_zero();
            spec += color * (0.25 * n.dot(half).max(0.0).powi(32) * vis);
        }
        let c = fb.albedo[i] * light + spec;
        out.copy_from_slice(&[to8(c.x), to8(c.y), to8(c.z), 255]);
    };
    // A row per task: the counts are summed per row, not per pixel.
    img.pixels
        .par_chunks_mut((4 * w as usize).max(4))
        .enumerate()
        .map(|(y, row)| {
            let mut count = ShadeCounts::default();
            for (x, out) in row.chunks_exact_mut(4).enumerate() {
                shade_pixel(y * w as usize + x, out, &mut count);
            }
            count
        })
        .reduce(ShadeCounts::default, ShadeCounts::add)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The screen-space AO estimate's mean over pixels (16,384 pixels' jitter) is the same at 4
    /// and 64 samples, and equal to the kernel's integral, for occluders that take part of the
    /// hemisphere: a wall beside the point, a low ceiling and a close box. Tolerance 0.004: a
    /// fraction of 4 samples spreads by at most 0.5, so the mean of 16,384 has a standard error
    /// under 0.004 / 4; a single fixed kernel (one jitter for every pixel, as before) misses
    /// the integral at 4 samples by more.
    #[test]
    fn screen_ao_has_the_same_mean_for_every_sample_count() {
        let r = 2.0f32;
        type Occluder = (&'static str, fn(Vec3) -> bool);
        let occluders: [Occluder; 3] = [
            ("wall", |s| s.x > 0.3),
            ("ceiling", |s| s.z > 0.9),
            ("box", |s| s.x.abs() < 0.6 && s.y > 0.0 && s.z < 0.8),
        ];
        let pixels = 16_384u32;
        let mean_occluded =
            |count: u32, hit: fn(Vec3) -> bool, jitter: &dyn Fn(u32) -> [f32; 3]| {
                let phases = ao_sample_phases(count);
                let total: f64 = (0..pixels)
                    .map(|px| {
                        let j = jitter(px);
                        let occluded = phases
                            .iter()
                            .filter(|&&ph| hit(ao_sample_offset(ph, count, r, j)))
                            .count();
                        occluded as f64 / f64::from(count)
                    })
                    .sum();
                total / f64::from(pixels)
            };
        let mut fixed_off = 0.0f64;
        for (name, hit) in occluders {
            let integral = mean_occluded(1024, hit, &ao_pixel_jitter);
            let m4 = mean_occluded(4, hit, &ao_pixel_jitter);
            let m64 = mean_occluded(64, hit, &ao_pixel_jitter);
            assert!(
                integral > 0.05 && integral < 0.95,
                "{name}: occludes part of the hemisphere ({integral})"
            );
            assert!(
                (m4 - integral).abs() < 0.004 && (m64 - integral).abs() < 0.004,
                "{name}: mean occlusion at 4 / 64 samples {m4} / {m64}, integral {integral}"
            );
            let fixed = mean_occluded(4, hit, &|_| [0.5, 0.0, 0.0]);
            fixed_off = fixed_off.max((fixed - integral).abs());
        }
        assert!(fixed_off > 0.02, "{fixed_off}");
    }

    #[test]
    fn screen_ao_samples_stay_in_the_kernel() {
        // Every sample lies in the upper hemisphere between a quarter of the radius and all
        // of it, whatever the jitter (edges included).
        for count in [1u32, 4, 16, 64] {
            for (ph, j) in ao_sample_phases(count).into_iter().zip(
                [
                    [0.0, 0.0, 0.0],
                    [0.999_999, 0.999_999, 0.999_999],
                    [0.5, 0.25, 0.75],
                ]
                .into_iter()
                .cycle(),
            ) {
                let s = ao_sample_offset(ph, count, 2.0, j);
                let len = s.length();
                assert!(
                    s.z >= 0.0 && (0.5 - 1e-5..=2.0 + 1e-5).contains(&len),
                    "{s:?}"
                );
            }
        }
    }

    /// The tile bounds only skip taps whose answer they know: visibility equals the plain
    /// percentage-closer filter at every radius, for receivers in front of, inside and behind
    /// a rough depth map, at its edges and outside it.
    #[test]
    fn tile_bounds_give_exactly_the_full_filter() {
        let (w, h) = (53u32, 40u32);
        let cam = fit_light_camera(
            Vec3::new(0.3, -1.0, 0.2),
            Vec3::splat(-1.0),
            Vec3::splat(1.0),
            w,
            1e-6,
        )
        .unwrap();
        let cam = Camera::new(
            cam.view_from_world,
            Projection::Orthographic {
                half_width: 1.2,
                half_height: 1.2,
                near: 0.1,
                far: 4.0,
            },
            w,
            h,
        );
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        // Smooth regions, steps and empty texels (INFINITY).
        let depth: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                if x > 40.0 && y < 10.0 {
                    f32::INFINITY
                } else if (x - 20.0).abs() < 6.0 && (y - 20.0).abs() < 5.0 {
                    0.3 + 0.01 * rng.random::<f32>()
                } else {
                    0.5 + 0.004 * x + 0.002 * y
                }
            })
            .collect();
        let mut bounds = Vec::new();
        let tiles_x = tile_bounds(&depth, w as i32, h as i32, None, &mut bounds);
        let map = ShadowMap {
            cam,
            depth,
            texel_world: 2.0 / cam.fy,
            bounds,
            tiles_x,
            cube_pixels: 0,
        };
        let mut skipped = 0;
        for _ in 0..4000 {
            let p = Vec3::new(
                rng.random_range(-1.6..1.6),
                rng.random_range(-1.6..1.6),
                rng.random_range(-1.6..1.6),
            );
            let n = Vec3::new(rng.random(), rng.random(), rng.random()).normalize_or_zero();
            for pcf in 0..=3 {
                let (v, reads) = map.visibility(p, n, 0.001, pcf);
                // The plain filter, as the GPU shader computes it.
                let offset = n * (1.5 * map.texel_world);
                let s = map
                    .cam
                    .project_view(map.cam.view_from_world.transform_point3(p + offset));
                let recv = map
                    .cam
                    .ndc_depth(s.z - (2.0 * map.texel_world + 1.5 * 0.001));
                let (ix, iy) = (s.x.floor() as i32, s.y.floor() as i32);
                let (mut lit, mut taps) = (0, 0);
                for dy in -pcf..=pcf {
                    for dx in -pcf..=pcf {
                        let (x, y) = (ix + dx, iy + dy);
                        taps += 1;
                        let inside = x >= 0 && y >= 0 && x < w as i32 && y < h as i32;
                        if !inside || recv <= map.depth[(y * w as i32 + x) as usize] {
                            lit += 1;
                        }
                    }
                }
                assert_eq!(v, lit as f32 / taps as f32, "{p} {n} pcf {pcf}");
                if pcf > 0 && reads < taps {
                    skipped += 1;
                }
            }
        }
        assert!(skipped > 1000, "the bounds decided {skipped} windows");
    }
}

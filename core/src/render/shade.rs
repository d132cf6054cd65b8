//! Shadow maps, the resolve pass (depth + id → G-buffer) and deferred Phong shading.

use glam::{Mat3, Mat4, Vec3, Vec4Swizzles};
use rayon::prelude::*;

use super::MESH_ID_FLAG;
use super::asvo::{PassSettings, QNode, VoxelInstance, draw_voxels};
use super::buffers::{DepthTarget, EMPTY_KEY, FrameBuffers, PixelId, RgbaImage, key_depth};
use super::camera::{Camera, Projection};
use super::deform::NodeInfo;
use super::krs::{KRS_ID_FLAG, KrsLighting, KrsPass};
use super::raster::{MeshInstance, WorldTriangle, draw_triangles};
use super::stats::LevelStats;
use crate::mesh::{linear_to_srgb, srgb_to_linear};
use crate::render::Quality;
use crate::scene::Light;
use crate::svo::decode_normal;

/// A directional light's depth map.
pub(crate) struct ShadowMap {
    pub(crate) cam: Camera,
    /// NDC depth per texel, `INFINITY` where nothing casts.
    pub(crate) depth: Vec<f32>,
    /// World size of one texel.
    pub(crate) texel_world: f32,
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
    pub(crate) fn render(
        cam: Camera,
        voxels: &[VoxelInstance<'_>],
        meshes: &[MeshInstance<'_>],
        tris: &[WorldTriangle],
        quality: &Quality,
        levels: &mut Vec<LevelStats>,
    ) -> Self {
        let mut target = DepthTarget::new(cam.width, cam.height);
        draw_triangles(tris, meshes, &cam, &target, true);
        if quality.occlusion_culling {
            target.update_all_tiles();
        }
        let pass = draw_voxels(
            voxels,
            &cam,
            &mut target,
            &PassSettings {
                lod_pixel_threshold: quality.lod_pixel_threshold,
                occlusion_culling: quality.occlusion_culling,
                id_base: 0,
                keep_refs: false,
                shadow_casters_only: true,
            },
        );
        super::stats::FrameStats::merge_levels(levels, &pass.levels);
        let texel_world = 2.0 / cam.fy;
        let depth = target.into_keys().into_par_iter().map(key_depth).collect();
        Self {
            cam,
            depth,
            texel_world,
        }
    }

    /// Fraction of light reaching a world point (1 = lit), with a normal offset, a depth bias
    /// of a few texels plus the receiver's own splat size, and PCF.
    fn visibility(&self, p_world: Vec3, n_world: Vec3, receiver_size_world: f32, pcf: i32) -> f32 {
        // Splat depth is the nearest corner of a node, so a flat voxel surface is a staircase
        // up to one node deep in both maps: bias by both node sizes, and offset along the normal
        // so grazing receivers do not sample their own texel.
        let offset = n_world * (1.5 * self.texel_world);
        let q = self.cam.view_from_world.transform_point3(p_world + offset);
        let s = self.cam.project_view(q);
        let bias = 2.0 * self.texel_world + 1.5 * receiver_size_world;
        let recv = self.cam.ndc_depth(s.z - bias);
        let (w, h) = (self.cam.width as i32, self.cam.height as i32);
        let (ix, iy) = (s.x.floor() as i32, s.y.floor() as i32);
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
        lit as f32 / taps as f32
    }
}

/// Turns packed keys into the G-buffer.
#[allow(
    clippy::too_many_arguments,
    reason = "one call site; the arguments are the frame's parts"
)]
pub(crate) fn resolve(
    keys: &[u64],
    cam: &Camera,
    voxels: &[VoxelInstance<'_>],
    refs: &[QNode],
    meshes: &[MeshInstance<'_>],
    tris: &[WorldTriangle],
) -> FrameBuffers {
    let (w, h) = (cam.width, cam.height);
    let normal_mats: Vec<Mat3> = meshes
        .iter()
        .map(|m| Mat3::from_mat4(m.world_from_object).inverse().transpose())
        .collect();
    let eye = cam.eye();
    let n = keys.len();
    let mut fb = FrameBuffers {
        width: w,
        height: h,
        depth: vec![1.0; n],
        ids: vec![PixelId::default(); n],
        normal: vec![Vec3::ZERO; n],
        albedo: vec![Vec3::ZERO; n],
    };
    let FrameBuffers {
        depth,
        ids,
        normal,
        albedo,
        ..
    } = &mut fb;
    depth
        .par_iter_mut()
        .zip(ids.par_iter_mut())
        .zip(normal.par_iter_mut())
        .zip(albedo.par_iter_mut())
        .enumerate()
        .for_each(|(i, (((d, id), nrm), alb))| {
            let key = keys[i];
            if key == EMPTY_KEY {
                return;
            }
            *d = key_depth(key);
            let raw = (key & 0xffff_ffff) as u32;
            if raw & KRS_ID_FLAG == KRS_ID_FLAG {
                // Filled by `resolve_krs` from the pass's own records.
                return;
            }
            if raw & MESH_ID_FLAG != 0 {
                let Some(t) = tris.get((raw & !MESH_ID_FLAG) as usize) else {
                    return;
                };
                let m = &meshes[t.mesh as usize];
                let part = &m.model.parts[t.part as usize];
                let (x, y) = ((i as u32 % w) as f32 + 0.5, (i as u32 / w) as f32 + 0.5);
                let p = cam.unproject(x, y, *d);
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
                if face.dot(eye - p) < 0.0 {
                    nw = -nw;
                }
                *nrm = nw;
                *alb = color.xyz();
                *id = PixelId {
                    object: m.label,
                    node: (u64::from(t.part) << 32) | u64::from(t.tri),
                };
            } else {
                let Some(q) = refs.get(raw as usize) else {
                    return;
                };
                let o = &voxels[q.obj as usize];
                let info = NodeInfo {
                    svo: o.svo,
                    node: q.node,
                };
                let v = info.voxel();
                *nrm = o.deform.normal_to_world(&info, decode_normal(v.normal));
                *alb = Vec3::new(
                    srgb_byte_to_linear(v.color[0]),
                    srgb_byte_to_linear(v.color[1]),
                    srgb_byte_to_linear(v.color[2]),
                );
                *id = PixelId {
                    object: o.label,
                    node: (u64::from(q.node.level) << 32) | u64::from(q.node.index),
                };
            }
        });
    fb
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

/// `srgb_to_linear(v / 255)` for every byte: three `powf` per pixel dominated the resolve.
/// Same values as the function, so results are unchanged.
fn srgb_byte_to_linear(v: u8) -> f32 {
    static TABLE: std::sync::LazyLock<[f32; 256]> =
        std::sync::LazyLock::new(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)));
    TABLE[usize::from(v)]
}

/// Fills the G-buffer of pixels the KRS won: object label, kernel as node, the §6.1 normal and
/// the textured albedo recorded when the ray hit.
pub(crate) fn resolve_krs(fb: &mut FrameBuffers, keys: &[u64], pass: &KrsPass, labels: &[u32]) {
    fb.ids
        .par_iter_mut()
        .zip(fb.normal.par_iter_mut())
        .zip(fb.albedo.par_iter_mut())
        .enumerate()
        .for_each(|(i, ((id, nrm), alb))| {
            let raw = (keys[i] & 0xffff_ffff) as u32;
            if keys[i] == EMPTY_KEY || raw & KRS_ID_FLAG != KRS_ID_FLAG {
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
    /// One entry per light: its shadow map when it casts shadows this frame.
    pub(crate) shadows: Vec<Option<ShadowMap>>,
    pub(crate) ambient: Vec3,
    pub(crate) background: Vec3,
    /// World radius of the ambient-occlusion samples (see [`AoKernel`]).
    pub(crate) ao_radius_world: f32,
    /// KRS shadow rays, AO and Algorithm 2 diffuse factors.
    pub(crate) krs: KrsLighting<'a>,
}

/// The golden angle in radians: successive AO sample azimuths are this far apart.
const GOLDEN_ANGLE: f32 = 2.399_963_2;

/// Screen-space ambient occlusion from the resolved depth buffer (`quality.ao_samples`).
///
/// Why screen space: it treats voxels and meshes alike (both are in the one depth buffer), costs
/// a fixed number of depth reads per pixel whatever the scene, and a GPU renderer can do the
/// same reads. Sample `i` of `n` (all fixed, no per-pixel noise, so both renderers agree):
/// `u = (i + ½)/n`, a cosine-weighted hemisphere direction with `cos θ = √(1 − u)`, azimuth
/// `φ = i · golden angle` around the normal, at distance `r · (¼ + ¾ · fract((i + ½) · 0.618034))`.
/// See `docs/rendering.md` for the occlusion test.
/// The screen-space AO sample offsets, in the tangent frame of the shaded point (x, y along the
/// tangents, z along the normal) and scaled by their distance: `count` points of a
/// cosine-weighted hemisphere on a golden-angle spiral, at distances from a quarter of
/// `radius_world` to all of it. The GPU renderer uploads exactly these, so both renderers
/// occlude with bit-identical offsets.
#[must_use]
pub fn ao_sample_offsets(count: u32, radius_world: f32) -> Vec<Vec3> {
    let n = count as f32;
    (0..count)
        .map(|i| {
            let fi = i as f32 + 0.5;
            let u = fi / n;
            let cos_t = (1.0 - u).sqrt();
            let sin_t = u.sqrt();
            let phi = i as f32 * GOLDEN_ANGLE;
            let frac = (fi * 0.618_034).fract();
            let dist = radius_world * (0.25 + 0.75 * frac);
            Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t) * dist
        })
        .collect()
}

pub(crate) struct AoKernel {
    /// Per sample: tangent-frame direction scaled by its distance (x, y along the tangents,
    /// z along the normal).
    samples: Vec<Vec3>,
    radius_world: f32,
}

impl AoKernel {
    pub(crate) fn new(count: u32, radius_world: f32) -> Self {
        Self {
            samples: ao_sample_offsets(count, radius_world),
            radius_world,
        }
    }

    /// Fraction of samples not occluded (1 = open) at world point `p` with unit normal `n`.
    /// A sample is occluded when the depth buffer at its pixel holds a surface nearer the eye
    /// than the sample by more than `eps_world` (the voxel staircase: splats store a node's
    /// nearest depth) and by less than the radius (a far foreground object does not darken).
    fn openness(&self, fb: &FrameBuffers, cam: &Camera, p: Vec3, n: Vec3, eps_world: f32) -> f32 {
        if self.samples.is_empty() || n == Vec3::ZERO {
            return 1.0;
        }
        let helper = if n.y.abs() < 0.99 { Vec3::Y } else { Vec3::X };
        let t = n.cross(helper).normalize_or_zero();
        let b = n.cross(t);
        let (w, h) = (cam.width as f32, cam.height as f32);
        let mut occluded = 0u32;
        for s in &self.samples {
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
            if fb.ids[idx].object == 0 {
                continue;
            }
            let gap = d_q - cam.view_depth(fb.depth[idx]);
            if gap > eps_world && gap < self.radius_world {
                occluded += 1;
            }
        }
        1.0 - occluded as f32 / self.samples.len() as f32
    }
}

/// Deferred Phong over the G-buffer; writes an sRGB image.
pub(crate) fn shade(
    fb: &FrameBuffers,
    cam: &Camera,
    lighting: &Lighting<'_>,
    quality: &Quality,
) -> RgbaImage {
    let (w, h) = (fb.width, fb.height);
    let mut img = RgbaImage::new(w, h);
    let eye = cam.eye();
    let pcf = quality.shadow_pcf_radius.min(8) as i32;
    let to8 = linear_to_srgb8;
    let bg = [
        to8(lighting.background.x),
        to8(lighting.background.y),
        to8(lighting.background.z),
        255,
    ];
    let ao = AoKernel::new(quality.ao_samples, lighting.ao_radius_world);
    let lights: Vec<(Vec3, Vec3)> = lighting
        .lights
        .iter()
        .map(|l| (-l.direction.normalize_or_zero(), l.color * l.intensity))
        .collect();
    img.pixels
        .par_chunks_mut(4)
        .enumerate()
        .for_each(|(i, out)| {
            if fb.ids[i].object == 0 {
                out.copy_from_slice(&bg);
                return;
            }
            let (x, y) = ((i as u32 % w) as f32 + 0.5, (i as u32 / w) as f32 + 0.5);
            let krs_px = lighting.krs.pass.pixels.get(i).and_then(Option::as_ref);
            // A KRS pixel keeps its exact hit point; others come back from 32-bit NDC depth.
            let p = krs_px.map_or_else(|| cam.unproject(x, y, fb.depth[i]), |px| px.position);
            let n = fb.normal[i];
            let v = (eye - p).normalize_or_zero();
            let receiver = cam.pixel_world_size(cam.view_depth(fb.depth[i]))
                * quality.lod_pixel_threshold.max(1.0);
            // The AO staircase tolerance: the receiver term of the shadow bias.
            let open = ao.openness(fb, cam, p, n, 1.5 * receiver);
            let footprint = krs_px.map_or(receiver, |px| px.epsilon.max(receiver));
            // Screen-space AO (every surface in the depth buffer) times the KRS distance AO
            // (occlusion by KRS geometry, also outside the screen).
            let mut light = lighting.ambient * (open * lighting.krs.ambient(p, n));
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
                let mut vis = match lighting.shadows.get(li) {
                    Some(Some(sm)) => sm.visibility(p, n, receiver, pcf),
                    _ => 1.0,
                };
                if vis > 0.0 && lighting.lights[li].casts_shadows {
                    vis *= lighting.krs.shadow(p, n, l, footprint);
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
        });
    let _ = h;
    img
}

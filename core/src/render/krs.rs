//! KRS objects in the CPU renderer (KRS paper §4, §6): per-pixel sphere tracing into the shared
//! packed depth+id target, so KRS, voxels and meshes occlude each other; the G-buffer gets the
//! analytic §6.1 normal and the textured albedo (§6.2); Algorithm 2 diffuse factors for the
//! shading pass; shadow rays and distance-sampled ambient occlusion through the KRS.
//!
//! The pass runs after triangles and voxels: each ray stops at the depth already in its pixel
//! (nothing behind it can win), which is the KRS counterpart of the voxels' occlusion culling.
//! With tile acceleration on, each 8×8-pixel tile first marches its cone (§4.1) and its rays
//! start where the cone stops being empty; hits are identical with and without (see
//! `docs/krs.md`).

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::MESH_ID_FLAG;
use super::buffers::{DepthTarget, EMPTY_KEY, key_depth, pack_key};
use super::camera::Camera;
use crate::krs::{
    AoSettings, PreparedScene, ShadowSettings, TraceSettings, ambient_occlusion, ao_jitter,
    shade_colour, shading_threshold, shadow_counted, tile_cone, tile_start_distance_counted, trace,
};
use crate::quality::Quality;
use crate::scene::Light;

/// Ids with these bits set are KRS fragments (the low bits are the prepared object's index).
/// Triangles keep [`MESH_ID_FLAG`] with bit 30 clear: a frame would need 2^30 triangles (48 GiB
/// of world triangles) before their ids reached it.
pub(crate) const KRS_ID_FLAG: u32 = MESH_ID_FLAG | (1 << 30);

/// Edge of a screen tile for the §4.1 cone march, in pixels.
pub const KRS_TILE: u32 = 8;

/// Penumbra factor k of soft KRS shadows (visibility = min k·d/t along the ray): 16 gives a
/// penumbra about 1/16 radian wide, a sun-like light.
pub const SOFT_SHADOW_K: f32 = 16.0;

/// Width of the Algorithm 2 blend zone around each mirror plane, in pixels at the hit's depth
/// (§6.1: the threshold is proportional to depth so the blend stays a fixed screen width).
pub const SMOOTHING_PX: f32 = 2.0;

/// Reach of the ambient-occlusion distance samples, in object units of the smallest-scale KRS
/// object (a tree of the presets is about 6 units tall: the samples see crevices, forks and
/// the ground around a trunk, not the whole forest).
pub const AO_REACH_OBJECT_UNITS: f32 = 0.4;

/// The KRS objects of a frame: a prepared scene (validated, transforms composed) and the label
/// each object reports in [`super::PixelId::object`].
#[derive(Debug, Clone, Default)]
pub struct KrsLayer {
    /// The objects, in world space.
    pub scene: PreparedScene,
    /// `labels[i]` is reported for pixels showing `scene.objects[i]` (1-based; 0 = background).
    pub labels: Vec<u32>,
    /// Whether the KRS casts shadows (shadow rays through it from every lit pixel).
    pub casts_shadows: bool,
}

impl KrsLayer {
    /// True when there is nothing to trace.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.scene.objects.iter().all(|o| o.is_empty)
    }

    /// The smallest object scale (sets the AO reach), 1 when empty.
    fn min_scale(&self) -> f32 {
        self.scene
            .objects
            .iter()
            .filter(|o| !o.is_empty)
            .map(|o| o.object.world_from_object.scale)
            .fold(f32::INFINITY, f32::min)
            .clamp(1e-30, 1e30)
    }
}

/// Counters of the KRS pass.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct KrsStats {
    /// Primary rays traced (pixels not already covered at the near plane).
    pub rays: u64,
    /// Rays that hit a KRS surface in front of what the pixel held.
    pub hits: u64,
    /// Distance evaluations of primary rays (rejected over-relaxed probes included).
    pub steps: u64,
    /// Evaluations spent by the §4.1 tile cones.
    pub tile_steps: u64,
    /// Primary rays that ran out of steps (drawn as misses).
    pub exhausted: u64,
    /// Over-relaxed probes taken back.
    pub relaxation_fallbacks: u64,
    /// Shadow rays traced through the KRS.
    pub shadow_rays: u64,
    /// Distance evaluations of those shadow rays.
    #[serde(default)]
    pub shadow_steps: u64,
    /// Distance evaluations of the KRS ambient occlusion (samples per shaded pixel).
    #[serde(default)]
    pub ao_evals: u64,
}

impl KrsStats {
    /// Both counts added, field by field.
    fn sum(a: Self, b: Self) -> Self {
        Self {
            rays: a.rays + b.rays,
            hits: a.hits + b.hits,
            steps: a.steps + b.steps,
            tile_steps: a.tile_steps + b.tile_steps,
            exhausted: a.exhausted + b.exhausted,
            relaxation_fallbacks: a.relaxation_fallbacks + b.relaxation_fallbacks,
            shadow_rays: a.shadow_rays + b.shadow_rays,
            shadow_steps: a.shadow_steps + b.shadow_steps,
            ao_evals: a.ao_evals + b.ao_evals,
        }
    }
}

/// One KRS fragment that won its pixel's depth test when it was written.
#[derive(Debug, Clone, Copy)]
pub(crate) struct KrsPixel {
    /// Index into the prepared scene.
    pub(crate) object: u32,
    /// Kernel hit (reported as the pixel's node).
    pub(crate) kernel: u32,
    /// Exact hit position (better than one reconstructed from 32-bit NDC depth).
    pub(crate) position: Vec3,
    /// World normal (§6.1).
    pub(crate) normal: Vec3,
    /// Linear albedo, textured (§6.2).
    pub(crate) albedo: Vec3,
    /// Epsilon at the hit: how far the point may be from the surface.
    pub(crate) epsilon: f32,
}

/// What the pass leaves for resolve and shading.
#[derive(Default)]
pub(crate) struct KrsPass {
    /// Per pixel, the KRS fragment written there (the key decides whether it won); empty when
    /// the frame has no KRS.
    pub(crate) pixels: Vec<Option<KrsPixel>>,
    /// Per pixel and light (`pixel * max(lights, 1) + light`): the Algorithm 2 diffuse
    /// factor; NaN where the plain `n·l` applies (no KRS fragment).
    pub(crate) diffuse: Vec<f32>,
    /// Directions towards each light, for the factors.
    light_dirs: Vec<Vec3>,
    pub(crate) stats: KrsStats,
}

/// A camera ray with the map from its parameter to view depth: `depth(t) = depth0 + t·cos`.
#[derive(Debug, Clone, Copy)]
struct PixelRay {
    origin: Vec3,
    dir: Vec3,
    depth0: f32,
    cos: f32,
}

impl PixelRay {
    /// The ray through screen point `(sx, sy)`. Directions are built in view space and rotated,
    /// never as a difference of far-apart world points (a camera 1e6 units out would lose them).
    fn new(cam: &Camera, sx: f32, sy: f32) -> Self {
        let x = (sx - 0.5 * cam.width as f32) / cam.fx;
        let y = (0.5 * cam.height as f32 - sy) / cam.fy;
        let rot = cam.world_from_view;
        if cam.perspective {
            let dir_view = Vec3::new(x, y, -1.0).normalize_or(Vec3::NEG_Z);
            Self {
                origin: cam.eye(),
                dir: rot.transform_vector3(dir_view).normalize_or(Vec3::NEG_Z),
                depth0: 0.0,
                cos: -dir_view.z,
            }
        } else {
            Self {
                origin: rot.transform_point3(Vec3::new(x, y, -cam.near)),
                dir: rot.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z),
                depth0: cam.near,
                cos: 1.0,
            }
        }
    }

    fn t_of_depth(&self, depth: f32) -> f32 {
        (depth - self.depth0) / self.cos.max(1e-12)
    }

    fn depth_of_t(&self, t: f32) -> f32 {
        self.depth0 + t * self.cos
    }
}

/// Tracing settings for a camera: a pixel-cone epsilon of `krs_epsilon_scale` pixels. The GPU
/// KRS pass takes its epsilon and sample grid from these too.
#[must_use]
pub fn trace_settings(cam: &Camera, quality: &Quality) -> TraceSettings {
    let pixel = 1.0 / cam.fy.min(cam.fx).max(1e-30);
    let (cone, floor) = if cam.perspective {
        // The floor is the footprint at the near plane: rays start there, and nothing nearer
        // is drawn.
        (pixel, quality.krs_epsilon_scale * pixel * cam.near)
    } else {
        (0.0, quality.krs_epsilon_scale * pixel)
    };
    TraceSettings {
        eps_scale: quality.krs_epsilon_scale,
        pixel_cone_ratio: cone,
        min_epsilon: floor.max(1e-9),
        max_steps: quality.krs_max_steps,
        max_distance: f32::INFINITY,
        over_relaxation: quality.krs_over_relaxation,
        start_distance: 0.0,
    }
}

/// Traces every pixel not already covered nearer, writes KRS fragments into `target` and
/// their records into `pass` (its buffers reused from frame to frame: a steady frame
/// allocates nothing here).
///
/// The image is cut into bands of [`KRS_TILE`] rows, traced in parallel; each band writes its
/// own rows of `pass`, tile by tile, so no fragment list is gathered and copied afterwards.
pub(crate) fn draw_krs(
    layer: &KrsLayer,
    lights: &[Light],
    cam: &Camera,
    target: &DepthTarget,
    quality: &Quality,
    pass: &mut KrsPass,
) {
    pass.stats = KrsStats::default();
    let (w, h) = (cam.width, cam.height);
    let n = w as usize * h as usize;
    // Without KRS objects the per-pixel records are empty (readers use `get`), and what an
    // earlier frame held is freed: at 8192² they are 3.7 GB.
    if layer.is_empty() || n == 0 {
        pass.pixels = Vec::new();
        pass.diffuse = Vec::new();
        return;
    }
    pass.pixels.clear();
    pass.diffuse.clear();
    let lights_n = lights.len();
    // One factor slot per pixel even without lights, so the bands below split both evenly.
    let slots = lights_n.max(1);
    pass.pixels.resize(n, None);
    pass.diffuse.resize(n * slots, f32::NAN);
    pass.light_dirs.clear();
    pass.light_dirs
        .extend(lights.iter().map(|l| -l.direction.normalize_or_zero()));
    let base = trace_settings(cam, quality);
    let tiles_x = w.div_ceil(KRS_TILE);
    let use_tiles = quality.krs_tile_acceleration && cam.perspective;
    let t_far_depth = cam.far;
    let light_dirs = &pass.light_dirs[..];
    let band = KRS_TILE as usize * w as usize;

    pass.stats = pass
        .pixels
        .par_chunks_mut(band)
        .zip(pass.diffuse.par_chunks_mut(band * slots))
        .enumerate()
        .map(|(ty, (pixels, diffuse))| {
            let ty = ty as u32;
            let mut stats = KrsStats::default();
            for tx in 0..tiles_x {
                let (x0, y0) = (tx * KRS_TILE, ty * KRS_TILE);
                let (x1, y1) = ((x0 + KRS_TILE).min(w), (y0 + KRS_TILE).min(h));
                let tile_start = if use_tiles {
                    let corners = [
                        (x0 as f32, y0 as f32),
                        (x1 as f32, y0 as f32),
                        (x0 as f32, y1 as f32),
                        (x1 as f32, y1 as f32),
                    ]
                    .map(|(x, y)| PixelRay::new(cam, x, y).dir);
                    let (axis, half_angle) = tile_cone(&corners);
                    let settings = TraceSettings {
                        max_distance: PixelRay::new(
                            cam,
                            0.5 * (x0 + x1) as f32,
                            0.5 * (y0 + y1) as f32,
                        )
                        .t_of_depth(t_far_depth)
                            * 2.0,
                        ..base
                    };
                    let (t, steps) = tile_start_distance_counted(
                        &layer.scene,
                        cam.eye(),
                        axis,
                        half_angle,
                        &settings,
                    );
                    stats.tile_steps += u64::from(steps);
                    t
                } else {
                    0.0
                };
                for y in y0..y1 {
                    for x in x0..x1 {
                        let i = y as usize * w as usize + x as usize;
                        // This pixel's place in the band's rows.
                        let local = i - y0 as usize * w as usize;
                        let ray = PixelRay::new(cam, x as f32 + 0.5, y as f32 + 0.5);
                        let existing = target.keys[i].load(Ordering::Relaxed);
                        let limit_depth = if existing == EMPTY_KEY {
                            cam.far
                        } else {
                            cam.view_depth(key_depth(existing)).min(cam.far)
                        };
                        let t_min = ray.t_of_depth(cam.near).max(0.0);
                        let t_max = ray.t_of_depth(limit_depth);
                        if t_max.is_nan() || t_max <= t_min {
                            continue;
                        }
                        let settings = TraceSettings {
                            start_distance: t_min.max(tile_start),
                            // A hair beyond the held depth: a tie goes to the key comparison.
                            max_distance: t_max * (1.0 + 1e-6),
                            ..base
                        };
                        let hit = trace(&layer.scene, ray.origin, ray.dir, &settings);
                        stats.rays += 1;
                        stats.steps += u64::from(hit.steps);
                        stats.relaxation_fallbacks += u64::from(hit.relaxation_fallbacks);
                        stats.exhausted += u64::from(hit.exhausted);
                        if !hit.hit {
                            continue;
                        }
                        let ndc = cam.ndc_depth(ray.depth_of_t(hit.t));
                        if !(0.0..=1.0).contains(&ndc) || !hit.position.is_finite() {
                            continue;
                        }
                        let key = pack_key(ndc, KRS_ID_FLAG | hit.object as u32);
                        if key >= existing {
                            continue;
                        }
                        target.write(x, y, key);
                        stats.hits += 1;
                        let obj = &layer.scene.objects[hit.object];
                        let threshold =
                            shading_threshold(hit.t, base.pixel_cone_ratio, SMOOTHING_PX);
                        let factors = &mut diffuse[local * slots..local * slots + lights_n];
                        for (d, &l) in factors.iter_mut().zip(light_dirs) {
                            *d = obj.smooth_shading(hit.position, l, threshold).diffuse;
                        }
                        let normal = hit.normal.normalize_or(-ray.dir);
                        pixels[local] = Some(KrsPixel {
                            object: hit.object as u32,
                            kernel: hit.kernel.map_or(u32::MAX, |k| k as u32),
                            position: hit.position,
                            normal,
                            albedo: shade_colour(&layer.scene, &hit).clamp(Vec3::ZERO, Vec3::ONE),
                            epsilon: hit.epsilon,
                        });
                    }
                }
            }
            stats
        })
        .reduce(KrsStats::default, KrsStats::sum);
}

/// Lighting inputs from the KRS for the shading pass.
pub(crate) struct KrsLighting<'a> {
    pub(crate) layer: &'a KrsLayer,
    pub(crate) pass: &'a KrsPass,
    /// Shadow rays through the KRS (quality.shadows and the layer casts).
    pub(crate) shadows: bool,
    pub(crate) soft: bool,
    pub(crate) max_steps: u32,
    /// AO samples (0 = off) and their spacing in world units.
    pub(crate) ao_samples: u32,
    pub(crate) ao_spacing: f32,
    /// Shadow rays traced (for the frame statistics).
    pub(crate) shadow_rays: AtomicU64,
}

impl<'a> KrsLighting<'a> {
    pub(crate) fn new(layer: &'a KrsLayer, pass: &'a KrsPass, quality: &Quality) -> Self {
        let samples = quality.ao_samples;
        Self {
            layer,
            pass,
            shadows: quality.shadows && layer.casts_shadows && !layer.is_empty(),
            soft: quality.krs_soft_shadows,
            max_steps: quality.krs_max_steps,
            ao_samples: if layer.is_empty() { 0 } else { samples },
            ao_spacing: AO_REACH_OBJECT_UNITS * layer.min_scale() / samples.max(1) as f32,
            shadow_rays: AtomicU64::new(0),
        }
    }

    /// The Algorithm 2 diffuse factor for pixel `i` and light `li`, if it applies.
    pub(crate) fn diffuse(&self, i: usize, li: usize, lights: usize) -> Option<f32> {
        self.pass
            .diffuse
            .get(i * lights.max(1) + li)
            .copied()
            .filter(|d| d.is_finite())
    }

    /// Light visibility through the KRS from a receiver at `p` with normal `n`; `footprint` is
    /// how far the receiver point may be from its true surface (pixel size or hit epsilon).
    /// Also returns the distance evaluations the shadow ray took.
    pub(crate) fn shadow(&self, p: Vec3, n: Vec3, to_light: Vec3, footprint: f32) -> (f32, u32) {
        if !self.shadows {
            return (1.0, 0);
        }
        self.shadow_rays.fetch_add(1, Ordering::Relaxed);
        let settings = ShadowSettings {
            // Leave the receiver: it may be a KRS surface whose estimate there is ~epsilon.
            start_offset: 2.0 * footprint,
            max_distance: 1e6,
            max_steps: self.max_steps,
            epsilon: 0.5 * footprint,
            softness: self.soft.then_some(SOFT_SHADOW_K),
        };
        shadow_counted(
            &self.layer.scene,
            p + n * (2.0 * footprint),
            to_light,
            &settings,
        )
    }

    /// Ambient accessibility from the KRS around `p` (1 when AO is off) for pixel `pixel` of
    /// the image drawn (its index picks the samples' jitter, `krs::ao_jitter`), and the
    /// distance evaluations it took (one per sample).
    pub(crate) fn ambient(&self, p: Vec3, n: Vec3, pixel: u32) -> (f32, u32) {
        if self.ao_samples == 0 {
            return (1.0, 0);
        }
        let open = ambient_occlusion(
            &self.layer.scene,
            p,
            n,
            &AoSettings {
                samples: self.ao_samples,
                spacing: self.ao_spacing,
                strength: 1.0,
                jitter: ao_jitter(pixel),
            },
        );
        (open, self.ao_samples)
    }
}

//! The frame's decisions, made before any GPU object is touched: the views (the camera and
//! one shadow camera per shadow-casting light), every frame buffer's size, the limits they
//! must fit, and which passes run. Pure: unit-tested without a device.

use glam::{Mat4, Vec3};
use thicket_core::quality::Quality;
use thicket_core::scene::{Light, OrbitCamera};

use super::super::gpu_data::{GBUFFER_TEXEL_BYTES, KEY_BYTES, OCCLUSION_TILE, ViewUniform};
use super::super::{AtomicPath, GpuError};

/// A camera as the passes see it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::gpu) struct ViewSpec {
    pub(in crate::gpu) view_from_world: Mat4,
    pub(in crate::gpu) clip_from_view: Mat4,
    pub(in crate::gpu) width: u32,
    pub(in crate::gpu) height: u32,
    pub(in crate::gpu) perspective: bool,
    pub(in crate::gpu) fx: f32,
    pub(in crate::gpu) fy: f32,
    pub(in crate::gpu) near: f32,
    pub(in crate::gpu) far: f32,
}

impl ViewSpec {
    /// The passes' view of a CPU reference camera (perspective or orthographic), so both
    /// renderers project with the same numbers.
    pub(in crate::gpu) fn from_camera(cam: &thicket_core::render::Camera) -> Self {
        let (fx, fy) = cam.focal_px();
        Self {
            view_from_world: cam.view_from_world,
            clip_from_view: cam.clip_from_view(),
            width: cam.width,
            height: cam.height,
            perspective: cam.is_perspective(),
            fx,
            fy,
            near: cam.near(),
            far: cam.far(),
        }
    }

    /// The shadow camera of the CPU reference: `core::render::shade::fit_light_camera` (the
    /// box fit, at most `max_size` texels per edge, texels no finer than `finest_texel_world`),
    /// called rather than copied so both renderers sample the same shadow texels.
    pub(in crate::gpu) fn fit_light_bound(
        direction: Vec3,
        lo: Vec3,
        hi: Vec3,
        max_size: u32,
        finest_texel_world: f32,
    ) -> Option<Self> {
        thicket_core::render::shade::fit_light_camera(
            direction,
            lo,
            hi,
            max_size,
            finest_texel_world,
        )
        .map(|cam| Self::from_camera(&cam))
    }

    /// The view's uniform block for a pass writing in `write_mode`.
    pub(in crate::gpu) fn uniform(
        &self,
        write_mode: u32,
        quality: &Quality,
        occlusion: bool,
    ) -> ViewUniform {
        ViewUniform {
            view_from_world: self.view_from_world.to_cols_array_2d(),
            clip_from_world: (self.clip_from_view * self.view_from_world).to_cols_array_2d(),
            world_from_view: self.view_from_world.inverse().to_cols_array_2d(),
            size: [self.width, self.height],
            perspective: u32::from(self.perspective),
            write_mode,
            fx: self.fx,
            fy: self.fy,
            near: self.near,
            far: self.far,
            lod_pixel_threshold: quality.lod_pixel_threshold,
            occlusion: u32::from(occlusion),
            tiles_x: self.width.div_ceil(OCCLUSION_TILE),
            cube_pixel_threshold: quality.cube_pixel_threshold,
        }
    }
}

/// One light's shadow map this frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::gpu) struct ShadowPlan {
    /// Index of the light in the document.
    pub(in crate::gpu) light: usize,
    /// Its camera (the CPU's `fit_light_camera`).
    pub(in crate::gpu) view: ViewSpec,
    /// Where its keys start in the shadow key buffer (a multiple of the device's storage
    /// offset alignment, so its passes can bind just this range).
    pub(in crate::gpu) offset: u64,
    /// Bytes of its keys.
    pub(in crate::gpu) bytes: u64,
    /// Bytes its passes bind from `offset` (its slot: at least `bytes`).
    pub(in crate::gpu) slot_bytes: u64,
}

/// The device limits a plan must respect.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::gpu) struct PlanLimits {
    /// `max_storage_buffer_binding_size`.
    pub(in crate::gpu) binding: u64,
    /// `min_storage_buffer_offset_alignment`.
    pub(in crate::gpu) offset_alignment: u64,
}

impl PlanLimits {
    pub(in crate::gpu) fn of(limits: &wgpu::Limits) -> Self {
        Self {
            binding: limits.max_storage_buffer_binding_size,
            offset_alignment: u64::from(limits.min_storage_buffer_offset_alignment.max(4)),
        }
    }
}

/// What the scene offers the plan (after the upload and the skin's posing).
#[derive(Clone, Copy, Debug)]
pub(in crate::gpu) struct PlanScene<'a> {
    /// The lights of the document.
    pub(in crate::gpu) lights: &'a [Light],
    /// World bounds of everything drawn (`None`: nothing).
    pub(in crate::gpu) bounds: Option<(Vec3, Vec3)>,
    /// Voxel objects uploaded.
    pub(in crate::gpu) voxel_objects: usize,
    /// Triangles of every mesh, and of the shadow-casting ones (first in the buffer).
    pub(in crate::gpu) triangles: u32,
    pub(in crate::gpu) caster_triangles: u32,
    /// Whether the document holds KRS objects.
    pub(in crate::gpu) krs: bool,
    /// The shadow maps' slot size of an earlier frame ([`FramePlan::shadow_slot`]; 0: none):
    /// slots only grow while they fit a binding, so a camera moving back and forth keeps
    /// every map's place and binding.
    pub(in crate::gpu) kept_shadow_slot: u64,
}

/// Which passes the frame encodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::gpu) struct PassSet {
    /// Shadow casters rasterised into the shadow maps.
    pub(in crate::gpu) shadow_meshes: bool,
    /// Voxel objects traversed into the shadow maps.
    pub(in crate::gpu) shadow_voxels: bool,
    /// The view's meshes rasterised.
    pub(in crate::gpu) meshes: bool,
    /// The view's voxel objects traversed.
    pub(in crate::gpu) voxels: bool,
    /// The second (id) pass of the two-pass 32-bit path.
    pub(in crate::gpu) id_pass: bool,
    /// Hi-Z occlusion tiles rebuilt before each level of the view's traversal.
    pub(in crate::gpu) hiz: bool,
    /// KRS trace and lighting.
    pub(in crate::gpu) krs: bool,
}

/// One frame's decisions (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub(in crate::gpu) struct FramePlan {
    /// The CPU reference's camera for the view (what `main` and the KRS pass's constants are
    /// taken from).
    pub(in crate::gpu) camera: thicket_core::render::Camera,
    /// The view.
    pub(in crate::gpu) main: ViewSpec,
    /// One map per shadow-casting light that has a shadow camera, packed in one key buffer.
    pub(in crate::gpu) shadows: Vec<ShadowPlan>,
    /// The splat path.
    pub(in crate::gpu) path: AtomicPath,
    /// Pixels of the view.
    pub(in crate::gpu) pixels: u64,
    /// Bytes of the view's key buffer, its G-buffer and its occlusion tiles.
    pub(in crate::gpu) key_bytes: u64,
    pub(in crate::gpu) gbuffer_bytes: u64,
    pub(in crate::gpu) tile_bytes: u64,
    /// Bytes of every shadow map's slot together (0 without maps): the shadow key buffer.
    pub(in crate::gpu) shadow_key_bytes: u64,
    /// 32-bit words the shade pass binds (at least 4).
    pub(in crate::gpu) shadow_words: u64,
    /// Bytes of every map's slot when the maps have equal slots (`None`: packed tightly).
    pub(in crate::gpu) shadow_slot: Option<u64>,
    /// Workgroups of one Hi-Z build.
    pub(in crate::gpu) hiz_groups: (u32, u32),
    /// Workgroups of a per-pixel pass (8 × 8 pixels each).
    pub(in crate::gpu) pixel_groups: (u32, u32),
    /// Size of the attachment the shadow maps' mesh draws share (`None`: no shadow meshes).
    pub(in crate::gpu) shadow_attachment: Option<(u32, u32)>,
    /// The passes that run.
    pub(in crate::gpu) passes: PassSet,
}

/// Workgroups (x, y) of 256 invocations covering `words` 32-bit words (the clear pass).
pub(in crate::gpu) fn clear_groups(words: u64) -> (u32, u32) {
    let groups = words.div_ceil(256);
    let gx = groups.min(65535) as u32;
    let gy = groups.div_ceil(u64::from(gx.max(1))) as u32;
    (gx, gy)
}

impl FramePlan {
    /// Plans a `width × height` frame of `scene` from `camera`.
    ///
    /// # Errors
    /// [`GpuError::TooLarge`] when the view's buffers or the shadow maps together exceed a
    /// storage binding.
    pub(in crate::gpu) fn new(
        camera: &OrbitCamera,
        (width, height): (u32, u32),
        quality: &Quality,
        scene: &PlanScene<'_>,
        path: AtomicPath,
        limits: PlanLimits,
    ) -> Result<Self, GpuError> {
        let main_camera = thicket_core::render::Camera::from_orbit(camera, width, height);
        let main = ViewSpec::from_camera(&main_camera);
        let fits = fit_shadows(&main_camera, quality, scene);
        let pixels = u64::from(width) * u64::from(height);
        let key_bytes = pixels * KEY_BYTES;
        let gbuffer_bytes = pixels * GBUFFER_TEXEL_BYTES;
        if key_bytes > limits.binding || gbuffer_bytes > limits.binding {
            return Err(GpuError::TooLarge {
                what: "G-buffer",
                bytes: gbuffer_bytes,
                limit: limits.binding,
            });
        }
        let (shadows, shadow_slot) = layout_shadows(&fits, limits, scene.kept_shadow_slot)?;
        let shadow_key_bytes = shadow_keys_end(&shadows);
        let tiles = (
            width.div_ceil(OCCLUSION_TILE),
            height.div_ceil(OCCLUSION_TILE),
        );
        let (sw, sh) = shadows.iter().fold((0, 0), |(a, b), m| {
            (a.max(m.view.width), b.max(m.view.height))
        });
        // The maps' shared attachment in power-of-two sizes (no larger than the largest map
        // the quality allows), so a camera move that resizes the maps a little keeps it.
        let bucket = |e: u32| e.next_power_of_two().min(quality.shadow_map_size.max(e));
        let has_voxels = scene.voxel_objects > 0;
        let passes = PassSet {
            shadow_meshes: !shadows.is_empty() && scene.caster_triangles > 0,
            shadow_voxels: !shadows.is_empty() && has_voxels,
            meshes: scene.triangles > 0,
            voxels: has_voxels,
            id_pass: path == AtomicPath::TwoPass32,
            hiz: has_voxels && quality.occlusion_culling,
            krs: scene.krs,
        };
        Ok(Self {
            camera: main_camera,
            main,
            path,
            pixels,
            key_bytes,
            gbuffer_bytes,
            tile_bytes: u64::from(tiles.0) * u64::from(tiles.1) * 4,
            shadow_key_bytes,
            // The whole buffer may be larger (reused from a larger frame): clear and bind only
            // what the maps use.
            shadow_words: shadow_key_bytes.max(16) / 4,
            shadow_slot,
            hiz_groups: (tiles.0.div_ceil(8), tiles.1.div_ceil(8)),
            pixel_groups: (width.div_ceil(8), height.div_ceil(8)),
            shadow_attachment: passes.shadow_meshes.then_some((bucket(sw), bucket(sh))),
            shadows,
            passes,
        })
    }

    /// The view's size in pixels.
    pub(in crate::gpu) fn size(&self) -> (u32, u32) {
        (self.main.width, self.main.height)
    }
}

/// Shadow cameras: one per shadow-casting light, as the CPU's `render_scene` (none with
/// shadows off, nothing that casts, or nothing drawn), each fit to everything drawn:
/// (light index, camera).
fn fit_shadows(
    main_camera: &thicket_core::render::Camera,
    quality: &Quality,
    scene: &PlanScene<'_>,
) -> Vec<(usize, ViewSpec)> {
    let has_casters = scene.voxel_objects > 0 || scene.caster_triangles > 0;
    let Some((lo, hi)) = scene.bounds else {
        return Vec::new();
    };
    if !quality.shadows || !has_casters || !lo.is_finite() || !hi.is_finite() {
        return Vec::new();
    }
    // The CPU's choice, called rather than copied (one view pixel where the scene comes
    // nearest the eye; an orthographic view's pixel).
    let finest = thicket_core::render::finest_shadow_texel(main_camera, lo, hi);
    scene
        .lights
        .iter()
        .enumerate()
        .filter(|(_, l)| l.casts_shadows)
        .filter_map(|(light, l)| {
            let view =
                ViewSpec::fit_light_bound(l.direction, lo, hi, quality.shadow_map_size, finest)?;
            Some((light, view))
        })
        .collect()
}

/// Bytes of the shadow key buffer that holds `maps` (the end of the last one).
fn shadow_keys_end(maps: &[ShadowPlan]) -> u64 {
    maps.last().map_or(0, |m| m.offset + m.slot_bytes)
}

/// Places every map in the one shadow key buffer, each at an offset its passes can bind its
/// range at (a multiple of the storage offset alignment).
///
/// Each map gets a slot of the same size: the largest map's bytes rounded up to a power of
/// two, or `kept_slot` when that is larger. A camera move that resizes the maps within their
/// slots (the maps' texel size follows the view) keeps every offset, binding and the buffer,
/// so such a frame creates nothing. When the slots would exceed a binding, smaller slots are
/// tried, then the maps are packed tightly (returned slot `None`).
///
/// # Errors
/// [`GpuError::TooLarge`] when even the packed maps exceed a binding (the shade pass binds
/// them all at once).
fn layout_shadows(
    fits: &[(usize, ViewSpec)],
    limits: PlanLimits,
    kept_slot: u64,
) -> Result<(Vec<ShadowPlan>, Option<u64>), GpuError> {
    let bytes_of = |v: &ViewSpec| u64::from(v.width) * u64::from(v.height) * KEY_BYTES;
    let layout = |slot: Option<u64>| {
        let mut next = 0u64;
        fits.iter()
            .map(|&(light, view)| {
                let bytes = bytes_of(&view);
                let offset = next.next_multiple_of(limits.offset_alignment);
                let slot_bytes = slot.unwrap_or(bytes);
                next = offset + slot_bytes;
                ShadowPlan {
                    light,
                    view,
                    offset,
                    bytes,
                    slot_bytes,
                }
            })
            .collect::<Vec<_>>()
    };
    if fits.is_empty() {
        return Ok((Vec::new(), None));
    }
    let largest = fits.iter().map(|(_, v)| bytes_of(v)).max().unwrap_or(0);
    let bucket = largest.next_power_of_two();
    for slot in [bucket.max(kept_slot), bucket] {
        let slotted = layout(Some(slot));
        if shadow_keys_end(&slotted) <= limits.binding {
            return Ok((slotted, Some(slot)));
        }
    }
    let packed = layout(None);
    let bytes = shadow_keys_end(&packed);
    if bytes > limits.binding {
        return Err(GpuError::TooLarge {
            what: if packed.len() == 1 {
                "shadow map"
            } else {
                "shadow maps (one per shadow-casting light, bound together)"
            },
            bytes,
            limit: limits.binding,
        });
    }
    Ok((packed, None))
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: PlanLimits = PlanLimits {
        binding: 128 << 20,
        offset_alignment: 256,
    };

    fn light(direction: Vec3, casts_shadows: bool) -> Light {
        Light {
            name: "l".into(),
            direction,
            color: Vec3::ONE,
            intensity: 1.0,
            casts_shadows,
        }
    }

    fn scene(lights: &[Light]) -> PlanScene<'_> {
        PlanScene {
            lights,
            bounds: Some((Vec3::splat(-1.0), Vec3::splat(1.0))),
            voxel_objects: 1,
            triangles: 12,
            caster_triangles: 12,
            krs: false,
            kept_shadow_slot: 0,
        }
    }

    fn plan(scene: &PlanScene<'_>, quality: &Quality, path: AtomicPath) -> FramePlan {
        FramePlan::new(
            &OrbitCamera::default(),
            (200, 100),
            quality,
            scene,
            path,
            LIMITS,
        )
        .expect("fits")
    }

    #[test]
    fn light_camera_holds_the_box() {
        let (lo, hi) = (Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 1.0, 0.5));
        let v = ViewSpec::fit_light_bound(Vec3::new(-0.4, -1.0, -0.3), lo, hi, 256, 0.0)
            .expect("direction");
        let clip = v.clip_from_view * v.view_from_world;
        for k in 0..8 {
            let c = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let ndc = clip.project_point3(c);
            assert!(ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0, "{ndc}");
            assert!((0.0..=1.0).contains(&ndc.z), "{ndc}");
        }
        assert!(ViewSpec::fit_light_bound(Vec3::ZERO, lo, hi, 256, 0.0).is_none());
    }

    #[test]
    fn view_sizes_follow_the_target() {
        let lights = [light(Vec3::NEG_Y, true)];
        let p = plan(&scene(&lights), &Quality::default(), AtomicPath::Key64);
        assert_eq!(p.size(), (200, 100));
        assert_eq!(p.pixels, 20_000);
        assert_eq!(p.key_bytes, 20_000 * KEY_BYTES);
        assert_eq!(p.gbuffer_bytes, 20_000 * GBUFFER_TEXEL_BYTES);
        let tiles = u64::from(200u32.div_ceil(OCCLUSION_TILE) * 100u32.div_ceil(OCCLUSION_TILE));
        assert_eq!(p.tile_bytes, tiles * 4);
        assert_eq!(p.pixel_groups, (25, 13));
    }

    #[test]
    fn shadow_maps_are_packed_at_aligned_offsets_without_overlap() {
        let lights = [
            light(Vec3::new(-0.3, -1.0, -0.2), true),
            light(Vec3::new(0.5, -1.0, 0.1), false),
            light(Vec3::new(0.2, -0.7, 0.6), true),
            light(Vec3::ZERO, true),
        ];
        let p = plan(&scene(&lights), &Quality::default(), AtomicPath::Key64);
        // The non-casting light and the one without a direction get no map.
        assert_eq!(
            p.shadows.iter().map(|m| m.light).collect::<Vec<_>>(),
            [0, 2]
        );
        let mut end = 0;
        for m in &p.shadows {
            assert_eq!(m.offset % LIMITS.offset_alignment, 0);
            assert!(m.offset >= end, "maps overlap");
            assert_eq!(
                m.bytes,
                u64::from(m.view.width) * u64::from(m.view.height) * KEY_BYTES
            );
            assert!(m.slot_bytes >= m.bytes && m.slot_bytes.is_power_of_two());
            end = m.offset + m.slot_bytes;
        }
        assert_eq!(p.shadow_key_bytes, end);
        assert_eq!(p.shadow_words, end / 4);
        assert_eq!(p.shadow_slot, Some(p.shadows[0].slot_bytes));
        assert!(p.passes.shadow_meshes && p.passes.shadow_voxels);
        let (aw, ah) = p.shadow_attachment.expect("shadow meshes");
        for m in &p.shadows {
            assert!(m.view.width <= aw && m.view.height <= ah);
        }
    }

    #[test]
    fn a_small_camera_move_keeps_the_shadow_layout() {
        let lights = [
            light(Vec3::new(-0.3, -1.0, -0.2), true),
            light(Vec3::new(0.2, -0.7, 0.6), true),
        ];
        let s = scene(&lights);
        let q = Quality::default();
        let at = |distance: f32| {
            let cam = OrbitCamera {
                distance,
                ..OrbitCamera::default()
            };
            FramePlan::new(&cam, (200, 100), &q, &s, AtomicPath::Key64, LIMITS).expect("fits")
        };
        let layout = |p: &FramePlan| {
            let slots: Vec<_> = p.shadows.iter().map(|m| (m.offset, m.slot_bytes)).collect();
            (slots, p.shadow_key_bytes, p.shadow_attachment)
        };
        let bytes = |p: &FramePlan| p.shadows.iter().map(|m| m.bytes).collect::<Vec<_>>();
        // The maps' texels follow the view: a step back resizes them. Steps that stay within
        // the slots keep every offset, binding and the buffer.
        let mut resized_in_place = 0;
        for step in 0..40 {
            let (a, b) = (at(5.0 + step as f32 * 0.05), at(5.05 + step as f32 * 0.05));
            if bytes(&a) == bytes(&b) {
                continue;
            }
            let largest = |p: &FramePlan| p.shadows.iter().map(|m| m.bytes).max();
            let same_bucket =
                largest(&a).map(u64::next_power_of_two) == largest(&b).map(u64::next_power_of_two);
            assert_eq!(layout(&a) == layout(&b), same_bucket, "step {step}");
            resized_in_place += usize::from(same_bucket);
        }
        assert!(
            resized_in_place > 0,
            "no step resized the maps within their slots"
        );
    }

    #[test]
    fn kept_slots_are_reused_while_they_fit() {
        let lights = [light(Vec3::new(-0.3, -1.0, -0.2), true)];
        let q = Quality::default();
        let fresh = plan(&scene(&lights), &q, AtomicPath::Key64);
        let slot = fresh.shadow_slot.expect("one slotted map");
        let kept = PlanScene {
            kept_shadow_slot: slot * 4,
            ..scene(&lights)
        };
        let p = plan(&kept, &q, AtomicPath::Key64);
        assert_eq!(p.shadow_slot, Some(slot * 4));
        assert_eq!(p.shadows[0].slot_bytes, slot * 4);
        assert_eq!(p.shadows[0].bytes, fresh.shadows[0].bytes);
        // A kept slot over the binding limit is given up for the map's own.
        let huge = PlanScene {
            kept_shadow_slot: LIMITS.binding * 2,
            ..scene(&lights)
        };
        assert_eq!(plan(&huge, &q, AtomicPath::Key64).shadow_slot, Some(slot));
    }

    #[test]
    fn maps_are_packed_when_their_slots_exceed_a_binding() {
        let lights = [
            light(Vec3::new(-0.3, -1.0, -0.2), true),
            light(Vec3::new(0.2, -0.7, 0.6), true),
        ];
        // A scene around the eye: the maps are as large as the quality allows.
        let s = PlanScene {
            bounds: Some((Vec3::splat(-50.0), Vec3::splat(50.0))),
            ..scene(&lights)
        };
        let q = Quality {
            shadow_map_size: 300,
            ..Quality::default()
        };
        let roomy = plan(&s, &q, AtomicPath::Key64);
        let packed_end = {
            let first = &roomy.shadows[0];
            first.bytes.next_multiple_of(256) + roomy.shadows[1].bytes
        };
        let tight = PlanLimits {
            binding: packed_end,
            offset_alignment: 256,
        };
        assert!(
            roomy.shadow_key_bytes > tight.binding,
            "the slots do not fit"
        );
        let p = FramePlan::new(
            &OrbitCamera::default(),
            (200, 100),
            &q,
            &s,
            AtomicPath::Key64,
            tight,
        )
        .expect("packed maps fit");
        for m in &p.shadows {
            assert_eq!(m.slot_bytes, m.bytes);
        }
        assert_eq!(p.shadow_key_bytes, packed_end);
        assert_eq!(p.shadow_slot, None);
    }

    #[test]
    fn no_shadow_maps_without_shadows_casters_or_bounds() {
        let lights = [light(Vec3::NEG_Y, true)];
        let off = Quality {
            shadows: false,
            ..Quality::default()
        };
        let q = Quality::default();
        let no_casters = PlanScene {
            voxel_objects: 0,
            caster_triangles: 0,
            ..scene(&lights)
        };
        let no_bounds = PlanScene {
            bounds: None,
            ..scene(&lights)
        };
        for p in [
            plan(&scene(&lights), &off, AtomicPath::Key64),
            plan(&no_casters, &q, AtomicPath::Key64),
            plan(&no_bounds, &q, AtomicPath::Key64),
        ] {
            assert!(p.shadows.is_empty());
            assert_eq!(p.shadow_key_bytes, 0);
            assert_eq!(
                p.shadow_words, 4,
                "the clear and shade bind at least 16 bytes"
            );
            assert!(!p.passes.shadow_meshes && !p.passes.shadow_voxels);
            assert_eq!(p.shadow_attachment, None);
        }
        // The control: the same scene with shadows on has its map.
        assert_eq!(
            plan(&scene(&lights), &q, AtomicPath::Key64).shadows.len(),
            1
        );
    }

    #[test]
    fn passes_follow_the_path_and_the_scene() {
        let lights = [];
        let s = scene(&lights);
        let q = Quality::default();
        let one = plan(&s, &q, AtomicPath::Key64);
        let two = plan(&s, &q, AtomicPath::TwoPass32);
        assert!(!one.passes.id_pass && two.passes.id_pass);
        assert!(one.passes.meshes && one.passes.voxels);
        assert_eq!(one.passes.hiz, q.occlusion_culling);
        let meshes_only = PlanScene {
            voxel_objects: 0,
            krs: true,
            ..s
        };
        let p = plan(&meshes_only, &q, AtomicPath::Key64);
        assert!(p.passes.meshes && !p.passes.voxels && !p.passes.hiz && p.passes.krs);
    }

    #[test]
    fn buffers_over_a_binding_are_refused() {
        let lights = [light(Vec3::NEG_Y, true)];
        let tiny = PlanLimits {
            binding: 1024,
            offset_alignment: 256,
        };
        let err = FramePlan::new(
            &OrbitCamera::default(),
            (200, 100),
            &Quality::default(),
            &scene(&lights),
            AtomicPath::Key64,
            tiny,
        );
        assert!(
            matches!(
                err,
                Err(GpuError::TooLarge {
                    what: "G-buffer",
                    ..
                })
            ),
            "{err:?}"
        );
        // A view that fits but shadow maps that do not.
        let small = PlanLimits {
            binding: 200 * 100 * GBUFFER_TEXEL_BYTES,
            offset_alignment: 256,
        };
        let big_maps = Quality {
            shadow_map_size: 4096,
            ..Quality::default()
        };
        let around_the_eye = PlanScene {
            bounds: Some((Vec3::splat(-50.0), Vec3::splat(50.0))),
            ..scene(&lights)
        };
        let err = FramePlan::new(
            &OrbitCamera::default(),
            (200, 100),
            &big_maps,
            &around_the_eye,
            AtomicPath::Key64,
            small,
        );
        assert!(
            matches!(
                err,
                Err(GpuError::TooLarge {
                    what: "shadow map",
                    ..
                })
            ),
            "{err:?}"
        );
    }

    #[test]
    fn clear_groups_cover_every_word() {
        assert_eq!(clear_groups(0), (0, 0));
        assert_eq!(clear_groups(256), (1, 1));
        assert_eq!(clear_groups(257), (2, 1));
        let (gx, gy) = clear_groups(65536 * 256);
        assert!(u64::from(gx) * u64::from(gy) * 256 >= 65536 * 256);
        assert!(gx <= 65535);
    }
}

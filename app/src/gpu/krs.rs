//! The KRS pass (KRS paper §4, §6; `shaders/krs_trace.wgsl`): KRS objects packed into storage
//! buffers, a per-pixel sphere tracer that writes the shared G-buffer after the resolve pass
//! (so voxels, meshes and KRS share one depth), and a lighting pass that computes what the
//! CPU's `shade` takes from the KRS: the exact hit point, Algorithm 2 diffuse factors, shadow
//! rays through the KRS from every covered pixel and distance-sampled ambient occlusion.
//!
//! The design mirrors `core::render::krs` step for step (same epsilon rule, sample grid,
//! over-relaxation, bounding interval, §4.1 tile cones, shadow and AO settings), in f32; see
//! `docs/gpu.md` "KRS pass" for the precision argument.

use glam::Vec3;
use thicket_core::krs::{Kernel, KrsScene, Pattern, PreparedScene, SampleGrid, TextureMode};
// The KRS shading constants are the CPU reference's own, so the two cannot drift apart.
use super::passes::{BindGroups, BufferPool, Gpu};
use thicket_core::quality::Quality;
use thicket_core::render::{
    AO_REACH_OBJECT_UNITS, Camera, SMOOTHING_PX, SOFT_SHADOW_K, trace_settings,
};
use thicket_core::scene::{Document, Light, SceneError};

use super::GpuError;
use super::gpu_data::{
    KRS_COUNTERS, KRS_FRAME_SHADOWS, KRS_FRAME_SOFT, KRS_FRAME_TILES, KRS_OBJ_BOUNDED,
    KRS_OBJ_DISTORTED, KRS_OBJ_EMPTY, KrsFrameUniform, KrsKernelGpu, KrsKernelKind, KrsObjectGpu,
    KrsPattern, KrsTextureMode,
};

/// Counters of the KRS pass, read back with the frame's other counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GpuKrsStats {
    /// Primary rays traced (pixels not already covered at the near plane).
    pub rays: u64,
    /// Rays that hit a KRS surface in front of what the pixel held.
    pub hits: u64,
    /// Distance evaluations of primary rays (rejected over-relaxed probes included).
    pub steps: u64,
    /// Most evaluations one primary ray took.
    pub max_steps: u64,
    /// Primary rays that ran out of steps.
    pub exhausted: u64,
    /// Over-relaxed probes taken back.
    pub relaxation_fallbacks: u64,
    /// Evaluations spent by the §4.1 tile cones.
    pub tile_steps: u64,
    /// Shadow rays traced through the KRS.
    pub shadow_rays: u64,
    /// Distance evaluations of those shadow rays.
    pub shadow_steps: u64,
    /// Distance evaluations of the KRS ambient occlusion.
    pub ao_evals: u64,
}

impl GpuKrsStats {
    /// Decodes the KRS words of the counter buffer.
    pub(super) fn from_counters(words: &[u32]) -> Self {
        let base = KRS_COUNTERS as usize;
        let w = |i: usize| u64::from(words.get(base + i).copied().unwrap_or(0));
        let w64 = |i: usize| w(i) | (w(i + 1) << 32);
        Self {
            rays: w(0),
            hits: w(1),
            steps: w64(2),
            max_steps: w(4),
            exhausted: w(5),
            relaxation_fallbacks: w(6),
            tile_steps: w(7),
            shadow_rays: w(8),
            shadow_steps: w64(9),
            ao_evals: w64(11),
        }
    }

    /// Mean distance evaluations per primary ray (0 without rays).
    #[must_use]
    pub fn steps_per_ray(&self) -> f64 {
        if self.rays == 0 {
            0.0
        } else {
            self.steps as f64 / self.rays as f64
        }
    }
}

/// The visible KRS objects of a document in world space, validated and prepared as the CPU
/// reference's `render_document` prepares them (`None` when there are none).
///
/// # Errors
/// [`GpuError::InvalidDocument`] when an object does not validate.
pub fn prepared_krs(doc: &Document) -> Result<Option<PreparedScene>, GpuError> {
    let objects: Vec<_> = doc
        .objects
        .iter()
        .filter(|o| o.visible)
        .filter_map(thicket_core::scene::Object::krs_in_world)
        .collect();
    if objects.is_empty() {
        return Ok(None);
    }
    let scene = KrsScene { objects }.prepare().map_err(|e| {
        GpuError::InvalidDocument(SceneError::Invalid {
            what: "krs".into(),
            context: "document".into(),
            detail: e.to_string(),
        })
    })?;
    Ok(Some(scene).filter(|s| s.objects.iter().any(|o| !o.is_empty)))
}

/// KRS objects flattened for the shader.
#[derive(Debug, Clone, Default)]
pub struct PackedKrs {
    /// One entry per prepared object.
    pub objects: Vec<KrsObjectGpu>,
    /// Every object's kernels, in order.
    pub kernels: Vec<KrsKernelGpu>,
    /// Mirrors (normal, offset), then empty zones (centre, radius); lights are appended per
    /// frame.
    pub vectors: Vec<[f32; 4]>,
    /// Smallest object scale (sets the AO reach).
    pub min_scale: f32,
}

fn v4(v: Vec3, w: f32) -> [f32; 4] {
    v.extend(w).to_array()
}

/// The GPU code of a kernel's variant.
fn kernel_kind(k: &Kernel) -> KrsKernelKind {
    match k {
        Kernel::Empty => KrsKernelKind::Empty,
        Kernel::Sphere(_) => KrsKernelKind::Sphere,
        Kernel::InfinitePlane(_) => KrsKernelKind::Plane,
        Kernel::Capsule(_) => KrsKernelKind::Capsule,
        Kernel::RoundedBox(_) => KrsKernelKind::Box,
        Kernel::TorusSegment(_) => KrsKernelKind::TorusSegment,
        Kernel::ToroidalCapsule(_) => KrsKernelKind::ToroidalCapsule,
    }
}

fn pack_kernel(k: &Kernel) -> KrsKernelGpu {
    let mut out = KrsKernelGpu {
        kind: [kernel_kind(k).code(), 0, 0, 0],
        colour: [0.0; 4],
        params: [[0.0; 4]; 6],
    };
    if let Some(m) = k.material() {
        out.colour = v4(m.colour, 0.0);
    }
    match k {
        Kernel::Empty => {}
        Kernel::Sphere(s) => {
            out.params[0] = v4(s.centre, s.radius);
        }
        Kernel::InfinitePlane(p) => {
            out.params[0] = v4(p.normal, p.offset);
        }
        Kernel::Capsule(c) => {
            out.params[0] = v4(c.start, c.radius);
            out.params[1] = v4(c.end, 0.0);
        }
        Kernel::RoundedBox(b) => {
            out.params[0] = v4(b.centre, b.rounding);
            out.params[1] = b.rotation.inverse().to_array();
            out.params[2] = v4(b.half_extents, 0.0);
            out.params[3] = b.rotation.to_array();
        }
        Kernel::TorusSegment(t) | Kernel::ToroidalCapsule(t) => {
            // The same f32 values the CPU derives (basis, sin/cos of the sweep, end points),
            // so both sides compare the same numbers.
            let (s, c) = t.sweep_radians.sin_cos();
            out.params[0] = v4(t.centre, t.major_radius);
            out.params[1] = v4(t.axis, t.minor_radius);
            out.params[2] = v4(t.start_dir, t.sweep_radians);
            out.params[3] = v4(t.axis.cross(t.start_dir), s);
            out.params[4] = v4(t.end_point(), c);
            out.params[5] = v4(t.start_point(), 0.0);
        }
    }
    out
}

impl PackedKrs {
    /// Flattens a prepared scene.
    #[must_use]
    pub fn pack(scene: &PreparedScene) -> Self {
        let mut out = Self::default();
        let mut zones: Vec<[f32; 4]> = Vec::new();
        let mut zone_owner: Vec<(usize, u32)> = Vec::new();
        for o in &scene.objects {
            let obj = &o.object;
            let t = obj.world_from_object;
            let first_mirror = out.vectors.len() as u32;
            out.vectors
                .extend(obj.mirrors.iter().map(|m| v4(m.normal, m.offset)));
            let first_kernel = out.kernels.len() as u32;
            out.kernels.extend(obj.kernels.iter().map(pack_kernel));
            zone_owner.push((out.objects.len(), zones.len() as u32));
            zones.extend(obj.empty_zones.iter().map(|z| v4(z.centre, z.radius)));
            let mut flags = 0;
            if o.is_empty {
                flags |= KRS_OBJ_EMPTY;
            }
            if obj.distortion.is_some() {
                flags |= KRS_OBJ_DISTORTED;
            }
            let bound = o.bound_world.map_or([0.0; 4], |(c, r)| {
                flags |= KRS_OBJ_BOUNDED;
                v4(c, r)
            });
            let d = obj.distortion.unwrap_or_default();
            let tex = &obj.texturing;
            out.objects.push(KrsObjectGpu {
                inv_rotation: t.rotation.inverse().to_array(),
                rotation: t.rotation.to_array(),
                translation_scale: v4(t.translation, t.scale),
                bound,
                first_mirror,
                mirror_count: obj.mirrors.len() as u32,
                first_kernel,
                first_zone: 0,
                zone_count: obj.empty_zones.len() as u32,
                flags,
                texture_mode: match tex.mode {
                    TextureMode::None => KrsTextureMode::None,
                    TextureMode::Triplanar => KrsTextureMode::Triplanar,
                    TextureMode::KernelParam => KrsTextureMode::KernelParam,
                }
                .code(),
                pattern: match tex.pattern {
                    Pattern::Checker => KrsPattern::Checker,
                    Pattern::Bark => KrsPattern::Bark,
                }
                .code(),
                inv_scale: 1.0 / t.scale,
                lipschitz: o.lipschitz,
                amplitude: d.amplitude,
                frequency: d.frequency,
                seed: d.seed,
                tex_scale: tex.scale,
                tex_contrast: tex.contrast,
                tex_sharpness: tex.sharpness,
            });
        }
        let zone_base = out.vectors.len() as u32;
        for (i, first) in zone_owner {
            out.objects[i].first_zone = zone_base + first;
        }
        out.vectors.extend(zones);
        out.min_scale = scene
            .objects
            .iter()
            .filter(|o| !o.is_empty)
            .map(|o| o.object.world_from_object.scale)
            .fold(f32::INFINITY, f32::min)
            .clamp(1e-30, 1e30);
        out
    }
}

/// The per-frame constants: the CPU's `trace_settings` and `SampleGrid` for this camera,
/// called rather than re-derived (a grid without a cone keeps f32::MAX for ∞: WGSL has no
/// infinity).
fn frame_uniform(
    cam: &Camera,
    quality: &Quality,
    objects: u32,
    lights: &[Light],
    light_base: u32,
    min_scale: f32,
) -> KrsFrameUniform {
    let settings = trace_settings(cam, quality);
    let grid = SampleGrid::new(&settings);
    let (t0, log_step, u0) = if grid.t0.is_finite() {
        (grid.t0 as f32, grid.log_step as f32, grid.u0 as f32)
    } else {
        (f32::MAX, 1.0, f32::MAX)
    };
    let mut flags = 0;
    if quality.krs_tile_acceleration && cam.is_perspective() {
        flags |= KRS_FRAME_TILES;
    }
    if quality.shadows {
        flags |= KRS_FRAME_SHADOWS;
    }
    if quality.krs_soft_shadows {
        flags |= KRS_FRAME_SOFT;
    }
    let ao_samples = quality.ao_samples;
    KrsFrameUniform {
        eps_scale: settings.eps_scale,
        pixel_cone: settings.pixel_cone_ratio,
        min_epsilon: settings.min_epsilon,
        max_steps: settings.max_steps,
        over_relaxation: if settings.over_relaxation.is_finite() {
            settings.over_relaxation
        } else {
            1.0
        },
        grid_q0: grid.q0 as f32,
        grid_t0: t0,
        grid_log_step: log_step,
        grid_u0: u0,
        object_count: objects,
        light_count: lights.len() as u32,
        light_base,
        flags,
        ao_samples,
        ao_spacing: AO_REACH_OBJECT_UNITS * min_scale / ao_samples.max(1) as f32,
        receiver_px: quality.frame_settings().receiver_px,
        stride: 1 + lights.len() as u32,
        smoothing_px: SMOOTHING_PX,
        soft_k: SOFT_SHADOW_K,
        pad: 0,
    }
}

/// Layout, pipelines and bind group of the KRS pass: the pipelines are created once per
/// device, the buffers and the bind group persist across frames (rewritten each frame,
/// recreated only when a size grows; see `passes`).
pub(super) struct KrsPipelines {
    bgl: wgpu::BindGroupLayout,
    trace: wgpu::ComputePipeline,
    light: wgpu::ComputePipeline,
    groups: BindGroups,
}

/// One frame's KRS work: the per-pixel lighting buffer shade.wgsl reads.
pub(super) struct KrsFrame {
    /// `stride` vec4 per pixel (see `krs_trace.wgsl`).
    pub(super) light_buf: wgpu::Buffer,
    /// Entries per pixel.
    pub(super) stride: u32,
    groups: (u32, u32),
}

/// The frame's buffers the KRS pass binds.
pub(super) struct KrsBindings<'a> {
    pub(super) view: &'a wgpu::Buffer,
    pub(super) gbuffer: &'a wgpu::Buffer,
    pub(super) counters: &'a wgpu::Buffer,
}

/// What the KRS pass reads of a frame.
pub(super) struct KrsInputs<'a> {
    /// The document's prepared KRS objects ([`prepared_krs`]).
    pub(super) scene: &'a PreparedScene,
    pub(super) doc: &'a Document,
    pub(super) quality: &'a Quality,
    pub(super) cam: &'a Camera,
    /// The view's size in pixels.
    pub(super) size: (u32, u32),
    pub(super) bindings: KrsBindings<'a>,
}

/// The pass's bind group layouts (one group), checked against `krs_trace.wgsl` by a test.
pub(super) fn bind_group_entries() -> Vec<Vec<wgpu::BindGroupLayoutEntry>> {
    use super::passes::{storage, uniform};
    let cs = wgpu::ShaderStages::COMPUTE;
    vec![vec![
        uniform(0, false, cs),
        uniform(1, false, cs),
        storage(2, true, cs),
        storage(3, true, cs),
        storage(4, true, cs),
        storage(5, false, cs),
        storage(6, false, cs),
        storage(7, false, cs),
    ]]
}

impl KrsPipelines {
    pub(super) fn new(device: &wgpu::Device) -> Result<Self, GpuError> {
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("krs"),
            entries: &bind_group_entries()[0],
        });
        let src = super::shaders::compose("krs_trace.wgsl")?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("krs_trace.wgsl"),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("krs"),
            bind_group_layouts: &[Some(&bgl)],
            immediate_size: 0,
        });
        let pipeline = |entry_point: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry_point),
                layout: Some(&layout),
                module: &module,
                entry_point: Some(entry_point),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                cache: None,
            })
        };
        Ok(Self {
            trace: pipeline("trace"),
            light: pipeline("light"),
            bgl,
            groups: BindGroups::default(),
        })
    }

    /// Packs the document's prepared KRS objects (see [`prepared_krs`]) and writes this
    /// frame's buffers.
    ///
    /// # Errors
    /// [`GpuError::TooLarge`] when the per-pixel lighting buffer exceeds a storage binding.
    pub(super) fn prepare(
        &mut self,
        gpu: Gpu<'_>,
        pool: &mut BufferPool,
        inputs: &KrsInputs<'_>,
    ) -> Result<KrsFrame, GpuError> {
        let (doc, size) = (inputs.doc, inputs.size);
        let mut packed = PackedKrs::pack(inputs.scene);
        let light_base = packed.vectors.len() as u32;
        packed.vectors.extend(doc.lights.iter().map(|l| {
            v4(
                -l.direction.normalize_or_zero(),
                if l.casts_shadows { 1.0 } else { 0.0 },
            )
        }));
        let uniform = frame_uniform(
            inputs.cam,
            inputs.quality,
            packed.objects.len() as u32,
            &doc.lights,
            light_base,
            packed.min_scale,
        );
        let pixels = u64::from(size.0) * u64::from(size.1);
        let light_bytes = pixels * u64::from(uniform.stride) * 16;
        let limit = gpu.device.limits().max_storage_buffer_binding_size;
        if light_bytes > limit {
            return Err(GpuError::TooLarge {
                what: "KRS lighting buffer",
                bytes: light_bytes,
                limit,
            });
        }
        let storage = wgpu::BufferUsages::STORAGE;
        let mut upload = |label: &'static str, data: &[u8], usage: wgpu::BufferUsages| {
            // Empty bindings are not allowed; a zeroed pad is never read (counts are 0).
            pool.upload(gpu, label, 0, data, usage)
        };
        let frame_buf = upload(
            "krs frame",
            bytemuck::bytes_of(&uniform),
            wgpu::BufferUsages::UNIFORM,
        );
        let objects = upload(
            "krs objects",
            bytemuck::cast_slice(&packed.objects),
            storage,
        );
        let kernels = upload(
            "krs kernels",
            bytemuck::cast_slice(&packed.kernels),
            storage,
        );
        let vectors = upload(
            "krs vectors",
            bytemuck::cast_slice(&packed.vectors),
            storage,
        );
        // Every pixel's entries are written by the trace before anything reads them.
        let light_buf = pool.get(gpu, "krs lighting", 0, light_bytes.max(256), storage);
        let b = &inputs.bindings;
        let buffers = [
            b.view, &frame_buf, &objects, &kernels, &vectors, b.gbuffer, &light_buf, b.counters,
        ];
        self.groups.set_buffers(gpu, &self.bgl, "krs", 0, &buffers);
        Ok(KrsFrame {
            light_buf,
            stride: uniform.stride,
            groups: (size.0.div_ceil(8), size.1.div_ceil(8)),
        })
    }

    /// Records the trace pass (after resolve).
    pub(super) fn trace(&self, pass: &mut wgpu::ComputePass<'_>, frame: &KrsFrame) {
        pass.set_pipeline(&self.trace);
        if let Some(bg) = self.groups.get(0) {
            pass.set_bind_group(0, bg, &[]);
        }
        pass.dispatch_workgroups(frame.groups.0, frame.groups.1, 1);
    }

    /// Records the lighting pass (after trace, before shade).
    pub(super) fn light(&self, pass: &mut wgpu::ComputePass<'_>, frame: &KrsFrame) {
        pass.set_pipeline(&self.light);
        if let Some(bg) = self.groups.get(0) {
            pass.set_bind_group(0, bg, &[]);
        }
        pass.dispatch_workgroups(frame.groups.0, frame.groups.1, 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counters_decode_64_bit_sums() {
        let mut words = vec![0u32; 64];
        let b = KRS_COUNTERS as usize;
        words[b] = 10;
        words[b + 2] = 5;
        words[b + 3] = 2;
        words[b + 4] = 77;
        words[b + 11] = 1;
        words[b + 12] = 1;
        let s = GpuKrsStats::from_counters(&words);
        assert_eq!(s.rays, 10);
        assert_eq!(s.steps, 5 + (2 << 32));
        assert_eq!(s.max_steps, 77);
        assert_eq!(s.ao_evals, 1 + (1 << 32));
        assert!((s.steps_per_ray() - s.steps as f64 / 10.0).abs() < 1e-9);
    }

    #[test]
    fn packing_keeps_every_kernel_and_mirror_of_the_tree() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/tree.thicket.json");
        let doc = crate::files::load_document(&path).expect("tree sample loads");
        let scene = prepared_krs(&doc).expect("valid").expect("has KRS");
        let packed = PackedKrs::pack(&scene);
        let mirrors: usize = scene.objects.iter().map(|o| o.object.mirrors.len()).sum();
        let kernels: usize = scene.objects.iter().map(|o| o.object.kernels.len()).sum();
        assert_eq!(packed.objects.len(), scene.objects.len());
        assert_eq!(packed.kernels.len(), kernels);
        let zones: usize = scene
            .objects
            .iter()
            .map(|o| o.object.empty_zones.len())
            .sum();
        assert_eq!(packed.vectors.len(), mirrors + zones);
        assert!(packed.min_scale > 0.0 && packed.min_scale.is_finite());
    }
}

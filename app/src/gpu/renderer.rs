//! The long-lived [`Renderer`] (layouts and pipelines, created once) and one frame's work.

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Instant;

use glam::{Mat4, UVec3, Vec3};
use thicket_core::render::Quality;
use thicket_core::scene::{Document, OrbitCamera};
use wgpu::util::DeviceExt;

use super::scene::{SceneCache, UploadStats};
use super::skin::{SkinCache, SkinFrame};

use super::context::Capabilities;
use super::gpu_data::{
    COUNTER_WORDS, CUBE_PIXEL_COUNTERS, ClearParams, GBUFFER_TEXEL_BYTES, KEY_BYTES, LightGpu,
    MAX_LEVELS, MODE_DEPTH, MODE_ID, MODE_KEY64, NO_SHADOW_MAP, NODE_PARAMS_STRIDE, NodeParams,
    OCCLUSION_TILE, OVERFLOW_COUNTER, QUEUE_ENTRY_BYTES, ResolveChunk, SPLAT_PIXEL_COUNTERS,
    STATS_PER_LEVEL, STATS_START, ShadingUniform, ShadowMapGpu, ViewUniform, ao_kernel,
};
use super::{AtomicPath, GpuError, GpuFrameStats, GpuLevelStats, shaders};

/// An RGBA8 colour target the renderer writes (sRGB-encoded values in an `Rgba8Unorm`
/// texture: display it as already encoded).
pub struct RenderTarget {
    /// The texture (`STORAGE_BINDING | COPY_SRC | TEXTURE_BINDING`).
    pub texture: wgpu::Texture,
    /// A view of it.
    pub view: wgpu::TextureView,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl RenderTarget {
    /// A target of `width × height` pixels.
    ///
    /// # Errors
    /// [`GpuError::BadSize`] for a zero size or one above the device's texture limit.
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> Result<Self, GpuError> {
        let max = device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(GpuError::BadSize { width, height, max });
        }
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("thicket target"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        Ok(Self {
            texture,
            view,
            width,
            height,
        })
    }
}

/// The last frame's G-buffer, read back (tests, parity checks, picking).
#[derive(Debug, Clone, PartialEq)]
pub struct GBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// NDC depth per pixel (0 near, 1 far); `INFINITY` where nothing was drawn.
    pub depth: Vec<f32>,
    /// World normal per pixel (zero where empty).
    pub normal: Vec<Vec3>,
    /// Linear albedo per pixel (zero where empty).
    pub albedo: Vec<Vec3>,
}

/// Reads an [`RenderTarget`] back as tightly packed RGBA8 rows, top row first.
///
/// # Errors
/// [`GpuError::Readback`] when mapping fails.
pub fn read_rgba8(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    target: &RenderTarget,
) -> Result<Vec<u8>, GpuError> {
    let row = target.width * 4;
    let padded =
        row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let size = u64::from(padded) * u64::from(target.height);
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("thicket readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    enc.copy_texture_to_buffer(
        target.texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &staging,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(target.height),
            },
        },
        wgpu::Extent3d {
            width: target.width,
            height: target.height,
            depth_or_array_layers: 1,
        },
    );
    queue.submit([enc.finish()]);
    let bytes = map_read(device, &staging)?;
    let mut out = Vec::with_capacity((row * target.height) as usize);
    for y in 0..target.height as usize {
        let start = y * padded as usize;
        out.extend_from_slice(&bytes[start..start + row as usize]);
    }
    Ok(out)
}

/// Maps a `MAP_READ` buffer, waits, copies its bytes out and unmaps it.
pub(super) fn map_read(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        // The receiver only disappears if this function already returned an error.
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    rx.recv()
        .map_err(|e| GpuError::Readback(e.to_string()))?
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    let bytes = slice
        .get_mapped_range()
        .map_err(|e| GpuError::Readback(e.to_string()))?
        .to_vec();
    buffer.unmap();
    Ok(bytes)
}

/// A camera as the passes see it.
#[derive(Clone, Copy)]
struct ViewSpec {
    view_from_world: Mat4,
    clip_from_view: Mat4,
    width: u32,
    height: u32,
    perspective: bool,
    fx: f32,
    fy: f32,
    near: f32,
    far: f32,
}

impl ViewSpec {
    /// The passes' view of a CPU reference camera (perspective or orthographic), so both
    /// renderers project with the same numbers.
    fn from_camera(cam: &thicket_core::render::Camera) -> Self {
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
    fn fit_light_bound(
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

    fn uniform(&self, write_mode: u32, quality: &Quality, occlusion: bool) -> ViewUniform {
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

/// Layouts and pipelines, created once per device.
pub struct Renderer {
    caps: Capabilities,
    force_two_pass: bool,
    trav_bgl: [wgpu::BindGroupLayout; 3],
    indirect_bgl: wgpu::BindGroupLayout,
    clear_bgl: wgpu::BindGroupLayout,
    mesh_bgl: wgpu::BindGroupLayout,
    resolve_bgl: wgpu::BindGroupLayout,
    shade_bgl: wgpu::BindGroupLayout,
    hiz_bgl: wgpu::BindGroupLayout,
    hiz: wgpu::ComputePipeline,
    seed: wgpu::ComputePipeline,
    prepare: wgpu::ComputePipeline,
    traverse32: wgpu::ComputePipeline,
    traverse64: Option<wgpu::ComputePipeline>,
    clear: wgpu::ComputePipeline,
    mesh32: wgpu::RenderPipeline,
    mesh64: Option<wgpu::RenderPipeline>,
    resolve: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
    /// The KRS pass (trace and lighting), built with the first frame that has KRS objects (its
    /// shader is the largest; frames without KRS never pay for compiling it).
    krs: Option<super::krs::KrsPipelines>,
    /// Per-frame buffers, reused while large enough.
    buffers: HashMap<&'static str, wgpu::Buffer>,
    /// Dummy depth attachments for the mesh passes (the atomics do the depth test).
    attachments: HashMap<(u32, u32), wgpu::Texture>,
    last_size: (u32, u32),
    /// The scene on the GPU (`None` until the first upload).
    scene: Option<SceneCache>,
    /// Counters and timestamps read back through a ring of staging buffers.
    readback: ReadbackRing,
    /// When set, `render` returns without waiting for the frame's counters.
    async_readback: bool,
    /// Frames submitted so far.
    frame_index: u64,
    /// Rigged objects' skin data and joint matrices.
    skin: SkinCache,
    /// Repeats of the splat-bandwidth measurement the next frame runs (see
    /// [`Renderer::measure_splat_bandwidth`]), and its result.
    splat_probe: Option<u32>,
    splat_probe_result: Option<Result<super::splat_bw::SplatBandwidth, GpuError>>,
}

fn storage(
    binding: u32,
    read_only: bool,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn uniform(
    binding: u32,
    dynamic: bool,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: dynamic,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind group of whole buffers at bindings 0, 1, 2, … in order.
pub(super) fn bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    label: &str,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry<'_>> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// Which pass a timestamp pair measures.
struct Timed {
    name: &'static str,
    first_query: u32,
}

/// A render pass with only a depth attachment, cleared and discarded: the mesh passes write
/// their depth into the key buffer with atomics, the attachment only gives them a target.
fn depth_only_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    ts: &mut Option<Timestamps>,
    name: &'static str,
    attachment: &wgpu::TextureView,
) -> wgpu::RenderPass<'e> {
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(name),
        color_attachments: &[],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: attachment,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: wgpu::StoreOp::Discard,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: ts.as_mut().and_then(|t| t.render(name)),
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// Timestamp bookkeeping for one frame.
struct Timestamps {
    set: wgpu::QuerySet,
    used: Vec<Timed>,
}

const MAX_TIMED_PASSES: u32 = 16;

impl Timestamps {
    fn compute<'a>(
        &'a mut self,
        name: &'static str,
    ) -> Option<wgpu::ComputePassTimestampWrites<'a>> {
        let q = self.used.len() as u32 * 2;
        if q / 2 >= MAX_TIMED_PASSES {
            return None;
        }
        self.used.push(Timed {
            name,
            first_query: q,
        });
        Some(wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(q),
            end_of_pass_write_index: Some(q + 1),
        })
    }

    fn render<'a>(&'a mut self, name: &'static str) -> Option<wgpu::RenderPassTimestampWrites<'a>> {
        let q = self.used.len() as u32 * 2;
        if q / 2 >= MAX_TIMED_PASSES {
            return None;
        }
        self.used.push(Timed {
            name,
            first_query: q,
        });
        Some(wgpu::RenderPassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(q),
            end_of_pass_write_index: Some(q + 1),
        })
    }
}

/// One traversal to encode: an object seen from a view.
struct Traversal {
    first_slot: u32,
    depth: u8,
    /// The pool chunk holding the object (selects the group-0 bind group).
    chunk: usize,
}

/// One light's shadow map this frame.
struct ShadowPlan {
    /// Index of the light in the document.
    light: usize,
    /// Its camera (the CPU's `fit_light_camera`).
    view: ViewSpec,
    /// Where its keys start in the shadow key buffer (a multiple of the device's storage
    /// offset alignment, so its passes can bind just this range).
    offset: u64,
    /// Bytes of its keys.
    bytes: u64,
}

impl Renderer {
    /// Creates every layout and pipeline. The 64-bit splat pipelines exist only when the
    /// device has `SHADER_INT64_ATOMIC_MIN_MAX`.
    ///
    /// # Errors
    /// [`GpuError::Shader`] when an embedded shader's imports are broken; pipeline creation
    /// errors surface through the device's error handler.
    pub fn new(device: &wgpu::Device, _queue: &wgpu::Queue) -> Result<Self, GpuError> {
        let caps = Capabilities::of(device);
        let cs = wgpu::ShaderStages::COMPUTE;
        let module = |path: &str| -> Result<wgpu::ShaderModule, GpuError> {
            let src = shaders::compose(path)?;
            Ok(device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(path),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            }))
        };
        let bgl = |label: &str, entries: &[wgpu::BindGroupLayoutEntry]| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
        };
        let trav_bgl = [
            bgl(
                "traverse 0",
                &[
                    uniform(0, false, cs),
                    storage(1, false, cs),
                    storage(2, true, cs),
                    storage(4, false, cs),
                    storage(5, true, cs),
                    // Skin data and joint matrices (gpu/skin.rs).
                    storage(6, true, cs),
                    storage(7, true, cs),
                ],
            ),
            bgl("traverse 1", &[uniform(0, true, cs)]),
            bgl("traverse 2", &[storage(0, true, cs), storage(1, false, cs)]),
        ];
        let indirect_bgl = bgl("indirect", &[storage(0, false, cs)]);
        let hiz_bgl = bgl(
            "hiz",
            &[
                uniform(0, false, cs),
                storage(1, true, cs),
                storage(2, false, cs),
            ],
        );
        let clear_bgl = bgl("clear", &[uniform(0, false, cs), storage(1, false, cs)]);
        let vf = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let mesh_bgl = bgl(
            "mesh",
            &[
                uniform(0, false, vf),
                storage(1, true, wgpu::ShaderStages::VERTEX),
                storage(2, false, wgpu::ShaderStages::FRAGMENT),
            ],
        );
        let resolve_bgl = bgl(
            "resolve",
            &[
                uniform(0, false, cs),
                storage(1, true, cs),
                storage(2, true, cs),
                storage(3, true, cs),
                storage(4, true, cs),
                storage(5, false, cs),
                storage(6, true, cs),
                storage(7, true, cs),
                storage(8, true, cs),
                uniform(9, false, cs),
            ],
        );
        let shade_bgl = bgl(
            "shade",
            &[
                uniform(0, false, cs),
                // The shadow maps (`ShadowMapGpu`, one per shadow-casting light).
                storage(1, true, cs),
                uniform(2, false, cs),
                storage(3, true, cs),
                storage(4, true, cs),
                storage(5, true, cs),
                wgpu::BindGroupLayoutEntry {
                    binding: 6,
                    visibility: cs,
                    ty: wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: wgpu::TextureFormat::Rgba8Unorm,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                    count: None,
                },
                storage(7, true, cs),
            ],
        );
        let layout = |label: &str, groups: &[&wgpu::BindGroupLayout]| {
            let groups: Vec<Option<&wgpu::BindGroupLayout>> =
                groups.iter().map(|g| Some(*g)).collect();
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &groups,
                immediate_size: 0,
            })
        };
        let compute = |label: &str,
                       layout: &wgpu::PipelineLayout,
                       module: &wgpu::ShaderModule,
                       entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: Some(layout),
                module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                cache: None,
            })
        };
        let trav_layout = layout("traverse", &[&trav_bgl[0], &trav_bgl[1], &trav_bgl[2]]);
        let queue_mod = module("asvo_queue.wgsl")?;
        let queue_layout = layout(
            "traverse queue",
            &[&trav_bgl[0], &trav_bgl[1], &trav_bgl[2], &indirect_bgl],
        );
        let seed = compute("seed", &queue_layout, &queue_mod, "seed");
        let prepare = compute("prepare", &queue_layout, &queue_mod, "prepare_indirect");
        let traverse32 = compute(
            "traverse32",
            &trav_layout,
            &module("asvo_splat32.wgsl")?,
            "traverse",
        );
        let traverse64 = if caps.int64_atomics {
            Some(compute(
                "traverse64",
                &trav_layout,
                &module("asvo_splat64.wgsl")?,
                "traverse",
            ))
        } else {
            None
        };
        let hiz = compute(
            "hiz",
            &layout("hiz", &[&hiz_bgl]),
            &module("hiz.wgsl")?,
            "build_tiles",
        );
        let clear = compute(
            "clear",
            &layout("clear", &[&clear_bgl]),
            &module("clear.wgsl")?,
            "clear",
        );
        let resolve = compute(
            "resolve",
            &layout("resolve", &[&resolve_bgl]),
            &module("resolve.wgsl")?,
            "resolve",
        );
        let shade = compute(
            "shade",
            &layout("shade", &[&shade_bgl]),
            &module("shade.wgsl")?,
            "shade",
        );
        let mesh_layout = layout("mesh", &[&mesh_bgl]);
        let mesh_pipeline = |label: &str, m: &wgpu::ShaderModule| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&mesh_layout),
                vertex: wgpu::VertexState {
                    module: m,
                    entry_point: Some("vs_main"),
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState {
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: wgpu::TextureFormat::Depth32Float,
                    depth_write_enabled: Some(false),
                    depth_compare: Some(wgpu::CompareFunction::Always),
                    stencil: wgpu::StencilState::default(),
                    bias: wgpu::DepthBiasState::default(),
                }),
                multisample: wgpu::MultisampleState::default(),
                fragment: Some(wgpu::FragmentState {
                    module: m,
                    entry_point: Some("fs_main"),
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                    targets: &[],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let mesh32 = mesh_pipeline("mesh32", &module("mesh32.wgsl")?);
        let mesh64 = if caps.int64_atomics {
            Some(mesh_pipeline("mesh64", &module("mesh64.wgsl")?))
        } else {
            None
        };
        Ok(Self {
            caps,
            force_two_pass: false,
            trav_bgl,
            indirect_bgl,
            clear_bgl,
            mesh_bgl,
            resolve_bgl,
            shade_bgl,
            hiz_bgl,
            hiz,
            seed,
            prepare,
            traverse32,
            traverse64,
            clear,
            mesh32,
            mesh64,
            resolve,
            shade,
            krs: None,
            buffers: HashMap::new(),
            attachments: HashMap::new(),
            last_size: (0, 0),
            scene: None,
            readback: ReadbackRing::default(),
            async_readback: false,
            frame_index: 0,
            skin: SkinCache::default(),
            splat_probe: None,
            splat_probe_result: None,
        })
    }

    /// What the device offers.
    #[must_use]
    pub fn capabilities(&self) -> Capabilities {
        self.caps
    }

    /// Forces the two-pass 32-bit splat path even when 64-bit atomics exist (tests, A/B).
    pub fn set_force_two_pass(&mut self, force: bool) {
        self.force_two_pass = force;
    }

    /// The splat path the next frame uses.
    #[must_use]
    pub fn atomic_path(&self) -> AtomicPath {
        if self.traverse64.is_some() && !self.force_two_pass {
            AtomicPath::Key64
        } else {
            AtomicPath::TwoPass32
        }
    }

    /// A buffer of at least `size` bytes under `name`, reused across frames.
    fn buffer(
        &mut self,
        device: &wgpu::Device,
        name: &'static str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let size = size.max(16).next_multiple_of(16);
        if let Some(b) = self.buffers.get(name)
            && b.size() >= size
            && b.usage().contains(usage)
        {
            return b.clone();
        }
        let b = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(name),
            size,
            usage,
            mapped_at_creation: false,
        });
        self.buffers.insert(name, b.clone());
        b
    }

    fn attachment(&mut self, device: &wgpu::Device, w: u32, h: u32) -> wgpu::TextureView {
        self.attachments
            .entry((w, h))
            .or_insert_with(|| {
                device.create_texture(&wgpu::TextureDescriptor {
                    label: Some("mesh pass attachment"),
                    size: wgpu::Extent3d {
                        width: w,
                        height: h,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: wgpu::TextureFormat::Depth32Float,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                })
            })
            .create_view(&wgpu::TextureViewDescriptor::default())
    }

    /// Renders `doc` from `camera` into `target`. Uploads the whole scene first (any change to
    /// the document shows); an editor that knows what changed uploads with
    /// [`Renderer::update_voxel_region`] and draws with [`Renderer::render_uploaded`].
    ///
    /// Waits for the GPU and returns this frame's counters (and timestamps when the device has
    /// them), unless [`Renderer::set_async_readback`] is on.
    ///
    /// # Errors
    /// [`GpuError`] for an invalid document, camera or quality, scene data over the device's
    /// binding limit, or a validation / out-of-memory error raised while encoding the frame.
    #[allow(
        clippy::too_many_arguments,
        reason = "the frame's inputs: device, queue, scene, view, knobs, target"
    )]
    pub fn render(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        camera: &OrbitCamera,
        quality: &Quality,
        target: &RenderTarget,
    ) -> Result<GpuFrameStats, GpuError> {
        self.frame(device, queue, doc, camera, quality, target, true)
    }

    /// Renders with the scene as last uploaded: only transforms, lights and camera are read
    /// from `doc` each frame, plus what can be seen without an edit region (objects added,
    /// removed or hidden, or a pool that changed length, cause an upload of what changed). A
    /// voxel edit that keeps the pool lengths must be announced with
    /// [`Renderer::update_voxel_region`] first, or the frame shows the old voxels.
    ///
    /// # Errors
    /// As [`Renderer::render`].
    #[allow(
        clippy::too_many_arguments,
        reason = "the frame's inputs: device, queue, scene, view, knobs, target"
    )]
    pub fn render_uploaded(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        camera: &OrbitCamera,
        quality: &Quality,
        target: &RenderTarget,
    ) -> Result<GpuFrameStats, GpuError> {
        self.frame(device, queue, doc, camera, quality, target, false)
    }

    /// Packs and uploads the whole scene.
    ///
    /// # Errors
    /// [`GpuError::InvalidDocument`], [`GpuError::TooLarge`], or an error raised by the device.
    pub fn upload_document(
        &mut self,
        device: &wgpu::Device,
        doc: &Document,
    ) -> Result<UploadStats, GpuError> {
        doc.validate()?;
        let scene = SceneCache::build(device, doc, &device.limits())?;
        let stats = UploadStats {
            full: true,
            bytes: scene.bytes(),
            writes: scene.buffer_count(),
            ..UploadStats::default()
        };
        self.scene = Some(scene);
        self.skin.invalidate();
        Ok(stats)
    }

    /// How many chunks the uploaded scene's voxel pools are split into (each chunk's buffers
    /// fit one storage binding; 0 before the first upload).
    #[must_use]
    pub fn pool_chunks(&self) -> usize {
        self.scene.as_ref().map_or(0, |s| s.chunks.len())
    }

    /// After an edit of voxel object `object_id` inside the inclusive box `lo..=hi` (voxel
    /// coordinates, e.g. a sculpt's changed region): uploads only the node ranges the edit can
    /// have changed. When the object's pools outgrew the room reserved for them, the pools get
    /// larger buffers filled from the old ones on the GPU first ([`UploadStats::grown`]), so
    /// the upload is still only the region. Falls back to a full upload when nothing is
    /// uploaded yet, the scene's objects changed, or grown pools exceed a binding. An empty box
    /// (`lo > hi` on some axis: an edit that changed no voxel, such as a rig's pose) uploads
    /// nothing; frames read rigs themselves.
    ///
    /// # Errors
    /// As [`Renderer::upload_document`].
    pub fn update_voxel_region(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        object_id: u64,
        lo: UVec3,
        hi: UVec3,
    ) -> Result<UploadStats, GpuError> {
        if let Some(s) = self
            .scene
            .as_mut()
            .and_then(|s| s.update_voxel_region(device, queue, doc, object_id, lo, hi))
        {
            return Ok(s);
        }
        self.upload_document(device, doc)
    }

    /// With `on`, [`Renderer::render`] returns as soon as the frame is submitted: its
    /// statistics carry the newest counters that have arrived (from an earlier frame, see
    /// [`GpuFrameStats::counters_frame`]), read through a ring of staging buffers mapped with
    /// `map_async`, so the GPU never waits for the CPU. Off (the default) waits for each frame.
    pub fn set_async_readback(&mut self, on: bool) {
        self.async_readback = on;
    }

    /// The newest frame statistics that have arrived, after a non-blocking device poll (for a
    /// perf overlay between frames).
    ///
    /// # Errors
    /// [`GpuError::Readback`] when polling the device fails.
    pub fn poll_counters(
        &mut self,
        device: &wgpu::Device,
    ) -> Result<Option<GpuFrameStats>, GpuError> {
        device
            .poll(wgpu::PollType::Poll)
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        self.readback.collect();
        Ok(self.readback.latest.clone())
    }

    #[allow(
        clippy::too_many_arguments,
        reason = "render's inputs plus whether to upload the whole scene"
    )]
    fn frame(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        camera: &OrbitCamera,
        quality: &Quality,
        target: &RenderTarget,
        full_upload: bool,
    ) -> Result<GpuFrameStats, GpuError> {
        doc.validate()?;
        camera.validate()?;
        quality.validate()?;
        let t_start = Instant::now();
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let result: Result<GpuFrameStats, GpuError> = (|| {
            let refreshed = if full_upload {
                None
            } else {
                self.scene
                    .as_mut()
                    .and_then(|s| s.refresh(device, queue, doc))
            };
            let mut upload = match refreshed {
                Some(u) => u,
                None => self.upload_document(device, doc)?,
            };
            let scene = self
                .scene
                .as_mut()
                .ok_or_else(|| GpuError::Device("no scene uploaded".into()))?;
            let skin = self.skin.prepare(device, queue, doc, scene, quality)?;
            upload.bytes += skin.upload.bytes;
            upload.writes += skin.upload.writes;
            upload.joint_bytes += skin.upload.joint_bytes;
            upload.skin_data |= skin.upload.skin_data;
            let mut stats =
                self.encode_and_run(device, queue, doc, camera, quality, target, &skin)?;
            stats.upload = upload;
            Ok(stats)
        })();
        let oom_err = pollster::block_on(oom.pop());
        let val_err = pollster::block_on(validation.pop());
        if let Some(e) = oom_err {
            return Err(GpuError::OutOfMemory(e.to_string()));
        }
        if let Some(e) = val_err {
            return Err(GpuError::Device(e.to_string()));
        }
        let mut stats = result?;
        stats.total_ms = t_start.elapsed().as_secs_f64() * 1e3;
        self.last_size = (target.width, target.height);
        Ok(stats)
    }

    /// Renders one frame as [`Renderer::render_uploaded`] does and, before it, measures the
    /// bandwidth of its view's voxel pass against a same-size buffer copy, `repeats` times
    /// each (see [`super::splat_bw`] for the byte accounting and the timing). Returns the
    /// frame's statistics and the measurement, whose counters equal the frame's.
    ///
    /// # Errors
    /// As [`Renderer::render`]; [`GpuError::Device`] on the two-pass 32-bit path or with
    /// asynchronous readback (the measurement needs the 64-bit splat and waited counters).
    #[allow(
        clippy::too_many_arguments,
        reason = "the frame's inputs plus the repeat count"
    )]
    pub fn measure_splat_bandwidth(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        camera: &OrbitCamera,
        quality: &Quality,
        target: &RenderTarget,
        repeats: u32,
    ) -> Result<(GpuFrameStats, super::splat_bw::SplatBandwidth), GpuError> {
        if self.atomic_path() != AtomicPath::Key64 || self.async_readback {
            return Err(GpuError::Device(
                "the splat bandwidth is measured on the 64-bit splat path with waited counters \
                 only"
                    .into(),
            ));
        }
        self.splat_probe = Some(repeats);
        self.splat_probe_result = None;
        let stats = self.frame(device, queue, doc, camera, quality, target, false);
        self.splat_probe = None;
        let measured = self.splat_probe_result.take();
        let stats = stats?;
        let measured = measured.ok_or_else(|| {
            GpuError::Device("the frame ended before its voxel pass was measured".into())
        })??;
        Ok((stats, measured))
    }

    /// Reads the last frame's G-buffer back.
    ///
    /// # Errors
    /// [`GpuError::Readback`] when nothing was rendered yet or mapping fails.
    pub fn read_gbuffer(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<GBuffer, GpuError> {
        let (w, h) = self.last_size;
        let gbuf = self
            .buffers
            .get("gbuffer")
            .cloned()
            .filter(|_| w > 0)
            .ok_or_else(|| GpuError::Readback("no frame rendered yet".into()))?;
        let bytes = u64::from(w) * u64::from(h) * GBUFFER_TEXEL_BYTES;
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("gbuffer readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        enc.copy_buffer_to_buffer(&gbuf, 0, &staging, 0, bytes);
        queue.submit([enc.finish()]);
        let raw = map_read(device, &staging)?;
        let texels: &[[u32; 4]] = bytemuck::cast_slice(&raw);
        let unorm = |bits: u32| -> [f32; 2] {
            [
                f32::from((bits & 0xffff) as u16) / 65535.0,
                f32::from((bits >> 16) as u16) / 65535.0,
            ]
        };
        let snorm = |bits: u32| -> [f32; 2] {
            let s = |b: u16| (f32::from(b as i16) / 32767.0).max(-1.0);
            [s((bits & 0xffff) as u16), s((bits >> 16) as u16)]
        };
        let mut g = GBuffer {
            width: w,
            height: h,
            depth: Vec::with_capacity(texels.len()),
            normal: Vec::with_capacity(texels.len()),
            albedo: Vec::with_capacity(texels.len()),
        };
        for t in texels {
            if t[3] == u32::MAX {
                g.depth.push(f32::INFINITY);
                g.normal.push(Vec3::ZERO);
                g.albedo.push(Vec3::ZERO);
                continue;
            }
            let [r, gr] = unorm(t[0]);
            let [b, nz] = unorm(t[1]);
            let [nx, ny] = snorm(t[2]);
            g.depth.push(f32::from_bits(t[3]));
            g.normal.push(Vec3::new(nx, ny, nz * 2.0 - 1.0));
            g.albedo.push(Vec3::new(r, gr, b));
        }
        Ok(g)
    }

    #[allow(
        clippy::too_many_lines,
        reason = "one frame's encoding, in pass order; splitting it would scatter the ordering"
    )]
    #[allow(
        clippy::too_many_arguments,
        reason = "render's inputs plus the frame's skinning data"
    )]
    fn encode_and_run(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        camera: &OrbitCamera,
        quality: &Quality,
        target: &RenderTarget,
        skin: &SkinFrame,
    ) -> Result<GpuFrameStats, GpuError> {
        use wgpu::BufferUsages as U;
        let probe = self.splat_probe.take();
        let limits = device.limits();
        let scene = self
            .scene
            .as_ref()
            .ok_or_else(|| GpuError::Device("no scene uploaded".into()))?;
        let mut frame_objects = scene.frame_objects(doc);
        skin.apply(scene, &mut frame_objects);
        let (tri_buf, texture_buf) = (scene.tri_buf.clone(), scene.texture_buf.clone());
        // Per pool chunk: (inner nodes, attributes, skin data, resolve range).
        let chunks: Vec<(wgpu::Buffer, wgpu::Buffer, wgpu::Buffer, ResolveChunk)> = scene
            .chunks
            .iter()
            .zip(&skin.data_bufs)
            .enumerate()
            .map(|(i, (c, skin_data))| {
                (
                    c.inner_buf.clone(),
                    c.attr_buf.clone(),
                    skin_data.clone(),
                    ResolveChunk {
                        attr_start: c.attr_start,
                        attr_end: c.attr_end,
                        others: u32::from(i == 0),
                        pad: 0,
                    },
                )
            })
            .collect();
        if chunks.len() != scene.chunks.len() {
            return Err(GpuError::Device(
                "skin data does not follow the pool chunks".into(),
            ));
        }
        let (caster_tris, tri_count, cap) =
            (scene.caster_tris, scene.tri_count, scene.queue_capacity);
        let voxel_entries: Vec<(Mat4, u8, u32, u32, u32, usize)> = scene
            .voxels
            .iter()
            .zip(&frame_objects.world_from_voxel)
            .map(|(e, &m)| {
                (
                    m,
                    e.depth,
                    e.inner_base,
                    e.attr_inner_base,
                    e.attr_leaf_base,
                    e.chunk,
                )
            })
            .collect();
        let (w, h) = (target.width, target.height);
        let main_camera = thicket_core::render::Camera::from_orbit(camera, w, h);
        let main = ViewSpec::from_camera(&main_camera);
        let path = self.atomic_path();

        // Shadow cameras: one per shadow-casting light, as the CPU's `render_scene` (none with
        // shadows off, nothing that casts, or nothing drawn), each fit to everything drawn.
        let has_casters = !scene.voxels.is_empty() || caster_tris > 0;
        let mut shadows: Vec<ShadowPlan> = Vec::new();
        if let Some((lo, hi)) = frame_objects.bounds
            && quality.shadows
            && has_casters
            && lo.is_finite()
            && hi.is_finite()
        {
            // The CPU's choice, called rather than copied (one view pixel where the scene
            // comes nearest the eye; an orthographic view's pixel).
            let finest = thicket_core::render::finest_shadow_texel(&main_camera, lo, hi);
            // Every map in one key buffer, each at an offset its passes can bind its range at.
            let align = u64::from(limits.min_storage_buffer_offset_alignment.max(4));
            let mut next = 0u64;
            for (light, l) in doc.lights.iter().enumerate() {
                if !l.casts_shadows {
                    continue;
                }
                let Some(view) =
                    ViewSpec::fit_light_bound(l.direction, lo, hi, quality.shadow_map_size, finest)
                else {
                    continue;
                };
                let offset = next.next_multiple_of(align);
                let bytes = u64::from(view.width) * u64::from(view.height) * KEY_BYTES;
                next = offset + bytes;
                shadows.push(ShadowPlan {
                    light,
                    view,
                    offset,
                    bytes,
                });
            }
        }

        let pixels = u64::from(w) * u64::from(h);
        let key_bytes = pixels * KEY_BYTES;
        let binding_limit = limits.max_storage_buffer_binding_size;
        if key_bytes > binding_limit || pixels * GBUFFER_TEXEL_BYTES > binding_limit {
            return Err(GpuError::TooLarge {
                what: "G-buffer",
                bytes: pixels * GBUFFER_TEXEL_BYTES,
                limit: binding_limit,
            });
        }
        // The shade pass binds every map at once, so they must fit one binding together.
        let shadow_key_bytes = shadows.last().map_or(0, |m| m.offset + m.bytes);
        if shadow_key_bytes > binding_limit {
            return Err(GpuError::TooLarge {
                what: if shadows.len() == 1 {
                    "shadow map"
                } else {
                    "shadow maps (one per shadow-casting light, bound together)"
                },
                bytes: shadow_key_bytes,
                limit: binding_limit,
            });
        }

        // Scene buffers.
        let upload = |name: &str, data: &[u8], usage: U| {
            let contents: Vec<u8> = if data.is_empty() {
                vec![0; 256]
            } else {
                data.to_vec()
            };
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(name),
                contents: &contents,
                usage,
            })
        };
        let object_buf = upload(
            "objects",
            bytemuck::cast_slice(&frame_objects.objects),
            U::STORAGE,
        );
        let lights: Vec<LightGpu> = doc
            .lights
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let c = l.color * l.intensity;
                LightGpu {
                    to_light: (-l.direction.normalize_or_zero()).to_array(),
                    shadow_map: shadows
                        .iter()
                        .position(|m| m.light == i)
                        .map_or(NO_SHADOW_MAP, |m| m as u32),
                    color: c.extend(0.0).to_array(),
                }
            })
            .collect();
        let light_buf = upload("lights", bytemuck::cast_slice(&lights), U::STORAGE);

        // Frame buffers.
        let keys_main = self.buffer(device, "keys", key_bytes, U::STORAGE);
        let keys_shadow = self.buffer(device, "shadow keys", shadow_key_bytes, U::STORAGE);
        // The whole buffer may be larger (reused from a larger frame): clear and bind only
        // what the maps use.
        let shadow_words = shadow_key_bytes.max(16) / 4;
        let tiles = self.buffer(
            device,
            "occlusion tiles",
            u64::from(w.div_ceil(OCCLUSION_TILE)) * u64::from(h.div_ceil(OCCLUSION_TILE)) * 4,
            U::STORAGE,
        );
        let gbuffer = self.buffer(
            device,
            "gbuffer",
            pixels * GBUFFER_TEXEL_BYTES,
            U::STORAGE | U::COPY_SRC,
        );
        let counters = self.buffer(
            device,
            "counters",
            u64::from(COUNTER_WORDS) * 4,
            U::STORAGE | U::COPY_SRC | U::COPY_DST,
        );
        let indirect = self.buffer(
            device,
            "indirect",
            u64::from(MAX_LEVELS) * 12,
            U::STORAGE | U::INDIRECT,
        );
        let queue_a = self.buffer(device, "queue a", cap * QUEUE_ENTRY_BYTES, U::STORAGE);
        let queue_b = self.buffer(device, "queue b", cap * QUEUE_ENTRY_BYTES, U::STORAGE);

        // Uniforms: views and per-dispatch node parameters.
        let first_mode = if path == AtomicPath::Key64 {
            MODE_KEY64
        } else {
            MODE_DEPTH
        };
        let view_main = upload(
            "view",
            bytemuck::bytes_of(&main.uniform(first_mode, quality, quality.occlusion_culling)),
            U::UNIFORM,
        );
        let view_main_id = upload(
            "view id pass",
            // The id pass must visit every node the depth pass drew: no culling there.
            bytemuck::bytes_of(&main.uniform(MODE_ID, quality, false)),
            U::UNIFORM,
        );
        let shadow_uniforms: Vec<ViewUniform> = shadows
            .iter()
            .map(|m| m.view.uniform(MODE_DEPTH, quality, false))
            .collect();
        let shadow_views: Vec<wgpu::Buffer> = shadow_uniforms
            .iter()
            .map(|u| upload("shadow view", bytemuck::bytes_of(u), U::UNIFORM))
            .collect();
        let shadow_maps: Vec<ShadowMapGpu> = shadows
            .iter()
            .zip(&shadow_uniforms)
            .map(|(m, &view)| ShadowMapGpu {
                view,
                // Below the binding limit (checked above), so the word index fits.
                key_word_offset: (m.offset / 4) as u32,
                pad: [0; 3],
            })
            .collect();
        let shadow_map_buf = upload(
            "shadow maps",
            bytemuck::cast_slice(&shadow_maps),
            U::STORAGE,
        );
        let mut slots: Vec<u8> = Vec::new();
        let mut make_traversals = |spec: &ViewSpec, stats_base: u32| -> Vec<Traversal> {
            voxel_entries
                .iter()
                .zip(&skin.params)
                .map(
                    |(
                        &(
                            world_from_voxel,
                            depth,
                            inner_base,
                            attr_inner_base,
                            attr_leaf_base,
                            chunk,
                        ),
                        &skin_params,
                    )| {
                        let first_slot = (slots.len() as u64 / NODE_PARAMS_STRIDE) as u32;
                        let base = NodeParams::for_object(
                            spec.view_from_world * world_from_voxel,
                            world_from_voxel,
                        );
                        for level in 0..=u32::from(depth) {
                            let p = NodeParams {
                                level,
                                node_size: 1u32 << (u32::from(depth) - level),
                                leaf_level: u32::from(depth),
                                queue_capacity: cap as u32,
                                inner_base,
                                leaf_base: 0,
                                attr_inner_base,
                                attr_leaf_base,
                                stats_base,
                                skin: skin_params,
                                ..base
                            };
                            slots.extend_from_slice(bytemuck::bytes_of(&p));
                            slots.resize(
                                slots.len()
                                    + (NODE_PARAMS_STRIDE as usize - size_of::<NodeParams>()),
                                0,
                            );
                        }
                        Traversal {
                            first_slot,
                            depth,
                            chunk,
                        }
                    },
                )
                .collect()
        };
        let main_trav = make_traversals(&main, STATS_START);
        // Every map counts into the one shadow range: `shadow_levels` is summed over lights,
        // as the CPU's `FrameStats::shadow_levels`.
        let shadow_travs: Vec<Vec<Traversal>> = shadows
            .iter()
            .map(|m| make_traversals(&m.view, STATS_START + MAX_LEVELS * STATS_PER_LEVEL))
            .collect();
        if slots.is_empty() {
            slots.resize(NODE_PARAMS_STRIDE as usize, 0);
        }
        let params_buf = upload("node params", &slots, U::UNIFORM);
        let clear_main = upload(
            "clear keys",
            bytemuck::bytes_of(&ClearParams {
                count: (pixels * 2) as u32,
                pad: [0; 3],
            }),
            U::UNIFORM,
        );
        let clear_shadow = upload(
            "clear shadow keys",
            bytemuck::bytes_of(&ClearParams {
                count: u32::try_from(shadow_words).unwrap_or(u32::MAX),
                pad: [0; 3],
            }),
            U::UNIFORM,
        );
        // KRS objects: traced after resolve into the same G-buffer (see gpu/krs.rs).
        let krs_scene = super::krs::prepared_krs(doc)?;
        if krs_scene.is_some() && self.krs.is_none() {
            self.krs = Some(super::krs::KrsPipelines::new(device)?);
        }
        let krs_frame = super::krs::KrsPipelines::prepare(
            self.krs.as_ref(),
            device,
            krs_scene.as_ref(),
            doc,
            quality,
            super::krs::KrsCamera {
                fx: main.fx,
                fy: main.fy,
                near: main.near,
                perspective: main.perspective,
            },
            (w, h),
            &super::krs::KrsBindings {
                view: &view_main,
                gbuffer: &gbuffer,
                counters: &counters,
            },
        )?;
        let krs_light_dummy;
        let krs_light = match &krs_frame {
            Some(k) => &k.light_buf,
            None => {
                krs_light_dummy = upload("krs lighting (none)", &[], U::STORAGE);
                &krs_light_dummy
            }
        };
        // Ambient occlusion as the CPU's `render_scene`: radius from the scene bounds the shadow
        // map is fitted to, grown by the bounded KRS objects' balls (0 without bounds: no
        // sample can then be occluded, and none is taken).
        let ao_radius = thicket_core::render::ao_radius_world(match &krs_scene {
            Some(k) => thicket_core::render::with_krs_bounds(frame_objects.bounds, k),
            None => frame_objects.bounds,
        });
        let (ao_count, ao_kernel) = ao_kernel(quality.ao_samples, ao_radius);
        let shading = ShadingUniform {
            ambient: doc.ambient.extend(0.0).to_array(),
            background: doc.background.extend(0.0).to_array(),
            light_count: lights.len() as u32,
            pcf_radius: quality.shadow_pcf_radius.min(8),
            receiver_px: quality.lod_pixel_threshold.max(1.0),
            ao_count,
            ao_radius,
            krs_stride: krs_frame.as_ref().map_or(0, |k| k.stride),
            pad: [0; 2],
            ao_kernel,
        };
        let shading_buf = upload("shading", bytemuck::bytes_of(&shading), U::UNIFORM);

        // Bind groups.
        // One per pool chunk: its inner nodes and skin data.
        let trav0 = |view: &wgpu::Buffer,
                     keys: wgpu::BufferBinding<'_>,
                     (inner_buf, skin_data): (&wgpu::Buffer, &wgpu::Buffer)| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("traverse 0"),
                layout: &self.trav_bgl[0],
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: view.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: counters.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: inner_buf.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: wgpu::BindingResource::Buffer(keys),
                    },
                    wgpu::BindGroupEntry {
                        binding: 5,
                        resource: tiles.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 6,
                        resource: skin_data.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 7,
                        resource: skin.joint_buf.as_entire_binding(),
                    },
                ],
            })
        };
        let bg_hiz = bind_group(
            device,
            &self.hiz_bgl,
            "hiz",
            &[&view_main, &keys_main, &tiles],
        );
        let hiz_groups = (
            w.div_ceil(OCCLUSION_TILE).div_ceil(8),
            h.div_ceil(OCCLUSION_TILE).div_ceil(8),
        );
        let occlusion = quality.occlusion_culling;
        let bg_indirect = bind_group(device, &self.indirect_bgl, "indirect", &[&indirect]);
        let per_chunk = |view: &wgpu::Buffer, keys: &wgpu::BufferBinding<'_>| {
            chunks
                .iter()
                .map(|(inner, _, skin_data, _)| trav0(view, keys.clone(), (inner, skin_data)))
                .collect::<Vec<wgpu::BindGroup>>()
        };
        let bg_main = per_chunk(&view_main, &keys_main.as_entire_buffer_binding());
        let bg_main_id = per_chunk(&view_main_id, &keys_main.as_entire_buffer_binding());
        // Each map's passes see only its own range of the shadow key buffer, so the splat and
        // mesh shaders index it from 0 as they index the view's.
        let shadow_keys_of = |m: &ShadowPlan| wgpu::BufferBinding {
            buffer: &keys_shadow,
            offset: m.offset,
            size: wgpu::BufferSize::new(m.bytes),
        };
        let bg_shadows: Vec<Vec<wgpu::BindGroup>> = shadows
            .iter()
            .zip(&shadow_views)
            .map(|(m, v)| per_chunk(v, &shadow_keys_of(m)))
            .collect();
        let bg_params = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("node params"),
            layout: &self.trav_bgl[1],
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &params_buf,
                    offset: 0,
                    size: wgpu::BufferSize::new(size_of::<NodeParams>() as u64),
                }),
            }],
        });
        let bg_ab = bind_group(
            device,
            &self.trav_bgl[2],
            "queues a→b",
            &[&queue_a, &queue_b],
        );
        let bg_ba = bind_group(
            device,
            &self.trav_bgl[2],
            "queues b→a",
            &[&queue_b, &queue_a],
        );
        let bg_clear_main = bind_group(
            device,
            &self.clear_bgl,
            "clear keys",
            &[&clear_main, &keys_main],
        );
        let bg_clear_shadow = bind_group(
            device,
            &self.clear_bgl,
            "clear shadow",
            &[&clear_shadow, &keys_shadow],
        );
        let bg_mesh_main = bind_group(
            device,
            &self.mesh_bgl,
            "mesh",
            &[&view_main, &tri_buf, &keys_main],
        );
        let bg_mesh_main_id = bind_group(
            device,
            &self.mesh_bgl,
            "mesh id",
            &[&view_main_id, &tri_buf, &keys_main],
        );
        let bg_mesh_shadows: Vec<wgpu::BindGroup> = shadows
            .iter()
            .zip(&shadow_views)
            .map(|(m, v)| {
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("mesh shadow"),
                    layout: &self.mesh_bgl,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: v.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: tri_buf.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: wgpu::BindingResource::Buffer(shadow_keys_of(m)),
                        },
                    ],
                })
            })
            .collect();
        // One resolve dispatch per pool chunk, each over the voxel ids its attributes hold.
        let bg_resolve: Vec<wgpu::BindGroup> = chunks
            .iter()
            .map(|(_, attr_buf, skin_data, range)| {
                let range_buf = upload("resolve chunk", bytemuck::bytes_of(range), U::UNIFORM);
                bind_group(
                    device,
                    &self.resolve_bgl,
                    "resolve",
                    &[
                        &view_main,
                        &keys_main,
                        attr_buf,
                        &object_buf,
                        &tri_buf,
                        &gbuffer,
                        skin_data,
                        &skin.joint_buf,
                        &texture_buf,
                        &range_buf,
                    ],
                )
            })
            .collect();
        let bg_shade = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shade"),
            layout: &self.shade_bgl,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: view_main.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: shadow_map_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: shading_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: light_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: gbuffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &keys_shadow,
                        offset: 0,
                        size: wgpu::BufferSize::new(shadow_words * 4),
                    }),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: wgpu::BindingResource::TextureView(&target.view),
                },
                wgpu::BindGroupEntry {
                    binding: 7,
                    resource: krs_light.as_entire_binding(),
                },
            ],
        });
        let main_attachment = self.attachment(device, w, h);
        // One attachment for every map's mesh draw (each draws into its own viewport of it).
        let (sw, sh) = shadows.iter().fold((0, 0), |(a, b), m| {
            (a.max(m.view.width), b.max(m.view.height))
        });
        let shadow_attachment =
            (!shadows.is_empty() && caster_tris > 0).then(|| self.attachment(device, sw, sh));

        let mut ts = if self.caps.timestamps {
            Some(Timestamps {
                set: device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("pass timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count: MAX_TIMED_PASSES * 2,
                }),
                used: Vec::new(),
            })
        } else {
            None
        };

        // Encoding, in pass order.
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("frame"),
        });
        enc.clear_buffer(&counters, 0, None);
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("clear"),
                timestamp_writes: ts.as_mut().and_then(|t| t.compute("clear")),
            });
            pass.set_pipeline(&self.clear);
            for (bg, words) in [
                (&bg_clear_main, pixels * 2),
                (
                    &bg_clear_shadow,
                    if shadows.is_empty() { 0 } else { shadow_words },
                ),
            ] {
                if words == 0 {
                    continue;
                }
                let groups = words.div_ceil(256);
                let gx = groups.min(65535) as u32;
                let gy = groups.div_ceil(u64::from(gx.max(1))) as u32;
                pass.set_bind_group(0, bg, &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
        }
        let mesh_pass = |enc: &mut wgpu::CommandEncoder,
                         ts: &mut Option<Timestamps>,
                         name: &'static str,
                         pipeline: &wgpu::RenderPipeline,
                         bg: &wgpu::BindGroup,
                         attachment: &wgpu::TextureView,
                         tris: u32| {
            if tris == 0 {
                return;
            }
            let mut pass = depth_only_pass(enc, ts, name, attachment);
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bg, &[]);
            pass.draw(0..tris * 3, 0..1);
        };
        let traverse_pass = |enc: &mut wgpu::CommandEncoder,
                             ts: &mut Option<Timestamps>,
                             name: &'static str,
                             pipeline: &wgpu::ComputePipeline,
                             views: &[(&[wgpu::BindGroup], &[Traversal])],
                             hiz: bool| {
            if views.iter().all(|(_, travs)| travs.is_empty()) {
                return;
            }
            // One pass for every view given (all shadow maps: one timed pass, however many
            // lights cast).
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(name),
                timestamp_writes: ts.as_mut().and_then(|t| t.compute(name)),
            });
            for (bg0, t) in views.iter().flat_map(|&(bgs, travs)| {
                travs
                    .iter()
                    .filter_map(move |t| Some((bgs.get(t.chunk)?, t)))
            }) {
                let slot = |level: u32| ((t.first_slot + level) as u64 * NODE_PARAMS_STRIDE) as u32;
                pass.set_bind_group(0, bg0, &[]);
                pass.set_bind_group(3, &bg_indirect, &[]);
                pass.set_pipeline(&self.seed);
                pass.set_bind_group(1, &bg_params, &[slot(0)]);
                pass.set_bind_group(2, &bg_ba, &[]);
                pass.dispatch_workgroups(1, 1, 1);
                for level in 0..=u32::from(t.depth) {
                    if hiz {
                        // Occlusion tiles from everything drawn so far (meshes, earlier
                        // levels and objects); its layout differs, so rebind after it.
                        pass.set_pipeline(&self.hiz);
                        pass.set_bind_group(0, &bg_hiz, &[]);
                        pass.dispatch_workgroups(hiz_groups.0, hiz_groups.1, 1);
                        pass.set_pipeline(&self.prepare);
                        pass.set_bind_group(0, bg0, &[]);
                        pass.set_bind_group(2, &bg_ba, &[]);
                        pass.set_bind_group(3, &bg_indirect, &[]);
                    }
                    pass.set_bind_group(1, &bg_params, &[slot(level)]);
                    pass.set_pipeline(&self.prepare);
                    pass.dispatch_workgroups(1, 1, 1);
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(2, if level % 2 == 0 { &bg_ab } else { &bg_ba }, &[]);
                    pass.dispatch_workgroups_indirect(&indirect, u64::from(level) * 12);
                }
            }
        };

        if let Some(attachment) = &shadow_attachment {
            // Every map's casters in one render pass, each map in its own viewport of the
            // shared attachment (the fragment's pixel indexes that map's key range).
            let name = "shadow meshes";
            let mut pass = depth_only_pass(&mut enc, &mut ts, name, attachment);
            pass.set_pipeline(&self.mesh32);
            for (m, bg) in shadows.iter().zip(&bg_mesh_shadows) {
                let (mw, mh) = (m.view.width, m.view.height);
                pass.set_viewport(0.0, 0.0, mw as f32, mh as f32, 0.0, 1.0);
                pass.set_scissor_rect(0, 0, mw, mh);
                pass.set_bind_group(0, bg, &[]);
                pass.draw(0..caster_tris * 3, 0..1);
            }
        }
        let shadow_views_trav: Vec<(&[wgpu::BindGroup], &[Traversal])> = bg_shadows
            .iter()
            .zip(&shadow_travs)
            .map(|(bg, t)| (bg.as_slice(), t.as_slice()))
            .collect();
        traverse_pass(
            &mut enc,
            &mut ts,
            "shadow voxels",
            &self.traverse32,
            &shadow_views_trav,
            false,
        );
        match (path, &self.mesh64, &self.traverse64) {
            (AtomicPath::Key64, Some(mesh64), Some(trav64)) => {
                mesh_pass(
                    &mut enc,
                    &mut ts,
                    "meshes",
                    mesh64,
                    &bg_mesh_main,
                    &main_attachment,
                    tri_count,
                );
                traverse_pass(
                    &mut enc,
                    &mut ts,
                    "voxels",
                    trav64,
                    &[(bg_main.as_slice(), &main_trav)],
                    occlusion,
                );
            }
            _ => {
                mesh_pass(
                    &mut enc,
                    &mut ts,
                    "meshes",
                    &self.mesh32,
                    &bg_mesh_main,
                    &main_attachment,
                    tri_count,
                );
                traverse_pass(
                    &mut enc,
                    &mut ts,
                    "voxels",
                    &self.traverse32,
                    &[(bg_main.as_slice(), &main_trav)],
                    occlusion,
                );
                mesh_pass(
                    &mut enc,
                    &mut ts,
                    "meshes",
                    &self.mesh32,
                    &bg_mesh_main_id,
                    &main_attachment,
                    tri_count,
                );
                traverse_pass(
                    &mut enc,
                    &mut ts,
                    "voxels",
                    &self.traverse32,
                    &[(bg_main_id.as_slice(), &main_trav)],
                    false,
                );
            }
        }
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("resolve"),
                timestamp_writes: ts.as_mut().and_then(|t| t.compute("resolve")),
            });
            pass.set_pipeline(&self.resolve);
            for bg in &bg_resolve {
                pass.set_bind_group(0, bg, &[]);
                pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
            }
        }
        if let (Some(k), Some(krs)) = (&krs_frame, &self.krs) {
            for (name, trace) in [("krs trace", true), ("krs light", false)] {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(name),
                    timestamp_writes: ts.as_mut().and_then(|t| t.compute(name)),
                });
                if trace {
                    krs.trace(&mut pass, k);
                } else {
                    krs.light(&mut pass, k);
                }
            }
        }
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("shade"),
                timestamp_writes: ts.as_mut().and_then(|t| t.compute("shade")),
            });
            pass.set_pipeline(&self.shade);
            pass.set_bind_group(0, &bg_shade, &[]);
            pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        }
        // The splat-bandwidth measurement: the view's voxel pass alone, in submissions of its
        // own before the frame's (which then redoes every state the measurement changed).
        if let Some(repeats) = probe {
            let result = match (path, &self.mesh64, &self.traverse64) {
                (AtomicPath::Key64, Some(mesh64), Some(trav64)) => {
                    let restore = |enc: &mut wgpu::CommandEncoder| {
                        enc.clear_buffer(&counters, 0, None);
                        {
                            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                                label: Some("clear keys"),
                                timestamp_writes: None,
                            });
                            pass.set_pipeline(&self.clear);
                            let groups = (pixels * 2).div_ceil(256);
                            let gx = groups.min(65535) as u32;
                            let gy = groups.div_ceil(u64::from(gx.max(1))) as u32;
                            pass.set_bind_group(0, &bg_clear_main, &[]);
                            pass.dispatch_workgroups(gx, gy, 1);
                        }
                        mesh_pass(
                            enc,
                            &mut None,
                            "meshes",
                            mesh64,
                            &bg_mesh_main,
                            &main_attachment,
                            tri_count,
                        );
                    };
                    let splat = |enc: &mut wgpu::CommandEncoder, set: Option<&wgpu::QuerySet>| {
                        let mut ts = set.map(|s| Timestamps {
                            set: s.clone(),
                            used: Vec::new(),
                        });
                        traverse_pass(
                            enc,
                            &mut ts,
                            "voxels",
                            trav64,
                            &[(bg_main.as_slice(), &main_trav)],
                            occlusion,
                        );
                    };
                    let read_counters = || {
                        let staging = device.create_buffer(&wgpu::BufferDescriptor {
                            label: Some("splat bandwidth counters"),
                            size: COUNTER_BYTES,
                            usage: U::MAP_READ | U::COPY_DST,
                            mapped_at_creation: false,
                        });
                        let mut e = device.create_command_encoder(&Default::default());
                        e.copy_buffer_to_buffer(&counters, 0, &staging, 0, COUNTER_BYTES);
                        queue.submit([e.finish()]);
                        let meta = FrameMeta {
                            frame: 0,
                            timed: Vec::new(),
                            triangles: 0,
                            atomic_path: path,
                            period_ns: 0.0,
                        };
                        let d = decode_counters(&map_read(device, &staging)?, &meta);
                        Ok((d.levels, d.splat_pixels))
                    };
                    let builds = if occlusion {
                        main_trav.iter().map(|t| u64::from(t.depth) + 1).sum()
                    } else {
                        0
                    };
                    super::splat_bw::measure(
                        device,
                        queue,
                        &super::splat_bw::ProbePasses {
                            restore: &restore,
                            splat: &splat,
                            read_counters: &read_counters,
                        },
                        repeats,
                        super::splat_bw::OcclusionWork {
                            builds,
                            width: w,
                            height: h,
                        },
                        self.caps.timestamps,
                    )
                }
                _ => Err(GpuError::Device(
                    "the splat bandwidth is measured on the 64-bit splat path only".into(),
                )),
            };
            self.splat_probe_result = Some(result);
        }
        // Counters and timestamps go to a free staging slot of the ring; with no free slot
        // (async readback running behind), this frame's counters are skipped rather than
        // waited for.
        let slot = self.readback.free_slot(device);
        if let Some(slot) = slot {
            let staging = self.readback.slots[slot].buffer.clone();
            enc.copy_buffer_to_buffer(&counters, 0, &staging, 0, COUNTER_BYTES);
            if let Some(t) = ts.as_ref().filter(|t| !t.used.is_empty()) {
                let n = t.used.len() as u32 * 2;
                let resolve = self.buffer(
                    device,
                    "timestamp resolve",
                    u64::from(MAX_TIMED_PASSES * 2) * 8,
                    U::QUERY_RESOLVE | U::COPY_SRC,
                );
                enc.resolve_query_set(&t.set, 0..n, &resolve, 0);
                enc.copy_buffer_to_buffer(&resolve, 0, &staging, COUNTER_BYTES, u64::from(n) * 8);
            }
        }
        queue.submit([enc.finish()]);
        self.frame_index += 1;
        let meta = FrameMeta {
            frame: self.frame_index,
            timed: ts
                .as_ref()
                .map(|t| t.used.iter().map(|u| (u.name, u.first_query)).collect())
                .unwrap_or_default(),
            triangles: u64::from(tri_count),
            atomic_path: path,
            period_ns: f64::from(queue.get_timestamp_period()),
        };
        let mut stats = GpuFrameStats {
            triangles: u64::from(tri_count),
            atomic_path: path,
            frame: self.frame_index,
            ..GpuFrameStats::default()
        };
        if let Some(slot) = slot {
            self.readback.start(slot, meta);
        }
        if self.async_readback {
            device
                .poll(wgpu::PollType::Poll)
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            self.readback.collect();
            if let Some(latest) = &self.readback.latest {
                stats.fill_counters_from(latest);
            }
        } else {
            let slot = slot.ok_or_else(|| GpuError::Readback("no staging slot".into()))?;
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            self.readback.collect();
            let got = self
                .readback
                .latest
                .as_ref()
                .filter(|l| l.frame == self.frame_index)
                .ok_or_else(|| {
                    GpuError::Readback(format!(
                        "counters of frame {} did not arrive (slot {slot})",
                        self.frame_index
                    ))
                })?;
            stats.fill_counters_from(got);
        }
        Ok(stats)
    }
}

/// Bytes of the counter buffer.
const COUNTER_BYTES: u64 = COUNTER_WORDS as u64 * 4;
/// Staging slots in the readback ring: a frame's counters arrive a few frames later without
/// the GPU ever waiting for the CPU.
const READBACK_SLOTS: usize = 4;

/// What is needed to decode a frame's counters once they arrive.
#[derive(Clone)]
struct FrameMeta {
    frame: u64,
    timed: Vec<(&'static str, u32)>,
    triangles: u64,
    atomic_path: AtomicPath,
    period_ns: f64,
}

/// Slot states (shared with the `map_async` callback).
const SLOT_IDLE: u32 = 0;
const SLOT_PENDING: u32 = 1;
const SLOT_MAPPED: u32 = 2;
const SLOT_FAILED: u32 = 3;

struct ReadbackSlot {
    buffer: wgpu::Buffer,
    state: Arc<AtomicU32>,
    meta: Option<FrameMeta>,
}

/// A ring of `MAP_READ` buffers that counters and timestamps are copied into at the end of a
/// frame and mapped asynchronously (`map_async`), so reading them never stalls the GPU.
#[derive(Default)]
struct ReadbackRing {
    slots: Vec<ReadbackSlot>,
    /// The newest decoded frame statistics.
    latest: Option<GpuFrameStats>,
}

impl ReadbackRing {
    /// An idle slot (created on first use, up to [`READBACK_SLOTS`]).
    fn free_slot(&mut self, device: &wgpu::Device) -> Option<usize> {
        if let Some(i) = self
            .slots
            .iter()
            .position(|s| s.state.load(Ordering::Acquire) == SLOT_IDLE)
        {
            return Some(i);
        }
        if self.slots.len() >= READBACK_SLOTS {
            return None;
        }
        self.slots.push(ReadbackSlot {
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("counters readback"),
                size: COUNTER_BYTES + u64::from(MAX_TIMED_PASSES * 2) * 8,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            state: Arc::new(AtomicU32::new(SLOT_IDLE)),
            meta: None,
        });
        Some(self.slots.len() - 1)
    }

    /// Requests the mapping of a slot whose copy was just submitted.
    fn start(&mut self, i: usize, meta: FrameMeta) {
        let slot = &mut self.slots[i];
        slot.meta = Some(meta);
        slot.state.store(SLOT_PENDING, Ordering::Release);
        let state = slot.state.clone();
        slot.buffer
            .slice(..)
            .map_async(wgpu::MapMode::Read, move |r| {
                state.store(
                    if r.is_ok() { SLOT_MAPPED } else { SLOT_FAILED },
                    Ordering::Release,
                );
            });
    }

    /// Decodes every slot whose mapping completed (call after a device poll); keeps the newest.
    fn collect(&mut self) {
        for slot in &mut self.slots {
            match slot.state.load(Ordering::Acquire) {
                SLOT_MAPPED => {
                    let decoded = slot
                        .buffer
                        .slice(..)
                        .get_mapped_range()
                        .ok()
                        .and_then(|view| slot.meta.as_ref().map(|m| decode_counters(&view, m)));
                    slot.buffer.unmap();
                    if let Some(d) = decoded
                        && self.latest.as_ref().is_none_or(|l| l.frame < d.frame)
                    {
                        self.latest = Some(d);
                    }
                    slot.state.store(SLOT_IDLE, Ordering::Release);
                }
                SLOT_FAILED => slot.state.store(SLOT_IDLE, Ordering::Release),
                _ => {}
            }
        }
    }
}

/// Frame statistics from a staging slot's bytes: counters, then timestamp pairs.
fn decode_counters(raw: &[u8], meta: &FrameMeta) -> GpuFrameStats {
    let words: &[u32] = bytemuck::cast_slice(&raw[..COUNTER_BYTES as usize]);
    let levels_of = |base: u32| -> Vec<GpuLevelStats> {
        let mut v: Vec<GpuLevelStats> = (0..MAX_LEVELS)
            .map(|l| {
                let i = (base + l * STATS_PER_LEVEL) as usize;
                GpuLevelStats {
                    visited: u64::from(words[i]),
                    split: u64::from(words[i + 1]),
                    splatted: u64::from(words[i + 2]),
                    frustum_culled: u64::from(words[i + 3]),
                    occlusion_culled: u64::from(words[i + 4]),
                    cubes: u64::from(words[i + 5]),
                }
            })
            .collect();
        while v.last().is_some_and(|l| l.visited == 0) {
            v.pop();
        }
        v
    };
    let levels = levels_of(STATS_START);
    let mut stats = GpuFrameStats {
        splats: levels.iter().map(|l| l.splatted).sum(),
        levels,
        shadow_levels: levels_of(STATS_START + MAX_LEVELS * STATS_PER_LEVEL),
        queue_overflow: u64::from(words[OVERFLOW_COUNTER as usize]),
        splat_pixels: u64::from(words[SPLAT_PIXEL_COUNTERS as usize]),
        cube_pixels: u64::from(words[CUBE_PIXEL_COUNTERS as usize]),
        krs: super::krs::GpuKrsStats::from_counters(words),
        triangles: meta.triangles,
        atomic_path: meta.atomic_path,
        frame: meta.frame,
        counters_frame: Some(meta.frame),
        ..GpuFrameStats::default()
    };
    if !meta.timed.is_empty() {
        let ticks: &[u64] = bytemuck::cast_slice(&raw[COUNTER_BYTES as usize..]);
        for &(name, q) in &meta.timed {
            let q = q as usize;
            let ms = ticks[q + 1].saturating_sub(ticks[q]) as f64 * meta.period_ns * 1e-6;
            match stats.pass_ms.iter_mut().find(|(n, _)| *n == name) {
                Some((_, acc)) => *acc += ms,
                None => stats.pass_ms.push((name, ms)),
            }
        }
        stats.gpu_timestamps = true;
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

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
}

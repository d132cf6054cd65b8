//! The one bridge between egui and the GPU renderer: an egui-wgpu paint callback.
//!
//! - At start-up [`install`] puts the long-lived state (the [`Renderer`] with its pipelines,
//!   the blit pipeline, the render target) into egui-wgpu's `callback_resources`.
//! - Each frame the view adds a [`ViewportCallback`] that carries plain values: the document
//!   snapshot (shared, not copied), the content key, camera and target size.
//! - `prepare` renders only when that key differs from the last rendered one (the camera, the
//!   document or its quality settings changed, or the view was resized); otherwise the last
//!   image is composited again. The callback carries the chain of voxel regions the view read
//!   from the editor's change feed (dabs, tool edits, their undo and redo, a linked
//!   enhancement's fine model; empty ones for changes that upload nothing, such as a pose):
//!   when the GPU holds the document at one of their start states, `prepare` uploads just
//!   those regions ([`Renderer::update_voxel_region`]) instead of the whole scene. `paint`
//!   only draws the image into the view rectangle.
//! - A failure (no adapter features, invalid document, device loss) is logged once and handed
//!   to the UI through the [`ViewportLink`]; it never panics and the document stays editable.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use thicket_core::scene::{Document, OrbitCamera};

use crate::editor::VoxelRegion;

pub use crate::preview::frame_depth::FrameDepth;

use crate::gpu::context::{install_error_handlers, wanted_features, wanted_limits};
use crate::gpu::{
    ErrorSlot, GpuError, GpuFrameStats, RenderTarget, Renderer, UploadStats, shaders,
};

/// What the last rendered frame did, shared between the callback and the UI.
#[derive(Debug, Clone, Default)]
pub struct ViewportStatus {
    /// The adapter in one line (name, backend, driver).
    pub adapter: String,
    /// The adapter is a software rasteriser (`wgpu::DeviceType::Cpu`, such as lavapipe): it
    /// runs the GPU renderer's shaders on the CPU: its viewport frames on the sample projects took
    /// 11 to 113× as long as the CPU preview's (BENCHMARKS.md), so the view's Auto mode draws with the CPU preview.
    pub software: bool,
    /// Statistics of the last rendered frame.
    pub stats: Option<GpuFrameStats>,
    /// Frames the renderer actually ran (not counting frames that reused the image).
    pub frames_rendered: u64,
    /// Frames composited (rendered or reused).
    pub frames_painted: u64,
    /// Wall-clock milliseconds of the last render call (upload, passes, wait).
    pub last_render_ms: f64,
    /// Size of the last rendered image in pixels.
    pub size_px: [u32; 2],
    /// The last error, shown in the view until a frame renders again.
    pub error: Option<String>,
    /// What the last rendered frame uploaded before drawing.
    pub last_upload: Option<UploadStats>,
    /// Frames that uploaded only an edited voxel region.
    pub region_uploads: u64,
    /// The depth of the shown frame, read back once the view stood still on it and a
    /// callback asked for it ([`ViewportCallback::want_depth`]).
    pub depth: Option<FrameDepth>,
    /// The frame whose depth was last read (or tried): it is not read again.
    pub depth_read: Option<FrameKey>,
}

/// A handle to the [`ViewportStatus`] (cloning shares it).
#[derive(Debug, Clone, Default)]
pub struct ViewportLink(Arc<Mutex<ViewportStatus>>);

impl ViewportLink {
    /// Locks the status (a poisoned lock still holds usable counters).
    pub fn lock(&self) -> MutexGuard<'_, ViewportStatus> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// The device descriptor the renderer needs: its optional features where the adapter has
/// them (64-bit atomics, timestamps) and raised buffer limits.
#[must_use]
pub fn device_descriptor(adapter: &wgpu::Adapter) -> wgpu::DeviceDescriptor<'static> {
    let mut features = adapter.features() & wanted_features();
    if !features.contains(wgpu::Features::SHADER_INT64) {
        features.remove(wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX);
    }
    wgpu::DeviceDescriptor {
        label: Some("thicket editor"),
        required_features: features,
        required_limits: wanted_limits(adapter),
        ..Default::default()
    }
}

/// The egui-wgpu setup for the editor window and the UI tests: Vulkan or GL (a software
/// adapter such as lavapipe works) with [`device_descriptor`].
#[must_use]
pub fn wgpu_setup() -> egui_wgpu::WgpuSetup {
    let mut setup = egui_wgpu::WgpuSetupCreateNew::without_display_handle();
    if std::env::var_os("WGPU_BACKEND").is_none() {
        setup.instance_descriptor.backends = wgpu::Backends::VULKAN | wgpu::Backends::GL;
    }
    setup.device_descriptor = Arc::new(device_descriptor);
    egui_wgpu::WgpuSetup::CreateNew(setup)
}

/// Puts the long-lived viewport state into the render state's callback resources and returns
/// the link the UI reads. Errors creating the renderer are reported through the link.
pub fn install(render_state: &egui_wgpu::RenderState) -> ViewportLink {
    let link = ViewportLink::default();
    let info = render_state.adapter.get_info();
    {
        let mut status = link.lock();
        status.adapter = format!("{} ({:?}, {})", info.name, info.backend, info.driver);
        status.software = info.device_type == wgpu::DeviceType::Cpu;
    }
    let device = &render_state.device;
    let errors = install_error_handlers(device);
    let renderer = match Renderer::new(device, &render_state.queue) {
        Ok(r) => Some(r),
        Err(e) => {
            log::error!("viewport: {e}");
            link.lock().error = Some(format!("The GPU renderer is unavailable: {e}"));
            None
        }
    };
    let blit = match Blit::new(device, render_state.target_format) {
        Ok(b) => Some(b),
        Err(e) => {
            log::error!("viewport: {e}");
            link.lock().error = Some(format!("The viewport cannot draw: {e}"));
            None
        }
    };
    render_state
        .renderer
        .write()
        .callback_resources
        .insert(Resources {
            renderer,
            blit,
            errors,
            frame: None,
            last_key: None,
            uploaded: None,
            depth_error: None,
            link: link.clone(),
        });
    link
}

/// Draws the renderer's target into the view rectangle.
struct Blit {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
}

impl Blit {
    fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Result<Self, GpuError> {
        let src = shaders::compose("viewport_blit.wgsl")?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("viewport blit"),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("viewport blit"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("viewport blit"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("viewport blit"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[],
            },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(if format.is_srgb() {
                    "fs_srgb_target"
                } else {
                    "fs_main"
                }),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            multiview_mask: None,
            cache: None,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("viewport blit"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        Ok(Self {
            pipeline,
            layout,
            sampler,
        })
    }
}

/// The rendered image and its bind group for the blit.
struct Frame {
    target: RenderTarget,
    bind_group: wgpu::BindGroup,
    /// False when the last render into it failed (nothing valid to show).
    valid: bool,
}

/// Long-lived state in egui-wgpu's callback resources.
struct Resources {
    renderer: Option<Renderer>,
    blit: Option<Blit>,
    errors: ErrorSlot,
    frame: Option<Frame>,
    last_key: Option<FrameKey>,
    /// The content key of the document the GPU buffers hold (after a successful render).
    uploaded: Option<(u64, u64)>,
    link: ViewportLink,
    /// The last depth readback's failure, logged once.
    depth_error: Option<String>,
}

/// Everything that decides the image: when it equals the last one, nothing is rendered.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameKey {
    /// The document's content key ([`crate::editor::Editor::content_key`]).
    pub content: (u64, u64),
    /// The document's animation key ([`crate::editor::Editor::animation_key`]): a new clip
    /// time or pose redraws with the uploaded scene (rigged models upload only their joint
    /// matrices).
    pub animation: u64,
    /// The view camera.
    pub camera: OrbitCamera,
    /// Target size in pixels.
    pub size_px: [u32; 2],
    /// Samples per pixel side to draw: the document's `supersample`, or 1 while the view keeps
    /// changing (an orbit, a stroke, playback), as the CPU preview's moving frames.
    pub supersample: u32,
}

/// The per-frame paint callback: plain values and a shared document snapshot.
pub struct ViewportCallback {
    /// What decides the image.
    pub key: FrameKey,
    /// The document as of `key.content` (shared with the UI, not copied per frame).
    pub doc: Arc<Document>,
    /// A chain of voxel edits ending at `key.content` (each starts where the one before ends).
    /// When the GPU holds the document at one of their `from` states, uploading the regions
    /// from there on brings it to `doc`.
    pub regions: Vec<VoxelRegion>,
    /// The view hides overlay lines behind what is drawn: once a frame is shown a second
    /// time (the view stood still on it), its depth is read back into
    /// [`ViewportStatus::depth`]. Frames drawn once, while the view moves, are not read.
    pub want_depth: bool,
}

impl Resources {
    /// Reads the shown frame's depth into the status, once per frame drawn: tried once for
    /// each key, whatever happens (no frame, a failed frame, a failed readback), so the view
    /// never waits for a depth that will not come.
    fn read_depth(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, key: &FrameKey) {
        if self.link.lock().depth_read.as_ref() == Some(key) {
            return;
        }
        let read = match (self.renderer.as_mut(), self.frame.as_ref()) {
            (Some(renderer), Some(frame)) if frame.valid => renderer
                .read_depth(device, queue)
                .map_err(|e| e.to_string()),
            _ => Err("no frame is shown".to_owned()),
        };
        let depth = match read {
            Ok((w, h, depth)) => Some(FrameDepth::new(
                key.content,
                key.animation,
                key.camera,
                [w, h],
                depth.into(),
            )),
            Err(e) => {
                // Overlays are then hidden by voxels only (the view's ray picks). Said once.
                if self.depth_error.as_deref() != Some(e.as_str()) {
                    log::warn!("viewport: the frame's depth for the overlays: {e}");
                    self.depth_error = Some(e);
                }
                None
            }
        };
        let mut status = self.link.lock();
        status.depth = depth;
        status.depth_read = Some(key.clone());
    }

    fn report(&mut self, e: &GpuError) {
        let text = e.to_string();
        let mut status = self.link.lock();
        // Shown once: the same error every frame is logged only the first time.
        if status.error.as_deref() != Some(text.as_str()) {
            log::error!("viewport: {text}");
            status.error = Some(text);
        }
    }

    fn render(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, cb: &ViewportCallback) {
        let (Some(renderer), Some(blit)) = (self.renderer.as_mut(), self.blit.as_ref()) else {
            return;
        };
        let [w, h] = cb.key.size_px;
        let size_ok = self
            .frame
            .as_ref()
            .is_some_and(|f| f.target.width == w && f.target.height == h);
        if !size_ok {
            match RenderTarget::new(device, w, h) {
                Ok(target) => {
                    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("viewport blit"),
                        layout: &blit.layout,
                        entries: &[
                            wgpu::BindGroupEntry {
                                binding: 0,
                                resource: wgpu::BindingResource::TextureView(&target.view),
                            },
                            wgpu::BindGroupEntry {
                                binding: 1,
                                resource: wgpu::BindingResource::Sampler(&blit.sampler),
                            },
                        ],
                    });
                    self.frame = Some(Frame {
                        target,
                        bind_group,
                        valid: false,
                    });
                }
                Err(e) => {
                    self.frame = None;
                    self.report(&e);
                    return;
                }
            }
        }
        let Some(frame) = self.frame.as_mut() else {
            return;
        };
        let t0 = Instant::now();
        // The GPU holds the document at `uploaded`: when the only change since is a voxel
        // edit, upload that region and draw with the rest of the scene as it is.
        let unchanged = self.uploaded == Some(cb.key.content);
        let chained = cb.regions.last().is_some_and(|r| r.to == cb.key.content);
        let region = cb
            .regions
            .iter()
            .position(|r| self.uploaded == Some(r.from))
            .filter(|_| chained && !unchanged)
            .map(|start| &cb.regions[start..]);
        // Upload the edited regions, if that is what changed, then draw: uploading the whole
        // scene first unless nothing or only the regions changed. The upload reported is the
        // regions' and the frame's own.
        let regions_upload = match region {
            Some(regions) => regions
                .iter()
                .filter(|r| !r.is_empty())
                .try_fold(UploadStats::default(), |acc, r| {
                    renderer
                        .update_voxel_region(device, queue, &cb.doc, r.object, r.lo, r.hi)
                        .map(|up| acc.combined(up))
                })
                .map(Some),
            None => Ok(None),
        };
        let full = region.is_none() && !unchanged;
        let result = regions_upload.and_then(|regions_up| {
            let doc = &cb.doc;
            // The document's quality, with one sample per pixel while the view moves.
            let view = thicket_core::render::View {
                width: frame.target.width,
                height: frame.target.height,
                camera: Some(cb.key.camera),
                quality: thicket_core::quality::Quality {
                    supersample: cb.key.supersample,
                    ..doc.quality.clone()
                },
            };
            let stats = if full {
                renderer.render(device, queue, doc, &view, &frame.target)
            } else {
                renderer.render_uploaded(device, queue, doc, &view, &frame.target)
            }?;
            // The regions' upload plus what the frame itself uploaded (a pool that changed
            // length, a rig's joint matrices).
            let up = regions_up.map_or(stats.upload, |r| r.combined(stats.upload));
            Ok((stats, up))
        });
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let lost = self.errors.take();
        match (result, lost) {
            (Ok((stats, upload)), None) => {
                frame.valid = true;
                self.uploaded = Some(cb.key.content);
                let mut status = self.link.lock();
                status.stats = Some(stats);
                status.frames_rendered += 1;
                status.last_render_ms = ms;
                status.size_px = [w, h];
                status.error = None;
                status.last_upload = Some(upload);
                if region.is_some() && !upload.full {
                    status.region_uploads += 1;
                }
            }
            (Err(e), _) | (Ok(_), Some(e)) => {
                frame.valid = false;
                // Nothing valid is shown: no depth hides anything.
                self.link.lock().depth = None;
                // What the GPU holds is unknown now: the next frame uploads everything.
                self.uploaded = None;
                self.report(&e);
            }
        }
    }
}

impl egui_wgpu::CallbackTrait for ViewportCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen_descriptor: &egui_wgpu::ScreenDescriptor,
        _egui_encoder: &mut wgpu::CommandEncoder,
        callback_resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        let Some(res) = callback_resources.get_mut::<Resources>() else {
            return Vec::new();
        };
        // A failed frame is not retried every frame either: only a new key renders again.
        if res.last_key.as_ref() != Some(&self.key) {
            res.last_key = Some(self.key.clone());
            res.render(device, queue, self);
        } else if self.want_depth {
            res.read_depth(device, queue, &self.key);
        }
        Vec::new()
    }

    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        render_pass: &mut wgpu::RenderPass<'static>,
        callback_resources: &egui_wgpu::CallbackResources,
    ) {
        let Some(res) = callback_resources.get::<Resources>() else {
            return;
        };
        let (Some(blit), Some(frame)) = (res.blit.as_ref(), res.frame.as_ref()) else {
            return;
        };
        if !frame.valid {
            return;
        }
        render_pass.set_pipeline(&blit.pipeline);
        render_pass.set_bind_group(0, &frame.bind_group, &[]);
        render_pass.draw(0..3, 0..1);
        res.link.lock().frames_painted += 1;
    }
}

/// Adds the viewport's paint callback for `rect`.
pub fn paint_callback(rect: egui::Rect, callback: ViewportCallback) -> egui::Shape {
    egui::Shape::Callback(egui_wgpu::Callback::new_paint_callback(rect, callback))
}

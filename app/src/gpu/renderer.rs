//! The long-lived [`Renderer`] (layouts and pipelines, created once) and one frame's work.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::time::Instant;

use glam::{UVec3, Vec3};
use thicket_core::quality::Quality;
use thicket_core::render::View;
use thicket_core::scene::{Document, OrbitCamera};

use super::context::Capabilities;
use super::gpu_data::{
    COUNTER_BYTES, CUBE_PIXEL_COUNTERS, GBUFFER_TEXEL_BYTES, MAX_LEVELS, OVERFLOW_COUNTER,
    SPLAT_PIXEL_COUNTERS, STATS_PER_LEVEL, STATS_START,
};
use super::passes::clear::ClearPass;
use super::passes::hiz::HizPass;
use super::passes::mesh::MeshPass;
use super::passes::plan::{FramePlan, PlanLimits, PlanScene};
use super::passes::resolve::ResolvePass;
use super::passes::shade::{ShadeInputs, ShadePass};
use super::passes::supersample::{SupersamplePass, samples_per_side};
use super::passes::traverse::{TraversePass, Views};
use super::passes::{BufferPool, FrameBuffers, Gpu, MAX_TIMED_PASSES, Timestamps};
use super::scene::{SceneCache, UploadStats};
use super::skin::{SkinCache, SkinFrame};
use super::{AtomicPath, GpuError, GpuFrameStats, GpuLevelStats};

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
    /// A view of this target's size through `camera` with `quality`.
    #[must_use]
    pub fn view(&self, camera: &OrbitCamera, quality: &Quality) -> View {
        View {
            width: self.width,
            height: self.height,
            camera: Some(*camera),
            quality: quality.clone(),
        }
    }

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

/// A supersampled frame's G-buffer at its image's size: per pixel, the sample nearest the
/// pixel's centre, as the CPU's `FrameBuffers::decimate`.
fn decimate(g: GBuffer, k: u32) -> GBuffer {
    if k <= 1 {
        return g;
    }
    let (w, h) = (g.width / k, g.height / k);
    let (big_w, k, c) = (g.width as usize, k as usize, (k / 2) as usize);
    let at = |x: usize, y: usize| (y * k + c) * big_w + x * k + c;
    let pick = |v: &[Vec3]| -> Vec<Vec3> {
        (0..h as usize)
            .flat_map(|y| (0..w as usize).map(move |x| (x, y)))
            .map(|(x, y)| v[at(x, y)])
            .collect()
    };
    GBuffer {
        width: w,
        height: h,
        depth: (0..h as usize)
            .flat_map(|y| (0..w as usize).map(move |x| (x, y)))
            .map(|(x, y)| g.depth[at(x, y)])
            .collect(),
        normal: pick(&g.normal),
        albedo: pick(&g.albedo),
    }
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

/// What one frame reads: the document, the view and the knobs, and where it draws.
#[derive(Clone, Copy)]
pub(super) struct FrameInputs<'a> {
    pub(super) doc: &'a Document,
    pub(super) camera: &'a OrbitCamera,
    pub(super) quality: &'a Quality,
    pub(super) target: &'a RenderTarget,
}

/// How a frame brings the scene on the GPU up to date.
#[derive(Clone, Copy, PartialEq, Eq)]
enum SceneUpload {
    /// Pack and upload the whole document.
    Full,
    /// Upload what can be seen to have changed (see [`Renderer::render_uploaded`]).
    Changed,
}

/// Layouts and pipelines, created once per device, and the frame's persistent buffers and
/// bind groups (one module per pass, see `gpu::passes`).
pub struct Renderer {
    caps: Capabilities,
    force_two_pass: bool,
    clear: ClearPass,
    hiz: HizPass,
    traverse: TraversePass,
    mesh: MeshPass,
    resolve: ResolvePass,
    shade: ShadePass,
    supersample: SupersamplePass,
    /// The KRS pass (trace and lighting), built with the first frame that has KRS objects (its
    /// shader is the largest; frames without KRS never pay for compiling it).
    krs: Option<super::krs::KrsPipelines>,
    /// Per-frame buffers, reused while large enough.
    pool: BufferPool,
    /// Buffers, bind groups, textures and query sets the frames created so far.
    created: Arc<AtomicU64>,
    /// The shadow maps' slot size so far (see `passes::plan::layout_shadows`).
    shadow_slot: u64,
    /// The pass timestamps' query set (created with the first frame on a device that has them).
    timestamps: Option<wgpu::QuerySet>,
    /// The last frame's drawn size (the samples' when supersampled) and samples per side.
    last_size: (u32, u32),
    last_samples_per_side: u32,
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

/// A prepared frame: its plan and the KRS pass's frame (when it has KRS objects).
struct Prepared {
    plan: FramePlan,
    counters: wgpu::Buffer,
    krs: Option<super::krs::KrsFrame>,
    triangles: u32,
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
        Ok(Self {
            caps,
            force_two_pass: false,
            clear: ClearPass::new(device)?,
            hiz: HizPass::new(device)?,
            traverse: TraversePass::new(device, caps.int64_atomics)?,
            mesh: MeshPass::new(device, caps.int64_atomics)?,
            resolve: ResolvePass::new(device)?,
            shade: ShadePass::new(device)?,
            supersample: SupersamplePass::new(device)?,
            krs: None,
            pool: BufferPool::default(),
            created: Arc::new(AtomicU64::new(0)),
            shadow_slot: 0,
            timestamps: None,
            last_size: (0, 0),
            last_samples_per_side: 1,
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
        if self.traverse.has_key64() && !self.force_two_pass {
            AtomicPath::Key64
        } else {
            AtomicPath::TwoPass32
        }
    }

    /// Buffers, bind groups, textures and query sets the frames created so far (scene and
    /// skin uploads not included: they create only when the document's data changes). A frame
    /// that differs from the last only by its camera adds none.
    #[must_use]
    pub fn resource_creations(&self) -> u64 {
        self.created.load(Ordering::Relaxed)
    }

    /// Renders `doc` as `view` sees it (its camera, or the document's; its quality) into
    /// `target`, which must be the view's size. Uploads the whole scene first (any change to
    /// the document shows); an editor that knows what changed uploads with
    /// [`Renderer::update_voxel_region`] and draws with [`Renderer::render_uploaded`].
    ///
    /// Waits for the GPU and returns this frame's counters (and timestamps when the device has
    /// them), unless [`Renderer::set_async_readback`] is on.
    ///
    /// # Errors
    /// [`GpuError`] for an invalid document, camera or quality, a target of another size than
    /// the view's, scene data over the device's binding limit, or a validation / out-of-memory error raised while encoding the frame.
    pub fn render(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        view: &View,
        target: &RenderTarget,
    ) -> Result<GpuFrameStats, GpuError> {
        let camera = view_camera(doc, view, target)?;
        let inputs = FrameInputs {
            doc,
            camera: &camera,
            quality: &view.quality,
            target,
        };
        self.frame(device, queue, &inputs, SceneUpload::Full)
    }

    /// Renders with the scene as last uploaded: only transforms, lights and camera are read
    /// from `doc` each frame, plus what can be seen without an edit region (objects added,
    /// removed or hidden, or a pool that changed length, cause an upload of what changed). A
    /// voxel edit that keeps the pool lengths must be announced with
    /// [`Renderer::update_voxel_region`] first, or the frame shows the old voxels.
    ///
    /// # Errors
    /// As [`Renderer::render`].
    pub fn render_uploaded(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        view: &View,
        target: &RenderTarget,
    ) -> Result<GpuFrameStats, GpuError> {
        let camera = view_camera(doc, view, target)?;
        let inputs = FrameInputs {
            doc,
            camera: &camera,
            quality: &view.quality,
            target,
        };
        self.frame(device, queue, &inputs, SceneUpload::Changed)
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

    fn frame(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &FrameInputs<'_>,
        upload: SceneUpload,
    ) -> Result<GpuFrameStats, GpuError> {
        let FrameInputs {
            doc,
            camera,
            quality,
            target: _,
        } = *inputs;
        doc.validate()?;
        camera.validate()?;
        quality.validate()?;
        let t_start = Instant::now();
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let result: Result<GpuFrameStats, GpuError> = (|| {
            let refreshed = match upload {
                SceneUpload::Full => None,
                SceneUpload::Changed => self
                    .scene
                    .as_mut()
                    .and_then(|s| s.refresh(device, queue, doc)),
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
            let mut stats = self.encode_and_run(device, queue, inputs, &skin)?;
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
    pub fn measure_splat_bandwidth(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        doc: &Document,
        view: &View,
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
        let camera = view_camera(doc, view, target)?;
        self.splat_probe = Some(repeats);
        self.splat_probe_result = None;
        let inputs = FrameInputs {
            doc,
            camera: &camera,
            quality: &view.quality,
            target,
        };
        let stats = self.frame(device, queue, &inputs, SceneUpload::Changed);
        self.splat_probe = None;
        let measured = self.splat_probe_result.take();
        let stats = stats?;
        let measured = measured.ok_or_else(|| {
            GpuError::Device("the frame ended before its voxel pass was measured".into())
        })??;
        Ok((stats, measured))
    }

    /// Bytes of the per-frame buffers and textures held (key buffers, G-buffer, queues,
    /// shadow maps, the supersampled frame's samples target; not the scene's pools): what a
    /// larger image or [`Quality::supersample`] costs in device memory.
    #[must_use]
    pub fn frame_bytes(&self) -> u64 {
        // The samples target is RGBA8.
        self.pool.bytes() + 4 * self.supersample.samples_texels()
    }

    /// The last frame's G-buffer (at the supersampled size, `last_size`).
    fn last_gbuffer(&self) -> Result<wgpu::Buffer, GpuError> {
        self.pool
            .peek("gbuffer", 0)
            .cloned()
            .filter(|_| self.last_size.0 > 0)
            .ok_or_else(|| GpuError::Readback("no frame rendered yet".into()))
    }

    /// Reads the last frame's depth back at its image size: for a supersampled frame only the
    /// rows holding each pixel's kept sample (the one [`Renderer::read_gbuffer`] keeps) are
    /// copied, so the staging buffer is `k` times the image's texels, not `k²`; only depth is
    /// decoded. NDC depth per pixel, row by row from the top; `INFINITY` where nothing was
    /// drawn. The editor hides its overlay lines behind it.
    ///
    /// # Errors
    /// [`GpuError::Readback`] when nothing was rendered yet or mapping fails.
    pub fn read_depth(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<(u32, u32, Vec<f32>), GpuError> {
        let (big_w, big_h) = self.last_size;
        let k = self.last_samples_per_side.max(1);
        let gbuf = self.last_gbuffer()?;
        let (w, h) = (big_w / k, big_h / k);
        let row_bytes = u64::from(big_w) * GBUFFER_TEXEL_BYTES;
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("depth readback"),
            size: (row_bytes * u64::from(h)).max(GBUFFER_TEXEL_BYTES),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        for y in 0..u64::from(h) {
            let big_row = y * u64::from(k) + u64::from(k / 2);
            enc.copy_buffer_to_buffer(
                &gbuf,
                big_row * row_bytes,
                &staging,
                y * row_bytes,
                row_bytes,
            );
        }
        queue.submit([enc.finish()]);
        let raw = map_read(device, &staging)?;
        let texels: &[[u32; 4]] = bytemuck::cast_slice(&raw);
        let (big_w, k) = (big_w as usize, k as usize);
        let depth = (0..h as usize)
            .flat_map(|y| (0..w as usize).map(move |x| y * big_w + x * k + k / 2))
            .map(|i| match texels.get(i) {
                Some(t) if t[3] != u32::MAX => f32::from_bits(t[3]),
                _ => f32::INFINITY,
            })
            .collect();
        Ok((w, h, depth))
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
        let gbuf = self.last_gbuffer()?;
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
        Ok(decimate(g, self.last_samples_per_side))
    }

    /// One frame after the scene and skin are up to date: plan, prepare, encode, submit and
    /// (unless asynchronous) read the counters back.
    fn encode_and_run(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &FrameInputs<'_>,
        skin: &SkinFrame,
    ) -> Result<GpuFrameStats, GpuError> {
        let probe = self.splat_probe.take();
        let created = self.created.clone();
        let gpu = Gpu::new(device, queue, &created);
        let prepared = self.prepare_passes(gpu, inputs, skin)?;
        if self.caps.timestamps && self.timestamps.is_none() {
            self.timestamps = Some(gpu.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: MAX_TIMED_PASSES * 2,
            }));
        }
        let mut ts = self.timestamps.clone().map(|set| Timestamps {
            set,
            used: Vec::new(),
        });
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("frame"),
        });
        self.encode_passes(&mut enc, &mut ts, &prepared);
        // The splat-bandwidth measurement: the view's voxel pass alone, in submissions of its
        // own before the frame's (which then redoes every state the measurement changed).
        if let Some(repeats) = probe {
            self.splat_probe_result = Some(self.measure_probe(gpu, &prepared, repeats));
        }
        self.submit_and_read(gpu, enc, ts.as_ref(), &prepared)
    }

    /// Plans the frame and prepares every pass: this frame's uniforms written, bind groups
    /// kept unless what they bind changed.
    fn prepare_passes(
        &mut self,
        gpu: Gpu<'_>,
        inputs: &FrameInputs<'_>,
        skin: &SkinFrame,
    ) -> Result<Prepared, GpuError> {
        let FrameInputs {
            doc,
            camera,
            quality,
            target,
        } = *inputs;
        let path = self.atomic_path();
        let scene = self
            .scene
            .as_ref()
            .ok_or_else(|| GpuError::Device("no scene uploaded".into()))?;
        if skin.data_bufs.len() != scene.chunks.len() {
            return Err(GpuError::Device(
                "skin data does not follow the pool chunks".into(),
            ));
        }
        let mut frame_objects = scene.frame_objects(doc);
        skin.apply(scene, &mut frame_objects);
        // KRS objects: traced after resolve into the same G-buffer (see gpu/krs.rs).
        let krs_scene = super::krs::prepared_krs(doc)?;
        // Supersampled, every pass draws an image k times the target's size (the same view),
        // which the supersample pass then filters down: the CPU's `render_supersampled`.
        let k = samples_per_side(
            target.width,
            target.height,
            quality.supersample,
            gpu.device.limits().max_texture_dimension_2d,
        );
        let drawn = (target.width * k, target.height * k);
        let plan = FramePlan::new(
            camera,
            drawn,
            quality,
            &PlanScene {
                lights: &doc.lights,
                bounds: frame_objects.bounds,
                voxel_objects: scene.voxels.len(),
                triangles: scene.tri_count,
                caster_triangles: scene.caster_tris,
                krs: krs_scene.is_some(),
                kept_shadow_slot: self.shadow_slot,
            },
            path,
            PlanLimits::of(&gpu.device.limits()),
        )?;
        if let Some(slot) = plan.shadow_slot {
            self.shadow_slot = slot;
        }
        let pool = &mut self.pool;
        let bufs = FrameBuffers::prepare(
            pool,
            gpu,
            &plan,
            quality,
            bytemuck::cast_slice(&frame_objects.objects),
            scene.queue_capacity,
        );
        self.clear.prepare(gpu, pool, &plan, &bufs);
        self.hiz.prepare(gpu, &plan, &bufs);
        self.traverse
            .prepare(gpu, pool, &plan, &bufs, (scene, &frame_objects, skin));
        self.mesh.prepare(gpu, &plan, &bufs, scene);
        self.resolve.prepare(gpu, pool, &plan, &bufs, (scene, skin));
        if krs_scene.is_some() && self.krs.is_none() {
            self.krs = Some(super::krs::KrsPipelines::new(gpu.device)?);
        }
        let krs = match (&mut self.krs, &krs_scene) {
            (Some(k), Some(s)) => Some(k.prepare(
                gpu,
                pool,
                &super::krs::KrsInputs {
                    scene: s,
                    doc,
                    quality,
                    cam: &plan.camera,
                    size: plan.size(),
                    bindings: super::krs::KrsBindings {
                        view: &bufs.view,
                        gbuffer: &bufs.gbuffer,
                        counters: &bufs.counters,
                    },
                },
            )?),
            _ => None,
        };
        // Ambient occlusion as the CPU's `render_scene`: radius from the scene bounds the shadow
        // map is fitted to, grown by the bounded KRS objects' balls (0 without bounds: no
        // sample can then be occluded, and none is taken).
        let ao_radius = thicket_core::render::ao_radius_world(match &krs_scene {
            Some(k) => thicket_core::render::with_krs_bounds(frame_objects.bounds, k),
            None => frame_objects.bounds,
        });
        let samples =
            self.supersample
                .prepare(gpu, pool, k, (target.width, target.height), &target.view);
        let shade_inputs = ShadeInputs {
            doc,
            quality,
            ao_radius,
            krs: krs.as_ref().map(|k| (&k.light_buf, k.stride)),
            target: samples.as_ref().unwrap_or(&target.view),
        };
        self.shade.prepare(gpu, pool, &plan, &bufs, &shade_inputs);
        self.last_size = drawn;
        self.last_samples_per_side = k;
        Ok(Prepared {
            plan,
            counters: bufs.counters.clone(),
            krs,
            triangles: scene.tri_count,
        })
    }

    /// Every pass, in order: clear → shadow maps (meshes, voxels) → the view (meshes and
    /// voxels, twice on the two-pass path) → resolve → KRS → shade.
    fn encode_passes(
        &self,
        enc: &mut wgpu::CommandEncoder,
        ts: &mut Option<Timestamps>,
        prepared: &Prepared,
    ) {
        let plan = &prepared.plan;
        let key64 = plan.path == AtomicPath::Key64;
        enc.clear_buffer(&prepared.counters, 0, None);
        self.clear.encode(enc, ts);
        self.mesh.encode_shadows(enc, ts);
        self.traverse
            .encode(enc, ts, "shadow voxels", Views::Shadows, false, None);
        let hiz = plan.passes.hiz.then_some(&self.hiz);
        self.mesh.encode_view(enc, ts, key64, false);
        self.traverse
            .encode(enc, ts, "voxels", Views::Main, key64, hiz);
        if plan.passes.id_pass {
            self.mesh.encode_view(enc, ts, false, true);
            self.traverse
                .encode(enc, ts, "voxels", Views::MainId, false, None);
        }
        self.resolve.encode(enc, ts);
        if let (Some(k), Some(krs)) = (&prepared.krs, &self.krs) {
            for (name, trace) in [("krs trace", true), ("krs light", false)] {
                let mut pass = super::passes::compute_pass(enc, ts, name);
                if trace {
                    krs.trace(&mut pass, k);
                } else {
                    krs.light(&mut pass, k);
                }
            }
        }
        self.shade.encode(enc, ts);
        self.supersample.encode(enc, ts);
    }

    /// The splat-bandwidth measurement of the view's voxel pass (see [`super::splat_bw`]).
    fn measure_probe(
        &self,
        gpu: Gpu<'_>,
        prepared: &Prepared,
        repeats: u32,
    ) -> Result<super::splat_bw::SplatBandwidth, GpuError> {
        let plan = &prepared.plan;
        if plan.path != AtomicPath::Key64 {
            return Err(GpuError::Device(
                "the splat bandwidth is measured on the 64-bit splat path only".into(),
            ));
        }
        let hiz = plan.passes.hiz.then_some(&self.hiz);
        let counters = &prepared.counters;
        let restore = |enc: &mut wgpu::CommandEncoder| {
            enc.clear_buffer(counters, 0, None);
            self.clear.encode_view_only(enc);
            self.mesh.encode_view(enc, &mut None, true, false);
        };
        let splat = |enc: &mut wgpu::CommandEncoder, set: Option<&wgpu::QuerySet>| {
            let mut ts = set.map(|s| Timestamps {
                set: s.clone(),
                used: Vec::new(),
            });
            self.traverse
                .encode(enc, &mut ts, "voxels", Views::Main, true, hiz);
        };
        let (device, queue) = (gpu.device, gpu.queue);
        let read_counters = || {
            let staging = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("splat bandwidth counters"),
                size: COUNTER_BYTES,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut e = device.create_command_encoder(&Default::default());
            e.copy_buffer_to_buffer(counters, 0, &staging, 0, COUNTER_BYTES);
            queue.submit([e.finish()]);
            let meta = FrameMeta {
                frame: 0,
                timed: Vec::new(),
                triangles: 0,
                atomic_path: plan.path,
                period_ns: 0.0,
            };
            let d = decode_counters(&map_read(device, &staging)?, &meta);
            Ok((d.levels, d.splat_pixels))
        };
        let builds = if hiz.is_some() {
            let travs = self.traverse.main_traversals();
            travs.iter().map(|t| u64::from(t.depth) + 1).sum()
        } else {
            0
        };
        let (width, height) = plan.size();
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
                width,
                height,
            },
            self.caps.timestamps,
        )
    }

    /// Copies the counters and timestamps to a free staging slot, submits, and returns the
    /// frame's statistics: its own counters once they arrive, or with asynchronous readback
    /// the newest that have.
    fn submit_and_read(
        &mut self,
        gpu: Gpu<'_>,
        mut enc: wgpu::CommandEncoder,
        ts: Option<&Timestamps>,
        prepared: &Prepared,
    ) -> Result<GpuFrameStats, GpuError> {
        let (device, queue) = (gpu.device, gpu.queue);
        let path = prepared.plan.path;
        // Counters and timestamps go to a free staging slot of the ring; with no free slot
        // (async readback running behind), this frame's counters are skipped rather than
        // waited for.
        let slot = self.readback.free_slot(gpu);
        if let Some(slot) = slot {
            let staging = self.readback.slots[slot].buffer.clone();
            enc.copy_buffer_to_buffer(&prepared.counters, 0, &staging, 0, COUNTER_BYTES);
            if let Some(t) = ts.filter(|t| !t.used.is_empty()) {
                let n = t.used.len() as u32 * 2;
                let resolve = self.pool.get(
                    gpu,
                    "timestamp resolve",
                    0,
                    u64::from(MAX_TIMED_PASSES * 2) * 8,
                    wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                );
                enc.resolve_query_set(&t.set, 0..n, &resolve, 0);
                enc.copy_buffer_to_buffer(&resolve, 0, &staging, COUNTER_BYTES, u64::from(n) * 8);
            }
        }
        queue.submit([enc.finish()]);
        self.frame_index += 1;
        let triangles = u64::from(prepared.triangles);
        let meta = FrameMeta {
            frame: self.frame_index,
            timed: ts
                .map(|t| t.used.iter().map(|u| (u.name, u.first_query)).collect())
                .unwrap_or_default(),
            triangles,
            atomic_path: path,
            period_ns: f64::from(queue.get_timestamp_period()),
        };
        let mut stats = GpuFrameStats {
            triangles,
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
    fn free_slot(&mut self, gpu: Gpu<'_>) -> Option<usize> {
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
            buffer: gpu.create_buffer(&wgpu::BufferDescriptor {
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

/// The camera `view` looks through, once its size is checked against `target`'s.
fn view_camera(
    doc: &Document,
    view: &View,
    target: &RenderTarget,
) -> Result<OrbitCamera, GpuError> {
    if [view.width, view.height] != [target.width, target.height] {
        return Err(GpuError::ViewSize {
            view: [view.width, view.height],
            target: [target.width, target.height],
        });
    }
    Ok(view.orbit_camera(doc))
}

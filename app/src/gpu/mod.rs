//! The wgpu renderer (ASVO paper §4, Fig. 8; §8.1): the same algorithms as the CPU reference
//! renderer in `thicket_core::render`, on the GPU, headless-capable.
//!
//! A frame (see `docs/gpu.md`): clear the packed depth+id key buffers → one shadow map per
//! shadow-casting light (meshes rasterised, voxels traversed, depth only) → the view:
//! meshes rasterised and voxels splatted into one key buffer (64-bit `atomicMin` of
//! `depth << 32 | id` when the adapter has `SHADER_INT64_ATOMIC_MIN_MAX`, else two 32-bit
//! passes) → resolve ids to a G-buffer → KRS objects sphere-traced into the same G-buffer
//! ([`krs`]) → deferred Phong with PCF shadows → RGBA8 target.
//!
//! - [`context`]: headless device creation and error handlers.
//! - [`Renderer`]: pipelines and layouts created once; [`Renderer::render`] per frame.
//! - [`render_document_to_image`]: one call for the CLI (creates its own device).

pub mod context;
pub mod gpu_data;
pub mod krs;
mod passes;
mod renderer;
mod scene;
pub mod shaders;
mod skin;
pub mod splat_bw;

pub use context::{Capabilities, ErrorSlot, GpuContext};
pub use renderer::{GBuffer, RenderTarget, Renderer, read_rgba8};
pub use scene::{UploadStats, voxel_pool_bytes};

use thicket_core::quality::QualityError;
use thicket_core::render::View;
use thicket_core::scene::{Document, SceneError};

/// Why the GPU could not render.
#[derive(Debug, Clone, PartialEq)]
pub enum GpuError {
    /// No adapter on the Vulkan or GL backends.
    NoAdapter(String),
    /// The adapter refused the device.
    RequestDevice(String),
    /// A validation or internal error reported by wgpu.
    Device(String),
    /// The device ran out of memory.
    OutOfMemory(String),
    /// The device was lost (driver reset, removal).
    DeviceLost(String),
    /// A WGSL file is missing or its imports are broken.
    Shader(String),
    /// Reading a buffer back failed.
    Readback(String),
    /// The image size is zero or above the device's texture limit.
    BadSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// The device's limit.
        max: u32,
    },
    /// Scene data does not fit a buffer binding.
    TooLarge {
        /// Which buffer.
        what: &'static str,
        /// Bytes needed.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// One voxel object's pool does not fit a buffer binding by itself (pools are split into
    /// chunks of whole objects, so every object must fit one binding alone).
    ObjectTooLarge {
        /// The object's name.
        object: String,
        /// Which of its pools.
        what: &'static str,
        /// Bytes the pool needs (spare room for edits included).
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// The document holds a value a renderer must not see.
    InvalidDocument(SceneError),
    /// A quality knob is out of range.
    InvalidQuality(QualityError),
    /// The view's size is not the target's.
    ViewSize {
        /// The view's size.
        view: [u32; 2],
        /// The target's size.
        target: [u32; 2],
    },
}

// Written out because the app crate does not depend on `thiserror`.
impl std::fmt::Display for GpuError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoAdapter(e) => write!(
                f,
                "no GPU adapter found (Vulkan or GL; a software driver such as lavapipe works): {e}"
            ),
            Self::RequestDevice(e) => write!(f, "could not create the GPU device: {e}"),
            Self::Device(e) => write!(f, "GPU error: {e}"),
            Self::OutOfMemory(e) => write!(f, "GPU out of memory: {e}"),
            Self::DeviceLost(e) => write!(f, "GPU device lost: {e}"),
            Self::Shader(e) => write!(f, "shader: {e}"),
            Self::Readback(e) => write!(f, "reading GPU data back failed: {e}"),
            Self::BadSize { width, height, max } => write!(
                f,
                "image size {width}×{height} is not renderable (1..={max} pixels per edge)"
            ),
            Self::TooLarge { what, bytes, limit } => write!(
                f,
                "{what} needs {bytes} bytes, above this device's limit of {limit} bytes per binding"
            ),
            Self::ObjectTooLarge {
                object,
                what,
                bytes,
                limit,
            } => write!(
                f,
                "voxel object \"{object}\": its {what} needs {bytes} bytes, above this device's \
                 limit of {limit} bytes per binding (objects are split across bindings, but one \
                 object must fit a binding alone)"
            ),
            Self::InvalidDocument(e) => write!(f, "cannot render the document: {e}"),
            Self::InvalidQuality(e) => write!(f, "cannot render with these quality settings: {e}"),
            Self::ViewSize { view, target } => write!(
                f,
                "the view is {}×{} pixels but its target {}×{}",
                view[0], view[1], target[0], target[1]
            ),
        }
    }
}

impl std::error::Error for GpuError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::InvalidDocument(e) => Some(e),
            Self::InvalidQuality(e) => Some(e),
            _ => None,
        }
    }
}

impl From<SceneError> for GpuError {
    fn from(e: SceneError) -> Self {
        Self::InvalidDocument(e)
    }
}

impl From<QualityError> for GpuError {
    fn from(e: QualityError) -> Self {
        Self::InvalidQuality(e)
    }
}

/// Which splat path a frame used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AtomicPath {
    /// One 64-bit `atomicMin` of (depth << 32 | id).
    #[default]
    Key64,
    /// Two passes of 32-bit atomics (depth, then id where the depth matches).
    TwoPass32,
}

/// Counters for one octree level (summed over objects): the same counters as the CPU
/// reference renderer's, so overlays and benches read both alike.
pub type GpuLevelStats = thicket_core::render::LevelStats;

/// What a GPU frame did and how long it took.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GpuFrameStats {
    /// View traversal counters per level.
    pub levels: Vec<GpuLevelStats>,
    /// Shadow-map traversal counters per level.
    pub shadow_levels: Vec<GpuLevelStats>,
    /// Splats drawn in the view (sum of `levels[..].splatted`).
    pub splats: u64,
    /// Children dropped because a traversal queue was full (0 unless the scene is huge).
    pub queue_overflow: u64,
    /// Pixels covered by the view's voxel splats: the key atomics its traversal issued (the
    /// depth pass's on the two-pass path).
    pub splat_pixels: u64,
    /// Pixels the view's exact cubes tested (one ray–box test each, included in
    /// `splat_pixels`).
    pub cube_pixels: u64,
    /// Triangles submitted for the view.
    pub triangles: u64,
    /// Milliseconds per pass: GPU timestamps when `gpu_timestamps`, else empty.
    pub pass_ms: Vec<(&'static str, f64)>,
    /// Whether `pass_ms` comes from timestamp queries.
    pub gpu_timestamps: bool,
    /// CPU-side milliseconds from the start of encoding to the end of the wait.
    pub total_ms: f64,
    /// The splat path used.
    pub atomic_path: AtomicPath,
    /// This frame's number (1 for a renderer's first frame).
    pub frame: u64,
    /// The frame the counters and timings came from: this frame when waiting, an earlier one
    /// (or `None` before any arrived) with asynchronous readback.
    pub counters_frame: Option<u64>,
    /// What the frame uploaded before drawing.
    pub upload: UploadStats,
    /// Counters of the KRS pass (zero without KRS objects).
    pub krs: krs::GpuKrsStats,
}

impl GpuFrameStats {
    /// Copies counters and timings from a decoded frame (asynchronous readback).
    pub(crate) fn fill_counters_from(&mut self, from: &Self) {
        self.levels.clone_from(&from.levels);
        self.shadow_levels.clone_from(&from.shadow_levels);
        self.splats = from.splats;
        self.queue_overflow = from.queue_overflow;
        self.splat_pixels = from.splat_pixels;
        self.cube_pixels = from.cube_pixels;
        self.krs = from.krs;
        self.pass_ms.clone_from(&from.pass_ms);
        self.gpu_timestamps = from.gpu_timestamps;
        self.counters_frame = from.counters_frame;
    }
}

/// Renders a document on a fresh headless device (for the CLI): returns the sRGB RGBA8 image
/// (row-major, top row first) and the frame's statistics.
///
/// # Errors
/// [`GpuError`] when there is no adapter, the document or quality is invalid, or the GPU fails.
pub fn render_document_to_image(
    doc: &Document,
    view: &View,
) -> Result<(Vec<u8>, GpuFrameStats), GpuError> {
    let ctx = GpuContext::new_headless(wgpu::PowerPreference::HighPerformance)?;
    render_with_context(&ctx, doc, view)
}

/// Renders a document with an existing context (tests and benches reuse one device).
///
/// # Errors
/// As [`render_document_to_image`].
pub fn render_with_context(
    ctx: &GpuContext,
    doc: &Document,
    view: &View,
) -> Result<(Vec<u8>, GpuFrameStats), GpuError> {
    let mut renderer = Renderer::new(&ctx.device, &ctx.queue)?;
    let target = RenderTarget::new(&ctx.device, view.width, view.height)?;
    let stats = renderer.render(&ctx.device, &ctx.queue, doc, view, &target)?;
    let image = read_rgba8(&ctx.device, &ctx.queue, &target)?;
    if let Some(e) = ctx.errors.take() {
        return Err(e);
    }
    Ok((image, stats))
}

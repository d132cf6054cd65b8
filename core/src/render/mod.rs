//! CPU reference renderers (ASVO paper §4, Fig. 8, Fig. 10, §8.1), multi-threaded with rayon.
//!
//! A frame: shadow maps (one per shadow-casting light, orthographic, fit to the scene) →
//! triangles into the view's packed depth+id target → voxel objects by the breadth-first ASVO
//! traversal into the same target → KRS objects by sphere tracing into the same target →
//! resolve ids to a G-buffer → deferred Phong (shadow maps for voxel and mesh casters, shadow
//! rays for KRS casters). Depth is NDC z (0 near, 1 far, as `clip_from_world`); see
//! `docs/rendering.md` for the conventions a GPU renderer must match.
//!
//! Entry points: [`render_document`] for a [`Document`], [`render_scene`] for callers that bring
//! their own per-node transform ([`NodeDeform`], e.g. skinning), [`render_scene_with_krs`] to
//! add KRS objects to such a scene. A caller that draws frame after frame keeps a [`Renderer`]
//! instead: it owns every frame buffer, so a steady-state frame allocates nothing.

mod asvo;
mod buffers;
mod camera;
mod krs;
mod raster;
mod sampled;
pub mod scenes;
pub mod shade;
mod stats;

#[cfg(test)]
mod krs_tests;
#[cfg(test)]
mod patch_tests;
#[cfg(test)]
mod renderer_tests;
#[cfg(test)]
mod supersample_tests;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tile_tests;

use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;

pub use asvo::{FACE_BITS, VoxelInstance};
pub use buffers::{FrameBuffers, ImageError, PixelId, RgbaImage};
pub use camera::{Camera, Projection};
pub use krs::{
    AO_REACH_OBJECT_UNITS, KRS_TILE, KrsLayer, KrsStats, SMOOTHING_PX, SOFT_SHADOW_K,
    trace_settings,
};
pub use raster::MeshInstance;
pub use stats::{FrameStats, LevelStats, ShadingStats, StageTimes};

use crate::deform::{NodeDeform, RigidDeform};
use crate::quality::{Quality, QualityError};
use crate::scene::{Document, Light, ObjectKind, OrbitCamera, SceneError};

/// Largest accepted image edge in pixels.
pub const MAX_IMAGE_SIZE: u32 = 16384;

/// Ambient-occlusion sample radius as a fraction of the scene bounds' diagonal (voxels, meshes
/// and the bounding balls of bounded KRS objects): scale-free, so a house of 128 voxel units
/// and a 2-unit sphere get the same look.
pub const AO_RADIUS_OF_SCENE: f32 = 0.05;

/// The screen-space AO radius in world units for a scene whose drawn content has `bounds`
/// (0 when there are none: AO then has nothing to sample and costs nothing). Both renderers
/// use this, so their AO kernels agree.
#[must_use]
pub fn ao_radius_world(bounds: Option<(Vec3, Vec3)>) -> f32 {
    bounds.map_or(0.0, |(lo, hi)| {
        let r = AO_RADIUS_OF_SCENE * (hi - lo).length();
        if r.is_finite() { r } else { 0.0 }
    })
}

/// `bounds` grown by the world bounding balls of a prepared KRS scene's bounded objects
/// (unbounded ones, such as an endless ground, add nothing: they have no size to scale by).
#[must_use]
pub fn with_krs_bounds(
    bounds: Option<(Vec3, Vec3)>,
    scene: &crate::krs::PreparedScene,
) -> Option<(Vec3, Vec3)> {
    scene
        .objects
        .iter()
        .filter(|o| !o.is_empty)
        .filter_map(|o| o.bound_world)
        .filter(|(c, r)| c.is_finite() && r.is_finite())
        .fold(bounds, |b, (c, r)| {
            let (lo, hi) = (c - Vec3::splat(r), c + Vec3::splat(r));
            Some(b.map_or((lo, hi), |(a, z)| (a.min(lo), z.max(hi))))
        })
}

/// Ids with this bit set are triangles; below it, voxel splats.
pub(crate) const MESH_ID_FLAG: u32 = 1 << 31;

/// Why a frame could not be rendered.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// Width or height is zero.
    #[error("image size {width}×{height} is empty: both edges must be at least 1 pixel")]
    ZeroSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// Width or height is above [`MAX_IMAGE_SIZE`].
    #[error(
        "image size {width}×{height} is too large: the limit is {MAX_IMAGE_SIZE} pixels per edge"
    )]
    TooLarge {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// The document has a value a renderer must not see.
    #[error("cannot render the document: {0}")]
    InvalidDocument(#[from] SceneError),
    /// A quality knob is out of range.
    #[error("cannot render with these quality settings: {0}")]
    InvalidQuality(#[from] QualityError),
    /// Another renderer behind the same interface failed (the GPU renderer in a sweep: its
    /// device, driver or limits); the text says what and where.
    #[error("the {renderer} renderer failed: {message}")]
    Backend {
        /// Which renderer.
        renderer: &'static str,
        /// Its error, as text.
        message: String,
    },
}

/// A view of a document: image size, camera and quality. Both renderers take one (the CPU
/// renderer here, the GPU renderer in the app): `(document, &View, target)`.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Image width in pixels (1..=16384).
    pub width: u32,
    /// Image height in pixels (1..=16384).
    pub height: u32,
    /// The view; `None` uses the document's camera.
    pub camera: Option<OrbitCamera>,
    /// Quality knobs (the document's own are ignored: the caller decides).
    pub quality: Quality,
}

impl View {
    /// A view at a size with the document's camera and the default quality.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            camera: None,
            quality: Quality::default(),
        }
    }

    /// The camera it looks through: its own, or the document's.
    #[must_use]
    pub fn orbit_camera(&self, doc: &Document) -> OrbitCamera {
        self.camera.unwrap_or(doc.camera)
    }
}

/// A scene as the renderer sees it: instances with their transforms resolved.
pub struct RenderScene<'a> {
    /// Voxel objects.
    pub voxels: Vec<VoxelInstance<'a>>,
    /// Triangle-mesh objects.
    pub meshes: Vec<MeshInstance<'a>>,
    /// Directional lights.
    pub lights: &'a [Light],
    /// Linear RGB ambient light.
    pub ambient: Vec3,
    /// Linear RGB background.
    pub background: Vec3,
}

/// Heap bytes a CPU frame holds per image pixel at its peak, besides the shadow maps: the depth
/// target's keys and depths, the G-buffer (depth, ids, normal, albedo), the shading buffers and
/// the image, with the per-splat references of an ordinary view. Measured with a counting
/// allocator on the samples (`the_render_estimate_holds_the_measured_peak_without_overstating_it`).
const FRAME_BYTES_PER_PIXEL: u64 = 120;
/// Heap bytes per shadow-map texel: the light's depth target while it is drawn and the map kept.
const SHADOW_BYTES_PER_TEXEL: u64 = 24;
/// Scene-side allocations that do not grow with the image (instance lists, triangle lists).
const FRAME_BYTES_FIXED: u64 = 4 << 20;
/// The estimate fits its shadow maps to a texel this much finer than the render does, so a
/// scene box a little larger than the document's bounds (a skinned pose) stays inside it.
const SHADOW_TEXEL_MARGIN: f32 = 1.25;

/// An upper estimate of the heap a CPU render of `req` holds at its peak, so a request can be
/// refused before it allocates (see [`crate::budget`]): the image's buffers, and each
/// shadow-casting light's map fitted as the render fits it (to the voxel and mesh objects'
/// bounds, at most `shadow_map_size`² texels). It does not count the document itself, which
/// is already in memory. An invalid camera or size gives the image buffers alone (the render
/// refuses those anyway).
#[must_use]
pub fn estimate_peak_bytes(doc: &Document, req: &View) -> u64 {
    let quality = &req.quality;
    // A supersampled frame draws its samples as an image k times the size.
    let k = supersample_factor(req.width, req.height, quality.supersample);
    let (width, height) = (req.width.saturating_mul(k), req.height.saturating_mul(k));
    let pixels = u64::from(width) * u64::from(height);
    let orbit = req.orbit_camera(doc);
    let mut texels = 0u64;
    if quality.shadows && orbit.validate().is_ok() && width > 0 && height > 0 {
        let cam = Camera::from_orbit(&orbit, width, height);
        let bounds = doc
            .objects
            .iter()
            .filter(|o| o.visible && !matches!(o.kind, ObjectKind::Krs(_)))
            .filter_map(crate::scene::Object::world_bounds)
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)));
        if let Some((lo, hi)) = bounds.filter(|(lo, hi)| lo.is_finite() && hi.is_finite()) {
            let finest = finest_shadow_texel(&cam, lo, hi) / SHADOW_TEXEL_MARGIN;
            for light in doc.lights.iter().filter(|l| l.casts_shadows) {
                let size = shade::fit_light_camera(
                    light.direction,
                    lo,
                    hi,
                    quality.shadow_map_size,
                    finest,
                )
                .map_or(u64::from(quality.shadow_map_size).pow(2), |c| {
                    u64::from(c.width) * u64::from(c.height)
                });
                texels += size;
            }
        }
    }
    FRAME_BYTES_FIXED
        .saturating_add(pixels.saturating_mul(FRAME_BYTES_PER_PIXEL))
        .saturating_add(texels.saturating_mul(SHADOW_BYTES_PER_TEXEL))
}

/// The samples per pixel side a frame of `width`×`height` draws for
/// [`Quality::supersample`] `k`: `k`, or less where `k` times the image would exceed
/// [`MAX_IMAGE_SIZE`] (at least 1).
#[must_use]
pub fn supersample_factor(width: u32, height: u32, k: u32) -> u32 {
    let fits = MAX_IMAGE_SIZE / width.max(height).max(1);
    k.min(fits).max(1)
}

fn check_size(width: u32, height: u32) -> Result<(), RenderError> {
    if width == 0 || height == 0 {
        return Err(RenderError::ZeroSize { width, height });
    }
    if width > MAX_IMAGE_SIZE || height > MAX_IMAGE_SIZE {
        return Err(RenderError::TooLarge { width, height });
    }
    Ok(())
}

/// Renders a document: validates it, places every visible object with its rigid transform and
/// renders with [`render_scene`]. A temporary [`Renderer`]: callers that draw frame after frame
/// keep one instead.
///
/// # Errors
/// [`RenderError`] for an empty or oversized image, an invalid document, camera or quality.
pub fn render_document(
    doc: &Document,
    req: &View,
) -> Result<(RgbaImage, FrameBuffers, FrameStats), RenderError> {
    let mut r = Renderer::new();
    r.render_document_inner(doc, req, None, true)?;
    Ok(r.take_frame())
}

/// [`render_document`] for a viewer that renders one document again and again while its camera
/// moves (the editor's CPU preview): shadow maps are taken from `cache` when nothing they depend
/// on changed (see [`ShadowCache`]). `content_key` must change whenever the document's content
/// does (its objects, their voxels, transforms, rigs or playback time); the caller vouches for
/// that, since comparing millions of voxels would cost more than the shadow map.
///
/// # Errors
/// As [`render_document`].
pub fn render_document_cached(
    doc: &Document,
    req: &View,
    cache: &mut ShadowCache,
    content_key: u64,
) -> Result<(RgbaImage, FrameBuffers, FrameStats), RenderError> {
    let mut r = Renderer::new();
    r.render_document_inner(doc, req, Some((cache, content_key)), true)?;
    Ok(r.take_frame())
}

/// A frame a [`Renderer`] drew, borrowed from it until its next frame.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    /// The shaded sRGB image.
    pub image: &'a RgbaImage,
    /// The resolved G-buffer.
    pub buffers: &'a FrameBuffers,
    /// What the frame cost.
    pub stats: &'a FrameStats,
}

/// The CPU renderer with the state it keeps from one frame to the next: the view's depth
/// target and occlusion tiles, the traversal's queues and per-block tables, the G-buffer, the
/// image, each light's shadow map and the light pass's target, the shading pass's kernels.
///
/// Why: every buffer is sized by the image or the shadow map, so a frame that allocated them
/// afresh paid for the allocation and, on a small model, more for the page faults of memory
/// the allocator had returned to the system than for the drawing itself. A renderer grows its
/// buffers when a frame needs more than any before it and never shrinks them, so a frame of a
/// size it has seen allocates nothing (rigid voxel and mesh objects; KRS objects and skinned
/// poses still allocate their own per-frame data). The images are the same as the free
/// functions' ([`render_document`] and friends use a temporary renderer).
#[derive(Default)]
pub struct Renderer {
    /// Where a document is turned into a [`RenderScene`].
    doc: DocumentScratch,
    /// The document's KRS objects prepared for tracing, kept while they do not change.
    krs: KrsCache,
    frame: FrameState,
}

/// A document's visible KRS objects prepared for tracing, and what they were prepared from.
///
/// Why: preparing copies and validates every kernel and mirror list, a few allocations per
/// object each frame; an orbit or playback frame changes none of them.
#[derive(Default)]
struct KrsCache {
    /// What `layer` was prepared from: per visible KRS object of the document, its label, its
    /// KRS and its transform, serialised. Bytes rather than `==`, which takes `-0.0` for `0.0`
    /// where the tracer does not (a kernel's texture frame turns with the sign of a zero).
    source: Vec<u8>,
    /// Whether `layer` was prepared from `source` (not after a failed or unknown one).
    holds_source: bool,
    /// The next document's, written to compare (kept for its allocation).
    probe: Vec<u8>,
    layer: KrsLayer,
}

impl KrsCache {
    /// Writes what `doc`'s visible KRS objects would be prepared from into `out`; false when
    /// it could not be written (then `out` names nothing).
    fn describe(doc: &Document, out: &mut Vec<u8>) -> bool {
        out.clear();
        for (i, o) in doc.objects.iter().enumerate() {
            let ObjectKind::Krs(k) = &o.kind else {
                continue;
            };
            if !o.visible {
                continue;
            }
            out.extend_from_slice(&(i as u32 + 1).to_le_bytes());
            // Writing into a `Vec` cannot fail, and these types serialise without error (a
            // NaN is written as null, and fails validation before a frame is drawn). An error
            // would only make the next frame prepare again.
            if serde_json::to_writer(&mut *out, k).is_err()
                || serde_json::to_writer(&mut *out, &o.transform).is_err()
            {
                return false;
            }
            out.push(b'\n');
        }
        true
    }

    /// Prepares `doc`'s visible KRS objects unless they are the ones already prepared.
    fn update(&mut self, doc: &Document) -> Result<(), RenderError> {
        let known = Self::describe(doc, &mut self.probe);
        if known && self.holds_source && self.probe == self.source {
            return Ok(());
        }
        std::mem::swap(&mut self.source, &mut self.probe);
        self.holds_source = false;
        let mut objects = Vec::new();
        let mut labels = Vec::new();
        for (i, o) in doc.objects.iter().enumerate() {
            if !o.visible {
                continue;
            }
            // A transform the KRS cannot take (validation refuses it) draws nothing.
            if let Some(world) = o.krs_in_world() {
                objects.push(world);
                labels.push(i as u32 + 1);
            }
        }
        // Validated with the document, so preparing cannot fail; the error is still reported,
        // never unwrapped.
        let prepared = crate::krs::KrsScene { objects }.prepare().map_err(|e| {
            RenderError::InvalidDocument(SceneError::Invalid {
                what: "krs".into(),
                context: "document".into(),
                detail: e.to_string(),
            })
        });
        match prepared {
            Ok(scene) => {
                self.layer = KrsLayer {
                    scene,
                    labels,
                    casts_shadows: true,
                };
                self.holds_source = known;
                Ok(())
            }
            Err(e) => {
                // Nothing kept: the next frame prepares again.
                self.layer = KrsLayer::default();
                Err(e)
            }
        }
    }
}

/// A document's per-frame scene lists, kept empty between frames (only their capacity).
#[derive(Default)]
struct DocumentScratch {
    /// Per visible rigid voxel object: its transform.
    rigid: Vec<RigidDeform>,
    /// Per visible skinned voxel object: its pose (kept empty between frames, as `voxels`).
    skinned: Vec<crate::skin::SkinDeform<'static>>,
    voxels: Vec<VoxelInstance<'static>>,
    meshes: Vec<MeshInstance<'static>>,
}

/// An empty list of `U` in the allocation of `v` (same size and alignment: the types differ
/// only in lifetimes), so a per-frame list of borrowed instances keeps its capacity from one
/// frame to the next without holding the borrows. The standard library collects a consuming
/// iterator into the source's allocation when the layouts match; where it would not, this
/// allocates a fresh list and the results are the same.
fn recycle<T, U>(mut v: Vec<T>) -> Vec<U> {
    v.clear();
    v.into_iter().filter_map(|_| None).collect()
}

/// The buffers a frame draws into.
#[derive(Default)]
struct FrameState {
    target: buffers::DepthTarget,
    voxels: asvo::VoxelScratch,
    tris: Vec<raster::WorldTriangle>,
    normal_mats: Vec<glam::Mat3>,
    sampled: sampled::SampledTexels,
    /// World boxes of the changes a cached shadow map is patched for (see
    /// [`ShadowCache::note_change`]).
    patch_boxes: Vec<(Vec3, Vec3)>,
    light_pass: shade::ShadowBuffers,
    /// One per light: the map drawn for this frame alone (kept for its allocations).
    own_maps: Vec<Option<shade::ShadowMap>>,
    shadow_use: Vec<shade::ShadowUse>,
    shade: shade::ShadeScratch,
    krs_pass: krs::KrsPass,
    image: RgbaImage,
    fb: FrameBuffers,
    stats: FrameStats,
}

impl Renderer {
    /// A renderer with no buffers yet (the first frame allocates them).
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// [`render_document`] into this renderer's buffers.
    ///
    /// # Errors
    /// As [`render_document`].
    pub fn render_document(
        &mut self,
        doc: &Document,
        req: &View,
    ) -> Result<Frame<'_>, RenderError> {
        self.render_document_inner(doc, req, None, true)?;
        Ok(self.frame())
    }

    /// [`render_document_cached`] into this renderer's buffers.
    ///
    /// # Errors
    /// As [`render_document`].
    pub fn render_document_cached(
        &mut self,
        doc: &Document,
        req: &View,
        cache: &mut ShadowCache,
        content_key: u64,
    ) -> Result<Frame<'_>, RenderError> {
        self.render_document_inner(doc, req, Some((cache, content_key)), true)?;
        Ok(self.frame())
    }

    /// [`render_scene_with_krs`] into this renderer's buffers.
    ///
    /// # Errors
    /// As [`render_scene_with_krs`].
    pub fn render_scene(
        &mut self,
        scene: &RenderScene<'_>,
        krs_layer: &KrsLayer,
        cam: &Camera,
        quality: &Quality,
    ) -> Result<Frame<'_>, RenderError> {
        self.frame
            .render_supersampled(scene, krs_layer, cam, quality, None, true)?;
        Ok(self.frame())
    }

    /// The last frame drawn (empty buffers before the first; unspecified after a frame that
    /// returned an error, until the next one succeeds).
    #[must_use]
    pub fn frame(&self) -> Frame<'_> {
        Frame {
            image: &self.frame.image,
            buffers: &self.frame.fb,
            stats: &self.frame.stats,
        }
    }

    /// Moves the last frame's image, G-buffer and counters out (the next frame allocates them
    /// again): for a caller that keeps them beyond the next frame.
    pub fn take_frame(&mut self) -> (RgbaImage, FrameBuffers, FrameStats) {
        (
            std::mem::take(&mut self.frame.image),
            std::mem::take(&mut self.frame.fb),
            std::mem::take(&mut self.frame.stats),
        )
    }

    /// `sampled_only`: see [`FrameState::render`].
    fn render_document_inner(
        &mut self,
        doc: &Document,
        req: &View,
        cache: Option<(&mut ShadowCache, u64)>,
        sampled_only: bool,
    ) -> Result<(), RenderError> {
        check_size(req.width, req.height)?;
        doc.validate()?;
        req.quality.validate()?;
        let orbit = req.orbit_camera(doc);
        orbit.validate()?;
        let cam = Camera::from_orbit(&orbit, req.width, req.height);

        let DocumentScratch {
            rigid,
            skinned: skinned_kept,
            voxels,
            meshes,
        } = &mut self.doc;
        // Rigid objects' transforms and skinned objects' poses in the renderer's lists.
        rigid.clear();
        let mut skinned: Vec<crate::skin::SkinDeform<'_>> = recycle(std::mem::take(skinned_kept));
        for o in doc.objects.iter().filter(|o| o.visible) {
            if let ObjectKind::Voxels(v) = &o.kind {
                match &v.rig {
                    Some(rig) => skinned.push(skin_deform(o, v, rig, &req.quality)),
                    None => rigid.push(rigid_deform(o, v)),
                }
            }
        }
        let (mut rigid_iter, mut skinned_iter) = (rigid.iter(), skinned.iter());
        let mut scene = RenderScene {
            voxels: recycle(std::mem::take(voxels)),
            meshes: recycle(std::mem::take(meshes)),
            lights: &doc.lights,
            ambient: doc.ambient,
            background: doc.background,
        };
        for (i, o) in doc.objects.iter().enumerate() {
            if !o.visible {
                continue;
            }
            let label = i as u32 + 1;
            match &o.kind {
                ObjectKind::Voxels(v) => {
                    let deform: Option<&dyn NodeDeform> = if v.rig.is_some() {
                        skinned_iter.next().map(|d| d as &dyn NodeDeform)
                    } else {
                        rigid_iter.next().map(|d| d as &dyn NodeDeform)
                    };
                    if let Some(deform) = deform {
                        scene.voxels.push(VoxelInstance {
                            svo: &v.svo,
                            deform,
                            casts_shadows: true,
                            label,
                        });
                    }
                }
                ObjectKind::Mesh(m) => scene.meshes.push(MeshInstance {
                    model: &m.model,
                    world_from_object: o.transform.matrix(),
                    casts_shadows: m.casts_shadows,
                    label,
                }),
                // KRS objects were collected above for the sphere-tracing pass.
                ObjectKind::Krs(_) => {}
            }
        }
        let result = self.krs.update(doc).and_then(|()| {
            self.frame.render_supersampled(
                &scene,
                &self.krs.layer,
                &cam,
                &req.quality,
                cache,
                sampled_only,
            )
        });
        // Hand the lists' allocations back for the next frame.
        *voxels = recycle(scene.voxels);
        *meshes = recycle(scene.meshes);
        // Dropping the poses hands their buffers back to their rigs.
        *skinned_kept = recycle(skinned);
        result
    }
}

/// The transform of a rigid voxel object.
fn rigid_deform(o: &crate::scene::Object, v: &crate::scene::VoxelModel) -> RigidDeform {
    RigidDeform::new(o.transform.matrix() * v.object_from_voxel())
}

/// The per-node transform of a skinned voxel object as the renderers draw it: at its rig's
/// playback clip and time, with the stretch [`effective_stretch`] gives under `quality`. The
/// editor's posed pick and its stretch overlay place nodes with it too, so they agree.
#[must_use]
pub fn skin_deform<'a>(
    o: &'a crate::scene::Object,
    v: &'a crate::scene::VoxelModel,
    rig: &'a crate::skin::Rig,
    quality: &Quality,
) -> crate::skin::SkinDeform<'a> {
    let stretch = effective_stretch(rig, quality);
    crate::skin::SkinDeform::for_rig(
        rig,
        &v.svo,
        o.transform.matrix(),
        v.object_from_voxel(),
        rig.playback.clip,
        rig.playback.time_secs,
    )
    .with_settings(stretch)
}

/// [`render_document`] with every caster drawn into its shadow maps, wherever the shading
/// reads them or not: the reference the sampled-texel maps are tested against.
#[cfg(test)]
pub(crate) fn render_document_full_shadow_maps(
    doc: &Document,
    req: &View,
) -> Result<(RgbaImage, FrameBuffers, FrameStats), RenderError> {
    let mut r = Renderer::new();
    r.render_document_inner(doc, req, None, false)?;
    Ok(r.take_frame())
}

/// How much finer than wanted a cached shadow map may be and still be used, per axis: a map
/// made while the camera was nearer keeps serving as it backs off (its texels are then finer
/// than the view needs, so shadows are at least as sharp as an uncached frame's).
pub const SHADOW_CACHE_MAX_FINER: f32 = 1.6;

/// How much finer than the frame wants a shadow cache renders a map, per axis, so that the
/// next frames can use it while the camera moves: orbiting changes the distance to the
/// scene's nearest point (the bench's near orbit by 16 % from a face of the bounds to an edge),
/// and each step nearer would otherwise render the map again. It costs up to 1.56× the shadow
/// traversal in the frames that render a map.
pub const SHADOW_CACHE_HEADROOM: f32 = 1.25;

/// Shadow maps kept from one frame to the next while only the camera moves.
///
/// Why: a shadow map depends on the light, the casters and the quality, not on the camera,
/// except through its texel size (one texel per view pixel where the scene comes nearest the
/// eye). In the render bench's near 3M-voxel frame the shadow pass is about half the frame.
///
/// A map is reused when the document content key, the lights and the quality are equal to the
/// ones it was made with, its light view is the same, and its texel is no coarser than the
/// frame wants and at most [`SHADOW_CACHE_MAX_FINER`] times finer. Otherwise it is rendered
/// again, [`SHADOW_CACHE_HEADROOM`] times finer than wanted (or at the quality's size limit).
/// So a cached frame can differ from an uncached one only by sharper shadows (a finer map),
/// never by coarser or stale ones. The first frame of a new key (content, lights or quality)
/// keeps nothing: it is drawn exactly as an uncached frame, whose maps hold casters only
/// where its shading reads them, since an edit is often followed by another; the next frame
/// with that key draws the full maps it keeps.
///
/// Except after edits the caller describes ([`Self::note_change`]): when the content went from
/// the maps' key to the frame's through changes inside known world boxes, each map is drawn
/// again only in the texels those boxes can reach from the light (widened by the largest
/// footprint the traversal splats whole), and keeps the rest. Those texels get exactly what a
/// full redraw gives them, so the maps equal freshly drawn ones.
#[derive(Default)]
pub struct ShadowCache {
    key: Option<(u64, Vec<Light>, Quality)>,
    /// One entry per light, as `Lighting::shadows`.
    maps: Vec<Option<Arc<shade::ShadowMap>>>,
    /// Changes since the maps' content key, in order, each starting where the last ended.
    changes: Vec<ContentChange>,
    /// How much finer than wanted a map may be and still be used (`None`:
    /// [`SHADOW_CACHE_MAX_FINER`]).
    max_finer: Option<f32>,
}

/// A change of a document's content from one key to another, all of it inside a world box:
/// what moved, appeared or vanished lies within `lo..=hi` before and after.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContentChange {
    /// Content key before the change.
    pub from: u64,
    /// Content key after it.
    pub to: u64,
    /// World box of everything the change touched (minimum corner).
    pub lo: Vec3,
    /// World box of everything the change touched (maximum corner).
    pub hi: Vec3,
}

/// At most this many changes are remembered between frames; a longer chain redraws whole maps
/// (the boxes would cover most of them anyway).
const MAX_CHANGES: usize = 64;

impl ShadowCache {
    /// An empty cache.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// The cache, using maps up to `factor` times finer per axis than a frame wants (at least
    /// [`SHADOW_CACHE_MAX_FINER`]). A viewer that draws low-resolution frames while the
    /// camera moves sets it to that ratio divided by its resolution scale, so that those
    /// frames use the full-resolution frames' maps instead of drawing coarser ones in turn
    /// with them (their shadows are then sharper than an uncached low-resolution frame's).
    #[must_use]
    pub fn with_max_finer(mut self, factor: f32) -> Self {
        self.max_finer = Some(factor.max(SHADOW_CACHE_MAX_FINER));
        self
    }

    /// Drops every map (a viewer that stops rendering gives their memory back).
    pub fn clear(&mut self) {
        self.key = None;
        self.maps.clear();
        self.changes.clear();
    }

    /// Tells the cache that the content changed by `change` only. A change that does not start
    /// where the maps' content (or the last noted change) ends, or whose box is not finite,
    /// breaks the chain: the next frame of new content then redraws whole maps, as without
    /// notes. A frame whose content is the chain's end redraws only the changed texels.
    pub fn note_change(&mut self, change: ContentChange) {
        let Some((content, ..)) = &self.key else {
            return;
        };
        let head = self.changes.last().map_or(*content, |c| c.to);
        // An empty box (`lo > hi` on an axis) is a change nothing drawn saw.
        let finite = change.lo.is_finite() && change.hi.is_finite();
        if change.from == head && finite && self.changes.len() < MAX_CHANGES {
            self.changes.push(change);
        } else if change.from != change.to || !finite {
            // Unknown ground: nothing can be patched until the maps are drawn again.
            self.clear();
        }
    }

    /// Whether it holds no map.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.maps.iter().all(Option::is_none)
    }

    /// The cached map of light `index` if it can stand in for `wanted` (see the type's docs).
    fn reusable(&self, index: usize, wanted: &Camera) -> Option<Arc<shade::ShadowMap>> {
        let m = self.maps.get(index)?.as_ref()?;
        map_serves(&m.cam, wanted, self.finer_limit()).then(|| Arc::clone(m))
    }

    fn finer_limit(&self) -> f32 {
        self.max_finer.unwrap_or(SHADOW_CACHE_MAX_FINER)
    }
}

/// Whether a map drawn through `cam` can stand in for one `wanted` by a frame (see
/// [`ShadowCache`]).
fn map_serves(cam: &Camera, wanted: &Camera, max_finer: f32) -> bool {
    let same_view =
        cam.view_from_world == wanted.view_from_world && cam.projection == wanted.projection;
    let fine_enough = cam.width >= wanted.width && cam.height >= wanted.height;
    let not_too_fine = cam.width as f32 <= wanted.width as f32 * max_finer;
    same_view && fine_enough && not_too_fine
}

/// The texels of a map seen through `cam` that the world box `lo..=hi` covers, widened by
/// `margin` texels (inclusive `[x0, y0, x1, y1]`), or `None` when it misses the map or is
/// empty.
fn box_texels(cam: &Camera, lo: Vec3, hi: Vec3, margin: f32) -> Option<[u32; 4]> {
    if lo.cmpgt(hi).any() {
        return None;
    }
    let (mut min, mut max) = (glam::Vec2::INFINITY, glam::Vec2::NEG_INFINITY);
    for k in 0..8 {
        let corner = Vec3::select(glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0), hi, lo);
        let p = cam.project_view(cam.view_from_world.transform_point3(corner));
        min = min.min(p.truncate());
        max = max.max(p.truncate());
    }
    let (w, h) = (cam.width as f32, cam.height as f32);
    let (x0, y0) = (
        (min.x - margin).floor().max(0.0),
        (min.y - margin).floor().max(0.0),
    );
    let (x1, y1) = (
        (max.x + margin).ceil().min(w - 1.0),
        (max.y + margin).ceil().min(h - 1.0),
    );
    // Not finite (a perspective corner behind the eye) would give NaN: take the whole map.
    if !(min.is_finite() && max.is_finite()) {
        return Some([0, 0, cam.width - 1, cam.height - 1]);
    }
    (x0 <= x1 && y0 <= y1).then_some([x0 as u32, y0 as u32, x1 as u32, y1 as u32])
}

/// The per-node transform of every voxel object of a document (`None` for meshes): rigid
/// objects get a [`RigidDeform`]; skinned ones (with a [`crate::skin::Rig`]) a
/// [`crate::skin::SkinDeform`] at the rig's playback clip and time with its stretch settings,
/// the multiplier scaled by [`Quality::stretch_multiplier`].
#[must_use]
pub fn document_deforms<'a>(
    doc: &'a Document,
    quality: &Quality,
) -> Vec<Option<Box<dyn NodeDeform + 'a>>> {
    doc.objects
        .iter()
        .map(|o| match &o.kind {
            ObjectKind::Voxels(v) => Some(match &v.rig {
                Some(rig) => Box::new(skin_deform(o, v, rig, quality)) as Box<dyn NodeDeform>,
                None => Box::new(rigid_deform(o, v)),
            }),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
        })
        .collect()
}

/// The stretch settings a rig is drawn with under `quality`: the rig's own, its multiplier
/// scaled by the quality's, its strategy replaced by the quality's override when there is one.
/// Every renderer and overlay uses this, so they agree.
#[must_use]
pub fn effective_stretch(
    rig: &crate::skin::Rig,
    quality: &Quality,
) -> crate::skin::StretchSettings {
    let mut stretch = rig.stretch;
    stretch.multiplier *= quality.stretch_multiplier;
    if let Some(strategy) = quality.stretch_strategy {
        stretch.strategy = strategy;
    }
    stretch
}

/// Renders a scene from a camera.
///
/// # Errors
/// [`RenderError`] for an empty or oversized image or invalid quality.
pub fn render_scene(
    scene: &RenderScene<'_>,
    cam: &Camera,
    quality: &Quality,
) -> Result<(RgbaImage, FrameBuffers, FrameStats), RenderError> {
    render_scene_with_krs(scene, &KrsLayer::default(), cam, quality)
}

/// Renders a scene plus KRS objects from a camera: the KRS is sphere-traced into the same
/// depth+id target after triangles and voxels, so all three occlude each other; KRS casters
/// shadow every pixel by shadow rays, voxel and mesh casters shadow KRS pixels through the
/// shadow maps.
///
/// # Errors
/// [`RenderError`] for an empty or oversized image or invalid quality.
pub fn render_scene_with_krs(
    scene: &RenderScene<'_>,
    krs_layer: &KrsLayer,
    cam: &Camera,
    quality: &Quality,
) -> Result<(RgbaImage, FrameBuffers, FrameStats), RenderError> {
    let mut r = Renderer::new();
    r.frame
        .render_supersampled(scene, krs_layer, cam, quality, None, true)?;
    Ok(r.take_frame())
}

impl FrameState {
    /// [`Self::render`] with [`Quality::supersample`]: the frame is drawn at `k` times the
    /// camera's size (the same view), then its image is box-filtered and its G-buffer decimated
    /// to the camera's size, in place. The counters count samples.
    fn render_supersampled(
        &mut self,
        scene: &RenderScene<'_>,
        krs_layer: &KrsLayer,
        cam: &Camera,
        quality: &Quality,
        cache: Option<(&mut ShadowCache, u64)>,
        sampled_only: bool,
    ) -> Result<(), RenderError> {
        let k = supersample_factor(cam.width, cam.height, quality.supersample);
        if k == 1 {
            return self.render(scene, krs_layer, cam, quality, cache, sampled_only);
        }
        let samples = Camera::new(
            cam.view_from_world,
            cam.projection,
            cam.width * k,
            cam.height * k,
        );
        self.render(scene, krs_layer, &samples, quality, cache, sampled_only)?;
        let t0 = Instant::now();
        self.image.downsample(k);
        self.fb.decimate(k);
        let ms = ms_since(t0);
        self.stats.times.shade_ms += ms;
        self.stats.times.total_ms += ms;
        Ok(())
    }

    /// [`render_scene_with_krs`] into these buffers, with shadow maps from and into `cache`
    /// when there is one. Without a cache, `sampled_only` draws casters into a map only where
    /// the frame's shading reads it (the image is the same either way; tests compare the two).
    fn render(
        &mut self,
        scene: &RenderScene<'_>,
        krs_layer: &KrsLayer,
        cam: &Camera,
        quality: &Quality,
        cache: Option<(&mut ShadowCache, u64)>,
        sampled_only: bool,
    ) -> Result<(), RenderError> {
        check_size(cam.width, cam.height)?;
        quality.validate()?;
        let t_start = Instant::now();
        let stats = &mut self.stats;
        stats.reset();

        raster::world_triangles_into(&scene.meshes, &mut self.tris);
        let tris = &self.tris[..];
        stats.triangles = tris.len() as u64;

        // View: triangles, then voxels into the same depth.
        let t0 = Instant::now();
        let target = &mut self.target;
        target.reset(cam.width, cam.height);
        stats.triangles_rasterised =
            raster::draw_triangles(tris, &scene.meshes, cam, target, false);
        // With no triangle drawn the tiles are already right (all empty).
        if stats.triangles_rasterised > 0 && quality.occlusion_culling {
            target.update_all_tiles();
        }
        stats.times.triangles_ms = ms_since(t0);
        let pass = asvo::draw_voxels(
            &scene.voxels,
            cam,
            target,
            &asvo::PassSettings {
                lod_pixel_threshold: quality.lod_pixel_threshold,
                cube_pixel_threshold: quality.cube_pixel_threshold,
                occlusion_culling: quality.occlusion_culling,
                id_base: 0,
                keep_refs: true,
                shadow_casters_only: false,
                sampled: None,
            },
            &mut self.voxels,
        );
        stats.levels.extend_from_slice(&self.voxels.levels);
        stats.rect_pixels = pass.rect_pixels;
        stats.cube_pixels = pass.cube_pixels;
        stats.times.traversal_ms = pass.traversal_ms;
        stats.times.splat_ms = pass.splat_ms;

        let t0 = Instant::now();
        let krs_pass = &mut self.krs_pass;
        krs::draw_krs(krs_layer, scene.lights, cam, target, quality, krs_pass);
        let krs_pass = &*krs_pass;
        stats.krs = krs_pass.stats;
        stats.times.krs_ms = ms_since(t0);

        let t0 = Instant::now();
        let fb = &mut self.fb;
        shade::resolve(
            target,
            cam,
            &scene.voxels,
            &self.voxels.refs,
            &scene.meshes,
            tris,
            &mut self.normal_mats,
            fb,
        );
        shade::resolve_krs(fb, target, krs_pass, &krs_layer.labels);
        stats.times.resolve_ms = ms_since(t0);
        stats.covered_pixels = fb.covered_pixels() as u64;

        // Shadow maps, after the view: a map drawn for this frame alone needs the G-buffer to
        // know which texels its shading reads (see `SampledTexels`).
        let t0 = Instant::now();
        let shadow_use = &mut self.shadow_use;
        // Dropped first: a cached map held here too could not be redrawn in place.
        shadow_use.clear();
        shadow_use.resize_with(scene.lights.len(), Default::default);
        self.own_maps.truncate(scene.lights.len());
        self.own_maps.resize_with(scene.lights.len(), || None);
        let bounds = scene_bounds(scene, tris);
        // A shadow map with nothing drawn into it would only cost every pixel its filter taps.
        let has_casters = scene
            .voxels
            .iter()
            .any(|v| v.casts_shadows && !v.svo.is_empty())
            || tris
                .iter()
                .any(|t| scene.meshes[t.mesh as usize].casts_shadows);
        // A cache made for other content, lights or quality holds nothing usable: start it
        // afresh. That frame draws its maps as an uncached frame would (only the texels it
        // reads) and keeps none: a change is often followed by another (a stroke, playback),
        // and a full map costs more. The next frame with the same key draws full maps and
        // keeps them.
        // Content reached through noted changes keeps its maps and redraws only the changed
        // texels (`patch` holds the changes' world boxes).
        let mut fresh_key = false;
        let patch = &mut self.patch_boxes;
        patch.clear();
        let mut patching = false;
        let mut cache = cache.map(|(c, content)| {
            let same_setup = c
                .key
                .as_ref()
                .is_some_and(|(_, lights, q)| lights[..] == scene.lights[..] && q == quality);
            let same = same_setup && c.key.as_ref().is_some_and(|(k, ..)| *k == content);
            // The content may be any point of the chain (a frame of an earlier snapshot).
            let reached = c.changes.iter().position(|ch| ch.to == content);
            if let Some(n) = reached.filter(|_| same_setup && !same) {
                patch.extend(c.changes.drain(..=n).map(|ch| (ch.lo, ch.hi)));
                patching = true;
                if let Some((k, ..)) = c.key.as_mut() {
                    *k = content;
                }
            } else if !same {
                c.key = Some((content, scene.lights.to_vec(), quality.clone()));
                c.maps.clear();
                c.changes.clear();
                fresh_key = true;
            }
            c.maps.resize(scene.lights.len(), None);
            c
        });
        for (li, light) in scene.lights.iter().enumerate() {
            let Some((lo, hi)) = bounds else { break };
            if !(quality.shadows && light.casts_shadows && has_casters) {
                continue;
            }
            // One texel per view pixel where the scene comes nearest the eye: each halving of
            // the texel quadruples the shadow traversal for detail the view cannot resolve
            // (PCF blurs over three texels anyway).
            let finest = finest_shadow_texel(cam, lo, hi);
            let fit = |texel: f32| {
                shade::fit_light_camera(light.direction, lo, hi, quality.shadow_map_size, texel)
            };
            let Some(lc) = fit(finest) else { continue };
            if patching && let Some(c) = cache.as_mut() {
                // A map that cannot be patched (another view, shared, never drawn whole) must
                // not be reused for the new content: it is drawn again below.
                let limit = c.finer_limit();
                let mut slot = c.maps[li].take();
                let patched = slot
                    .as_mut()
                    .filter(|m| map_serves(&m.cam, &lc, limit))
                    .and_then(Arc::get_mut)
                    .and_then(|m| {
                        let cam = m.cam;
                        let margin = quality.lod_pixel_threshold.ceil() + 2.0;
                        let windows = rayon::iter::ParallelIterator::filter_map(
                            rayon::iter::IntoParallelRefIterator::par_iter(&patch[..]),
                            |&(lo, hi)| box_texels(&cam, lo, hi, margin),
                        );
                        self.sampled.reset(cam.width, cam.height, windows);
                        m.redraw_region(
                            &scene.voxels,
                            &scene.meshes,
                            tris,
                            quality,
                            &self.sampled,
                            &mut stats.shadow_levels,
                            &mut self.light_pass,
                        )
                        .map(|texels| (texels, m.cube_pixels))
                    });
                if let Some((texels, cube_pixels)) = patched {
                    stats.shadow_maps_patched += 1;
                    stats.shadow_texels_patched += texels;
                    stats.shadow_cube_pixels += cube_pixels;
                    if let Some(m) = &slot {
                        shadow_use[li] = shade::ShadowUse::Cached(Arc::clone(m));
                    }
                    c.maps[li] = slot;
                    continue;
                }
            }
            if let Some(m) = cache.as_ref().and_then(|c| c.reusable(li, &lc)) {
                stats.shadow_maps_reused += 1;
                shadow_use[li] = shade::ShadowUse::Cached(m);
                continue;
            }
            // A map for this frame alone holds casters only where its shading reads; a cached
            // map serves other views too, so it holds them all.
            if let Some(c) = cache.as_mut().filter(|_| !fresh_key) {
                let lc = fit(finest / SHADOW_CACHE_HEADROOM).unwrap_or(lc);
                // The cache's old map is redrawn in place when nothing else holds it. It is out
                // of the cache while drawn: a render that panics leaves no half-drawn map there.
                let slot = &mut c.maps[li];
                let mut kept = slot.take();
                match kept.as_mut().and_then(Arc::get_mut) {
                    Some(m) => {
                        m.cam = lc;
                        m.redraw(
                            &scene.voxels,
                            &scene.meshes,
                            tris,
                            quality,
                            None,
                            &mut stats.shadow_levels,
                            &mut self.light_pass,
                        );
                    }
                    None => {
                        kept = Some(Arc::new(shade::ShadowMap::render(
                            lc,
                            &scene.voxels,
                            &scene.meshes,
                            tris,
                            quality,
                            None,
                            &mut stats.shadow_levels,
                            &mut self.light_pass,
                        )));
                    }
                }
                if let Some(m) = &kept {
                    stats.shadow_cube_pixels += m.cube_pixels;
                    shadow_use[li] = shade::ShadowUse::Cached(Arc::clone(m));
                }
                *slot = kept;
                continue;
            }
            let sampled = if sampled_only {
                let krs_pixels = &krs_pass.pixels;
                shade::sampled_texels(&lc, light, fb, cam, krs_pixels, quality, &mut self.sampled);
                Some(&self.sampled)
            } else {
                None
            };
            let map = self.own_maps[li].get_or_insert_with(|| shade::ShadowMap::empty(lc));
            map.cam = lc;
            map.redraw(
                &scene.voxels,
                &scene.meshes,
                tris,
                quality,
                sampled,
                &mut stats.shadow_levels,
                &mut self.light_pass,
            );
            stats.shadow_cube_pixels += map.cube_pixels;
            shadow_use[li] = shade::ShadowUse::Own;
        }
        stats.times.shadow_ms = ms_since(t0);

        let t0 = Instant::now();
        let lighting = shade::Lighting {
            lights: scene.lights,
            shadows: shadow_use,
            own_maps: &self.own_maps,
            ambient: scene.ambient,
            background: scene.background,
            ao_radius_world: ao_radius_world(with_krs_bounds(bounds, &krs_layer.scene)),
            krs: krs::KrsLighting::new(krs_layer, krs_pass, quality),
        };
        let counts = shade::shade(
            fb,
            cam,
            &lighting,
            quality,
            &mut self.image,
            &mut self.shade,
        );
        stats.shading = Some(counts.shading);
        stats.krs.shadow_steps = counts.krs_shadow_steps;
        stats.krs.ao_evals = counts.krs_ao_evals;
        stats.krs.shadow_rays = lighting
            .krs
            .shadow_rays
            .load(std::sync::atomic::Ordering::Relaxed);
        stats.times.shade_ms = ms_since(t0);
        stats.times.total_ms = ms_since(t_start);
        Ok(())
    }
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// World bounds of everything drawn (casters and receivers), for fitting shadow maps.
fn scene_bounds(scene: &RenderScene<'_>, tris: &[raster::WorldTriangle]) -> Option<(Vec3, Vec3)> {
    let mut b = asvo::voxel_bounds(&scene.voxels, false);
    for t in tris {
        for p in t.world {
            b = Some(b.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))));
        }
    }
    b.filter(|(lo, hi)| lo.is_finite() && hi.is_finite())
}

/// The finest shadow texel (world units) a view of the scene box `lo..hi` can resolve: one view
/// pixel where the scene comes nearest the eye (perspective), or the pixel size of an
/// orthographic view. Both renderers fit their shadow cameras with it.
#[must_use]
pub fn finest_shadow_texel(cam: &Camera, lo: Vec3, hi: Vec3) -> f32 {
    let eye = cam.eye();
    let nearest = (eye.clamp(lo, hi) - eye).length().max(cam.near());
    cam.pixel_world_size(nearest)
}

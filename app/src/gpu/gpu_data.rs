//! Structs shared between Rust and WGSL: `#[repr(C)]`, `bytemuck::Pod`, with compile-time size
//! assertions so a field added on one side only fails the build.

use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Mat4, Vec3};

/// A camera with its image size.
///
/// Keep in sync with `shaders/common/types.wgsl` (`View`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ViewUniform {
    /// `view_from_world`.
    pub view_from_world: [[f32; 4]; 4],
    /// `clip_from_world` (depth 0..1).
    pub clip_from_world: [[f32; 4]; 4],
    /// `world_from_view` (its last column is the eye).
    pub world_from_view: [[f32; 4]; 4],
    /// Image width and height in pixels.
    pub size: [u32; 2],
    /// 1 for a perspective camera, 0 for orthographic.
    pub perspective: u32,
    /// How splats write keys: [`MODE_KEY64`], [`MODE_DEPTH`] or [`MODE_ID`].
    pub write_mode: u32,
    /// Pixels per view unit at view depth 1 (perspective) or per unit (orthographic), x.
    pub fx: f32,
    /// Same for y.
    pub fy: f32,
    /// Near plane view depth.
    pub near: f32,
    /// Far plane view depth.
    pub far: f32,
    /// ASVO: split while the projected edge exceeds this many pixels.
    pub lod_pixel_threshold: f32,
    /// 1: the traversal culls nodes behind the occlusion tiles; 0: no occlusion culling.
    pub occlusion: u32,
    /// Occlusion tiles per row.
    pub tiles_x: u32,
    /// ASVO: splats wider or taller than this many pixels are drawn as their exact cube.
    pub cube_pixel_threshold: f32,
}
const _: () = assert!(std::mem::size_of::<ViewUniform>() == 240);

/// 64-bit path: one `atomicMin` of the packed key.
pub const MODE_KEY64: u32 = 0;
/// 32-bit path pass 1 (and shadow maps): `atomicMin` of the depth bits.
pub const MODE_DEPTH: u32 = 1;
/// 32-bit path pass 2: `atomicMin` of the id where the depth matches.
pub const MODE_ID: u32 = 2;

/// Index of the first per-view statistics counter in the counter buffer.
pub const STATS_START: u32 = 64;
/// Most octree levels a traversal counts (depth ≤ 21, so 22 levels are used).
pub const MAX_LEVELS: u32 = 32;
/// Counters per level: visited, split, splatted, frustum culled, occlusion culled, and of the
/// splatted those drawn as exact cubes.
pub const STATS_PER_LEVEL: u32 = 6;
/// Edge of an occlusion tile in pixels (`OCCLUSION_TILE` in `common/types.wgsl`).
pub const OCCLUSION_TILE: u32 = 8;
/// Index of the queue-overflow counter.
pub const OVERFLOW_COUNTER: u32 = 32;
/// First of two counters of the pixels covered by voxel splats, i.e. the key atomics the
/// traversal issued: `[0]` the view, `[1]` shadow maps (`SPLAT_PIXEL_COUNTERS` in
/// `common/types.wgsl`). The splat-bandwidth measurement counts its bytes from them.
pub const SPLAT_PIXEL_COUNTERS: u32 = 34;
/// First of two counters of the pixels exact cubes tested (one ray–box test each, a key atomic
/// where it hits): `[0]` the view, `[1]` shadow maps (`CUBE_PIXEL_COUNTERS` in
/// `common/types.wgsl`).
pub const CUBE_PIXEL_COUNTERS: u32 = 36;
const _: () = assert!(
    SPLAT_PIXEL_COUNTERS > OVERFLOW_COUNTER
        && CUBE_PIXEL_COUNTERS == SPLAT_PIXEL_COUNTERS + 2
        && CUBE_PIXEL_COUNTERS + 2 <= KRS_COUNTERS
);
/// Bits of a voxel key's id that carry the face of an exact cube (`FACE_BITS` in
/// `common/types.wgsl`, the CPU's `render::asvo::FACE_BITS`): ids are `attribute << FACE_BITS |
/// face`, so attributes must stay below `MESH_ID_FLAG >> FACE_BITS`.
pub const FACE_BITS: u32 = thicket_core::render::FACE_BITS;
/// Length of the counter buffer in u32: queue counts, overflow, two views' statistics.
pub const COUNTER_WORDS: u32 = STATS_START + 2 * MAX_LEVELS * STATS_PER_LEVEL;
/// Bytes of the counter buffer.
pub const COUNTER_BYTES: u64 = COUNTER_WORDS as u64 * 4;

/// One traversal dispatch: an object seen from a view at one level.
///
/// Keep in sync with `shaders/common/types.wgsl` (`NodeParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct NodeParams {
    /// Columns of the linear part of `view_from_voxel` (w unused).
    pub linear: [[f32; 4]; 3],
    /// xyz: translation of `view_from_voxel`; w: longest world edge of a 1-voxel node.
    pub translation_edge: [f32; 4],
    /// View-space AABB half extent of a 1-voxel node (w unused).
    pub half_extent_unit: [f32; 4],
    /// Octree level of this dispatch (0 = root).
    pub level: u32,
    /// Edge of a node at this level, in voxels.
    pub node_size: u32,
    /// The octree depth: nodes at this level are leaves.
    pub leaf_level: u32,
    /// Entries each queue holds.
    pub queue_capacity: u32,
    /// Object's first inner node in the scene's inner pool.
    pub inner_base: u32,
    /// Object's first leaf in the scene's leaf numbering (unused by the shader; kept for
    /// symmetry and debugging).
    pub leaf_base: u32,
    /// Attribute index of the object's inner node 0.
    pub attr_inner_base: u32,
    /// Attribute index of the object's leaf 0.
    pub attr_leaf_base: u32,
    /// First statistics counter of this view.
    pub stats_base: u32,
    /// Padding to a 16-byte multiple.
    pub pad: [u32; 3],
    /// How a rigged object's nodes are skinned ([`SkinParams::strategy`] is [`SkinStrategy::Rigid`]
    /// for rigid objects).
    pub skin: SkinParams,
}
const _: () = assert!(std::mem::size_of::<NodeParams>() == 192);
const _: () = assert!(std::mem::offset_of!(NodeParams, skin) == 128);
const _: () = assert!(std::mem::size_of::<NodeParams>() as u64 <= NODE_PARAMS_STRIDE);

/// Declares a `u32` code enum the shaders compare against, with the WGSL constant name of each
/// variant: [`constants_wgsl`] writes them, so the values have one definition.
macro_rules! wgsl_codes {
    ($(#[$m:meta])* pub enum $name:ident {
        $($(#[$vm:meta])* $v:ident = $val:literal => $wgsl:literal,)*
    }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[repr(u32)]
        pub enum $name {
            $($(#[$vm])* $v = $val,)*
        }
        impl $name {
            /// Every variant with the name of its WGSL constant.
            pub const WGSL: &'static [(&'static str, Self)] = &[$(($wgsl, Self::$v)),*];

            /// The code written into the GPU struct.
            #[must_use]
            pub const fn code(self) -> u32 {
                self as u32
            }
        }
    };
}

wgsl_codes! {
    /// [`SkinParams::strategy`]: a rigid object, or a rigged one's stretch strategy
    /// (`StretchStrategy`).
    pub enum SkinStrategy {
        /// A rigid object (no skinning).
        Rigid = 0 => "SKIN_RIGID",
        /// `StretchStrategy::Off`.
        Off = 1 => "SKIN_OFF",
        /// `StretchStrategy::Thesis`.
        Thesis = 2 => "SKIN_THESIS",
        /// `StretchStrategy::Corners`.
        Corners = 3 => "SKIN_CORNERS",
        /// `StretchStrategy::Adaptive`.
        Adaptive = 4 => "SKIN_ADAPTIVE",
    }
}

/// [`SkinParams::flags`]: the object's corner weights are uploaded.
pub const SKIN_HAS_CORNERS: u32 = 1;
/// [`SkinParams::flags`]: the object's per-leaf stretch overrides are uploaded.
pub const SKIN_HAS_OVERRIDES: u32 = 2;

/// Per-object skinning constants: where its joint matrices and skin data lie, and its stretch
/// settings (see `app/src/gpu/skin.rs`).
///
/// Keep in sync with `shaders/common/types.wgsl` (`SkinParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
pub struct SkinParams {
    /// First matrix of the object in the joint buffer.
    pub joint_base: u32,
    /// Joints of its skeleton.
    pub joint_count: u32,
    /// A [`SkinStrategy`] code.
    pub strategy: u32,
    /// [`SKIN_HAS_CORNERS`] | [`SKIN_HAS_OVERRIDES`].
    pub flags: u32,
    /// Word offset of inner node 0's skin pair in the skin data.
    pub inner_skin: u32,
    /// Word offset of leaf 0's skin pair.
    pub leaf_skin: u32,
    /// Word offset of inner node 0's corner block (16 words per node).
    pub inner_corners: u32,
    /// Word offset of leaf 0's corner block.
    pub leaf_corners: u32,
    /// Word offset of inner node 0's subtree joint range (start, count).
    pub subtree_ranges: u32,
    /// Word offset of the object's subtree joint list.
    pub subtree_joints: u32,
    /// Word offset of the leaves' override bytes (4 per word).
    pub overrides: u32,
    /// Padding.
    pub pad: u32,
    /// Global stretch multiplier (the rig's times the quality's).
    pub multiplier: f32,
    /// Lower bound on a scalar stretch factor.
    pub min_factor: f32,
    /// Upper bound on a scalar stretch factor.
    pub max_factor: f32,
    /// Largest factor a descendant may be drawn with, times the multiplier (culling boxes).
    pub grow: f32,
}
const _: () = assert!(std::mem::size_of::<SkinParams>() == 64);

/// Dynamic-offset stride of [`NodeParams`] slots (the minimum uniform offset alignment wgpu
/// guarantees).
pub const NODE_PARAMS_STRIDE: u64 = 256;

impl NodeParams {
    /// Per-object constants for `view_from_voxel` (the CPU reference's rigid fast path).
    #[must_use]
    pub fn for_object(view_from_voxel: Mat4, world_from_voxel: Mat4) -> Self {
        let linear = Mat3::from_mat4(view_from_voxel);
        let abs = Mat3::from_cols(
            linear.x_axis.abs(),
            linear.y_axis.abs(),
            linear.z_axis.abs(),
        );
        let half = abs * Vec3::splat(0.5);
        let wl = Mat3::from_mat4(world_from_voxel);
        let edge = wl
            .x_axis
            .length()
            .max(wl.y_axis.length())
            .max(wl.z_axis.length());
        let t = view_from_voxel.w_axis.truncate();
        Self {
            linear: [
                linear.x_axis.extend(0.0).to_array(),
                linear.y_axis.extend(0.0).to_array(),
                linear.z_axis.extend(0.0).to_array(),
            ],
            translation_edge: [t.x, t.y, t.z, edge],
            half_extent_unit: half.extend(0.0).to_array(),
            ..Self::zeroed()
        }
    }
}

/// Per-object constants of the resolve pass.
///
/// Keep in sync with `shaders/common/types.wgsl` (`ObjectInfo`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ObjectInfo {
    /// Columns of the inverse transpose of `world_from_voxel`'s linear part (w unused).
    pub normal_from_voxel: [[f32; 4]; 3],
    /// Rigged objects: `[1, attribute index of inner node 0, of leaf 0, 0]`; rigid: zeros.
    pub skin_attr: [u32; 4],
    /// Rigged objects: the skinning constants the resolve needs for normals.
    pub skin: SkinParams,
}
const _: () = assert!(std::mem::size_of::<ObjectInfo>() == 128);
const _: () = assert!(std::mem::offset_of!(ObjectInfo, skin) == 64);

/// One directional light.
///
/// Keep in sync with `shaders/common/types.wgsl` (`LightGpu`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct LightGpu {
    /// Unit vector toward the light.
    pub to_light: [f32; 3],
    /// Index of this light's shadow map in the shade pass's [`ShadowMapGpu`] array, or
    /// [`NO_SHADOW_MAP`] when it has none this frame.
    pub shadow_map: u32,
    /// Linear colour × intensity (w unused).
    pub color: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<LightGpu>() == 32);
const _: () = assert!(std::mem::offset_of!(LightGpu, shadow_map) == 12);

/// [`LightGpu::shadow_map`] of a light without a shadow map (`NO_SHADOW_MAP` in
/// `common/types.wgsl`).
pub const NO_SHADOW_MAP: u32 = u32::MAX;

/// One light's shadow map as the shade pass reads it: the light camera and where its texels
/// start in the shared shadow key buffer (every map lies in one buffer, each at an offset the
/// traversal and mesh passes can bind its range at).
///
/// Keep in sync with `shaders/common/types.wgsl` (`ShadowMap`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ShadowMapGpu {
    /// The light camera (as the map was drawn with).
    pub view: ViewUniform,
    /// First `u32` of this map in the shadow key buffer (texel `p`'s depth bits are at
    /// `key_word_offset + 2p + 1`).
    pub key_word_offset: u32,
    /// Padding to a 16-byte multiple.
    pub pad: [u32; 3],
}
const _: () = assert!(std::mem::size_of::<ShadowMapGpu>() == 256);
const _: () = assert!(std::mem::offset_of!(ShadowMapGpu, key_word_offset) == 240);

/// Supersampling's resolve: samples per pixel side and the target's size.
///
/// Keep in sync with `shaders/supersample.wgsl` (`Supersample`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct SupersampleUniform {
    /// Samples per pixel side (the frame was drawn `k` times the target's size).
    pub k: u32,
    /// Target width in pixels.
    pub width: u32,
    /// Target height in pixels.
    pub height: u32,
    /// Padding to 16 bytes.
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<SupersampleUniform>() == 16);

/// Deferred-shading constants.
///
/// Keep in sync with `shaders/common/types.wgsl` (`Shading`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ShadingUniform {
    /// Linear ambient (w unused).
    pub ambient: [f32; 4],
    /// Linear background (w unused).
    pub background: [f32; 4],
    /// Lights in the light buffer.
    pub light_count: u32,
    /// PCF radius in shadow texels.
    pub pcf_radius: u32,
    /// The receiver's splat size in pixels (max(1, LOD threshold)).
    pub receiver_px: f32,
    /// Ambient-occlusion samples in `ao_kernel` (0 = off; `quality.ao_samples`).
    pub ao_count: u32,
    /// World radius of the ambient-occlusion samples.
    pub ao_radius: f32,
    /// Entries per pixel of the KRS lighting buffer (0: no KRS this frame; see
    /// `shaders/krs_trace.wgsl`).
    pub krs_stride: u32,
    /// Padding.
    pub pad: [u32; 2],
    /// Ambient-occlusion sample phases (xyz: elevation stratum start, azimuth phase, distance
    /// phase; w unused), computed on the CPU with the reference's formulas
    /// (`render::shade::ao_sample_phases`); the shader adds each pixel's jitter as the CPU's
    /// `ao_sample_offset` does.
    pub ao_kernel: [[f32; 4]; MAX_AO_SAMPLES],
}
const _: () = assert!(std::mem::size_of::<ShadingUniform>() == 64 + 16 * MAX_AO_SAMPLES);
const _: () = assert!(std::mem::offset_of!(ShadingUniform, ao_kernel) == 64);

/// Most ambient-occlusion samples the shading uniform holds (the limit `Quality::validate`
/// enforces on `ao_samples`).
pub const MAX_AO_SAMPLES: usize = 64;

/// Parameters of the clear pass.
///
/// Keep in sync with `shaders/clear.wgsl` (`ClearParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ClearParams {
    /// Words to fill.
    pub count: u32,
    /// Padding.
    pub pad: [u32; 3],
}
const _: () = assert!(std::mem::size_of::<ClearParams>() == 16);

/// Which pixels one resolve dispatch writes: the voxel pools are split into chunks of whole
/// objects (`scene::PoolChunk`), and the resolve runs once per chunk with that chunk's
/// attribute buffer bound.
///
/// Keep in sync with `shaders/resolve.wgsl` (`ResolveChunk`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ResolveChunk {
    /// Global attribute index (voxel id) of the bound attribute buffer's first element.
    pub attr_start: u32,
    /// One past the last voxel id this dispatch resolves.
    pub attr_end: u32,
    /// 1 when this dispatch also writes the pixels that are not voxels (meshes, background):
    /// exactly one dispatch per frame does.
    pub others: u32,
    /// Padding.
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<ResolveChunk>() == 16);

/// Bytes of one queue entry (`vec4<u32>`: node index, origin xyz).
pub const QUEUE_ENTRY_BYTES: u64 = 16;
/// Bytes of one packed key (depth bits << 32 | id).
pub const KEY_BYTES: u64 = 8;
/// Bytes of one G-buffer texel (`vec4<u32>`).
pub const GBUFFER_TEXEL_BYTES: u64 = 16;
/// One world-space triangle of the mesh buffer (read as `array<vec4<f32>>`, `TRI_STRIDE`
/// vec4 per triangle).
///
/// Keep in sync with `shaders/common/mesh.wgsl` and `shaders/resolve.wgsl` (`TRI_STRIDE`, the
/// slots they read).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuTriangle {
    /// World positions (w = 1).
    pub positions: [[f32; 4]; 3],
    /// World normals; w = 1 when the part has vertex normals, else 0 (use the face normal).
    pub normals: [[f32; 4]; 3],
    /// Linear RGBA: material base colour × vertex colour.
    pub colors: [[f32; 4]; 3],
    /// Texture coordinates of the first two vertices (u, v, u, v).
    pub uv_ab: [f32; 4],
    /// Texture coordinates of the third vertex, then the base-colour texture's index in the
    /// texture table as an exactly representable float ([`NO_TEXTURE`]: none), then padding.
    /// A float rather than bits reinterpreted from an integer: small integers as float bits
    /// are denormals, which a GPU may flush to zero.
    pub uv_c_texture: [f32; 4],
}
/// `vec4<f32>` per world triangle in the mesh buffer.
pub const TRI_VEC4S: usize = 11;
const _: () = assert!(std::mem::size_of::<GpuTriangle>() == TRI_VEC4S * 16);
const _: () = assert!(std::mem::offset_of!(GpuTriangle, colors) == 6 * 16);
const _: () = assert!(std::mem::offset_of!(GpuTriangle, uv_c_texture) == 10 * 16);
/// [`GpuTriangle::uv_c_texture`]`[2]` of a triangle without a texture.
pub const NO_TEXTURE: f32 = -1.0;
/// Most textures a scene may hold: texture indices travel as floats, exact up to 2^24.
pub const MAX_TEXTURES: usize = 1 << 24;
/// Words at the start of the texture buffer: the linear value (f32 bits) of each sRGB byte,
/// from the CPU's own table, so both renderers decode texels to the same floats.
pub const TEXTURE_LUT_WORDS: usize = 256;
/// Words per entry of the texture table that follows the look-up table: first texel word,
/// width, height, padding.
pub const TEXTURE_ENTRY_WORDS: usize = 4;
/// Bit marking triangle ids.
pub const MESH_ID_FLAG: u32 = 1 << 31;

/// The ambient-occlusion sample phases of the CPU reference
/// ([`thicket_core::render::shade::ao_sample_phases`], specified in docs/rendering.md "Ambient
/// occlusion"), packed for the shader's uniform. `count` is clamped to [`MAX_AO_SAMPLES`];
/// returns the count used.
#[must_use]
pub fn ao_kernel(count: u32, radius_world: f32) -> (u32, [[f32; 4]; MAX_AO_SAMPLES]) {
    // As the CPU's `AoKernel`: no radius (nothing with a size in the scene), no samples.
    let count = if radius_world > 0.0 && radius_world.is_finite() {
        count.min(MAX_AO_SAMPLES as u32)
    } else {
        0
    };
    let mut out = [[0.0; 4]; MAX_AO_SAMPLES];
    for (slot, v) in out
        .iter_mut()
        .zip(thicket_core::render::shade::ao_sample_phases(count))
    {
        *slot = [v[0], v[1], v[2], 0.0];
    }
    (count, out)
}

/// One KRS object of the KRS pass (`core::krs::PreparedObject`, flattened).
///
/// Keep in sync with `shaders/krs_trace.wgsl` (`KrsObject`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct KrsObjectGpu {
    /// `object_from_world` rotation (quaternion xyzw).
    pub inv_rotation: [f32; 4],
    /// `world_from_object` rotation (quaternion xyzw).
    pub rotation: [f32; 4],
    /// xyz: translation; w: uniform scale.
    pub translation_scale: [f32; 4],
    /// World bounding ball (centre, radius), valid with [`KRS_OBJ_BOUNDED`].
    pub bound: [f32; 4],
    /// First mirror in the vector buffer.
    pub first_mirror: u32,
    /// Mirrors (the object has one kernel more).
    pub mirror_count: u32,
    /// First kernel in the kernel buffer.
    pub first_kernel: u32,
    /// First empty zone in the vector buffer.
    pub first_zone: u32,
    /// Empty zones.
    pub zone_count: u32,
    /// [`KRS_OBJ_EMPTY`] | [`KRS_OBJ_DISTORTED`] | [`KRS_OBJ_BOUNDED`].
    pub flags: u32,
    /// A [`KrsTextureMode`] code.
    pub texture_mode: u32,
    /// A [`KrsPattern`] code.
    pub pattern: u32,
    /// 1 / scale.
    pub inv_scale: f32,
    /// Lipschitz bound of the warp (1 without distortion).
    pub lipschitz: f32,
    /// Distortion amplitude.
    pub amplitude: f32,
    /// Distortion frequency.
    pub frequency: f32,
    /// Distortion seed.
    pub seed: u32,
    /// Texture cells per object unit.
    pub tex_scale: f32,
    /// Texture contrast.
    pub tex_contrast: f32,
    /// Triplanar sharpness.
    pub tex_sharpness: f32,
}
const _: () = assert!(std::mem::size_of::<KrsObjectGpu>() == 128);

/// [`KrsObjectGpu::flags`]: every kernel is empty.
pub const KRS_OBJ_EMPTY: u32 = 1;
/// [`KrsObjectGpu::flags`]: the object has a distortion.
pub const KRS_OBJ_DISTORTED: u32 = 2;
/// [`KrsObjectGpu::flags`]: `bound` holds a bounding ball.
pub const KRS_OBJ_BOUNDED: u32 = 4;

wgsl_codes! {
    /// [`KrsObjectGpu::texture_mode`] (`core::krs::TextureMode`).
    pub enum KrsTextureMode {
        /// The kernel's plain colour.
        None = 0 => "KRS_TEXTURE_NONE",
        /// Triplanar projection in object space.
        Triplanar = 1 => "KRS_TEXTURE_TRIPLANAR",
        /// Kernel-parametrised coordinates (§6.2).
        KernelParam = 2 => "KRS_TEXTURE_KERNEL_PARAM",
    }
}

wgsl_codes! {
    /// [`KrsObjectGpu::pattern`] (`core::krs::Pattern`).
    pub enum KrsPattern {
        /// Alternating cells.
        Checker = 0 => "KRS_PATTERN_CHECKER",
        /// Streaked value noise.
        Bark = 1 => "KRS_PATTERN_BARK",
    }
}

wgsl_codes! {
    /// [`KrsKernelGpu::kind`] (`core::krs::Kernel`'s variants).
    pub enum KrsKernelKind {
        /// `Kernel::Empty`.
        Empty = 0 => "KRS_EMPTY",
        /// `Kernel::Sphere`.
        Sphere = 1 => "KRS_SPHERE",
        /// `Kernel::InfinitePlane`.
        Plane = 2 => "KRS_PLANE",
        /// `Kernel::Capsule`.
        Capsule = 3 => "KRS_CAPSULE",
        /// `Kernel::RoundedBox`.
        Box = 4 => "KRS_BOX",
        /// `Kernel::TorusSegment`.
        TorusSegment = 5 => "KRS_TORUS_SEGMENT",
        /// `Kernel::ToroidalCapsule`.
        ToroidalCapsule = 6 => "KRS_TOROIDAL_CAPSULE",
    }
}

/// One kernel of the KRS pass. Field use by kind is documented in `shaders/krs_trace.wgsl`
/// (`torus_closest` for tori).
///
/// Keep in sync with `shaders/krs_trace.wgsl` (`KrsKernel`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct KrsKernelGpu {
    /// x: a [`KrsKernelKind`] code.
    pub kind: [u32; 4],
    /// Linear material colour (w unused).
    pub colour: [f32; 4],
    /// Shape parameters.
    pub params: [[f32; 4]; 6],
}
const _: () = assert!(std::mem::size_of::<KrsKernelGpu>() == 128);

/// Per-frame constants of the KRS pass.
///
/// Keep in sync with `shaders/krs_trace.wgsl` (`KrsFrame`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct KrsFrameUniform {
    /// Epsilon scale (`quality.krs_epsilon_scale`).
    pub eps_scale: f32,
    /// Pixel footprint per unit distance.
    pub pixel_cone: f32,
    /// Epsilon floor.
    pub min_epsilon: f32,
    /// Step budget per ray.
    pub max_steps: u32,
    /// Over-relaxation factor.
    pub over_relaxation: f32,
    /// Sample grid: spacing of the uniform part.
    pub grid_q0: f32,
    /// Sample grid: parameter where the cone takes over.
    pub grid_t0: f32,
    /// Sample grid: index step of the geometric part.
    pub grid_log_step: f32,
    /// Sample grid: index at `grid_t0`.
    pub grid_u0: f32,
    /// Objects in the object buffer.
    pub object_count: u32,
    /// Lights (at `light_base` in the vector buffer).
    pub light_count: u32,
    /// First light in the vector buffer.
    pub light_base: u32,
    /// [`KRS_FRAME_TILES`] | [`KRS_FRAME_SHADOWS`] | [`KRS_FRAME_SOFT`].
    pub flags: u32,
    /// KRS ambient-occlusion samples (0 = off).
    pub ao_samples: u32,
    /// Their spacing in world units.
    pub ao_spacing: f32,
    /// The receiver's splat size in pixels (as `ShadingUniform::receiver_px`).
    pub receiver_px: f32,
    /// Entries of the per-pixel KRS lighting buffer per pixel (1 + lights).
    pub stride: u32,
    /// Algorithm 2 blend width in pixels.
    pub smoothing_px: f32,
    /// Soft-shadow penumbra factor.
    pub soft_k: f32,
    /// Padding.
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<KrsFrameUniform>() == 80);

/// [`KrsFrameUniform::flags`]: §4.1 tile cones start the rays.
pub const KRS_FRAME_TILES: u32 = 1;
/// [`KrsFrameUniform::flags`]: shadow rays through the KRS.
pub const KRS_FRAME_SHADOWS: u32 = 2;
/// [`KrsFrameUniform::flags`]: soft KRS shadows.
pub const KRS_FRAME_SOFT: u32 = 4;
/// First KRS word of the counter buffer (`KRS_COUNTERS` in `krs_trace.wgsl`), in the unused
/// range between the overflow counter and the per-view statistics.
pub const KRS_COUNTERS: u32 = 40;
const _: () = assert!(KRS_COUNTERS > OVERFLOW_COUNTER && KRS_COUNTERS + 13 <= STATS_START);

/// The constants the shaders share with this file, by their WGSL name: the one definition of
/// each. [`super::shaders::compose`] puts them (with the code enums' values: [`wgsl_constants`],
/// written as [`constants_wgsl`], the generated `constants.wgsl`) before every shader, so a
/// WGSL file that kept its own copy would not compile (WGSL forbids redeclaring a constant).
pub const WGSL_CONSTANTS: &[(&str, u32)] = &[
    ("MESH_ID_FLAG", MESH_ID_FLAG),
    ("FACE_BITS", FACE_BITS),
    ("FACE_MASK", (1 << FACE_BITS) - 1),
    ("MODE_KEY64", MODE_KEY64),
    ("MODE_DEPTH", MODE_DEPTH),
    ("MODE_ID", MODE_ID),
    ("OVERFLOW_COUNTER", OVERFLOW_COUNTER),
    ("SPLAT_PIXEL_COUNTERS", SPLAT_PIXEL_COUNTERS),
    ("CUBE_PIXEL_COUNTERS", CUBE_PIXEL_COUNTERS),
    ("STATS_START", STATS_START),
    ("MAX_LEVELS", MAX_LEVELS),
    ("STATS_PER_LEVEL", STATS_PER_LEVEL),
    ("OCCLUSION_TILE", OCCLUSION_TILE),
    ("NO_SHADOW_MAP", NO_SHADOW_MAP),
    ("TRI_STRIDE", TRI_VEC4S as u32),
    ("TEXTURE_LUT_WORDS", TEXTURE_LUT_WORDS as u32),
    ("TEXTURE_ENTRY_WORDS", TEXTURE_ENTRY_WORDS as u32),
    ("KRS_COUNTERS", KRS_COUNTERS),
    ("KRS_OBJ_EMPTY", KRS_OBJ_EMPTY),
    ("KRS_OBJ_DISTORTED", KRS_OBJ_DISTORTED),
    ("KRS_OBJ_BOUNDED", KRS_OBJ_BOUNDED),
    ("KRS_FRAME_TILES", KRS_FRAME_TILES),
    ("KRS_FRAME_SHADOWS", KRS_FRAME_SHADOWS),
    ("KRS_FRAME_SOFT", KRS_FRAME_SOFT),
    ("SKIN_HAS_CORNERS", SKIN_HAS_CORNERS),
    ("SKIN_HAS_OVERRIDES", SKIN_HAS_OVERRIDES),
];

/// Every constant of the generated `constants.wgsl`: [`WGSL_CONSTANTS`], then each code enum's
/// variants ([`SkinStrategy`], [`KrsKernelKind`], [`KrsTextureMode`], [`KrsPattern`]).
#[must_use]
pub fn wgsl_constants() -> Vec<(&'static str, u32)> {
    fn codes<T: Copy>(table: &[(&'static str, T)], code: fn(T) -> u32) -> Vec<(&'static str, u32)> {
        table.iter().map(|&(n, v)| (n, code(v))).collect()
    }
    let mut out = WGSL_CONSTANTS.to_vec();
    out.extend(codes(SkinStrategy::WGSL, SkinStrategy::code));
    out.extend(codes(KrsKernelKind::WGSL, KrsKernelKind::code));
    out.extend(codes(KrsTextureMode::WGSL, KrsTextureMode::code));
    out.extend(codes(KrsPattern::WGSL, KrsPattern::code));
    out
}

/// The generated `constants.wgsl`: one `const NAME: u32 = VALUEu;` per [`wgsl_constants`]
/// entry.
#[must_use]
pub fn constants_wgsl() -> String {
    let mut out = String::from("// Generated from app/src/gpu/gpu_data.rs (wgsl_constants).\n");
    for (name, value) in wgsl_constants() {
        out.push_str(&format!("const {name}: u32 = {value}u;\n"));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_params_half_extent_of_rotated_voxel() {
        // A 45° turn about y widens the view AABB of a unit voxel to √2/2 in x and z.
        let r = Mat4::from_rotation_y(std::f32::consts::FRAC_PI_4);
        let p = NodeParams::for_object(r, r);
        let h = std::f32::consts::FRAC_1_SQRT_2;
        assert!((p.half_extent_unit[0] - h).abs() < 1e-6);
        assert!((p.half_extent_unit[1] - 0.5).abs() < 1e-6);
        assert!((p.half_extent_unit[2] - h).abs() < 1e-6);
        assert!((p.translation_edge[3] - 1.0).abs() < 1e-6);
    }
}

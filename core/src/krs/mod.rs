//! Kernel-reflection sequences (KRS, Szécsi): procedural geometry whose distance function over
//! 2^n kernel instances costs O(n).
//!
//! A [`KrsObject`] holds kernels K0..Kn and mirror planes R0..R(n−1). Its distance is Algorithm 1
//! of the paper ([`KrsObject::distance_object`]): walk the mirrors from n−1 down to 0, fold the
//! point onto the negative side of each, and take the minimum with the kernel of that level.
//! A [`KrsScene`] is a union of objects; [`KrsScene::prepare`] validates it once and gives a
//! [`PreparedScene`] that the per-ray tracer ([`trace()`]), shadow and AO rays, shading
//! (Algorithm 2) and the collision/picking queries read.
//!
//! | file | owns |
//! |---|---|
//! | `kernel.rs` | kernel shapes, materials, analytic distance, normal, parametrisation |
//! | `mirror.rs` | mirror planes |
//! | `object.rs` | objects, scenes, validation, Algorithm 1, brute force, normals |
//! | `distort.rs` | the Lipschitz-bounded noise warp (symmetry hiding, §5.2) |
//! | `trace.rs` | sphere tracing, over-relaxation, tile start distances (§4.1), shadows, AO |
//! | `shade.rs` | Algorithm 2 (smooth shading), triplanar and kernel-parametrised texturing |
//! | `tree.rs` | the tree builder (§7.2) |
//! | `forest.rs` | growing a forest from trees, on a terrain or as a union (§7.2, §5) |
//! | `presets.rs` | tree, bush, grass, rock, terrain, coral, sponge, forest |
//! | `query.rs` | distance + normal, bounding spheres, instance enumeration, empty zones |
//!
//! The design notes (reflection order, epsilon, Lipschitz bounds, tree mapping) are in
//! `docs/krs.md`.

mod distort;
pub mod forest;
mod kernel;
mod mirror;
mod object;
pub mod presets;
mod query;
pub mod repetition;
mod shade;
mod trace;
mod tree;

pub use distort::Distortion;
pub use kernel::{
    BoxKernel, CapsuleKernel, Kernel, KernelBound, KernelProblem, Material, PlaneKernel,
    SphereKernel, TorusKernel,
};
pub use mirror::MirrorPlane;
pub use object::{
    EmptyZone, KrsError, KrsObject, KrsScene, PreparedObject, PreparedScene, Sample, Similarity,
};
pub use query::{KernelInstance, SurfaceQuery};
pub use shade::{
    Pattern, SmoothShading, TextureMode, Texturing, shade_colour, shading_threshold,
    triplanar_colour,
};
pub use trace::{
    AoSettings, SampleGrid, ShadowSettings, TraceHit, TraceSettings, ambient_occlusion, ao_jitter,
    shadow, shadow_counted, tile_cone, tile_start_distance, tile_start_distance_counted, trace,
};
pub use tree::{LeafParams, TreeError, TreeParams, spiral_route};

/// Most reflection levels a KRS object in a document may have. Each level costs one fold per
/// distance evaluation, so this bounds the work a (possibly hostile) file can ask for per ray;
/// it is far above anything the paper needs (a forest of 2^17 trees of 2^8 leaves is 25 levels).
pub const MAX_KRS_LEVELS: usize = 4096;

/// Wellons' `lowbias32` finaliser: a cheap, well-mixed 32-bit hash, shared by the distortion
/// lattice and the AO jitter (and by `lowbias32` in `shaders/common/types.wgsl`, bit for bit).
#[inline]
#[must_use]
pub(crate) fn lowbias32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

#[cfg(test)]
mod tests;

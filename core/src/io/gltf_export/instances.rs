//! KRS → kernel meshes plus one transform per kernel instance (for `EXT_mesh_gpu_instancing`).
//!
//! A KRS instance's transform is the object's similarity times the reflections taken to reach
//! it, so half of them have a negative determinant. glTF flips the winding of a node whose
//! transform mirrors, but `EXT_mesh_gpu_instancing` stores per-instance TRS (translation,
//! rotation quaternion, scale) and engines differ on negative scales. So no instance transform
//! here mirrors: each kernel is meshed twice, as it is and reflected by F = diag(−1, 1, 1)
//! with its winding reversed, and a mirrored instance M draws the reflected mesh with M·F,
//! a proper similarity: M·F·(F·p) = M·p.

use glam::{Affine3A, Mat3, Quat, Vec3};
use rayon::prelude::*;

use super::fields::{ColoredMesh, FieldError, MAX_RESOLUTION, mesh_distance_field};
use crate::krs::{Kernel, KernelBound, PreparedObject};

/// One instance placement: `world = translation + rotation · (scale · p)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InstanceTransform {
    /// Translation.
    pub translation: Vec3,
    /// Unit rotation.
    pub rotation: Quat,
    /// Per-axis scale (positive; uniform for KRS).
    pub scale: Vec3,
}

impl InstanceTransform {
    /// Maps a point.
    #[must_use]
    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        self.translation + self.rotation * (self.scale * p)
    }
}

/// One kernel's meshes and instances.
#[derive(Debug, Clone, PartialEq)]
pub struct KernelInstances {
    /// Kernel index in the object.
    pub kernel: usize,
    /// The kernel meshed in object space.
    pub mesh: ColoredMesh,
    /// The mesh reflected by x → −x, winding reversed (for mirrored instances).
    pub mirrored_mesh: ColoredMesh,
    /// Placements of `mesh`.
    pub transforms: Vec<InstanceTransform>,
    /// Placements of `mirrored_mesh`.
    pub mirrored_transforms: Vec<InstanceTransform>,
}

/// Splits a similarity (uniform scale, possibly mirrored) into a proper TRS, and whether it
/// mirrored (then the TRS is for the x-reflected mesh).
pub(crate) fn proper_trs(xf: &Affine3A) -> (InstanceTransform, bool) {
    let m = Mat3::from(xf.matrix3);
    let mirrored = m.determinant() < 0.0;
    let m = if mirrored {
        m * Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0))
    } else {
        m
    };
    let scale = m.determinant().cbrt().max(f32::MIN_POSITIVE);
    let rotation = super::writer::unit_quat(Quat::from_mat3(&(m * (1.0 / scale))));
    (
        InstanceTransform {
            translation: Vec3::from(xf.translation),
            rotation,
            scale: Vec3::splat(scale),
        },
        mirrored,
    )
}

/// `mesh` reflected by F = diag(−1, 1, 1): positions and normals mirrored, each triangle's
/// winding reversed so its front face stays outside. A mirrored placement M draws it with the
/// proper similarity M·F (`proper_trs`).
#[must_use]
pub fn mirrored_x(mesh: &ColoredMesh) -> ColoredMesh {
    let flip = Vec3::new(-1.0, 1.0, 1.0);
    ColoredMesh {
        positions: mesh.positions.iter().map(|&p| p * flip).collect(),
        normals: mesh.normals.iter().map(|&n| n * flip).collect(),
        colors: mesh.colors.clone(),
        indices: mesh
            .indices
            .chunks_exact(3)
            .flat_map(|t| [t[0], t[2], t[1]])
            .collect(),
    }
}

/// Cells across the thinnest section of a kernel (a twig's diameter, a leaf ball's) that the
/// kernel mesh gets at least: with fewer, a tube thinner than a cell falls between the lattice
/// points and meshes empty.
pub const MIN_CELLS_ACROSS: f32 = 4.0;

/// Half the thinnest extent of a kernel's solid: a sphere's, capsule's or tube's radius, a
/// box's smallest half extent. `None` for empty and unbounded kernels.
fn thinnest_half_extent(kernel: &Kernel) -> Option<f32> {
    match kernel {
        Kernel::Empty | Kernel::InfinitePlane(_) => None,
        Kernel::Sphere(k) => Some(k.radius),
        Kernel::Capsule(k) => Some(k.radius),
        Kernel::RoundedBox(k) => Some(k.half_extents.min_element()),
        Kernel::TorusSegment(k) | Kernel::ToroidalCapsule(k) => Some(k.minor_radius),
    }
}

/// Cells along the side `box_size` of a kernel's meshing box: `kernel_resolution`, raised so
/// that the thinnest section spans [`MIN_CELLS_ACROSS`] cells (the lattice is sparse, so a long
/// thin twig costs cells along its surface only), at most [`MAX_RESOLUTION`].
fn kernel_mesh_resolution(kernel: &Kernel, box_size: f32, kernel_resolution: u32) -> u32 {
    let needed = thinnest_half_extent(kernel)
        .filter(|h| *h > 0.0)
        .map_or(0.0, |h| (box_size * MIN_CELLS_ACROSS / (2.0 * h)).ceil());
    // `as` saturates: a degenerate (zero-width) kernel asks for the maximum.
    (needed.min(MAX_RESOLUTION as f32) as u32)
        .max(kernel_resolution)
        .min(MAX_RESOLUTION)
}

/// The kernels of `object` as meshes (each kernel's own distance field at
/// `kernel_resolution` cells across its bounding ball, more for thin kernels: see
/// [`MIN_CELLS_ACROSS`]) and the placements of all its instances.
///
/// # Errors
/// [`FieldError::TooManyTriangles`] when the object has more than `max_instances` instances
/// (checked before any is enumerated); [`FieldError::Unbounded`] for an unbounded kernel, a
/// distortion or empty zones (instances cannot carry them: export the distance-field mesh
/// instead); mesher errors.
pub fn krs_instances(
    object: &PreparedObject,
    kernel_resolution: u32,
    max_instances: usize,
) -> Result<Vec<KernelInstances>, FieldError> {
    let o = &object.object;
    if object.is_empty {
        return Err(FieldError::Empty);
    }
    if o.distortion.is_some() || !o.empty_zones.is_empty() {
        return Err(FieldError::Unbounded(format!(
            "KRS object {:?} has a distortion or empty zones, which kernel instances cannot \
             carry; export its distance-field mesh (cubes mode) instead",
            o.name
        )));
    }
    let count = o.instance_count();
    if count > max_instances as u128 {
        return Err(FieldError::TooManyInstances {
            count,
            limit: max_instances as u64,
            what: format!(
                "KRS object {:?}, one mesh per kernel (instances mode; the default mode \
                 instances whole prototypes instead)",
                o.name
            ),
        });
    }
    let mut out: Vec<KernelInstances> = Vec::new();
    for (k, kernel) in o.kernels.iter().enumerate() {
        let (c, r) = match kernel.bound() {
            KernelBound::Empty => continue,
            KernelBound::Unbounded => {
                return Err(FieldError::Unbounded(format!(
                    "KRS object {:?}: kernel {k} is unbounded (a half-space) and has no finite \
                     mesh to instance; export the distance-field mesh (cubes mode) instead",
                    o.name
                )));
            }
            KernelBound::Sphere(c, r) => (c, r),
        };
        let margin = Vec3::splat(r * 1.05 + 1e-6);
        let distance = |p: Vec3| kernel.distance(p);
        let resolution = kernel_mesh_resolution(kernel, 2.0 * margin.x, kernel_resolution);
        let (positions, indices) = mesh_distance_field(
            &distance,
            c - margin,
            c + margin,
            resolution,
            u64::MAX,
            &|_| true,
        )?;
        let colour = kernel.material().map_or(Vec3::splat(0.6), |m| m.colour);
        let normals: Vec<Vec3> = positions.par_iter().map(|&p| kernel.normal(p)).collect();
        let mesh = ColoredMesh {
            colors: vec![colour.extend(1.0); positions.len()],
            positions,
            normals,
            indices,
        };
        let mirrored_mesh = mirrored_x(&mesh);
        out.push(KernelInstances {
            kernel: k,
            mesh,
            mirrored_mesh,
            transforms: Vec::new(),
            mirrored_transforms: Vec::new(),
        });
    }
    for inst in object.instances(max_instances) {
        let Some(entry) = out.iter_mut().find(|e| e.kernel == inst.kernel) else {
            continue;
        };
        let (trs, mirrored) = proper_trs(&inst.world_from_kernel);
        if mirrored {
            entry.mirrored_transforms.push(trs);
        } else {
            entry.transforms.push(trs);
        }
    }
    Ok(out)
}

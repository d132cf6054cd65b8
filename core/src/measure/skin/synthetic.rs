//! A synthetic skinned model with a known answer: a closed cylinder of two rigid halves that
//! bends 90° at its middle, for measuring stretch strategies against arithmetic instead of
//! against each other.
//!
//! The cylinder runs along Y from `−half_length` to `+half_length` with radius `R`; vertices
//! below `y = 0` follow joint 0 (`root`), vertices above follow joint 1 (`elbow`, at the
//! origin). The clip `bend` turns the elbow from 0 to 90° about Z over the first second and
//! holds it for one more. Bent, the upper half lies along −X and the mesh closes the outer side
//! of the elbow with the stretched strip between the two rings at `y = ±ε`: the strip of the
//! ring point at angle θ (x = R cos θ) goes from `(R cos θ, 0)` to `(0, R cos θ)` in the XY
//! plane, so seen along Z the strips fill the triangle `x, y ≥ 0, x + y ≤ R` of area `R²/2`
//! ([`bend_hole_area`]). Rigid halves drawn without stretch cover none of that triangle except
//! what the voxels straddling the joint (half-weighted, so skinned onto its diagonal) and the
//! conservative voxel margin reach: with voxel edge `v`, the uncovered area lies between
//! `(R − 2v)²/2 − 2Rv` and `R²/2`.

use std::f32::consts::{FRAC_PI_2, TAU};

use glam::{Quat, Vec3, Vec4};

use crate::io::{SkinnedImport, voxelize_skinned};
use crate::mesh::{Material, MeshModel, TriangleMesh};
use crate::scene::{Document, ObjectKind};
use crate::skin::SkinError;
use crate::skin::clip::{AnimationClip, Channel, Interpolation, Property};
use crate::skin::skeleton::{Joint, Skeleton};
use crate::voxelize::{Resolution, VoxelizeSettings};

/// Radius of the measured cylinder ([`bending_cylinder_document`]).
pub const CYLINDER_RADIUS: f32 = 0.4;
/// Half length of the measured cylinder.
pub const CYLINDER_HALF_LENGTH: f32 = 1.0;
/// Segments around the measured cylinder.
pub const CYLINDER_SEGMENTS: u32 = 48;

/// Half the height of the strip between the two rigid halves, as a fraction of the radius.
const STRIP: f32 = 1e-3;

/// The bending cylinder as an import (mesh in bind pose, two joints, the `bend` clip); see the
/// module doc. `segments` around (at least 3).
#[must_use]
pub fn bending_cylinder(radius: f32, half_length: f32, segments: u32) -> SkinnedImport {
    let segments = segments.max(3);
    let eps = STRIP * radius;
    // Rings bottom to top: (y, joint).
    let rings = [(-half_length, 0u16), (-eps, 0), (eps, 1), (half_length, 1)];
    let mut mesh = TriangleMesh::default();
    let push = |mesh: &mut TriangleMesh, p: Vec3, n: Vec3, joint: u16| {
        mesh.positions.push(p);
        mesh.normals.push(n);
        mesh.joints.push([joint, 0, 0, 0]);
        mesh.weights.push([1.0, 0.0, 0.0, 0.0]);
        (mesh.positions.len() - 1) as u32
    };
    let ring_start: Vec<u32> = rings
        .iter()
        .map(|&(y, joint)| {
            let start = mesh.positions.len() as u32;
            for s in 0..segments {
                let a = TAU * s as f32 / segments as f32;
                let n = Vec3::new(a.cos(), 0.0, -a.sin());
                push(&mut mesh, Vec3::new(0.0, y, 0.0) + n * radius, n, joint);
            }
            start
        })
        .collect();
    // Sides: counter-clockwise seen from outside.
    for r in 0..rings.len() - 1 {
        for s in 0..segments {
            let t = (s + 1) % segments;
            let (a, b) = (ring_start[r] + s, ring_start[r] + t);
            let (c, d) = (ring_start[r + 1] + s, ring_start[r + 1] + t);
            mesh.indices.extend([a, b, d, a, d, c]);
        }
    }
    // Caps.
    for (r, normal) in [(0usize, -Vec3::Y), (rings.len() - 1, Vec3::Y)] {
        let (y, joint) = rings[r];
        let centre = push(&mut mesh, Vec3::new(0.0, y, 0.0), normal, joint);
        for s in 0..segments {
            let t = (s + 1) % segments;
            let (a, b) = (ring_start[r] + s, ring_start[r] + t);
            if normal.y > 0.0 {
                mesh.indices.extend([centre, a, b]);
            } else {
                mesh.indices.extend([centre, b, a]);
            }
        }
    }
    let skeleton = Skeleton::new(vec![
        Joint {
            name: "root".into(),
            ..Joint::default()
        },
        Joint {
            name: "elbow".into(),
            parent: Some(0),
            ..Joint::default()
        },
    ])
    .map(|(s, _)| s)
    .unwrap_or_default();
    let quat = |q: Quat| Vec4::new(q.x, q.y, q.z, q.w);
    let bend = AnimationClip {
        name: "bend".into(),
        duration_secs: 2.0,
        channels: vec![Channel {
            joint: 1,
            property: Property::Rotation,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0, 2.0],
            values: vec![
                quat(Quat::IDENTITY),
                quat(Quat::from_rotation_z(FRAC_PI_2)),
                quat(Quat::from_rotation_z(FRAC_PI_2)),
            ],
        }],
        ..AnimationClip::default()
    };
    SkinnedImport {
        skeleton,
        clips: vec![bend],
        mesh: MeshModel {
            parts: vec![mesh],
            materials: vec![Material::default()],
        },
        ..SkinnedImport::default()
    }
}

/// The area, seen along Z, of the outer side of the bent elbow that only stretch can cover:
/// `R²/2` (see the module doc).
#[must_use]
pub fn bend_hole_area(radius: f32) -> f32 {
    0.5 * radius * radius
}

/// A lower bound on the uncovered area of unstretched voxels of edge `voxel` in the same view:
/// the triangle shrunk by the two-voxel conservative margin, less the band of half-weighted
/// voxels along its diagonal (see the module doc).
#[must_use]
pub fn bend_hole_area_min(radius: f32, voxel: f32) -> f32 {
    let r = (radius - 2.0 * voxel).max(0.0);
    (0.5 * r * r - 2.0 * radius * voxel).max(0.0)
}

/// A document holding the measured cylinder ([`CYLINDER_RADIUS`], [`CYLINDER_HALF_LENGTH`],
/// [`CYLINDER_SEGMENTS`]) voxelized at octree `depth` with its rig: what the tests and `thicket
/// skin-report --cylinder DEPTH` measure.
///
/// # Errors
/// [`SkinError::Voxelize`] when the voxelizer refuses the depth.
pub fn bending_cylinder_document(depth: u8) -> Result<Document, SkinError> {
    let import = bending_cylinder(CYLINDER_RADIUS, CYLINDER_HALF_LENGTH, CYLINDER_SEGMENTS);
    let v = voxelize_skinned(
        &import,
        &VoxelizeSettings {
            resolution: Resolution::Depth(depth),
            ..VoxelizeSettings::default()
        },
        &|_| true,
    )?;
    let mut doc = Document::default();
    doc.add("Bending cylinder", ObjectKind::Voxels(v.model));
    Ok(doc)
}

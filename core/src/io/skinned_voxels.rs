//! Skinned glTF → skinned voxel model: voxelize the bind-pose mesh, give every voxel the four
//! strongest joint weights of the surface point it came from (normalised to sum to 255; the
//! voxelizer's attribute transfer interpolates the triangle's vertex weights), let internal nodes
//! merge their children's weights for LOD, and attach the skeleton and clips as a [`Rig`].

use super::gltf_skinned::SkinnedImport;
use crate::scene::VoxelModel;
use crate::skin::SkinError;
use crate::skin::rig::{Rig, check_weights};
use crate::svo::MAX_SKIN_JOINTS;
use crate::voxelize::{VoxelizeSettings, VoxelizeStats, voxelize};

/// What [`voxelize_skinned`] made.
#[derive(Debug, Clone)]
pub struct SkinnedVoxels {
    /// The voxel model in bind-pose mesh space, with its rig (first clip playing at 0 s).
    pub model: VoxelModel,
    /// The voxelizer's counts.
    pub stats: VoxelizeStats,
}

/// Voxelizes an imported skinned mesh in its bind pose and attaches the rig.
///
/// # Errors
/// [`SkinError::Rig`] when the skeleton has more than [`MAX_SKIN_JOINTS`] joints (voxel joint
/// indices are bytes) or is invalid, [`SkinError::Voxelize`] when the voxelizer refuses.
pub fn voxelize_skinned(
    import: &SkinnedImport,
    settings: &VoxelizeSettings,
    progress: &dyn Fn(f32) -> bool,
) -> Result<SkinnedVoxels, SkinError> {
    let joints = import.skeleton.len();
    if joints > MAX_SKIN_JOINTS {
        return Err(SkinError::Rig {
            problem: format!(
                "the skeleton has {joints} joints; a skinned voxel model addresses at most \
                 {MAX_SKIN_JOINTS} (one byte per joint index)"
            ),
        });
    }
    let v = voxelize(&import.mesh, settings, progress)
        .map_err(|source| SkinError::Voxelize { source })?;
    let mut rig = Rig::new(import.skeleton.clone(), import.clips.clone());
    let mut reference = import.mesh.clone();
    for m in &mut reference.materials {
        // Geometry is what measurements need; the texture is in the voxels' colours already.
        m.base_color_texture = None;
    }
    for p in &mut reference.parts {
        p.uvs.clear();
        p.colors.clear();
    }
    rig.reference_mesh = Some(reference);
    rig.validate()?;
    check_weights(&v.svo, joints)?;
    Ok(SkinnedVoxels {
        model: VoxelModel {
            svo: v.svo,
            voxel_size: v.voxel_size,
            origin: v.origin,
            material_names: import
                .mesh
                .materials
                .iter()
                .map(|m| m.name.clone())
                .collect(),
            rig: Some(rig),
            volume: None,
            palette: Vec::new(),
            frames: None,
        },
        stats: v.stats,
    })
}

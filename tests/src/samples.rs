//! The sample projects in `projects/`, built deterministically from `../shared/assets`.
//!
//! `cargo run -p thicket-tests --bin make-samples` rewrites them; the test
//! `samples_are_reproducible` checks the committed files equal a fresh build, so a sample can
//! never silently drift from the code that made it.

use anyhow::{Context, Result};
use glam::{Vec2, Vec3, Vec4};
use thicket_core::io::vox::import_vox;
use thicket_core::mesh::{Material, MeshModel, TriangleMesh};
use thicket_core::scene::{Document, Light, MeshObject, ObjectKind, Transform};

use crate::asset;

/// Names of the samples, as in `projects/NAME.thicket.json`.
pub const SAMPLES: [&str; 3] = ["house", "mixed", "terrain"];

/// A flat square ground plane of half-size `half` at height `y`, facing +Y.
#[must_use]
pub fn ground_plane(half: f32, y: f32) -> TriangleMesh {
    let positions = vec![
        Vec3::new(-half, y, -half),
        Vec3::new(half, y, -half),
        Vec3::new(half, y, half),
        Vec3::new(-half, y, half),
    ];
    TriangleMesh {
        positions,
        normals: vec![Vec3::Y; 4],
        uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
        indices: vec![0, 2, 1, 0, 3, 2],
        ..TriangleMesh::default()
    }
}

fn frame(doc: &mut Document, yaw_deg: f32, pitch_deg: f32) {
    doc.camera.yaw_deg = yaw_deg;
    doc.camera.pitch_deg = pitch_deg;
    if let Some((lo, hi)) = doc.bounds() {
        doc.camera.frame(lo, hi);
    }
}

/// Builds one sample by name.
///
/// # Errors
/// An unknown name or an asset that fails to load.
pub fn build(name: &str) -> Result<Document> {
    let mut doc = Document::default();
    match name {
        // obj_house4.vox: 180,202 voxels, 12 colours (Mike Judge, CC BY 4.0).
        "house" => {
            let path = asset("vox/mmmm/obj_house4.vox");
            import_vox(&path)
                .with_context(|| format!("loading {}", path.display()))?
                .add_to(&mut doc);
            doc.lights[0].direction = Vec3::new(-0.5, -1.0, -0.35);
            frame(&mut doc, 35.0, 25.0);
        }
        // A voxel character standing on a ground plane next to a triangle-mesh rock, lit so the
        // voxels shadow the ground and the rock occludes part of the character.
        "mixed" => {
            let vox = asset("vox/mmmm/chr_army1.vox");
            import_vox(&vox)
                .with_context(|| format!("loading {}", vox.display()))?
                .add_to(&mut doc);
            let rock_path = asset("static/kenney_rock_largeA.glb");
            let mut rock = thicket_core::io::import_gltf(&rock_path)
                .with_context(|| format!("loading {}", rock_path.display()))?;
            // Kenney's rock is about 1 unit across; the character is about 20 voxels tall.
            let rock_id = doc.add(
                "Rock",
                ObjectKind::Mesh(MeshObject {
                    model: std::mem::take(&mut rock),
                    casts_shadows: true,
                }),
            );
            let (lo, hi) = doc.bounds().context("the character has voxels")?;
            let size = hi - lo;
            if let Some(o) = doc.objects.iter_mut().find(|o| o.id == rock_id) {
                o.transform = Transform {
                    translation: Vec3::new(hi.x + size.x * 0.1, lo.y, lo.z + size.z * 0.9),
                    scale: Vec3::splat(size.y * 0.8),
                    ..Transform::default()
                };
            }
            let ground = MeshModel {
                parts: vec![ground_plane(size.max_element() * 2.5, 0.0)],
                materials: vec![Material {
                    name: "ground".into(),
                    base_color: Vec4::new(0.45, 0.5, 0.4, 1.0),
                    ..Material::default()
                }],
            };
            let ground_id = doc.add(
                "Ground",
                ObjectKind::Mesh(MeshObject {
                    model: ground,
                    casts_shadows: false,
                }),
            );
            let center = (lo + hi) * 0.5;
            if let Some(o) = doc.objects.iter_mut().find(|o| o.id == ground_id) {
                o.transform.translation = Vec3::new(center.x, lo.y, center.z);
            }
            doc.lights = vec![Light {
                direction: Vec3::new(0.6, -1.0, 0.45),
                ..Light::default()
            }];
            frame(&mut doc, 25.0, 22.0);
        }
        "terrain" => terrain(&mut doc)?,
        other => anyhow::bail!("unknown sample {other:?}; known: {}", SAMPLES.join(", ")),
    }
    doc.validate()?;
    Ok(doc)
}

/// Coarse voxels per axis of the sample terrain (the paper's Fig. 1 is a coarse noise terrain).
pub const TERRAIN_SIZE: u32 = 64;
/// Expansion factor of the sample terrain's enhancement.
pub const TERRAIN_FACTOR: u32 = 16;
/// The coarse columns `lo..hi` (x and z) whose enhancement the sample stores. The whole map at
/// 16x is about 6 M shell fragments (about 90 MB of payload at 15 bytes each), too much for the
/// repository, so the sample keeps the editable coarse map whole and stores the enhancement of
/// this block: exactly the fragments a full enhancement has there (see `terrain`).
pub const TERRAIN_BLOCK: (u32, u32) = (20, 44);

/// The enhancement settings of the sample terrain: subdivision with the paper's strata
/// (thresholds 3 and 4 by altitude parity), colours blended within a material.
#[must_use]
pub fn terrain_settings() -> thicket_core::enhance::EnhanceSettings {
    use thicket_core::enhance::{EnhanceSettings, Method, SubdivideSettings, ThresholdPattern};
    EnhanceSettings {
        method: Method::Subdivide,
        factor: TERRAIN_FACTOR,
        subdivide: SubdivideSettings {
            threshold: ThresholdPattern::Alternating {
                even: 3.0,
                odd: 4.0,
            },
        },
        ..EnhanceSettings::default()
    }
}

/// The coarse 64³ noise terrain (hidden: the editable source) and the 16x enhancement of the
/// block [`TERRAIN_BLOCK`] of its columns, as "terrain (enhanced)" (the names `thicket
/// enhance` gives). Only the block plus the rule's one-voxel dependency margin is enhanced, then
/// the fragments outside the block are dropped, which gives exactly what enhancing the whole
/// map and cropping would.
fn terrain(doc: &mut Document) -> Result<()> {
    use thicket_core::enhance::{Enhancer, sample_terrain};
    use thicket_core::scene::VoxelModel;
    use thicket_core::svo::Svo;

    let coarse = sample_terrain(TERRAIN_SIZE, 1)?;
    let (lo, hi) = TERRAIN_BLOCK;
    let margin = 1;
    let (mlo, mhi) = (lo.saturating_sub(margin), (hi + margin).min(TERRAIN_SIZE));
    let window = Svo::from_voxels(
        coarse.depth(),
        false,
        coarse
            .leaves()
            .into_iter()
            .filter(|(c, _)| (mlo..mhi).contains(&c.x) && (mlo..mhi).contains(&c.z)),
    )?;
    let settings = terrain_settings();
    let enhancer = Enhancer::new(&window, &settings)?;
    anyhow::ensure!(
        enhancer.dependency_radius() <= margin,
        "the sample's margin is smaller than the rule's dependency radius"
    );
    let f = TERRAIN_FACTOR;
    let fine = enhancer.into_fine();
    let block = Svo::from_voxels(
        fine.depth(),
        false,
        fine.leaves().into_iter().filter(|(p, _)| {
            let c = *p / f;
            (lo..hi).contains(&c.x) && (lo..hi).contains(&c.z)
        }),
    )?;
    // 4 units across for the coarse map.
    let voxel_size = 4.0 / TERRAIN_SIZE as f32;
    let names = vec![
        "default".to_owned(),
        "grass".to_owned(),
        "rock".to_owned(),
        "dirt".to_owned(),
    ];
    let coarse_id = doc.add(
        "terrain",
        ObjectKind::Voxels(VoxelModel {
            svo: coarse,
            voxel_size,
            origin: Vec3::ZERO,
            material_names: names.clone(),
            rig: None,
        }),
    );
    if let Some(o) = doc.objects.iter_mut().find(|o| o.id == coarse_id) {
        o.visible = false;
    }
    doc.add(
        "terrain (enhanced)",
        ObjectKind::Voxels(VoxelModel {
            svo: block,
            voxel_size: voxel_size / f as f32,
            origin: Vec3::ZERO,
            material_names: names,
            rig: None,
        }),
    );
    doc.lights[0].direction = Vec3::new(-0.45, -1.0, -0.3);
    frame(doc, 30.0, 30.0);
    Ok(())
}

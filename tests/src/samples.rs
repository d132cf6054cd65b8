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
pub const SAMPLES: [&str; 2] = ["house", "mixed"];

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
        other => anyhow::bail!("unknown sample {other:?}; known: {}", SAMPLES.join(", ")),
    }
    doc.validate()?;
    Ok(doc)
}

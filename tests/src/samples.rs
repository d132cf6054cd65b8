//! The sample projects in `projects/`, built deterministically from `../shared/assets`.
//!
//! `cargo run -p thicket-tests --bin make-samples` rewrites them; the test
//! `samples_are_reproducible` checks the committed files equal a fresh build, so a sample can
//! never silently drift from the code that made it.

use anyhow::{Context, Result};
use glam::{UVec3, Vec2, Vec3, Vec4};
use thicket_core::io::vox::import_vox;
use thicket_core::krs;
use thicket_core::mesh::{Material, MeshModel, TriangleMesh};
use thicket_core::scene::{
    Document, Light, MeshObject, ObjectKind, OrbitCamera, Transform, TreeBuilderLink,
};

use crate::asset;

/// Names of the samples, as in `projects/NAME.thicket.json`.
pub const SAMPLES: [&str; 11] = [
    "house",
    "mixed",
    "terrain",
    "cesiumman",
    "critter",
    "tree",
    "forest",
    "rock",
    "grassland",
    "coral",
    "woodland",
];

/// Octree depth of the CesiumMan sample: 256 voxels over its longest side (about 7 mm voxels).
pub const CESIUM_MAN_DEPTH: u8 = 8;

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
        // CesiumMan (© 2017 Cesium, CC BY 4.0) voxelized in its bind pose with joint weights,
        // carrying its skeleton and walk cycle; shown mid-stride.
        "cesiumman" => {
            use thicket_core::io::{import_skinned, voxelize_skinned};
            use thicket_core::skin::StretchStrategy;
            use thicket_core::voxelize::{Resolution, VoxelizeSettings};
            let path = asset("skinned/CesiumMan.glb");
            let import =
                import_skinned(&path).with_context(|| format!("loading {}", path.display()))?;
            let mut v = voxelize_skinned(
                &import,
                &VoxelizeSettings {
                    resolution: Resolution::Depth(CESIUM_MAN_DEPTH),
                    ..VoxelizeSettings::default()
                },
                &|_| true,
            )
            .with_context(|| format!("voxelizing {}", path.display()))?;
            if let Some(rig) = v.model.rig.as_mut() {
                rig.playback.time_secs = 0.5;
                rig.stretch.strategy = StretchStrategy::Adaptive;
            }
            doc.add("CesiumMan", ObjectKind::Voxels(v.model));
            doc.lights[0].direction = Vec3::new(-0.4, -1.0, -0.5);
            frame(&mut doc, 60.0, 12.0);
        }
        "critter" => critter(&mut doc)?,
        "tree" => krs_tree(&mut doc),
        "forest" => krs_forest(&mut doc),
        "rock" => krs_rock(&mut doc)?,
        "grassland" => krs_grassland(&mut doc)?,
        "coral" => krs_coral(&mut doc)?,
        "woodland" => krs_woodland(&mut doc)?,
        other => anyhow::bail!("unknown sample {other:?}; known: {}", SAMPLES.join(", ")),
    }
    doc.validate()?;
    Ok(doc)
}

/// Edge of one voxel of the critter sample (metres): 72 voxels tall, 1.8 m.
pub const CRITTER_VOXEL_SIZE: f32 = 0.025;

/// A character made in Thicket from boxes (as the Box tool makes them), rigged natively: a
/// 16-joint skeleton placed at the middle of each limb's thickness, bound with geodesic
/// weights, and a one-second walk cycle keyed as Euler angles. Nothing comes from a triangle
/// rig: this is the path `thicket rig` and `thicket animate` (and the editor's Rig section)
/// take.
fn critter(doc: &mut Document) -> Result<()> {
    use thicket_core::skin::bind::{BindControl, BindMethod, bind};
    use thicket_core::skin::rig::Binding;
    use thicket_core::skin::{ClipSpec, JointSpec, KeySpec, Rig, SkeletonSpec, Wrap};
    use thicket_core::svo::{Svo, Voxel};
    let skin = [232, 184, 150, 255];
    let shirt = [196, 60, 52, 255];
    let trousers = [52, 72, 140, 255];
    let boots = [60, 44, 36, 255];
    // (min, max exclusive, colour), later boxes win.
    let boxes: [([u32; 3], [u32; 3], [u8; 4]); 12] = [
        // The character faces +Z (glTF's front), so its left side is +X.
        ([9, 0, 6], [17, 28, 14], trousers),             // leg R
        ([21, 0, 6], [29, 28, 14], trousers),            // leg L
        ([9, 0, 6], [17, 5, 18], boots),                 // boot R, toes to +Z
        ([21, 0, 6], [29, 5, 18], boots),                // boot L
        ([7, 28, 4], [31, 56, 16], shirt),               // torso
        ([1, 50, 7], [7, 56, 13], shirt),                // shoulder R
        ([31, 50, 7], [37, 56, 13], shirt),              // shoulder L
        ([1, 24, 7], [6, 50, 13], shirt),                // arm R, a voxel clear of the torso
        ([32, 24, 7], [37, 50, 13], shirt),              // arm L
        ([11, 56, 3], [27, 72, 17], skin),               // head
        ([14, 63, 16], [17, 66, 17], [20, 20, 24, 255]), // eye
        ([21, 63, 16], [24, 66, 17], [20, 20, 24, 255]), // eye
    ];
    let mut voxels = Vec::new();
    for (lo, hi, colour) in boxes {
        for z in lo[2]..hi[2] {
            for y in lo[1]..hi[1] {
                for x in lo[0]..hi[0] {
                    // Hands: the arms' lowest voxels are skin.
                    let c = if !(7..31).contains(&x) && y < 28 {
                        skin
                    } else {
                        colour
                    };
                    voxels.push((UVec3::new(x, y, z), Voxel::new(c, Vec3::Y)));
                }
            }
        }
    }
    let svo = Svo::from_voxels(7, false, voxels)?;
    let size = CRITTER_VOXEL_SIZE;
    // Centred on x = 0, z = 0, feet on the ground.
    let origin = Vec3::new(-19.0 * size, 0.0, -10.0 * size);
    let at = |x: f32, y: f32, z: f32| (origin + Vec3::new(x, y, z) * size).to_array();
    let j = |name: &str, parent: Option<&str>, p: [f32; 3]| JointSpec {
        name: name.into(),
        parent: parent.map(Into::into),
        position: p,
    };
    let spec = SkeletonSpec {
        joints: vec![
            j("hip", None, at(19.0, 28.0, 10.0)),
            j("spine", Some("hip"), at(19.0, 42.0, 10.0)),
            j("neck", Some("spine"), at(19.0, 56.0, 10.0)),
            j("head", Some("neck"), at(19.0, 62.0, 10.0)),
            j("leg.R", Some("hip"), at(13.0, 26.0, 10.0)),
            j("shin.R", Some("leg.R"), at(13.0, 14.0, 10.0)),
            j("foot.R", Some("shin.R"), at(13.0, 3.0, 10.0)),
            j("leg.L", Some("hip"), at(25.0, 26.0, 10.0)),
            j("shin.L", Some("leg.L"), at(25.0, 14.0, 10.0)),
            j("foot.L", Some("shin.L"), at(25.0, 3.0, 10.0)),
            j("arm.R", Some("spine"), at(3.5, 52.0, 10.0)),
            j("forearm.R", Some("arm.R"), at(3.5, 39.0, 10.0)),
            j("hand.R", Some("forearm.R"), at(3.5, 27.0, 10.0)),
            j("arm.L", Some("spine"), at(34.5, 52.0, 10.0)),
            j("forearm.L", Some("arm.L"), at(34.5, 39.0, 10.0)),
            j("hand.L", Some("forearm.L"), at(34.5, 27.0, 10.0)),
        ],
    };
    let bounds = svo.bounds().map(|(lo, hi)| {
        (
            origin + lo.as_vec3() * size,
            origin + (hi + 1).as_vec3() * size,
        )
    });
    let skeleton = spec.to_skeleton(bounds)?;
    let (svo, _) = bind(
        &svo,
        origin,
        size,
        &skeleton,
        BindMethod::Geodesic,
        BindControl::default(),
    )?;
    // A walk: legs swing ±25° (forward is +Z, a negative turn about X), knees bend on the
    // way forward, arms swing against the legs, the hip bobs twice per step.
    let key = |joint: &str, time: f32, x_deg: f32| KeySpec {
        joint: joint.into(),
        time,
        rotation_deg: Some([x_deg, 0.0, 0.0]),
        translation: None,
    };
    let mut keys = Vec::new();
    for (k, t) in [0.0f32, 0.25, 0.5, 0.75, 1.0].into_iter().enumerate() {
        let swing = [25.0, 0.0, -25.0, 0.0, 25.0][k];
        let knee = [0.0, 35.0, 0.0, 5.0, 0.0][k];
        keys.push(key("leg.L", t, -swing));
        keys.push(key("leg.R", t, swing));
        keys.push(key("shin.L", t, knee));
        keys.push(key("shin.R", t, [0.0, 5.0, 0.0, 35.0, 0.0][k]));
        keys.push(key("arm.L", t, 0.8 * swing));
        keys.push(key("arm.R", t, -0.8 * swing));
        keys.push(key("forearm.L", t, -15.0));
        keys.push(key("forearm.R", t, -15.0));
        keys.push(KeySpec {
            joint: "hip".into(),
            time: t,
            rotation_deg: Some([0.0, 0.0, 0.0]),
            translation: Some([0.0, [0.0, 0.03, 0.0, 0.03, 0.0][k], 0.0]),
        });
    }
    let walk = ClipSpec {
        name: "walk".into(),
        length: 1.0,
        interpolation: thicket_core::skin::author::KeyInterpolation::Cubic,
        looping: true,
        keys,
        frame_rate: 24.0,
    };
    let clip = walk.to_clip(&skeleton)?;
    let binding = Binding {
        method: BindMethod::Geodesic,
        skeleton: SkeletonSpec::of_skeleton(&skeleton),
    };
    let mut rig = Rig::new(skeleton, vec![clip]);
    rig.binding = Some(binding);
    rig.playback.wrap = Wrap::Loop;
    rig.playback.time_secs = 0.25;
    let id = doc.add(
        "Critter",
        ObjectKind::Voxels(thicket_core::scene::VoxelModel {
            svo,
            voxel_size: size,
            origin,
            rig: Some(rig),
            ..thicket_core::scene::VoxelModel::default()
        }),
    );
    // The whole figure sways ±8° about Y over the walk (rigid per-object keys on the rig's
    // clock): a keyed object transform next to the bones.
    let mut motion = thicket_core::scene::ObjectMotion::default();
    for (t, deg) in [(0.0f32, 0.0f32), (0.25, 8.0), (0.75, -8.0), (1.0, 0.0)] {
        motion.set_key(
            t,
            &thicket_core::scene::Transform {
                rotation: glam::Quat::from_rotation_y(deg.to_radians()),
                ..thicket_core::scene::Transform::default()
            },
        );
    }
    if let Some(o) = doc.objects.iter_mut().find(|o| o.id == id) {
        o.motion = Some(motion);
    }
    doc.apply_motion(None);
    doc.lights[0].direction = Vec3::new(-0.5, -1.0, -0.6);
    frame(doc, 30.0, 12.0);
    Ok(())
}

/// Coarse voxels per axis of the sample terrain (the paper's Fig. 1 is a coarse noise terrain).
pub const TERRAIN_SIZE: u32 = 64;
/// Expansion factor of the sample terrain's enhancement.
pub const TERRAIN_FACTOR: u32 = 16;
/// The coarse columns `lo..hi` (x and z) of the 64³ map that the sample cuts out as a map of its
/// own and enhances whole. The whole map at 16x is about 6.4 M shell fragments (about 96 MB of
/// payload at 15 bytes each), too much for the repository, so the sample takes a block of it.
pub const TERRAIN_BLOCK: (u32, u32) = (20, 44);
/// Coarse layers kept below the lowest column top of the block: the piece keeps a base of dirt
/// and rock under its lowest point instead of standing on the full 64-voxel-deep map.
pub const TERRAIN_BASE: u32 = 3;

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

/// A block of the coarse 64³ noise terrain, cut out as a map of its own (hidden: the editable
/// source, "terrain"), and its 16x enhancement, "terrain (enhanced)": what `thicket enhance
/// --object terrain --factor 16` makes of it. Enhancing the cut-out block, rather than cropping
/// an enhancement of the whole map, closes its sides into cliffs: the enhancer sees empty space
/// past the cut and makes fragments there, so the piece is a closed solid.
fn terrain(doc: &mut Document) -> Result<()> {
    use thicket_core::enhance::{Enhancer, sample_terrain};
    use thicket_core::scene::VoxelModel;
    use thicket_core::svo::Svo;

    let map = sample_terrain(TERRAIN_SIZE, 1)?;
    let (lo, hi) = TERRAIN_BLOCK;
    let in_block = |c: UVec3| (lo..hi).contains(&c.x) && (lo..hi).contains(&c.z);
    let mut tops = std::collections::HashMap::new();
    for (c, _) in map.leaves() {
        if in_block(c) {
            let top = tops.entry((c.x, c.z)).or_insert(0);
            *top = (*top).max(c.y + 1);
        }
    }
    let lowest = tops
        .values()
        .copied()
        .min()
        .context("the block holds no terrain")?;
    let base = lowest.saturating_sub(TERRAIN_BASE);
    let block: Vec<(UVec3, thicket_core::svo::Voxel)> = map
        .leaves()
        .into_iter()
        .filter(|(c, _)| in_block(*c) && c.y >= base)
        .map(|(c, v)| (c - UVec3::new(lo, base, lo), v))
        .collect();
    let extent = (hi - lo).max(TERRAIN_SIZE - base);
    let depth = extent.next_power_of_two().trailing_zeros() as u8;
    let coarse = Svo::from_voxels(depth, false, block)?;
    let fine = Enhancer::new(&coarse, &terrain_settings())?.into_fine();
    let f = TERRAIN_FACTOR;
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
            volume: None,
            palette: Vec::new(),
            frames: None,
        }),
    );
    if let Some(o) = doc.objects.iter_mut().find(|o| o.id == coarse_id) {
        o.visible = false;
    }
    let fine_id = doc.add(
        "terrain (enhanced)",
        ObjectKind::Voxels(VoxelModel {
            svo: fine,
            voxel_size: voxel_size / f as f32,
            origin: Vec3::ZERO,
            material_names: names,
            rig: None,
            volume: None,
            palette: Vec::new(),
            frames: None,
        }),
    );
    // Linked, so the editor keeps the fine terrain in step with strokes on the coarse one.
    doc.enhancements.push(thicket_core::scene::EnhancementLink {
        source: coarse_id,
        target: fine_id,
        settings: terrain_settings(),
    });
    // A low sun from the side the camera looks across: the terraces and the ridge cast shadows
    // the view can see (from high above, almost none showed and the shadow knobs measured
    // nothing on this sample).
    doc.lights[0].direction = Vec3::new(-0.9, -0.45, 0.2);
    frame(doc, 30.0, 30.0);
    Ok(())
}

/// Height of a KRS surface above `(x, z)`: a ray traced straight down from high above.
fn surface_height(scene: &krs::PreparedScene, x: f32, z: f32) -> Option<f32> {
    let top = 1000.0;
    let hit = krs::trace(
        scene,
        Vec3::new(x, top, z),
        Vec3::NEG_Y,
        &krs::TraceSettings {
            pixel_cone_ratio: 0.0,
            min_epsilon: 1e-4,
            max_steps: 4096,
            max_distance: 2.0 * top,
            ..krs::TraceSettings::default()
        },
    );
    hit.hit.then_some(hit.position.y)
}

/// The KRS tree preset (2^8 leaves, 7 branches on its route) on a triangle-mesh ground: KRS
/// and mesh share the depth buffer, and the tree shadows the ground by shadow rays. The flat
/// ground, lowest in the scene, casts nothing, so the frame builds no shadow map for it (one
/// would cost every ground pixel its filter taps for no visible shadow). The tree records its
/// tree-builder parameters, so the editor's builder opens it ("Edit tree").
fn krs_tree(doc: &mut Document) {
    let tree = doc.add("Tree", ObjectKind::Krs(krs::presets::tree()));
    // The parameters it was built from: the editor's tree builder opens it with them.
    doc.tree_builders.push(TreeBuilderLink {
        object: tree,
        params: krs::presets::tree_params(),
    });
    let ground = MeshModel {
        parts: vec![ground_plane(7.0, 0.0)],
        materials: vec![Material {
            name: "grass".into(),
            base_color: Vec4::new(0.35, 0.45, 0.25, 1.0),
            ..Material::default()
        }],
    };
    doc.add(
        "Ground",
        ObjectKind::Mesh(MeshObject {
            model: ground,
            casts_shadows: false,
        }),
    );
    doc.lights = vec![Light {
        direction: Vec3::new(-0.5, -1.0, -0.35),
        ..Light::default()
    }];
    doc.camera = OrbitCamera {
        target: Vec3::new(0.0, 2.6, 0.0),
        yaw_deg: 30.0,
        pitch_deg: 12.0,
        distance: 11.0,
        near: 0.1,
        far: 100.0,
        ..OrbitCamera::default()
    };
    doc.background = Vec3::new(0.55, 0.65, 0.8);
}

/// The forest preset (the tree reflected by 17 more mirrors: 2^17 trees, 33,423,360 kernel
/// instances) on a KRS ground plane, seen from the forest's corner.
fn krs_forest(doc: &mut Document) {
    for o in krs::presets::forest_scene().objects {
        let name = match o.name.as_str() {
            "forest" => "Forest".to_owned(),
            "ground" => "Ground".to_owned(),
            other => other.to_owned(),
        };
        doc.add(name, ObjectKind::Krs(o));
    }
    doc.lights = vec![Light {
        direction: Vec3::new(0.4, -0.8, 0.5),
        ..Light::default()
    }];
    doc.camera = OrbitCamera {
        target: Vec3::new(40.0, 2.0, 40.0),
        yaw_deg: 225.0,
        pitch_deg: 14.0,
        distance: 70.0,
        near: 0.5,
        far: 4000.0,
        ..OrbitCamera::default()
    };
    doc.background = Vec3::new(0.55, 0.65, 0.8);
}

/// KRS terrain (a ground half-space folded by 14 tilted mirrors) with three battered rocks
/// (§7.1, Fig. 7: planar kernels, 14 reflection levels, distortion, smooth shading, triplanar
/// texture), each from its own seed, each placed at the terrain height traced under it.
fn krs_rock(doc: &mut Document) -> Result<()> {
    let terrain = krs::presets::terrain();
    let ground = krs::KrsScene {
        objects: vec![terrain.clone()],
    }
    .prepare()?;
    doc.add("Terrain", ObjectKind::Krs(terrain));
    for (i, (x, z, scale, seed)) in [
        (0.0f32, 0.0f32, 1.3f32, 5u64),
        (2.4, -1.3, 0.75, 12),
        (-2.0, 1.3, 0.55, 23),
    ]
    .into_iter()
    .enumerate()
    {
        let y = surface_height(&ground, x, z)
            .with_context(|| format!("terrain height under rock {i}"))?;
        let id = doc.add(
            format!("Rock {}", i + 1),
            ObjectKind::Krs(krs::presets::battered_rock(seed)),
        );
        if let Some(o) = doc.objects.iter_mut().find(|o| o.id == id) {
            // The preset sits 0.55 above its origin; sink it a little into the soil.
            o.transform = Transform {
                translation: Vec3::new(x, y - 0.2 * scale, z),
                rotation: glam::Quat::IDENTITY,
                scale: Vec3::splat(scale),
            };
        }
    }
    doc.lights = vec![Light {
        direction: Vec3::new(-0.6, -0.7, -0.3),
        ..Light::default()
    }];
    let y0 = surface_height(&ground, 0.0, 0.0).context("terrain height")?;
    doc.camera = OrbitCamera {
        target: Vec3::new(0.0, y0 + 0.6, 0.0),
        yaw_deg: 20.0,
        pitch_deg: 22.0,
        distance: 7.0,
        near: 0.1,
        far: 500.0,
        ..OrbitCamera::default()
    };
    doc.background = Vec3::new(0.6, 0.68, 0.78);
    Ok(())
}

/// Adds the terrain and the scattered piece of [`krs::presets::on_terrain`] as two objects.
fn add_on_terrain(doc: &mut Document, scene: krs::KrsScene, piece: &str) {
    for (o, name) in scene.objects.into_iter().zip(["Terrain", piece]) {
        doc.add(name, ObjectKind::Krs(o));
    }
}

/// Grass tufts (a curved blade fanned by 8 mirrors: 256 blades) scattered by 12 more
/// reflections that the KRS terrain under them shares (§7.2), so every one of the 4,096 tufts
/// stands on the ground: about a million blades.
fn krs_grassland(doc: &mut Document) -> Result<()> {
    let scene = krs::presets::on_terrain(
        krs::presets::grass_tuft(),
        krs::Material::new(Vec3::new(0.42, 0.36, 0.22), 5),
        &krs::presets::Scatter {
            count: 12,
            jitter: 0.08,
            tilt: 0.12,
            fine_levels: 8,
            gap: (-0.75, -0.5),
            seed: 8,
            regular: false,
        },
        0,
    )?;
    add_on_terrain(doc, scene, "Grass");
    doc.lights = vec![Light {
        direction: Vec3::new(-0.5, -0.6, -0.4),
        ..Light::default()
    }];
    doc.camera = OrbitCamera {
        target: Vec3::new(3.0, 0.3, 3.0),
        yaw_deg: 215.0,
        pitch_deg: 26.0,
        distance: 5.0,
        near: 0.05,
        far: 400.0,
        ..OrbitCamera::default()
    };
    doc.background = Vec3::new(0.6, 0.7, 0.82);
    Ok(())
}

/// A reef: the coral preset (capsule branches, round tips, slightly distorted) scattered by 5
/// reflections over a sandy KRS floor that shares them; the floor takes the coral's warp, so the
/// 32 corals stand on it exactly.
fn krs_coral(doc: &mut Document) -> Result<()> {
    let scene = krs::presets::on_terrain(
        krs::presets::coral(),
        krs::Material::new(Vec3::new(0.78, 0.72, 0.55), 8),
        &krs::presets::Scatter {
            count: 5,
            jitter: 0.3,
            tilt: 0.1,
            fine_levels: 5,
            gap: (0.0, 0.5),
            seed: 21,
            regular: false,
        },
        4,
    )?;
    add_on_terrain(doc, scene, "Coral");
    doc.lights = vec![Light {
        direction: Vec3::new(-0.3, -1.0, -0.45),
        ..Light::default()
    }];
    doc.camera = OrbitCamera {
        target: Vec3::new(0.8, 0.5, 0.8),
        yaw_deg: 35.0,
        pitch_deg: 20.0,
        distance: 4.2,
        near: 0.05,
        far: 200.0,
        ..OrbitCamera::default()
    };
    doc.background = Vec3::new(0.35, 0.55, 0.7);
    Ok(())
}

/// A forest on KRS terrain (§7.2), grown from the tree sample's tree as an artist grows it in
/// the editor (Forest section, or `thicket forest --on Terrain`): 128 × 128 trees by 14 more
/// reflections that the terrain shares (about 4 million kernel instances); the terrain adds 5
/// small folds of its own between the trees. Every tree stands on the ground, leaning with the
/// slope it grows on. The tree stays in the project, hidden, so the forest can be regrown.
fn krs_woodland(doc: &mut Document) -> Result<()> {
    let tree = doc.add("Tree", ObjectKind::Krs(krs::presets::tree()));
    doc.tree_builders.push(TreeBuilderLink {
        object: tree,
        params: krs::presets::tree_params(),
    });
    let radius = krs::KrsScene {
        objects: vec![krs::presets::tree()],
    }
    .prepare()?
    .objects[0]
        .bound_world
        .context("the tree is bounded")?
        .1;
    let terrain = doc.add(
        "Terrain",
        ObjectKind::Krs(krs::presets::folded_ground(
            krs::Material::new(Vec3::new(0.33, 0.38, 0.2), 5),
            5,
            radius,
            42,
        )),
    );
    let plan = doc
        .plan_forest(&[tree], Some(terrain), &woodland_forest())
        .map_err(anyhow::Error::msg)?;
    let ids = doc.apply_forest(plan);
    if let Some(o) = doc.objects.iter_mut().find(|o| Some(&o.id) == ids.first()) {
        o.name = "Forest".to_owned();
    }
    doc.lights = vec![Light {
        direction: Vec3::new(0.4, -0.8, 0.5),
        ..Light::default()
    }];
    doc.camera = OrbitCamera {
        target: Vec3::new(30.0, 2.0, 30.0),
        yaw_deg: 225.0,
        pitch_deg: 16.0,
        distance: 55.0,
        near: 0.5,
        far: 3000.0,
        ..OrbitCamera::default()
    };
    doc.background = Vec3::new(0.55, 0.65, 0.8);
    Ok(())
}

/// How the woodland sample's forest is grown: 2^14 trees about 8.8 apart (the bounding radius
/// of the tree times 2.3), rows turned by up to 0.06 rad, gaps varied by up to 12 %, the ground
/// tilted by up to 0.03 rad per fold.
#[must_use]
pub fn woodland_forest() -> krs::forest::ForestParams {
    krs::forest::ForestParams {
        trees: [128, 128],
        area: [1126.0, 1126.0],
        jitter: 0.06,
        spread: 0.12,
        tilt: 0.03,
        warp: 0.0,
        warp_frequency: 0.5,
        seed: 42,
    }
}

//! Procedural scenes for tests, benchmarks and quick previews: surface-only voxel spheres and
//! terrain built with [`Svo::from_fn`] (work follows the surface), a ground-plane mesh, and a
//! mixed scene. Sizes are parameters so a test can stay small and a benchmark can go to
//! millions of voxels.

use glam::{Quat, UVec3, Vec3, Vec4};

use crate::mesh::{Material, MeshModel, TriangleMesh, unit_cube};
use crate::scene::{Document, Light, MeshObject, ObjectKind, Transform, VoxelModel};
use crate::svo::{Svo, SvoError, Voxel};

/// A hollow sphere shell about `thickness` voxels thick, centred in a `2^depth` octree with
/// radius `radius_fraction` of half the extent. Normals point outward; colour varies smoothly
/// with the normal so LOD averages stay close to their leaves.
///
/// # Errors
/// [`SvoError::BadDepth`].
pub fn sphere_shell(depth: u8, radius_fraction: f32) -> Result<Svo, SvoError> {
    let extent = (1u64 << depth) as f32;
    let center = Vec3::splat(0.5 * extent);
    let radius = 0.5 * extent * radius_fraction.clamp(0.0, 1.0);
    // Half of √3: the shell is closed for rays in every direction.
    let half_thickness = 0.87f32;
    Svo::from_fn(
        depth,
        false,
        move |origin: UVec3, size: u32| {
            let lo = origin.as_vec3();
            let hi = lo + Vec3::splat(size as f32);
            let nearest = center.clamp(lo, hi);
            let min_d = (nearest - center).length();
            let far_corner = Vec3::new(
                if center.x - lo.x > hi.x - center.x {
                    lo.x
                } else {
                    hi.x
                },
                if center.y - lo.y > hi.y - center.y {
                    lo.y
                } else {
                    hi.y
                },
                if center.z - lo.z > hi.z - center.z {
                    lo.z
                } else {
                    hi.z
                },
            );
            let max_d = (far_corner - center).length();
            min_d <= radius + half_thickness + 1.0 && max_d >= radius - half_thickness - 1.0
        },
        move |c: UVec3| {
            let p = c.as_vec3() + Vec3::splat(0.5) - center;
            let d = p.length();
            if (d - radius).abs() > half_thickness {
                return None;
            }
            let n = p.normalize_or_zero();
            let color = [
                (150.0 + 90.0 * n.x) as u8,
                (140.0 + 80.0 * n.y) as u8,
                (120.0 + 60.0 * n.z) as u8,
                255,
            ];
            Some(Voxel::new(color, n))
        },
    )
}

/// Height of the procedural terrain at column `(x, z)` for an octree of `extent` voxels.
fn terrain_height(x: f32, z: f32, extent: f32) -> f32 {
    let (u, v) = (x / extent, z / extent);
    extent
        * (0.3
            + 0.08 * (u * 9.0).sin() * (v * 7.0).cos()
            + 0.04 * (u * 23.0 + 1.0).sin() * (v * 19.0 + 2.0).sin())
}

/// A rolling heightfield surface, one or two voxels thick, filling the octree's x and z.
/// Colour goes from green (low) to brown-white (high).
///
/// # Errors
/// [`SvoError::BadDepth`].
pub fn terrain(depth: u8) -> Result<Svo, SvoError> {
    let extent = (1u64 << depth) as f32;
    // |∂h/∂x| ≤ extent · (0.08·9 + 0.04·23) / extent = 1.64 voxels per voxel.
    let slope = 1.7f32;
    Svo::from_fn(
        depth,
        false,
        move |origin: UVec3, size: u32| {
            let s = size as f32;
            let (cx, cz) = (origin.x as f32 + 0.5 * s, origin.z as f32 + 0.5 * s);
            let h = terrain_height(cx, cz, extent);
            let reach = slope * s + 2.0;
            let (y0, y1) = (origin.y as f32, origin.y as f32 + s);
            y1 >= h - reach && y0 <= h + reach
        },
        move |c: UVec3| {
            let (x, z) = (c.x as f32 + 0.5, c.z as f32 + 0.5);
            let h = terrain_height(x, z, extent);
            let y = c.y as f32 + 0.5;
            // Thick enough where steep that columns stay connected.
            let dx = terrain_height(x + 1.0, z, extent) - h;
            let dz = terrain_height(x, z + 1.0, extent) - h;
            let thickness = 1.0 + dx.abs().max(dz.abs());
            if y > h || y < h - thickness {
                return None;
            }
            let n = Vec3::new(-dx, 1.0, -dz).normalize_or_zero();
            let t = ((h / extent - 0.2) / 0.2).clamp(0.0, 1.0);
            let color = [
                (70.0 + 130.0 * t) as u8,
                (130.0 + 60.0 * t) as u8,
                (60.0 + 120.0 * t) as u8,
                255,
            ];
            Some(Voxel::new(color, n))
        },
    )
}

/// A voxel object spanning the world box `[-half, half]³`.
#[must_use]
pub fn voxel_object(svo: Svo, half: f32) -> ObjectKind {
    let extent = svo.extent() as f32;
    ObjectKind::Voxels(VoxelModel {
        svo,
        voxel_size: 2.0 * half / extent,
        origin: Vec3::splat(-half),
        material_names: Vec::new(),
        rig: None,
        volume: None,
        palette: Vec::new(),
        frames: None,
    })
}

/// A square in the XZ plane at height 0, `2 × half` wide, facing +Y, one colour.
#[must_use]
pub fn ground_plane(half: f32, color: Vec4) -> MeshModel {
    let mut mesh = TriangleMesh {
        positions: vec![
            Vec3::new(-half, 0.0, -half),
            Vec3::new(half, 0.0, -half),
            Vec3::new(half, 0.0, half),
            Vec3::new(-half, 0.0, half),
        ],
        indices: vec![0, 2, 1, 0, 3, 2],
        ..TriangleMesh::default()
    };
    mesh.compute_normals();
    MeshModel {
        parts: vec![mesh],
        materials: vec![Material {
            name: "ground".into(),
            base_color: color,
            ..Material::default()
        }],
    }
}

/// A document with one voxel sphere shell (world radius about `radius_fraction`) at the origin.
///
/// # Errors
/// [`SvoError::BadDepth`].
pub fn sphere_document(depth: u8, radius_fraction: f32) -> Result<Document, SvoError> {
    let mut doc = Document::default();
    doc.add(
        "Sphere",
        voxel_object(sphere_shell(depth, radius_fraction)?, 1.0),
    );
    Ok(doc)
}

/// A mixed scene: a voxel sphere resting above a ground-plane mesh, a triangle-mesh cube beside
/// it, one sun casting shadows. Meshes cast shadows too.
///
/// # Errors
/// [`SvoError::BadDepth`].
pub fn mixed_document(sphere_depth: u8) -> Result<Document, SvoError> {
    let mut doc = Document::default();
    let sphere = doc.add(
        "Sphere",
        voxel_object(sphere_shell(sphere_depth, 0.9)?, 0.5),
    );
    let cube = doc.add(
        "Cube",
        ObjectKind::Mesh(MeshObject {
            model: MeshModel {
                parts: vec![unit_cube()],
                materials: vec![Material {
                    name: "cube".into(),
                    base_color: Vec4::new(0.8, 0.2, 0.15, 1.0),
                    ..Material::default()
                }],
            },
            casts_shadows: true,
        }),
    );
    let ground = doc.add(
        "Ground",
        ObjectKind::Mesh(MeshObject {
            model: ground_plane(2.0, Vec4::new(0.6, 0.6, 0.55, 1.0)),
            casts_shadows: true,
        }),
    );
    for o in &mut doc.objects {
        if o.id == sphere {
            o.transform.translation = Vec3::new(0.0, 0.7, 0.0);
        } else if o.id == cube {
            o.transform = Transform {
                translation: Vec3::new(0.9, 0.3, 0.4),
                rotation: Quat::from_rotation_y(0.5),
                scale: Vec3::splat(0.6),
            };
        } else if o.id == ground {
            o.transform = Transform::default();
        }
    }
    doc.lights = vec![Light {
        direction: Vec3::new(-0.5, -1.0, -0.35),
        ..Light::default()
    }];
    doc.camera.target = Vec3::new(0.2, 0.4, 0.0);
    doc.camera.distance = 4.2;
    doc.camera.pitch_deg = 25.0;
    doc.camera.yaw_deg = 20.0;
    doc.camera.near = 0.05;
    doc.camera.far = 50.0;
    Ok(doc)
}

/// The house sample's wall seen obliquely from a few voxels away (yaw 60°, pitch 20°, distance
/// 45 from the project's target, clip planes fitted): its leaves are tens of pixels wide, the
/// view where exact cubes matter (the render bench, `cube_profile` and the GPU parity test use
/// it). `None` for a document without bounds.
#[must_use]
pub fn house_close_up(house: &Document) -> Option<crate::scene::OrbitCamera> {
    let (lo, hi) = house.bounds()?;
    let mut c = crate::scene::OrbitCamera {
        yaw_deg: 60.0,
        pitch_deg: 20.0,
        distance: 45.0,
        ..house.camera
    };
    c.fit_clip(lo, hi);
    Some(c)
}

/// A document holding one solid ball of radius 27 voxels in a 64³ octree (0.05 world units a
/// voxel), its camera framing it: one colour inside and a shell of many, so its inside is
/// tiles and its surface is not (tile tests of both renderers).
#[must_use]
pub fn solid_ball() -> Document {
    ball(BallInside::Coloured)
}

/// What fills [`ball`]'s inside.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BallInside {
    /// One colour.
    Coloured,
    /// Voxels enclosed on all six faces are interior ([`Voxel::INTERIOR`]), as a solid
    /// import's; the rest is the coloured shell.
    Interior,
    /// Nothing: the shell of [`Self::Interior`] alone (what the renderers should draw of it).
    Hollow,
}

/// [`solid_ball`] with its inside as `inside` says.
#[must_use]
pub fn ball(inside: BallInside) -> Document {
    let (depth, r) = (6u8, 27.0f32);
    let e = 1u32 << depth;
    let c = e as f32 / 2.0;
    let in_ball = |p: glam::IVec3| (p.as_vec3() + 0.5 - c).length() <= r;
    let mut voxels = Vec::new();
    for z in 0..e {
        for y in 0..e {
            for x in 0..e {
                let p = Vec3::new(x as f32, y as f32, z as f32) + 0.5 - c;
                let d = p.length();
                if d > r {
                    continue;
                }
                let at = UVec3::new(x, y, z).as_ivec3();
                let enclosed = crate::svo::FACE_NEIGHBOURS.iter().all(|&f| in_ball(at + f));
                let v = if d > r - 1.5 {
                    Voxel::new([(x * 4) as u8, (y * 4) as u8, 90, 255], p)
                } else {
                    Voxel::new([200, 60, 20, 255], Vec3::Z)
                };
                let v = match inside {
                    BallInside::Coloured => v,
                    BallInside::Interior if enclosed => Voxel::INTERIOR,
                    BallInside::Hollow if enclosed => continue,
                    BallInside::Interior | BallInside::Hollow => v,
                };
                voxels.push((UVec3::new(x, y, z), v));
            }
        }
    }
    let mut doc = Document::default();
    let svo = Svo::from_voxels(depth, false, voxels)
        .unwrap_or_else(|_| unreachable!("every voxel is inside the 64³ octree"));
    doc.add(
        "Ball",
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: 0.05,
            ..VoxelModel::default()
        }),
    );
    doc.camera.frame(Vec3::ZERO, Vec3::splat(3.2));
    doc
}

/// A figure made of voxel boxes and rigged natively (a skeleton spec, a binding, a clip of
/// Euler keys, as `thicket rig` and `thicket animate` make it): the tests' rigged models.
/// Positions are in voxels.
pub struct BoxFigure<'a> {
    /// The object's name.
    pub name: &'a str,
    /// Half-open voxel boxes `(lo, hi)`.
    pub boxes: &'a [([u32; 3], [u32; 3])],
    /// Octree depth.
    pub depth: u8,
    /// Voxel size in the model's units.
    pub voxel_size: f32,
    /// Where voxel (0, 0, 0)'s corner lies.
    pub origin: Vec3,
    /// Whether voxels enclosed on all six faces are [`Voxel::INTERIOR`] (a solid import's
    /// inside) rather than coloured.
    pub interior: bool,
    /// Colour of a voxel.
    pub color: fn(UVec3) -> [u8; 4],
    /// `(name, parent, position in voxels)`.
    pub joints: &'a [(&'a str, Option<&'a str>, [f32; 3])],
    /// How the skeleton is bound.
    pub method: crate::skin::bind::BindMethod,
    /// The looping 1 s clip "walk": `(joint, time, rotation in degrees)`.
    pub keys: &'a [(&'a str, f32, [f32; 3])],
    /// How its keys interpolate.
    pub interpolation: crate::skin::author::KeyInterpolation,
}

/// The document holding `f` as its one object, playing its clip from 0 s.
///
/// # Panics
/// When the figure does not fit its octree, or its skeleton or keys are invalid (a test's
/// own mistake).
#[must_use]
pub fn box_figure(f: &BoxFigure<'_>) -> Document {
    use crate::skin::Rig;
    use crate::skin::author::{ClipSpec, JointSpec, KeySpec, SkeletonSpec};
    use crate::skin::bind::{BindControl, bind};
    let solid = |p: glam::IVec3| {
        f.boxes.iter().any(|(lo, hi)| {
            p.cmpge(UVec3::from(*lo).as_ivec3()).all() && p.cmplt(UVec3::from(*hi).as_ivec3()).all()
        })
    };
    let mut voxels = Vec::new();
    for &(lo, hi) in f.boxes {
        for z in lo[2]..hi[2] {
            for y in lo[1]..hi[1] {
                for x in lo[0]..hi[0] {
                    let c = UVec3::new(x, y, z);
                    let enclosed = f.interior
                        && crate::svo::FACE_NEIGHBOURS
                            .iter()
                            .all(|&d| solid(c.as_ivec3() + d));
                    let v = if enclosed {
                        Voxel::INTERIOR
                    } else {
                        Voxel::new((f.color)(c), Vec3::Y)
                    };
                    voxels.push((c, v));
                }
            }
        }
    }
    let svo = Svo::from_voxels(f.depth, false, voxels)
        .unwrap_or_else(|e| unreachable!("the figure fits its octree: {e}"));
    let skeleton = SkeletonSpec {
        joints: f
            .joints
            .iter()
            .map(|&(name, parent, p)| JointSpec {
                name: name.into(),
                parent: parent.map(Into::into),
                position: (f.origin + Vec3::from(p) * f.voxel_size).to_array(),
            })
            .collect(),
    }
    .to_skeleton(None)
    .unwrap_or_else(|e| unreachable!("a valid skeleton: {e}"));
    let (svo, _) = bind(
        &svo,
        f.origin,
        f.voxel_size,
        &skeleton,
        f.method,
        BindControl::default(),
    )
    .unwrap_or_else(|e| unreachable!("the figure binds: {e}"));
    let clip = ClipSpec {
        name: "walk".into(),
        length: 1.0,
        interpolation: f.interpolation,
        looping: true,
        keys: f
            .keys
            .iter()
            .map(|&(joint, time, deg)| KeySpec {
                joint: joint.into(),
                time,
                rotation_deg: Some(deg),
                translation: None,
            })
            .collect(),
        frame_rate: 24.0,
    }
    .to_clip(&skeleton)
    .unwrap_or_else(|e| unreachable!("a valid clip: {e}"));
    let mut doc = Document::default();
    doc.add(
        f.name,
        ObjectKind::Voxels(VoxelModel {
            svo,
            voxel_size: f.voxel_size,
            origin: f.origin,
            rig: Some(Rig::new(skeleton, vec![clip])),
            ..VoxelModel::default()
        }),
    );
    doc
}

/// A solid blocky figure, rigidly bound and posed mid-stride: legs, a torso, an arm and a head
/// of 8 to 24 voxels a side in a 64³ octree, each voxel following one joint, the enclosed
/// voxels [`Voxel::INTERIOR`] (so each limb's inside is interior tiles carrying its joint's
/// weights), with a looping clip played at 0.35 s and boxes stretched to their skinned corners
/// (`StretchStrategy::Corners`).
#[must_use]
pub fn rigid_solid_figure() -> Document {
    let mut doc = box_figure(&BoxFigure {
        name: "Figure",
        boxes: &[
            ([18, 2, 24], [26, 22, 32]),
            ([34, 2, 24], [42, 22, 32]),
            ([14, 22, 20], [46, 46, 36]),
            ([46, 36, 24], [62, 44, 32]),
            ([24, 46, 22], [36, 58, 34]),
        ],
        depth: 6,
        voxel_size: 0.05,
        origin: Vec3::new(-1.6, 0.0, -1.4),
        interior: true,
        color: |c| [120 + (c.y * 2) as u8, 90, (c.x * 3) as u8, 255],
        joints: &[
            ("hip", None, [30.0, 24.0, 28.0]),
            ("chest", Some("hip"), [30.0, 44.0, 28.0]),
            ("head", Some("chest"), [30.0, 52.0, 28.0]),
            ("arm", Some("chest"), [46.0, 40.0, 28.0]),
            ("hand", Some("arm"), [60.0, 40.0, 28.0]),
            ("leg.R", Some("hip"), [22.0, 22.0, 28.0]),
            ("shin.R", Some("leg.R"), [22.0, 10.0, 28.0]),
            ("leg.L", Some("hip"), [38.0, 22.0, 28.0]),
            ("shin.L", Some("leg.L"), [38.0, 10.0, 28.0]),
        ],
        method: crate::skin::bind::BindMethod::Rigid,
        keys: &[
            ("leg.R", 0.0, [35.0, 0.0, 0.0]),
            ("leg.R", 0.5, [-35.0, 0.0, 0.0]),
            ("leg.L", 0.0, [-35.0, 0.0, 0.0]),
            ("leg.L", 0.5, [35.0, 0.0, 0.0]),
            ("shin.R", 0.25, [50.0, 0.0, 0.0]),
            ("arm", 0.5, [0.0, 25.0, -70.0]),
            ("head", 0.5, [0.0, 40.0, 10.0]),
        ],
        interpolation: crate::skin::author::KeyInterpolation::Linear,
    });
    if let Some(ObjectKind::Voxels(v)) = doc.objects.first_mut().map(|o| &mut o.kind)
        && let Some(rig) = &mut v.rig
    {
        rig.playback.time_secs = 0.35;
        // Boxes from the corner weights: they close a rigid joint's gaps, and the renderers
        // then read every drawn node's corner weights from the skinning tables.
        rig.stretch.strategy = crate::skin::StretchStrategy::Corners;
    }
    if let Some((lo, hi)) = doc.bounds() {
        doc.camera.frame(lo, hi);
    }
    doc
}

/// `doc` with every voxel model stored voxel by voxel, the same stored with tiles (in a
/// skinned model, only its interior tiles), and how many tiles those hold (the pair the tile
/// tests render and compare).
#[must_use]
pub fn without_and_with_tiles(doc: &Document) -> (Document, Document, u64) {
    let (mut flat, mut tiled) = (doc.clone(), doc.clone());
    let mut tiles = 0;
    for (a, b) in flat.objects.iter_mut().zip(&mut tiled.objects) {
        if let (ObjectKind::Voxels(a), ObjectKind::Voxels(b)) = (&mut a.kind, &mut b.kind) {
            a.svo = std::mem::take(&mut a.svo).without_tiles();
            b.svo = std::mem::take(&mut b.svo).with_tiles();
            tiles += b.svo.tile_count();
        }
    }
    (flat, tiled, tiles)
}

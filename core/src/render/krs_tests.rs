//! KRS in the CPU renderer: depth compositing with voxels and meshes, shadows both ways, AO,
//! extremes (no NaN or Inf anywhere in the G-buffer).

use glam::{Vec3, Vec4};

use super::scenes::{self, voxel_object};
use super::*;
use crate::krs::{Kernel, KrsObject, Material, MirrorPlane, PlaneKernel, SphereKernel, presets};
use crate::scene::{MeshObject, Transform};

pub(super) fn ball(centre: Vec3, radius: f32, colour: Vec3) -> ObjectKind {
    ObjectKind::Krs(KrsObject {
        kernels: vec![Kernel::Sphere(SphereKernel {
            centre,
            radius,
            material: Material::new(colour, 1),
        })],
        ..KrsObject::default()
    })
}

fn quality() -> Quality {
    Quality {
        shadow_map_size: 256,
        ao_samples: 0,
        ..Quality::default()
    }
}

fn request(size: u32, quality: Quality) -> View {
    View {
        width: size,
        height: size,
        camera: None,
        quality,
    }
}

fn label(doc: &Document, id: u64) -> u32 {
    doc.objects.iter().position(|o| o.id == id).unwrap() as u32 + 1
}

fn pixel_of(cam: &Camera, p: Vec3) -> (u32, u32) {
    let s = cam.world_to_screen(p);
    (s.x as u32, s.y as u32)
}

fn assert_finite(fb: &FrameBuffers) {
    for i in 0..fb.depth.len() {
        assert!(
            fb.depth[i].is_finite() && (0.0..=1.0).contains(&fb.depth[i]),
            "depth {} at {i}",
            fb.depth[i]
        );
        assert!(fb.normal[i].is_finite(), "normal {} at {i}", fb.normal[i]);
        assert!(fb.albedo[i].is_finite(), "albedo {} at {i}", fb.albedo[i]);
        if fb.ids[i].object != 0 {
            assert!(
                (fb.normal[i].length() - 1.0).abs() < 1e-3,
                "normal {} at {i}",
                fb.normal[i]
            );
        }
    }
}

#[test]
fn krs_and_voxels_occlude_each_other() {
    let mut doc = Document::default();
    // A voxel ball of radius ~0.45 at the origin; a KRS ball in front of its left half and a
    // larger KRS ball behind its right half that sticks out beyond it.
    let voxels = doc.add(
        "Voxels",
        voxel_object(scenes::sphere_shell(5, 0.9).unwrap(), 0.5),
    );
    let front = doc.add("Front", ball(Vec3::new(-0.3, 0.0, 1.0), 0.25, Vec3::X));
    let back = doc.add("Back", ball(Vec3::new(0.5, 0.0, -1.5), 0.8, Vec3::Y));
    doc.camera = OrbitCamera {
        target: Vec3::ZERO,
        yaw_deg: 0.0,
        pitch_deg: 0.0,
        distance: 5.0,
        near: 0.1,
        far: 20.0,
        ..OrbitCamera::default()
    };
    let (_, fb, stats) = render_document(&doc, &request(64, quality())).unwrap();
    let cam = Camera::from_orbit(&doc.camera, 64, 64);
    assert_finite(&fb);
    assert!(stats.krs.hits > 0 && stats.krs.rays > 0, "{:?}", stats.krs);

    // The front KRS ball hides the voxels behind it.
    let (x, y) = pixel_of(&cam, Vec3::new(-0.3, 0.0, 1.2));
    assert_eq!(fb.id(x, y).object, label(&doc, front));
    // The voxels hide the back KRS ball where they overlap on screen.
    let (x, y) = pixel_of(&cam, Vec3::new(0.25, 0.0, 0.4));
    assert_eq!(fb.id(x, y).object, label(&doc, voxels));
    // Beside the voxels, the back ball shows.
    let (x, y) = pixel_of(&cam, Vec3::new(1.0, 0.0, -1.0));
    assert_eq!(fb.id(x, y).object, label(&doc, back));
    // Depths follow the geometry: the front ball is nearer than the voxels' surface would be.
    let (fx, fy) = pixel_of(&cam, Vec3::new(-0.3, 0.0, 1.2));
    let (vx, vy) = pixel_of(&cam, Vec3::new(0.25, 0.0, 0.4));
    let i = |x: u32, y: u32| (y * 64 + x) as usize;
    assert!(fb.depth[i(fx, fy)] < fb.depth[i(vx, vy)]);
    // The KRS depth is the NDC depth of the traced point (the same convention as splats): the
    // front ball's nearest point is at view depth 5 − 1.25 = 3.75, and the tracer stops within
    // one epsilon (a pixel's footprint there, 0.05) in front of it.
    let (cx, cy) = pixel_of(&cam, Vec3::new(-0.3, 0.0, 1.25));
    let d = cam.view_depth(fb.depth[i(cx, cy)]);
    let footprint = cam.pixel_world_size(3.75);
    assert!(
        d <= 3.75 + 1e-3 && d > 3.75 - 1.5 * footprint,
        "view depth {d}, footprint {footprint}"
    );
}

#[test]
fn krs_and_meshes_shadow_each_other() {
    // Light straight down. A KRS ball above a mesh ground shadows it; a mesh quad above a KRS
    // ground (half-space kernel) shadows that.
    let mut doc = Document::default();
    let mesh_ground = doc.add(
        "MeshGround",
        ObjectKind::Mesh(MeshObject {
            model: scenes::ground_plane(1.0, Vec4::new(0.7, 0.7, 0.7, 1.0)),
            casts_shadows: true,
        }),
    );
    let roof = doc.add(
        "Roof",
        ObjectKind::Mesh(MeshObject {
            model: scenes::ground_plane(0.4, Vec4::new(0.7, 0.3, 0.3, 1.0)),
            casts_shadows: true,
        }),
    );
    doc.add("Ball", ball(Vec3::new(-1.0, 0.6, 0.0), 0.3, Vec3::ONE));
    let krs_ground = doc.add(
        "KrsGround",
        ObjectKind::Krs(KrsObject {
            kernels: vec![Kernel::InfinitePlane(PlaneKernel {
                normal: Vec3::Y,
                offset: -0.5,
                material: Material::new(Vec3::splat(0.7), 2),
            })],
            ..KrsObject::default()
        }),
    );
    for o in &mut doc.objects {
        if o.id == mesh_ground {
            o.transform.translation = Vec3::new(-1.0, 0.0, 0.0);
        } else if o.id == roof {
            o.transform.translation = Vec3::new(1.2, 0.3, 0.0);
        }
    }
    doc.lights[0].direction = Vec3::new(0.0, -1.0, 0.0);
    doc.camera = OrbitCamera {
        target: Vec3::new(0.0, 0.0, 0.0),
        yaw_deg: 0.0,
        pitch_deg: 50.0,
        distance: 4.0,
        near: 0.1,
        far: 30.0,
        ..OrbitCamera::default()
    };
    let (img, fb, stats) = render_document(&doc, &request(96, quality())).unwrap();
    let cam = Camera::from_orbit(&doc.camera, 96, 96);
    assert_finite(&fb);
    assert!(stats.krs.shadow_rays > 0);
    let brightness = |(x, y): (u32, u32)| u32::from(img.pixel(x, y)[1]);

    // Mesh ground: under the KRS ball (seen past it, toward the camera) vs in the open.
    let shaded = pixel_of(&cam, Vec3::new(-1.0, 0.0, 0.2));
    let open = pixel_of(&cam, Vec3::new(-1.7, 0.0, 0.7));
    assert_eq!(fb.id(shaded.0, shaded.1).object, label(&doc, mesh_ground));
    assert_eq!(fb.id(open.0, open.1).object, label(&doc, mesh_ground));
    assert!(
        brightness(shaded) + 40 < brightness(open),
        "KRS shadow on the mesh: {} vs {}",
        brightness(shaded),
        brightness(open)
    );

    // KRS ground: under the mesh roof (seen past its front edge) vs in the open.
    let shaded = pixel_of(&cam, Vec3::new(1.2, -0.5, 0.3));
    let open = pixel_of(&cam, Vec3::new(0.3, -0.5, 1.0));
    assert_eq!(fb.id(shaded.0, shaded.1).object, label(&doc, krs_ground));
    assert_eq!(fb.id(open.0, open.1).object, label(&doc, krs_ground));
    assert!(
        brightness(shaded) + 40 < brightness(open),
        "mesh shadow on the KRS: {} vs {}",
        brightness(shaded),
        brightness(open)
    );
}

#[test]
fn ao_darkens_the_ground_next_to_a_trunk() {
    let mut doc = Document::default();
    doc.add("Tree", ObjectKind::Krs(presets::tree()));
    doc.add(
        "Ground",
        ObjectKind::Mesh(MeshObject {
            model: scenes::ground_plane(4.0, Vec4::new(0.7, 0.7, 0.7, 1.0)),
            casts_shadows: true,
        }),
    );
    doc.camera = OrbitCamera {
        target: Vec3::new(0.0, 0.3, 0.0),
        yaw_deg: 0.0,
        pitch_deg: 30.0,
        distance: 3.0,
        near: 0.1,
        far: 30.0,
        ..OrbitCamera::default()
    };
    doc.lights.clear();
    let cam = Camera::from_orbit(&doc.camera, 64, 64);
    let near_trunk = pixel_of(&cam, Vec3::new(0.0, 0.0, 0.3));
    let render = |ao: u32| {
        let q = Quality {
            ao_samples: ao,
            ..quality()
        };
        render_document(&doc, &request(64, q)).unwrap().0
    };
    let (plain, with_ao) = (render(0), render(4));
    let v = |img: &RgbaImage| img.pixel(near_trunk.0, near_trunk.1)[1];
    assert!(v(&with_ao) < v(&plain), "{} vs {}", v(&with_ao), v(&plain));
    // Far from the tree AO changes nothing.
    let far = pixel_of(&cam, Vec3::new(1.5, 0.0, 1.0));
    assert_eq!(plain.pixel(far.0, far.1), with_ao.pixel(far.0, far.1));
}

#[test]
fn ao_in_a_krs_only_scene_counts_the_krs_once_and_costs_nothing_without_a_size() {
    // A KRS ball resting on an endless KRS ground, nothing else: the screen AO takes its radius
    // from the ball's bounding ball (before, KRS-only scenes had no bounds, paid for every
    // sample and got no occlusion), and skips KRS occluders, which the KRS distance AO counts.
    let ground = Kernel::InfinitePlane(PlaneKernel::default());
    let mut doc = Document::default();
    doc.add(
        "Ball",
        ball(Vec3::new(0.0, 1.02, 0.0), 1.0, Vec3::new(0.8, 0.8, 0.8)),
    );
    doc.add(
        "Ground",
        ObjectKind::Krs(KrsObject {
            kernels: vec![ground],
            ..KrsObject::default()
        }),
    );
    doc.camera = OrbitCamera {
        target: Vec3::new(0.0, 0.5, 0.0),
        yaw_deg: 20.0,
        pitch_deg: 25.0,
        distance: 5.0,
        near: 0.1,
        far: 100.0,
        ..OrbitCamera::default()
    };
    doc.lights.clear();
    let render = |doc: &Document, ao: u32| {
        let q = Quality {
            ao_samples: ao,
            ..quality()
        };
        render_document(doc, &request(64, q)).unwrap()
    };
    let (img, _, st) = render(&doc, 8);
    let taps = st.shading.expect("shading stats").ao_taps;
    assert!(taps > 0, "the ball gives the scene a size, so AO samples");
    // Only the KRS distance AO darkens here (no voxels or meshes to occlude on screen).
    let cam = Camera::from_orbit(&doc.camera, 64, 64);
    let contact = pixel_of(&cam, Vec3::new(0.0, 0.0, 0.35));
    let plain_img = render(&doc, 0).0;
    assert!(
        img.pixel(contact.0, contact.1)[1] < plain_img.pixel(contact.0, contact.1)[1],
        "the ground under the ball is darker with AO"
    );
    // The endless ground alone has no size: no AO radius, so no samples at all.
    let mut flat = doc.clone();
    flat.objects.retain(|o| o.name == "Ground");
    let (flat_img, _, st) = render(&flat, 8);
    assert_eq!(st.shading.expect("shading stats").ao_taps, 0);
    assert_eq!(flat_img, render(&flat, 0).0);
}

#[test]
fn tiles_and_over_relaxation_do_not_change_the_image() {
    let mut doc = Document::default();
    doc.add("Tree", ObjectKind::Krs(presets::tree()));
    doc.camera = OrbitCamera {
        target: Vec3::new(0.0, 2.5, 0.0),
        pitch_deg: 10.0,
        distance: 9.0,
        ..OrbitCamera::default()
    };
    let base = Quality {
        krs_tile_acceleration: false,
        krs_over_relaxation: 1.0,
        shadows: false,
        ..quality()
    };
    let (img0, fb0, s0) = render_document(&doc, &request(48, base.clone())).unwrap();
    let fast = Quality {
        krs_tile_acceleration: true,
        krs_over_relaxation: 1.6,
        ..base
    };
    let (img1, fb1, s1) = render_document(&doc, &request(48, fast)).unwrap();
    assert_eq!(fb0.coverage(), fb1.coverage());
    assert_eq!(fb0.depth, fb1.depth);
    assert_eq!(img0, img1);
    assert!(s0.krs.hits > 100, "{:?}", s0.krs);
    assert!(s1.krs.steps < s0.krs.steps, "{:?} vs {:?}", s1.krs, s0.krs);
}

#[test]
fn extremes_give_finite_buffers() {
    // n = 64 reflections, tiny and huge radii, coincident and antiparallel mirrors.
    let mut kernels = vec![Kernel::Sphere(SphereKernel {
        centre: Vec3::new(0.3, 0.1, 0.0),
        radius: 0.05,
        ..SphereKernel::default()
    })];
    let mut mirrors = Vec::new();
    for i in 0..64 {
        let a = i as f32 * 2.399;
        mirrors.push(MirrorPlane::new(
            Vec3::new(a.cos(), 0.3 * (i as f32).sin(), a.sin()),
            0.02 * (i % 5) as f32,
        ));
        kernels.push(Kernel::Empty);
    }
    mirrors[10] = mirrors[9];
    mirrors[12] = MirrorPlane {
        normal: -mirrors[11].normal,
        offset: -mirrors[11].offset,
    };
    let deep = KrsObject {
        kernels,
        mirrors,
        ..KrsObject::default()
    };
    let mut doc = Document::default();
    doc.add("Deep", ObjectKind::Krs(deep));
    doc.add("Tiny", ball(Vec3::new(0.0, 1.0, 0.0), 1e-7, Vec3::ONE));
    let huge = doc.add(
        "Huge",
        ball(Vec3::new(0.0, -1e6 - 2.0, 0.0), 1e6, Vec3::ONE),
    );
    doc.add("Tree", ObjectKind::Krs(presets::tree()));
    doc.add("Forest", ObjectKind::Krs(presets::forest()));
    doc.validate().unwrap();
    let q = Quality {
        krs_max_steps: 64,
        ao_samples: 2,
        krs_soft_shadows: true,
        ..quality()
    };
    let cameras = [
        // Far away: the camera 1e6 units out.
        OrbitCamera {
            distance: 1e6,
            near: 10.0,
            far: 3e6,
            ..OrbitCamera::default()
        },
        // Grazing: just above the huge ball's top, looking along it.
        OrbitCamera {
            target: Vec3::new(0.0, -1.99, 0.0),
            pitch_deg: 0.01,
            distance: 30.0,
            near: 0.01,
            far: 1e4,
            ..OrbitCamera::default()
        },
        // Inside the forest's canopy looking up.
        OrbitCamera {
            target: Vec3::new(0.0, 4.0, 0.0),
            pitch_deg: -60.0,
            distance: 2.0,
            near: 0.01,
            far: 1e4,
            ..OrbitCamera::default()
        },
    ];
    for camera in cameras {
        let req = View {
            camera: Some(camera),
            ..request(24, q.clone())
        };
        let (_, fb, stats) = render_document(&doc, &req).unwrap();
        assert_finite(&fb);
        assert!(stats.krs.rays > 0, "{camera:?}");
    }
    // The grazing view sees the huge ball's horizon.
    let req = View {
        camera: Some(cameras[1]),
        ..request(24, q)
    };
    let (_, fb, _) = render_document(&doc, &req).unwrap();
    let huge_label = label(&doc, huge);
    assert!(fb.ids.iter().any(|id| id.object == huge_label));
}

#[test]
fn krs_follows_the_object_transform() {
    let mut doc = Document::default();
    let id = doc.add("Ball", ball(Vec3::ZERO, 0.2, Vec3::ONE));
    doc.objects[0].transform = Transform {
        translation: Vec3::new(0.5, 0.0, 0.0),
        scale: Vec3::splat(2.0),
        ..Transform::default()
    };
    doc.camera = OrbitCamera {
        yaw_deg: 0.0,
        pitch_deg: 0.0,
        distance: 4.0,
        ..OrbitCamera::default()
    };
    let (_, fb, _) = render_document(&doc, &request(64, quality())).unwrap();
    let cam = Camera::from_orbit(&doc.camera, 64, 64);
    let l = label(&doc, id);
    // Radius 0.2 × 2 = 0.4 around x = 0.5.
    let (x, y) = pixel_of(&cam, Vec3::new(0.85, 0.0, 0.0));
    assert_eq!(fb.id(x, y).object, l);
    let (x, y) = pixel_of(&cam, Vec3::new(-0.0, 0.0, 0.0));
    assert_eq!(fb.id(x, y).object, 0);
}

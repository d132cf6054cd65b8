//! Textured triangle meshes on the GPU against the CPU reference: the base-colour texture is
//! sampled in the resolve pass exactly as `Texture::sample_linear` samples it on the CPU
//! (bilinear, repeat wrapping, texel centres at half-integers, the CPU's sRGB table).
//!
//! Spot (Keenan Crane, public domain) is imported through the same path as File > Import (an
//! OBJ with a material library naming the PNG); a generated scene covers the sampling
//! extremes. Both splat paths; the tolerance is the parity tests' (`Tolerance::GPU_PARITY`).

use std::path::{Path, PathBuf};

use glam::{Quat, Vec2, Vec3, Vec4};
use thicket::gpu::{GBuffer, GpuContext, RenderTarget, Renderer};
use thicket_core::mesh::{Material, MeshModel, Texture, TriangleMesh};
use thicket_core::render::{FrameBuffers, View, render_document};
use thicket_core::scene::{Document, Light, MeshObject, ObjectKind};

mod common;
use common::gpu::{assert_same_as_full_upload, context, cpu_gpu_parity, gpu_frame};

const ASSETS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/assets");

/// Spot as the editor imports it: its OBJ (which has no material library of its own) beside
/// an `.mtl` that names the PNG, opened with `files::load_document`.
fn spot_document(dir: &Path) -> Document {
    let spot = PathBuf::from(ASSETS).join("static/spot");
    let obj = std::fs::read_to_string(spot.join("spot_triangulated.obj")).expect("spot .obj");
    let obj_path = dir.join("spot.obj");
    std::fs::write(&obj_path, format!("mtllib spot.mtl\nusemtl spot\n{obj}")).expect("write");
    // Beside the .obj: references are confined to the file's folder (an absolute path to
    // the asset would be refused).
    std::fs::copy(spot.join("spot_texture.png"), dir.join("spot_texture.png")).expect("copy");
    std::fs::write(
        dir.join("spot.mtl"),
        "newmtl spot\nKd 1 1 1\nmap_Kd spot_texture.png\n",
    )
    .expect("write");
    let mut doc = thicket::files::load_document(&obj_path).expect("spot imports");
    // Side light, so the texture is not the only thing that varies over the surface.
    doc.lights = vec![Light {
        direction: Vec3::new(-0.6, -0.7, -0.4),
        ..Light::default()
    }];
    doc.camera.yaw_deg += 35.0;
    doc
}

fn meshes_mut(doc: &mut Document) -> impl Iterator<Item = &mut MeshModel> {
    doc.objects.iter_mut().filter_map(|o| match &mut o.kind {
        ObjectKind::Mesh(m) => Some(&mut m.model),
        _ => None,
    })
}

/// The same document with every base-colour texture removed.
fn untextured(doc: &Document) -> Document {
    let mut d = doc.clone();
    for m in meshes_mut(&mut d) {
        for mat in &mut m.materials {
            mat.base_color_texture = None;
        }
    }
    d
}

fn cpu_frame(doc: &Document, size: (u32, u32)) -> (thicket_core::render::RgbaImage, FrameBuffers) {
    let req = View {
        width: size.0,
        height: size.1,
        camera: Some(doc.camera),
        quality: doc.quality.clone(),
    };
    let (img, fb, _) = render_document(doc, &req).expect("CPU frame");
    (img, fb)
}

/// Mean and largest |albedo difference| (summed over RGB) over pixels both frames cover.
fn albedo_error(g: &GBuffer, fb: &FrameBuffers) -> (f32, f32, usize) {
    let (mut sum, mut max, mut n) = (0.0f32, 0.0f32, 0usize);
    for i in 0..fb.albedo.len() {
        if fb.ids[i].object == 0 || !g.depth[i].is_finite() {
            continue;
        }
        let d = (g.albedo[i] - fb.albedo[i]).abs();
        let e = d.x + d.y + d.z;
        sum += e;
        max = max.max(e);
        n += 1;
    }
    (sum / n.max(1) as f32, max, n)
}

/// CPU and GPU frames of `doc` on both splat paths: image parity under the shared tolerance;
/// returns the GPU G-buffers (64-bit path, then two-pass) and the CPU buffers.
fn both_paths(
    ctx: &GpuContext,
    name: &str,
    doc: &Document,
    size: (u32, u32),
) -> (Vec<GBuffer>, FrameBuffers) {
    let (cpu, fb) = cpu_frame(doc, size);
    let mut gbuffers = Vec::new();
    for two_pass in [false, true] {
        let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
        assert!(
            two_pass || r.capabilities().int64_atomics,
            "this adapter has no SHADER_INT64_ATOMIC_MIN_MAX: the 64-bit path cannot be tested here"
        );
        r.set_force_two_pass(two_pass);
        let (gpu, g, _) = gpu_frame(ctx, &mut r, doc, size, &doc.quality);
        let stem = format!("{name}-{}", if two_pass { "32" } else { "64" });
        let p = cpu_gpu_parity(
            "thicket-gpu-texture",
            &stem,
            &doc.camera,
            (&cpu, &fb),
            (&gpu, &g),
        );
        assert!(p.both_covered > 0, "{stem}: nothing drawn");
        eprintln!("{stem}: {p:?}");
        gbuffers.push(g);
    }
    (gbuffers, fb)
}

#[test]
fn textured_spot_matches_the_cpu_reference_and_shows_its_texture() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("temp dir");
    let doc = spot_document(dir.path());
    let texture = meshes_mut(&mut doc.clone())
        .flat_map(|m| m.materials.clone())
        .find_map(|m| m.base_color_texture)
        .expect("the importer attached the texture");
    assert_eq!((texture.width, texture.height), (1024, 1024));
    let size = (128, 112);
    let (gbuffers, fb) = both_paths(&ctx, "spot", &doc, size);

    // The texture shows: on the mesh's pixels the GPU's albedo agrees with the textured CPU
    // frame far better than with the CPU frame of the same scene without the texture (which is
    // what the GPU drew before it sampled textures).
    let (_, plain_fb) = cpu_frame(&untextured(&doc), size);
    for g in &gbuffers {
        let (textured_mean, textured_max, n) = albedo_error(g, &fb);
        let (plain_mean, _, _) = albedo_error(g, &plain_fb);
        eprintln!(
            "spot albedo error over {n} pixels: vs textured CPU mean {textured_mean:.5} max {textured_max:.4}; vs untextured CPU mean {plain_mean:.4}"
        );
        assert!(n > 1500, "Spot covers only {n} pixels");
        assert!(
            plain_mean > 0.1,
            "the texture barely changes Spot: {plain_mean}"
        );
        assert!(
            textured_mean * 50.0 < plain_mean,
            "GPU albedo is not the textured one: {textured_mean} vs untextured {plain_mean}"
        );
    }
}

/// A `w`×`h` texture with distinct texels (sRGB bytes; alpha varies too).
fn texture(w: u32, h: u32, seed: u32) -> Texture {
    let mut rgba8 = Vec::with_capacity((w * h * 4) as usize);
    for i in 0..w * h {
        let k = i
            .wrapping_mul(2_654_435_761)
            .wrapping_add(seed.wrapping_mul(40_503));
        rgba8.extend_from_slice(&[
            (k >> 24) as u8,
            (k >> 16) as u8 | 0x20,
            (k >> 8) as u8,
            (k as u8) | 0x80,
        ]);
    }
    Texture {
        width: w,
        height: h,
        rgba8,
    }
}

/// A quad facing +z centred at (`x`, `y`), with per-corner texture coordinates (none when `uvs` is empty),
/// vertex colours and material `material`.
fn quad((x, y): (f32, f32), uvs: &[Vec2], colors: &[Vec4], material: usize) -> TriangleMesh {
    let mut m = TriangleMesh {
        positions: vec![
            Vec3::new(x - 0.45, y - 0.45, 0.0),
            Vec3::new(x + 0.45, y - 0.45, 0.0),
            Vec3::new(x + 0.45, y + 0.45, 0.0),
            Vec3::new(x - 0.45, y + 0.45, 0.0),
        ],
        uvs: uvs.to_vec(),
        colors: colors.to_vec(),
        indices: vec![0, 1, 2, 0, 2, 3],
        material,
        ..TriangleMesh::default()
    };
    m.compute_normals();
    m
}

/// Quads that sample at the extremes: texture coordinates far outside [0, 1] (repeat, negative),
/// a 1×1 texture, coordinates of 2^24 (no fraction left), infinite coordinates (white), a
/// textured material on a part without coordinates (untextured), a texture shorter than its
/// size says (white), a textured material with a base colour and vertex colours.
fn extremes_document() -> Document {
    let uv = |a: [f32; 2], b: [f32; 2], c: [f32; 2], d: [f32; 2]| {
        vec![Vec2::from(a), Vec2::from(b), Vec2::from(c), Vec2::from(d)]
    };
    let huge = 16_777_216.0;
    let mut short = texture(4, 4, 9);
    short.rgba8.truncate(40);
    let materials = vec![
        Material {
            base_color_texture: Some(texture(3, 2, 1)),
            ..Material::default()
        },
        Material {
            base_color_texture: Some(texture(1, 1, 2)),
            ..Material::default()
        },
        Material {
            base_color_texture: Some(texture(4, 4, 3)),
            ..Material::default()
        },
        Material {
            base_color_texture: Some(texture(2, 2, 4)),
            ..Material::default()
        },
        Material {
            base_color: Vec4::new(0.5, 0.8, 0.3, 1.0),
            base_color_texture: Some(short),
            ..Material::default()
        },
        Material {
            base_color: Vec4::new(0.9, 0.6, 0.8, 1.0),
            base_color_texture: Some(texture(5, 3, 5)),
            ..Material::default()
        },
    ];
    let white = [Vec4::ONE; 4];
    let parts = vec![
        quad(
            (-1.5, 0.5),
            &uv([-2.25, 2.5], [3.75, 2.5], [3.75, -1.5], [-2.25, -1.5]),
            &[],
            0,
        ),
        quad(
            (-0.5, 0.5),
            &uv([-7.3, 11.1], [5.2, 11.1], [5.2, -3.9], [-7.3, -3.9]),
            &[],
            1,
        ),
        quad((0.5, 0.5), &[Vec2::new(huge, -huge); 4], &white, 2),
        quad(
            (1.5, 0.5),
            &uv([f32::INFINITY, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]),
            &[],
            3,
        ),
        quad((-1.5, -0.5), &[], &[], 3),
        quad(
            (-0.5, -0.5),
            &uv([0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]),
            &[],
            4,
        ),
        quad(
            (0.5, -0.5),
            &uv([-0.6, 1.7], [1.4, 1.7], [1.4, -0.3], [-0.6, -0.3]),
            &[
                Vec4::new(1.0, 0.2, 0.2, 1.0),
                Vec4::new(0.2, 1.0, 0.2, 1.0),
                Vec4::new(0.2, 0.2, 1.0, 1.0),
                Vec4::ONE,
            ],
            5,
        ),
    ];
    let mut doc = Document::default();
    doc.add(
        "Quads",
        ObjectKind::Mesh(MeshObject {
            model: MeshModel { parts, materials },
            casts_shadows: true,
        }),
    );
    doc.lights = vec![Light {
        direction: Vec3::new(0.2, -0.3, -1.0),
        ..Light::default()
    }];
    doc.camera.target = Vec3::ZERO;
    doc.camera.yaw_deg = 0.0;
    doc.camera.pitch_deg = 0.0;
    doc.camera.distance = 4.2;
    doc
}

#[test]
fn texture_sampling_extremes_match_the_cpu_reference() {
    let ctx = context();
    let doc = extremes_document();
    let size = (128, 96);
    let (gbuffers, fb) = both_paths(&ctx, "texture-extremes", &doc, size);
    let (_, plain_fb) = cpu_frame(&untextured(&doc), size);
    for g in &gbuffers {
        let (mean, max, n) = albedo_error(g, &fb);
        let (plain_mean, _, _) = albedo_error(g, &plain_fb);
        eprintln!(
            "extremes albedo error over {n} pixels: mean {mean:.6} max {max:.5}; vs untextured {plain_mean:.4}"
        );
        assert!(n > 1000, "the quads cover only {n} pixels");
        // Bilinear sampling is continuous, so the few-ulp differences between the CPU's and
        // the GPU's barycentrics move no pixel's albedo by more than a fraction of an 8-bit step.
        assert!(max < 2.0 / 255.0, "albedo differs by {max} somewhere");
        assert!(
            mean * 100.0 < plain_mean,
            "{mean} vs untextured {plain_mean}"
        );
    }
}

#[test]
fn moving_a_textured_mesh_uploads_only_its_triangles() {
    // A transform change re-packs the triangles (with the texture indices they had) and leaves
    // the texture buffer alone; the frame equals a fresh full upload. A texture of another
    // shape is a new upload.
    let ctx = context();
    let mut doc = extremes_document();
    let size = (64, 48);
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    let target = RenderTarget::new(&ctx.device, size.0, size.1).expect("target");
    let q = doc.quality.clone();
    let first = r
        .render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("first frame");
    assert!(first.upload.full);
    let tris: u64 = meshes_mut(&mut doc)
        .map(|m| m.triangle_count() as u64)
        .sum();
    doc.objects[0].transform.translation.y = 0.2;
    doc.objects[0].transform.rotation = Quat::from_rotation_z(0.1);
    let moved = r
        .render_uploaded(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("moved frame");
    assert!(!moved.upload.full, "{:?}", moved.upload);
    assert_eq!(moved.upload.writes, 1, "{:?}", moved.upload);
    assert_eq!(
        moved.upload.bytes,
        tris * std::mem::size_of::<thicket::gpu::gpu_data::GpuTriangle>() as u64,
        "{:?}",
        moved.upload
    );
    assert_same_as_full_upload(&ctx, &doc, &q, &target);

    if let Some(m) = meshes_mut(&mut doc).next() {
        m.materials[0].base_color_texture = Some(texture(6, 5, 11));
    }
    let retextured = r
        .render_uploaded(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )
        .expect("retextured frame");
    assert!(retextured.upload.full, "{:?}", retextured.upload);
    assert!(ctx.errors.take().is_none(), "uncaptured GPU error");
}

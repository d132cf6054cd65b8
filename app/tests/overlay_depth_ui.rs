//! The view's overlay lines (the ground grid, the world axes, the volume box) are hidden behind
//! whatever the shown frame drew in front of them: meshes, KRS surfaces and posed rigged models
//! as well as voxels, in the CPU preview and the GPU viewport (lavapipe here and in CI).

use egui_kittest::Harness;
use egui_kittest::wgpu::{WgpuTestRenderer, create_render_state};
use glam::{Quat, Vec3};
use thicket::editor::Editor;
use thicket::preview::viewport::FrameDepth;
use thicket::ui::EditorApp;
use thicket::ui::view::{Projector, ViewRenderer, behind_voxels};
use thicket_core::quality::Quality;
use thicket_core::render::{Camera, View, render_document};
use thicket_core::scene::{Document, MeshObject, ObjectKind, OrbitCamera, Transform};

/// A 2 m wide, 2.5 m tall box mesh standing on the ground at the origin (the world axes, 2 m
/// long here, end inside it), seen from above at 35°.
fn cube_scene() -> Document {
    let mut doc = Document::default();
    let id = doc.add(
        "Cube",
        ObjectKind::Mesh(MeshObject {
            model: thicket_core::mesh::MeshModel {
                parts: vec![thicket_core::mesh::unit_cube()],
                materials: vec![thicket_core::mesh::Material::default()],
            },
            casts_shadows: true,
        }),
    );
    doc.objects
        .iter_mut()
        .find(|o| o.id == id)
        .unwrap()
        .transform = Transform {
        translation: Vec3::new(0.0, 1.25, 0.0),
        rotation: Quat::IDENTITY,
        scale: Vec3::new(2.0, 2.5, 2.0),
    };
    doc.camera = OrbitCamera {
        target: Vec3::new(0.0, 0.5, 0.0),
        yaw_deg: 30.0,
        pitch_deg: 35.0,
        distance: 7.0,
        orthographic: false,
        ..doc.camera
    };
    doc.quality.shadows = false;
    doc
}

/// The CPU renderer's depth of `doc` at `w`×`h`, as the preview hands it to the view.
fn frame_depth(doc: &Document, [w, h]: [u32; 2]) -> FrameDepth {
    let request = View {
        width: w,
        height: h,
        camera: Some(doc.camera),
        quality: Quality {
            shadows: false,
            supersample: 1,
            ..doc.quality.clone()
        },
    };
    let (_, buffers, _) = render_document(doc, &request).expect("the scene renders");
    FrameDepth::new(
        (0, 0),
        0,
        doc.camera,
        [w, h],
        buffers.depth.as_slice().into(),
    )
}

/// For pixels well inside what was drawn (a 5×5 neighbourhood covered, its view depths within
/// 2 %): the drawn surface point and points in front of it show, points 10 % of the view depth
/// behind it are hidden. Returns how many pixels were tested.
fn hides_only_behind_the_surface(frame: &FrameDepth, what: &str) -> usize {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let cam = Camera::from_orbit(&frame.camera, frame.width, frame.height);
    let view = |x: usize, y: usize| {
        let d = frame.depth[y * w + x];
        (d < 1.0).then(|| cam.view_depth(d))
    };
    let mut tested = 0;
    for y in (2..h - 2).step_by(5) {
        for x in (2..w - 2).step_by(5) {
            let Some(vd) = view(x, y) else { continue };
            let flat = (y - 2..=y + 2)
                .flat_map(|yy| (x - 2..=x + 2).map(move |xx| (xx, yy)))
                .all(|(xx, yy)| view(xx, yy).is_some_and(|v| (v - vd).abs() < 0.02 * vd));
            if !flat {
                continue;
            }
            let (sx, sy) = (x as f32 + 0.5, y as f32 + 0.5);
            let surface = cam.unproject(sx, sy, frame.depth[y * w + x]);
            let toward_eye = cam.toward_eye(surface);
            assert!(
                !frame.hides(surface),
                "{what}: the drawn surface at pixel ({x}, {y}) shows"
            );
            assert!(
                !frame.hides(surface + toward_eye * 0.1 * vd),
                "{what}: a point in front of pixel ({x}, {y}) shows"
            );
            assert!(
                frame.hides(surface - toward_eye * 0.1 * vd),
                "{what}: a point behind pixel ({x}, {y})'s surface is hidden"
            );
            tested += 1;
        }
    }
    // A background pixel hides nothing at any depth.
    let background = (0..w * h)
        .find(|&i| frame.depth[i] >= 1.0)
        .expect("some background");
    let (bx, by) = ((background % w) as f32 + 0.5, (background / w) as f32 + 0.5);
    for d in [0.1, 0.5, 0.9, 0.999] {
        assert!(
            !frame.hides(cam.unproject(bx, by, d)),
            "{what}: background at depth {d}"
        );
    }
    tested
}

/// A mesh, a KRS rock and the posed rigged critter each hide the points behind them by their
/// drawn depth, where the voxel rays the overlays used before see nothing.
#[test]
fn a_frame_hides_what_lies_behind_meshes_krs_and_posed_rigs() {
    let mut rock = Document::default();
    rock.add("Rock", ObjectKind::Krs(thicket_core::krs::presets::rock()));
    if let Some((lo, hi)) = rock.bounds() {
        rock.camera.frame(lo, hi);
    }
    let critter =
        thicket::files::load_document(std::path::Path::new("../projects/critter.thicket.json"))
            .expect("the sample loads");
    for (what, doc) in [
        ("cube mesh", cube_scene()),
        ("KRS rock", rock),
        ("critter", critter),
    ] {
        let frame = frame_depth(&doc, [160, 120]);
        let tested = hides_only_behind_the_surface(&frame, what);
        assert!(
            tested >= 8,
            "{what}: only {tested} pixels inside the silhouette"
        );
    }
    // The voxel rays alone would not hide the ground under the cube.
    let doc = cube_scene();
    let editor = Editor::new(doc.clone(), None);
    let rect = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(160.0, 120.0));
    let proj = Projector::new(doc.camera, rect);
    let under = Vec3::ZERO;
    assert!(!behind_voxels(&proj, &editor, under));
    assert!(frame_depth(&doc, [160, 120]).hides(under));
}

/// The view's pixels that the grid and axes change: the window drawn with and without them.
fn grid_pixels(
    h: &mut Harness<'static, EditorApp>,
    settle: impl Fn(&mut Harness<'static, EditorApp>),
) -> Vec<(u32, u32)> {
    h.state_mut().view.show_grid = false;
    settle(h);
    let without = h.render().expect("render");
    h.state_mut().view.show_grid = true;
    settle(h);
    let with = h.render().expect("render");
    let rect = h.state().view.last_rect;
    let mut changed = Vec::new();
    for y in rect.top() as u32..rect.bottom() as u32 {
        for x in rect.left() as u32..rect.right() as u32 {
            if with.get_pixel(x, y) != without.get_pixel(x, y) {
                changed.push((x, y));
            }
        }
    }
    changed
}

/// No grid or axis pixel lies inside the box's silhouette (shrunk by 3 px for the lines'
/// anti-aliasing), and the grid shows around it.
fn grid_stays_outside_the_cube(
    h: &mut Harness<'static, EditorApp>,
    changed: &[(u32, u32)],
    cpu: bool,
) {
    let what = if cpu { "CPU preview" } else { "GPU viewport" };
    let app = h.state();
    // Where the box covers the view, from a render of its own.
    let rect = app.view.last_rect;
    let frame = frame_depth(
        app.editor.doc(),
        [rect.width().round() as u32, rect.height().round() as u32],
    );
    let covered = |x: f32, y: f32| {
        let fx = ((x - rect.left()) / rect.width() * frame.width as f32).floor();
        let fy = ((y - rect.top()) / rect.height() * frame.height as f32).floor();
        fx >= 0.0
            && fy >= 0.0
            && (fx as u32) < frame.width
            && (fy as u32) < frame.height
            && frame.depth[fy as usize * frame.width as usize + fx as usize] < 1.0
    };
    let inside = |x: u32, y: u32| {
        let (x, y) = (x as f32 + 0.5, y as f32 + 0.5);
        (-3..=3).all(|dy| (-3..=3).all(|dx| covered(x + dx as f32, y + dy as f32)))
    };
    let inside_count = (rect.top() as u32..rect.bottom() as u32)
        .flat_map(|y| (rect.left() as u32..rect.right() as u32).map(move |x| (x, y)))
        .filter(|&(x, y)| inside(x, y))
        .count();
    assert!(
        inside_count > 2_000,
        "{what}: the cube covers {inside_count} px"
    );
    let through: Vec<_> = changed.iter().filter(|&&(x, y)| inside(x, y)).collect();
    assert!(
        through.is_empty(),
        "{what}: {} grid pixels inside the cube, e.g. {:?}",
        through.len(),
        &through[..through.len().min(5)]
    );
    assert!(
        changed.len() > 1_000,
        "{what}: the grid shows ({} px)",
        changed.len()
    );
    let app = h.state();
    assert!(
        app.view.shown_depth(&app.editor, cpu).is_some(),
        "{what}: the shown frame's depth is known"
    );
    // The axes start at the origin, under the box: lines do run behind it (with the voxel
    // rays alone, which see no mesh, 4,243 of their pixels were drawn inside it).
    let editor = &h.state().editor;
    let proj = Projector::new(editor.doc().camera, rect);
    let under = proj.to_screen(Vec3::ZERO).expect("in view");
    assert!(
        inside(under.x as u32, under.y as u32),
        "{what}: the origin is under the cube"
    );
}

/// The real editor with the CPU preview: the grid is hidden behind a mesh cube.
#[test]
fn the_grid_is_hidden_behind_a_mesh_in_the_cpu_preview() {
    let mut app = EditorApp::new(Editor::new(cube_scene(), None));
    app.autosave_secs = 0;
    app.native_dialogs = false;
    app.view.renderer = ViewRenderer::Cpu;
    let mut h = Harness::builder()
        .with_size(egui::vec2(900.0, 640.0))
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    let settle = |h: &mut Harness<'static, EditorApp>| {
        for _ in 0..4 {
            h.state_mut().view.wait_for_cpu_preview();
            h.run_steps(1);
        }
    };
    let changed = grid_pixels(&mut h, settle);
    grid_stays_outside_the_cube(&mut h, &changed, true);
}

/// The real editor with the GPU viewport: once the view is still, the frame's depth is read
/// back and the grid is hidden behind a mesh cube.
#[test]
fn the_grid_is_hidden_behind_a_mesh_in_the_gpu_viewport() {
    let render_state = create_render_state(
        thicket::preview::viewport::wgpu_setup(),
        egui_wgpu::RendererOptions::PREDICTABLE,
    );
    let link = thicket::preview::viewport::install(&render_state);
    let mut app = EditorApp::new(Editor::new(cube_scene(), None));
    app.autosave_secs = 0;
    app.native_dialogs = false;
    app.attach_gpu(link.clone());
    app.view.renderer = ViewRenderer::Gpu;
    let mut h = Harness::builder()
        .with_size(egui::vec2(900.0, 640.0))
        .renderer(WgpuTestRenderer::from_render_state(render_state))
        .build_ui_state(|ui, app: &mut EditorApp| app.ui_root(ui), app);
    let settle = |h: &mut Harness<'static, EditorApp>| {
        // Frames are drawn in `render` (the paint callback); the depth is read on the next.
        for _ in 0..3 {
            h.run_steps(1);
            let _ = h.render();
        }
    };
    settle(&mut h);
    let rendered = link.lock().frames_rendered;
    let changed = grid_pixels(&mut h, settle);
    let status = link.lock().clone();
    assert!(status.error.is_none(), "{:?}", status.error);
    assert!(status.depth.is_some(), "the depth was read back");
    assert_eq!(
        status.frames_rendered, rendered,
        "reading the depth and toggling the grid render no frame"
    );
    grid_stays_outside_the_cube(&mut h, &changed, false);
}

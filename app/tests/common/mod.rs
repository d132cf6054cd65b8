//! What the integration test files share: running the real `thicket` binary and reading its
//! output; the GPU parity helpers are in [`gpu`].

// Each test file compiles this module on its own and uses only part of it.
#![allow(dead_code)]

use std::process::{Command, Output};

pub mod gpu;

/// The real editor app in an egui_kittest harness of `size` points, without autosave or
/// desktop dialogs, after two frames.
pub fn ui_harness(
    editor: thicket::editor::Editor,
    size: egui::Vec2,
) -> egui_kittest::Harness<'static, thicket::ui::EditorApp> {
    let mut app = thicket::ui::EditorApp::new(editor);
    // The UI tests must not touch the user's recovery folder or depend on it.
    app.autosave_secs = 0;
    app.native_dialogs = false;
    let mut h = egui_kittest::Harness::builder()
        .with_size(size)
        .build_ui_state(|ui, app: &mut thicket::ui::EditorApp| app.ui_root(ui), app);
    h.run_steps(2);
    h
}

/// Lets the CPU preview catch up with the document and shows its image.
pub fn settle_preview(h: &mut egui_kittest::Harness<'static, thicket::ui::EditorApp>) {
    for _ in 0..4 {
        h.state_mut().view.wait_for_cpu_preview();
        h.run_steps(1);
    }
}

/// A primary click at `at` (press and release without moving).
pub fn click_at(h: &mut egui_kittest::Harness<'static, thicket::ui::EditorApp>, at: egui::Pos2) {
    h.hover_at(at);
    h.run_steps(1);
    h.drag_at(at);
    h.run_steps(1);
    h.drop_at(at);
    h.run_steps(2);
}

/// Runs `thicket ARGS` (logging off) and returns what it printed and its exit status.
pub fn thicket(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_thicket"))
        .args(args)
        .env("RUST_LOG", "off")
        .output()
        .expect("the thicket binary runs")
}

/// Standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A MagicaVoxel animation in the pre-0.99 layout: three models (frames of 2, 3 and 4 voxels)
/// and no scene graph.
pub fn animated_vox_bytes() -> Vec<u8> {
    fn chunk(out: &mut Vec<u8>, id: &[u8; 4], content: &[u8]) {
        out.extend_from_slice(id);
        out.extend_from_slice(&(content.len() as u32).to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(content);
    }
    let frames: [&[[u8; 4]]; 3] = [
        &[[0, 0, 0, 1], [1, 0, 0, 1]],
        &[[0, 0, 0, 2], [1, 0, 0, 2], [2, 0, 1, 3]],
        &[[0, 0, 0, 4], [1, 0, 0, 4], [0, 1, 0, 5], [1, 1, 1, 5]],
    ];
    let mut main = Vec::new();
    for voxels in frames {
        let size: Vec<u8> = [3u32, 2, 2].iter().flat_map(|s| s.to_le_bytes()).collect();
        chunk(&mut main, b"SIZE", &size);
        let mut xyzi = (voxels.len() as u32).to_le_bytes().to_vec();
        xyzi.extend(voxels.iter().flatten());
        chunk(&mut main, b"XYZI", &xyzi);
    }
    let mut bytes = b"VOX ".to_vec();
    bytes.extend_from_slice(&150u32.to_le_bytes());
    bytes.extend_from_slice(b"MAIN");
    bytes.extend_from_slice(&0u32.to_le_bytes());
    bytes.extend_from_slice(&(main.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&main);
    bytes
}

/// A glTF scene made with gltf-json (`scene.gltf` and `scene.bin` in `dir`): a parent turned 30 degrees about y, scaled 2 and moved, with
/// three children: "Cube" (a unit cube turned 45 degrees about x: the whole transform fits an
/// object), "Slab" (a unit cube stretched 3x along x: the stretch is baked in) and "Ground" (a
/// 200 x 200 plane, hundreds of times larger than the rest).
pub fn write_node_scene(dir: &std::path::Path) -> std::path::PathBuf {
    let cube: Vec<[f32; 3]> = (0..8)
        .map(|i| {
            [
                (i & 1) as f32 - 0.5,
                ((i >> 1) & 1) as f32 - 0.5,
                ((i >> 2) & 1) as f32 - 0.5,
            ]
        })
        .collect();
    let cube_indices: [u16; 36] = [
        0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6,
        1, 3, 5, 3, 7, 5,
    ];
    let plane: [[f32; 3]; 4] = [
        [-100.0, 0.0, -100.0],
        [100.0, 0.0, -100.0],
        [-100.0, 0.0, 100.0],
        [100.0, 0.0, 100.0],
    ];
    let plane_indices: [u16; 6] = [0, 2, 1, 1, 2, 3];
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut push = |bytes: &[u8], target: u32| {
        views.push(serde_json::json!({
            "buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len(), "target": target
        }));
        bin.extend_from_slice(bytes);
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
    };
    let floats =
        |v: &[[f32; 3]]| -> Vec<u8> { v.iter().flatten().flat_map(|f| f.to_le_bytes()).collect() };
    let shorts = |v: &[u16]| -> Vec<u8> { v.iter().flat_map(|i| i.to_le_bytes()).collect() };
    push(&floats(&cube), 34962);
    push(&shorts(&cube_indices), 34963);
    push(&floats(&plane), 34962);
    push(&shorts(&plane_indices), 34963);
    std::fs::write(dir.join("scene.bin"), &bin).unwrap();
    let turn = glam::Quat::from_rotation_y(30f32.to_radians());
    let tilt = glam::Quat::from_rotation_x(45f32.to_radians());
    let root: gltf::json::Root = serde_json::from_value(serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "Parent", "children": [1, 2, 3], "translation": [5.0, 0.0, -2.0],
             "rotation": turn.to_array(), "scale": [2.0, 2.0, 2.0]},
            {"name": "Cube", "mesh": 0, "translation": [1.0, 1.0, 0.0],
             "rotation": tilt.to_array()},
            {"name": "Slab", "mesh": 0, "translation": [-2.0, 0.5, 0.0], "scale": [3.0, 1.0, 1.0]},
            {"name": "Ground", "mesh": 1, "translation": [0.0, -1.0, 0.0]}
        ],
        "meshes": [
            {"name": "cube", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
            {"name": "plane", "primitives": [{"attributes": {"POSITION": 2}, "indices": 3}]}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": [-0.5, -0.5, -0.5], "max": [0.5, 0.5, 0.5]},
            {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-100.0, 0.0, -100.0], "max": [100.0, 0.0, 100.0]},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": views,
        "buffers": [{"uri": "scene.bin", "byteLength": bin.len()}]
    }))
    .unwrap();
    let path = dir.join("scene.gltf");
    std::fs::write(&path, gltf::json::serialize::to_vec_pretty(&root).unwrap()).unwrap();
    path
}

//! What the integration test files share: running the real `thicket` binary and reading its
//! output; the GPU parity helpers are in [`gpu`].

// Each test file compiles this module on its own and uses only part of it.
#![allow(dead_code)]

use std::process::{Command, Output};

pub mod gpu;

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

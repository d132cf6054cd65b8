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

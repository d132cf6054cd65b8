//! The Thicket editor, GPU renderer and CLI as a library, so tests can build the whole app.
//!
//! | module | owns |
//! |---|---|
//! | [`bench`](mod@bench) | `thicket bench`: timing the CPU and GPU renderers |
//! | [`cli`] | the `thicket` command line |
//! | [`files`] | opening any supported file as a document; `info` summaries |
//! | [`editor`] | editor state, commands, undo/redo (no UI) |
//! | [`gpu`] | the wgpu renderer (headless-capable) |
//! | [`preview`] | the view's image: GPU view, egui-wgpu bridge, CPU preview, analysis overlays |
//! | [`preview::viewport`] | the one bridge between egui and the GPU renderer (paint callback) |
//! | [`tradeoff`] | `thicket tradeoff`: quality sweep reports and plots |
//! | [`ui`] | the eframe app: menu bar, tool bar, outliner, inspector, 3D view, perf overlay |

// Habits made checks (clippy runs with -D warnings): every public item documented, and no
// unwrap/expect outside tests (bad input is an error, never a panic).
#![warn(missing_docs)]
#![cfg_attr(not(test), warn(clippy::unwrap_used, clippy::expect_used))]

pub mod bench;
pub mod cli;
pub mod editor;
pub mod files;
pub mod gpu;
pub mod preview;
pub mod tradeoff;
pub mod ui;

//! The Thicket editor, GPU renderer and CLI as a library, so tests can build the whole app.
//!
//! | module | owns |
//! |---|---|
//! | [`cli`] | the `thicket` command line |
//! | [`files`] | opening any supported file as a document; `info` summaries |
//! | [`editor`] | editor state, commands, undo/redo (no UI) |
//! | [`gpu`] | the wgpu renderer (headless-capable) |
//! | [`tradeoff`] | `thicket tradeoff`: quality sweep reports and plots |
//! | [`ui`] | the eframe app: menu bar, outliner, inspector, status bar, preview |

pub mod cli;
pub mod editor;
pub mod files;
pub mod gpu;
pub mod tradeoff;
pub mod ui;

//! The Thicket editor, GPU renderer and CLI as a library, so tests can build the whole app.

pub mod gpu;

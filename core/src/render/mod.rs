//! `render` (work in progress).

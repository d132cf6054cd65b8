//! `scene` (work in progress).

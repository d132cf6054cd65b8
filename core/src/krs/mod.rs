//! `krs` (work in progress).

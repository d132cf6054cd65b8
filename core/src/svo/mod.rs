//! `svo` (work in progress).

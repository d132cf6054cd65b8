//! `measure` (work in progress).

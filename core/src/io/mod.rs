//! `io` (work in progress).

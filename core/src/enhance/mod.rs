//! `enhance` (work in progress).

//! `sculpt` (work in progress).

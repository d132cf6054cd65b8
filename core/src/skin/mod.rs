//! `skin` (work in progress).

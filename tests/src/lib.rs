//! Shared helpers for Thicket's cross-crate tests.

//! Tests for the KRS module.

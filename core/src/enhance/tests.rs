//! Tests of `enhance`.

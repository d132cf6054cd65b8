//! Measurements: image error metrics now; quality sweeps (time vs error) and reports later.

pub mod image;

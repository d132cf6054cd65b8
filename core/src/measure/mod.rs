//! Measurements: image error metrics, frame error against a reference render, quality sweeps
//! (time and work vs error) and their Pareto fronts.

pub mod compare;
pub mod image;
pub mod pareto;
pub mod skin;
pub mod sweep;

pub use compare::{Frame, FrameError, compare_frames};
pub use pareto::{Dominance, pareto_front};
pub use sweep::{
    KnobEffect, KnobValues, SweepError, SweepPoint, SweepReport, SweepSettings, default_knobs,
    estimate_sweep_peak_bytes, reference_quality, sweep, sweep_document,
    sweep_document_with_cancel, sweep_with_cancel, work_units,
};

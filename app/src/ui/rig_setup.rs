//! The Rig section's state (kept by the pose tool, drawn by `rig_panel`).

use thicket_core::skin::BindMethod;

/// What the weight brush does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WeightMode {
    /// Toward weight 1 on the selected joint.
    Add,
    /// Toward weight 0 on the selected joint.
    Subtract,
    /// Toward the average of the neighbours.
    Smooth,
}

/// The Rig section's state.
#[derive(Debug)]
pub struct RigSetup {
    /// Clicks on the selected voxel model place joints (Rig mode).
    pub placing: bool,
    /// How Bind computes weights.
    pub method: BindMethod,
    /// Drags on the selected rigged model paint the selected joint's weight.
    pub painting: bool,
    /// The weight brush's mode.
    pub mode: WeightMode,
    /// Brush radius in voxels.
    pub radius: f32,
    /// Fraction of the way to the target per dab (Add / Subtract).
    pub strength: f32,
    /// Show the selected joint's weights as a heat map over the model.
    pub show_weights: bool,
    /// A Bind the app should start as a job: (object, method).
    pub bind_request: Option<(u64, BindMethod)>,
    /// The name field of the selected joint while it has the keyboard: ((object, joint), text).
    pub(super) name_edit: Option<((u64, usize), String)>,
    /// The name field of a clip, while it is edited: (clip, text).
    pub(super) clip_edit: Option<(usize, String)>,
    /// New clip's name and length.
    pub(super) clip_name: String,
    pub(super) clip_length: f32,
    /// Why the last rig command was refused.
    pub error: Option<String>,
}

impl Default for RigSetup {
    fn default() -> Self {
        Self {
            placing: false,
            method: BindMethod::Geodesic,
            painting: false,
            mode: WeightMode::Add,
            radius: 3.0,
            strength: 0.5,
            show_weights: false,
            bind_request: None,
            name_edit: None,
            clip_edit: None,
            clip_name: "action".into(),
            clip_length: 1.0,
            error: None,
        }
    }
}

impl RigSetup {
    /// Whether left drags in the view paint weights (they do not orbit then).
    #[must_use]
    pub fn paints(&self) -> bool {
        self.painting
    }
}

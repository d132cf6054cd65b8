//! Enhancement settings (serde, every struct `#[serde(default)]`) and their validation.

use serde::{Deserialize, Serialize};

use super::EnhanceError;

/// Largest expansion factor: fragment rows of one cell plus a margin must fit a `u128`, and a
/// cell's `F³` bit set stays at most 32 KiB.
pub const MAX_FACTOR: u32 = 64;

/// Largest probe count per fragment.
pub const MAX_PROBES: u32 = 4096;

/// Largest probe spread in coarse voxels (the footprint is `(2⌈spread⌉ + 1)³` voxels).
pub const MAX_SPREAD: f32 = 8.0;

/// Which of the paper's two operators builds the fragments.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Recursive subdivision (§2): power-of-two factors only.
    #[default]
    Subdivide,
    /// Direct resampling with a stored probe pattern (§3): any integer factor.
    Resample,
}

/// A threshold per material.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MaterialThreshold {
    /// Material id.
    pub material: u8,
    /// Threshold for fragments of that material.
    pub threshold: f32,
}

/// How the threshold varies over the fragments. For [`Method::Subdivide`] a threshold is a
/// voxel count (whole numbers; 0 acts as 1 and values above 4 act as 4, see the module docs);
/// for [`Method::Resample`] it is a fraction of the probes (a fragment is solid when *more*
/// than `threshold × count` probes hit; values ≥ 1 mean "every probe").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ThresholdPattern {
    /// One threshold everywhere.
    Constant {
        /// The threshold.
        value: f32,
    },
    /// Alternates with the least significant bit of the fragment's altitude (fine y): the
    /// paper's strata (3/4 gives delicate layers with rounded corners).
    Alternating {
        /// Fragments at even altitude.
        even: f32,
        /// Fragments at odd altitude.
        odd: f32,
    },
    /// By material. Subdivision: the material of the coarse voxel the fragment lies in
    /// (`default` where that voxel is empty). Resampling: the majority material among the
    /// fragment's probe hits.
    PerMaterial {
        /// Threshold for materials not listed (and for empty source voxels).
        default: f32,
        /// Listed materials.
        materials: Vec<MaterialThreshold>,
    },
}

impl ThresholdPattern {
    /// `(even, odd)` threshold for material `m` (`None`: empty source voxel / no material).
    #[must_use]
    pub fn for_material(&self, m: Option<u8>) -> (f32, f32) {
        match self {
            Self::Constant { value } => (*value, *value),
            Self::Alternating { even, odd } => (*even, *odd),
            Self::PerMaterial { default, materials } => {
                let t = m
                    .and_then(|m| materials.iter().find(|e| e.material == m))
                    .map_or(*default, |e| e.threshold);
                (t, t)
            }
        }
    }

    fn values(&self) -> Vec<f32> {
        match self {
            Self::Constant { value } => vec![*value],
            Self::Alternating { even, odd } => vec![*even, *odd],
            Self::PerMaterial { default, materials } => std::iter::once(*default)
                .chain(materials.iter().map(|e| e.threshold))
                .collect(),
        }
    }
}

/// Recursive subdivision parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SubdivideSettings {
    /// Voxel-count threshold pattern (1–4).
    pub threshold: ThresholdPattern,
}

impl Default for SubdivideSettings {
    fn default() -> Self {
        Self {
            threshold: ThresholdPattern::Constant { value: 2.0 },
        }
    }
}

/// Direct resampling parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ResampleSettings {
    /// Probe-fraction threshold pattern (the paper used 0.25).
    pub threshold: ThresholdPattern,
    /// Probes per fragment (the paper showed 4 and 512).
    pub probe_count: u32,
    /// Probe offsets are uniform in `[-spread, spread]³`, in coarse voxels (the paper: 1.0).
    pub spread: f32,
    /// Seed of the stored pattern.
    pub seed: u64,
}

impl Default for ResampleSettings {
    fn default() -> Self {
        Self {
            threshold: ThresholdPattern::Constant { value: 0.25 },
            probe_count: 16,
            spread: 1.0,
            seed: 1,
        }
    }
}

/// How fragments take the colour of the voxels that made them. Either way the fragment takes
/// the majority material of its contributing voxels, and only voxels of that material give it
/// colour, so different materials keep crisp edges.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ColorMode {
    /// Weighted average in linear space of the same-material contributors.
    #[default]
    Blend,
    /// The strongest same-material contributor's colour.
    Nearest,
}

/// Random-walk ("snowflake") lighting of §4.4, baked into the fragment colours.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LightingSettings {
    /// Bake lighting into the colours.
    pub enabled: bool,
    /// Direction toward the sun (Y up); normalised on use.
    pub sun_direction: [f32; 3],
    /// Linear RGB added by a sun particle fraction of 1.
    pub sun_color: [f32; 3],
    /// Linear RGB added by a sky particle fraction of 1.
    pub sky_color: [f32; 3],
    /// Linear light every fragment gets.
    pub ambient: f32,
    /// Sun particles per fragment (wander biased toward the sun).
    pub sun_particles: u32,
    /// Sky particles per fragment (wander uniformly).
    pub sky_particles: u32,
    /// Steps a particle must survive without touching a solid fragment.
    pub steps: u32,
    /// Step length in coarse voxels (so the look does not change with the factor).
    pub step_length: f32,
    /// 0: sun particles wander uniformly; 1: they go straight toward the sun.
    pub sun_bias: f32,
    /// Seed; each fragment seeds its own generator from it and its coordinate.
    pub seed: u64,
}

impl Default for LightingSettings {
    fn default() -> Self {
        Self {
            enabled: false,
            sun_direction: [0.4, 1.0, 0.3],
            sun_color: [0.9, 0.85, 0.75],
            sky_color: [0.35, 0.45, 0.6],
            ambient: 0.15,
            sun_particles: 8,
            sky_particles: 8,
            steps: 8,
            step_length: 0.25,
            sun_bias: 0.7,
            seed: 7,
        }
    }
}

/// Everything that decides an enhancement's output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct EnhanceSettings {
    /// Subdivision or resampling.
    pub method: Method,
    /// Linear expansion factor (fragments per voxel edge), 1..=[`MAX_FACTOR`].
    pub factor: u32,
    /// Subdivision parameters (used when `method` is `Subdivide`).
    pub subdivide: SubdivideSettings,
    /// Resampling parameters (used when `method` is `Resample`).
    pub resample: ResampleSettings,
    /// Colour rule.
    pub color: ColorMode,
    /// Baked lighting.
    pub lighting: LightingSettings,
}

impl Default for EnhanceSettings {
    fn default() -> Self {
        Self {
            method: Method::Subdivide,
            factor: 4,
            subdivide: SubdivideSettings::default(),
            resample: ResampleSettings::default(),
            color: ColorMode::Blend,
            lighting: LightingSettings::default(),
        }
    }
}

fn bad(field: &'static str, reason: impl Into<String>) -> EnhanceError {
    EnhanceError::Invalid {
        field,
        reason: reason.into(),
    }
}

fn check_color(field: &'static str, c: [f32; 3]) -> Result<(), EnhanceError> {
    if c.iter().any(|v| !v.is_finite() || *v < 0.0 || *v > 16.0) {
        return Err(bad(field, format!("{c:?} must be finite and in 0..=16")));
    }
    Ok(())
}

impl EnhanceSettings {
    /// Checks every parameter is finite and in range.
    ///
    /// # Errors
    /// [`EnhanceError::Invalid`] naming the field and what is allowed.
    pub fn validate(&self) -> Result<(), EnhanceError> {
        if self.factor == 0 || self.factor > MAX_FACTOR {
            return Err(bad(
                "factor",
                format!("{} is outside 1..={MAX_FACTOR}", self.factor),
            ));
        }
        match self.method {
            Method::Subdivide => {
                if !self.factor.is_power_of_two() {
                    return Err(bad(
                        "factor",
                        format!(
                            "recursive subdivision doubles per level, so the factor must be a \
                             power of two (got {}); use method \"resample\" for other factors",
                            self.factor
                        ),
                    ));
                }
                for t in self.subdivide.threshold.values() {
                    if !t.is_finite() || t < 0.0 || t.fract() != 0.0 {
                        return Err(bad(
                            "subdivide.threshold",
                            format!("{t} must be a whole voxel count (1..=4)"),
                        ));
                    }
                }
            }
            Method::Resample => {
                let r = &self.resample;
                for t in r.threshold.values() {
                    if !t.is_finite() || t < 0.0 {
                        return Err(bad(
                            "resample.threshold",
                            format!("{t} must be a finite fraction ≥ 0"),
                        ));
                    }
                }
                if r.probe_count == 0 || r.probe_count > MAX_PROBES {
                    return Err(bad(
                        "resample.probe_count",
                        format!("{} is outside 1..={MAX_PROBES}", r.probe_count),
                    ));
                }
                if !r.spread.is_finite() || r.spread < 0.0 || r.spread > MAX_SPREAD {
                    return Err(bad(
                        "resample.spread",
                        format!("{} is outside 0..={MAX_SPREAD} voxels", r.spread),
                    ));
                }
            }
        }
        let l = &self.lighting;
        if l.enabled {
            let d = l.sun_direction;
            if d.iter().any(|v| !v.is_finite()) || d.iter().all(|v| *v == 0.0) {
                return Err(bad(
                    "lighting.sun_direction",
                    format!("{d:?} must be finite and non-zero"),
                ));
            }
            check_color("lighting.sun_color", l.sun_color)?;
            check_color("lighting.sky_color", l.sky_color)?;
            if !l.ambient.is_finite() || !(0.0..=16.0).contains(&l.ambient) {
                return Err(bad(
                    "lighting.ambient",
                    format!("{} not in 0..=16", l.ambient),
                ));
            }
            if l.sun_particles > 1024 || l.sky_particles > 1024 {
                return Err(bad("lighting.particles", "at most 1024 per kind"));
            }
            if l.steps == 0 || l.steps > 1024 {
                return Err(bad(
                    "lighting.steps",
                    format!("{} outside 1..=1024", l.steps),
                ));
            }
            if !l.step_length.is_finite() || l.step_length <= 0.0 || l.step_length > 4.0 {
                return Err(bad(
                    "lighting.step_length",
                    format!("{} outside (0, 4] voxels", l.step_length),
                ));
            }
            if l.steps as f32 * l.step_length > 16.0 {
                return Err(bad(
                    "lighting.steps",
                    "steps × step_length must be at most 16 voxels (it sets the re-enhancement \
                     window after an edit)",
                ));
            }
            if !l.sun_bias.is_finite() || !(0.0..=1.0).contains(&l.sun_bias) {
                return Err(bad(
                    "lighting.sun_bias",
                    format!("{} not in 0..=1", l.sun_bias),
                ));
            }
        }
        Ok(())
    }
}

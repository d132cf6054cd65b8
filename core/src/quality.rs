//! The one set of quality knobs read by every renderer. Each knob trades time for error; the
//! trade is measured by `measure` sweeps, and the presets are chosen from its Pareto front.

use crate::skin::StretchStrategy;
use serde::{Deserialize, Serialize};

/// A named preset row: draft / balanced / final.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum QualityPreset {
    /// Fastest interactive preview.
    Draft,
    /// The editor default.
    #[default]
    Balanced,
    /// Offline renders and references.
    Final,
}

/// Why a quality setting was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum QualityError {
    /// A knob outside its allowed range (or not finite).
    #[error("quality setting {name} = {value} is out of range ({range})")]
    OutOfRange {
        /// Knob name as used by `--quality NAME=VALUE`.
        name: &'static str,
        /// The refused value.
        value: f64,
        /// The allowed range, for the message.
        range: &'static str,
    },
    /// An unknown knob name.
    #[error("unknown quality setting {0:?}; known: {known}", known = Quality::KNOBS.join(", "))]
    Unknown(String),
    /// A value that does not parse.
    #[error("quality setting {name}: {value:?} is not a valid value")]
    Parse {
        /// Knob name.
        name: String,
        /// The text given.
        value: String,
    },
}

/// Quality knobs shared by the CPU reference and the GPU renderer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Quality {
    /// ASVO: a node is split while its projected size exceeds this many pixels.
    pub lod_pixel_threshold: f32,
    /// ASVO: a splat whose screen rectangle is wider or taller than this many pixels is drawn
    /// as its exact cube (per-pixel ray–box: true depth, straight edges, the face's normal)
    /// instead of the paper's rectangle at its nearest depth. Up close, voxels are then cubes;
    /// far away nothing changes. Large values keep the rectangles everywhere.
    pub cube_pixel_threshold: f32,
    /// ASVO: hierarchical-depth occlusion culling (paper §8.1.2).
    pub occlusion_culling: bool,
    /// Shadow maps on/off.
    pub shadows: bool,
    /// Shadow map edge in texels.
    pub shadow_map_size: u32,
    /// Percentage-closer filter radius in shadow texels (0 = hard).
    pub shadow_pcf_radius: u32,
    /// Ambient-occlusion samples (0 = off).
    pub ao_samples: u32,
    /// KRS: pixel-cone epsilon multiplier (1 = one pixel footprint).
    pub krs_epsilon_scale: f32,
    /// KRS: maximum sphere-tracing steps per ray.
    pub krs_max_steps: u32,
    /// KRS: over-relaxation factor (1 = off).
    pub krs_over_relaxation: f32,
    /// KRS: screen-tile cone acceleration (paper §4.1).
    pub krs_tile_acceleration: bool,
    /// KRS: soft shadows (penumbra from distance samples) instead of hard.
    pub krs_soft_shadows: bool,
    /// Skinning: global multiplier applied to every stretch factor.
    pub stretch_multiplier: f32,
    /// Skinning: one stretch strategy for every skinned model, overriding each model's own
    /// (`None`: each model keeps its own). Knob values: `model`, `off`, `thesis`, `corners`,
    /// `adaptive`; a sweep over it measures the strategies against each other on one view.
    pub stretch_strategy: Option<StretchStrategy>,
    /// Enhancement: probe count for direct resampling.
    pub enhancement_samples: u32,
}

impl Default for Quality {
    fn default() -> Self {
        Self::preset(QualityPreset::Balanced)
    }
}

impl Quality {
    /// Knob names accepted by [`Quality::set`].
    pub const KNOBS: [&'static str; 15] = [
        "lod_pixel_threshold",
        "cube_pixel_threshold",
        "occlusion_culling",
        "shadows",
        "shadow_map_size",
        "shadow_pcf_radius",
        "ao_samples",
        "krs_epsilon_scale",
        "krs_max_steps",
        "krs_over_relaxation",
        "krs_tile_acceleration",
        "krs_soft_shadows",
        "stretch_multiplier",
        "stretch_strategy",
        "enhancement_samples",
    ];

    /// A preset row.
    #[must_use]
    pub fn preset(p: QualityPreset) -> Self {
        let balanced = Self {
            lod_pixel_threshold: 1.0,
            cube_pixel_threshold: 3.0,
            occlusion_culling: true,
            shadows: true,
            shadow_map_size: 2048,
            shadow_pcf_radius: 1,
            ao_samples: 0,
            krs_epsilon_scale: 0.5,
            krs_max_steps: 160,
            krs_over_relaxation: 1.5,
            krs_tile_acceleration: true,
            krs_soft_shadows: false,
            stretch_multiplier: 1.0,
            stretch_strategy: None,
            enhancement_samples: 16,
        };
        match p {
            QualityPreset::Balanced => balanced,
            QualityPreset::Draft => Self {
                lod_pixel_threshold: 2.0,
                cube_pixel_threshold: 6.0,
                shadow_map_size: 1024,
                shadow_pcf_radius: 0,
                ao_samples: 0,
                krs_max_steps: 96,
                ..balanced
            },
            QualityPreset::Final => Self {
                lod_pixel_threshold: 0.5,
                cube_pixel_threshold: 1.5,
                shadow_map_size: 4096,
                shadow_pcf_radius: 2,
                ao_samples: 16,
                krs_epsilon_scale: 0.25,
                krs_max_steps: 400,
                krs_soft_shadows: true,
                enhancement_samples: 32,
                ..balanced
            },
        }
    }

    /// Checks every knob is finite and in range.
    ///
    /// # Errors
    /// The first knob out of range.
    pub fn validate(&self) -> Result<(), QualityError> {
        fn check(
            name: &'static str,
            v: f64,
            lo: f64,
            hi: f64,
            range: &'static str,
        ) -> Result<(), QualityError> {
            // The knobs are f32 and the bounds are written in decimal: compare in f32, so the
            // documented bounds themselves (0.01, 1.95) are inside the range.
            let (v32, lo32, hi32) = (v as f32, lo as f32, hi as f32);
            if v.is_finite() && v32 >= lo32 && v32 <= hi32 {
                Ok(())
            } else {
                Err(QualityError::OutOfRange {
                    name,
                    value: v,
                    range,
                })
            }
        }
        check(
            "lod_pixel_threshold",
            f64::from(self.lod_pixel_threshold),
            0.05,
            64.0,
            "0.05..=64",
        )?;
        check(
            "cube_pixel_threshold",
            f64::from(self.cube_pixel_threshold),
            1.0,
            1e6,
            "1..=1000000",
        )?;
        check(
            "shadow_map_size",
            f64::from(self.shadow_map_size),
            16.0,
            16384.0,
            "16..=16384",
        )?;
        check(
            "shadow_pcf_radius",
            f64::from(self.shadow_pcf_radius),
            0.0,
            8.0,
            "0..=8",
        )?;
        check(
            "ao_samples",
            f64::from(self.ao_samples),
            0.0,
            64.0,
            "0..=64",
        )?;
        check(
            "krs_epsilon_scale",
            f64::from(self.krs_epsilon_scale),
            0.01,
            100.0,
            "0.01..=100",
        )?;
        check(
            "krs_max_steps",
            f64::from(self.krs_max_steps),
            1.0,
            10_000.0,
            "1..=10000",
        )?;
        check(
            "krs_over_relaxation",
            f64::from(self.krs_over_relaxation),
            1.0,
            1.95,
            "1..=1.95",
        )?;
        check(
            "stretch_multiplier",
            f64::from(self.stretch_multiplier),
            0.0,
            8.0,
            "0..=8",
        )?;
        check(
            "enhancement_samples",
            f64::from(self.enhancement_samples),
            1.0,
            1024.0,
            "1..=1024",
        )?;
        Ok(())
    }

    /// Sets one knob from text (`--quality NAME=VALUE`), validating the result.
    ///
    /// # Errors
    /// Unknown name, unparsable value or out of range; `self` is unchanged on error.
    pub fn set(&mut self, name: &str, value: &str) -> Result<(), QualityError> {
        let parse_err = || QualityError::Parse {
            name: name.to_owned(),
            value: value.to_owned(),
        };
        let f = || value.trim().parse::<f32>().map_err(|_| parse_err());
        let u = || value.trim().parse::<u32>().map_err(|_| parse_err());
        let b = || match value.trim() {
            "1" | "true" | "on" | "yes" => Ok(true),
            "0" | "false" | "off" | "no" => Ok(false),
            _ => Err(parse_err()),
        };
        let mut q = self.clone();
        match name {
            "lod_pixel_threshold" => q.lod_pixel_threshold = f()?,
            "cube_pixel_threshold" => q.cube_pixel_threshold = f()?,
            "occlusion_culling" => q.occlusion_culling = b()?,
            "shadows" => q.shadows = b()?,
            "shadow_map_size" => q.shadow_map_size = u()?,
            "shadow_pcf_radius" => q.shadow_pcf_radius = u()?,
            "ao_samples" => q.ao_samples = u()?,
            "krs_epsilon_scale" => q.krs_epsilon_scale = f()?,
            "krs_max_steps" => q.krs_max_steps = u()?,
            "krs_over_relaxation" => q.krs_over_relaxation = f()?,
            "krs_tile_acceleration" => q.krs_tile_acceleration = b()?,
            "krs_soft_shadows" => q.krs_soft_shadows = b()?,
            "stretch_multiplier" => q.stretch_multiplier = f()?,
            "stretch_strategy" => {
                q.stretch_strategy = match value.trim().to_ascii_lowercase().as_str() {
                    "model" => None,
                    "off" => Some(StretchStrategy::Off),
                    "thesis" => Some(StretchStrategy::Thesis),
                    "corners" => Some(StretchStrategy::Corners),
                    "adaptive" => Some(StretchStrategy::Adaptive),
                    _ => return Err(parse_err()),
                }
            }
            "enhancement_samples" => q.enhancement_samples = u()?,
            _ => return Err(QualityError::Unknown(name.to_owned())),
        }
        q.validate()?;
        *self = q;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_ordered() {
        for p in [
            QualityPreset::Draft,
            QualityPreset::Balanced,
            QualityPreset::Final,
        ] {
            Quality::preset(p).validate().unwrap();
        }
        let (d, f) = (
            Quality::preset(QualityPreset::Draft),
            Quality::preset(QualityPreset::Final),
        );
        assert!(d.lod_pixel_threshold > f.lod_pixel_threshold);
    }

    #[test]
    fn set_refuses_bad_values_and_keeps_state() {
        let mut q = Quality::default();
        assert!(matches!(
            q.set("lod_pixel_threshold", "NaN"),
            Err(QualityError::OutOfRange { .. })
        ));
        assert!(matches!(
            q.set("lod_pixel_threshold", "abc"),
            Err(QualityError::Parse { .. })
        ));
        assert!(matches!(q.set("nope", "1"), Err(QualityError::Unknown(_))));
        assert_eq!(q, Quality::default());
        q.set("shadows", "off").unwrap();
        assert!(!q.shadows);
        q.set("stretch_strategy", "Corners").unwrap();
        assert_eq!(q.stretch_strategy, Some(StretchStrategy::Corners));
        assert!(matches!(
            q.set("stretch_strategy", "wide"),
            Err(QualityError::Parse { .. })
        ));
        assert_eq!(q.stretch_strategy, Some(StretchStrategy::Corners));
        q.set("stretch_strategy", "model").unwrap();
        assert_eq!(q.stretch_strategy, None);
        for name in Quality::KNOBS {
            assert!(
                !matches!(q.clone().set(name, "1"), Err(QualityError::Unknown(_))),
                "{name}"
            );
        }
    }
}

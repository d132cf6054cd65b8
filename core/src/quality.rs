//! The one set of quality knobs read by every renderer. Each knob trades time for error; the
//! trade is measured by `measure` sweeps, and the presets are chosen from its Pareto front.

use crate::skin::StretchStrategy;
use serde::{Deserialize, Serialize};

/// The most samples per pixel side [`Quality::supersample`] allows (16 samples per pixel).
pub const MAX_SUPERSAMPLE: u32 = 4;

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
        /// The allowed range, for the message (from the knob's [`KnobSpec`]).
        range: String,
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
    /// Antialiasing: both renderers draw `supersample`² samples per pixel (a grid of
    /// `supersample` × `supersample`) and averages them in linear light, for `supersample`² the
    /// work. Sub-pixel detail (KRS grass, leaves, far voxels' edges) then shows as the part of
    /// the pixel it covers instead of all or nothing. Every knob counted in pixels (LOD, exact
    /// cubes, KRS epsilon) is counted in samples. 1 = one sample per pixel.
    pub supersample: u32,
}

impl Default for Quality {
    fn default() -> Self {
        Self::preset(QualityPreset::Balanced)
    }
}

/// The widest shadow PCF radius any renderer filters with (texels): the knob's maximum, also
/// applied to values read from files.
pub const MAX_PCF_RADIUS: u32 = 8;

/// The rules both renderers derive from a [`Quality`], in one place
/// ([`Quality::frame_settings`]): each renderer reads these instead of re-applying the rules.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameSettings {
    /// Shadow PCF radius in texels, at most [`MAX_PCF_RADIUS`].
    pub pcf_radius: u32,
    /// Pixels a shadow receiver's depth bias spans: the LOD threshold, at least one pixel (a
    /// splat at the cut covers that much of the surface, so a receiver within it must not
    /// shadow itself).
    pub receiver_px: f32,
}

impl Quality {
    /// The settings both renderers derive from these knobs.
    #[must_use]
    pub fn frame_settings(&self) -> FrameSettings {
        FrameSettings {
            pcf_radius: self.shadow_pcf_radius.min(MAX_PCF_RADIUS),
            receiver_px: self.lod_pixel_threshold.max(1.0),
        }
    }

    /// Knob names accepted by [`Quality::set`], in [`KNOB_SPECS`] order.
    pub const KNOBS: [&'static str; KNOB_SPECS.len()] = {
        let mut names = [""; KNOB_SPECS.len()];
        let mut i = 0;
        while i < KNOB_SPECS.len() {
            names[i] = KNOB_SPECS[i].name;
            i += 1;
        }
        names
    };

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
            supersample: 1,
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
                supersample: 3,
                ..balanced
            },
        }
    }

    /// Checks every knob is finite and in its [`KnobSpec`] range.
    ///
    /// # Errors
    /// The first knob out of range.
    pub fn validate(&self) -> Result<(), QualityError> {
        for spec in KNOB_SPECS {
            // The knobs are f32 and the bounds are written in decimal: compare in f32, so the
            // documented bounds themselves (0.01, 1.95) are inside the range.
            let (v, lo, hi) = match spec.kind {
                KnobKind::F32 { get, min, max, .. } => (f64::from(get(self)), min, max),
                KnobKind::U32 { get, min, max, .. } => {
                    (f64::from(get(self)), min as f32, max as f32)
                }
                KnobKind::Bool { .. } | KnobKind::StretchStrategy { .. } => continue,
            };
            let v32 = v as f32;
            if !(v.is_finite() && v32 >= lo && v32 <= hi) {
                return Err(QualityError::OutOfRange {
                    name: spec.name,
                    value: v,
                    range: spec.range_text(),
                });
            }
        }
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
        let spec = KnobSpec::named(name).ok_or_else(|| QualityError::Unknown(name.to_owned()))?;
        let mut q = self.clone();
        match spec.kind {
            KnobKind::F32 { get_mut, .. } => *get_mut(&mut q) = f()?,
            KnobKind::U32 { get_mut, .. } => *get_mut(&mut q) = u()?,
            KnobKind::Bool { get_mut, .. } => *get_mut(&mut q) = b()?,
            KnobKind::StretchStrategy { get_mut, .. } => {
                *get_mut(&mut q) = match value.trim().to_ascii_lowercase().as_str() {
                    "model" => None,
                    "off" => Some(StretchStrategy::Off),
                    "thesis" => Some(StretchStrategy::Thesis),
                    "corners" => Some(StretchStrategy::Corners),
                    "adaptive" => Some(StretchStrategy::Adaptive),
                    _ => return Err(parse_err()),
                }
            }
        }
        q.validate()?;
        *self = q;
        Ok(())
    }
}

/// How a knob is stored, read and bounded. The accessors let every reader (validation,
/// `--quality` parsing, the inspector's widgets) go through the one table.
#[derive(Clone, Copy)]
pub enum KnobKind {
    /// A real number in `min..=max`.
    F32 {
        /// Reads the knob.
        get: fn(&Quality) -> f32,
        /// Writes the knob.
        get_mut: fn(&mut Quality) -> &mut f32,
        /// Smallest allowed value.
        min: f32,
        /// Largest allowed value.
        max: f32,
    },
    /// A count in `min..=max`.
    U32 {
        /// Reads the knob.
        get: fn(&Quality) -> u32,
        /// Writes the knob.
        get_mut: fn(&mut Quality) -> &mut u32,
        /// Smallest allowed value.
        min: u32,
        /// Largest allowed value.
        max: u32,
    },
    /// On or off (`1`/`true`/`on`/`yes`, `0`/`false`/`off`/`no`).
    Bool {
        /// Reads the knob.
        get: fn(&Quality) -> bool,
        /// Writes the knob.
        get_mut: fn(&mut Quality) -> &mut bool,
    },
    /// A stretch strategy for every skinned model, or each model's own (`model`, `off`,
    /// `thesis`, `corners`, `adaptive`).
    StretchStrategy {
        /// Reads the knob.
        get: fn(&Quality) -> Option<StretchStrategy>,
        /// Writes the knob.
        get_mut: fn(&mut Quality) -> &mut Option<StretchStrategy>,
    },
}

/// One quality knob: its name (as `--quality NAME=VALUE` and sweeps spell it), kind and range,
/// unit, the inspector's label, what it does, and the values a default sweep tries.
#[derive(Clone, Copy)]
pub struct KnobSpec {
    /// The knob's name, as in `--quality NAME=VALUE` and `thicket tradeoff --knob`.
    pub name: &'static str,
    /// How it is stored and bounded.
    pub kind: KnobKind,
    /// Its unit (empty for a bare number, a switch or a choice).
    pub unit: &'static str,
    /// The inspector's label.
    pub label: &'static str,
    /// What it does (the inspector's tooltip).
    pub doc: &'static str,
    /// The values a default quality sweep tries (empty: not swept by default).
    pub sweep: &'static [&'static str],
}

impl KnobSpec {
    /// The row of the knob called `name`, if there is one.
    #[must_use]
    pub fn named(name: &str) -> Option<&'static KnobSpec> {
        KNOB_SPECS.iter().find(|k| k.name == name)
    }

    /// The allowed range as text (`0.05..=64`), empty for switches and choices.
    #[must_use]
    pub fn range_text(&self) -> String {
        match self.kind {
            KnobKind::F32 { min, max, .. } => format!("{min}..={max}"),
            KnobKind::U32 { min, max, .. } => format!("{min}..={max}"),
            KnobKind::Bool { .. } | KnobKind::StretchStrategy { .. } => String::new(),
        }
    }
}

/// A [`KnobSpec`] row; `$field` names the [`Quality`] field of the same name.
macro_rules! knob {
    (f32 $field:ident, $min:expr, $max:expr, $unit:expr, $label:expr, $doc:expr, $sweep:expr) => {
        KnobSpec {
            name: stringify!($field),
            kind: KnobKind::F32 {
                get: |q| q.$field,
                get_mut: |q| &mut q.$field,
                min: $min,
                max: $max,
            },
            unit: $unit,
            label: $label,
            doc: $doc,
            sweep: $sweep,
        }
    };
    (u32 $field:ident, $min:expr, $max:expr, $unit:expr, $label:expr, $doc:expr, $sweep:expr) => {
        KnobSpec {
            name: stringify!($field),
            kind: KnobKind::U32 {
                get: |q| q.$field,
                get_mut: |q| &mut q.$field,
                min: $min,
                max: $max,
            },
            unit: $unit,
            label: $label,
            doc: $doc,
            sweep: $sweep,
        }
    };
    (bool $field:ident, $label:expr, $doc:expr) => {
        KnobSpec {
            name: stringify!($field),
            kind: KnobKind::Bool {
                get: |q| q.$field,
                get_mut: |q| &mut q.$field,
            },
            unit: "",
            label: $label,
            doc: $doc,
            sweep: &[],
        }
    };
}

/// Every quality knob, in the order validation checks them and `--quality` lists them.
pub const KNOB_SPECS: &[KnobSpec] = &[
    knob!(f32 lod_pixel_threshold, 0.05, 64.0, "px", "LOD threshold px",
        "ASVO: a node is split while its projected size exceeds this many pixels",
        &["0.5", "1", "2", "4", "8"]),
    knob!(f32 cube_pixel_threshold, 1.0, 1e6, "px", "Exact cubes above px",
        "ASVO: splats wider than this many pixels are drawn as exact cubes (true depth, \
         straight edges, face normals); a large value keeps the paper's rectangles",
        &["1.5", "3", "6", "12", "1000000"]),
    knob!(bool occlusion_culling, "Occlusion culling", "ASVO: hierarchical occlusion culling"),
    knob!(bool shadows, "Shadows", "Shadow maps on/off"),
    knob!(u32 shadow_map_size, 16, 16384, "texels", "Shadow map", "Shadow map edge in texels",
        &["256", "512", "1024", "2048", "4096"]),
    knob!(u32 shadow_pcf_radius, 0, MAX_PCF_RADIUS, "texels", "Shadow PCF radius",
        "Shadow filter radius in texels (0 = hard)", &["0", "1", "2", "3"]),
    knob!(u32 ao_samples, 0, 64, "samples", "AO samples", "Ambient-occlusion samples (0 = off)",
        &["0", "4", "8", "16"]),
    knob!(f32 krs_epsilon_scale, 0.01, 100.0, "px", "KRS epsilon ×",
        "KRS: pixel-cone epsilon multiplier (1 = one pixel)", &[]),
    knob!(u32 krs_max_steps, 1, 10_000, "steps", "KRS max steps",
        "KRS: most sphere-tracing steps per ray", &[]),
    knob!(f32 krs_over_relaxation, 1.0, 1.95, "", "KRS over-relaxation",
        "KRS: sphere-tracing over-relaxation (1 = off)", &[]),
    knob!(bool krs_tile_acceleration, "KRS tile acceleration", "KRS: screen-tile cone acceleration"),
    knob!(bool krs_soft_shadows, "KRS soft shadows", "KRS: soft instead of hard shadows"),
    knob!(f32 stretch_multiplier, 0.0, 8.0, "×", "Stretch ×",
        "Skinning: multiplier on every stretch factor", &[]),
    KnobSpec {
        name: "stretch_strategy",
        kind: KnobKind::StretchStrategy {
            get: |q| q.stretch_strategy,
            get_mut: |q| &mut q.stretch_strategy,
        },
        unit: "",
        label: "Stretch strategy",
        doc: "Skinning: one stretch strategy for every skinned model, or each model's own (set \
              in its stretch panel)",
        sweep: &[],
    },
    knob!(u32 enhancement_samples, 1, 1024, "probes", "Enhancement samples",
        "Detail enhancement: probes per fragment", &[]),
    knob!(u32 supersample, 1, MAX_SUPERSAMPLE, "samples per pixel side", "Supersampling",
        "Both renderers (preview, GPU view, renders, image exports): draw k × k samples per \
         pixel and average them, so grass, leaves and far edges thinner than a pixel show as \
         the part of it they cover; k² the work. 1 = off.",
        &["1", "2", "3"]),
];

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

    #[test]
    fn the_knob_table_bounds_every_numeric_knob_at_its_edges() {
        let mut checked = 0;
        for spec in KNOB_SPECS {
            let (lo, hi, below, above) = match spec.kind {
                KnobKind::F32 { min, max, .. } => (
                    min.to_string(),
                    max.to_string(),
                    (min - min.abs().max(1.0) * 0.01).to_string(),
                    (max + max.abs().max(1.0) * 0.01).to_string(),
                ),
                KnobKind::U32 { min, max, .. } => (
                    min.to_string(),
                    max.to_string(),
                    min.checked_sub(1)
                        .map_or_else(|| "-1".into(), |m| m.to_string()),
                    (max + 1).to_string(),
                ),
                KnobKind::Bool { .. } | KnobKind::StretchStrategy { .. } => continue,
            };
            let mut q = Quality::default();
            q.set(spec.name, &lo).unwrap();
            q.set(spec.name, &hi).unwrap();
            assert!(q.set(spec.name, &below).is_err(), "{} = {below}", spec.name);
            assert!(q.set(spec.name, &above).is_err(), "{} = {above}", spec.name);
            checked += 1;
        }
        assert_eq!(checked, 11);
        let e = Quality {
            krs_over_relaxation: 2.0,
            ..Quality::default()
        };
        assert_eq!(
            e.validate().unwrap_err().to_string(),
            "quality setting krs_over_relaxation = 2 is out of range (1..=1.95)"
        );
    }
}

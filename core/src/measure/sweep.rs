//! Quality sweeps: render a reference, then each setting of any [`Quality`] knob (by name, so
//! knobs added later are sweepable without changing this code); per setting, the median time
//! of N renders, a deterministic work count and the error against the reference.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::compare::{Frame, FrameError, compare_frames};
use super::image::MeasureError;
use super::pareto::{Dominance, pareto_front};
use crate::quality::{KNOB_SPECS, Quality, QualityError, QualityPreset};
use crate::render::{Camera, FrameBuffers, FrameStats, RenderError, Renderer, RgbaImage, View};
use crate::scene::Document;

/// Most settings one sweep may render (a grid over many knobs grows fast).
pub const MAX_SWEEP_POINTS: usize = 4096;

/// Why a sweep could not run.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A `NAME=V1,V2,...` specification that does not parse.
    #[error(
        "knob specification {spec:?}: {why} (expected NAME=V1,V2,... e.g. lod_pixel_threshold=0.5,1,2)"
    )]
    BadSpec {
        /// The text given.
        spec: String,
        /// What is wrong with it.
        why: &'static str,
    },
    /// A knob name or value the quality settings refuse.
    #[error("knob {name}={value}: {source}")]
    Knob {
        /// Knob name.
        name: String,
        /// The value.
        value: String,
        /// Why it was refused.
        source: QualityError,
    },
    /// Zero renders per point.
    #[error("a sweep needs at least one render per setting (got 0)")]
    NoRepeats,
    /// Too many settings.
    #[error(
        "the sweep has {0} settings; the limit is {MAX_SWEEP_POINTS} (sweep fewer values or not as a grid)"
    )]
    TooManyPoints(usize),
    /// A render failed.
    #[error("rendering setting {label}: {source}")]
    Render {
        /// The setting being rendered.
        label: String,
        /// The renderer's error.
        source: RenderError,
    },
    /// The caller's cancel flag was set (the editor's Cancel button).
    #[error("the sweep was cancelled")]
    Cancelled,
    /// The frames cannot be compared.
    #[error("comparing setting {label} with the reference: {source}")]
    Measure {
        /// The setting.
        label: String,
        /// Why.
        source: MeasureError,
    },
}

/// One knob and the values to try, as text (what [`Quality::set`] parses).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct KnobValues {
    /// Knob name, one of [`Quality::KNOBS`].
    pub name: String,
    /// Values to try.
    pub values: Vec<String>,
}

impl KnobValues {
    /// Parses `NAME=V1,V2,...` and checks every value against [`Quality::set`].
    ///
    /// # Errors
    /// [`SweepError::BadSpec`] for malformed text, [`SweepError::Knob`] for an unknown knob or
    /// a value out of range.
    pub fn parse(spec: &str) -> Result<Self, SweepError> {
        let bad = |why| SweepError::BadSpec {
            spec: spec.to_owned(),
            why,
        };
        let (name, values) = spec.split_once('=').ok_or_else(|| bad("no '='"))?;
        let name = name.trim();
        if name.is_empty() {
            return Err(bad("empty knob name"));
        }
        let values: Vec<String> = values.split(',').map(|v| v.trim().to_owned()).collect();
        if values.iter().any(String::is_empty) {
            return Err(bad("empty value"));
        }
        let kv = Self {
            name: name.to_owned(),
            values,
        };
        kv.check()?;
        Ok(kv)
    }

    fn check(&self) -> Result<(), SweepError> {
        for v in &self.values {
            let mut q = Quality::default();
            q.set(&self.name, v).map_err(|source| SweepError::Knob {
                name: self.name.clone(),
                value: v.clone(),
                source,
            })?;
        }
        Ok(())
    }
}

/// The knobs the CPU reference renderer reads today, with values around the presets: what a
/// sweep covers when none are given.
#[must_use]
pub fn default_knobs() -> Vec<KnobValues> {
    KNOB_SPECS
        .iter()
        .filter(|k| !k.sweep.is_empty())
        .map(|k| KnobValues {
            name: k.name.to_owned(),
            values: k.sweep.iter().map(|v| (*v).to_owned()).collect(),
        })
        .collect()
}

/// The reference setting: the `final` preset raised further on every knob where more is
/// closer to the ideal image — LOD threshold 0.25 px (every voxel splat below a quarter pixel),
/// shadow maps up to 8192 texels, 32 AO samples, KRS epsilon 0.125 px with
/// 2000 steps and no over-relaxation (it can step over thin features), 128 enhancement probes,
/// and 4×4 samples per pixel (`supersample`): the ideal pixel is the mean over its area, and at
/// one sample per pixel sub-pixel detail (KRS grass, leaves) is all or nothing, so a
/// one-sample reference would only be one more aliased image (on the grassland sample, halving
/// the KRS epsilon from 0.125 to 0.03 px moves the one-sample image by RMSE 0.086). The
/// knobs counted in pixels count samples, so they are four times finer again in pixels.
/// Knobs that are choices rather than precision keep their `final` values: culling, stretch
/// multiplier, tile acceleration, soft shadows, and the PCF radius (a softness filter: a wider
/// reference filter would rank any blur, even a too-small shadow map, as "closer").
#[must_use]
pub fn reference_quality() -> Quality {
    let mut q = Quality::preset(QualityPreset::Final);
    for (name, value) in [
        ("lod_pixel_threshold", "0.25"),
        ("cube_pixel_threshold", "1"),
        ("shadow_map_size", "8192"),
        ("ao_samples", "32"),
        ("krs_epsilon_scale", "0.125"),
        ("krs_max_steps", "2000"),
        ("krs_over_relaxation", "1"),
        ("enhancement_samples", "128"),
        ("supersample", "4"),
    ] {
        // Every value is in range for its knob (the unit test checks the result validates);
        // a knob that was renamed keeps its `final` value rather than failing every sweep.
        let _ = q.set(name, value);
    }
    q
}

/// Which settings a sweep renders.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepSettings {
    /// The setting every variation starts from.
    pub base: Quality,
    /// Knobs and their values.
    pub knobs: Vec<KnobValues>,
    /// `false`: vary one knob at a time from `base`; `true`: every combination.
    pub grid: bool,
    /// Also render the draft / balanced / final presets as points.
    pub presets: bool,
    /// Renders per setting; the time is their median.
    pub repeats: usize,
}

impl Default for SweepSettings {
    fn default() -> Self {
        Self {
            base: Quality::default(),
            knobs: default_knobs(),
            grid: false,
            presets: true,
            repeats: 3,
        }
    }
}

/// A setting to render: a label, the knob changes from the base, the resulting quality.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Setting {
    /// e.g. `lod_pixel_threshold=2` or `preset draft`.
    pub label: String,
    /// `(knob, value)` changes applied to the base (empty for presets and the base itself).
    pub changes: Vec<(String, String)>,
    /// The preset this setting is, if any.
    pub preset: Option<QualityPreset>,
    /// The full quality.
    pub quality: Quality,
}

/// The settings a sweep renders, duplicates (same quality) merged into one with both labels.
///
/// # Errors
/// [`SweepError::Knob`] for a refused value, [`SweepError::TooManyPoints`].
pub fn settings_of(s: &SweepSettings) -> Result<Vec<Setting>, SweepError> {
    let mut out: Vec<Setting> = Vec::new();
    let mut push = |mut st: Setting| {
        if let Some(same) = out.iter_mut().find(|o| o.quality == st.quality) {
            same.label = format!("{} / {}", same.label, st.label);
            same.preset = same.preset.or(st.preset);
            if same.changes.is_empty() {
                same.changes = std::mem::take(&mut st.changes);
            }
        } else {
            out.push(st);
        }
    };
    let apply = |changes: &[(String, String)]| -> Result<Quality, SweepError> {
        let mut q = s.base.clone();
        for (name, value) in changes {
            q.set(name, value).map_err(|source| SweepError::Knob {
                name: name.clone(),
                value: value.clone(),
                source,
            })?;
        }
        Ok(q)
    };
    let label = |changes: &[(String, String)]| {
        if changes.is_empty() {
            "base".to_owned()
        } else {
            changes
                .iter()
                .map(|(n, v)| format!("{n}={v}"))
                .collect::<Vec<_>>()
                .join(" ")
        }
    };
    let count: usize = if s.grid {
        s.knobs
            .iter()
            .map(|k| k.values.len().max(1))
            .try_fold(1usize, usize::checked_mul)
            .unwrap_or(usize::MAX)
    } else {
        s.knobs.iter().map(|k| k.values.len()).sum::<usize>() + 1
    };
    if count > MAX_SWEEP_POINTS {
        return Err(SweepError::TooManyPoints(count));
    }
    if s.presets {
        for (p, name) in [
            (QualityPreset::Draft, "draft"),
            (QualityPreset::Balanced, "balanced"),
            (QualityPreset::Final, "final"),
        ] {
            push(Setting {
                label: format!("preset {name}"),
                changes: Vec::new(),
                preset: Some(p),
                quality: Quality::preset(p),
            });
        }
    }
    push(Setting {
        label: "base".to_owned(),
        changes: Vec::new(),
        preset: None,
        quality: s.base.clone(),
    });
    if s.grid {
        let mut combos: Vec<Vec<(String, String)>> = vec![Vec::new()];
        for k in &s.knobs {
            combos = combos
                .into_iter()
                .flat_map(|c| {
                    k.values.iter().map(move |v| {
                        let mut c = c.clone();
                        c.push((k.name.clone(), v.clone()));
                        c
                    })
                })
                .collect();
        }
        for c in combos {
            let quality = apply(&c)?;
            push(Setting {
                label: label(&c),
                changes: c,
                preset: None,
                quality,
            });
        }
    } else {
        for k in &s.knobs {
            for v in &k.values {
                let c = vec![(k.name.clone(), v.clone())];
                let quality = apply(&c)?;
                push(Setting {
                    label: label(&c),
                    changes: c,
                    preset: None,
                    quality,
                });
            }
        }
    }
    Ok(out)
}

/// Deterministic work of a frame, a cost that does not depend on machine load, from the
/// renderer's own counters: octree nodes visited for the view and the shadow maps, triangles
/// rasterised, KRS distance evaluations (primary rays, tile cones, shadow rays, KRS ambient
/// occlusion), the pixels of exact cubes in the view and the shadow maps (a ray–box test each,
/// at most), one shading tap per covered pixel, and the shading pass's shadow-map reads (PCF
/// taps and the tile bounds that decide whole filter windows) and screen-space AO samples.
///
/// Passes every frame makes over all its pixels or texels whatever the knobs (clears, depth
/// conversion, resolve, the shadow-map tile bounds) are not counted. A renderer that does not
/// count its shading lookups ([`FrameStats::shading`] is `None`, e.g. a GPU renderer) is
/// charged the full filter: `(2r+1)²` taps per pixel and shadow-casting light for PCF radius
/// r (`shadow_lights` of them), plus `ao_samples` per pixel.
#[must_use]
pub fn work_units(stats: &FrameStats, quality: &Quality, shadow_lights: usize) -> u64 {
    let nodes: u64 = stats
        .levels
        .iter()
        .chain(&stats.shadow_levels)
        .map(|l| l.visited)
        .sum();
    let k = &stats.krs;
    let krs = k.steps + k.tile_steps + k.shadow_steps + k.ao_evals;
    let shading = match stats.shading {
        Some(s) => s.shadow_taps + s.ao_taps,
        None => {
            let pcf = u64::from(2 * quality.shadow_pcf_radius + 1);
            let shadow_taps = if quality.shadows {
                shadow_lights as u64 * pcf * pcf
            } else {
                0
            };
            stats.covered_pixels * (shadow_taps + u64::from(quality.ao_samples))
        }
    };
    let cubes = stats.cube_pixels + stats.shadow_cube_pixels;
    nodes + stats.triangles_rasterised + krs + cubes + stats.covered_pixels + shading
}

/// One measured setting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepPoint {
    /// The setting.
    pub setting: Setting,
    /// Every render's wall time in milliseconds.
    pub times_ms: Vec<f64>,
    /// Median of `times_ms`.
    pub time_ms: f64,
    /// Fastest of `times_ms`: with [`SweepPoint::time_max_ms`], the spread drawn as an error
    /// bar (a median of a few renders on a shared machine is only as good as this band).
    #[serde(default)]
    pub time_min_ms: f64,
    /// Slowest of `times_ms`.
    #[serde(default)]
    pub time_max_ms: f64,
    /// [`work_units`] of the frame.
    pub work: u64,
    /// Error against the reference.
    pub error: FrameError,
    /// Counters of the (first) render.
    pub stats: FrameStats,
    /// On the (median time, RMSE) Pareto front.
    pub on_time_front: bool,
    /// On the (work, RMSE) Pareto front.
    pub on_work_front: bool,
}

/// What one knob of a one-at-a-time sweep did at the sweep's image size.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct KnobEffect {
    /// Knob name.
    pub name: String,
    /// The values tried (the base's own value is measured too, as the base point).
    pub values: Vec<String>,
    /// How many different images (told apart by error and work) the knob's settings and the
    /// base drew: 1 means the knob has no effect at this size.
    pub distinct_images: usize,
    /// Left out of the points and the plot because it had no effect.
    pub dropped: bool,
    /// Values that drew the same image as another setting of the knob, as `(value, same as)`
    /// (`same as` is an earlier value, or `base`): the range over which the knob changes the
    /// image is the other values. They stay in the points (a value asked for is measured).
    #[serde(default)]
    pub same_image: Vec<(String, String)>,
    /// Two of the knob's settings have render-time spreads (min-max) that do not overlap:
    /// the knob moves the time beyond the noise of repeated renders.
    #[serde(default)]
    pub time_beyond_noise: bool,
}

impl KnobEffect {
    /// A one-line account for the CLI and the editor: kept with how many images, or dropped.
    #[must_use]
    pub fn summary(&self) -> String {
        if self.dropped {
            format!(
                "{}: no effect at this size ({} gave the same image): dropped",
                self.name,
                self.values.join(", ")
            )
        } else {
            let same: Vec<String> = self
                .same_image
                .iter()
                .map(|(v, as_)| format!("{v} = {as_}"))
                .collect();
            format!(
                "{}: {} different images from {} value(s) ({}){}; time {} the render spread: kept",
                self.name,
                self.distinct_images,
                self.values.len(),
                self.values.join(", "),
                if same.is_empty() {
                    String::new()
                } else {
                    format!("; same image: {}", same.join(", "))
                },
                if self.time_beyond_noise {
                    "moves beyond"
                } else {
                    "stays within"
                }
            )
        }
    }
}

/// Indices of the points that are `knob`'s settings: the base (which holds the knob at its
/// base value) and the base with the knob set to each value. Points are matched by quality,
/// so merged duplicates (a value equal to the base's) are found whatever their label.
fn knob_members(base: &Quality, knob: &KnobValues, points: &[SweepPoint]) -> Vec<usize> {
    let qualities: Vec<Quality> = std::iter::once(base.clone())
        .chain(knob.values.iter().filter_map(|v| {
            let mut q = base.clone();
            q.set(&knob.name, v).ok().map(|()| q)
        }))
        .collect();
    points
        .iter()
        .enumerate()
        .filter(|(_, p)| qualities.contains(&p.setting.quality))
        .map(|(i, _)| i)
        .collect()
}

/// Screens the knobs of a one-at-a-time sweep: a knob whose settings all drew the same image
/// (identical error against the reference and identical work) cannot be traded at this size,
/// so its points are removed (the base and the presets stay). Returns each knob's effect.
fn screen_knobs(settings: &SweepSettings, points: &mut Vec<SweepPoint>) -> Vec<KnobEffect> {
    let base = &settings.base;
    let mut drop = vec![false; points.len()];
    let effects = settings
        .knobs
        .iter()
        .map(|k| {
            let members = knob_members(base, k, points);
            let mut images: Vec<(u64, FrameError)> = Vec::new();
            for &i in &members {
                let key = (points[i].work, points[i].error);
                if !images.contains(&key) {
                    images.push(key);
                }
            }
            // Each value's image against the base's and the earlier values' (in the order
            // given): the first to draw an image owns it.
            let value_point = |v: &str| {
                let mut q = base.clone();
                q.set(&k.name, v).ok()?;
                points.iter().position(|p| p.setting.quality == q)
            };
            let base_point = points.iter().position(|p| p.setting.quality == *base);
            let mut owners: Vec<(String, (u64, FrameError))> = base_point
                .map(|i| ("base".to_owned(), (points[i].work, points[i].error)))
                .into_iter()
                .collect();
            let mut same_image = Vec::new();
            for v in &k.values {
                let Some(i) = value_point(v) else { continue };
                let key = (points[i].work, points[i].error);
                let is_base = Some(i) == base_point;
                match owners.iter().find(|(_, o)| *o == key) {
                    Some((owner, _)) if !is_base => same_image.push((v.clone(), owner.clone())),
                    Some(_) => {}
                    None => owners.push((v.clone(), key)),
                }
            }
            let time_beyond_noise = members.iter().any(|&a| {
                members
                    .iter()
                    .any(|&b| points[a].time_min_ms > points[b].time_max_ms)
            });
            let dropped = images.len() <= 1;
            if dropped {
                for &i in &members {
                    let p = &points[i].setting;
                    if p.preset.is_none() && p.quality != *base {
                        drop[i] = true;
                    }
                }
            }
            KnobEffect {
                name: k.name.clone(),
                values: k.values.clone(),
                distinct_images: images.len(),
                dropped,
                same_image,
                time_beyond_noise,
            }
        })
        .collect();
    let mut i = 0;
    points.retain(|_| {
        i += 1;
        !drop[i - 1]
    });
    effects
}

/// A whole sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepReport {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Renders per setting.
    pub repeats: usize,
    /// The reference setting ([`reference_quality`] unless the caller chose another).
    pub reference_quality: Quality,
    /// Median reference render time in milliseconds.
    pub reference_time_ms: f64,
    /// Work of the reference frame.
    pub reference_work: u64,
    /// The measured settings, in render order, without those of knobs that had no effect.
    pub points: Vec<SweepPoint>,
    /// What each knob did to the image at this size (empty for a grid sweep, which is not
    /// screened): a knob whose settings all drew the same image is dropped from `points`.
    #[serde(default)]
    pub knobs: Vec<KnobEffect>,
    /// Margins used for the fronts.
    pub time_dominance: Dominance,
    /// Margins used for the work front.
    pub work_dominance: Dominance,
}

impl SweepReport {
    /// Names of the knobs left out as having no effect at this size.
    #[must_use]
    pub fn dropped_knobs(&self) -> Vec<&str> {
        self.knobs
            .iter()
            .filter(|k| k.dropped)
            .map(|k| k.name.as_str())
            .collect()
    }

    /// The point of a preset, if the sweep rendered presets.
    #[must_use]
    pub fn preset_point(&self, p: QualityPreset) -> Option<&SweepPoint> {
        self.points.iter().find(|pt| pt.setting.preset == Some(p))
    }

    /// A point that dominates point `index` on (work, RMSE) with [`SweepReport::work_dominance`]
    /// (the cheapest such), or `None` when it is on the work front: why a preset is off it.
    #[must_use]
    pub fn work_dominator(&self, index: usize) -> Option<&SweepPoint> {
        let key = |p: &SweepPoint| (p.work as f64, p.error.rmse);
        let target = key(self.points.get(index)?);
        self.points
            .iter()
            .enumerate()
            .filter(|&(j, p)| j != index && self.work_dominance.dominates(key(p), target))
            .map(|(_, p)| p)
            .min_by_key(|p| p.work)
    }

    /// Marks the two fronts.
    fn mark_fronts(&mut self) {
        let by_time: Vec<(f64, f64)> = self
            .points
            .iter()
            .map(|p| (p.time_ms, p.error.rmse))
            .collect();
        let by_work: Vec<(f64, f64)> = self
            .points
            .iter()
            .map(|p| (p.work as f64, p.error.rmse))
            .collect();
        let tf = pareto_front(&by_time, &self.time_dominance);
        let wf = pareto_front(&by_work, &self.work_dominance);
        for (i, p) in self.points.iter_mut().enumerate() {
            p.on_time_front = tf.contains(&i);
            p.on_work_front = wf.contains(&i);
        }
    }

    /// CSV: one row per point (label, knob changes, time, work, every error metric, fronts).
    #[must_use]
    pub fn to_csv(&self) -> String {
        let mut s = String::from(
            "label,changes,preset,time_ms,work,rmse,psnr_db,coverage_mismatch,holes,bloat,\
             depth_mean_rel,depth_max_rel,splats,nodes_visited,on_time_front,on_work_front,\
             time_min_ms,time_max_ms\n",
        );
        for p in &self.points {
            let e = &p.error;
            let changes: Vec<String> = p
                .setting
                .changes
                .iter()
                .map(|(n, v)| format!("{n}={v}"))
                .collect();
            s.push_str(&format!(
                "{},{},{},{:.3},{},{:.6},{:.3},{},{},{},{:.6},{:.6},{},{},{},{},{:.3},{:.3}\n",
                csv_field(&p.setting.label),
                csv_field(&changes.join(" ")),
                p.setting
                    .preset
                    .map_or(String::new(), |p| format!("{p:?}").to_lowercase()),
                p.time_ms,
                p.work,
                e.rmse,
                e.psnr_db,
                e.coverage_mismatch,
                e.holes,
                e.bloat,
                e.depth_mean_rel,
                e.depth_max_rel,
                p.stats.splats(),
                p.stats.nodes_visited(),
                p.on_time_front,
                p.on_work_front,
                p.time_min_ms,
                p.time_max_ms,
            ));
        }
        s
    }
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

/// Dominance margins for time: medians of a few renders on a shared machine move by ~10 %.
pub const TIME_DOMINANCE: Dominance = Dominance {
    cost_rel_margin: 0.10,
    error_abs_margin: 1e-4,
};

/// Dominance margins for work: the count is exact; 1 % keeps a setting that differs by a few
/// nodes from counting as better. RMSE below 1e-4 (0.026 of an 8-bit level) is rounding.
pub const WORK_DOMINANCE: Dominance = Dominance {
    cost_rel_margin: 0.01,
    error_abs_margin: 1e-4,
};

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

type Rendered = (RgbaImage, FrameBuffers, FrameStats);

/// Renders `q` `repeats` times; returns the first frame and every time.
fn timed<F>(
    render: &mut F,
    q: &Quality,
    repeats: usize,
) -> Result<(Rendered, Vec<f64>), Option<RenderError>>
where
    F: FnMut(&Quality) -> Result<Rendered, Option<RenderError>>,
{
    let mut first = None;
    let mut times = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let t = Instant::now();
        let frame = render(q)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
        first.get_or_insert(frame);
    }
    // `repeats >= 1` is checked by the caller, so a frame exists.
    first.map(|f| (f, times)).ok_or(Some(RenderError::ZeroSize {
        width: 0,
        height: 0,
    }))
}

/// Runs a sweep with any renderer: `render` draws one frame for a quality (the CPU reference
/// or a GPU renderer), `camera` is the view it draws (for depth), `shadow_lights` the number of
/// shadow-casting lights (for [`work_units`]). `progress` is told each finished setting.
///
/// # Errors
/// [`SweepError`] for bad settings or a failing render.
pub fn sweep<F>(
    settings: &SweepSettings,
    reference: &Quality,
    camera: &Camera,
    shadow_lights: usize,
    render: F,
    progress: impl FnMut(usize, usize, &str),
) -> Result<SweepReport, SweepError>
where
    F: FnMut(&Quality) -> Result<Rendered, RenderError>,
{
    sweep_with_cancel(
        settings,
        reference,
        camera,
        shadow_lights,
        render,
        progress,
        &AtomicBool::new(false),
    )
}

/// [`sweep`] that checks `cancel` before every render and stops with
/// [`SweepError::Cancelled`] once it is set (a background sweep in the editor).
///
/// # Errors
/// [`SweepError`] for bad settings, a failing render or a cancel.
pub fn sweep_with_cancel<F>(
    settings: &SweepSettings,
    reference: &Quality,
    camera: &Camera,
    shadow_lights: usize,
    mut render: F,
    mut progress: impl FnMut(usize, usize, &str),
    cancel: &AtomicBool,
) -> Result<SweepReport, SweepError>
where
    F: FnMut(&Quality) -> Result<Rendered, RenderError>,
{
    let mut render = |q: &Quality| {
        if cancel.load(Ordering::Relaxed) {
            Err(None)
        } else {
            render(q).map_err(Some)
        }
    };
    if settings.repeats == 0 {
        return Err(SweepError::NoRepeats);
    }
    for k in &settings.knobs {
        k.check()?;
    }
    let list = settings_of(settings)?;
    fn failed(label: &str) -> impl FnOnce(Option<RenderError>) -> SweepError + '_ {
        move |e| match e {
            Some(source) => SweepError::Render {
                label: label.to_owned(),
                source,
            },
            None => SweepError::Cancelled,
        }
    }
    let ((ref_img, ref_fb, ref_stats), mut ref_times) =
        timed(&mut render, reference, settings.repeats).map_err(failed("reference"))?;
    // `Vec::capacity` may exceed the length asked for: the total is the list's length.
    let total = list.len();
    progress(0, total, "reference");
    let mut points = Vec::with_capacity(total);
    for (i, setting) in list.into_iter().enumerate() {
        let ((img, fb, stats), mut times) = timed(&mut render, &setting.quality, settings.repeats)
            .map_err(failed(&setting.label))?;
        let error = compare_frames(
            Frame {
                image: &ref_img,
                buffers: &ref_fb,
            },
            Frame {
                image: &img,
                buffers: &fb,
            },
            camera,
        )
        .map_err(|source| SweepError::Measure {
            label: setting.label.clone(),
            source,
        })?;
        progress(i + 1, total, &setting.label);
        let time_ms = median(&mut times);
        points.push(SweepPoint {
            work: work_units(&stats, &setting.quality, shadow_lights),
            time_ms,
            time_min_ms: times.iter().copied().fold(f64::INFINITY, f64::min),
            time_max_ms: times.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            times_ms: times,
            error,
            stats,
            setting,
            on_time_front: false,
            on_work_front: false,
        });
    }
    // A grid crosses every knob with every other: a knob's own settings are not a line to
    // screen, so a grid is reported whole.
    let knobs = if settings.grid {
        Vec::new()
    } else {
        screen_knobs(settings, &mut points)
    };
    let mut report = SweepReport {
        width: ref_img.width,
        height: ref_img.height,
        repeats: settings.repeats,
        reference_quality: reference.clone(),
        reference_time_ms: median(&mut ref_times),
        reference_work: work_units(&ref_stats, reference, shadow_lights),
        points,
        knobs,
        time_dominance: TIME_DOMINANCE,
        work_dominance: WORK_DOMINANCE,
    };
    report.mark_fronts();
    Ok(report)
}

/// Bytes a CPU sweep keeps per pixel besides the frame it is drawing: the reference's image
/// and G-buffer (kept for every comparison) and the current setting's first frame (kept while
/// its repeats run).
const SWEEP_KEPT_BYTES_PER_PIXEL: u64 = 2
    * (std::mem::size_of::<[u8; 4]>()
        + std::mem::size_of::<f32>()
        + std::mem::size_of::<crate::render::PixelId>()
        + 2 * std::mem::size_of::<glam::Vec3>()) as u64;

/// Estimated peak heap bytes of [`sweep_document`] at `width`×`height`: the largest frame it
/// draws (the reference's or any setting's, each from [`crate::render::estimate_peak_bytes`])
/// plus the frames it keeps between renders. The document itself is not counted. Callers check
/// it against a [`crate::budget::MemoryBudget`] before starting a sweep.
///
/// # Errors
/// [`SweepError`] for settings that [`sweep_document`] would refuse.
pub fn estimate_sweep_peak_bytes(
    doc: &Document,
    width: u32,
    height: u32,
    settings: &SweepSettings,
) -> Result<u64, SweepError> {
    for k in &settings.knobs {
        k.check()?;
    }
    let frame = |q: &Quality| {
        let mut req = View::new(width, height);
        req.quality = q.clone();
        crate::render::estimate_peak_bytes(doc, &req)
    };
    let largest = settings_of(settings)?
        .iter()
        .map(|s| frame(&s.quality))
        .chain([frame(&reference_quality())])
        .max()
        .unwrap_or(0);
    let kept = (u64::from(width) * u64::from(height)).saturating_mul(SWEEP_KEPT_BYTES_PER_PIXEL);
    Ok(largest.saturating_add(kept))
}

/// [`sweep`] with the CPU reference renderer on a document, from its camera, against
/// [`reference_quality`].
///
/// # Errors
/// [`SweepError`].
pub fn sweep_document(
    doc: &Document,
    width: u32,
    height: u32,
    settings: &SweepSettings,
    progress: impl FnMut(usize, usize, &str),
) -> Result<SweepReport, SweepError> {
    sweep_document_with_cancel(
        doc,
        width,
        height,
        settings,
        progress,
        &AtomicBool::new(false),
    )
}

/// [`sweep_document`] that stops with [`SweepError::Cancelled`] once `cancel` is set (checked
/// before every render).
///
/// # Errors
/// [`SweepError`].
pub fn sweep_document_with_cancel(
    doc: &Document,
    width: u32,
    height: u32,
    settings: &SweepSettings,
    progress: impl FnMut(usize, usize, &str),
    cancel: &AtomicBool,
) -> Result<SweepReport, SweepError> {
    let camera = Camera::from_orbit(&doc.camera, width, height);
    let shadow_lights = doc.lights.iter().filter(|l| l.casts_shadows).count();
    // One renderer for the whole sweep: its depth targets, queues and shadow maps are made
    // once, so a setting's time is its drawing, not page faults. Each frame's image, G-buffer
    // and counters are moved out, since the sweep keeps them.
    let mut renderer = Renderer::new();
    sweep_with_cancel(
        settings,
        &reference_quality(),
        &camera,
        shadow_lights,
        |q| {
            let mut req = View::new(width, height);
            req.quality = q.clone();
            renderer.render_document(doc, &req)?;
            Ok(renderer.take_frame())
        },
        progress,
        cancel,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::render_document;

    #[test]
    fn knob_specs_parse_and_refuse() {
        let k = KnobValues::parse("lod_pixel_threshold=0.5, 1,2").unwrap();
        assert_eq!(k.name, "lod_pixel_threshold");
        assert_eq!(k.values, ["0.5", "1", "2"]);
        for bad in ["lod_pixel_threshold", "=1", "lod_pixel_threshold=1,,2"] {
            assert!(
                matches!(KnobValues::parse(bad), Err(SweepError::BadSpec { .. })),
                "{bad}"
            );
        }
        let e = KnobValues::parse("lod_pixel_threshold=1,NaN").unwrap_err();
        assert!(e.to_string().contains("lod_pixel_threshold=NaN"), "{e}");
        assert!(matches!(
            KnobValues::parse("no_such_knob=1"),
            Err(SweepError::Knob { .. })
        ));
        // Every knob the quality settings know is sweepable by name.
        for name in Quality::KNOBS {
            let v = match name {
                "shadow_map_size" => "64",
                "stretch_strategy" => "corners",
                _ => "1",
            };
            KnobValues::parse(&format!("{name}={v}")).unwrap();
        }
        for k in default_knobs() {
            k.check().unwrap();
        }
    }

    #[test]
    fn reference_is_valid_and_finer_than_final() {
        let r = reference_quality();
        r.validate().unwrap();
        let f = Quality::preset(QualityPreset::Final);
        assert!(r.lod_pixel_threshold < f.lod_pixel_threshold);
        assert!(r.shadow_map_size > f.shadow_map_size);
        assert!(r.krs_epsilon_scale < f.krs_epsilon_scale);
        assert!(r.krs_max_steps > f.krs_max_steps);
        assert!(r.supersample > f.supersample);
    }

    #[test]
    fn settings_one_at_a_time_grid_and_merging() {
        let base = Quality::default();
        let s = SweepSettings {
            base: base.clone(),
            knobs: vec![
                KnobValues::parse("lod_pixel_threshold=1,2").unwrap(),
                KnobValues::parse("shadows=on,off").unwrap(),
            ],
            grid: false,
            presets: false,
            repeats: 1,
        };
        let one = settings_of(&s).unwrap();
        // base (= lod 1 = shadows on, merged), lod 2, shadows off.
        assert_eq!(one.len(), 3, "{one:#?}");
        assert!(one[0].label.contains("base") && one[0].label.contains("shadows=on"));
        let grid = settings_of(&SweepSettings {
            grid: true,
            ..s.clone()
        })
        .unwrap();
        assert_eq!(grid.len(), 4);
        assert!(
            grid.iter()
                .any(|g| !g.quality.shadows && g.quality.lod_pixel_threshold == 2.0)
        );
        let with_presets = settings_of(&SweepSettings {
            presets: true,
            ..s.clone()
        })
        .unwrap();
        // Balanced is the base: merged, so 3 presets + lod 2 + shadows off.
        assert_eq!(with_presets.len(), 5);
        let too_many = SweepSettings {
            grid: true,
            knobs: (0..13)
                .map(|_| KnobValues::parse("lod_pixel_threshold=1,2").unwrap())
                .collect(),
            ..s
        };
        assert!(matches!(
            settings_of(&too_many),
            Err(SweepError::TooManyPoints(8192))
        ));
    }

    #[test]
    fn work_counts_what_the_shading_knobs_cost() {
        let doc = crate::render::scenes::mixed_document(5).unwrap();
        let frame = |ao: u32, pcf: u32| {
            let mut req = View::new(48, 48);
            req.quality.ao_samples = ao;
            req.quality.shadow_pcf_radius = pcf;
            let (_, _, stats) = render_document(&doc, &req).unwrap();
            let q = req.quality;
            (work_units(&stats, &q, 1), stats)
        };
        let (w0, s0) = frame(0, 1);
        let (w8, s8) = frame(8, 1);
        // Every covered pixel with a normal takes 8 AO samples, and the work says so.
        let ao = s8.shading.unwrap().ao_taps;
        assert!(ao > 0 && ao <= 8 * s8.covered_pixels, "{ao}");
        assert_eq!(w8 - w0, ao);
        assert_eq!(s0.shading.unwrap().ao_taps, 0);
        // A wider filter reads more shadow-map texels; never more than the full filter.
        let (w2, s2) = frame(0, 2);
        let (t1, t2) = (
            s0.shading.unwrap().shadow_taps,
            s2.shading.unwrap().shadow_taps,
        );
        assert!(t2 > t1 && w2 > w0, "{t1} {t2}");
        assert!(t2 <= s2.covered_pixels * (25 + 4), "{t2}");
        // A renderer that does not count is charged the full filter.
        let uncounted = FrameStats {
            shading: None,
            ..s2.clone()
        };
        let q = Quality {
            shadow_pcf_radius: 2,
            ao_samples: 0,
            ..Quality::default()
        };
        assert_eq!(
            work_units(&uncounted, &q, 1) - work_units(&s2, &q, 1) + t2,
            25 * s2.covered_pixels
        );
    }

    #[test]
    fn a_set_cancel_flag_stops_the_sweep_before_the_next_render() {
        let doc = crate::render::scenes::sphere_document(4, 0.4).unwrap();
        let settings = SweepSettings {
            knobs: vec![KnobValues::parse("lod_pixel_threshold=1,2,4,8").unwrap()],
            presets: false,
            repeats: 1,
            ..SweepSettings::default()
        };
        let cancel = AtomicBool::new(true);
        let r = sweep_document_with_cancel(&doc, 16, 16, &settings, |_, _, _| {}, &cancel);
        assert!(matches!(r, Err(SweepError::Cancelled)), "{r:?}");
        // Cancelled after the second setting: no further render is started.
        let cancel = AtomicBool::new(false);
        let mut seen = Vec::new();
        let r = sweep_document_with_cancel(
            &doc,
            16,
            16,
            &settings,
            |done, total, _| {
                seen.push((done, total));
                if done == 2 {
                    cancel.store(true, Ordering::Relaxed);
                }
            },
            &cancel,
        );
        assert!(matches!(r, Err(SweepError::Cancelled)), "{r:?}");
        // base (= lod 1, merged), lod 2, 4, 8.
        assert_eq!(seen, [(0, 4), (1, 4), (2, 4)]);
    }

    #[test]
    fn the_sweep_estimate_holds_the_measured_peak_without_overstating_it() {
        let house_path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/house.thicket.json");
        let house = crate::io::project::load(&house_path).expect("the house sample");
        let sphere = crate::render::scenes::sphere_document(6, 0.4).unwrap();
        let shadows = SweepSettings {
            knobs: vec![KnobValues::parse("shadow_map_size=256,2048").unwrap()],
            presets: false,
            repeats: 1,
            ..SweepSettings::default()
        };
        let presets = SweepSettings {
            knobs: vec![KnobValues::parse("lod_pixel_threshold=1,4").unwrap()],
            repeats: 2,
            ..SweepSettings::default()
        };
        for (name, doc, (w, h), settings) in [
            ("house 160x120 shadow sizes", &house, (160, 120), &shadows),
            ("house 96x96 presets", &house, (96, 96), &presets),
            ("sphere 128x128 presets", &sphere, (128, 128), &presets),
        ] {
            let estimate = estimate_sweep_peak_bytes(doc, w, h, settings).unwrap();
            let (report, peak) = crate::io::fuzz::peak_heap_bytes_on_one_thread(|| {
                sweep_document(doc, w, h, settings, |_, _, _| {})
            });
            let report = report.unwrap();
            eprintln!(
                "{name}: {} settings, peak {peak} B, estimate {estimate} B ({:.2}x)",
                report.points.len(),
                estimate as f64 / peak as f64
            );
            assert!(
                peak > u64::from(w * h) * 32,
                "{name}: a sweep holds more than two frames' images ({peak})"
            );
            assert!(
                estimate >= peak,
                "{name}: estimate {estimate} below the measured peak {peak}"
            );
            assert!(
                estimate <= 3 * peak,
                "{name}: estimate {estimate} over 3x the measured peak {peak}"
            );
        }
        // A knob the sweep would refuse is refused by the estimate too.
        let bad = SweepSettings {
            knobs: vec![KnobValues {
                name: "no_such_knob".to_owned(),
                values: vec!["1".to_owned()],
            }],
            ..SweepSettings::default()
        };
        assert!(estimate_sweep_peak_bytes(&sphere, 64, 64, &bad).is_err());
    }

    #[test]
    fn sweep_on_a_small_scene_measures_error_against_the_reference() {
        let doc = crate::render::scenes::sphere_document(5, 0.4).unwrap();
        let settings = SweepSettings {
            knobs: vec![KnobValues::parse("lod_pixel_threshold=0.25,4,16").unwrap()],
            presets: false,
            repeats: 2,
            ..SweepSettings::default()
        };
        let mut calls = 0;
        let r = sweep_document(&doc, 48, 48, &settings, |_, _, _| calls += 1).unwrap();
        assert_eq!(calls, r.points.len() + 1);
        assert!(r.points.iter().all(|p| p.times_ms.len() == 2));
        let find = |l: &str| {
            r.points
                .iter()
                .find(|p| p.setting.label.contains(l))
                .unwrap()
        };
        // Coarser LOD: fewer nodes visited, more error and coverage mismatch (bigger splats
        // bloat the silhouette, which also means more shaded pixels: work is not monotonic).
        let (fine, coarse) = (find("=0.25"), find("=16"));
        let (nf, nc) = (fine.stats.nodes_visited(), coarse.stats.nodes_visited());
        assert!(nc < nf, "{nc} vs {nf}");
        assert!(coarse.error.rmse > fine.error.rmse);
        assert!(coarse.error.bloat > 0 && coarse.error.coverage_mismatch >= coarse.error.bloat);
        // The cheapest point cannot be dominated on work.
        let cheapest = r.points.iter().min_by_key(|p| p.work).unwrap();
        assert!(cheapest.on_work_front);
        let csv = r.to_csv();
        assert_eq!(csv.lines().count(), r.points.len() + 1);
        let json = serde_json::to_string(&r).unwrap();
        assert!(json.contains("reference_quality"));
    }

    #[test]
    fn a_knob_that_cannot_change_the_image_is_dropped_and_one_that_does_is_kept() {
        // No light casts shadows: the shadow map's size cannot change a pixel, the LOD can.
        let mut doc = crate::render::scenes::sphere_document(5, 0.4).unwrap();
        for l in &mut doc.lights {
            l.casts_shadows = false;
        }
        let settings = SweepSettings {
            knobs: vec![
                KnobValues::parse("shadow_map_size=256,1024,4096").unwrap(),
                KnobValues::parse("lod_pixel_threshold=0.5,4,16").unwrap(),
            ],
            repeats: 3,
            ..SweepSettings::default()
        };
        let r = sweep_document(&doc, 40, 40, &settings, |_, _, _| {}).unwrap();
        let effect = |name: &str| r.knobs.iter().find(|k| k.name == name).unwrap();
        let shadow = effect("shadow_map_size");
        assert!(shadow.dropped, "{shadow:?}");
        assert_eq!(shadow.distinct_images, 1);
        assert!(
            shadow.summary().contains("no effect"),
            "{}",
            shadow.summary()
        );
        let lod = effect("lod_pixel_threshold");
        assert!(!lod.dropped && lod.distinct_images >= 2, "{lod:?}");
        // The whole knob is one image, so each value names the base as its twin.
        assert_eq!(shadow.same_image.len(), 3, "{shadow:?}");
        assert!(shadow.same_image.iter().all(|(_, as_)| as_ == "base"));
        assert!(lod.summary().ends_with("kept"), "{}", lod.summary());
        let labels: Vec<&str> = r.points.iter().map(|p| p.setting.label.as_str()).collect();
        // The dropped knob's points are gone; the base, the presets and the LOD stay.
        assert!(
            !labels
                .iter()
                .any(|l| l.contains("shadow_map_size=256") || l.contains("shadow_map_size=4096")),
            "{labels:?}"
        );
        for kept in [
            "base",
            "preset draft",
            "preset final",
            "lod_pixel_threshold=16",
        ] {
            assert!(
                labels.iter().any(|l| l.contains(kept)),
                "{kept}: {labels:?}"
            );
        }
        // Every point carries its spread around the median.
        for p in &r.points {
            assert_eq!(p.times_ms.len(), 3);
            assert!(
                p.time_min_ms <= p.time_ms && p.time_ms <= p.time_max_ms,
                "{}: {} {} {}",
                p.setting.label,
                p.time_min_ms,
                p.time_ms,
                p.time_max_ms
            );
            assert!(p.times_ms.contains(&p.time_min_ms) && p.times_ms.contains(&p.time_max_ms));
        }
        let csv = r.to_csv();
        assert!(
            csv.lines()
                .next()
                .unwrap()
                .ends_with(",time_min_ms,time_max_ms")
        );
        // A grid is not screened: every setting stays.
        let grid = sweep_document(
            &doc,
            24,
            24,
            &SweepSettings {
                grid: true,
                presets: false,
                repeats: 1,
                ..settings
            },
            |_, _, _| {},
        )
        .unwrap();
        assert!(grid.knobs.is_empty());
        assert_eq!(grid.points.len(), 9 + 1, "the 3x3 grid and the base");
    }

    #[test]
    fn the_house_presets_trade_work_for_error_in_order() {
        // Work is the deterministic cost (time is not asserted): at a modest size the presets
        // are ordered draft < balanced < final in work and the reverse in error.
        let house_path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/house.thicket.json");
        let house = crate::io::project::load(&house_path).expect("the house sample");
        let settings = SweepSettings {
            knobs: Vec::new(),
            repeats: 1,
            ..SweepSettings::default()
        };
        let r = sweep_document(&house, 160, 160, &settings, |_, _, _| {}).unwrap();
        let p = |q| r.preset_point(q).unwrap();
        let (d, b, f) = (
            p(QualityPreset::Draft),
            p(QualityPreset::Balanced),
            p(QualityPreset::Final),
        );
        eprintln!(
            "work {} {} {}, rmse {} {} {}",
            d.work, b.work, f.work, d.error.rmse, b.error.rmse, f.error.rmse
        );
        assert!(d.work < b.work && b.work < f.work);
        assert!(d.error.rmse > b.error.rmse && b.error.rmse > f.error.rmse);
        // With the presets alone, each is on the work front: none is dominated.
        for i in 0..r.points.len() {
            assert!(r.points[i].on_work_front && r.work_dominator(i).is_none());
        }
    }
}

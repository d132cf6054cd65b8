//! Per-ray sphere tracing (§4), over-relaxation (Keinert et al. 2014), tile start distances
//! (§4.1), shadow rays and ambient occlusion (§6.5).
//!
//! The frame renderer owns pixels and tiles; this module answers one ray (or one tile cone) at
//! a time.

use glam::{DVec3, Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::kernel::Material;
use super::object::PreparedScene;

/// Sphere-tracing knobs (all in world units). Part of the renderer's quality settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TraceSettings {
    /// Multiplier on the pixel-cone epsilon: 1 stops when the unbounding sphere projects to one
    /// pixel; larger is faster and blurrier (coarser continuous LOD).
    pub eps_scale: f32,
    /// Pixel footprint per unit distance (≈ pixel angle in radians, `2·tan(fov/2)/height`).
    pub pixel_cone_ratio: f32,
    /// Absolute floor of epsilon, so rays starting on a surface still terminate.
    pub min_epsilon: f32,
    /// Distance evaluations per ray before giving up.
    pub max_steps: u32,
    /// Largest ray parameter considered (from the ray origin).
    pub max_distance: f32,
    /// Over-relaxation factor ω (1 = plain sphere tracing; 1.2–1.6 typical).
    pub over_relaxation: f32,
    /// Ray parameter to start from (e.g. from [`tile_start_distance`]).
    pub start_distance: f32,
}

impl Default for TraceSettings {
    fn default() -> Self {
        Self {
            eps_scale: 1.0,
            pixel_cone_ratio: 1.0 / 800.0,
            min_epsilon: 1e-6,
            max_steps: 256,
            max_distance: 1e4,
            over_relaxation: 1.0,
            start_distance: 0.0,
        }
    }
}

impl TraceSettings {
    /// The termination threshold at ray parameter `t`: ε = eps_scale · pixel_cone_ratio · t
    /// (so the last unbounding sphere projects to about a pixel), at least `min_epsilon`.
    #[inline]
    pub fn epsilon(&self, t: f64) -> f32 {
        ((self.eps_scale * self.pixel_cone_ratio) as f64 * t).max(self.min_epsilon as f64) as f32
    }
}

/// Result of tracing one ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceHit {
    /// Whether the ray came within epsilon of the surface.
    pub hit: bool,
    /// Ray parameter of the hit (world units when the direction is unit); `max_distance` on a
    /// miss.
    pub t: f32,
    /// World-space hit position.
    pub position: Vec3,
    /// World-space unit normal (analytic, §6.1).
    pub normal: Vec3,
    /// Index of the object hit.
    pub object: usize,
    /// Index of the kernel hit within that object.
    pub kernel: Option<usize>,
    /// The kernel's material.
    pub material: Material,
    /// The hit point in the hit kernel's own space (after the reflections taken).
    pub kernel_point: Vec3,
    /// Kernel-parametrised coordinates (§6.2) of the hit.
    pub kernel_uv: Vec2,
    /// Distance evaluations spent (including rejected over-relaxed steps).
    pub steps: u32,
    /// Epsilon at the hit (use it to offset secondary rays).
    pub epsilon: f32,
    /// The ray ran out of steps before hitting or leaving the scene.
    pub exhausted: bool,
    /// Over-relaxed steps that overshot and were taken back.
    pub relaxation_fallbacks: u32,
}

impl TraceHit {
    fn miss(origin: Vec3, dir: Vec3, t: f32, steps: u32) -> Self {
        Self {
            hit: false,
            t,
            position: origin + dir * t,
            normal: -dir,
            object: 0,
            kernel: None,
            material: Material::default(),
            kernel_point: Vec3::ZERO,
            kernel_uv: Vec2::ZERO,
            steps,
            epsilon: 0.0,
            exhausted: false,
            relaxation_fallbacks: 0,
        }
    }
}

/// The ray-parameter interval in which any geometry can lie (bounding balls of the objects,
/// computed in f64 so a ray from 1e6 units away still lands on them), clipped to
/// `[start, max]`. `None` when the ray misses every object.
///
/// Each ball is inflated by Lipschitz · epsilon so that no point outside the interval has a
/// distance estimate below epsilon: skipping it cannot change which point the tracer reports.
fn ray_interval(
    scene: &PreparedScene,
    o: DVec3,
    d: DVec3,
    start: f64,
    max: f64,
    epsilon: impl Fn(f64) -> f64,
) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for obj in scene.objects.iter().filter(|o| !o.is_empty) {
        let Some((c, r)) = obj.bound_world else {
            return Some((start, max)).filter(|(a, b)| a <= b);
        };
        let oc = o - c.as_dvec3();
        let r = r as f64;
        let far = oc.length() + r;
        let r = r * (1.0 + 1e-6) + 1e-6 + 1.01 * obj.lipschitz as f64 * epsilon(far);
        let b = oc.dot(d);
        let disc = b * b - (oc.length_squared() - r * r);
        if disc < 0.0 {
            continue;
        }
        let s = disc.sqrt();
        lo = lo.min(-b - s);
        hi = hi.max(-b + s);
    }
    let lo = lo.max(start);
    let hi = hi.min(max);
    (lo <= hi).then_some((lo, hi))
}

/// Safety factor on epsilon when certifying that a stretch of the ray holds no hit, so float
/// rounding in the distance cannot make two traces of the same ray disagree.
const CERTIFY_MARGIN: f64 = 1.001;

/// The canonical sample positions along a ray: spaced ε(t)/2 (uniform where the `min_epsilon`
/// floor rules, geometric where the pixel cone does). Hits are only reported on these
/// positions, so any tracer that skips only certified stretches reports the same hit (the GPU
/// KRS pass takes its constants from here).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleGrid {
    /// Spacing in the uniform part.
    pub q0: f64,
    /// Ray parameter where the cone epsilon overtakes the floor (∞ without a cone).
    pub t0: f64,
    /// ln(1 + cone/2): index step of the geometric part.
    pub log_step: f64,
    /// Index at t0.
    pub u0: f64,
}

impl SampleGrid {
    /// The grid of a ray traced with `settings`.
    #[must_use]
    pub fn new(settings: &TraceSettings) -> Self {
        let cone = (settings.eps_scale as f64 * settings.pixel_cone_ratio as f64).max(0.0);
        let floor = (settings.min_epsilon as f64).max(1e-12);
        let q0 = 0.5 * floor;
        if cone > 0.0 && cone.is_finite() {
            let t0 = floor / cone;
            Self {
                q0,
                t0,
                log_step: (0.5 * cone).ln_1p(),
                u0: t0 / q0,
            }
        } else {
            Self {
                q0,
                t0: f64::INFINITY,
                log_step: 1.0,
                u0: f64::INFINITY,
            }
        }
    }

    /// Continuous index of ray parameter t.
    fn index(&self, t: f64) -> f64 {
        if t < self.t0 {
            t / self.q0
        } else {
            self.u0 + (t / self.t0).ln() / self.log_step
        }
    }

    /// Ray parameter of index u.
    fn param(&self, u: f64) -> f64 {
        if u < self.u0 {
            u * self.q0
        } else {
            self.t0 * ((u - self.u0) * self.log_step).exp()
        }
    }
}

/// Sphere-traces one ray from `origin` along `dir` (normalised here) through `scene`.
///
/// The ray is sampled on a canonical grid of positions spaced ε(t)/2 (see
/// [`TraceSettings::epsilon`]); the hit is the first grid position whose distance estimate is
/// below ε. A sample with estimate d certifies, by the 1-Lipschitz bound, that no position up
/// to t + d − ε can be a hit, so the tracer jumps to the first grid position past that. With
/// over-relaxation (ω > 1, Keinert et al. 2014) it also probes at t + ω'·(d − ε), with ω' ≤ ω
/// lowered where the estimate falls fast along the ray (a probe could not pass there); a probe
/// whose certified stretch overlaps the previous one extends the jump (and probing continues
/// from it), otherwise it is discarded (a fallback) and tracing resumes on the grid. Because only
/// certified positions are skipped, plain, over-relaxed and tile-started traces report exactly
/// the same hit (mask and t). A miss is reported when the ray leaves the scene's bounds or
/// `max_distance`, or `max_steps` is spent (`exhausted`).
pub fn trace(scene: &PreparedScene, origin: Vec3, dir: Vec3, settings: &TraceSettings) -> TraceHit {
    let Some(dir) = dir.try_normalize() else {
        return TraceHit::miss(origin, Vec3::Z, 0.0, 0);
    };
    let max_distance = if settings.max_distance.is_finite() {
        settings.max_distance
    } else {
        1e30
    };
    if !origin.is_finite() {
        return TraceHit::miss(Vec3::ZERO, dir, 0.0, 0);
    }
    // Re-normalise in f64: an f32-unit vector is off by ~1e-8, which at 1e6 units turns a
    // clear miss of a bounding ball into a hit.
    let (o, d) = (origin.as_dvec3(), dir.as_dvec3().normalize_or_zero());
    let start = settings.start_distance.max(0.0) as f64;
    let eps = |t: f64| settings.epsilon(t) as f64;
    let Some((t_lo, t_hi)) = ray_interval(scene, o, d, start, max_distance as f64, eps) else {
        return TraceHit::miss(origin, dir, max_distance, 0);
    };
    let at = |t: f64| (o + d * t).as_vec3();
    let mut omega = if settings.over_relaxation.is_finite() {
        settings.over_relaxation.clamp(1.0, 1.99)
    } else {
        1.0
    } as f64;
    let grid = SampleGrid::new(settings);
    // Certified-free radius of a sample at t with estimate dist.
    let free = |t: f64, dist: f64| dist - CERTIFY_MARGIN * eps(t + dist.max(0.0));

    let mut k = grid.index(t_lo).ceil();
    let mut steps = 0u32;
    let mut fallbacks = 0u32;
    let mut exhausted = true;
    let mut hit_t = None;
    let omega_max = omega;
    // Previous grid sample's estimate, to notice when the ray moves away from geometry again.
    let mut last_grid_d = f64::INFINITY;

    // A rejected probe's certified stretch: still true, used once the march closes the gap.
    let mut pending: Option<(f64, f64)> = None;
    // The last evaluated sample in ray order and the estimate's rate of decrease along the
    // ray, for choosing the relaxation factor.
    let mut prev: Option<(f64, f64)> = None;
    let mut slope = 0.0f64;
    while steps < settings.max_steps {
        let t = grid.param(k);
        if t > t_hi {
            exhausted = false;
            break;
        }
        let dist = scene.distance(at(t)) as f64;
        steps += 1;
        if !dist.is_finite() {
            exhausted = false;
            break;
        }
        if dist < eps(t) {
            hit_t = Some(t);
            break;
        }
        if let Some((tp, dp)) = prev
            && t > tp
        {
            slope = (dp - dist) / (t - tp);
        }
        prev = Some((t, dist));
        if omega_max > 1.0 && dist > last_grid_d {
            // Past the obstacle that made a probe fail: relax again.
            omega = omega_max;
        }
        last_grid_d = dist;
        let mut reach = t + free(t, dist);
        let (mut cur_t, mut cur_d) = (t, dist);
        // Over-relaxed probes. The step is relative to the certified radius r = d − ε: for a
        // plane met at angle θ (the estimate falls by s = sin θ per unit of t), a probe at
        // t + ω·r certifies back to its own start exactly when ω ≤ 2 / (1 + s), so ω is capped
        // there with s estimated from the last two samples; a probe that gains less than a
        // grid spacing (ε/2) over the plain step is not worth its evaluation.
        while omega > 1.0 && steps < settings.max_steps {
            let r = free(cur_t, cur_d);
            let w = (2.0 / (1.0 + slope.max(0.0))).min(omega);
            if w <= 1.0 || (w - 1.0) * r < 0.5 * eps(cur_t) {
                break;
            }
            let t2 = cur_t + w * r;
            if t2 > t_hi {
                // The probe would land past the bounds; the stretch up to them is not
                // certified by anything yet, so the plain march goes on.
                break;
            }
            let d2 = scene.distance(at(t2)) as f64;
            steps += 1;
            let r2 = if d2.is_finite() { free(t2, d2) } else { -1.0 };
            if d2.is_finite() {
                slope = (cur_d - d2) / (t2 - cur_t);
            }
            if !(r2 > 0.0 && t2 - r2 <= reach) {
                // Overshoot: the ray is heading into something. As in Keinert et al., stop
                // relaxing (until the ray moves away from geometry again); keep what the probe
                // certified for when the plain march reaches it.
                fallbacks += 1;
                omega = 1.0;
                if r2 > 0.0 {
                    pending = Some((t2 - r2, t2 + r2));
                }
                break;
            }
            prev = Some((t2, d2));
            reach = t2 + r2;
            (cur_t, cur_d) = (t2, d2);
        }
        if let Some((lo, hi)) = pending
            && reach >= lo
        {
            reach = reach.max(hi);
            pending = None;
        }
        k = (k + 1.0).max(grid.index(reach.max(t)).floor() + 1.0);
    }
    let Some(t) = hit_t else {
        let t_end = grid.param(k).min(max_distance as f64);
        let mut miss = TraceHit::miss(origin, dir, t_end as f32, steps);
        miss.exhausted = exhausted;
        miss.relaxation_fallbacks = fallbacks;
        return miss;
    };
    let position = at(t);
    let (object, normal, kernel, kernel_point, material, kernel_uv) = surface_at(scene, position)
        .unwrap_or((0, -dir, None, Vec3::ZERO, Material::default(), Vec2::ZERO));
    TraceHit {
        hit: true,
        t: t as f32,
        position,
        normal,
        object,
        kernel,
        material,
        kernel_point,
        kernel_uv,
        steps,
        epsilon: settings.epsilon(t),
        exhausted: false,
        relaxation_fallbacks: fallbacks,
    }
}

type SurfaceInfo = (usize, Vec3, Option<usize>, Vec3, Material, Vec2);

fn surface_at(scene: &PreparedScene, p: Vec3) -> Option<SurfaceInfo> {
    let (i, _) = scene.nearest_object(p)?;
    let obj = &scene.objects[i];
    let (s, normal) = obj.sample_world(p);
    let uv = s
        .kernel
        .and_then(|k| obj.object.kernels.get(k))
        .map_or(Vec2::ZERO, |k| k.param_coords(s.kernel_point));
    Some((
        i,
        normal,
        s.kernel,
        s.kernel_point,
        obj.material(s.kernel),
        uv,
    ))
}

/// Axis and half-angle (radians) of the cone from the eye that contains the given ray
/// directions (e.g. a tile's four corner rays).
pub fn tile_cone(directions: &[Vec3]) -> (Vec3, f32) {
    let sum: Vec3 = directions.iter().filter_map(|d| d.try_normalize()).sum();
    let axis = sum.normalize_or(Vec3::NEG_Z);
    let min_cos = directions
        .iter()
        .filter_map(|d| d.try_normalize())
        .map(|d| d.dot(axis))
        .fold(1.0f32, f32::min)
        .clamp(-1.0, 1.0);
    // A little margin for rounding in the caller's corner directions.
    (axis, min_cos.acos() * (1.0 + 1e-4) + 1e-6)
}

/// §4.1 screen-tile acceleration: marches the cone (apex `eye`, `axis`, `half_angle` radians)
/// with unbounding spheres that cover its whole cross-section, and returns a ray parameter from
/// which every ray of the cone can start tracing safely.
///
/// Each sphere (centre at axial distance t, radius d) covers the beam over axial distances
/// [t − h, t + h] with h = √(d² − w²) and w = (t + d)·tan(half_angle) (+ epsilon, so no point
/// where the per-pixel tracer would have stopped is skipped); the next centre is t + h, so the
/// covered ranges chain without gaps. Marching stops at the first sphere that no longer covers
/// the beam. A ray at angle θ ≤ half_angle reaches axial distance z at parameter z / cos θ ≥ z,
/// so the returned axial distance is safe as a start parameter for all of them.
pub fn tile_start_distance(
    scene: &PreparedScene,
    eye: Vec3,
    axis: Vec3,
    half_angle: f32,
    settings: &TraceSettings,
) -> f32 {
    tile_start_distance_counted(scene, eye, axis, half_angle, settings).0
}

/// [`tile_start_distance`] with the number of distance evaluations it spent (to weigh the
/// tile gain against its cost).
pub fn tile_start_distance_counted(
    scene: &PreparedScene,
    eye: Vec3,
    axis: Vec3,
    half_angle: f32,
    settings: &TraceSettings,
) -> (f32, u32) {
    let Some(axis) = axis.try_normalize() else {
        return (0.0, 0);
    };
    if !(half_angle.is_finite() && (0.0..1.5).contains(&half_angle) && eye.is_finite()) {
        return (0.0, 0);
    }
    let tan = half_angle.tan() as f64;
    let (o, d) = (eye.as_dvec3(), axis.as_dvec3());
    let max_distance = settings.max_distance.min(1e30) as f64;
    let mut t = 0.0f64;
    let mut steps = 0u32;
    for _ in 0..settings.max_steps {
        let dist = scene.distance((o + d * t).as_vec3()) as f64;
        steps += 1;
        if !dist.is_finite() {
            return (max_distance as f32, steps);
        }
        let w = (t + dist) * tan;
        // Keep every covered point at least epsilon away: those are exactly the positions the
        // per-pixel tracer may skip, so starting later cannot change its hit.
        let radius = dist - CERTIFY_MARGIN * settings.epsilon(t + dist.max(0.0)) as f64;
        if radius <= w {
            break;
        }
        let h = (radius * radius - w * w).sqrt();
        t += h;
        if t >= max_distance {
            return (max_distance as f32, steps);
        }
    }
    // Round down so f64→f32 conversion never moves the start past the safe range.
    ((t * (1.0 - 1e-6)) as f32, steps)
}

/// Shadow-ray knobs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShadowSettings {
    /// Distance along the ray to skip before marching (leave the surface).
    pub start_offset: f32,
    /// Longest shadow ray.
    pub max_distance: f32,
    /// Step budget.
    pub max_steps: u32,
    /// Occluder threshold.
    pub epsilon: f32,
    /// Soft shadows with penumbra factor k (larger = harder); `None` for hard shadows.
    pub softness: Option<f32>,
}

impl Default for ShadowSettings {
    fn default() -> Self {
        Self {
            start_offset: 1e-3,
            max_distance: 100.0,
            max_steps: 128,
            epsilon: 1e-4,
            softness: None,
        }
    }
}

/// Light visibility in [0, 1] along a shadow ray from `origin` towards the light along `dir`
/// (1 = lit). Hard: 0 when an occluder is hit. Soft: the smallest `k·d/t` met along the ray
/// (the unbounding sphere's angular size), clamped to [0, 1].
pub fn shadow(scene: &PreparedScene, origin: Vec3, dir: Vec3, settings: &ShadowSettings) -> f32 {
    shadow_counted(scene, origin, dir, settings).0
}

/// [`shadow`] and the number of distance evaluations it took (the renderer's work count).
#[must_use]
pub fn shadow_counted(
    scene: &PreparedScene,
    origin: Vec3,
    dir: Vec3,
    settings: &ShadowSettings,
) -> (f32, u32) {
    let Some(dir) = dir.try_normalize() else {
        return (1.0, 0);
    };
    if !origin.is_finite() {
        return (1.0, 0);
    }
    let (o, d) = (origin.as_dvec3(), dir.as_dvec3().normalize_or_zero());
    let start = settings.start_offset.max(0.0) as f64;
    let eps = settings.epsilon as f64;
    let Some((t_lo, t_hi)) =
        ray_interval(scene, o, d, start, settings.max_distance as f64, |_| eps)
    else {
        return (1.0, 0);
    };
    let mut t = t_lo.max(start);
    let mut visibility = 1.0f64;
    let k = settings
        .softness
        .filter(|k| k.is_finite() && *k > 0.0)
        .map(f64::from);
    let mut steps = 0u32;
    for _ in 0..settings.max_steps {
        if t > t_hi {
            break;
        }
        steps += 1;
        let dist = scene.distance((o + d * t).as_vec3()) as f64;
        if !dist.is_finite() {
            break;
        }
        if dist < settings.epsilon as f64 {
            return (0.0, steps);
        }
        if let Some(k) = k {
            visibility = visibility.min(k * dist / t.max(1e-12));
        }
        t += dist;
    }
    (visibility.clamp(0.0, 1.0) as f32, steps)
}

/// Ambient-occlusion knobs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AoSettings {
    /// Number of distance samples along the normal.
    pub samples: u32,
    /// Spacing of the samples in world units: the reach is `samples · spacing`.
    pub spacing: f32,
    /// Strength multiplier.
    pub strength: f32,
    /// Where each sample lies in its stratum, in [0, 1): sample i (from 0) is at height
    /// `(i + 1 − jitter) · spacing`. The renderers draw it per pixel ([`ao_jitter`]), which
    /// makes the estimate unbiased: its mean over the jitter is the same integral for every
    /// sample count, and only its noise falls as the count grows. 0.5 is the midpoint rule.
    pub jitter: f32,
}

impl Default for AoSettings {
    fn default() -> Self {
        Self {
            samples: 5,
            spacing: 0.05,
            strength: 1.0,
            jitter: 0.5,
        }
    }
}

/// The AO jitter of pixel `pixel` (its index in the image drawn, row-major): a fixed hash
/// (Wellons' `lowbias32`) of the index, in [0, 1) with 24 bits, so the CPU and GPU renderers
/// draw the same value for the same pixel and a frame is deterministic.
/// Keep in sync with `shaders/common/types.wgsl` (`ao_jitter`).
#[must_use]
pub fn ao_jitter(pixel: u32) -> f32 {
    (super::lowbias32(pixel) >> 8) as f32 / 16_777_216.0
}

/// Ambient accessibility in [0, 1] (1 = open) at surface point `p` with normal `n`: the
/// occlusion is the weighted mean over heights h in (0, R] (R = `samples · spacing`, the
/// reach) of the shortfall `(h − d(p + h·n)) / h` clamped to [0, 1] (0 on an open surface, where
/// the free distance is h), with weights `w(h) = 2^(−4h/R)` (halving every quarter of the
/// reach, whatever the count) normalised by their integral over the reach. It is estimated by
/// stratified sampling: one sample per stratum of width `spacing`, at `(i + 1 − jitter) ·
/// spacing`, so the estimate's mean over the jitter is the integral itself for every sample
/// count (the earlier fixed heights `i · spacing` were a quadrature whose value moved with the
/// count: 4 samples looked past the first quarter of the reach).
pub fn ambient_occlusion(scene: &PreparedScene, p: Vec3, n: Vec3, settings: &AoSettings) -> f32 {
    let Some(n) = n.try_normalize() else {
        return 1.0;
    };
    if settings.samples == 0 || !(settings.spacing.is_finite() && settings.spacing > 0.0) {
        return 1.0;
    }
    let reach = settings.samples as f32 * settings.spacing;
    // ∫₀^R 2^(−4h/R) dh = R · (1 − 2^−4) / (4 ln 2).
    let weight_integral = reach * (15.0 / 16.0) / (4.0 * std::f32::consts::LN_2);
    let offset = 1.0 - settings.jitter.clamp(0.0, 1.0);
    let mut occlusion = 0.0f32;
    for i in 0..settings.samples {
        let h = (i as f32 + offset).max(1e-3) * settings.spacing;
        let d = scene.distance(p + n * h);
        let shortfall = if d.is_finite() {
            ((h - d) / h).clamp(0.0, 1.0)
        } else {
            0.0
        };
        occlusion += (-4.0 * h / reach).exp2() * shortfall;
    }
    let occlusion = occlusion * settings.spacing / weight_integral;
    (1.0 - settings.strength * occlusion).clamp(0.0, 1.0)
}

//! Smooth shading by light-direction interpolation near mirror planes (Algorithm 2, §6.1) and
//! procedural texturing (§6.2): triplanar in unfolded object space, or kernel-parametrised in
//! each instance's own frame.

use glam::{Mat3, Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::object::{PreparedObject, PreparedScene};
use super::trace::TraceHit;

/// Result of Algorithm 2 at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothShading {
    /// Nearest kernel, `None` when every kernel is empty.
    pub kernel: Option<usize>,
    /// The folded point in that kernel's space.
    pub kernel_point: Vec3,
    /// Kernel-space unit normal at that point.
    pub normal_kernel: Vec3,
    /// Light direction carried into kernel space, interpolated near mirror planes (unit).
    pub light_kernel: Vec3,
    /// Lambert factor max(0, normal · light) in kernel space.
    pub diffuse: f32,
}

/// Smoothing threshold proportional to depth (§6.1): `smoothing_px` pixels' worth of world
/// distance at ray parameter `t`.
pub fn shading_threshold(t: f32, pixel_cone_ratio: f32, smoothing_px: f32) -> f32 {
    (smoothing_px * pixel_cone_ratio * t).max(0.0)
}

impl PreparedObject {
    /// Algorithm 2: folds `p_world` like Algorithm 1 while carrying the light direction
    /// `light_world` (towards the light) into kernel space; within `e_threshold_world` of a
    /// mirror plane the direction is blended between its reflected and unreflected versions,
    /// so normals that jump across a plane (non-separated kernels) shade continuously.
    /// A threshold of 0 gives the flat (exact-fold) shading.
    pub fn smooth_shading(
        &self,
        p_world: Vec3,
        light_world: Vec3,
        e_threshold_world: f32,
    ) -> SmoothShading {
        let p_object = self.object_from_world(p_world);
        let light_object = self
            .object_dir_from_world(light_world)
            .normalize_or(Vec3::Y);
        // A warp w maps normals by Jᵀ: n_object ∝ Jᵀ·F·n_kernel (F the reflections taken).
        // Carrying J·l into warped space instead of l gives n_kernel·(Fᵀ·J·l) = (Jᵀ·F·n)·l, so
        // the light is folded and blended exactly as without a warp and the Lambert factor is
        // rescaled by |J·l| / |Jᵀ·F·n| at the end: with no blending this is the flat distorted
        // shading (`sample_world`'s normal) exactly.
        let jacobian = self.object.distortion.map(|d| d.jacobian_columns(p_object));
        let (mut p, light0, light_len) = match (&self.object.distortion, jacobian) {
            (Some(d), Some([jx, jy, jz])) => {
                let jl = jx * light_object.x + jy * light_object.y + jz * light_object.z;
                (d.warp(p_object), jl.normalize_or(light_object), jl.length())
            }
            _ => (p_object, light_object, 1.0),
        };
        let e_threshold = (e_threshold_world / self.object.world_from_object.scale).max(0.0);
        let obj = &self.object;
        let n = obj.mirrors.len();
        let mut omega = light0;
        let mut best_d = f32::INFINITY;
        let mut best: Option<(usize, Vec3, Vec3, Mat3)> = None;
        let mut frame = Mat3::IDENTITY;
        let mut consider = |i: usize, p: Vec3, omega: Vec3, frame: Mat3| {
            if let Some(k) = obj.kernels.get(i).filter(|k| !k.is_empty()) {
                let d = k.distance(p);
                if d < best_d {
                    best_d = d;
                    best = Some((i, p, omega, frame));
                }
            }
        };
        consider(n, p, omega, frame);
        for i in (0..n).rev() {
            let m = &obj.mirrors[i];
            let e = m.signed_distance(p);
            if e > 0.0 {
                p = m.reflect_point(p);
                if jacobian.is_some() {
                    frame *= m.matrix();
                }
            }
            let rho = m.reflect_dir(omega);
            let w = if e_threshold > 0.0 {
                (e / e_threshold + 0.5).clamp(0.0, 1.0)
            } else if e > 0.0 {
                1.0
            } else {
                0.0
            };
            // Re-normalise: the blend of two unit vectors is shorter than unit.
            omega = omega
                .lerp(rho, w)
                .normalize_or(if e > 0.0 { rho } else { omega });
            consider(i, p, omega, frame);
        }
        match best {
            None => SmoothShading {
                kernel: None,
                kernel_point: p,
                normal_kernel: Vec3::Y,
                light_kernel: omega,
                diffuse: 0.0,
            },
            Some((i, kp, light_kernel, frame)) => {
                let normal_kernel = obj.kernels[i].normal(kp);
                let mut diffuse = normal_kernel.dot(light_kernel).max(0.0);
                if let Some([jx, jy, jz]) = jacobian {
                    let n = frame * normal_kernel;
                    let jt_n = Vec3::new(jx.dot(n), jy.dot(n), jz.dot(n)).length();
                    diffuse = if jt_n > 0.0 {
                        (diffuse * light_len / jt_n).min(1.0)
                    } else {
                        0.0
                    };
                }
                SmoothShading {
                    kernel: Some(i),
                    kernel_point: kp,
                    normal_kernel,
                    light_kernel,
                    diffuse,
                }
            }
        }
    }
}

/// Which coordinates drive the procedural texture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum TextureMode {
    /// Plain material colour.
    #[default]
    None,
    /// Triplanar projection of unfolded object-space position (terrain, rock: no repetition
    /// between instances).
    Triplanar,
    /// Kernel-parametrised coordinates (along and around a branch), same on every instance.
    KernelParam,
}

/// A procedural 2D pattern (no image assets).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Pattern {
    /// A checkerboard of the material colour, lighter and darker.
    #[default]
    Checker,
    /// Bark-like streaks: value noise stretched across the `x` coordinate.
    Bark,
}

/// Texturing of a KRS object.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Texturing {
    /// Which coordinates to use.
    pub mode: TextureMode,
    /// Which pattern.
    pub pattern: Pattern,
    /// Pattern cells per object-space unit.
    pub scale: f32,
    /// Colour modulation depth in [0, 1].
    pub contrast: f32,
    /// Triplanar blend exponent (higher = sharper transitions between projections).
    pub sharpness: f32,
}

impl Default for Texturing {
    fn default() -> Self {
        Self {
            mode: TextureMode::None,
            pattern: Pattern::Checker,
            scale: 4.0,
            contrast: 0.4,
            sharpness: 4.0,
        }
    }
}

fn hash2(x: i64, y: i64) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343) ^ (y as u32).wrapping_mul(0xd816_3841);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297a_2d39);
    h ^= h >> 15;
    (h >> 8) as f32 / 16_777_215.0
}

fn value_noise2(p: Vec2) -> f32 {
    let c = p.floor();
    let t = p - c;
    let s = t * t * (Vec2::splat(3.0) - 2.0 * t);
    let (x, y) = (c.x as i64, c.y as i64);
    let a = hash2(x, y) + (hash2(x + 1, y) - hash2(x, y)) * s.x;
    let b = hash2(x, y + 1) + (hash2(x + 1, y + 1) - hash2(x, y + 1)) * s.x;
    a + (b - a) * s.y
}

impl Pattern {
    /// Pattern value in [0, 1] at 2D coordinates (in cells).
    pub fn value(&self, uv: Vec2) -> f32 {
        match self {
            Pattern::Checker => {
                let cell = uv.floor();
                if (cell.x as i64 + cell.y as i64).rem_euclid(2) == 0 {
                    1.0
                } else {
                    0.0
                }
            }
            Pattern::Bark => {
                // Streaks along x (the branch), broken up by a second octave.
                let streak = value_noise2(Vec2::new(uv.x * 0.25, uv.y * 3.0));
                let detail = value_noise2(uv * 2.0 + Vec2::splat(17.0));
                (0.75 * streak + 0.25 * detail).clamp(0.0, 1.0)
            }
        }
    }
}

fn modulate(base: Vec3, value: f32, contrast: f32) -> Vec3 {
    (base * (1.0 + contrast.clamp(0.0, 1.0) * (value - 0.5))).clamp(Vec3::ZERO, Vec3::ONE)
}

/// Triplanar texture (§6.2): the pattern projected along the three axes at `p` and blended by
/// `|n|^sharpness`.
pub fn triplanar_colour(p: Vec3, n: Vec3, base: Vec3, texturing: &Texturing) -> Vec3 {
    let w = n.abs().powf(texturing.sharpness.max(1.0));
    let sum = w.x + w.y + w.z;
    let w = if sum > 0.0 && sum.is_finite() {
        w / sum
    } else {
        Vec3::splat(1.0 / 3.0)
    };
    let q = p * texturing.scale;
    let v = w.x * texturing.pattern.value(Vec2::new(q.y, q.z))
        + w.y * texturing.pattern.value(Vec2::new(q.x, q.z))
        + w.z * texturing.pattern.value(Vec2::new(q.x, q.y));
    modulate(base, v, texturing.contrast)
}

/// Albedo of a hit: the kernel's material colour, textured as its object asks.
pub fn shade_colour(scene: &PreparedScene, hit: &TraceHit) -> Vec3 {
    let base = hit.material.colour;
    let Some(obj) = scene.objects.get(hit.object) else {
        return base;
    };
    let tex = &obj.object.texturing;
    match tex.mode {
        TextureMode::None => base,
        TextureMode::Triplanar => {
            let p = obj.object_from_world(hit.position);
            let n = obj.object_dir_from_world(hit.normal);
            triplanar_colour(p, n, base, tex)
        }
        TextureMode::KernelParam => modulate(
            base,
            tex.pattern.value(hit.kernel_uv * tex.scale),
            tex.contrast,
        ),
    }
}

//! Lipschitz-bounded distortion (§5.2): a smooth value-noise warp `w(p) = p + A·noise(f·p)`.
//!
//! The distorted object is `{p : d(w(p)) ≤ 0}`. Since `d` (Algorithm 1) is 1-Lipschitz,
//! `d(w(p)) / Lip(w)` is a lower bound of the distance to that set, so the tracer divides the
//! step by [`Distortion::lipschitz_bound`] (derivation in `docs/krs.md`).

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// A smooth noise warp of object space.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Distortion {
    /// Displacement amplitude A in object-space units (≥ 0); each noise component is in [−1, 1].
    pub amplitude: f32,
    /// Spatial frequency f in lattice cells per object-space unit (≥ 0).
    pub frequency: f32,
    /// Noise seed.
    pub seed: u32,
}

impl Default for Distortion {
    fn default() -> Self {
        Self {
            amplitude: 0.05,
            frequency: 1.0,
            seed: 1,
        }
    }
}

/// Bound on the spectral norm of the Jacobian of `noise` (lattice units): every partial
/// derivative of one component is `s'(t)·(a − b)` with `s' ≤ 1.5` (cubic smoothstep) and
/// `|a − b| ≤ 2`, so each of the nine entries is ≤ 3 and the Frobenius norm ≤ 9.
pub const NOISE_JACOBIAN_BOUND: f32 = 9.0;

impl Distortion {
    /// The declared Lipschitz constant of the warp: `1 + 9·A·f`.
    pub fn lipschitz_bound(&self) -> f32 {
        1.0 + NOISE_JACOBIAN_BOUND * self.amplitude * self.frequency
    }

    /// The columns `∂w/∂x, ∂w/∂y, ∂w/∂z` of the warp's Jacobian at `p`, by central differences
    /// of the smooth warp (the step the normals use, `1e-3 / f`).
    pub fn jacobian_columns(&self, p: Vec3) -> [Vec3; 3] {
        let h = 1e-3 / self.frequency.max(1e-3);
        let column = |axis: Vec3| (self.warp(p + axis * h) - self.warp(p - axis * h)) / (2.0 * h);
        [column(Vec3::X), column(Vec3::Y), column(Vec3::Z)]
    }

    /// The largest displacement `|w(p) − p|` (each of the three components ≤ A).
    pub fn max_displacement(&self) -> f32 {
        self.amplitude * 3f32.sqrt()
    }

    /// Checks that the parameters are finite and non-negative.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.amplitude.is_finite() && self.amplitude >= 0.0) {
            return Err(format!(
                "amplitude {} must be finite and ≥ 0",
                self.amplitude
            ));
        }
        if !(self.frequency.is_finite() && self.frequency >= 0.0) {
            return Err(format!(
                "frequency {} must be finite and ≥ 0",
                self.frequency
            ));
        }
        if !self.lipschitz_bound().is_finite() {
            return Err("amplitude × frequency overflows".to_owned());
        }
        Ok(())
    }

    /// The warped point `p + A·noise(f·p)`.
    #[inline]
    pub fn warp(&self, p: Vec3) -> Vec3 {
        p + self.amplitude * value_noise3(p * self.frequency, self.seed)
    }
}

#[inline]
fn hash(x: i64, y: i64, z: i64, seed: u32) -> u32 {
    // Wrapping integer mix, then lowbias32; any lattice point maps to a stable value.
    super::lowbias32(
        (x as u32).wrapping_mul(0x8da6_b343)
            ^ (y as u32).wrapping_mul(0xd816_3841)
            ^ (z as u32).wrapping_mul(0xcb1a_b31f)
            ^ seed.wrapping_mul(0x9e37_79b9),
    )
}

#[inline]
fn unit_value(h: u32) -> f32 {
    (h >> 8) as f32 * (2.0 / 16_777_215.0) - 1.0
}

/// Three independent channels of value noise in [−1, 1], C¹ (cubic smoothstep).
#[inline]
fn value_noise3(p: Vec3, seed: u32) -> Vec3 {
    let cell = p.floor();
    let t = (p - cell).clamp(Vec3::ZERO, Vec3::ONE);
    let s = t * t * (Vec3::splat(3.0) - 2.0 * t);
    // Saturating float → int casts keep huge coordinates finite and deterministic.
    let (ix, iy, iz) = (cell.x as i64, cell.y as i64, cell.z as i64);
    let mut corners = [Vec3::ZERO; 8];
    for (i, c) in corners.iter_mut().enumerate() {
        let (dx, dy, dz) = ((i & 1) as i64, ((i >> 1) & 1) as i64, ((i >> 2) & 1) as i64);
        let h = hash(
            ix.wrapping_add(dx),
            iy.wrapping_add(dy),
            iz.wrapping_add(dz),
            seed,
        );
        *c = Vec3::new(
            unit_value(h),
            unit_value(hash(h as i64, 1, 0, seed)),
            unit_value(hash(h as i64, 2, 0, seed)),
        );
    }
    let x00 = corners[0].lerp(corners[1], s.x);
    let x10 = corners[2].lerp(corners[3], s.x);
    let x01 = corners[4].lerp(corners[5], s.x);
    let x11 = corners[6].lerp(corners[7], s.x);
    let y0 = x00.lerp(x10, s.y);
    let y1 = x01.lerp(x11, s.y);
    y0.lerp(y1, s.z)
}

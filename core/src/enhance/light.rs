//! Random-walk ("snowflake") lighting (paper §4.4): from each shell fragment, sun particles
//! wander biased toward the sun and sky particles wander uniformly, in fixed-length steps
//! through the fine occupancy; a particle that survives `steps` steps without entering a solid
//! fragment lights its fragment. Each fragment seeds its own PCG from the lighting seed and its
//! fine coordinate, so results do not depend on thread count or visiting order. Directions
//! come from rejection sampling (no trigonometry), so the walk is plain IEEE arithmetic.

use glam::{IVec3, Vec3};
use rand::{RngCore, SeedableRng};
use rand_pcg::Pcg32;

use super::grid::{CoarseGrid, cell_key};
use super::{CellState, Engine, Scratch};
use crate::mesh::linear_to_srgb_byte;

/// Lighting settings turned into working units.
pub(crate) struct LightParams {
    sun_dir: Vec3,
    sun_color: Vec3,
    sky_color: Vec3,
    ambient: f32,
    sun_n: u32,
    sky_n: u32,
    steps: u32,
    /// Step length in fine fragments.
    step_fine: f32,
    bias: f32,
    seed: u64,
    /// Coarse cells a particle can reach from its fragment's cell.
    pub(crate) reach_cells: i32,
}

impl LightParams {
    pub(crate) fn new(s: &super::LightingSettings, factor: u32) -> Self {
        let f = factor as f32;
        let path = s.steps as f32 * s.step_length;
        Self {
            sun_dir: Vec3::from(s.sun_direction)
                .try_normalize()
                .unwrap_or(Vec3::Y),
            sun_color: Vec3::from(s.sun_color),
            sky_color: Vec3::from(s.sky_color),
            ambient: s.ambient,
            sun_n: s.sun_particles,
            sky_n: s.sky_particles,
            steps: s.steps,
            step_fine: s.step_length * f,
            bias: s.sun_bias,
            seed: s.seed,
            // Start offset (one fragment) + path, with a margin for float rounding.
            reach_cells: (1.0 / f + path + 1e-3).ceil() as i32,
        }
    }

    /// The lit colour of fragment `p` (fine coordinates) with normal `n` and albedo `albedo`.
    pub(crate) fn shade(
        &self,
        engine: &Engine,
        grid: &CoarseGrid,
        p: IVec3,
        n: Vec3,
        albedo: [u8; 4],
        scratch: &mut Scratch,
    ) -> [u8; 4] {
        let mut rng = Pcg32::seed_from_u64(splitmix(self.seed ^ splitmix(cell_key(p))));
        let mut walker = Walker {
            engine,
            grid,
            scratch,
            last: None,
            fine_extent: grid.extent * engine.f,
        };
        let start = p.as_vec3() + Vec3::splat(0.5) + n;
        let mut sun = 0u32;
        for _ in 0..self.sun_n {
            if self.walk(&mut walker, &mut rng, start, true) {
                sun += 1;
            }
        }
        let mut sky = 0u32;
        for _ in 0..self.sky_n {
            if self.walk(&mut walker, &mut rng, start, false) {
                sky += 1;
            }
        }
        let frac = |k: u32, n: u32| if n == 0 { 0.0 } else { k as f32 / n as f32 };
        let light = Vec3::splat(self.ambient)
            + self.sun_color * frac(sun, self.sun_n)
            + self.sky_color * frac(sky, self.sky_n);
        let lin = super::srgb_byte_to_linear;
        let out = Vec3::new(lin(albedo[0]), lin(albedo[1]), lin(albedo[2])) * light;
        [
            linear_to_srgb_byte(out.x),
            linear_to_srgb_byte(out.y),
            linear_to_srgb_byte(out.z),
            albedo[3],
        ]
    }

    fn walk(&self, w: &mut Walker<'_, '_>, rng: &mut Pcg32, start: Vec3, sun: bool) -> bool {
        let mut q = start;
        if w.solid(q) {
            return false;
        }
        for _ in 0..self.steps {
            let r = random_unit(rng);
            let dir = if sun {
                (self.sun_dir * self.bias + r * (1.0 - self.bias))
                    .try_normalize()
                    .unwrap_or(self.sun_dir)
            } else {
                r
            };
            q += dir * self.step_fine;
            if w.solid(q) {
                return false;
            }
        }
        true
    }
}

fn splitmix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

fn random_unit(rng: &mut Pcg32) -> Vec3 {
    let u = |rng: &mut Pcg32| (rng.next_u32() >> 8) as f32 * (2.0 / (1u32 << 24) as f32) - 1.0;
    loop {
        let v = Vec3::new(u(rng), u(rng), u(rng));
        let l2 = v.length_squared();
        if l2 > 1e-6 && l2 <= 1.0 {
            return v / l2.sqrt();
        }
    }
}

/// Fine occupancy look-ups along one fragment's walks; remembers the last cell.
struct Walker<'a, 's> {
    engine: &'a Engine,
    grid: &'a CoarseGrid,
    scratch: &'s mut Scratch,
    last: Option<(IVec3, CellState)>,
    fine_extent: i32,
}

impl Walker<'_, '_> {
    fn solid(&mut self, q: Vec3) -> bool {
        let p = q.floor();
        let fe = self.fine_extent as f32;
        if p.cmplt(Vec3::ZERO).any() || p.cmpge(Vec3::splat(fe)).any() {
            return false;
        }
        let p = p.as_ivec3();
        let f = self.engine.f;
        let c = p / f;
        if self.last.as_ref().is_none_or(|(lc, _)| *lc != c) {
            let s = self.engine.oracle_cell(c, self.grid, self.scratch);
            self.last = Some((c, s));
        }
        match &self.last {
            Some((_, CellState::Uniform(b))) => *b,
            Some((_, CellState::Mixed(r))) => {
                let l = p - c * f;
                r.get(l.x as usize, l.y as usize, l.z as usize)
            }
            None => false,
        }
    }
}

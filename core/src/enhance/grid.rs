//! The enhancer's private copy of the coarse map: occupancy, colour and material in 8³ bricks
//! kept in a hash map, so memory follows the solid voxels and a window gather costs a few
//! hash look-ups, not an octree descent per voxel.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::{IVec3, UVec3};

use crate::svo::{Svo, Voxel};

/// A multiply-xorshift hasher for integer keys. The standard SipHash costs more than the work
/// it guards on these hot look-ups; keys are our own coordinates, never attacker-chosen.
#[derive(Default, Clone, Copy)]
pub(crate) struct FastHasher(u64);

impl Hasher for FastHasher {
    fn finish(&self) -> u64 {
        let mut x = self.0;
        x ^= x >> 33;
        x = x.wrapping_mul(0xff51_afd7_ed55_8ccd);
        x ^= x >> 33;
        x
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }

    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

/// Hash map with [`FastHasher`].
pub(crate) type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<FastHasher>>;

/// Packs a (possibly negative) cell coordinate into one key: 21 bits per axis, offset so
/// coordinates down to -2^20 stay distinct.
#[inline]
pub(crate) fn cell_key(c: IVec3) -> u64 {
    let f = |v: i32| (i64::from(v) + (1 << 20)) as u64 & 0x1f_ffff;
    f(c.x) | f(c.y) << 21 | f(c.z) << 42
}

const BRICK: i32 = 8;
const BRICK_VOXELS: usize = 512;

#[derive(Clone)]
struct Brick {
    occ: [u64; 8],
    /// Interior voxels (`Voxel::is_interior`): solid, but with no colour to give.
    interior: [u64; 8],
    color: [[u8; 4]; BRICK_VOXELS],
    material: [u8; BRICK_VOXELS],
}

/// Solid voxels of the coarse map with their colour and material.
#[derive(Clone, Default)]
pub(crate) struct CoarseGrid {
    /// Voxels per axis (the coarse octree's extent).
    pub(crate) extent: i32,
    index: FastMap<u64, u32>,
    bricks: Vec<Brick>,
}

#[inline]
fn split(p: IVec3) -> (u64, usize) {
    let b = IVec3::new(p.x >> 3, p.y >> 3, p.z >> 3);
    let l = (p.x & 7) | (p.y & 7) << 3 | (p.z & 7) << 6;
    (cell_key(b), l as usize)
}

impl CoarseGrid {
    /// Copies every solid voxel of `svo`.
    pub(crate) fn from_svo(svo: &Svo) -> Self {
        let mut g = Self {
            extent: svo.extent() as i32,
            ..Self::default()
        };
        svo.for_each_leaf(|c, v| g.set(c.as_ivec3(), Some(&v)));
        g
    }

    /// Whether `p` lies inside the map.
    #[inline]
    pub(crate) fn inside(&self, p: IVec3) -> bool {
        p.cmpge(IVec3::ZERO).all() && p.cmplt(IVec3::splat(self.extent)).all()
    }

    /// Sets or clears one voxel (ignored outside the map).
    pub(crate) fn set(&mut self, p: IVec3, v: Option<&Voxel>) {
        if !self.inside(p) {
            return;
        }
        let (key, l) = split(p);
        let bi = match self.index.get(&key) {
            Some(&i) => i as usize,
            None => {
                if v.is_none() {
                    return;
                }
                self.bricks.push(Brick {
                    occ: [0; 8],
                    interior: [0; 8],
                    color: [[0; 4]; BRICK_VOXELS],
                    material: [0; BRICK_VOXELS],
                });
                let i = self.bricks.len() - 1;
                self.index.insert(key, i as u32);
                i
            }
        };
        let b = &mut self.bricks[bi];
        match v {
            Some(v) => {
                b.occ[l >> 6] |= 1 << (l & 63);
                if v.is_interior() {
                    b.interior[l >> 6] |= 1 << (l & 63);
                } else {
                    b.interior[l >> 6] &= !(1 << (l & 63));
                }
                b.color[l] = v.color;
                b.material[l] = v.material;
            }
            None => {
                b.occ[l >> 6] &= !(1 << (l & 63));
                b.interior[l >> 6] &= !(1 << (l & 63));
                b.color[l] = [0; 4];
                b.material[l] = 0;
            }
        }
    }

    /// Re-reads the inclusive box `lo..=hi` from `svo` (after an edit).
    pub(crate) fn refresh(&mut self, svo: &Svo, lo: UVec3, hi: UVec3) {
        let max = UVec3::splat(svo.extent().saturating_sub(1));
        let hi = hi.min(max);
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let c = UVec3::new(x, y, z);
                    let v = svo.get(c);
                    self.set(c.as_ivec3(), v.as_ref());
                }
            }
        }
    }

    /// Whether `p` is solid (outside the map is empty).
    #[inline]
    pub(crate) fn solid(&self, p: IVec3) -> bool {
        if !self.inside(p) {
            return false;
        }
        let (key, l) = split(p);
        self.index
            .get(&key)
            .is_some_and(|&i| self.bricks[i as usize].occ[l >> 6] >> (l & 63) & 1 == 1)
    }

    /// Calls `f` for every solid voxel (brick order; callers sort when order matters).
    pub(crate) fn for_each_solid(&self, mut f: impl FnMut(IVec3)) {
        for (&key, &bi) in &self.index {
            let b = &self.bricks[bi as usize];
            let base = IVec3::new(
                (key & 0x1f_ffff) as i32 - (1 << 20),
                ((key >> 21) & 0x1f_ffff) as i32 - (1 << 20),
                ((key >> 42) & 0x1f_ffff) as i32 - (1 << 20),
            ) * BRICK;
            for (w, &word) in b.occ.iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let l = w * 64 + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let l = l as i32;
                    f(base + IVec3::new(l & 7, (l >> 3) & 7, l >> 6));
                }
            }
        }
    }

    /// Gathers the cube of radius `r` around `c` into `w` (outside the map is empty).
    pub(crate) fn gather(&self, c: IVec3, r: i32, w: &mut Window) {
        w.r = r;
        w.side = (2 * r + 1) as usize;
        let n = w.side * w.side * w.side;
        w.occ.clear();
        w.occ.resize(n, false);
        w.color.clear();
        w.color.resize(n, [0; 4]);
        w.material.clear();
        w.material.resize(n, 0);
        w.interior.clear();
        w.interior.resize(n, false);
        w.solid_count = 0;
        // Remember the last brick: a window crosses at most a few bricks.
        let mut last: Option<(u64, Option<u32>)> = None;
        let mut i = 0;
        for z in -r..=r {
            for y in -r..=r {
                for x in -r..=r {
                    let p = c + IVec3::new(x, y, z);
                    if self.inside(p) {
                        let (key, l) = split(p);
                        let bi = match last {
                            Some((k, b)) if k == key => b,
                            _ => {
                                let b = self.index.get(&key).copied();
                                last = Some((key, b));
                                b
                            }
                        };
                        if let Some(bi) = bi {
                            let b = &self.bricks[bi as usize];
                            if b.occ[l >> 6] >> (l & 63) & 1 == 1 {
                                w.occ[i] = true;
                                w.color[i] = b.color[l];
                                w.material[i] = b.material[l];
                                w.interior[i] = b.interior[l >> 6] >> (l & 63) & 1 == 1;
                                w.solid_count += 1;
                            }
                        }
                    }
                    i += 1;
                }
            }
        }
    }
}

/// A dense cube of coarse voxels around a centre cell, x fastest.
#[derive(Clone, Default, Debug)]
pub(crate) struct Window {
    /// Radius in cells.
    pub(crate) r: i32,
    /// `2r + 1`.
    pub(crate) side: usize,
    pub(crate) occ: Vec<bool>,
    pub(crate) color: Vec<[u8; 4]>,
    pub(crate) material: Vec<u8>,
    /// Interior voxels: solid, but they give fragments no colour.
    pub(crate) interior: Vec<bool>,
    pub(crate) solid_count: usize,
}

impl Window {
    /// Index of offset `d` (each component in `-r..=r`).
    #[inline]
    pub(crate) fn idx(&self, d: IVec3) -> usize {
        let s = self.side as i32;
        ((d.z + self.r) * s * s + (d.y + self.r) * s + (d.x + self.r)) as usize
    }

    /// True when every cell of the sub-cube of radius `r` around offset `d` has the same
    /// occupancy.
    pub(crate) fn uniform_around(&self, d: IVec3, r: i32) -> bool {
        let first = self.occ[self.idx(d - IVec3::splat(r))];
        for z in -r..=r {
            for y in -r..=r {
                let row = self.idx(d + IVec3::new(-r, y, z));
                if self.occ[row..=row + 2 * r as usize]
                    .iter()
                    .any(|&o| o != first)
                {
                    return false;
                }
            }
        }
        true
    }

    /// True when the whole window has one occupancy.
    pub(crate) fn uniform(&self) -> bool {
        self.solid_count == 0 || self.solid_count == self.occ.len()
    }
}

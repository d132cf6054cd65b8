//! Recursive subdivision (paper §2): each voxel becomes 2×2×2 fragments; a fragment is solid
//! when the count of solid voxels among its source voxel and the source's three face
//! neighbours toward the fragment reaches the threshold. Repeated `k` times for factor `2^k`.
//!
//! Two implementations that must agree (tested):
//! * [`LUT`]: the paper's §4.2 table, indexed by the 7-voxel neighbourhood (2^7 = 128
//!   configurations), giving the 8-fragment mask for each threshold; [`subdivide_dense`] applies
//!   it voxel by voxel (the reference, used by tests).
//! * [`subdivide_cell`]: the production kernel. One coarse cell's fragments depend only on its
//!   3×3×3 window (see `docs/enhance.md` for the proof), so each cell is expanded on its own,
//!   level by level, with x rows as `u128` bit sets: one boolean expression evaluates up to 64
//!   voxels, so the cost per level is the number of rows, `(2^l + 2)^2`, which follows the
//!   surface area, not the volume.

use glam::IVec3;

use super::grid::Window;

/// Bit of the centre voxel in a 7-voxel configuration; the face neighbours follow as
/// -x, +x, -y, +y, -z, +z in bits 1..=6.
pub const CFG_CENTRE: u8 = 1;

const fn bit(config: u8, b: u8) -> u8 {
    (config >> b) & 1
}

/// The direct rule: whether fragment `octant` (bit 0 = +x half, bit 1 = +y, bit 2 = +z) of a
/// voxel with 7-voxel configuration `config` is solid for threshold `t`.
#[must_use]
pub const fn rule_direct(config: u8, octant: u8, t: u8) -> bool {
    let x = if octant & 1 != 0 {
        bit(config, 2)
    } else {
        bit(config, 1)
    };
    let y = if octant & 2 != 0 {
        bit(config, 4)
    } else {
        bit(config, 3)
    };
    let z = if octant & 4 != 0 {
        bit(config, 6)
    } else {
        bit(config, 5)
    };
    bit(config, 0) + x + y + z >= t
}

const fn build_lut() -> [[u8; 128]; 4] {
    let mut lut = [[0u8; 128]; 4];
    let mut t = 0;
    while t < 4 {
        let mut cfg = 0;
        while cfg < 128 {
            let mut mask = 0u8;
            let mut o = 0;
            while o < 8 {
                if rule_direct(cfg as u8, o, t as u8 + 1) {
                    mask |= 1 << o;
                }
                o += 1;
            }
            lut[t][cfg] = mask;
            cfg += 1;
        }
        t += 1;
    }
    lut
}

/// `LUT[t - 1][config]` is the mask of solid fragments (bit = octant) for threshold `t`
/// (1..=4) and 7-voxel configuration `config` ([`CFG_CENTRE`] and the face bits).
pub const LUT: [[u8; 128]; 4] = build_lut();

/// Per-level threshold of the fragments inside each cell of the 3×3×3 window:
/// `t[cell][altitude parity]`, `cell = (dz+1)*9 + (dy+1)*3 + (dx+1)`, values 1..=4.
pub(crate) type CellThresholds = [[u8; 2]; 27];

/// A cube of fine fragments as x rows: bit `x` of `rows[z * w + y]`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Region {
    /// Side in fragments.
    pub(crate) w: usize,
    pub(crate) rows: Vec<u128>,
}

impl Region {
    #[inline]
    pub(crate) fn row(&self, y: usize, z: usize) -> u128 {
        self.rows[z * self.w + y]
    }

    #[inline]
    pub(crate) fn get(&self, x: usize, y: usize, z: usize) -> bool {
        self.rows[z * self.w + y] >> x & 1 == 1
    }
}

#[inline]
fn spread32(x: u32) -> u64 {
    let mut x = u64::from(x);
    x = (x | x << 16) & 0x0000_ffff_0000_ffff;
    x = (x | x << 8) & 0x00ff_00ff_00ff_00ff;
    x = (x | x << 4) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | x << 2) & 0x3333_3333_3333_3333;
    x = (x | x << 1) & 0x5555_5555_5555_5555;
    x
}

/// Moves bit `i` to bit `2i`.
#[inline]
fn spread(x: u64) -> u128 {
    u128::from(spread32(x as u32)) | u128::from(spread32((x >> 32) as u32)) << 64
}

#[inline]
fn low_mask(n: usize) -> u128 {
    if n >= 128 {
        u128::MAX
    } else {
        (1u128 << n) - 1
    }
}

/// Bit-parallel `count(a, b, c, d) >= t`.
#[inline]
fn count_ge(t: u8, a: u128, b: u128, c: u128, d: u128) -> u128 {
    match t {
        0 | 1 => a | b | c | d,
        2 => {
            let (s1, c1, s2, c2) = (a ^ b, a & b, c ^ d, c & d);
            c1 | c2 | (s1 & s2)
        }
        3 => {
            let (s1, c1, s2, c2) = (a ^ b, a & b, c ^ d, c & d);
            (c1 & c2) | (c1 & s2) | (c2 & s1)
        }
        _ => a & b & c & d,
    }
}

/// Fragments of coarse cell `c` at level `k` (factor `2^k`) with a one-fragment margin: the
/// result is `(2^k + 2)^3`, local index `i` ↔ global fine coordinate `c * 2^k - 1 + i`.
/// `win` is the 3×3×3 window around `c`; `extent` is the coarse map's extent (fragments
/// outside the map are empty at every level).
pub(crate) fn subdivide_cell(
    win: &Window,
    c: IVec3,
    k: u32,
    thresholds: &CellThresholds,
    extent: i32,
    scratch: &mut Region,
) -> Region {
    debug_assert_eq!(win.r, 1);
    // Level 0: the window itself, origin c - 1.
    let mut cur = Region {
        w: 3,
        rows: vec![0; 9],
    };
    for z in 0..3 {
        for y in 0..3 {
            let mut row = 0u128;
            for x in 0..3 {
                if win.occ[z * 9 + y * 3 + x] {
                    row |= 1 << x;
                }
            }
            cur.rows[z * 3 + y] = row;
        }
    }
    let mut origin = c - IVec3::ONE;
    for level in 1..=k {
        let w = cur.w;
        let cw = 2 * w - 2;
        let c_origin = origin * 2 + IVec3::ONE;
        let side = 1i32 << level;
        let map_side = extent << level;
        let cell_lo = c * side;
        scratch.w = cw;
        scratch.rows.clear();
        scratch.rows.resize(cw * cw, 0);
        // x bits inside the map at this level.
        let mut x_valid = 0u128;
        for j in 0..cw {
            let g = c_origin.x + j as i32;
            if (0..map_side).contains(&g) {
                x_valid |= 1 << j;
            }
        }
        let seg_l = 1u128;
        let seg_r = 1u128 << (cw - 1);
        let seg_m = low_mask(cw) & !seg_l & !seg_r;
        for jz in 0..cw {
            let gz = c_origin.z + jz as i32;
            if !(0..map_side).contains(&gz) {
                continue;
            }
            let (iz, dz) = ((jz + 1) >> 1, (jz + 1) & 1);
            let nz = if dz == 1 { iz + 1 } else { iz - 1 };
            let cz = ((gz - cell_lo.z).div_euclid(side) + 1) as usize;
            for jy in 0..cw {
                let gy = c_origin.y + jy as i32;
                if !(0..map_side).contains(&gy) {
                    continue;
                }
                let (iy, dy) = ((jy + 1) >> 1, (jy + 1) & 1);
                let ny = if dy == 1 { iy + 1 } else { iy - 1 };
                let cy = ((gy - cell_lo.y).div_euclid(side) + 1) as usize;
                let parity = (gy & 1) as usize;
                let base = cz * 9 + cy * 3;
                let t_l = thresholds[base][parity];
                let t_m = thresholds[base + 1][parity];
                let t_r = thresholds[base + 2][parity];
                let p = cur.rows[iz * w + iy];
                let yn = cur.rows[iz * w + ny];
                let zn = cur.rows[nz * w + iy];
                let x0 = p << 1;
                let x1 = p >> 1;
                let pw = low_mask(w);
                let eval = |t: u8| -> u128 {
                    let o0 = count_ge(t, p, x0, yn, zn) & pw;
                    let o1 = count_ge(t, p, x1, yn, zn) & pw;
                    (spread(o0 as u64) | spread(o1 as u64) << 1) >> 1
                };
                let row = if t_l == t_m && t_m == t_r {
                    eval(t_m)
                } else {
                    let mut row = eval(t_m) & seg_m;
                    row |= eval(t_l) & seg_l;
                    row |= eval(t_r) & seg_r;
                    row
                };
                scratch.rows[jz * cw + jy] = row & x_valid;
            }
        }
        std::mem::swap(&mut cur, scratch);
        origin = c_origin;
    }
    cur
}

/// Reference implementation: one subdivision level of a dense `n³` occupancy grid (x fastest;
/// outside is empty) through [`LUT`], with the threshold of each fragment given by
/// `threshold(source voxel, fragment coordinate)`. Returns the `(2n)³` grid.
#[must_use]
pub fn subdivide_dense(
    occ: &[bool],
    n: usize,
    threshold: &dyn Fn(IVec3, IVec3) -> u8,
) -> Vec<bool> {
    let at = |p: IVec3| -> bool {
        p.cmpge(IVec3::ZERO).all()
            && p.cmplt(IVec3::splat(n as i32)).all()
            && occ[(p.z as usize * n + p.y as usize) * n + p.x as usize]
    };
    let m = 2 * n;
    let mut out = vec![false; m * m * m];
    for z in 0..n as i32 {
        for y in 0..n as i32 {
            for x in 0..n as i32 {
                let p = IVec3::new(x, y, z);
                let mut cfg = u8::from(at(p));
                let faces = [
                    -IVec3::X,
                    IVec3::X,
                    -IVec3::Y,
                    IVec3::Y,
                    -IVec3::Z,
                    IVec3::Z,
                ];
                for (b, d) in faces.iter().enumerate() {
                    cfg |= u8::from(at(p + *d)) << (b + 1);
                }
                for o in 0..8u8 {
                    let f = p * 2
                        + IVec3::new(i32::from(o & 1), i32::from(o >> 1 & 1), i32::from(o >> 2));
                    let t = threshold(p, f).clamp(1, 4);
                    if LUT[usize::from(t - 1)][usize::from(cfg)] >> o & 1 == 1 {
                        out[(f.z as usize * m + f.y as usize) * m + f.x as usize] = true;
                    }
                }
            }
        }
    }
    out
}

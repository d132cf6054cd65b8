//! A coarse terrain for samples, tests and benchmarks (the kind of map in the paper's Fig. 1):
//! a heightmap of smooth value noise, grass on gentle tops, dirt under it, rock on steep
//! slopes, high ground and deep down.

use glam::{UVec3, Vec3};

use super::EnhanceError;
use crate::svo::{Svo, Voxel, encode_normal};

/// Material id of grass.
pub const MAT_GRASS: u8 = 1;
/// Material id of rock.
pub const MAT_ROCK: u8 = 2;
/// Material id of dirt.
pub const MAT_DIRT: u8 = 3;

fn hash2(x: i32, z: i32, seed: u64) -> u64 {
    let mut h = seed ^ (x as u32 as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    h ^= (z as u32 as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f);
    h ^= h >> 29;
    h = h.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h ^ (h >> 32)
}

fn lattice(x: i32, z: i32, seed: u64) -> f32 {
    (hash2(x, z, seed) >> 40) as f32 / (1u64 << 24) as f32
}

/// Smooth value noise in `[0, 1)` with lattice spacing `cell`.
fn value_noise(x: f32, z: f32, cell: f32, seed: u64) -> f32 {
    let (gx, gz) = (x / cell, z / cell);
    let (x0, z0) = (gx.floor(), gz.floor());
    let (tx, tz) = (gx - x0, gz - z0);
    let s = |t: f32| t * t * (3.0 - 2.0 * t);
    let (sx, sz) = (s(tx), s(tz));
    let (ix, iz) = (x0 as i32, z0 as i32);
    let a = lattice(ix, iz, seed);
    let b = lattice(ix + 1, iz, seed);
    let c = lattice(ix, iz + 1, seed);
    let d = lattice(ix + 1, iz + 1, seed);
    (a + (b - a) * sx) + ((c + (d - c) * sx) - (a + (b - a) * sx)) * sz
}

/// A `size³` coarse terrain (`size` is rounded up to a power of two for the octree; voxels lie
/// in `0..size`), deterministic for `seed`.
///
/// # Errors
/// [`EnhanceError::Invalid`] unless `4 <= size <= 1024`.
pub fn sample_terrain(size: u32, seed: u64) -> Result<Svo, EnhanceError> {
    if !(4..=1024).contains(&size) {
        return Err(EnhanceError::Invalid {
            field: "size",
            reason: format!("terrain size {size} is outside 4..=1024"),
        });
    }
    let n = size as i32;
    let sf = size as f32;
    let height = |x: i32, z: i32| -> i32 {
        let (x, z) = (x.clamp(0, n - 1) as f32, z.clamp(0, n - 1) as f32);
        let mut v = 0.0;
        let mut amp = 0.55;
        let mut cell = (sf / 3.0).max(2.0);
        for o in 0..3u64 {
            v += amp * value_noise(x, z, cell, seed.wrapping_add(o * 0x51ed));
            amp *= 0.5;
            cell *= 0.5;
        }
        // v in [0, 0.9625): heights from a fifth to about four fifths of the map.
        ((0.2 + 0.65 * v) * sf).floor().clamp(1.0, sf - 1.0) as i32
    };
    let mut voxels = Vec::new();
    for z in 0..n {
        for x in 0..n {
            let h = height(x, z);
            let gx = (height(x + 1, z) - height(x - 1, z)) as f32 * 0.5;
            let gz = (height(x, z + 1) - height(x, z - 1)) as f32 * 0.5;
            let slope = gx.abs().max(gz.abs());
            let normal = encode_normal(Vec3::new(-gx, 1.0, -gz));
            for y in 0..h {
                let depth = h - 1 - y;
                let material = if slope >= 1.5 || h as f32 > 0.7 * sf || depth >= 5 {
                    MAT_ROCK
                } else if depth == 0 {
                    MAT_GRASS
                } else {
                    MAT_DIRT
                };
                let base: [u8; 3] = match material {
                    MAT_GRASS => [84, 138, 56],
                    MAT_DIRT => [118, 84, 56],
                    _ => [126, 122, 116],
                };
                let j = (hash2(x * 131 + y, z, seed ^ 0xabcd) % 17) as i32 - 8;
                let color = [
                    (i32::from(base[0]) + j).clamp(0, 255) as u8,
                    (i32::from(base[1]) + j).clamp(0, 255) as u8,
                    (i32::from(base[2]) + j).clamp(0, 255) as u8,
                    255,
                ];
                voxels.push((
                    UVec3::new(x as u32, y as u32, z as u32),
                    Voxel {
                        color,
                        normal,
                        material,
                        skin: Default::default(),
                    },
                ));
            }
        }
    }
    let depth = size.next_power_of_two().trailing_zeros() as u8;
    Ok(Svo::from_voxels(depth, false, voxels)?)
}

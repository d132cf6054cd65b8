//! 63-bit Morton codes (21 bits per axis), the sort key that puts siblings next to each other.

use glam::UVec3;

fn split3(v: u32) -> u64 {
    let mut x = u64::from(v) & 0x1f_ffff;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

fn compact3(v: u64) -> u32 {
    let mut x = v & 0x1249_2492_4924_9249;
    x = (x ^ (x >> 2)) & 0x10c3_0c30_c30c_30c3;
    x = (x ^ (x >> 4)) & 0x100f_00f0_0f00_f00f;
    x = (x ^ (x >> 8)) & 0x1f_0000_ff00_00ff;
    x = (x ^ (x >> 16)) & 0x1f_0000_0000_ffff;
    x = (x ^ (x >> 32)) & 0x1f_ffff;
    x as u32
}

/// Interleaves the low 21 bits of x, y, z (x in bit 0) into a Morton code.
#[must_use]
pub fn morton_encode(c: UVec3) -> u64 {
    split3(c.x) | split3(c.y) << 1 | split3(c.z) << 2
}

/// Inverse of [`morton_encode`].
#[must_use]
pub fn morton_decode(code: u64) -> UVec3 {
    UVec3::new(compact3(code), compact3(code >> 1), compact3(code >> 2))
}

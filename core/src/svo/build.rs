//! Bulk construction: sort voxels by Morton code and build the levels bottom-up, so siblings are
//! contiguous by construction and no edit machinery is involved.

use glam::UVec3;
use rayon::prelude::*;

use super::morton::morton_encode;
use super::voxel::{Voxel, merge};
use super::{Attrs, Svo, SvoError, octant_offset};

impl Svo {
    /// Builds an octree from `(coordinate, voxel)` pairs. Later duplicates replace earlier ones.
    ///
    /// # Errors
    /// [`SvoError::BadDepth`], or [`SvoError::OutOfBounds`] for the first coordinate outside.
    pub fn from_voxels(
        depth: u8,
        has_skin: bool,
        voxels: impl IntoIterator<Item = (UVec3, Voxel)>,
    ) -> Result<Self, SvoError> {
        let mut svo = Self::new(depth, has_skin)?;
        let extent = svo.extent();
        let mut coded: Vec<(u64, Voxel)> = Vec::new();
        for (c, v) in voxels {
            if c.max_element() >= extent {
                return Err(SvoError::OutOfBounds {
                    coord: c.to_array(),
                    extent,
                });
            }
            coded.push((morton_encode(c), v));
        }
        if coded.is_empty() {
            return Ok(svo);
        }
        // Stable sort keeps input order among duplicates, so "last wins" is well defined.
        coded.par_sort_by_key(|e| e.0);
        let mut unique: Vec<(u64, Voxel)> = Vec::with_capacity(coded.len());
        for e in coded {
            match unique.last_mut() {
                Some(last) if last.0 == e.0 => *last = e,
                _ => unique.push(e),
            }
        }

        let leaf_attr = Attrs {
            color: unique.iter().map(|e| e.1.color).collect(),
            normal: unique.iter().map(|e| e.1.normal).collect(),
            material: unique.iter().map(|e| e.1.material).collect(),
            skin: if has_skin {
                unique.iter().map(|e| e.1.skin).collect()
            } else {
                Vec::new()
            },
            interior: unique.iter().any(|e| e.1.is_interior()),
        };

        // levels[l] for l in 0..depth: (code, mask, first child index within level l + 1).
        let mut levels: Vec<Vec<(u64, u8, u32)>> = vec![Vec::new(); depth as usize];
        let mut child_codes: Vec<u64> = unique.iter().map(|e| e.0).collect();
        for l in (0..depth as usize).rev() {
            let mut parents: Vec<(u64, u8, u32)> = Vec::new();
            for (i, &code) in child_codes.iter().enumerate() {
                let parent = code >> 3;
                let bit = 1u8 << (code & 7);
                match parents.last_mut() {
                    Some(p) if p.0 == parent => p.1 |= bit,
                    _ => parents.push((parent, bit, i as u32)),
                }
            }
            child_codes = parents.iter().map(|p| p.0).collect();
            levels[l] = parents;
        }

        let mut base = vec![0u32; depth as usize + 1];
        for l in 1..depth as usize {
            base[l] = base[l - 1] + levels[l - 1].len() as u32;
        }
        let inner_total: usize = levels.iter().map(Vec::len).sum();
        let mut inner_mask = Vec::with_capacity(inner_total);
        let mut inner_first = Vec::with_capacity(inner_total);
        for (l, nodes) in levels.iter().enumerate() {
            let child_base = if l + 1 == depth as usize {
                0
            } else {
                base[l + 1]
            };
            for &(_, mask, first) in nodes {
                inner_mask.push(mask);
                inner_first.push(child_base + first);
            }
        }

        let mut inner_attr = Attrs::default();
        inner_attr.push_empty(inner_total, has_skin);
        for l in (0..depth as usize).rev() {
            let (lo, hi) = (base[l] as usize, base[l] as usize + levels[l].len());
            let children = if l + 1 == depth as usize {
                &leaf_attr
            } else {
                &inner_attr
            };
            let merged: Vec<Voxel> = (lo..hi)
                .into_par_iter()
                .map(|i| {
                    let first = inner_first[i] as usize;
                    let n = inner_mask[i].count_ones() as usize;
                    merge(
                        (first..first + n)
                            .map(|c| (children.color[c], children.normal[c], children.material[c])),
                        children.skin.get(first..first + n),
                    )
                })
                .collect();
            for (i, v) in (lo..hi).zip(&merged) {
                inner_attr.set(i, v);
            }
        }

        svo.leaf_count = unique.len() as u64;
        svo.inner_count = inner_total as u64;
        svo.inner_mask = inner_mask;
        svo.inner_first = inner_first;
        svo.inner_attr = inner_attr;
        svo.leaf_attr = leaf_attr;
        if svo.tiling {
            Ok(svo.with_tiles())
        } else {
            Ok(svo)
        }
    }

    /// Builds an octree from a callback. `may_contain(origin, size)` prunes whole cubes that hold
    /// no solid voxel (return `true` when unsure); `voxel(coord)` gives each voxel. Work follows
    /// the cubes `may_contain` keeps, so a surface callback costs surface, not volume.
    ///
    /// # Errors
    /// [`SvoError::BadDepth`].
    pub fn from_fn(
        depth: u8,
        has_skin: bool,
        may_contain: impl Fn(UVec3, u32) -> bool + Sync,
        voxel: impl Fn(UVec3) -> Option<Voxel> + Sync,
    ) -> Result<Self, SvoError> {
        if depth == 0 || depth > super::MAX_DEPTH {
            return Err(SvoError::BadDepth(depth));
        }
        fn collect(
            origin: UVec3,
            size: u32,
            may_contain: &(impl Fn(UVec3, u32) -> bool + Sync),
            voxel: &(impl Fn(UVec3) -> Option<Voxel> + Sync),
            out: &mut Vec<(UVec3, Voxel)>,
        ) {
            if !may_contain(origin, size) {
                return;
            }
            if size == 1 {
                if let Some(v) = voxel(origin) {
                    out.push((origin, v));
                }
                return;
            }
            let half = size / 2;
            for k in 0..8u8 {
                collect(
                    origin + octant_offset(k, half),
                    half,
                    may_contain,
                    voxel,
                    out,
                );
            }
        }
        let extent = 1u32 << depth;
        let half = extent / 2;
        let voxels: Vec<(UVec3, Voxel)> = if may_contain(UVec3::ZERO, extent) {
            (0..8u8)
                .into_par_iter()
                .flat_map_iter(|k| {
                    let mut out = Vec::new();
                    collect(octant_offset(k, half), half, &may_contain, &voxel, &mut out);
                    out
                })
                .collect()
        } else {
            Vec::new()
        };
        Self::from_voxels(depth, has_skin, voxels)
    }
}

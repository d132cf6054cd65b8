//! Bulk construction: sort voxels by Morton code and build the levels bottom-up, so siblings are
//! contiguous by construction and no edit machinery is involved.

use glam::UVec3;
use rayon::prelude::*;

use super::morton::morton_encode;
use super::voxel::{Voxel, merge};
use super::{Attrs, Svo, SvoError, TILE, octant_offset};

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

        svo.build_sorted(unique, Vec::new());
        if svo.tiling {
            Ok(svo.with_tiles())
        } else {
            Ok(svo)
        }
    }

    /// Builds an octree from stored runs in one bottom-up pass: `runs` are `(origin, height,
    /// voxel)` in Morton order of their origins, leaves (height 0) and tiles (a cube of
    /// `2^height` voxels a side, `1 <= height <= depth`, origin aligned to its size) that do not
    /// overlap, each tile's value one this octree may store as a tile
    /// ([`Self::tile_value_ok`]); what [`Self::for_each_run`] gives and a file stores. Equal to
    /// building the leaves and putting each tile in, without walking a path per tile.
    ///
    /// # Errors
    /// [`SvoError::BadDepth`], or [`SvoError::OutOfBounds`] for the first run outside.
    pub(crate) fn from_runs(
        depth: u8,
        has_skin: bool,
        runs: impl IntoIterator<Item = (UVec3, u8, Voxel)>,
    ) -> Result<Self, SvoError> {
        let mut svo = Self::new(depth, has_skin)?;
        let extent = svo.extent();
        let runs = runs.into_iter();
        let (mut leaves, mut tiles) = (Vec::with_capacity(runs.size_hint().0), Vec::new());
        for (c, height, v) in runs {
            if c.max_element() >= extent || height > depth {
                return Err(SvoError::OutOfBounds {
                    coord: c.to_array(),
                    extent,
                });
            }
            let code = morton_encode(c);
            if height == 0 {
                leaves.push((code, svo.stored(v)));
            } else {
                debug_assert!(svo.tile_value_ok(&v), "tile value {v:?}");
                tiles.push((code, height, svo.stored(v)));
            }
        }
        debug_assert!(leaves.is_sorted_by_key(|e| e.0) && tiles.is_sorted_by_key(|e| e.0));
        svo.build_sorted(leaves, tiles);
        if svo.tiling {
            Ok(svo.with_tiles())
        } else {
            Ok(svo)
        }
    }

    /// Lays out an empty octree's nodes level by level (each level in Morton order, as
    /// [`Self::repack`] keeps them): `leaves` are `(Morton code, voxel)` sorted and unique,
    /// `tiles` `(origin's Morton code, height, voxel)` sorted, none overlapping a leaf or
    /// another tile.
    fn build_sorted(&mut self, leaves: Vec<(u64, Voxel)>, tiles: Vec<(u64, u8, Voxel)>) {
        let (depth, has_skin) = (usize::from(self.depth), self.has_skin);
        if leaves.is_empty() && tiles.is_empty() {
            return;
        }
        let leaf_attr = Attrs {
            color: leaves.iter().map(|e| e.1.color).collect(),
            normal: leaves.iter().map(|e| e.1.normal).collect(),
            material: leaves.iter().map(|e| e.1.material).collect(),
            skin: if has_skin {
                leaves.iter().map(|e| e.1.skin).collect()
            } else {
                Vec::new()
            },
            interior: leaves.iter().any(|e| e.1.is_interior()),
        };
        // Tiles by level (a tile of height h is a node at level depth − h), each list in code
        // order: codes at the tile's own level.
        let mut tiles_at: Vec<Vec<(u64, Voxel)>> = vec![Vec::new(); depth];
        let mut tile_voxels = 0u64;
        let tile_count = tiles.len() as u64;
        for (code, height, v) in tiles {
            let h = u32::from(height);
            tiles_at[depth - height as usize].push((code >> (3 * h), v));
            tile_voxels += 1u64 << (3 * h);
        }

        // levels[l] for l in 0..depth: (code, mask, first child index within level l + 1), a
        // tile's first being TILE.
        let mut levels: Vec<Vec<(u64, u8, u32)>> = vec![Vec::new(); depth];
        let leaf_count = leaves.len() as u64;
        let mut child_codes: Vec<u64> = leaves.iter().map(|e| e.0).collect();
        drop(leaves);
        for l in (0..depth).rev() {
            let mut parents: Vec<(u64, u8, u32)> = Vec::new();
            for (i, &code) in child_codes.iter().enumerate() {
                let parent = code >> 3;
                let bit = 1u8 << (code & 7);
                match parents.last_mut() {
                    Some(p) if p.0 == parent => p.1 |= bit,
                    _ => parents.push((parent, bit, i as u32)),
                }
            }
            // Merge this level's tiles in, by code.
            let here = &tiles_at[l];
            let nodes = if here.is_empty() {
                parents
            } else {
                let mut nodes = Vec::with_capacity(parents.len() + here.len());
                let mut t = here.iter().peekable();
                for p in parents {
                    while let Some(&&(code, _)) = t.peek().filter(|e| e.0 < p.0) {
                        nodes.push((code, 0, TILE));
                        t.next();
                    }
                    debug_assert!(t.peek().is_none_or(|e| e.0 != p.0), "a tile overlaps");
                    nodes.push(p);
                }
                nodes.extend(t.map(|&(code, _)| (code, 0, TILE)));
                nodes
            };
            child_codes = nodes.iter().map(|p| p.0).collect();
            levels[l] = nodes;
        }
        drop(child_codes);

        let mut base = vec![0u32; depth + 1];
        for l in 1..depth {
            base[l] = base[l - 1] + levels[l - 1].len() as u32;
        }
        let inner_total: usize = levels.iter().map(Vec::len).sum();
        let mut inner_mask = Vec::with_capacity(inner_total);
        let mut inner_first = Vec::with_capacity(inner_total);
        for (l, nodes) in levels.iter().enumerate() {
            let child_base = if l + 1 == depth { 0 } else { base[l + 1] };
            for &(_, mask, first) in nodes {
                inner_mask.push(mask);
                inner_first.push(if first == TILE {
                    TILE
                } else {
                    child_base + first
                });
            }
        }

        let mut inner_attr = Attrs::default();
        inner_attr.push_empty(inner_total, has_skin);
        for (l, here) in tiles_at.iter().enumerate() {
            let mut slot = base[l] as usize;
            for (code, v) in here {
                // The tile's slot: its place in its level's code order.
                slot += levels[l][slot - base[l] as usize..].partition_point(|n| n.0 < *code);
                inner_attr.set(slot, v);
            }
        }
        for l in (0..depth).rev() {
            let (lo, hi) = (base[l] as usize, base[l] as usize + levels[l].len());
            let children = if l + 1 == depth {
                &leaf_attr
            } else {
                &inner_attr
            };
            let merged: Vec<Option<Voxel>> = (lo..hi)
                .into_par_iter()
                .map(|i| {
                    let first = inner_first[i] as usize;
                    let n = inner_mask[i].count_ones() as usize;
                    (n > 0).then(|| {
                        merge(
                            (first..first + n).map(|c| {
                                (children.color[c], children.normal[c], children.material[c])
                            }),
                            children.skin.get(first..first + n),
                        )
                    })
                })
                .collect();
            for (i, v) in (lo..hi).zip(&merged) {
                if let Some(v) = v {
                    inner_attr.set(i, v);
                }
            }
        }

        self.leaf_count = leaf_count + tile_voxels;
        self.tile_count = tile_count;
        self.tile_voxels = tile_voxels;
        self.inner_count = inner_total as u64;
        self.inner_mask = inner_mask;
        self.inner_first = inner_first;
        self.inner_attr = inner_attr;
        self.leaf_attr = leaf_attr;
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

//! The shadow-map texels a frame's shading reads.
//!
//! Why: a shadow map is looked up only where a visible pixel faces its light, and only within
//! the PCF window around that pixel's position in the map. A caster whose footprint touches
//! none of those texels cannot change any lookup, so the shadow pass of a single frame culls
//! it like a node outside the frustum (docs/rendering.md "Shadow maps"). Every texel a lookup
//! reads still gets every caster, so the image is exactly the one a full map gives.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

/// Edge of a mask tile in texels, as a shift (8×8 texels: whole occlusion tiles, see
/// `DepthTarget::fill_nearest`).
const TILE_SHIFT: u32 = 3;
const _: () = assert!((1u32 << TILE_SHIFT).is_multiple_of(super::buffers::TILE));

/// Tiles of a shadow map that hold at least one texel some lookup reads, with a summed-area
/// table so that a rectangle query costs four reads.
#[derive(Default)]
pub(crate) struct SampledTexels {
    width: u32,
    height: u32,
    tiles_x: u32,
    tiles_y: u32,
    /// Per tile, row by row: whether some lookup reads it.
    read: Vec<bool>,
    /// `(tiles_x + 1) × (tiles_y + 1)` prefix sums of `read` (row 0 and column 0 zero).
    sums: Vec<u32>,
    /// Scratch of [`Self::reset`]: the flags as the windows set them, from any thread.
    marks: Vec<AtomicBool>,
}

impl SampledTexels {
    /// The mask of a `width`×`height` map from the inclusive texel windows of every lookup
    /// (`[x0, y0, x1, y1]`, inside the map). The result does not depend on the windows' order.
    #[cfg(test)]
    pub(crate) fn new(
        width: u32,
        height: u32,
        windows: impl ParallelIterator<Item = [u32; 4]>,
    ) -> Self {
        let mut m = Self::default();
        m.reset(width, height, windows);
        m
    }

    /// Makes this the mask of a `width`×`height` map from the inclusive texel windows of
    /// every lookup (`[x0, y0, x1, y1]`, inside the map), keeping its allocations. The result
    /// does not depend on the windows' order.
    pub(crate) fn reset(
        &mut self,
        width: u32,
        height: u32,
        windows: impl ParallelIterator<Item = [u32; 4]>,
    ) {
        let tiles_x = width.div_ceil(1 << TILE_SHIFT);
        let tiles_y = height.div_ceil(1 << TILE_SHIFT);
        let n = tiles_x as usize * tiles_y as usize;
        let marks = &mut self.marks;
        marks.truncate(n);
        for m in marks.iter_mut() {
            *m.get_mut() = false;
        }
        marks.resize_with(n, || AtomicBool::new(false));
        let flags = &marks[..];
        windows.for_each(|[x0, y0, x1, y1]| {
            for ty in y0 >> TILE_SHIFT..=y1 >> TILE_SHIFT {
                for tx in x0 >> TILE_SHIFT..=x1 >> TILE_SHIFT {
                    if let Some(t) = flags.get((ty * tiles_x + tx) as usize) {
                        t.store(true, Ordering::Relaxed);
                    }
                }
            }
        });
        let read = &mut self.read;
        read.clear();
        read.extend(marks.iter_mut().map(|m| *m.get_mut()));
        let stride = tiles_x as usize + 1;
        let sums = &mut self.sums;
        sums.clear();
        sums.resize(stride * (tiles_y as usize + 1), 0);
        for ty in 0..tiles_y as usize {
            let mut row = 0u32;
            for tx in 0..tiles_x as usize {
                row += u32::from(read[ty * tiles_x as usize + tx]);
                sums[(ty + 1) * stride + tx + 1] = sums[ty * stride + tx + 1] + row;
            }
        }
        self.width = width;
        self.height = height;
        self.tiles_x = tiles_x;
        self.tiles_y = tiles_y;
    }

    /// The texel rectangles (inclusive, inside the map) of the tiles no lookup reads.
    pub(crate) fn unread(&self) -> impl Iterator<Item = [u32; 4]> + '_ {
        (0..self.tiles_y).flat_map(move |ty| {
            (0..self.tiles_x).filter_map(move |tx| {
                let (x0, y0) = (tx << TILE_SHIFT, ty << TILE_SHIFT);
                let x1 = (x0 + (1 << TILE_SHIFT) - 1).min(self.width - 1);
                let y1 = (y0 + (1 << TILE_SHIFT) - 1).min(self.height - 1);
                (!self.read[(ty * self.tiles_x + tx) as usize]).then_some([x0, y0, x1, y1])
            })
        })
    }

    /// Whether this is the mask of a `width`×`height` map.
    pub(crate) fn is_for(&self, width: u32, height: u32) -> bool {
        (self.width, self.height) == (width, height)
    }

    /// Whether texel `(x, y)` (inside the map) lies in a tile some lookup reads.
    #[inline]
    pub(crate) fn is_read(&self, x: u32, y: u32) -> bool {
        self.read[((y >> TILE_SHIFT) * self.tiles_x + (x >> TILE_SHIFT)) as usize]
    }

    /// Whether any texel of the inclusive rectangle lies in a tile some lookup reads (a
    /// conservative answer: the tile, not the texel).
    #[inline]
    pub(crate) fn any(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> bool {
        let (tx0, ty0) = ((x0 >> TILE_SHIFT) as usize, (y0 >> TILE_SHIFT) as usize);
        let tx1 = ((x1 >> TILE_SHIFT) + 1).min(self.tiles_x) as usize;
        let ty1 = ((y1 >> TILE_SHIFT) + 1).min(self.tiles_y) as usize;
        if tx0 >= tx1 || ty0 >= ty1 {
            return false;
        }
        let stride = self.tiles_x as usize + 1;
        let s = &self.sums;
        s[ty1 * stride + tx1] + s[ty0 * stride + tx0]
            > s[ty0 * stride + tx1] + s[ty1 * stride + tx0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every query answers as a scan of the marked tiles would, at the map's edges, for
    /// rectangles of one texel to the whole map, and with nothing read at all.
    #[test]
    fn any_agrees_with_a_scan_of_the_marked_tiles() {
        let (w, h) = (61u32, 37u32);
        let windows = vec![
            [0u32, 0, 0, 0],
            [60, 36, 60, 36],
            [17, 9, 19, 11],
            [30, 20, 45, 21],
        ];
        let mask = SampledTexels::new(w, h, windows.clone().into_par_iter());
        let marked = |x: u32, y: u32| {
            windows.iter().any(|&[x0, y0, x1, y1]| {
                (x0 >> 3..=x1 >> 3).contains(&(x >> 3)) && (y0 >> 3..=y1 >> 3).contains(&(y >> 3))
            })
        };
        let mut hits = 0;
        for (x0, x1) in [
            (0, 0),
            (0, 60),
            (7, 8),
            (8, 15),
            (16, 23),
            (24, 29),
            (56, 60),
            (40, 60),
        ] {
            for (y0, y1) in [
                (0, 0),
                (0, 36),
                (7, 8),
                (8, 15),
                (16, 23),
                (24, 31),
                (32, 36),
            ] {
                let scan = (y0..=y1).any(|y| (x0..=x1).any(|x| marked(x, y)));
                assert_eq!(mask.any(x0, y0, x1, y1), scan, "{x0}..{x1} × {y0}..{y1}");
                hits += usize::from(scan);
            }
        }
        assert!(hits > 5 && hits < 56, "{hits} of 56 queries hit");
        let none = SampledTexels::new(w, h, Vec::<[u32; 4]>::new().into_par_iter());
        assert!(!none.any(0, 0, w - 1, h - 1));
    }
}
